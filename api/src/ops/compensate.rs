//! `compensate`: joint commands that put the tool on targets, through a model and its
//! predictor, and the targets CSV they are read from.

use std::path::Path;

use armcomp_core::algorithms::compensate::{CompensationMode, CompensationParams, Compensator, default_start};
use armcomp_core::algorithms::ik::{IkError, IkTarget};
use armcomp_core::data::measurement::{
    CsvLayout, csv_text, joint_header, joint_row, parse_poses_with_sensors, split_header,
};
use armcomp_core::kinematics::sensor::{GravityReading, SensorReadings};
use armcomp_core::model::tree::Coordinate;
use armcomp_core::model::units::LengthUnit;
use armcomp_core::support::cancel::Cancel;
use armcomp_core::support::io::InputLimits;
use armcomp_core::support::text::shown;
use armcomp_core::{Robot, Units};
use nalgebra::{Isometry3, Point3, Quaternion, UnitQuaternion, Vector3};

use crate::error::{Error, LockReason, Result};

/// The frame targets are given in and corrected targets are returned in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Frame {
    /// The tracker's, as in measurement files; for a model with several stations, ambiguous
    /// (refused: name the station).
    Measurement,
    /// The measurement frame of the model's station `k` (see [`station_index`]).
    Station(usize),
    /// The robot base.
    Base,
}

/// The index of `robot`'s station called `name`, or an error that lists them.
pub fn station_index(robot: &Robot, name: &str) -> Result<usize> {
    let names: Vec<&str> = robot.stations().iter().map(|s| s.name.as_str()).collect();
    names
        .iter()
        .position(|n| *n == name)
        .ok_or_else(|| armcomp_core::Error::InvalidArgument {
            what: "station".into(),
            reason: if names.is_empty() {
                format!(
                    "the model has no stations (one measurement frame), so `{}` is none of them",
                    shown(name)
                )
            } else {
                format!(
                    "`{}` is not a station of the model; its stations are {}",
                    shown(name),
                    armcomp_core::data::measurement::listed(&names)
                )
            },
        })
        .map_err(Error::from)
}

/// `T_meas_base` of the targets' frame `frame` (`None` for the base frame), or why it is
/// ambiguous: targets "in the measurement frame" of a model with several stations could be in
/// any of them.
fn measurement_frame(robot: &Robot, frame: Frame) -> Result<Option<Isometry3<f64>>> {
    match frame {
        Frame::Base => Ok(None),
        Frame::Station(k) => Ok(Some(robot.station_frame(k))),
        Frame::Measurement if robot.stations().len() > 1 => {
            let names: Vec<&str> = robot.stations().iter().map(|s| s.name.as_str()).collect();
            Err(armcomp_core::Error::InvalidArgument {
                what: "targets' frame".into(),
                reason: format!(
                    "the model has {} stations ({}), each its own measurement frame: name the one the targets are \
                     given in (`--station NAME`), or give them in the base frame",
                    names.len(),
                    armcomp_core::data::measurement::listed(&names)
                ),
            }
            .into())
        }
        Frame::Measurement => Ok(Some(robot.t_meas_base())),
    }
}

/// One target: a position (m) and optionally the tool orientation to keep.
#[derive(Debug, Clone, PartialEq)]
pub struct Target {
    /// Position (m).
    pub position: Vector3<f64>,
    /// Tool orientation, same frame as the position.
    pub orientation: Option<UnitQuaternion<f64>>,
}

/// Joint commands for a batch of targets.
#[derive(Debug, Clone)]
pub struct CompensationRun {
    /// Per target, the joint command (SI, one value per independent joint).
    pub q: Vec<Vec<f64>>,
    /// Per target, where the model without its predictor puts the tool at the command: the
    /// target to hand a controller that knows only the rigid model (m, in the targets' frame).
    pub corrected: Vec<Vector3<f64>>,
    /// Per target, the predictor's standard deviation (m, measurement frame), when it gives one.
    pub std: Vec<Option<Vector3<f64>>>,
    /// Targets (index, miss in m) out of reach (in either mode) or that exact mode's model
    /// with its residual still misses: their commands are the closest found.
    pub unconverged: Vec<(usize, f64)>,
    /// Whether the model's fitted predictor took part.
    pub has_predictor: bool,
    /// Per coordinate, whether it kept its start value (locked, or not moving the tool).
    pub locked: Vec<bool>,
}

/// Where compensation starts and which joints it keeps.
#[derive(Debug, Clone, Default)]
pub struct Joints {
    /// Start configurations (SI, one value per coordinate): one for every target, or one per
    /// target; none for [`default_start`].
    pub starts: Vec<Vec<f64>>,
    /// Coordinates kept at their start value besides those that do not move the tool.
    pub locked: Vec<bool>,
    /// The sensors' readings the robot stands at (its tilt now): one for every target, or one
    /// per target; none when no sensor is read.
    pub sensors: Vec<SensorReadings>,
}

impl Joints {
    /// `starts`, each checked to be a configuration of `robot`, and the `locked` coordinates
    /// ([`locked_by_name`]).
    pub fn new(robot: &Robot, starts: Vec<Vec<f64>>, locked: Vec<bool>) -> Result<Self> {
        for (k, q) in starts.iter().enumerate() {
            robot
                .tree()
                .check_q(q)
                .map_err(|source| Error::StartConfiguration { index: k + 1, source })?;
        }
        Ok(Joints {
            starts,
            locked,
            sensors: Vec::new(),
        })
    }
}

/// One reading of the robot's sensors from `(sensor name, cells)` pairs, the cells in SI as a
/// measurement file's columns hold them (an accelerometer's x, y, z in m/s², or any common
/// scale; an inclinometer's roll and pitch in rad). An unknown sensor, a wrong number of cells
/// or a reading that gives no direction is refused, naming the sensor.
pub fn sensor_readings(robot: &Robot, readings: &[(String, Vec<f64>)]) -> Result<SensorReadings> {
    let bad = |reason: String| {
        Error::Core(armcomp_core::Error::InvalidArgument {
            what: "sensors".into(),
            reason,
        })
    };
    let mut out = SensorReadings::default();
    for (name, cells) in readings {
        let sensors = robot.sensors();
        let Some(k) = sensors.iter().position(|s| &s.name == name) else {
            let names: Vec<&str> = sensors.iter().map(|s| s.name.as_str()).collect();
            return Err(bad(format!(
                "`{}` is not a sensor of `{}`; its sensors are: {}",
                shown(name),
                robot.name(),
                if names.is_empty() {
                    "none".into()
                } else {
                    names.join(", ")
                }
            )));
        };
        let s = &sensors[k];
        if cells.len() != s.kind.n_columns() || cells.iter().any(|v| !v.is_finite()) {
            return Err(bad(format!(
                "sensor `{name}`: an {} reads {} finite numbers ({}), got {:?}",
                s.kind.name(),
                s.kind.n_columns(),
                s.kind.cells(),
                cells
            )));
        }
        let mut v = nalgebra::Vector4::zeros();
        v.as_mut_slice()[..cells.len()].copy_from_slice(cells);
        let direction = s
            .kind
            .gravity_direction(&v)
            .map_err(|m| bad(format!("sensor `{name}`: {m}")))?;
        out.set(
            k,
            Some(GravityReading {
                body: s.body,
                direction,
            }),
        );
    }
    Ok(out)
}

/// Per coordinate, whether `names` (coordinate names) lock it; a mimic joint is refused with
/// the joint that drives it, an unknown name with the robot's joints.
pub fn locked_by_name(robot: &Robot, names: &[String]) -> Result<Vec<bool>> {
    let tree = robot.tree();
    let coordinates = tree.coordinate_names();
    let mut locked = vec![false; tree.nq()];
    for name in names {
        if let Some(c) = coordinates.iter().position(|n| n == name) {
            locked[c] = true;
            continue;
        }
        let reason = match tree.joint_index(name).map(|j| &tree.joints()[j].coordinate) {
            Some(Coordinate::Mimic(c)) => LockReason::Mimic {
                follows: c.terms.iter().map(|(i, _)| coordinates[*i].clone()).collect(),
            },
            Some(_) => LockReason::Fixed,
            None => LockReason::Unknown {
                robot: robot.name().to_string(),
                joints: coordinates.to_vec(),
            },
        };
        return Err(Error::LockedJoint {
            name: name.clone(),
            reason,
        });
    }
    Ok(locked)
}

/// Start configurations from a CSV of joint columns (the rules of measurement files; a joint
/// without a column starts where [`default_start`] puts it), one row per target or one row
/// for all, with the readings of the robot's sensors whose columns it has (empty when it has
/// none): the tilt the robot stands at. The file is read within the robot's
/// [input limits](Robot::input_limits).
pub fn read_starts(path: &Path, robot: &Robot) -> armcomp_core::Result<(Vec<Vec<f64>>, Vec<SensorReadings>)> {
    let text = armcomp_core::support::io::read_text(path, robot.input_limits())?;
    let layout = CsvLayout {
        hold: default_start(robot).into_iter().map(Some).collect(),
        ..robot.csv_layout()
    };
    let (starts, sensors): (Vec<Vec<f64>>, Vec<SensorReadings>) =
        parse_poses_with_sensors(&text, path, &layout)?.into_iter().unzip();
    let sensors = if sensors.iter().all(SensorReadings::is_empty) {
        Vec::new()
    } else {
        sensors
    };
    // A start file holds joint values and sensor readings only: a column of another name is
    // a misspelt joint, which would leave that joint at its default start without a word.
    let mut reader = csv::ReaderBuilder::new()
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    if let Ok(header) = reader.headers() {
        let joints = robot.tree().coordinate_names();
        let known = |name: &str| {
            joints.iter().any(|j| j == name) || robot.sensors().iter().any(|s| s.columns.iter().any(|c| c == name))
        };
        if let Some(h) = header.iter().find(|h| !known(split_header(h).0)) {
            let line = armcomp_core::data::measurement::line_at(&text, header.position());
            let names: Vec<&str> = joints.iter().map(String::as_str).collect();
            return Err(armcomp_core::Error::input_at(
                path,
                Some(line),
                Some(h),
                format!(
                    "column `{}` is not a joint of `{}`; a start file has a column per joint it sets, of {}, and \
                     the columns of the sensors it gives readings of",
                    shown(h),
                    robot.name(),
                    armcomp_core::data::measurement::listed(&names)
                ),
            ));
        }
    }
    if starts.is_empty() {
        return Err(armcomp_core::Error::input_at(
            path,
            None,
            None,
            "no start configurations".into(),
        ));
    }
    Ok((starts, sensors))
}

/// The solver settings every caller uses.
pub fn options() -> CompensationParams {
    CompensationParams::default()
}

/// Compensates `targets` in order, each from its start in `joints` (else [`default_start`]),
/// changing only the joints that move the tool and are not locked; an error names the target
/// through `describe(index)`. Stops between targets once `cancel` is cancelled.
pub fn run(
    robot: &Robot,
    targets: &[Target],
    joints: &Joints,
    mode: CompensationMode,
    frame: Frame,
    describe: &dyn Fn(usize) -> String,
    cancel: &Cancel,
) -> Result<CompensationRun> {
    let options = options();
    let mut comp = Compensator::for_model(robot, options)?;
    if !joints.locked.is_empty() {
        comp.lock(&joints.locked)?;
    }
    let default = [default_start(robot)];
    let starts = match joints.starts.len() {
        0 => &default[..],
        n if n == 1 || n == targets.len() => &joints.starts[..],
        n => {
            return Err(Error::StartCount {
                starts: n,
                targets: targets.len(),
            });
        }
    };
    let sensors = match joints.sensors.len() {
        n if n <= 1 || n == targets.len() => &joints.sensors[..],
        n => {
            return Err(Error::StartCount {
                starts: n,
                targets: targets.len(),
            });
        }
    };
    let t_meas_base = measurement_frame(robot, frame)?;
    let to_base = t_meas_base.map_or_else(Isometry3::identity, |t| t.inverse());
    let mut run = CompensationRun {
        q: Vec::with_capacity(targets.len()),
        corrected: Vec::with_capacity(targets.len()),
        std: Vec::with_capacity(targets.len()),
        unconverged: Vec::new(),
        has_predictor: comp.has_predictor(),
        locked: comp.locked().to_vec(),
    };
    for (i, t) in targets.iter().enumerate() {
        cancel.check()?;
        if let Some(&readings) = sensors.get(i.min(sensors.len().saturating_sub(1))) {
            comp.set_sensors(readings);
        }
        let c = match comp.compensate_target(&ik_target(t, &to_base), &starts[i.min(starts.len() - 1)], mode) {
            Ok(c) => c,
            // A target out of reach keeps the closest command found, listed with its miss as
            // exact mode's misses are, so that one target does not cost the batch its others.
            Err(IkError::Unreachable {
                closest_q,
                closest_point,
                distance,
                ..
            }) => {
                run.unconverged.push((i, distance));
                run.corrected.push(match t_meas_base {
                    Some(t) => t.transform_point(&Point3::from(closest_point)).coords,
                    None => closest_point,
                });
                run.std.push(comp.residual_std_at(&closest_q));
                run.q.push(closest_q);
                continue;
            }
            Err(source) => {
                return Err(Error::Target {
                    target: describe(i),
                    source: Box::new(source),
                });
            }
        };
        if mode == CompensationMode::Exact && c.mismatch > options.tolerance {
            run.unconverged.push((i, c.mismatch));
        }
        run.corrected.push(match t_meas_base {
            Some(t) => t.transform_point(&Point3::from(c.corrected_target)).coords,
            None => c.corrected_target,
        });
        run.q.push(comp.q().to_vec());
        run.std.push(comp.residual_std());
    }
    Ok(run)
}

/// `target` as the inverse kinematics takes it: moved into the base frame by `to_base` (the
/// identity for targets in the base frame).
pub fn ik_target(target: &Target, to_base: &Isometry3<f64>) -> IkTarget {
    let position = to_base.transform_point(&Point3::from(target.position)).coords;
    match target.orientation {
        Some(r) => IkTarget::Pose(Isometry3::from_parts(position.into(), to_base.rotation * r)),
        None => IkTarget::Position(position),
    }
}

impl CompensationRun {
    /// The output CSV of `armcomp compensate`: joint commands and corrected targets in the
    /// model's units, with the predictor's standard deviations when every target has one.
    pub fn to_csv(&self, robot: &Robot) -> String {
        let units = robot.units();
        let lu = units.length.symbol();
        let mut header = joint_header(robot.tree(), units);
        header.extend(["x_cmd", "y_cmd", "z_cmd"].map(|c| format!("{c}[{lu}]")));
        let with_std = self.std.iter().all(Option::is_some);
        if with_std {
            header.extend(["std_x", "std_y", "std_z"].map(|c| format!("{c}[{lu}]")));
        }
        let rows = self
            .q
            .iter()
            .zip(&self.corrected)
            .zip(&self.std)
            .map(|((q, corrected), std)| {
                let mut row = joint_row(q, robot.tree(), units);
                row.extend(corrected.iter().map(|v| units.len_out(*v).to_string()));
                if let (true, Some(s)) = (with_std, std) {
                    row.extend(s.iter().map(|v| units.len_out(*v).to_string()));
                }
                row
            });
        csv_text(std::iter::once(header).chain(rows))
    }
}

/// The tool orientation `[qw, qx, qy, qz]`: a unit quaternion, with the same tolerance as
/// measurement files (rounded quaternions are renormalised).
pub fn orientation(wxyz: [f64; 4]) -> Result<UnitQuaternion<f64>, String> {
    let q = Quaternion::new(wxyz[0], wxyz[1], wxyz[2], wxyz[3]);
    if (q.norm() - 1.0).abs() > 1e-3 {
        return Err(format!("orientation quaternion has norm {:.6}, expected 1", q.norm()));
    }
    Ok(UnitQuaternion::from_quaternion(q))
}

/// Reads `x, y, z` targets (m) and optional `qw, qx, qy, qz` orientations with their line
/// numbers, erroring with file, line and column; the file is read within `limits`.
pub fn read_targets(path: &Path, units: Units, limits: InputLimits) -> armcomp_core::Result<Vec<(usize, Target)>> {
    let text = armcomp_core::support::io::read_text(path, limits)?;
    // The same reading rules as measurement files: `#` comments, blank lines skipped, cells
    // trimmed, quoted cells allowed.
    let mut reader = csv::ReaderBuilder::new()
        .flexible(true)
        .trim(csv::Trim::All)
        .comment(Some(b'#'))
        .from_reader(text.as_bytes());
    let mut lines = armcomp_core::data::measurement::LineCounter::new(&text);
    let header = reader
        .headers()
        .map_err(|e| armcomp_core::Error::input_at(path, None, None, format!("the header is not readable CSV: {e}")))?
        .clone();
    if header.iter().all(str::is_empty) {
        return Err(armcomp_core::Error::input_at(
            path,
            None,
            None,
            "empty; expected a header `x[mm],y[mm],z[mm]`".into(),
        ));
    }
    let header_line = lines.line_at(header.position());
    let at_header =
        |column: &str, message: String| armcomp_core::Error::input_at(path, Some(header_line), Some(column), message);
    // Columns 0..3 are x, y, z (with their scale to m), 3..7 are qw, qx, qy, qz (scale 1).
    let mut columns: [Option<(usize, f64)>; 7] = [None; 7];
    let mut n_columns = 0;
    for (c, h) in header.iter().enumerate() {
        n_columns += 1;
        let (name, unit) = split_header(h);
        let Some(slot) = ["x", "y", "z", "qw", "qx", "qy", "qz"].iter().position(|n| *n == name) else {
            return Err(at_header(
                h,
                format!(
                    "column {}: unexpected `{}`; expected x, y, z with a length unit, e.g. `x[mm]`, and optionally qw, qx, qy, qz",
                    c + 1,
                    shown(h)
                ),
            ));
        };
        let scale = match (slot, unit) {
            (0..3, None) => units.length.to_si(),
            (0..3, Some(u)) => LengthUnit::parse(u).map(LengthUnit::to_si).ok_or_else(|| {
                at_header(
                    h,
                    format!(
                        "column {}: unknown length unit `{}` (expected m, cm, mm or in)",
                        c + 1,
                        shown(u)
                    ),
                )
            })?,
            (_, None) => 1.0,
            (_, Some(u)) => {
                return Err(at_header(
                    h,
                    format!(
                        "column {}: a quaternion component has no unit, found `[{}]`",
                        c + 1,
                        shown(u)
                    ),
                ));
            }
        };
        if columns[slot].replace((c, scale)).is_some() {
            return Err(at_header(name, format!("column `{}` appears twice", shown(name))));
        }
    }
    if columns[..3].iter().any(Option::is_none) {
        return Err(armcomp_core::Error::input_at(
            path,
            Some(header_line),
            None,
            "expected the columns x, y and z".into(),
        ));
    }
    let with_orientation = match columns[3..].iter().filter(|c| c.is_some()).count() {
        0 => false,
        4 => true,
        _ => {
            return Err(armcomp_core::Error::input_at(
                path,
                Some(header_line),
                None,
                "an orientation needs all four columns qw, qx, qy, qz".into(),
            ));
        }
    };
    let mut targets = Vec::new();
    for record in reader.records() {
        let row = record
            .map_err(|e| armcomp_core::Error::input_at(path, None, None, format!("a row is not readable CSV: {e}")))?;
        let line = lines.line_at(row.position());
        let cells: Vec<&str> = row.iter().collect();
        if cells.len() != n_columns {
            return Err(armcomp_core::Error::input_at(
                path,
                Some(line),
                None,
                format!("{} values, the header has {n_columns}", cells.len()),
            ));
        }
        let mut values = [0.0; 7];
        for (value, &(c, scale)) in values
            .iter_mut()
            .zip(&columns)
            .filter_map(|(v, c)| c.as_ref().map(|c| (v, c)))
        {
            let v: f64 = cells[c].parse().ok().filter(|v: &f64| v.is_finite()).ok_or_else(|| {
                armcomp_core::Error::input_at(
                    path,
                    Some(line),
                    Some(&header[c]),
                    format!("column {}: `{}` is not a finite number", c + 1, shown(cells[c])),
                )
            })?;
            *value = v * scale;
        }
        let orientation = if with_orientation {
            let q = orientation([values[3], values[4], values[5], values[6]])
                .map_err(|m| armcomp_core::Error::input_at(path, Some(line), None, m))?;
            Some(q)
        } else {
            None
        };
        targets.push((
            line,
            Target {
                position: Vector3::new(values[0], values[1], values[2]),
                orientation,
            },
        ));
    }
    if targets.is_empty() {
        return Err(armcomp_core::Error::input_at(path, None, None, "no targets".into()));
    }
    Ok(targets)
}
