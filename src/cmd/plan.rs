use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::bail;
use armcomp_api::ops::plan::{PlanParams, PlanPool};
use armcomp_core::analysis::design::{Criterion, SelectionReport};
use armcomp_core::data::measurement::{MeasurementSet, has_positions, parse_poses, write_csv, write_poses};
use armcomp_core::support::io::write_atomic;

#[derive(clap::Args)]
pub struct Args {
    /// The robot file.
    #[arg(long)]
    robot: PathBuf,
    /// Number of poses (for `trajectory`: trajectory points × neighbours instead).
    #[arg(long, default_value_t = 100, value_parser = super::at_least_one)]
    n: usize,
    /// sobol, halton, random, grid (even sets); d-optimal, a-optimal or uncertainty (the best
    /// subset of a pool for calibration: largest log det of the information, smallest sum of
    /// posterior variances, smallest predicted position variance over the pool); or trajectory
    /// (pool poses nearest to a task trajectory). Default: sobol, uncertainty with `--next`.
    #[arg(long)]
    method: Option<String>,
    /// Spread poses evenly over the joint ranges (`joint`) or over the Cartesian box the tool
    /// reaches, through IK (`cartesian`). For a sampled pool this is the pool's space.
    #[arg(long, default_value = "joint")]
    space: String,
    /// The pool to pick from: a number of poses to sample (default 10 × n for the optimal
    /// methods, 2000 for trajectory), or a CSV file: measured rows (retrospective selection:
    /// which rows to calibrate on) or joint configurations without measurements. A file
    /// named like a number is given as `./100`.
    #[arg(long)]
    pool: Option<String>,
    /// How a sampled pool is drawn: sobol, halton, random or grid.
    #[arg(long, default_value = "sobol")]
    pool_sampler: String,
    /// Parameters the optimal methods should determine (as `armcomp calibrate --identify`;
    /// error models' columns go through the deformed model).
    #[arg(long, value_delimiter = ',')]
    identify: Vec<String>,
    /// Propose the next K poses to measure given those measured so far (`--measured`).
    #[arg(long, value_parser = super::at_least_one)]
    next: Option<usize>,
    /// Measurement CSV of the poses measured so far: their information counts as known.
    #[arg(long)]
    measured: Option<PathBuf>,
    /// Standard deviation of the tracker noise per axis, in mm (weighs data against priors).
    #[arg(long, default_value_t = 0.1)]
    noise_mm: f64,
    /// Most exchange passes refining the greedy choice of the optimal methods (0: greedy only).
    #[arg(long, default_value_t = 10)]
    exchange_passes: usize,
    /// Print the selection report of the optimal methods as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Task trajectory for `trajectory`: joint configurations in task order (a poses CSV with
    /// units in the header, e.g. recorded while teaching).
    #[arg(long)]
    trajectory: Option<PathBuf>,
    /// Points spread along the trajectory by arc length.
    #[arg(long, default_value_t = 50, value_parser = super::at_least_one)]
    trajectory_points: usize,
    /// Nearest pool poses taken per trajectory point.
    #[arg(long, default_value_t = 10, value_parser = super::at_least_one)]
    per_point: usize,
    /// Seed of every random choice; the same seed gives the same bytes.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output poses CSV (joint columns in the robot file's units), written atomically; with a
    /// measured `--pool`, the chosen rows as a measurement CSV.
    #[arg(long)]
    out: PathBuf,
}

/// `--pool`: a number of poses to sample, or a file of measured rows or configurations;
/// none gives `Sampled(0)`, the method's default size.
fn read_pool(robot: &armcomp_core::Robot, text: Option<&str>) -> anyhow::Result<PlanPool> {
    let Some(t) = text else {
        return Ok(PlanPool::Sampled(0));
    };
    match t.trim().parse::<usize>() {
        Ok(0) => bail!("--pool 0: give a number of poses to sample (at least 1) or a file"),
        Ok(n) => Ok(PlanPool::Sampled(n)),
        Err(_) => {
            let path = Path::new(t);
            let text = armcomp_core::support::io::read_text(path, super::input_limits())?;
            // A robot measured by contacts reads its rows as contacts (a configuration alone
            // says not which fixed point or plane it touches).
            let contacts = robot.measures_fixed_points() || robot.measures_planes();
            Ok(if has_positions(&text) || contacts {
                PlanPool::Measured(super::read_measurements(robot, path, None)?)
            } else {
                PlanPool::Configurations(parse_poses(&text, path, &robot.csv_layout())?)
            })
        }
    }
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let robot = super::load_robot(&args.robot)?;
    let mut read: Vec<&Path> = args.trajectory.iter().map(|p| p.as_path()).collect();
    read.extend(args.measured.as_deref());
    let pool_file = args.pool.as_deref().filter(|t| t.trim().parse::<usize>().is_err());
    read.extend(pool_file.map(Path::new));
    super::check_output(&args.out, &robot, &read)?;
    if args.next.is_some() && args.measured.is_none() {
        bail!("--next proposes what to measure after the poses of --measured FILE; give that file");
    }
    if !(args.noise_mm.is_finite() && args.noise_mm > 0.0) {
        bail!("--noise-mm must be positive, got {}", args.noise_mm);
    }
    let trajectory = match &args.trajectory {
        Some(path) => Some(parse_poses(
            &armcomp_core::support::io::read_text(path, super::input_limits())?,
            path,
            &robot.csv_layout(),
        )?),
        None if args.method.as_deref() == Some("trajectory") => {
            bail!("--method trajectory needs --trajectory FILE (joint configurations in task order)")
        }
        None => None,
    };
    let params = PlanParams {
        n: args.n,
        method: args.method.clone(),
        space: args.space.clone(),
        pool: read_pool(&robot, args.pool.as_deref())?,
        pool_sampler: args.pool_sampler.clone(),
        identify: args.identify.clone(),
        next: args.next,
        measured: match &args.measured {
            Some(path) => super::read_measurements(&robot, path, None)?,
            None => Default::default(),
        },
        measurement_std: args.noise_mm * 1e-3,
        exchange_passes: args.exchange_passes,
        trajectory,
        trajectory_points: args.trajectory_points,
        per_point: args.per_point,
        seed: args.seed,
    };
    let run = armcomp_api::ops::plan::run(&robot, &params)?;
    for w in &run.warnings {
        eprintln!("warning: {w}");
    }
    let text = match &run.chosen_samples {
        Some(samples) => {
            let set = MeasurementSet {
                samples: samples.clone(),
                ..MeasurementSet::default()
            };
            write_csv(&set, robot.tree(), robot.units())
        }
        None => write_poses(&run.poses, robot.tree(), robot.units()),
    };
    write_atomic(&args.out, text.as_bytes())?;
    if let Some(report) = &run.selection {
        if args.json {
            println!("{}", serde_json::to_string_pretty(&run.selection_json())?);
        } else {
            print_report(report, params.measured.samples.len(), run.rows.as_deref());
        }
    }
    let source = pool_file.map(|f| format!(" of {f}")).unwrap_or_default();
    eprintln!(
        "wrote {} poses to {} ({}{source})",
        run.poses.len(),
        args.out.display(),
        run.note
    );
    Ok(ExitCode::SUCCESS)
}

fn print_report(r: &SelectionReport, measured: usize, rows: Option<&[usize]>) {
    let what = match r.criterion {
        Criterion::DOptimal => "log det of the prior-scaled information",
        Criterion::AOptimal => "sum of posterior over prior variances",
        Criterion::Uncertainty => "mean predicted 3-D position variance over the pool (m²)",
    };
    println!(
        "{}: {what} {:.6e} after the greedy choice, {:.6e} after {} exchange(s)",
        r.criterion.name(),
        r.greedy_value,
        r.value,
        r.exchanges
    );
    println!(
        "predicted RMS 3-D position std over the pool: {:.4} mm {}, {:.4} mm with the chosen poses",
        r.workspace_std_before * 1e3,
        if measured > 0 {
            format!("from the {measured} measured sample(s)")
        } else {
            "from the priors alone".into()
        },
        r.workspace_std_after * 1e3
    );
    let id = &r.identifiability;
    println!(
        "identifiability of the chosen{} poses: {} equations, {} parameters, rank {} of {}, condition number {:.3e} \
         ({:.3e} with priors and fixes)",
        if measured > 0 { " and measured" } else { "" },
        id.n_equations,
        id.n_params,
        id.rank,
        id.n_params,
        id.condition_number,
        id.condition_number_free
    );
    if !id.message.is_empty() {
        println!("identifiability: {}", id.message);
    }
    // The worst-determined parameters: largest posterior std relative to the prior's, or to
    // the std before for those without a prior.
    let mut order: Vec<usize> = (0..r.params.len()).collect();
    let relative = |k: usize| {
        let reference = if r.prior_std[k].is_finite() {
            r.prior_std[k]
        } else {
            r.std_before[k]
        };
        r.std_after[k] / reference.max(1e-300)
    };
    order.sort_by(|&a, &b| relative(b).total_cmp(&relative(a)));
    println!(
        "{:<34} {:>12} {:>12} {:>12}  unit   (the {} least determined of {}; --json lists all)",
        "parameter",
        "prior std",
        "std before",
        "std after",
        order.len().min(10),
        order.len()
    );
    for &k in order.iter().take(10) {
        let show = |v: f64| {
            if v.is_finite() {
                format!("{:>12.4e}", v)
            } else {
                format!("{:>12}", "none")
            }
        };
        println!(
            "{:<34} {} {} {}  {}",
            r.params[k],
            show(r.prior_std[k]),
            show(r.std_before[k]),
            show(r.std_after[k]),
            r.units[k]
        );
    }
    if let Some(rows) = rows {
        let list: Vec<String> = rows.iter().map(|r| r.to_string()).collect();
        println!("rows: {}", list.join(","));
    }
}
