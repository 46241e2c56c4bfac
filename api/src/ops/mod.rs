//! The computations behind the subcommands, shared by the command line and the Python
//! package so that both give the same numbers and write the same bytes. They return values;
//! printing, progress bars and exit codes stay with the callers.

pub mod calibrate;
pub mod compensate;
pub mod diagnose;
pub mod evaluate;
pub mod export_ros;
pub mod export_urdf;
pub mod fit;
pub mod learn;
pub mod plan;
pub mod simulate;
