//! Choosing how strongly the priors hold a calibration, by cross-validation on the training
//! data alone: each candidate prior scale calibrates on k − 1 folds of the poses (of the
//! stations, for data from several: a held-out station is registered before it is scored) and is scored
//! on the fold left out (plane contacts by their height above the plane the training folds
//! identified); the scale with the lowest pooled held-out RMS wins.
//!
//! A full-geometry calibration from a few dozen poses has nearly as many parameters as
//! equations: with the robot file's priors as written it fits the noise, with much tighter
//! ones it cannot move the parameters the data does determine. Which lies between is a
//! property of the robot and the data, so it is measured rather than guessed.

use rayon::prelude::*;
use serde::Serialize;

use crate::analysis::held_out::held_out_errors;
use crate::calibrate::{CalibrationParams, FitsProgress, calibrate, register_held_out_stations};
use crate::data::measurement::Sample;
use crate::data::split::{FoldPlan, subset};
use crate::error::{Error, Result};
use crate::robot::Robot;

/// The prior scales [`choose_prior_scale`] tries by default: factors on the robot file's prior
/// standard deviations, from 100 times tighter to none at all (infinite).
pub const DEFAULT_GRID: [f64; 8] = [0.01, 0.03, 0.1, 0.3, 1.0, 3.0, 10.0, f64::INFINITY];

/// One candidate's cross-validated score.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PriorScaleScore {
    /// The factor on the prior standard deviations (`null` in JSON for no priors).
    pub scale: f64,
    /// Pooled RMS of the 3-D position error over the held-out folds (mm); for plane contacts,
    /// of the height above the plane.
    pub held_out_rms_mm: f64,
}

/// What cross-validation chose, and the scores it chose from.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PriorChoice {
    /// The chosen factor.
    pub scale: f64,
    /// Number of folds.
    pub folds: usize,
    /// What each fold held out together: `pose`, or `station` for data from several.
    pub grouped_by: String,
    /// The seed that shuffled the poses into folds.
    pub seed: u64,
    /// Every candidate scored, in the order tried.
    pub scores: Vec<PriorScaleScore>,
    /// Whether a stop request ([`CalibrationParams::cancel`]) ended the cross-validation: the choice is
    /// the best of the candidates whose every fold was scored before it.
    pub interrupted: bool,
}

/// Picks the factor on the prior standard deviations from `grid` that predicts held-out poses
/// of `samples` best in the cross-validation `plan` says, calibrating as `params` says;
/// `progress` sees every fit done. Deterministic for a seed; the folds and candidates run in parallel.
pub fn choose_prior_scale(
    robot: &Robot,
    samples: &[Sample],
    params: &CalibrationParams,
    grid: &[f64],
    plan: &FoldPlan,
    progress: &(dyn Fn(FitsProgress) + Sync),
) -> Result<PriorChoice> {
    if grid.is_empty() || grid.iter().any(|s| s.is_nan() || *s <= 0.0) {
        return Err(Error::InvalidArgument {
            what: "prior scales to try".into(),
            reason: format!("expected positive numbers, got {grid:?}"),
        });
    }
    let (splits, folding) = crate::data::split::folds(samples, plan.k, plan.seed, &plan.by)?;
    let jobs: Vec<(usize, usize)> = (0..grid.len())
        .flat_map(|g| (0..splits.len()).map(move |f| (g, f)))
        .collect();
    let done = std::sync::atomic::AtomicUsize::new(0);
    let sums: Vec<Option<(f64, usize)>> = jobs
        .par_iter()
        .map(|&(g, f)| {
            if params.cancel.is_cancelled() {
                return Ok(None);
            }
            let p = CalibrationParams {
                prior_scale: grid[g],
                ..params.clone()
            };
            let train = subset(samples, &splits[f].train);
            let test = subset(samples, &splits[f].test);
            let Some(fit) = crate::support::cancel::finished(calibrate(robot, &train, &p, &mut |_| {}))? else {
                return Ok(None);
            };
            let mut fitted = fit.robot;
            register_held_out_stations(&mut fitted, &train, &test)?;
            // Every kind of row scored by what it measures (a plane contact by its height above
            // the plane the fold identified, ...); rows the fold cannot score are left out.
            let scored = held_out_errors(&fitted, &train, &test)?
                .iter()
                .flatten()
                .fold((0.0, 0), |(sum, n), e| (sum + e.norm_squared(), n + 1));
            progress(FitsProgress {
                done: done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1,
                total: jobs.len(),
                last: None,
            });
            Ok(Some(scored))
        })
        .collect::<Result<_>>()?;
    let interrupted = sums.iter().any(Option::is_none);
    let mut scores = Vec::with_capacity(grid.len());
    for (g, &scale) in grid.iter().enumerate() {
        let (mut sum, mut n) = (0.0, 0);
        let folds = &sums[g * splits.len()..(g + 1) * splits.len()];
        // A candidate with a fold the stop left unfitted is not scored.
        if folds.iter().any(Option::is_none) {
            continue;
        }
        for (s, k) in folds.iter().flatten() {
            sum += s;
            n += k;
        }
        scores.push(PriorScaleScore {
            scale,
            held_out_rms_mm: (sum / n.max(1) as f64).sqrt() * 1e3,
        });
    }
    let best = match scores
        .iter()
        .min_by(|a, b| a.held_out_rms_mm.total_cmp(&b.held_out_rms_mm))
    {
        Some(s) => s.scale,
        None => return Err(Error::Interrupted),
    };
    Ok(PriorChoice {
        scale: best,
        folds: splits.len(),
        grouped_by: folding.grouped_by,
        seed: plan.seed,
        scores,
        interrupted,
    })
}
