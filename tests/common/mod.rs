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
