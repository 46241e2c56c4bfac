//! The papers' protocols run on the built-in twins with hidden truth (`armcomp demo`): every
//! number is computed on each run; the papers' published values are carried as references.

pub mod agile_justin;
pub mod industrial;
pub mod plots;
pub mod report;
pub mod rock_drill;
pub mod seed_sweep;

use std::fmt;
use std::time::Instant;

use armcomp_core::algorithms::compensate::{CompensationMode, CompensationParams, Compensator, mid_range};
use armcomp_core::algorithms::evaluate::ErrorStats;
use armcomp_core::algorithms::ik::{IkParams, IkTarget, IkWorkspace, solve_ik};
use armcomp_core::algorithms::simulate::{SimulateParams, simulate};
use armcomp_core::data::measurement::Sample;
use armcomp_core::plugin::FittedPredictor;
use armcomp_core::{Result, Robot};
use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use serde::Serialize;

/// A published value of the paper a row reproduces.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PaperValue {
    /// Mean absolute error along the table's axis, or the mean 3-D error (mm).
    pub mean_mm: f64,
    /// The variance the paper gives, when it gives one (mm²).
    pub variance_mm2: Option<f64>,
}

/// One compensation pipeline's result on the test targets.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Row {
    /// What was done.
    pub name: String,
    /// The paper's value for the same pipeline, when it has one.
    pub paper: Option<PaperValue>,
    /// Training poses used (0 for models that learn nothing).
    pub training_poses: usize,
    /// Identification and training time (s).
    pub training_s: f64,
    /// Mean |z| error (mm).
    pub mean_abs_z_mm: f64,
    /// Variance of the error per axis, averaged over x, y, z (mm²), as the paper's Table I.
    pub variance_mm2: f64,
    /// Mean 3-D error (mm).
    pub mean_mm: f64,
    /// Largest 3-D error (mm).
    pub max_mm: f64,
    /// Error of every test target (mm, measurement frame), for plots.
    pub errors_mm: Vec<[f64; 3]>,
}

/// What a table's paper column measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PaperMetric {
    /// Mean absolute error along z (the deflection paper's Table I).
    MeanAbsZ,
    /// Mean 3-D error (the ANN paper's accuracy).
    Mean3d,
}

/// A table of rows with what they were computed on.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Table {
    /// Title.
    pub title: String,
    /// How the data were made.
    pub setup: String,
    /// Measurement noise per axis (mm).
    pub noise_mm: f64,
    /// Mean |z| of the measurement noise alone (mm): σ·√(2/π).
    pub noise_mean_abs_z_mm: f64,
    /// What the rows' paper values measure.
    pub paper_metric: PaperMetric,
    /// The rows.
    pub rows: Vec<Row>,
}

impl Table {
    /// The row named `name`.
    pub fn row(&self, name: &str) -> Option<&Row> {
        self.rows.iter().find(|r| r.name == name)
    }
}

/// The table as text, the paper's values beside the measured ones (one line per row).
impl fmt::Display for Table {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(f, "== {}", self.title)?;
        writeln!(f, "   {}", self.setup)?;
        writeln!(
            f,
            "   measurement noise {:.2} mm per axis (mean |z| of the noise alone {:.3} mm)",
            self.noise_mm, self.noise_mean_abs_z_mm
        )?;
        writeln!(
            f,
            "   {:<50} {:>6} {:>9} {:>10} {:>10} {:>9} {:>9} {:>14}",
            "pipeline", "poses", "train s", "mean|z|", "variance", "3-D mean", "3-D max", "paper"
        )?;
        for r in &self.rows {
            let paper = match r.paper {
                Some(PaperValue {
                    mean_mm,
                    variance_mm2: Some(v),
                }) => format!("{mean_mm:.2} / {v:.2}"),
                Some(PaperValue { mean_mm, .. }) => format!("{mean_mm:.2}"),
                None => String::new(),
            };
            writeln!(
                f,
                "   {:<50} {:>6} {:>9.2} {:>10.3} {:>10.3} {:>9.3} {:>9.3} {:>14}",
                r.name, r.training_poses, r.training_s, r.mean_abs_z_mm, r.variance_mm2, r.mean_mm, r.max_mm, paper
            )?;
        }
        Ok(())
    }
}

/// Test targets and how the truth is seen on them.
pub struct TestBench<'a> {
    /// The hidden truth.
    pub truth: &'a Robot,
    /// Targets (m, base frame of the truth = what commands are computed for).
    pub targets: Vec<Vector3<f64>>,
    /// Noise of the camera that checks where the tool went.
    pub noise: SimulateParams,
    /// A task that keeps the tool's orientation; without one, every target's compensation
    /// starts from the middle of the joint ranges.
    pub task: Option<TaughtTask>,
}

/// A task whose tool keeps one orientation, as a controller runs it: every target is compensated
/// as a pose at the task's orientation, started from its taught configuration without restarts
/// (so the command stays on the task's branch).
pub struct TaughtTask {
    /// Taught configuration per target (rad).
    pub taught: Vec<Vec<f64>>,
    /// The tool orientation of the task (truth's measurement frame).
    pub orientation: UnitQuaternion<f64>,
}

impl TestBench<'_> {
    /// Compensates every target with `model` (and `predictor`), commands the truth with the
    /// result and measures where its tool went: one row. Every row sees the same noise draws.
    pub fn row(
        &self,
        name: &str,
        model: &Robot,
        predictor: Option<&dyn FittedPredictor>,
        mode: CompensationMode,
        training: (usize, f64),
        paper: Option<PaperValue>,
    ) -> Result<Row> {
        let mut options = CompensationParams::default();
        if self.task.is_some() {
            // Stay on the taught configuration's branch, as a controller would.
            options.ik.restarts = 0;
        }
        let mut comp = Compensator::new(model, predictor, options)?;
        let mid = mid_range(model);
        let t_model = model.t_meas_base();
        let mut commands = Vec::with_capacity(self.targets.len());
        for (i, t) in self.targets.iter().enumerate() {
            // Targets are given to the model in its own idea of the measurement frame.
            let target_meas = self.truth.t_meas_base().transform_point(&(*t).into());
            let target_model = t_model.inverse_transform_point(&target_meas).coords;
            let (target, q0) = match &self.task {
                Some(task) => {
                    let rotation = t_model.rotation.inverse() * task.orientation;
                    let pose = Isometry3::from_parts(target_model.into(), rotation);
                    (IkTarget::Pose(pose), &task.taught[i])
                }
                None => (IkTarget::Position(target_model), &mid),
            };
            match comp.compensate_target(&target, q0, mode) {
                Ok(_) => commands.push(comp.q().to_vec()),
                // The closest configuration is what a controller would be sent.
                Err(armcomp_core::IkError::Unreachable { closest_q, .. }) => commands.push(closest_q),
                Err(e) => return Err(e.into()),
            }
        }
        let seen = simulate(self.truth, &commands, self.noise)?;
        let errors: Vec<Vector3<f64>> = seen
            .samples
            .iter()
            .zip(&self.targets)
            .map(|(s, t): (&Sample, _)| s.position - self.truth.t_meas_base().transform_point(&(*t).into()).coords)
            .collect();
        Ok(Row::from_errors(name, paper, training, &errors))
    }
}

impl Row {
    /// The row of a pipeline from its errors at the test targets (m, measurement frame,
    /// measured minus wanted); `training` is (poses, seconds).
    pub fn from_errors(name: &str, paper: Option<PaperValue>, training: (usize, f64), errors: &[Vector3<f64>]) -> Row {
        let stats = ErrorStats::from_errors(errors);
        let n = errors.len() as f64;
        let mean = errors.iter().sum::<Vector3<f64>>() / n;
        let variance = (0..3)
            .map(|k| errors.iter().map(|e| (e[k] - mean[k]).powi(2)).sum::<f64>() / (n - 1.0).max(1.0))
            .sum::<f64>()
            / 3.0
            * 1e6;
        Row {
            name: name.to_string(),
            paper,
            training_poses: training.0,
            training_s: training.1,
            mean_abs_z_mm: stats.mean_abs_mm.z,
            variance_mm2: variance,
            mean_mm: stats.mean_mm,
            max_mm: stats.max_mm,
            errors_mm: errors.iter().map(|e| [e.x * 1e3, e.y * 1e3, e.z * 1e3]).collect(),
        }
    }
}

/// The joint values at which `model` puts its tool at `position` with `orientation` (its base
/// frame), by inverse kinematics from `start` without restarts, so the solution stays on the
/// start's branch; `None` when it does not converge.
pub fn pose_command(
    model: &Robot,
    position: &Vector3<f64>,
    orientation: &UnitQuaternion<f64>,
    start: &[f64],
    ik: &mut IkWorkspace,
) -> Option<Vec<f64>> {
    let options = IkParams {
        restarts: 0,
        ..IkParams::default()
    };
    let pose = IkTarget::Pose(Isometry3::from_parts((*position).into(), *orientation));
    solve_ik(model, model.tool(), &pose, start, &options, ik)
        .ok()
        .map(|_| ik.q().to_vec())
}

/// Runs `f` and returns its value with the seconds it took.
pub fn timed<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let start = Instant::now();
    let v = f();
    (v, start.elapsed().as_secs_f64())
}
