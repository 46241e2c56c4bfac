//! The inner loops of GP prediction: a row of squared-exponential kernel values against every
//! training input, and dot products along the training rows.
//!
//! Each loop is compiled twice, for the portable x86-64 baseline and for AVX2, and the build
//! the CPU supports is picked at run time (`multiversion`), so one binary runs everywhere and
//! uses 256-bit registers where they exist. That needs plain arithmetic the compiler can
//! vectorise for either target, which is why `exp` is written here: SIMD libraries pick their
//! instruction set when they are compiled, for the baseline, and libm's `exp` is a scalar call.
//! Both builds perform the same IEEE operations in the same order (Rust never fuses a multiply
//! and an add on its own), so they give the same bits.

use multiversion::multiversion;

/// Rows handled together: four f64 lanes, one AVX2 register or two SSE2 registers.
const LANES: usize = 4;

/// Arguments below this give `exp` under the smallest normal number; they are returned as 0.
const EXP_UNDERFLOW: f64 = -708.0;

/// `exp(x)` for `x ≤ 0` (0 below −708, NaN for NaN), within two ulp of the correctly rounded value.
///
/// `x = k ln 2 + r` with `k` the nearest integer to `x / ln 2` and `|r| ≤ ln 2 / 2`, then
/// `exp(x) = 2^k exp(r)`, with `exp(r) = 1 + r + r² q(r)`, `q` the degree-9 Chebyshev fit of
/// `(eʳ − 1 − r)/r²` on `|r| ≤ ln 2 / 2` (fit error below 1.3·10⁻¹⁷; one Horner step less than
/// the degree-12 Taylor series), and `2^k` built in the exponent bits. The coefficients are
/// mpmath's at 50 digits, rounded: `chebyfit(lambda r: (exp(r) - 1 - r) / r**2, [-h, h], 10)`
/// with `h = log(2) / 2` (the series `1/2 + r/6 + r²/24` where `|r| < 1e-10`). `ln 2` is split
/// in two (fdlibm's constants) so that `k ln 2` is exact to the last bit of `r`. Branch-free, so
/// a loop of it vectorises.
#[inline(always)]
pub(crate) fn exp_nonpositive(x: f64) -> f64 {
    // Adding 1.5·2⁵² rounds to an integer held in the low mantissa bits.
    const ROUND: f64 = 6_755_399_441_055_744.0;
    const LN2_HI: f64 = 0.693_147_180_369_123_8;
    const LN2_LO: f64 = 1.908_214_929_270_587_7e-10;
    let xc = x.max(EXP_UNDERFLOW);
    let t = xc * std::f64::consts::LOG2_E + ROUND;
    let k = t - ROUND;
    let r = (xc - k * LN2_HI) - k * LN2_LO;
    // Horner on 1 + r + r² q(r), q's coefficients highest first (see above).
    let mut p = 2.510_037_583_256_123_4e-8;
    for c in [
        2.762_007_587_998_336_7e-7,
        2.755_726_848_031_002_4e-6,
        2.480_152_132_236_869_2e-5,
        1.984_126_986_304_054_5e-4,
        1.388_888_891_719_671_9e-3,
        8.333_333_333_330_065e-3,
        4.166_666_666_662_416_4e-2,
        0.166_666_666_666_666_69,
        0.500_000_000_000_000_1,
        1.0,
        1.0,
    ] {
        p = p * r + c;
    }
    // k sits in the low bits of t; 2^k has biased exponent k + 1023 (≥ 1 as k ≥ −1022).
    let k_bits = t.to_bits().wrapping_sub(ROUND.to_bits());
    let two_k = f64::from_bits(k_bits.wrapping_add(1023) << 52);
    let v = if x < EXP_UNDERFLOW { 0.0 } else { p * two_k };
    if x.is_nan() { x } else { v }
}

/// `w_i = σ_f² exp(−½ Σ_j (u_j − x_ij)²)` for every training row `i`, where `columns` holds the
/// `d` length-scaled inputs as runs of `n = w.len()` values (run `j` = input `j` of every row).
#[multiversion(targets("x86_64+avx2", "x86_64+avx"))]
pub(crate) fn kernel_row(columns: &[f64], u: &[f64], signal_variance: f64, w: &mut [f64]) {
    let n = w.len();
    // Squared distances four rows at a time, every dimension summed in registers.
    let (blocks, rest) = w.as_chunks_mut::<LANES>();
    for (b, block) in blocks.iter_mut().enumerate() {
        let mut acc = [0.0; LANES];
        for (column, &uj) in columns.chunks_exact(n).zip(u) {
            for (a, &x) in acc.iter_mut().zip(&column[LANES * b..LANES * (b + 1)]) {
                let t = x - uj;
                *a += t * t;
            }
        }
        *block = acc;
    }
    let done = LANES * blocks.len();
    for (i, wi) in rest.iter_mut().enumerate() {
        *wi = columns
            .chunks_exact(n)
            .zip(u)
            .map(|(c, uj)| (c[done + i] - uj).powi(2))
            .sum();
    }
    for wi in w.iter_mut() {
        *wi = signal_variance * exp_nonpositive(-0.5 * *wi);
    }
}

/// `Σ a_i b_i` with sixteen running sums: one sum would fix the order of the additions and keep
/// the compiler from vectorising it, and one register of sums would wait on the latency of
/// each addition; four registers keep the adder busy.
#[multiversion(targets("x86_64+avx2", "x86_64+avx"))]
pub(crate) fn dot(a: &[f64], b: &[f64]) -> f64 {
    const SUMS: usize = 4 * LANES;
    let (ca, ra) = a.as_chunks::<SUMS>();
    let (cb, rb) = b.as_chunks::<SUMS>();
    let tail: f64 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    let mut acc = [0.0; SUMS];
    for (x, y) in ca.iter().zip(cb) {
        for l in 0..SUMS {
            acc[l] += x[l] * y[l];
        }
    }
    // An opaque copy: with the pairwise reduction below in view, the compiler vectorises the
    // loop above two lanes wide even in the AVX2 build; behind it, four wide (the same
    // operations in the same order, so the same bits).
    let mut acc = std::hint::black_box(acc);
    // Pairwise, so that the reduction does not depend on the register width either.
    let mut width = SUMS;
    while width > 1 {
        width /= 2;
        for l in 0..width {
            acc[l] += acc[l + width];
        }
    }
    acc[0] + tail
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance in units in the last place between two positive finite numbers.
    fn ulps(a: f64, b: f64) -> u64 {
        a.to_bits().abs_diff(b.to_bits())
    }

    #[test]
    fn exp_matches_libm_within_two_ulp() {
        // Dense near 0 (where kernel values live) and across the whole range down to underflow.
        let xs = (0..=200_000)
            .map(|i| -(i as f64) * 1e-4)
            .chain((0..=70_800).map(|i| -(i as f64) * 1e-2 - 0.003_7));
        for x in xs {
            let (got, want) = (exp_nonpositive(x), x.exp());
            if x < EXP_UNDERFLOW {
                assert_eq!(got, 0.0, "exp({x})");
            } else {
                assert!(ulps(got, want) <= 2, "exp({x}) = {got:e}, libm {want:e}");
            }
        }
        assert_eq!(exp_nonpositive(0.0), 1.0);
        assert_eq!(exp_nonpositive(-1e4), 0.0);
        assert_eq!(exp_nonpositive(f64::NEG_INFINITY), 0.0);
        assert!(exp_nonpositive(f64::NAN).is_nan());
    }

    #[test]
    fn kernel_row_matches_the_formula() {
        // 3 inputs, 11 rows: two blocks of four and a tail of three.
        let (n, d) = (11, 3);
        let rows: Vec<[f64; 3]> = (0..n)
            .map(|i| {
                let t = i as f64;
                [0.3 * t - 1.0, (0.7 * t).sin(), 2.0 - 0.25 * t]
            })
            .collect();
        let columns: Vec<f64> = (0..d).flat_map(|j| rows.iter().map(move |r| r[j])).collect();
        let u = [0.2, -0.4, 1.1];
        let mut w = vec![0.0; n];
        kernel_row(&columns, &u, 2.5, &mut w);
        for (i, r) in rows.iter().enumerate() {
            let sq: f64 = r.iter().zip(&u).map(|(x, v)| (x - v) * (x - v)).sum();
            let want = 2.5 * (-0.5 * sq).exp();
            assert!(
                (w[i] - want).abs() <= 4.0 * f64::EPSILON * want,
                "row {i}: {} vs {want}",
                w[i]
            );
        }
        let ones = vec![1.0; n];
        let sum: f64 = w.iter().sum();
        assert!((dot(&w, &ones) - sum).abs() <= 1e-15 * sum);
    }
}
