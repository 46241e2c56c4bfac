//! Kinematic conventions for armcomp: classic DH, modified DH (Craig, with Hayati's beta) and
//! the product of exponentials. Each compiles to armcomp-core's kinematic tree and exposes its
//! geometric parameters for identification.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

mod common;
pub mod dh;
pub mod mdh;
pub mod poe;

pub use common::{JointKind, MimicSpec, OriginSpec, PriorSpec};
pub use dh::{DhChain, DhJoint, DhSpec};
pub use mdh::{MdhChain, MdhJoint, MdhSpec};
pub use poe::{PoeChain, PoeJoint, PoeSpec};

use armcomp_core::{PluginInfo, Role};

/// The plugins of this crate, for the registry.
pub fn plugins() -> Vec<PluginInfo> {
    vec![
        PluginInfo {
            type_name: "mdh",
            role: Role::Kinematics,
            doc: "Modified Denavit-Hartenberg (Craig) table, with Hayati's beta for nearly parallel axes",
            diagnosis_candidate: false,
            candidates: None,
            schema: |g| <MdhSpec as schemars::JsonSchema>::json_schema(g),
        },
        PluginInfo {
            type_name: "dh",
            role: Role::Kinematics,
            doc: "Classic Denavit-Hartenberg table",
            diagnosis_candidate: false,
            candidates: None,
            schema: |g| <DhSpec as schemars::JsonSchema>::json_schema(g),
        },
        PluginInfo {
            type_name: "poe",
            role: Role::Kinematics,
            doc: "Product of exponentials: screw axes at home in base coordinates",
            diagnosis_candidate: false,
            candidates: None,
            schema: |g| <PoeSpec as schemars::JsonSchema>::json_schema(g),
        },
    ]
}
