//! Building a robot from its file: the chain, points, masses, shapes, sensors, stations,
//! the measurement set-up and the error models, every problem gathered with its field.

use std::path::Path;

use nalgebra::{Isometry3, Vector3};

use crate::error::{Issue, Issues, Result};
use crate::kinematics::collision::{BodyShape, CollisionGeometry, Fixture};
use crate::kinematics::point_kinematics::PointKinematics;
use crate::kinematics::sensor::{GravitySensor, MAX_SENSORS, SensorKind, gravity_sensor_index};
use crate::model::geom::xyz_rpy;
use crate::model::mass::{BeamRigidity, MassModel, Payload};
use crate::model::shape::{Geometry, Shape};
use crate::model::tree::KinematicTree;
use crate::model::units::Units;
use crate::plugin::{BuildContext, Chain, ErrorModel, ErrorModelSpec, ModelContext};
use crate::robot::robot_file::{BeamSpec, RobotFile, SourceFile};
use crate::robot::{ResolvedPoint, Robot, Station};
use crate::support::io::InputLimits;

/// Gravity (m/s²) no robot works in: a hundred times Earth's.
const ABSURD_GRAVITY: f64 = 1e3;

/// Gravity (m/s²) beyond which a robot file is warned about: twice Earth's, more than any
/// planet a robot is calibrated on, and what a unit slip (cm/s²) or a typo gives.
const PLAUSIBLE_GRAVITY: f64 = 20.0;

impl Robot {
    /// Reads, checks and builds a robot file within the default [`InputLimits`]; every problem
    /// names the file, line and field.
    pub fn from_path(path: &Path) -> Result<Robot> {
        Robot::from_path_with(path, InputLimits::default())
    }

    /// [`from_path`](Robot::from_path) with every file it reads (the robot file, URDF, meshes)
    /// within `limits`.
    pub fn from_path_with(path: &Path, limits: InputLimits) -> Result<Robot> {
        // Parsing may load libraries too (a fitted run-time predictor).
        let (read, files) = crate::support::io::recording_reads(|| RobotFile::read(path, limits));
        let (file, src) = read?;
        let mut robot = Robot::from_source(file, &src, limits)?;
        robot.reads.extend(files);
        Ok(robot)
    }

    /// Checks and builds a parsed robot file, mapping problems to lines of `src`; the files it
    /// names are read within `limits`.
    pub fn from_source(file: RobotFile, src: &SourceFile, limits: InputLimits) -> Result<Robot> {
        let dir = src.path.parent().map(Path::to_path_buf).unwrap_or_default();
        let mut robot = Robot::build_from(file, &dir, limits, Some(src)).map_err(|issues| src.invalid(issues))?;
        robot.source = Some(src.path.clone());
        Ok(robot)
    }

    /// Checks and builds a robot description; `base_dir` resolves relative paths in it, and the
    /// files it names are read within `limits`. The files read meanwhile on this thread are the
    /// robot's [`inputs`](Robot::inputs).
    pub fn build(file: RobotFile, base_dir: &Path, limits: InputLimits) -> Result<Robot, Vec<Issue>> {
        Robot::build_from(file, base_dir, limits, None)
    }

    /// [`build`](Robot::build); warnings name their line in `src`, when given.
    fn build_from(
        file: RobotFile,
        base_dir: &Path,
        limits: InputLimits,
        src: Option<&SourceFile>,
    ) -> Result<Robot, Vec<Issue>> {
        let (built, files) =
            crate::support::io::recording_reads(|| Robot::build_unrecorded(file, base_dir, limits, src));
        let mut robot = built?;
        robot.reads = files;
        Ok(robot)
    }

    fn build_unrecorded(
        mut file: RobotFile,
        base_dir: &Path,
        limits: InputLimits,
        src: Option<&SourceFile>,
    ) -> Result<Robot, Vec<Issue>> {
        let mut issues = Issues::default();
        let units = file.units;
        let ctx = BuildContext {
            units,
            base_dir,
            path: "kinematics",
            limits,
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
        let sensors = resolve_sensors(&file, &base_tree, &mut issues);
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
            limits,
        };
        match file.predictor.as_deref().map(|p| p.resolve(&pctx)) {
            Some(Ok(Some(resolved))) => file.predictor = Some(resolved),
            Some(Err(e)) => issues.0.extend(e.0),
            Some(Ok(None)) | None => {}
        }

        if let Some(p) = file.fitted_predictor.as_deref() {
            let nq = base_tree.nq();
            if !(p.n_inputs() == nq || p.n_inputs() == nq + 3) || p.n_outputs() != 3 {
                issues.push(
                    "fitted_predictor",
                    format!(
                        "takes {} inputs and gives {} outputs; a predictor of this robot takes its {nq} joint values \
                         (and the point's position, 3 more) and gives a position residual (3): the model file was \
                         written for another robot",
                        p.n_inputs(),
                        p.n_outputs()
                    ),
                );
            }
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
            gravity_sensor: gravity_sensor_index(&sensors),
            sensors,
            hold,
            payload_point,
            collision,
            warnings,
            reads: Vec::new(),
            limits,
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

        let models = build_error_models(&robot, base_dir, limits, &mut issues);
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

/// The file's sensors on links of `tree`, with their columns and noise checked: at most
/// [`MAX_SENSORS`], one per link, no column claimed twice.
fn resolve_sensors(file: &RobotFile, base_tree: &KinematicTree, issues: &mut Issues) -> Vec<GravitySensor> {
    if file.sensors.len() > MAX_SENSORS {
        issues.push(
            format!("sensors[{MAX_SENSORS}]"),
            format!(
                "{} sensors declared; a robot reads at most {MAX_SENSORS} (their readings travel with every evaluation)",
                file.sensors.len()
            ),
        );
    }
    let mut sensors = Vec::new();
    for (i, spec) in file.sensors.iter().enumerate().take(MAX_SENSORS) {
        let path = format!("sensors[{i}]");
        let mut ok = true;
        if let Err(m) = check_column_name(&spec.name, false) {
            issues.push(
                format!("{path}.name"),
                format!("sensor name `{}` {m}", spec.name.escape_debug()),
            );
            ok = false;
        } else if let Some(k) = file.sensors[..i].iter().position(|o| o.name == spec.name) {
            issues.push(
                format!("{path}.name"),
                format!("sensor `{}` is declared twice (also sensors[{k}])", spec.name),
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
        } else if let Some(k) = file.sensors[..i].iter().position(|o| o.link == spec.link) {
            // Two sensors on one link read one orientation: the second adds nothing a model
            // could use, and would make two turns of the same link.
            issues.push(
                format!("{path}.link"),
                format!(
                    "sensor `{}` is on link `{}`, which sensor `{}` (sensors[{k}]) is on already; one sensor per link",
                    spec.name, spec.link, file.sensors[k].name
                ),
            );
            ok = false;
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
                (file.sensors[..i].iter())
                    .find(|o| o.columns.contains(c))
                    .map(|o| format!("is a column of sensor `{}` too", o.name))
            };
            if let Some(m) = clash {
                issues.push(
                    format!("{path}.columns[{k}]"),
                    format!("column `{}` {m}", c.escape_debug()),
                );
                ok = false;
            }
        }
        let noise = match (
            spec.noise,
            spec.kind.column_scale(spec.noise_unit.as_deref(), file.units.angle),
        ) {
            (None, _) => 0.0,
            (Some(_), Err(m)) => {
                issues.push(
                    format!("{path}.noise_unit"),
                    format!("the noise is in a unit of its columns: {m}"),
                );
                ok = false;
                0.0
            }
            (Some(v), Ok(scale)) if v.is_finite() && v >= 0.0 && v * scale < spec.kind.absurd_noise() => v * scale,
            (Some(v), Ok(_)) => {
                issues.push(
                    format!("{path}.noise"),
                    format!(
                        "a standard deviation of {v} {} is no {}'s: expected zero or more, below {}",
                        spec.noise_unit.as_deref().unwrap_or(match spec.kind {
                            SensorKind::Accelerometer => "m/s2",
                            SensorKind::Inclinometer => file.units.angle.symbol(),
                        }),
                        spec.kind.name(),
                        match spec.kind {
                            SensorKind::Accelerometer => "1 g",
                            SensorKind::Inclinometer => "10 deg",
                        }
                    ),
                );
                ok = false;
                0.0
            }
        };
        if let Some(body) = body.filter(|_| ok) {
            sensors.push(GravitySensor {
                name: spec.name.clone(),
                kind: spec.kind,
                body,
                columns: spec.columns.clone(),
                noise,
            });
        }
    }
    sensors
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

/// Checks what plane contacts add to [measurement] (of `kind = "plane"`, or `point` and `pose`
/// whose data mix them in): nominal planes with finite poses and distinct names, a non-empty
/// list of constrained components without repeats, and a frame link that is a link of the
/// robot other than its root.
fn check_planes(m: &crate::robot::robot_file::MeasurementSpec, tree: &KinematicTree, issues: &mut Issues) {
    use crate::robot::robot_file::MeasurementKind;
    let planar = m.kind != MeasurementKind::FixedPoint;
    for (i, p) in m.planes.iter().enumerate() {
        let field = format!("measurement.planes[{i}]");
        if !planar {
            issues.push(
                field.clone(),
                "a plane is what plane contacts touch, which a robot of fixed points does not measure; expected \
                 `kind` `plane`, `point` or `pose` in [measurement]",
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
            "constrains plane contacts, which a robot of fixed points does not measure; expected `kind` `plane`, \
             `point` or `pose` in [measurement]",
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

impl Robot {
    /// The names of the parameters `spec` would have as an error model of this robot (built
    /// against its tree and mass model, not added to it): what tells a candidate effect that
    /// duplicates a parameter the robot already has.
    pub fn error_model_param_names(&self, spec: &dyn ErrorModelSpec) -> std::result::Result<Vec<String>, Issues> {
        let base_dir = self.base_dir();
        let ctx = ModelContext {
            build: BuildContext {
                units: self.units(),
                base_dir: &base_dir,
                path: "error_models",
                limits: self.limits,
            },
            tree: &self.tree,
            mass: &self.mass,
            sensors: &self.sensors,
            gravity_sensor: self.gravity_sensor,
            gravity: self.gravity,
        };
        Ok(spec.build(&ctx)?.params().iter().map(|p| p.name.clone()).collect())
    }
}

/// The file's error models built against the finished tree and mass model of `robot`, with
/// every parameter name owned once and every `fixed` entry matching a parameter.
fn build_error_models(
    robot: &Robot,
    base_dir: &Path,
    limits: InputLimits,
    issues: &mut Issues,
) -> Vec<Box<dyn ErrorModel>> {
    let units = robot.units();
    let mut models = Vec::new();
    for (i, spec) in robot.file.error_models.iter().enumerate() {
        let path = format!("error_models[{i}]");
        let mctx = ModelContext {
            build: BuildContext {
                units,
                base_dir,
                path: &path,
                limits,
            },
            tree: &robot.tree,
            mass: &robot.mass,
            sensors: &robot.sensors,
            gravity_sensor: robot.gravity_sensor,
            gravity: robot.gravity,
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
