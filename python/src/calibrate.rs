//! `calibrate`: identification from measurements, as `armcomp calibrate` does it.

use armcomp_api::ops::calibrate::Prior;
use armcomp_core::calibrate::{CalibrationParams, Loss};
use pyo3::prelude::*;

use crate::errors::{IntoPy, input_error};
use crate::measurements::PyMeasurements;
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

/// Identifies a model of `robot` from `data`; returns the model, the report as JSON text (what
/// `armcomp calibrate --json` prints) and whether the fit ended far above the declared noise.
/// Without `noise_mm` the noise is estimated from the data with the fit. `progress`, when
/// given, is called as `progress("prior scale", done, total)` after every fit of the prior's
/// cross-validation (`prior = "auto"`). `loss`: `"squared"` (least squares) or `"huber"`
/// (squared up to 3 robust noises, linear beyond: gross errors pull the fit little).
#[pyfunction]
#[pyo3(signature = (robot, data, identify = None, noise_mm = None, prior = None, max_iterations = 100, restarts = 2, seed = 0, progress = None, loss = "squared"))]
#[allow(clippy::too_many_arguments)]
pub fn calibrate(
    py: Python<'_>,
    robot: PyRef<'_, PyRobot>,
    data: PyRef<'_, PyMeasurements>,
    identify: Option<Vec<String>>,
    noise_mm: Option<f64>,
    prior: Option<&Bound<'_, PyAny>>,
    max_iterations: usize,
    restarts: usize,
    seed: u64,
    progress: Option<Py<PyAny>>,
    loss: &str,
) -> PyResult<(PyRobot, String, bool)> {
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
    let set = data.resolve(&robot.robot)?;
    let adopted = armcomp_api::with_stations(&robot.robot, &set).py()?;
    let robot = adopted.as_ref().unwrap_or(&robot.robot);
    let params = CalibrationParams {
        identify: identify.unwrap_or_default(),
        measurement_std: noise_mm.unwrap_or(0.1) * 1e-3,
        max_iterations,
        restarts,
        seed,
        loss,
        ..CalibrationParams::default()
    };
    let run = crate::interrupt::run(py, |cancel| {
        armcomp_api::ops::calibrate::run(
            robot,
            &set.samples,
            CalibrationParams {
                cancel: cancel.clone(),
                ..params
            },
            armcomp_api::ops::calibrate::Choices {
                prior,
                noise_declared: noise_mm.is_some(),
                fold_groups: None,
            },
            &|p| crate::progress::report(progress.as_ref(), "prior scale", p.done, p.total),
            &mut |_| {},
        )
    })?
    .py()?;
    let json = serde_json::to_string(&run.to_json(&set.rows)).expect("JSON values print");
    let far = run.calibration.report.far_above_noise();
    Ok((PyRobot::wrap(run.calibration.robot), json, far))
}
