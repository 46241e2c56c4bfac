//! Run-time plugins: the example cable-sag library loaded through the C ABI against the same
//! model linked in, and every way a plugin library or its config can be wrong.

use std::path::{Path, PathBuf};
use std::process::Command;
use std::sync::OnceLock;

use armcomp_core::algorithms::simulate::{SimulateParams, simulate};
use armcomp_core::analysis::diagnose::{DiagnoseParams, diagnose};
use armcomp_core::calibrate::{CalibrationParams, calibrate};
use armcomp_core::kinematics::subtree_loads::SubtreeLoads;
use armcomp_core::model::sampling::{Sampler, configurations};
use armcomp_core::robot::robot_file::SourceFile;
use armcomp_core::support::io::InputLimits;
use armcomp_core::{
    Error, FittedPredictor, Perturbation, PredictorSpec, Robot, RobotFile, StaticState, TrainingSet, TreeWorkspace,
};
use armcomp_learn::gp::GpSpec;
use nalgebra::Vector3;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use crate::common::{Scratch, random_configurations, root};

/// `target/debug`, where this test binary's profile puts libraries built with `cargo build`.
fn target_profile_dir() -> PathBuf {
    // The test binary is `target/debug/deps/integration-<hash>`.
    let exe = std::env::current_exe().unwrap();
    exe.parent().and_then(Path::parent).unwrap().to_path_buf()
}

/// Builds the example plugin and the loader's faulty test plugins once per test run, so no test
/// relies on a library left over from an earlier build.
fn built_plugins() -> &'static Path {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = target_profile_dir();
        let target = dir.parent().unwrap();
        for args in [
            &["build", "--profile", "test", "-p", "cable-sag", "--lib"][..],
            &["build", "--profile", "test", "-p", "armcomp-sdk", "--examples"][..],
        ] {
            let status = Command::new(env!("CARGO"))
                .args(args)
                .env("CARGO_TARGET_DIR", target)
                .current_dir(root())
                .status()
                .expect("cargo runs");
            assert!(status.success(), "cargo {args:?} failed");
        }
        dir
    })
}

/// Lets this test process load plugin libraries: robot files their own folder's, and, as a
/// user's `plugin_dirs` would, anything under the scratch folders (model files written
/// elsewhere name their library by its absolute path). The refusals are checked through the
/// command line, in processes of their own.
fn allow_plugins() {
    armcomp_sdk::set_policy(armcomp_sdk::PluginPolicy {
        allow: true,
        trusted_dirs: vec![std::env::temp_dir()],
    });
}

fn library_file(name: &str) -> String {
    format!("{}{name}{}", std::env::consts::DLL_PREFIX, std::env::consts::DLL_SUFFIX)
}

/// A scratch folder holding the example robot file and the freshly built cable-sag library.
fn example_folder(tag: &str) -> (Scratch, PathBuf) {
    allow_plugins();
    let scratch = Scratch::new(tag);
    let lib = library_file("cable_sag");
    std::fs::copy(built_plugins().join(&lib), scratch.0.join(&lib)).unwrap();
    let robot = std::fs::read_to_string(root().join("plugins/examples/cable_sag/robot.toml")).unwrap();
    let path = scratch.file("robot.toml", &robot);
    (scratch, path)
}

/// The example robot with the same model linked in (the rlib's spec type, no library), with the
/// hose's mass per length `mass_per_length` (kg/m; the file says 2.5).
fn linked_robot(mass_per_length: f64) -> Robot {
    let text = std::fs::read_to_string(root().join("plugins/examples/cable_sag/robot.toml")).unwrap();
    let (head, _) = text.split_once("[[error_models]]").unwrap();
    let src = SourceFile {
        path: "linked.toml".into(),
        text: head.into(),
        format: armcomp_core::robot::robot_file::Format::Toml,
    };
    let mut file: RobotFile = src.parse().unwrap();
    file.error_models.push(Box::new(cable_sag::CableSagSpec {
        link: "boom".into(),
        length: Some(1500.0),
        mass_per_length,
    }));
    Robot::from_source(file, &src, InputLimits::default()).unwrap()
}

fn robot_from_text(text: &str, path: &Path) -> armcomp_core::Result<Robot> {
    let src = SourceFile {
        path: path.to_path_buf(),
        text: text.into(),
        format: armcomp_core::robot::robot_file::Format::Toml,
    };
    let file: RobotFile = src.parse()?;
    Robot::from_source(file, &src, InputLimits::default())
}

#[test]
fn runtime_plugin_matches_the_linked_model_bit_for_bit() {
    let (_scratch, path) = example_folder("rt-exact");
    let runtime = Robot::from_path(&path).unwrap();
    let linked = linked_robot(2.5);
    assert_eq!(runtime.error_models()[0].params(), linked.error_models()[0].params());
    let (mut ws_rt, mut ws_ln) = (runtime.workspace(), linked.workspace());
    for q in random_configurations(&linked, 50, 7) {
        for temperature in [None, Some(35.0)] {
            runtime.forward_into(&q, temperature, &mut ws_rt);
            linked.forward_into(&q, temperature, &mut ws_ln);
            assert!(!ws_ln.perturbation.is_zero(), "the hose bends the boom");
            assert_eq!(ws_rt.perturbation, ws_ln.perturbation, "q = {q:?}");
            assert_eq!(ws_rt.frames.point, ws_ln.frames.point, "q = {q:?}");
            assert_eq!(ws_rt.frames.body, ws_ln.frames.body, "q = {q:?}");
        }
    }
}

/// Calibration evaluates a run-time model for many samples at once (rayon over samples), each
/// thread with its own parameter values; the plugin handle is shared and no lock orders the
/// calls. Every result must be the one the model gives alone, bit for bit, and the one the same
/// model gives linked in.
#[test]
fn runtime_plugin_evaluated_from_many_threads_at_once_matches_one_thread_bit_for_bit() {
    let (_scratch, path) = example_folder("rt-threads");
    let runtime = Robot::from_path(&path).unwrap();
    let linked = linked_robot(2.5);
    let configurations = random_configurations(&linked, 400, 13);
    // Sample i: its own hose mass per length (kg/m) and, every other one, a temperature.
    let evaluate = |robot: &Robot, i: usize, q: &[f64]| -> Perturbation {
        let tree = robot.tree();
        let mut frames = TreeWorkspace::new(tree);
        tree.forward_into(q, &mut frames);
        let loads = SubtreeLoads::of(tree, &frames, robot.mass());
        let state = StaticState {
            q,
            tree,
            frames: &frames,
            mass: robot.mass(),
            loads: &loads,
            gravity: robot.gravity(),
            temperature: (i % 2 == 1).then_some(25.0),
            sensors: Default::default(),
        };
        let mut out = Perturbation::zeros(tree);
        robot.error_models()[0].perturb(&state, &[0.5 + 0.01 * i as f64], &mut out);
        out
    };
    let one_thread: Vec<Perturbation> = configurations
        .iter()
        .enumerate()
        .map(|(i, q)| evaluate(&runtime, i, q))
        .collect();
    for (i, q) in configurations.iter().enumerate() {
        assert_eq!(one_thread[i], evaluate(&linked, i, q), "sample {i}");
        assert!(!one_thread[i].is_zero(), "sample {i}: the hose bends the boom");
    }
    // More threads than cores, so calls interleave on every core; several rounds, since a race
    // need not show in one.
    let pool = rayon::ThreadPoolBuilder::new().num_threads(6).build().unwrap();
    for round in 0..5 {
        let many_threads: Vec<Perturbation> = pool.install(|| {
            configurations
                .par_iter()
                .enumerate()
                .map(|(i, q)| evaluate(&runtime, i, q))
                .collect()
        });
        for (i, (many, one)) in many_threads.iter().zip(&one_thread).enumerate() {
            assert_eq!(many, one, "round {round}, sample {i}");
        }
    }
}

/// A run-time predictor (the Gaussian process of armcomp-learn, exported by the SDK's
/// `gp_plugin` example) fitted and queried through the ABI gives what the same predictor linked
/// in gives, bit for bit: one thread or six at once on one handle, mean and predictive standard
/// deviation, and after a round trip through a model file.
#[test]
fn runtime_predictor_matches_the_linked_one_from_many_threads_bit_for_bit() {
    allow_plugins();
    let scratch = Scratch::new("rt-predictor");
    let lib = library_file("gp_plugin");
    std::fs::copy(built_plugins().join("examples").join(&lib), scratch.0.join(&lib)).unwrap();
    // Two joint-like inputs, two outputs: smooth functions of them, 80 seeded rows.
    let mut rng = StdRng::seed_from_u64(4);
    let rows = |rng: &mut StdRng, n: usize| -> Vec<f64> { (0..2 * n).map(|_| rng.random_range(-1.5..1.5)).collect() };
    let inputs = rows(&mut rng, 80);
    let targets: Vec<f64> = inputs
        .chunks_exact(2)
        .flat_map(|x| [1e-3 * (x[0].sin() + 0.5 * x[1]), 2e-3 * (x[0] * x[1]).cos()])
        .collect();
    let data = TrainingSet {
        inputs: &inputs,
        targets: &targets,
        n_inputs: 2,
        n_outputs: 2,
        input_ranges: &[],
    };
    let linked = GpSpec {
        restarts: 0,
        max_iterations: 20,
        ..GpSpec::default()
    }
    .fit(&data)
    .unwrap();
    let runtime = armcomp_sdk::PluginPredictorSpec {
        library: scratch.0.join(&lib).to_string_lossy().into_owned(),
        model: "gp".into(),
        config: serde_json::json!({ "restarts": 0, "max_iterations": 20 }),
        folder: None,
    }
    .fit(&data)
    .unwrap();
    assert_eq!((runtime.n_inputs(), runtime.n_outputs()), (2, 2));
    let queries = rows(&mut rng, 300);
    // Mean and standard deviation of each query, four numbers.
    let predict = |p: &dyn FittedPredictor, x: &[f64]| -> [f64; 4] {
        let (mut mean, mut std, mut scratch) = ([0.0; 2], [0.0; 2], Vec::new());
        p.predict_into(x, &mut mean, &mut scratch);
        assert!(
            p.predict_std_into(x, &mut std, &mut scratch),
            "a GP has a predictive std"
        );
        [mean[0], mean[1], std[0], std[1]]
    };
    let reference: Vec<[f64; 4]> = queries.chunks_exact(2).map(|x| predict(linked.as_ref(), x)).collect();
    let one_thread: Vec<[f64; 4]> = queries.chunks_exact(2).map(|x| predict(runtime.as_ref(), x)).collect();
    assert_eq!(one_thread, reference);
    assert!(reference.iter().all(|r| r[2] > 0.0 && r[3] > 0.0));
    let pool = rayon::ThreadPoolBuilder::new().num_threads(6).build().unwrap();
    for round in 0..5 {
        let many: Vec<[f64; 4]> = pool.install(|| {
            queries
                .par_chunks_exact(2)
                .map(|x| predict(runtime.as_ref(), x))
                .collect()
        });
        assert_eq!(many, reference, "round {round}");
    }
    let stored = serde_json::to_string(&runtime).unwrap();
    let reloaded: Box<dyn FittedPredictor> = serde_json::from_str(&stored).unwrap();
    let again: Vec<[f64; 4]> = queries.chunks_exact(2).map(|x| predict(reloaded.as_ref(), x)).collect();
    assert_eq!(again, reference);
}

/// A predictor library beside its robot file is found there from any working folder, the way
/// an error model's is: `validate` loads and names it, `learn` fits through it, and the model
/// file written beside it loads it again.
#[test]
fn a_predictor_library_beside_the_robot_file_is_found_from_another_folder() {
    let scratch = Scratch::new("rt-predictor-folder");
    let sub = scratch.0.join("sub");
    std::fs::create_dir_all(&sub).unwrap();
    let lib = library_file("gp_plugin");
    std::fs::copy(built_plugins().join("examples").join(&lib), sub.join(&lib)).unwrap();
    let bad = root().join("tests/bad_inputs");
    let robot = std::fs::read_to_string(bad.join("arm.toml")).unwrap()
        + "\n[predictor]\ntype = \"plugin\"\nlibrary = \"gp_plugin\"\nmodel = \"gp\"\nconfig = { restarts = 0, max_iterations = 20 }\n";
    std::fs::write(sub.join("robot.toml"), robot).unwrap();
    std::fs::copy(bad.join("arm.csv"), sub.join("arm.csv")).unwrap();
    let run_here = |args: &[&str]| {
        let out = Command::new(env!("CARGO_BIN_EXE_armcomp"))
            .args(args)
            .current_dir(&scratch.0)
            .env_remove("ARMCOMP_CONFIG")
            .env("XDG_CONFIG_HOME", scratch.0.join("no-config"))
            .output()
            .unwrap();
        let text = format!(
            "{}{}",
            String::from_utf8_lossy(&out.stdout),
            String::from_utf8_lossy(&out.stderr)
        );
        (out.status.code(), text)
    };
    let (code, text) = run_here(&["validate", "--allow-plugins", "sub/robot.toml"]);
    assert_eq!(code, Some(0), "{text}");
    assert!(text.contains("sub/robot.toml: ok"), "{text}");
    let named = format!(
        "sub/robot.toml: loaded and checked the plugin library {}",
        sub.canonicalize().unwrap().join(&lib).display()
    );
    assert!(text.contains(&named), "expected `{named}` in: {text}");
    let learn = [
        "learn",
        "--allow-plugins",
        "--model",
        "sub/robot.toml",
        "--data",
        "sub/arm.csv",
        "--out",
        "sub/model.toml",
    ];
    let (code, text) = run_here(&learn);
    assert_eq!(code, Some(0), "{text}");
    let (code, text) = run_here(&[
        "evaluate",
        "--allow-plugins",
        "--model",
        "sub/model.toml",
        "--data",
        "sub/arm.csv",
    ]);
    assert_eq!(code, Some(0), "{text}");
    // Without permission, the fitted predictor's library is not loaded.
    let (code, text) = run_here(&["evaluate", "--model", "sub/model.toml", "--data", "sub/arm.csv"]);
    assert_eq!(code, Some(1), "{text}");
    assert!(text.contains("run-time plugins are not allowed"), "{text}");
}

#[test]
fn runtime_plugin_bends_the_boom_as_the_cantilever_formula_says() {
    let (_scratch, path) = example_folder("rt-formula");
    let robot = Robot::from_path(&path).unwrap();
    // Boom horizontal, head straight: the hose load w = μ g is perpendicular to the boom.
    let q = [0.0, 0.0, 0.0];
    let rigid = robot.tree().point_positions(&q)[robot.tool()];
    let bent = robot.forward(&q).unwrap().point_position(robot.tool());
    let (w, l, e): (f64, f64, f64) = (2.5 * 9.81, 1.5, 70e9);
    let i = (0.06f64.powi(4) - 0.054f64.powi(4)) / 12.0;
    let tip = w * l.powi(4) / (8.0 * e * i);
    let slope = w * l.powi(3) / (6.0 * e * i);
    // The seat moves by the SE(3) exponential of its twist (translation `-tip` along the boom
    // frame's y, which is world z here; rotation `-slope` about its z), and the rigid head
    // carries the tool 0.3 m along the turned axis.
    let (a, phi) = (-tip, -slope);
    let seat = Vector3::new(-(1.0 - phi.cos()) / phi * a, phi.sin() / phi * a, 0.0);
    let expected = Vector3::new(seat.x + 0.3 * (phi.cos() - 1.0), 0.0, seat.y + 0.3 * phi.sin());
    let moved = bent - rigid;
    assert!(
        (moved - expected).norm() < 1e-12,
        "moved {moved:?}, expected {expected:?}"
    );
}

#[test]
fn identified_values_are_written_back_and_the_model_file_reloads() {
    let (scratch, path) = example_folder("rt-specwith");
    let robot = Robot::from_path(&path).unwrap();
    let model = &robot.error_models()[0];
    assert_eq!(model.params()[0].name, "cable_sag.boom.mass_per_length");
    let spec = model.spec_with(&[3.75]);
    let mut file = robot.to_file();
    file.error_models = vec![spec];
    // Model files may be written anywhere: the library path is kept absolute.
    let out = scratch.0.join("elsewhere");
    std::fs::create_dir_all(&out).unwrap();
    let text = toml::to_string(&file).unwrap();
    let reloaded = robot_from_text(&text, &out.join("model.toml")).unwrap();
    let p = &reloaded.error_models()[0].params()[0];
    assert_eq!((p.name.as_str(), p.nominal), ("cable_sag.boom.mass_per_length", 3.75));
}

#[test]
fn loaded_plugin_types_are_listed_with_their_role() {
    let (_scratch, path) = example_folder("rt-list");
    Robot::from_path(&path).unwrap();
    let entry = armcomp_api::plugins()
        .into_iter()
        .find(|p| p.type_name == "cable_sag")
        .expect("the loaded type is in the registry");
    assert_eq!(entry.role, armcomp_core::Role::ErrorModel);
    assert!(entry.diagnosis_candidate);
    let (code, out, err) = run(&[
        "plugins",
        "--allow-plugins",
        "--library",
        built_plugins().join("cable_sag").to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.lines()
            .any(|l| l.contains("cable_sag") && l.contains("[diagnosis candidate]")),
        "{out}"
    );
}

fn run(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_armcomp")).args(args).output().unwrap();
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into(),
        String::from_utf8_lossy(&out.stderr).into(),
    )
}

#[test]
fn simulate_runs_a_truth_robot_with_a_runtime_plugin() {
    let (scratch, path) = example_folder("rt-simulate");
    let csv = scratch.0.join("data.csv");
    let (code, _, err) = run(&[
        "simulate",
        "--allow-plugins",
        "--robot",
        path.to_str().unwrap(),
        "--n",
        "5",
        "--out",
        csv.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(std::fs::read_to_string(csv).unwrap().lines().count(), 6);
}

/// The error of building the example robot with its last error model replaced by `entry`,
/// in a folder that holds the faulty test plugins; the robot file is `robot.toml` there.
fn build_error(tag: &str, entry: &str, extra_files: &[(&str, &[u8])]) -> String {
    let (scratch, path) = example_folder(tag);
    for lib in ["faulty_plugin", "wrong_abi_plugin", "incomplete_plugin"] {
        let file = library_file(lib);
        std::fs::copy(built_plugins().join("examples").join(&file), scratch.0.join(&file)).unwrap();
    }
    for (name, bytes) in extra_files {
        std::fs::write(scratch.0.join(name), bytes).unwrap();
    }
    let text = std::fs::read_to_string(&path).unwrap();
    let text = format!("{text}\n[[error_models]]\n{entry}\n");
    std::fs::write(&path, text).unwrap();
    match Robot::from_path(&path) {
        Ok(_) => panic!("{entry} should not build"),
        Err(e @ Error::InvalidFile { .. }) => e.to_string(),
        Err(e) => panic!("unexpected error kind: {e}"),
    }
}

/// Asserts that `message` names the file, the line, the field and says `what`.
fn assert_names(message: &str, line: usize, field: &str, what: &str) {
    let prefix = format!("robot.toml:{line}: {field}: ");
    assert!(message.contains(&prefix), "expected `{prefix}` in: {message}");
    assert!(message.contains(what), "expected `{what}` in: {message}");
}

#[test]
fn a_missing_library_names_the_field_and_the_file() {
    let e = build_error(
        "rt-missing",
        "type = \"plugin\"\nlibrary = \"no_such\"\nmodel = \"x\"",
        &[],
    );
    assert_names(&e, 62, "error_models[1].library", &library_file("no_such"));
}

#[test]
fn a_file_that_is_not_a_library_is_rejected() {
    let e = build_error(
        "rt-notlib",
        "type = \"plugin\"\nlibrary = \"garbage.so\"\nmodel = \"x\"",
        &[("garbage.so", b"not an ELF file at all")],
    );
    assert_names(
        &e,
        62,
        "error_models[1].library",
        "garbage.so: not a loadable shared library",
    );
}

#[test]
fn a_library_of_another_abi_version_is_rejected() {
    let e = build_error(
        "rt-abi",
        "type = \"plugin\"\nlibrary = \"wrong_abi_plugin\"\nmodel = \"x\"",
        &[],
    );
    assert_names(
        &e,
        62,
        "error_models[1].library",
        &format!(
            "speaks plugin ABI version {}, this armcomp speaks version {}",
            armcomp_sdk::abi::ABI_VERSION + 1000,
            armcomp_sdk::abi::ABI_VERSION
        ),
    );
}

#[test]
fn a_library_without_the_entry_points_is_rejected() {
    let e = build_error(
        "rt-symbol",
        "type = \"plugin\"\nlibrary = \"incomplete_plugin\"\nmodel = \"x\"",
        &[],
    );
    assert_names(&e, 62, "error_models[1].library", "does not export `armcomp_type_info`");
}

#[test]
fn an_unknown_model_lists_the_library_types() {
    let e = build_error(
        "rt-model",
        "type = \"plugin\"\nlibrary = \"cable_sag\"\nmodel = \"sag\"",
        &[],
    );
    assert_names(
        &e,
        63,
        "error_models[1].model",
        "has no error model named `sag`; it has: `cable_sag`",
    );
}

#[test]
fn a_config_violating_the_plugin_schema_names_the_field() {
    let e = build_error(
        "rt-schema",
        "type = \"plugin\"\nlibrary = \"cable_sag\"\nmodel = \"cable_sag\"\nconfig = { link = \"boom\", length = -1.0, mass_per_length = 1.0 }",
        &[],
    );
    assert_names(
        &e,
        64,
        "error_models[1].config.length",
        "-1.0 is less than the minimum of 0",
    );
}

#[test]
fn a_config_the_plugin_rejects_names_the_field() {
    let e = build_error(
        "rt-reject",
        "type = \"plugin\"\nlibrary = \"faulty_plugin\"\nmodel = \"faulty\"\nconfig = { mode = \"reject\" }",
        &[],
    );
    assert_names(&e, 64, "error_models[1].config.mode", "rejects its config on purpose");
}

#[test]
fn a_plugin_that_panics_is_reported_and_the_host_keeps_running() {
    let e = build_error(
        "rt-panic",
        "type = \"plugin\"\nlibrary = \"faulty_plugin\"\nmodel = \"faulty\"\nconfig = { mode = \"panic\" }",
        &[],
    );
    assert_names(
        &e,
        60,
        "error_models[1]",
        "the plugin panicked: faulty model panics on purpose",
    );
}

#[test]
fn a_plugin_returning_nan_is_rejected() {
    let e = build_error(
        "rt-nan",
        "type = \"plugin\"\nlibrary = \"faulty_plugin\"\nmodel = \"faulty\"\nconfig = { mode = \"nan\" }",
        &[],
    );
    assert_names(
        &e,
        60,
        "error_models[1]",
        "perturb returned NaN among the joint offsets (value 0)",
    );
}

#[test]
fn a_plugin_returning_the_wrong_number_of_values_is_rejected() {
    let e = build_error(
        "rt-short",
        "type = \"plugin\"\nlibrary = \"faulty_plugin\"\nmodel = \"faulty\"\nconfig = { mode = \"short\" }",
        &[],
    );
    assert_names(
        &e,
        60,
        "error_models[1]",
        "perturb: the model returned 4 joint offsets, expected 3",
    );
}

#[test]
fn calibration_identifies_the_runtime_parameter_as_it_does_the_linked_one() {
    let (scratch, path) = example_folder("rt-calibrate");
    let truth = Robot::from_path(&path).unwrap();
    let poses = configurations(truth.tree(), Sampler::Sobol, 120, 3).unwrap();
    let noise = SimulateParams {
        noise_std: 0.01e-3,
        seed: 11,
    };
    let samples = simulate(&truth, &poses, noise).unwrap().samples;
    // Both starts believe the hose weighs 1 kg/m; the truth's is 2.5 kg/m.
    let text = std::fs::read_to_string(&path).unwrap();
    let start_path = scratch.file(
        "start.toml",
        &text.replace("mass_per_length = 2.5", "mass_per_length = 1.0"),
    );
    let runtime_start = Robot::from_path(&start_path).unwrap();
    let linked_start = linked_robot(1.0);
    let name = "cable_sag.boom.mass_per_length";
    let params = CalibrationParams {
        identify: vec![name.to_string()],
        measurement_std: noise.noise_std,
        ..Default::default()
    };
    let identified = |start: &Robot| {
        let cal = calibrate(start, &samples, &params, &mut |_| {}).unwrap();
        assert!(cal.report.converged, "{}", cal.report.stop_reason);
        let p = cal.report.params.iter().find(|p| p.name == name).unwrap();
        (p.value, p.std)
    };
    let (runtime, std) = identified(&runtime_start);
    let (linked, _) = identified(&linked_start);
    assert_eq!(
        runtime, linked,
        "the loaded and the linked model identify the same value"
    );
    assert!(
        std > 0.0 && (runtime - 2.5).abs() < 4.0 * std,
        "identified {runtime} ± {std}, truth 2.5"
    );
}

#[test]
fn diagnose_names_a_hose_hidden_in_the_data_from_the_library_candidates() {
    // The library's error model joins the built-in ones with a per-link template. (Other tests
    // load copies of the library from folders they remove; the registry lists those too.)
    allow_plugins();
    let mut plugins = armcomp_api::registry::builtin_plugins();
    plugins.extend(armcomp_sdk::load_library(&built_plugins().join(library_file("cable_sag"))).unwrap());
    let entry = plugins.iter().find(|p| p.type_name == "cable_sag").unwrap();
    // The truth carries a bundle of hoses, 5 kg/m (the linked model); the model as given knows
    // none.
    let truth = linked_robot(5.0);
    let mut file = truth.to_file();
    file.error_models.clear();
    let nominal = truth.rebuild(file).unwrap();
    // Only the boom has a beam for the hose to bend; a robot that has the hose already is
    // offered none (its parameters would be given twice).
    let offered = |robot: &Robot| -> Vec<(String, String)> {
        (entry.candidates.unwrap())(robot)
            .into_iter()
            .map(|c| (c.location, c.label))
            .collect()
    };
    assert_eq!(offered(&nominal), [("boom".into(), "boom link cable sag".into())]);
    assert_eq!(offered(&truth), []);
    let noise = 0.02e-3;
    let poses = configurations(truth.tree(), Sampler::Sobol, 90, 5).unwrap();
    let mut samples = simulate(
        &truth,
        &poses,
        SimulateParams {
            noise_std: noise,
            seed: 6,
        },
    )
    .unwrap()
    .samples;
    // Measured with and without a 10 kg test weight, as one would to tell a sagging hose (which
    // the weight does not change) from a giving joint (which it does). The truth has no
    // effect of the payload, so the simulated positions stand.
    for (i, s) in samples.iter_mut().enumerate() {
        s.payload = Some(if i % 2 == 0 { 0.0 } else { 10.0 });
    }
    let params = DiagnoseParams {
        calibration: CalibrationParams {
            measurement_std: noise,
            max_iterations: 30,
            ..Default::default()
        },
        max_steps: 1,
        ..Default::default()
    };
    let r = diagnose(&nominal, &samples, &plugins, None, &params, &|_| {})
        .unwrap()
        .report;
    let step = r.steps.first().expect("an effect is found");
    assert_eq!(
        (step.effect.as_str(), step.location.as_str()),
        ("cable_sag", "boom"),
        "found {}",
        step.summary
    );
    assert!(
        step.heldout_after.rms_mm <= 0.5 * r.initial.rms_mm,
        "held-out RMS {:.4} → {:.4} mm",
        r.initial.rms_mm,
        step.heldout_after.rms_mm
    );
    // Without the test weight a giving j2 would explain the data as well; with it, it cannot.
    let j2 = step.ranking.iter().find(|c| c.label == "joint j2 compliance").unwrap();
    assert!(!j2.indistinguishable_from_best, "{}", step.summary);
    let mu = step.params["cable_sag.boom.mass_per_length"].value;
    assert!((mu - 5.0).abs() < 0.5, "identified {mu} kg/m, truth 5");
}
