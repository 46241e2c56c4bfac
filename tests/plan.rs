//! Pose planning: optimal designs against direct and hand-computed optima, collision-free
//! choices, Cartesian sets through IK, trajectory similarity.

use std::process::Command;

use armcomp_core::CollisionModel;
use armcomp_core::algorithms::plan::{Space, resample_by_arc_length, spread, trajectory_similar};
use armcomp_core::analysis::design::{
    Criterion, Design, SelectionParams, optimal_subset, pose_candidates, select_poses,
};
use armcomp_core::calibrate::{ParameterSpace, identification_jacobian};
use armcomp_core::model::sampling::{Sampler, configurations};
use armcomp_core::support::io::InputLimits;
use nalgebra::{DMatrix, Vector3};

use crate::common::robots::PENDULUM;
use crate::common::{Scratch, robot, robot_from_toml, root};

const ALL: fn(&[f64]) -> bool = |_| true;

#[test]
fn d_optimal_value_matches_a_direct_determinant_and_beats_sobol() {
    let r = robot("industrial-6dof.toml");
    // Geometry only: every parameter has a prior, so the scaling is the priors' alone.
    let identify = vec!["j2.*".to_string(), "j3.*".to_string(), "j5.*".to_string()];
    let pool = configurations(r.tree(), Sampler::Sobol, 120, 1).unwrap();
    let params = SelectionParams {
        identify: identify.clone(),
        ..SelectionParams::default()
    };
    let report = select_poses(&r, &pose_candidates(&r, &pool), 12, &[], &[], &params).unwrap();
    let chosen = &report.chosen;
    assert_eq!(chosen.len(), 12);
    let mut unique = chosen.clone();
    unique.sort();
    unique.dedup();
    assert_eq!(unique.len(), 12, "a pose was picked twice");
    assert!(report.value >= report.greedy_value, "exchanges never make it worse");

    // Independent: log det(I + Σ JᵢᵀJᵢ) with J in noise units per prior standard deviation.
    let sigma = params.measurement_std;
    let log_det = |poses: &[Vec<f64>]| {
        let (jac, names) = identification_jacobian(&r, poses, &identify).unwrap();
        let space = ParameterSpace::new(&r);
        let prior: Vec<f64> = names
            .iter()
            .map(|n| space.params[space.index(n).unwrap()].info.sigma)
            .collect();
        let j = DMatrix::from_fn(jac.nrows(), jac.ncols(), |i, k| jac[(i, k)] * prior[k] / sigma);
        let m = DMatrix::identity(j.ncols(), j.ncols()) + j.transpose() * &j;
        2.0 * m.cholesky().unwrap().l().diagonal().map(f64::ln).sum()
    };
    let chosen_poses: Vec<Vec<f64>> = chosen.iter().map(|&i| pool[i].clone()).collect();
    let direct = log_det(&chosen_poses);
    assert!(
        (direct - report.value).abs() < 1e-8 * direct.abs().max(1.0),
        "{direct} vs {}",
        report.value
    );
    // More information than the first 12 Sobol poses of the same pool.
    let sobol = log_det(&pool[..12]);
    assert!(direct > sobol + 1.0, "D-optimal {direct} vs Sobol {sobol}");
}

/// The pendulum (a 1 m link swinging in a vertical plane, 10 kg at `r` = 0.8 m, limits
/// −30° … 180°, the tool at the tip) on a compliant joint, `extra` appended. Joint offset `δ`
/// and compliance `c` both move the tool along the circle's tangent: by `L δ` and by
/// `L c τ(q)` with the gravity torque `τ = −m g r cos q`, so the measurement is linear in
/// `(δ, c)` with regressor `(1, cos q)`.
fn pendulum(extra: &str) -> String {
    format!("{PENDULUM}[[error_models]]\ntype = \"joint_compliance\"\ncompliance = {{ j1 = 0.0 }}\n{extra}")
}

/// Every 5° over the pendulum's range, as a poses CSV.
fn pendulum_grid() -> (Vec<f64>, String) {
    let degrees: Vec<f64> = (0..=42).map(|k| -30.0 + 5.0 * f64::from(k)).collect();
    let mut csv = String::from("j1[deg]\n");
    for d in &degrees {
        csv.push_str(&format!("{d}\n"));
    }
    (degrees, csv)
}

#[test]
fn d_optimal_picks_the_ends_of_the_regressor_range_through_the_compliance_model() {
    // For y = a + b x with x = cos q, the D-optimal pair maximises (x₁ − x₂)²: x = 1 (q = 0°)
    // and x = −1 (q = 180°). The compliance column exists only through the deformed model.
    let r = robot_from_toml(&pendulum(""));
    let (degrees, _) = pendulum_grid();
    let poses: Vec<Vec<f64>> = degrees.iter().map(|d| vec![d.to_radians()]).collect();
    let pool = pose_candidates(&r, &poses);
    let identify = vec!["j1.theta".to_string(), "joint_compliance".to_string()];
    let params = SelectionParams {
        identify: identify.clone(),
        ..SelectionParams::default()
    };
    let report = select_poses(&r, &pool, 2, &[], &[], &params).unwrap();
    let mut picked: Vec<f64> = report.chosen.iter().map(|&i| degrees[i]).collect();
    picked.sort_by(f64::total_cmp);
    assert_eq!(picked, [0.0, 180.0]);
    assert_eq!(report.params, ["j1.theta", "joint_compliance.j1"]);
    // Both parameters determined: the identifiability report of the pair says so.
    assert_eq!(report.identifiability.rank, 2, "{:?}", report.identifiability);
    // Online: after measuring q = 0° (x = 1) alone, the next pose is x = −1.
    let measured = pool[degrees.iter().position(|d| *d == 0.0).unwrap()].clone();
    let next = select_poses(&r, &pool, 1, &measured, &[], &params).unwrap();
    assert_eq!(degrees[next.chosen[0]], 180.0);
    // ... and so for the predicted error over the range: (1, x) is best pinned down where
    // measured at both ends.
    let uncertainty = SelectionParams {
        criterion: Criterion::Uncertainty,
        ..params
    };
    let next = select_poses(&r, &pool, 1, &measured, &[], &uncertainty).unwrap();
    assert_eq!(degrees[next.chosen[0]], 180.0);
    assert!(next.workspace_std_after < next.workspace_std_before);
}

/// The design `y = a + b x` with ten candidates at x = 0 and ten at x = 1, one row each.
fn two_point_design(criterion: Criterion) -> Design {
    let xs: Vec<f64> = [0.0; 10].into_iter().chain([1.0; 10]).collect();
    Design {
        rows: DMatrix::from_fn(20, 2, |i, k| if k == 0 { 1.0 } else { xs[i] }),
        offsets: (0..=20).collect(),
        start: DMatrix::identity(2, 2) * 1e-9,
        weight: match criterion {
            Criterion::DOptimal | Criterion::AOptimal => DMatrix::identity(2, 2),
            Criterion::Uncertainty => unreachable!("not used here"),
        },
    }
}

#[test]
fn d_and_a_optimal_designs_of_a_straight_line_match_the_hand_calculation() {
    // With k of n = 10 points at x = 0: M = [[n, n−k], [n−k, n−k]], det M = k (n − k), largest
    // at k = 5; trace M⁻¹ = (2n − k) / (k (n − k)) = 15/25, 14/24, 13/21 for k = 5, 6, 7:
    // smallest at k = 6 (the continuous optimum puts 2 − √2 ≈ 0.586 of the points at x = 0).
    for (criterion, at_zero, value) in [
        (Criterion::DOptimal, 5, 25f64.ln()),
        (Criterion::AOptimal, 6, 14.0 / 24.0),
    ] {
        let design = two_point_design(criterion);
        let report = optimal_subset(&design, 10, criterion, 10).unwrap();
        let zeros = report.chosen.iter().filter(|&&i| i < 10).count();
        assert_eq!(zeros, at_zero, "{criterion:?}: {:?}", report.chosen);
        assert!(
            (report.value - value).abs() < 1e-6,
            "{criterion:?}: {} vs {value}",
            report.value
        );
        // Greedy alone: the first pick goes to the lower index on ties, the exchanges repair it.
        let greedy = optimal_subset(&design, 10, criterion, 0).unwrap();
        assert_eq!(greedy.value, greedy.greedy_value);
    }
}

#[test]
fn plan_never_picks_a_colliding_pose() {
    // A post where the pendulum's tip would be at 150° … 180°.
    let dir = Scratch::new("plan-collide");
    let text = pendulum(
        r#"
[[fixtures]]
name = "post"
geometry = { shape = "box", size = [0.3, 0.6, 0.3] }
xyz = [-1.0, 0.3, 0.0]
"#,
    );
    let robot_file = dir.file("pendulum.toml", &text);
    let r = robot_from_toml(&text);
    let collision = CollisionModel::new(r.tree(), r.collision());
    let mut ws = collision.workspace();
    let (degrees, csv) = pendulum_grid();
    let colliding: Vec<f64> = degrees
        .iter()
        .copied()
        .filter(|d| collision.collides(&[d.to_radians()], &mut ws))
        .collect();
    assert!(colliding.contains(&180.0) && colliding.len() < 10, "{colliding:?}");
    let pool = dir.file("pool.csv", &csv);
    let measured = dir.file("measured.csv", "j1[deg],x[m],y[m],z[m]\n0,1,0,0\n");
    let bin = env!("CARGO_BIN_EXE_armcomp");
    let run = |extra: &[&str]| {
        let out = dir.0.join("out.csv");
        let _ = std::fs::remove_file(&out);
        let status = Command::new(bin)
            .args(["plan", "--robot"])
            .arg(&robot_file)
            .args(["--identify", "j1.theta,joint_compliance", "--out"])
            .arg(&out)
            .args(extra)
            .output()
            .unwrap();
        assert!(status.status.success(), "{}", String::from_utf8_lossy(&status.stderr));
        let text = std::fs::read_to_string(&out).unwrap();
        armcomp_core::data::measurement::parse_poses(&text, "out.csv".as_ref(), &r.csv_layout()).unwrap()
    };
    let pool_arg = pool.to_str().unwrap();
    let measured_arg = measured.to_str().unwrap();
    for extra in [
        vec!["--method", "d-optimal", "--n", "2", "--pool", pool_arg],
        vec!["--method", "a-optimal", "--n", "4", "--pool", pool_arg],
        vec![
            "--method",
            "d-optimal",
            "--n",
            "3",
            "--pool-sampler",
            "grid",
            "--pool",
            "60",
        ],
        vec!["--next", "2", "--measured", measured_arg, "--pool", pool_arg],
    ] {
        let poses = run(&extra);
        assert!(!poses.is_empty());
        for q in &poses {
            assert!(
                !collision.collides(q, &mut ws),
                "{extra:?} picked {:.1}°",
                q[0].to_degrees()
            );
        }
        // The free end of the range is still taken: the collision filter, not chance, kept
        // the post's poses out.
        let top = poses.iter().map(|q| q[0].to_degrees()).fold(f64::MIN, f64::max);
        assert!(top > 100.0, "{extra:?}: {poses:?}");
    }
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
    for method in ["a-optimal", "uncertainty"] {
        assert_eq!(run("a.csv", method), run("b.csv", method), "{method}");
    }
    let a = run("a.csv", "d-optimal");
    let b = run("b.csv", "d-optimal");
    assert_eq!(a, b);
    let r = robot("industrial-6dof.toml");
    let poses = armcomp_core::data::measurement::parse_poses(&a, "a.csv".as_ref(), &r.csv_layout()).unwrap();
    assert_eq!(poses.len(), 15);
    let halton = run("c.csv", "halton");
    assert_ne!(halton, a);
}

#[test]
fn retrospective_selection_names_rows_that_calibrate_reads() {
    // TALOS' 31 interleaved training rows as the pool: the chosen rows come back as data rows
    // of the file (for `calibrate --rows`) and as a measurement CSV holding exactly those rows.
    let dir = Scratch::new("plan-rows");
    let bin = env!("CARGO_BIN_EXE_armcomp");
    let r = robot("talos-left-arm.toml");
    let data = root().join("data/talos-left-arm/measurements.csv");
    let all = armcomp_core::data::measurement::read_csv(&data, &r.csv_layout(), InputLimits::default()).unwrap();
    let train = all.select_rows(&"even".parse().unwrap());
    let pool = dir.file(
        "train.csv",
        &armcomp_core::data::measurement::write_csv(&train, r.tree(), r.units()),
    );
    let out = dir.0.join("chosen.csv");
    let output = Command::new(bin)
        .args(["plan", "--robot"])
        .arg(root().join("robots/talos-left-arm.toml"))
        .args([
            "--method",
            "d-optimal",
            "--n",
            "15",
            "--identify",
            "base,markers,offsets",
            "--json",
            "--pool",
        ])
        .arg(&pool)
        .arg("--out")
        .arg(&out)
        .output()
        .unwrap();
    assert!(output.status.success(), "{}", String::from_utf8_lossy(&output.stderr));
    let report: serde_json::Value = serde_json::from_slice(&output.stdout).unwrap();
    let rows: Vec<usize> = serde_json::from_value(report["rows"].clone()).unwrap();
    assert_eq!(rows.len(), 15);
    assert!(report["identifiability"]["n_params"].as_u64().unwrap() == 18);
    // The pool file's row k is the data file's row 2k.
    let written = armcomp_core::data::measurement::read_csv(&out, &r.csv_layout(), InputLimits::default()).unwrap();
    for (k, &row) in rows.iter().enumerate() {
        assert_eq!(written.samples[k], all.samples[2 * row], "row {row}");
    }
    // The row list is a valid `--rows` argument selecting the same samples of the pool.
    let list: Vec<String> = rows.iter().map(|r| r.to_string()).collect();
    let pool_set = armcomp_core::data::measurement::read_csv(&pool, &r.csv_layout(), InputLimits::default()).unwrap();
    let again = pool_set.select_rows(&list.join(",").parse().unwrap());
    assert_eq!(again.samples.len(), 15);
    assert!(again.samples.iter().all(|s| written.samples.contains(s)));
}
