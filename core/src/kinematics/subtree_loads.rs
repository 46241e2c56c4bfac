//! The mass and first mass moment of every subtree of a tree in one configuration: what
//! gravity loads are computed from (see `gravity.rs`).

use nalgebra::Vector3;

use crate::kinematics::workspace::TreeWorkspace;
use crate::model::mass::MassModel;
use crate::model::tree::KinematicTree;

/// The mass (kg) and first mass moment `Σ m·c` (kg m, world) of every body's subtree, payload
/// included, for one configuration. One backward pass over the tree fills it; the gravity
/// wrench of any subtree about any point is then a few operations, where summing the subtree's
/// bodies per query made a model's loads quadratic in the number of bodies.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SubtreeLoads {
    mass: Vec<f64>,
    first_moment: Vec<Vector3<f64>>,
}

impl SubtreeLoads {
    /// The loads of `tree` at the frames `frames` (body poses) with `mass` (allocating; see
    /// [`update`](Self::update) to reuse buffers).
    pub fn of(tree: &KinematicTree, frames: &TreeWorkspace, mass: &MassModel) -> Self {
        let mut loads = SubtreeLoads::default();
        loads.update(tree, frames, mass);
        loads
    }

    /// Recomputes the loads in place; allocates only on the first call for a tree.
    pub fn update(&mut self, tree: &KinematicTree, frames: &TreeWorkspace, mass: &MassModel) {
        let n = tree.bodies().len();
        self.mass.clear();
        self.mass.resize(n, 0.0);
        self.first_moment.clear();
        self.first_moment.resize(n, Vector3::zeros());
        for (k, b) in mass.bodies.iter().enumerate().take(n) {
            if b.mass != 0.0 {
                self.mass[k] = b.mass;
                self.first_moment[k] = frames.body[k].transform_point(&b.com.into()).coords * b.mass;
            }
        }
        if let Some(p) = &mass.payload
            && p.mass != 0.0
            && p.body < n
        {
            self.mass[p.body] += p.mass;
            self.first_moment[p.body] += frames.body[p.body].transform_point(&p.com.into()).coords * p.mass;
        }
        // Body k > 0 hangs from joint k − 1, whose parent body comes before it.
        for k in (1..n).rev() {
            let parent = tree.joints()[k - 1].parent;
            self.mass[parent] += self.mass[k];
            let m = self.first_moment[k];
            self.first_moment[parent] += m;
        }
    }

    /// Mass (kg) of the subtree rooted at body `c`, payload included.
    pub fn mass(&self, c: usize) -> f64 {
        self.mass[c]
    }

    /// Gravity force (N, world) and its moment (N m, world) about `about` of the subtree rooted
    /// at body `c` under `gravity` (m/s², world): `M g` and `(Σ m·c − M·about) × g`.
    #[inline]
    pub fn wrench(&self, c: usize, gravity: &Vector3<f64>, about: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        let m = self.mass[c];
        (gravity * m, (self.first_moment[c] - about * m).cross(gravity))
    }
}
