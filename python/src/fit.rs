//! `fit`: the model ladder, as `armcomp fit` climbs it.

use pyo3::prelude::*;

use crate::errors::{IntoPy, input_error};
use crate::measurements::PyMeasurements;
use crate::robot::PyRobot;

/// Chooses the model of `robot` from `data` by repeated cross-validation (`folds` drawn
/// `repeats` times) and fits it on all of `data`; returns the model and the report as JSON text (what `armcomp fit --json` prints).
/// `groups`: one label per data row; folds then hold out whole groups. `progress`, when given,
/// is called as `progress("model choice", done, total)` after every fit.
#[pyfunction]
#[pyo3(signature = (robot, data, noise_mm = None, folds = 5, seed = 0, groups = None, predictor = Some("gp"), progress = None, noise_deg = None, repeats = None))]
#[allow(clippy::too_many_arguments)]
pub fn fit(
    py: Python<'_>,
    robot: PyRef<'_, PyRobot>,
    data: PyRef<'_, PyMeasurements>,
    noise_mm: Option<f64>,
    folds: usize,
    seed: u64,
    groups: Option<Vec<String>>,
    predictor: Option<&str>,
    progress: Option<Py<PyAny>>,
    noise_deg: Option<f64>,
    repeats: Option<usize>,
) -> PyResult<(PyRobot, String)> {
    let robot = robot.robot.clone();
    let set = data.resolve(&robot)?;
    let fold_groups = match groups {
        Some(labels) => {
            let rows = set.rows.iter().max().map_or(0, |r| r + 1);
            if labels.len() < rows {
                return Err(input_error(
                    &format!("groups: one label per data row expected ({rows}), got {}", labels.len()),
                    None,
                    None,
                    Some("groups"),
                ));
            }
            Some(armcomp_api::ops::fit::groups_of(&labels, &set.rows))
        }
        None => None,
    };
    let predictor = predictor.filter(|p| *p != "none").map(str::to_string);
    let ladder = crate::interrupt::run(py, |cancel| {
        let params = armcomp_api::ops::fit::FitParams {
            noise_mm,
            noise_deg,
            folds,
            repeats,
            seed,
            fold_groups,
            predictor,
            cancel: cancel.clone(),
        };
        armcomp_api::ops::fit::run(&robot, &set, params, &|p| {
            crate::progress::report(progress.as_ref(), "model choice", p.done, p.total)
        })
    })?
    .py()?;
    let json = serde_json::to_string(&armcomp_api::ops::fit::to_json(&ladder)).expect("JSON values print");
    Ok((PyRobot::wrap(ladder.robot), json))
}
