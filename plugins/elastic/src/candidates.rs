//! The instances of each effect the diagnosis workflow tries on a robot: per moving joint, per
//! beam link, or once for the whole arm, each at values that add nothing until calibrated.

use armcomp_core::{Candidate, Motion, Robot};
use serde_json::{Value, json};

/// One candidate per moving joint on a marker's path (revolute only when `revolute_only`), its
/// spec built by `spec` from the joint name: effects elsewhere (a humanoid's other arm, legs,
/// head) cannot move a marker.
fn per_joint(robot: &Robot, revolute_only: bool, what: &str, spec: impl Fn(&str) -> Value) -> Vec<Candidate> {
    robot
        .tree()
        .joints()
        .iter()
        .zip(robot.measured_joints())
        .filter(|(_, on)| *on)
        .map(|(j, _)| j)
        .filter(|j| match j.motion {
            Motion::Revolute(_) => true,
            Motion::Prismatic(_) => !revolute_only,
            Motion::Fixed => false,
        })
        .map(|j| Candidate {
            location: j.name.clone(),
            label: format!("joint {} {what}", j.name),
            spec: spec(&j.name),
        })
        .collect()
}

/// Whether the robot has an elastic model, through which a changed load (a tilted gravity, a
/// heavier payload) shows.
fn responds_to_loads(robot: &Robot) -> bool {
    robot.error_models().iter().any(|m| {
        m.params().iter().any(|p| {
            ["joint_compliance.", "lateral_compliance.", "cantilever."]
                .iter()
                .any(|prefix| p.name.starts_with(prefix))
        })
    })
}

fn global(label: &str, spec: Value) -> Vec<Candidate> {
    vec![Candidate {
        location: "global".into(),
        label: label.into(),
        spec,
    }]
}

pub(crate) fn joint_compliance(robot: &Robot) -> Vec<Candidate> {
    per_joint(
        robot,
        false,
        "compliance",
        |j| json!({ "type": "joint_compliance", "compliance": { j: 0.0 } }),
    )
}

pub(crate) fn lateral_compliance(robot: &Robot) -> Vec<Candidate> {
    per_joint(
        robot,
        false,
        "lateral compliance (tilt under bending)",
        |j| json!({ "type": "lateral_compliance", "compliance": { j: [0.0, 0.0] } }),
    )
}

pub(crate) fn backlash(robot: &Robot) -> Vec<Candidate> {
    per_joint(
        robot,
        false,
        "backlash",
        |j| json!({ "type": "backlash", "backlash": { j: 0.0 } }),
    )
}

pub(crate) fn encoder_eccentricity(robot: &Robot) -> Vec<Candidate> {
    per_joint(
        robot,
        true,
        "encoder eccentricity",
        |j| json!({ "type": "encoder_eccentricity", "eccentricity": { j: [0.0, 0.0] } }),
    )
}

pub(crate) fn transmission_scale(robot: &Robot) -> Vec<Candidate> {
    per_joint(
        robot,
        false,
        "transmission scale",
        |j| json!({ "type": "transmission_scale", "scale": { j: 0.0 } }),
    )
}

/// Each link with a beam section on a marker's path, bending at its nominal rigidity scaled by
/// what calibration identifies (a scale of 1 is the beam as declared).
pub(crate) fn cantilever_deflection(robot: &Robot) -> Vec<Candidate> {
    let on = robot.measured_joints();
    // A link bends what hangs beyond its own joint (body `b` moves on joint `b - 1`).
    let carries_marker = |name: &str| robot.tree().body_index(name).is_some_and(|b| b > 0 && on[b - 1]);
    robot
        .built_from()
        .links
        .iter()
        .filter(|l| l.beam.is_some() && carries_marker(&l.name))
        .map(|l| Candidate {
            location: l.name.clone(),
            label: format!("{} link bending", l.name),
            spec: json!({ "type": "cantilever_deflection", "links": [l.name], "ei_scale": { &l.name: 1.0 } }),
        })
        .collect()
}

pub(crate) fn thermal_growth(_robot: &Robot) -> Vec<Candidate> {
    global(
        "thermal growth of the links",
        json!({ "type": "thermal_growth", "coefficient": 0.0 }),
    )
}

/// A tilted base differs from a turned measurement frame only through what the tilted gravity
/// bends, so it is tried once the robot has an elastic model.
pub(crate) fn base_tilt(robot: &Robot) -> Vec<Candidate> {
    if !responds_to_loads(robot) {
        return Vec::new();
    }
    global("base tilt", json!({ "type": "base_tilt", "tilt": [0.0, 0.0] }))
}

/// Every sensor whose reading does not turn the chain yet: a base that rocks from row to row,
/// a column that leans, shows in the points once its link turns by what the sensor reads.
pub(crate) fn measured_tilt(robot: &Robot) -> Vec<Candidate> {
    let values = robot.error_values();
    (robot.sensors().iter().enumerate())
        .filter(|(k, _)| robot.sensor_mounting(*k, values).is_none())
        .map(|(_, s)| Candidate {
            location: robot.tree().bodies()[s.body].name.clone(),
            label: format!("measured tilt of sensor {}", s.name),
            spec: json!({ "type": "measured_tilt", "sensor": s.name, "mounting": [0.0, 0.0] }),
        })
        .collect()
}

/// A wrong payload mass shows through what it bends, so it is tried once the robot has an
/// elastic model.
pub(crate) fn payload_mass_error(robot: &Robot) -> Vec<Candidate> {
    if !responds_to_loads(robot) {
        return Vec::new();
    }
    global(
        "payload mass error",
        json!({ "type": "payload_mass_error", "mass": 0.0, "scale": 0.0 }),
    )
}
