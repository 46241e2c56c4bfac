//! armcomp-learn's tests (one test binary): the Gaussian process against closed forms and finite
//! differences, the networks and the sparrow search on synthetic residuals and test functions,
//! the baselines against exact answers, and the contract every predictor keeps (determinism,
//! serde round trips, clear errors).

mod baselines;
mod common;
mod contract;
mod gp;
mod nets;
mod sweep;
