//! A compact L-BFGS minimiser for the Gaussian process hyper-parameters.
//!
//! Hand-written rather than taken from an optimisation crate because the log marginal
//! likelihood's value and gradient come out of one O(n³) Cholesky factorisation and inverse;
//! solvers that ask for the cost and the gradient through separate calls (argmin's
//! `CostFunction` / `Gradient`) would factorise twice per point. Backtracking (Armijo) line
//! search; curvature pairs with `sᵀy ≤ 0` are skipped, which keeps the inverse-Hessian estimate
//! positive definite.

use std::collections::VecDeque;

/// Pairs of steps and gradient changes remembered.
const MEMORY: usize = 8;

/// Relative decrease below which the iteration stops: the likelihood is a sum over hundreds of
/// rows, and hyper-parameters that agree to this level predict the same to far below the noise.
const REL_TOLERANCE: f64 = 1e-7;

/// Minimises `f` from `x0`. `f(x, grad)` returns the value (+∞ where undefined, e.g. a failed
/// factorisation) and writes the gradient. Returns the best point and its value; `on_iteration`
/// is called once per iteration (progress).
pub(crate) fn minimize(
    x0: &[f64],
    max_iterations: usize,
    mut f: impl FnMut(&[f64], &mut [f64]) -> f64,
    mut on_iteration: impl FnMut(),
) -> (Vec<f64>, f64) {
    let n = x0.len();
    let mut x = x0.to_vec();
    let mut g = vec![0.0; n];
    let mut fx = f(&x, &mut g);
    if !fx.is_finite() {
        return (x, f64::INFINITY);
    }
    let mut pairs: VecDeque<(Vec<f64>, Vec<f64>, f64)> = VecDeque::with_capacity(MEMORY);
    let (mut d, mut x_new, mut g_new) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
    let mut alpha = [0.0; MEMORY];
    for _ in 0..max_iterations {
        on_iteration();
        // Two-loop recursion: d = -H g.
        d.iter_mut().zip(&g).for_each(|(d, g)| *d = -g);
        for (a, (s, y, rho)) in alpha.iter_mut().zip(pairs.iter()).rev() {
            *a = rho * dot(s, &d);
            d.iter_mut().zip(y).for_each(|(d, y)| *d -= *a * y);
        }
        let gamma = match pairs.back() {
            Some((s, y, _)) => dot(s, y) / dot(y, y),
            // First step: at most unit length in log-parameter space.
            None => 1.0 / norm(&g).max(1.0),
        };
        d.iter_mut().for_each(|d| *d *= gamma);
        for (a, (s, y, rho)) in alpha.iter().zip(pairs.iter()) {
            let b = rho * dot(y, &d);
            d.iter_mut().zip(s).for_each(|(d, s)| *d += (a - b) * s);
        }
        let mut slope = dot(&g, &d);
        if slope >= 0.0 {
            // Not a descent direction: restart from steepest descent.
            pairs.clear();
            d.iter_mut().zip(&g).for_each(|(d, g)| *d = -g);
            let scale = 1.0 / norm(&d).max(1.0);
            d.iter_mut().for_each(|d| *d *= scale);
            slope = dot(&g, &d);
        }
        let mut t = 1.0;
        let mut accepted = None;
        for _ in 0..30 {
            x_new
                .iter_mut()
                .zip(&x)
                .zip(&d)
                .for_each(|((xn, x), d)| *xn = x + t * d);
            let f_new = f(&x_new, &mut g_new);
            if f_new.is_finite() && f_new <= fx + 1e-4 * t * slope {
                accepted = Some(f_new);
                break;
            }
            t *= 0.5;
        }
        let Some(f_new) = accepted else { break };
        let s: Vec<f64> = x_new.iter().zip(&x).map(|(a, b)| a - b).collect();
        let y: Vec<f64> = g_new.iter().zip(&g).map(|(a, b)| a - b).collect();
        let sy = dot(&s, &y);
        if sy > 1e-12 {
            if pairs.len() == MEMORY {
                pairs.pop_front();
            }
            pairs.push_back((s, y, 1.0 / sy));
        }
        let change = fx - f_new;
        x.copy_from_slice(&x_new);
        g.copy_from_slice(&g_new);
        fx = f_new;
        if change <= REL_TOLERANCE * (1.0 + fx.abs()) || norm(&g) < 1e-6 {
            break;
        }
    }
    (x, fx)
}

fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a * b).sum()
}

fn norm(a: &[f64]) -> f64 {
    dot(a, a).sqrt()
}
