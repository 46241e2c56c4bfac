//! Numbers the kinematics loops are written over: one `f64` (one configuration) or [`Lanes`]
//! (the same quantity in several configurations at once, structure of arrays), so that one
//! loop serves single calls and batches.

use std::ops::{Add, Mul, Neg, Sub};

/// Configurations evaluated together: four f64 lanes, one AVX2 register or two SSE2 registers.
pub const LANES: usize = 4;

/// One quantity in [`LANES`] configurations. Its operations are loops over the lanes, which the
/// compiler turns into vector instructions of whatever width the surrounding code is built for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lanes(pub [f64; LANES]);

impl Add for Lanes {
    type Output = Lanes;
    #[inline(always)]
    fn add(self, o: Lanes) -> Lanes {
        Lanes(std::array::from_fn(|l| self.0[l] + o.0[l]))
    }
}

impl Sub for Lanes {
    type Output = Lanes;
    #[inline(always)]
    fn sub(self, o: Lanes) -> Lanes {
        Lanes(std::array::from_fn(|l| self.0[l] - o.0[l]))
    }
}

impl Mul for Lanes {
    type Output = Lanes;
    #[inline(always)]
    fn mul(self, o: Lanes) -> Lanes {
        Lanes(std::array::from_fn(|l| self.0[l] * o.0[l]))
    }
}

impl Neg for Lanes {
    type Output = Lanes;
    #[inline(always)]
    fn neg(self) -> Lanes {
        Lanes(self.0.map(|v| -v))
    }
}

/// What the kinematics loops need of a number type.
pub trait Real: Copy + Add<Output = Self> + Sub<Output = Self> + Mul<Output = Self> + Neg<Output = Self> {
    /// How many values [`sin_cos_into`](Real::sin_cos_into) takes at a time.
    const PACK: usize;
    /// The constant `v` (in every lane).
    fn splat(v: f64) -> Self;
    /// Sine and cosine of every entry of `x` into `sin` and `cos` (same lengths, a multiple of
    /// [`PACK`](Real::PACK)), through [`sin_cos`](crate::kinematics::sincos::sin_cos) so that single calls
    /// and batches give the same bits.
    fn sin_cos_into(x: &[Self], sin: &mut [Self], cos: &mut [Self]);
}

impl Real for f64 {
    /// Angles of one configuration go through the lanes [`LANES`] at a time.
    const PACK: usize = LANES;

    #[inline(always)]
    fn splat(v: f64) -> f64 {
        v
    }

    #[inline(always)]
    fn sin_cos_into(x: &[f64], sin: &mut [f64], cos: &mut [f64]) {
        let (x, _) = x.as_chunks::<LANES>();
        let (sin, _) = sin.as_chunks_mut::<LANES>();
        let (cos, _) = cos.as_chunks_mut::<LANES>();
        for ((x, s), c) in x.iter().zip(sin).zip(cos) {
            (*s, *c) = crate::kinematics::sincos::sin_cos(*x);
        }
    }
}

impl Real for Lanes {
    const PACK: usize = 1;

    #[inline(always)]
    fn splat(v: f64) -> Lanes {
        Lanes([v; LANES])
    }

    #[inline(always)]
    fn sin_cos_into(x: &[Lanes], sin: &mut [Lanes], cos: &mut [Lanes]) {
        for ((x, s), c) in x.iter().zip(sin.iter_mut()).zip(cos.iter_mut()) {
            (s.0, c.0) = crate::kinematics::sincos::sin_cos(x.0);
        }
    }
}
