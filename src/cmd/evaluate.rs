use std::path::PathBuf;
use std::process::ExitCode;

use armcomp_core::Robot;
use armcomp_core::evaluate::{ErrorStats, position_errors};

use super::read_measurements;

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
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let robot = Robot::from_path(&args.model)?;
    let data = read_measurements(&robot, &args.data)?;
    let stats = ErrorStats::from_errors(&position_errors(&robot, &data.samples));
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
