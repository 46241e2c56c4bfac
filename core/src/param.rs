//! Identifiable parameters: what calibration may change, with names, units and priors.

use serde::{Deserialize, Serialize};

/// The physical quantity of a parameter; the value is always stored in SI.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Quantity {
    /// metres
    Length,
    /// radians
    Angle,
    /// a ratio or gain without unit
    Dimensionless,
    /// radians per newton-metre (joint compliance)
    Compliance,
    /// kilograms
    Mass,
    /// newton-metres squared (flexural rigidity EI, torsional rigidity GJ)
    Rigidity,
    /// per kelvin (thermal expansion)
    PerKelvin,
    /// radians per newton (lateral compliance per unit bending moment arm), or other derived units
    Other(&'static str),
}

impl Quantity {
    /// The SI unit symbol.
    pub fn si_unit(&self) -> &'static str {
        match self {
            Quantity::Length => "m",
            Quantity::Angle => "rad",
            Quantity::Dimensionless => "1",
            Quantity::Compliance => "rad/(N m)",
            Quantity::Mass => "kg",
            Quantity::Rigidity => "N m^2",
            Quantity::PerKelvin => "1/K",
            Quantity::Other(u) => u,
        }
    }
}

/// One identifiable parameter of a chain, an error model or the measurement setup.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ParamInfo {
    /// Stable dotted name, e.g. `j3.theta` or `joint_compliance.j2`.
    pub name: String,
    /// What it measures; the value is in the quantity's SI unit.
    pub quantity: Quantity,
    /// The value the robot file gives (SI).
    pub nominal: f64,
    /// Prior standard deviation (SI) used to regularise identification; `f64::INFINITY` for none.
    pub sigma: f64,
    /// Smallest physically meaningful value (SI); `-f64::INFINITY` for none.
    pub lower: f64,
    /// Largest physically meaningful value (SI); `f64::INFINITY` for none.
    pub upper: f64,
    /// Whether the fit's cost may have several minima along this parameter (a backlash that
    /// flips with the load's sign, a scale of a stiffness): calibration's restarts move it by
    /// its typical size, not only by its prior.
    pub multimodal: bool,
}

impl ParamInfo {
    /// A parameter with a prior and no bounds.
    pub fn new(name: impl Into<String>, quantity: Quantity, nominal: f64, sigma: f64) -> Self {
        ParamInfo {
            name: name.into(),
            quantity,
            nominal,
            sigma,
            lower: f64::NEG_INFINITY,
            upper: f64::INFINITY,
            multimodal: false,
        }
    }

    /// The same parameter marked as one along which the cost may have several minima.
    pub fn multimodal(mut self) -> Self {
        self.multimodal = true;
        self
    }

    /// The same parameter restricted to `[lower, upper]` (SI), which calibration respects.
    pub fn with_bounds(mut self, lower: f64, upper: f64) -> Self {
        self.lower = lower;
        self.upper = upper;
        self
    }
}
