//! Integration tests of whole workflows through the library and the CLI (one test binary).

mod cli;
mod common;
mod conventions;
mod fk;
mod jacobian;
mod malformed;
mod measurement;
mod robot_files;
mod runtime_plugins;
mod simulate;
