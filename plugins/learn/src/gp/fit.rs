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

impl GpSpec {
    pub(super) fn check(&self) -> Result<()> {
        check_count("max_optimization_samples", self.max_optimization_samples, 2)?;
        if !(self.noise_floor.is_finite() && self.noise_floor >= 0.0) {
            return Err(invalid(
                "noise_floor",
                format!("expected a finite non-negative variance, got {}", self.noise_floor),
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
    fn fit_with(&self, data: &TrainingSet<'_>, control: &FitControl<'_>) -> Result<Box<dyn FittedPredictor>> {
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
                None => self.optimise(&sub_x, &columns(&y, k, &rows, &group), d, &mut rng, control)?,
            };
            let scaled = scale_inputs(&x, &hyper.length_scales);
            // Jitter only when the factorisation fails (near-duplicate rows with tiny noise).
            let sf2 = hyper.signal_std * hyper.signal_std;
            let (jitter, chol) = std::iter::once(0.0)
                .chain((0..8).map(|e| sf2 * 1e-10 * 10f64.powi(e)))
                .find_map(|j| factor(&scaled, d, &hyper, j).map(|c| (j, c)))
                .ok_or_else(|| Error::Degenerate {
                    what: "gp".into(),
                    reason: "kernel matrix is not positive definite even with jitter".into(),
                })?;
            let all: Vec<usize> = (0..s.n).collect();
            let targets = DMatrix::from_row_slice(s.n, group.len(), &columns(&y, k, &all, &group));
            let mut a = targets;
            chol.solve_lower_triangular_mut(&mut a);
            chol.tr_solve_lower_triangular_mut(&mut a);
            let alpha: Vec<f64> = (0..s.n)
                .flat_map(|i| (0..group.len()).map(move |c| (i, c)))
                .map(|(i, c)| a[(i, c)])
                .collect();
            caches.push(KernelCache::new(&scaled, d, &alpha, group.len(), Some(chol)));
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
