//! Product of exponentials: `T(q) = exp([S1] q1) ··· exp([Sn] qn) · M`.
//!
//! Each joint gives its screw axis at the home configuration (q = 0) in base coordinates: a
//! direction `axis` and, for revolute joints, a `point` on the axis. Points on links (the tool
//! pose is the home pose M) are given in base coordinates at home. In the tree, a joint's frame
//! is base-aligned at home and sits on its axis, which makes the product of exponentials exact:
//! `exp([S] q) = Tr(r) · Rot(axis, q) · Tr(-r)` telescopes along the chain.

use armcomp_core::model::geom::unit;
use armcomp_core::{BuildContext, Chain, Error, Issues, KinematicTree, KinematicsSpec, ParamInfo, Quantity, Result};
use nalgebra::{Isometry3, Vector3};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::common::{ChainCore, JointGeometry, PriorSpec, joint_spec};
use crate::mdh::is_default_prior;

fn default_base() -> String {
    "base".into()
}

joint_spec! {
    /// One joint's screw at home, in base coordinates (length unit for `point`).
    PoeJoint {
        /// Direction of the joint axis (any length; normalised).
        axis: [f64; 3],
        /// A point on the axis (revolute joints; ignored by prismatic ones).
        #[serde(default)]
        point: [f64; 3],
    }
}

/// A product-of-exponentials chain or tree.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct PoeSpec {
    /// Name of the base link (default `base`).
    #[serde(default = "default_base")]
    pub base: String,
    /// The joints in order.
    #[serde(deserialize_with = "crate::common::joints")]
    pub joints: Vec<PoeJoint>,
    /// Prior standard deviations of the parameters.
    #[serde(default, skip_serializing_if = "is_default_prior")]
    pub prior: PriorSpec,
}

/// A compiled POE chain.
#[derive(Debug, Clone)]
pub struct PoeChain {
    spec: PoeSpec,
    units: armcomp_core::Units,
    core: ChainCore,
}

const SUFFIXES: [&str; 6] = ["axis_x", "axis_y", "axis_z", "point_x", "point_y", "point_z"];

#[typetag::serde(name = "poe")]
impl KinematicsSpec for PoeSpec {
    fn build(&self, ctx: &BuildContext<'_>) -> Result<Box<dyn Chain>, Issues> {
        let u = ctx.units;
        let mut issues = Issues::default();
        for (i, j) in self.joints.iter().enumerate() {
            if unit(Vector3::from(j.axis)).is_none() && j.kind != crate::common::JointKind::Fixed {
                issues.push(
                    format!("{}.joints[{i}].axis", ctx.path),
                    "expected a non-zero direction",
                );
            }
        }
        if !issues.is_empty() {
            return Err(issues);
        }
        let geo = self
            .joints
            .iter()
            .map(|j| {
                let p = u.len3(j.point);
                SUFFIXES
                    .iter()
                    .zip([j.axis[0], j.axis[1], j.axis[2], p[0], p[1], p[2]])
                    .enumerate()
                    .map(|(k, (s, v))| {
                        (
                            *s,
                            if k < 3 {
                                Quantity::Dimensionless
                            } else {
                                Quantity::Length
                            },
                            v,
                        )
                    })
                    .collect()
            })
            .collect();
        let common: Vec<_> = self.joints.iter().map(PoeJoint::common).collect();
        let core = ChainCore::resolve(&self.base, &common, geo, &self.prior, ctx)?;
        Ok(Box::new(PoeChain {
            spec: self.clone(),
            units: u,
            core,
        }))
    }
}

impl Chain for PoeChain {
    fn params(&self) -> &[ParamInfo] {
        self.core.params()
    }

    fn tree(&self, values: &[f64]) -> Result<KinematicTree> {
        self.core.tree(values, |j, v| {
            let axis = unit(Vector3::new(v[0], v[1], v[2])).ok_or_else(|| Error::InvalidArgument {
                what: format!("joint {}", j + 1),
                reason: "the POE axis has zero length".into(),
            })?;
            let r = Vector3::new(v[3], v[4], v[5]);
            Ok(JointGeometry {
                pre: Isometry3::translation(r.x, r.y, r.z),
                axis,
                post: Isometry3::translation(-r.x, -r.y, -r.z),
            })
        })
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn KinematicsSpec> {
        let mut spec = self.spec.clone();
        for (j, joint) in spec.joints.iter_mut().enumerate() {
            let v = self.core.joint_values(values, j);
            joint.axis = [v[0], v[1], v[2]];
            joint.point = [v[3], v[4], v[5]].map(|x| self.units.len_out(x));
        }
        Box::new(spec)
    }
}
