//! The measurement noise and the priors' scales chosen from the data: type-II maximum
//! likelihood (MacKay's evidence iterations) on the calibration problem linearised at its fit.
//!
//! With the noise `σ` per axis and, for every [`PriorGroup`], a factor `s_g` on the prior
//! standard deviations `σ₀ₖ` of its parameters, the linearised model's evidence is largest
//! where
//!
//! - `σ² = ‖r‖² / (N − γ)`, the residual variance with the `γ` parameters the data
//!   determine subtracted from the `N` equations, and
//! - `s_g² = Σₖ∈g (Δθₖ/σ₀ₖ)² / γ_g`, the spread of the group's moves over the number of them
//!   the data determine,
//!
//! where `γₖ = 1 − (A⁻¹)ₖₖ / σₖ²` with `A = JᵀJ/σ² + diag(1/σₖ²)` (MacKay, *Bayesian
//! interpolation*, 1992). The fit and these updates alternate, each fit starting where the last
//! ended, until no hyper-parameter changes by more than a few percent.

use super::{Calibration, CalibrationParams, IterationInfo, Linearisation, ParameterSpace, PriorGroup, calibrate};
use crate::data::measurement::Sample;
use crate::error::Result;
use crate::robot::Robot;
use nalgebra::DMatrix;
use nalgebra::linalg::SymmetricEigen;
use serde::Serialize;

/// Which parameters share a prior scale.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Grouping {
    /// One scale per [`PriorGroup`]: every length of the chain alike, every angle alike.
    Groups,
    /// One scale per chain parameter (automatic relevance determination), one per group for
    /// the rest: a few large manufacturing errors among many small ones, as real arms have
    /// them, are not shrunk towards the many.
    PerParameter,
}

/// Settings of [`calibrate_with_evidence`].
#[derive(Debug, Clone, PartialEq)]
pub struct EvidenceParams {
    /// Which parameters share a prior scale.
    pub grouping: Grouping,
    /// Estimate the noise (otherwise the calibration's `measurement_std` is kept).
    pub estimate_noise: bool,
    /// Estimate one prior scale per group (otherwise the calibration's priors are kept).
    pub estimate_priors: bool,
    /// Most rounds of fit and update.
    pub max_rounds: usize,
    /// Done when no hyper-parameter changes by more than this fraction in a round.
    pub tolerance: f64,
    /// The smallest and largest factor a group's prior may be given: a group the data do not
    /// move is held (not pinned exactly), a group they move freely keeps a prior far wider
    /// than its file's.
    pub scale_range: (f64, f64),
}

impl Default for EvidenceParams {
    fn default() -> Self {
        EvidenceParams {
            estimate_noise: true,
            estimate_priors: true,
            grouping: Grouping::PerParameter,
            max_rounds: 30,
            tolerance: 0.02,
            scale_range: (1e-3, 1e3),
        }
    }
}

/// One group's prior scale as chosen.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct GroupScale {
    /// The group.
    pub group: PriorGroup,
    /// Its name in reports (`lengths`, `angles`, `joint_offsets`, an error model's type).
    pub label: String,
    /// The factor on the robot file's prior standard deviations of its parameters.
    pub scale: f64,
    /// Its free parameters.
    pub n_params: usize,
    /// How many of them the data determine (`γ_g`, 0 to `n_params`).
    pub determined: f64,
}

/// One parameter's prior scale, with one scale per parameter.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParameterScale {
    /// The parameter.
    pub name: String,
    /// The factor on its file's prior standard deviation.
    pub scale: f64,
    /// How far the data determine it (0 to 1).
    pub determined: f64,
}

/// What the evidence iterations chose.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct EvidenceReport {
    /// Whether the noise was estimated (otherwise it is the declared one, or every measured
    /// position carries its own standard deviations and none is shared).
    pub noise_estimated: bool,
    /// The noise standard deviation per axis (mm).
    pub noise_mm: f64,
    /// Its standard error (mm), from the residual degrees of freedom.
    pub noise_std_mm: f64,
    /// The equations of the measured positions (or plane heights) the parameters leave free,
    /// `N − γ`: what the noise is measured on. Below one the parameters fit every row, the
    /// estimate is driven towards zero with the residuals, and the noise is not determined by
    /// these rows.
    pub noise_dof: f64,
    /// The orientation noise per axis (deg), when the robot measures poses: estimated from
    /// the orientation residuals alone, its own degrees of freedom, as the positions' is.
    pub orientation_noise_deg: Option<f64>,
    /// The position noise per axis of the fixed-point rows (mm), when the data mix them with
    /// measured positions: estimated from their residuals alone (a socket is not a tracker).
    pub fixed_point_noise_mm: Option<f64>,
    /// Its standard error (mm).
    pub fixed_point_noise_std_mm: Option<f64>,
    /// The residual RMS of each axis of the measurement frame (mm) over the measured positions
    /// (zero without any, as with plane contacts alone): unequal values say the tracker is
    /// better along some axes.
    pub rms_per_axis_mm: [f64; 3],
    /// The number of parameters the data determine (`γ`), out of the free ones.
    pub determined: f64,
    /// Free parameters of the fit.
    pub n_free: usize,
    /// Equations (three per measured position).
    pub n_equations: usize,
    /// How the scales were grouped.
    pub grouping: Grouping,
    /// The chosen prior scales, per group with priors (with one scale per parameter, the
    /// geometric mean of the group's).
    pub groups: Vec<GroupScale>,
    /// With one scale per parameter, each free parameter's (empty otherwise).
    pub parameters: Vec<ParameterScale>,
    /// The log evidence of the linearised model at the chosen hyper-parameters (nats; the
    /// parameters without priors contribute a constant, so compare only models that share
    /// them).
    pub log_evidence: f64,
    /// Rounds of fit and update run.
    pub rounds: usize,
    /// Whether the hyper-parameters settled within the tolerance.
    pub converged: bool,
    /// Whether the last fit converged. When it did not, the noise is the residuals' at the
    /// best parameters found, not at a minimum, and the priors' scales are the last
    /// converged fit's (or the first guesses).
    pub fit_converged: bool,
}

/// Quantities of one linearisation at given hyper-parameters.
struct Update {
    /// Per free parameter, how much the data determine it (`γₖ`).
    gamma: Vec<f64>,
    /// Per residual kind (measured positions, orientations, fixed points of mixed data, and
    /// positions weighed by their own standard deviations, whose noise is not estimated): the
    /// squared residuals in SI units, the equations, and the share of the determined
    /// parameters (`γ`) its rows carry.
    kinds: [Kind; 4],
    log_evidence: f64,
}

#[derive(Debug, Clone, Copy, Default)]
struct Kind {
    sse: f64,
    n: f64,
    gamma: f64,
}

impl Kind {
    /// The noise the evidence sets for this kind: `σ² = SSE / (N − γ)`.
    fn noise(&self) -> f64 {
        (self.sse / (self.n - self.gamma).max(1.0)).sqrt().max(1e-12)
    }
}

/// Residual row `i`'s kind (0 measured positions, 1 orientations, 2 fixed points of mixed
/// data, 3 positions with their own standard deviations) and the noise it was whitened by.
fn row_kind(lin: &Linearisation, i: usize) -> (usize, f64) {
    if i >= lin.position_rows {
        return (1, lin.orientation_noise);
    }
    if lin.own_std_samples[lin.position_row_of[i].0] {
        return (3, lin.noise);
    }
    match lin.fixed_point_noise {
        Some(sigma) if lin.fixed_point_samples[lin.position_row_of[i].0] => (2, sigma),
        _ => (0, lin.noise),
    }
}

fn update(lin: &Linearisation) -> Update {
    let n = lin.free.len();
    let mut a: DMatrix<f64> = lin.jacobian.transpose() * &lin.jacobian;
    let alpha: Vec<f64> = lin.prior_sigma.iter().map(|s| s.powi(-2)).collect();
    for c in 0..n {
        a[(c, c)] += alpha[c];
    }
    // The eigen-decomposition gives the inverse's diagonal and the log-determinant at once;
    // directions the data and priors leave at zero curvature (fixed combinations are not in
    // `free`, so only round-off) count as undetermined.
    let eig = SymmetricEigen::new(a);
    let floor = eig.eigenvalues.amax() * 1e-14;
    let mut inv_diag = vec![0.0; n];
    let mut log_det = 0.0;
    for (i, &l) in eig.eigenvalues.iter().enumerate() {
        let l = l.max(floor).max(f64::MIN_POSITIVE);
        log_det += l.ln();
        let v = eig.eigenvectors.column(i);
        for c in 0..n {
            inv_diag[c] += v[c] * v[c] / l;
        }
    }
    let gamma: Vec<f64> = (0..n).map(|c| (1.0 - alpha[c] * inv_diag[c]).clamp(0.0, 1.0)).collect();
    let chi2 = lin.residuals.norm_squared();
    // Each kind's share of γ is the sum of its rows' leverages (J A⁻¹ Jᵀ)ᵢᵢ, so the kinds'
    // noises follow MacKay's update each over its own equations.
    let mut kinds = [Kind::default(); 4];
    let scaled = &lin.jacobian * &eig.eigenvectors;
    let measured_rows = lin.residuals.len() - lin.distance_rows;
    for (i, r) in lin.residuals.iter().take(measured_rows).enumerate() {
        let (k, sigma) = row_kind(lin, i);
        let leverage: f64 = (0..n)
            .map(|l| scaled[(i, l)].powi(2) / eig.eigenvalues[l].max(floor).max(f64::MIN_POSITIVE))
            .sum();
        kinds[k].sse += (r * sigma).powi(2);
        kinds[k].n += 1.0;
        kinds[k].gamma += leverage;
    }
    let log_noise: f64 = [lin.noise, lin.orientation_noise, lin.fixed_point_noise.unwrap_or(1.0)]
        .iter()
        .zip(&kinds)
        .map(|(sigma, kind)| kind.n * (2.0 * std::f64::consts::PI * sigma * sigma).ln())
        .sum();
    debug_assert_eq!(kinds.iter().map(|k| k.n).sum::<f64>(), measured_rows as f64);
    let prior: f64 = lin
        .free
        .iter()
        .zip(&alpha)
        .map(|(&k, &al)| {
            if al > 0.0 {
                al * (lin.theta[k] - lin.centre[k]).powi(2)
            } else {
                0.0
            }
        })
        .sum();
    let log_alpha: f64 = alpha.iter().filter(|&&al| al > 0.0).map(|al| al.ln()).sum();
    // In the parameters' SI units: A above is JᵀJ/σ² + α (the Jacobian is of r/σ).
    let log_evidence = -0.5 * chi2 - 0.5 * prior + 0.5 * log_alpha - 0.5 * log_det - 0.5 * log_noise;
    Update {
        gamma,
        kinds,
        log_evidence,
    }
}

/// The number of parameters the data determine at the linearisation `lin` under the priors
/// it was fitted with (`γ = Σₖ γₖ`, the effective number of parameters): each free parameter
/// without a prior counts one, one its prior holds where it starts counts none.
pub fn effective_parameters(lin: &Linearisation) -> f64 {
    update(lin).gamma.iter().sum()
}

/// Calibrates `robot` on `samples` as `params` says, with the noise and the prior scale of
/// every group of selected parameters chosen by the evidence (see the module documentation).
/// `params.measurement_std` is the first guess of the noise, and its value when
/// `evidence.estimate_noise` is off; `params.prior_scale` and `group_prior_scales` are the
/// first guess of the scales. Deterministic.
pub fn calibrate_with_evidence(
    robot: &Robot,
    samples: &[Sample],
    params: &CalibrationParams,
    evidence: &EvidenceParams,
    observer: &mut dyn FnMut(&IterationInfo),
) -> Result<(Calibration, EvidenceReport)> {
    let mut p = params.clone();
    // Scales are estimated relative to the file's priors as scaled by `prior_scale`.
    let estimate_priors = evidence.estimate_priors && p.use_priors;
    let mut fit = calibrate(robot, samples, &p, observer)?;
    let mut rounds = 1;
    let mut converged = false;
    // A fit that did not converge still updates the noise from its residuals: a first guess
    // far below the noise is what most often keeps it from converging (every residual many
    // times its noise makes the convergence test, in standard deviations, as many times
    // stricter, and more so the more rows there are), and the next fit, weighed by the
    // estimate, then converges. The priors' scales need a minimum and wait for one. A round
    // that changes nothing ends the rounds, converged or not; the report says which.
    loop {
        let at_minimum = fit.report.converged;
        if !at_minimum && !evidence.estimate_noise {
            break;
        }
        let lin = &fit.linearisation;
        let u = update(lin);
        let mut changed: f64 = 0.0;
        let mut next = p.clone();
        if evidence.estimate_noise {
            // Rows that all carry their own standard deviations leave the shared noise unused.
            if u.kinds[0].n > 0.0 {
                let noise = u.kinds[0].noise().max(1e-9);
                changed = changed.max((noise / p.measurement_std).ln().abs());
                next.measurement_std = noise;
            }
            if u.kinds[1].n > 0.0 {
                let noise = u.kinds[1].noise().max(1e-9);
                changed = changed.max((noise / p.orientation_std).ln().abs());
                next.orientation_std = noise;
            }
            if let (true, Some(old)) = (u.kinds[2].n > 0.0, lin.fixed_point_noise) {
                let noise = u.kinds[2].noise().max(1e-9);
                changed = changed.max((noise / old).ln().abs());
                next.fixed_point_std = Some(noise);
            }
        }
        if estimate_priors && at_minimum {
            let scales = scale_updates(lin, &u, &p, evidence);
            for (g, s, determined) in &scales {
                // A scale the data hardly see (a pruned parameter on its way to the smallest
                // scale) changes the fit by nothing: it does not keep the rounds going.
                if *determined >= 0.01 {
                    changed = changed.max((s / current_scale(&p, *g)).ln().abs());
                }
            }
            next.group_prior_scales = scales.into_iter().map(|(g, s, _)| (g, s)).collect();
        }
        if changed <= evidence.tolerance.ln_1p() {
            converged = at_minimum;
            break;
        }
        if rounds >= evidence.max_rounds {
            break;
        }
        next.start = Some(lin.theta.clone());
        // Later rounds start at a fit of nearly the same problem: restarts found what they
        // could in the first.
        next.restarts = 0;
        fit = calibrate(robot, samples, &next, observer)?;
        p = next;
        rounds += 1;
    }
    let report = report(robot, samples, &fit, &p, evidence, rounds, converged);
    if report.noise_estimated && report.noise_dof < 1.0 {
        fit.report.warnings.push(format!(
            "the noise is not determined by these rows: the parameters fit all but {:.2} of the position \
             equations, so its estimate ({:.4} mm) only follows the residuals towards zero; declare the \
             instrument's noise or measure more rows",
            report.noise_dof.max(0.0),
            report.noise_mm
        ));
    }
    Ok((fit, report))
}

fn report(
    robot: &Robot,
    samples: &[Sample],
    fit: &Calibration,
    p: &CalibrationParams,
    evidence: &EvidenceParams,
    rounds: usize,
    converged: bool,
) -> EvidenceReport {
    let lin = &fit.linearisation;
    let u = update(lin);
    let dof = (u.kinds[0].n - u.kinds[0].gamma).max(1.0);
    let space = ParameterSpace::for_samples(robot, samples);
    // Per group: parameters, determined, and the sum of log scales (for the geometric mean).
    let mut groups: Vec<(GroupScale, f64)> = Vec::new();
    let mut parameters = Vec::new();
    for (c, g) in lin.groups.iter().enumerate() {
        if !lin.prior_sigma[c].is_finite() {
            continue;
        }
        let scale = current_scale(p, hyper_group(lin, c, evidence.grouping)) * p.prior_scale;
        if hyper_group(lin, c, evidence.grouping) != *g {
            parameters.push(ParameterScale {
                name: space.params[lin.free[c]].info.name.clone(),
                scale,
                determined: u.gamma[c],
            });
        }
        match groups.iter_mut().find(|(s, _)| s.group == *g) {
            Some((s, logs)) => {
                s.n_params += 1;
                s.determined += u.gamma[c];
                *logs += scale.ln();
            }
            None => groups.push((
                GroupScale {
                    group: *g,
                    label: g.label(robot),
                    scale,
                    n_params: 1,
                    determined: u.gamma[c],
                },
                scale.ln(),
            )),
        }
    }
    let mut groups: Vec<GroupScale> = groups
        .into_iter()
        .map(|(mut s, logs)| {
            s.scale = (logs / s.n_params as f64).exp();
            s
        })
        .collect();
    groups.sort_by_key(|g| g.group);
    // Measured positions only: a fixed point's residual is not along a tracker's axes.
    let (mut axis, mut rows) = ([0.0; 3], [0usize; 3]);
    for (i, r) in lin.residuals.iter().take(lin.position_rows).enumerate() {
        if let ((0, sigma), (_, Some(a))) = (row_kind(lin, i), lin.position_row_of[i]) {
            axis[a] += (r * sigma).powi(2);
            rows[a] += 1;
        }
    }
    // The samples whose residuals count (every axis has one row of each).
    let n = rows[0].max(1) as f64;
    EvidenceReport {
        noise_estimated: evidence.estimate_noise && u.kinds[0].n > 0.0,
        noise_mm: lin.noise * 1e3,
        noise_std_mm: lin.noise * 1e3 / (2.0 * dof).sqrt(),
        noise_dof: u.kinds[0].n - u.kinds[0].gamma,
        orientation_noise_deg: (u.kinds[1].n > 0.0).then(|| lin.orientation_noise.to_degrees()),
        fixed_point_noise_mm: lin.fixed_point_noise.map(|s| s * 1e3),
        fixed_point_noise_std_mm: lin
            .fixed_point_noise
            .map(|s| s * 1e3 / (2.0 * (u.kinds[2].n - u.kinds[2].gamma).max(1.0)).sqrt()),
        rms_per_axis_mm: axis.map(|s| (s / n).sqrt() * 1e3),
        fit_converged: fit.report.converged,
        determined: u.gamma.iter().sum(),
        n_free: lin.free.len(),
        n_equations: lin.residuals.len(),
        grouping: evidence.grouping,
        groups,
        parameters,
        log_evidence: u.log_evidence,
        rounds,
        converged,
    }
}

/// The factor `params` puts on the priors of hyper-parameter group `g` beyond its
/// `prior_scale`.
fn current_scale(params: &CalibrationParams, g: PriorGroup) -> f64 {
    params
        .group_prior_scales
        .iter()
        .filter(|(h, _)| *h == g)
        .map(|(_, s)| s)
        .product()
}

/// The group whose scale free parameter `c` of `lin` shares: its own for chain parameters with
/// one scale per parameter.
fn hyper_group(lin: &Linearisation, c: usize, grouping: Grouping) -> PriorGroup {
    match (grouping, lin.groups[c]) {
        (Grouping::PerParameter, PriorGroup::JointOffsets | PriorGroup::Lengths | PriorGroup::Angles) => {
            PriorGroup::Parameter(lin.free[c])
        }
        (_, g) => g,
    }
}

/// MacKay's update of every hyper-parameter group's scale at the linearisation `lin`, fitted
/// with `params`: the new scale and how many parameters of the group the data determine.
fn scale_updates(
    lin: &Linearisation,
    u: &Update,
    params: &CalibrationParams,
    evidence: &EvidenceParams,
) -> Vec<(PriorGroup, f64, f64)> {
    let mut groups: Vec<PriorGroup> = (0..lin.free.len())
        .filter(|&c| lin.prior_sigma[c].is_finite())
        .map(|c| hyper_group(lin, c, evidence.grouping))
        .collect();
    groups.sort();
    groups.dedup();
    let (lo, hi) = evidence.scale_range;
    groups
        .into_iter()
        .map(|g| {
            let old = current_scale(params, g);
            let (mut moves, mut gamma) = (0.0, 0.0);
            for (c, &k) in lin.free.iter().enumerate() {
                if hyper_group(lin, c, evidence.grouping) == g && lin.prior_sigma[c].is_finite() {
                    // In units of the group's unscaled prior.
                    let sigma0 = lin.prior_sigma[c] / old;
                    moves += ((lin.theta[k] - lin.centre[k]) / sigma0).powi(2);
                    gamma += u.gamma[c];
                }
            }
            let scale = if gamma > 1e-12 { (moves / gamma).sqrt() } else { lo };
            // Bounded relative to the file's priors times `prior_scale`.
            (g, scale.clamp(lo, hi), gamma)
        })
        .collect()
}
