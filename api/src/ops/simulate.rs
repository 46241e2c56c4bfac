//! `simulate`: measurements of a truth robot at drawn or given poses, with tracker noise.

use armcomp_core::Robot;
use armcomp_core::algorithms::simulate::{Ground, SimulateParams, TiltDraw, random_stations, simulate_tilted};
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

/// Where a simulated robot stands while it is measured (see [`run_standing`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Stand {
    /// Measured from this many stations, in as many consecutive blocks of the poses; `None`:
    /// the truth's own stations.
    pub stations: Option<usize>,
    /// The grounds it stands on, each measured from a station named after it (in place of
    /// `stations` and the tilt).
    pub grounds: Vec<(String, Ground)>,
    /// Standard deviation of the base's tilt about its x and y axes (deg).
    pub tilt_deg: f64,
    /// The tilt drawn once per station rather than at every pose.
    pub tilt_per_station: bool,
}

/// [`run_tilted`] with `truth` standing as `stand` says: the stations drawn (a stream of the
/// seed's own, so that the same seed draws the same poses whatever the stations) and given to
/// `truth`, named by the grounds when there are any.
pub fn run_standing(
    truth: &mut Robot,
    poses: &[Vec<f64>],
    noise_mm: f64,
    stand: &Stand,
    seed: u64,
) -> armcomp_core::Result<MeasurementSet> {
    let grounds = &stand.grounds;
    let invalid = |reason: String| armcomp_core::Error::InvalidArgument {
        what: "--ground".into(),
        reason,
    };
    let twice = (grounds.iter().enumerate()).find(|(k, (n, _))| grounds[..*k].iter().any(|(m, _)| m == n));
    if let Some((_, (name, _))) = twice {
        return Err(invalid(format!(
            "`{name}` is given twice; each ground needs a name of its own"
        )));
    }
    // A tilt beside the grounds is refused where the grounds are drawn (`simulate_tilted`).
    if !grounds.is_empty() && (stand.stations.is_some() || stand.tilt_per_station) {
        return Err(invalid(
            "each ground is a station with its own tilt: give the grounds alone, without stations or a tilt".into(),
        ));
    }
    if let Some(k) = stand.stations.or((!grounds.is_empty()).then_some(grounds.len())) {
        let mut stations = self::stations(truth, k, poses.len(), seed.wrapping_add(0x5851_f42d_4c95_7f2d))?;
        for (station, (name, _)) in stations.iter_mut().zip(grounds) {
            station.name.clone_from(name);
        }
        truth.set_stations(stations);
    }
    let draw = if !grounds.is_empty() {
        TiltDraw::Grounds(grounds.iter().map(|(_, g)| g.clone()).collect())
    } else if stand.tilt_per_station {
        TiltDraw::PerStation
    } else {
        TiltDraw::PerRow
    };
    run_tilted(truth, poses, noise_mm, stand.tilt_deg, draw, seed)
}
