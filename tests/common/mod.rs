//! Helpers shared by the integration tests.

use std::path::{Path, PathBuf};

use armcomp_core::robot::robot_file::{Format, SourceFile};
use armcomp_core::support::io::InputLimits;
use armcomp_core::{Robot, RobotFile};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// The repository root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).to_path_buf()
}

/// A robot file from the repository's `robots/` folder.
pub fn robot(name: &str) -> Robot {
    Robot::from_path(&root().join("robots").join(name)).expect("built-in robot files are valid")
}

/// A robot from TOML text.
pub fn robot_from_toml(text: &str) -> Robot {
    let src = SourceFile {
        path: "test.toml".into(),
        text: text.into(),
        format: Format::Toml,
    };
    let file: RobotFile = src.parse().expect("test robot parses");
    Robot::from_source(file, &src, InputLimits::default()).expect("test robot builds")
}

/// Random joint vectors inside the limits (±π for unlimited revolute joints), seeded.
pub fn random_configurations(robot: &Robot, n: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = StdRng::seed_from_u64(seed);
    let lims = robot.tree().coordinate_limits().to_vec();
    (0..n)
        .map(|_| {
            lims.iter()
                .map(|l| match l {
                    Some(l) => rng.random_range(l.lower..=l.upper),
                    None => rng.random_range(-std::f64::consts::PI..std::f64::consts::PI),
                })
                .collect()
        })
        .collect()
}

/// A scratch folder unique to this test, removed when dropped.
pub struct Scratch(pub PathBuf);

impl Scratch {
    pub fn new(tag: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("armcomp-test-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        Scratch(dir)
    }
    pub fn file(&self, name: &str, text: &str) -> PathBuf {
        let p = self.0.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }
}

impl Drop for Scratch {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

pub mod robots;

/// `nominal` with a transmission scale of `scale` on `joint` among its error models: a joint
/// turning further than commanded, which the nominal model lacks.
pub fn with_transmission_scale(nominal: &Robot, joint: &str, scale: f64) -> Robot {
    let mut file = nominal.to_file();
    let spec = serde_json::json!({"type": "transmission_scale", "scale": {joint: scale}});
    file.error_models.push(serde_json::from_value(spec).unwrap());
    nominal.rebuild(file).unwrap()
}

/// The diagnosis of `nominal` on `samples` (at most two steps, every built-in candidate),
/// calibrating as `calibration` says; asserts, for `seed`, that the first effect it names is
/// `first` (effect, location) and that it cuts the held-out RMS below `share` of what it was.
pub fn assert_diagnosis_names(
    nominal: &Robot,
    samples: &[armcomp_core::data::measurement::Sample],
    calibration: armcomp_core::calibrate::CalibrationParams,
    first: (&str, &str),
    share: f64,
    seed: u64,
) {
    use armcomp_core::analysis::diagnose::{DiagnoseParams, diagnose};
    let params = DiagnoseParams {
        calibration,
        max_steps: 2,
        ..Default::default()
    };
    let report = diagnose(
        nominal,
        samples,
        &armcomp_api::registry::builtin_plugins(),
        None,
        &params,
        &|_| {},
    )
    .unwrap()
    .report;
    let named = report.steps.first().map(|s| (s.effect.as_str(), s.location.as_str()));
    assert_eq!(named, Some(first), "seed {seed}");
    let step = &report.steps[0];
    assert!(
        step.heldout_after.rms_mm < share * step.heldout_before.rms_mm,
        "seed {seed}: {} → {} mm",
        step.heldout_before.rms_mm,
        step.heldout_after.rms_mm
    );
}

/// `model` with a GP (default settings) learned on what it leaves of `samples`, as `armcomp
/// learn --predictor gp` fits it.
pub fn learn_gp(
    model: &Robot,
    samples: &[armcomp_core::data::measurement::Sample],
) -> armcomp_api::ops::learn::LearnRun {
    let spec = armcomp_api::ops::learn::default_predictor("gp").unwrap();
    armcomp_api::ops::learn::run(
        model,
        model.to_file(),
        samples,
        Some(spec),
        None,
        &armcomp_core::FitControl::default(),
    )
    .unwrap()
}
