//! The C ABI between the armcomp host and a run-time plugin library, version [`ABI_VERSION`].
//!
//! Everything that crosses the library boundary is defined here: `#[repr(C)]` structs of plain
//! numbers, pointers and lengths, the status codes and the exported symbol names. Any change to
//! a layout or a signature bumps [`ABI_VERSION`]; the host refuses a library whose
//! `armcomp_abi_version()` differs.
//!
//! Conventions: SI units and radians; a pose is 7 numbers `[x, y, z, qi, qj, qk, qw]`
//! (translation, then the unit quaternion with the scalar last); a twist is 6 numbers
//! `[dx, dy, dz, δx, δy, δz]`; arrays are row-major, one entry after the other; "no value" is
//! NaN where a number is optional. Strings are UTF-8, not NUL-terminated, given as
//! pointer + length ([`AbiStr`]).
//!
//! Symbols a plugin exports (all `extern "C"`):
//!
//! | symbol | signature |
//! |---|---|
//! | `armcomp_abi_version` | `() -> u32` |
//! | `armcomp_type_count` | `() -> u32` |
//! | `armcomp_type_info` | `(index: u32, out: *mut AbiTypeInfo) -> i32` |
//! | `armcomp_last_error` | `() -> AbiStr` (message of the last failed call on this thread) |
//! | `armcomp_model_create` | `(type: u32, config_json: AbiStr, ctx: *const AbiModelContext, out: *mut *mut c_void) -> i32` |
//! | `armcomp_model_param_count` | `(model: *mut c_void) -> u32` |
//! | `armcomp_model_param` | `(model: *mut c_void, index: u32, out: *mut AbiParam) -> i32` |
//! | `armcomp_model_perturb` | `(model: *mut c_void, state: *const AbiState, values: *const f64, n_values: usize, out: *const AbiPerturbation) -> i32` |
//! | `armcomp_model_spec_with` | `(model: *mut c_void, values: *const f64, n_values: usize, out_json: *mut AbiStr) -> i32` |
//! | `armcomp_model_destroy` | `(model: *mut c_void)` |
//! | `armcomp_predictor_fit` | `(type: u32, config_json: AbiStr, data: *const AbiTrainingSet, out: *mut *mut c_void) -> i32` |
//! | `armcomp_predictor_load` | `(type: u32, fitted_json: AbiStr, out: *mut *mut c_void) -> i32` |
//! | `armcomp_predictor_shape` | `(predictor: *mut c_void, n_inputs: *mut usize, n_outputs: *mut usize) -> i32` |
//! | `armcomp_predictor_predict` | `(predictor: *mut c_void, input: *const f64, n_inputs: usize, out: *mut f64, n_outputs: usize, with_std: u32, out_std: *mut f64) -> i32` |
//! | `armcomp_predictor_save` | `(predictor: *mut c_void, out_json: *mut AbiStr) -> i32` |
//! | `armcomp_predictor_destroy` | `(predictor: *mut c_void)` |
//!
//! Every function but the destroyers returns a status: [`STATUS_OK`], [`STATUS_ERROR`] (the
//! message is in `armcomp_last_error`), [`STATUS_ISSUES`] (the last error is a JSON array of
//! `{"path": ..., "message": ...}` naming fields of the config) or [`STATUS_UNSUPPORTED`].
//!
//! Threads (since version 4): once created, a handle is only read. The host calls any entry
//! point but the destroyers on one handle from several threads at once: calibration evaluates
//! `armcomp_model_perturb` for many samples in parallel, and `armcomp_predictor_predict` is
//! called the same way. These two write only into the buffers the host passes in; whatever
//! scratch memory a plugin needs is its own per thread. Strings a plugin hands back stay valid
//! until the next call into the library on the same thread. A destroyer is called once, when
//! no other call on that handle runs, and the handle is not used afterwards. The SDK's export
//! side ([`export_plugins!`](crate::export_plugins)) meets this by construction: the core
//! traits require `Send + Sync`, a handle is only ever borrowed shared, and the buffers a call
//! reuses are thread-local.

use std::os::raw::c_void;

/// The ABI version this crate speaks. Bumped on any change of a layout, a signature or a
/// contract.
///
/// Version 2 added [`AbiTypeInfo::candidate_template`]; version 3 the input ranges of
/// [`AbiTrainingSet`]; version 4 made calls on one handle concurrent (see the module docs), so
/// [`AbiPerturbation`] is now buffers the host owns and the plugin fills.
pub const ABI_VERSION: u32 = 4;

/// The call succeeded.
pub const STATUS_OK: i32 = 0;
/// The call failed; `armcomp_last_error` says why.
pub const STATUS_ERROR: i32 = 1;
/// The config was rejected; `armcomp_last_error` is a JSON array of `{path, message}`.
pub const STATUS_ISSUES: i32 = 2;
/// The plugin does not provide this (e.g. a predictive standard deviation).
pub const STATUS_UNSUPPORTED: i32 = 3;

/// [`AbiTypeInfo::role`] of an error model.
pub const ROLE_ERROR_MODEL: u32 = 1;
/// [`AbiTypeInfo::role`] of a residual predictor.
pub const ROLE_PREDICTOR: u32 = 2;

/// [`AbiTree::joint_motions`]: the joint does not move.
pub const MOTION_FIXED: u32 = 0;
/// [`AbiTree::joint_motions`]: rotation about the axis.
pub const MOTION_REVOLUTE: u32 = 1;
/// [`AbiTree::joint_motions`]: translation along the axis.
pub const MOTION_PRISMATIC: u32 = 2;

/// [`AbiTree::joint_coordinates`]: a fixed joint, no value.
pub const COORDINATE_NONE: u32 = 0;
/// [`AbiTree::joint_coordinates`]: driven by the next independent coordinate of `q`.
pub const COORDINATE_INDEPENDENT: u32 = 1;
/// [`AbiTree::joint_coordinates`]: follows earlier coordinates through its coupling terms.
pub const COORDINATE_MIMIC: u32 = 2;

/// Quantity codes of [`AbiParam::quantity`]; `QUANTITY_OTHER` takes its unit from `unit`.
pub const QUANTITY_LENGTH: u32 = 0;
/// radians
pub const QUANTITY_ANGLE: u32 = 1;
/// a ratio without unit
pub const QUANTITY_DIMENSIONLESS: u32 = 2;
/// rad/(N m)
pub const QUANTITY_COMPLIANCE: u32 = 3;
/// kg
pub const QUANTITY_MASS: u32 = 4;
/// N m²
pub const QUANTITY_RIGIDITY: u32 = 5;
/// 1/K
pub const QUANTITY_PER_KELVIN: u32 = 6;
/// any other SI unit, named in [`AbiParam::unit`]
pub const QUANTITY_OTHER: u32 = 7;

/// Numbers per pose: `[x, y, z, qi, qj, qk, qw]`.
pub const POSE_LEN: usize = 7;
/// Numbers per twist: `[dx, dy, dz, δx, δy, δz]`.
pub const TWIST_LEN: usize = 6;

/// A UTF-8 string slice owned by the side that hands it over.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct AbiStr {
    /// First byte (may be null when `len` is 0).
    pub ptr: *const u8,
    /// Number of bytes.
    pub len: usize,
}

/// One plugin type a library provides.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct AbiTypeInfo {
    /// The type name robot files use (`model = "..."`).
    pub name: AbiStr,
    /// One line saying what it is.
    pub doc: AbiStr,
    /// [`ROLE_ERROR_MODEL`] or [`ROLE_PREDICTOR`].
    pub role: u32,
    /// 1 when the diagnosis workflow may try it as a missing effect.
    pub diagnosis_candidate: u32,
    /// JSON Schema of the config (draft 2020-12); empty for none.
    pub config_schema: AbiStr,
    /// How the diagnosis workflow instantiates a candidate error model, as the JSON of
    /// `armcomp_core::CandidateTemplate`: `{"per": "joint" | "link" | "global", "field": <the
    /// config field that takes the joint or link name>, "label": <what the effect is called>,
    /// "config": <the rest of the config at values that add nothing until calibrated>}`.
    /// Empty: once, globally, with an empty config, labelled with the type name.
    pub candidate_template: AbiStr,
}

/// The kinematic tree (see `armcomp_core::KinematicTree`): body 0 is the base, body `j + 1` the
/// child of joint `j`.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct AbiTree {
    /// Number of joints; there are `n_joints + 1` bodies.
    pub n_joints: usize,
    /// Number of named points.
    pub n_points: usize,
    /// Number of independent coordinates (length of `q`).
    pub n_coordinates: usize,
    /// Body names, `n_joints + 1`.
    pub body_names: *const AbiStr,
    /// Convention frame of each body in its tree frame, `7 × (n_joints + 1)`.
    pub body_convention_frames: *const f64,
    /// Joint names, `n_joints`.
    pub joint_names: *const AbiStr,
    /// Parent body of each joint, `n_joints`.
    pub joint_parents: *const usize,
    /// Joint frame in the parent body, `7 × n_joints`.
    pub joint_placements: *const f64,
    /// `MOTION_*` of each joint, `n_joints`.
    pub joint_motions: *const u32,
    /// Unit axis of each joint in its frame, `3 × n_joints` (zeros for fixed joints).
    pub joint_axes: *const f64,
    /// `COORDINATE_*` of each joint, `n_joints`.
    pub joint_coordinates: *const u32,
    /// Mimic terms of joint `j` are `coupling_starts[j]..coupling_starts[j + 1]`, `n_joints + 1`.
    pub coupling_starts: *const usize,
    /// Constant offset of each joint's coupling (0 unless mimic), `n_joints`.
    pub coupling_offsets: *const f64,
    /// Independent coordinate of each mimic term.
    pub coupling_coordinates: *const usize,
    /// Multiplier of each mimic term.
    pub coupling_multipliers: *const f64,
    /// `[lower, upper]` of each independent coordinate (NaN, NaN: unlimited), `2 × n_coordinates`.
    pub coordinate_limits: *const f64,
    /// Point names, `n_points`.
    pub point_names: *const AbiStr,
    /// Body of each point, `n_points`.
    pub point_bodies: *const usize,
    /// Pose of each point in its body frame, `7 × n_points`.
    pub point_locals: *const f64,
}

/// The mass model (see `armcomp_core::model::mass::MassModel`), per body in tree order.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct AbiMass {
    /// Number of bodies.
    pub n_bodies: usize,
    /// Mass of each body (kg).
    pub body_mass: *const f64,
    /// Centre of mass in the body frame (m), `3 × n_bodies`.
    pub body_com: *const f64,
    /// `[EI_y, EI_z, GJ]` (N m²) of each body seen as a beam, NaN for bodies without, `3 × n_bodies`.
    pub body_beam: *const f64,
    /// Payload mass (kg), NaN when there is no payload.
    pub payload_mass: f64,
    /// Body carrying the payload.
    pub payload_body: usize,
    /// Payload centre of mass in that body's frame (m).
    pub payload_com: [f64; 3],
}

/// What an error model is built against (see `armcomp_core::ModelContext`).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct AbiModelContext {
    /// The robot file's length unit (`m`, `cm`, `mm`, `in`): the config is written in it.
    pub length_unit: AbiStr,
    /// The robot file's angle unit (`rad`, `deg`).
    pub angle_unit: AbiStr,
    /// Field path of the config in the robot file, to prefix issue paths with.
    pub field_path: AbiStr,
    /// Folder of the robot file, for relative paths in the config.
    pub base_dir: AbiStr,
    /// The nominal tree.
    pub tree: AbiTree,
    /// The mass model, payload included.
    pub mass: AbiMass,
}

/// The static state an error model perturbs (see `armcomp_core::StaticState`): joint values, the
/// rigid frames, the loads.
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct AbiState {
    /// Independent joint values (rad, m), `n_q`.
    pub q: *const f64,
    /// Length of `q`.
    pub n_q: usize,
    /// Number of bodies (`n_joints + 1`).
    pub n_bodies: usize,
    /// Number of joints.
    pub n_joints: usize,
    /// Number of points.
    pub n_points: usize,
    /// World pose of each body (rigid forward kinematics), `7 × n_bodies`.
    pub body_frames: *const f64,
    /// World pose of each joint frame, before the joint's motion, `7 × n_joints`.
    pub joint_frames: *const f64,
    /// World pose of each point, `7 × n_points`.
    pub point_frames: *const f64,
    /// Value of each joint (rad, m; mimic joints resolved), `n_joints`.
    pub joint_values: *const f64,
    /// Gravity in the base frame (m/s²).
    pub gravity: [f64; 3],
    /// Ambient temperature (°C), NaN when the measurement gives none.
    pub temperature: f64,
    /// The mass model, payload included.
    pub mass: AbiMass,
}

/// Where a model writes its deformation: buffers the host owns, sized by the host for the tree
/// the model was built against. The plugin checks the counts against its own and writes every
/// entry (the host fills the buffers with NaN before the call, so an entry left out is
/// reported as a non-finite value).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct AbiPerturbation {
    /// Twist of each joint's placement, `6 × n_joint_twists`.
    pub joint_twists: *mut f64,
    /// Number of joint twists (the number of joints).
    pub n_joint_twists: usize,
    /// Offset added to each joint value, `n_joint_offsets`.
    pub joint_offsets: *mut f64,
    /// Number of joint offsets (the number of joints).
    pub n_joint_offsets: usize,
    /// Twist of each point's pose on its body, `6 × n_point_twists`.
    pub point_twists: *mut f64,
    /// Number of point twists (the number of points).
    pub n_point_twists: usize,
}

/// One identifiable parameter (see `armcomp_core::ParamInfo`).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct AbiParam {
    /// Stable dotted name, e.g. `cable_sag.mass_per_length`.
    pub name: AbiStr,
    /// `QUANTITY_*`.
    pub quantity: u32,
    /// SI unit symbol when `quantity` is [`QUANTITY_OTHER`], else empty.
    pub unit: AbiStr,
    /// Nominal value (SI).
    pub nominal: f64,
    /// Prior standard deviation (SI); infinity for none.
    pub sigma: f64,
}

/// Training data of a residual predictor (see `armcomp_core::TrainingSet`).
#[repr(C)]
#[derive(Debug, Clone, Copy)]
pub struct AbiTrainingSet {
    /// Inputs, row-major, `n_samples × n_inputs`.
    pub inputs: *const f64,
    /// Targets, row-major, `n_samples × n_outputs`.
    pub targets: *const f64,
    /// Number of rows.
    pub n_samples: usize,
    /// Inputs per row.
    pub n_inputs: usize,
    /// Outputs per row.
    pub n_outputs: usize,
    /// The range each input is used over (the robot's joint limits, rad or m), `2 ×
    /// n_input_ranges` numbers `[lower, upper]` per input, NaN bounds for an input of unknown
    /// range.
    pub input_ranges: *const f64,
    /// Inputs with a range entry: 0 (none known) or `n_inputs`.
    pub n_input_ranges: usize,
}

/// Signatures of the exported symbols, as the host calls them.
pub mod signatures {
    use super::*;

    /// `armcomp_abi_version`
    pub type AbiVersion = unsafe extern "C" fn() -> u32;
    /// `armcomp_type_count`
    pub type TypeCount = unsafe extern "C" fn() -> u32;
    /// `armcomp_type_info`
    pub type TypeInfo = unsafe extern "C" fn(u32, *mut AbiTypeInfo) -> i32;
    /// `armcomp_last_error`
    pub type LastError = unsafe extern "C" fn() -> AbiStr;
    /// `armcomp_model_create`
    pub type ModelCreate = unsafe extern "C" fn(u32, AbiStr, *const AbiModelContext, *mut *mut c_void) -> i32;
    /// `armcomp_model_param_count`
    pub type ModelParamCount = unsafe extern "C" fn(*mut c_void) -> u32;
    /// `armcomp_model_param`
    pub type ModelParam = unsafe extern "C" fn(*mut c_void, u32, *mut AbiParam) -> i32;
    /// `armcomp_model_perturb`
    pub type ModelPerturb =
        unsafe extern "C" fn(*mut c_void, *const AbiState, *const f64, usize, *const AbiPerturbation) -> i32;
    /// `armcomp_model_spec_with`
    pub type ModelSpecWith = unsafe extern "C" fn(*mut c_void, *const f64, usize, *mut AbiStr) -> i32;
    /// `armcomp_model_destroy`, `armcomp_predictor_destroy`
    pub type Destroy = unsafe extern "C" fn(*mut c_void);
    /// `armcomp_predictor_fit`
    pub type PredictorFit = unsafe extern "C" fn(u32, AbiStr, *const AbiTrainingSet, *mut *mut c_void) -> i32;
    /// `armcomp_predictor_load`
    pub type PredictorLoad = unsafe extern "C" fn(u32, AbiStr, *mut *mut c_void) -> i32;
    /// `armcomp_predictor_shape`
    pub type PredictorShape = unsafe extern "C" fn(*mut c_void, *mut usize, *mut usize) -> i32;
    /// `armcomp_predictor_predict`
    pub type PredictorPredict =
        unsafe extern "C" fn(*mut c_void, *const f64, usize, *mut f64, usize, u32, *mut f64) -> i32;
    /// `armcomp_predictor_save`
    pub type PredictorSave = unsafe extern "C" fn(*mut c_void, *mut AbiStr) -> i32;
}
