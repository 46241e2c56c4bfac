//! `armcomp validate`, `armcomp schema` and `armcomp check-pose` from Python.

use std::path::PathBuf;

use armcomp_core::CollisionModel;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::robot::PyRobot;

/// Checks a robot file as `armcomp validate` does (syntax and types, semantics, the JSON
/// Schema): its problems as dicts (`file`, `line` or None, the field `path`, `message`), as
/// `armcomp validate --json` prints them; an empty list when the file is valid.
#[pyfunction]
pub fn validate(py: Python<'_>, path: PathBuf) -> PyResult<Vec<Bound<'_, PyDict>>> {
    let schema = armcomp::robot_schema();
    let found = py.detach(|| armcomp::validate_file(&path, &schema));
    found
        .into_iter()
        .map(|d| {
            let out = PyDict::new(py);
            out.set_item("file", d.file.display().to_string())?;
            out.set_item("line", d.line)?;
            out.set_item("path", d.path)?;
            out.set_item("message", d.message)?;
            Ok(out)
        })
        .collect()
}

/// The JSON Schema of robot files as `armcomp schema` prints it (JSON text), for editors and
/// checkers.
#[pyfunction]
pub fn schema() -> String {
    armcomp::schema_text()
}

/// Collisions at configuration `q` as `armcomp check-pose` finds them: one dict per pair in
/// contact or within its margin (`first`, `second`, `fixture`, `distance` in m, negative for
/// an overlap, and the closest points `point_first`, `point_second`, m, base frame).
#[pyfunction]
pub fn check_pose<'py>(py: Python<'py>, robot: &PyRobot, q: &Bound<'py, PyAny>) -> PyResult<Vec<Bound<'py, PyDict>>> {
    let q = robot.configuration(q)?;
    let model = CollisionModel::new(robot.robot.tree(), robot.robot.collision());
    let mut ws = model.workspace();
    let contacts = py.detach(|| model.check(&q, &mut ws));
    contacts
        .iter()
        .map(|c| {
            let d = PyDict::new(py);
            d.set_item("first", &c.first)?;
            d.set_item("second", &c.second)?;
            d.set_item("fixture", c.fixture)?;
            d.set_item("distance", c.distance)?;
            d.set_item("point_first", [c.point_first.x, c.point_first.y, c.point_first.z])?;
            d.set_item("point_second", [c.point_second.x, c.point_second.y, c.point_second.z])?;
            Ok(d)
        })
        .collect()
}
