//! Several stations (instrument set-ups), each its own measurement frame, against a simulated
//! truth whose geometry and station frames are known: joint calibration recovers both, a
//! station column of one value changes nothing, a new station is registered for evaluation,
//! and cross-validation holds out whole stations.

use armcomp_core::algorithms::evaluate::{ErrorStats, position_errors};
use armcomp_core::algorithms::simulate::{SimulateParams, random_stations, simulate};
use armcomp_core::calibrate::{CalibrationParams, ParameterSpace, calibrate, register_stations};
use armcomp_core::data::measurement::{MeasurementSet, parse_csv, write_csv};
use armcomp_core::model::sampling::{Sampler, configurations};
use armcomp_core::{FitControl, Robot, Station};

use crate::common::robot;

const NOISE: f64 = 0.05e-3; // m per axis

/// The nominal industrial arm and a truth with its geometry moved (changes, SI) and `k`
/// random stations drawn from `seed`.
fn truth_with_stations(k: usize, seed: u64) -> (Robot, Robot, Vec<(&'static str, f64)>) {
    let nominal = robot("industrial-6dof.toml");
    let deg = 1f64.to_radians();
    let changes = vec![
        ("j2.alpha", 0.2 * deg),
        ("j3.a", 1e-3),
        ("j3.beta", 0.1 * deg),
        ("j4.d", -1.5e-3),
        ("j5.theta", 0.3 * deg),
    ];
    let space = ParameterSpace::new(&nominal);
    let mut theta = space.initial();
    for (name, delta) in &changes {
        theta[space.index(name).unwrap()] += delta;
    }
    let mut truth = space.apply(&nominal, &theta).unwrap();
    let stations = random_stations(&truth, k, seed);
    truth.set_stations(stations);
    (nominal, truth, changes)
}

fn measure(truth: &Robot, n: usize, seed: u64) -> MeasurementSet {
    let poses = configurations(truth.tree(), Sampler::Sobol, n, seed).unwrap();
    measure_at(truth, &poses, seed + 1000)
}

/// How far frame `a` is from `b`: translation (m) and rotation (rad).
fn frame_gap(a: &nalgebra::Isometry3<f64>, b: &nalgebra::Isometry3<f64>) -> (f64, f64) {
    let d = a.inverse() * b;
    (d.translation.vector.norm(), d.rotation.angle())
}

#[test]
fn three_stations_share_the_geometry_and_each_frame_is_recovered() {
    let (mut nominal, truth, changes) = truth_with_stations(3, 21);
    let data = measure(&truth, 180, 3);
    assert_eq!(data.stations, ["st1", "st2", "st3"]);
    // The stations really differ: metres and tens of degrees apart.
    let (shift, turn) = frame_gap(&truth.station_frame(1), &truth.station_frame(2));
    assert!(shift > 0.3 && turn > 0.2, "{shift} m, {turn} rad");
    assert_eq!(nominal.adopt_stations(&data.stations), [0, 1, 2]);
    let params = CalibrationParams {
        measurement_std: NOISE,
        ..Default::default()
    };
    let cal = calibrate(&nominal, &data.samples, &params, &mut |_| {}).unwrap();
    let r = &cal.report;
    assert!(r.converged, "{}", r.stop_reason);
    assert!(r.registered);
    // Geometry shared by the stations, recovered within its uncertainty.
    let space = ParameterSpace::new(&nominal);
    let truth_theta = ParameterSpace::new(&truth).initial();
    for (name, _) in &changes {
        let p = r.params.iter().find(|p| p.name == *name).unwrap();
        let t = truth_theta[space.index(name).unwrap()];
        assert!(
            (p.value - t).abs() < 4.0 * p.std + 1e-9,
            "{name}: identified {}, truth {t}, std {}",
            p.value,
            p.std
        );
    }
    // Each station's frame within the noise: a tenth of a millimetre, a hundredth of a degree.
    assert_eq!(cal.robot.stations().len(), 3);
    for (k, station) in cal.robot.stations().iter().enumerate() {
        assert_eq!(station.name, truth.stations()[k].name);
        let (shift, turn) = frame_gap(&station.frame, &truth.station_frame(k));
        assert!(
            shift < 0.1e-3 && turn < 0.01f64.to_radians(),
            "station {}: {shift} m, {turn} rad off",
            station.name
        );
    }
    for name in ["base[st2].x", "base[st3].yaw", "base[st1].roll"] {
        assert!(r.params.iter().any(|p| p.name == name), "no {name}");
    }
    assert!(!r.params.iter().any(|p| p.name == "base.x"));
    // Every station fits to the noise: √3·σ RMS in 3-D.
    assert_eq!(r.per_station.len(), 3);
    for st in &r.per_station {
        assert_eq!(st.stats.n, 60);
        assert!(
            st.stats.rms_mm < 1.2 * 3f64.sqrt() * NOISE * 1e3,
            "{}: {}",
            st.station,
            st.stats.rms_mm
        );
    }

    // One frame for all the data cannot fit them: the stations are metres apart.
    let one_frame = robot("industrial-6dof.toml");
    let mut pooled = data.samples.clone();
    pooled.iter_mut().for_each(|s| s.station = 0);
    let single = calibrate(&one_frame, &pooled, &params, &mut |_| {}).unwrap().report;
    assert!(single.after.rms_mm > 100.0 * r.after.rms_mm, "{}", single.after.rms_mm);
}

#[test]
fn a_station_column_of_one_value_changes_nothing() {
    let (nominal, truth, _) = truth_with_stations(1, 0);
    let mut data = measure(&truth, 60, 5);
    assert!(data.stations.is_empty());
    let params = CalibrationParams {
        measurement_std: NOISE,
        ..Default::default()
    };
    // The same rows written without and with a `station` column naming one station, read back.
    let layout = nominal.csv_layout();
    let without = write_csv(&data, truth.tree(), truth.units());
    let without = parse_csv(&without, std::path::Path::new("plain.csv"), &layout).unwrap();
    let plain = calibrate(&nominal, &without.samples, &params, &mut |_| {}).unwrap();
    data.stations = vec!["north".into()];
    let text = write_csv(&data, truth.tree(), truth.units());
    assert!(text.starts_with("j1") && text.contains(",station,") && text.contains(",north,"));
    let read = parse_csv(&text, std::path::Path::new("one.csv"), &layout).unwrap();
    assert_eq!(read.stations, ["north"]);
    let mut named = robot("industrial-6dof.toml");
    assert!(named.adopt_stations(&read.stations).is_empty());
    assert!(named.stations().is_empty());
    let with_column = calibrate(&named, &read.samples, &params, &mut |_| {}).unwrap();
    let names = |c: &armcomp_core::calibrate::Calibration| -> Vec<String> {
        c.report.params.iter().map(|p| p.name.clone()).collect()
    };
    assert_eq!(names(&plain), names(&with_column));
    assert!(names(&plain).contains(&"base.x".to_string()));
    for (a, b) in plain.report.params.iter().zip(&with_column.report.params) {
        assert_eq!(a.value, b.value, "{}", a.name);
    }
    assert!(with_column.report.per_station.is_empty());
    assert!(with_column.robot.to_file().measurement.unwrap().stations.is_empty());
}

#[test]
fn a_new_station_is_registered_for_evaluation() {
    let (mut nominal, truth, _) = truth_with_stations(2, 4);
    let data = measure(&truth, 120, 7);
    nominal.adopt_stations(&data.stations);
    let params = CalibrationParams {
        measurement_std: NOISE,
        ..Default::default()
    };
    let mut model = calibrate(&nominal, &data.samples, &params, &mut |_| {}).unwrap().robot;
    // The truth measured again from a station of its own, which the model has never seen.
    let far = random_stations(&truth, 3, 99).pop().unwrap();
    let space = ParameterSpace::new(&truth);
    let mut truth_there = space.apply(&truth, &space.initial()).unwrap();
    truth_there.set_stations(vec![Station {
        name: "east".into(),
        frame: far.frame,
    }]);
    let mut new_data = measure(&truth_there, 50, 8);
    new_data.stations = vec!["east".into()];
    let new = model.adopt_stations(&new_data.stations);
    assert_eq!(new, [0]);
    // Seen through the model's first frame, the new station's points are metres off.
    let unregistered = ErrorStats::from_errors(&position_errors(&model, &new_data.samples));
    assert!(unregistered.rms_mm > 100.0, "{}", unregistered.rms_mm);
    assert!(
        register_stations(&mut model, &new_data.samples, &new)
            .unwrap()
            .is_empty()
    );
    let (shift, turn) = frame_gap(&model.station_frame(0), &far.frame);
    assert!(shift < 0.1e-3 && turn < 0.01f64.to_radians(), "{shift} m, {turn} rad");
    let registered = ErrorStats::from_errors(&position_errors(&model, &new_data.samples));
    assert!(
        registered.rms_mm < 1.3 * 3f64.sqrt() * NOISE * 1e3,
        "{}",
        registered.rms_mm
    );
}

#[test]
fn an_empty_station_cell_names_its_line() {
    let nominal = robot("industrial-6dof.toml");
    let text = "j1[deg],j2[deg],j3[deg],j4[deg],j5[deg],j6[deg],station,x[mm],y[mm],z[mm]\n\
                0,0,0,0,0,0,a,1000,0,500\n\
                # a comment\n\
                0,10,0,0,0,0,,1000,0,400\n";
    let e = parse_csv(text, std::path::Path::new("s.csv"), &nominal.csv_layout()).unwrap_err();
    let message = e.to_string();
    assert!(
        message.contains("s.csv") && message.contains(":4") && message.contains("station"),
        "{message}"
    );
}

/// A signal planted per group: each station's poses cluster in joint space and carry an offset
/// of their own (a set-up error no model term has). A nearest-neighbour predictor scored on
/// random folds finds each held-out pose's offset in its own station's other poses and looks
/// far better than it is; folds that hold out whole stations see it predict a station it has
/// never seen, as it would in use.
#[test]
fn grouped_folds_see_through_a_signal_planted_per_station() {
    use armcomp_core::algorithms::evaluate::cross_validated_predictor_errors;
    use armcomp_core::data::split::FoldBy;
    use rand::{Rng, SeedableRng};

    let (groups, per_group) = (6, 25);
    let mut truth = robot("industrial-6dof.toml");
    let names: Vec<String> = (1..=groups).map(|g| format!("g{g}")).collect();
    truth.adopt_stations(&names);
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let centres = configurations(truth.tree(), Sampler::Random, groups, 9).unwrap();
    let poses: Vec<Vec<f64>> = centres
        .iter()
        .flat_map(|c| {
            let c = c.clone();
            (0..per_group)
                .map(|_| c.iter().map(|v| v + rng.random_range(-0.05..0.05)).collect())
                .collect::<Vec<Vec<f64>>>()
        })
        .collect();
    let mut data = measure_at(&truth, &poses, 1);
    let offsets: Vec<nalgebra::Vector3<f64>> = (0..groups)
        .map(|_| nalgebra::Vector3::from_fn(|_, _| rng.random_range(-2e-3..2e-3)))
        .collect();
    for s in &mut data.samples {
        s.position += offsets[s.station];
    }
    let planted_rms = (offsets.iter().map(|o| o.norm_squared()).sum::<f64>() / groups as f64).sqrt() * 1e3;
    let knn = armcomp_learn::KnnSpec::default();
    let (random, random_folds) = cross_validated_predictor_errors(
        &truth,
        &knn,
        &data.samples,
        5,
        0,
        &FoldBy::Poses,
        &FitControl::default(),
    )
    .unwrap();
    let by = FoldBy::choose(&data.samples, None);
    assert_eq!(by, FoldBy::Stations);
    let (grouped, grouped_folds) =
        cross_validated_predictor_errors(&truth, &knn, &data.samples, 5, 0, &by, &FitControl::default()).unwrap();
    assert_eq!(random_folds.to_string(), "folds: 5, grouped by pose");
    assert_eq!(grouped_folds.to_string(), "folds: 5, grouped by station");
    // Random folds: the station's own offset is learned from its neighbours.
    assert!(
        random.rms_mm < 0.3 * planted_rms,
        "random folds {} mm of {planted_rms}",
        random.rms_mm
    );
    // Grouped folds: a new station's offset cannot be predicted; the score says so.
    assert!(
        grouped.rms_mm > 0.7 * planted_rms,
        "grouped folds {} mm of {planted_rms}",
        grouped.rms_mm
    );
}

fn measure_at(truth: &Robot, poses: &[Vec<f64>], seed: u64) -> MeasurementSet {
    simulate(truth, poses, SimulateParams { noise_std: NOISE, seed }).unwrap()
}

/// A residual predictor learned at one station lowers the error at another: it predicts in the
/// robot's base frame, so re-registering the model at the new station (`--identify base`)
/// keeps it, and it follows the robot. The truth is the boom's hidden one (bending and effects
/// the rigid model lacks); held-out rows of the second station, on three seeds.
#[test]
fn a_predictor_learned_at_one_station_lowers_the_error_at_another() {
    let gp = armcomp_learn::GpSpec {
        max_optimization_samples: 60,
        max_iterations: 15,
        ..Default::default()
    };
    let with_identify = |identify: &[&str]| CalibrationParams {
        identify: identify.iter().map(|s| s.to_string()).collect(),
        measurement_std: NOISE,
        ..Default::default()
    };
    for seed in [1, 2, 3] {
        let mut truth = robot("rock-drill-truth.toml");
        truth.set_stations(random_stations(&truth, 2, seed));
        let data = measure(&truth, 400, seed);
        // Each station as a user has it: a data set in its own instrument frame.
        let at = |k: usize| -> Vec<_> {
            let rows = data.samples.iter().filter(|s| s.station == k);
            rows.map(|s| armcomp_core::data::measurement::Sample {
                station: 0,
                ..s.clone()
            })
            .collect()
        };
        let (a, b) = (at(0), at(1));
        let (register, held_out) = b.split_at(40);
        // Station A: the geometry, then the predictor of what it leaves.
        let nominal = robot("rock-drill.toml");
        let model = calibrate(&nominal, &a, &with_identify(&["base", "geometry"]), &mut |_| {})
            .unwrap()
            .robot;
        let mut file = model.to_file();
        file.fitted_predictor = Some(
            armcomp_core::algorithms::evaluate::fit_residual_predictor(&model, &gp, &a, &FitControl::default())
                .unwrap(),
        );
        file.predictor_frame = Some(armcomp_core::robot::robot_file::PredictorFrame::Base);
        let learned = model.rebuild(file).unwrap();
        // Station B: only the frame registered, with and without the predictor.
        let moved = calibrate(&learned, register, &with_identify(&["base"]), &mut |_| {}).unwrap();
        let carried = moved
            .report
            .fitted_predictor
            .as_ref()
            .expect("the report says what became of it");
        assert!(carried.kept, "{}", carried.reason);
        assert!(moved.robot.predictor().is_some());
        let bare = calibrate(&model, register, &with_identify(&["base"]), &mut |_| {}).unwrap();
        let with = ErrorStats::from_errors(&position_errors(&moved.robot, held_out)).rms_mm;
        let without = ErrorStats::from_errors(&position_errors(&bare.robot, held_out)).rms_mm;
        // The same predictor read in the measurement frame it was learned in: what a predictor
        // that does not follow the robot gives at the new station.
        let mut file = moved.robot.to_file();
        file.fitted_predictor = Some(
            armcomp_core::algorithms::evaluate::fit_residual_predictor(&model, &gp, &a, &FitControl::default())
                .unwrap(),
        );
        file.predictor_frame = Some(armcomp_core::robot::robot_file::PredictorFrame::Measurement);
        let stuck = moved.robot.rebuild(file).unwrap();
        let in_old_frame = ErrorStats::from_errors(&position_errors(&stuck, held_out)).rms_mm;
        println!(
            "seed {seed}: held-out RMS at station B {without:.4} mm without the predictor, {with:.4} mm with it \
             (in the base frame), {in_old_frame:.4} mm read in station A's frame"
        );
        assert!(
            with < 0.7 * without,
            "seed {seed}: {with} mm with, {without} mm without"
        );
        // Learning the geometry again would drop it, and say so.
        let refit = calibrate(&learned, register, &with_identify(&["base", "offsets"]), &mut |_| {}).unwrap();
        assert!(!refit.report.fitted_predictor.unwrap().kept);
        assert!(refit.robot.predictor().is_none());
    }
}

/// The same from the command line: `learn` writes the predictor in the base frame, and
/// `calibrate --identify base` at another station keeps it, says so, and the model it writes
/// predicts that station's other rows better than the re-registered model without it.
#[test]
fn the_command_line_carries_a_learned_predictor_to_another_station() {
    use crate::cli::armcomp;
    let dir = crate::common::Scratch::new("predictor-station");
    let path = |name: &str| dir.file(name, "").display().to_string();
    let all = path("all.csv");
    let (code, _, err) = armcomp(&[
        "simulate",
        "--robot",
        "robots/rock-drill-truth.toml",
        "--stations",
        "2",
        "--n",
        "240",
        "--noise-mm",
        "0.05",
        "--seed",
        "4",
        "--out",
        &all,
    ]);
    assert_eq!(code, 0, "{err}");
    // One file per station, as two set-ups give them.
    let text = std::fs::read_to_string(&all).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap();
    let column = header
        .split(',')
        .position(|c| c == "station")
        .expect("a station column");
    let (a, b) = (path("a.csv"), path("b.csv"));
    for (file, name) in [(&a, "st1"), (&b, "st2")] {
        let rows: Vec<&str> = text
            .lines()
            .skip(1)
            .filter(|l| l.split(',').nth(column) == Some(name))
            .collect();
        assert!(rows.len() > 80, "{name}: {} rows", rows.len());
        std::fs::write(file, format!("{header}\n{}\n", rows.join("\n"))).unwrap();
    }
    let (model, learned, moved, bare) = (path("m.toml"), path("ml.toml"), path("mb.toml"), path("b0.toml"));
    // Exit 3: the rigid model ends far above the noise, as it should on the boom.
    let run = |args: &[&str]| {
        let (code, out, err) = armcomp(args);
        assert!(code == 0 || code == 3, "{args:?}: {err}");
        out
    };
    run(&[
        "calibrate",
        "--robot",
        "robots/rock-drill.toml",
        "--data",
        &a,
        "--identify",
        "base,geometry",
        "--out",
        &model,
    ]);
    run(&[
        "learn",
        "--model",
        &model,
        "--data",
        &a,
        "--predictor",
        "gp",
        "--out",
        &learned,
    ]);
    assert!(
        std::fs::read_to_string(&learned)
            .unwrap()
            .contains("predictor_frame = \"base\"")
    );
    let register = |from: &str, to: &str| {
        run(&[
            "calibrate",
            "--robot",
            from,
            "--data",
            &b,
            "--rows",
            "0..40",
            "--identify",
            "base",
            "--out",
            to,
        ])
    };
    let out = register(&learned, &moved);
    assert!(out.contains("fitted predictor kept"), "{out}");
    register(&model, &bare);
    let rms = |m: &str| {
        let out = run(&["evaluate", "--model", m, "--data", &b, "--rows", "40..", "--json"]);
        let v: serde_json::Value = serde_json::from_str(&out).unwrap();
        v["rms_mm"].as_f64().unwrap_or_else(|| panic!("no rms_mm in {v}"))
    };
    let (with, without) = (rms(&moved), rms(&bare));
    assert!(
        with < 0.7 * without,
        "{with} mm with the predictor, {without} mm without"
    );
}

/// `--group-by COLUMN` folds the cross-validation of `learn`, `calibrate --prior auto` and
/// `diagnose` by a column's values, as `fit` does, and the reports say so.
#[test]
fn group_by_a_column_folds_every_cross_validation_and_says_so() {
    use crate::cli::armcomp;
    let dir = crate::common::Scratch::new("group-by");
    // Four sessions of ten rows.
    let (_, data) = forty_rows_with(&dir, "session", |row| format!("s{}", row / 10));
    let out = |name: &str| dir.file(name, "").display().to_string();
    let (m1, m2) = (out("m1.toml"), out("m2.toml"));
    let (code, stdout, err) = armcomp(&[
        "calibrate",
        "--robot",
        "robots/industrial-6dof.toml",
        "--data",
        &data,
        "--prior",
        "auto",
        "--group-by",
        "session",
        "--out",
        &m1,
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("grouped by session"), "{stdout}");
    let (code, stdout, err) = armcomp(&[
        "learn",
        "--model",
        &m1,
        "--data",
        &data,
        "--predictor",
        "ridge",
        "--group-by",
        "session",
        "--out",
        &m2,
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("folds: 4, grouped by session"), "{stdout}");
    // Without --prior auto nothing is cross-validated: the flag would be silently ignored.
    let (code, _, err) = armcomp(&[
        "calibrate",
        "--robot",
        "robots/industrial-6dof.toml",
        "--data",
        &data,
        "--group-by",
        "session",
        "--out",
        &m1,
    ]);
    assert_ne!(code, 0);
    assert!(err.contains("--group-by") && err.contains("--prior auto"), "{err}");
    // A column the file does not have is named with the header.
    let (code, _, err) = armcomp(&[
        "diagnose",
        "--robot",
        "robots/industrial-6dof.toml",
        "--data",
        &data,
        "--group-by",
        "day",
    ]);
    assert_ne!(code, 0);
    assert!(err.contains("no column `day`") && err.contains("session"), "{err}");
}

/// Each station of `fitted` within the noise of the truth's: a tenth of a millimetre, a
/// hundredth of a degree.
fn assert_stations_recovered(fitted: &Robot, truth: &Robot, what: &str) {
    assert_eq!(fitted.stations().len(), truth.stations().len(), "{what}");
    for (k, station) in fitted.stations().iter().enumerate() {
        assert_eq!(station.name, truth.stations()[k].name, "{what}");
        let (shift, turn) = frame_gap(&station.frame, &truth.station_frame(k));
        assert!(
            shift < 0.1e-3 && turn < 0.01f64.to_radians(),
            "{what}, station {}: {shift} m, {turn} rad off",
            station.name
        );
    }
}

#[test]
fn fit_gives_the_robot_the_data_stations_and_registers_each() {
    // The nominal robot knows no station; the data hold three, metres apart.
    let (nominal, truth, _) = truth_with_stations(3, 23);
    let data = measure(&truth, 150, 5);
    assert!(nominal.stations().is_empty());
    let params = armcomp_api::ops::fit::FitParams {
        noise_mm: Some(NOISE * 1e3),
        noise_deg: None,
        folds: 3,
        repeats: Some(1),
        seed: 0,
        fold_groups: None,
        predictor: None,
        cancel: Default::default(),
    };
    let ladder = armcomp_api::ops::fit::run(&nominal, &data, params, &|_| {}).unwrap();
    assert_eq!(ladder.report.folds_by, "station");
    assert_stations_recovered(&ladder.robot, &truth, "fit");
    // Every held-out station is registered before it is scored, so the chosen rung's error
    // is the noise's (√3·σ in 3-D), not the metres between the stations.
    assert!(
        ladder.report.expected_rms_mm < 2.0 * 3f64.sqrt() * NOISE * 1e3,
        "{}",
        ladder.report.expected_rms_mm
    );
}

#[test]
fn diagnose_gives_the_robot_the_data_stations_and_registers_each() {
    let (nominal, truth, _) = truth_with_stations(3, 29);
    let data = measure(&truth, 150, 7);
    let params = armcomp_core::analysis::diagnose::DiagnoseParams {
        max_steps: 1,
        calibration: CalibrationParams {
            measurement_std: NOISE,
            ..Default::default()
        },
        ..Default::default()
    };
    let diagnosis = armcomp_api::ops::diagnose::run(
        &nominal,
        &data,
        &params,
        armcomp_api::ops::diagnose::LearnableBy::None,
        &|_| {},
    )
    .unwrap();
    assert_eq!(diagnosis.report.grouped_by, "station");
    assert_stations_recovered(&diagnosis.robot, &truth, "diagnose");
    // Geometry the truth moved, fitted across the stations: held out, at the noise.
    assert!(
        diagnosis.report.initial.rms_mm < 2.0 * 3f64.sqrt() * NOISE * 1e3,
        "{}",
        diagnosis.report.initial.rms_mm
    );
}

#[test]
fn fit_and_diagnose_read_stations_from_the_command_line() {
    use crate::cli::armcomp;
    let dir = crate::common::Scratch::new("fit-diagnose-stations");
    let data = dir.file("all.csv", "").display().to_string();
    let (code, _, err) = armcomp(&[
        "simulate",
        "--robot",
        "robots/industrial-6dof-truth.toml",
        "--stations",
        "3",
        "--n",
        "120",
        "--noise-mm",
        "0.05",
        "--seed",
        "2",
        "--out",
        &data,
    ]);
    assert_eq!(code, 0, "{err}");
    let out = dir.file("fitted.toml", "").display().to_string();
    for args in [
        // The noise is left to the data: the truth has effects the nominal robot lacks, so a
        // declared 0.05 mm would rightly make `fit` exit 3 (far above the declared noise).
        vec!["fit", "--folds", "3", "--predictor", "none"],
        vec!["diagnose", "--max-steps", "1", "--predictor", "none"],
    ] {
        let mut args = args.clone();
        args.extend(["--robot", "robots/industrial-6dof.toml", "--data", &data, "--out", &out]);
        let (code, _, err) = armcomp(&args);
        // 0, or 2 for a chosen fit that did not converge; never the refusal (1).
        assert!(code == 0 || code == 2, "{args:?}: {err}");
        let model = Robot::from_path(std::path::Path::new(&out)).unwrap();
        let names: Vec<&str> = model.stations().iter().map(|s| s.name.as_str()).collect();
        assert_eq!(names, ["st1", "st2", "st3"], "{}", args[0]);
    }
}

/// `compensate` on a model of three stations: targets "in the measurement frame" are refused,
/// naming the stations; with `--station st2` its commands are those for the same targets moved
/// into the base frame by station st2's frame by hand and given with `--frame base`.
#[test]
fn compensate_takes_the_station_the_targets_are_given_in() {
    use crate::cli::armcomp;
    let dir = crate::common::Scratch::new("compensate-station");
    let data = dir.file("all.csv", "").display().to_string();
    let model = dir.file("model.toml", "").display().to_string();
    let (code, _, err) = armcomp(&[
        "simulate",
        "--robot",
        "robots/industrial-6dof-truth.toml",
        "--stations",
        "3",
        "--n",
        "60",
        "--seed",
        "4",
        "--out",
        &data,
    ]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = armcomp(&[
        "calibrate",
        "--robot",
        "robots/industrial-6dof.toml",
        "--data",
        &data,
        "--out",
        &model,
    ]);
    assert!(code == 0 || code == 2, "{err}");
    let fitted = Robot::from_path(std::path::Path::new(&model)).unwrap();
    assert_eq!(fitted.stations().len(), 3);
    let st2 = fitted.station_frame(1);
    // Reachable targets: where the model puts the tool at two configurations, in the base
    // frame, and the same points in station st2's frame.
    let in_base: Vec<nalgebra::Vector3<f64>> = crate::common::random_configurations(&fitted, 2, 5)
        .iter()
        .map(|q| fitted.forward(q).unwrap().point[fitted.tool()].translation.vector)
        .collect();
    let csv = |ps: &[nalgebra::Vector3<f64>]| {
        let mut s = String::from("x[m],y[m],z[m]\n");
        for p in ps {
            s.push_str(&format!("{:?},{:?},{:?}\n", p.x, p.y, p.z));
        }
        s
    };
    let base_targets: Vec<nalgebra::Vector3<f64>> = in_base
        .iter()
        .map(|p| st2.transform_point(&(*p).into()).coords)
        .collect();
    let t_station = dir.file("station.csv", &csv(&base_targets)).display().to_string();
    let t_base = dir.file("base.csv", &csv(&in_base)).display().to_string();
    let out = |name: &str| dir.file(name, "").display().to_string();
    let (o1, o2, o3) = (out("c1.csv"), out("c2.csv"), out("c3.csv"));
    let (code, _, err) = armcomp(&["compensate", "--model", &model, "--targets", &t_station, "--out", &o1]);
    assert_ne!(code, 0);
    assert!(
        err.contains("3 stations") && err.contains("st2") && err.contains("--station"),
        "{err}"
    );
    let (code, _, err) = armcomp(&[
        "compensate",
        "--model",
        &model,
        "--targets",
        &t_station,
        "--station",
        "st2",
        "--out",
        &o2,
    ]);
    assert_eq!(code, 0, "{err}");
    let (code, _, err) = armcomp(&[
        "compensate",
        "--model",
        &model,
        "--targets",
        &t_base,
        "--frame",
        "base",
        "--out",
        &o3,
    ]);
    assert_eq!(code, 0, "{err}");
    let joints = |path: &str| -> Vec<f64> {
        let text = std::fs::read_to_string(path).unwrap();
        text.lines()
            .skip(1)
            .flat_map(|l| {
                l.split(',')
                    .take(6)
                    .map(|v| v.parse::<f64>().unwrap())
                    .collect::<Vec<_>>()
            })
            .collect()
    };
    let (a, b) = (joints(&o2), joints(&o3));
    assert_eq!(a.len(), 12);
    for (x, y) in a.iter().zip(&b) {
        assert!((x - y).abs() < 1e-9, "{a:?} vs {b:?}");
    }
    let (code, _, err) = armcomp(&[
        "compensate",
        "--model",
        &model,
        "--targets",
        &t_station,
        "--station",
        "nowhere",
        "--out",
        &o2,
    ]);
    assert_ne!(code, 0);
    assert!(err.contains("nowhere") && err.contains("st1"), "{err}");
}

/// Rows with no session, station or time structure: `fit` and `learn` say their expected
/// error holds for these rows' conditions only, and offer the temperature column the data
/// have; folds by blocks of it (`--group-by temperature:4`) end the note.
#[test]
fn folds_over_one_session_say_so_and_blocks_of_a_column_end_it() {
    use crate::cli::armcomp;
    let dir = crate::common::Scratch::new("one-session");
    let (plain, warm) = forty_rows_with(&dir, "temperature[C],operator", |row| {
        format!("{},ann", 20.25 + 0.25 * row as f64)
    });
    let model = dir.file("m.toml", "").display().to_string();
    let learned = dir.file("l.toml", "").display().to_string();
    let (code, _, err) = armcomp(&[
        "fit",
        "--robot",
        "robots/industrial-6dof.toml",
        "--data",
        &plain,
        "--predictor",
        "none",
        "--out",
        &model,
    ]);
    assert!(code == 0 || code == 2, "{err}");
    assert!(
        err.contains("one session") && err.contains("--group-by COLUMN:N"),
        "{err}"
    );
    let learn = |data: &str, extra: &[&str]| {
        let mut args = vec![
            "learn",
            "--model",
            &model,
            "--data",
            data,
            "--predictor",
            "ridge",
            "--out",
            &learned,
        ];
        args.extend_from_slice(extra);
        armcomp(&args)
    };
    let (code, _, err) = learn(&plain, &[]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("one session"), "{err}");
    let (code, _, err) = learn(&warm, &[]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("`--group-by temperature:5`"), "{err}");
    let (code, stdout, err) = learn(&warm, &["--group-by", "temperature:4"]);
    assert_eq!(code, 0, "{err}");
    assert!(stdout.contains("grouped by `temperature` in 4 blocks"), "{stdout}");
    assert!(!err.contains("one session"), "{err}");
    // Blocks cut a numeric column; a text one is refused with its row.
    let (code, _, err) = learn(&warm, &["--group-by", "operator:4"]);
    assert_ne!(code, 0);
    assert!(
        err.contains("data row 0, column `operator`: `ann` is not a number"),
        "{err}"
    );
}

/// Blocks of consecutive values, as many rows each, ties kept together: by hand.
#[test]
fn blocks_of_a_column_hold_consecutive_values() {
    use armcomp_api::ops::fit::blocks_of;
    assert_eq!(blocks_of(&[5.0, 1.0, 3.0, 2.0, 4.0, 6.0], 3), [2, 0, 1, 0, 1, 2]);
    assert_eq!(blocks_of(&[1.0, 1.0, 1.0, 2.0], 2), [0, 0, 0, 1]);
    assert_eq!(blocks_of(&[3.0, 1.0, 2.0, 4.0], 4), [2, 0, 1, 3]);
}

/// 40 rows the industrial arm's nominal model simulates (0.05 mm noise), written plain and
/// again with `columns` appended to the header and `cells(data row)` to each row: the paths
/// of both files.
fn forty_rows_with(dir: &crate::common::Scratch, columns: &str, cells: impl Fn(usize) -> String) -> (String, String) {
    let plain = dir.file("plain.csv", "").display().to_string();
    let (code, _, err) = crate::cli::armcomp(&[
        "simulate",
        "--robot",
        "robots/industrial-6dof.toml",
        "--n",
        "40",
        "--noise-mm",
        "0.05",
        "--out",
        &plain,
    ]);
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&plain).unwrap();
    let with: Vec<String> = text
        .lines()
        .enumerate()
        .map(|(i, l)| match i {
            0 => format!("{l},{columns}"),
            _ => format!("{l},{}", cells(i - 1)),
        })
        .collect();
    let data = dir
        .file("with-columns.csv", &(with.join("\n") + "\n"))
        .display()
        .to_string();
    (plain, data)
}
