//! Fixed-point measurements and known distances: simulated truths recovered with their unknown
//! points, the residuals' Jacobian against finite differences, what fixed points cannot see,
//! and the MUKCa Panda sockets (real data beside the repository).

use std::path::Path;

use armcomp_core::Robot;
use armcomp_core::algorithms::simulate::{FixedPointParams, simulate_fixed_points};
use armcomp_core::calibrate::evidence::{EvidenceParams, calibrate_with_evidence};
use armcomp_core::calibrate::{
    CalibrationParams, ParamGroup, ParameterSpace, calibrate, identifiability, samples_jacobian,
};
use armcomp_core::data::measurement::{Sample, parse_csv, write_csv};
use armcomp_core::robot::Conditions;
use nalgebra::Vector3;
use rand::SeedableRng;
use rand_distr::{Distribution, Normal};

use crate::common::{assert_diagnosis_names, random_configurations, robot_from_toml, root, with_transmission_scale};

/// The Panda of `robots/panda-sockets.toml` with its `[measurement] distances` line replaced by
/// `distances` (empty for none).
fn panda(distances: &str) -> Robot {
    let text = std::fs::read_to_string(root().join("robots/panda-sockets.toml")).unwrap();
    let urdf = root().join("tests/data/urdf/panda_sockets.urdf");
    let text: String = text
        .lines()
        .map(|l| {
            if l.starts_with("distances") {
                distances.to_string()
            } else {
                l.replace("../tests/data/urdf/panda_sockets.urdf", &urdf.display().to_string())
            }
        })
        .collect::<Vec<_>>()
        .join("\n");
    robot_from_toml(&text)
}

const KNOWN_50MM: &str = r#"distances = [{ between = ["hole_0", "hole_1"], mm = 50.0 }]"#;

/// The truth's sockets (measurement frame, m): two 50 mm apart and a third elsewhere.
fn sockets() -> Vec<(String, Vector3<f64>)> {
    vec![
        ("hole_0".into(), Vector3::new(0.45, -0.025, 0.12)),
        ("hole_1".into(), Vector3::new(0.45, 0.025, 0.12)),
        ("far".into(), Vector3::new(0.25, 0.35, 0.35)),
    ]
}

/// `nominal` with the named parameters moved (SI).
fn truth_of(nominal: &Robot, changes: &[(&str, f64)]) -> Robot {
    let space = ParameterSpace::new(nominal);
    let mut theta = space.initial();
    for (name, delta) in changes {
        theta[space.index(name).unwrap_or_else(|| panic!("no parameter {name}"))] += delta;
    }
    space.apply(nominal, &theta).unwrap()
}

/// The tool's position through `robot`'s full model and measurement frame.
fn model_point(robot: &Robot, q: &[f64]) -> Vector3<f64> {
    let mut ws = robot.workspace();
    let m = robot.markers()[0];
    robot.forward_with_into(robot.tree(), robot.error_values(), q, Conditions::default(), &mut ws);
    robot
        .t_meas_base()
        .transform_point(&ws.frames.point[m].translation.vector.into())
        .coords
}

/// Joint offsets and lengths of the truth, a few tenths of a millimetre to a millimetre at the
/// tool: what a Panda's calibration finds.
const CHANGES: [(&str, f64); 5] = [
    ("panda_joint2.offset", 1.5e-3),
    ("panda_joint4.offset", -1.0e-3),
    ("panda_joint6.offset", 2.0e-3),
    ("panda_joint3.y", 0.8e-3),
    ("panda_joint5.y", -0.6e-3),
];

/// The ladder on socket contacts alone: a held-out contact is scored by its distance from where
/// its fold's training contacts put the socket; the truth's offsets and lengths are found
/// (three seeds).
#[test]
fn the_ladder_scores_fixed_points_by_their_held_out_distance() {
    use armcomp_core::analysis::ladder::Rung;
    let nominal = panda("");
    let truth = truth_of(&nominal, &CHANGES);
    for seed in 1..=3 {
        let params = FixedPointParams {
            per_point: 40,
            joint_noise_std: 2e-5,
            seed: 60 + seed,
        };
        let samples = simulate_fixed_points(&truth, &sockets(), params).unwrap().samples;
        let report = crate::planes::climb_contacts(&nominal, &samples, seed);
        assert_eq!(report.scored_by, "fixed-point distance");
        let registration = report.candidates[0].rms_mm;
        assert!(
            report.chosen.rung != Rung::Registration && registration > 5.0 * report.expected_rms_mm,
            "seed {seed}: {:?}",
            report.candidates
        );
        // Joint noise of 2e-5 rad moves the ball by about 2e-5 × 0.5 m per joint: a few
        // hundredths of a millimetre, which the held-out distance comes down to.
        assert!(report.expected_rms_mm < 0.1, "seed {seed}: {:?}", report.candidates);
    }
}

/// 60 contacts of `truth`'s ball with each socket, its joints read with 3e-5 rad of noise.
fn socket_contacts(truth: &Robot, seed: u64) -> Vec<Sample> {
    let params = FixedPointParams {
        per_point: 60,
        joint_noise_std: 3e-5,
        seed,
    };
    simulate_fixed_points(truth, &sockets(), params).unwrap().samples
}

/// A residual predictor learns from contacts what the model leaves of the positions they
/// measure (each contact at where the model's contacts put its socket): a joint turning 1 %
/// further than commanded, missing from the model, is learned from socket contacts alone, the
/// cross-validated error with the predictor under 30 % of the model's (three seeds).
#[test]
fn a_residual_predictor_learns_from_fixed_points() {
    let nominal = panda("");
    let truth = with_transmission_scale(&nominal, "panda_joint2", 0.01);
    for seed in 1..=3 {
        let samples = socket_contacts(&truth, 10 + seed);
        let run = crate::common::learn_gp(&nominal, &samples);
        let (held_out, _) = run.cross_validated.expect("enough poses to cross-validate");
        assert!(
            run.before.rms_mm > 1.0 && held_out.rms_mm < 0.3 * run.before.rms_mm,
            "seed {seed}: model alone {} mm, cross-validated with the predictor {} mm",
            run.before.rms_mm,
            held_out.rms_mm
        );
    }
}

/// The robot alone, no instrument: a joint that turns 1 % further than commanded is named from
/// its contacts with three sockets, each held-out contact scored by its distance from where its
/// fold's training contacts put the socket (three seeds).
#[test]
fn the_diagnosis_names_an_effect_from_fixed_points_alone() {
    let nominal = panda("");
    let truth = with_transmission_scale(&nominal, "panda_joint2", 0.01);
    for seed in 1..=3 {
        let samples = socket_contacts(&truth, seed);
        let calibration = CalibrationParams {
            measurement_std: 5e-5,
            ..Default::default()
        };
        assert_diagnosis_names(
            &nominal,
            &samples,
            calibration,
            ("transmission_scale", "panda_joint2"),
            0.1,
            seed,
        );
    }
}

#[test]
fn a_fixed_point_truth_is_recovered_with_its_points() {
    let nominal = panda(KNOWN_50MM);
    let truth = truth_of(&nominal, &CHANGES);
    let noise = 2e-5; // rad per encoder: about 20 µm at the ball
    let params = FixedPointParams {
        per_point: 30,
        joint_noise_std: noise,
        seed: 7,
    };
    let data = simulate_fixed_points(&truth, &sockets(), params).unwrap();
    assert!(data.samples.iter().all(|s| s.fixed_point.is_some()));
    // The parameters the truth moved, and (always, with fixed points) the points themselves.
    let cal = calibrate(
        &nominal,
        &data.samples,
        &CalibrationParams {
            identify: CHANGES.iter().map(|(n, _)| n.to_string()).collect(),
            measurement_std: 3e-5,
            ..CalibrationParams::default()
        },
        &mut |_| {},
    )
    .unwrap();
    let report = &cal.report;
    for (name, delta) in CHANGES {
        let r = report.params.iter().find(|r| r.name == name).unwrap();
        let err = (r.value - r.initial - delta).abs();
        assert!(
            err < 4.0 * r.std && r.std < 0.2 * delta.abs(),
            "{name}: moved by {}, truth {delta} (std {})",
            r.value - r.initial,
            r.std
        );
    }
    assert!(
        report.params.iter().all(|p| !p.name.starts_with("base.")),
        "the base frame is not identified from fixed points"
    );
    // The unknown points, as the truth put them, within 4 of their standard deviations and
    // 0.1 mm.
    for (name, p) in sockets() {
        for (a, axis) in ["x", "y", "z"].iter().enumerate() {
            let r = report
                .params
                .iter()
                .find(|r| r.name == format!("fixed_point.{name}.{axis}"))
                .unwrap_or_else(|| panic!("fixed point {name} is reported"));
            let err = (r.value - p[a]).abs();
            assert!(
                err < 1e-4 && err < 4.0 * r.std.max(5e-6),
                "{}: {} m, truth {} m (std {} m)",
                r.name,
                r.value,
                p[a],
                r.std
            );
        }
    }
    // The identified model puts the tool where the truth does, across the workspace.
    let before_mm = spread_to(&nominal, &truth);
    let after_mm = spread_to(&cal.robot, &truth);
    assert!(
        before_mm > 0.5,
        "the truth differs from the nominal model: {before_mm} mm"
    );
    assert!(
        after_mm < 0.05,
        "calibrated model off the truth by {after_mm} mm RMS (nominal {before_mm} mm)"
    );
}

/// The Panda measuring the ball's position with a tracker as well as putting it into sockets:
/// `kind = "point"`, fixed points among the rows (and without them, no known distance).
fn mixed_panda(sockets: bool) -> Robot {
    let text = std::fs::read_to_string(root().join("robots/panda-sockets.toml")).unwrap();
    let urdf = root().join("tests/data/urdf/panda_sockets.urdf");
    let text: String = (text.lines())
        .filter(|l| sockets || !l.starts_with("distances"))
        .map(|l| {
            l.replace("kind = \"fixed_point\"", "kind = \"point\"")
                .replace("../tests/data/urdf/panda_sockets.urdf", &urdf.display().to_string())
        })
        .collect::<Vec<_>>()
        .join("\n");
    robot_from_toml(&text)
}

/// Mixed data of `truth`: `n` tracker positions with noise `tracker_std` per axis (m), and
/// the sockets' rows with encoder noise `joint_std` (rad); also the socket rows' actual
/// position noise per axis (m), from the truth's tool at the noisy joint values.
fn mixed_samples(truth: &Robot, n: usize, tracker_std: f64, joint_std: f64, seed: u64) -> (Vec<Sample>, f64) {
    let params = FixedPointParams {
        per_point: 30,
        joint_noise_std: joint_std,
        seed,
    };
    let mut samples = simulate_fixed_points(truth, &sockets(), params).unwrap().samples;
    let points = sockets();
    let socket_sq: f64 = (samples.iter())
        .map(|s| {
            let c = points
                .iter()
                .find(|(n, _)| Some(n) == s.fixed_point.as_ref())
                .unwrap()
                .1;
            (model_point(truth, &s.q) - c).norm_squared()
        })
        .sum();
    let socket_std = (socket_sq / (3.0 * samples.len() as f64)).sqrt();
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed + 100);
    let noise = Normal::new(0.0, tracker_std).unwrap();
    for q in random_configurations(truth, n, seed + 200) {
        let p = model_point(truth, &q) + Vector3::from_fn(|_, _| noise.sample(&mut rng));
        samples.push(Sample {
            position: p,
            fixed_point: None,
            ..samples[0].clone()
        });
        samples.last_mut().unwrap().q = q;
    }
    (samples, socket_std)
}

#[test]
fn mixed_positions_and_fixed_points_weigh_by_their_noise() {
    let nominal = mixed_panda(true);
    let (samples, _) = mixed_samples(&truth_of(&nominal, &CHANGES), 40, 2e-4, 2e-5, 5);
    // No iteration: both linearisations are at the same parameters, the robot's values.
    let normal = |fixed_point_std: f64| {
        let params = CalibrationParams {
            measurement_std: 2e-4,
            fixed_point_std: Some(fixed_point_std),
            max_iterations: 0,
            restarts: 0,
            start: Some(ParameterSpace::for_samples(&nominal, &samples).initial()),
            ..CalibrationParams::default()
        };
        let lin = calibrate(&nominal, &samples, &params, &mut |_| {})
            .unwrap()
            .linearisation;
        let j = &lin.jacobian;
        let rows = |fixed: bool| -> Vec<usize> {
            (0..lin.position_rows)
                .filter(|i| lin.fixed_point_samples[i / 3] == fixed)
                .collect()
        };
        let part = |rows: Vec<usize>| {
            let m = j.select_rows(rows.iter());
            m.transpose() * m
        };
        (part(rows(false)), part(rows(true)))
    };
    let (p1, f1) = normal(2e-5);
    let (p2, f2) = normal(4e-5);
    assert!(f1.norm() > 0.0 && p1.norm() > 0.0);
    assert!(
        (&p2 - &p1).norm() <= 1e-12 * p1.norm(),
        "the tracker's weight is unchanged"
    );
    assert!(
        (&f2 * 4.0 - &f1).norm() <= 1e-10 * f1.norm(),
        "the sockets' weight is a quarter"
    );
}

#[test]
fn mixed_kinds_are_fitted_together_each_with_the_noise_of_its_own_rows() {
    let nominal = mixed_panda(true);
    let truth = truth_of(&nominal, &CHANGES);
    for seed in [1, 2, 3] {
        let tracker = 2e-4;
        let (samples, socket_std) = mixed_samples(&truth, 40, tracker, 2e-5, seed);
        let identify = CHANGES
            .iter()
            .map(|(n, _)| n.to_string())
            .chain(["base".into()])
            .collect();
        let params = CalibrationParams {
            identify,
            ..CalibrationParams::default()
        };
        let (cal, ev) =
            calibrate_with_evidence(&nominal, &samples, &params, &EvidenceParams::default(), &mut |_| {}).unwrap();
        // Each kind's noise from its own residuals: the tracker's as drawn, the sockets' as the
        // encoder noise put the ball off them (a tenth of the tracker's).
        let fixed = ev.fixed_point_noise_mm.expect("mixed data estimate the sockets' noise") * 1e-3;
        assert!(
            (ev.noise_mm * 1e-3 / tracker - 1.0).abs() < 0.25,
            "seed {seed}: tracker noise {} mm, drawn {} mm",
            ev.noise_mm,
            tracker * 1e3
        );
        assert!(
            (fixed / socket_std - 1.0).abs() < 0.2,
            "seed {seed}: socket noise {} mm, actual {} mm",
            fixed * 1e3,
            socket_std * 1e3
        );
        // The sockets, ten times the more precise, pin the geometry they see: the model puts
        // the tool where the truth does (robot base frame, which the sockets see without the
        // tracker's frame) better than the tracker's rows alone do.
        let tracker_rows: Vec<Sample> = samples.iter().filter(|s| s.fixed_point.is_none()).cloned().collect();
        let alone = calibrate(&mixed_panda(false), &tracker_rows, &params, &mut |_| {}).unwrap();
        let (mixed_mm, alone_mm) = (base_spread_to(&cal.robot, &truth), base_spread_to(&alone.robot, &truth));
        assert!(
            mixed_mm < 0.02 && mixed_mm < 0.3 * alone_mm,
            "seed {seed}: {mixed_mm} mm off the truth, the tracker alone {alone_mm} mm"
        );
        for (name, p) in sockets() {
            let r = cal
                .report
                .params
                .iter()
                .find(|r| r.name == format!("fixed_point.{name}.x"))
                .unwrap();
            assert!(
                (r.value - p.x).abs() < 1e-4,
                "seed {seed}: {} {} against {}",
                r.name,
                r.value,
                p.x
            );
        }
    }
}

#[test]
fn mixed_files_are_read_written_and_checked() {
    let robot = mixed_panda(true);
    let head = "panda_joint1[deg],panda_joint2[deg],panda_joint3[deg],panda_joint4[deg],panda_joint5[deg],panda_joint6[deg],panda_joint7[deg]";
    let text = format!(
        "{head},kind,fixed_point,x[mm],y[mm],z[mm]\n0,10,0,-90,0,90,0,fixed_point,hole_0,,,\n\
         5,10,0,-90,0,90,0,point,,500,20,300\n"
    );
    let set = parse_csv(&text, Path::new("m.csv"), &robot.csv_layout()).unwrap();
    assert_eq!(set.samples.len(), 2);
    assert_eq!(set.samples[0].fixed_point.as_deref(), Some("hole_0"));
    assert_eq!(set.samples[1].fixed_point, None);
    assert!((set.samples[1].position - Vector3::new(0.5, 0.02, 0.3)).norm() < 1e-12);
    // Written and read back, the same samples.
    let written = write_csv(&set, robot.tree(), robot.units());
    let again = parse_csv(&written, Path::new("w.csv"), &robot.csv_layout()).unwrap();
    assert_eq!(again.samples, set.samples);
    // A file of sockets alone joins a tracker's file (given to `--data` twice).
    let sockets = format!("{head},fixed_point\n0,10,0,-90,0,90,0,hole_1\n");
    let set = parse_csv(&sockets, Path::new("s.csv"), &robot.csv_layout()).unwrap();
    assert_eq!(set.samples[0].fixed_point.as_deref(), Some("hole_1"));
    let bad = [
        (
            format!("{head},kind,fixed_point,x,y,z\n0,10,0,-90,0,90,0,point,hole_0,,,\n"),
            "column `kind` says `point`",
        ),
        (
            format!("{head},kind,fixed_point,x,y,z\n0,10,0,-90,0,90,0,socket,hole_0,,,\n"),
            "`socket` is not a measurement kind",
        ),
        (
            format!("{head},fixed_point,x,y,z\n0,10,0,-90,0,90,0,,,,\n"),
            "names the fixed point it was measured at",
        ),
        (
            format!("{head},fixed_point\n0,10,0,-90,0,90,0,\n"),
            "column `fixed_point` is empty",
        ),
    ];
    for (text, message) in bad {
        let e = parse_csv(&text, Path::new("b.csv"), &robot.csv_layout())
            .unwrap_err()
            .to_string();
        assert!(e.contains("b.csv:2") && e.contains(message), "{e}");
    }
}

/// RMS distance (mm) between the tool of `a` and of `b` in their base frames over
/// configurations spread over the ranges.
fn base_spread_to(a: &Robot, b: &Robot) -> f64 {
    let qs =
        armcomp_core::model::sampling::configurations(a.tree(), armcomp_core::model::sampling::Sampler::Sobol, 50, 11)
            .unwrap();
    let tool = |r: &Robot, q: &[f64]| {
        let mut ws = r.workspace();
        r.forward_with_into(r.tree(), r.error_values(), q, Conditions::default(), &mut ws);
        ws.frames.point[r.markers()[0]].translation.vector
    };
    let sum: f64 = qs.iter().map(|q| (tool(a, q) - tool(b, q)).norm_squared()).sum();
    (sum / qs.len() as f64).sqrt() * 1e3
}

/// RMS distance (mm) between the tool of `a` and of `b` over configurations spread over the
/// ranges.
fn spread_to(a: &Robot, b: &Robot) -> f64 {
    let qs =
        armcomp_core::model::sampling::configurations(a.tree(), armcomp_core::model::sampling::Sampler::Sobol, 50, 11)
            .unwrap();
    let sum: f64 = qs
        .iter()
        .map(|q| (model_point(a, q) - model_point(b, q)).norm_squared())
        .sum();
    (sum / qs.len() as f64).sqrt() * 1e3
}

#[test]
fn the_known_distance_fixes_the_scale_the_fixed_points_cannot_see() {
    // A truth 2 % larger than its nominal model in every length.
    let nominal = panda(KNOWN_50MM);
    let space = ParameterSpace::new(&nominal);
    let mut theta = space.initial();
    for (k, p) in space.params.iter().enumerate() {
        if p.info.quantity == armcomp_core::model::param::Quantity::Length && p.group == ParamGroup::Geometry {
            theta[k] *= 1.02;
        }
    }
    let truth = space.apply(&nominal, &theta).unwrap();
    let sockets: Vec<(String, Vector3<f64>)> = sockets().into_iter().take(2).collect();
    let params = FixedPointParams {
        per_point: 25,
        joint_noise_std: 1e-5,
        seed: 3,
    };
    let data = simulate_fixed_points(&truth, &sockets, params).unwrap();
    let fit = |robot: &Robot| {
        let cal = calibrate(
            robot,
            &data.samples,
            &CalibrationParams {
                measurement_std: 2e-5,
                use_priors: false,
                ..CalibrationParams::default()
            },
            &mut |_| {},
        )
        .unwrap();
        let at = |name: &str| {
            Vector3::from_fn(|a, _| {
                let axis = ["x", "y", "z"][a];
                cal.report
                    .params
                    .iter()
                    .find(|r| r.name == format!("fixed_point.{name}.{axis}"))
                    .unwrap()
                    .value
            })
        };
        (
            (at("hole_0") - at("hole_1")).norm() * 1e3,
            cal.report.identifiability.message.clone(),
        )
    };
    // The nominal model seen through the truth's data puts the sockets 2 % too close.
    let (without, message) = fit(&panda(""));
    assert!(
        message.contains("scale is not observable"),
        "without a distance the report says the scale is not observable: {message}"
    );
    assert!((without - 50.0).abs() > 0.5, "without the distance: {without} mm");
    let (with, message) = fit(&nominal);
    assert!(!message.contains("scale"), "{message}");
    assert!((with - 50.0).abs() < 0.05, "with the distance: {with} mm");
}

#[test]
fn the_fixed_point_jacobian_matches_finite_differences() {
    let robot = panda(KNOWN_50MM);
    // Configurations of the truth put into the sockets: seen through the nominal model the
    // points spread by a millimetre, so the residuals are not zero.
    let truth = truth_of(&robot, &CHANGES);
    let params = FixedPointParams {
        per_point: 6,
        joint_noise_std: 0.0,
        seed: 5,
    };
    let samples = simulate_fixed_points(&truth, &sockets(), params).unwrap().samples;
    let space = ParameterSpace::new(&robot).with_fixed_points(&samples);
    // The fixed points where calibration starts them: the mean of the model's points.
    let mut start = space.initial();
    for (name, _) in sockets() {
        let pts: Vec<Vector3<f64>> = samples
            .iter()
            .filter(|s| s.fixed_point.as_deref() == Some(name.as_str()))
            .map(|s| model_point(&robot, &s.q))
            .collect();
        let mean = pts.iter().sum::<Vector3<f64>>() / pts.len() as f64;
        for (a, axis) in ["x", "y", "z"].iter().enumerate() {
            start[space.index(&format!("fixed_point.{name}.{axis}")).unwrap()] = mean[a];
        }
    }
    // Residuals as the problem states them: modelled point minus its fixed point, then the
    // distance's error.
    let residuals = |theta: &[f64]| -> Vec<f64> {
        let model = space.apply(&robot, theta).unwrap();
        let point = |name: &str| {
            Vector3::from_fn(|a, _| {
                theta[space
                    .index(&format!("fixed_point.{name}.{}", ["x", "y", "z"][a]))
                    .unwrap()]
            })
        };
        let mut r: Vec<f64> = samples
            .iter()
            .flat_map(|s| {
                (model_point(&model, &s.q) - point(s.fixed_point.as_deref().unwrap()))
                    .data
                    .0[0]
            })
            .collect();
        r.push((point("hole_0") - point("hole_1")).norm() - 0.05);
        r
    };
    for (name, h) in [
        ("panda_joint2.offset", 1e-6),
        ("panda_joint3.y", 1e-6),
        ("panda_joint5.rot_u", 1e-6),
        ("marker.ball.z", 1e-6),
        ("fixed_point.hole_0.x", 1e-6),
        ("fixed_point.hole_1.y", 1e-6),
        ("fixed_point.far.z", 1e-6),
    ] {
        let (jac, names) = samples_jacobian(&robot, &samples, &[name.to_string()]).unwrap();
        assert_eq!(
            jac.nrows(),
            3 * samples.len() + 1,
            "three rows a sample and one for the distance"
        );
        let c = names
            .iter()
            .position(|n| n == name)
            .unwrap_or_else(|| panic!("{name} in {names:?}"));
        let k = space.index(name).unwrap();
        let at = |d: f64| {
            let mut theta = start.clone();
            theta[k] += d;
            residuals(&theta)
        };
        let (plus, minus) = (at(h), at(-h));
        let scale = plus
            .iter()
            .zip(&minus)
            .fold(0.0f64, |m, (a, b)| m.max(((a - b) / (2.0 * h)).abs()));
        assert!(scale > 1e-3, "{name} moves the residuals");
        for (i, (a, b)) in plus.iter().zip(&minus).enumerate() {
            let fd = (a - b) / (2.0 * h);
            assert!(
                (jac[(i, c)] - fd).abs() <= 1e-5 * scale,
                "{name}, row {i}: analytic {} vs finite differences {fd}",
                jac[(i, c)]
            );
        }
    }
}

#[test]
fn a_fixed_point_calibration_says_it_cannot_see_the_base_frame() {
    let robot = panda(KNOWN_50MM);
    let params = FixedPointParams {
        per_point: 8,
        joint_noise_std: 0.0,
        seed: 9,
    };
    let samples = simulate_fixed_points(&robot, &sockets(), params).unwrap().samples;
    let asked = CalibrationParams {
        identify: vec!["base".into(), "offsets".into()],
        ..CalibrationParams::default()
    };
    let report = identifiability(&robot, &samples, &asked).unwrap();
    assert!(
        report
            .message
            .contains("a fixed-point-only calibration cannot see the base frame"),
        "{}",
        report.message
    );
    let cal = calibrate(&robot, &samples, &asked, &mut |_| {}).unwrap();
    let names: Vec<&str> = cal.report.params.iter().map(|p| p.name.as_str()).collect();
    assert!(!names.iter().any(|n| n.starts_with("base.")), "{names:?}");
    assert!(
        names.contains(&"panda_joint2.offset") && names.contains(&"fixed_point.far.x"),
        "{names:?}"
    );
    // The robot file's base frame is kept.
    assert_eq!(cal.robot.t_meas_base(), robot.t_meas_base());
}

#[test]
fn fixed_point_files_are_read_and_checked() {
    let robot = panda(KNOWN_50MM);
    let head = "panda_joint1[deg],panda_joint2[deg],panda_joint3[deg],panda_joint4[deg],panda_joint5[deg],panda_joint6[deg],panda_joint7[deg]";
    let ok = format!("{head},fixed_point\n0,10,0,-90,0,90,0,hole_0\n5,10,0,-90,0,90,0,hole_1\n");
    let set = parse_csv(&ok, Path::new("f.csv"), &robot.csv_layout()).unwrap();
    assert_eq!(set.samples.len(), 2);
    assert_eq!(set.samples[1].fixed_point.as_deref(), Some("hole_1"));
    assert!((set.samples[1].q[0] - 5f64.to_radians()).abs() < 1e-12);
    let bad = [
        (
            format!("{head}\n0,10,0,-90,0,90,0\n"),
            ":1",
            "missing column `fixed_point`",
        ),
        (
            format!("{head},fixed_point\n0,10,0,-90,0,90,0,\n"),
            ":2",
            "column `fixed_point` is empty",
        ),
        (
            format!("{head},fixed_point,x,y,z\n0,10,0,-90,0,90,0,hole_0,1,2,3\n"),
            ":1",
            "gives no measured position",
        ),
    ];
    for (text, line, message) in bad {
        let e = parse_csv(&text, Path::new("f.csv"), &robot.csv_layout())
            .unwrap_err()
            .to_string();
        assert!(e.contains(&format!("f.csv{line}")) && e.contains(message), "{e}");
    }
    // A position robot reads fixed points among its positions, but a row gives one or the
    // other.
    let point_robot = crate::common::robot("industrial-6dof.toml");
    let names = point_robot.tree().coordinate_names().join(",");
    let text = format!("{names},x,y,z,fixed_point\n0,0,0,0,0,0,1,2,3,a\n");
    let e = parse_csv(&text, Path::new("p.csv"), &point_robot.csv_layout())
        .unwrap_err()
        .to_string();
    assert!(e.contains("p.csv:2") && e.contains("gives no measured position"), "{e}");
    // A distance naming a fixed point the data lack is refused with its place in the file.
    let other = panda(r#"distances = [{ between = ["hole_0", "hole_9"], mm = 50.0 }]"#);
    let e = calibrate(&other, &set.samples, &CalibrationParams::default(), &mut |_| {})
        .unwrap_err()
        .to_string();
    assert!(e.contains("measurement.distances[0]") && e.contains("hole_9"), "{e}");
}

/// The MUKCa data (platonics-delft/kinematics_calibration, MIT) beside the repository.
fn panda_data() -> Option<std::path::PathBuf> {
    let dir = root().join("../shared/data/panda-sockets");
    if dir.join("data/panda_1/front/hole_0.csv").is_file() {
        Some(dir)
    } else {
        eprintln!(
            "skipped: {} not found (see docs/reproductions/panda-sockets.md)",
            dir.display()
        );
        None
    }
}

/// Samples of one table place: the headerless joint files (7 columns, rad) of both sockets
/// with a header and a `fixed_point` column, read as armcomp reads any measurement file.
fn place(robot: &Robot, dir: &Path, robot_name: &str, place: &str) -> Vec<Sample> {
    let mut text = (1..=7)
        .map(|j| format!("panda_joint{j}[rad]"))
        .collect::<Vec<_>>()
        .join(",");
    text.push_str(",fixed_point\n");
    for hole in ["hole_0", "hole_1"] {
        let rows = std::fs::read_to_string(dir.join(format!("data/{robot_name}/{place}/{hole}.csv"))).unwrap();
        for row in rows.lines().filter(|l| !l.trim().is_empty()) {
            text.push_str(&format!("{},{hole}\n", row.trim()));
        }
    }
    parse_csv(&text, Path::new(place), &robot.csv_layout()).unwrap().samples
}

#[test]
#[ignore = "target not reached yet: panda_1 held out at 0.64 mm (back-high 0.88 mm, its sockets 1 mm off 50), \
            published 0.347 mm; see docs/reproductions/panda-sockets.md"]
fn panda_sockets_held_out_places_are_consistent_to_a_third_of_a_millimetre() {
    let Some(dir) = panda_data() else { return };
    let robot = crate::common::robot("panda-sockets.toml");
    let train = place(&robot, &dir, "panda_1", "front");
    let start = std::time::Instant::now();
    let cal = calibrate(
        &robot,
        &train,
        &CalibrationParams {
            measurement_std: 1e-4,
            ..CalibrationParams::default()
        },
        &mut |_| {},
    )
    .unwrap();
    let seconds = start.elapsed().as_secs_f64();
    let mut spreads = Vec::new();
    for test in ["right", "back-high"] {
        let samples = place(&robot, &dir, "panda_1", test);
        let before = armcomp_api::ops::evaluate::run(&robot, &samples)
            .unwrap()
            .fixed_points
            .unwrap();
        let after = armcomp_api::ops::evaluate::run(&cal.robot, &samples)
            .unwrap()
            .fixed_points
            .unwrap();
        let distance = &after.distances[0];
        eprintln!(
            "panda_1 {test}: spread {:.3} -> {:.3} mm, distance {:.3} mm",
            before.spread_mm, after.spread_mm, distance.modelled_mm
        );
        assert!(
            distance.error_mm < 0.5,
            "{test}: sockets {} mm apart",
            distance.modelled_mm
        );
        spreads.push(after.spread_mm);
    }
    let heldout = spreads.iter().sum::<f64>() / spreads.len() as f64;
    eprintln!("panda_1 held out: {heldout:.3} mm, calibration {seconds:.2} s");
    assert!(heldout <= 0.35, "held-out consistency {heldout} mm");
}

#[test]
fn simulate_calibrate_and_evaluate_fixed_points_on_the_command_line() {
    let s = crate::common::Scratch::new("fixed-points");
    let write = |name: &str, robot: &Robot| {
        let path = s.0.join(name);
        std::fs::write(&path, robot.to_file().to_text_for(&path).unwrap()).unwrap();
        path.display().to_string()
    };
    let nominal = panda(KNOWN_50MM);
    let truth = write("truth.toml", &truth_of(&nominal, &CHANGES));
    let nominal = write("nominal.toml", &nominal);
    let data = s.0.join("data.csv").display().to_string();
    let model = s.0.join("model.toml").display().to_string();
    let run = |args: &[&str]| {
        let (code, out, err) = crate::cli::armcomp(args);
        assert_eq!(code, 0, "{args:?}: {err}");
        out
    };
    run(&[
        "simulate",
        "--robot",
        &truth,
        "--fixed-point",
        "hole_0=450,-25,120",
        "--fixed-point",
        "hole_1=450,25,120",
        "--fixed-point",
        "far=250,350,350",
        "--n",
        "25",
        "--joint-noise-deg",
        "0.0005",
        "--seed",
        "2",
        "--out",
        &data,
    ]);
    run(&[
        "calibrate",
        "--robot",
        &nominal,
        "--data",
        &data,
        "--noise-mm",
        "0.02",
        "--out",
        &model,
    ]);
    let spread = |model: &str| {
        let json: serde_json::Value =
            serde_json::from_str(&run(&["evaluate", "--model", model, "--data", &data, "--json"])).unwrap();
        let f = &json["fixed_points"];
        (
            f["spread_mm"].as_f64().unwrap(),
            f["distances"][0]["error_mm"].as_f64().unwrap(),
        )
    };
    let (before, _) = spread(&nominal);
    let (after, distance) = spread(&model);
    assert!(
        before > 0.3,
        "the truth's points seen through the nominal model spread by {before} mm"
    );
    assert!(after < 0.03, "calibrated spread {after} mm (nominal {before} mm)");
    assert!(distance < 0.02, "distance error {distance} mm");
}
