//! Pose planning: D-optimal information, Cartesian sets through IK, trajectory similarity.

use std::process::Command;

use armcomp_core::calibrate::identification_jacobian;
use armcomp_core::plan::{Space, d_optimal, information_log_det, resample_by_arc_length, spread, trajectory_similar};
use armcomp_core::sampling::{Sampler, configurations};
use nalgebra::{DMatrix, Vector3};

use crate::common::{Scratch, robot, root};

const ALL: fn(&[f64]) -> bool = |_| true;

#[test]
fn d_optimal_gain_bookkeeping_matches_a_direct_determinant_and_beats_sobol() {
    let r = robot("industrial-6dof.toml");
    let identify = vec!["j2.*".to_string(), "j3.*".to_string(), "j5.*".to_string()];
    let pool = configurations(r.tree(), Sampler::Sobol, 120, 1).unwrap();
    let (chosen, log_det) = d_optimal(&r, &pool, 12, &identify).unwrap();
    assert_eq!(chosen.len(), 12);
    let mut unique = chosen.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), 12, "a pose was picked twice");

    // Independent: log det(εI + Σ JᵢᵀJᵢ) of the chosen poses with the pool's column scaling.
    let (jac, _) = identification_jacobian(&r, &pool, &identify).unwrap();
    let scales: Vec<f64> = jac.column_iter().map(|c| c.norm()).collect();
    let (sel, _) = identification_jacobian(
        &r,
        &chosen.iter().map(|&i| pool[i].clone()).collect::<Vec<_>>(),
        &identify,
    )
    .unwrap();
    let sel = DMatrix::from_fn(sel.nrows(), sel.ncols(), |i, k| sel[(i, k)] / scales[k]);
    let mut m = sel.transpose() * &sel;
    for i in 0..m.nrows() {
        m[(i, i)] += 1e-6;
    }
    let direct = 2.0 * m.cholesky().unwrap().l().diagonal().map(f64::ln).sum();
    assert!(
        (direct - log_det).abs() < 1e-6 * direct.abs().max(1.0),
        "{direct} vs {log_det}"
    );

    // More information than the first 12 Sobol poses of the same pool.
    let sobol: Vec<Vec<f64>> = pool[..12].to_vec();
    let chosen_poses: Vec<Vec<f64>> = chosen.iter().map(|&i| pool[i].clone()).collect();
    let d = information_log_det(&r, &chosen_poses, &identify).unwrap();
    let s = information_log_det(&r, &sobol, &identify).unwrap();
    assert!(d > s + 1.0, "D-optimal {d} vs Sobol {s}");
}

#[test]
fn cartesian_sets_reach_their_targets_inside_the_workspace_box() {
    let r = robot("rock-drill.toml");
    let plan = spread(&r, Space::Cartesian, Sampler::Halton, 20, 3, &ALL).unwrap();
    assert_eq!(plan.poses.len(), 20);
    let mut ws = r.workspace();
    for (q, target) in plan.poses.iter().zip(&plan.tool_positions) {
        r.tree().check_q(q).unwrap();
        for (v, l) in q.iter().zip(r.tree().coordinate_limits()) {
            let l = l.unwrap();
            assert!(*v >= l.lower - 1e-12 && *v <= l.upper + 1e-12);
        }
        r.forward_into(q, None, &mut ws);
        let err = (ws.frames.point_position(r.tool()) - target).norm();
        assert!(err < 1e-6, "IK missed its target by {err} m");
    }
    // A filter that rejects everything leaves nothing and says so.
    let none = spread(&r, Space::Joint, Sampler::Sobol, 5, 0, &|_| false).unwrap();
    assert!(none.poses.is_empty() && none.rejected == 100);
}

#[test]
fn arc_length_resampling_of_an_l_shaped_path() {
    // 3 m along x then 1 m along y: 5 points every 1 m.
    let path = [
        Vector3::new(0.0, 0.0, 0.0),
        Vector3::new(3.0, 0.0, 0.0),
        Vector3::new(3.0, 1.0, 0.0),
    ];
    let pts = resample_by_arc_length(&path, 5);
    let expected = [[0.0, 0.0], [1.0, 0.0], [2.0, 0.0], [3.0, 0.0], [3.0, 1.0]];
    for (p, e) in pts.iter().zip(expected) {
        assert!(
            (p.x - e[0]).abs() < 1e-12 && (p.y - e[1]).abs() < 1e-12,
            "{p:?} vs {e:?}"
        );
    }
}

#[test]
fn trajectory_similar_picks_the_nearest_unused_pool_points() {
    let r = robot("industrial-6dof.toml");
    let pool = spread(&r, Space::Joint, Sampler::Sobol, 200, 4, &ALL).unwrap();
    let trajectory = configurations(r.tree(), Sampler::Random, 6, 9).unwrap();
    let chosen = trajectory_similar(&r, &trajectory, &pool.tool_positions, 4, 5).unwrap();
    assert_eq!(chosen.len(), 20);
    let mut ws = r.workspace();
    let path: Vec<Vector3<f64>> = trajectory
        .iter()
        .map(|q| {
            r.forward_into(q, None, &mut ws);
            ws.frames.point_position(r.tool())
        })
        .collect();
    // Brute force: the first trajectory point is the path's start; its 5 nearest pool points
    // are the first 5 chosen.
    let mut by_distance: Vec<usize> = (0..pool.tool_positions.len()).collect();
    by_distance.sort_by(|&a, &b| {
        (pool.tool_positions[a] - path[0])
            .norm()
            .total_cmp(&(pool.tool_positions[b] - path[0]).norm())
    });
    assert_eq!(chosen[..5], by_distance[..5]);
    let mut unique = chosen.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), 20, "pool points are used once");
    assert!(trajectory_similar(&r, &trajectory, &pool.tool_positions, 50, 10).is_err());
}

#[test]
fn plan_cli_is_deterministic_and_reads_back_as_poses() {
    let dir = Scratch::new("plan");
    let bin = env!("CARGO_BIN_EXE_armcomp");
    let robot_file = root().join("robots/industrial-6dof.toml");
    let run = |out: &str, method: &str| {
        let status = Command::new(bin)
            .args(["plan", "--robot"])
            .arg(&robot_file)
            .args(["--n", "15", "--method", method, "--seed", "7", "--out"])
            .arg(dir.0.join(out))
            .output()
            .unwrap();
        assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
        std::fs::read_to_string(dir.0.join(out)).unwrap()
    };
    let a = run("a.csv", "d-optimal");
    let b = run("b.csv", "d-optimal");
    assert_eq!(a, b);
    let r = robot("industrial-6dof.toml");
    let poses = armcomp_core::measurement::parse_poses(&a, "a.csv".as_ref(), &r.csv_layout()).unwrap();
    assert_eq!(poses.len(), 15);
    let halton = run("c.csv", "halton");
    assert_ne!(halton, a);
}
