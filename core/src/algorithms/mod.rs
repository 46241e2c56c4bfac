//! What is done with a built robot: accuracy on measurements, inverse kinematics,
//! compensation, measurement planning, simulation, and where residuals live.

pub mod compensate;
pub mod evaluate;
pub mod ik;
pub mod plan;
pub mod residuals;
pub mod simulate;
