//! DLR's Agile Justin: the 500 published calibration measurements (Tenhumberg & Bäuml,
//! Humanoids 2021) read as published, and the paper's step-by-step calibration table reproduced
//! on them.
//!
//! The published file has one row per pose: an index, `joints` (a numpy-printed vector of 19
//! joint values in rad: torso 3, right arm 7, left arm 7, head 2) and `markers` (a
//! numpy-printed 2×3 array in m: right-hand marker, then left-hand marker, in the Vicon frame).
//! Each row becomes two samples, one per marker.

use std::path::Path;
use std::time::Instant;

use armcomp_core::algorithms::evaluate::{ErrorStats, position_errors};
use armcomp_core::analysis::diagnose::{DiagnoseParams, DiagnosisReport, diagnose};
use armcomp_core::calibrate::{CalibrationParams, calibrate};
use armcomp_core::data::measurement::Sample;
use armcomp_core::data::split::{Split, holdout, kfold, pose_groups, subset};
use armcomp_core::error::Location;
use armcomp_core::{Error, PredictorSpec, Result, Robot, TrainingSet};
use nalgebra::Vector3;
use serde::Serialize;

/// The published measurements, unchanged.
pub const MEASUREMENTS: &str = include_str!("../../data/agile-justin/measurements.csv");

/// Where [`MEASUREMENTS`] lives in the repository (used in messages).
pub const MEASUREMENTS_PATH: &str = "data/agile-justin/measurements.csv";

/// The robot's joint names in the order of the published `joints` vector.
pub const DATA_JOINTS: [&str; 19] = [
    "t1", "t2", "t3", "r1", "r2", "r3", "r4", "r5", "r6", "r7", "l1", "l2", "l3", "l4", "l5", "l6", "l7", "h1", "h2",
];

/// The measured points in the order of the published `markers` rows.
pub const DATA_MARKERS: [&str; 2] = ["marker_r", "marker_l"];

/// The numbers of a numpy-printed array (`[ 1.0 -2e-3 ...]`, rows in nested brackets).
fn numpy_numbers(text: &str) -> std::result::Result<Vec<f64>, String> {
    let t = text.trim();
    if !(t.starts_with('[') && t.ends_with(']')) {
        return Err(format!(
            "expected a bracketed numpy array, got `{}`",
            t.chars().take(40).collect::<String>()
        ));
    }
    t.replace(['[', ']'], " ")
        .split_whitespace()
        .map(|w| {
            w.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("`{w}` is not a finite number"))
        })
        .collect()
}

/// Reads the published measurement file for `robot`: joint values by [`DATA_JOINTS`] (joints
/// the robot lacks must be zero in every row), the two markers by [`DATA_MARKERS`]. `path`
/// is used in messages.
pub fn parse_measurements(text: &str, path: &Path, robot: &Robot) -> Result<Vec<Sample>> {
    let err = |line: u64, message: String| Error::InputAt {
        location: Location::line(path, line as usize),
        column: None,
        message,
    };
    let tree = robot.tree();
    let names = tree.coordinate_names();
    let mut coord_of_column = Vec::with_capacity(DATA_JOINTS.len());
    for name in DATA_JOINTS {
        coord_of_column.push(names.iter().position(|n| n == name));
    }
    for name in names {
        if !DATA_JOINTS.contains(&name.as_str()) {
            return Err(err(
                1,
                format!(
                    "the robot's joint `{name}` is not in the data (joints: {})",
                    DATA_JOINTS.join(", ")
                ),
            ));
        }
    }
    let mut points = Vec::new();
    for name in DATA_MARKERS {
        match tree.points().iter().position(|p| p.name == name) {
            Some(p) => points.push(p),
            None => {
                return Err(err(
                    1,
                    format!("the robot has no point `{name}` for the data's markers"),
                ));
            }
        }
    }
    let mut reader = csv::ReaderBuilder::new().from_reader(text.as_bytes());
    let headers = reader
        .headers()
        .map_err(|e| err(1, format!("cannot read the header: {e}")))?;
    let column = |name: &str| {
        headers.iter().position(|h| h.trim() == name).ok_or_else(|| {
            err(
                1,
                format!(
                    "no `{name}` column (header: {})",
                    headers.iter().collect::<Vec<_>>().join(",")
                ),
            )
        })
    };
    let (joints_col, markers_col) = (column("joints")?, column("markers")?);
    let mut samples = Vec::new();
    for record in reader.records() {
        let record = record.map_err(|e| err(e.position().map_or(0, |p| p.line()), e.to_string()))?;
        let line = record.position().map_or(0, |p| p.line());
        let field = |col: usize, name: &str| {
            record
                .get(col)
                .ok_or_else(|| err(line, format!("missing the `{name}` field")))
                .and_then(|f| numpy_numbers(f).map_err(|m| err(line, format!("`{name}`: {m}"))))
        };
        let joints = field(joints_col, "joints")?;
        if joints.len() != DATA_JOINTS.len() {
            return Err(err(
                line,
                format!("`joints`: expected {} values, got {}", DATA_JOINTS.len(), joints.len()),
            ));
        }
        let markers = field(markers_col, "markers")?;
        if markers.len() != 3 * DATA_MARKERS.len() {
            return Err(err(
                line,
                format!(
                    "`markers`: expected a {}x3 array, got {} values",
                    DATA_MARKERS.len(),
                    markers.len()
                ),
            ));
        }
        let mut q = vec![0.0; names.len()];
        for (k, (&v, coord)) in joints.iter().zip(&coord_of_column).enumerate() {
            match coord {
                Some(c) => q[*c] = v,
                None if v != 0.0 => {
                    return Err(err(
                        line,
                        format!(
                            "`joints`: joint `{}` is {v} rad but the robot does not model it",
                            DATA_JOINTS[k]
                        ),
                    ));
                }
                None => {}
            }
        }
        for (m, &point) in points.iter().enumerate() {
            samples.push(Sample {
                q: q.clone(),
                point,
                position: Vector3::new(markers[3 * m], markers[3 * m + 1], markers[3 * m + 2]),
                orientation: None,
                payload: None,
                temperature: None,
                torque: None,
                fixed_point: None,
                plane: None,
                sensors: Default::default(),
                station: 0,
                position_std: None,
            });
        }
    }
    if samples.is_empty() {
        return Err(err(1, "no measurements".into()));
    }
    Ok(samples)
}

/// A row of the paper's table: residual TCP error (mm).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PublishedRow {
    /// Mean (mm).
    pub mean_mm: f64,
    /// Standard deviation (mm).
    pub std_mm: f64,
    /// Largest (mm).
    pub max_mm: f64,
}

/// One step of the paper's calibration: what is identified (cumulative) and what it reports.
#[derive(Debug, Clone, Copy)]
pub struct Step {
    /// Short label.
    pub label: &'static str,
    /// The parameters identified in this step (see `ParameterSpace::select`).
    pub identify: &'static [&'static str],
    /// The paper's row.
    pub published: PublishedRow,
}

const fn row(mean_mm: f64, std_mm: f64, max_mm: f64) -> PublishedRow {
    PublishedRow {
        mean_mm,
        std_mm,
        max_mm,
    }
}

/// The paper's table, each step adding to the previous one.
pub const STEPS: [Step; 5] = [
    Step {
        label: "frames only (base + markers)",
        identify: &["base", "markers"],
        published: row(21.33, 9.71, 63.41),
    },
    Step {
        label: "+ joint offsets",
        identify: &["base", "markers", "offsets"],
        published: row(18.18, 7.8, 45.9),
    },
    Step {
        label: "+ all DH parameters",
        identify: &["base", "markers", "geometry"],
        published: row(10.5, 5.74, 36.37),
    },
    Step {
        label: "+ joint compliance",
        identify: &["base", "markers", "geometry", "joint_compliance"],
        published: row(5.64, 2.57, 12.83),
    },
    Step {
        label: "+ lateral compliance",
        identify: &["base", "markers", "geometry", "joint_compliance", "lateral_compliance"],
        published: row(PAPER_FULL_MODEL_MEAN_MM, 1.71, 8.23),
    },
];

/// Tracker noise assumed by the fits (m per axis): Vicon markers on a moving humanoid.
pub const MEASUREMENT_STD: f64 = 1e-3;

/// The paper's held-out mean of its full model (mm): the last step's published figure.
pub const PAPER_FULL_MODEL_MEAN_MM: f64 = 3.12;

/// The most tool-chosen poses with which the learning curve's target (the paper's full-model
/// mean) is to be reached.
pub const TARGET_POSES: usize = 80;

/// The residual predictor of the pipeline's last step: ridge regression on the joint angles'
/// sines and cosines (degree 1), lightly regularised.
pub const PREDICTOR: armcomp_learn::RidgeSpec = armcomp_learn::RidgeSpec {
    lambda: 0.05,
    degree: 1,
    trig: true,
};

/// Calibrates each selection (see `ParameterSpace::select`) in turn on `train`, each starting
/// from the previous result; returns the robot after each with the seconds its step took.
fn calibrate_sequence(robot: &Robot, train: &[Sample], selections: &[Vec<String>]) -> Result<Vec<(Robot, f64)>> {
    let mut out: Vec<(Robot, f64)> = Vec::with_capacity(selections.len());
    for identify in selections {
        let params = CalibrationParams {
            identify: identify.clone(),
            measurement_std: MEASUREMENT_STD,
            ..CalibrationParams::default()
        };
        let start = out.last().map_or(robot, |(r, _)| r);
        let started = Instant::now();
        let calibrated = calibrate(start, train, &params, &mut |_| {})?.robot;
        out.push((calibrated, started.elapsed().as_secs_f64()));
    }
    Ok(out)
}

/// The paper's full model (the last step) fitted on `train` step by step, as the table does.
pub fn fit_full_model(robot: &Robot, train: &[Sample]) -> Result<Robot> {
    let selections: Vec<Vec<String>> = STEPS
        .iter()
        .map(|s| s.identify.iter().map(|w| w.to_string()).collect())
        .collect();
    let mut robots = calibrate_sequence(robot, train, &selections)?;
    Ok(robots.pop().expect("five steps").0)
}

/// A parameter group of the paper's leave-one-out analysis (full model minus that group).
#[derive(Debug, Clone, Copy)]
pub struct ParamGroup {
    /// The paper's name of the group.
    pub label: &'static str,
    /// The parameters it stands for (see `ParameterSpace::select`).
    pub identify: &'static str,
    /// The paper's mean residual (mm) of the full model without the group.
    pub paper_mean_mm: f64,
}

/// The full model's parameter groups, in the order of the paper's leave-one-out ranking (the
/// group whose removal hurts most first).
pub const GROUPS: [ParamGroup; 6] = [
    ParamGroup {
        label: "joint compliance (kappa_theta)",
        identify: "joint_compliance",
        paper_mean_mm: 9.09,
    },
    ParamGroup {
        label: "DH alpha",
        identify: "*.alpha",
        paper_mean_mm: 6.48,
    },
    ParamGroup {
        label: "DH theta (joint offsets)",
        identify: "*.theta",
        paper_mean_mm: 6.35,
    },
    ParamGroup {
        label: "lateral compliance (kappa_alpha, kappa_beta)",
        identify: "lateral_compliance",
        paper_mean_mm: 4.85,
    },
    ParamGroup {
        label: "DH r (a)",
        identify: "*.a",
        paper_mean_mm: 4.33,
    },
    ParamGroup {
        label: "DH d",
        identify: "*.d",
        paper_mean_mm: 3.46,
    },
];

/// The full model's steps (frames; geometry; + joint compliance; + lateral compliance) with
/// `left_out` (a [`GROUPS`] entry's `identify`) taken out of every step.
fn steps_without(left_out: &str) -> Vec<Vec<String>> {
    let frames = ["base", "markers"];
    let geometry = ["*.theta", "*.alpha", "*.a", "*.d"];
    let mut steps: Vec<Vec<&str>> = vec![frames.to_vec()];
    let mut all: Vec<&str> = frames.iter().chain(&geometry).copied().collect();
    steps.push(all.clone());
    for model in ["joint_compliance", "lateral_compliance"] {
        all.push(model);
        steps.push(all.clone());
    }
    steps
        .into_iter()
        .map(|s| s.into_iter().filter(|w| *w != left_out).map(String::from).collect())
        .collect()
}

/// Held-out errors on `split` of the full model without each of [`GROUPS`] in turn (same
/// order), each calibrated step by step on the training poses.
pub fn leave_one_out(robot: &Robot, samples: &[Sample], split: &Split) -> Result<Vec<ErrorStats>> {
    let train = subset(samples, &split.train);
    let test = subset(samples, &split.test);
    GROUPS
        .iter()
        .map(|g| {
            let robots = calibrate_sequence(robot, &train, &steps_without(g.identify))?;
            let (last, _) = robots.last().expect("four steps");
            Ok(ErrorStats::from_errors(&position_errors(last, &test)))
        })
        .collect()
}

/// `robot` without its error models: the rigid model whose frames the paper's first step fits.
pub fn rigid(robot: &Robot) -> Result<Robot> {
    let mut file = robot.to_file();
    file.error_models.clear();
    robot.rebuild(file)
}

/// `armcomp diagnose` on the data, starting from the frames-only model: the rigid robot whose
/// measurement frame and markers are identified, every candidate effect of `plugins` tried on
/// top (k-fold held-out scores, `folds` folds split by pose with `seed`), at most `max_steps`
/// effects accepted.
pub fn diagnose_from_frames(
    robot: &Robot,
    samples: &[Sample],
    plugins: &[armcomp_core::PluginInfo],
    folds: usize,
    seed: u64,
    max_steps: usize,
) -> Result<DiagnosisReport> {
    let params = DiagnoseParams {
        folds,
        seed,
        calibration: CalibrationParams {
            identify: STEPS[0].identify.iter().map(|s| s.to_string()).collect(),
            measurement_std: MEASUREMENT_STD,
            ..CalibrationParams::default()
        },
        max_steps,
        ..DiagnoseParams::default()
    };
    Ok(diagnose(&rigid(robot)?, samples, plugins, None, &params, &|_| {})?.report)
}

/// Residual statistics of one step on the fitted and the held-out poses.
#[derive(Debug, Clone, Serialize)]
pub struct StepResult {
    /// The step's label.
    pub step: String,
    /// On the poses it was fitted to.
    pub train: ErrorStats,
    /// On the held-out poses.
    pub test: ErrorStats,
    /// The paper's row (none for steps beyond the paper).
    pub published: Option<PublishedRow>,
    /// Seconds this step's identification took (for the predictor: fitting it and predicting
    /// the held-out poses).
    pub seconds: f64,
    /// Measured-minus-modelled position of every held-out sample (m, measurement frame), in
    /// the order of the split's held-out indices; for plots, not printed.
    #[serde(skip)]
    pub test_errors: Vec<Vector3<f64>>,
}

/// Label of the row that adds a residual predictor over the last step.
pub const PREDICTOR_STEP: &str = "+ residual predictor";

/// Measured-minus-modelled positions (m), one per sample.
type Errors = Vec<Vector3<f64>>;

/// Per-pose rows of a predictor: the samples of each pose, joint values, residuals.
type PoseRows = (Vec<Vec<usize>>, Vec<f64>, Vec<f64>);

/// One step's errors on one split: fitted, held-out, and the seconds the step took.
struct StepErrors {
    train: Errors,
    test: Errors,
    seconds: f64,
}

/// Fitted and held-out errors of every step on one split, and of `predictor` (when given)
/// learning the last step's residual on the fitted poses.
fn split_errors(
    robot: &Robot,
    train: &[Sample],
    test: &[Sample],
    steps: &[Step],
    predictor: Option<&dyn PredictorSpec>,
) -> Result<Vec<StepErrors>> {
    let selections: Vec<Vec<String>> = steps
        .iter()
        .map(|s| s.identify.iter().map(|w| w.to_string()).collect())
        .collect();
    let robots = calibrate_sequence(robot, train, &selections)?;
    let mut out: Vec<_> = robots
        .iter()
        .map(|(r, seconds)| StepErrors {
            train: position_errors(r, train),
            test: position_errors(r, test),
            seconds: *seconds,
        })
        .collect();
    if let (Some(p), Some((last, _))) = (predictor, robots.last()) {
        let started = Instant::now();
        let test_errors = residual_corrected_errors(last, train, test, p)?;
        let seconds = started.elapsed().as_secs_f64();
        out.push(StepErrors {
            train: residual_corrected_errors(last, train, train, p)?,
            test: test_errors,
            seconds,
        });
    }
    Ok(out)
}

/// Runs `steps` (and `predictor` over the last) on one split of `samples`.
pub fn step_table(
    robot: &Robot,
    samples: &[Sample],
    split: &Split,
    steps: &[Step],
    predictor: Option<&dyn PredictorSpec>,
) -> Result<Vec<StepResult>> {
    let train = subset(samples, &split.train);
    let test = subset(samples, &split.test);
    let errors = split_errors(robot, &train, &test, steps, predictor)?;
    Ok(errors
        .iter()
        .enumerate()
        .map(|(k, e)| StepResult {
            step: step_label(steps, k).to_string(),
            train: ErrorStats::from_errors(&e.train),
            test: ErrorStats::from_errors(&e.test),
            published: steps.get(k).map(|s| s.published),
            seconds: e.seconds,
            test_errors: e.test.clone(),
        })
        .collect())
}

/// The label of row `k` of a table of `steps` (the predictor's row after the steps).
fn step_label(steps: &[Step], k: usize) -> &'static str {
    steps.get(k).map_or(PREDICTOR_STEP, |s| s.label)
}

/// One row of the k-fold table: every sample's held-out error, pooled over the folds.
#[derive(Debug, Clone)]
pub struct KfoldErrors {
    /// The step's label.
    pub step: String,
    /// Measured-minus-modelled position of every sample (m, measurement frame) while its pose
    /// was held out, fold after fold in the folds' held-out order.
    pub test_errors: Vec<Vector3<f64>>,
    /// Poses fitted in each fold (the smallest fold's count when folds differ).
    pub train_poses: usize,
    /// Seconds of the step, summed over the folds.
    pub seconds: f64,
}

/// The held-out errors of every step (and of `predictor`) over `k` folds, each pose held out
/// once, pooled.
pub fn kfold_errors(
    robot: &Robot,
    samples: &[Sample],
    k: usize,
    seed: u64,
    steps: &[Step],
    predictor: Option<&dyn PredictorSpec>,
) -> Result<Vec<KfoldErrors>> {
    let mut pooled: Vec<KfoldErrors> = Vec::new();
    for split in kfold(samples, k, seed)? {
        let train = subset(samples, &split.train);
        let test = subset(samples, &split.test);
        let train_poses = pose_groups(&train).len();
        let errors = split_errors(robot, &train, &test, steps, predictor)?;
        for (i, e) in errors.into_iter().enumerate() {
            if pooled.len() <= i {
                pooled.push(KfoldErrors {
                    step: step_label(steps, i).to_string(),
                    test_errors: Vec::new(),
                    train_poses,
                    seconds: 0.0,
                });
            }
            let row = &mut pooled[i];
            row.test_errors.extend(e.test);
            row.train_poses = row.train_poses.min(train_poses);
            row.seconds += e.seconds;
        }
    }
    Ok(pooled)
}

/// The fixed 250 / 250 split of the poses used for the held-out table.
pub fn half_split(samples: &[Sample], seed: u64) -> Result<Split> {
    holdout(samples, 0.5, seed)
}

/// Learns what a calibrated model leaves, on the fitted poses: one row per pose, its joint
/// values in, the measured-minus-modelled positions of both markers (m, measurement frame)
/// out. Returns the corrected errors on `test` (same order as `test`).
pub fn residual_corrected_errors(
    robot: &Robot,
    train: &[Sample],
    test: &[Sample],
    predictor: &dyn PredictorSpec,
) -> Result<Vec<Vector3<f64>>> {
    let rows = |samples: &[Sample]| -> Result<PoseRows> {
        let groups = pose_groups(samples);
        let errors = position_errors(robot, samples);
        let mut inputs = Vec::new();
        let mut targets = Vec::new();
        for g in &groups {
            if g.len() != DATA_MARKERS.len() {
                return Err(Error::Dimension {
                    what: format!("markers measured at the pose of sample {}", g[0] + 1),
                    expected: DATA_MARKERS.len(),
                    got: g.len(),
                });
            }
            inputs.extend_from_slice(&samples[g[0]].q);
            for &i in g {
                targets.extend_from_slice(errors[i].as_slice());
            }
        }
        Ok((groups, inputs, targets))
    };
    let (_, inputs, targets) = rows(train)?;
    let nq = robot.tree().nq();
    let fitted = predictor.fit(&TrainingSet {
        inputs: &inputs,
        targets: &targets,
        n_inputs: nq,
        n_outputs: 3 * DATA_MARKERS.len(),
        input_ranges: robot.tree().coordinate_limits(),
    })?;
    let (groups, inputs, targets) = rows(test)?;
    let mut out = vec![Vector3::zeros(); test.len()];
    let mut predicted = vec![0.0; 3 * DATA_MARKERS.len()];
    let mut scratch = Vec::new();
    for (k, g) in groups.iter().enumerate() {
        fitted.predict_into(&inputs[k * nq..(k + 1) * nq], &mut predicted, &mut scratch);
        for (m, &i) in g.iter().enumerate() {
            let t = &targets[(k * DATA_MARKERS.len() + m) * 3..][..3];
            let p = &predicted[3 * m..3 * m + 3];
            out[i] = Vector3::new(t[0] - p[0], t[1] - p[1], t[2] - p[2]);
        }
    }
    Ok(out)
}
