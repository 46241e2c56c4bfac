//! `calibrate`: identification from measurements, as `armcomp calibrate` does it.

use armcomp_api::ops::calibrate::Prior;
use std::path::PathBuf;

use armcomp_core::calibrate::{CalibrationParams, Loss};
use armcomp_core::data::measurement::MeasurementSet;
use pyo3::prelude::*;

use crate::arrays::Covariance;

use crate::errors::{IntoPy, input_error};
use crate::robot::PyRobot;

/// `prior`: a positive factor, `"evidence"`, `"auto"` or `"none"`.
fn prior(value: &Bound<'_, PyAny>) -> PyResult<Prior> {
    let text = match value.extract::<f64>() {
        Ok(v) => v.to_string(),
        Err(_) => value.extract::<String>()?,
    };
    text.parse()
        .map_err(|m: String| input_error(&format!("prior: {m}"), None, None, Some("prior")))
}

/// Identifies a model of `robot` from `data` (one `Measurements` or a list, one station
/// each); returns the model, the report as JSON text (what `armcomp calibrate --json`
/// prints), whether the fit ended far above the declared noise, the free parameters'
/// covariance `(names, matrix)` (SI units) and the report page's data when `report` names a
/// folder to write it to. Without `noise_mm` the noise is estimated from the data with the
/// fit. `noise_deg`: the orientation noise of poses and plane tilts (degrees). `progress`, when
/// given, is called as `progress("prior scale", done, total)` after every fit of the prior's
/// cross-validation (`prior = "auto"`). `loss`: `"squared"` (least squares) or `"huber"`
/// (squared up to 3 robust noises, linear beyond: gross errors pull the fit little).
/// `exclude_outliers`: fit again without the rows of gross errors, as `--exclude-outliers`.
/// `groups` (a label per data row) or `group_by` (a CSV column) fold `prior = "auto"`'s
/// cross-validation by whole groups, as `--group-by`; by default a set-up column of the CSV.
#[pyfunction]
#[pyo3(signature = (robot, data, identify = None, noise_mm = None, prior = None, max_iterations = 100, restarts = 2, seed = 0, progress = None, loss = "squared", noise_deg = None, exclude_outliers = false, report = None, groups = None, group_by = None))]
#[allow(clippy::too_many_arguments)]
pub fn calibrate<'py>(
    py: Python<'py>,
    robot: PyRef<'_, PyRobot>,
    data: &Bound<'py, PyAny>,
    identify: Option<Vec<String>>,
    noise_mm: Option<f64>,
    prior: Option<&Bound<'_, PyAny>>,
    max_iterations: usize,
    restarts: usize,
    seed: u64,
    progress: Option<Py<PyAny>>,
    loss: &str,
    noise_deg: Option<f64>,
    exclude_outliers: bool,
    report: Option<PathBuf>,
    groups: Option<Vec<String>>,
    group_by: Option<&str>,
) -> PyResult<Calibrated<'py>> {
    let loss = match loss {
        "squared" => Loss::Squared,
        "huber" => Loss::Huber,
        other => {
            return Err(input_error(
                &format!("unknown loss `{other}`; expected \"squared\" or \"huber\""),
                None,
                None,
                Some("loss"),
            ));
        }
    };
    let prior = match prior {
        Some(p) => self::prior(p)?,
        None => Prior::Scale(1.0),
    };
    armcomp_api::ops::calibrate::check_noises(noise_mm, noise_deg).py()?;
    if (groups.is_some() || group_by.is_some()) && prior != Prior::Auto {
        return Err(input_error(
            "groups and group_by fold the cross-validation of prior=\"auto\"; without it nothing is cross-validated",
            None,
            None,
            Some("group_by"),
        ));
    }
    crate::report::check(report.as_deref(), &robot.robot, data)?;
    let mut set = crate::measurements::resolve_stations(&robot.robot, data)?;
    let adopted = armcomp_api::with_stations(&robot.robot, &set).py()?;
    let robot = adopted.as_ref().unwrap_or(&robot.robot);
    let params = CalibrationParams {
        identify: identify.unwrap_or_default(),
        measurement_std: noise_mm.unwrap_or(0.1) * 1e-3,
        orientation_std: noise_deg.unwrap_or(0.1).to_radians(),
        max_iterations,
        restarts,
        seed,
        loss,
        ..CalibrationParams::default()
    };
    let noise_declared = noise_mm.is_some() && (noise_deg.is_some() || !robot.measures_pose());
    let calibrate_on = |set: &MeasurementSet| {
        let choices = armcomp_api::ops::calibrate::Choices {
            prior,
            noise_declared,
            fold_groups: match prior {
                Prior::Auto => crate::measurements::fold_groups(data, set, groups.clone(), group_by)?,
                _ => None,
            },
        };
        let samples = &set.samples;
        crate::interrupt::run(py, |cancel| {
            armcomp_api::ops::calibrate::run(
                robot,
                samples,
                CalibrationParams {
                    cancel: cancel.clone(),
                    ..params.clone()
                },
                choices,
                &|p| crate::progress::report(progress.as_ref(), "prior scale", p.done, p.total),
                &mut |_| {},
            )
        })?
        .py()
    };
    let mut run = calibrate_on(&set)?;
    let outliers = run.outlier_rows(&set.rows);
    if exclude_outliers && !outliers.is_empty() {
        (set.samples, set.rows) = armcomp_api::ops::calibrate::without_rows(&set.samples, &set.rows, &outliers);
        run = calibrate_on(&set)?;
    }
    let page = crate::report::write(report.as_deref(), || {
        armcomp_api::model_report::for_calibrate(robot, &set.samples, &set.rows, &run)
    })?;
    let json = serde_json::to_string(&run.to_json(&set.rows)).expect("JSON values print");
    let far = run.calibration.report.far_above_noise();
    let covariance = crate::arrays::covariance(py, &run.calibration.report.covariance);
    Ok((PyRobot::wrap(run.calibration.robot), json, far, covariance, page))
}

/// What `calibrate` returns to the Python layer.
type Calibrated<'py> = (PyRobot, String, bool, Covariance<'py>, Option<String>);
