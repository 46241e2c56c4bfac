//! `armcomp.Measurements`: measured positions with their joint values, from a CSV or arrays.
//!
//! A CSV names joints and points, so it is read against a robot: at once when one is given,
//! else when the data are first used with one (calibration, evaluation). Arrays and the
//! results of `simulate` carry joint and point names and are matched to each robot by name.

use std::path::PathBuf;
use std::sync::Arc;

use armcomp_core::Robot;
use armcomp_core::data::measurement::{MeasurementSet, RowSelection, Sample, parse_csv, write_csv_with_sensors};
use armcomp_core::support::io::{check_output, write_atomic};
use nalgebra::Vector3;
use numpy::{AllowTypeChange, PyArray2, PyArrayLike2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyType;

use crate::errors::{IntoPy, file_error, input_error, warn_all};
use crate::robot::PyRobot;

/// Names given with arrays, when they were.
type Names<'a> = Option<&'a [String]>;

/// Where the data come from.
#[derive(Debug, Clone)]
enum Source {
    /// A CSV's text, read against a robot when used.
    Csv {
        path: PathBuf,
        text: Arc<String>,
        rows: Option<RowSelection>,
    },
    /// Samples whose joint values follow `joint_names` (`None`: the robot's own order) and
    /// whose point indices refer to `point_names` (`None`: each sample measures the robot's
    /// first marker).
    Samples {
        set: MeasurementSet,
        joint_names: Option<Vec<String>>,
        point_names: Option<Vec<String>>,
    },
}

/// Measured positions (m, measurement frame) with the joint values (SI) they were measured at.
#[pyclass(name = "Measurements", module = "armcomp", frozen)]
pub struct PyMeasurements {
    source: Source,
    /// The CSV file the samples were read from, which `save` never replaces.
    pub read_from: Option<PathBuf>,
    /// The CSV's text with the name messages give it, when the samples come from one: its
    /// other columns (a session, a time) give the folds' groups.
    table: Option<(PathBuf, Arc<String>)>,
}

impl PyMeasurements {
    /// Samples resolved against `robot`: their own, read with it.
    pub fn from_set(robot: &Robot, set: MeasurementSet) -> Self {
        let tree = robot.tree();
        PyMeasurements {
            source: Source::Samples {
                set,
                joint_names: Some(tree.coordinate_names().to_vec()),
                point_names: Some(tree.points().iter().map(|p| p.name.clone()).collect()),
            },
            read_from: None,
            table: None,
        }
    }

    /// Measurements from CSV `text` (called `path` in messages), read against `robot` now when
    /// given; `rows` as `read` takes them.
    fn csv(
        path: PathBuf,
        text: String,
        robot: Option<PyRef<'_, PyRobot>>,
        rows: Option<&Bound<'_, PyAny>>,
        read_from: Option<PathBuf>,
    ) -> PyResult<Self> {
        let rows = rows.map(|r| row_selection(r, "rows")).transpose()?;
        let text = Arc::new(text);
        let data = PyMeasurements {
            source: Source::Csv {
                path: path.clone(),
                text: text.clone(),
                rows,
            },
            read_from: read_from.clone(),
            table: Some((path, text)),
        };
        match robot {
            Some(r) => Ok(PyMeasurements::from_set(&r.robot, data.resolve(&r.robot)?).like(&data)),
            None => Ok(data),
        }
    }

    /// The same samples, from where `other`'s came.
    fn like(self, other: &PyMeasurements) -> Self {
        PyMeasurements {
            read_from: other.read_from.clone(),
            table: other.table.clone(),
            ..self
        }
    }

    /// The samples for `robot`: the CSV read against it, or joint values and points matched
    /// by name (joints the data lack hold the robot file's `hold` values).
    pub fn resolve(&self, robot: &Robot) -> PyResult<MeasurementSet> {
        let set = match &self.source {
            Source::Csv { path, text, rows } => {
                let mut set = parse_csv(text, path, &robot.csv_layout()).py()?;
                if let Some(rows) = rows {
                    set = set.select_rows(rows);
                }
                Python::attach(|py| warn_all(py, &set.warnings))?;
                set
            }
            Source::Samples {
                set,
                joint_names,
                point_names,
            } => map_by_name(robot, set, joint_names.as_deref(), point_names.as_deref())?,
        };
        if set.samples.is_empty() {
            return Err(input_error("no measurements", None, None, None));
        }
        Ok(set)
    }

    /// The samples when they do not need a robot to be read, with the joint and point names
    /// they were given.
    fn samples(&self) -> PyResult<(&MeasurementSet, Names<'_>, Names<'_>)> {
        match &self.source {
            Source::Samples {
                set,
                joint_names,
                point_names,
            } => Ok((set, joint_names.as_deref(), point_names.as_deref())),
            Source::Csv { path, .. } => Err(PyValueError::new_err(format!(
                "{}: a CSV is read against a robot; use Measurements.read(path, robot) to see its values",
                path.display()
            ))),
        }
    }
}

/// `data`, one `Measurements` or a sequence of them (one station each, named by its file's
/// name or, for arrays, `station1`, `station2`, ...; a `station` column of one set names its
/// own), resolved against `robot` as `--data a.csv --data b.csv` reads them; the robot takes
/// their stations with `armcomp_api::with_stations`.
pub fn resolve_stations(robot: &Robot, data: &Bound<'_, PyAny>) -> PyResult<MeasurementSet> {
    Ok(match data.cast::<PyMeasurements>() {
        Ok(one) => one.get().resolve(robot)?,
        Err(_) => {
            let list: Vec<PyRef<'_, PyMeasurements>> = data.extract().map_err(|_| {
                input_error(
                    "data: expected Measurements or a list of them (one station each)",
                    None,
                    None,
                    Some("data"),
                )
            })?;
            let names: Vec<String> = (list.iter().enumerate())
                .map(|(k, m)| {
                    (m.read_from.as_ref())
                        .and_then(|p| p.file_stem())
                        .map_or_else(|| format!("station{}", k + 1), |s| s.to_string_lossy().into_owned())
                })
                .collect();
            if let Some((_, twice)) = names.iter().enumerate().find(|(i, n)| names[..*i].contains(n)) {
                return Err(input_error(
                    &format!(
                        "two data sets are named `{twice}`: each is a station named by its file's name, so rename one \
                         (or give the files a `station` column)"
                    ),
                    None,
                    None,
                    Some("data"),
                ));
            }
            let sets = list.iter().map(|m| m.resolve(robot)).collect::<PyResult<Vec<_>>>()?;
            MeasurementSet::from_files(sets, &names)
        }
    })
}

/// `set` with joint values in `robot`'s order and point indices of `robot`.
fn map_by_name(
    robot: &Robot,
    set: &MeasurementSet,
    joint_names: Option<&[String]>,
    point_names: Option<&[String]>,
) -> PyResult<MeasurementSet> {
    let tree = robot.tree();
    let layout = robot.csv_layout();
    let names = tree.coordinate_names();
    // For each of the robot's coordinates, the data's column or the value it holds.
    let columns: Vec<Result<usize, f64>> = match joint_names {
        None => (0..tree.nq()).map(Ok).collect(),
        Some(given) => {
            if let Some(unknown) = given.iter().find(|g| !names.contains(g)) {
                return Err(input_error(
                    &format!(
                        "the robot has no joint `{unknown}`; its joints are: {}",
                        names.join(", ")
                    ),
                    None,
                    None,
                    Some("joint_names"),
                ));
            }
            let mut missing = Vec::new();
            let columns = names
                .iter()
                .zip(&layout.hold)
                .map(|(n, hold)| match (given.iter().position(|g| g == n), hold) {
                    (Some(c), _) => Ok(c),
                    (None, Some(v)) => Err(*v),
                    (None, None) => {
                        missing.push(n.as_str());
                        Err(f64::NAN)
                    }
                })
                .collect();
            if !missing.is_empty() {
                return Err(input_error(
                    &format!(
                        "joint values missing for joint(s) that move the measured points: {}",
                        missing.join(", ")
                    ),
                    None,
                    None,
                    Some("joint_names"),
                ));
            }
            columns
        }
    };
    let width = joint_names.map_or(tree.nq(), <[String]>::len);
    // Torques are per coordinate, sensor readings per body: kept only when the data's joints
    // are the robot's, in order.
    let same_joints = width == tree.nq() && columns.iter().enumerate().all(|(i, c)| *c == Ok(i));
    let mut samples = Vec::with_capacity(set.samples.len());
    for (i, s) in set.samples.iter().enumerate() {
        if s.q.len() != width {
            return Err(input_error(
                &format!("sample {}: {} joint values, expected {width}", i + 1, s.q.len()),
                None,
                None,
                Some("joints"),
            ));
        }
        let point = match point_names {
            None => layout.points[0],
            Some(p) => {
                let name = &p[s.point];
                tree.point_index(name).ok_or_else(|| {
                    input_error(
                        &format!("sample {}: the robot has no point `{name}`", i + 1),
                        None,
                        None,
                        Some("points"),
                    )
                })?
            }
        };
        let q: Vec<f64> = columns.iter().map(|c| c.map_or_else(|v| v, |c| s.q[c])).collect();
        tree.check_q(&q)
            .map_err(|e| armcomp_core::Error::InvalidArgument {
                what: format!("sample {}", i + 1),
                reason: e.to_string(),
            })
            .py()?;
        samples.push(Sample {
            q,
            point,
            torque: if same_joints { s.torque.clone() } else { None },
            // A sensor reading names a body of the tree it was read for.
            sensors: if same_joints { s.sensors } else { Default::default() },
            ..s.clone()
        });
    }
    Ok(MeasurementSet {
        samples,
        rows: set.rows.clone(),
        warnings: Vec::new(),
        stations: set.stations.clone(),
    })
}

#[pymethods]
impl PyMeasurements {
    /// Measurements from arrays: `joints` (n × joints, SI: rad, m), `positions` (n × 3, m,
    /// measurement frame), `points` (the measured point of each row by name, or one name for
    /// all; default: the robot's first marker) and `joint_names` (the columns of `joints`;
    /// default: every joint of the robot in its order; joints left out hold the robot file's
    /// `hold` values).
    #[new]
    #[pyo3(signature = (joints, positions, points = None, joint_names = None))]
    fn new(
        joints: PyArrayLike2<'_, f64, AllowTypeChange>,
        positions: PyArrayLike2<'_, f64, AllowTypeChange>,
        points: Option<&Bound<'_, PyAny>>,
        joint_names: Option<Vec<String>>,
    ) -> PyResult<Self> {
        let q = crate::arrays::rows(&joints, "joints", joint_names.as_ref().map(Vec::len))?;
        let p = crate::arrays::rows(&positions, "positions", Some(3))?;
        if q.len() != p.len() {
            return Err(input_error(
                &format!("joints has {} rows, positions {}", q.len(), p.len()),
                None,
                None,
                Some("positions"),
            ));
        }
        // Point names: one per row, or one for all; indices into the list of distinct names.
        let (point_names, index): (Option<Vec<String>>, Vec<usize>) = match points {
            None => (None, vec![0; q.len()]),
            Some(obj) => {
                let per_row: Vec<String> = match obj.extract::<String>() {
                    Ok(one) => vec![one; q.len()],
                    Err(_) => obj.extract()?,
                };
                if per_row.len() != q.len() {
                    return Err(input_error(
                        &format!("points has {} names for {} rows", per_row.len(), q.len()),
                        None,
                        None,
                        Some("points"),
                    ));
                }
                let mut names: Vec<String> = Vec::new();
                let index = per_row
                    .iter()
                    .map(|n| match names.iter().position(|m| m == n) {
                        Some(i) => i,
                        None => {
                            names.push(n.clone());
                            names.len() - 1
                        }
                    })
                    .collect();
                (Some(names), index)
            }
        };
        if let Some(bad) = p.iter().flatten().chain(q.iter().flatten()).find(|v| !v.is_finite()) {
            return Err(input_error(&format!("a value is not finite: {bad}"), None, None, None));
        }
        let samples = q
            .into_iter()
            .zip(p)
            .zip(index)
            .map(|((q, p), point)| Sample {
                q,
                point,
                position: Vector3::new(p[0], p[1], p[2]),
                orientation: None,
                payload: None,
                temperature: None,
                torque: None,
                fixed_point: None,
                plane: None,
                sensors: Default::default(),
                station: 0,
                position_std: None,
            })
            .collect::<Vec<_>>();
        let rows = (0..samples.len()).collect();
        Ok(PyMeasurements {
            source: Source::Samples {
                set: MeasurementSet {
                    samples,
                    rows,
                    warnings: Vec::new(),
                    stations: Vec::new(),
                },
                joint_names,
                point_names,
            },
            read_from: None,
            table: None,
        })
    }

    /// Reads a measurement CSV (units in the headers, see the project's file formats) from a
    /// path, a file object or a `pandas.DataFrame` with the file's columns; with `robot` it is
    /// read against it now, else when first used. `rows` keeps some data rows
    /// (0-based, header excluded): `"even"`, `"odd"`, `"N"`, `"A..B"`, comma-separated, or a
    /// sequence of row indices.
    #[classmethod]
    #[pyo3(signature = (source, robot = None, rows = None))]
    fn read(
        _cls: &Bound<'_, PyType>,
        source: &Bound<'_, PyAny>,
        robot: Option<PyRef<'_, PyRobot>>,
        rows: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<Self> {
        // A DataFrame is the CSV it writes: its columns are the file's, units in the names.
        if source.hasattr("to_csv")? && source.hasattr("columns")? {
            let kwargs = pyo3::types::PyDict::new(source.py());
            kwargs.set_item("index", false)?;
            let text: String = source.call_method("to_csv", (), Some(&kwargs))?.extract()?;
            return PyMeasurements::csv(PathBuf::from("<DataFrame>"), text, robot, rows, None);
        }
        if source.hasattr("read")? {
            let content = source.call_method0("read")?;
            let text = match content.extract::<String>() {
                Ok(t) => t,
                Err(_) => String::from_utf8(content.extract::<Vec<u8>>()?).map_err(|e| {
                    input_error(&format!("the file is not UTF-8 text: {e}"), None, None, Some("source"))
                })?,
            };
            let name = (source.getattr("name").ok())
                .and_then(|n| n.extract::<String>().ok())
                .unwrap_or_else(|| "<file object>".into());
            return PyMeasurements::csv(PathBuf::from(name), text, robot, rows, None);
        }
        let path: PathBuf = source.extract().map_err(|_| {
            input_error(
                &format!(
                    "expected a path, a file object or a DataFrame, got {}",
                    source.get_type()
                ),
                None,
                None,
                Some("source"),
            )
        })?;
        let text =
            armcomp_core::support::io::read_text(&path, crate::input_limits()).map_err(|e| file_error(&e, &path))?;
        PyMeasurements::csv(path.clone(), text, robot, rows, Some(path))
    }

    /// The measurement CSV `save` writes for `robot`, as a `pandas.DataFrame` (its columns
    /// the file's, units in their names); `Measurements.read` reads it back.
    fn to_dataframe<'py>(&self, py: Python<'py>, robot: PyRef<'_, PyRobot>) -> PyResult<Bound<'py, PyAny>> {
        let set = self.resolve(&robot.robot)?;
        let text = write_csv_with_sensors(&set, robot.robot.tree(), robot.robot.units(), robot.robot.sensors());
        let pandas = py
            .import("pandas")
            .map_err(|_| pyo3::exceptions::PyImportError::new_err("to_dataframe needs pandas: pip install pandas"))?;
        let buffer = py.import("io")?.getattr("StringIO")?.call1((text,))?;
        pandas.call_method1("read_csv", (buffer,))
    }

    /// Measurements from the text of a measurement CSV, as `read` reads a file; `name` is how
    /// messages call it (`<text>` by default). `read` takes file objects and DataFrames
    /// through it.
    #[classmethod]
    #[pyo3(signature = (text, robot = None, rows = None, name = None))]
    fn parse(
        _cls: &Bound<'_, PyType>,
        text: String,
        robot: Option<PyRef<'_, PyRobot>>,
        rows: Option<&Bound<'_, PyAny>>,
        name: Option<String>,
    ) -> PyResult<Self> {
        let limit = crate::input_limits().max_bytes;
        if text.len() as u64 > limit {
            return Err(input_error(
                &format!("the CSV text is {} bytes, above the limit of {limit}", text.len()),
                None,
                None,
                Some("text"),
            ));
        }
        PyMeasurements::csv(
            PathBuf::from(name.unwrap_or_else(|| "<text>".into())),
            text,
            robot,
            rows,
            None,
        )
    }

    /// The samples `index` picks: a row position, a slice or a sequence of positions (of
    /// these measurements, not of the file's rows).
    fn __getitem__(&self, index: &Bound<'_, PyAny>) -> PyResult<Self> {
        let (set, joint_names, point_names) = self.samples()?;
        let n = set.samples.len();
        let picked: Vec<usize> = if let Ok(slice) = index.cast::<pyo3::types::PySlice>() {
            let i = slice.indices(n as isize)?;
            (0..i.slicelength)
                .map(|k| (i.start + k as isize * i.step) as usize)
                .collect()
        } else if let Ok(k) = index.extract::<isize>() {
            vec![position(k, n)?]
        } else {
            let list: Vec<isize> = index.extract().map_err(|_| {
                PyValueError::new_err(format!("index: expected a position, a slice or positions, got {index}"))
            })?;
            list.into_iter().map(|k| position(k, n)).collect::<PyResult<_>>()?
        };
        Ok(PyMeasurements {
            source: Source::Samples {
                set: MeasurementSet {
                    samples: picked.iter().map(|&i| set.samples[i].clone()).collect(),
                    rows: picked.iter().map(|&i| set.rows[i]).collect(),
                    warnings: Vec::new(),
                    stations: set.stations.clone(),
                },
                joint_names: joint_names.map(<[String]>::to_vec),
                point_names: point_names.map(<[String]>::to_vec),
            },
            read_from: self.read_from.clone(),
            table: self.table.clone(),
        })
    }

    /// The data rows of the samples (0-based, header excluded, as `rows` counts them).
    #[getter]
    fn rows(&self) -> PyResult<Vec<usize>> {
        Ok(self.samples()?.0.rows.clone())
    }

    /// These measurements read against `robot` (joint values in its order, its points).
    fn for_robot(&self, robot: PyRef<'_, PyRobot>) -> PyResult<Self> {
        Ok(PyMeasurements::from_set(&robot.robot, self.resolve(&robot.robot)?).like(self))
    }

    /// Joint values, one row per sample (SI), in the order of `joint_names`.
    #[getter]
    fn joints<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let (set, names, _) = self.samples()?;
        let q: Vec<Vec<f64>> = set.samples.iter().map(|s| s.q.clone()).collect();
        let width = names.map_or_else(|| q.first().map_or(0, Vec::len), <[String]>::len);
        Ok(crate::arrays::matrix(py, &q, width))
    }

    /// Measured positions (m, measurement frame), one row per sample.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let (set, _, _) = self.samples()?;
        let p: Vec<_> = set.samples.iter().map(|s| s.position).collect();
        Ok(crate::arrays::points(py, &p))
    }

    /// The measured point of each sample, by name (None: the robot's first marker).
    #[getter]
    fn points(&self) -> PyResult<Option<Vec<String>>> {
        let (set, _, names) = self.samples()?;
        Ok(names.map(|n| set.samples.iter().map(|s| n[s.point].clone()).collect()))
    }

    /// The columns of `joints` (None: the robot's joints in order).
    #[getter]
    fn joint_names(&self) -> PyResult<Option<Vec<String>>> {
        Ok(self.samples()?.1.map(<[String]>::to_vec))
    }

    /// Writes the measurements as a measurement CSV for `robot` (its joints and units),
    /// atomically, never over the CSV they were read from or a file the robot was read from.
    fn save(&self, path: PathBuf, robot: PyRef<'_, PyRobot>) -> PyResult<()> {
        let mut inputs = robot.robot.inputs();
        inputs.extend(self.read_from.clone());
        check_output(&path, &inputs).py()?;
        let set = self.resolve(&robot.robot)?;
        let text = write_csv_with_sensors(&set, robot.robot.tree(), robot.robot.units(), robot.robot.sensors());
        write_atomic(&path, text.as_bytes()).py()
    }

    fn __len__(&self) -> PyResult<usize> {
        Ok(self.samples()?.0.samples.len())
    }

    fn __repr__(&self) -> String {
        match &self.source {
            Source::Csv { path, .. } => format!("Measurements.read({:?})", path.display().to_string()),
            Source::Samples { set, .. } => format!("Measurements({} samples)", set.samples.len()),
        }
    }
}

/// `rows` (the argument `what`): a selection as `--rows` writes it, or a sequence of 0-based
/// data rows.
pub fn row_selection(rows: &Bound<'_, PyAny>, what: &str) -> PyResult<RowSelection> {
    let text = match rows.extract::<String>() {
        Ok(t) => t,
        Err(_) => {
            let list: Vec<usize> = rows.extract().map_err(|_| {
                input_error(
                    &format!("{what}: expected a selection such as \"even\" or \"0..40\", or row indices, got {rows}"),
                    None,
                    None,
                    Some(what),
                )
            })?;
            let listed: Vec<String> = list.iter().map(usize::to_string).collect();
            listed.join(",")
        }
    };
    text.parse::<RowSelection>()
        .map_err(|m| input_error(&format!("{what}: {m}"), None, None, Some(what)))
}

/// Position `k` of `n` samples, negative counting from the end as Python does.
fn position(k: isize, n: usize) -> PyResult<usize> {
    let i = if k < 0 { k + n as isize } else { k };
    if i < 0 || i >= n as isize {
        return Err(pyo3::exceptions::PyIndexError::new_err(format!(
            "sample {k} out of range: there are {n}"
        )));
    }
    Ok(i as usize)
}

/// The files `data` (one `Measurements` or a sequence) were read from, which no output may
/// replace.
pub fn files(data: &Bound<'_, PyAny>) -> Vec<PathBuf> {
    match data.cast::<PyMeasurements>() {
        Ok(one) => one.get().read_from.iter().cloned().collect(),
        Err(_) => (data.extract::<Vec<PyRef<'_, PyMeasurements>>>())
            .map(|list| list.iter().filter_map(|m| m.read_from.clone()).collect())
            .unwrap_or_default(),
    }
}

/// The folds' groups of `set` (read from `data`, one `Measurements` or a list): `labels`, one
/// per data row; else the CSV column `group_by` names (`COLUMN:N`: blocks of a numeric one);
/// else, as the command line, the set-up column (`session`, ...) every CSV has. Returns the
/// grouping's name and each sample's group, or `None` (folds by station or by pose).
pub fn fold_groups(
    data: &Bound<'_, PyAny>,
    set: &MeasurementSet,
    labels: Option<Vec<String>>,
    group_by: Option<&str>,
) -> PyResult<Option<(String, Vec<usize>)>> {
    if let Some(labels) = labels {
        if group_by.is_some() {
            return Err(input_error(
                "give groups or group_by, not both",
                None,
                None,
                Some("group_by"),
            ));
        }
        let rows = set.rows.iter().max().map_or(0, |r| r + 1);
        if labels.len() < rows {
            return Err(input_error(
                &format!("groups: one label per data row expected ({rows}), got {}", labels.len()),
                None,
                None,
                Some("groups"),
            ));
        }
        return Ok(Some((
            "groups".into(),
            armcomp_api::ops::fit::groups_of(&labels, &set.rows),
        )));
    }
    let list: Vec<PyRef<'_, PyMeasurements>> = match data.cast::<PyMeasurements>() {
        Ok(one) => vec![one.borrow()],
        Err(_) => data.extract()?,
    };
    let tables: Option<Vec<(&str, &std::path::Path)>> = (list.iter())
        .map(|m| m.table.as_ref().map(|(p, t)| (t.as_str(), p.as_path())))
        .collect();
    match tables {
        Some(tables) => armcomp_api::ops::fit::groups_by_column(group_by, &tables, &set.rows).py(),
        None if group_by.is_some() => Err(input_error(
            "group_by reads a column of the measurement CSV, and these measurements come from arrays; give \
             groups= (a label per row) instead",
            None,
            None,
            Some("group_by"),
        )),
        None => Ok(None),
    }
}
