//! Forward kinematics and Jacobians into a reusable workspace (no allocation per call).

use nalgebra::{Isometry3, Matrix3x6, Matrix3xX, Matrix6xX, Point3, Vector3, Vector6};

use crate::model::geom::exp_twist;
use crate::model::perturbation::Perturbation;
use crate::model::tree::{Coordinate, KinematicTree, Motion};

/// Buffers for one evaluation of a [`KinematicTree`]: world poses of bodies, joint frames and
/// points. Create once per thread with [`TreeWorkspace::new`] and reuse.
#[derive(Debug, Clone)]
pub struct TreeWorkspace {
    /// World pose of each body (index 0 = base).
    pub body: Vec<Isometry3<f64>>,
    /// World pose of each joint frame (before the joint's motion).
    pub joint_frame: Vec<Isometry3<f64>>,
    /// World pose of each point.
    pub point: Vec<Isometry3<f64>>,
    /// Value of each joint used in the last evaluation (rad or m), offsets included.
    pub joint_value: Vec<f64>,
    /// Each joint's motion at that value (joint frame to body), kept so that a deformed
    /// evaluation reuses the rigid one's where the deformation leaves the value alone.
    pub motion: Vec<Isometry3<f64>>,
}

impl TreeWorkspace {
    /// Buffers sized for `tree`.
    pub fn new(tree: &KinematicTree) -> Self {
        TreeWorkspace {
            body: vec![Isometry3::identity(); tree.bodies().len()],
            joint_frame: vec![Isometry3::identity(); tree.joints().len()],
            point: vec![Isometry3::identity(); tree.points().len()],
            joint_value: vec![0.0; tree.joints().len()],
            motion: vec![Isometry3::identity(); tree.joints().len()],
        }
    }

    /// World position of point `p` from the last evaluation.
    pub fn point_position(&self, p: usize) -> Vector3<f64> {
        self.point[p].translation.vector
    }
}

impl KinematicTree {
    /// Rigid forward kinematics of every body, joint frame and point, with the base at the
    /// origin. `q` must hold [`nq`](KinematicTree::nq) values (see [`check_q`](KinematicTree::check_q)).
    pub fn forward_into(&self, q: &[f64], ws: &mut TreeWorkspace) {
        self.forward_impl(q, None, 0, None, ws);
    }

    /// Forward kinematics of the chain deformed by `pert` (Eq. 1–2 composed along the tree).
    pub fn forward_perturbed_into(&self, q: &[f64], pert: &Perturbation, ws: &mut TreeWorkspace) {
        self.forward_impl(q, Some(pert), 0, None, ws);
    }

    /// [`forward_perturbed_into`](Self::forward_perturbed_into) given `rigid`, the rigid
    /// evaluation of the same `q`: the joints before the first one `pert` moves are copied from
    /// it rather than recomputed. The same bits as the full evaluation.
    pub fn forward_perturbed_from_rigid_into(
        &self,
        q: &[f64],
        pert: &Perturbation,
        rigid: &TreeWorkspace,
        ws: &mut TreeWorkspace,
    ) {
        let first = (0..self.joints.len())
            .find(|&j| pert.joint_offset[j] != 0.0 || pert.joint_twist[j] != nalgebra::Vector6::zeros())
            .unwrap_or(self.joints.len());
        copy_prefix(rigid, first, ws);
        self.forward_impl(q, Some(pert), first, Some(rigid), ws);
    }

    /// Rigid [`forward_into`](Self::forward_into) of a tree that differs from the one `prefix`
    /// evaluated at the same `q` only in the placements of the joints `stepped` (ascending) and
    /// in its points (what a step of geometry leaves; the joints' motions and coordinates must
    /// be the same): joints outside the subtrees of `stepped` are copied from `prefix`, the
    /// others recomposed with the motions it holds (no sine or cosine). The same bits as the
    /// full evaluation.
    pub fn forward_restepped_into(&self, q: &[f64], prefix: &TreeWorkspace, stepped: &[usize], ws: &mut TreeWorkspace) {
        debug_assert_eq!(q.len(), self.nq());
        let first = stepped.first().map_or(self.joints.len(), |&j| j);
        copy_prefix(prefix, first, ws);
        for (j, joint) in self.joints.iter().enumerate().skip(first) {
            // A support lists the joints from the root down, so joint `a` (at depth
            // `support[a + 1].len() − 1` of its own) carries body j + 1 iff it sits at that depth
            // of body j + 1's support.
            let carried = |a: &usize| self.support[j + 1].get(self.support[a + 1].len() - 1) == Some(a);
            if stepped.iter().any(carried) {
                let frame = ws.body[joint.parent] * joint.placement;
                ws.joint_frame[j] = frame;
                ws.body[j + 1] = compose_motion(&joint.motion, &frame, &prefix.motion[j]);
            } else {
                ws.joint_frame[j] = prefix.joint_frame[j];
                ws.body[j + 1] = prefix.body[j + 1];
            }
            ws.joint_value[j] = prefix.joint_value[j];
            ws.motion[j] = prefix.motion[j];
        }
        self.points_into(None, ws);
    }

    /// Evaluates joints `start..` (the ones before are in `ws` already) and every point; with
    /// `rigid`, the rigid evaluation of the same `q`, a joint whose value the deformation
    /// leaves alone takes its motion from there (the same bits, no sine and cosine).
    fn forward_impl(
        &self,
        q: &[f64],
        pert: Option<&Perturbation>,
        start: usize,
        rigid: Option<&TreeWorkspace>,
        ws: &mut TreeWorkspace,
    ) {
        debug_assert_eq!(q.len(), self.nq());
        ws.body[0] = Isometry3::identity();
        for (j, joint) in self.joints.iter().enumerate().skip(start) {
            let mut value = self.joint_value(j, q);
            let mut frame = ws.body[joint.parent] * joint.placement;
            let mut offset = 0.0;
            if let Some(p) = pert {
                offset = p.joint_offset[j];
                value += offset;
                if p.joint_twist[j] != nalgebra::Vector6::zeros() {
                    frame *= exp_twist(&p.joint_twist[j]);
                }
            }
            let motion = match rigid {
                Some(r) if offset == 0.0 => r.motion[j],
                _ => joint.motion.transform(value),
            };
            ws.joint_value[j] = value;
            ws.joint_frame[j] = frame;
            ws.motion[j] = motion;
            ws.body[j + 1] = compose_motion(&joint.motion, &frame, &motion);
        }
        self.points_into(pert, ws);
    }

    /// Every point's pose from the bodies in `ws`, each deformed by its twist in `pert`.
    fn points_into(&self, pert: Option<&Perturbation>, ws: &mut TreeWorkspace) {
        for (i, point) in self.points.iter().enumerate() {
            let mut pose = ws.body[point.body] * point.local;
            if let Some(p) = pert
                && p.point_twist[i] != nalgebra::Vector6::zeros()
            {
                pose *= exp_twist(&p.point_twist[i]);
            }
            ws.point[i] = pose;
        }
    }

    /// First-order change of point `p`'s world position (m) when `deformation`, the
    /// perturbation of the last evaluation in `ws`, changes by `change` (allocating; see
    /// [`PointSensitivity`] to reuse one point's map for many changes).
    pub fn point_perturbation_effect(
        &self,
        ws: &TreeWorkspace,
        deformation: &Perturbation,
        p: usize,
        change: &Perturbation,
    ) -> Vector3<f64> {
        let mut map = PointSensitivity::default();
        map.update(self, ws, deformation, p);
        map.effect(change)
    }

    /// Allocating convenience: world positions of every point (m).
    pub fn point_positions(&self, q: &[f64]) -> Vec<Vector3<f64>> {
        let mut ws = TreeWorkspace::new(self);
        self.forward_into(q, &mut ws);
        ws.point.iter().map(|p| p.translation.vector).collect()
    }

    /// Jacobian of the world position of point `p` with respect to `q` (3 × nq), from the frames
    /// of the last evaluation in `ws`. Mimic joints contribute to the columns of the
    /// coordinates they follow. Error-model perturbations are treated as constant.
    pub fn point_jacobian_into(&self, ws: &TreeWorkspace, p: usize, out: &mut Matrix3xX<f64>) {
        let pos = ws.point[p].translation.vector;
        out.fill(0.0);
        for &j in &self.support[self.points[p].body] {
            if let Some(col) = self.joint_velocity(ws, j, &pos) {
                self.scatter(j, |c, k| {
                    let mut dst = out.column_mut(c);
                    dst += col.0 * k;
                });
            }
        }
    }

    /// Jacobian of the pose of point `p` (6 × nq): rows 0–2 the linear velocity of the point,
    /// rows 3–5 the angular velocity, both in world coordinates (the "space-at-point" form).
    pub fn pose_jacobian_into(&self, ws: &TreeWorkspace, p: usize, out: &mut Matrix6xX<f64>) {
        let pos = ws.point[p].translation.vector;
        out.fill(0.0);
        for &j in &self.support[self.points[p].body] {
            if let Some((lin, ang)) = self.joint_velocity(ws, j, &pos) {
                self.scatter(j, |c, k| {
                    for r in 0..3 {
                        out[(r, c)] += lin[r] * k;
                        out[(r + 3, c)] += ang[r] * k;
                    }
                });
            }
        }
    }

    /// Linear velocity of `pos` and angular velocity produced by unit speed of joint `j`.
    #[inline]
    fn joint_velocity(&self, ws: &TreeWorkspace, j: usize, pos: &Vector3<f64>) -> Option<(Vector3<f64>, Vector3<f64>)> {
        let frame = &ws.joint_frame[j];
        match self.joints[j].motion {
            Motion::Revolute(axis) => {
                let w = frame.rotation * axis.into_inner();
                let origin: Point3<f64> = frame.translation.vector.into();
                Some((w.cross(&(pos - origin.coords)), w))
            }
            Motion::Prismatic(axis) => Some((frame.rotation * axis.into_inner(), Vector3::zeros())),
            Motion::Fixed => None,
        }
    }

    /// Calls `f(column, d value_j / d q_column)` for each coordinate joint `j` depends on.
    #[inline]
    fn scatter(&self, j: usize, mut f: impl FnMut(usize, f64)) {
        match &self.joints[j].coordinate {
            Coordinate::Independent(i) => f(*i, 1.0),
            Coordinate::Mimic(c) => c.terms.iter().for_each(|(i, k)| f(*i, *k)),
            Coordinate::None => {}
        }
    }
}

/// `frame * motion` without the parts a motion leaves at identity (a rotation has no
/// translation, a slide no rotation): the same values, fewer operations.
#[inline]
fn compose_motion(kind: &Motion, frame: &Isometry3<f64>, motion: &Isometry3<f64>) -> Isometry3<f64> {
    match kind {
        Motion::Revolute(_) => Isometry3::from_parts(frame.translation, frame.rotation * motion.rotation),
        Motion::Prismatic(_) => Isometry3::from_parts(
            (frame.translation.vector + frame.rotation * motion.translation.vector).into(),
            frame.rotation,
        ),
        Motion::Fixed => *frame,
    }
}

/// Copies the bodies, joint frames and values that joints `..first` determine from `from`.
fn copy_prefix(from: &TreeWorkspace, first: usize, ws: &mut TreeWorkspace) {
    // Body `first` hangs from joint `first − 1`; later joints only move later bodies.
    ws.body[..=first].copy_from_slice(&from.body[..=first]);
    ws.joint_frame[..first].copy_from_slice(&from.joint_frame[..first]);
    ws.joint_value[..first].copy_from_slice(&from.joint_value[..first]);
    ws.motion[..first].copy_from_slice(&from.motion[..first]);
}

/// How one point's world position responds, to first order, to a change of the deformation
/// of the last evaluation: per joint it depends on, the displacement per unit of its twist
/// (through the twist exponential's right Jacobian, at the deformed joint frame) and per unit
/// of its offset (along or about its axis), and per unit of the point's own twist. Built once
/// per evaluation, it turns any change into a displacement with a few dot products, the
/// derivative of [`KinematicTree::forward_perturbed_into`] along that change without a second
/// forward pass. Buffers are reused across [`update`](Self::update)s.
#[derive(Debug, Clone, Default)]
pub struct PointSensitivity {
    /// `(joint, 3 × 6 map of its twist)`.
    twists: Vec<(usize, Matrix3x6<f64>)>,
    /// `(joint, displacement per unit offset)`.
    offsets: Vec<(usize, Vector3<f64>)>,
    /// The map of the point's own twist.
    point_twist: Matrix3x6<f64>,
    point: usize,
}

impl PointSensitivity {
    /// The map of point `p` at the evaluation in `ws` of `tree` deformed by `deformation`.
    pub fn update(&mut self, tree: &KinematicTree, ws: &TreeWorkspace, deformation: &Perturbation, p: usize) {
        let pos = ws.point[p].translation.vector;
        self.twists.clear();
        self.offsets.clear();
        self.point = p;
        for &j in &tree.support[tree.points[p].body] {
            let frame = &ws.joint_frame[j];
            let r = frame.rotation.to_rotation_matrix().into_inner();
            // A body twist (v, w) at the frame moves the point by R v + (R w) × (pos − o).
            let arm = crate::model::geom::skew(&(pos - frame.translation.vector));
            let mut map = Matrix3x6::zeros();
            map.fixed_view_mut::<3, 3>(0, 0).copy_from(&r);
            map.fixed_view_mut::<3, 3>(0, 3).copy_from(&(-arm * r));
            self.twists
                .push((j, right_jacobian_rows(&deformation.joint_twist[j], &map)));
            if let Some((lin, _)) = tree.joint_velocity(ws, j, &pos) {
                self.offsets.push((j, lin));
            }
        }
        let mut map = Matrix3x6::zeros();
        map.fixed_view_mut::<3, 3>(0, 0)
            .copy_from(&ws.point[p].rotation.to_rotation_matrix().into_inner());
        self.point_twist = right_jacobian_rows(&deformation.point_twist[p], &map);
    }

    /// The displacement of the point (m, world) for the deformation change `change`.
    pub fn effect(&self, change: &Perturbation) -> Vector3<f64> {
        let mut dp = self.point_twist * change.point_twist[self.point];
        for (j, map) in &self.twists {
            let xi = &change.joint_twist[*j];
            if *xi != Vector6::zeros() {
                dp += map * xi;
            }
        }
        for (j, lin) in &self.offsets {
            dp += lin * change.joint_offset[*j];
        }
        dp
    }
}

/// `map · J_r(ξ)`: the rows of `map` carried through the right Jacobian of the twist
/// exponential (see [`crate::model::geom::exp_twist_right_jacobian`]), each row by the transposed
/// series. `map` itself when `ξ` is zero.
fn right_jacobian_rows(xi: &Vector6<f64>, map: &Matrix3x6<f64>) -> Matrix3x6<f64> {
    if *xi == Vector6::zeros() {
        return *map;
    }
    let mut out = Matrix3x6::zeros();
    for i in 0..3 {
        let row = map.row(i).transpose();
        out.set_row(
            i,
            &crate::model::geom::exp_twist_right_jacobian_transpose(xi, &row).transpose(),
        );
    }
    out
}
