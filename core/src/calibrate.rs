//! Calibration: Levenberg–Marquardt identification of the chain, error-model, measurement-frame
//! and marker parameters from measured positions.
//!
//! The problem is weighted least squares with priors:
//! `min ½ Σ ‖(p̂(θ, qᵢ) − pᵢ) / σ‖² + ½ Σ ((θₖ − θₖ⁰) / σₖ)²`, where `p̂` is the full model
//! (chain + error models) seen through `T_meas_base`, `σ` the tracker noise and `σₖ` each
//! parameter's prior. Jacobian columns are exact for markers (a rotation), cheap forward
//! differences for the base frame (no kinematics re-run), and forward differences of the full
//! model for everything else, computed in parallel.
//!
//! Before iterating, the scaled Jacobian is decomposed to find directions the data cannot
//! determine. Each is named; it is left to the priors when one of its parameters has a prior,
//! otherwise its dominant parameter is fixed at the starting value, so nothing drifts.
//!
//! The Levenberg–Marquardt loop is written here rather than taken from a crate because it needs
//! bounds, priors, parameter fixing and a best-so-far result on non-convergence together, and
//! the available crates pull in another nalgebra version.

use nalgebra::{DMatrix, DVector, Isometry3, Matrix3, Rotation3, SymmetricEigen, Vector3, Vector6};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use serde::Serialize;

use crate::error::{Error, Result};
use crate::evaluate::ErrorStats;
use crate::geom::xyz_rpy;
use crate::measurement::Sample;
use crate::param::{ParamInfo, Quantity};
use crate::perturbation::Perturbation;
use crate::robot::{Conditions, Robot, RobotWorkspace};
use crate::tree::{KinematicTree, Motion};

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
/// base frame (`base.x … base.yaw`), markers (`marker.<point>.x|y|z`).
#[derive(Debug, Clone)]
pub struct ParameterSpace {
    /// The parameters.
    pub params: Vec<SpaceParam>,
    n_chain: usize,
    error_offsets: Vec<usize>,
    base_offset: usize,
    marker_offset: usize,
}

/// Base-frame parameters, in the order of [`xyz_rpy`].
const BASE_NAMES: [&str; 6] = ["x", "y", "z", "roll", "pitch", "yaw"];

impl ParameterSpace {
    /// The parameters of `robot`, starting at its current values.
    pub fn new(robot: &Robot) -> Self {
        let mut params = Vec::new();
        for (info, v) in robot.chain_params().iter().zip(robot.chain_values()) {
            let mut info = info.clone();
            info.nominal = *v;
            params.push(SpaceParam {
                info,
                group: ParamGroup::Geometry,
                model_type: String::new(),
            });
        }
        let n_chain = params.len();
        let mut error_offsets = Vec::new();
        for (i, (m, values)) in robot.error_models().iter().zip(robot.error_values()).enumerate() {
            error_offsets.push(params.len());
            let model_type = model_type_name(robot, i);
            for (info, v) in m.params().iter().zip(values) {
                let mut info = info.clone();
                info.nominal = *v;
                params.push(SpaceParam {
                    info,
                    group: ParamGroup::ErrorModel(i),
                    model_type: model_type.clone(),
                });
            }
        }
        let base_offset = params.len();
        let (xyz, rpy) = base_xyz_rpy(&robot.t_meas_base());
        let mut setup = setup_param_names(robot).into_iter();
        for k in 0..BASE_NAMES.len() {
            let (quantity, value) = if k < 3 {
                (Quantity::Length, xyz[k])
            } else {
                (Quantity::Angle, rpy[k - 3])
            };
            params.push(SpaceParam {
                info: ParamInfo::new(
                    setup.next().expect("one name per base parameter"),
                    quantity,
                    value,
                    f64::INFINITY,
                ),
                group: ParamGroup::Base,
                model_type: String::new(),
            });
        }
        let marker_offset = params.len();
        for i in 0..robot.markers().len() {
            for _ in 0..3 {
                params.push(SpaceParam {
                    info: ParamInfo::new(
                        setup.next().expect("three names per marker"),
                        Quantity::Length,
                        0.0,
                        f64::INFINITY,
                    ),
                    group: ParamGroup::Marker(i),
                    model_type: String::new(),
                });
            }
        }
        ParameterSpace {
            params,
            n_chain,
            error_offsets,
            base_offset,
            marker_offset,
        }
    }

    /// Starting values of every parameter (SI; marker entries are offsets from the file's).
    pub fn initial(&self) -> Vec<f64> {
        self.params.iter().map(|p| p.info.nominal).collect()
    }

    /// Indices of the parameters named by `identify`: group words `base`, `markers`,
    /// `geometry` (of the measured chain: the joints that move a marker), `offsets` (its
    /// joint-value offsets: `θ` of revolute and `d` of prismatic joints, `offset` of URDF
    /// joints), `errors` (every error model), `all`, an error model's type name
    /// (e.g. `joint_compliance`), or a parameter name pattern with `*` wildcards (`j2.*`).
    /// Empty means `base, markers, geometry, errors`. What the robot file's `fixed` names is
    /// left out.
    pub fn select(&self, robot: &Robot, identify: &[String]) -> Result<Vec<usize>> {
        let default = ["base", "markers", "geometry", "errors"].map(String::from);
        let words: &[String] = if identify.is_empty() { &default } else { identify };
        // Geometry words mean the chain the markers hang from: a joint elsewhere (another
        // limb, a wheel, a sensor mount) cannot move what was measured.
        let measured = robot.measured_joints();
        let on_measured_chain = |name: &str| {
            name.rsplit_once('.')
                .and_then(|(joint, _)| robot.tree().joint_index(joint))
                .is_none_or(|j| measured[j])
        };
        let mut chosen = vec![false; self.params.len()];
        for word in words {
            let word = word.trim();
            let mut any = false;
            for (k, p) in self.params.iter().enumerate() {
                let hit = match word {
                    "all" => true,
                    "base" => p.group == ParamGroup::Base,
                    "markers" => matches!(p.group, ParamGroup::Marker(_)),
                    "geometry" => p.group == ParamGroup::Geometry && on_measured_chain(&p.info.name),
                    "errors" => matches!(p.group, ParamGroup::ErrorModel(_)),
                    "offsets" => {
                        p.group == ParamGroup::Geometry
                            && on_measured_chain(&p.info.name)
                            && is_joint_offset(robot.tree(), &p.info.name)
                    }
                    w if w.contains('*') => glob_match(w, &p.info.name),
                    w => p.model_type == w || p.info.name == w,
                };
                if hit {
                    chosen[k] = true;
                    any = true;
                }
            }
            if !any && !identify.is_empty() {
                let types: Vec<String> = (0..robot.error_models().len())
                    .map(|i| model_type_name(robot, i))
                    .collect();
                let types = if types.is_empty() {
                    "it has none".to_string()
                } else {
                    types.join(", ")
                };
                return Err(Error::Input(format!(
                    "--identify `{word}` matches no parameter; use base, markers, geometry, offsets, errors, all, \
                     an error model of this robot ({types}), or a name pattern such as `j2.*`"
                )));
            }
        }
        // What the robot file fixes is known: never refitted, whatever the words select.
        let fixed = &robot.file.fixed;
        Ok((0..self.params.len())
            .filter(|&k| chosen[k] && !fixed.iter().any(|f| name_matches(f, &self.params[k].info.name)))
            .collect())
    }

    /// Decodes a full parameter vector into what forward kinematics needs.
    fn decode(&self, robot: &Robot, theta: &[f64]) -> Result<Decoded> {
        let errors = self
            .error_offsets
            .iter()
            .zip(robot.error_values())
            .map(|(&o, v)| theta[o..o + v.len()].to_vec())
            .collect();
        Ok(Decoded {
            tree: self.tree(robot, theta)?,
            errors,
            t_meas_base: self.base_pose(theta),
        })
    }

    /// The tree of the chain parameters of `theta` with the markers moved by their offsets:
    /// error models see the points where the model file will put them (a payload hanging at a
    /// marker, a point on a bending link).
    fn tree(&self, robot: &Robot, theta: &[f64]) -> Result<KinematicTree> {
        let mut tree = robot.tree_for(&theta[..self.n_chain])?;
        for (i, &m) in robot.markers().iter().enumerate() {
            let o = self.marker_offset + 3 * i;
            let delta = Vector3::new(theta[o], theta[o + 1], theta[o + 2]);
            if delta != Vector3::zeros() {
                let point = &tree.points()[m];
                let mut local = point.local;
                // Offsets are in the body's convention frame, as the file's coordinates.
                local.translation.vector += tree.bodies()[point.body].convention_frame.rotation * delta;
                tree.set_point_local(m, local);
            }
        }
        Ok(tree)
    }

    fn base_pose(&self, theta: &[f64]) -> Isometry3<f64> {
        let b = &theta[self.base_offset..self.base_offset + 6];
        xyz_rpy([b[0], b[1], b[2]], [b[3], b[4], b[5]])
    }
}

/// Names of the measurement-setup parameters of `robot`, in [`ParameterSpace`] order: the base
/// frame (`base.x … base.yaw`), then each marker's offset (`marker.<point>.x|y|z`).
pub(crate) fn setup_param_names(robot: &Robot) -> Vec<String> {
    let base = BASE_NAMES.iter().map(|n| format!("base.{n}"));
    let markers = robot.markers().iter().flat_map(|&m| {
        let name = &robot.tree().points()[m].name;
        ["x", "y", "z"].map(|a| format!("marker.{name}.{a}"))
    });
    base.chain(markers).collect()
}

/// The `type` of error model `i` as written in the robot file.
fn model_type_name(robot: &Robot, i: usize) -> String {
    serde_json::to_value(&robot.file.error_models[i])
        .ok()
        .and_then(|v| v.get("type").and_then(|t| t.as_str()).map(String::from))
        .unwrap_or_default()
}

/// Whether chain parameter `name` (`<joint>.<suffix>`) adds to its joint's value.
fn is_joint_offset(tree: &KinematicTree, name: &str) -> bool {
    let Some((joint, suffix)) = name.rsplit_once('.') else {
        return false;
    };
    match tree.joint_index(joint).map(|j| &tree.joints()[j].motion) {
        Some(Motion::Revolute(_)) => suffix == "theta" || suffix == "offset",
        Some(Motion::Prismatic(_)) => suffix == "d" || suffix == "offset",
        _ => false,
    }
}

/// Whether parameter `name` is `pattern`, or matches it when it has `*` wildcards.
pub(crate) fn name_matches(pattern: &str, name: &str) -> bool {
    pattern == name || (pattern.contains('*') && glob_match(pattern, name))
}

/// `*` matches any run of characters (`pattern` has at least one); everything else matches
/// itself.
fn glob_match(pattern: &str, name: &str) -> bool {
    let parts: Vec<&str> = pattern.split('*').collect();
    let (first, last) = (parts[0], parts[parts.len() - 1]);
    if !name.starts_with(first) || name.len() < first.len() + last.len() || !name.ends_with(last) {
        return false;
    }
    let mut rest = &name[first.len()..name.len() - last.len()];
    for part in &parts[1..parts.len() - 1] {
        match rest.find(part) {
            Some(i) => rest = &rest[i + part.len()..],
            None => return false,
        }
    }
    true
}

fn base_xyz_rpy(t: &Isometry3<f64>) -> ([f64; 3], [f64; 3]) {
    let (r, p, y) = t.rotation.euler_angles();
    let v = t.translation.vector;
    ([v.x, v.y, v.z], [r, p, y])
}

/// A parameter vector made ready for evaluation.
#[derive(Debug, Clone)]
struct Decoded {
    tree: KinematicTree,
    errors: Vec<Vec<f64>>,
    t_meas_base: Isometry3<f64>,
}

/// Per-sample intermediate results: the point in the robot base frame and the rotation that
/// maps a marker offset into it.
struct Evaluation {
    world: Vec<Vector3<f64>>,
    marker_rot: Vec<Matrix3<f64>>,
}

fn evaluate(robot: &Robot, d: &Decoded, samples: &[Sample], ws: &mut RobotWorkspace) -> Evaluation {
    let mut world = Vec::with_capacity(samples.len());
    let mut marker_rot = Vec::with_capacity(samples.len());
    for s in samples {
        robot.forward_with_into(&d.tree, &d.errors, &s.q, Conditions::of(s), ws);
        let point = &d.tree.points()[s.point];
        let rot = ws.frames.body[point.body].rotation.to_rotation_matrix().into_inner()
            * d.tree.bodies()[point.body]
                .convention_frame
                .rotation
                .to_rotation_matrix()
                .into_inner();
        world.push(ws.frames.point[s.point].translation.vector);
        marker_rot.push(rot);
    }
    Evaluation { world, marker_rot }
}

fn to_meas(t: &Isometry3<f64>, world: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    world.iter().map(|p| t.transform_point(&(*p).into()).coords).collect()
}

/// Settings of [`calibrate`].
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrationParams {
    /// What to identify (see [`ParameterSpace::select`]); empty for the default.
    pub identify: Vec<String>,
    /// Standard deviation of the tracker noise per axis (m); weighs data against priors.
    pub measurement_std: f64,
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
    /// their typical size as well.
    pub restarts: usize,
    /// Seed of the restarts' perturbations; the same seed gives the same fit.
    pub seed: u64,
}

/// A fit whose RMS is this many times what the declared noise gives is restarted (see
/// [`CalibrationParams::restarts`]); below it the fit explains the data to within its noise.
pub const RESTART_ABOVE_NOISE: f64 = 1.5;

impl Default for CalibrationParams {
    fn default() -> Self {
        CalibrationParams {
            identify: Vec::new(),
            measurement_std: 1e-4,
            max_iterations: 100,
            tolerance: 1e-10,
            min_improvement: 1e-4,
            min_step: 1e-2,
            rank_tolerance: 1e-5,
            use_priors: true,
            prior_scale: 1.0,
            restarts: 2,
            seed: 0,
        }
    }
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
    /// Value before calibration (SI; marker entries are offsets from the file's position).
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
    /// ([`crate::param::ParamInfo::plausible`]); a fit that needs an implausible value is warned about.
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

    /// Whether the data or the model is wrong, not just noisy: far above the noise, or units
    /// that look mislabelled.
    pub fn suspect(&self) -> bool {
        self.far_above_noise() || self.units_mislabelled
    }
}

/// An identified robot and the report of how it was identified.
#[derive(Debug)]
pub struct Calibration {
    /// The robot with the identified values (its [`Robot::to_file`] is the model file).
    pub robot: Robot,
    /// The report.
    pub report: CalibrationReport,
}

/// State shared by the pieces of one calibration run.
struct Problem<'a> {
    robot: &'a Robot,
    space: &'a ParameterSpace,
    samples: &'a [Sample],
    sigma: f64,
}

impl Problem<'_> {
    fn predict(&self, theta: &[f64]) -> Result<(Decoded, Evaluation, Vec<Vector3<f64>>)> {
        let d = self.space.decode(self.robot, theta)?;
        let mut ws = self.robot.workspace();
        let e = evaluate(self.robot, &d, self.samples, &mut ws);
        let meas = to_meas(&d.t_meas_base, &e.world);
        Ok((d, e, meas))
    }

    /// ½χ² of `stage` with the priors of `free` centred at `theta0`: what Levenberg–Marquardt
    /// minimises.
    fn cost(&self, stage: &Stage, theta0: &[f64], free: &[usize]) -> f64 {
        let r = self.residuals(&to_meas(&stage.d.t_meas_base, &stage.e.world));
        self.cost_of(&stage.theta, theta0, free, &r)
    }

    fn cost_of(&self, theta: &[f64], theta0: &[f64], free: &[usize], r: &DVector<f64>) -> f64 {
        let prior: f64 = free
            .iter()
            .map(|&k| ((theta[k] - theta0[k]) / self.space.params[k].info.sigma).powi(2))
            .sum();
        0.5 * (r.norm_squared() + prior)
    }

    /// The RMS of `stage`'s 3-D residuals over what the noise alone gives (√3 σ).
    fn rms_over_noise(&self, stage: &Stage) -> f64 {
        let r = self.residuals(&to_meas(&stage.d.t_meas_base, &stage.e.world));
        (r.norm_squared() / (3.0 * self.samples.len() as f64)).sqrt()
    }

    /// Measurement residuals `(p̂ − p) / σ`, three per sample.
    fn residuals(&self, predicted: &[Vector3<f64>]) -> DVector<f64> {
        DVector::from_iterator(
            3 * self.samples.len(),
            predicted.iter().zip(self.samples).flat_map(|(p, s)| {
                let r = (p - s.position) / self.sigma;
                [r.x, r.y, r.z]
            }),
        )
    }

    /// How each Jacobian column of `free` is computed at `theta`.
    fn column_plans(&self, theta: &[f64], d: &Decoded, free: &[usize], form: JacobianForm) -> Result<Vec<ColumnPlan>> {
        let space = self.space;
        free.iter()
            .map(|&k| {
                let p = &space.params[k];
                Ok(match p.group {
                    ParamGroup::Marker(i) => ColumnPlan::Marker {
                        point: self.robot.markers()[i],
                        axis: (k - space.marker_offset) % 3,
                    },
                    ParamGroup::Base => {
                        let (mut t, h) = step(theta, k, p);
                        t[k] += h;
                        ColumnPlan::Base {
                            from: space.base_pose(theta),
                            to: space.base_pose(&t),
                            h,
                        }
                    }
                    ParamGroup::ErrorModel(i) => {
                        let (_, h) = step(theta, k, p);
                        let mut values = d.errors[i].clone();
                        values[k - space.error_offsets[i]] += h;
                        if self.robot.error_models()[i].adjusts_loads() {
                            let mut errors = d.errors.clone();
                            errors[i] = values;
                            ColumnPlan::Loads { errors, h }
                        } else {
                            ColumnPlan::Model { model: i, values, h }
                        }
                    }
                    ParamGroup::Geometry => {
                        let (mut t, h) = step(theta, k, p);
                        t[k] += h;
                        let tree = space.tree(self.robot, &t)?;
                        if form == JacobianForm::Exact && !self.robot.error_models().is_empty() {
                            ColumnPlan::Finite { tree, h }
                        } else {
                            geometry_plan(&d.tree, tree, h)
                        }
                    }
                })
            })
            .collect()
    }

    /// Jacobian of the measurement residuals with respect to the parameters `free`.
    ///
    /// Geometry that moves joint placements and point frames is differentiated through
    /// first-order twists at the joint frames: a few vector operations per sample instead of a
    /// forward kinematics run; on deformed robots that holds the deformation, and the exact
    /// `form` differences the full model instead. Error-model parameters are differenced
    /// through the deformed kinematics only (the model's share of the deformation re-evaluated,
    /// the rigid frames reused).
    fn jacobian(
        &self,
        theta: &[f64],
        d: &Decoded,
        e: &Evaluation,
        free: &[usize],
        form: JacobianForm,
    ) -> Result<DMatrix<f64>> {
        let plans = self.column_plans(theta, d, free, form)?;
        let ncols = plans.len();
        let r_meas = d.t_meas_base.rotation.to_rotation_matrix().into_inner();
        let n_models = self.robot.error_models().len();
        let rows: Vec<Vec<f64>> = self
            .samples
            .par_iter()
            .enumerate()
            .map_init(
                || {
                    let pert = Perturbation::zeros(&d.tree);
                    (
                        self.robot.workspace(),
                        self.robot.workspace(),
                        vec![pert.clone(); n_models],
                        pert,
                    )
                },
                |(ws, ws_fd, base_perts, scratch), (s_idx, s)| {
                    let cond = Conditions::of(s);
                    self.robot.forward_with_into(&d.tree, &d.errors, &s.q, cond, ws);
                    for (i, bp) in base_perts.iter_mut().enumerate() {
                        bp.clear();
                        self.robot.model_perturbation_into(i, &d.tree, &d.errors[i], s, ws, bp);
                    }
                    let body = d.tree.points()[s.point].body;
                    let support = d.tree.support(body);
                    let p = e.world[s_idx];
                    let frames = &ws.frames;
                    let twist_effect = |j: usize, xi: &Vector6<f64>| -> Vector3<f64> {
                        let f = &frames.joint_frame[j];
                        let v = f.rotation * xi.fixed_rows::<3>(0);
                        let w = f.rotation * xi.fixed_rows::<3>(3);
                        v + w.cross(&(p - f.translation.vector))
                    };
                    let point_rot = frames.point[s.point].rotation;
                    let mut row = vec![0.0; 3 * ncols];
                    for (c, plan) in plans.iter().enumerate() {
                        let dp_meas = match plan {
                            ColumnPlan::Marker { point, axis } => {
                                if *point != s.point {
                                    continue;
                                }
                                r_meas * e.marker_rot[s_idx].column(*axis)
                            }
                            ColumnPlan::Base { from, to, h } => {
                                (to.transform_point(&p.into()) - from.transform_point(&p.into())) / *h
                            }
                            ColumnPlan::Twists { joints, points } => {
                                let mut dp = Vector3::zeros();
                                for (j, xi) in joints {
                                    if support.contains(j) {
                                        dp += twist_effect(*j, xi);
                                    }
                                }
                                for (i, xi) in points {
                                    if *i == s.point {
                                        dp += point_rot * xi.fixed_rows::<3>(0);
                                    }
                                }
                                r_meas * dp
                            }
                            ColumnPlan::Loads { errors, h } => {
                                // A changed load changes what every elastic model does.
                                self.robot.forward_with_into(&d.tree, errors, &s.q, cond, ws_fd);
                                let dp = (ws_fd.frames.point[s.point].translation.vector
                                    - ws.frames.point[s.point].translation.vector)
                                    / *h;
                                r_meas * dp
                            }
                            ColumnPlan::Finite { tree, h } => {
                                self.robot.forward_with_into(tree, &d.errors, &s.q, cond, ws_fd);
                                let dp = (ws_fd.frames.point[s.point].translation.vector
                                    - ws.frames.point[s.point].translation.vector)
                                    / *h;
                                r_meas * dp
                            }
                            ColumnPlan::Model { model, values, h } => {
                                // Total deformation with this model's share re-evaluated at
                                // the stepped value; the rigid frames stay as they are.
                                scratch.clone_from(&ws.perturbation);
                                subtract(scratch, &base_perts[*model]);
                                self.robot
                                    .model_perturbation_into(*model, &d.tree, values, s, ws, scratch);
                                d.tree.forward_perturbed_into(&s.q, scratch, &mut ws_fd.frames);
                                let dp = (ws_fd.frames.point[s.point].translation.vector
                                    - ws.frames.point[s.point].translation.vector)
                                    / *h;
                                r_meas * dp
                            }
                        };
                        for a in 0..3 {
                            row[3 * c + a] = dp_meas[a] / self.sigma;
                        }
                    }
                    row
                },
            )
            .collect();
        let mut jac = DMatrix::zeros(3 * self.samples.len(), ncols);
        for (s_idx, row) in rows.iter().enumerate() {
            for c in 0..ncols {
                for a in 0..3 {
                    jac[(3 * s_idx + a, c)] = row[3 * c + a];
                }
            }
        }
        Ok(jac)
    }
}

/// `out -= other`, entry by entry.
fn subtract(out: &mut Perturbation, other: &Perturbation) {
    out.joint_twist
        .iter_mut()
        .zip(&other.joint_twist)
        .for_each(|(a, b)| *a -= b);
    out.joint_offset
        .iter_mut()
        .zip(&other.joint_offset)
        .for_each(|(a, b)| *a -= b);
    out.point_twist
        .iter_mut()
        .zip(&other.point_twist)
        .for_each(|(a, b)| *a -= b);
}

/// How the Jacobian treats the deformation of a robot with error models.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum JacobianForm {
    /// Every column exact: geometry differenced through the full deformed model, so the
    /// deformation's own dependence on the geometry (its moment arms) is included.
    Exact,
    /// Geometry columns as first-order twists at the deformed frames with the deformation
    /// held: a few vector operations per pose and column, off by the relative size of the
    /// deflections (about 1e-3), which is what an iteration far from the minimum needs.
    HeldDeformation,
}

/// How one Jacobian column is computed (see [`Problem::jacobian`]).
enum ColumnPlan {
    /// Geometry acting through joint placements and point frames: the twist per unit of the
    /// parameter at each joint frame and point it moves.
    Twists {
        joints: Vec<(usize, Vector6<f64>)>,
        points: Vec<(usize, Vector6<f64>)>,
    },
    /// Geometry that changes a joint's motion: finite differences of the full model.
    Finite { tree: KinematicTree, h: f64 },
    /// An error-model parameter: finite differences of the deformed kinematics with that
    /// model's deformation re-evaluated (the rigid kinematics is reused).
    /// `values` are the model's parameters with this one stepped by `h`.
    Model { model: usize, values: Vec<f64>, h: f64 },
    /// A parameter of a load-adjusting model (a payload mass, a base tilt): finite differences
    /// of the full model, since every elastic model responds to the load. `errors` are all the
    /// models' parameters with this one stepped by `h`.
    Loads { errors: Vec<Vec<f64>>, h: f64 },
    /// A base-frame parameter: finite differences of `T_meas_base` (no kinematics) between
    /// the current pose and the one with the parameter stepped by `h`.
    Base {
        from: Isometry3<f64>,
        to: Isometry3<f64>,
        h: f64,
    },
    /// A marker offset along `axis` of its link frame: exact.
    Marker { point: usize, axis: usize },
}

/// The column plan of a geometry parameter whose step `h` turns `tree` into `stepped`.
fn geometry_plan(tree: &KinematicTree, stepped: KinematicTree, h: f64) -> ColumnPlan {
    let same_motion = tree
        .joints()
        .iter()
        .zip(stepped.joints())
        .all(|(a, b)| a.motion == b.motion && a.coordinate == b.coordinate);
    if !same_motion {
        return ColumnPlan::Finite { tree: stepped, h };
    }
    let twist = |a: &Isometry3<f64>, b: &Isometry3<f64>| -> Option<Vector6<f64>> {
        let rel = a.inverse() * b;
        let v = rel.translation.vector / h;
        let w = rel.rotation.scaled_axis() / h;
        let xi = Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z);
        (xi != Vector6::zeros()).then_some(xi)
    };
    let joints = tree
        .joints()
        .iter()
        .zip(stepped.joints())
        .enumerate()
        .filter_map(|(j, (a, b))| twist(&a.placement, &b.placement).map(|xi| (j, xi)))
        .collect();
    let points = tree
        .points()
        .iter()
        .zip(stepped.points())
        .enumerate()
        .filter_map(|(i, (a, b))| twist(&a.local, &b.local).map(|xi| (i, xi)))
        .collect();
    ColumnPlan::Twists { joints, points }
}

/// The size a parameter of this kind typically has when it matters (SI): 10 mm, 0.6°, 1 %,
/// 1e-4 rad/(N m), 0.1 kg, ...
fn typical_size(info: &ParamInfo) -> f64 {
    match info.quantity {
        Quantity::Length | Quantity::Angle | Quantity::Dimensionless => 1e-2,
        Quantity::Compliance => 1e-4,
        Quantity::Mass => 0.1,
        Quantity::Rigidity => 1e3,
        Quantity::PerKelvin => 1e-6,
        Quantity::Other(_) => 1e-3,
    }
}

/// A copy of `theta` and a forward-difference step for parameter `k`, signed to stay within
/// the upper bound. Steps are 1e-6 of the value or of a typical scale, whichever is larger.
///
/// The typical scales are generous: a parameter that starts at zero (every candidate effect of
/// the diagnosis does) is stepped by the typical scale alone, and the step must move the tool
/// well above the round-off of metre-sized positions (1e-16 m) even under small loads. A
/// compliance stepped by 1e-13 rad/(N m) under the 0.1 N m of a lateral moment moves it by
/// 1e-14 m, which the identifiability analysis cannot tell from zero.
fn step(theta: &[f64], k: usize, p: &SpaceParam) -> (Vec<f64>, f64) {
    let typical = if p.info.sigma.is_finite() {
        p.info.sigma
    } else {
        typical_size(&p.info)
    };
    let mut h = 1e-6 * theta[k].abs().max(typical);
    if theta[k] + h > p.info.upper {
        h = -h;
    }
    (theta.to_vec(), h)
}

/// How many prior standard deviations a parameter the data barely determine may move.
pub const PRIOR_BOX: f64 = 3.0;

/// The parameters of `free` with a prior that the data barely determine: with the data their
/// standard deviation (linearised at the start, `jac` holding the columns of `selected`) is
/// still above half their prior's, so the data adds less than three times the prior's
/// information. A model error can push such a parameter far along a direction the data hardly
/// sees (a prismatic joint's length against a marker); its prior then bounds it.
fn barely_seen(space: &ParameterSpace, jac: &DMatrix<f64>, selected: &[usize], free: &[usize]) -> Vec<usize> {
    let cols: Vec<usize> = free
        .iter()
        .map(|k| {
            selected
                .iter()
                .position(|s| s == k)
                .expect("free parameters are selected")
        })
        .collect();
    let j = DMatrix::from_fn(jac.nrows(), cols.len(), |r, c| jac[(r, cols[c])]);
    let mut a = j.transpose() * &j;
    for (c, &k) in free.iter().enumerate() {
        a[(c, c)] += space.params[k].info.sigma.powi(-2);
    }
    let Some(chol) = a.cholesky() else {
        return Vec::new();
    };
    let inv = chol.inverse();
    free.iter()
        .enumerate()
        .filter(|&(c, &k)| {
            let sigma = space.params[k].info.sigma;
            sigma.is_finite() && inv[(c, c)].sqrt() > 0.5 * sigma
        })
        .map(|(_, &k)| k)
        .collect()
}

/// Finds the directions the data cannot determine and decides what to fix (see the module
/// documentation). `jac` holds the columns of `free`.
fn analyse(
    space: &ParameterSpace,
    jac: &DMatrix<f64>,
    free: &[usize],
    tol: f64,
) -> (IdentifiabilityReport, Vec<usize>) {
    let norms: Vec<f64> = (0..jac.ncols()).map(|c| jac.column(c).norm()).collect();
    let has_prior = |c: usize| space.params[free[c]].info.sigma.is_finite();
    let name = |c: usize| space.params[free[c]].info.name.clone();
    let mut fixed: Vec<usize> = Vec::new(); // column positions
    let mut deficiencies = Vec::new();
    // Scaled normal matrix over a set of columns, its eigen-decomposition, and the null basis.
    let null_space = |cols: &[usize]| -> (SymmetricEigen<f64, nalgebra::Dyn>, Vec<usize>, f64) {
        let scaled = DMatrix::from_fn(jac.nrows(), cols.len(), |r, c| {
            let n = norms[cols[c]];
            if n > 0.0 { jac[(r, cols[c])] / n } else { 0.0 }
        });
        let eig = SymmetricEigen::new(scaled.transpose() * &scaled);
        let max = eig.eigenvalues.iter().copied().fold(0.0, f64::max);
        let null = (0..cols.len())
            .filter(|&i| eig.eigenvalues[i] <= tol * tol * max)
            .collect();
        (eig, null, max)
    };
    let all: Vec<usize> = (0..free.len()).collect();
    let (eig_all, null_all, max_all) = null_space(&all);
    let min_all = eig_all.eigenvalues.iter().copied().fold(f64::INFINITY, f64::min);
    let rank = free.len() - null_all.len();
    let condition_number = if null_all.is_empty() && min_all > 0.0 {
        (max_all / min_all).sqrt()
    } else {
        f64::INFINITY
    };
    // Fix, one at a time, the dominant parameter of a null direction no prior holds.
    loop {
        let active: Vec<usize> = all.iter().copied().filter(|c| !fixed.contains(c)).collect();
        if active.is_empty() {
            break;
        }
        let (eig, null, _) = null_space(&active);
        if null.is_empty() {
            break;
        }
        // Null basis rows of the parameters with priors; a combination of basis vectors that
        // vanishes there is a direction nothing holds.
        let basis = DMatrix::from_fn(active.len(), null.len(), |r, c| eig.eigenvectors[(r, null[c])]);
        let prior_rows: Vec<usize> = (0..active.len()).filter(|&r| has_prior(active[r])).collect();
        let free_direction = if prior_rows.is_empty() {
            Some(basis.column(0).into_owned())
        } else {
            let sub = DMatrix::from_fn(prior_rows.len(), null.len(), |r, c| basis[(prior_rows[r], c)]);
            // Eigenvectors of subᵀ·sub with (numerically) zero eigenvalue span them.
            let gram = (sub.transpose() * &sub).symmetric_eigen();
            (0..null.len())
                .find(|&i| gram.eigenvalues[i] <= 1e-12)
                .map(|i| &basis * gram.eigenvectors.column(i))
        };
        let Some(direction) = free_direction else {
            // Every remaining null direction involves a prior: report them as regularised.
            for v in sparse_basis(&basis) {
                deficiencies.push(Deficiency {
                    combination: combination(&v, &active, &name),
                    action: "regularised".into(),
                    fixed: None,
                });
            }
            break;
        };
        let (pos, _) = direction
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .expect("a direction has entries");
        let col = active[pos];
        deficiencies.push(Deficiency {
            combination: combination(&direction, &active, &name),
            action: "fixed".into(),
            fixed: Some(name(col)),
        });
        fixed.push(col);
    }
    let mut message = String::new();
    let n_equations = jac.nrows();
    if n_equations < free.len() {
        message.push_str(&format!(
            "{} measured positions give {n_equations} equations for {} parameters, too few to determine them all. ",
            n_equations / 3,
            free.len()
        ));
    }
    if !deficiencies.is_empty() {
        // The largest combinations first: they say most about how the parameters trade off.
        let mut shown: Vec<&Deficiency> = deficiencies.iter().collect();
        shown.sort_by_key(|d| std::cmp::Reverse(d.combination.len()));
        let list: Vec<String> = shown
            .iter()
            .take(10)
            .map(|d| {
                let names: Vec<&str> = d.combination.iter().map(|(n, _)| n.as_str()).collect();
                match &d.fixed {
                    Some(f) => format!("{{{}}} (fixed {f})", names.join(", ")),
                    None => format!("{{{}}} (held by priors)", names.join(", ")),
                }
            })
            .collect();
        let held = deficiencies.iter().filter(|d| d.fixed.is_none()).count();
        let more = deficiencies.len().saturating_sub(list.len());
        message.push_str(&format!(
            "The data cannot determine {} combination(s) of parameters ({} held by priors, {} fixed){}: {}{}.",
            deficiencies.len(),
            held,
            deficiencies.len() - held,
            if more > 0 { "; the largest" } else { "" },
            list.join("; "),
            if more > 0 {
                format!("; and {more} more (the JSON report lists all)")
            } else {
                String::new()
            }
        ));
    }
    let report = IdentifiabilityReport {
        n_equations,
        n_params: free.len(),
        rank,
        condition_number,
        condition_number_free: f64::NAN,
        deficiencies,
        held_by_priors: Vec::new(),
        message,
    };
    (report, fixed.iter().map(|&c| free[c]).collect())
}

/// A basis of the column space of `basis` (one null direction per column) that is as sparse as
/// Gauss–Jordan elimination with full pivoting makes it: each vector has one pivot parameter
/// that no other vector contains, so the combinations read like "these few move together"
/// rather than eigenvectors mixing everything.
fn sparse_basis(basis: &DMatrix<f64>) -> Vec<DVector<f64>> {
    let mut m = basis.transpose(); // one direction per row
    let (rows, cols) = m.shape();
    let mut used_cols = vec![false; cols];
    for r in 0..rows {
        let mut best = (r, 0, 0.0);
        for i in r..rows {
            for c in (0..cols).filter(|&c| !used_cols[c]) {
                if m[(i, c)].abs() > best.2 {
                    best = (i, c, m[(i, c)].abs());
                }
            }
        }
        let (i, c, v) = best;
        if v == 0.0 {
            break;
        }
        m.swap_rows(r, i);
        used_cols[c] = true;
        let pivot = m[(r, c)];
        let row = m.row(r) / pivot;
        m.set_row(r, &row);
        for k in (0..rows).filter(|&k| k != r) {
            let f = m[(k, c)];
            if f != 0.0 {
                let updated = m.row(k) - row.clone() * f;
                m.set_row(k, &updated);
            }
        }
    }
    (0..rows).map(|r| m.row(r).transpose()).collect()
}

/// The entries of a null direction worth naming (at least a tenth of the largest), largest
/// first, normalised so that the largest is ±1.
fn combination(v: &DVector<f64>, cols: &[usize], name: &impl Fn(usize) -> String) -> Vec<(String, f64)> {
    let max = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let sign = v.iter().find(|x| x.abs() == max).map_or(1.0, |x| x.signum());
    let mut out: Vec<(String, f64)> = v
        .iter()
        .enumerate()
        .filter(|(_, x)| x.abs() >= 0.1 * max)
        .map(|(i, x)| (name(cols[i]), x * sign / max))
        .collect();
    out.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
    out
}

/// What the data determine of the selected parameters, before any fitting.
struct Assessment {
    report: IdentifiabilityReport,
    /// The selected parameters left free (not fixed as undeterminable).
    free: Vec<usize>,
    /// The free parameters the data barely determine (see [`barely_seen`]).
    held: Vec<usize>,
}

/// The identifiability of the parameters `selected` from the Jacobian `jac` (residuals in units
/// of the noise, columns of `selected`): what cannot be determined (fixed or held by priors)
/// and what is barely determined, with the report saying so.
fn assess(space: &ParameterSpace, jac: &DMatrix<f64>, selected: &[usize], tol: f64) -> Assessment {
    let (mut report, fixed) = analyse(space, jac, selected, tol);
    let free: Vec<usize> = selected.iter().copied().filter(|k| !fixed.contains(k)).collect();
    let held = barely_seen(space, jac, selected, &free);
    if !held.is_empty() {
        report.held_by_priors = held.iter().map(|&k| space.params[k].info.name.clone()).collect();
        let sep = if report.message.is_empty() { "" } else { " " };
        report.message.push_str(&format!(
            "{sep}{} parameter(s) the data barely determine are kept within {PRIOR_BOX} prior standard deviations \
             of their start: {}.",
            held.len(),
            report.held_by_priors.join(", ")
        ));
    }
    Assessment { report, free, held }
}

/// The condition number of the normal matrix `a` (priors included) after scaling it to a unit
/// diagonal, and the diagonal of its inverse (infinite when singular).
fn normal_equations(a: &DMatrix<f64>) -> (f64, Vec<f64>) {
    let n = a.nrows();
    let scale = DVector::from_iterator(n, (0..n).map(|c| a[(c, c)].sqrt().max(1e-300)));
    let scaled = DMatrix::from_fn(n, n, |i, k| a[(i, k)] / (scale[i] * scale[k]));
    let eig = scaled.clone().symmetric_eigen();
    let (emin, emax) = eig
        .eigenvalues
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| (lo.min(*v), hi.max(*v)));
    let condition = if emin > 0.0 {
        (emax / emin).sqrt()
    } else {
        f64::INFINITY
    };
    let inv_diag = match scaled.try_inverse() {
        Some(inv) => (0..n).map(|c| inv[(c, c)] / (scale[c] * scale[c])).collect(),
        None => vec![f64::INFINITY; n],
    };
    (condition, inv_diag)
}

/// The robot's parameter space with the priors `params` asks for (scaled by its
/// `prior_scale`, or none).
fn prior_space(robot: &Robot, params: &CalibrationParams) -> ParameterSpace {
    let mut space = ParameterSpace::new(robot);
    for p in &mut space.params {
        p.info.sigma = if params.use_priors {
            p.info.sigma * params.prior_scale
        } else {
            f64::INFINITY
        };
    }
    space
}

/// How well measurements at the configurations of `samples` (their measured positions are not
/// used) would determine the parameters `params.identify` selects, before any fit: the
/// identifiability report [`calibrate`] starts from (linearised at the robot's values, the
/// measurement frame as the robot file guesses it), with the condition number over the free
/// parameters with their priors. For judging a set of poses before measuring it.
pub fn identifiability(robot: &Robot, samples: &[Sample], params: &CalibrationParams) -> Result<IdentifiabilityReport> {
    if samples.is_empty() {
        return Err(Error::Input("an identifiability report needs at least one pose".into()));
    }
    let space = prior_space(robot, params);
    let selected = space.select(robot, &params.identify)?;
    let problem = Problem {
        robot,
        space: &space,
        samples,
        sigma: params.measurement_std,
    };
    let theta = space.initial();
    let (d, e, _) = problem.predict(&theta)?;
    let jac = problem.jacobian(&theta, &d, &e, &selected, JacobianForm::Exact)?;
    let Assessment { mut report, free, .. } = assess(&space, &jac, &selected, params.rank_tolerance);
    let cols: Vec<usize> = free
        .iter()
        .map(|k| {
            selected
                .iter()
                .position(|s| s == k)
                .expect("free parameters are selected")
        })
        .collect();
    let j = DMatrix::from_fn(jac.nrows(), cols.len(), |r, c| jac[(r, cols[c])]);
    let mut a = j.transpose() * &j;
    for (c, &k) in free.iter().enumerate() {
        a[(c, c)] += space.params[k].info.sigma.powi(-2);
    }
    report.condition_number_free = normal_equations(&a).0;
    Ok(report)
}

/// Identifies the parameters chosen by `params.identify` from `samples` (measured positions
/// in the measurement frame). `observer` sees every iteration (for a progress display).
///
/// The fit is staged so that a poor guess of the measurement frame cannot leak into the chain:
/// when the whole base frame is identified it is first registered in closed form (the
/// measured points against the nominal model's), then the measurement frame and markers are
/// fitted alone, and only then everything selected, each stage starting where the last ended.
/// Parameters the data cannot determine are reported and held (see the module documentation);
/// when the iteration limit is reached the best parameters found are kept and the report says
/// it did not converge.
pub fn calibrate(
    robot: &Robot,
    samples: &[Sample],
    params: &CalibrationParams,
    observer: &mut dyn FnMut(&IterationInfo),
) -> Result<Calibration> {
    if samples.is_empty() {
        return Err(Error::Input("calibration needs at least one measurement".into()));
    }
    if !(params.measurement_std.is_finite() && params.measurement_std > 0.0) {
        return Err(Error::Input(format!(
            "the measurement noise must be positive, got {} m",
            params.measurement_std
        )));
    }
    if params.identify.iter().any(|w| w.trim().is_empty()) {
        return Err(Error::Input(
            "--identify has an empty entry; name what to identify (base, markers, geometry, offsets, errors, all, \
             an error model type or a parameter pattern such as `j2.*`)"
                .into(),
        ));
    }
    if params.prior_scale.is_nan() || params.prior_scale <= 0.0 {
        return Err(Error::Input(format!(
            "the prior scale must be positive (or infinite for no priors), got {}",
            params.prior_scale
        )));
    }
    for (i, s) in samples.iter().enumerate() {
        robot
            .tree()
            .check_q(&s.q)
            .map_err(|e| Error::Input(format!("sample {}: {e}", i + 1)))?;
        if s.point >= robot.tree().points().len() {
            return Err(Error::Input(format!(
                "sample {}: point index {} does not exist",
                i + 1,
                s.point
            )));
        }
    }
    let space = prior_space(robot, params);
    let selected = space.select(robot, &params.identify)?;
    let problem = Problem {
        robot,
        space: &space,
        samples,
        sigma: params.measurement_std,
    };
    // The priors' centre: the robot's values, the measurement frame as registered.
    let mut theta0 = space.initial();
    let (_, _, pred) = problem.predict(&theta0)?;
    // A model whose residuals overflow cannot be fitted; say which value to look at.
    if let Some(i) = (0..samples.len()).find(|&i| !(pred[i] - samples[i].position).norm_squared().is_finite()) {
        return Err(Error::Input(format!(
            "the robot model puts sample {}'s point at {:?} m, too far for a finite residual; a value in the robot \
             file is out of range",
            i + 1,
            pred[i].as_slice()
        )));
    }
    let before = stats(samples, &pred);
    let base: Vec<usize> = (space.base_offset..space.base_offset + 6).collect();
    let registered = base.iter().all(|k| selected.contains(k)) && register_base(&space, &mut theta0, samples, &pred);
    let (d, e, _) = problem.predict(&theta0)?;

    // Identifiability at the start decides what is held.
    let jac0 = problem.jacobian(&theta0, &d, &e, &selected, JacobianForm::Exact)?;
    let Assessment {
        report: mut identifiability,
        free,
        held,
    } = assess(&space, &jac0, &selected, params.rank_tolerance);
    let mut held_space = space.clone();
    for &k in &held {
        let info = &mut held_space.params[k].info;
        info.lower = info.lower.max(theta0[k] - PRIOR_BOX * info.sigma);
        info.upper = info.upper.min(theta0[k] + PRIOR_BOX * info.sigma);
    }
    let problem = Problem {
        space: &held_space,
        ..problem
    };
    let frames: Vec<usize> = free
        .iter()
        .copied()
        .filter(|&k| matches!(space.params[k].group, ParamGroup::Base | ParamGroup::Marker(_)))
        .collect();
    let mut stage = Stage {
        theta: theta0.clone(),
        d,
        e,
        iterations: 0,
    };
    let mut outcome = StageOutcome {
        converged: free.is_empty(),
        stop_reason: "nothing to identify".into(),
    };
    if !frames.is_empty() && frames.len() < free.len() {
        problem.levenberg_marquardt(&mut stage, &theta0, &frames, params, observer)?;
    }
    if !free.is_empty() {
        outcome = problem.levenberg_marquardt(&mut stage, &theta0, &free, params, observer)?;
    }
    let mut restarts_rms_mm = Vec::new();
    if !free.is_empty() && problem.rms_over_noise(&stage) > RESTART_ABOVE_NOISE {
        let mut best_cost = problem.cost(&stage, &theta0, &free);
        let mut rng = StdRng::seed_from_u64(params.seed);
        for _ in 0..params.restarts {
            let mut start = stage.theta.clone();
            for &k in &free {
                // One draw per parameter whether used or not, so that two fits sharing their
                // first parameters (a baseline and a candidate) start from the same geometry.
                let z: f64 = StandardNormal.sample(&mut rng);
                let info = &held_space.params[k].info;
                let spread = if info.multimodal {
                    typical_size(info)
                } else {
                    info.sigma
                };
                if spread.is_finite() {
                    start[k] = (start[k] + z * spread).clamp(info.lower, info.upper);
                }
            }
            let Ok((d, e, _)) = problem.predict(&start) else {
                continue;
            };
            let mut trial = Stage {
                theta: start,
                d,
                e,
                iterations: 0,
            };
            let trial_outcome = problem.levenberg_marquardt(&mut trial, &theta0, &free, params, observer)?;
            restarts_rms_mm.push(problem.rms_over_noise(&trial) * 3f64.sqrt() * params.measurement_std * 1e3);
            let cost = problem.cost(&trial, &theta0, &free);
            if cost < best_cost {
                (best_cost, stage, outcome) = (cost, trial, trial_outcome);
            }
        }
    }
    let Stage {
        theta,
        d,
        e,
        iterations,
    } = stage;

    // Linearised covariance at the solution, scaled by the fit's own residual variance.
    let pred = to_meas(&d.t_meas_base, &e.world);
    let r = problem.residuals(&pred);
    let j = problem.jacobian(&theta, &d, &e, &free, JacobianForm::Exact)?;
    let mut a = j.transpose() * &j;
    for (c, &k) in free.iter().enumerate() {
        a[(c, c)] += space.params[k].info.sigma.powi(-2);
    }
    let dof = (r.len() as f64 - free.len() as f64).max(1.0);
    let s2 = r.norm_squared() / dof;
    let (condition_number_free, inv_diag) = normal_equations(&a);
    identifiability.condition_number_free = condition_number_free;
    let cov_diag: Vec<f64> = inv_diag.iter().map(|v| s2 * v).collect();
    let initial = space.initial();
    let params_out = selected
        .iter()
        .map(|&k| {
            // The bounds the fit kept, the prior's box included.
            let info = &held_space.params[k].info;
            let c = free.iter().position(|&f| f == k);
            ParamResult {
                name: info.name.clone(),
                quantity: info.quantity,
                unit: info.quantity.si_unit(),
                initial: initial[k],
                value: theta[k],
                std: c.map_or(0.0, |c| cov_diag[c].max(0.0).sqrt()),
                fixed: c.is_none(),
                at_bound: c.is_some() && (theta[k] <= info.lower || theta[k] >= info.upper),
                plausible: info.is_plausible(theta[k]),
            }
        })
        .collect();

    let after = stats(samples, &pred);
    let rms_over_noise = after.rms_mm * 1e-3 / (3f64.sqrt() * params.measurement_std);
    // Mislabelled units are looked for whatever the fit reached: with enough freedom a fit
    // can shrink the arm onto positions read a thousand times too small.
    let unit_mistake = unit_mistake(&problem, &theta0)?;
    let mut warnings = Vec::new();
    if rms_over_noise > FAR_ABOVE_NOISE || rms_over_noise.is_nan() {
        warnings.push(format!(
            "the fit's RMS ({:.4} mm) is {rms_over_noise:.0} times what the declared noise ({} mm per axis) gives \
             (√3·σ = {:.4} mm)",
            after.rms_mm,
            params.measurement_std * 1e3,
            3f64.sqrt() * params.measurement_std * 1e3
        ));
        if unit_mistake.is_none() {
            warnings.push(
                "likely causes: wrong units in the data or the robot file, measurements of another point than the \
                 markers (or rows mixed up), the noise declared too small, or an effect the model lacks (try \
                 `armcomp diagnose`)"
                    .into(),
            );
        }
    }
    let units_mislabelled = unit_mistake.is_some();
    warnings.extend(unit_mistake);
    // A value no real robot has says the model explains the data with the wrong effect.
    warnings.extend(
        selected
            .iter()
            .filter(|&&k| free.contains(&k))
            .filter_map(|&k| held_space.params[k].info.implausibility(theta[k])),
    );
    let calibrated = apply(robot, &space, &theta)?;
    Ok(Calibration {
        robot: calibrated,
        report: CalibrationReport {
            n_samples: samples.len(),
            measured_chain: robot.measured_joint_names(),
            registered,
            prior_scale: params.use_priors.then_some(params.prior_scale),
            identifiability,
            params: params_out,
            iterations,
            restarts_rms_mm,
            converged: outcome.converged,
            stop_reason: outcome.stop_reason,
            before,
            after,
            rms_over_noise,
            units_mislabelled,
            warnings,
        },
    })
}

/// Where a fit stands: parameters, what they decode to, and the iterations so far.
struct Stage {
    theta: Vec<f64>,
    d: Decoded,
    e: Evaluation,
    iterations: usize,
}

/// How a Levenberg–Marquardt run ended.
struct StageOutcome {
    converged: bool,
    stop_reason: String,
}

impl Problem<'_> {
    /// Levenberg–Marquardt over the parameters `free`, from `stage`, with priors centred at
    /// `theta0`; leaves the best parameters found in `stage`.
    fn levenberg_marquardt(
        &self,
        stage: &mut Stage,
        theta0: &[f64],
        free: &[usize],
        params: &CalibrationParams,
        observer: &mut dyn FnMut(&IterationInfo),
    ) -> Result<StageOutcome> {
        let space = self.space;
        let prior_w: Vec<f64> = free.iter().map(|&k| 1.0 / space.params[k].info.sigma).collect();
        let cost_of = |theta: &[f64], r: &DVector<f64>| self.cost_of(theta, theta0, free, r);
        let Stage {
            theta,
            d,
            e,
            iterations,
        } = stage;
        let mut r = self.residuals(&to_meas(&d.t_meas_base, &e.world));
        let mut cost = cost_of(theta, &r);
        let mut lambda = 1e-3;
        let mut converged = false;
        // Why the last accepted step was small, when it was: the step test. Convergence needs
        // it and the gradient test at the point the step reached.
        let mut small_step: Option<String> = None;
        // Deformed robots iterate on the fast form while it makes progress, and finish on the
        // exact one, so the minimum and the convergence test are those of the true model.
        let mut form = if self.robot.error_models().is_empty() {
            JacobianForm::Exact
        } else {
            JacobianForm::HeldDeformation
        };
        let stop_reason = loop {
            crate::interrupt::check()?;
            let j = self.jacobian(theta, d, e, free, form)?;
            let mut a = j.transpose() * &j;
            let mut g = j.transpose() * &r;
            for (c, (&k, w)) in free.iter().zip(&prior_w).enumerate() {
                a[(c, c)] += w * w;
                g[c] += w * w * (theta[k] - theta0[k]);
            }
            let floor = 1e-12 * a.diagonal().max().max(1e-300);
            // Standard deviations (in units of the noise) from the undamped normal matrix, to
            // judge whether a step still moves anything that matters.
            let std: Vec<f64> = match a.clone().cholesky() {
                Some(c) => {
                    let inv = c.inverse();
                    (0..free.len()).map(|i| inv[(i, i)].max(0.0).sqrt()).collect()
                }
                None => vec![f64::INFINITY; free.len()],
            };
            // The gradient test, made independent of scale and correlation: how far the full
            // Newton step from here (the bounds respected) would move each parameter, in its
            // standard deviations. At a minimum it moves nothing that matters; a damped crawl
            // far from one leaves a large step. Correlated parameters whose gradients cancel
            // in combination pass, and a parameter held at its bound by the data passes.
            // Where the matrix is singular, each parameter's gradient over its own curvature.
            let blocked = |c: usize, step: f64| {
                let b = &space.params[free[c]].info;
                let v = theta[free[c]];
                (v <= b.lower && step < 0.0) || (v >= b.upper && step > 0.0)
            };
            let newton = bounded_step(&a, &g, blocked).unwrap_or_else(|| {
                DVector::from_iterator(free.len(), (0..free.len()).map(|c| g[c] / a[(c, c)].max(floor)))
            });
            let gradient = newton
                .iter()
                .enumerate()
                .map(|(c, dc)| {
                    let sd = if std[c].is_finite() {
                        std[c]
                    } else {
                        1.0 / a[(c, c)].max(floor).sqrt()
                    };
                    (dc / sd).abs()
                })
                .fold(0.0, |m: f64, v| if v.is_nan() { f64::NAN } else { m.max(v) });
            let gradient_ok = gradient <= params.min_step;
            if let Some(step) = small_step.as_ref().filter(|_| gradient_ok) {
                converged = true;
                break format!("{step}, and the Newton step is {gradient:.1e} standard deviations");
            }
            if *iterations >= params.max_iterations {
                break format!(
                    "iteration limit ({}) reached; the Newton step is {gradient:.1e} standard deviations",
                    params.max_iterations
                );
            }
            *iterations += 1;
            let mut accepted = false;
            while lambda <= 1e12 {
                let mut m = a.clone();
                for c in 0..free.len() {
                    m[(c, c)] += lambda * a[(c, c)].max(floor);
                }
                let Some(delta) = bounded_step(&m, &g, blocked) else {
                    lambda *= 10.0;
                    continue;
                };
                let mut trial = theta.clone();
                for (c, &k) in free.iter().enumerate() {
                    let b = &space.params[k].info;
                    trial[k] = (theta[k] + delta[c]).clamp(b.lower, b.upper);
                }
                let Ok((d1, e1, pred1)) = self.predict(&trial) else {
                    lambda *= 4.0;
                    continue;
                };
                let r1 = self.residuals(&pred1);
                let cost1 = cost_of(&trial, &r1);
                if cost1.is_finite() && cost1 < cost {
                    let improvement = cost - cost1;
                    let relative = improvement / cost.max(1e-300);
                    let moved = free
                        .iter()
                        .zip(&std)
                        .map(|(&k, sd)| (trial[k] - theta[k]).abs() / sd)
                        .fold(0.0, f64::max);
                    (*theta, *d, *e, r, cost) = (trial, d1, e1, r1, cost1);
                    lambda = (lambda / 3.0).max(1e-12);
                    accepted = true;
                    // Once a step gains less than the noise can tell apart (½χ² by less than
                    // one), the fast form's error matters more than its speed.
                    if improvement < 1.0 {
                        form = JacobianForm::Exact;
                    }
                    small_step = if relative < params.tolerance || improvement < params.min_improvement {
                        Some(format!("the last step improved ½χ² by only {improvement:.2e}"))
                    } else if moved < params.min_step {
                        Some(format!(
                            "the last step moved no parameter by more than {:.1}% of its standard deviation",
                            100.0 * moved
                        ))
                    } else {
                        None
                    };
                    break;
                }
                lambda *= 4.0;
            }
            observer(&IterationInfo {
                iteration: *iterations,
                max_iterations: params.max_iterations,
                rms: (r.norm_squared() / self.samples.len() as f64).sqrt() * params.measurement_std,
                lambda,
            });
            if !accepted && form == JacobianForm::HeldDeformation {
                form = JacobianForm::Exact;
                small_step = None;
                lambda = 1e-3;
                continue;
            }
            if !accepted {
                // No step lowers the cost: a minimum if the gradient vanishes there, otherwise
                // the model cannot be evaluated or differentiated near here.
                converged = gradient_ok && cost.is_finite();
                break if converged {
                    format!("no step lowers the cost further; the Newton step is {gradient:.1e} standard deviations")
                } else {
                    format!(
                        "no step lowers the cost, but the Newton step is {gradient:.1e} standard deviations \
                         (cost {cost:.3e}): not a minimum"
                    )
                };
            }
        };
        Ok(StageOutcome { converged, stop_reason })
    }
}

/// The damped step `−m⁻¹g` with the parameters that sit at a bound and would step out of it
/// held (`blocked(c, step)`): solving for the others alone keeps the step a descent direction
/// of the free ones, where clipping the full step to the bounds distorts it and leaves the
/// solver crawling. `None` when the matrix is not positive definite.
fn bounded_step(m: &DMatrix<f64>, g: &DVector<f64>, blocked: impl Fn(usize, f64) -> bool) -> Option<DVector<f64>> {
    let n = g.len();
    let mut held = vec![false; n];
    loop {
        let mut mm = m.clone();
        let mut rhs = -g;
        for c in (0..n).filter(|&c| held[c]) {
            mm.row_mut(c).fill(0.0);
            mm.column_mut(c).fill(0.0);
            mm[(c, c)] = 1.0;
            rhs[c] = 0.0;
        }
        let delta = mm.cholesky()?.solve(&rhs);
        let newly: Vec<usize> = (0..n).filter(|&c| !held[c] && blocked(c, delta[c])).collect();
        if newly.is_empty() {
            return Some(delta);
        }
        newly.into_iter().for_each(|c| held[c] = true);
    }
}

/// Registers the measurement frame in closed form: the rigid transform that best maps the
/// model's points (robot base frame) onto the measured ones (see [`rigid_fit`]). Writes it
/// into the base parameters of `theta` and returns true, or leaves `theta` alone and returns
/// false when the points do not span a plane (a rotation is then not determined).
fn register_base(space: &ParameterSpace, theta: &mut [f64], samples: &[Sample], measured_now: &[Vector3<f64>]) -> bool {
    // `measured_now` are the model's points seen through the current base frame; map them
    // back into the base frame.
    let t_now = space.base_pose(theta);
    let model: Vec<Vector3<f64>> = measured_now
        .iter()
        .map(|p| t_now.inverse_transform_point(&(*p).into()).coords)
        .collect();
    let measured: Vec<Vector3<f64>> = samples.iter().map(|s| s.position).collect();
    let Some((rotation, v)) = rigid_fit(&model, &measured) else {
        return false;
    };
    let (r, p, y) = rotation.euler_angles();
    let values = [v.x, v.y, v.z, r, p, y];
    theta[space.base_offset..space.base_offset + 6].copy_from_slice(&values);
    true
}

/// The rigid transform (rotation, then translation) that best maps `model` onto `measured` in
/// least squares, by the SVD of their cross-covariance (Kabsch/Umeyama, no scale); none when
/// the points do not span a plane.
fn rigid_fit(model: &[Vector3<f64>], measured: &[Vector3<f64>]) -> Option<(Rotation3<f64>, Vector3<f64>)> {
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

/// RMS (m) of `measured` against `model` after the best rigid registration; infinite when
/// none is determined.
fn registered_rms(model: &[Vector3<f64>], measured: &[Vector3<f64>]) -> f64 {
    let Some((rotation, translation)) = rigid_fit(model, measured) else {
        return f64::INFINITY;
    };
    let sum: f64 = model
        .iter()
        .zip(measured)
        .map(|(m, s)| (rotation * m + translation - s).norm_squared())
        .sum();
    (sum / model.len() as f64).sqrt()
}

/// A unit mistake the data give away: the starting model registered rigidly onto the measured
/// points fits ten times better once the positions or the revolute joint values are read in
/// the other unit. The message names the mistake and the fix.
fn unit_mistake(problem: &Problem<'_>, theta0: &[f64]) -> Result<Option<String>> {
    let model_points = |samples: &[Sample]| -> Result<Vec<Vector3<f64>>> {
        let p = Problem { samples, ..*problem };
        Ok(p.predict(theta0)?.1.world)
    };
    let measured: Vec<Vector3<f64>> = problem.samples.iter().map(|s| s.position).collect();
    let model = model_points(problem.samples)?;
    let as_declared = registered_rms(&model, &measured);
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
        Ok(registered_rms(&model_points(&samples)?, &measured))
    };
    let deg = 180.0 / std::f64::consts::PI;
    let scaled = |f: f64| registered_rms(&model, &measured.iter().map(|p| p * f).collect::<Vec<_>>());
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

/// Sensitivity of every marker's measured position at each pose to the parameters `identify`
/// selects (as for [`calibrate`]): `3 × markers` rows per pose in pose order, one column per
/// parameter (m per SI unit). Returns the matrix and the parameter names.
pub fn identification_jacobian(
    robot: &Robot,
    poses: &[Vec<f64>],
    identify: &[String],
) -> Result<(DMatrix<f64>, Vec<String>)> {
    let samples: Vec<Sample> = poses.iter().flat_map(|q| marker_samples(robot, q)).collect();
    samples_jacobian(robot, &samples, identify)
}

/// One sample per marker of `robot` at configuration `q` (measured positions zero): what
/// measuring every marker there would give, for planning.
pub fn marker_samples(robot: &Robot, q: &[f64]) -> Vec<Sample> {
    robot
        .markers()
        .iter()
        .map(|&m| Sample {
            q: q.to_vec(),
            point: m,
            position: Vector3::zeros(),
            orientation: None,
            payload: None,
            temperature: None,
            torque: None,
        })
        .collect()
}

/// [`identification_jacobian`] at the configurations, points and conditions (payload,
/// temperature) of `samples`: three rows per sample, in sample order; their measured
/// positions are not used.
pub fn samples_jacobian(robot: &Robot, samples: &[Sample], identify: &[String]) -> Result<(DMatrix<f64>, Vec<String>)> {
    for s in samples {
        robot.tree().check_q(&s.q)?;
    }
    let space = ParameterSpace::new(robot);
    let selected = space.select(robot, identify)?;
    let problem = Problem {
        robot,
        space: &space,
        samples,
        sigma: 1.0,
    };
    let theta = space.initial();
    let (d, e, _) = problem.predict(&theta)?;
    let jac = problem.jacobian(&theta, &d, &e, &selected, JacobianForm::Exact)?;
    Ok((
        jac,
        selected.iter().map(|&k| space.params[k].info.name.clone()).collect(),
    ))
}

fn stats(samples: &[Sample], predicted: &[Vector3<f64>]) -> ErrorStats {
    let errors: Vec<Vector3<f64>> = samples.iter().zip(predicted).map(|(s, p)| s.position - p).collect();
    ErrorStats::from_errors(&errors)
}

impl ParameterSpace {
    /// The robot with every parameter of `theta` (a full vector, as [`initial`](Self::initial))
    /// written into its description.
    pub fn apply(&self, robot: &Robot, theta: &[f64]) -> Result<Robot> {
        apply(robot, self, theta)
    }

    /// Index of the parameter called `name`.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.params.iter().position(|p| p.info.name == name)
    }
}

fn apply(robot: &Robot, space: &ParameterSpace, theta: &[f64]) -> Result<Robot> {
    if theta.len() != space.params.len() {
        return Err(Error::Dimension {
            what: "calibration parameters".into(),
            expected: space.params.len(),
            got: theta.len(),
        });
    }
    let errors: Vec<Vec<f64>> = space
        .error_offsets
        .iter()
        .zip(robot.error_values())
        .map(|(&o, v)| theta[o..o + v.len()].to_vec())
        .collect();
    let mut file = robot.file_with(&theta[..space.n_chain], &errors);
    let units = file.units;
    let b = &theta[space.base_offset..space.base_offset + 6];
    let measurement = file.measurement.get_or_insert_with(Default::default);
    measurement.base_xyz = [b[0], b[1], b[2]].map(|v| units.len_out(v));
    measurement.base_rpy = [b[3], b[4], b[5]].map(|v| units.ang_out(v));
    for (i, &m) in robot.markers().iter().enumerate() {
        let name = &robot.tree().points()[m].name;
        let o = space.marker_offset + 3 * i;
        if let Some(p) = file.points.iter_mut().find(|p| &p.name == name) {
            for a in 0..3 {
                p.xyz[a] += units.len_out(theta[o + a]);
            }
        }
    }
    robot.rebuild(file)
}
