//! Forward kinematics and Jacobians of many configurations in one call, into a caller's buffer
//! (what the Python package's `fk_many` hands a whole numpy batch to). A rigid robot runs the
//! batched point kinematics ([`PointKinematics::forward_many_into`](crate::point_kinematics::PointKinematics::forward_many_into)); one with error models
//! evaluates its full model configuration by configuration.

use nalgebra::{IsometryMatrix3, Matrix6xX};

use crate::error::{Error, Result};
use crate::point_kinematics_many::PointKinematicsManyWorkspace;
use crate::robot::{Robot, RobotWorkspace};

/// Buffers for the batch calls of a [`Robot`]; create once with [`Robot::batch_workspace`].
#[derive(Debug, Clone)]
pub struct BatchWorkspace {
    many: PointKinematicsManyWorkspace,
    robot: RobotWorkspace,
    jacobian: Matrix6xX<f64>,
}

impl Robot {
    /// Buffers sized for this robot's batch calls.
    pub fn batch_workspace(&self) -> BatchWorkspace {
        BatchWorkspace {
            many: self.kinematics().many_workspace(),
            robot: self.workspace(),
            jacobian: Matrix6xX::zeros(self.tree().nq()),
        }
    }

    /// Positions (m, base frame) of every point at the `n` configurations of `qs` (row-major,
    /// [`nq`](crate::KinematicTree::nq) values each), through the full model, written to `out`
    /// as `x, y, z` per point per configuration. Checks every configuration before writing;
    /// allocates nothing.
    pub fn point_positions_many_into(
        &self,
        n: usize,
        qs: &[f64],
        out: &mut [f64],
        ws: &mut BatchWorkspace,
    ) -> Result<()> {
        let width = 3 * self.tree().points().len();
        self.check_configurations(n, qs, "positions", width, out.len())?;
        if self.error_models().is_empty() {
            return self.kinematics().point_positions_many_into(n, qs, out, &mut ws.many);
        }
        let nq = self.tree().nq();
        for i in 0..n {
            self.forward_into(&qs[i * nq..(i + 1) * nq], None, &mut ws.robot);
            let o = &mut out[i * width..(i + 1) * width];
            for (p, xyz) in ws.robot.frames.point.iter().zip(o.chunks_exact_mut(3)) {
                xyz.copy_from_slice(p.translation.vector.as_slice());
            }
        }
        Ok(())
    }

    /// Poses (base frame) of every point at the `n` configurations of `qs`, through the full
    /// model, into `out` (`n ×` points, configuration by configuration). Checks every
    /// configuration before writing; allocates nothing.
    pub fn forward_many_into(
        &self,
        n: usize,
        qs: &[f64],
        out: &mut [IsometryMatrix3<f64>],
        ws: &mut BatchWorkspace,
    ) -> Result<()> {
        let np = self.tree().points().len();
        self.check_configurations(n, qs, "poses", np, out.len())?;
        if self.error_models().is_empty() {
            return self.kinematics().forward_many_into(n, qs, out, &mut ws.many);
        }
        let nq = self.tree().nq();
        for i in 0..n {
            self.forward_into(&qs[i * nq..(i + 1) * nq], None, &mut ws.robot);
            for (p, pose) in ws.robot.frames.point.iter().zip(&mut out[i * np..(i + 1) * np]) {
                *pose = IsometryMatrix3::from_parts(p.translation, p.rotation.to_rotation_matrix());
            }
        }
        Ok(())
    }

    /// The 6 × nq pose Jacobian of point `point` (as
    /// [`PointKinematics::pose_jacobian_into`](crate::point_kinematics::PointKinematics::pose_jacobian_into);
    /// with error models, of the deformed arm with the deformation held, as the IK uses it) at
    /// the `n` configurations of `qs`, into `out` as `n` column-major 6 × nq blocks. Checks
    /// every configuration before writing; allocates nothing.
    pub fn pose_jacobian_many_into(
        &self,
        n: usize,
        qs: &[f64],
        point: usize,
        out: &mut [f64],
        ws: &mut BatchWorkspace,
    ) -> Result<()> {
        if point >= self.tree().points().len() {
            return Err(Error::InvalidArgument {
                what: "pose Jacobian".into(),
                reason: format!(
                    "point {point} does not exist; the robot has {}",
                    self.tree().points().len()
                ),
            });
        }
        let nq = self.tree().nq();
        self.check_configurations(n, qs, "Jacobians", 6 * nq, out.len())?;
        if self.error_models().is_empty() {
            return self
                .kinematics()
                .pose_jacobian_many_into(n, qs, point, out, &mut ws.many);
        }
        for i in 0..n {
            self.forward_into(&qs[i * nq..(i + 1) * nq], None, &mut ws.robot);
            self.tree()
                .pose_jacobian_into(&ws.robot.frames, point, &mut ws.jacobian);
            out[6 * nq * i..6 * nq * (i + 1)].copy_from_slice(ws.jacobian.as_slice());
        }
        Ok(())
    }

    /// Checks the sizes of a batch and every configuration in it.
    fn check_configurations(&self, n: usize, qs: &[f64], what: &str, width: usize, got: usize) -> Result<()> {
        let nq = self.tree().nq();
        for (what, expected, got) in [("configurations", n * nq, qs.len()), (what, n * width, got)] {
            if expected != got {
                return Err(Error::Dimension {
                    what: what.into(),
                    expected,
                    got,
                });
            }
        }
        for i in 0..n {
            self.tree()
                .check_q(&qs[i * nq..(i + 1) * nq])
                .map_err(|e| Error::InvalidArgument {
                    what: format!("configuration {}", i + 1),
                    reason: e.to_string(),
                })?;
        }
        Ok(())
    }
}
