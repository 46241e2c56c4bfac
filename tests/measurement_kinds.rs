//! Measurement kinds as residual blocks: pose rows (position and orientation) against simulated
//! truths, finite differences and the normal equations.

use armcomp_core::Robot;
use armcomp_core::calibrate::{CalibrationParams, ParameterSpace, calibrate, samples_jacobian};
use armcomp_core::data::measurement::{Sample, parse_csv};
use armcomp_core::model::sampling::{Sampler, configurations};
use armcomp_core::robot::Conditions;
use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, Normal};

use crate::common::{robot_from_toml, root};

/// The rock drill measured as poses (a 6-DoF probe on the drill bit), with `extra` appended.
fn pose_robot(extra: &str) -> Robot {
    let text = std::fs::read_to_string(root().join("robots/rock-drill.toml")).unwrap();
    let text = text.replacen("[measurement]", "[measurement]\nkind = \"pose\"", 1);
    robot_from_toml(&format!("{text}{extra}"))
}

/// The measured pose of the tool through `robot`'s full model and measurement frame.
fn model_pose(robot: &Robot, q: &[f64]) -> Isometry3<f64> {
    let mut ws = robot.workspace();
    let point = robot.markers()[0];
    robot.forward_with_into(robot.tree(), robot.error_values(), q, Conditions::default(), &mut ws);
    robot.t_meas_base() * ws.frames.point[point]
}

/// Pose samples of `truth` at `n` configurations with Gaussian noise: `sigma_p` (m) per axis on
/// the position, a turn of `sigma_r` (rad) per axis on the orientation.
fn pose_samples(truth: &Robot, n: usize, sigma_p: f64, sigma_r: f64, seed: u64) -> Vec<Sample> {
    let mut rng = StdRng::seed_from_u64(seed);
    let (np, nr) = (Normal::new(0.0, sigma_p).unwrap(), Normal::new(0.0, sigma_r).unwrap());
    configurations(truth.tree(), Sampler::Sobol, n, seed)
        .unwrap()
        .into_iter()
        .map(|q| {
            let pose = model_pose(truth, &q);
            let dp = Vector3::from_fn(|_, _| np.sample(&mut rng));
            let dr = Vector3::from_fn(|_, _| nr.sample(&mut rng));
            Sample {
                point: truth.markers()[0],
                position: pose.translation.vector + dp,
                orientation: Some(UnitQuaternion::from_scaled_axis(dr) * pose.rotation),
                payload: None,
                temperature: None,
                torque: None,
                fixed_point: None,
                plane: None,
                sensors: Default::default(),
                station: 0,
                q,
                position_std: None,
            }
        })
        .collect()
}

/// A truth: `nominal` with the named parameters moved (SI).
fn truth_of(nominal: &Robot, changes: &[(&str, f64)]) -> Robot {
    let space = ParameterSpace::new(nominal);
    let mut theta = space.initial();
    for (name, delta) in changes {
        theta[space.index(name).unwrap_or_else(|| panic!("no parameter {name}"))] += delta;
    }
    space.apply(nominal, &theta).unwrap()
}

/// The residuals of pose samples as calibration stacks them, positions first (m) then
/// orientations (`log(R_measᵀ R̂)`, rad), through a robot rebuilt from its file.
fn stacked_residuals(robot: &Robot, samples: &[Sample]) -> Vec<f64> {
    let poses: Vec<Isometry3<f64>> = samples.iter().map(|s| model_pose(robot, &s.q)).collect();
    let positions = poses
        .iter()
        .zip(samples)
        .flat_map(|(p, s)| (p.translation.vector - s.position).data.0[0]);
    let turns = poses.iter().zip(samples).flat_map(|(p, s)| {
        let r = (s.orientation.unwrap().inverse() * p.rotation).scaled_axis();
        r.data.0[0]
    });
    positions.chain(turns).collect()
}

/// A robot, a relative tolerance, and parameters with their finite-difference steps.
type JacobianCase<'a> = (Robot, f64, &'a [(&'a str, f64)]);

#[test]
fn the_pose_jacobian_matches_finite_differences_of_the_full_model() {
    let compliant = "\n[[error_models]]\ntype = \"cantilever_deflection\"\n\n[[error_models]]\ntype = \"joint_compliance\"\ncompliance = { j2 = 2e-5, j5 = 3e-5 }\n";
    let cases: [JacobianCase; 2] = [
        (
            pose_robot(""),
            1e-6,
            &[
                ("j2.a", 1e-6),
                ("j3.alpha", 1e-6),
                ("j6.d", 1e-6),
                ("base.roll", 1e-6),
                ("base.yaw", 1e-6),
                ("marker.tool.y", 1e-6),
                ("marker.tool.rx", 1e-6),
                ("marker.tool.rz", 1e-6),
            ],
        ),
        (
            pose_robot(compliant),
            1e-4,
            &[
                ("j2.a", 1e-6),
                ("j5.theta", 1e-6),
                ("cantilever.boom.ei_scale", 1e-5),
                ("joint_compliance.j5", 1e-8),
                ("marker.tool.ry", 1e-6),
            ],
        ),
    ];
    for (robot, tol, params) in &cases {
        // Measured orientations 0.4 rad away from the model's, so that the residual's own
        // curvature (the inverse right Jacobian) matters.
        let mut samples = pose_samples(robot, 10, 0.0, 0.0, 3);
        let turn = UnitQuaternion::from_scaled_axis(Vector3::new(0.2, -0.3, 0.15));
        for s in &mut samples {
            s.orientation = Some(turn * s.orientation.unwrap());
        }
        let space = ParameterSpace::new(robot);
        for (name, h) in params.iter() {
            let (jac, _) = samples_jacobian(robot, &samples, &[name.to_string()]).unwrap();
            assert_eq!(
                jac.nrows(),
                6 * samples.len(),
                "three position and three orientation rows a sample"
            );
            let k = space.index(name).unwrap();
            let at = |d: f64| {
                let mut theta = space.initial();
                theta[k] += d;
                stacked_residuals(&space.apply(robot, &theta).unwrap(), &samples)
            };
            let (plus, minus) = (at(*h), at(-*h));
            let fd: Vec<f64> = plus.iter().zip(&minus).map(|(a, b)| (a - b) / (2.0 * h)).collect();
            for block in [0..3 * samples.len(), 3 * samples.len()..6 * samples.len()] {
                let scale = fd[block.clone()].iter().fold(0.0f64, |m, v| m.max(v.abs()));
                for i in block {
                    assert!(
                        (jac[(i, 0)] - fd[i]).abs() <= tol * scale.max(1e-9),
                        "{name} row {i}: Jacobian {} vs finite differences {} (scale {scale})",
                        jac[(i, 0)],
                        fd[i]
                    );
                }
            }
        }
    }
}

/// The same pose rows written in each spelling: quaternion (and its negative), rotation vector
/// in degrees, roll-pitch-yaw in radians.
fn spelled(robot: &Robot, samples: &[Sample], spelling: &str) -> String {
    let joints: Vec<String> = robot.tree().coordinate_names().iter().map(|n| n.to_string()).collect();
    let (cols, unit): (&[&str], &str) = match spelling {
        "quaternion" | "negated" => (&["qw", "qx", "qy", "qz"], ""),
        "rotation_vector" => (&["rx", "ry", "rz"], "[deg]"),
        _ => (&["roll", "pitch", "yaw"], "[rad]"),
    };
    let mut text = format!(
        "{},x[m],y[m],z[m],{}\n",
        joints
            .iter()
            .zip(robot.tree().coordinate_is_prismatic())
            .map(|(j, prismatic)| format!("{j}[{}]", if *prismatic { "m" } else { "rad" }))
            .collect::<Vec<_>>()
            .join(","),
        cols.iter().map(|c| format!("{c}{unit}")).collect::<Vec<_>>().join(",")
    );
    for s in samples {
        let q = s.orientation.unwrap();
        let angles: Vec<f64> = match spelling {
            "quaternion" => vec![q.w, q.i, q.j, q.k],
            "negated" => vec![-q.w, -q.i, -q.j, -q.k],
            "rotation_vector" => q.scaled_axis().iter().map(|v| v.to_degrees()).collect(),
            _ => {
                let (r, p, y) = q.euler_angles();
                vec![r, p, y]
            }
        };
        let row: Vec<String> =
            s.q.iter()
                .chain(s.position.iter())
                .chain(angles.iter())
                .map(|v| format!("{v:e}"))
                .collect();
        text.push_str(&row.join(","));
        text.push('\n');
    }
    text
}

#[test]
fn quaternion_signs_and_the_three_orientation_spellings_give_the_same_fit() {
    let nominal = pose_robot("");
    let truth = truth_of(
        &nominal,
        &[("j2.a", 2e-3), ("j4.alpha", 1e-3), ("marker.tool.rz", 0.02)],
    );
    let samples = pose_samples(&truth, 30, 5e-5, 2e-4, 7);
    let params = CalibrationParams {
        measurement_std: 5e-5,
        orientation_std: 2e-4,
        ..CalibrationParams::default()
    };
    let mut fits: Vec<(String, Vec<(f64, f64)>)> = Vec::new();
    for spelling in ["quaternion", "negated", "rotation_vector", "roll_pitch_yaw"] {
        let text = spelled(&nominal, &samples, spelling);
        let set = parse_csv(&text, "poses.csv".as_ref(), &nominal.csv_layout()).unwrap();
        for (read, s) in set.samples.iter().zip(&samples) {
            let angle = read.orientation.unwrap().angle_to(&s.orientation.unwrap());
            assert!(angle < 1e-9, "{spelling}: read {angle} rad away from what was written");
        }
        let fit = calibrate(&nominal, &set.samples, &params, &mut |_| {}).unwrap();
        fits.push((
            spelling.into(),
            fit.report.params.iter().map(|p| (p.value, p.std)).collect(),
        ));
    }
    // Spellings differ by round-off in the last digits of the orientations; the fits by no more
    // than a thousandth of each parameter's standard deviation (a sign flip not at all).
    let (_, reference) = &fits[0];
    for (spelling, values) in &fits[1..] {
        for ((a, _), (b, std)) in values.iter().zip(reference) {
            let tol = if spelling == "negated" { 0.0 } else { 1e-3 * std };
            assert!((a - b).abs() <= tol, "{spelling}: {a} vs {b} (std {std})");
        }
    }
}

#[test]
fn doubling_the_orientation_noise_divides_its_weight_by_four() {
    let nominal = pose_robot("");
    let samples = pose_samples(&truth_of(&nominal, &[("j3.a", 1e-3)]), 20, 5e-5, 2e-4, 11);
    // No iteration: both linearisations are at the same parameters, the robot's values.
    let normal = |orientation_std: f64| {
        let params = CalibrationParams {
            measurement_std: 5e-5,
            orientation_std,
            max_iterations: 0,
            restarts: 0,
            start: Some(ParameterSpace::new(&nominal).initial()),
            ..CalibrationParams::default()
        };
        let lin = calibrate(&nominal, &samples, &params, &mut |_| {})
            .unwrap()
            .linearisation;
        let j = &lin.jacobian;
        let rows = lin.position_rows;
        let positions = j.rows(0, rows).transpose() * j.rows(0, rows);
        let turns = j.rows(rows, j.nrows() - rows).transpose() * j.rows(rows, j.nrows() - rows);
        (positions, turns)
    };
    let (p1, r1) = normal(2e-4);
    let (p2, r2) = normal(4e-4);
    assert!(r1.norm() > 0.0);
    assert!(
        (&p2 - &p1).norm() <= 1e-12 * p1.norm(),
        "the positions' weight is unchanged"
    );
    assert!(
        (&r2 * 4.0 - &r1).norm() <= 1e-10 * r1.norm(),
        "the orientations' weight is a quarter"
    );
}

#[test]
fn a_simulated_pose_truth_and_its_noises_are_recovered_over_seeds() {
    use armcomp_core::calibrate::evidence::{EvidenceParams, calibrate_with_evidence};
    let nominal = pose_robot("");
    let changes = [
        ("j2.a", 2e-3),
        ("j4.alpha", 1.5e-3),
        ("marker.tool.rx", 0.02),
        ("marker.tool.ry", -0.01),
    ];
    let truth = truth_of(&nominal, &changes);
    let (sigma_p, sigma_r) = (5e-5, 3e-4);
    let evidence = EvidenceParams {
        estimate_priors: false,
        ..EvidenceParams::default()
    };
    let mut noise_ratios = Vec::new();
    for seed in 0..3 {
        let samples = pose_samples(&truth, 40, sigma_p, sigma_r, 100 + seed);
        let params = CalibrationParams {
            identify: ["base", "markers", "geometry"].map(String::from).to_vec(),
            ..CalibrationParams::default()
        };
        let (fit, report) = calibrate_with_evidence(&nominal, &samples, &params, &evidence, &mut |_| {}).unwrap();
        let space = ParameterSpace::new(&nominal);
        for (name, delta) in changes {
            let p = fit.report.params.iter().find(|p| p.name == name).unwrap();
            let want = space.initial()[space.index(name).unwrap()] + delta;
            assert!(
                (p.value - want).abs() <= 4.0 * p.std,
                "seed {seed}: {name} = {} ± {}, truth {want}",
                p.value,
                p.std
            );
        }
        // A fit to within the noise: the orientation residual's RMS is about √3 σ_r.
        let after = fit.report.after_orientation.unwrap();
        assert!(
            after.rms_deg < 1.3 * 3f64.sqrt() * sigma_r.to_degrees(),
            "seed {seed}: {after:?}"
        );
        noise_ratios.push((
            report.noise_mm * 1e-3 / sigma_p,
            report.orientation_noise_deg.unwrap().to_radians() / sigma_r,
        ));
    }
    // Each kind's noise estimated from its own residuals, within 15 % on average over the seeds.
    let n = noise_ratios.len() as f64;
    let (p, r) = noise_ratios
        .iter()
        .fold((0.0, 0.0), |(a, b), (x, y)| (a + x / n, b + y / n));
    assert!(
        (p - 1.0).abs() < 0.15 && (r - 1.0).abs() < 0.15,
        "noise estimates over truth: {noise_ratios:?}"
    );
}

/// `evaluate --register` on poses: 8 poses with 5 mm of position noise and 0.005° of
/// orientation noise, the frame 0.1 m and a few degrees off. The closed form on the positions
/// alone turns the frame by what the positions' noise allows; fitting it to the positions and
/// orientations together, each weighed by the noise its residuals give, lands its turn at
/// least twice as near the truth's, on four seeds.
#[test]
fn registering_poses_uses_their_orientations() {
    use armcomp_core::calibrate::{register_stations, register_stations_on_poses};
    let nominal = pose_robot("");
    let truth = truth_of(&nominal, &[("base.x", 0.1), ("base.yaw", 0.05), ("base.roll", 0.02)]);
    let turn_error = |r: &Robot| (r.station_frame(0).rotation.inverse() * truth.station_frame(0).rotation).angle();
    for seed in 1..=4 {
        let samples = pose_samples(&truth, 8, 5e-3, 0.005f64.to_radians(), 40 + seed);
        let (mut positions, mut poses) = (pose_robot(""), pose_robot(""));
        assert!(register_stations(&mut positions, &samples, &[0]).unwrap().is_empty());
        assert!(
            register_stations_on_poses(&mut poses, &samples, &[0])
                .unwrap()
                .is_empty()
        );
        let (by_positions, by_poses) = (turn_error(&positions), turn_error(&poses));
        assert!(
            by_poses < 0.5 * by_positions,
            "seed {seed}: the frame's turn is off by {:.4}° registered on the positions, {:.4}° on the poses",
            by_positions.to_degrees(),
            by_poses.to_degrees()
        );
    }
}

/// A pose's orientation error as a rotation vector: rows measured exactly, then turned by a
/// known small rotation `d` in the measurement frame, read back as `d` (to round-off), and as
/// its angle by `orientation_errors`.
#[test]
fn an_orientation_error_is_the_turn_from_the_model_to_the_measurement() {
    use armcomp_core::algorithms::evaluate::{orientation_error_vectors, orientation_errors};
    let robot = pose_robot("");
    let mut samples = pose_samples(&robot, 4, 0.0, 0.0, 3);
    let d = Vector3::new(0.003, -0.002, 0.01);
    for s in &mut samples {
        s.orientation = Some(UnitQuaternion::from_scaled_axis(d) * s.orientation.unwrap());
    }
    for (v, a) in orientation_error_vectors(&robot, &samples)
        .into_iter()
        .zip(orientation_errors(&robot, &samples))
    {
        let v = v.unwrap();
        assert!((v - d).norm() < 1e-12, "{v}");
        assert!((a.unwrap() - d.norm()).abs() < 1e-12);
    }
}

/// `fit` scores poses as poses: rows of a truth with 0.01 mm position noise and 2 mrad
/// orientation noise per axis. With the orientations, every candidate's held-out score holds
/// at least the orientation noise's share, `√3 · 2 mrad × 100 mm` (the default noises' ratio)
/// = 0.35 mm, less a tenth; the same rows as positions alone score far below it.
#[test]
fn the_ladder_scores_poses_by_position_and_orientation() {
    use armcomp_core::analysis::ladder::{LadderParams, climb};
    let nominal = pose_robot("");
    let truth = truth_of(&nominal, &[("base.x", 0.01), ("base.yaw", 0.02)]);
    let poses = pose_samples(&truth, 30, 1e-5, 2e-3, 7);
    let params = LadderParams {
        folds: 3,
        repeats: 1,
        ..LadderParams::new(CalibrationParams::default(), false)
    };
    let with = climb(&nominal, &poses, &params, &|_| {}).unwrap().report;
    assert!(with.scored_by.starts_with("pose"), "{}", with.scored_by);
    let floor = 3f64.sqrt() * 2e-3 * 0.1 * 1e3 * 0.9;
    for c in &with.candidates {
        assert!(c.rms_mm > floor, "{}: {} mm", c.label, c.rms_mm);
    }
    let positions: Vec<Sample> = poses
        .iter()
        .map(|s| Sample {
            orientation: None,
            ..s.clone()
        })
        .collect();
    let without = climb(&nominal, &positions, &params, &|_| {}).unwrap().report;
    let best = (without.candidates.iter())
        .map(|c| c.rms_mm)
        .fold(f64::INFINITY, f64::min);
    assert!(best < floor / 3.0, "positions alone: {best} mm");
}
