//! Physical error models for armcomp: what makes a real, long, heavy arm miss.
//!
//! One concept per module: gravity deflection of links as cantilevers ([`cantilever`]), joint
//! compliance ([`joint_compliance`]) and lateral compliance ([`lateral_compliance`]), base and
//! tool frame offsets ([`geometric_offsets`]), and the deflection paper's Eq. 5 mapping link
//! differentials to the tool ([`differential`]). Further effects for the diagnosis workflow:
//! [`backlash`], [`encoder_eccentricity`], [`thermal_growth`], [`base_tilt`], [`measured_tilt`],
//! [`payload_mass_error`], [`transmission_scale`]. [`equilibrium`] iterates the loads on the
//! deformed arm for very elastic arms. Every model reads its loads from the mass model and
//! gravity of the static state and writes small twists into the chain (paper Eq. 1–3).
#![warn(missing_docs)]
#![forbid(unsafe_code)]

mod candidates;
mod common;

pub mod backlash;
pub mod base_tilt;
pub mod cantilever;
pub mod differential;
pub mod encoder_eccentricity;
pub mod equilibrium;
pub mod geometric_offsets;
pub mod joint_compliance;
pub mod lateral_compliance;
pub mod measured_tilt;
pub mod payload_mass_error;
pub mod thermal_growth;
pub mod transmission_scale;

pub use backlash::{BacklashModel, BacklashSpec};
pub use base_tilt::{BaseTiltModel, BaseTiltSpec};
pub use cantilever::{Beam, CantileverModel, CantileverSpec};
pub use common::{ElasticError, adjoint};
pub use differential::{tool_differential, tool_differential_world};
pub use encoder_eccentricity::{EncoderEccentricityModel, EncoderEccentricitySpec};
pub use equilibrium::{EquilibriumParams, EquilibriumReport, EquilibriumWorkspace, solve_equilibrium};
pub use geometric_offsets::{GeometricOffsetsModel, GeometricOffsetsSpec};
pub use joint_compliance::{JointComplianceModel, JointComplianceSpec};
pub use lateral_compliance::{LateralComplianceModel, LateralComplianceSpec};
pub use measured_tilt::{MeasuredTiltModel, MeasuredTiltSpec};
pub use payload_mass_error::{PayloadMassErrorModel, PayloadMassErrorSpec};
pub use thermal_growth::{ThermalGrowthModel, ThermalGrowthSpec};
pub use transmission_scale::{TransmissionScaleModel, TransmissionScaleSpec};

use armcomp_core::{CandidateFn, PluginInfo, Role};

macro_rules! entry {
    ($name:literal, $spec:ty, $candidates:expr, $doc:literal) => {{
        let candidates: Option<&'static CandidateFn> = $candidates;
        PluginInfo {
            type_name: $name,
            role: Role::ErrorModel,
            doc: $doc,
            diagnosis_candidate: candidates.is_some(),
            candidates,
            schema: |g| <$spec as schemars::JsonSchema>::json_schema(g),
        }
    }};
}

/// The plugins of this crate, for the registry.
pub fn plugins() -> Vec<PluginInfo> {
    vec![
        entry!(
            "cantilever_deflection",
            CantileverSpec,
            Some(&candidates::cantilever_deflection),
            "Links bend under gravity as Euler-Bernoulli cantilevers (own weight, tip force and moment), per-link EI/GJ scale"
        ),
        entry!(
            "joint_compliance",
            JointComplianceSpec,
            Some(&candidates::joint_compliance),
            "Joints give way in proportion to their gravity torque: dq = c * tau(q)"
        ),
        entry!(
            "lateral_compliance",
            LateralComplianceSpec,
            Some(&candidates::lateral_compliance),
            "Joints tilt about the two axes perpendicular to their axis in proportion to the bending moment they carry"
        ),
        entry!(
            "geometric_offsets",
            GeometricOffsetsSpec,
            // Base and tool frame errors are what the measurement frame and the marker offsets
            // already identify: as a candidate it could never earn its parameters.
            None,
            "Small rigid errors of the base frame and the tool frame (6 parameters each)"
        ),
        entry!(
            "backlash",
            BacklashSpec,
            Some(&candidates::backlash),
            "Gear dead band per joint; the joint rests on the side its gravity torque pushes it to"
        ),
        entry!(
            "encoder_eccentricity",
            EncoderEccentricitySpec,
            Some(&candidates::encoder_eccentricity),
            "Off-centre encoder: joint angle error a*sin(q) + b*cos(q) per joint"
        ),
        entry!(
            "thermal_growth",
            ThermalGrowthSpec,
            Some(&candidates::thermal_growth),
            "Link lengths grow with temperature: expansion coefficient per kelvin"
        ),
        entry!(
            "base_tilt",
            BaseTiltSpec,
            Some(&candidates::base_tilt),
            "The base stands tilted by two small angles; the arm turns with it and every elastic model sees the tilted gravity"
        ),
        entry!(
            "measured_tilt",
            MeasuredTiltSpec,
            Some(&candidates::measured_tilt),
            "A gravity sensor's reading turns the chain at its link, row by row (a rocking base, a leaning column); identifies how the sensor is mounted"
        ),
        entry!(
            "payload_mass_error",
            PayloadMassErrorSpec,
            Some(&candidates::payload_mass_error),
            "The payload weighs (1 + scale) times what is declared plus a mass; every elastic model sees the corrected payload"
        ),
        entry!(
            "transmission_scale",
            TransmissionScaleSpec,
            Some(&candidates::transmission_scale),
            "Gear ratio or encoder scale error per joint: the joint turns (1 + s) times the command"
        ),
    ]
}
