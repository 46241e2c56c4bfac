//! Measurement CSV files: one row per measured pose.
//!
//! Columns (any order; units in brackets, else the robot file's units):
//! one per joint coordinate named as the joint (`j2[deg]`, `j3[mm]`); optional `point` (the
//! measured point's name; default: the first marker); `x`, `y`, `z` (`x[mm]`), the position in
//! the measurement frame; optional orientation `qw, qx, qy, qz`; optional `payload[kg]`,
//! `temperature[C]`, and joint torques `tau_<joint>[Nm]`.

use std::path::Path;

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

use crate::error::{Error, Result};
use crate::tree::KinematicTree;
use crate::units::{AngleUnit, LengthUnit, Units};

/// One measured pose.
#[derive(Debug, Clone, PartialEq)]
pub struct Sample {
    /// Joint values (rad, m), one per independent coordinate.
    pub q: Vec<f64>,
    /// Index of the measured point in the tree's points.
    pub point: usize,
    /// Measured position in the measurement frame (m).
    pub position: Vector3<f64>,
    /// Measured orientation, when the tracker gives one.
    pub orientation: Option<UnitQuaternion<f64>>,
    /// Payload mass (kg), when given.
    pub payload: Option<f64>,
    /// Ambient temperature (°C), when given.
    pub temperature: Option<f64>,
    /// Joint torques (N m), one per coordinate, when given.
    pub torque: Option<Vec<f64>>,
}

/// A set of measured poses, with the warnings raised while reading it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MeasurementSet {
    /// The samples, in file order.
    pub samples: Vec<Sample>,
    /// Non-fatal findings (joint values outside limits, ...), each naming its line.
    pub warnings: Vec<String>,
}

/// What a column holds.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Column {
    Joint { coord: usize, scale: f64 },
    Point,
    Position { axis: usize, scale: f64 },
    Quat(usize),
    Payload(f64),
    Temperature(f64),
    Torque(usize),
}

/// Splits a column header `x[mm]` into its name and optional unit.
pub fn split_header(h: &str) -> (&str, Option<&str>) {
    let h = h.trim();
    match (h.find('['), h.ends_with(']')) {
        (Some(i), true) => (h[..i].trim(), Some(h[i + 1..h.len() - 1].trim())),
        _ => (h, None),
    }
}

/// Reads measurements for `tree`; `units` applies to columns without a unit; `default_point`
/// is the point measured when there is no `point` column.
pub fn read_csv(path: &Path, tree: &KinematicTree, units: Units, default_point: usize) -> Result<MeasurementSet> {
    let text = crate::io::read_text(path)?;
    parse_csv(&text, path, tree, units, default_point)
}

/// Parses measurement CSV text (see [`read_csv`]); `path` is used in messages.
pub fn parse_csv(
    text: &str,
    path: &Path,
    tree: &KinematicTree,
    units: Units,
    default_point: usize,
) -> Result<MeasurementSet> {
    parse_table(text, path, tree, units, default_point, true)
}

/// Parses a CSV of joint configurations only (joint columns, same header rules); other
/// measurement columns, if present, are read and ignored.
pub fn parse_poses(text: &str, path: &Path, tree: &KinematicTree, units: Units) -> Result<Vec<Vec<f64>>> {
    Ok(parse_table(text, path, tree, units, 0, false)?
        .samples
        .into_iter()
        .map(|s| s.q)
        .collect())
}

fn parse_table(
    text: &str,
    path: &Path,
    tree: &KinematicTree,
    units: Units,
    default_point: usize,
    with_positions: bool,
) -> Result<MeasurementSet> {
    let err = |line: Option<usize>, msg: String| {
        let at = line.map(|l| format!(":{l}")).unwrap_or_default();
        Error::Input(format!("{}{at}: {msg}", path.display()))
    };
    let mut reader = csv::ReaderBuilder::new()
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let headers = reader
        .headers()
        .map_err(|e| err(Some(1), format!("cannot read the header: {e}")))?
        .clone();
    let names = tree.coordinate_names();
    let mut columns = Vec::new();
    let mut seen: Vec<String> = Vec::new();
    for h in headers.iter() {
        let (name, unit) = split_header(h);
        if seen.iter().any(|s| s == name) {
            return Err(err(Some(1), format!("column `{name}` appears twice")));
        }
        seen.push(name.to_string());
        let length = |u: Option<&str>| -> Result<f64> {
            match u {
                None => Ok(units.length.to_si()),
                Some(u) => LengthUnit::parse(u).map(LengthUnit::to_si).ok_or_else(|| {
                    err(
                        Some(1),
                        format!("column `{h}`: unknown length unit `{u}` (expected m, cm, mm or in)"),
                    )
                }),
            }
        };
        let col = if let Some(c) = names.iter().position(|n| n == name) {
            let scale = if tree.coordinate_is_prismatic()[c] {
                length(unit)?
            } else {
                match unit {
                    None => units.angle.to_si(),
                    Some(u) => AngleUnit::parse(u).map(AngleUnit::to_si).ok_or_else(|| {
                        err(Some(1), format!("column `{h}`: joint `{name}` is revolute; expected an angle unit (rad or deg), got `{u}`"))
                    })?,
                }
            };
            Column::Joint { coord: c, scale }
        } else {
            match name {
                "point" => Column::Point,
                "x" | "y" | "z" => Column::Position {
                    axis: (name.as_bytes()[0] - b'x') as usize,
                    scale: length(unit)?,
                },
                "qw" | "qx" | "qy" | "qz" => {
                    Column::Quat(["qw", "qx", "qy", "qz"].iter().position(|n| *n == name).unwrap_or(0))
                }
                "payload" => Column::Payload(match unit {
                    None | Some("kg") => 1.0,
                    Some("g") => 1e-3,
                    Some(u) => {
                        return Err(err(
                            Some(1),
                            format!("column `{h}`: expected a mass unit (kg or g), got `{u}`"),
                        ));
                    }
                }),
                "temperature" => Column::Temperature(match unit {
                    None | Some("C") | Some("degC") => 0.0,
                    Some("K") => -273.15,
                    Some(u) => return Err(err(Some(1), format!("column `{h}`: expected C or K, got `{u}`"))),
                }),
                n if n.starts_with("tau_") => match names.iter().position(|j| j == &n[4..]) {
                    Some(c) => Column::Torque(c),
                    None => return Err(err(Some(1), format!("column `{h}`: `{}` is not a joint", &n[4..]))),
                },
                _ => {
                    return Err(err(
                        Some(1),
                        format!(
                            "unexpected column `{h}`; expected joint columns ({}), x, y, z, and optionally point, qw/qx/qy/qz, payload, temperature, tau_<joint>",
                            names.join(", ")
                        ),
                    ));
                }
            }
        };
        columns.push(col);
    }
    let has = |f: &dyn Fn(&Column) -> bool| columns.iter().any(f);
    for (c, n) in names.iter().enumerate() {
        if !has(&|k| matches!(k, Column::Joint { coord, .. } if *coord == c)) {
            return Err(err(
                Some(1),
                format!(
                    "missing column for joint `{n}` (e.g. `{n}[{}]`)",
                    if tree.coordinate_is_prismatic()[c] { "mm" } else { "deg" }
                ),
            ));
        }
    }
    for (axis, n) in ["x", "y", "z"].iter().enumerate().filter(|_| with_positions) {
        if !has(&|k| matches!(k, Column::Position { axis: a, .. } if *a == axis)) {
            return Err(err(
                Some(1),
                format!("missing column `{n}` (measured position, e.g. `{n}[mm]`)"),
            ));
        }
    }
    let nquat = columns.iter().filter(|c| matches!(c, Column::Quat(_))).count();
    if nquat != 0 && nquat != 4 {
        return Err(err(
            Some(1),
            "an orientation needs all four columns qw, qx, qy, qz".into(),
        ));
    }
    let has_torque = has(&|k| matches!(k, Column::Torque(_)));

    let mut set = MeasurementSet::default();
    for record in reader.records() {
        let record = record.map_err(|e| {
            err(
                e.position().map(|p| p.line() as usize),
                format!("cannot read the row: {e}"),
            )
        })?;
        let line = record.position().map_or(0, |p| p.line() as usize);
        if record.len() != columns.len() {
            return Err(err(
                Some(line),
                format!(
                    "expected {} values (one per column), got {}",
                    columns.len(),
                    record.len()
                ),
            ));
        }
        let mut s = Sample {
            q: vec![0.0; names.len()],
            point: default_point,
            position: Vector3::zeros(),
            orientation: None,
            payload: None,
            temperature: None,
            torque: has_torque.then(|| vec![0.0; names.len()]),
        };
        let mut quat = [0.0; 4];
        for (field, (col, head)) in record.iter().zip(columns.iter().zip(headers.iter())) {
            if let Column::Point = col {
                s.point = tree.point_index(field).ok_or_else(|| {
                    err(
                        Some(line),
                        format!("column `point`: `{field}` is not a point of the robot"),
                    )
                })?;
                continue;
            }
            let v: f64 = field
                .parse()
                .map_err(|_| err(Some(line), format!("column `{head}`: `{field}` is not a number")))?;
            if !v.is_finite() {
                return Err(err(
                    Some(line),
                    format!("column `{head}`: {field} is not a finite number"),
                ));
            }
            match *col {
                Column::Joint { coord, scale } => s.q[coord] = v * scale,
                Column::Position { axis, scale } => s.position[axis] = v * scale,
                Column::Quat(k) => quat[k] = v,
                Column::Payload(_) if v < 0.0 => {
                    return Err(err(
                        Some(line),
                        format!("column `{head}`: expected a mass of zero or more, got {field}"),
                    ));
                }
                Column::Payload(scale) => s.payload = Some(v * scale),
                Column::Temperature(offset) => s.temperature = Some(v + offset),
                Column::Torque(c) => {
                    if let Some(t) = s.torque.as_mut() {
                        t[c] = v;
                    }
                }
                Column::Point => {}
            }
        }
        if nquat == 4 {
            let q = Quaternion::new(quat[0], quat[1], quat[2], quat[3]);
            if (q.norm() - 1.0).abs() > 1e-3 {
                return Err(err(
                    Some(line),
                    format!("orientation quaternion has norm {:.6}, expected 1", q.norm()),
                ));
            }
            s.orientation = Some(UnitQuaternion::from_quaternion(q));
        }
        for (c, lim) in tree.coordinate_limits().iter().enumerate() {
            if let Some(l) = lim
                && (s.q[c] < l.lower - 1e-9 || s.q[c] > l.upper + 1e-9)
            {
                set.warnings.push(format!(
                    "{}:{line}: joint `{}` is outside its limits",
                    path.display(),
                    names[c]
                ));
            }
        }
        set.samples.push(s);
    }
    if set.samples.is_empty() {
        return Err(err(None, "no measurements (only a header)".into()));
    }
    if with_positions {
        check_magnitudes(&set, &columns, &headers, tree, path)?;
    }
    Ok(set)
}

/// Catches unit mistakes that the numbers give away: millimetres declared as metres, degrees
/// declared as radians.
fn check_magnitudes(
    set: &MeasurementSet,
    columns: &[Column],
    headers: &csv::StringRecord,
    tree: &KinematicTree,
    path: &Path,
) -> Result<()> {
    let mut norms: Vec<f64> = set.samples.iter().map(|s| s.position.norm()).collect();
    norms.sort_by(f64::total_cmp);
    let median = norms[norms.len() / 2];
    let pos_scale = columns.iter().find_map(|c| {
        if let Column::Position { scale, .. } = c {
            Some(*scale)
        } else {
            None
        }
    });
    // No arm measured by a tracker sits 50 m from it; such numbers are millimetres.
    if pos_scale == Some(1.0) && median > 50.0 {
        return Err(Error::Input(format!(
            "{}: positions are declared in metres but their median distance is {median:.0} m; they look like millimetres (write `x[mm]`)",
            path.display()
        )));
    }
    for (col, head) in columns.iter().zip(headers.iter()) {
        if let Column::Joint { coord, scale } = *col {
            let max = set.samples.iter().map(|s| s.q[coord].abs()).fold(0.0, f64::max);
            let prismatic = tree.coordinate_is_prismatic()[coord];
            if !prismatic && scale == 1.0 && max > 4.0 * std::f64::consts::PI {
                return Err(Error::Input(format!(
                    "{}: column `{head}` is in radians but reaches {max:.1}; it looks like degrees (write `[deg]`)",
                    path.display()
                )));
            }
            if prismatic && scale == 1.0 && max > 50.0 {
                return Err(Error::Input(format!(
                    "{}: column `{head}` is in metres but reaches {max:.1}; it looks like millimetres (write `[mm]`)",
                    path.display()
                )));
            }
        }
    }
    Ok(())
}

/// Writes measurements as CSV in the given units (joint columns as `name[unit]`, positions as
/// `x[unit]`); deterministic text for equal inputs.
pub fn write_csv(set: &MeasurementSet, tree: &KinematicTree, units: Units) -> String {
    let lu = units.length.symbol();
    let mut header = joint_header(tree, units);
    let several_points = set.samples.iter().any(|s| s.point != set.samples[0].point);
    if several_points {
        header.push("point".into());
    }
    header.extend(["x", "y", "z"].map(|a| format!("{a}[{lu}]")));
    let first = set.samples.first();
    let with_quat = first.is_some_and(|s| s.orientation.is_some());
    let with_payload = first.is_some_and(|s| s.payload.is_some());
    let with_temp = first.is_some_and(|s| s.temperature.is_some());
    if with_quat {
        header.extend(["qw", "qx", "qy", "qz"].map(String::from));
    }
    if with_payload {
        header.push("payload[kg]".into());
    }
    if with_temp {
        header.push("temperature[C]".into());
    }
    let mut out = header.join(",");
    out.push('\n');
    for s in &set.samples {
        let mut row = joint_row(&s.q, tree, units);
        if several_points {
            row.push(tree.points()[s.point].name.clone());
        }
        row.extend(s.position.iter().map(|v| format!("{}", units.len_out(*v))));
        if with_quat && let Some(q) = s.orientation {
            row.extend([q.w, q.i, q.j, q.k].map(|v| format!("{v}")));
        }
        if with_payload {
            row.push(format!("{}", s.payload.unwrap_or(0.0)));
        }
        if with_temp {
            row.push(format!("{}", s.temperature.unwrap_or(20.0)));
        }
        out.push_str(&row.join(","));
        out.push('\n');
    }
    out
}

/// Joint column headers with units (`j2[deg]`, `j3[mm]`).
pub fn joint_header(tree: &KinematicTree, units: Units) -> Vec<String> {
    let (lu, au) = (units.length.symbol(), units.angle.symbol());
    tree.coordinate_names()
        .iter()
        .zip(tree.coordinate_is_prismatic())
        .map(|(n, p)| format!("{n}[{}]", if *p { lu } else { au }))
        .collect()
}

/// Joint values of one row in the header's units.
pub fn joint_row(q: &[f64], tree: &KinematicTree, units: Units) -> Vec<String> {
    q.iter()
        .zip(tree.coordinate_is_prismatic())
        .map(|(v, p)| format!("{}", if *p { units.len_out(*v) } else { units.ang_out(*v) }))
        .collect()
}

/// Writes joint configurations as a poses CSV (the joint columns of the measurement format),
/// which [`parse_poses`] and `armcomp simulate --poses` read back.
pub fn write_poses(poses: &[Vec<f64>], tree: &KinematicTree, units: Units) -> String {
    let mut out = joint_header(tree, units).join(",");
    out.push('\n');
    for q in poses {
        out.push_str(&joint_row(q, tree, units).join(","));
        out.push('\n');
    }
    out
}
