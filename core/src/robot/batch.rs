//! Forward kinematics and Jacobians of many configurations in one call, into a caller's buffer
//! (what the Python package's `fk_many` hands a whole numpy batch to, and what simulation,
//! planning and evaluation evaluate their poses through). A rigid robot runs the batched point
//! kinematics ([`PointKinematics::forward_many_into`]); one with error models evaluates its full
//! model configuration by configuration.

use nalgebra::{IsometryMatrix3, Matrix6xX, Vector3};

use crate::error::{Error, Result};
use crate::kinematics::point_kinematics::PointKinematics;
use crate::kinematics::point_kinematics_many::PointKinematicsManyWorkspace;
use crate::kinematics::workspace::TreeWorkspace;
use crate::robot::{Robot, RobotWorkspace};

/// Buffers for the batch calls of one [`Robot`], and the points they write: every point
/// ([`Robot::batch_workspace`]) or some ([`Robot::batch_workspace_for`], which also holds
/// those points' compiled kinematics). Create once and use with that robot only.
#[derive(Debug, Clone)]
pub struct BatchWorkspace {
    /// The points of a [`Robot::batch_workspace_for`] (their kinematics compiled from the
    /// robot's tree); `None`: every point, through [`Robot::kinematics`].
    some: Option<PointKinematics>,
    many: PointKinematicsManyWorkspace,
    robot: RobotWorkspace,
    jacobian: Matrix6xX<f64>,
}

impl Robot {
    /// Buffers for batch calls that write every point of this robot, in the tree's order.
    pub fn batch_workspace(&self) -> BatchWorkspace {
        self.batch_workspace_of(None)
    }

    /// Buffers for batch calls that write only the points `points` (indices into
    /// [`KinematicTree::points`](crate::KinematicTree::points), e.g. the markers or the tool),
    /// in that order: on a rigid robot only their paths are evaluated.
    pub fn batch_workspace_for(&self, points: &[usize]) -> Result<BatchWorkspace> {
        Ok(self.batch_workspace_of(Some(PointKinematics::for_points(self.tree(), points)?)))
    }

    fn batch_workspace_of(&self, some: Option<PointKinematics>) -> BatchWorkspace {
        BatchWorkspace {
            many: some.as_ref().unwrap_or(self.kinematics()).many_workspace(),
            some,
            robot: self.workspace(),
            jacobian: Matrix6xX::zeros(self.tree().nq()),
        }
    }

    /// Positions (m, base frame) of the workspace's points at the `n` configurations of `qs`
    /// (row-major, [`nq`](crate::KinematicTree::nq) values each), through the full model,
    /// written to `out` as `x, y, z` per point per configuration. Checks every configuration
    /// before writing; allocates nothing.
    pub fn point_positions_many_into(
        &self,
        n: usize,
        qs: &[f64],
        out: &mut [f64],
        ws: &mut BatchWorkspace,
    ) -> Result<()> {
        let plan = ws.some.as_ref().unwrap_or(self.kinematics());
        let width = 3 * plan.tree_points().len();
        self.check_configurations(plan, n, qs, "positions", width, out.len())?;
        if self.error_models().is_empty() {
            return plan.point_positions_many_into(n, qs, out, &mut ws.many);
        }
        self.full_model_each(n, qs, &mut ws.robot, |i, frames| {
            let o = &mut out[i * width..(i + 1) * width];
            for (&p, xyz) in plan.tree_points().iter().zip(o.chunks_exact_mut(3)) {
                xyz.copy_from_slice(frames.point[p].translation.vector.as_slice());
            }
        });
        Ok(())
    }

    /// Poses (base frame) of the workspace's points at the `n` configurations of `qs`, through
    /// the full model, into `out` (`n ×` points, configuration by configuration). Checks every
    /// configuration before writing; allocates nothing.
    pub fn forward_many_into(
        &self,
        n: usize,
        qs: &[f64],
        out: &mut [IsometryMatrix3<f64>],
        ws: &mut BatchWorkspace,
    ) -> Result<()> {
        let plan = ws.some.as_ref().unwrap_or(self.kinematics());
        let np = plan.tree_points().len();
        self.check_configurations(plan, n, qs, "poses", np, out.len())?;
        if self.error_models().is_empty() {
            return plan.forward_many_into(n, qs, out, &mut ws.many);
        }
        self.full_model_each(n, qs, &mut ws.robot, |i, frames| {
            for (&p, pose) in plan.tree_points().iter().zip(&mut out[i * np..(i + 1) * np]) {
                let p = &frames.point[p];
                *pose = IsometryMatrix3::from_parts(p.translation, p.rotation.to_rotation_matrix());
            }
        });
        Ok(())
    }

    /// The 6 × nq pose Jacobian of the workspace's point `k` (the tree's point `k` for
    /// [`batch_workspace`](Self::batch_workspace); as
    /// [`PointKinematics::pose_jacobian_into`]; with error models, of the deformed arm with
    /// the deformation held, as the IK uses it) at the `n` configurations of `qs`, into `out`
    /// as `n` column-major 6 × nq blocks. Checks every configuration before writing; allocates
    /// nothing.
    pub fn pose_jacobian_many_into(
        &self,
        n: usize,
        qs: &[f64],
        k: usize,
        out: &mut [f64],
        ws: &mut BatchWorkspace,
    ) -> Result<()> {
        let plan = ws.some.as_ref().unwrap_or(self.kinematics());
        let Some(&point) = plan.tree_points().get(k) else {
            return Err(Error::InvalidArgument {
                what: "pose Jacobian".into(),
                reason: format!("point {k} does not exist; the batch has {}", plan.tree_points().len()),
            });
        };
        let nq = self.tree().nq();
        self.check_configurations(plan, n, qs, "Jacobians", 6 * nq, out.len())?;
        if self.error_models().is_empty() {
            return plan.pose_jacobian_many_into(n, qs, k, out, &mut ws.many);
        }
        let jacobian = &mut ws.jacobian;
        self.full_model_each(n, qs, &mut ws.robot, |i, frames| {
            self.tree().pose_jacobian_into(frames, point, jacobian);
            out[6 * nq * i..6 * nq * (i + 1)].copy_from_slice(jacobian.as_slice());
        });
        Ok(())
    }

    /// Positions (m, base frame) of the points `points` at each configuration of `poses`,
    /// through the full model as [`point_positions_many_into`](Self::point_positions_many_into):
    /// `poses.len() × points.len()` of them, configuration by configuration.
    pub fn point_positions_many(&self, points: &[usize], poses: &[Vec<f64>]) -> Result<Vec<Vector3<f64>>> {
        // Lengths first, so that a short configuration is named rather than the batch's total;
        // the batch call checks the values.
        let nq = self.tree().nq();
        for (i, q) in poses.iter().enumerate().filter(|(_, q)| q.len() != nq) {
            self.check_configuration(i, q)?;
        }
        let mut ws = self.batch_workspace_for(points)?;
        let mut out = vec![0.0; 3 * points.len() * poses.len()];
        self.point_positions_many_into(poses.len(), &poses.concat(), &mut out, &mut ws)?;
        Ok(out.chunks_exact(3).map(Vector3::from_column_slice).collect())
    }

    /// The full model at each of the `n` configurations of `qs` in turn, its frames handed to
    /// `write` with the configuration's index.
    fn full_model_each(
        &self,
        n: usize,
        qs: &[f64],
        ws: &mut RobotWorkspace,
        mut write: impl FnMut(usize, &TreeWorkspace),
    ) {
        let nq = self.tree().nq();
        for i in 0..n {
            self.forward_into(&qs[i * nq..(i + 1) * nq], None, ws);
            write(i, &ws.frames);
        }
    }

    /// Checks the sizes of a batch of `plan` and every configuration in it.
    fn check_configurations(
        &self,
        plan: &PointKinematics,
        n: usize,
        qs: &[f64],
        what: &str,
        width: usize,
        got: usize,
    ) -> Result<()> {
        plan.check_batch(n, qs, what, width, got)?;
        let nq = self.tree().nq();
        (0..n).try_for_each(|i| self.check_configuration(i, &qs[i * nq..(i + 1) * nq]))
    }

    /// Checks configuration `i` (from 0) of a batch, naming it from 1.
    fn check_configuration(&self, i: usize, q: &[f64]) -> Result<()> {
        self.tree().check_q(q).map_err(|e| Error::InvalidArgument {
            what: format!("configuration {}", i + 1),
            reason: e.to_string(),
        })
    }
}
