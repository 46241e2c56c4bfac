//! `learn`: fits a model's residual predictor and stores it in the model file.

use std::time::Instant;

use armcomp_core::algorithms::evaluate::{
    ErrorStats, cross_validated_predictor_errors, fit_residual_predictor, model_errors, predictor_errors,
};
use armcomp_core::analysis::held_out::{contacts_as_positions, measures_positions};
use armcomp_core::data::measurement::Sample;
use armcomp_core::{Error, FitControl, PredictorSpec, Robot, RobotFile, Role};

/// A model with its fitted predictor and how much the predictor removes on the training data.
#[derive(Debug)]
pub struct LearnRun {
    /// The model with the fitted predictor (built from the model file; `to_text_for` writes it).
    pub robot: Robot,
    /// Errors of the model alone on these rows (nothing of it was fitted here, so they are
    /// its errors on any rows).
    pub before: ErrorStats,
    /// Errors with the predictor on the rows it was fitted on (optimistic: it has seen them).
    pub after: ErrorStats,
    /// Errors with the predictor on poses it was not fitted on (every pose held out once in
    /// [`CV_FOLDS`]-fold cross-validation, whole stations for data from several), and how the
    /// folds were drawn; `None` with too few poses for that. The same rows, the same errors
    /// (measured minus modelled position, the predictions in the base frame) and the same
    /// statistics as `after`: only whether the predictor saw the row differs.
    pub cross_validated: Option<(ErrorStats, armcomp_core::data::split::Folding)>,
    /// For a model `fit` wrote (one with a fit record): the same folds with the physical model
    /// fitted again on each fold's training rows too, from where its fit started and the way
    /// it was fitted, the model alone and then with the predictor. These are the figures `fit`
    /// scored the model by; `cross_validated` keeps the physical model fitted on every row,
    /// which has seen the held-out rows, so it is the lower of the two.
    pub refitted: Option<Refitted>,
    /// Fitting time (s).
    pub seconds: f64,
}

/// Held-out errors with the physical model fitted again in every fold (see [`LearnRun::refitted`]).
#[derive(Debug, Clone, serde::Serialize)]
pub struct Refitted {
    /// The physical model alone.
    pub model: ErrorStats,
    /// With the predictor fitted on what the fold's model leaves on its training rows.
    pub with_predictor: ErrorStats,
}

/// Folds of the cross-validated error `learn` reports beside the training error.
pub const CV_FOLDS: usize = 5;

/// A cross-validated RMS this many times the training RMS says the predictor memorised its
/// rows rather than learned a pattern that carries to other poses.
pub const MEMORISING_RATIO: f64 = 2.0;

impl LearnRun {
    /// What the fit suggests is wrong: a predictor that memorised its rows, or one that
    /// predicts held-out poses no better than the model alone.
    pub fn warnings(&self) -> Vec<String> {
        let Some((cv, _)) = &self.cross_validated else {
            return vec![format!(
                "too few poses for a cross-validated error ({CV_FOLDS} folds need {CV_FOLDS}); the training error says \
                 nothing of other poses"
            )];
        };
        let mut out = Vec::new();
        if let Some(r) = &self.refitted {
            // The model's own figures: the training rows say nothing here (a GP interpolates them).
            if r.with_predictor.rms_mm >= r.model.rms_mm {
                out.push(format!(
                    "the predictor does not help on rows it was not fitted on (RMS {:.4} mm with it, {:.4} mm without, \
                     the physical model fitted again in every fold)",
                    r.with_predictor.rms_mm, r.model.rms_mm
                ));
            }
            return out;
        }
        if cv.rms_mm > MEMORISING_RATIO * self.after.rms_mm {
            out.push(format!(
                "the predictor memorises: RMS {:.4} mm on its training rows but {:.4} mm on rows it was not fitted on",
                self.after.rms_mm, cv.rms_mm
            ));
        }
        if cv.rms_mm >= self.before.rms_mm {
            out.push(format!(
                "the predictor does not help on rows it was not fitted on (RMS {:.4} mm with it, {:.4} mm without): \
                 what the model leaves is not learnable from these rows",
                cv.rms_mm, self.before.rms_mm
            ));
        }
        out
    }
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
/// model's `[predictor]` table. `control` sees the training and then the cross-validation's
/// folds, and can stop them.
pub fn run(
    robot: &Robot,
    mut file: RobotFile,
    samples: &[Sample],
    predictor: Option<Box<dyn PredictorSpec>>,
    fold_groups: Option<(String, Vec<usize>)>,
    control: &FitControl<'_>,
) -> armcomp_core::Result<LearnRun> {
    // The model's own spec as built: a run-time library found beside the model file.
    let Some(spec) = predictor.as_deref().or(robot.predictor_spec()) else {
        return Err(Error::InvalidArgument {
            what: "predictor".into(),
            reason: "the model has no [predictor] table; name a predictor (e.g. gp) or add a `[predictor]` table with its type and settings"
                .into(),
        });
    };
    // Contacts become the positions they measure under the model (its fixed points and planes);
    // a fold's model fitted again would measure them otherwise, so only positions are refitted.
    let positions = measures_positions(samples);
    let converted;
    let samples = if measures_positions(samples) {
        samples
    } else {
        converted = contacts_as_positions(robot, samples)?;
        &converted
    };
    let start = Instant::now();
    let fitted = fit_residual_predictor(robot, spec, samples, control)?;
    let seconds = start.elapsed().as_secs_f64();
    let before = ErrorStats::from_errors(&model_errors(robot, samples));
    let after = ErrorStats::from_errors(&predictor_errors(robot, fitted.as_ref(), samples));
    let poses = armcomp_core::data::split::pose_groups(samples).len();
    let by = armcomp_core::data::split::FoldBy::choose(samples, fold_groups);
    let cross_validated = if poses >= CV_FOLDS {
        Some(cross_validated_predictor_errors(
            robot, spec, samples, CV_FOLDS, 0, &by, control,
        )?)
    } else {
        None
    };
    let refitted = match (&cross_validated, armcomp_core::calibrate::before_fit(robot, samples)?) {
        (Some(_), Some(start)) if positions => Some(refitted_errors(robot, &start, spec, samples, &by, control)?),
        _ => None,
    };
    if let Some(spec) = predictor {
        file.predictor = Some(spec);
    }
    file.fitted_predictor = Some(fitted);
    file.predictor_frame = Some(armcomp_core::robot::robot_file::PredictorFrame::Base);
    let written = Robot::build(file, &robot.base_dir(), robot.input_limits()).map_err(Error::InvalidModel)?;
    Ok(LearnRun {
        robot: written,
        before,
        after,
        cross_validated,
        refitted,
        seconds,
    })
}

/// The held-out errors of [`LearnRun::refitted`]: in each of [`CV_FOLDS`] folds (seed 0, as
/// `cross_validated`), the physical model fitted on the training rows from `start` (the model
/// before its fit) as `model`'s fit record says, then the predictor on what it leaves.
fn refitted_errors(
    model: &Robot,
    start: &Robot,
    spec: &dyn PredictorSpec,
    samples: &[Sample],
    by: &armcomp_core::data::split::FoldBy,
    control: &FitControl<'_>,
) -> armcomp_core::Result<Refitted> {
    use armcomp_core::calibrate::{CalibrationParams, calibrate, register_held_out_stations};
    use armcomp_core::data::split::{folds, subset};
    let (splits, _) = folds(samples, CV_FOLDS, 0, by)?;
    let params = CalibrationParams {
        cancel: control.cancel.clone(),
        ..CalibrationParams::default()
    }
    .continued_from(model, samples, false, false);
    let (mut alone, mut with) = (Vec::new(), Vec::new());
    for (k, split) in splits.iter().enumerate() {
        let train = subset(samples, &split.train);
        let test = subset(samples, &split.test);
        let mut fit = calibrate(start, &train, &params, &mut |_| {})?.robot;
        register_held_out_stations(&mut fit, &train, &test)?;
        let fold_control = FitControl {
            progress: None,
            cancel: control.cancel.clone(),
        };
        let fitted = fit_residual_predictor(&fit, spec, &train, &fold_control)?;
        alone.extend(model_errors(&fit, &test));
        with.extend(predictor_errors(&fit, fitted.as_ref(), &test));
        control.report("refitted folds", k + 1, splits.len());
    }
    Ok(Refitted {
        model: ErrorStats::from_errors(&alone),
        with_predictor: ErrorStats::from_errors(&with),
    })
}
