//! Collision checking of a robot against itself and the fixtures of its cell, with parry.
//!
//! A [`CollisionModel`] is built once from a tree and its [`CollisionGeometry`]: the link shapes, the fixtures and the
//! list of shape pairs worth testing. Pairs on the same link, on links joined only by fixed
//! joints and on adjacent links (one moving joint apart, fixed joints aside) are left out, since
//! they touch by design; so are fixtures against the links fixed to the base, which is mounted
//! in the cell. Checking a configuration evaluates rigid forward kinematics into a
//! [`CollisionWorkspace`] and queries the pairs; nothing is allocated except the returned contacts.

use nalgebra::{Isometry3, Vector3};
use parry3d_f64::math::Pose;
use parry3d_f64::query;
use parry3d_f64::shape::SharedShape;

use crate::kinematics::workspace::TreeWorkspace;
use crate::model::shape::{Shape, from_vec, to_pose};
use crate::model::tree::{KinematicTree, Motion};

/// A shape fixed to a body of the tree (SI).
#[derive(Debug, Clone, PartialEq)]
pub struct BodyShape {
    /// The body (tree index).
    pub body: usize,
    /// The shape's frame in the body frame.
    pub local: Isometry3<f64>,
    /// The shape.
    pub shape: Shape,
}

/// A shape fixed in the robot's base frame: the floor, a table, a wall, a part.
#[derive(Debug, Clone, PartialEq)]
pub struct Fixture {
    /// Name, as in the robot file.
    pub name: String,
    /// The shape's frame in the base frame.
    pub pose: Isometry3<f64>,
    /// The shape.
    pub shape: Shape,
}

/// The collision description of a robot, resolved against its tree (SI).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CollisionGeometry {
    /// Shapes on links.
    pub shapes: Vec<BodyShape>,
    /// Shapes in the cell.
    pub fixtures: Vec<Fixture>,
    /// Distance below which two shapes count as colliding (m); 0 means touching.
    pub margin: f64,
    /// Body pairs never checked against each other (besides adjacent and rigidly joined ones).
    pub ignore: Vec<(usize, usize)>,
}

/// One pair of shapes closer than the margin (as `armcomp check-pose --json` lists it).
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Contact {
    /// The first link.
    pub first: String,
    /// The second link, or the fixture.
    pub second: String,
    /// Whether `second` is a fixture rather than a link.
    pub fixture: bool,
    /// Signed distance (m): negative is the penetration depth.
    pub distance: f64,
    /// Closest (or deepest) point on the first shape, base frame (m).
    pub point_first: Vector3<f64>,
    /// Closest (or deepest) point on the second shape, base frame (m).
    pub point_second: Vector3<f64>,
}

#[derive(Debug, Clone)]
struct LinkShape {
    body: usize,
    local: Isometry3<f64>,
    shape: SharedShape,
}

/// Link shapes, fixtures and the pairs to test; immutable once built.
#[derive(Debug, Clone)]
pub struct CollisionModel {
    tree: KinematicTree,
    shapes: Vec<LinkShape>,
    fixtures: Vec<(String, Pose, SharedShape)>,
    /// Shape index pairs (link vs link).
    pairs: Vec<(usize, usize)>,
    /// (shape index, fixture index) pairs. Fixtures go first in queries: parry 0.31 places a
    /// half-space wrongly when it is the second shape of a contact query.
    fixture_pairs: Vec<(usize, usize)>,
    margin: f64,
}

/// Buffers for checking configurations: the frames and the world pose of each link shape.
#[derive(Debug, Clone)]
pub struct CollisionWorkspace {
    frames: TreeWorkspace,
    poses: Vec<Pose>,
}

impl CollisionModel {
    /// The collision model of a tree with the given shapes and fixtures (a robot's:
    /// `CollisionModel::new(robot.tree(), robot.collision())`).
    pub fn new(tree: &KinematicTree, geometry: &CollisionGeometry) -> CollisionModel {
        let rigid = rigid_groups(tree);
        let shapes: Vec<LinkShape> = geometry
            .shapes
            .iter()
            .map(|s| {
                let (shape, offset) = s.shape.to_parry();
                LinkShape {
                    body: s.body,
                    local: s.local * offset,
                    shape,
                }
            })
            .collect();
        let ignored = |a: usize, b: usize| {
            rigid[a] == rigid[b]
                || adjacent(tree, &rigid, a, b)
                || geometry
                    .ignore
                    .iter()
                    .any(|&(x, y)| (x, y) == (a, b) || (x, y) == (b, a))
        };
        let mut pairs = Vec::new();
        for i in 0..shapes.len() {
            for k in i + 1..shapes.len() {
                if !ignored(shapes[i].body, shapes[k].body) {
                    pairs.push((i, k));
                }
            }
        }
        let mut fixture_pairs = Vec::new();
        for (i, s) in shapes.iter().enumerate() {
            if rigid[s.body] == rigid[0] {
                continue;
            }
            for f in 0..geometry.fixtures.len() {
                fixture_pairs.push((i, f));
            }
        }
        let fixtures = geometry
            .fixtures
            .iter()
            .map(|f| {
                let (shape, offset) = f.shape.to_parry();
                (f.name.clone(), to_pose(&(f.pose * offset)), shape)
            })
            .collect();
        CollisionModel {
            tree: tree.clone(),
            shapes,
            fixtures,
            pairs,
            fixture_pairs,
            margin: geometry.margin,
        }
    }

    /// Buffers sized for this model.
    pub fn workspace(&self) -> CollisionWorkspace {
        CollisionWorkspace {
            frames: TreeWorkspace::new(&self.tree),
            poses: vec![Pose::IDENTITY; self.shapes.len()],
        }
    }

    /// Number of shape pairs tested per configuration (link–link and link–fixture).
    pub fn pair_count(&self) -> usize {
        self.pairs.len() + self.fixture_pairs.len()
    }

    fn place(&self, q: &[f64], ws: &mut CollisionWorkspace) {
        self.tree.forward_into(q, &mut ws.frames);
        for (pose, s) in ws.poses.iter_mut().zip(&self.shapes) {
            *pose = to_pose(&(ws.frames.body[s.body] * s.local));
        }
    }

    /// Every pair closer than the margin at joint values `q` (rad, m; one per coordinate),
    /// link pairs first, in a fixed order.
    pub fn check(&self, q: &[f64], ws: &mut CollisionWorkspace) -> Vec<Contact> {
        self.place(q, ws);
        let mut out = Vec::new();
        let name = |s: &LinkShape| self.tree.bodies()[s.body].name.clone();
        for &(i, k) in &self.pairs {
            let (a, b) = (&self.shapes[i], &self.shapes[k]);
            if let Some(c) = self.contact(&ws.poses[i], &a.shape, &ws.poses[k], &b.shape) {
                out.push(Contact {
                    first: name(a),
                    second: name(b),
                    fixture: false,
                    ..c
                });
            }
        }
        for &(i, f) in &self.fixture_pairs {
            let (fname, fpose, fshape) = &self.fixtures[f];
            if let Some(c) = self.contact(fpose, fshape, &ws.poses[i], &self.shapes[i].shape) {
                out.push(Contact {
                    first: name(&self.shapes[i]),
                    second: fname.clone(),
                    fixture: true,
                    point_first: c.point_second,
                    point_second: c.point_first,
                    ..c
                });
            }
        }
        out
    }

    /// Whether any pair is closer than the margin at `q`; stops at the first one and allocates
    /// nothing, for planners rejecting poses.
    pub fn collides(&self, q: &[f64], ws: &mut CollisionWorkspace) -> bool {
        self.place(q, ws);
        self.pairs.iter().any(|&(i, k)| {
            self.contact(&ws.poses[i], &self.shapes[i].shape, &ws.poses[k], &self.shapes[k].shape)
                .is_some()
        }) || self.fixture_pairs.iter().any(|&(i, f)| {
            let (_, fpose, fshape) = &self.fixtures[f];
            self.contact(fpose, fshape, &ws.poses[i], &self.shapes[i].shape)
                .is_some()
        })
    }

    /// The contact of two placed shapes if they are within the margin (names left empty).
    fn contact(&self, p1: &Pose, s1: &SharedShape, p2: &Pose, s2: &SharedShape) -> Option<Contact> {
        // Every shape pair we build (convex solids, a half-space only against them) is
        // supported by parry's dispatcher, so `Unsupported` cannot occur.
        let c = query::contact(p1, s1.as_ref(), p2, s2.as_ref(), self.margin).ok()??;
        Some(Contact {
            first: String::new(),
            second: String::new(),
            fixture: false,
            distance: c.dist,
            point_first: from_vec(c.point1),
            point_second: from_vec(c.point2),
        })
    }
}

/// For each body, the first body of its rigid group: bodies joined only by fixed joints never
/// move relative to each other.
fn rigid_groups(tree: &KinematicTree) -> Vec<usize> {
    let mut group: Vec<usize> = (0..tree.bodies().len()).collect();
    for (j, joint) in tree.joints().iter().enumerate() {
        if joint.motion == Motion::Fixed {
            group[j + 1] = group[joint.parent];
        }
    }
    group
}

/// Whether the rigid groups of two bodies are joined by one joint.
fn adjacent(tree: &KinematicTree, rigid: &[usize], a: usize, b: usize) -> bool {
    let (ga, gb) = (rigid[a], rigid[b]);
    let parent_group = |g: usize| (g > 0).then(|| rigid[tree.joints()[g - 1].parent]);
    parent_group(ga) == Some(gb) || parent_group(gb) == Some(ga)
}
