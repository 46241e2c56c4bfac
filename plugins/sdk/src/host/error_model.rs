//! A run-time error model: the `plugin` spec of robot files and the model it builds, a handle of
//! a loaded library behind the core's [`ErrorModel`] trait.

use std::cell::Cell;
use std::collections::BTreeMap;
use std::sync::Mutex;

use armcomp_core::kinematics::subtree_loads::SubtreeLoads;
use armcomp_core::{
    Error, ErrorModel, ErrorModelSpec, Issues, ModelContext, ParamInfo, Perturbation, Quantity, Result, Role,
    StaticState, TreeWorkspace,
};
use nalgebra::{Vector3, Vector6};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::handle::PluginHandle;
use super::{ConfigObject, LoadedType, PluginLibrary, empty_config, lock, one_issue, owned};
use crate::abi::*;
use crate::flat::{FlatMass, FlatState, FlatTree, abi_str};
use crate::per_thread::with_buffers;

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
        _ => issues.push(path, lib.failure(status, what).to_string()),
    }
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
        let (lib, ty) = PluginLibrary::resolve(
            ctx.build.base_dir,
            &self.library,
            &self.model,
            Role::ErrorModel,
            Some(&self.config),
            path,
        )?;
        let spec = PluginErrorModelSpec {
            library: lib.path.to_string_lossy().into_owned(),
            ..self.clone()
        };
        let model = PluginErrorModel::create(lib, ty, spec, ctx, &format!("{path}.config"))?;
        model.probe(ctx).map_err(|m| one_issue(path, m))?;
        Ok(Box::new(model))
    }
}

/// The host's side of a perturb call, reused by the calls of one thread: the flat state the
/// plugin reads and the buffers it writes its deformation into.
#[derive(Default)]
struct PerturbBuffers {
    state: FlatState,
    joint_twists: Vec<f64>,
    joint_offsets: Vec<f64>,
    point_twists: Vec<f64>,
}

thread_local! {
    static PERTURB_BUFFERS: Cell<Option<PerturbBuffers>> = const { Cell::new(None) };
}

/// `buffer` as `len` NaNs, so that an entry the plugin leaves out shows as non-finite.
fn nan_filled(buffer: &mut Vec<f64>, len: usize) -> *mut f64 {
    buffer.clear();
    buffer.resize(len, f64::NAN);
    buffer.as_mut_ptr()
}

/// An error model living in a plugin library, behind the core's [`ErrorModel`] trait.
#[derive(Debug)]
pub struct PluginErrorModel {
    handle: PluginHandle,
    spec: PluginErrorModelSpec,
    params: Vec<ParamInfo>,
    n_joints: usize,
    n_points: usize,
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
        let mut raw = std::ptr::null_mut();
        // SAFETY: the context's arrays live in `tree`, `mass` and `ctx` for the whole call.
        let status = unsafe { (library.api.model_create)(ty.index, abi_str(&config), &abi_ctx, &mut raw) };
        if status != STATUS_OK || raw.is_null() {
            let what = format!("model `{}` cannot be built", spec.model);
            return Err(plugin_issues(library, status, config_path, &what));
        }
        // SAFETY: a live handle just created by this library, owned by nothing else.
        let handle = unsafe { PluginHandle::new(library, spec.model.clone(), raw, library.api.model_destroy) };
        let mut model = PluginErrorModel {
            handle,
            spec,
            params: Vec::new(),
            n_joints: ctx.tree.joints().len(),
            n_points: ctx.tree.points().len(),
        };
        model.params = model.read_params().map_err(|e| one_issue(config_path, e.to_string()))?;
        Ok(model)
    }

    fn read_params(&self) -> Result<Vec<ParamInfo>> {
        let (lib, raw) = (self.handle.library, self.handle.raw());
        // SAFETY: a live handle of this library.
        let count = unsafe { (lib.api.model_param_count)(raw) };
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
            let status = unsafe { (lib.api.model_param)(raw, i, &mut p) };
            if status != STATUS_OK {
                return Err(lib.failure(status, &format!("parameter {i} cannot be read")));
            }
            // SAFETY: the strings are valid until the next call into the library on this thread.
            let (name, unit) = unsafe { (owned(p.name), owned(p.unit)) };
            let q = quantity(p.quantity, unit).map_err(|m| lib.unusable(format!("parameter `{name}`: {m}")))?;
            if !p.nominal.is_finite() || p.sigma.is_nan() || p.sigma <= 0.0 {
                return Err(lib.unusable(format!(
                    "parameter `{name}` has nominal value {} and prior sigma {}; expected a finite value and a positive sigma",
                    p.nominal, p.sigma
                )));
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
        let loads = SubtreeLoads::of(tree, &frames, ctx.mass);
        for temperature in [None, Some(30.0)] {
            let state = StaticState {
                q: &q,
                tree,
                frames: &frames,
                mass: ctx.mass,
                loads: &loads,
                gravity: Vector3::new(0.0, 0.0, -9.81),
                temperature,
                sensors: Default::default(),
            };
            self.try_perturb(&state, &values, &mut out).map_err(|e| {
                format!(
                    "model `{}` fails at mid-range joint values with its nominal parameters: {e}",
                    self.spec.model
                )
            })?;
        }
        self.try_spec_with(&values).map(|_| ()).map_err(|e| e.to_string())
    }

    /// The last failure of a `perturb` or `spec_with` call, if any (the trait cannot return it).
    pub fn last_failure(&self) -> Option<String> {
        self.handle.last_failure()
    }

    /// The plugin's deformation added to `out`, after checking its values. Takes no lock: the
    /// plugin may run this on several threads at once (ABI version 4), each with its own
    /// buffers.
    fn try_perturb(&self, state: &StaticState<'_>, values: &[f64], out: &mut Perturbation) -> Result<()> {
        let h = &self.handle;
        if values.len() != self.params.len() {
            return Err(Error::Dimension {
                what: format!("parameter values of model `{}`", h.model),
                expected: self.params.len(),
                got: values.len(),
            });
        }
        with_buffers(&PERTURB_BUFFERS, |b| {
            let abi_state = b.state.fill(state);
            let view = AbiPerturbation {
                joint_twists: nan_filled(&mut b.joint_twists, TWIST_LEN * self.n_joints),
                n_joint_twists: self.n_joints,
                joint_offsets: nan_filled(&mut b.joint_offsets, self.n_joints),
                n_joint_offsets: self.n_joints,
                point_twists: nan_filled(&mut b.point_twists, TWIST_LEN * self.n_points),
                n_point_twists: self.n_points,
            };
            // SAFETY: a live handle; the state's arrays live in `b.state` and `state`, the
            // output buffers in `b` (this thread's alone), for the call; `values` is valid.
            let status =
                unsafe { (h.library.api.model_perturb)(h.raw(), &abi_state, values.as_ptr(), values.len(), &view) };
            if status != STATUS_OK {
                return Err(h.failure(status, "perturb"));
            }
            for (what, values) in [
                ("joint twists", &b.joint_twists),
                ("joint offsets", &b.joint_offsets),
                ("point twists", &b.point_twists),
            ] {
                if let Some(i) = values.iter().position(|v| !v.is_finite()) {
                    return Err(h
                        .library
                        .unusable(format!("perturb returned {} among the {what} (value {i})", values[i])));
                }
            }
            for (t, src) in out.joint_twist.iter_mut().zip(b.joint_twists.chunks_exact(TWIST_LEN)) {
                *t += Vector6::from_column_slice(src);
            }
            for (v, src) in out.joint_offset.iter_mut().zip(&b.joint_offsets) {
                *v += src;
            }
            for (t, src) in out.point_twist.iter_mut().zip(b.point_twists.chunks_exact(TWIST_LEN)) {
                *t += Vector6::from_column_slice(src);
            }
            Ok(())
        })
    }

    fn try_spec_with(&self, values: &[f64]) -> Result<PluginErrorModelSpec> {
        let api = &self.handle.library.api;
        let config = self.handle.json("spec_with", |raw, json| {
            // SAFETY: a live handle; `values` and `json` are valid for the call.
            unsafe { (api.model_spec_with)(raw, values.as_ptr(), values.len(), json) }
        })?;
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
        if let Err(e) = self.try_perturb(state, values, out) {
            out.joint_offset.iter_mut().for_each(|v| *v = f64::NAN);
            self.handle.record_failure(&e);
        }
    }

    /// Built models passed this at build time with their nominal values; should the plugin fail
    /// later, the spec keeps the config it was built from and [`last_failure`] says why.
    ///
    /// [`last_failure`]: PluginErrorModel::last_failure
    fn spec_with(&self, values: &[f64]) -> Box<dyn ErrorModelSpec> {
        match self.try_spec_with(values) {
            Ok(spec) => Box::new(spec),
            Err(e) => {
                self.handle.record_failure(&e);
                Box::new(self.spec.clone())
            }
        }
    }
}
