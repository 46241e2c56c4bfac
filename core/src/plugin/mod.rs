//! The three plugin roles' traits (the registry entry is in [`crate::robot::registry`]).
//!
//! Each role is a pair, in the linfa/pinocchio spirit: a serialisable *spec* read from the robot
//! file through `typetag` (its `type` field names the plugin), and the built object the
//! pipelines use. Specs derive `schemars::JsonSchema` so the robot-file schema covers them.

pub mod gravity;

use std::fmt::Debug;
use std::path::Path;

use nalgebra::{Isometry3, UnitQuaternion, Vector3};

use crate::error::{Issues, Result};
use crate::kinematics::sensor::{GravitySensor, SensorReadings};
use crate::kinematics::subtree_loads::SubtreeLoads;
use crate::kinematics::workspace::TreeWorkspace;
use crate::model::mass::MassModel;
use crate::model::param::ParamInfo;
use crate::model::perturbation::Perturbation;
use crate::model::shape::Shape;
use crate::model::tree::{KinematicTree, Limits};
use crate::model::units::Units;
use crate::support::cancel::Cancel;
use crate::support::io::InputLimits;

/// What a spec needs to know about the file it came from.
#[derive(Debug, Clone, Copy)]
pub struct BuildContext<'a> {
    /// The file's declared units.
    pub units: Units,
    /// Folder of the robot file, for relative paths (URDF, plugin libraries).
    pub base_dir: &'a Path,
    /// Field path of the spec in the file, for issues (e.g. `kinematics`, `error_models[1]`).
    pub path: &'a str,
    /// How large the files the spec reads (URDF, meshes) may be.
    pub limits: InputLimits,
}

// ---------------------------------------------------------------------------------------------
// Kinematics

/// A kinematic convention as written in a robot file (MDH table, DH table, POE screws, URDF...).
#[typetag::serde(tag = "type")]
pub trait KinematicsSpec: Debug + Send + Sync {
    /// Checks the description and compiles it into a [`Chain`] (SI units). Every problem is
    /// reported with its field path relative to the file's root.
    fn build(&self, ctx: &BuildContext<'_>) -> Result<Box<dyn Chain>, Issues>;
    /// Rewrites the absolute file paths it names (a URDF's) relative to `dir`, the folder of the
    /// model file it is written to, so that the model moved with its files still loads. Paths
    /// with no relative form (another drive) stay as they are; the default names no file.
    fn paths_relative_to(&mut self, _dir: &std::path::Path) {}
}

/// A compiled convention: its identifiable parameters and the tree they produce.
pub trait Chain: Debug + Send + Sync {
    /// Identifiable parameters with their nominal values (SI), in a fixed order.
    fn params(&self) -> &[ParamInfo];
    /// The kinematic tree for parameter `values` (same order as [`params`](Chain::params)).
    /// Bodies carry names that points and links in the robot file refer to.
    fn tree(&self, values: &[f64]) -> Result<KinematicTree>;
    /// When parameter `param` moves one joint's placement and nothing else (no motion axis,
    /// no body frame): that joint (index into the [tree](Chain::tree)'s joints) and its
    /// placement at `values`. A calibration's Jacobian then steps the parameter without
    /// building a tree; `None` (the default) builds one.
    fn placement_moved_by(&self, _values: &[f64], _param: usize) -> Option<(usize, Isometry3<f64>)> {
        None
    }
    /// The spec with `values` written back in the file's units, for model files.
    fn spec_with(&self, values: &[f64]) -> Box<dyn KinematicsSpec>;
    /// Mass properties and shapes of links that the convention's own description carries (a
    /// URDF's inertials and collision elements); the robot file's `links` override them.
    fn links(&self) -> &[LinkData] {
        &[]
    }
    /// Things skipped while reading the description (e.g. meshes that cannot be found), for
    /// the user to see; none of them stops the build.
    fn warnings(&self) -> &[String] {
        &[]
    }
}

/// What a convention's description says about one link besides kinematics, in the tree body
/// frame (SI).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LinkData {
    /// The link (body) name.
    pub name: String,
    /// Mass (kg) and centre of mass (m), when given.
    pub mass: Option<(f64, Vector3<f64>)>,
    /// Collision shapes with their frames in the body frame.
    pub shapes: Vec<(Isometry3<f64>, Shape)>,
}

// ---------------------------------------------------------------------------------------------
// Error models

/// What an error model may look at when it is built.
#[derive(Debug, Clone, Copy)]
pub struct ModelContext<'a> {
    /// File context (units, folder, field path).
    pub build: BuildContext<'a>,
    /// The nominal tree (body and joint names and indices).
    pub tree: &'a KinematicTree,
    /// Masses, centres of mass and beam sections of the bodies.
    pub mass: &'a MassModel,
    /// The robot's sensors (`[[sensors]]`), in the file's order: what
    /// [`StaticState::sensors`] holds the readings of.
    pub sensors: &'a [GravitySensor],
    /// The sensor among them whose reading gives the direction of gravity, if any.
    pub gravity_sensor: Option<usize>,
    /// The robot file's gravity (m/s², base frame): the direction of a level base.
    pub gravity: Vector3<f64>,
}

/// The static state an error model perturbs: joint values, the rigid frames, the loads.
#[derive(Debug, Clone, Copy)]
pub struct StaticState<'a> {
    /// Independent joint values (rad, m).
    pub q: &'a [f64],
    /// The tree being evaluated.
    pub tree: &'a KinematicTree,
    /// Rigid forward kinematics of `q` (world = robot base).
    pub frames: &'a TreeWorkspace,
    /// Mass model, payload included.
    pub mass: &'a MassModel,
    /// The subtree loads of `mass` at `frames` (see [`SubtreeLoads::update`]).
    pub loads: &'a SubtreeLoads,
    /// Gravity in the base frame (m/s²).
    pub gravity: Vector3<f64>,
    /// Ambient temperature (°C), when the measurement gives one.
    pub temperature: Option<f64>,
    /// The row's sensor readings, one slot per sensor of [`ModelContext::sensors`], already
    /// turned from the sensor's frame into its link's by the mountings models identify
    /// ([`ErrorModel::sensor_mounting`]).
    pub sensors: SensorReadings,
}

/// A physical error model as written in a robot file.
#[typetag::serde(tag = "type")]
pub trait ErrorModelSpec: Debug + Send + Sync {
    /// Checks the description against the robot and builds the model.
    fn build(&self, ctx: &ModelContext<'_>) -> Result<Box<dyn ErrorModel>, Issues>;
}

/// A built error model: named parameters and the deformation they cause.
pub trait ErrorModel: Debug + Send + Sync {
    /// Identifiable parameters with their nominal values (SI).
    fn params(&self) -> &[ParamInfo];
    /// Adds this model's deformation at `state` for parameter `values` to `out`. Must not
    /// allocate: it runs inside FK, IK and calibration loops.
    fn perturb(&self, state: &StaticState<'_>, values: &[f64], out: &mut Perturbation);
    /// The spec with `values` written back in the file's units, for model files.
    fn spec_with(&self, values: &[f64]) -> Box<dyn ErrorModelSpec>;
    /// Whether the model, at parameter `values`, moves no frame and changes no load whatever
    /// the configuration, geometry, loads and conditions (every compliance zero, say), so that
    /// callers may skip it. `false`, the default, is always correct.
    fn is_inactive(&self, _values: &[f64]) -> bool {
        false
    }
    /// Whether the model changes the loads every model sees ([`adjust_loads`](Self::adjust_loads)):
    /// a payload heavier than declared, a tilted gravity. Such a model acts only through the
    /// elastic models that respond to loads, with their own (identified) compliances.
    fn adjusts_loads(&self) -> bool {
        false
    }
    /// Changes `loads` (the declared ones, or what earlier models made of them) for parameter
    /// `values`. Must not allocate.
    fn adjust_loads(&self, _values: &[f64], _loads: &mut Loads) {}
    /// The sensor (an index into [`ModelContext::sensors`]) by whose reading this model turns
    /// the chain at that sensor's link (a measured tilt), and at `values` the sensor's
    /// mounting: the rotation from the sensor's frame to its link's frame. The robot turns the
    /// sensor's readings by it before any model or load sees them (so the gravity of every
    /// elastic model is corrected too); a simulated truth reads through it, and turns its
    /// measured points by the tilt of a base that has one. Calibration differences the full
    /// model for such a model's parameters. None, the default: the model reads no sensor.
    fn sensor_mounting(&self, _values: &[f64]) -> Option<(usize, UnitQuaternion<f64>)> {
        None
    }
}

/// The loads error models respond to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Loads {
    /// Gravity in the base frame (m/s²).
    pub gravity: Vector3<f64>,
    /// The payload's mass (kg; 0 without a payload).
    pub payload_mass: f64,
}

// ---------------------------------------------------------------------------------------------
// Residual predictors

/// Training data for a residual predictor: one row per sample.
#[derive(Debug, Clone, Copy)]
pub struct TrainingSet<'a> {
    /// Inputs, row-major, `n × n_inputs` (joint values first, then optional extra inputs).
    pub inputs: &'a [f64],
    /// Targets, row-major, `n × n_outputs` (residual position error in m, or pose error).
    pub targets: &'a [f64],
    /// Number of inputs per row.
    pub n_inputs: usize,
    /// Number of outputs per row.
    pub n_outputs: usize,
    /// The range each input is used over (rad or m: the robot's joint limits), one per input,
    /// or empty when unknown. Predictors scale an input by at least its range, so what they learn
    /// from a narrow slice of it is not blown up when they are queried across the whole of it.
    pub input_ranges: &'a [Option<Limits>],
}

/// How far a predictor's training has come, for a progress display.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TrainingProgress {
    /// What is being run: an optimiser (`"gp"`, `"adam"`, `"lm"`, `"sparrows"`) or the
    /// cross-validation's `"folds"`.
    pub stage: &'static str,
    /// Steps done.
    pub done: usize,
    /// Steps in all (an optimiser may end before).
    pub total: usize,
}

/// How one training runs: where it reports its progress and what stops it. The default
/// reports nothing and is never stopped.
#[derive(Clone, Default)]
pub struct FitControl<'a> {
    /// Called after every step of the training.
    pub progress: Option<&'a (dyn Fn(TrainingProgress) + Sync)>,
    /// Stops the training with [`Interrupted`](crate::Error::Interrupted) once cancelled.
    pub cancel: Cancel,
}

impl FitControl<'_> {
    /// Passes a step to [`progress`](Self::progress), if any.
    pub fn report(&self, stage: &'static str, done: usize, total: usize) {
        if let Some(progress) = self.progress {
            progress(TrainingProgress { stage, done, total });
        }
    }
}

impl Debug for FitControl<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FitControl")
            .field("progress", &self.progress.map(|_| "callback"))
            .field("cancel", &self.cancel)
            .finish()
    }
}

/// A residual predictor's hyper-parameters as written in a robot file.
#[typetag::serde(tag = "type")]
pub trait PredictorSpec: Debug + Send + Sync {
    /// Fits the predictor; deterministic for the spec's seed.
    fn fit(&self, data: &TrainingSet<'_>) -> Result<Box<dyn FittedPredictor>> {
        self.fit_with(data, &FitControl::default())
    }
    /// [`fit`](Self::fit), reporting to and stopped by `control`; the same result for the same
    /// spec and data whatever the control.
    fn fit_with(&self, data: &TrainingSet<'_>, control: &FitControl<'_>) -> Result<Box<dyn FittedPredictor>>;
    /// Checks the spec against the file that names it, when the robot is built, and returns
    /// the spec to fit in its place if its meaning depends on where that file lies (a run-time
    /// library's path); `None`, the default, keeps the spec as written.
    fn resolve(&self, _ctx: &BuildContext<'_>) -> Result<Option<Box<dyn PredictorSpec>>, Issues> {
        Ok(None)
    }
    /// This spec with what a fit of it chose by search held ([`FittedPredictor::searched`]:
    /// a GP's hyper-parameters), so that fits on near-identical data (one fold's residuals
    /// under several prior schemes) skip the search and differ only by their data; `None`,
    /// the default: nothing to hold.
    fn holding(&self, _searched: &serde_json::Value) -> Option<Box<dyn PredictorSpec>> {
        None
    }
}

/// A fitted residual predictor, stored in model files.
#[typetag::serde(tag = "type")]
pub trait FittedPredictor: Debug + Send + Sync {
    /// Number of inputs it expects.
    fn n_inputs(&self) -> usize;
    /// Number of outputs it produces.
    fn n_outputs(&self) -> usize;
    /// What its fit chose by search, for [`PredictorSpec::holding`]; `None`, the default:
    /// nothing searched.
    fn searched(&self) -> Option<serde_json::Value> {
        None
    }
    /// Predicts into `out` (length `n_outputs`). `scratch` is reused between calls, so after the
    /// first call nothing is allocated.
    fn predict_into(&self, input: &[f64], out: &mut [f64], scratch: &mut Vec<f64>);
    /// Predictive standard deviation per output into `out`, for predictors that have one;
    /// returns false (and leaves `out` alone) for those that do not.
    fn predict_std_into(&self, _input: &[f64], _out: &mut [f64], _scratch: &mut Vec<f64>) -> bool {
        false
    }
    /// Predicts into `out` and the derivative of every output with respect to every input into
    /// `jacobian` (row-major, `n_outputs × n_inputs`), for predictors that are differentiable;
    /// returns false (and leaves both alone) for those that are not. Compensation uses it to
    /// solve the model and the residual together by Newton's method.
    fn predict_jacobian_into(
        &self,
        _input: &[f64],
        _out: &mut [f64],
        _jacobian: &mut [f64],
        _scratch: &mut Vec<f64>,
    ) -> bool {
        false
    }
}
