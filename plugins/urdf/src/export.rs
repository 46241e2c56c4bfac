//! Writing a calibrated URDF: the robot's URDF with every joint's `<origin>` and `<axis>`
//! replaced by the identified geometry and everything else (links, inertials, meshes,
//! transmissions, comments) kept as written, so ROS and MoveIt load it under the same names.
//! The URDF parameters are URDF's own origin and axis, so every identified joint is
//! expressible without adding frames.

use std::path::{Path, PathBuf};

use armcomp_core::{Error, KinematicTree, Motion, Result, Robot};

use crate::chain::UrdfSpec;
use crate::document::{UrdfDocument, UrdfJointType};

/// The URDF text of `robot` at its current chain parameters, and the URDF file it was
/// rewritten from; the robot's kinematics must be `urdf`.
pub fn calibrated_urdf(robot: &Robot) -> Result<(PathBuf, String)> {
    // The spec is a trait object; its serialised form says which plugin it is.
    let mut value = serde_json::to_value(&robot.file.kinematics)
        .map_err(|e| Error::Input(format!("cannot read the kinematics description: {e}")))?;
    let kind = value
        .get("type")
        .and_then(|t| t.as_str())
        .unwrap_or_default()
        .to_string();
    if kind != "urdf" {
        return Err(Error::Input(format!(
            "export-urdf needs a robot whose kinematics is `type = \"urdf\"`; this one is `{kind}`"
        )));
    }
    if let Some(obj) = value.as_object_mut() {
        obj.remove("type");
    }
    let spec: UrdfSpec =
        serde_json::from_value(value).map_err(|e| Error::Input(format!("invalid urdf kinematics: {e}")))?;
    let dir = robot.source.as_deref().and_then(Path::parent).unwrap_or(Path::new("."));
    let path = dir.join(&spec.path);
    let doc = UrdfDocument::read(&path).map_err(|e| Error::Input(e.join("\n")))?;
    Ok((path, rewrite(&doc, robot.tree())))
}

/// `doc`'s text with the origins and axes of the joints of `tree` (matched by name).
pub fn rewrite(doc: &UrdfDocument, tree: &KinematicTree) -> String {
    let mut edits: Vec<(std::ops::Range<usize>, String)> = Vec::new();
    for j in &doc.joints {
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
