//! Mass properties and beam sections of links, as the physical error models need them.

use nalgebra::Vector3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// A beam cross-section, perpendicular to the beam axis (local x). Local y is the section's
/// width direction, local z its height direction. Dimensions in the file's length unit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "shape", rename_all = "snake_case", deny_unknown_fields)]
pub enum Section {
    /// Solid circle.
    SolidRound {
        /// Diameter.
        diameter: f64,
    },
    /// Circular tube.
    Tube {
        /// Outer diameter.
        outer_diameter: f64,
        /// Wall thickness.
        wall: f64,
    },
    /// Solid rectangle.
    Rectangle {
        /// Extent along local y.
        width: f64,
        /// Extent along local z.
        height: f64,
    },
    /// Rectangular tube with a uniform wall.
    RectTube {
        /// Outer extent along local y.
        width: f64,
        /// Outer extent along local z.
        height: f64,
        /// Wall thickness.
        wall: f64,
    },
    /// I-beam: two flanges (along y) joined by a web (along z).
    IBeam {
        /// Flange width (along y).
        width: f64,
        /// Total height (along z).
        height: f64,
        /// Flange thickness.
        flange: f64,
        /// Web thickness.
        web: f64,
    },
}

/// Area and second moments of a section, SI.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SectionProperties {
    /// Area (m²).
    pub area: f64,
    /// Second moment about local y, `∫ z² dA` (m⁴): bending that deflects along z.
    pub iy: f64,
    /// Second moment about local z, `∫ y² dA` (m⁴): bending that deflects along y.
    pub iz: f64,
    /// Torsion constant (m⁴).
    pub j: f64,
}

impl Section {
    /// The section's dimensions, for validation messages: `(field, value)` pairs.
    pub fn dimensions(&self) -> Vec<(&'static str, f64)> {
        match *self {
            Section::SolidRound { diameter } => vec![("diameter", diameter)],
            Section::Tube { outer_diameter, wall } => vec![("outer_diameter", outer_diameter), ("wall", wall)],
            Section::Rectangle { width, height } => vec![("width", width), ("height", height)],
            Section::RectTube { width, height, wall } => vec![("width", width), ("height", height), ("wall", wall)],
            Section::IBeam {
                width,
                height,
                flange,
                web,
            } => {
                vec![("width", width), ("height", height), ("flange", flange), ("web", web)]
            }
        }
    }

    /// The dimension that no real section can have with the others (a wall that fills the tube,
    /// flanges taller than the beam, a web wider than it), with what was expected.
    pub fn impossible(&self) -> Option<(&'static str, String)> {
        match *self {
            Section::Tube { outer_diameter, wall } if 2.0 * wall >= outer_diameter => Some((
                "wall",
                format!(
                    "a wall of {wall} fills a tube of outer diameter {outer_diameter}; expected less than half the diameter ({}), or a `solid_round` section",
                    outer_diameter / 2.0
                ),
            )),
            Section::RectTube { width, height, wall } if 2.0 * wall >= width.min(height) => Some((
                "wall",
                format!(
                    "a wall of {wall} fills a {width} × {height} tube; expected less than half the smaller side ({}), or a `rectangle` section",
                    width.min(height) / 2.0
                ),
            )),
            Section::IBeam { height, flange, .. } if 2.0 * flange >= height => Some((
                "flange",
                format!(
                    "two flanges of {flange} fill a beam of height {height}; expected less than half the height ({})",
                    height / 2.0
                ),
            )),
            Section::IBeam { width, web, .. } if web > width => Some((
                "web",
                format!("a web of {web} is wider than the flanges ({width}); expected at most the width"),
            )),
            _ => None,
        }
    }

    /// Area, second moments and torsion constant, with lengths scaled to metres by `to_m`.
    /// Closed forms: circles exact; rectangle torsion after Roark; thin-walled rectangular tube
    /// torsion after Bredt; I-beam torsion as an open thin-walled section.
    pub fn properties(&self, to_m: f64) -> SectionProperties {
        use std::f64::consts::PI;
        match *self {
            Section::SolidRound { diameter } => {
                let d = diameter * to_m;
                let i = PI * d.powi(4) / 64.0;
                SectionProperties {
                    area: PI * d * d / 4.0,
                    iy: i,
                    iz: i,
                    j: 2.0 * i,
                }
            }
            Section::Tube { outer_diameter, wall } => {
                let d = outer_diameter * to_m;
                let di = d - 2.0 * wall * to_m;
                let i = PI * (d.powi(4) - di.powi(4)) / 64.0;
                SectionProperties {
                    area: PI * (d * d - di * di) / 4.0,
                    iy: i,
                    iz: i,
                    j: 2.0 * i,
                }
            }
            Section::Rectangle { width, height } => {
                let (b, h) = (width * to_m, height * to_m);
                let (a, c) = if b >= h { (b, h) } else { (h, b) };
                let j = a * c.powi(3) * (1.0 / 3.0 - 0.21 * (c / a) * (1.0 - c.powi(4) / (12.0 * a.powi(4))));
                SectionProperties {
                    area: b * h,
                    iy: b * h.powi(3) / 12.0,
                    iz: h * b.powi(3) / 12.0,
                    j,
                }
            }
            Section::RectTube { width, height, wall } => {
                let (b, h, t) = (width * to_m, height * to_m, wall * to_m);
                let (bi, hi) = (b - 2.0 * t, h - 2.0 * t);
                let j = 2.0 * t * (b - t).powi(2) * (h - t).powi(2) / (b + h - 2.0 * t);
                SectionProperties {
                    area: b * h - bi * hi,
                    iy: (b * h.powi(3) - bi * hi.powi(3)) / 12.0,
                    iz: (h * b.powi(3) - hi * bi.powi(3)) / 12.0,
                    j,
                }
            }
            Section::IBeam {
                width,
                height,
                flange,
                web,
            } => {
                let (b, h, tf, tw) = (width * to_m, height * to_m, flange * to_m, web * to_m);
                let hw = h - 2.0 * tf;
                SectionProperties {
                    area: 2.0 * b * tf + hw * tw,
                    iy: (b * h.powi(3) - (b - tw) * hw.powi(3)) / 12.0,
                    iz: (2.0 * tf * b.powi(3) + hw * tw.powi(3)) / 12.0,
                    j: (2.0 * b * tf.powi(3) + hw * tw.powi(3)) / 3.0,
                }
            }
        }
    }
}

/// Flexural and torsional rigidities of a link seen as a beam (SI).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BeamRigidity {
    /// `E·Iy` (N m²): resists bending that deflects along the section's z.
    pub ei_y: f64,
    /// `E·Iz` (N m²): resists bending that deflects along the section's y.
    pub ei_z: f64,
    /// `G·J` (N m²): resists torsion.
    pub gj: f64,
}

/// Mass properties of one body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyMass {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in the tree body frame (m).
    pub com: Vector3<f64>,
    /// Beam rigidities, when the link is modelled as a beam.
    pub beam: Option<BeamRigidity>,
}

/// A payload carried at a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Payload {
    /// Mass (kg).
    pub mass: f64,
    /// The body it is fixed to.
    pub body: usize,
    /// Its centre of mass in that body's frame (m).
    pub com: Vector3<f64>,
}

/// Masses of every body of a tree, plus the payload.
#[derive(Debug, Clone, PartialEq)]
pub struct MassModel {
    /// One entry per body (index as in the tree); massless bodies have mass 0.
    pub bodies: Vec<BodyMass>,
    /// The payload, if any.
    pub payload: Option<Payload>,
}

impl MassModel {
    /// Massless, rigid bodies for a tree with `n_bodies` bodies.
    pub fn massless(n_bodies: usize) -> Self {
        MassModel {
            bodies: vec![
                BodyMass {
                    mass: 0.0,
                    com: Vector3::zeros(),
                    beam: None
                };
                n_bodies
            ],
            payload: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rect_tube_equals_difference_of_rectangles() {
        let s = Section::RectTube {
            width: 60.0,
            height: 80.0,
            wall: 5.0,
        }
        .properties(1e-3);
        let outer = Section::Rectangle {
            width: 60.0,
            height: 80.0,
        }
        .properties(1e-3);
        let inner = Section::Rectangle {
            width: 50.0,
            height: 70.0,
        }
        .properties(1e-3);
        assert!((s.iy - (outer.iy - inner.iy)).abs() < 1e-18);
        assert!((s.iz - (outer.iz - inner.iz)).abs() < 1e-18);
        assert!((s.area - (outer.area - inner.area)).abs() < 1e-15);
    }

    #[test]
    fn thin_tube_approaches_thin_ring_formula() {
        // Thin ring: I = π r³ t.
        let (d, t) = (0.2, 0.0005);
        let s = Section::Tube {
            outer_diameter: d,
            wall: t,
        }
        .properties(1.0);
        let r = (d - t) / 2.0;
        let thin = std::f64::consts::PI * r.powi(3) * t;
        assert!((s.iy - thin).abs() / thin < 1e-4);
    }

    #[test]
    fn square_torsion_constant_matches_table() {
        // Roark: a square of side a has J ≈ 0.1406 a⁴.
        let s = Section::Rectangle {
            width: 1.0,
            height: 1.0,
        }
        .properties(1.0);
        assert!((s.j - 0.1406).abs() < 1e-3);
    }
}
