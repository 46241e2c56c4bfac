//! Measurement CSV files: one row per measured pose.
//!
//! Columns (any order; units in brackets, else the robot file's units):
//! one per joint coordinate named as the joint (`j2[deg]`, `j3[mm]`), required only for the
//! joints that move a measured point (the measured chain; the others hold the robot file's
//! `hold` values); `x`, `y`, `z` (`x[mm]`), the position in the measurement frame, with an
//! optional `point` (the measured point's name; default: the first marker), or numbered
//! triples `x1, y1, z1`, `x2, ...` for several points measured at once (the robot file's
//! markers in order; all three cells of a point left empty when it was not seen); optional
//! orientation in one of four spellings: a unit quaternion `qw, qx, qy, qz` (either sign), a
//! rotation vector `rx, ry, rz` (axis times angle, `rx[deg]`, at most 180° long), URDF
//! roll-pitch-yaw `roll, pitch, yaw` (fixed axes x, then y, then z: `R = Rz(yaw)·Ry(pitch)·Rx(roll)`,
//! as Pinocchio's `rpyToMatrix`), or Euler angles named by their order,
//! `intrinsic_<axes>_1, _2, _3` (about the moving axes: `intrinsic_zyx` is
//! `R = Rz(θ₁)·Ry(θ₂)·Rx(θ₃)`) or `extrinsic_<axes>_1, _2, _3` (about the fixed axes:
//! `extrinsic_xyz` is `R = Rz(θ₃)·Ry(θ₂)·Rx(θ₁)`, roll-pitch-yaw's); optional `payload[kg]`, `temperature[C]`, and joint torques
//! `tau_<joint>[Nm]`; optional `sx, sy, sz` (`sx[mm]`), the standard deviation of each axis of
//! the row's position as the instrument gave it, all three or none, empty in a row without;
//! optional `station` (a name: the instrument set-up that measured the row,
//! each its own measurement frame); the columns of the robot file's sensor (`[[sensors]]`: an
//! accelerometer's reading, an inclinometer's roll and pitch), which give the direction of
//! gravity per row. A robot file of `kind = "fixed_point"` reads rows without a position: a
//! `fixed_point` column names the unknown fixed point the marker was put into (`socket_a`); one of
//! `kind = "plane"`, a `plane` column names the unknown plane it was pressed on (`table`).
//! Other columns (timestamps, marker quality, joints of other limbs) are
//! ignored with one notice. Repeated rows are kept: repeatability measurements are data.

use std::path::Path;

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

mod read;

use read::parse_table;

use crate::error::{Error, Location, Result};
use crate::kinematics::sensor::{GravitySensor, SensorKind, SensorReadings};
use crate::model::tree::KinematicTree;
use crate::model::units::Units;
use crate::support::io::InputLimits;
use crate::support::text::{check_name, shown};

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
    /// The unknown fixed point the measured point was put into, by name, for fixed-point
    /// measurements (`position` is then unused).
    pub fixed_point: Option<String>,
    /// The unknown plane the measured point (a contact frame) was pressed on, by name, for
    /// plane contacts (`position` is then unused).
    pub plane: Option<String>,
    /// The readings of the robot's sensors whose columns are given (one slot per sensor, in
    /// the robot file's order): the directions of gravity they measured.
    pub sensors: SensorReadings,
    /// The station (instrument set-up) that measured it: an index into
    /// [`MeasurementSet::stations`] and, once the robot is given the data's stations
    /// ([`Robot::with_stations`](crate::Robot::with_stations)), into the robot's; 0 when the
    /// data have one station.
    pub station: usize,
    /// The standard deviation of each axis of `position` (m) the instrument gave for this row
    /// (the `sx, sy, sz` columns), when it did: calibration then divides the row's residual by
    /// it instead of the noise all other rows share.
    pub position_std: Option<Vector3<f64>>,
}

/// What a sample measures.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum SampleKind {
    /// A measured position (and orientation, for a pose).
    Position,
    /// A contact with an unknown fixed point, by name ([`Sample::fixed_point`]).
    FixedPoint,
    /// A contact with an unknown plane, by name ([`Sample::plane`]).
    Plane,
}

impl SampleKind {
    /// Every kind, positions first.
    pub const ALL: [SampleKind; 3] = [SampleKind::Position, SampleKind::Plane, SampleKind::FixedPoint];
}

impl Sample {
    /// What the sample measures.
    pub fn kind(&self) -> SampleKind {
        match (&self.fixed_point, &self.plane) {
            (Some(_), _) => SampleKind::FixedPoint,
            (None, Some(_)) => SampleKind::Plane,
            (None, None) => SampleKind::Position,
        }
    }
}

/// A set of measured poses, with the warnings raised while reading it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MeasurementSet {
    /// The samples, in file order.
    pub samples: Vec<Sample>,
    /// The data row (0-based, header and comments excluded) each sample comes from; several
    /// samples share a row when it measures several points.
    pub rows: Vec<usize>,
    /// Non-fatal findings (joint values outside limits, ...), each naming its line.
    pub warnings: Vec<String>,
    /// The names of the stations the samples' [`Sample::station`] index, in order of first
    /// appearance; empty when the data have no `station` column (one station).
    pub stations: Vec<String>,
}

/// What a column holds.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Column {
    Joint {
        coord: usize,
        scale: f64,
    },
    Point,
    /// What the row measures (`point`, `pose` or `fixed_point`), checked against its cells.
    Kind,
    /// The name of the unknown fixed point the marker was put into, or (`plane`) of the
    /// unknown plane it was pressed on: the layout's [group column](CsvLayout::group_column),
    /// or in data of measured positions the rows that are contacts instead.
    Group {
        plane: bool,
    },
    /// `slot`: which measured point a numbered column (`x2` → 1) is; `None` for plain `x`.
    Position {
        slot: Option<usize>,
        axis: usize,
        scale: f64,
    },
    /// An orientation cell: its spelling, which of its cells, and the angle unit's scale
    /// (1 for a quaternion).
    Orientation(Spelling, usize, f64),
    /// `sx`, `sy`, `sz`: the standard deviation of the row's position along an axis.
    PositionStd {
        axis: usize,
        scale: f64,
    },
    Payload(f64),
    Temperature(f64),
    Torque(usize),
    /// A cell of a sensor's reading: the sensor, the cell, and its unit's scale to SI.
    Sensor(usize, usize, f64),
    Station,
    /// A column armcomp does not use (a timestamp, marker quality, another limb's joint).
    Ignored,
}

impl Column {
    /// `v`, a cell of this column, in SI, and the magnitude beyond which it cannot be a
    /// measurement (a typo, a corrupt file; such a number would also overflow the squares and
    /// sums it goes into), with that bound in words.
    fn si_and_bound(&self, v: f64) -> Option<(f64, f64, &'static str)> {
        match *self {
            // A thousand turns, or 10 km of travel.
            Column::Joint { scale, .. } => Some((v * scale, 1e4, "10000 rad (or m for a prismatic joint)")),
            Column::Position { scale, .. } | Column::PositionStd { scale, .. } => Some((v * scale, 1e4, "10 km")),
            Column::Payload(scale) => Some((v * scale, 1e6, "1000 t")),
            Column::Temperature(offset) => Some((v + offset, 1e4, "10000 °C")),
            Column::Torque(_) => Some((v, 1e9, "1e9 N·m")),
            // An accelerometer's scale is free (its direction is used); an inclinometer's
            // angles are checked against their ranges.
            Column::Sensor(_, _, scale) => Some((v * scale, 1e6, "1e6")),
            // A quaternion's norm is checked to be 1.
            Column::Orientation(Spelling::Quaternion, ..) => None,
            Column::Orientation(_, _, scale) => Some((v * scale, 1e4, "10000 rad")),
            Column::Point | Column::Kind | Column::Group { .. } | Column::Station | Column::Ignored => None,
        }
    }
}

/// How a measurement file writes an orientation (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Spelling {
    Quaternion,
    RotationVector,
    RollPitchYaw,
    /// Euler angles about `axes` (0 x, 1 y, 2 z) in turn: the moving frame's axes
    /// (`intrinsic_<axes>_1, _2, _3`) or the fixed frame's (`extrinsic_<axes>_1, _2, _3`).
    Euler {
        intrinsic: bool,
        axes: [usize; 3],
    },
}

/// The largest norm a rotation vector's cells may have: π, with room for the rounding of a
/// half turn written in degrees. A larger one is no rotation vector a tracker writes (its
/// rotation is that of a shorter vector the other way), but three Euler angles in the wrong
/// columns often are.
const MAX_ROTATION_VECTOR_NORM: f64 = std::f64::consts::PI + 1e-4;

impl Spelling {
    const ALL: [(Spelling, [&'static str; 4]); 3] = [
        (Spelling::Quaternion, ["qw", "qx", "qy", "qz"]),
        (Spelling::RotationVector, ["rx", "ry", "rz", ""]),
        (Spelling::RollPitchYaw, ["roll", "pitch", "yaw", ""]),
    ];

    /// The spelling and cell of column `name`, if it is an orientation column.
    fn of(name: &str) -> Option<(Spelling, usize)> {
        Spelling::ALL
            .iter()
            .find_map(|(s, cells)| cells.iter().position(|c| !c.is_empty() && *c == name).map(|k| (*s, k)))
            .or_else(|| Spelling::euler_cell(name))
    }

    /// `intrinsic_zyx_2` → Euler angles about z, y, x of the moving frame, cell 1; consecutive
    /// axes must differ (`zyz` is an order, `zzy` is not).
    fn euler_cell(name: &str) -> Option<(Spelling, usize)> {
        let (frame, rest) = name.split_once('_')?;
        let intrinsic = match frame {
            "intrinsic" => true,
            "extrinsic" => false,
            _ => return None,
        };
        let (order, cell) = rest.split_once('_')?;
        let cell = match cell {
            "1" => 0,
            "2" => 1,
            "3" => 2,
            _ => return None,
        };
        let mut axes = [0; 3];
        let letters = order.as_bytes();
        if letters.len() != 3 {
            return None;
        }
        for (a, l) in axes.iter_mut().zip(letters) {
            *a = match l {
                b'x' => 0,
                b'y' => 1,
                b'z' => 2,
                _ => return None,
            };
        }
        (axes[0] != axes[1] && axes[1] != axes[2]).then_some((Spelling::Euler { intrinsic, axes }, cell))
    }

    /// The spelling's column names, in cell order.
    fn cells(self) -> Vec<String> {
        if let Spelling::Euler { intrinsic, axes } = self {
            let frame = if intrinsic { "intrinsic" } else { "extrinsic" };
            let order: String = axes.iter().map(|&a| ['x', 'y', 'z'][a]).collect();
            return (1..=3).map(|k| format!("{frame}_{order}_{k}")).collect();
        }
        let cells = &Spelling::ALL
            .iter()
            .find(|(s, _)| *s == self)
            .expect("every other spelling is listed")
            .1;
        let n = if self == Spelling::Quaternion { 4 } else { 3 };
        cells[..n].iter().map(|c| c.to_string()).collect()
    }

    /// The rotation of cells `v` (angles in rad); an error for a quaternion whose norm is not 1
    /// and for a rotation vector longer than half a turn.
    fn rotation(self, v: [f64; 4]) -> std::result::Result<UnitQuaternion<f64>, String> {
        match self {
            Spelling::Quaternion => {
                let q = Quaternion::new(v[0], v[1], v[2], v[3]);
                if (q.norm() - 1.0).abs() > 1e-3 {
                    return Err(format!("orientation quaternion has norm {:.6}, expected 1", q.norm()));
                }
                Ok(UnitQuaternion::from_quaternion(q))
            }
            Spelling::RotationVector => {
                let r = Vector3::new(v[0], v[1], v[2]);
                if r.norm() > MAX_ROTATION_VECTOR_NORM {
                    return Err(format!(
                        "rotation vector rx, ry, rz has norm {:.2}°, but a rotation vector (axis times angle) is at \
                         most 180° long: are these Euler angles? Name their columns by their order, e.g. \
                         intrinsic_xyz_1, intrinsic_xyz_2, intrinsic_xyz_3 (or extrinsic_…, or roll, pitch, yaw)",
                        r.norm().to_degrees()
                    ));
                }
                Ok(UnitQuaternion::from_scaled_axis(r))
            }
            Spelling::RollPitchYaw => Ok(UnitQuaternion::from_euler_angles(v[0], v[1], v[2])),
            Spelling::Euler { intrinsic, axes } => {
                let turn = |k: usize| UnitQuaternion::from_axis_angle(&Vector3::ith_axis(axes[k]), v[k]);
                // Intrinsic turns compose to the right (each about the axes the last left),
                // extrinsic ones to the left (each about the fixed axes).
                Ok(if intrinsic {
                    turn(0) * turn(1) * turn(2)
                } else {
                    turn(2) * turn(1) * turn(0)
                })
            }
        }
    }
}

/// Splits a column header `x[mm]` into its name and optional unit.
pub fn split_header(h: &str) -> (&str, Option<&str>) {
    let h = h.trim();
    match (h.find('['), h.ends_with(']')) {
        (Some(i), true) => (h[..i].trim(), Some(h[i + 1..h.len() - 1].trim())),
        _ => (h, None),
    }
}

/// What a measurement CSV is read against: the robot's joints and points, and the values of
/// joints a file may leave out ([`Robot::csv_layout`](crate::Robot::csv_layout) builds it).
#[derive(Debug, Clone)]
pub struct CsvLayout<'a> {
    /// The kinematic tree: joint names, limits, points.
    pub tree: &'a KinematicTree,
    /// Units of columns whose header gives none.
    pub units: Units,
    /// The measured points: numbered position columns `x1, y1, z1`, `x2, ...` are `points[0]`,
    /// `points[1]`, ...; plain `x, y, z` without a `point` column measure `points[0]`.
    pub points: Vec<usize>,
    /// Per independent coordinate, the value it holds when the file has no column for it
    /// (rad or m); `None` makes its column required.
    pub hold: Vec<Option<f64>>,
    /// Whether the robot measures poses: a file without orientation columns is then read as
    /// positions with a warning.
    pub orientation: bool,
    /// Whether the robot measures fixed points: rows then name their fixed point in a
    /// `fixed_point` column instead of giving a position.
    pub fixed_points: bool,
    /// Whether the robot measures plane contacts: rows then name their plane in a `plane`
    /// column instead of giving a position.
    pub planes: bool,
    /// The robot's sensors, whose columns are read when the file has them (each all or
    /// none).
    pub sensors: Vec<GravitySensor>,
}

impl<'a> CsvLayout<'a> {
    /// A layout in which every joint needs a column and plain `x, y, z` measure `point`.
    pub fn strict(tree: &'a KinematicTree, units: Units, point: usize) -> Self {
        CsvLayout {
            tree,
            units,
            points: vec![point],
            hold: vec![None; tree.nq()],
            orientation: false,
            fixed_points: false,
            planes: false,
            sensors: Vec::new(),
        }
    }

    /// The column rows without a measured position name their group in (`fixed_point` or
    /// `plane`), with what it names, when the robot measures such rows.
    pub fn group_column(&self) -> Option<(&'static str, &'static str)> {
        if self.fixed_points {
            Some(("fixed_point", "fixed point"))
        } else if self.planes {
            Some(("plane", "plane"))
        } else {
            None
        }
    }
}

/// Reads measurements (see the module documentation) against `layout`, within `limits`.
pub fn read_csv(path: &Path, layout: &CsvLayout<'_>, limits: InputLimits) -> Result<MeasurementSet> {
    let text = crate::support::io::read_text(path, limits)?;
    parse_csv(&text, path, layout)
}

/// Parses measurement CSV text (see [`read_csv`]); `path` is used in messages.
pub fn parse_csv(text: &str, path: &Path, layout: &CsvLayout<'_>) -> Result<MeasurementSet> {
    parse_table(text, path, layout, true)
}

/// Parses a CSV of joint configurations only (joint columns, same header rules); other
/// columns, if present, are ignored.
pub fn parse_poses(text: &str, path: &Path, layout: &CsvLayout<'_>) -> Result<Vec<Vec<f64>>> {
    Ok(parse_poses_with_sensors(text, path, layout)?
        .into_iter()
        .map(|(q, _)| q)
        .collect())
}

/// [`parse_poses`] with each row's readings of the layout's sensors whose columns the table
/// has (each sensor all its columns or none, its cells checked as in measurement files).
pub fn parse_poses_with_sensors(
    text: &str,
    path: &Path,
    layout: &CsvLayout<'_>,
) -> Result<Vec<(Vec<f64>, SensorReadings)>> {
    Ok(parse_table(text, path, layout, false)?
        .samples
        .into_iter()
        .map(|s| (s.q, s.sensors))
        .collect())
}

/// Whether `name` is a column measurement files give a meaning of their own (besides the
/// fixed names the robot file checks): an orientation cell or a numbered position.
pub fn is_measurement_column(name: &str) -> bool {
    Spelling::of(name).is_some() || numbered_position(name).is_some()
}

/// The 1-based line of the record a csv reader read at `position` in `text` (0 when
/// unknown). The reader's own line count leaves out comment lines, and its position is where
/// it started reading, before the comment and blank lines it skipped: those are skipped here.
/// For many records of one text use a [`LineCounter`].
pub fn line_at(text: &str, position: Option<&csv::Position>) -> usize {
    LineCounter::new(text).line_at(position)
}

/// [`line_at`] for the records of one text read in order: the newlines are counted on from the
/// previous record, so numbering every row of a file stays linear in its size.
#[derive(Debug, Clone)]
pub struct LineCounter<'a> {
    text: &'a str,
    /// A byte offset and the 1-based line it is on.
    byte: usize,
    line: usize,
}

impl<'a> LineCounter<'a> {
    /// A counter at the start of `text`.
    pub fn new(text: &'a str) -> Self {
        LineCounter { text, byte: 0, line: 1 }
    }

    /// The 1-based line of the record read at `position` (0 when unknown); positions before
    /// the previous one are counted from the start again.
    pub fn line_at(&mut self, position: Option<&csv::Position>) -> usize {
        let Some(p) = position else { return 0 };
        let start = (p.byte() as usize).min(self.text.len());
        if start < self.byte {
            (self.byte, self.line) = (0, 1);
        }
        self.line += self.text.as_bytes()[self.byte..start]
            .iter()
            .filter(|&&b| b == b'\n')
            .count();
        self.byte = start;
        let skipped = self
            .text
            .get(start..)
            .unwrap_or_default()
            .lines()
            .take_while(|l| l.trim().is_empty() || l.starts_with('#'))
            .count();
        self.line + skipped
    }
}

/// An error in measurement file `path` at `line`, in no one column.
fn input_error(path: &Path, line: Option<usize>, message: String) -> Error {
    Error::input_at(path, line, None, message)
}

/// Most cells a line of a measurement file may hold: far more than the columns of any robot's
/// file (joints, markers, sensors), and few enough that a record of them is small.
pub const MAX_COLUMNS: usize = 1 << 20;

/// Refuses, in one pass over the bytes and before any is parsed, a line of more than
/// [`MAX_COLUMNS`] cells: the CSV reader keeps a record's cell boundaries, so a file that is a
/// line of commas would fill the memory many times its size.
fn check_line_widths(text: &str, path: &Path) -> Result<()> {
    for (k, line) in text.lines().enumerate() {
        let cells = line.bytes().filter(|b| *b == b',').count() + 1;
        if cells > MAX_COLUMNS {
            return Err(input_error(
                path,
                Some(k + 1),
                format!("{cells} cells in one line; a measurement file has at most {MAX_COLUMNS} columns"),
            ));
        }
    }
    Ok(())
}

/// A reader of measurement CSV `text` (comments `#`, cells trimmed, rows of any length) and its
/// header; `path` is used in messages.
fn open_table<'t>(text: &'t str, path: &Path) -> Result<(csv::Reader<&'t [u8]>, csv::StringRecord)> {
    check_line_widths(text, path)?;
    let mut reader = csv::ReaderBuilder::new()
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let headers = reader
        .headers()
        .map_err(|e| {
            input_error(
                path,
                Some(line_at(text, e.position())),
                format!("cannot read the header: {e}"),
            )
        })?
        .clone();
    Ok((reader, headers))
}

/// Columns that name a set-up of the measurement (a session, a ground, a day): folds hold out
/// whole values of the first of them a file has when the user names no column, since rows of
/// one set-up share what changed between set-ups.
pub const SET_UP_COLUMNS: [&str; 5] = ["session", "setup", "set_up", "ground", "day"];

/// The first of [`SET_UP_COLUMNS`] the header of measurement CSV `text` has, if any.
pub fn set_up_column(text: &str, path: &Path) -> Result<Option<&'static str>> {
    let (_, headers) = open_table(text, path)?;
    Ok(SET_UP_COLUMNS
        .into_iter()
        .find(|c| headers.iter().any(|h| split_header(h).0 == *c)))
}

/// Words whose presence in a column's name marks it as ordering the rows in time or
/// temperature: what folds by blocks of it (`--group-by COLUMN:N`) can hold out.
const ORDERING_WORDS: [&str; 5] = ["time", "stamp", "date", "temp", "hour"];

/// The columns of measurement CSV `text` whose names say they carry time or temperature
/// (see [`ORDERING_WORDS`]), in header order.
pub fn ordering_columns(text: &str, path: &Path) -> Result<Vec<String>> {
    let (_, headers) = open_table(text, path)?;
    Ok(headers
        .iter()
        .map(|h| split_header(h).0.to_string())
        .filter(|name| {
            let lower = name.to_ascii_lowercase();
            ORDERING_WORDS.iter().any(|w| lower.contains(w))
        })
        .collect())
}

/// The values of column `name` of measurement CSV `text`, one per data row (header and
/// comments excluded, as [`MeasurementSet::rows`] counts them), trimmed: what groups rows
/// into sessions or stations. `path` is used in messages.
pub fn column_values(text: &str, path: &Path, name: &str) -> Result<Vec<String>> {
    let err = |line: Option<usize>, message: String| Error::input_at(path, line, Some(name), message);
    let (mut reader, headers) = open_table(text, path)?;
    // The bare name or the header as written, unit and all (`x[mm]`), which the error lists.
    let wanted = split_header(name).0;
    let Some(col) = headers.iter().position(|h| split_header(h).0 == wanted) else {
        return Err(err(
            Some(line_at(text, headers.position())),
            format!(
                "no column `{}` to group the rows by; the header has {}",
                shown(name),
                listed(&headers.iter().collect::<Vec<_>>())
            ),
        ));
    };
    let mut lines = LineCounter::new(text);
    reader
        .records()
        .map(|r| {
            let r = r.map_err(|e| {
                input_error(
                    path,
                    Some(line_at(text, e.position())),
                    format!("cannot read the row: {e}"),
                )
            })?;
            match r.get(col) {
                Some(v) if !v.is_empty() => check_name(v).map(|()| v.to_string()).map_err(|m| {
                    err(
                        Some(lines.line_at(r.position())),
                        format!("column `{}`: {m}", shown(name)),
                    )
                }),
                _ => Err(err(
                    Some(lines.line_at(r.position())),
                    format!(
                        "column `{}` is empty in this row; every row needs its group",
                        shown(name)
                    ),
                )),
            }
        })
        .collect()
}

/// Whether the header of CSV `text` has a measured-position column (`x`, `y`, `z` or numbered
/// `x1`, ...): measurements rather than joint configurations alone.
pub fn has_positions(text: &str) -> bool {
    // A header too wide to read is not looked into: the reader of measurements refuses it.
    let first = text
        .lines()
        .find(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'));
    if first.is_some_and(|l| l.bytes().filter(|b| *b == b',').count() >= MAX_COLUMNS) {
        return true;
    }
    let mut reader = csv::ReaderBuilder::new()
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    reader.headers().is_ok_and(|h| {
        h.iter().any(|c| {
            let (name, _) = split_header(c);
            matches!(name, "x" | "y" | "z") || numbered_position(name).is_some()
        })
    })
}

/// `x3` → `(axis 0, slot 2)`: a numbered position column.
fn numbered_position(name: &str) -> Option<(usize, usize)> {
    let axis = ["x", "y", "z"].iter().position(|a| name.starts_with(a))?;
    let k: usize = name[1..].parse().ok().filter(|k| *k >= 1)?;
    Some((axis, k - 1))
}

/// Checks a row's `kind` cell against what its other cells measure.
fn check_kind_cell(kind: &str, s: &Sample) -> std::result::Result<(), String> {
    let is = if s.fixed_point.is_some() {
        "fixed_point"
    } else if s.plane.is_some() {
        "plane"
    } else if s.orientation.is_some() {
        "pose"
    } else {
        "point"
    };
    let gives = |k: &str| match k {
        "fixed_point" => "names a fixed point and no position",
        "plane" => "names a plane and no position",
        "pose" => "gives a position and an orientation",
        _ => "gives a position without an orientation",
    };
    match kind.trim() {
        k if k == is => Ok(()),
        k @ ("point" | "pose" | "fixed_point" | "plane") => Err(format!(
            "column `kind` says `{k}`, but the row {}; a `{k}` row {}",
            gives(is),
            gives(k)
        )),
        k => Err(format!(
            "column `kind`: `{}` is not a measurement kind; expected point, pose, fixed_point or plane",
            shown(k)
        )),
    }
}

/// `` `a`, `b` `` ..., the first ten of `names` (each as [`shown`]) and how many more there are.
pub fn listed(names: &[&str]) -> String {
    let mut text = names
        .iter()
        .take(10)
        .map(|c| format!("`{}`", shown(c)))
        .collect::<Vec<_>>()
        .join(", ");
    if names.len() > 10 {
        text.push_str(&format!(" and {} more", names.len() - 10));
    }
    text
}

/// Which data rows of a measurement file to use (0-based, header excluded): comma-separated
/// `even`, `odd`, a row `N`, or a half-open range `A..B`, `A..`, `..B`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RowSelection(Vec<RowRange>);

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RowRange {
    Even,
    Odd,
    Span(usize, Option<usize>),
}

impl std::str::FromStr for RowSelection {
    type Err = Error;

    fn from_str(text: &str) -> Result<Self> {
        let invalid = |item: &str, reason: &str| Error::InvalidArgument {
            what: format!("row selection `{item}`"),
            reason: reason.into(),
        };
        let bad = |item: &str| {
            invalid(
                item,
                "expected `even`, `odd`, a row number or a range `A..B`, `A..`, `..B` (rows 0-based)",
            )
        };
        let number = |t: &str, item: &str| t.trim().parse::<usize>().map_err(|_| bad(item));
        let items = text
            .split(',')
            .map(|item| {
                let t = item.trim();
                Ok(match t {
                    "even" => RowRange::Even,
                    "odd" => RowRange::Odd,
                    _ => match t.split_once("..") {
                        Some((a, b)) => {
                            let start = if a.trim().is_empty() { 0 } else { number(a, item)? };
                            let end = if b.trim().is_empty() {
                                None
                            } else {
                                Some(number(b, item)?)
                            };
                            if end.is_some_and(|e| e <= start) {
                                return Err(invalid(item, "the range is empty"));
                            }
                            RowRange::Span(start, end)
                        }
                        None => {
                            let n = number(t, item)?;
                            RowRange::Span(n, Some(n + 1))
                        }
                    },
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(RowSelection(items))
    }
}

/// The selection as it is written (`even,3,10..20`), for messages.
impl std::fmt::Display for RowSelection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        for (k, r) in self.0.iter().enumerate() {
            if k > 0 {
                write!(f, ",")?;
            }
            match *r {
                RowRange::Even => write!(f, "even")?,
                RowRange::Odd => write!(f, "odd")?,
                RowRange::Span(a, Some(b)) if b == a + 1 => write!(f, "{a}")?,
                RowRange::Span(a, Some(b)) => write!(f, "{a}..{b}")?,
                RowRange::Span(a, None) => write!(f, "{a}..")?,
            }
        }
        Ok(())
    }
}

impl RowSelection {
    /// Whether data row `row` is selected.
    pub fn contains(&self, row: usize) -> bool {
        self.0.iter().any(|r| match *r {
            RowRange::Even => row.is_multiple_of(2),
            RowRange::Odd => row % 2 == 1,
            RowRange::Span(a, b) => row >= a && b.is_none_or(|b| row < b),
        })
    }
}

impl MeasurementSet {
    /// The samples of the selected rows, and their rows.
    pub fn select_rows(&self, selection: &RowSelection) -> MeasurementSet {
        self.select_rows_by(|r| selection.contains(r))
    }

    /// The samples of the data rows `keep` keeps, and their rows. A station none of them
    /// belongs to is dropped (the kept samples' station indices follow), so a selection of one
    /// station's rows is data of one set-up, and no command sees a station without rows.
    pub fn select_rows_by(&self, keep: impl Fn(usize) -> bool) -> MeasurementSet {
        let mut set = self.rows_where(keep);
        let used: Vec<bool> = (0..set.stations.len())
            .map(|k| set.samples.iter().any(|s| s.station == k))
            .collect();
        let index: Vec<usize> = (used.iter())
            .scan(0, |next, &u| {
                let k = *next;
                *next += usize::from(u);
                Some(k)
            })
            .collect();
        for s in &mut set.samples {
            if let Some(&k) = index.get(s.station) {
                s.station = k;
            }
        }
        let mut kept = used.iter();
        set.stations.retain(|_| kept.next().copied().unwrap_or(true));
        set
    }

    /// The samples of the data rows `keep` keeps, and their rows, every station kept with its
    /// index (for subsets of data whose stations a robot has already adopted).
    pub fn rows_where(&self, keep: impl Fn(usize) -> bool) -> MeasurementSet {
        let (samples, rows) = (self.samples.iter().zip(&self.rows))
            .filter(|(_, r)| keep(**r))
            .map(|(s, r)| (s.clone(), *r))
            .unzip();
        MeasurementSet {
            samples,
            rows,
            warnings: self.warnings.clone(),
            stations: self.stations.clone(),
        }
    }

    /// Several measurement files read as one set, each file its own station named by
    /// `names[i]` (its file name, say) unless it has a `station` column, whose names are
    /// used: rows of different files with the same station name share a frame. Data rows are
    /// numbered on across the files, in order. One set is returned as it is.
    pub fn from_files(sets: Vec<MeasurementSet>, names: &[String]) -> MeasurementSet {
        if sets.len() == 1 {
            return sets.into_iter().next().unwrap_or_default();
        }
        let mut out = MeasurementSet::default();
        for (set, name) in sets.into_iter().zip(names) {
            let first_row = out.rows.last().map_or(0, |r| r + 1);
            let own: Vec<&String> = if set.stations.is_empty() {
                vec![name]
            } else {
                set.stations.iter().collect()
            };
            let index: Vec<usize> = own
                .iter()
                .map(|n| match out.stations.iter().position(|o| o == *n) {
                    Some(k) => k,
                    None => {
                        out.stations.push((*n).clone());
                        out.stations.len() - 1
                    }
                })
                .collect();
            out.samples.extend(set.samples.into_iter().map(|mut s| {
                s.station = index[s.station];
                s
            }));
            out.rows.extend(set.rows.iter().map(|r| first_row + r));
            out.warnings.extend(set.warnings);
        }
        out
    }
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
    // Fixed-point rows of mixed data measure no position.
    let mut norms: Vec<f64> = (set.samples.iter())
        .filter(|s| s.fixed_point.is_none())
        .map(|s| s.position.norm())
        .collect();
    norms.sort_by(f64::total_cmp);
    let median = norms.get(norms.len() / 2).copied().unwrap_or(0.0);
    let pos_scale = columns.iter().find_map(|c| {
        if let Column::Position { scale, .. } = c {
            Some(*scale)
        } else {
            None
        }
    });
    // No arm measured by a tracker sits 50 m from it; such numbers are millimetres.
    if pos_scale == Some(1.0) && median > 50.0 {
        return Err(Error::InputAt {
            location: Location::file(path),
            column: None,
            message: format!(
                "positions are declared in metres but their median distance is {median:.0} m; they look like millimetres (write `x[mm]`)"
            ),
        });
    }
    for (col, head) in columns.iter().zip(headers.iter()) {
        if let Column::Joint { coord, scale } = *col {
            let max = set.samples.iter().map(|s| s.q[coord].abs()).fold(0.0, f64::max);
            let prismatic = tree.coordinate_is_prismatic()[coord];
            if !prismatic && scale == 1.0 && max > 4.0 * std::f64::consts::PI {
                return Err(Error::InputAt {
                    location: Location::file(path),
                    column: Some(head.to_string()),
                    message: format!(
                        "column `{}` is in radians but reaches {max:.1}; it looks like degrees (write `[deg]`)",
                        shown(head)
                    ),
                });
            }
            if prismatic && scale == 1.0 && max > 50.0 {
                return Err(Error::InputAt {
                    location: Location::file(path),
                    column: Some(head.to_string()),
                    message: format!(
                        "column `{}` is in metres but reaches {max:.1}; it looks like millimetres (write `[mm]`)",
                        shown(head)
                    ),
                });
            }
        }
    }
    Ok(())
}

/// Writes measurements as CSV in the given units (joint columns as `name[unit]`, positions as
/// `x[unit]`, or the `fixed_point` or `plane` column of samples without a position); deterministic text for equal
/// inputs.
pub fn write_csv(set: &MeasurementSet, tree: &KinematicTree, units: Units) -> String {
    write_csv_with_sensors(set, tree, units, &[])
}

/// [`write_csv`] with the columns of `sensors` (the robot's, in its order; an accelerometer's
/// in g, an inclinometer's in the angle unit): those of each sensor every sample has a reading
/// of.
pub fn write_csv_with_sensors(
    set: &MeasurementSet,
    tree: &KinematicTree,
    units: Units,
    sensors: &[GravitySensor],
) -> String {
    let lu = units.length.symbol();
    let mut header = joint_header(tree, units);
    let several_points = set.samples.iter().any(|s| s.point != set.samples[0].point);
    if several_points {
        header.push("point".into());
    }
    let with_station = !set.stations.is_empty();
    if with_station {
        header.push("station".into());
    }
    let first = set.samples.first();
    // Mixed data give positions, and fixed points or planes in a column of their own.
    let fixed_points = set.samples.iter().any(|s| s.fixed_point.is_some());
    let planes = set.samples.iter().any(|s| s.plane.is_some());
    let measured = set.samples.iter().find(|s| s.kind() == SampleKind::Position);
    if fixed_points {
        header.push("fixed_point".into());
    }
    if planes {
        header.push("plane".into());
    }
    if measured.is_some() {
        header.extend(["x", "y", "z"].map(|a| format!("{a}[{lu}]")));
    }
    let with_quat = measured.is_some_and(|s| s.orientation.is_some());
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
    let read: Vec<(usize, &GravitySensor)> = (sensors.iter().enumerate())
        .filter(|(k, _)| first.is_some() && set.samples.iter().all(|s| s.sensors.get(*k).is_some()))
        .collect();
    for (_, g) in &read {
        let unit = match g.kind {
            SensorKind::Accelerometer => "g",
            SensorKind::Inclinometer => units.angle.symbol(),
        };
        header.extend(g.columns.iter().map(|c| format!("{c}[{unit}]")));
    }
    let rows = set.samples.iter().map(|s| {
        let mut row = joint_row(&s.q, tree, units);
        if several_points {
            row.push(tree.points()[s.point].name.clone());
        }
        if with_station {
            row.push(set.stations[s.station].clone());
        }
        if fixed_points {
            row.push(s.fixed_point.clone().unwrap_or_default());
        }
        if planes {
            row.push(s.plane.clone().unwrap_or_default());
        }
        if measured.is_some() {
            match s.fixed_point.is_some() || s.plane.is_some() {
                true => row.extend(std::iter::repeat_n(String::new(), 3)),
                false => row.extend(s.position.iter().map(|v| format!("{}", units.len_out(*v)))),
            }
        }
        if with_quat {
            match s.orientation {
                Some(q) => row.extend([q.w, q.i, q.j, q.k].map(|v| format!("{v}"))),
                None => row.extend(std::iter::repeat_n(String::new(), 4)),
            }
        }
        if with_payload {
            row.push(format!("{}", s.payload.unwrap_or(0.0)));
        }
        if with_temp {
            row.push(format!("{}", s.temperature.unwrap_or(20.0)));
        }
        for (reading, g) in read.iter().filter_map(|(k, g)| s.sensors.get(*k).map(|r| (r, g))) {
            let cells = g.kind.cells_for(&reading.direction);
            row.extend(cells.iter().take(g.columns.len()).map(|&v| match g.kind {
                SensorKind::Accelerometer => format!("{v}"),
                SensorKind::Inclinometer => format!("{}", units.ang_out(v)),
            }));
        }
        row
    });
    csv_text(std::iter::once(header).chain(rows))
}

/// CSV text of `records`, the header first, every record as long as the header, through the
/// csv crate: a field with a comma, a quote or a line break is quoted, lines end in `\n`.
pub fn csv_text<R, F>(records: impl IntoIterator<Item = R>) -> String
where
    R: IntoIterator<Item = F>,
    F: AsRef<[u8]>,
{
    let mut writer = csv::Writer::from_writer(Vec::new());
    for record in records {
        writer
            .write_record(record)
            .expect("records as long as the header write to memory");
    }
    let bytes = writer.into_inner().expect("writing to memory cannot fail");
    String::from_utf8(bytes).expect("the fields are text")
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
    let rows = poses.iter().map(|q| joint_row(q, tree, units));
    csv_text(std::iter::once(joint_header(tree, units)).chain(rows))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn record_lines_count_comment_and_blank_lines() {
        // Lines: 1 header, 2 comment, 3 row, 4 blank, 5 comment, 6 row, 7 row.
        let text = "a,b\n# note\n1,2\n\n# another\n3,4\n5,6\n";
        let mut reader = csv::ReaderBuilder::new()
            .comment(Some(b'#'))
            .from_reader(text.as_bytes());
        let header = reader.headers().unwrap().clone();
        let rows: Vec<csv::StringRecord> = reader.records().map(|r| r.unwrap()).collect();
        let mut lines = LineCounter::new(text);
        assert_eq!(lines.line_at(header.position()), 1);
        let got: Vec<usize> = rows.iter().map(|r| lines.line_at(r.position())).collect();
        assert_eq!(got, [3, 6, 7]);
        // Out of order: counted from the start again, as the one-off function does.
        assert_eq!(lines.line_at(rows[0].position()), 3);
        assert_eq!(line_at(text, rows[2].position()), 7);
        assert_eq!(lines.line_at(None), 0);
    }
}
