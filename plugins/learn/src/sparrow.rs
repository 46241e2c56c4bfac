//! The sparrow search algorithm (SSA) of Xue & Shen (2020), a population-based minimiser used
//! by `ssa_bp` to find starting weights for back-propagation.

use armcomp_core::{FitControl, Result};
use rand::Rng;
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand_distr::StandardNormal;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::data::{Steps, check_count, check_fraction, check_positive, invalid};

/// Sparrow search settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct SparrowParams {
    /// Number of sparrows.
    pub population: usize,
    /// Share of the population, best first, that are producers (discoverers), PD.
    pub producer_share: f64,
    /// Share of the population picked at random each iteration as scouts aware of danger, SD.
    pub scout_share: f64,
    /// Safety threshold ST in [0.5, 1]: producers search widely while the alarm value R2 < ST.
    pub safety_threshold: f64,
    /// Iterations (iter_max).
    pub iterations: usize,
    /// Every coordinate is searched in `[-bound, bound]`.
    pub bound: f64,
}

impl Default for SparrowParams {
    fn default() -> Self {
        SparrowParams {
            population: 30,
            producer_share: 0.2,
            scout_share: 0.1,
            safety_threshold: 0.8,
            iterations: 100,
            bound: 1.0,
        }
    }
}

impl SparrowParams {
    /// Checks the settings, naming the offending field.
    pub fn check(&self) -> Result<()> {
        check_count("search.population", self.population, 2)?;
        check_count("search.iterations", self.iterations, 1)?;
        check_fraction("search.producer_share", self.producer_share, 1.0)?;
        check_fraction("search.scout_share", self.scout_share, 1.0)?;
        check_positive("search.bound", self.bound)?;
        if !(0.5..=1.0).contains(&self.safety_threshold) {
            return Err(invalid(
                "search.safety_threshold",
                format!("expected a value in [0.5, 1], got {}", self.safety_threshold),
            ));
        }
        if self.producers() >= self.population {
            return Err(invalid(
                "search.producer_share",
                format!(
                    "{} of {} sparrows leaves no scroungers",
                    self.producer_share, self.population
                ),
            ));
        }
        Ok(())
    }

    fn producers(&self) -> usize {
        ((self.producer_share * self.population as f64).round() as usize).max(1)
    }

    fn scouts(&self) -> usize {
        ((self.scout_share * self.population as f64).round() as usize).min(self.population)
    }

    /// Fitness evaluations a search with these settings makes.
    pub fn evaluations(&self) -> usize {
        self.population + self.iterations * (self.population + self.scouts())
    }
}

/// Outcome of a sparrow search.
#[derive(Debug, Clone, PartialEq)]
pub struct SparrowReport {
    /// The best position found.
    pub best: Vec<f64>,
    /// Its fitness.
    pub fitness: f64,
    /// Fitness evaluations made.
    pub evaluations: usize,
}

/// Guards the scouts' division when the best and worst fitness coincide (as in the original).
const EPS: f64 = 1e-50;

/// Minimises `fitness` over `[-bound, bound]^dim` (NaN counts as +∞).
///
/// The update rules are those of Xue & Shen (2020), Eq. 3–5, not the deflection paper's
/// Eq. 6–8, which misprint them: in its Eq. 7 the starving scroungers' exponent divides by
/// `α·iter_max` instead of `i²`, the condition `i > n/2` lost its `i`, and the fed scroungers move
/// from `X^{t+1}_{i,j}` instead of the best producer `X_P^{t+1}`; in its Eq. 8 the best sparrow's
/// step `K·|X − X_worst| / ((f_i − f_w) + ε)` is wrapped in an `exp` that the original does not
/// have, and the left side reads `X^t` for `X^{t+1}`. As in the authors' reference code,
/// the alarm value R2 is drawn once per iteration, α once per producer, `A⁺·L` applies the scalar
/// `Σ_j A_j |X_j − X_P,j| / d` to every coordinate, and each sparrow remembers its best position
/// (the `X^t` the rules move from); here a sparrow's memory is updated after every evaluation,
/// so no evaluation is lost when a scout moves the same sparrow again.
pub fn sparrow_search(
    dim: usize,
    params: &SparrowParams,
    rng: &mut StdRng,
    control: &FitControl<'_>,
    mut fitness: impl FnMut(&[f64]) -> f64,
) -> Result<SparrowReport> {
    params.check()?;
    check_count("search dimension", dim, 1)?;
    let n = params.population;
    let b = params.bound;
    let iter_max = params.iterations as f64;
    let mut eval = |x: &[f64]| {
        let f = fitness(x);
        if f.is_nan() { f64::INFINITY } else { f }
    };
    // Personal best positions (row-major n × dim) and their fitness.
    let mut best_x: Vec<f64> = (0..n * dim).map(|_| rng.random_range(-b..=b)).collect();
    let mut best_f: Vec<f64> = best_x.chunks_exact(dim).map(&mut eval).collect();
    let mut evaluations = n;
    let mut x = vec![0.0; dim];
    let mut order: Vec<usize> = (0..n).collect();
    let mut picks: Vec<usize> = (0..n).collect();
    let (producers, scouts) = (params.producers(), params.scouts());
    let mut worst = vec![0.0; dim];
    let mut global = vec![0.0; dim];
    let mut producer_best = vec![0.0; dim];

    let mut try_move = |s: usize, x: &mut [f64], best_x: &mut [f64], best_f: &mut [f64]| -> (f64, bool) {
        for v in x.iter_mut() {
            *v = v.clamp(-b, b);
        }
        let f = eval(x);
        let improved = f < best_f[s];
        if improved {
            best_f[s] = f;
            best_x[s * dim..(s + 1) * dim].copy_from_slice(x);
        }
        (f, improved)
    };

    let mut steps = Steps::new(control, "sparrows", params.iterations);
    for _ in 0..params.iterations {
        control.cancel.check()?;
        order.sort_by(|&a, &c| best_f[a].total_cmp(&best_f[c]));
        let (g, w) = (order[0], order[n - 1]);
        let (f_g, f_w) = (best_f[g], best_f[w]);
        global.copy_from_slice(&best_x[g * dim..(g + 1) * dim]);
        worst.copy_from_slice(&best_x[w * dim..(w + 1) * dim]);

        // Producers (discoverers), Eq. 3.
        let r2: f64 = rng.random();
        let mut producer_f = f64::INFINITY;
        for (rank, &s) in order[..producers].iter().enumerate() {
            let own = &best_x[s * dim..(s + 1) * dim];
            if r2 < params.safety_threshold {
                // α ∈ (0, 1].
                let alpha = 1.0 - rng.random::<f64>();
                let shrink = (-((rank + 1) as f64) / (alpha * iter_max)).exp();
                x.iter_mut().zip(own).for_each(|(v, o)| *v = o * shrink);
            } else {
                let q: f64 = rng.sample(StandardNormal);
                x.iter_mut().zip(own).for_each(|(v, o)| *v = o + q);
            }
            let (f, _) = try_move(s, &mut x, &mut best_x, &mut best_f);
            if f < producer_f {
                producer_f = f;
                producer_best.copy_from_slice(&x);
            }
        }

        // Scroungers (joiners), Eq. 4.
        for (rank, &s) in order.iter().enumerate().skip(producers) {
            let i = (rank + 1) as f64;
            let own = &best_x[s * dim..(s + 1) * dim];
            if rank + 1 > n / 2 {
                // Starving: fly elsewhere.
                let q: f64 = rng.sample(StandardNormal);
                for ((v, o), wv) in x.iter_mut().zip(own).zip(&worst) {
                    *v = q * ((wv - o) / (i * i)).exp();
                }
            } else {
                let step = own
                    .iter()
                    .zip(&producer_best)
                    .map(|(o, p)| {
                        if rng.random::<bool>() {
                            (o - p).abs()
                        } else {
                            -(o - p).abs()
                        }
                    })
                    .sum::<f64>()
                    / dim as f64;
                x.iter_mut().zip(&producer_best).for_each(|(v, p)| *v = p + step);
            }
            try_move(s, &mut x, &mut best_x, &mut best_f);
        }

        // Scouts aware of danger, Eq. 5.
        let (chosen, _) = picks.partial_shuffle(rng, scouts);
        for &s in chosen.iter() {
            let own = &best_x[s * dim..(s + 1) * dim];
            if best_f[s] > f_g {
                // At the edge of the group: move towards the safest place.
                for ((v, o), gv) in x.iter_mut().zip(own).zip(&global) {
                    let beta: f64 = rng.sample(StandardNormal);
                    *v = gv + beta * (o - gv).abs();
                }
            } else {
                // In the middle (the best): walk away at random, relative to the worst.
                let k: f64 = rng.random_range(-1.0..=1.0);
                let denom = (best_f[s] - f_w) + EPS;
                for ((v, o), wv) in x.iter_mut().zip(own).zip(&worst) {
                    *v = o + k * (o - wv).abs() / denom;
                }
            }
            try_move(s, &mut x, &mut best_x, &mut best_f);
        }
        evaluations += n + scouts;
        steps.step();
    }
    let g = (0..n).min_by(|&a, &c| best_f[a].total_cmp(&best_f[c])).unwrap_or(0);
    Ok(SparrowReport {
        best: best_x[g * dim..(g + 1) * dim].to_vec(),
        fitness: best_f[g],
        evaluations,
    })
}
