//! The ROS 2 messages a bag's measurement streams are read from, decoded from CDR.
//!
//! A serialized ROS 2 message is a 4-byte encapsulation header (`00 01`: little-endian CDR,
//! `00 00`: big-endian; two option bytes) followed by the CDR body, aligned from the body's
//! start. The body is decoded by the `cdr-encoding` crate (the DDS implementation RustDDS's own
//! CDR codec) through serde structs that mirror the message definitions field by field, in
//! order: CDR is not self-describing, so the order is the layout.

use serde::{Deserialize, Serialize};

/// `builtin_interfaces/msg/Time`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}

impl Time {
    /// Nanoseconds since the clock's epoch.
    pub fn nanos(self) -> i64 {
        i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec)
    }

    /// The time `nanos` nanoseconds after the epoch.
    pub fn from_nanos(nanos: i64) -> Time {
        Time {
            sec: nanos.div_euclid(1_000_000_000) as i32,
            nanosec: nanos.rem_euclid(1_000_000_000) as u32,
        }
    }
}

/// `std_msgs/msg/Header`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Header {
    pub stamp: Time,
    pub frame_id: String,
}

/// `sensor_msgs/msg/JointState`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct JointState {
    pub header: Header,
    pub name: Vec<String>,
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
    pub effort: Vec<f64>,
}

/// `geometry_msgs/msg/Vector3` and `geometry_msgs/msg/Point` (the same layout).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Vector3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

/// `geometry_msgs/msg/Quaternion` (x, y, z, w in this order).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Quaternion {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub w: f64,
}

/// `geometry_msgs/msg/Pose`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Pose {
    pub position: Vector3,
    pub orientation: Quaternion,
}

/// `geometry_msgs/msg/PoseStamped`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct PoseStamped {
    pub header: Header,
    pub pose: Pose,
}

/// `geometry_msgs/msg/Transform`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Transform {
    pub translation: Vector3,
    pub rotation: Quaternion,
}

/// `geometry_msgs/msg/TransformStamped`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct TransformStamped {
    pub header: Header,
    pub child_frame_id: String,
    pub transform: Transform,
}

/// `tf2_msgs/msg/TFMessage` (what `/tf` and `/tf_static` carry).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct TfMessage {
    pub transforms: Vec<TransformStamped>,
}

/// The ROS 2 type names (`sensor_msgs/msg/JointState`) of the messages read.
pub mod type_name {
    pub const JOINT_STATE: &str = "sensor_msgs/msg/JointState";
    pub const POSE_STAMPED: &str = "geometry_msgs/msg/PoseStamped";
    pub const TRANSFORM_STAMPED: &str = "geometry_msgs/msg/TransformStamped";
    pub const TF_MESSAGE: &str = "tf2_msgs/msg/TFMessage";
}

/// Decodes a serialized ROS 2 message (encapsulation header and CDR body); the error says
/// what is wrong with the bytes.
pub fn decode<T: for<'de> Deserialize<'de>>(bytes: &[u8]) -> Result<T, String> {
    let (head, body) = bytes.split_at_checked(4).ok_or_else(|| {
        format!(
            "{} bytes, shorter than the 4-byte CDR encapsulation header",
            bytes.len()
        )
    })?;
    let decoded = match (head[0], head[1]) {
        (0, 1) => cdr_encoding::from_bytes::<T, byteorder::LittleEndian>(body),
        (0, 0) => cdr_encoding::from_bytes::<T, byteorder::BigEndian>(body),
        (a, b) => {
            return Err(format!(
                "encapsulation {a:02x} {b:02x} is not plain CDR (00 00 or 00 01)"
            ));
        }
    };
    decoded.map(|(value, _)| value).map_err(|e| format!("CDR body: {e}"))
}

/// Encodes `message` as a ROS 2 publisher serializes it: little-endian CDR with its
/// encapsulation header.
pub fn encode<T: Serialize>(message: &T) -> Vec<u8> {
    let mut bytes = vec![0, 1, 0, 0];
    bytes.extend(
        cdr_encoding::to_vec::<T, byteorder::LittleEndian>(message).expect("these message types serialize to CDR"),
    );
    bytes
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_joint_state_has_the_ros2_byte_layout() {
        // By hand, little-endian CDR of a JointState stamped 3 s + 5 ns in frame "" with one
        // joint "a" at 0.5 rad, no velocity or effort: sec, nanosec, frame_id (length 1, the
        // terminator, 3 bytes of padding), one name (length 2: "a" and the terminator, 2
        // bytes of padding), one position (its count ends at byte 32 of the body, aligned to 8
        // from the body's start, so no padding before the double), two empty sequences.
        let msg = JointState {
            header: Header {
                stamp: Time { sec: 3, nanosec: 5 },
                frame_id: String::new(),
            },
            name: vec!["a".into()],
            position: vec![0.5],
            velocity: vec![],
            effort: vec![],
        };
        let mut expected = vec![0u8, 1, 0, 0];
        expected.extend(3i32.to_le_bytes());
        expected.extend(5u32.to_le_bytes());
        expected.extend(1u32.to_le_bytes());
        expected.extend([0, 0, 0, 0]);
        expected.extend(1u32.to_le_bytes());
        expected.extend(2u32.to_le_bytes());
        expected.extend([b'a', 0, 0, 0]);
        expected.extend(1u32.to_le_bytes());
        expected.extend(0.5f64.to_le_bytes());
        expected.extend(0u32.to_le_bytes());
        expected.extend(0u32.to_le_bytes());
        let bytes = encode(&msg);
        assert_eq!(bytes, expected);
        assert_eq!(decode::<JointState>(&bytes).unwrap(), msg);
    }

    #[test]
    fn big_endian_bodies_decode_and_other_encapsulations_are_refused() {
        let mut bytes = vec![0u8, 0, 0, 0];
        for v in [1.0f64, 2.0, 3.0] {
            bytes.extend(v.to_be_bytes());
        }
        let v: Vector3 = decode(&bytes).unwrap();
        assert_eq!((v.x, v.y, v.z), (1.0, 2.0, 3.0));
        bytes[1] = 3;
        assert!(decode::<Vector3>(&bytes).unwrap_err().contains("not plain CDR"));
        assert!(decode::<Vector3>(&bytes[..2]).unwrap_err().contains("shorter"));
        let short = [0u8, 1, 0, 0, 1, 2, 3];
        assert!(decode::<Vector3>(&short).unwrap_err().contains("CDR body"));
    }

    #[test]
    fn negative_times_round_trip() {
        for ns in [
            -1_500_000_001i64,
            -1,
            0,
            7,
            1_700_000_000_123_456_789 % (i32::MAX as i64 * 1_000_000_000),
        ] {
            assert_eq!(Time::from_nanos(ns).nanos(), ns);
        }
    }
}
