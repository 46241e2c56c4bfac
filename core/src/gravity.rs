//! Gravity loads: the weight of everything a joint carries (payload included), as a force and
//! moment about a point, and as the torque about the joint's axis or force along it. Error
//! models bend the chain by these loads; the diagnosis correlates residuals with them.

use nalgebra::Vector3;

use crate::plugin::StaticState;
use crate::tree::{KinematicTree, Motion};

/// For every body, the bodies of the subtree it roots (itself included), for load sums.
#[derive(Debug, Clone)]
pub struct Subtrees {
    bodies: Vec<Vec<usize>>,
}

impl Subtrees {
    /// The subtrees of `tree`'s bodies.
    pub fn new(tree: &KinematicTree) -> Self {
        let n = tree.bodies().len();
        let bodies = (0..n)
            .map(|c| {
                if c == 0 {
                    return (0..n).collect();
                }
                (c..n)
                    .filter(|&k| k == c || tree.support(k).contains(&(c - 1)))
                    .collect()
            })
            .collect();
        Subtrees { bodies }
    }

    /// Bodies in the subtree rooted at body `c` (itself first).
    pub fn of(&self, c: usize) -> &[usize] {
        &self.bodies[c]
    }

    /// Whether body `k` is in the subtree rooted at body `c`.
    pub fn contains(&self, c: usize, k: usize) -> bool {
        self.bodies[c].binary_search(&k).is_ok()
    }
}

/// Gravity force (N, world) and its moment (N m, world) about `about` of the subtree rooted at
/// body `c`, the payload included when it hangs in that subtree. Rigid frames of `state`.
#[inline]
pub fn subtree_wrench(
    state: &StaticState<'_>,
    subtrees: &Subtrees,
    c: usize,
    about: &Vector3<f64>,
) -> (Vector3<f64>, Vector3<f64>) {
    let mut force = Vector3::zeros();
    let mut moment = Vector3::zeros();
    let g = state.gravity;
    for &k in subtrees.of(c) {
        let b = &state.mass.bodies[k];
        if b.mass != 0.0 {
            let f = g * b.mass;
            let com = state.frames.body[k].transform_point(&b.com.into()).coords;
            force += f;
            moment += (com - about).cross(&f);
        }
    }
    if let Some(p) = &state.mass.payload
        && p.mass != 0.0
        && subtrees.contains(c, p.body)
    {
        let f = g * p.mass;
        let com = state.frames.body[p.body].transform_point(&p.com.into()).coords;
        force += f;
        moment += (com - about).cross(&f);
    }
    (force, moment)
}

/// Gravity torque (N m) about joint `j`'s axis (revolute) or force (N) along it (prismatic)
/// from the subtree it moves; 0 for fixed joints.
#[inline]
pub fn joint_gravity_load(state: &StaticState<'_>, subtrees: &Subtrees, j: usize) -> f64 {
    let frame = &state.frames.joint_frame[j];
    let origin = frame.translation.vector;
    match state.tree.joints()[j].motion {
        Motion::Revolute(axis) => {
            let (_, m) = subtree_wrench(state, subtrees, j + 1, &origin);
            (frame.rotation * axis.into_inner()).dot(&m)
        }
        Motion::Prismatic(axis) => {
            let (f, _) = subtree_wrench(state, subtrees, j + 1, &origin);
            (frame.rotation * axis.into_inner()).dot(&f)
        }
        Motion::Fixed => 0.0,
    }
}
