//! Calibration: Levenberg–Marquardt identification of the chain, error-model, measurement-frame
//! and marker parameters from measured positions.
//!
//! The problem is weighted least squares with priors:
//! `min ½ Σ ‖(p̂(θ, qᵢ) − pᵢ) / σ‖² + ½ Σ ((θₖ − θₖ⁰) / σₖ)²`, where `p̂` is the full model
//! (chain + error models) seen through `T_meas_base`, `σ` the tracker noise and `σₖ` each
//! parameter's prior. Jacobian columns are exact for markers (a rotation), cheap forward
//! differences for the base frame (no kinematics re-run), first-order twists at the joint
//! frames for geometry (on deformed robots with the deformation held while the fit makes
//! progress, then differences of the full model), differences of the deformed kinematics for
//! error-model parameters (of the whole model for load-adjusting ones), computed in parallel.
//!
//! Files: `space` (the parameters by name, the robot with a parameter vector written in),
//! `jacobian` (evaluation and columns), `identifiability` (what the data cannot determine),
//! `solver` (a stage as a problem for the shared Levenberg–Marquardt loop of
//! [`crate::support::least_squares`]: bounds, priors, the Jacobian forms, progress), `registration`
//! (the measurement frame in closed form, mislabelled units), `score` (what further parameters
//! would gain, predicted at a fit); the driver [`calibrate`] and the
//! report types are here.
//!
//! Before iterating, the scaled Jacobian is decomposed to find directions the data cannot
//! determine. Each is named; it is left to the priors when one of its parameters has a prior,
//! otherwise its dominant parameter is fixed at the starting value, so nothing drifts.

use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, UnitQuaternion, Vector3, Vector6};
use serde::Serialize;

use crate::algorithms::evaluate::{AngleStats, ErrorStats, StationStats};
use crate::data::measurement::{Sample, SampleKind};
use crate::error::Result;
use crate::model::param::{ParamInfo, Quantity};
use crate::model::tree::KinematicTree;
use crate::robot::{PlaneConstraints, Robot};
use crate::support::cancel::Cancel;

mod driver;
pub mod evidence;
mod identifiability;
mod jacobian;
pub mod plausibility;
mod registration;
mod robust;
mod score;
mod solver;
mod space;

pub use driver::{calibrate, check_station_rows};
pub use identifiability::identifiability;
use jacobian::to_meas;
pub use jacobian::{identification_jacobian, marker_samples, samples_jacobian, samples_jacobian_by_sample};
pub use registration::{register_held_out_stations, register_stations, register_stations_on_poses};
pub use robust::{Drift, GROSS_ERROR, HUBER_K, Loss, Outlier, drift, gross_errors, robust_noise};
pub use score::{ScoreTest, score_test};

/// Which part of the model a parameter belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(tag = "kind", content = "index", rename_all = "snake_case")]
pub enum ParamGroup {
    /// The kinematic convention's geometry (index into the chain's parameters).
    Geometry,
    /// Error model `i` (index into the robot's error models).
    ErrorModel(usize),
    /// The robot base pose in the measurement frame.
    Base,
    /// Marker `i` (index into [`Robot::markers`]).
    Marker(usize),
    /// Fixed point `i` of fixed-point measurements (index into
    /// [`ParameterSpace::fixed_points`]): its position in the measurement frame, a nuisance
    /// parameter identified with the robot.
    FixedPoint(usize),
    /// Plane `i` of plane contacts (index into [`ParameterSpace::planes`]): its height and
    /// tilts in the measurement frame, a nuisance parameter identified with the robot.
    Plane(usize),
}

/// Parameters whose prior standard deviations share one scale when the scales are chosen from
/// the data ([`evidence`]): what one kind of manufacturing or modelling uncertainty holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize)]
#[serde(tag = "kind", content = "index", rename_all = "snake_case")]
pub enum PriorGroup {
    /// The measurement frame (`base.*`).
    Frame,
    /// Marker offsets.
    Markers,
    /// Joint-value offsets of the chain (`θ` of revolute, `d` of prismatic joints).
    JointOffsets,
    /// Other chain lengths (link lengths and offsets, origin translations).
    Lengths,
    /// Other chain angles (twists, origin rotations, axis tilts).
    Angles,
    /// Every parameter of error model `i`.
    ErrorModel(usize),
    /// The positions of the fixed points of fixed-point measurements.
    FixedPoints,
    /// The planes of plane contacts.
    Planes,
    /// Parameter `k` of the [`ParameterSpace`] alone (a scale of its own: automatic relevance
    /// determination).
    Parameter(usize),
}

impl PriorGroup {
    /// A short name for reports: `frame`, `markers`, `joint_offsets`, `lengths`, `angles`, or
    /// the error model's type.
    pub fn label(&self, robot: &Robot) -> String {
        match self {
            PriorGroup::Frame => "frame".into(),
            PriorGroup::Markers => "markers".into(),
            PriorGroup::FixedPoints => "fixed_points".into(),
            PriorGroup::Planes => "planes".into(),
            PriorGroup::JointOffsets => "joint_offsets".into(),
            PriorGroup::Lengths => "lengths".into(),
            PriorGroup::Angles => "angles".into(),
            PriorGroup::ErrorModel(i) => robot.error_model_types().get(*i).cloned().unwrap_or_default(),
            PriorGroup::Parameter(k) => format!("#{k}"),
        }
    }
}

/// One parameter of a [`ParameterSpace`]: what calibration may change.
#[derive(Debug, Clone, Serialize)]
pub struct SpaceParam {
    /// Name, quantity, starting value, prior and bounds.
    pub info: ParamInfo,
    /// What it belongs to.
    pub group: ParamGroup,
    /// Type name of the error model it belongs to (empty otherwise).
    pub model_type: String,
}

/// Every parameter of a robot calibration can touch, in a fixed order: chain, error models,
/// base frame (`base.x … base.yaw`; with several stations one per station,
/// `base[<station>].x …`), markers (`marker.<point>.x|y|z`), then the fixed points of
/// fixed-point measurements (`fixed_point.<name>.x|y|z`, see
/// [`with_fixed_points`](Self::with_fixed_points)), then the planes of plane contacts
/// (`plane.<name>.height|roll|pitch`, see [`with_planes`](Self::with_planes)).
#[derive(Debug, Clone)]
pub struct ParameterSpace {
    /// The parameters.
    pub params: Vec<SpaceParam>,
    /// The fixed points' names, in the order of their parameters.
    pub fixed_points: Vec<String>,
    fixed_point_offset: usize,
    /// The planes' names, in the order of their parameters.
    pub planes: Vec<String>,
    plane_offset: usize,
    /// Each plane's nominal pose (measurement frame): the robot file's, or fitted to its rows.
    plane_nominal: Vec<Isometry3<f64>>,
    n_chain: usize,
    error_offsets: Vec<usize>,
    base_offset: usize,
    /// Measurement frames: one per station of the robot ([`Robot::n_stations`]).
    n_stations: usize,
    marker_offset: usize,
    /// Parameters per marker: 3 (position), or 6 with its orientation.
    marker_dofs: usize,
}

/// A parameter vector made ready for evaluation.
#[derive(Debug, Clone)]
struct Decoded {
    tree: KinematicTree,
    errors: Vec<Vec<f64>>,
    /// `T_meas_base` per station.
    frames: Vec<Isometry3<f64>>,
    /// The fixed points' positions, measurement frame (m).
    fixed_points: Vec<Vector3<f64>>,
    /// The planes' poses, measurement frame (their normal is the `z` axis).
    planes: Vec<Isometry3<f64>>,
}

/// Per-sample intermediate results: the point in the robot base frame, the rotation that
/// maps a marker offset into it, and the point's orientation in that frame.
struct Evaluation {
    world: Vec<Vector3<f64>>,
    marker_rot: Vec<Matrix3<f64>>,
    rotation: Vec<UnitQuaternion<f64>>,
}

/// Settings of [`calibrate`].
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationParams {
    /// What to identify (see [`ParameterSpace::select`]); empty for the default.
    pub identify: Vec<String>,
    /// Standard deviation of the tracker noise per axis (m); weighs data against priors.
    pub measurement_std: f64,
    /// Standard deviation of the measured orientation's noise per axis (rad), when the robot
    /// measures poses: weighs orientations against positions and priors.
    pub orientation_std: f64,
    /// Standard deviation per axis of where the tool sits in a fixed point (m), for data that
    /// mix fixed-point rows with measured positions (a socket is not a tracker); `None`: the
    /// measured positions' [`measurement_std`](Self::measurement_std). Data of fixed points
    /// alone are weighed by `measurement_std`.
    pub fixed_point_std: Option<f64>,
    /// Most Levenberg–Marquardt iterations, over all stages of the fit.
    pub max_iterations: usize,
    /// Converged when an accepted step lowers the cost by less than this fraction.
    pub tolerance: f64,
    /// Converged when an accepted step lowers `½χ²` (residuals in units of the noise) by less
    /// than this: such a change moves no parameter by a meaningful part of its uncertainty.
    pub min_improvement: f64,
    /// Converged when an accepted step moves every parameter by less than this fraction of
    /// its standard deviation (creeping along directions the data barely determines).
    pub min_step: f64,
    /// Directions whose singular value is below this fraction of the largest (scaled
    /// Jacobian) count as not identifiable.
    pub rank_tolerance: f64,
    /// Whether the parameters' priors regularise the fit; without them every direction the
    /// data cannot determine is fixed.
    pub use_priors: bool,
    /// Factor on every prior standard deviation of the robot file (chain and error models):
    /// below 1 holds the parameters closer to their starting values, infinite drops the
    /// priors. [`choose_prior_scale`] picks it by cross-validation.
    pub prior_scale: f64,
    /// Fits that end more than [`RESTART_ABOVE_NOISE`] times above the noise are repeated
    /// this many times from perturbed starts, keeping the lowest cost: every parameter with a
    /// prior moved by a normal draw of its prior standard deviation, and parameters along
    /// which the cost has several minima ([`ParamInfo::multimodal`]: backlash, scales) by
    /// their typical size as well. Only fits where another minimum is likely are restarted: a
    /// multimodal parameter is free or the fit did not converge (see
    /// [`restart_converged`](Self::restart_converged)).
    pub restarts: usize,
    /// Also restart converged fits whose free parameters have one minimum each (geometry,
    /// compliances), where restarts rarely find a lower cost.
    pub restart_converged: bool,
    /// Which parameters a restart moves: every free one, or only those along which the cost
    /// has several minima (the diagnosis: a candidate is then compared with its baseline on
    /// the minima of its own parameters, and a fit without such a parameter is not restarted).
    pub restart_moves: RestartMoves,
    /// Seed of the restarts' perturbations; the same seed gives the same fit.
    pub seed: u64,
    /// A fit whose RMS stays over [`STALL_ABOVE_NOISE`] times what the noise gives stops when
    /// this many accepted steps in a row each lower its cost by less than [`STALL_GAIN`]: the
    /// model cannot explain the data, and the rest of the budget would buy a little RMS with
    /// poorly determined parameters. 0 never stops early.
    pub stall_iterations: usize,
    /// Further factors on the prior standard deviations of whole groups (on top of
    /// [`prior_scale`](Self::prior_scale)); [`evidence`] chooses them from the data.
    pub group_prior_scales: Vec<(PriorGroup, f64)>,
    /// Where to start the fit: a full parameter vector ([`Linearisation::theta`] of an earlier
    /// fit of the same robot and selection), instead of the robot's values registered in
    /// closed form. The priors stay centred on the robot's values.
    pub start: Option<Vec<f64>>,
    /// How each sample's residual enters the cost: least squares, or Huber's loss, which
    /// gross errors cannot pull far (plane contacts are always fitted by least squares).
    pub loss: Loss,
    /// Stops the fit (and its restarts) with [`Interrupted`](crate::Error::Interrupted) once
    /// cancelled.
    pub cancel: Cancel,
}

impl CalibrationParams {
    /// These settings continued from `robot`'s fit record ([`FitRecord`](crate::robot::robot_file::FitRecord)),
    /// so that a command on a fitted model fits it again the way it was fitted: its identified
    /// set when `identify` is empty, its priors (each parameter's recorded factor on the file's
    /// prior, or none) unless `priors_given`, and its noise unless `noise_declared`. Unchanged
    /// for a robot without a record.
    pub fn continued_from(
        mut self,
        robot: &Robot,
        samples: &[Sample],
        noise_declared: bool,
        priors_given: bool,
    ) -> Self {
        let Some(record) = &robot.built_from().fitted else {
            return self;
        };
        if self.identify.is_empty() {
            self.identify = record.identify.clone();
        }
        if !noise_declared {
            self.measurement_std = record.noise_mm * 1e-3;
            if let Some(deg) = record.noise_deg {
                self.orientation_std = deg.to_radians();
            }
        }
        if !priors_given {
            let space = ParameterSpace::for_samples(robot, samples);
            self.use_priors = record.use_priors;
            self.prior_scale = 1.0;
            self.group_prior_scales = record
                .prior_scales
                .iter()
                .filter_map(|(name, scale)| Some((PriorGroup::Parameter(space.index(name)?), *scale)))
                .collect();
        }
        self
    }
}

/// `robot` with the values its fit record says its parameters had before that fit (where
/// their priors were centred), so that fitting it again on the same rows starts where that fit
/// started, not from its answer, which has seen every row; `None` for a robot without such a
/// record.
pub fn before_fit(robot: &Robot, samples: &[Sample]) -> Result<Option<Robot>> {
    let Some(record) = robot.built_from().fitted.as_ref().filter(|r| !r.nominal.is_empty()) else {
        return Ok(None);
    };
    let space = ParameterSpace::for_samples(robot, samples);
    let mut theta = space.initial();
    for (name, &value) in &record.nominal {
        if let Some(k) = space.index(name) {
            theta[k] = value;
        }
    }
    space.apply(robot, &theta).map(Some)
}

/// Which free parameters a restart of [`calibrate`] moves from where the fit ended.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum RestartMoves {
    /// Every free parameter: by a normal draw of its prior (multimodal ones by their typical
    /// size).
    #[default]
    Every,
    /// Only the multimodal ones ([`ParamInfo::multimodal`]: backlash, rigidity scales).
    Multimodal,
}

/// A fit whose RMS is this many times what the declared noise gives is restarted (see
/// [`CalibrationParams::restarts`]); below it the fit explains the data to within its noise.
pub const RESTART_ABOVE_NOISE: f64 = 1.5;

/// See [`CalibrationParams::stall_iterations`].
pub const STALL_ABOVE_NOISE: f64 = 3.0;

/// See [`CalibrationParams::stall_iterations`]: a relative decrease of the cost (1 %).
pub const STALL_GAIN: f64 = 0.01;

impl Default for CalibrationParams {
    fn default() -> Self {
        CalibrationParams {
            identify: Vec::new(),
            measurement_std: 1e-4,
            orientation_std: 1e-3,
            fixed_point_std: None,
            max_iterations: 100,
            tolerance: 1e-10,
            min_improvement: 1e-4,
            min_step: 1e-2,
            rank_tolerance: 1e-5,
            use_priors: true,
            prior_scale: 1.0,
            restarts: 2,
            restart_converged: false,
            restart_moves: RestartMoves::Every,
            seed: 0,
            stall_iterations: 5,
            group_prior_scales: Vec::new(),
            start: None,
            loss: Loss::Squared,
            cancel: Cancel::default(),
        }
    }
}

/// Progress of a search made of many calibrations (cross-validation folds, rungs, prior
/// scales): fits done of the total, and what the fit just done was and took.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FitsProgress {
    /// Fits done.
    pub done: usize,
    /// Fits in all.
    pub total: usize,
    /// The fit just done: what it fitted (a rung of `fit`'s ladder) and its seconds, where
    /// the search has such stages.
    pub last: Option<(&'static str, f64)>,
}

/// One Levenberg–Marquardt iteration, for progress display.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IterationInfo {
    /// Iteration number (1-based).
    pub iteration: usize,
    /// Most iterations allowed.
    pub max_iterations: usize,
    /// RMS of the 3-D position residual after the iteration (m).
    pub rms: f64,
    /// Damping after the iteration.
    pub lambda: f64,
}

/// A combination of parameters the data cannot determine, and what was done about it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Deficiency {
    /// The parameters involved with their weights in the null direction (columns scaled to
    /// unit norm; the largest weight is ±1).
    pub combination: Vec<(String, f64)>,
    /// `regularised` (a prior holds it) or `fixed` (the named parameter keeps its start value).
    pub action: String,
    /// The parameter fixed, for `fixed`.
    pub fixed: Option<String>,
}

/// A parameter the data cannot determine on its own, held at its start value (the robot
/// file's, the priors' centre) while the fit goes on without it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Undetermined {
    /// Dotted name.
    pub parameter: String,
    /// Why, in words.
    pub reason: String,
}

/// How well the selected parameters are determined by the data.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct IdentifiabilityReport {
    /// Number of scalar equations (3 per measured position).
    pub n_equations: usize,
    /// Number of selected parameters.
    pub n_params: usize,
    /// Numerical rank of the column-scaled measurement Jacobian.
    pub rank: usize,
    /// Its condition number (largest over smallest singular value; infinite when deficient).
    pub condition_number: f64,
    /// Condition number over the parameters left free after fixing.
    pub condition_number_free: f64,
    /// The combinations it cannot determine.
    pub deficiencies: Vec<Deficiency>,
    /// Parameters the data barely determine (their standard deviation with the data is still
    /// above half their prior's), kept within [`PRIOR_BOX`] prior standard deviations of
    /// their start.
    pub held_by_priors: Vec<String>,
    /// Parameters without a prior whose standard deviation with the data would exceed the
    /// whole range their model calls plausible: held at their start value, not fitted.
    pub undetermined: Vec<Undetermined>,
    /// Plain-language summary of any problem (empty when fully identifiable).
    pub message: String,
}

/// One parameter before and after.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParamResult {
    /// Dotted name.
    pub name: String,
    /// What it measures.
    #[serde(skip)]
    pub quantity: Quantity,
    /// SI unit of the values.
    pub unit: &'static str,
    /// Value before calibration (SI; marker entries are offsets from the file's position, fixed points
    /// the mean of the starting model's points).
    pub initial: f64,
    /// Identified value (SI).
    pub value: f64,
    /// Standard deviation from the linearised covariance (SI); 0 for fixed parameters.
    pub std: f64,
    /// Whether it was held at its start value because the data cannot determine it.
    pub fixed: bool,
    /// Whether the fit left it on one of its physical bounds (a compliance at 0, ...): the
    /// data pushed it as far as it may go, so its value says more about the model than about
    /// the robot.
    pub at_bound: bool,
    /// Whether the value lies in the range its model calls physically plausible
    /// ([`crate::model::param::ParamInfo::plausible`]); a fit that needs an implausible value is warned about.
    pub plausible: bool,
}

/// What calibration did and how well it fits.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CalibrationReport {
    /// Measured positions used.
    pub n_samples: usize,
    /// The joints that move the measured points, base first: the chain whose geometry
    /// `geometry` and `offsets` select.
    pub measured_chain: Vec<String>,
    /// The joints a measurement file must give (the measured chain's driving joints, mimic
    /// joints left out, minus those the robot file holds).
    pub csv_joints: Vec<String>,
    /// Whether the measurement frame was first registered in closed form.
    pub registered: bool,
    /// The factor applied to the robot file's prior standard deviations (none without priors).
    pub prior_scale: Option<f64>,
    /// Identifiability of the selected parameters at the start.
    pub identifiability: IdentifiabilityReport,
    /// Selected parameters.
    pub params: Vec<ParamResult>,
    /// Iterations run.
    pub iterations: usize,
    /// Final training RMS (mm) of each restart from a perturbed start, in order; empty when
    /// the first fit already reached the noise (see [`CalibrationParams::restarts`]).
    pub restarts_rms_mm: Vec<f64>,
    /// Whether the cost stopped decreasing within the tolerance.
    pub converged: bool,
    /// Why the iteration stopped.
    pub stop_reason: String,
    /// Residuals on the calibration data before.
    pub before: ErrorStats,
    /// Residuals on the calibration data after.
    pub after: ErrorStats,
    /// Residuals after, per station, when the data come from several.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub per_station: Vec<StationStats>,
    /// Orientation residuals before, when the robot measures poses.
    pub before_orientation: Option<AngleStats>,
    /// Orientation residuals after, when the robot measures poses.
    pub after_orientation: Option<AngleStats>,
    /// The 3-D RMS after, over what the declared noise alone gives (`√3 σ`); above
    /// [`FAR_ABOVE_NOISE`] the model or the data is wrong, not just noisy.
    pub rms_over_noise: f64,
    /// Whether the data read in another unit (metres for millimetres, radians for degrees,
    /// or the reverse) fit the starting model far better than as declared; the warnings say
    /// which and the fix.
    pub units_mislabelled: bool,
    /// What the fit suggests is wrong when it ends far above the noise or the units look
    /// mislabelled, most likely first.
    pub warnings: Vec<String>,
    /// Why the fit describes no robot, with the likely cause, when it does not: an estimated
    /// noise beyond any instrument's or a model that explains almost none of the data (see
    /// [`plausibility::implausibility`]; set by the callers that estimate the noise).
    pub implausible: Option<String>,
    /// Samples whose residual is far beyond the noise (see [`gross_errors`]), largest first.
    pub outliers: Vec<Outlier>,
    /// A residual that changes steadily with the sample order (a tracker drifting), when
    /// there is one (see [`drift`]).
    pub drift: Option<Drift>,
    /// The loss the fit minimised.
    pub loss: Loss,
    /// Samples Huber's loss weighed less than the others (residual beyond [`HUBER_K`] robust
    /// noises at the end); 0 for least squares.
    pub downweighted: usize,
    /// What became of the fitted predictor the robot carried, when it carried one.
    pub fitted_predictor: Option<PredictorCarried>,
    /// The free parameters' covariance, which `--json` leaves out: its size grows with the
    /// square of the parameters.
    #[serde(skip)]
    pub covariance: ParameterCovariance,
}

/// The linearised covariance of the free parameters at the solution, scaled by the fit's own
/// residual variance: the square of each parameter's [`ParamResult::std`] on its diagonal.
/// Entries are in the parameters' SI units (m², m·rad, rad², ...); a parameter the data leave
/// undetermined has an infinite variance and NaN covariances.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ParameterCovariance {
    /// The free parameters, in the matrix's order.
    pub names: Vec<String>,
    /// `names.len()` × `names.len()`, symmetric.
    pub matrix: DMatrix<f64>,
}

/// Whether a calibration kept the fitted residual predictor of the robot it started from, and
/// why: a predictor in the base frame stays valid when only the measurement frames moved.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PredictorCarried {
    /// Whether the calibrated model carries it.
    pub kept: bool,
    /// Why, in words.
    pub reason: String,
}

/// How many times the RMS its declared noise gives (`√3 σ` in 3-D) a fit's residual may reach
/// before the report calls it far above the noise: noise mis-declared by a factor of a few
/// stays below it; wrong units, wrong points or a missing effect of that size do not.
pub const FAR_ABOVE_NOISE: f64 = 10.0;

impl CalibrationReport {
    /// Whether the fit ended far above the noise the data declares (see [`FAR_ABOVE_NOISE`]).
    pub fn far_above_noise(&self) -> bool {
        self.rms_over_noise.is_nan() || self.rms_over_noise > FAR_ABOVE_NOISE
    }

    /// Whether the data or the model is wrong, not just noisy: far above the noise, units
    /// that look mislabelled, or a fit that describes no robot.
    pub fn suspect(&self) -> bool {
        self.far_above_noise() || self.units_mislabelled || self.implausible.is_some()
    }
}

/// An identified robot and the report of how it was identified.
#[derive(Debug)]
pub struct Calibration {
    /// The robot with the identified values (its [`Robot::to_file`] is the model file).
    pub robot: Robot,
    /// The report.
    pub report: CalibrationReport,
    /// The problem linearised at the solution.
    pub linearisation: Linearisation,
}

/// A fitted calibration problem linearised at its solution: what the evidence of the model
/// (and so the noise and the prior scales the data support) is computed from, and where a
/// refit with other hyper-parameters starts.
#[derive(Debug, Clone)]
pub struct Linearisation {
    /// Every parameter of the [`ParameterSpace`] at the solution (SI).
    pub theta: Vec<f64>,
    /// The priors' centres (the robot's values, the measurement frame as registered).
    pub centre: Vec<f64>,
    /// The parameters the fit moved (indices into `theta`).
    pub free: Vec<usize>,
    /// The prior standard deviation of each free parameter as the fit used it (SI; infinite
    /// for none).
    pub prior_sigma: Vec<f64>,
    /// The group of each free parameter.
    pub groups: Vec<PriorGroup>,
    /// The noise standard deviation per axis the fit weighed the data with (m).
    pub noise: f64,
    /// The orientation noise per axis it weighed orientations with (rad).
    pub orientation_noise: f64,
    /// The position noise per axis it weighed fixed-point samples with (m), when the data mix
    /// them with measured positions.
    pub fixed_point_noise: Option<f64>,
    /// Per sample, whether it was measured in a fixed point.
    pub fixed_point_samples: Vec<bool>,
    /// Per sample, whether its position rows were weighed by its own standard deviations
    /// ([`Sample::position_std`]) rather than by `noise`.
    pub own_std_samples: Vec<bool>,
    /// How many leading residuals are positions; the rest are orientations, then the
    /// `distance_rows` known distances.
    pub position_rows: usize,
    /// Per position row, its sample and its axis (`x`, `y`, `z` as 0, 1, 2), or `None` for a
    /// plane contact's height.
    pub position_row_of: Vec<(usize, Option<usize>)>,
    /// How many trailing residuals are known distances between fixed points (weighed by their
    /// own declared noise, which the evidence does not estimate).
    pub distance_rows: usize,
    /// Measurement residuals `(p̂ − p) / noise`, three per sample, then
    /// `log(R_measᵀ R̂) / orientation_noise`, three per oriented sample.
    pub residuals: DVector<f64>,
    /// Their Jacobian with respect to the free parameters (per SI unit).
    pub jacobian: DMatrix<f64>,
}

/// State shared by the pieces of one calibration run.
struct Problem<'a> {
    robot: &'a Robot,
    space: &'a ParameterSpace,
    samples: &'a [Sample],
    /// The position noise per axis (m).
    sigma: f64,
    /// The orientation noise per axis (rad).
    sigma_rot: f64,
    /// The position noise per axis of fixed-point samples (m) when the data mix them with
    /// measured positions, `sigma` otherwise.
    sigma_fixed: f64,
    /// Per sample, the square root of the weight its kind's noise gives it against `sigma`
    /// (`sigma / sigma_fixed` for fixed-point samples of mixed data); empty: all 1.
    kind_weights: Vec<f64>,
    /// The samples whose orientation is a residual block (the robot measures poses, or plane
    /// contacts with constrained tilts), in order.
    oriented: Vec<usize>,
    /// Per sample, the fixed point it was measured in (index into the space's fixed points).
    fixed: Vec<Option<usize>>,
    /// Per sample, the plane it was pressed on (index into the space's planes).
    plane: Vec<Option<usize>>,
    /// What plane contacts constrain, when the samples have any.
    constraints: Option<PlaneConstraints>,
    /// Per sample, its first position row; then the number of position rows. A sample has 3,
    /// or a plane contact 1 (the height) or 0.
    position_start: Vec<usize>,
    /// Per oriented sample, its first orientation row after the position rows; then their
    /// number. A sample has 3, or a plane contact its constrained tilts.
    turn_start: Vec<usize>,
    /// The known distances between fixed points: a residual row each, after the orientations.
    distances: Vec<KnownDistance>,
    /// Per sample, the square root of its robust weight ([`Loss::Huber`]); empty: all 1.
    weights: Vec<f64>,
    /// Whether some measured position carries its own standard deviations.
    own_std: bool,
}

/// Whether `samples` mix fixed-point samples with measured positions.
fn mixes_fixed_points(samples: &[Sample]) -> bool {
    samples.iter().any(|s| s.fixed_point.is_some()) && samples.iter().any(|s| s.fixed_point.is_none())
}

/// The noise a [`Problem`] weighs its residuals by: per axis of measured positions (m), of
/// orientations (rad) and, in data that mix them with measured positions, of fixed points (m).
#[derive(Debug, Clone, Copy)]
struct Noise {
    sigma: f64,
    sigma_rot: f64,
    sigma_fixed: Option<f64>,
}

impl Noise {
    /// Unit noise: residuals in SI units.
    const UNIT: Noise = Noise {
        sigma: 1.0,
        sigma_rot: 1.0,
        sigma_fixed: None,
    };

    fn of(params: &CalibrationParams) -> Self {
        Noise {
            sigma: params.measurement_std,
            sigma_rot: params.orientation_std,
            sigma_fixed: params.fixed_point_std,
        }
    }
}

/// A known distance between fixed points `a` and `b` (indices into the space's fixed points),
/// in metres, with its standard deviation.
#[derive(Debug, Clone, Copy)]
struct KnownDistance {
    a: usize,
    b: usize,
    metres: f64,
    sigma: f64,
}

impl<'a> Problem<'a> {
    fn new(robot: &'a Robot, space: &'a ParameterSpace, samples: &'a [Sample], noise: Noise) -> Self {
        let Noise { sigma, sigma_rot, .. } = noise;
        let sigma_fixed = if mixes_fixed_points(samples) {
            noise.sigma_fixed.unwrap_or(sigma)
        } else {
            sigma
        };
        let kind_weights = if sigma_fixed == sigma {
            Vec::new()
        } else {
            samples
                .iter()
                .map(|s| {
                    if s.fixed_point.is_some() {
                        sigma / sigma_fixed
                    } else {
                        1.0
                    }
                })
                .collect()
        };
        let contacts = samples.iter().any(|s| s.plane.is_some());
        let constraints = (robot.measures_planes() || contacts).then(|| robot.plane_constraints());
        // Plane contacts give their height and tilts (as constrained), other samples three rows each.
        let widths = |s: &Sample| match (&s.plane, constraints) {
            (Some(_), Some(c)) => (usize::from(c.height), c.tilts()),
            _ => (3, 3),
        };
        let oriented: Vec<usize> = (0..samples.len())
            .filter(|&i| {
                let s = &samples[i];
                match s.plane {
                    Some(_) => widths(s).1 > 0,
                    None => robot.measures_pose() && s.orientation.is_some(),
                }
            })
            .collect();
        let prefix = |w: &mut dyn Iterator<Item = usize>| {
            let mut at = vec![0];
            for w in w {
                at.push(at.last().copied().unwrap_or(0) + w);
            }
            at
        };
        let position_start = prefix(&mut samples.iter().map(|s| widths(s).0));
        let turn_start = prefix(&mut oriented.iter().map(|&i| widths(&samples[i]).1));
        let plane_index = |name: &str| space.planes.iter().position(|f| f == name);
        let plane = samples
            .iter()
            .map(|s| s.plane.as_deref().and_then(plane_index))
            .collect();
        let index = |name: &str| space.fixed_points.iter().position(|f| f == name);
        let fixed = samples
            .iter()
            .map(|s| s.fixed_point.as_deref().and_then(index))
            .collect();
        // Distances between fixed points the data lack are refused by `calibrate`.
        let distances = robot
            .known_distances()
            .iter()
            .filter_map(|d| {
                Some(KnownDistance {
                    a: index(&d.between[0])?,
                    b: index(&d.between[1])?,
                    metres: d.mm * 1e-3,
                    sigma: d.noise_mm.map_or(sigma, |n| n * 1e-3),
                })
            })
            .collect();
        Problem {
            robot,
            space,
            samples,
            sigma,
            sigma_rot,
            sigma_fixed,
            kind_weights,
            oriented,
            fixed,
            plane,
            constraints,
            position_start,
            turn_start,
            distances,
            weights: Vec::new(),
            own_std: samples.iter().any(|s| s.position_std.is_some()),
        }
    }

    /// The standard deviations per axis sample `i`'s position rows are weighed by instead of
    /// `sigma`: its own, for a measured position that carries them.
    fn own_std(&self, i: usize) -> Option<Vector3<f64>> {
        let s = &self.samples[i];
        s.position_std.filter(|_| s.kind() == SampleKind::Position)
    }

    /// The noise it weighs residuals by.
    fn noise(&self) -> Noise {
        Noise {
            sigma: self.sigma,
            sigma_rot: self.sigma_rot,
            sigma_fixed: Some(self.sigma_fixed),
        }
    }

    /// The position noise per axis of sample `i` (m).
    fn position_sigma(&self, i: usize) -> f64 {
        if self.fixed[i].is_some() {
            self.sigma_fixed
        } else {
            self.sigma
        }
    }

    /// Number of residuals: the position rows, the orientation rows, one per known distance.
    fn n_residuals(&self) -> usize {
        self.position_rows() + self.turn_rows() + self.distances.len()
    }

    /// Number of leading residuals that are positions (or plane contacts' heights).
    fn position_rows(&self) -> usize {
        self.position_start.last().copied().unwrap_or(0)
    }

    /// Number of orientation residuals (after the position rows).
    fn turn_rows(&self) -> usize {
        self.turn_start.last().copied().unwrap_or(0)
    }

    /// Sample `i`'s position rows.
    fn position_range(&self, i: usize) -> std::ops::Range<usize> {
        self.position_start[i]..self.position_start[i + 1]
    }

    /// Every residual row of sample `i`: its position rows, then its orientation rows.
    fn rows_of_sample(&self, i: usize) -> Vec<usize> {
        let turns = self.oriented.binary_search(&i).map(|k| self.turn_range(k));
        self.position_range(i).chain(turns.into_iter().flatten()).collect()
    }

    /// The `k`-th oriented sample's orientation rows.
    fn turn_range(&self, k: usize) -> std::ops::Range<usize> {
        let r0 = self.position_rows();
        r0 + self.turn_start[k]..r0 + self.turn_start[k + 1]
    }

    /// What sample `i`'s modelled point `p` is compared with: its measured position, the
    /// position of the fixed point it was put into, or `p` moved onto the plane it was pressed
    /// on along the plane's normal (measurement frame, m).
    fn target(&self, d: &Decoded, i: usize, p: &Vector3<f64>) -> Vector3<f64> {
        match (self.fixed[i], self.plane[i]) {
            (Some(g), _) => d.fixed_points[g],
            (_, Some(g)) => {
                let plane = &d.planes[g];
                let normal = plane.rotation * Vector3::z();
                p - normal * normal.dot(&(p - plane.translation.vector))
            }
            _ => self.samples[i].position,
        }
    }

    /// The targets of every sample at its modelled point (see [`target`](Self::target)).
    fn targets(&self, d: &Decoded, predicted: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
        (0..self.samples.len())
            .map(|i| self.target(d, i, &predicted[i]))
            .collect()
    }

    /// The space's starting values with each fixed point started in closed form (see
    /// [`start_fixed_points`](Self::start_fixed_points)).
    fn start(&self) -> Result<Vec<f64>> {
        let mut theta = self.space.initial();
        self.start_fixed_points(&mut theta)?;
        Ok(theta)
    }

    /// Sets each fixed point of `theta` to the mean of the points the model at `theta` puts
    /// its samples at (measurement frame).
    fn start_fixed_points(&self, theta: &mut [f64]) -> Result<()> {
        if self.space.fixed_points.is_empty() {
            return Ok(());
        }
        let (_, _, predicted) = self.predict(theta)?;
        let mut sums = vec![(Vector3::zeros(), 0usize); self.space.fixed_points.len()];
        for (g, p) in self.fixed.iter().zip(&predicted) {
            if let Some(g) = g {
                sums[*g].0 += p;
                sums[*g].1 += 1;
            }
        }
        for (g, (sum, n)) in sums.iter().enumerate() {
            if *n > 0 {
                let o = self.space.fixed_point_offset + 3 * g;
                theta[o..o + 3].copy_from_slice((sum / *n as f64).as_slice());
            }
        }
        Ok(())
    }

    /// Sample `i`'s plane-contact residuals, unwhitened: its height above its plane (m) and
    /// its frame's roll and pitch from the plane's (rad), FIGAROH's `rpy(T_planeᵀ T_contact)`.
    fn plane_gap(&self, d: &Decoded, e: &Evaluation, i: usize, g: usize) -> PlaneGap {
        let plane = &d.planes[g];
        let normal = plane.rotation * Vector3::z();
        let view = &d.frames[self.samples[i].station];
        let p = view.transform_point(&e.world[i].into()).coords;
        let contact = view.rotation * e.rotation[i];
        // The plane's normal seen from the contact frame: the last row of the relative
        // rotation, which its roll and pitch depend on alone.
        let m = contact.inverse() * normal;
        PlaneGap {
            height: normal.dot(&(p - plane.translation.vector)),
            roll: m.y.atan2(m.z),
            pitch: (-m.x).atan2(m.y.hypot(m.z)),
            normal,
            offset: p - plane.translation.vector,
            m,
            contact,
        }
    }

    /// ‖p_a − p_b‖ of known distance `k` at `d` and the unit vector from b to a.
    fn distance(&self, d: &Decoded, k: usize) -> (f64, Vector3<f64>) {
        let KnownDistance { a, b, .. } = self.distances[k];
        let v = d.fixed_points[a] - d.fixed_points[b];
        let n = v.norm();
        (n, if n > 0.0 { v / n } else { Vector3::zeros() })
    }
}

/// How far a plane contact is from its plane as a model puts it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactGap {
    /// The plane's index in order of first appearance in the samples.
    pub plane: usize,
    /// Height of the contact above the plane (m).
    pub height: f64,
    /// Roll of the contact frame from the plane's (rad).
    pub roll: f64,
    /// Pitch of the contact frame from the plane's (rad).
    pub pitch: f64,
    /// The plane's normal (measurement frame).
    pub normal: Vector3<f64>,
}

/// Per sample, its gap from its plane (`None` for other samples); per plane, its name and
/// whether it was fitted to the samples.
pub type ContactGaps = (Vec<Option<ContactGap>>, Vec<(String, bool)>);

/// Each plane sample's gap from its plane as the rigid model of `robot` puts it, its planes the
/// robot file's (a model file's: the identified ones) or, for a plane it does not name, the
/// plane fitted to the samples' contacts; `None` for other samples. Also the planes' names and
/// whether each was fitted.
pub fn contact_gaps(robot: &Robot, samples: &[Sample]) -> Result<ContactGaps> {
    let space = ParameterSpace::for_samples(robot, samples);
    let problem = Problem::new(robot, &space, samples, Noise::UNIT);
    let (d, e, _) = problem.predict(&space.initial())?;
    let gaps = (0..samples.len())
        .map(|i| {
            problem.plane[i].map(|g| {
                let gap = problem.plane_gap(&d, &e, i, g);
                ContactGap {
                    plane: g,
                    height: gap.height,
                    roll: gap.roll,
                    pitch: gap.pitch,
                    normal: gap.normal,
                }
            })
        })
        .collect();
    let nominal = robot.nominal_planes();
    let names = space
        .planes
        .iter()
        .map(|n| (n.clone(), !nominal.iter().any(|(m, _)| m == n)))
        .collect();
    Ok((gaps, names))
}

/// How far a model puts the contacts of one plane from it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlaneFit {
    /// The plane's name.
    pub name: String,
    /// Its samples.
    pub n: usize,
    /// Whether the plane was fitted to these samples (the model names no such plane), rather
    /// than the model's own.
    pub fitted: bool,
    /// RMS of the contacts' out-of-plane distance (mm).
    pub rms_mm: f64,
    /// Largest out-of-plane distance (mm).
    pub max_mm: f64,
    /// RMS of the contact frames' roll from the plane's (deg).
    pub roll_rms_deg: f64,
    /// RMS of their pitch from the plane's (deg).
    pub pitch_rms_deg: f64,
}

/// What a model makes of plane contacts, per plane.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PlaneEvaluation {
    /// Per plane, in order of first appearance.
    pub planes: Vec<PlaneFit>,
    /// RMS of the out-of-plane distance over every contact (mm).
    pub rms_mm: f64,
}

/// Evaluates `robot` on plane-contact samples whose position errors (the measured position
/// unused and zero) are `errors`, its fitted predictor's correction included: each contact,
/// moved by that correction, against its plane as the model file gives it (identified by
/// `calibrate`), or fitted to the contacts when it names no such plane. Rewrites each plane
/// sample's error as its point moved onto the plane minus the point; `None` when no sample
/// names a plane.
pub fn evaluate_planes(
    robot: &Robot,
    samples: &[Sample],
    errors: &mut [Vector3<f64>],
) -> Result<Option<PlaneEvaluation>> {
    if samples.iter().all(|s| s.plane.is_none()) {
        return Ok(None);
    }
    let (mut gaps, names) = contact_gaps(robot, samples)?;
    if robot.predictor().is_some() {
        // The predictor's correction of each point is what it takes from the model's error.
        let model = crate::algorithms::evaluate::model_errors(robot, samples);
        for ((gap, m), e) in gaps.iter_mut().zip(&model).zip(errors.iter()) {
            if let Some(g) = gap {
                g.height += g.normal.dot(&(m - e));
            }
        }
    }
    let rms = |v: &mut dyn Iterator<Item = f64>| {
        let (sum, n) = v.fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
        (sum / n.max(1) as f64).sqrt()
    };
    let planes = names
        .iter()
        .enumerate()
        .map(|(g, (name, fitted))| {
            let mine: Vec<_> = gaps.iter().flatten().filter(|c| c.plane == g).collect();
            PlaneFit {
                name: name.clone(),
                n: mine.len(),
                fitted: *fitted,
                rms_mm: rms(&mut mine.iter().map(|c| c.height)) * 1e3,
                max_mm: mine.iter().fold(0.0f64, |m, c| m.max(c.height.abs())) * 1e3,
                roll_rms_deg: rms(&mut mine.iter().map(|c| c.roll)).to_degrees(),
                pitch_rms_deg: rms(&mut mine.iter().map(|c| c.pitch)).to_degrees(),
            }
        })
        .collect();
    for (e, c) in errors.iter_mut().zip(&gaps) {
        if let Some(c) = c {
            *e = -c.normal * c.height;
        }
    }
    let rms_mm = rms(&mut gaps.iter().flatten().map(|c| c.height)) * 1e3;
    Ok(Some(PlaneEvaluation { planes, rms_mm }))
}

/// A plane contact's residuals and what their derivatives need.
struct PlaneGap {
    /// Height above the plane (m).
    height: f64,
    /// Roll of the contact frame from the plane's (rad).
    roll: f64,
    /// Pitch of the contact frame from the plane's (rad).
    pitch: f64,
    /// The plane's normal (measurement frame).
    normal: Vector3<f64>,
    /// The contact point minus the plane's origin (measurement frame).
    offset: Vector3<f64>,
    /// The normal seen from the contact frame.
    m: Vector3<f64>,
    /// The contact frame's orientation (measurement frame).
    contact: UnitQuaternion<f64>,
}

impl PlaneGap {
    /// The constrained tilts' change per change `dm` of the normal seen from the contact frame,
    /// whitened by `sigma_rot`, in the order roll, pitch; unused entries zero.
    fn tilt_rows(&self, c: &PlaneConstraints, dm: &Vector3<f64>, sigma_rot: f64) -> [f64; 2] {
        let m = &self.m;
        let yz = m.y * m.y + m.z * m.z;
        let d_roll = (m.z * dm.y - m.y * dm.z) / yz;
        let d_pitch = -dm.x / yz.sqrt();
        constrained(c, [d_roll / sigma_rot, d_pitch / sigma_rot])
    }

    /// The constrained tilts, whitened, in the order roll, pitch; unused entries zero.
    fn tilts(&self, c: &PlaneConstraints, sigma_rot: f64) -> [f64; 2] {
        constrained(c, [self.roll / sigma_rot, self.pitch / sigma_rot])
    }
}

/// The entries of `[roll, pitch]` that `c` constrains, packed to the front; the rest zero.
fn constrained(c: &PlaneConstraints, [roll, pitch]: [f64; 2]) -> [f64; 2] {
    let mut out = [0.0; 2];
    let mut k = 0;
    for (on, v) in [(c.roll, roll), (c.pitch, pitch)] {
        if on {
            out[k] = v;
            k += 1;
        }
    }
    out
}

/// The plane through `points` (measurement frame, m) in closed form, its normal its `z` axis:
/// the least-squares plane (through the centroid, normal to the direction of least spread),
/// its normal on the side of `axis` (the contact frames' mean `z` axis); with points that do
/// not spread in two directions (one spot touched again and again), the plane through their
/// centroid normal to `axis`.
pub(super) fn fit_plane(points: &[Vector3<f64>], axis: &Vector3<f64>) -> Isometry3<f64> {
    let n = points.len().max(1) as f64;
    let centroid: Vector3<f64> = points.iter().sum::<Vector3<f64>>() / n;
    let scatter: Matrix3<f64> = points.iter().map(|p| (p - centroid) * (p - centroid).transpose()).sum();
    let eig = scatter.symmetric_eigen();
    let mut order = [0, 1, 2];
    order.sort_by(|&a, &b| eig.eigenvalues[a].total_cmp(&eig.eigenvalues[b]));
    // Spread of at least a millimetre RMS in two directions, well above the third.
    let middle = eig.eigenvalues[order[1]];
    let spread = middle > 1e-6 * n && middle > 1e2 * eig.eigenvalues[order[0]].max(0.0);
    let mut normal = if spread || axis.norm() == 0.0 {
        eig.eigenvectors.column(order[0]).into_owned()
    } else {
        axis.normalize()
    };
    if normal.dot(axis) < 0.0 {
        normal = -normal;
    }
    let rotation = UnitQuaternion::rotation_between(&Vector3::z(), &normal)
        .unwrap_or_else(|| UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI));
    Isometry3::from_parts(centroid.into(), rotation)
}

/// How the Jacobian treats the deformation of a robot with error models.
#[derive(Debug, Clone, Copy)]
enum JacobianForm<'a> {
    /// Every column exact: geometry columns add the change of the deformation a step causes
    /// (its moment arms), the models re-evaluated on the stepped rigid kinematics and mapped
    /// to the point at the deformed frames.
    Exact,
    /// Geometry columns as first-order twists at the deformed frames with the deformation
    /// held: a few vector operations per pose and column, off by the relative size of the
    /// deflections (about 1e-3), which is what an iteration far from the minimum needs.
    HeldDeformation,
    /// The held form plus a deformation part the exact form returned earlier for the same
    /// samples and columns ([`Problem::jacobian_parts`]): exact to the change of that part
    /// since, which near a minimum is far below what the fit can resolve.
    HeldPlus(&'a DMatrix<f64>),
}

/// How one Jacobian column is computed (see [`Problem::jacobian`]).
enum ColumnPlan {
    /// Geometry acting through joint placements and point frames: the twist per unit of the
    /// parameter at each joint frame and point it moves. With `deformation`, the exact form:
    /// the change of the error models' deformation the step causes (its moment arms) is added,
    /// to first order at the deformed frames.
    Twists {
        joints: Vec<(usize, Vector6<f64>)>,
        points: Vec<(usize, Vector6<f64>)>,
        /// The stepped tree, its stepped joints (ascending) and the step.
        deformation: Option<(KinematicTree, Vec<usize>, f64)>,
    },
    /// Geometry that changes a joint's motion: finite differences of the full model.
    Finite { tree: KinematicTree, h: f64 },
    /// An error-model parameter: the difference of that model's deformation at
    /// `errors[model]` (every model's parameters, this one stepped by `h`), to first order at
    /// the deformed frames (the rigid kinematics and the other models' share are reused); the
    /// orientation of pose samples is differenced through the full model at `errors`.
    Model {
        model: usize,
        errors: Vec<Vec<f64>>,
        h: f64,
    },
    /// A parameter of a load-adjusting model (a payload mass, a base tilt): finite differences
    /// of the full model, since every elastic model responds to the load. `errors` are all the
    /// models' parameters with this one stepped by `h`.
    Loads { errors: Vec<Vec<f64>>, h: f64 },
    /// A frame parameter of `station`: finite differences of its `T_meas_base` (no
    /// kinematics) between the current pose and the one with the parameter stepped by `h`;
    /// zero for the other stations' samples.
    Base {
        station: usize,
        from: Isometry3<f64>,
        to: Isometry3<f64>,
        h: f64,
    },
    /// A marker offset along `axis` 0–2 of its link frame, or a turn about axis `axis − 3` of
    /// the point's own frame: exact.
    Marker { point: usize, axis: usize },
    /// Fixed point `index`'s coordinate `axis` (measurement frame): exact.
    FixedPoint { index: usize, axis: usize },
    /// A parameter of plane `index`: the change of the plane's origin and normal per unit of
    /// it (measurement frame): exact.
    Plane {
        index: usize,
        origin: Vector3<f64>,
        normal: Vector3<f64>,
    },
}

/// How many prior standard deviations a parameter the data barely determine may move.
pub const PRIOR_BOX: f64 = 3.0;

/// What the data determine of the selected parameters, before any fitting.
struct Assessment {
    report: IdentifiabilityReport,
    /// The selected parameters left free (not fixed as undeterminable).
    free: Vec<usize>,
    /// The free parameters the data barely determine (see [`barely_seen`]).
    held: Vec<usize>,
}

/// Where a fit stands: parameters, what they decode to, and the iterations so far.
struct Stage {
    theta: Vec<f64>,
    d: Decoded,
    e: Evaluation,
    iterations: usize,
    /// The exact Jacobian at `theta` and the parameters of its columns, once computed.
    exact_jacobian: Option<(Vec<usize>, DMatrix<f64>)>,
}

/// How a Levenberg–Marquardt run ended.
struct StageOutcome {
    /// It converged, or stopped early far above the noise
    /// ([`CalibrationParams::stall_iterations`]), as far as its model can go.
    converged: bool,
    stop_reason: String,
}
