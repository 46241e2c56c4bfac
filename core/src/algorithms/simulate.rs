//! Simulated measurements: a "truth" robot's full model, seen by a noisy tracker.

use nalgebra::{Isometry3, Translation3, UnitQuaternion, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rand_distr::{Distribution, Normal, StandardNormal};

use crate::error::{Error, Result};

use crate::data::measurement::{MeasurementSet, Sample};
use crate::kinematics::sensor::{GravityReading, SensorReadings};
use crate::robot::{Conditions, Robot, Station};

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

/// Tilt (rad) beyond which a simulated base is not standing but falling over.
pub const ABSURD_TILT: f64 = 0.5;

/// Measures every marker of `truth` at each configuration: `T_meas_base · FK(q) · p_marker`
/// through the full model (chain and error models; a rigid truth through the markers' batched
/// point kinematics), plus Gaussian noise per axis. A truth with several stations measures the
/// poses in as many consecutive blocks of (nearly) equal size, each from its station's frame,
/// as a total station set up again for every data set does; a truth with sensors
/// (`[[sensors]]`) stands level and they read it, see [`simulate_tilted`].
pub fn simulate(truth: &Robot, poses: &[Vec<f64>], params: SimulateParams) -> Result<MeasurementSet> {
    simulate_tilted(truth, poses, params, 0.0, TiltDraw::PerRow)
}

/// How often a simulated base tilt is drawn anew.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum TiltDraw {
    /// At every pose: a carrier that moves between measurements.
    #[default]
    PerRow,
    /// Once per station: a carrier parked on different ground for each set-up, standing still
    /// while that station measures.
    PerStation,
    /// One ground per station, in the truth's station order: the base stands on each tilted by
    /// its own angle and rocks on it from pose to pose. The per-ground values replace the
    /// standard deviation `tilt_std`, which must be 0.
    Grounds(Vec<Ground>),
}

/// A ground the robot stands on while one station measures it.
#[derive(Debug, Clone, PartialEq)]
pub struct Ground {
    /// How far the ground tilts the base (rad), about a horizontal axis drawn from the seed.
    pub tilt: f64,
    /// Standard deviation (rad) of the base's rocking about its x and y axes, drawn anew at
    /// every pose: soft ground giving under the moving arm.
    pub rocking: f64,
}

/// [`simulate`] with the base standing tilted by a different angle at every pose (or station,
/// as `draw` says): about the base x and y axes, each drawn from a normal distribution of
/// standard deviation `tilt_std` (rad) with the noise's seed (a stream of its own, so the noise
/// is that of [`simulate`]).
/// Gravity in the base frame turns the other way (as `base_tilt` turns it) and the elastic
/// models respond to it. Every sensor of the truth (a tilt needs one) records its link's
/// orientation against gravity as the truth stands, the bending below it included, through its
/// mounting and with its noise; the truth itself is evaluated with the exact tilt.
///
/// What the tilt turns is the truth's to say: when it has a `measured_tilt` on a sensor of the
/// base, the base rocks under a tracker standing on the ground and the tilt turns the measured
/// points; otherwise the tracker moves with the base (it is carried on it, or the base frame is
/// registered again at every station), so the tilt shows only through the loads. A truth's
/// column leans through its elastic models: a `measured_tilt` on a sensor off the base would
/// turn it by its own reading, and is refused.
pub fn simulate_tilted(
    truth: &Robot,
    poses: &[Vec<f64>],
    params: SimulateParams,
    tilt_std: f64,
    draw: TiltDraw,
) -> Result<MeasurementSet> {
    if !(tilt_std.is_finite() && (0.0..=ABSURD_TILT).contains(&tilt_std)) {
        return Err(Error::InvalidArgument {
            what: "tilt".into(),
            reason: format!(
                "expected a standard deviation between 0 and {:.0} deg, got {} deg",
                ABSURD_TILT.to_degrees(),
                tilt_std.to_degrees()
            ),
        });
    }
    let tilted = match &draw {
        TiltDraw::Grounds(grounds) => {
            check_grounds(grounds, tilt_std, truth.stations().len().max(1))?;
            grounds.iter().any(|g| g.tilt > 0.0 || g.rocking > 0.0)
        }
        _ => tilt_std > 0.0,
    };
    if tilted && truth.sensors().is_empty() {
        return Err(Error::InvalidArgument {
            what: "tilt".into(),
            reason: "a tilted base needs a sensor in the truth's robot file (`[[sensors]]`) to read it".into(),
        });
    }
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
    let (positions, readings) = if truth.sensors().is_empty() {
        (truth.point_positions_many(truth.markers(), poses)?, Vec::new())
    } else {
        let tilt = Normal::new(0.0, tilt_std).map_err(|e| Error::InvalidArgument {
            what: "tilt".into(),
            reason: e.to_string(),
        })?;
        let mut tilt_rng = StdRng::seed_from_u64(params.seed ^ 0x7117_5eed_0000_0001);
        let next = |rng: &mut StdRng| Vector3::new(tilt.sample(rng), tilt.sample(rng), 0.0);
        // The sensors' noise is a stream of its own too.
        let mut sensor_rng = StdRng::seed_from_u64(params.seed ^ 0x5e45_0a15_0000_0002);
        match &draw {
            TiltDraw::PerRow => tilted_positions(truth, poses, |_| next(&mut tilt_rng), &mut sensor_rng)?,
            TiltDraw::PerStation => {
                let tilts: Vec<Vector3<f64>> = (0..n_stations).map(|_| next(&mut tilt_rng)).collect();
                tilted_positions(
                    truth,
                    poses,
                    |i| tilts[station_of(i, n_stations, poses.len())],
                    &mut sensor_rng,
                )?
            }
            TiltDraw::Grounds(grounds) => {
                // Each ground's tilt about a horizontal axis of its own, then its rocking.
                let standing: Vec<Vector3<f64>> = (grounds.iter())
                    .map(|g| {
                        let heading = tilt_rng.random_range(-std::f64::consts::PI..std::f64::consts::PI);
                        Vector3::new(heading.cos(), heading.sin(), 0.0) * g.tilt
                    })
                    .collect();
                tilted_positions(
                    truth,
                    poses,
                    |i| {
                        let s = station_of(i, n_stations, poses.len());
                        let rock = grounds[s].rocking;
                        standing[s]
                            + Vector3::new(tilt_rng.sample(StandardNormal), tilt_rng.sample(StandardNormal), 0.0) * rock
                    },
                    &mut sensor_rng,
                )?
            }
        }
    };
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
        let station = station_of(i, n_stations, poses.len());
        let t = truth.station_frame(station);
        for (&m, p) in truth.markers().iter().zip(at) {
            let mut p = t.transform_point(&(*p).into()).coords;
            for k in 0..3 {
                p[k] += normal.sample(&mut rng);
            }
            // A pose is a data row, shared by its points as a file writes them.
            set.rows.push(i);
            set.samples.push(Sample {
                q: q.clone(),
                point: m,
                position: p,
                orientation: None,
                payload: None,
                temperature: None,
                torque: None,
                fixed_point: None,
                plane: None,
                sensors: readings.get(i).copied().unwrap_or_default(),
                station,
                position_std: None,
            });
        }
    }
    Ok(set)
}

/// Settings of a simulated fixed-point campaign.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FixedPointParams {
    /// Configurations per fixed point.
    pub per_point: usize,
    /// Standard deviation of the joint encoders' noise (rad, or m for a prismatic joint): what
    /// a fixed-point measurement's noise is, since no position is measured.
    pub joint_noise_std: f64,
    /// Seed of the starting configurations and the noise.
    pub seed: u64,
}

/// Where a simulated campaign without an instrument puts the tool (measurement frame, m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Contact {
    /// Into a fixed point.
    FixedPoint(nalgebra::Vector3<f64>),
    /// On a plane (its normal the pose's `z` axis), at places drawn uniformly within `spread`
    /// of its origin along its `x` and `y` axes, turned about the normal at random; flush
    /// (the tool's `z` axis along the normal) when the truth constrains tilts.
    Plane {
        /// The plane's pose.
        pose: Isometry3<f64>,
        /// Half the side of the square the contacts are drawn in (m).
        spread: f64,
    },
}

/// Puts the tool of `truth` (its first marker) into each named fixed point (measurement frame,
/// m) from `per_point` configurations: [`simulate_contacts`] with fixed points.
pub fn simulate_fixed_points(
    truth: &Robot,
    points: &[(String, nalgebra::Vector3<f64>)],
    params: FixedPointParams,
) -> Result<MeasurementSet> {
    let contacts: Vec<(String, Contact)> = points
        .iter()
        .map(|(name, p)| (name.clone(), Contact::FixedPoint(*p)))
        .collect();
    simulate_contacts(truth, &contacts, params)
}

/// Puts the tool of `truth` (its first marker) at each named contact from `per_point`
/// configurations, found by inverse kinematics of the full model from seeded starts spread
/// over the joint ranges: the rows a campaign without an instrument records (a ball put into a
/// socket again and again, a tool pressed on a table). Fails when a contact is reached from
/// too few starts.
pub fn simulate_contacts(
    truth: &Robot,
    contacts: &[(String, Contact)],
    params: FixedPointParams,
) -> Result<MeasurementSet> {
    use crate::algorithms::ik::{IkParams, IkTarget, IkWorkspace, solve_ik};
    if truth.frame_link().is_some() {
        return Err(Error::InvalidArgument {
            what: "robot".into(),
            reason: "measures in a frame link's frame; contacts are simulated in the root's frame only".into(),
        });
    }
    let flush = truth.plane_constraints().tilts() > 0;
    // No encoder is off by more than a quarter turn: a larger noise is another unit or a slip.
    if !(0.0..=std::f64::consts::FRAC_PI_2).contains(&params.joint_noise_std) {
        return Err(Error::InvalidArgument {
            what: "joint noise".into(),
            reason: format!(
                "expected from 0 to 90 degrees, got {:e} degrees",
                params.joint_noise_std.to_degrees()
            ),
        });
    }
    if let Some((k, (name, _))) =
        (contacts.iter().enumerate()).find(|(k, (n, _))| contacts[..*k].iter().any(|(m, _)| m == n))
    {
        return Err(Error::InvalidArgument {
            what: format!("contact {}", k + 1),
            reason: format!(
                "`{}` names two contacts; each fixed point or plane has a name of its own",
                crate::support::text::shown(name)
            ),
        });
    }
    let normal = Normal::new(0.0, params.joint_noise_std).map_err(|e| Error::InvalidArgument {
        what: "joint noise".into(),
        reason: e.to_string(),
    })?;
    let mut rng = StdRng::seed_from_u64(params.seed);
    let marker = truth.markers().first().copied().ok_or_else(|| Error::InvalidArgument {
        what: "robot".into(),
        reason: "has no marker to put at the contacts".into(),
    })?;
    // Many more starts than rows: some do not reach a point within the joint limits.
    let tries = 20 * params.per_point.max(1);
    let starts = crate::model::sampling::configurations(
        truth.tree(),
        crate::model::sampling::Sampler::Sobol,
        tries * contacts.len(),
        params.seed,
    )?;
    let opts = IkParams {
        restarts: 0,
        ..IkParams::default()
    };
    let mut ws = IkWorkspace::new(truth);
    let t_base_meas = truth.t_meas_base().inverse();
    let mut set = MeasurementSet::default();
    let spot = rand_distr::Uniform::new_inclusive(-1.0, 1.0).expect("a finite range");
    for (k, (name, contact)) in contacts.iter().enumerate() {
        let mut found = 0;
        for q0 in &starts[k * tries..(k + 1) * tries] {
            if found == params.per_point {
                break;
            }
            let target = match contact {
                Contact::FixedPoint(p) => IkTarget::Position(t_base_meas.transform_point(&(*p).into()).coords),
                Contact::Plane { pose, spread } => {
                    let (u, v, turn) = (spot.sample(&mut rng), spot.sample(&mut rng), spot.sample(&mut rng));
                    let at = t_base_meas
                        * pose
                        * crate::model::geom::xyz_rpy(
                            [u * spread, v * spread, 0.0],
                            [0.0, 0.0, turn * std::f64::consts::PI],
                        );
                    if flush {
                        IkTarget::Pose(at)
                    } else {
                        IkTarget::Position(at.translation.vector)
                    }
                }
            };
            if solve_ik(truth, marker, &target, q0, &opts, &mut ws).is_err() {
                continue;
            }
            // An encoder reads a joint at its limit within the limit.
            let limits = truth.tree().coordinate_limits();
            let q: Vec<f64> = ws
                .q()
                .iter()
                .zip(limits)
                .map(|(v, l)| {
                    let v = v + normal.sample(&mut rng);
                    l.map_or(v, |l| v.clamp(l.lower, l.upper))
                })
                .collect();
            set.rows.push(set.samples.len());
            set.samples.push(Sample {
                q,
                point: marker,
                position: nalgebra::Vector3::zeros(),
                orientation: None,
                payload: None,
                temperature: None,
                torque: None,
                fixed_point: matches!(contact, Contact::FixedPoint(_)).then(|| name.clone()),
                plane: matches!(contact, Contact::Plane { .. }).then(|| name.clone()),
                sensors: Default::default(),
                station: 0,
                position_std: None,
            });
            found += 1;
        }
        if found < params.per_point {
            return Err(Error::InvalidArgument {
                what: match contact {
                    Contact::FixedPoint(_) => format!("fixed point `{name}`"),
                    Contact::Plane { .. } => format!("plane `{name}`"),
                },
                reason: format!(
                    "reached from {found} of {tries} starts, fewer than the {} asked for; is it within the arm's reach?",
                    params.per_point
                ),
            });
        }
    }
    Ok(set)
}

/// Checks grounds against the truth's `n_stations` (one each) and their angles.
fn check_grounds(grounds: &[Ground], tilt_std: f64, n_stations: usize) -> Result<()> {
    let fail = |reason: String| {
        Err(Error::InvalidArgument {
            what: "grounds".into(),
            reason,
        })
    };
    if tilt_std != 0.0 {
        return fail("each ground gives its own tilt and rocking; give no tilt beside them".into());
    }
    if grounds.len() != n_stations {
        return fail(format!(
            "{} grounds for {n_stations} station(s); each ground is measured from a station of its own",
            grounds.len()
        ));
    }
    for (k, g) in grounds.iter().enumerate() {
        for (what, v) in [("tilt", g.tilt), ("rocking", g.rocking)] {
            if !(v.is_finite() && (0.0..=ABSURD_TILT).contains(&v)) {
                return fail(format!(
                    "ground {}: expected a {what} between 0 and {:.0} deg, got {} deg",
                    k + 1,
                    ABSURD_TILT.to_degrees(),
                    v.to_degrees()
                ));
            }
        }
    }
    Ok(())
}

/// The station that measures pose `i` of `n_poses`: consecutive blocks of (nearly) equal size.
fn station_of(i: usize, n_stations: usize, n_poses: usize) -> usize {
    i * n_stations / n_poses
}

/// The markers' positions (m, base frame) at `poses` with the base tilted by `tilt(i)` (a
/// rotation vector, rad) at pose `i`, and the readings every sensor records there (see
/// [`simulate_tilted`]), its noise drawn from `rng`.
fn tilted_positions(
    truth: &Robot,
    poses: &[Vec<f64>],
    mut tilt: impl FnMut(usize) -> Vector3<f64>,
    rng: &mut StdRng,
) -> Result<(Vec<Vector3<f64>>, Vec<SensorReadings>)> {
    let tree = truth.tree();
    let sensors = truth.sensors();
    let values = truth.error_values();
    let mountings: Vec<Option<UnitQuaternion<f64>>> =
        (0..sensors.len()).map(|k| truth.sensor_mounting(k, values)).collect();
    if let Some(k) = (0..sensors.len()).find(|&k| sensors[k].body != 0 && mountings[k].is_some()) {
        return Err(Error::InvalidArgument {
            what: "truth".into(),
            reason: format!(
                "turns its chain by the reading of sensor `{}`, which is off the base: a simulated truth leans \
                 through its elastic models, and the sensor records the lean",
                sensors[k].name
            ),
        });
    }
    let turns_base = (0..sensors.len()).any(|k| sensors[k].body == 0 && mountings[k].is_some());
    let mut ws = truth.workspace();
    let down = truth.gravity().try_normalize(0.0).unwrap_or(-Vector3::z());
    let mut positions = Vec::with_capacity(poses.len() * truth.markers().len());
    let mut readings = Vec::with_capacity(poses.len());
    for (i, q) in poses.iter().enumerate() {
        tree.check_q(q)?;
        tree.forward_into(q, &mut ws.rigid);
        // Gravity seen from a tilted base turns the other way (as `base_tilt` turns it).
        let tilted = UnitQuaternion::from_scaled_axis(tilt(i)).inverse_transform_vector(&down);
        // The truth is evaluated with the exact tilt: through the rigid frames, read so that
        // its mountings turn the readings back to it.
        let mut exact = SensorReadings::default();
        for (k, s) in sensors.iter().enumerate() {
            let r = GravityReading::of_base_direction(s.body, &tilted, tree, &ws.rigid);
            let mounting = mountings[k].unwrap_or_default();
            exact.set(
                k,
                Some(GravityReading {
                    direction: mounting.inverse_transform_vector(&r.direction),
                    ..r
                }),
            );
        }
        let conditions = Conditions {
            sensors: exact,
            ..Conditions::default()
        };
        truth.forward_with_into(tree, values, q, conditions, &mut ws);
        positions.extend(truth.markers().iter().map(|&m| ws.frames.point[m].translation.vector));
        // What the sensors record: the base's the tilt; a link's its orientation in the frames
        // as the truth stands, which a base turned under the tracker expresses in the level
        // frame.
        let frame_down = if turns_base { down } else { tilted };
        let mut recorded = SensorReadings::default();
        for (k, s) in sensors.iter().enumerate() {
            let at = match s.body {
                0 => GravityReading::of_base_direction(0, &tilted, tree, &ws.rigid),
                b => GravityReading::of_base_direction(b, &frame_down, tree, &ws.frames),
            };
            let reading = s
                .simulated_reading(&at.direction, &mountings[k].unwrap_or_default(), || {
                    rng.sample(rand_distr::StandardNormal)
                })
                .map_err(|m| Error::InvalidArgument {
                    what: format!("sensor `{}` at pose {}", s.name, i + 1),
                    reason: m,
                })?;
            recorded.set(k, Some(reading));
        }
        readings.push(recorded);
    }
    Ok((positions, readings))
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
