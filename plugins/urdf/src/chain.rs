//! The `urdf` kinematics plugin: a URDF file as an identifiable chain.
//!
//! Every URDF joint becomes a tree joint (fixed joints too, so every link is a body that points
//! and links can name); a link's frame is the URDF link frame. Each joint's origin is
//! identifiable as a translation and a small rotation applied after the origin's
//! roll-pitch-yaw, in the origin frame, rather than roll-pitch-yaw themselves, which lose a
//! degree of freedom at ±90° pitch (common in ROS URDFs). The bases are aligned with a moving
//! joint's axis `a` and two fixed directions `u, v` perpendicular to it, so that the joint's
//! value offset is one parameter, `offset` (what calibrating joint offsets identifies):
//! - fixed joint: translation `x, y, z` (m), rotation `rx, ry, rz` (rad);
//! - revolute: translation `x, y, z`, rotation `rot_u, rot_v` and `offset` (rad, about `a`);
//! - prismatic: translation `t_u, t_v` and `offset` (m, along `a`), rotation `rx, ry, rz`.
//!
//! A joint's axis is not a parameter of its own: tilting it is the same as rotating the
//! joint's origin and undoing that rotation in the next joint's origin (`R·Rot(a, q) =
//! Rot(R·a, q)·R`), which every joint on a measured chain has, so axis parameters would only
//! add directions the data cannot tell apart. Identified values are written back as per-joint
//! `joints` overrides of the origin, in the robot file's units.
//!
//! The joint vector `q` holds the moving joints that mimic no other, in the order the URDF file
//! lists them.

use std::collections::HashMap;
use std::path::PathBuf;

use armcomp_chains::PriorSpec;
use armcomp_core::{
    BuildContext, Chain, Coupling, Issues, KinematicTree, KinematicsSpec, Limits, LinkData, Motion, ParamInfo,
    Quantity, Result, Units,
};
use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::document::{UrdfDocument, UrdfJointType};

/// Identified geometry of one joint, replacing the URDF's (the robot file's units).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct UrdfJointOverride {
    /// The URDF joint's name.
    pub name: String,
    /// Origin translation (length unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub xyz: Option<[f64; 3]>,
    /// Origin roll, pitch, yaw, URDF convention (angle unit).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rpy: Option<[f64; 3]>,
    /// Axis direction in the joint frame (normalised on use).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub axis: Option<[f64; 3]>,
}

/// A robot described by a URDF file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct UrdfSpec {
    /// The URDF file, relative to the robot file (or absolute).
    pub path: String,
    /// Identified joint geometry replacing the URDF's, as calibration writes it back.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub joints: Vec<UrdfJointOverride>,
    /// Prior standard deviations of the parameters.
    #[serde(default, skip_serializing_if = "is_default_prior")]
    pub prior: PriorSpec,
}

fn is_default_prior(p: &PriorSpec) -> bool {
    *p == PriorSpec::default()
}

/// One joint, compiled (placement order).
#[derive(Debug, Clone)]
struct CompiledJoint {
    name: String,
    moving: bool,
    prismatic: bool,
    /// Parent body index.
    parent: usize,
    child: String,
    /// Origin translation (m) and rotation before the identified changes.
    xyz: Vector3<f64>,
    rotation: UnitQuaternion<f64>,
    axis: Unit<Vector3<f64>>,
    /// Two directions perpendicular to the axis and each other, the basis of the identified
    /// rotation (revolute) or translation (prismatic) across the axis.
    across: [Vector3<f64>; 2],
    limits: Option<Limits>,
    /// `(placement index of the followed joint, multiplier, offset)`.
    mimic: Option<(usize, f64, f64)>,
    first_param: usize,
}

/// A compiled URDF robot.
#[derive(Debug, Clone)]
pub struct UrdfChain {
    spec: UrdfSpec,
    units: Units,
    /// The URDF file as resolved; model files name it relative to themselves.
    resolved: PathBuf,
    base: String,
    /// In placement order (parents first).
    joints: Vec<CompiledJoint>,
    /// Placement indices in file order.
    file_order: Vec<usize>,
    params: Vec<ParamInfo>,
    /// New coordinate k (file order) = placement-order coordinate `coordinate_order[k]`.
    coordinate_order: Vec<usize>,
    links: Vec<LinkData>,
    warnings: Vec<String>,
}

#[typetag::serde(name = "urdf")]
impl KinematicsSpec for UrdfSpec {
    fn build(&self, ctx: &BuildContext<'_>) -> Result<Box<dyn Chain>, Issues> {
        let field = format!("{}.path", ctx.path);
        let file = ctx.base_dir.join(&self.path);
        let to_issues = |errors: Vec<String>| {
            let mut issues = Issues::default();
            errors.into_iter().for_each(|e| issues.push(field.clone(), e));
            issues
        };
        let doc = UrdfDocument::read(&file, ctx.limits).map_err(to_issues)?;
        let order = doc.placement_order().map_err(to_issues)?;
        UrdfChain::compile(self, &doc, &order, ctx).map(|c| Box::new(c) as Box<dyn Chain>)
    }

    fn paths_relative_to(&mut self, dir: &std::path::Path) {
        let path = std::path::Path::new(&self.path);
        if path.is_absolute()
            && let Some(relative) = pathdiff::diff_paths(path, dir)
        {
            self.path = relative.display().to_string();
        }
    }
}

/// Two unit directions perpendicular to `axis` and to each other, chosen deterministically.
fn across_basis(axis: &Unit<Vector3<f64>>) -> [Vector3<f64>; 2] {
    let a = axis.into_inner();
    let least = if a.x.abs() <= a.y.abs() && a.x.abs() <= a.z.abs() {
        Vector3::x()
    } else if a.y.abs() <= a.z.abs() {
        Vector3::y()
    } else {
        Vector3::z()
    };
    let u = a.cross(&least).normalize();
    [u, a.cross(&u)]
}

impl UrdfChain {
    fn compile(
        spec: &UrdfSpec,
        doc: &UrdfDocument,
        order: &[usize],
        ctx: &BuildContext<'_>,
    ) -> Result<UrdfChain, Issues> {
        let units = ctx.units;
        let mut issues = Issues::default();
        let mut doc_index: HashMap<&str, usize> = HashMap::new();
        for (f, j) in doc.joints.iter().enumerate().rev() {
            doc_index.insert(j.name.as_str(), f);
        }
        let mut overrides: HashMap<&str, &UrdfJointOverride> = HashMap::new();
        for (i, o) in spec.joints.iter().enumerate() {
            let path = format!("{}.joints[{i}]", ctx.path);
            match doc_index.get(o.name.as_str()).map(|&f| &doc.joints[f]) {
                None => issues.push(format!("{path}.name"), format!("the URDF has no joint `{}`", o.name)),
                Some(j) if o.axis.is_some() && j.kind == UrdfJointType::Fixed => issues.push(
                    format!("{path}.axis"),
                    format!("joint `{}` is fixed and has no axis", o.name),
                ),
                Some(_) => {}
            }
            if overrides.insert(o.name.as_str(), o).is_some() {
                issues.push(
                    format!("{path}.name"),
                    format!("joint `{}` is overridden twice", o.name),
                );
            }
            for (field, v) in [("xyz", o.xyz), ("rpy", o.rpy), ("axis", o.axis)] {
                if let Some(v) = v
                    && v.iter().any(|x| !x.is_finite())
                {
                    issues.push(format!("{path}.{field}"), "expected three finite numbers");
                }
            }
            // As in the URDF itself: no origin a kilometre away or turned sixteen times.
            for (field, si, quantity) in [
                ("xyz", o.xyz.map(|v| units.len3(v)), Quantity::Length),
                ("rpy", o.rpy.map(|v| units.ang3(v)), Quantity::Angle),
            ] {
                if let (Some(v), Some((most, words))) = (si, quantity.absurd_beyond())
                    && v.iter().any(|x| x.abs() > most)
                {
                    issues.push(
                        format!("{path}.{field}"),
                        format!("physically absurd; expected magnitudes of at most {words}"),
                    );
                }
            }
            if let Some(a) = o.axis
                && !(1e-24..=1e24).contains(&a.iter().map(|x| x * x).sum::<f64>())
            {
                issues.push(
                    format!("{path}.axis"),
                    "expected a non-zero direction of finite length (a unit vector)",
                );
            }
        }
        spec.prior.check(&format!("{}.prior", ctx.path), &mut issues);
        if !issues.is_empty() {
            return Err(issues);
        }

        // Parameters in file order.
        let sigma = |q| spec.prior.sigma(q, &units);
        let mut params = Vec::new();
        let mut first_param = vec![0; doc.joints.len()];
        let mut geometry = Vec::new();
        for (f, j) in doc.joints.iter().enumerate() {
            let o = overrides.get(j.name.as_str()).copied();
            let xyz = o.and_then(|o| o.xyz).map_or(j.xyz, |v| units.len3(v));
            let rpy = o.and_then(|o| o.rpy).map_or(j.rpy, |v| units.ang3(v));
            let axis = o.and_then(|o| o.axis).unwrap_or(j.axis);
            first_param[f] = params.len();
            let mut push = |name: &str, quantity, nominal| {
                params.push(ParamInfo::new(
                    format!("{}.{name}", j.name),
                    quantity,
                    nominal,
                    sigma(quantity),
                ))
            };
            let (l, a) = (Quantity::Length, Quantity::Angle);
            if j.kind == UrdfJointType::Prismatic {
                ["t_u", "t_v", "offset"].iter().for_each(|n| push(n, l, 0.0));
            } else {
                ["x", "y", "z"].iter().zip(xyz).for_each(|(n, v)| push(n, l, v));
            }
            match j.kind {
                UrdfJointType::Revolute | UrdfJointType::Continuous => {
                    ["rot_u", "rot_v", "offset"].iter().for_each(|n| push(n, a, 0.0))
                }
                _ => ["rx", "ry", "rz"].iter().for_each(|n| push(n, a, 0.0)),
            }
            geometry.push((xyz, rpy, axis));
        }

        // Joints in placement order; bodies are numbered the same way (body p + 1 is the child
        // of the joint placed p-th).
        let mut placement = vec![None; doc.joints.len()];
        for (p, &f) in order.iter().enumerate() {
            placement[f] = Some(p);
        }
        let placement_of = |file_index: usize| placement[file_index];
        // The placement index of the joint whose child is each link (the first placed).
        let mut child_of: HashMap<&str, usize> = HashMap::new();
        let mut joints: Vec<CompiledJoint> = Vec::new();
        let mut placed_coordinate = vec![None; doc.joints.len()];
        let mut ncoord = 0;
        for &f in order {
            let j = &doc.joints[f];
            let parent = if j.parent == doc.root {
                0
            } else {
                child_of.get(j.parent.as_str()).map_or(0, |p| p + 1)
            };
            let (xyz, rpy, axis) = geometry[f];
            let axis = Unit::new_normalize(Vector3::from(axis));
            let moving = j.kind != UrdfJointType::Fixed;
            let mimic = j.mimic.as_ref().map(|(target, k, off)| {
                let t = doc_index.get(target.as_str()).copied();
                (t.and_then(placement_of).unwrap_or(0), *k, *off)
            });
            if moving && mimic.is_none() {
                placed_coordinate[f] = Some(ncoord);
                ncoord += 1;
            }
            child_of.entry(j.child.as_str()).or_insert(joints.len());
            joints.push(CompiledJoint {
                name: j.name.clone(),
                moving,
                prismatic: j.kind == UrdfJointType::Prismatic,
                parent,
                child: j.child.clone(),
                xyz: Vector3::from(xyz),
                rotation: UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]),
                across: across_basis(&axis),
                axis,
                limits: j.limits.map(|[lower, upper]| Limits { lower, upper }),
                mimic,
                first_param: first_param[f],
            });
        }
        let coordinate_order = placed_coordinate.iter().flatten().copied().collect();
        let file_order = (0..doc.joints.len()).filter_map(placement_of).collect();
        let links = doc
            .links
            .iter()
            .map(|l| LinkData {
                name: l.name.clone(),
                mass: l.inertial.map(|(m, com)| (m, Vector3::from(com))),
                shapes: l.collisions.clone(),
            })
            .collect();
        Ok(UrdfChain {
            spec: spec.clone(),
            units,
            resolved: std::fs::canonicalize(&doc.path).unwrap_or_else(|_| doc.path.clone()),
            base: doc.root.clone(),
            joints,
            file_order,
            params,
            coordinate_order,
            links,
            warnings: doc.warnings.clone(),
        })
    }

    /// Origin of joint `j` (placement order) for its six parameter values `v` (see the module
    /// documentation for their order).
    fn origin(&self, j: &CompiledJoint, v: &[f64]) -> Isometry3<f64> {
        let [u, w] = j.across;
        let a = j.axis.into_inner();
        let (translation, small) = match (j.moving, j.prismatic) {
            (false, _) => (Vector3::new(v[0], v[1], v[2]), Vector3::new(v[3], v[4], v[5])),
            (true, true) => (
                j.xyz + j.rotation * (u * v[0] + w * v[1] + a * v[2]),
                Vector3::new(v[3], v[4], v[5]),
            ),
            (true, false) => (Vector3::new(v[0], v[1], v[2]), u * v[3] + w * v[4] + a * v[5]),
        };
        let rotation = j.rotation * UnitQuaternion::from_scaled_axis(small);
        Isometry3::from_parts(Translation3::from(translation), rotation)
    }

    fn joint_values<'v>(&self, j: &CompiledJoint, values: &'v [f64]) -> &'v [f64] {
        &values[j.first_param..j.first_param + 6]
    }
}

impl Chain for UrdfChain {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    fn tree(&self, values: &[f64]) -> Result<KinematicTree> {
        if values.len() != self.params.len() {
            return Err(armcomp_core::Error::Dimension {
                what: "chain parameters".into(),
                expected: self.params.len(),
                got: values.len(),
            });
        }
        let mut tree = KinematicTree::new(self.base.clone());
        let mut coordinate = vec![0; self.joints.len()];
        let mut next = 0;
        for (p, j) in self.joints.iter().enumerate() {
            let placement = self.origin(j, self.joint_values(j, values));
            let motion = match (j.moving, j.prismatic) {
                (false, _) => Motion::Fixed,
                (true, true) => Motion::Prismatic(j.axis),
                (true, false) => Motion::Revolute(j.axis),
            };
            match j.mimic {
                Some((target, k, offset)) => {
                    let coupling = Coupling {
                        terms: vec![(coordinate[target], k)],
                        offset,
                    };
                    tree.add_mimic_joint(j.name.clone(), j.parent, placement, motion, coupling, j.child.clone())?
                }
                None => {
                    if j.moving {
                        coordinate[p] = next;
                        next += 1;
                    }
                    tree.add_joint(j.name.clone(), j.parent, placement, motion, j.limits, j.child.clone())?
                }
            };
        }
        tree.reorder_coordinates(&self.coordinate_order)?;
        Ok(tree)
    }

    // Each joint's six parameters move its placement alone (the axis and the body frames are
    // the file's), and the tree's joints are `self.joints` in order.
    fn placement_moved_by(&self, values: &[f64], param: usize) -> Option<(usize, Isometry3<f64>)> {
        let j = self
            .joints
            .iter()
            .position(|j| (j.first_param..j.first_param + 6).contains(&param))?;
        let joint = &self.joints[j];
        Some((j, self.origin(joint, self.joint_values(joint, values))))
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn KinematicsSpec> {
        let u = self.units;
        let overrides: HashMap<&str, &UrdfJointOverride> =
            self.spec.joints.iter().map(|o| (o.name.as_str(), o)).collect();
        let mut joints = Vec::new();
        for &p in &self.file_order {
            let j = &self.joints[p];
            let v = self.joint_values(j, values);
            let nominal: Vec<f64> = self.params[j.first_param..j.first_param + v.len()]
                .iter()
                .map(|p| p.nominal)
                .collect();
            if v == nominal.as_slice() {
                // Unchanged: keep what the file said, digit for digit.
                joints.extend(overrides.get(j.name.as_str()).map(|&o| o.clone()));
                continue;
            }
            let origin = self.origin(j, v);
            let (r, pi, y) = origin.rotation.euler_angles();
            let t = origin.translation.vector;
            joints.push(UrdfJointOverride {
                name: j.name.clone(),
                xyz: Some([u.len_out(t.x), u.len_out(t.y), u.len_out(t.z)]),
                rpy: Some([u.ang_out(r), u.ang_out(pi), u.ang_out(y)]),
                axis: overrides.get(j.name.as_str()).and_then(|o| o.axis),
            });
        }
        Box::new(UrdfSpec {
            path: self.resolved.display().to_string(),
            joints,
            prior: self.spec.prior,
        })
    }

    fn links(&self) -> &[LinkData] {
        &self.links
    }

    fn warnings(&self) -> &[String] {
        &self.warnings
    }
}
