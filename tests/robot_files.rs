//! The shipped robot files: valid, round-trip, and the committed schema is current.

use armcomp_core::robot::robot_file::{Format, SourceFile};
use armcomp_core::support::io::InputLimits;
use armcomp_core::{Robot, RobotFile};

use crate::common::{random_configurations, root};

fn robot_files() -> Vec<std::path::PathBuf> {
    let mut files: Vec<_> = std::fs::read_dir(root().join("robots"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    files.sort();
    assert!(files.len() >= 4, "robots/ holds the built-in twins");
    files
}

#[test]
fn every_robot_file_validates() {
    let schema = armcomp_api::robot_schema();
    for f in robot_files() {
        let problems = armcomp_api::validate_file(&f, &schema, InputLimits::default());
        assert!(problems.is_empty(), "{}: {problems:?}", f.display());
    }
}

#[test]
fn every_robot_file_round_trips_through_toml_and_json() {
    for f in robot_files() {
        let robot = Robot::from_path(&f).unwrap();
        let qs = random_configurations(&robot, 20, 7);
        let toml_text = toml::to_string(&robot.to_file()).unwrap();
        let json_text = serde_json::to_string_pretty(&robot.to_file()).unwrap();
        for (text, format) in [(toml_text, Format::Toml), (json_text, Format::Json)] {
            let src = SourceFile {
                path: f.clone(),
                text,
                format,
            };
            let file: RobotFile = src.parse().unwrap_or_else(|e| panic!("{}: {e}", f.display()));
            let again = Robot::from_source(file, &src, InputLimits::default()).unwrap();
            assert_eq!(again.chain_values(), robot.chain_values(), "{}", f.display());
            for q in &qs {
                let a = robot.forward(q).unwrap();
                let b = again.forward(q).unwrap();
                for (pa, pb) in a.point.iter().zip(&b.point) {
                    assert!((pa.translation.vector - pb.translation.vector).norm() < 1e-12);
                }
            }
        }
    }
}

#[test]
fn committed_schema_is_up_to_date() {
    let committed = std::fs::read_to_string(root().join("schemas/robot.schema.json")).unwrap();
    assert!(
        committed == armcomp_api::schema_text(),
        "schemas/robot.schema.json is stale: run `cargo run -- schema --out schemas/robot.schema.json`"
    );
}

#[test]
fn schema_lists_every_registered_plugin() {
    let schema = armcomp_api::robot_schema();
    let kin = &schema["$defs"]["KinematicsPlugin"]["oneOf"];
    let names: Vec<_> = kin
        .as_array()
        .unwrap()
        .iter()
        .map(|s| s["properties"]["type"]["const"].clone())
        .collect();
    for p in armcomp_api::plugins()
        .iter()
        .filter(|p| p.role == armcomp_core::Role::Kinematics)
    {
        assert!(
            names.contains(&serde_json::json!(p.type_name)),
            "{} missing",
            p.type_name
        );
    }
}

/// A built-in plugin's `type` is written twice, as its typetag name and in its registry entry:
/// the two lists agree, role by role. Unknown types are rejected with typetag's list of the
/// names it knows; a registered type deserialises as far as its first missing field.
#[test]
fn registry_names_are_the_names_robot_files_deserialise() {
    use armcomp_core::{ErrorModelSpec, KinematicsSpec, PredictorSpec, Role};
    fn error_of(role: Role, value: serde_json::Value) -> Option<String> {
        match role {
            Role::Kinematics => serde_json::from_value::<Box<dyn KinematicsSpec>>(value).err(),
            Role::ErrorModel => serde_json::from_value::<Box<dyn ErrorModelSpec>>(value).err(),
            Role::Predictor => serde_json::from_value::<Box<dyn PredictorSpec>>(value).err(),
        }
        .map(|e| e.to_string())
    }
    let plugins = armcomp_api::registry::builtin_plugins();
    for role in [Role::Kinematics, Role::ErrorModel, Role::Predictor] {
        let mut registered: Vec<&str> = plugins.iter().filter(|p| p.role == role).map(|p| p.type_name).collect();
        registered.sort_unstable();
        for name in &registered {
            if let Some(e) = error_of(role, serde_json::json!({ "type": name })) {
                assert!(!e.contains("unknown variant"), "{role:?} `{name}`: {e}");
            }
        }
        let e = error_of(role, serde_json::json!({ "type": "no-such-plugin" })).expect("an unknown type is refused");
        let list = e
            .split_once("expected one of ")
            .or_else(|| e.split_once("expected "))
            .unwrap_or_else(|| panic!("{role:?}: {e}"))
            .1;
        // The example run-time plugin is also linked into this test binary, to compare its
        // library with the same code in process; it is not built in.
        let mut known: Vec<&str> = list
            .split('`')
            .skip(1)
            .step_by(2)
            .filter(|n| *n != "cable_sag")
            .collect();
        known.sort_unstable();
        assert_eq!(
            known, registered,
            "{role:?}: typetag knows {known:?}, the registry lists {registered:?}"
        );
    }
}
