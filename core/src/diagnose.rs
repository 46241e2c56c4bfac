//! Diagnosis: which physical effect is the model missing?
//!
//! The current model is calibrated on the training folds of a k-fold split by pose and scored
//! on the poses each fold holds out. Every candidate effect the registry can instantiate on the
//! robot (per joint, per link or once) is added in turn, calibrated together with everything
//! the model already identifies, and scored the same way. The best candidate is accepted when
//! it *earns its parameters*:
//!
//! - it lowers the pooled held-out RMS by at least [`DiagnoseParams::min_rms_reduction`]
//!   (5 % by default): held-out scores already punish over-fitting, but a gain of a few percent
//!   is within what the choice of folds moves a score by on a hundred poses, so it is not
//!   evidence of a missing effect;
//! - and the held-out Gaussian log-likelihood gain `n·ln(SSE₀/SSE₁)` (`n` scalar residuals)
//!   exceeds the BIC penalty `k·ln n` of its `k` parameters, so that a candidate with many
//!   parameters needs a proportionally larger gain.
//!
//! The accepted effect joins the model and the search repeats until no candidate earns its
//! parameters or [`DiagnoseParams::max_steps`] is reached. Finally a residual predictor is fitted
//! to what is left, fold by fold, to tell how much of it is unexplained but learnable.
//!
//! Every fold calibration starts from the robot file as given plus the accepted effects at
//! their neutral values, so no held-out pose ever influences a fold's start.

use std::collections::BTreeMap;

use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;

use crate::calibrate::{CalibrationParams, calibrate};
use crate::error::{Error, Result};
use crate::evaluate::{ErrorStats, position_errors};
use crate::measurement::Sample;
use crate::param::Quantity;
use crate::plugin::{Candidate, ErrorModelSpec, PluginInfo, PredictorSpec, Role, TrainingSet};
use crate::residuals::{ResidualDescription, describe_residuals};
use crate::robot::Robot;
use crate::split::{Split, kfold, subset};

/// Settings of [`diagnose`].
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnoseParams {
    /// Number of folds of the held-out score (split by pose).
    pub folds: usize,
    /// Seed of the split.
    pub seed: u64,
    /// Settings of every calibration (what to identify, noise, iterations).
    pub calibration: CalibrationParams,
    /// Smallest relative reduction of the held-out RMS that counts as an improvement.
    pub min_rms_reduction: f64,
    /// Most effects added.
    pub max_steps: usize,
}

impl Default for DiagnoseParams {
    fn default() -> Self {
        DiagnoseParams {
            folds: 3,
            seed: 0,
            calibration: CalibrationParams::default(),
            min_rms_reduction: 0.05,
            max_steps: 5,
        }
    }
}

/// One candidate as scored in one round.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RankedCandidate {
    /// The plugin type (`joint_compliance`, ...).
    pub effect: String,
    /// The joint or link it acts at, or `global`.
    pub location: String,
    /// What it is in words.
    pub label: String,
    /// Parameters it adds.
    pub n_params: usize,
    /// Held-out errors with it added (pooled over the folds), when it could be evaluated.
    pub heldout: Option<ErrorStats>,
    /// Share of the held-out RMS before the round that it removes (negative when worse).
    pub share_removed: f64,
    /// Whether it passes the acceptance rule (see the module documentation).
    pub earns_parameters: bool,
    /// Why it could not be evaluated.
    pub error: Option<String>,
    /// Held-out errors per sample (m), for the next round.
    #[serde(skip)]
    heldout_errors: Vec<Vector3<f64>>,
}

/// An identified parameter value (SI).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct IdentifiedValue {
    /// Value (SI).
    pub value: f64,
    /// Its SI unit.
    pub unit: &'static str,
}

/// One accepted effect.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DiagnosisStep {
    /// The plugin type.
    pub effect: String,
    /// The joint or link it acts at, or `global`.
    pub location: String,
    /// What it is in words.
    pub label: String,
    /// The finding in one sentence, values in the units engineers read.
    pub summary: String,
    /// Its parameters identified on all the data (SI).
    pub params: BTreeMap<String, IdentifiedValue>,
    /// Held-out errors before adding it.
    pub heldout_before: ErrorStats,
    /// Held-out errors after.
    pub heldout_after: ErrorStats,
    /// Share of the held-out RMS it removes.
    pub share_removed: f64,
    /// Every candidate of the round, best first.
    pub ranking: Vec<RankedCandidate>,
}

/// The model the diagnosis ends with.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FinalModel {
    /// The effects added, in order.
    pub effects: Vec<String>,
    /// Its held-out errors.
    pub heldout: ErrorStats,
    /// Where its held-out residuals live.
    pub residuals: ResidualDescription,
    /// The last round's candidates, none of which earned its parameters (empty when the step
    /// limit stopped the search).
    pub ranking: Vec<RankedCandidate>,
}

/// How much of the final held-out residual a predictor learns from the joint values.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LearnableResidual {
    /// The predictor's type.
    pub predictor: String,
    /// Held-out errors of the final model.
    pub heldout_before: ErrorStats,
    /// Held-out errors with the predictor (trained on each fold's training residuals) applied.
    pub heldout_after: ErrorStats,
    /// Share of the held-out RMS it removes: unexplained by physics, but learnable.
    pub share_learnable: f64,
}

/// What the diagnosis found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DiagnosisReport {
    /// Measured positions used.
    pub n_samples: usize,
    /// Folds of the held-out score.
    pub folds: usize,
    /// Held-out errors of the model as given.
    pub initial: ErrorStats,
    /// Where its held-out residuals live.
    pub initial_residuals: ResidualDescription,
    /// The accepted effects, in order.
    pub steps: Vec<DiagnosisStep>,
    /// The model at the end.
    #[serde(rename = "final")]
    pub final_model: FinalModel,
    /// What a residual predictor learns of the rest, when one was given.
    pub learnable_residual: Option<LearnableResidual>,
    /// Held-out error norms (mm) per sample of the initial model and after each step.
    #[serde(skip)]
    pub heldout_norms_mm: Vec<Vec<f64>>,
}

/// The improved robot (calibrated on all the data, the found effects added) and the report.
#[derive(Debug)]
pub struct Diagnosis {
    /// The improved robot; its [`Robot::to_file`] is the improved robot file.
    pub robot: Robot,
    /// The report.
    pub report: DiagnosisReport,
}

/// A candidate together with the plugin type that offers it.
struct Offer {
    effect: &'static str,
    candidate: Candidate,
}

/// Finds, one by one, the effects of `plugins` (the registry) that `robot` misses according to
/// `samples`; `predictor` (its type name and spec) learns what remains.
pub fn diagnose(
    robot: &Robot,
    samples: &[Sample],
    plugins: &[PluginInfo],
    predictor: Option<(&str, &dyn PredictorSpec)>,
    params: &DiagnoseParams,
) -> Result<Diagnosis> {
    if !(params.min_rms_reduction.is_finite() && (0.0..1.0).contains(&params.min_rms_reduction)) {
        return Err(Error::Input(format!(
            "the smallest RMS reduction must be between 0 and 1, got {}",
            params.min_rms_reduction
        )));
    }
    let splits = kfold(samples, params.folds, params.seed)?;
    let given = robot.error_models().len();
    // The robot as given plus the accepted effects at their neutral values.
    let mut model = robot.rebuild(robot.to_file())?;
    let mut current = heldout_errors(&model, samples, &splits, &params.calibration)?;
    let initial = ErrorStats::from_errors(&current);
    let initial_residuals = describe_residuals(robot, samples, &current);
    let mut heldout_norms_mm = vec![norms_mm(&current)];
    let mut fitted = calibrate(&model, samples, &params.calibration, &mut |_| {})?.robot;
    let mut steps: Vec<DiagnosisStep> = Vec::new();
    let mut last_ranking = Vec::new();
    while steps.len() < params.max_steps {
        let offers: Vec<Offer> = offers(&fitted, plugins)
            .into_iter()
            .filter(|o| {
                !steps
                    .iter()
                    .any(|s| s.effect == o.effect && s.location == o.candidate.location)
            })
            .collect();
        let mut ranking: Vec<RankedCandidate> = offers
            .par_iter()
            .map(|o| score(&model, given, o, samples, &splits, &current, params))
            .collect();
        ranking.sort_by(|a, b| rank_key(a).total_cmp(&rank_key(b)).then_with(|| a.label.cmp(&b.label)));
        let Some(best) = ranking.first().filter(|c| c.earns_parameters).cloned() else {
            last_ranking = ranking;
            break;
        };
        let offer = offers
            .iter()
            .find(|o| o.effect == best.effect && o.candidate.location == best.location)
            .expect("the ranking is made of the offers");
        model = with_effect(&model, offer)?;
        fitted = calibrate(&model, samples, &selection(&model, given, params), &mut |_| {})?.robot;
        let before = ErrorStats::from_errors(&current);
        let after = best.heldout.expect("an accepted candidate was evaluated");
        let values = new_model_values(&fitted);
        steps.push(DiagnosisStep {
            effect: best.effect.clone(),
            location: best.location.clone(),
            label: best.label.clone(),
            summary: format!(
                "{}, {}: removes {:.0}% of the remaining held-out RMS ({:.3} → {:.3} mm)",
                best.label,
                values
                    .iter()
                    .map(|(_, q, v)| readable(*q, *v))
                    .collect::<Vec<_>>()
                    .join(", "),
                100.0 * best.share_removed,
                before.rms_mm,
                after.rms_mm
            ),
            params: values
                .iter()
                .map(|(name, q, v)| {
                    (
                        name.clone(),
                        IdentifiedValue {
                            value: *v,
                            unit: q.si_unit(),
                        },
                    )
                })
                .collect(),
            heldout_before: before,
            heldout_after: after,
            share_removed: best.share_removed,
            ranking,
        });
        current = best.heldout_errors;
        heldout_norms_mm.push(norms_mm(&current));
    }
    let learnable_residual = match predictor {
        Some((name, spec)) => Some(learnable(
            &model,
            samples,
            &splits,
            &current,
            name,
            spec,
            &selection(&model, given, params),
        )?),
        None => None,
    };
    let report = DiagnosisReport {
        n_samples: samples.len(),
        folds: params.folds,
        initial,
        initial_residuals,
        final_model: FinalModel {
            effects: steps.iter().map(|s| s.label.clone()).collect(),
            heldout: ErrorStats::from_errors(&current),
            residuals: describe_residuals(&fitted, samples, &current),
            ranking: last_ranking,
        },
        steps,
        learnable_residual,
        heldout_norms_mm,
    };
    Ok(Diagnosis { robot: fitted, report })
}

/// Every candidate the error-model plugins offer for `robot`, in registry order.
fn offers(robot: &Robot, plugins: &[PluginInfo]) -> Vec<Offer> {
    plugins
        .iter()
        .filter(|p| p.role == Role::ErrorModel && p.diagnosis_candidate)
        .filter_map(|p| p.candidates.map(|f| (p.type_name, f)))
        .flat_map(|(effect, f)| f(robot).into_iter().map(move |candidate| Offer { effect, candidate }))
        .collect()
}

/// `model` with the offered effect added.
fn with_effect(model: &Robot, offer: &Offer) -> Result<Robot> {
    let spec: Box<dyn ErrorModelSpec> = serde_json::from_value(offer.candidate.spec.clone()).map_err(|e| {
        Error::Input(format!(
            "the `{}` plugin offered a candidate spec it cannot read ({}): {e}",
            offer.effect, offer.candidate.label
        ))
    })?;
    let mut file = model.to_file();
    file.error_models.push(spec);
    model.rebuild(file)
}

/// The calibration settings for `model`: the caller's selection plus, when the caller names
/// one, the parameters of the effects the diagnosis added after the `given` models of the
/// robot file (those are always identified; an empty selection already includes them).
fn selection(model: &Robot, given: usize, params: &DiagnoseParams) -> CalibrationParams {
    let mut out = params.calibration.clone();
    if !out.identify.is_empty() {
        let added = model.error_models().iter().skip(given);
        out.identify
            .extend(added.flat_map(|m| m.params().iter().map(|p| p.name.clone())));
    }
    out
}

/// Held-out RMS for ranking; candidates that could not be evaluated go last.
fn rank_key(c: &RankedCandidate) -> f64 {
    c.heldout.map_or(f64::INFINITY, |s| s.rms_mm)
}

/// Held-out errors per sample (m): each fold's calibration scored on the poses it held out.
fn heldout_errors(
    model: &Robot,
    samples: &[Sample],
    splits: &[Split],
    calibration: &CalibrationParams,
) -> Result<Vec<Vector3<f64>>> {
    let mut errors = vec![Vector3::zeros(); samples.len()];
    for split in splits {
        let fit = calibrate(model, &subset(samples, &split.train), calibration, &mut |_| {})?;
        for (&i, e) in split
            .test
            .iter()
            .zip(position_errors(&fit.robot, &subset(samples, &split.test)))
        {
            errors[i] = e;
        }
    }
    Ok(errors)
}

fn sse(errors: &[Vector3<f64>]) -> f64 {
    errors.iter().map(|e| e.norm_squared()).sum()
}

fn norms_mm(errors: &[Vector3<f64>]) -> Vec<f64> {
    errors.iter().map(|e| e.norm() * 1e3).collect()
}

/// Adds the offered effect to `model_file`, scores it by k-fold and applies the acceptance rule
/// against the held-out errors `current` of the model without it.
fn score(
    model: &Robot,
    given: usize,
    offer: &Offer,
    samples: &[Sample],
    splits: &[Split],
    current: &[Vector3<f64>],
    params: &DiagnoseParams,
) -> RankedCandidate {
    let mut out = RankedCandidate {
        effect: offer.effect.to_string(),
        location: offer.candidate.location.clone(),
        label: offer.candidate.label.clone(),
        n_params: 0,
        heldout: None,
        share_removed: 0.0,
        earns_parameters: false,
        error: None,
        heldout_errors: Vec::new(),
    };
    let evaluated = (|| {
        let model = with_effect(model, offer)?;
        let n_params = model.error_models().last().map_or(0, |m| m.params().len());
        let calibration = selection(&model, given, params);
        Ok::<_, Error>((n_params, heldout_errors(&model, samples, splits, &calibration)?))
    })();
    match evaluated {
        Err(e) => out.error = Some(e.to_string()),
        Ok((n_params, errors)) => {
            let (sse0, sse1) = (sse(current), sse(&errors));
            let n = 3.0 * samples.len() as f64;
            out.n_params = n_params;
            out.share_removed = 1.0 - (sse1 / sse0).sqrt();
            out.earns_parameters =
                out.share_removed >= params.min_rms_reduction && n * (sse0 / sse1).ln() > n_params as f64 * n.ln();
            out.heldout = Some(ErrorStats::from_errors(&errors));
            out.heldout_errors = errors;
        }
    }
    out
}

/// Name, quantity and identified value (SI) of each parameter of the last error model.
fn new_model_values(robot: &Robot) -> Vec<(String, Quantity, f64)> {
    match (robot.error_models().last(), robot.error_values().last()) {
        (Some(m), Some(values)) => m
            .params()
            .iter()
            .zip(values)
            .map(|(p, v)| (p.name.clone(), p.quantity, *v))
            .collect(),
        _ => Vec::new(),
    }
}

/// A value in the unit a field engineer reads it in: mm, degrees, or SI in scientific notation.
pub fn readable(quantity: Quantity, value: f64) -> String {
    match quantity {
        Quantity::Length => format!("{:.3} mm", value * 1e3),
        Quantity::Angle => format!("{:.4} deg", value.to_degrees()),
        Quantity::Dimensionless => format!("{value:.4}"),
        Quantity::Mass => format!("{value:.3} kg"),
        q => format!("{value:.3e} {}", q.si_unit()),
    }
}

/// Fits `spec` to each fold's training residuals of `model` (joint values in, residual
/// position out) and scores the corrected held-out errors against `current`.
fn learnable(
    model: &Robot,
    samples: &[Sample],
    splits: &[Split],
    current: &[Vector3<f64>],
    name: &str,
    spec: &dyn PredictorSpec,
    calibration: &CalibrationParams,
) -> Result<LearnableResidual> {
    let nq = model.tree().nq();
    let mut corrected = current.to_vec();
    for split in splits {
        let train = subset(samples, &split.train);
        let fit = calibrate(model, &train, calibration, &mut |_| {})?;
        let residuals = position_errors(&fit.robot, &train);
        let inputs: Vec<f64> = train.iter().flat_map(|s| s.q.iter().copied()).collect();
        let targets: Vec<f64> = residuals.iter().flat_map(|r| r.iter().copied()).collect();
        let predictor = spec.fit(&TrainingSet {
            inputs: &inputs,
            targets: &targets,
            n_inputs: nq,
            n_outputs: 3,
        })?;
        let (mut out, mut scratch) = ([0.0; 3], Vec::new());
        for &i in &split.test {
            predictor.predict_into(&samples[i].q, &mut out, &mut scratch);
            corrected[i] -= Vector3::from(out);
        }
    }
    let before = ErrorStats::from_errors(current);
    let after = ErrorStats::from_errors(&corrected);
    Ok(LearnableResidual {
        predictor: name.to_string(),
        heldout_before: before,
        heldout_after: after,
        share_learnable: 1.0 - after.rms_mm / before.rms_mm,
    })
}
