//! Payload mass error: the payload weighs `(1 + s)·m + Δm` where the file or the measurement
//! declares `m`: a relative scale error `s` for declared masses wrong by a factor (a scale
//! calibrated wrongly, a gripper's share), an offset `Δm` for a constant error (an unlisted
//! adapter). Both enter linearly, like `transmission_scale`. The extra weight `s·m + Δm` bends the joints it hangs from through their compliances:
//! `dq_i = c_i · τ_i`, `τ_i` its torque about joint `i` (force along it for prismatic joints).
//!
//! Bounds keep the identified values physical: `s ≥ −1`, and `Δm ≥ −m_file` (the file's
//! payload, 0 without one), so a payload declared as the file's, or as nothing, never comes
//! out with a negative mass.

use std::collections::BTreeMap;

use armcomp_core::{
    ErrorModel, ErrorModelSpec, Issues, ModelContext, Motion, ParamInfo, Perturbation, Quantity, StaticState,
};
use nalgebra::Vector3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::common::{check_finite, name_list, resolve_joint_table};
use crate::joint_compliance::check_compliance;

/// Payload mass error as written in the robot file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PayloadMassErrorSpec {
    /// Extra mass (kg; negative when the payload is lighter than declared).
    #[serde(default)]
    pub mass: f64,
    /// Relative error of the declared payload mass: it weighs `1 + scale` times what is
    /// declared (plus `mass`).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub scale: f64,
    /// Where the extra mass hangs (default: the declared payload, or the point `tool`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point: Option<String>,
    /// Joint compliances (rad/(N m), m/N for prismatic joints) through which it acts.
    pub compliance: BTreeMap<String, f64>,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// Where a payload mass error hangs.
#[derive(Debug, Clone, Copy)]
enum Site {
    /// At a tree point (index).
    Point(usize),
    /// At the declared payload.
    Payload,
}

/// The built payload-mass-error model.
#[derive(Debug, Clone)]
pub struct PayloadMassErrorModel {
    spec: PayloadMassErrorSpec,
    /// Where the extra mass hangs: a point of the tree being evaluated, or the declared
    /// payload of the mass model being evaluated (either may move during calibration).
    site: Site,
    /// The body it hangs on.
    body: usize,
    compliance: Vec<(usize, f64)>,
    params: Vec<ParamInfo>,
}

#[typetag::serde(name = "payload_mass_error")]
impl ErrorModelSpec for PayloadMassErrorSpec {
    fn build(&self, ctx: &ModelContext<'_>) -> Result<Box<dyn ErrorModel>, Issues> {
        let path = ctx.build.path;
        let tree = ctx.tree;
        let mut issues = Issues::default();
        check_finite(&mut issues, &format!("{path}.mass"), self.mass);
        if !(self.scale.is_finite() && self.scale >= -1.0) {
            issues.push(
                format!("{path}.scale"),
                format!("expected a relative error of -1 or more, got {}", self.scale),
            );
        }
        let declared = ctx.mass.payload.as_ref().map_or(0.0, |p| p.mass);
        if self.compliance.is_empty() {
            issues.push(format!("{path}.compliance"), "expected at least one joint compliance");
        }
        let compliance = resolve_joint_table(ctx, "compliance", &self.compliance, &mut issues, check_compliance);
        let at = match (&self.point, &ctx.mass.payload) {
            (Some(name), _) => tree.point_index(name).map(|p| (tree.points()[p].body, Site::Point(p))),
            (None, Some(p)) => Some((p.body, Site::Payload)),
            (None, None) => tree
                .point_index("tool")
                .map(|p| (tree.points()[p].body, Site::Point(p))),
        };
        if at.is_none() {
            issues.push(
                format!("{path}.point"),
                format!(
                    "point `{}` does not exist; points are: {}",
                    self.point.as_deref().unwrap_or("tool"),
                    name_list(tree.points().iter().map(|p| p.name.as_str()))
                ),
            );
        }
        let Some((body, site)) = at.filter(|_| issues.is_empty()) else {
            return Err(issues);
        };
        let compliance = compliance
            .into_iter()
            .filter(|(j, _)| tree.support(body).contains(j))
            .collect();
        Ok(Box::new(PayloadMassErrorModel {
            spec: self.clone(),
            site,
            body,
            compliance,
            params: vec![
                // A payload mis-declared by more than its own mass (or 20 kg for light ones)
                // is a different payload.
                ParamInfo::new("payload_mass_error.mass", Quantity::Mass, self.mass, f64::INFINITY)
                    .with_bounds(-declared, f64::INFINITY)
                    .with_plausible(-declared, declared.max(20.0)),
                ParamInfo::new(
                    "payload_mass_error.scale",
                    Quantity::Dimensionless,
                    self.scale,
                    f64::INFINITY,
                )
                .with_bounds(-1.0, f64::INFINITY)
                // Scales and catalogue masses are off by percents; by half is another payload.
                .with_plausible(-0.5, 0.5),
            ],
        }))
    }
}

impl ErrorModel for PayloadMassErrorModel {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    fn perturb(&self, state: &StaticState<'_>, values: &[f64], out: &mut Perturbation) {
        let declared = state.mass.payload.as_ref().map_or(0.0, |p| p.mass);
        let f = state.gravity * (values[0] + values[1] * declared);
        let local = match self.site {
            Site::Point(p) => state.tree.points()[p].local.translation.vector,
            Site::Payload => state.mass.payload.as_ref().map_or_else(Vector3::zeros, |p| p.com),
        };
        let p = state.frames.body[self.body].transform_point(&local.into()).coords;
        for &(j, c) in &self.compliance {
            let frame = &state.frames.joint_frame[j];
            let load = match state.tree.joints()[j].motion {
                Motion::Revolute(a) => (frame.rotation * a.into_inner()).dot(&(p - frame.translation.vector).cross(&f)),
                Motion::Prismatic(a) => (frame.rotation * a.into_inner()).dot(&f),
                Motion::Fixed => 0.0,
            };
            out.joint_offset[j] += c * load;
        }
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn ErrorModelSpec> {
        let mut spec = self.spec.clone();
        spec.mass = values[0];
        spec.scale = values[1];
        Box::new(spec)
    }
}
