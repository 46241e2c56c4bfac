//! Published URDFs (`tests/data/urdf/`, sources in its README) read as ROS reads them: every
//! link's pose against pinocchio's (`reference.json`, written by `make_reference.py`), warnings
//! summarised per kind, the Panda against Franka's published modified-DH table, and a small
//! robot with every construct ROS tolerates against hand calculations.

use std::f64::consts::FRAC_PI_2;
use std::path::PathBuf;

use armcomp_core::Robot;
use armcomp_core::model::geom::{rx, rz, tx, tz};
use armcomp_core::support::io::InputLimits;
use armcomp_urdf::robot_from_urdf;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use serde_json::Value;

use crate::common::{Scratch, root};

fn corpus() -> PathBuf {
    root().join("tests/data/urdf")
}

fn reference() -> Value {
    let text = std::fs::read_to_string(corpus().join("reference.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// `[x, y, z, qx, qy, qz, qw]` as a pose.
fn pose(v: &Value) -> Isometry3<f64> {
    let n: Vec<f64> = v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
    let rotation = UnitQuaternion::from_quaternion(Quaternion::new(n[6], n[3], n[4], n[5]));
    Isometry3::from_parts(Translation3::new(n[0], n[1], n[2]), rotation)
}

/// The joint vector for values by joint name.
fn q_by_name(robot: &Robot, values: &serde_json::Map<String, Value>) -> Vec<f64> {
    robot
        .tree()
        .coordinate_names()
        .iter()
        .map(|n| {
            values[n]
                .as_f64()
                .unwrap_or_else(|| panic!("no reference value for `{n}`"))
        })
        .collect()
}

/// Position (m) and rotation (rad) distance.
fn distance(a: &Isometry3<f64>, b: &Isometry3<f64>) -> (f64, f64) {
    (
        (a.translation.vector - b.translation.vector).norm(),
        (a.rotation.inverse() * b.rotation).angle(),
    )
}

#[test]
fn corpus_link_poses_equal_pinocchio() {
    let reference = reference();
    let robots = reference["robots"].as_object().unwrap();
    assert_eq!(robots.len(), 7);
    for (file, expected) in robots {
        let robot =
            robot_from_urdf(&corpus().join(file), InputLimits::default()).unwrap_or_else(|e| panic!("{file}: {e}"));
        let configurations = expected["configurations"].as_array().unwrap();
        // The independent joints are pinocchio's moving joints less the mimic ones.
        let mimic: Vec<&str> = expected["mimic_joints"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_str().unwrap())
            .collect();
        let mut independent: Vec<&str> = configurations[0]["q"]
            .as_object()
            .unwrap()
            .keys()
            .map(String::as_str)
            .filter(|n| !mimic.contains(n))
            .collect();
        let mut ours: Vec<&str> = robot.tree().coordinate_names().iter().map(String::as_str).collect();
        independent.sort_unstable();
        ours.sort_unstable();
        assert_eq!(ours, independent, "{file}: independent joints");
        for (c, configuration) in configurations.iter().enumerate() {
            let q = q_by_name(&robot, configuration["q"].as_object().unwrap());
            let frames = robot.forward(&q).unwrap();
            let links = configuration["links"].as_object().unwrap();
            assert_eq!(links.len(), robot.tree().bodies().len(), "{file}: every link is a body");
            for (link, p) in links {
                let body = robot
                    .tree()
                    .body_index(link)
                    .unwrap_or_else(|| panic!("{file}: no body `{link}`"));
                let (d, r) = distance(&frames.body[body], &pose(p));
                assert!(
                    d < 1e-9 && r < 1e-9,
                    "{file}, configuration {c}, link `{link}`: {d:e} m, {r:e} rad from pinocchio"
                );
            }
        }
    }
}

#[test]
fn corpus_warnings_are_one_line_per_kind() {
    // Meshes are not vendored: each file's `package://` collision meshes make one line (with
    // no ROS package of these robots installed in ROS_PACKAGE_PATH).
    for (file, lines) in [
        ("ur5_robot.urdf", 1),
        ("panda.urdf", 1),
        ("baxter.urdf", 1),
        ("romeo.urdf", 1),
        ("romeo_laas_small.urdf", 0),
        ("tiago.urdf", 1),
        ("talos_full_v2.urdf", 1),
    ] {
        let robot = robot_from_urdf(&corpus().join(file), InputLimits::default()).unwrap();
        assert_eq!(robot.warnings().len(), lines, "{file}: {:#?}", robot.warnings());
    }
    // TALOS: 47 of its 52 collision elements are meshes, all in `talos_description`.
    let path = corpus().join("talos_full_v2.urdf");
    let talos = robot_from_urdf(&path, InputLimits::default()).unwrap();
    assert_eq!(
        talos.warnings()[0],
        format!(
            "{}: 47 collision meshes skipped (package `talos_description` not found above the URDF or in ROS_PACKAGE_PATH); first: link `torso_2_link` at line 19",
            path.display()
        )
    );
}

#[test]
fn panda_flange_follows_frankas_modified_dh_table() {
    // Franka Emika's published Craig parameters (a, d, α) of joints 1-7 and the flange.
    let a = [0.0, 0.0, 0.0, 0.0825, -0.0825, 0.0, 0.088, 0.0];
    let d = [0.333, 0.0, 0.316, 0.0, 0.384, 0.0, 0.0, 0.107];
    let alpha = [
        0.0, -FRAC_PI_2, FRAC_PI_2, FRAC_PI_2, -FRAC_PI_2, FRAC_PI_2, FRAC_PI_2, 0.0,
    ];
    let robot = robot_from_urdf(&corpus().join("panda.urdf"), InputLimits::default()).unwrap();
    let flange = robot.tree().body_index("panda_link8").unwrap();
    let names: Vec<String> = (1..=7).map(|i| format!("panda_joint{i}")).collect();
    let arm: Vec<usize> = names
        .iter()
        .map(|n| robot.tree().coordinate_names().iter().position(|c| c == n).unwrap())
        .collect();
    let mut q = vec![0.0; robot.tree().coordinate_names().len()];
    for k in 0..5 {
        for (i, &c) in arm.iter().enumerate() {
            q[c] = ((k * 7 + i) as f64 * 0.77).sin() * 1.5;
        }
        let mut t = Isometry3::identity();
        for i in 0..8 {
            let theta = if i < 7 { q[arm[i]] } else { 0.0 };
            t = t * rx(alpha[i]) * tx(a[i]) * rz(theta) * tz(d[i]);
        }
        let (dp, dr) = distance(&robot.forward(&q).unwrap().body[flange], &t);
        assert!(dp < 1e-12 && dr < 1e-12, "{dp:e} m, {dr:e} rad");
    }
    // Home: the flange 88 mm ahead of the base axis at 926 mm, pointing down.
    let home = robot.forward(&vec![0.0; q.len()]).unwrap().body[flange];
    assert!((home.translation.vector - Vector3::new(0.088, 0.0, 0.926)).norm() < 1e-12);
    assert!((home.rotation * Vector3::z() + Vector3::z()).norm() < 1e-12);
}

/// A robot with what ROS tolerates: floating and planar joints, `<axis/>` without `xyz`, a
/// mimic chain, mimics of nothing that moves, textures without files, and the tags of
/// simulators, controllers and sensors.
const LENIENT: &str = r#"<?xml version="1.0"?>
<robot name="lenient" xmlns:xacro="http://www.ros.org/wiki/xacro">
  <material name="grey"><texture/></material>
  <link name="world"/>
  <joint name="mount" type="floating">
    <origin xyz="0 0 1" rpy="0 0 1.5707963267948966"/>
    <parent link="world"/><child link="base"/>
  </joint>
  <link name="base">
    <visual><geometry><box size="0.1 0.1 0.1"/></geometry><material name="skin"><texture/></material></visual>
    <self_collision_checking><geometry><sphere radius="0.1"/></geometry></self_collision_checking>
  </link>
  <joint name="slide" type="planar">
    <origin xyz="0.5 0 0"/><parent link="base"/><child link="carriage"/><axis xyz="0 0 1"/>
  </joint>
  <link name="carriage"/>
  <joint name="shoulder" type="revolute">
    <origin xyz="0 0 0.2"/><parent link="carriage"/><child link="upper"/><axis/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <link name="upper"/>
  <joint name="finger_b" type="prismatic">
    <origin xyz="0.3 0 0"/><parent link="upper"/><child link="b"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
    <mimic joint="finger_c" multiplier="2" offset="0.01"/>
  </joint>
  <joint name="finger_a" type="prismatic">
    <origin xyz="0.3 0 0"/><parent link="upper"/><child link="a"/><axis xyz="0 1 0"/>
    <limit lower="0" upper="0.1" effort="1" velocity="1"/>
  </joint>
  <joint name="finger_c" type="prismatic">
    <origin xyz="0.3 0 0"/><parent link="upper"/><child link="c"/><axis xyz="0 1 0"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
    <mimic joint="finger_a" multiplier="-1"/>
  </joint>
  <joint name="thumb" type="revolute">
    <origin xyz="0 0 0.4"/><parent link="upper"/><child link="t"/><axis xyz="0 0 1"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
    <mimic joint="ghost"/>
  </joint>
  <joint name="pinky" type="continuous">
    <origin xyz="0 0 0.5"/><parent link="upper"/><child link="p"/><axis xyz="0 0 1"/>
    <mimic joint="slide"/>
  </joint>
  <link name="a"/><link name="b"/><link name="c"/><link name="t"/><link name="p"/>
  <gazebo reference="base"><sensor type="camera" name="cam"><plugin name="x" filename="libx.so"/></sensor></gazebo>
  <transmission name="tr"><type>transmission_interface/SimpleTransmission</type>
    <joint name="shoulder"><hardwareInterface>hardware_interface/EffortJointInterface</hardwareInterface></joint>
    <actuator name="motor"><mechanicalReduction>100</mechanicalReduction></actuator>
  </transmission>
  <ros2_control name="system" type="system"><hardware><plugin>mock</plugin></hardware>
    <joint name="shoulder"><command_interface name="position"/></joint>
  </ros2_control>
  <sensor name="imu" update_rate="100"><parent link="base"/><origin xyz="0 0 0"/><imu/></sensor>
  <xacro:property name="unused" value="1"/>
</robot>
"#;

fn line_of(text: &str, needle: &str) -> usize {
    text.lines().position(|l| l.contains(needle)).unwrap() + 1
}

#[test]
fn what_ros_tolerates_loads_with_hand_computed_frames() {
    let s = Scratch::new("urdf-lenient");
    let path = s.file("lenient.urdf", LENIENT);
    let robot = robot_from_urdf(&path, InputLimits::default()).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        robot.tree().coordinate_names(),
        ["shoulder", "finger_a", "thumb", "pinky"]
    );
    let (qs, qa, qt, qp) = (0.7, 0.04, -0.3, 2.5);
    let frames = robot.forward(&[qs, qa, qt, qp]).unwrap();
    let at = |link: &str| frames.body[robot.tree().body_index(link).unwrap()];
    // Floating and planar joints stay at their origins; the shoulder turns about x.
    let base = Isometry3::translation(0.0, 0.0, 1.0) * rz(FRAC_PI_2);
    let upper = base * tx(0.5) * tz(0.2) * rx(qs);
    let offset = |x: f64, y: f64, z: f64| Isometry3::translation(x, y, z);
    // c = -a; b = 2c + 0.01 (a mimic of a mimic); thumb and pinky move on their own.
    let expected = [
        ("carriage", base * tx(0.5)),
        ("upper", upper),
        ("a", upper * offset(0.3, qa, 0.0)),
        ("c", upper * offset(0.3, -qa, 0.0)),
        ("b", upper * offset(0.3, -2.0 * qa + 0.01, 0.0)),
        ("t", upper * tz(0.4) * rz(qt)),
        ("p", upper * tz(0.5) * rz(qp)),
    ];
    for (link, want) in expected {
        let (d, r) = distance(&at(link), &want);
        assert!(d < 1e-12 && r < 1e-12, "{link}: {d:e} m, {r:e} rad");
    }
    let file = path.display();
    assert_eq!(
        robot.warnings(),
        [
            format!(
                "{file}: 2 joints held at their origins (type `floating` or `planar`, read as fixed: only revolute, continuous and prismatic joints move); first: joint `mount` at line {}",
                line_of(LENIENT, "name=\"mount\"")
            ),
            format!(
                "{file}: 2 <mimic> elements ignored (naming no moving joint: such joints move on their own, as pinocchio reads them); first: joint `thumb` at line {}",
                line_of(LENIENT, "name=\"thumb\"")
            ),
        ]
    );
    // The calibrated copy keeps every ignored element as written.
    let doc = armcomp_urdf::UrdfDocument::read(&path, InputLimits::default()).unwrap();
    let every_joint: Vec<&str> = doc.joints.iter().map(|j| j.name.as_str()).collect();
    let text = armcomp_urdf::rewrite(&doc, robot.tree(), &every_joint);
    for kept in [
        "<texture/>",
        "<ros2_control",
        "<xacro:property",
        "<mimic joint=\"ghost\"/>",
    ] {
        assert!(text.contains(kept), "{kept}");
    }
}

#[test]
fn urdf_errors_name_file_line_and_element_once() {
    let s = Scratch::new("urdf-error-text");
    let path = s.file(
        "bad.urdf",
        "<robot name=\"r\">\n<link name=\"base\"/>\n<link name=\"arm\"/>\n<joint name=\"j\" type=\"spherical\">\n<parent link=\"base\"/><child link=\"arm\"/>\n</joint>\n</robot>\n",
    );
    let want = format!(
        "{}:4: joint `j`: type `spherical` is not supported; expected revolute, continuous, prismatic, fixed, floating or planar",
        path.display()
    );
    assert_eq!(
        robot_from_urdf(&path, InputLimits::default()).unwrap_err().to_string(),
        want
    );
    let problems = armcomp_api::validate_file(&path, &armcomp_api::robot_schema(), InputLimits::default());
    assert_eq!(problems.iter().map(ToString::to_string).collect::<Vec<_>>(), [want]);
}
