//! Rigid transforms in matrix form over a [`Real`]: what the point-kinematics loops compose,
//! the same code for one configuration (`f64`) and for [`Lanes`](crate::kinematics::lanes::Lanes) of them.

use nalgebra::{Isometry3, IsometryMatrix3, Matrix3, Rotation3, Translation3, Vector3};

use crate::kinematics::lanes::Real;

/// `x ↦ R x + p`: the rotation's columns (the frame's axes in the outer frame) and the
/// translation (its origin).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Frame<T> {
    pub(crate) r: [[T; 3]; 3],
    pub(crate) p: [T; 3],
}

impl Frame<f64> {
    /// The matrix form of `iso`.
    pub(crate) fn from_isometry(iso: &Isometry3<f64>) -> Frame<f64> {
        let m = iso.rotation.to_rotation_matrix().into_inner();
        Frame {
            r: std::array::from_fn(|c| std::array::from_fn(|i| m[(i, c)])),
            p: iso.translation.vector.into(),
        }
    }

    /// The same transform as nalgebra's matrix-form isometry.
    pub(crate) fn to_isometry(self) -> IsometryMatrix3<f64> {
        let m = Matrix3::from_fn(|i, c| self.r[c][i]);
        IsometryMatrix3::from_parts(
            Translation3::from(Vector3::from(self.p)),
            Rotation3::from_matrix_unchecked(m),
        )
    }
}

impl<T: Real> Frame<T> {
    /// The constant `c` (in every lane).
    #[inline(always)]
    pub(crate) fn splat(c: &Frame<f64>) -> Frame<T> {
        Frame {
            r: c.r.map(|col| col.map(T::splat)),
            p: c.p.map(T::splat),
        }
    }

    /// `R v` for a vector given in this frame.
    #[inline(always)]
    fn rotate(&self, v: &[f64; 3]) -> [T; 3] {
        let (a, b, c) = (T::splat(v[0]), T::splat(v[1]), T::splat(v[2]));
        std::array::from_fn(|i| self.r[0][i] * a + self.r[1][i] * b + self.r[2][i] * c)
    }

    /// `self · c`: the constant transform `c` given in this frame, composed on the right.
    #[inline(always)]
    pub(crate) fn then(&self, c: &Frame<f64>) -> Frame<T> {
        let p = self.rotate(&c.p);
        Frame {
            r: std::array::from_fn(|j| self.rotate(&c.r[j])),
            p: std::array::from_fn(|i| p[i] + self.p[i]),
        }
    }

    /// `self · Rz(θ)` given `cos θ` and `sin θ`.
    #[inline(always)]
    pub(crate) fn rotated_z(&self, cos: T, sin: T) -> Frame<T> {
        let [x, y, z] = self.r;
        Frame {
            r: [
                std::array::from_fn(|i| x[i] * cos + y[i] * sin),
                std::array::from_fn(|i| y[i] * cos - x[i] * sin),
                z,
            ],
            p: self.p,
        }
    }

    /// `self · Tz(d)`.
    #[inline(always)]
    pub(crate) fn translated_z(&self, d: T) -> Frame<T> {
        Frame {
            r: self.r,
            p: std::array::from_fn(|i| self.p[i] + self.r[2][i] * d),
        }
    }
}
