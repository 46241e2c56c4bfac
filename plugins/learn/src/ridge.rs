//! `ridge`: ridge regression on standardised features of the inputs (linear, optionally their
//! pairwise products and squares, and sines and cosines of the raw inputs), a baseline.

use armcomp_core::{Error, FitControl, FittedPredictor, PredictorSpec, Result, TrainingSet};
use nalgebra::DMatrix;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::data::{Samples, Standardizer, invalid};

/// Ridge regression: `min Σ |y − Fw|² / n + λ |w|²` on standardised features and targets.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct RidgeSpec {
    /// Penalty λ ≥ 0 per sample on the standardised weights (0 is plain least squares).
    pub lambda: f64,
    /// Polynomial degree of the features of the standardised inputs: 1 (linear) or 2 (adds
    /// every pairwise product and square).
    pub degree: u8,
    /// Adds `sin x` and `cos x` of every raw input (joint angles in rad).
    pub trig: bool,
}

impl Default for RidgeSpec {
    fn default() -> Self {
        RidgeSpec {
            lambda: 1e-6,
            degree: 1,
            trig: false,
        }
    }
}

/// Which features a ridge model computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct RidgeFeatures {
    /// 1 or 2.
    pub degree: u8,
    /// Sines and cosines of the raw inputs.
    pub trig: bool,
}

impl RidgeFeatures {
    fn count(self, d: usize) -> usize {
        d + if self.degree == 2 { d * (d + 1) / 2 } else { 0 } + if self.trig { 2 * d } else { 0 }
    }

    /// Features of one row from its raw inputs `x` and standardised inputs `z` (`inputs` made
    /// them; an input it ignores gives no trigonometric features either).
    fn compute(self, x: &[f64], inputs: &Standardizer, z: &[f64], out: &mut [f64]) {
        let d = x.len();
        out[..d].copy_from_slice(z);
        let mut f = d;
        if self.degree == 2 {
            for i in 0..d {
                for j in i..d {
                    out[f] = z[i] * z[j];
                    f += 1;
                }
            }
        }
        if self.trig {
            for (j, v) in x.iter().enumerate() {
                let (sin, cos) = if inputs.ignores(j) { (0.0, 0.0) } else { v.sin_cos() };
                out[f] = sin;
                out[f + 1] = cos;
                f += 2;
            }
        }
    }
}

/// What a fitted ridge model is made of, as stored in model files.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RidgeModel {
    /// Input standardisation.
    pub inputs: Standardizer,
    /// The features computed.
    pub features: RidgeFeatures,
    /// Feature standardisation.
    pub feature_scaling: Standardizer,
    /// Output standardisation.
    pub outputs: Standardizer,
    /// Weights, row-major `n_features × n_outputs` (standardised units; no intercept, as both
    /// sides are centred).
    pub weights: Vec<f64>,
}

/// A fitted ridge regression (`ridge_fitted`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "RidgeModel", into = "RidgeModel")]
pub struct FittedRidge(RidgeModel);

impl TryFrom<RidgeModel> for FittedRidge {
    type Error = Error;

    fn try_from(m: RidgeModel) -> Result<Self> {
        let d = m.inputs.mean.len();
        let nf = m.features.count(d);
        let k = m.outputs.mean.len();
        if !(1..=2).contains(&m.features.degree)
            || m.inputs.scale.len() != d
            || m.feature_scaling.mean.len() != nf
            || m.feature_scaling.scale.len() != nf
            || m.outputs.scale.len() != k
            || m.weights.len() != nf * k
        {
            return Err(invalid(
                "ridge_fitted",
                format!(
                    "{d} inputs, degree {} and {k} outputs do not match {} weights",
                    m.features.degree,
                    m.weights.len()
                ),
            ));
        }
        Ok(FittedRidge(m))
    }
}

stored_model!(FittedRidge, RidgeModel);

#[typetag::serde(name = "ridge_fitted")]
impl FittedPredictor for FittedRidge {
    fn n_inputs(&self) -> usize {
        self.0.inputs.mean.len()
    }

    fn n_outputs(&self) -> usize {
        self.0.outputs.mean.len()
    }

    fn predict_into(&self, input: &[f64], out: &mut [f64], scratch: &mut Vec<f64>) {
        let m = &self.0;
        let d = self.n_inputs();
        let k = self.n_outputs();
        assert_eq!(input.len(), d, "ridge_fitted: input length");
        assert_eq!(out.len(), k, "ridge_fitted: output length");
        let nf = m.features.count(d);
        if scratch.len() < d + 2 * nf {
            scratch.resize(d + 2 * nf, 0.0);
        }
        let (z, rest) = scratch.split_at_mut(d);
        let (raw, phi) = rest.split_at_mut(nf);
        m.inputs.apply(input, z);
        m.features.compute(input, &m.inputs, z, raw);
        m.feature_scaling.apply(raw, &mut phi[..nf]);
        out.fill(0.0);
        for (f, w) in phi[..nf].iter().zip(m.weights.chunks_exact(k)) {
            out.iter_mut().zip(w).for_each(|(o, w)| *o += f * w);
        }
        m.outputs.restore(out);
    }
}

#[typetag::serde(name = "ridge")]
impl PredictorSpec for RidgeSpec {
    fn fit_with(&self, data: &TrainingSet<'_>, control: &FitControl<'_>) -> Result<Box<dyn FittedPredictor>> {
        control.cancel.check()?;
        if !(self.lambda.is_finite() && self.lambda >= 0.0) {
            return Err(invalid(
                "lambda",
                format!("expected a finite non-negative number, got {}", self.lambda),
            ));
        }
        if !(1..=2).contains(&self.degree) {
            return Err(invalid("degree", format!("expected 1 or 2, got {}", self.degree)));
        }
        let s = Samples::check(data, 2)?;
        let (n, d, k) = (s.n, s.n_inputs, s.n_outputs);
        let features = RidgeFeatures {
            degree: self.degree,
            trig: self.trig,
        };
        let nf = features.count(d);
        let inputs = Standardizer::fit_inputs(s.inputs, d, s.input_ranges);
        let mut z = vec![0.0; d];
        let mut raw = vec![0.0; n * nf];
        for (i, row) in raw.chunks_exact_mut(nf).enumerate() {
            inputs.apply(s.input(i), &mut z);
            features.compute(s.input(i), &inputs, &z, row);
        }
        let feature_scaling = Standardizer::fit(&raw, nf);
        let outputs = Standardizer::fit(s.targets, k);
        let f = DMatrix::from_row_slice(n, nf, &feature_scaling.apply_rows(&raw));
        let y = DMatrix::from_row_slice(n, k, &outputs.apply_rows(s.targets));
        let mut gram = f.tr_mul(&f) / n as f64;
        for i in 0..nf {
            gram[(i, i)] += self.lambda;
        }
        let rhs = f.tr_mul(&y) / n as f64;
        let w = gram
            .cholesky()
            .map(|c| c.solve(&rhs))
            .ok_or_else(|| Error::Degenerate {
                what: "ridge".into(),
                reason: format!(
                    "the {nf} features are linearly dependent on these {n} samples; set lambda > 0 or lower the degree"
                ),
            })?;
        let weights = (0..nf)
            .flat_map(|i| (0..k).map(move |c| (i, c)))
            .map(|(i, c)| w[(i, c)])
            .collect();
        Ok(Box::new(FittedRidge::try_from(RidgeModel {
            inputs,
            features,
            feature_scaling,
            outputs,
            weights,
        })?))
    }
}
