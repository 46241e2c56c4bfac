//! Joint compliance: each joint gives way in proportion to the gravity load it carries,
//! `dq_i = c_i · τ_i(q)` (DESIGN formulas), with `τ_i` the gravity torque about the joint axis
//! (or force along it, for a prismatic joint) of everything the joint moves, payload included.
//! Without a torque sensor only `c_i` times the masses is identifiable.

use std::collections::BTreeMap;

use armcomp_core::{
    ErrorModel, ErrorModelSpec, Issues, ModelContext, Motion, ParamInfo, Perturbation, Quantity, StaticState,
};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::common::resolve_joint_table;
use armcomp_core::gravity::{Subtrees, joint_gravity_load};

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

/// The built joint-compliance model.
#[derive(Debug, Clone)]
pub struct JointComplianceModel {
    spec: JointComplianceSpec,
    joints: Vec<usize>,
    subtrees: Subtrees,
    params: Vec<ParamInfo>,
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
            })
            .collect();
        Ok(Box::new(JointComplianceModel {
            spec: self.clone(),
            joints: resolved.iter().map(|(j, _)| *j).collect(),
            subtrees: Subtrees::new(ctx.tree),
            params,
        }))
    }
}

impl ErrorModel for JointComplianceModel {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    fn perturb(&self, state: &StaticState<'_>, values: &[f64], out: &mut Perturbation) {
        for (&j, &c) in self.joints.iter().zip(values) {
            out.joint_offset[j] += c * joint_gravity_load(state, &self.subtrees, j);
        }
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
