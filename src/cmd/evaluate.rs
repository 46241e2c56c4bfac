use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use armcomp_core::Robot;
use armcomp_core::evaluate::{ErrorStats, position_errors};
use armcomp_core::io::{check_not_input, write_atomic};
use armcomp_core::measurement::{Sample, joint_header, joint_row};
use nalgebra::Vector3;

use super::read_measurements;

#[derive(clap::Args)]
pub struct Args {
    /// The model (a robot file, e.g. written by `armcomp calibrate`).
    #[arg(long)]
    model: PathBuf,
    /// Measurement CSV to compare the model with (held-out data).
    #[arg(long)]
    data: PathBuf,
    /// Use only these rows of the data (0-based, header excluded), comma-separated: `even`,
    /// `odd`, a row `N`, or a range `A..B`, `A..`, `..B` (e.g. a training split).
    #[arg(long)]
    rows: Option<armcomp_core::measurement::RowSelection>,
    /// Print JSON: {"n", "mean_mm", "std_mm", "rms_mm", "max_mm", "mean_abs_mm": {"x", "y", "z"}}.
    #[arg(long)]
    json: bool,
    /// Also write every sample's residual to this CSV (atomically): its row among the data rows,
    /// the point, the joint values and measured minus modelled x, y, z and distance, in the
    /// measurement frame and the model's length unit, the predictor included.
    #[arg(long, value_name = "FILE")]
    residuals: Option<PathBuf>,
}

/// The residuals CSV: one row per sample, in file order.
fn residuals_csv(robot: &Robot, samples: &[Sample], errors: &[Vector3<f64>]) -> String {
    let units = robot.file.units;
    let lu = units.length.symbol();
    let mut out = format!(
        "sample,point,{},x_err[{lu}],y_err[{lu}],z_err[{lu}],err[{lu}]\n",
        joint_header(robot.tree(), units).join(",")
    );
    for (i, (s, e)) in samples.iter().zip(errors).enumerate() {
        let point = &robot.tree().points()[s.point].name;
        let joints = joint_row(&s.q, robot.tree(), units).join(",");
        let [x, y, z, d] = [e.x, e.y, e.z, e.norm()].map(|v| units.len_out(v));
        // Writing to a String cannot fail.
        let _ = writeln!(out, "{},{point},{joints},{x},{y},{z},{d}", i + 1);
    }
    out
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    if let Some(out) = &args.residuals {
        check_not_input(out, &[&args.model, &args.data])?;
    }
    let robot = armcomp::load_robot(&args.model)?;
    let data = read_measurements(&robot, &args.data, args.rows.as_ref())?;
    let errors = position_errors(&robot, &data.samples);
    let stats = ErrorStats::from_errors(&errors);
    if let Some(out) = &args.residuals {
        write_atomic(out, residuals_csv(&robot, &data.samples, &errors).as_bytes())?;
    }
    // Per measured point, when there are several.
    let mut points: Vec<usize> = data.samples.iter().map(|s| s.point).collect();
    points.sort_unstable();
    points.dedup();
    let per_point: Vec<(String, ErrorStats)> = if points.len() > 1 {
        points
            .iter()
            .map(|&p| {
                let e: Vec<_> = errors
                    .iter()
                    .zip(&data.samples)
                    .filter(|(_, s)| s.point == p)
                    .map(|(e, _)| *e)
                    .collect();
                (robot.tree().points()[p].name.clone(), ErrorStats::from_errors(&e))
            })
            .collect()
    } else {
        Vec::new()
    };
    if args.json {
        let mut value = serde_json::to_value(stats)?;
        if !per_point.is_empty() {
            value["per_point"] =
                serde_json::to_value(per_point.iter().cloned().collect::<std::collections::BTreeMap<_, _>>())?;
        }
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        println!("{}", stats_line(&stats));
        for (name, s) in &per_point {
            println!("  point {name}: {}", stats_line(s));
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
