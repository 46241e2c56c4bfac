//! The spec (hyper-parameters of the search) and the fit: standardise, optimise the
//! likelihood on a subset, factorise the full set.

use armcomp_core::{Error, FitControl, FittedPredictor, PredictorSpec, Result, TrainingSet};
use nalgebra::DMatrix;
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::data::{Samples, Standardizer, Steps, check_count, invalid};
use crate::lbfgs;

use super::*;

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
    /// Seed of the restarts, the optimisation subset and the inducing rows.
    pub seed: u64,
    /// Training sets of at most this many rows get the exact process (an n × n factorisation:
    /// O(n³) time, 8 n² bytes); larger ones the inducing-point mean through `inducing` rows.
    pub exact_up_to: usize,
    /// Inducing rows of a larger set, drawn with the seed (O(n m²) time, O(m²) memory).
    pub inducing: usize,
    /// The most memory the fit may take, MiB; a fit that would take more is refused before it
    /// starts, saying what it would need.
    pub max_memory_mib: u64,
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
            exact_up_to: 1000,
            inducing: 300,
            max_memory_mib: 2048,
        }
    }
}

impl GpSpec {
    pub(super) fn check(&self) -> Result<()> {
        check_count("max_optimization_samples", self.max_optimization_samples, 2)?;
        check_count("inducing", self.inducing, 2)?;
        if !(self.noise_floor.is_finite() && self.noise_floor >= 0.0) {
            return Err(invalid(
                "noise_floor",
                format!("expected a finite non-negative variance, got {}", self.noise_floor),
            ));
        }
        Ok(())
    }

    /// The rows whose inputs the fitted process keeps for `n` training rows: all of them when
    /// the exact process is affordable, else `inducing` drawn with `rng` (sorted).
    fn kept_rows(&self, n: usize, rng: &mut StdRng) -> Option<Vec<usize>> {
        (n > self.exact_up_to.max(self.inducing)).then(|| {
            let mut rows: Vec<usize> = (0..n).collect();
            rows.shuffle(rng);
            rows.truncate(self.inducing);
            rows.sort_unstable();
            rows
        })
    }

    /// Bytes the fit of `n` rows with `k` outputs holds at its peak (its largest matrices),
    /// beside the training set itself.
    pub fn memory_bytes(&self, n: usize, k: usize) -> u64 {
        let opt = n.min(self.max_optimization_samples) as u64;
        let likelihood = 8 * 3 * opt * opt;
        let fit = if n > self.exact_up_to.max(self.inducing) {
            sparse_bytes(self.inducing, k)
        } else {
            8 * (n as u64) * (n as u64) + 8 * 2 * (n * k) as u64
        };
        likelihood.max(fit)
    }

    /// Refuses a fit of `n` rows with `k` outputs that would exceed `max_memory_mib`.
    fn check_memory(&self, n: usize, k: usize) -> Result<()> {
        let need = self.memory_bytes(n, k);
        let limit = self.max_memory_mib.saturating_mul(1 << 20);
        if need > limit {
            let mib = |b: u64| b.div_ceil(1 << 20);
            return Err(invalid(
                "gp",
                format!(
                    "fitting {n} rows would take about {} MiB, above max_memory_mib = {}; lower exact_up_to \
                     (now {}) or inducing (now {}), or raise max_memory_mib",
                    mib(need),
                    self.max_memory_mib,
                    self.exact_up_to,
                    self.inducing
                ),
            ));
        }
        Ok(())
    }

    /// The hyper-parameters maximising the log marginal likelihood of `y` (columns `outputs`).
    pub(super) fn optimise(
        &self,
        x: &[f64],
        y: &[f64],
        d: usize,
        rng: &mut StdRng,
        control: &FitControl<'_>,
    ) -> Result<GpHyperParams> {
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
        let mut steps = Steps::new(control, "gp", starts.len() * self.max_iterations);
        let mut best: Option<(Vec<f64>, f64)> = None;
        let mut iterations = 0;
        for start in &starts {
            control.cancel.check()?;
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
                || {
                    steps.step();
                    iterations += 1;
                },
            );
            if value.is_finite() && best.as_ref().is_none_or(|(_, b)| value < *b) {
                best = Some((theta, value));
            }
        }
        let (theta, _) = best.ok_or_else(|| Error::NotConverged {
            what: "gp hyper-parameter fit".into(),
            iterations,
            best: format!(
                "the marginal likelihood could not be evaluated at any of the {} starts (degenerate inputs?)",
                starts.len()
            ),
        })?;
        Ok(GpHyperParams::from_log_params(&theta, self.noise_floor))
    }
}

#[typetag::serde(name = "gp")]
impl PredictorSpec for GpSpec {
    /// One kernel's hyper-parameters held as `fixed`; per-output kernels keep their search
    /// (`fixed` is one set for all).
    fn holding(&self, searched: &serde_json::Value) -> Option<Box<dyn PredictorSpec>> {
        let hypers: Vec<GpHyperParams> = serde_json::from_value(searched.clone()).ok()?;
        match (self.kernels, hypers.as_slice()) {
            (KernelSharing::Shared, [hyper]) => Some(Box::new(GpSpec {
                fixed: Some(hyper.clone()),
                ..self.clone()
            })),
            _ => None,
        }
    }

    fn fit_with(&self, data: &TrainingSet<'_>, control: &FitControl<'_>) -> Result<Box<dyn FittedPredictor>> {
        self.check()?;
        let s = Samples::check(data, 2)?;
        let (d, k) = (s.n_inputs, s.n_outputs);
        self.check_memory(s.n, k)?;
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
        let kept = self.kept_rows(s.n, &mut rng);
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
                None => self.optimise(&sub_x, &columns(&y, k, &rows, &group), d, &mut rng, control)?,
            };
            let scaled = scale_inputs(&x, &hyper.length_scales);
            let all: Vec<usize> = (0..s.n).collect();
            let targets = columns(&y, k, &all, &group);
            // The factor is also what the predictive standard deviation needs: of the kept
            // rows' matrix, with the smallest jitter that makes it positive definite.
            let (kept_scaled, jitter, chol, alpha) = match &kept {
                None => {
                    let (jitter, chol) = kernel_factor(&scaled, d, &hyper)?;
                    let alpha = exact_weights(&chol, &targets);
                    (scaled, jitter, chol, alpha)
                }
                Some(kept) => {
                    let inducing: Vec<f64> = kept
                        .iter()
                        .flat_map(|&i| scaled[i * d..(i + 1) * d].iter().copied())
                        .collect();
                    let alpha = sparse_weights(&scaled, &inducing, d, &hyper, &targets)?;
                    let (jitter, chol) = kernel_factor(&inducing, d, &hyper)?;
                    (inducing, jitter, chol, alpha)
                }
            };
            control.cancel.check()?;
            caches.push(KernelCache::new(&kept_scaled, d, &alpha, group.len(), Some(chol)));
            kernels.push(GpKernelModel {
                outputs: group,
                hyper,
                jitter,
                alpha,
            });
        }
        let train_inputs = match &kept {
            None => x,
            Some(kept) => kept
                .iter()
                .flat_map(|&i| x[i * d..(i + 1) * d].iter().copied())
                .collect(),
        };
        Ok(Box::new(FittedGp {
            model: GpModel {
                inputs,
                outputs,
                train_inputs,
                kernels,
            },
            caches,
        }))
    }
}

/// The lower Cholesky factor of `K(scaled) + σ_n² I` and the jitter it needed: none unless the
/// factorisation fails (near-duplicate rows with tiny noise).
fn kernel_factor(scaled: &[f64], d: usize, hyper: &GpHyperParams) -> Result<(f64, DMatrix<f64>)> {
    let sf2 = hyper.signal_std * hyper.signal_std;
    std::iter::once(0.0)
        .chain((0..8).map(|e| sf2 * 1e-10 * 10f64.powi(e)))
        .find_map(|j| factor(scaled, d, hyper, j).map(|c| (j, c)))
        .ok_or_else(|| Error::Degenerate {
            what: "gp".into(),
            reason: "kernel matrix is not positive definite even with jitter".into(),
        })
}

/// The exact process's weights `α = (K + σ_n² I)⁻¹ y` (row-major `n × g`) from the factor
/// `chol` of the matrix and the targets (row-major `n × g`).
fn exact_weights(chol: &DMatrix<f64>, targets: &[f64]) -> Vec<f64> {
    let n = chol.nrows();
    let g = targets.len() / n;
    let mut a = DMatrix::from_row_slice(n, g, targets);
    chol.solve_lower_triangular_mut(&mut a);
    chol.tr_solve_lower_triangular_mut(&mut a);
    (0..n)
        .flat_map(|i| (0..g).map(move |c| (i, c)))
        .map(|(i, c)| a[(i, c)])
        .collect()
}
