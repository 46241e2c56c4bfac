//! The fitted process: its stored form (model files) and the predictor built from it.

use armcomp_core::{Error, FittedPredictor, Result};
use nalgebra::{DMatrix, DVectorViewMut};
use serde::{Deserialize, Serialize};

use crate::data::{Standardizer, invalid};
use crate::rbf::{dot, kernel_row};

use super::*;

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

/// What a fitted GP is made of, as stored in model files: what the predictive mean needs (the
/// training inputs and the weights α), linear in the rows. The Cholesky factor is not stored
/// (it would be n² numbers); the predictive standard deviation recomputes it, bit for bit, on
/// its first use.
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
/// vectorise; and the Cholesky factor of the kernel matrix, once the predictive standard
/// deviation has needed it.
#[derive(Debug, Clone)]
pub(super) struct KernelCache {
    /// `d × n`: run `j` holds the `j`-th length-scaled input of every training row.
    pub(super) columns: Vec<f64>,
    /// `m × n`: run `l` holds the weights of the kernel's `l`-th output.
    pub(super) alpha: Vec<f64>,
    /// The lower Cholesky factor, `None` inside when the stored hyper-parameters and jitter do
    /// not give a positive definite matrix. Factorising is O(n³) in time and O(n²) in memory
    /// (minutes and a gigabyte at 12,000 rows), which reading a model file, copying a
    /// predictor or predicting the mean must not pay: only the standard deviation does.
    chol: std::sync::OnceLock<Option<DMatrix<f64>>>,
}

impl KernelCache {
    /// From the row-major length-scaled inputs (`n × d`) and weights (`n × m`), with the
    /// factor when the caller has it (the fit).
    pub(super) fn new(scaled: &[f64], d: usize, alpha: &[f64], m: usize, chol: Option<DMatrix<f64>>) -> Self {
        KernelCache {
            columns: transpose(scaled, d),
            alpha: transpose(alpha, m),
            chol: chol.map(|c| Some(c).into()).unwrap_or_default(),
        }
    }

    /// The Cholesky factor of the kernel matrix of `kernel`, computed on first use from the
    /// length-scaled inputs (`d` of them per row); `None` when it is not positive definite.
    fn chol(&self, kernel: &GpKernelModel, d: usize) -> Option<&DMatrix<f64>> {
        self.chol
            .get_or_init(|| {
                let n = self.columns.len() / d;
                // Back to row-major, the layout the fit factorised, so the factor is the fit's
                // bit for bit.
                let scaled = transpose(&self.columns, n);
                factor(&scaled, d, &kernel.hyper, kernel.jitter)
            })
            .as_ref()
    }
}

/// Row-major `rows × width` into width runs of `rows` values.
pub(super) fn transpose(values: &[f64], width: usize) -> Vec<f64> {
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
    pub(super) model: GpModel,
    pub(super) caches: Vec<KernelCache>,
}

/// Lower Cholesky factor of `K(scaled) + (σ_n² + jitter) I`.
pub(super) fn factor(scaled: &[f64], d: usize, hyper: &GpHyperParams, jitter: f64) -> Option<DMatrix<f64>> {
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
            return Err(invalid(
                "gp_fitted",
                "standardisation and training inputs disagree in size".into(),
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
                        return Err(invalid(
                            "gp_fitted",
                            format!("output {o} is missing or predicted twice"),
                        ));
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
            if !(kernel.jitter.is_finite() && kernel.jitter >= 0.0) {
                return Err(invalid(
                    "gp_fitted",
                    format!("jitter must be finite and non-negative, got {}", kernel.jitter),
                ));
            }
            if let Some(i) = kernel.alpha.iter().position(|a| !a.is_finite()) {
                return Err(invalid("gp_fitted", format!("alpha[{i}] is not finite")));
            }
            let scaled = scale_inputs(&model.train_inputs, &kernel.hyper.length_scales);
            caches.push(KernelCache::new(&scaled, d, &kernel.alpha, kernel.outputs.len(), None));
        }
        if covered.contains(&false) {
            return Err(invalid("gp_fitted", "some outputs have no kernel".into()));
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
    pub(super) fn n_training(&self) -> usize {
        self.model.train_inputs.len() / self.n_inputs()
    }

    /// Standardises `input` and divides it by each kernel's length-scales into `scratch`
    /// (`kernels × d` values), growing it to `extra` more values.
    pub(super) fn prepare<'s>(&self, input: &[f64], scratch: &'s mut Vec<f64>, extra: usize) -> &'s mut [f64] {
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

    /// The kernels' hyper-parameters, a list in kernel order.
    fn searched(&self) -> Option<serde_json::Value> {
        let hypers: Vec<&GpHyperParams> = self.model.kernels.iter().map(|k| &k.hyper).collect();
        serde_json::to_value(hypers).ok()
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
            // A stored model whose matrix is not positive definite has no standard deviation.
            let Some(chol) = cache.chol(kernel, d) else {
                return false;
            };
            // v = L⁻¹ k*, var = σ_f² − vᵀv.
            let mut v = DVectorViewMut::from_slice(kstar, n);
            chol.solve_lower_triangular_mut(&mut v);
            let std = (sf2 - v.norm_squared()).max(0.0).sqrt();
            for &o in &kernel.outputs {
                out[o] = std;
            }
        }
        self.model.outputs.restore_std(out);
        true
    }
}
