//! The model of a robot, without evaluating it: rigid transforms, units, the kinematic tree,
//! parameters, masses, shapes, small deformations, and joint-space sampling.

pub mod geom;
pub mod mass;
pub mod param;
pub mod perturbation;
pub mod sampling;
pub mod shape;
pub mod tree;
pub mod units;
