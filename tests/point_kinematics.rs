//! The compiled point kinematics (`PointKinematics`) against the full tree's FK (checked
//! against hand calculations in `fk.rs`), pinocchio's link poses and central differences; the
//! batches against single calls, with and without error models.

use std::path::PathBuf;

use armcomp_api::read_robot;
use armcomp_core::support::io::InputLimits;
use armcomp_core::{Error, KinematicTree, Motion, PointKinematics, Robot, TreeWorkspace};
use nalgebra::{Isometry3, IsometryMatrix3, Matrix6xX, Quaternion, UnitQuaternion, Vector3};

use crate::common::{random_configurations, root};

/// Every robot the repository ships: `robots/`, the test robots and the URDF corpus.
fn every_robot() -> Vec<(PathBuf, Robot)> {
    let mut files = Vec::new();
    for dir in ["robots", "tests/data/robots", "tests/data/urdf"] {
        for entry in std::fs::read_dir(root().join(dir)).unwrap() {
            let path = entry.unwrap().path();
            if matches!(path.extension().and_then(|e| e.to_str()), Some("toml" | "urdf")) {
                files.push(path);
            }
        }
    }
    files.sort();
    files
        .into_iter()
        .map(|p| {
            let robot = read_robot(&p, InputLimits::default()).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
            (p, robot)
        })
        .collect()
}

fn robot_at(path: &str) -> Robot {
    read_robot(&root().join(path), InputLimits::default()).unwrap()
}

/// Position (m) and largest rotation-matrix entry difference between two poses.
fn pose_difference(a: &IsometryMatrix3<f64>, b: &IsometryMatrix3<f64>) -> (f64, f64) {
    let dr = (a.rotation.matrix() - b.rotation.matrix()).abs().max();
    ((a.translation.vector - b.translation.vector).norm(), dr)
}

fn matrix_form(iso: &Isometry3<f64>) -> IsometryMatrix3<f64> {
    IsometryMatrix3::from_parts(iso.translation, iso.rotation.to_rotation_matrix())
}

/// The plan's point poses at `q` against the full tree's, largest differences over points.
fn plan_against_tree(tree: &KinematicTree, plan: &PointKinematics, q: &[f64]) -> (f64, f64) {
    let mut full = TreeWorkspace::new(tree);
    tree.forward_into(q, &mut full);
    let mut ws = plan.workspace();
    plan.forward_into(q, &mut ws);
    let mut worst: (f64, f64) = (0.0, 0.0);
    for (k, &p) in plan.tree_points().iter().enumerate() {
        let (d, r) = pose_difference(&ws.point_pose(k), &matrix_form(&full.point[p]));
        worst = (worst.0.max(d), worst.1.max(r));
    }
    worst
}

#[test]
fn path_fk_equals_full_fk_for_every_point_of_every_robot() {
    let robots = every_robot();
    assert!(robots.len() >= 20, "{} robots", robots.len());
    for (path, robot) in &robots {
        let tree = robot.tree();
        for q in random_configurations(robot, 5, 11) {
            // Every point at once (the robot's own plan), and each point alone.
            let (d, r) = plan_against_tree(tree, robot.kinematics(), &q);
            assert!(d < 1e-12 && r < 1e-12, "{}: {d:e} m, {r:e}", path.display());
            for p in 0..tree.points().len() {
                let alone = PointKinematics::for_points(tree, &[p]).unwrap();
                let (d, r) = plan_against_tree(tree, &alone, &q);
                assert!(d < 1e-12 && r < 1e-12, "{}, point {p}: {d:e} m, {r:e}", path.display());
            }
        }
    }
}

#[test]
fn path_fk_evaluates_only_the_moving_joints_on_the_path() {
    // The UR5's tool: its six arm joints, not the fixed ones (base, flange, tool0).
    let ur5 = robot_at("tests/data/urdf/ur5_robot.urdf");
    let tree = ur5.tree();
    let plan = PointKinematics::for_points(tree, &[ur5.tool()]).unwrap();
    let names: Vec<&str> = plan.joints().iter().map(|&j| tree.joints()[j].name.as_str()).collect();
    assert_eq!(
        names,
        [
            "shoulder_pan_joint",
            "shoulder_lift_joint",
            "elbow_joint",
            "wrist_1_joint",
            "wrist_2_joint",
            "wrist_3_joint"
        ]
    );
    assert!(tree.joints().len() > 6);
    // TALOS' left-gripper marker: the two torso and seven arm joints of its 59.
    let talos = robot_at("robots/talos-left-arm.toml");
    let plan = PointKinematics::for_points(talos.tree(), &[talos.tool()]).unwrap();
    let names: Vec<&str> = plan
        .joints()
        .iter()
        .map(|&j| talos.tree().joints()[j].name.as_str())
        .collect();
    assert_eq!(
        names,
        [
            "torso_1_joint",
            "torso_2_joint",
            "arm_left_1_joint",
            "arm_left_2_joint",
            "arm_left_3_joint",
            "arm_left_4_joint",
            "arm_left_5_joint",
            "arm_left_6_joint",
            "arm_left_7_joint"
        ]
    );
    // A point fixed to the base needs no joint and sits where its fixed joints put it.
    let mut tree = KinematicTree::new("base");
    let bracket = tree
        .add_joint(
            "bracket",
            0,
            Isometry3::translation(0.1, 0.0, 0.0),
            Motion::Fixed,
            None,
            "b",
        )
        .unwrap();
    tree.add_joint(
        "arm",
        0,
        Isometry3::translation(0.0, 0.0, 1.0),
        Motion::Revolute(Vector3::z_axis()),
        None,
        "a",
    )
    .unwrap();
    tree.add_point("p", bracket, Isometry3::translation(0.0, 0.2, 0.0))
        .unwrap();
    let plan = PointKinematics::new(&tree);
    assert!(plan.joints().is_empty());
    let mut ws = plan.workspace();
    plan.forward_into(&[0.7], &mut ws);
    assert_eq!(ws.point_position(0), Vector3::new(0.1, 0.2, 0.0));
}

#[test]
fn path_fk_matches_pinocchio_on_the_urdf_corpus() {
    let corpus = root().join("tests/data/urdf");
    let text = std::fs::read_to_string(corpus.join("reference.json")).unwrap();
    let reference: serde_json::Value = serde_json::from_str(&text).unwrap();
    for (file, expected) in reference["robots"].as_object().unwrap() {
        // A bare URDF has a point at every link's origin, named as the link.
        let robot = read_robot(&corpus.join(file), InputLimits::default()).unwrap();
        let tree = robot.tree();
        let plan = robot.kinematics();
        let mut ws = plan.workspace();
        for configuration in expected["configurations"].as_array().unwrap() {
            let values = configuration["q"].as_object().unwrap();
            let q: Vec<f64> = tree
                .coordinate_names()
                .iter()
                .map(|n| values[n].as_f64().unwrap())
                .collect();
            plan.forward_into(&q, &mut ws);
            for (link, v) in configuration["links"].as_object().unwrap() {
                let n: Vec<f64> = v.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()).collect();
                let k = tree.point_index(link).unwrap();
                let pose = ws.point_pose(k);
                let rotation = UnitQuaternion::from_quaternion(Quaternion::new(n[6], n[3], n[4], n[5]));
                let d = (pose.translation.vector - Vector3::new(n[0], n[1], n[2])).norm();
                let r = (rotation.to_rotation_matrix().matrix() - pose.rotation.matrix())
                    .abs()
                    .max();
                assert!(d < 1e-9 && r < 1e-9, "{file}, `{link}`: {d:e} m, {r:e} from pinocchio");
            }
        }
    }
}

/// Largest difference between the plan's pose Jacobian of point `k` and the tree's, and
/// between it and central differences of the plan's FK.
fn jacobian_errors(robot: &Robot, k: usize, q: &[f64]) -> (f64, f64) {
    let tree = robot.tree();
    let plan = robot.kinematics();
    let n = tree.nq();
    let mut ws = plan.workspace();
    plan.forward_into(q, &mut ws);
    let mut ours = Matrix6xX::zeros(n);
    plan.pose_jacobian_into(&ws, k, &mut ours);
    let mut full = TreeWorkspace::new(tree);
    tree.forward_into(q, &mut full);
    let mut theirs = Matrix6xX::zeros(n);
    tree.pose_jacobian_into(&full, plan.tree_points()[k], &mut theirs);
    let h = 1e-6;
    let mut fd_error: f64 = 0.0;
    for c in 0..n {
        let mut at = |dq: f64| {
            let mut qc = q.to_vec();
            qc[c] += dq;
            plan.forward_into(&qc, &mut ws);
            ws.point_pose(k)
        };
        let (plus, minus) = (at(h), at(-h));
        let v = (plus.translation.vector - minus.translation.vector) / (2.0 * h);
        // Angular velocity in world coordinates: log(R+ R-ᵀ) / 2h (through a quaternion, as
        // the matrix's own angle is an arccosine near 1).
        let turn = UnitQuaternion::from_rotation_matrix(&(plus.rotation * minus.rotation.inverse()));
        let w = turn.scaled_axis() / (2.0 * h);
        for r in 0..3 {
            fd_error = fd_error
                .max((ours[(r, c)] - v[r]).abs())
                .max((ours[(r + 3, c)] - w[r]).abs());
        }
    }
    ((ours - theirs).abs().max(), fd_error)
}

/// Mimic joints (Agile Justin's torso, TIAGo's gripper), prismatic ones (the rock-drill boom,
/// TIAGo's torso lift), a long tree (TALOS).
const VARIED: [&str; 5] = [
    "robots/agile-justin.toml",
    "robots/rock-drill.toml",
    "tests/data/urdf/tiago.urdf",
    "tests/data/urdf/ur5_robot.urdf",
    "robots/talos-left-arm.toml",
];

#[test]
fn path_jacobian_equals_the_trees_and_central_differences() {
    for path in VARIED {
        let robot = robot_at(path);
        for q in random_configurations(&robot, 3, 5) {
            for k in 0..robot.tree().points().len() {
                let (tree, fd) = jacobian_errors(&robot, k, &q);
                assert!(
                    tree < 1e-12 && fd < 1e-7,
                    "{path}, point {k}: {tree:e} from the tree's, {fd:e} from differences"
                );
            }
        }
    }
}

/// `n` random configurations of `robot`, row-major.
fn batch(robot: &Robot, n: usize, seed: u64) -> Vec<f64> {
    random_configurations(robot, n, seed).concat()
}

#[test]
fn batches_equal_single_calls_bit_for_bit() {
    // Lane counts of 4 and 8 both leave remainders among these sizes.
    for path in VARIED {
        let robot = robot_at(path);
        let plan = robot.kinematics();
        let (nq, np) = (plan.nq(), plan.tree_points().len());
        let mut single = plan.workspace();
        let mut many = plan.many_workspace();
        let mut jacobian = Matrix6xX::zeros(nq);
        for n in [0, 1, 3, 4, 5, 7, 8, 9, 13] {
            let qs = batch(&robot, n, n as u64);
            let mut poses = vec![IsometryMatrix3::identity(); n * np];
            plan.forward_many_into(n, &qs, &mut poses, &mut many).unwrap();
            let mut positions = vec![0.0; n * np * 3];
            plan.point_positions_many_into(n, &qs, &mut positions, &mut many)
                .unwrap();
            let k = np - 1;
            let mut jacobians = vec![0.0; n * 6 * nq];
            plan.pose_jacobian_many_into(n, &qs, k, &mut jacobians, &mut many)
                .unwrap();
            for (i, q) in qs.chunks_exact(nq).enumerate() {
                plan.forward_into(q, &mut single);
                for p in 0..np {
                    assert_eq!(
                        poses[i * np + p],
                        single.point_pose(p),
                        "{path}: n = {n}, {i}, point {p}"
                    );
                    let xyz = &positions[3 * (i * np + p)..3 * (i * np + p + 1)];
                    assert_eq!(
                        xyz,
                        single.point_position(p).as_slice(),
                        "{path}: n = {n}, {i}, point {p}"
                    );
                }
                plan.pose_jacobian_into(&single, k, &mut jacobian);
                assert_eq!(
                    &jacobians[i * 6 * nq..(i + 1) * 6 * nq],
                    jacobian.as_slice(),
                    "{path}: n = {n}, configuration {i}"
                );
            }
        }
    }
}

#[test]
fn robot_batches_run_the_full_model_configuration_by_configuration() {
    // With error models: the same values as the full model's single calls (the deformation
    // held in the Jacobian); rigid: the tree's FK to 1e-12.
    for (path, rigid) in [
        ("robots/industrial-6dof-truth.toml", false),
        ("robots/rock-drill-deflection.toml", false),
        ("robots/rock-drill.toml", true),
        ("robots/talos-left-arm.toml", true),
    ] {
        let robot = robot_at(path);
        assert_eq!(robot.error_models().is_empty(), rigid, "{path}");
        let tree = robot.tree();
        let (nq, np, n) = (tree.nq(), tree.points().len(), 6);
        let qs = batch(&robot, n, 3);
        let mut ws = robot.batch_workspace();
        let mut poses = vec![IsometryMatrix3::identity(); n * np];
        robot.forward_many_into(n, &qs, &mut poses, &mut ws).unwrap();
        let mut positions = vec![0.0; n * np * 3];
        robot
            .point_positions_many_into(n, &qs, &mut positions, &mut ws)
            .unwrap();
        let mut jacobians = vec![0.0; n * 6 * nq];
        robot
            .pose_jacobian_many_into(n, &qs, robot.tool(), &mut jacobians, &mut ws)
            .unwrap();
        let mut full = robot.workspace();
        let mut jacobian = Matrix6xX::zeros(nq);
        let tolerance = if rigid { 1e-12 } else { 0.0 };
        for (i, q) in qs.chunks_exact(nq).enumerate() {
            robot.forward_into(q, None, &mut full);
            for p in 0..np {
                let expected = matrix_form(&full.frames.point[p]);
                let (d, r) = pose_difference(&poses[i * np + p], &expected);
                assert!(
                    d <= tolerance && r <= tolerance,
                    "{path}: {i}, point {p}: {d:e} m, {r:e}"
                );
                let xyz = Vector3::from_column_slice(&positions[3 * (i * np + p)..3 * (i * np + p + 1)]);
                assert!(
                    (xyz - expected.translation.vector).norm() <= tolerance,
                    "{path}: {i}, point {p}"
                );
            }
            tree.pose_jacobian_into(&full.frames, robot.tool(), &mut jacobian);
            let got = Matrix6xX::from_column_slice(&jacobians[i * 6 * nq..(i + 1) * 6 * nq]);
            assert!((got - &jacobian).abs().max() <= tolerance, "{path}: Jacobian {i}");
        }
    }
}

#[test]
fn batch_calls_reject_wrong_sizes_points_and_values() {
    let robot = robot_at("robots/rock-drill.toml");
    let (nq, np) = (robot.tree().nq(), robot.tree().points().len());
    let qs = batch(&robot, 3, 1);
    let mut ws = robot.batch_workspace();
    let mut poses = vec![IsometryMatrix3::identity(); 3 * np];
    let err = robot
        .forward_many_into(3, &qs[..3 * nq - 1], &mut poses, &mut ws)
        .unwrap_err();
    assert!(
        matches!(err, Error::Dimension { expected, .. } if expected == 3 * nq),
        "{err}"
    );
    let err = robot.forward_many_into(3, &qs, &mut poses[1..], &mut ws).unwrap_err();
    assert!(matches!(err, Error::Dimension { .. }), "{err}");
    let mut bad = qs.clone();
    bad[nq + 1] = f64::NAN;
    let err = robot.forward_many_into(3, &bad, &mut poses, &mut ws).unwrap_err();
    assert!(err.to_string().contains("configuration 2"), "{err}");
    let mut jacobians = vec![0.0; 3 * 6 * nq];
    let err = robot
        .pose_jacobian_many_into(3, &qs, np, &mut jacobians, &mut ws)
        .unwrap_err();
    assert!(err.to_string().contains(&format!("point {np} does not exist")), "{err}");
    let err = PointKinematics::for_points(robot.tree(), &[np]).unwrap_err();
    assert!(err.to_string().contains(&format!("point {np} does not exist")), "{err}");
    // Nothing was written by the rejected calls.
    assert!(poses.iter().all(|p| *p == IsometryMatrix3::identity()));
}
