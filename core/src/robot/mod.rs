//! A robot built from its file: the compiled chain, named points, mass model and error models.

pub mod batch;
pub mod candidate;
pub mod registry;
pub mod robot_file;

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Vector3};

use crate::data::measurement::{CsvLayout, Sample};
use crate::error::{Error, Issue, Issues, Result};
use crate::kinematics::collision::{BodyShape, CollisionGeometry, Fixture};
use crate::kinematics::point_kinematics::PointKinematics;
use crate::kinematics::sensor::{GravityReading, GravitySensor};
use crate::kinematics::subtree_loads::SubtreeLoads;
use crate::kinematics::workspace::TreeWorkspace;
use crate::model::geom::xyz_rpy;
use crate::model::mass::{BeamRigidity, MassModel, Payload};
use crate::model::param::ParamInfo;
use crate::model::perturbation::Perturbation;
use crate::model::shape::{Geometry, Shape};
use crate::model::tree::KinematicTree;
use crate::model::units::Units;
use crate::plugin::{BuildContext, Chain, ErrorModel, ModelContext, StaticState};
use crate::robot::robot_file::{BeamSpec, RobotFile, SourceFile};
use crate::support::limits::Cost;

/// A point resolved against the tree: body index and pose in the convention's link frame.
#[derive(Debug, Clone)]
struct ResolvedPoint {
    name: String,
    body: usize,
    local: Isometry3<f64>,
}

/// One station (instrument set-up) and its measurement frame: the robot base pose seen from
/// it.
#[derive(Debug, Clone, PartialEq)]
pub struct Station {
    /// The name a measurement file's `station` column gives it.
    pub name: String,
    /// `T_meas_base` of this station.
    pub frame: Isometry3<f64>,
}

/// A robot ready to evaluate: built once from a [`RobotFile`], then used read-only.
#[derive(Debug)]
pub struct Robot {
    /// The description it was built from (its values are not updated by
    /// [`set_chain_values`](Robot::set_chain_values); [`to_file`](Robot::to_file) writes them back).
    file: RobotFile,
    /// Where the description was read from, if from a file.
    pub source: Option<PathBuf>,
    chain: Box<dyn Chain>,
    chain_values: Vec<f64>,
    tree: KinematicTree,
    /// The rigid kinematics of every point of `tree`, compiled from it.
    kinematics: PointKinematics,
    points: Vec<ResolvedPoint>,
    mass: MassModel,
    gravity: Vector3<f64>,
    tool: usize,
    error_models: Vec<Box<dyn ErrorModel>>,
    error_values: Vec<Vec<f64>>,
    t_meas_base: Isometry3<f64>,
    /// The measurement frames of several stations (the first is `t_meas_base`); empty for one.
    stations: Vec<Station>,
    /// The body of `[measurement] frame_link`, resolved once: the calibration asks per sample.
    frame_link: Option<usize>,
    markers: Vec<usize>,
    /// The sensor giving the direction of gravity per measurement row, if the file has one.
    gravity_sensor: Option<GravitySensor>,
    /// Per coordinate, the value the robot file says it held while measuring (rad or m).
    hold: Vec<Option<f64>>,
    /// The point a payload hangs at (the file's payload point, else the tool); a payload given
    /// per measurement without one hangs at the base origin.
    payload_point: Option<usize>,
    collision: CollisionGeometry,
    warnings: Vec<String>,
    /// Files read to build it besides `source` (URDF, meshes, plugin libraries).
    reads: Vec<PathBuf>,
}

/// Conditions of one evaluation that error models may depend on besides the joint values.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Conditions {
    /// Ambient temperature (°C).
    pub temperature: Option<f64>,
    /// Payload mass (kg) replacing the robot file's payload.
    pub payload: Option<f64>,
    /// The measured direction of gravity (a sensor's reading), replacing the robot file's
    /// direction; the file's magnitude is kept.
    pub gravity: Option<GravityReading>,
}

impl Conditions {
    /// The conditions a measured sample records.
    pub fn of(sample: &crate::data::measurement::Sample) -> Self {
        Conditions {
            temperature: sample.temperature,
            payload: sample.payload,
            gravity: sample.gravity,
        }
    }
}

/// Buffers for evaluating a [`Robot`]: rigid frames, the deformation, the deformed frames.
#[derive(Debug, Clone)]
pub struct RobotWorkspace {
    /// Rigid forward kinematics (what error models look at).
    pub rigid: TreeWorkspace,
    /// The deformation the error models produced.
    pub perturbation: Perturbation,
    /// Forward kinematics of the deformed arm (equal to `rigid` without error models).
    pub frames: TreeWorkspace,
    /// The mass model with a per-evaluation payload applied.
    pub mass: MassModel,
    /// The subtree loads of the last evaluation's rigid frames.
    pub loads: SubtreeLoads,
    /// Whether the last evaluation's loads were the robot's own mass model (otherwise `mass`)
    /// and its gravity, as load-adjusting error models left them.
    own_mass: bool,
    gravity: Vector3<f64>,
}

/// Gravity (m/s²) no robot works in: a hundred times Earth's.
const ABSURD_GRAVITY: f64 = 1e3;

/// Gravity (m/s²) beyond which a robot file is warned about: twice Earth's, more than any
/// planet a robot is calibrated on, and what a unit slip (cm/s²) or a typo gives.
const PLAUSIBLE_GRAVITY: f64 = 20.0;

/// Names of the base frame's six parameters (`base.<name>`), in the order of
/// [`xyz_rpy`](crate::model::geom::xyz_rpy): position, then roll, pitch, yaw.
pub(crate) const BASE_NAMES: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];

impl Robot {
    /// Reads, checks and builds a robot file; every problem names the file, line and field.
    pub fn from_path(path: &Path) -> Result<Robot> {
        // Parsing may load libraries too (a fitted run-time predictor).
        let (read, files) = crate::support::io::recording_reads(|| RobotFile::read(path));
        let (file, src) = read?;
        let mut robot = Robot::from_source(file, &src)?;
        robot.reads.extend(files);
        Ok(robot)
    }

    /// Checks and builds a parsed robot file, mapping problems to lines of `src`.
    pub fn from_source(file: RobotFile, src: &SourceFile) -> Result<Robot> {
        let dir = src.path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut robot = Robot::build_from(file, &dir, Some(src)).map_err(|issues| src.invalid(issues))?;
        robot.source = Some(src.path.clone());
        Ok(robot)
    }

    /// Checks and builds a robot description; `base_dir` resolves relative paths in it. The
    /// files read meanwhile on this thread are the robot's [`inputs`](Robot::inputs).
    pub fn build(file: RobotFile, base_dir: &Path) -> Result<Robot, Vec<Issue>> {
        Robot::build_from(file, base_dir, None)
    }

    /// [`build`](Robot::build); warnings name their line in `src`, when given.
    fn build_from(file: RobotFile, base_dir: &Path, src: Option<&SourceFile>) -> Result<Robot, Vec<Issue>> {
        let (built, files) = crate::support::io::recording_reads(|| Robot::build_unrecorded(file, base_dir, src));
        let mut robot = built?;
        robot.reads = files;
        Ok(robot)
    }

    fn build_unrecorded(mut file: RobotFile, base_dir: &Path, src: Option<&SourceFile>) -> Result<Robot, Vec<Issue>> {
        let mut issues = Issues::default();
        let units = file.units;
        let ctx = BuildContext {
            units,
            base_dir,
            path: "kinematics",
        };
        let chain = file.kinematics.build(&ctx).map_err(|i| i.0)?;
        let chain_values: Vec<f64> = chain.params().iter().map(|p| p.nominal).collect();
        let base_tree = chain
            .tree(&chain_values)
            .map_err(|e| vec![Issue::new("kinematics", e.to_string())])?;

        if file.gravity.iter().any(|g| !g.is_finite()) {
            issues.push("gravity", "expected three finite numbers (m/s²)");
        } else if let Some(g) = file.gravity.iter().find(|g| g.abs() > ABSURD_GRAVITY) {
            issues.push(
                "gravity",
                format!(
                    "a component of {g:e} m/s² is physically absurd; expected a magnitude of at most {ABSURD_GRAVITY} m/s² (Earth's is 9.81)"
                ),
            );
        }
        let gravity = Vector3::from(file.gravity);

        check_joint_names(&file, &base_tree, &mut issues);

        let (points, tool) = resolve_points(&file, &base_tree, &units, &mut issues);

        let (mut mass, shapes) = mass_and_shapes(&file, chain.as_ref(), &base_tree, &units, &mut issues);
        let collision = collision_geometry(&file, &base_tree, shapes, &mut issues);
        let warnings = chain.warnings().to_vec();

        let payload_point = resolve_payload(&file, &points, tool, &base_tree, &mut mass, &mut issues);

        let (t_meas_base, markers, hold) = measurement_setup(&file, &base_tree, &points, tool, &units, &mut issues);
        let gravity_sensor = resolve_sensors(&file, &base_tree, &mut issues);
        let stations = station_frames(&file, &units, &mut issues);
        let t_meas_base = stations.first().map_or(t_meas_base, |s| s.frame);
        let frame_link = (file.measurement.as_ref())
            .and_then(|m| m.frame_link.as_ref())
            .and_then(|name| base_tree.body_index(name));

        // A predictor that names files (a run-time library) finds them beside this file, as
        // error models do, and not in the working folder it is later fitted from.
        let pctx = BuildContext {
            units,
            base_dir,
            path: "predictor",
        };
        match file.predictor.as_deref().map(|p| p.resolve(&pctx)) {
            Some(Ok(Some(resolved))) => file.predictor = Some(resolved),
            Some(Err(e)) => issues.0.extend(e.0),
            Some(Ok(None)) | None => {}
        }

        if !issues.is_empty() {
            return Err(issues.0);
        }

        let mut robot = Robot {
            file,
            source: None,
            chain,
            chain_values,
            kinematics: PointKinematics::new(&base_tree),
            tree: base_tree,
            points,
            mass,
            gravity,
            tool: tool.unwrap_or(0),
            error_models: Vec::new(),
            error_values: Vec::new(),
            t_meas_base,
            stations,
            frame_link,
            markers,
            gravity_sensor,
            hold,
            payload_point,
            collision,
            warnings,
            reads: Vec::new(),
        };
        let tree = robot
            .tree_for(&robot.chain_values)
            .map_err(|e| vec![Issue::new("kinematics", e.to_string())])?;
        robot.set_tree(tree);
        // The payload's centre of mass is its point's pose in the tree (bit for bit, so that
        // `mass_under` sees it unmoved).
        let site = robot.payload_site(&robot.tree);
        if let Some(p) = robot.mass.payload.as_mut() {
            p.com = site.1;
        }

        let models = build_error_models(&robot, base_dir, &mut issues);
        if !issues.is_empty() {
            return Err(issues.0);
        }
        robot.error_values = models
            .iter()
            .map(|m| m.params().iter().map(|p| p.nominal).collect())
            .collect();
        robot.error_models = models;
        let implausible = implausible_values(&robot);
        robot.warnings.extend(implausible.0.into_iter().map(|mut i| match src {
            Some(src) => {
                i.line = src.line_of_path(&i.path);
                i.in_file(&src.path)
            }
            None => i.in_model(),
        }));
        Ok(robot)
    }

    /// The tree for chain parameter `values`, with the robot's points attached.
    pub fn tree_for(&self, values: &[f64]) -> Result<KinematicTree> {
        let mut tree = self.chain.tree(values)?;
        for p in &self.points {
            let local = tree.bodies()[p.body].convention_frame * p.local;
            tree.add_point(p.name.clone(), p.body, local)?;
        }
        Ok(tree)
    }

    /// Folder that relative paths in the description resolve against.
    pub fn base_dir(&self) -> PathBuf {
        self.source
            .as_deref()
            .and_then(Path::parent)
            .map(Path::to_path_buf)
            .unwrap_or_default()
    }

    /// Builds another robot from `file` as if it lived next to this one (same folder, same
    /// source for messages); used to apply identified values.
    pub fn rebuild(&self, file: RobotFile) -> Result<Robot> {
        let mut robot = Robot::build(file, &self.base_dir()).map_err(Error::InvalidModel)?;
        robot.source = self.source.clone();
        for f in &self.reads {
            if !robot.reads.contains(f) {
                robot.reads.push(f.clone());
            }
        }
        Ok(robot)
    }

    /// Every file this robot was read from: its source, and the files that names (URDF,
    /// meshes, plugin libraries). Outputs must never replace one of them.
    pub fn inputs(&self) -> Vec<PathBuf> {
        let mut files: Vec<PathBuf> = self.source.iter().cloned().collect();
        for f in &self.reads {
            if !files.contains(f) {
                files.push(f.clone());
            }
        }
        files
    }

    /// The description it was built from, as given: parameter values as read (see
    /// [`to_file`](Robot::to_file) for the current ones), its `[predictor]` table and fitted
    /// predictor.
    pub fn built_from(&self) -> &RobotFile {
        &self.file
    }
    /// The robot's name.
    pub fn name(&self) -> &str {
        &self.file.name
    }
    /// Its free-text description, if the file has one.
    pub fn description(&self) -> Option<&str> {
        self.file.description.as_deref()
    }
    /// The units its file is written in, which its outputs use too.
    pub fn units(&self) -> Units {
        self.file.units
    }
    /// Parameter name patterns the file fixes: calibration never refits them.
    pub fn fixed(&self) -> &[String] {
        &self.file.fixed
    }
    /// The `type` of each error model, as robot files write it.
    pub fn error_model_types(&self) -> Vec<String> {
        self.file
            .error_models
            .iter()
            .map(|m| {
                serde_json::to_value(m)
                    .ok()
                    .and_then(|v| v.get("type").and_then(|t| t.as_str()).map(String::from))
                    .unwrap_or_default()
            })
            .collect()
    }
    /// The compiled kinematic convention.
    pub fn chain(&self) -> &dyn Chain {
        self.chain.as_ref()
    }
    /// Current values of the chain parameters (SI).
    pub fn chain_values(&self) -> &[f64] {
        &self.chain_values
    }
    /// Identifiable parameters of the chain.
    pub fn chain_params(&self) -> &[ParamInfo] {
        self.chain.params()
    }
    /// The kinematic tree at the current parameters, with points.
    pub fn tree(&self) -> &KinematicTree {
        &self.tree
    }

    /// The rigid kinematics of every point of the [`tree`](Robot::tree), the points in the
    /// tree's order: only the joints on their paths, fixed joints folded in.
    pub fn kinematics(&self) -> &PointKinematics {
        &self.kinematics
    }
    /// Mass model, payload included.
    pub fn mass(&self) -> &MassModel {
        &self.mass
    }
    /// Gravity in the base frame (m/s²).
    pub fn gravity(&self) -> Vector3<f64> {
        self.gravity
    }
    /// Index of the tool point in [`tree().points()`](KinematicTree::points).
    pub fn tool(&self) -> usize {
        self.tool
    }
    /// Indices of the points the tracker measures.
    pub fn markers(&self) -> &[usize] {
        &self.markers
    }

    /// Per tree joint, whether it is on the path from the base to a marker or to the frame link.
    pub fn measured_joints(&self) -> Vec<bool> {
        let mut on = vec![false; self.tree.joints().len()];
        for b in self.measured_bodies() {
            self.tree.support(b).iter().for_each(|&j| on[j] = true);
        }
        on
    }

    /// The bodies whose paths from the root move what is measured: the markers' and the frame
    /// link's (whose joints move the measurement frame).
    fn measured_bodies(&self) -> Vec<usize> {
        let markers = self.markers.iter().map(|&m| self.tree.points()[m].body);
        markers.chain(self.frame_link()).collect()
    }

    /// Names of the moving joints on the path from the base to a marker or to the frame link, in tree
    /// order.
    pub fn measured_joint_names(&self) -> Vec<String> {
        let on = self.measured_joints();
        self.tree
            .joints()
            .iter()
            .zip(on)
            .filter(|(j, on)| *on && j.motion != crate::model::tree::Motion::Fixed)
            .map(|(j, _)| j.name.clone())
            .collect()
    }

    /// Names of the joints a measurement file must give a column for: the measured chain's
    /// independent coordinates (a mimic joint's driving joint, never the mimic) whose value
    /// the robot file does not `hold`, in coordinate order.
    pub fn csv_joint_names(&self) -> Vec<String> {
        self.csv_layout()
            .hold
            .iter()
            .zip(self.tree.coordinate_names())
            .filter(|(held, _)| held.is_none())
            .map(|(_, name)| name.clone())
            .collect()
    }

    /// Per independent coordinate, whether it moves a marker: the measured chain, whose
    /// joints a measurement file must give.
    pub fn measured_coordinates(&self) -> Vec<bool> {
        self.tree.coordinates_moving(&self.measured_bodies())
    }

    /// How measurement files of this robot are read: numbered position columns are its
    /// markers; a coordinate of the measured chain needs a column unless the file says what it
    /// held, every other one holds that value, 0, or the middle of its limits when 0 is outside.
    pub fn csv_layout(&self) -> CsvLayout<'_> {
        let measured = self.measured_coordinates();
        let hold = self
            .hold
            .iter()
            .zip(self.tree.coordinate_limits())
            .zip(measured)
            .map(|((held, limits), measured)| match (held, measured) {
                (Some(v), _) => Some(*v),
                (None, true) => None,
                (None, false) => Some(match limits {
                    Some(l) if !(l.lower..=l.upper).contains(&0.0) => 0.5 * (l.lower + l.upper),
                    _ => 0.0,
                }),
            })
            .collect();
        CsvLayout {
            tree: &self.tree,
            units: self.units(),
            points: if self.markers.is_empty() {
                vec![self.tool]
            } else {
                self.markers.clone()
            },
            hold,
            orientation: self.measures_pose(),
            fixed_points: self.measures_fixed_points(),
            planes: self.measures_planes(),
            gravity_sensor: self.gravity_sensor.clone(),
        }
    }

    /// Whether the robot file declares fixed-point measurements
    /// (`[measurement] kind = "fixed_point"`).
    pub fn measures_fixed_points(&self) -> bool {
        self.file
            .measurement
            .as_ref()
            .is_some_and(|m| m.kind == crate::robot::robot_file::MeasurementKind::FixedPoint)
    }

    /// Whether the robot file declares plane contacts (`[measurement] kind = "plane"`).
    pub fn measures_planes(&self) -> bool {
        self.file
            .measurement
            .as_ref()
            .is_some_and(|m| m.kind == crate::robot::robot_file::MeasurementKind::Plane)
    }

    /// Whether the measurements need no instrument (fixed points, plane contacts): the robot's
    /// base frame is then invisible, moving with the unknown points or planes.
    pub fn measures_without_instrument(&self) -> bool {
        self.measures_fixed_points() || self.measures_planes()
    }

    /// The nominal planes the robot file declares (measurement frame, SI), by name.
    pub fn nominal_planes(&self) -> Vec<(String, Isometry3<f64>)> {
        let units = self.file.units;
        self.file
            .measurement
            .iter()
            .flat_map(|m| &m.planes)
            .map(|p| (p.name.clone(), xyz_rpy(units.len3(p.xyz), units.ang3(p.rpy))))
            .collect()
    }

    /// What a plane contact constrains, in the order height, roll, pitch (all three unless
    /// the robot file's `constrain` says otherwise).
    pub fn plane_constraints(&self) -> PlaneConstraints {
        use crate::robot::robot_file::PlaneComponent;
        let listed = self.file.measurement.as_ref().map_or(&[][..], |m| &m.constrain);
        let has = |c| listed.is_empty() || listed.contains(&c);
        PlaneConstraints {
            height: has(PlaneComponent::Height),
            roll: has(PlaneComponent::Roll),
            pitch: has(PlaneComponent::Pitch),
        }
    }

    /// The link the measurements are expressed in (`[measurement] frame_link`), when it is
    /// not the root.
    pub fn frame_link(&self) -> Option<usize> {
        self.frame_link
    }

    /// The known distances between fixed points the robot file declares.
    pub fn known_distances(&self) -> &[crate::robot::robot_file::DistanceSpec] {
        self.file.measurement.as_ref().map_or(&[], |m| &m.distances)
    }

    /// Whether the robot file declares pose measurements (`[measurement] kind = "pose"`).
    pub fn measures_pose(&self) -> bool {
        self.file
            .measurement
            .as_ref()
            .is_some_and(|m| m.kind == crate::robot::robot_file::MeasurementKind::Pose)
    }

    /// Calibration parameters per marker: its position, and with pose measurements its
    /// orientation too (`rx, ry, rz`, a rotation vector about the point's own axes).
    pub fn marker_dofs(&self) -> usize {
        let tilts = self.measures_planes() && self.plane_constraints().tilts() > 0;
        if self.measures_pose() || tilts { 6 } else { 3 }
    }
    /// Floating-point operations of one forward kinematics: about a hundred and fifty a body
    /// for the rigid chain (a transform product and the points on it), and as much again a body
    /// for every error model (loads, compliances, deflections). Sizes are checked against
    /// [the limits](crate::support::limits) with it.
    pub fn fk_flops(&self) -> f64 {
        150.0 * self.tree.bodies().len() as f64 * (1 + self.error_models.len()) as f64
    }
    /// What one planned or simulated pose costs: its joint values and a sample for each
    /// measured point in memory, with their CSV text (about 20 characters a number); its forward
    /// kinematics and that text in time (a shortest round-trip decimal takes about as long as
    /// 150 operations).
    pub fn pose_cost(&self) -> Cost {
        let joints = self.tree.coordinate_names().len() as f64;
        let points = self.markers.len().max(1) as f64;
        let values = 8.0 * joints + 48.0;
        Cost {
            bytes: values + points * (std::mem::size_of::<Sample>() as f64 + values + 20.0 * (joints + 3.0)),
            flops: self.fk_flops() + 150.0 * points * (joints + 3.0),
        }
    }
    /// Guess of the robot base pose in the measurement frame.
    pub fn t_meas_base(&self) -> Isometry3<f64> {
        self.t_meas_base
    }
    /// The stations of data measured from several (see [`Station`]); empty for one, whose
    /// frame is [`t_meas_base`](Self::t_meas_base).
    pub fn stations(&self) -> &[Station] {
        &self.stations
    }
    /// The measurement frame of station `k` ([`Sample::station`]): `t_meas_base` for a robot
    /// with one station.
    pub fn station_frame(&self, k: usize) -> Isometry3<f64> {
        self.stations.get(k).map_or(self.t_meas_base, |s| s.frame)
    }
    /// How many measurement frames calibration identifies: one per station, at least one.
    pub fn n_stations(&self) -> usize {
        self.stations.len().max(1)
    }
    /// Sets the stations (none or one: a single frame, `t_meas_base`), in the description too.
    pub fn set_stations(&mut self, mut stations: Vec<Station>) {
        if let Some(first) = stations.first() {
            self.t_meas_base = first.frame;
        }
        if stations.len() == 1 {
            stations.clear();
        }
        let units = self.units();
        let spec = |frame: &Isometry3<f64>| {
            let v = frame.translation.vector;
            let (r, p, y) = frame.rotation.euler_angles();
            (
                [v.x, v.y, v.z].map(|v| units.len_out(v)),
                [r, p, y].map(|v| units.ang_out(v)),
            )
        };
        let m = self.file.measurement.get_or_insert_with(Default::default);
        (m.base_xyz, m.base_rpy) = spec(&self.t_meas_base);
        m.stations = stations
            .iter()
            .map(|s| {
                let (base_xyz, base_rpy) = spec(&s.frame);
                crate::robot::robot_file::StationSpec {
                    name: s.name.clone(),
                    base_xyz,
                    base_rpy,
                }
            })
            .collect();
        self.stations = stations;
    }
    /// Gives the robot the stations `names` of a measurement set, in that order, so that the
    /// set's [`Sample::station`] indices are the robot's: a station it knows keeps its frame, a
    /// new one starts at the first station's. Returns the indices of the new ones, which need
    /// registering. Data of one station keep the robot's frame (as data without stations).
    pub fn adopt_stations(&mut self, names: &[String]) -> Vec<usize> {
        let known = |name: &String| self.stations.iter().find(|s| &s.name == name).map(|s| s.frame);
        if names.len() == 1 && self.stations.is_empty() {
            return Vec::new();
        }
        let mut new = Vec::new();
        let stations = names
            .iter()
            .enumerate()
            .map(|(k, name)| Station {
                name: name.clone(),
                frame: known(name).unwrap_or_else(|| {
                    new.push(k);
                    self.t_meas_base
                }),
            })
            .collect();
        if !names.is_empty() {
            self.set_stations(stations);
        }
        new
    }
    /// The built error models.
    pub fn error_models(&self) -> &[Box<dyn ErrorModel>] {
        &self.error_models
    }
    /// Current parameter values of each error model (SI).
    pub fn error_values(&self) -> &[Vec<f64>] {
        &self.error_values
    }
    /// Link shapes, fixtures and collision settings (see [`CollisionModel`](crate::CollisionModel)).
    pub fn collision(&self) -> &CollisionGeometry {
        &self.collision
    }
    /// What was skipped while reading the description (e.g. meshes that cannot be found).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }
    /// Names of the measurement-setup parameters, in [`ParameterSpace`](crate::calibrate::ParameterSpace) order: the base
    /// frame (`base.x … base.yaw`), then each marker's offset (`marker.<point>.x|y|z`, and `rx|ry|rz` when it measures poses).
    pub fn setup_param_names(&self) -> Vec<String> {
        let base = BASE_NAMES.iter().map(|n| format!("base.{n}"));
        let markers = self.markers().iter().flat_map(|&m| {
            let name = &self.tree().points()[m].name;
            ["x", "y", "z", "rx", "ry", "rz"][..self.marker_dofs()]
                .iter()
                .map(move |a| format!("marker.{name}.{a}"))
        });
        base.chain(markers).collect()
    }

    /// The residual predictor the robot file configures (hyper-parameters), if any.
    pub fn predictor_spec(&self) -> Option<&dyn crate::plugin::PredictorSpec> {
        self.file.predictor.as_deref()
    }
    /// The predictor fitted to this robot's residuals (a model file written by `learn`), if any.
    pub fn predictor(&self) -> Option<&dyn crate::plugin::FittedPredictor> {
        self.file.fitted_predictor.as_deref()
    }
    /// The frame the fitted predictor's outputs are in (`measurement` for a file that does not
    /// say: files written before the predictor followed the robot).
    pub fn predictor_frame(&self) -> crate::robot::robot_file::PredictorFrame {
        self.file.predictor_frame.unwrap_or_default()
    }

    /// Sets the chain parameters and rebuilds the tree.
    pub fn set_chain_values(&mut self, values: &[f64]) -> Result<()> {
        if values.len() != self.chain_values.len() {
            return Err(Error::Dimension {
                what: "chain parameters".into(),
                expected: self.chain_values.len(),
                got: values.len(),
            });
        }
        let tree = self.tree_for(values)?;
        self.set_tree(tree);
        self.chain_values = values.to_vec();
        Ok(())
    }

    /// Replaces the tree and the point kinematics compiled from it.
    fn set_tree(&mut self, tree: KinematicTree) {
        self.kinematics = PointKinematics::new(&tree);
        self.tree = tree;
    }

    /// Buffers sized for this robot.
    pub fn workspace(&self) -> RobotWorkspace {
        RobotWorkspace {
            rigid: TreeWorkspace::new(&self.tree),
            perturbation: Perturbation::zeros(&self.tree),
            frames: TreeWorkspace::new(&self.tree),
            mass: self.mass.clone(),
            loads: SubtreeLoads::default(),
            own_mass: true,
            gravity: self.gravity,
        }
    }

    /// Forward kinematics of the full model (chain + error models) into `ws.frames`.
    /// `temperature` (°C) is passed to models that use it.
    pub fn forward_into(&self, q: &[f64], temperature: Option<f64>, ws: &mut RobotWorkspace) {
        let conditions = Conditions {
            temperature,
            ..Conditions::default()
        };
        self.forward_with_into(&self.tree, &self.error_values, q, conditions, ws);
    }

    /// Forward kinematics of the full model with other parameter values than the robot's own:
    /// `tree` from [`tree_for`](Robot::tree_for) and one value list per error model (what
    /// calibration varies). A payload in `conditions` replaces the file's payload mass.
    pub fn forward_with_into(
        &self,
        tree: &KinematicTree,
        error_values: &[Vec<f64>],
        q: &[f64],
        conditions: Conditions,
        ws: &mut RobotWorkspace,
    ) {
        if self.error_models.is_empty() {
            tree.forward_into(q, &mut ws.rigid);
            ws.frames.clone_from(&ws.rigid);
            return;
        }
        self.deformation_into(tree, error_values, q, conditions, ws);
        tree.forward_perturbed_from_rigid_into(q, &ws.perturbation, &ws.rigid, &mut ws.frames);
    }

    /// The first half of [`forward_with_into`](Robot::forward_with_into): the rigid frames
    /// into `ws.rigid` and the error models' deformation into `ws.perturbation`, without the
    /// deformed frames (`ws.frames` is left as it was).
    pub fn deformation_into(
        &self,
        tree: &KinematicTree,
        error_values: &[Vec<f64>],
        q: &[f64],
        conditions: Conditions,
        ws: &mut RobotWorkspace,
    ) {
        tree.forward_into(q, &mut ws.rigid);
        self.deformation_at_rigid_into(tree, error_values, q, conditions, ws);
    }

    /// [`deformation_into`](Robot::deformation_into) of a tree that differs from the one
    /// `prefix` evaluated at the same `q` only in the placements of the joints `stepped` and in
    /// its points (see [`KinematicTree::forward_restepped_into`]); the same bits.
    #[allow(clippy::too_many_arguments)]
    pub fn deformation_restepped_into(
        &self,
        tree: &KinematicTree,
        error_values: &[Vec<f64>],
        q: &[f64],
        conditions: Conditions,
        prefix: &TreeWorkspace,
        stepped: &[usize],
        ws: &mut RobotWorkspace,
    ) {
        tree.forward_restepped_into(q, prefix, stepped, &mut ws.rigid);
        self.deformation_at_rigid_into(tree, error_values, q, conditions, ws);
    }

    /// The error models' deformation at the rigid frames already in `ws.rigid`.
    fn deformation_at_rigid_into(
        &self,
        tree: &KinematicTree,
        error_values: &[Vec<f64>],
        q: &[f64],
        conditions: Conditions,
        ws: &mut RobotWorkspace,
    ) {
        ws.perturbation.clear();
        let (own_mass, gravity) = self.loads_into(conditions, tree, &ws.rigid, error_values, &mut ws.mass);
        ws.own_mass = own_mass;
        ws.gravity = gravity;
        let mass = if own_mass { &self.mass } else { &ws.mass };
        ws.loads.update(tree, &ws.rigid, mass);
        let state = StaticState {
            q,
            tree,
            frames: &ws.rigid,
            mass,
            loads: &ws.loads,
            gravity,
            temperature: conditions.temperature,
        };
        for (m, v) in self.error_models.iter().zip(error_values) {
            if !m.is_inactive(v) {
                m.perturb(&state, v, &mut ws.perturbation);
            }
        }
    }

    /// Whether some error model deforms the robot at `error_values` (one list per model; see
    /// [`ErrorModel::is_inactive`]).
    pub fn deforms_at(&self, error_values: &[Vec<f64>]) -> bool {
        self.error_models
            .iter()
            .zip(error_values)
            .any(|(m, v)| !m.is_inactive(v))
    }

    /// The loads under `conditions` with the points of `tree` and error-model `values`:
    /// whether the mass model is the robot's own (otherwise the one written into `scratch`:
    /// a payload applied, or load-adjusting models' payload mass) and the gravity (base
    /// frame; a measured direction carried there by the rigid frames `frames` of `tree`),
    /// load-adjusting models applied in order.
    pub fn loads_into(
        &self,
        conditions: Conditions,
        tree: &KinematicTree,
        frames: &TreeWorkspace,
        error_values: &[Vec<f64>],
        scratch: &mut MassModel,
    ) -> (bool, Vector3<f64>) {
        let adjusting = self.error_models.iter().any(|m| m.adjusts_loads());
        let own = self.mass_is_own(conditions, tree);
        let gravity = self.gravity_under(conditions, tree, frames);
        if !adjusting {
            if !own {
                self.mass_under(conditions, tree, scratch);
            }
            return (own, gravity);
        }
        if own {
            scratch.clone_from(&self.mass);
        } else {
            self.mass_under(conditions, tree, scratch);
        }
        let declared = scratch.payload.as_ref().map_or(0.0, |p| p.mass);
        // A load-adjusting model starts from the measured gravity: `base_tilt` then turns it by
        // a constant angle, the sensor's misalignment with the base (see its documentation).
        let mut loads = crate::plugin::Loads {
            gravity,
            payload_mass: declared,
        };
        for (m, v) in self.error_models.iter().zip(error_values) {
            m.adjust_loads(v, &mut loads);
        }
        if loads.payload_mass != declared {
            let (body, com) = self.payload_site(tree);
            scratch.payload.get_or_insert(Payload { mass: 0.0, body, com }).mass = loads.payload_mass;
        }
        (false, loads.gravity)
    }

    /// Gravity in the base frame (m/s²) under `conditions`: the robot file's, or its magnitude
    /// along a measured direction carried to the base frame by the rigid frames `frames` of
    /// `tree` (the sensor's link where the row's joint values put it).
    pub fn gravity_under(&self, conditions: Conditions, tree: &KinematicTree, frames: &TreeWorkspace) -> Vector3<f64> {
        match conditions.gravity {
            Some(reading) => self.gravity.norm() * reading.in_base(tree, frames),
            None => self.gravity,
        }
    }

    /// The sensor whose columns give the direction of gravity per measurement row, if any.
    pub fn gravity_sensor(&self) -> Option<&GravitySensor> {
        self.gravity_sensor.as_ref()
    }

    /// The mass model under `conditions` with the points of `tree`: the robot's own, or a copy
    /// in `scratch` when they carry a payload (that mass at the payload's site) or when `tree`
    /// moves the payload's point (calibration moving a marker the payload hangs at, or the
    /// convention frame the point is given in), so that a fit sees the payload where its
    /// model file will put it.
    pub fn mass_under<'a>(
        &'a self,
        conditions: Conditions,
        tree: &KinematicTree,
        scratch: &'a mut MassModel,
    ) -> &'a MassModel {
        if self.mass_is_own(conditions, tree) {
            return &self.mass;
        }
        scratch.clone_from(&self.mass);
        let (body, com) = self.payload_site(tree);
        let site = scratch.payload.get_or_insert(Payload { mass: 0.0, body, com });
        site.com = com;
        if let Some(m) = conditions.payload {
            site.mass = m;
        }
        scratch
    }

    /// Whether [`mass_under`](Robot::mass_under) is the robot's own mass model.
    fn mass_is_own(&self, conditions: Conditions, tree: &KinematicTree) -> bool {
        conditions.payload.is_none()
            && self
                .mass
                .payload
                .as_ref()
                .is_none_or(|p| p.com == self.payload_site(tree).1)
    }

    /// Body and position in it (m) where a payload hangs, with the points of `tree`.
    fn payload_site(&self, tree: &KinematicTree) -> (usize, Vector3<f64>) {
        self.payload_point.map_or((0, Vector3::zeros()), |p| {
            let point = &tree.points()[p];
            (point.body, point.local.translation.vector)
        })
    }

    /// Adds the deformation of error model `model` alone, with parameter `values`, to `out`,
    /// at the rigid frames of the last [`forward_with_into`](Robot::forward_with_into) in `ws`
    /// (same `tree`, and the joint values and conditions of `sample`). Calibration
    /// differentiates models through this.
    pub fn model_perturbation_into(
        &self,
        model: usize,
        tree: &KinematicTree,
        values: &[f64],
        sample: &crate::data::measurement::Sample,
        ws: &RobotWorkspace,
        out: &mut Perturbation,
    ) {
        let conditions = Conditions::of(sample);
        let state = StaticState {
            q: &sample.q,
            tree,
            frames: &ws.rigid,
            mass: if ws.own_mass { &self.mass } else { &ws.mass },
            loads: &ws.loads,
            gravity: ws.gravity,
            temperature: conditions.temperature,
        };
        self.error_models[model].perturb(&state, values, out);
    }

    /// Position of point `point` in the measurement frame for sample-like inputs, through the
    /// full model at the robot's own parameters (m).
    pub fn measured_position(
        &self,
        q: &[f64],
        point: usize,
        conditions: Conditions,
        ws: &mut RobotWorkspace,
    ) -> Vector3<f64> {
        self.forward_with_into(&self.tree, &self.error_values, q, conditions, ws);
        self.t_meas_base
            .transform_point(&ws.frames.point[point].translation.vector.into())
            .coords
    }

    /// Allocating convenience: checks `q`, evaluates the full model, returns the frames.
    pub fn forward(&self, q: &[f64]) -> Result<TreeWorkspace> {
        self.tree.check_q(q)?;
        let mut ws = self.workspace();
        self.forward_into(q, None, &mut ws);
        Ok(ws.frames)
    }

    /// The description with the current parameter values written back, in the file's units.
    pub fn to_file(&self) -> RobotFile {
        self.file_with(&self.chain_values, &self.error_values)
    }

    /// The model's text for `path` (JSON for `.json`, else TOML). With a fitted predictor it is
    /// the description the robot was built from, whose values the predictor was fitted to (as
    /// `armcomp learn` writes a model); else the current values written back into it (as
    /// `armcomp calibrate` does).
    pub fn to_text_for(&self, path: &Path) -> Result<String> {
        if self.predictor().is_some() {
            self.file.to_text_for(path)
        } else {
            self.to_file().to_text_for(path)
        }
    }

    /// The description with other chain and error-model values written back (file units).
    pub fn file_with(&self, chain_values: &[f64], error_values: &[Vec<f64>]) -> RobotFile {
        let mut out = RobotFile {
            name: self.file.name.clone(),
            description: self.file.description.clone(),
            units: self.units(),
            gravity: self.file.gravity,
            kinematics: self.chain.spec_with(chain_values),
            links: self.file.links.clone(),
            points: self.file.points.clone(),
            tool: self.file.tool.clone(),
            payload: self.file.payload.clone(),
            error_models: self
                .error_models
                .iter()
                .zip(error_values)
                .map(|(m, v)| m.spec_with(v))
                .collect(),
            predictor: None,
            fitted_predictor: None,
            predictor_frame: None,
            measurement: self.file.measurement.clone(),
            sensors: self.file.sensors.clone(),
            fixtures: self.file.fixtures.clone(),
            collision: self.file.collision.clone(),
            fixed: self.file.fixed.clone(),
        };
        // Predictor specs are not clonable trait objects; round-trip through JSON keeps them.
        if let Some(p) = &self.file.predictor {
            out.predictor = serde_json::to_value(p)
                .ok()
                .and_then(|v| serde_json::from_value(v).ok());
        }
        out
    }
}

/// Names that measurement CSV files use for their own columns.
const RESERVED_COLUMNS: [&str; 10] = ["point", "x", "y", "z", "qw", "qx", "qy", "qz", "payload", "temperature"];

/// Why `name` cannot be written in CSV files (and `--q name=value` lists): as a value, or with
/// `header`, as a column of its own (a joint's).
fn check_column_name(name: &str, header: bool) -> std::result::Result<(), String> {
    if name.is_empty() {
        return Err("is empty".into());
    }
    if name.trim() != name {
        return Err("begins or ends with white space".into());
    }
    if let Some(c) = name.chars().find(|c| c.is_control() || ",\"'[]=#".contains(*c)) {
        return Err(format!(
            "contains `{}`; names appear in CSV headers and `--q name=value` lists, so use letters, digits, `_`, `-` or `.`",
            c.escape_debug()
        ));
    }
    if header && (RESERVED_COLUMNS.contains(&name) || name.starts_with("tau_")) {
        return Err("is the name of a measurement CSV column (point, x, y, z, qw, qx, qy, qz, payload, temperature, tau_<joint>)".into());
    }
    Ok(())
}

/// The file's sensor on a link of `tree`, with its columns checked. One sensor for now: the
/// physics takes one direction of gravity per row, and two sensors on different links disagree
/// by the bending between them, which no rule of averaging would make right.
fn resolve_sensors(file: &RobotFile, base_tree: &KinematicTree, issues: &mut Issues) -> Option<GravitySensor> {
    if file.sensors.len() > 1 {
        issues.push(
            "sensors[1]",
            format!(
                "{} sensors declared; the direction of gravity is read from one sensor per robot",
                file.sensors.len()
            ),
        );
    }
    let spec = file.sensors.first()?;
    let path = "sensors[0]";
    let mut ok = true;
    if let Err(m) = check_column_name(&spec.name, false) {
        issues.push(
            format!("{path}.name"),
            format!("sensor name `{}` {m}", spec.name.escape_debug()),
        );
        ok = false;
    }
    let body = base_tree.body_index(&spec.link);
    if body.is_none() {
        issues.push(
            format!("{path}.link"),
            format!(
                "sensor `{}` is on link `{}`, which does not exist; links are: {}",
                spec.name,
                spec.link,
                body_names(base_tree)
            ),
        );
    }
    let n = spec.kind.n_columns();
    if spec.columns.len() != n {
        issues.push(
            format!("{path}.columns"),
            format!(
                "an {} has {n} columns ({}), got {}",
                spec.kind.name(),
                spec.kind.cells(),
                spec.columns.len()
            ),
        );
        ok = false;
    }
    for (k, c) in spec.columns.iter().enumerate() {
        let clash = if let Err(m) = check_column_name(c, true) {
            Some(m)
        } else if base_tree.coordinate_names().iter().any(|j| j == c) {
            Some("is the name of a joint's column".to_string())
        } else if crate::data::measurement::is_measurement_column(c) {
            Some("is the name of a measurement CSV column (an orientation or a numbered position)".to_string())
        } else if spec.columns[..k].contains(c) {
            Some("appears twice".to_string())
        } else {
            None
        };
        if let Some(m) = clash {
            issues.push(
                format!("{path}.columns[{k}]"),
                format!("column `{}` {m}", c.escape_debug()),
            );
            ok = false;
        }
    }
    Some(GravitySensor {
        name: spec.name.clone(),
        kind: spec.kind,
        body: body.filter(|_| ok)?,
        columns: spec.columns.clone(),
    })
}

/// The file's points on the links of `tree`, and the index of the tool among them.
fn resolve_points(
    file: &RobotFile,
    base_tree: &KinematicTree,
    units: &Units,
    issues: &mut Issues,
) -> (Vec<ResolvedPoint>, Option<usize>) {
    // Points.
    let mut points = Vec::new();
    let mut point_names = std::collections::HashSet::new();
    for (i, p) in file.points.iter().enumerate() {
        let path = format!("points[{i}]");
        if !point_names.insert(p.name.as_str()) {
            issues.push(format!("{path}.name"), format!("point `{}` is defined twice", p.name));
        }
        if let Err(m) = check_column_name(&p.name, false) {
            issues.push(
                format!("{path}.name"),
                format!("point name `{}` {m}", p.name.escape_debug()),
            );
        }
        if p.xyz.iter().chain(p.rpy.iter()).any(|v| !v.is_finite()) {
            issues.push(format!("{path}.xyz"), "expected finite numbers");
            continue;
        }
        match base_tree.body_index(&p.link) {
            Some(body) => {
                let local = xyz_rpy(units.len3(p.xyz), units.ang3(p.rpy));
                points.push(ResolvedPoint {
                    name: p.name.clone(),
                    body,
                    local,
                });
            }
            None => issues.push(
                format!("{path}.link"),
                format!(
                    "point `{}` is on link `{}`, which does not exist; links are: {}",
                    p.name,
                    p.link,
                    body_names(base_tree)
                ),
            ),
        }
    }
    let tool = points.iter().position(|p| p.name == file.tool);
    if tool.is_none() && !file.points.iter().any(|p| p.name == file.tool) {
        issues.push(
            "tool",
            format!(
                "the tool point `{}` is not among the points ([[points]] with name = \"{}\")",
                file.tool, file.tool
            ),
        );
    }
    (points, tool)
}

/// Masses, centres of mass, beams and collision shapes of the links: the convention's own
/// (URDF inertials and collision elements) first, then the file's links override them.
fn mass_and_shapes(
    file: &RobotFile,
    chain: &dyn Chain,
    base_tree: &KinematicTree,
    units: &Units,
    issues: &mut Issues,
) -> (MassModel, Vec<BodyShape>) {
    let mut mass = MassModel::massless(base_tree.bodies().len());
    let mut shapes = Vec::new();
    for l in chain.links() {
        let Some(body) = base_tree.body_index(&l.name) else {
            continue;
        };
        if let Some((m, com)) = l.mass {
            mass.bodies[body].mass = m;
            mass.bodies[body].com = com;
        }
        shapes.extend(l.shapes.iter().map(|(local, shape)| BodyShape {
            body,
            local: *local,
            shape: *shape,
        }));
    }
    for (i, l) in file.links.iter().enumerate() {
        let path = format!("links[{i}]");
        if let Some(k) = file.links[..i].iter().position(|o| o.name == l.name) {
            issues.push(
                format!("{path}.name"),
                format!(
                    "link `{}` is described twice (also links[{k}]); merge the two entries",
                    l.name
                ),
            );
            continue;
        }
        let Some(body) = base_tree.body_index(&l.name) else {
            issues.push(
                format!("{path}.name"),
                format!("link `{}` does not exist; links are: {}", l.name, body_names(base_tree)),
            );
            continue;
        };
        let frame = base_tree.bodies()[body].convention_frame;
        if let Some(m) = l.mass
            && !(m.is_finite() && m > 0.0)
        {
            issues.push(
                format!("{path}.mass"),
                format!("expected a positive mass in kg, got {m}"),
            );
        }
        if let Some(c) = l.com
            && c.iter().any(|v| !v.is_finite())
        {
            issues.push(format!("{path}.com"), "expected three finite numbers");
        }
        if !l.shapes.is_empty() {
            shapes.retain(|s| s.body != body);
            for (k, s) in l.shapes.iter().enumerate() {
                let spath = format!("{path}.shapes[{k}]");
                if let Some(shape) = placed_shape(&s.geometry, s.xyz, s.rpy, units, &spath, issues) {
                    if shape.1 == Shape::Plane {
                        issues.push(
                            format!("{spath}.geometry"),
                            "a plane is unbounded: declare it as a fixture",
                        );
                        continue;
                    }
                    shapes.push(BodyShape {
                        body,
                        local: frame * shape.0,
                        shape: shape.1,
                    });
                }
            }
        }
        let from_density = match (l.density, l.mass) {
            (Some(_), Some(_)) => {
                issues.push(
                    format!("{path}.density"),
                    "give either `mass` or `density` (with shapes), not both",
                );
                None
            }
            (Some(rho), None) if !(rho.is_finite() && rho > 0.0) => {
                issues.push(
                    format!("{path}.density"),
                    format!("expected a positive density in kg/m³, got {rho}"),
                );
                None
            }
            (Some(rho), None) => {
                let solids = shapes
                    .iter()
                    .filter(|s| s.body == body)
                    .filter_map(|s| Some(s.shape.mass_properties(rho)?.transformed(&s.local)))
                    .reduce(|a, b| a.combined(&b));
                if solids.is_none() {
                    issues.push(
                        format!("{path}.density"),
                        "a density needs the link's `shapes` (or URDF collision elements) to give a volume",
                    );
                }
                solids
            }
            (None, _) => None,
        };
        let body_mass = &mut mass.bodies[body];
        if let Some(m) = l.mass {
            body_mass.mass = m;
        }
        if let Some(solid) = from_density {
            body_mass.mass = solid.mass;
            body_mass.com = solid.com;
        }
        if let Some(c) = l.com {
            body_mass.com = frame.transform_point(&units.len3(c).into()).coords;
        }
        body_mass.beam = l
            .beam
            .as_ref()
            .and_then(|b| beam_rigidity(b, units.length.to_si(), &format!("{path}.beam"), issues));
    }
    (mass, shapes)
}

/// The file's payload into `mass`; the point a payload hangs at (without one, a payload given
/// per measurement hangs at the tool).
fn resolve_payload(
    file: &RobotFile,
    points: &[ResolvedPoint],
    tool: Option<usize>,
    base_tree: &KinematicTree,
    mass: &mut MassModel,
    issues: &mut Issues,
) -> Option<usize> {
    let mut payload_point = tool;
    if let Some(p) = &file.payload {
        if !(p.mass.is_finite() && p.mass >= 0.0) {
            issues.push(
                "payload.mass",
                format!("expected a mass of zero or more kg, got {}", p.mass),
            );
        }
        let name = p.point.as_deref().unwrap_or(&file.tool);
        match points.iter().find(|q| q.name == name) {
            Some(q) => {
                let local = base_tree.bodies()[q.body].convention_frame * q.local;
                mass.payload = Some(Payload {
                    mass: p.mass,
                    body: q.body,
                    com: local.translation.vector,
                });
                payload_point = points.iter().position(|r| r.name == name);
            }
            None => issues.push("payload.point", format!("point `{name}` does not exist")),
        }
    }
    payload_point
}

/// The stations of the file's `[[measurement.stations]]`, checked.
fn station_frames(file: &RobotFile, units: &Units, issues: &mut Issues) -> Vec<Station> {
    let specs = file.measurement.iter().flat_map(|m| &m.stations);
    let mut stations: Vec<Station> = Vec::new();
    for (i, s) in specs.enumerate() {
        let at = format!("measurement.stations[{i}]");
        if s.name.trim().is_empty() {
            issues.push(
                format!("{at}.name"),
                "is empty; name the station as the data's `station` column does",
            );
        } else if stations.iter().any(|o| o.name == s.name) {
            issues.push(format!("{at}.name"), format!("station `{}` is listed twice", s.name));
        }
        if s.base_xyz.iter().chain(&s.base_rpy).any(|v| !v.is_finite()) {
            issues.push(at, "base_xyz and base_rpy need three finite numbers each".to_string());
            continue;
        }
        stations.push(Station {
            name: s.name.clone(),
            frame: xyz_rpy(units.len3(s.base_xyz), units.ang3(s.base_rpy)),
        });
    }
    stations
}

/// Checks what `kind = "plane"` adds to [measurement]: nominal planes with finite poses and
/// distinct names, a non-empty list of constrained components without repeats, and a frame
/// link that is a link of the robot other than its root.
fn check_planes(m: &crate::robot::robot_file::MeasurementSpec, tree: &KinematicTree, issues: &mut Issues) {
    use crate::robot::robot_file::MeasurementKind;
    let planar = m.kind == MeasurementKind::Plane;
    for (i, p) in m.planes.iter().enumerate() {
        let field = format!("measurement.planes[{i}]");
        if !planar {
            issues.push(
                field.clone(),
                "a plane is what plane contacts touch; expected `kind = \"plane\"` in [measurement]",
            );
        }
        if p.name.trim().is_empty() {
            issues.push(
                format!("{field}.name"),
                "is empty; name the plane as the data's `plane` column does",
            );
        } else if m.planes[..i].iter().any(|o| o.name == p.name) {
            issues.push(format!("{field}.name"), format!("plane `{}` is listed twice", p.name));
        }
        if p.xyz.iter().chain(&p.rpy).any(|v| !v.is_finite()) {
            issues.push(field, "xyz and rpy need three finite numbers each");
        }
    }
    if !m.constrain.is_empty() && !planar {
        issues.push(
            "measurement.constrain",
            "constrains plane contacts; expected `kind = \"plane\"` in [measurement]",
        );
    }
    for (i, c) in m.constrain.iter().enumerate() {
        if m.constrain[..i].contains(c) {
            issues.push(
                format!("measurement.constrain[{i}]"),
                format!("`{}` is listed twice", format!("{c:?}").to_lowercase()),
            );
        }
    }
    if let Some(link) = &m.frame_link {
        match tree.body_index(link) {
            None => issues.push("measurement.frame_link", format!("`{link}` is not a link of the robot")),
            Some(b) if tree.support(b).is_empty() => issues.push(
                "measurement.frame_link",
                format!(
                    "`{link}` is the robot's root, whose frame the measurements are in already; leave frame_link out"
                ),
            ),
            Some(_) => {}
        }
    }
}

/// What a plane contact constrains (see [`Robot::plane_constraints`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PlaneConstraints {
    /// The marker's distance from the plane.
    pub height: bool,
    /// The marker frame's roll from the plane's.
    pub roll: bool,
    /// The marker frame's pitch from the plane's.
    pub pitch: bool,
}

impl PlaneConstraints {
    /// How many tilts are constrained (0, 1 or 2).
    pub fn tilts(&self) -> usize {
        usize::from(self.roll) + usize::from(self.pitch)
    }
}

/// The measurement frame's starting pose, the markers (the tool when none is named) and the
/// values joints outside the measured chain hold (SI).
fn measurement_setup(
    file: &RobotFile,
    base_tree: &KinematicTree,
    points: &[ResolvedPoint],
    tool: Option<usize>,
    units: &Units,
    issues: &mut Issues,
) -> (Isometry3<f64>, Vec<usize>, Vec<Option<f64>>) {
    let (t_meas_base, marker_names) = match &file.measurement {
        Some(m) => (
            xyz_rpy(units.len3(m.base_xyz), units.ang3(m.base_rpy)),
            m.markers.clone(),
        ),
        None => (Isometry3::identity(), Vec::new()),
    };
    for (field, v) in file
        .measurement
        .iter()
        .flat_map(|m| [("base_xyz", m.base_xyz), ("base_rpy", m.base_rpy)])
    {
        if v.iter().any(|x| !x.is_finite()) {
            issues.push(
                format!("measurement.{field}"),
                format!("expected three finite numbers, got {v:?}"),
            );
        }
    }
    if let Some(m) = &file.measurement {
        for (i, d) in m.distances.iter().enumerate() {
            let field = format!("measurement.distances[{i}]");
            if m.kind == crate::robot::robot_file::MeasurementKind::Plane {
                issues.push(
                    field.clone(),
                    "a known distance is between fixed points, which plane contacts do not measure; expected `kind` \
                     `fixed_point`, `point` or `pose` in [measurement]",
                );
            }
            if d.between[0] == d.between[1] {
                issues.push(
                    format!("{field}.between"),
                    format!("names `{}` twice; expected two different fixed points", d.between[0]),
                );
            }
            if !(d.mm.is_finite() && d.mm > 0.0) {
                issues.push(
                    format!("{field}.mm"),
                    format!("expected a positive distance in mm, got {}", d.mm),
                );
            }
            if let Some(n) = d.noise_mm
                && !(n.is_finite() && n > 0.0)
            {
                issues.push(
                    format!("{field}.noise_mm"),
                    format!("expected a positive standard deviation in mm, got {n}"),
                );
            }
        }
    }
    if let Some(m) = &file.measurement {
        check_planes(m, base_tree, issues);
    }
    let names = base_tree.coordinate_names();
    let mut hold = vec![None; names.len()];
    for (name, v) in file.measurement.iter().flat_map(|m| &m.hold) {
        let field = format!("measurement.hold.{name}");
        match names.iter().position(|n| n == name) {
            Some(c) if v.is_finite() => {
                let si = if base_tree.coordinate_is_prismatic()[c] {
                    units.len(*v)
                } else {
                    units.ang(*v)
                };
                let out = |v| {
                    if base_tree.coordinate_is_prismatic()[c] {
                        units.len_out(v)
                    } else {
                        units.ang_out(v)
                    }
                };
                match base_tree.coordinate_limits()[c] {
                    // A held joint outside its range is a pose the arm cannot take.
                    Some(l) if !(l.lower - 1e-12..=l.upper + 1e-12).contains(&si) => issues.push(
                        field,
                        format!(
                            "{v} is outside the joint's limits; expected a value from {:.4} to {:.4} (the file's units)",
                            out(l.lower),
                            out(l.upper)
                        ),
                    ),
                    _ => hold[c] = Some(si),
                }
            }
            Some(_) => issues.push(field, "expected a finite number"),
            None => issues.push(
                field,
                format!(
                    "`{name}` is not an independent joint (expected one of: {})",
                    names.join(", ")
                ),
            ),
        }
    }
    let point_index: std::collections::HashMap<&str, usize> = points
        .iter()
        .enumerate()
        .rev()
        .map(|(k, p)| (p.name.as_str(), k))
        .collect();
    let mut markers = Vec::new();
    for (i, name) in marker_names.iter().enumerate() {
        match point_index.get(name.as_str()).copied() {
            // Listed twice, a point would be measured, written and fitted twice a pose.
            Some(k) if markers.contains(&k) => issues.push(
                format!("measurement.markers[{i}]"),
                format!("point `{name}` is listed twice; expected each marker once"),
            ),
            Some(k) => markers.push(k),
            None => issues.push(
                format!("measurement.markers[{i}]"),
                format!("point `{name}` does not exist"),
            ),
        }
    }
    if markers.is_empty()
        && let Some(t) = tool
    {
        markers.push(t);
    }
    (t_meas_base, markers, hold)
}

/// Legal values no robot is likely to have (a typo, a unit slip), each with the bound it
/// passes: gravity beyond [`PLAUSIBLE_GRAVITY`], error-model parameters outside the range their
/// model calls plausible. Absurd values are errors before this is reached.
fn implausible_values(robot: &Robot) -> Issues {
    let mut found = Issues::default();
    let g = robot.gravity.norm();
    if g > PLAUSIBLE_GRAVITY {
        found.push(
            "gravity",
            format!(
                "a magnitude of {g:.3} m/s² is implausible; expected at most {PLAUSIBLE_GRAVITY} m/s² (Earth's is 9.81)"
            ),
        );
    }
    for (i, m) in robot.error_models.iter().enumerate() {
        for p in m.params().iter().filter(|p| !p.is_plausible(p.nominal)) {
            found.push(
                format!("error_models[{i}]"),
                format!(
                    "`{}` = {} is implausible; its model expects {} to {}",
                    p.name,
                    p.quantity.readable(p.nominal),
                    p.quantity.readable(p.plausible.0),
                    p.quantity.readable(p.plausible.1)
                ),
            );
        }
    }
    found
}

/// The file's error models built against the finished tree and mass model of `robot`, with
/// every parameter name owned once and every `fixed` entry matching a parameter.
fn build_error_models(robot: &Robot, base_dir: &Path, issues: &mut Issues) -> Vec<Box<dyn ErrorModel>> {
    let units = robot.units();
    let mut models = Vec::new();
    for (i, spec) in robot.file.error_models.iter().enumerate() {
        let path = format!("error_models[{i}]");
        let mctx = ModelContext {
            build: BuildContext {
                units,
                base_dir,
                path: &path,
            },
            tree: &robot.tree,
            mass: &robot.mass,
        };
        match spec.build(&mctx) {
            Ok(m) => {
                for p in m.params() {
                    if let Some(why) = p.absurdity(p.nominal) {
                        issues.push(path.clone(), why);
                    }
                }
                models.push(m);
            }
            Err(e) => issues.0.extend(e.0),
        }
    }
    // A model listed twice would give two parameters of one name, which calibration and
    // model files cannot tell apart.
    let mut owners = std::collections::HashMap::new();
    for (i, m) in models.iter().enumerate() {
        for p in m.params() {
            if let Some(k) = owners.insert(p.name.as_str(), i).filter(|k| *k != i) {
                issues.push(
                    format!("error_models[{i}]"),
                    format!(
                        "its parameter `{}` is also a parameter of error_models[{k}]; is the model listed twice?",
                        p.name
                    ),
                );
                break;
            }
        }
    }
    // Every entry of `fixed` must name a parameter calibration knows.
    let names: Vec<String> = robot
        .chain_params()
        .iter()
        .chain(models.iter().flat_map(|m| m.params()))
        .map(|p| p.name.clone())
        .chain(robot.setup_param_names())
        .collect();
    for (i, pattern) in robot.file.fixed.iter().enumerate() {
        if !names.iter().any(|n| crate::model::param::name_matches(pattern, n)) {
            issues.push(
                format!("fixed[{i}]"),
                format!(
                    "`{pattern}` matches no parameter of this robot; names are like {}",
                    names.iter().take(4).cloned().collect::<Vec<_>>().join(", ")
                ),
            );
        }
    }
    models
}

/// Joint names must be usable as CSV columns; issues point at the joint's entry when the
/// kinematics lists joints by name, else at the kinematics.
fn check_joint_names(file: &RobotFile, tree: &KinematicTree, issues: &mut Issues) {
    let listed = serde_json::to_value(&file.kinematics).ok();
    let entries = listed.as_ref().and_then(|v| v.get("joints")).and_then(|j| j.as_array());
    for joint in tree.joints() {
        if let Err(m) = check_column_name(&joint.name, true) {
            let path = entries
                .and_then(|e| {
                    e.iter()
                        .position(|j| j.get("name").and_then(|n| n.as_str()) == Some(&joint.name))
                })
                .map_or_else(|| "kinematics".to_string(), |i| format!("kinematics.joints[{i}].name"));
            issues.push(path, format!("joint name `{}` {m}", joint.name.escape_debug()));
        }
    }
}

fn body_names(tree: &KinematicTree) -> String {
    tree.bodies()
        .iter()
        .map(|b| format!("`{}`", b.name))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A shape and its frame in metres, or issues naming what is not finite or not positive.
fn placed_shape(
    geometry: &Geometry,
    xyz: [f64; 3],
    rpy: [f64; 3],
    units: &Units,
    path: &str,
    issues: &mut Issues,
) -> Option<(Isometry3<f64>, Shape)> {
    if xyz.iter().chain(&rpy).any(|v| !v.is_finite()) {
        issues.push(format!("{path}.xyz"), "expected finite numbers for `xyz` and `rpy`");
        return None;
    }
    match geometry.to_shape(units) {
        Ok(shape) => Some((xyz_rpy(units.len3(xyz), units.ang3(rpy)), shape)),
        Err(message) => {
            issues.push(format!("{path}.geometry"), message);
            None
        }
    }
}

/// Fixtures, margin and ignored pairs resolved against the tree.
fn collision_geometry(
    file: &RobotFile,
    tree: &KinematicTree,
    shapes: Vec<BodyShape>,
    issues: &mut Issues,
) -> CollisionGeometry {
    let units = file.units;
    let mut fixtures: Vec<Fixture> = Vec::new();
    for (i, f) in file.fixtures.iter().enumerate() {
        let path = format!("fixtures[{i}]");
        if fixtures.iter().any(|g| g.name == f.name) {
            issues.push(format!("{path}.name"), format!("fixture `{}` is defined twice", f.name));
        }
        if let Some((pose, shape)) = placed_shape(&f.geometry, f.xyz, f.rpy, &units, &path, issues) {
            fixtures.push(Fixture {
                name: f.name.clone(),
                pose,
                shape,
            });
        }
    }
    let spec = file.collision.clone().unwrap_or_default();
    if !(spec.margin.is_finite() && spec.margin >= 0.0) {
        issues.push(
            "collision.margin",
            format!("expected a distance of zero or more (length unit), got {}", spec.margin),
        );
    }
    let mut ignore = Vec::new();
    for (i, pair) in spec.ignore.iter().enumerate() {
        let found: Vec<Option<usize>> = pair.iter().map(|n| tree.body_index(n)).collect();
        for (k, name) in pair.iter().enumerate() {
            if found[k].is_none() {
                issues.push(
                    format!("collision.ignore[{i}][{k}]"),
                    format!("link `{name}` does not exist; links are: {}", body_names(tree)),
                );
            }
        }
        if let [Some(a), Some(b)] = found[..] {
            ignore.push((a, b));
        }
    }
    CollisionGeometry {
        shapes,
        fixtures,
        margin: units.len(spec.margin),
        ignore,
    }
}

/// Rigidities of a beam description, or issues naming what is missing or not positive.
fn beam_rigidity(b: &BeamSpec, to_m: f64, path: &str, issues: &mut Issues) -> Option<BeamRigidity> {
    let mut positive = |field: &str, v: f64, unit: &str| {
        let ok = v.is_finite() && v > 0.0;
        if !ok {
            issues.push(
                format!("{path}.{field}"),
                format!("expected a positive {unit}, got {v}"),
            );
        }
        ok
    };
    match (&b.section, b.ei_y, b.ei_z, b.gj) {
        (None, Some(ei_y), Some(ei_z), Some(gj)) => {
            let ok = positive("ei_y", ei_y, "rigidity in N m²")
                & positive("ei_z", ei_z, "rigidity in N m²")
                & positive("gj", gj, "rigidity in N m²");
            ok.then_some(BeamRigidity { ei_y, ei_z, gj })
        }
        (Some(section), None, None, None) => {
            let mut ok = true;
            for (field, v) in section.dimensions() {
                ok &= positive(&format!("section.{field}"), v, "length");
            }
            let e = b.youngs_modulus;
            let Some(e) = e else {
                issues.push(
                    format!("{path}.youngs_modulus"),
                    "a section needs a Young's modulus in Pa",
                );
                return None;
            };
            ok &= positive("youngs_modulus", e, "modulus in Pa");
            let g = b.shear_modulus.unwrap_or(e / 2.6);
            ok &= positive("shear_modulus", g, "modulus in Pa");
            if !ok {
                return None;
            }
            if let Some((field, message)) = section.impossible() {
                issues.push(format!("{path}.section.{field}"), message);
                return None;
            }
            let s = section.properties(to_m);
            if !(s.area > 0.0 && s.iy > 0.0 && s.iz > 0.0 && s.j > 0.0) {
                issues.push(
                    format!("{path}.section"),
                    "the walls or flanges are thicker than the section allows",
                );
                return None;
            }
            Some(BeamRigidity {
                ei_y: e * s.iy,
                ei_z: e * s.iz,
                gj: g * s.j,
            })
        }
        _ => {
            issues.push(path.to_string(), "expected either `section` with `youngs_modulus` (and optional `shear_modulus`), or all of `ei_y`, `ei_z`, `gj`");
            None
        }
    }
}
