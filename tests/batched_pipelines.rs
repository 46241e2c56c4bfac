//! Simulation, planning and evaluation evaluate their poses through the batch calls (the
//! batched point kinematics on a rigid robot, the full model on one with error models): each
//! against the full model's single call per configuration (`Robot::forward_into`, checked
//! against hand calculations in `fk.rs`), to 1e-12 m on rigid robots, to the bit otherwise.

use armcomp_api::read_robot;
use armcomp_core::algorithms::evaluate::model_errors;
use armcomp_core::algorithms::plan::{Space, spread, trajectory_similar};
use armcomp_core::algorithms::simulate::{SimulateParams, simulate};
use armcomp_core::data::measurement::Sample;
use armcomp_core::model::sampling::Sampler;
use armcomp_core::support::io::InputLimits;
use armcomp_core::{Conditions, Error, Robot};
use nalgebra::{IsometryMatrix3, Matrix6xX, Vector3};

use crate::common::{random_configurations, robot, root};

/// Agile Justin (two arms, a marker on each) without its error models.
fn rigid_justin() -> Robot {
    let justin = robot("agile-justin.toml");
    let mut file = justin.to_file();
    file.error_models.clear();
    justin.rebuild(file).unwrap()
}

/// `(robot, rigid)`: rigid ones with several markers and with a point at every link (a bare
/// URDF), and ones with error models.
fn robots() -> Vec<(&'static str, Robot, bool)> {
    vec![
        ("rigid agile-justin", rigid_justin(), true),
        (
            "ur5 (bare URDF)",
            read_robot(&root().join("tests/data/urdf/ur5_robot.urdf"), InputLimits::default()).unwrap(),
            true,
        ),
        ("rock-drill", robot("rock-drill.toml"), true),
        ("agile-justin", robot("agile-justin.toml"), false),
        ("rock-drill-truth", robot("rock-drill-truth.toml"), false),
    ]
}

/// Position (m, base frame) of point `p` at `q` through the full model's single call.
fn full_model_position(robot: &Robot, q: &[f64], p: usize) -> Vector3<f64> {
    let mut ws = robot.workspace();
    robot.forward_into(q, None, &mut ws);
    ws.frames.point_position(p)
}

fn tolerance(rigid: bool) -> f64 {
    if rigid { 1e-12 } else { 0.0 }
}

#[test]
fn simulation_measures_every_marker_through_the_full_model() {
    for (name, r, rigid) in robots() {
        assert_eq!(r.error_models().is_empty(), rigid, "{name}");
        let poses = random_configurations(&r, 9, 5);
        let params = SimulateParams {
            noise_std: 0.0,
            seed: 1,
        };
        let set = simulate(&r, &poses, params).unwrap();
        assert_eq!(set.samples.len(), poses.len() * r.markers().len(), "{name}");
        let expected = (poses.iter().enumerate()).flat_map(|(i, q)| r.markers().iter().map(move |&m| (i, q, m)));
        assert_eq!(set.rows.len(), set.samples.len(), "{name}: a data row for every sample");
        for ((s, &row), (i, q, m)) in set.samples.iter().zip(&set.rows).zip(expected) {
            assert_eq!(
                (row, &s.q, s.point),
                (i, q, m),
                "{name}: a pose is a row, shared by its points"
            );
            let p = r.t_meas_base() * nalgebra::Point3::from(full_model_position(&r, q, m));
            let d = (s.position - p.coords).norm();
            assert!(d <= tolerance(rigid), "{name}: {d:e} m");
        }
        // A bad configuration is named, and nothing is simulated.
        let mut bad = poses.clone();
        bad[3][0] = f64::NAN;
        let err = simulate(&r, &bad, params).unwrap_err();
        assert!(err.to_string().contains("configuration 4"), "{name}: {err}");
    }
}

#[test]
fn planned_tool_positions_are_the_full_models() {
    for (name, r, rigid) in robots() {
        let plan = spread(&r, Space::Joint, Sampler::Sobol, 12, 2, &|q: &[f64]| q[0] > 0.0).unwrap();
        assert_eq!(plan.poses.len(), 12, "{name}");
        assert!(plan.rejected > 0, "{name}: the filter rejected some");
        for (q, p) in plan.poses.iter().zip(&plan.tool_positions) {
            assert!(q[0] > 0.0, "{name}");
            let d = (p - full_model_position(&r, q, r.tool())).norm();
            assert!(d <= tolerance(rigid), "{name}: {d:e} m");
        }
        // The trajectory's tool path: a pool whose positions are the trajectory's own tool
        // positions, one per trajectory point, is picked back in order.
        let trajectory = random_configurations(&r, 5, 8);
        let pool: Vec<Vector3<f64>> = trajectory
            .iter()
            .map(|q| full_model_position(&r, q, r.tool()))
            .collect();
        let chosen = trajectory_similar(&r, &trajectory, &pool, 2, 1).unwrap();
        assert_eq!(chosen, [0, 4], "{name}");
    }
}

/// A sample measuring point `point` at `q`, at a made-up measured position.
fn sample(q: &[f64], point: usize, k: usize) -> Sample {
    Sample {
        q: q.to_vec(),
        point,
        position: Vector3::new(0.1 * k as f64, -0.2, 0.3 + 0.01 * k as f64),
        orientation: None,
        payload: None,
        temperature: None,
        torque: None,
        fixed_point: None,
        plane: None,
        sensors: Default::default(),
        station: 0,
        position_std: None,
    }
}

#[test]
fn model_errors_are_the_full_models_in_any_sample_order() {
    for (name, r, rigid) in robots() {
        let poses = random_configurations(&r, 300, 6);
        let (tool, markers) = (r.tool(), r.markers());
        // Markers of one pose side by side, a pose measured again later, points in any order,
        // more configurations than one pass holds.
        let mut samples = Vec::new();
        for (i, q) in poses.iter().enumerate() {
            for &m in markers.iter().rev() {
                samples.push(sample(q, m, samples.len()));
            }
            if i % 7 == 3 {
                samples.push(sample(&poses[i / 2], tool, samples.len()));
                samples.push(sample(q, tool, samples.len()));
            }
        }
        let errors = model_errors(&r, &samples);
        assert_eq!(errors.len(), samples.len());
        let mut ws = r.workspace();
        for (s, e) in samples.iter().zip(&errors) {
            let expected = s.position - r.measured_position(&s.q, s.point, Conditions::of(s), &mut ws);
            let d = (e - expected).norm();
            assert!(d <= tolerance(rigid), "{name}: {d:e} m");
        }
        assert!(model_errors(&r, &[]).is_empty());
    }
}

#[test]
fn batches_of_some_points_write_those_points_in_their_order() {
    for (name, r, rigid) in robots() {
        let tree = r.tree();
        let (nq, n) = (tree.nq(), 6);
        let some = [r.tool(), 0];
        let mut ws = r.batch_workspace_for(&some).unwrap();
        let poses_q = random_configurations(&r, n, 4);
        let qs = poses_q.concat();
        let mut poses = vec![IsometryMatrix3::identity(); n * some.len()];
        r.forward_many_into(n, &qs, &mut poses, &mut ws).unwrap();
        let mut positions = vec![0.0; 3 * n * some.len()];
        r.point_positions_many_into(n, &qs, &mut positions, &mut ws).unwrap();
        let mut jacobians = vec![0.0; 6 * nq * n];
        r.pose_jacobian_many_into(n, &qs, 1, &mut jacobians, &mut ws).unwrap();
        let mut full = r.workspace();
        let mut jacobian = Matrix6xX::zeros(nq);
        for (i, q) in poses_q.iter().enumerate() {
            r.forward_into(q, None, &mut full);
            for (k, &p) in some.iter().enumerate() {
                let expected = &full.frames.point[p];
                let pose = &poses[i * some.len() + k];
                let d = (pose.translation.vector - expected.translation.vector).norm();
                let dr = (pose.rotation.matrix() - expected.rotation.to_rotation_matrix().matrix())
                    .abs()
                    .max();
                assert!(
                    d <= tolerance(rigid) && dr <= tolerance(rigid),
                    "{name}: {d:e} m, {dr:e}"
                );
                let at = 3 * (i * some.len() + k);
                let xyz = Vector3::from_column_slice(&positions[at..at + 3]);
                assert!((xyz - expected.translation.vector).norm() <= tolerance(rigid), "{name}");
            }
            tree.pose_jacobian_into(&full.frames, 0, &mut jacobian);
            let got = Matrix6xX::from_column_slice(&jacobians[i * 6 * nq..(i + 1) * 6 * nq]);
            assert!(
                (got - &jacobian).abs().max() <= tolerance(rigid),
                "{name}: Jacobian {i}"
            );
        }
        // The workspace has two points: a third does not exist, nor does a point beyond the
        // tree's.
        let err = r
            .pose_jacobian_many_into(n, &qs, 2, &mut jacobians, &mut ws)
            .unwrap_err();
        assert!(err.to_string().contains("point 2 does not exist"), "{name}: {err}");
        let np = tree.points().len();
        let err = r.batch_workspace_for(&[np]).unwrap_err();
        assert!(matches!(err, Error::InvalidArgument { .. }), "{name}: {err}");
    }
}
