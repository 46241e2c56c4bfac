//! A robot built from its file: the compiled chain, named points, mass model and error models.
//!
//! The type and its accessors are here; building it from a file is in `build.rs`, evaluating
//! the full model in `forward.rs`, writing values back into a description in `write_back.rs`.
//! The file format itself is [`robot_file`]; many configurations at once, [`batch`].

pub mod batch;
pub mod candidate;
pub mod registry;
pub mod robot_file;

mod build;
mod forward;
mod write_back;

use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Vector3};

use crate::data::measurement::{CsvLayout, Sample};
use crate::error::{Error, Result};
use crate::kinematics::collision::CollisionGeometry;
use crate::kinematics::point_kinematics::PointKinematics;
use crate::kinematics::sensor::{GravitySensor, SensorReadings};
use crate::kinematics::subtree_loads::SubtreeLoads;
use crate::kinematics::workspace::TreeWorkspace;
use crate::model::geom::xyz_rpy;
use crate::model::mass::MassModel;
use crate::model::param::ParamInfo;
use crate::model::perturbation::Perturbation;
use crate::model::tree::KinematicTree;
use crate::model::units::Units;
use crate::plugin::{Chain, ErrorModel};
use crate::robot::robot_file::RobotFile;
use crate::support::io::InputLimits;
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
    /// The sensors read per measurement row, in the file's order.
    sensors: Vec<GravitySensor>,
    /// The one among them whose reading gives the elastic models the direction of gravity.
    gravity_sensor: Option<usize>,
    /// Per coordinate, the value the robot file says it held while measuring (rad or m).
    hold: Vec<Option<f64>>,
    /// The point a payload hangs at (the file's payload point, else the tool); a payload given
    /// per measurement without one hangs at the base origin.
    payload_point: Option<usize>,
    collision: CollisionGeometry,
    warnings: Vec<String>,
    /// Files read to build it besides `source` (URDF, meshes, plugin libraries).
    reads: Vec<PathBuf>,
    /// How large the files it was built from could be; a rebuild reads within them again.
    limits: InputLimits,
}

/// Conditions of one evaluation that error models may depend on besides the joint values.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Conditions {
    /// Ambient temperature (°C).
    pub temperature: Option<f64>,
    /// Payload mass (kg) replacing the robot file's payload.
    pub payload: Option<f64>,
    /// The sensors' readings (one slot per sensor of the robot): the gravity sensor's
    /// direction replaces the robot file's (its magnitude is kept), and error models such as
    /// `measured_tilt` read theirs.
    pub sensors: SensorReadings,
}

impl Conditions {
    /// The conditions a measured sample records.
    pub fn of(sample: &crate::data::measurement::Sample) -> Self {
        Conditions {
            temperature: sample.temperature,
            payload: sample.payload,
            sensors: sample.sensors,
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
    /// The last evaluation's sensor readings, turned into their links' frames by the
    /// mountings the error models identify.
    sensors: SensorReadings,
}

/// Names of the base frame's six parameters (`base.<name>`), in the order of
/// [`xyz_rpy`](crate::model::geom::xyz_rpy): position, then roll, pitch, yaw.
pub(crate) const BASE_NAMES: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];

impl Robot {
    /// The tree for chain parameter `values`, with the robot's points attached.
    pub fn tree_for(&self, values: &[f64]) -> Result<KinematicTree> {
        let mut tree = self.chain.tree(values)?;
        for p in &self.points {
            let local = tree.bodies()[p.body].convention_frame * p.local;
            tree.add_point(p.name.clone(), p.body, local)?;
        }
        Ok(tree)
    }

    /// How large the files it was built from could be (those a rebuild reads again).
    pub fn input_limits(&self) -> InputLimits {
        self.limits
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
        let mut robot = Robot::build(file, &self.base_dir(), self.limits).map_err(Error::InvalidModel)?;
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
            sensors: self.sensors.clone(),
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

#[cfg(test)]
mod tests;
