//! armcomp: the library behind the `armcomp` command. It gathers the built-in plugins into one
//! registry, composes the robot-file JSON Schema from their specs, and checks robot files
//! (schema first, then semantics), reporting every problem with file, line and field.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod config;
pub mod diagnosis_report;
pub mod load;
pub mod ops;
pub mod registry;
pub mod validate;

pub use load::{load_robot, read_robot};
pub use registry::{plugins, robot_schema, schema_text};
pub use validate::{Diagnostic, Validation, check_file, validate_file};
