//! One module per subcommand.

pub mod check_pose;
pub mod demo;
pub mod export_urdf;
pub mod fk;
pub mod plugins;
pub mod schema;
pub mod simulate;
pub mod validate;
