//! Sine and cosine of several angles at once, written so that a loop over lanes vectorises.
//!
//! libm's `sin`/`cos` are scalar calls, and SIMD crates (`wide`'s `f64x4::sin_cos`) pick their
//! instruction set when they are compiled, for the x86-64 baseline, and fuse multiply-adds only
//! where that baseline has them, so their bits depend on the build. The function here is plain
//! arithmetic with no branch per lane: the kinematics loops inline it into code compiled for
//! the baseline and for AVX2 (`multiversion`), and every build performs the same IEEE
//! operations in the same order (Rust never fuses a multiply and an add on its own), so they
//! give the same bits.

/// Above this magnitude (rad) lanes, and non-finite ones, use libm. Below it the three-part
/// reduction is exact but for its last product (`k · PIO2_HI` and `k · PIO2_MID` are exact
/// while the quadrant `k` < 2²⁸, here below 2²³).
const REDUCTION_LIMIT: f64 = 1.0e7;

/// `(sin x, cos x)` of every lane, within two units in the last place of libm's values (see
/// the tests) except near the zeros away from the origin, where the absolute error stays below
/// `10⁻³⁰ |x|` (the three-part π/2 holds 106 bits); libm's values beyond ±10⁷ rad.
///
/// `x = k π/2 + r` with `k` the nearest integer to `x · 2/π` and `|r| ≤ π/4`, `π/2` split in
/// three (Cephes' constants: the first two have short mantissas so that `k · part` is exact),
/// then Cephes' minimax polynomials of degree 13 (sine) and 14 (cosine) on `r`, and the
/// quadrant picks which of them, with which sign, is the sine and the cosine.
#[inline(always)]
pub fn sin_cos<const N: usize>(x: [f64; N]) -> ([f64; N], [f64; N]) {
    let mut s = [0.0; N];
    let mut c = [0.0; N];
    for l in 0..N {
        (s[l], c[l]) = sin_cos_reduced(x[l]);
    }
    if x.iter().any(|v| v.is_nan() || v.abs() > REDUCTION_LIMIT) {
        beyond_reduction(&x, &mut s, &mut c);
    }
    (s, c)
}

/// libm's values for the lanes beyond the reduction. Out of line, so that the compiler does
/// not evaluate libm's `sin` and `cos` for every lane and pick afterwards.
#[cold]
#[inline(never)]
fn beyond_reduction<const N: usize>(x: &[f64; N], s: &mut [f64; N], c: &mut [f64; N]) {
    for l in 0..N {
        if x[l].is_nan() || x[l].abs() > REDUCTION_LIMIT {
            (s[l], c[l]) = x[l].sin_cos();
        }
    }
}

/// The branch-free body of [`sin_cos`] for one lane with `|x| ≤ REDUCTION_LIMIT`.
#[inline(always)]
fn sin_cos_reduced(x: f64) -> (f64, f64) {
    // Adding 1.5·2⁵² rounds to an integer (ties to even) held in the low mantissa bits.
    const ROUND: f64 = 6_755_399_441_055_744.0;
    const PIO2_HI: f64 = 1.5707963109016418;
    const PIO2_MID: f64 = 1.5893254712295857e-8;
    const PIO2_LO: f64 = 6.123233995736766e-17;
    const SIN: [f64; 6] = [
        1.5896230157654656e-10,
        -2.5050747762857807e-8,
        2.7557313621385722e-6,
        -0.0001984126982958954,
        0.008333333333322118,
        -0.1666666666666663,
    ];
    const COS: [f64; 6] = [
        -1.1358536521387682e-11,
        2.087570084197473e-9,
        -2.755731417929674e-7,
        2.4801587288851704e-5,
        -0.0013888888888873056,
        0.041666666666666595,
    ];
    let xa = x.abs();
    let t = xa * std::f64::consts::FRAC_2_PI + ROUND;
    let k = t - ROUND;
    let quadrant = t.to_bits().wrapping_sub(ROUND.to_bits());
    let r = ((xa - k * PIO2_HI) - k * PIO2_MID) - k * PIO2_LO;
    let r2 = r * r;
    let mut ps = SIN[0];
    let mut pc = COS[0];
    for i in 1..6 {
        ps = ps * r2 + SIN[i];
        pc = pc * r2 + COS[i];
    }
    let sin_r = r + r * r2 * ps;
    let cos_r = (1.0 - 0.5 * r2) + r2 * r2 * pc;
    let odd = quadrant & 1 == 1;
    let (s, c) = if odd { (cos_r, sin_r) } else { (sin_r, cos_r) };
    // sin changes sign in quadrants 2 and 3 and with x; cos in quadrants 1 and 2.
    let sin_sign = ((quadrant & 2) << 62) ^ (x.to_bits() & (1 << 63));
    let cos_sign = (quadrant.wrapping_add(1) & 2) << 62;
    (
        f64::from_bits(s.to_bits() ^ sin_sign),
        f64::from_bits(c.to_bits() ^ cos_sign),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Error of `got` in units in the last place of `want`, with errors below `1e-30 |x|`
    /// (the reduction's, which only shows near the zeros away from the origin) counted as none.
    fn ulps(got: f64, want: f64, x: f64) -> f64 {
        let err = (got - want).abs();
        if err <= 1e-30 * x.abs() {
            return 0.0;
        }
        let w = want.abs().max(f64::MIN_POSITIVE);
        err / (w.next_up() - w)
    }

    fn check(xs: impl Iterator<Item = f64>) -> (f64, f64) {
        let mut worst = (0.0f64, 0.0f64);
        let xs: Vec<f64> = xs.collect();
        for chunk in xs.chunks_exact(4) {
            let (s, c) = sin_cos::<4>(chunk.try_into().unwrap());
            for ((&x, s), c) in chunk.iter().zip(s).zip(c) {
                let (ws, wc) = x.sin_cos();
                worst.0 = worst.0.max((s - ws).abs()).max((c - wc).abs());
                worst.1 = worst.1.max(ulps(s, ws, x)).max(ulps(c, wc, x));
            }
        }
        worst
    }

    #[test]
    fn sin_cos_matches_libm_on_a_dense_grid() {
        // Every joint angle a robot reaches, densely, and the quadrant boundaries exactly.
        let dense = (-4_000_000..=4_000_000).map(|i| i as f64 * 5e-6);
        let (abs, ulp) = check(dense);
        assert!(abs <= 2.3e-16 && ulp <= 2.0, "largest error {abs:e} ({ulp} ulp)");
        let boundaries = (-4000..=4000).flat_map(|k| {
            let b = k as f64 * std::f64::consts::FRAC_PI_4;
            [b, b.next_up(), b.next_down(), b + 1e-9]
        });
        let (abs, ulp) = check(boundaries);
        assert!(abs <= 2.3e-16 && ulp <= 2.0, "largest error {abs:e} ({ulp} ulp)");
        // Large arguments up to where the reduction stays exact.
        let large = (0..200_000).map(|i| (i as f64 * 50.000_37).copysign(if i % 2 == 0 { 1.0 } else { -1.0 }));
        let (abs, _) = check(large);
        assert!(abs <= 1e-12, "largest error {abs:e} on large arguments");
    }

    #[test]
    fn sin_cos_falls_back_to_libm_beyond_the_reduction_and_keeps_nan() {
        let x = [1e9, f64::INFINITY, f64::NAN, 0.5];
        let (s, c) = sin_cos(x);
        assert_eq!((s[0], c[0]), 1e9f64.sin_cos());
        assert!(s[1].is_nan() && c[1].is_nan() && s[2].is_nan() && c[2].is_nan());
        assert!((s[3] - 0.5f64.sin()).abs() < 1e-16 && (c[3] - 0.5f64.cos()).abs() < 1e-16);
        // Signed zero as libm gives it.
        let (s, c) = sin_cos([-0.0, 0.0, -0.0, 0.0]);
        assert!(s[0] == 0.0 && s[0].is_sign_negative() && s[1].is_sign_positive() && c[0] == 1.0);
    }
}
