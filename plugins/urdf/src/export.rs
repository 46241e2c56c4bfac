//! Writing a calibrated URDF: the robot's URDF with the `<origin>` and `<axis>` of every joint
//! the model overrides replaced by the identified geometry, and everything else (other joints,
//! links, inertials, meshes, transmissions, comments) kept byte for byte, so ROS and MoveIt load
//! it under the same names. The URDF parameters are URDF's own origin and axis, so every
//! identified joint is expressible without adding frames. Each marker (the measured points,
//! whose offsets calibration identifies on their links) is added as a link of its own on a
//! fixed joint, so the exported URDF puts the measured point where the model does.

use std::path::{Path, PathBuf};

use armcomp_core::{Error, KinematicTree, Motion, Result, Robot};
use nalgebra::{Isometry3, UnitQuaternion, Vector3};
use quick_xml::escape::escape;

use crate::chain::UrdfSpec;
use crate::document::{UrdfDocument, UrdfJointType};

/// Values closer to zero than this (m or rad) are written as 0: what calibration leaves in a
/// parameter the data do not fix (a joint origin the measurement frame absorbs) is rounding,
/// and `-3.09e-11` would read as an identified offset. Zeroing moves a point by at most this
/// times the arm's length, far below any measurement.
pub const ZERO_BELOW: f64 = 1e-10;

/// A calibrated URDF and what it was made from.
#[derive(Debug, Clone)]
pub struct CalibratedUrdf {
    /// The URDF file it was rewritten from.
    pub source: PathBuf,
    /// The calibrated URDF text.
    pub text: String,
    /// The joints whose origin (and axis) were rewritten.
    pub identified: Vec<String>,
    /// The markers added as fixed joints.
    pub markers: Vec<MarkerJoint>,
    /// How many written values were below [`ZERO_BELOW`] and written as 0.
    pub zeroed: usize,
    /// Every moving joint that mimics no other, in file order, with its identified value
    /// offset relative to the source URDF ([`JointOffset`]).
    pub offsets: Vec<JointOffset>,
}

/// What a joint's identified origin turns about (or slides along) its axis relative to the
/// source URDF's: the model at joint value `q` stands where the source URDF puts the joint's
/// child at `q + offset`, as far as that turn (slide) goes; the origin's other changes (tilts,
/// shifts across the axis) only the calibrated URDF holds.
#[derive(Debug, Clone, PartialEq)]
pub struct JointOffset {
    /// The URDF joint's name.
    pub joint: String,
    /// The offset: rad about the axis for a revolute or continuous joint, m along it for a
    /// prismatic one.
    pub offset: f64,
    /// Whether the joint is prismatic (the offset in m).
    pub prismatic: bool,
}

/// A marker written as a fixed joint from its link to a new link named as the marker, or, where
/// the URDF already uses that name, the first free one of `<name>_marker`, `<name>_marker_2`, ….
#[derive(Debug, Clone)]
pub struct MarkerJoint {
    /// The marker's name in the robot file.
    pub name: String,
    /// The new link's name: `name` unless the URDF already had it.
    pub link: String,
    /// The fixed joint's name (`<link>_joint`); `None` for a marker at the origin of a link of
    /// its own name, which the URDF already holds.
    pub joint: Option<String>,
    /// The link the marker is on.
    pub parent: String,
    /// The marker in the parent link's frame (written with values below [`ZERO_BELOW`] as 0).
    pub offset: Isometry3<f64>,
}

/// The URDF text of `robot` at its current chain parameters; the robot's kinematics must be
/// `urdf`.
pub fn calibrated_urdf(robot: &Robot) -> Result<CalibratedUrdf> {
    let invalid = |reason: String| Error::InvalidArgument {
        what: "kinematics".into(),
        reason,
    };
    // The spec is a trait object; its serialised form says which plugin it is.
    let mut value = serde_json::to_value(robot.chain().spec_with(robot.chain_values()))
        .map_err(|e| invalid(format!("cannot read the description: {e}")))?;
    let kind = value
        .get("type")
        .and_then(|t| t.as_str())
        .unwrap_or_default()
        .to_string();
    if kind != "urdf" {
        return Err(invalid(format!(
            "export-urdf needs a robot whose kinematics is `type = \"urdf\"`; this one is `{kind}`"
        )));
    }
    if let Some(obj) = value.as_object_mut() {
        obj.remove("type");
    }
    let spec: UrdfSpec = serde_json::from_value(value).map_err(|e| invalid(format!("invalid urdf kinematics: {e}")))?;
    let dir = robot.source.as_deref().and_then(Path::parent).unwrap_or(Path::new("."));
    let path = dir.join(&spec.path);
    let doc = UrdfDocument::load(&path, robot.input_limits()).map_err(|issues| Error::InvalidFile {
        file: path.clone(),
        issues,
    })?;
    let identified: Vec<String> = spec.joints.iter().map(|o| o.name.clone()).collect();
    let names: Vec<&str> = identified.iter().map(String::as_str).collect();
    let mut zeroed = 0;
    let mut text = rewrite_counting(&doc, robot.tree(), &names, &mut zeroed);
    let markers = marker_joints(&doc, robot);
    let added: String = markers
        .iter()
        .filter_map(|m| {
            Some(format!(
                "  <link name=\"{}\"/>\n  <joint name=\"{}\" type=\"fixed\">\n    <parent link=\"{}\"/>\n    <child link=\"{}\"/>\n    {}\n  </joint>\n",
                escape(m.link.as_str()),
                escape(m.joint.as_deref()?),
                escape(m.parent.as_str()),
                escape(m.link.as_str()),
                origin(&m.offset, &mut zeroed)
            ))
        })
        .collect();
    // The root element's closing tag, which a URDF that parsed has.
    let end = text.rfind("</robot").ok_or_else(|| Error::InvalidArgument {
        what: path.display().to_string(),
        reason: "no closing `</robot>` to add the markers before".into(),
    })?;
    text.insert_str(end, &(added + &measurement_frames_comment(robot)));
    let offsets = joint_offsets(&doc, robot.tree());
    Ok(CalibratedUrdf {
        text,
        source: path,
        identified,
        markers,
        zeroed,
        offsets,
    })
}

/// The measurement frames as a comment: they are the tracker's, not the robot's, so no link
/// holds them, but a user of the URDF needs them to compare it with the measurements.
fn measurement_frames_comment(robot: &Robot) -> String {
    let xyz_rpy = |t: &nalgebra::Isometry3<f64>| {
        let (r, p, y) = t.rotation.euler_angles();
        let v = t.translation.vector;
        format!("xyz=\"{} {} {}\" rpy=\"{r} {p} {y}\"", v.x, v.y, v.z)
    };
    let frames: Vec<String> = match robot.stations() {
        [] => vec![format!("  measurement frame: {}", xyz_rpy(&robot.t_meas_base()))],
        stations => (stations.iter())
            .map(|s| format!("  station {}: {}", s.name.replace("--", "- -"), xyz_rpy(&s.frame)))
            .collect(),
    };
    format!(
        "  <!-- The robot base's pose in the measurement frame (the tracker's; m, rad, the URDF's \
         origin convention), which no link holds:\n{}\n  -->\n",
        frames.join("\n")
    )
}

/// The value offsets of `tree`'s joints relative to `doc`, the URDF it was built from: the
/// chain writes a revolute joint's origin rotation as `R_urdf · exp(s)` with `s` along the
/// axis and two directions across it, and a prismatic joint's origin translation as
/// `xyz_urdf + R_urdf · d`, so the offset is the axis' component of `s` (of `d`).
fn joint_offsets(doc: &UrdfDocument, tree: &KinematicTree) -> Vec<JointOffset> {
    doc.joints
        .iter()
        .filter(|j| j.kind != UrdfJointType::Fixed && j.mimic.is_none())
        .filter_map(|j| {
            let t = &tree.joints()[tree.joint_index(&j.name)?];
            let nominal = UnitQuaternion::from_euler_angles(j.rpy[0], j.rpy[1], j.rpy[2]);
            let (axis, prismatic) = match t.motion {
                Motion::Revolute(a) => (a, false),
                Motion::Prismatic(a) => (a, true),
                Motion::Fixed => return None,
            };
            let along = if prismatic {
                nominal.inverse() * (t.placement.translation.vector - Vector3::from(j.xyz))
            } else {
                (nominal.inverse() * t.placement.rotation).scaled_axis()
            };
            Some(JointOffset {
                joint: j.name.clone(),
                offset: along.dot(&axis),
                prismatic,
            })
        })
        .collect()
}

/// The markers of `robot` (its tool when it names none) as fixed joints to links of their own,
/// each named as its marker where the URDF (and the markers before it) leave that link name and
/// its `<link>_joint` free, else the first free `<name>_marker`, `<name>_marker_2`, ….
fn marker_joints(doc: &UrdfDocument, robot: &Robot) -> Vec<MarkerJoint> {
    let tree = robot.tree();
    let markers = match robot.markers() {
        [] => vec![robot.tool()],
        m => m.to_vec(),
    };
    let mut links: std::collections::HashSet<String> = doc.links.iter().map(|l| l.name.clone()).collect();
    let mut joints: std::collections::HashSet<String> = doc.joints.iter().map(|j| j.name.clone()).collect();
    let mut written = Vec::with_capacity(markers.len());
    for m in markers {
        let point = &tree.points()[m];
        let parent = tree.bodies()[point.body].name.clone();
        let at_origin = origin(&point.local, &mut 0) == origin(&Isometry3::identity(), &mut 0);
        if parent == point.name && at_origin {
            written.push(MarkerJoint {
                name: point.name.clone(),
                link: point.name.clone(),
                joint: None,
                parent,
                offset: point.local,
            });
            continue;
        }
        let free = |link: &String| !links.contains(link) && !joints.contains(&format!("{link}_joint"));
        let link = std::iter::once(point.name.clone())
            .chain(std::iter::once(format!("{}_marker", point.name)))
            .chain((2..).map(|k| format!("{}_marker_{k}", point.name)))
            .find(free)
            .expect("an unbounded list of names has one the finite URDF does not use");
        let joint = format!("{link}_joint");
        links.insert(link.clone());
        joints.insert(joint.clone());
        written.push(MarkerJoint {
            name: point.name.clone(),
            link,
            joint: Some(joint),
            parent,
            offset: point.local,
        });
    }
    written
}

/// `v`, or 0 below [`ZERO_BELOW`] (never `-0.0`), counting the non-zero values zeroed.
fn exported(v: f64, zeroed: &mut usize) -> f64 {
    if v.abs() >= ZERO_BELOW {
        return v;
    }
    if v != 0.0 {
        *zeroed += 1;
    }
    0.0
}

/// `<origin xyz=… rpy=…/>` of `p`, tiny values zeroed.
fn origin(p: &Isometry3<f64>, zeroed: &mut usize) -> String {
    let (r, pitch, y) = p.rotation.euler_angles();
    let v = p.translation.vector;
    let [x, yy, z, r, pitch, y] = [v.x, v.y, v.z, r, pitch, y].map(|v| exported(v, zeroed));
    format!("<origin xyz=\"{x:?} {yy:?} {z:?}\" rpy=\"{r:?} {pitch:?} {y:?}\"/>")
}

/// `doc`'s text with the origins and axes of the joints named `joints` taken from `tree`
/// (matched by name, values below [`ZERO_BELOW`] written as 0); every other byte as it was.
pub fn rewrite(doc: &UrdfDocument, tree: &KinematicTree, joints: &[&str]) -> String {
    rewrite_counting(doc, tree, joints, &mut 0)
}

/// [`rewrite`], counting the values written as 0 into `zeroed`.
fn rewrite_counting(doc: &UrdfDocument, tree: &KinematicTree, joints: &[&str], zeroed: &mut usize) -> String {
    let mut edits: Vec<(std::ops::Range<usize>, String)> = Vec::new();
    for j in doc.joints.iter().filter(|j| joints.contains(&j.name.as_str())) {
        let Some(t) = tree.joint_index(&j.name).map(|k| &tree.joints()[k]) else {
            continue;
        };
        // Insert missing elements just before `</joint>`.
        let close = doc.text[j.range.clone()]
            .rfind("</")
            .map_or(j.range.end, |k| j.range.start + k);
        let origin = origin(&t.placement, zeroed);
        edits.push(match &j.origin_range {
            Some(range) => (range.clone(), origin),
            None => (close..close, format!("  {origin}\n  ")),
        });
        let axis = match t.motion {
            Motion::Revolute(a) | Motion::Prismatic(a) => a,
            Motion::Fixed => continue,
        };
        debug_assert_ne!(j.kind, UrdfJointType::Fixed);
        let [x, y, z] = [axis.x, axis.y, axis.z].map(|v| exported(v, zeroed));
        let axis = format!("<axis xyz=\"{x:?} {y:?} {z:?}\"/>");
        edits.push(match &j.axis_range {
            Some(range) => (range.clone(), axis),
            None => (close..close, format!("  {axis}\n  ")),
        });
    }
    edits.sort_by_key(|(r, _)| std::cmp::Reverse(r.start));
    let mut text = doc.text.clone();
    for (range, new) in edits {
        text.replace_range(range, &new);
    }
    text
}
