use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Mutex;

use armcomp_core::support::io::write_atomic;

use super::{check_output, read_station_files};

#[derive(clap::Args)]
pub struct Args {
    /// The nominal robot file (its values are the starting point and the priors' centre).
    #[arg(long)]
    robot: PathBuf,
    /// Measurement CSV to choose and fit the model on; several (`--data a.csv --data b.csv`)
    /// are one station each, named by the file name, unless they have a `station` column.
    /// Every station gets its own measurement frame, registered in closed form and refined.
    #[arg(long, required = true)]
    data: Vec<PathBuf>,
    #[command(flatten)]
    rows: super::Rows,
    /// Where to write the chosen model (TOML, or JSON for a .json extension), atomically.
    #[arg(long)]
    out: PathBuf,
    /// Standard deviation of the tracker noise per axis, in mm. Default: estimated from the
    /// data with every fit.
    #[arg(long)]
    noise_mm: Option<f64>,
    /// Standard deviation of the orientation noise per axis (poses, plane contacts' tilts), in
    /// degrees. The noises are declared, not estimated, when `--noise-mm` is given and this too
    /// (or the robot measures no poses); default 0.1 where it is not estimated.
    #[arg(long)]
    noise_deg: Option<f64>,
    /// Outer cross-validation folds that score the rungs.
    #[arg(long, default_value_t = 5)]
    folds: usize,
    #[command(flatten)]
    group: super::GroupBy,
    /// The residual predictor tried on top of the best physical model (gp, mlp, ssa_bp,
    /// ridge, knn), or `none`.
    #[arg(long, default_value = "gp")]
    predictor: String,
    /// Seed of the folds; the same seed gives the same bytes.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Print the ladder as JSON on stdout.
    #[arg(long)]
    json: bool,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let robot = super::load_robot(&args.robot)?;
    let data_files: Vec<&std::path::Path> = args.data.iter().map(|p| p.as_path()).collect();
    check_output(&args.out, &robot, &data_files)?;
    let data = read_station_files(&robot, &args.data, args.rows.rows.as_ref())?;
    let fold_groups = args.group.groups(&data_files, &data.rows)?.map(|(_, g)| g);
    let predictor = (args.predictor.trim() != "none").then(|| args.predictor.trim().to_string());
    let bar = Mutex::new(indicatif::ProgressBar::new(0));
    if let Ok(b) = bar.lock() {
        b.set_style(
            indicatif::ProgressStyle::with_template(
                "choosing the model {bar:30} {pos}/{len} fits  {elapsed} (about {eta} left)",
            )
            .expect("the template is valid"),
        );
    }
    // Ctrl-C ends the cross-validation with the rungs fitted so far, the choice among them
    // fitted on all rows.
    let ladder = crate::stoppable(|cancel| {
        let params = armcomp_api::ops::fit::FitParams {
            noise_mm: args.noise_mm,
            noise_deg: args.noise_deg,
            folds: args.folds,
            seed: args.seed,
            fold_groups,
            predictor,
            cancel: cancel.clone(),
        };
        armcomp_api::ops::fit::run(&robot, &data, params, &|p| {
            if let Ok(b) = bar.lock() {
                b.set_length(p.total as u64);
                b.set_position(p.done as u64);
            }
        })
    });
    if let Ok(b) = bar.lock() {
        b.finish_and_clear();
    }
    let ladder = ladder?;
    let text = ladder.robot.to_text_for(&args.out)?;
    write_atomic(&args.out, text.as_bytes())?;
    let r = &ladder.report;
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&armcomp_api::ops::fit::to_json(&ladder))?
        );
    } else {
        println!(
            "{} rows, nested cross-validation (folds: {}, grouped by {}); every choice made inside the training folds",
            data.samples.len(),
            r.folds,
            args.group
                .group_by
                .as_deref()
                .map_or(r.folds_by.clone(), |c| format!("`{c}`"))
        );
        if r.scored_by != "position" {
            println!("a held-out row's error: {}", r.scored_by);
        }
        println!(
            "{:<26} {:>14} {:>12} {:>9}  verdict",
            "rung", "held-out RMS", "± spread", "time"
        );
        for s in &r.rungs {
            let mean = s.fold_rms_mm.iter().sum::<f64>() / s.fold_rms_mm.len().max(1) as f64;
            let spread = (s.fold_rms_mm.iter().map(|v| (v - mean).powi(2)).sum::<f64>()
                / (s.fold_rms_mm.len().max(2) - 1) as f64)
                .sqrt();
            println!(
                "{:<26} {:>11.3} mm {:>9.3} mm {:>7.1} s  {}: {}",
                s.label,
                s.rms_mm,
                spread,
                s.seconds,
                if s.kept { "kept" } else { "not kept" },
                s.reason
            );
        }
        if let Some(why) = &r.predictor_not_tried {
            println!("residual predictor not tried: {why}");
        }
        let e = &r.evidence;
        println!(
            "chosen: {} (expected held-out RMS {:.3} mm); on all rows the noise is {:.4} ± {:.4} mm per axis, {:.1} of {} parameters determined",
            r.chosen.label(),
            r.expected_rms_mm,
            e.noise_mm,
            e.noise_std_mm,
            e.determined,
            e.n_free
        );
        println!("wrote {}", args.out.display());
    }
    for w in &ladder.calibration.report.warnings {
        eprintln!("warning: {w}");
    }
    if r.interrupted {
        eprintln!(
            "interrupted: the model was chosen among the {} rung(s) whose folds were all fitted before the stop",
            r.rungs.len()
        );
        return Ok(ExitCode::from(130));
    }
    Ok(if ladder.calibration.report.converged {
        ExitCode::SUCCESS
    } else {
        eprintln!(
            "warning: the chosen model's fit did not converge ({}); the best parameters found were written",
            ladder.calibration.report.stop_reason
        );
        ExitCode::from(2)
    })
}
