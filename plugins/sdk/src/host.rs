//! The host side: loads plugin libraries and wraps their handles in the core traits.
//!
//! A robot file uses a run-time error model through the built-in `plugin` type:
//!
//! ```toml
//! [[error_models]]
//! type = "plugin"
//! library = "cable_sag"          # relative to the robot file; no extension: libcable_sag.so etc.
//! model = "cable_sag"            # a type the library exports
//! config = { length = 600.0, mass_per_length = 0.8 }
//! ```
//!
//! Loading a library runs its code, so nothing loads unless the user allows it (see
//! [`PluginPolicy`]): `--allow-plugins` lets a robot file load libraries inside its own folder,
//! and folders the user trusts load from anywhere.
//!
//! Libraries are loaded once per canonical path and never unloaded, so handles and the type
//! names they registered stay valid for the life of the process. Loading checks the ABI
//! version first, then every symbol; each type's config is validated against the JSON Schema
//! the library provides before the plugin sees it. Every failure becomes an issue naming the
//! library file and the robot-file field.

use std::collections::BTreeMap;
use std::os::raw::c_void;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard, PoisonError, RwLock};

use armcomp_core::{
    CandidateFn, CandidateScope, CandidateTemplate, Error, ErrorModel, ErrorModelSpec, FittedPredictor, Issue, Issues,
    ModelContext, ParamInfo, Perturbation, PluginInfo, PredictorSpec, Quantity, Result, Role, StaticState, TrainingSet,
    TreeWorkspace,
};
use libloading::Library;
use nalgebra::{Vector3, Vector6};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use crate::abi::{self, *};
use crate::flat::{FlatMass, FlatState, FlatTree, abi_str};

/// The file name of a library named without extension on this platform (`libNAME.so`,
/// `libNAME.dylib`, `NAME.dll`); a path with an extension is kept as it is.
pub fn platform_library_path(path: &Path) -> PathBuf {
    if path.extension().is_some() {
        return path.to_path_buf();
    }
    let name = path.file_name().map(|n| n.to_string_lossy()).unwrap_or_default();
    path.with_file_name(format!(
        "{}{name}{}",
        std::env::consts::DLL_PREFIX,
        std::env::consts::DLL_SUFFIX
    ))
}

/// The entry points of a loaded library.
#[derive(Clone, Copy)]
struct Api {
    last_error: abi::signatures::LastError,
    model_create: abi::signatures::ModelCreate,
    model_param_count: abi::signatures::ModelParamCount,
    model_param: abi::signatures::ModelParam,
    model_perturb: abi::signatures::ModelPerturb,
    model_spec_with: abi::signatures::ModelSpecWith,
    model_destroy: abi::signatures::Destroy,
    predictor_fit: abi::signatures::PredictorFit,
    predictor_load: abi::signatures::PredictorLoad,
    predictor_shape: abi::signatures::PredictorShape,
    predictor_predict: abi::signatures::PredictorPredict,
    predictor_save: abi::signatures::PredictorSave,
    predictor_destroy: abi::signatures::Destroy,
}

/// One type a loaded library exports.
struct LoadedType {
    index: u32,
    info: PluginInfo,
    validator: Option<jsonschema::Validator>,
}

/// A loaded plugin library; lives for the rest of the process.
pub struct PluginLibrary {
    path: PathBuf,
    file_name: String,
    api: Api,
    types: Vec<LoadedType>,
}

impl std::fmt::Debug for PluginLibrary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PluginLibrary").field("path", &self.path).finish()
    }
}

static LIBRARIES: Mutex<BTreeMap<PathBuf, &'static PluginLibrary>> = Mutex::new(BTreeMap::new());

/// Which plugin libraries this process may load. Loading runs a library's code, so by default
/// none loads.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct PluginPolicy {
    /// The user allows the libraries of this run (`--allow-plugins`): those a robot file names
    /// inside its own folder (predictor libraries: inside the working folder), and those named
    /// on the command line.
    pub allow: bool,
    /// Folders whose libraries load from any robot file, allowed or not (`plugin_dirs` of the
    /// user config).
    pub trusted_dirs: Vec<PathBuf>,
}

static POLICY: RwLock<PluginPolicy> = RwLock::new(PluginPolicy {
    allow: false,
    trusted_dirs: Vec::new(),
});

/// Libraries allowed on the command line in this process (canonical paths).
static NAMED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

/// How messages about libraries refused by the policy begin.
pub const NOT_ALLOWED: &str = "run-time plugins are not allowed";

/// Sets which libraries this process may load; trusted folders that exist are kept by their
/// canonical paths, so links cannot widen them.
pub fn set_policy(policy: PluginPolicy) {
    let trusted_dirs = policy
        .trusted_dirs
        .iter()
        .filter_map(|d| d.canonicalize().ok())
        .collect();
    *POLICY.write().unwrap_or_else(PoisonError::into_inner) = PluginPolicy {
        allow: policy.allow,
        trusted_dirs,
    };
}

/// Where a library was named, which bounds where it may be.
#[derive(Debug, Clone, Copy)]
pub enum Origin<'a> {
    /// By a file whose libraries must lie in this folder (or a trusted one).
    File(&'a Path),
    /// On the command line.
    CommandLine,
}

fn not_allowed(library: &Path) -> String {
    format!(
        "{NOT_ALLOWED}: loading {} would run its code; pass --allow-plugins to allow it, or list its folder in `plugin_dirs` of the user config",
        library.display()
    )
}

/// Whether the policy lets the library at `canonical` load.
fn permit(canonical: &Path, origin: Origin<'_>) -> std::result::Result<(), String> {
    let policy = POLICY.read().unwrap_or_else(PoisonError::into_inner);
    // A library the user named on the command line may then be named by any file (diagnosis
    // candidates name it by its absolute path).
    let named = lock(&NAMED).iter().any(|p| p == canonical);
    if named || policy.trusted_dirs.iter().any(|d| canonical.starts_with(d)) {
        return Ok(());
    }
    if !policy.allow {
        return Err(not_allowed(canonical));
    }
    if let Origin::File(folder) = origin {
        let folder = if folder.as_os_str().is_empty() {
            Path::new(".")
        } else {
            folder
        };
        let folder = folder
            .canonicalize()
            .map_err(|e| format!("cannot resolve the folder {}: {e}", folder.display()))?;
        if !canonical.starts_with(&folder) {
            return Err(format!(
                "{} lies outside {}; a file may load libraries from its own folder only, unless their folder is listed in `plugin_dirs` of the user config",
                canonical.display(),
                folder.display()
            ));
        }
    }
    Ok(())
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // A panic while holding the lock cannot leave the data half-written: it is only inserted
    // into or read, so the data is still good.
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Copies a string the plugin handed over.
///
/// # Safety
/// `s` must be valid for this call, as the ABI guarantees.
unsafe fn owned(s: AbiStr) -> String {
    if s.len == 0 || s.ptr.is_null() {
        return String::new();
    }
    // SAFETY: non-null, and valid for `len` bytes by the caller's guarantee.
    let bytes = unsafe { std::slice::from_raw_parts(s.ptr, s.len) };
    String::from_utf8_lossy(bytes).into_owned()
}

impl PluginLibrary {
    /// Loads a library (once per canonical path). The message of an error says what is wrong
    /// with the file; the caller adds which field named it.
    /// Loads a library (once per canonical path) if the [`PluginPolicy`] lets a library named
    /// at `origin` load. The message of an error says what is wrong with the file; the caller
    /// adds which field named it.
    pub fn load(path: &Path, origin: Origin<'_>) -> std::result::Result<&'static PluginLibrary, String> {
        let canonical = match path.canonicalize() {
            Ok(c) => c,
            // Without permission, a missing library is refused as any other: nothing is
            // probed on the user's behalf.
            Err(_) if !POLICY.read().unwrap_or_else(PoisonError::into_inner).allow => {
                return Err(not_allowed(path));
            }
            Err(e) => return Err(format!("cannot open plugin library {}: {e}", path.display())),
        };
        permit(&canonical, origin)?;
        if let Origin::CommandLine = origin {
            lock(&NAMED).push(canonical.clone());
        }
        armcomp_core::io::check_input_file(&canonical)
            .map_err(|m| format!("plugin library {} {m}", canonical.display()))?;
        armcomp_core::io::note_read(&canonical);
        let mut libraries = lock(&LIBRARIES);
        if let Some(lib) = libraries.get(&canonical) {
            return Ok(lib);
        }
        let lib = Self::open(&canonical)?;
        libraries.insert(canonical, lib);
        Ok(lib)
    }

    fn open(path: &Path) -> std::result::Result<&'static PluginLibrary, String> {
        let file_name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        // SAFETY: loading runs the library's initialisers; a plugin library is trusted code the
        // user named, and it is never unloaded, so no symbol outlives it.
        let library =
            unsafe { Library::new(path) }.map_err(|e| format!("{file_name} is not a loadable shared library: {e}"))?;
        let library: &'static Library = Box::leak(Box::new(library));
        macro_rules! symbol {
            ($name:literal, $ty:ty) => {
                // SAFETY: the symbol has this signature in every library that reports our ABI
                // version, which is checked before any other symbol is looked up.
                *unsafe { library.get::<$ty>(concat!($name, "\0").as_bytes()) }.map_err(|_| {
                    format!(
                        "{file_name} does not export `{}`, which plugin ABI version {} requires",
                        $name, ABI_VERSION
                    )
                })?
            };
        }
        // SAFETY: `armcomp_abi_version` takes nothing and returns a u32 in every ABI version.
        let version = unsafe { library.get::<abi::signatures::AbiVersion>(b"armcomp_abi_version\0") }
            .map_err(|_| format!("{file_name} is not an armcomp plugin: it does not export `armcomp_abi_version`"))?;
        // SAFETY: as above.
        let version = unsafe { version() };
        if version != ABI_VERSION {
            return Err(format!(
                "{file_name} speaks plugin ABI version {version}, this armcomp speaks version {ABI_VERSION}; rebuild the plugin against this armcomp-sdk"
            ));
        }
        let type_count = symbol!("armcomp_type_count", abi::signatures::TypeCount);
        let type_info = symbol!("armcomp_type_info", abi::signatures::TypeInfo);
        let api = Api {
            last_error: symbol!("armcomp_last_error", abi::signatures::LastError),
            model_create: symbol!("armcomp_model_create", abi::signatures::ModelCreate),
            model_param_count: symbol!("armcomp_model_param_count", abi::signatures::ModelParamCount),
            model_param: symbol!("armcomp_model_param", abi::signatures::ModelParam),
            model_perturb: symbol!("armcomp_model_perturb", abi::signatures::ModelPerturb),
            model_spec_with: symbol!("armcomp_model_spec_with", abi::signatures::ModelSpecWith),
            model_destroy: symbol!("armcomp_model_destroy", abi::signatures::Destroy),
            predictor_fit: symbol!("armcomp_predictor_fit", abi::signatures::PredictorFit),
            predictor_load: symbol!("armcomp_predictor_load", abi::signatures::PredictorLoad),
            predictor_shape: symbol!("armcomp_predictor_shape", abi::signatures::PredictorShape),
            predictor_predict: symbol!("armcomp_predictor_predict", abi::signatures::PredictorPredict),
            predictor_save: symbol!("armcomp_predictor_save", abi::signatures::PredictorSave),
            predictor_destroy: symbol!("armcomp_predictor_destroy", abi::signatures::Destroy),
        };
        let mut lib = PluginLibrary {
            path: path.to_path_buf(),
            file_name,
            api,
            types: Vec::new(),
        };
        // SAFETY: no arguments.
        let count = unsafe { type_count() };
        for index in 0..count {
            let mut info = AbiTypeInfo {
                name: abi_str(""),
                doc: abi_str(""),
                role: 0,
                diagnosis_candidate: 0,
                config_schema: abi_str(""),
                candidate_template: abi_str(""),
            };
            // SAFETY: `info` is valid for one write.
            let status = unsafe { type_info(index, &mut info) };
            if status != STATUS_OK {
                return Err(lib.describe_failure(status, &format!("type {index} cannot be described")));
            }
            // SAFETY: the strings are valid until the next call into the library.
            let (name, doc, schema, template) = unsafe {
                (
                    owned(info.name),
                    owned(info.doc),
                    owned(info.config_schema),
                    owned(info.candidate_template),
                )
            };
            let role = match info.role {
                ROLE_ERROR_MODEL => Role::ErrorModel,
                ROLE_PREDICTOR => Role::Predictor,
                other => return Err(format!("{}: type `{name}` has unknown role {other}", lib.file_name)),
            };
            let validator = if schema.is_empty() {
                None
            } else {
                let value: Value = serde_json::from_str(&schema).map_err(|e| {
                    format!(
                        "{}: type `{name}` has a config schema that is not JSON: {e}",
                        lib.file_name
                    )
                })?;
                Some(jsonschema::validator_for(&value).map_err(|e| {
                    format!(
                        "{}: type `{name}` has a config schema that does not compile: {e}",
                        lib.file_name
                    )
                })?)
            };
            let diagnosis_candidate = role == Role::ErrorModel && info.diagnosis_candidate == 1;
            let candidates = if diagnosis_candidate {
                let template = if template.is_empty() {
                    CandidateTemplate {
                        per: CandidateScope::Global,
                        field: None,
                        label: name.replace('_', " "),
                        config: Default::default(),
                    }
                } else {
                    CandidateTemplate::from_json(&template)
                        .map_err(|e| format!("{}: type `{name}`: {e}", lib.file_name))?
                };
                Some(generic_candidates(path, &name, template))
            } else {
                None
            };
            lib.types.push(LoadedType {
                index,
                // The registry holds `&'static` names and candidate functions; the library
                // lives as long, and is loaded once per path, so each is leaked once.
                info: PluginInfo {
                    type_name: Box::leak(name.into_boxed_str()),
                    role,
                    doc: Box::leak(doc.into_boxed_str()),
                    diagnosis_candidate,
                    candidates,
                    schema: |g| <PluginErrorModelSpec as JsonSchema>::json_schema(g),
                },
                validator,
            });
        }
        Ok(Box::leak(Box::new(lib)))
    }

    /// The library file's name, for messages.
    pub fn file_name(&self) -> &str {
        &self.file_name
    }

    /// The registry entries of the types it exports.
    pub fn plugins(&self) -> Vec<PluginInfo> {
        self.types.iter().map(|t| t.info).collect()
    }

    fn find(&self, name: &str, role: Role) -> std::result::Result<&LoadedType, String> {
        self.types
            .iter()
            .find(|t| t.info.type_name == name && t.info.role == role)
            .ok_or_else(|| {
                let names: Vec<_> = self
                    .types
                    .iter()
                    .filter(|t| t.info.role == role)
                    .map(|t| format!("`{}`", t.info.type_name))
                    .collect();
                format!(
                    "{} has no {} named `{name}`; it has: {}",
                    self.file_name,
                    role.field().trim_end_matches('s').replace('_', " "),
                    if names.is_empty() {
                        "none".into()
                    } else {
                        names.join(", ")
                    }
                )
            })
    }

    /// The message of the last failure on this thread.
    fn last_error(&self) -> String {
        // SAFETY: no arguments; the string is valid until the next call on this thread.
        unsafe { owned((self.api.last_error)()) }
    }

    fn describe_failure(&self, status: i32, what: &str) -> String {
        match status {
            STATUS_UNSUPPORTED => format!("{}: {what}: not supported", self.file_name),
            _ => format!("{}: {what}: {}", self.file_name, self.last_error()),
        }
    }
}

/// The diagnosis candidates of a library's error model: `template` instantiated on the robot,
/// each config wrapped in the `plugin` spec that loads it from the library at `path`.
fn generic_candidates(path: &Path, model: &str, template: CandidateTemplate) -> &'static CandidateFn {
    let library = path.to_string_lossy().into_owned();
    let model = model.to_string();
    Box::leak(Box::new(move |robot: &armcomp_core::Robot| {
        template.instantiate(
            robot,
            |config| serde_json::json!({ "type": "plugin", "library": library, "model": model, "config": config }),
        )
    }))
}

/// Registry entries of every type of every library loaded so far, in load order of paths.
pub fn loaded_plugins() -> Vec<PluginInfo> {
    lock(&LIBRARIES).values().flat_map(|l| l.plugins()).collect()
}

/// The registry entries of the host's own types, the `plugin` error model and predictor.
pub fn plugins() -> Vec<PluginInfo> {
    vec![
        PluginInfo {
            type_name: "plugin",
            role: Role::ErrorModel,
            doc: "An error model from a shared library loaded at run time (library, model, config)",
            diagnosis_candidate: false,
            candidates: None,
            schema: |g| <PluginErrorModelSpec as JsonSchema>::json_schema(g),
        },
        PluginInfo {
            type_name: "plugin",
            role: Role::Predictor,
            doc: "A residual predictor from a shared library loaded at run time (library, model, config)",
            diagnosis_candidate: false,
            candidates: None,
            schema: |g| <PluginPredictorSpec as JsonSchema>::json_schema(g),
        },
    ]
}

fn empty_config() -> Value {
    Value::Object(Default::default())
}

/// Schema of a config: any JSON object; the library's own schema checks it when it is loaded.
type ConfigObject = serde_json::Map<String, Value>;

/// A run-time error model as written in a robot file (`type = "plugin"`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PluginErrorModelSpec {
    /// The shared library: a path relative to the robot file, inside its folder unless the
    /// library's folder is trusted (`plugin_dirs` of the user config). Without an
    /// extension the platform's naming applies: `cable_sag` is `libcable_sag.so` on Linux,
    /// `libcable_sag.dylib` on macOS, `cable_sag.dll` on Windows.
    pub library: String,
    /// The error-model type the library exports.
    pub model: String,
    /// The model's own configuration, in the robot file's units, checked against the schema the
    /// library provides.
    #[serde(default = "empty_config")]
    #[schemars(with = "ConfigObject")]
    pub config: Value,
}

/// Turns a library's validation errors on `config` into issues under `path` (`...config.field`).
fn schema_issues(validator: &jsonschema::Validator, config: &Value, path: &str, file_name: &str) -> Issues {
    let mut issues = Issues::default();
    for e in validator.iter_errors(config) {
        let mut field = path.to_string();
        for seg in e.instance_path().as_str().split('/').filter(|s| !s.is_empty()) {
            let seg = seg.replace("~1", "/").replace("~0", "~");
            if seg.chars().all(|c| c.is_ascii_digit()) {
                field.push_str(&format!("[{seg}]"));
            } else {
                field.push('.');
                field.push_str(&seg);
            }
        }
        issues.push(field, format!("{e} (schema of {file_name})"));
    }
    issues
}

/// One config problem as a plugin reports it with [`STATUS_ISSUES`].
#[derive(Deserialize)]
struct IssueRecord {
    path: String,
    message: String,
}

/// Issues a plugin returned with [`STATUS_ISSUES`], or one issue at `path` naming the failure.
fn plugin_issues(lib: &PluginLibrary, status: i32, path: &str, what: &str) -> Issues {
    let mut issues = Issues::default();
    let text = lib.last_error();
    match serde_json::from_str::<Vec<IssueRecord>>(&text) {
        Ok(list) if status == STATUS_ISSUES => {
            for i in list {
                issues.push(i.path, format!("{} ({})", i.message, lib.file_name));
            }
        }
        _ => issues.push(path, lib.describe_failure(status, what)),
    }
    issues
}

fn one_issue(path: impl Into<String>, message: impl Into<String>) -> Issues {
    let mut issues = Issues::default();
    issues.push(path, message);
    issues
}

/// `Quantity::Other` holds a `&'static str`; each distinct unit a plugin names is leaked once.
fn interned_unit(unit: String) -> &'static str {
    static UNITS: Mutex<BTreeMap<String, &'static str>> = Mutex::new(BTreeMap::new());
    let mut units = lock(&UNITS);
    if let Some(u) = units.get(&unit) {
        return u;
    }
    let leaked: &'static str = Box::leak(unit.clone().into_boxed_str());
    units.insert(unit, leaked);
    leaked
}

fn quantity(code: u32, unit: String) -> std::result::Result<Quantity, String> {
    Ok(match code {
        QUANTITY_LENGTH => Quantity::Length,
        QUANTITY_ANGLE => Quantity::Angle,
        QUANTITY_DIMENSIONLESS => Quantity::Dimensionless,
        QUANTITY_COMPLIANCE => Quantity::Compliance,
        QUANTITY_MASS => Quantity::Mass,
        QUANTITY_RIGIDITY => Quantity::Rigidity,
        QUANTITY_PER_KELVIN => Quantity::PerKelvin,
        QUANTITY_OTHER if !unit.is_empty() => Quantity::Other(interned_unit(unit)),
        QUANTITY_OTHER => return Err("a parameter of quantity `other` needs a unit".into()),
        other => return Err(format!("unknown quantity code {other}")),
    })
}

#[typetag::serde(name = "plugin")]
impl ErrorModelSpec for PluginErrorModelSpec {
    fn build(&self, ctx: &ModelContext<'_>) -> std::result::Result<Box<dyn ErrorModel>, Issues> {
        let path = ctx.build.path;
        let file = platform_library_path(&ctx.build.base_dir.join(&self.library));
        let lib = PluginLibrary::load(&file, Origin::File(ctx.build.base_dir))
            .map_err(|m| one_issue(format!("{path}.library"), m))?;
        let ty = lib
            .find(&self.model, Role::ErrorModel)
            .map_err(|m| one_issue(format!("{path}.model"), m))?;
        let config_path = format!("{path}.config");
        if let Some(v) = &ty.validator {
            let issues = schema_issues(v, &self.config, &config_path, &lib.file_name);
            if !issues.is_empty() {
                return Err(issues);
            }
        }
        let spec = PluginErrorModelSpec {
            library: lib.path.to_string_lossy().into_owned(),
            ..self.clone()
        };
        let model = PluginErrorModel::create(lib, ty, spec, ctx, &config_path)?;
        model.probe(ctx).map_err(|m| one_issue(path, m))?;
        Ok(Box::new(model))
    }
}

/// A handle and the buffers its calls reuse; used under the model's lock only.
struct ModelCall {
    handle: *mut c_void,
    state: FlatState,
}

// SAFETY: the handle is only touched under `PluginErrorModel::call`'s lock, so by one thread
// at a time, which is all the ABI asks.
unsafe impl Send for ModelCall {}

/// An error model living in a plugin library, behind the core's [`ErrorModel`] trait.
pub struct PluginErrorModel {
    library: &'static PluginLibrary,
    spec: PluginErrorModelSpec,
    params: Vec<ParamInfo>,
    n_joints: usize,
    n_points: usize,
    call: Mutex<ModelCall>,
    failure: Mutex<Option<String>>,
}

impl std::fmt::Debug for PluginErrorModel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PluginErrorModel")
            .field("library", &self.library.file_name)
            .field("model", &self.spec.model)
            .field("params", &self.params)
            .finish()
    }
}

impl PluginErrorModel {
    fn create(
        library: &'static PluginLibrary,
        ty: &LoadedType,
        spec: PluginErrorModelSpec,
        ctx: &ModelContext<'_>,
        config_path: &str,
    ) -> std::result::Result<Self, Issues> {
        let tree = FlatTree::new(ctx.tree);
        let mut mass = FlatMass::default();
        mass.fill(ctx.mass);
        let base_dir = ctx.build.base_dir.to_string_lossy();
        let config = spec.config.to_string();
        let abi_ctx = AbiModelContext {
            length_unit: abi_str(ctx.build.units.length.symbol()),
            angle_unit: abi_str(ctx.build.units.angle.symbol()),
            field_path: abi_str(config_path),
            base_dir: abi_str(&base_dir),
            tree: tree.abi(),
            mass: mass.abi(),
        };
        let mut handle = std::ptr::null_mut();
        // SAFETY: the context's arrays live in `tree`, `mass` and `ctx` for the whole call.
        let status = unsafe { (library.api.model_create)(ty.index, abi_str(&config), &abi_ctx, &mut handle) };
        if status != STATUS_OK || handle.is_null() {
            let what = format!("model `{}` cannot be built", spec.model);
            return Err(plugin_issues(library, status, config_path, &what));
        }
        let mut model = PluginErrorModel {
            library,
            spec,
            params: Vec::new(),
            n_joints: ctx.tree.joints().len(),
            n_points: ctx.tree.points().len(),
            call: Mutex::new(ModelCall {
                handle,
                state: FlatState::default(),
            }),
            failure: Mutex::new(None),
        };
        model.params = model.read_params().map_err(|m| one_issue(config_path, m))?;
        Ok(model)
    }

    fn read_params(&self) -> std::result::Result<Vec<ParamInfo>, String> {
        let handle = lock(&self.call).handle;
        let lib = self.library;
        // SAFETY: a live handle of this library.
        let count = unsafe { (lib.api.model_param_count)(handle) };
        let mut params = Vec::new();
        for i in 0..count {
            let mut p = AbiParam {
                name: abi_str(""),
                quantity: 0,
                unit: abi_str(""),
                nominal: 0.0,
                sigma: 0.0,
            };
            // SAFETY: a live handle; `p` is valid for one write.
            let status = unsafe { (lib.api.model_param)(handle, i, &mut p) };
            if status != STATUS_OK {
                return Err(lib.describe_failure(status, &format!("parameter {i} cannot be read")));
            }
            // SAFETY: the strings are valid until the next call with this handle.
            let (name, unit) = unsafe { (owned(p.name), owned(p.unit)) };
            let q = quantity(p.quantity, unit).map_err(|m| format!("{}: parameter `{name}`: {m}", lib.file_name))?;
            if !p.nominal.is_finite() || p.sigma.is_nan() || p.sigma <= 0.0 {
                return Err(format!(
                    "{}: parameter `{name}` has nominal value {} and prior sigma {}; expected a finite value and a positive sigma",
                    lib.file_name, p.nominal, p.sigma
                ));
            }
            params.push(ParamInfo::new(name, q, p.nominal, p.sigma));
        }
        Ok(params)
    }

    /// Evaluates the plugin at mid-range joint values, with and without a temperature, so that
    /// a model that fails, panics or returns bad values is reported when the robot is built.
    fn probe(&self, ctx: &ModelContext<'_>) -> std::result::Result<(), String> {
        let tree = ctx.tree;
        let q: Vec<f64> = tree
            .coordinate_limits()
            .iter()
            .map(|l| l.map_or(0.0, |l| 0.5 * (l.lower + l.upper)))
            .collect();
        let mut frames = TreeWorkspace::new(tree);
        tree.forward_into(&q, &mut frames);
        let values: Vec<f64> = self.params.iter().map(|p| p.nominal).collect();
        let mut out = Perturbation::zeros(tree);
        for temperature in [None, Some(30.0)] {
            let state = StaticState {
                q: &q,
                tree,
                frames: &frames,
                mass: ctx.mass,
                gravity: Vector3::new(0.0, 0.0, -9.81),
                temperature,
            };
            self.try_perturb(&state, &values, &mut out).map_err(|m| {
                format!(
                    "model `{}` fails at mid-range joint values with its nominal parameters: {m}",
                    self.spec.model
                )
            })?;
        }
        self.try_spec_with(&values).map(|_| ())
    }

    /// The last failure of a `perturb` call, if any (the trait's `perturb` cannot return it).
    pub fn last_failure(&self) -> Option<String> {
        lock(&self.failure).clone()
    }

    /// The plugin's deformation added to `out`, after checking its sizes and values.
    fn try_perturb(
        &self,
        state: &StaticState<'_>,
        values: &[f64],
        out: &mut Perturbation,
    ) -> std::result::Result<(), String> {
        let lib = self.library;
        if values.len() != self.params.len() {
            return Err(format!(
                "{} parameter values for a model with {} parameters",
                values.len(),
                self.params.len()
            ));
        }
        let mut call = lock(&self.call);
        let handle = call.handle;
        let abi_state = call.state.fill(state);
        let mut view = AbiPerturbation {
            joint_twists: std::ptr::null(),
            n_joint_twists: 0,
            joint_offsets: std::ptr::null(),
            n_joint_offsets: 0,
            point_twists: std::ptr::null(),
            n_point_twists: 0,
        };
        // SAFETY: a live handle; the state's arrays live in `call.state` and `state` for the
        // call; `values` and `view` are valid.
        let status = unsafe { (lib.api.model_perturb)(handle, &abi_state, values.as_ptr(), values.len(), &mut view) };
        if status != STATUS_OK {
            return Err(lib.describe_failure(status, "perturb"));
        }
        let sizes = [
            ("joint twists", view.n_joint_twists, self.n_joints),
            ("joint offsets", view.n_joint_offsets, self.n_joints),
            ("point twists", view.n_point_twists, self.n_points),
        ];
        for (what, got, expected) in sizes {
            if got != expected {
                return Err(format!(
                    "{}: perturb returned {got} {what}, expected {expected}",
                    lib.file_name
                ));
            }
        }
        let slice = |ptr: *const f64, len: usize| -> std::result::Result<&[f64], String> {
            if len == 0 {
                return Ok(&[]);
            }
            if ptr.is_null() {
                return Err(format!("{}: perturb returned a null buffer", lib.file_name));
            }
            // SAFETY: the plugin's buffers hold the counts it declared (checked above) and stay
            // valid until the next call with this handle, which the lock excludes.
            Ok(unsafe { std::slice::from_raw_parts(ptr, len) })
        };
        let joint_twists = slice(view.joint_twists, TWIST_LEN * self.n_joints)?;
        let joint_offsets = slice(view.joint_offsets, self.n_joints)?;
        let point_twists = slice(view.point_twists, TWIST_LEN * self.n_points)?;
        for (what, values) in [
            ("joint twists", joint_twists),
            ("joint offsets", joint_offsets),
            ("point twists", point_twists),
        ] {
            if let Some(i) = values.iter().position(|v| !v.is_finite()) {
                return Err(format!(
                    "{}: perturb returned {} among the {what} (value {i})",
                    lib.file_name, values[i]
                ));
            }
        }
        for (t, src) in out.joint_twist.iter_mut().zip(joint_twists.chunks_exact(TWIST_LEN)) {
            *t += Vector6::from_column_slice(src);
        }
        for (v, src) in out.joint_offset.iter_mut().zip(joint_offsets) {
            *v += src;
        }
        for (t, src) in out.point_twist.iter_mut().zip(point_twists.chunks_exact(TWIST_LEN)) {
            *t += Vector6::from_column_slice(src);
        }
        Ok(())
    }

    fn try_spec_with(&self, values: &[f64]) -> std::result::Result<PluginErrorModelSpec, String> {
        let lib = self.library;
        let call = lock(&self.call);
        let mut json = abi_str("");
        // SAFETY: a live handle; `values` and `json` are valid for the call.
        let status = unsafe { (lib.api.model_spec_with)(call.handle, values.as_ptr(), values.len(), &mut json) };
        if status != STATUS_OK {
            return Err(lib.describe_failure(status, "spec_with"));
        }
        // SAFETY: the string is valid until the next call with this handle.
        let json = unsafe { owned(json) };
        let config: Value = serde_json::from_str(&json)
            .map_err(|e| format!("{}: spec_with returned invalid JSON: {e}", lib.file_name))?;
        Ok(PluginErrorModelSpec {
            config,
            ..self.spec.clone()
        })
    }
}

impl ErrorModel for PluginErrorModel {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    /// A failure here cannot be returned through the trait: the joint offsets become NaN, so
    /// that every result computed from them is visibly invalid, and [`last_failure`] says why.
    ///
    /// [`last_failure`]: PluginErrorModel::last_failure
    fn perturb(&self, state: &StaticState<'_>, values: &[f64], out: &mut Perturbation) {
        if let Err(message) = self.try_perturb(state, values, out) {
            out.joint_offset.iter_mut().for_each(|v| *v = f64::NAN);
            *lock(&self.failure) = Some(message);
        }
    }

    /// Built models passed this at build time with their nominal values; should the plugin fail
    /// later, the spec keeps the config it was built from and [`last_failure`] says why.
    ///
    /// [`last_failure`]: PluginErrorModel::last_failure
    fn spec_with(&self, values: &[f64]) -> Box<dyn ErrorModelSpec> {
        match self.try_spec_with(values) {
            Ok(spec) => Box::new(spec),
            Err(message) => {
                *lock(&self.failure) = Some(message);
                Box::new(self.spec.clone())
            }
        }
    }
}

impl Drop for PluginErrorModel {
    fn drop(&mut self) {
        let call = self.call.get_mut().unwrap_or_else(PoisonError::into_inner);
        // SAFETY: the handle is live and never used again.
        unsafe { (self.library.api.model_destroy)(call.handle) };
    }
}

/// A run-time residual predictor as written in a robot file (`type = "plugin"`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PluginPredictorSpec {
    /// The shared library, relative to the working directory (predictor specs are fitted
    /// without the robot file's folder) and inside it unless the library's folder is trusted;
    /// platform naming as for error models.
    pub library: String,
    /// The predictor type the library exports.
    pub model: String,
    /// The predictor's own hyper-parameters, checked against the schema the library provides.
    #[serde(default = "empty_config")]
    #[schemars(with = "ConfigObject")]
    pub config: Value,
}

#[typetag::serde(name = "plugin")]
impl PredictorSpec for PluginPredictorSpec {
    fn fit(&self, data: &TrainingSet<'_>) -> Result<Box<dyn FittedPredictor>> {
        let lib = PluginLibrary::load(
            &platform_library_path(Path::new(&self.library)),
            Origin::File(Path::new(".")),
        )
        .map_err(|m| Error::InvalidModel(vec![Issue::new("predictor.library", m)]))?;
        let ty = lib
            .find(&self.model, Role::Predictor)
            .map_err(|m| Error::InvalidModel(vec![Issue::new("predictor.model", m)]))?;
        if let Some(v) = &ty.validator {
            let issues = schema_issues(v, &self.config, "predictor.config", &lib.file_name);
            if !issues.is_empty() {
                return Err(Error::InvalidModel(issues.0));
            }
        }
        let n = data.inputs.len() / data.n_inputs.max(1);
        if data.inputs.len() != n * data.n_inputs || data.targets.len() != n * data.n_outputs {
            return Err(Error::Input(format!(
                "training set of {} inputs and {} targets is not {n} rows of {} and {}",
                data.inputs.len(),
                data.targets.len(),
                data.n_inputs,
                data.n_outputs
            )));
        }
        if !data.input_ranges.is_empty() && data.input_ranges.len() != data.n_inputs {
            return Err(Error::Input(format!(
                "training set has {} input ranges for {} inputs; expected one per input or none",
                data.input_ranges.len(),
                data.n_inputs
            )));
        }
        let ranges: Vec<f64> = data
            .input_ranges
            .iter()
            .flat_map(|r| r.map_or([f64::NAN; 2], |r| [r.lower, r.upper]))
            .collect();
        let set = AbiTrainingSet {
            inputs: data.inputs.as_ptr(),
            targets: data.targets.as_ptr(),
            n_samples: n,
            n_inputs: data.n_inputs,
            n_outputs: data.n_outputs,
            input_ranges: ranges.as_ptr(),
            n_input_ranges: data.input_ranges.len(),
        };
        let config = self.config.to_string();
        let mut handle = std::ptr::null_mut();
        // SAFETY: the arrays of `set` and `config` live for the call; `handle` is valid.
        let status = unsafe { (lib.api.predictor_fit)(ty.index, abi_str(&config), &set, &mut handle) };
        if status != STATUS_OK || handle.is_null() {
            return Err(Error::Input(lib.describe_failure(
                status,
                &format!("predictor `{}` cannot be fitted", self.model),
            )));
        }
        Ok(Box::new(PluginPredictor::new(lib, ty, self.model.clone(), handle)?))
    }
}

/// A handle used under the predictor's lock only.
struct PredictorCall(*mut c_void);

// SAFETY: the handle is only touched under `PluginPredictor::call`'s lock.
unsafe impl Send for PredictorCall {}

/// A fitted predictor living in a plugin library, behind the core's [`FittedPredictor`] trait.
/// In model files it is `{type = "plugin", library, model, fitted}`, `fitted` being the plugin's
/// own JSON.
pub struct PluginPredictor {
    library: &'static PluginLibrary,
    model: String,
    n_inputs: usize,
    n_outputs: usize,
    call: Mutex<PredictorCall>,
    failure: Mutex<Option<String>>,
}

impl std::fmt::Debug for PluginPredictor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PluginPredictor")
            .field("library", &self.library.file_name)
            .field("model", &self.model)
            .finish()
    }
}

/// How a [`PluginPredictor`] is stored.
#[derive(Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct PredictorRecord {
    library: String,
    model: String,
    fitted: Value,
}

impl PluginPredictor {
    fn new(library: &'static PluginLibrary, ty: &LoadedType, model: String, handle: *mut c_void) -> Result<Self> {
        let mut predictor = PluginPredictor {
            library,
            model,
            n_inputs: 0,
            n_outputs: 0,
            call: Mutex::new(PredictorCall(handle)),
            failure: Mutex::new(None),
        };
        let (n_inputs, n_outputs) = (&mut predictor.n_inputs, &mut predictor.n_outputs);
        // SAFETY: a live handle; both outputs valid for one write.
        let status = unsafe { (library.api.predictor_shape)(handle, n_inputs, n_outputs) };
        if status != STATUS_OK {
            // Dropping `predictor` destroys the handle.
            return Err(Error::Input(
                library.describe_failure(status, &format!("predictor `{}` shape", ty.info.type_name)),
            ));
        }
        Ok(predictor)
    }

    fn load(record: PredictorRecord) -> std::result::Result<Self, String> {
        let lib = PluginLibrary::load(Path::new(&record.library), Origin::File(Path::new(".")))?;
        let ty = lib.find(&record.model, Role::Predictor)?;
        let json = record.fitted.to_string();
        let mut handle = std::ptr::null_mut();
        // SAFETY: `json` lives for the call; `handle` is valid for one write.
        let status = unsafe { (lib.api.predictor_load)(ty.index, abi_str(&json), &mut handle) };
        if status != STATUS_OK || handle.is_null() {
            return Err(lib.describe_failure(status, &format!("predictor `{}` cannot be loaded", record.model)));
        }
        PluginPredictor::new(lib, ty, record.model, handle).map_err(|e| e.to_string())
    }

    /// The last failure of a prediction, if any (the trait's `predict_into` cannot return it).
    pub fn last_failure(&self) -> Option<String> {
        lock(&self.failure).clone()
    }

    fn try_predict(
        &self,
        input: &[f64],
        out: &mut [f64],
        std: Option<&mut [f64]>,
    ) -> std::result::Result<bool, String> {
        let lib = self.library;
        if input.len() != self.n_inputs || out.len() != self.n_outputs {
            return Err(format!(
                "{}: predictor `{}` takes {} inputs and gives {} outputs, got {} and {}",
                lib.file_name,
                self.model,
                self.n_inputs,
                self.n_outputs,
                input.len(),
                out.len()
            ));
        }
        let call = lock(&self.call);
        let (with_std, std_ptr) = match std {
            Some(s) if s.len() == self.n_outputs => (1, s.as_mut_ptr()),
            Some(_) => {
                return Err(format!(
                    "{}: standard deviation buffer of the wrong size",
                    lib.file_name
                ));
            }
            None => (0, std::ptr::null_mut()),
        };
        // SAFETY: a live handle; `input`, `out` and `std_ptr` hold the sizes passed.
        let status = unsafe {
            (lib.api.predictor_predict)(
                call.0,
                input.as_ptr(),
                input.len(),
                out.as_mut_ptr(),
                out.len(),
                with_std,
                std_ptr,
            )
        };
        match status {
            STATUS_OK => {}
            STATUS_UNSUPPORTED if with_std == 1 => return Ok(false),
            _ => return Err(lib.describe_failure(status, "predict")),
        }
        if let Some(i) = out.iter().position(|v| !v.is_finite()) {
            return Err(format!("{}: predict returned {} as output {i}", lib.file_name, out[i]));
        }
        Ok(true)
    }
}

impl Serialize for PluginPredictor {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        let call = lock(&self.call);
        let mut json = abi_str("");
        // SAFETY: a live handle; `json` valid for one write.
        let status = unsafe { (self.library.api.predictor_save)(call.0, &mut json) };
        if status != STATUS_OK {
            return Err(serde::ser::Error::custom(self.library.describe_failure(status, "save")));
        }
        // SAFETY: the string is valid until the next call with this handle.
        let fitted: Value = serde_json::from_str(&unsafe { owned(json) }).map_err(serde::ser::Error::custom)?;
        PredictorRecord {
            library: self.library.path.to_string_lossy().into_owned(),
            model: self.model.clone(),
            fitted,
        }
        .serialize(s)
    }
}

impl<'de> Deserialize<'de> for PluginPredictor {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        PluginPredictor::load(PredictorRecord::deserialize(d)?).map_err(serde::de::Error::custom)
    }
}

#[typetag::serde(name = "plugin")]
impl FittedPredictor for PluginPredictor {
    fn n_inputs(&self) -> usize {
        self.n_inputs
    }

    fn n_outputs(&self) -> usize {
        self.n_outputs
    }

    /// On failure the outputs become NaN and [`PluginPredictor::last_failure`] says why.
    fn predict_into(&self, input: &[f64], out: &mut [f64], _scratch: &mut Vec<f64>) {
        if let Err(m) = self.try_predict(input, out, None) {
            out.iter_mut().for_each(|v| *v = f64::NAN);
            *lock(&self.failure) = Some(m);
        }
    }

    fn predict_std_into(&self, input: &[f64], out: &mut [f64], _scratch: &mut Vec<f64>) -> bool {
        let mut mean = vec![0.0; self.n_outputs];
        match self.try_predict(input, &mut mean, Some(out)) {
            Ok(has_std) => has_std && out.iter().all(|v| v.is_finite()),
            Err(m) => {
                *lock(&self.failure) = Some(m);
                false
            }
        }
    }
}

impl Drop for PluginPredictor {
    fn drop(&mut self) {
        let call = self.call.get_mut().unwrap_or_else(PoisonError::into_inner);
        // SAFETY: the handle is live and never used again.
        unsafe { (self.library.api.predictor_destroy)(call.0) };
    }
}

/// Loads a library named on the command line to list its types (`armcomp plugins --library`).
pub fn load_library(path: &Path) -> std::result::Result<Vec<PluginInfo>, String> {
    Ok(PluginLibrary::load(&platform_library_path(path), Origin::CommandLine)?.plugins())
}
