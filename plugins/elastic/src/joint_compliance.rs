//! Joint compliance: each joint gives way in proportion to the gravity load it carries,
//! `dq_i = c_i · τ_i(q)` (DESIGN formulas), with `τ_i` the gravity torque about the joint axis
//! (or force along it, for a prismatic joint) of everything the joint moves, payload included.
//! Without a torque sensor only `c_i` times the masses is identifiable.
//!
//! Mimic couplings are taken as mechanical (a linkage, like the one that keeps Agile Justin's
//! chest upright): the drive of an independent joint carries the generalised gravity force of
//! its coordinate, its own torque plus `k · τ_m` of every joint `m` coupled to it with
//! multiplier `k` (virtual work), and its deflection moves those joints too (`k · dq_i`). A
//! compliance given for a mimic joint is the coupling's own elasticity, `c_m · τ_m` on that
//! joint alone.

use std::collections::BTreeMap;

use armcomp_core::{
    Coordinate, ErrorModel, ErrorModelSpec, Issues, KinematicTree, ModelContext, Motion, ParamInfo, Perturbation,
    Quantity, StaticState,
};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::common::resolve_joint_table;
use armcomp_core::plugin::gravity::joint_gravity_load;

/// Checks a compliance: finite and not negative.
pub(crate) fn check_compliance(issues: &mut Issues, path: &str, v: f64) -> bool {
    let ok = v.is_finite() && v >= 0.0;
    if !ok {
        issues.push(
            path,
            format!("expected a compliance of zero or more (rad/(N m), or m/N for prismatic joints), got {v}"),
        );
    }
    ok
}

/// The unit of a joint's compliance.
/// The largest plausible rotational compliance (rad/(N m)): 10 N m turns a hobby servo by
/// 6°; every real arm is stiffer.
pub(crate) const PLAUSIBLE_ROTATIONAL_COMPLIANCE: f64 = 1e-2;

/// The largest plausible linear compliance of a slide (m/N): 10 N push it by 1 cm.
const PLAUSIBLE_LINEAR_COMPLIANCE: f64 = 1e-3;

pub(crate) fn compliance_quantity(motion: &Motion) -> Quantity {
    match motion {
        Motion::Prismatic(_) => Quantity::Other("m/N"),
        _ => Quantity::Compliance,
    }
}

/// Joint compliance as written in the robot file.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct JointComplianceSpec {
    /// Compliance per joint name: rad/(N m) for revolute joints, m/N for prismatic ones.
    pub compliance: BTreeMap<String, f64>,
}

/// A compliant joint and the mimic joints coupled to its coordinate.
#[derive(Debug, Clone)]
struct CompliantJoint {
    joint: usize,
    /// `(mimic joint, multiplier)`; empty for mimic joints themselves.
    followers: Vec<(usize, f64)>,
}

/// The built joint-compliance model.
#[derive(Debug, Clone)]
pub struct JointComplianceModel {
    spec: JointComplianceSpec,
    joints: Vec<CompliantJoint>,
    params: Vec<ParamInfo>,
}

/// The mimic joints of `tree` that follow the coordinate of joint `j`, with their multipliers.
fn followers(tree: &KinematicTree, j: usize) -> Vec<(usize, f64)> {
    let Coordinate::Independent(i) = tree.joints()[j].coordinate else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for (m, joint) in tree.joints().iter().enumerate() {
        if let Coordinate::Mimic(c) = &joint.coordinate {
            let k: f64 = c.terms.iter().filter(|(c, _)| *c == i).map(|(_, k)| k).sum();
            if k != 0.0 {
                out.push((m, k));
            }
        }
    }
    out
}

#[typetag::serde(name = "joint_compliance")]
impl ErrorModelSpec for JointComplianceSpec {
    fn build(&self, ctx: &ModelContext<'_>) -> Result<Box<dyn ErrorModel>, Issues> {
        let mut issues = Issues::default();
        if self.compliance.is_empty() {
            issues.push(
                format!("{}.compliance", ctx.build.path),
                "expected at least one joint, e.g. compliance = { j2 = 1e-6 }",
            );
        }
        let resolved = resolve_joint_table(ctx, "compliance", &self.compliance, &mut issues, check_compliance);
        if !issues.is_empty() {
            return Err(issues);
        }
        let joints = ctx.tree.joints();
        let params = resolved
            .iter()
            .map(|&(j, v)| {
                ParamInfo::new(
                    format!("joint_compliance.{}", joints[j].name),
                    compliance_quantity(&joints[j].motion),
                    v,
                    f64::INFINITY,
                )
                // A negative compliance is not physical, and the spec rejects it.
                .with_bounds(0.0, f64::INFINITY)
                .with_plausible(
                    0.0,
                    match joints[j].motion {
                        Motion::Prismatic(_) => PLAUSIBLE_LINEAR_COMPLIANCE,
                        _ => PLAUSIBLE_ROTATIONAL_COMPLIANCE,
                    },
                )
            })
            .collect();
        Ok(Box::new(JointComplianceModel {
            spec: self.clone(),
            joints: resolved
                .iter()
                .map(|&(joint, _)| CompliantJoint {
                    joint,
                    followers: followers(ctx.tree, joint),
                })
                .collect(),
            params,
        }))
    }
}

impl ErrorModel for JointComplianceModel {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    fn perturb(&self, state: &StaticState<'_>, values: &[f64], out: &mut Perturbation) {
        for (cj, &c) in self.joints.iter().zip(values) {
            if c == 0.0 {
                continue;
            }
            let mut load = joint_gravity_load(state, cj.joint);
            for &(m, k) in &cj.followers {
                load += k * joint_gravity_load(state, m);
            }
            let dq = c * load;
            out.joint_offset[cj.joint] += dq;
            for &(m, k) in &cj.followers {
                out.joint_offset[m] += k * dq;
            }
        }
    }

    fn is_inactive(&self, values: &[f64]) -> bool {
        values.iter().all(|&c| c == 0.0)
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn ErrorModelSpec> {
        let mut spec = self.spec.clone();
        for (p, &v) in self.params.iter().zip(values) {
            let name = p.name.trim_start_matches("joint_compliance.");
            spec.compliance.insert(name.to_string(), v);
        }
        Box::new(spec)
    }
}
