//! `armcomp demo agile-justin --learning-curve` and `armcomp demo talos`: held-out error
//! against the number of training poses, for the poses `armcomp plan` chooses and for random
//! subsets, on real measurements.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use armcomp::agile_justin::{MEASUREMENT_STD, MEASUREMENTS, MEASUREMENTS_PATH, STEPS, fit_full_model, half_split};
use armcomp::demos::report::Curve;
use armcomp::learning_curve::{CurveParams, LearningCurveReport, fits, learning_curve};
use armcomp::twins::Twin;
use armcomp_core::calibrate::{CalibrationParams, calibrate};
use armcomp_core::design::{Criterion, SelectionParams};
use armcomp_core::evaluate::ErrorStats;
use armcomp_core::measurement::{Sample, read_csv};
use armcomp_core::prior_choice::{DEFAULT_GRID, choose_prior_scale};
use armcomp_core::split::subset;
use armcomp_core::{Result, Robot};

/// Options of the learning-curve demos.
pub struct Options {
    /// Print the curves as JSON on stdout.
    pub json: bool,
    /// Seed of the split (Agile Justin) and of the random subsets.
    pub seed: u64,
    /// How the tool chooses.
    pub criterion: Criterion,
    /// Random subsets per size.
    pub draws: usize,
    /// Also write the HTML report into this folder.
    pub report: Option<PathBuf>,
}

/// The sizes of the curves (poses).
pub const SIZES: [usize; 7] = [20, 40, 60, 80, 100, 150, 250];

/// The paper's full-data held-out mean on Agile Justin (mm).
const JUSTIN_TARGET_MM: f64 = 3.12;

/// The most tool-chosen poses the Agile Justin target allows.
const JUSTIN_TARGET_POSES: usize = 80;

fn progress(total: usize, what: &str) -> indicatif::ProgressBar {
    let bar = indicatif::ProgressBar::new(total as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template(&format!("{what} {{bar:30}} {{pos}}/{{len}} fits  {{elapsed}}"))
            .expect("the template is valid"),
    );
    bar
}

fn run_curve(
    robot: &Robot,
    train: &[Sample],
    test: &[Sample],
    params: &CurveParams,
    title: &str,
    fit: &(dyn Fn(&[Sample]) -> Result<Robot> + Sync),
) -> anyhow::Result<LearningCurveReport> {
    let bar = progress(fits(params, armcomp_core::split::pose_groups(train).len()), title);
    let curve = learning_curve(robot, train, test, params, title, fit, &|| bar.inc(1));
    bar.finish_and_clear();
    Ok(curve?)
}

/// `armcomp demo agile-justin --learning-curve`: the paper's full model fitted step by step on
/// the chosen poses of the 250 training poses, scored on the 250 held-out poses.
pub fn agile_justin(opts: &Options) -> anyhow::Result<ExitCode> {
    let robot = Twin::get("agile-justin").expect("built in").robot()?;
    let samples = armcomp::agile_justin::parse_measurements(MEASUREMENTS, Path::new(MEASUREMENTS_PATH), &robot)?;
    let split = half_split(&samples, opts.seed)?;
    let (train, test) = (subset(&samples, &split.train), subset(&samples, &split.test));
    let full = STEPS[STEPS.len() - 1];
    let params = CurveParams {
        sizes: SIZES.to_vec(),
        draws: opts.draws,
        seed: opts.seed,
        selection: SelectionParams {
            criterion: opts.criterion,
            identify: full.identify.iter().map(|w| w.to_string()).collect(),
            measurement_std: MEASUREMENT_STD,
            ..SelectionParams::default()
        },
    };
    let title = format!(
        "Agile Justin: held-out mean of the full model ({}) against training poses, split seed {}",
        full.label, opts.seed
    );
    let curve = run_curve(&robot, &train, &test, &params, &title, &|s| fit_full_model(&robot, s))?;
    let curves = vec![Curve {
        report: curve,
        metric: "mean",
        reference: Some((JUSTIN_TARGET_MM, "paper, 250 poses".into())),
    }];
    emit(&curves, opts)?;
    if !opts.json {
        justin_targets(&curves[0].report);
    }
    Ok(ExitCode::SUCCESS)
}

/// Whether the Agile Justin targets hold, with the numbers.
fn justin_targets(c: &LearningCurveReport) {
    let reached = c
        .points
        .iter()
        .find(|p| p.size <= JUSTIN_TARGET_POSES && p.selected.mean_mm <= JUSTIN_TARGET_MM);
    match reached {
        Some(p) => println!(
            "   target: held-out mean ≤ {JUSTIN_TARGET_MM} mm from at most {JUSTIN_TARGET_POSES} chosen poses: met ({:.2} mm from {})",
            p.selected.mean_mm, p.size
        ),
        None => {
            let best = c
                .points
                .iter()
                .filter(|p| p.size <= JUSTIN_TARGET_POSES)
                .map(|p| format!("{} poses {:.2} mm", p.size, p.selected.mean_mm))
                .collect::<Vec<_>>()
                .join(", ");
            println!(
                "   target: held-out mean ≤ {JUSTIN_TARGET_MM} mm from at most {JUSTIN_TARGET_POSES} chosen poses: NOT met ({best})"
            );
        }
    }
    beats_median(c, |s| s.mean_mm);
}

/// Prints at how many sizes the choice beats the median random subset.
fn beats_median(c: &LearningCurveReport, stat: fn(&ErrorStats) -> f64) {
    let compared: Vec<_> = c.points.iter().filter(|p| p.size < c.train_poses).collect();
    let wins: Vec<String> = compared
        .iter()
        .filter(|p| stat(&p.selected) < p.random_summary(stat)[1])
        .map(|p| p.size.to_string())
        .collect();
    println!(
        "   target: the choice beats the median random subset at every size below all {} training poses: {} ({} of {}{})",
        c.train_poses,
        if wins.len() == compared.len() { "met" } else { "NOT met" },
        wins.len(),
        compared.len(),
        if wins.is_empty() {
            String::new()
        } else {
            format!(": {}", wins.join(", "))
        }
    );
}

/// FIGAROH's full-data joint-offset held-out RMSE per split (mm).
const FIGAROH_OFFSETS_RMS: [(&str, &str, &str, f64); 2] =
    [("interleaved", "even", "odd", 2.14), ("time", "..40", "40..", 3.19)];

/// `armcomp demo talos`: TALOS' two splits, at the joint-offset level (FIGAROH's, no priors)
/// and with full geometry (priors scaled by cross-validation on the chosen poses).
pub fn talos(opts: &Options, robot_path: &Path, data_path: &Path) -> anyhow::Result<ExitCode> {
    let robot = armcomp::load_robot(robot_path).with_context(|| {
        format!(
            "{}: run from the repository root, or give --robot",
            robot_path.display()
        )
    })?;
    let set = read_csv(data_path, &robot.csv_layout())
        .with_context(|| format!("{}: run from the repository root", data_path.display()))?;
    let mut curves = Vec::new();
    for (split, train_rows, test_rows, figaroh) in FIGAROH_OFFSETS_RMS {
        let train = set
            .select_rows(&train_rows.parse().map_err(anyhow::Error::msg)?)
            .samples;
        let test = set.select_rows(&test_rows.parse().map_err(anyhow::Error::msg)?).samples;
        let n = train.len();
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
                draws: opts.draws,
                seed: opts.seed,
                selection: SelectionParams {
                    criterion: opts.criterion,
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
                    p.prior_scale = choose_prior_scale(&robot, s, &p, &DEFAULT_GRID, 5, 0)?.scale;
                }
                Ok(calibrate(&robot, s, &p, &mut |_| {})?.robot)
            };
            let title = format!("TALOS, {split} split: held-out RMSE at the level {level}");
            let curve = run_curve(&robot, &train, &test, &params, &title, &fit)?;
            curves.push(Curve {
                report: curve,
                metric: "rms",
                reference: Some((figaroh, "FIGAROH, joint offsets, all training rows".into())),
            });
        }
    }
    emit(&curves, opts)?;
    if !opts.json {
        for c in &curves {
            let figaroh = c.reference.as_ref().map_or(f64::NAN, |r| r.0);
            let half = c.report.train_poses / 2;
            if let Some(p) = c.report.points.iter().find(|p| p.size == half) {
                println!(
                    "   {}: from {half} chosen rows {:.2} mm RMSE against FIGAROH's {figaroh} from all {}: {}",
                    c.report.title,
                    p.selected.rms_mm,
                    c.report.train_poses,
                    if p.selected.rms_mm <= figaroh { "met" } else { "NOT met" }
                );
            }
            beats_median(&c.report, |s| s.rms_mm);
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// Prints the curves (text or JSON) and writes the report.
fn emit(curves: &[Curve], opts: &Options) -> anyhow::Result<()> {
    if let Some(dir) = &opts.report {
        let page = armcomp::demos::report::write_page(dir, &[], curves)?;
        eprintln!("wrote {}", page.display());
    }
    if opts.json {
        let value: Vec<&LearningCurveReport> = curves.iter().map(|c| &c.report).collect();
        println!("{}", serde_json::to_string_pretty(&value)?);
        return Ok(());
    }
    for c in curves {
        let stat = c.stat();
        println!(
            "== {} ({} training poses, {} held out; {} choice, random: {} seeded draws)",
            c.report.title,
            c.report.train_poses,
            c.report.test_poses,
            opts.criterion.name(),
            opts.draws
        );
        println!(
            "   {:>5}  {:>22}  {:>36}",
            "poses",
            format!("choice {} mm", c.metric),
            format!("random {} mm: mean, median (min–max)", c.metric)
        );
        for p in &c.report.points {
            let [mean, median, lo, hi] = p.random_summary(stat);
            println!(
                "   {:>5}  {:>22.2}  {:>14.2} {:>7.2} ({:.2}–{:.2})",
                p.size,
                stat(&p.selected),
                mean,
                median,
                lo,
                hi
            );
        }
    }
    Ok(())
}
