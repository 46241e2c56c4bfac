//! Choosing the model from the training rows alone: a grid of candidates — the levels
//! registration → joint offsets → geometry → error models, each under several prior schemes,
//! each with and without a residual predictor — every one scored by the same repeated, grouped
//! cross-validation.
//!
//! Each candidate is fitted on the training part of every outer fold exactly as it will be
//! fitted on all the rows, its own choices (the noise, the evidence's prior scales, the
//! predictor's hyper-parameters) made inside that part, and scored on the fold left out; no
//! choice sees the rows that score it. The folds hold out whole pose groups, or whole groups
//! of a named column (a session, a station), since random folds over clustered poses are
//! optimistic. They are drawn [`LadderParams::repeats`] times with different seeds, and every
//! candidate is scored on the same draws, so two candidates are compared on equal folds and
//! the seeds' spread of their difference measures how far the folds alone move it.
//!
//! The choice is the safest level with a candidate whose score is within that noise of the
//! best (the lowest level without a predictor first, then with a predictor the highest level
//! under it), among those most of whose fold fits
//! converged to physically plausible values; within it, the first prior scheme (the evidence
//! first) whose paired difference from the level's best lies within its standard error over the
//! held-out groups. A candidate that is not sound is chosen only when no sound one is within
//! the noise, and the report says so. Then stacking: when a weighted mean of the level's schemes
//! (weights on the simplex, fitted to their out-of-fold errors) beats that one by more than the
//! standard error of the paired difference, the model is that mean, every parameter the
//! weighted mean of the schemes' values.
//!
//! The expected error is the choice's own cross-validated score: each fold's rows are scored by
//! the choice made from the other folds' rows. The best of many candidates' scores would be
//! optimistic, since the choice among them has seen the rows that score it.

use std::time::Instant;

use nalgebra::{DMatrix, DVector, Vector3, Vector6};
use rayon::prelude::*;
use serde::Serialize;

use crate::algorithms::evaluate::fit_residual_predictor;
use crate::calibrate::evidence::{EvidenceParams, EvidenceReport, Grouping, calibrate_with_evidence};
use crate::calibrate::{Calibration, CalibrationParams, FitsProgress, register_held_out_stations};
use crate::data::measurement::Sample;
use crate::data::split::{FoldBy, Split, subset};
use crate::error::{Error, Result};
use crate::plugin::{FitControl, PredictorSpec};
use crate::robot::Robot;
use crate::robot::robot_file::{FitRecord, RobotFile};
use crate::support::cancel::Cancel;

/// A physical level of the ladder: what is identified.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
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
}

impl Rung {
    /// What the rung identifies, as `--identify` words.
    pub fn identify(self) -> &'static [&'static str] {
        match self {
            Rung::Registration => &["base", "markers"],
            Rung::JointOffsets => &["base", "markers", "offsets"],
            Rung::Geometry => &["base", "markers", "geometry"],
            Rung::ErrorModels => &["base", "markers", "geometry", "errors"],
        }
    }

    /// Its name in reports.
    pub fn label(self) -> &'static str {
        match self {
            Rung::Registration => "registration",
            Rung::JointOffsets => "joint offsets",
            Rung::Geometry => "geometry",
            Rung::ErrorModels => "geometry + error models",
        }
    }
}

/// How a candidate holds its parameters towards the robot file's values.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PriorScheme {
    /// The file's priors with scales chosen by the evidence (one per parameter of the chain, or
    /// one per group of parameters), the noise estimated with them.
    Evidence(Grouping),
    /// The file's prior standard deviations times this factor.
    File(f64),
    /// No priors: every direction the data cannot determine is fixed (the base parameters a
    /// QR decomposition of the Jacobian keeps), the rest fitted freely.
    None,
}

impl PriorScheme {
    /// Its name in reports: `evidence per parameter`, `evidence per group`, `file ×0.3`, `no
    /// priors`.
    pub fn label(&self) -> String {
        match self {
            PriorScheme::Evidence(Grouping::PerParameter) => "evidence per parameter".into(),
            PriorScheme::Evidence(Grouping::Groups) => "evidence per group".into(),
            PriorScheme::File(s) => format!("file ×{s}"),
            PriorScheme::None => "no priors".into(),
        }
    }

    /// The schemes `armcomp fit` tries: the evidence both ways, the file's priors at five
    /// scales, and none.
    pub fn defaults() -> Vec<PriorScheme> {
        let mut schemes = vec![
            PriorScheme::Evidence(Grouping::PerParameter),
            PriorScheme::Evidence(Grouping::Groups),
        ];
        schemes.extend([0.1, 0.3, 1.0, 3.0, 10.0].map(PriorScheme::File));
        schemes.push(PriorScheme::None);
        schemes
    }
}

/// One candidate model: a level, a prior scheme, and whether a residual predictor learns what
/// it leaves.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Candidate {
    /// What is identified.
    pub rung: Rung,
    /// How the priors are set.
    pub prior: PriorScheme,
    /// Whether a residual predictor is fitted on what the physical model leaves.
    pub predictor: bool,
}

impl Candidate {
    /// Its name in reports: `geometry, file ×0.3 + predictor`.
    pub fn label(&self) -> String {
        format!(
            "{}, {}{}",
            self.rung.label(),
            self.prior.label(),
            if self.predictor { " + predictor" } else { "" }
        )
    }
}

/// Settings of [`climb`].
#[derive(Debug)]
pub struct LadderParams {
    /// How each candidate calibrates (its `identify` and priors are the candidate's; its
    /// `measurement_std` is the declared noise when `noise_declared`, else the first guess).
    pub calibration: CalibrationParams,
    /// Whether the noise is declared (otherwise estimated with every fit).
    pub noise_declared: bool,
    /// Outer folds.
    pub folds: usize,
    /// How many times the folds are drawn, each with its own seed derived from `seed`.
    pub repeats: usize,
    /// Seed of the folds.
    pub seed: u64,
    /// A group per sample (a session, a station): folds hold out whole groups. `None` holds
    /// out whole poses.
    pub fold_groups: Option<Vec<usize>>,
    /// The prior schemes every level is fitted under ([`PriorScheme::defaults`]).
    pub schemes: Vec<PriorScheme>,
    /// The residual predictor tried on every physical candidate (none: no such candidates).
    pub predictor: Option<Box<dyn PredictorSpec>>,
}

impl LadderParams {
    /// The settings `armcomp fit` uses by default around `calibration`: 5 folds drawn 3 times,
    /// every default prior scheme, no predictor.
    pub fn new(calibration: CalibrationParams, noise_declared: bool) -> LadderParams {
        LadderParams {
            calibration,
            noise_declared,
            folds: 5,
            repeats: 3,
            seed: 0,
            fold_groups: None,
            schemes: PriorScheme::defaults(),
            predictor: None,
        }
    }
}

/// One candidate's cross-validated score.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CandidateScore {
    /// The candidate.
    pub candidate: Candidate,
    /// Its name in reports.
    pub label: String,
    /// Pooled held-out RMS over every outer fold of every repeat, of the error
    /// [`LadderReport::scored_by`] names (mm).
    pub rms_mm: f64,
    /// The pooled held-out RMS of each repeat of the folds (mm).
    pub repeat_rms_mm: Vec<f64>,
    /// Held-out RMS of each outer fold, repeat after repeat (mm).
    pub fold_rms_mm: Vec<f64>,
    /// The standard deviation of the folds' RMS (mm).
    pub spread_mm: f64,
    /// How far its score lies above the best candidate's, on equal folds (mm; mean over the
    /// repeats).
    pub excess_mm: f64,
    /// The standard error of that excess over the repeats (mm): how far the draw of the folds
    /// alone moves it (0 with one repeat).
    pub excess_std_error_mm: f64,
    /// Whether its score is within the noise of the best (see the module documentation).
    pub within_noise: bool,
    /// The parameters its fits determine (the mean over the folds of `γ`, the trace of the
    /// data's share of the posterior).
    pub effective_params: f64,
    /// Why it is not sound (most of its fold fits did not converge, or hold implausible
    /// values), if so.
    pub not_sound: Option<String>,
    /// Wall-clock time of its fits (s); the prior schemes of a level share their fits' time.
    pub seconds: f64,
}

/// What the ladder chose and how.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LadderReport {
    /// Every candidate scored, level by level.
    pub candidates: Vec<CandidateScore>,
    /// The candidate chosen (with a stack, its heaviest member).
    pub chosen: Candidate,
    /// When the model is a weighted mean of the chosen level's prior schemes (stacking): each
    /// member and its weight; empty otherwise.
    pub stack: Vec<StackMember>,
    /// Why, in words.
    pub reason: String,
    /// Said first when the chosen candidate is not sound (no sound one scored within the noise).
    pub warning: Option<String>,
    /// The held-out error to expect from the model (mm): the cross-validated RMS of the
    /// whole choice, each fold scored by the choice made without its rows.
    pub expected_rms_mm: f64,
    /// Outer folds.
    pub folds: usize,
    /// Repeats of the folds scored (fewer than asked after a stop request).
    pub repeats: usize,
    /// What each fold held out together: `pose`, `station` (data from several), or `groups`
    /// (the caller's).
    pub folds_by: String,
    /// What a held-out row's error is: `position` (its 3-D error), `plane height` (a contact's
    /// height above the plane its fold identified), `fixed-point distance` (a contact's
    /// distance from where its fold's contacts put the point), `+`-joined for mixed data; for
    /// measured poses, the position's error with the orientation's turn as a displacement
    /// (`pose: ...`, naming the length).
    pub scored_by: String,
    /// Why the residual predictor was not tried although one was asked for, if so.
    pub predictor_not_tried: Option<String>,
    /// The noise and priors chosen for the chosen candidate on all rows.
    pub evidence: EvidenceReport,
    /// Whether a stop request ([`CalibrationParams::cancel`]) came: the candidates are scored
    /// on the repeats and levels whose every fold was fitted before it, and the choice among
    /// them was fitted on all rows all the same (a request during that fit lets it finish).
    pub interrupted: bool,
}

/// A member of a stack: a prior scheme of the chosen level and its weight.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StackMember {
    /// The scheme.
    pub prior: PriorScheme,
    /// Its name in reports.
    pub label: String,
    /// Its weight (the weights sum to one).
    pub weight: f64,
}

/// The chosen model, fitted on all rows.
#[derive(Debug)]
pub struct Ladder {
    /// The model (with its fitted predictor when the chosen candidate has one).
    pub robot: Robot,
    /// The calibration of the chosen physical model on all rows.
    pub calibration: Calibration,
    /// The ladder.
    pub report: LadderReport,
}

/// The levels [`climb`] fits for `robot`: registration, joint offsets, geometry, and the error
/// models when the robot has any.
fn physical_rungs(robot: &Robot) -> Vec<Rung> {
    let mut rungs = vec![Rung::Registration, Rung::JointOffsets, Rung::Geometry];
    if !robot.error_models().is_empty() {
        rungs.push(Rung::ErrorModels);
    }
    rungs
}

/// One fit of a level under one prior scheme.
struct SchemeFit {
    calibration: Calibration,
    evidence: EvidenceReport,
}

/// Fits `rung` on `samples` under each of `schemes`, in that order. The evidence with one scale
/// per parameter is fitted first whatever the list: the others start where it ended, from its
/// noise (each still estimates its own unless the noise is declared), since a fit of the same
/// level under other priors lies close by.
fn fit_schemes(
    robot: &Robot,
    samples: &[Sample],
    params: &LadderParams,
    rung: Rung,
    schemes: &[PriorScheme],
    cancel: &Cancel,
) -> Result<Vec<SchemeFit>> {
    let base = CalibrationParams {
        identify: rung.identify().iter().map(|w| w.to_string()).collect(),
        cancel: cancel.clone(),
        ..params.calibration.clone()
    };
    let evidence = |grouping, estimate_priors| EvidenceParams {
        grouping,
        estimate_noise: !params.noise_declared,
        estimate_priors,
        ..EvidenceParams::default()
    };
    let fit = |p: &CalibrationParams, e: &EvidenceParams| -> Result<SchemeFit> {
        let (calibration, evidence) = calibrate_with_evidence(robot, samples, p, e, &mut |_| {})?;
        Ok(SchemeFit { calibration, evidence })
    };
    let first = fit(&base, &evidence(Grouping::PerParameter, true))?;
    let lin = &first.calibration.linearisation;
    let warm = CalibrationParams {
        start: Some(lin.theta.clone()),
        measurement_std: lin.noise,
        orientation_std: lin.orientation_noise,
        fixed_point_std: lin.fixed_point_noise.or(base.fixed_point_std),
        restarts: 0,
        ..base.clone()
    };
    let mut first = Some(first);
    let mut fits = Vec::with_capacity(schemes.len());
    for &scheme in schemes {
        fits.push(match scheme {
            PriorScheme::Evidence(Grouping::PerParameter) => match first.take() {
                Some(f) => f,
                None => fit(&base, &evidence(Grouping::PerParameter, true))?,
            },
            PriorScheme::Evidence(grouping) => fit(&warm, &evidence(grouping, true))?,
            PriorScheme::File(scale) => fit(
                &CalibrationParams {
                    prior_scale: base.prior_scale * scale,
                    ..warm.clone()
                },
                &evidence(Grouping::PerParameter, false),
            )?,
            PriorScheme::None => fit(
                &CalibrationParams {
                    use_priors: false,
                    ..warm.clone()
                },
                &evidence(Grouping::PerParameter, false),
            )?,
        });
    }
    Ok(fits)
}

/// Why a fit cannot be stood behind, if it cannot: it did not converge, or a free parameter
/// ended outside its physically plausible range.
fn not_sound(calibration: &Calibration) -> Option<String> {
    let r = &calibration.report;
    if !r.converged {
        return Some(format!("a fit did not converge ({})", r.stop_reason));
    }
    let implausible: Vec<&str> = r
        .params
        .iter()
        .filter(|p| !p.fixed && !p.plausible)
        .map(|p| p.name.as_str())
        .collect();
    (!implausible.is_empty()).then(|| format!("implausible values: {}", implausible.join(", ")))
}

/// `robot`'s file with `spec` fitted on what it leaves on `samples`.
fn file_with_predictor(
    robot: &Robot,
    spec: &dyn PredictorSpec,
    samples: &[Sample],
    cancel: &Cancel,
) -> Result<RobotFile> {
    let control = FitControl {
        progress: None,
        cancel: cancel.clone(),
    };
    let fitted = fit_residual_predictor(robot, spec, samples, &control)?;
    let mut file = robot.to_file();
    file.predictor = Some(serde_json::from_value(serde_json::to_value(spec).map_err(json_error)?).map_err(json_error)?);
    file.fitted_predictor = Some(fitted);
    file.predictor_frame = Some(crate::robot::robot_file::PredictorFrame::Base);
    Ok(file)
}

/// The record of how the chosen candidate was fitted on all rows (`fit`), for the commands that
/// continue from the model.
fn fit_record(
    robot: &Robot,
    samples: &[Sample],
    params: &LadderParams,
    chosen: Candidate,
    fit: &SchemeFit,
    expected_rms_mm: f64,
) -> FitRecord {
    let lin = &fit.calibration.linearisation;
    let space = crate::calibrate::ParameterSpace::for_samples(robot, samples);
    let prior_scales = lin
        .free
        .iter()
        .zip(&lin.prior_sigma)
        .filter(|(_, sigma)| sigma.is_finite())
        .map(|(&k, sigma)| (space.params[k].info.name.clone(), sigma / space.params[k].info.sigma))
        .collect();
    FitRecord {
        identify: chosen.rung.identify().iter().map(|w| w.to_string()).collect(),
        prior: chosen.prior.label(),
        use_priors: chosen.prior != PriorScheme::None,
        prior_scales,
        noise_mm: lin.noise * 1e3,
        noise_estimated: !params.noise_declared,
        noise_deg: robot.measures_pose().then(|| lin.orientation_noise.to_degrees()),
        expected_rms_mm: Some(expected_rms_mm),
        predictor: chosen.predictor,
        nominal: (lin.free.iter())
            .map(|&k| (space.params[k].info.name.clone(), lin.centre[k]))
            .collect(),
    }
}

fn json_error(e: serde_json::Error) -> Error {
    Error::InvalidArgument {
        what: "predictor".into(),
        reason: e.to_string(),
    }
}

/// What one outer fold says of one scheme of a level.
struct SchemeScore {
    /// The held-out error of each of the fold's test samples (m; `None` where its fold cannot
    /// score it), without and with the predictor: the position's, then for a pose its turn
    /// ([`pose_lever`]).
    errors: Vec<Option<Vector6<f64>>>,
    with_predictor: Option<Vec<Option<Vector6<f64>>>>,
    not_sound: Option<String>,
    effective_params: f64,
}

/// Fits `rung` under every scheme on `split`'s training rows and scores each on its test rows.
fn score_fold(
    robot: &Robot,
    samples: &[Sample],
    split: &Split,
    params: &LadderParams,
    rung: Rung,
    predictor: Option<&dyn PredictorSpec>,
    cancel: &Cancel,
) -> Result<Vec<SchemeScore>> {
    let train = subset(samples, &split.train);
    let test = subset(samples, &split.test);
    let lever = pose_lever(params, samples);
    let errors = |model: &Robot| -> Result<Vec<Option<Vector6<f64>>>> {
        let positions = crate::analysis::held_out::held_out_errors(model, &train, &test)?;
        let turns = match lever {
            Some(_) => crate::algorithms::evaluate::orientation_error_vectors(model, &test),
            None => vec![None; test.len()],
        };
        Ok((positions.into_iter().zip(turns))
            .map(|(p, r)| {
                let r = r.unwrap_or_else(Vector3::zeros) * lever.unwrap_or(0.0);
                p.map(|p| Vector6::new(p.x, p.y, p.z, r.x, r.y, r.z))
            })
            .collect())
    };
    // The schemes of one fold leave near-identical residuals: the predictor's search (a GP's
    // hyper-parameters) is made on the first scheme's and held for the others, which then
    // differ by their residuals alone.
    let mut held: Option<Box<dyn PredictorSpec>> = None;
    fit_schemes(robot, &train, params, rung, &params.schemes, cancel)?
        .into_iter()
        .map(|fit| {
            let not_sound = not_sound(&fit.calibration);
            let effective_params = crate::calibrate::evidence::effective_parameters(&fit.calibration.linearisation);
            let mut model = fit.calibration.robot;
            register_held_out_stations(&mut model, &train, &test)?;
            let with_predictor = match predictor {
                Some(spec) => {
                    let file = file_with_predictor(&model, held.as_deref().unwrap_or(spec), &train, cancel)?;
                    if held.is_none() {
                        held = (file.fitted_predictor.as_ref())
                            .and_then(|f| f.searched())
                            .and_then(|s| spec.holding(&s));
                    }
                    Some(errors(&model.rebuild(file)?)?)
                }
                None => None,
            };
            Ok(SchemeScore {
                errors: errors(&model)?,
                with_predictor,
                not_sound,
                effective_params,
            })
        })
        .collect()
}

/// For data with measured orientations, the length (m) that turns an orientation error into a
/// displacement in a held-out score: the noises' ratio `measurement_std / orientation_std`
/// (0.1 mm per mrad, so 100 mm, by default), so that a pose is scored as the fit weighs it;
/// `None` for positions alone.
fn pose_lever(params: &LadderParams, samples: &[Sample]) -> Option<f64> {
    let c = &params.calibration;
    samples
        .iter()
        .any(|s| s.orientation.is_some())
        .then(|| c.measurement_std / c.orientation_std)
}

/// The fold draws of [`climb`]: `repeats` seeds derived from `seed`, a draw that repeats an
/// earlier one (one group per fold leaves nothing to draw) left out.
fn draws(samples: &[Sample], params: &LadderParams, by: &FoldBy) -> Result<(Vec<Vec<Split>>, String)> {
    let repeats = params.repeats.max(1) as u64;
    let mut out: Vec<Vec<Split>> = Vec::new();
    let mut grouped_by = String::new();
    for k in 0..repeats {
        let seed = params.seed.wrapping_mul(repeats).wrapping_add(k);
        let (splits, folding) = crate::data::split::folds(samples, params.folds, seed, by)?;
        grouped_by = folding.grouped_by;
        let key = |s: &[Split]| {
            let mut tests: Vec<Vec<usize>> = s.iter().map(|s| s.test.clone()).collect();
            tests.sort();
            tests
        };
        if !out.iter().any(|o| key(o) == key(&splits)) {
            out.push(splits);
        }
    }
    Ok((out, grouped_by))
}

/// A level's fold scores in one repeat: per fold, per scheme; `None` when a stop request left
/// one of its folds unfitted.
type LevelScores = Option<Vec<Vec<SchemeScore>>>;

/// Chooses among the candidates by repeated cross-validation on `samples` and fits the choice
/// on all of them (see the module documentation). `progress` sees every fold's fits done.
/// Deterministic for a seed; the folds and levels of a repeat run in parallel.
pub fn climb(
    robot: &Robot,
    samples: &[Sample],
    params: &LadderParams,
    progress: &(dyn Fn(FitsProgress) + Sync),
) -> Result<Ladder> {
    // By the caller's groups, else by station for data from several, else by pose.
    let by = FoldBy::choose(
        samples,
        params.fold_groups.clone().map(|g| ("the given groups".to_string(), g)),
    );
    let (draws, folds_by) = draws(samples, params, &by)?;
    let cancel = &params.calibration.cancel;
    let rungs = physical_rungs(robot);
    // A residual predictor learns 3-D errors, which fixed-point and plane rows do not give.
    let positions_only = crate::analysis::held_out::measures_positions(samples);
    let predictor = params.predictor.as_deref().filter(|_| positions_only);
    let predictor_not_tried = (params.predictor.is_some() && !positions_only)
        .then(|| "fixed-point and plane rows give no 3-D error for a residual predictor to learn".to_string());
    let total = draws.iter().map(|d| d.len() * rungs.len()).sum::<usize>() + 1 + usize::from(predictor.is_some());
    let done = std::sync::atomic::AtomicUsize::new(0);
    let tick = |last: Option<(&'static str, f64)>| {
        let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
        progress(FitsProgress { done: d, total, last });
    };
    let mut seconds = vec![0.0; rungs.len()];
    let mut results: Vec<Vec<LevelScores>> = Vec::new();
    // Repeat after repeat, so that a stop request leaves whole repeats scored.
    for splits in &draws {
        let jobs: Vec<(usize, usize)> = (0..rungs.len())
            .flat_map(|r| (0..splits.len()).map(move |f| (r, f)))
            .collect();
        let fitted: Vec<Option<(Vec<SchemeScore>, f64)>> = jobs
            .par_iter()
            .map(|&(r, f)| {
                if cancel.is_cancelled() {
                    return Ok(None);
                }
                let start = Instant::now();
                let scored = score_fold(robot, samples, &splits[f], params, rungs[r], predictor, cancel);
                let Some(scores) = crate::support::cancel::finished(scored)? else {
                    return Ok(None);
                };
                let seconds = start.elapsed().as_secs_f64();
                tick(Some((rungs[r].label(), seconds)));
                Ok(Some((scores, seconds)))
            })
            .collect::<Result<_>>()?;
        let mut it = fitted.into_iter();
        let mut level = Vec::with_capacity(rungs.len());
        for secs in seconds.iter_mut() {
            let folds: Option<Vec<_>> = it.by_ref().take(splits.len()).collect();
            level.push(folds.map(|folds| {
                folds
                    .into_iter()
                    .map(|(scores, s)| {
                        *secs += s;
                        scores
                    })
                    .collect()
            }));
        }
        results.push(level);
        if cancel.is_cancelled() {
            break;
        }
    }
    let interrupted = cancel.is_cancelled();
    let mut gathered = gather(
        samples.len(),
        &rungs,
        params,
        predictor.is_some(),
        &draws,
        &results,
        &seconds,
    );
    if gathered.candidates.is_empty() {
        return Err(Error::Interrupted);
    }
    let groups = held_out_groups(samples, &by);
    let choice = choose(&gathered, &groups, &vec![true; samples.len()]);
    let expected_rms_mm = Some(nested_rms_mm(&gathered, &groups))
        .filter(|v| v.is_finite())
        .unwrap_or(gathered.candidates[choice.index].rms_mm);
    for (score, excess) in gathered.candidates.iter_mut().zip(&choice.excess) {
        score.excess_mm = excess.mean;
        score.excess_std_error_mm = excess.std_error;
        score.within_noise = excess.within_noise;
    }
    let candidates = gathered.candidates;
    let chosen = candidates[choice.index].candidate;
    let stack: Vec<StackMember> = (choice.stack.iter())
        .map(|&(c, weight)| StackMember {
            prior: candidates[c].candidate.prior,
            label: candidates[c].candidate.prior.label(),
            weight,
        })
        .collect();
    // The choice is fitted on all rows whether a stop request came before or during that fit;
    // only a further one stops it.
    let final_cancel = cancel.for_last_step();
    let schemes: Vec<PriorScheme> = if stack.is_empty() {
        vec![chosen.prior]
    } else {
        stack.iter().map(|m| m.prior).collect()
    };
    let start = Instant::now();
    let mut fits = fit_schemes(robot, samples, params, chosen.rung, &schemes, &final_cancel)?;
    let heaviest = schemes.iter().position(|&p| p == chosen.prior).unwrap_or(0);
    let stacked = (!stack.is_empty())
        .then(|| stacked_model(robot, samples, &fits, &stack))
        .transpose()?;
    let mut fit = fits.swap_remove(heaviest);
    if let Some(model) = stacked {
        fit.calibration.robot = model;
    }
    tick(Some(("the choice on all rows", start.elapsed().as_secs_f64())));
    let fitted = &fit.calibration.robot;
    let start = Instant::now();
    let mut file = match predictor.filter(|_| chosen.predictor) {
        Some(spec) => file_with_predictor(fitted, spec, samples, &final_cancel)?,
        None => fitted.to_file(),
    };
    if predictor.is_some() {
        let what = if chosen.predictor {
            "its predictor on all rows"
        } else {
            "the model file"
        };
        tick(Some((what, start.elapsed().as_secs_f64())));
    }
    let mut record = fit_record(robot, samples, params, chosen, &fit, expected_rms_mm);
    if !stack.is_empty() {
        record.prior = format!(
            "stack: {}",
            (stack.iter())
                .map(|m| format!("{:.3} × {}", m.weight, m.label))
                .collect::<Vec<_>>()
                .join(" + ")
        );
    }
    file.fitted = Some(record);
    let model = fitted.rebuild(file)?;
    Ok(Ladder {
        robot: model,
        calibration: fit.calibration,
        report: LadderReport {
            expected_rms_mm,
            candidates,
            chosen,
            stack,
            reason: choice.reason,
            warning: choice.warning,
            folds: draws.first().map_or(0, Vec::len),
            repeats: results.iter().filter(|l| l.iter().all(Option::is_some)).count(),
            folds_by,
            scored_by: match pose_lever(params, samples) {
                Some(lever) => format!(
                    "pose: position, and the orientation error times {:.1} mm (the noises' ratio)",
                    lever * 1e3
                ),
                None => crate::analysis::held_out::scored_by(samples),
            },
            predictor_not_tried,
            evidence: fit.evidence,
            interrupted: interrupted || cancel.is_cancelled(),
        },
    })
}

/// The model whose every parameter is the weighted mean of the fits' values: to first order
/// in the small corrections, the weighted mean of their predictions, as one model file that
/// every command reads.
fn stacked_model(robot: &Robot, samples: &[Sample], fits: &[SchemeFit], stack: &[StackMember]) -> Result<Robot> {
    let space = crate::calibrate::ParameterSpace::for_samples(robot, samples);
    let mut theta = vec![0.0; space.initial().len()];
    for (fit, member) in fits.iter().zip(stack) {
        let values = &fit.calibration.linearisation.theta;
        if values.len() != theta.len() {
            return Err(Error::Dimension {
                what: "stacked calibration parameters".into(),
                expected: theta.len(),
                got: values.len(),
            });
        }
        for (t, v) in theta.iter_mut().zip(values) {
            *t += member.weight * v;
        }
    }
    space.apply(robot, &theta)
}

/// Every candidate's score from the fold scores of every repeat (`results[repeat][level]`),
/// with each candidate's held-out errors per repeat. Levels with no repeat scored are left out.
fn gather(
    n: usize,
    rungs: &[Rung],
    params: &LadderParams,
    with_predictor: bool,
    draws: &[Vec<Split>],
    results: &[Vec<LevelScores>],
    seconds: &[f64],
) -> Gathered {
    let mut out = Gathered {
        // The draws a stop request left unscored have no errors: only those with results.
        fold_of: draws
            .iter()
            .take(results.len())
            .map(|splits| {
                let mut of = vec![None; n];
                for (f, split) in splits.iter().enumerate() {
                    for &i in &split.test {
                        of[i] = Some(f);
                    }
                }
                of
            })
            .collect(),
        ..Gathered::default()
    };
    for (r, &rung) in rungs.iter().enumerate() {
        for (s, &prior) in params.schemes.iter().enumerate() {
            for predictor in [false, true].into_iter().filter(|&p| !p || with_predictor) {
                let mut by_repeat = Vec::with_capacity(results.len());
                let mut fold_rms_mm = Vec::new();
                let (mut first_flaw, mut flawed, mut effective, mut fits) = (None, 0usize, 0.0, 0usize);
                for (k, level) in results.iter().enumerate() {
                    let mut errors = vec![None; n];
                    for (split, fold) in draws[k].iter().zip(level[r].iter().flatten()) {
                        let score = &fold[s];
                        let e = match (&score.with_predictor, predictor) {
                            (Some(with), true) => with,
                            _ => &score.errors,
                        };
                        for (&i, v) in split.test.iter().zip(e) {
                            errors[i] = *v;
                        }
                        let sq: Vec<f64> = e.iter().flatten().map(|v| v.norm_squared()).collect();
                        if !sq.is_empty() {
                            fold_rms_mm.push(rms_mm(&sq));
                        }
                        if let Some(why) = &score.not_sound {
                            flawed += 1;
                            first_flaw.get_or_insert_with(|| why.clone());
                        }
                        effective += score.effective_params;
                        fits += 1;
                    }
                    by_repeat.push(errors);
                }
                if fits == 0 {
                    continue;
                }
                let candidate = Candidate { rung, prior, predictor };
                let all = summary(&by_repeat, &vec![true; n]);
                out.candidates.push(CandidateScore {
                    candidate,
                    label: candidate.label(),
                    rms_mm: all.rms_mm,
                    repeat_rms_mm: all.repeat_rms.iter().flatten().copied().collect(),
                    spread_mm: std_dev(&fold_rms_mm),
                    fold_rms_mm,
                    excess_mm: 0.0,
                    excess_std_error_mm: 0.0,
                    within_noise: false,
                    effective_params: effective / fits as f64,
                    // A fold fit that stalls now and then is the folds' luck; most of them is the model's.
                    not_sound: (2 * flawed > fits)
                        .then(|| format!("{flawed} of {fits} fold fits: {}", first_flaw.unwrap_or_default())),
                    seconds: seconds[r],
                });
                out.errors.push(by_repeat);
            }
        }
    }
    out
}

/// What [`gather`] collects: every candidate's score, and its held-out error of every sample
/// in every repeat (`errors[candidate][repeat][sample]`, `None` where unscored), with the fold
/// that held each sample out in each repeat.
#[derive(Default)]
struct Gathered {
    candidates: Vec<CandidateScore>,
    errors: Vec<Vec<Vec<Option<Vector6<f64>>>>>,
    fold_of: Vec<Vec<Option<usize>>>,
}

/// The RMS (mm) of squared errors `sq` (m²).
fn rms_mm(sq: &[f64]) -> f64 {
    (sq.iter().sum::<f64>() / sq.len() as f64).sqrt() * 1e3
}

/// One candidate's errors summed up over the samples `mask` keeps.
struct Summary {
    /// The pooled RMS (mm) of the samples' mean squared error over the repeats.
    rms_mm: f64,
    /// The RMS of each repeat (mm; `None` for a repeat with no kept sample scored).
    repeat_rms: Vec<Option<f64>>,
    /// Each sample's squared error averaged over the repeats (m²; NaN where not kept or never
    /// scored).
    sample_sq: Vec<f64>,
}

fn summary(by_repeat: &[Vec<Option<Vector6<f64>>>], mask: &[bool]) -> Summary {
    let n = mask.len();
    let (mut sum, mut count) = (vec![0.0; n], vec![0usize; n]);
    let repeat_rms = by_repeat
        .iter()
        .map(|errors| {
            let mut sq = Vec::with_capacity(n);
            for (i, e) in errors.iter().enumerate().filter(|&(i, _)| mask[i]) {
                if let Some(e) = e {
                    let v = e.norm_squared();
                    sq.push(v);
                    sum[i] += v;
                    count[i] += 1;
                }
            }
            (!sq.is_empty()).then(|| rms_mm(&sq))
        })
        .collect();
    let sample_sq: Vec<f64> = sum
        .iter()
        .zip(&count)
        .map(|(s, &c)| if c == 0 { f64::NAN } else { s / c as f64 })
        .collect();
    let scored: Vec<f64> = sample_sq.iter().copied().filter(|v| !v.is_nan()).collect();
    Summary {
        rms_mm: if scored.is_empty() { f64::NAN } else { rms_mm(&scored) },
        repeat_rms,
        sample_sq,
    }
}

/// The standard error of the mean paired difference `a − b` of per-sample squared errors over
/// the held-out groups (each group's mean over its samples; the samples of one pose or session
/// are not independent), and that mean.
fn paired_difference(a: &[f64], b: &[f64], groups: &[usize]) -> (f64, f64) {
    let n_groups = groups.iter().max().map_or(0, |m| m + 1);
    let (mut sum, mut count) = (vec![0.0; n_groups], vec![0usize; n_groups]);
    for i in (0..a.len()).filter(|&i| !a[i].is_nan() && !b[i].is_nan()) {
        sum[groups[i]] += a[i] - b[i];
        count[groups[i]] += 1;
    }
    let d: Vec<f64> = sum
        .iter()
        .zip(&count)
        .filter(|(_, c)| **c > 0)
        .map(|(s, &c)| s / c as f64)
        .collect();
    let mean = d.iter().sum::<f64>() / d.len().max(1) as f64;
    (mean, std_dev(&d) / (d.len().max(1) as f64).sqrt())
}

/// The sample standard deviation of `v` (0 for fewer than two values).
fn std_dev(v: &[f64]) -> f64 {
    if v.len() < 2 {
        return 0.0;
    }
    let mean = v.iter().sum::<f64>() / v.len() as f64;
    (v.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (v.len() - 1) as f64).sqrt()
}

/// The smallest excess over the best score that still counts as noise when the repeats cannot
/// measure it (one repeat, or repeats that agree exactly): half a percent.
const MIN_SCORE_NOISE: f64 = 0.005;

/// How far a candidate's score lies above the best one's on equal folds (mm), its standard
/// error over the repeats, and whether that is within the noise.
#[derive(Clone, Copy)]
struct Excess {
    mean: f64,
    std_error: f64,
    within_noise: bool,
}

/// A choice: one candidate, or a weighted mean of some of one level's candidates.
struct Choice {
    /// The candidate chosen (with a stack, its heaviest member).
    index: usize,
    /// With a stack, its members and their weights (summing to one); empty otherwise.
    stack: Vec<(usize, f64)>,
    reason: String,
    warning: Option<String>,
    excess: Vec<Excess>,
}

impl Choice {
    /// Its held-out error of sample `i` in repeat `k`: the candidate's, or the weighted mean of
    /// the members' (the error of the weighted mean of their predictions).
    fn error(&self, g: &Gathered, k: usize, i: usize) -> Option<Vector6<f64>> {
        if self.stack.is_empty() {
            return g.errors[self.index][k][i];
        }
        (self.stack.iter()).try_fold(Vector6::zeros(), |sum, &(c, w)| Some(sum + g.errors[c][k][i]? * w))
    }
}

/// Picks the choice from the samples `mask` keeps (see the module documentation); `groups`
/// gives each sample's held-out group.
fn choose(g: &Gathered, groups: &[usize], mask: &[bool]) -> Choice {
    let candidates = &g.candidates;
    let sums: Vec<Summary> = g.errors.iter().map(|e| summary(e, mask)).collect();
    let best = (0..candidates.len())
        .filter(|&c| sums[c].rms_mm.is_finite())
        .min_by(|&a, &b| sums[a].rms_mm.total_cmp(&sums[b].rms_mm))
        .unwrap_or(0);
    let best_rms = sums[best].rms_mm;
    let excess: Vec<Excess> = sums
        .iter()
        .map(|s| {
            // Paired on the repeats both were scored on: equal folds.
            let d: Vec<f64> = (s.repeat_rms.iter().zip(&sums[best].repeat_rms))
                .filter_map(|(a, b)| Some((*a)? - (*b)?))
                .collect();
            let mean = if d.is_empty() {
                f64::NAN
            } else {
                d.iter().sum::<f64>() / d.len() as f64
            };
            let std_error = std_dev(&d) / (d.len().max(1) as f64).sqrt();
            Excess {
                mean,
                std_error,
                within_noise: mean <= std_error.max(MIN_SCORE_NOISE * best_rms),
            }
        })
        .collect();
    // The safest level and predictor with a candidate within the noise of the best, among the
    // sound ones while there are any (see `safety`).
    let level = |c: usize| (candidates[c].candidate.rung, candidates[c].candidate.predictor);
    let eligible = |c: usize, sound: bool| excess[c].within_noise && (!sound || candidates[c].not_sound.is_none());
    let safest = |sound: bool| {
        (0..candidates.len())
            .filter(|&c| eligible(c, sound))
            .min_by_key(|&c| safety(candidates[c].candidate))
            .map(level)
    };
    let (chosen_level, sound) = match safest(true) {
        Some(l) => (l, true),
        None => (safest(false).unwrap_or(level(best)), false),
    };
    // Within it, the schemes score alike when their paired difference from the level's best is
    // within its standard error over the held-out groups: the first of them in the order of
    // the schemes (the evidence first), so that the choice does not follow the folds' noise.
    let members: Vec<usize> = (0..candidates.len())
        .filter(|&c| level(c) == chosen_level && (!sound || candidates[c].not_sound.is_none()))
        .filter(|&c| sums[c].rms_mm.is_finite())
        .collect();
    let lead = members
        .iter()
        .copied()
        .min_by(|&a, &b| sums[a].rms_mm.total_cmp(&sums[b].rms_mm))
        .unwrap_or(best);
    let index = members
        .iter()
        .copied()
        .find(|&c| {
            let (mean, se) = paired_difference(&sums[c].sample_sq, &sums[lead].sample_sq, groups);
            mean <= se
        })
        .unwrap_or(lead);
    let stack = stack_of(g, &members, &sums[index].sample_sq, groups, mask);
    let warning = (!sound).then(|| {
        format!(
            "no candidate whose fits converged to plausible values scored within the noise of the best; the chosen \
             one is not sound: {}",
            candidates[index].not_sound.clone().unwrap_or_default()
        )
    });
    let single = if index == best {
        "the best score".to_string()
    } else {
        format!(
            "the safest {}candidate within the folds' noise of the best ({}, {:.3} mm), the first prior scheme \
             within the standard error of its level's best",
            if sound { "sound " } else { "" },
            candidates[best].label,
            best_rms
        )
    };
    let (index, reason) = match stack.iter().max_by(|a, b| a.1.total_cmp(&b.1)) {
        Some(&(heaviest, _)) => (
            heaviest,
            format!(
                "{single}; then a weighted mean of its level's prior schemes, whose held-out predictions beat that \
                 one beyond their standard error"
            ),
        ),
        None => (index, single),
    };
    Choice {
        index,
        stack,
        reason,
        warning,
        excess,
    }
}

/// The order in which candidates scoring alike are preferred, safest first: without a
/// predictor the lowest level (fewest parameters), then with a predictor the highest level
/// under it. A predictor learns the training poses' residuals and carries them less far beyond
/// those poses than a physical parameter does, and what it learns of a poorer physical model
/// carries least far (on TALOS' time split, joint offsets with a GP scored within the noise of
/// geometry in cross-validation and gave 2.19 mm on the later rows).
fn safety(c: Candidate) -> (bool, i32) {
    let rung = c.rung as i32;
    (c.predictor, if c.predictor { -rung } else { rung })
}

/// At most this many candidates are stacked (the best by score): the weights are found over
/// every subset of them.
const MAX_STACKED: usize = 10;

/// The weights (on the simplex) of `members`' held-out errors whose weighted mean has the
/// least squared error over the samples `mask` keeps, when that mean beats `single` (the
/// single choice's per-sample squared errors) by more than the standard error of their paired
/// difference over the held-out groups; empty otherwise. This is stacking: the weights are
/// those of the candidates' out-of-fold predictions.
fn stack_of(g: &Gathered, members: &[usize], single: &[f64], groups: &[usize], mask: &[bool]) -> Vec<(usize, f64)> {
    let mut members = members.to_vec();
    if members.len() < 2 {
        return Vec::new();
    }
    members.sort_by(|&a, &b| g.candidates[a].rms_mm.total_cmp(&g.candidates[b].rms_mm));
    members.truncate(MAX_STACKED);
    let m = members.len();
    let n = mask.len();
    let mut gram = DMatrix::<f64>::zeros(m, m);
    let mut e = vec![Vector6::zeros(); m];
    for k in 0..g.fold_of.len() {
        for i in (0..n).filter(|&i| mask[i]) {
            let all = members
                .iter()
                .zip(e.iter_mut())
                .all(|(&c, slot)| match g.errors[c][k][i] {
                    Some(v) => {
                        *slot = v;
                        true
                    }
                    None => false,
                });
            if all {
                for a in 0..m {
                    for b in a..m {
                        gram[(a, b)] += e[a].dot(&e[b]);
                    }
                }
            }
        }
    }
    gram.fill_lower_triangle_with_upper_triangle();
    let weights = simplex_least_squares(&gram);
    let kept: Vec<(usize, f64)> = (members.iter().copied().zip(weights))
        .filter(|&(_, w)| w > 1e-3)
        .collect();
    if kept.len() < 2 {
        return Vec::new();
    }
    let total: f64 = kept.iter().map(|(_, w)| w).sum();
    let kept: Vec<(usize, f64)> = kept.into_iter().map(|(c, w)| (c, w / total)).collect();
    let stacked = Choice {
        index: kept[0].0,
        stack: kept,
        reason: String::new(),
        warning: None,
        excess: Vec::new(),
    };
    let (mut sum, mut count) = (vec![0.0; n], vec![0usize; n]);
    for k in 0..g.fold_of.len() {
        for i in (0..n).filter(|&i| mask[i]) {
            if let Some(v) = stacked.error(g, k, i) {
                sum[i] += v.norm_squared();
                count[i] += 1;
            }
        }
    }
    let stacked_sq: Vec<f64> = (sum.iter().zip(&count))
        .map(|(s, &c)| if c == 0 { f64::NAN } else { s / c as f64 })
        .collect();
    let (mean, se) = paired_difference(&stacked_sq, single, groups);
    if mean < -se { stacked.stack } else { Vec::new() }
}

/// The weights `w ≥ 0`, `Σ w = 1` minimising `wᵀ G w` for a Gram matrix `G` of a few columns.
/// Exact: the minimum lies on some support `S`, where `w_S ∝ G_SS⁻¹ 1`; every support is tried
/// (at most [`MAX_STACKED`] columns, so at most 1023 systems of that size), simpler and surer
/// than an iterative quadratic-programming solver for a problem this small.
fn simplex_least_squares(gram: &DMatrix<f64>) -> Vec<f64> {
    let m = gram.nrows();
    let mut best = (f64::INFINITY, vec![0.0; m]);
    for support in 1u32..(1 << m) {
        let idx: Vec<usize> = (0..m).filter(|&j| support & (1 << j) != 0).collect();
        let sub = DMatrix::from_fn(idx.len(), idx.len(), |a, b| gram[(idx[a], idx[b])]);
        let Some(chol) = sub.clone().cholesky() else {
            continue;
        };
        let x = chol.solve(&DVector::from_element(idx.len(), 1.0));
        let total = x.sum();
        if total.is_nan() || total <= 0.0 || x.iter().any(|&v| v <= 0.0) {
            continue;
        }
        let w = x / total;
        let objective = w.dot(&(&sub * &w));
        if objective < best.0 {
            let mut full = vec![0.0; m];
            for (a, &j) in idx.iter().enumerate() {
                full[j] = w[a];
            }
            best = (objective, full);
        }
    }
    if best.0.is_infinite() {
        // Every support singular (identical errors): the first column alone.
        best.1[0] = 1.0;
    }
    best.1
}

/// The held-out RMS of the choice itself (mm): in every repeat, each fold's samples scored by
/// the choice [`choose`] makes from the other folds' samples, so that the choice among the
/// candidates is cross-validated as well as their fits (NaN when nothing was scored).
fn nested_rms_mm(g: &Gathered, groups: &[usize]) -> f64 {
    let mut sq = Vec::new();
    for (k, fold_of) in g.fold_of.iter().enumerate() {
        let n_folds = fold_of.iter().flatten().max().map_or(0, |m| m + 1);
        for f in 0..n_folds {
            let mask: Vec<bool> = fold_of.iter().map(|&o| o != Some(f)).collect();
            let choice = choose(g, groups, &mask);
            for i in (0..fold_of.len()).filter(|&i| fold_of[i] == Some(f)) {
                if let Some(e) = choice.error(g, k, i) {
                    sq.push(e.norm_squared());
                }
            }
        }
    }
    if sq.is_empty() { f64::NAN } else { rms_mm(&sq) }
}

/// Each sample's held-out group under `by`: its column value, station or pose.
fn held_out_groups(samples: &[Sample], by: &FoldBy) -> Vec<usize> {
    match by {
        FoldBy::Column { groups, .. } => groups.clone(),
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
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simplex_weights_match_the_hand_solution() {
        // Uncorrelated errors of variances a and b: w₁ = b / (a + b), the inverse-variance mean.
        let (a, b) = (1.0, 3.0);
        let w = simplex_least_squares(&DMatrix::from_row_slice(2, 2, &[a, 0.0, 0.0, b]));
        assert!((w[0] - 0.75).abs() < 1e-12 && (w[1] - 0.25).abs() < 1e-12, "{w:?}");
        // G⁻¹1 ∝ (2.5, −0.5) leaves the simplex: the constrained minimum is the first alone.
        let w = simplex_least_squares(&DMatrix::from_row_slice(2, 2, &[1.0, 1.5, 1.5, 4.0]));
        assert_eq!(w, vec![1.0, 0.0]);
        // Three columns, the third a copy of the first (singular Gram): the copy adds nothing.
        let g = DMatrix::from_row_slice(3, 3, &[2.0, 0.0, 2.0, 0.0, 2.0, 0.0, 2.0, 0.0, 2.0]);
        let w = simplex_least_squares(&g);
        assert!((w[0] + w[2] - 0.5).abs() < 1e-12 && (w[1] - 0.5).abs() < 1e-12, "{w:?}");
    }
}
