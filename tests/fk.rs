//! Forward kinematics against poses computed by hand.

use std::f64::consts::FRAC_PI_2;

use crate::common::robot_from_toml;
use crate::common::robots::PLANAR_2R;

#[test]
fn planar_two_link_arm_matches_trigonometry() {
    let robot = robot_from_toml(PLANAR_2R);
    for (q1, q2) in [(0.0, 0.0), (0.3, -1.1), (2.0, 0.5), (-2.9, 3.0)] {
        let f = robot.forward(&[q1, q2]).unwrap();
        let p = f.point[robot.tool()].translation.vector;
        let x = 0.7 * f64::cos(q1) + 0.4 * f64::cos(q1 + q2);
        let y = 0.7 * f64::sin(q1) + 0.4 * f64::sin(q1 + q2);
        assert!(
            (p.x - x).abs() < 1e-12 && (p.y - y).abs() < 1e-12 && p.z.abs() < 1e-12,
            "{p:?} vs ({x}, {y}, 0)"
        );
        // The tool's x axis points along the last link: rotation by q1 + q2 about z.
        let xa = f.point[robot.tool()].rotation * nalgebra::Vector3::x();
        assert!((xa.x - (q1 + q2).cos()).abs() < 1e-12 && (xa.y - (q1 + q2).sin()).abs() < 1e-12);
    }
}

#[test]
fn prismatic_joint_units_and_direction() {
    // A vertical column (prismatic along z) carrying a horizontal arm; file in mm and deg.
    let robot = robot_from_toml(
        r#"
name = "column"
[units]
length = "mm"
angle = "deg"
[kinematics]
type = "mdh"
[[kinematics.joints]]
name = "lift"
kind = "prismatic"
d = 100.0
limits = [0.0, 500.0]
[[kinematics.joints]]
name = "turn"
alpha = 90.0
[[points]]
name = "tool"
link = "turn"
xyz = [250.0, 0.0, 0.0]
"#,
    );
    // q = 0.2 m lift, 90 deg turn about the (rotated) z axis, which points along -y of the base.
    let f = robot.forward(&[0.2, FRAC_PI_2]).unwrap();
    let p = f.point[robot.tool()].translation.vector;
    // Frame 2 = Tz(0.3) Rx(90°); its x is base x, its y is base z; rotating x about z2 by 90°
    // gives y2 = base z, so the tool is 0.25 m above the joint.
    assert!((p - nalgebra::Vector3::new(0.0, 0.0, 0.55)).norm() < 1e-12, "{p:?}");
    let lim = robot.tree().coordinate_limits()[0].unwrap();
    assert!((lim.upper - 0.5).abs() < 1e-15, "limits are converted to metres");
}

#[test]
fn mimic_coupling_follows_sum_of_sources() {
    // Agile Justin's torso keeps the upper body upright: q3 = -(q1 + q2). Three parallel
    // revolute axes with the third coupled: the last link keeps its orientation.
    let robot = robot_from_toml(
        r#"
name = "torso"
[kinematics]
type = "mdh"
[[kinematics.joints]]
name = "t1"
[[kinematics.joints]]
name = "t2"
a = 0.3
[[kinematics.joints]]
name = "t3"
a = 0.3
mimic = { joints = ["t1", "t2"], multipliers = [-1.0, -1.0] }
[[points]]
name = "tool"
link = "t3"
xyz = [0.1, 0.0, 0.0]
"#,
    );
    assert_eq!(robot.tree().nq(), 2);
    let (q1, q2) = (0.4, -0.9);
    let f = robot.forward(&[q1, q2]).unwrap();
    let t = f.point[robot.tool()];
    let x = 0.3 * q1.cos() + 0.3 * (q1 + q2).cos() + 0.1;
    let y = 0.3 * q1.sin() + 0.3 * (q1 + q2).sin();
    assert!((t.translation.vector - nalgebra::Vector3::new(x, y, 0.0)).norm() < 1e-12);
    assert!(t.rotation.angle() < 1e-12, "upper body stays upright");
}

#[test]
fn classic_dh_single_link_matches_formula() {
    // Rz(q) Tz(d) Tx(a) Rx(alpha): with alpha = 90°, a point on the link's y axis ends up along z.
    let robot = robot_from_toml(
        r#"
name = "dh1"
[kinematics]
type = "dh"
[[kinematics.joints]]
name = "j1"
d = 0.2
a = 0.5
alpha = 1.5707963267948966
[[points]]
name = "tool"
link = "j1"
xyz = [0.0, 0.1, 0.0]
"#,
    );
    let q = 0.6;
    let p = robot.forward(&[q]).unwrap().point[robot.tool()].translation.vector;
    let expected = nalgebra::Vector3::new(0.5 * q.cos(), 0.5 * q.sin(), 0.2 + 0.1);
    assert!((p - expected).norm() < 1e-12, "{p:?} vs {expected:?}");
}

#[test]
fn tree_with_two_branches_evaluates_both() {
    let robot = robot_from_toml(
        r#"
name = "two-arms"
[kinematics]
type = "mdh"
[[kinematics.joints]]
name = "torso"
d = 1.0
[[kinematics.joints]]
name = "right"
parent = "torso"
a = 0.5
[[kinematics.joints]]
name = "left"
parent = "torso"
a = -0.5
[[points]]
name = "tool"
link = "right"
[[points]]
name = "left_hand"
link = "left"
"#,
    );
    let f = robot.forward(&[FRAC_PI_2, 0.0, 0.0]).unwrap();
    let r = f.point[robot.tree().point_index("tool").unwrap()].translation.vector;
    let l = f.point[robot.tree().point_index("left_hand").unwrap()]
        .translation
        .vector;
    assert!((r - nalgebra::Vector3::new(0.0, 0.5, 1.0)).norm() < 1e-12, "{r:?}");
    assert!((l - nalgebra::Vector3::new(0.0, -0.5, 1.0)).norm() < 1e-12, "{l:?}");
}

/// Joint values by name: each named coordinate gets its value and the others none, whatever the
/// order; a fixed or mimic joint, an unknown name and a name given twice are refused.
#[test]
fn joint_values_by_name_land_on_their_coordinates() {
    let robot = crate::common::robot("talos-left-arm.toml");
    let tree = robot.tree();
    let names = tree.coordinate_names();
    let (a, b) = (names[3].as_str(), names[1].as_str());
    let q = tree.coordinates_by_name([(a, 0.25), (b, -0.5)]).unwrap();
    assert_eq!(q.iter().flatten().count(), 2);
    assert_eq!((q[3], q[1]), (Some(0.25), Some(-0.5)));
    let fixed = tree
        .joints()
        .iter()
        .map(|j| j.name.as_str())
        .find(|n| !names.iter().any(|c| c == n))
        .expect("TALOS has fixed joints");
    for (pairs, expected) in [
        (vec![(fixed, 0.0)], "is fixed or follows another joint"),
        (vec![("no_such_joint", 0.0)], "has no joint `no_such_joint`"),
        (vec![(a, 0.0), (a, 1.0)], "is given twice"),
    ] {
        let e = tree.coordinates_by_name(pairs).unwrap_err().to_string();
        assert!(e.contains(expected), "{e}");
    }
}
