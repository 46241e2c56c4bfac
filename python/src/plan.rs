//! `plan`: measurement poses, as `armcomp plan` plans them.

use armcomp::ops::plan::{PlanParams, run};
use numpy::{AllowTypeChange, PyArray2, PyArrayLike2};
use pyo3::prelude::*;

use crate::errors::IntoPy;
use crate::robot::PyRobot;

/// Plans `n` measurement poses (n × joints, SI) for `robot` by `method` (sobol, halton,
/// random, grid, d-optimal, trajectory), never in collision; returns them and a note.
#[pyfunction]
#[pyo3(signature = (robot, n = 100, method = "sobol", space = "joint", pool = None, pool_sampler = "sobol", identify = None, trajectory = None, trajectory_points = 50, per_point = 10, seed = 0))]
#[allow(clippy::too_many_arguments)]
pub fn plan<'py>(
    py: Python<'py>,
    robot: PyRef<'_, PyRobot>,
    n: usize,
    method: &str,
    space: &str,
    pool: Option<usize>,
    pool_sampler: &str,
    identify: Option<Vec<String>>,
    trajectory: Option<PyArrayLike2<'py, f64, AllowTypeChange>>,
    trajectory_points: usize,
    per_point: usize,
    seed: u64,
) -> PyResult<(Bound<'py, PyArray2<f64>>, String)> {
    let r = robot.robot.clone();
    let trajectory = trajectory
        .map(|t| crate::arrays::rows(&t, "trajectory", Some(r.tree().nq())))
        .transpose()?;
    let params = PlanParams {
        n,
        method: method.into(),
        space: space.into(),
        pool,
        pool_sampler: pool_sampler.into(),
        identify: identify.unwrap_or_default(),
        trajectory,
        trajectory_points,
        per_point,
        seed,
    };
    let planned = crate::interrupt::run(py, || run(&r, &params))?.py()?;
    Ok((crate::arrays::matrix(py, &planned.poses, r.tree().nq()), planned.note))
}
