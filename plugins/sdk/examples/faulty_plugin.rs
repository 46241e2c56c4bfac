//! An error model that misbehaves as its config asks, for the loader's tests: it rejects its
//! config, panics, returns NaN, or returns one joint offset too many.

use armcomp_core::{ErrorModel, ErrorModelSpec, Issues, ModelContext, ParamInfo, Perturbation, Quantity, StaticState};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// How to misbehave.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
enum Mode {
    /// Build fails with an issue on `mode`.
    Reject,
    /// `perturb` panics.
    Panic,
    /// `perturb` returns NaN.
    Nan,
    /// `perturb` returns one joint offset more than the tree has joints.
    Short,
}

#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
struct FaultySpec {
    mode: Mode,
}

#[derive(Debug)]
struct FaultyModel {
    spec: FaultySpec,
    params: Vec<ParamInfo>,
}

#[typetag::serde(name = "faulty")]
impl ErrorModelSpec for FaultySpec {
    fn build(&self, ctx: &ModelContext<'_>) -> Result<Box<dyn ErrorModel>, Issues> {
        if self.mode == Mode::Reject {
            let mut issues = Issues::default();
            issues.push(
                format!("{}.mode", ctx.build.path),
                "this model rejects its config on purpose",
            );
            return Err(issues);
        }
        Ok(Box::new(FaultyModel {
            spec: self.clone(),
            params: vec![ParamInfo::new("faulty.gain", Quantity::Dimensionless, 1.0, 1.0)],
        }))
    }
}

impl ErrorModel for FaultyModel {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    fn perturb(&self, _state: &StaticState<'_>, values: &[f64], out: &mut Perturbation) {
        match self.spec.mode {
            Mode::Reject => {}
            Mode::Panic => panic!("faulty model panics on purpose"),
            Mode::Nan => out.joint_offset[0] = f64::NAN * values[0],
            Mode::Short => out.joint_offset.push(values[0]),
        }
    }

    fn spec_with(&self, _values: &[f64]) -> Box<dyn ErrorModelSpec> {
        Box::new(self.spec.clone())
    }
}

armcomp_sdk::export_plugins! {
    error_model FaultySpec { name: "faulty", doc: "Misbehaves as configured (loader tests)" },
}
