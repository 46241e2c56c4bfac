//! `armcomp.Robot`: a robot or model file (or a bare URDF) ready to evaluate.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, TryLockError};

use armcomp_core::calibrate::ParameterSpace;
use armcomp_core::robot::robot_file::{Format, SourceFile};
use armcomp_core::support::io::{check_output, write_atomic};
use armcomp_core::{BatchWorkspace, PointKinematicsWorkspace, Robot, RobotFile};
use nalgebra::{IsometryMatrix3, Matrix6xX};
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray1, PyArray2, PyArray3, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{Matrix, vector_arg};
use crate::errors::{IntoPy, file_error, input_error};
use crate::measurements::PyMeasurements;

/// A robot: kinematics, points, error models and (for a model) identified values and a
/// fitted predictor. Values are SI (m, rad) in and out, whatever units the file uses.
#[pyclass(name = "Robot", module = "armcomp", frozen)]
pub struct PyRobot {
    pub robot: Arc<Robot>,
    /// The buffers of `fk`, `fk_many` and `jacobian`, kept so that a call allocates none.
    scratch: Mutex<Scratch>,
}

/// What the kinematics calls of one [`PyRobot`] evaluate into.
struct Scratch {
    batch: BatchWorkspace,
    poses: Vec<IsometryMatrix3<f64>>,
    point: PointKinematicsWorkspace,
    jacobian: Matrix6xX<f64>,
}

impl Scratch {
    fn new(robot: &Robot) -> Self {
        Scratch {
            batch: robot.batch_workspace(),
            poses: vec![IsometryMatrix3::identity(); robot.tree().points().len()],
            point: robot.kinematics().workspace(),
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
        PyRobot {
            scratch: Mutex::new(Scratch::new(&robot)),
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
            Err(TryLockError::WouldBlock) => f(&mut Scratch::new(&self.robot)),
        }
    }

    /// Index of the point named `name`, or the tool.
    fn point_index(&self, name: Option<&str>) -> PyResult<usize> {
        let tree = self.robot.tree();
        match name {
            None => Ok(self.robot.tool()),
            Some(n) => tree.point_index(n).ok_or_else(|| {
                let names: Vec<&str> = tree.points().iter().map(|p| p.name.as_str()).collect();
                input_error(
                    &format!("the robot has no point `{n}`; its points are: {}", names.join(", ")),
                    None,
                    None,
                    Some("point"),
                )
            }),
        }
    }

    /// `q` checked against the robot's joints.
    pub(crate) fn configuration(&self, q: &Bound<'_, PyAny>) -> PyResult<Vec<f64>> {
        let q = match q.cast::<PyDict>() {
            Ok(named) => self.named_configuration(named)?,
            Err(_) => vector_arg(q, "q", "for several configurations, one a row, call fk_many")?,
        };
        self.robot.tree().check_q(&q).py()?;
        Ok(q)
    }

    /// Joint values given by name (`{"joint": value}`), in the robot's order: every joint
    /// once, no other name, since another library's order is a silent error of metres.
    fn named_configuration(&self, named: &Bound<'_, PyDict>) -> PyResult<Vec<f64>> {
        let error = |message: String| input_error(&message, None, None, Some("q"));
        let mut pairs = Vec::with_capacity(named.len());
        for (key, value) in named.iter() {
            let name: String = key
                .extract()
                .map_err(|_| error(format!("joint names are strings, got {key}")))?;
            let v: f64 = value
                .extract()
                .map_err(|_| error(format!("joint `{name}`: expected a number, got {value}")))?;
            pairs.push((name, v));
        }
        let tree = self.robot.tree();
        let q = tree
            .coordinates_by_name(pairs.iter().map(|(n, v)| (n.as_str(), *v)))
            .py()?;
        let missing: Vec<&str> = (tree.coordinate_names().iter().zip(&q))
            .filter(|(_, v)| v.is_none())
            .map(|(n, _)| n.as_str())
            .collect();
        if !missing.is_empty() {
            return Err(error(format!("no value for joint(s) {}", missing.join(", "))));
        }
        Ok(q.into_iter().flatten().collect())
    }
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
        let text = self.robot.to_text_for(Path::new("model.toml")).py()?;
        let rebuild = py.get_type::<PyRobot>().getattr("from_toml")?;
        Ok((rebuild, (text, self.robot.base_dir())))
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
        let q = crate::arrays::matrix_arg(
            q,
            "Q",
            "one configuration per row (n × joints); for one configuration use fk(q) or Q.reshape(1, -1)",
        )?;
        let (n, nq) = q.as_array().dim();
        let tree = self.robot.tree();
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
        // A C-ordered float64 array is read in place; anything else is copied once.
        let copy;
        let qs = match q.as_slice() {
            Ok(s) if q.is_c_contiguous() => s,
            _ => {
                copy = q.as_array().iter().copied().collect::<Vec<f64>>();
                &copy
            }
        };
        let points = tree.points().len();
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
    }

    /// The 6 × nq Jacobian of the tool (or the named point) at `q`: rows 0–2 its linear
    /// velocity, rows 3–5 the angular velocity, base frame, of the chain at this robot's
    /// geometry (the error models' deformation is not differentiated).
    #[pyo3(signature = (q, point = None))]
    fn jacobian<'py>(
        &self,
        py: Python<'py>,
        q: &Bound<'py, PyAny>,
        point: Option<&str>,
    ) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let q = self.configuration(q)?;
        let p = self.point_index(point)?;
        // The robot's point kinematics hold the tree's points in the tree's order.
        let kinematics = self.robot.kinematics();
        let jacobian = self.with_scratch(|Scratch { point, jacobian, .. }| {
            kinematics.forward_into(&q, point);
            kinematics.pose_jacobian_into(point, p, jacobian);
            Array2::from_shape_fn((6, kinematics.nq()), |(r, c)| jacobian[(r, c)])
        });
        Ok(jacobian.into_pyarray(py))
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
    /// of its URDF kept) to `path`. Error models and a fitted predictor, which URDF cannot
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
