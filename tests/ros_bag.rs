//! `armcomp import-bag`: ROS 2 bags written here (MCAP through the `mcap` crate's writer,
//! sqlite3 in rosbag2's schema) from a simulated truth with known rests and a known clock
//! offset between the joint states and the tracker; the postures, the offset and, through a
//! calibration of the imported rows, the truth's parameters are recovered; damaged bags are
//! named and nothing is written.

use std::collections::BTreeMap;
use std::ffi::{OsStr, OsString};
use std::path::Path;
use std::process::Command;

use armcomp_bag::msg::{
    self, Header, JointState, Pose, PoseStamped, Quaternion, TfMessage, Time, Transform, TransformStamped, Vector3,
};
use armcomp_bag::{Bag, ImportSettings, import_bag};
use armcomp_core::Robot;
use armcomp_core::algorithms::simulate::{SimulateParams, simulate};
use armcomp_core::calibrate::{CalibrationParams, ParameterSpace, calibrate};
use armcomp_core::data::measurement::read_csv;
use armcomp_core::model::sampling::{Sampler, configurations};
use armcomp_core::support::io::InputLimits;
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};

use crate::common::{Scratch, robot, root};

/// Tracker noise per axis (m) and joint encoder noise (rad).
const TRACKER_NOISE: f64 = 20e-6;
const ENCODER_NOISE: f64 = 1e-6;
const JOINT_HZ: f64 = 125.0;
const TRACKER_HZ: f64 = 60.0;
/// The recording's start on the joints' clock (ns): a day of 2023.
const EPOCH: i64 = 1_700_000_000_000_000_000;

/// A recording of the truth moving between postures and resting at each: the rests' spans
/// (s from the start), the joint states (stamp, configuration) and the tracker's samples
/// (stamp on its own clock, measured position).
struct Recording {
    postures: Vec<Vec<f64>>,
    rests: Vec<(f64, f64)>,
    joints: Vec<(i64, Vec<f64>)>,
    tracker: Vec<(i64, nalgebra::Vector3<f64>)>,
    /// The tracker's true (noise-free) position at each posture.
    at_postures: Vec<nalgebra::Vector3<f64>>,
}

/// Rests of 1.3 to 1.7 s and moves of 0.8 to 1.2 s (smooth, (1 − cos)/2), lengths varied so
/// that no lag but the true one lines the speeds up; the tracker stamps an instant `t` of the
/// joints' clock as `t + offset`.
fn record(truth: &Robot, n: usize, offset: f64, seed: u64) -> Recording {
    let postures = configurations(truth.tree(), Sampler::Sobol, n, seed).unwrap();
    let mut rests = Vec::new();
    let mut t = 0.0;
    for k in 0..n {
        let rest = 1.3 + 0.1 * ((k * 7) % 5) as f64;
        rests.push((t, t + rest));
        t += rest + 0.8 + 0.1 * ((k * 3) % 5) as f64;
    }
    let end = rests.last().unwrap().1;
    let q_at = |t: f64| -> Vec<f64> {
        let k = rests.iter().rposition(|r| r.0 <= t).unwrap_or(0);
        if t <= rests[k].1 || k + 1 == n {
            return postures[k].clone();
        }
        let (a, b) = (rests[k].1, rests[k + 1].0);
        let s = 0.5 * (1.0 - (std::f64::consts::PI * (t - a) / (b - a)).cos());
        postures[k]
            .iter()
            .zip(&postures[k + 1])
            .map(|(x, y)| x + (y - x) * s)
            .collect()
    };
    let mut rng = StdRng::seed_from_u64(seed + 1);
    let encoder = Normal::new(0.0, ENCODER_NOISE).unwrap();
    let joints = (0..=(end * JOINT_HZ) as usize)
        .map(|i| {
            let t = i as f64 / JOINT_HZ;
            let q = q_at(t).into_iter().map(|v| v + encoder.sample(&mut rng)).collect();
            (EPOCH + (t * 1e9).round() as i64, q)
        })
        .collect();
    let times: Vec<f64> = (0..(end * TRACKER_HZ) as usize)
        .map(|j| 0.004 + j as f64 / TRACKER_HZ)
        .collect();
    let poses: Vec<Vec<f64>> = times.iter().map(|&t| q_at(t)).collect();
    let params = SimulateParams {
        noise_std: TRACKER_NOISE,
        seed: seed + 2,
    };
    let measured = simulate(truth, &poses, params).unwrap().samples;
    let tracker = times
        .iter()
        .zip(measured)
        .map(|(t, s)| (EPOCH + ((t + offset) * 1e9).round() as i64, s.position))
        .collect();
    let exact = simulate(
        truth,
        &postures,
        SimulateParams {
            noise_std: 0.0,
            seed: 0,
        },
    )
    .unwrap();
    Recording {
        postures,
        rests,
        joints,
        tracker,
        at_postures: exact.samples.iter().map(|s| s.position).collect(),
    }
}

fn header(stamp: i64, frame: &str) -> Header {
    Header {
        stamp: Time::from_nanos(stamp),
        frame_id: frame.into(),
    }
}

fn point(p: &nalgebra::Vector3<f64>) -> Vector3 {
    Vector3 { x: p.x, y: p.y, z: p.z }
}

const IDENTITY: Quaternion = Quaternion {
    x: 0.0,
    y: 0.0,
    z: 0.0,
    w: 1.0,
};

/// The joint states of a recording, named as `names` (the robot's joints, then a gripper's).
fn joint_state(stamp: i64, q: &[f64], names: &[String]) -> Vec<u8> {
    let mut position = q.to_vec();
    position.push(0.01);
    msg::encode(&JointState {
        header: header(stamp, ""),
        name: names.to_vec(),
        position,
        velocity: vec![],
        effort: vec![],
    })
}

fn joint_names(truth: &Robot) -> Vec<String> {
    let mut names = truth.tree().coordinate_names().to_vec();
    names.push("gripper_finger".into());
    names
}

/// A message of a bag: (receive time ns, topic, bytes), the receive time a few ms after the
/// stamp on the joints' clock.
type Written = (i64, &'static str, Vec<u8>);

/// The recording as `/tf`: each tracker sample in a TFMessage beside an unrelated transform,
/// every tenth carrying the unrelated one alone; one message damaged; a log topic beside.
/// Returns the messages and how many carry no tracker transform.
fn tf_messages(rec: &Recording, truth: &Robot, offset: f64) -> (Vec<Written>, usize) {
    let names = joint_names(truth);
    let mut out: Vec<Written> = rec
        .joints
        .iter()
        .map(|(t, q)| (t + 2_000_000, "/joint_states", joint_state(*t, q, &names)))
        .collect();
    let mut foreign = 0;
    for (k, (t, p)) in rec.tracker.iter().enumerate() {
        let other = TransformStamped {
            header: header(*t, "world"),
            child_frame_id: "base_link".into(),
            transform: Transform {
                translation: Vector3 { x: 1.0, y: 2.0, z: 3.0 },
                rotation: IDENTITY,
            },
        };
        let mut transforms = vec![other];
        if k % 10 == 3 {
            foreign += 1;
        } else {
            transforms.push(TransformStamped {
                header: header(*t, "tracker"),
                child_frame_id: "tool_marker".into(),
                transform: Transform {
                    translation: point(p),
                    rotation: IDENTITY,
                },
            });
        }
        let received = t - (offset * 1e9) as i64 + 5_000_000;
        out.push((received, "/tf", msg::encode(&TfMessage { transforms })));
    }
    out.push((EPOCH + 1_000_000_000, "/tf", vec![0, 1, 0, 0, 7]));
    for k in 0..5 {
        out.push((EPOCH + k * 300_000_000, "/rosout", vec![0, 1, 0, 0, 1, 2, 3, 4]));
    }
    out.sort_by_key(|m| m.0);
    (out, foreign)
}

fn type_of(topic: &str) -> &'static str {
    match topic {
        "/joint_states" => msg::type_name::JOINT_STATE,
        "/tf" => msg::type_name::TF_MESSAGE,
        "/tracker/pose" => msg::type_name::POSE_STAMPED,
        _ => "rcl_interfaces/msg/Log",
    }
}

fn write_mcap(path: &Path, messages: &[Written]) {
    let file = std::io::BufWriter::new(std::fs::File::create(path).unwrap());
    let mut w = mcap::Writer::new(file).unwrap();
    let mut channels: BTreeMap<&str, u16> = BTreeMap::new();
    for (k, (t, topic, data)) in messages.iter().enumerate() {
        let channel = *channels.entry(*topic).or_insert_with(|| {
            let schema = w.add_schema(type_of(topic), "ros2msg", b"").unwrap();
            w.add_channel(schema, topic, "cdr", &BTreeMap::new()).unwrap()
        });
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: k as u32,
            log_time: *t as u64,
            publish_time: *t as u64,
        };
        w.write_to_known_channel(&header, data).unwrap();
    }
    w.finish().unwrap();
}

/// A sqlite3 bag in rosbag2's schema (tables `topics` and `messages`).
fn write_sqlite(path: &Path, messages: &[Written]) {
    let conn = rusqlite::Connection::open(path).unwrap();
    conn.execute_batch(
        "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, \
         serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
         CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, timestamp INTEGER NOT NULL, \
         data BLOB NOT NULL);
         CREATE INDEX timestamp_idx ON messages (timestamp ASC);",
    )
    .unwrap();
    let mut ids: BTreeMap<&str, i64> = BTreeMap::new();
    let tx = conn.unchecked_transaction().unwrap();
    for (t, topic, data) in messages {
        let next = ids.len() as i64 + 1;
        let id = *ids.entry(*topic).or_insert_with(|| {
            tx.execute(
                "INSERT INTO topics VALUES (?1, ?2, ?3, 'cdr', '')",
                rusqlite::params![next, topic, type_of(topic)],
            )
            .unwrap();
            next
        });
        tx.execute(
            "INSERT INTO messages (topic_id, timestamp, data) VALUES (?1, ?2, ?3)",
            rusqlite::params![id, t, data],
        )
        .unwrap();
    }
    tx.commit().unwrap();
}

/// The recording as PoseStamped messages in the tracker's frame.
fn pose_messages(rec: &Recording, truth: &Robot, offset: f64) -> Vec<Written> {
    let names = joint_names(truth);
    let mut out: Vec<Written> = rec
        .joints
        .iter()
        .map(|(t, q)| (t + 2_000_000, "/joint_states", joint_state(*t, q, &names)))
        .collect();
    out.extend(rec.tracker.iter().map(|(t, p)| {
        let pose = PoseStamped {
            header: header(*t, "tracker"),
            pose: Pose {
                position: point(p),
                orientation: IDENTITY,
            },
        };
        (
            t - (offset * 1e9) as i64 + 5_000_000,
            "/tracker/pose",
            msg::encode(&pose),
        )
    }));
    out.sort_by_key(|m| m.0);
    out
}

fn import_cli(args: &[OsString]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_armcomp"))
        .arg("import-bag")
        .args(args)
        .output()
        .unwrap()
}

/// Command-line arguments of strings and paths alike.
fn args(items: &[&dyn AsRef<OsStr>]) -> Vec<OsString> {
    items
        .iter()
        .map(|s| AsRef::<OsStr>::as_ref(*s).to_os_string())
        .collect()
}

/// A truth: the nominal robot with the named parameters moved (SI).
fn truth_of(nominal: &Robot, changes: &[(&str, f64)]) -> (Robot, Vec<f64>) {
    let space = ParameterSpace::new(nominal);
    let mut theta = space.initial();
    for (name, delta) in changes {
        theta[space.index(name).unwrap()] += delta;
    }
    (space.apply(nominal, &theta).unwrap(), theta)
}

#[test]
fn an_mcap_bag_of_tf_gives_the_postures_the_offset_and_through_calibration_the_truth() {
    let dir = Scratch::new("ros-bag-mcap");
    let nominal_path = root().join("robots/industrial-6dof.toml");
    let nominal = robot("industrial-6dof.toml");
    let deg = 1f64.to_radians();
    let (truth, theta) = truth_of(
        &nominal,
        &[
            ("j2.alpha", 0.2 * deg),
            ("j3.a", 1e-3),
            ("j4.d", -1.5e-3),
            ("j5.theta", 0.3 * deg),
            ("base.x", 0.8),
            ("base.z", 0.1),
        ],
    );
    let offset = 0.3172;
    let rec = record(&truth, 50, offset, 5);
    let (messages, foreign) = tf_messages(&rec, &truth, offset);
    let bag = dir.0.join("session.mcap");
    write_mcap(&bag, &messages);
    let out = dir.0.join("rows.csv");
    let base = args(&[
        &"--bag",
        &bag,
        &"--robot",
        &nominal_path,
        &"--measurement-topic",
        &"/tf",
        &"--parent-frame",
        &"tracker",
        &"--child-frame",
        &"tool_marker",
        &"--out",
        &out,
    ]);
    // The gripper's joint is not the robot's: refused, named.
    let refused = import_cli(&base);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(
        !refused.status.success() && stderr.contains("`gripper_finger`") && stderr.contains("--ignore-joint"),
        "{stderr}"
    );
    assert!(!out.exists());
    let mut with_gripper = base.clone();
    with_gripper.extend(args(&[&"--ignore-joint", &"gripper_finger", &"--json"]));
    let run = import_cli(&with_gripper);
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let report: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap();

    // Every rest is a posture, at its true start (joint clock, from the first joint stamp).
    let postures = report["postures"].as_array().unwrap();
    assert_eq!(postures.len(), rec.rests.len());
    for (p, (start, end)) in postures.iter().zip(&rec.rests) {
        assert!(
            (p["start"].as_f64().unwrap() - start).abs() < 0.02,
            "{p} vs rest {start}..{end}"
        );
        assert!((p["duration"].as_f64().unwrap() - (end - start)).abs() < 0.03, "{p}");
    }
    // The offset within a millisecond, and within four of its stated uncertainties (a floor of
    // a tenth of a millisecond for the parabola's own bias).
    let est = report["clock_offset"]["seconds"].as_f64().unwrap();
    let std = report["clock_offset"]["std"].as_f64().unwrap();
    assert!(
        (est - offset).abs() < 1e-3 && (est - offset).abs() < 4.0 * std + 1e-4,
        "offset {est} ± {std}, truth {offset}"
    );
    // Dropped samples, counted by reason.
    let dropped = &report["dropped"];
    assert_eq!(dropped["unknown_frame"].as_u64().unwrap() as usize, foreign);
    assert_eq!(dropped["bad_message"].as_u64().unwrap(), 1);
    assert!(dropped["joints_moving"].as_u64().unwrap() > 0 && dropped["outside_rest"].as_u64().unwrap() > 0);
    assert_eq!(report["other_messages"].as_u64().unwrap(), 5);
    // Repeatability: the tracker's noise, √3 σ as a 3-D spread (√((n−1)/n) of it).
    let mut reps: Vec<f64> = postures.iter().map(|p| p["repeatability"].as_f64().unwrap()).collect();
    reps.sort_by(f64::total_cmp);
    let median = reps[reps.len() / 2];
    assert!(
        (median / (3f64.sqrt() * TRACKER_NOISE) - 1.0).abs() < 0.15,
        "median repeatability {median}"
    );

    // The rows: each posture's joints and the truth's point there, within the averaged noise.
    let set = read_csv(&out, &nominal.csv_layout(), InputLimits::default()).unwrap();
    assert_eq!(set.samples.len(), rec.postures.len());
    for ((s, q), p) in set.samples.iter().zip(&rec.postures).zip(&rec.at_postures) {
        let dq = s.q.iter().zip(q).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
        assert!(dq < 1e-6, "joints off by {dq} rad");
        assert!(
            (s.position - p).norm() < 15e-6,
            "position off by {} m",
            (s.position - p).norm()
        );
    }
    // Calibrating the imported rows recovers the truth.
    let params = CalibrationParams {
        measurement_std: TRACKER_NOISE / 8.0,
        ..Default::default()
    };
    let cal = calibrate(&nominal, &set.samples, &params, &mut |_| {}).unwrap();
    assert!(cal.report.converged, "{}", cal.report.stop_reason);
    let space = ParameterSpace::new(&nominal);
    for name in ["j2.alpha", "j3.a", "j4.d", "j5.theta", "base.x", "base.z"] {
        let p = cal.report.params.iter().find(|p| p.name == name).unwrap();
        let t = theta[space.index(name).unwrap()];
        assert!(
            (p.value - t).abs() < 4.0 * p.std + 1e-9,
            "{name}: identified {} ± {}, truth {t}",
            p.value,
            p.std
        );
    }
    // Some of these are loosely determined by fifty postures (their std is large), so the
    // calibrated model is also checked where it matters: it puts the point where the truth
    // does, at poses not measured.
    let fresh = configurations(truth.tree(), Sampler::Sobol, 40, 77).unwrap();
    let exact = |r: &Robot| {
        simulate(
            r,
            &fresh,
            SimulateParams {
                noise_std: 0.0,
                seed: 0,
            },
        )
        .unwrap()
        .samples
    };
    let worst = exact(&truth)
        .iter()
        .zip(exact(&cal.robot))
        .map(|(a, b)| (a.position - b.position).norm())
        .fold(0.0, f64::max);
    assert!(
        worst < 0.1e-3,
        "calibrated model off the truth by up to {worst} m at new poses"
    );
}

#[test]
fn a_sqlite_bag_folder_with_a_3_9_s_offset_is_lined_up_and_one_beyond_the_bound_refused() {
    let dir = Scratch::new("ros-bag-sqlite");
    let nominal = robot("industrial-6dof.toml");
    let offset = -3.9;
    let rec = record(&nominal, 14, offset, 7);
    let folder = dir.0.join("session");
    std::fs::create_dir(&folder).unwrap();
    std::fs::write(folder.join("metadata.yaml"), "rosbag2_bagfile_information: {}\n").unwrap();
    write_sqlite(&folder.join("session_0.db3"), &pose_messages(&rec, &nominal, offset));
    let mut settings = ImportSettings::new("/joint_states", "/tracker/pose");
    settings.ignored_joints = vec!["gripper_finger".into()];
    settings.parent_frame = Some("tracker".into());
    let bag = Bag::open(&folder).unwrap();
    let mut passes = Vec::new();
    let import = import_bag(&bag, &nominal, &settings, &mut |p| passes.push(p)).unwrap();
    let o = import.report.clock_offset;
    assert!((o.seconds - offset).abs() < 1e-3, "{o:?}");
    assert_eq!(import.set.samples.len(), rec.rests.len());
    for (s, p) in import.set.samples.iter().zip(&rec.at_postures) {
        assert!((s.position - p).norm() < 15e-6);
    }
    // Progress: both passes, each reaching its total.
    for pass in [1, 2] {
        let last = passes.iter().rev().find(|p| p.pass == pass).unwrap();
        assert_eq!(last.position.done, last.position.total);
    }
    // Another frame: every tracker message dropped as such.
    settings.parent_frame = Some("map".into());
    let err = import_bag(&bag, &nominal, &settings, &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(err.contains("the tracked point does not move"), "{err}");
    // Beyond the bound: refused with the estimate, nothing written.
    let out = dir.0.join("rows.csv");
    let run = import_cli(&args(&[
        &"--bag",
        &folder,
        &"--robot",
        &root().join("robots/industrial-6dof.toml"),
        &"--measurement-topic",
        &"/tracker/pose",
        &"--ignore-joint",
        &"gripper_finger",
        &"--max-clock-offset-s",
        &"2",
        &"--out",
        &out,
    ]));
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(
        !run.status.success() && stderr.contains("-3.9") && stderr.contains("--max-clock-offset-s"),
        "{stderr}"
    );
    assert!(!out.exists());
}

/// Runs the import of `bag` into a fresh output and returns its error text, checking that
/// nothing was written.
fn refused(bag: &Path, topic: &str, out: &Path) -> String {
    let run = import_cli(&args(&[
        &"--bag",
        &bag,
        &"--robot",
        &root().join("robots/industrial-6dof.toml"),
        &"--measurement-topic",
        &topic,
        &"--ignore-joint",
        &"gripper_finger",
        &"--out",
        &out,
    ]));
    assert!(!run.status.success());
    assert!(!out.exists(), "an output was written for {}", bag.display());
    String::from_utf8_lossy(&run.stderr).into_owned()
}

#[test]
fn corrupt_and_truncated_bags_are_named_and_nothing_is_written() {
    let dir = Scratch::new("ros-bag-damaged");
    let nominal = robot("industrial-6dof.toml");
    let rec = record(&nominal, 6, 0.05, 9);
    let messages = pose_messages(&rec, &nominal, 0.05);
    let out = dir.0.join("rows.csv");
    let mcap_path = dir.0.join("good.mcap");
    write_mcap(&mcap_path, &messages);
    let bytes = std::fs::read(&mcap_path).unwrap();
    let db_path = dir.0.join("good.db3");
    write_sqlite(&db_path, &messages);
    let db = std::fs::read(&db_path).unwrap();

    let truncated = dir.0.join("truncated.mcap");
    std::fs::write(&truncated, &bytes[..bytes.len() * 3 / 5]).unwrap();
    let err = refused(&truncated, "/tracker/pose", &out);
    assert!(err.contains("truncated.mcap") && err.contains("is truncated"), "{err}");

    let mut damaged = bytes.clone();
    let mid = damaged.len() / 2;
    damaged[mid..mid + 64].iter_mut().for_each(|b| *b ^= 0x5a);
    let corrupt = dir.0.join("corrupt.mcap");
    std::fs::write(&corrupt, &damaged).unwrap();
    let err = refused(&corrupt, "/tracker/pose", &out);
    assert!(err.contains("corrupt.mcap") && err.contains("is corrupt"), "{err}");

    let truncated_db = dir.0.join("truncated.db3");
    std::fs::write(&truncated_db, &db[..db.len() / 2]).unwrap();
    let err = refused(&truncated_db, "/tracker/pose", &out);
    assert!(
        err.contains("truncated.db3") && err.contains("corrupt or truncated"),
        "{err}"
    );

    let mut damaged_db = db.clone();
    let page = 4096 * (damaged_db.len() / 4096 / 2);
    damaged_db[page..page + 4096].iter_mut().for_each(|b| *b = 0xff);
    let corrupt_db = dir.0.join("corrupt.db3");
    std::fs::write(&corrupt_db, &damaged_db).unwrap();
    let err = refused(&corrupt_db, "/tracker/pose", &out);
    assert!(
        err.contains("corrupt.db3") && err.contains("corrupt or truncated"),
        "{err}"
    );

    let not_a_bag = dir.file("notes.mcap", "joint states, by hand\n");
    let err = refused(&not_a_bag, "/tracker/pose", &out);
    assert!(
        err.contains("notes.mcap") && err.contains("neither an MCAP file nor a sqlite3"),
        "{err}"
    );

    // A topic the bag lacks: named with the bag's topics.
    let err = refused(&mcap_path, "/vicon/marker", &out);
    assert!(
        err.contains("/vicon/marker") && err.contains("/tracker/pose (geometry_msgs/msg/PoseStamped)"),
        "{err}"
    );
}
