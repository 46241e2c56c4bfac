//! URDF robots: FK against hand calculations and the MDH twins, trees, mimic joints, joint
//! order, identifiable parameters, calibrated export and re-import, and bad files.

use std::f64::consts::FRAC_PI_2;

use armcomp_core::model::geom::{rx, rz, tx, tz};
use armcomp_core::support::io::InputLimits;
use armcomp_core::{Robot, RobotFile};
use armcomp_urdf::robot_from_urdf;
use nalgebra::{Isometry3, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::common::{Scratch, random_configurations, robot, root};

fn urdf(name: &str) -> Robot {
    robot_from_urdf(&root().join("robots").join(name), InputLimits::default()).expect("shipped URDFs are valid")
}

fn urdf_text(scratch: &Scratch, name: &str, text: &str) -> Result<Robot, String> {
    robot_from_urdf(&scratch.file(name, text), InputLimits::default()).map_err(|e| e.to_string())
}

/// World position of a body by name.
fn body_position(robot: &Robot, q: &[f64], body: &str) -> Vector3<f64> {
    let f = robot.forward(q).unwrap();
    f.body[robot.tree().body_index(body).unwrap()].translation.vector
}

#[test]
fn urdf_twins_equal_their_mdh_forms_body_by_body() {
    for (urdf_file, mdh_file) in [
        ("rock-drill.urdf", "rock-drill.toml"),
        ("industrial-6dof.urdf", "industrial-6dof.toml"),
    ] {
        let u = urdf(urdf_file);
        let m = robot(mdh_file);
        assert_eq!(u.tree().coordinate_names(), m.tree().coordinate_names());
        for q in random_configurations(&m, 50, 11) {
            let fu = u.forward(&q).unwrap();
            let fm = m.forward(&q).unwrap();
            for (k, b) in m.tree().bodies().iter().enumerate() {
                let ku = u.tree().body_index(&b.name).unwrap();
                let d = (fu.body[ku].translation.vector - fm.body[k].translation.vector).norm();
                let r = (fu.body[ku].rotation.inverse() * fm.body[k].rotation).angle();
                assert!(d < 1e-9 && r < 1e-9, "{urdf_file} {}: {d:e} m, {r:e} rad", b.name);
            }
            let tool_u = fu.point[u.tree().point_index("tool").unwrap()].translation.vector;
            let tool_m = fm.point[m.tool()].translation.vector;
            assert!((tool_u - tool_m).norm() < 1e-9, "{urdf_file} tool");
        }
        // Masses and centres of mass from the URDF inertials equal the robot file's.
        for (k, b) in m.tree().bodies().iter().enumerate() {
            let ku = u.tree().body_index(&b.name).unwrap();
            let (bm, bu) = (m.mass().bodies[k], u.mass().bodies[ku]);
            assert!((bm.mass - bu.mass).abs() < 1e-12, "{urdf_file} {} mass", b.name);
            assert!((bm.com - bu.com).norm() < 1e-12, "{urdf_file} {} com", b.name);
        }
    }
}

#[test]
fn ur5_matches_its_published_dh_table() {
    let r = urdf("ur5.urdf");
    assert_eq!(r.tree().points()[r.tool()].name, "tool0");
    // Home: (a2 + a3, -(d4 + d6), d1 - d5), the figure in every UR5 kinematics note.
    let home = body_position(&r, &[0.0; 6], "tool0");
    assert!(
        (home - Vector3::new(-0.81725, -0.19145, -0.005491)).norm() < 1e-12,
        "{home:?}"
    );
    // Any pose: the classic DH product written out from the published table.
    let d = [0.089159, 0.0, 0.0, 0.10915, 0.09465, 0.0823];
    let a = [0.0, -0.425, -0.39225, 0.0, 0.0, 0.0];
    let alpha = [FRAC_PI_2, 0.0, 0.0, FRAC_PI_2, -FRAC_PI_2, 0.0];
    let mut rng = StdRng::seed_from_u64(5);
    for _ in 0..20 {
        let q: Vec<f64> = (0..6).map(|_| rng.random_range(-3.0..3.0)).collect();
        let mut t = Isometry3::identity();
        for i in 0..6 {
            t = t * rz(q[i]) * tz(d[i]) * tx(a[i]) * rx(alpha[i]);
        }
        let f = r.forward(&q).unwrap();
        let tool = f.body[r.tree().body_index("tool0").unwrap()];
        assert!((tool.translation.vector - t.translation.vector).norm() < 1e-12);
        assert!((tool.rotation.inverse() * t.rotation).angle() < 1e-12);
    }
}

#[test]
fn origin_xyz_rpy_and_axis_follow_the_urdf_convention() {
    // One revolute joint about an oblique axis, its origin turned by roll-pitch-yaw, and a fixed
    // tip 0.2 m along the child's x: the tip is T(xyz) Rz(y) Ry(p) Rx(r) Rot(axis, q) (0.2, 0, 0).
    let s = Scratch::new("urdf-origin");
    let r = urdf_text(
        &s,
        "a.urdf",
        r#"<robot name="a">
  <link name="base"/><link name="arm"/><link name="tip"/>
  <joint name="j" type="revolute">
    <origin xyz="0.1 0.2 0.3" rpy="0.3 -0.4 1.1"/>
    <parent link="base"/><child link="arm"/>
    <axis xyz="0 3 4"/>
    <limit lower="-1" upper="1" effort="1" velocity="1"/>
  </joint>
  <joint name="tip_joint" type="fixed">
    <origin xyz="0.2 0 0"/>
    <parent link="arm"/><child link="tip"/>
  </joint>
</robot>"#,
    )
    .unwrap();
    let q: f64 = 0.7;
    let axis = nalgebra::Unit::new_normalize(Vector3::new(0.0, 0.6, 0.8));
    let (c, sn) = (q.cos(), q.sin());
    // Rodrigues, written out.
    let k = armcomp_core::model::geom::skew(&axis);
    let rot = nalgebra::Matrix3::identity() + k * sn + k * k * (1.0 - c);
    let tip_in_joint = rot * Vector3::new(0.2, 0.0, 0.0);
    let (r0, p0, y0) = (0.3f64, -0.4f64, 1.1f64);
    let rpy = armcomp_core::model::geom::rz(y0) * armcomp_core::model::geom::ry(p0) * rx(r0);
    let expected = Vector3::new(0.1, 0.2, 0.3) + rpy.rotation * tip_in_joint;
    let got = body_position(&r, &[q], "tip");
    assert!((got - expected).norm() < 1e-12, "{got:?} vs {expected:?}");
    let lim = r.tree().coordinate_limits()[0].unwrap();
    assert_eq!((lim.lower, lim.upper), (-1.0, 1.0));
}

const TWO_ARMS: &str = r#"<robot name="two-arms">
  <link name="base"/><link name="torso"/><link name="left"/><link name="right"/>
  <link name="left_hand"/><link name="right_hand"/>
  <joint name="right_shoulder" type="revolute">
    <origin xyz="0 -0.2 0"/><parent link="torso"/><child link="right"/>
    <axis xyz="0 1 0"/><limit lower="-2" upper="2" effort="1" velocity="1"/>
  </joint>
  <joint name="torso_lift" type="prismatic">
    <origin xyz="0 0 0.5"/><parent link="base"/><child link="torso"/>
    <axis xyz="0 0 1"/><limit lower="0" upper="0.3" effort="1" velocity="1"/>
  </joint>
  <joint name="left_shoulder" type="continuous">
    <origin xyz="0 0.2 0"/><parent link="torso"/><child link="left"/>
    <axis xyz="0 1 0"/>
  </joint>
  <joint name="left_wrist" type="fixed">
    <origin xyz="0.3 0 0"/><parent link="left"/><child link="left_hand"/>
  </joint>
  <joint name="right_wrist" type="fixed">
    <origin xyz="0.3 0 0"/><parent link="right"/><child link="right_hand"/>
  </joint>
</robot>"#;

#[test]
fn tree_with_two_end_links_and_file_joint_order() {
    let s = Scratch::new("urdf-tree");
    let r = urdf_text(&s, "two.urdf", TWO_ARMS).unwrap();
    // The right shoulder is listed before the lift it hangs from: q still follows the file.
    assert_eq!(
        r.tree().coordinate_names(),
        ["right_shoulder", "torso_lift", "left_shoulder"]
    );
    assert!(
        r.tree().coordinate_limits()[2].is_none(),
        "continuous joints have no limits"
    );
    let (qr, lift, ql) = (0.4, 0.1, -0.9);
    let q = [qr, lift, ql];
    // About +y by θ, x turns into (cos θ, 0, -sin θ).
    let right = body_position(&r, &q, "right_hand");
    let left = body_position(&r, &q, "left_hand");
    let z = 0.5 + lift;
    assert!((right - Vector3::new(0.3 * qr.cos(), -0.2, z - 0.3 * qr.sin())).norm() < 1e-12);
    assert!((left - Vector3::new(0.3 * ql.cos(), 0.2, z - 0.3 * ql.sin())).norm() < 1e-12);
    // The tool is the last end link the file lists.
    assert_eq!(r.tree().points()[r.tool()].name, "right_hand");
}

#[test]
fn mimic_joints_follow_with_multiplier_and_offset() {
    // A gripper whose second finger mirrors the first; the mimic joint is listed first.
    let s = Scratch::new("urdf-mimic");
    let r = urdf_text(
        &s,
        "g.urdf",
        r#"<robot name="gripper">
  <link name="palm"/><link name="finger_a"/><link name="finger_b"/>
  <joint name="finger_b_joint" type="prismatic">
    <parent link="palm"/><child link="finger_b"/><axis xyz="0 1 0"/>
    <mimic joint="finger_a_joint" multiplier="-1" offset="-0.01"/>
  </joint>
  <joint name="finger_a_joint" type="prismatic">
    <parent link="palm"/><child link="finger_a"/><axis xyz="0 1 0"/>
    <limit lower="0" upper="0.04" effort="1" velocity="1"/>
  </joint>
</robot>"#,
    )
    .unwrap();
    assert_eq!(r.tree().coordinate_names(), ["finger_a_joint"]);
    let a = body_position(&r, &[0.03], "finger_a");
    let b = body_position(&r, &[0.03], "finger_b");
    assert!((a - Vector3::new(0.0, 0.03, 0.0)).norm() < 1e-15);
    assert!((b - Vector3::new(0.0, -0.04, 0.0)).norm() < 1e-15);
}

/// A chain of `n` revolute joints about z, `j{k}` mimicking `j{k-1}` with `mimic` (XML
/// attributes) when given, each 1 mm along x.
fn chain_urdf(n: usize, mimic: Option<&str>) -> String {
    let mut text = String::from("<robot name=\"chain\">\n<link name=\"l0\"/>\n");
    for k in 1..=n {
        let m = match mimic {
            Some(attrs) if k > 1 => format!("<mimic joint=\"j{}\" {attrs}/>", k - 1),
            _ => String::new(),
        };
        text.push_str(&format!(
            "<link name=\"l{k}\"/>\n<joint name=\"j{k}\" type=\"revolute\"><parent link=\"l{}\"/><child link=\"l{k}\"/>\
             <origin xyz=\"0.001 0 0\"/><axis xyz=\"0 0 1\"/><limit lower=\"-1\" upper=\"1\" effort=\"1\" \
             velocity=\"1\"/>{m}</joint>\n",
            k - 1
        ));
    }
    text + "</robot>\n"
}

#[test]
fn a_long_mimic_chain_composes_to_its_first_joint() {
    // j_k = j_(k-1) + 1 mrad, so j_k = q + (k - 1) mrad: with q = 0 the last of n links points
    // at (n - 1) mrad, and the chain's end sits at Σ_k (cos, sin)((k - 1) mrad) mm.
    let n = 3000;
    let s = Scratch::new("urdf-mimic-chain");
    let r = urdf_text(
        &s,
        "chain.urdf",
        &chain_urdf(n, Some("multiplier=\"1\" offset=\"0.001\"")),
    )
    .unwrap();
    assert_eq!(r.tree().coordinate_names(), ["j1"]);
    // Body l_k sits at the end of joint k's origin, turned by the joints before it.
    let end: Vector3<f64> = (1..=n)
        .map(|k| {
            let turned: f64 = (1..k).map(|i| (i - 1) as f64 * 1e-3).sum();
            Vector3::new(turned.cos(), turned.sin(), 0.0) * 1e-3
        })
        .sum();
    let got = body_position(&r, &[0.0], &format!("l{n}"));
    assert!((got - end).norm() < 1e-9, "{got} vs {end}");
}

#[test]
fn a_urdf_of_more_joints_than_a_request_may_hold_is_refused_before_reading_them() {
    let s = Scratch::new("urdf-joint-count");
    let started = std::time::Instant::now();
    let err = urdf_text(&s, "huge.urdf", &chain_urdf(20_000, None)).unwrap_err();
    assert!(err.contains("huge.urdf:1: joints of the URDF 20000: at most "), "{err}");
    assert!(
        started.elapsed() < std::time::Duration::from_secs(15),
        "{:?}",
        started.elapsed()
    );
}

#[test]
fn export_urdf_writes_names_as_xml() {
    let s = Scratch::new("urdf-export-names");
    let urdf = std::fs::read_to_string(root().join("tests/bad_inputs/arm.urdf")).unwrap();
    s.file("arm.urdf", &urdf);
    let model = s.file(
        "arm.toml",
        "name = \"arm\"\ntool = \"a&b<c>\"\n\n[kinematics]\ntype = \"urdf\"\npath = \"arm.urdf\"\n\n[[points]]\nname = \"a&b<c>\"\nlink = \"fore\"\nxyz = [0.2, 0.0, 0.0]\n",
    );
    let out = s.0.join("out.urdf");
    let (code, _, err) = crate::cli::armcomp(&[
        "export-urdf",
        "--model",
        model.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&out).unwrap();
    let xml = roxmltree::Document::parse(&text).unwrap_or_else(|e| panic!("not well-formed: {e}\n{text}"));
    let names: Vec<&str> = xml
        .descendants()
        .filter(|n| n.has_tag_name("link"))
        .filter_map(|n| n.attribute("name"))
        .collect();
    assert!(names.contains(&"a&b<c>"), "{names:?}");
}

#[test]
fn origin_rotation_parameters_stay_identifiable_at_ninety_degrees_pitch() {
    // rock-drill's j2 origin has pitch -90°, where roll and yaw coincide; the small-rotation
    // parameters still turn the boom about three independent axes.
    let r = urdf("rock-drill.urdf");
    let names: Vec<&str> = r.chain_params().iter().map(|p| p.name.as_str()).collect();
    let boom = r.tree().body_index("boom").unwrap();
    let q = [0.1, 0.2, 0.05, 0.3, -0.2, 0.1, 0.02];
    let base = r.tree().forward_rotation(&q, boom);
    let mut cols = nalgebra::Matrix3::zeros();
    for (c, p) in ["j2.rot_u", "j2.rot_v", "j2.offset"].iter().enumerate() {
        let k = names.iter().position(|n| n == p).unwrap();
        let mut v = r.chain_values().to_vec();
        v[k] += 1e-6;
        let moved = r.tree_for(&v).unwrap().forward_rotation(&q, boom);
        cols.set_column(c, &((base.inverse() * moved).scaled_axis() / 1e-6));
    }
    assert!(cols.determinant().abs() > 0.5, "{cols}");
    // Six per joint: 7 moving joints and the fixed tool joint.
    assert_eq!(names.len(), 8 * 6);
}

trait ForwardRotation {
    fn forward_rotation(&self, q: &[f64], body: usize) -> nalgebra::UnitQuaternion<f64>;
}

impl ForwardRotation for armcomp_core::KinematicTree {
    fn forward_rotation(&self, q: &[f64], body: usize) -> nalgebra::UnitQuaternion<f64> {
        let mut ws = armcomp_core::TreeWorkspace::new(self);
        self.forward_into(q, &mut ws);
        ws.body[body].rotation
    }
}

/// Every body's world pose for `q`, by name.
fn poses(r: &Robot, q: &[f64]) -> Vec<(String, Isometry3<f64>)> {
    let f = r.forward(q).unwrap();
    r.tree()
        .bodies()
        .iter()
        .zip(&f.body)
        .map(|(b, p)| (b.name.clone(), *p))
        .collect()
}

fn assert_same_fk(a: &Robot, b: &Robot, qs: &[Vec<f64>], tol: f64) {
    for q in qs {
        for ((na, pa), (nb, pb)) in poses(a, q).iter().zip(poses(b, q)) {
            assert_eq!(*na, nb);
            let d = (pa.translation.vector - pb.translation.vector).norm();
            let r = (pa.rotation.inverse() * pb.rotation).angle();
            assert!(d < tol && r < tol, "{na}: {d:e} m, {r:e} rad");
        }
    }
}

#[test]
fn calibrated_values_survive_the_model_file_and_export_urdf() {
    let s = Scratch::new("urdf-export");
    for name in ["ur5.urdf", "rock-drill.urdf"] {
        let mut r = urdf(name);
        // "Identified" values: every parameter perturbed (mm, mrad).
        let mut rng = StdRng::seed_from_u64(3);
        let values: Vec<f64> = r
            .chain_values()
            .iter()
            .map(|v| v + rng.random_range(-3e-3..3e-3))
            .collect();
        r.set_chain_values(&values).unwrap();
        let qs = random_configurations(&r, 20, 9);
        let nominal = urdf(name);
        assert!(
            (body_position(&r, &qs[0], r.tree().bodies().last().unwrap().name.as_str())
                - body_position(&nominal, &qs[0], nominal.tree().bodies().last().unwrap().name.as_str()))
            .norm()
                > 1e-4,
            "the perturbation must show"
        );

        // The model file (robot file with identified values) loads back to the same FK.
        let model = s.file(&format!("{name}.model.toml"), &toml::to_string(&r.to_file()).unwrap());
        let again = Robot::from_path(&model).unwrap();
        assert_same_fk(&r, &again, &qs, 1e-12);

        // The calibrated URDF, as a bare URDF, gives the same FK, names and masses.
        let out = s.0.join(format!("calibrated-{name}"));
        let (code, _, err) = crate::cli::armcomp(&[
            "export-urdf",
            "--model",
            model.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 0, "{err}");
        let exported = robot_from_urdf(&out, InputLimits::default()).unwrap();
        assert_same_fk(&r, &exported, &qs, 1e-12);
        assert_eq!(exported.mass(), r.mass());
        let text = std::fs::read_to_string(&out).unwrap();
        assert!(text.contains("<inertia ixx=\"0\""), "links are kept as written");
        let t = r.t_meas_base().translation.vector;
        assert!(
            text.contains(&format!("measurement frame: xyz=\"{} {} {}\"", t.x, t.y, t.z)),
            "the measurement frame, which no link holds, is named: {text}"
        );
    }
    // Refuses to overwrite its input, and a non-URDF model.
    let (code, _, err) = crate::cli::armcomp(&[
        "export-urdf",
        "--model",
        "robots/rock-drill.toml",
        "--out",
        s.0.join("x.urdf").to_str().unwrap(),
    ]);
    assert_eq!(code, 1);
    assert!(err.contains("type = \"urdf\""), "{err}");
}

#[test]
fn a_model_names_its_urdf_relative_to_itself_and_moves_with_it() {
    let s = Scratch::new("urdf-relative");
    let cell = s.0.join("cell");
    std::fs::create_dir_all(cell.join("models")).unwrap();
    std::fs::write(cell.join("two.urdf"), TWO_ARMS).unwrap();
    let robot_file = cell.join("cell.toml");
    std::fs::write(
        &robot_file,
        "name = \"cell\"\ntool = \"tool\"\n[kinematics]\ntype = \"urdf\"\npath = \"two.urdf\"\n\
         [[points]]\nname = \"tool\"\nlink = \"right_hand\"\nxyz = [0.01, 0, 0]\n",
    )
    .unwrap();
    let robot = Robot::from_path(&robot_file).unwrap();
    let model = cell.join("models").join("model.toml");
    let text = robot.to_text_for(&model).unwrap();
    assert!(text.contains("path = \"../two.urdf\""), "{text}");
    std::fs::write(&model, text).unwrap();
    // The folder moved whole: the model finds its URDF where it left it.
    let moved = s.0.join("moved");
    std::fs::rename(&cell, &moved).unwrap();
    let again = Robot::from_path(&moved.join("models").join("model.toml")).unwrap();
    let qs = random_configurations(&robot, 10, 4);
    assert_same_fk(&robot, &again, &qs, 1e-12);
}

#[test]
fn robot_file_with_urdf_kinematics_and_overrides() {
    let s = Scratch::new("urdf-robot-file");
    s.file("two.urdf", TWO_ARMS);
    let path = s.file(
        "cell.toml",
        r#"
name = "cell"
tool = "tool"
[units]
length = "mm"
angle = "deg"
[kinematics]
type = "urdf"
path = "two.urdf"
joints = [{ name = "torso_lift", xyz = [0, 0, 600] }]
[[points]]
name = "tool"
link = "right_hand"
xyz = [10, 0, 0]
[[links]]
name = "right"
mass = 2.0
com = [150, 0, 0]
"#,
    );
    let r = Robot::from_path(&path).unwrap();
    let p = r.forward(&[0.0, 0.0, 0.0]).unwrap().point[r.tool()].translation.vector;
    assert!((p - Vector3::new(0.31, -0.2, 0.6)).norm() < 1e-12, "{p:?}");
    let right = r.tree().body_index("right").unwrap();
    assert_eq!(r.mass().bodies[right].mass, 2.0);
    assert!((r.mass().bodies[right].com - Vector3::new(0.15, 0.0, 0.0)).norm() < 1e-15);
    let file: RobotFile = toml::from_str(&toml::to_string(&r.to_file()).unwrap()).unwrap();
    assert!(
        format!("{:?}", file.kinematics).contains("torso_lift"),
        "unchanged overrides are kept"
    );

    let bad = s.file(
        "bad.toml",
        "name = \"b\"\n[kinematics]\ntype = \"urdf\"\npath = \"two.urdf\"\njoints = [{ name = \"nope\" }]\n",
    );
    let err = Robot::from_path(&bad).unwrap_err().to_string();
    assert!(
        err.contains("bad.toml:5: kinematics.joints[0].name") && err.contains("`nope`"),
        "{err}"
    );
}

#[test]
fn fk_takes_joint_values_by_name() {
    let by_name = crate::cli::armcomp(&[
        "fk",
        "--robot",
        "robots/ur5.urdf",
        "--q",
        "shoulder_pan_joint=0.3,elbow_joint=-1.2",
        "--json",
    ]);
    let by_position = crate::cli::armcomp(&["fk", "--robot", "robots/ur5.urdf", "--q", "0.3,0,-1.2,0,0,0", "--json"]);
    assert_eq!(by_name.0, 0, "{}", by_name.2);
    assert_eq!(by_name.1, by_position.1);
    let v: serde_json::Value = serde_json::from_str(&by_name.1).unwrap();
    assert_eq!(v["points"].as_object().unwrap().len(), 8, "every link is a point");
    let (code, _, err) = crate::cli::armcomp(&["fk", "--robot", "robots/ur5.urdf", "--q", "wrist_9=1"]);
    assert_eq!(code, 1);
    assert!(
        err.contains("no joint `wrist_9`") && err.contains("shoulder_pan_joint"),
        "{err}"
    );
}

/// A URDF built around one bad piece.
fn one_joint(joint: &str) -> String {
    format!("<robot name=\"r\">\n<link name=\"base\"/>\n<link name=\"arm\"/>\n{joint}\n</robot>\n")
}

#[test]
fn bad_urdf_files_are_clear_errors() {
    let s = Scratch::new("urdf-bad");
    let ok_joint = |body: &str| {
        format!("<joint name=\"j\" type=\"revolute\">\n<parent link=\"base\"/><child link=\"arm\"/>{body}\n</joint>")
    };
    let cases: Vec<(&str, String, Vec<&str>)> = vec![
        ("malformed", "<robot name=\"r\"><link name=\"a\"></robot>".into(), vec!["malformed XML", "1:"]),
        (
            "missing-parent",
            one_joint("<joint name=\"j\" type=\"fixed\">\n<parent link=\"ghost\"/><child link=\"arm\"/>\n</joint>"),
            vec![":4: joint `j`", "parent link `ghost`"],
        ),
        (
            "loop",
            "<robot name=\"r\"><link name=\"a\"/><link name=\"b\"/>\n<joint name=\"ab\" type=\"fixed\"><parent link=\"a\"/><child link=\"b\"/></joint>\n<joint name=\"ba\" type=\"fixed\"><parent link=\"b\"/><child link=\"a\"/></joint></robot>".into(),
            vec!["closed loop"],
        ),
        (
            "two-parents",
            "<robot name=\"r\"><link name=\"a\"/><link name=\"b\"/><link name=\"c\"/>\n<joint name=\"ac\" type=\"fixed\"><parent link=\"a\"/><child link=\"c\"/></joint>\n<joint name=\"bc\" type=\"fixed\"><parent link=\"b\"/><child link=\"c\"/></joint></robot>".into(),
            vec!["joint `bc`", "also the child of joint `ac`", "loop"],
        ),
        (
            "unknown-type",
            one_joint("<joint name=\"j\" type=\"hinge\">\n<parent link=\"base\"/><child link=\"arm\"/>\n</joint>"),
            vec![":4: joint `j`", "unknown joint type `hinge`"],
        ),
        (
            "nan-origin",
            one_joint(&ok_joint("<origin xyz=\"0 NaN 0\"/>")),
            vec![":4: joint `j`", "<origin xyz>", "finite"],
        ),
        (
            "empty-origin",
            one_joint(&ok_joint("<origin xyz=\"\" rpy=\"0 0 0\"/>")),
            vec!["joint `j`", "<origin xyz>", "got \"\""],
        ),
        (
            "zero-axis",
            one_joint(&ok_joint("<axis xyz=\"0 0 0\"/>")),
            vec!["joint `j`", "non-zero direction"],
        ),
    ];
    for (tag, text, needles) in cases {
        let name = format!("{tag}.urdf");
        let err = urdf_text(&s, &name, &text).expect_err(tag);
        assert!(err.contains(&name), "{tag}: the file is named: {err}");
        for n in needles {
            assert!(err.contains(n), "{tag}: `{n}` missing in: {err}");
        }
    }
}

#[test]
fn ros_package_meshes_are_skipped_with_a_warning_and_stl_boxes_read() {
    let s = Scratch::new("urdf-mesh");
    std::fs::create_dir_all(s.0.join("meshes")).unwrap();
    // An ASCII STL tetrahedron spanning x 0..0.2, y -0.1..0.1, z 0..0.05.
    s.file(
        "meshes/part.stl",
        "solid p\nfacet normal 0 0 1\nouter loop\nvertex 0 -0.1 0\nvertex 0.2 0 0\nvertex 0 0.1 0\nendloop\nendfacet\nfacet normal 0 0 1\nouter loop\nvertex 0 -0.1 0\nvertex 0 0.1 0\nvertex 0 0 0.05\nendloop\nendfacet\nendsolid p\n",
    );
    let r = urdf_text(
        &s,
        "m.urdf",
        r#"<robot name="m"><link name="base">
<collision><geometry><mesh filename="package://some_description/meshes/base.stl"/></geometry></collision>
<collision><origin xyz="1 0 0"/><geometry><mesh filename="meshes/part.stl" scale="2 2 2"/></geometry></collision>
<collision><geometry><mesh filename="meshes/not_copied.stl"/></geometry></collision>
</link></robot>"#,
    )
    .unwrap();
    let w = r.warnings().join("\n");
    assert!(w.contains("some_description") && w.contains("skipped"), "{w}");
    // A plain path to a mesh that is not there loads too, as ROS loads it.
    assert!(w.contains("mesh file not found"), "{w}");
    assert!(w.contains("bounding box"), "{w}");
    let shapes = &r.collision().shapes;
    assert_eq!(shapes.len(), 1);
    let armcomp_core::model::shape::Shape::Box(size) = shapes[0].shape else {
        panic!("{:?}", shapes[0].shape)
    };
    // STL stores single precision.
    assert!(
        (Vector3::from(size) - Vector3::new(0.4, 0.4, 0.1)).norm() < 1e-7,
        "{size:?}"
    );
    let c = shapes[0].local.translation.vector;
    assert!((c - Vector3::new(1.2, 0.0, 0.05)).norm() < 1e-7, "{c:?}");
    // The bare URDF still validates; the warning does not stop it.
    let problems = armcomp_api::validate_file(
        &s.0.join("m.urdf"),
        &armcomp_api::robot_schema(),
        InputLimits::default(),
    );
    assert!(problems.is_empty(), "{problems:?}");
}

#[test]
fn export_urdf_names_a_marker_whose_link_name_is_taken_with_a_free_one() {
    // The point `right` shares its name with a URDF link, and `right_marker_joint` is a joint
    // of the URDF too: the marker's link must become `right_marker_2`. The point `left` takes
    // `left_marker`, which is free.
    let s = Scratch::new("urdf-export-free-name");
    s.file(
        "two.urdf",
        &TWO_ARMS.replace("<joint name=\"right_wrist\"", "<joint name=\"right_marker_joint\""),
    );
    let model = s.file(
        "cell.toml",
        r#"
name = "cell"
tool = "right"
[units]
length = "mm"
angle = "deg"
[kinematics]
type = "urdf"
path = "two.urdf"
[[points]]
name = "right"
link = "right_hand"
xyz = [10, 20, 30]
[[points]]
name = "left"
link = "left_hand"
xyz = [-5, 0, 40]
[measurement]
markers = ["right", "left"]
"#,
    );
    let out = s.0.join("calibrated.urdf");
    let (code, _, log) = crate::cli::armcomp(&[
        "export-urdf",
        "--model",
        model.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{log}");
    for (marker, link) in [("right", "right_marker_2"), ("left", "left_marker")] {
        assert!(
            log.lines().any(|l| l.contains(&format!("marker `{marker}`"))
                && l.contains(&format!(
                    "to a new link `{link}` (the URDF already uses the name `{marker}`)"
                ))),
            "{marker} → {link}: {log}"
        );
    }
    // Read back as a bare URDF, each new link sits where the model puts its point: the
    // offsets of the robot file by hand, from the URDF's fixed wrists at x = 0.3 m.
    let model = Robot::from_path(&model).unwrap();
    let bare = robot_from_urdf(&out, InputLimits::default()).unwrap();
    let q = [0.4, 0.1, -0.9];
    let (a, b) = (model.forward(&q).unwrap(), bare.forward(&q).unwrap());
    for (point, link, local) in [
        ("right", "right_marker_2", Vector3::new(0.31, 0.02, 0.03)),
        ("left", "left_marker", Vector3::new(0.295, 0.0, 0.04)),
    ] {
        let p = a.point[model.tree().point_index(point).unwrap()].translation.vector;
        let l = b.body[bare.tree().body_index(link).unwrap()].translation.vector;
        assert!((p - l).norm() < 1e-12, "{point}: {p:?} vs {l:?}");
        let arm = bare.tree().body_index(point).unwrap();
        let by_hand = b.body[arm] * nalgebra::Point3::from(local);
        assert!((by_hand.coords - l).norm() < 1e-12, "{link}: {by_hand:?} vs {l:?}");
    }
}
