//! Thermal growth: every link length (joint seats and point offsets) grows by
//! `α · (T − T_ref)` with the temperature `T` the measurement reports; nothing happens when it
//! reports none.

use armcomp_core::{ErrorModel, ErrorModelSpec, Issues, ModelContext, ParamInfo, Perturbation, Quantity, StaticState};
use nalgebra::{Isometry3, Vector6};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::common::check_finite;

fn default_reference() -> f64 {
    20.0
}

/// Thermal growth as written in the robot file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ThermalGrowthSpec {
    /// Linear expansion coefficient α (1/K), e.g. 1.2e-5 for steel, 2.3e-5 for aluminium.
    #[serde(default)]
    pub coefficient: f64,
    /// Temperature (°C) at which the nominal geometry holds (default 20).
    #[serde(default = "default_reference")]
    pub reference_temperature: f64,
}

/// The built thermal-growth model.
#[derive(Debug, Clone)]
pub struct ThermalGrowthModel {
    spec: ThermalGrowthSpec,
    /// Per joint, then per point: the translation of the nominal placement in its own frame.
    joint_lengths: Vec<nalgebra::Vector3<f64>>,
    point_lengths: Vec<nalgebra::Vector3<f64>>,
    params: Vec<ParamInfo>,
}

fn own_frame_translation(x: &Isometry3<f64>) -> nalgebra::Vector3<f64> {
    x.rotation.inverse_transform_vector(&x.translation.vector)
}

#[typetag::serde(name = "thermal_growth")]
impl ErrorModelSpec for ThermalGrowthSpec {
    fn build(&self, ctx: &ModelContext<'_>) -> Result<Box<dyn ErrorModel>, Issues> {
        let path = ctx.build.path;
        let mut issues = Issues::default();
        check_finite(&mut issues, &format!("{path}.coefficient"), self.coefficient);
        check_finite(
            &mut issues,
            &format!("{path}.reference_temperature"),
            self.reference_temperature,
        );
        if !issues.is_empty() {
            return Err(issues);
        }
        Ok(Box::new(ThermalGrowthModel {
            spec: self.clone(),
            joint_lengths: ctx
                .tree
                .joints()
                .iter()
                .map(|j| own_frame_translation(&j.placement))
                .collect(),
            point_lengths: ctx
                .tree
                .points()
                .iter()
                .map(|p| own_frame_translation(&p.local))
                .collect(),
            // Structural metals grow by 10–25e-6 per kelvin, moulded or printed plastics (scale
            // models) by up to 2e-4, carbon fibre slightly shrinks.
            params: vec![
                ParamInfo::new(
                    "thermal_growth.coefficient",
                    Quantity::PerKelvin,
                    self.coefficient,
                    1e-5,
                )
                .with_plausible(-2e-6, 2e-4),
            ],
        }))
    }
}

impl ErrorModel for ThermalGrowthModel {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    fn perturb(&self, state: &StaticState<'_>, values: &[f64], out: &mut Perturbation) {
        let Some(t) = state.temperature else { return };
        let k = values[0] * (t - self.spec.reference_temperature);
        if k == 0.0 || !k.is_finite() {
            return;
        }
        for (tw, l) in out.joint_twist.iter_mut().zip(&self.joint_lengths) {
            *tw += Vector6::new(k * l.x, k * l.y, k * l.z, 0.0, 0.0, 0.0);
        }
        for (tw, l) in out.point_twist.iter_mut().zip(&self.point_lengths) {
            *tw += Vector6::new(k * l.x, k * l.y, k * l.z, 0.0, 0.0, 0.0);
        }
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn ErrorModelSpec> {
        let mut spec = self.spec.clone();
        spec.coefficient = values[0];
        Box::new(spec)
    }
}
