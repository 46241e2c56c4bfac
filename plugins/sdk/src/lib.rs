//! armcomp-sdk: error models and residual predictors as run-time plugins.
//!
//! A plugin author implements the core traits (`ErrorModelSpec`/`ErrorModel`,
//! `PredictorSpec`/`FittedPredictor`) exactly as for a plugin linked into armcomp, then exports
//! them from a `cdylib` with one [`export_plugins!`] call. The library speaks the versioned C ABI
//! of [`abi`]; the host side ([`host`], feature `host`) loads it with libloading, checks the ABI
//! version and symbols, validates configs against the schemas the plugin provides, and wraps the
//! handles in the same traits, so the pipelines cannot tell a loaded model from a built-in one.
//! No panic and no NaN crosses the boundary: every entry point catches panics, and the host
//! rejects non-finite outputs and outputs of the wrong size.
//!
//! ```ignore
//! armcomp_sdk::export_plugins! {
//!     error_model CableSagSpec {
//!         name: "cable_sag",
//!         doc: "A cable hanging along the boom pulls its tip down",
//!         diagnosis_candidate: true,
//!         candidate: { "per": "link", "field": "link", "label": "cable sag",
//!                      "config": { "mass_per_length": 0.0 } },
//!     },
//! }
//! ```
#![warn(missing_docs)]
// The only crate with `unsafe`: each block says why it is sound.
#![deny(clippy::undocumented_unsafe_blocks)]

pub mod abi;
#[doc(hidden)]
pub mod export;
pub mod flat;
#[cfg(feature = "host")]
pub mod host;
mod per_thread;

#[cfg(feature = "host")]
pub use host::{
    NOT_ALLOWED, PluginErrorModel, PluginErrorModelSpec, PluginPolicy, PluginPredictor, PluginPredictorSpec,
    load_library, loaded_libraries, loaded_plugins, plugins, set_policy,
};

/// Exports error models and predictors through the C ABI of [`abi`]. Call it once, at the root
/// of a `cdylib` crate, listing every type the library provides:
///
/// - `error_model Spec { name: "...", doc: "...", diagnosis_candidate: true, candidate: {...} }`,
///   where `Spec` implements `ErrorModelSpec + serde::de::DeserializeOwned + schemars::JsonSchema`;
///   its config in the robot file is `Spec` as JSON/TOML; `diagnosis_candidate` is optional
///   (false); `candidate`, optional, is the JSON (as for `serde_json::json!`) of an
///   `armcomp_core::CandidateTemplate` telling the diagnosis how to instantiate the model, e.g.
///   `{ "per": "link", "field": "link", "label": "cable sag", "config": { "mass_per_length": 0.0 } }`
///   (without it, a candidate is tried once, globally, with an empty config).
/// - `predictor Spec { name: "...", doc: "..." }`, where `Spec` implements
///   `PredictorSpec + serde::de::DeserializeOwned + schemars::JsonSchema`.
///
/// The name should be the one the spec's `#[typetag::serde(name = ...)]` gives, so that the same
/// crate linked in as an rlib reads the same robot files with `type = "<name>"`. Plugins must keep
/// the default `panic = "unwind"`: panics are caught at the boundary.
#[macro_export]
macro_rules! export_plugins {
    ($($role:ident $spec:ty {
        name: $name:literal,
        doc: $doc:literal
        $(, diagnosis_candidate: $cand:literal)?
        $(, candidate: $template:tt)?
        $(,)?
    }),+ $(,)?) => {
        static ARMCOMP_PLUGIN_TYPES: &[$crate::export::TypeEntry] = &[
            $($crate::export_plugins!(
                @entry $role $spec, $name, $doc,
                $crate::export_plugins!(@candidate $($cand)?),
                $crate::export_plugins!(@template $($template)?)
            )),+
        ];
        static ARMCOMP_PLUGIN_TEXTS: ::std::sync::OnceLock<
            ::std::vec::Vec<::std::result::Result<$crate::export::TypeTexts, ::std::string::String>>,
        > = ::std::sync::OnceLock::new();

        /// The plugin ABI version this library speaks.
        #[unsafe(no_mangle)]
        pub extern "C" fn armcomp_abi_version() -> u32 {
            $crate::abi::ABI_VERSION
        }

        /// Number of types this library exports.
        #[unsafe(no_mangle)]
        pub extern "C" fn armcomp_type_count() -> u32 {
            $crate::export::type_count(ARMCOMP_PLUGIN_TYPES)
        }

        /// The last error on this thread.
        #[unsafe(no_mangle)]
        pub extern "C" fn armcomp_last_error() -> $crate::abi::AbiStr {
            $crate::export::last_error()
        }

        /// See [`armcomp_sdk::abi`].
        ///
        /// # Safety
        /// The pointer arguments must follow the armcomp plugin ABI.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn armcomp_type_info(index: u32, out: *mut $crate::abi::AbiTypeInfo) -> i32 {
            // SAFETY: the host follows the ABI, which is what the callee requires.
            unsafe { $crate::export::type_info(ARMCOMP_PLUGIN_TYPES, &ARMCOMP_PLUGIN_TEXTS, index, out) }
        }

        /// See [`armcomp_sdk::abi`].
        ///
        /// # Safety
        /// The pointer arguments must follow the armcomp plugin ABI.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn armcomp_model_create(
            index: u32,
            config: $crate::abi::AbiStr,
            ctx: *const $crate::abi::AbiModelContext,
            out: *mut *mut ::std::os::raw::c_void,
        ) -> i32 {
            // SAFETY: the host follows the ABI, which is what the callee requires.
            unsafe { $crate::export::model_create(ARMCOMP_PLUGIN_TYPES, index, config, ctx, out) }
        }

        /// See [`armcomp_sdk::abi`].
        ///
        /// # Safety
        /// The pointer arguments must follow the armcomp plugin ABI.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn armcomp_model_param_count(model: *mut ::std::os::raw::c_void) -> u32 {
            // SAFETY: the host follows the ABI, which is what the callee requires.
            unsafe { $crate::export::model_param_count(model) }
        }

        /// See [`armcomp_sdk::abi`].
        ///
        /// # Safety
        /// The pointer arguments must follow the armcomp plugin ABI.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn armcomp_model_param(
            model: *mut ::std::os::raw::c_void,
            index: u32,
            out: *mut $crate::abi::AbiParam,
        ) -> i32 {
            // SAFETY: the host follows the ABI, which is what the callee requires.
            unsafe { $crate::export::model_param(model, index, out) }
        }

        /// See [`armcomp_sdk::abi`].
        ///
        /// # Safety
        /// The pointer arguments must follow the armcomp plugin ABI.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn armcomp_model_perturb(
            model: *mut ::std::os::raw::c_void,
            state: *const $crate::abi::AbiState,
            values: *const f64,
            n_values: usize,
            out: *mut $crate::abi::AbiPerturbation,
        ) -> i32 {
            // SAFETY: the host follows the ABI, which is what the callee requires.
            unsafe { $crate::export::model_perturb(model, state, values, n_values, out) }
        }

        /// See [`armcomp_sdk::abi`].
        ///
        /// # Safety
        /// The pointer arguments must follow the armcomp plugin ABI.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn armcomp_model_spec_with(
            model: *mut ::std::os::raw::c_void,
            values: *const f64,
            n_values: usize,
            out: *mut $crate::abi::AbiStr,
        ) -> i32 {
            // SAFETY: the host follows the ABI, which is what the callee requires.
            unsafe { $crate::export::model_spec_with(model, values, n_values, out) }
        }

        /// See [`armcomp_sdk::abi`].
        ///
        /// # Safety
        /// The pointer arguments must follow the armcomp plugin ABI.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn armcomp_model_destroy(model: *mut ::std::os::raw::c_void) {
            // SAFETY: the host follows the ABI, which is what the callee requires.
            unsafe { $crate::export::model_destroy(model) }
        }

        /// See [`armcomp_sdk::abi`].
        ///
        /// # Safety
        /// The pointer arguments must follow the armcomp plugin ABI.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn armcomp_predictor_fit(
            index: u32,
            config: $crate::abi::AbiStr,
            data: *const $crate::abi::AbiTrainingSet,
            out: *mut *mut ::std::os::raw::c_void,
        ) -> i32 {
            // SAFETY: the host follows the ABI, which is what the callee requires.
            unsafe { $crate::export::predictor_fit(ARMCOMP_PLUGIN_TYPES, index, config, data, out) }
        }

        /// See [`armcomp_sdk::abi`].
        ///
        /// # Safety
        /// The pointer arguments must follow the armcomp plugin ABI.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn armcomp_predictor_load(
            index: u32,
            fitted: $crate::abi::AbiStr,
            out: *mut *mut ::std::os::raw::c_void,
        ) -> i32 {
            // SAFETY: the host follows the ABI, which is what the callee requires.
            unsafe { $crate::export::predictor_load(ARMCOMP_PLUGIN_TYPES, index, fitted, out) }
        }

        /// See [`armcomp_sdk::abi`].
        ///
        /// # Safety
        /// The pointer arguments must follow the armcomp plugin ABI.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn armcomp_predictor_shape(
            predictor: *mut ::std::os::raw::c_void,
            n_inputs: *mut usize,
            n_outputs: *mut usize,
        ) -> i32 {
            // SAFETY: the host follows the ABI, which is what the callee requires.
            unsafe { $crate::export::predictor_shape(predictor, n_inputs, n_outputs) }
        }

        /// See [`armcomp_sdk::abi`].
        ///
        /// # Safety
        /// The pointer arguments must follow the armcomp plugin ABI.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn armcomp_predictor_predict(
            predictor: *mut ::std::os::raw::c_void,
            input: *const f64,
            n_inputs: usize,
            out: *mut f64,
            n_outputs: usize,
            with_std: u32,
            out_std: *mut f64,
        ) -> i32 {
            // SAFETY: the host follows the ABI, which is what the callee requires.
            unsafe { $crate::export::predictor_predict(predictor, input, n_inputs, out, n_outputs, with_std, out_std) }
        }

        /// See [`armcomp_sdk::abi`].
        ///
        /// # Safety
        /// The pointer arguments must follow the armcomp plugin ABI.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn armcomp_predictor_save(
            predictor: *mut ::std::os::raw::c_void,
            out: *mut $crate::abi::AbiStr,
        ) -> i32 {
            // SAFETY: the host follows the ABI, which is what the callee requires.
            unsafe { $crate::export::predictor_save(predictor, out) }
        }

        /// See [`armcomp_sdk::abi`].
        ///
        /// # Safety
        /// The pointer arguments must follow the armcomp plugin ABI.
        #[unsafe(no_mangle)]
        pub unsafe extern "C" fn armcomp_predictor_destroy(predictor: *mut ::std::os::raw::c_void) {
            // SAFETY: the host follows the ABI, which is what the callee requires.
            unsafe { $crate::export::predictor_destroy(predictor) }
        }
    };
    (@candidate) => { false };
    (@candidate $cand:literal) => { $cand };
    (@template) => { None };
    (@template $template:tt) => { Some(|| $crate::export::serde_json::json!($template)) };
    (@entry error_model $spec:ty, $name:literal, $doc:literal, $cand:expr, $template:expr) => {
        $crate::export::TypeEntry {
            name: $name,
            doc: $doc,
            diagnosis_candidate: $cand,
            candidate_template: $template,
            constructor: $crate::export::Constructor::ErrorModel($crate::export::create_model::<$spec>),
            schema: $crate::export::schema_of::<$spec>,
        }
    };
    (@entry predictor $spec:ty, $name:literal, $doc:literal, $cand:expr, $template:expr) => {
        $crate::export::TypeEntry {
            name: $name,
            doc: $doc,
            diagnosis_candidate: $cand,
            candidate_template: $template,
            constructor: $crate::export::Constructor::Predictor($crate::export::fit_predictor::<$spec>),
            schema: $crate::export::schema_of::<$spec>,
        }
    };
}
