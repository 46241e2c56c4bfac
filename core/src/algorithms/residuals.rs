//! Where held-out residuals live: statistics per axis and the correlation of each residual
//! component with the joint values, the gravity load at each joint, the payload, the
//! temperature and the order of measurement. A model error that depends on one of these shows
//! up as a strong correlation with it.

use nalgebra::Vector3;
use serde::Serialize;

use crate::data::measurement::Sample;
use crate::model::tree::Motion;
use crate::plugin::StaticState;
use crate::plugin::gravity::joint_gravity_load;
use crate::robot::{Conditions, Robot};

/// Mean and RMS of one residual component (mm).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct AxisResidual {
    /// `x`, `y` or `z` of the measurement frame.
    pub axis: &'static str,
    /// Mean (mm): a constant offset the model misses.
    pub mean_mm: f64,
    /// Root mean square (mm).
    pub rms_mm: f64,
}

/// Pearson correlation of the residual with one variable.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualCorrelation {
    /// What the variable is, e.g. `joint j2`, `gravity torque j2`, `payload`, `time order`.
    pub variable: String,
    /// Its unit.
    pub unit: &'static str,
    /// Correlation with the residual's x, y, z components and its 3-D norm, in that order.
    pub r: [f64; 4],
}

/// How the residuals of a model are distributed.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ResidualDescription {
    /// Per axis of the measurement frame.
    pub axes: [AxisResidual; 3],
    /// Correlations with every variable that varies over the data, in a fixed order: joint
    /// values, gravity loads, payload, temperature, time order.
    pub correlations: Vec<ResidualCorrelation>,
}

/// Describes `residuals` (measured minus modelled, m, one per sample) against the conditions of
/// `samples`; gravity loads are those of `robot`'s rigid model at each sample.
pub fn describe_residuals(robot: &Robot, samples: &[Sample], residuals: &[Vector3<f64>]) -> ResidualDescription {
    let n = residuals.len().max(1) as f64;
    let axes = [0, 1, 2].map(|k| AxisResidual {
        axis: ["x", "y", "z"][k],
        mean_mm: residuals.iter().map(|r| r[k]).sum::<f64>() / n * 1e3,
        rms_mm: (residuals.iter().map(|r| r[k] * r[k]).sum::<f64>() / n).sqrt() * 1e3,
    });
    let components: [Vec<f64>; 4] = [
        residuals.iter().map(|r| r.x).collect(),
        residuals.iter().map(|r| r.y).collect(),
        residuals.iter().map(|r| r.z).collect(),
        residuals.iter().map(|r| r.norm()).collect(),
    ];
    let tree = robot.tree();
    // Only the measured chain: another limb's joints hold still, and its loads change only as
    // the chain carries it around, which the chain's own variables already say.
    let (measured_coordinates, measured_joints) = (robot.measured_coordinates(), robot.measured_joints());
    let mut variables: Vec<(String, &'static str, Vec<f64>)> = Vec::new();
    for (i, name) in tree.coordinate_names().iter().enumerate() {
        if !measured_coordinates[i] {
            continue;
        }
        let unit = if tree.coordinate_is_prismatic()[i] { "m" } else { "rad" };
        variables.push((format!("joint {name}"), unit, samples.iter().map(|s| s.q[i]).collect()));
    }
    let loads = gravity_loads(robot, samples);
    for (j, joint) in tree.joints().iter().enumerate().filter(|(j, _)| measured_joints[*j]) {
        let unit = match joint.motion {
            Motion::Revolute(_) => "N m",
            Motion::Prismatic(_) => "N",
            Motion::Fixed => continue,
        };
        variables.push((
            format!("gravity load {}", joint.name),
            unit,
            loads.iter().map(|l| l[j]).collect(),
        ));
    }
    if samples.iter().all(|s| s.payload.is_some()) {
        variables.push((
            "payload".into(),
            "kg",
            samples.iter().filter_map(|s| s.payload).collect(),
        ));
    }
    if samples.iter().all(|s| s.temperature.is_some()) {
        variables.push((
            "temperature".into(),
            "°C",
            samples.iter().filter_map(|s| s.temperature).collect(),
        ));
    }
    variables.push((
        "time order".into(),
        "sample",
        (0..samples.len()).map(|i| i as f64).collect(),
    ));
    let correlations = variables
        .into_iter()
        .filter_map(|(variable, unit, values)| {
            let r = components.clone().map(|c| pearson(&values, &c));
            // A variable that does not vary (a fixed joint, no payload change) says nothing.
            r.iter()
                .all(|v| v.is_finite())
                .then_some(ResidualCorrelation { variable, unit, r })
        })
        .collect();
    ResidualDescription { axes, correlations }
}

/// Gravity torque (N m) about each joint's axis, or force (N) along it, of everything the joint
/// moves, payload included, at each sample of the rigid model; one entry per tree joint.
pub fn gravity_loads(robot: &Robot, samples: &[Sample]) -> Vec<Vec<f64>> {
    let tree = robot.tree();
    let mut ws = robot.workspace();
    samples
        .iter()
        .map(|s| {
            let conditions = Conditions::of(s);
            tree.forward_into(&s.q, &mut ws.rigid);
            let mass = robot.mass_under(conditions, tree, &mut ws.mass);
            ws.loads.update(tree, &ws.rigid, mass);
            let state = StaticState {
                q: &s.q,
                tree,
                frames: &ws.rigid,
                mass,
                loads: &ws.loads,
                gravity: robot.gravity_under(conditions, tree, &ws.rigid, robot.error_values()),
                temperature: conditions.temperature,
                sensors: robot.sensor_readings(conditions, robot.error_values()),
            };
            (0..tree.joints().len())
                .map(|j| joint_gravity_load(&state, j))
                .collect()
        })
        .collect()
}

/// Pearson correlation; NaN when either side does not vary.
fn pearson(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len().min(b.len()) as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let (mut sab, mut saa, mut sbb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sab += (x - ma) * (y - mb);
        saa += (x - ma) * (x - ma);
        sbb += (y - mb) * (y - mb);
    }
    let scale = (saa * sbb).sqrt();
    // Relative tolerance: round-off of a constant column is not variation.
    if scale <= 1e-300 || saa <= 1e-24 * a.iter().map(|x| x * x).sum::<f64>() {
        return f64::NAN;
    }
    sab / scale
}
