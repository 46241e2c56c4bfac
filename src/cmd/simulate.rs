use std::path::PathBuf;
use std::process::ExitCode;

use armcomp_core::io::write_atomic;
use armcomp_core::measurement::{parse_poses, write_csv_with_sensor};

#[derive(clap::Args)]
pub struct Args {
    /// The truth robot file (its error models carry the true values), or a bare URDF.
    #[arg(long)]
    robot: PathBuf,
    /// Number of poses to draw inside the joint limits (ignored with --poses).
    #[arg(long, default_value_t = 100, value_parser = super::at_least_one)]
    n: usize,
    /// How to draw poses: sobol, halton, random or grid.
    #[arg(long, default_value = "sobol")]
    sampler: String,
    /// Read the poses from this CSV (joint columns with units in the header) instead of drawing them.
    #[arg(long)]
    poses: Option<PathBuf>,
    /// Standard deviation of the measurement noise per axis, in mm.
    #[arg(long, default_value_t = 0.0)]
    noise_mm: f64,
    /// Standard deviation (deg) of the base's tilt about its x and y axes, drawn anew at every
    /// pose; the robot file's sensor (`[[sensors]]`) reads it and its columns are written.
    #[arg(long, default_value_t = 0.0)]
    tilt_deg: f64,
    /// Seed for pose sampling and noise; the same seed gives the same bytes.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output CSV (written atomically; in the robot file's units).
    #[arg(long)]
    out: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let truth = armcomp::load_robot(&args.robot)?;
    let poses_file: Vec<&std::path::Path> = args.poses.iter().map(|p| p.as_path()).collect();
    super::check_output(&args.out, &truth, &poses_file)?;
    let poses = match &args.poses {
        Some(p) => {
            let text = armcomp_core::io::read_text(p)?;
            parse_poses(&text, p, &truth.csv_layout())?
        }
        None => armcomp::ops::simulate::draw_poses(&truth, &args.sampler, args.n, args.seed)?,
    };
    let set = armcomp::ops::simulate::run_tilted(&truth, &poses, args.noise_mm, args.tilt_deg, args.seed)?;
    for w in &set.warnings {
        eprintln!("warning: {w}");
    }
    let text = write_csv_with_sensor(&set, truth.tree(), truth.units(), truth.gravity_sensor());
    write_atomic(&args.out, text.as_bytes())?;
    eprintln!(
        "wrote {} measurements of {} poses to {} (noise {} mm per axis, seed {})",
        set.samples.len(),
        poses.len(),
        args.out.display(),
        args.noise_mm,
        args.seed
    );
    Ok(ExitCode::SUCCESS)
}
