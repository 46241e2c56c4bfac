//! Compensation: the joint command that puts the tool on a target, through the full model
//! (chain + error models) and, when the model carries one, its fitted residual predictor.
//!
//! The predictor maps joint values to the residual `measured − modelled` (m, measurement
//! frame), so the arm is expected at `FK(q) + e(q)` (with `e` rotated into the base frame).
//! Two ways to invert that:
//! - [`CompensationMode::Paper`], the deflection paper's Sec. II.C two-step: IK on the model,
//!   predict the residual at that command, shift the target by it, IK again;
//! - [`CompensationMode::Exact`]: solves `FK(q) + e(q) = target` itself, by Newton's method on
//!   the model and the residual together: the residual is linearised at the current command
//!   (value and derivative, for predictors that have one) and IK solves the model plus that
//!   linear offset; this repeats, with the value re-predicted and the derivative kept (the
//!   chord method), until the full model lands within the tolerance, typically three solves
//!   after the first on the rock-drill twin. Predictors without a derivative get the
//!   fixed-point version (the residual held constant within each solve), which converges
//!   linearly at the rate of the residual's sensitivity.
//!
//! Only the joints that move the tool (the measured chain, for a tool that is a marker) change:
//! every other joint keeps its start value, so compensating one arm of a humanoid leaves its
//! legs, head and other arm where they were. More joints can be locked
//! ([`Compensator::lock`]).

use nalgebra::{Matrix3, UnitQuaternion, Vector3};

use crate::algorithms::evaluate::predictor_input_into;
use crate::algorithms::ik::{IkError, IkParams, IkReport, IkTarget, IkWorkspace, LinearOffset, Start, solve_from};
use crate::error::{Error, Result};
use crate::kinematics::sensor::SensorReadings;
use crate::plugin::FittedPredictor;
use crate::robot::Robot;
use crate::robot::robot_file::PredictorFrame;

/// Position tolerance (m) of the first solve when a predictor follows. It only sets where the
/// residual is first linearised, and the solves after it work on the full model, so coming
/// within a tenth of a millimetre is enough: the final command then moves by the residual
/// (millimetres) anyway, and each tighter iteration here would cost a model evaluation.
const FIRST_SOLVE_TOLERANCE: f64 = 1e-4;

/// Tolerance of each later solve as a share of the full model's mismatch before it.
const INNER_TOLERANCE_FRACTION: f64 = 1e-3;

/// How the predictor's residual enters the inverse kinematics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CompensationMode {
    /// IK, predict at that command, shift the target, IK again (the paper's Sec. II.C).
    Paper,
    /// IK on the model including the predicted residual (a fixed point of the shift).
    #[default]
    Exact,
}

/// Settings of a [`Compensator`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CompensationParams {
    /// The inverse kinematics of each step.
    pub ik: IkParams,
    /// Most re-linearisations of the residual in exact mode.
    pub max_shifts: usize,
    /// Exact mode stops when the full model (chain, error models and predicted residual) puts
    /// the point within this distance of the target (m).
    pub tolerance: f64,
}

impl Default for CompensationParams {
    fn default() -> Self {
        CompensationParams {
            ik: IkParams {
                position_tolerance: 1e-9,
                ..IkParams::default()
            },
            max_shifts: 20,
            tolerance: 1e-8,
        }
    }
}

/// One compensated target; the joint command is in [`Compensator::q`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Compensation {
    /// Where the model without the residual puts the point at the command: the target minus
    /// the predicted residual the command was solved for (m, base frame). The target itself,
    /// within the IK tolerance, without a predictor.
    pub corrected_target: Vector3<f64>,
    /// The residual predicted at the command (m, base frame); zero without a predictor.
    pub residual: Vector3<f64>,
    /// The last inverse kinematics solve.
    pub ik: IkReport,
    /// Solves after the first, each with the residual predicted at the previous command (0
    /// without a predictor, 1 in paper mode).
    pub shifts: usize,
    /// Distance from the target of the point the full model (with the predicted residual)
    /// gives at the command (m); within the tolerance once exact mode converged.
    pub mismatch: f64,
}

/// Reusable buffers and the model to compensate with; nothing is allocated per target after
/// the first one.
#[derive(Debug)]
pub struct Compensator<'a> {
    robot: &'a Robot,
    predictor: Option<&'a dyn FittedPredictor>,
    /// Rotation from the predictor's frame to the base frame.
    base_from_predictor: UnitQuaternion<f64>,
    params: CompensationParams,
    ik: IkWorkspace,
    /// The residual linearised at the current command (base frame).
    offset: LinearOffset,
    out: [f64; 3],
    /// What the predictor takes: the command, then the tool's position for a predictor
    /// fitted on several points ([`predictor_input_into`]).
    input: Vec<f64>,
    /// Row-major `3 × inputs` derivative of the residual (predictor's frame).
    derivative: Vec<f64>,
    scratch: Vec<f64>,
}

impl<'a> Compensator<'a> {
    /// A compensator for `robot` and, optionally, a residual predictor fitted on it (joint
    /// values in, three residual components out, in the base frame as
    /// [`fit_residual_predictor`](crate::algorithms::evaluate::fit_residual_predictor) fits them).
    pub fn new(
        robot: &'a Robot,
        predictor: Option<&'a dyn FittedPredictor>,
        params: CompensationParams,
    ) -> Result<Self> {
        Self::with_frame(robot, predictor, PredictorFrame::Base, params)
    }

    /// [`new`](Self::new) for a predictor whose outputs are in `frame`.
    fn with_frame(
        robot: &'a Robot,
        predictor: Option<&'a dyn FittedPredictor>,
        frame: PredictorFrame,
        params: CompensationParams,
    ) -> Result<Self> {
        let nq = robot.tree().nq();
        let n_inputs = predictor.map_or(nq, |p| p.n_inputs());
        if let Some(p) = predictor.filter(|p| !(p.n_inputs() == nq || p.n_inputs() == nq + 3) || p.n_outputs() != 3) {
            return Err(Error::InvalidArgument {
                what: "fitted predictor".into(),
                reason: format!(
                    "takes {} inputs and gives {} outputs; compensating `{}` needs {nq} joint values (and the point's position, 3) in and a position residual (3) out",
                    p.n_inputs(),
                    p.n_outputs(),
                    robot.name()
                ),
            });
        }
        let mut ik = IkWorkspace::new(robot);
        ik.lock(&tool_chain(robot).iter().map(|moving| !moving).collect::<Vec<_>>())?;
        Ok(Compensator {
            robot,
            predictor,
            base_from_predictor: match frame {
                PredictorFrame::Base => UnitQuaternion::identity(),
                PredictorFrame::Measurement => robot.t_meas_base().rotation.inverse(),
            },
            params,
            ik,
            offset: LinearOffset::zeros(robot.tree().nq()),
            out: [0.0; 3],
            input: {
                let mut input = Vec::with_capacity(n_inputs);
                predictor_input_into(robot, n_inputs, &vec![0.0; nq], robot.tool(), &mut input);
                input
            },
            derivative: vec![0.0; 3 * n_inputs],
            scratch: Vec::new(),
        })
    }

    /// The robot's own fitted predictor, if its file carries one.
    pub fn for_model(robot: &'a Robot, params: CompensationParams) -> Result<Self> {
        Self::with_frame(robot, robot.predictor(), robot.predictor_frame(), params)
    }

    /// The joint command of the last [`compensate`](Compensator::compensate).
    pub fn q(&self) -> &[f64] {
        self.ik.q()
    }

    /// Keeps the coordinates flagged in `locked` (one flag per coordinate) at their start
    /// values, besides those that do not move the tool, which stay locked.
    pub fn lock(&mut self, locked: &[bool]) -> Result<()> {
        let chain = tool_chain(self.robot);
        let nq = chain.len();
        if locked.len() != nq {
            return Err(Error::Dimension {
                what: "locked joints".into(),
                expected: nq,
                got: locked.len(),
            });
        }
        let all: Vec<bool> = locked.iter().zip(&chain).map(|(l, moving)| *l || !moving).collect();
        self.ik.lock(&all)
    }

    /// Per coordinate, whether compensation keeps it at its start value.
    pub fn locked(&self) -> &[bool] {
        self.ik.locked()
    }

    /// Compensates the targets that follow under the sensors' `readings` (the robot's tilt
    /// now), as a measured row's readings turn and load the model.
    pub fn set_sensors(&mut self, readings: SensorReadings) {
        self.params.ik.sensors = readings;
    }

    /// Whether a predictor takes part.
    pub fn has_predictor(&self) -> bool {
        self.predictor.is_some()
    }

    /// The joint command that puts the tool on `target` (m, base frame), starting from `q0`.
    pub fn compensate(
        &mut self,
        target: &Vector3<f64>,
        q0: &[f64],
        mode: CompensationMode,
    ) -> std::result::Result<Compensation, IkError> {
        self.compensate_target(&IkTarget::Position(*target), q0, mode)
    }

    /// The joint command that puts the tool on `target` (base frame), starting from `q0`: a
    /// position, or a pose whose orientation the tool then keeps. The predictor corrects the
    /// position only (it learns position residuals); the orientation is the model's.
    pub fn compensate_target(
        &mut self,
        target: &IkTarget,
        q0: &[f64],
        mode: CompensationMode,
    ) -> std::result::Result<Compensation, IkError> {
        let position = match target {
            IkTarget::Position(p) => *p,
            IkTarget::Pose(t) => t.translation.vector,
        };
        // With a predictor the first solve only has to come near: the solves after it, from
        // its result, set the final accuracy. Without one it is the answer.
        let first_tolerance = match self.predictor {
            Some(_) => self.params.ik.position_tolerance.max(FIRST_SOLVE_TOLERANCE),
            None => self.params.ik.position_tolerance,
        };
        let mut report = solve(
            self.robot,
            &self.params.ik,
            &mut self.ik,
            target,
            None,
            Start::Given(q0),
            first_tolerance,
        )?;
        let Some(predictor) = self.predictor else {
            return Ok(Compensation {
                corrected_target: self.ik.robot.frames.point[self.robot.tool()].translation.vector,
                residual: Vector3::zeros(),
                ik: report,
                shifts: 0,
                mismatch: report.position_error,
            });
        };
        let max_shifts = match mode {
            CompensationMode::Paper => 1,
            CompensationMode::Exact => self.params.max_shifts,
        };
        let mut shifts = 0;
        loop {
            let residual = self.linearise(predictor, mode, shifts == 0);
            let at = self.ik.robot.frames.point[self.robot.tool()].translation.vector;
            let mismatch = (at + residual - position).norm();
            if shifts == max_shifts || (mode == CompensationMode::Exact && mismatch <= self.params.tolerance) {
                return Ok(Compensation {
                    corrected_target: at,
                    residual,
                    ik: report,
                    shifts,
                    mismatch,
                });
            }
            // Inexact Newton: each solve only has to beat the next chord step's own error,
            // a few thousandths of this mismatch; the final accuracy is checked above on the
            // full model, never taken from the solve.
            let tolerance = self
                .params
                .ik
                .position_tolerance
                .max(INNER_TOLERANCE_FRACTION * mismatch);
            report = solve(
                self.robot,
                &self.params.ik,
                &mut self.ik,
                target,
                Some(&self.offset),
                Start::Previous,
                tolerance,
            )?;
            shifts += 1;
        }
    }

    /// Predictive standard deviation of the residual at the last command (m, per axis of the
    /// predictor's frame), for predictors that have one.
    pub fn residual_std(&mut self) -> Option<Vector3<f64>> {
        let nq = self.ik.q().len();
        self.input[..nq].copy_from_slice(self.ik.q());
        self.std_of_input()
    }

    /// As [`residual_std`](Self::residual_std), at the joint values `q` (the closest
    /// configuration to a target out of reach).
    pub fn residual_std_at(&mut self, q: &[f64]) -> Option<Vector3<f64>> {
        self.input[..q.len()].copy_from_slice(q);
        self.std_of_input()
    }

    fn std_of_input(&mut self) -> Option<Vector3<f64>> {
        let p = self.predictor?;
        p.predict_std_into(&self.input, &mut self.out, &mut self.scratch)
            .then(|| Vector3::from(self.out))
    }

    /// Predicts the residual at the current command into `self.offset` (rotated into the base
    /// frame) and returns its value. In exact mode the first call also takes the predictor's
    /// derivative, when it has one, and later calls keep it: the derivative changes little over
    /// the few millimetres the command still moves, so the chord method converges nearly as fast
    /// as Newton's while predicting only the value. Paper mode holds the residual constant.
    fn linearise(&mut self, predictor: &dyn FittedPredictor, mode: CompensationMode, first: bool) -> Vector3<f64> {
        let q = self.ik.q();
        let nq = q.len();
        self.input[..nq].copy_from_slice(q);
        let rotation: Matrix3<f64> = self.base_from_predictor.to_rotation_matrix().into_inner();
        if first {
            let derivative = mode == CompensationMode::Exact
                && predictor.predict_jacobian_into(&self.input, &mut self.out, &mut self.derivative, &mut self.scratch);
            if !derivative {
                self.derivative.fill(0.0);
                predictor.predict_into(&self.input, &mut self.out, &mut self.scratch);
            }
            let (d, ni) = (&self.derivative, self.input.len());
            for c in 0..nq {
                let column = rotation * Vector3::new(d[c], d[ni + c], d[2 * ni + c]);
                self.offset.jacobian.set_column(c, &column);
            }
        } else {
            predictor.predict_into(&self.input, &mut self.out, &mut self.scratch);
        }
        self.offset.value = rotation * Vector3::from(self.out);
        self.offset.q_ref.copy_from_slice(q);
        self.offset.value
    }
}

/// IK of `robot`'s tool onto `target` with the model plus `offset`, from `start`, to
/// `position_tolerance` (the other settings from `params`).
fn solve(
    robot: &Robot,
    params: &IkParams,
    ik: &mut IkWorkspace,
    target: &IkTarget,
    offset: Option<&LinearOffset>,
    start: Start<'_>,
    position_tolerance: f64,
) -> std::result::Result<IkReport, IkError> {
    let params = IkParams {
        position_tolerance,
        ..*params
    };
    solve_from(robot, robot.tool(), target, offset, start, &params, ik)
}

/// The middle of the joint limits (zero for unlimited joints), a start that makes each
/// command independent of the targets before it.
pub fn mid_range(robot: &Robot) -> Vec<f64> {
    robot
        .tree()
        .coordinate_limits()
        .iter()
        .map(|l| l.map_or(0.0, |l| 0.5 * (l.lower + l.upper)))
        .collect()
}

/// Per coordinate, whether it moves the tool: the joints compensation may change.
pub fn tool_chain(robot: &Robot) -> Vec<bool> {
    robot
        .tree()
        .coordinates_moving(&[robot.tree().points()[robot.tool()].body])
}

/// Where compensation starts when no configuration is given: the joints that move the tool
/// at the middle of their limits ([`mid_range`]), every other joint where a measurement file
/// holds it when it has no column for it (the robot file's `hold`, else 0, else the middle of
/// the limits).
pub fn default_start(robot: &Robot) -> Vec<f64> {
    robot
        .csv_layout()
        .hold
        .iter()
        .zip(mid_range(robot))
        .zip(tool_chain(robot))
        .map(|((held, mid), moving)| if moving { mid } else { held.unwrap_or(mid) })
        .collect()
}
