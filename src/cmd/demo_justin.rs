//! `armcomp demo agile-justin`: the paper's calibration table reproduced on DLR's 500 real
//! measurements, on the fitted poses and on held-out poses, beside the published numbers.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use armcomp_core::PredictorSpec;
use armcomp_core::algorithms::evaluate::ErrorStats;
use armcomp_core::analysis::diagnose::DiagnosisReport;
use armcomp_repro::agile_justin::{
    GROUPS, STEPS, StepResult, diagnose_from_frames, half_split, kfold_errors, leave_one_out, parse_measurements,
    step_table,
};
use armcomp_repro::agile_justin::{MEASUREMENTS, MEASUREMENTS_PATH};
use armcomp_repro::twins::Twin;
use serde::Serialize;

/// JustinParams of `armcomp demo agile-justin`.
pub struct JustinParams {
    /// Print the results as JSON on stdout.
    pub json: bool,
    /// Folds of the cross-validation (0 skips it).
    pub folds: usize,
    /// Seed of the 250 / 250 split and of the folds.
    pub seed: u64,
    /// Leave out the residual predictor (ridge regression on the joint angles' sines and
    /// cosines) over the calibrated elastic model.
    pub no_predictor: bool,
    /// Run the paper's leave-one-out analysis on the fixed split.
    pub leave_one_out: bool,
    /// Most effects `armcomp diagnose` may add to the frames-only model (0 skips it).
    pub diagnose_steps: usize,
    /// Also write the HTML report (tables and plots of the held-out errors) into this folder.
    pub report: Option<PathBuf>,
}

/// Folds of the diagnosis' held-out scores (its default).
const DIAGNOSE_FOLDS: usize = 3;

/// The full model without one parameter group: the paper's number and ours (held-out).
#[derive(Serialize)]
struct LeaveOneOutRow {
    group: &'static str,
    paper_mean_mm: f64,
    heldout: ErrorStats,
}

#[derive(Serialize)]
struct Output {
    poses: usize,
    seed: u64,
    steps: Vec<StepResult>,
    folds: usize,
    kfold_test: Vec<ErrorStats>,
    leave_one_out: Vec<LeaveOneOutRow>,
    diagnosis: Option<DiagnosisReport>,
    seconds: f64,
}

fn cells(s: &ErrorStats) -> String {
    format!("{:>6.2} {:>6.2} {:>6.2}", s.mean_mm, s.std_mm, s.max_mm)
}

/// The work of one fold: every step of the table fitted once, about ten seconds.
const FOLD_FLOPS: f64 = 1e10;

pub fn run(opts: &JustinParams) -> anyhow::Result<ExitCode> {
    let started = std::time::Instant::now();
    let robot = Twin::get("agile-justin").expect("built in").robot()?;
    let samples = parse_measurements(MEASUREMENTS, Path::new(MEASUREMENTS_PATH), &robot)?;
    let split = half_split(&samples, opts.seed)?;
    if opts.folds > 0 {
        // The folds are checked before the step table's seconds of fitting, not after.
        armcomp_core::data::split::kfold(&samples, opts.folds, opts.seed)?;
        armcomp_core::support::limits::check("--folds", opts.folds, "folds", &|k| {
            armcomp_core::support::limits::Cost::per_unit(k, 0.0, FOLD_FLOPS)
        })?;
    }
    let predictor = armcomp_repro::agile_justin::PREDICTOR;
    let predictor: Option<&dyn PredictorSpec> = (!opts.no_predictor).then_some(&predictor);
    let steps = step_table(&robot, &samples, &split, &STEPS, predictor)?;
    let kfold = if opts.folds > 0 {
        kfold_errors(&robot, &samples, opts.folds, opts.seed, &STEPS, predictor)?
    } else {
        Vec::new()
    };
    let kfold_test = kfold.iter().map(|f| ErrorStats::from_errors(&f.test_errors)).collect();
    let leave_one_out = if opts.leave_one_out {
        let stats = leave_one_out(&robot, &samples, &split)?;
        GROUPS
            .iter()
            .zip(stats)
            .map(|(g, heldout)| LeaveOneOutRow {
                group: g.label,
                paper_mean_mm: g.paper_mean_mm,
                heldout,
            })
            .collect()
    } else {
        Vec::new()
    };
    let diagnosis = if opts.diagnose_steps > 0 {
        Some(diagnose_from_frames(
            &robot,
            &samples,
            &armcomp_api::plugins(),
            DIAGNOSE_FOLDS,
            opts.seed,
            opts.diagnose_steps,
        )?)
    } else {
        None
    };
    if let Some(dir) = &opts.report {
        let tables = armcomp_repro::demos::agile_justin::tables(
            samples.len() / 2,
            split.train.len() / 2,
            opts.seed,
            &steps,
            (opts.folds > 0).then_some((opts.folds, kfold.as_slice())),
        );
        let page = armcomp_repro::demos::report::write(dir, &tables)?;
        eprintln!("wrote {}", page.display());
    }
    let out = Output {
        poses: samples.len() / 2,
        seed: opts.seed,
        steps,
        folds: opts.folds,
        kfold_test,
        leave_one_out,
        diagnosis,
        seconds: started.elapsed().as_secs_f64(),
    };
    if opts.json {
        println!("{}", serde_json::to_string_pretty(&out)?);
        return Ok(ExitCode::SUCCESS);
    }
    println!(
        "== agile-justin: {} poses, 2 markers each ({MEASUREMENTS_PATH}); split {} / {} poses (seed {})",
        out.poses,
        split.train.len() / 2,
        split.test.len() / 2,
        out.seed
    );
    println!("   residual marker error, mm: mean std max");
    let kf = if out.folds > 0 {
        format!("  {:>2}-fold held-out   ", out.folds)
    } else {
        String::new()
    };
    println!(
        "   {:<30} {:<20}  {:<20}  {:<20}{kf}",
        "step", "paper", "fitted", "held-out"
    );
    for (i, s) in out.steps.iter().enumerate() {
        let paper = s.published.map_or(format!("{:>20}", "-"), |p| {
            format!("{:>6.2} {:>6.2} {:>6.2}", p.mean_mm, p.std_mm, p.max_mm)
        });
        let k = out
            .kfold_test
            .get(i)
            .map(|k| format!("  {}", cells(k)))
            .unwrap_or_default();
        println!("   {:<30} {paper}  {}  {}{k}", s.step, cells(&s.train), cells(&s.test));
    }
    if !out.leave_one_out.is_empty() {
        let last = out.steps.get(STEPS.len() - 1).map_or(f64::NAN, |s| s.test.mean_mm);
        println!(
            "\n   leave one out: the full model without one group, held-out mean (mm; full model {last:.2}, paper {})",
            armcomp_repro::agile_justin::PAPER_FULL_MODEL_MEAN_MM
        );
        println!("   {:<52} {:>6} {:>6}", "without", "paper", "ours");
        for r in &out.leave_one_out {
            println!("   {:<52} {:>6.2} {:>6.2}", r.group, r.paper_mean_mm, r.heldout.mean_mm);
        }
    }
    if let Some(d) = &out.diagnosis {
        print_diagnosis(d);
    }
    println!("   ({:.1} s)", out.seconds);
    Ok(ExitCode::SUCCESS)
}

/// The effects `armcomp diagnose` adds to the frames-only model, beside the paper's ranking.
fn print_diagnosis(d: &DiagnosisReport) {
    println!(
        "\n   armcomp diagnose from the frames-only model ({}-fold held-out, mean / RMS mm)",
        d.folds
    );
    println!("   {:<4} {:<52} {:>6} {:>6}", "step", "effect", "mean", "RMS");
    println!(
        "   {:<4} {:<52} {:>6.2} {:>6.2}",
        0, "frames only (base + markers)", d.initial.mean_mm, d.initial.rms_mm
    );
    for (i, s) in d.steps.iter().enumerate() {
        println!(
            "   {:<4} + {:<50} {:>6.2} {:>6.2}",
            i + 1,
            s.label,
            s.heldout_after.mean_mm,
            s.heldout_after.rms_mm
        );
    }
    match d.final_model.ranking.first() {
        Some(best) => println!(
            "   stopped: the best next candidate ({}) is not kept: {}",
            best.label, best.verdict
        ),
        None => println!("   stopped at the step limit"),
    }
    let paper: Vec<&str> = GROUPS.iter().map(|g| g.label).collect();
    println!("   paper's leave-one-out ranking: {}", paper.join(" > "));
}
