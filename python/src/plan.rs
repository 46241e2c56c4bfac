//! `plan`: measurement poses, as `armcomp plan` plans them.

use armcomp_api::ops::plan::{PlanParams, PlanPool, run};
use numpy::{AllowTypeChange, PyArrayLike2};
use pyo3::prelude::*;

use crate::arrays::Matrix;
use crate::errors::{IntoPy, input_error};
use crate::measurements::PyMeasurements;
use crate::robot::PyRobot;

/// Poses, note, chosen data rows and the selection report's JSON.
type PlanOutput<'py> = (Matrix<'py>, String, Option<Vec<usize>>, Option<String>);

/// Plans measurement poses for `robot` by `method` (sobol, halton, random, grid, d-optimal,
/// a-optimal, uncertainty, trajectory), never in collision. `pool` is a number of poses to
/// sample, an array of configurations or `Measurements` (retrospective selection). Returns
/// the poses, a note, the chosen data rows (measured pool) and the selection report as JSON
/// text (optimal methods).
#[pyfunction]
#[pyo3(signature = (robot, n = 100, method = None, space = "joint", pool = None, pool_sampler = "sobol", identify = None, next = None, measured = None, noise_mm = 0.1, exchange_passes = 10, trajectory = None, trajectory_points = 50, per_point = 10, seed = 0))]
#[allow(clippy::too_many_arguments)]
pub fn plan<'py>(
    py: Python<'py>,
    robot: PyRef<'_, PyRobot>,
    n: usize,
    method: Option<String>,
    space: &str,
    pool: Option<Bound<'py, PyAny>>,
    pool_sampler: &str,
    identify: Option<Vec<String>>,
    next: Option<usize>,
    measured: Option<PyRef<'_, PyMeasurements>>,
    noise_mm: f64,
    exchange_passes: usize,
    trajectory: Option<PyArrayLike2<'py, f64, AllowTypeChange>>,
    trajectory_points: usize,
    per_point: usize,
    seed: u64,
) -> PyResult<PlanOutput<'py>> {
    let r = robot.robot.clone();
    let nq = r.tree().nq();
    let trajectory = trajectory
        .map(|t| crate::arrays::rows(&t, "trajectory", Some(nq)))
        .transpose()?;
    let pool = match pool {
        None => PlanPool::Sampled(0),
        Some(p) => {
            if let Ok(size) = p.extract::<usize>() {
                if size == 0 {
                    return Err(input_error(
                        "pool 0: give a number of poses to sample (at least 1), configurations or measurements",
                        None,
                        None,
                        Some("pool"),
                    ));
                }
                PlanPool::Sampled(size)
            } else if let Ok(data) = p.cast::<PyMeasurements>() {
                PlanPool::Measured(data.borrow().resolve(&r)?)
            } else {
                let array: PyArrayLike2<'py, f64, AllowTypeChange> = p.extract().map_err(|_| {
                    input_error(
                        "pool: expected a number of poses, an n × joints array of configurations or Measurements",
                        None,
                        None,
                        Some("pool"),
                    )
                })?;
                PlanPool::Configurations(crate::arrays::rows(&array, "pool", Some(nq))?)
            }
        }
    };
    let measured = match measured {
        Some(m) => m.resolve(&r)?,
        None => Default::default(),
    };
    let params = PlanParams {
        n,
        method,
        space: space.into(),
        pool,
        pool_sampler: pool_sampler.into(),
        identify: identify.unwrap_or_default(),
        next,
        measured,
        measurement_std: noise_mm * 1e-3,
        exchange_passes,
        trajectory,
        trajectory_points,
        per_point,
        seed,
    };
    let planned = crate::interrupt::run(py, |_| run(&r, &params))?.py()?;
    crate::errors::warn_all(py, &planned.warnings)?;
    let selection = planned.selection_json().map(|v| v.to_string());
    Ok((
        crate::arrays::matrix(py, &planned.poses, nq),
        planned.note,
        planned.rows,
        selection,
    ))
}
