//! What the physical models share: name look-ups with issues and the mapping of world-frame
//! small motions to twists of the frames they perturb (gravity loads are core's `gravity`).

use std::collections::BTreeMap;

use armcomp_core::{Issues, ModelContext, Motion};
use nalgebra::{Isometry3, Vector3, Vector6};

/// Errors of this crate's helpers (the plugins themselves report [`Issues`]).
#[derive(Debug, thiserror::Error)]
pub enum ElasticError {
    /// The static equilibrium iteration did not settle.
    #[error("static equilibrium not reached after {iterations} iterations (last change {change:e})")]
    NotConverged {
        /// Iterations done.
        iterations: usize,
        /// Largest change of a joint offset or twist component in the last iteration.
        change: f64,
    },
    /// A caller gave values that cannot be used.
    #[error(transparent)]
    Input(#[from] armcomp_core::Error),
}

/// Checks that `v` is finite and strictly positive; records an issue at `path` otherwise.
pub(crate) fn check_positive(issues: &mut Issues, path: &str, v: f64, what: &str) -> bool {
    let ok = v.is_finite() && v > 0.0;
    if !ok {
        issues.push(path, format!("expected a positive {what}, got {v}"));
    }
    ok
}

/// Checks that `v` is finite; records an issue at `path` otherwise.
pub(crate) fn check_finite(issues: &mut Issues, path: &str, v: f64) -> bool {
    let ok = v.is_finite();
    if !ok {
        issues.push(path, format!("expected a finite number, got {v}"));
    }
    ok
}

/// Comma-separated, back-quoted names, for messages.
pub(crate) fn name_list<'a>(names: impl Iterator<Item = &'a str>) -> String {
    names.map(|n| format!("`{n}`")).collect::<Vec<_>>().join(", ")
}

/// Resolves the keys of a `joint name → value` table to movable joints; issues name the key.
/// Returns `(joint index, value)` in tree order.
pub(crate) fn resolve_joint_table(
    ctx: &ModelContext<'_>,
    field: &str,
    table: &BTreeMap<String, f64>,
    issues: &mut Issues,
    mut check: impl FnMut(&mut Issues, &str, f64) -> bool,
) -> Vec<(usize, f64)> {
    let tree = ctx.tree;
    let mut out = Vec::new();
    for (name, &v) in table {
        let path = format!("{}.{field}.{name}", ctx.build.path);
        match tree.joint_index(name) {
            Some(j) if !matches!(tree.joints()[j].motion, Motion::Fixed) => {
                if check(issues, &path, v) {
                    out.push((j, v));
                }
            }
            Some(_) => issues.push(path, format!("joint `{name}` is fixed; it has no value to perturb")),
            None => issues.push(
                path,
                format!(
                    "joint `{name}` does not exist; joints are: {}",
                    name_list(tree.joints().iter().map(|j| j.name.as_str()))
                ),
            ),
        }
    }
    out.sort_by_key(|(j, _)| *j);
    out
}

/// The twist (in `frame`'s own coordinates, translation first) that moves `frame`'s origin by
/// `u` and turns it by the rotation vector `theta`, both given in world coordinates.
#[inline]
pub(crate) fn world_motion_to_twist(frame: &Isometry3<f64>, u: &Vector3<f64>, theta: &Vector3<f64>) -> Vector6<f64> {
    let d = frame.rotation.inverse_transform_vector(u);
    let r = frame.rotation.inverse_transform_vector(theta);
    Vector6::new(d.x, d.y, d.z, r.x, r.y, r.z)
}

/// Adjoint map of a twist: `ξ` in the coordinates of frame B → the same motion in frame A's
/// coordinates, where `a_b` is B's pose in A (`A_b · exp(ξ) · A_b⁻¹ = exp(Ad ξ)`).
#[inline]
pub fn adjoint(a_b: &Isometry3<f64>, xi: &Vector6<f64>) -> Vector6<f64> {
    let v = Vector3::new(xi[0], xi[1], xi[2]);
    let w = Vector3::new(xi[3], xi[4], xi[5]);
    let rw = a_b.rotation * w;
    let rv = a_b.rotation * v + a_b.translation.vector.cross(&rw);
    Vector6::new(rv.x, rv.y, rv.z, rw.x, rw.y, rw.z)
}
