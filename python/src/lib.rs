//! The native part of the `armcomp` Python package (`armcomp._armcomp`): robots, measurements
//! and the operations of the command line, with numpy arrays in and out. The Python layer
//! (`pysrc/armcomp`) turns the JSON reports into dataclasses and raises `NotConverged`.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

mod arrays;
mod calibrate;
mod compensate;
mod diagnose;
mod errors;
mod evaluate;
mod fit;
mod frames;
mod interrupt;
mod learn;
mod measurements;
mod plan;
mod progress;
mod report;
mod robot;
mod simulate;
mod validate;

use std::sync::OnceLock;

use armcomp_core::support::io::InputLimits;
use pyo3::prelude::*;

/// The user config's input limits, read when the module is imported.
static LIMITS: OnceLock<InputLimits> = OnceLock::new();

/// The limits every file this module reads is held to.
fn input_limits() -> InputLimits {
    LIMITS.get().copied().unwrap_or_default()
}

#[pymodule]
fn _armcomp(m: &Bound<'_, PyModule>) -> PyResult<()> {
    // The user config applies as for the command line; run-time plugin libraries load only
    // from the folders it trusts.
    let limits = armcomp_api::config::apply(false).map_err(|e| errors::core_error(&e, None))?;
    let _ = LIMITS.set(limits);
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    m.add_class::<robot::PyRobot>()?;
    m.add_class::<measurements::PyMeasurements>()?;
    m.add_function(wrap_pyfunction!(calibrate::calibrate, m)?)?;
    m.add_function(wrap_pyfunction!(evaluate::evaluate, m)?)?;
    m.add_function(wrap_pyfunction!(fit::fit, m)?)?;
    m.add_function(wrap_pyfunction!(simulate::simulate, m)?)?;
    m.add_function(wrap_pyfunction!(diagnose::diagnose, m)?)?;
    m.add_function(wrap_pyfunction!(learn::learn, m)?)?;
    m.add_function(wrap_pyfunction!(compensate::compensate, m)?)?;
    m.add_function(wrap_pyfunction!(plan::plan, m)?)?;
    m.add_function(wrap_pyfunction!(validate::validate, m)?)?;
    m.add_function(wrap_pyfunction!(validate::check_pose, m)?)?;
    m.add_function(wrap_pyfunction!(validate::schema, m)?)?;
    m.add_function(wrap_pyfunction!(validate::plugins, m)?)?;
    m.add_function(wrap_pyfunction!(validate::allow_plugins, m)?)?;
    Ok(())
}
