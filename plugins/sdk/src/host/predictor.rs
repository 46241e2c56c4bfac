//! A run-time residual predictor: the `plugin` spec of robot files and the fitted predictor it
//! gives, a handle of a loaded library behind the core's [`FittedPredictor`] trait.

use std::os::raw::c_void;
use std::path::{Path, PathBuf};

use armcomp_core::{
    BuildContext, Error, FitControl, FittedPredictor, Issues, PredictorSpec, Result, Role, TrainingSet,
};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::handle::PluginHandle;
use super::{ConfigObject, PluginLibrary, empty_config};
use crate::abi::*;
use crate::flat::abi_str;

/// A run-time residual predictor as written in a robot file (`type = "plugin"`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PluginPredictorSpec {
    /// The shared library: a path relative to the robot file, inside its folder unless the
    /// library's folder is trusted; platform naming as for error models.
    pub library: String,
    /// The predictor type the library exports.
    pub model: String,
    /// The predictor's own hyper-parameters, checked against the schema the library provides.
    #[serde(default = "empty_config")]
    #[schemars(with = "ConfigObject")]
    pub config: Value,
    /// The folder of the file that names the spec, which `library` is relative to and must lie
    /// in; set when the robot is built, the working folder for a spec made in code.
    #[serde(skip)]
    #[schemars(skip)]
    pub folder: Option<PathBuf>,
}

#[typetag::serde(name = "plugin")]
impl PredictorSpec for PluginPredictorSpec {
    fn fit_with(&self, data: &TrainingSet<'_>, control: &FitControl<'_>) -> Result<Box<dyn FittedPredictor>> {
        // A library's fit is one call that cannot be stopped part-way.
        control.cancel.check()?;
        let (lib, ty) = PluginLibrary::resolve(
            self.folder.as_deref().unwrap_or(Path::new("")),
            &self.library,
            &self.model,
            Role::Predictor,
            Some(&self.config),
            "predictor",
        )
        .map_err(|issues| Error::InvalidModel(issues.0))?;
        let n = data.inputs.len() / data.n_inputs.max(1);
        if data.inputs.len() != n * data.n_inputs || data.targets.len() != n * data.n_outputs {
            return Err(Error::InvalidArgument {
                what: "training set".into(),
                reason: format!(
                    "{} inputs and {} targets are not {n} rows of {} and {}",
                    data.inputs.len(),
                    data.targets.len(),
                    data.n_inputs,
                    data.n_outputs
                ),
            });
        }
        if !data.input_ranges.is_empty() && data.input_ranges.len() != data.n_inputs {
            return Err(Error::InvalidArgument {
                what: "training set".into(),
                reason: format!(
                    "{} input ranges for {} inputs; expected one per input or none",
                    data.input_ranges.len(),
                    data.n_inputs
                ),
            });
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
        let mut raw = std::ptr::null_mut();
        // SAFETY: the arrays of `set` and `config` live for the call; `raw` is valid.
        let status = unsafe { (lib.api.predictor_fit)(ty.index, abi_str(&config), &set, &mut raw) };
        if status != STATUS_OK || raw.is_null() {
            return Err(lib.failure(status, &format!("predictor `{}` cannot be fitted", self.model)));
        }
        Ok(Box::new(PluginPredictor::new(lib, self.model.clone(), raw)?))
    }

    /// Loads the library from the robot file's folder and checks the config against its schema
    /// before anything is fitted; the spec to fit names the library by its resolved path.
    fn resolve(&self, ctx: &BuildContext<'_>) -> std::result::Result<Option<Box<dyn PredictorSpec>>, Issues> {
        let (lib, _) = PluginLibrary::resolve(
            ctx.base_dir,
            &self.library,
            &self.model,
            Role::Predictor,
            Some(&self.config),
            ctx.path,
        )?;
        Ok(Some(Box::new(PluginPredictorSpec {
            library: lib.path.to_string_lossy().into_owned(),
            folder: Some(ctx.base_dir.to_path_buf()),
            ..self.clone()
        })))
    }
}

/// A fitted predictor living in a plugin library, behind the core's [`FittedPredictor`] trait.
/// In model files it is `{type = "plugin", library, model, fitted}`, `fitted` being the plugin's
/// own JSON.
#[derive(Debug)]
pub struct PluginPredictor {
    handle: PluginHandle,
    n_inputs: usize,
    n_outputs: usize,
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
    /// Takes ownership of `raw`, a live predictor handle of `library`, and reads its shape.
    fn new(library: &'static PluginLibrary, model: String, raw: *mut c_void) -> Result<Self> {
        // SAFETY: the caller hands over a live handle just made by this library.
        let handle = unsafe { PluginHandle::new(library, model, raw, library.api.predictor_destroy) };
        let (mut n_inputs, mut n_outputs) = (0, 0);
        // SAFETY: a live handle; both outputs valid for one write.
        let status = unsafe { (library.api.predictor_shape)(raw, &mut n_inputs, &mut n_outputs) };
        if status != STATUS_OK {
            // Dropping `handle` destroys the plugin's predictor.
            return Err(handle.failure(status, &format!("predictor `{}` shape", handle.model)));
        }
        Ok(PluginPredictor {
            handle,
            n_inputs,
            n_outputs,
        })
    }

    fn load(record: PredictorRecord) -> Result<Self> {
        // The library lies beside the model file that stores the predictor.
        let folder = armcomp_core::robot::robot_file::folder_being_read().unwrap_or_default();
        let lib = PluginLibrary::load_for_file(&folder, &record.library)?;
        let ty = lib.find(&record.model, Role::Predictor)?;
        let json = record.fitted.to_string();
        let mut raw = std::ptr::null_mut();
        // SAFETY: `json` lives for the call; `raw` is valid for one write.
        let status = unsafe { (lib.api.predictor_load)(ty.index, abi_str(&json), &mut raw) };
        if status != STATUS_OK || raw.is_null() {
            return Err(lib.failure(status, &format!("predictor `{}` cannot be loaded", record.model)));
        }
        PluginPredictor::new(lib, record.model, raw)
    }

    /// The last failure of a prediction, if any (the trait's `predict_into` cannot return it).
    pub fn last_failure(&self) -> Option<String> {
        self.handle.last_failure()
    }

    /// The prediction into `out`, and its standard deviation into `std` when asked; false when
    /// the plugin has none. Takes no lock: the plugin may run this on several threads at once
    /// (ABI version 4).
    fn try_predict(&self, input: &[f64], out: &mut [f64], std: Option<&mut [f64]>) -> Result<bool> {
        let h = &self.handle;
        for (what, expected, got) in [
            ("inputs", self.n_inputs, input.len()),
            ("outputs", self.n_outputs, out.len()),
            (
                "standard deviations",
                self.n_outputs,
                std.as_ref().map_or(self.n_outputs, |s| s.len()),
            ),
        ] {
            if got != expected {
                return Err(Error::Dimension {
                    what: format!("{what} of predictor `{}`", h.model),
                    expected,
                    got,
                });
            }
        }
        let (with_std, std_ptr) = match std {
            Some(s) => (1, s.as_mut_ptr()),
            None => (0, std::ptr::null_mut()),
        };
        // SAFETY: a live handle; `input`, `out` and `std_ptr` hold the sizes passed and are
        // this call's alone.
        let status = unsafe {
            (h.library.api.predictor_predict)(
                h.raw(),
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
            _ => return Err(h.failure(status, "predict")),
        }
        if let Some(i) = out.iter().position(|v| !v.is_finite()) {
            return Err(h.library.unusable(format!("predict returned {} as output {i}", out[i])));
        }
        Ok(true)
    }
}

impl Serialize for PluginPredictor {
    fn serialize<S: serde::Serializer>(&self, s: S) -> std::result::Result<S::Ok, S::Error> {
        let api = &self.handle.library.api;
        let fitted = self
            .handle
            .json("save", |raw, json| {
                // SAFETY: a live handle; `json` valid for one write.
                unsafe { (api.predictor_save)(raw, json) }
            })
            .map_err(serde::ser::Error::custom)?;
        PredictorRecord {
            library: self.handle.library.path.to_string_lossy().into_owned(),
            model: self.handle.model.clone(),
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
        if let Err(e) = self.try_predict(input, out, None) {
            out.iter_mut().for_each(|v| *v = f64::NAN);
            self.handle.record_failure(&e);
        }
    }

    fn predict_std_into(&self, input: &[f64], out: &mut [f64], scratch: &mut Vec<f64>) -> bool {
        // The mean the plugin computes alongside goes to the caller's scratch.
        scratch.resize(self.n_outputs, 0.0);
        match self.try_predict(input, &mut scratch[..self.n_outputs], Some(out)) {
            Ok(has_std) => has_std && out.iter().all(|v| v.is_finite()),
            Err(e) => {
                self.handle.record_failure(&e);
                false
            }
        }
    }
}
