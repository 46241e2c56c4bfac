use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, bail};
use armcomp_core::support::io::write_atomic;
use armcomp_core::{FitControl, RobotFile, TrainingProgress};

use super::{check_output, read_measurements};

#[derive(clap::Args)]
pub struct Args {
    /// The model (e.g. written by `armcomp calibrate`); its `[predictor]` table says what to
    /// fit unless `--predictor` does.
    #[arg(long)]
    model: PathBuf,
    /// Fit this predictor type with its default settings (gp, mlp, ssa_bp, ridge, knn; see
    /// `armcomp plugins`), replacing the model's `[predictor]` table.
    #[arg(long)]
    predictor: Option<String>,
    /// Measurement CSV to learn the model's residual from (one or several points).
    #[arg(long)]
    data: PathBuf,
    #[command(flatten)]
    rows: super::Rows,
    /// Where to write the model with the fitted predictor (written atomically).
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    group: super::GroupBy,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let robot = super::load_robot(&args.model)?;
    let predictor = args
        .predictor
        .as_deref()
        .map(armcomp_api::ops::learn::default_predictor)
        .transpose()?;
    if predictor.is_none() && robot.predictor_spec().is_none() {
        bail!(
            "{}: no [predictor] table; name one with --predictor (e.g. gp) or add a `[predictor]` table",
            args.model.display()
        );
    }
    check_output(&args.out, &robot, &[&args.data])?;
    let data = read_measurements(&robot, &args.data, args.rows.rows.as_ref())?;
    // The written file is the model's own text re-read, so everything in it is kept.
    let (file, _) =
        RobotFile::read(&args.model, super::input_limits()).with_context(|| format!("{}", args.model.display()))?;
    let groups = args.group.groups(&[&args.data], &data.rows)?;
    let bar = crate::progress::bar(Some(0), "{msg:>12} {bar:30} {pos}/{len} {elapsed_precise}");
    // Each optimiser, then the cross-validation's folds, restarts the bar.
    let progress = |p: TrainingProgress| {
        if bar.message() != p.stage || bar.length() != Some(p.total as u64) {
            bar.reset();
            bar.set_message(p.stage);
            bar.set_length(p.total as u64);
        }
        bar.set_position(p.done as u64);
    };
    let control = FitControl {
        progress: Some(&progress),
        ..FitControl::default()
    };
    let run = armcomp_api::ops::learn::run(&robot, file, &data.samples, predictor, groups, &control);
    bar.finish_and_clear();
    let run = run?;
    let (seconds, before, after) = (run.seconds, run.before, run.after);
    write_atomic(&args.out, run.robot.to_text_for(&args.out)?.as_bytes())?;
    println!("fitted in {seconds:.2} s on {} measurements", data.samples.len());
    // One footing for every line: the same rows, measured minus modelled position, mean and RMS
    // of its length; only whether the predictor saw the row differs.
    println!("position error on these rows (mm)              mean      RMS");
    let line = |what: &str, s: &armcomp_core::algorithms::evaluate::ErrorStats| {
        println!("  {what:<44} {:>8.4} {:>8.4}", s.mean_mm, s.rms_mm);
    };
    line("model alone", &before);
    line("with the predictor, rows it was fitted on", &after);
    if let Some((cv, folding)) = &run.cross_validated {
        line("with the predictor, rows it was not fitted on", cv);
        println!(
            "  (the model alone was not fitted here: its figure holds for any rows; the predictor's on its own \
             rows is optimistic, on rows it did not see, each predicted by a fit on the other folds of \
             cross-validation, {folding}, it is what to expect of new rows)"
        );
    }
    if let Some(r) = &run.refitted {
        line("fitted again in every fold: the model alone", &r.model);
        line("fitted again in every fold: with the predictor", &r.with_predictor);
        println!(
            "  (the model's fit record: each fold's training rows fit the physical model again, from where `fit` \
             started and as it fitted, then the predictor; these are the figures `fit` scored the model by, and \
             what to expect of new rows)"
        );
    }
    println!("wrote {}", args.out.display());
    for w in run.warnings() {
        eprintln!("warning: {w}");
    }
    if let Some((_, folding)) = &run.cross_validated
        && let Some(note) = args.group.one_session_note(&[&args.data], &folding.grouped_by)?
    {
        eprintln!("note: {note}");
    }
    Ok(ExitCode::SUCCESS)
}
