//! Transmission ratio error: the gear ratio or encoder resolution differs from its nominal
//! value, so the joint turns `(1 + s)` times the commanded value, `dq = s · q` per joint.

use std::collections::BTreeMap;

use armcomp_core::{ErrorModel, ErrorModelSpec, Issues, ModelContext, ParamInfo, Perturbation, Quantity, StaticState};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::common::{check_finite, resolve_joint_table};

/// Transmission scale errors as written in the robot file.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct TransmissionScaleSpec {
    /// Relative scale error `s` per joint name (0 = nominal ratio).
    pub scale: BTreeMap<String, f64>,
}

/// The built transmission-scale model.
#[derive(Debug, Clone)]
pub struct TransmissionScaleModel {
    spec: TransmissionScaleSpec,
    joints: Vec<usize>,
    params: Vec<ParamInfo>,
}

#[typetag::serde(name = "transmission_scale")]
impl ErrorModelSpec for TransmissionScaleSpec {
    fn build(&self, ctx: &ModelContext<'_>) -> Result<Box<dyn ErrorModel>, Issues> {
        let mut issues = Issues::default();
        if self.scale.is_empty() {
            issues.push(
                format!("{}.scale", ctx.build.path),
                "expected at least one joint, e.g. scale = { j1 = 0.0 }",
            );
        }
        // The joint turns (1 + s) times its command: at s = -1 it never moves, below it runs
        // backwards; no gear or encoder error does either.
        let resolved = resolve_joint_table(ctx, "scale", &self.scale, &mut issues, |issues, path, v| {
            if !check_finite(issues, path, v) {
                return false;
            }
            if v <= -1.0 {
                issues.push(
                    path,
                    format!(
                        "{v} would stop or reverse the joint (it turns 1 + s times its command); expected more than -1"
                    ),
                );
                return false;
            }
            true
        });
        if !issues.is_empty() {
            return Err(issues);
        }
        let params = resolved
            .iter()
            .map(|&(j, v)| {
                ParamInfo::new(
                    format!("transmission_scale.{}", ctx.tree.joints()[j].name),
                    Quantity::Dimensionless,
                    v,
                    0.01,
                )
                // Gear ratios are exact; belts, capstans and trimmed servos are off by percents.
                .with_plausible(-0.2, 0.2)
            })
            .collect();
        Ok(Box::new(TransmissionScaleModel {
            spec: self.clone(),
            joints: resolved.into_iter().map(|(j, _)| j).collect(),
            params,
        }))
    }
}

impl ErrorModel for TransmissionScaleModel {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    fn perturb(&self, state: &StaticState<'_>, values: &[f64], out: &mut Perturbation) {
        for (&j, &s) in self.joints.iter().zip(values) {
            out.joint_offset[j] += s * state.frames.joint_value[j];
        }
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn ErrorModelSpec> {
        let mut spec = self.spec.clone();
        for (p, &v) in self.params.iter().zip(values) {
            spec.scale
                .insert(p.name.trim_start_matches("transmission_scale.").to_string(), v);
        }
        Box::new(spec)
    }
}
