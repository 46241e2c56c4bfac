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

use armcomp_core::{Error, FittedPredictor, PredictorSpec, Result, TrainingSet};
use nalgebra::{DMatrix, DVectorViewMut};
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::data::{Samples, Standardizer, check_count, check_positive, progress};
use crate::lbfgs;
use crate::rbf::{dot, kernel_row};

/// Whether the outputs share one kernel.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum KernelSharing {
    /// One set of hyper-parameters for all outputs (one factorisation).
    #[default]
    Shared,
    /// Independent hyper-parameters per output.
    PerOutput,
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

    fn check(&self, d: usize) -> Result<()> {
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
            return Err(Error::Input(format!(
                "gp noise_std: expected a finite non-negative number, got {}",
                self.noise_std
            )));
        }
        Ok(())
    }
}

/// Gaussian process regression (ARD RBF kernel + noise).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct GpSpec {
    /// `shared` (one kernel for all outputs) or `per_output`.
    pub kernels: KernelSharing,
    /// Optimiser starts besides the default one (ℓ = 1, σ_f = 1, σ_n = 0.1), drawn with the seed.
    pub restarts: usize,
    /// L-BFGS iterations per start.
    pub max_iterations: usize,
    /// Rows used to optimise the hyper-parameters (a seeded random subset when there are more).
    pub max_optimization_samples: usize,
    /// Smallest noise variance the optimiser may reach (standardised units).
    pub noise_floor: f64,
    /// Fixed hyper-parameters (standardised units) instead of optimising them.
    pub fixed: Option<GpHyperParams>,
    /// Seed of the restarts and the optimisation subset.
    pub seed: u64,
}

impl Default for GpSpec {
    fn default() -> Self {
        GpSpec {
            kernels: KernelSharing::Shared,
            restarts: 1,
            max_iterations: 50,
            max_optimization_samples: 250,
            noise_floor: 1e-6,
            fixed: None,
            seed: 0,
        }
    }
}

/// The log marginal likelihood of standardised data under a kernel, with its gradient.
#[derive(Debug, Clone, Copy)]
pub struct GpLikelihood<'a> {
    inputs: &'a [f64],
    targets: &'a [f64],
    n: usize,
    d: usize,
    k: usize,
    noise_floor: f64,
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
        let chol = kmat
            .cholesky()
            .ok_or_else(|| Error::Input("gp: kernel matrix is not positive definite".into()))?;
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
fn scale_inputs(inputs: &[f64], length_scales: &[f64]) -> Vec<f64> {
    let d = length_scales.len();
    let mut out = inputs.to_vec();
    for row in out.chunks_exact_mut(d) {
        row.iter_mut().zip(length_scales).for_each(|(v, l)| *v /= l);
    }
    out
}

/// The noise-free kernel matrix `σ_f² exp(-½ |z_i − z_j|²)` of length-scaled inputs `z`.
fn signal_matrix(scaled: &[f64], d: usize, signal_std: f64) -> DMatrix<f64> {
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

fn sq_dist(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y) * (x - y)).sum()
}

/// The columns `outputs` of the rows `rows` of the row-major `y` (`k` columns), row-major.
fn columns(y: &[f64], k: usize, rows: &[usize], outputs: &[usize]) -> Vec<f64> {
    rows.iter()
        .flat_map(|&i| outputs.iter().map(move |&o| y[i * k + o]))
        .collect()
}

/// One kernel of a fitted GP and the outputs it predicts, as stored in model files.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GpKernelModel {
    /// Output indices this kernel predicts.
    pub outputs: Vec<usize>,
    /// Its hyper-parameters (standardised units).
    pub hyper: GpHyperParams,
    /// Diagonal jitter added to the noise variance to make the factorisation succeed.
    pub jitter: f64,
    /// `K⁻¹ y` per training row, row-major `n × outputs.len()`.
    pub alpha: Vec<f64>,
}

/// What a fitted GP is made of, as stored in model files. The Cholesky factor is not stored (it
/// would be n² numbers); it is recomputed, bit for bit, when the model is read.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GpModel {
    /// Input standardisation.
    pub inputs: Standardizer,
    /// Output standardisation (targets in their own units, m for positions).
    pub outputs: Standardizer,
    /// Standardised training inputs, row-major `n × n_inputs`.
    pub train_inputs: Vec<f64>,
    /// The kernels, covering every output once.
    pub kernels: Vec<GpKernelModel>,
}

/// Per-kernel data derived from the model, laid out for prediction: the length-scaled training
/// inputs and the weights α stored column by column (one contiguous run of n values per input
/// dimension and per output), so that the per-query loops run along the training rows and
/// vectorise; and the Cholesky factor of the kernel matrix.
#[derive(Debug, Clone)]
struct KernelCache {
    /// `d × n`: run `j` holds the `j`-th length-scaled input of every training row.
    columns: Vec<f64>,
    /// `m × n`: run `l` holds the weights of the kernel's `l`-th output.
    alpha: Vec<f64>,
    chol: DMatrix<f64>,
}

impl KernelCache {
    /// From the row-major length-scaled inputs (`n × d`) and weights (`n × m`).
    fn new(scaled: &[f64], d: usize, alpha: &[f64], m: usize, chol: DMatrix<f64>) -> Self {
        KernelCache {
            columns: transpose(scaled, d),
            alpha: transpose(alpha, m),
            chol,
        }
    }
}

/// Row-major `rows × width` into width runs of `rows` values.
fn transpose(values: &[f64], width: usize) -> Vec<f64> {
    let rows = values.len() / width;
    let mut out = vec![0.0; values.len()];
    for (i, row) in values.chunks_exact(width).enumerate() {
        for (j, v) in row.iter().enumerate() {
            out[j * rows + i] = *v;
        }
    }
    out
}

/// A fitted Gaussian process (`gp_fitted`). The predictive standard deviation is that of the
/// latent function (the mean's uncertainty), without the measurement noise.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(try_from = "GpModel", into = "GpModel")]
pub struct FittedGp {
    model: GpModel,
    caches: Vec<KernelCache>,
}

/// Lower Cholesky factor of `K(scaled) + (σ_n² + jitter) I`.
fn factor(scaled: &[f64], d: usize, hyper: &GpHyperParams, jitter: f64) -> Option<DMatrix<f64>> {
    let mut k = signal_matrix(scaled, d, hyper.signal_std);
    let diag = hyper.noise_std * hyper.noise_std + jitter;
    for i in 0..k.nrows() {
        k[(i, i)] += diag;
    }
    k.cholesky().map(|c| c.unpack())
}

impl TryFrom<GpModel> for FittedGp {
    type Error = Error;

    fn try_from(model: GpModel) -> Result<Self> {
        let d = model.inputs.mean.len();
        let k = model.outputs.mean.len();
        if d == 0
            || model.inputs.scale.len() != d
            || model.outputs.scale.len() != k
            || !model.train_inputs.len().is_multiple_of(d)
        {
            return Err(Error::Input(
                "gp_fitted: standardisation and training inputs disagree in size".into(),
            ));
        }
        let n = model.train_inputs.len() / d;
        let mut covered = vec![false; k];
        let mut caches = Vec::with_capacity(model.kernels.len());
        for kernel in &model.kernels {
            kernel.hyper.check(d)?;
            for &o in &kernel.outputs {
                match covered.get_mut(o) {
                    Some(c) if !*c => *c = true,
                    _ => {
                        return Err(Error::Input(format!(
                            "gp_fitted: output {o} is missing or predicted twice"
                        )));
                    }
                }
            }
            if kernel.alpha.len() != n * kernel.outputs.len() {
                return Err(Error::Dimension {
                    what: "gp_fitted alpha".into(),
                    expected: n * kernel.outputs.len(),
                    got: kernel.alpha.len(),
                });
            }
            let scaled = scale_inputs(&model.train_inputs, &kernel.hyper.length_scales);
            let chol = factor(&scaled, d, &kernel.hyper, kernel.jitter)
                .ok_or_else(|| Error::Input("gp_fitted: kernel matrix is not positive definite".into()))?;
            caches.push(KernelCache::new(&scaled, d, &kernel.alpha, kernel.outputs.len(), chol));
        }
        if covered.contains(&false) {
            return Err(Error::Input("gp_fitted: some outputs have no kernel".into()));
        }
        Ok(FittedGp { model, caches })
    }
}

impl From<FittedGp> for GpModel {
    fn from(f: FittedGp) -> Self {
        f.model
    }
}

impl FittedGp {
    /// The stored model.
    pub fn model(&self) -> &GpModel {
        &self.model
    }

    /// Number of training rows.
    fn n_training(&self) -> usize {
        self.model.train_inputs.len() / self.n_inputs()
    }

    /// Standardises `input` and divides it by each kernel's length-scales into `scratch`
    /// (`kernels × d` values), growing it to `extra` more values.
    fn prepare<'s>(&self, input: &[f64], scratch: &'s mut Vec<f64>, extra: usize) -> &'s mut [f64] {
        let d = self.n_inputs();
        let need = d * (self.model.kernels.len() + 1) + extra;
        if scratch.len() < need {
            scratch.resize(need, 0.0);
        }
        let (z, rest) = scratch.split_at_mut(d);
        self.model.inputs.apply(input, z);
        for (kernel, zk) in self.model.kernels.iter().zip(rest.chunks_exact_mut(d)) {
            for ((o, v), l) in zk.iter_mut().zip(z.iter()).zip(&kernel.hyper.length_scales) {
                *o = v / l;
            }
        }
        &mut scratch[d..need]
    }
}

#[typetag::serde(name = "gp_fitted")]
impl FittedPredictor for FittedGp {
    fn n_inputs(&self) -> usize {
        self.model.inputs.mean.len()
    }

    fn n_outputs(&self) -> usize {
        self.model.outputs.mean.len()
    }

    fn predict_into(&self, input: &[f64], out: &mut [f64], scratch: &mut Vec<f64>) {
        let d = self.n_inputs();
        assert_eq!(input.len(), d, "gp_fitted: input length");
        assert_eq!(out.len(), self.n_outputs(), "gp_fitted: output length");
        let n = self.n_training();
        let buf = self.prepare(input, scratch, n);
        let (u, w) = buf.split_at_mut(d * self.model.kernels.len());
        for ((kernel, cache), uk) in self.model.kernels.iter().zip(&self.caches).zip(u.chunks_exact(d)) {
            kernel_row(&cache.columns, uk, kernel.hyper.signal_std * kernel.hyper.signal_std, w);
            for (&o, alpha) in kernel.outputs.iter().zip(cache.alpha.chunks_exact(n)) {
                out[o] = dot(w, alpha);
            }
        }
        self.model.outputs.restore(out);
    }

    fn predict_jacobian_into(
        &self,
        input: &[f64],
        out: &mut [f64],
        jacobian: &mut [f64],
        scratch: &mut Vec<f64>,
    ) -> bool {
        let d = self.n_inputs();
        let k = self.n_outputs();
        assert_eq!(input.len(), d, "gp_fitted: input length");
        assert_eq!(out.len(), k, "gp_fitted: output length");
        assert_eq!(jacobian.len(), k * d, "gp_fitted: jacobian length");
        let n = self.n_training();
        let buf = self.prepare(input, scratch, (1 + k) * n);
        let (u, rest) = buf.split_at_mut(d * self.model.kernels.len());
        let (w, weighted) = rest.split_at_mut(n);
        for ((kernel, cache), uk) in self.model.kernels.iter().zip(&self.caches).zip(u.chunks_exact(d)) {
            kernel_row(&cache.columns, uk, kernel.hyper.signal_std * kernel.hyper.signal_std, w);
            // With u = z/ℓ and rows x_i (length-scaled): ∂k_i/∂u_j = k_i (x_ij − u_j), so
            // ∂mean/∂u_j = Σ_i x_ij α_i k_i − u_j · mean.
            let m = kernel.outputs.len();
            for ((&o, alpha), run) in kernel
                .outputs
                .iter()
                .zip(cache.alpha.chunks_exact(n))
                .zip(weighted.chunks_exact_mut(n))
            {
                out[o] = dot(w, alpha);
                for ((v, wi), a) in run.iter_mut().zip(w.iter()).zip(alpha) {
                    *v = wi * a;
                }
            }
            // Each input's column once, against every output's weights while it is in cache.
            for (j, column) in cache.columns.chunks_exact(n).enumerate() {
                // Back to the raw units of the input: ∂u_j/∂x_j = 1 / (s_j ℓ_j).
                let per_input = self.model.inputs.gain(j) / kernel.hyper.length_scales[j];
                for (&o, run) in kernel.outputs.iter().zip(weighted[..m * n].chunks_exact(n)) {
                    jacobian[o * d + j] = (dot(column, run) - uk[j] * out[o]) * self.model.outputs.scale[o] * per_input;
                }
            }
        }
        self.model.outputs.restore(out);
        true
    }

    fn predict_std_into(&self, input: &[f64], out: &mut [f64], scratch: &mut Vec<f64>) -> bool {
        let d = self.n_inputs();
        assert_eq!(input.len(), d, "gp_fitted: input length");
        assert_eq!(out.len(), self.n_outputs(), "gp_fitted: output length");
        let n = self.n_training();
        let buf = self.prepare(input, scratch, n);
        let (u, kstar) = buf.split_at_mut(d * self.model.kernels.len());
        for ((kernel, cache), uk) in self.model.kernels.iter().zip(&self.caches).zip(u.chunks_exact(d)) {
            let sf2 = kernel.hyper.signal_std * kernel.hyper.signal_std;
            kernel_row(&cache.columns, uk, sf2, kstar);
            // v = L⁻¹ k*, var = σ_f² − vᵀv.
            let mut v = DVectorViewMut::from_slice(kstar, n);
            cache.chol.solve_lower_triangular_mut(&mut v);
            let std = (sf2 - v.norm_squared()).max(0.0).sqrt();
            for &o in &kernel.outputs {
                out[o] = std;
            }
        }
        self.model.outputs.restore_std(out);
        true
    }
}

impl GpSpec {
    fn check(&self) -> Result<()> {
        check_count("max_optimization_samples", self.max_optimization_samples, 2)?;
        if !(self.noise_floor.is_finite() && self.noise_floor >= 0.0) {
            return Err(Error::Input(format!(
                "noise_floor: expected a finite non-negative variance, got {}",
                self.noise_floor
            )));
        }
        Ok(())
    }

    /// The hyper-parameters maximising the log marginal likelihood of `y` (columns `outputs`).
    fn optimise(&self, x: &[f64], y: &[f64], d: usize, rng: &mut StdRng) -> Result<GpHyperParams> {
        let k = y.len() * d / x.len();
        let lik = GpLikelihood::new(x, d, y, k, self.noise_floor)?;
        let mut starts = vec![{
            let mut t = vec![0.0; d + 2];
            t[d + 1] = 0.1f64.ln();
            t
        }];
        for _ in 0..self.restarts {
            let mut t: Vec<f64> = (0..d).map(|_| rng.random_range(0.3f64.ln()..10f64.ln())).collect();
            t.push(rng.random_range(0.3f64.ln()..3f64.ln()));
            t.push(rng.random_range(0.01f64.ln()..0.5f64.ln()));
            starts.push(t);
        }
        let bar = progress((starts.len() * self.max_iterations) as u64, "gp");
        let mut best: Option<(Vec<f64>, f64)> = None;
        for start in &starts {
            armcomp_core::interrupt::check()?;
            let (theta, value) = lbfgs::minimize(
                start,
                self.max_iterations,
                |t, g| match lik.value_and_gradient(t, g) {
                    Ok(v) => {
                        // The optimiser minimises -ln p.
                        g.iter_mut().for_each(|g| *g = -*g);
                        -v
                    }
                    Err(_) => f64::INFINITY,
                },
                || bar.inc(1),
            );
            if value.is_finite() && best.as_ref().is_none_or(|(_, b)| value < *b) {
                best = Some((theta, value));
            }
        }
        bar.finish_and_clear();
        let (theta, _) = best.ok_or_else(|| {
            Error::Input("gp: the marginal likelihood could not be evaluated at any start (degenerate inputs?)".into())
        })?;
        Ok(GpHyperParams::from_log_params(&theta, self.noise_floor))
    }
}

#[typetag::serde(name = "gp")]
impl PredictorSpec for GpSpec {
    fn fit(&self, data: &TrainingSet<'_>) -> Result<Box<dyn FittedPredictor>> {
        self.check()?;
        let s = Samples::check(data, 2)?;
        let (d, k) = (s.n_inputs, s.n_outputs);
        let inputs = Standardizer::fit_inputs(s.inputs, d, s.input_ranges);
        let outputs = Standardizer::fit(s.targets, k);
        let x = inputs.apply_rows(s.inputs);
        let y = outputs.apply_rows(s.targets);
        let mut rng = StdRng::seed_from_u64(self.seed);
        let mut rows: Vec<usize> = (0..s.n).collect();
        if s.n > self.max_optimization_samples {
            rows.shuffle(&mut rng);
            rows.truncate(self.max_optimization_samples);
            rows.sort_unstable();
        }
        let groups: Vec<Vec<usize>> = match self.kernels {
            KernelSharing::Shared => vec![(0..k).collect()],
            KernelSharing::PerOutput => (0..k).map(|o| vec![o]).collect(),
        };
        let sub_x: Vec<f64> = rows
            .iter()
            .flat_map(|&i| x[i * d..(i + 1) * d].iter().copied())
            .collect();
        let mut kernels = Vec::with_capacity(groups.len());
        let mut caches = Vec::with_capacity(groups.len());
        for group in groups {
            let hyper = match &self.fixed {
                Some(h) => {
                    h.check(d)?;
                    h.clone()
                }
                None => self.optimise(&sub_x, &columns(&y, k, &rows, &group), d, &mut rng)?,
            };
            let scaled = scale_inputs(&x, &hyper.length_scales);
            // Jitter only when the factorisation fails (near-duplicate rows with tiny noise).
            let sf2 = hyper.signal_std * hyper.signal_std;
            let (jitter, chol) = std::iter::once(0.0)
                .chain((0..8).map(|e| sf2 * 1e-10 * 10f64.powi(e)))
                .find_map(|j| factor(&scaled, d, &hyper, j).map(|c| (j, c)))
                .ok_or_else(|| Error::Input("gp: kernel matrix is not positive definite even with jitter".into()))?;
            let all: Vec<usize> = (0..s.n).collect();
            let targets = DMatrix::from_row_slice(s.n, group.len(), &columns(&y, k, &all, &group));
            let mut a = targets;
            chol.solve_lower_triangular_mut(&mut a);
            chol.tr_solve_lower_triangular_mut(&mut a);
            let alpha: Vec<f64> = (0..s.n)
                .flat_map(|i| (0..group.len()).map(move |c| (i, c)))
                .map(|(i, c)| a[(i, c)])
                .collect();
            caches.push(KernelCache::new(&scaled, d, &alpha, group.len(), chol));
            kernels.push(GpKernelModel {
                outputs: group,
                hyper,
                jitter,
                alpha,
            });
        }
        Ok(Box::new(FittedGp {
            model: GpModel {
                inputs,
                outputs,
                train_inputs: x,
                kernels,
            },
            caches,
        }))
    }
}
