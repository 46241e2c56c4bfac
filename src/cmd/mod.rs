//! One module per subcommand.

pub mod demo;
pub mod fk;
pub mod plugins;
pub mod schema;
pub mod simulate;
pub mod validate;
