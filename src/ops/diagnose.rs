//! `diagnose`: the residual predictor that scores what remains learnable, around
//! [`armcomp_core::diagnose::diagnose`].

use armcomp_core::diagnose::{DiagnoseParams, DiagnoseProgress, Diagnosis, diagnose};
use armcomp_core::measurement::Sample;
use armcomp_core::{PredictorSpec, Robot};

/// The predictor that scores the learnable residual.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LearnableBy {
    /// A Gaussian process, seeded by the diagnosis seed.
    Gp,
    /// Ridge regression (fast baseline).
    Ridge,
    /// Not scored.
    None,
}

/// Diagnoses `robot` on `samples` with every registered plugin's candidates; `progress` hears
/// of every fold calibration.
pub fn run(
    robot: &Robot,
    samples: &[Sample],
    params: &DiagnoseParams,
    learnable_by: LearnableBy,
    progress: &(dyn Fn(DiagnoseProgress) + Sync),
) -> armcomp_core::Result<Diagnosis> {
    let gp = armcomp_learn::GpSpec {
        seed: params.seed,
        ..Default::default()
    };
    let ridge = armcomp_learn::RidgeSpec::default();
    let predictor: Option<(&str, &dyn PredictorSpec)> = match learnable_by {
        LearnableBy::Gp => Some(("gp", &gp)),
        LearnableBy::Ridge => Some(("ridge", &ridge)),
        LearnableBy::None => None,
    };
    diagnose(robot, samples, &crate::plugins(), predictor, params, progress)
}
