//! `simulate`: measurements of a truth robot with tracker noise, as `armcomp simulate` makes them.

use numpy::{AllowTypeChange, PyArrayLike2};
use pyo3::prelude::*;

use crate::errors::IntoPy;
use crate::measurements::PyMeasurements;
use crate::robot::PyRobot;

/// Measures `truth` at `poses` (n × joints, SI) or at `n` poses drawn by `sampler`, with
/// `noise_mm` of noise per axis; `seed` draws poses and noise (same seed, same values).
#[pyfunction]
#[pyo3(signature = (truth, poses = None, n = 100, sampler = "sobol", noise_mm = 0.0, seed = 0))]
pub fn simulate(
    truth: PyRef<'_, PyRobot>,
    poses: Option<PyArrayLike2<'_, f64, AllowTypeChange>>,
    n: usize,
    sampler: &str,
    noise_mm: f64,
    seed: u64,
) -> PyResult<PyMeasurements> {
    let robot = &truth.robot;
    let poses = match poses {
        Some(p) => crate::arrays::rows(&p, "poses", Some(robot.tree().nq()))?,
        None => armcomp_api::ops::simulate::draw_poses(robot, sampler, n, seed).py()?,
    };
    let set = armcomp_api::ops::simulate::run(robot, &poses, noise_mm, seed).py()?;
    Ok(PyMeasurements::from_set(robot, set))
}
