//! The command line, run as a user would.

use std::process::Command;

use crate::common::{Scratch, root};

pub fn armcomp(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_armcomp"))
        .args(args)
        .current_dir(root())
        .output()
        .unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

#[test]
fn fk_json_reports_points_and_tool_pose() {
    let (code, out, err) = armcomp(&[
        "fk",
        "--robot",
        "robots/industrial-6dof.toml",
        "--q",
        "0,0,0,0,0,0",
        "--json",
    ]);
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    // At home, Craig's PUMA: tool at (a2 + a3, d3, -(d4 + 0.1)) with the flange pointing down.
    let p = &v["tool"]["position"];
    let expected = [0.4318 + 0.02032, 0.14909, -(0.43307 + 0.1)];
    for k in 0..3 {
        assert!((p[k].as_f64().unwrap() - expected[k]).abs() < 1e-12, "{p}");
    }
    assert_eq!(v["points"]["tool"], *p);
    let q = v["tool"]["quaternion"].as_array().unwrap();
    assert!(
        (q[1].as_f64().unwrap().abs() - 1.0).abs() < 1e-12,
        "half turn about x: {q:?}"
    );
}

#[test]
fn fk_degrees_and_bad_input() {
    let (code, out, _) = armcomp(&[
        "fk",
        "--robot",
        "robots/rock-drill.toml",
        "--q",
        "0,0,0.1,0,0,0,0",
        "--deg",
    ]);
    assert_eq!(code, 0);
    assert!(
        out.contains("1.010000"),
        "prismatic values stay in metres under --deg: {out}"
    );
    let (code, _, err) = armcomp(&["fk", "--robot", "robots/rock-drill.toml", "--q", "0,0,0"]);
    assert_eq!(code, 1);
    assert!(err.contains("3 values") && err.contains("7 joints"), "{err}");
    let (code, _, err) = armcomp(&["fk", "--robot", "robots/rock-drill.toml", "--q", "0,x,0,0,0,0,0"]);
    assert_eq!(code, 1);
    assert!(err.contains("value 2"), "{err}");
}

#[test]
fn validate_exit_codes() {
    let (code, out, _) = armcomp(&["validate", "robots/rock-drill.toml", "robots/industrial-6dof.toml"]);
    assert_eq!(code, 0, "{out}");
    let s = Scratch::new("cli-validate");
    let bad = s.file("bad.toml", "name = 3\n");
    let (code, out, _) = armcomp(&["validate", "robots/rock-drill.toml", bad.to_str().unwrap()]);
    assert_eq!(code, 1);
    assert!(out.contains("bad.toml:1: name: invalid type"), "{out}");
}

#[test]
fn schema_out_plugins_and_demo() {
    let s = Scratch::new("cli-schema");
    let out_path = s.0.join("schema.json");
    let (code, _, err) = armcomp(&["schema", "--out", out_path.to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(std::fs::read_to_string(&out_path).unwrap(), armcomp_api::schema_text());
    let (code, out, _) = armcomp(&["plugins", "--json"]);
    assert_eq!(code, 0);
    let list: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert!(
        list.as_array()
            .unwrap()
            .iter()
            .any(|p| p["type"] == "mdh" && p["role"] == "kinematics")
    );
    let (code, out, _) = armcomp(&["demo", "industrial"]);
    assert_eq!(code, 0);
    assert!(out.contains("industrial-poe"), "{out}");
    let (code, _, err) = armcomp(&["demo", "nope"]);
    assert_eq!(code, 1);
    assert!(err.contains("rock-drill"), "{err}");
    // A sweep over seeds: rock drill only, at least one seed, no report; refused before running.
    for (args, says) in [
        (&["demo", "industrial", "--seeds", "2"][..], "rock-drill demo only"),
        (&["demo", "--seeds", "0"][..], "expected at least 1"),
        (
            &["demo", "--seeds", "2", "--report", "out"][..],
            "--report draws one seed",
        ),
    ] {
        let (code, _, err) = armcomp(args);
        assert_eq!(code, 1, "{args:?}: {err}");
        assert!(err.contains(says), "{args:?}: {err}");
    }
}
