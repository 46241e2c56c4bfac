//! Payload mass error: the payload weighs `(1 + s)·m + Δm` where the file or the measurement
//! declares `m`: a relative scale error `s` for declared masses wrong by a factor (a scale
//! calibrated wrongly, a gripper's share), an offset `Δm` for a constant error (an unlisted
//! adapter). Both enter linearly, like `transmission_scale`. The model changes the payload every
//! elastic model of the robot sees (joint and lateral compliance, link bending), so the extra
//! weight bends the arm through their own identified values; it hangs where the payload does
//! (`[payload] point`, or the tool).
//!
//! Bounds keep the identified values physical: `s ≥ −1`, and `Δm ≥ −m_file` (the file's
//! payload, 0 without one), so a payload declared as the file's, or as nothing, never comes
//! out with a negative mass.

use armcomp_core::{
    ErrorModel, ErrorModelSpec, Issues, Loads, ModelContext, ParamInfo, Perturbation, Quantity, StaticState,
};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::common::check_finite;

/// Payload mass error as written in the robot file.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PayloadMassErrorSpec {
    /// Extra mass (kg; negative when the payload is lighter than declared).
    #[serde(default)]
    pub mass: f64,
    /// Relative error of the declared payload mass: it weighs `1 + scale` times what is
    /// declared (plus `mass`).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub scale: f64,
}

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// The built payload-mass-error model.
#[derive(Debug, Clone)]
pub struct PayloadMassErrorModel {
    spec: PayloadMassErrorSpec,
    params: Vec<ParamInfo>,
}

#[typetag::serde(name = "payload_mass_error")]
impl ErrorModelSpec for PayloadMassErrorSpec {
    fn build(&self, ctx: &ModelContext<'_>) -> Result<Box<dyn ErrorModel>, Issues> {
        let path = ctx.build.path;
        let mut issues = Issues::default();
        check_finite(&mut issues, &format!("{path}.mass"), self.mass);
        if !(self.scale.is_finite() && self.scale >= -1.0) {
            issues.push(
                format!("{path}.scale"),
                format!("expected a relative error of -1 or more, got {}", self.scale),
            );
        }
        if !issues.is_empty() {
            return Err(issues);
        }
        let declared = ctx.mass.payload.as_ref().map_or(0.0, |p| p.mass);
        Ok(Box::new(PayloadMassErrorModel {
            spec: self.clone(),
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

    /// The payload acts through the other models' response to its mass.
    fn perturb(&self, _state: &StaticState<'_>, _values: &[f64], _out: &mut Perturbation) {}

    fn adjusts_loads(&self) -> bool {
        true
    }

    fn adjust_loads(&self, values: &[f64], loads: &mut Loads) {
        loads.payload_mass = (1.0 + values[1]) * loads.payload_mass + values[0];
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn ErrorModelSpec> {
        let mut spec = self.spec.clone();
        spec.mass = values[0];
        spec.scale = values[1];
        Box::new(spec)
    }
}
