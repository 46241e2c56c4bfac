//! Which poses are worth measuring: optimal subsets of a pool of candidate poses for
//! identifying a robot's parameters (optimal experiment design).
//!
//! The identification Jacobian of every candidate ([`samples_jacobian_by_sample`], error models through
//! the deformed kinematics) is expressed in units of the tracker noise per parameter unit,
//! each parameter scaled by its prior standard deviation so that neither millimetres against
//! radians nor compliances against lengths dominate (parameters without a prior, such as the
//! measurement frame, are scaled to a unit root-mean-square sensitivity over the pool and get a
//! vanishing prior). The information of a set of poses is then `M = P + Σ JᵢᵀJᵢ`, `P` the prior
//! information (identity on parameters with a prior) plus what was measured already, and
//! `M⁻¹` the linearised posterior covariance. Criteria:
//!
//! - **D-optimal**: largest `log det M` (the smallest joint confidence region);
//! - **A-optimal**: smallest `trace M⁻¹` (the sum of the posterior variances, each relative to
//!   its prior's);
//! - **uncertainty**: smallest mean posterior variance of the predicted marker positions over a
//!   workspace sample (`trace(G M⁻¹ Gᵀ)` per position, I-optimality): the poses that most
//!   reduce the predicted error where the robot will work.
//!
//! Selection is greedy, every candidate's gain kept up to date with rank-`r` Woodbury updates
//! of `W = M⁻¹ Jᵀ` (a step costs `O(pool · p · r)`, no determinant is recomputed), followed by
//! exchange passes (Fedorov): each chosen pose is taken out and the best candidate put in its
//! place when that improves the criterion, until a pass changes nothing.

use nalgebra::{Cholesky, DMatrix};
use serde::Serialize;

use crate::calibrate::{
    CalibrationParams, IdentifiabilityReport, ParamGroup, ParameterSpace, identifiability, samples_jacobian_by_sample,
};
use crate::data::measurement::Sample;
use crate::error::{Error, Result};
use crate::robot::Robot;

/// What a selection optimises (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Criterion {
    /// Largest `log det M`.
    DOptimal,
    /// Smallest `trace M⁻¹` (prior-scaled parameters).
    AOptimal,
    /// Smallest mean predicted position variance over a workspace sample.
    Uncertainty,
}

impl Criterion {
    /// The name `armcomp plan --method` takes.
    pub fn name(self) -> &'static str {
        match self {
            Criterion::DOptimal => "d-optimal",
            Criterion::AOptimal => "a-optimal",
            Criterion::Uncertainty => "uncertainty",
        }
    }
}

impl std::str::FromStr for Criterion {
    type Err = String;

    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s.trim() {
            "d-optimal" => Ok(Criterion::DOptimal),
            "a-optimal" => Ok(Criterion::AOptimal),
            "uncertainty" => Ok(Criterion::Uncertainty),
            other => Err(format!(
                "unknown selection criterion `{other}`; expected d-optimal, a-optimal or uncertainty"
            )),
        }
    }
}

/// A design whose information matrix cannot be factored: the parameters are not all
/// identifiable from the poses (and priors) given.
fn not_positive_definite() -> Error {
    Error::Degenerate {
        what: "pose selection".into(),
        reason: "the information matrix is not positive definite".into(),
    }
}

/// Prior information on parameters without a prior, relative to the unit root-mean-square
/// sensitivity of one measured coordinate: small enough not to count, large enough to keep
/// `M` invertible.
const NO_PRIOR: f64 = 1e-6;

/// A design problem in scaled coordinates: candidates as blocks of rows of one matrix.
#[derive(Debug, Clone)]
pub struct Design {
    /// Every candidate's rows, stacked (information units: `Σ rowsᵀ rows` adds to `M`).
    pub rows: DMatrix<f64>,
    /// Candidate `i` owns rows `offsets[i]..offsets[i + 1]`.
    pub offsets: Vec<usize>,
    /// The information before any candidate: prior plus what was measured already (`p × p`).
    pub start: DMatrix<f64>,
    /// `A` of the trace criteria, `trace(A M⁻¹)`: the identity for A-optimal, the workspace's
    /// `GᵀG` per position for uncertainty (`p × p`; unused by D-optimal).
    pub weight: DMatrix<f64>,
}

impl Design {
    fn candidates(&self) -> usize {
        self.offsets.len() - 1
    }

    fn block(&self, i: usize) -> (usize, usize) {
        (self.offsets[i], self.offsets[i + 1] - self.offsets[i])
    }

    /// The information of `set`: `start + Σ JᵢᵀJᵢ`.
    pub fn information(&self, set: &[usize]) -> DMatrix<f64> {
        let mut m = self.start.clone();
        for &i in set {
            let (o, r) = self.block(i);
            let j = self.rows.rows(o, r);
            m += j.transpose() * j;
        }
        m
    }

    /// The criterion's value for `set`: `log det M` (D-optimal, larger is better) or
    /// `trace(A M⁻¹)` (the others, smaller is better).
    pub fn value(&self, set: &[usize], criterion: Criterion) -> Result<f64> {
        let chol = Cholesky::new(self.information(set)).ok_or_else(not_positive_definite)?;
        Ok(match criterion {
            Criterion::DOptimal => 2.0 * chol.l().diagonal().map(f64::ln).sum(),
            _ => (&self.weight * chol.inverse()).trace(),
        })
    }
}

/// What [`optimal_subset`] chose.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SubsetReport {
    /// Candidate indices, in the order they entered the set.
    pub chosen: Vec<usize>,
    /// The criterion's value of the set (see [`Design::value`]).
    pub value: f64,
    /// Its value after the greedy pass, before exchanges.
    pub greedy_value: f64,
    /// Exchanges made.
    pub exchanges: usize,
}

/// `W = M⁻¹ Jᵀ` over all candidates and `V = A W` (for the trace criteria).
struct DesignState {
    w: DMatrix<f64>,
    v: DMatrix<f64>,
}

impl DesignState {
    fn new(design: &Design, set: &[usize], criterion: Criterion) -> Result<Self> {
        let chol = Cholesky::new(design.information(set)).ok_or_else(not_positive_definite)?;
        let w = chol.solve(&design.rows.transpose());
        let v = match criterion {
            Criterion::DOptimal => DMatrix::zeros(0, 0),
            _ => &design.weight * &w,
        };
        Ok(DesignState { w, v })
    }

    /// The gain of adding candidate `i`: `log det(I + JᵢWᵢ)`, or the drop of `trace(A M⁻¹)`,
    /// `trace((I + JᵢWᵢ)⁻¹ WᵢᵀVᵢ)`. `None` when the update is not positive definite.
    fn gain(&self, design: &Design, i: usize, criterion: Criterion) -> Option<f64> {
        let (o, r) = design.block(i);
        let wi = self.w.columns(o, r);
        let s = DMatrix::identity(r, r) + design.rows.rows(o, r) * wi;
        let chol = Cholesky::new(s)?;
        Some(match criterion {
            Criterion::DOptimal => 2.0 * chol.l().diagonal().map(f64::ln).sum(),
            _ => (chol.inverse() * (wi.transpose() * self.v.columns(o, r))).trace(),
        })
    }

    /// Adds candidate `i` to the set (`sign` 1) or takes it out (`sign` −1): Woodbury,
    /// `W' = W ∓ Wᵢ (I ± JᵢWᵢ)⁻¹ JᵢW`.
    fn update(&mut self, design: &Design, i: usize, sign: f64, criterion: Criterion) -> Result<()> {
        let (o, r) = design.block(i);
        let ji = design.rows.rows(o, r);
        let wi = self.w.columns(o, r).into_owned();
        let s = DMatrix::identity(r, r) + (ji * &wi) * sign;
        let s_inv = s.try_inverse().ok_or_else(|| Error::Degenerate {
            what: "pose selection".into(),
            reason: "a rank update of the information is singular".into(),
        })?;
        let k = s_inv * (ji * &self.w);
        self.w -= (&wi * &k) * sign;
        if criterion != Criterion::DOptimal {
            let vi = self.v.columns(o, r).into_owned();
            self.v -= (vi * &k) * sign;
        }
        Ok(())
    }

    /// The candidate outside `taken` with the largest gain (the first of equals).
    fn best(&self, design: &Design, taken: &[bool], criterion: Criterion) -> Option<(usize, f64)> {
        (0..design.candidates())
            .filter(|&i| !taken[i])
            .filter_map(|i| self.gain(design, i, criterion).map(|g| (i, g)))
            .fold(None, |best, (i, g)| match best {
                Some((_, bg)) if bg >= g => best,
                _ => Some((i, g)),
            })
    }
}

/// The `n` candidates of `design` that optimise `criterion`: greedy, then at most
/// `exchange_passes` exchange passes (see the module documentation). Deterministic: ties go
/// to the lower index.
pub fn optimal_subset(design: &Design, n: usize, criterion: Criterion, exchange_passes: usize) -> Result<SubsetReport> {
    let nc = design.candidates();
    if n > nc {
        return Err(Error::InvalidArgument {
            what: "poses to pick".into(),
            reason: format!("cannot pick {n} from a pool of {nc}"),
        });
    }
    let mut taken = vec![false; nc];
    let mut chosen = Vec::with_capacity(n);
    let mut state = DesignState::new(design, &[], criterion)?;
    for _ in 0..n {
        let Some((best, _)) = state.best(design, &taken, criterion) else {
            break;
        };
        taken[best] = true;
        chosen.push(best);
        state.update(design, best, 1.0, criterion)?;
    }
    let greedy_value = design.value(&chosen, criterion)?;
    let mut exchanges = 0;
    for _ in 0..exchange_passes {
        // A fresh state per pass keeps round-off from accumulating over the updates.
        let mut state = DesignState::new(design, &chosen, criterion)?;
        let mut changed = false;
        for slot in chosen.iter_mut() {
            let out = *slot;
            state.update(design, out, -1.0, criterion)?;
            taken[out] = false;
            let keep = state.gain(design, out, criterion).unwrap_or(f64::NEG_INFINITY);
            let (best, gain) = state.best(design, &taken, criterion).unwrap_or((out, keep));
            // Only a clear improvement counts, so round-off never swaps back and forth.
            let swap = best != out && gain > keep + 1e-9 * keep.abs().max(1e-12);
            let put = if swap { best } else { out };
            if swap {
                exchanges += 1;
                changed = true;
            }
            taken[put] = true;
            *slot = put;
            state.update(design, put, 1.0, criterion)?;
        }
        if !changed {
            break;
        }
    }
    Ok(SubsetReport {
        value: design.value(&chosen, criterion)?,
        chosen,
        greedy_value,
        exchanges,
    })
}

/// Settings of [`select_poses`].
#[derive(Debug, Clone, PartialEq)]
pub struct SelectionParams {
    /// What to optimise.
    pub criterion: Criterion,
    /// The parameters to identify (as `armcomp calibrate --identify`; empty for its default).
    pub identify: Vec<String>,
    /// Standard deviation of the tracker noise per axis (m): weighs the data against the
    /// priors.
    pub measurement_std: f64,
    /// Most exchange passes after the greedy choice (0 for greedy only).
    pub exchange_passes: usize,
}

impl Default for SelectionParams {
    fn default() -> Self {
        SelectionParams {
            criterion: Criterion::DOptimal,
            identify: Vec::new(),
            measurement_std: 1e-4,
            exchange_passes: 10,
        }
    }
}

/// What [`select_poses`] chose and how well the chosen poses (with those measured already)
/// determine the parameters.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SelectionReport {
    /// The criterion optimised.
    pub criterion: Criterion,
    /// Indices into the pool, in the order they entered the set.
    pub chosen: Vec<usize>,
    /// The criterion's value of the set after the greedy pass (scaled units; see
    /// [`Design::value`]).
    pub greedy_value: f64,
    /// The same after the exchanges.
    pub value: f64,
    /// Exchanges the refinement made.
    pub exchanges: usize,
    /// The parameters, in the order of the other vectors.
    pub params: Vec<String>,
    /// Their SI units.
    pub units: Vec<&'static str>,
    /// Their prior standard deviations (SI; infinite without a prior).
    pub prior_std: Vec<f64>,
    /// Their linearised posterior standard deviations (SI) from the priors and the poses
    /// measured already, before the chosen ones.
    pub std_before: Vec<f64>,
    /// The same with the chosen poses measured.
    pub std_after: Vec<f64>,
    /// Root-mean-square predicted standard deviation of the measured 3-D positions over the
    /// workspace sample (m), before and after the chosen poses.
    pub workspace_std_before: f64,
    /// The same after.
    pub workspace_std_after: f64,
    /// The identifiability report a calibration on the chosen and the measured poses would
    /// start from.
    pub identifiability: IdentifiabilityReport,
}

/// One candidate per configuration of `poses`: every marker of the robot measured there.
pub fn pose_candidates(robot: &Robot, poses: &[Vec<f64>]) -> Vec<Vec<Sample>> {
    poses
        .iter()
        .map(|q| crate::calibrate::marker_samples(robot, q))
        .collect()
}

/// Chooses `n` of the candidate poses `pool` (each the samples measured at one pose: its
/// markers, payload and temperature) for identifying `params.identify` of `robot`, given the
/// samples `measured` already. For the uncertainty criterion the predicted position variance
/// is averaged over `workspace` (the pool when empty). See the module documentation.
pub fn select_poses(
    robot: &Robot,
    pool: &[Vec<Sample>],
    n: usize,
    measured: &[Sample],
    workspace: &[Vec<Sample>],
    params: &SelectionParams,
) -> Result<SelectionReport> {
    if !(params.measurement_std.is_finite() && params.measurement_std > 0.0) {
        return Err(Error::InvalidArgument {
            what: "measurement noise".into(),
            reason: format!("must be positive, got {} m", params.measurement_std),
        });
    }
    if let Some(i) = pool.iter().position(Vec::is_empty) {
        return Err(Error::InvalidArgument {
            what: format!("candidate pose {}", i + 1),
            reason: "measures no point".into(),
        });
    }
    let flat: Vec<Sample> = pool.iter().flatten().cloned().collect();
    let work: Vec<Sample> = workspace.iter().flatten().cloned().collect();
    // One Jacobian of the measured samples, the pool's and the workspace's, so that they share
    // their columns: the contacts' fixed points and planes are parameters too.
    let all: Vec<Sample> = measured.iter().chain(&flat).chain(&work).cloned().collect();
    let (jac_all, names, widths) = samples_jacobian_by_sample(robot, &all, &params.identify)?;
    // The rows of `n` samples from sample `from` on.
    let block = |from: usize, n: usize| {
        let r0: usize = widths[..from].iter().sum();
        let r: usize = widths[from..from + n].iter().sum();
        jac_all.rows(r0, r).into_owned()
    };
    let jac = block(measured.len(), flat.len());
    let widths = &widths[measured.len()..measured.len() + flat.len()];
    let p = names.len();
    let space = ParameterSpace::for_samples(robot, &all);
    let selected: Vec<_> = names
        .iter()
        .map(|name| {
            space
                .index(name)
                .map(|k| &space.params[k])
                .expect("selected parameters are in the space")
        })
        .collect();
    let info: Vec<_> = selected.iter().map(|p| &p.info).collect();
    // Scale: the prior's standard deviation, or what gives a unit RMS sensitivity per
    // measured coordinate over the pool.
    let sigma = params.measurement_std;
    let rows_n = jac.nrows().max(1) as f64;
    let scales: Vec<f64> = (0..p)
        .map(|c| {
            let prior = info[c].sigma;
            if prior.is_finite() && prior > 0.0 {
                prior
            } else {
                let rms = jac.column(c).norm() / rows_n.sqrt();
                if rms > 0.0 { sigma / rms } else { 1.0 }
            }
        })
        .collect();
    let scale = |m: DMatrix<f64>, noise: f64| DMatrix::from_fn(m.nrows(), p, |r, c| m[(r, c)] * scales[c] / noise);
    let rows = scale(jac, sigma);
    // A candidate's rows: its samples', as wide as each sample's kind (a position's three, a
    // pose's six, a plane contact's height and tilts).
    let mut offsets = vec![0];
    let mut width = widths.iter();
    for c in pool {
        let rows: usize = width.by_ref().take(c.len()).sum();
        offsets.push(offsets.last().copied().unwrap_or(0) + rows);
    }
    let mut start = DMatrix::from_fn(p, p, |i, k| {
        if i != k {
            0.0
        } else if info[i].sigma.is_finite() && info[i].sigma > 0.0 {
            1.0
        } else {
            NO_PRIOR
        }
    });
    if !measured.is_empty() {
        let m = scale(block(0, measured.len()), sigma);
        start += m.transpose() * m;
    }
    // The workspace's position sensitivities (m per scaled unit), per measured position.
    let (work_from, n_work) = match work.is_empty() {
        true => (measured.len(), flat.len()),
        false => (measured.len() + flat.len(), work.len()),
    };
    let mut g = scale(block(work_from, n_work), 1.0);
    // Contact rows (a socket's distance, a plane's height) move with the robot's parameters as
    // its point does; the contacts' own unknowns (fixed points, planes) are not the robot's.
    for (c, param) in selected.iter().enumerate() {
        if matches!(param.group, ParamGroup::FixedPoint(_) | ParamGroup::Plane(_)) {
            g.column_mut(c).fill(0.0);
        }
    }
    let per_position = (g.transpose() * &g) / n_work.max(1) as f64;
    let design = Design {
        rows,
        offsets,
        start,
        weight: match params.criterion {
            Criterion::Uncertainty => per_position.clone(),
            _ => DMatrix::identity(p, p),
        },
    };
    let subset = optimal_subset(&design, n, params.criterion, params.exchange_passes)?;
    let posterior = |set: &[usize]| -> Result<DMatrix<f64>> {
        Cholesky::new(design.information(set))
            .map(|c| c.inverse())
            .ok_or_else(not_positive_definite)
    };
    let before = posterior(&[])?;
    let after = posterior(&subset.chosen)?;
    let stds = |cov: &DMatrix<f64>| (0..p).map(|c| cov[(c, c)].max(0.0).sqrt() * scales[c]).collect();
    let workspace_std = |cov: &DMatrix<f64>| (&per_position * cov).trace().max(0.0).sqrt();
    let mut chosen_samples: Vec<Sample> = measured.to_vec();
    chosen_samples.extend(subset.chosen.iter().flat_map(|&i| pool[i].iter().cloned()));
    let identifiability = identifiability(
        robot,
        &chosen_samples,
        &CalibrationParams {
            identify: params.identify.clone(),
            measurement_std: sigma,
            ..CalibrationParams::default()
        },
    )?;
    Ok(SelectionReport {
        criterion: params.criterion,
        chosen: subset.chosen,
        greedy_value: subset.greedy_value,
        value: subset.value,
        exchanges: subset.exchanges,
        units: info.iter().map(|i| i.quantity.si_unit()).collect(),
        prior_std: info.iter().map(|i| i.sigma).collect(),
        params: names,
        std_before: stds(&before),
        std_after: stds(&after),
        workspace_std_before: workspace_std(&before),
        workspace_std_after: workspace_std(&after),
        identifiability,
    })
}
