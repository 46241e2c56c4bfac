//! The C and C++ examples of the compensation library, compiled with the machine's `cc` and
//! `c++` against the static and the shared library, run, and checked independently: the
//! commands they print put the modelled tool on the targets (the model evaluated here), and
//! they are `armcomp compensate`'s commands.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use armcomp_core::Robot;
use armcomp_core::algorithms::evaluate::position_errors;
use armcomp_core::algorithms::simulate::{SimulateParams, simulate};
use armcomp_core::data::measurement::{Sample, parse_poses, write_csv};
use nalgebra::Vector3;

use crate::cli::armcomp;
use crate::common::{Scratch, random_configurations, root};

/// `target/debug`, where this test binary's profile puts the libraries `cargo build` makes.
fn target_profile_dir() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    exe.parent().and_then(Path::parent).unwrap().to_path_buf()
}

/// Builds the library (static and shared) once per test run, so no test links one left over
/// from an earlier build. The whole workspace's test build is asked for, not the library's
/// alone: its features are then those `cargo test` unified, so after `cargo test` nothing is
/// compiled again (`-p armcomp-ffi` alone rebuilt most dependencies, minutes on CI). `--lib`
/// is needed beside `--tests`: `--tests` builds each library as its test harness only, so on a
/// clean clone the shared and static libraries would not exist.
fn built_library() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = target_profile_dir();
        let status = Command::new(env!("CARGO"))
            .args(["build", "--profile", "test", "--workspace", "--lib", "--tests"])
            .env("CARGO_TARGET_DIR", dir.parent().unwrap())
            .current_dir(root())
            .status()
            .expect("cargo runs");
        assert!(
            status.success(),
            "cargo build of the workspace's tests (with armcomp-ffi) failed"
        );
        dir
    })
}

/// Whether `compiler` runs; the examples are skipped, saying so, when it does not.
fn have(compiler: &str) -> bool {
    let found = Command::new(compiler)
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !found {
        eprintln!("skipped: no `{compiler}` on this machine to compile the examples with");
    }
    found
}

/// Compiles `source` (in ffi/examples) with `compiler` and `flags` into `exe`.
fn compile(compiler: &str, source: &str, flags: &[&str], exe: &Path) {
    let include = root().join("ffi/include");
    let out = Command::new(compiler)
        .arg("-Wall")
        .arg("-Wextra")
        .arg("-Werror")
        .arg("-I")
        .arg(&include)
        .arg(root().join("ffi/examples").join(source))
        .args(flags)
        .arg("-o")
        .arg(exe)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{compiler} {source}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// The joint values `exe args` prints, one command per line.
fn run(exe: &Path, args: &[String]) -> Vec<Vec<f64>> {
    let out = Command::new(exe).args(args).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout)
        .unwrap()
        .lines()
        .map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect())
        .collect()
}

/// Where the full model (chain, error models, predicted residual) puts the tool at `q` (m,
/// measurement frame), by the evaluation `armcomp evaluate` makes.
fn modelled_tool(robot: &Robot, q: &[f64]) -> Vector3<f64> {
    let at_origin = Sample {
        q: q.to_vec(),
        point: robot.tool(),
        position: Vector3::zeros(),
        orientation: None,
        payload: None,
        temperature: None,
        torque: None,
        fixed_point: None,
        plane: None,
        sensors: Default::default(),
        position_std: None,
        station: 0,
    };
    -position_errors(robot, &[at_origin])[0]
}

/// `armcomp compensate`'s commands for `targets` (m, measurement frame).
fn cli_commands(s: &Scratch, model: &Path, robot: &Robot, targets: &[Vector3<f64>]) -> Vec<Vec<f64>> {
    let mut csv = String::from("x[m],y[m],z[m]\n");
    for t in targets {
        csv.push_str(&format!("{:?},{:?},{:?}\n", t.x, t.y, t.z));
    }
    let targets_path = s.file("targets.csv", &csv);
    let out = s.0.join("commands.csv");
    let (code, _, err) = armcomp(&[
        "compensate",
        "--model",
        model.to_str().unwrap(),
        "--targets",
        targets_path.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    // The joint columns come first and read back as poses.
    let nq = robot.tree().nq();
    let text = std::fs::read_to_string(&out).unwrap();
    let joints: Vec<String> = text
        .lines()
        .map(|l| l.split(',').take(nq).collect::<Vec<_>>().join(","))
        .collect();
    parse_poses(&joints.join("\n"), &out, &robot.csv_layout()).unwrap()
}

#[test]
fn c_example_commands_put_the_modelled_tool_on_the_targets_as_the_cli_does() {
    if !have("cc") {
        return;
    }
    let s = Scratch::new("ffi-c");
    // The rock-drill deflection model with a ridge predictor learned on its truth.
    let truth = Robot::from_path(&root().join("robots/rock-drill-truth.toml")).unwrap();
    let nominal = std::fs::read_to_string(root().join("robots/rock-drill-deflection.toml")).unwrap();
    let model_in = s.file("model.toml", &format!("{nominal}\n[predictor]\ntype = \"ridge\"\n"));
    let data = simulate(
        &truth,
        &random_configurations(&truth, 80, 21),
        SimulateParams {
            noise_std: 0.0,
            seed: 1,
        },
    )
    .unwrap();
    let data_path = s.file("data.csv", &write_csv(&data, truth.tree(), truth.units()));
    let model_path = s.0.join("learned.toml");
    let (code, _, err) = armcomp(&[
        "learn",
        "--model",
        model_in.to_str().unwrap(),
        "--data",
        data_path.to_str().unwrap(),
        "--out",
        model_path.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let model = Robot::from_path(&model_path).unwrap();
    assert!(model.predictor().is_some());

    let lib = built_library();
    let exe = s.0.join("compensate_points");
    let archive = lib.join("libarmcomp_ffi.a");
    compile(
        "cc",
        "compensate_points.c",
        &["-std=c11", archive.to_str().unwrap(), "-lm", "-lpthread", "-ldl"],
        &exe,
    );
    // Targets the modelled tool reaches: where it is at other configurations.
    let targets: Vec<Vector3<f64>> = random_configurations(&model, 8, 22)
        .iter()
        .map(|q| {
            let mid: Vec<f64> = armcomp_core::algorithms::compensate::mid_range(&model);
            // Halfway to the middle of the ranges, inside the workspace.
            let q: Vec<f64> = q.iter().zip(&mid).map(|(a, m)| 0.5 * (a + m)).collect();
            modelled_tool(&model, &q)
        })
        .collect();
    let mut args = vec![model_path.to_str().unwrap().to_string()];
    for t in &targets {
        args.extend(t.iter().map(|v| format!("{v:?}")));
    }
    let commands = run(&exe, &args);
    assert_eq!(commands.len(), targets.len());
    let cli = cli_commands(&s, &model_path, &model, &targets);
    let tolerance = armcomp_api::ops::compensate::options().tolerance;
    for ((q, q_cli), t) in commands.iter().zip(&cli).zip(&targets) {
        let landed = modelled_tool(&model, q);
        assert!(
            (landed - t).norm() <= tolerance,
            "the modelled tool misses by {:e} m",
            (landed - t).norm()
        );
        let apart = (landed - modelled_tool(&model, q_cli)).norm();
        assert!(apart < 1e-9, "the CLI's command puts the tool {apart:e} m away");
    }

    // The latency program of BENCHMARKS.md builds and runs (two rounds here).
    let latency = s.0.join("latency");
    compile(
        "cc",
        "latency.c",
        &["-std=c11", "-O2", archive.to_str().unwrap(), "-lm", "-lpthread", "-ldl"],
        &latency,
    );
    let centre = targets[0].iter().map(|v| format!("{v:?}"));
    let args: Vec<String> = std::iter::once(model_path.to_str().unwrap().to_string())
        .chain(centre)
        .chain(["2".to_string()])
        .collect();
    let out = Command::new(&latency).args(&args).output().unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    assert!(text.starts_with("calls 54 median_us "), "{text}");
}

#[test]
fn cpp_example_reaches_a_pose_through_the_shared_library() {
    if !have("c++") {
        return;
    }
    let s = Scratch::new("ffi-cpp");
    let model_path = root().join("robots/industrial-6dof.toml");
    let model = Robot::from_path(&model_path).unwrap();
    let lib = built_library();
    let exe = s.0.join("compensate_pose");
    let rpath = format!("-Wl,-rpath,{}", lib.display());
    compile(
        "c++",
        "compensate_pose.cpp",
        &[
            "-std=c++17",
            "-L",
            lib.to_str().unwrap(),
            "-larmcomp_ffi",
            rpath.as_str(),
        ],
        &exe,
    );
    let mid = armcomp_core::algorithms::compensate::mid_range(&model);
    for q in random_configurations(&model, 4, 5) {
        let q: Vec<f64> = q.iter().zip(&mid).map(|(a, m)| 0.5 * (a + m)).collect();
        let pose = model.forward(&q).unwrap().point[model.tool()];
        let r = pose.rotation.quaternion();
        let p = pose.translation.vector;
        let args: Vec<String> = std::iter::once(model_path.to_str().unwrap().to_string())
            .chain([p.x, p.y, p.z, r.w, r.i, r.j, r.k].iter().map(|v| format!("{v:?}")))
            .collect();
        let command = &run(&exe, &args)[0];
        let reached = model.forward(command).unwrap().point[model.tool()];
        let miss = (reached.translation.vector - p).norm();
        assert!(miss < 1e-9, "the tool misses by {miss:e} m");
        assert!(reached.rotation.angle_to(&pose.rotation) < 1e-9);
    }
}
