//! Solid shapes of links and fixtures: what files declare, their mass properties, and the
//! parry shapes collision checking uses.
//!
//! Conventions follow URDF: boxes are centred on their frame, cylinders and capsules run along
//! their frame's z axis and are centred on it. parry's own cylinders run along y, so the
//! conversion to parry turns them (see [`Shape::to_parry`]); glam types stay behind this file
//! and `collision.rs`.

use nalgebra::{Isometry3, Matrix3, Vector3};
use parry3d_f64::math::{Pose, Rot3, Vec3};
use parry3d_f64::shape::SharedShape;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use crate::model::units::Units;

/// A shape as written in a robot file (dimensions in the file's length unit).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(tag = "shape", rename_all = "snake_case", deny_unknown_fields)]
pub enum Geometry {
    /// A box centred on its frame.
    Box {
        /// Edge lengths along x, y, z.
        size: [f64; 3],
    },
    /// A cylinder along z, centred on its frame.
    Cylinder {
        /// Radius.
        radius: f64,
        /// Length along z.
        length: f64,
    },
    /// A sphere centred on its frame.
    Sphere {
        /// Radius.
        radius: f64,
    },
    /// A capsule along z, centred on its frame: a cylinder of `length` with hemispherical ends.
    Capsule {
        /// Radius.
        radius: f64,
        /// Length of the cylindrical part along z (the ends add one radius each).
        length: f64,
    },
    /// Everything below the frame's xy plane (a floor); fixtures only.
    Plane,
}

/// A shape in SI units (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    /// Edge lengths along x, y, z.
    Box([f64; 3]),
    /// Radius and length along z.
    Cylinder {
        /// Radius (m).
        radius: f64,
        /// Length along z (m).
        length: f64,
    },
    /// Radius.
    Sphere(f64),
    /// Radius and length of the cylindrical part along z.
    Capsule {
        /// Radius (m).
        radius: f64,
        /// Length of the cylindrical part (m).
        length: f64,
    },
    /// The half-space z ≤ 0.
    Plane,
}

/// Mass, centre of mass and inertia of a solid (SI).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassProperties {
    /// Mass (kg).
    pub mass: f64,
    /// Centre of mass in the frame the solid was given in (m).
    pub com: Vector3<f64>,
    /// Inertia tensor about the centre of mass, axes of that frame (kg m²).
    pub inertia: Matrix3<f64>,
}

impl Geometry {
    /// The shape in metres, or a message saying which dimension is not a positive length.
    pub fn to_shape(&self, units: &Units) -> Result<Shape, String> {
        let positive = |name: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(units.len(v))
            } else {
                Err(format!("expected a positive length for `{name}`, got {v}"))
            }
        };
        Ok(match *self {
            Geometry::Box { size } => Shape::Box([
                positive("size[0]", size[0])?,
                positive("size[1]", size[1])?,
                positive("size[2]", size[2])?,
            ]),
            Geometry::Cylinder { radius, length } => Shape::Cylinder {
                radius: positive("radius", radius)?,
                length: positive("length", length)?,
            },
            Geometry::Sphere { radius } => Shape::Sphere(positive("radius", radius)?),
            Geometry::Capsule { radius, length } => Shape::Capsule {
                radius: positive("radius", radius)?,
                length: positive("length", length)?,
            },
            Geometry::Plane => Shape::Plane,
        })
    }
}

impl Shape {
    /// The parry shape and its pose in this shape's frame (parry cylinders run along y).
    pub fn to_parry(&self) -> (SharedShape, Isometry3<f64>) {
        match *self {
            Shape::Box(s) => (
                SharedShape::cuboid(s[0] / 2.0, s[1] / 2.0, s[2] / 2.0),
                Isometry3::identity(),
            ),
            Shape::Cylinder { radius, length } => (
                SharedShape::cylinder(length / 2.0, radius),
                crate::model::geom::rx(std::f64::consts::FRAC_PI_2),
            ),
            Shape::Sphere(r) => (SharedShape::ball(r), Isometry3::identity()),
            Shape::Capsule { radius, length } => (SharedShape::capsule_z(length / 2.0, radius), Isometry3::identity()),
            Shape::Plane => (SharedShape::halfspace(Vec3::Z), Isometry3::identity()),
        }
    }

    /// Mass properties of the solid at `density` (kg/m³), in the shape's frame; `None` for a
    /// plane, which has no finite mass.
    pub fn mass_properties(&self, density: f64) -> Option<MassProperties> {
        if matches!(self, Shape::Plane) {
            return None;
        }
        let (shape, local) = self.to_parry();
        let mp = shape.mass_properties(density).transform_by(&to_pose(&local));
        let i = mp.reconstruct_inertia_matrix();
        let c = mp.local_com;
        Some(MassProperties {
            mass: mp.mass(),
            com: Vector3::new(c.x, c.y, c.z),
            inertia: Matrix3::from_fn(|r, k| i.col(k)[r]),
        })
    }
}

/// An nalgebra pose as parry's (glam) pose.
pub(crate) fn to_pose(iso: &Isometry3<f64>) -> Pose {
    let t = iso.translation.vector;
    let q = iso.rotation.quaternion();
    Pose::from_parts(Vec3::new(t.x, t.y, t.z), Rot3::from_xyzw(q.i, q.j, q.k, q.w))
}

/// A glam vector as nalgebra's.
pub(crate) fn from_vec(v: Vec3) -> Vector3<f64> {
    Vector3::new(v.x, v.y, v.z)
}

impl MassProperties {
    /// The same solid seen from a frame in which its own frame sits at `pose`.
    pub fn transformed(&self, pose: &Isometry3<f64>) -> MassProperties {
        let r = pose.rotation.to_rotation_matrix();
        MassProperties {
            mass: self.mass,
            com: pose.transform_point(&self.com.into()).coords,
            inertia: r.matrix() * self.inertia * r.matrix().transpose(),
        }
    }

    /// The union of two solids given in the same frame (parallel-axis theorem).
    pub fn combined(&self, other: &MassProperties) -> MassProperties {
        let mass = self.mass + other.mass;
        if mass <= 0.0 {
            return *self;
        }
        let com = (self.com * self.mass + other.com * other.mass) / mass;
        let shifted = |p: &MassProperties| {
            let d = p.com - com;
            p.inertia + (Matrix3::identity() * d.norm_squared() - d * d.transpose()) * p.mass
        };
        MassProperties {
            mass,
            com,
            inertia: shifted(self) + shifted(other),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn close(a: &Matrix3<f64>, b: &Matrix3<f64>, tol: f64) -> bool {
        (a - b).norm() <= tol * b.norm()
    }

    #[test]
    fn box_inertia_matches_closed_form() {
        let (a, b, c, rho) = (0.3, 0.2, 0.5, 2700.0);
        let mp = Shape::Box([a, b, c]).mass_properties(rho).unwrap();
        let m = rho * a * b * c;
        assert!((mp.mass - m).abs() < 1e-12 * m);
        let i = Matrix3::from_diagonal(&Vector3::new(b * b + c * c, a * a + c * c, a * a + b * b)) * (m / 12.0);
        assert!(close(&mp.inertia, &i, 1e-12), "{}", mp.inertia);
        assert!(mp.com.norm() < 1e-15);
    }

    #[test]
    fn cylinder_along_z_inertia_matches_closed_form() {
        let (r, h, rho) = (0.05, 0.4, 7850.0);
        let mp = Shape::Cylinder { radius: r, length: h }.mass_properties(rho).unwrap();
        let m = rho * PI * r * r * h;
        assert!((mp.mass - m).abs() < 1e-12 * m);
        let side = m * (3.0 * r * r + h * h) / 12.0;
        let i = Matrix3::from_diagonal(&Vector3::new(side, side, m * r * r / 2.0));
        assert!(close(&mp.inertia, &i, 1e-12), "{}", mp.inertia);
    }

    #[test]
    fn sphere_inertia_matches_closed_form() {
        let (r, rho) = (0.1, 1000.0);
        let mp = Shape::Sphere(r).mass_properties(rho).unwrap();
        let m = rho * 4.0 / 3.0 * PI * r.powi(3);
        assert!((mp.mass - m).abs() < 1e-12 * m);
        let i = Matrix3::identity() * (0.4 * m * r * r);
        assert!(close(&mp.inertia, &i, 1e-12));
    }

    #[test]
    fn offset_and_combined_solids_follow_parallel_axis_theorem() {
        // Two equal spheres at ±d on x: com at the middle, Iyy = 2 (2/5 m r² + m d²).
        let (r, d, rho) = (0.05, 0.2, 1000.0);
        let s = Shape::Sphere(r).mass_properties(rho).unwrap();
        let a = s.transformed(&Isometry3::translation(d, 0.0, 0.0));
        let b = s.transformed(&Isometry3::translation(-d, 0.0, 0.0));
        let both = a.combined(&b);
        let m = s.mass;
        assert!(both.com.norm() < 1e-15);
        let iyy = 2.0 * (0.4 * m * r * r + m * d * d);
        assert!((both.inertia[(1, 1)] - iyy).abs() < 1e-12 * iyy);
        assert!((both.inertia[(0, 0)] - 2.0 * 0.4 * m * r * r).abs() < 1e-12 * iyy);
    }
}
