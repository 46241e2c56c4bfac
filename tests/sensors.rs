//! Sensor inputs: a base accelerometer read per measurement row, on simulated data of a boom
//! whose base is tilted by a known, different angle at every pose; and the checks of sensor
//! declarations and columns.

use std::path::Path;

use armcomp_core::Robot;
use armcomp_core::algorithms::evaluate::{ErrorStats, position_errors};
use armcomp_core::algorithms::simulate::{SimulateParams, TiltDraw, random_stations, simulate_tilted};
use armcomp_core::calibrate::{CalibrationParams, ParameterSpace, calibrate};
use armcomp_core::data::measurement::{Sample, parse_csv};
use armcomp_core::model::sampling::{Sampler, configurations};
use armcomp_core::support::io::InputLimits;

use crate::common::{robot, robot_from_toml};

const NOISE: f64 = 0.05e-3; // m per axis
const TILT: f64 = 3.0; // deg, standard deviation per axis

fn measure(truth: &Robot, n: usize, seed: u64) -> Vec<Sample> {
    let poses = configurations(truth.tree(), Sampler::Sobol, n, seed).unwrap();
    let params = SimulateParams {
        noise_std: NOISE,
        seed: seed + 1000,
    };
    simulate_tilted(truth, &poses, params, TILT.to_radians(), TiltDraw::PerRow)
        .unwrap()
        .samples
}

/// The same rows without the sensor's reading: what the file gives with its columns ignored.
fn without_sensor(samples: &[Sample]) -> Vec<Sample> {
    samples
        .iter()
        .map(|s| Sample {
            gravity: None,
            ..s.clone()
        })
        .collect()
}

/// RMS of the 3-D error of isotropic Gaussian noise with `sigma` per axis: √3·σ (mm).
fn noise_rms_mm(sigma: f64) -> f64 {
    3f64.sqrt() * sigma * 1e3
}

/// The tilted boom's nominal model and its truth: softer beams than the nominal sections say
/// and a longer boom.
fn nominal_and_truth() -> (Robot, Robot) {
    let nominal = robot("rock-drill-tilted.toml");
    let space = ParameterSpace::new(&nominal);
    let mut theta = space.initial();
    for (name, delta) in [
        ("cantilever.boom.ei_scale", -0.3),
        ("cantilever.feed_yaw.ei_scale", -0.2),
        ("j3.d", 2e-3),
    ] {
        theta[space.index(name).unwrap_or_else(|| panic!("no parameter {name}"))] += delta;
    }
    let truth = space.apply(&nominal, &theta).unwrap();
    (nominal, truth)
}

#[test]
fn a_base_accelerometer_brings_a_tilted_boom_to_the_noise_floor() {
    let (nominal, truth) = nominal_and_truth();
    let train = measure(&truth, 150, 1);
    let test = measure(&truth, 60, 2);
    // The tilt is a few degrees at every pose, as drawn.
    let tilts: Vec<f64> = train
        .iter()
        .map(|s| {
            s.gravity
                .unwrap()
                .direction
                .angle(&-nalgebra::Vector3::z())
                .to_degrees()
        })
        .collect();
    let mean_tilt = tilts.iter().sum::<f64>() / tilts.len() as f64;
    assert!((2.5..5.0).contains(&mean_tilt), "mean tilt {mean_tilt} deg");

    let params = CalibrationParams {
        measurement_std: NOISE,
        restarts: 0,
        ..Default::default()
    };
    let held_out = |train: &[Sample], test: &[Sample]| {
        let cal = calibrate(&nominal, train, &params, &mut |_| {}).unwrap();
        ErrorStats::from_errors(&position_errors(&cal.robot, test)).rms_mm
    };
    let with = held_out(&train, &test);
    let without = held_out(&without_sensor(&train), &without_sensor(&test));
    let floor = noise_rms_mm(NOISE);
    eprintln!("held-out RMS: {with:.4} mm with the sensor, {without:.4} mm without; noise {floor:.4} mm");
    assert!(
        with < 1.3 * floor,
        "with the sensor: held-out RMS {with} mm, noise {floor} mm"
    );
    assert!(
        without > 3.0 * floor,
        "without the sensor: held-out RMS {without} mm, noise {floor} mm"
    );
}

/// The field case: a total station set up three times around the boom, the carrier parked on
/// other ground for each set-up (a tilt per station, read by the base accelerometer). One
/// calibration across the stations (a frame each, the boom shared) reaches the noise floor on
/// held-out rows of every station; without the accelerometer columns it cannot, since no one
/// base tilt fits stations tilted differently. Three seeds.
#[test]
fn stations_tilted_differently_reach_the_noise_floor_with_the_accelerometer() {
    let floor = noise_rms_mm(NOISE);
    let params = CalibrationParams {
        measurement_std: NOISE,
        restarts: 0,
        ..Default::default()
    };
    for seed in [1, 2, 3] {
        let (mut nominal, mut truth) = nominal_and_truth();
        truth.set_stations(random_stations(&truth, 3, seed));
        let poses = configurations(truth.tree(), Sampler::Sobol, 240, seed).unwrap();
        let noise = SimulateParams {
            noise_std: NOISE,
            seed: seed + 1000,
        };
        let data = simulate_tilted(&truth, &poses, noise, TILT.to_radians(), TiltDraw::PerStation).unwrap();
        // One tilt per station: every row of a station reads the same gravity.
        for k in 0..3 {
            let mut rows = data.samples.iter().filter(|s| s.station == k);
            let first = rows.next().unwrap().gravity.unwrap().direction;
            assert!(rows.all(|s| s.gravity.unwrap().direction == first));
        }
        nominal.adopt_stations(&data.stations);
        let (train, test): (Vec<_>, Vec<_>) = data.samples.iter().cloned().enumerate().partition(|(i, _)| i % 2 == 0);
        let (train, test): (Vec<Sample>, Vec<Sample>) = (
            train.into_iter().map(|(_, s)| s).collect(),
            test.into_iter().map(|(_, s)| s).collect(),
        );
        let held_out = |train: &[Sample], test: &[Sample]| {
            let cal = calibrate(&nominal, train, &params, &mut |_| {}).unwrap();
            ErrorStats::from_errors(&position_errors(&cal.robot, test)).rms_mm
        };
        let with = held_out(&train, &test);
        let without = held_out(&without_sensor(&train), &without_sensor(&test));
        println!(
            "seed {seed}: held-out RMS over 3 stations {with:.4} mm with the accelerometer, {without:.4} mm without; \
             noise {floor:.4} mm"
        );
        assert!(
            with < 1.3 * floor,
            "seed {seed}: with the sensor {with} mm, noise {floor} mm"
        );
        assert!(
            without > 1.5 * with,
            "seed {seed}: without {without} mm, with {with} mm"
        );
    }
}

/// A small robot: one revolute joint and an inclinometer on its link.
fn tilted_robot(sensor: &str) -> Robot {
    robot_from_toml(&format!(
        r#"
name = "sensor-check"
[units]
length = "mm"
angle = "deg"
[kinematics]
type = "mdh"
[[kinematics.joints]]
name = "j1"
link = "arm"
limits = [-90, 90]
[[points]]
name = "tool"
link = "arm"
xyz = [300, 0, 0]
{sensor}
"#
    ))
}

const INCLINOMETER: &str = r#"[[sensors]]
name = "arm_tilt"
kind = "inclinometer"
link = "arm"
columns = ["arm_roll", "arm_pitch"]"#;

fn read(robot: &Robot, text: &str) -> Result<armcomp_core::data::measurement::MeasurementSet, String> {
    parse_csv(text, Path::new("m.csv"), &robot.csv_layout()).map_err(|e| e.to_string())
}

#[test]
fn sensor_columns_are_read_in_their_units_and_bad_cells_name_line_and_column() {
    let r = tilted_robot(INCLINOMETER);
    // Pitch 2 deg: gravity leans toward the link's +x by 2 deg.
    let set = read(&r, "j1[deg],x,y,z,arm_roll[deg],arm_pitch[deg]\n0,300,0,0,0,2\n").unwrap();
    let g = set.samples[0].gravity.unwrap();
    let s = 2f64.to_radians().sin();
    assert!((g.direction - nalgebra::Vector3::new(s, 0.0, -(1.0 - s * s).sqrt())).norm() < 1e-15);
    // Without a unit, the file's angle unit (deg).
    let same = read(&r, "j1[deg],x,y,z,arm_roll,arm_pitch\n0,300,0,0,0,2\n").unwrap();
    assert_eq!(same.samples[0].gravity, set.samples[0].gravity);

    let cases = [
        (
            "j1,x,y,z,arm_roll[mm],arm_pitch\n0,300,0,0,0,2\n",
            "m.csv:1: column `arm_roll[mm]` of sensor `arm_tilt`: an inclinometer column reads an angle",
        ),
        (
            "j1,x,y,z,arm_roll\n0,300,0,0,0\n",
            "m.csv:1: sensor `arm_tilt` needs all its columns (arm_roll, arm_pitch); missing `arm_pitch`",
        ),
        (
            "j1,x,y,z,arm_roll,arm_pitch\n0,300,0,0,0,2\n0,300,0,0,,2\n",
            "m.csv:3: column `arm_roll`: empty",
        ),
        (
            "j1,x,y,z,arm_roll,arm_pitch\n0,300,0,0,0,120\n",
            "m.csv:2: sensor `arm_tilt` (columns arm_roll, arm_pitch): roll 0.000 deg, pitch 120.000 deg",
        ),
    ];
    for (text, expected) in cases {
        let e = read(&r, text).unwrap_err();
        assert!(e.contains(expected), "{e}\nexpected: {expected}");
    }
    // A file without the sensor's columns is read with the file's gravity, and says so.
    let plain = read(&r, "j1,x,y,z\n0,300,0,0\n").unwrap();
    assert!(plain.samples[0].gravity.is_none());
    assert!(
        plain
            .warnings
            .iter()
            .any(|w| w.contains("no columns of sensor `arm_tilt`"))
    );

    // An accelerometer reading zero gives no direction.
    let acc = tilted_robot(
        r#"[[sensors]]
name = "acc"
kind = "accelerometer"
link = "base"
columns = ["ax", "ay", "az"]"#,
    );
    let e = read(&acc, "j1,x,y,z,ax[g],ay[g],az[g]\n0,300,0,0,0,0,0\n").unwrap_err();
    assert!(e.contains("m.csv:2: sensor `acc`") && e.contains("reads zero"), "{e}");
    let e = read(&acc, "j1,x,y,z,ax[deg],ay[g],az[g]\n0,300,0,0,0,0,1\n").unwrap_err();
    assert!(e.contains("column `ax[deg]` of sensor `acc`"), "{e}");
}

#[test]
fn sensor_declarations_are_checked() {
    let build = |sensor: &str| {
        let text = format!(
            "name = \"s\"\n[kinematics]\ntype = \"mdh\"\n[[kinematics.joints]]\nname = \"j1\"\nlink = \"arm\"\n\
             [[points]]\nname = \"tool\"\nlink = \"arm\"\n{sensor}\n"
        );
        let src = armcomp_core::SourceFile {
            path: "s.toml".into(),
            text,
            format: armcomp_core::robot::robot_file::Format::Toml,
        };
        match src.parse::<armcomp_core::RobotFile>() {
            Ok(file) => Robot::from_source(file, &src, InputLimits::default())
                .unwrap_err()
                .to_string(),
            Err(e) => e.to_string(),
        }
    };
    let e = build("[[sensors]]\nname = \"a\"\nkind = \"inclinometer\"\nlink = \"nowhere\"\ncolumns = [\"r\", \"p\"]");
    assert!(
        e.contains("sensors[0].link") && e.contains("`nowhere`, which does not exist"),
        "{e}"
    );
    let e = build("[[sensors]]\nname = \"a\"\nkind = \"accelerometer\"\nlink = \"arm\"\ncolumns = [\"r\", \"p\"]");
    assert!(e.contains("an accelerometer has 3 columns"), "{e}");
    let e = build("[[sensors]]\nname = \"a\"\nkind = \"inclinometer\"\nlink = \"arm\"\ncolumns = [\"j1\", \"x\"]");
    assert!(e.contains("column `j1` is the name of a joint's column"), "{e}");
    assert!(e.contains("column `x` is the name of a measurement CSV column"), "{e}");
    let e = build("[[sensors]]\nname = \"a\"\nkind = \"gyro\"\nlink = \"arm\"\ncolumns = [\"r\", \"p\"]");
    assert!(e.contains("gyro"), "{e}");
}
