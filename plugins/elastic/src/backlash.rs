//! Backlash: each listed joint sits at one side of its gear dead band, the side gravity pushes
//! it to: `dq = b · tanh(τ / τ_s)`, with `b` half the dead band and `τ` the gravity torque
//! about the joint (force along it for prismatic joints). `τ_s` smooths the switch so that IK
//! and calibration see a differentiable model.

use std::collections::BTreeMap;

use armcomp_core::{
    ErrorModel, ErrorModelSpec, Issues, ModelContext, Motion, ParamInfo, Perturbation, Quantity, StaticState,
};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::common::{check_positive, resolve_joint_table};
use armcomp_core::plugin::gravity::joint_gravity_load;

fn default_smoothing() -> f64 {
    1.0
}

/// Backlash as written in the robot file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BacklashSpec {
    /// Half dead band per joint name, in the file's angle (or length, for prismatic) unit.
    pub backlash: BTreeMap<String, f64>,
    /// Torque (N m, or force in N) over which the joint crosses its dead band (default 1).
    #[serde(default = "default_smoothing")]
    pub smoothing: f64,
}

/// The built backlash model.
#[derive(Debug, Clone)]
pub struct BacklashModel {
    spec: BacklashSpec,
    units: armcomp_core::Units,
    joints: Vec<(usize, bool)>,
    params: Vec<ParamInfo>,
}

#[typetag::serde(name = "backlash")]
impl ErrorModelSpec for BacklashSpec {
    fn build(&self, ctx: &ModelContext<'_>) -> Result<Box<dyn ErrorModel>, Issues> {
        let mut issues = Issues::default();
        let path = ctx.build.path;
        if self.backlash.is_empty() {
            issues.push(
                format!("{path}.backlash"),
                "expected at least one joint, e.g. backlash = { j2 = 0.01 }",
            );
        }
        check_positive(
            &mut issues,
            &format!("{path}.smoothing"),
            self.smoothing,
            "torque in N m",
        );
        // A play is a width: zero or more.
        let resolved = resolve_joint_table(ctx, "backlash", &self.backlash, &mut issues, |i, p, v| {
            let ok = v.is_finite() && v >= 0.0;
            if !ok {
                i.push(p, format!("expected a play of zero or more, got {v}"));
            }
            ok
        });
        if !issues.is_empty() {
            return Err(issues);
        }
        let u = ctx.build.units;
        let tree = ctx.tree;
        let mut joints = Vec::new();
        let mut params = Vec::new();
        for (j, v) in resolved {
            let prismatic = matches!(tree.joints()[j].motion, Motion::Prismatic(_));
            let (q, si) = if prismatic {
                (Quantity::Length, u.len(v))
            } else {
                (Quantity::Angle, u.ang(v))
            };
            params.push(
                ParamInfo::new(format!("backlash.{}", tree.joints()[j].name), q, si, f64::INFINITY)
                    .with_bounds(0.0, f64::INFINITY)
                    // Gear trains play by hundredths of a degree, worn ones by tenths; a
                    // millimetre-scale play is a loose slide.
                    .with_plausible(0.0, if prismatic { 5e-3 } else { 1f64.to_radians() })
                    // The play's effect flips with the load's sign: a fit from zero may stop short.
                    .multimodal(),
            );
            joints.push((j, prismatic));
        }
        Ok(Box::new(BacklashModel {
            spec: self.clone(),
            units: u,
            joints,
            params,
        }))
    }
}

impl ErrorModel for BacklashModel {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    fn perturb(&self, state: &StaticState<'_>, values: &[f64], out: &mut Perturbation) {
        for (&(j, _), &b) in self.joints.iter().zip(values) {
            let tau = joint_gravity_load(state, j);
            out.joint_offset[j] += b * (tau / self.spec.smoothing).tanh();
        }
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn ErrorModelSpec> {
        let mut spec = self.spec.clone();
        for ((p, &(_, prismatic)), &v) in self.params.iter().zip(&self.joints).zip(values) {
            let name = p.name.trim_start_matches("backlash.").to_string();
            let out = if prismatic {
                self.units.len_out(v)
            } else {
                self.units.ang_out(v)
            };
            spec.backlash.insert(name, out);
        }
        Box::new(spec)
    }
}
