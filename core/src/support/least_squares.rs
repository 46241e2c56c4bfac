//! Levenberg–Marquardt for nonlinear least squares, the one loop behind calibration and
//! network training.
//!
//! A problem ([`LeastSquares`]) gives residuals `r(x)` and their Jacobian; it may add bounds,
//! Gaussian priors, a cheaper approximate Jacobian and a hook run after every iteration
//! (progress, early stopping). [`levenberg_marquardt`] minimises
//! `½‖r(x)‖² + ½ Σ ((xᵢ − cᵢ) / σᵢ)²` within the bounds.
//!
//! The loop is written here rather than taken from a crate because calibration needs bounds,
//! priors and a best-so-far result on non-convergence together, and the available crates pull
//! in another nalgebra version.

use std::ops::ControlFlow;

use nalgebra::{DMatrix, DVector};

use crate::error::Result;
use crate::support::cancel::Cancel;

/// A nonlinear least-squares problem: residuals, their Jacobian, and optional constraints and
/// hooks for [`levenberg_marquardt`].
pub trait LeastSquares {
    /// Number of parameters.
    fn n_params(&self) -> usize;

    /// Number of residuals.
    fn n_residuals(&self) -> usize;

    /// The residuals at `x` into `r` (length [`n_residuals`](Self::n_residuals)). An error
    /// means the model cannot be evaluated at `x`: a trial step there is rejected, like one
    /// that raises the cost.
    fn residuals_into(&mut self, x: &[f64], r: &mut DVector<f64>) -> Result<()>;

    /// The Jacobian `∂r/∂x` at `x` into `j` (residuals × parameters). `x` is always the point
    /// the loop last moved to (see [`accept`](Self::accept)). With `approximate`, a problem
    /// that has a cheaper approximation ([`has_approximate_jacobian`](Self::has_approximate_jacobian))
    /// may write that instead. An error ends the loop.
    fn jacobian_into(&mut self, x: &[f64], approximate: bool, j: &mut DMatrix<f64>) -> Result<()>;

    /// Whether [`jacobian_into`](Self::jacobian_into) has an approximate form. The loop uses it
    /// while steps gain at least [`LmParams::exact_jacobian_below`], then the exact form; a
    /// step the approximation cannot find is looked for again with the exact form.
    fn has_approximate_jacobian(&self) -> bool {
        false
    }

    /// Lower and upper bound of every parameter, when there are bounds.
    fn bounds(&self) -> Option<(&[f64], &[f64])> {
        None
    }

    /// Gaussian priors, when there are: the centre and standard deviation of every parameter
    /// (infinite for none). Each adds `½((xᵢ − cᵢ) / σᵢ)²` to the cost.
    fn prior(&self) -> Option<(&[f64], &[f64])> {
        None
    }

    /// The loop moved to `x`, the point of the last [`residuals_into`](Self::residuals_into)
    /// call (the start, or an accepted step): a problem that keeps what it evaluated there for
    /// the Jacobian keeps it now.
    fn accept(&mut self, _x: &[f64]) {}

    /// Called after every iteration; [`ControlFlow::Break`] ends the loop
    /// ([`LmStop::Stopped`]): progress display, early stopping on held-out data.
    fn iteration(&mut self, _it: &LmIteration<'_>) -> ControlFlow<()> {
        ControlFlow::Continue(())
    }
}

/// How the damping `λ` enters the normal equations `(JᵀJ + λD) δ = −Jᵀr`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Damping {
    /// Marquardt: `D` is the diagonal of `JᵀJ` (with priors), so the damping is invariant to
    /// the parameters' units.
    Scaled,
    /// Levenberg: `D = I`, for parameters of one scale (standardised network weights).
    Identity,
}

/// The convergence tests of [`levenberg_marquardt`]. Converged means: an accepted step was
/// small (it lowered the cost by less than `tolerance` relatively or `min_improvement`
/// absolutely, or moved every parameter by less than `min_step` of its standard deviation),
/// and the full Newton step from where it ended (bounds respected) moves every parameter by at
/// most `min_step` standard deviations. Standard deviations are those of the undamped normal
/// matrix, in units of the residuals' scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConvergenceParams {
    /// Relative decrease of the cost below which a step is small.
    pub tolerance: f64,
    /// Absolute decrease of the cost below which a step is small.
    pub min_improvement: f64,
    /// Step size, in standard deviations, below which a step is small and the Newton step is
    /// negligible.
    pub min_step: f64,
}

/// When [`levenberg_marquardt`] gives up on a model that cannot explain the data: the cost
/// still above `above_cost` and each of the last `iterations` accepted steps lowering it by
/// less than the fraction `gain`. Such a fit crawls along directions the data barely
/// determine, buying a little RMS with implausible values, for its whole iteration budget.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StallParams {
    /// Consecutive slow accepted steps that end the loop.
    pub iterations: usize,
    /// Relative decrease of the cost below which an accepted step is slow.
    pub gain: f64,
    /// Only costs above this stall (below it the fit explains the data and converges).
    pub above_cost: f64,
}

/// Settings of [`levenberg_marquardt`].
#[derive(Debug, Clone, PartialEq)]
pub struct LmParams {
    /// Most iterations (each one Jacobian and the damped solves until a step is accepted).
    pub max_iterations: usize,
    /// How the damping scales.
    pub damping: Damping,
    /// Damping at the start.
    pub initial_damping: f64,
    /// Factor on the damping after a step that does not lower the cost (after a singular
    /// damped matrix the factor is 10).
    pub damping_increase: f64,
    /// Divisor of the damping after an accepted step (the damping stays at least 1e-12).
    pub damping_decrease: f64,
    /// The loop ends when the damping needed to lower the cost exceeds this.
    pub max_damping: f64,
    /// A step that lowers the cost by less than this switches an approximate Jacobian to the
    /// exact one (with residuals in units of their noise, 1 is what the noise can tell apart).
    pub exact_jacobian_below: f64,
    /// The convergence tests; without them the loop ends only on the iteration limit, a cost
    /// no damping lowers, or the iteration hook, and computes no standard deviations.
    pub convergence: Option<ConvergenceParams>,
    /// Ends the loop early when the fit stalls far above the noise ([`LmStop::Stalled`]).
    pub stall: Option<StallParams>,
    /// Ends the loop with [`Error::Interrupted`](crate::Error::Interrupted) once cancelled
    /// (checked before every iteration).
    pub cancel: Cancel,
}

impl Default for LmParams {
    /// Marquardt's scaled damping with the convergence tests, as calibration uses them.
    fn default() -> Self {
        LmParams {
            max_iterations: 100,
            damping: Damping::Scaled,
            initial_damping: 1e-3,
            damping_increase: 4.0,
            damping_decrease: 3.0,
            max_damping: 1e12,
            exact_jacobian_below: 1.0,
            convergence: Some(ConvergenceParams {
                tolerance: 1e-10,
                min_improvement: 1e-4,
                min_step: 1e-2,
            }),
            stall: None,
            cancel: Cancel::default(),
        }
    }
}

/// What the iteration hook sees after an iteration.
#[derive(Debug, Clone, Copy)]
pub struct LmIteration<'a> {
    /// Iterations so far (1-based).
    pub iteration: usize,
    /// The current parameters.
    pub x: &'a [f64],
    /// The residuals there.
    pub residuals: &'a DVector<f64>,
    /// The cost there (priors included).
    pub cost: f64,
    /// The damping after the iteration.
    pub damping: f64,
    /// Whether the iteration found a step that lowers the cost.
    pub accepted: bool,
}

/// Why an accepted step counted as small.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SmallStep {
    /// It lowered the cost by only this much.
    Improvement(f64),
    /// It moved no parameter by more than this many standard deviations.
    Moved(f64),
}

/// Why [`levenberg_marquardt`] stopped.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LmStop {
    /// The convergence tests passed after this small step.
    Converged(SmallStep),
    /// [`LmParams::max_iterations`] reached.
    IterationLimit,
    /// No damping up to [`LmParams::max_damping`] gives a step that lowers the cost.
    NoDescent,
    /// The iteration hook asked to stop.
    Stopped,
    /// The cost stayed above [`StallParams::above_cost`] while the last
    /// [`StallParams::iterations`] accepted steps each lowered it by less than
    /// [`StallParams::gain`].
    Stalled,
}

/// What [`levenberg_marquardt`] did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LmReport {
    /// Iterations run.
    pub iterations: usize,
    /// Whether it ended at a minimum: the convergence tests passed, or no step lowers a finite
    /// cost where the Newton step is negligible (without tests: where the cost is finite).
    pub converged: bool,
    /// Why it stopped.
    pub stop: LmStop,
    /// The cost at the end (priors included).
    pub cost: f64,
    /// The last Newton step in standard deviations (largest over the parameters; see
    /// [`ConvergenceParams`]), when the convergence tests ran.
    pub newton_step: Option<f64>,
}

/// The smallest damping (a step divided below it gains nothing and risks a singular matrix).
const MIN_DAMPING: f64 = 1e-12;

/// Minimises `problem`'s cost from `x`, leaving in `x` the best point found (the loop only
/// moves to points of lower cost, so that is where it ends). [`LmParams::cancel`] is checked
/// before every iteration.
pub fn levenberg_marquardt<P: LeastSquares + ?Sized>(
    problem: &mut P,
    x: &mut [f64],
    params: &LmParams,
) -> Result<LmReport> {
    let n = problem.n_params();
    assert_eq!(
        x.len(),
        n,
        "levenberg_marquardt: {} parameters for a problem of {n}",
        x.len()
    );
    let constraints = Constraints::of(problem);
    let mut lm = LmState::start(problem, x, params, &constraints)?;
    let mut converged = false;
    let stop = loop {
        params.cancel.check()?;
        if params.convergence.is_none() && lm.iterations >= params.max_iterations {
            // Without the tests the Jacobian at the last point serves nothing.
            break LmStop::IterationLimit;
        }
        problem.jacobian_into(x, lm.approximate, &mut lm.j)?;
        let normal = NormalEquations::build(&lm.j, &lm.r, &constraints, x);
        let std = normal.standard_deviations(params.convergence.is_some());
        let gradient_ok = match params.convergence {
            Some(conv) => {
                let gradient = normal.newton_step(&std, |c, step| constraints.blocked(x, c, step));
                lm.newton_step = Some(gradient);
                gradient <= conv.min_step
            }
            None => true,
        };
        if let Some(step) = lm.small_step.filter(|_| gradient_ok) {
            converged = true;
            break LmStop::Converged(step);
        }
        if params.stall.is_some_and(|st| lm.slow >= st.iterations) {
            break LmStop::Stalled;
        }
        if lm.iterations >= params.max_iterations {
            break LmStop::IterationLimit;
        }
        lm.iterations += 1;
        let accepted = lm.damped_step(problem, x, &normal, &std, &constraints, params);
        let it = LmIteration {
            iteration: lm.iterations,
            x,
            residuals: &lm.r,
            cost: lm.cost,
            damping: lm.lambda,
            accepted,
        };
        if problem.iteration(&it).is_break() {
            break LmStop::Stopped;
        }
        if !accepted && lm.approximate {
            // The approximation may be what hides the descent: look again with the exact form.
            lm.approximate = false;
            lm.small_step = None;
            lm.lambda = params.initial_damping;
            continue;
        }
        if !accepted {
            // No step lowers the cost: a minimum if the Newton step vanishes there, otherwise
            // the model cannot be evaluated or differentiated near here.
            converged = gradient_ok && lm.cost.is_finite();
            break LmStop::NoDescent;
        }
    };
    Ok(LmReport {
        iterations: lm.iterations,
        converged,
        stop,
        cost: lm.cost,
        newton_step: lm.newton_step,
    })
}

/// A problem's bounds and priors, copied once so that the loop can borrow the problem
/// mutably while it uses them.
struct Constraints {
    bounds: Option<(Vec<f64>, Vec<f64>)>,
    prior: Option<(Vec<f64>, Vec<f64>)>,
    /// `1 / σᵢ` of every prior (empty without priors).
    prior_w: Vec<f64>,
}

impl Constraints {
    fn of<P: LeastSquares + ?Sized>(problem: &P) -> Self {
        let bounds = problem.bounds().map(|(lo, hi)| (lo.to_vec(), hi.to_vec()));
        let prior = problem.prior().map(|(c, s)| (c.to_vec(), s.to_vec()));
        let prior_w: Vec<f64> = prior.iter().flat_map(|(_, s)| s.iter().map(|s| 1.0 / s)).collect();
        Constraints { bounds, prior, prior_w }
    }

    /// The cost at `x` with residuals `r`, priors included.
    fn cost(&self, x: &[f64], r: &DVector<f64>) -> f64 {
        let n = x.len();
        let prior: f64 = self
            .prior
            .iter()
            .flat_map(|(c, s)| (0..n).map(move |i| ((x[i] - c[i]) / s[i]).powi(2)))
            .sum();
        0.5 * (r.norm_squared() + prior)
    }

    /// Whether parameter `c`, at `x`, sits at a bound that a step of `step` would leave.
    fn blocked(&self, x: &[f64], c: usize, step: f64) -> bool {
        self.bounds
            .as_ref()
            .is_some_and(|(lo, hi)| (x[c] <= lo[c] && step < 0.0) || (x[c] >= hi[c] && step > 0.0))
    }

    /// `x + delta` into `trial`, stopped at the first bound the step meets: a scaled damped
    /// step still lowers the linear model, where clipping each parameter to its bound distorts
    /// the step (rejected, the damping grows, the solver crawls). The parameter that landed on
    /// its bound is held there by the next step if it pushes outward.
    fn step_into(&self, x: &[f64], delta: &DVector<f64>, trial: &mut [f64]) {
        let n = x.len();
        match &self.bounds {
            Some((lo, hi)) => {
                let alpha = (0..n).fold(1.0f64, |alpha, c| {
                    let to = x[c] + delta[c];
                    if to < lo[c] {
                        alpha.min((lo[c] - x[c]) / delta[c])
                    } else if to > hi[c] {
                        alpha.min((hi[c] - x[c]) / delta[c])
                    } else {
                        alpha
                    }
                });
                for c in 0..n {
                    trial[c] = (x[c] + alpha * delta[c]).clamp(lo[c], hi[c]);
                }
            }
            None => {
                for c in 0..n {
                    trial[c] = x[c] + delta[c];
                }
            }
        }
    }
}

/// The normal equations `a δ = −g` at the current point (priors included), with the floor
/// under their diagonal that keeps the scaled damping and the per-parameter fallbacks finite.
struct NormalEquations {
    a: DMatrix<f64>,
    g: DVector<f64>,
    floor: f64,
}

impl NormalEquations {
    fn build(j: &DMatrix<f64>, r: &DVector<f64>, constraints: &Constraints, x: &[f64]) -> Self {
        let mut a = j.transpose() * j;
        let mut g = j.transpose() * r;
        if let Some((centre, _)) = &constraints.prior {
            for (c, w) in constraints.prior_w.iter().enumerate() {
                a[(c, c)] += w * w;
                g[c] += w * w * (x[c] - centre[c]);
            }
        }
        let floor = 1e-12 * a.diagonal().max().max(1e-300);
        NormalEquations { a, g, floor }
    }

    /// Standard deviations (in units of the residuals' scale) from the undamped matrix, to
    /// judge whether a step still moves anything that matters; none when `wanted` is false
    /// (no convergence tests), infinite where the matrix is singular.
    fn standard_deviations(&self, wanted: bool) -> Vec<f64> {
        let n = self.g.len();
        if !wanted {
            return Vec::new();
        }
        match self.a.clone().cholesky() {
            Some(c) => {
                let inv = c.inverse();
                (0..n).map(|i| inv[(i, i)].max(0.0).sqrt()).collect()
            }
            None => vec![f64::INFINITY; n],
        }
    }

    /// The Newton-step test, independent of scale and correlation: how far the full Newton
    /// step from here (the bounds respected) would move each parameter, in its standard
    /// deviations `std` (the largest over the parameters). At a minimum it moves nothing that
    /// matters; a damped crawl far from one leaves a large step. Correlated parameters whose
    /// gradients cancel in combination pass, and a parameter held at its bound by the data
    /// passes. Where the matrix is singular, each parameter's gradient over its own curvature.
    fn newton_step(&self, std: &[f64], blocked: impl Fn(usize, f64) -> bool) -> f64 {
        let (a, g, floor) = (&self.a, &self.g, self.floor);
        let n = g.len();
        let newton = bounded_step(a, g, blocked)
            .unwrap_or_else(|| DVector::from_iterator(n, (0..n).map(|c| g[c] / a[(c, c)].max(floor))));
        newton
            .iter()
            .enumerate()
            .map(|(c, dc)| {
                let sd = if std[c].is_finite() {
                    std[c]
                } else {
                    1.0 / a[(c, c)].max(floor).sqrt()
                };
                (dc / sd).abs()
            })
            .fold(0.0, |m: f64, v| if v.is_nan() { f64::NAN } else { m.max(v) })
    }

    /// The matrix damped by `lambda` the way `damping` says.
    fn damped(&self, lambda: f64, damping: Damping) -> DMatrix<f64> {
        let a = &self.a;
        let mut m = a.clone();
        for c in 0..self.g.len() {
            m[(c, c)] += match damping {
                Damping::Scaled => lambda * a[(c, c)].max(self.floor),
                Damping::Identity => lambda,
            };
        }
        m
    }
}

/// What the loop carries from one iteration to the next: buffers, the current cost and
/// damping, and what the convergence and stall tests remember.
struct LmState {
    r: DVector<f64>,
    r_trial: DVector<f64>,
    j: DMatrix<f64>,
    trial: Vec<f64>,
    cost: f64,
    lambda: f64,
    approximate: bool,
    iterations: usize,
    newton_step: Option<f64>,
    /// Why the last accepted step was small, when it was: the step test. Convergence needs it
    /// and the Newton-step test at the point the step reached.
    small_step: Option<SmallStep>,
    /// Consecutive slow accepted steps (see `StallParams`).
    slow: usize,
}

impl LmState {
    /// The state at the start `x`, which the problem evaluates and accepts.
    fn start<P: LeastSquares + ?Sized>(
        problem: &mut P,
        x: &[f64],
        params: &LmParams,
        constraints: &Constraints,
    ) -> Result<Self> {
        let mut r = DVector::zeros(problem.n_residuals());
        let r_trial = r.clone();
        let j = DMatrix::zeros(r.len(), x.len());
        let trial = x.to_vec();
        problem.residuals_into(x, &mut r)?;
        problem.accept(x);
        let cost = constraints.cost(x, &r);
        Ok(LmState {
            r,
            r_trial,
            j,
            trial,
            cost,
            lambda: params.initial_damping,
            approximate: problem.has_approximate_jacobian(),
            iterations: 0,
            newton_step: None,
            small_step: None,
            slow: 0,
        })
    }

    /// Tries damped steps from `x`, the damping growing, until one lowers the cost (accepted:
    /// true) or the damping exceeds its limit (false).
    fn damped_step<P: LeastSquares + ?Sized>(
        &mut self,
        problem: &mut P,
        x: &mut [f64],
        normal: &NormalEquations,
        std: &[f64],
        constraints: &Constraints,
        params: &LmParams,
    ) -> bool {
        loop {
            let m = normal.damped(self.lambda, params.damping);
            match bounded_step(&m, &normal.g, |c, step| constraints.blocked(x, c, step)) {
                // A singular damped matrix: more damping makes it definite.
                None => self.lambda *= 10.0,
                Some(delta) => {
                    constraints.step_into(x, &delta, &mut self.trial);
                    // A point where the model cannot be evaluated is rejected like a worse one.
                    let cost1 = match problem.residuals_into(&self.trial, &mut self.r_trial) {
                        Ok(()) => constraints.cost(&self.trial, &self.r_trial),
                        Err(_) => f64::NAN,
                    };
                    if cost1.is_finite() && cost1 < self.cost {
                        self.accept(problem, x, cost1, std, params);
                        return true;
                    }
                    self.lambda *= params.damping_increase;
                }
            }
            if self.lambda > params.max_damping {
                return false;
            }
        }
    }

    /// Moves `x` to the trial point of cost `cost1`, lowers the damping and updates what the
    /// Jacobian choice, the stall test and the convergence tests remember of the step.
    fn accept<P: LeastSquares + ?Sized>(
        &mut self,
        problem: &mut P,
        x: &mut [f64],
        cost1: f64,
        std: &[f64],
        params: &LmParams,
    ) {
        let improvement = self.cost - cost1;
        let relative = improvement / self.cost.max(1e-300);
        let moved = (0..x.len())
            .map(|c| (self.trial[c] - x[c]).abs() / std.get(c).copied().unwrap_or(f64::INFINITY))
            .fold(0.0, f64::max);
        x.copy_from_slice(&self.trial);
        std::mem::swap(&mut self.r, &mut self.r_trial);
        self.cost = cost1;
        problem.accept(x);
        self.lambda = (self.lambda / params.damping_decrease).max(MIN_DAMPING);
        if improvement < params.exact_jacobian_below {
            self.approximate = false;
        }
        self.slow = match params.stall {
            Some(st) if self.cost > st.above_cost && relative < st.gain => self.slow + 1,
            _ => 0,
        };
        self.small_step = params.convergence.and_then(|conv| {
            if relative < conv.tolerance || improvement < conv.min_improvement {
                Some(SmallStep::Improvement(improvement))
            } else if moved < conv.min_step {
                Some(SmallStep::Moved(moved))
            } else {
                None
            }
        });
    }
}

/// The damped step `−m⁻¹g` with the parameters that sit at a bound and would step out of it
/// held (`blocked(c, step)`): solving for the others alone keeps the step a descent direction
/// of the free ones, where clipping the full step to the bounds distorts it and leaves the
/// solver crawling. `None` when the matrix is not positive definite.
fn bounded_step(m: &DMatrix<f64>, g: &DVector<f64>, blocked: impl Fn(usize, f64) -> bool) -> Option<DVector<f64>> {
    let n = g.len();
    let mut held = vec![false; n];
    loop {
        let mut mm = m.clone();
        let mut rhs = -g;
        for c in (0..n).filter(|&c| held[c]) {
            mm.row_mut(c).fill(0.0);
            mm.column_mut(c).fill(0.0);
            mm[(c, c)] = 1.0;
            rhs[c] = 0.0;
        }
        let delta = mm.cholesky()?.solve(&rhs);
        let newly: Vec<usize> = (0..n).filter(|&c| !held[c] && blocked(c, delta[c])).collect();
        if newly.is_empty() {
            return Some(delta);
        }
        newly.into_iter().for_each(|c| held[c] = true);
    }
}

#[cfg(test)]
mod tests {
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    use super::*;

    /// Rosenbrock's function as residuals, `r₁ = 10(y − x²)`, `r₂ = 1 − x`, optionally with
    /// bounds.
    struct Rosenbrock {
        bounds: Option<([f64; 2], [f64; 2])>,
    }

    impl LeastSquares for Rosenbrock {
        fn n_params(&self) -> usize {
            2
        }

        fn n_residuals(&self) -> usize {
            2
        }

        fn residuals_into(&mut self, p: &[f64], r: &mut DVector<f64>) -> Result<()> {
            r[0] = 10.0 * (p[1] - p[0] * p[0]);
            r[1] = 1.0 - p[0];
            Ok(())
        }

        fn jacobian_into(&mut self, p: &[f64], _approximate: bool, j: &mut DMatrix<f64>) -> Result<()> {
            j.copy_from_slice(&[-20.0 * p[0], -1.0, 10.0, 0.0]);
            Ok(())
        }

        fn bounds(&self) -> Option<(&[f64], &[f64])> {
            self.bounds.as_ref().map(|(lo, hi)| (&lo[..], &hi[..]))
        }
    }

    /// Tests tight enough to reach a zero-residual minimum to rounding.
    fn tight() -> LmParams {
        LmParams {
            convergence: Some(ConvergenceParams {
                tolerance: 0.0,
                min_improvement: 0.0,
                min_step: 1e-10,
            }),
            ..LmParams::default()
        }
    }

    #[test]
    fn rosenbrock_reaches_its_minimum() {
        for damping in [Damping::Scaled, Damping::Identity] {
            let mut x = [-1.2, 1.0];
            let report = levenberg_marquardt(
                &mut Rosenbrock { bounds: None },
                &mut x,
                &LmParams { damping, ..tight() },
            )
            .unwrap();
            assert!(report.converged, "{damping:?}: {report:?}");
            assert!(
                (x[0] - 1.0).abs() < 1e-8 && (x[1] - 1.0).abs() < 1e-8,
                "{damping:?}: ended at {x:?}"
            );
        }
    }

    /// With `x ≤ 0.5` the minimum is on the bound: for fixed `x` the cost is least at `y = x²`,
    /// leaving `½(1 − x)²`, which falls up to the bound. At `(0.5, 0.25)` the gradient is
    /// `(−0.5, 0)`, pointing out of the feasible side with a multiplier of 0.5 ≥ 0: the KKT
    /// point.
    #[test]
    fn bounded_rosenbrock_stops_at_the_kkt_point() {
        let mut problem = Rosenbrock {
            bounds: Some(([-2.0, -2.0], [0.5, 2.0])),
        };
        let mut x = [-1.2, 1.0];
        let report = levenberg_marquardt(&mut problem, &mut x, &tight()).unwrap();
        assert!(report.converged, "{report:?}");
        assert!(
            (x[0] - 0.5).abs() < 1e-8 && (x[1] - 0.25).abs() < 1e-8,
            "ended at {x:?}"
        );
        assert!((report.cost - 0.125).abs() < 1e-12, "cost {}", report.cost);
    }

    /// `r = A x − b` with Gaussian priors: the minimum solves `(AᵀA + W) x = Aᵀb + W c`,
    /// `W = diag(1/σ²)`.
    struct Linear {
        a: DMatrix<f64>,
        b: DVector<f64>,
        centre: Vec<f64>,
        sigma: Vec<f64>,
    }

    impl LeastSquares for Linear {
        fn n_params(&self) -> usize {
            self.a.ncols()
        }

        fn n_residuals(&self) -> usize {
            self.a.nrows()
        }

        fn residuals_into(&mut self, x: &[f64], r: &mut DVector<f64>) -> Result<()> {
            *r = &self.a * DVector::from_column_slice(x) - &self.b;
            Ok(())
        }

        fn jacobian_into(&mut self, _x: &[f64], _approximate: bool, j: &mut DMatrix<f64>) -> Result<()> {
            j.copy_from(&self.a);
            Ok(())
        }

        fn prior(&self) -> Option<(&[f64], &[f64])> {
            Some((&self.centre, &self.sigma))
        }
    }

    #[test]
    fn linear_least_squares_match_the_normal_equations() {
        let mut rng = StdRng::seed_from_u64(3);
        let a = DMatrix::from_fn(20, 4, |_, _| rng.random_range(-1.0..1.0));
        let b = DVector::from_fn(20, |_, _| rng.random_range(-1.0..1.0));
        // Infinite standard deviations are no priors; finite ones pull towards the centre.
        for sigma in [f64::INFINITY, 0.3] {
            let centre = vec![0.5, -0.25, 1.0, 0.0];
            let w = DMatrix::from_diagonal_element(4, 4, sigma.powi(-2));
            let expected = (a.transpose() * &a + &w)
                .lu()
                .solve(&(a.transpose() * &b + &w * DVector::from_column_slice(&centre)))
                .unwrap();
            let mut problem = Linear {
                a: a.clone(),
                b: b.clone(),
                centre,
                sigma: vec![sigma; 4],
            };
            let mut x = [0.0; 4];
            let report = levenberg_marquardt(&mut problem, &mut x, &tight()).unwrap();
            assert!(report.converged, "σ = {sigma}: {report:?}");
            for (v, e) in x.iter().zip(expected.iter()) {
                assert!((v - e).abs() < 1e-9, "σ = {sigma}: {x:?}, expected {expected}");
            }
        }
    }

    /// The iteration hook ends the loop, and sees each iteration once.
    #[test]
    fn the_iteration_hook_stops_the_loop() {
        struct Counting {
            inner: Rosenbrock,
            seen: Vec<usize>,
        }
        impl LeastSquares for Counting {
            fn n_params(&self) -> usize {
                2
            }
            fn n_residuals(&self) -> usize {
                2
            }
            fn residuals_into(&mut self, x: &[f64], r: &mut DVector<f64>) -> Result<()> {
                self.inner.residuals_into(x, r)
            }
            fn jacobian_into(&mut self, x: &[f64], a: bool, j: &mut DMatrix<f64>) -> Result<()> {
                self.inner.jacobian_into(x, a, j)
            }
            fn iteration(&mut self, it: &LmIteration<'_>) -> ControlFlow<()> {
                self.seen.push(it.iteration);
                if it.iteration == 3 {
                    ControlFlow::Break(())
                } else {
                    ControlFlow::Continue(())
                }
            }
        }
        let mut problem = Counting {
            inner: Rosenbrock { bounds: None },
            seen: Vec::new(),
        };
        let mut x = [-1.2, 1.0];
        let report = levenberg_marquardt(&mut problem, &mut x, &tight()).unwrap();
        assert_eq!(report.stop, LmStop::Stopped);
        assert_eq!((report.iterations, problem.seen), (3, vec![1, 2, 3]));
    }
}
