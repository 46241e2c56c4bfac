//! Base tilt: the robot stands slightly tilted, by small angles about the base x and y axes.
//! The whole arm turns with its base (applied like a base frame error), and gravity seen in the
//! base frame tilts the other way: every elastic model of the robot (joint and lateral
//! compliance, link bending) sees the tilted gravity, with its own identified values.
//!
//! With a gravity sensor (`[[sensors]]`) the tilt turns the measured gravity, so it is the
//! sensor's constant misalignment with the base, not the ground's slope: the sensor follows a
//! tilt that changes from row to row, which one identified constant cannot, and the constant
//! left between the sensor and the base frame is what the points can still tell. The tilt of
//! each row then loads the elastic models only; to turn the chain by it too (a base rocking
//! under a tracker on the ground), use [`measured_tilt`](crate::measured_tilt) instead, whose
//! mounting is this misalignment (of opposite sign: the mounting turns the reading into the
//! base frame, this tilt turns the reading's gravity back).
use armcomp_core::{
    ErrorModel, ErrorModelSpec, Issues, Loads, ModelContext, ParamInfo, Perturbation, Quantity, StaticState,
};
use nalgebra::{UnitQuaternion, Vector3, Vector6};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::common::check_finite;
use crate::geometric_offsets::BodyAttachments;

/// Base tilt as written in the robot file.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BaseTiltSpec {
    /// Tilt about the base x and y axes, in the file's angle unit.
    #[serde(default)]
    pub tilt: [f64; 2],
}

/// The built base-tilt model.
#[derive(Debug, Clone)]
pub struct BaseTiltModel {
    spec: BaseTiltSpec,
    units: armcomp_core::Units,
    base: BodyAttachments,
    params: Vec<ParamInfo>,
}

#[typetag::serde(name = "base_tilt")]
impl ErrorModelSpec for BaseTiltSpec {
    fn build(&self, ctx: &ModelContext<'_>) -> Result<Box<dyn ErrorModel>, Issues> {
        let path = ctx.build.path;
        let mut issues = Issues::default();
        for (k, v) in self.tilt.iter().enumerate() {
            check_finite(&mut issues, &format!("{path}.tilt[{k}]"), *v);
        }
        if !issues.is_empty() {
            return Err(issues);
        }
        let u = ctx.build.units;
        Ok(Box::new(BaseTiltModel {
            spec: self.clone(),
            units: u,
            base: BodyAttachments::of(ctx.tree, 0),
            // A base set on a slope or a sagging floor tilts by up to a few degrees.
            params: tilt_params("base_tilt", &self.tilt, &u),
        }))
    }
}

/// Two small angles `<prefix>.x` and `<prefix>.y` about the x and y axes (SI, from `values` in
/// the file's angle unit): prior 1°, plausible within ±5°. A base's tilt, a sensor's mounting.
pub(crate) fn tilt_params(prefix: &str, values: &[f64; 2], units: &armcomp_core::Units) -> Vec<ParamInfo> {
    ["x", "y"]
        .iter()
        .zip(values)
        .map(|(axis, v)| {
            ParamInfo::new(
                format!("{prefix}.{axis}"),
                Quantity::Angle,
                units.ang(*v),
                1f64.to_radians(),
            )
            .with_plausible(-5f64.to_radians(), 5f64.to_radians())
        })
        .collect()
}

/// The rotation of the two tilt angles `values` (rad, about x and y) of [`tilt_params`].
pub(crate) fn tilt_rotation(values: &[f64]) -> UnitQuaternion<f64> {
    UnitQuaternion::from_scaled_axis(Vector3::new(values[0], values[1], 0.0))
}

impl ErrorModel for BaseTiltModel {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    fn perturb(&self, state: &StaticState<'_>, values: &[f64], out: &mut Perturbation) {
        let eps = Vector6::new(0.0, 0.0, 0.0, values[0], values[1], 0.0);
        self.base.apply(&eps, state.tree, out);
    }

    fn adjusts_loads(&self) -> bool {
        true
    }

    fn adjust_loads(&self, values: &[f64], loads: &mut Loads) {
        loads.gravity = tilt_rotation(values).inverse_transform_vector(&loads.gravity);
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn ErrorModelSpec> {
        let mut spec = self.spec.clone();
        spec.tilt = [self.units.ang_out(values[0]), self.units.ang_out(values[1])];
        Box::new(spec)
    }
}
