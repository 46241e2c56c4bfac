//! Gross errors and the robust loss: the noise read from the median residual, the samples far
//! beyond it, a residual drifting with the sample order, and Huber's loss, which lets a few
//! gross errors pull a fit no harder than a sample at its threshold.

use nalgebra::Vector3;
use serde::Serialize;

use super::driver::measured_minus_modelled;
use super::{Problem, Stage, to_meas};
use crate::data::measurement::SampleKind;

/// How each sample's residual enters the fit's cost.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Loss {
    /// Least squares: every sample's squared residual.
    #[default]
    Squared,
    /// Huber's: a sample's squared 3-D residual up to [`HUBER_K`] times the robust noise per
    /// axis ([`robust_noise`] of the fit's own residuals), growing linearly beyond, so that a
    /// gross error pulls the fit as hard as a sample at the threshold and no harder.
    /// Minimised by iteratively reweighted least squares, each round warm-started.
    Huber,
}

/// Huber's threshold in robust noises per axis, on a sample's 3-D residual: Gaussian noise
/// goes beyond it in 3 % of the samples, which then weigh a little less.
pub const HUBER_K: f64 = 3.0;

/// Most reweighting rounds of a Huber fit; they stop earlier once no weight changes by more
/// than [`WEIGHT_TOLERANCE`].
pub(super) const MAX_REWEIGHTS: usize = 8;

/// The change of every weight below which a Huber fit's reweighting has converged.
pub(super) const WEIGHT_TOLERANCE: f64 = 1e-3;

/// A sample whose residual is far beyond the noise: a marker seen through a broken line of
/// sight, a row from another session, a typo.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Outlier {
    /// Its index among the calibration's samples.
    pub sample: usize,
    /// Its 3-D residual, or a plane contact's height (mm).
    pub residual_mm: f64,
    /// That residual over the robust noise per axis (of the heights for a plane contact).
    pub over_noise: f64,
}

/// A residual that changes steadily with the sample order.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Drift {
    /// The change of the residual from the first sample to the last, per axis (mm).
    pub change_mm: [f64; 3],
    /// Its largest t statistic over the axes.
    pub t: f64,
}

/// A 3-D residual this many times the robust noise per axis is a gross error: Gaussian noise
/// gives one that large once in 80 000 samples.
pub const GROSS_ERROR: f64 = 5.0;

/// 1.4826 times the median of `abs` (non-negative values): the standard deviation of
/// Gaussian noise they would come from, which a few gross errors do not inflate.
fn scaled_median(mut abs: Vec<f64>) -> f64 {
    if abs.is_empty() {
        return 0.0;
    }
    let mid = abs.len() / 2;
    let (_, median, _) = abs.select_nth_unstable_by(mid, f64::total_cmp);
    1.4826 * *median
}

/// The robust noise per axis of residuals `errors` (m): 1.4826 times the median absolute
/// residual component, which a few gross errors do not inflate.
pub fn robust_noise(errors: &[Vector3<f64>]) -> f64 {
    scaled_median(errors.iter().flat_map(|e| e.iter().map(|v| v.abs())).collect())
}

/// A residual below this (m) is no gross error whatever the noise: noise-free rows (a
/// simulation without noise) leave residuals of round-off, some of them many times the others.
const NOT_GROSS: f64 = 1e-6;

/// The samples whose residual `sizes[i]` (m) exceeds [`GROSS_ERROR`] times `noise` (and
/// [`NOT_GROSS`]), largest first.
fn beyond(sizes: &[f64], noise: f64) -> Vec<Outlier> {
    if noise <= 0.0 {
        return Vec::new();
    }
    let mut out: Vec<Outlier> = (sizes.iter().enumerate())
        .filter(|&(_, &e)| e > GROSS_ERROR * noise && e > NOT_GROSS)
        .map(|(i, &e)| Outlier {
            sample: i,
            residual_mm: e * 1e3,
            over_noise: e / noise,
        })
        .collect();
    out.sort_by(|a, b| b.residual_mm.total_cmp(&a.residual_mm));
    out
}

/// The samples of `errors` (measured minus modelled, m) whose 3-D residual exceeds
/// [`GROSS_ERROR`] times the robust noise, largest first.
pub fn gross_errors(errors: &[Vector3<f64>]) -> Vec<Outlier> {
    let sizes: Vec<f64> = errors.iter().map(|e| e.norm()).collect();
    beyond(&sizes, robust_noise(errors))
}

/// [`gross_errors`] judged within each kind of sample: in mixed data the sockets' residuals
/// are a tracker's tenth, and one robust noise of both would call every tracker row a gross
/// error. A plane contact's residual has one component, so its noise is the heights' own
/// (the robust noise per axis of a 3-D check would be that of two zero components).
pub(super) fn gross_errors_by_kind(errors: &[Vector3<f64>], kinds: &[SampleKind]) -> Vec<Outlier> {
    let mut out: Vec<Outlier> = (SampleKind::ALL.into_iter())
        .flat_map(|kind| {
            let index: Vec<usize> = (0..errors.len()).filter(|&i| kinds[i] == kind).collect();
            let own: Vec<Vector3<f64>> = index.iter().map(|&i| errors[i]).collect();
            let found = match kind {
                SampleKind::Plane => {
                    let heights: Vec<f64> = own.iter().map(|e| e.norm()).collect();
                    beyond(&heights, scaled_median(heights.clone()))
                }
                _ => gross_errors(&own),
            };
            found.into_iter().map(move |o| Outlier {
                sample: index[o.sample],
                ..o
            })
        })
        .collect();
    out.sort_by(|a, b| b.residual_mm.total_cmp(&a.residual_mm));
    out
}

/// A linear trend of the residuals `errors` (m) over the sample order, when one axis' slope
/// is more than 5 standard errors from zero and moves the residual by more than twice the
/// robust noise over the data: what a tracker drifting over a session leaves. (Poses measured
/// in workspace order leave the same trend; the report says so.)
pub fn drift(errors: &[Vector3<f64>]) -> Option<Drift> {
    let n = errors.len();
    if n < 10 {
        return None;
    }
    let noise = robust_noise(errors);
    let t_mean = (n as f64 - 1.0) / 2.0;
    let stt: f64 = (0..n).map(|i| (i as f64 - t_mean).powi(2)).sum();
    let mut change_mm = [0.0; 3];
    let mut t_max: f64 = 0.0;
    let mut big = false;
    for a in 0..3 {
        let mean = errors.iter().map(|e| e[a]).sum::<f64>() / n as f64;
        let slope = errors
            .iter()
            .enumerate()
            .map(|(i, e)| (i as f64 - t_mean) * (e[a] - mean))
            .sum::<f64>()
            / stt;
        let sse: f64 = errors
            .iter()
            .enumerate()
            .map(|(i, e)| (e[a] - mean - slope * (i as f64 - t_mean)).powi(2))
            .sum();
        let se = (sse / (n as f64 - 2.0) / stt).sqrt();
        let change = slope * (n as f64 - 1.0);
        change_mm[a] = change * 1e3;
        if se > 0.0 {
            let t = (slope / se).abs();
            if t > 5.0 && change.abs() > 2.0 * noise {
                big = true;
            }
            t_max = t_max.max(t);
        }
    }
    big.then_some(Drift { change_mm, t: t_max })
}

impl Problem<'_> {
    /// The square roots of Huber's weights of `stage`'s samples: 1 within [`HUBER_K`] robust
    /// noises of their 3-D residual `e`, `√(HUBER_K σ̂ / |e|)` beyond (the weight that makes
    /// a squared residual's gradient Huber's).
    pub(super) fn huber_weights(&self, stage: &Stage) -> Vec<f64> {
        let predicted = to_meas(&stage.d.frames, self.samples, &stage.e.world);
        let errors = measured_minus_modelled(&self.targets(&stage.d, &predicted), &predicted);
        // Each kind against its own robust noise (see `gross_errors_by_kind`).
        let of_kind = |fixed: bool| -> Vec<Vector3<f64>> {
            (errors.iter().zip(&self.fixed))
                .filter(|(_, f)| f.is_some() == fixed)
                .map(|(e, _)| *e)
                .collect()
        };
        let thresholds = [false, true].map(|fixed| HUBER_K * robust_noise(&of_kind(fixed)));
        errors
            .iter()
            .zip(&self.fixed)
            .map(|(e, fixed)| {
                let threshold = thresholds[usize::from(fixed.is_some())];
                let u = e.norm();
                if threshold > 0.0 && u > threshold {
                    (threshold / u).sqrt()
                } else {
                    1.0
                }
            })
            .collect()
    }

    /// Calls `scale(row, w)` for every residual row of a sample whose weight is not 1 (its
    /// position rows and its orientation rows), `w` the square root of the product of its
    /// robust weight and the weight its kind's noise gives it: for a position row with its
    /// own standard deviation `s`, `σ / s` (the row whitened by `s` instead of `σ`).
    pub(super) fn weigh_rows(&self, mut scale: impl FnMut(usize, f64)) {
        if self.weights.is_empty() && self.kind_weights.is_empty() && !self.own_std {
            return;
        }
        let weight = |i: usize| self.weights.get(i).unwrap_or(&1.0) * self.kind_weights.get(i).unwrap_or(&1.0);
        for i in 0..self.samples.len() {
            let own = self.own_std(i);
            let robust = self.weights.get(i).unwrap_or(&1.0);
            for (axis, row) in self.position_range(i).enumerate() {
                let w = own.map_or_else(|| weight(i), |s| robust * self.sigma / s[axis]);
                if w != 1.0 {
                    scale(row, w);
                }
            }
        }
        for (k, &i) in self.oriented.iter().enumerate() {
            let w = weight(i);
            if w != 1.0 {
                self.turn_range(k).for_each(|row| scale(row, w));
            }
        }
    }
}
