//! Measurement pose planning: where to put the arm so that a few hundred measurements say as
//! much as possible.
//!
//! - joint-space sets (Sobol, Halton, pseudo-random, grid) inside the limits;
//! - Cartesian sets: quasi-random points in the box the tool can reach, each turned into a
//!   configuration by IK on the full model (the ANN paper's QRS pool); points IK cannot reach
//!   are skipped;
//! - optimal subsets of a pool for calibration are [`crate::analysis::design`]'s;
//! - trajectory-similar subsets (ANN paper Sec. 3.4.1): points spread along a task trajectory
//!   by arc length, and for each the nearest unused pool points by tool position.
//!
//! Every method takes an `accept` filter (e.g. collision checking) applied to candidates. Tool
//! positions come from the batch calls ([`Robot::point_positions_many`]): the tool's path alone
//! on a rigid robot, the full model with error models.

use nalgebra::Vector3;

use crate::algorithms::ik::{IkParams, IkTarget, IkWorkspace, solve_ik};
use crate::error::{Error, Result};
use crate::model::sampling::{SOBOL_POINTS, Sampler, configurations, unit_points};
use crate::robot::Robot;

/// Where a set of poses spreads evenly.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Space {
    /// Evenly over the joint ranges.
    Joint,
    /// Evenly over the Cartesian box the tool reaches (through IK).
    Cartesian,
}

/// A planned set of poses and what was left out on the way.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanReport {
    /// Joint configurations (rad, m).
    pub poses: Vec<Vec<f64>>,
    /// Tool positions at those configurations (m, robot base frame).
    pub tool_positions: Vec<Vector3<f64>>,
    /// Candidates IK could not reach.
    pub unreachable: usize,
    /// Candidates the `accept` filter rejected.
    pub rejected: usize,
}

/// `n` evenly spread poses in `space`, drawn with `sampler` and `seed`, each passing `accept`.
/// Fewer are returned (and the report says why) when candidates run out: at most `20 n` are
/// tried, and for a grid only its `n` points (a longer grid's first `n` points would fill a
/// corner of the ranges only).
pub fn spread(
    robot: &Robot,
    space: Space,
    sampler: Sampler,
    n: usize,
    seed: u64,
    accept: &dyn Fn(&[f64]) -> bool,
) -> Result<PlanReport> {
    let mut report = PlanReport {
        poses: Vec::new(),
        tool_positions: Vec::new(),
        unreachable: 0,
        rejected: 0,
    };
    let tries = match sampler {
        Sampler::Grid => n,
        // Sobol's table ends at SOBOL_POINTS; fewer tries, not a shorter set.
        Sampler::Sobol => n.saturating_mul(20).min(SOBOL_POINTS).max(n),
        _ => n.saturating_mul(20).max(n),
    };
    match space {
        Space::Joint => {
            for q in configurations(robot.tree(), sampler, tries, seed)? {
                if report.poses.len() == n {
                    break;
                }
                if !accept(&q) {
                    report.rejected += 1;
                    continue;
                }
                report.poses.push(q);
            }
            report.tool_positions = robot.point_positions_many(&[robot.tool()], &report.poses)?;
        }
        Space::Cartesian => {
            // The reachable box and IK starts come from a joint-space pool.
            let starts = configurations(robot.tree(), Sampler::Sobol, 2000, seed ^ 0x5eed)?;
            let start_pos = robot.point_positions_many(&[robot.tool()], &starts)?;
            let (lo, hi) = start_pos.iter().fold(
                (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY)),
                |(lo, hi), p| (lo.inf(p), hi.sup(p)),
            );
            let opts = IkParams {
                restarts: 2,
                max_iterations: 100,
                position_tolerance: 1e-7,
                ..IkParams::default()
            };
            let mut ik = IkWorkspace::new(robot);
            for u in unit_points(sampler, tries, 3, seed)? {
                if report.poses.len() == n {
                    break;
                }
                let target = Vector3::new(
                    lo.x + u[0] * (hi.x - lo.x),
                    lo.y + u[1] * (hi.y - lo.y),
                    lo.z + u[2] * (hi.z - lo.z),
                );
                let nearest = nearest(&start_pos, &target, 1)[0];
                match solve_ik(
                    robot,
                    robot.tool(),
                    &IkTarget::Position(target),
                    &starts[nearest],
                    &opts,
                    &mut ik,
                ) {
                    Ok(_) if accept(ik.q()) => {
                        report.poses.push(ik.q().to_vec());
                        report.tool_positions.push(target);
                    }
                    Ok(_) => report.rejected += 1,
                    Err(_) => report.unreachable += 1,
                }
            }
        }
    }
    Ok(report)
}

/// Indices of the `k` points of `set` nearest to `p`, nearest first.
fn nearest(set: &[Vector3<f64>], p: &Vector3<f64>, k: usize) -> Vec<usize> {
    let mut idx: Vec<usize> = (0..set.len()).collect();
    idx.sort_by(|&a, &b| (set[a] - p).norm_squared().total_cmp(&(set[b] - p).norm_squared()));
    idx.truncate(k);
    idx
}

/// Trajectory-similar selection (ANN paper Sec. 3.4.1): `points` positions spread along the
/// tool path of `trajectory` (configurations in task order) by arc length, and for each the
/// `per_point` nearest unused pool positions. Returns indices into `pool_positions`.
pub fn trajectory_similar(
    robot: &Robot,
    trajectory: &[Vec<f64>],
    pool_positions: &[Vector3<f64>],
    points: usize,
    per_point: usize,
) -> Result<Vec<usize>> {
    if trajectory.is_empty() {
        return Err(Error::InvalidArgument {
            what: "trajectory".into(),
            reason: "has no configurations".into(),
        });
    }
    if points * per_point > pool_positions.len() {
        return Err(Error::InvalidArgument {
            what: "pool".into(),
            reason: format!(
                "{points} trajectory points × {per_point} neighbours need {} pool poses; the pool has {}",
                points * per_point,
                pool_positions.len()
            ),
        });
    }
    let path = robot.point_positions_many(&[robot.tool()], trajectory)?;
    let mut taken = vec![false; pool_positions.len()];
    let mut out = Vec::with_capacity(points * per_point);
    for target in resample_by_arc_length(&path, points) {
        let mut candidates: Vec<usize> = (0..pool_positions.len()).filter(|&i| !taken[i]).collect();
        candidates.sort_by(|&a, &b| {
            (pool_positions[a] - target)
                .norm_squared()
                .total_cmp(&(pool_positions[b] - target).norm_squared())
        });
        for &i in candidates.iter().take(per_point) {
            taken[i] = true;
            out.push(i);
        }
    }
    Ok(out)
}

/// `n` points evenly spaced by arc length along a polyline (its ends included).
pub fn resample_by_arc_length(path: &[Vector3<f64>], n: usize) -> Vec<Vector3<f64>> {
    if path.len() < 2 || n < 2 {
        return path.iter().take(n.max(1)).copied().cycle().take(n).collect();
    }
    let mut cumulative = vec![0.0];
    for w in path.windows(2) {
        cumulative.push(cumulative.last().copied().unwrap_or(0.0) + (w[1] - w[0]).norm());
    }
    let total = *cumulative.last().unwrap_or(&0.0);
    (0..n)
        .map(|k| {
            let s = total * k as f64 / (n - 1) as f64;
            let i = cumulative.partition_point(|&c| c <= s).clamp(1, path.len() - 1);
            let seg = cumulative[i] - cumulative[i - 1];
            let t = if seg > 0.0 { (s - cumulative[i - 1]) / seg } else { 0.0 };
            path[i - 1] + (path[i] - path[i - 1]) * t.clamp(0.0, 1.0)
        })
        .collect()
}
