//! The Levenberg–Marquardt stages: bounded steps, priors, the convergence tests.

use nalgebra::{DMatrix, DVector};

use crate::error::Result;

use super::*;

impl Problem<'_> {
    /// Levenberg–Marquardt over the parameters `free`, from `stage`, with priors centred at
    /// `theta0`; leaves the best parameters found in `stage`.
    pub(super) fn levenberg_marquardt(
        &self,
        stage: &mut Stage,
        theta0: &[f64],
        free: &[usize],
        params: &CalibrationParams,
        observer: &mut dyn FnMut(&IterationInfo),
    ) -> Result<StageOutcome> {
        let space = self.space;
        let prior_w: Vec<f64> = free.iter().map(|&k| 1.0 / space.params[k].info.sigma).collect();
        let cost_of = |theta: &[f64], r: &DVector<f64>| self.cost_of(theta, theta0, free, r);
        let Stage {
            theta,
            d,
            e,
            iterations,
        } = stage;
        let mut r = self.residuals(&to_meas(&d.t_meas_base, &e.world));
        let mut cost = cost_of(theta, &r);
        let mut lambda = 1e-3;
        let mut converged = false;
        // Why the last accepted step was small, when it was: the step test. Convergence needs
        // it and the gradient test at the point the step reached.
        let mut small_step: Option<String> = None;
        // Deformed robots iterate on the fast form while it makes progress, and finish on the
        // exact one, so the minimum and the convergence test are those of the true model.
        let mut form = if self.robot.error_models().is_empty() {
            JacobianForm::Exact
        } else {
            JacobianForm::HeldDeformation
        };
        let stop_reason = loop {
            crate::interrupt::check()?;
            let j = self.jacobian(theta, d, e, free, form)?;
            let mut a = j.transpose() * &j;
            let mut g = j.transpose() * &r;
            for (c, (&k, w)) in free.iter().zip(&prior_w).enumerate() {
                a[(c, c)] += w * w;
                g[c] += w * w * (theta[k] - theta0[k]);
            }
            let floor = 1e-12 * a.diagonal().max().max(1e-300);
            // Standard deviations (in units of the noise) from the undamped normal matrix, to
            // judge whether a step still moves anything that matters.
            let std: Vec<f64> = match a.clone().cholesky() {
                Some(c) => {
                    let inv = c.inverse();
                    (0..free.len()).map(|i| inv[(i, i)].max(0.0).sqrt()).collect()
                }
                None => vec![f64::INFINITY; free.len()],
            };
            // The gradient test, made independent of scale and correlation: how far the full
            // Newton step from here (the bounds respected) would move each parameter, in its
            // standard deviations. At a minimum it moves nothing that matters; a damped crawl
            // far from one leaves a large step. Correlated parameters whose gradients cancel
            // in combination pass, and a parameter held at its bound by the data passes.
            // Where the matrix is singular, each parameter's gradient over its own curvature.
            let blocked = |c: usize, step: f64| {
                let b = &space.params[free[c]].info;
                let v = theta[free[c]];
                (v <= b.lower && step < 0.0) || (v >= b.upper && step > 0.0)
            };
            let newton = bounded_step(&a, &g, blocked).unwrap_or_else(|| {
                DVector::from_iterator(free.len(), (0..free.len()).map(|c| g[c] / a[(c, c)].max(floor)))
            });
            let gradient = newton
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
                .fold(0.0, |m: f64, v| if v.is_nan() { f64::NAN } else { m.max(v) });
            let gradient_ok = gradient <= params.min_step;
            if let Some(step) = small_step.as_ref().filter(|_| gradient_ok) {
                converged = true;
                break format!("{step}, and the Newton step is {gradient:.1e} standard deviations");
            }
            if *iterations >= params.max_iterations {
                break format!(
                    "iteration limit ({}) reached; the Newton step is {gradient:.1e} standard deviations",
                    params.max_iterations
                );
            }
            *iterations += 1;
            let mut accepted = false;
            while lambda <= 1e12 {
                let mut m = a.clone();
                for c in 0..free.len() {
                    m[(c, c)] += lambda * a[(c, c)].max(floor);
                }
                let Some(delta) = bounded_step(&m, &g, blocked) else {
                    lambda *= 10.0;
                    continue;
                };
                // Stop at the first bound the step meets: a scaled damped step still lowers
                // the linear model, where clipping each parameter to its bound distorts the
                // step (rejected, the damping grows, the solver crawls). The parameter that
                // landed on its bound is held there by the next step if it pushes outward.
                let alpha = free.iter().enumerate().fold(1.0f64, |alpha, (c, &k)| {
                    let b = &space.params[k].info;
                    let to = theta[k] + delta[c];
                    if to < b.lower {
                        alpha.min((b.lower - theta[k]) / delta[c])
                    } else if to > b.upper {
                        alpha.min((b.upper - theta[k]) / delta[c])
                    } else {
                        alpha
                    }
                });
                let mut trial = theta.clone();
                for (c, &k) in free.iter().enumerate() {
                    let b = &space.params[k].info;
                    trial[k] = (theta[k] + alpha * delta[c]).clamp(b.lower, b.upper);
                }
                let Ok((d1, e1, pred1)) = self.predict(&trial) else {
                    lambda *= 4.0;
                    continue;
                };
                let r1 = self.residuals(&pred1);
                let cost1 = cost_of(&trial, &r1);
                if cost1.is_finite() && cost1 < cost {
                    let improvement = cost - cost1;
                    let relative = improvement / cost.max(1e-300);
                    let moved = free
                        .iter()
                        .zip(&std)
                        .map(|(&k, sd)| (trial[k] - theta[k]).abs() / sd)
                        .fold(0.0, f64::max);
                    (*theta, *d, *e, r, cost) = (trial, d1, e1, r1, cost1);
                    lambda = (lambda / 3.0).max(1e-12);
                    accepted = true;
                    // Once a step gains less than the noise can tell apart (½χ² by less than
                    // one), the fast form's error matters more than its speed.
                    if improvement < 1.0 {
                        form = JacobianForm::Exact;
                    }
                    small_step = if relative < params.tolerance || improvement < params.min_improvement {
                        Some(format!("the last step improved ½χ² by only {improvement:.2e}"))
                    } else if moved < params.min_step {
                        Some(format!(
                            "the last step moved no parameter by more than {:.1}% of its standard deviation",
                            100.0 * moved
                        ))
                    } else {
                        None
                    };
                    break;
                }
                lambda *= 4.0;
            }
            observer(&IterationInfo {
                iteration: *iterations,
                max_iterations: params.max_iterations,
                rms: (r.norm_squared() / self.samples.len() as f64).sqrt() * params.measurement_std,
                lambda,
            });
            if !accepted && form == JacobianForm::HeldDeformation {
                form = JacobianForm::Exact;
                small_step = None;
                lambda = 1e-3;
                continue;
            }
            if !accepted {
                // No step lowers the cost: a minimum if the gradient vanishes there, otherwise
                // the model cannot be evaluated or differentiated near here.
                converged = gradient_ok && cost.is_finite();
                break if converged {
                    format!("no step lowers the cost further; the Newton step is {gradient:.1e} standard deviations")
                } else {
                    format!(
                        "no step lowers the cost, but the Newton step is {gradient:.1e} standard deviations \
                         (cost {cost:.3e}): not a minimum"
                    )
                };
            }
        };
        Ok(StageOutcome { converged, stop_reason })
    }
}

/// The damped step `−m⁻¹g` with the parameters that sit at a bound and would step out of it
/// held (`blocked(c, step)`): solving for the others alone keeps the step a descent direction
/// of the free ones, where clipping the full step to the bounds distorts it and leaves the
/// solver crawling. `None` when the matrix is not positive definite.
pub(super) fn bounded_step(
    m: &DMatrix<f64>,
    g: &DVector<f64>,
    blocked: impl Fn(usize, f64) -> bool,
) -> Option<DVector<f64>> {
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
