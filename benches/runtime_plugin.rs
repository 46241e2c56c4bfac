//! A run-time error model from many threads: the example cable-sag library loaded through the C
//! ABI against the same model linked in, in the two places calibration evaluates it in parallel
//! (rayon over samples): the deflected forward kinematics of a batch of configurations, and the
//! identification Jacobian whose geometry columns difference the full deformed model.

use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

use armcomp_core::calibrate::samples_jacobian;
use armcomp_core::data::measurement::Sample;
use armcomp_core::model::sampling::{Sampler, configurations};
use armcomp_core::robot::robot_file::{Format, SourceFile};
use armcomp_core::support::io::InputLimits;
use armcomp_core::{Robot, RobotFile};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::Vector3;
use rayon::prelude::*;

/// Configurations per batch.
const N: usize = 2000;

/// Builds the example plugin into this bench's target folder and returns the library's path.
fn built_library() -> PathBuf {
    // The bench binary is `target/release/deps/runtime_plugin-<hash>`.
    let exe = std::env::current_exe().expect("bench path");
    let profile_dir = exe.parent().and_then(Path::parent).expect("target/<profile>");
    let status = Command::new(env!("CARGO"))
        .args(["build", "--release", "-p", "cable-sag", "--lib"])
        .env("CARGO_TARGET_DIR", profile_dir.parent().expect("target folder"))
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .status()
        .expect("cargo runs");
    assert!(status.success(), "building the cable-sag plugin failed");
    let name = format!(
        "{}cable_sag{}",
        std::env::consts::DLL_PREFIX,
        std::env::consts::DLL_SUFFIX
    );
    profile_dir.join(name)
}

/// The example robot with the hose loaded from the library (`runtime`) and linked in.
fn robots(folder: &Path) -> (Robot, Robot) {
    // Registers the built-in kinematic conventions.
    armcomp_api::registry::plugins();
    let text = include_str!("../plugins/examples/cable_sag/robot.toml");
    let library = built_library();
    std::fs::copy(&library, folder.join(library.file_name().expect("file name"))).expect("library copied");
    let path = folder.join("robot.toml");
    std::fs::write(&path, text).expect("robot file written");
    armcomp_sdk::set_policy(armcomp_sdk::PluginPolicy {
        allow: true,
        trusted_dirs: Vec::new(),
    });
    let runtime = Robot::from_path(&path).expect("runtime robot builds");
    let (head, _) = text.split_once("[[error_models]]").expect("the file has the plugin");
    let src = SourceFile {
        path: "linked.toml".into(),
        text: head.into(),
        format: Format::Toml,
    };
    let mut file: RobotFile = src.parse().expect("robot parses");
    file.error_models.push(Box::new(cable_sag::CableSagSpec {
        link: "boom".into(),
        length: Some(1500.0),
        mass_per_length: 2.5,
    }));
    let linked = Robot::from_source(file, &src, InputLimits::default()).expect("linked robot builds");
    (runtime, linked)
}

fn bench(c: &mut Criterion) {
    let folder = tempfile::tempdir().expect("scratch folder");
    let (runtime, linked) = robots(folder.path());
    let poses = configurations(linked.tree(), Sampler::Sobol, N, 1).expect("poses");
    let samples: Vec<Sample> = poses
        .iter()
        .map(|q| Sample {
            q: q.clone(),
            point: linked.tool(),
            position: Vector3::zeros(),
            orientation: None,
            payload: None,
            temperature: None,
            torque: None,
            fixed_point: None,
            plane: None,
            sensors: Default::default(),
            station: 0,
            position_std: None,
        })
        .collect();
    let identify = vec!["all".to_string()];
    eprintln!(
        "{} rayon threads; {} identified parameters",
        rayon::current_num_threads(),
        samples_jacobian(&linked, &samples, &identify)
            .expect("jacobian")
            .1
            .len()
    );
    let mut group = c.benchmark_group("runtime_plugin");
    group.sample_size(20).measurement_time(Duration::from_secs(5));
    group.throughput(Throughput::Elements(N as u64));
    for (name, robot) in [("linked", &linked), ("runtime", &runtime)] {
        group.bench_function(format!("parallel_fk/{name}"), |b| {
            b.iter(|| {
                poses.par_iter().for_each_init(
                    || robot.workspace(),
                    |ws, q| {
                        robot.forward_into(black_box(q), None, ws);
                        black_box(ws.frames.point[0].translation.vector);
                    },
                )
            })
        });
        group.bench_function(format!("jacobian/{name}"), |b| {
            b.iter(|| samples_jacobian(robot, black_box(&samples), &identify).expect("jacobian"))
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
