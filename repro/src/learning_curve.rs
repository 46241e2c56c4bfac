//! Learning curves: held-out error against the number of training poses, for the poses
//! `armcomp plan` chooses and for random subsets of the same training poses.
//!
//! Everything is decided on the training poses alone: the selection sees only them (its
//! workspace is the training pool), the fit only the chosen ones; the held-out poses score.
//! Random subsets of one draw are nested (the first `n` poses of one seeded permutation), so
//! the curve of a draw is a user measuring in random order.

use std::path::Path;

use armcomp_core::algorithms::evaluate::{ErrorStats, position_errors};
use armcomp_core::analysis::design::{Criterion, SelectionParams, select_poses};
use armcomp_core::analysis::prior_choice::{DEFAULT_GRID, choose_prior_scale};
use armcomp_core::calibrate::{CalibrationParams, calibrate};
use armcomp_core::data::measurement::{MeasurementSet, RowSelection, Sample};
use armcomp_core::data::split::{FoldBy, FoldPlan, pose_groups, subset};
use armcomp_core::{Result, Robot};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rayon::prelude::*;
use serde::Serialize;

use crate::agile_justin::{
    MEASUREMENT_STD, MEASUREMENTS, MEASUREMENTS_PATH, STEPS, fit_full_model, half_split, parse_measurements,
};
use crate::twins::Twin;

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

/// The sizes of the demos' curves (poses).
pub const SIZES: [usize; 7] = [20, 40, 60, 80, 100, 150, 250];

/// Agile Justin's curve (`armcomp demo agile-justin --learning-curve`): the paper's full
/// model, fitted step by step as the step table does, on poses of the table's 250 training
/// poses (split `seed`), chosen by `criterion` for the full model's parameters with the
/// fits' tracker noise, or drawn at random (`draws` per size); scored on the 250 held-out
/// poses.
pub fn agile_justin_curve(
    seed: u64,
    criterion: Criterion,
    draws: usize,
    on_fit: &(dyn Fn() + Sync),
) -> Result<LearningCurveReport> {
    let robot = Twin::get("agile-justin").expect("built in").robot()?;
    let samples = parse_measurements(MEASUREMENTS, Path::new(MEASUREMENTS_PATH), &robot)?;
    let split = half_split(&samples, seed)?;
    let (train, test) = (subset(&samples, &split.train), subset(&samples, &split.test));
    let full = STEPS[STEPS.len() - 1];
    let params = CurveParams {
        sizes: SIZES.to_vec(),
        draws,
        seed,
        selection: SelectionParams {
            criterion,
            identify: full.identify.iter().map(|w| w.to_string()).collect(),
            measurement_std: MEASUREMENT_STD,
            ..SelectionParams::default()
        },
    };
    let title = format!(
        "Agile Justin: held-out mean of the full model ({}) against training poses, split seed {seed}",
        full.label
    );
    learning_curve(
        &robot,
        &train,
        &test,
        &params,
        &title,
        &|s| fit_full_model(&robot, s),
        on_fit,
    )
}

/// A TALOS curve: the split, and FIGAROH's full-data joint-offset held-out RMSE on it.
#[derive(Debug, Clone, Serialize)]
pub struct TalosCurve {
    /// `interleaved` or `time` (data/talos-left-arm/README.md).
    pub split: &'static str,
    /// FIGAROH's joint-offset held-out RMSE from all training rows (mm).
    pub figaroh_offsets_rms_mm: f64,
    /// The curve.
    pub report: LearningCurveReport,
}

/// TALOS' splits: name, training rows, held-out rows, FIGAROH's joint-offset held-out RMSE (mm).
pub const TALOS_SPLITS: [(&str, &str, &str, f64); 2] =
    [("interleaved", "even", "odd", 2.14), ("time", "..40", "40..", 3.19)];

/// TALOS' curves (`armcomp demo talos`) on `set` (its measurements for `robot`): on each split,
/// at the joint-offset level without priors (FIGAROH's) and with full geometry held by priors
/// scaled by 5-fold cross-validation on the fitted rows; sizes half the training rows, the
/// [`SIZES`] up to the training rows, and all of them.
pub fn talos_curves(
    robot: &Robot,
    set: &MeasurementSet,
    seed: u64,
    criterion: Criterion,
    draws: usize,
    on_fit: &(dyn Fn() + Sync),
) -> Result<Vec<TalosCurve>> {
    let mut curves = Vec::new();
    for (split, train_rows, test_rows, figaroh) in TALOS_SPLITS {
        let rows = |spec: &str| -> Result<Vec<Sample>> {
            let selection: RowSelection = spec.parse()?;
            Ok(set.select_rows(&selection).samples)
        };
        let (train, test) = (rows(train_rows)?, rows(test_rows)?);
        let n = pose_groups(&train).len();
        let mut sizes: Vec<usize> = SIZES.iter().copied().filter(|&s| s <= n).chain([n / 2, n]).collect();
        sizes.sort_unstable();
        sizes.dedup();
        let levels: [(&str, &str, bool); 2] = [
            ("joint offsets, no priors", "base,markers,offsets", false),
            (
                "full geometry, priors by cross-validation",
                "base,markers,geometry",
                true,
            ),
        ];
        for (level, identify, cv) in levels {
            let identify: Vec<String> = identify.split(',').map(String::from).collect();
            let params = CurveParams {
                sizes: sizes.clone(),
                draws,
                seed,
                selection: SelectionParams {
                    criterion,
                    identify: identify.clone(),
                    ..SelectionParams::default()
                },
            };
            let calibration = CalibrationParams {
                identify,
                use_priors: cv,
                ..CalibrationParams::default()
            };
            let fit = |s: &[Sample]| -> Result<Robot> {
                let mut p = calibration.clone();
                if cv {
                    p.prior_scale = choose_prior_scale(
                        robot,
                        s,
                        &p,
                        &DEFAULT_GRID,
                        &FoldPlan {
                            k: 5,
                            seed: 0,
                            by: FoldBy::choose(s, None),
                        },
                        &|_| {},
                    )?
                    .scale;
                }
                Ok(calibrate(robot, s, &p, &mut |_| {})?.robot)
            };
            let title = format!("TALOS, {split} split: held-out RMSE at the level {level}");
            curves.push(TalosCurve {
                split,
                figaroh_offsets_rms_mm: figaroh,
                report: learning_curve(robot, &train, &test, &params, &title, &fit, on_fit)?,
            });
        }
    }
    Ok(curves)
}
