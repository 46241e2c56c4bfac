//! Classic Denavit–Hartenberg: link `i`'s frame is `Rz(theta + q) · Tz(d) · Tx(a) · Rx(alpha)`
//! after link `i-1`'s frame (for prismatic joints `q` adds to `d`).
//!
//! In the tree, joint `i`'s frame is link `i-1`'s DH frame (its axis is z_{i-1}); the constant
//! `Rz(theta) Tz(d) Tx(a) Rx(alpha)` is the child link's convention frame, so points are still
//! given in the DH frame of their link.

use armcomp_core::model::geom::{rx, rz, tx, tz};
use armcomp_core::{BuildContext, Chain, Issues, KinematicTree, KinematicsSpec, ParamInfo, Quantity, Result};
use nalgebra::{Isometry3, Vector3};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::common::{ChainCore, JointGeometry, PriorSpec, joint_spec};
use crate::mdh::is_default_prior;

fn default_base() -> String {
    "base".into()
}

joint_spec! {
    /// One joint of a classic DH table (lengths and angles in the file's units).
    DhJoint {
        /// Joint angle offset about z_{i-1}.
        #[serde(default)]
        theta: f64,
        /// Offset along z_{i-1}.
        #[serde(default)]
        d: f64,
        /// Length of the common normal along x_i.
        #[serde(default)]
        a: f64,
        /// Twist about x_i.
        #[serde(default)]
        alpha: f64,
    }
}

/// A classic-DH chain or tree.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DhSpec {
    /// Name of the base link (default `base`).
    #[serde(default = "default_base")]
    pub base: String,
    /// The joints in order.
    #[serde(deserialize_with = "crate::common::joints")]
    pub joints: Vec<DhJoint>,
    /// Prior standard deviations of the parameters.
    #[serde(default, skip_serializing_if = "is_default_prior")]
    pub prior: PriorSpec,
}

/// A compiled classic-DH chain.
#[derive(Debug, Clone)]
pub struct DhChain {
    spec: DhSpec,
    units: armcomp_core::Units,
    core: ChainCore,
}

#[typetag::serde(name = "dh")]
impl KinematicsSpec for DhSpec {
    fn build(&self, ctx: &BuildContext<'_>) -> Result<Box<dyn Chain>, Issues> {
        let u = ctx.units;
        let geo = self
            .joints
            .iter()
            .map(|j| {
                vec![
                    ("theta", Quantity::Angle, u.ang(j.theta)),
                    ("d", Quantity::Length, u.len(j.d)),
                    ("a", Quantity::Length, u.len(j.a)),
                    ("alpha", Quantity::Angle, u.ang(j.alpha)),
                ]
            })
            .collect();
        let common: Vec<_> = self.joints.iter().map(DhJoint::common).collect();
        let core = ChainCore::resolve(&self.base, &common, geo, &self.prior, ctx)?;
        Ok(Box::new(DhChain {
            spec: self.clone(),
            units: u,
            core,
        }))
    }
}

impl Chain for DhChain {
    fn params(&self) -> &[ParamInfo] {
        self.core.params()
    }

    fn tree(&self, values: &[f64]) -> Result<KinematicTree> {
        self.core.tree(values, |_, v| {
            Ok(JointGeometry {
                pre: Isometry3::identity(),
                axis: Vector3::z_axis(),
                post: rz(v[0]) * tz(v[1]) * tx(v[2]) * rx(v[3]),
            })
        })
    }

    fn spec_with(&self, values: &[f64]) -> Box<dyn KinematicsSpec> {
        let mut spec = self.spec.clone();
        for (j, joint) in spec.joints.iter_mut().enumerate() {
            let v = self.core.joint_values(values, j);
            joint.theta = self.units.ang_out(v[0]);
            joint.d = self.units.len_out(v[1]);
            joint.a = self.units.len_out(v[2]);
            joint.alpha = self.units.ang_out(v[3]);
        }
        Box::new(spec)
    }
}
