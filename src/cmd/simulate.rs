use std::path::PathBuf;
use std::process::ExitCode;

use armcomp_core::io::write_atomic;
use armcomp_core::measurement::{parse_poses, write_csv};

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
    /// Seed for pose sampling and noise; the same seed gives the same bytes.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Measure from this many stations (total-station set-ups), each its own measurement
    /// frame drawn from --seed around the truth's (see `armcomp_core::simulate::random_stations`):
    /// the poses in as many consecutive blocks, and a `station` column (`st1`, `st2`, ...).
    /// Default: the truth's stations, or one.
    #[arg(long, value_parser = super::at_least_one)]
    stations: Option<usize>,
    /// Output CSV (written atomically; in the robot file's units).
    #[arg(long)]
    out: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let mut truth = armcomp::load_robot(&args.robot)?;
    if let Some(k) = args.stations {
        // A stream of its own: the same seed draws the same poses whatever the stations.
        let stations =
            armcomp_core::simulate::random_stations(&truth, k, args.seed.wrapping_add(0x5851_f42d_4c95_7f2d));
        truth.set_stations(stations);
    }
    let poses_file: Vec<&std::path::Path> = args.poses.iter().map(|p| p.as_path()).collect();
    super::check_output(&args.out, &truth, &poses_file)?;
    let poses = match &args.poses {
        Some(p) => {
            let text = armcomp_core::io::read_text(p)?;
            parse_poses(&text, p, &truth.csv_layout())?
        }
        None => armcomp::ops::simulate::draw_poses(&truth, &args.sampler, args.n, args.seed)?,
    };
    let set = armcomp::ops::simulate::run(&truth, &poses, args.noise_mm, args.seed)?;
    for w in &set.warnings {
        eprintln!("warning: {w}");
    }
    write_atomic(&args.out, write_csv(&set, truth.tree(), truth.units()).as_bytes())?;
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
