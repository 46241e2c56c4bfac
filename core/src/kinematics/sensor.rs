//! Sensors read per measurement row: an accelerometer or inclinometer on a link gives the
//! direction of gravity in that link's frame at every pose, so that a base standing on uneven
//! ground loads the elastic models with the gravity it really had, and a `measured_tilt` error
//! model can turn the chain at that link by it (see `docs/robot-files.md`, "Sensors").

use nalgebra::{UnitQuaternion, Vector3, Vector4};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::kinematics::workspace::TreeWorkspace;
use crate::model::tree::KinematicTree;
use crate::model::units::AngleUnit;
use crate::support::text::shown;

/// What a sensor measures, and so what its columns hold.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum SensorKind {
    /// Three columns: what an accelerometer at rest reads along the link's x, y, z, the
    /// reaction to gravity (+1 g along the link's up axis on level ground). Any scale (`[g]`,
    /// `[m/s2]`, none): only the direction is used.
    Accelerometer,
    /// Two columns: the link frame's roll and pitch from level, in an angle unit (the header's
    /// `[deg]`/`[rad]`, else the file's); the link frame is `Ry(pitch)·Rx(roll)` from a level
    /// frame, as URDF roll-pitch-yaw with any yaw (which gravity does not see).
    Inclinometer,
}

/// One g (m/s²), the standard acceleration of gravity.
pub const STANDARD_GRAVITY: f64 = 9.80665;

impl SensorKind {
    /// The kind as the robot file spells it.
    pub fn name(self) -> &'static str {
        match self {
            SensorKind::Accelerometer => "accelerometer",
            SensorKind::Inclinometer => "inclinometer",
        }
    }

    /// What its columns hold, in order.
    pub fn cells(self) -> &'static str {
        match self {
            SensorKind::Accelerometer => "the reading along x, y, z",
            SensorKind::Inclinometer => "roll, pitch",
        }
    }

    /// The standard deviation (SI) of a column beyond which a sensor of this kind says nothing
    /// about gravity: 1 g for an accelerometer, 10 degrees for an inclinometer.
    pub fn absurd_noise(self) -> f64 {
        match self {
            SensorKind::Accelerometer => STANDARD_GRAVITY,
            SensorKind::Inclinometer => 10f64.to_radians(),
        }
    }

    /// How many columns a sensor of this kind has.
    pub fn n_columns(self) -> usize {
        match self {
            SensorKind::Accelerometer => 3,
            SensorKind::Inclinometer => 2,
        }
    }

    /// The scale to SI of a column header's unit `unit` (None: no unit), or why it is refused.
    /// `default` is the file's angle unit, used by inclinometer columns without one.
    pub fn column_scale(self, unit: Option<&str>, default: AngleUnit) -> Result<f64, String> {
        match (self, unit) {
            // Only the direction of an accelerometer's reading is used, but its columns must
            // share a scale: each is read in m/s² (a column without a unit too).
            (SensorKind::Accelerometer, None | Some("m/s2" | "m/s^2" | "m/s²")) => Ok(1.0),
            (SensorKind::Accelerometer, Some("g")) => Ok(STANDARD_GRAVITY),
            (SensorKind::Accelerometer, Some(u)) => Err(format!(
                "an accelerometer column reads an acceleration (g or m/s2, or no unit), got `{}`",
                shown(u)
            )),
            (SensorKind::Inclinometer, None) => Ok(default.to_si()),
            (SensorKind::Inclinometer, Some(u)) => AngleUnit::parse(u)
                .map(AngleUnit::to_si)
                .ok_or_else(|| format!("an inclinometer column reads an angle (rad or deg), got `{}`", shown(u))),
        }
    }

    /// The unit direction of gravity in the sensor's link frame from its cells (SI; the first
    /// [`n_columns`](Self::n_columns) of `cells`), or why they give none.
    pub fn gravity_direction(self, cells: &Vector4<f64>) -> Result<Vector3<f64>, String> {
        match self {
            SensorKind::Accelerometer => {
                let reading = cells.fixed_rows::<3>(0).into_owned();
                let norm = reading.norm();
                if !(norm > 0.0 && norm.is_finite()) {
                    return Err("the accelerometer reads zero: it gives no direction of gravity".into());
                }
                // An accelerometer at rest reads the reaction to gravity, pointing up.
                Ok(-reading / norm)
            }
            SensorKind::Inclinometer => {
                let (roll, pitch) = (cells[0], cells[1]);
                if roll.abs() > std::f64::consts::PI || pitch.abs() > std::f64::consts::FRAC_PI_2 {
                    return Err(format!(
                        "roll {:.3} deg, pitch {:.3} deg: expected a roll within ±180 deg and a pitch within ±90 deg",
                        roll.to_degrees(),
                        pitch.to_degrees()
                    ));
                }
                // (0, 0, -1) of the level frame seen from Ry(pitch)·Rx(roll).
                let (sr, cr) = roll.sin_cos();
                let (sp, cp) = pitch.sin_cos();
                Ok(Vector3::new(sp, -sr * cp, -cr * cp))
            }
        }
    }

    /// The cells (SI; accelerometers in g) a perfect sensor of this kind reads when gravity
    /// points along unit `direction` of its link frame: the inverse of
    /// [`gravity_direction`](Self::gravity_direction), for simulated measurements.
    pub fn cells_for(self, direction: &Vector3<f64>) -> Vector4<f64> {
        match self {
            SensorKind::Accelerometer => Vector4::new(-direction.x, -direction.y, -direction.z, 0.0),
            SensorKind::Inclinometer => {
                let pitch = direction.x.clamp(-1.0, 1.0).asin();
                let roll = (-direction.y).atan2(-direction.z);
                Vector4::new(roll, pitch, 0.0, 0.0)
            }
        }
    }
}

/// A sensor declared in the robot file (`[[sensors]]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SensorSpec {
    /// The sensor's name, for messages and for the error models that read it.
    pub name: String,
    /// What it measures: `accelerometer` (3 columns) or `inclinometer` (roll and pitch).
    pub kind: SensorKind,
    /// The link it is fixed to; its columns are in that link's frame (a point's frame). One
    /// sensor per link.
    pub link: String,
    /// Its columns in measurement files, in order (x, y, z; or roll, pitch).
    pub columns: Vec<String>,
    /// The standard deviation of each of its columns, in `noise_unit`: what `simulate` adds to
    /// its readings. None: a perfect sensor.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise: Option<f64>,
    /// The unit of `noise`, as a column header gives it: `deg` or `rad` for an inclinometer
    /// (default: the file's angle unit), `g` or `m/s2` for an accelerometer (default: m/s²).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_unit: Option<String>,
}

/// A sensor of the built robot: its link's body and its columns.
#[derive(Debug, Clone, PartialEq)]
pub struct GravitySensor {
    /// The sensor's name.
    pub name: String,
    /// What it measures.
    pub kind: SensorKind,
    /// The tree body of its link.
    pub body: usize,
    /// Its column names, in order.
    pub columns: Vec<String>,
    /// The standard deviation of each column (SI: rad for an inclinometer, m/s² for an
    /// accelerometer); 0 for a perfect sensor.
    pub noise: f64,
}

impl GravitySensor {
    /// The reading of this sensor, mounted on its link turned by `mounting` (sensor frame to
    /// link frame), when gravity points along unit `down` of its link's frame, with the
    /// sensor's noise drawn by `draw` (one standard normal number per column): what a
    /// simulated campaign records.
    pub fn simulated_reading(
        &self,
        down: &Vector3<f64>,
        mounting: &UnitQuaternion<f64>,
        mut draw: impl FnMut() -> f64,
    ) -> Result<GravityReading, String> {
        let mut cells = self.kind.cells_for(&mounting.inverse_transform_vector(down));
        // Cells of an accelerometer are in g.
        let scale = match self.kind {
            SensorKind::Accelerometer => self.noise / STANDARD_GRAVITY,
            SensorKind::Inclinometer => self.noise,
        };
        for k in 0..self.kind.n_columns() {
            cells[k] += scale * draw();
        }
        Ok(GravityReading {
            body: self.body,
            direction: self.kind.gravity_direction(&cells)?,
        })
    }
}

/// Among `sensors`, the one whose reading gives the elastic models their direction of gravity:
/// the one on the base (the tree's root), which no bending turns, else the first declared.
pub fn gravity_sensor_index(sensors: &[GravitySensor]) -> Option<usize> {
    (sensors.iter().position(|s| s.body == 0)).or((!sensors.is_empty()).then_some(0))
}

/// Most sensors one robot may declare: their readings travel with every evaluation's
/// conditions, which are copied into the forward kinematics' inner loops and so have a fixed
/// size.
pub const MAX_SENSORS: usize = 4;

/// One row's readings, one slot per sensor of the robot in the order of its `[[sensors]]`;
/// a slot is empty when the row has no reading of that sensor. Fixed-size and `Copy`, so
/// evaluations carry it without allocating.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct SensorReadings([Option<GravityReading>; MAX_SENSORS]);

impl SensorReadings {
    /// The reading of sensor `k`, if the row has one.
    #[inline]
    pub fn get(&self, k: usize) -> Option<&GravityReading> {
        self.0.get(k).and_then(Option::as_ref)
    }

    /// Sets the reading of sensor `k` (< [`MAX_SENSORS`]; the robot's build refuses more).
    #[inline]
    pub fn set(&mut self, k: usize, reading: Option<GravityReading>) {
        self.0[k] = reading;
    }

    /// Readings with only sensor `k`'s.
    pub fn one(k: usize, reading: GravityReading) -> Self {
        let mut r = SensorReadings::default();
        r.set(k, Some(reading));
        r
    }

    /// Whether no sensor is read.
    pub fn is_empty(&self) -> bool {
        self.0.iter().all(Option::is_none)
    }

    /// Every slot, in sensor order.
    pub fn iter(&self) -> impl Iterator<Item = Option<&GravityReading>> {
        self.0.iter().map(Option::as_ref)
    }
}

/// One row's measured direction of gravity, in the frame of the link the sensor is on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GravityReading {
    /// The tree body of the sensor's link.
    pub body: usize,
    /// Unit direction of gravity in the link's frame (its convention frame, where the robot
    /// file places points).
    pub direction: Vector3<f64>,
}

impl GravityReading {
    /// The direction of gravity in the base frame, through the rigid frames `frames` of `tree`
    /// (the sensor's link as the row's joint values place it).
    #[inline]
    pub fn in_base(&self, tree: &KinematicTree, frames: &TreeWorkspace) -> Vector3<f64> {
        frames.body[self.body].rotation * (tree.bodies()[self.body].convention_frame.rotation * self.direction)
    }

    /// The reading of a sensor on `body` when gravity points along unit `down` of the base
    /// frame, through `tree` at `frames`: the inverse of [`in_base`](Self::in_base).
    pub fn of_base_direction(body: usize, down: &Vector3<f64>, tree: &KinematicTree, frames: &TreeWorkspace) -> Self {
        let link = frames.body[body].rotation * tree.bodies()[body].convention_frame.rotation;
        GravityReading {
            body,
            direction: link.inverse_transform_vector(down),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::geom::rz;
    use crate::model::tree::Motion;
    use nalgebra::{Isometry3, Unit};

    #[test]
    fn accelerometer_columns_in_different_units_give_one_direction() {
        // x in g, y in m/s², z without a unit: 0.1 g, 0.980665 m/s² and 9.80665 read as one
        // vector (0.1, 0.1, 1) g, so gravity is its opposite, normalised.
        let scale = |u| SensorKind::Accelerometer.column_scale(u, AngleUnit::Deg).unwrap();
        let reading = Vector4::new(
            0.1 * scale(Some("g")),
            0.980665 * scale(Some("m/s2")),
            9.80665 * scale(None),
            0.0,
        );
        let d = SensorKind::Accelerometer.gravity_direction(&reading).unwrap();
        assert!((d + Vector3::new(0.1, 0.1, 1.0).normalize()).norm() < 1e-12, "{d}");
        assert!(
            SensorKind::Accelerometer
                .column_scale(Some("deg"), AngleUnit::Deg)
                .is_err()
        );
    }

    #[test]
    fn inclinometer_angles_give_the_hand_computed_direction() {
        // Pitch 10 deg alone: the link's x axis dips by 10 deg, so gravity has +sin 10 deg on x.
        let d = SensorKind::Inclinometer
            .gravity_direction(&Vector4::new(0.0, 10f64.to_radians(), 0.0, 0.0))
            .unwrap();
        let s = 10f64.to_radians().sin();
        assert!((d - Vector3::new(s, 0.0, -(1.0 - s * s).sqrt())).norm() < 1e-15);
        // Roll 10 deg alone: the y axis rises by 10 deg, so gravity has -sin 10 deg on y.
        let d = SensorKind::Inclinometer
            .gravity_direction(&Vector4::new(10f64.to_radians(), 0.0, 0.0, 0.0))
            .unwrap();
        assert!((d - Vector3::new(0.0, -s, -(1.0 - s * s).sqrt())).norm() < 1e-15);
        // An accelerometer reading 1 g up on level ground: gravity straight down.
        let d = SensorKind::Accelerometer
            .gravity_direction(&Vector4::new(0.0, 0.0, 9.81, 0.0))
            .unwrap();
        assert_eq!(d, Vector3::new(0.0, 0.0, -1.0));
        assert!(SensorKind::Accelerometer.gravity_direction(&Vector4::zeros()).is_err());
    }

    #[test]
    fn cells_for_inverts_gravity_direction() {
        let down = Vector3::new(0.05, -0.03, -1.0).normalize();
        for kind in [SensorKind::Accelerometer, SensorKind::Inclinometer] {
            let back = kind.gravity_direction(&kind.cells_for(&down)).unwrap();
            assert!((back - down).norm() < 1e-14, "{kind:?}");
        }
    }

    #[test]
    fn a_simulated_reading_goes_through_the_mounting_with_its_noise_in_column_units() {
        let sensor = |kind, noise| GravitySensor {
            name: "s".into(),
            kind,
            body: 0,
            columns: Vec::new(),
            noise,
        };
        let down = Vector3::new(0.02, -0.01, -1.0).normalize();
        // Mounted turned by 1° about x: it reads gravity turned back by that.
        let mounting = UnitQuaternion::from_scaled_axis(Vector3::new(1f64.to_radians(), 0.0, 0.0));
        for kind in [SensorKind::Accelerometer, SensorKind::Inclinometer] {
            let r = sensor(kind, 0.0).simulated_reading(&down, &mounting, || 1.0).unwrap();
            assert!((mounting * r.direction - down).norm() < 1e-14, "{kind:?}");
        }
        // One standard deviation on every cell: an inclinometer's 0.01° moves its roll and
        // pitch by 0.01°; an accelerometer's 0.01 m/s² moves its cells (in g) by 0.01/g₀.
        let incl = sensor(SensorKind::Inclinometer, 0.01f64.to_radians());
        let r = incl
            .simulated_reading(&down, &UnitQuaternion::identity(), || 1.0)
            .unwrap();
        let (a, b) = (
            SensorKind::Inclinometer.cells_for(&down),
            SensorKind::Inclinometer.cells_for(&r.direction),
        );
        assert!(((b - a).fixed_rows::<2>(0) - nalgebra::Vector2::repeat(0.01f64.to_radians())).norm() < 1e-12);
        let acc = sensor(SensorKind::Accelerometer, 0.01);
        let r = acc
            .simulated_reading(&down, &UnitQuaternion::identity(), || 1.0)
            .unwrap();
        let shifted = -(down + Vector3::repeat(-0.01 / STANDARD_GRAVITY));
        assert!((r.direction + shifted.normalize()).norm() < 1e-12, "{}", r.direction);
        // Readings hold a slot per sensor.
        let mut readings = SensorReadings::default();
        assert!(readings.is_empty());
        readings.set(2, Some(r));
        assert!(readings.get(2).is_some() && readings.get(0).is_none() && readings.get(MAX_SENSORS).is_none());
    }

    #[test]
    fn a_reading_on_a_turned_link_is_carried_to_the_base_frame() {
        // Base -> link1 through a revolute joint about z at q, then a convention frame turned
        // by 90 deg about x (as an MDH alpha of 90 deg would place it).
        let mut tree = KinematicTree::new("base");
        let link = tree
            .add_joint(
                "j1",
                0,
                Isometry3::translation(0.3, 0.0, 0.5),
                Motion::Revolute(Unit::new_normalize(Vector3::z())),
                None,
                "link1",
            )
            .unwrap();
        tree.set_convention_frame(link, crate::model::geom::rx(std::f64::consts::FRAC_PI_2));
        let mut frames = TreeWorkspace::new(&tree);
        let q = 30f64.to_radians();
        tree.forward_into(&[q], &mut frames);
        assert!(frames.body[link].rotation.angle_to(&rz(q).rotation) < 1e-15);

        // The base stands tilted: gravity in the base frame leans 2 deg toward +x.
        let t = 2f64.to_radians();
        let down_base = Vector3::new(t.sin(), 0.0, -t.cos());
        // By hand: the link's frame is Rz(30°)·Rx(90°) in the base frame, so the sensor reads
        // Rx(90°)ᵀ·Rz(30°)ᵀ·down. Rz(30°)ᵀ·(s, 0, -c) = (s cos30, -s sin30, -c); Rx(90°)ᵀ maps
        // (a, b, c) to (a, c, -b).
        let (s, c) = (t.sin(), t.cos());
        let (s30, c30) = (0.5, 3f64.sqrt() / 2.0);
        let by_hand = Vector3::new(s * c30, -c, s * s30);
        // An inclinometer reading on that link: roll and pitch of this direction.
        let cells = SensorKind::Inclinometer.cells_for(&by_hand);
        let reading = GravityReading {
            body: link,
            direction: SensorKind::Inclinometer.gravity_direction(&cells).unwrap(),
        };
        assert!((reading.in_base(&tree, &frames) - down_base).norm() < 1e-14);
        let back = GravityReading::of_base_direction(link, &down_base, &tree, &frames);
        assert!((back.direction - by_hand).norm() < 1e-14);
    }
}
