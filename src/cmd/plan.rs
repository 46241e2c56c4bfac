use std::cell::RefCell;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::bail;
use armcomp_core::collision::CollisionModel;
use armcomp_core::io::write_atomic;
use armcomp_core::measurement::{parse_poses, write_poses};
use armcomp_core::plan::{Space, d_optimal, spread, trajectory_similar};
use armcomp_core::sampling::Sampler;

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
    let space = match args.space.as_str() {
        "joint" => Space::Joint,
        "cartesian" => Space::Cartesian,
        other => bail!("unknown --space `{other}`; expected joint or cartesian"),
    };
    // Poses in collision (self-collision or fixtures) are never planned.
    let collision = CollisionModel::new(&robot);
    let collision_ws = RefCell::new(collision.workspace());
    let accept = |q: &[f64]| !collision.collides(q, &mut collision_ws.borrow_mut());
    let pool_sampler = Sampler::parse(&args.pool_sampler)?;
    let pool = |n: usize| spread(&robot, space, pool_sampler, n, args.seed, &accept);
    let (poses, note) = match args.method.as_str() {
        "d-optimal" => {
            let pool = pool(args.pool.unwrap_or(10 * args.n))?;
            let (chosen, log_det) = d_optimal(&robot, &pool.poses, args.n.min(pool.poses.len()), &args.identify)?;
            (
                chosen.iter().map(|&i| pool.poses[i].clone()).collect::<Vec<_>>(),
                format!(
                    "picked from a pool of {} ({} unreachable); log det of the scaled information {log_det:.2}",
                    pool.poses.len(),
                    pool.unreachable
                ),
            )
        }
        "trajectory" => {
            let Some(path) = &args.trajectory else {
                bail!("--method trajectory needs --trajectory FILE (joint configurations in task order)");
            };
            let text = armcomp_core::io::read_text(path)?;
            let trajectory = parse_poses(&text, path, &robot.csv_layout())?;
            let pool = pool(args.pool.unwrap_or(2000))?;
            let chosen = trajectory_similar(
                &robot,
                &trajectory,
                &pool.tool_positions,
                args.trajectory_points,
                args.per_point,
            )?;
            (
                chosen.iter().map(|&i| pool.poses[i].clone()).collect(),
                format!(
                    "{} trajectory points × {} nearest of a pool of {}",
                    args.trajectory_points,
                    args.per_point,
                    pool.poses.len()
                ),
            )
        }
        sampler => {
            let plan = spread(&robot, space, Sampler::parse(sampler)?, args.n, args.seed, &accept)?;
            let note = format!(
                "{} unreachable and {} colliding candidates skipped",
                plan.unreachable, plan.rejected
            );
            (plan.poses, note)
        }
    };
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
