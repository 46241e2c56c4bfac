//! The log marginal likelihood of the kernel hyper-parameters and its gradient.

use armcomp_core::{Error, Result, TrainingSet};
use nalgebra::DMatrix;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::data::{Samples, check_positive, invalid};

/// The error of a kernel matrix that cannot be factored, in the computation `what`.
pub(super) fn not_positive_definite(what: &str) -> Error {
    Error::Degenerate {
        what: what.into(),
        reason: "kernel matrix is not positive definite".into(),
    }
}

/// Kernel hyper-parameters in standardised units:
/// `k(x, x') = σ_f² exp(-½ Σ_d (x_d − x'_d)² / ℓ_d²) + σ_n² δ(x, x')`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GpHyperParams {
    /// ARD length-scale ℓ_d per input.
    pub length_scales: Vec<f64>,
    /// Signal standard deviation σ_f.
    pub signal_std: f64,
    /// Noise standard deviation σ_n.
    pub noise_std: f64,
}

impl GpHyperParams {
    /// The hyper-parameters at the optimiser's log-parameters
    /// `θ = [ln ℓ_1, …, ln ℓ_D, ln σ_f, ln σ_e]`, where `σ_n² = noise_floor + σ_e²` keeps the
    /// kernel matrix well conditioned on noise-free data.
    pub fn from_log_params(theta: &[f64], noise_floor: f64) -> Self {
        let d = theta.len() - 2;
        GpHyperParams {
            length_scales: theta[..d].iter().map(|t| t.exp()).collect(),
            signal_std: theta[d].exp(),
            noise_std: (noise_floor + (2.0 * theta[d + 1]).exp()).sqrt(),
        }
    }

    pub(super) fn check(&self, d: usize) -> Result<()> {
        if self.length_scales.len() != d {
            return Err(Error::Dimension {
                what: "gp length_scales".into(),
                expected: d,
                got: self.length_scales.len(),
            });
        }
        for (i, l) in self.length_scales.iter().enumerate() {
            check_positive(&format!("gp length_scales[{i}]"), *l)?;
        }
        check_positive("gp signal_std", self.signal_std)?;
        if !(self.noise_std.is_finite() && self.noise_std >= 0.0) {
            return Err(invalid(
                "gp noise_std",
                format!("expected a finite non-negative number, got {}", self.noise_std),
            ));
        }
        Ok(())
    }
}

/// The log marginal likelihood of standardised data under a kernel, with its gradient.
#[derive(Debug, Clone, Copy)]
pub struct GpLikelihood<'a> {
    pub(super) inputs: &'a [f64],
    pub(super) targets: &'a [f64],
    pub(super) n: usize,
    pub(super) d: usize,
    pub(super) k: usize,
    pub(super) noise_floor: f64,
}

impl<'a> GpLikelihood<'a> {
    /// Row-major `inputs` (`n × n_inputs`) and `targets` (`n × n_outputs`), in the units the
    /// kernel applies to; `noise_floor` as in [`GpHyperParams::from_log_params`].
    pub fn new(
        inputs: &'a [f64],
        n_inputs: usize,
        targets: &'a [f64],
        n_outputs: usize,
        noise_floor: f64,
    ) -> Result<Self> {
        let samples = Samples::check(
            &TrainingSet {
                inputs,
                targets,
                n_inputs,
                n_outputs,
                input_ranges: &[],
            },
            1,
        )?;
        Ok(GpLikelihood {
            inputs,
            targets,
            n: samples.n,
            d: n_inputs,
            k: n_outputs,
            noise_floor,
        })
    }

    /// `ln p(Y | X, θ) = Σ_c [-½ y_cᵀ K⁻¹ y_c] − k Σ ln L_ii − n k ln(2π) / 2` at the
    /// log-parameters `theta` (see [`GpHyperParams::from_log_params`]), and its gradient
    /// `∂/∂θ = ½ tr((A Aᵀ − k K⁻¹) ∂K/∂θ)` with `A = K⁻¹ Y` written into `grad`.
    pub fn value_and_gradient(&self, theta: &[f64], grad: &mut [f64]) -> Result<f64> {
        let (n, d, k) = (self.n, self.d, self.k);
        if theta.len() != d + 2 || grad.len() != d + 2 {
            return Err(Error::Dimension {
                what: "gp log-parameters".into(),
                expected: d + 2,
                got: theta.len().min(grad.len()),
            });
        }
        let hyper = GpHyperParams::from_log_params(theta, self.noise_floor);
        let scaled = scale_inputs(self.inputs, &hyper.length_scales);
        let kf = signal_matrix(&scaled, d, hyper.signal_std);
        let mut kmat = kf.clone();
        for i in 0..n {
            kmat[(i, i)] += hyper.noise_std * hyper.noise_std;
        }
        let chol = kmat.cholesky().ok_or_else(|| not_positive_definite("gp"))?;
        let y = DMatrix::from_row_slice(n, k, self.targets);
        let a = chol.solve(&y);
        let log_det: f64 = 2.0 * chol.l_dirty().diagonal().iter().map(|v| v.ln()).sum::<f64>();
        let value = -0.5 * y.component_mul(&a).sum()
            - 0.5 * k as f64 * log_det
            - 0.5 * (n * k) as f64 * (2.0 * std::f64::consts::PI).ln();
        // W = A Aᵀ − k K⁻¹, symmetric.
        let mut w = chol.inverse();
        w *= -(k as f64);
        w.gemm(1.0, &a, &a.transpose(), 1.0);
        grad.fill(0.0);
        for j in 0..n {
            for i in 0..n {
                let wk = w[(i, j)] * kf[(i, j)];
                grad[d] += wk;
                for (g, (zi, zj)) in grad[..d]
                    .iter_mut()
                    .zip(scaled[i * d..].iter().zip(&scaled[j * d..j * d + d]))
                {
                    *g += 0.5 * wk * (zi - zj) * (zi - zj);
                }
            }
        }
        let noise_excess = (2.0 * theta[d + 1]).exp();
        grad[d + 1] = w.trace() * noise_excess;
        Ok(value)
    }
}

/// Inputs divided by their length-scales, row-major.
pub(super) fn scale_inputs(inputs: &[f64], length_scales: &[f64]) -> Vec<f64> {
    let d = length_scales.len();
    let mut out = inputs.to_vec();
    for row in out.chunks_exact_mut(d) {
        row.iter_mut().zip(length_scales).for_each(|(v, l)| *v /= l);
    }
    out
}

/// The noise-free kernel matrix `σ_f² exp(-½ |z_i − z_j|²)` of length-scaled inputs `z`.
pub(super) fn signal_matrix(scaled: &[f64], d: usize, signal_std: f64) -> DMatrix<f64> {
    let n = scaled.len() / d;
    let sf2 = signal_std * signal_std;
    let mut m = DMatrix::zeros(n, n);
    for j in 0..n {
        m[(j, j)] = sf2;
        for i in j + 1..n {
            let v = sf2 * (-0.5 * sq_dist(&scaled[i * d..(i + 1) * d], &scaled[j * d..(j + 1) * d])).exp();
            m[(i, j)] = v;
            m[(j, i)] = v;
        }
    }
    m
}

pub(super) fn sq_dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// The columns `outputs` of the rows `rows` of the row-major `y` (`k` columns), row-major.
pub(super) fn columns(y: &[f64], k: usize, rows: &[usize], outputs: &[usize]) -> Vec<f64> {
    rows.iter()
        .flat_map(|&i| outputs.iter().map(move |&o| y[i * k + o]))
        .collect()
}
