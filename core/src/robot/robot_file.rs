//! The robot file: what users write (TOML, or JSON), read with errors that name the file, the
//! line and the field.

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use schemars::{JsonSchema, Schema, SchemaGenerator, json_schema};
use serde::{Deserialize, Serialize};

use crate::error::{Error, Issue, Result};
use crate::model::mass::Section;
use crate::model::shape::Geometry;
use crate::model::units::Units;
use crate::plugin::{ErrorModelSpec, FittedPredictor, KinematicsSpec, PredictorSpec};
use crate::support::io::InputLimits;

fn default_gravity() -> [f64; 3] {
    [0.0, 0.0, -9.81]
}

fn default_tool() -> String {
    "tool".to_string()
}

/// A robot description: kinematics, mass model, named points, error models, predictor.
#[derive(Debug, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
#[schemars(title = "armcomp robot file")]
pub struct RobotFile {
    /// Name of the robot.
    pub name: String,
    /// What the robot is, where its numbers come from.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub description: Option<String>,
    /// Units of every length and angle in this file.
    #[serde(default)]
    pub units: Units,
    /// Gravity in the robot base frame (m/s², always SI).
    #[serde(default = "default_gravity")]
    pub gravity: [f64; 3],
    /// The kinematic convention and its parameters.
    #[schemars(with = "KinematicsPlugin")]
    pub kinematics: Box<dyn KinematicsSpec>,
    /// Mass properties and beam sections of links (by link name).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub links: Vec<LinkSpec>,
    /// Named points fixed to links: the tool, measurement markers.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub points: Vec<PointSpec>,
    /// Name of the point that is the tool (default `tool`).
    #[serde(default = "default_tool")]
    pub tool: String,
    /// A payload carried at a point.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub payload: Option<PayloadSpec>,
    /// Physical error models composed into the chain.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    #[schemars(with = "Vec<ErrorModelPlugin>")]
    pub error_models: Vec<Box<dyn ErrorModelSpec>>,
    /// The residual predictor learned on what the physical model leaves.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(with = "Option<PredictorPlugin>")]
    pub predictor: Option<Box<dyn PredictorSpec>>,
    /// The predictor fitted on this model's residuals (`armcomp learn` writes it): joint
    /// values in, measured minus modelled position (m, measurement frame) out. Dropped when
    /// the model's parameters change, since it no longer matches them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(with = "Option<serde_json::Map<String, serde_json::Value>>")]
    pub fitted_predictor: Option<Box<dyn FittedPredictor>>,
    /// The frame the fitted predictor's residuals are in: `base` (the robot's own, as `learn`
    /// writes them: the predictor follows the robot to another measurement frame or station)
    /// or `measurement` (the frame of the data it was fitted on; files written before this key
    /// existed). Absent: `measurement`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub predictor_frame: Option<PredictorFrame>,
    /// The measurement setup: where the tracker is, which points it sees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub measurement: Option<MeasurementSpec>,
    /// Sensors read per measurement row (an accelerometer or inclinometer giving the direction
    /// of gravity), with their columns in measurement files.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sensors: Vec<crate::kinematics::sensor::SensorSpec>,
    /// Shapes fixed in the cell (floor, tables, walls), for collision checking.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub fixtures: Vec<FixtureSpec>,
    /// Collision-checking settings.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub collision: Option<CollisionSpec>,
    /// Parameters known well enough that calibration and diagnosis keep them at the values
    /// this file gives: names as calibration reports them, `*` matching any run of characters
    /// (`joint_compliance.j5`, `j2.*`, `base.*`, `marker.tool.z`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub fixed: Vec<String>,
    /// How this model was fitted (`armcomp fit` and `calibrate` write it): what later commands
    /// on the model continue from unless told otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fitted: Option<FitRecord>,
}

/// How a model was fitted: the identified set, the priors, the noise, and what
/// cross-validation expected of it. `diagnose`, `learn` and `calibrate` on the model fit
/// again the same way unless their flags say otherwise.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FitRecord {
    /// What was identified, as `calibrate --identify` words.
    pub identify: Vec<String>,
    /// The prior scheme in words (`evidence per parameter`, `file ×0.3`, `no priors`, ...).
    pub prior: String,
    /// Whether the parameters had priors (`false`: every direction the data could not
    /// determine was fixed).
    pub use_priors: bool,
    /// Per free parameter with a prior, the factor the fit put on this file's prior standard
    /// deviation (parameter names as calibration reports them).
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub prior_scales: BTreeMap<String, f64>,
    /// The tracker noise per axis the fit weighed the rows by (mm).
    pub noise_mm: f64,
    /// Whether that noise was estimated from the rows (else declared).
    pub noise_estimated: bool,
    /// The orientation noise per axis (degrees), when the robot measures poses.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_deg: Option<f64>,
    /// The held-out RMS cross-validation expected of the model (mm), when it was chosen by it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub expected_rms_mm: Option<f64>,
    /// Whether the choice included the residual predictor the model carries.
    #[serde(default)]
    pub predictor: bool,
    /// Each identified parameter's value before the fit (SI, parameter names as calibration
    /// reports them): where its prior was centred, so that a command fitting the model again on
    /// the same rows starts where the fit started rather than from its answer.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub nominal: BTreeMap<String, f64>,
}

/// Mass properties and beam section of one link.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LinkSpec {
    /// The link's name as the kinematics defines it.
    pub name: String,
    /// Mass (kg).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<f64>,
    /// Centre of mass in the link frame (length unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub com: Option<[f64; 3]>,
    /// The link seen as a beam, for the deflection model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub beam: Option<BeamSpec>,
    /// Density (kg/m³): without `mass`, the link's mass and centre of mass are those of its
    /// `shapes` made of this material.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub density: Option<f64>,
    /// Solid shapes of the link, for collision checking (and mass with `density`); they replace
    /// the collision elements a URDF gives for this link.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub shapes: Vec<ShapeSpec>,
}

/// A shape placed in a link's frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ShapeSpec {
    /// The shape (dimensions in the length unit); `plane` is for fixtures only.
    pub geometry: Geometry,
    /// Position of the shape's frame in the link frame (length unit).
    #[serde(default)]
    pub xyz: [f64; 3],
    /// Orientation of the shape's frame in the link frame, roll-pitch-yaw (angle unit).
    #[serde(default)]
    pub rpy: [f64; 3],
}

/// A shape fixed in the robot's base frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct FixtureSpec {
    /// Name used in collision reports.
    pub name: String,
    /// The shape (dimensions in the length unit); `plane` is the half-space below the frame's
    /// xy plane, a floor.
    pub geometry: Geometry,
    /// Position of the shape's frame in the base frame (length unit).
    #[serde(default)]
    pub xyz: [f64; 3],
    /// Orientation of the shape's frame in the base frame, roll-pitch-yaw (angle unit).
    #[serde(default)]
    pub rpy: [f64; 3],
}

/// Collision-checking settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, Default)]
#[serde(deny_unknown_fields)]
pub struct CollisionSpec {
    /// Shapes closer than this count as colliding (length unit; default 0: touching).
    #[serde(default)]
    pub margin: f64,
    /// Link pairs never checked against each other, e.g. `[["upper_arm", "cable_guide"]]`.
    /// Links on the same rigid body and links one joint apart are never checked anyway.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ignore: Vec<[String; 2]>,
}

/// A link's beam: a section and a material, or the rigidities directly.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BeamSpec {
    /// Cross-section (dimensions in the length unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub section: Option<Section>,
    /// Young's modulus E (Pa).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub youngs_modulus: Option<f64>,
    /// Shear modulus G (Pa); defaults to E / 2.6 (Poisson ratio 0.3).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shear_modulus: Option<f64>,
    /// Flexural rigidity E·Iy (N m²), instead of section and material.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ei_y: Option<f64>,
    /// Flexural rigidity E·Iz (N m²), instead of section and material.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub ei_z: Option<f64>,
    /// Torsional rigidity G·J (N m²), instead of section and material.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub gj: Option<f64>,
}

/// A named point (with orientation) on a link.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PointSpec {
    /// Name, e.g. `tool` or `marker_1`.
    pub name: String,
    /// The link it is fixed to (`base` or a link the kinematics defines).
    pub link: String,
    /// Position in the link frame (length unit).
    #[serde(default)]
    pub xyz: [f64; 3],
    /// Orientation in the link frame as URDF roll-pitch-yaw (angle unit).
    #[serde(default)]
    pub rpy: [f64; 3],
}

/// A payload carried at a point.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PayloadSpec {
    /// Mass (kg).
    pub mass: f64,
    /// The point it hangs at (default: the tool).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point: Option<String>,
}

/// The measurement setup.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MeasurementSpec {
    /// What each row of a measurement file measures at the markers: `point` (a position),
    /// `pose` (a position and an orientation; the markers' orientations on their links are
    /// identified with their positions), `fixed_point` (no position: the marker was put into
    /// the unknown fixed point its `fixed_point` column names, whose position is identified) or
    /// `plane` (no position: the marker, a contact frame, pressed on the unknown plane its
    /// `plane` column names, whose height and tilts are identified).
    #[serde(default, skip_serializing_if = "MeasurementKind::is_point")]
    pub kind: MeasurementKind,
    /// The link whose frame the measurements are expressed in, when it is not the robot's
    /// root (a foot standing on the floor, a camera on a head): the measured pose is then
    /// `T_root_link⁻¹ · T_root_marker`, and `base_xyz`/`base_rpy` place that link's frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame_link: Option<String>,
    /// Guess of the robot base position in the tracker frame (length unit).
    #[serde(default)]
    pub base_xyz: [f64; 3],
    /// Guess of the robot base orientation in the tracker frame, roll-pitch-yaw (angle unit).
    #[serde(default)]
    pub base_rpy: [f64; 3],
    /// The points the tracker measures (default: the tool). Numbered position columns of a
    /// measurement file (`x1, y1, z1`, `x2, ...`) are these points in this order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub markers: Vec<String>,
    /// Values of joints that held still while measuring (length or angle unit by the joint's
    /// type), used when a measurement file has no column for them. A joint that moves no
    /// marker and is not named here holds 0, or the middle of its limits if 0 is outside them.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub hold: BTreeMap<String, f64>,
    /// Known distances between fixed points (`kind = "fixed_point"`, or fixed points among
    /// the positions of `"point"` or `"pose"`): without one the scale of
    /// the robot is not observable from fixed points alone.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub distances: Vec<DistanceSpec>,
    /// Nominal poses of the planes of plane contacts (`kind = "plane"`, or contacts among the
    /// positions of `point` and `pose`), by the name their `plane` column gives; a plane not
    /// listed starts from a fit to its rows.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub planes: Vec<PlaneSpec>,
    /// What a plane contact constrains (any kind but `fixed_point`): `height` (the marker's distance
    /// from the plane) and the tilts `roll` and `pitch` of the marker's frame from the
    /// plane's. Default: all three (flush contact); `["height"]` for a point touching.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub constrain: Vec<PlaneComponent>,
    /// The measurement frames of several stations (instrument set-ups), when the data were
    /// measured from more than one: a measurement file's `station` column names them. The
    /// first is also `base_xyz`/`base_rpy`, which this list overrides.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub stations: Vec<StationSpec>,
}

/// A known distance between two fixed points, e.g. two sockets of a printed tool.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DistanceSpec {
    /// The two fixed points, as the measurement file's `fixed_point` column names them.
    pub between: [String; 2],
    /// The distance (mm, whatever the file's length unit).
    pub mm: f64,
    /// Standard deviation of that distance (mm); default: the tracker noise per axis the
    /// calibration weighs positions with.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise_mm: Option<f64>,
}

/// A plane's nominal pose in the measurement frame: its normal is the frame's `z` axis.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PlaneSpec {
    /// The name a measurement file's `plane` column gives it.
    pub name: String,
    /// A point of the plane (length unit).
    #[serde(default)]
    pub xyz: [f64; 3],
    /// Its orientation, roll-pitch-yaw (angle unit).
    #[serde(default)]
    pub rpy: [f64; 3],
}

/// A component of a plane contact.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum PlaneComponent {
    /// The marker's distance from the plane along its normal.
    Height,
    /// The marker frame's turn from the plane's about the plane's `x` axis.
    Roll,
    /// The marker frame's turn from the plane's about the plane's `y` axis.
    Pitch,
}

/// One station's measurement frame: the robot base pose seen from it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StationSpec {
    /// The name a measurement file's `station` column gives it.
    pub name: String,
    /// The robot base position in the station's frame (length unit).
    #[serde(default)]
    pub base_xyz: [f64; 3],
    /// The robot base orientation in the station's frame, roll-pitch-yaw (angle unit).
    #[serde(default)]
    pub base_rpy: [f64; 3],
}

/// What the rows of a measurement file measure at the markers.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum MeasurementKind {
    /// A position of each measured marker.
    #[default]
    Point,
    /// A position and an orientation (a motion-capture rigid body, a 6-DoF probe).
    Pose,
    /// No position: the marker put into an unknown fixed point (a ball in a socket, a tip on
    /// a divot) named by the row's `fixed_point` column.
    FixedPoint,
    /// No position: the marker (a contact frame) pressed on an unknown plane (a table) named
    /// by the row's `plane` column.
    Plane,
}

/// The frame a fitted residual predictor's outputs are in (see [`RobotFile::predictor_frame`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum PredictorFrame {
    /// The robot's base frame: measured minus modelled position rotated out of the measurement
    /// frame of its row, so that re-registering the robot (another station, `calibrate
    /// --identify base`) keeps the predictor valid.
    Base,
    /// The measurement frame of the data the predictor was fitted on.
    #[default]
    Measurement,
}

impl MeasurementKind {
    /// Whether it is the default, `point`.
    pub fn is_point(&self) -> bool {
        *self == MeasurementKind::Point
    }
}

macro_rules! plugin_placeholder {
    ($ty:ident, $name:literal, $doc:literal) => {
        #[doc = concat!("Schema placeholder for one `", $name, "`; the registry fills in the plugins.")]
        pub struct $ty;
        impl JsonSchema for $ty {
            fn schema_name() -> Cow<'static, str> {
                Cow::Borrowed($name)
            }
            fn json_schema(_: &mut SchemaGenerator) -> Schema {
                json_schema!({ "description": $doc })
            }
        }
    };
}

plugin_placeholder!(
    KinematicsPlugin,
    "KinematicsPlugin",
    "A kinematics plugin, chosen by `type`."
);
plugin_placeholder!(
    ErrorModelPlugin,
    "ErrorModelPlugin",
    "An error-model plugin, chosen by `type`."
);
plugin_placeholder!(
    PredictorPlugin,
    "PredictorPlugin",
    "A residual-predictor plugin, chosen by `type`."
);

/// The format of a robot or model file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Format {
    /// TOML (`.toml`).
    Toml,
    /// JSON (`.json`).
    Json,
}

thread_local! {
    /// The folders of the files [`SourceFile::parse`] is reading on this thread, innermost last.
    static READING: std::cell::RefCell<Vec<PathBuf>> = const { std::cell::RefCell::new(Vec::new()) };
}

/// Pops the folder `parse` pushed even if deserialising panics.
struct ReadingGuard;

impl Drop for ReadingGuard {
    fn drop(&mut self) {
        READING.with(|r| r.borrow_mut().pop());
    }
}

/// The folder of the file being parsed on this thread (empty for the working folder), if any:
/// a value that loads a file while it is read (a fitted run-time predictor names its library)
/// finds it there, since serde cannot hand it the file's path.
pub fn folder_being_read() -> Option<PathBuf> {
    READING.with(|r| r.borrow().last().cloned())
}

/// A text file kept in memory so that field paths can be mapped back to lines.
#[derive(Debug, Clone)]
pub struct SourceFile {
    /// The path as the user gave it.
    pub path: PathBuf,
    /// The whole text.
    pub text: String,
    /// How it is written.
    pub format: Format,
}

impl SourceFile {
    /// Reads a file within `limits`; the format follows the extension (`.json` is JSON,
    /// anything else TOML).
    pub fn read(path: &Path, limits: InputLimits) -> Result<Self> {
        let text = crate::support::io::read_text(path, limits)?;
        let format = match path.extension().and_then(|e| e.to_str()) {
            Some(e) if e.eq_ignore_ascii_case("json") => Format::Json,
            _ => Format::Toml,
        };
        Ok(SourceFile {
            path: path.to_path_buf(),
            text,
            format,
        })
    }

    /// 1-based line of a byte offset.
    pub fn line_of_offset(&self, offset: usize) -> usize {
        self.text.as_bytes()[..offset.min(self.text.len())]
            .iter()
            .filter(|b| **b == b'\n')
            .count()
            + 1
    }

    /// 1-based line where the field at a dotted path (`a.b[2].c`) is written, if found.
    pub fn line_of_path(&self, path: &str) -> Option<usize> {
        match self.format {
            Format::Toml => toml_span_of_path(&self.text, path).map(|o| self.line_of_offset(o)),
            Format::Json => json_span_of_path(&self.text, path).map(|o| self.line_of_offset(o)),
        }
    }

    /// Deserialises the whole file into `T`; failures name the line and the field path.
    /// Meanwhile [`folder_being_read`] is this file's folder.
    pub fn parse<T: serde::de::DeserializeOwned>(&self) -> Result<T> {
        READING.with(|r| {
            r.borrow_mut()
                .push(self.path.parent().map(Path::to_path_buf).unwrap_or_default())
        });
        let _guard = ReadingGuard;
        self.parse_here()
    }

    fn parse_here<T: serde::de::DeserializeOwned>(&self) -> Result<T> {
        let issue = match self.format {
            Format::Toml => {
                let de = toml::Deserializer::parse(&self.text).map_err(|e| self.toml_error(&e, String::new()))?;
                match serde_path_to_error::deserialize(de) {
                    Ok(v) => return Ok(v),
                    Err(e) => {
                        let path = clean_path(&e.path().to_string());
                        return Err(self.toml_error(e.inner(), path));
                    }
                }
            }
            Format::Json => {
                let mut de = serde_json::Deserializer::from_str(&self.text);
                match serde_path_to_error::deserialize(&mut de) {
                    Ok(v) => return Ok(v),
                    Err(e) => {
                        let path = clean_path(&e.path().to_string());
                        let inner = e.into_inner();
                        let message = strip_json_position(&inner.to_string());
                        match deeper(&path, &message) {
                            Some((path, message)) => Issue {
                                line: self.line_of_path(&path).or(Some(inner.line())),
                                path,
                                message,
                            },
                            None => Issue {
                                path,
                                message,
                                line: Some(inner.line()),
                            },
                        }
                    }
                }
            }
        };
        Err(Error::InvalidFile {
            file: self.path.clone(),
            issues: vec![issue],
        })
    }

    /// The issue of a TOML error. Some of it is read from the message text because there is
    /// nowhere else to read it from: serde builds a deserializer's errors through
    /// `de::Error::custom(text)`, so what kind of error it is (an invalid type and what was
    /// found, an unknown field and its name) and the inner path [`tracked`] adds arrive as
    /// text, and `toml::de::Error` exposes only that text, a span and no kind.
    fn toml_error(&self, e: &toml::de::Error, path: String) -> Error {
        if let Some((path, message)) = deeper(&path, e.message().trim()) {
            let line = self
                .line_of_path(&path)
                .or_else(|| e.span().map(|s| self.line_of_offset(s.start)));
            return Error::InvalidFile {
                file: self.path.clone(),
                issues: vec![Issue { path, message, line }],
            };
        }
        let line = e.span().map(|s| self.line_of_offset(s.start));
        let line = line.or_else(|| self.line_of_path(&path));
        let mut message = e.message().trim().to_string();
        // toml says which key only by its span.
        if message == "duplicate key"
            && let Some(key) = e.span().and_then(|s| self.text.get(s))
        {
            message = format!("duplicate key `{}`", key.trim());
        }
        // Plugin specs are read behind typetag, so serde's path and span stop at the plugin's
        // table; a value of the wrong type is still findable when it is the only one below.
        let (path, line) = match unexpected_value(&message).and_then(|v| toml_find_value(&self.text, &path, v)) {
            Some((p, offset)) => (p, Some(self.line_of_offset(offset))),
            None => (path, line),
        };
        // An unknown key is findable by its name below the plugin's line.
        let line = match (line, backticked_after(&message, "unknown field ")) {
            (Some(from), Some(key)) => self.line_of_key(key, from).or(Some(from)),
            (line, _) => line,
        };
        Error::InvalidFile {
            file: self.path.clone(),
            issues: vec![Issue { path, message, line }],
        }
    }

    /// First line at or after `from` that assigns `key` (`key = ...`).
    fn line_of_key(&self, key: &str, from: usize) -> Option<usize> {
        self.text
            .lines()
            .enumerate()
            .skip(from.saturating_sub(1))
            .find_map(|(i, l)| {
                let rest = l.trim_start().strip_prefix(key)?;
                rest.trim_start().starts_with('=').then_some(i + 1)
            })
    }

    /// Attaches lines to issues found after parsing and wraps them as an error for this file.
    pub fn invalid(&self, issues: Vec<Issue>) -> Error {
        let issues = issues
            .into_iter()
            .map(|mut i| {
                if i.line.is_none() {
                    i.line = self.line_of_path(&i.path);
                }
                i
            })
            .collect();
        Error::InvalidFile {
            file: self.path.clone(),
            issues,
        }
    }
}

/// Deserialises the field `field` of a plugin's spec so that an error inside it says where:
/// serde's path stops at a plugin's table (typetag reads the table whole before the plugin's
/// type sees it), so the message begins ``at `field[1].kind`: `` and the file's reader moves
/// that into the issue's path and line. Use it as `deserialize_with` through a function that
/// names the field.
pub fn tracked<'de, D, T>(d: D, field: &str) -> std::result::Result<T, D::Error>
where
    D: serde::Deserializer<'de>,
    T: Deserialize<'de>,
{
    serde_path_to_error::deserialize(d).map_err(|e| {
        let inner = clean_path(&e.path().to_string());
        let sep = if inner.is_empty() || inner.starts_with('[') {
            ""
        } else {
            "."
        };
        <D::Error as serde::de::Error>::custom(format!("at `{field}{sep}{inner}`: {}", e.into_inner()))
    })
}

/// The path and message of an error [`tracked`] inside the plugin table at `path`. The path
/// travels in the text because serde's error trait carries nothing else; a side channel
/// (a thread-local set by `tracked`) would outlive errors that typetag or an untagged enum
/// catch and discard, and name the wrong field.
fn deeper(path: &str, message: &str) -> Option<(String, String)> {
    let rest = message.strip_prefix("at `")?;
    let (inner, message) = rest.split_once("`: ")?;
    let sep = if path.is_empty() { "" } else { "." };
    Some((format!("{path}{sep}{inner}"), message.to_string()))
}

/// The first `name` in "...`prefix``name`..." messages.
fn backticked_after<'m>(message: &'m str, prefix: &str) -> Option<&'m str> {
    let rest = &message[message.find(prefix)? + prefix.len()..];
    let rest = rest.strip_prefix('`')?;
    Some(&rest[..rest.find('`')?])
}

/// serde_path_to_error writes `.` for the root and `?` for unknown positions.
fn clean_path(p: &str) -> String {
    if p == "." {
        String::new()
    } else {
        p.replace(".?", "").replace('?', "")
    }
}

/// serde_json's message without the ` at line L column C` its `Display` appends: the error
/// gives the line and column as numbers but not the message without them.
fn strip_json_position(msg: &str) -> String {
    match msg.rfind(" at line ") {
        Some(i) => msg[..i].to_string(),
        None => msg.to_string(),
    }
}

/// Splits `a.b[2].c` into segments.
enum Seg<'a> {
    Key(&'a str),
    Index(usize),
}

fn segments(path: &str) -> Vec<Seg<'_>> {
    let mut out = Vec::new();
    for part in path.split('.').filter(|s| !s.is_empty()) {
        let (key, rest) = match part.find('[') {
            Some(i) => (&part[..i], &part[i..]),
            None => (part, ""),
        };
        if !key.is_empty() {
            out.push(Seg::Key(key));
        }
        for idx in rest.split('[').filter(|s| !s.is_empty()) {
            if let Ok(i) = idx.trim_end_matches(']').parse() {
                out.push(Seg::Index(i));
            }
        }
    }
    out
}

/// Byte offset of the deepest element of `path` that exists in a JSON text: the key of an
/// object member, the start of an array element.
fn json_span_of_path(text: &str, path: &str) -> Option<usize> {
    let target = segments(path);
    let mut scanner = JsonScanner {
        bytes: text.as_bytes(),
        at: 0,
        best: None,
    };
    scanner.value(Some(&target));
    scanner.best
}

/// Walks JSON text (already known to parse) to find where a path is written.
struct JsonScanner<'a> {
    bytes: &'a [u8],
    at: usize,
    best: Option<usize>,
}

impl JsonScanner<'_> {
    fn peek(&self) -> Option<u8> {
        self.bytes.get(self.at).copied()
    }

    fn skip_space(&mut self) {
        while self.peek().is_some_and(|b| b.is_ascii_whitespace()) {
            self.at += 1;
        }
    }

    /// Skips a string starting at its opening quote and returns its raw content.
    fn string(&mut self) -> Option<&[u8]> {
        self.at += 1;
        let start = self.at;
        loop {
            match self.peek()? {
                b'\\' => self.at += 2,
                b'"' => break,
                _ => self.at += 1,
            }
        }
        self.at += 1;
        self.bytes.get(start..self.at - 1)
    }

    /// Skips one value; `rest` is what remains of the target path inside it, if it is on it.
    fn value(&mut self, rest: Option<&[Seg<'_>]>) -> Option<()> {
        self.skip_space();
        match self.peek()? {
            b'{' => {
                self.at += 1;
                loop {
                    self.skip_space();
                    match self.peek()? {
                        b'}' => break,
                        b',' => self.at += 1,
                        _ => {
                            let key_at = self.at;
                            let key = self.string()?;
                            let inner = match rest {
                                Some([Seg::Key(k), tail @ ..]) if k.as_bytes() == key => {
                                    self.best = Some(key_at);
                                    Some(tail)
                                }
                                _ => None,
                            };
                            self.skip_space();
                            self.at += 1; // the colon
                            self.value(inner)?;
                        }
                    }
                }
                self.at += 1;
            }
            b'[' => {
                self.at += 1;
                let mut index = 0;
                loop {
                    self.skip_space();
                    match self.peek()? {
                        b']' => break,
                        b',' => {
                            self.at += 1;
                            index += 1;
                        }
                        _ => {
                            let inner = match rest {
                                Some([Seg::Index(i), tail @ ..]) if *i == index => {
                                    self.best = Some(self.at);
                                    Some(tail)
                                }
                                _ => None,
                            };
                            self.value(inner)?;
                        }
                    }
                }
                self.at += 1;
            }
            b'"' => {
                self.string()?;
            }
            _ => {
                let start = self.at;
                while self
                    .peek()
                    .is_some_and(|b| !b.is_ascii_whitespace() && !b",}]".contains(&b))
                {
                    self.at += 1;
                }
                // Not a value where one belongs: the text is not JSON, stop.
                if self.at == start {
                    return None;
                }
            }
        }
        Some(())
    }
}

/// A position inside a parsed TOML document.
#[derive(Clone, Copy)]
enum Node<'a> {
    Item(&'a toml_edit::Item),
    Table(&'a toml_edit::Table),
    Value(&'a toml_edit::Value),
}

/// The child of `node` at `seg`, with the byte offset where it is written.
fn child<'a>(node: Node<'a>, seg: &Seg<'_>) -> Option<(Option<usize>, Node<'a>)> {
    use toml_edit::{Item, Value};
    let start = |s: Option<std::ops::Range<usize>>| s.map(|r| r.start);
    match (node, seg) {
        (Node::Item(Item::Table(t)) | Node::Table(t), Seg::Key(k)) => {
            t.get_key_value(k).map(|(key, it)| (start(key.span()), Node::Item(it)))
        }
        (Node::Item(Item::ArrayOfTables(a)), Seg::Index(i)) => a.get(*i).map(|t| (start(t.span()), Node::Table(t))),
        (Node::Item(Item::Value(v)) | Node::Value(v), seg) => match (v, seg) {
            (Value::InlineTable(t), Seg::Key(k)) => {
                t.get_key_value(k).map(|(key, it)| (start(key.span()), Node::Item(it)))
            }
            (Value::Array(a), Seg::Index(i)) => a.get(*i).map(|v| (start(v.span()), Node::Value(v))),
            _ => None,
        },
        _ => None,
    }
}

/// What serde says it found in "invalid type: string \"x\", expected f64" messages.
fn unexpected_value(message: &str) -> Option<&str> {
    let rest = message
        .strip_prefix("invalid type: ")
        .or_else(|| message.strip_prefix("invalid value: "))?;
    Some(rest.split(", expected").next().unwrap_or(rest))
}

/// The path and offset of the one value under `path` that serde would describe as `found`
/// (`string "x"`, ``integer `3` ``, `sequence`, ...), if exactly one is.
fn toml_find_value(text: &str, path: &str, found: &str) -> Option<(String, usize)> {
    let doc = toml_edit::Document::parse(text).ok()?;
    let mut node = Node::Item(doc.as_item());
    for seg in segments(path) {
        node = child(node, &seg)?.1;
    }
    let mut hits = Vec::new();
    collect_values(node, path.to_string(), None, found, &mut hits);
    match hits.as_slice() {
        [one] => Some(one.clone()),
        _ => None,
    }
}

/// Every value under `node` whose serde description is `found`, with its path and offset.
fn collect_values(node: Node<'_>, path: String, at: Option<usize>, found: &str, hits: &mut Vec<(String, usize)>) {
    use toml_edit::{Item, Value};
    let key = |k: &str| {
        if path.is_empty() {
            k.to_string()
        } else {
            format!("{path}.{k}")
        }
    };
    let start = |s: Option<std::ops::Range<usize>>| s.map(|r| r.start);
    let value = match node {
        Node::Item(Item::Table(t)) | Node::Table(t) => {
            for (k, item) in t.iter() {
                let at = t.key(k).and_then(|k| start(k.span()));
                collect_values(Node::Item(item), key(k), at, found, hits);
            }
            return;
        }
        Node::Item(Item::ArrayOfTables(a)) => {
            for (i, t) in a.iter().enumerate() {
                collect_values(Node::Table(t), format!("{path}[{i}]"), start(t.span()), found, hits);
            }
            return;
        }
        Node::Item(Item::Value(v)) | Node::Value(v) => v,
        Node::Item(Item::None) => return,
    };
    let description = match value {
        Value::String(s) => format!("string {:?}", s.value()),
        Value::Integer(i) => format!("integer `{}`", i.value()),
        Value::Boolean(b) => format!("boolean `{}`", b.value()),
        Value::Float(_) | Value::Datetime(_) => String::new(),
        Value::Array(a) => {
            for (i, v) in a.iter().enumerate() {
                collect_values(Node::Value(v), format!("{path}[{i}]"), start(v.span()), found, hits);
            }
            "sequence".into()
        }
        Value::InlineTable(t) => {
            for (k, v) in t.iter() {
                let at = t.key(k).and_then(|k| start(k.span()));
                collect_values(Node::Value(v), key(k), at, found, hits);
            }
            "map".into()
        }
    };
    if description == found
        && let Some(at) = at.or_else(|| start(value.span()))
    {
        hits.push((path, at));
    }
}

/// Byte offset of the deepest element of `path` that exists in a TOML text.
fn toml_span_of_path(text: &str, path: &str) -> Option<usize> {
    let doc = toml_edit::Document::parse(text).ok()?;
    let mut node = Node::Item(doc.as_item());
    let mut best = None;
    for seg in segments(path) {
        let Some((span, next)) = child(node, &seg) else { break };
        best = span.or(best);
        node = next;
    }
    best
}

impl RobotFile {
    /// Reads and parses a robot file (TOML, or JSON by extension) within `limits`. Semantic
    /// checks happen when the robot is built ([`Robot::from_source`](crate::Robot::from_source)).
    pub fn read(path: &Path, limits: InputLimits) -> Result<(RobotFile, SourceFile)> {
        let src = SourceFile::read(path, limits)?;
        let file = src.parse()?;
        Ok((file, src))
    }

    /// The file as text for `path`: JSON for a `.json` extension, TOML otherwise.
    pub fn to_text_for(&self, path: &Path) -> Result<String> {
        let json = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("json"));
        let text = if json {
            serde_json::to_string_pretty(self)
                .map(|mut t| {
                    t.push('\n');
                    t
                })
                .map_err(|e| e.to_string())
        } else {
            toml::to_string(self).map_err(|e| e.to_string())
        };
        text.map_err(|message| Error::not_written(path, format!("cannot serialise the robot description: {message}")))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn src(text: &str) -> SourceFile {
        SourceFile {
            path: "t.toml".into(),
            text: text.into(),
            format: Format::Toml,
        }
    }

    #[test]
    fn finds_lines_of_nested_paths() {
        let s = src(
            "name = \"x\"\n\n[kinematics]\ntype = \"mdh\"\n\n[[kinematics.joints]]\nname = \"a\"\n\n[[kinematics.joints]]\nname = \"b\"\nlimits = [1, 2]\n\n[[points]]\nname = \"tool\"\nlink = { x = 1 }\n",
        );
        assert_eq!(s.line_of_path("name"), Some(1));
        assert_eq!(s.line_of_path("kinematics.type"), Some(4));
        assert_eq!(s.line_of_path("kinematics.joints[1].limits"), Some(11));
        assert_eq!(s.line_of_path("kinematics.joints[1].limits[1]"), Some(11));
        assert_eq!(s.line_of_path("kinematics.joints[0].name"), Some(7));
        assert_eq!(s.line_of_path("points[0].link.x"), Some(15));
        assert_eq!(s.line_of_path("points[0].nothing"), Some(13));
    }

    #[test]
    fn finds_lines_of_json_paths() {
        let s = SourceFile {
            path: "t.json".into(),
            text: "{\n  \"name\": \"x\",\n  \"kinematics\": {\n    \"type\": \"mdh\",\n    \"joints\": [\n      {\"name\": \"a\\\"b\"},\n      {\n        \"name\": \"b\",\n        \"limits\": [1, 2]\n      }\n    ]\n  }\n}\n".into(),
            format: Format::Json,
        };
        assert_eq!(s.line_of_path("name"), Some(2));
        assert_eq!(s.line_of_path("kinematics.type"), Some(4));
        assert_eq!(s.line_of_path("kinematics.joints[0].name"), Some(6));
        assert_eq!(s.line_of_path("kinematics.joints[1].limits[1]"), Some(9));
        assert_eq!(s.line_of_path("kinematics.joints[1].nothing"), Some(7));
        // Text that is not JSON ends the search instead of looping.
        assert_eq!(json_span_of_path("[}", "a[0]"), None);
        assert_eq!(json_span_of_path("{\"a\": [1, }", "a[1]"), Some(10));
    }
}
