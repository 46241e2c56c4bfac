//! The plugin side of the ABI: what [`export_plugins!`](crate::export_plugins) expands to calls.
//!
//! Each entry point reads the host's flat arguments back into core types, runs the plugin's own
//! Rust implementation of the core traits inside `catch_unwind`, and turns every failure (an
//! error, rejected config, a panic) into a status code with a message for
//! `armcomp_last_error`.
//!
//! Calls on one handle may run on several threads at once (ABI version 4): a handle is only
//! ever borrowed shared, what it holds is `Send + Sync` (checked below at compile time), and the
//! buffers a call reuses, like the strings it hands back, are per thread.

use std::cell::{Cell, RefCell};
use std::os::raw::c_void;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;
use std::sync::OnceLock;

use armcomp_core::kinematics::subtree_loads::SubtreeLoads;
use armcomp_core::model::mass::MassModel;
use armcomp_core::support::io::InputLimits;
use armcomp_core::{
    AngleUnit, BuildContext, CandidateTemplate, ErrorModel, ErrorModelSpec, FittedPredictor, Issues, KinematicTree,
    LengthUnit, Limits, ModelContext, Perturbation, PredictorSpec, Quantity, StaticState, TrainingSet, TreeWorkspace,
    Units,
};
use nalgebra::Vector3;
use schemars::JsonSchema;
use schemars::generate::SchemaSettings;
use serde::de::DeserializeOwned;

use crate::abi::*;

// The `export_plugins!` expansion builds candidate templates with `json!`.
use crate::flat::{abi_str, frames_into, mass_into, slice, slice_mut, text, tree_from_abi};
use crate::per_thread::with_buffers;
pub use serde_json;

/// Why a call failed, before it becomes a status code.
enum Failure {
    /// A message for `armcomp_last_error`.
    Message(String),
    /// Config problems with their field paths.
    Issues(Issues),
}

impl From<String> for Failure {
    fn from(m: String) -> Self {
        Failure::Message(m)
    }
}

thread_local! {
    static LAST_ERROR: RefCell<String> = const { RefCell::new(String::new()) };
    /// The last string a call on this thread handed back (`spec_with`, `save`).
    static HANDED_BACK: RefCell<String> = const { RefCell::new(String::new()) };
}

/// The string in `key`; it stays there until the next write on this thread.
fn view(key: &'static std::thread::LocalKey<RefCell<String>>) -> AbiStr {
    key.with(|s| abi_str(&s.borrow()))
}

fn set_last_error(message: String) {
    LAST_ERROR.with(|e| *e.borrow_mut() = message);
}

/// `armcomp_last_error`: the message of the last failed call on this thread.
pub fn last_error() -> AbiStr {
    view(&LAST_ERROR)
}

/// Keeps `text` for the host until the next call on this thread hands back another string.
fn hand_back(text: String) -> AbiStr {
    HANDED_BACK.with(|s| *s.borrow_mut() = text);
    view(&HANDED_BACK)
}

fn panic_message(payload: &(dyn std::any::Any + Send)) -> String {
    match (payload.downcast_ref::<&str>(), payload.downcast_ref::<String>()) {
        (Some(s), _) => s.to_string(),
        (_, Some(s)) => s.clone(),
        _ => "a panic without message".to_string(),
    }
}

/// Runs `f`, turning its failures and panics into a status code and the last error.
fn guard(f: impl FnOnce() -> Result<i32, Failure>) -> i32 {
    match catch_unwind(AssertUnwindSafe(f)) {
        Ok(Ok(status)) => status,
        Ok(Err(Failure::Message(m))) => {
            set_last_error(m);
            STATUS_ERROR
        }
        Ok(Err(Failure::Issues(issues))) => {
            let list: Vec<_> = issues
                .0
                .iter()
                .map(|i| serde_json::json!({ "path": i.path, "message": i.message }))
                .collect();
            set_last_error(serde_json::Value::Array(list).to_string());
            STATUS_ISSUES
        }
        Err(payload) => {
            set_last_error(format!("the plugin panicked: {}", panic_message(payload.as_ref())));
            STATUS_ERROR
        }
    }
}

/// Builds an error model from its config JSON and the context.
pub type CreateModel = fn(&str, &ModelContext<'_>) -> Result<Box<dyn ErrorModel>, Issues>;
/// Fits a predictor from its config JSON and the data.
pub type FitPredictor = fn(&str, &TrainingSet<'_>) -> Result<Box<dyn FittedPredictor>, String>;

/// How one exported type is built; the macro fills this in with the author's types.
pub enum Constructor {
    /// An error model.
    ErrorModel(CreateModel),
    /// A residual predictor.
    Predictor(FitPredictor),
}

/// One type a plugin library exports.
pub struct TypeEntry {
    /// Its type name.
    pub name: &'static str,
    /// One line saying what it is.
    pub doc: &'static str,
    /// Whether diagnosis may try it.
    pub diagnosis_candidate: bool,
    /// How diagnosis instantiates it (a `CandidateTemplate` as JSON), when it says how.
    pub candidate_template: Option<fn() -> serde_json::Value>,
    /// How it is built.
    pub constructor: Constructor,
    /// JSON Schema of its config.
    pub schema: fn() -> String,
}

/// The JSON Schema (draft 2020-12) of a spec type, as text.
pub fn schema_of<S: JsonSchema>() -> String {
    SchemaSettings::draft2020_12()
        .into_generator()
        .into_root_schema_for::<S>()
        .to_value()
        .to_string()
}

/// Config issue for a JSON text that does not deserialise into `S`, at the failing field.
fn parse_config<S: DeserializeOwned>(config: &str, path: &str) -> Result<S, Issues> {
    let mut de = serde_json::Deserializer::from_str(config);
    serde_path_to_error::deserialize(&mut de).map_err(|e| {
        let field = e.path().to_string();
        let field = if field == "." {
            String::new()
        } else {
            format!(".{field}")
        };
        let mut issues = Issues::default();
        let message = e.into_inner().to_string();
        let message = message.split(" at line ").next().unwrap_or_default().to_string();
        issues.push(format!("{path}{field}"), message);
        issues
    })
}

/// Builds an error model of spec type `S` from its JSON config.
pub fn create_model<S: ErrorModelSpec + DeserializeOwned>(
    config: &str,
    ctx: &ModelContext<'_>,
) -> Result<Box<dyn ErrorModel>, Issues> {
    parse_config::<S>(config, ctx.build.path)?.build(ctx)
}

/// Fits a predictor of spec type `S` from its JSON config.
pub fn fit_predictor<S: PredictorSpec + DeserializeOwned>(
    config: &str,
    data: &TrainingSet<'_>,
) -> Result<Box<dyn FittedPredictor>, String> {
    let spec = parse_config::<S>(config, "config").map_err(|i| {
        i.0.iter()
            .map(|i| format!("{}: {}", i.path, i.message))
            .collect::<Vec<_>>()
            .join("; ")
    })?;
    spec.fit(data).map_err(|e| e.to_string())
}

/// The texts a type describes itself with, made once and kept for the life of the library
/// (the ABI hands out pointers into them).
pub struct TypeTexts {
    schema: String,
    candidate_template: String,
}

fn type_texts(t: &TypeEntry) -> Result<TypeTexts, String> {
    let candidate_template = match t.candidate_template {
        None => String::new(),
        Some(template) => {
            let text = template().to_string();
            // Checked here so that a malformed template fails when the library is loaded.
            CandidateTemplate::from_json(&text).map_err(|e| format!("type `{}`: {e}", t.name))?;
            text
        }
    };
    Ok(TypeTexts {
        schema: (t.schema)(),
        candidate_template,
    })
}

/// `armcomp_type_count`.
pub fn type_count(types: &[TypeEntry]) -> u32 {
    u32::try_from(types.len()).unwrap_or(u32::MAX)
}

fn entry(types: &[TypeEntry], index: u32) -> Result<&TypeEntry, Failure> {
    types
        .get(index as usize)
        .ok_or_else(|| Failure::Message(format!("no type {index}; this library has {}", types.len())))
}

/// `armcomp_type_info`.
///
/// # Safety
/// `out` must be valid for one write.
pub unsafe fn type_info(
    types: &[TypeEntry],
    texts: &OnceLock<Vec<Result<TypeTexts, String>>>,
    index: u32,
    out: *mut AbiTypeInfo,
) -> i32 {
    guard(|| {
        let t = entry(types, index)?;
        let texts = texts.get_or_init(|| types.iter().map(type_texts).collect());
        let own = texts[index as usize].as_ref().map_err(|e| e.clone())?;
        let info = AbiTypeInfo {
            name: abi_str(t.name),
            doc: abi_str(t.doc),
            role: match t.constructor {
                Constructor::ErrorModel(_) => ROLE_ERROR_MODEL,
                Constructor::Predictor(_) => ROLE_PREDICTOR,
            },
            diagnosis_candidate: u32::from(t.diagnosis_candidate),
            config_schema: abi_str(&own.schema),
            candidate_template: abi_str(&own.candidate_template),
        };
        // SAFETY: the caller guarantees `out` is valid for one write.
        unsafe { out.write(info) };
        Ok(STATUS_OK)
    })
}

/// An error model behind the ABI, with the tree it was built against; only read after creation.
struct ModelHandle {
    model: Box<dyn ErrorModel>,
    tree: KinematicTree,
}

/// A fitted predictor behind the ABI; only read after creation.
struct PredictorHandle {
    predictor: Box<dyn FittedPredictor>,
}

// ABI version 4 lets the host call one handle from several threads at once: what a handle
// holds must be shareable, and the entry points only borrow it shared.
const _: () = {
    const fn shareable<T: Send + Sync>() {}
    shareable::<ModelHandle>();
    shareable::<PredictorHandle>();
};

/// What a perturb call fills on the plugin side, reused by the calls of one thread.
struct PerturbBuffers {
    frames: TreeWorkspace,
    mass: MassModel,
    loads: SubtreeLoads,
    perturbation: Perturbation,
}

impl Default for PerturbBuffers {
    fn default() -> Self {
        PerturbBuffers {
            frames: TreeWorkspace {
                body: Vec::new(),
                joint_frame: Vec::new(),
                point: Vec::new(),
                joint_value: Vec::new(),
                motion: Vec::new(),
            },
            mass: MassModel::massless(0),
            loads: SubtreeLoads::default(),
            perturbation: Perturbation {
                joint_twist: Vec::new(),
                joint_offset: Vec::new(),
                point_twist: Vec::new(),
            },
        }
    }
}

impl PerturbBuffers {
    /// Sizes the buffers for `tree` and zeroes the perturbation; allocates only when a model of
    /// another tree (or one that resized its perturbation) used them last.
    fn fit(&mut self, tree: &KinematicTree) {
        let f = &self.frames;
        if (f.body.len(), f.joint_frame.len(), f.point.len())
            != (tree.bodies().len(), tree.joints().len(), tree.points().len())
        {
            self.frames = TreeWorkspace::new(tree);
        }
        let p = &self.perturbation;
        if (p.joint_twist.len(), p.joint_offset.len(), p.point_twist.len())
            == (tree.joints().len(), tree.joints().len(), tree.points().len())
        {
            self.perturbation.clear();
        } else {
            self.perturbation = Perturbation::zeros(tree);
        }
    }
}

thread_local! {
    static PERTURB_BUFFERS: Cell<Option<PerturbBuffers>> = const { Cell::new(None) };
    static PREDICT_SCRATCH: Cell<Option<Vec<f64>>> = const { Cell::new(None) };
}

/// `armcomp_model_create`.
///
/// # Safety
/// `config` and every pointer of `*ctx` must be valid as documented on [`AbiModelContext`];
/// `out` must be valid for one write.
pub unsafe fn model_create(
    types: &[TypeEntry],
    index: u32,
    config: AbiStr,
    ctx: *const AbiModelContext,
    out: *mut *mut c_void,
) -> i32 {
    guard(|| {
        let Constructor::ErrorModel(create) = entry(types, index)?.constructor else {
            return Err(format!("type {index} is not an error model").into());
        };
        // SAFETY: the caller guarantees `ctx` points to a valid context for this call.
        let ctx = unsafe { ctx.as_ref() }.ok_or_else(|| "null model context".to_string())?;
        // SAFETY: strings and arrays of the context are valid for this call.
        let (config, length, angle, path, base_dir, tree) = unsafe {
            (
                text(config)?,
                text(ctx.length_unit)?,
                text(ctx.angle_unit)?,
                text(ctx.field_path)?,
                text(ctx.base_dir)?,
                tree_from_abi(&ctx.tree)?,
            )
        };
        let mut mass = MassModel::massless(0);
        // SAFETY: the mass arrays are valid for this call.
        unsafe { mass_into(&ctx.mass, &mut mass) }?;
        let units = Units {
            length: LengthUnit::parse(length).ok_or_else(|| format!("unknown length unit `{length}`"))?,
            angle: AngleUnit::parse(angle).ok_or_else(|| format!("unknown angle unit `{angle}`"))?,
        };
        let mctx = ModelContext {
            build: BuildContext {
                units,
                base_dir: Path::new(base_dir),
                path,
                // The host's limits do not cross the C ABI: a library reads with its own copy
                // of the readers, within their default.
                limits: InputLimits::default(),
            },
            tree: &tree,
            mass: &mass,
            // Sensors do not cross the C ABI, nor the file's gravity, which only the models that
            // read sensors look at: a run-time model reads none, and the standard gravity
            // stands in.
            sensors: &[],
            gravity_sensor: None,
            gravity: Vector3::new(0.0, 0.0, -armcomp_core::kinematics::sensor::STANDARD_GRAVITY),
        };
        let model = create(config, &mctx).map_err(Failure::Issues)?;
        let handle = Box::new(ModelHandle { model, tree });
        // SAFETY: the caller guarantees `out` is valid for one write.
        unsafe { out.write(Box::into_raw(handle).cast()) };
        Ok(STATUS_OK)
    })
}

/// The handle behind a model pointer, shared: other threads may be reading it too.
///
/// # Safety
/// `model` must come from [`model_create`] and not be destroyed before `'a` ends.
unsafe fn model_handle<'a>(model: *mut c_void) -> Result<&'a ModelHandle, Failure> {
    // SAFETY: forwarded from the caller; nothing writes to a handle after its creation.
    unsafe { model.cast::<ModelHandle>().as_ref() }.ok_or_else(|| Failure::Message("null model handle".into()))
}

/// `armcomp_model_param_count`.
///
/// # Safety
/// As [`model_handle`].
pub unsafe fn model_param_count(model: *mut c_void) -> u32 {
    // SAFETY: forwarded from the caller.
    match unsafe { model_handle(model) } {
        Ok(h) => u32::try_from(h.model.params().len()).unwrap_or(u32::MAX),
        Err(_) => 0,
    }
}

fn quantity_code(q: &Quantity) -> (u32, &'static str) {
    match q {
        Quantity::Length => (QUANTITY_LENGTH, ""),
        Quantity::Angle => (QUANTITY_ANGLE, ""),
        Quantity::Dimensionless => (QUANTITY_DIMENSIONLESS, ""),
        Quantity::Compliance => (QUANTITY_COMPLIANCE, ""),
        Quantity::Mass => (QUANTITY_MASS, ""),
        Quantity::Rigidity => (QUANTITY_RIGIDITY, ""),
        Quantity::PerKelvin => (QUANTITY_PER_KELVIN, ""),
        Quantity::Other(unit) => (QUANTITY_OTHER, unit),
    }
}

/// `armcomp_model_param`.
///
/// # Safety
/// As [`model_handle`]; `out` must be valid for one write.
pub unsafe fn model_param(model: *mut c_void, index: u32, out: *mut AbiParam) -> i32 {
    guard(|| {
        // SAFETY: forwarded from the caller.
        let h = unsafe { model_handle(model) }?;
        let params = h.model.params();
        let p = params
            .get(index as usize)
            .ok_or_else(|| format!("no parameter {index}; the model has {}", params.len()))?;
        let (quantity, unit) = quantity_code(&p.quantity);
        let param = AbiParam {
            name: abi_str(&p.name),
            quantity,
            unit: abi_str(unit),
            nominal: p.nominal,
            sigma: p.sigma,
        };
        // SAFETY: the caller guarantees `out` is valid for one write.
        unsafe { out.write(param) };
        Ok(STATUS_OK)
    })
}

/// `armcomp_model_perturb`: the model's deformation alone, into the host's buffers.
///
/// # Safety
/// As [`model_handle`]; `*state` valid as documented on [`AbiState`], `values` valid for
/// `n_values` reads, the buffers of `*out` for the counts it declares, and no other call
/// reading or writing them.
pub unsafe fn model_perturb(
    model: *mut c_void,
    state: *const AbiState,
    values: *const f64,
    n_values: usize,
    out: *const AbiPerturbation,
) -> i32 {
    guard(|| {
        // SAFETY: forwarded from the caller.
        let h = unsafe { model_handle(model) }?;
        // SAFETY: the caller guarantees a valid state and output description for this call.
        let (s, out) = unsafe { (state.as_ref(), out.as_ref()) };
        let (s, out) = (
            s.ok_or_else(|| "null state".to_string())?,
            out.ok_or_else(|| "null output".to_string())?,
        );
        // SAFETY: arrays of the state and `values` are valid for their declared lengths.
        let (q, values) = unsafe { (slice(s.q, s.n_q)?, slice(values, n_values)?) };
        if q.len() != h.tree.nq() || values.len() != h.model.params().len() {
            return Err(format!(
                "expected {} joint values and {} parameter values, got {} and {}",
                h.tree.nq(),
                h.model.params().len(),
                q.len(),
                values.len()
            )
            .into());
        }
        with_buffers(&PERTURB_BUFFERS, |b| {
            b.fit(&h.tree);
            // SAFETY: as above.
            unsafe {
                frames_into(s, &mut b.frames)?;
                mass_into(&s.mass, &mut b.mass)?;
            }
            b.loads.update(&h.tree, &b.frames, &b.mass);
            let state = StaticState {
                q,
                tree: &h.tree,
                frames: &b.frames,
                mass: &b.mass,
                loads: &b.loads,
                gravity: Vector3::from(s.gravity),
                temperature: (!s.temperature.is_nan()).then_some(s.temperature),
                // The C ABI carries gravity, not the readings: a run-time model sees none.
                sensors: Default::default(),
            };
            h.model.perturb(&state, values, &mut b.perturbation);
            let p = &b.perturbation;
            let counts = [
                ("joint twists", p.joint_twist.len(), out.n_joint_twists),
                ("joint offsets", p.joint_offset.len(), out.n_joint_offsets),
                ("point twists", p.point_twist.len(), out.n_point_twists),
            ];
            for (what, got, expected) in counts {
                if got != expected {
                    return Err(format!("the model returned {got} {what}, expected {expected}").into());
                }
            }
            // SAFETY: the host's buffers hold the counts it declared, which the caller
            // guarantees no one else touches during the call.
            let (joint_twists, joint_offsets, point_twists) = unsafe {
                (
                    slice_mut(out.joint_twists, TWIST_LEN * out.n_joint_twists)?,
                    slice_mut(out.joint_offsets, out.n_joint_offsets)?,
                    slice_mut(out.point_twists, TWIST_LEN * out.n_point_twists)?,
                )
            };
            for (dst, t) in joint_twists.chunks_exact_mut(TWIST_LEN).zip(&p.joint_twist) {
                dst.copy_from_slice(t.as_slice());
            }
            joint_offsets.copy_from_slice(&p.joint_offset);
            for (dst, t) in point_twists.chunks_exact_mut(TWIST_LEN).zip(&p.point_twist) {
                dst.copy_from_slice(t.as_slice());
            }
            Ok(STATUS_OK)
        })
    })
}

/// `armcomp_model_spec_with`: the config with `values` written back, as JSON without `type`.
///
/// # Safety
/// As [`model_handle`]; `values` valid for `n_values` reads, `out_json` for one write.
pub unsafe fn model_spec_with(model: *mut c_void, values: *const f64, n_values: usize, out_json: *mut AbiStr) -> i32 {
    guard(|| {
        // SAFETY: forwarded from the caller.
        let h = unsafe { model_handle(model) }?;
        // SAFETY: `values` is valid for `n_values` reads.
        let values = unsafe { slice(values, n_values) }?;
        if values.len() != h.model.params().len() {
            return Err(format!(
                "expected {} parameter values, got {}",
                h.model.params().len(),
                values.len()
            )
            .into());
        }
        let spec = h.model.spec_with(values);
        let mut json = serde_json::to_value(&spec).map_err(|e| format!("the spec does not serialise: {e}"))?;
        if let Some(map) = json.as_object_mut() {
            map.remove("type");
        }
        // SAFETY: the caller guarantees `out_json` is valid for one write.
        unsafe { out_json.write(hand_back(json.to_string())) };
        Ok(STATUS_OK)
    })
}

/// `armcomp_model_destroy`.
///
/// # Safety
/// `model` must come from [`model_create`] and not be used afterwards.
pub unsafe fn model_destroy(model: *mut c_void) {
    if !model.is_null() {
        // Dropping the author's model may panic; nothing may unwind into the host.
        let _ = catch_unwind(|| {
            // SAFETY: the pointer came from `Box::into_raw` in `model_create`.
            drop(unsafe { Box::from_raw(model.cast::<ModelHandle>()) })
        });
    }
}

/// # Safety
/// `out` must be valid for one write.
unsafe fn give_predictor(predictor: Box<dyn FittedPredictor>, out: *mut *mut c_void) -> Result<i32, Failure> {
    let handle = Box::new(PredictorHandle { predictor });
    // SAFETY: forwarded from the caller.
    unsafe { out.write(Box::into_raw(handle).cast()) };
    Ok(STATUS_OK)
}

/// `armcomp_predictor_fit`.
///
/// # Safety
/// `config` and the arrays of `*data` valid as documented on [`AbiTrainingSet`]; `out` valid for
/// one write.
pub unsafe fn predictor_fit(
    types: &[TypeEntry],
    index: u32,
    config: AbiStr,
    data: *const AbiTrainingSet,
    out: *mut *mut c_void,
) -> i32 {
    guard(|| {
        let Constructor::Predictor(fit) = entry(types, index)?.constructor else {
            return Err(format!("type {index} is not a predictor").into());
        };
        // SAFETY: the caller guarantees valid data for this call.
        let d = unsafe { data.as_ref() }.ok_or_else(|| "null training set".to_string())?;
        // SAFETY: as above, with the declared lengths.
        let (config, inputs, targets, ranges) = unsafe {
            (
                text(config)?,
                slice(d.inputs, d.n_samples * d.n_inputs)?,
                slice(d.targets, d.n_samples * d.n_outputs)?,
                slice(d.input_ranges, 2 * d.n_input_ranges)?,
            )
        };
        let input_ranges: Vec<Option<Limits>> = ranges
            .chunks_exact(2)
            .map(|r| {
                (!r[0].is_nan() && !r[1].is_nan()).then_some(Limits {
                    lower: r[0],
                    upper: r[1],
                })
            })
            .collect();
        let set = TrainingSet {
            inputs,
            targets,
            n_inputs: d.n_inputs,
            n_outputs: d.n_outputs,
            input_ranges: &input_ranges,
        };
        let predictor = fit(config, &set)?;
        // SAFETY: forwarded from the caller.
        unsafe { give_predictor(predictor, out) }
    })
}

/// `armcomp_predictor_load`: a fitted predictor from the JSON `armcomp_predictor_save` wrote.
///
/// # Safety
/// `fitted_json` valid for this call, `out` for one write.
pub unsafe fn predictor_load(types: &[TypeEntry], index: u32, fitted_json: AbiStr, out: *mut *mut c_void) -> i32 {
    guard(|| {
        if !matches!(entry(types, index)?.constructor, Constructor::Predictor(_)) {
            return Err(format!("type {index} is not a predictor").into());
        }
        // SAFETY: the caller guarantees a valid string for this call.
        let json = unsafe { text(fitted_json) }?;
        let predictor: Box<dyn FittedPredictor> =
            serde_json::from_str(json).map_err(|e| format!("the fitted predictor does not load: {e}"))?;
        // SAFETY: forwarded from the caller.
        unsafe { give_predictor(predictor, out) }
    })
}

/// The handle behind a predictor pointer, shared: other threads may be reading it too.
///
/// # Safety
/// `predictor` must come from [`predictor_fit`] or [`predictor_load`] and not be destroyed
/// before `'a` ends.
unsafe fn predictor_handle<'a>(predictor: *mut c_void) -> Result<&'a PredictorHandle, Failure> {
    // SAFETY: forwarded from the caller; nothing writes to a handle after its creation.
    unsafe { predictor.cast::<PredictorHandle>().as_ref() }
        .ok_or_else(|| Failure::Message("null predictor handle".into()))
}

/// `armcomp_predictor_shape`.
///
/// # Safety
/// As [`predictor_handle`]; both outputs valid for one write.
pub unsafe fn predictor_shape(predictor: *mut c_void, n_inputs: *mut usize, n_outputs: *mut usize) -> i32 {
    guard(|| {
        // SAFETY: forwarded from the caller.
        let h = unsafe { predictor_handle(predictor) }?;
        // SAFETY: the caller guarantees both outputs are valid for one write.
        unsafe {
            n_inputs.write(h.predictor.n_inputs());
            n_outputs.write(h.predictor.n_outputs());
        }
        Ok(STATUS_OK)
    })
}

/// `armcomp_predictor_predict`: the prediction, and with `with_std = 1` its standard deviation
/// ([`STATUS_UNSUPPORTED`] when the predictor has none).
///
/// # Safety
/// As [`predictor_handle`]; `input` valid for `n_inputs` reads, `out` (and `out_std` when
/// `with_std = 1`) for `n_outputs` writes, which no other call touches meanwhile.
pub unsafe fn predictor_predict(
    predictor: *mut c_void,
    input: *const f64,
    n_inputs: usize,
    out: *mut f64,
    n_outputs: usize,
    with_std: u32,
    out_std: *mut f64,
) -> i32 {
    guard(|| {
        // SAFETY: forwarded from the caller.
        let h = unsafe { predictor_handle(predictor) }?;
        if n_inputs != h.predictor.n_inputs() || n_outputs != h.predictor.n_outputs() {
            return Err(format!(
                "expected {} inputs and {} outputs, got {n_inputs} and {n_outputs}",
                h.predictor.n_inputs(),
                h.predictor.n_outputs()
            )
            .into());
        }
        // SAFETY: `input` is valid for `n_inputs` reads.
        let input = unsafe { slice(input, n_inputs) }?;
        if out.is_null() || (with_std == 1 && out_std.is_null()) {
            return Err("null output buffer".to_string().into());
        }
        // SAFETY: non-null and valid for `n_outputs` writes, by the caller's guarantee.
        let out = unsafe { std::slice::from_raw_parts_mut(out, n_outputs) };
        with_buffers(&PREDICT_SCRATCH, |scratch| {
            h.predictor.predict_into(input, out, scratch);
            if with_std == 1 {
                // SAFETY: as for `out`.
                let out_std = unsafe { std::slice::from_raw_parts_mut(out_std, n_outputs) };
                if !h.predictor.predict_std_into(input, out_std, scratch) {
                    return Ok(STATUS_UNSUPPORTED);
                }
            }
            Ok(STATUS_OK)
        })
    })
}

/// `armcomp_predictor_save`: the fitted predictor as JSON (with its own `type`).
///
/// # Safety
/// As [`predictor_handle`]; `out_json` valid for one write.
pub unsafe fn predictor_save(predictor: *mut c_void, out_json: *mut AbiStr) -> i32 {
    guard(|| {
        // SAFETY: forwarded from the caller.
        let h = unsafe { predictor_handle(predictor) }?;
        let json = serde_json::to_string(&h.predictor).map_err(|e| format!("the predictor does not serialise: {e}"))?;
        // SAFETY: the caller guarantees `out_json` is valid for one write.
        unsafe { out_json.write(hand_back(json)) };
        Ok(STATUS_OK)
    })
}

/// `armcomp_predictor_destroy`.
///
/// # Safety
/// `predictor` must come from [`predictor_fit`] or [`predictor_load`] and not be used afterwards.
pub unsafe fn predictor_destroy(predictor: *mut c_void) {
    if !predictor.is_null() {
        let _ = catch_unwind(|| {
            // SAFETY: the pointer came from `Box::into_raw` in `give_predictor`.
            drop(unsafe { Box::from_raw(predictor.cast::<PredictorHandle>()) })
        });
    }
}

#[cfg(test)]
mod tests {
    use std::sync::Mutex;

    use super::*;

    /// The ranges the last fit received.
    static SEEN: Mutex<Vec<Option<Limits>>> = Mutex::new(Vec::new());

    fn recording_fit(_: &str, data: &TrainingSet<'_>) -> Result<Box<dyn FittedPredictor>, String> {
        *SEEN.lock().unwrap() = data.input_ranges.to_vec();
        Err("recorded".into())
    }

    #[test]
    fn predictor_fit_hands_the_input_ranges_over() {
        let types = [TypeEntry {
            name: "recorder",
            doc: "records its training set",
            diagnosis_candidate: false,
            candidate_template: None,
            constructor: Constructor::Predictor(recording_fit),
            schema: || "{}".into(),
        }];
        let (inputs, targets) = ([0.1, 0.2, 0.3, 0.4, 0.5, 0.6], [1.0, 2.0]);
        // Three inputs: a range, an unknown one (NaN bounds), a range.
        let ranges = [-1.0, 1.0, f64::NAN, f64::NAN, 0.0, 0.105];
        let set = AbiTrainingSet {
            inputs: inputs.as_ptr(),
            targets: targets.as_ptr(),
            n_samples: 2,
            n_inputs: 3,
            n_outputs: 1,
            input_ranges: ranges.as_ptr(),
            n_input_ranges: 3,
        };
        let config = "{}";
        let config = AbiStr {
            ptr: config.as_ptr(),
            len: config.len(),
        };
        let mut out = std::ptr::null_mut();
        // SAFETY: every array of `set` and the config live for the call; `out` is valid.
        let status = unsafe { predictor_fit(&types, 0, config, &set, &mut out) };
        assert_eq!(status, STATUS_ERROR);
        assert_eq!(
            *SEEN.lock().unwrap(),
            [
                Some(Limits {
                    lower: -1.0,
                    upper: 1.0
                }),
                None,
                Some(Limits {
                    lower: 0.0,
                    upper: 0.105
                }),
            ]
        );
        // No ranges: an empty slice, whatever the pointer.
        let none = AbiTrainingSet {
            input_ranges: std::ptr::null(),
            n_input_ranges: 0,
            ..set
        };
        // SAFETY: as above.
        let status = unsafe { predictor_fit(&types, 0, config, &none, &mut out) };
        assert_eq!(status, STATUS_ERROR);
        assert!(SEEN.lock().unwrap().is_empty());
    }
}
