//! Simulated measurements: a "truth" robot's full model, seen by a noisy tracker.

use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};

use crate::error::{Error, Result};
use crate::measurement::{MeasurementSet, Sample};
use crate::robot::Robot;

/// Settings of a simulated measurement campaign.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimulateParams {
    /// Standard deviation of the tracker noise per axis (m).
    pub noise_std: f64,
    /// Seed of the noise.
    pub seed: u64,
}

/// Noise (m per axis) at which simulated measurements say nothing about an arm: no tracker
/// is off by a metre.
pub const ABSURD_NOISE: f64 = 1.0;

/// Noise (m per axis) beyond any tracker's (laser trackers are off by hundredths of a
/// millimetre, cameras by a millimetre): allowed, with a warning.
pub const IMPLAUSIBLE_NOISE: f64 = 5e-3;

/// Measures every marker of `truth` at each configuration: `T_meas_base · FK(q) · p_marker`
/// through the full model (chain and error models; a rigid truth through the markers' batched
/// point kinematics), plus Gaussian noise per axis.
pub fn simulate(truth: &Robot, poses: &[Vec<f64>], params: SimulateParams) -> Result<MeasurementSet> {
    if !(params.noise_std.is_finite() && params.noise_std >= 0.0) {
        return Err(Error::InvalidArgument {
            what: "noise".into(),
            reason: format!("must be zero or positive, got {} m", params.noise_std),
        });
    }
    if params.noise_std > ABSURD_NOISE {
        return Err(Error::InvalidArgument {
            what: "noise".into(),
            reason: format!(
                "{:.3e} mm per axis is no tracker's noise; expected at most {:.0} mm",
                params.noise_std * 1e3,
                ABSURD_NOISE * 1e3
            ),
        });
    }
    let normal = Normal::new(0.0, params.noise_std).map_err(|e| Error::InvalidArgument {
        what: "noise".into(),
        reason: e.to_string(),
    })?;
    let mut rng = StdRng::seed_from_u64(params.seed);
    let t = truth.t_meas_base();
    let positions = truth.point_positions_many(truth.markers(), poses)?;
    let mut set = MeasurementSet::default();
    if params.noise_std > IMPLAUSIBLE_NOISE {
        set.warnings.push(format!(
            "a noise of {:.3} mm per axis is more than any tracker's (at most {:.0} mm)",
            params.noise_std * 1e3,
            IMPLAUSIBLE_NOISE * 1e3
        ));
    }
    let per_pose = positions.chunks_exact(truth.markers().len().max(1));
    for (q, at) in poses.iter().zip(per_pose) {
        for (&m, p) in truth.markers().iter().zip(at) {
            let mut p = t.transform_point(&(*p).into()).coords;
            for k in 0..3 {
                p[k] += normal.sample(&mut rng);
            }
            set.samples.push(Sample {
                q: q.clone(),
                point: m,
                position: p,
                orientation: None,
                payload: None,
                temperature: None,
                torque: None,
            });
        }
    }
    Ok(set)
}
