//! What every predictor does with its training set: check it, standardise it, split it.

use armcomp_core::{Error, FitControl, Limits, Result, TrainingSet};
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use serde::{Deserialize, Serialize};

/// A checked training set: row-major inputs and targets with their sizes.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Samples<'a> {
    pub inputs: &'a [f64],
    pub targets: &'a [f64],
    pub n: usize,
    pub n_inputs: usize,
    pub n_outputs: usize,
    /// One range per input, or empty.
    pub input_ranges: &'a [Option<Limits>],
}

impl<'a> Samples<'a> {
    /// Checks sizes and values of `data`; `min_samples` is what the predictor needs to fit.
    pub fn check(data: &TrainingSet<'a>, min_samples: usize) -> Result<Self> {
        let (d, k) = (data.n_inputs, data.n_outputs);
        if d == 0 || k == 0 {
            return Err(invalid_set(format!(
                "expected at least one input and one output per row, got {d} inputs and {k} outputs"
            )));
        }
        if !data.inputs.len().is_multiple_of(d) {
            return Err(invalid_set(format!(
                "{} input values are not a whole number of rows of {d} inputs",
                data.inputs.len()
            )));
        }
        let n = data.inputs.len() / d;
        if data.targets.len() != n * k {
            return Err(Error::Dimension {
                what: format!("training targets ({n} rows of {k} outputs)"),
                expected: n * k,
                got: data.targets.len(),
            });
        }
        if n < min_samples {
            return Err(invalid_set(format!("expected at least {min_samples} samples, got {n}")));
        }
        for (name, values, width) in [("input", data.inputs, d), ("target", data.targets, k)] {
            if let Some(i) = values.iter().position(|v| !v.is_finite()) {
                return Err(invalid_set(format!(
                    "{name} {} of row {} is {}; expected a finite number",
                    i % width,
                    i / width,
                    values[i]
                )));
            }
        }
        if !data.input_ranges.is_empty() && data.input_ranges.len() != d {
            return Err(Error::Dimension {
                what: format!("training input ranges (one per input, {d} inputs)"),
                expected: d,
                got: data.input_ranges.len(),
            });
        }
        for (j, r) in data.input_ranges.iter().enumerate() {
            if let Some(r) = r
                && !(r.lower.is_finite() && r.upper.is_finite() && r.lower <= r.upper)
            {
                return Err(invalid_set(format!(
                    "range of input {j} is [{}, {}]; expected finite bounds, lower ≤ upper",
                    r.lower, r.upper
                )));
            }
        }
        Ok(Samples {
            inputs: data.inputs,
            targets: data.targets,
            n,
            n_inputs: d,
            n_outputs: k,
            input_ranges: data.input_ranges,
        })
    }

    pub fn input(&self, i: usize) -> &'a [f64] {
        &self.inputs[i * self.n_inputs..(i + 1) * self.n_inputs]
    }
}

/// Spread (rad or m: a milliradian or a millimetre) below which a joint's values in the
/// training data are encoder or measurement jitter: the joint held still, and nothing about it
/// can be learnt.
pub const INPUT_SCALE_FLOOR: f64 = 1e-3;

/// Per-column affine map to zero mean and unit standard deviation, learnt on the training set.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Standardizer {
    /// Column means.
    pub mean: Vec<f64>,
    /// Column scales: standard deviations (1 for constant columns, which then only get centred);
    /// for inputs, 0 marks a column that is ignored (mapped to 0), see
    /// [`fit_inputs`](Self::fit_inputs).
    pub scale: Vec<f64>,
}

impl Standardizer {
    /// Fits the map to the columns of the row-major `values` (`width` columns).
    pub fn fit(values: &[f64], width: usize) -> Self {
        let (mean, sd) = Self::moments(values, width);
        let scale = sd
            .into_iter()
            // A constant column carries no information; scaling it by 1 keeps it harmless.
            .map(|sd| {
                if sd > 1e-12 * (1.0 + sd) && sd.is_normal() {
                    sd
                } else {
                    1.0
                }
            })
            .collect();
        Standardizer { mean, scale }
    }

    /// Column means and standard deviations.
    fn moments(values: &[f64], width: usize) -> (Vec<f64>, Vec<f64>) {
        let n = (values.len() / width).max(1) as f64;
        let mut mean = vec![0.0; width];
        for row in values.chunks_exact(width) {
            for (m, v) in mean.iter_mut().zip(row) {
                *m += v;
            }
        }
        mean.iter_mut().for_each(|m| *m /= n);
        let mut sd = vec![0.0; width];
        for row in values.chunks_exact(width) {
            for ((s, v), m) in sd.iter_mut().zip(row).zip(&mean) {
                *s += (v - m) * (v - m);
            }
        }
        sd.iter_mut().for_each(|s| *s = (*s / n).sqrt());
        (mean, sd)
    }

    /// [`fit`](Self::fit) for joint values (rad or m), each used over its range in `ranges` (one
    /// per column, or empty when unknown):
    /// - A column whose standard deviation is below [`INPUT_SCALE_FLOOR`] held still in the
    ///   data: it is ignored (scale 0), and what is learnt holds whatever value it takes later.
    ///   Its jitter would otherwise be scaled up into a feature, and weights nothing trained
    ///   would act on it once it moves.
    /// - Any other column is scaled by at least the standard deviation of a uniform spread over
    ///   its range, `(upper − lower)/√12`. A column seen at two close values (two extensions of
    ///   a telescope a few millimetres apart) would otherwise have a slope learnt over that gap
    ///   multiplied by the ratio of its range to the gap when queried at the other end.
    pub fn fit_inputs(values: &[f64], width: usize, ranges: &[Option<Limits>]) -> Self {
        let (mean, sd) = Self::moments(values, width);
        let scale = sd
            .into_iter()
            .enumerate()
            .map(|(j, sd)| {
                if sd < INPUT_SCALE_FLOOR {
                    return 0.0;
                }
                let uniform = ranges
                    .get(j)
                    .copied()
                    .flatten()
                    .map_or(0.0, |r| (r.upper - r.lower) / 12f64.sqrt());
                sd.max(uniform)
            })
            .collect();
        Standardizer { mean, scale }
    }

    /// Factor a deviation from column `j`'s mean is multiplied by: `1/scale`, 0 for an ignored
    /// column.
    pub fn gain(&self, j: usize) -> f64 {
        if self.ignores(j) { 0.0 } else { 1.0 / self.scale[j] }
    }

    /// Whether column `j` is ignored (held still in the training data).
    pub fn ignores(&self, j: usize) -> bool {
        self.scale[j] <= 0.0
    }

    /// Standardises `raw` into `out`.
    pub fn apply(&self, raw: &[f64], out: &mut [f64]) {
        for (j, ((o, r), m)) in out.iter_mut().zip(raw).zip(&self.mean).enumerate() {
            *o = if self.ignores(j) { 0.0 } else { (r - m) / self.scale[j] };
        }
    }

    /// Standardises every row of the row-major `values`.
    pub fn apply_rows(&self, values: &[f64]) -> Vec<f64> {
        let mut out = vec![0.0; values.len()];
        for (o, r) in out
            .chunks_exact_mut(self.mean.len())
            .zip(values.chunks_exact(self.mean.len()))
        {
            self.apply(r, o);
        }
        out
    }

    /// Maps standardised values in place back to the original units.
    pub fn restore(&self, values: &mut [f64]) {
        for ((v, m), s) in values.iter_mut().zip(&self.mean).zip(&self.scale) {
            *v = *v * s + m;
        }
    }

    /// Maps standard deviations in place back to the original units.
    pub fn restore_std(&self, values: &mut [f64]) {
        for (v, s) in values.iter_mut().zip(&self.scale) {
            *v *= s;
        }
    }
}

/// Seeded split of `0..n` into (training, held-out) indices; `fraction` of the rows, rounded,
/// is held out, always leaving at least one row to train on.
pub(crate) fn split_indices(n: usize, fraction: f64, rng: &mut StdRng) -> (Vec<usize>, Vec<usize>) {
    let mut order: Vec<usize> = (0..n).collect();
    order.shuffle(rng);
    let held = ((fraction * n as f64).round() as usize).min(n.saturating_sub(1));
    let train = order.split_off(held);
    (train, order)
}

/// The error of a setting `field` that cannot be used, and why.
pub(crate) fn invalid(field: &str, reason: String) -> Error {
    Error::InvalidArgument {
        what: field.into(),
        reason,
    }
}

/// The error of a training set that cannot be used, and why.
fn invalid_set(reason: String) -> Error {
    invalid("training set", reason)
}

/// Checks that a fraction lies in `[0, max]`, naming the field.
pub(crate) fn check_fraction(field: &str, value: f64, max: f64) -> Result<()> {
    if (0.0..=max).contains(&value) {
        Ok(())
    } else {
        Err(invalid(
            field,
            format!("expected a fraction in [0, {max}], got {value}"),
        ))
    }
}

/// Checks that a count is at least `min`, naming the field.
pub(crate) fn check_count(field: &str, value: usize, min: usize) -> Result<()> {
    if value >= min {
        Ok(())
    } else {
        Err(invalid(field, format!("expected at least {min}, got {value}")))
    }
}

/// Checks that a real hyper-parameter is finite and positive, naming the field.
pub(crate) fn check_positive(field: &str, value: f64) -> Result<()> {
    if value.is_finite() && value > 0.0 {
        Ok(())
    } else {
        Err(invalid(
            field,
            format!("expected a finite positive number, got {value}"),
        ))
    }
}

/// Counts the steps of one training loop of `total` steps and reports each to its control.
pub(crate) struct Steps<'c, 'a> {
    control: &'c FitControl<'a>,
    stage: &'static str,
    done: usize,
    total: usize,
}

impl<'c, 'a> Steps<'c, 'a> {
    pub(crate) fn new(control: &'c FitControl<'a>, stage: &'static str, total: usize) -> Self {
        Steps {
            control,
            stage,
            done: 0,
            total,
        }
    }

    /// One more step done.
    pub(crate) fn step(&mut self) {
        self.done += 1;
        self.control.report(self.stage, self.done, self.total);
    }
}
