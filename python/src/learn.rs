//! `learn`: fits a model's residual predictor, as `armcomp learn` does.

use armcomp_core::{FitControl, RobotFile, TrainingProgress};
use pyo3::prelude::*;

use crate::errors::IntoPy;
use crate::measurements::PyMeasurements;
use crate::robot::PyRobot;

/// Fits `predictor` (a type with its default settings), or the predictor `model`'s
/// `[predictor]` table describes, on `data`; returns the model with the fitted predictor and
/// `(seconds, before, after)` with the training errors of the model alone and with the
/// predictor as JSON text. `groups`: one label per data row, or `group_by` a column of the CSV
/// (`COLUMN:N`: blocks of a numeric one); the cross-validation then holds out whole groups, as
/// `--group-by` does.
#[pyfunction]
#[pyo3(signature = (model, data, predictor = None, progress = None, groups = None, group_by = None))]
pub fn learn(
    py: Python<'_>,
    model: PyRef<'_, PyRobot>,
    data: Bound<'_, PyMeasurements>,
    predictor: Option<&str>,
    progress: Option<Py<PyAny>>,
    groups: Option<Vec<String>>,
    group_by: Option<&str>,
) -> PyResult<(PyRobot, String)> {
    let predictor = predictor
        .map(armcomp_api::ops::learn::default_predictor)
        .transpose()
        .map_err(|e| crate::errors::input_error(&e.to_string(), None, None, Some("predictor")))?;
    let robot = model.robot.clone();
    let set = data.get().resolve(&robot)?;
    let fold_groups = crate::measurements::fold_groups(data.as_any(), &set, groups, group_by)?;
    // The model's own description, every field kept (the command line re-reads its file).
    let value = serde_json::to_value(robot.built_from()).expect("a robot file serialises");
    let file: RobotFile = serde_json::from_value(value)
        .map_err(|e| armcomp_core::Error::InvalidArgument {
            what: "model".into(),
            reason: format!("its description does not read back: {e}"),
        })
        .py()?;
    let run = crate::interrupt::run(py, |cancel| {
        let report = |p: TrainingProgress| crate::progress::report(progress.as_ref(), p.stage, p.done, p.total);
        let control = FitControl {
            progress: Some(&report),
            cancel: cancel.clone(),
        };
        armcomp_api::ops::learn::run(&robot, file, &set.samples, predictor, fold_groups.clone(), &control)
    })?
    .py()?;
    let json = serde_json::json!({
        "seconds": run.seconds,
        "before": run.before,
        "after": run.after,
        "cross_validated": run.cross_validated.as_ref().map(|(stats, _)| stats),
        "cross_validation": run.cross_validated.as_ref().map(|(_, folding)| folding),
        "refitted": run.refitted,
        "warnings": run.warnings(),
    });
    Ok((PyRobot::wrap(run.robot), json.to_string()))
}
