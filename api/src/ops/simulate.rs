//! `simulate`: measurements of a truth robot at drawn or given poses, with tracker noise.

use armcomp_core::Robot;
use armcomp_core::algorithms::simulate::{SimulateParams, TiltDraw, random_stations, simulate_tilted};
use armcomp_core::data::measurement::MeasurementSet;
use armcomp_core::model::sampling::{Sampler, configurations};
use armcomp_core::robot::Station;
use armcomp_core::support::limits::{self, Cost};

/// `n` poses drawn inside the joint limits of `truth` by `sampler` (sobol, halton, random or
/// grid); `n` is checked against [the limits](armcomp_core::support::limits) of simulating them first.
pub fn draw_poses(truth: &Robot, sampler: &str, n: usize, seed: u64) -> armcomp_core::Result<Vec<Vec<f64>>> {
    let sampler = Sampler::parse(sampler)?;
    let pose = truth.pose_cost();
    limits::check("--n", n, "poses", &|n| Cost::per_unit(n, pose.bytes, pose.flops))?;
    configurations(truth.tree(), sampler, n, seed)
}

/// `k` stations drawn from `seed` around `truth`'s measurement frame (see [`random_stations`])
/// to measure `n_poses` poses in blocks: at most one station per pose, each held to the cost of
/// its frame, name and the six unknowns it brings to a calibration, before any is drawn.
pub fn stations(truth: &Robot, k: usize, n_poses: usize, seed: u64) -> armcomp_core::Result<Vec<Station>> {
    // A station's frame and name, its entry in the robot's description and the measurement
    // file, and its six frame columns over its rows in a calibration's Jacobian.
    limits::check("--stations", k, "stations", &|k| {
        Cost::per_unit(k, 512.0, 6.0 * 6.0 * 100.0)
    })?;
    if k > n_poses {
        return Err(armcomp_core::Error::InvalidArgument {
            what: "--stations".into(),
            reason: format!(
                "{k} stations for {n_poses} poses; each station measures a block of the poses, so give at most one \
                 station per pose"
            ),
        });
    }
    Ok(random_stations(truth, k, seed))
}

/// Measures `truth` at `poses` with `noise_mm` of noise per axis, the noise drawn from `seed`.
pub fn run(truth: &Robot, poses: &[Vec<f64>], noise_mm: f64, seed: u64) -> armcomp_core::Result<MeasurementSet> {
    run_tilted(truth, poses, noise_mm, 0.0, TiltDraw::PerRow, seed)
}

/// [`run`] with the base tilted about its x and y axes by angles drawn per pose (or per station)
/// with a standard deviation of `tilt_deg` (see [`simulate_tilted`]).
pub fn run_tilted(
    truth: &Robot,
    poses: &[Vec<f64>],
    noise_mm: f64,
    tilt_deg: f64,
    draw: TiltDraw,
    seed: u64,
) -> armcomp_core::Result<MeasurementSet> {
    // Noise draws use a stream of their own so that the same poses get the same noise
    // whether they were sampled or read from a file.
    let params = SimulateParams {
        noise_std: noise_mm * 1e-3,
        seed: seed.wrapping_add(0x9e37_79b9_7f4a_7c15),
    };
    simulate_tilted(truth, poses, params, tilt_deg.to_radians(), draw)
}
