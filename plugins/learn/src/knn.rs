//! `knn`: k-nearest-neighbour regression in standardised input space, a baseline.
//!
//! Brute force over the training rows: for the data sizes of arm calibration (hundreds to a few
//! thousand rows, a handful of inputs) one pass is a few microseconds, needs no index structure
//! and allocates nothing.

use armcomp_core::{Error, FitControl, FittedPredictor, PredictorSpec, Result, TrainingSet};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::data::{Samples, Standardizer, check_count, invalid};

/// How the neighbours' targets are averaged.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum KnnWeighting {
    /// Plain mean.
    #[default]
    Uniform,
    /// Weights 1/distance; an exact match returns its own target.
    InverseDistance,
}

/// k-nearest-neighbour regression (Euclidean distance on standardised inputs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct KnnSpec {
    /// Number of neighbours.
    pub k: usize,
    /// `uniform` or `inverse_distance`.
    pub weighting: KnnWeighting,
}

impl Default for KnnSpec {
    fn default() -> Self {
        KnnSpec {
            k: 5,
            weighting: KnnWeighting::Uniform,
        }
    }
}

/// What a fitted kNN model is made of, as stored in model files. Targets are kept in their own
/// units: averaging commutes with standardisation, and k = 1 then returns them exactly.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KnnModel {
    /// Number of neighbours.
    pub k: usize,
    /// Averaging of the neighbours.
    pub weighting: KnnWeighting,
    /// Input standardisation.
    pub inputs: Standardizer,
    /// Standardised training inputs, row-major `n × n_inputs`.
    pub train_inputs: Vec<f64>,
    /// Training targets, row-major `n × n_outputs`.
    pub targets: Vec<f64>,
    /// Outputs per row.
    pub n_outputs: usize,
}

/// A fitted kNN regressor (`knn_fitted`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "KnnModel", into = "KnnModel")]
pub struct FittedKnn(KnnModel);

impl TryFrom<KnnModel> for FittedKnn {
    type Error = Error;

    fn try_from(m: KnnModel) -> Result<Self> {
        let d = m.inputs.mean.len();
        let n = m.train_inputs.len().checked_div(d).unwrap_or(0);
        if d == 0
            || m.inputs.scale.len() != d
            || m.n_outputs == 0
            || m.train_inputs.len() != n * d
            || m.targets.len() != n * m.n_outputs
            || m.k == 0
            || m.k > n
        {
            return Err(invalid(
                "knn_fitted",
                format!(
                    "k = {}, {d} inputs and {} outputs do not match {} training values and {} targets",
                    m.k,
                    m.n_outputs,
                    m.train_inputs.len(),
                    m.targets.len()
                ),
            ));
        }
        Ok(FittedKnn(m))
    }
}

stored_model!(FittedKnn, KnnModel);

#[typetag::serde(name = "knn_fitted")]
impl FittedPredictor for FittedKnn {
    fn n_inputs(&self) -> usize {
        self.0.inputs.mean.len()
    }

    fn n_outputs(&self) -> usize {
        self.0.n_outputs
    }

    fn predict_into(&self, input: &[f64], out: &mut [f64], scratch: &mut Vec<f64>) {
        let m = &self.0;
        let (d, k, c) = (self.n_inputs(), m.k, m.n_outputs);
        assert_eq!(input.len(), d, "knn_fitted: input length");
        assert_eq!(out.len(), c, "knn_fitted: output length");
        if scratch.len() < d + 2 * k {
            scratch.resize(d + 2 * k, 0.0);
        }
        let (z, rest) = scratch.split_at_mut(d);
        let (dist, index) = rest[..2 * k].split_at_mut(k);
        m.inputs.apply(input, z);
        dist.fill(f64::INFINITY);
        // Sorted insertion; the strict comparison keeps the earlier row on ties (deterministic).
        for (i, row) in m.train_inputs.chunks_exact(d).enumerate() {
            let r2: f64 = row.iter().zip(z.iter()).map(|(a, b)| (a - b) * (a - b)).sum();
            if r2 < dist[k - 1] {
                let mut p = k - 1;
                while p > 0 && r2 < dist[p - 1] {
                    dist[p] = dist[p - 1];
                    index[p] = index[p - 1];
                    p -= 1;
                }
                dist[p] = r2;
                // Row indices are far below 2^53, so they survive the round trip through f64.
                index[p] = i as f64;
            }
        }
        out.fill(0.0);
        let exact = dist.iter().take_while(|r2| **r2 == 0.0).count();
        let (used, weight): (usize, fn(f64) -> f64) = match (m.weighting, exact) {
            (KnnWeighting::Uniform, _) => (k, |_| 1.0),
            (KnnWeighting::InverseDistance, 0) => (k, |r2| 1.0 / r2.sqrt()),
            (KnnWeighting::InverseDistance, e) => (e, |_| 1.0),
        };
        let mut total = 0.0;
        for (r2, idx) in dist[..used].iter().zip(&index[..used]) {
            let w = weight(*r2);
            let i = *idx as usize;
            total += w;
            out.iter_mut()
                .zip(&m.targets[i * c..(i + 1) * c])
                .for_each(|(o, t)| *o += w * t);
        }
        out.iter_mut().for_each(|o| *o /= total);
    }
}

#[typetag::serde(name = "knn")]
impl PredictorSpec for KnnSpec {
    fn fit_with(&self, data: &TrainingSet<'_>, control: &FitControl<'_>) -> Result<Box<dyn FittedPredictor>> {
        control.cancel.check()?;
        check_count("k", self.k, 1)?;
        let s = Samples::check(data, self.k)?;
        let inputs = Standardizer::fit_inputs(s.inputs, s.n_inputs, s.input_ranges);
        Ok(Box::new(FittedKnn::try_from(KnnModel {
            k: self.k,
            weighting: self.weighting,
            train_inputs: inputs.apply_rows(s.inputs),
            inputs,
            targets: s.targets.to_vec(),
            n_outputs: s.n_outputs,
        })?))
    }
}
