//! Rigid forward kinematics and Jacobians of chosen points only, compiled once from a tree.
//!
//! [`KinematicTree::forward_into`] evaluates every joint and body, also fixed links off the
//! path to the points (a humanoid URDF has dozens), which collision, gravity loads and error
//! models need. When only the points' poses are wanted, [`PointKinematics`] evaluates just the
//! moving joints on their paths from the base, in topological order, each placed relative to
//! its nearest moving ancestor with the fixed joints between them multiplied in once when it is
//! built (as Pinocchio folds fixed joints into frames). Each joint's frame is also turned so
//! that it moves about or along its z axis, which makes a joint's motion a mix of two columns
//! (`rotated_z`) instead of a general rotation. The loop is written once over [`Real`]: `f64`
//! for one configuration here, [`Lanes`](crate::kinematics::lanes::Lanes) of configurations for the
//! batches of `point_kinematics_many`, with the same bits.

use nalgebra::{Isometry3, IsometryMatrix3, Matrix6xX, UnitQuaternion, Vector3};

use crate::error::{Error, Result};
use crate::kinematics::frame::Frame;
use crate::kinematics::lanes::Real;
use crate::model::geom::rotation_z_to;
use crate::model::tree::{Coordinate, KinematicTree, Motion};

/// One moving joint of the plan.
#[derive(Debug, Clone, PartialEq)]
struct Step {
    /// The step of the nearest moving ancestor (`None`: the base).
    parent: Option<usize>,
    /// This joint's frame, turned so that its axis is z, in the parent step's frame (after
    /// the parent's motion), the fixed joints in between folded in.
    placement: Frame<f64>,
    prismatic: bool,
    coordinate: Coordinate,
}

/// One point of the plan.
#[derive(Debug, Clone, PartialEq)]
struct PlanPoint {
    /// The step it moves with (`None`: fixed to the base).
    step: Option<usize>,
    /// Its pose in that step's frame.
    local: Frame<f64>,
}

/// The compiled kinematics of some points of a [`KinematicTree`] (see the module docs): built
/// once with [`new`](Self::new) or [`for_points`](Self::for_points), evaluated with
/// [`forward_into`](Self::forward_into) into a [`PointKinematicsWorkspace`] or many
/// configurations at once with `forward_many_into`. Rebuild it when the tree changes.
#[derive(Debug, Clone, PartialEq)]
pub struct PointKinematics {
    steps: Vec<Step>,
    points: Vec<PlanPoint>,
    /// The tree's index of each point of the plan.
    tree_points: Vec<usize>,
    /// The tree's index of each step's joint.
    joints: Vec<usize>,
    /// The coordinates the steps read, ascending.
    coordinates: Vec<usize>,
    nq: usize,
}

/// The values one evaluation leaves, per moving joint of the plan and per point.
#[derive(Debug, Clone)]
pub(crate) struct Evaluation<T> {
    /// Each step's joint value, sine and cosine, padded with zeros to whole packs.
    value: Vec<T>,
    sin: Vec<T>,
    cos: Vec<T>,
    /// Each step's frame after its motion, z its axis.
    pub(crate) frame: Vec<Frame<T>>,
    pub(crate) point: Vec<Frame<T>>,
}

impl<T: Real> Evaluation<T> {
    pub(crate) fn new(plan: &PointKinematics) -> Self {
        let zero = T::splat(0.0);
        let frame = Frame {
            r: [[zero; 3]; 3],
            p: [zero; 3],
        };
        let packed = plan.steps.len().next_multiple_of(T::PACK);
        Evaluation {
            value: vec![zero; packed],
            sin: vec![zero; packed],
            cos: vec![zero; packed],
            frame: vec![frame; plan.steps.len()],
            point: vec![frame; plan.points.len()],
        }
    }
}

/// Buffers for [`PointKinematics::forward_into`]; create once with
/// [`PointKinematics::workspace`] and reuse.
#[derive(Debug, Clone)]
pub struct PointKinematicsWorkspace {
    eval: Evaluation<f64>,
}

impl PointKinematicsWorkspace {
    /// World pose of the plan's point `k` from the last evaluation.
    pub fn point_pose(&self, k: usize) -> IsometryMatrix3<f64> {
        self.eval.point[k].to_isometry()
    }

    /// World position (m) of the plan's point `k` from the last evaluation.
    pub fn point_position(&self, k: usize) -> Vector3<f64> {
        Vector3::from(self.eval.point[k].p)
    }
}

impl PointKinematics {
    /// The plan for every point of `tree`, in the tree's order.
    pub fn new(tree: &KinematicTree) -> Self {
        let all: Vec<usize> = (0..tree.points().len()).collect();
        Self::for_points(tree, &all).expect("every point of the tree exists")
    }

    /// The plan for the tree's points `points` (indices into [`KinematicTree::points`]), which
    /// become the plan's points `0..points.len()` in that order.
    pub fn for_points(tree: &KinematicTree, points: &[usize]) -> Result<Self> {
        if let Some(&p) = points.iter().find(|&&p| p >= tree.points().len()) {
            return Err(Error::InvalidArgument {
                what: "point-kinematics plan".into(),
                reason: format!("point {p} does not exist; the tree has {}", tree.points().len()),
            });
        }
        let joints = tree.joints();
        let moving = |j: usize| joints[j].motion != Motion::Fixed;
        let mut needed = vec![false; joints.len()];
        for &p in points {
            for &j in tree.support(tree.points()[p].body) {
                needed[j] |= moving(j);
            }
        }
        let mut plan = PointKinematics {
            steps: Vec::new(),
            points: Vec::with_capacity(points.len()),
            tree_points: points.to_vec(),
            joints: Vec::new(),
            coordinates: Vec::new(),
            nq: tree.nq(),
        };
        // Per step, the turn taking z onto its joint's axis.
        let mut align: Vec<UnitQuaternion<f64>> = Vec::new();
        let mut step_of = vec![usize::MAX; joints.len()];
        for (j, joint) in joints.iter().enumerate().filter(|(j, _)| needed[*j]) {
            let (parent, rel) = anchor(tree, &step_of, &align, joint.parent);
            let (axis, prismatic) = match joint.motion {
                Motion::Revolute(axis) => (axis, false),
                Motion::Prismatic(axis) => (axis, true),
                Motion::Fixed => unreachable!("only moving joints are steps"),
            };
            let turn = rotation_z_to(&axis);
            let placement = rel * joint.placement * Isometry3::from_parts(Default::default(), turn);
            step_of[j] = plan.steps.len();
            align.push(turn);
            plan.joints.push(j);
            plan.steps.push(Step {
                parent,
                placement: Frame::from_isometry(&placement),
                prismatic,
                coordinate: joint.coordinate.clone(),
            });
        }
        for &p in points {
            let point = &tree.points()[p];
            let (step, rel) = anchor(tree, &step_of, &align, point.body);
            plan.points.push(PlanPoint {
                step,
                local: Frame::from_isometry(&(rel * point.local)),
            });
        }
        let reads = tree.coordinates_moving(&points.iter().map(|&p| tree.points()[p].body).collect::<Vec<_>>());
        plan.coordinates = (0..plan.nq).filter(|&i| reads[i]).collect();
        Ok(plan)
    }

    /// The tree's index of each of the plan's points.
    pub fn tree_points(&self) -> &[usize] {
        &self.tree_points
    }

    /// The tree's indices of the joints the plan evaluates (the moving joints on the points'
    /// paths), in topological order.
    pub fn joints(&self) -> &[usize] {
        &self.joints
    }

    /// Length of the joint vector `q` the plan takes.
    pub fn nq(&self) -> usize {
        self.nq
    }

    /// The coordinates (entries of `q`) the points depend on, ascending.
    pub fn coordinates(&self) -> &[usize] {
        &self.coordinates
    }

    /// Buffers sized for this plan.
    pub fn workspace(&self) -> PointKinematicsWorkspace {
        PointKinematicsWorkspace {
            eval: Evaluation::new(self),
        }
    }

    /// World poses of the plan's points at `q` (the base at the origin, as
    /// [`KinematicTree::forward_into`]); `q` must hold [`nq`](Self::nq) values. Allocates
    /// nothing.
    pub fn forward_into(&self, q: &[f64], ws: &mut PointKinematicsWorkspace) {
        debug_assert_eq!(q.len(), self.nq);
        forward(self, q, &mut ws.eval);
    }

    /// Jacobian of the pose of the plan's point `k` (6 × nq) from the last evaluation in `ws`,
    /// as [`KinematicTree::pose_jacobian_into`]: rows 0–2 the point's linear velocity, rows 3–5
    /// the angular velocity, world coordinates; mimic joints add to the columns of the
    /// coordinates they follow.
    pub fn pose_jacobian_into(&self, ws: &PointKinematicsWorkspace, k: usize, out: &mut Matrix6xX<f64>) {
        let (columns, _) = out.as_mut_slice().as_chunks_mut::<6>();
        columns.fill([0.0; 6]);
        self.pose_jacobian(&ws.eval, k, columns);
    }

    /// The frames of every step and the poses of every point at `q`.
    #[inline(always)]
    pub(crate) fn evaluate<T: Real>(&self, q: &[T], ev: &mut Evaluation<T>) {
        for (v, step) in ev.value.iter_mut().zip(&self.steps) {
            *v = match &step.coordinate {
                Coordinate::Independent(i) => q[*i],
                Coordinate::Mimic(c) => c
                    .terms
                    .iter()
                    .fold(T::splat(c.offset), |acc, (i, k)| acc + T::splat(*k) * q[*i]),
                Coordinate::None => T::splat(0.0),
            };
        }
        T::sin_cos_into(&ev.value, &mut ev.sin, &mut ev.cos);
        for (s, step) in self.steps.iter().enumerate() {
            let joint = match step.parent {
                Some(p) => ev.frame[p].then(&step.placement),
                None => Frame::splat(&step.placement),
            };
            ev.frame[s] = if step.prismatic {
                joint.translated_z(ev.value[s])
            } else {
                joint.rotated_z(ev.cos[s], ev.sin[s])
            };
        }
        for (out, point) in ev.point.iter_mut().zip(&self.points) {
            *out = match point.step {
                Some(s) => ev.frame[s].then(&point.local),
                None => Frame::splat(&point.local),
            };
        }
    }

    /// The pose Jacobian of point `k` of the evaluation `ev` into `out` (one `[T; 6]` column,
    /// linear then angular velocity, per coordinate): the columns of the plan's
    /// [`coordinates`](Self::coordinates) are written, the others left as they are (zero).
    #[inline(always)]
    pub(crate) fn pose_jacobian<T: Real>(&self, ev: &Evaluation<T>, k: usize, out: &mut [[T; 6]]) {
        let zero = T::splat(0.0);
        for &i in &self.coordinates {
            out[i] = [zero; 6];
        }
        let pos = ev.point[k].p;
        let mut next = self.points[k].step;
        while let Some(s) = next {
            let step = &self.steps[s];
            let frame = &ev.frame[s];
            let w = frame.r[2];
            let column = if step.prismatic {
                [w[0], w[1], w[2], zero, zero, zero]
            } else {
                // w × (pos − origin); the motion about z leaves the origin where the joint is.
                let d: [T; 3] = std::array::from_fn(|i| pos[i] - frame.p[i]);
                [
                    w[1] * d[2] - w[2] * d[1],
                    w[2] * d[0] - w[0] * d[2],
                    w[0] * d[1] - w[1] * d[0],
                    w[0],
                    w[1],
                    w[2],
                ]
            };
            match &step.coordinate {
                Coordinate::Independent(i) => out[*i] = std::array::from_fn(|r| out[*i][r] + column[r]),
                Coordinate::Mimic(c) => c
                    .terms
                    .iter()
                    .for_each(|(i, m)| add(&mut out[*i], &column, T::splat(*m))),
                Coordinate::None => {}
            }
            next = step.parent;
        }
    }
}

/// [`PointKinematics::evaluate`] of one configuration, compiled for the baseline and for AVX
/// and AVX2 like the batches: the joints' sines and cosines go four to a register.
#[multiversion::multiversion(targets("x86_64+avx2", "x86_64+avx"))]
fn forward(plan: &PointKinematics, q: &[f64], ev: &mut Evaluation<f64>) {
    plan.evaluate(q, ev);
}

/// `dst += k · column`.
#[inline(always)]
fn add<T: Real>(dst: &mut [T; 6], column: &[T; 6], k: T) {
    for (d, c) in dst.iter_mut().zip(column) {
        *d = *d + *c * k;
    }
}

/// The nearest moving joint's step on the path to `body` (`None`: the base) and `body`'s pose
/// in that step's frame: the step's turn undone, then the fixed joints after it.
fn anchor(
    tree: &KinematicTree,
    step_of: &[usize],
    align: &[UnitQuaternion<f64>],
    body: usize,
) -> (Option<usize>, Isometry3<f64>) {
    let joints = tree.joints();
    let support = tree.support(body);
    let last = support.iter().rposition(|&j| joints[j].motion != Motion::Fixed);
    let (step, mut rel) = match last {
        Some(i) => {
            let s = step_of[support[i]];
            (Some(s), Isometry3::from_parts(Default::default(), align[s].inverse()))
        }
        None => (None, Isometry3::identity()),
    };
    for &j in &support[last.map_or(0, |i| i + 1)..] {
        rel *= joints[j].placement;
    }
    (step, rel)
}
