//! The Gaussian process of armcomp-learn exported as a run-time residual predictor, for the
//! loader's tests: the same predictor linked in is the reference its predictions and predictive
//! standard deviations are checked against.

armcomp_sdk::export_plugins! {
    predictor armcomp_learn::gp::GpSpec { name: "gp", doc: "Gaussian process regression (loader tests)" },
}
