//! Lateral joint compliance (as identified for DLR's Agile Justin): a joint tilts about the
//! two axes perpendicular to its motion axis in proportion to the bending moment it carries,
//! `δ_u = c_u · M_u`, `δ_v = c_v · M_v`, with `M` the gravity moment of everything beyond the
//! joint about the joint origin. The axes are the joint frame's x made perpendicular to the
//! motion axis (`u`) and `v = axis × u` (for MDH joints: the joint frame's x and y).
//!
//! A telescopic section (a prismatic joint) leans in its guide the same way, about the joint's
//! frame before the motion, where it leaves the guide. With an `overlap`, the length of the
//! section inside its guide at joint value 0, the compliance is the one at that overlap and grows
//! as `(overlap / (overlap − q))²` as the section slides out by `q`: the guide's bearings, spread
//! over less length, hold the moment with forces that grow as one over their spacing, and the
//! lean is their play-free deflection over that spacing.

use std::collections::BTreeMap;

use armcomp_core::{
    ErrorModel, ErrorModelSpec, Issues, ModelContext, Motion, ParamInfo, Perturbation, Quantity, StaticState,
};
use nalgebra::{Vector3, Vector6};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::common::{check_finite, name_list};
use armcomp_core::plugin::gravity::subtree_wrench;

/// Lateral compliance as written in the robot file.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LateralComplianceSpec {
    /// Per joint name: `[c_u, c_v]` in rad/(N m) about the two axes perpendicular to its axis.
    pub compliance: BTreeMap<String, [f64; 2]>,
    /// Per prismatic joint of `compliance` (a telescopic section): how far the section reaches
    /// into its guide at joint value 0, in the file's length unit. Its compliance is the one at
    /// that overlap, scaled by `(overlap / (overlap − q))²` as it slides out by `q`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub overlap: BTreeMap<String, f64>,
}

/// The shortest overlap, as a share of the overlap at joint value 0, the scaling follows: a
/// section out beyond this is about to leave its guide, and the lean is held at that value
/// rather than grow without bound.
const MIN_OVERLAP_SHARE: f64 = 0.1;

#[derive(Debug, Clone)]
struct LateralJoint {
    joint: usize,
    /// The perpendicular axes in joint-frame coordinates.
    u: Vector3<f64>,
    v: Vector3<f64>,
    /// For a telescopic section: its overlap with the guide at joint value 0 (m).
    overlap: Option<f64>,
}

/// The built lateral-compliance model.
#[derive(Debug, Clone)]
pub struct LateralComplianceModel {
    spec: LateralComplianceSpec,
    joints: Vec<LateralJoint>,
    params: Vec<ParamInfo>,
}

#[typetag::serde(name = "lateral_compliance")]
impl ErrorModelSpec for LateralComplianceSpec {
    fn build(&self, ctx: &ModelContext<'_>) -> Result<Box<dyn ErrorModel>, Issues> {
        let tree = ctx.tree;
        let path = ctx.build.path;
        let mut issues = Issues::default();
        if self.compliance.is_empty() {
            issues.push(
                format!("{path}.compliance"),
                "expected at least one joint, e.g. compliance = { j2 = [1e-6, 1e-6] }",
            );
        }
        let mut joints = Vec::new();
        let mut params = Vec::new();
        for (name, c) in &self.compliance {
            let p = format!("{path}.compliance.{name}");
            let Some(j) = tree.joint_index(name) else {
                issues.push(
                    p,
                    format!(
                        "joint `{name}` does not exist; joints are: {}",
                        name_list(tree.joints().iter().map(|j| j.name.as_str()))
                    ),
                );
                continue;
            };
            let axis = match tree.joints()[j].motion {
                Motion::Revolute(a) | Motion::Prismatic(a) => a.into_inner(),
                Motion::Fixed => Vector3::z(),
            };
            let mut ok = true;
            for (k, v) in c.iter().enumerate() {
                ok &= check_finite(&mut issues, &format!("{p}[{k}]"), *v);
                if *v < 0.0 {
                    issues.push(
                        format!("{p}[{k}]"),
                        format!("expected a compliance of zero or more, got {v}"),
                    );
                    ok = false;
                }
            }
            if !ok {
                continue;
            }
            let mut u = Vector3::x() - axis * axis.x;
            if u.norm() < 1e-6 {
                u = Vector3::y() - axis * axis.y;
            }
            let u = u.normalize();
            let v = axis.cross(&u);
            let overlap = match self.overlap.get(name) {
                None => None,
                Some(&o) => {
                    let p = format!("{path}.overlap.{name}");
                    if !matches!(tree.joints()[j].motion, Motion::Prismatic(_)) {
                        issues.push(
                            p,
                            "an overlap is for a prismatic joint (a telescopic section in its guide)",
                        );
                        continue;
                    }
                    if !(o.is_finite() && o > 0.0) {
                        issues.push(p, format!("expected a positive length, got {o}"));
                        continue;
                    }
                    Some(ctx.build.units.len(o))
                }
            };
            joints.push((
                j,
                LateralJoint {
                    joint: j,
                    u,
                    v,
                    overlap,
                },
                *c,
            ));
        }
        for name in self.overlap.keys().filter(|n| !self.compliance.contains_key(*n)) {
            issues.push(
                format!("{path}.overlap.{name}"),
                format!("joint `{name}` has no compliance here; give it one in `compliance` too"),
            );
        }
        if !issues.is_empty() {
            return Err(issues);
        }
        joints.sort_by_key(|(j, _, _)| *j);
        for (j, _, c) in &joints {
            for (k, axis) in ["u", "v"].iter().enumerate() {
                params.push(
                    ParamInfo::new(
                        format!("lateral_compliance.{}.{axis}", tree.joints()[*j].name),
                        Quantity::Compliance,
                        c[k],
                        f64::INFINITY,
                    )
                    // The spec accepts no negative compliance.
                    .with_bounds(0.0, f64::INFINITY)
                    .with_plausible(0.0, crate::joint_compliance::PLAUSIBLE_ROTATIONAL_COMPLIANCE),
                );
            }
        }
        Ok(Box::new(LateralComplianceModel {
            spec: self.clone(),
            joints: joints.into_iter().map(|(_, l, _)| l).collect(),
            params,
        }))
    }
}

impl ErrorModel for LateralComplianceModel {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    fn perturb(&self, state: &StaticState<'_>, values: &[f64], out: &mut Perturbation) {
        for (i, l) in self.joints.iter().enumerate() {
            let (mut cu, mut cv) = (values[2 * i], values[2 * i + 1]);
            if cu == 0.0 && cv == 0.0 {
                continue;
            }
            if let Some(o) = l.overlap {
                let left = (o - state.tree.joint_value(l.joint, state.q)).max(MIN_OVERLAP_SHARE * o);
                let scale = (o / left).powi(2);
                cu *= scale;
                cv *= scale;
            }
            let frame = &state.frames.joint_frame[l.joint];
            let origin = frame.translation.vector;
            let (_, m) = subtree_wrench(state, l.joint + 1, &origin);
            let m_local = frame.rotation.inverse_transform_vector(&m);
            let d = l.u * (cu * l.u.dot(&m_local)) + l.v * (cv * l.v.dot(&m_local));
            out.joint_twist[l.joint] += Vector6::new(0.0, 0.0, 0.0, d.x, d.y, d.z);
        }
    }

    fn is_inactive(&self, values: &[f64]) -> bool {
        values.iter().all(|&c| c == 0.0)
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn ErrorModelSpec> {
        let mut spec = self.spec.clone();
        for (i, p) in self.params.chunks(2).enumerate() {
            let name = p[0]
                .name
                .trim_start_matches("lateral_compliance.")
                .trim_end_matches(".u");
            spec.compliance
                .insert(name.to_string(), [values[2 * i], values[2 * i + 1]]);
        }
        Box::new(spec)
    }
}
