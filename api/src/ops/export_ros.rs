//! `export-ros`: what a ROS 2 robot reads of a calibrated model: the calibrated URDF (checked
//! by reloading it), the joint offsets as ROS parameters, the measurement frame as a static
//! transform, and a manifest with the SHA-256 of each file and where they came from.

use std::path::Path;

use armcomp_core::Robot;
use armcomp_urdf::{CalibratedUrdf, JointOffset, robot_from_urdf};
use nalgebra::{Isometry3, Vector3};
use serde::Serialize;
use sha2::{Digest, Sha256};

use crate::error::{Error, Result};

/// The calibrated URDF's file name in the export folder.
pub const URDF_FILE: &str = "calibrated.urdf";
/// The joint offsets' file name.
pub const OFFSETS_FILE: &str = "joint_offsets.yaml";
/// The measurement frame's file name.
pub const TRANSFORM_FILE: &str = "measurement_frame.yaml";
/// The manifest's file name.
pub const MANIFEST_FILE: &str = "manifest.json";
/// How far (m) the reloaded URDF may put a link or a point from where the model puts it.
pub const RELOAD_TOLERANCE: f64 = 1e-9;

/// Whether `name` is a file an export writes (what its folder may hold).
pub fn is_export_file(name: &str) -> bool {
    [URDF_FILE, OFFSETS_FILE, TRANSFORM_FILE, MANIFEST_FILE].contains(&name)
}

/// The configurations the reloaded URDF is checked at.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CheckedAt {
    /// The joint values of a measurement file's rows.
    Measured {
        /// The measurement file as given.
        file: String,
        /// Its SHA-256 (hex).
        sha256: String,
        /// The rows read.
        rows: usize,
    },
    /// Configurations drawn at random inside the joint limits.
    Sampled {
        /// How many.
        n: usize,
        /// The seed they were drawn with.
        seed: u64,
    },
}

/// An export, checked and ready to be written.
#[derive(Debug, Clone)]
pub struct RosExport {
    /// The files (name in the folder, bytes), the manifest last.
    pub files: Vec<(String, Vec<u8>)>,
    /// The joint offsets written.
    pub offsets: Vec<JointOffset>,
    /// The largest distance (m) between a link or point of the reloaded URDF and the model's.
    pub reload_deviation: f64,
    /// The largest distance (m) between the source URDF's tool and markers at the joint values
    /// plus the offsets and the model's: what using the offsets with the source URDF misses.
    pub offsets_only_deviation: f64,
    /// How many configurations both were checked at.
    pub configurations: usize,
    /// The robot base in the measurement frame.
    pub t_meas_base: Isometry3<f64>,
}

/// The SHA-256 of `bytes` in lower-case hex.
pub fn sha256_hex(bytes: &[u8]) -> String {
    Sha256::digest(bytes).iter().map(|b| format!("{b:02x}")).collect()
}

/// Builds and checks the export of `robot` (read from `model_file`, whose bytes are
/// `model_bytes`): `urdf` is its calibrated URDF ([`armcomp_urdf::calibrated_urdf`]),
/// `reference` the model the URDF must reproduce (`robot` itself, or its rigid geometry when
/// the URDF drops error models), `configurations` where to compare them and `checked` what
/// they are. The URDF is written into a temporary folder beside `out` (the export's folder,
/// which this does not write) and read back from there as a bare URDF; an export whose reload
/// moves a link or point by more than [`RELOAD_TOLERANCE`] is refused. `measurement_frame`
/// names the tracker's frame in the static transform.
#[allow(clippy::too_many_arguments)] // each is a distinct input the manifest records
pub fn export(
    robot: &Robot,
    reference: &Robot,
    urdf: &CalibratedUrdf,
    model_file: &Path,
    model_bytes: &[u8],
    configurations: &[Vec<f64>],
    checked: CheckedAt,
    measurement_frame: &str,
    out: &Path,
) -> Result<RosExport> {
    let parent = match out.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let staging = tempfile::Builder::new()
        .prefix(".armcomp-export-check.")
        .tempdir_in(parent)
        .map_err(|e| io_error(parent, &e))?;
    let staged = staging.path().join(URDF_FILE);
    std::fs::write(&staged, urdf.text.as_bytes()).map_err(|e| io_error(&staged, &e))?;
    let reloaded = robot_from_urdf(&staged, robot.input_limits())?;
    let reload_deviation = largest_distance(reference, &reloaded, configurations, &[])?;
    if reload_deviation > RELOAD_TOLERANCE {
        return Err(Error::ReloadMismatch {
            deviation: reload_deviation,
            tolerance: RELOAD_TOLERANCE,
            configurations: configurations.len(),
        });
    }
    let source = robot_from_urdf(&urdf.source, robot.input_limits())?;
    let offsets_only_deviation = largest_distance(reference, &source, configurations, &urdf.offsets)?;
    let t_meas_base = robot.t_meas_base();
    let base = robot.tree().bodies()[0].name.clone();
    let source_name = urdf
        .source
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let mut files = vec![
        (URDF_FILE.to_string(), urdf.text.clone().into_bytes()),
        (
            OFFSETS_FILE.to_string(),
            offsets_yaml(&urdf.offsets, &source_name)?.into_bytes(),
        ),
        (
            TRANSFORM_FILE.to_string(),
            transform_yaml(&t_meas_base, measurement_frame, &base)?.into_bytes(),
        ),
    ];
    let source_bytes = armcomp_core::support::io::read_bytes(&urdf.source, robot.input_limits())?;
    let manifest = Manifest {
        armcomp: env!("CARGO_PKG_VERSION"),
        model: FileHash {
            file: model_file.display().to_string(),
            sha256: sha256_hex(model_bytes),
        },
        source_urdf: FileHash {
            file: urdf.source.display().to_string(),
            sha256: sha256_hex(&source_bytes),
        },
        fitted_on: "unknown: the model file does not record the data it was fitted on",
        reload_check: ReloadCheck {
            at: checked,
            configurations: configurations.len(),
            max_deviation_m: reload_deviation,
            tolerance_m: RELOAD_TOLERANCE,
        },
        offsets_only_max_deviation_m: offsets_only_deviation,
        files: files
            .iter()
            .map(|(name, bytes)| FileHash {
                file: name.clone(),
                sha256: sha256_hex(bytes),
            })
            .collect(),
    };
    let mut text = serde_json::to_string_pretty(&manifest).map_err(|e| {
        Error::Core(armcomp_core::Error::InvalidArgument {
            what: "manifest".into(),
            reason: e.to_string(),
        })
    })?;
    text.push('\n');
    files.push((MANIFEST_FILE.to_string(), text.into_bytes()));
    Ok(RosExport {
        files,
        offsets: urdf.offsets.clone(),
        reload_deviation,
        offsets_only_deviation,
        configurations: configurations.len(),
        t_meas_base,
    })
}

fn io_error(path: &Path, e: &std::io::Error) -> Error {
    Error::Core(armcomp_core::Error::Io {
        path: path.to_path_buf(),
        kind: e.kind(),
        os_code: e.raw_os_error(),
        message: e.to_string(),
    })
}

#[derive(Serialize)]
struct FileHash {
    file: String,
    sha256: String,
}

#[derive(Serialize)]
struct ReloadCheck {
    at: CheckedAt,
    configurations: usize,
    max_deviation_m: f64,
    tolerance_m: f64,
}

#[derive(Serialize)]
struct Manifest {
    armcomp: &'static str,
    model: FileHash,
    source_urdf: FileHash,
    fitted_on: &'static str,
    reload_check: ReloadCheck,
    offsets_only_max_deviation_m: f64,
    files: Vec<FileHash>,
}

/// The largest distance (m, base frame) over `configurations` between `reference`'s links,
/// tool and markers and the links and points of the same names of `other`, a bare URDF robot,
/// at the same joint values (matched by name) plus `offsets`. With offsets, only the links carrying
/// the tool and markers are compared (the source URDF has no marker links): what an
/// offsets-only deployment misses.
fn largest_distance(
    reference: &Robot,
    other: &Robot,
    configurations: &[Vec<f64>],
    offsets: &[JointOffset],
) -> Result<f64> {
    let tree = reference.tree();
    let names = tree.coordinate_names();
    let other_names = other.tree().coordinate_names();
    let mut mapping = Vec::with_capacity(other_names.len());
    for name in other_names {
        let Some(k) = names.iter().position(|n| n == name) else {
            return Err(Error::Core(armcomp_core::Error::InvalidArgument {
                what: format!("URDF joint `{name}`"),
                reason: format!("moves in the URDF but is no joint of `{}`", reference.name()),
            }));
        };
        let offset = offsets.iter().find(|o| &o.joint == name).map_or(0.0, |o| o.offset);
        mapping.push((k, offset));
    }
    let point_of = |robot: &Robot, name: &str| robot.tree().points().iter().position(|p| p.name == name);
    let mut markers: Vec<usize> = reference.markers().to_vec();
    markers.push(reference.tool());
    let carrying: Vec<usize> = markers.iter().map(|&m| tree.points()[m].body).collect();
    // (the reference's point, or body, and the other's point of its name)
    let mut compared: Vec<(Compared, usize)> = Vec::new();
    if offsets.is_empty() {
        for &m in &markers {
            let name = &tree.points()[m].name;
            let Some(o) = point_of(other, name) else {
                return Err(Error::Core(armcomp_core::Error::InvalidArgument {
                    what: format!("point `{name}`"),
                    reason: "has no link of its name in the exported URDF".into(),
                }));
            };
            compared.push((Compared::Point(m), o));
        }
    }
    for (b, body) in tree.bodies().iter().enumerate() {
        if (offsets.is_empty() || carrying.contains(&b))
            && let Some(o) = point_of(other, &body.name)
        {
            compared.push((Compared::Body(b), o));
        }
    }
    let mut largest = 0.0f64;
    let mut q_other = vec![0.0; other_names.len()];
    for q in configurations {
        for (v, (k, offset)) in q_other.iter_mut().zip(&mapping) {
            *v = q[*k] + offset;
        }
        let at = reference.forward(q)?;
        let there = other.forward(&q_other)?;
        for &(here, o) in &compared {
            let here: Vector3<f64> = match here {
                Compared::Point(p) => at.point[p].translation.vector,
                Compared::Body(b) => at.body[b].translation.vector,
            };
            largest = largest.max((here - there.point[o].translation.vector).norm());
        }
    }
    Ok(largest)
}

/// What of the reference model is compared.
#[derive(Clone, Copy)]
enum Compared {
    /// A point (the tool, a marker).
    Point(usize),
    /// A body's origin (a URDF link's frame).
    Body(usize),
}

/// ROS 2 parameters for every node (`/**`): `joint_offsets.names` and
/// `joint_offsets.values` (rad, m for prismatic joints), in the same order.
#[derive(Serialize)]
struct OffsetsFile<'a> {
    #[serde(rename = "/**")]
    all_nodes: OffsetsNode<'a>,
}

#[derive(Serialize)]
struct OffsetsNode<'a> {
    #[serde(rename = "ros__parameters")]
    parameters: OffsetsParameters<'a>,
}

#[derive(Serialize)]
struct OffsetsParameters<'a> {
    joint_offsets: OffsetsTable<'a>,
}

#[derive(Serialize)]
struct OffsetsTable<'a> {
    names: Vec<&'a str>,
    values: Vec<f64>,
    units: Vec<&'static str>,
}

fn yaml_error(e: serde_norway::Error) -> Error {
    Error::Core(armcomp_core::Error::InvalidArgument {
        what: "YAML".into(),
        reason: e.to_string(),
    })
}

/// The joint offsets as a ROS 2 parameter file, with a comment on what they mean.
fn offsets_yaml(offsets: &[JointOffset], source: &str) -> Result<String> {
    let file = OffsetsFile {
        all_nodes: OffsetsNode {
            parameters: OffsetsParameters {
                joint_offsets: OffsetsTable {
                    names: offsets.iter().map(|o| o.joint.as_str()).collect(),
                    values: offsets.iter().map(|o| o.offset).collect(),
                    units: offsets.iter().map(|o| if o.prismatic { "m" } else { "rad" }).collect(),
                },
            },
        },
    };
    let body = serde_norway::to_string(&file).map_err(yaml_error)?;
    Ok(format!(
        "# Joint offsets identified by armcomp relative to {source} (rad; m for prismatic joints).\n\
         # With that URDF: position = encoder + offset, encoder command = command - offset.\n\
         # Not with calibrated.urdf, whose joint origins already hold them.\n{body}"
    ))
}

#[derive(Serialize)]
struct TransformFile<'a> {
    static_transform: Transform<'a>,
}

#[derive(Serialize)]
struct Transform<'a> {
    frame_id: &'a str,
    child_frame_id: &'a str,
    translation: [f64; 3],
    rotation_xyzw: [f64; 4],
    arguments: Vec<String>,
}

/// The robot base in the measurement frame as a static transform: its parts, and the
/// `static_transform_publisher` arguments `x y z qx qy qz qw frame_id child_frame_id`.
fn transform_yaml(t_meas_base: &Isometry3<f64>, frame: &str, base: &str) -> Result<String> {
    let v = t_meas_base.translation.vector;
    let q = t_meas_base.rotation.quaternion();
    // One of the two quaternions of the rotation: the one with w >= 0.
    let sign = if q.w < 0.0 { -1.0 } else { 1.0 };
    let rotation = [q.i, q.j, q.k, q.w].map(|c| sign * c + 0.0);
    let translation = [v.x, v.y, v.z].map(|c| c + 0.0);
    let mut arguments: Vec<String> = translation.iter().chain(&rotation).map(|c| format!("{c:?}")).collect();
    arguments.extend([frame.to_string(), base.to_string()]);
    let file = TransformFile {
        static_transform: Transform {
            frame_id: frame,
            child_frame_id: base,
            translation,
            rotation_xyzw: rotation,
            arguments,
        },
    };
    let body = serde_norway::to_string(&file).map_err(yaml_error)?;
    Ok(format!(
        "# The robot base `{base}` in the measurement frame `{frame}` as calibration identified it (m).\n\
         # ros2 run tf2_ros static_transform_publisher <arguments>, or Node(package='tf2_ros',\n\
         # executable='static_transform_publisher', arguments=[...]) in a launch file.\n{body}"
    ))
}
