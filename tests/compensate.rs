//! Compensation: commanding the truth robot with the computed command lands on the target.

use armcomp_core::algorithms::compensate::{CompensationMode, CompensationParams, Compensator, mid_range, tool_chain};
use armcomp_core::algorithms::evaluate::{ErrorStats, fit_residual_predictor, position_errors};
use armcomp_core::algorithms::ik::{IkParams, IkTarget, IkWorkspace, LinearOffset, solve_ik_with_offset};
use armcomp_core::algorithms::simulate::{SimulateParams, simulate};
use armcomp_core::data::measurement::{read_csv, write_csv};
use armcomp_core::support::io::InputLimits;
use armcomp_core::{FitControl, PredictorSpec};
use armcomp_learn::{GpSpec, KnnSpec, RidgeSpec};
use nalgebra::Matrix3xX;
use nalgebra::{Isometry3, Vector3};

use crate::cli::armcomp;
use crate::common::{Scratch, random_configurations, robot, root};

/// Truth tool positions at random configurations (m, base = measurement frame of the twin).
fn targets(truth: &armcomp_core::Robot, n: usize, seed: u64) -> Vec<Vector3<f64>> {
    random_configurations(truth, n, seed)
        .iter()
        .map(|q| truth.forward(q).unwrap().point[truth.tool()].translation.vector)
        .collect()
}

/// `armcomp compensate --model M --targets T --out O [extra…]`: exit code, stdout, stderr.
fn compensate_cli(
    model: &str,
    targets: &std::path::Path,
    out: &std::path::Path,
    extra: &[&str],
) -> (i32, String, String) {
    let mut args = vec![
        "compensate",
        "--model",
        model,
        "--targets",
        targets.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    armcomp(&args)
}

#[test]
fn the_truth_as_model_compensates_exactly() {
    let truth = robot("rock-drill-truth.toml");
    let mut comp = Compensator::for_model(&truth, CompensationParams::default()).unwrap();
    let q0 = vec![0.0, 0.2, 0.05, 0.5, -0.4, 0.0, 0.03];
    for t in targets(&truth, 10, 3) {
        let c = comp.compensate(&t, &q0, CompensationMode::Exact).unwrap();
        assert_eq!(c.shifts, 0);
        let landed = truth.forward(comp.q()).unwrap().point[truth.tool()].translation.vector;
        assert!((landed - t).norm() < 1e-8, "{}", (landed - t).norm());
    }
}

#[test]
fn ik_with_a_linear_offset_solves_the_offset_model() {
    let robot = robot("rock-drill-deflection.toml");
    let nq = robot.tree().nq();
    // An offset of a few millimetres that changes with every joint.
    let offset = LinearOffset {
        value: Vector3::new(0.004, -0.003, 0.006),
        jacobian: Matrix3xX::from_fn(nq, |r, c| 0.002 * ((r + 2 * c) as f64).sin()),
        q_ref: mid_range(&robot),
    };
    let mut ws = IkWorkspace::new(&robot);
    for t in targets(&robot, 8, 21) {
        let opts = IkParams {
            position_tolerance: 1e-10,
            ..IkParams::default()
        };
        solve_ik_with_offset(
            &robot,
            robot.tool(),
            &IkTarget::Position(t),
            Some(&offset),
            &mid_range(&robot),
            &opts,
            &mut ws,
        )
        .unwrap();
        // Independently: the model's point plus value + C (q − q_ref) is on the target.
        let q = ws.q();
        let dq = nalgebra::DVector::from_iterator(nq, q.iter().zip(&offset.q_ref).map(|(a, b)| a - b));
        let moved = offset.value + &offset.jacobian * dq;
        let at = robot.forward(q).unwrap().point[robot.tool()].translation.vector + moved;
        assert!((at - t).norm() < 1e-9, "{:e}", (at - t).norm());
    }
}

/// Exact mode with predictors that do (GP) and do not (ridge) have a derivative: the model plus
/// the predicted residual, evaluated here on its own, lands on every target. kNN is not smooth
/// enough for the fixed-point iteration to contract everywhere; where it does not, the miss it
/// reports is the true one.
/// The truth measured without noise at 120 random configurations.
fn noiseless_data(truth: &armcomp_core::Robot, seed: u64) -> armcomp_core::data::measurement::MeasurementSet {
    let params = SimulateParams {
        noise_std: 0.0,
        seed: 1,
    };
    simulate(truth, &random_configurations(truth, 120, seed), params).unwrap()
}

/// A GP whose hyper-parameter search is cut short, for speed.
fn quick_gp() -> GpSpec {
    GpSpec {
        max_optimization_samples: 60,
        max_iterations: 15,
        ..GpSpec::default()
    }
}

#[test]
fn exact_mode_solves_model_plus_residual() {
    let truth = robot("rock-drill-truth.toml");
    let model = robot("rock-drill-deflection.toml");
    let data = noiseless_data(&truth, 31);
    let gp = quick_gp();
    let ridge = RidgeSpec::default();
    let knn = KnnSpec::default();
    let rotation = model.t_meas_base().rotation.inverse();
    for (name, spec) in [("gp", &gp as &dyn PredictorSpec), ("ridge", &ridge), ("knn", &knn)] {
        let predictor = fit_residual_predictor(&model, spec, &data.samples, &FitControl::default()).unwrap();
        let mut comp = Compensator::new(&model, Some(predictor.as_ref()), CompensationParams::default()).unwrap();
        let q0 = mid_range(&model);
        let (mut out, mut scratch) = ([0.0; 3], Vec::new());
        for t in targets(&truth, 6, 32) {
            let c = comp.compensate(&t, &q0, CompensationMode::Exact).unwrap();
            let q = comp.q().to_vec();
            predictor.predict_into(&q, &mut out, &mut scratch);
            let at = model.forward(&q).unwrap().point[model.tool()].translation.vector + rotation * Vector3::from(out);
            let miss = (at - t).norm();
            assert!(
                (c.mismatch - miss).abs() < 1e-12,
                "{name}: reported {:e}, {miss:e}",
                c.mismatch
            );
            if name != "knn" {
                assert!(miss <= 1e-8, "{name}: the full model misses by {miss:e} m");
            }
            assert!(c.shifts >= 1, "{name}: the residual was never applied");
        }
    }
}

#[test]
fn learn_then_compensate_lands_the_truth_near_its_targets() {
    let dir = Scratch::new("compensate");
    let truth = robot("rock-drill-truth.toml");
    // The nominal deflection model with a GP for what it misses.
    let nominal_text = std::fs::read_to_string(root().join("robots/rock-drill-deflection.toml")).unwrap();
    let model = dir.file(
        "model.toml",
        &format!("{nominal_text}\n[predictor]\ntype = \"gp\"\nseed = 1\nmax_optimization_samples = 150\n"),
    );
    let poses = random_configurations(&truth, 250, 11);
    let data = simulate(
        &truth,
        &poses,
        SimulateParams {
            noise_std: 0.0,
            seed: 1,
        },
    )
    .unwrap();
    let data_path = dir.file("data.csv", &write_csv(&data, truth.tree(), truth.units()));
    let fitted = dir.0.join("fitted.toml");
    let (code, _, err) = armcomp(&[
        "learn",
        "--model",
        model.to_str().unwrap(),
        "--data",
        data_path.to_str().unwrap(),
        "--out",
        fitted.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");

    // Evaluate includes the predictor: on fresh data it beats the model alone by far.
    let fitted_robot = armcomp_core::Robot::from_path(&fitted).unwrap();
    let nominal = robot("rock-drill-deflection.toml");
    let fresh = simulate(
        &truth,
        &random_configurations(&truth, 50, 12),
        SimulateParams {
            noise_std: 0.0,
            seed: 2,
        },
    )
    .unwrap();
    let alone = ErrorStats::from_errors(&position_errors(&nominal, &fresh.samples));
    let with = ErrorStats::from_errors(&position_errors(&fitted_robot, &fresh.samples));
    assert!(
        with.mean_mm < 0.1 * alone.mean_mm,
        "{} vs {}",
        with.mean_mm,
        alone.mean_mm
    );

    let goals = targets(&truth, 20, 13);
    let mut csv = String::from("# tool targets\nx[m],y[m],z[m]\n");
    for t in &goals {
        csv.push_str(&format!("{},{},{}\n", t.x, t.y, t.z));
    }
    let targets_path = dir.file("targets.csv", &csv);
    let mut landed_error = Vec::new();
    for mode in ["paper", "exact"] {
        let out = dir.0.join(format!("commands-{mode}.csv"));
        let (code, _, err) = compensate_cli(fitted.to_str().unwrap(), &targets_path, &out, &["--mode", mode]);
        assert_eq!(code, 0, "{err}");
        let text = std::fs::read_to_string(&out).unwrap();
        let header = text.lines().next().unwrap();
        assert!(
            header.ends_with("x_cmd[mm],y_cmd[mm],z_cmd[mm],std_x[mm],std_y[mm],std_z[mm]"),
            "{header}"
        );
        // The joint columns read back as poses; command the truth with them.
        let commands = read_csv(
            &out,
            &armcomp_core::data::measurement::CsvLayout::strict(truth.tree(), truth.units(), truth.tool()),
            InputLimits::default(),
        );
        assert!(commands.is_err(), "commands carry no measured x, y, z");
        let poses = armcomp_core::data::measurement::parse_poses(
            &text
                .lines()
                .map(|l| l.split(',').take(7).collect::<Vec<_>>().join(","))
                .collect::<Vec<_>>()
                .join("\n"),
            &out,
            &truth.csv_layout(),
        )
        .unwrap();
        let errors: Vec<f64> = poses
            .iter()
            .zip(&goals)
            .map(|(q, t)| (truth.forward(q).unwrap().point[truth.tool()].translation.vector - t).norm())
            .collect();
        let mean = errors.iter().sum::<f64>() / errors.len() as f64;
        landed_error.push(mean);
    }
    // Uncompensated through the nominal deflection model, for scale.
    let mut comp = Compensator::for_model(&nominal, CompensationParams::default()).unwrap();
    let q0 = armcomp_core::algorithms::compensate::mid_range(&nominal);
    let mut before = 0.0;
    for t in &goals {
        comp.compensate(t, &q0, CompensationMode::Exact).unwrap();
        before += (truth.forward(comp.q()).unwrap().point[truth.tool()].translation.vector - t).norm();
    }
    before /= goals.len() as f64;
    let (paper, exact) = (landed_error[0], landed_error[1]);
    assert!(exact < 0.1 * before, "exact {exact} m vs uncompensated {before} m");
    assert!(paper < 0.3 * before, "paper {paper} m vs uncompensated {before} m");
    assert!(exact <= paper * 1.05, "exact {exact} m, paper {paper} m");
}

/// Tool poses of `model` at configurations in the middle half of its joint ranges, their
/// positions moved by `shift` (m): targets a pose command can reach from the middle.
fn inner_poses(model: &armcomp_core::Robot, n: usize, seed: u64, shift: Vector3<f64>) -> Vec<Isometry3<f64>> {
    let mid = mid_range(model);
    random_configurations(model, n, seed)
        .iter()
        .map(|q| {
            let q: Vec<f64> = q.iter().zip(&mid).map(|(v, m)| m + 0.5 * (v - m)).collect();
            let mut pose = model.forward(&q).unwrap().point[model.tool()];
            pose.translation.vector += shift;
            pose
        })
        .collect()
}

/// A pose target: the tool keeps the asked orientation while the model plus the predicted
/// residual lands on the asked position, both checked on the model and the predictor directly.
#[test]
fn exact_mode_keeps_the_orientation_of_a_pose_target() {
    let truth = robot("rock-drill-truth.toml");
    let model = robot("rock-drill-deflection.toml");
    let data = noiseless_data(&truth, 41);
    let predictor = fit_residual_predictor(&model, &quick_gp(), &data.samples, &FitControl::default()).unwrap();
    let rotation = model.t_meas_base().rotation.inverse();
    let mut comp = Compensator::new(&model, Some(predictor.as_ref()), CompensationParams::default()).unwrap();
    let (mut out, mut scratch) = ([0.0; 3], Vec::new());
    for target in inner_poses(&model, 6, 42, Vector3::zeros()) {
        let c = comp
            .compensate_target(&IkTarget::Pose(target), &mid_range(&model), CompensationMode::Exact)
            .unwrap();
        let q = comp.q().to_vec();
        let tool = model.forward(&q).unwrap().point[model.tool()];
        predictor.predict_into(&q, &mut out, &mut scratch);
        let miss = (tool.translation.vector + rotation * Vector3::from(out) - target.translation.vector).norm();
        assert!(miss <= 1e-8, "the full model misses the position by {miss:e} m");
        assert!((c.mismatch - miss).abs() < 1e-12, "reported {:e}, {miss:e}", c.mismatch);
        let turn = tool.rotation.angle_to(&target.rotation);
        assert!(
            turn <= 1e-8,
            "the tool is turned {turn:e} rad from the asked orientation"
        );
        assert!(c.shifts >= 1, "the residual was never applied");
    }
}

/// `armcomp compensate` with `qw, qx, qy, qz` columns: the commands put the model's tool on each
/// target pose, given in the measurement frame.
#[test]
fn compensate_cli_reads_pose_targets() {
    let dir = Scratch::new("compensate-pose");
    let model = robot("rock-drill-deflection.toml");
    let t_meas_base = model.t_meas_base();
    let goals: Vec<Isometry3<f64>> = inner_poses(&model, 5, 43, Vector3::new(0.004, -0.003, 0.005))
        .into_iter()
        .map(|p| t_meas_base * p)
        .collect();
    let mut csv = String::from("qw,qx,qy,qz,x[mm],y[mm],z[mm]\n");
    for g in &goals {
        let (q, p) = (g.rotation.quaternion(), g.translation.vector * 1e3);
        csv.push_str(&format!("{},{},{},{},{},{},{}\n", q.w, q.i, q.j, q.k, p.x, p.y, p.z));
    }
    let targets_path = dir.file("poses.csv", &csv);
    let out = dir.0.join("commands.csv");
    let (code, _, err) = compensate_cli("robots/rock-drill-deflection.toml", &targets_path, &out, &[]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&out).unwrap();
    let nq = model.tree().nq();
    let poses = armcomp_core::data::measurement::parse_poses(
        &text
            .lines()
            .map(|l| l.split(',').take(nq).collect::<Vec<_>>().join(","))
            .collect::<Vec<_>>()
            .join("\n"),
        &out,
        &model.csv_layout(),
    )
    .unwrap();
    assert_eq!(poses.len(), goals.len());
    for (q, goal) in poses.iter().zip(&goals) {
        let landed = t_meas_base * model.forward(q).unwrap().point[model.tool()];
        // The commands are written with the file's precision, not the solver's.
        let miss = (landed.translation.vector - goal.translation.vector).norm();
        assert!(miss < 1e-6, "position missed by {miss:e} m");
        let turn = landed.rotation.angle_to(&goal.rotation);
        assert!(turn < 1e-6, "orientation missed by {turn:e} rad");
    }

    for (name, text, expected) in [
        (
            "half.csv",
            "x[mm],y[mm],z[mm],qw,qx\n1,2,3,1,0\n",
            "half.csv:1: an orientation needs all four columns qw, qx, qy, qz",
        ),
        (
            "unnormed.csv",
            "x[mm],y[mm],z[mm],qw,qx,qy,qz\n1,2,3,1,0,0,0\n1,2,3,0.5,0,0,0\n",
            "unnormed.csv:3: orientation quaternion has norm 0.500000, expected 1",
        ),
    ] {
        let bad = dir.file(name, text);
        let (code, _, err) = compensate_cli("robots/rock-drill-deflection.toml", &bad, &out, &[]);
        assert_ne!(code, 0);
        assert!(err.contains(expected), "{err}");
    }
}

#[test]
fn compensate_reports_bad_targets_with_line_and_column() {
    let dir = Scratch::new("compensate-bad");
    let bad = dir.file("t.csv", "x[mm],y[mm],z[mm]\n100,0,400\n100,abc,400\n");
    let out = dir.0.join("c.csv");
    let (code, _, err) = compensate_cli("robots/rock-drill.toml", &bad, &out, &[]);
    assert_ne!(code, 0);
    assert!(err.contains("t.csv:3: column 2: `abc` is not a finite number"), "{err}");
    assert!(!out.exists());
    // The library's error is the same input error, with the column's header as data.
    match armcomp_api::ops::compensate::read_targets(&bad, robot("rock-drill.toml").units(), InputLimits::default()) {
        Err(armcomp_core::Error::InputAt { location, column, .. }) => {
            assert_eq!((location.line, column.as_deref()), (Some(3), Some("y[mm]")));
        }
        other => panic!("expected an input error, got {other:?}"),
    }
    let (code, _, err) = compensate_cli("robots/rock-drill.toml", &bad, &bad, &[]);
    assert_ne!(code, 0);
    assert!(err.contains("refusing to overwrite an input"), "{err}");
}

/// A rock-drill file with a second marker, a nest 80 mm beside the drill bit on the feed.
fn with_two_markers(name: &str) -> armcomp_core::Robot {
    let text = std::fs::read_to_string(root().join("robots").join(name))
        .unwrap()
        .replacen(
            "[measurement]",
            "[[points]]\nname = \"nest\"\nlink = \"feed\"\nxyz = [0.0, 80.0, 0.0]\n\n[measurement]",
            1,
        )
        .replacen("markers = [\"tool\"]", "markers = [\"tool\", \"nest\"]", 1);
    crate::common::robot_from_toml(&text)
}

#[test]
fn a_residual_predictor_learns_several_points_and_compensates_the_tool() {
    let truth = with_two_markers("rock-drill-truth.toml");
    let model = with_two_markers("rock-drill-deflection.toml");
    assert_eq!(model.markers().len(), 2);
    let data = noiseless_data(&truth, 41);
    let (train, test) = data.samples.split_at(160);
    let predictor = fit_residual_predictor(&model, &quick_gp(), train, &FitControl::default()).unwrap();
    assert_eq!(predictor.n_inputs(), model.tree().nq() + 3);
    let mut file = model.to_file();
    file.fitted_predictor = Some(predictor);
    file.predictor_frame = Some(armcomp_core::robot::robot_file::PredictorFrame::Base);
    let learned = model.rebuild(file).unwrap();
    for &point in model.markers() {
        let of_point: Vec<_> = test.iter().filter(|s| s.point == point).cloned().collect();
        assert!(of_point.len() > 20);
        let before = ErrorStats::from_errors(&armcomp_core::algorithms::evaluate::model_errors(&model, &of_point));
        let after = ErrorStats::from_errors(&position_errors(&learned, &of_point));
        assert!(
            after.rms_mm < 0.5 * before.rms_mm,
            "point {point}: {} -> {} mm",
            before.rms_mm,
            after.rms_mm
        );
    }
    // The tool's residual is predicted at its own position on the feed.
    let mut comp = Compensator::for_model(&learned, CompensationParams::default()).unwrap();
    let q0 = mid_range(&learned);
    for t in targets(&truth, 3, 42) {
        let c = comp.compensate(&t, &q0, CompensationMode::Exact).unwrap();
        assert!(c.mismatch < 1e-6, "{}", c.mismatch);
    }
}

/// A model without a `[predictor]` table (a calibrated bare URDF has none) learns with
/// `--predictor TYPE`, which also becomes its table; without either, `learn` says how.
#[test]
fn learn_fits_the_predictor_named_on_the_command_line() {
    let dir = Scratch::new("learn-predictor");
    let truth = robot("rock-drill-truth.toml");
    let model = root().join("robots/rock-drill-deflection.toml");
    let data = simulate(
        &truth,
        &random_configurations(&truth, 200, 21),
        SimulateParams {
            noise_std: 0.0,
            seed: 1,
        },
    )
    .unwrap();
    let data_path = dir.file("data.csv", &write_csv(&data, truth.tree(), truth.units()));
    let fitted = dir.0.join("fitted.toml");
    let run = |extra: &[&str]| {
        let mut args = vec![
            "learn",
            "--model",
            model.to_str().unwrap(),
            "--data",
            data_path.to_str().unwrap(),
            "--out",
            fitted.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        armcomp(&args)
    };
    let (code, _, err) = run(&[]);
    assert_ne!(code, 0);
    assert!(err.contains("--predictor") && err.contains("[predictor]"), "{err}");
    assert!(!fitted.exists());
    let (code, _, err) = run(&["--predictor", "ridge"]);
    assert_eq!(code, 0, "{err}");
    let fitted_robot = armcomp_core::Robot::from_path(&fitted).unwrap();
    let spec = serde_json::to_value(fitted_robot.predictor_spec().expect("the table is written")).unwrap();
    assert_eq!(spec["type"], "ridge");
    assert!(fitted_robot.predictor().is_some());
    let fresh = simulate(
        &truth,
        &random_configurations(&truth, 50, 22),
        SimulateParams {
            noise_std: 0.0,
            seed: 2,
        },
    )
    .unwrap();
    let alone = ErrorStats::from_errors(&position_errors(&robot("rock-drill-deflection.toml"), &fresh.samples));
    let with = ErrorStats::from_errors(&position_errors(&fitted_robot, &fresh.samples));
    assert!(
        with.mean_mm < 0.8 * alone.mean_mm,
        "{} vs {}",
        with.mean_mm,
        alone.mean_mm
    );
    let (code, _, err) = run(&["--predictor", "nope"]);
    assert_ne!(code, 0);
    assert!(err.contains("nope") && err.contains("gp"), "{err}");
}

/// TALOS, a humanoid whose marker is on the left gripper: the coordinate named `name`.
fn coordinate(r: &armcomp_core::Robot, name: &str) -> usize {
    r.tree().coordinate_names().iter().position(|n| n == name).unwrap()
}

/// Compensating the left arm's marker of a humanoid moves only the torso and left arm, from
/// any start; a locked joint keeps its value exactly; the target is still reached (by FK).
#[test]
fn compensation_moves_only_the_measured_chain_and_keeps_locked_joints() {
    let r = robot("talos-left-arm.toml");
    let chain = tool_chain(&r);
    assert_eq!(chain, r.measured_coordinates());
    assert_eq!(chain.iter().filter(|c| **c).count(), 9);
    assert!(r.tree().nq() > 30);
    let locked_joint = coordinate(&r, "arm_left_2_joint");
    let mut locked = vec![false; r.tree().nq()];
    locked[locked_joint] = true;
    let mut comp = Compensator::for_model(&r, CompensationParams::default()).unwrap();
    comp.lock(&locked).unwrap();
    // Starts with every joint somewhere (legs bent, head turned, the other arm raised), and
    // truths that differ from them only in the free joints.
    let starts = random_configurations(&r, 6, 91);
    let moves = random_configurations(&r, 6, 92);
    for (start, moved) in starts.iter().zip(&moves) {
        let truth: Vec<f64> = (0..start.len())
            .map(|c| if chain[c] && !locked[c] { moved[c] } else { start[c] })
            .collect();
        let target = r.forward(&truth).unwrap().point[r.tool()].translation.vector;
        comp.compensate(&target, start, CompensationMode::Exact).unwrap();
        let q = comp.q().to_vec();
        for (c, name) in r.tree().coordinate_names().iter().enumerate() {
            if !chain[c] || locked[c] {
                assert_eq!(q[c].to_bits(), start[c].to_bits(), "{name} moved");
            }
        }
        let landed = r.forward(&q).unwrap().point[r.tool()].translation.vector;
        assert!((landed - target).norm() < 1e-8, "{:e}", (landed - target).norm());
    }
    // A locked joint outside its limits cannot be kept: refused, named.
    let mut outside = starts[0].clone();
    let limits = r.tree().coordinate_limits()[locked_joint].unwrap();
    outside[locked_joint] = limits.upper + 0.1;
    let target = r.forward(&starts[0]).unwrap().point[r.tool()].translation.vector;
    let err = comp.compensate(&target, &outside, CompensationMode::Exact).unwrap_err();
    assert!(err.to_string().contains("locked joint `arm_left_2_joint`"), "{err}");
}

/// `armcomp compensate --start S --lock …` on the humanoid: the commands keep every joint
/// outside the left arm at the start file's value (or the robot file's hold value, 0), the
/// locked torso where the start puts it, and land on the targets by FK.
#[test]
fn compensate_cli_keeps_the_start_outside_the_measured_chain() {
    let dir = Scratch::new("compensate-talos");
    let r = robot("talos-left-arm.toml");
    let names = r.tree().coordinate_names();
    let given = [
        ("torso_1_joint", 0.2),
        ("torso_2_joint", 0.1),
        ("head_1_joint", 0.3),
        ("leg_left_4_joint", 0.5),
        ("arm_right_4_joint", -0.4),
    ];
    let header: Vec<String> = given.iter().map(|(n, _)| format!("{n}[rad]")).collect();
    let values: Vec<String> = given.iter().map(|(_, v)| v.to_string()).collect();
    let start_path = dir.file("start.csv", &format!("{}\n{}\n", header.join(","), values.join(",")));
    // The start, by hand: the given joints, every other one at 0, or the middle of its limits
    // where they exclude 0 (what a measurement file holds a joint at without a column).
    let mut start: Vec<f64> = r
        .tree()
        .coordinate_limits()
        .iter()
        .map(|l| match l {
            Some(l) if l.lower > 0.0 || l.upper < 0.0 => 0.5 * (l.lower + l.upper),
            _ => 0.0,
        })
        .collect();
    for (n, v) in given {
        start[coordinate(&r, n)] = v;
    }
    let arm: Vec<usize> = (1..=7)
        .map(|k| coordinate(&r, &format!("arm_left_{k}_joint")))
        .collect();
    let mut targets = Vec::new();
    let mut csv = String::from("x[m],y[m],z[m]\n");
    for moved in random_configurations(&r, 4, 17) {
        let mut truth = start.clone();
        arm.iter().for_each(|&c| truth[c] = moved[c]);
        let p = r.forward(&truth).unwrap().point[r.tool()].translation.vector;
        csv.push_str(&format!("{},{},{}\n", p.x, p.y, p.z));
        targets.push(p);
    }
    let targets_path = dir.file("targets.csv", &csv);
    let out = dir.0.join("commands.csv");
    let (code, _, err) = compensate_cli(
        "robots/talos-left-arm.toml",
        &targets_path,
        &out,
        &[
            "--frame",
            "base",
            "--start",
            start_path.to_str().unwrap(),
            "--lock",
            "torso_1_joint,torso_2_joint",
        ],
    );
    assert_eq!(code, 0, "{err}");
    assert!(
        err.contains(&format!("changed 7 of {} joints: arm_left_1_joint", names.len())),
        "{err}"
    );
    let text = std::fs::read_to_string(&out).unwrap();
    let nq = r.tree().nq();
    let joint_columns: String = text
        .lines()
        .map(|l| l.split(',').take(nq).collect::<Vec<_>>().join(","))
        .collect::<Vec<_>>()
        .join("\n");
    let commands = armcomp_core::data::measurement::parse_poses(&joint_columns, &out, &r.csv_layout()).unwrap();
    assert_eq!(commands.len(), targets.len());
    for (q, target) in commands.iter().zip(&targets) {
        for (c, name) in names.iter().enumerate() {
            if !arm.contains(&c) {
                assert!(
                    (q[c] - start[c]).abs() < 1e-12,
                    "{name}: {} instead of {}",
                    q[c],
                    start[c]
                );
            }
        }
        let landed = r.forward(q).unwrap().point[r.tool()].translation.vector;
        assert!((landed - target).norm() < 1e-6, "{:e}", (landed - target).norm());
    }

    for (lock, expected) in [
        (
            "arm_left_9_joint",
            "locked joint `arm_left_9_joint` is not a joint of `talos-left-arm`",
        ),
        ("gripper_left_base_link_joint", "is a fixed joint"),
    ] {
        let (code, _, err) = compensate_cli(
            "robots/talos-left-arm.toml",
            &targets_path,
            &out,
            &["--frame", "base", "--lock", lock],
        );
        assert_ne!(code, 0);
        assert!(err.contains(expected), "{err}");
    }
}

/// What compensation refuses comes back typed, each message naming what to change.
#[test]
fn compensation_refusals_are_typed() {
    use armcomp_api::ops::compensate::{Frame, Joints, Target, locked_by_name, run};
    use armcomp_api::{Error, LockReason};
    let justin = robot("agile-justin.toml");
    let err = locked_by_name(&justin, &["t4".into()]).unwrap_err();
    assert!(
        matches!(&err, Error::LockedJoint { name, reason: LockReason::Mimic { follows } } if name == "t4" && follows == &["t2", "t3"]),
        "{err:?}"
    );
    assert_eq!(
        err.to_string(),
        "locked joint `t4` is a mimic joint; lock the joint it follows: `t2`, `t3`"
    );
    let drill = robot("rock-drill.toml");
    let err = Joints::new(&drill, vec![vec![0.0]], Vec::new()).unwrap_err();
    assert!(matches!(err, Error::StartConfiguration { index: 1, .. }), "{err:?}");
    let source = std::error::Error::source(&err).expect("the core error is the source");
    assert!(source.downcast_ref::<armcomp_core::Error>().is_some(), "{source}");
    let start = armcomp_core::algorithms::compensate::default_start(&drill);
    let joints = Joints::new(&drill, vec![start; 2], Vec::new()).unwrap();
    let target = Target {
        position: Vector3::new(1.0, 0.0, 0.4),
        orientation: None,
    };
    let err = run(
        &drill,
        &[target.clone(), target.clone(), target],
        &joints,
        CompensationMode::Exact,
        Frame::Measurement,
        &|i| format!("target {i}"),
        &armcomp_core::support::cancel::Cancel::default(),
    )
    .unwrap_err();
    assert_eq!(
        err.to_string(),
        "2 start configurations for 3 targets; give one for all or one per target"
    );
}
