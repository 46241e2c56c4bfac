//! Residual predictors for armcomp: what the physical model leaves, learned from measurements.
//!
//! Each predictor is a serialisable spec ([`armcomp_core::PredictorSpec`], hyper-parameters and
//! a seed) that fits into a serialisable [`armcomp_core::FittedPredictor`]. Inputs and targets
//! are standardised inside every fitted model; fits are deterministic for a seed; prediction
//! allocates nothing after the first call.
//!
//! - [`ssa_bp`]: the deflection paper's SSA-BP, a [`sparrow`] search over the weights of a
//!   back-propagation [`network`], refined by gradient ([`train`]);
//! - [`mlp`]: the same network trained by Adam or Levenberg–Marquardt alone;
//! - [`gp`]: Gaussian process regression with an ARD RBF kernel, with predictive uncertainty;
//! - [`ridge`] and [`knn`]: baselines.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

/// `From<$fitted> for $model` and `$fitted::model()`, for fitted predictors that wrap the checked
/// form they are stored in.
macro_rules! stored_model {
    ($fitted:ident, $model:ident) => {
        impl From<$fitted> for $model {
            fn from(f: $fitted) -> Self {
                f.0
            }
        }

        impl $fitted {
            /// The stored model.
            pub fn model(&self) -> &$model {
                &self.0
            }
        }
    };
}

mod data;
mod lbfgs;
mod rbf;

pub mod gp;
pub mod knn;
pub mod mlp;
pub mod network;
pub mod ridge;
pub mod sparrow;
pub mod ssa_bp;
pub mod train;

pub use data::Standardizer;
pub use gp::{FittedGp, GpHyperParams, GpKernelModel, GpLikelihood, GpModel, GpSpec, KernelSharing};
pub use knn::{FittedKnn, KnnModel, KnnSpec, KnnWeighting};
pub use mlp::MlpSpec;
pub use network::{FittedMlp, MlpModel, Network};
pub use ridge::{FittedRidge, RidgeFeatures, RidgeModel, RidgeSpec};
pub use sparrow::{SparrowParams, SparrowReport, sparrow_search};
pub use ssa_bp::SsaBpSpec;
pub use train::{GradientMethod, TrainingParams};

use armcomp_core::{PluginInfo, Role};

macro_rules! entry {
    ($name:literal, $spec:ty, $doc:literal) => {
        PluginInfo {
            type_name: $name,
            role: Role::Predictor,
            doc: $doc,
            diagnosis_candidate: false,
            candidates: None,
            schema: |g| <$spec as schemars::JsonSchema>::json_schema(g),
        }
    };
}

/// The plugins of this crate, for the registry.
pub fn plugins() -> Vec<PluginInfo> {
    vec![
        entry!(
            "ssa_bp",
            SsaBpSpec,
            "Back-propagation network whose starting weights come from a sparrow search (Xue & Shen 2020), refined by Adam or Levenberg-Marquardt"
        ),
        entry!(
            "mlp",
            MlpSpec,
            "Multilayer perceptron (one or two tanh hidden layers) trained by Adam or Levenberg-Marquardt with early stopping"
        ),
        entry!(
            "gp",
            GpSpec,
            "Gaussian process regression, ARD RBF kernel and noise fitted by maximum marginal likelihood; predictive standard deviation"
        ),
        entry!(
            "ridge",
            RidgeSpec,
            "Ridge regression on standardised linear, optionally quadratic and trigonometric features (baseline)"
        ),
        entry!(
            "knn",
            KnnSpec,
            "k-nearest-neighbour regression in standardised input space (baseline)"
        ),
    ]
}
