use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use armcomp_core::Robot;
use armcomp_core::evaluate::{ErrorStats, position_errors};
use armcomp_core::io::write_atomic;
use armcomp_core::measurement::{Sample, joint_header, joint_row};
use nalgebra::Vector3;

use super::{check_output, read_measurements};

#[derive(clap::Args)]
pub struct Args {
    /// The model (a robot file, e.g. written by `armcomp calibrate`).
    #[arg(long)]
    model: PathBuf,
    /// Measurement CSV to compare the model with (held-out data).
    #[arg(long)]
    data: PathBuf,
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
    let robot = armcomp::load_robot(&args.model)?;
    if let Some(out) = &args.residuals {
        check_output(out, &robot, &[&args.data])?;
    }
    let data = read_measurements(&robot, &args.data)?;
    let errors = position_errors(&robot, &data.samples);
    let stats = ErrorStats::from_errors(&errors);
    if let Some(out) = &args.residuals {
        write_atomic(out, residuals_csv(&robot, &data.samples, &errors).as_bytes())?;
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&stats)?);
    } else {
        println!(
            "n {}  mean {:.4} mm  std {:.4} mm  RMS {:.4} mm  max {:.4} mm  mean |x| {:.4} |y| {:.4} |z| {:.4} mm",
            stats.n,
            stats.mean_mm,
            stats.std_mm,
            stats.rms_mm,
            stats.max_mm,
            stats.mean_abs_mm.x,
            stats.mean_abs_mm.y,
            stats.mean_abs_mm.z
        );
    }
    Ok(ExitCode::SUCCESS)
}
