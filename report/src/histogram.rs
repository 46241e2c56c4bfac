//! Binning of the error histograms the report pages plot.

/// Counts of `values` in `bins` bins of `width` from zero; the last bin takes the overflow.
pub fn bin_counts(values: &[f64], width: f64, bins: usize) -> Vec<usize> {
    let mut counts = vec![0usize; bins];
    for v in values {
        counts[((v / width) as usize).min(bins - 1)] += 1;
    }
    counts
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn values_fall_in_their_bin_and_overflow_in_the_last() {
        // Bins of 0.5 from zero: [0, 0.5), [0.5, 1), [1, 1.5); 0.5 opens the second, 7 overflows.
        assert_eq!(bin_counts(&[0.0, 0.49, 0.5, 1.2, 7.0], 0.5, 3), [2, 1, 2]);
        assert_eq!(bin_counts(&[], 1.0, 2), [0, 0]);
    }
}
