use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::bail;
use armcomp::ops::plan::{PlanParams, PlanRun};
use armcomp_core::io::write_atomic;
use armcomp_core::measurement::{parse_poses, write_poses};

#[derive(clap::Args)]
pub struct Args {
    /// The robot file.
    #[arg(long)]
    robot: PathBuf,
    /// Number of poses (for `trajectory`: trajectory points × neighbours instead).
    #[arg(long, default_value_t = 100, value_parser = super::at_least_one)]
    n: usize,
    /// sobol, halton, random, grid (even sets), d-optimal (best subset of a pool for
    /// calibration) or trajectory (pool poses nearest to a task trajectory).
    #[arg(long, default_value = "sobol")]
    method: String,
    /// Spread poses evenly over the joint ranges (`joint`) or over the Cartesian box the tool
    /// reaches, through IK (`cartesian`). For d-optimal and trajectory this is the pool's space.
    #[arg(long, default_value = "joint")]
    space: String,
    /// Pool size for d-optimal (default 10 × n) and trajectory (default 2000).
    #[arg(long)]
    pool: Option<usize>,
    /// How the pool is drawn: sobol, halton, random or grid.
    #[arg(long, default_value = "sobol")]
    pool_sampler: String,
    /// Parameters the d-optimal plan should determine (as `armcomp calibrate --identify`).
    #[arg(long, value_delimiter = ',')]
    identify: Vec<String>,
    /// Task trajectory for `trajectory`: joint configurations in task order (a poses CSV with
    /// units in the header, e.g. recorded while teaching).
    #[arg(long)]
    trajectory: Option<PathBuf>,
    /// Points spread along the trajectory by arc length.
    #[arg(long, default_value_t = 50)]
    trajectory_points: usize,
    /// Nearest pool poses taken per trajectory point.
    #[arg(long, default_value_t = 10)]
    per_point: usize,
    /// Seed of every random choice; the same seed gives the same bytes.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output poses CSV (joint columns in the robot file's units), written atomically.
    #[arg(long)]
    out: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let robot = armcomp::load_robot(&args.robot)?;
    let trajectory_file: Vec<&std::path::Path> = args.trajectory.iter().map(|p| p.as_path()).collect();
    super::check_output(&args.out, &robot, &trajectory_file)?;
    let trajectory = match &args.trajectory {
        Some(path) => {
            let text = armcomp_core::io::read_text(path)?;
            Some(parse_poses(&text, path, &robot.csv_layout())?)
        }
        None if args.method == "trajectory" => {
            bail!("--method trajectory needs --trajectory FILE (joint configurations in task order)")
        }
        None => None,
    };
    let params = PlanParams {
        n: args.n,
        method: args.method.clone(),
        space: args.space.clone(),
        pool: args.pool,
        pool_sampler: args.pool_sampler.clone(),
        identify: args.identify.clone(),
        trajectory,
        trajectory_points: args.trajectory_points,
        per_point: args.per_point,
        seed: args.seed,
    };
    let PlanRun { poses, note } = armcomp::ops::plan::run(&robot, &params)?;
    if poses.len() < args.n && args.method != "trajectory" {
        eprintln!("warning: only {} of {} poses could be planned", poses.len(), args.n);
    }
    write_atomic(
        &args.out,
        write_poses(&poses, robot.tree(), robot.file.units).as_bytes(),
    )?;
    eprintln!("wrote {} poses to {} ({note})", poses.len(), args.out.display());
    Ok(ExitCode::SUCCESS)
}
