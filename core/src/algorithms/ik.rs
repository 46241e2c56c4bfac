//! Inverse kinematics on the full model: the deformed arm that [`Robot::forward_into`] gives
//! (chain + error models), so the joint command found reaches the target *with* deflection.
//!
//! Two iterations, both on the task Jacobian of the deformed frames (error-model deformations
//! held constant within a step, which costs a little convergence speed, never accuracy: the
//! error is always measured on the full model):
//! - [`IkMethod::NewtonRaphson`], as in the deflection paper: `Δq = Jᵀ (J Jᵀ)⁻¹ e` (the
//!   minimum-norm step, which also serves redundant chains), with step halving when the error
//!   does not drop;
//! - [`IkMethod::DampedLeastSquares`]: `Δq = Jᵀ (J Jᵀ + μ I)⁻¹ e` with `μ` adapted
//!   Levenberg–Marquardt style, robust near singular configurations.
//!
//! Joint limits are respected by projecting every iterate onto them. Locked coordinates
//! ([`IkWorkspace::lock`]) keep their start value exactly: their Jacobian columns are left out
//! and restarts do not move them. A start that stalls is followed by deterministic restarts
//! spread over the limits (Sobol points). When no start
//! reaches the tolerance the error carries the closest configuration found and its distance;
//! the iteration count is capped, so the solver always returns.

use nalgebra::{Cholesky, Isometry3, Matrix3, Matrix3xX, Matrix6, Matrix6xX, Vector3, Vector6};

use crate::error::Error;
use crate::kinematics::sensor::SensorReadings;
use crate::robot::{Conditions, Robot, RobotWorkspace};

/// What to reach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum IkTarget {
    /// A position of the point (m, base frame); orientation free.
    Position(Vector3<f64>),
    /// A full pose of the point (base frame).
    Pose(Isometry3<f64>),
}

/// The iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum IkMethod {
    /// Newton–Raphson with the minimum-norm (pseudo-inverse) step and step halving.
    NewtonRaphson,
    /// Damped least squares (Levenberg–Marquardt) with damping `½|e|² + μ`, `μ` adapted.
    #[default]
    DampedLeastSquares,
}

/// A position offset linear in the joint values, `value + jacobian · (q − q_ref)` (m, base
/// frame), added to the point's modelled position: the first-order model of a learnt residual
/// around `q_ref`, so that one solve inverts the model and the residual together.
#[derive(Debug, Clone, PartialEq)]
pub struct LinearOffset {
    /// The offset at `q_ref` (m).
    pub value: Vector3<f64>,
    /// Its derivative with respect to each joint value (m/rad or m/m), `3 × nq`.
    pub jacobian: Matrix3xX<f64>,
    /// Where it is linearised.
    pub q_ref: Vec<f64>,
}

impl LinearOffset {
    /// A zero offset for `nq` joint values.
    pub fn zeros(nq: usize) -> Self {
        LinearOffset {
            value: Vector3::zeros(),
            jacobian: Matrix3xX::zeros(nq),
            q_ref: vec![0.0; nq],
        }
    }

    /// The offset at `q` (m).
    pub fn at(&self, q: &[f64]) -> Vector3<f64> {
        let mut v = self.value;
        for (c, (a, b)) in q.iter().zip(&self.q_ref).enumerate() {
            v += self.jacobian.column(c) * (a - b);
        }
        v
    }
}

/// Settings of [`solve_ik`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkParams {
    /// The iteration.
    pub method: IkMethod,
    /// Most iterations per start.
    pub max_iterations: usize,
    /// Further starts (Sobol points within the limits) after the given one fails.
    pub restarts: usize,
    /// Position error (m) at which the target counts as reached.
    pub position_tolerance: f64,
    /// Orientation error (rad) at which a pose target counts as reached.
    pub orientation_tolerance: f64,
    /// Metres per radian when position and orientation errors are weighed together.
    pub orientation_weight: f64,
    /// Initial value of the adaptive part `μ` of the damping `½|e|² + μ` of damped least
    /// squares (m²).
    pub damping: f64,
    /// Largest change of one joint in one step (rad or m).
    pub max_step: f64,
    /// Temperature (°C) passed to error models that use it.
    pub temperature: Option<f64>,
    /// The sensors' readings (the robot's current tilt), passed to error models as a measured
    /// row's are.
    pub sensors: SensorReadings,
}

impl IkParams {
    /// The conditions the full model is evaluated under.
    pub fn conditions(&self) -> Conditions {
        Conditions {
            temperature: self.temperature,
            sensors: self.sensors,
            ..Conditions::default()
        }
    }
}

impl Default for IkParams {
    fn default() -> Self {
        IkParams {
            method: IkMethod::default(),
            max_iterations: 200,
            restarts: 64,
            position_tolerance: 1e-10,
            orientation_tolerance: 1e-10,
            orientation_weight: 1.0,
            damping: 1e-6,
            max_step: 0.5,
            temperature: None,
            sensors: SensorReadings::default(),
        }
    }
}

/// How a successful solve went; the joint values are in [`IkWorkspace::q`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct IkReport {
    /// Iterations over all starts.
    pub iterations: usize,
    /// Starts used (1 = the given one).
    pub starts: usize,
    /// Final position error (m).
    pub position_error: f64,
    /// Final orientation error (rad; 0 for position targets).
    pub orientation_error: f64,
}

/// Why IK gave no solution.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IkError {
    /// No start reached the target within the tolerances: the closest configuration found.
    #[error(
        "target not reached: closest point [{:.6}, {:.6}, {:.6}] m is {distance:.3e} m away (orientation error {orientation_error:.3e} rad) after {iterations} iterations",
        closest_point.x, closest_point.y, closest_point.z
    )]
    Unreachable {
        /// Joint values of the closest configuration found (within limits).
        closest_q: Vec<f64>,
        /// Where the point is at `closest_q` (m, base frame).
        closest_point: Vector3<f64>,
        /// Its distance to the target position (m).
        distance: f64,
        /// Its orientation error (rad; 0 for position targets).
        orientation_error: f64,
        /// Iterations over all starts.
        iterations: usize,
    },
    /// The request itself cannot be used.
    #[error(transparent)]
    Input(#[from] Error),
}

/// A target not reached is the core's [`Error::NotConverged`] (the closest configuration is
/// dropped); a bad request is the core error it carries.
impl From<IkError> for Error {
    fn from(e: IkError) -> Self {
        match e {
            IkError::Unreachable {
                closest_point,
                distance,
                orientation_error,
                iterations,
                ..
            } => Error::NotConverged {
                what: "IK".into(),
                iterations,
                best: format!(
                    "closest point [{:.6}, {:.6}, {:.6}] m is {distance:.3e} m from the target (orientation error {orientation_error:.3e} rad)",
                    closest_point.x, closest_point.y, closest_point.z
                ),
            },
            IkError::Input(e) => e,
        }
    }
}

/// Buffers of the solver, made once per robot and thread; solving allocates nothing per
/// iteration.
#[derive(Debug, Clone)]
pub struct IkWorkspace {
    /// Full-model evaluation buffers; after a solve they hold the solution's frames.
    pub robot: RobotWorkspace,
    jac: Matrix6xX<f64>,
    q: Vec<f64>,
    /// The start of the current solve.
    start: Vec<f64>,
    trial: Vec<f64>,
    best: Vec<f64>,
    dq: Vec<f64>,
    /// Per coordinate, whether the solver keeps it at its start value.
    locked: Vec<bool>,
}

impl IkWorkspace {
    /// Buffers sized for `robot`.
    pub fn new(robot: &Robot) -> Self {
        let n = robot.tree().nq();
        IkWorkspace {
            robot: robot.workspace(),
            jac: Matrix6xX::zeros(n),
            q: vec![0.0; n],
            start: vec![0.0; n],
            trial: vec![0.0; n],
            best: vec![0.0; n],
            dq: vec![0.0; n],
            locked: vec![false; n],
        }
    }

    /// Which coordinates later solves keep at their start value (one flag per coordinate;
    /// none by default).
    pub fn lock(&mut self, locked: &[bool]) -> Result<(), Error> {
        if locked.len() != self.locked.len() {
            return Err(Error::Dimension {
                what: "locked joints".into(),
                expected: self.locked.len(),
                got: locked.len(),
            });
        }
        self.locked.copy_from_slice(locked);
        Ok(())
    }

    /// Per coordinate, whether solves keep it at its start value.
    pub fn locked(&self) -> &[bool] {
        &self.locked
    }

    /// Joint values of the last solve (the solution, or the closest configuration found).
    pub fn q(&self) -> &[f64] {
        &self.q
    }
}

/// Weighted error of the point's current pose in `ws.frames` with respect to `target`:
/// rows 0–2 position (m), rows 3–5 orientation as a world rotation vector times the weight.
/// The position includes `offset` at `q`, when there is one.
fn task_error(
    rw: &RobotWorkspace,
    point: usize,
    target: &IkTarget,
    weight: f64,
    offset: Option<&LinearOffset>,
    q: &[f64],
) -> (Vector6<f64>, f64, f64) {
    let pose = &rw.frames.point[point];
    let position = pose.translation.vector + offset.map_or_else(Vector3::zeros, |o| o.at(q));
    match target {
        IkTarget::Position(p) => {
            let e = p - position;
            (Vector6::new(e.x, e.y, e.z, 0.0, 0.0, 0.0), e.norm(), 0.0)
        }
        IkTarget::Pose(t) => {
            let e = t.translation.vector - position;
            let r = (t.rotation * pose.rotation.inverse()).scaled_axis();
            let w = r * weight;
            (Vector6::new(e.x, e.y, e.z, w.x, w.y, w.z), e.norm(), r.norm())
        }
    }
}

fn project(robot: &Robot, q: &mut [f64]) {
    for (v, l) in q.iter_mut().zip(robot.tree().coordinate_limits()) {
        if let Some(l) = l {
            *v = v.clamp(l.lower, l.upper);
        }
    }
}

/// `J Jᵀ` (6 × 6); for position targets the orientation block is the identity.
fn gram(jac: &Matrix6xX<f64>, pose_target: bool) -> Matrix6<f64> {
    let mut jjt = Matrix6::zeros();
    for c in 0..jac.ncols() {
        let col = jac.column(c);
        jjt += col * col.transpose();
    }
    if !pose_target {
        for r in 3..6 {
            jjt[(r, r)] = 1.0;
        }
    }
    jjt
}

/// `(J Jᵀ + reg I)⁻¹ e` from the Gram matrix `jjt`. For position targets the orientation rows
/// of `J` are zero, so only the 3 × 3 position block is factored: a fifth of the work of the
/// 6 × 6 system, which otherwise costs as much as a Jacobian.
fn solve_normal(jjt: &Matrix6<f64>, reg: f64, e: &Vector6<f64>, pose_target: bool) -> Option<Vector6<f64>> {
    if pose_target {
        let a = jjt + Matrix6::from_diagonal_element(reg);
        return Cholesky::new(a).map(|ch| ch.solve(e));
    }
    let a = jjt.fixed_view::<3, 3>(0, 0) + Matrix3::from_diagonal_element(reg);
    let y = Cholesky::new(a)?.solve(&e.fixed_rows::<3>(0).into_owned());
    Some(Vector6::new(y.x, y.y, y.z, 0.0, 0.0, 0.0))
}

/// Zeroes the Jacobian columns of joints sitting at a limit whose step points beyond it;
/// true when any column was removed.
fn free_blocked(robot: &Robot, q: &[f64], dq: &[f64], jac: &mut Matrix6xX<f64>) -> bool {
    let mut any = false;
    for (k, l) in robot.tree().coordinate_limits().iter().enumerate() {
        let Some(l) = l else { continue };
        let span = (l.upper - l.lower).abs().max(1e-300);
        let at_low = q[k] <= l.lower + 1e-12 * span && dq[k] < 0.0;
        let at_high = q[k] >= l.upper - 1e-12 * span && dq[k] > 0.0;
        if (at_low || at_high) && jac.column(k).iter().any(|v| *v != 0.0) {
            jac.column_mut(k).fill(0.0);
            any = true;
        }
    }
    any
}

/// Solves IK for point `point` (index in `robot.tree().points()`, e.g. [`Robot::tool`]) from
/// the start `q0`. On success the joint values are in [`IkWorkspace::q`] and `ws.robot.frames`
/// holds the full model there. Targets are in the robot base frame.
pub fn solve_ik(
    robot: &Robot,
    point: usize,
    target: &IkTarget,
    q0: &[f64],
    opts: &IkParams,
    ws: &mut IkWorkspace,
) -> Result<IkReport, IkError> {
    solve_ik_with_offset(robot, point, target, None, q0, opts, ws)
}

/// [`solve_ik`] for the point moved by a [`LinearOffset`] (its Jacobian joins the task
/// Jacobian's position rows), e.g. a learnt residual linearised at the previous solution.
pub fn solve_ik_with_offset(
    robot: &Robot,
    point: usize,
    target: &IkTarget,
    offset: Option<&LinearOffset>,
    q0: &[f64],
    opts: &IkParams,
    ws: &mut IkWorkspace,
) -> Result<IkReport, IkError> {
    solve_from(robot, point, target, offset, Start::Given(q0), opts, ws)
}

/// Where a solve starts.
#[derive(Clone, Copy)]
pub(crate) enum Start<'q> {
    /// These joint values.
    Given(&'q [f64]),
    /// Where the last solve with the same robot, workspace and conditions ended
    /// ([`IkWorkspace::q`]), whose frames the workspace still holds: saves one evaluation of
    /// the full model when solves follow each other.
    Previous,
}

/// [`solve_ik_with_offset`] from `start`.
pub(crate) fn solve_from(
    robot: &Robot,
    point: usize,
    target: &IkTarget,
    offset: Option<&LinearOffset>,
    start_at: Start<'_>,
    opts: &IkParams,
    ws: &mut IkWorkspace,
) -> Result<IkReport, IkError> {
    take_start(robot, start_at, ws)?;
    check_target(robot, point, target, offset)?;
    let solve = Solve {
        robot,
        point,
        target,
        offset,
        opts,
        pose_target: matches!(target, IkTarget::Pose(_)),
    };
    let mut iterations = 0;
    let mut best_cost = f64::INFINITY;
    for start in 0..=opts.restarts {
        let previous = start == 0 && matches!(start_at, Start::Previous);
        solve.seed(start, previous, ws);
        let mut at = solve.iterate_at(ws);
        solve.iterate(&mut at, &mut iterations, ws);
        if solve.converged(&at) {
            return Ok(IkReport {
                iterations,
                starts: start + 1,
                position_error: at.pe,
                orientation_error: at.oe,
            });
        }
        if at.cost < best_cost {
            best_cost = at.cost;
            ws.best.copy_from_slice(&ws.q);
        }
    }
    Err(solve.closest(iterations, ws))
}

/// Checks that `ws` fits `robot` and copies the start into it; a locked coordinate is kept
/// exactly, so a start outside its limits cannot be projected onto them and is refused.
fn take_start(robot: &Robot, start_at: Start<'_>, ws: &mut IkWorkspace) -> Result<(), IkError> {
    let tree = robot.tree();
    let n = tree.nq();
    if ws.q.len() != n {
        return Err(Error::InvalidArgument {
            what: "IK workspace".into(),
            reason: format!("made for a robot with {} joint values, this one has {n}", ws.q.len()),
        }
        .into());
    }
    match start_at {
        Start::Given(q0) => {
            tree.check_q(q0)?;
            ws.start.copy_from_slice(q0);
        }
        Start::Previous => ws.start.copy_from_slice(&ws.q),
    }
    for (k, l) in tree.coordinate_limits().iter().enumerate() {
        if let Some(l) = l
            && ws.locked[k]
            && !(l.lower..=l.upper).contains(&ws.start[k])
        {
            return Err(Error::InvalidArgument {
                what: format!("locked joint `{}`", tree.coordinate_names()[k]),
                reason: {
                    let unit = if tree.coordinate_is_prismatic()[k] { "m" } else { "rad" };
                    format!(
                        "held at {} {unit}, outside its limits [{}, {}] {unit}",
                        ws.start[k], l.lower, l.upper
                    )
                },
            }
            .into());
        }
    }
    Ok(())
}

/// Checks that the point exists, the target is finite and the offset fits the robot.
fn check_target(robot: &Robot, point: usize, target: &IkTarget, offset: Option<&LinearOffset>) -> Result<(), IkError> {
    let tree = robot.tree();
    let n = tree.nq();
    if point >= tree.points().len() {
        return Err(Error::InvalidArgument {
            what: format!("point {point}"),
            reason: format!("does not exist; the robot has {} points", tree.points().len()),
        }
        .into());
    }
    let finite = match target {
        IkTarget::Position(p) => p.iter().all(|v| v.is_finite()),
        IkTarget::Pose(t) => t.to_homogeneous().iter().all(|v| v.is_finite()),
    };
    if !finite {
        return Err(Error::InvalidArgument {
            what: "IK target".into(),
            reason: "not finite".into(),
        }
        .into());
    }
    if let Some(o) = offset
        && (o.q_ref.len() != n || o.jacobian.ncols() != n)
    {
        return Err(Error::InvalidArgument {
            what: "linear offset".into(),
            reason: format!(
                "made for {} joint values and {} Jacobian columns, the robot has {n} joint values",
                o.q_ref.len(),
                o.jacobian.ncols()
            ),
        }
        .into());
    }
    Ok(())
}

/// One checked request: what every start and iteration of the solve reads.
struct Solve<'a> {
    robot: &'a Robot,
    point: usize,
    target: &'a IkTarget,
    offset: Option<&'a LinearOffset>,
    opts: &'a IkParams,
    pose_target: bool,
}

/// Where one start's iteration stands: the error at [`IkWorkspace::q`], its norms, its cost
/// and the adaptive damping.
struct Iterate {
    e: Vector6<f64>,
    pe: f64,
    oe: f64,
    cost: f64,
    mu: f64,
}

impl Solve<'_> {
    fn converged(&self, at: &Iterate) -> bool {
        at.pe <= self.opts.position_tolerance && at.oe <= self.opts.orientation_tolerance
    }

    /// The task error at `q`, whose full model `ws.robot` holds.
    fn error(&self, ws: &RobotWorkspace, q: &[f64]) -> (Vector6<f64>, f64, f64) {
        task_error(
            ws,
            self.point,
            self.target,
            self.opts.orientation_weight,
            self.offset,
            q,
        )
    }

    /// Start `start` into `ws.q` with its full model: the given one, then Sobol points within
    /// the limits. The `previous` solve's end already has its frames in the workspace.
    fn seed(&self, start: usize, previous: bool, ws: &mut IkWorkspace) {
        let tree = self.robot.tree();
        let limits = tree.coordinate_limits();
        if start == 0 {
            ws.q.copy_from_slice(&ws.start);
        } else {
            for (k, v) in ws.q.iter_mut().enumerate() {
                let h = crate::model::sampling::sobol_coordinate(start as u32, k, 0);
                *v = match limits[k] {
                    _ if ws.locked[k] => ws.start[k],
                    Some(l) => l.lower + (l.upper - l.lower) * h,
                    None if tree.coordinate_is_prismatic()[k] => ws.start[k],
                    None => -std::f64::consts::PI + 2.0 * std::f64::consts::PI * h,
                };
            }
        }
        if !previous {
            project(self.robot, &mut ws.q);
            self.robot
                .forward_under_into(&ws.q, self.opts.conditions(), &mut ws.robot);
        }
    }

    /// The iteration's state at the seeded start.
    fn iterate_at(&self, ws: &IkWorkspace) -> Iterate {
        let (e, pe, oe) = self.error(&ws.robot, &ws.q);
        Iterate {
            e,
            pe,
            oe,
            cost: e.norm_squared(),
            mu: self.opts.damping.max(0.0),
        }
    }

    /// Iterates from the seeded start until it converges, no step lowers the error, the error
    /// stalls or the iterations run out; `iterations` counts them over all starts.
    fn iterate(&self, at: &mut Iterate, iterations: &mut usize, ws: &mut IkWorkspace) {
        let mut checkpoint = at.cost;
        for it in 0..self.opts.max_iterations {
            if self.converged(at) {
                break;
            }
            *iterations += 1;
            self.task_jacobian(ws);
            if !self.step(at, ws) {
                // Restore the frames of the current iterate and give up on this start.
                self.robot
                    .forward_under_into(&ws.q, self.opts.conditions(), &mut ws.robot);
                break;
            }
            // Stall detection: the error must keep shrinking.
            if it % 20 == 19 {
                if at.cost > 0.9 * checkpoint {
                    break;
                }
                checkpoint = at.cost;
            }
        }
    }

    /// Task Jacobian of the deformed arm into `ws.jac`: locked columns zero, the offset's
    /// Jacobian added to the position rows, orientation rows weighted (zero for positions).
    fn task_jacobian(&self, ws: &mut IkWorkspace) {
        let w = self.opts.orientation_weight;
        self.robot
            .tree()
            .pose_jacobian_into(&ws.robot.frames, self.point, &mut ws.jac);
        for c in 0..ws.q.len() {
            if ws.locked[c] {
                ws.jac.column_mut(c).fill(0.0);
                continue;
            }
            if let Some(o) = self.offset {
                for r in 0..3 {
                    ws.jac[(r, c)] += o.jacobian[(r, c)];
                }
            }
            for r in 3..6 {
                ws.jac[(r, c)] = if self.pose_target { ws.jac[(r, c)] * w } else { 0.0 };
            }
        }
    }

    /// One iteration's step from `ws.q` with the task Jacobian in `ws.jac`, the damping raised
    /// (or the step halved) until one lowers the error: true when one did, `ws.q` moved there.
    fn step(&self, at: &mut Iterate, ws: &mut IkWorkspace) -> bool {
        let opts = self.opts;
        let mut jjt = gram(&ws.jac, self.pose_target);
        let scale = 1.0 + jjt.trace();
        for _attempt in 0..(12 + ws.q.len()) {
            // Damping grows with the error (Sugihara 2011, λ = ½|e|² + μ): large steps
            // are damped far from the target and near singular configurations, where
            // a fixed small μ lets a step overshoot into another branch or a limit, and
            // the damping vanishes as the error does, so the end is Gauss–Newton's.
            let reg = match opts.method {
                IkMethod::NewtonRaphson => 1e-14 * scale,
                IkMethod::DampedLeastSquares => at.mu + 0.5 * at.cost + 1e-14 * scale,
            };
            let Some(y) = solve_normal(&jjt, reg, &at.e, self.pose_target) else {
                at.mu = (at.mu * 10.0).max(1e-12 * scale);
                continue;
            };
            for (c, d) in ws.dq.iter_mut().enumerate() {
                *d = ws.jac.column(c).dot(&y);
            }
            // Joints at a limit that the step pushes outwards leave the problem (active
            // set); the step is solved again without them.
            if free_blocked(self.robot, &ws.q, &ws.dq, &mut ws.jac) {
                jjt = gram(&ws.jac, self.pose_target);
                continue;
            }
            if self.line_search(at, ws) {
                at.mu = (at.mu / 3.0).max(0.0);
                return true;
            }
            if opts.method == IkMethod::NewtonRaphson {
                return false;
            }
            at.mu = (at.mu * 8.0).max(1e-9 * scale);
        }
        false
    }

    /// Tries the step `ws.dq`, shortened to the largest joint step: Newton–Raphson halves it
    /// until the error drops, damped least squares tries it once (its damping is raised
    /// instead). True when the error dropped, `ws.q` and `at` moved there.
    fn line_search(&self, at: &mut Iterate, ws: &mut IkWorkspace) -> bool {
        let opts = self.opts;
        let largest = ws.dq.iter().fold(0.0f64, |m, d| m.max(d.abs()));
        let mut alpha = if largest > opts.max_step {
            opts.max_step / largest
        } else {
            1.0
        };
        let tries = if opts.method == IkMethod::NewtonRaphson { 12 } else { 1 };
        for _ in 0..tries {
            for k in 0..ws.q.len() {
                ws.trial[k] = ws.q[k] + alpha * ws.dq[k];
            }
            project(self.robot, &mut ws.trial);
            self.robot
                .forward_under_into(&ws.trial, opts.conditions(), &mut ws.robot);
            let (e2, pe2, oe2) = self.error(&ws.robot, &ws.trial);
            let c2 = e2.norm_squared();
            if c2 < at.cost {
                ws.q.copy_from_slice(&ws.trial);
                (at.e, at.pe, at.oe, at.cost) = (e2, pe2, oe2, c2);
                return true;
            }
            alpha *= 0.5;
        }
        false
    }

    /// The failure: the closest configuration over all starts, left in `ws` with its frames.
    fn closest(&self, iterations: usize, ws: &mut IkWorkspace) -> IkError {
        ws.q.copy_from_slice(&ws.best);
        self.robot
            .forward_under_into(&ws.q, self.opts.conditions(), &mut ws.robot);
        let (_, pe, oe) = self.error(&ws.robot, &ws.q);
        IkError::Unreachable {
            closest_q: ws.best.clone(),
            closest_point: ws.robot.frames.point[self.point].translation.vector
                + self.offset.map_or_else(Vector3::zeros, |o| o.at(&ws.q)),
            distance: pe,
            orientation_error: oe,
            iterations,
        }
    }
}
