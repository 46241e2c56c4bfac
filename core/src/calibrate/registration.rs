//! Closed-form registration of the measurement frame, and the check for mislabelled units.

use nalgebra::{Matrix3, Rotation3, Vector3};

use super::evidence::{EvidenceParams, calibrate_with_evidence};
use super::{CalibrationParams, Noise, ParameterSpace, Problem};
use crate::data::measurement::{Sample, SampleKind};
use crate::error::Result;
use crate::robot::Robot;

/// Registers station `station`'s measurement frame in closed form: the rigid transform that
/// best maps the model's points (robot base frame) onto that station's measured ones (see
/// [`rigid_fit`]). Writes it into the station's frame parameters of `theta` and returns true,
/// or leaves `theta` alone and returns false when the points do not span a plane (a rotation
/// is then not determined).
pub(super) fn register_base(
    space: &ParameterSpace,
    theta: &mut [f64],
    station: usize,
    samples: &[Sample],
    measured_now: &[Vector3<f64>],
) -> bool {
    // `measured_now` are the model's points seen through the current frame; map them back
    // into the base frame.
    let t_now = space.base_pose(theta, station);
    let (model, measured): (Vec<Vector3<f64>>, Vec<Vector3<f64>>) = samples
        .iter()
        .zip(measured_now)
        // Fixed-point and plane samples measure no position to register on.
        .filter(|(s, _)| s.station == station && s.kind() == SampleKind::Position)
        .map(|(s, p)| (t_now.inverse_transform_point(&(*p).into()).coords, s.position))
        .unzip();
    if model.is_empty() {
        return false;
    }
    let Some((rotation, v)) = rigid_fit(&model, &measured) else {
        return false;
    };
    let (r, p, y) = rotation.euler_angles();
    let values = [v.x, v.y, v.z, r, p, y];
    theta[space.station_params(station)].copy_from_slice(&values);
    true
}

/// The rigid transform (rotation, then translation) that best maps `model` onto `measured` in
/// least squares, by the SVD of their cross-covariance (Kabsch/Umeyama, no scale); none when
/// the points do not span a plane.
pub(super) fn rigid_fit(model: &[Vector3<f64>], measured: &[Vector3<f64>]) -> Option<(Rotation3<f64>, Vector3<f64>)> {
    let n = model.len() as f64;
    let cm = model.iter().sum::<Vector3<f64>>() / n;
    let cs = measured.iter().sum::<Vector3<f64>>() / n;
    let mut h = Matrix3::zeros();
    for (m, s) in model.iter().zip(measured) {
        h += (m - cm) * (s - cs).transpose();
    }
    let svd = h.svd(true, true);
    let (u, v_t) = (svd.u?, svd.v_t?);
    let mut sv: Vec<f64> = svd.singular_values.iter().copied().collect();
    sv.sort_by(|a, b| b.total_cmp(a));
    if sv[1].is_nan() || sv[1] <= 1e-9 * sv[0].max(1e-300) {
        return None;
    }
    let v = v_t.transpose();
    let d = (v * u.transpose()).determinant().signum();
    let rotation = v * Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, d)) * u.transpose();
    let rotation = Rotation3::from_matrix_unchecked(rotation);
    Some((rotation, cs - rotation * cm))
}

/// RMS (m) of `measured` against `model` after the best rigid registration of each station's
/// points (`stations[i]` is point `i`'s); infinite when one is not determined.
pub(super) fn registered_rms(model: &[Vector3<f64>], measured: &[Vector3<f64>], stations: &[usize]) -> f64 {
    let n_stations = stations.iter().max().map_or(1, |k| k + 1);
    let mut sum = 0.0;
    for k in 0..n_stations {
        let (m, s): (Vec<Vector3<f64>>, Vec<Vector3<f64>>) = model
            .iter()
            .zip(measured)
            .zip(stations)
            .filter(|(_, st)| **st == k)
            .map(|((m, s), _)| (*m, *s))
            .unzip();
        if m.is_empty() {
            continue;
        }
        let Some((rotation, translation)) = rigid_fit(&m, &s) else {
            return f64::INFINITY;
        };
        sum += m
            .iter()
            .zip(&s)
            .map(|(m, s)| (rotation * m + translation - s).norm_squared())
            .sum::<f64>();
    }
    (sum / model.len() as f64).sqrt()
}

/// A unit mistake the data give away: the starting model registered rigidly onto the measured
/// points fits ten times better once the positions or the revolute joint values are read in
/// the other unit. The message names the mistake and the fix.
pub(super) fn unit_mistake(problem: &Problem<'_>, theta0: &[f64]) -> Result<Option<String>> {
    // Fixed-point and plane samples measure no position whose unit could be wrong.
    if problem.fixed.iter().any(Option::is_some) || problem.plane.iter().any(Option::is_some) {
        return Ok(None);
    }
    let model_points = |samples: &[Sample]| -> Result<Vec<Vector3<f64>>> {
        let p = Problem::new(problem.robot, problem.space, samples, problem.noise());
        Ok(p.predict(theta0)?.1.world)
    };
    let measured: Vec<Vector3<f64>> = problem.samples.iter().map(|s| s.position).collect();
    let stations: Vec<usize> = problem.samples.iter().map(|s| s.station).collect();
    let model = model_points(problem.samples)?;
    let as_declared = registered_rms(&model, &measured, &stations);
    let revolute: Vec<bool> = problem
        .robot
        .tree()
        .coordinate_is_prismatic()
        .iter()
        .map(|p| !p)
        .collect();
    let rescaled_angles = |f: f64| -> Result<f64> {
        let samples: Vec<Sample> = problem
            .samples
            .iter()
            .map(|s| {
                let mut s = s.clone();
                s.q.iter_mut()
                    .zip(&revolute)
                    .filter(|(_, r)| **r)
                    .for_each(|(q, _)| *q *= f);
                s
            })
            .collect();
        Ok(registered_rms(&model_points(&samples)?, &measured, &stations))
    };
    let deg = 180.0 / std::f64::consts::PI;
    let scaled = |f: f64| registered_rms(&model, &measured.iter().map(|p| p * f).collect::<Vec<_>>(), &stations);
    let hypotheses = [
        (
            scaled(1e3),
            "the positions look like metres declared as millimetres: read 1000 times larger they fit",
            "declare the position columns in metres (`x[m]`, `y[m]`, `z[m]`)",
        ),
        (
            scaled(1e-3),
            "the positions look like millimetres declared as metres: read 1000 times smaller they fit",
            "declare the position columns in millimetres (`x[mm]`, `y[mm]`, `z[mm]`)",
        ),
        (
            rescaled_angles(deg)?,
            "the revolute joint values look like radians declared as degrees: read as radians they fit",
            "declare the joint columns in radians (`j1[rad]`, ...)",
        ),
        (
            rescaled_angles(1.0 / deg)?,
            "the revolute joint values look like degrees declared as radians: read as degrees they fit",
            "declare the joint columns in degrees (`j1[deg]`, ...)",
        ),
    ];
    let best = hypotheses
        .iter()
        .filter(|(rms, _, _)| *rms < 0.1 * as_declared)
        .min_by(|a, b| a.0.total_cmp(&b.0));
    Ok(best.map(|(rms, what, fix)| {
        format!(
            "{what} (the starting model registered onto them leaves {:.3} mm instead of {:.3} mm); {fix}",
            rms * 1e3,
            as_declared * 1e3
        )
    }))
}

/// Registers the measurement frames of `stations` (indices into the robot's stations, 0 for a
/// robot with one) in closed form on `samples`, the rest of the model as it is (without its
/// residual predictor), and writes them into `robot`: what `armcomp evaluate` does for data
/// from a station the model does not know (with [`register_stations_on_poses`]). Returns the
/// stations whose points did not span a plane, which keep their frame.
pub fn register_stations(robot: &mut Robot, samples: &[Sample], stations: &[usize]) -> Result<Vec<usize>> {
    if let Some((i, s)) = samples
        .iter()
        .enumerate()
        .find(|(_, s)| s.station >= robot.n_stations())
    {
        return Err(crate::error::Error::InvalidArgument {
            what: format!("sample {}", i + 1),
            reason: format!("station {} is not one of the robot's", s.station + 1),
        });
    }
    // Nothing to register leaves the frames bit for bit (a round trip through the parameter
    // vector's roll-pitch-yaw would move them by rounding).
    if stations.is_empty() {
        return Ok(Vec::new());
    }
    let space = ParameterSpace::new(robot);
    let mut theta = space.initial();
    let problem = Problem::new(robot, &space, samples, Noise::UNIT);
    let (_, _, measured_now) = problem.predict(&theta)?;
    let failed = stations
        .iter()
        .copied()
        .filter(|&k| !register_base(&space, &mut theta, k, samples, &measured_now))
        .collect();
    let names: Vec<String> = match robot.stations() {
        [] => vec![String::new()],
        s => s.iter().map(|s| s.name.clone()).collect(),
    };
    let frames = names
        .into_iter()
        .enumerate()
        .map(|(k, name)| crate::robot::Station {
            name,
            frame: space.base_pose(&theta, k),
        })
        .collect();
    robot.set_stations(frames);
    Ok(failed)
}

/// [`register_stations`], and for a robot that measures poses the frames registered then
/// fitted to the positions and orientations together, each kind weighed by the noise its own
/// residuals give (the evidence): the closed form sees the positions only, and a frame's turn
/// is often better seen by the orientations (poses measured in a small region). What
/// `armcomp evaluate --register` does, so that poses are scored as poses.
pub fn register_stations_on_poses(robot: &mut Robot, samples: &[Sample], stations: &[usize]) -> Result<Vec<usize>> {
    let failed = register_stations(robot, samples, stations)?;
    register_on_poses(robot, samples, stations, &failed)?;
    Ok(failed)
}

/// For a robot that measures poses, fits the frames of `stations` (but those in `failed`) to
/// the positions and orientations together, from where they are: a calibration of the frames
/// alone.
fn register_on_poses(robot: &mut Robot, samples: &[Sample], stations: &[usize], failed: &[usize]) -> Result<()> {
    let registered: Vec<usize> = stations.iter().copied().filter(|k| !failed.contains(k)).collect();
    let oriented = samples
        .iter()
        .any(|s| registered.contains(&s.station) && s.kind() == SampleKind::Position && s.orientation.is_some());
    if !robot.measures_pose() || !oriented {
        return Ok(());
    }
    let space = ParameterSpace::new(robot);
    let params = CalibrationParams {
        identify: (registered.iter())
            .flat_map(|&k| space.station_params(k))
            .map(|i| space.params[i].info.name.clone())
            .collect(),
        // The frame's cost has one minimum near the closed form.
        restarts: 0,
        ..CalibrationParams::default()
    };
    let evidence = EvidenceParams {
        estimate_priors: false,
        ..EvidenceParams::default()
    };
    let (fit, _) = calibrate_with_evidence(robot, samples, &params, &evidence, &mut |_| {})?;
    // A robot of one station keeps its frame outside its (empty) list of stations.
    let frames = (0..robot.n_stations())
        .map(|k| crate::robot::Station {
            name: robot.stations().get(k).map_or_else(String::new, |s| s.name.clone()),
            frame: fit.robot.station_frame(k),
        })
        .collect();
    robot.set_stations(frames);
    Ok(())
}

/// Registers in closed form the frames of the stations of held-out `test` that `train` has no
/// sample of: a fit on `train` knows nothing of them, as a model knows nothing of a station
/// set up after it was calibrated, and `armcomp evaluate` registers those too. Stations whose
/// points do not span a plane keep their frame.
pub fn register_held_out_stations(fitted: &mut Robot, train: &[Sample], test: &[Sample]) -> Result<()> {
    let n = fitted.n_stations();
    let (mut trained, mut tested) = (vec![false; n], vec![false; n]);
    train
        .iter()
        .filter(|s| s.station < n)
        .for_each(|s| trained[s.station] = true);
    test.iter()
        .filter(|s| s.station < n)
        .for_each(|s| tested[s.station] = true);
    let missing: Vec<usize> = (0..n).filter(|&k| tested[k] && !trained[k]).collect();
    if !missing.is_empty() {
        register_stations(fitted, test, &missing)?;
    }
    Ok(())
}
