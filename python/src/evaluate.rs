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
/// `--register` does (stations the model does not know always are). `register_on`: register
/// them on these rows only (a station's stationing points) and evaluate on the others, as
/// `--register-on` does.
#[pyfunction]
#[pyo3(signature = (model, data, register = false, register_on = None, report = None))]
pub fn evaluate<'py>(
    py: Python<'py>,
    model: PyRef<'_, PyRobot>,
    data: &Bound<'py, PyAny>,
    register: bool,
    register_on: Option<&Bound<'py, PyAny>>,
    report: Option<PathBuf>,
) -> PyResult<(String, Bound<'py, PyArray2<f64>>, Option<String>)> {
    crate::report::check(report.as_deref(), &model.robot, data)?;
    let mut set = crate::measurements::resolve_stations(&model.robot, data)?;
    let on = register_on
        .map(|r| crate::measurements::row_selection(r, "register_on"))
        .transpose()?;
    if register && on.is_some() {
        return Err(crate::errors::input_error(
            "register_on registers the stations on those rows: give it without register",
            None,
            None,
            Some("register_on"),
        ));
    }
    // As the command line: the model takes the data's stations, a copy with its fitted
    // predictor, only when its frames may change.
    let mut owned = None;
    let mut stations = Vec::new();
    if register || on.is_some() || !set.stations.is_empty() {
        let mut copy = crate::robot::copy_of(&model.robot).py()?;
        let new = copy.adopt_stations(&set.stations);
        stations = if register {
            (0..copy.n_stations()).collect()
        } else {
            new
        };
        owned = Some(copy);
    }
    let given = model.robot.clone();
    let evaluation = crate::interrupt::run(py, |_| match (owned.as_mut(), &on) {
        (Some(r), Some(on)) => armcomp_api::ops::evaluate::register_on_then_run(r, &set, on, None).map(|(rows, e)| {
            set = rows;
            e
        }),
        (Some(r), None) => armcomp_api::ops::evaluate::run_registered(r, &set.samples, &stations),
        (None, _) => armcomp_api::ops::evaluate::run(&given, &set.samples),
    })?
    .py()?;
    let robot = owned.as_ref().unwrap_or(&given);
    let page = crate::report::write(report.as_deref(), || {
        armcomp_api::model_report::for_evaluate(robot, &set.samples, &set.rows, &evaluation)
    })?;
    let json = serde_json::to_string(&evaluation.to_json()).expect("JSON values print");
    Ok((json, crate::arrays::points(py, &evaluation.errors), page))
}
