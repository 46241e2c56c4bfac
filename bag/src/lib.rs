//! ROS 2 bags (MCAP or sqlite3) read into measurements: the static postures of a recording of
//! joint states and a tracked point or pose, with the clock offset between the two streams
//! estimated from their motion and applied.
//!
//! The bag is streamed twice, never held whole. The first pass decodes both streams, finds the
//! joints' rests (every coordinate slower than its threshold for at least the rest time, speeds
//! from consecutive positions) and puts two speeds of the tracked point on a common time grid,
//! the tracker's and the one the robot model predicts from the joints; between the passes the
//! clock offset is the lag that best lines the two up. The second pass
//! shifts the tracker's stamps by that offset and averages its samples inside each rest. What
//! the import holds grows with the recording's duration (8 bytes per grid step and stream) and
//! its number of rests, not with its messages or their size.

#![forbid(unsafe_code)]

pub mod motion;
pub mod msg;
pub mod source;

use std::collections::BTreeMap;
use std::path::PathBuf;

use armcomp_core::data::measurement::{MeasurementSet, Sample};
use armcomp_core::{Conditions, Robot};
use nalgebra::{Quaternion, UnitQuaternion, Vector3};

pub use motion::ClockOffset;
use motion::{GridSignal, Rest, RestDetector};
pub use source::{Bag, Position, Storage, Topic};

/// What went wrong with an import.
#[derive(Debug, thiserror::Error)]
pub enum BagError {
    /// The bag (a file of it) is unreadable, corrupt, truncated or not what the flags say.
    #[error("{}: {message}", path.display())]
    Input { path: PathBuf, message: String },
    /// A setting (a flag) cannot be used with this bag or robot.
    #[error("{flag}: {message}")]
    Setting { flag: &'static str, message: String },
    /// The streams were read but give no measurement, or a clock offset that is refused.
    #[error("{0}")]
    Data(String),
}

/// Which time stamp orders and aligns the samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub enum Clock {
    /// The message's `header.stamp`, set by the publisher (the sensor's clock).
    #[default]
    Header,
    /// When the recorder received the message (the bag's clock).
    Receive,
}

/// What to import and how (SI units).
#[derive(Debug, Clone)]
pub struct ImportSettings {
    /// The `sensor_msgs/msg/JointState` topic.
    pub joint_topic: String,
    /// The `geometry_msgs/msg/PoseStamped`, `geometry_msgs/msg/TransformStamped` or
    /// `tf2_msgs/msg/TFMessage` topic of the tracked point.
    pub measurement_topic: String,
    /// The tracker's frame (a pose's `header.frame_id`, a transform's parent) and the tracked
    /// body's (a transform's `child_frame_id`): required for `/tf`, checked when given.
    pub parent_frame: Option<String>,
    pub child_frame: Option<String>,
    /// Joint names in the messages that are not the robot's and are left out (a gripper's).
    pub ignored_joints: Vec<String>,
    /// The robot's point the tracker measures (default: its first marker).
    pub point: Option<String>,
    /// The shortest rest (s).
    pub rest_time: f64,
    /// The speed under which a joint rests (rad/s; m/s for a prismatic joint).
    pub motion_threshold: f64,
    /// The largest clock offset accepted (s).
    pub max_clock_offset: f64,
    pub clock: Clock,
    /// The grid on which the speeds are correlated (s).
    pub grid_step: f64,
    /// The largest record of a bag file (bytes).
    pub max_record_bytes: u64,
}

impl ImportSettings {
    /// Settings for two topics with the defaults: rests of 1 s under 0.5 deg/s (0.5 mm/s), a
    /// clock offset up to 5 s, header stamps, a 10 ms grid.
    pub fn new(joint_topic: &str, measurement_topic: &str) -> Self {
        ImportSettings {
            joint_topic: joint_topic.into(),
            measurement_topic: measurement_topic.into(),
            parent_frame: None,
            child_frame: None,
            ignored_joints: Vec::new(),
            point: None,
            rest_time: 1.0,
            motion_threshold: 0.5f64.to_radians(),
            max_clock_offset: 5.0,
            clock: Clock::Header,
            grid_step: 0.01,
            max_record_bytes: armcomp_core::support::io::InputLimits::default().max_bytes,
        }
    }
}

/// Why a sample was left out.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DropReason {
    /// A joint sample taken while the joints moved.
    JointsMoving,
    /// A joint sample of a rest shorter than the rest time.
    RestTooShort,
    /// A joint sample of a rest during which the tracker gave no sample.
    RestWithoutTracker,
    /// A tracker sample outside every rest (once its stamp is shifted by the clock offset).
    OutsideRest,
    /// A tracker message of another frame (a pose's `frame_id`, a transform's frames).
    UnknownFrame,
    /// A message that does not decode, or whose values are not finite, whose joint arrays
    /// differ in length, or whose quaternion is not of unit norm.
    BadMessage,
    /// A message whose header stamp is zero (not set by its publisher).
    NoStamp,
    /// A message stamped no later than the one before it on its topic.
    OutOfOrder,
}

impl DropReason {
    /// The reason in words.
    pub fn describe(self) -> &'static str {
        match self {
            DropReason::JointsMoving => "joint samples while the joints moved",
            DropReason::RestTooShort => "joint samples of rests shorter than the rest time",
            DropReason::RestWithoutTracker => "joint samples of rests without a tracker sample",
            DropReason::OutsideRest => "tracker samples outside every rest",
            DropReason::UnknownFrame => "tracker messages of other frames",
            DropReason::BadMessage => "messages that do not decode or hold bad values",
            DropReason::NoStamp => "messages without a header stamp",
            DropReason::OutOfOrder => "messages stamped out of order",
        }
    }
}

/// One static posture found.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Posture {
    /// When the rest began and how long it lasted (s, joint clock, from the first joint sample).
    pub start: f64,
    pub duration: f64,
    pub joint_samples: u64,
    pub tracker_samples: u64,
    /// The tracker samples' spread about their mean: the root of their mean squared distance
    /// from it (m); `None` from a single sample.
    pub repeatability: Option<f64>,
}

/// What an import found, besides its measurements.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct ImportReport {
    pub files: Vec<PathBuf>,
    pub joint_messages: u64,
    pub measurement_messages: u64,
    /// Messages of the bag's other topics, skipped.
    pub other_messages: u64,
    pub clock_offset: ClockOffset,
    pub postures: Vec<Posture>,
    /// Samples left out, per reason.
    pub dropped: BTreeMap<DropReason, u64>,
}

/// The measurements of a bag and the report of their import.
#[derive(Debug, Clone)]
pub struct Import {
    /// One sample per posture: the mean configuration and the mean tracked position (and
    /// orientation, for a robot measuring poses).
    pub set: MeasurementSet,
    pub report: ImportReport,
}

/// How far an import has come: its pass (1: finding rests and motion; 2: averaging the
/// tracker inside the rests) and the pass' position.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Progress {
    pub pass: u8,
    pub position: Position,
}

/// A decoded tracker sample.
struct Tracked {
    stamp: i64,
    position: Vector3<f64>,
    orientation: UnitQuaternion<f64>,
}

/// The robot's side of an import: which coordinate each joint name drives.
struct JointMap<'a> {
    robot: &'a Robot,
    /// The names of the last message and, per name, its coordinate (`None`: left out).
    names: Vec<String>,
    coords: Vec<Option<usize>>,
    /// Values of the coordinates no message gives (the robot file's hold values).
    base: Vec<f64>,
    ignored: &'a [String],
}

impl<'a> JointMap<'a> {
    fn new(robot: &'a Robot, ignored: &'a [String]) -> Self {
        let base = robot.csv_layout().hold.iter().map(|h| h.unwrap_or(0.0)).collect();
        JointMap {
            robot,
            names: Vec::new(),
            coords: Vec::new(),
            base,
            ignored,
        }
    }

    /// The mapping for a message's names: an error naming the joints the robot does not know
    /// and those it needs that the message lacks.
    fn remap(&mut self, names: &[String]) -> Result<(), BagError> {
        let tree = self.robot.tree();
        let coordinates = tree.coordinate_names();
        let joints: Vec<&str> = tree.joints().iter().map(|j| j.name.as_str()).collect();
        let mut unknown = Vec::new();
        self.coords = names
            .iter()
            .map(|n| {
                let c = coordinates.iter().position(|c| c == n);
                // A robot's joint that is no coordinate (a mimic, a fixed joint) follows the others.
                if c.is_none() && !joints.contains(&n.as_str()) && !self.ignored.contains(n) {
                    unknown.push(n.as_str());
                }
                c
            })
            .collect();
        if !unknown.is_empty() {
            return Err(BagError::Setting {
                flag: "--joint-topic",
                message: format!(
                    "the joint states name joints the robot has not: {} (leave them out with --ignore-joint, or \
                     check the robot file)",
                    armcomp_core::data::measurement::listed(&unknown)
                ),
            });
        }
        let layout = self.robot.csv_layout();
        let missing: Vec<&str> = (layout.hold.iter().zip(coordinates).enumerate())
            .filter(|(k, (h, _))| h.is_none() && !self.coords.contains(&Some(*k)))
            .map(|(_, (_, n))| n.as_str())
            .collect();
        if !missing.is_empty() {
            return Err(BagError::Setting {
                flag: "--joint-topic",
                message: format!(
                    "the joint states lack joints that move the measured point: {}",
                    armcomp_core::data::measurement::listed(&missing)
                ),
            });
        }
        self.names = names.to_vec();
        Ok(())
    }

    /// The configuration of a joint state, or why it is dropped.
    fn configuration(&mut self, js: &msg::JointState, q: &mut Vec<f64>) -> Result<Option<DropReason>, BagError> {
        if js.name.len() != js.position.len() || js.position.iter().any(|v| !v.is_finite()) {
            return Ok(Some(DropReason::BadMessage));
        }
        if js.name != self.names {
            self.remap(&js.name)?;
        }
        q.clone_from(&self.base);
        for (c, v) in self.coords.iter().zip(&js.position) {
            if let Some(c) = c {
                q[*c] = *v;
            }
        }
        Ok(None)
    }
}

/// A decoded message's stamp (ns) by the chosen clock, or why it has none.
fn stamp_of(header: &msg::Header, log_time: i64, clock: Clock) -> Result<i64, DropReason> {
    match clock {
        Clock::Receive => Ok(log_time),
        Clock::Header if header.stamp == msg::Time::default() => Err(DropReason::NoStamp),
        Clock::Header => Ok(header.stamp.nanos()),
    }
}

/// The tracker sample of a measurement message, or why it is dropped; an error for a topic
/// of a type that measures nothing.
fn tracked_of(m: &source::Message<'_>, settings: &ImportSettings) -> Result<Result<Tracked, DropReason>, BagError> {
    use msg::type_name::*;
    let frame_ok = |parent: &str, child: Option<&str>| {
        settings.parent_frame.as_deref().is_none_or(|p| p == parent)
            && settings
                .child_frame
                .as_deref()
                .is_none_or(|c| child.is_none_or(|child| child == c))
    };
    let (header, translation, rotation) = match m.type_name {
        POSE_STAMPED => match msg::decode::<msg::PoseStamped>(m.data) {
            Err(_) => return Ok(Err(DropReason::BadMessage)),
            Ok(p) if !frame_ok(&p.header.frame_id, None) => return Ok(Err(DropReason::UnknownFrame)),
            Ok(p) => (p.header, p.pose.position, p.pose.orientation),
        },
        TRANSFORM_STAMPED => match msg::decode::<msg::TransformStamped>(m.data) {
            Err(_) => return Ok(Err(DropReason::BadMessage)),
            Ok(t) if !frame_ok(&t.header.frame_id, Some(&t.child_frame_id)) => {
                return Ok(Err(DropReason::UnknownFrame));
            }
            Ok(t) => (t.header, t.transform.translation, t.transform.rotation),
        },
        TF_MESSAGE => {
            let (Some(parent), Some(child)) = (&settings.parent_frame, &settings.child_frame) else {
                return Err(BagError::Setting {
                    flag: "--parent-frame, --child-frame",
                    message: format!(
                        "`{}` carries transforms between many frames: name the tracker's frame and the tracked body's",
                        settings.measurement_topic
                    ),
                });
            };
            match msg::decode::<msg::TfMessage>(m.data) {
                Err(_) => return Ok(Err(DropReason::BadMessage)),
                Ok(tf) => match (tf.transforms.into_iter())
                    .find(|t| &t.header.frame_id == parent && &t.child_frame_id == child)
                {
                    None => return Ok(Err(DropReason::UnknownFrame)),
                    Some(t) => (t.header, t.transform.translation, t.transform.rotation),
                },
            }
        }
        other => {
            return Err(BagError::Setting {
                flag: "--measurement-topic",
                message: format!(
                    "`{}` is of type `{other}`; a measurement is read from {POSE_STAMPED}, {TRANSFORM_STAMPED} or \
                     {TF_MESSAGE}",
                    settings.measurement_topic
                ),
            });
        }
    };
    let stamp = match stamp_of(&header, m.log_time, settings.clock) {
        Ok(s) => s,
        Err(reason) => return Ok(Err(reason)),
    };
    let position = Vector3::new(translation.x, translation.y, translation.z);
    let q = Quaternion::new(rotation.w, rotation.x, rotation.y, rotation.z);
    if !position.iter().chain(q.coords.iter()).all(|v| v.is_finite()) || (q.norm() - 1.0).abs() > 1e-3 {
        return Ok(Err(DropReason::BadMessage));
    }
    Ok(Ok(Tracked {
        stamp,
        position,
        orientation: UnitQuaternion::from_quaternion(q),
    }))
}

/// The sums a posture's tracker samples are averaged from.
#[derive(Debug, Clone, Default)]
struct PostureSums {
    n: u64,
    mean: Vector3<f64>,
    /// Welford's sum of squared distances from the running mean.
    m2: f64,
    /// Quaternions summed on the first one's side (`q` and `−q` are one rotation).
    quaternion: Quaternion<f64>,
}

impl PostureSums {
    fn add(&mut self, p: &Vector3<f64>, q: &UnitQuaternion<f64>) {
        self.n += 1;
        let delta = p - self.mean;
        self.mean += delta / self.n as f64;
        self.m2 += delta.dot(&(p - self.mean));
        let q = q.quaternion();
        let first = if self.n == 1 { *q } else { self.quaternion };
        self.quaternion += if first.dot(q) < 0.0 { -q } else { *q };
    }
}

/// Imports the bag at `settings`' topics for `robot`: its static postures as measurements,
/// each the mean of the joints and of the tracker over one rest, with the clock offset
/// between the streams estimated from their motion and applied. `progress` is told how far
/// each pass has come.
pub fn import_bag(
    bag: &Bag,
    robot: &Robot,
    settings: &ImportSettings,
    progress: &mut dyn FnMut(Progress),
) -> Result<Import, BagError> {
    check_settings(settings)?;
    let tree = robot.tree();
    let point = match &settings.point {
        None => *robot.markers().first().ok_or_else(|| BagError::Setting {
            flag: "--point",
            message: "the robot file has no marker: name the measured point".into(),
        })?,
        Some(name) => tree
            .points()
            .iter()
            .position(|p| &p.name == name)
            .ok_or_else(|| BagError::Setting {
                flag: "--point",
                message: format!("the robot has no point `{name}`"),
            })?,
    };
    let thresholds: Vec<f64> = tree
        .coordinate_is_prismatic()
        .iter()
        .map(|&p| {
            if p {
                settings.motion_threshold.to_degrees() * 1e-3
            } else {
                settings.motion_threshold
            }
        })
        .collect();
    let topics = [settings.joint_topic.as_str(), settings.measurement_topic.as_str()];
    let step = settings.grid_step;
    // 2^24 grid steps: two days at 10 ms, 128 MiB per stream.
    let max_points = 1usize << 24;
    let mut dropped: BTreeMap<DropReason, u64> = BTreeMap::new();

    // Pass 1: rests, speeds, counts.
    let mut joints = JointMap::new(robot, &settings.ignored_joints);
    let mut rests = RestDetector::new(thresholds, settings.rest_time);
    let (mut joint_speed, mut tracker_speed) = (GridSignal::default(), GridSignal::default());
    let mut origin: Option<i64> = None;
    let mut last_joint: Option<(i64, Vector3<f64>)> = None;
    let mut ws = robot.workspace();
    let mut last_tracked: Option<(i64, Vector3<f64>)> = None;
    let (mut joint_messages, mut measurement_messages) = (0u64, 0u64);
    let mut q = Vec::with_capacity(tree.nq());
    let mut types_seen = [false; 2];
    let grid_error = |e: String| BagError::Data(format!("{}: {e}", bag_name(bag)));
    let summary = bag.stream(
        &topics,
        settings.max_record_bytes,
        &mut |position| progress(Progress { pass: 1, position }),
        &mut |m| {
            types_seen[m.topic] = true;
            if m.topic == 0 {
                joint_messages += 1;
                if m.type_name != msg::type_name::JOINT_STATE {
                    return Err(BagError::Setting {
                        flag: "--joint-topic",
                        message: format!(
                            "`{}` is of type `{}`, not {}",
                            settings.joint_topic,
                            m.type_name,
                            msg::type_name::JOINT_STATE
                        ),
                    });
                }
                let Ok(js) = msg::decode::<msg::JointState>(m.data) else {
                    count(&mut dropped, DropReason::BadMessage, 1);
                    return Ok(());
                };
                if let Some(reason) = joints.configuration(&js, &mut q)? {
                    count(&mut dropped, reason, 1);
                    return Ok(());
                }
                let stamp = match stamp_of(&js.header, m.log_time, settings.clock) {
                    Ok(s) => s,
                    Err(reason) => {
                        count(&mut dropped, reason, 1);
                        return Ok(());
                    }
                };
                if last_joint.as_ref().is_some_and(|(t, _)| stamp <= *t) {
                    count(&mut dropped, DropReason::OutOfOrder, 1);
                    return Ok(());
                }
                let t0 = *origin.get_or_insert(stamp);
                let t = seconds(stamp - t0);
                rests.push(t, &q);
                // The marker's speed as the robot model predicts it from the joints: the same
                // quantity as the tracker's, whatever the measurement frame (a rigid motion
                // keeps speeds), so that the two speeds line up without a bias from their
                // shapes.
                let predicted = robot.measured_position(&q, point, Conditions::default(), &mut ws);
                if let Some((prev, p0)) = &last_joint {
                    let dt = seconds(stamp - *prev);
                    joint_speed
                        .push(t - 0.5 * dt, (predicted - *p0).norm() / dt, step, max_points)
                        .map_err(grid_error)?;
                }
                last_joint = Some((stamp, predicted));
            } else {
                measurement_messages += 1;
                let tracked = match tracked_of(&m, settings)? {
                    Ok(t) => t,
                    Err(reason) => {
                        count(&mut dropped, reason, 1);
                        return Ok(());
                    }
                };
                if last_tracked.is_some_and(|(t, _)| tracked.stamp <= t) {
                    count(&mut dropped, DropReason::OutOfOrder, 1);
                    return Ok(());
                }
                let t0 = *origin.get_or_insert(tracked.stamp);
                if let Some((prev, p0)) = last_tracked {
                    let dt = seconds(tracked.stamp - prev);
                    let speed = (tracked.position - p0).norm() / dt;
                    tracker_speed
                        .push(seconds(tracked.stamp - t0) - 0.5 * dt, speed, step, max_points)
                        .map_err(grid_error)?;
                }
                last_tracked = Some((tracked.stamp, tracked.position));
            }
            Ok(())
        },
    )?;
    rests.finish();
    for (k, topic) in topics.iter().enumerate() {
        if !types_seen[k] {
            let listed: Vec<String> = summary
                .topics
                .iter()
                .map(|t| format!("{} ({})", t.name, t.type_name))
                .collect();
            return Err(BagError::Setting {
                flag: if k == 0 { "--joint-topic" } else { "--measurement-topic" },
                message: format!(
                    "{} has no message on `{topic}`; its topics: {}",
                    bag_name(bag),
                    if listed.is_empty() {
                        "none".into()
                    } else {
                        listed.join(", ")
                    }
                ),
            });
        }
    }
    for (reason, n) in [
        (DropReason::JointsMoving, rests.moving),
        (DropReason::RestTooShort, rests.too_short),
    ] {
        if n > 0 {
            count(&mut dropped, reason, n);
        }
    }
    if rests.rests.is_empty() {
        return Err(BagError::Data(format!(
            "{}: the joints never rest for {} s under {} deg/s (--rest-s, --motion-threshold-deg-s)",
            bag_name(bag),
            settings.rest_time,
            settings.motion_threshold.to_degrees()
        )));
    }
    let offset = motion::estimate_offset(&joint_speed, &tracker_speed, step)
        .map_err(|e| BagError::Data(format!("{}: {e}", bag_name(bag))))?;
    if offset.seconds.abs() > settings.max_clock_offset {
        return Err(BagError::Data(format!(
            "{}: the tracker's clock is {:+.4} s ± {:.4} s off the joints' (correlation {:.2}), beyond the {} s \
             accepted (--max-clock-offset-s): synchronize the clocks, or raise the bound if the offset is expected",
            bag_name(bag),
            offset.seconds,
            offset.std,
            offset.correlation,
            settings.max_clock_offset
        )));
    }

    // Pass 2: the tracker inside the rests, its stamps moved onto the joints' clock. A rest's
    // edges are trimmed by three uncertainties of the offset.
    let origin = origin.unwrap_or_default();
    let margin = 3.0 * offset.std;
    let mut sums = vec![PostureSums::default(); rests.rests.len()];
    let mut next = 0;
    let mut last_stamp: Option<i64> = None;
    bag.stream(
        &topics[1..],
        settings.max_record_bytes,
        &mut |position| progress(Progress { pass: 2, position }),
        &mut |m| {
            // Bad, foreign and out-of-order messages were counted in the first pass.
            let Ok(tracked) = tracked_of(&m, settings)? else {
                return Ok(());
            };
            if last_stamp.is_some_and(|t| tracked.stamp <= t) {
                return Ok(());
            }
            last_stamp = Some(tracked.stamp);
            let t = seconds(tracked.stamp - origin) - offset.seconds;
            let all = &rests.rests;
            while next < all.len() && all[next].end - margin < t {
                next += 1;
            }
            match all.get(next) {
                Some(rest) if t >= rest.start + margin => sums[next].add(&tracked.position, &tracked.orientation),
                _ => count(&mut dropped, DropReason::OutsideRest, 1),
            }
            Ok(())
        },
    )?;

    let mut set = MeasurementSet::default();
    let mut postures = Vec::new();
    for (rest, s) in rests.rests.iter().zip(&sums) {
        if s.n == 0 {
            count(&mut dropped, DropReason::RestWithoutTracker, rest.samples);
            continue;
        }
        set.rows.push(set.samples.len());
        set.samples.push(sample_of(rest, s, point, robot.measures_pose()));
        postures.push(Posture {
            start: rest.start,
            duration: rest.end - rest.start,
            joint_samples: rest.samples,
            tracker_samples: s.n,
            repeatability: (s.n > 1).then(|| (s.m2 / s.n as f64).sqrt()),
        });
    }
    if set.samples.is_empty() {
        return Err(BagError::Data(format!(
            "{}: the tracker gave no sample during any of the {} rests of the joints",
            bag_name(bag),
            rests.rests.len()
        )));
    }
    Ok(Import {
        set,
        report: ImportReport {
            files: bag.files.iter().map(|(p, _)| p.clone()).collect(),
            joint_messages,
            measurement_messages,
            other_messages: summary.other_messages,
            clock_offset: offset,
            postures,
            dropped,
        },
    })
}

fn check_settings(s: &ImportSettings) -> Result<(), BagError> {
    let positive = |flag: &'static str, v: f64, unit: &str| {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(BagError::Setting {
                flag,
                message: format!("expected a positive number of {unit}, got {v}"),
            })
        }
    };
    positive("--rest-s", s.rest_time, "seconds")?;
    positive("--motion-threshold-deg-s", s.motion_threshold, "deg/s")?;
    positive("--max-clock-offset-s", s.max_clock_offset, "seconds")?;
    positive("grid step", s.grid_step, "seconds")
}

fn sample_of(rest: &Rest, s: &PostureSums, point: usize, pose: bool) -> Sample {
    Sample {
        q: rest.q.clone(),
        point,
        position: s.mean,
        orientation: pose.then(|| UnitQuaternion::from_quaternion(s.quaternion)),
        payload: None,
        temperature: None,
        torque: None,
        fixed_point: None,
        plane: None,
        sensors: Default::default(),
        position_std: None,
        station: 0,
    }
}

/// Counts `n` more samples dropped for `reason`.
fn count(dropped: &mut BTreeMap<DropReason, u64>, reason: DropReason, n: u64) {
    *dropped.entry(reason).or_default() += n;
}

fn seconds(nanos: i64) -> f64 {
    nanos as f64 * 1e-9
}

/// The bag's name in messages: its file, or its first file and how many more.
fn bag_name(bag: &Bag) -> String {
    match bag.files.as_slice() {
        [(one, _)] => one.display().to_string(),
        [(first, _), rest @ ..] => format!("{} (and {} more files)", first.display(), rest.len()),
        [] => "the bag".into(),
    }
}
