//! Measured tilt: a gravity sensor's reading turns the chain at the sensor's link, row by row.
//!
//! On soft or uneven ground a base rocks from pose to pose by hundredths of a degree, and a
//! column leans under the arm's moment. A sensor (`[[sensors]]`) reads its link's orientation
//! against gravity on every row. This model compares that reading with the direction of gravity
//! the model predicts at the link, and turns the chain at the link by the smallest rotation
//! between the two: about axes square to gravity only (roll and pitch), since gravity does not
//! see a turn about itself. On the base, the joints seated on it and the points on it move, in
//! their own frames, as `geometric_offsets` moves the base's; everything beyond turns with them.
//! A link off the base turns where it is seated: about its joint's frame before the joint's
//! motion. For a revolute joint that is the link's own origin; a telescopic section (a prismatic
//! joint) leans about where it leaves its guide, not about its far end that slides out.
//!
//! Gravity does not see a turn about itself, so the reading leaves one direction of the turn
//! open. On the base the smallest turn is the one wanted: a base rocks about its own
//! horizontal axes, and the smallest turn from a level base has no part about its vertical.
//! A link off the base leans about axes square to its joint's axis: a section does not twist
//! in its guide, and a turn about a revolute joint's axis is that joint's own angle. When the
//! joint's axis stands near the vertical (a column on tilted ground), the smallest turn is not
//! square to it: a lean of 0.06° on a column standing 3° off the vertical would carry a twist
//! of 0.003° about the column, 0.08 mm at 1.5 m from it. The turn is then given the part about
//! gravity that makes it square to the axis. Nearer the horizontal that part grows without
//! bound (gravity sees a turn about a level axis itself), so it is faded out between 60° and
//! 37° from the vertical, and a level axis keeps the smallest turn.
//!
//! The prediction is the robot file's gravity (a level base) for a sensor on the base. For a
//! sensor on another link it is the gravity the elastic models see, carried to the link by the
//! rigid chain, when that gravity is read on the base (so the base's own turn is not counted
//! again, and what is left is the link's lean); otherwise the file's gravity. The bending that
//! other error models put between the base and the link is not in the prediction: a lean this
//! model turns should not be modelled by a compliance below the link as well.
//!
//! Its parameters are the sensor's mounting on its link: two small angles about the link's x
//! and y axes (sensor frame to link frame). The robot turns every reading of the sensor by it
//! before any model sees it ([`ErrorModel::sensor_mounting`]), so the elastic models load the
//! arm with the corrected gravity too. A constant turn of the base is what the measurement
//! frame already identifies; the mounting shows through what the corrected gravity bends.
//!
//! Against [`base_tilt`](crate::base_tilt): that model identifies one constant tilt of the base
//! (with a sensor, the sensor's misalignment, the per-row tilt only loading the elastic models)
//! and cannot follow a base that rocks from row to row; this one turns the chain by the tilt of
//! every row, and identifies the same misalignment as its mounting. Use one or the other on a
//! base sensor; both turn the measured gravity by two angles ([`tilt_rotation`]).

use armcomp_core::{ErrorModel, ErrorModelSpec, Issues, ModelContext, Motion, ParamInfo, Perturbation, StaticState};
use nalgebra::{UnitQuaternion, Vector3, Vector6};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::base_tilt::{tilt_params, tilt_rotation};
use crate::common::{check_finite, name_list};
use crate::geometric_offsets::BodyAttachments;

/// A measured tilt as written in the robot file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MeasuredTiltSpec {
    /// The sensor (its `[[sensors]]` name) whose reading turns the chain at its link.
    pub sensor: String,
    /// How the sensor sits on its link: turned about the link's x and y axes, in the file's
    /// angle unit.
    #[serde(default)]
    pub mounting: [f64; 2],
}

/// What the link's measured orientation is compared with.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Reference {
    /// The robot file's gravity: a level base.
    Level,
    /// The gravity the elastic models see, read on the base.
    BaseReading,
}

/// Where a measured tilt turns the chain.
#[derive(Debug, Clone)]
enum Turned {
    /// The base: the joints seated on it and its points.
    Base(BodyAttachments),
    /// The joint (its frame before the motion) whose child is the sensor's link, and its axis
    /// in that frame (none for a fixed joint).
    Joint(usize, Option<Vector3<f64>>),
}

/// The built measured-tilt model.
#[derive(Debug, Clone)]
pub struct MeasuredTiltModel {
    spec: MeasuredTiltSpec,
    units: armcomp_core::Units,
    /// The sensor's index among the robot's.
    sensor: usize,
    /// Its link's body.
    body: usize,
    /// What the turn moves: the base's attachments, or the joint the link is seated on.
    turned: Turned,
    reference: Reference,
    /// The direction of the file's gravity (base frame).
    level: Vector3<f64>,
    params: Vec<ParamInfo>,
}

#[typetag::serde(name = "measured_tilt")]
impl ErrorModelSpec for MeasuredTiltSpec {
    fn build(&self, ctx: &ModelContext<'_>) -> Result<Box<dyn ErrorModel>, Issues> {
        let path = ctx.build.path;
        let mut issues = Issues::default();
        for (k, v) in self.mounting.iter().enumerate() {
            check_finite(&mut issues, &format!("{path}.mounting[{k}]"), *v);
        }
        let sensor = ctx.sensors.iter().position(|s| s.name == self.sensor);
        if sensor.is_none() {
            issues.push(
                format!("{path}.sensor"),
                match ctx.sensors {
                    [] => format!(
                        "sensor `{}` is not declared: the robot file has no `[[sensors]]`",
                        self.sensor
                    ),
                    s => format!(
                        "sensor `{}` is not declared; sensors are: {}",
                        self.sensor,
                        name_list(s.iter().map(|s| s.name.as_str()))
                    ),
                },
            );
        }
        let level = ctx.gravity.try_normalize(0.0);
        if level.is_none() {
            issues.push(
                format!("{path}.sensor"),
                "the robot file's gravity is zero: a level base has no direction to compare the reading with",
            );
        }
        let (Some(sensor), Some(level), true) = (sensor, level, issues.is_empty()) else {
            return Err(issues);
        };
        let body = ctx.sensors[sensor].body;
        let read_on_base = ctx.gravity_sensor.is_some_and(|g| ctx.sensors[g].body == 0);
        let units = ctx.build.units;
        Ok(Box::new(MeasuredTiltModel {
            spec: self.clone(),
            units,
            sensor,
            body,
            // Body `b > 0` is the child of joint `b − 1` (see `KinematicTree`).
            turned: match body {
                0 => Turned::Base(BodyAttachments::of(ctx.tree, 0)),
                b => Turned::Joint(
                    b - 1,
                    match ctx.tree.joints()[b - 1].motion {
                        Motion::Revolute(a) | Motion::Prismatic(a) => Some(a.into_inner()),
                        Motion::Fixed => None,
                    },
                ),
            },
            reference: if body != 0 && read_on_base {
                Reference::BaseReading
            } else {
                Reference::Level
            },
            level,
            // A sensor is screwed on within a degree or so; beyond a few it was put on wrong.
            params: tilt_params(&format!("measured_tilt.{}", self.sensor), &self.mounting, &units),
        }))
    }
}

impl ErrorModel for MeasuredTiltModel {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    fn perturb(&self, state: &StaticState<'_>, _values: &[f64], out: &mut Perturbation) {
        // A row without the sensor's reading (a file without its columns) stands as modelled.
        let Some(reading) = state.sensors.get(self.sensor) else {
            return;
        };
        let tree = state.tree;
        // Both directions in the link's body frame; the reading is in its convention frame,
        // its mounting already applied (`sensor_mounting`).
        let measured = tree.bodies()[self.body].convention_frame.rotation * reading.direction;
        let reference = match self.reference {
            Reference::Level => self.level,
            Reference::BaseReading => state.gravity.try_normalize(0.0).unwrap_or(self.level),
        };
        let predicted = state.frames.body[self.body]
            .rotation
            .inverse_transform_vector(&reference);
        // The link turned by this takes the measured gravity to where the model predicts it,
        // as the tilted link really stands in the level frame. Opposite directions (a link
        // upside down against its prediction) have no smallest turn: nothing is added.
        let Some(turn) = UnitQuaternion::rotation_between(&measured, &predicted) else {
            return;
        };
        let r = turn.scaled_axis();
        match &self.turned {
            Turned::Base(attachments) => attachments.apply(&Vector6::new(0.0, 0.0, 0.0, r.x, r.y, r.z), tree, out),
            Turned::Joint(j, axis) => {
                // The turn in the link's frame, carried into the joint's frame before its
                // motion (for a prismatic joint the same axes; for a revolute one turned by q).
                let motion = state.frames.joint_frame[*j].rotation.inverse() * state.frames.body[self.body].rotation;
                let mut r = motion * r;
                if let Some(a) = axis {
                    // The part about gravity that makes the turn square to the axis (module docs);
                    // none near a level axis, where `c` may be zero.
                    let down = motion * predicted;
                    let c = down.dot(a);
                    let w = square_weight(c.abs());
                    if w > 0.0 {
                        r -= down * (w * r.dot(a) / c);
                    }
                }
                out.joint_twist[*j] += Vector6::new(0.0, 0.0, 0.0, r.x, r.y, r.z);
            }
        }
    }

    fn sensor_mounting(&self, values: &[f64]) -> Option<(usize, UnitQuaternion<f64>)> {
        Some((self.sensor, tilt_rotation(values)))
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn ErrorModelSpec> {
        let mut spec = self.spec.clone();
        spec.mounting = [self.units.ang_out(values[0]), self.units.ang_out(values[1])];
        Box::new(spec)
    }
}

/// How much of the part about gravity a turn is given to make it square to a joint's axis,
/// from `c`, the cosine of the axis' angle to gravity: all of it within 37° of the vertical
/// (`c` ≥ 0.8), none beyond 60° (`c` ≤ 0.5), and a smooth step between, so the model stays
/// differentiable in the link's orientation.
fn square_weight(c: f64) -> f64 {
    let t = ((c - 0.5) / 0.3).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}
