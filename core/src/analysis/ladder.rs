//! Choosing the model from the training rows alone: the ladder registration → joint offsets →
//! geometry → residual predictor, every rung scored by nested cross-validation.
//!
//! Each rung is fitted on the training part of every outer fold exactly as it will be fitted on
//! all the rows, its choices (noise, prior scales, the predictor's hyper-parameters) made
//! inside that part by the evidence, and scored on the fold left out; a choice never sees the
//! rows that score it. A rung is kept only when it beats the last rung kept by more than the
//! standard error of the paired difference, so a richer model must earn its parameters on rows
//! it has not seen. The folds hold out whole pose groups, or whole groups of a named column
//! (a session, a station) when the caller gives them, since random folds over clustered poses
//! are optimistic.

use std::time::Instant;

use rayon::prelude::*;
use serde::Serialize;

use crate::algorithms::evaluate::fit_residual_predictor;
use crate::calibrate::evidence::{EvidenceParams, EvidenceReport, calibrate_with_evidence};
use crate::calibrate::{Calibration, CalibrationParams, FitsProgress, register_held_out_stations};
use crate::data::measurement::Sample;
use crate::data::split::{FoldBy, Split, subset};
use crate::error::{Error, Result};
use crate::plugin::{FitControl, PredictorSpec};
use crate::robot::Robot;
use crate::support::cancel::Cancel;

/// A rung of the ladder.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Rung {
    /// The measurement frame and the markers.
    Registration,
    /// Plus the joint offsets of the measured chain.
    JointOffsets,
    /// Plus every geometry parameter of the measured chain.
    Geometry,
    /// Plus the robot file's error models (when it has any).
    ErrorModels,
    /// The best physical rung with a residual predictor on what it leaves.
    Predictor,
}

impl Rung {
    /// What the rung identifies, as `--identify` words.
    fn identify(self) -> &'static [&'static str] {
        match self {
            Rung::Registration => &["base", "markers"],
            Rung::JointOffsets => &["base", "markers", "offsets"],
            Rung::Geometry => &["base", "markers", "geometry"],
            Rung::ErrorModels | Rung::Predictor => &["base", "markers", "geometry", "errors"],
        }
    }

    /// Its name in reports.
    pub fn label(self) -> &'static str {
        match self {
            Rung::Registration => "registration",
            Rung::JointOffsets => "joint offsets",
            Rung::Geometry => "geometry",
            Rung::ErrorModels => "geometry + error models",
            Rung::Predictor => "+ residual predictor",
        }
    }
}

/// Settings of [`climb`].
#[derive(Debug)]
pub struct LadderParams {
    /// How each rung calibrates (its `identify` is the rung's; its `measurement_std` is the
    /// declared noise when `noise_declared`, else the first guess).
    pub calibration: CalibrationParams,
    /// Whether the noise is declared (otherwise estimated with every fit).
    pub noise_declared: bool,
    /// Outer folds.
    pub folds: usize,
    /// Seed of the folds.
    pub seed: u64,
    /// A group per sample (a session, a station): folds hold out whole groups. `None` holds
    /// out whole poses.
    pub fold_groups: Option<Vec<usize>>,
    /// The residual predictor to try on top of the best physical rung (none: no such rung).
    pub predictor: Option<Box<dyn PredictorSpec>>,
}

/// One rung's nested cross-validated score.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RungScore {
    /// The rung.
    pub rung: Rung,
    /// Its name in reports.
    pub label: String,
    /// Pooled held-out RMS over the outer folds of the error [`LadderReport::scored_by`] names
    /// (mm).
    pub rms_mm: f64,
    /// Held-out RMS of each outer fold (mm).
    pub fold_rms_mm: Vec<f64>,
    /// Mean held-out squared error gained over the last rung kept (mm², positive is better;
    /// 0 for the first rung).
    pub gain_mm2: f64,
    /// The standard error of that gain (mm²) over the held-out pose groups.
    pub gain_std_error_mm2: f64,
    /// Whether it was kept (it beats the last rung kept by more than the standard error).
    pub kept: bool,
    /// Why it was or was not kept.
    pub reason: String,
    /// Wall-clock time of its fits (s).
    pub seconds: f64,
}

/// What the ladder chose and how.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LadderReport {
    /// Every rung tried, in order.
    pub rungs: Vec<RungScore>,
    /// The rung chosen.
    pub chosen: Rung,
    /// Its nested cross-validated RMS: the held-out error to expect from the model (mm).
    pub expected_rms_mm: f64,
    /// Outer folds.
    pub folds: usize,
    /// What each fold held out together: `pose`, `station` (data from several), or `groups`
    /// (the caller's).
    pub folds_by: String,
    /// What a held-out row's error is: `position` (its 3-D error), `plane height` (a contact's
    /// height above the plane its fold identified), `fixed-point distance` (a contact's
    /// distance from where its fold's contacts put the point), `+`-joined for mixed data.
    pub scored_by: String,
    /// Why the residual predictor was not tried although one was asked for, if so.
    pub predictor_not_tried: Option<String>,
    /// The noise and priors the evidence chose for the chosen rung on all rows.
    pub evidence: EvidenceReport,
    /// Whether a stop request ([`CalibrationParams::cancel`]) ended the cross-validation: the rungs
    /// are those whose every fold was fitted before it (the predictor's is not tried), and the
    /// choice among them was fitted on all rows after it.
    pub interrupted: bool,
}

/// The chosen model, fitted on all rows.
#[derive(Debug)]
pub struct Ladder {
    /// The model (with its fitted predictor when that rung was chosen).
    pub robot: Robot,
    /// The calibration of the chosen physical rung on all rows.
    pub calibration: Calibration,
    /// The ladder.
    pub report: LadderReport,
}

/// The rungs [`climb`] fits for `robot`: registration, joint offsets, geometry, and the error
/// models when the robot has any.
fn physical_rungs(robot: &Robot) -> Vec<Rung> {
    let mut rungs = vec![Rung::Registration, Rung::JointOffsets, Rung::Geometry];
    if !robot.error_models().is_empty() {
        rungs.push(Rung::ErrorModels);
    }
    rungs
}

fn calibration_params(params: &LadderParams, rung: Rung) -> (CalibrationParams, EvidenceParams) {
    let calibration = CalibrationParams {
        identify: rung.identify().iter().map(|w| w.to_string()).collect(),
        ..params.calibration.clone()
    };
    let evidence = EvidenceParams {
        estimate_noise: !params.noise_declared,
        ..EvidenceParams::default()
    };
    (calibration, evidence)
}

fn fit_rung(
    robot: &Robot,
    samples: &[Sample],
    params: &LadderParams,
    rung: Rung,
    cancel: &Cancel,
) -> Result<(Calibration, EvidenceReport)> {
    let (mut calibration, evidence) = calibration_params(params, rung);
    calibration.cancel = cancel.clone();
    calibrate_with_evidence(robot, samples, &calibration, &evidence, &mut |_| {})
}

/// `robot` with `spec` fitted on what it leaves on `samples`.
fn with_predictor(robot: &Robot, spec: &dyn PredictorSpec, samples: &[Sample], cancel: &Cancel) -> Result<Robot> {
    let control = FitControl {
        progress: None,
        cancel: cancel.clone(),
    };
    let fitted = fit_residual_predictor(robot, spec, samples, &control)?;
    let mut file = robot.to_file();
    file.predictor = Some(serde_json::from_value(serde_json::to_value(spec).map_err(json_error)?).map_err(json_error)?);
    file.fitted_predictor = Some(fitted);
    file.predictor_frame = Some(crate::robot::robot_file::PredictorFrame::Base);
    robot.rebuild(file)
}

fn json_error(e: serde_json::Error) -> Error {
    Error::InvalidArgument {
        what: "predictor".into(),
        reason: e.to_string(),
    }
}

/// Squared held-out error of every sample (m²), in sample order, from the folds' models
/// ([`held_out_errors`](crate::analysis::held_out::held_out_errors)); NaN for a sample its fold
/// cannot score.
fn held_out_errors(samples: &[Sample], splits: &[Split], models: &[Robot]) -> Result<Vec<f64>> {
    let mut out = vec![f64::NAN; samples.len()];
    for (split, model) in splits.iter().zip(models) {
        let errors = crate::analysis::held_out::held_out_errors(
            model,
            &subset(samples, &split.train),
            &subset(samples, &split.test),
        )?;
        for (&i, e) in split.test.iter().zip(errors) {
            out[i] = e.map_or(f64::NAN, |e| e.norm_squared());
        }
    }
    Ok(out)
}

/// Chooses among the rungs by nested cross-validation on `samples` and fits the choice on all
/// of them (see the module documentation). `progress` sees every fit done. Deterministic for
/// a seed; folds and rungs run in parallel.
pub fn climb(
    robot: &Robot,
    samples: &[Sample],
    params: &LadderParams,
    progress: &(dyn Fn(FitsProgress) + Sync),
) -> Result<Ladder> {
    // By the caller's groups, else by station for data from several, else by pose; `groups`
    // is what the spread of the scores is judged over.
    let by = FoldBy::choose(samples, params.fold_groups.clone().map(|g| ("groups".to_string(), g)));
    let (splits, folding) = crate::data::split::folds(samples, params.folds, params.seed, &by)?;
    let groups: Vec<usize> = match by {
        FoldBy::Column { groups, .. } => groups,
        FoldBy::Stations => samples.iter().map(|s| s.station).collect(),
        FoldBy::Poses => {
            let mut g = vec![0; samples.len()];
            for (k, members) in crate::data::split::pose_groups(samples).iter().enumerate() {
                for &i in members {
                    g[i] = k;
                }
            }
            g
        }
    };
    let folds_by = folding.grouped_by;
    let cancel = &params.calibration.cancel;
    let rungs = physical_rungs(robot);
    // Every rung on every fold, the choice on all rows, the predictor on every fold and on all rows.
    // A residual predictor learns 3-D errors, which fixed-point and plane rows do not give.
    let positions_only = crate::analysis::held_out::measures_positions(samples);
    let predictor = params.predictor.as_ref().filter(|_| positions_only);
    let total = rungs.len() * splits.len() + 1 + predictor.map_or(0, |_| splits.len() + 1);
    let done = std::sync::atomic::AtomicUsize::new(0);
    let tick = || {
        let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        progress(FitsProgress { done: d, total });
    };
    // Every rung on every fold, in parallel.
    let jobs: Vec<(usize, usize)> = (0..rungs.len())
        .flat_map(|r| (0..splits.len()).map(move |f| (r, f)))
        .collect();
    let timed: Vec<Option<(Robot, f64)>> = jobs
        .par_iter()
        .map(|&(r, f)| {
            if cancel.is_cancelled() {
                return Ok(None);
            }
            let start = Instant::now();
            let train = subset(samples, &splits[f].train);
            let Some((cal, _)) = crate::support::cancel::finished(fit_rung(robot, &train, params, rungs[r], cancel))?
            else {
                return Ok(None);
            };
            let mut model = cal.robot;
            register_held_out_stations(&mut model, &train, &subset(samples, &splits[f].test))?;
            tick();
            Ok(Some((model, start.elapsed().as_secs_f64())))
        })
        .collect::<Result<_>>()?;
    let interrupted = timed.iter().any(Option::is_none);
    // The rungs whose every fold was fitted, up to the first a stop left unfinished.
    let mut fold_models: Vec<Vec<Robot>> = Vec::new();
    let mut seconds = Vec::new();
    let mut it = timed.into_iter();
    for _ in &rungs {
        let Some(fits) = it.by_ref().take(splits.len()).collect::<Option<Vec<_>>>() else {
            break;
        };
        let (models, secs): (Vec<Robot>, Vec<f64>) = fits.into_iter().unzip();
        fold_models.push(models);
        seconds.push(secs.iter().sum::<f64>());
    }
    if fold_models.is_empty() {
        return Err(Error::Interrupted);
    }
    let rungs = &rungs[..fold_models.len()];
    let mut scores = Vec::new();
    let mut kept_errors: Option<Vec<f64>> = None;
    let mut chosen = 0;
    for (r, &rung) in rungs.iter().enumerate() {
        let errors = held_out_errors(samples, &splits, &fold_models[r])?;
        let score = score_rung(rung, &errors, kept_errors.as_deref(), &groups, &splits, seconds[r]);
        if score.kept {
            kept_errors = Some(errors);
            chosen = r;
        }
        scores.push(score);
    }
    let mut chosen_rung = rungs[chosen];
    let mut predictor_models = None;
    // The choice is still fitted on all rows after a stop request; only a further one stops it.
    let final_cancel = if interrupted { cancel.renewed() } else { cancel.clone() };
    let predictor_not_tried = (params.predictor.is_some() && !positions_only)
        .then(|| "fixed-point and plane rows give no 3-D error for a residual predictor to learn".to_string());
    if let Some(spec) = predictor.filter(|_| !interrupted) {
        let start = Instant::now();
        let models: Vec<Robot> = splits
            .par_iter()
            .zip(&fold_models[chosen])
            .map(|(split, model)| {
                let m = with_predictor(model, spec.as_ref(), &subset(samples, &split.train), cancel);
                tick();
                m
            })
            .collect::<Result<_>>()?;
        let errors = held_out_errors(samples, &splits, &models)?;
        let score = score_rung(
            Rung::Predictor,
            &errors,
            kept_errors.as_deref(),
            &groups,
            &splits,
            start.elapsed().as_secs_f64(),
        );
        if score.kept {
            chosen_rung = Rung::Predictor;
            predictor_models = Some(models);
        }
        scores.push(score);
    }
    let expected_rms_mm = scores.iter().rev().find(|s| s.kept).map_or(f64::NAN, |s| s.rms_mm);
    // The choice fitted on all rows.
    let (calibration, evidence) = fit_rung(robot, samples, params, rungs[chosen], &final_cancel)?;
    tick();
    let model = match (&params.predictor, predictor_models) {
        (Some(spec), Some(_)) => {
            let m = with_predictor(&calibration.robot, spec.as_ref(), samples, &final_cancel)?;
            tick();
            m
        }
        _ => {
            if predictor.is_some() && !interrupted {
                // Not kept: its fit on all rows is not needed, and the count is complete.
                tick();
            }
            calibration.robot.rebuild(calibration.robot.to_file())?
        }
    };
    Ok(Ladder {
        robot: model,
        calibration,
        report: LadderReport {
            rungs: scores,
            chosen: chosen_rung,
            expected_rms_mm,
            folds: splits.len(),
            folds_by,
            scored_by: crate::analysis::held_out::scored_by(samples),
            predictor_not_tried,
            evidence,
            interrupted,
        },
    })
}

/// Scores a rung's held-out squared errors `errors` (m², per sample; NaN for unscored samples,
/// the same for every rung) against those of the last rung kept: the pooled RMS, and the
/// paired gain over the held-out groups with its standard error.
fn score_rung(
    rung: Rung,
    errors: &[f64],
    kept: Option<&[f64]>,
    groups: &[usize],
    splits: &[Split],
    seconds: f64,
) -> RungScore {
    let rms_of = |indices: &mut dyn Iterator<Item = usize>| {
        let (sum, n) = indices
            .map(|i| errors[i])
            .filter(|e| !e.is_nan())
            .fold((0.0, 0usize), |(s, n), e| (s + e, n + 1));
        if n == 0 {
            f64::NAN
        } else {
            (sum / n as f64).sqrt() * 1e3
        }
    };
    let rms_mm = rms_of(&mut (0..errors.len()));
    // A fold none of whose rows is scored has no RMS.
    let fold_rms_mm = splits
        .iter()
        .map(|s| rms_of(&mut s.test.iter().copied()))
        .filter(|r| !r.is_nan())
        .collect();
    let Some(kept) = kept else {
        return RungScore {
            rung,
            label: rung.label().into(),
            rms_mm,
            fold_rms_mm,
            gain_mm2: 0.0,
            gain_std_error_mm2: 0.0,
            kept: true,
            reason: "the first rung".into(),
            seconds,
        };
    };
    // Paired differences per held-out group (the samples of one pose or session are not
    // independent), each group's the mean over its samples.
    let n_groups = groups.iter().max().map_or(0, |m| m + 1);
    let (mut sum, mut count) = (vec![0.0; n_groups], vec![0usize; n_groups]);
    for i in (0..errors.len()).filter(|&i| !errors[i].is_nan()) {
        sum[groups[i]] += (kept[i] - errors[i]) * 1e6;
        count[groups[i]] += 1;
    }
    let d: Vec<f64> = sum
        .iter()
        .zip(&count)
        .filter(|(_, c)| **c > 0)
        .map(|(s, &c)| s / c as f64)
        .collect();
    let m = d.len() as f64;
    let mean = d.iter().sum::<f64>() / m;
    let var = d.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (m - 1.0).max(1.0);
    let se = (var / m).sqrt();
    let kept_flag = mean > se;
    let reason = if kept_flag {
        format!("beats the last rung kept by {mean:.3} mm² per row, more than its standard error {se:.3}")
    } else if mean > 0.0 {
        format!("gains {mean:.3} mm² per row, within its standard error {se:.3}: not earned")
    } else {
        format!("does worse on held-out rows ({mean:.3} mm² per row)")
    };
    RungScore {
        rung,
        label: rung.label().into(),
        rms_mm,
        fold_rms_mm,
        gain_mm2: mean,
        gain_std_error_mm2: se,
        kept: kept_flag,
        reason,
        seconds,
    }
}
