//! Modified Denavit–Hartenberg (Craig), with Hayati's optional beta for nearly parallel axes.
//!
//! Joint `i` sits in link `i-1`'s frame at `Rx(alpha) · Tx(a) · Ry(beta) · Rz(theta) · Tz(d)`
//! and moves about (revolute) or along (prismatic) its own z axis. Link frames are the joint
//! frames after motion, so points on a link are given in its MDH frame.

use armcomp_core::model::geom::{rx, ry, rz, tx, tz};
use armcomp_core::{BuildContext, Chain, Issues, KinematicTree, KinematicsSpec, ParamInfo, Quantity, Result};
use nalgebra::{Isometry3, Vector3};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::common::{ChainCore, JointGeometry, PriorSpec, joint_spec};

fn default_base() -> String {
    "base".into()
}

joint_spec! {
    /// One joint of a modified-DH table (lengths and angles in the file's units).
    MdhJoint {
        /// Twist of joint axis i about the common normal x_{i-1}.
        #[serde(default)]
        alpha: f64,
        /// Length of the common normal along x_{i-1}.
        #[serde(default)]
        a: f64,
        /// Joint angle offset about z_i.
        #[serde(default)]
        theta: f64,
        /// Offset along z_i.
        #[serde(default)]
        d: f64,
        /// Hayati's rotation about y, for axes nearly parallel to the previous one (identifiable
        /// only when present).
        #[serde(default, skip_serializing_if = "Option::is_none")]
        beta: Option<f64>,
    }
}

/// A modified-DH (Craig) chain or tree.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct MdhSpec {
    /// Name of the base link (default `base`).
    #[serde(default = "default_base")]
    pub base: String,
    /// The joints in order; each hangs from the previous joint's link unless `parent` says otherwise.
    #[serde(deserialize_with = "crate::common::joints")]
    pub joints: Vec<MdhJoint>,
    /// Prior standard deviations of the parameters.
    #[serde(default, skip_serializing_if = "is_default_prior")]
    pub prior: PriorSpec,
}

pub(crate) fn is_default_prior(p: &PriorSpec) -> bool {
    *p == PriorSpec::default()
}

/// A compiled modified-DH chain.
#[derive(Debug, Clone)]
pub struct MdhChain {
    spec: MdhSpec,
    units: armcomp_core::Units,
    core: ChainCore,
}

#[typetag::serde(name = "mdh")]
impl KinematicsSpec for MdhSpec {
    fn build(&self, ctx: &BuildContext<'_>) -> Result<Box<dyn Chain>, Issues> {
        let u = ctx.units;
        let geo = self
            .joints
            .iter()
            .map(|j| {
                let mut g = vec![
                    ("alpha", Quantity::Angle, u.ang(j.alpha)),
                    ("a", Quantity::Length, u.len(j.a)),
                    ("theta", Quantity::Angle, u.ang(j.theta)),
                    ("d", Quantity::Length, u.len(j.d)),
                ];
                if let Some(b) = j.beta {
                    g.push(("beta", Quantity::Angle, u.ang(b)));
                }
                g
            })
            .collect();
        let common: Vec<_> = self.joints.iter().map(MdhJoint::common).collect();
        let core = ChainCore::resolve(&self.base, &common, geo, &self.prior, ctx)?;
        Ok(Box::new(MdhChain {
            spec: self.clone(),
            units: u,
            core,
        }))
    }
}

/// The MDH transform of one joint from `[alpha, a, theta, d, (beta)]` (SI).
pub fn mdh_transform(v: &[f64]) -> Isometry3<f64> {
    let beta = v.get(4).copied().unwrap_or(0.0);
    rx(v[0]) * tx(v[1]) * ry(beta) * rz(v[2]) * tz(v[3])
}

impl Chain for MdhChain {
    fn params(&self) -> &[ParamInfo] {
        self.core.params()
    }

    fn tree(&self, values: &[f64]) -> Result<KinematicTree> {
        self.core.tree(values, |_, v| {
            Ok(JointGeometry {
                pre: mdh_transform(v),
                axis: Vector3::z_axis(),
                post: Isometry3::identity(),
            })
        })
    }

    // A joint's MDH parameters move its placement alone: the axis is z and no body frame
    // differs from its joint's.
    fn placement_moved_by(&self, values: &[f64], param: usize) -> Option<(usize, Isometry3<f64>)> {
        self.core.placement_moved_by(values, param, mdh_transform)
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn KinematicsSpec> {
        let mut spec = self.spec.clone();
        for (j, joint) in spec.joints.iter_mut().enumerate() {
            let v = self.core.joint_values(values, j);
            joint.alpha = self.units.ang_out(v[0]);
            joint.a = self.units.len_out(v[1]);
            joint.theta = self.units.ang_out(v[2]);
            joint.d = self.units.len_out(v[3]);
            if joint.beta.is_some() {
                joint.beta = Some(self.units.ang_out(v[4]));
            }
        }
        Box::new(spec)
    }
}
