use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Context;
use armcomp_api::ops::diagnose::{LearnableBy, NoiseFrom};
use armcomp_core::calibrate::CalibrationParams;

use armcomp_core::algorithms::evaluate::ErrorStats;
use armcomp_core::algorithms::residuals::ResidualDescription;
use armcomp_core::analysis::diagnose::{DiagnoseParams, DiagnoseStage, DiagnosisReport, RankedCandidate};
use armcomp_core::support::io::write_atomic;

use super::{check_output, inputs, read_station_files};

#[derive(Clone, Copy, clap::ValueEnum)]
enum Predictor {
    /// Gaussian process.
    Gp,
    /// Ridge regression (fast baseline).
    Ridge,
    /// Do not score the learnable residual.
    None,
}

#[derive(clap::Args)]
pub struct Args {
    /// The robot file to diagnose (its values are the starting point and the priors' centre).
    #[arg(long)]
    robot: PathBuf,
    /// Measurement CSV; several (`--data a.csv --data b.csv`) are one station each, named by
    /// the file name, unless they have a `station` column. Every station gets its own
    /// measurement frame, registered in closed form and refined.
    #[arg(long, required = true)]
    data: Vec<PathBuf>,
    #[command(flatten)]
    rows: super::Rows,
    /// Where to write the improved robot file (found effects added, calibrated on all the
    /// data), written atomically; never over an input.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Folder for the report: index.html, report.json and SVG plots.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Seed of the k-fold split and of the residual predictor.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Number of folds of the held-out score.
    #[arg(long, default_value_t = 3)]
    folds: usize,
    /// Most effects to add.
    #[arg(long, default_value_t = 5)]
    max_steps: usize,
    /// Smallest held-out RMS reduction, in percent, that an effect must bring to be added.
    #[arg(long, default_value_t = 5.0)]
    min_reduction_percent: f64,
    /// Standard deviation of the tracker noise per axis, in mm: weighs data against priors, and
    /// candidates are judged against the held-out error above the floor it gives. Default: the
    /// model's fit record's, else estimated from the data for the model as given.
    #[arg(long)]
    noise_mm: Option<f64>,
    /// Refit every candidate on the folds, also those the score test at the current fit shows
    /// cannot earn their parameters (slower; for checking the screening).
    #[arg(long)]
    exhaustive: bool,
    /// What to identify besides each candidate, as for `calibrate --identify`.
    #[arg(long, value_delimiter = ',')]
    identify: Vec<String>,
    /// Residual predictor that scores what remains learnable.
    #[arg(long, value_enum, default_value_t = Predictor::Gp)]
    predictor: Predictor,
    /// A run-time plugin library whose error models join the candidates (repeatable); without
    /// an extension the platform's naming applies (`libNAME.so`, ...).
    #[arg(long = "library", value_name = "LIB")]
    libraries: Vec<PathBuf>,
    /// Keep the rows the final model leaves far beyond the noise (over 5 times the robust
    /// noise per axis: a broken line of sight, a typo) instead of searching again without
    /// them; they are listed either way.
    #[arg(long)]
    keep_outliers: bool,
    #[command(flatten)]
    group: super::GroupBy,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    for lib in &args.libraries {
        armcomp_sdk::load_library(lib).with_context(|| format!("--library {}", lib.display()))?;
    }
    let robot = super::load_robot(&args.robot)?;
    let libraries: Vec<PathBuf> = args
        .libraries
        .iter()
        .map(|l| armcomp_sdk::host::platform_library_path(l))
        .collect();
    let data_files: Vec<&std::path::Path> = args.data.iter().map(PathBuf::as_path).collect();
    let read: Vec<&std::path::Path> = (data_files.iter().copied())
        .chain(libraries.iter().map(PathBuf::as_path))
        .collect();
    if let Some(out) = &args.out {
        check_output(out, &robot, &read)?;
    }
    if let Some(dir) = &args.report {
        armcomp_api::diagnosis_report::check(dir, &inputs(&robot, &read))?;
    }
    let data = read_station_files(&robot, &args.data, args.rows.rows.as_ref())?;
    let given = CalibrationParams {
        identify: args.identify.clone(),
        measurement_std: args.noise_mm.unwrap_or(0.1) * 1e-3,
        ..CalibrationParams::default()
    };
    let (calibration, noise_from) =
        armcomp_api::ops::diagnose::calibration_for(&robot, &data, given, args.noise_mm.is_some())?;
    let params = DiagnoseParams {
        fold_groups: args.group.groups(&data_files, &data.rows)?,
        folds: args.folds,
        seed: args.seed,
        calibration,
        min_rms_reduction: args.min_reduction_percent / 100.0,
        max_steps: args.max_steps,
        exhaustive: args.exhaustive,
        exclude_gross_errors: !args.keep_outliers,
    };
    let learnable_by = match args.predictor {
        Predictor::Gp => LearnableBy::Gp,
        Predictor::Ridge => LearnableBy::Ridge,
        Predictor::None => LearnableBy::None,
    };
    let bar = crate::progress::bar(
        Some(0),
        "{msg} {bar:30} {pos}/{len} fold calibrations  {elapsed} (about {eta} left)",
    );
    let result = crate::stoppable(|cancel| {
        let mut params = params.clone();
        params.calibration.cancel = cancel.clone();
        armcomp_api::ops::diagnose::run(&robot, &data, &params, learnable_by, &|p| {
            // A new stage restarts the bar, so that its estimate is the stage's own.
            if bar.length() != Some(p.total as u64) || p.done == 0 {
                bar.reset();
                bar.set_length(p.total as u64);
                bar.set_message(match p.stage {
                    DiagnoseStage::Baseline => "model as given:".to_string(),
                    DiagnoseStage::Round(n) => format!("effect {n}, candidates that can win:"),
                    DiagnoseStage::Learnable => "learnable residual:".to_string(),
                });
            }
            bar.set_position(p.done as u64);
        })
    });
    bar.finish_and_clear();
    let diagnosis = result?;
    let report = &diagnosis.report;
    let mut notes = vec![format!(
        "noise {:.4} mm per axis ({}): candidates are judged against the held-out error above its floor",
        params.calibration.measurement_std * 1e3,
        match noise_from {
            NoiseFrom::Declared => "--noise-mm",
            NoiseFrom::FitRecord => "the model's fit record",
            NoiseFrom::Estimated => "estimated from the data for the model as given",
        }
    )];
    if let Some(out) = &args.out {
        let control = armcomp_core::FitControl {
            progress: None,
            cancel: armcomp_core::support::cancel::Cancel::default(),
        };
        let (model, note) = armcomp_api::ops::diagnose::output_model(&robot, &diagnosis, &data.samples, &control)?;
        notes.extend(note);
        let text = model.as_ref().unwrap_or(&robot).to_text_for(out)?;
        write_atomic(out, text.as_bytes())?;
    }
    if let Some(dir) = &args.report {
        armcomp_api::diagnosis_report::write(dir, report)?;
    }
    // The gross errors as data rows (0-based, as --rows counts them).
    let gross_rows = armcomp_api::ops::diagnose::gross_error_rows(report, &data.rows);
    if args.json {
        let value = armcomp_api::ops::diagnose::to_json(report, &data.rows);
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        for n in &notes {
            println!("{n}");
        }
        print_report(report, &gross_rows);
        if let Some(out) = &args.out {
            println!("wrote {}", out.display());
        }
        if let Some(dir) = &args.report {
            println!("wrote {}", dir.join("index.html").display());
        }
    }
    if report.interrupted {
        eprintln!(
            "interrupted: the model and report hold the {} effect(s) found before the stop",
            report.steps.len()
        );
        return Ok(ExitCode::from(130));
    }
    Ok(ExitCode::SUCCESS)
}

fn stats(s: &ErrorStats) -> String {
    format!("{:>8.4} {:>8.4} {:>8.4}", s.mean_mm, s.rms_mm, s.max_mm)
}

fn print_residuals(title: &str, d: &ResidualDescription) {
    println!("{title}");
    for a in &d.axes {
        println!("  {}: mean {:+.4} mm, RMS {:.4} mm", a.axis, a.mean_mm, a.rms_mm);
    }
    println!(
        "  {:<28} {:>7} {:>7} {:>7} {:>7}",
        "correlation with", "x", "y", "z", "|e|"
    );
    for c in &d.correlations {
        println!(
            "  {:<28} {:>+7.2} {:>+7.2} {:>+7.2} {:>+7.2}",
            format!("{} ({})", c.variable, c.unit),
            c.r[0],
            c.r[1],
            c.r[2],
            c.r[3]
        );
    }
}

fn print_ranking(ranking: &[RankedCandidate]) {
    for c in ranking.iter().take(5) {
        match &c.heldout {
            Some(h) => println!(
                "    {:<48} {:>2}/{} params  RMS {:.4} mm  {:+6.1}%{}{}",
                c.label,
                c.identified_params,
                c.n_params,
                h.rms_mm,
                -100.0 * c.share_removed,
                if c.earns_parameters {
                    String::new()
                } else {
                    format!("  (not kept: {})", c.verdict)
                },
                if c.indistinguishable_from_best {
                    "  (the data cannot tell it from the first)"
                } else {
                    ""
                }
            ),
            None if !c.refitted => println!("    {:<48} ({})", c.label, c.verdict),
            None => println!("    {:<48} failed: {}", c.label, c.error.as_deref().unwrap_or("")),
        }
    }
}

fn print_report(r: &DiagnosisReport, gross_rows: &[usize]) {
    let what = if r.gross_errors_excluded {
        " (0-based as --rows counts): the search was made again without them (--keep-outliers keeps them)"
    } else {
        " (0-based as --rows counts): kept"
    };
    super::print_gross_errors("of the final model ", gross_rows, what, r.drift.as_ref());
    println!(
        "{} {}, held-out scores (mean / RMS / max in mm; folds: {}, grouped by {})",
        r.n_samples,
        armcomp_api::diagnosis_report::rows_scored_by(r),
        r.folds,
        r.grouped_by
    );
    print_residuals("held-out residuals of the model as given:", &r.initial_residuals);
    println!(
        "\n{:<4} {:<40} {:>26}   {:>26} {:>8}",
        "step", "effect", "before", "after", "removed"
    );
    println!("{:<4} {:<40} {:>26}", "0", "model as given", stats(&r.initial));
    for (i, s) in r.steps.iter().enumerate() {
        println!(
            "{:<4} {:<40} {}   {} {:>7.1}%",
            i + 1,
            s.label,
            stats(&s.heldout_before),
            stats(&s.heldout_after),
            100.0 * s.share_removed
        );
    }
    if !r.per_kind.is_empty() {
        println!("each kind of row on its own (held-out RMS as given → at the end):");
        for k in &r.per_kind {
            println!(
                "     {:<40} n {:<5} {:.4} → {:.4} mm",
                k.kind, k.n, k.before_rms_mm, k.after_rms_mm
            );
        }
    }
    for (i, s) in r.steps.iter().enumerate() {
        println!("\nstep {}: {}", i + 1, s.summary);
        print_ranking(&s.ranking);
    }
    if r.interrupted {
        println!("\ninterrupted while searching for effect {}", r.steps.len() + 1);
    }
    if !r.final_model.ranking.is_empty() {
        println!("\nno further candidate earns its parameters; best of the last round:");
        print_ranking(&r.final_model.ranking);
    }
    println!();
    print_residuals("held-out residuals at the end:", &r.final_model.residuals);
    if let Some(l) = &r.learnable_residual {
        println!(
            "\nlearnable residual ({}): held-out RMS {:.4} → {:.4} mm; {:.0}% of what remains is unexplained but learnable",
            l.predictor,
            l.heldout_before.rms_mm,
            l.heldout_after.rms_mm,
            100.0 * l.share_learnable
        );
    }
}
