//! `diagnose`: the residual predictor that scores what remains learnable, around
//! [`armcomp_core::analysis::diagnose::diagnose`].

use armcomp_core::analysis::diagnose::{DiagnoseParams, DiagnoseProgress, Diagnosis, DiagnosisReport, diagnose};
use armcomp_core::data::measurement::MeasurementSet;
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

/// Diagnoses `robot`, given the data's stations, on `data` with every registered plugin's
/// candidates; `progress` hears of every fold calibration.
pub fn run(
    robot: &Robot,
    data: &MeasurementSet,
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
    let adopted = crate::with_stations(robot, data)?;
    diagnose(
        adopted.as_ref().unwrap_or(robot),
        &data.samples,
        &crate::plugins(),
        predictor,
        params,
        progress,
    )
}

/// The data rows (as `--rows` counts them) of the diagnosis' gross errors, largest first;
/// `rows` gives each sample's row.
pub fn gross_error_rows(report: &DiagnosisReport, rows: &[usize]) -> Vec<usize> {
    report.gross_errors.iter().map(|o| rows[o.sample]).collect()
}

/// The report as `armcomp diagnose --json` prints it: with `gross_error_rows`.
pub fn to_json(report: &DiagnosisReport, rows: &[usize]) -> serde_json::Value {
    // Plain numbers, strings and lists: it cannot fail.
    let mut value = serde_json::to_value(report).expect("the report serialises");
    value["gross_error_rows"] = gross_error_rows(report, rows).into();
    value
}
