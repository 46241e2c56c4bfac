//! The robot built, evaluated and written back, on a one-joint arm whose answers are known by
//! hand: a link of length `l` turning about z puts its tool at `(l cos q, l sin q, 0)`.

use std::path::Path;

use nalgebra::{Isometry3, Translation3, Vector3};

use crate::error::{Issues, Result};
use crate::model::param::{ParamInfo, Quantity};
use crate::model::tree::{KinematicTree, Motion};
use crate::plugin::{BuildContext, Chain, KinematicsSpec};
use crate::robot::Robot;
use crate::robot::robot_file::RobotFile;
use crate::support::io::InputLimits;

/// A kinematics plugin for these tests alone: one revolute joint and a link of length `length`
/// (m) to the `tool` body.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
struct OneLink {
    length: f64,
}

#[derive(Debug)]
struct OneLinkChain {
    params: Vec<ParamInfo>,
}

#[typetag::serde(name = "robot_tests_one_link")]
impl KinematicsSpec for OneLink {
    fn build(&self, _ctx: &BuildContext<'_>) -> Result<Box<dyn Chain>, Issues> {
        let length = ParamInfo::new("link.length", Quantity::Length, self.length, 1e-3);
        Ok(Box::new(OneLinkChain { params: vec![length] }))
    }
}

impl Chain for OneLinkChain {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    fn tree(&self, values: &[f64]) -> Result<KinematicTree> {
        let mut tree = KinematicTree::new("base");
        let link = tree.add_joint(
            "j1",
            0,
            Isometry3::identity(),
            Motion::Revolute(Vector3::z_axis()),
            None,
            "link",
        )?;
        let mount = Isometry3::from_parts(Translation3::new(values[0], 0.0, 0.0), Default::default());
        tree.add_joint("tool_mount", link, mount, Motion::Fixed, None, "tool")?;
        Ok(tree)
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn KinematicsSpec> {
        Box::new(OneLink { length: values[0] })
    }
}

fn file(extra: &str) -> RobotFile {
    let text = format!(
        "name = \"one link\"\n{extra}\nkinematics = {{ type = \"robot_tests_one_link\", length = 0.5 }}\n\
         [[points]]\nname = \"tool\"\nlink = \"tool\"\nxyz = [0.0, 0.0, 0.0]\n"
    );
    toml::from_str(&text).unwrap()
}

fn tool_at(robot: &Robot, q: f64) -> Vector3<f64> {
    let frames = robot.forward(&[q]).unwrap();
    let tool = robot.tree().body_index("tool").unwrap();
    frames.body[tool].translation.vector
}

#[test]
fn a_rigid_robot_puts_its_tool_where_its_chain_does() {
    let robot = Robot::build(file(""), Path::new("."), InputLimits::default()).unwrap();
    for q in [0.0, 0.3, -2.0] {
        let expected = Vector3::new(0.5 * f64::cos(q), 0.5 * f64::sin(q), 0.0);
        assert!((tool_at(&robot, q) - expected).norm() < 1e-12, "q = {q}");
    }
}

#[test]
fn values_written_back_build_the_same_robot() {
    let mut robot = Robot::build(file(""), Path::new("."), InputLimits::default()).unwrap();
    robot.set_chain_values(&[0.8]).unwrap();
    let rebuilt = Robot::build(robot.to_file(), Path::new("."), InputLimits::default()).unwrap();
    assert_eq!(rebuilt.chain_values(), [0.8]);
    assert!((tool_at(&rebuilt, 0.0) - Vector3::new(0.8, 0.0, 0.0)).norm() < 1e-12);
}

#[test]
fn an_absurd_gravity_is_refused_at_its_field() {
    let issues = Robot::build(
        file("gravity = [0.0, 0.0, -9810.0]"),
        Path::new("."),
        InputLimits::default(),
    )
    .unwrap_err();
    assert!(
        issues
            .iter()
            .any(|i| i.path == "gravity" && i.message.contains("absurd")),
        "{issues:?}"
    );
    assert!(
        Robot::build(
            file("gravity = [0.0, 0.0, -9.81]"),
            Path::new("."),
            InputLimits::default()
        )
        .is_ok()
    );
}
