//! Encoder eccentricity: an encoder mounted off-centre reads the joint angle with an error that
//! repeats once per turn, `dq = a · sin q + b · cos q` (first harmonic of the joint angle).

use std::collections::BTreeMap;

use armcomp_core::{
    ErrorModel, ErrorModelSpec, Issues, ModelContext, Motion, ParamInfo, Perturbation, Quantity, StaticState,
};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::common::{check_finite, name_list};

/// Encoder eccentricity as written in the robot file.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct EncoderEccentricitySpec {
    /// Per revolute joint name: `[a, b]`, amplitudes of `sin q` and `cos q` in the angle unit.
    pub eccentricity: BTreeMap<String, [f64; 2]>,
}

/// The built encoder-eccentricity model.
#[derive(Debug, Clone)]
pub struct EncoderEccentricityModel {
    spec: EncoderEccentricitySpec,
    units: armcomp_core::Units,
    joints: Vec<usize>,
    params: Vec<ParamInfo>,
}

#[typetag::serde(name = "encoder_eccentricity")]
impl ErrorModelSpec for EncoderEccentricitySpec {
    fn build(&self, ctx: &ModelContext<'_>) -> Result<Box<dyn ErrorModel>, Issues> {
        let tree = ctx.tree;
        let path = ctx.build.path;
        let u = ctx.build.units;
        let mut issues = Issues::default();
        if self.eccentricity.is_empty() {
            issues.push(format!("{path}.eccentricity"), "expected at least one revolute joint");
        }
        let mut found = Vec::new();
        for (name, ab) in &self.eccentricity {
            let p = format!("{path}.eccentricity.{name}");
            match tree.joint_index(name) {
                Some(j) if matches!(tree.joints()[j].motion, Motion::Revolute(_)) => {
                    if check_finite(&mut issues, &format!("{p}[0]"), ab[0])
                        & check_finite(&mut issues, &format!("{p}[1]"), ab[1])
                    {
                        found.push((j, *ab));
                    }
                }
                Some(_) => issues.push(p, format!("joint `{name}` is not revolute")),
                None => issues.push(
                    p,
                    format!(
                        "joint `{name}` does not exist; joints are: {}",
                        name_list(tree.joints().iter().map(|j| j.name.as_str()))
                    ),
                ),
            }
        }
        if !issues.is_empty() {
            return Err(issues);
        }
        found.sort_by_key(|(j, _)| *j);
        let mut params = Vec::new();
        for (j, ab) in &found {
            let n = &tree.joints()[*j].name;
            // A mounted encoder disc is off centre by hundredths of a degree; a degree means
            // a damaged or slipping one.
            let plausible = 1f64.to_radians();
            for (k, component) in ["sin", "cos"].into_iter().enumerate() {
                params.push(
                    ParamInfo::new(
                        format!("encoder_eccentricity.{n}.{component}"),
                        Quantity::Angle,
                        u.ang(ab[k]),
                        0.01,
                    )
                    .with_plausible(-plausible, plausible),
                );
            }
        }
        Ok(Box::new(EncoderEccentricityModel {
            spec: self.clone(),
            units: u,
            joints: found.into_iter().map(|(j, _)| j).collect(),
            params,
        }))
    }
}

impl ErrorModel for EncoderEccentricityModel {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    fn perturb(&self, state: &StaticState<'_>, values: &[f64], out: &mut Perturbation) {
        for (i, &j) in self.joints.iter().enumerate() {
            let (s, c) = state.frames.joint_value[j].sin_cos();
            out.joint_offset[j] += values[2 * i] * s + values[2 * i + 1] * c;
        }
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn ErrorModelSpec> {
        let mut spec = self.spec.clone();
        for (i, p) in self.params.chunks(2).enumerate() {
            let name = p[0]
                .name
                .trim_start_matches("encoder_eccentricity.")
                .trim_end_matches(".sin");
            let ab = [self.units.ang_out(values[2 * i]), self.units.ang_out(values[2 * i + 1])];
            spec.eccentricity.insert(name.to_string(), ab);
        }
        Box::new(spec)
    }
}
