//! Physical error models for armcomp: what makes a real, long, heavy arm miss.
//!
//! One concept per module: gravity deflection of links as cantilevers ([`cantilever`]), joint
//! compliance ([`joint_compliance`]) and lateral compliance ([`lateral_compliance`]), base and
//! tool frame offsets ([`geometric_offsets`]), and the deflection paper's Eq. 5 mapping link
//! differentials to the tool ([`differential`]). [`equilibrium`] iterates the loads on the
//! deformed arm for very elastic arms. Every model reads its loads from the mass model and
//! gravity of the static state and writes small twists into the chain (paper Eq. 1–3).

mod common;

pub mod cantilever;
pub mod differential;
pub mod equilibrium;
pub mod geometric_offsets;
pub mod joint_compliance;
pub mod lateral_compliance;

pub use cantilever::{Beam, CantileverModel, CantileverSpec};
pub use common::{ElasticError, adjoint};
pub use differential::{tool_differential, tool_differential_world};
pub use equilibrium::{EquilibriumOptions, EquilibriumReport, EquilibriumWorkspace, solve_equilibrium};
pub use geometric_offsets::{GeometricOffsetsModel, GeometricOffsetsSpec};
pub use joint_compliance::{JointComplianceModel, JointComplianceSpec};
pub use lateral_compliance::{LateralComplianceModel, LateralComplianceSpec};

use armcomp_core::{PluginInfo, Role};

macro_rules! entry {
    ($name:literal, $spec:ty, $candidate:expr, $doc:literal) => {
        PluginInfo {
            type_name: $name,
            role: Role::ErrorModel,
            doc: $doc,
            diagnosis_candidate: $candidate,
            schema: |g| <$spec as schemars::JsonSchema>::json_schema(g),
        }
    };
}

/// The plugins of this crate, for the registry.
pub fn plugins() -> Vec<PluginInfo> {
    vec![
        entry!(
            "cantilever_deflection",
            CantileverSpec,
            true,
            "Links bend under gravity as Euler-Bernoulli cantilevers (own weight, tip force and moment), per-link EI/GJ scale"
        ),
        entry!(
            "joint_compliance",
            JointComplianceSpec,
            true,
            "Joints give way in proportion to their gravity torque: dq = c * tau(q)"
        ),
        entry!(
            "lateral_compliance",
            LateralComplianceSpec,
            true,
            "Joints tilt about the two axes perpendicular to their axis in proportion to the bending moment they carry"
        ),
        entry!(
            "geometric_offsets",
            GeometricOffsetsSpec,
            true,
            "Small rigid errors of the base frame and the tool frame (6 parameters each)"
        ),
    ]
}
