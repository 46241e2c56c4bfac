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
    let normal = Normal::new(0.0, params.noise_std).map_err(|e| Error::InvalidArgument {
        what: "noise".into(),
        reason: e.to_string(),
    })?;
    let mut rng = StdRng::seed_from_u64(params.seed);
    let t = truth.t_meas_base();
    let positions = truth.point_positions_many(truth.markers(), poses)?;
    let mut set = MeasurementSet::default();
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
