//! Helpers shared by the tests: the synthetic residual and held-out error measures.

mod residual;

pub use residual::{Data, RANGES};

use armcomp_core::FittedPredictor;

/// Per-output (held-out RMS error of `model`, standard deviation of the target) on `test`.
pub fn rms_vs_std(model: &dyn FittedPredictor, test: &Data) -> Vec<(f64, f64)> {
    let (d, k) = (model.n_inputs(), model.n_outputs());
    let n = test.inputs.len() / d;
    let mut out = vec![0.0; k];
    let mut scratch = Vec::new();
    let mut err = vec![0.0; k];
    let mut mean = vec![0.0; k];
    for i in 0..n {
        model.predict_into(&test.inputs[i * d..(i + 1) * d], &mut out, &mut scratch);
        for c in 0..k {
            let t = test.targets[i * k + c];
            err[c] += (out[c] - t).powi(2);
            mean[c] += t / n as f64;
        }
    }
    let mut var = vec![0.0; k];
    for i in 0..n {
        for c in 0..k {
            var[c] += (test.targets[i * k + c] - mean[c]).powi(2) / n as f64;
        }
    }
    (0..k).map(|c| ((err[c] / n as f64).sqrt(), var[c].sqrt())).collect()
}

/// Asserts the held-out RMS of every output is below `share` of the target's std.
pub fn assert_fits(name: &str, model: &dyn FittedPredictor, test: &Data, share: f64) {
    for (c, (rms, std)) in rms_vs_std(model, test).into_iter().enumerate() {
        assert!(
            rms < share * std,
            "{name}: output {c} held-out RMS {:.3} mm, target std {:.3} mm (limit {share} × std)",
            rms * 1e3,
            std * 1e3
        );
    }
}
