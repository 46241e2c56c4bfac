//! Gradient training of a [`Network`]: Adam on seeded mini-batches, or Levenberg–Marquardt for
//! small networks (core's shared loop, [`armcomp_core::support::least_squares`]), both with early
//! stopping on a held-out share of the rows.

use std::ops::ControlFlow;

use armcomp_core::support::least_squares::{self, Damping, LeastSquares, LmIteration, LmParams};
use armcomp_core::{Error, FitControl, Result};
use nalgebra::{DMatrix, DVector};
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::data::{Samples, Standardizer, Steps, check_count, check_fraction, check_positive, split_indices};
use crate::network::{FittedMlp, MlpModel, Network};

/// How the weights are refined by gradient.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum GradientMethod {
    /// Adam on shuffled mini-batches.
    #[default]
    Adam,
    /// Levenberg–Marquardt on all training rows (Jacobian by back-propagation); for networks of
    /// at most 2000 weights.
    LevenbergMarquardt,
}

/// Gradient training settings. Inputs and targets are standardised before training, so the
/// learning rate and damping are unit-free.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct TrainingParams {
    /// `adam` or `levenberg_marquardt`.
    pub method: GradientMethod,
    /// Adam: passes over the training rows; Levenberg–Marquardt: iterations.
    pub max_epochs: usize,
    /// Adam step size.
    pub learning_rate: f64,
    /// Adam mini-batch size (rows).
    pub batch_size: usize,
    /// Share of the rows held out for early stopping (0 monitors the training error instead).
    pub validation_fraction: f64,
    /// Epochs (iterations) without improvement of the monitored error before stopping; the best
    /// weights seen are kept.
    pub patience: usize,
    /// Levenberg–Marquardt starting damping λ in `(JᵀJ + λI) δ = -Jᵀr`.
    pub initial_damping: f64,
}

impl Default for TrainingParams {
    fn default() -> Self {
        TrainingParams {
            method: GradientMethod::Adam,
            max_epochs: 1000,
            learning_rate: 0.005,
            batch_size: 32,
            validation_fraction: 0.15,
            patience: 100,
            initial_damping: 1e-2,
        }
    }
}

/// Networks larger than this are too costly for Levenberg–Marquardt's `JᵀJ` (P × P).
const LM_MAX_PARAMS: usize = 2000;

impl TrainingParams {
    pub(crate) fn check(&self, n_params: usize) -> Result<()> {
        check_count("training.max_epochs", self.max_epochs, 1)?;
        check_count("training.batch_size", self.batch_size, 1)?;
        check_count("training.patience", self.patience, 1)?;
        check_positive("training.learning_rate", self.learning_rate)?;
        check_positive("training.initial_damping", self.initial_damping)?;
        check_fraction("training.validation_fraction", self.validation_fraction, 0.5)?;
        if self.method == GradientMethod::LevenbergMarquardt && n_params > LM_MAX_PARAMS {
            return Err(Error::InvalidArgument {
                what: "training.method".into(),
                reason: format!(
                    "levenberg_marquardt is for networks of at most {LM_MAX_PARAMS} weights, this one has {n_params}; use adam or smaller hidden layers"
                ),
            });
        }
        Ok(())
    }
}

/// A training set standardised for a network, with its held-out split.
pub(crate) struct NetData {
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    pub d: usize,
    pub k: usize,
    pub train: Vec<usize>,
    pub held_out: Vec<usize>,
    pub inputs: Standardizer,
    pub outputs: Standardizer,
}

impl NetData {
    pub fn new(samples: &Samples<'_>, validation_fraction: f64, rng: &mut StdRng) -> Self {
        let inputs = Standardizer::fit_inputs(samples.inputs, samples.n_inputs, samples.input_ranges);
        let outputs = Standardizer::fit(samples.targets, samples.n_outputs);
        let (train, held_out) = split_indices(samples.n, validation_fraction, rng);
        NetData {
            x: inputs.apply_rows(samples.inputs),
            y: outputs.apply_rows(samples.targets),
            d: samples.n_inputs,
            k: samples.n_outputs,
            train,
            held_out,
            inputs,
            outputs,
        }
    }

    fn row(&self, i: usize) -> (&[f64], &[f64]) {
        (
            &self.x[i * self.d..(i + 1) * self.d],
            &self.y[i * self.k..(i + 1) * self.k],
        )
    }

    /// Mean squared (standardised) error of `params` over the rows `rows`; `acts` is scratch.
    pub fn mse(&self, net: &Network, params: &[f64], rows: &[usize], acts: &mut [f64]) -> f64 {
        let mut sum = 0.0;
        for &i in rows {
            let (x, y) = self.row(i);
            net.forward(params, x, acts);
            let out = &acts[acts.len() - self.k..];
            sum += out.iter().zip(y).map(|(o, t)| (o - t) * (o - t)).sum::<f64>();
        }
        sum / (rows.len() * self.k) as f64
    }

    /// The fitted predictor for trained `params`.
    pub fn fitted(self, net: Network, params: Vec<f64>) -> Result<FittedMlp> {
        FittedMlp::try_from(MlpModel {
            network: net,
            params,
            inputs: self.inputs,
            outputs: self.outputs,
        })
    }
}

/// Keeps the best weights by the monitored error and says when patience has run out.
struct EarlyStopping {
    best: Vec<f64>,
    best_error: f64,
    since: usize,
    patience: usize,
}

impl EarlyStopping {
    fn new(params: &[f64], error: f64, patience: usize) -> Self {
        EarlyStopping {
            best: params.to_vec(),
            best_error: error,
            since: 0,
            patience,
        }
    }

    /// Records the error of `params`; true when training should stop.
    fn update(&mut self, params: &[f64], error: f64) -> bool {
        if error < self.best_error {
            self.best_error = error;
            self.best.copy_from_slice(params);
            self.since = 0;
        } else {
            self.since += 1;
        }
        self.since >= self.patience
    }
}

/// Refines `params` in place by the configured gradient method; the best weights by the
/// monitored error (held-out rows, or training rows when none are held out) are kept.
/// Every epoch is reported to `control`, whose stop request ends training early with
/// [`Error::Interrupted`].
pub(crate) fn train(
    net: &Network,
    params: &mut [f64],
    data: &NetData,
    tp: &TrainingParams,
    rng: &mut StdRng,
    control: &FitControl<'_>,
) -> Result<()> {
    match tp.method {
        GradientMethod::Adam => adam(net, params, data, tp, rng, control),
        GradientMethod::LevenbergMarquardt => levenberg_marquardt(net, params, data, tp, control)?,
    }
    control.cancel.check()
}

fn monitored(data: &NetData) -> &[usize] {
    if data.held_out.is_empty() {
        &data.train
    } else {
        &data.held_out
    }
}

fn adam(
    net: &Network,
    params: &mut [f64],
    data: &NetData,
    tp: &TrainingParams,
    rng: &mut StdRng,
    control: &FitControl<'_>,
) {
    const BETA1: f64 = 0.9;
    const BETA2: f64 = 0.999;
    const EPS: f64 = 1e-8;
    let np = params.len();
    let (mut m, mut v, mut grad) = (vec![0.0; np], vec![0.0; np], vec![0.0; np]);
    let mut acts = vec![0.0; net.n_activations()];
    let mut deltas = acts.clone();
    let mut dout = vec![0.0; data.k];
    let mut order = data.train.clone();
    let mut stop = EarlyStopping::new(params, data.mse(net, params, monitored(data), &mut acts), tp.patience);
    let mut steps = Steps::new(control, "adam", tp.max_epochs);
    let mut step = 0;
    for _ in 0..tp.max_epochs {
        // A stopped run ends here; the fit that called it returns the interruption.
        if control.cancel.is_cancelled() {
            break;
        }
        order.shuffle(rng);
        for batch in order.chunks(tp.batch_size) {
            grad.fill(0.0);
            let scale = 2.0 / (batch.len() * data.k) as f64;
            for &i in batch {
                let (x, y) = data.row(i);
                net.forward(params, x, &mut acts);
                let out = &acts[acts.len() - data.k..];
                for ((g, o), t) in dout.iter_mut().zip(out).zip(y) {
                    *g = scale * (o - t);
                }
                net.backward(params, x, &acts, &dout, &mut grad, &mut deltas);
            }
            step += 1;
            let c1 = 1.0 - BETA1.powi(step);
            let c2 = 1.0 - BETA2.powi(step);
            for (((p, g), m), v) in params.iter_mut().zip(&grad).zip(&mut m).zip(&mut v) {
                *m = BETA1 * *m + (1.0 - BETA1) * g;
                *v = BETA2 * *v + (1.0 - BETA2) * g * g;
                *p -= tp.learning_rate * (*m / c1) / ((*v / c2).sqrt() + EPS);
            }
        }
        steps.step();
        if stop.update(params, data.mse(net, params, monitored(data), &mut acts)) {
            break;
        }
    }
    params.copy_from_slice(&stop.best);
}

/// Training on all rows as least squares: the residuals `output − target` of the training
/// rows, the Jacobian by one back-propagation per output, the held-out error checked after
/// every iteration.
struct NetFit<'a, 'c> {
    net: &'a Network,
    data: &'a NetData,
    acts: Vec<f64>,
    deltas: Vec<f64>,
    grad_row: Vec<f64>,
    unit: Vec<f64>,
    stop: EarlyStopping,
    steps: Steps<'c, 'a>,
}

impl LeastSquares for NetFit<'_, '_> {
    fn n_params(&self) -> usize {
        self.net.n_params()
    }

    fn n_residuals(&self) -> usize {
        self.data.train.len() * self.data.k
    }

    fn residuals_into(&mut self, params: &[f64], res: &mut DVector<f64>) -> Result<()> {
        let k = self.data.k;
        for (r, &i) in self.data.train.iter().enumerate() {
            let (x, y) = self.data.row(i);
            self.net.forward(params, x, &mut self.acts);
            let out = &self.acts[self.acts.len() - k..];
            for c in 0..k {
                res[r * k + c] = out[c] - y[c];
            }
        }
        Ok(())
    }

    fn jacobian_into(&mut self, params: &[f64], _approximate: bool, jac: &mut DMatrix<f64>) -> Result<()> {
        let k = self.data.k;
        for (r, &i) in self.data.train.iter().enumerate() {
            let x = self.data.row(i).0;
            self.net.forward(params, x, &mut self.acts);
            for c in 0..k {
                self.unit.fill(0.0);
                self.unit[c] = 1.0;
                self.grad_row.fill(0.0);
                self.net
                    .backward(params, x, &self.acts, &self.unit, &mut self.grad_row, &mut self.deltas);
                for (p, g) in self.grad_row.iter().enumerate() {
                    jac[(r * k + c, p)] = *g;
                }
            }
        }
        Ok(())
    }

    fn iteration(&mut self, it: &LmIteration<'_>) -> ControlFlow<()> {
        self.steps.step();
        let error = self.data.mse(self.net, it.x, monitored(self.data), &mut self.acts);
        if self.stop.update(it.x, error) {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    }
}

fn levenberg_marquardt(
    net: &Network,
    params: &mut [f64],
    data: &NetData,
    tp: &TrainingParams,
    control: &FitControl<'_>,
) -> Result<()> {
    let mut acts = vec![0.0; net.n_activations()];
    let stop = EarlyStopping::new(params, data.mse(net, params, monitored(data), &mut acts), tp.patience);
    let mut fit = NetFit {
        net,
        data,
        deltas: acts.clone(),
        acts,
        grad_row: vec![0.0; params.len()],
        unit: vec![0.0; data.k],
        stop,
        steps: Steps::new(control, "lm", tp.max_epochs),
    };
    let lm = LmParams {
        max_iterations: tp.max_epochs,
        damping: Damping::Identity,
        initial_damping: tp.initial_damping,
        damping_increase: 10.0,
        damping_decrease: 10.0,
        // No damping up to this makes progress: a minimum of the training error.
        max_damping: 1e10,
        exact_jacobian_below: 0.0,
        // Early stopping on the held-out rows decides the end.
        convergence: None,
        stall: None,
        cancel: control.cancel.clone(),
    };
    let outcome = least_squares::levenberg_marquardt(&mut fit, params, &lm);
    params.copy_from_slice(&fit.stop.best);
    outcome.map(|_| ())
}
