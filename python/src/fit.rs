//! `fit`: the model ladder, as `armcomp fit` climbs it.

use std::path::PathBuf;

use pyo3::prelude::*;

use crate::arrays::Covariance;

use crate::errors::IntoPy;
use crate::robot::PyRobot;

/// Chooses the model of `robot` from `data` (one `Measurements` or a list, one station each)
/// by repeated cross-validation (`folds` drawn `repeats` times) and fits it on all of `data`;
/// returns the model, the report as JSON text (what `armcomp fit --json` prints), the chosen
/// fit's parameter covariance and the report page's data when `report` names a folder to
/// write it to.
/// `groups`: one label per data row, or `group_by` a column of the CSV (`COLUMN:N`: blocks of
/// a numeric one), and folds hold out whole groups; without either, a set-up column of the
/// CSV (`session`, ...) as the command line. `progress`, when given,
/// is called as `progress("model choice", done, total)` after every fit.
#[pyfunction]
#[pyo3(signature = (robot, data, noise_mm = None, folds = 5, seed = 0, groups = None, predictor = Some("gp"), progress = None, noise_deg = None, repeats = None, report = None, group_by = None))]
#[allow(clippy::too_many_arguments)]
pub fn fit<'py>(
    py: Python<'py>,
    robot: PyRef<'_, PyRobot>,
    data: &Bound<'py, PyAny>,
    noise_mm: Option<f64>,
    folds: usize,
    seed: u64,
    groups: Option<Vec<String>>,
    predictor: Option<&str>,
    progress: Option<Py<PyAny>>,
    noise_deg: Option<f64>,
    repeats: Option<usize>,
    report: Option<PathBuf>,
    group_by: Option<&str>,
) -> PyResult<(PyRobot, String, Covariance<'py>, Option<String>)> {
    crate::report::check(report.as_deref(), &robot.robot, data)?;
    let set = crate::measurements::resolve_stations(&robot.robot, data)?;
    let adopted = armcomp_api::with_stations(&robot.robot, &set).py()?;
    let robot = adopted.map_or_else(|| robot.robot.clone(), std::sync::Arc::new);
    let fold_groups = crate::measurements::fold_groups(data, &set, groups, group_by)?.map(|(_, g)| g);
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
    let page = crate::report::write(report.as_deref(), || {
        armcomp_api::model_report::for_fit(&robot, &set.samples, &set.rows, &ladder)
    })?;
    let json = serde_json::to_string(&armcomp_api::ops::fit::to_json(&ladder)).expect("JSON values print");
    let covariance = crate::arrays::covariance(py, &ladder.calibration.report.covariance);
    Ok((PyRobot::wrap(ladder.robot), json, covariance, page))
}
