//! The score (Lagrange-multiplier) test: what refitting a fitted model with further parameters
//! would gain, predicted from the Jacobian at the fit, without fitting.
//!
//! At the fit `θ₁` the added parameters `θ₂` sit at their neutral values, so the residuals `r`
//! are the fit's. One Gauss–Newton step of the augmented problem lowers the penalised cost by
//! `gᵀA⁻¹g` (`g = Jᵀr`, `A = JᵀJ + S⁻¹`, residuals in units of the noise); the model's own
//! parameters alone would lower it by `g₁ᵀA₁₁⁻¹g₁` (zero at an exact minimum, where this is
//! the Schur form `g₂ᵀ(A₂₂ − A₂₁A₁₁⁻¹A₁₂)⁻¹g₂`). The difference is what the added parameters
//! are worth to first order: a diagnosis refits only the candidates for which it is large.
//! A fit that stopped short of its minimum (held parameters on their boxes, a budget run out)
//! leaves a drop in its own parameters too; both predictions take the same step, so what the
//! model alone would reach is the baseline the candidate is judged against.
//! A candidate that starts away from the fit (a link bending at its nominal stiffness) is
//! judged by the cost it reaches, not by the drop from where it starts.

use super::space::prior_space;
use super::{CalibrationParams, JacobianForm, Noise, Problem};
use crate::data::measurement::Sample;
use crate::error::Result;
use crate::model::param::ParamInfo;
use crate::robot::Robot;
use nalgebra::{DMatrix, DVector};

/// What adding parameters to a fitted model is predicted to gain.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ScoreTest {
    /// Sum of squared residuals (m²) predicted after refitting with the added parameters
    /// (orientation residuals of pose measurements counted in units of the position noise).
    pub predicted_sse: f64,
    /// The same prediction for the model's own parameters alone (m²): the fit's sum of squares
    /// at a minimum, lower when the fit stopped short of one.
    pub baseline_sse: f64,
}

impl ScoreTest {
    /// Share of the model's RMS that refitting with the added parameters is predicted to
    /// remove.
    pub fn predicted_share(&self) -> f64 {
        let sse = self.baseline_sse;
        if sse > 0.0 {
            1.0 - (self.predicted_sse.clamp(0.0, sse) / sse).sqrt()
        } else {
            0.0
        }
    }
}

/// The score test of the parameters named `added` of `robot`, whose other values are a fit to
/// `samples` and the added ones at their starting values. `params` selects what a refit would
/// identify (the added parameters among it) and its priors; the priors are centred on `robot`.
///
/// Along a parameter whose cost has several minima ([`ParamInfo::multimodal`]: a backlash, a
/// stiffness scale that acts through its inverse) the first order says little, so the model is
/// also evaluated with it at values across its plausible range, the other parameters adjusted
/// to first order; the lowest prediction is kept.
pub fn score_test(
    robot: &Robot,
    samples: &[Sample],
    params: &CalibrationParams,
    added: &[String],
) -> Result<ScoreTest> {
    let space = prior_space(robot, params, samples);
    let selected = space.select(robot, &params.identify)?;
    let problem = Problem::new(robot, &space, samples, Noise::of(params));
    let theta = problem.start()?;
    let (d, e, _) = problem.predict(&theta)?;
    let r = problem.residuals(&d, &e);
    let j = problem.jacobian(&theta, &d, &e, &selected, JacobianForm::Exact)?;
    let mut a = j.tr_mul(&j);
    for (c, &k) in selected.iter().enumerate() {
        let sigma = space.params[k].info.sigma;
        if sigma.is_finite() {
            a[(c, c)] += sigma.powi(-2);
        }
    }
    let is_added = |k: usize| added.contains(&space.params[k].info.name);
    let all: Vec<usize> = (0..selected.len()).collect();
    let own: Vec<usize> = all.iter().copied().filter(|&c| !is_added(selected[c])).collect();
    // In units of the noise: the cost after one Gauss–Newton step in every parameter.
    let g = j.tr_mul(&r);
    let baseline = r.norm_squared() - gauss_newton_drop(&a, &g, &own);
    let mut best = r.norm_squared() - gauss_newton_drop(&a, &g, &all);
    for &k in selected
        .iter()
        .filter(|&&k| is_added(k) && space.params[k].info.multimodal)
    {
        for v in probes(&space.params[k].info) {
            let mut probe = theta.clone();
            probe[k] = v;
            let Ok((d, e, _)) = problem.predict(&probe) else {
                continue;
            };
            let r = problem.residuals(&d, &e);
            let cost = r.norm_squared() - gauss_newton_drop(&a, &j.tr_mul(&r), &own);
            if cost.is_finite() {
                best = best.min(cost);
            }
        }
    }
    let to_m2 = params.measurement_std.powi(2);
    Ok(ScoreTest {
        predicted_sse: best.max(0.0) * to_m2,
        baseline_sse: baseline.max(0.0) * to_m2,
    })
}

/// Values across a multimodal parameter's plausible range (within its bounds): four, evenly
/// spaced on a log scale when the range is positive (a stiffness scale of 0.1 to 10).
fn probes(info: &ParamInfo) -> Vec<f64> {
    let (lo, hi) = (info.plausible.0.max(info.lower), info.plausible.1.min(info.upper));
    if !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return Vec::new();
    }
    (0..4)
        .map(|i| {
            let t = i as f64 / 3.0;
            if lo > 0.0 {
                lo * (hi / lo).powf(t)
            } else {
                lo + (hi - lo) * t
            }
        })
        .collect()
}

/// `gᵀA⁻¹g` over the columns `cols`: the cost drop of one Gauss–Newton step in them. The
/// columns are scaled to unit diagonal and directions the data and priors leave undetermined
/// (relative singular value below 1e-10) dropped, as the fit would hold them.
fn gauss_newton_drop(a: &DMatrix<f64>, g: &DVector<f64>, cols: &[usize]) -> f64 {
    if cols.is_empty() {
        return 0.0;
    }
    let scale: Vec<f64> = cols
        .iter()
        .map(|&c| {
            let d = a[(c, c)];
            if d > 0.0 { d.sqrt().recip() } else { 0.0 }
        })
        .collect();
    let sub = DMatrix::from_fn(cols.len(), cols.len(), |i, k| {
        a[(cols[i], cols[k])] * scale[i] * scale[k]
    });
    let gs = DVector::from_fn(cols.len(), |i, _| g[cols[i]] * scale[i]);
    let svd = sub.svd(true, true);
    let eps = 1e-10 * svd.singular_values.max();
    match svd.solve(&gs, eps) {
        Ok(x) => gs.dot(&x),
        Err(_) => 0.0,
    }
}
