//! Units at the boundary: robot files and CSV headers declare them, everything inside is SI
//! (metres, radians, kilograms, newtons).

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A length unit accepted in files and on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema, Default)]
#[serde(rename_all = "lowercase")]
pub enum LengthUnit {
    /// metre
    #[default]
    M,
    /// centimetre
    Cm,
    /// millimetre
    Mm,
    /// inch
    In,
}

impl LengthUnit {
    /// Metres per one of this unit.
    pub fn to_si(self) -> f64 {
        match self {
            LengthUnit::M => 1.0,
            LengthUnit::Cm => 0.01,
            LengthUnit::Mm => 0.001,
            LengthUnit::In => 0.0254,
        }
    }

    /// The unit's symbol as written in files.
    pub fn symbol(self) -> &'static str {
        match self {
            LengthUnit::M => "m",
            LengthUnit::Cm => "cm",
            LengthUnit::Mm => "mm",
            LengthUnit::In => "in",
        }
    }

    /// Parses a unit symbol (`m`, `cm`, `mm`, `in`).
    pub fn parse(s: &str) -> Option<Self> {
        match s.trim() {
            "m" => Some(LengthUnit::M),
            "cm" => Some(LengthUnit::Cm),
            "mm" => Some(LengthUnit::Mm),
            "in" => Some(LengthUnit::In),
            _ => None,
        }
    }
}

/// An angle unit accepted in files and on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema, Default)]
#[serde(rename_all = "lowercase")]
pub enum AngleUnit {
    /// radian
    #[default]
    Rad,
    /// degree
    Deg,
}

impl AngleUnit {
    /// Radians per one of this unit.
    pub fn to_si(self) -> f64 {
        match self {
            AngleUnit::Rad => 1.0,
            AngleUnit::Deg => std::f64::consts::PI / 180.0,
        }
    }

    /// The unit's symbol as written in files.
    pub fn symbol(self) -> &'static str {
        match self {
            AngleUnit::Rad => "rad",
            AngleUnit::Deg => "deg",
        }
    }

    /// Parses a unit symbol (`rad`, `deg`).
    pub fn parse(s: &str) -> Option<Self> {
        match s.trim() {
            "rad" => Some(AngleUnit::Rad),
            "deg" => Some(AngleUnit::Deg),
            _ => None,
        }
    }
}

/// The units a robot file writes its lengths and angles in. Masses are always kg, forces N,
/// moduli Pa, gravity m/s².
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema, Default)]
#[serde(deny_unknown_fields)]
pub struct Units {
    /// Unit of every length in the file (`m`, `cm`, `mm`, `in`).
    #[serde(default)]
    pub length: LengthUnit,
    /// Unit of every angle in the file (`rad`, `deg`).
    #[serde(default)]
    pub angle: AngleUnit,
}

impl Units {
    /// A length in file units → metres.
    pub fn len(&self, v: f64) -> f64 {
        v * self.length.to_si()
    }
    /// An angle in file units → radians.
    pub fn ang(&self, v: f64) -> f64 {
        v * self.angle.to_si()
    }
    /// Metres → file units.
    pub fn len_out(&self, v: f64) -> f64 {
        v / self.length.to_si()
    }
    /// Radians → file units.
    pub fn ang_out(&self, v: f64) -> f64 {
        v / self.angle.to_si()
    }
    /// A point in file units → metres.
    pub fn len3(&self, v: [f64; 3]) -> [f64; 3] {
        v.map(|x| self.len(x))
    }
    /// Angles in file units → radians.
    pub fn ang3(&self, v: [f64; 3]) -> [f64; 3] {
        v.map(|x| self.ang(x))
    }
}
