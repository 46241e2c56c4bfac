//! `evaluate`: position errors of a model on measurements, as `armcomp evaluate` reports them.

use std::path::PathBuf;

use numpy::PyArray2;
use pyo3::prelude::*;

use crate::errors::IntoPy;
use crate::robot::PyRobot;

/// Errors of `model` (with its fitted predictor) on `data` (one `Measurements` or a list, one
/// station each): the report as JSON text (what `armcomp evaluate --json` prints), the
/// measured-minus-modelled positions (n × 3, m) and the report page's data when `report` names
/// a folder to write it to. `register`: register every station's frame on these data first, as
/// `--register` does (stations the model does not know always are).
#[pyfunction]
#[pyo3(signature = (model, data, register = false, report = None))]
pub fn evaluate<'py>(
    py: Python<'py>,
    model: PyRef<'_, PyRobot>,
    data: &Bound<'py, PyAny>,
    register: bool,
    report: Option<PathBuf>,
) -> PyResult<(String, Bound<'py, PyArray2<f64>>, Option<String>)> {
    crate::report::check(report.as_deref(), &model.robot, data)?;
    let (set, adopted, new) = crate::measurements::resolve_stations(&model.robot, data)?;
    // A copy of the model only when its frames change.
    let mut owned = match adopted {
        Some(r) => Some(r),
        None if register => Some(model.robot.rebuild(model.robot.to_file()).py()?),
        None => None,
    };
    let stations: Vec<usize> = match &owned {
        Some(r) if register => (0..r.n_stations()).collect(),
        _ => new,
    };
    let given = model.robot.clone();
    let evaluation = crate::interrupt::run(py, |_| match owned.as_mut() {
        Some(r) => armcomp_api::ops::evaluate::run_registered(r, &set.samples, &stations),
        None => armcomp_api::ops::evaluate::run(&given, &set.samples),
    })?
    .py()?;
    let robot = owned.as_ref().unwrap_or(&given);
    let page = crate::report::write(report.as_deref(), || {
        armcomp_api::model_report::for_evaluate(robot, &set.samples, &set.rows, &evaluation)
    })?;
    let json = serde_json::to_string(&evaluation.to_json()).expect("JSON values print");
    Ok((json, crate::arrays::points(py, &evaluation.errors), page))
}
