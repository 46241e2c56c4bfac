//! `report=DIR` of `calibrate`, `evaluate` and `fit`: the page `--report DIR` writes.

use std::path::{Path, PathBuf};

use armcomp_api::model_report::ModelReport;
use armcomp_core::Robot;
use pyo3::prelude::*;

use crate::errors::IntoPy;

/// Refuses a report folder that would replace an input (`robot`'s files or `data`'s), before
/// any work.
pub fn check(dir: Option<&Path>, robot: &Robot, data: &Bound<'_, PyAny>) -> PyResult<()> {
    let Some(dir) = dir else { return Ok(()) };
    let mut inputs: Vec<PathBuf> = robot.inputs();
    inputs.extend(crate::measurements::files(data));
    armcomp_api::model_report::check(dir, &inputs).py()
}

/// Writes the page `build` makes into `dir`, when one is given, and returns its data
/// (`report.json`'s text).
pub fn write(
    dir: Option<&Path>,
    build: impl FnOnce() -> armcomp_core::Result<ModelReport>,
) -> PyResult<Option<String>> {
    let Some(dir) = dir else { return Ok(None) };
    let page = build().py()?;
    armcomp_api::model_report::write(dir, &page).py()?;
    Ok(Some(
        serde_json::to_string(&page).expect("plain numbers, strings and lists serialise"),
    ))
}
