//! Learning curves: held-out error against the number of training poses, for the poses
//! `armcomp plan` chooses and for random subsets of the same training poses.
//!
//! Everything is decided on the training poses alone: the selection sees only them (its
//! workspace is the training pool), the fit only the chosen ones; the held-out poses score.
//! Random subsets of one draw are nested (the first `n` poses of one seeded permutation), so
//! the curve of a draw is a user measuring in random order.

use armcomp_core::design::{SelectionParams, select_poses};
use armcomp_core::evaluate::{ErrorStats, position_errors};
use armcomp_core::measurement::Sample;
use armcomp_core::split::pose_groups;
use armcomp_core::{Result, Robot};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rayon::prelude::*;
use serde::Serialize;

/// Settings of [`learning_curve`].
#[derive(Debug, Clone)]
pub struct CurveParams {
    /// Training-set sizes (poses); sizes above the training poses available are skipped.
    pub sizes: Vec<usize>,
    /// Random subsets per size.
    pub draws: usize,
    /// Seed of the random subsets (draw `d` uses `seed + d`).
    pub seed: u64,
    /// How the tool chooses.
    pub selection: SelectionParams,
}

/// One size of the curve.
#[derive(Debug, Clone, Serialize)]
pub struct CurvePoint {
    /// Training poses.
    pub size: usize,
    /// Held-out errors of the model fitted on the tool's choice.
    pub selected: ErrorStats,
    /// Held-out errors of the model fitted on each random subset (one when the size is every
    /// training pose: then there is nothing to choose).
    pub random: Vec<ErrorStats>,
}

impl CurvePoint {
    /// Mean, median, minimum and maximum over the random subsets of a statistic (mm).
    pub fn random_summary(&self, stat: fn(&ErrorStats) -> f64) -> [f64; 4] {
        let mut v: Vec<f64> = self.random.iter().map(stat).collect();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        if n == 0 {
            return [f64::NAN; 4];
        }
        let median = if n % 2 == 1 {
            v[n / 2]
        } else {
            0.5 * (v[n / 2 - 1] + v[n / 2])
        };
        [v.iter().sum::<f64>() / n as f64, median, v[0], v[n - 1]]
    }
}

/// A learning curve.
#[derive(Debug, Clone, Serialize)]
pub struct LearningCurveReport {
    /// What was fitted and scored.
    pub title: String,
    /// Training poses available.
    pub train_poses: usize,
    /// Held-out poses.
    pub test_poses: usize,
    /// The sizes, smallest first.
    pub points: Vec<CurvePoint>,
}

/// The curve of `fit` (training samples → fitted robot) trained on `train` and scored on
/// `test`, at each of `params.sizes` for the tool's choice and for random subsets; `on_fit`
/// is called after every fit (for a progress display). Fits run side by side.
pub fn learning_curve(
    robot: &Robot,
    train: &[Sample],
    test: &[Sample],
    params: &CurveParams,
    title: &str,
    fit: &(dyn Fn(&[Sample]) -> Result<Robot> + Sync),
    on_fit: &(dyn Fn() + Sync),
) -> Result<LearningCurveReport> {
    let groups = pose_groups(train);
    let pool: Vec<Vec<Sample>> = groups
        .iter()
        .map(|g| g.iter().map(|&i| train[i].clone()).collect())
        .collect();
    let sizes: Vec<usize> = params.sizes.iter().copied().filter(|&n| n <= pool.len()).collect();
    let permutations: Vec<Vec<usize>> = (0..params.draws as u64)
        .map(|d| {
            let mut p: Vec<usize> = (0..pool.len()).collect();
            p.shuffle(&mut StdRng::seed_from_u64(params.seed.wrapping_add(d)));
            p
        })
        .collect();
    // Every fit to run: (size, None for the tool's choice or Some(draw), pool indices).
    let mut jobs: Vec<(usize, Option<usize>, Vec<usize>)> = Vec::new();
    for &n in &sizes {
        let chosen = if n == pool.len() {
            (0..n).collect()
        } else {
            select_poses(robot, &pool, n, &[], &[], &params.selection)?.chosen
        };
        jobs.push((n, None, chosen));
        let draws = if n == pool.len() { 0 } else { params.draws };
        for (d, p) in permutations.iter().enumerate().take(draws) {
            jobs.push((n, Some(d), p[..n].to_vec()));
        }
    }
    let scored: Vec<ErrorStats> = jobs
        .par_iter()
        .map(|(_, _, idx)| {
            let samples: Vec<Sample> = idx.iter().flat_map(|&i| pool[i].iter().cloned()).collect();
            let fitted = fit(&samples)?;
            on_fit();
            Ok(ErrorStats::from_errors(&position_errors(&fitted, test)))
        })
        .collect::<Result<_>>()?;
    let points = sizes
        .iter()
        .map(|&n| {
            let of_size = || jobs.iter().zip(&scored).filter(move |((size, _, _), _)| *size == n);
            let selected = of_size()
                .find(|((_, draw, _), _)| draw.is_none())
                .map(|(_, s)| *s)
                .expect("one choice per size");
            let random: Vec<ErrorStats> = of_size()
                .filter(|((_, draw, _), _)| draw.is_some())
                .map(|(_, s)| *s)
                .collect();
            CurvePoint {
                size: n,
                random: if random.is_empty() { vec![selected] } else { random },
                selected,
            }
        })
        .collect();
    Ok(LearningCurveReport {
        title: title.to_string(),
        train_poses: pool.len(),
        test_poses: pose_groups(test).len(),
        points,
    })
}

/// Fits to run for `params` on `train_poses` training poses (for a progress bar).
pub fn fits(params: &CurveParams, train_poses: usize) -> usize {
    params
        .sizes
        .iter()
        .filter(|&&n| n <= train_poses)
        .map(|&n| if n == train_poses { 1 } else { 1 + params.draws })
        .sum()
}
