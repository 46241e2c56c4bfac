//! `export-urdf`: a model's identified URDF geometry, and what URDF cannot hold of it.

use armcomp_core::Robot;
use armcomp_core::algorithms::evaluate::position_errors;
use armcomp_core::data::measurement::Sample;
use armcomp_urdf::{CalibratedUrdf, ZERO_BELOW};
use nalgebra::Isometry3;

/// What of `robot` a URDF cannot express: its error models by type and a fitted predictor.
pub fn inexpressible(robot: &Robot) -> Vec<String> {
    let mut parts = robot.error_model_types();
    if robot.predictor().is_some() {
        parts.push("the fitted residual predictor".into());
    }
    parts
}

/// How far (m, largest over `samples`) dropping the error models and predictor moves the
/// measured points: what a rigid-only export loses.
pub fn rigid_deviation(robot: &Robot, samples: &[Sample]) -> armcomp_core::Result<f64> {
    let rigid = rigid(robot)?;
    let full = position_errors(robot, samples);
    let without = position_errors(&rigid, samples);
    Ok(full
        .iter()
        .zip(&without)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max))
}

/// `robot` without its error models and predictor: what a URDF of it holds.
pub fn rigid(robot: &Robot) -> armcomp_core::Result<Robot> {
    let mut rigid_file = robot.to_file();
    rigid_file.error_models.clear();
    rigid_file.fitted_predictor = None;
    rigid_file.predictor = None;
    robot.rebuild(rigid_file)
}

/// What an export wrote and what it left out, one `[status, item, details]` row each, values in
/// `robot`'s units: the rewritten joints, the markers added, the values written as 0, and the
/// measurement frame and the `dropped` models ([`inexpressible`]), which a URDF does not hold.
pub fn summary(robot: &Robot, urdf: &CalibratedUrdf, dropped: &[String]) -> Vec<[String; 3]> {
    let units = robot.units();
    let pose = |p: &Isometry3<f64>| {
        let v = p.translation.vector;
        let (r, pitch, y) = p.rotation.euler_angles();
        // `+ 0.0` turns -0 into 0, which prints without a sign.
        let [x, yy, z] = [v.x, v.y, v.z].map(|c| units.len_out(c) + 0.0);
        let [r, pitch, y] = [r, pitch, y].map(|a| units.ang_out(a) + 0.0);
        format!(
            "xyz [{x:.6}, {yy:.6}, {z:.6}] {}, rpy [{r:.6}, {pitch:.6}, {y:.6}] {}",
            units.length.symbol(),
            units.angle.symbol()
        )
    };
    let mut rows = Vec::new();
    for joint in &urdf.identified {
        rows.push([
            "written".into(),
            format!("joint `{joint}`"),
            "identified origin and axis".into(),
        ]);
    }
    for m in &urdf.markers {
        rows.push(match &m.joint {
            Some(joint) => [
                "written".into(),
                format!("marker `{}`", m.name),
                format!(
                    "fixed joint `{joint}` from `{}` to a new link `{}`{}: {}",
                    m.parent,
                    m.link,
                    if m.link == m.name {
                        String::new()
                    } else {
                        format!(" (the URDF already uses the name `{}`)", m.name)
                    },
                    pose(&m.offset)
                ),
            ],
            None => [
                "kept".into(),
                format!("marker `{}`", m.name),
                format!("the origin of the URDF's link `{}`", m.name),
            ],
        });
    }
    if urdf.zeroed > 0 {
        rows.push([
            "written as 0".into(),
            format!("{} value(s)", urdf.zeroed),
            format!("below {ZERO_BELOW:e} m or rad: rounding left by calibration, not geometry"),
        ]);
    }
    rows.push([
        "not written".into(),
        "measurement frame".into(),
        format!(
            "the tracker's, not part of the robot: the robot base is at {} in it",
            pose(&robot.t_meas_base())
        ),
    ]);
    for d in dropped {
        rows.push([
            "not written".into(),
            d.clone(),
            "URDF cannot express it (--rigid-only)".into(),
        ]);
    }
    rows
}
