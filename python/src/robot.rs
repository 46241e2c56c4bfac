//! `armcomp.Robot`: a robot or model file (or a bare URDF) ready to evaluate.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, TryLockError};

use armcomp_core::calibrate::ParameterSpace;
use armcomp_core::data::measurement::Sample;
use armcomp_core::robot::robot_file::{Format, SourceFile};
use armcomp_core::support::io::{check_output, write_atomic};
use armcomp_core::{BatchWorkspace, Robot, RobotFile, RobotWorkspace, TreeWorkspace};
use nalgebra::{Isometry3, IsometryMatrix3, Matrix6xX, Vector3};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{Matrix, vector_arg};
use crate::errors::{IntoPy, file_error, input_error};
use crate::frames::{Frames, Reference, jacobian_into};
use crate::measurements::PyMeasurements;

/// A robot: kinematics, points, error models and (for a model) identified values and a
/// fitted predictor. Values are SI (m, rad) in and out, whatever units the file uses.
#[pyclass(name = "Robot", module = "armcomp", frozen)]
pub struct PyRobot {
    pub robot: Arc<Robot>,
    /// Its points and links by name.
    frames: Frames,
    /// The buffers of `fk`, `fk_many`, `pose` and `jacobian`, kept so that a call allocates none.
    scratch: Mutex<Scratch>,
}

/// What the kinematics calls of one [`PyRobot`] evaluate into.
struct Scratch {
    batch: BatchWorkspace,
    poses: Vec<IsometryMatrix3<f64>>,
    /// The full model's evaluation (frame poses).
    full: RobotWorkspace,
    /// The rigid evaluation of the frames' tree (Jacobians).
    rigid: TreeWorkspace,
    jacobian: Matrix6xX<f64>,
}

impl Scratch {
    fn new(robot: &Robot, frames: &Frames) -> Self {
        Scratch {
            batch: robot.batch_workspace(),
            poses: vec![IsometryMatrix3::identity(); robot.tree().points().len()],
            full: robot.workspace(),
            rigid: TreeWorkspace::new(&frames.tree),
            jacobian: Matrix6xX::zeros(robot.tree().nq()),
        }
    }
}

impl PyRobot {
    /// Wraps a robot an operation built (its reading warnings were issued when it was loaded).
    pub fn wrap(robot: Robot) -> Self {
        PyRobot::shared(Arc::new(robot))
    }

    /// Wraps a robot shared with another Python object.
    pub fn shared(robot: Arc<Robot>) -> Self {
        let frames = Frames::of(robot.tree());
        PyRobot {
            scratch: Mutex::new(Scratch::new(&robot, &frames)),
            frames,
            robot,
        }
    }

    /// Wraps a robot just read, handing its reading warnings to Python's `warnings`.
    pub fn new(py: Python<'_>, robot: Robot) -> PyResult<Self> {
        crate::errors::warn_all(py, robot.warnings())?;
        Ok(PyRobot::wrap(robot))
    }

    /// `f` on the robot's buffers, or on fresh ones while another thread holds them: never
    /// waiting for the lock, so a call holding the GIL cannot deadlock against one computing
    /// without it, and threads evaluating one robot run side by side. Buffers a panic left
    /// behind are only scratch, overwritten by the next call.
    fn with_scratch<R>(&self, f: impl FnOnce(&mut Scratch) -> R) -> R {
        match self.scratch.try_lock() {
            Ok(mut guard) => f(&mut guard),
            Err(TryLockError::Poisoned(e)) => f(&mut e.into_inner()),
            Err(TryLockError::WouldBlock) => f(&mut Scratch::new(&self.robot, &self.frames)),
        }
    }

    /// `q` checked against the robot's joints: values in the robot's order, or by joint name
    /// (a dict, or a `pandas.Series` read by its index).
    pub(crate) fn configuration(&self, q: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
        let q = match named_values(q)? {
            Some(pairs) => self.named_configuration(&pairs, "q")?,
            None => vector_arg(q, "q", "for several configurations, one a row, call fk_many")?,
        };
        self.robot.tree().check_q(&q).py()?;
        Ok(q)
    }

    /// Configurations one a row: an `n × nq` array in the robot's order (read in place when
    /// it is a C-ordered float64 array), or a `pandas.DataFrame` whose columns name joints (the
    /// others at their `hold` values). `f` gets the values row after row and the row count.
    fn with_configurations<R>(
        &self,
        q: &Bound<'_, PyAny>,
        f: impl FnOnce(&[f64], usize) -> PyResult<R>,
    ) -> PyResult<R> {
        let tree = self.robot.tree();
        if q.hasattr("columns")? && q.hasattr("to_numpy")? {
            let names: Vec<String> = (q.getattr("columns")?.try_iter()?)
                .map(|c| c.and_then(|c| c.str().map(|s| s.to_string())))
                .collect::<PyResult<_>>()?;
            let columns = self.joint_columns(&names, "Q")?;
            let values = crate::arrays::matrix_arg(&q.call_method0("to_numpy")?, "Q", "numbers in every column")?;
            let n = values.as_array().nrows();
            let mut flat = Vec::with_capacity(n * tree.nq());
            for row in values.as_array().rows() {
                flat.extend(columns.iter().map(|c| c.map_or_else(|held| held, |c| row[c])));
            }
            return f(&flat, n);
        }
        let q = crate::arrays::matrix_arg(
            q,
            "Q",
            "one configuration per row (n × joints); for one configuration use fk(q) or Q.reshape(1, -1)",
        )?;
        let (n, nq) = q.as_array().dim();
        if nq != tree.nq() {
            return Err(input_error(
                &format!(
                    "Q has {nq} columns but the robot has {} joints: {}",
                    tree.nq(),
                    tree.coordinate_names().join(", ")
                ),
                None,
                None,
                Some("Q"),
            ));
        }
        match q.as_slice() {
            Ok(s) if q.is_c_contiguous() => f(s, n),
            _ => f(&q.as_array().iter().copied().collect::<Vec<f64>>(), n),
        }
    }

    /// Joint values given by name, in the robot's order (see [`joint_columns`](Self::joint_columns)).
    fn named_configuration(&self, pairs: &[(String, f64)], field: &str) -> PyResult<Vec<f64>> {
        let names: Vec<String> = pairs.iter().map(|(n, _)| n.clone()).collect();
        let columns = self.joint_columns(&names, field)?;
        Ok(columns
            .iter()
            .map(|c| c.map_or_else(|held| held, |c| pairs[c].1))
            .collect())
    }

    /// For each of the robot's joints, the position of its value among values given by the
    /// joint `names`, or the robot file's `hold` value when `names` leave it out. A joint with
    /// neither is an error, as is a name the robot lacks or gives twice, since another
    /// library's order is a silent error of metres. Found once for a whole batch.
    fn joint_columns(&self, names: &[String], field: &str) -> PyResult<Vec<Result<usize, f64>>> {
        let tree = self.robot.tree();
        // The names' positions travel as the values: small integers are exact in f64, and the
        // names are checked as values by name always are.
        let given = tree
            .coordinates_by_name(names.iter().enumerate().map(|(c, n)| (n.as_str(), c as f64)))
            .py()?;
        let hold = self.robot.csv_layout().hold;
        let columns: Vec<Option<Result<usize, f64>>> = (given.iter().zip(&hold))
            .map(|(c, h)| c.map(|c| Ok(c as usize)).or(h.map(Err)))
            .collect();
        let missing: Vec<&str> = (tree.coordinate_names().iter().zip(&columns))
            .filter(|(_, c)| c.is_none())
            .map(|(n, _)| n.as_str())
            .collect();
        if !missing.is_empty() {
            return Err(input_error(
                &format!(
                    "no value for joint(s) {}, which the robot file does not hold either",
                    missing.join(", ")
                ),
                None,
                None,
                Some(field),
            ));
        }
        Ok(columns.into_iter().flatten().collect())
    }

    /// The poses of `frames` (indices of [`Frames`]) through the full model at `q`, base frame.
    fn frame_poses_into(&self, q: &[f64], frames: &[usize], s: &mut Scratch, out: &mut [f64]) {
        self.robot.forward_into(q, None, &mut s.full);
        let points = self.robot.tree().points();
        for (&k, block) in frames.iter().zip(out.chunks_exact_mut(16)) {
            let pose: Isometry3<f64> = match k.checked_sub(points.len()) {
                None => s.full.frames.point[k],
                Some(_) => s.full.frames.body[self.frames.tree.points()[k].body],
            };
            let h = pose.to_homogeneous();
            for (i, v) in block.iter_mut().enumerate() {
                *v = h[(i / 4, i % 4)];
            }
        }
    }

    /// `n` configurations of `qs`, one after the other, checked against the joints.
    fn check_rows(&self, qs: &[f64], n: usize) -> PyResult<()> {
        let tree = self.robot.tree();
        for (i, q) in qs.chunks_exact(tree.nq().max(1)).take(n).enumerate() {
            tree.check_q(q)
                .map_err(|e| input_error(&format!("configuration {}: {e}", i + 1), None, None, Some("Q")))?;
        }
        Ok(())
    }

    /// A sample of `point` (default the first marker) measured from `station` under the given
    /// conditions, at no configuration yet and measured at the origin.
    fn prediction_sample(
        &self,
        point: Option<&str>,
        station: Option<&str>,
        temperature: Option<f64>,
        payload: Option<f64>,
    ) -> PyResult<Sample> {
        let tree = self.robot.tree();
        let point = match point {
            None => self.robot.markers().first().copied().unwrap_or(self.robot.tool()),
            Some(name) => tree.point_index(name).ok_or_else(|| {
                let names: Vec<&str> = tree.points().iter().map(|p| p.name.as_str()).collect();
                input_error(
                    &format!("the robot has no point `{name}`; its points are: {}", names.join(", ")),
                    None,
                    None,
                    Some("point"),
                )
            })?,
        };
        let stations = self.robot.stations();
        let station = match station {
            None => 0,
            Some(name) => stations.iter().position(|s| s.name == name).ok_or_else(|| {
                let names: Vec<&str> = stations.iter().map(|s| s.name.as_str()).collect();
                input_error(
                    &format!(
                        "the robot has no station `{name}`; its stations are: {}",
                        if names.is_empty() {
                            "none (one measurement frame)".to_string()
                        } else {
                            names.join(", ")
                        }
                    ),
                    None,
                    None,
                    Some("station"),
                )
            })?,
        };
        Ok(Sample {
            q: Vec::new(),
            point,
            position: Vector3::zeros(),
            orientation: None,
            payload,
            temperature,
            torque: None,
            fixed_point: None,
            plane: None,
            sensors: Default::default(),
            station,
            position_std: None,
        })
    }

    /// The modelled measured positions of `samples` (measured at the origin): minus their
    /// errors through the very path of `evaluate`, so that the two agree to the bit.
    fn predicted(&self, samples: Vec<Sample>) -> Vec<Vector3<f64>> {
        let errors = armcomp_core::algorithms::evaluate::position_errors(&self.robot, &samples);
        errors.into_iter().map(|e| -e).collect()
    }
}

/// `pose` as a 4 × 4 homogeneous matrix.
fn homogeneous<'py>(py: Python<'py>, pose: &Isometry3<f64>) -> Matrix<'py> {
    let h = pose.to_homogeneous();
    Array2::from_shape_fn((4, 4), |(r, c)| h[(r, c)]).into_pyarray(py)
}

/// `(name, value)` pairs of joint values given by name: a dict, or a `pandas.Series` (anything
/// with an `index` and `items()`); `None` for values by position.
fn named_values(q: &Bound<'_, PyAny>) -> PyResult<Option<Vec<(String, f64)>>> {
    let items = match q.cast::<PyDict>() {
        Ok(d) => d.items().into_any(),
        Err(_) if q.hasattr("index")? && q.hasattr("items")? => q.call_method0("items")?,
        Err(_) => return Ok(None),
    };
    let error = |message: String| input_error(&message, None, None, Some("q"));
    let mut pairs = Vec::new();
    for item in items.try_iter()? {
        let (key, value): (Bound<'_, PyAny>, Bound<'_, PyAny>) = item?.extract()?;
        let name: String = key
            .extract()
            .map_err(|_| error(format!("joint names are strings, got {key}")))?;
        let v: f64 = value
            .extract()
            .map_err(|_| error(format!("joint `{name}`: expected a number, got {value}")))?;
        pairs.push((name, v));
    }
    Ok(Some(pairs))
}

/// `robot`'s model file as text with the folder its relative paths (a URDF) resolve against:
/// what rebuilds it, its fitted predictor included.
fn model_text(robot: &Robot) -> armcomp_core::Result<(String, PathBuf)> {
    let base_dir = robot.base_dir();
    Ok((robot.to_text_for(&base_dir.join("model.toml"))?, base_dir))
}

/// A copy of `robot` to change (its stations' frames), its fitted predictor kept, which
/// [`Robot::to_file`] leaves out.
pub fn copy_of(robot: &Robot) -> armcomp_core::Result<Robot> {
    let (text, base_dir) = model_text(robot)?;
    let src = SourceFile {
        path: base_dir.join("<copy>"),
        text,
        format: Format::Toml,
    };
    Robot::from_source(src.parse()?, &src, crate::input_limits())
}

/// Writes `text` to `path` atomically, never over a file `robot` was read from.
pub fn write_output(robot: &Robot, path: &Path, text: &str) -> PyResult<()> {
    check_output(path, &robot.inputs()).py()?;
    write_atomic(path, text.as_bytes()).py()
}

#[pymethods]
impl PyRobot {
    /// Reads a robot or model file (TOML, or JSON by extension) or a bare URDF (SI units, a
    /// point at every link). What was skipped while reading is issued as warnings.
    #[staticmethod]
    fn load(py: Python<'_>, path: PathBuf) -> PyResult<Self> {
        let robot = py
            .detach(|| armcomp_api::read_robot(&path, crate::input_limits()))
            .map_err(|e| file_error(&e, &path))?;
        PyRobot::new(py, robot)
    }

    /// Builds a robot from robot-file TOML text; relative paths in it (a URDF, meshes) are
    /// resolved against `base_dir` (default: the working folder).
    #[staticmethod]
    #[pyo3(signature = (text, base_dir = None))]
    fn from_toml(py: Python<'_>, text: String, base_dir: Option<PathBuf>) -> PyResult<Self> {
        let src = SourceFile {
            path: base_dir.unwrap_or_default().join("<from_toml>"),
            text,
            format: Format::Toml,
        };
        let robot = py
            .detach(|| {
                let file: RobotFile = src.parse()?;
                Robot::from_source(file, &src, crate::input_limits())
            })
            .py()?;
        PyRobot::new(py, robot)
    }

    /// Pickling (multiprocessing): the robot file with this robot's values, rebuilt where its
    /// relative paths (a URDF) resolve as they did.
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<(Bound<'py, PyAny>, (String, PathBuf))> {
        let rebuild = py.get_type::<PyRobot>().getattr("from_toml")?;
        Ok((rebuild, model_text(&self.robot).py()?))
    }

    /// The robot's name.
    #[getter]
    fn name(&self) -> String {
        self.robot.name().to_string()
    }

    /// Names of the independent joints: the columns of `q`, in order.
    #[getter]
    fn joint_names(&self) -> Vec<String> {
        self.robot.tree().coordinate_names().to_vec()
    }

    /// Number of independent joints.
    #[getter]
    fn nq(&self) -> usize {
        self.robot.tree().nq()
    }

    /// Lower and upper limit of each joint (nq × 2, SI; ±inf where the file gives none).
    #[getter]
    fn joint_limits<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        let limits = self.robot.tree().coordinate_limits();
        Array2::from_shape_fn((limits.len(), 2), |(i, c)| match (limits[i], c) {
            (Some(l), 0) => l.lower,
            (Some(l), _) => l.upper,
            (None, 0) => f64::NEG_INFINITY,
            (None, _) => f64::INFINITY,
        })
        .into_pyarray(py)
    }

    /// Names of the points, in the order `fk` returns them.
    #[getter]
    fn points(&self) -> Vec<String> {
        self.robot.tree().points().iter().map(|p| p.name.clone()).collect()
    }

    /// Name of the tool point.
    #[getter]
    fn tool(&self) -> String {
        self.robot.tree().points()[self.robot.tool()].name.clone()
    }

    /// Names of the measured points (the measurement CSV's `x1, y1, z1`, `x2`, ...).
    #[getter]
    fn markers(&self) -> Vec<String> {
        let points = self.robot.tree().points();
        self.robot.markers().iter().map(|&m| points[m].name.clone()).collect()
    }

    /// What was skipped while reading the description.
    #[getter]
    fn warnings(&self) -> Vec<String> {
        self.robot.warnings().to_vec()
    }

    /// The identifiable parameters: `(names, values, units)` with values in SI units (chain
    /// geometry, error models, measurement frame `base.*` and marker offsets `marker.*`), as a
    /// calibration of this model starts from them. Marker offsets, and a URDF joint's small
    /// rotations and `offset`, are corrections on the model's stored marker positions and
    /// joint origins: they read 0 on every model, calibrated or not, since a calibrated model
    /// holds what was found in those positions and origins. What a calibration changed is in
    /// its report (each parameter's `initial` and `value`).
    #[getter]
    fn parameters<'py>(&self, py: Python<'py>) -> (Vec<String>, Bound<'py, PyArray1<f64>>, Vec<&'static str>) {
        let space = ParameterSpace::new(&self.robot);
        let names = space.params.iter().map(|p| p.info.name.clone()).collect();
        let values = space.initial().into_pyarray(py);
        let units = space.params.iter().map(|p| p.info.quantity.si_unit()).collect();
        (names, values, units)
    }

    /// Forward kinematics of the full model at `q` (SI; in the order of `joint_names`, or a
    /// dict by joint name naming every joint once): the positions of every point (a
    /// `points × 3` array, m, base frame) and the tool pose (a 4 × 4 homogeneous matrix).
    fn fk<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>) -> PyResult<(Matrix<'py>, Matrix<'py>)> {
        let q = self.configuration(q)?;
        // A batch of one, so that `fk` and `fk_many` give the same bits.
        let robot = &self.robot;
        self.with_scratch(|Scratch { batch, poses, .. }| {
            robot.forward_many_into(1, &q, poses, batch).py()?;
            let positions = Array2::from_shape_fn((poses.len(), 3), |(p, k)| poses[p].translation.vector[k]);
            let tool = poses[robot.tool()].to_homogeneous();
            let pose = Array2::from_shape_fn((4, 4), |(r, c)| tool[(r, c)]);
            Ok((positions.into_pyarray(py), pose.into_pyarray(py)))
        })
    }

    /// Forward kinematics of many configurations in one call: `Q` is `n × nq` (SI), the result
    /// `n × points × 3` (m, base frame), computed without the GIL straight into the array.
    /// With `tool=True` also the tool poses, `n × 4 × 4` homogeneous matrices: `(positions,
    /// tools)`.
    #[pyo3(signature = (q, tool = false))]
    fn fk_many<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>, tool: bool) -> PyResult<Bound<'py, PyAny>> {
        let points = self.robot.tree().points().len();
        self.with_configurations(q, |qs, n| {
            if tool {
                // Whole poses: one buffer for the batch, then the two arrays from it.
                let mut poses = vec![nalgebra::IsometryMatrix3::identity(); n * points];
                py.detach(|| self.with_scratch(|s| self.robot.forward_many_into(n, qs, &mut poses, &mut s.batch)))
                    .py()?;
                let t = self.robot.tool();
                let positions = numpy::ndarray::Array3::from_shape_fn((n, points, 3), |(i, p, k)| {
                    poses[i * points + p].translation.vector[k]
                });
                let mut tools = numpy::ndarray::Array3::zeros((n, 4, 4));
                for (i, mut m) in tools.outer_iter_mut().enumerate() {
                    let h = poses[i * points + t].to_homogeneous();
                    m.indexed_iter_mut().for_each(|((r, c), v)| *v = h[(r, c)]);
                }
                return Ok((positions.into_pyarray(py), tools.into_pyarray(py))
                    .into_pyobject(py)?
                    .into_any());
            }
            let out = PyArray3::<f64>::zeros(py, [n, points, 3], false);
            {
                let mut write = out.readwrite();
                let slice = write.as_slice_mut().expect("a new array is contiguous");
                py.detach(|| self.with_scratch(|s| self.robot.point_positions_many_into(n, qs, slice, &mut s.batch)))
                    .py()?;
            }
            Ok(out.into_any())
        })
    }

    /// Names of every frame `pose` and `jacobian` take: the points (as `points` lists them),
    /// then each link of the kinematic tree no point is named after, at the link's origin.
    #[getter]
    fn frames(&self) -> Vec<String> {
        self.frames.names.clone()
    }

    /// The pose of `frame` (a point or a link; default the tool) at `q` through the full
    /// model: a 4 × 4 homogeneous matrix `t_base_frame` (m, base frame).
    #[pyo3(signature = (q, frame = None))]
    fn pose<'py>(&self, py: Python<'py>, q: &Bound<'py, PyAny>, frame: Option<&str>) -> PyResult<Matrix<'py>> {
        let q = self.configuration(q)?;
        let k = self.frames.index(frame, self.robot.tool())?;
        let mut h = [0.0; 16];
        self.with_scratch(|s| self.frame_poses_into(&q, &[k], s, &mut h));
        Ok(Array2::from_shape_vec((4, 4), h.to_vec())
            .expect("16 values")
            .into_pyarray(py))
    }

    /// The poses of `frames` (names; default every frame, in the order of `frames`) at each
    /// configuration of `Q` (n × nq, or a DataFrame by joint name), through the full model:
    /// `n × frames × 4 × 4` homogeneous matrices (m, base frame), computed without the GIL.
    #[pyo3(signature = (q, frames = None))]
    fn poses_many<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        frames: Option<Vec<String>>,
    ) -> PyResult<Bound<'py, numpy::PyArray4<f64>>> {
        let ks = self.frames.indices(frames, self.robot.tool())?;
        let nq = self.robot.tree().nq();
        self.with_configurations(q, |qs, n| {
            self.check_rows(qs, n)?;
            let out = numpy::PyArray4::<f64>::zeros(py, [n, ks.len(), 4, 4], false);
            {
                let mut write = out.readwrite();
                let slice = write.as_slice_mut().expect("a new array is contiguous");
                py.detach(|| {
                    self.with_scratch(|s| {
                        let per_row = ks.len() * 16;
                        for (q, block) in qs.chunks_exact(nq).zip(slice.chunks_exact_mut(per_row.max(1))) {
                            self.frame_poses_into(q, &ks, s, block);
                        }
                    })
                });
            }
            Ok(out)
        })
    }

    /// The 6 × nq Jacobian of `frame` (a point or a link; default the tool) at `q`: rows 0–2
    /// linear, rows 3–5 angular velocity per unit joint speed, of the chain at this robot's
    /// geometry (the error models' deformation is not differentiated). `reference`, as
    /// pinocchio's `ReferenceFrame` (its values are accepted too): `"local_world_aligned"`
    /// (default; the frame origin's velocity and the angular velocity in base axes),
    /// `"world"` (the spatial velocity at the base origin) or `"local"` (both in the frame's
    /// own axes).
    #[pyo3(signature = (q, frame = None, reference = None))]
    fn jacobian<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        frame: Option<&str>,
        reference: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let q = self.configuration(q)?;
        let k = self.frames.index(frame, self.robot.tool())?;
        let reference = reference.map_or(Ok(Reference::LocalWorldAligned), Reference::parse)?;
        let nq = self.robot.tree().nq();
        let jacobian = self.with_scratch(|s| {
            self.frames.tree.forward_into(&q, &mut s.rigid);
            jacobian_into(&self.frames, k, reference, &s.rigid, &mut s.jacobian);
            Array2::from_shape_fn((6, nq), |(r, c)| s.jacobian[(r, c)])
        });
        Ok(jacobian.into_pyarray(py))
    }

    /// The Jacobians of `frames` (names; default the tool alone) at each configuration of `Q`
    /// (n × nq, or a DataFrame by joint name) in `reference` (as `jacobian`): an
    /// `n × frames × 6 × nq` array, computed without the GIL.
    #[pyo3(signature = (q, frames = None, reference = None))]
    fn jacobians_many<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        frames: Option<Vec<String>>,
        reference: Option<&Bound<'py, PyAny>>,
    ) -> PyResult<Bound<'py, numpy::PyArray4<f64>>> {
        let ks = match frames {
            None => vec![self.robot.tool()],
            names => self.frames.indices(names, self.robot.tool())?,
        };
        let reference = reference.map_or(Ok(Reference::LocalWorldAligned), Reference::parse)?;
        let nq = self.robot.tree().nq();
        self.with_configurations(q, |qs, n| {
            self.check_rows(qs, n)?;
            let out = numpy::PyArray4::<f64>::zeros(py, [n, ks.len(), 6, nq], false);
            {
                let mut write = out.readwrite();
                let slice = write.as_slice_mut().expect("a new array is contiguous");
                py.detach(|| {
                    self.with_scratch(|s| {
                        let per_frame = (6 * nq).max(1);
                        let mut blocks = slice.chunks_exact_mut(per_frame);
                        for q in qs.chunks_exact(nq.max(1)).take(n) {
                            self.frames.tree.forward_into(q, &mut s.rigid);
                            for &k in &ks {
                                jacobian_into(&self.frames, k, reference, &s.rigid, &mut s.jacobian);
                                let block = blocks.next().expect("sized for every frame of every row");
                                for (i, v) in block.iter_mut().enumerate() {
                                    *v = s.jacobian[(i / nq, i % nq)];
                                }
                            }
                        }
                    })
                });
            }
            Ok(out)
        })
    }

    /// The modelled position (m) of `point` (default the first marker) at `q` in the
    /// measurement frame of `station` (its name; default the robot's one frame or first
    /// station): the full model and, when the model carries one, its fitted residual
    /// predictor: what a tracker would read, as `evaluate` compares it with the measured one.
    /// `temperature` (°C) and `payload` (kg) are the conditions error models may read.
    #[pyo3(signature = (q, point = None, station = None, temperature = None, payload = None))]
    fn predict<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        point: Option<&str>,
        station: Option<&str>,
        temperature: Option<f64>,
        payload: Option<f64>,
    ) -> PyResult<Bound<'py, PyArray1<f64>>> {
        let q = self.configuration(q)?;
        let at = self.prediction_sample(point, station, temperature, payload)?;
        let predicted = self.predicted(vec![Sample { q, ..at }]);
        Ok(numpy::ndarray::arr1(predicted[0].as_slice()).into_pyarray(py))
    }

    /// `predict` at each configuration of `Q` (n × nq, or a DataFrame by joint name): n × 3 (m,
    /// measurement frame), computed without the GIL.
    #[pyo3(signature = (q, point = None, station = None, temperature = None, payload = None))]
    fn predict_many<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        point: Option<&str>,
        station: Option<&str>,
        temperature: Option<f64>,
        payload: Option<f64>,
    ) -> PyResult<Matrix<'py>> {
        let at = self.prediction_sample(point, station, temperature, payload)?;
        let nq = self.robot.tree().nq();
        let samples = self.with_configurations(q, |qs, n| {
            self.check_rows(qs, n)?;
            Ok(qs
                .chunks_exact(nq.max(1))
                .take(n)
                .map(|q| Sample {
                    q: q.to_vec(),
                    ..at.clone()
                })
                .collect::<Vec<_>>())
        })?;
        let predicted = py.detach(|| self.predicted(samples));
        Ok(crate::arrays::points(py, &predicted))
    }

    /// The pose of the robot's base in its measurement frame, `t_measurement_base` (4 × 4, m):
    /// a point `p` of the base frame is at `t @ [p, 1]` in the tracker's frame. For data from
    /// several stations, `stations` gives each one's.
    #[getter]
    fn measurement_frame<'py>(&self, py: Python<'py>) -> Matrix<'py> {
        homogeneous(py, &self.robot.t_meas_base())
    }

    /// Each station's `t_measurement_base` (4 × 4, m) by name; empty for a robot measured
    /// from one place (see `measurement_frame`).
    #[getter]
    fn stations<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let out = PyDict::new(py);
        for s in self.robot.stations() {
            out.set_item(&s.name, homogeneous(py, &s.frame))?;
        }
        Ok(out)
    }

    /// Each measured point's placement on its link: `{marker: (link, position)}` with the
    /// position (3, m) in that link's frame, the frame `pose(q, link)` gives. `to_urdf` writes
    /// the markers as fixed frames and names the measurement frame, which no link holds, in a
    /// comment.
    #[getter]
    fn marker_offsets<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let tree = self.robot.tree();
        let out = PyDict::new(py);
        for &m in self.robot.markers() {
            let p = &tree.points()[m];
            let position = numpy::ndarray::arr1(p.local.translation.vector.as_slice()).into_pyarray(py);
            out.set_item(&p.name, (tree.bodies()[p.body].name.clone(), position))?;
        }
        Ok(out)
    }

    /// The robot file with this robot's values as text (TOML, or JSON with `format="json"`).
    #[pyo3(signature = (format = "toml"))]
    fn to_text(&self, format: &str) -> PyResult<String> {
        let name = match format {
            "toml" => "model.toml",
            "json" => "model.json",
            other => {
                return Err(input_error(
                    &format!("unknown format `{other}`; expected toml or json"),
                    None,
                    None,
                    Some("format"),
                ));
            }
        };
        self.robot.to_text_for(Path::new(name)).py()
    }

    /// Writes the robot file with this robot's values (a calibrated model, with its fitted
    /// predictor) to `path` atomically: TOML, or JSON for a `.json` extension; never over a
    /// file it was read from.
    fn save(&self, path: PathBuf) -> PyResult<()> {
        let text = self.robot.to_text_for(&path).py()?;
        write_output(&self.robot, &path, &text)
    }

    /// Writes the model's URDF with the identified joint origins and axes (every other byte
    /// of its URDF kept, the markers added as fixed frames, the measurement frame named in a
    /// comment) to `path`. Error models and a fitted predictor, which URDF cannot
    /// hold, are refused unless `rigid_only`; with `data` it returns how far (m) dropping them
    /// moves the measured points, else None.
    #[pyo3(signature = (path, rigid_only = false, data = None))]
    fn to_urdf(
        &self,
        path: PathBuf,
        rigid_only: bool,
        data: Option<PyRef<'_, PyMeasurements>>,
    ) -> PyResult<Option<f64>> {
        let robot = &self.robot;
        let dropped = armcomp_api::ops::export_urdf::inexpressible(robot);
        if !dropped.is_empty() && !rigid_only {
            return Err(input_error(
                &format!(
                    "URDF cannot express {}; the exported URDF would not be this model. Pass rigid_only=True (and data=) to export the rigid geometry anyway",
                    dropped.join(", ")
                ),
                None,
                None,
                None,
            ));
        }
        let urdf = armcomp_urdf::calibrated_urdf(robot).py()?;
        let mut inputs = robot.inputs();
        inputs.push(urdf.source.clone());
        check_output(&path, &inputs).py()?;
        let deviation = match (&data, dropped.is_empty()) {
            (Some(d), false) => {
                let set = d.resolve(robot)?;
                Some(armcomp_api::ops::export_urdf::rigid_deviation(robot, &set.samples).py()?)
            }
            _ => None,
        };
        write_atomic(&path, urdf.text.as_bytes()).py()?;
        Ok(deviation)
    }

    fn __repr__(&self) -> String {
        format!(
            "Robot({:?}, {} joints, {} points, tool {:?})",
            self.robot.name(),
            self.robot.tree().nq(),
            self.robot.tree().points().len(),
            self.tool()
        )
    }
}
