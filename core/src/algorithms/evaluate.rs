//! Accuracy of a model on measurements: per-sample position errors and their statistics.

use nalgebra::Vector3;
use rayon::prelude::*;
use serde::Serialize;

use crate::data::measurement::Sample;
use crate::error::{Error, Result};
use crate::kinematics::point_kinematics::PointKinematics;
use crate::plugin::{FitControl, FittedPredictor, PredictorSpec, TrainingSet};
use crate::robot::robot_file::PredictorFrame;
use crate::robot::{Conditions, Robot};

/// Statistics of 3-D position errors, in millimetres (the unit people compare arms in).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ErrorStats {
    /// Number of measured positions.
    pub n: usize,
    /// Mean of the 3-D error norms (mm).
    pub mean_mm: f64,
    /// Sample standard deviation (n − 1) of the 3-D error norms (mm).
    pub std_mm: f64,
    /// Root mean square of the 3-D error norms (mm).
    pub rms_mm: f64,
    /// Largest 3-D error norm (mm).
    pub max_mm: f64,
    /// Mean absolute error per axis of the measurement frame (mm).
    pub mean_abs_mm: AxisErrors,
}

/// The errors of one station's samples, when the data come from several.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct StationStats {
    /// The station's name.
    pub station: String,
    /// Its samples' errors.
    #[serde(flatten)]
    pub stats: ErrorStats,
}

/// [`ErrorStats`] of `errors` (one per sample of `samples`, m) per station of `robot` that has
/// samples, in the robot's order; empty when the robot has one station.
pub fn per_station(robot: &Robot, samples: &[Sample], errors: &[Vector3<f64>]) -> Vec<StationStats> {
    if robot.stations().len() < 2 {
        return Vec::new();
    }
    robot
        .stations()
        .iter()
        .enumerate()
        .filter_map(|(k, station)| {
            let e: Vec<Vector3<f64>> = samples
                .iter()
                .zip(errors)
                .filter(|(s, _)| s.station == k)
                .map(|(_, e)| *e)
                .collect();
            // A station without rows here (data of other set-ups) has nothing to say.
            (!e.is_empty()).then(|| StationStats {
                station: station.name.clone(),
                stats: ErrorStats::from_errors(&e),
            })
        })
        .collect()
}

/// One value per axis (mm).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AxisErrors {
    /// Along x.
    pub x: f64,
    /// Along y.
    pub y: f64,
    /// Along z.
    pub z: f64,
}

impl ErrorStats {
    /// Statistics of error vectors given in metres; all zeros for an empty list.
    pub fn from_errors(errors: &[Vector3<f64>]) -> Self {
        let n = errors.len();
        let mut out = ErrorStats {
            n,
            mean_mm: 0.0,
            std_mm: 0.0,
            rms_mm: 0.0,
            max_mm: 0.0,
            mean_abs_mm: AxisErrors { x: 0.0, y: 0.0, z: 0.0 },
        };
        if n == 0 {
            return out;
        }
        let norms: Vec<f64> = errors.iter().map(|e| e.norm() * 1e3).collect();
        let nf = n as f64;
        out.mean_mm = norms.iter().sum::<f64>() / nf;
        out.rms_mm = (norms.iter().map(|v| v * v).sum::<f64>() / nf).sqrt();
        out.max_mm = norms.iter().copied().fold(0.0, f64::max);
        if n > 1 {
            out.std_mm = (norms.iter().map(|v| (v - out.mean_mm).powi(2)).sum::<f64>() / (nf - 1.0)).sqrt();
        }
        let abs = |k: usize| errors.iter().map(|e| e[k].abs()).sum::<f64>() / nf * 1e3;
        out.mean_abs_mm = AxisErrors {
            x: abs(0),
            y: abs(1),
            z: abs(2),
        };
        out
    }
}

/// Statistics of orientation errors (the angle of `log(R_measᵀ R̂)`), in degrees.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AngleStats {
    /// Number of measured orientations.
    pub n: usize,
    /// Mean angle (deg).
    pub mean_deg: f64,
    /// Root mean square angle (deg).
    pub rms_deg: f64,
    /// Largest angle (deg).
    pub max_deg: f64,
}

impl AngleStats {
    /// Statistics of angles given in radians; all zeros for an empty list.
    pub fn from_angles(angles: &[f64]) -> Self {
        let n = angles.len();
        let nf = n.max(1) as f64;
        let deg: Vec<f64> = angles.iter().map(|a| a.to_degrees()).collect();
        AngleStats {
            n,
            mean_deg: deg.iter().sum::<f64>() / nf,
            rms_deg: (deg.iter().map(|v| v * v).sum::<f64>() / nf).sqrt(),
            max_deg: deg.iter().copied().fold(0.0, f64::max),
        }
    }
}

/// The orientation error (rad, the angle between measured and modelled) of each sample that
/// has a measured orientation, through the robot's full model and measurement frame; `None`
/// for the others.
pub fn orientation_errors(robot: &Robot, samples: &[Sample]) -> Vec<Option<f64>> {
    orientation_error_vectors(robot, samples)
        .into_iter()
        .map(|e| e.map(|e| e.norm()))
        .collect()
}

/// The orientation error of each sample that has a measured orientation as a rotation vector
/// (rad, measurement frame): the turn from the modelled orientation to the measured one,
/// `log(R_measured · R_modelledᵀ)`, whose length is [`orientation_errors`]'s angle; `None` for
/// the others.
pub fn orientation_error_vectors(robot: &Robot, samples: &[Sample]) -> Vec<Option<Vector3<f64>>> {
    let mut ws = robot.workspace();
    samples
        .iter()
        .map(|s| {
            let measured = s.orientation?;
            robot.forward_with_into(robot.tree(), robot.error_values(), &s.q, Conditions::of(s), &mut ws);
            let modelled = robot.station_frame(s.station).rotation * ws.frames.point[s.point].rotation;
            Some((measured * modelled.inverse()).scaled_axis())
        })
        .collect()
}

/// Measured minus modelled position of each sample (m, measurement frame), through the
/// robot's full model, its measurement-frame guess and, when the file carries one, its fitted
/// residual predictor.
pub fn position_errors(robot: &Robot, samples: &[Sample]) -> Vec<Vector3<f64>> {
    let mut errors = model_errors(robot, samples);
    if let Some(p) = robot.predictor() {
        subtract_predictions(robot, p, robot.predictor_frame(), samples, &mut errors);
    }
    errors
}

/// Subtracts `predictor`'s prediction at each sample, its outputs in `frame`, from the
/// sample's error (measurement frame of its station) in `errors`.
fn subtract_predictions(
    robot: &Robot,
    predictor: &dyn FittedPredictor,
    frame: PredictorFrame,
    samples: &[Sample],
    errors: &mut [Vector3<f64>],
) {
    let (mut out, mut scratch, mut input) = ([0.0; 3], Vec::new(), Vec::new());
    for (e, s) in errors.iter_mut().zip(samples) {
        predictor_input_into(robot, predictor.n_inputs(), &s.q, s.point, &mut input);
        predictor.predict_into(&input, &mut out, &mut scratch);
        let predicted = Vector3::from(out);
        *e -= match frame {
            PredictorFrame::Base => robot.station_frame(s.station).rotation * predicted,
            PredictorFrame::Measurement => predicted,
        };
    }
}

/// The errors `robot`'s physical model and `predictor` (fitted on what that model leaves, its
/// outputs in the base frame) leave together at `samples`: the one footing of a predictor's
/// training error and of its cross-validated one ([`cross_validated_predictor_errors`]).
pub fn predictor_errors(robot: &Robot, predictor: &dyn FittedPredictor, samples: &[Sample]) -> Vec<Vector3<f64>> {
    let mut errors = model_errors(robot, samples);
    subtract_predictions(robot, predictor, PredictorFrame::Base, samples, &mut errors);
    errors
}

/// How well `spec`, fitted on what `robot`'s physical model leaves, predicts poses it was not
/// fitted on: every sample held out once in `folds`-fold cross-validation, folded as `by`
/// says (by pose, by station, by a column; shuffled by `seed`), the errors after the held-out
/// predictions pooled. A predictor whose training error is far below this has memorised its
/// rows. Returns the statistics and how the folds were drawn. `control` sees the folds done
/// (stage `"folds"`) and stops every fold's training.
pub fn cross_validated_predictor_errors(
    robot: &Robot,
    spec: &dyn PredictorSpec,
    samples: &[Sample],
    folds: usize,
    seed: u64,
    by: &crate::data::split::FoldBy,
    control: &FitControl<'_>,
) -> Result<(ErrorStats, crate::data::split::Folding)> {
    let (splits, folding) = crate::data::split::folds(samples, folds, seed, by)?;
    // The folds train at once: each stops with the others, the count of folds done is the progress.
    let fold_control = FitControl {
        progress: None,
        cancel: control.cancel.clone(),
    };
    let done = std::sync::atomic::AtomicUsize::new(0);
    let parts: Vec<Vec<Vector3<f64>>> = splits
        .par_iter()
        .map(|split| {
            let train = crate::data::split::subset(samples, &split.train);
            let test = crate::data::split::subset(samples, &split.test);
            let fitted = fit_residual_predictor(robot, spec, &train, &fold_control)?;
            let d = done.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
            control.report("folds", d, splits.len());
            Ok(predictor_errors(robot, fitted.as_ref(), &test))
        })
        .collect::<Result<_>>()?;
    Ok((ErrorStats::from_errors(&parts.concat()), folding))
}

/// Writes into `input` what a residual predictor with `n_inputs` inputs takes at joint values
/// `q` for point `point` of `robot`: the joint values, followed, for a predictor fitted on
/// several points (`n_inputs` = nq + 3), by the point's position in its body's frame (m).
pub fn predictor_input_into(robot: &Robot, n_inputs: usize, q: &[f64], point: usize, input: &mut Vec<f64>) {
    input.clear();
    input.extend_from_slice(q);
    if n_inputs == q.len() + 3 {
        input.extend(robot.tree().points()[point].local.translation.vector.iter());
    }
}

/// Measured minus modelled position of each sample (m, measurement frame) through the physical
/// model alone (chain and error models, no predictor): what a residual predictor learns.
/// Samples give points of `robot` and configurations of its size.
pub fn model_errors(robot: &Robot, samples: &[Sample]) -> Vec<Vector3<f64>> {
    if robot.error_models().is_empty() {
        return rigid_model_errors(robot, samples);
    }
    let mut ws = robot.workspace();
    samples
        .iter()
        .map(|s| {
            robot.forward_with_into(robot.tree(), robot.error_values(), &s.q, Conditions::of(s), &mut ws);
            let p = ws.frames.point[s.point].translation.vector;
            s.position - robot.station_frame(s.station).transform_point(&p.into()).coords
        })
        .collect()
}

/// [`model_errors`] of a rigid robot, whose points do not depend on the conditions: the
/// measured points' batched kinematics, one configuration per run of samples at the same joint
/// values (the markers of one pose).
fn rigid_model_errors(robot: &Robot, samples: &[Sample]) -> Vec<Vector3<f64>> {
    let mut points: Vec<usize> = samples.iter().map(|s| s.point).collect();
    points.sort_unstable();
    points.dedup();
    let plan = PointKinematics::for_points(robot.tree(), &points).expect("samples measure points of the robot");
    // Each tree point's place among the measured ones.
    let mut slot = vec![0; robot.tree().points().len()];
    for (k, &p) in points.iter().enumerate() {
        slot[p] = k;
    }
    let (mut qs, mut config, mut n) = (Vec::new(), Vec::with_capacity(samples.len()), 0);
    for (i, s) in samples.iter().enumerate() {
        if i == 0 || s.q != samples[i - 1].q {
            qs.extend_from_slice(&s.q);
            n += 1;
        }
        config.push(n - 1);
    }
    let width = 3 * points.len();
    let mut positions = vec![0.0; n * width];
    plan.point_positions_many_into(n, &qs, &mut positions, &mut plan.many_workspace())
        .expect("samples hold configurations of the robot's size");
    samples
        .iter()
        .zip(config)
        .map(|(s, c)| {
            let at = c * width + 3 * slot[s.point];
            let p = Vector3::from_column_slice(&positions[at..at + 3]);
            s.position - robot.station_frame(s.station).transform_point(&p.into()).coords
        })
        .collect()
}

/// Fits `spec` on what the physical model of `robot` leaves on `samples`: joint values in,
/// the position residual (m, rotated from the measurement frame of its station into the base
/// frame: [`PredictorFrame::Base`]) out. When the samples measure several points,
/// each point's position in its body's frame (m) is three more inputs, so one predictor
/// learns how the residual varies across the points (see [`predictor_input_into`]). `control`
/// sees the training's progress and can stop it.
pub fn fit_residual_predictor(
    robot: &Robot,
    spec: &dyn PredictorSpec,
    samples: &[Sample],
    control: &FitControl<'_>,
) -> Result<Box<dyn FittedPredictor>> {
    let Some(first) = samples.first() else {
        return Err(Error::InvalidArgument {
            what: "measurements".into(),
            reason: "none to learn the residual from".into(),
        });
    };
    let nq = robot.tree().nq();
    let n_inputs = if samples.iter().any(|s| s.point != first.point) {
        nq + 3
    } else {
        nq
    };
    let mut inputs = Vec::with_capacity(samples.len() * n_inputs);
    let mut input = Vec::new();
    for s in samples {
        predictor_input_into(robot, n_inputs, &s.q, s.point, &mut input);
        inputs.extend_from_slice(&input);
    }
    let mut ranges = robot.tree().coordinate_limits().to_vec();
    ranges.resize(n_inputs, None);
    // In the base frame, so that the predictor follows the robot to another station.
    let targets: Vec<f64> = model_errors(robot, samples)
        .iter()
        .zip(samples)
        .flat_map(|(e, s)| (robot.station_frame(s.station).rotation.inverse() * e).data.0[0])
        .collect();
    spec.fit_with(
        &TrainingSet {
            inputs: &inputs,
            targets: &targets,
            n_inputs,
            n_outputs: 3,
            input_ranges: &ranges,
        },
        control,
    )
}

/// How tightly a model puts the samples of one fixed point together.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FixedPointSpread {
    /// The fixed point's name.
    pub name: String,
    /// Its samples.
    pub n: usize,
    /// Mean distance of its modelled points from their mean (mm): the consistency of MUKCa.
    pub mean_mm: f64,
    /// Largest distance of a modelled point from their mean (mm).
    pub max_mm: f64,
}

/// A known distance between two fixed points against the model's.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DistanceCheck {
    /// The two fixed points.
    pub between: [String; 2],
    /// The known distance (mm).
    pub known_mm: f64,
    /// The distance between the means of their modelled points (mm).
    pub modelled_mm: f64,
    /// `|modelled − known|` (mm).
    pub error_mm: f64,
}

/// What a model makes of fixed-point samples: each fixed point's spread and the known
/// distances between them.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FixedPointEvaluation {
    /// Per fixed point, in order of first appearance.
    pub points: Vec<FixedPointSpread>,
    /// The points' `mean_mm` weighted by their sample counts (mm).
    pub spread_mm: f64,
    /// Per known distance of the robot file whose two points the samples hold.
    pub distances: Vec<DistanceCheck>,
}

/// Evaluates `robot` on fixed-point samples whose position errors (measured minus modelled,
/// the measured position unused and zero) are `errors`: since a fixed point's position is not
/// measured, the mean of its modelled points stands for it. Rewrites each fixed-point sample's
/// error as that mean minus its modelled point; `None` when no sample names a fixed point.
pub fn evaluate_fixed_points(
    robot: &Robot,
    samples: &[Sample],
    errors: &mut [Vector3<f64>],
) -> Option<FixedPointEvaluation> {
    let mut names: Vec<&str> = Vec::new();
    let group: Vec<Option<usize>> = samples
        .iter()
        .map(|s| {
            let name = s.fixed_point.as_deref()?;
            Some(names.iter().position(|n| *n == name).unwrap_or_else(|| {
                names.push(name);
                names.len() - 1
            }))
        })
        .collect();
    if names.is_empty() {
        return None;
    }
    let modelled: Vec<Vector3<f64>> = samples.iter().zip(errors.iter()).map(|(s, e)| s.position - e).collect();
    let mut sums = vec![(Vector3::zeros(), 0usize); names.len()];
    for (g, p) in group.iter().zip(&modelled) {
        if let Some(g) = g {
            sums[*g].0 += p;
            sums[*g].1 += 1;
        }
    }
    let means: Vec<Vector3<f64>> = sums.iter().map(|(s, n)| s / *n as f64).collect();
    let mut points: Vec<FixedPointSpread> = names
        .iter()
        .zip(&sums)
        .map(|(name, (_, n))| FixedPointSpread {
            name: name.to_string(),
            n: *n,
            mean_mm: 0.0,
            max_mm: 0.0,
        })
        .collect();
    for ((g, p), e) in group.iter().zip(&modelled).zip(errors.iter_mut()) {
        if let Some(g) = *g {
            *e = means[g] - p;
            let d = e.norm() * 1e3;
            points[g].mean_mm += d / points[g].n as f64;
            points[g].max_mm = points[g].max_mm.max(d);
        }
    }
    let n: usize = points.iter().map(|p| p.n).sum();
    let spread_mm = points.iter().map(|p| p.mean_mm * p.n as f64).sum::<f64>() / n as f64;
    let distances = robot
        .known_distances()
        .iter()
        .filter_map(|d| {
            let a = names.iter().position(|n| *n == d.between[0])?;
            let b = names.iter().position(|n| *n == d.between[1])?;
            let modelled_mm = (means[a] - means[b]).norm() * 1e3;
            Some(DistanceCheck {
                between: d.between.clone(),
                known_mm: d.mm,
                modelled_mm,
                error_mm: (modelled_mm - d.mm).abs(),
            })
        })
        .collect();
    Some(FixedPointEvaluation {
        points,
        spread_mm,
        distances,
    })
}
