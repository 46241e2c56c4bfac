//! `armcomp export-ros`: a UR5 model with known joint offsets, a shifted joint origin, a marker
//! and a measurement frame exported; each file read back and checked against those known
//! values, the URDF against the model, the hashes against `sha256sum`.

use std::path::{Path, PathBuf};
use std::process::Command;

use armcomp_core::Robot;
use armcomp_core::support::io::InputLimits;
use armcomp_urdf::{UrdfDocument, robot_from_urdf};
use nalgebra::{Unit, UnitQuaternion, Vector3};

use crate::cli::armcomp;
use crate::common::{Scratch, random_configurations, root};

/// The offsets put into the model (rad), by joint.
const OFFSETS: [(&str, f64); 2] = [("shoulder_lift_joint", 0.0123), ("elbow_joint", -0.0071)];
/// The measurement frame: the base's position (m) and roll, pitch, yaw (rad) in it.
const BASE_XYZ: [f64; 3] = [1.25, -0.5, 0.2];
const BASE_RPY: [f64; 3] = [0.1, -0.2, 0.3];

/// A UR5 robot file whose joints `OFFSETS` turn about their axes by those angles (written as
/// origin overrides, as calibration writes them), with `wrist_1_joint` shifted by `shift` (m),
/// a marker on `tool0` and the measurement frame `BASE_*`.
fn model_text(shift: [f64; 3]) -> String {
    let urdf = root().join("robots/ur5.urdf");
    let doc = UrdfDocument::load(&urdf, InputLimits::default()).unwrap();
    let mut overrides = String::new();
    for j in &doc.joints {
        let offset = OFFSETS.iter().find(|(n, _)| *n == j.name).map(|(_, v)| *v);
        let moved = j.name == "wrist_1_joint";
        if offset.is_none() && !moved {
            continue;
        }
        let nominal = UnitQuaternion::from_euler_angles(j.rpy[0], j.rpy[1], j.rpy[2]);
        let axis = Unit::new_normalize(Vector3::from(j.axis));
        let turned = nominal * UnitQuaternion::from_axis_angle(&axis, offset.unwrap_or(0.0));
        let (r, p, y) = turned.euler_angles();
        let xyz = if moved {
            [j.xyz[0] + shift[0], j.xyz[1] + shift[1], j.xyz[2] + shift[2]]
        } else {
            j.xyz
        };
        overrides.push_str(&format!(
            "[[kinematics.joints]]\nname = \"{}\"\nxyz = {xyz:?}\nrpy = [{r:?}, {p:?}, {y:?}]\n\n",
            j.name
        ));
    }
    format!(
        "name = \"ur5-cell\"\ntool = \"marker\"\n[units]\nlength = \"m\"\nangle = \"rad\"\n\n[kinematics]\ntype = \"urdf\"\npath = {:?}\n\n{overrides}[[points]]\nname = \"marker\"\nlink = \"tool0\"\nxyz = [0.01, -0.02, 0.05]\n\n[measurement]\nmarkers = [\"marker\"]\nbase_xyz = {BASE_XYZ:?}\nbase_rpy = {BASE_RPY:?}\n",
        urdf.to_str().unwrap()
    )
}

/// `sha256sum FILE`'s hash.
fn sha256sum(path: &Path) -> String {
    let out = Command::new("sha256sum").arg(path).output().expect("sha256sum runs");
    String::from_utf8(out.stdout)
        .unwrap()
        .split_whitespace()
        .next()
        .unwrap()
        .to_string()
}

fn yaml(path: &Path) -> serde_norway::Value {
    serde_norway::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn export(model: &Path, out: &Path, extra: &[&str]) -> (i32, String) {
    let mut args = vec![
        "export-ros",
        "--model",
        model.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    let (code, _, err) = armcomp(&args);
    (code, err)
}

#[test]
fn export_ros_writes_what_reproduces_the_model() {
    let s = Scratch::new("export-ros");
    let shift = [0.002, -0.001, 0.003];
    let model_path = s.file("model.toml", &model_text(shift));
    let out = s.0.join("ros");
    let (code, err) = export(&model_path, &out, &["--samples", "50", "--seed", "4"]);
    assert_eq!(code, 0, "{err}");
    let model = Robot::from_path(&model_path).unwrap();
    let qs = random_configurations(&model, 40, 8);

    // The URDF, read back as a bare URDF, puts the marker and every link where the model does.
    let urdf: PathBuf = out.join("calibrated.urdf");
    let reloaded = robot_from_urdf(&urdf, InputLimits::default()).unwrap();
    let marker = reloaded
        .tree()
        .points()
        .iter()
        .position(|p| p.name == "marker")
        .unwrap();
    for q in &qs {
        let a = model.forward(q).unwrap().point[model.tool()].translation.vector;
        let b = reloaded.forward(q).unwrap().point[marker].translation.vector;
        assert!((a - b).norm() < 1e-9, "{:e} m", (a - b).norm());
    }

    // The offsets are the ones put in, every other joint's 0, in the documented shape.
    let offsets = yaml(&out.join("joint_offsets.yaml"));
    let table = &offsets["/**"]["ros__parameters"]["joint_offsets"];
    let names: Vec<String> = serde_norway::from_value(table["names"].clone()).unwrap();
    let values: Vec<f64> = serde_norway::from_value(table["values"].clone()).unwrap();
    let units: Vec<String> = serde_norway::from_value(table["units"].clone()).unwrap();
    assert_eq!(names, model.tree().coordinate_names());
    assert!(units.iter().all(|u| u == "rad"));
    for (name, value) in names.iter().zip(&values) {
        let expected = OFFSETS.iter().find(|(n, _)| n == name).map_or(0.0, |(_, v)| *v);
        assert!((value - expected).abs() < 1e-12, "{name}: {value} vs {expected}");
    }
    // Their sign: the source URDF at q + offset is the model without the shift at q.
    let unshifted = s.file("unshifted.toml", &model_text([0.0; 3]));
    let unshifted = Robot::from_path(&unshifted).unwrap();
    let source = robot_from_urdf(&root().join("robots/ur5.urdf"), InputLimits::default()).unwrap();
    let tool0 = source.tree().points().iter().position(|p| p.name == "tool0").unwrap();
    let tool0_body = unshifted
        .tree()
        .bodies()
        .iter()
        .position(|b| b.name == "tool0")
        .unwrap();
    for q in &qs {
        let shifted_q: Vec<f64> = q.iter().zip(&values).map(|(q, o)| q + o).collect();
        let a = unshifted.forward(q).unwrap().body[tool0_body].translation.vector;
        let b = source.forward(&shifted_q).unwrap().point[tool0].translation.vector;
        assert!((a - b).norm() < 1e-12, "{:e} m", (a - b).norm());
    }

    // The static transform is the measurement frame of the file.
    let transform = &yaml(&out.join("measurement_frame.yaml"))["static_transform"];
    let translation: [f64; 3] = serde_norway::from_value(transform["translation"].clone()).unwrap();
    let [x, y, z, w]: [f64; 4] = serde_norway::from_value(transform["rotation_xyzw"].clone()).unwrap();
    let arguments: Vec<String> = serde_norway::from_value(transform["arguments"].clone()).unwrap();
    assert_eq!(translation, BASE_XYZ);
    let expected = UnitQuaternion::from_euler_angles(BASE_RPY[0], BASE_RPY[1], BASE_RPY[2]);
    let got = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z));
    assert!(got.angle_to(&expected) < 1e-12 && w >= 0.0);
    assert_eq!(arguments.len(), 9);
    assert_eq!(arguments[7..], ["tracker".to_string(), "base_link".to_string()]);
    let numbers: Vec<f64> = arguments[..7].iter().map(|a| a.parse().unwrap()).collect();
    assert_eq!(numbers, [translation.to_vec(), vec![x, y, z, w]].concat());

    // The manifest: every file's hash as sha256sum computes it, the model's, the check made.
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    for f in manifest["files"].as_array().unwrap() {
        let name = f["file"].as_str().unwrap();
        assert_eq!(f["sha256"], sha256sum(&out.join(name)), "{name}");
    }
    assert_eq!(manifest["files"].as_array().unwrap().len(), 3);
    assert_eq!(manifest["model"]["sha256"], sha256sum(&model_path));
    assert_eq!(
        manifest["source_urdf"]["sha256"],
        sha256sum(&root().join("robots/ur5.urdf"))
    );
    assert!(manifest["fitted_on"].as_str().unwrap().starts_with("unknown"));
    let check = &manifest["reload_check"];
    assert_eq!(check["at"]["sampled"]["n"], 50);
    assert_eq!(check["configurations"], 50);
    assert!(check["max_deviation_m"].as_f64().unwrap() < 1e-9);
    // The shift of wrist_1 is what the offsets alone miss: a few millimetres at the tool.
    let missed = manifest["offsets_only_max_deviation_m"].as_f64().unwrap();
    let shift_norm = Vector3::from(shift).norm();
    assert!(missed > 0.3 * shift_norm && missed < 3.0 * shift_norm, "{missed}");
}

#[test]
fn export_ros_checks_at_measured_configurations_and_refuses_to_overwrite_inputs() {
    let s = Scratch::new("export-ros-data");
    let model_path = s.file("model.toml", &model_text([0.0; 3]));
    let model = Robot::from_path(&model_path).unwrap();
    let data = armcomp_core::algorithms::simulate::simulate(
        &model,
        &random_configurations(&model, 12, 2),
        armcomp_core::algorithms::simulate::SimulateParams {
            noise_std: 0.0,
            seed: 1,
        },
    )
    .unwrap();
    let data_path = s.file(
        "data.csv",
        &armcomp_core::data::measurement::write_csv(&data, model.tree(), model.units()),
    );
    let out = s.0.join("ros");
    let (code, err) = export(&model_path, &out, &["--data", data_path.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    let manifest: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("manifest.json")).unwrap()).unwrap();
    let at = &manifest["reload_check"]["at"]["measured"];
    assert_eq!(at["rows"], 12);
    assert_eq!(at["sha256"], sha256sum(&data_path));
    // Offsets alone reproduce a model whose only change is its offsets.
    assert!(manifest["offsets_only_max_deviation_m"].as_f64().unwrap() < 1e-12);

    // An output folder holding an input is refused, and left as it was.
    let (code, err) = export(&model_path, &s.0, &[]);
    assert_eq!(code, 1);
    assert!(
        err.contains("model.toml") || err.contains("not part of a report"),
        "{err}"
    );
    assert!(!s.0.join("calibrated.urdf").exists());

    // A model with error models URDF cannot hold is refused without --rigid-only; nothing is
    // written.
    let elastic = root().join("robots/field-arm-elastic.toml");
    let out = s.0.join("elastic");
    let (code, err) = export(&elastic, &out, &[]);
    assert_eq!(code, 1);
    assert!(err.contains("URDF cannot express"), "{err}");
    assert!(!out.exists());
}
