//! The deflection paper's Eq. 5: the tool's differential motion as the sum of every link's
//! differential motion mapped to the tool.

use armcomp_core::{KinematicTree, Motion, Perturbation, TreeWorkspace};
use nalgebra::{Vector3, Vector6};

use crate::common::adjoint;

/// First-order differential motion `D = [dx, dy, dz, δx, δy, δz]` of point `point`, in that
/// point's own frame, caused by `pert` (Eq. 5).
///
/// Each joint twist `Δ_i` (in joint frame `i`) is carried to the point by
/// `[nᵀ (p×n)ᵀ; oᵀ (p×o)ᵀ; aᵀ (p×a)ᵀ; 0 nᵀ; 0 oᵀ; 0 aᵀ]` with `(n, o, a, p)` the point's pose
/// in frame `i`, which is the adjoint of its inverse. Joint offsets enter as a twist about (or
/// along) the joint axis in the child link's frame; the point's own twist is added as it is.
/// `frames` holds the rigid forward kinematics of the configuration.
pub fn tool_differential(
    tree: &KinematicTree,
    frames: &TreeWorkspace,
    pert: &Perturbation,
    point: usize,
) -> Vector6<f64> {
    let tool = frames.point[point];
    let mut d = pert.point_twist[point];
    for &j in tree.support(tree.points()[point].body) {
        let twist = pert.joint_twist[j];
        if twist != Vector6::zeros() {
            let rel = frames.joint_frame[j].inverse() * tool;
            d += adjoint(&rel.inverse(), &twist);
        }
        let dq = pert.joint_offset[j];
        if dq != 0.0 {
            let xi = match tree.joints()[j].motion {
                Motion::Revolute(axis) => {
                    let w = axis.into_inner() * dq;
                    Vector6::new(0.0, 0.0, 0.0, w.x, w.y, w.z)
                }
                Motion::Prismatic(axis) => {
                    let v: Vector3<f64> = axis.into_inner() * dq;
                    Vector6::new(v.x, v.y, v.z, 0.0, 0.0, 0.0)
                }
                Motion::Fixed => Vector6::zeros(),
            };
            let rel = frames.body[j + 1].inverse() * tool;
            d += adjoint(&rel.inverse(), &xi);
        }
    }
    d
}

/// [`tool_differential`] in world coordinates: `(displacement of the point, rotation vector)`.
pub fn tool_differential_world(
    tree: &KinematicTree,
    frames: &TreeWorkspace,
    pert: &Perturbation,
    point: usize,
) -> (Vector3<f64>, Vector3<f64>) {
    let d = tool_differential(tree, frames, pert, point);
    let r = frames.point[point].rotation;
    (r * Vector3::new(d[0], d[1], d[2]), r * Vector3::new(d[3], d[4], d[5]))
}
