//! Evaluating the model: forward kinematics and Jacobians of the tree into a reusable workspace,
//! the compiled point kinematics (one configuration or many at once), sensor readings,
//! collision checks and the gravity loads of subtrees.

pub mod collision;
mod frame;
mod lanes;
pub mod point_kinematics;
pub mod point_kinematics_many;
pub mod sensor;
mod sincos;
pub mod subtree_loads;
pub mod workspace;
