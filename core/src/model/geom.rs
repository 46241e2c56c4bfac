//! Elementary rigid transforms and small-motion algebra used by every convention.
//!
//! All lengths in metres, all angles in radians.

use nalgebra::{Isometry3, Matrix3, Translation3, Unit, UnitQuaternion, Vector3, Vector6};

/// Rotation about the x axis by `a` rad.
pub fn rx(a: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), a),
    )
}

/// Rotation about the y axis by `a` rad.
pub fn ry(a: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_axis_angle(&Vector3::y_axis(), a),
    )
}

/// Rotation about the z axis by `a` rad.
pub fn rz(a: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_axis_angle(&Vector3::z_axis(), a),
    )
}

/// Translation along x by `d` m.
pub fn tx(d: f64) -> Isometry3<f64> {
    Isometry3::translation(d, 0.0, 0.0)
}

/// Translation along z by `d` m.
pub fn tz(d: f64) -> Isometry3<f64> {
    Isometry3::translation(0.0, 0.0, d)
}

/// Pose from a translation (m) and URDF roll-pitch-yaw angles (rad): `R = Rz(yaw) Ry(pitch) Rx(roll)`.
pub fn xyz_rpy(xyz: [f64; 3], rpy: [f64; 3]) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(xyz[0], xyz[1], xyz[2]),
        UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
    )
}

/// Skew-symmetric matrix of `v`, so that `skew(v) * w = v × w`.
pub fn skew(v: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -v.z, v.y, v.z, 0.0, -v.x, -v.y, v.x, 0.0)
}

/// Exponential of a twist `(d, δ)` = `[dx, dy, dz, δx, δy, δz]` (translation first, as in the
/// deflection paper's Eq. 5). The result agrees with `I + Δ` (Eq. 3) to first order and is an
/// exact rigid motion, so perturbed chains stay orthonormal.
pub fn exp_twist(twist: &Vector6<f64>) -> Isometry3<f64> {
    let v = Vector3::new(twist[0], twist[1], twist[2]);
    let w = Vector3::new(twist[3], twist[4], twist[5]);
    let theta = w.norm();
    if theta < 1e-12 {
        return Isometry3::from_parts(Translation3::from(v), UnitQuaternion::identity());
    }
    // One sine and cosine of the half angle serve the quaternion and, through sin θ = 2 sₕcₕ
    // and 1 − cos θ = 2 sₕ² (free of cancellation at small angles), the left Jacobian.
    let (sh, ch) = (0.5 * theta).sin_cos();
    // One division: the others are products with its result (divisions are slow).
    let inv = 1.0 / theta;
    let sh_t = sh * inv;
    let axis = w * sh_t;
    let rot = UnitQuaternion::new_unchecked(nalgebra::Quaternion::new(ch, axis.x, axis.y, axis.z));
    // Left Jacobian of SO(3) applied to v: V v = v + (1-cos)/θ² K v + (θ-sin)/θ³ K² v with
    // K v = w × v, two cross products instead of the matrices.
    let wv = w.cross(&v);
    let wwv = w.cross(&wv);
    let t = v + wv * (2.0 * sh_t * sh_t) + wwv * ((theta - 2.0 * sh * ch) * (inv * inv * inv));
    Isometry3::from_parts(Translation3::from(t), rot)
}

/// The body-frame twist by which [`exp_twist`] moves when its argument moves: with
/// `exp(ξ + δ) = exp(ξ) · exp(J_r(ξ) δ + O(δ²))`, returns `J_r(ξ) δ`, the right Jacobian
/// `Σ (−ad_ξ)^k / (k+1)!` applied to `δ`. The series is cut after the fifth power, which is
/// exact to |ξ|⁶/5040 relative, ample for the small deformation twists it is used on.
pub fn exp_twist_right_jacobian(xi: &Vector6<f64>, delta: &Vector6<f64>) -> Vector6<f64> {
    // ad_ξ x = (w × x_v + v × x_w, w × x_w), with translation first.
    right_jacobian_series(xi, delta, |v, w, x| {
        let (xv, xw) = (x.fixed_rows::<3>(0), x.fixed_rows::<3>(3));
        let a = w.cross(&xv) + v.cross(&xw);
        let b = w.cross(&xw);
        Vector6::new(a.x, a.y, a.z, b.x, b.y, b.z)
    })
}

/// `J_r(ξ)ᵀ y`, the transposed series of [`exp_twist_right_jacobian`], for carrying row
/// vectors (maps from a body twist to a displacement) through it.
pub fn exp_twist_right_jacobian_transpose(xi: &Vector6<f64>, y: &Vector6<f64>) -> Vector6<f64> {
    // ad_ξᵀ y = (−w × y_v, −v × y_v − w × y_w).
    right_jacobian_series(xi, y, |v, w, y| {
        let (yv, yw) = (y.fixed_rows::<3>(0), y.fixed_rows::<3>(3));
        let a = -w.cross(&yv);
        let b = -v.cross(&yv) - w.cross(&yw);
        Vector6::new(a.x, a.y, a.z, b.x, b.y, b.z)
    })
}

/// `Σ (−A)^k x / (k+1)!` for k ≤ 5, `A` the action `ad(v, w, x)` of ξ = (v, w) or its transpose.
fn right_jacobian_series(
    xi: &Vector6<f64>,
    x: &Vector6<f64>,
    ad: impl Fn(&Vector3<f64>, &Vector3<f64>, &Vector6<f64>) -> Vector6<f64>,
) -> Vector6<f64> {
    let (v, w) = (xi.fixed_rows::<3>(0).into_owned(), xi.fixed_rows::<3>(3).into_owned());
    let mut term = *x;
    let mut sum = *x;
    let mut factorial = 1.0;
    for k in 1..=5 {
        factorial *= (k + 1) as f64;
        term = -ad(&v, &w, &term);
        sum += term / factorial;
    }
    sum
}

/// `J_r⁻¹(φ)`, the inverse right Jacobian of SO(3) at the rotation vector `φ`: with
/// `R = exp(φ)`, `log(R · exp(u)) = φ + J_r⁻¹(φ) u + O(u²)`. How an orientation residual
/// `log(R_measᵀ R_model)` moves when the model turns, exact at residuals of any size below π.
pub fn so3_right_jacobian_inverse(phi: &Vector3<f64>) -> Matrix3<f64> {
    let theta = phi.norm();
    let k = skew(phi);
    // (1/θ² − (1 + cos θ)/(2θ sin θ)), whose series starts at 1/12 (and cancels below 1e-4).
    let c = if theta < 1e-4 {
        1.0 / 12.0 + theta * theta / 720.0
    } else {
        (1.0 / (theta * theta)) - (1.0 + theta.cos()) / (2.0 * theta * theta.sin())
    };
    Matrix3::identity() + k * 0.5 + k * k * c
}

/// A unit vector, or `None` when `v` is (numerically) zero.
pub fn unit(v: Vector3<f64>) -> Option<Unit<Vector3<f64>>> {
    Unit::try_new(v, 1e-12)
}

/// A rotation taking the z axis onto `dir` (the shortest arc; any roll about `dir` would do).
pub fn rotation_z_to(dir: &Unit<Vector3<f64>>) -> UnitQuaternion<f64> {
    UnitQuaternion::rotation_between(&Vector3::z(), dir).unwrap_or_else(|| {
        // Antiparallel: rotate half a turn about x.
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exp_twist_right_jacobian_is_the_derivative_of_the_exponential() {
        // A deformation-sized twist and a direction; exp(ξ)⁻¹ exp(ξ + hδ) against
        // exp(h J_r δ) by central differences of the matrix entries.
        let xi = Vector6::new(0.02, -0.01, 0.03, 0.15, -0.08, 0.1);
        let delta = Vector6::new(0.3, 0.5, -0.2, 0.7, -0.4, 0.9);
        let h = 1e-6;
        let rel = |s: f64| (exp_twist(&xi).inverse() * exp_twist(&(xi + delta * s))).to_homogeneous();
        let fd = (rel(h) - rel(-h)) / (2.0 * h);
        let j = exp_twist_right_jacobian(&xi, &delta);
        let mut expected = nalgebra::Matrix4::zeros();
        expected
            .fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&skew(&Vector3::new(j[3], j[4], j[5])));
        expected
            .fixed_view_mut::<3, 1>(0, 3)
            .copy_from(&Vector3::new(j[0], j[1], j[2]));
        assert!((fd - expected).norm() < 1e-8, "{fd} vs {expected}");
        // The plain δ is off by the first-order term, far above that tolerance.
        let mut plain = nalgebra::Matrix4::zeros();
        plain
            .fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&skew(&Vector3::new(delta[3], delta[4], delta[5])));
        plain
            .fixed_view_mut::<3, 1>(0, 3)
            .copy_from(&Vector3::new(delta[0], delta[1], delta[2]));
        assert!((fd - plain).norm() > 1e-2);
        // The transposed series is the adjoint: y · (J δ) = (Jᵀ y) · δ.
        let y = Vector6::new(-0.2, 0.9, 0.4, -0.6, 0.1, 0.8);
        let (a, b) = (y.dot(&j), exp_twist_right_jacobian_transpose(&xi, &y).dot(&delta));
        assert!((a - b).abs() < 1e-15, "{a} vs {b}");
    }

    #[test]
    fn xyz_rpy_matches_urdf_fixed_axis_convention() {
        // URDF: rpy are fixed-axis rotations applied roll, then pitch, then yaw.
        let (r, p, y) = (0.3, -0.4, 1.1);
        let a = xyz_rpy([0.0; 3], [r, p, y]);
        let b = rz(y) * ry(p) * rx(r);
        assert!((a.to_homogeneous() - b.to_homogeneous()).norm() < 1e-14);
    }

    #[test]
    fn exp_twist_is_first_order_identity_plus_delta() {
        let t = Vector6::new(1e-6, -2e-6, 3e-6, 2e-6, 1e-6, -1e-6);
        let e = exp_twist(&t).to_homogeneous();
        let mut delta = nalgebra::Matrix4::zeros();
        delta
            .fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&skew(&Vector3::new(t[3], t[4], t[5])));
        delta[(0, 3)] = t[0];
        delta[(1, 3)] = t[1];
        delta[(2, 3)] = t[2];
        let lin = nalgebra::Matrix4::identity() + delta;
        assert!((e - lin).norm() < 1e-11);
    }

    /// Against the matrix exponential of the twist's 4 × 4 form, from tiny to large angles.
    #[test]
    fn exp_twist_is_the_matrix_exponential() {
        for (scale, tol) in [(1e-9, 1e-15), (1e-3, 1e-15), (0.3, 1e-14), (2.5, 1e-13)] {
            let t = Vector6::new(0.4, -0.2, 0.7, 0.3, -0.5, 0.8) * scale;
            let mut m = nalgebra::Matrix4::zeros();
            m.fixed_view_mut::<3, 3>(0, 0)
                .copy_from(&skew(&Vector3::new(t[3], t[4], t[5])));
            m[(0, 3)] = t[0];
            m[(1, 3)] = t[1];
            m[(2, 3)] = t[2];
            let err = (exp_twist(&t).to_homogeneous() - m.exp()).norm();
            assert!(err < tol, "scale {scale}: {err:e}");
        }
    }

    #[test]
    fn exp_twist_pure_rotation_about_offset_axis() {
        // A screw about z through (1,0,0): v = -w × r = (0, 1, 0)·θ for w = z.
        let th = 0.7;
        let r = Vector3::new(1.0, 0.0, 0.0);
        let w = Vector3::z() * th;
        let v = -w.cross(&r);
        let e = exp_twist(&Vector6::new(v.x, v.y, v.z, w.x, w.y, w.z));
        // The point on the axis stays fixed.
        let p = e.transform_point(&nalgebra::Point3::from(r));
        assert!((p.coords - r).norm() < 1e-12);
    }
}
