//! `armcomp demo agile-justin`: the paper's calibration table reproduced on DLR's 500 real
//! measurements, on the fitted poses and on held-out poses, beside the published numbers.

use std::path::Path;
use std::process::ExitCode;

use armcomp::agile_justin::{MEASUREMENTS, MEASUREMENTS_PATH};
use armcomp::agile_justin::{STEPS, StepResult, half_split, kfold_table, parse_measurements, step_table};
use armcomp::twins::Twin;
use armcomp_core::PredictorSpec;
use armcomp_core::evaluate::ErrorStats;
use serde::Serialize;

/// Options of `armcomp demo agile-justin`.
pub struct Options {
    /// Print the results as JSON on stdout.
    pub json: bool,
    /// Folds of the cross-validation (0 skips it).
    pub folds: usize,
    /// Seed of the 250 / 250 split and of the folds.
    pub seed: u64,
    /// Leave out the residual predictor (ridge regression on the joint angles' sines and
    /// cosines) over the calibrated elastic model.
    pub no_predictor: bool,
}

#[derive(Serialize)]
struct Output {
    poses: usize,
    seed: u64,
    steps: Vec<StepResult>,
    folds: usize,
    kfold_test: Vec<ErrorStats>,
    seconds: f64,
}

fn cells(s: &ErrorStats) -> String {
    format!("{:>6.2} {:>6.2} {:>6.2}", s.mean_mm, s.std_mm, s.max_mm)
}

pub fn run(opts: &Options) -> anyhow::Result<ExitCode> {
    let started = std::time::Instant::now();
    let robot = Twin::get("agile-justin").expect("built in").robot()?;
    let samples = parse_measurements(MEASUREMENTS, Path::new(MEASUREMENTS_PATH), &robot)?;
    let split = half_split(&samples, opts.seed)?;
    let predictor = armcomp_learn::RidgeSpec {
        lambda: 0.05,
        degree: 1,
        trig: true,
    };
    let predictor: Option<&dyn PredictorSpec> = (!opts.no_predictor).then_some(&predictor);
    let steps = step_table(&robot, &samples, &split, &STEPS, predictor)?;
    let kfold_test = if opts.folds > 0 {
        kfold_table(&robot, &samples, opts.folds, opts.seed, &STEPS, predictor)?
    } else {
        Vec::new()
    };
    let out = Output {
        poses: samples.len() / 2,
        seed: opts.seed,
        steps,
        folds: opts.folds,
        kfold_test,
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
    println!("   ({:.1} s)", out.seconds);
    Ok(ExitCode::SUCCESS)
}
