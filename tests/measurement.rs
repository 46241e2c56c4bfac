//! Measurement CSV: round trip, units, and every kind of bad input naming its line and column.

use std::path::Path;

use armcomp_core::data::measurement::{CsvLayout, MeasurementSet, Sample, parse_csv, write_csv};
use armcomp_core::{AngleUnit, LengthUnit, Robot, Units};
use nalgebra::{Isometry3, Vector3};

use crate::common::robots::PLANAR_2R;
use crate::common::{random_configurations, robot, robot_from_toml};

fn drill() -> Robot {
    robot("rock-drill.toml")
}

fn parse(text: &str) -> Result<MeasurementSet, String> {
    let r = drill();
    parse_csv(
        text,
        Path::new("m.csv"),
        &CsvLayout::strict(r.tree(), r.units(), r.tool()),
    )
    .map_err(|e| e.to_string())
}

const HEADER: &str = "j1[deg],j2[deg],j3[mm],j4[deg],j5[deg],j6[deg],j7[mm],x[mm],y[mm],z[mm]";

#[test]
fn write_then_read_gives_the_same_samples() {
    let r = drill();
    let samples: Vec<Sample> = random_configurations(&r, 50, 3)
        .into_iter()
        .enumerate()
        .map(|(i, q)| Sample {
            position: Vector3::new(0.9 + i as f64 * 1e-3, -0.1, 0.5),
            q,
            point: r.tool(),
            orientation: None,
            payload: Some(1.5),
            temperature: Some(21.0 + i as f64 * 0.1),
            torque: None,
            fixed_point: None,
            plane: None,
            sensors: Default::default(),
            station: 0,
            position_std: None,
        })
        .collect();
    let set = MeasurementSet {
        rows: (0..samples.len()).collect(),
        samples,
        warnings: vec![],
        stations: vec![],
    };
    for units in [
        Units {
            length: LengthUnit::Mm,
            angle: AngleUnit::Deg,
        },
        Units::default(),
    ] {
        let text = write_csv(&set, r.tree(), units);
        let back = parse_csv(
            &text,
            Path::new("m.csv"),
            &CsvLayout::strict(r.tree(), Units::default(), r.tool()),
        )
        .unwrap();
        assert_eq!(back.samples.len(), set.samples.len());
        for (a, b) in set.samples.iter().zip(&back.samples) {
            for (x, y) in a.q.iter().zip(&b.q) {
                assert!((x - y).abs() < 1e-12, "{x} vs {y}");
            }
            assert!((a.position - b.position).norm() < 1e-12);
            assert_eq!(a.payload, b.payload);
            assert!((a.temperature.unwrap() - b.temperature.unwrap()).abs() < 1e-12);
        }
        assert!(back.warnings.is_empty(), "{:?}", back.warnings);
    }
}

#[test]
fn header_units_convert_to_si() {
    let set = parse(&format!("{HEADER}\n10,20,50,0,-10,5,30,1000,-20,300\n")).unwrap();
    let s = &set.samples[0];
    assert!((s.q[0] - 10f64.to_radians()).abs() < 1e-15);
    assert!((s.q[2] - 0.05).abs() < 1e-15);
    assert!((s.position - Vector3::new(1.0, -0.02, 0.3)).norm() < 1e-15);
    // Without units the robot file's (mm, deg) apply.
    let set = parse("j1,j2,j3,j4,j5,j6,j7,x,y,z\n10,20,50,0,-10,5,30,1000,-20,300\n").unwrap();
    assert!((set.samples[0].q[2] - 0.05).abs() < 1e-15);
}

fn assert_err(text: &str, words: &[&str]) {
    let e = parse(text).expect_err("expected an error");
    for w in words {
        assert!(e.contains(w), "`{e}` lacks `{w}`");
    }
}

#[test]
fn bad_inputs_name_line_and_column() {
    assert_err(
        &format!("{HEADER}\n10,20,50,0,-10,5,30,1000,NaN,300\n"),
        &["m.csv:2", "y[mm]", "not a finite"],
    );
    assert_err(
        &format!("{HEADER}\n10,20,50,0,-10,5,30,1000,inf,300\n"),
        &["m.csv:2", "y[mm]"],
    );
    assert_err(
        &format!("{HEADER}\n10,20,50,0,-10,5,30,1000,abc,300\n"),
        &["m.csv:2", "`abc` is not a number"],
    );
    assert_err(
        &format!("{HEADER}\n10,20,50,0,-10,5,30,1000,300\n"),
        &["m.csv:2", "expected 10 values", "got 9"],
    );
    assert_err(
        &HEADER.replace("j4[deg],", "").replace("j6[deg],", ""),
        &["missing column(s) for 2 joint(s)", "j4[deg], j6[deg]"],
    );
    assert_err(&HEADER.replace(",z[mm]", ""), &["missing column `z`"]);
    assert_err(
        &HEADER.replace("j3[mm]", "j3[deg]"),
        &["j3", "unknown length unit `deg`"],
    );
    assert_err(&HEADER.replace("j1[deg]", "j1[mm]"), &["revolute", "`mm`"]);
}

/// The column an error is in comes as data beside the message (Python's `InputError.field`).
#[test]
fn bad_inputs_carry_their_column() {
    let column = |text: &str| {
        let r = drill();
        match parse_csv(
            text,
            Path::new("m.csv"),
            &CsvLayout::strict(r.tree(), r.units(), r.tool()),
        ) {
            Err(armcomp_core::Error::InputAt { column, .. }) => column,
            other => panic!("expected an input error, got {other:?}"),
        }
    };
    let row = |cells: &str| format!("{HEADER}\n{cells}\n");
    assert_eq!(
        column(&row("10,20,50,0,-10,5,30,1000,abc,300")).as_deref(),
        Some("y[mm]")
    );
    assert_eq!(column(&HEADER.replace(",z[mm]", "")).as_deref(), Some("z"));
    assert_eq!(column(&HEADER.replace("j3[mm]", "j3[deg]")).as_deref(), Some("j3[deg]"));
    assert_eq!(column(&row("10,20,50,0,-10,5,30,1000,300")), None);
}

#[test]
fn unit_mistakes_are_detected_by_magnitude() {
    let m = HEADER
        .replace("[mm]", "[m]")
        .replace("j3[m]", "j3[mm]")
        .replace("j7[m]", "j7[mm]");
    assert_err(
        &format!("{m}\n10,20,50,0,-10,5,30,1000,-20,300\n10,20,50,0,-10,5,31,1000,-20,301\n"),
        &["look like millimetres", "x[mm]"],
    );
    let r = HEADER.replace("j2[deg]", "j2[rad]");
    assert_err(
        &format!("{r}\n10,20,50,0,-10,5,30,1000,-20,300\n"),
        &["`j2[rad]`", "looks like degrees"],
    );
}

#[test]
fn repeated_rows_are_data_and_limits_are_summarised() {
    // Repeatability measurements repeat a pose exactly: both rows are kept.
    let row = "10,20,50,0,-10,5,30,1000,-20,300";
    let set = parse(&format!("{HEADER}\n{row}\n{row}\n")).unwrap();
    assert_eq!(set.samples.len(), 2);
    assert_eq!(set.samples[0], set.samples[1]);
    // A joint outside its limits in several rows is one warning naming the first line.
    let out = "10,40,50,0,-10,5,30,1000,-20,300";
    let set = parse(&format!("{HEADER}\n{row}\n{out}\n{out}\n")).unwrap();
    assert_eq!(set.warnings.len(), 1, "{:?}", set.warnings);
    let w = &set.warnings[0];
    assert!(
        w.contains("m.csv:3") && w.contains("`j2`") && w.contains("in 2 row(s)"),
        "{w}"
    );
}

#[test]
fn unused_columns_are_ignored_with_one_notice() {
    let set = parse(&format!(
        "t,{HEADER},quality\n0.5,10,20,50,0,-10,5,30,1000,-20,300,0.9\n"
    ))
    .unwrap();
    assert_eq!(set.samples.len(), 1);
    assert!((set.samples[0].position - Vector3::new(1.0, -0.02, 0.3)).norm() < 1e-15);
    assert_eq!(set.warnings.len(), 1, "{:?}", set.warnings);
    assert!(set.warnings[0].contains("`t`, `quality` ignored"), "{:?}", set.warnings);
}

/// A point whose name holds a comma and quotes is written quoted (`"` doubled, RFC 4180) and
/// reads back as the same point; every other field is written as it is. Robot files keep
/// their names free of both, but trees built otherwise (a URDF's link names) need not.
#[test]
fn point_names_with_commas_and_quotes_round_trip() {
    let name = r#"nest, "B""#;
    let r = robot_from_toml(PLANAR_2R);
    let mut tree = r.tree().clone();
    let body = tree.points()[r.tool()].body;
    let nest = tree.add_point(name, body, Isometry3::identity()).unwrap();
    let sample = |point, x| Sample {
        q: vec![0.5, -0.25],
        point,
        position: Vector3::new(x, 0.5, 0.0),
        orientation: None,
        payload: None,
        temperature: None,
        torque: None,
        fixed_point: None,
        plane: None,
        sensors: Default::default(),
        station: 0,
        position_std: None,
    };
    let set = MeasurementSet {
        samples: vec![sample(r.tool(), 1.0), sample(nest, 0.25)],
        rows: vec![0, 1],
        warnings: vec![],
        stations: vec![],
    };
    let units = Units {
        length: LengthUnit::M,
        angle: AngleUnit::Rad,
    };
    let text = write_csv(&set, &tree, units);
    assert_eq!(
        text,
        "j1[rad],j2[rad],point,x[m],y[m],z[m]\n\
         0.5,-0.25,tool,1,0.5,0\n\
         0.5,-0.25,\"nest, \"\"B\"\"\",0.25,0.5,0\n"
    );
    let back = parse_csv(&text, Path::new("m.csv"), &CsvLayout::strict(&tree, units, r.tool())).unwrap();
    let points: Vec<usize> = back.samples.iter().map(|s| s.point).collect();
    assert_eq!(points, [r.tool(), nest]);
    assert_eq!(back.samples[1].position, Vector3::new(0.25, 0.5, 0.0));
}

/// `sx, sy, sz` are read in their unit as each row's standard deviations; a row leaving all
/// three empty has none; a partial triple, a deviation of zero or a lone `sx` is refused at its
/// line.
#[test]
fn position_standard_deviations_are_read_per_row() {
    let header = format!("{HEADER},sx[mm],sy[mm],sz[um]");
    let header = header.replace("sz[um]", "sz[cm]");
    let set = parse(&format!(
        "{header}\n10,20,50,0,-10,5,30,1000,-20,300,0.1,0.2,0.03\n10,20,50,0,-10,5,30,1000,-20,300,,,\n"
    ))
    .unwrap();
    let std = set.samples[0].position_std.expect("the first row gives its deviations");
    assert!((std - Vector3::new(0.1e-3, 0.2e-3, 0.3e-3)).norm() < 1e-15, "{std:?}");
    assert_eq!(set.samples[1].position_std, None);
    assert!(set.warnings.iter().all(|w| !w.contains("sx")), "{:?}", set.warnings);
    assert_err(
        &format!("{header}\n10,20,50,0,-10,5,30,1000,-20,300,0.1,,0.03\n"),
        &["m.csv:2", "some of sx, sy, sz are empty"],
    );
    assert_err(
        &format!("{header}\n10,20,50,0,-10,5,30,1000,-20,300,0.1,0,0.03\n"),
        &["m.csv:2", "sy[mm]", "above zero"],
    );
    assert_err(
        &format!("{HEADER},sx[mm]\n10,20,50,0,-10,5,30,1000,-20,300,0.1\n"),
        &["m.csv:1", "sx, sy, sz"],
    );
}

/// The rotation about `axis` (0 x, 1 y, 2 z) by `a`, written out.
fn turn(axis: usize, a: f64) -> nalgebra::Matrix3<f64> {
    let (s, c) = a.sin_cos();
    match axis {
        0 => nalgebra::Matrix3::new(1.0, 0.0, 0.0, 0.0, c, -s, 0.0, s, c),
        1 => nalgebra::Matrix3::new(c, 0.0, s, 0.0, 1.0, 0.0, -s, 0.0, c),
        _ => nalgebra::Matrix3::new(c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0),
    }
}

/// Euler angles named by their order against the hand-multiplied matrices: intrinsic turns
/// compose left to right, extrinsic ones right to left, for a Tait–Bryan and a proper order;
/// intrinsic zyx and extrinsic xyz are roll-pitch-yaw.
#[test]
fn euler_angles_are_read_in_their_named_order() {
    let angles = [30.0f64, -50.0, 70.0];
    let [a, b, c] = angles.map(f64::to_radians);
    let cases = [
        ("intrinsic_zyx", turn(2, a) * turn(1, b) * turn(0, c)),
        ("extrinsic_zyx", turn(0, c) * turn(1, b) * turn(2, a)),
        ("intrinsic_zyz", turn(2, a) * turn(1, b) * turn(2, c)),
        ("extrinsic_xyz", turn(2, c) * turn(1, b) * turn(0, a)),
    ];
    for (order, want) in cases {
        let header = format!("{HEADER},{order}_1[deg],{order}_2[deg],{order}_3[deg]");
        let set = parse(&format!("{header}\n10,20,50,0,-10,5,30,1000,-20,300,30,-50,70\n")).unwrap();
        let got = set.samples[0].orientation.expect("an orientation").to_rotation_matrix();
        assert!((got.matrix() - want).norm() < 1e-12, "{order}: {got} against {want}");
    }
    let rpy = parse(&format!(
        "{HEADER},roll[deg],pitch[deg],yaw[deg]\n10,20,50,0,-10,5,30,1000,-20,300,70,-50,30\n"
    ))
    .unwrap();
    let zyx = turn(2, a) * turn(1, b) * turn(0, c);
    let got = rpy.samples[0].orientation.unwrap().to_rotation_matrix();
    assert!((got.matrix() - zyx).norm() < 1e-12);
    assert_err(
        &format!("{HEADER},intrinsic_zyx_1,intrinsic_zyx_2\n10,20,50,0,-10,5,30,1000,-20,300,1,2\n"),
        &["m.csv:1", "intrinsic_zyx_1, intrinsic_zyx_2, intrinsic_zyx_3"],
    );
}

/// Three Euler angles typed into rotation-vector columns: a vector longer than half a turn is
/// refused at its line, naming the Euler spellings; one within it is read.
#[test]
fn a_rotation_vector_longer_than_half_a_turn_is_refused() {
    let header = format!("{HEADER},rx[deg],ry[deg],rz[deg]");
    assert_err(
        &format!("{header}\n10,20,50,0,-10,5,30,1000,-20,300,10,20,30\n10,20,50,0,-10,5,30,1000,-20,300,170,-40,95\n"),
        &["m.csv:3", "rotation vector", "at most 180°", "intrinsic_xyz_1"],
    );
    let set = parse(&format!("{header}\n10,20,50,0,-10,5,30,1000,-20,300,0,0,179.9\n")).unwrap();
    let angle = set.samples[0].orientation.unwrap().angle().to_degrees();
    assert!((angle - 179.9).abs() < 1e-9, "{angle}");
}
