//! Malformed robot files: each gives its own clear message naming the field, and none panics.

use crate::common::Scratch;
use armcomp_core::support::io::InputLimits;

const GOOD: &str = r#"name = "ok"

[units]
length = "mm"
angle = "deg"

[kinematics]
type = "mdh"

[[kinematics.joints]]
name = "j1"
limits = [-90.0, 90.0]

[[kinematics.joints]]
name = "j2"
a = 300.0
limits = [-45.0, 45.0]

[[links]]
name = "j2"
mass = 2.0
beam = { ei_y = 100.0, ei_z = 120.0, gj = 80.0 }

[[points]]
name = "tool"
link = "j2"
xyz = [200.0, 0.0, 0.0]
"#;

/// Validates `text` (after replacing `from` with `to` in the good file) and returns the problems.
fn problems(tag: &str, from: &str, to: &str) -> Vec<armcomp_api::Diagnostic> {
    assert!(GOOD.contains(from), "test setup: `{from}` not in the good file");
    let s = Scratch::new(tag);
    let p = s.file("robot.toml", &GOOD.replacen(from, to, 1));
    armcomp_api::validate_file(&p, &armcomp_api::robot_schema(), InputLimits::default())
}

fn assert_one(tag: &str, from: &str, to: &str, path: &str, line: usize, words: &[&str]) {
    let ps = problems(tag, from, to);
    assert!(!ps.is_empty(), "{tag}: expected a problem");
    let p = ps
        .iter()
        .find(|p| p.path == path)
        .unwrap_or_else(|| panic!("{tag}: no problem at `{path}`: {ps:#?}"));
    assert_eq!(p.line, Some(line), "{tag}: line of {p}");
    for w in words {
        assert!(p.message.contains(w), "{tag}: message `{}` lacks `{w}`", p.message);
    }
}

#[test]
fn good_file_is_valid() {
    let s = Scratch::new("good");
    let p = s.file("robot.toml", GOOD);
    assert_eq!(
        armcomp_api::validate_file(&p, &armcomp_api::robot_schema(), InputLimits::default()),
        vec![]
    );
}

#[test]
fn bad_toml_syntax() {
    let ps = problems("syntax", "a = 300.0", "a = 300.0.0");
    assert_eq!(ps.len(), 1);
    assert_eq!(ps[0].line, Some(16), "{}", ps[0]);
    assert!(
        ps[0].message.to_lowercase().contains("invalid") || ps[0].message.contains("expected"),
        "{}",
        ps[0]
    );
}

#[test]
fn wrong_value_type() {
    assert_one(
        "type",
        "mass = 2.0",
        "mass = \"heavy\"",
        "links[0].mass",
        21,
        &["invalid type", "f64"],
    );
}

#[test]
fn unknown_plugin_type() {
    let ps = problems("plugin", "type = \"mdh\"", "type = \"mdhh\"");
    assert_eq!(ps.len(), 1, "{ps:?}");
    let p = &ps[0];
    assert!(p.path.starts_with("kinematics"), "{p}");
    assert!(
        p.message.contains("mdhh") && p.message.contains("mdh") && p.message.contains("poe"),
        "{p}"
    );
}

#[test]
fn negative_stiffness() {
    assert_one(
        "stiffness",
        "ei_y = 100.0",
        "ei_y = -100.0",
        "links[0].beam.ei_y",
        22,
        &["positive", "-100"],
    );
}

#[test]
fn lower_limit_above_upper() {
    assert_one(
        "limits",
        "limits = [-45.0, 45.0]",
        "limits = [45.0, -45.0]",
        "kinematics.joints[1].limits",
        17,
        &["lower limit 45 is above upper limit -45"],
    );
}

#[test]
fn point_on_missing_link() {
    assert_one(
        "link",
        "link = \"j2\"",
        "link = \"j9\"",
        "points[0].link",
        26,
        &["`j9`", "does not exist", "`j2`"],
    );
}

#[test]
fn unknown_unit() {
    assert_one(
        "unit",
        "length = \"mm\"",
        "length = \"furlong\"",
        "units.length",
        4,
        &["furlong", "mm"],
    );
}

#[test]
fn missing_file_and_unreadable_input_are_errors_not_panics() {
    let ps = armcomp_api::validate_file(
        std::path::Path::new("/nonexistent/robot.toml"),
        &armcomp_api::robot_schema(),
        InputLimits::default(),
    );
    assert_eq!(ps.len(), 1);
    assert_eq!(ps[0].to_string(), "/nonexistent/robot.toml: does not exist");
    let ps = problems("empty", GOOD, "");
    assert!(ps.iter().any(|p| p.message.contains("missing field")), "{ps:?}");
}

#[test]
fn several_problems_are_all_reported() {
    let s = Scratch::new("many");
    let text = GOOD
        .replace("ei_y = 100.0", "ei_y = -100.0")
        .replace("link = \"j2\"\nxyz", "link = \"j9\"\nxyz");
    let p = s.file("robot.toml", &text);
    let ps = armcomp_api::validate_file(&p, &armcomp_api::robot_schema(), InputLimits::default());
    assert!(ps.len() >= 2, "{ps:?}");
}

#[test]
fn misspelt_key_inside_a_plugin_is_located() {
    let ps = problems("typo", "a = 300.0", "aa = 300.0");
    assert_eq!(ps.len(), 1, "{ps:?}");
    assert_eq!(ps[0].line, Some(16), "{}", ps[0]);
    assert!(
        ps[0].message.contains("unknown field `aa`") && ps[0].message.contains("`alpha`"),
        "{}",
        ps[0]
    );
}
