//! Test robots built in code and small helpers.

use std::path::Path;

use armcomp_core::kinematics::subtree_loads::SubtreeLoads;
use armcomp_core::support::io::InputLimits;
use armcomp_core::{Perturbation, Robot, RobotFile, StaticState, TreeWorkspace};
use nalgebra::Vector3;

/// A one-joint pendulum in the vertical plane, 10 kg at 0.8 m, the tool at 1 m, no error
/// models: one of the robots the workspace's tests share (`tests/data/robots/` at its root).
pub const PENDULUM: &str = include_str!("../../../../tests/data/robots/pendulum.toml");

/// Builds a robot from a TOML robot file; panics with the issues when it is invalid.
pub fn robot(src: &str) -> Robot {
    // Link the plugin crates so their typetag registrations are present.
    let _ = armcomp_chains::plugins();
    let _ = armcomp_elastic::plugins();
    let file: RobotFile = toml::from_str(src).unwrap_or_else(|e| panic!("parse: {e}\n{src}"));
    Robot::build(file, Path::new("."), InputLimits::default()).unwrap_or_else(|e| panic!("build: {e:?}"))
}

/// Builds a robot expecting it to fail; returns the issues' `path: message` lines.
pub fn robot_issues(src: &str) -> Vec<String> {
    let _ = armcomp_chains::plugins();
    let _ = armcomp_elastic::plugins();
    let file: RobotFile = toml::from_str(src).unwrap_or_else(|e| panic!("parse: {e}\n{src}"));
    match Robot::build(file, Path::new("."), InputLimits::default()) {
        Ok(_) => panic!("expected the robot to be rejected"),
        Err(issues) => issues.iter().map(|i| format!("{}: {}", i.path, i.message)).collect(),
    }
}

/// The perturbation model `m` of `robot` produces at `q` for parameter `values`, and the rigid frames.
pub fn perturbation_of(
    robot: &Robot,
    m: usize,
    values: &[f64],
    q: &[f64],
    temperature: Option<f64>,
) -> (Perturbation, TreeWorkspace) {
    let tree = robot.tree();
    let mut rigid = TreeWorkspace::new(tree);
    tree.forward_into(q, &mut rigid);
    let mut pert = Perturbation::zeros(tree);
    let loads = SubtreeLoads::of(tree, &rigid, robot.mass());
    let state = StaticState {
        q,
        tree,
        frames: &rigid,
        mass: robot.mass(),
        loads: &loads,
        gravity: robot.gravity(),
        temperature,
        sensors: Default::default(),
    };
    robot.error_models()[m].perturb(&state, values, &mut pert);
    (pert, rigid)
}

/// Relative difference `|a - b| / |b|`.
pub fn rel(a: &Vector3<f64>, b: &Vector3<f64>) -> f64 {
    (a - b).norm() / b.norm()
}

pub mod robots;
