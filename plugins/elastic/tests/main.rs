//! armcomp-elastic's tests against physics (one test binary): textbook cantilevers, an
//! independent integration of the beam equation, compliance, parameter Jacobians, and IK.

mod common;
mod deflection;
mod ik;
mod jacobians;
