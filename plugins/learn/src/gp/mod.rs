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
//! Up to `exact_up_to` rows (1,000) the process is exact. Beyond, the mean is the
//! inducing-point (subset-of-regressors) one: `inducing` rows (300) drawn with the seed carry
//! the weights, which every row's target enters, in O(n m²) time and O(m²) memory, so 100,000
//! rows fit in seconds and a model file holds m rows, not n. The defaults keep a fit of a few
//! thousand rows near 0.1 s, since `fit` fits the predictor on every candidate of every fold;
//! on a smooth field 300 of 3,000 rows come within 5 % of the exact process (the tests).
//! Drawn rows, not chosen ones (k-means centres, greedy selection): a uniform draw follows the
//! data's own density, costs nothing and is reproducible from the seed. Its predictive standard deviation is the exact
//! process's on the inducing rows alone, which is larger than the full set's would be: it errs
//! on the side of caution. A fit that would take more than `max_memory_mib` is refused before
//! it starts.
//!
//! Files: `likelihood` (the marginal likelihood and its gradient), `fit` (the spec and the
//! fit), `sparse` (the inducing-point weights), `fitted` (the fitted process and its stored
//! form).

mod fit;
mod fitted;
mod likelihood;
mod sparse;

pub use fit::{GpSpec, KernelSharing};
use fitted::*;
pub use fitted::{FittedGp, GpKernelModel, GpModel};
use likelihood::*;
pub use likelihood::{GpHyperParams, GpLikelihood};
use sparse::*;
