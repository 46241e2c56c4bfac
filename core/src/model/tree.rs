//! The kinematic tree every convention compiles to (Pinocchio-style model).
//!
//! Bodies are numbered so that body 0 is the base and body `j + 1` is the child of joint `j`;
//! every joint's parent body precedes it (topological order). A joint sits at a fixed
//! `placement` in its parent body's frame and then moves its child body about (revolute) or
//! along (prismatic) a unit axis given in the joint frame. The model is immutable; all buffers
//! live in a [`TreeWorkspace`](crate::TreeWorkspace) so that FK and Jacobians never allocate.

use nalgebra::{Isometry3, Translation3, Unit, UnitQuaternion, Vector3};

use crate::error::{Error, Result};

/// How a joint moves its child body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Motion {
    /// Rotation about the unit axis (joint frame) by the joint value in rad.
    Revolute(Unit<Vector3<f64>>),
    /// Translation along the unit axis (joint frame) by the joint value in m.
    Prismatic(Unit<Vector3<f64>>),
    /// No motion; the placement alone.
    Fixed,
}

impl Motion {
    /// The motion's transform for joint value `v`.
    #[inline]
    pub fn transform(&self, v: f64) -> Isometry3<f64> {
        match self {
            Motion::Revolute(axis) => {
                Isometry3::from_parts(Translation3::identity(), UnitQuaternion::from_axis_angle(axis, v))
            }
            Motion::Prismatic(axis) => {
                Isometry3::from_parts(Translation3::from(axis.into_inner() * v), UnitQuaternion::identity())
            }
            Motion::Fixed => Isometry3::identity(),
        }
    }
}

/// Where a joint's value comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum Coordinate {
    /// The joint is driven by independent coordinate `index` of the joint vector `q`.
    Independent(usize),
    /// The joint follows others.
    Mimic(Coupling),
    /// A fixed joint has no value.
    None,
}

/// A mimic coupling: `value = offset + Σ multiplier · q[index]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Coupling {
    /// `(independent coordinate index, multiplier)` pairs.
    pub terms: Vec<(usize, f64)>,
    /// Constant offset (rad or m).
    pub offset: f64,
}

/// One joint of the tree.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// Name as in the robot file.
    pub name: String,
    /// Parent body index (0 = base); always less than this joint's child body index.
    pub parent: usize,
    /// Joint frame in the parent body's frame.
    pub placement: Isometry3<f64>,
    /// How the child body moves.
    pub motion: Motion,
    /// Where the value comes from.
    pub coordinate: Coordinate,
}

/// A body (link) of the tree, with the mass properties the physical models need.
#[derive(Debug, Clone, PartialEq)]
pub struct Body {
    /// Name as in the robot file.
    pub name: String,
    /// The convention's own frame of this link in the tree body frame (identity for MDH/URDF;
    /// the constant part of the DH transform for classic DH). Points given in the convention's
    /// link frame are mapped through it.
    pub convention_frame: Isometry3<f64>,
}

/// A named point (with orientation) fixed to a body: the tool, a marker, a tracker nest.
#[derive(Debug, Clone, PartialEq)]
pub struct Point {
    /// Name as in the robot file.
    pub name: String,
    /// The body it is fixed to.
    pub body: usize,
    /// Its pose in the body frame.
    pub local: Isometry3<f64>,
}

/// Limits of one independent coordinate, in rad or m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Limits {
    /// Lower bound.
    pub lower: f64,
    /// Upper bound.
    pub upper: f64,
}

/// The immutable kinematic model.
#[derive(Debug, Clone, PartialEq)]
pub struct KinematicTree {
    pub(crate) joints: Vec<Joint>,
    pub(crate) bodies: Vec<Body>,
    pub(crate) points: Vec<Point>,
    /// Names of the independent coordinates (the joint vector `q`), in order.
    pub(crate) coord_names: Vec<String>,
    pub(crate) coord_limits: Vec<Option<Limits>>,
    pub(crate) coord_is_prismatic: Vec<bool>,
    /// For each body, the joints on its path from the base (in order), for Jacobians.
    pub(crate) support: Vec<Vec<usize>>,
}

impl KinematicTree {
    /// An empty tree with a base body named `base_name`.
    pub fn new(base_name: impl Into<String>) -> Self {
        KinematicTree {
            joints: Vec::new(),
            bodies: vec![Body {
                name: base_name.into(),
                convention_frame: Isometry3::identity(),
            }],
            points: Vec::new(),
            coord_names: Vec::new(),
            coord_limits: Vec::new(),
            coord_is_prismatic: Vec::new(),
            support: vec![Vec::new()],
        }
    }

    /// Adds an actuated joint driven by a new independent coordinate; returns its child body index.
    pub fn add_joint(
        &mut self,
        name: impl Into<String>,
        parent: usize,
        placement: Isometry3<f64>,
        motion: Motion,
        limits: Option<Limits>,
        child: impl Into<String>,
    ) -> Result<usize> {
        let name = name.into();
        let coordinate = match motion {
            Motion::Fixed => Coordinate::None,
            _ => {
                self.coord_names.push(name.clone());
                self.coord_limits.push(limits);
                self.coord_is_prismatic.push(matches!(motion, Motion::Prismatic(_)));
                Coordinate::Independent(self.coord_names.len() - 1)
            }
        };
        self.push_joint(
            Joint {
                name,
                parent,
                placement,
                motion,
                coordinate,
            },
            child.into(),
        )
    }

    /// Adds a joint that follows independent coordinates (see [`Coupling`]).
    pub fn add_mimic_joint(
        &mut self,
        name: impl Into<String>,
        parent: usize,
        placement: Isometry3<f64>,
        motion: Motion,
        coupling: Coupling,
        child: impl Into<String>,
    ) -> Result<usize> {
        let name = name.into();
        if let Some((i, _)) = coupling.terms.iter().find(|(i, _)| *i >= self.coord_names.len()) {
            return Err(Error::InvalidArgument {
                what: format!("mimic joint `{name}`"),
                reason: format!("the coordinate {i} it follows does not exist yet"),
            });
        }
        let joint = Joint {
            name,
            parent,
            placement,
            motion,
            coordinate: Coordinate::Mimic(coupling),
        };
        self.push_joint(joint, child.into())
    }

    fn push_joint(&mut self, joint: Joint, child: String) -> Result<usize> {
        if joint.parent >= self.bodies.len() {
            return Err(Error::InvalidArgument {
                what: format!("joint `{}`", joint.name),
                reason: format!(
                    "parent body {} does not exist; only {} do (topological order required)",
                    joint.parent,
                    self.bodies.len()
                ),
            });
        }
        let mut support = self.support[joint.parent].clone();
        support.push(self.joints.len());
        self.support.push(support);
        self.joints.push(joint);
        self.bodies.push(Body {
            name: child,
            convention_frame: Isometry3::identity(),
        });
        Ok(self.bodies.len() - 1)
    }

    /// Renumbers the independent coordinates so that new coordinate `k` is old coordinate
    /// `order[k]`: conventions whose file order differs from the tree's topological order use
    /// it so that `q` follows the file.
    pub fn reorder_coordinates(&mut self, order: &[usize]) -> Result<()> {
        let n = self.nq();
        let mut new_of_old = vec![usize::MAX; n];
        for (k, &old) in order.iter().enumerate() {
            if old >= n || new_of_old[old] != usize::MAX {
                return Err(Error::InvalidArgument {
                    what: "coordinate order".into(),
                    reason: format!("{order:?} is not a permutation of 0..{n}"),
                });
            }
            new_of_old[old] = k;
        }
        if order.len() != n {
            return Err(Error::Dimension {
                what: "coordinate order".into(),
                expected: n,
                got: order.len(),
            });
        }
        self.coord_names = order.iter().map(|&o| self.coord_names[o].clone()).collect();
        self.coord_limits = order.iter().map(|&o| self.coord_limits[o]).collect();
        self.coord_is_prismatic = order.iter().map(|&o| self.coord_is_prismatic[o]).collect();
        for joint in &mut self.joints {
            match &mut joint.coordinate {
                Coordinate::Independent(i) => *i = new_of_old[*i],
                Coordinate::Mimic(c) => c.terms.iter_mut().for_each(|t| t.0 = new_of_old[t.0]),
                Coordinate::None => {}
            }
        }
        Ok(())
    }

    /// Sets the convention frame of a body (see [`Body::convention_frame`]).
    pub fn set_convention_frame(&mut self, body: usize, frame: Isometry3<f64>) {
        self.bodies[body].convention_frame = frame;
    }

    /// Adds a named point on `body`, its pose given in the tree body frame; returns its index.
    pub fn add_point(&mut self, name: impl Into<String>, body: usize, local: Isometry3<f64>) -> Result<usize> {
        let name = name.into();
        if body >= self.bodies.len() {
            return Err(Error::InvalidArgument {
                what: format!("point `{name}`"),
                reason: format!("body {body} does not exist"),
            });
        }
        self.points.push(Point { name, body, local });
        Ok(self.points.len() - 1)
    }

    /// Moves point `point` to `local` (its pose in its body frame).
    pub fn set_point_local(&mut self, point: usize, local: Isometry3<f64>) {
        self.points[point].local = local;
    }

    /// Joints in topological order.
    pub fn joints(&self) -> &[Joint] {
        &self.joints
    }
    /// Bodies; body 0 is the base, body `j + 1` the child of joint `j`.
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }
    /// Named points.
    pub fn points(&self) -> &[Point] {
        &self.points
    }
    /// Number of independent coordinates (length of `q`).
    pub fn nq(&self) -> usize {
        self.coord_names.len()
    }
    /// Names of the independent coordinates, in the order of `q`.
    pub fn coordinate_names(&self) -> &[String] {
        &self.coord_names
    }
    /// Limits of each independent coordinate.
    pub fn coordinate_limits(&self) -> &[Option<Limits>] {
        &self.coord_limits
    }
    /// Whether each independent coordinate is prismatic (m) rather than revolute (rad).
    pub fn coordinate_is_prismatic(&self) -> &[bool] {
        &self.coord_is_prismatic
    }
    /// The joints on the path from the base to `body`, base first.
    pub fn support(&self, body: usize) -> &[usize] {
        &self.support[body]
    }
    /// Per independent coordinate, whether it moves any of `bodies` (directly, or through a
    /// mimic joint on their path): the coordinates a measurement of points on them depends on.
    pub fn coordinates_moving(&self, bodies: &[usize]) -> Vec<bool> {
        let mut moving = vec![false; self.nq()];
        for &b in bodies {
            for &j in &self.support[b] {
                match &self.joints[j].coordinate {
                    Coordinate::Independent(i) => moving[*i] = true,
                    Coordinate::Mimic(c) => c.terms.iter().for_each(|(i, _)| moving[*i] = true),
                    Coordinate::None => {}
                }
            }
        }
        moving
    }
    /// Index of a body by name.
    pub fn body_index(&self, name: &str) -> Option<usize> {
        self.bodies.iter().position(|b| b.name == name)
    }
    /// Index of a point by name.
    pub fn point_index(&self, name: &str) -> Option<usize> {
        self.points.iter().position(|p| p.name == name)
    }
    /// Index of a joint by name.
    pub fn joint_index(&self, name: &str) -> Option<usize> {
        self.joints.iter().position(|j| j.name == name)
    }

    /// Joint values given by name, in the order of `q`: per coordinate the value named for it,
    /// `None` where none was (the caller says what that means). A name that is no coordinate
    /// (a fixed or mimic joint, or none at all) and a name given twice are errors.
    pub fn coordinates_by_name<'a>(&self, named: impl IntoIterator<Item = (&'a str, f64)>) -> Result<Vec<Option<f64>>> {
        let mut q = vec![None; self.nq()];
        for (name, value) in named {
            let reason = match self.coord_names.iter().position(|n| n == name) {
                Some(i) if q[i].is_none() => {
                    q[i] = Some(value);
                    continue;
                }
                Some(_) => format!("`{name}` is given twice"),
                None if self.joint_index(name).is_some() => format!(
                    "joint `{name}` is fixed or follows another joint (mimic); set one of: {}",
                    self.coord_names.join(", ")
                ),
                None => format!(
                    "the robot has no joint `{name}`; its joints are: {}",
                    self.coord_names.join(", ")
                ),
            };
            return Err(Error::InvalidArgument {
                what: "joint values by name".into(),
                reason,
            });
        }
        Ok(q)
    }

    /// The value of joint `j` for joint vector `q` (rad or m; 0 for fixed joints).
    #[inline]
    pub fn joint_value(&self, j: usize, q: &[f64]) -> f64 {
        match &self.joints[j].coordinate {
            Coordinate::Independent(i) => q[*i],
            Coordinate::Mimic(c) => c.offset + c.terms.iter().map(|(i, k)| k * q[*i]).sum::<f64>(),
            Coordinate::None => 0.0,
        }
    }

    /// Checks that `q` has one value per independent coordinate, all finite.
    pub fn check_q(&self, q: &[f64]) -> Result<()> {
        if q.len() != self.nq() {
            return Err(Error::Dimension {
                what: "joint vector".into(),
                expected: self.nq(),
                got: q.len(),
            });
        }
        if let Some(i) = q.iter().position(|v| !v.is_finite()) {
            return Err(Error::InvalidArgument {
                what: format!("joint value {} (`{}`)", i + 1, self.coord_names[i]),
                reason: format!("{} is not a finite number", q[i]),
            });
        }
        Ok(())
    }
}
