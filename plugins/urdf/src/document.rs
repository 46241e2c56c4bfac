//! Reading a URDF file: the XML checked element by element (so every problem names the joint or
//! link and its line), the values read with `urdf-rs`, and the tree's topology resolved.

use std::ops::Range;
use std::path::{Path, PathBuf};

use armcomp_core::shape::Shape;
use nalgebra::Isometry3;

use crate::mesh::{MeshOutcome, mesh_bounding_box};

/// How a URDF joint moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UrdfJointType {
    /// Rotation within limits.
    Revolute,
    /// Rotation without limits.
    Continuous,
    /// Translation within limits.
    Prismatic,
    /// No motion.
    Fixed,
}

/// One `<joint>` as read, SI.
#[derive(Debug, Clone)]
pub struct UrdfJoint {
    /// The `name` attribute.
    pub name: String,
    /// 1-based line of the element.
    pub line: usize,
    /// Its type.
    pub kind: UrdfJointType,
    /// Parent link name.
    pub parent: String,
    /// Child link name.
    pub child: String,
    /// Origin translation (m).
    pub xyz: [f64; 3],
    /// Origin roll, pitch, yaw (rad).
    pub rpy: [f64; 3],
    /// Axis in the joint frame (not normalised; non-zero for moving joints).
    pub axis: [f64; 3],
    /// `[lower, upper]` (rad or m) when the file gives finite limits.
    pub limits: Option<[f64; 2]>,
    /// `(followed joint, multiplier, offset)`.
    pub mimic: Option<(String, f64, f64)>,
    /// Byte range of the whole element, and of its `<origin>` and `<axis>` children.
    pub range: Range<usize>,
    /// Byte range of the `<origin>` element, when present.
    pub origin_range: Option<Range<usize>>,
    /// Byte range of the `<axis>` element, when present.
    pub axis_range: Option<Range<usize>>,
}

/// One `<link>` as read, SI, in the link frame.
#[derive(Debug, Clone)]
pub struct UrdfLink {
    /// The `name` attribute.
    pub name: String,
    /// 1-based line of the element.
    pub line: usize,
    /// Mass (kg) and centre of mass (m), when the link has an `<inertial>`.
    pub inertial: Option<(f64, [f64; 3])>,
    /// Collision shapes (meshes as their bounding boxes).
    pub collisions: Vec<(Isometry3<f64>, Shape)>,
}

/// A URDF robot, checked: one root, every joint's links exist, no loop.
#[derive(Debug, Clone)]
pub struct UrdfDocument {
    /// The file.
    pub path: PathBuf,
    /// Its text, kept for writing calibrated copies.
    pub text: String,
    /// The `<robot name>`.
    pub name: String,
    /// The root link (child of no joint).
    pub root: String,
    /// Links in file order.
    pub links: Vec<UrdfLink>,
    /// Joints in file order.
    pub joints: Vec<UrdfJoint>,
    /// What was skipped (meshes that cannot be found or read).
    pub warnings: Vec<String>,
}

impl UrdfDocument {
    /// Reads and checks a URDF file. Every problem is one message naming the file, the line and
    /// the element.
    pub fn read(path: &Path) -> Result<UrdfDocument, Vec<String>> {
        let text = armcomp_core::io::read_text(path).map_err(|e| vec![e.to_string()])?;
        UrdfDocument::parse(path, text)
    }

    /// Checks and reads URDF `text`; `path` names it in messages and resolves mesh files.
    pub fn parse(path: &Path, text: String) -> Result<UrdfDocument, Vec<String>> {
        let file = path.display().to_string();
        let xml = roxmltree::Document::parse(&text).map_err(|e| vec![format!("{file}: malformed XML: {e}")])?;
        let mut errors = Vec::new();
        let line_of = |n: roxmltree::Node<'_, '_>| xml.text_pos_at(n.range().start).row as usize;
        let robot_el = xml.root_element();
        if !robot_el.has_tag_name("robot") {
            return Err(vec![format!(
                "{file}:{}: expected a <robot> element at the top, found <{}>",
                line_of(robot_el),
                robot_el.tag_name().name()
            )]);
        }
        // Element-level checks with lines; urdf-rs reports neither line nor element.
        let mut joint_nodes = Vec::new();
        let mut link_nodes = Vec::new();
        for el in robot_el.children().filter(|n| n.is_element()) {
            let what = el.tag_name().name();
            if what != "joint" && what != "link" {
                continue;
            }
            let line = line_of(el);
            let Some(name) = el.attribute("name").filter(|n| !n.trim().is_empty()) else {
                errors.push(format!("{file}:{line}: <{what}> without a `name`"));
                continue;
            };
            let at = format!("{file}:{line}: {what} `{name}`");
            if what == "joint" {
                check_joint(el, &at, &mut errors);
                joint_nodes.push(el);
            } else {
                for sub in el.children().filter(|n| n.is_element()) {
                    let tag = sub.tag_name().name();
                    for o in sub.children().filter(|n| n.has_tag_name("origin")) {
                        check_origin(o, &format!("{at}: <{tag}>"), &mut errors);
                    }
                    if tag == "inertial" {
                        check_numbers(sub, "mass", "value", 1, &format!("{at}: <inertial>"), &mut errors);
                    }
                }
                link_nodes.push(el);
            }
        }
        if !errors.is_empty() {
            return Err(errors);
        }
        let robot = urdf_rs::read_from_string(&text).map_err(|e| vec![format!("{file}: not a valid URDF: {e}")])?;
        if robot.links.len() != link_nodes.len() || robot.joints.len() != joint_nodes.len() {
            return Err(vec![format!(
                "{file}: the URDF reader saw {} links and {} joints where the XML has {} and {}",
                robot.links.len(),
                robot.joints.len(),
                link_nodes.len(),
                joint_nodes.len()
            )]);
        }

        let dir = path.parent().unwrap_or(Path::new("."));
        let mut warnings = Vec::new();
        let mut links = Vec::new();
        for (l, node) in robot.links.iter().zip(&link_nodes) {
            let line = line_of(*node);
            let at = format!("{file}:{line}: link `{}`", l.name);
            if links.iter().any(|k: &UrdfLink| k.name == l.name) {
                errors.push(format!("{at}: a link of this name is defined twice"));
            }
            let inertial = node.children().any(|n| n.has_tag_name("inertial")).then(|| {
                let m = l.inertial.mass.value;
                if !(m.is_finite() && m >= 0.0) {
                    errors.push(format!("{at}: <inertial>: expected a mass of zero or more kg, got {m}"));
                }
                (m, l.inertial.origin.xyz.0)
            });
            let mut collisions = Vec::new();
            for c in &l.collision {
                let origin = armcomp_core::geom::xyz_rpy(c.origin.xyz.0, c.origin.rpy.0);
                match collision_shape(&c.geometry, dir) {
                    Ok(MeshOutcome::Shape(pose, shape, note)) => {
                        if let Some(n) = note {
                            warnings.push(format!("{at}: {n}"));
                        }
                        collisions.push((origin * pose, shape));
                    }
                    Ok(MeshOutcome::Skipped(why)) => warnings.push(format!("{at}: collision mesh skipped: {why}")),
                    Err(e) => errors.push(format!("{at}: <collision>: {e}")),
                }
            }
            links.push(UrdfLink {
                name: l.name.clone(),
                line,
                inertial,
                collisions,
            });
        }

        let mut joints = Vec::new();
        for (j, node) in robot.joints.iter().zip(&joint_nodes) {
            let line = line_of(*node);
            let at = format!("{file}:{line}: joint `{}`", j.name);
            if joints.iter().any(|k: &UrdfJoint| k.name == j.name) {
                errors.push(format!("{at}: a joint of this name is defined twice"));
            }
            let kind = match j.joint_type {
                urdf_rs::JointType::Revolute => UrdfJointType::Revolute,
                urdf_rs::JointType::Continuous => UrdfJointType::Continuous,
                urdf_rs::JointType::Prismatic => UrdfJointType::Prismatic,
                urdf_rs::JointType::Fixed => UrdfJointType::Fixed,
                ref other => {
                    errors.push(format!(
                        "{at}: type `{other:?}` is not supported; expected revolute, continuous, prismatic or fixed"
                    ));
                    continue;
                }
            };
            for (role, link) in [("parent", &j.parent.link), ("child", &j.child.link)] {
                if !links.iter().any(|l| &l.name == link) {
                    errors.push(format!("{at}: its {role} link `{link}` is not defined in the file"));
                }
            }
            let moving = kind != UrdfJointType::Fixed;
            let axis = j.axis.xyz.0;
            if moving && axis.iter().map(|v| v * v).sum::<f64>().sqrt() < 1e-12 {
                errors.push(format!("{at}: <axis xyz>: expected a non-zero direction"));
            }
            let has_limit = node.children().any(|n| n.has_tag_name("limit"));
            let limits = (has_limit && matches!(kind, UrdfJointType::Revolute | UrdfJointType::Prismatic))
                .then_some([j.limit.lower, j.limit.upper])
                .filter(|l| l.iter().all(|v| v.is_finite()));
            if let Some([lo, hi]) = limits
                && lo > hi
            {
                errors.push(format!("{at}: <limit>: lower {lo} is above upper {hi}"));
            }
            // ROS (urdfdom, pinocchio) ignores `<mimic>` on a fixed joint: it has nothing to move.
            let mimic = j
                .mimic
                .as_ref()
                .filter(|_| moving)
                .map(|m| (m.joint.clone(), m.multiplier.unwrap_or(1.0), m.offset.unwrap_or(0.0)));
            let child_range = |tag: &str| node.children().find(|n| n.has_tag_name(tag)).map(|n| n.range());
            joints.push(UrdfJoint {
                name: j.name.clone(),
                line,
                kind,
                parent: j.parent.link.clone(),
                child: j.child.link.clone(),
                xyz: j.origin.xyz.0,
                rpy: j.origin.rpy.0,
                axis,
                limits,
                mimic,
                range: node.range(),
                origin_range: child_range("origin"),
                axis_range: child_range("axis"),
            });
        }
        for j in &joints {
            let at = format!("{file}:{}: joint `{}`", j.line, j.name);
            if let Some((target, k, off)) = &j.mimic {
                match joints.iter().find(|o| &o.name == target) {
                    None => errors.push(format!("{at}: <mimic joint=\"{target}\">: no joint of that name")),
                    Some(o) if o.mimic.is_some() || o.kind == UrdfJointType::Fixed => errors.push(format!(
                        "{at}: <mimic joint=\"{target}\">: that joint is fixed or itself a mimic joint"
                    )),
                    Some(_) if !(k.is_finite() && off.is_finite()) => {
                        errors.push(format!("{at}: <mimic>: expected finite multiplier and offset"))
                    }
                    Some(_) => {}
                }
            }
            if let Some(other) = joints.iter().find(|o| o.child == j.child && o.name != j.name) {
                errors.push(format!(
                    "{at}: link `{}` is also the child of joint `{}` (line {}): a closed kinematic loop, which URDF cannot describe",
                    j.child, other.name, other.line
                ));
            }
        }
        let roots: Vec<&str> = links
            .iter()
            .filter(|l| !joints.iter().any(|j| j.child == l.name))
            .map(|l| l.name.as_str())
            .collect();
        let root = match roots.as_slice() {
            [one] => one.to_string(),
            [] if links.is_empty() => {
                errors.push(format!("{file}: the robot has no <link>"));
                String::new()
            }
            [] => {
                errors.push(format!(
                    "{file}: every link is the child of a joint, so the joints form a closed loop; a URDF robot is a tree with one root link"
                ));
                String::new()
            }
            many => {
                errors.push(format!(
                    "{file}: several links are the child of no joint ({}); a URDF robot is a tree with one root link",
                    many.join(", ")
                ));
                String::new()
            }
        };
        if !errors.is_empty() {
            return Err(errors);
        }
        Ok(UrdfDocument {
            path: path.to_path_buf(),
            name: robot.name,
            root,
            links,
            joints,
            warnings,
            text,
        })
    }

    /// The joints in an order where each joint's parent link, and the joint it mimics, come
    /// first: file order wherever the file allows it. Fails on joints unreachable from the root
    /// (a loop) or mimicking a joint below themselves.
    pub fn placement_order(&self) -> Result<Vec<usize>, Vec<String>> {
        let mut placed_links = vec![self.root.as_str()];
        let mut placed = vec![false; self.joints.len()];
        let mut order = Vec::with_capacity(self.joints.len());
        while order.len() < self.joints.len() {
            let next = self.joints.iter().enumerate().position(|(i, j)| {
                !placed[i]
                    && placed_links.contains(&j.parent.as_str())
                    && j.mimic.as_ref().is_none_or(|(t, _, _)| {
                        self.joints.iter().position(|o| &o.name == t).is_some_and(|k| placed[k])
                    })
            });
            let Some(i) = next else {
                return Err(self
                    .joints
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| !placed[*i])
                    .map(|(_, j)| {
                        format!(
                            "{}:{}: joint `{}`: not reachable from the root link `{}` (its parent link `{}` hangs in a closed loop, or it mimics a joint below itself)",
                            self.path.display(),
                            j.line,
                            j.name,
                            self.root,
                            j.parent
                        )
                    })
                    .collect());
            };
            placed[i] = true;
            placed_links.push(&self.joints[i].child);
            order.push(i);
        }
        Ok(order)
    }
}

/// The shape of a `<collision>` geometry; meshes become bounding boxes.
fn collision_shape(g: &urdf_rs::Geometry, dir: &Path) -> Result<MeshOutcome, String> {
    let positive = |what: &str, v: f64| {
        if v.is_finite() && v > 0.0 {
            Ok(v)
        } else {
            Err(format!("{what}: expected a positive length in m, got {v}"))
        }
    };
    let shape = match g {
        urdf_rs::Geometry::Box { size } => Shape::Box([
            positive("<box size>", size[0])?,
            positive("<box size>", size[1])?,
            positive("<box size>", size[2])?,
        ]),
        urdf_rs::Geometry::Cylinder { radius, length } => Shape::Cylinder {
            radius: positive("<cylinder radius>", *radius)?,
            length: positive("<cylinder length>", *length)?,
        },
        urdf_rs::Geometry::Capsule { radius, length } => Shape::Capsule {
            radius: positive("<capsule radius>", *radius)?,
            length: positive("<capsule length>", *length)?,
        },
        urdf_rs::Geometry::Sphere { radius } => Shape::Sphere(positive("<sphere radius>", *radius)?),
        urdf_rs::Geometry::Mesh { filename, scale } => {
            let scale = scale.map_or([1.0; 3], |s| s.0);
            return mesh_bounding_box(filename, scale, dir);
        }
    };
    Ok(MeshOutcome::Shape(Isometry3::identity(), shape, None))
}

/// Checks a joint element: type, origin, parent, child, axis, limit and mimic attributes.
fn check_joint(el: roxmltree::Node<'_, '_>, at: &str, errors: &mut Vec<String>) {
    match el.attribute("type") {
        Some("revolute" | "continuous" | "prismatic" | "fixed") => {}
        Some(t @ ("floating" | "planar" | "spherical")) => errors.push(format!(
            "{at}: type `{t}` is not supported; expected revolute, continuous, prismatic or fixed"
        )),
        Some(t) => errors.push(format!(
            "{at}: unknown joint type `{t}`; expected revolute, continuous, prismatic or fixed"
        )),
        None => errors.push(format!("{at}: missing `type`")),
    }
    for role in ["parent", "child"] {
        let found = el.children().find(|n| n.has_tag_name(role));
        if found
            .and_then(|n| n.attribute("link"))
            .is_none_or(|l| l.trim().is_empty())
        {
            errors.push(format!("{at}: expected <{role} link=\"...\"/>"));
        }
    }
    for o in el.children().filter(|n| n.has_tag_name("origin")) {
        check_origin(o, at, errors);
    }
    check_numbers(el, "axis", "xyz", 3, at, errors);
    check_numbers(el, "limit", "lower", 1, at, errors);
    check_numbers(el, "limit", "upper", 1, at, errors);
    check_numbers(el, "mimic", "multiplier", 1, at, errors);
    check_numbers(el, "mimic", "offset", 1, at, errors);
    if let Some(m) = el.children().find(|n| n.has_tag_name("mimic"))
        && m.attribute("joint").is_none_or(|j| j.trim().is_empty())
    {
        errors.push(format!("{at}: <mimic> without the `joint` it follows"));
    }
}

fn check_origin(o: roxmltree::Node<'_, '_>, at: &str, errors: &mut Vec<String>) {
    for attr in ["xyz", "rpy"] {
        if let Some(v) = o.attribute(attr) {
            check_list(v, 3, &format!("{at}: <origin {attr}>"), errors);
        }
    }
}

/// Checks `<child attr="...">` of `el`, when present, holds `n` finite numbers.
fn check_numbers(el: roxmltree::Node<'_, '_>, child: &str, attr: &str, n: usize, at: &str, errors: &mut Vec<String>) {
    for c in el.children().filter(|c| c.has_tag_name(child)) {
        if let Some(v) = c.attribute(attr) {
            check_list(v, n, &format!("{at}: <{child} {attr}>"), errors);
        }
    }
}

fn check_list(v: &str, n: usize, at: &str, errors: &mut Vec<String>) {
    let parts: Vec<&str> = v.split_whitespace().collect();
    let ok = parts.len() == n && parts.iter().all(|p| p.parse::<f64>().is_ok_and(f64::is_finite));
    if !ok {
        errors.push(format!("{at}: expected {n} finite number(s), got \"{v}\""));
    }
}
