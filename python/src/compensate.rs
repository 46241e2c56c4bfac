//! `compensate`: joint commands for a batch of targets, as `armcomp compensate` computes them.

use armcomp_api::ops::compensate::{Frame, Joints, Target, locked_by_name, orientation, run, sensor_readings};
use armcomp_core::algorithms::compensate::CompensationMode;
use nalgebra::Vector3;
use numpy::PyArray2;
use pyo3::prelude::*;

use crate::errors::{IntoPy, input_error};
use crate::robot::PyRobot;

/// What `compensate` returns: commands (n × joints), corrected targets (n × 3), the
/// predictor's standard deviations (n × 3, or None) and the rows exact mode could not meet.
type Commands<'py> = (
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray2<f64>>,
    Option<Bound<'py, PyArray2<f64>>>,
    Vec<(usize, f64)>,
);

/// Joint commands that put `model`'s tool on `targets`: n × 3 positions (m), or n × 7 with a
/// tool orientation `qw, qx, qy, qz` to keep, in the measurement or base `frame`; from `start`
/// (1 or n rows of joint values, SI), changing only the joints that move the tool and are not
/// in `lock`. `sensors` maps a sensor's name to its reading now, as its columns hold it in SI
/// (an accelerometer's x, y, z in m/s²; an inclinometer's roll, pitch in rad): the tilt every
/// target is compensated at.
#[pyfunction]
#[pyo3(signature = (model, targets, mode = "exact", frame = "measurement", start = None, lock = Vec::new(), sensors = None))]
#[allow(clippy::too_many_arguments)]
pub fn compensate<'py>(
    py: Python<'py>,
    model: PyRef<'_, PyRobot>,
    targets: &Bound<'py, PyAny>,
    mode: &str,
    frame: &str,
    start: Option<Bound<'py, PyAny>>,
    lock: Vec<String>,
    sensors: Option<std::collections::BTreeMap<String, Vec<f64>>>,
) -> PyResult<Commands<'py>> {
    let bad = |field: &str, message: String| input_error(&message, None, None, Some(field));
    let mode = match mode {
        "exact" => CompensationMode::Exact,
        "paper" => CompensationMode::Paper,
        other => return Err(bad("mode", format!("unknown mode `{other}`; expected exact or paper"))),
    };
    let frame = match frame {
        "measurement" => Frame::Measurement,
        "base" => Frame::Base,
        other => {
            return Err(bad(
                "frame",
                format!("unknown frame `{other}`; expected measurement or base"),
            ));
        }
    };
    let targets = crate::arrays::matrix_arg(
        targets,
        "targets",
        "one target per row (n × 3, or n × 7 with qw, qx, qy, qz)",
    )?;
    let rows = crate::arrays::rows(&targets, "targets", None)?;
    let targets = rows
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let orientation = match r.len() {
                3 => None,
                7 => Some(
                    orientation([r[3], r[4], r[5], r[6]]).map_err(|m| bad("targets", format!("target {i}: {m}")))?,
                ),
                w => return Err(bad("targets", format!("targets: expected 3 or 7 columns, got {w}"))),
            };
            if r.iter().any(|v| !v.is_finite()) {
                return Err(bad("targets", format!("target {i}: a value is not finite")));
            }
            Ok(Target {
                position: Vector3::new(r[0], r[1], r[2]),
                orientation,
            })
        })
        .collect::<PyResult<Vec<_>>>()?;
    let robot = model.robot.clone();
    let starts = match &start {
        Some(s) => {
            let s = crate::arrays::matrix_arg(s, "start", "1 or n rows of joint values (SI)")?;
            crate::arrays::rows(&s, "start", Some(robot.tree().nq()))?
        }
        None => Vec::new(),
    };
    let locked = locked_by_name(&robot, &lock).py()?;
    let readings: Vec<(String, Vec<f64>)> = sensors.unwrap_or_default().into_iter().collect();
    let joints = Joints {
        sensors: if readings.is_empty() {
            Vec::new()
        } else {
            vec![sensor_readings(&robot, &readings).py()?]
        },
        ..Joints::new(&robot, starts, locked).py()?
    };
    let describe = |i: usize| format!("target {i}");
    let out = crate::interrupt::run(py, |cancel| {
        run(&robot, &targets, &joints, mode, frame, &describe, cancel)
    })?
    .py()?;
    let std = out
        .std
        .iter()
        .copied()
        .collect::<Option<Vec<_>>>()
        .filter(|s| !s.is_empty())
        .map(|s| crate::arrays::points(py, &s));
    Ok((
        crate::arrays::matrix(py, &out.q, robot.tree().nq()),
        crate::arrays::points(py, &out.corrected),
        std,
        out.unconverged,
    ))
}
