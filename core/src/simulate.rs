//! Simulated measurements: a "truth" robot's full model, seen by a noisy tracker.

use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal};

use crate::error::{Error, Result};
use crate::measurement::{MeasurementSet, Sample};
use crate::robot::{Robot, Station};

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
/// point kinematics), plus Gaussian noise per axis. A truth with several stations measures the
/// poses in as many consecutive blocks of (nearly) equal size, each from its station's frame,
/// as a total station set up again for every data set does.
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
    let n_stations = truth.stations().len().max(1);
    let positions = truth.point_positions_many(truth.markers(), poses)?;
    let mut set = MeasurementSet::default();
    if params.noise_std > IMPLAUSIBLE_NOISE {
        set.warnings.push(format!(
            "a noise of {:.3} mm per axis is more than any tracker's (at most {:.0} mm)",
            params.noise_std * 1e3,
            IMPLAUSIBLE_NOISE * 1e3
        ));
    }
    set.stations = truth.stations().iter().map(|s| s.name.clone()).collect();
    let per_pose = positions.chunks_exact(truth.markers().len().max(1));
    for (i, (q, at)) in poses.iter().zip(per_pose).enumerate() {
        let station = i * n_stations / poses.len();
        let t = truth.station_frame(station);
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
                station,
            });
        }
    }
    Ok(set)
}

/// `k` stations `st1` … `stK` around `truth`'s measurement frame, drawn from `seed`: `st1` is
/// the truth's own frame; every other is it moved as a total station set up again around the
/// robot is: turned about the vertical by a yaw uniform in ±180°, tilted by a roll and a pitch
/// uniform in ±2°, and shifted by a translation uniform in ±2 m horizontally and ±0.5 m
/// vertically. None for `k` ≤ 1 (the truth's one frame).
pub fn random_stations(truth: &Robot, k: usize, seed: u64) -> Vec<Station> {
    if k <= 1 {
        return Vec::new();
    }
    let mut rng = StdRng::seed_from_u64(seed);
    let t = truth.t_meas_base();
    (0..k)
        .map(|i| {
            let frame = if i == 0 {
                t
            } else {
                let tilt = 2f64.to_radians();
                let turn = UnitQuaternion::from_euler_angles(
                    rng.random_range(-tilt..tilt),
                    rng.random_range(-tilt..tilt),
                    rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
                );
                let shift = Translation3::new(
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-2.0..2.0),
                    rng.random_range(-0.5..0.5),
                );
                Isometry3::from_parts(shift, turn) * t
            };
            Station {
                name: format!("st{}", i + 1),
                frame,
            }
        })
        .collect()
}
