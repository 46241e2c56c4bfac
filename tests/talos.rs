//! TALOS as a user brings it: the ROS URDF as published and the tracker CSV with only the
//! measured chain's joints. Held-out errors at the levels FIGAROH publishes for the same
//! splits (data/talos-left-arm/README.md) are the independent reference.

use std::process::Command;

use armcomp_core::algorithms::evaluate::{ErrorStats, model_errors};
use armcomp_core::analysis::prior_choice::{DEFAULT_GRID, choose_prior_scale};
use armcomp_core::calibrate::{CalibrationParams, calibrate};
use armcomp_core::data::measurement::{MeasurementSet, RowSelection, parse_csv, read_csv};
use armcomp_core::data::split::{FoldBy, FoldPlan};
use armcomp_core::support::io::InputLimits;

use crate::common::{Scratch, random_configurations, robot, root};

fn data() -> (armcomp_core::Robot, MeasurementSet) {
    let r = robot("talos-left-arm.toml");
    let set = read_csv(
        &root().join("data/talos-left-arm/measurements.csv"),
        &r.csv_layout(),
        InputLimits::default(),
    )
    .unwrap();
    (r, set)
}

fn rows(set: &MeasurementSet, spec: &str) -> Vec<armcomp_core::data::measurement::Sample> {
    set.select_rows(&spec.parse::<RowSelection>().unwrap()).samples
}

/// Held-out RMSE (mm) of `identify` fitted on `train` rows, scored on `test` rows.
fn held_out_rms(identify: &str, use_priors: bool, train: &str, test: &str) -> f64 {
    let (r, set) = data();
    let params = CalibrationParams {
        identify: identify.split(',').map(String::from).collect(),
        use_priors,
        ..Default::default()
    };
    let fitted = calibrate(&r, &rows(&set, train), &params, &mut |_| {}).unwrap();
    assert!(fitted.report.converged, "{}", fitted.report.stop_reason);
    ErrorStats::from_errors(&model_errors(&fitted.robot, &rows(&set, test))).rms_mm
}

#[test]
fn the_measured_chain_is_the_torso_and_left_arm() {
    let (r, set) = data();
    assert_eq!(set.samples.len(), 61);
    let chain = r.measured_joint_names();
    assert_eq!(chain.len(), 9, "{chain:?}");
    assert_eq!(chain[0], "torso_1_joint");
    assert_eq!(chain[8], "arm_left_7_joint");
    // Everything else holds still: at 0, or mid-range where 0 is outside the limits (the
    // knees).
    let measured = r.measured_coordinates();
    assert!(r.tree().nq() > 30);
    let limits = r.tree().coordinate_limits();
    let mut mid_range = 0;
    for s in &set.samples {
        for (c, v) in s.q.iter().enumerate().filter(|(c, _)| !measured[*c]) {
            let expected = match limits[c] {
                Some(l) if l.lower > 0.0 || l.upper < 0.0 => {
                    mid_range += 1;
                    0.5 * (l.lower + l.upper)
                }
                _ => 0.0,
            };
            assert_eq!(*v, expected, "{}", r.tree().coordinate_names()[c]);
        }
    }
    assert!(mid_range > 0);
    // The timestamp column is ignored with one notice.
    assert_eq!(set.warnings.len(), 1, "{:?}", set.warnings);
    assert!(set.warnings[0].contains("`t`"), "{:?}", set.warnings);
}

#[test]
fn missing_measured_chain_columns_are_named_together() {
    let (r, _) = data();
    let text = std::fs::read_to_string(root().join("data/talos-left-arm/measurements.csv")).unwrap();
    // Drop the torso_2_joint and arm_left_4_joint columns (6th and 10th).
    let cut: String = text
        .lines()
        .map(|l| {
            l.split(',')
                .enumerate()
                .filter(|(i, _)| *i != 5 && *i != 9)
                .map(|(_, v)| v)
                .collect::<Vec<_>>()
                .join(",")
                + "\n"
        })
        .collect();
    let e = parse_csv(&cut, "m.csv".as_ref(), &r.csv_layout())
        .unwrap_err()
        .to_string();
    assert!(e.contains("m.csv:1"), "{e}");
    assert!(
        e.contains("2 joint(s)") && e.contains("torso_2_joint[deg]") && e.contains("arm_left_4_joint[deg]"),
        "{e}"
    );
}

#[test]
fn registration_reproduces_figaroh_on_both_splits() {
    // FIGAROH 1.0.2: 5.84 (interleaved) and 9.49 mm (time split) held out.
    let interleaved = held_out_rms("base,markers", true, "even", "odd");
    let time = held_out_rms("base,markers", true, "..40", "40..");
    assert!((interleaved - 5.84).abs() < 0.01, "{interleaved}");
    assert!((time - 9.49).abs() < 0.01, "{time}");
}

#[test]
fn joint_offsets_reproduce_figaroh_on_both_splits() {
    // FIGAROH's plain least squares: 2.14 and 3.19 mm held out.
    let interleaved = held_out_rms("base,markers,offsets", false, "even", "odd");
    let time = held_out_rms("base,markers,offsets", false, "..40", "40..");
    assert!((interleaved - 2.14).abs() < 0.05, "{interleaved}");
    assert!((time - 3.19).abs() < 0.05, "{time}");
}

/// FIGAROH's `full_params` level: its 38 parameters for each split (its QR selection, from
/// tests/data/figaroh_talos_full_params.txt), no priors, run to convergence. FIGAROH 1.0.2:
/// 0.39 / 1.34 mm (interleaved) and 0.41 / 0.92 mm (time split) train / held out.
#[test]
fn full_params_reproduce_figaroh_given_its_parameters() {
    let text = std::fs::read_to_string(root().join("tests/data/figaroh_talos_full_params.txt")).unwrap();
    let chain = |split: &str| -> Vec<String> {
        let line = text.lines().find_map(|l| l.strip_prefix(&format!("{split}="))).unwrap();
        ["base", "markers"]
            .into_iter()
            .chain(line.split(','))
            .map(String::from)
            .collect()
    };
    let (r, set) = data();
    for (split, train, test, train_rms, held_rms) in [
        ("interleaved", "even", "odd", 0.39, 1.34),
        ("time", "..40", "40..", 0.41, 0.92),
    ] {
        let params = CalibrationParams {
            identify: chain(split),
            use_priors: false,
            max_iterations: 5000,
            restarts: 0,
            ..Default::default()
        };
        let fitted = calibrate(&r, &rows(&set, train), &params, &mut |_| {}).unwrap();
        assert!(fitted.report.converged, "{split}: {}", fitted.report.stop_reason);
        // The rows determine every one of them: nothing is fixed.
        let id = &fitted.report.identifiability;
        assert_eq!((id.n_params, id.rank), (38, 38), "{split}: {}", id.message);
        let rms = |spec: &str| ErrorStats::from_errors(&model_errors(&fitted.robot, &rows(&set, spec))).rms_mm;
        let (t, h) = (rms(train), rms(test));
        assert!(
            (t - train_rms).abs() < 0.005 && (h - held_rms).abs() < 0.005,
            "{split}: {t} / {h} mm"
        );
    }
}

#[test]
fn a_zero_guess_of_the_measurement_frame_does_not_leak_into_the_chain() {
    // The file's base frame is the identity, 120 mm and several degrees from the truth; the
    // torso joints' origins must still stay near the URDF's.
    let (r, set) = data();
    let params = CalibrationParams {
        identify: vec!["base".into(), "markers".into(), "geometry".into()],
        ..Default::default()
    };
    let fitted = calibrate(&r, &rows(&set, "even"), &params, &mut |_| {}).unwrap();
    assert!(fitted.report.registered);
    for p in fitted.report.params.iter().filter(|p| p.name.starts_with("torso_")) {
        let moved = (p.value - p.initial).abs();
        let limit = if p.unit == "m" { 0.01 } else { 2f64.to_radians() };
        assert!(moved < limit, "{} moved by {moved}", p.name);
    }
}

#[test]
fn the_prior_scale_is_chosen_on_training_folds_deterministically() {
    let (r, set) = data();
    let train = rows(&set, "..40");
    let params = CalibrationParams {
        identify: vec!["base".into(), "markers".into(), "geometry".into()],
        ..Default::default()
    };
    let grid = [0.1, 1.0, 10.0];
    let plan = FoldPlan {
        k: 4,
        seed: 3,
        by: FoldBy::Poses,
    };
    let a = choose_prior_scale(&r, &train, &params, &grid, &plan, &|_| {}).unwrap();
    let b = choose_prior_scale(&r, &train, &params, &grid, &plan, &|_| {}).unwrap();
    assert_eq!(a, b);
    assert!(grid.contains(&a.scale));
    let best = a.scores.iter().map(|s| s.held_out_rms_mm).fold(f64::INFINITY, f64::min);
    assert_eq!(
        a.scores.iter().find(|s| s.scale == a.scale).unwrap().held_out_rms_mm,
        best
    );
    assert!(DEFAULT_GRID.contains(&f64::INFINITY));
}

/// `armcomp export-urdf` of `model` into `calibrated.urdf` in `s`: the file and the output.
fn export_urdf(s: &Scratch, model: &std::path::Path) -> (std::path::PathBuf, String) {
    let out = s.0.join("calibrated.urdf");
    let (ok, log) = armcomp(&[
        "export-urdf",
        "--model",
        model.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{log}");
    (out, log)
}

fn armcomp(args: &[&str]) -> (bool, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_armcomp")).args(args).output().unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).to_string() + &String::from_utf8_lossy(&out.stderr),
    )
}

#[test]
fn held_out_rows_do_not_change_an_auto_prior_calibration() {
    // Training on the even rows with the prior chosen by cross-validation: the odd rows may
    // hold anything without changing a byte of the model.
    let s = Scratch::new("talos-auto");
    let original = std::fs::read_to_string(root().join("data/talos-left-arm/measurements.csv")).unwrap();
    let corrupted: String = original
        .lines()
        .enumerate()
        .map(|(i, l)| {
            if i >= 1 && (i - 1) % 2 == 1 {
                l.replacen(",0.", ",9.", 1) + "\n"
            } else {
                l.to_string() + "\n"
            }
        })
        .collect();
    let robot_file = root().join("robots/talos-left-arm.toml");
    let robot_file = robot_file.to_str().unwrap();
    let mut models = Vec::new();
    for (name, text) in [("a.csv", &original), ("b.csv", &corrupted)] {
        let data = s.file(name, text);
        let out = s.0.join(format!("{name}.toml"));
        let (ok, log) = armcomp(&[
            "calibrate",
            "--robot",
            robot_file,
            "--data",
            data.to_str().unwrap(),
            "--rows",
            "even",
            "--identify",
            "base,markers,geometry",
            "--prior",
            "auto",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(ok, "{log}");
        assert!(log.contains("prior scale chosen by 5-fold cross-validation"), "{log}");
        models.push(std::fs::read_to_string(out).unwrap());
    }
    assert_eq!(models[0], models[1]);
}

#[test]
fn export_urdf_rewrites_only_identified_joints_and_matches_the_model() {
    let s = Scratch::new("talos-export");
    let (r, set) = data();
    let params = CalibrationParams {
        identify: vec!["base".into(), "markers".into(), "offsets".into()],
        use_priors: false,
        ..Default::default()
    };
    let fitted = calibrate(&r, &rows(&set, "even"), &params, &mut |_| {}).unwrap();
    let model = s.file(
        "model.toml",
        &fitted.robot.to_file().to_text_for("model.toml".as_ref()).unwrap(),
    );
    let (out, log) = export_urdf(&s, &model);
    // Byte-identical outside the identified joints' elements.
    let original = std::fs::read_to_string(root().join("data/talos-left-arm/talos_full_v2.urdf")).unwrap();
    let exported = std::fs::read_to_string(&out).unwrap();
    let doc = armcomp_urdf::UrdfDocument::parse("x.urdf".as_ref(), original.clone(), InputLimits::default()).unwrap();
    let identified: Vec<&armcomp_urdf::UrdfJoint> = doc
        .joints
        .iter()
        .filter(|j| fitted.robot.measured_joint_names().contains(&j.name))
        .collect();
    assert!(!identified.is_empty());
    let first = identified.iter().map(|j| j.range.start).min().unwrap();
    let last = identified.iter().map(|j| j.range.end).max().unwrap();
    assert_eq!(original[..first], exported[..first]);
    // The identified marker is added last, as a link of its own on a fixed joint.
    let added = exported.rfind("  <link name=\"marker\"/>").unwrap();
    let end = exported.rfind("</robot>").unwrap();
    assert!(exported[added..end].contains("<parent link=\"gripper_left_base_link\"/>"));
    let without = format!("{}{}", &exported[..added], &exported[end..]);
    let tail = original.len() - last;
    assert_eq!(original[last..], without[without.len() - tail..]);
    // The exported URDF, read as any URDF, puts the marker's link and the marker where the
    // model does.
    let bare = armcomp_urdf::robot_from_urdf(&out, InputLimits::default()).unwrap();
    let link = bare.tree().body_index("gripper_left_base_link").unwrap();
    let marker = bare.tree().point_index("marker").unwrap();
    let model = &fitted.robot;
    let marker_body = model.tree().points()[model.tool()].body;
    assert!(model.tree().points()[model.tool()].local.translation.vector.norm() > 1e-3);
    for q in random_configurations(model, 5, 11) {
        let (a, b) = (model.forward(&q).unwrap(), bare.forward(&q).unwrap());
        for (a, b) in [
            (a.body[marker_body], b.body[link]),
            (a.point[model.tool()], b.point[marker]),
        ] {
            assert!((a.translation.vector - b.translation.vector).norm() < 1e-9);
            assert!(a.rotation.angle_to(&b.rotation) < 1e-9);
        }
    }
    // The table says what was written and what was not.
    for (status, item) in [
        ("written ", "joint `arm_left_1_joint`"),
        ("written ", "marker `marker`"),
        ("not written ", "measurement frame"),
    ] {
        assert!(row(&log, status, item), "{status}{item}: {log}");
    }
}

/// Whether `log` has a table row of `status` about `item`.
fn row(log: &str, status: &str, item: &str) -> bool {
    log.lines()
        .any(|l| l.trim_start().starts_with(status) && l.contains(item))
}

/// Values a fit leaves at rounding level are written as exactly 0, with a count in the table,
/// and the marker's offset is written; the export still matches the model.
#[test]
fn export_urdf_writes_rounding_as_zero() {
    let s = Scratch::new("talos-export-zero");
    let urdf = root().join("data/talos-left-arm/talos_full_v2.urdf");
    let model = s.file(
        "model.toml",
        &format!(
            r#"name = "talos-left-arm"
kinematics = {{ type = "urdf", path = {:?}, joints = [{{ name = "arm_left_3_joint", xyz = [-3.09e-11, 0.0, 2e-9] }}] }}
points = [{{ name = "marker", link = "gripper_left_base_link", xyz = [0.01, 4e-11, -0.02] }}]
tool = "marker"

[measurement]
markers = ["marker"]
"#,
            urdf.display().to_string()
        ),
    );
    let (out, log) = export_urdf(&s, &model);
    assert!(row(&log, "written as 0 ", "2 value(s)"), "{log}");
    let exported = std::fs::read_to_string(&out).unwrap();
    assert!(
        exported.contains("<origin xyz=\"0.0 0.0 2e-9\" rpy=\"0.0 0.0 0.0\"/>"),
        "{exported}"
    );
    assert!(
        exported.contains("<origin xyz=\"0.01 0.0 -0.02\" rpy=\"0.0 0.0 0.0\"/>"),
        "{exported}"
    );
    let r = armcomp_core::Robot::from_path(&model).unwrap();
    let bare = armcomp_urdf::robot_from_urdf(&out, InputLimits::default()).unwrap();
    let marker = bare.tree().point_index("marker").unwrap();
    for q in random_configurations(&r, 5, 12) {
        let a = r.forward(&q).unwrap().point[r.tool()].translation.vector;
        let b = bare.forward(&q).unwrap().point[marker].translation.vector;
        assert!((a - b).norm() < 1e-9, "{:e}", (a - b).norm());
    }
}
