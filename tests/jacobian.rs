//! Analytic Jacobians against central finite differences.

use armcomp_core::{Robot, TreeWorkspace};
use nalgebra::{Matrix3xX, Matrix6xX, Vector3};
use proptest::prelude::*;

use crate::common::{robot, robot_from_toml};

/// Max abs difference between the analytic point/pose Jacobians and central differences.
fn jacobian_error(robot: &Robot, q: &[f64]) -> (f64, f64) {
    let tree = robot.tree();
    let n = tree.nq();
    let tool = robot.tool();
    let mut ws = TreeWorkspace::new(tree);
    tree.forward_into(q, &mut ws);
    let mut jp = Matrix3xX::zeros(n);
    let mut jt = Matrix6xX::zeros(n);
    tree.point_jacobian_into(&ws, tool, &mut jp);
    tree.pose_jacobian_into(&ws, tool, &mut jt);
    let h = 1e-6;
    let (mut ep, mut et): (f64, f64) = (0.0, 0.0);
    for c in 0..n {
        let mut qp = q.to_vec();
        let mut qm = q.to_vec();
        qp[c] += h;
        qm[c] -= h;
        tree.forward_into(&qp, &mut ws);
        let (pp, rp) = (ws.point[tool].translation.vector, ws.point[tool].rotation);
        tree.forward_into(&qm, &mut ws);
        let (pm, rm) = (ws.point[tool].translation.vector, ws.point[tool].rotation);
        let v = (pp - pm) / (2.0 * h);
        // Angular velocity in world coordinates: log(R+ R-^T) / 2h.
        let w: Vector3<f64> = (rp * rm.inverse()).scaled_axis() / (2.0 * h);
        for r in 0..3 {
            ep = ep.max((jp[(r, c)] - v[r]).abs());
            et = et.max((jt[(r, c)] - v[r]).abs()).max((jt[(r + 3, c)] - w[r]).abs());
        }
    }
    (ep, et)
}

fn mimic_tree() -> Robot {
    robot_from_toml(
        r#"
name = "mimic"
[kinematics]
type = "mdh"
[[kinematics.joints]]
name = "a"
d = 0.3
[[kinematics.joints]]
name = "b"
alpha = 1.2
a = 0.4
[[kinematics.joints]]
name = "c"
a = 0.35
alpha = -0.4
mimic = { joints = ["a", "b"], multipliers = [-0.5, 2.0], offset = 0.1 }
[[kinematics.joints]]
name = "d"
kind = "prismatic"
alpha = 0.7
theta = 0.3
[[points]]
name = "tool"
link = "d"
xyz = [0.1, -0.05, 0.2]
rpy = [0.3, 0.2, 0.1]
"#,
    )
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn rock_drill_jacobians_match_finite_differences(u in prop::collection::vec(0.0f64..1.0, 7)) {
        let r = robot("rock-drill.toml");
        let q: Vec<f64> = r.tree().coordinate_limits().iter().zip(&u).map(|(l, u)| {
            let l = l.unwrap();
            l.lower + u * (l.upper - l.lower)
        }).collect();
        let (ep, et) = jacobian_error(&r, &q);
        // Central differences with h = 1e-6 on a ~1 m arm: truncation ~1e-12, rounding ~1e-10.
        prop_assert!(ep < 1e-7 && et < 1e-7, "point {ep:e}, pose {et:e}");
    }

    #[test]
    fn industrial_jacobians_match_finite_differences(q in prop::collection::vec(-3.0f64..3.0, 6)) {
        let (ep, et) = jacobian_error(&robot("industrial-6dof.toml"), &q);
        prop_assert!(ep < 1e-7 && et < 1e-7, "point {ep:e}, pose {et:e}");
    }

    #[test]
    fn mimic_tree_jacobians_match_finite_differences(q in prop::collection::vec(-2.0f64..2.0, 3)) {
        let (ep, et) = jacobian_error(&mimic_tree(), &q);
        prop_assert!(ep < 1e-7 && et < 1e-7, "point {ep:e}, pose {et:e}");
    }
}
