//! Reading a URDF file: the XML checked element by element (so every problem names the joint or
//! link and its line), the values read with `urdf-rs`, and the tree's topology resolved.
//!
//! Every file ROS reads (urdfdom, and pinocchio on it) is read here too: elements that carry no
//! kinematics (`<gazebo>`, `<transmission>`, `<ros2_control>`, sensors, visuals, materials, any
//! unknown tag) are ignored; joints of type `floating` and `planar` are read as fixed at their
//! origin (their neutral pose: a calibrated arm does not move them); a `<mimic>` on a fixed
//! joint is ignored, as ROS does, and one that names no moving joint is ignored so that the joint
//! moves on its own, as pinocchio reads it; a mimic of a mimic joint follows the joint at the end
//! of the chain. What was ignored or skipped is reported as warnings, one line per kind.

use std::collections::{HashMap, HashSet};
use std::ops::Range;
use std::path::{Path, PathBuf};

use armcomp_core::Issue;
use armcomp_core::model::param::Quantity;
use armcomp_core::model::shape::Shape;
use armcomp_core::support::io::InputLimits;
use armcomp_core::support::limits::{self, Cost};
use nalgebra::Isometry3;
use roxmltree::Node;

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
    /// No motion; also `floating` and `planar` joints, held at their origin.
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
    /// `(followed joint, multiplier, offset)`; the followed joint moves and mimics none.
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
    /// What was ignored or skipped (meshes that cannot be found or read), one line per kind.
    pub warnings: Vec<String>,
}

impl UrdfDocument {
    /// Reads and checks a URDF file. Every problem is one message naming the file, the line and
    /// the element. It and its meshes are read within `limits`.
    pub fn read(path: &Path, limits: InputLimits) -> Result<UrdfDocument, Vec<String>> {
        UrdfDocument::load(path, limits).map_err(|issues| in_file(path, &issues))
    }

    /// Reads and checks a URDF file. Every problem names its line (when it has one) and its
    /// element, but not the file: an [`armcomp_core::Error::InvalidFile`] of `path` holds them.
    /// It and its meshes are read within `limits`.
    pub fn load(path: &Path, limits: InputLimits) -> Result<UrdfDocument, Vec<Issue>> {
        let text = armcomp_core::support::io::read_text(path, limits).map_err(|e| {
            // The issue is reported within the file, which it need not name again.
            vec![match e {
                armcomp_core::Error::InputAt { location, message, .. } => Issue {
                    line: location.line,
                    ..Issue::new("", message)
                },
                other => Issue::new("", other.to_string()),
            }]
        })?;
        UrdfDocument::parse(path, text, limits)
    }

    /// Checks and reads URDF `text`; `path` names it in warnings and resolves mesh files, which
    /// are read within `limits`.
    pub fn parse(path: &Path, text: String, limits: InputLimits) -> Result<UrdfDocument, Vec<Issue>> {
        let file = path.display().to_string();
        let xml = roxmltree::Document::parse(&text)
            .map_err(|e| vec![at_line(e.pos().row as usize, format!("malformed XML: {e}"))])?;
        let line_starts = std::iter::once(0)
            .chain(text.match_indices('\n').map(|(k, _)| k + 1))
            .collect();
        let mut reading = Reading {
            xml: &xml,
            line_starts,
            errors: Vec::new(),
            warnings: Tally::default(),
            limits,
        };
        let robot_el = reading.robot_element()?;
        let (joint_nodes, link_nodes) = reading.check_elements(robot_el);
        if !reading.errors.is_empty() {
            return Err(reading.errors);
        }
        // Each body of the tree lists the joints that move it, so a chain of n joints holds
        // n²/2 of them, built and copied a few times (16 n² bytes at most): counted before any
        // joint is read.
        limits::check("joints of the URDF", joint_nodes.len(), "joints", &|k| {
            let k = k as f64;
            Cost {
                bytes: 16.0 * k * k,
                flops: 50.0 * k * k,
            }
        })
        .map_err(|e| vec![at_line(reading.line_of(robot_el), e.to_string())])?;
        let robot = read_values(&text, robot_el, link_nodes.len(), joint_nodes.len())?;
        let dir = path.parent().unwrap_or(Path::new("."));
        let mut links = Vec::new();
        let mut link_names = HashSet::new();
        for (l, node) in robot.links.iter().zip(&link_nodes) {
            let link = reading.link(l, *node, &mut link_names, dir);
            links.push(link);
        }
        let mut joints = Vec::new();
        let mut joint_names = HashSet::new();
        for (j, node) in robot.joints.iter().zip(&joint_nodes) {
            if let Some(joint) = reading.joint(j, *node, &link_names, &mut joint_names) {
                joints.push(joint);
            }
        }
        resolve_mimics(&mut joints, &mut reading.warnings, &mut reading.errors);
        reading.check_loops(&joints);
        let root = reading.root(&links, &joints);
        if !reading.errors.is_empty() {
            return Err(reading.errors);
        }
        let doc = UrdfDocument {
            path: path.to_path_buf(),
            name: robot.name,
            root,
            links,
            joints,
            warnings: reading.warnings.lines(&file),
            text,
        };
        doc.placement()?;
        Ok(doc)
    }

    /// The joints in an order where each joint's parent link, and the joint it mimics, come
    /// first: file order wherever the file allows it. Fails on joints unreachable from the root
    /// (a loop) or mimicking a joint below themselves.
    pub fn placement_order(&self) -> Result<Vec<usize>, Vec<String>> {
        self.placement().map_err(|issues| in_file(&self.path, &issues))
    }

    fn placement(&self) -> Result<Vec<usize>, Vec<Issue>> {
        // A priority topological sort: the lowest file index among the joints whose parent
        // link and mimicked joint are placed goes next, each joint counting what it waits for.
        let n = self.joints.len();
        let mut by_name: HashMap<&str, usize> = HashMap::new();
        for (i, j) in self.joints.iter().enumerate().rev() {
            by_name.insert(j.name.as_str(), i);
        }
        let mut on_link: HashMap<&str, Vec<usize>> = HashMap::new();
        let mut on_joint: Vec<Vec<usize>> = vec![Vec::new(); n];
        let mut waits = vec![0usize; n];
        let mut ready = std::collections::BinaryHeap::new();
        for (i, j) in self.joints.iter().enumerate() {
            if j.parent != self.root {
                on_link.entry(j.parent.as_str()).or_default().push(i);
                waits[i] += 1;
            }
            if let Some((t, _, _)) = &j.mimic {
                // A mimicked joint that does not exist is never placed, nor is this one.
                if let Some(&k) = by_name.get(t.as_str()) {
                    on_joint[k].push(i);
                }
                waits[i] += 1;
            }
            if waits[i] == 0 {
                ready.push(std::cmp::Reverse(i));
            }
        }
        let mut placed = vec![false; n];
        let mut order = Vec::with_capacity(n);
        while order.len() < n {
            let next = ready.pop().map(|std::cmp::Reverse(i)| i);
            let Some(i) = next else {
                return Err(self
                    .joints
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| !placed[*i])
                    .map(|(_, j)| {
                        at_line(
                            j.line,
                            format!(
                                "joint `{}`: not reachable from the root link `{}` (its parent link `{}` hangs in a closed loop, or it mimics a joint below itself)",
                                j.name, self.root, j.parent
                            ),
                        )
                    })
                    .collect());
            };
            placed[i] = true;
            order.push(i);
            let freed = (on_link.remove(self.joints[i].child.as_str()).into_iter().flatten())
                .chain(std::mem::take(&mut on_joint[i]));
            for k in freed {
                waits[k] -= 1;
                if waits[k] == 0 {
                    ready.push(std::cmp::Reverse(k));
                }
            }
        }
        Ok(order)
    }
}

/// The largest magnitude of a `<mimic>` multiplier: no gearing couples two joints a thousand
/// to one.
const ABSURD_MULTIPLIER: f64 = 1e3;

/// The largest magnitude of a `<mimic>` offset (rad, or m for a prismatic joint): sixteen turns,
/// or a hundred metres.
const ABSURD_MIMIC_OFFSET: f64 = 100.0;

/// What [`UrdfDocument::parse`] carries from one element to the next: the XML (for lines), the
/// problems found so far and the warnings.
struct Reading<'x, 'input> {
    xml: &'x roxmltree::Document<'input>,
    /// The byte offset where each line of the text starts: a node's line found by bisection
    /// (roxmltree's `text_pos_at` counts from the start of the text, quadratic over a file).
    line_starts: Vec<usize>,
    errors: Vec<Issue>,
    warnings: Tally,
    /// How large mesh files may be.
    limits: InputLimits,
}

impl<'x, 'input> Reading<'x, 'input> {
    /// 1-based line where `n` starts.
    fn line_of(&self, n: roxmltree::Node<'_, '_>) -> usize {
        self.line_starts.partition_point(|&start| start <= n.range().start)
    }

    /// The `<robot>` element at the top.
    fn robot_element(&self) -> Result<Node<'x, 'input>, Vec<Issue>> {
        let robot_el = self.xml.root_element();
        if !robot_el.has_tag_name("robot") {
            return Err(vec![at_line(
                self.line_of(robot_el),
                format!(
                    "expected a <robot> element at the top, found <{}>",
                    robot_el.tag_name().name()
                ),
            )]);
        }
        Ok(robot_el)
    }

    /// Element-level checks with lines (urdf-rs reports neither line nor element); the
    /// `<joint>` and `<link>` elements, in file order.
    fn check_elements(&mut self, robot_el: Node<'x, 'input>) -> (Vec<Node<'x, 'input>>, Vec<Node<'x, 'input>>) {
        let mut joint_nodes = Vec::new();
        let mut link_nodes = Vec::new();
        for el in robot_el.children().filter(|n| n.is_element()) {
            let what = el.tag_name().name();
            if what != "joint" && what != "link" {
                continue;
            }
            let line = self.line_of(el);
            let Some(name) = el.attribute("name").filter(|n| !n.trim().is_empty()) else {
                self.errors.push(at_line(line, format!("<{what}> without a `name`")));
                continue;
            };
            let at = format!("{what} `{name}`");
            let mut found = Vec::new();
            if what == "joint" {
                check_joint(el, &at, &mut found);
                joint_nodes.push(el);
            } else {
                self.check_link(el, &at, &mut found);
                link_nodes.push(el);
            }
            self.errors.extend(found.into_iter().map(|m| at_line(line, m)));
        }
        (joint_nodes, link_nodes)
    }

    /// Checks the children of the `<link>` element `el` (named `at` in messages): problems
    /// on the link's line into `found`, unknown shapes on their own lines.
    fn check_link(&mut self, el: roxmltree::Node<'_, '_>, at: &str, found: &mut Vec<String>) {
        for sub in el.children().filter(|n| n.is_element()) {
            let tag = sub.tag_name().name();
            for o in sub.children().filter(|n| n.has_tag_name("origin")) {
                check_origin(o, &format!("{at}: <{tag}>"), found);
            }
            if tag == "inertial" {
                check_numbers(sub, "mass", "value", 1, &format!("{at}: <inertial>"), found);
            }
            // urdf-rs names an unknown shape without its line or link.
            for shape in sub
                .children()
                .filter(|n| n.has_tag_name("geometry"))
                .flat_map(|g| g.children().filter(|n| n.is_element()))
                .filter(|n| !SHAPES.contains(&n.tag_name().name()))
            {
                self.errors.push(at_line(
                    self.line_of(shape),
                    format!(
                        "{at}: <{tag}> <geometry>: unknown shape <{}>; expected one of <{}>",
                        shape.tag_name().name(),
                        SHAPES.join(">, <")
                    ),
                ));
            }
        }
    }

    /// The link `l` as urdf-rs read it from `node`, after the links read before it (their
    /// names in `names`, which it joins); mesh files are found from `dir`.
    fn link(
        &mut self,
        l: &urdf_rs::Link,
        node: roxmltree::Node<'_, '_>,
        names: &mut HashSet<String>,
        dir: &Path,
    ) -> UrdfLink {
        let line = self.line_of(node);
        let at = format!("link `{}`", l.name);
        if !names.insert(l.name.clone()) {
            self.errors
                .push(at_line(line, format!("{at}: a link of this name is defined twice")));
        }
        let inertial = node.children().any(|n| n.has_tag_name("inertial")).then(|| {
            let m = l.inertial.mass.value;
            let (most, words) = Quantity::Mass.absurd_beyond().unwrap_or((f64::MAX, ""));
            if !(0.0..=most).contains(&m) {
                self.errors.push(at_line(
                    line,
                    format!("{at}: <inertial>: expected a mass of zero or more kg, at most {words}, got {m:e} kg"),
                ));
            }
            let (far, far_words) = Quantity::Length.absurd_beyond().unwrap_or((f64::MAX, ""));
            if let Some(v) = l.inertial.origin.xyz.0.iter().find(|v| !(-far..=far).contains(*v)) {
                self.errors.push(at_line(
                    line,
                    format!(
                        "{at}: <inertial> <origin>: {v:e} m is physically absurd; expected a magnitude of at most {far_words}"
                    ),
                ));
            }
            (m, l.inertial.origin.xyz.0)
        });
        let mut collisions = Vec::new();
        for c in &l.collision {
            let origin = armcomp_core::model::geom::xyz_rpy(c.origin.xyz.0, c.origin.rpy.0);
            match collision_shape(&c.geometry, dir, self.limits) {
                Ok(MeshOutcome::Shape(pose, shape)) => {
                    if matches!(c.geometry, urdf_rs::Geometry::Mesh { .. }) {
                        self.warnings.add(MESH_BOXED, String::new(), line, &at);
                    }
                    collisions.push((origin * pose, shape));
                }
                Ok(MeshOutcome::Skipped(why)) => self.warnings.add(MESH_SKIPPED, why, line, &at),
                Err(e) => self.errors.push(at_line(line, format!("{at}: <collision>: {e}"))),
            }
        }
        UrdfLink {
            name: l.name.clone(),
            line,
            inertial,
            collisions,
        }
    }

    /// The joint `j` as urdf-rs read it from `node`, after the joints read before it (their
    /// names in `names`, which it joins), its links among `links`; none for a type refused
    /// before.
    fn joint(
        &mut self,
        j: &urdf_rs::Joint,
        node: roxmltree::Node<'_, '_>,
        links: &HashSet<String>,
        names: &mut HashSet<String>,
    ) -> Option<UrdfJoint> {
        let line = self.line_of(node);
        let at = format!("joint `{}`", j.name);
        if !names.insert(j.name.clone()) {
            self.errors
                .push(at_line(line, format!("{at}: a joint of this name is defined twice")));
        }
        let kind = match j.joint_type {
            urdf_rs::JointType::Revolute => UrdfJointType::Revolute,
            urdf_rs::JointType::Continuous => UrdfJointType::Continuous,
            urdf_rs::JointType::Prismatic => UrdfJointType::Prismatic,
            urdf_rs::JointType::Fixed => UrdfJointType::Fixed,
            urdf_rs::JointType::Floating | urdf_rs::JointType::Planar => {
                let why =
                    "type `floating` or `planar`, read as fixed: only revolute, continuous and prismatic joints move";
                self.warnings.add(HELD_AT_ORIGIN, why.into(), line, &at);
                UrdfJointType::Fixed
            }
            // Refused by `check_joint` before urdf-rs read the file.
            urdf_rs::JointType::Spherical => return None,
        };
        for (role, link) in [("parent", &j.parent.link), ("child", &j.child.link)] {
            if !links.contains(link) {
                self.errors.push(at_line(
                    line,
                    format!("{at}: its {role} link `{link}` is not defined in the file"),
                ));
            }
        }
        let moving = kind != UrdfJointType::Fixed;
        let axis = j.axis.xyz.0;
        let length = axis.iter().map(|v| v * v).sum::<f64>().sqrt();
        if moving && !(1e-12..=1e12).contains(&length) {
            self.errors.push(at_line(
                line,
                format!(
                    "{at}: <axis xyz>: expected a non-zero direction of finite length (a unit vector), got length {length:e}"
                ),
            ));
        }
        let mut origin = (j.origin.xyz.0.iter().map(|v| (v, Quantity::Length)))
            .chain(j.origin.rpy.0.iter().map(|v| (v, Quantity::Angle)));
        if let Some((v, q)) = origin.find(|(v, q)| q.absurd_beyond().is_some_and(|(b, _)| !(-b..=b).contains(*v))) {
            let words = q.absurd_beyond().map_or("", |(_, w)| w);
            self.errors.push(at_line(
                line,
                format!(
                    "{at}: <origin>: {v:e} {} is physically absurd; expected a magnitude of at most {words}",
                    q.si_unit()
                ),
            ));
        }
        let has_limit = node.children().any(|n| n.has_tag_name("limit"));
        let limits = (has_limit && matches!(kind, UrdfJointType::Revolute | UrdfJointType::Prismatic))
            .then_some([j.limit.lower, j.limit.upper])
            .filter(|l| l.iter().all(|v| v.is_finite()));
        if let Some([lo, hi]) = limits
            && lo > hi
        {
            self.errors
                .push(at_line(line, format!("{at}: <limit>: lower {lo} is above upper {hi}")));
        }
        // ROS (urdfdom, pinocchio) ignores `<mimic>` on a fixed joint: it has nothing to move.
        let mimic = j
            .mimic
            .as_ref()
            .filter(|_| moving)
            .map(|m| (m.joint.clone(), m.multiplier.unwrap_or(1.0), m.offset.unwrap_or(0.0)));
        let child_range = |tag: &str| node.children().find(|n| n.has_tag_name(tag)).map(|n| n.range());
        Some(UrdfJoint {
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
        })
    }

    /// Refuses a link that is the child of two joints: a closed loop.
    fn check_loops(&mut self, joints: &[UrdfJoint]) {
        let mut parents_of: HashMap<&str, Vec<&UrdfJoint>> = HashMap::new();
        for j in joints {
            parents_of.entry(j.child.as_str()).or_default().push(j);
        }
        for j in joints {
            if let Some(other) = parents_of[j.child.as_str()].iter().find(|o| o.name != j.name) {
                self.errors.push(at_line(
                    j.line,
                    format!(
                        "joint `{}`: link `{}` is also the child of joint `{}` (line {}): a closed kinematic loop, which URDF cannot describe",
                        j.name, j.child, other.name, other.line
                    ),
                ));
            }
        }
    }

    /// The one link that is the child of no joint (empty, with the problem recorded, when
    /// there is none or more than one).
    fn root(&mut self, links: &[UrdfLink], joints: &[UrdfJoint]) -> String {
        let children: HashSet<&str> = joints.iter().map(|j| j.child.as_str()).collect();
        let roots: Vec<&str> = links
            .iter()
            .filter(|l| !children.contains(l.name.as_str()))
            .map(|l| l.name.as_str())
            .collect();
        match roots.as_slice() {
            [one] => one.to_string(),
            [] if links.is_empty() => {
                self.errors.push(Issue::new("", "the robot has no <link>"));
                String::new()
            }
            [] => {
                self.errors.push(Issue::new(
                    "",
                    "every link is the child of a joint, so the joints form a closed loop; a URDF robot is a tree with one root link",
                ));
                String::new()
            }
            many => {
                self.errors.push(Issue::new(
                    "",
                    format!(
                        "several links are the child of no joint ({}); a URDF robot is a tree with one root link",
                        many.join(", ")
                    ),
                ));
                String::new()
            }
        }
    }
}

/// The values of the checked XML as urdf-rs reads them; it must see the `n_links` links and
/// `n_joints` joints the XML has, or the elements and their values would not pair up.
fn read_values(
    text: &str,
    robot_el: roxmltree::Node<'_, '_>,
    n_links: usize,
    n_joints: usize,
) -> Result<urdf_rs::Robot, Vec<Issue>> {
    let robot = urdf_rs::read_from_string(&for_urdf_rs(text, robot_el))
        .map_err(|e| vec![Issue::new("", format!("not a valid URDF: {e}"))])?;
    if robot.links.len() != n_links || robot.joints.len() != n_joints {
        return Err(vec![Issue::new(
            "",
            format!(
                "the URDF reader saw {} links and {} joints where the XML has {} and {}",
                robot.links.len(),
                robot.joints.len(),
                n_links,
                n_joints
            ),
        )]);
    }
    Ok(robot)
}

/// Points every `<mimic>` at the joint that moves on its own at the end of its chain, composing
/// multipliers and offsets (`a = k·b + o`, `b = k'·c + o'` gives `a = k·k'·c + k·o' + o`). A
/// chain that ends on no moving joint (a missing name, a fixed joint, a loop) loses its mimic:
/// urdfdom accepts such a file, and pinocchio's reader moves every mimic joint on its own.
fn resolve_mimics(joints: &mut [UrdfJoint], warnings: &mut Tally, errors: &mut Vec<Issue>) {
    type Coupling = Option<(String, f64, f64)>;
    let follows: Vec<Coupling> = joints.iter().map(|j| j.mimic.clone()).collect();
    let mut by_name: HashMap<&str, usize> = HashMap::new();
    for (i, j) in joints.iter().enumerate().rev() {
        by_name.insert(j.name.as_str(), i);
    }
    // The moving joint a joint's mimic names.
    let target = |i: usize| {
        (follows[i].as_ref())
            .and_then(|(t, _, _)| by_name.get(t.as_str()).copied())
            .filter(|&t| joints[t].kind != UrdfJointType::Fixed)
    };
    // `a = k·b + o` composed with `b`'s own coupling to its end.
    let compose = |(_, k, o): &(String, f64, f64), end: &Coupling| -> Coupling {
        end.as_ref()
            .map(|(root, k_end, o_end)| (root.clone(), k * k_end, o + k * o_end))
    };
    // Each chain walked once: a joint's coupling is its mimic composed with that of the joint
    // it names, kept for the joints that reach it later (quadratic in a long chain otherwise).
    let mut resolved: Vec<Option<Coupling>> = vec![None; joints.len()];
    let mut on_path = vec![false; joints.len()];
    for start in 0..joints.len() {
        if follows[start].is_none() || resolved[start].is_some() {
            continue;
        }
        let mut path = Vec::new();
        let mut i = start;
        let mut end = loop {
            path.push(i);
            on_path[i] = true;
            let own = follows[i].as_ref().expect("a joint on the path mimics");
            match target(i) {
                // No moving joint, or a loop back onto the path.
                None => break None,
                Some(t) if on_path[t] => break None,
                Some(t) => match (&follows[t], &resolved[t]) {
                    (None, _) => break Some(own.clone()),
                    (Some(_), Some(r)) => break compose(own, r),
                    (Some(_), None) => i = t,
                },
            }
        };
        for (n, &p) in path.iter().rev().enumerate() {
            if n > 0 {
                end = compose(follows[p].as_ref().expect("a joint on the path mimics"), &end);
            }
            resolved[p] = Some(end.clone());
            on_path[p] = false;
        }
    }
    for (j, r) in joints.iter_mut().zip(resolved) {
        let Some(coupling) = r else {
            continue;
        };
        j.mimic = coupling;
        let at = format!("joint `{}`", j.name);
        match &j.mimic {
            None => warnings.add(
                MIMIC_IGNORED,
                "naming no moving joint: such joints move on their own, as pinocchio reads them".into(),
                j.line,
                &at,
            ),
            // NaN fails both comparisons.
            Some((_, k, offset)) if !(k.abs() <= ABSURD_MULTIPLIER && offset.abs() <= ABSURD_MIMIC_OFFSET) => errors
                .push(at_line(
                    j.line,
                    format!(
                        "{at}: <mimic>: multiplier {k:e} and offset {offset:e} (composed along its chain) are \
                         physically absurd; expected a multiplier of magnitude at most {ABSURD_MULTIPLIER} and an \
                         offset of at most {ABSURD_MIMIC_OFFSET} (rad or m)"
                    ),
                )),
            Some(_) => {}
        }
    }
}

/// The text given to `urdf-rs`: the file with everything but `<link>` and `<joint>` elements,
/// and the links' `<visual>`s, blanked out (lines kept). armcomp uses none of it, and urdf-rs reads
/// visuals and materials more strictly than urdfdom (a `<texture/>` without `filename`, as some
/// published URDFs have, fails the whole file). An `<axis>` without `xyz`, which urdfdom reads
/// as (1, 0, 0), is blanked too: urdf-rs refuses it, and an absent axis is (1, 0, 0) there.
/// Lines and byte ranges in messages and calibrated copies refer to the original text.
fn for_urdf_rs(text: &str, robot: roxmltree::Node<'_, '_>) -> String {
    let mut bytes = text.as_bytes().to_vec();
    let mut blank = |n: roxmltree::Node<'_, '_>| {
        for b in &mut bytes[n.range()] {
            if *b != b'\n' {
                *b = b' ';
            }
        }
    };
    for el in robot.children().filter(|n| n.is_element()) {
        let unused = |n: &roxmltree::Node<'_, '_>| match el.tag_name().name() {
            "link" => n.has_tag_name("visual"),
            "joint" => n.has_tag_name("axis") && n.attribute("xyz").is_none(),
            _ => false,
        };
        if el.has_tag_name("link") || el.has_tag_name("joint") {
            el.children().filter(unused).for_each(&mut blank);
        } else {
            blank(el);
        }
    }
    // Whole elements became ASCII spaces, so the bytes are still UTF-8.
    String::from_utf8_lossy(&bytes).into_owned()
}

/// Problems as messages that name the file.
fn in_file(path: &Path, issues: &[Issue]) -> Vec<String> {
    issues.iter().map(|i| i.in_file(path)).collect()
}

/// The shapes a URDF `<geometry>` may hold.
const SHAPES: [&str; 5] = ["box", "cylinder", "capsule", "sphere", "mesh"];

/// A problem at a line of the file; the message names the element.
fn at_line(line: usize, message: String) -> Issue {
    Issue {
        path: String::new(),
        message,
        line: Some(line),
    }
}

/// A kind of warning: what happened to one element, and to several.
type Kind = (&'static str, &'static str);
const MESH_SKIPPED: Kind = ("collision mesh skipped", "collision meshes skipped");
const MESH_BOXED: Kind = (
    "collision mesh approximated by its bounding box",
    "collision meshes approximated by their bounding boxes",
);
const HELD_AT_ORIGIN: Kind = ("held at its origin", "joints held at their origins");
const MIMIC_IGNORED: Kind = ("<mimic> ignored", "<mimic> elements ignored");

/// Warnings counted by kind and reason, each with its first element: a humanoid whose meshes are
/// not on disk gives one line, not one per link.
#[derive(Default)]
struct Tally(Vec<Counted>);

struct Counted {
    kind: Kind,
    why: String,
    count: usize,
    line: usize,
    element: String,
}

impl Tally {
    fn add(&mut self, kind: Kind, why: String, line: usize, element: &str) {
        match self.0.iter_mut().find(|c| c.kind == kind && c.why == why) {
            Some(c) => c.count += 1,
            None => self.0.push(Counted {
                kind,
                why,
                count: 1,
                line,
                element: element.to_string(),
            }),
        }
    }

    /// One line per kind: `file:line: element: what (why)` for a single element, else
    /// `file: n what (why); first: element at line l`.
    fn lines(self, file: &str) -> Vec<String> {
        self.0
            .into_iter()
            .map(|c| {
                let why = if c.why.is_empty() {
                    String::new()
                } else {
                    format!(" ({})", c.why)
                };
                if c.count == 1 {
                    format!("{file}:{}: {}: {}{why}", c.line, c.element, c.kind.0)
                } else {
                    format!(
                        "{file}: {} {}{why}; first: {} at line {}",
                        c.count, c.kind.1, c.element, c.line
                    )
                }
            })
            .collect()
    }
}

/// The shape of a `<collision>` geometry; meshes become bounding boxes.
fn collision_shape(g: &urdf_rs::Geometry, dir: &Path, limits: InputLimits) -> Result<MeshOutcome, String> {
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
            return mesh_bounding_box(filename, scale, dir, limits);
        }
    };
    Ok(MeshOutcome::Shape(Isometry3::identity(), shape))
}

/// The joint types urdfdom reads (not `spherical`, which urdf-rs knows).
const JOINT_TYPES: &str = "expected revolute, continuous, prismatic, fixed, floating or planar";

/// Checks a joint element: type, origin, parent, child, axis, limit and mimic attributes.
fn check_joint(el: roxmltree::Node<'_, '_>, at: &str, errors: &mut Vec<String>) {
    match el.attribute("type") {
        Some("revolute" | "continuous" | "prismatic" | "fixed" | "floating" | "planar") => {}
        Some("spherical") => errors.push(format!("{at}: type `spherical` is not supported; {JOINT_TYPES}")),
        Some(t) => errors.push(format!("{at}: unknown joint type `{t}`; {JOINT_TYPES}")),
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
