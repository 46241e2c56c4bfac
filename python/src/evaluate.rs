//! `evaluate`: position errors of a model on measurements, as `armcomp evaluate` reports them.

use numpy::PyArray2;
use pyo3::prelude::*;

use crate::errors::IntoPy;
use crate::measurements::PyMeasurements;
use crate::robot::PyRobot;

/// Errors of `model` (with its fitted predictor) on `data`: the report as JSON text (what
/// `armcomp evaluate --json` prints) and the measured-minus-modelled positions (n × 3, m).
#[pyfunction]
pub fn evaluate<'py>(
    py: Python<'py>,
    model: PyRef<'_, PyRobot>,
    data: PyRef<'_, PyMeasurements>,
) -> PyResult<(String, Bound<'py, PyArray2<f64>>)> {
    let robot = model.robot.clone();
    let set = data.resolve(&robot)?;
    let report = crate::interrupt::run(py, |_| armcomp_api::ops::evaluate::run(&robot, &set.samples))?.py()?;
    let json = serde_json::to_string(&report.to_json()).expect("JSON values print");
    Ok((json, crate::arrays::points(py, &report.errors)))
}
