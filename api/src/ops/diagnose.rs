//! `diagnose`: the residual predictor that scores what remains learnable, around
//! [`armcomp_core::analysis::diagnose::diagnose`].

use armcomp_core::analysis::diagnose::{DiagnoseParams, DiagnoseProgress, Diagnosis, DiagnosisReport, diagnose};
use armcomp_core::calibrate::CalibrationParams;
use armcomp_core::calibrate::evidence::{EvidenceParams, calibrate_with_evidence};
use armcomp_core::data::measurement::{MeasurementSet, Sample};
use armcomp_core::{FitControl, PredictorSpec, Robot};

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
    let robot = adopted.as_ref().unwrap_or(robot);
    // A fitted model is fitted again from where its fit started, as `fit` scored it: from its
    // own answer, every fold would start from values that have seen the fold's rows.
    let restored = armcomp_core::calibrate::before_fit(robot, &data.samples)?;
    diagnose(
        restored.as_ref().unwrap_or(robot),
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

/// Where the diagnosis' noise (the floor candidates are judged against) came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NoiseFrom {
    /// `--noise-mm`.
    Declared,
    /// The model's fit record.
    FitRecord,
    /// The evidence of the model as given, fitted on all rows.
    Estimated,
}

/// The calibration settings the diagnosis of `robot` (given the data's stations) on `data` uses: continued from the
/// model's fit record (its identified set, priors and noise, unless `calibration` sets them:
/// `noise_declared`), and without a declared or recorded noise the noise the evidence
/// estimates for the model as given on all rows.
pub fn calibration_for(
    robot: &Robot,
    data: &MeasurementSet,
    calibration: CalibrationParams,
    noise_declared: bool,
) -> armcomp_core::Result<(CalibrationParams, NoiseFrom)> {
    let adopted = crate::with_stations(robot, data)?;
    let robot = adopted.as_ref().unwrap_or(robot);
    let samples = &data.samples;
    let recorded = robot.built_from().fitted.is_some();
    let mut calibration = calibration.continued_from(robot, samples, noise_declared, false);
    let from = match (noise_declared, recorded) {
        (true, _) => NoiseFrom::Declared,
        (false, true) => NoiseFrom::FitRecord,
        (false, false) => {
            let evidence = EvidenceParams {
                estimate_priors: false,
                ..EvidenceParams::default()
            };
            let (fit, _) = calibrate_with_evidence(robot, samples, &calibration, &evidence, &mut |_| {})?;
            calibration.measurement_std = fit.linearisation.noise;
            calibration.orientation_std = fit.linearisation.orientation_noise;
            NoiseFrom::Estimated
        }
    };
    Ok((calibration, from))
}

/// The model `diagnose --out` writes, and what became of the given model's predictor: `None`
/// for the model as given (with its predictor and fit record) when no effect was added to a
/// fitted model (one with a predictor or a fit record), so that a diagnosis that finds nothing
/// never changes what `fit` or `learn` left; else the diagnosed model (a nominal robot
/// calibrated on the rows, with the data's stations), with the given model's predictor fitted
/// again on what it leaves on `samples`, so that a predictor is never dropped without a word.
pub fn output_model(
    given: &Robot,
    diagnosis: &Diagnosis,
    samples: &[Sample],
    control: &FitControl<'_>,
) -> armcomp_core::Result<(Option<Robot>, Option<String>)> {
    let fitted = given.predictor().is_some() || given.built_from().fitted.is_some();
    if diagnosis.report.steps.is_empty() && fitted {
        let note = if given.predictor().is_some() {
            "no effect was added: the model is written as given, its fitted predictor kept"
        } else {
            "no effect was added: the model is written as given"
        };
        return Ok((None, Some(note.to_string())));
    }
    let diagnosed = &diagnosis.robot;
    if given.predictor().is_none() || diagnosed.predictor_spec().is_none() {
        return Ok((Some(diagnosed.rebuild(diagnosed.to_file())?), None));
    }
    let run = crate::ops::learn::run(diagnosed, diagnosed.to_file(), samples, None, None, control)?;
    let note = format!(
        "the given model's predictor was fitted again on what the diagnosed model leaves (training RMS {:.4} mm)",
        run.after.rms_mm
    );
    Ok((Some(run.robot), Some(note)))
}
