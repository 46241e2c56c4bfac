//! The back-propagation network shared by the MLP and SSA-BP: one or two tanh hidden layers and
//! a linear output layer, its weights and biases in one flat vector (what the sparrow search
//! moves and what gradient training updates), and the fitted predictor built on it.

use armcomp_core::{Error, FittedPredictor, Result};
use rand::Rng;
use rand::rngs::StdRng;
use serde::{Deserialize, Serialize};

use crate::data::{Standardizer, invalid};

/// Layer widths `[inputs, hidden..., outputs]`. Parameters are stored layer by layer, each as its
/// weight matrix (row-major, `out × in`) followed by its biases.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Network {
    /// Widths of the input, hidden and output layers.
    pub sizes: Vec<usize>,
}

impl Network {
    /// A network for `n_inputs` → `hidden` → `n_outputs`; one or two hidden layers of width ≥ 1.
    pub fn new(n_inputs: usize, hidden: &[usize], n_outputs: usize) -> Result<Self> {
        if hidden.is_empty() || hidden.len() > 2 || hidden.contains(&0) {
            return Err(invalid(
                "hidden",
                format!("expected one or two hidden layer widths of at least 1, got {hidden:?}"),
            ));
        }
        let mut sizes = vec![n_inputs];
        sizes.extend_from_slice(hidden);
        sizes.push(n_outputs);
        Ok(Network { sizes })
    }

    /// Number of weights and biases.
    pub fn n_params(&self) -> usize {
        self.sizes.windows(2).map(|w| (w[0] + 1) * w[1]).sum()
    }

    /// Length of the activation buffer (every layer after the input).
    pub fn n_activations(&self) -> usize {
        self.sizes[1..].iter().sum()
    }

    /// Glorot-uniform weights and zero biases.
    pub fn init(&self, rng: &mut StdRng) -> Vec<f64> {
        let mut params = Vec::with_capacity(self.n_params());
        for w in self.sizes.windows(2) {
            let limit = (6.0 / (w[0] + w[1]) as f64).sqrt();
            params.extend((0..w[0] * w[1]).map(|_| rng.random_range(-limit..limit)));
            params.extend(std::iter::repeat_n(0.0, w[1]));
        }
        params
    }

    /// Evaluates the network at `x` into `acts` (length [`n_activations`](Self::n_activations));
    /// the outputs are its last `n_outputs` values.
    pub fn forward(&self, params: &[f64], x: &[f64], acts: &mut [f64]) {
        let layers = self.sizes.len() - 1;
        let (mut p, mut a) = (0, 0);
        for l in 0..layers {
            let (n_in, n_out) = (self.sizes[l], self.sizes[l + 1]);
            let (done, rest) = acts.split_at_mut(a);
            let input = if l == 0 { x } else { &done[a - n_in..] };
            let out = &mut rest[..n_out];
            let (weights, biases) = params[p..p + (n_in + 1) * n_out].split_at(n_in * n_out);
            for ((o, row), b) in out.iter_mut().zip(weights.chunks_exact(n_in)).zip(biases) {
                let s = b + row.iter().zip(input).map(|(w, v)| w * v).sum::<f64>();
                *o = if l + 1 < layers { s.tanh() } else { s };
            }
            p += (n_in + 1) * n_out;
            a += n_out;
        }
    }

    /// The derivative of the outputs with respect to the inputs at the `x` whose activations
    /// [`forward`](Self::forward) left in `acts`, into `jacobian` (row-major, outputs × inputs),
    /// by forward-mode differentiation; `tangents` is scratch of `n_activations × n_inputs`.
    pub fn input_jacobian(&self, params: &[f64], acts: &[f64], tangents: &mut [f64], jacobian: &mut [f64]) {
        let d = self.sizes[0];
        let layers = self.sizes.len() - 1;
        let (mut p, mut a) = (0, 0);
        for l in 0..layers {
            let (n_in, n_out) = (self.sizes[l], self.sizes[l + 1]);
            let weights = &params[p..p + n_in * n_out];
            let (done, rest) = tangents.split_at_mut(a * d);
            let out = &mut rest[..n_out * d];
            for (o_row, w_row) in out.chunks_exact_mut(d).zip(weights.chunks_exact(n_in)) {
                if l == 0 {
                    // The input's own tangent is the identity.
                    o_row.copy_from_slice(w_row);
                } else {
                    o_row.fill(0.0);
                    for (w, t_row) in w_row.iter().zip(done[(a - n_in) * d..].chunks_exact(d)) {
                        for (o, t) in o_row.iter_mut().zip(t_row) {
                            *o += w * t;
                        }
                    }
                }
            }
            if l + 1 < layers {
                // tanh' = 1 - tanh².
                for (o_row, h) in out.chunks_exact_mut(d).zip(&acts[a..a + n_out]) {
                    o_row.iter_mut().for_each(|o| *o *= 1.0 - h * h);
                }
            }
            p += (n_in + 1) * n_out;
            a += n_out;
        }
        let k = self.sizes[layers];
        jacobian.copy_from_slice(&tangents[(a - k) * d..a * d]);
    }

    /// Adds to `grad` the gradient, with respect to the parameters, of `Σ dout · output` at `x`
    /// (back-propagation); `acts` must hold [`forward`](Self::forward)'s result for `x`, and
    /// `deltas` is scratch of the same length.
    pub fn backward(
        &self,
        params: &[f64],
        x: &[f64],
        acts: &[f64],
        dout: &[f64],
        grad: &mut [f64],
        deltas: &mut [f64],
    ) {
        let layers = self.sizes.len() - 1;
        let mut p = self.n_params();
        let mut a = self.n_activations();
        let k = self.sizes[layers];
        deltas[a - k..a].copy_from_slice(dout);
        for l in (0..layers).rev() {
            let (n_in, n_out) = (self.sizes[l], self.sizes[l + 1]);
            p -= (n_in + 1) * n_out;
            a -= n_out;
            let input = if l == 0 { x } else { &acts[a - n_in..a] };
            let (g_w, g_b) = grad[p..p + (n_in + 1) * n_out].split_at_mut(n_in * n_out);
            let (before, current) = deltas.split_at_mut(a);
            let delta = &current[..n_out];
            for ((g_row, gb), d) in g_w.chunks_exact_mut(n_in).zip(g_b.iter_mut()).zip(delta) {
                *gb += d;
                for (g, v) in g_row.iter_mut().zip(input) {
                    *g += d * v;
                }
            }
            if l > 0 {
                let prev = &mut before[a - n_in..];
                prev.fill(0.0);
                let weights = &params[p..p + n_in * n_out];
                for (row, d) in weights.chunks_exact(n_in).zip(delta) {
                    for (pd, w) in prev.iter_mut().zip(row) {
                        *pd += w * d;
                    }
                }
                // tanh' = 1 - tanh².
                for (pd, h) in prev.iter_mut().zip(input) {
                    *pd *= 1.0 - h * h;
                }
            }
        }
    }
}

/// What a trained network is made of, as stored in model files.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MlpModel {
    /// The architecture.
    pub network: Network,
    /// Weights and biases, layer by layer (see [`Network`]).
    pub params: Vec<f64>,
    /// Input standardisation.
    pub inputs: Standardizer,
    /// Output standardisation (targets in their own units, m for positions).
    pub outputs: Standardizer,
}

/// A trained network with the standardisation of its inputs and outputs (`mlp_fitted`, the
/// fitted form of both `mlp` and `ssa_bp`). Its parts are checked to agree when it is built or
/// read, so prediction cannot index out of bounds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "MlpModel", into = "MlpModel")]
pub struct FittedMlp(MlpModel);

impl TryFrom<MlpModel> for FittedMlp {
    type Error = Error;

    fn try_from(m: MlpModel) -> Result<Self> {
        let s = &m.network.sizes;
        if s.len() < 3
            || s.contains(&0)
            || m.params.len() != m.network.n_params()
            || m.inputs.mean.len() != s[0]
            || m.inputs.scale.len() != s[0]
            || m.outputs.mean.len() != s[s.len() - 1]
            || m.outputs.scale.len() != s[s.len() - 1]
        {
            return Err(invalid(
                "mlp_fitted",
                format!(
                    "layer sizes {s:?} do not match {} parameters and {}/{} standardised columns",
                    m.params.len(),
                    m.inputs.mean.len(),
                    m.outputs.mean.len()
                ),
            ));
        }
        Ok(FittedMlp(m))
    }
}

stored_model!(FittedMlp, MlpModel);

#[typetag::serde(name = "mlp_fitted")]
impl FittedPredictor for FittedMlp {
    fn n_inputs(&self) -> usize {
        self.0.network.sizes[0]
    }

    fn n_outputs(&self) -> usize {
        self.0.network.sizes[self.0.network.sizes.len() - 1]
    }

    fn predict_into(&self, input: &[f64], out: &mut [f64], scratch: &mut Vec<f64>) {
        let m = &self.0;
        let d = self.n_inputs();
        let k = self.n_outputs();
        assert_eq!(input.len(), d, "mlp_fitted: input length");
        assert_eq!(out.len(), k, "mlp_fitted: output length");
        let need = d + m.network.n_activations();
        if scratch.len() < need {
            scratch.resize(need, 0.0);
        }
        let (x, acts) = scratch.split_at_mut(d);
        m.inputs.apply(input, x);
        let acts = &mut acts[..need - d];
        m.network.forward(&m.params, x, acts);
        out.copy_from_slice(&acts[acts.len() - k..]);
        m.outputs.restore(out);
    }

    fn predict_jacobian_into(
        &self,
        input: &[f64],
        out: &mut [f64],
        jacobian: &mut [f64],
        scratch: &mut Vec<f64>,
    ) -> bool {
        let m = &self.0;
        let d = self.n_inputs();
        let k = self.n_outputs();
        assert_eq!(input.len(), d, "mlp_fitted: input length");
        assert_eq!(out.len(), k, "mlp_fitted: output length");
        assert_eq!(jacobian.len(), k * d, "mlp_fitted: jacobian length");
        let n_acts = m.network.n_activations();
        let need = d + n_acts * (1 + d);
        if scratch.len() < need {
            scratch.resize(need, 0.0);
        }
        let (x, rest) = scratch.split_at_mut(d);
        let (acts, tangents) = rest.split_at_mut(n_acts);
        m.inputs.apply(input, x);
        m.network.forward(&m.params, x, acts);
        out.copy_from_slice(&acts[n_acts - k..]);
        m.outputs.restore(out);
        m.network
            .input_jacobian(&m.params, acts, &mut tangents[..n_acts * d], jacobian);
        // Back to raw units: outputs scale up, inputs were divided by their scale.
        for (row, so) in jacobian.chunks_exact_mut(d).zip(&m.outputs.scale) {
            for (j, g) in row.iter_mut().enumerate() {
                *g *= so * m.inputs.gain(j);
            }
        }
        true
    }
}
