use std::path::PathBuf;
use std::process::ExitCode;

use armcomp_core::algorithms::evaluate::ErrorStats;
use armcomp_core::support::io::write_atomic;

use super::{check_output, read_stations};

#[derive(clap::Args)]
pub struct Args {
    /// The model (a robot file, e.g. written by `armcomp calibrate`).
    #[arg(long)]
    model: PathBuf,
    /// Measurement CSV to compare the model with (held-out data); several are one station
    /// each, named by the file name, unless they have a `station` column. A station the model
    /// does not know (its `[[measurement.stations]]`) is registered in closed form first.
    #[arg(long, required = true)]
    data: Vec<PathBuf>,
    /// Register every station's measurement frame in closed form on these data before
    /// evaluating, known ones too (data from a new set-up of a station the model knows, or
    /// without a `station` column). With pose measurements the frames are then fitted to the
    /// positions and orientations together, each weighed by the noise its residuals give. The
    /// geometry, error models and predictor stay the model's.
    #[arg(long)]
    register: bool,
    /// Register the stations on these rows of the data only (a station's stationing points, in
    /// --rows' syntax: `0..12,225..237`), as --register does, and evaluate on the others (those
    /// of --rows that are not among them). Every station of the data needs rows here.
    #[arg(long, value_name = "ROWS", conflicts_with = "register")]
    register_on: Option<armcomp_core::data::measurement::RowSelection>,
    #[command(flatten)]
    rows: super::Rows,
    /// Print JSON: {"n", "mean_mm", "std_mm", "rms_mm", "max_mm", "mean_abs_mm": {"x", "y", "z"}},
    /// with pose measurements "orientation": {"n", "mean_deg", "rms_deg", "max_deg"}, and with
    /// fixed-point measurements "fixed_points": {"points": [{"name", "n", "mean_mm", "max_mm"}],
    /// "spread_mm", "distances": [{"between", "known_mm", "modelled_mm", "error_mm"}]} (a fixed
    /// point's errors are from the mean of its modelled points), with plane contacts "planes":
    /// {"planes": [{"name", "n", "fitted", "rms_mm", "max_mm", "roll_rms_deg", "pitch_rms_deg"}],
    /// "rms_mm"} (against the model's planes, or fitted to the rows for a plane it lacks); with
    /// several stations "per_station": [{"station", "n", "rms_mm", ...}] and
    /// "registered_stations": [names registered on these data].
    #[arg(long)]
    json: bool,
    /// Also write every sample's residual to this CSV (atomically): its row among the data rows,
    /// the point, the joint values and measured minus modelled x, y, z and distance, in the
    /// measurement frame and the model's length unit, the predictor included.
    #[arg(long, value_name = "FILE")]
    residuals: Option<PathBuf>,
    /// Folder for a report (written atomically): index.html, one page with its plots inline
    /// that needs no network, and report.json, every number and plot point of the page.
    #[arg(long, value_name = "DIR")]
    report: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let mut robot = super::load_robot(&args.model)?;
    let data_files: Vec<&std::path::Path> = args.data.iter().map(|p| p.as_path()).collect();
    if let Some(out) = &args.residuals {
        check_output(out, &robot, &data_files)?;
    }
    super::check_report(args.report.as_deref(), &robot, &data_files, args.residuals.as_deref())?;
    let (data, report) = match &args.register_on {
        None => {
            let (data, new) = read_stations(&mut robot, &args.data, args.rows.rows.as_ref())?;
            let register: Vec<usize> = if args.register {
                (0..robot.n_stations()).collect()
            } else {
                new
            };
            let report = armcomp_api::ops::evaluate::run_registered(&mut robot, &data.samples, &register)?;
            (data, report)
        }
        Some(on) => {
            let (all, _) = read_stations(&mut robot, &args.data, None)?;
            let (evaluated, report) =
                armcomp_api::ops::evaluate::register_on_then_run(&mut robot, &all, on, args.rows.rows.as_ref())?;
            (evaluated, report)
        }
    };
    if let Some(out) = &args.residuals {
        write_atomic(out, report.residuals_csv(&robot, &data.samples).as_bytes())?;
    }
    if let Some(dir) = &args.report {
        let page = armcomp_api::model_report::for_evaluate(&robot, &data.samples, &data.rows, &report)?;
        armcomp_api::model_report::write(dir, &page)?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report.to_json())?);
    } else {
        // Mixed data: the first line is the measured positions', the fixed points follow.
        let mixed = report.fixed_points.is_some() && report.stats.n < data.samples.len();
        let what = if mixed { "measured positions: " } else { "" };
        println!("{what}{}", stats_line(&report.stats));
        if let Some(o) = &report.orientation {
            println!(
                "  orientation: n {}  mean {:.4} deg  RMS {:.4} deg  max {:.4} deg",
                o.n, o.mean_deg, o.rms_deg, o.max_deg
            );
        }
        for (name, s) in &report.per_point {
            println!("  point {name}: {}", stats_line(s));
        }
        if let Some(f) = &report.fixed_points {
            println!(
                "  fixed points: spread {:.4} mm (mean distance from their mean, weighted by samples)",
                f.spread_mm
            );
            for p in &f.points {
                println!(
                    "    {}: n {}  spread {:.4} mm  max {:.4} mm",
                    p.name, p.n, p.mean_mm, p.max_mm
                );
            }
            for d in &f.distances {
                println!(
                    "  distance {}–{}: known {:.4} mm  modelled {:.4} mm  error {:.4} mm",
                    d.between[0], d.between[1], d.known_mm, d.modelled_mm, d.error_mm
                );
            }
        }
        if let Some(p) = &report.planes {
            println!("  planes: out-of-plane RMS {:.4} mm", p.rms_mm);
            for f in &p.planes {
                println!(
                    "    {}{}: n {}  out-of-plane RMS {:.4} mm  max {:.4} mm  roll RMS {:.4} deg  pitch RMS {:.4} deg",
                    f.name,
                    if f.fitted { " (fitted to these rows)" } else { "" },
                    f.n,
                    f.rms_mm,
                    f.max_mm,
                    f.roll_rms_deg,
                    f.pitch_rms_deg
                );
            }
        }
        for st in &report.per_station {
            println!("  station {}: {}", st.station, stats_line(&st.stats));
        }
        if !report.registered.is_empty() {
            let names: Vec<&str> = report
                .registered
                .iter()
                .map(|n| if n.is_empty() { "(the one station)" } else { n })
                .collect();
            println!(
                "measurement frame of station(s) {} registered in closed form on these data",
                names.join(", ")
            );
        }
        if let Some(dir) = &args.report {
            println!("wrote {}", dir.join("index.html").display());
        }
    }
    Ok(ExitCode::SUCCESS)
}

fn stats_line(s: &ErrorStats) -> String {
    format!(
        "n {}  mean {:.4} mm  std {:.4} mm  RMS {:.4} mm  max {:.4} mm  mean |x| {:.4} |y| {:.4} |z| {:.4} mm",
        s.n, s.mean_mm, s.std_mm, s.rms_mm, s.max_mm, s.mean_abs_mm.x, s.mean_abs_mm.y, s.mean_abs_mm.z
    )
}
