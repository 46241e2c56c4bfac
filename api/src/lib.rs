//! armcomp-api: the library behind the `armcomp` command and the Python package. It runs the
//! operations of the subcommands ([`ops`]), gathers the built-in plugins into one registry,
//! composes the robot-file JSON Schema from their specs, and checks robot files (schema first,
//! then semantics), reporting every problem with file, line and field. It returns values and
//! typed [`Error`]s; printing is the callers'.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

pub mod config;
pub mod diagnosis_report;
pub mod error;
pub mod load;
pub mod model_report;
pub mod ops;
pub mod registry;
pub mod validate;

pub use error::{Error, LockReason, Result};
pub use load::{read_robot, with_stations};
pub use registry::{plugins, robot_schema, schema_text};
pub use validate::{Diagnostic, Validation, check_file, validate_file};
