//! `diagnose`: finds the effects a model misses, as `armcomp diagnose` does.

use armcomp_api::ops::diagnose::LearnableBy;
use armcomp_core::analysis::diagnose::{DiagnoseParams, DiagnoseStage};
use armcomp_core::calibrate::CalibrationParams;
use pyo3::prelude::*;

use crate::errors::{IntoPy, input_error};
use crate::measurements::PyMeasurements;
use crate::robot::PyRobot;

/// Diagnoses `robot` on `data`; returns the improved model (found effects added, calibrated
/// on all the data; the model as given when none is, its predictor kept or fitted again) and
/// the report as JSON text (what `armcomp diagnose --json` prints). Without `noise_mm` the
/// noise is the model's fit record's, else estimated for the model as given.
/// `progress`, when given, is called as `progress(stage, done, total)` after every fold
/// calibration (`stage`: "model as given", "effect N", "learnable residual"). When the final
/// model leaves rows far beyond the noise, the search is made again without them
/// (`keep_outliers=True` keeps them); the report lists them (`gross_errors`) either way.
/// `groups`: one label per data row, or `group_by` a CSV column (`COLUMN:N`: blocks), so that
/// folds hold out whole groups (`--group-by`; default a set-up column of the CSV);
/// `exhaustive`: refit every candidate on the folds (`--exhaustive`); `report`: a folder for
/// the diagnosis page (`--report`); `library`: run-time plugin libraries whose error models
/// join the candidates (`--library`), loaded only after `armcomp.allow_plugins()`.
#[pyfunction]
#[pyo3(signature = (robot, data, seed = 0, folds = 3, max_steps = 5, min_reduction_percent = 5.0, noise_mm = None, identify = None, predictor = "gp", progress = None, keep_outliers = false, groups = None, exhaustive = false, report = None, group_by = None, library = None))]
#[allow(clippy::too_many_arguments)]
pub fn diagnose(
    py: Python<'_>,
    robot: PyRef<'_, PyRobot>,
    data: Bound<'_, PyMeasurements>,
    seed: u64,
    folds: usize,
    max_steps: usize,
    min_reduction_percent: f64,
    noise_mm: Option<f64>,
    identify: Option<Vec<String>>,
    predictor: Option<&str>,
    progress: Option<Py<PyAny>>,
    keep_outliers: bool,
    groups: Option<Vec<String>>,
    exhaustive: bool,
    report: Option<std::path::PathBuf>,
    group_by: Option<&str>,
    library: Option<Vec<std::path::PathBuf>>,
) -> PyResult<(PyRobot, String)> {
    // A library runs its code: it loads only when `allow_plugins()` allowed it (or from a
    // folder the user config trusts), as `--library` does with `--allow-plugins`.
    let libraries: Vec<std::path::PathBuf> = library.unwrap_or_default();
    for lib in &libraries {
        armcomp_sdk::load_library(lib)
            .map_err(|e| input_error(&format!("library {}: {e}", lib.display()), None, None, Some("library")))?;
    }
    let learnable_by = match predictor {
        Some("gp") => LearnableBy::Gp,
        Some("ridge") => LearnableBy::Ridge,
        None | Some("none") => LearnableBy::None,
        Some(other) => {
            return Err(input_error(
                &format!("unknown predictor `{other}`; expected gp, ridge or None"),
                None,
                None,
                Some("predictor"),
            ));
        }
    };
    let robot = robot.robot.clone();
    if let Some(dir) = &report {
        let mut inputs = robot.inputs();
        inputs.extend(data.get().read_from.clone());
        inputs.extend(libraries.iter().map(|l| armcomp_sdk::host::platform_library_path(l)));
        armcomp_api::diagnosis_report::check(dir, &inputs).py()?;
    }
    let set = data.get().resolve(&robot)?;
    let fold_groups = crate::measurements::fold_groups(data.as_any(), &set, groups, group_by)?;
    let given = CalibrationParams {
        identify: identify.unwrap_or_default(),
        measurement_std: noise_mm.unwrap_or(0.1) * 1e-3,
        ..CalibrationParams::default()
    };
    let (calibration, _) = armcomp_api::ops::diagnose::calibration_for(&robot, &set, given, noise_mm.is_some()).py()?;
    let params = DiagnoseParams {
        folds,
        seed,
        calibration,
        min_rms_reduction: min_reduction_percent / 100.0,
        max_steps,
        exclude_gross_errors: !keep_outliers,
        exhaustive,
        fold_groups,
    };
    let diagnosis = crate::interrupt::run(py, |cancel| {
        let mut params = params.clone();
        params.calibration.cancel = cancel.clone();
        armcomp_api::ops::diagnose::run(&robot, &set, &params, learnable_by, &|p| {
            let stage = match p.stage {
                DiagnoseStage::Baseline => "model as given".to_string(),
                DiagnoseStage::Round(n) => format!("effect {n}"),
                DiagnoseStage::Learnable => "learnable residual".to_string(),
            };
            crate::progress::report(progress.as_ref(), &stage, p.done, p.total);
        })
    })?
    .py()?;
    if let Some(dir) = &report {
        armcomp_api::diagnosis_report::write(dir, &diagnosis.report).py()?;
    }
    let json = armcomp_api::ops::diagnose::to_json(&diagnosis.report, &set.rows).to_string();
    let control = armcomp_core::FitControl {
        progress: None,
        cancel: Default::default(),
    };
    let (model, _) = armcomp_api::ops::diagnose::output_model(&robot, &diagnosis, &set.samples, &control).py()?;
    Ok((
        model.map_or_else(|| PyRobot::shared(robot.clone()), PyRobot::wrap),
        json,
    ))
}
