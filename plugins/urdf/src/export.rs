//! Writing a calibrated URDF: the robot's URDF with the `<origin>` and `<axis>` of every joint
//! the model overrides replaced by the identified geometry, and everything else (other joints,
//! links, inertials, meshes, transmissions, comments) kept byte for byte, so ROS and MoveIt load
//! it under the same names. The URDF parameters are URDF's own origin and axis, so every
//! identified joint is expressible without adding frames.

use std::path::{Path, PathBuf};

use armcomp_core::{Error, KinematicTree, Motion, Result, Robot};

use crate::chain::UrdfSpec;
use crate::document::{UrdfDocument, UrdfJointType};

/// A calibrated URDF and what it was made from.
#[derive(Debug, Clone)]
pub struct CalibratedUrdf {
    /// The URDF file it was rewritten from.
    pub source: PathBuf,
    /// The calibrated URDF text.
    pub text: String,
    /// The joints whose origin (and axis) were rewritten.
    pub identified: Vec<String>,
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
    let doc = UrdfDocument::load(&path).map_err(|issues| Error::InvalidFile {
        file: path.clone(),
        issues,
    })?;
    let identified: Vec<String> = spec.joints.iter().map(|o| o.name.clone()).collect();
    let names: Vec<&str> = identified.iter().map(String::as_str).collect();
    Ok(CalibratedUrdf {
        text: rewrite(&doc, robot.tree(), &names),
        source: path,
        identified,
    })
}

/// `doc`'s text with the origins and axes of the joints named `joints` taken from `tree`
/// (matched by name); every other byte as it was.
pub fn rewrite(doc: &UrdfDocument, tree: &KinematicTree, joints: &[&str]) -> String {
    let mut edits: Vec<(std::ops::Range<usize>, String)> = Vec::new();
    for j in doc.joints.iter().filter(|j| joints.contains(&j.name.as_str())) {
        let Some(t) = tree.joint_index(&j.name).map(|k| &tree.joints()[k]) else {
            continue;
        };
        // Insert missing elements just before `</joint>`.
        let close = doc.text[j.range.clone()]
            .rfind("</")
            .map_or(j.range.end, |k| j.range.start + k);
        let p = t.placement;
        let (r, pitch, y) = p.rotation.euler_angles();
        let v = p.translation.vector;
        let origin = format!(
            "<origin xyz=\"{:?} {:?} {:?}\" rpy=\"{r:?} {pitch:?} {y:?}\"/>",
            v.x, v.y, v.z
        );
        edits.push(match &j.origin_range {
            Some(range) => (range.clone(), origin),
            None => (close..close, format!("  {origin}\n  ")),
        });
        let axis = match t.motion {
            Motion::Revolute(a) | Motion::Prismatic(a) => a,
            Motion::Fixed => continue,
        };
        debug_assert_ne!(j.kind, UrdfJointType::Fixed);
        let axis = format!("<axis xyz=\"{:?} {:?} {:?}\"/>", axis.x, axis.y, axis.z);
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
