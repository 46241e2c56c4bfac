//! `armcomp demo agile-justin --learning-curve` and `armcomp demo talos`: held-out error
//! against the number of training poses, for the poses `armcomp plan` chooses and for random
//! subsets, on real measurements (the curves are `armcomp_repro::learning_curve`'s).

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::Context;
use armcomp_core::algorithms::evaluate::ErrorStats;
use armcomp_core::analysis::design::Criterion;
use armcomp_core::data::measurement::read_csv;
use armcomp_repro::agile_justin::{PAPER_FULL_MODEL_MEAN_MM as JUSTIN_TARGET_MM, TARGET_POSES as JUSTIN_TARGET_POSES};
use armcomp_repro::demos::report::Curve;
use armcomp_repro::learning_curve::{LearningCurveReport, agile_justin_curve, talos_curves};

/// CurveParams of the learning-curve demos.
pub struct CurveParams {
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

/// TALOS' robot file and measurements, from the repository root.
const TALOS_ROBOT: &str = "robots/talos-left-arm.toml";
const TALOS_DATA: &str = "data/talos-left-arm/measurements.csv";

/// `result`, its error telling where the default `path` is looked for when the user gave no
/// `flag`; a path the user gave is wrong as the error itself says.
fn default_hint<T>(result: anyhow::Result<T>, defaulted: bool, path: &str, flag: &str) -> anyhow::Result<T> {
    if defaulted {
        result.with_context(|| format!("{path}: run from the repository root, or give {flag}"))
    } else {
        result
    }
}

/// A progress display counting fits (the fits of all curves run one curve after another).
fn progress() -> indicatif::ProgressBar {
    crate::progress::bar(None, "learning curves {spinner} {pos} fits  {elapsed}")
}

/// `armcomp demo agile-justin --learning-curve`.
pub fn agile_justin(opts: &CurveParams) -> anyhow::Result<ExitCode> {
    let bar = progress();
    let curve = agile_justin_curve(opts.seed, opts.criterion, opts.draws, &|| bar.inc(1));
    bar.finish_and_clear();
    let curves = vec![Curve {
        report: curve?,
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

/// `armcomp demo talos`: TALOS' two splits at two levels (the robot file and data are read
/// from the given paths, by default from the repository root's).
pub fn talos(opts: &CurveParams, robot_path: Option<&Path>, data_path: Option<&Path>) -> anyhow::Result<ExitCode> {
    let robot = default_hint(
        super::load_robot(robot_path.unwrap_or(Path::new(TALOS_ROBOT))).map_err(anyhow::Error::from),
        robot_path.is_none(),
        TALOS_ROBOT,
        "--robot",
    )?;
    let set = default_hint(
        read_csv(
            data_path.unwrap_or(Path::new(TALOS_DATA)),
            &robot.csv_layout(),
            super::input_limits(),
        )
        .map_err(anyhow::Error::from),
        data_path.is_none(),
        TALOS_DATA,
        "--data",
    )?;
    let bar = progress();
    let talos = talos_curves(&robot, &set, opts.seed, opts.criterion, opts.draws, &|| bar.inc(1));
    bar.finish_and_clear();
    let curves: Vec<Curve> = talos?
        .into_iter()
        .map(|c| Curve {
            report: c.report,
            metric: "rms",
            reference: Some((
                c.figaroh_offsets_rms_mm,
                "FIGAROH, joint offsets, all training rows".into(),
            )),
        })
        .collect();
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
fn emit(curves: &[Curve], opts: &CurveParams) -> anyhow::Result<()> {
    if let Some(dir) = &opts.report {
        let page = armcomp_repro::demos::report::write_page(dir, &[], curves)?;
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
