//! `plan`: measurement poses, evenly spread, optimal for calibration (D-, A-optimal or least
//! predicted uncertainty, from a sampled pool, given configurations or measured rows), or near
//! a task trajectory; never in collision.

use std::cell::RefCell;

use armcomp_core::algorithms::plan::{Space, spread, trajectory_similar};
use armcomp_core::analysis::design::{Criterion, SelectionParams, SelectionReport, pose_candidates, select_poses};
use armcomp_core::data::measurement::{MeasurementSet, Sample, listed};
use armcomp_core::kinematics::collision::CollisionModel;
use armcomp_core::model::sampling::Sampler;
use armcomp_core::support::limits::{self, Cost};
use armcomp_core::support::text::shown;
use armcomp_core::{Error, Result, Robot};

/// Where the optimal and trajectory methods pick from.
#[derive(Debug, Clone)]
pub enum PlanPool {
    /// This many configurations sampled collision-free (0: the method's default, 10 × n for
    /// the optimal methods, 2000 for trajectory).
    Sampled(usize),
    /// Joint configurations without measurements (SI).
    Configurations(Vec<Vec<f64>>),
    /// Measured rows: retrospective selection of the rows worth calibrating on.
    Measured(MeasurementSet),
}

/// Settings of [`run`].
#[derive(Debug, Clone)]
pub struct PlanParams {
    /// Number of poses (for `trajectory`: trajectory points × neighbours instead).
    pub n: usize,
    /// sobol, halton, random, grid, d-optimal, a-optimal, uncertainty or trajectory; `None`:
    /// sobol, or uncertainty with `next`.
    pub method: Option<String>,
    /// `joint` or `cartesian`: where poses (or a sampled pool) spread evenly.
    pub space: String,
    /// What the optimal and trajectory methods pick from.
    pub pool: PlanPool,
    /// How a sampled pool is drawn: sobol, halton, random or grid.
    pub pool_sampler: String,
    /// Parameters the optimal methods should determine (as calibration's `identify`).
    pub identify: Vec<String>,
    /// Propose this many poses to measure after `measured` (replaces `n`).
    pub next: Option<usize>,
    /// Samples measured so far: their information counts as known.
    pub measured: MeasurementSet,
    /// Standard deviation of the tracker noise per axis (m).
    pub measurement_std: f64,
    /// Most exchange passes refining the greedy choice of the optimal methods.
    pub exchange_passes: usize,
    /// The task trajectory for `trajectory`: joint configurations in task order (SI).
    pub trajectory: Option<Vec<Vec<f64>>>,
    /// Points spread along the trajectory by arc length.
    pub trajectory_points: usize,
    /// Nearest pool poses per trajectory point.
    pub per_point: usize,
    /// Seed of every random choice.
    pub seed: u64,
}

impl Default for PlanParams {
    fn default() -> Self {
        PlanParams {
            n: 100,
            method: None,
            space: "joint".into(),
            pool: PlanPool::Sampled(0),
            pool_sampler: "sobol".into(),
            identify: Vec::new(),
            next: None,
            measured: MeasurementSet::default(),
            measurement_std: 1e-4,
            exchange_passes: 10,
            trajectory: None,
            trajectory_points: 50,
            per_point: 10,
            seed: 0,
        }
    }
}

/// Planned poses and how they were found.
#[derive(Debug, Clone)]
pub struct PlanRun {
    /// The poses (SI joint values).
    pub poses: Vec<Vec<f64>>,
    /// What was picked from what, or skipped.
    pub note: String,
    /// The optimal methods' report: criterion values, identifiability, parameter stds.
    pub selection: Option<SelectionReport>,
    /// With a measured pool: the data rows chosen, and their samples (every marker).
    pub rows: Option<Vec<usize>>,
    /// With a measured pool: the samples of the chosen rows, in the chosen order.
    pub chosen_samples: Option<Vec<Sample>>,
    /// Fewer poses than asked for, and why.
    pub warnings: Vec<String>,
}

impl PlanRun {
    /// The optimal methods' report as `armcomp plan --json` prints it, with the chosen `rows`.
    pub fn selection_json(&self) -> Option<serde_json::Value> {
        self.selection.as_ref().map(|report| {
            // Plain numbers, strings and lists: serialising cannot fail.
            let mut value = serde_json::to_value(report).expect("the report serialises");
            value["rows"] = serde_json::to_value(&self.rows).expect("rows serialise");
            value
        })
    }
}

/// The error of a planning setting `what` that cannot be used, and why.
fn invalid(what: &str, reason: String) -> Error {
    Error::InvalidArgument {
        what: what.into(),
        reason,
    }
}

/// Plans measurement poses for `robot`.
pub fn run(robot: &Robot, p: &PlanParams) -> Result<PlanRun> {
    let space = match p.space.as_str() {
        "joint" => Space::Joint,
        "cartesian" => Space::Cartesian,
        other => {
            return Err(invalid(
                "space",
                format!("unknown space `{other}`; expected joint or cartesian"),
            ));
        }
    };
    if p.next.is_some() && p.measured.samples.is_empty() {
        return Err(invalid(
            "next",
            "proposing the next poses needs the poses measured so far".into(),
        ));
    }
    let method = p
        .method
        .clone()
        .unwrap_or_else(|| if p.next.is_some() { "uncertainty" } else { "sobol" }.to_string());
    let n = p.next.unwrap_or(p.n);
    let contacts = robot.measures_fixed_points() || robot.measures_planes();
    if contacts && !(matches!(p.pool, PlanPool::Measured(_)) && method.parse::<Criterion>().is_ok()) {
        let what = if robot.measures_planes() {
            "plane"
        } else {
            "fixed_point"
        };
        return Err(invalid(
            "pool",
            format!(
                "this robot is measured by contacts (`kind = \"{what}\"`), and a configuration drawn from the joint \
                 ranges touches no contact; plan picks among contact rows: give a pool file of configurations at \
                 the contacts with their `{what}` column (measured, or from `armcomp simulate`) and the method \
                 d-optimal, a-optimal or uncertainty"
            ),
        ));
    }
    check_sizes(robot, p, &method, space, n)?;
    // Poses in collision (self-collision or fixtures) are never planned.
    let collision = CollisionModel::new(robot.tree(), robot.collision());
    let collision_ws = RefCell::new(collision.workspace());
    let accept = |q: &[f64]| !collision.collides(q, &mut collision_ws.borrow_mut());
    let pool_sampler = Sampler::parse(&p.pool_sampler)?;
    let sampled = |n: usize| spread(robot, space, pool_sampler, n, p.seed, &accept);
    if let Ok(criterion) = method.parse::<Criterion>() {
        let candidates = match &p.pool {
            PlanPool::Measured(set) => measured_candidates(robot, set, &accept)?,
            PlanPool::Configurations(poses) => {
                let total = poses.len();
                let poses: Vec<Vec<f64>> = poses.iter().filter(|q| accept(q)).cloned().collect();
                Candidates {
                    note: format!(
                        "picked from {} configurations{}",
                        poses.len(),
                        skipped(total - poses.len())
                    ),
                    samples: pose_candidates(robot, &poses),
                    rows: None,
                }
            }
            PlanPool::Sampled(size) => {
                let plan = sampled(if *size == 0 { 10 * n } else { *size })?;
                Candidates {
                    note: format!(
                        "picked from a sampled pool of {} ({} unreachable, {} colliding left out)",
                        plan.poses.len(),
                        plan.unreachable,
                        plan.rejected
                    ),
                    samples: pose_candidates(robot, &plan.poses),
                    rows: None,
                }
            }
        };
        return optimal(robot, p, criterion, n, candidates);
    }
    if p.next.is_some() || !p.measured.samples.is_empty() {
        return Err(invalid(
            "method",
            format!(
                "the next poses and the measured ones go with the methods d-optimal, a-optimal and uncertainty, not `{method}`"
            ),
        ));
    }
    let mut warnings = Vec::new();
    let (poses, note) = match method.as_str() {
        "trajectory" => {
            let Some(trajectory) = &p.trajectory else {
                return Err(invalid(
                    "trajectory",
                    "method trajectory needs a trajectory (joint configurations in task order)".into(),
                ));
            };
            let PlanPool::Sampled(size) = p.pool else {
                return Err(invalid(
                    "pool",
                    "method trajectory samples its pool; give the pool as a number of poses".into(),
                ));
            };
            for (what, v) in [("trajectory_points", p.trajectory_points), ("per_point", p.per_point)] {
                if v == 0 {
                    return Err(invalid(
                        what,
                        "expected at least 1: none gives no pose to measure".into(),
                    ));
                }
            }
            let pool = sampled(if size == 0 { 2000 } else { size })?;
            let chosen = trajectory_similar(
                robot,
                trajectory,
                &pool.tool_positions,
                p.trajectory_points,
                p.per_point,
            )?;
            (
                chosen.iter().map(|&i| pool.poses[i].clone()).collect(),
                format!(
                    "{} trajectory points × {} nearest of a pool of {}",
                    p.trajectory_points,
                    p.per_point,
                    pool.poses.len()
                ),
            )
        }
        sampler => {
            let sampler = Sampler::parse(sampler).map_err(|_| {
                invalid(
                    "method",
                    format!(
                        "unknown method `{sampler}`; expected sobol, halton, random, grid (even sets), d-optimal, a-optimal, uncertainty (optimal subsets) or trajectory"
                    ),
                )
            })?;
            let plan = spread(robot, space, sampler, n, p.seed, &accept)?;
            if plan.poses.len() < n {
                warnings.push(format!("only {} of {n} poses could be planned", plan.poses.len()));
            }
            let note = format!(
                "{} unreachable and {} colliding candidates skipped",
                plan.unreachable, plan.rejected
            );
            (plan.poses, note)
        }
    };
    Ok(PlanRun {
        poses,
        note,
        selection: None,
        rows: None,
        chosen_samples: None,
        warnings,
    })
}

/// Checks the sizes asked for (`n` poses, or the `--next` ones, and a sampled pool) against
/// [the limits](armcomp_core::support::limits) before anything is sampled: drawing a pose costs its
/// tries (20 for the quasi-random samplers, each a collision check, and through IK in
/// Cartesian space), and the optimal methods score every pool pose at every pick and exchange
/// pass against the parameters' information.
fn check_sizes(robot: &Robot, p: &PlanParams, method: &str, space: Space, n: usize) -> Result<()> {
    let optimal = method.parse::<Criterion>().is_ok();
    let fk = robot.fk_flops();
    let pose = robot.pose_cost();
    let joints = robot.tree().coordinate_names().len() as f64;
    let sampler = if optimal || method == "trajectory" {
        p.pool_sampler.as_str()
    } else {
        method
    };
    // A grid tries its own points only.
    let tries = if sampler == "grid" { 1.0 } else { 20.0 };
    let per_try = match space {
        Space::Joint => 2.0 * fk,
        // A hundred iterations, each a Jacobian of every joint.
        Space::Cartesian => 100.0 * (joints + 1.0) * fk,
    };
    let drawn = (tries * (8.0 * joints + 48.0) + pose.bytes, tries * per_try + pose.flops);
    let n_name = if p.next.is_some() { "--next" } else { "--n" };
    if method == "trajectory" {
        // Its pool is sampled; the rest is a nearest-neighbour search per trajectory point.
        let PlanPool::Sampled(size) = p.pool else {
            return Ok(());
        };
        return limits::check("--pool", size, "poses", &|n| Cost::per_unit(n, drawn.0, drawn.1));
    }
    if !optimal {
        return limits::check(n_name, n, "poses", &|n| Cost::per_unit(n, drawn.0, drawn.1));
    }
    let params = (robot.chain_params().len()
        + robot.error_models().iter().map(|m| m.params().len()).sum::<usize>()
        + robot.setup_param_names().len()) as f64;
    let rows = 3.0 * robot.markers().len().max(1) as f64;
    // A candidate's Jacobian rows, scaled and unscaled, and its samples.
    let candidate_bytes = 16.0 * rows * params + pose.bytes;
    let scoring =
        |picks: usize, passes: usize| rows * params * (fk + params * picks as f64 * passes.saturating_add(1) as f64);
    let (sampled, default_pool) = match p.pool {
        PlanPool::Sampled(size) => (true, (size == 0).then_some(10)),
        _ => (false, None),
    };
    let cost_with = |pool: usize, picks: usize, passes: usize| {
        let (bytes, flops) = if sampled { drawn } else { (0.0, 0.0) };
        Cost::per_unit(pool, bytes + candidate_bytes, flops + scoring(picks, passes))
    };
    // The poses asked for first, then the passes: too many passes are too many for the
    // smallest pool too, and the pool's message would then ask for fewer than no poses.
    limits::check(n_name, n, "poses", &|n| cost_with(n, n, 0))?;
    limits::check("--exchange-passes", p.exchange_passes, "passes", &|e| {
        cost_with(n, n, e)
    })?;
    let cost = |pool: usize, picks: usize| cost_with(pool, picks, p.exchange_passes);
    let pool = match &p.pool {
        PlanPool::Sampled(size) => *size,
        PlanPool::Configurations(poses) => poses.len(),
        PlanPool::Measured(set) => set.rows.len(),
    };
    if let Some(times) = default_pool {
        return limits::check(n_name, n, "poses", &|n| cost(times * n, n));
    }
    limits::check("--pool", pool, "poses", &|pool| cost(pool, n))?;
    limits::check(n_name, n, "poses", &|n| cost(pool, n))
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
fn measured_candidates(robot: &Robot, set: &MeasurementSet, accept: &dyn Fn(&[f64]) -> bool) -> Result<Candidates> {
    let mut groups: Vec<(usize, Vec<Sample>)> = Vec::new();
    for (s, &row) in on_robot_stations(robot, set, "pool")?.into_iter().zip(&set.rows) {
        match groups.last_mut() {
            Some((r, g)) if *r == row => g.push(s.clone()),
            _ => groups.push((row, vec![s])),
        }
    }
    let total = groups.len();
    let (rows, samples): (Vec<usize>, Vec<Vec<Sample>>) = groups.into_iter().filter(|(_, g)| accept(&g[0].q)).unzip();
    Ok(Candidates {
        note: format!(
            "picked from {} measured rows{}",
            rows.len(),
            skipped(total - rows.len())
        ),
        samples,
        rows: Some(rows),
    })
}

/// The samples of `set` with their stations renumbered to the robot's, by name: a file
/// numbers the stations of its `station` column in its own order. A station the robot does
/// not know has no measurement frame to plan with.
fn on_robot_stations(robot: &Robot, set: &MeasurementSet, what: &str) -> Result<Vec<Sample>> {
    let known = robot.stations();
    let index: Vec<usize> = match set.stations.as_slice() {
        [] => Vec::new(),
        [_] if known.is_empty() => vec![0],
        names => (names.iter())
            .map(|name| {
                known.iter().position(|s| &s.name == name).ok_or_else(|| {
                    let robot_has: Vec<&str> = known.iter().map(|s| s.name.as_str()).collect();
                    invalid(
                        what,
                        format!(
                            "its station `{}` is not a station of the robot (it has {}); plan with the model calibrated \
                             on those stations, or without the `station` column",
                            shown(name),
                            if robot_has.is_empty() { "one measurement frame".to_string() } else { listed(&robot_has) }
                        ),
                    )
                })
            })
            .collect::<Result<_>>()?,
    };
    Ok((set.samples.iter())
        .map(|s| Sample {
            station: index.get(s.station).copied().unwrap_or(0),
            ..s.clone()
        })
        .collect())
}

fn skipped(colliding: usize) -> String {
    if colliding > 0 {
        format!(" ({colliding} colliding left out)")
    } else {
        String::new()
    }
}

/// The optimal methods: the best `n` of the candidates given the measured samples.
fn optimal(robot: &Robot, p: &PlanParams, criterion: Criterion, n: usize, candidates: Candidates) -> Result<PlanRun> {
    if candidates.samples.is_empty() {
        return Err(invalid(
            "pool",
            format!("it has no collision-free pose to pick from ({})", candidates.note),
        ));
    }
    let params = SelectionParams {
        criterion,
        identify: p.identify.clone(),
        measurement_std: p.measurement_std,
        exchange_passes: p.exchange_passes,
    };
    let report = select_poses(
        robot,
        &candidates.samples,
        n.min(candidates.samples.len()),
        &on_robot_stations(robot, &p.measured, "measured")?,
        &[],
        &params,
    )?;
    let poses: Vec<Vec<f64>> = report
        .chosen
        .iter()
        .map(|&i| candidates.samples[i][0].q.clone())
        .collect();
    let mut warnings = Vec::new();
    if poses.len() < n {
        warnings.push(format!("only {} poses could be picked", poses.len()));
    }
    let rows = candidates
        .rows
        .as_ref()
        .map(|rows| report.chosen.iter().map(|&i| rows[i]).collect());
    let chosen_samples = candidates.rows.as_ref().map(|_| {
        report
            .chosen
            .iter()
            .flat_map(|&i| candidates.samples[i].iter().cloned())
            .collect()
    });
    Ok(PlanRun {
        poses,
        note: candidates.note,
        selection: Some(report),
        rows,
        chosen_samples,
        warnings,
    })
}
