//! Property tests: robot files, URDFs and measurement CSVs mutated at random (bytes deleted,
//! tokens and junk inserted, lines repeated, text cut short) go through the parsers and the
//! robot builder without a panic and without a hang; each gives a robot or an error.

use std::path::Path;
use std::sync::mpsc;
use std::time::Duration;

use armcomp_core::Robot;
use armcomp_core::data::measurement::{parse_csv, parse_poses};
use armcomp_core::support::io::InputLimits;
use proptest::prelude::*;

use crate::common::root;

/// One change to a file's bytes; positions are taken modulo the length.
#[derive(Debug, Clone)]
enum Edit {
    Delete(usize, usize),
    Insert(usize, Vec<u8>),
    RepeatLine(usize),
    Truncate(usize),
}

/// Tokens that matter to TOML, JSON, XML and CSV, and values that are out of range.
const TOKENS: &[&str] = &[
    "nan",
    "inf",
    "-inf",
    "-1",
    "0",
    "1e308",
    "-1e-320",
    "\"",
    "'",
    "[",
    "]",
    "{",
    "}",
    "=",
    ",",
    ":",
    "\n",
    "#",
    "\u{feff}",
    "[[points]]",
    "[[links]]",
    "[[kinematics.joints]]",
    "<",
    ">",
    "</joint>",
    "<link name=\"a\"/>",
    "/dev/zero",
    "..",
    "\"\"",
    "1.5e3",
    "true",
    "x[mm]",
    "j1[deg]",
    "point",
];

fn edits() -> impl Strategy<Value = Vec<Edit>> {
    let token = prop::sample::select(TOKENS).prop_map(|t| t.as_bytes().to_vec());
    let junk = prop::collection::vec(any::<u8>(), 1..8);
    prop::collection::vec(
        prop_oneof![
            (any::<usize>(), 1..40usize).prop_map(|(at, n)| Edit::Delete(at, n)),
            (any::<usize>(), token).prop_map(|(at, t)| Edit::Insert(at, t)),
            (any::<usize>(), junk).prop_map(|(at, j)| Edit::Insert(at, j)),
            any::<usize>().prop_map(Edit::RepeatLine),
            any::<usize>().prop_map(Edit::Truncate),
        ],
        1..6,
    )
}

fn apply(text: &[u8], edits: &[Edit]) -> Vec<u8> {
    let mut bytes = text.to_vec();
    for e in edits {
        let at = |a: usize| a % (bytes.len() + 1);
        match e {
            Edit::Delete(a, n) => {
                let start = at(*a);
                let end = (start + n).min(bytes.len());
                bytes.drain(start..end);
            }
            Edit::Insert(a, t) => {
                let start = at(*a);
                bytes.splice(start..start, t.iter().copied());
            }
            Edit::RepeatLine(a) => {
                let start = at(*a);
                let begin = bytes[..start].iter().rposition(|b| *b == b'\n').map_or(0, |i| i + 1);
                let end = bytes[start..]
                    .iter()
                    .position(|b| *b == b'\n')
                    .map_or(bytes.len(), |i| start + i + 1);
                let line = bytes[begin..end].to_vec();
                bytes.splice(end..end, line);
            }
            Edit::Truncate(a) => {
                let start = at(*a);
                bytes.truncate(start);
            }
        }
    }
    bytes
}

/// Runs `f` on a thread of its own and says whether it returned within the time a parser of
/// these small files could ever need, or panicked.
fn settles(f: impl FnOnce() + Send + 'static) -> Result<(), String> {
    let (done, wait) = mpsc::channel();
    std::thread::spawn(move || {
        f();
        let _ = done.send(());
    });
    match wait.recv_timeout(Duration::from_secs(30)) {
        Ok(()) => Ok(()),
        Err(mpsc::RecvTimeoutError::Timeout) => Err("still running after 30 s: a hang".into()),
        Err(mpsc::RecvTimeoutError::Disconnected) => Err("panicked".into()),
    }
}

fn base(name: &str) -> Vec<u8> {
    std::fs::read(root().join("tests/bad_inputs").join(name)).unwrap()
}

/// Writes `bytes` as `name` into a fresh folder (beside the arm's URDF, which robot files
/// name), then checks `name` there.
fn check_file(name: &'static str, bytes: Vec<u8>) -> Result<(), String> {
    settles(move || {
        let dir = tempfile::tempdir().unwrap();
        std::fs::write(dir.path().join("arm.urdf"), base("arm.urdf")).unwrap();
        let path = dir.path().join(name);
        std::fs::write(&path, bytes).unwrap();
        let _ = armcomp_api::validate_file(&path, &armcomp_api::robot_schema(), InputLimits::default());
        let _ = armcomp_api::read_robot(&path, InputLimits::default());
    })
}

fn arm() -> &'static Robot {
    static ARM: std::sync::OnceLock<Robot> = std::sync::OnceLock::new();
    ARM.get_or_init(|| Robot::from_path(&root().join("tests/bad_inputs/arm.toml")).unwrap())
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn mutated_toml_robot_files_never_panic_or_hang(edits in edits()) {
        check_file("robot.toml", apply(&base("arm.toml"), &edits)).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn mutated_json_robot_files_never_panic_or_hang(edits in edits()) {
        check_file("robot.json", apply(&base("arm.json"), &edits)).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn mutated_robot_files_naming_a_urdf_never_panic_or_hang(edits in edits()) {
        check_file("robot.toml", apply(&base("urdf-arm.toml"), &edits)).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn mutated_urdfs_never_panic_or_hang(edits in edits()) {
        check_file("arm.urdf", apply(&base("arm.urdf"), &edits)).map_err(TestCaseError::fail)?;
    }

    #[test]
    fn mutated_measurement_csvs_never_panic_or_hang(edits in edits()) {
        let text = String::from_utf8_lossy(&apply(&base("arm.csv"), &edits)).into_owned();
        settles(move || {
            let robot = arm();
            let path = Path::new("data.csv");
            let _ = parse_csv(&text, path, &robot.csv_layout());
            let _ = parse_poses(&text, path, &robot.csv_layout());
        })
        .map_err(TestCaseError::fail)?;
    }
}
