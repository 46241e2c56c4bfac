//! `export-urdf`: a model's identified URDF geometry, and what URDF cannot hold of it.

use armcomp_core::Robot;
use armcomp_core::evaluate::position_errors;
use armcomp_core::measurement::Sample;

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
    let mut rigid_file = robot.to_file();
    rigid_file.error_models.clear();
    rigid_file.fitted_predictor = None;
    rigid_file.predictor = None;
    let rigid = robot.rebuild(rigid_file)?;
    let full = position_errors(robot, samples);
    let without = position_errors(&rigid, samples);
    Ok(full
        .iter()
        .zip(&without)
        .map(|(a, b)| (a - b).norm())
        .fold(0.0, f64::max))
}
