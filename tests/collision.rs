//! Collision checking on constructed cases with known distances, link shapes with a density,
//! and the check-pose command.

use armcomp_core::{CollisionModel, Robot};
use nalgebra::Vector3;

use crate::common::{Scratch, robot_from_toml, root};

/// A planar 3R arm (z axes parallel, links 500 and 400 mm) with a 100 mm sphere on the base,
/// a box on the first link that overlaps it (adjacent: never checked), a 50 mm sphere on the
/// last link 150 mm out, and a floor `floor_mm` below the base.
fn cell(margin_mm: f64, floor_mm: f64) -> Robot {
    robot_from_toml(&format!(
        r#"
name = "cell"
tool = "tip"
[units]
length = "mm"
[kinematics]
type = "mdh"
[[kinematics.joints]]
name = "j1"
[[kinematics.joints]]
name = "j2"
a = 500
[[kinematics.joints]]
name = "j3"
a = 400
[[links]]
name = "base"
shapes = [{{ geometry = {{ shape = "sphere", radius = 100 }} }}]
[[links]]
name = "j1"
shapes = [{{ geometry = {{ shape = "box", size = [400, 60, 60] }}, xyz = [250, 0, 0] }}]
[[links]]
name = "j3"
shapes = [{{ geometry = {{ shape = "sphere", radius = 50 }}, xyz = [150, 0, 0] }}]
[[points]]
name = "tip"
link = "j3"
xyz = [150, 0, 0]
[[fixtures]]
name = "floor"
geometry = {{ shape = "plane" }}
xyz = [0, 0, {}]
[collision]
margin = {margin_mm}
"#,
        -floor_mm
    ))
}

/// Joint values putting the last sphere's centre `d` metres from the base centre: with q1 = 0
/// and q2 = π the third joint sits at (0.1, 0), so |(0.1, 0) + 0.15 (cos φ, sin φ)| = d.
fn q_at_distance(d: f64) -> [f64; 3] {
    let cos_phi = (d * d - 0.1 * 0.1 - 0.15 * 0.15) / (2.0 * 0.1 * 0.15);
    assert!(cos_phi.abs() <= 1.0, "{d} m is out of reach");
    let phi = cos_phi.acos();
    [0.0, std::f64::consts::PI, phi - std::f64::consts::PI]
}

#[test]
fn spheres_overlapping_separated_and_within_margin() {
    let r = cell(0.0, 1000.0);
    let model = CollisionModel::new(r.tree(), r.collision());
    let mut ws = model.workspace();
    // Check the construction independently: the tip is where the sphere centre should be.
    let q = q_at_distance(0.14);
    let tip = r.forward(&q).unwrap().point[r.tool()].translation.vector;
    assert!((tip.norm() - 0.14).abs() < 1e-12);

    // 140 mm apart, radii 100 + 50: 10 mm overlap.
    let c = model.check(&q, &mut ws);
    assert_eq!(c.len(), 1, "{c:?}");
    assert_eq!((c[0].first.as_str(), c[0].second.as_str()), ("base", "j3"));
    assert!((c[0].distance + 0.010).abs() < 1e-9, "{}", c[0].distance);
    assert!((c[0].point_first - tip.normalize() * 0.1).norm() < 1e-9);
    assert!(model.collides(&q, &mut ws));

    // 151 mm apart: 1 mm clear.
    let q = q_at_distance(0.151);
    assert!(model.check(&q, &mut ws).is_empty());
    assert!(!model.collides(&q, &mut ws));

    // With a 2 mm margin the same pose is too close, at a distance of 1 mm.
    let strict = cell(2.0, 1000.0);
    let model = CollisionModel::new(strict.tree(), strict.collision());
    let mut ws = model.workspace();
    let c = model.check(&q, &mut ws);
    assert_eq!(c.len(), 1);
    assert!((c[0].distance - 0.001).abs() < 1e-9, "{}", c[0].distance);
}

#[test]
fn adjacent_links_are_ignored_and_the_floor_is_a_fixture() {
    // The j1 box overlaps the base sphere in every pose; they are adjacent, so never reported.
    let r = cell(0.0, 40.0);
    let model = CollisionModel::new(r.tree(), r.collision());
    // base–j3 and j1–j3 (base–j1 are adjacent), then j1 and j3 against the floor.
    assert_eq!(model.pair_count(), 2 + 2);
    let mut ws = model.workspace();
    // The 50 mm sphere on the plane of the base, a floor 40 mm down: 10 mm into it.
    let c = model.check(&q_at_distance(0.2), &mut ws);
    assert_eq!(c.len(), 1, "{c:?}");
    assert!(c[0].fixture && c[0].second == "floor" && c[0].first == "j3", "{c:?}");
    assert!((c[0].distance + 0.010).abs() < 1e-9);
    assert!((c[0].point_second.z + 0.040).abs() < 1e-12);
}

#[test]
fn link_mass_from_shapes_and_density() {
    // An aluminium box 400 × 60 × 60 mm starting at the joint, and a steel sphere r = 50 mm
    // at its end: mass and centre of mass by hand.
    let r = robot_from_toml(
        r#"
name = "beam"
[units]
length = "mm"
[kinematics]
type = "mdh"
[[kinematics.joints]]
name = "j1"
[[links]]
name = "j1"
density = 2700
shapes = [
  { geometry = { shape = "box", size = [400, 60, 60] }, xyz = [200, 0, 0] },
  { geometry = { shape = "cylinder", radius = 50, length = 100 }, xyz = [400, 0, 0], rpy = [0, 90, 0] },
]
[[points]]
name = "tool"
link = "j1"
"#,
    );
    let m_box = 2700.0 * 0.4 * 0.06 * 0.06;
    let m_cyl = 2700.0 * std::f64::consts::PI * 0.05 * 0.05 * 0.1;
    let body = &r.mass().bodies[1];
    assert!((body.mass - (m_box + m_cyl)).abs() < 1e-9 * body.mass);
    let com_x = (m_box * 0.2 + m_cyl * 0.4) / (m_box + m_cyl);
    assert!(
        (body.com - Vector3::new(com_x, 0.0, 0.0)).norm() < 1e-12,
        "{:?}",
        body.com
    );
}

#[test]
fn bad_shapes_are_clear_errors() {
    let s = Scratch::new("collision-bad");
    let path = s.file(
        "bad.toml",
        r#"name = "b"
[kinematics]
type = "mdh"
[[kinematics.joints]]
name = "j1"
[[links]]
name = "j1"
density = 1000
mass = 2
shapes = [{ geometry = { shape = "sphere", radius = -1 } }]
[[fixtures]]
name = "table"
geometry = { shape = "box", size = [1, 0, 1] }
[collision]
ignore = [["j1", "nowhere"]]
"#,
    );
    let err = Robot::from_path(&path).unwrap_err().to_string();
    for needle in [
        "links[0].shapes[0].geometry: expected a positive length for `radius`",
        "links[0].density: give either `mass` or `density`",
        "fixtures[0].geometry: expected a positive length for `size[1]`",
        "collision.ignore[0][1]: link `nowhere` does not exist",
    ] {
        assert!(err.contains(needle), "`{needle}` missing in:\n{err}");
    }
}

#[test]
fn check_pose_reports_collisions_as_text_and_json() {
    let robot = root().join("tests/data/robots/two-link-collision.urdf");
    let r = robot.to_str().unwrap();
    let (code, out, err) = crate::cli::armcomp(&["check-pose", "--robot", r, "--q", "0,0"]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("no collision (1 shape pairs checked)"), "{out}");
    // Upper arm horizontal, elbow folded back: the lower capsule (radius 40 mm) lies along the
    // top face of the base box, its axis on the face.
    let (code, out, _) = crate::cli::armcomp(&[
        "check-pose",
        "--robot",
        r,
        "--q",
        "shoulder=90,elbow=90",
        "--deg",
        "--json",
    ]);
    assert_eq!(code, 2, "{out}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(v["collides"], true);
    assert_eq!(v["contacts"][0]["first"], "base");
    assert_eq!(v["contacts"][0]["second"], "lower");
    let d = v["contacts"][0]["distance"].as_f64().unwrap();
    assert!((d + 0.04).abs() < 1e-9, "{d}");
}
