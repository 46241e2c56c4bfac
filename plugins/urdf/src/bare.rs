//! A bare URDF as a robot: what `--robot arm.urdf` stands for.

use std::path::Path;

use armcomp_core::robot::robot_file::PointSpec;
use armcomp_core::support::io::InputLimits;
use armcomp_core::{Robot, RobotFile, Units};

use crate::chain::UrdfSpec;
use crate::document::UrdfDocument;

/// The robot file a bare URDF stands for: SI units, the URDF's kinematics and inertials, one
/// point at the origin of every link (named as the link), and the tool at the last link the
/// file lists that carries no joint (an end link). The URDF is read within `limits`.
pub fn robot_file_for_urdf(path: &Path, limits: InputLimits) -> armcomp_core::Result<RobotFile> {
    let doc = UrdfDocument::load(path, limits).map_err(|issues| armcomp_core::Error::InvalidFile {
        file: path.to_path_buf(),
        issues,
    })?;
    let points = doc
        .links
        .iter()
        .map(|l| PointSpec {
            name: l.name.clone(),
            link: l.name.clone(),
            xyz: [0.0; 3],
            rpy: [0.0; 3],
        })
        .collect();
    let tool = doc
        .links
        .iter()
        .rev()
        .find(|l| !doc.joints.iter().any(|j| j.parent == l.name))
        .map_or_else(|| doc.root.clone(), |l| l.name.clone());
    let absolute = std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf());
    Ok(RobotFile {
        name: doc.name.clone(),
        description: Some(format!("URDF {}", path.display())),
        units: Units::default(),
        gravity: [0.0, 0.0, -9.81],
        kinematics: Box::new(UrdfSpec {
            path: absolute.display().to_string(),
            joints: Vec::new(),
            prior: Default::default(),
        }),
        links: Vec::new(),
        points,
        tool,
        payload: None,
        error_models: Vec::new(),
        predictor: None,
        fitted_predictor: None,
        predictor_frame: None,
        measurement: None,
        sensors: Vec::new(),
        fixtures: Vec::new(),
        collision: None,
        fixed: Vec::new(),
        fitted: None,
    })
}

/// Builds the robot of a bare URDF, whose files are read within `limits`; problems name the
/// URDF file, line and element.
pub fn robot_from_urdf(path: &Path, limits: InputLimits) -> armcomp_core::Result<Robot> {
    let file = robot_file_for_urdf(path, limits)?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut robot = Robot::build(file, dir, limits).map_err(|issues| armcomp_core::Error::InvalidFile {
        file: path.to_path_buf(),
        issues,
    })?;
    robot.source = Some(path.to_path_buf());
    Ok(robot)
}
