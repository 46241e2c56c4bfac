use std::path::PathBuf;
use std::process::ExitCode;

use armcomp_api::ops::calibrate::Prior;
use armcomp_core::calibrate::{CalibrationParams, CalibrationReport, Loss};
use armcomp_core::model::param::Quantity;
use armcomp_core::support::cancel::Cancel;
use armcomp_core::support::io::write_atomic;

use super::{check_output, read_stations};

/// `--loss`: the cost each row's residual adds.
#[derive(Clone, Copy, clap::ValueEnum)]
enum LossArg {
    /// Least squares.
    Squared,
    /// Huber's loss: squared near the fit, linear far from it.
    Huber,
}

#[derive(clap::Args)]
pub struct Args {
    /// The nominal robot file (its values are the starting point and the priors' centre).
    #[arg(long)]
    robot: PathBuf,
    /// Measurement CSV to identify from; several (`--data a.csv --data b.csv`) are one
    /// station each, named by the file name, unless they have a `station` column. Every
    /// station gets its own measurement frame (`base[<station>].x` …).
    #[arg(long, required = true)]
    data: Vec<PathBuf>,
    #[command(flatten)]
    rows: super::Rows,
    /// Where to write the identified model: the robot file with identified values (TOML, or
    /// JSON for a .json extension), written atomically.
    #[arg(long)]
    out: PathBuf,
    /// What to identify, comma-separated: base, markers, geometry, offsets, errors, all, an
    /// error model's type (joint_compliance, ...) or a parameter pattern (j2.*).
    /// Default: base,markers,geometry,errors.
    #[arg(long, value_delimiter = ',')]
    identify: Vec<String>,
    /// Standard deviation of the tracker noise per axis, in mm (weighs data against priors).
    /// Default: estimated from the data with the fit (the evidence's maximum).
    #[arg(long)]
    noise_mm: Option<f64>,
    /// Standard deviation of the measured orientation per axis, in degrees, when the robot
    /// file measures poses (weighs orientations against positions). The noise is declared,
    /// not estimated, only when both --noise-mm and this are given.
    #[arg(long)]
    noise_deg: Option<f64>,
    /// Most Levenberg–Marquardt iterations.
    #[arg(long, default_value_t = 100)]
    max_iterations: usize,
    /// How strongly the robot file's priors hold the parameters: a factor on their standard
    /// deviations (1 as written, 0.1 ten times tighter), `none`, or `auto` (chosen by 5-fold
    /// cross-validation on the given data alone).
    #[arg(long, default_value = "1")]
    prior: Prior,
    /// Restarts from perturbed starts when the fit ends more than 1.5 times above the noise
    /// (a local minimum, or an effect the model lacks) and a free parameter has several minima
    /// (backlash, rigidity scales) or the fit did not converge; the lowest cost is kept.
    #[arg(long, default_value_t = 2)]
    restarts: usize,
    /// Seed of the restarts' perturbations; the same seed gives the same bytes.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Fit again without the rows whose residual is gross (over 5 times the robust noise per
    /// axis), and write that model; the rows are listed either way.
    #[arg(long)]
    exclude_outliers: bool,
    /// How each row's residual enters the fit: `squared` (least squares) or `huber` (squared
    /// up to 3 times the robust noise per axis, linear beyond, so that a few gross errors pull
    /// the fit no harder than a row at that threshold).
    #[arg(long, value_enum, default_value_t = LossArg::Squared)]
    loss: LossArg,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    json: bool,
    #[command(flatten)]
    group: super::GroupBy,
    /// Folder for a report (written atomically): index.html, one page with its plots inline
    /// that needs no network, and report.json, every number and plot point of the page.
    #[arg(long, value_name = "DIR")]
    report: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    armcomp_api::ops::calibrate::check_noises(args.noise_mm, args.noise_deg)?;
    let mut robot = super::load_robot(&args.robot)?;
    let data_files: Vec<&std::path::Path> = args.data.iter().map(|p| p.as_path()).collect();
    check_output(&args.out, &robot, &data_files)?;
    super::check_report(args.report.as_deref(), &robot, &data_files, Some(&args.out))?;
    let (mut data, _) = read_stations(&mut robot, &args.data, args.rows.rows.as_ref())?;
    let params = CalibrationParams {
        identify: args.identify.clone(),
        measurement_std: args.noise_mm.unwrap_or(0.1) * 1e-3,
        orientation_std: args.noise_deg.unwrap_or(0.1).to_radians(),
        max_iterations: args.max_iterations,
        restarts: args.restarts,
        seed: args.seed,
        loss: match args.loss {
            LossArg::Squared => Loss::Squared,
            LossArg::Huber => Loss::Huber,
        },
        ..CalibrationParams::default()
    };
    let bar = crate::progress::bar(
        Some(params.max_iterations as u64),
        "calibrating {bar:30} {pos}/{len} iterations  {msg}",
    );
    let mut observer = |it: &armcomp_core::calibrate::IterationInfo| {
        bar.set_position(it.iteration as u64);
        bar.set_message(format!("RMS {:.4} mm", it.rms * 1e3));
    };
    let declared = args.noise_mm.is_some() && (args.noise_deg.is_some() || !robot.measures_pose());
    if args.group.group_by.is_some() && args.prior != Prior::Auto {
        anyhow::bail!("--group-by folds the cross-validation of --prior auto; without it nothing is cross-validated");
    }
    let groups = |rows: &[usize]| args.group.groups(&data_files, rows);
    // The prior's cross-validation: a bar of its own, then the final fit's.
    let fits_bar = std::sync::Mutex::new(None::<indicatif::ProgressBar>);
    let fits = |p: armcomp_core::calibrate::FitsProgress| {
        let Ok(mut slot) = fits_bar.lock() else { return };
        let b = slot.get_or_insert_with(|| {
            crate::progress::bar(
                Some(p.total as u64),
                "choosing the prior scale {bar:30} {pos}/{len} fits  {elapsed} (about {eta} left)",
            )
        });
        b.set_position(p.done as u64);
        if p.done == p.total {
            b.finish_and_clear();
            *slot = None;
        }
    };
    let mut calibrate_on =
        |samples: &[armcomp_core::data::measurement::Sample], rows: &[usize], cancel: &Cancel| -> anyhow::Result<_> {
            let choices = armcomp_api::ops::calibrate::Choices {
                prior: args.prior,
                noise_declared: declared,
                fold_groups: groups(rows)?,
            };
            Ok(armcomp_api::ops::calibrate::run(
                &robot,
                samples,
                CalibrationParams {
                    cancel: cancel.clone(),
                    ..params.clone()
                },
                choices,
                &fits,
                &mut observer,
            )?)
        };
    // Ctrl-C ends `--prior auto`'s cross-validation with the scales scored so far.
    let mut run = if matches!(args.prior, Prior::Auto) {
        crate::stoppable(|cancel| calibrate_on(&data.samples, &data.rows, cancel))?
    } else {
        calibrate_on(&data.samples, &data.rows, &Cancel::default())?
    };
    let outlier_rows = run.outlier_rows(&data.rows);
    if args.exclude_outliers && !outlier_rows.is_empty() {
        (data.samples, data.rows) = armcomp_api::ops::calibrate::without_rows(&data.samples, &data.rows, &outlier_rows);
        run = calibrate_on(&data.samples, &data.rows, &Cancel::default())?;
    }
    bar.finish_and_clear();
    let (calibration, choice) = (&run.calibration, &run.prior_choice);
    let text = calibration.robot.to_text_for(&args.out)?;
    write_atomic(&args.out, text.as_bytes())?;
    if let Some(dir) = &args.report {
        let page = armcomp_api::model_report::for_calibrate(&robot, &data.samples, &data.rows, &run)?;
        armcomp_api::model_report::write(dir, &page)?;
    }
    let report = &calibration.report;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&run.to_json(&data.rows))?);
    } else {
        if let Some(c) = &choice {
            let scores: Vec<String> = c
                .scores
                .iter()
                .map(|s| format!("{} → {:.3}", scale_text(s.scale), s.held_out_rms_mm))
                .collect();
            println!(
                "prior scale chosen by {}-fold cross-validation on these data, grouped by {}: {} (held-out RMS in mm: {})",
                c.folds,
                c.grouped_by,
                scale_text(c.scale),
                scores.join(", ")
            );
        }
        if let Some(e) = &run.evidence {
            print_evidence(e);
        }
        print_report(report, &samples_in_words(&data.samples));
        print_gross_errors(&outlier_rows, report, args.exclude_outliers);
        if report.loss == Loss::Huber {
            println!(
                "Huber loss: {} of {} rows weighed less (residual over {} times the robust noise per axis)",
                report.downweighted,
                report.n_samples,
                armcomp_core::calibrate::HUBER_K
            );
        }
        if let Some(p) = &report.fitted_predictor {
            let verb = if p.kept { "kept" } else { "dropped" };
            println!("fitted predictor {verb}: {}", p.reason);
        }
        println!("wrote {}", args.out.display());
        if let Some(dir) = &args.report {
            println!("wrote {}", dir.join("index.html").display());
        }
    }
    for w in &report.warnings {
        eprintln!("warning: {w}");
    }
    if let Some(c) = choice.as_ref().filter(|c| c.interrupted) {
        eprintln!(
            "interrupted: the prior scale was chosen among the {} scored before the stop; the model was written",
            c.scores.len()
        );
        return Ok(ExitCode::from(130));
    }
    if !report.converged {
        eprintln!(
            "warning: calibration did not converge ({}); the best parameters found were written",
            report.stop_reason
        );
    }
    // Far above the noise or mislabelled units say more than not converged: the data or the
    // model is wrong.
    if let Some(why) = &report.implausible {
        eprintln!("error: {why}");
    }
    Ok(if report.suspect() {
        eprintln!("warning: the model was written, but check the data and the model (see the messages above)");
        ExitCode::from(3)
    } else if !report.converged {
        ExitCode::from(2)
    } else {
        ExitCode::SUCCESS
    })
}

/// The gross errors by data row, and a drift of the residuals over the rows.
fn print_gross_errors(rows: &[usize], report: &CalibrationReport, excluded: bool) {
    let what = if excluded {
        ": excluded, the model was fitted without them"
    } else {
        " (0-based as --rows counts; --exclude-outliers fits without them)"
    };
    super::print_gross_errors("", rows, what, report.drift.as_ref());
}

fn print_evidence(e: &armcomp_core::calibrate::evidence::EvidenceReport) {
    if e.noise_estimated {
        // Plane contacts alone have no tracker axes.
        let axes = if e.rms_per_axis_mm.iter().any(|v| *v > 0.0) {
            let [x, y, z] = e.rms_per_axis_mm;
            format!("residual RMS per axis x {x:.4}, y {y:.4}, z {z:.4} mm; ")
        } else {
            String::new()
        };
        println!(
            "noise estimated from the data: {:.4} ± {:.4} mm per axis ({axes}{:.1} of {} parameters determined by {} \
             equations)",
            e.noise_mm, e.noise_std_mm, e.determined, e.n_free, e.n_equations
        );
        if !e.fit_converged {
            println!(
                "  (from the residuals of a fit that did not converge, not at a minimum: the figure is an upper \
                 bound; declare the instrument's noise with --noise-mm, or see why the fit stopped below)"
            );
        }
        if let Some(deg) = e.orientation_noise_deg {
            println!("orientation noise estimated from the data: {deg:.4}° per axis");
        }
        if let (Some(mm), Some(std)) = (e.fixed_point_noise_mm, e.fixed_point_noise_std_mm) {
            println!("fixed-point noise estimated from the data: {mm:.4} ± {std:.4} mm per axis");
        }
    }
    if !e.groups.is_empty() {
        let groups: Vec<String> = e
            .groups
            .iter()
            .map(|g| {
                format!(
                    "{} ×{:.3} ({:.1} of {} determined)",
                    g.label, g.scale, g.determined, g.n_params
                )
            })
            .collect();
        println!("prior scales chosen by the evidence: {}", groups.join(", "));
    }
    println!(
        "log evidence {:.2} after {} round(s){}",
        e.log_evidence,
        e.rounds,
        if e.converged {
            ""
        } else {
            " (the hyper-parameters had not settled)"
        }
    );
}

fn scale_text(s: f64) -> String {
    if s.is_finite() { format!("{s}") } else { "none".into() }
}

/// A value in the unit people read it in: mm for lengths, degrees for angles, SI otherwise.
fn display(q: Quantity, v: f64) -> (f64, &'static str) {
    let (scale, unit) = q.display_unit();
    (v * scale, unit)
}

/// How many samples of each kind: `61 measured positions`, or for mixed data `40 samples (20
/// measured positions, 10 plane contacts, 10 fixed-point contacts)`.
fn samples_in_words(samples: &[armcomp_core::data::measurement::Sample]) -> String {
    use armcomp_core::data::measurement::SampleKind;
    let parts: Vec<String> = (SampleKind::ALL.into_iter())
        .map(|kind| (samples.iter().filter(|s| s.kind() == kind).count(), kind))
        .filter(|(n, _)| *n > 0)
        .map(|(n, kind)| match kind {
            SampleKind::Position => format!("{n} measured positions"),
            SampleKind::Plane => format!("{n} plane contacts"),
            SampleKind::FixedPoint => format!("{n} fixed-point contacts"),
        })
        .collect();
    match parts.as_slice() {
        [one] => one.clone(),
        _ => format!("{} samples ({})", samples.len(), parts.join(", ")),
    }
}

fn print_report(r: &CalibrationReport, samples: &str) {
    let id = &r.identifiability;
    println!(
        "measured chain: {} moving joint(s) from the base to the markers: {}",
        r.measured_chain.len(),
        r.measured_chain.join(", ")
    );
    println!(
        "joint columns the measurement CSV must hold: {}",
        r.csv_joints.join(", ")
    );
    if r.registered {
        println!("measurement frame registered in closed form before the fit");
    }
    println!(
        "{samples}, {} parameters selected, rank {} of {}, condition number {:.3e} ({:.3e} with priors and fixes)",
        id.n_params, id.rank, id.n_params, id.condition_number, id.condition_number_free
    );
    if !id.message.is_empty() {
        println!("identifiability: {}", id.message);
    }
    if !r.restarts_rms_mm.is_empty() {
        println!(
            "restarted from {} perturbed start(s), which ended at RMS {} mm; the lowest cost is kept",
            r.restarts_rms_mm.len(),
            r.restarts_rms_mm
                .iter()
                .map(|v| format!("{v:.4}"))
                .collect::<Vec<_>>()
                .join(", ")
        );
    }
    println!(
        "{} after {} iterations ({})",
        if r.converged { "converged" } else { "NOT converged" },
        r.iterations,
        r.stop_reason
    );
    println!(
        "{:<34} {:>14} {:>14} {:>12}  unit",
        "parameter", "initial", "identified", "std"
    );
    for p in &r.params {
        let q = p.quantity;
        let (a, unit) = display(q, p.initial);
        let (b, _) = display(q, p.value);
        let (s, _) = display(q, p.std);
        let std = if p.fixed {
            "fixed".to_string()
        } else if s.is_infinite() {
            // Nothing in the data or the priors fixes it.
            "undetermined".to_string()
        } else {
            format!("{s:.4e}")
        };
        println!("{:<34} {:>14.6} {:>14.6} {:>12}  {unit}", p.name, a, b, std);
    }
    for (label, s, o) in [
        ("before", &r.before, &r.before_orientation),
        ("after", &r.after, &r.after_orientation),
    ] {
        let turn = o.map_or(String::new(), |o| {
            format!(
                "; orientation mean {:.4}°, RMS {:.4}°, max {:.4}°",
                o.mean_deg, o.rms_deg, o.max_deg
            )
        });
        println!(
            "{label:>6}: mean {:.4} mm, std {:.4} mm, RMS {:.4} mm, max {:.4} mm{turn}",
            s.mean_mm, s.std_mm, s.rms_mm, s.max_mm
        );
    }
    for st in &r.per_station {
        println!(
            "  station {}: n {}, RMS {:.4} mm, max {:.4} mm",
            st.station, st.stats.n, st.stats.rms_mm, st.stats.max_mm
        );
    }
}
