//! Gravity loads: the weight of everything a joint carries (payload included), as a force and
//! moment about a point, and as the torque about the joint's axis or force along it. Error
//! models bend the chain by these loads; the diagnosis correlates residuals with them.

use nalgebra::Vector3;

use crate::model::tree::Motion;
use crate::plugin::StaticState;

/// Gravity force (N, world) and its moment (N m, world) about `about` of the subtree rooted at
/// body `c`, the payload included when it hangs in that subtree. Rigid frames of `state`.
#[inline]
pub fn subtree_wrench(state: &StaticState<'_>, c: usize, about: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
    state.loads.wrench(c, &state.gravity, about)
}

/// Gravity torque (N m) about joint `j`'s axis (revolute) or force (N) along it (prismatic)
/// from the subtree it moves; 0 for fixed joints.
#[inline]
pub fn joint_gravity_load(state: &StaticState<'_>, j: usize) -> f64 {
    let frame = &state.frames.joint_frame[j];
    let origin = frame.translation.vector;
    match state.tree.joints()[j].motion {
        Motion::Revolute(axis) => {
            let (_, m) = subtree_wrench(state, j + 1, &origin);
            (frame.rotation * axis.into_inner()).dot(&m)
        }
        Motion::Prismatic(axis) => {
            let (f, _) = subtree_wrench(state, j + 1, &origin);
            (frame.rotation * axis.into_inner()).dot(&f)
        }
        Motion::Fixed => 0.0,
    }
}
