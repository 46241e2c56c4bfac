//! URDF robots for armcomp: the `urdf` kinematics plugin (URDF joint origins and axes as
//! identifiable parameters, inertials and collision elements as link data), bare URDF files
//! as robots, and calibrated URDFs written back.
#![warn(missing_docs)]
#![forbid(unsafe_code)]

mod bare;
mod chain;
mod document;
mod export;
mod mesh;

pub use bare::{robot_file_for_urdf, robot_from_urdf};
pub use chain::{UrdfChain, UrdfJointOverride, UrdfSpec};
pub use document::{UrdfDocument, UrdfJoint, UrdfJointType, UrdfLink};
pub use export::{CalibratedUrdf, JointOffset, MarkerJoint, ZERO_BELOW, calibrated_urdf, rewrite};

use armcomp_core::{PluginInfo, Role};

/// The plugins of this crate, for the registry.
pub fn plugins() -> Vec<PluginInfo> {
    vec![PluginInfo {
        type_name: "urdf",
        role: Role::Kinematics,
        doc: "A URDF file: joint origins (xyz, small rotation on rpy) and axes identifiable, inertials and collision elements used",
        diagnosis_candidate: false,
        candidates: None,
        schema: |g| <UrdfSpec as schemars::JsonSchema>::json_schema(g),
    }]
}
