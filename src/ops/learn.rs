//! `learn`: fits a model's residual predictor and stores it in the model file.

use std::time::Instant;

use armcomp_core::evaluate::{ErrorStats, fit_residual_predictor, model_errors, position_errors};
use armcomp_core::measurement::Sample;
use armcomp_core::{Error, PredictorSpec, Robot, RobotFile, Role};

/// A model with its fitted predictor and how much the predictor removes on the training data.
#[derive(Debug)]
pub struct LearnRun {
    /// The model with the fitted predictor (built from the model file; `to_text_for` writes it).
    pub robot: Robot,
    /// Training errors of the model alone.
    pub before: ErrorStats,
    /// Training errors with the predictor.
    pub after: ErrorStats,
    /// Fitting time (s).
    pub seconds: f64,
}

/// A predictor type with its default settings (`gp`, `mlp`, `ssa_bp`, `ridge`, `knn`, as
/// `armcomp plugins` lists them).
pub fn default_predictor(type_name: &str) -> armcomp_core::Result<Box<dyn PredictorSpec>> {
    let known: Vec<String> = crate::registry::builtin_plugins()
        .iter()
        .filter(|p| p.role == Role::Predictor)
        .map(|p| p.type_name.to_string())
        .collect();
    if !known.iter().any(|k| k == type_name) {
        return Err(Error::UnknownPlugin {
            role: Role::Predictor,
            name: type_name.into(),
            known,
            provider: "armcomp".into(),
        });
    }
    serde_json::from_value(serde_json::json!({ "type": type_name })).map_err(|e| Error::InvalidArgument {
        what: format!("predictor `{type_name}`"),
        reason: e.to_string(),
    })
}

/// Fits `predictor`, or else the predictor `robot`'s `[predictor]` table describes, on
/// `samples` and stores it in `file`, the model's own description (re-read from its file by
/// the command line, so that everything in it is kept); a given `predictor` becomes the
/// model's `[predictor]` table.
pub fn run(
    robot: &Robot,
    mut file: RobotFile,
    samples: &[Sample],
    predictor: Option<Box<dyn PredictorSpec>>,
) -> armcomp_core::Result<LearnRun> {
    // The model's own spec as built: a run-time library found beside the model file.
    let Some(spec) = predictor.as_deref().or(robot.predictor_spec()) else {
        return Err(Error::InvalidArgument {
            what: "predictor".into(),
            reason: "the model has no [predictor] table; name a predictor (e.g. gp) or add a `[predictor]` table with its type and settings"
                .into(),
        });
    };
    let start = Instant::now();
    let fitted = fit_residual_predictor(robot, spec, samples)?;
    let seconds = start.elapsed().as_secs_f64();
    if let Some(spec) = predictor {
        file.predictor = Some(spec);
    }
    let before = ErrorStats::from_errors(&model_errors(robot, samples));
    file.fitted_predictor = Some(fitted);
    let written = Robot::build(file, &robot.base_dir()).map_err(Error::InvalidModel)?;
    let after = ErrorStats::from_errors(&position_errors(&written, samples));
    Ok(LearnRun {
        robot: written,
        before,
        after,
        seconds,
    })
}
