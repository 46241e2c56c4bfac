//! Geometric offsets of the base and tool frames: a small rigid motion of each, identifiable
//! (the chain's own parameter offsets are identified through the chain's parameters).
//!
//! The base error `ε_b` moves everything: the seat of every joint on the base and every point
//! on the base gets `Ad(X⁻¹) ε_b` with `X` its placement, which is exactly `E · X`. The tool
//! error is the point's own twist. Twists are `[dx, dy, dz, rx, ry, rz]` in the frame they move.

use armcomp_core::{
    ErrorModel, ErrorModelSpec, Issues, KinematicTree, ModelContext, ParamInfo, Perturbation, Quantity, StaticState,
};
use nalgebra::Vector6;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::common::{adjoint, check_finite, name_list};

fn default_point() -> String {
    "tool".into()
}

/// Base and tool frame errors as written in the robot file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct GeometricOffsetsSpec {
    /// Base frame error `[dx, dy, dz, rx, ry, rz]` in the file's length and angle units.
    #[serde(default)]
    pub base: [f64; 6],
    /// The point whose frame error is `tool` (default `tool`).
    #[serde(default = "default_point")]
    pub point: String,
    /// Tool frame error `[dx, dy, dz, rx, ry, rz]` in the point's frame, file units.
    #[serde(default)]
    pub tool: [f64; 6],
}

/// The built geometric-offsets model.
#[derive(Debug, Clone)]
pub struct GeometricOffsetsModel {
    spec: GeometricOffsetsSpec,
    units: armcomp_core::Units,
    base: BodyAttachments,
    tool: usize,
    params: Vec<ParamInfo>,
}

const SUFFIX: [&str; 6] = ["dx", "dy", "dz", "rx", "ry", "rz"];

/// Six parameters of a frame error named `<prefix>.dx` ... `<prefix>.rz`, SI.
pub(crate) fn frame_params(prefix: &str, values: &[f64; 6], units: &armcomp_core::Units) -> Vec<ParamInfo> {
    (0..6)
        .map(|k| {
            if k < 3 {
                // Machining and assembly put a frame off by millimetres, not decimetres.
                ParamInfo::new(
                    format!("{prefix}.{}", SUFFIX[k]),
                    Quantity::Length,
                    units.len(values[k]),
                    0.01,
                )
                .with_plausible(-0.05, 0.05)
            } else {
                ParamInfo::new(
                    format!("{prefix}.{}", SUFFIX[k]),
                    Quantity::Angle,
                    units.ang(values[k]),
                    1f64.to_radians(),
                )
                .with_plausible(-5f64.to_radians(), 5f64.to_radians())
            }
        })
        .collect()
}

/// The joints seated on one body and the points on it, which a rigid motion of that body (the
/// chain beyond it turning with it) moves.
#[derive(Debug, Clone)]
pub(crate) struct BodyAttachments {
    joints: Vec<usize>,
    points: Vec<usize>,
}

impl BodyAttachments {
    /// Body `body`'s (the base's: 0).
    pub fn of(tree: &KinematicTree, body: usize) -> Self {
        BodyAttachments {
            joints: (0..tree.joints().len())
                .filter(|&j| tree.joints()[j].parent == body)
                .collect(),
            points: (0..tree.points().len())
                .filter(|&p| tree.points()[p].body == body)
                .collect(),
        }
    }

    /// Adds the rigid motion `eps` of the body (in its body frame; the base's is the base
    /// frame) as twists of its joints and points. Their placements are read from `tree`, the
    /// one being evaluated: calibration varies the placement of a joint (its `alpha`, `d`,
    /// ...), and a twist mapped through the placement the model was built with would turn the
    /// wrong way.
    pub fn apply(&self, eps: &Vector6<f64>, tree: &KinematicTree, out: &mut Perturbation) {
        for &j in &self.joints {
            out.joint_twist[j] += adjoint(&tree.joints()[j].placement.inverse(), eps);
        }
        for &p in &self.points {
            out.point_twist[p] += adjoint(&tree.points()[p].local.inverse(), eps);
        }
    }
}

#[typetag::serde(name = "geometric_offsets")]
impl ErrorModelSpec for GeometricOffsetsSpec {
    fn build(&self, ctx: &ModelContext<'_>) -> Result<Box<dyn ErrorModel>, Issues> {
        let path = ctx.build.path;
        let mut issues = Issues::default();
        for (field, v) in [("base", &self.base), ("tool", &self.tool)] {
            for (k, x) in v.iter().enumerate() {
                check_finite(&mut issues, &format!("{path}.{field}[{k}]"), *x);
            }
        }
        let tool = ctx.tree.point_index(&self.point);
        if tool.is_none() {
            issues.push(
                format!("{path}.point"),
                format!(
                    "point `{}` does not exist; points are: {}",
                    self.point,
                    name_list(ctx.tree.points().iter().map(|p| p.name.as_str()))
                ),
            );
        }
        let Some(tool) = tool.filter(|_| issues.is_empty()) else {
            return Err(issues);
        };
        let units = ctx.build.units;
        let mut params = frame_params("geometric_offsets.base", &self.base, &units);
        params.extend(frame_params(
            &format!("geometric_offsets.{}", self.point),
            &self.tool,
            &units,
        ));
        Ok(Box::new(GeometricOffsetsModel {
            spec: self.clone(),
            units,
            base: BodyAttachments::of(ctx.tree, 0),
            tool,
            params,
        }))
    }
}

impl ErrorModel for GeometricOffsetsModel {
    fn params(&self) -> &[ParamInfo] {
        &self.params
    }

    fn perturb(&self, state: &StaticState<'_>, values: &[f64], out: &mut Perturbation) {
        let base = Vector6::from_column_slice(&values[..6]);
        self.base.apply(&base, state.tree, out);
        out.point_twist[self.tool] += Vector6::from_column_slice(&values[6..12]);
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn ErrorModelSpec> {
        let mut spec = self.spec.clone();
        let u = &self.units;
        for k in 0..6 {
            let f = |v: f64| if k < 3 { u.len_out(v) } else { u.ang_out(v) };
            spec.base[k] = f(values[k]);
            spec.tool[k] = f(values[6 + k]);
        }
        Box::new(spec)
    }
}
