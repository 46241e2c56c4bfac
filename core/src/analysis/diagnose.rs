//! Diagnosis: which physical effect is the model missing?
//!
//! The current model is calibrated on the training folds of a k-fold split by pose (by station
//! for data from several, each held-out station registered before it is scored) and scored
//! on the poses each fold holds out. Every candidate effect the registry can instantiate on the
//! robot (per joint, per link or once) is added in turn, calibrated together with everything
//! the model already identifies, and scored the same way.
//!
//! A candidate's `k` is the number of its parameters the calibration determines (the most over
//! the folds): a parameter that moves no measured position, like the tilt of a joint about the
//! vertical, which gravity never loads, is found undeterminable and fixed by the calibration,
//! and costs nothing. Candidates are ranked by the held-out BIC
//! `n·ln(SSE/n) + k·ln n` (`n` scalar residuals, SSE pooled over the held-out poses), so of two
//! candidates that explain the data equally well the one needing fewer parameters comes
//! first. The best is accepted when it *earns its parameters*:
//!
//! - it removes at least [`DiagnoseParams::min_rms_reduction`] (5 % by default) of the pooled
//!   held-out error that lies above the noise floor (the RMS the calibration's noise alone
//!   gives): held-out scores already punish over-fitting, but a gain of a few percent is within
//!   what the choice of folds moves a score by on a hundred poses, so it is not evidence of a
//!   missing effect; judged against the total, a model close to the floor could never name
//!   the effect that takes it there;
//! - and the held-out Gaussian log-likelihood gain `n·ln(SSE₀/SSE₁)` exceeds the BIC penalty
//!   `k·ln n`, so that a candidate with many parameters needs a proportionally larger gain;
//! - and its calibrations moved it: a candidate left at its neutral value (within
//!   [`NEUTRAL_Z`] standard deviations), on a bound or fixed in most folds did nothing itself,
//!   whatever its fit gained (a re-calibration that escaped a local minimum, say), so it is
//!   never named;
//! - and its values are physically plausible in most folds ([`crate::model::param::ParamInfo::plausible`]):
//!   an encoder eccentricity of degrees or a compliance that bends the arm by centimetres
//!   explains the data with values no real robot has.
//!
//! Every candidate carries its `verdict`, the first of these reasons that applies, in words.
//!
//! Some effects are indistinguishable from tool positions on a given robot: on the rock drill,
//! torsion of the short swing link turns the boom's pivot about the swing's axis in proportion
//! to the moment about it, which is exactly a lateral compliance of joint j2; a transmission
//! scale and an encoder eccentricity look alike over a joint's small range. The accepted
//! step therefore lists the candidates the data cannot tell from it: those whose held-out
//! squared errors do not differ from the winner's significantly (paired over the poses, less
//! than [`TIE_Z`] standard errors). The engineer reads "joint j2 lateral compliance; the data
//! cannot tell it from swing link bending" rather than a choice the noise made.
//!
//! The accepted effect joins the model and the search repeats until no candidate earns its
//! parameters or [`DiagnoseParams::max_steps`] is reached. Finally a residual predictor is fitted
//! to what is left, fold by fold, to tell how much of it is unexplained but learnable.
//!
//! Every fold calibration starts from the robot file as given plus the accepted effects at
//! their neutral values, so no held-out pose ever influences a fold's start.
//!
//! Gross errors (a marker seen through a broken line of sight) would pull every fit and
//! dominate every held-out score, hiding the effect the other samples show: when the final
//! model, fitted to all the samples, leaves some beyond [`crate::calibrate::GROSS_ERROR`]
//! robust noises, they are listed and the search is made again without them
//! ([`DiagnoseParams::exclude_gross_errors`]). (The model as given cannot tell them: a missing
//! effect's largest residuals lie that far above its median one.) A residual of the model as
//! given that drifts with the sample order is reported as a drift of the instrument.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};

use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;

use crate::algorithms::evaluate::{ErrorStats, model_errors, position_errors};
use crate::algorithms::residuals::{ResidualDescription, describe_residuals};
use crate::analysis::held_out::{held_out_errors, measures_positions};
use crate::calibrate::{
    CalibrationParams, Drift, Outlier, ParamResult, calibrate, register_held_out_stations, score_test,
};
use crate::data::measurement::Sample;
use crate::data::split::{FoldBy, Split, subset};
use crate::error::{Error, Result};
use crate::model::param::Quantity;
use crate::plugin::{ErrorModelSpec, FitControl, PredictorSpec, TrainingSet};
use crate::robot::Robot;
use crate::robot::candidate::Candidate;
use crate::robot::registry::PluginInfo;
use crate::role::Role;

/// Paired z-score of the held-out squared errors below which a candidate counts as explaining
/// the data as well as the accepted one (about 95 % two-sided).
pub const TIE_Z: f64 = 2.0;

/// A candidate's parameter within this many standard deviations of its neutral value counts
/// as not identified away from it.
pub const NEUTRAL_Z: f64 = 2.0;

/// A candidate is refitted (k-fold) only when the score test at the current fit predicts it
/// removes at least this share of [`DiagnoseParams::min_rms_reduction`] of the training RMS,
/// or it is among the [`MIN_REFITS`] the test ranks first. A held-out gain is smaller than the
/// training gain it comes from, and the first-order prediction of the effects offered (linear
/// in their parameters at the neutral value) is close to the refit's, so the margin of two
/// keeps every candidate that can earn its place.
pub const SCREEN_SHARE: f64 = 0.5;

/// The candidates the score test ranks first are refitted whatever it predicts, so that every
/// round reports held-out scores of its best few.
pub const MIN_REFITS: usize = 3;

/// Settings of [`diagnose`].
#[derive(Debug, Clone, PartialEq)]
pub struct DiagnoseParams {
    /// Number of folds of the held-out score (split by pose, or by station for data from
    /// several: at most one fold per station).
    pub folds: usize,
    /// Seed of the split.
    pub seed: u64,
    /// Settings of every calibration (what to identify, noise, iterations).
    pub calibration: CalibrationParams,
    /// Smallest relative reduction of the held-out RMS that counts as an improvement.
    pub min_rms_reduction: f64,
    /// Most effects added.
    pub max_steps: usize,
    /// Refit every candidate, not only those the score test says can win (see
    /// [`SCREEN_SHARE`]): for checking the screening, at many times the cost.
    pub exhaustive: bool,
    /// Hold out whole groups in each fold: a name (a CSV column) and each sample's group;
    /// `None` folds by station for data from several, else by pose.
    pub fold_groups: Option<(String, Vec<usize>)>,
    /// Search again without the samples that the final model, fitted to all of them, leaves
    /// far beyond the noise (see [`crate::calibrate::gross_errors`]); they are listed in
    /// [`DiagnosisReport::gross_errors`] either way.
    pub exclude_gross_errors: bool,
}

impl Default for DiagnoseParams {
    fn default() -> Self {
        DiagnoseParams {
            folds: 3,
            seed: 0,
            calibration: CalibrationParams::default(),
            min_rms_reduction: 0.05,
            max_steps: 5,
            exhaustive: false,
            fold_groups: None,
            exclude_gross_errors: true,
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
    /// Of these, the ones the calibration determines (see the module documentation).
    pub identified_params: usize,
    /// Held-out errors with it added (pooled over the folds), when it could be evaluated.
    pub heldout: Option<ErrorStats>,
    /// Held-out BIC `n·ln(SSE/n) + k·ln n` (SSE in mm²), the ranking key; lower is better.
    pub heldout_bic: f64,
    /// Share of the held-out RMS before the round that it removes (negative when worse).
    pub share_removed: f64,
    /// Share of the held-out error above the noise floor (the RMS the calibration's noise
    /// alone gives, `√3 σ`) that it removes: `1 − √((MSE₁ − f)/(MSE₀ − f))` with the floor's
    /// mean square `f`, what the acceptance rule judges. The total share when the model
    /// before already reaches the floor, or for contacts.
    pub share_above_floor: f64,
    /// Share of the training RMS the score test at the current fit predicts it removes (see
    /// [`crate::calibrate::score_test`]); `None` when the test could not be computed.
    pub predicted_share: Option<f64>,
    /// Whether it was refitted and scored on held-out folds; a candidate the score test shows
    /// cannot earn its place is not (its `verdict` says so).
    pub refitted: bool,
    /// Whether its calibrations left it where it started (every parameter within
    /// [`NEUTRAL_Z`] standard deviations of its neutral value, on a bound, or fixed) in most
    /// folds: the effect itself did nothing, so whatever its fit gained came from elsewhere
    /// (another minimum, other parameters) and it cannot be named. Never for an effect that
    /// acts at its starting values (a measured tilt turning the chain by the readings).
    pub at_neutral: bool,
    /// Whether its calibrations needed values outside the range its model calls physically
    /// plausible (an eccentricity of degrees, a compliance that bends the arm by centimetres)
    /// in most folds: it explains the data with values no real robot has, so it is not named.
    pub implausible_values: bool,
    /// Whether it passes the acceptance rule (see the module documentation).
    pub earns_parameters: bool,
    /// Why it does or does not earn its parameters, the first reason that applies: left at
    /// its neutral value, implausible values, too small a gain, or a gain below the BIC
    /// penalty.
    pub verdict: String,
    /// Whether the data cannot tell it from the best candidate of the round (paired z-score of
    /// the held-out squared errors below [`TIE_Z`]); false for the best itself.
    pub indistinguishable_from_best: bool,
    /// Why it could not be evaluated.
    pub error: Option<String>,
    /// Held-out errors per sample and fold ranks, for ties and the next round.
    #[serde(skip)]
    evaluation: Option<Heldout>,
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
    /// Other candidates that explain the data as well (labels), which the data cannot tell
    /// from this one; it comes first by needing fewer parameters or by a margin within noise.
    pub equivalent: Vec<String>,
    /// Every candidate of the round, best first.
    pub ranking: Vec<RankedCandidate>,
    /// Its values outside the range the model calls physically plausible, in words: the
    /// effect explains the data, but not with values a real robot has; likely another effect
    /// (or a wrong declared quantity, such as a payload's mass) acts through the same motion.
    pub implausible: Vec<String>,
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

/// One kind of row's held-out RMS in data of several kinds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct KindHeldout {
    /// What its rows are scored by: `position`, `plane height` or `fixed-point distance`.
    pub kind: String,
    /// Its rows.
    pub n: usize,
    /// Held-out RMS of the model as given (mm).
    pub before_rms_mm: f64,
    /// Held-out RMS of the final model (mm).
    pub after_rms_mm: f64,
}

/// Each kind's held-out RMS in `norms` (mm per sample, the model as given first, the final
/// model last), when `samples` are of several kinds.
fn per_kind(samples: &[Sample], norms: &[Vec<f64>]) -> Vec<KindHeldout> {
    let kinds = crate::analysis::held_out::kinds(samples);
    let (Some(first), Some(last)) = (norms.first(), norms.last()) else {
        return Vec::new();
    };
    if kinds.len() < 2 {
        return Vec::new();
    }
    kinds
        .into_iter()
        .map(|kind| {
            let rows: Vec<usize> = (0..samples.len())
                .filter(|&i| crate::analysis::held_out::kind_of(&samples[i]) == kind)
                .collect();
            let rms = |v: &[f64]| (rows.iter().map(|&i| v[i] * v[i]).sum::<f64>() / rows.len() as f64).sqrt();
            KindHeldout {
                kind: kind.to_string(),
                n: rows.len(),
                before_rms_mm: rms(first),
                after_rms_mm: rms(last),
            }
        })
        .collect()
}

/// What the diagnosis found.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DiagnosisReport {
    /// Rows used (those given, less the gross errors left out).
    pub n_samples: usize,
    /// What a held-out row's error is ([`held_out::scored_by`](crate::analysis::held_out::scored_by)):
    /// `position`, `plane height`, `fixed-point distance`, `+`-joined for mixed data.
    pub scored_by: String,
    /// The samples (indices into those given) that the final model of a search on all of
    /// them, fitted to all of them, leaves far beyond the noise, largest first; the search was
    /// made again without them when [`DiagnoseParams::exclude_gross_errors`].
    pub gross_errors: Vec<Outlier>,
    /// Whether the search was made again without the gross errors.
    pub gross_errors_excluded: bool,
    /// A residual of the model as given that changes steadily with the sample order: an
    /// instrument drifting over the session (or poses measured in workspace order), which no
    /// effect of the robot explains.
    pub drift: Option<Drift>,
    /// Folds of the held-out score.
    pub folds: usize,
    /// What each fold held out together: `pose`, or `station` for data from several.
    pub grouped_by: String,
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
    /// Held-out error norms (mm) per sample used of the initial model and after each step.
    #[serde(skip)]
    pub heldout_norms_mm: Vec<Vec<f64>>,
    /// Data of several kinds (positions, plane contacts, fixed points): each kind's held-out
    /// RMS before and after, since one pooled figure mixes 3-D errors with heights or
    /// distances. Empty for one kind.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub per_kind: Vec<KindHeldout>,
    /// Whether a stop request ([`CalibrationParams::cancel`]) ended the search early: the steps are
    /// those accepted before it, the round it interrupted is dropped.
    pub interrupted: bool,
}

/// What [`diagnose`] is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DiagnoseStage {
    /// Scoring the model as given on the folds.
    Baseline,
    /// Searching for the n-th effect (1-based): the candidates the score test keeps, refitted
    /// on the folds.
    Round(usize),
    /// Scoring what a residual predictor learns of the rest.
    Learnable,
}

/// Progress of [`diagnose`]: fold calibrations done of those the stage needs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DiagnoseProgress {
    /// The stage.
    pub stage: DiagnoseStage,
    /// Fold calibrations done.
    pub done: usize,
    /// Fold calibrations the stage needs.
    pub total: usize,
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
/// `samples`; `predictor` (its type name and spec) learns what remains. `progress` hears of
/// every fold calibration. A stop request ([`CalibrationParams::cancel`]) after the model as given is
/// scored ends the search with the effects found so far (the report says it was interrupted).
pub fn diagnose(
    robot: &Robot,
    samples: &[Sample],
    plugins: &[PluginInfo],
    predictor: Option<(&str, &dyn PredictorSpec)>,
    params: &DiagnoseParams,
    progress: &(dyn Fn(DiagnoseProgress) + Sync),
) -> Result<Diagnosis> {
    if !(params.min_rms_reduction.is_finite() && (0.0..1.0).contains(&params.min_rms_reduction)) {
        return Err(Error::InvalidArgument {
            what: "smallest RMS reduction".into(),
            reason: format!("must be between 0 and 1, got {}", params.min_rms_reduction),
        });
    }
    let first = search(
        robot,
        samples,
        params.fold_groups.clone(),
        plugins,
        predictor,
        params,
        progress,
    )?;
    let mut diagnosis = first.diagnosis;
    // Gross errors are those the final model leaves: a missing effect's largest residuals
    // under the model as given are no gross errors, and once explained they are not flagged.
    let gross_errors = first.gross_errors;
    let exclude = params.exclude_gross_errors && !gross_errors.is_empty() && !diagnosis.report.interrupted;
    if exclude {
        let keep: Vec<usize> = (0..samples.len())
            .filter(|i| !gross_errors.iter().any(|o| o.sample == *i))
            .collect();
        let groups = params
            .fold_groups
            .clone()
            .map(|(name, g)| (name, keep.iter().map(|&i| g[i]).collect()));
        diagnosis = search(
            robot,
            &subset(samples, &keep),
            groups,
            plugins,
            predictor,
            params,
            progress,
        )?
        .diagnosis;
    }
    diagnosis.report.gross_errors = gross_errors;
    diagnosis.report.gross_errors_excluded = exclude;
    diagnosis.report.drift = first.drift;
    Ok(diagnosis)
}

/// A search of [`diagnose`] and what it saw of the samples.
struct Searched {
    diagnosis: Diagnosis,
    /// The samples the final model, fitted to all of them, leaves far beyond the noise.
    gross_errors: Vec<Outlier>,
    /// A drift of the model as given's residuals over the sample order.
    drift: Option<Drift>,
}

/// The search of [`diagnose`] on `samples`, folds grouped by `fold_groups`.
fn search(
    robot: &Robot,
    samples: &[Sample],
    fold_groups: Option<(String, Vec<usize>)>,
    plugins: &[PluginInfo],
    predictor: Option<(&str, &dyn PredictorSpec)>,
    params: &DiagnoseParams,
    progress: &(dyn Fn(DiagnoseProgress) + Sync),
) -> Result<Searched> {
    let model = robot.rebuild(robot.to_file())?;
    let (splits, folding) = crate::data::split::folds(
        samples,
        params.folds,
        params.seed,
        &FoldBy::choose(samples, fold_groups),
    )?;
    let s = Search {
        samples,
        splits,
        given: robot.error_models().len(),
        floor: if samples
            .iter()
            .all(|s| s.kind() == crate::data::measurement::SampleKind::Position)
        {
            3.0 * params.calibration.measurement_std.powi(2)
        } else {
            0.0
        },
        params,
        progress,
    };
    let (mut found, drift) = Found::start(&s, model)?;
    let initial = ErrorStats::from_errors(&found.current.errors);
    let initial_residuals = describe_residuals(robot, samples, &found.current.errors);
    let mut last_ranking = Vec::new();
    let mut interrupted = false;
    while found.steps.len() < params.max_steps {
        let (offers, mut ranking) = s.round(&found, plugins);
        // A stopped calibration fails its candidate; the round is not worth ranking.
        if params.calibration.cancel.is_cancelled() {
            interrupted = true;
            break;
        }
        rank(&mut ranking);
        let Some(best) = ranking.first().filter(|c| c.earns_parameters).cloned() else {
            last_ranking = ranking;
            break;
        };
        found.accept(&s, best, ranking, &offers)?;
    }
    let Found {
        model,
        fitted,
        gross_errors,
        current,
        heldout_norms_mm,
        steps,
    } = found;
    let current = current.errors;
    let learnable_residual = s.learnable_residual(&model, &current, predictor, &mut interrupted)?;
    let report = DiagnosisReport {
        scored_by: crate::analysis::held_out::scored_by(samples),
        n_samples: samples.len(),
        gross_errors: Vec::new(),
        gross_errors_excluded: false,
        drift: None,
        folds: folding.folds,
        grouped_by: folding.grouped_by,
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
        per_kind: per_kind(samples, &heldout_norms_mm),
        heldout_norms_mm,
        interrupted,
    };
    Ok(Searched {
        diagnosis: Diagnosis { robot: fitted, report },
        gross_errors,
        drift,
    })
}

/// Where a search stands after the effects it accepted so far.
struct Found {
    /// The robot as given plus the accepted effects at their neutral values (where every fold
    /// calibration starts).
    model: Robot,
    /// `model` fitted to all the samples.
    fitted: Robot,
    /// The samples `fitted` leaves far beyond the noise.
    gross_errors: Vec<Outlier>,
    /// `model`'s held-out evaluation.
    current: Heldout,
    /// Held-out error norms (mm) per sample of the model as given and after each step.
    heldout_norms_mm: Vec<Vec<f64>>,
    steps: Vec<DiagnosisStep>,
}

impl Found {
    /// The start: `model`, the robot as given, scored on the folds and fitted to all the
    /// samples; and the drift of its residuals.
    fn start(s: &Search<'_>, model: Robot) -> Result<(Found, Option<Drift>)> {
        let current = s.heldout(
            &model,
            &s.params.calibration,
            &s.counter(DiagnoseStage::Baseline, s.splits.len()),
        )?;
        let first = calibrate(&model, s.samples, &s.selection(&model), &mut |_| {})?;
        let found = Found {
            heldout_norms_mm: vec![norms_mm(&current.errors)],
            fitted: first.robot,
            gross_errors: first.report.outliers,
            model,
            current,
            steps: Vec::new(),
        };
        Ok((found, first.report.drift))
    }

    /// Accepts `best`, the first of the round's `ranking` of `offers`: the effect joins the
    /// model, which is fitted again to all the samples, and the step is recorded.
    fn accept(
        &mut self,
        s: &Search<'_>,
        best: RankedCandidate,
        ranking: Vec<RankedCandidate>,
        offers: &[Offer],
    ) -> Result<()> {
        let offer = offers
            .iter()
            .find(|o| o.effect == best.effect && o.candidate.location == best.location)
            .expect("the ranking is made of the offers");
        self.model = with_effect(&self.model, offer)?;
        let fit = calibrate(&self.model, s.samples, &s.selection(&self.model), &mut |_| {})?;
        (self.fitted, self.gross_errors) = (fit.robot, fit.report.outliers);
        self.steps
            .push(accepted_step(&best, ranking, &self.fitted, &self.current));
        self.current = best.evaluation.expect("an accepted candidate was evaluated");
        self.heldout_norms_mm.push(norms_mm(&self.current.errors));
        Ok(())
    }
}

/// What every calibration of one search shares: the samples and their folds, how many error
/// models the robot file gives (the search adds its effects after them), the settings, and
/// where progress goes.
struct Search<'a> {
    samples: &'a [Sample],
    splits: Vec<Split>,
    given: usize,
    /// The mean squared held-out error per sample the noise alone gives (`3σ²`, m²) for
    /// measured positions; 0 for contacts, whose held-out errors are not 3-D tracker errors.
    floor: f64,
    params: &'a DiagnoseParams,
    progress: &'a (dyn Fn(DiagnoseProgress) + Sync),
}

impl Search<'_> {
    /// A counter of the stage's `total` fold calibrations that reports each.
    fn counter(&self, stage: DiagnoseStage, total: usize) -> impl Fn() + Sync + '_ {
        let progress = self.progress;
        progress(DiagnoseProgress { stage, done: 0, total });
        let done = AtomicUsize::new(0);
        move || {
            let done = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress(DiagnoseProgress { stage, done, total });
        }
    }

    /// One round's candidates: every effect not accepted yet offered for the current fit,
    /// those the score test keeps refitted on the folds and scored against the current
    /// held-out evaluation, the others screened out. Unranked.
    fn round(&self, found: &Found, plugins: &[PluginInfo]) -> (Vec<Offer>, Vec<RankedCandidate>) {
        let Found {
            model,
            fitted,
            current,
            steps,
            ..
        } = found;
        let offers: Vec<Offer> = offers(fitted, plugins)
            .into_iter()
            .filter(|o| {
                !steps
                    .iter()
                    .any(|s| s.effect == o.effect && s.location == o.candidate.location)
                    && !duplicates_a_parameter(fitted, o)
            })
            .collect();
        let predicted: Vec<Option<f64>> = offers.par_iter().map(|o| self.predicted_share(fitted, o)).collect();
        let refit = to_refit(&predicted, self.params);
        let tick = self.counter(
            DiagnoseStage::Round(steps.len() + 1),
            refit.iter().filter(|&&r| r).count() * self.splits.len(),
        );
        let ranking = offers
            .par_iter()
            .zip(&predicted)
            .zip(&refit)
            .map(|((o, &p), &r)| {
                if r {
                    self.score(model, o, p, current, &tick)
                } else {
                    screened_out(o, p, self.params)
                }
            })
            .collect();
        (offers, ranking)
    }

    /// The calibration settings for `model`: the caller's selection plus, when the caller names
    /// one, the parameters of the effects the diagnosis added after the models of the robot
    /// file (those are always identified; an empty selection already includes them).
    fn selection(&self, model: &Robot) -> CalibrationParams {
        let mut out = self.params.calibration.clone();
        // A candidate with a multimodal parameter is restarted from other values of it, converged
        // or not; the geometry stays where the fit ended, so a candidate gains from the minima of
        // its own parameters only, and fits without such a parameter need no restart.
        out.restart_moves = crate::calibrate::RestartMoves::Multimodal;
        if !out.identify.is_empty() {
            let added = model.error_models().iter().skip(self.given);
            out.identify
                .extend(added.flat_map(|m| m.params().iter().map(|p| p.name.clone())));
        }
        out
    }

    /// Calibrates `model` on each fold's training poses and scores it on the poses held out.
    /// `tick` hears of each fold's calibration.
    fn heldout(&self, model: &Robot, calibration: &CalibrationParams, tick: &(dyn Fn() + Sync)) -> Result<Heldout> {
        let samples = self.samples;
        let mut errors = vec![Vector3::zeros(); samples.len()];
        let mut fixed = Vec::with_capacity(self.splits.len());
        let mut params = Vec::with_capacity(self.splits.len());
        for split in &self.splits {
            let train = subset(samples, &split.train);
            let test = subset(samples, &split.test);
            let mut fit = calibrate(model, &train, calibration, &mut |_| {})?;
            register_held_out_stations(&mut fit.robot, &train, &test)?;
            tick();
            fixed.push(
                fit.report
                    .params
                    .iter()
                    .filter(|p| p.fixed)
                    .map(|p| p.name.clone())
                    .collect(),
            );
            // A sample its fold cannot score (a plane or fixed point no training row touched)
            // counts as no error for every model alike, so it moves no comparison.
            for (&i, e) in split.test.iter().zip(held_out_errors(&fit.robot, &train, &test)?) {
                errors[i] = e.unwrap_or_else(Vector3::zeros);
            }
            params.push(fit.report.params);
        }
        Ok(Heldout { errors, fixed, params })
    }

    /// The share of the training RMS that the offered effect, added to `fitted` (the current
    /// model fitted to all the samples) at its starting value, is predicted to remove by the
    /// score test.
    fn predicted_share(&self, fitted: &Robot, offer: &Offer) -> Option<f64> {
        let model = with_effect(fitted, offer).ok()?;
        // The score test linearises at the current fit. An effect that moves the model already
        // at its starting values starts elsewhere: it cannot be assessed so, and is refitted.
        if acts_at_start(fitted, &model, self.samples) {
            return None;
        }
        let added = added_params(&model);
        score_test(&model, self.samples, &self.selection(&model), &added)
            .ok()
            .map(|t| t.predicted_share())
    }

    /// Adds the offered effect to `model`, scores it by k-fold and applies the acceptance rule
    /// against the held-out evaluation `current` of the model without it.
    fn score(
        &self,
        model: &Robot,
        offer: &Offer,
        predicted_share: Option<f64>,
        current: &Heldout,
        tick: &(dyn Fn() + Sync),
    ) -> RankedCandidate {
        let mut out = unscored(offer, predicted_share);
        out.refitted = true;
        let evaluated = (|| {
            let candidate = with_effect(model, offer)?;
            let names = added_params(&candidate);
            let acts = acts_at_start(model, &candidate, self.samples);
            Ok::<_, Error>((
                names,
                acts,
                self.heldout(&candidate, &self.selection(&candidate), tick)?,
            ))
        })();
        match evaluated {
            Err(e) => out.error = Some(e.to_string()),
            Ok((names, acts, evaluation)) => {
                judge(&mut out, &names, acts, evaluation, current, self.floor, self.params)
            }
        }
        out
    }

    /// What `predictor` learns of the final residuals `current` of `model`; none without a
    /// predictor or after a stop request, which `interrupted` records when it comes during
    /// the predictor's fits.
    fn learnable_residual(
        &self,
        model: &Robot,
        current: &[Vector3<f64>],
        predictor: Option<(&str, &dyn PredictorSpec)>,
        interrupted: &mut bool,
    ) -> Result<Option<LearnableResidual>> {
        // A residual predictor learns 3-D errors, which fixed-point and plane rows do not give.
        Ok(
            match predictor.filter(|_| !*interrupted && measures_positions(self.samples)) {
                Some((name, spec)) => match self.learnable(model, current, name, spec) {
                    Err(Error::Interrupted) => {
                        *interrupted = true;
                        None
                    }
                    other => Some(other?),
                },
                None => None,
            },
        )
    }

    /// Fits `spec` (named `name`) to each fold's training residuals of `model` (joint values
    /// in, residual position out) and scores the corrected held-out errors against `current`.
    fn learnable(
        &self,
        model: &Robot,
        current: &[Vector3<f64>],
        name: &str,
        spec: &dyn PredictorSpec,
    ) -> Result<LearnableResidual> {
        let (samples, calibration) = (self.samples, self.selection(model));
        let tick = self.counter(DiagnoseStage::Learnable, self.splits.len());
        let nq = model.tree().nq();
        let mut corrected = current.to_vec();
        for split in &self.splits {
            let train = subset(samples, &split.train);
            let fit = calibrate(model, &train, &calibration, &mut |_| {})?;
            tick();
            let residuals = position_errors(&fit.robot, &train);
            let inputs: Vec<f64> = train.iter().flat_map(|s| s.q.iter().copied()).collect();
            let targets: Vec<f64> = residuals.iter().flat_map(|r| r.iter().copied()).collect();
            let control = FitControl {
                progress: None,
                cancel: calibration.cancel.clone(),
            };
            let predictor = spec.fit_with(
                &TrainingSet {
                    inputs: &inputs,
                    targets: &targets,
                    n_inputs: nq,
                    n_outputs: 3,
                    input_ranges: model.tree().coordinate_limits(),
                },
                &control,
            )?;
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
}

/// Orders a round's candidates: those that earn their parameters first (one that does not,
/// with implausible values or at its neutral value, is no explanation, however well it
/// scores), then by held-out BIC; and marks those the data cannot tell from the first.
fn rank(ranking: &mut [RankedCandidate]) {
    ranking.sort_by(|a, b| {
        b.earns_parameters
            .cmp(&a.earns_parameters)
            .then_with(|| a.heldout_bic.total_cmp(&b.heldout_bic))
            .then_with(|| rank_key(b).total_cmp(&rank_key(a)))
            .then_with(|| a.label.cmp(&b.label))
    });
    mark_ties(ranking);
}

/// The step that accepts `best`, the first of the round's `ranking`, into the model now
/// fitted to all the samples as `fitted`; `current` is the held-out evaluation before it.
fn accepted_step(
    best: &RankedCandidate,
    ranking: Vec<RankedCandidate>,
    fitted: &Robot,
    current: &Heldout,
) -> DiagnosisStep {
    let equivalent: Vec<String> = ranking
        .iter()
        .filter(|c| c.indistinguishable_from_best)
        .map(|c| c.label.clone())
        .collect();
    let before = ErrorStats::from_errors(&current.errors);
    let after = best.heldout.expect("an accepted candidate was evaluated");
    let values = new_model_values(fitted);
    let implausible: Vec<String> = match (fitted.error_models().last(), fitted.error_values().last()) {
        (Some(m), Some(v)) => m
            .params()
            .iter()
            .zip(v)
            .filter_map(|(p, &v)| p.implausibility(v))
            .collect(),
        _ => Vec::new(),
    };
    let alternatives = if equivalent.is_empty() {
        String::new()
    } else {
        format!("; the data cannot tell it from: {}", equivalent.join(", "))
    };
    let flagged = if implausible.is_empty() {
        String::new()
    } else {
        format!("; implausible: {}", implausible.join("; "))
    };
    DiagnosisStep {
        effect: best.effect.clone(),
        location: best.location.clone(),
        label: best.label.clone(),
        summary: format!(
            "{}, {}: removes {:.0}% of the remaining held-out RMS ({:.3} → {:.3} mm){alternatives}{flagged}",
            best.label,
            values
                .iter()
                .map(|(_, q, v)| q.readable(*v))
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
        equivalent,
        ranking,
        implausible,
    }
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

/// Whether the offered effect would give `model` a parameter it already has (the robot file
/// models that effect there already): such a candidate adds nothing and cannot be built.
fn duplicates_a_parameter(model: &Robot, offer: &Offer) -> bool {
    let Ok(spec) = serde_json::from_value::<Box<dyn ErrorModelSpec>>(offer.candidate.spec.clone()) else {
        return false;
    };
    let Ok(names) = model.error_model_param_names(spec.as_ref()) else {
        return false;
    };
    model
        .error_models()
        .iter()
        .flat_map(|m| m.params())
        .any(|p| names.contains(&p.name))
}

/// `model` with the offered effect added.
fn with_effect(model: &Robot, offer: &Offer) -> Result<Robot> {
    let spec: Box<dyn ErrorModelSpec> =
        serde_json::from_value(offer.candidate.spec.clone()).map_err(|e| Error::InvalidArgument {
            what: format!("the `{}` plugin", offer.effect),
            reason: format!(
                "offered a candidate spec it cannot read ({}): {e}",
                offer.candidate.label
            ),
        })?;
    let mut file = model.to_file();
    file.error_models.push(spec);
    model.rebuild(file)
}

/// Marks the candidates whose held-out squared errors do not differ significantly from those
/// of the first (paired over the poses): the data cannot tell them apart.
fn mark_ties(ranking: &mut [RankedCandidate]) {
    let Some((best, rest)) = ranking.split_first_mut() else {
        return;
    };
    let Some(reference) = &best.evaluation else {
        return;
    };
    for c in rest {
        if let Some(e) = &c.evaluation {
            c.indistinguishable_from_best = paired_z(&reference.errors, &e.errors) < TIE_Z;
        }
    }
}

/// z-score of the mean per-pose difference `|b|² − |a|²` of two sets of held-out errors:
/// how many standard errors `b` is worse than `a` (0 when they agree at every pose).
fn paired_z(a: &[Vector3<f64>], b: &[Vector3<f64>]) -> f64 {
    let d: Vec<f64> = a
        .iter()
        .zip(b)
        .map(|(a, b)| b.norm_squared() - a.norm_squared())
        .collect();
    let n = d.len() as f64;
    if n < 2.0 {
        return 0.0;
    }
    let mean = d.iter().sum::<f64>() / n;
    let var = d.iter().map(|x| (x - mean) * (x - mean)).sum::<f64>() / (n - 1.0);
    let se = (var / n).sqrt();
    if se > 0.0 { mean / se } else { 0.0 }
}

/// Held-out errors of a model and what its calibrations could determine.
#[derive(Debug, Clone, PartialEq)]
struct Heldout {
    /// Per sample (m): each fold's calibration scored on the poses it held out.
    errors: Vec<Vector3<f64>>,
    /// Per fold, the parameters its calibration could not determine and fixed.
    fixed: Vec<Vec<String>>,
    /// Per fold, every identified parameter as the calibration reported it.
    params: Vec<Vec<ParamResult>>,
}

/// Held-out BIC of `k` determined parameters over the scalar residuals of `errors` (in mm).
fn bic(errors: &[Vector3<f64>], k: usize) -> f64 {
    let n = 3.0 * errors.len() as f64;
    n * (sse(errors) * 1e6 / n).ln() + k as f64 * n.ln()
}

fn sse(errors: &[Vector3<f64>]) -> f64 {
    errors.iter().map(|e| e.norm_squared()).sum()
}

fn norms_mm(errors: &[Vector3<f64>]) -> Vec<f64> {
    errors.iter().map(|e| e.norm() * 1e3).collect()
}

/// Which candidates to refit: those the score test gives at least [`SCREEN_SHARE`] of the
/// smallest reduction, the [`MIN_REFITS`] it ranks first, and those it could not assess.
fn to_refit(predicted: &[Option<f64>], params: &DiagnoseParams) -> Vec<bool> {
    if params.exhaustive {
        return vec![true; predicted.len()];
    }
    let key = |p: Option<f64>| p.unwrap_or(f64::INFINITY);
    let mut order: Vec<usize> = (0..predicted.len()).collect();
    order.sort_by(|&a, &b| key(predicted[b]).total_cmp(&key(predicted[a])));
    let top = &order[..order.len().min(MIN_REFITS)];
    predicted
        .iter()
        .enumerate()
        .map(|(i, p)| top.contains(&i) || key(*p) >= SCREEN_SHARE * params.min_rms_reduction)
        .collect()
}

/// Orders candidates with equal held-out scores (those not refitted): larger predicted gains
/// first.
fn rank_key(c: &RankedCandidate) -> f64 {
    c.predicted_share.unwrap_or(f64::NEG_INFINITY)
}

/// A candidate as ranked before any fit: not evaluated, with the score test's prediction.
fn unscored(offer: &Offer, predicted_share: Option<f64>) -> RankedCandidate {
    RankedCandidate {
        effect: offer.effect.to_string(),
        location: offer.candidate.location.clone(),
        label: offer.candidate.label.clone(),
        n_params: 0,
        identified_params: 0,
        heldout: None,
        // Candidates that could not be evaluated go last.
        heldout_bic: f64::INFINITY,
        share_removed: 0.0,
        share_above_floor: 0.0,
        predicted_share,
        refitted: false,
        at_neutral: false,
        implausible_values: false,
        earns_parameters: false,
        verdict: String::new(),
        indistinguishable_from_best: false,
        error: None,
        evaluation: None,
    }
}

/// A candidate the score test shows cannot earn its place, with the reason.
fn screened_out(offer: &Offer, predicted_share: Option<f64>, params: &DiagnoseParams) -> RankedCandidate {
    let mut out = unscored(offer, predicted_share);
    out.verdict = format!(
        "not refitted: the score test at the current fit predicts it removes {:.1}% of the training RMS, where \
         earning its parameters takes {:.0}% of the held-out RMS",
        100.0 * predicted_share.unwrap_or(0.0),
        100.0 * params.min_rms_reduction
    );
    out
}

/// Names of the parameters of `model`'s last error model: the effect just added.
fn added_params(model: &Robot) -> Vec<String> {
    model
        .error_models()
        .last()
        .map_or(Vec::new(), |m| m.params().iter().map(|p| p.name.clone()).collect())
}

/// Whether `with`, a model with an effect added at its starting values, already evaluates
/// `samples` differently from `without`: an effect that acts by the conditions of each row (a
/// measured tilt turning the chain by the readings) rather than by its parameters' values.
fn acts_at_start(without: &Robot, with: &Robot, samples: &[Sample]) -> bool {
    let (before, after) = (model_errors(without, samples), model_errors(with, samples));
    before.iter().zip(&after).any(|(a, b)| (a - b).norm() > 1e-9)
}

/// Applies the acceptance rule to `out`, a candidate whose parameters `names` were refitted
/// to `evaluation`, against the held-out evaluation `current` of the model without it; `floor`
/// is the mean squared held-out error per sample the noise alone gives (m², 0 for none).
/// A candidate that `acts` at its starting values is never at its neutral value.
#[allow(clippy::too_many_arguments)]
fn judge(
    out: &mut RankedCandidate,
    names: &[String],
    acts: bool,
    evaluation: Heldout,
    current: &Heldout,
    floor: f64,
    params: &DiagnoseParams,
) {
    let n_samples = current.errors.len();
    let n_params = names.len();
    let k = evaluation
        .fixed
        .iter()
        .map(|fixed| names.iter().filter(|n| !fixed.contains(n)).count())
        .max()
        .unwrap_or(n_params);
    let (sse0, sse1) = (sse(&current.errors), sse(&evaluation.errors));
    let n = 3.0 * n_samples as f64;
    out.n_params = n_params;
    out.identified_params = k;
    out.share_removed = 1.0 - (sse1 / sse0).sqrt();
    let floor_sse = floor * n_samples as f64;
    out.share_above_floor = if sse0 > floor_sse && floor_sse > 0.0 {
        1.0 - ((sse1 - floor_sse).max(0.0) / (sse0 - floor_sse)).sqrt()
    } else {
        out.share_removed
    };
    let neutral_folds = evaluation
        .params
        .iter()
        .filter(|fold| {
            fold.iter()
                .filter(|p| names.contains(&p.name))
                .all(|p| p.fixed || p.at_bound || (p.value - p.initial).abs() <= NEUTRAL_Z * p.std)
        })
        .count();
    out.at_neutral = !acts && 2 * neutral_folds > evaluation.params.len();
    let implausible_folds = evaluation
        .params
        .iter()
        .filter(|fold| fold.iter().any(|p| names.contains(&p.name) && !p.fixed && !p.plausible))
        .count();
    out.implausible_values = 2 * implausible_folds > evaluation.params.len();
    let (gain, penalty) = (n * (sse0 / sse1).ln(), k as f64 * n.ln());
    out.verdict = verdict(out, gain, penalty, params);
    out.earns_parameters = !out.at_neutral
        && !out.implausible_values
        && out.share_above_floor >= params.min_rms_reduction
        && gain > penalty;
    out.heldout = Some(ErrorStats::from_errors(&evaluation.errors));
    out.heldout_bic = bic(&evaluation.errors, k);
    out.evaluation = Some(evaluation);
}

/// Why the judged candidate `c` does or does not earn its parameters, the first reason that
/// applies; `gain` is its held-out likelihood gain and `penalty` its BIC penalty.
fn verdict(c: &RankedCandidate, gain: f64, penalty: f64, params: &DiagnoseParams) -> String {
    let k = c.identified_params;
    if c.at_neutral {
        format!(
            "its calibrations left it at its neutral value (within {NEUTRAL_Z} standard deviations, on a bound \
             or fixed) in most folds: what its fit gained ({:.0}%) came from the other parameters",
            100.0 * c.share_removed
        )
    } else if c.implausible_values {
        format!(
            "removes {:.0}%, but only with values its model calls physically implausible in most folds",
            100.0 * c.share_removed
        )
    } else if c.share_above_floor < params.min_rms_reduction {
        format!(
            "removes {:.1}% of the held-out RMS above the noise floor, less than the {:.0}% that folds alone can \
             move a score by",
            100.0 * c.share_above_floor,
            100.0 * params.min_rms_reduction
        )
    } else if gain <= penalty {
        format!("its held-out likelihood gain {gain:.1} does not pay its {k} parameter(s) (BIC penalty {penalty:.1})")
    } else {
        format!(
            "earns its parameters: removes {:.0}% of the held-out RMS ({:.0}% of what lies above the noise floor)",
            100.0 * c.share_removed,
            100.0 * c.share_above_floor
        )
    }
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
