//! Integration tests of whole workflows through the library and the CLI (one test binary).

mod agile_justin;
mod architecture;
mod bad_inputs;
mod calibrate;
mod cli;
mod collision;
mod common;
mod compensate;
mod conventions;
mod demo;
mod demo_report;
mod diagnose;
mod docs;
mod fk;
mod jacobian;
mod learning_curve;
mod malformed;
mod measurement;
mod mutated_inputs;
mod plan;
mod robot_files;
mod runtime_plugins;
mod simulate;
mod talos;
mod urdf;
mod urdf_corpus;
