//! `armcomp validate`, `armcomp schema`, `armcomp plugins`, `armcomp check-pose` and `--allow-plugins` from Python.

use std::path::PathBuf;

use armcomp_core::CollisionModel;
use pyo3::prelude::*;

use crate::robot::PyRobot;

/// Checks a robot file as `armcomp validate` does (syntax and types, semantics, the JSON
/// Schema): its problems as `armcomp validate --json` prints them (JSON text).
#[pyfunction]
pub fn validate(py: Python<'_>, path: PathBuf) -> String {
    let schema = armcomp_api::robot_schema();
    let found = py.detach(|| armcomp_api::validate_file(&path, &schema, crate::input_limits()));
    serde_json::to_string(&found).expect("diagnostics serialise")
}

/// The JSON Schema of robot files as `armcomp schema` prints it (JSON text), for editors and
/// checkers.
#[pyfunction]
pub fn schema() -> String {
    armcomp_api::schema_text()
}

/// The built-in plugins and those of libraries loaded so far, as `armcomp plugins --json`
/// lists them (JSON text).
#[pyfunction]
pub fn plugins() -> String {
    armcomp_api::registry::plugins_json().to_string()
}

/// Collisions at configuration `q` as `armcomp check-pose --json` lists its `contacts` (JSON
/// text).
#[pyfunction]
pub fn check_pose(py: Python<'_>, robot: &PyRobot, q: &Bound<'_, PyAny>) -> PyResult<String> {
    let q = robot.configuration(q)?;
    let model = CollisionModel::new(robot.robot.tree(), robot.robot.collision());
    let mut ws = model.workspace();
    let contacts = py.detach(|| model.check(&q, &mut ws));
    Ok(serde_json::to_string(&contacts).expect("contacts serialise"))
}

/// Lets robot files load the run-time plugin libraries they name inside their own folder, and
/// `diagnose(library=...)` the libraries it names, for the rest of the process (or stops it
/// with `allow=False`), as `--allow-plugins` does for one command. Loading a library runs its
/// code: allow it only for files you trust. Libraries in the user config's `plugin_dirs`
/// load without it.
#[pyfunction]
#[pyo3(signature = (allow = true))]
pub fn allow_plugins(allow: bool) -> PyResult<()> {
    armcomp_api::config::apply(allow)
        .map(|_| ())
        .map_err(|e| crate::errors::core_error(&e, None))
}
