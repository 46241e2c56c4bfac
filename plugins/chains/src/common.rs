//! What every convention shares: joint kinds, limits, mimic couplings, tree topology, priors,
//! and the compiler from per-joint geometry to a [`KinematicTree`].

use armcomp_core::model::geom::xyz_rpy;
use armcomp_core::{BuildContext, Coupling, Issues, KinematicTree, Limits, Motion, ParamInfo, Quantity, Result, Units};
use nalgebra::{Isometry3, Unit, Vector3};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// The joint travel (SI: rad, or m for a prismatic joint) no joint has either way of zero: 160
/// turns, or a kilometre of slide. Beyond it a limit is a typo or a unit mix-up.
const ABSURD_TRAVEL: f64 = 1e3;

/// How a joint moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "lowercase")]
pub enum JointKind {
    /// Rotation; value in the file's angle unit.
    #[default]
    Revolute,
    /// Translation; value in the file's length unit.
    Prismatic,
    /// No motion (a fixed frame in the chain).
    Fixed,
}

/// A joint that follows others: `value = offset + Σ multiplier·value(joint)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MimicSpec {
    /// The independent joints it follows (declared earlier).
    pub joints: Vec<String>,
    /// One multiplier per joint (default 1 each).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub multipliers: Vec<f64>,
    /// Constant offset, in the joint's own unit (default 0).
    #[serde(default)]
    pub offset: f64,
}

/// A fixed frame inserted before a joint's convention transform.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema, Default)]
#[serde(deny_unknown_fields)]
pub struct OriginSpec {
    /// Translation (length unit).
    #[serde(default)]
    pub xyz: [f64; 3],
    /// URDF roll-pitch-yaw (angle unit).
    #[serde(default)]
    pub rpy: [f64; 3],
}

/// Prior standard deviations of the geometric parameters, in the file's units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema, Default)]
#[serde(deny_unknown_fields)]
pub struct PriorSpec {
    /// For lengths (default 5 mm).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub length: Option<f64>,
    /// For angles (default 1 deg).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub angle: Option<f64>,
}

impl PriorSpec {
    /// Records an issue for each standard deviation that is not positive; `path` is the
    /// spec's `prior` field.
    pub fn check(&self, path: &str, issues: &mut Issues) {
        for (k, v) in [("length", self.length), ("angle", self.angle)] {
            if let Some(v) = v
                && !(v.is_finite() && v > 0.0)
            {
                issues.push(
                    format!("{path}.{k}"),
                    format!("expected a positive standard deviation, got {v}"),
                );
            }
        }
    }

    /// The prior standard deviation (SI) of a parameter of quantity `q`.
    pub fn sigma(&self, q: Quantity, units: &Units) -> f64 {
        match q {
            Quantity::Length => self.length.map_or(0.005, |v| units.len(v)),
            Quantity::Angle => self.angle.map_or(1f64.to_radians(), |v| units.ang(v)),
            _ => f64::INFINITY,
        }
    }
}

/// The `joints` of a convention's spec, read so that an error names the joint and its field
/// (`kinematics.joints[2].kind`), not the whole `kinematics` table.
pub(crate) fn joints<'de, D, T>(d: D) -> std::result::Result<Vec<T>, D::Error>
where
    D: serde::Deserializer<'de>,
    T: serde::Deserialize<'de>,
{
    armcomp_core::robot::robot_file::tracked(d, "joints")
}

/// Declares a convention's joint struct: the shared fields plus the convention's own geometry.
macro_rules! joint_spec {
    ($(#[$m:meta])* $name:ident { $($(#[$fm:meta])* $field:ident : $ty:ty,)* }) => {
        $(#[$m])*
        #[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize, schemars::JsonSchema)]
        #[serde(deny_unknown_fields)]
        pub struct $name {
            /// Joint name, unique in the robot; its link is named after it unless `link` is given.
            pub name: String,
            /// `revolute` (default), `prismatic` or `fixed`.
            #[serde(default)]
            pub kind: $crate::common::JointKind,
            /// The link this joint hangs from (default: the previous joint's link, `base` first).
            #[serde(default, skip_serializing_if = "Option::is_none")]
            pub parent: Option<String>,
            /// Name of the link this joint moves (default: the joint's name).
            #[serde(default, skip_serializing_if = "Option::is_none")]
            pub link: Option<String>,
            /// `[lower, upper]` in the file's angle (revolute) or length (prismatic) unit.
            #[serde(default, skip_serializing_if = "Option::is_none")]
            pub limits: Option<[f64; 2]>,
            /// Coupling to earlier joints instead of an own coordinate.
            #[serde(default, skip_serializing_if = "Option::is_none")]
            pub mimic: Option<$crate::common::MimicSpec>,
            /// A fixed frame between the parent link and this joint's convention transform.
            #[serde(default, skip_serializing_if = "Option::is_none")]
            pub origin: Option<$crate::common::OriginSpec>,
            $($(#[$fm])* pub $field: $ty,)*
        }

        impl $name {
            pub(crate) fn common(&self) -> $crate::common::JointCommon<'_> {
                $crate::common::JointCommon {
                    name: &self.name,
                    kind: self.kind,
                    parent: self.parent.as_deref(),
                    link: self.link.as_deref(),
                    limits: self.limits,
                    mimic: self.mimic.as_ref(),
                    origin: self.origin,
                }
            }
        }
    };
}
pub(crate) use joint_spec;

/// The shared fields of one joint, borrowed from its spec.
pub(crate) struct JointCommon<'a> {
    pub name: &'a str,
    pub kind: JointKind,
    pub parent: Option<&'a str>,
    pub link: Option<&'a str>,
    pub limits: Option<[f64; 2]>,
    pub mimic: Option<&'a MimicSpec>,
    pub origin: Option<OriginSpec>,
}

/// One joint of a compiled chain: topology, limits, coupling, and where its parameters are.
#[derive(Debug, Clone)]
struct JointTopo {
    name: String,
    kind: JointKind,
    parent: usize,
    child: String,
    limits: Option<Limits>,
    mimic: Option<Coupling>,
    origin: Isometry3<f64>,
    first_param: usize,
}

/// The part of a convention that varies: a joint's frames from its parameter values.
pub(crate) struct JointGeometry {
    /// Joint frame in the parent link's convention frame (after any `origin`).
    pub pre: Isometry3<f64>,
    /// Motion axis in the joint frame.
    pub axis: Unit<Vector3<f64>>,
    /// The convention frame of the child link in the joint's moving frame.
    pub post: Isometry3<f64>,
}

/// Topology and parameters of a compiled chain, shared by every convention.
#[derive(Debug, Clone)]
pub(crate) struct ChainCore {
    base: String,
    joints: Vec<JointTopo>,
    params: Vec<ParamInfo>,
}

impl ChainCore {
    /// Resolves names, limits and couplings, and lays out the parameters: joint `i` owns
    /// `per_joint[i]` = `(suffix, quantity, nominal SI)` entries, named `<joint>.<suffix>`.
    pub fn resolve(
        base: &str,
        joints: &[JointCommon<'_>],
        per_joint: Vec<Vec<(&'static str, Quantity, f64)>>,
        prior: &PriorSpec,
        ctx: &BuildContext<'_>,
    ) -> Result<ChainCore, Issues> {
        let mut resolver = Resolver {
            issues: Issues::default(),
            units: ctx.units,
            prior,
            bodies: vec![base.to_string()],
            coord_of: Vec::new(),
            ncoord: 0,
            params: Vec::new(),
        };
        if joints.is_empty() {
            resolver
                .issues
                .push(format!("{}.joints", ctx.path), "expected at least one joint");
        }
        let mut topo = Vec::new();
        for (i, (j, geo)) in joints.iter().zip(per_joint).enumerate() {
            topo.push(resolver.joint(j, geo, &format!("{}.joints[{i}]", ctx.path)));
        }
        let Resolver { mut issues, params, .. } = resolver;
        prior.check(&format!("{}.prior", ctx.path), &mut issues);
        if !issues.is_empty() {
            return Err(issues);
        }
        Ok(ChainCore {
            base: base.to_string(),
            joints: topo,
            params,
        })
    }

    /// Identifiable parameters, in joint order.
    pub fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    /// The parameter values of joint `j`.
    pub fn joint_values<'v>(&self, values: &'v [f64], j: usize) -> &'v [f64] {
        let start = self.joints[j].first_param;
        let end = self.joints.get(j + 1).map_or(self.params.len(), |n| n.first_param);
        &values[start..end]
    }

    /// The joint that owns parameter `param` and its placement at `values`, for conventions
    /// whose bodies keep their joint's frame (`post` the identity) and whose axes are fixed:
    /// there a parameter moves its own joint's placement and nothing else.
    pub fn placement_moved_by(
        &self,
        values: &[f64],
        param: usize,
        pre: impl Fn(&[f64]) -> Isometry3<f64>,
    ) -> Option<(usize, Isometry3<f64>)> {
        let j = self.joints.iter().rposition(|t| t.first_param <= param)?;
        Some((j, self.joints[j].origin * pre(self.joint_values(values, j))))
    }

    /// Compiles the tree; `geometry(j, values_of_j)` gives each joint's frames.
    pub fn tree(
        &self,
        values: &[f64],
        geometry: impl Fn(usize, &[f64]) -> Result<JointGeometry>,
    ) -> Result<KinematicTree> {
        if values.len() != self.params.len() {
            return Err(armcomp_core::Error::Dimension {
                what: "chain parameters".into(),
                expected: self.params.len(),
                got: values.len(),
            });
        }
        let mut tree = KinematicTree::new(self.base.clone());
        for (j, t) in self.joints.iter().enumerate() {
            let g = geometry(j, self.joint_values(values, j))?;
            let parent_frame = tree.bodies()[t.parent].convention_frame;
            let placement = parent_frame * t.origin * g.pre;
            let motion = match t.kind {
                JointKind::Revolute => Motion::Revolute(g.axis),
                JointKind::Prismatic => Motion::Prismatic(g.axis),
                JointKind::Fixed => Motion::Fixed,
            };
            let body = match &t.mimic {
                Some(coupling) => tree.add_mimic_joint(
                    t.name.clone(),
                    t.parent,
                    placement,
                    motion,
                    coupling.clone(),
                    t.child.clone(),
                )?,
                None => tree.add_joint(t.name.clone(), t.parent, placement, motion, t.limits, t.child.clone())?,
            };
            tree.set_convention_frame(body, g.post);
        }
        Ok(tree)
    }
}

/// What [`ChainCore::resolve`] knows of the joints before the next: the links and joint
/// names defined so far, the coordinates handed out and the parameters laid out, and the
/// issues found.
struct Resolver<'p> {
    issues: Issues,
    units: Units,
    prior: &'p PriorSpec,
    /// Link names, the base first.
    bodies: Vec<String>,
    /// Every joint's name and its own coordinate (none for fixed and mimic joints).
    coord_of: Vec<(String, Option<usize>)>,
    ncoord: usize,
    params: Vec<ParamInfo>,
}

impl Resolver<'_> {
    /// Resolves joint `j` with its parameters `geo`; `path` is its field in the file.
    fn joint(&mut self, j: &JointCommon<'_>, geo: Vec<(&'static str, Quantity, f64)>, path: &str) -> JointTopo {
        let units = self.units;
        if self.coord_of.iter().any(|(n, _)| n == j.name) {
            self.issues
                .push(format!("{path}.name"), format!("joint `{}` is defined twice", j.name));
        }
        let child = j.link.unwrap_or(j.name).to_string();
        if self.bodies.contains(&child) {
            self.issues
                .push(format!("{path}.link"), format!("link `{child}` is defined twice"));
        }
        let parent = self.parent(j, path);
        let limits = self.limits(j, path);
        let mimic = j.mimic.map(|m| self.coupling(j, m, path));
        let own_coord = if j.kind != JointKind::Fixed && mimic.is_none() {
            self.ncoord += 1;
            Some(self.ncoord - 1)
        } else {
            None
        };
        self.coord_of.push((j.name.to_string(), own_coord));
        let origin = j.origin.unwrap_or_default();
        if origin.xyz.iter().chain(&origin.rpy).any(|v| !v.is_finite()) {
            self.issues.push(format!("{path}.origin"), "expected finite numbers");
        }
        let first_param = self.params.len();
        self.lay_out(j, geo, path);
        self.bodies.push(child.clone());
        JointTopo {
            name: j.name.to_string(),
            kind: j.kind,
            parent,
            child,
            limits,
            mimic,
            origin: xyz_rpy(units.len3(origin.xyz), units.ang3(origin.rpy)),
            first_param,
        }
    }

    /// A value of joint `j` in the file's unit, SI.
    fn scale(&self, j: &JointCommon<'_>, v: f64) -> f64 {
        if j.kind == JointKind::Prismatic {
            self.units.len(v)
        } else {
            self.units.ang(v)
        }
    }

    /// The index of the link joint `j` hangs from: the named one, or the last defined.
    fn parent(&mut self, j: &JointCommon<'_>, path: &str) -> usize {
        match j.parent {
            None => self.bodies.len() - 1,
            Some(p) => match self.bodies.iter().position(|b| b == p) {
                Some(k) => k,
                None => {
                    self.issues.push(
                        format!("{path}.parent"),
                        format!(
                            "link `{p}` is not defined before this joint; defined so far: {}",
                            self.bodies.join(", ")
                        ),
                    );
                    0
                }
            },
        }
    }

    /// Joint `j`'s limits, SI, when it has usable ones.
    fn limits(&mut self, j: &JointCommon<'_>, path: &str) -> Option<Limits> {
        match j.limits {
            Some([lo, hi]) if !(lo.is_finite() && hi.is_finite()) => {
                self.issues
                    .push(format!("{path}.limits"), "expected two finite numbers [lower, upper]");
                None
            }
            Some([lo, hi]) if lo > hi => {
                self.issues.push(
                    format!("{path}.limits"),
                    format!("lower limit {lo} is above upper limit {hi}"),
                );
                None
            }
            Some([lo, hi]) if lo == hi => {
                self.issues.push(
                    format!("{path}.limits"),
                    format!(
                        "equal limits [{lo}, {hi}] leave the joint no travel; make it `fixed`, or hold it with `[measurement] hold`"
                    ),
                );
                None
            }
            Some([lo, hi]) if self.scale(j, lo).abs().max(self.scale(j, hi).abs()) > ABSURD_TRAVEL => {
                self.issues.push(
                    format!("{path}.limits"),
                    format!(
                        "limits [{lo:e}, {hi:e}] are physically absurd; expected at most {ABSURD_TRAVEL} {} either way",
                        if j.kind == JointKind::Prismatic { "m" } else { "rad" }
                    ),
                );
                None
            }
            Some(_) if j.kind == JointKind::Fixed => {
                self.issues
                    .push(format!("{path}.limits"), "a fixed joint has no limits");
                None
            }
            Some([lo, hi]) => Some(Limits {
                lower: self.scale(j, lo),
                upper: self.scale(j, hi),
            }),
            None => None,
        }
    }

    /// The coupling of the mimic joint `j` to the earlier joints `m` names.
    fn coupling(&mut self, j: &JointCommon<'_>, m: &MimicSpec, path: &str) -> Coupling {
        if j.kind == JointKind::Fixed {
            self.issues
                .push(format!("{path}.mimic"), "a fixed joint cannot follow other joints");
        }
        if j.limits.is_some() {
            self.issues.push(
                format!("{path}.limits"),
                "a mimic joint takes its range from the joints it follows; remove `limits`",
            );
        }
        if !m.multipliers.is_empty() && m.multipliers.len() != m.joints.len() {
            self.issues.push(
                format!("{path}.mimic.multipliers"),
                format!(
                    "expected one multiplier per followed joint ({}), got {}",
                    m.joints.len(),
                    m.multipliers.len()
                ),
            );
        }
        if let Some(k) = m.multipliers.iter().position(|v| !v.is_finite()) {
            self.issues.push(
                format!("{path}.mimic.multipliers[{k}]"),
                format!("expected a finite number, got {}", m.multipliers[k]),
            );
        }
        if m.joints.is_empty() {
            self.issues
                .push(format!("{path}.mimic.joints"), "expected at least one joint to follow");
        }
        let terms = m
            .joints
            .iter()
            .enumerate()
            .filter_map(|(k, name)| {
                let mult = m.multipliers.get(k).copied().unwrap_or(1.0);
                match self.coord_of.iter().find(|(n, _)| n == name) {
                    Some((_, Some(c))) => Some((*c, mult)),
                    Some((_, None)) => {
                        self.issues.push(
                            format!("{path}.mimic.joints[{k}]"),
                            format!("joint `{name}` is fixed or itself a mimic joint"),
                        );
                        None
                    }
                    None => {
                        self.issues.push(
                            format!("{path}.mimic.joints[{k}]"),
                            format!("joint `{name}` is not defined before this joint"),
                        );
                        None
                    }
                }
            })
            .collect();
        Coupling {
            terms,
            offset: self.scale(j, m.offset),
        }
    }

    /// Lays out joint `j`'s parameters `geo` after those of the joints before it, named
    /// `<joint>.<suffix>`, each with its prior.
    fn lay_out(&mut self, j: &JointCommon<'_>, geo: Vec<(&'static str, Quantity, f64)>, path: &str) {
        for (suffix, quantity, nominal) in geo {
            let param = ParamInfo::new(
                format!("{}.{suffix}", j.name),
                quantity,
                nominal,
                self.prior.sigma(quantity, &self.units),
            );
            if !nominal.is_finite() {
                self.issues.push(format!("{path}.{suffix}"), "expected a finite number");
            } else if let Some(why) = param.absurdity(nominal) {
                self.issues.push(format!("{path}.{suffix}"), why);
            }
            self.params.push(param);
        }
    }
}
