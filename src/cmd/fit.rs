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
    /// Outer cross-validation folds that score the candidates.
    #[arg(long, default_value_t = 5)]
    folds: usize,
    /// How many times the folds are drawn, each with its own seed: every candidate is scored
    /// on every draw, and the draws' spread is the noise within which the simpler candidate
    /// is preferred. Default: 3, or 1 from 2,000 rows (folds that large barely move the
    /// scores from one draw to the next, and each draw is a whole ladder of fits).
    #[arg(long, value_parser = super::at_least_one)]
    repeats: Option<usize>,
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
    /// Folder for a report (written atomically): index.html, one page with its plots inline
    /// that needs no network, and report.json, every number and plot point of the page.
    #[arg(long, value_name = "DIR")]
    report: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let robot = super::load_robot(&args.robot)?;
    let data_files: Vec<&std::path::Path> = args.data.iter().map(|p| p.as_path()).collect();
    check_output(&args.out, &robot, &data_files)?;
    super::check_report(args.report.as_deref(), &robot, &data_files, Some(&args.out))?;
    let data = read_station_files(&robot, &args.data, args.rows.rows.as_ref())?;
    let grouping = args.group.groups(&data_files, &data.rows)?;
    let group_column = grouping.as_ref().map(|(c, _)| c.clone());
    let fold_groups = grouping.map(|(_, g)| g);
    let predictor = (args.predictor.trim() != "none").then(|| args.predictor.trim().to_string());
    let bar = Mutex::new(crate::progress::bar(
        Some(0),
        "choosing the model {bar:30} {pos}/{len} fits  {elapsed} (about {eta} left)  {msg}",
    ));
    // Seconds of fitting per rung so far (the folds run in parallel: their sum, not the wall
    // time), shown beside the memory the process holds.
    let stages: Mutex<Vec<(&'static str, f64)>> = Mutex::new(Vec::new());
    // Ctrl-C ends the cross-validation with the rungs fitted so far, the choice among them
    // fitted on all rows.
    let ladder = crate::stoppable(|cancel| {
        let params = armcomp_api::ops::fit::FitParams {
            noise_mm: args.noise_mm,
            noise_deg: args.noise_deg,
            folds: args.folds,
            repeats: args.repeats,
            seed: args.seed,
            fold_groups,
            predictor,
            cancel: cancel.clone(),
        };
        armcomp_api::ops::fit::run(&robot, &data, params, &|p| {
            if let (Ok(b), Ok(mut stages)) = (bar.lock(), stages.lock()) {
                b.set_length(p.total as u64);
                b.set_position(p.done as u64);
                if let Some((what, seconds)) = p.last {
                    match stages.iter_mut().find(|(w, _)| *w == what) {
                        Some((_, s)) => *s += seconds,
                        None => stages.push((what, seconds)),
                    }
                    b.set_message(crate::progress::stages_and_memory(&stages));
                }
            }
        })
    });
    if let Ok(b) = bar.lock() {
        b.finish_and_clear();
    }
    let ladder = ladder?;
    let text = ladder.robot.to_text_for(&args.out)?;
    write_atomic(&args.out, text.as_bytes())?;
    if let Some(dir) = &args.report {
        let given = armcomp_api::with_stations(&robot, &data)?;
        let page =
            armcomp_api::model_report::for_fit(given.as_ref().unwrap_or(&robot), &data.samples, &data.rows, &ladder)?;
        armcomp_api::model_report::write(dir, &page)?;
    }
    let r = &ladder.report;
    if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&armcomp_api::ops::fit::to_json(&ladder))?
        );
    } else {
        print_ladder(r, data.samples.len(), group_column.as_deref());
        println!("wrote {}", args.out.display());
        if let Some(dir) = &args.report {
            println!("wrote {}", dir.join("index.html").display());
        }
    }
    for w in &ladder.calibration.report.warnings {
        eprintln!("warning: {w}");
    }
    if let Some(note) = args.group.one_session_note(&data_files, &r.folds_by)? {
        eprintln!("note: {note}");
    }
    if r.interrupted {
        eprintln!(
            "interrupted: the model was chosen among the {} candidate(s) whose folds were all fitted before the stop",
            r.candidates.len()
        );
        return Ok(ExitCode::from(130));
    }
    // As `calibrate`: far above a declared noise, mislabelled units or a fit that describes
    // no robot say the data or the model is wrong.
    let chosen = &ladder.calibration.report;
    if let Some(why) = &chosen.implausible {
        eprintln!("error: {why}");
    }
    if chosen.suspect() {
        eprintln!("warning: the model was written, but check the data and the model (see the messages above)");
        return Ok(ExitCode::from(3));
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

/// The ladder as `fit` prints it: a warning first when the choice is not sound, then every
/// candidate with its score and spread, then the choice and its reason.
fn print_ladder(r: &armcomp_core::analysis::ladder::LadderReport, rows: usize, group_by: Option<&str>) {
    if let Some(w) = &r.warning {
        println!("warning: {w}");
    }
    println!(
        "{rows} rows, cross-validation (folds: {}, drawn {} time(s), grouped by {}); every choice made inside the training folds",
        r.folds,
        r.repeats,
        group_by.map_or(r.folds_by.clone(), |c| format!("`{c}`"))
    );
    if r.scored_by != "position" {
        println!("a held-out row's error: {}", r.scored_by);
    }
    println!(
        "  {:<52} {:>12} {:>10} {:>10} {:>7} {:>8}",
        "candidate", "held-out RMS", "± spread", "excess", "params", "time"
    );
    for c in &r.candidates {
        let mark = if armcomp_api::ops::fit::in_choice(r, c) {
            '*'
        } else if c.within_noise {
            '~'
        } else {
            ' '
        };
        println!(
            "{mark} {:<52} {:>9.3} mm {:>7.3} mm {:>7.3} mm {:>7.1} {:>6.1} s{}",
            c.label,
            c.rms_mm,
            c.spread_mm,
            c.excess_mm,
            c.effective_params,
            c.seconds,
            c.not_sound
                .as_deref()
                .map_or(String::new(), |w| format!("  not sound: {w}"))
        );
    }
    if let Some(why) = &r.predictor_not_tried {
        println!("residual predictor not tried: {why}");
    }
    let e = &r.evidence;
    let chosen = armcomp_api::ops::fit::choice_label(r);
    println!(
        "chosen (*): {}: {} (expected held-out RMS {:.3} mm, the choice itself cross-validated; ~ within the noise of the best); on all rows the noise is {:.4} ± {:.4} mm per axis, {:.1} of {} parameters determined",
        chosen, r.reason, r.expected_rms_mm, e.noise_mm, e.noise_std_mm, e.determined, e.n_free
    );
}
