//! Small deformations of the chain produced by error models (deflection paper Eq. 1–3).

use nalgebra::Vector6;

use crate::model::tree::KinematicTree;

/// Per-joint and per-point small motions that error models add to the rigid chain.
///
/// A twist is `[dx, dy, dz, δx, δy, δz]` (m, rad), expressed in the frame it perturbs, and
/// composed on the right: `T' = T · exp(Δ)`, which is the paper's `T' = T + T·Δ` (Eq. 1–2)
/// made exact to keep frames orthonormal.
#[derive(Debug, Clone, PartialEq)]
pub struct Perturbation {
    /// Twist of each joint's placement (deformation of the parent link at this joint's seat).
    pub joint_twist: Vec<Vector6<f64>>,
    /// Added to each joint's value (joint compliance, backlash, encoder errors), rad or m.
    pub joint_offset: Vec<f64>,
    /// Twist of each point's pose on its body (deformation of the link at the point).
    pub point_twist: Vec<Vector6<f64>>,
}

impl Perturbation {
    /// A zero perturbation sized for `tree`.
    pub fn zeros(tree: &KinematicTree) -> Self {
        Perturbation {
            joint_twist: vec![Vector6::zeros(); tree.joints().len()],
            joint_offset: vec![0.0; tree.joints().len()],
            point_twist: vec![Vector6::zeros(); tree.points().len()],
        }
    }

    /// Resets every entry to zero without reallocating.
    pub fn clear(&mut self) {
        self.joint_twist.iter_mut().for_each(|t| *t = Vector6::zeros());
        self.joint_offset.iter_mut().for_each(|v| *v = 0.0);
        self.point_twist.iter_mut().for_each(|t| *t = Vector6::zeros());
    }

    /// Sets `self` to `(a − b) · scale`, entry by entry (a difference quotient of two
    /// deformations), without reallocating.
    pub fn set_difference(&mut self, a: &Perturbation, b: &Perturbation, scale: f64) {
        for (o, (x, y)) in self
            .joint_twist
            .iter_mut()
            .zip(a.joint_twist.iter().zip(&b.joint_twist))
        {
            *o = (x - y) * scale;
        }
        for (o, (x, y)) in self
            .joint_offset
            .iter_mut()
            .zip(a.joint_offset.iter().zip(&b.joint_offset))
        {
            *o = (x - y) * scale;
        }
        for (o, (x, y)) in self
            .point_twist
            .iter_mut()
            .zip(a.point_twist.iter().zip(&b.point_twist))
        {
            *o = (x - y) * scale;
        }
    }

    /// True when every entry is exactly zero.
    pub fn is_zero(&self) -> bool {
        self.joint_twist.iter().all(|t| t.iter().all(|v| *v == 0.0))
            && self.joint_offset.iter().all(|v| *v == 0.0)
            && self.point_twist.iter().all(|t| t.iter().all(|v| *v == 0.0))
    }
}
