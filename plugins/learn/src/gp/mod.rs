//! `gp`: Gaussian process regression with an ARD squared-exponential (RBF) kernel and Gaussian
//! noise, hyper-parameters by maximising the log marginal likelihood, predictive mean and
//! standard deviation.
//!
//! Inputs and targets are standardised first; the kernel hyper-parameters live in those units.
//! With `kernels = "shared"` (default) all outputs share one kernel, so one factorisation of the
//! n × n kernel matrix serves every output and the likelihood is the sum over outputs; with
//! `"per_output"` each output gets its own length-scales, signal and noise (k times the cost).
//! Hyper-parameters are optimised on at most `max_optimization_samples` rows drawn with the seed
//! (the O(n³) likelihood is evaluated tens of times; the full set is factorised once at the
//! end), the predictor itself uses every row.
//!
//! Files: `likelihood` (the marginal likelihood and its gradient), `fit` (the spec and the
//! fit), `fitted` (the fitted process and its stored form).

mod fit;
mod fitted;
mod likelihood;

pub use fit::{GpSpec, KernelSharing};
use fitted::*;
pub use fitted::{FittedGp, GpKernelModel, GpModel};
use likelihood::*;
pub use likelihood::{GpHyperParams, GpLikelihood};
