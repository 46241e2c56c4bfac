//! The measurement table reader, in its steps: the file's size, the header's columns and how
//! they fit together, then each row's cells into samples, and the warnings of the whole file.

use std::collections::HashSet;
use std::path::Path;

use nalgebra::{Vector3, Vector4};

use super::{
    Column, CsvLayout, LineCounter, MeasurementSet, Sample, Spelling, check_kind_cell, check_magnitudes, input_error,
    line_at, listed, numbered_position, open_table, split_header,
};
use crate::error::{Error, Result};
use crate::kinematics::sensor::{GravityReading, MAX_SENSORS, SensorReadings, gravity_sensor_index};
use crate::model::units::{AngleUnit, LengthUnit};
use crate::support::limits::{self, Cost};
use crate::support::text::{check_name, shown};

/// Reads a measurement table against `layout`; without `with_positions` only the joint
/// columns are read (a file of configurations).
pub(super) fn parse_table(
    text: &str,
    path: &Path,
    layout: &CsvLayout<'_>,
    with_positions: bool,
) -> Result<MeasurementSet> {
    let table = Table {
        text,
        path,
        layout,
        with_positions,
    };
    let (mut reader, record) = open_table(text, path)?;
    let line = line_at(text, record.position());
    table.check_size(&record, line)?;
    let header = table.header(record, line)?;
    let mut set = MeasurementSet::default();
    table.header_warnings(&header, &mut set);
    table.read_rows(&mut reader, &header, &mut set)?;
    if set.samples.is_empty() {
        return Err(table.err(None, "no measurements (only a header)".into()));
    }
    if with_positions && layout.group_column().is_none() {
        check_magnitudes(&set, &header.columns, &header.record, layout.tree, path)?;
    }
    Ok(set)
}

/// One table being read: its text, where it came from, and what the robot expects of it.
struct Table<'t, 'l> {
    text: &'t str,
    path: &'t Path,
    layout: &'t CsvLayout<'l>,
    with_positions: bool,
}

/// The header read: what each column holds and how the rows are shaped.
struct Header {
    record: csv::StringRecord,
    /// Its cells as messages show them (see [`shown`]).
    shown: Vec<String>,
    /// Its 1-based line.
    line: usize,
    columns: Vec<Column>,
    /// The columns armcomp does not use, as written.
    ignored: Vec<String>,
    /// The position columns' slots: `None` for plain `x, y, z`, else which measured point.
    slots: Vec<Option<usize>>,
    /// How the orientation is spelt, when the table gives one.
    spelling: Option<Spelling>,
    /// The sensors whose columns the table has (all of them), by index into the layout's.
    sensors: Vec<usize>,
    has_torque: bool,
    /// Whether the rows give their positions' standard deviations (`sx, sy, sz`).
    has_position_std: bool,
    /// In data that mix measured positions with contacts, the columns naming a row's fixed
    /// point or plane (a robot of fixed points or planes only has a group column of its own).
    mixed_groups: Vec<usize>,
}

impl Header {
    /// The column and kind of the contacts among measured positions: `fixed_point` rows,
    /// `plane` rows, or both.
    fn mixed_kind(&self) -> (&'static str, &'static str) {
        let planes = self
            .mixed_groups
            .iter()
            .map(|&k| self.columns[k] == Column::Group { plane: true });
        match (planes.clone().any(|p| p), planes.clone().any(|p| !p)) {
            (true, true) => ("fixed_point` or `plane", "fixed point or plane"),
            (true, false) => ("plane", "plane"),
            _ => ("fixed_point", "fixed point"),
        }
    }

    fn has(&self, f: impl Fn(&Column) -> bool) -> bool {
        self.columns.iter().any(f)
    }
}

/// The cells of one row read so far.
struct Row<'c> {
    sample: Sample,
    /// Whether the row names a fixed point among measured positions (it gives no position).
    fixed_row: bool,
    kind_cell: Option<&'c str>,
    angles: [f64; 4],
    /// Per sensor of the layout, the cells of its reading.
    sensor_cells: [Vector4<f64>; MAX_SENSORS],
    /// Per slot, the position and how many of its cells were empty.
    positions: Vec<(Vector3<f64>, usize)>,
    /// The position's standard deviations, and how many of their cells were empty.
    position_std: (Vector3<f64>, usize),
}

/// One cell of a row: its text, its column, the column's header and the row's line.
#[derive(Clone, Copy)]
struct Cell<'c, 'h> {
    field: &'c str,
    col: &'h Column,
    head: &'h str,
    line: usize,
}

/// Per coordinate, the rows outside its limits, the first one's line and the worst excess.
type Outside = Vec<(usize, usize, f64)>;

impl<'t> Table<'t, '_> {
    fn err(&self, line: Option<usize>, message: String) -> Error {
        input_error(self.path, line, message)
    }

    /// An error in column `column` (its name or header cell) at `line`.
    fn err_in(&self, line: usize, column: &str, message: String) -> Error {
        Error::input_at(self.path, Some(line), Some(column), message)
    }

    /// Refuses, before any row is parsed, a table too large to work on, and one whose
    /// separator is not a comma.
    fn check_size(&self, record: &csv::StringRecord, line: usize) -> Result<()> {
        // Every cell of a column is read and kept in the row's record: a column costs its share
        // of each line.
        let lines = self.text.lines().count().max(1) as f64;
        limits::check("columns of the header", record.len(), "columns", &|n| {
            Cost::per_unit(n, 64.0 + 16.0 * lines, 50.0 * lines)
        })
        .map_err(|e| self.err(Some(line), e.to_string()))?;
        // Counted before any row is parsed: a file of millions of rows is refused at once.
        let rows = (self.text.lines().skip(line))
            .filter(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
            .count();
        limits::check(
            "data rows of a measurement file",
            rows,
            "rows",
            &limits::measurement_row_cost,
        )
        .map_err(|e| self.err(None, e.to_string()))?;
        // Spreadsheets export `;`- or tab-separated files, whose header reads as one mangled column.
        if let Some((_, words)) = [(';', "semicolons"), ('\t', "tabs")]
            .into_iter()
            .find(|(d, _)| record.iter().any(|h| h.contains(*d)))
        {
            return Err(self.err(
                Some(line),
                format!(
                    "the header separates its columns by {words}; measurement files are comma-separated (save the file as CSV with `,` between values)"
                ),
            ));
        }
        Ok(())
    }

    /// Reads the header's columns and checks that they fit together.
    fn header(&self, record: csv::StringRecord, line: usize) -> Result<Header> {
        let mut columns = Vec::new();
        let mut seen = HashSet::new();
        let mut ignored = Vec::new();
        for h in record.iter() {
            let name = split_header(h).0;
            if !seen.insert(name) {
                return Err(self.err_in(line, name, format!("column `{}` appears twice", shown(name))));
            }
            let column = self.column(h, line)?;
            if column == Column::Ignored {
                ignored.push(h.to_string());
            }
            columns.push(column);
        }
        let mut header = Header {
            shown: record.iter().map(shown).collect(),
            record,
            line,
            columns,
            ignored,
            slots: Vec::new(),
            spelling: None,
            sensors: Vec::new(),
            has_torque: false,
            has_position_std: false,
            mixed_groups: Vec::new(),
        };
        self.check_joint_columns(&header)?;
        header.slots = self.position_slots(&header)?;
        header.spelling = self.orientation_spelling(&header)?;
        header.sensors = self.sensor_columns(&header)?;
        header.has_torque = header.has(|k| matches!(k, Column::Torque(_)));
        header.has_position_std = self.position_std_columns(&header)?;
        if self.with_positions && self.layout.group_column().is_none() {
            header.mixed_groups = (header.columns.iter().enumerate())
                .filter(|(_, c)| matches!(c, Column::Group { .. }))
                .map(|(k, _)| k)
                .collect();
        }
        Ok(header)
    }

    /// What header cell `h` (a name and an optional `[unit]`) holds.
    fn column(&self, h: &str, line: usize) -> Result<Column> {
        let (layout, units) = (self.layout, self.layout.units);
        let (name, unit) = split_header(h);
        let shown_h = shown(h);
        let length = |u: Option<&str>| -> Result<f64> {
            match u {
                None => Ok(units.length.to_si()),
                Some(u) => LengthUnit::parse(u).map(LengthUnit::to_si).ok_or_else(|| {
                    self.err_in(
                        line,
                        h,
                        format!(
                            "column `{shown_h}`: unknown length unit `{}` (expected m, cm, mm or in)",
                            shown(u)
                        ),
                    )
                }),
            }
        };
        let angle = |u: &str, expected: &str| {
            AngleUnit::parse(u)
                .map(AngleUnit::to_si)
                .ok_or_else(|| self.err_in(line, h, format!("column `{shown_h}`: {expected}, got `{}`", shown(u))))
        };
        if let Some(c) = layout.tree.coordinate_names().iter().position(|n| n == name) {
            let scale = match unit {
                _ if layout.tree.coordinate_is_prismatic()[c] => length(unit)?,
                None => units.angle.to_si(),
                Some(u) => angle(
                    u,
                    &format!("joint `{name}` is revolute; expected an angle unit (rad or deg)"),
                )?,
            };
            return Ok(Column::Joint { coord: c, scale });
        }
        // Poses (a compensation's start) carry the sensors' readings too: the tilt they stand at.
        if let Some((k, sensor, cell)) = (layout.sensors.iter().enumerate())
            .find_map(|(k, g)| g.columns.iter().position(|c| c == name).map(|cell| (k, g, cell)))
        {
            let scale = sensor
                .kind
                .column_scale(unit, units.angle)
                .map_err(|m| self.err_in(line, h, format!("column `{shown_h}` of sensor `{}`: {m}", sensor.name)))?;
            return Ok(Column::Sensor(k, cell, scale));
        }
        if !self.with_positions {
            return Ok(Column::Ignored);
        }
        if let Some((axis, slot)) = numbered_position(name) {
            if slot >= layout.points.len() {
                let measured: Vec<&str> = (layout.points.iter())
                    .map(|&p| layout.tree.points()[p].name.as_str())
                    .collect();
                return Err(self.err_in(
                    line,
                    h,
                    format!(
                        "column `{shown_h}`: the robot measures {} point(s) ({}); numbered columns x1, x2, ... are the robot file's `[measurement] markers` in order",
                        measured.len(),
                        measured.join(", ")
                    ),
                ));
            }
            return Ok(Column::Position {
                slot: Some(slot),
                axis,
                scale: length(unit)?,
            });
        }
        if let Some((spelling, cell)) = Spelling::of(name) {
            let scale = match (spelling, unit) {
                (Spelling::Quaternion, None) => 1.0,
                (Spelling::Quaternion, Some(u)) => {
                    return Err(self.err_in(
                        line,
                        h,
                        format!("column `{shown_h}`: a quaternion has no unit, got `{}`", shown(u)),
                    ));
                }
                (_, None) => units.angle.to_si(),
                (_, Some(u)) => angle(u, "expected an angle unit (rad or deg)")?,
            };
            return Ok(Column::Orientation(spelling, cell, scale));
        }
        self.named_column(h, line, length)
    }

    /// What a header cell of a fixed name holds (`point`, `station`, `payload`, ...); anything
    /// else is ignored.
    fn named_column(&self, h: &str, line: usize, length: impl Fn(Option<&str>) -> Result<f64>) -> Result<Column> {
        let (name, unit) = split_header(h);
        let shown_h = shown(h);
        let wrong_unit = |expected: &str, u: &str| {
            self.err_in(
                line,
                h,
                format!("column `{shown_h}`: expected {expected}, got `{}`", shown(u)),
            )
        };
        Ok(match name {
            "point" => Column::Point,
            "kind" => Column::Kind,
            g if self.layout.group_column().is_some_and(|(c, _)| c == g) => Column::Group {
                plane: self.layout.planes,
            },
            // Fixed-point or plane-contact rows among measured positions (mixed data).
            "fixed_point" if !self.layout.planes => Column::Group { plane: false },
            "plane" if self.layout.group_column().is_none() => Column::Group { plane: true },
            g @ ("fixed_point" | "plane") => {
                let what = if g == "plane" { "plane contacts" } else { "fixed points" };
                return Err(self.err_in(
                    line,
                    g,
                    format!(
                        "column `{g}`: the robot file does not measure {what}; a file of {what} needs `kind = \
                         \"{g}\"` in the robot file's [measurement]"
                    ),
                ));
            }
            "station" => Column::Station,
            "x" | "y" | "z" => Column::Position {
                slot: None,
                axis: (name.as_bytes()[0] - b'x') as usize,
                scale: length(unit)?,
            },
            "sx" | "sy" | "sz" if self.layout.group_column().is_none() => Column::PositionStd {
                axis: (name.as_bytes()[1] - b'x') as usize,
                scale: length(unit)?,
            },
            "payload" => Column::Payload(match unit {
                None | Some("kg") => 1.0,
                Some("g") => 1e-3,
                Some(u) => return Err(wrong_unit("a mass unit (kg or g)", u)),
            }),
            "temperature" => Column::Temperature(match unit {
                None | Some("C") | Some("degC") => 0.0,
                Some("K") => -273.15,
                Some(u) => return Err(wrong_unit("C or K", u)),
            }),
            n if n.starts_with("tau_") => match self.layout.tree.coordinate_names().iter().position(|j| j == &n[4..]) {
                Some(c) => Column::Torque(c),
                None => {
                    return Err(self.err_in(
                        line,
                        h,
                        format!("column `{shown_h}`: `{}` is not a joint", shown(&n[4..])),
                    ));
                }
            },
            _ => Column::Ignored,
        })
    }

    /// Every joint that moves the measured points has its column, unless the layout holds it.
    fn check_joint_columns(&self, header: &Header) -> Result<()> {
        let tree = self.layout.tree;
        let missing: Vec<String> = (tree.coordinate_names().iter().enumerate())
            .filter(|&(c, _)| {
                self.layout.hold[c].is_none()
                    && !header.has(|k| matches!(k, Column::Joint { coord, .. } if *coord == c))
            })
            .map(|(c, n)| format!("{n}[{}]", if tree.coordinate_is_prismatic()[c] { "mm" } else { "deg" }))
            .collect();
        if missing.is_empty() {
            return Ok(());
        }
        Err(self.err(
            Some(header.line),
            format!(
                "missing column(s) for {} joint(s) that move the measured points: {}",
                missing.len(),
                missing.join(", ")
            ),
        ))
    }

    /// The position columns' slots — plain `x, y, z`, or numbered triples, one per measured
    /// point — checked against what the robot measures.
    fn position_slots(&self, header: &Header) -> Result<Vec<Option<usize>>> {
        let mut slots: Vec<Option<usize>> = (header.columns.iter())
            .filter_map(|c| match c {
                Column::Position { slot, .. } => Some(*slot),
                _ => None,
            })
            .collect();
        slots.sort();
        slots.dedup();
        let err = |message: String| Err(self.err(Some(header.line), message));
        if !self.with_positions {
            return Ok(slots);
        }
        if let Some((column, what)) = self.layout.group_column() {
            if !header.has(|k| matches!(k, Column::Group { .. })) {
                return Err(self.err_in(
                    header.line,
                    column,
                    format!(
                        "missing column `{column}` (the name of the {what} each row's marker was measured at); the robot \
                         file measures {what}s"
                    ),
                ));
            }
            if !slots.is_empty() || header.has(|k| matches!(k, Column::Orientation(..))) {
                return err(format!(
                    "a {what} file gives no measured position or orientation (its {what}s are identified); remove \
                     the x, y, z or orientation columns, or set the robot file's [measurement] kind to `point`"
                ));
            }
            return Ok(slots);
        }
        if slots.is_empty() && !header.has(|k| matches!(k, Column::Group { .. })) {
            return err(
                "missing columns `x`, `y`, `z` (measured position, e.g. `x[mm]`; or `x1, y1, z1`, ... for several points)".into(),
            );
        }
        if slots.contains(&None) && slots.len() > 1 {
            return err("plain `x, y, z` and numbered `x1, y1, z1` columns cannot be mixed".into());
        }
        if slots.iter().any(Option::is_some) && header.has(|k| matches!(k, Column::Point)) {
            return err("a `point` column goes with plain `x, y, z`; numbered columns name their point already".into());
        }
        for slot in &slots {
            let suffix = slot.map(|s| (s + 1).to_string()).unwrap_or_default();
            for (axis, a) in ["x", "y", "z"].iter().enumerate() {
                if !header.has(|k| matches!(k, Column::Position { slot: s, axis: x, .. } if s == slot && *x == axis)) {
                    return Err(self.err_in(
                        header.line,
                        &format!("{a}{suffix}"),
                        format!("missing column `{a}{suffix}` (measured position, e.g. `{a}{suffix}[mm]`)"),
                    ));
                }
            }
        }
        Ok(slots)
    }

    /// How the orientation is spelt: one spelling, all its cells, with one measured point.
    fn orientation_spelling(&self, header: &Header) -> Result<Option<Spelling>> {
        let mut spellings: Vec<Spelling> = (header.columns.iter())
            .filter_map(|c| match c {
                Column::Orientation(s, ..) => Some(*s),
                _ => None,
            })
            .collect();
        let n_cells = spellings.len();
        spellings.dedup();
        let err = |message: String| Err(self.err(Some(header.line), message));
        let spelling = match spellings.as_slice() {
            [] => None,
            [s] if n_cells == s.cells().len() => Some(*s),
            [s] => {
                return err(format!(
                    "an orientation needs all its columns: {}",
                    s.cells().join(", ")
                ));
            }
            _ => {
                return err(
                    "the orientation is given in several spellings; keep one of qw, qx, qy, qz (quaternion), rx, ry, \
                     rz (rotation vector), roll, pitch, yaw or Euler angles by their order (intrinsic_xyz_1, _2, _3; \
                     extrinsic_zyx_1, ...)"
                        .into(),
                );
            }
        };
        if spelling.is_some() && header.slots.len() > 1 {
            return err("an orientation goes with one measured point, not several".into());
        }
        Ok(spelling)
    }

    /// Whether the table gives its positions' standard deviations: all of `sx, sy, sz` or
    /// none, beside plain `x, y, z`.
    fn position_std_columns(&self, header: &Header) -> Result<bool> {
        let given: Vec<usize> = (header.columns.iter())
            .filter_map(|c| match c {
                Column::PositionStd { axis, .. } => Some(*axis),
                _ => None,
            })
            .collect();
        let err = |message: String| Err(self.err(Some(header.line), message));
        match given.len() {
            0 => Ok(false),
            3 if header.slots.iter().any(Option::is_some) => {
                err("`sx, sy, sz` go with plain `x, y, z`, one measured point per row, not numbered columns".into())
            }
            3 => Ok(true),
            _ => err("the positions' standard deviations need all three columns: sx, sy, sz (e.g. `sx[mm]`)".into()),
        }
    }

    /// The sensors the table gives readings of: each with all its columns, or none of them.
    fn sensor_columns(&self, header: &Header) -> Result<Vec<usize>> {
        let mut given = Vec::new();
        for (k, g) in self.layout.sensors.iter().enumerate() {
            let has = |cell: usize| header.has(|c| matches!(c, Column::Sensor(s, i, _) if *s == k && *i == cell));
            let missing: Vec<&str> = (g.columns.iter().enumerate())
                .filter(|&(cell, _)| !has(cell))
                .map(|(_, c)| c.as_str())
                .collect();
            if missing.is_empty() {
                given.push(k);
            } else if missing.len() < g.columns.len() {
                return Err(self.err(
                    Some(header.line),
                    format!(
                        "sensor `{}` needs all its columns ({}); missing {}",
                        g.name,
                        g.columns.join(", "),
                        listed(&missing)
                    ),
                ));
            }
        }
        Ok(given)
    }

    /// What the header alone tells the user: columns ignored, readings missing.
    fn header_warnings(&self, header: &Header, set: &mut MeasurementSet) {
        let path = self.path.display();
        // A pose robot's file without orientation is a file of positions (another session's, a
        // tracker without a 6-DoF probe): its rows are point measurements, and the user is told.
        if header.spelling.is_none() && self.layout.orientation && self.with_positions && !header.slots.is_empty() {
            set.warnings.push(format!(
                "{path}: the robot file measures poses but this file gives no orientation (qw, qx, qy, qz; rx, ry, \
                 rz; or roll, pitch, yaw): its rows are used as positions only"
            ));
        }
        let gravity = gravity_sensor_index(&self.layout.sensors);
        let missing = (self.layout.sensors.iter().enumerate())
            .filter(|(k, _)| self.with_positions && !header.sensors.contains(k));
        for (k, g) in missing {
            set.warnings.push(format!(
                "{path}: no columns of sensor `{}` ({}): its rows are evaluated without its reading{}",
                g.name,
                g.columns.join(", "),
                if gravity == Some(k) {
                    ", with the robot file's gravity"
                } else {
                    ""
                }
            ));
        }
        if !header.ignored.is_empty() {
            let ignored: Vec<&str> = header.ignored.iter().map(String::as_str).collect();
            set.warnings.push(format!(
                "{path}: column(s) {} ignored (not a joint of the robot or a measurement column)",
                listed(&ignored)
            ));
        }
    }

    /// Reads every row into `set`, then warns of joints outside their limits and of rows that
    /// measure nothing.
    fn read_rows(&self, reader: &mut csv::Reader<&[u8]>, header: &Header, set: &mut MeasurementSet) -> Result<()> {
        let tree = self.layout.tree;
        let mut outside: Outside = vec![(0, 0, 0.0); tree.nq()];
        let mut rows_without_point = 0;
        let mut lines = LineCounter::new(self.text);
        for (row, record) in reader.records().enumerate() {
            let record =
                record.map_err(|e| self.err(Some(lines.line_at(e.position())), format!("cannot read the row: {e}")))?;
            let line = lines.line_at(record.position());
            if record.len() != header.columns.len() {
                return Err(self.err(
                    Some(line),
                    format!(
                        "expected {} values (one per column), got {}",
                        header.columns.len(),
                        record.len()
                    ),
                ));
            }
            let mut cells = self.read_cells(&record, line, header, &mut set.stations)?;
            self.finish_row(&mut cells, line, header)?;
            note_limits(tree, &cells.sample.q, line, &mut outside);
            if !self.push_samples(cells, row, line, header, set)? {
                rows_without_point += 1;
            }
        }
        self.limit_warnings(&outside, set);
        if rows_without_point > 0 {
            set.warnings.push(format!(
                "{}: {rows_without_point} row(s) measure no point (every position cell empty) and were skipped",
                self.path.display()
            ));
        }
        Ok(())
    }

    /// The cells of one row: text cells (names, groups, stations) and numbers, in SI.
    fn read_cells<'c>(
        &self,
        record: &'c csv::StringRecord,
        line: usize,
        header: &Header,
        stations: &mut Vec<String>,
    ) -> Result<Row<'c>> {
        let layout = self.layout;
        let mut row = Row {
            sample: Sample {
                q: layout.hold.iter().map(|h| h.unwrap_or(0.0)).collect(),
                point: layout.points[0],
                position: Vector3::zeros(),
                orientation: None,
                payload: None,
                temperature: None,
                torque: header.has_torque.then(|| vec![0.0; layout.tree.nq()]),
                fixed_point: None,
                plane: None,
                sensors: SensorReadings::default(),
                station: 0,
                position_std: None,
            },
            fixed_row: header.mixed_groups.iter().any(|&k| !record[k].is_empty()),
            kind_cell: None,
            angles: [0.0; 4],
            sensor_cells: [Vector4::zeros(); MAX_SENSORS],
            positions: vec![(Vector3::zeros(), 0); header.slots.len()],
            position_std: (Vector3::zeros(), 0),
        };
        for (field, (col, head)) in record.iter().zip(header.columns.iter().zip(header.shown.iter())) {
            let cell = Cell { field, col, head, line };
            if self.text_cell(&mut row, &cell, header, stations)? {
                continue;
            }
            let v: f64 = field.parse().map_err(|_| {
                self.err_in(
                    line,
                    head,
                    format!("column `{head}`: `{}` is not a number", shown(field)),
                )
            })?;
            if !v.is_finite() {
                return Err(self.err_in(
                    line,
                    head,
                    format!("column `{head}`: {} is not a finite number", shown(field)),
                ));
            }
            if let Some((si, bound, words)) = col.si_and_bound(v)
                && si.abs() > bound
            {
                return Err(self.err_in(
                    line,
                    head,
                    format!(
                        "column `{head}`: {} is not a measurement; expected a magnitude of at most {words}",
                        shown(field)
                    ),
                ));
            }
            self.number_cell(&mut row, v, &cell, header)?;
        }
        Ok(row)
    }

    /// Reads a cell that is not a number (a point's, group's, station's or kind's name, an
    /// ignored cell, an empty position cell); whether it was one.
    fn text_cell<'c>(
        &self,
        row: &mut Row<'c>,
        cell: &Cell<'c, '_>,
        header: &Header,
        stations: &mut Vec<String>,
    ) -> Result<bool> {
        let Cell { field, col, head, line } = *cell;
        let err = |column: &str, message: String| Err(self.err_in(line, column, message));
        match col {
            Column::Ignored => {}
            Column::Point => {
                row.sample.point = self.layout.tree.point_index(field).ok_or_else(|| {
                    self.err_in(
                        line,
                        "point",
                        format!("column `point`: `{}` is not a point of the robot", shown(field)),
                    )
                })?;
            }
            Column::Kind => row.kind_cell = Some(field),
            Column::Group { .. } if field.is_empty() && !header.mixed_groups.is_empty() && !header.slots.is_empty() => {
            }
            Column::Group { plane } => {
                let (column, what) = if *plane {
                    ("plane", "plane")
                } else {
                    ("fixed_point", "fixed point")
                };
                if field.is_empty() {
                    return err(
                        column,
                        format!("column `{column}` is empty; every row names the {what} it was measured at"),
                    );
                }
                if row.sample.fixed_point.is_some() || row.sample.plane.is_some() {
                    return err(
                        column,
                        "the row names both a fixed point and a plane; a contact is made at one of them".into(),
                    );
                }
                check_name(field).map_err(|m| self.err_in(line, column, format!("column `{column}`: {m}")))?;
                if *plane {
                    row.sample.plane = Some(field.to_string());
                } else {
                    row.sample.fixed_point = Some(field.to_string());
                }
            }
            Column::Station if field.is_empty() => {
                return err(
                    "station",
                    "column `station` is empty in this row; every row needs its station's name".into(),
                );
            }
            Column::Station => {
                check_name(field).map_err(|m| self.err_in(line, "station", format!("column `station`: {m}")))?;
                row.sample.station = match stations.iter().position(|n| n == field) {
                    Some(k) => k,
                    None => {
                        stations.push(field.to_string());
                        stations.len() - 1
                    }
                };
            }
            Column::Position { .. } | Column::Orientation(..) | Column::PositionStd { .. } if row.fixed_row => {
                if !field.is_empty() {
                    let (column, what) = header.mixed_kind();
                    return err(
                        head,
                        format!(
                            "column `{head}`: a row naming a {what} gives no measured position or orientation; \
                             empty this cell or the row's `{column}`"
                        ),
                    );
                }
            }
            Column::Position { slot: None, .. } if field.is_empty() && !header.mixed_groups.is_empty() => {
                let (column, what) = header.mixed_kind();
                return err(
                    head,
                    format!(
                        "column `{head}` is empty; a row gives its measured position or names the {what} it was \
                         measured at in `{column}`"
                    ),
                );
            }
            Column::Position {
                slot: slot @ Some(_), ..
            } if field.is_empty() => {
                let k = header.slots.iter().position(|s| s == slot).unwrap_or(0);
                row.positions[k].1 += 1;
            }
            Column::PositionStd { .. } if field.is_empty() => row.position_std.1 += 1,
            Column::Sensor(..) if field.trim().is_empty() => {
                return err(
                    head,
                    format!("column `{head}`: empty; the sensor's reading is needed on every row"),
                );
            }
            _ => return Ok(false),
        }
        Ok(true)
    }

    /// Stores a cell's number `v` (as written; `field` is its text) where its column says.
    fn number_cell(&self, row: &mut Row<'_>, v: f64, cell: &Cell<'_, '_>, header: &Header) -> Result<()> {
        let Cell { field, col, head, line } = *cell;
        let s = &mut row.sample;
        match *col {
            Column::Joint { coord, scale } => s.q[coord] = v * scale,
            Column::Position { slot, axis, scale } => {
                let k = header.slots.iter().position(|s| *s == slot).unwrap_or(0);
                row.positions[k].0[axis] = v * scale;
            }
            Column::Orientation(_, k, scale) => row.angles[k] = v * scale,
            Column::PositionStd { .. } if v <= 0.0 => {
                return Err(self.err_in(
                    line,
                    head,
                    format!("column `{head}`: a standard deviation is above zero, got {field}"),
                ));
            }
            Column::PositionStd { axis, scale } => row.position_std.0[axis] = v * scale,
            Column::Payload(_) if v < 0.0 => {
                return Err(self.err_in(
                    line,
                    head,
                    format!("column `{head}`: expected a mass of zero or more, got {}", shown(field)),
                ));
            }
            Column::Payload(scale) => s.payload = Some(v * scale),
            Column::Temperature(offset) => s.temperature = Some(v + offset),
            Column::Torque(c) => {
                if let Some(t) = s.torque.as_mut() {
                    t[c] = v;
                }
            }
            Column::Sensor(k, cell, scale) => row.sensor_cells[k][cell] = v * scale,
            Column::Point | Column::Kind | Column::Group { .. } | Column::Station | Column::Ignored => {}
        }
        Ok(())
    }

    /// What a row's cells give together: its orientation, its kind checked, its gravity.
    fn finish_row(&self, row: &mut Row<'_>, line: usize, header: &Header) -> Result<()> {
        if let Some(spelling) = header.spelling.filter(|_| !row.fixed_row) {
            row.sample.orientation = Some(spelling.rotation(row.angles).map_err(|m| self.err(Some(line), m))?);
        }
        if let Some(kind) = row.kind_cell {
            check_kind_cell(kind, &row.sample).map_err(|m| self.err_in(line, "kind", m))?;
        }
        if header.has_position_std && !row.fixed_row {
            row.sample.position_std = match row.position_std {
                (std, 0) => Some(std),
                (_, 3) => None,
                _ => {
                    return Err(self.err(
                        Some(line),
                        "some of sx, sy, sz are empty; give all three (the row's standard deviations) or none (the \
                         row is weighed by the noise the others share)"
                            .into(),
                    ));
                }
            };
        }
        for &k in &header.sensors {
            let g = &self.layout.sensors[k];
            let direction = g.kind.gravity_direction(&row.sensor_cells[k]).map_err(|m| {
                self.err(
                    Some(line),
                    format!("sensor `{}` (columns {}): {m}", g.name, g.columns.join(", ")),
                )
            })?;
            let reading = GravityReading {
                body: g.body,
                direction,
            };
            row.sample.sensors.set(k, Some(reading));
        }
        Ok(())
    }

    /// Adds the row's samples to `set`, one per measured point seen; whether it measured any.
    fn push_samples(
        &self,
        row: Row<'_>,
        index: usize,
        line: usize,
        header: &Header,
        set: &mut MeasurementSet,
    ) -> Result<bool> {
        let s = row.sample;
        if !self.with_positions || s.fixed_point.is_some() || s.plane.is_some() {
            set.samples.push(s);
            set.rows.push(index);
            return Ok(true);
        }
        let before = set.samples.len();
        for (slot, &(position, empty)) in header.slots.iter().zip(&row.positions) {
            match (slot, empty) {
                (Some(_), 3) => continue, // the point was not seen in this row
                (Some(i), 1 | 2) => {
                    return Err(self.err(
                        Some(line),
                        format!(
                            "point {}: some of x{0}, y{0}, z{0} are empty; give all three or none",
                            i + 1
                        ),
                    ));
                }
                _ => {}
            }
            let mut sample = s.clone();
            if let Some(i) = slot {
                sample.point = self.layout.points[*i];
            }
            sample.position = position;
            set.samples.push(sample);
            set.rows.push(index);
        }
        Ok(set.samples.len() > before)
    }

    /// One warning per joint outside its limits in some rows.
    fn limit_warnings(&self, outside: &Outside, set: &mut MeasurementSet) {
        let tree = self.layout.tree;
        for (c, (rows, first, worst)) in outside.iter().enumerate().filter(|(_, o)| o.0 > 0) {
            let (value, unit) = if tree.coordinate_is_prismatic()[c] {
                (worst * 1e3, "mm")
            } else {
                (worst.to_degrees(), "deg")
            };
            set.warnings.push(format!(
                "{}:{first}: joint `{}` is outside its limits in {rows} row(s) (first on this line; at most {value:.3} {unit} beyond)",
                self.path.display(),
                tree.coordinate_names()[c]
            ));
        }
    }
}

/// Counts a row's joint values outside their limits into `outside`.
fn note_limits(tree: &crate::model::tree::KinematicTree, q: &[f64], line: usize, outside: &mut Outside) {
    for (c, lim) in tree.coordinate_limits().iter().enumerate() {
        if let Some(l) = lim
            && (q[c] < l.lower - 1e-9 || q[c] > l.upper + 1e-9)
        {
            let o = &mut outside[c];
            if o.0 == 0 {
                o.1 = line;
            }
            o.0 += 1;
            o.2 = o.2.max((l.lower - q[c]).max(q[c] - l.upper));
        }
    }
}
