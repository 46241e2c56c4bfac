//! `simulate`: measurements of a truth robot with tracker noise, as `armcomp simulate` makes them.

use armcomp_api::ops::simulate::Stand;
use armcomp_core::algorithms::simulate::Ground;
use numpy::{AllowTypeChange, PyArrayLike2};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::IntoPy;
use crate::measurements::PyMeasurements;
use crate::robot::PyRobot;

/// Measures `truth` at `poses` (n × joints, SI) or at `n` poses drawn by `sampler`, with
/// `noise_mm` of noise per axis; `seed` draws poses and noise (same seed, same values).
/// `stations`: measured from that many stations, as `--stations`; `tilt_deg` with `tilt_per`
/// ("row" or "station"): the base's tilt, as `--tilt-deg`/`--tilt-per`; `grounds`: a dict of
/// ground name → tilt in degrees or (tilt, rocking) in degrees, one station each, as `--ground`.
/// `truth` itself is left as it was.
#[pyfunction]
#[pyo3(signature = (
    truth, poses = None, n = 100, sampler = "sobol", noise_mm = 0.0, seed = 0,
    stations = None, tilt_deg = 0.0, tilt_per = "row", grounds = None
))]
#[allow(clippy::too_many_arguments)] // Python keywords, each one of the command line's flags
pub fn simulate(
    truth: PyRef<'_, PyRobot>,
    poses: Option<PyArrayLike2<'_, f64, AllowTypeChange>>,
    n: usize,
    sampler: &str,
    noise_mm: f64,
    seed: u64,
    stations: Option<usize>,
    tilt_deg: f64,
    tilt_per: &str,
    grounds: Option<&Bound<'_, PyDict>>,
) -> PyResult<PyMeasurements> {
    let robot = &truth.robot;
    let poses = match poses {
        Some(p) => crate::arrays::rows(&p, "poses", Some(robot.tree().nq()))?,
        None => armcomp_api::ops::simulate::draw_poses(robot, sampler, n, seed).py()?,
    };
    let tilt_per_station = match tilt_per {
        "row" => false,
        "station" => true,
        other => {
            let msg = format!("tilt_per `{other}`: expected \"row\" or \"station\"");
            return Err(crate::errors::input_error(&msg, None, None, Some("tilt_per")));
        }
    };
    let grounds = match grounds {
        Some(g) => g.iter().map(|(k, v)| ground(&k, &v)).collect::<PyResult<Vec<_>>>()?,
        None => Vec::new(),
    };
    let stand = Stand {
        stations,
        grounds,
        tilt_deg,
        tilt_per_station,
    };
    if stand == Stand::default() {
        let set = armcomp_api::ops::simulate::run(robot, &poses, noise_mm, seed).py()?;
        return Ok(PyMeasurements::from_set(robot, set));
    }
    // The stations are given to the truth that measures: a copy, so that `truth` stays as it was.
    let mut standing = crate::robot::copy_of(robot).py()?;
    let set = armcomp_api::ops::simulate::run_standing(&mut standing, &poses, noise_mm, &stand, seed).py()?;
    Ok(PyMeasurements::from_set(&standing, set))
}

/// One entry of `grounds`: a name and a tilt in degrees, or a (tilt, rocking) pair in degrees.
fn ground(name: &Bound<'_, PyAny>, value: &Bound<'_, PyAny>) -> PyResult<(String, Ground)> {
    let name: String = name.extract()?;
    let degrees: Option<(f64, f64)> = value
        .extract::<f64>()
        .map(|t| (t, 0.0))
        .or_else(|_| value.extract::<(f64, f64)>())
        .ok();
    match degrees {
        Some((tilt, rocking))
            if !name.trim().is_empty() && [tilt, rocking].iter().all(|x| x.is_finite() && *x >= 0.0) =>
        {
            let ground = Ground {
                tilt: tilt.to_radians(),
                rocking: rocking.to_radians(),
            };
            Ok((name, ground))
        }
        _ => {
            let msg = format!(
                "grounds[{name:?}]: expected a tilt in degrees or a (tilt, rocking) pair in degrees, both zero or more, \
                 e.g. {{\"soft\": (0.5, 0.03)}}"
            );
            Err(crate::errors::input_error(&msg, None, None, Some("grounds")))
        }
    }
}
