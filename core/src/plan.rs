//! Measurement pose planning: where to put the arm so that a few hundred measurements say as
//! much as possible.
//!
//! - joint-space sets (Sobol, Halton, pseudo-random, grid) inside the limits;
//! - Cartesian sets: quasi-random points in the box the tool can reach, each turned into a
//!   configuration by IK on the full model (the ANN paper's QRS pool); points IK cannot reach
//!   are skipped;
//! - D-optimal subsets: greedy selection from a pool maximising `log det(JᵀJ)` of the
//!   identification Jacobian (observability for calibration);
//! - trajectory-similar subsets (ANN paper Sec. 3.4.1): points spread along a task trajectory
//!   by arc length, and for each the nearest unused pool points by tool position.
//!
//! Every method takes an `accept` filter (e.g. collision checking) applied to candidates.

use nalgebra::{Cholesky, DMatrix, Vector3};

use crate::calibrate::identification_jacobian;
use crate::error::{Error, Result};
use crate::ik::{IkOptions, IkTarget, IkWorkspace, solve_ik};
use crate::robot::Robot;
use crate::sampling::{Sampler, configurations, unit_points};

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
/// tried.
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
    let tries = n.saturating_mul(20).max(n);
    let mut ws = robot.workspace();
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
                robot.forward_into(&q, None, &mut ws);
                report.tool_positions.push(ws.frames.point_position(robot.tool()));
                report.poses.push(q);
            }
        }
        Space::Cartesian => {
            // The reachable box and IK starts come from a joint-space pool.
            let starts = configurations(robot.tree(), Sampler::Sobol, 2000, seed ^ 0x5eed)?;
            let start_pos: Vec<Vector3<f64>> = starts
                .iter()
                .map(|q| {
                    robot.forward_into(q, None, &mut ws);
                    ws.frames.point_position(robot.tool())
                })
                .collect();
            let (lo, hi) = start_pos.iter().fold(
                (Vector3::repeat(f64::INFINITY), Vector3::repeat(f64::NEG_INFINITY)),
                |(lo, hi), p| (lo.inf(p), hi.sup(p)),
            );
            let opts = IkOptions {
                restarts: 2,
                max_iterations: 100,
                position_tolerance: 1e-7,
                ..IkOptions::default()
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

/// Greedy D-optimal selection of `n` poses from `pool` for identifying the parameters
/// `identify` selects (see [`crate::calibrate::ParameterSpace::select`]).
///
/// Columns are scaled to unit norm over the pool, the information matrix starts at `εI` so
/// directions no pose can determine do not dominate, and each step adds the pose with the
/// largest gain `log det(I + Jᵢ M⁻¹ Jᵢᵀ)`; the gains of all candidates are kept up to date
/// with rank-3 Woodbury updates, so a step costs `O(pool · p)`. Returns indices into `pool` in
/// selection order and the final `log det M`.
pub fn d_optimal(robot: &Robot, pool: &[Vec<f64>], n: usize, identify: &[String]) -> Result<(Vec<usize>, f64)> {
    if n > pool.len() {
        return Err(Error::Input(format!(
            "cannot pick {n} poses from a pool of {}",
            pool.len()
        )));
    }
    let (mut jac, _) = identification_jacobian(robot, pool, identify)?;
    let rows = jac.nrows() / pool.len().max(1);
    for mut c in jac.column_iter_mut() {
        let norm = c.norm();
        if norm > 0.0 {
            c /= norm;
        }
    }
    let p = jac.ncols();
    let eps = 1e-6;
    // W = M⁻¹ Jᵀ for all candidates (p × rows·pool), with M = εI at the start.
    let mut w: DMatrix<f64> = jac.transpose() / eps;
    let mut chosen = Vec::with_capacity(n);
    let mut taken = vec![false; pool.len()];
    let mut log_det = p as f64 * eps.ln();
    for _ in 0..n {
        // Gain of candidate i: log det(I + Jᵢ M⁻¹ Jᵢᵀ).
        let mut best = (usize::MAX, f64::NEG_INFINITY);
        for i in (0..pool.len()).filter(|&i| !taken[i]) {
            let ji = jac.rows(i * rows, rows);
            let s = DMatrix::identity(rows, rows) + ji * w.columns(i * rows, rows);
            let gain = Cholesky::new(s).map_or(f64::NEG_INFINITY, |c| 2.0 * c.l().diagonal().map(f64::ln).sum());
            if gain > best.1 {
                best = (i, gain);
            }
        }
        let (s_idx, gain) = best;
        if s_idx == usize::MAX {
            break;
        }
        taken[s_idx] = true;
        chosen.push(s_idx);
        log_det += gain;
        // Woodbury: M'⁻¹ = M⁻¹ − M⁻¹Jₛᵀ S⁻¹ Jₛ M⁻¹, so W' = W − Wₛ S⁻¹ (Jₛ W).
        let js = jac.rows(s_idx * rows, rows).into_owned();
        let ws = w.columns(s_idx * rows, rows).into_owned();
        let s = DMatrix::identity(rows, rows) + &js * &ws;
        let s_inv = s.try_inverse().ok_or_else(|| Error::Input("singular update".into()))?;
        let update = &ws * (s_inv * (&js * &w));
        w -= update;
    }
    Ok((chosen, log_det))
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
        return Err(Error::Input("the trajectory has no configurations".into()));
    }
    if points * per_point > pool_positions.len() {
        return Err(Error::Input(format!(
            "{points} trajectory points × {per_point} neighbours need {} pool poses; the pool has {}",
            points * per_point,
            pool_positions.len()
        )));
    }
    let mut ws = robot.workspace();
    let mut path = Vec::with_capacity(trajectory.len());
    for q in trajectory {
        robot.tree().check_q(q)?;
        robot.forward_into(q, None, &mut ws);
        path.push(ws.frames.point_position(robot.tool()));
    }
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

/// `log det(JᵀJ + εI)` of a pose set for the parameters `identify` selects (unscaled columns,
/// so compare sets of the same robot and parameters only).
pub fn information_log_det(robot: &Robot, poses: &[Vec<f64>], identify: &[String]) -> Result<f64> {
    let (jac, _) = identification_jacobian(robot, poses, identify)?;
    let mut m = jac.transpose() * &jac;
    for i in 0..m.nrows() {
        m[(i, i)] += 1e-6;
    }
    Cholesky::new(m)
        .map(|c| 2.0 * c.l().diagonal().map(f64::ln).sum())
        .ok_or_else(|| Error::Input("the information matrix is not positive definite".into()))
}
