//! `plan`: measurement poses, evenly spread, D-optimal or near a task trajectory; never in
//! collision.

use std::cell::RefCell;

use armcomp_core::collision::CollisionModel;
use armcomp_core::plan::{Space, d_optimal, spread, trajectory_similar};
use armcomp_core::sampling::Sampler;
use armcomp_core::{Error, Robot};

/// Settings of [`run`].
#[derive(Debug, Clone)]
pub struct PlanParams {
    /// Number of poses (for `trajectory`: trajectory points × neighbours instead).
    pub n: usize,
    /// sobol, halton, random, grid, d-optimal or trajectory.
    pub method: String,
    /// `joint` or `cartesian`: where poses (or the pool) spread evenly.
    pub space: String,
    /// Pool size for d-optimal (default 10 × n) and trajectory (default 2000).
    pub pool: Option<usize>,
    /// How the pool is drawn: sobol, halton, random or grid.
    pub pool_sampler: String,
    /// Parameters a d-optimal plan should determine (as calibration's `identify`).
    pub identify: Vec<String>,
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
            method: "sobol".into(),
            space: "joint".into(),
            pool: None,
            pool_sampler: "sobol".into(),
            identify: Vec::new(),
            trajectory: None,
            trajectory_points: 50,
            per_point: 10,
            seed: 0,
        }
    }
}

/// Planned poses (SI joint values) and a one-line account of how they were found.
#[derive(Debug, Clone)]
pub struct PlanRun {
    /// The poses.
    pub poses: Vec<Vec<f64>>,
    /// What was picked from what, or skipped.
    pub note: String,
}

/// Plans measurement poses for `robot`.
pub fn run(robot: &Robot, p: &PlanParams) -> armcomp_core::Result<PlanRun> {
    let space = match p.space.as_str() {
        "joint" => Space::Joint,
        "cartesian" => Space::Cartesian,
        other => {
            return Err(Error::Input(format!(
                "unknown space `{other}`; expected joint or cartesian"
            )));
        }
    };
    // Poses in collision (self-collision or fixtures) are never planned.
    let collision = CollisionModel::new(robot);
    let collision_ws = RefCell::new(collision.workspace());
    let accept = |q: &[f64]| !collision.collides(q, &mut collision_ws.borrow_mut());
    let pool_sampler = Sampler::parse(&p.pool_sampler)?;
    let pool = |n: usize| spread(robot, space, pool_sampler, n, p.seed, &accept);
    Ok(match p.method.as_str() {
        "d-optimal" => {
            let pool = pool(p.pool.unwrap_or(10 * p.n))?;
            let (chosen, log_det) = d_optimal(robot, &pool.poses, p.n.min(pool.poses.len()), &p.identify)?;
            PlanRun {
                poses: chosen.iter().map(|&i| pool.poses[i].clone()).collect(),
                note: format!(
                    "picked from a pool of {} ({} unreachable); log det of the scaled information {log_det:.2}",
                    pool.poses.len(),
                    pool.unreachable
                ),
            }
        }
        "trajectory" => {
            let Some(trajectory) = &p.trajectory else {
                return Err(Error::Input(
                    "method trajectory needs a trajectory (joint configurations in task order)".into(),
                ));
            };
            let pool = pool(p.pool.unwrap_or(2000))?;
            let chosen = trajectory_similar(
                robot,
                trajectory,
                &pool.tool_positions,
                p.trajectory_points,
                p.per_point,
            )?;
            PlanRun {
                poses: chosen.iter().map(|&i| pool.poses[i].clone()).collect(),
                note: format!(
                    "{} trajectory points × {} nearest of a pool of {}",
                    p.trajectory_points,
                    p.per_point,
                    pool.poses.len()
                ),
            }
        }
        sampler => {
            let plan = spread(robot, space, Sampler::parse(sampler)?, p.n, p.seed, &accept)?;
            PlanRun {
                note: format!(
                    "{} unreachable and {} colliding candidates skipped",
                    plan.unreachable, plan.rejected
                ),
                poses: plan.poses,
            }
        }
    })
}
