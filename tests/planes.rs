//! Plane contacts: a simulated truth recovered with its unknown planes, the residuals' Jacobian
//! (and the frame link's) against finite differences, what a plane cannot see, bad files, and
//! the command line round trip.

use armcomp_core::Robot;
use armcomp_core::algorithms::simulate::{Contact, FixedPointParams, simulate_contacts};
use armcomp_core::calibrate::{CalibrationParams, ParameterSpace, calibrate, identifiability};
use armcomp_core::data::measurement::{CsvLayout, Sample, parse_csv};
use armcomp_core::model::geom::xyz_rpy;
use armcomp_core::robot::Conditions;
use armcomp_core::robot::robot_file::{Format, RobotFile, SourceFile};
use armcomp_core::support::io::InputLimits;
use nalgebra::{Isometry3, Vector3};

use crate::common::{assert_diagnosis_names, robot_from_toml, root, with_transmission_scale};

/// The Panda of the sockets' URDF pressing its ball frame on planes, with `measurement` lines
/// added to its [measurement] table.
fn panda_text(measurement: &str) -> String {
    let urdf = root().join("tests/data/urdf/panda_sockets.urdf");
    format!(
        "name = \"panda-plane\"\nkinematics = {{ type = \"urdf\", path = \"{}\" }}\n\
         points = [{{ name = \"ball\", link = \"ball_link\", xyz = [0.0, 0.0, 0.0] }}]\ntool = \"ball\"\n\
         [measurement]\nkind = \"plane\"\nmarkers = [\"ball\"]\n{measurement}\n",
        urdf.display()
    )
}

fn panda(measurement: &str) -> Robot {
    robot_from_toml(&panda_text(measurement))
}

/// The truth's planes (measurement frame): a table facing down onto the tool and a tilted one.
fn planes() -> Vec<(String, Isometry3<f64>)> {
    vec![
        (
            "table".into(),
            xyz_rpy([0.5, 0.0, 0.15], [std::f64::consts::PI, 0.0, 0.0]),
        ),
        (
            "ramp".into(),
            xyz_rpy([0.35, 0.3, 0.25], [std::f64::consts::PI + 0.2, 0.15, 0.0]),
        ),
    ]
}

/// The robot file's nominal planes: the truth's, off by a few millimetres and tenths of a degree.
const NOMINAL_PLANES: &str = "planes = [{ name = \"table\", xyz = [500.0, 0.0, 147.0], rpy = [180.3, 0.2, 0.0] }, \
                              { name = \"ramp\", xyz = [350.0, 300.0, 253.0], rpy = [191.2, 8.3, 0.0] }]";

fn truth_of(nominal: &Robot, changes: &[(&str, f64)]) -> Robot {
    let space = ParameterSpace::new(nominal);
    let mut theta = space.initial();
    for (name, delta) in changes {
        theta[space.index(name).unwrap_or_else(|| panic!("no parameter {name}"))] += delta;
    }
    space.apply(nominal, &theta).unwrap()
}

const CHANGES: [(&str, f64); 5] = [
    ("panda_joint2.offset", 1.5e-3),
    ("panda_joint4.offset", -1.0e-3),
    ("panda_joint6.offset", 2.0e-3),
    ("panda_joint3.y", 0.8e-3),
    ("panda_joint5.y", -0.6e-3),
];

fn simulated(truth: &Robot, per_plane: usize, noise: f64, seed: u64) -> Vec<Sample> {
    let contacts: Vec<(String, Contact)> = planes()
        .into_iter()
        .map(|(name, pose)| (name, Contact::Plane { pose, spread: 0.08 }))
        .collect();
    let params = FixedPointParams {
        per_point: per_plane,
        joint_noise_std: noise,
        seed,
    };
    simulate_contacts(truth, &contacts, params).unwrap().samples
}

/// The tool's pose through `robot`'s rigid model, in the frame of `link` (the root's when
/// `None`) seen through its measurement frame.
fn contact(robot: &Robot, q: &[f64], link: Option<&str>) -> Isometry3<f64> {
    let mut ws = robot.workspace();
    let m = robot.markers()[0];
    robot.forward_with_into(robot.tree(), robot.error_values(), q, Conditions::default(), &mut ws);
    let frame = link.map_or(Isometry3::identity(), |l| {
        let b = robot.tree().body_index(l).unwrap();
        ws.frames.body[b] * robot.tree().bodies()[b].convention_frame
    });
    robot.t_meas_base() * frame.inverse() * ws.frames.point[m]
}

/// FIGAROH's gap: the height of `c` above `plane` and the roll and pitch of `plane⁻¹ · c`.
fn gap(plane: &Isometry3<f64>, c: &Isometry3<f64>) -> [f64; 3] {
    let rel = plane.inverse() * c;
    let (roll, pitch, _) = rel.rotation.euler_angles();
    [rel.translation.vector.z, roll, pitch]
}

#[test]
fn a_plane_truth_is_recovered_with_its_planes() {
    // No nominal planes: each starts from the plane fitted to its rows.
    let nominal = panda("");
    let truth = truth_of(&nominal, &CHANGES);
    let noise = 2e-5; // rad per encoder: some 20 µm and 40 µrad at the contact
    let samples = simulated(&truth, 40, noise, 3);
    assert!(samples.iter().all(|s| s.plane.is_some()));
    // The truth's contacts lie on their planes, flush.
    let exact = simulated(&truth, 3, 0.0, 4);
    for s in &exact {
        let plane = planes()
            .into_iter()
            .find(|(n, _)| Some(n) == s.plane.as_ref())
            .unwrap()
            .1;
        let [h, r, p] = gap(&plane, &contact(&truth, &s.q, None));
        assert!(h.abs() < 1e-8 && r.abs() < 1e-8 && p.abs() < 1e-8, "{h} {r} {p}");
    }
    let cal = calibrate(
        &nominal,
        &samples,
        &CalibrationParams {
            identify: CHANGES.iter().map(|(n, _)| n.to_string()).collect(),
            measurement_std: 3e-5,
            orientation_std: 6e-5,
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
            err < 4.0 * r.std && r.std < 0.25 * delta.abs(),
            "{name}: moved by {}, truth {delta} (std {})",
            r.value - r.initial,
            r.std
        );
    }
    assert!(report.params.iter().all(|p| !p.name.starts_with("base.")));
    assert!(report.params.iter().any(|p| p.name == "plane.ramp.pitch"));
    // The identified planes (the model file's) against the truth's: normals within 0.1 mrad,
    // the truth's origin within 0.05 mm of the identified plane.
    let identified = cal.robot.nominal_planes();
    for (name, pose) in planes() {
        let found = identified.iter().find(|(n, _)| *n == name).unwrap().1;
        let (n_true, n_found) = (pose.rotation * Vector3::z(), found.rotation * Vector3::z());
        let angle = n_true.angle(&n_found);
        let offset = n_found.dot(&(pose.translation.vector - found.translation.vector));
        assert!(
            angle < 1e-4 && offset.abs() < 5e-5,
            "{name}: normal off by {angle} rad, origin {offset} m"
        );
    }
    // The height residual ends at the noise: the RMS over σ near one.
    assert!(report.rms_over_noise < 1.5, "{}", report.rms_over_noise);
}

/// Tracker positions and table contacts in one fit (a robot of `kind = "point"` whose rows may
/// name a plane): the truth is recovered within its standard deviations, the contacts make
/// the offsets better determined than the positions alone do, and the fit ends at the noise
/// (three seeds).
#[test]
fn positions_and_plane_contacts_are_fitted_together() {
    use armcomp_core::algorithms::simulate::{SimulateParams, simulate};
    let nominal = robot_from_toml(&panda_text("").replace("kind = \"plane\"", "kind = \"point\""));
    let truth = truth_of(&nominal, &CHANGES);
    let params = CalibrationParams {
        identify: CHANGES.iter().map(|(n, _)| n.to_string()).collect(),
        measurement_std: 3e-5,
        orientation_std: 6e-5,
        ..CalibrationParams::default()
    };
    for seed in 1..=3 {
        let poses = crate::common::random_configurations(&truth, 12, seed);
        let tracker = SimulateParams {
            noise_std: 3e-5,
            seed: seed + 100,
        };
        let positions = simulate(&truth, &poses, tracker).unwrap().samples;
        let contacts = simulated(&truth, 30, 2e-5, seed + 200);
        let mixed: Vec<Sample> = positions.iter().chain(&contacts).cloned().collect();
        let alone = calibrate(&nominal, &positions, &params, &mut |_| {}).unwrap().report;
        let cal = calibrate(&nominal, &mixed, &params, &mut |_| {}).unwrap();
        let report = &cal.report;
        for (name, delta) in CHANGES {
            let r = report.params.iter().find(|r| r.name == name).unwrap();
            let a = alone.params.iter().find(|r| r.name == name).unwrap();
            assert!(
                (r.value - r.initial - delta).abs() < 4.0 * r.std && r.std < a.std,
                "seed {seed}, {name}: moved by {}, truth {delta} (std {}; positions alone {})",
                r.value - r.initial,
                r.std,
                a.std
            );
        }
        assert!(report.params.iter().any(|p| p.name == "plane.table.height"));
        assert!(report.rms_over_noise < 1.5, "seed {seed}: {}", report.rms_over_noise);
        // The figures of the measured positions alone; the contacts have their own.
        let evaluation = armcomp_api::ops::evaluate::run(&cal.robot, &mixed).unwrap();
        assert_eq!(evaluation.stats.n, positions.len());
        let planes = evaluation.planes.expect("the contacts are evaluated");
        assert!(
            planes.planes.iter().all(|p| p.rms_mm < 0.1),
            "seed {seed}: {:?}",
            planes.planes
        );
    }
    // The diagnosis on mixed rows gives each kind's held-out RMS, which pool to its figure.
    let poses = crate::common::random_configurations(&truth, 12, 7);
    let tracker = SimulateParams {
        noise_std: 3e-5,
        seed: 7,
    };
    let mut mixed = simulate(&truth, &poses, tracker).unwrap().samples;
    mixed.extend(simulated(&truth, 30, 2e-5, 207));
    let diagnosis = armcomp_core::analysis::diagnose::DiagnoseParams {
        calibration: params.clone(),
        max_steps: 0,
        ..Default::default()
    };
    let report = armcomp_core::analysis::diagnose::diagnose(&nominal, &mixed, &[], None, &diagnosis, &|_| {})
        .unwrap()
        .report;
    assert_eq!(report.scored_by, "position + plane height");
    let kinds: Vec<(&str, usize)> = report.per_kind.iter().map(|k| (k.kind.as_str(), k.n)).collect();
    assert_eq!(kinds, [("position", 12), ("plane height", 60)]);
    let pooled = report
        .per_kind
        .iter()
        .map(|k| k.n as f64 * k.before_rms_mm.powi(2))
        .sum::<f64>()
        / 72.0;
    assert!(
        (pooled.sqrt() - report.initial.rms_mm).abs() < 1e-9 * report.initial.rms_mm,
        "{report:?}"
    );
    // One file: a row gives its position or names its plane, and says which in `kind`.
    let joints: Vec<String> = nominal.csv_joint_names();
    let header = joints.iter().map(|j| format!("{j}[rad]")).collect::<Vec<_>>().join(",");
    let q = vec!["0.1"; joints.len()].join(",");
    let path = std::path::Path::new("mixed.csv");
    let text = format!("{header},kind,x,y,z,plane\n{q},point,0.5,0.1,0.2,\n{q},plane,,,,table\n");
    let set = parse_csv(&text, path, &nominal.csv_layout()).unwrap();
    let kinds: Vec<_> = set.samples.iter().map(|s| s.plane.as_deref()).collect();
    assert_eq!(kinds, [None, Some("table")]);
    assert_eq!(set.samples[0].position, Vector3::new(0.5, 0.1, 0.2));
    let wrong = format!("{header},kind,x,y,z,plane\n{q},plane,0.5,0.1,0.2,table\n");
    let e = parse_csv(&wrong, path, &nominal.csv_layout()).unwrap_err().to_string();
    assert!(
        e.contains("mixed.csv:2") && e.contains("a row naming a plane gives no measured position"),
        "{e}"
    );
    // Fixed points and planes among positions in one file, each row naming at most one.
    let both = format!("{header},x,y,z,plane,fixed_point\n{q},0.5,0.1,0.2,,\n{q},,,,table,\n{q},,,,,socket\n");
    let set = parse_csv(&both, path, &nominal.csv_layout()).unwrap();
    let kinds: Vec<_> = (set.samples.iter())
        .map(|s| (s.plane.as_deref(), s.fixed_point.as_deref()))
        .collect();
    assert_eq!(kinds, [(None, None), (Some("table"), None), (None, Some("socket"))]);
    let two = format!("{header},x,y,z,plane,fixed_point\n{q},,,,table,socket\n");
    let e = parse_csv(&two, path, &nominal.csv_layout()).unwrap_err().to_string();
    assert!(
        e.contains("mixed.csv:2") && e.contains("names both a fixed point and a plane"),
        "{e}"
    );
}

/// A residual predictor learned from table contacts (a joint turning 1 % further than the model
/// says) brings new contacts closer to their plane when the model is evaluated with it: by more
/// than 15 % of their height, which ignoring the predictor (as evaluations did) leaves unchanged.
#[test]
fn a_predictor_learned_from_contacts_corrects_new_contacts() {
    let nominal = panda("");
    let truth = with_transmission_scale(&nominal, "panda_joint2", 0.01);
    for seed in 1..=3 {
        let train = simulated(&truth, 60, 2e-5, 300 + seed);
        let test = simulated(&truth, 20, 2e-5, 400 + seed);
        let run = crate::common::learn_gp(&nominal, &train);
        let height = |robot: &Robot| {
            armcomp_api::ops::evaluate::run(robot, &test)
                .unwrap()
                .planes
                .unwrap()
                .rms_mm
        };
        let (without, with) = (height(&nominal), height(&run.robot));
        assert!(
            with < 0.85 * without,
            "seed {seed}: {without} mm without the predictor, {with} mm with it"
        );
    }
}

/// Contacts made with the tool off the table (three of 60, 2 mm above it, as when a contact
/// was recorded before the tool touched): the calibration names exactly those rows as gross
/// errors, judged against the heights' own noise, and none of the clean rows; on three seeds.
/// Among tracker positions the same contacts are found, and no drift is reported.
#[test]
fn contacts_off_their_plane_are_named_as_gross_errors() {
    let nominal = panda("constrain = [\"height\"]");
    let truth = truth_of(&nominal, &CHANGES);
    let params = CalibrationParams {
        identify: CHANGES.iter().map(|(n, _)| n.to_string()).collect(),
        measurement_std: 3e-5,
        ..CalibrationParams::default()
    };
    const LIFTED: [usize; 3] = [4, 33, 51];
    // The tool's height above its plane when joint 4 turns by `dq` at sample `i`.
    let lift = |samples: &mut [Sample], i: usize| {
        let plane = planes()
            .into_iter()
            .find(|(n, _)| Some(n) == samples[i].plane.as_ref())
            .unwrap()
            .1;
        let height = |q: &[f64]| gap(&plane, &contact(&truth, q, None))[0];
        let h0 = height(&samples[i].q);
        let mut q = samples[i].q.clone();
        q[3] += 1e-3;
        let rate = (height(&q) - h0) / 1e-3;
        samples[i].q[3] += 2e-3 / rate;
    };
    for seed in 1..=3 {
        let clean = simulated(&truth, 30, 2e-5, 500 + seed);
        let report = calibrate(&nominal, &clean, &params, &mut |_| {}).unwrap().report;
        assert!(report.outliers.is_empty(), "seed {seed}: {:?}", report.outliers);
        let mut dirty = clean.clone();
        LIFTED.iter().for_each(|&i| lift(&mut dirty, i));
        let report = calibrate(&nominal, &dirty, &params, &mut |_| {}).unwrap().report;
        let mut found: Vec<usize> = report.outliers.iter().map(|o| o.sample).collect();
        found.sort_unstable();
        assert_eq!(found, LIFTED, "seed {seed}: {:?}", report.outliers);
    }
    use armcomp_core::algorithms::simulate::{SimulateParams, simulate};
    let nominal =
        robot_from_toml(&panda_text("constrain = [\"height\"]").replace("kind = \"plane\"", "kind = \"point\""));
    let truth = truth_of(&nominal, &CHANGES);
    let poses = crate::common::random_configurations(&truth, 20, 9);
    let tracker = SimulateParams {
        noise_std: 3e-5,
        seed: 9,
    };
    let mut mixed = simulate(&truth, &poses, tracker).unwrap().samples;
    mixed.extend(simulated(&truth, 30, 2e-5, 509));
    LIFTED.iter().for_each(|&i| lift(&mut mixed, 20 + i));
    let report = calibrate(&nominal, &mixed, &params, &mut |_| {}).unwrap().report;
    let mut found: Vec<usize> = report.outliers.iter().map(|o| o.sample).collect();
    found.sort_unstable();
    assert_eq!(found, LIFTED.map(|i| 20 + i), "{:?}", report.outliers);
    assert!(report.drift.is_none(), "{:?}", report.drift);
}

/// `plan` chooses among plane contacts with each candidate's own rows (its height and its
/// tilts, which calibration lays out after every height): the chosen contacts' posterior
/// standard deviations equal those computed directly from their own Jacobian and the priors.
#[test]
fn plans_among_plane_contacts_use_each_contacts_own_rows() {
    use armcomp_core::analysis::design::{SelectionParams, select_poses};
    let robot = panda(NOMINAL_PLANES);
    let pool: Vec<Vec<Sample>> = simulated(&robot, 12, 0.0, 7).into_iter().map(|s| vec![s]).collect();
    let params = SelectionParams {
        identify: vec!["offsets".into()],
        ..SelectionParams::default()
    };
    let report = select_poses(&robot, &pool, 6, &[], &[], &params).unwrap();
    let chosen: Vec<Sample> = report.chosen.iter().map(|&i| pool[i][0].clone()).collect();
    let (jac, names) = armcomp_core::calibrate::samples_jacobian(&robot, &chosen, &params.identify).unwrap();
    assert_eq!(names, report.params);
    assert_eq!(jac.nrows(), 3 * chosen.len(), "a height and two tilts a contact");
    let mut information = jac.transpose() * &jac / params.measurement_std.powi(2);
    // The planes have no prior: the plan holds each by a vanishing one, 1e-6 in units of what
    // gives a unit RMS sensitivity per residual row over the pool.
    let flat: Vec<Sample> = pool.iter().flatten().cloned().collect();
    let (all, _) = armcomp_core::calibrate::samples_jacobian(&robot, &flat, &params.identify).unwrap();
    for (c, prior) in report.prior_std.iter().enumerate() {
        let scale = match prior.is_finite() {
            true => *prior,
            false => params.measurement_std * (all.nrows() as f64).sqrt() / all.column(c).norm(),
        };
        information[(c, c)] += if prior.is_finite() { 1.0 } else { 1e-6 } / (scale * scale);
    }
    assert!(names.iter().any(|n| n == "plane.table.height"), "{names:?}");
    let covariance = information.try_inverse().unwrap();
    for (c, name) in names.iter().enumerate() {
        let (direct, planned) = (covariance[(c, c)].sqrt(), report.std_after[c]);
        assert!(
            (direct - planned).abs() < 1e-4 * direct,
            "{name}: {direct} directly, {planned} planned"
        );
    }
}

/// Residuals as the problem states them (σ = 1): heights, then roll and pitch per sample.
fn residuals(robot: &Robot, space: &ParameterSpace, theta: &[f64], samples: &[Sample], link: Option<&str>) -> Vec<f64> {
    let model = space.apply(robot, theta).unwrap();
    let planes = model.nominal_planes();
    // A measured position's three rows (modelled minus measured), a contact's height; then
    // the contacts' roll and pitch.
    let mut rows = Vec::new();
    let mut tilts = Vec::new();
    for s in samples {
        let c = contact(&model, &s.q, link);
        match &s.plane {
            Some(name) => {
                let plane = planes.iter().find(|(n, _)| n == name).unwrap().1;
                let g = gap(&plane, &c);
                rows.push(g[0]);
                tilts.extend([g[1], g[2]]);
            }
            None => rows.extend((c.translation.vector - s.position).iter()),
        }
    }
    let positions = rows.len();
    rows.extend(tilts);
    rows.push(positions as f64);
    rows
}

/// The Jacobian calibration linearised at its (unconverged) end, against central differences of
/// the residuals `residuals` computes, whitened as calibration whitens them.
fn check_jacobian(robot: &Robot, samples: &[Sample], link: Option<&str>, names: &[&str]) {
    let (sigma, sigma_rot) = (1e-3, 1e-2);
    let cal = calibrate(
        robot,
        samples,
        &CalibrationParams {
            identify: names.iter().map(|n| n.to_string()).collect(),
            measurement_std: sigma,
            orientation_std: sigma_rot,
            max_iterations: 2,
            restarts: 0,
            ..CalibrationParams::default()
        },
        &mut |_| {},
    )
    .unwrap();
    let lin = &cal.linearisation;
    let space = ParameterSpace::for_samples(robot, samples);
    // The residual rows end with the number of position rows (not a residual).
    let whiten = |mut r: Vec<f64>| -> Vec<f64> {
        let n = r.pop().unwrap() as usize;
        r.iter()
            .enumerate()
            .map(|(i, v)| v / if i < n { sigma } else { sigma_rot })
            .collect()
    };
    let rows = whiten(residuals(robot, &space, &lin.theta, samples, link)).len();
    assert_eq!(
        lin.jacobian.nrows(),
        rows,
        "3 rows a position, a height and two tilts a contact"
    );
    for name in names {
        let k = space.index(name).unwrap_or_else(|| panic!("no parameter {name}"));
        let c = lin
            .free
            .iter()
            .position(|&f| f == k)
            .unwrap_or_else(|| panic!("{name} is fitted"));
        let h = 1e-6;
        let at = |d: f64| {
            let mut theta = lin.theta.clone();
            theta[k] += d;
            whiten(residuals(robot, &space, &theta, samples, link))
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
                (lin.jacobian[(i, c)] - fd).abs() < 1e-5 * scale,
                "{name}, row {i}: analytic {} vs finite differences {fd}",
                lin.jacobian[(i, c)]
            );
        }
    }
}

/// Positions and contacts in one problem: each kind's rows where the residuals put them.
#[test]
fn the_mixed_jacobian_matches_finite_differences() {
    use armcomp_core::algorithms::simulate::{SimulateParams, simulate};
    let robot = robot_from_toml(&panda_text(NOMINAL_PLANES).replace("kind = \"plane\"", "kind = \"point\""));
    let truth = truth_of(&robot, &CHANGES);
    let poses = crate::common::random_configurations(&truth, 4, 9);
    let tracker = SimulateParams {
        noise_std: 0.0,
        seed: 9,
    };
    let mut samples = simulate(&truth, &poses, tracker).unwrap().samples;
    // Contacts between the positions, so that neither kind's rows come all first.
    let contacts = simulated(&truth, 2, 0.0, 6);
    samples.splice(2..2, contacts);
    check_jacobian(
        &robot,
        &samples,
        None,
        &[
            "base.x",
            "panda_joint2.offset",
            "panda_joint3.y",
            "marker.ball.z",
            "plane.table.height",
            "plane.table.roll",
            "plane.ramp.pitch",
        ],
    );
}

#[test]
fn the_plane_jacobian_matches_finite_differences() {
    // The fit stopped after two steps: the planes' tilts and the marker's turn away from zero.
    let robot = panda(NOMINAL_PLANES);
    let samples = simulated(&truth_of(&robot, &CHANGES), 6, 0.0, 5);
    check_jacobian(
        &robot,
        &samples,
        None,
        &[
            "panda_joint2.offset",
            "panda_joint3.y",
            "panda_joint5.rot_u",
            "marker.ball.z",
            "marker.ball.rx",
            "plane.table.height",
            "plane.table.roll",
            "plane.table.pitch",
            "plane.ramp.pitch",
        ],
    );
}

#[test]
fn the_frame_link_jacobian_covers_both_paths() {
    // TALOS measured from its left sole, FIGAROH's table chain: the leg's joints move the frame,
    // the torso's and the arm's the gripper (random postures: the residuals are general).
    let urdf = root().join("tests/data/urdf/talos_full_v2.urdf");
    let robot = robot_from_toml(&format!(
        "name = \"talos-table\"\nkinematics = {{ type = \"urdf\", path = \"{}\" }}\n\
         points = [{{ name = \"contact\", link = \"gripper_left_base_link\", xyz = [0.0, 0.0, -0.12] }}]\n\
         tool = \"contact\"\n[measurement]\nkind = \"plane\"\nmarkers = [\"contact\"]\n\
         frame_link = \"left_sole_link\"\nplanes = [{{ name = \"table\", xyz = [0.3, 0.28, 1.0] }}]\n",
        urdf.display()
    ));
    let samples: Vec<Sample> = crate::common::random_configurations(&robot, 8, 9)
        .into_iter()
        .map(|q| Sample {
            q,
            point: robot.markers()[0],
            position: Vector3::zeros(),
            orientation: None,
            payload: None,
            temperature: None,
            torque: None,
            fixed_point: None,
            plane: Some("table".into()),
            sensors: Default::default(),
            station: 0,
            position_std: None,
        })
        .collect();
    check_jacobian(
        &robot,
        &samples,
        Some("left_sole_link"),
        &[
            "leg_left_2_joint.offset",
            "leg_left_4_joint.x",
            "torso_2_joint.offset",
            "arm_left_3_joint.offset",
            "arm_left_5_joint.y",
            "plane.table.roll",
        ],
    );
}

#[test]
fn identifiability_says_what_a_plane_cannot_see() {
    let robot = panda("");
    let samples = simulated(&truth_of(&robot, &CHANGES), 10, 0.0, 6);
    let report = identifiability(&robot, &samples, &CalibrationParams::default()).unwrap();
    let m = &report.message;
    assert!(
        m.contains("cannot see in-plane translation nor rotation about its normal"),
        "{m}"
    );
    assert!(m.contains("scale"), "{m}");
    // Flush contact hides the contact point's in-plane offset: the rank analysis finds it.
    assert!(
        report
            .deficiencies
            .iter()
            .any(|d| d.combination.iter().any(|(n, _)| n == "marker.ball.rz")),
        "{:?}",
        report.deficiencies
    );
}

fn robot_error(text: &str) -> String {
    let src = SourceFile {
        path: "bad.toml".into(),
        text: text.into(),
        format: Format::Toml,
    };
    match src.parse::<RobotFile>() {
        Err(e) => e.to_string(),
        Ok(file) => match Robot::from_source(file, &src, InputLimits::default()) {
            Err(e) => e.to_string(),
            Ok(_) => panic!("the file is refused"),
        },
    }
}

#[test]
fn bad_plane_files_are_refused_with_their_place() {
    let twice = robot_error(&panda_text("planes = [{ name = \"t\" }, { name = \"t\" }]"));
    assert!(
        twice.contains("bad.toml") && twice.contains("measurement.planes[1].name") && twice.contains("twice"),
        "{twice}"
    );
    let constrain = robot_error(&panda_text("constrain = [\"height\", \"height\"]"));
    assert!(constrain.contains("measurement.constrain[1]"), "{constrain}");
    let unknown = robot_error(&panda_text("constrain = [\"yaw\"]"));
    assert!(unknown.contains("bad.toml") && unknown.contains("yaw"), "{unknown}");
    let root_link = robot_error(&panda_text("frame_link = \"panda_link0\""));
    assert!(
        root_link.contains("measurement.frame_link") && root_link.contains("root"),
        "{root_link}"
    );
    let missing = robot_error(&panda_text("frame_link = \"nowhere\""));
    assert!(missing.contains("`nowhere` is not a link"), "{missing}");
    let point = robot_error(&panda_text("").replace(
        "kind = \"plane\"",
        "kind = \"fixed_point\"\nplanes = [{ name = \"t\" }]",
    ));
    assert!(
        point.contains("measurement.planes[0]") && point.contains("plane contacts touch"),
        "{point}"
    );

    // Measurement files: the plane column missing, or empty on a row.
    let robot = panda("");
    let layout: CsvLayout<'_> = robot.csv_layout();
    let joints: Vec<String> = robot.csv_joint_names();
    let header = joints.iter().map(|j| format!("{j}[rad]")).collect::<Vec<_>>().join(",");
    let zeros = vec!["0.1"; joints.len()].join(",");
    let path = std::path::Path::new("contacts.csv");
    let missing = parse_csv(&format!("{header}\n{zeros}\n"), path, &layout)
        .unwrap_err()
        .to_string();
    assert!(
        missing.contains("contacts.csv") && missing.contains("missing column `plane`"),
        "{missing}"
    );
    let empty = parse_csv(&format!("{header},plane\n{zeros},table\n{zeros},\n"), path, &layout)
        .unwrap_err()
        .to_string();
    assert!(
        empty.contains("contacts.csv") && empty.contains("contacts.csv:3") && empty.contains("column `plane` is empty"),
        "{empty}"
    );
    let positions = parse_csv(&format!("{header},plane,x,y,z\n{zeros},table,1,2,3\n"), path, &layout)
        .unwrap_err()
        .to_string();
    assert!(positions.contains("gives no measured position"), "{positions}");
}

#[test]
fn simulate_calibrate_and_evaluate_planes_on_the_command_line() {
    let s = crate::common::Scratch::new("planes");
    let write = |name: &str, robot: &Robot| {
        let path = s.0.join(name);
        std::fs::write(&path, robot.to_file().to_text_for(&path).unwrap()).unwrap();
        path.display().to_string()
    };
    let nominal = panda("");
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
        "--plane",
        "table=500,0,150,180,0,0",
        "--plane",
        "ramp=350,300,250,191.46,8.59,0",
        "--n",
        "30",
        "--joint-noise-deg",
        "0.001",
        "--seed",
        "2",
        "--out",
        &data,
    ]);
    assert!(
        std::fs::read_to_string(&data)
            .unwrap()
            .lines()
            .next()
            .unwrap()
            .ends_with(",plane")
    );
    run(&[
        "calibrate",
        "--robot",
        &nominal,
        "--data",
        &data,
        "--identify",
        &CHANGES.map(|(n, _)| n).join(","),
        "--noise-mm",
        "0.02",
        "--out",
        &model,
    ]);
    let planes = |model: &str| -> serde_json::Value {
        let json: serde_json::Value =
            serde_json::from_str(&run(&["evaluate", "--model", model, "--data", &data, "--json"])).unwrap();
        json["planes"].clone()
    };
    let (before, after) = (planes(&nominal), planes(&model));
    // The nominal model names no plane: each is fitted to the rows; the model's are identified.
    assert_eq!(before["planes"][0]["fitted"], true);
    assert_eq!(after["planes"][1]["fitted"], false);
    assert_eq!(after["planes"][1]["name"], "ramp");
    let (b, a) = (before["rms_mm"].as_f64().unwrap(), after["rms_mm"].as_f64().unwrap());
    assert!(
        b > 0.2,
        "the truth's contacts seen through the nominal model: {b} mm off their planes"
    );
    assert!(a < 0.05, "calibrated: {a} mm (nominal {b} mm)");
    let tilt = after["planes"][0]["roll_rms_deg"].as_f64().unwrap();
    assert!(tilt < 0.01, "calibrated roll {tilt} deg");
}

/// `simulate` of a truth that measures positions, given planes: the tracker's rows, then the
/// contacts' naming their plane, in one file that `calibrate` fits together (the truth's
/// changes recovered) and `evaluate` scores per kind; with socket contacts too, in a second
/// file or in the same one, every kind in one fit.
#[test]
fn simulate_writes_mixed_files_that_fit_and_score_together() {
    let s = crate::common::Scratch::new("mixed-planes");
    let nominal = robot_from_toml(&panda_text("").replace("kind = \"plane\"", "kind = \"point\""));
    let write = |name: &str, robot: &Robot| {
        let path = s.0.join(name);
        std::fs::write(&path, robot.to_file().to_text_for(&path).unwrap()).unwrap();
        path.display().to_string()
    };
    let truth = write("truth.toml", &truth_of(&nominal, &CHANGES));
    let nominal = write("nominal.toml", &nominal);
    let (data, model) = (s.0.join("data.csv"), s.0.join("model.toml"));
    let (data, model) = (data.to_str().unwrap(), model.to_str().unwrap());
    let run = |args: &[&str]| {
        let (code, out, err) = crate::cli::armcomp(args);
        assert_eq!(code, 0, "{args:?}: {err}");
        out
    };
    #[rustfmt::skip]
    run(&["simulate", "--robot", &truth, "--n", "15", "--noise-mm", "0.02", "--plane", "table=500,0,150,180,0,0",
          "--plane", "ramp=350,300,250,191.46,8.59,0", "--joint-noise-deg", "0.001", "--seed", "4", "--out", data]);
    let text = std::fs::read_to_string(data).unwrap();
    let header: Vec<&str> = text.lines().next().unwrap().split(',').collect();
    let plane = header.iter().position(|c| *c == "plane").expect("a plane column");
    let x = header
        .iter()
        .position(|c| c.starts_with("x["))
        .expect("position columns");
    let rows: Vec<Vec<&str>> = text.lines().skip(1).map(|l| l.split(',').collect()).collect();
    assert_eq!(rows.len(), 15 + 2 * 15);
    // A row measures a position or names a plane, never both.
    assert!(rows.iter().all(|r| r[plane].is_empty() != r[x].is_empty()));
    assert_eq!(rows.iter().filter(|r| r[plane] == "ramp").count(), 15);
    #[rustfmt::skip]
    let report = run(&["calibrate", "--robot", &nominal, "--data", data, "--identify",
                       &CHANGES.map(|(n, _)| n).join(","), "--noise-mm", "0.02", "--json", "--out", model]);
    let report: serde_json::Value = serde_json::from_str(&report).unwrap();
    for (name, delta) in CHANGES {
        let p = report["params"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["name"] == name)
            .unwrap();
        let moved = p["value"].as_f64().unwrap() - p["initial"].as_f64().unwrap();
        let std = p["std"].as_f64().unwrap();
        assert!(
            (moved - delta).abs() < 4.0 * std,
            "{name}: moved by {moved}, truth {delta} (std {std})"
        );
    }
    let evaluate = |model: &str| -> serde_json::Value {
        serde_json::from_str(&run(&["evaluate", "--model", model, "--data", data, "--json"])).unwrap()
    };
    let (before, after) = (evaluate(&nominal), evaluate(model));
    assert_eq!(after["n"], 15, "the positions' figures count the positions");
    let f = |v: &serde_json::Value| v.as_f64().unwrap();
    assert!(
        f(&before["rms_mm"]) > 0.5 && f(&after["rms_mm"]) < 0.06,
        "{before} → {after}"
    );
    assert!(
        f(&before["planes"]["rms_mm"]) > 0.2 && f(&after["planes"]["rms_mm"]) < 0.05,
        "{before} → {after}"
    );
    // A second file, of positions and socket contacts: every kind in one fit, each file its own
    // station, the truth's changes recovered more tightly than from the first file alone; and
    // positions, socket and table contacts in one file.
    let (sockets, all) = (s.0.join("sockets.csv"), s.0.join("all.csv"));
    let (sockets, all) = (sockets.to_str().unwrap(), all.to_str().unwrap());
    #[rustfmt::skip]
    run(&["simulate", "--robot", &truth, "--n", "15", "--noise-mm", "0.02", "--fixed-point", "a=500,0,100",
          "--joint-noise-deg", "0.001", "--seed", "5", "--out", sockets]);
    #[rustfmt::skip]
    run(&["simulate", "--robot", &truth, "--n", "15", "--noise-mm", "0.02", "--fixed-point", "a=500,0,100",
          "--plane", "table=500,0,150,180,0,0", "--joint-noise-deg", "0.001", "--seed", "6", "--out", all]);
    assert!(
        std::fs::read_to_string(all)
            .unwrap()
            .lines()
            .next()
            .unwrap()
            .contains(",fixed_point,plane,")
    );
    let param = |report: &serde_json::Value, name: &str| {
        let p = report["params"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["name"] == name)
            .cloned();
        p.unwrap_or_else(|| panic!("no {name}"))
    };
    for files in [&["--data", data, "--data", sockets][..], &["--data", all]] {
        // The two files hold the first one's rows and more.
        let superset = files.contains(&sockets);
        let identify = CHANGES.map(|(n, _)| n).join(",");
        let args = [
            &["calibrate", "--robot", &nominal][..],
            files,
            &["--identify", &identify],
        ];
        let args = [&args.concat()[..], &["--noise-mm", "0.02", "--json", "--out", model]].concat();
        let fitted: serde_json::Value = serde_json::from_str(&run(&args)).unwrap();
        for (name, delta) in CHANGES {
            let (p, alone) = (param(&fitted, name), param(&report, name));
            let moved = p["value"].as_f64().unwrap() - p["initial"].as_f64().unwrap();
            let std = p["std"].as_f64().unwrap();
            assert!(
                (moved - delta).abs() < 4.0 * std && (!superset || std < alone["std"].as_f64().unwrap()),
                "{files:?}, {name}: moved by {moved}, truth {delta} (std {std}; one file {})",
                alone["std"]
            );
        }
        for name in ["plane.table.height", "fixed_point.a.x"] {
            param(&fitted, name);
        }
    }
    #[rustfmt::skip]
    run(&["calibrate", "--robot", &nominal, "--data", data, "--data", sockets, "--identify",
          &CHANGES.map(|(n, _)| n).join(","), "--noise-mm", "0.02", "--out", model]);
    // Each station's figures are its measured positions', the contacts have their own.
    let scores = run(&[
        "evaluate", "--model", model, "--data", data, "--data", sockets, "--json",
    ]);
    let scores: serde_json::Value = serde_json::from_str(&scores).unwrap();
    let per_station: Vec<(&str, u64)> = (scores["per_station"].as_array().unwrap().iter())
        .map(|s| (s["station"].as_str().unwrap(), s["n"].as_u64().unwrap()))
        .collect();
    assert_eq!(per_station, [("data", 15), ("sockets", 15)], "{scores}");
    assert_eq!(scores["n"], 30);
    assert!(
        scores["planes"].is_object() && scores["fixed_points"].is_object(),
        "{scores}"
    );
}

/// The prior's cross-validation scores plane contacts by their held-out height above the
/// plane the training folds identified: priors too tight to let the joint offsets move leave
/// the truth's millimetre errors; the file's priors come down to the height noise the truth
/// itself shows on the same rows (its own planes fitted to them), on three seeds.
#[test]
fn the_prior_choice_scores_plane_contacts_by_their_held_out_height() {
    let nominal = panda("");
    let truth = truth_of(&nominal, &CHANGES);
    for seed in 1..=3 {
        let samples = simulated(&truth, 40, 2e-5, 20 + seed);
        let (gaps, _) = armcomp_core::calibrate::contact_gaps(&truth, &samples).unwrap();
        let noise =
            (gaps.iter().flatten().map(|g| g.height * g.height).sum::<f64>() / samples.len() as f64).sqrt() * 1e3;
        let params = CalibrationParams {
            identify: CHANGES.iter().map(|(n, _)| n.to_string()).collect(),
            measurement_std: 3e-5,
            orientation_std: 6e-5,
            ..CalibrationParams::default()
        };
        let plan = armcomp_core::data::split::FoldPlan {
            k: 4,
            seed,
            by: armcomp_core::data::split::FoldBy::Poses,
        };
        let choice = armcomp_core::analysis::prior_choice::choose_prior_scale(
            &nominal,
            &samples,
            &params,
            &[1e-3, 1.0],
            &plan,
            &|_| {},
        )
        .unwrap();
        let [tight, file] = [0, 1].map(|i| choice.scores[i].held_out_rms_mm);
        assert_eq!(choice.scale, 1.0, "seed {seed}: {:?}", choice.scores);
        assert!(tight > 10.0 * file, "seed {seed}: {tight} mm against {file} mm");
        assert!(
            file > 0.8 * noise && file < 2.0 * noise,
            "seed {seed}: held-out height {file} mm, the truth's own {noise} mm"
        );
    }
}

/// The ladder of `robot` on contacts alone (`samples`), each rung scored by what those rows
/// measure, with a GP asked for; returns the ladder's report.
pub fn climb_contacts(robot: &Robot, samples: &[Sample], seed: u64) -> armcomp_core::analysis::ladder::LadderReport {
    let calibration = CalibrationParams {
        measurement_std: 3e-5,
        orientation_std: 6e-5,
        ..CalibrationParams::default()
    };
    // One draw of the folds: what is checked is how a held-out contact is scored.
    let params = armcomp_core::analysis::ladder::LadderParams {
        folds: 4,
        repeats: 1,
        seed,
        predictor: Some(Box::new(armcomp_learn::GpSpec::default())),
        ..armcomp_core::analysis::ladder::LadderParams::new(calibration, true)
    };
    armcomp_core::analysis::ladder::climb(robot, samples, &params, &|_| {})
        .unwrap()
        .report
}

#[test]
fn the_ladder_scores_plane_contacts_by_their_held_out_height() {
    use armcomp_core::analysis::ladder::Rung;
    let nominal = panda("");
    let truth = truth_of(&nominal, &CHANGES);
    for seed in 1..=3 {
        let samples = simulated(&truth, 40, 2e-5, 40 + seed);
        let (gaps, _) = armcomp_core::calibrate::contact_gaps(&truth, &samples).unwrap();
        let noise =
            (gaps.iter().flatten().map(|g| g.height * g.height).sum::<f64>() / samples.len() as f64).sqrt() * 1e3;
        let report = climb_contacts(&nominal, &samples, seed);
        assert_eq!(report.scored_by, "plane height");
        // The truth's joint offsets move the contacts by millimetres: registration alone
        // (the planes' poses and the ball) leaves them, a rung with the offsets does not.
        let registration = report.candidates[0].rms_mm;
        assert!(
            report.chosen.rung != Rung::Registration && registration > 10.0 * report.expected_rms_mm,
            "seed {seed}: {:?}",
            report.candidates
        );
        // The best of a grid of candidates on 40 rows lies somewhat below what any one of them
        // gives on new rows: the truth's own heights are the scale, not a bound.
        assert!(
            report.expected_rms_mm > 0.7 * noise && report.expected_rms_mm < 2.0 * noise,
            "seed {seed}: expected held-out height {} mm, the truth's own {noise} mm ({})",
            report.expected_rms_mm,
            report.chosen.label()
        );
        assert!(report.predictor_not_tried.is_some() && report.candidates.iter().all(|c| !c.candidate.predictor));
    }
}

/// A joint that turns 1 % further than commanded is named from plane contacts alone, each
/// held-out contact scored by its height above the plane its fold identified (three seeds).
#[test]
fn the_diagnosis_names_an_effect_from_plane_contacts_alone() {
    let nominal = panda("");
    let truth = with_transmission_scale(&nominal, "panda_joint2", 0.01);
    for seed in 1..=3 {
        let samples = simulated(&truth, 60, 2e-5, 80 + seed);
        let calibration = CalibrationParams {
            measurement_std: 3e-5,
            orientation_std: 6e-5,
            ..Default::default()
        };
        assert_diagnosis_names(
            &nominal,
            &samples,
            calibration,
            ("transmission_scale", "panda_joint2"),
            0.2,
            seed,
        );
    }
}

/// FIGAROH's TALOS table contacts beside the repository (see docs/reproductions/talos-table.md):
/// the nominal model's gap on the validation postures is the published one, and each chain
/// calibrated on its training postures beats FIGAROH's published one-chain held-out figure
/// (9.26 mm left, 8.03 mm right).
#[test]
fn talos_table_contacts_beat_the_published_one_chain_figures() {
    let dir = root().join("../shared/data/talos-table-contact");
    if !dir.join("left_train.csv").is_file() {
        eprintln!(
            "skipped: {} not found (see docs/reproductions/talos-table.md)",
            dir.display()
        );
        return;
    }
    // Every row: 5 metadata fields, then the 32 joints (rad) that the header's fields 6–37 name.
    let read = |robot: &Robot, file: &str| -> Vec<Sample> {
        let text = std::fs::read_to_string(dir.join(file)).unwrap();
        let mut lines = text.lines();
        let header: Vec<&str> = lines.next().unwrap().split(',').collect();
        let mut csv = header[5..37]
            .iter()
            .map(|h| format!("{h}[rad]"))
            .collect::<Vec<_>>()
            .join(",");
        csv.push_str(",plane\n");
        for line in lines.filter(|l| !l.trim().is_empty()) {
            let fields: Vec<&str> = line.split(',').collect();
            csv.push_str(&format!("{},table\n", fields[5..37].join(",")));
        }
        parse_csv(&csv, std::path::Path::new(file), &robot.csv_layout())
            .unwrap()
            .samples
    };
    let gap = |robot: &Robot, samples: &[Sample]| {
        let mut errors = armcomp_core::algorithms::evaluate::model_errors(robot, samples);
        let planes = armcomp_core::calibrate::evaluate_planes(robot, samples, &mut errors);
        planes.unwrap().expect("plane rows").rms_mm
    };
    let cases = [
        ("left", "left_train.csv", "left_validation_fixed.csv", 288.2, 9.26),
        (
            "right",
            "right_train_fixed.csv",
            "right_validation_fixed.csv",
            292.0,
            8.03,
        ),
    ];
    for (side, train, validation, before, published) in cases {
        let robot = crate::common::robot(&format!("talos-table-{side}.toml"));
        let test = read(&robot, validation);
        let nominal = gap(&robot, &test);
        assert!(
            (nominal - before).abs() < 0.05,
            "{side}: nominal gap {nominal} mm, published {before}"
        );
        let params = CalibrationParams {
            identify: ["geometry", "marker.contact.rx", "marker.contact.ry"]
                .map(String::from)
                .to_vec(),
            measurement_std: 1e-3,
            orientation_std: 0.3f64.to_radians(),
            ..Default::default()
        };
        let cal = calibrate(&robot, &read(&robot, train), &params, &mut |_| {}).unwrap();
        assert!(cal.report.converged, "{side}: {}", cal.report.stop_reason);
        let held_out = gap(&cal.robot, &test);
        println!("{side}: held-out gap {held_out:.3} mm (FIGAROH {published} mm)");
        assert!(
            held_out < published,
            "{side}: held-out gap {held_out} mm, FIGAROH {published} mm"
        );
    }
}
