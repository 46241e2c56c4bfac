//! Which combinations of parameters the data cannot determine, and what holds them.

use nalgebra::{DMatrix, DVector, SymmetricEigen};

use super::driver::note_measurement_kinds;
use super::jacobian::typical_scale;
use super::space::prior_space;
use super::{
    Assessment, CalibrationParams, Deficiency, IdentifiabilityReport, JacobianForm, Noise, PRIOR_BOX, ParameterSpace,
    Problem, Undetermined,
};
use crate::data::measurement::Sample;
use crate::error::{Error, Result};
use crate::model::param::Quantity;
use crate::robot::Robot;

/// See [`analyse`]: below this many noise standard deviations over all the data, a typical
/// change of a parameter is not seen. Real columns are many orders of magnitude above it
/// (0.2 and more on the diagnosis sweep's robots), unseen ones at round-off (1e-13).
const UNSEEN: f64 = 1e-6;

/// The normal matrix of the parameters `free` with their priors, `JᵀJ + diag(σ⁻²)` (an
/// unbounded prior adds nothing), `jac` holding the Jacobian columns of `selected`: what the
/// calibration's covariance, the identifiability and the priors' checks invert.
pub(super) fn prior_normal_matrix(
    space: &ParameterSpace,
    jac: &DMatrix<f64>,
    selected: &[usize],
    free: &[usize],
) -> DMatrix<f64> {
    let cols: Vec<usize> = (free.iter())
        .map(|k| {
            selected
                .iter()
                .position(|s| s == k)
                .expect("free parameters are selected")
        })
        .collect();
    let j = DMatrix::from_fn(jac.nrows(), cols.len(), |r, c| jac[(r, cols[c])]);
    let mut a = j.transpose() * &j;
    for (c, &k) in free.iter().enumerate() {
        a[(c, c)] += space.params[k].info.sigma.powi(-2);
    }
    a
}

/// The parameters of `free` with a prior that the data barely determine: with the data their
/// standard deviation (linearised at the start, `jac` holding the columns of `selected`) is
/// still above half their prior's, so the data adds less than three times the prior's
/// information. A model error can push such a parameter far along a direction the data hardly
/// sees (a prismatic joint's length against a marker); its prior then bounds it.
pub(super) fn barely_seen(
    space: &ParameterSpace,
    jac: &DMatrix<f64>,
    selected: &[usize],
    free: &[usize],
) -> Vec<usize> {
    let a = prior_normal_matrix(space, jac, selected, free);
    let Some(chol) = a.cholesky() else {
        return Vec::new();
    };
    let inv = chol.inverse();
    free.iter()
        .enumerate()
        .filter(|&(c, &k)| {
            let sigma = space.params[k].info.sigma;
            sigma.is_finite() && inv[(c, c)].sqrt() > 0.5 * sigma
        })
        .map(|(_, &k)| k)
        .collect()
}

/// Takes out of `free`, one at a time, the parameter whose standard deviation with the data and
/// its prior (linearised at the start, `jac` holding the columns of `selected`, the other free
/// parameters' correlations included) exceeds the whole range its model calls plausible by the
/// most, until none does; returns them with the reason. A prior narrower than that range never
/// lets it: only a parameter without one, or whose prior a scale has widened past the
/// plausible (the evidence's, or `--prior none`), is taken out. Such a parameter is seen by the
/// data only through noise (a joint's compliance when the load's centre of mass lies on the
/// axis), and a fit moves it to values no robot has; held at its start, the fit goes on.
fn undetermined(
    space: &ParameterSpace,
    jac: &DMatrix<f64>,
    selected: &[usize],
    free: &mut Vec<usize>,
) -> Vec<Undetermined> {
    let mut held = Vec::new();
    loop {
        let a = prior_normal_matrix(space, jac, selected, free);
        // Scaled to a unit diagonal with a ridge far below any real information, so that a
        // direction nothing holds (priors widened without bound) reads as a huge standard
        // deviation instead of failing the factorisation.
        let scale: Vec<f64> = (0..free.len()).map(|c| a[(c, c)].sqrt().max(1e-300)).collect();
        let scaled = DMatrix::from_fn(free.len(), free.len(), |i, k| {
            a[(i, k)] / (scale[i] * scale[k]) + if i == k { 1e-12 } else { 0.0 }
        });
        let Some(inv) = scaled.cholesky().map(|chol| chol.inverse()) else {
            return held;
        };
        let worst = (free.iter().enumerate())
            .filter_map(|(c, &k)| {
                let info = &space.params[k].info;
                let range = info.plausible.1 - info.plausible.0;
                let std = inv[(c, c)].sqrt() / scale[c];
                (range.is_finite() && std > range).then_some((c, std / range, std))
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((c, _, std)) = worst else {
            return held;
        };
        let info = &space.params[free[c]].info;
        held.push(Undetermined {
            parameter: info.name.clone(),
            reason: undetermined_reason(
                info,
                format!(
                    "with these data its standard deviation would be {}, more than the whole range its model calls \
                     plausible, {} to {}",
                    info.quantity.readable(std),
                    info.quantity.readable(info.plausible.0),
                    info.quantity.readable(info.plausible.1),
                ),
            ),
        });
        free.remove(c);
    }
}

/// Why `info` is undetermined: `detail`, and what causes it for its kind of parameter.
fn undetermined_reason(info: &crate::model::param::ParamInfo, detail: String) -> String {
    let cause = match info.quantity {
        Quantity::Compliance => {
            "; no pose of the data loads its joint enough: the centre of mass it carries (the load's) lies on or near \
             the joint's axis"
        }
        _ => "",
    };
    format!("undetermined: {detail}{cause}")
}

/// Finds the directions the data cannot determine and decides what to fix (see the module
/// documentation). `jac` holds the columns of `free`.
pub(super) fn analyse(
    space: &ParameterSpace,
    jac: &DMatrix<f64>,
    free: &[usize],
    tol: f64,
) -> (IdentifiabilityReport, Vec<usize>) {
    // A column whose parameter, moved by its typical size, changes the predictions by less
    // than UNSEEN noise standard deviations over all the data is no column: the data cannot
    // see the parameter (a compliance about an axis gravity never loads: its moment is
    // round-off). Scaled to unit norm like the others, it would look independent of them.
    let norms: Vec<f64> = (0..jac.ncols())
        .map(|c| {
            let n = jac.column(c).norm();
            if n * typical_scale(&space.params[free[c]].info) < UNSEEN {
                0.0
            } else {
                n
            }
        })
        .collect();
    let has_prior = |c: usize| space.params[free[c]].info.sigma.is_finite();
    let name = |c: usize| space.params[free[c]].info.name.clone();
    let mut fixed: Vec<usize> = Vec::new(); // column positions
    let mut deficiencies = Vec::new();
    // Scaled normal matrix over a set of columns, its eigen-decomposition, and the null basis.
    let null_space = |cols: &[usize]| -> (SymmetricEigen<f64, nalgebra::Dyn>, Vec<usize>, f64) {
        let scaled = DMatrix::from_fn(jac.nrows(), cols.len(), |r, c| {
            let n = norms[cols[c]];
            if n > 0.0 { jac[(r, cols[c])] / n } else { 0.0 }
        });
        let eig = SymmetricEigen::new(scaled.transpose() * &scaled);
        let max = eig.eigenvalues.iter().copied().fold(0.0, f64::max);
        let null = (0..cols.len())
            .filter(|&i| eig.eigenvalues[i] <= tol * tol * max)
            .collect();
        (eig, null, max)
    };
    let all: Vec<usize> = (0..free.len()).collect();
    let (eig_all, null_all, max_all) = null_space(&all);
    let min_all = eig_all.eigenvalues.iter().copied().fold(f64::INFINITY, f64::min);
    let rank = free.len() - null_all.len();
    let condition_number = if null_all.is_empty() && min_all > 0.0 {
        (max_all / min_all).sqrt()
    } else {
        f64::INFINITY
    };
    // Fix, one at a time, the dominant parameter of a null direction no prior holds.
    loop {
        let active: Vec<usize> = all.iter().copied().filter(|c| !fixed.contains(c)).collect();
        if active.is_empty() {
            break;
        }
        let (eig, null, _) = null_space(&active);
        if null.is_empty() {
            break;
        }
        // Null basis rows of the parameters with priors; a combination of basis vectors that
        // vanishes there is a direction nothing holds.
        let basis = DMatrix::from_fn(active.len(), null.len(), |r, c| eig.eigenvectors[(r, null[c])]);
        let prior_rows: Vec<usize> = (0..active.len()).filter(|&r| has_prior(active[r])).collect();
        let free_direction = if prior_rows.is_empty() {
            Some(basis.column(0).into_owned())
        } else {
            let sub = DMatrix::from_fn(prior_rows.len(), null.len(), |r, c| basis[(prior_rows[r], c)]);
            // Eigenvectors of subᵀ·sub with (numerically) zero eigenvalue span them.
            let gram = (sub.transpose() * &sub).symmetric_eigen();
            (0..null.len())
                .find(|&i| gram.eigenvalues[i] <= 1e-12)
                .map(|i| &basis * gram.eigenvectors.column(i))
        };
        let Some(direction) = free_direction else {
            // Every remaining null direction involves a prior: report them as regularised.
            for v in sparse_basis(&basis) {
                deficiencies.push(Deficiency {
                    combination: combination(&v, &active, &name),
                    action: "regularised".into(),
                    fixed: None,
                });
            }
            break;
        };
        let (pos, _) = direction
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .expect("a direction has entries");
        let col = active[pos];
        deficiencies.push(Deficiency {
            combination: combination(&direction, &active, &name),
            action: "fixed".into(),
            fixed: Some(name(col)),
        });
        fixed.push(col);
    }
    let mut message = String::new();
    let n_equations = jac.nrows();
    if n_equations < free.len() {
        message.push_str(&format!(
            "The data give {n_equations} equations for {} parameters, too few to determine them all. ",
            free.len()
        ));
    }
    if !deficiencies.is_empty() {
        // The largest combinations first: they say most about how the parameters trade off.
        let mut shown: Vec<&Deficiency> = deficiencies.iter().collect();
        shown.sort_by_key(|d| std::cmp::Reverse(d.combination.len()));
        let list: Vec<String> = shown
            .iter()
            .take(10)
            .map(|d| {
                let names: Vec<&str> = d.combination.iter().map(|(n, _)| n.as_str()).collect();
                match &d.fixed {
                    Some(f) => format!("{{{}}} (fixed {f})", names.join(", ")),
                    None => format!("{{{}}} (held by priors)", names.join(", ")),
                }
            })
            .collect();
        let held = deficiencies.iter().filter(|d| d.fixed.is_none()).count();
        let more = deficiencies.len().saturating_sub(list.len());
        message.push_str(&format!(
            "The data cannot determine {} combination(s) of parameters ({} held by priors, {} fixed){}: {}{}.",
            deficiencies.len(),
            held,
            deficiencies.len() - held,
            if more > 0 { "; the largest" } else { "" },
            list.join("; "),
            if more > 0 {
                format!("; and {more} more (the JSON report lists all)")
            } else {
                String::new()
            }
        ));
    }
    let report = IdentifiabilityReport {
        n_equations,
        n_params: free.len(),
        rank,
        condition_number,
        condition_number_free: f64::NAN,
        deficiencies,
        held_by_priors: Vec::new(),
        undetermined: Vec::new(),
        message,
    };
    (report, fixed.iter().map(|&c| free[c]).collect())
}

/// A basis of the column space of `basis` (one null direction per column) that is as sparse as
/// Gauss–Jordan elimination with full pivoting makes it: each vector has one pivot parameter
/// that no other vector contains, so the combinations read like "these few move together"
/// rather than eigenvectors mixing everything.
pub(super) fn sparse_basis(basis: &DMatrix<f64>) -> Vec<DVector<f64>> {
    let mut m = basis.transpose(); // one direction per row
    let (rows, cols) = m.shape();
    let mut used_cols = vec![false; cols];
    for r in 0..rows {
        let mut best = (r, 0, 0.0);
        for i in r..rows {
            for c in (0..cols).filter(|&c| !used_cols[c]) {
                if m[(i, c)].abs() > best.2 {
                    best = (i, c, m[(i, c)].abs());
                }
            }
        }
        let (i, c, v) = best;
        if v == 0.0 {
            break;
        }
        m.swap_rows(r, i);
        used_cols[c] = true;
        let pivot = m[(r, c)];
        let row = m.row(r) / pivot;
        m.set_row(r, &row);
        for k in (0..rows).filter(|&k| k != r) {
            let f = m[(k, c)];
            if f != 0.0 {
                let updated = m.row(k) - row.clone() * f;
                m.set_row(k, &updated);
            }
        }
    }
    (0..rows).map(|r| m.row(r).transpose()).collect()
}

/// The entries of a null direction worth naming (at least a tenth of the largest), largest
/// first, normalised so that the largest is ±1.
pub(super) fn combination(v: &DVector<f64>, cols: &[usize], name: &impl Fn(usize) -> String) -> Vec<(String, f64)> {
    let max = v.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    let sign = v.iter().find(|x| x.abs() == max).map_or(1.0, |x| x.signum());
    let mut out: Vec<(String, f64)> = v
        .iter()
        .enumerate()
        .filter(|(_, x)| x.abs() >= 0.1 * max)
        .map(|(i, x)| (name(cols[i]), x * sign / max))
        .collect();
    out.sort_by(|a, b| b.1.abs().total_cmp(&a.1.abs()));
    out
}

/// The identifiability of the parameters `selected` from the Jacobian `jac` (residuals in units
/// of the noise, columns of `selected`): what cannot be determined (fixed or held by priors)
/// and what is barely determined, with the report saying so.
pub(super) fn assess(space: &ParameterSpace, jac: &DMatrix<f64>, selected: &[usize], tol: f64) -> Assessment {
    let (mut report, fixed) = analyse(space, jac, selected, tol);
    let mut free: Vec<usize> = selected.iter().copied().filter(|k| !fixed.contains(k)).collect();
    // A parameter fixed alone (no other in its null direction) is one the data cannot see.
    let unseen = (report.deficiencies.iter())
        .filter(|d| d.combination.len() == 1)
        .filter_map(|d| d.fixed.as_ref())
        .filter_map(|name| space.params.iter().find(|p| &p.info.name == name))
        .map(|p| Undetermined {
            parameter: p.info.name.clone(),
            reason: undetermined_reason(&p.info, "no row of the data sees it".into()),
        });
    report.undetermined = unseen.collect();
    report
        .undetermined
        .extend(undetermined(space, jac, selected, &mut free));
    if !report.undetermined.is_empty() {
        let sep = if report.message.is_empty() { "" } else { " " };
        let list: Vec<String> = (report.undetermined.iter())
            .map(|u| format!("{} ({})", u.parameter, u.reason))
            .collect();
        report.message.push_str(&format!(
            "{sep}{} parameter(s) the data cannot determine are held at their start value and the fit goes on \
             without them: {}.",
            list.len(),
            list.join("; ")
        ));
    }
    let held = barely_seen(space, jac, selected, &free);
    if !held.is_empty() {
        report.held_by_priors = held.iter().map(|&k| space.params[k].info.name.clone()).collect();
        let sep = if report.message.is_empty() { "" } else { " " };
        report.message.push_str(&format!(
            "{sep}{} parameter(s) the data barely determine are kept within {PRIOR_BOX} prior standard deviations \
             of their start: {}.",
            held.len(),
            report.held_by_priors.join(", ")
        ));
    }
    Assessment { report, free, held }
}

/// The condition number of the normal matrix `a` (priors included) after scaling it to a unit
/// diagonal, and its inverse: infinite on the diagonal and NaN off it for a parameter with a
/// share in a direction the data leave undetermined, whose variance is infinite; all infinite
/// when `a` holds a non-finite entry.
pub(super) fn normal_equations(a: &DMatrix<f64>) -> (f64, DMatrix<f64>) {
    let n = a.nrows();
    // No parameter left free: nothing is ill-conditioned. A non-finite entry (a noise of
    // zero or NaN upstream) would stall the eigen-solver, which iterates until convergence.
    if n == 0 {
        return (1.0, DMatrix::zeros(0, 0));
    }
    if a.iter().any(|v| !v.is_finite()) {
        return (f64::INFINITY, DMatrix::from_element(n, n, f64::INFINITY));
    }
    let scale = DVector::from_iterator(n, (0..n).map(|c| a[(c, c)].sqrt().max(1e-300)));
    let scaled = DMatrix::from_fn(n, n, |i, k| a[(i, k)] / (scale[i] * scale[k]));
    let eig = scaled.clone().symmetric_eigen();
    let (emin, emax) = eig
        .eigenvalues
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), v| (lo.min(*v), hi.max(*v)));
    let condition = if emin > 0.0 {
        (emax / emin).sqrt()
    } else {
        f64::INFINITY
    };
    // Symmetric to the bit, as a covariance is (an LU inverse is not quite); the diagonal is
    // the inverse's own.
    let unscaled =
        |inv: DMatrix<f64>| DMatrix::from_fn(n, n, |i, k| (inv[(i, k)] + inv[(k, i)]) / 2.0 / (scale[i] * scale[k]));
    // A direction the data and priors leave (numerically) undetermined gives an inverse of
    // round-off, whose entries can be anything, negative variances too: the variance of every
    // parameter with a share in such a direction is infinite, the others' the inverse's on the
    // rest of the directions.
    let tiny = 1e-12 * emax.max(f64::MIN_POSITIVE);
    if emin > tiny {
        return match scaled.try_inverse() {
            Some(inv) => (condition, unscaled(inv)),
            None => (condition, DMatrix::from_element(n, n, f64::INFINITY)),
        };
    }
    let determined: Vec<usize> = (0..n).filter(|&k| eig.eigenvalues[k] > tiny).collect();
    let undetermined: Vec<bool> = (0..n)
        .map(|c| (0..n).any(|k| eig.eigenvalues[k] <= tiny && eig.eigenvectors[(c, k)].powi(2) > 1e-12))
        .collect();
    let mut inv = unscaled(DMatrix::from_fn(n, n, |i, j| {
        (determined.iter())
            .map(|&k| eig.eigenvectors[(i, k)] * eig.eigenvectors[(j, k)] / eig.eigenvalues[k])
            .sum()
    }));
    for (c, _) in undetermined.iter().enumerate().filter(|(_, u)| **u) {
        inv.row_mut(c).fill(f64::NAN);
        inv.column_mut(c).fill(f64::NAN);
        inv[(c, c)] = f64::INFINITY;
    }
    (condition, inv)
}

/// How well measurements at the configurations of `samples` (their measured positions are not
/// used) would determine the parameters `params.identify` selects, before any fit: the
/// identifiability report [`calibrate`] starts from (linearised at the robot's values, the
/// measurement frame as the robot file guesses it), with the condition number over the free
/// parameters with their priors. For judging a set of poses before measuring it.
pub fn identifiability(robot: &Robot, samples: &[Sample], params: &CalibrationParams) -> Result<IdentifiabilityReport> {
    if samples.is_empty() {
        return Err(Error::InvalidArgument {
            what: "poses".into(),
            reason: "an identifiability report needs at least one".into(),
        });
    }
    let space = prior_space(robot, params, samples);
    let selected = space.select(robot, &params.identify)?;
    let problem = Problem::new(robot, &space, samples, Noise::of(params));
    let theta = problem.start()?;
    let (d, e, _) = problem.predict(&theta)?;
    let jac = problem.jacobian(&theta, &d, &e, &selected, JacobianForm::Exact)?;
    let Assessment { mut report, free, .. } = assess(&space, &jac, &selected, params.rank_tolerance);
    note_measurement_kinds(robot, &space, &selected, &mut report);
    report.condition_number_free = normal_equations(&prior_normal_matrix(&space, &jac, &selected, &free)).0;
    Ok(report)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_equations_match_a_hand_calculation() {
        // Scaled to a unit diagonal, [[2, 1], [1, 2]] is [[1, ½], [½, 1]]: eigenvalues 3/2 and
        // 1/2, so the condition number is √3; the inverse is [[2, -1], [-1, 2]] / 3.
        let (condition, inv) = normal_equations(&DMatrix::from_row_slice(2, 2, &[2.0, 1.0, 1.0, 2.0]));
        assert!((condition - 3f64.sqrt()).abs() < 1e-12, "{condition}");
        let expected = [2.0 / 3.0, -1.0 / 3.0, -1.0 / 3.0, 2.0 / 3.0];
        assert!(inv.iter().zip(expected).all(|(v, e)| (v - e).abs() < 1e-12), "{inv}");
    }

    #[test]
    fn normal_equations_of_no_parameter_or_of_non_finite_values_do_not_panic() {
        assert_eq!(normal_equations(&DMatrix::zeros(0, 0)), (1.0, DMatrix::zeros(0, 0)));
        let (condition, inv) = normal_equations(&DMatrix::from_row_slice(2, 2, &[f64::NAN, 0.0, 0.0, 1.0]));
        assert_eq!(condition, f64::INFINITY);
        assert_eq!(inv.diagonal().as_slice(), &[f64::INFINITY; 2]);
    }

    #[test]
    fn a_direction_nothing_determines_has_an_infinite_variance_and_the_others_keep_theirs() {
        // Parameters 0 and 1 seen only as their sum (rows [1, 1] twice), parameter 2 alone with
        // weight 4: 0 and 1 are undetermined, 2 has variance 1/4 exactly.
        let a = DMatrix::from_row_slice(3, 3, &[2.0, 2.0, 0.0, 2.0, 2.0, 0.0, 0.0, 0.0, 4.0]);
        let (condition, inv) = normal_equations(&a);
        assert!(condition > 1e6, "{condition}");
        assert_eq!(&inv.diagonal().as_slice()[..2], &[f64::INFINITY; 2]);
        assert!((inv[(2, 2)] - 0.25).abs() < 1e-12, "{inv}");
        // Nothing says how an undetermined parameter varies with a determined one.
        assert!(inv[(0, 2)].is_nan() && inv[(2, 1)].is_nan(), "{inv}");
    }
}
