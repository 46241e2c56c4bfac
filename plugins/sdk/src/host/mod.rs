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
//!
//! This module loads libraries under the policy and keeps the registry of loaded ones;
//! [`PluginErrorModel`] and [`PluginPredictor`] wrap a library's handles in the core traits,
//! both on a `PluginHandle` (`handle.rs`), which owns a handle and records its failures. The
//! hot calls (`perturb`, `predict`) take no lock: ABI version 4 lets a handle be called from
//! several threads at once, and the host's per-call buffers are per thread.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard, PoisonError, RwLock};

use armcomp_core::{CandidateFn, CandidateScope, CandidateTemplate, Error, Issues, PluginInfo, Result, Role};
use libloading::Library;
use schemars::JsonSchema;
use serde_json::Value;

use crate::abi::{self, *};
use crate::flat::abi_str;

mod error_model;
mod handle;
mod predictor;

pub use error_model::{PluginErrorModel, PluginErrorModelSpec};
pub use predictor::{PluginPredictor, PluginPredictorSpec};

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
    /// The user allows the libraries of this run (`--allow-plugins`): those a robot or model
    /// file names inside its own folder, and those named on the command line.
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

pub use armcomp_core::error::NOT_ALLOWED;

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

fn not_allowed(library: &Path) -> Error {
    Error::PluginNotAllowed {
        library: library.to_path_buf(),
    }
}

/// A problem with the library at `library`.
fn unusable(library: &Path, message: String) -> Error {
    Error::Plugin {
        library: library.to_path_buf(),
        message,
    }
}

/// Whether the policy lets the library at `canonical` load.
fn permit(canonical: &Path, origin: Origin<'_>) -> Result<()> {
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
        let folder = folder.canonicalize().map_err(|e| {
            unusable(
                canonical,
                format!("cannot resolve the folder {}: {e}", folder.display()),
            )
        })?;
        if !canonical.starts_with(&folder) {
            return Err(unusable(
                canonical,
                format!(
                    "lies outside {}; a file may load libraries from its own folder only, unless their folder is listed in `plugin_dirs` of the user config",
                    folder.display()
                ),
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
    /// Loads a library (once per canonical path) if the [`PluginPolicy`] lets a library named
    /// at `origin` load. The error says what is wrong with the file; the caller adds which field
    /// named it.
    pub fn load(path: &Path, origin: Origin<'_>) -> Result<&'static PluginLibrary> {
        let canonical = match path.canonicalize() {
            Ok(c) => c,
            // Without permission, a missing library is refused as any other: nothing is
            // probed on the user's behalf.
            Err(_) if !POLICY.read().unwrap_or_else(PoisonError::into_inner).allow => {
                return Err(not_allowed(path));
            }
            Err(e) => return Err(unusable(path, format!("cannot open: {e}"))),
        };
        permit(&canonical, origin)?;
        if let Origin::CommandLine = origin {
            lock(&NAMED).push(canonical.clone());
        }
        armcomp_core::support::io::check_input_file(&canonical).map_err(|m| unusable(&canonical, m))?;
        armcomp_core::support::io::note_read(&canonical);
        let mut libraries = lock(&LIBRARIES);
        if let Some(lib) = libraries.get(&canonical) {
            return Ok(lib);
        }
        let lib = Self::open(&canonical)?;
        libraries.insert(canonical, lib);
        Ok(lib)
    }

    fn open(path: &Path) -> Result<&'static PluginLibrary> {
        let file_name = path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default();
        // SAFETY: loading runs the library's initialisers; a plugin library is trusted code the
        // user named, and it is never unloaded, so no symbol outlives it.
        let library =
            unsafe { Library::new(path) }.map_err(|e| unusable(path, format!("not a loadable shared library: {e}")))?;
        let library: &'static Library = Box::leak(Box::new(library));
        macro_rules! symbol {
            ($name:literal, $ty:ty) => {
                // SAFETY: the symbol has this signature in every library that reports our ABI
                // version, which is checked before any other symbol is looked up.
                *unsafe { library.get::<$ty>(concat!($name, "\0").as_bytes()) }.map_err(|_| {
                    unusable(
                        path,
                        format!(
                            "does not export `{}`, which plugin ABI version {} requires",
                            $name, ABI_VERSION
                        ),
                    )
                })?
            };
        }
        // SAFETY: `armcomp_abi_version` takes nothing and returns a u32 in every ABI version.
        let version =
            unsafe { library.get::<abi::signatures::AbiVersion>(b"armcomp_abi_version\0") }.map_err(|_| {
                unusable(
                    path,
                    "not an armcomp plugin: it does not export `armcomp_abi_version`".into(),
                )
            })?;
        // SAFETY: as above.
        let version = unsafe { version() };
        if version != ABI_VERSION {
            return Err(Error::AbiMismatch {
                library: path.to_path_buf(),
                expected: ABI_VERSION,
                found: version,
            });
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
                return Err(lib.failure(status, &format!("type {index} cannot be described")));
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
                other => return Err(unusable(path, format!("type `{name}` has unknown role {other}"))),
            };
            let validator = if schema.is_empty() {
                None
            } else {
                let value: Value = serde_json::from_str(&schema)
                    .map_err(|e| unusable(path, format!("type `{name}` has a config schema that is not JSON: {e}")))?;
                Some(jsonschema::validator_for(&value).map_err(|e| {
                    unusable(
                        path,
                        format!("type `{name}` has a config schema that does not compile: {e}"),
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
                        .map_err(|e| unusable(path, format!("type `{name}`: {e}")))?
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

    fn find(&self, name: &str, role: Role) -> Result<&LoadedType> {
        self.types
            .iter()
            .find(|t| t.info.type_name == name && t.info.role == role)
            .ok_or_else(|| Error::UnknownPlugin {
                role,
                name: name.to_string(),
                known: self
                    .types
                    .iter()
                    .filter(|t| t.info.role == role)
                    .map(|t| t.info.type_name.to_string())
                    .collect(),
                provider: self.file_name.clone(),
            })
    }

    /// The library a file in `folder` names as `library`: a path relative to that folder, in
    /// the platform's naming, which loads only from inside it (or from a trusted folder). Every
    /// library a robot or model file names is found and checked this way.
    fn load_for_file(folder: &Path, library: &str) -> Result<&'static PluginLibrary> {
        Self::load(&platform_library_path(&folder.join(library)), Origin::File(folder))
    }

    /// The library a file in `folder` names as `library` ([`load_for_file`](Self::load_for_file))
    /// and its type `model` of `role`, with `config` (when given) checked against the type's
    /// schema; each problem an issue at its field under `field` (`field.library`,
    /// `field.model`, `field.config.…`).
    fn resolve(
        folder: &Path,
        library: &str,
        model: &str,
        role: Role,
        config: Option<&Value>,
        field: &str,
    ) -> std::result::Result<(&'static PluginLibrary, &'static LoadedType), Issues> {
        let lib = PluginLibrary::load_for_file(folder, library)
            .map_err(|e| one_issue(format!("{field}.library"), e.to_string()))?;
        let ty = lib
            .find(model, role)
            .map_err(|e| one_issue(format!("{field}.model"), e.to_string()))?;
        if let (Some(validator), Some(config)) = (&ty.validator, config) {
            let issues = schema_issues(validator, config, &format!("{field}.config"), &lib.file_name);
            if !issues.is_empty() {
                return Err(issues);
            }
        }
        Ok((lib, ty))
    }

    /// The message of the last failure on this thread.
    fn last_error(&self) -> String {
        // SAFETY: no arguments; the string is valid until the next call on this thread.
        unsafe { owned((self.api.last_error)()) }
    }

    /// The error of a call that returned `status`.
    fn failure(&self, status: i32, what: &str) -> Error {
        let reason = match status {
            STATUS_UNSUPPORTED => "not supported".to_string(),
            _ => self.last_error(),
        };
        self.unusable(format!("{what}: {reason}"))
    }

    /// A problem with this library.
    fn unusable(&self, message: String) -> Error {
        unusable(&self.path, message)
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

/// The files (canonical paths) of the libraries loaded so far.
pub fn loaded_libraries() -> Vec<PathBuf> {
    lock(&LIBRARIES).keys().cloned().collect()
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

/// Loads a library named on the command line to list its types (`armcomp plugins --library`).
pub fn load_library(path: &Path) -> Result<Vec<PluginInfo>> {
    Ok(PluginLibrary::load(&platform_library_path(path), Origin::CommandLine)?.plugins())
}

fn one_issue(path: impl Into<String>, message: impl Into<String>) -> Issues {
    let mut issues = Issues::default();
    issues.push(path, message);
    issues
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

fn empty_config() -> Value {
    Value::Object(Default::default())
}

/// Schema of a config: any JSON object; the library's own schema checks it when it is loaded.
type ConfigObject = serde_json::Map<String, Value>;
