use std::cell::RefCell;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::bail;
use armcomp_core::collision::CollisionModel;
use armcomp_core::design::{Criterion, SelectionParams, SelectionReport, pose_candidates, select_poses};
use armcomp_core::io::write_atomic;
use armcomp_core::measurement::{MeasurementSet, has_positions, parse_poses, write_csv, write_poses};
use armcomp_core::plan::{Space, spread, trajectory_similar};
use armcomp_core::sampling::Sampler;
use armcomp_core::{Robot, measurement::Sample};

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
    #[arg(long, default_value_t = 50)]
    trajectory_points: usize,
    /// Nearest pool poses taken per trajectory point.
    #[arg(long, default_value_t = 10)]
    per_point: usize,
    /// Seed of every random choice; the same seed gives the same bytes.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output poses CSV (joint columns in the robot file's units), written atomically; with a
    /// measured `--pool`, the chosen rows as a measurement CSV.
    #[arg(long)]
    out: PathBuf,
}

/// Where an optimal method picks from.
enum Pool {
    /// Sampled configurations (collision-free).
    Sampled(usize),
    /// A CSV file of measured rows or of joint configurations.
    File(PathBuf),
}

impl Pool {
    /// `--pool`: a number of poses to sample, or a file; none gives `Sampled(0)`, the method's
    /// default size.
    fn parse(text: Option<&str>) -> anyhow::Result<Pool> {
        Ok(match text {
            None => Pool::Sampled(0),
            Some(t) => match t.trim().parse::<usize>() {
                Ok(0) => bail!("--pool 0: give a number of poses to sample (at least 1) or a file"),
                Ok(n) => Pool::Sampled(n),
                Err(_) => Pool::File(PathBuf::from(t)),
            },
        })
    }
}

/// Candidates for the optimal methods: their samples and where they come from.
struct Candidates {
    samples: Vec<Vec<Sample>>,
    /// Data row of each candidate when the pool is measured.
    rows: Option<Vec<usize>>,
    note: String,
}

/// The measured rows of `set` as candidates (one per data row, its markers together), the
/// colliding ones left out.
fn row_candidates(set: &MeasurementSet, accept: &dyn Fn(&[f64]) -> bool) -> (Vec<Vec<Sample>>, Vec<usize>, usize) {
    let mut groups: Vec<(usize, Vec<Sample>)> = Vec::new();
    for (s, &row) in set.samples.iter().zip(&set.rows) {
        match groups.last_mut() {
            Some((r, g)) if *r == row => g.push(s.clone()),
            _ => groups.push((row, vec![s.clone()])),
        }
    }
    let total = groups.len();
    let (rows, samples): (Vec<usize>, Vec<Vec<Sample>>) = groups.into_iter().filter(|(_, g)| accept(&g[0].q)).unzip();
    let colliding = total - rows.len();
    (samples, rows, colliding)
}

fn file_candidates(robot: &Robot, path: &Path, accept: &dyn Fn(&[f64]) -> bool) -> anyhow::Result<Candidates> {
    let text = armcomp_core::io::read_text(path)?;
    if has_positions(&text) {
        let set = super::read_measurements(robot, path, None)?;
        let (samples, rows, colliding) = row_candidates(&set, accept);
        let note = format!(
            "picked from {} measured rows of {}{}",
            rows.len(),
            path.display(),
            skipped(colliding)
        );
        return Ok(Candidates {
            samples,
            rows: Some(rows),
            note,
        });
    }
    let poses = parse_poses(&text, path, &robot.csv_layout())?;
    let total = poses.len();
    let poses: Vec<Vec<f64>> = poses.into_iter().filter(|q| accept(q)).collect();
    Ok(Candidates {
        note: format!(
            "picked from {} configurations of {}{}",
            poses.len(),
            path.display(),
            skipped(total - poses.len())
        ),
        samples: pose_candidates(robot, &poses),
        rows: None,
    })
}

fn skipped(colliding: usize) -> String {
    if colliding > 0 {
        format!(" ({colliding} colliding left out)")
    } else {
        String::new()
    }
}

pub fn run(args: Args) -> anyhow::Result<ExitCode> {
    let robot = armcomp::load_robot(&args.robot)?;
    let pool_arg = Pool::parse(args.pool.as_deref())?;
    let mut read: Vec<&Path> = args.trajectory.iter().map(|p| p.as_path()).collect();
    read.extend(args.measured.as_deref());
    if let Pool::File(p) = &pool_arg {
        read.push(p);
    }
    super::check_output(&args.out, &robot, &read)?;
    let space = match args.space.as_str() {
        "joint" => Space::Joint,
        "cartesian" => Space::Cartesian,
        other => bail!("unknown --space `{other}`; expected joint or cartesian"),
    };
    if args.next.is_some() && args.measured.is_none() {
        bail!("--next proposes what to measure after the poses of --measured FILE; give that file");
    }
    let method = args
        .method
        .clone()
        .unwrap_or_else(|| if args.next.is_some() { "uncertainty" } else { "sobol" }.to_string());
    let n = args.next.unwrap_or(args.n);
    // Poses in collision (self-collision or fixtures) are never planned.
    let collision = CollisionModel::new(&robot);
    let collision_ws = RefCell::new(collision.workspace());
    let accept = |q: &[f64]| !collision.collides(q, &mut collision_ws.borrow_mut());
    let pool_sampler = Sampler::parse(&args.pool_sampler)?;
    let sampled = |n: usize| spread(&robot, space, pool_sampler, n, args.seed, &accept);
    if let Ok(criterion) = method.parse::<Criterion>() {
        let candidates = match &pool_arg {
            Pool::File(path) => file_candidates(&robot, path, &accept)?,
            Pool::Sampled(size) => {
                let size = if *size == 0 { 10 * n } else { *size };
                let plan = sampled(size)?;
                Candidates {
                    note: format!(
                        "picked from a sampled pool of {} ({} unreachable, {} colliding left out)",
                        plan.poses.len(),
                        plan.unreachable,
                        plan.rejected
                    ),
                    samples: pose_candidates(&robot, &plan.poses),
                    rows: None,
                }
            }
        };
        let measured = match &args.measured {
            Some(path) => super::read_measurements(&robot, path, None)?.samples,
            None => Vec::new(),
        };
        return optimal(
            &args,
            &robot,
            criterion,
            n.min(candidates.samples.len()),
            candidates,
            &measured,
        );
    }
    if args.next.is_some() || args.measured.is_some() {
        bail!("--next and --measured go with the methods d-optimal, a-optimal and uncertainty, not `{method}`");
    }
    let (poses, note) = match method.as_str() {
        "trajectory" => {
            let Some(path) = &args.trajectory else {
                bail!("--method trajectory needs --trajectory FILE (joint configurations in task order)");
            };
            let Pool::Sampled(size) = pool_arg else {
                bail!("--method trajectory samples its pool; give --pool a number of poses");
            };
            let text = armcomp_core::io::read_text(path)?;
            let trajectory = parse_poses(&text, path, &robot.csv_layout())?;
            let pool = sampled(if size == 0 { 2000 } else { size })?;
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
            let plan = spread(&robot, space, Sampler::parse(sampler)?, n, args.seed, &accept)?;
            let note = format!(
                "{} unreachable and {} colliding candidates skipped",
                plan.unreachable, plan.rejected
            );
            if plan.poses.len() < n {
                eprintln!("warning: only {} of {n} poses could be planned", plan.poses.len());
            }
            (plan.poses, note)
        }
    };
    write_atomic(
        &args.out,
        write_poses(&poses, robot.tree(), robot.file.units).as_bytes(),
    )?;
    eprintln!("wrote {} poses to {} ({note})", poses.len(), args.out.display());
    Ok(ExitCode::SUCCESS)
}

/// The optimal methods: choose, write, report.
fn optimal(
    args: &Args,
    robot: &Robot,
    criterion: Criterion,
    n: usize,
    candidates: Candidates,
    measured: &[Sample],
) -> anyhow::Result<ExitCode> {
    if candidates.samples.is_empty() {
        bail!("the pool has no collision-free pose to pick from ({})", candidates.note);
    }
    if !(args.noise_mm.is_finite() && args.noise_mm > 0.0) {
        bail!("--noise-mm must be positive, got {}", args.noise_mm);
    }
    let params = SelectionParams {
        criterion,
        identify: args.identify.clone(),
        measurement_std: args.noise_mm * 1e-3,
        exchange_passes: args.exchange_passes,
    };
    let report = select_poses(robot, &candidates.samples, n, measured, &[], &params)?;
    let (text, count) = match &candidates.rows {
        Some(_) => {
            let set = MeasurementSet {
                samples: report
                    .chosen
                    .iter()
                    .flat_map(|&i| candidates.samples[i].iter().cloned())
                    .collect(),
                ..MeasurementSet::default()
            };
            (write_csv(&set, robot.tree(), robot.file.units), report.chosen.len())
        }
        None => {
            let poses: Vec<Vec<f64>> = report
                .chosen
                .iter()
                .map(|&i| candidates.samples[i][0].q.clone())
                .collect();
            (write_poses(&poses, robot.tree(), robot.file.units), poses.len())
        }
    };
    if count < args.next.unwrap_or(args.n) {
        eprintln!("warning: only {count} poses could be picked");
    }
    write_atomic(&args.out, text.as_bytes())?;
    let rows: Option<Vec<usize>> = candidates
        .rows
        .as_ref()
        .map(|rows| report.chosen.iter().map(|&i| rows[i]).collect());
    if args.json {
        let mut value = serde_json::to_value(&report)?;
        value["rows"] = serde_json::to_value(&rows)?;
        println!("{}", serde_json::to_string_pretty(&value)?);
    } else {
        print_report(&report, measured.len(), rows.as_deref());
    }
    eprintln!("wrote {count} poses to {} ({})", args.out.display(), candidates.note);
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
