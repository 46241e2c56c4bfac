//! Compensation: the joint command that puts the tool on a target, through the full model
//! (chain + error models) and, when the model carries one, its fitted residual predictor.
//!
//! The predictor maps joint values to the residual `measured − modelled` (m, measurement
//! frame), so the arm is expected at `FK(q) + e(q)` (with `e` rotated into the base frame).
//! Two ways to invert that:
//! - [`CompensationMode::Paper`], the deflection paper's Sec. II.C two-step: IK on the model,
//!   predict the residual at that command, shift the target by it, IK again;
//! - [`CompensationMode::Exact`]: solves `FK(q) + e(q) = target` itself, by repeating the shift
//!   until the command no longer moves (a fixed point; the residual changes slowly with `q`,
//!   so each repetition shrinks the remaining mismatch by the residual's sensitivity).

use nalgebra::{UnitQuaternion, Vector3};

use crate::error::{Error, Result};
use crate::ik::{IkError, IkOptions, IkReport, IkTarget, IkWorkspace, solve_ik};
use crate::plugin::FittedPredictor;
use crate::robot::Robot;

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
pub struct CompensationOptions {
    /// The inverse kinematics of each step.
    pub ik: IkOptions,
    /// Most target shifts in exact mode.
    pub max_shifts: usize,
    /// Exact mode stops when a shift moves the corrected target by less than this (m).
    pub shift_tolerance: f64,
}

impl Default for CompensationOptions {
    fn default() -> Self {
        CompensationOptions {
            ik: IkOptions {
                position_tolerance: 1e-9,
                ..IkOptions::default()
            },
            max_shifts: 20,
            shift_tolerance: 1e-8,
        }
    }
}

/// One compensated target; the joint command is in [`Compensator::q`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Compensation {
    /// The target given to the model without the residual: the target minus the predicted
    /// residual (m, base frame). Equal to the target without a predictor.
    pub corrected_target: Vector3<f64>,
    /// The predicted residual at the command (m, base frame); zero without a predictor.
    pub residual: Vector3<f64>,
    /// The last inverse kinematics solve.
    pub ik: IkReport,
    /// Target shifts done (0 without a predictor, 1 in paper mode).
    pub shifts: usize,
}

/// Reusable buffers and the model to compensate with; nothing is allocated per target after
/// the first one.
#[derive(Debug)]
pub struct Compensator<'a> {
    robot: &'a Robot,
    predictor: Option<&'a dyn FittedPredictor>,
    /// Rotation from the measurement frame to the base frame (residuals are measured).
    base_from_meas: UnitQuaternion<f64>,
    options: CompensationOptions,
    ik: IkWorkspace,
    start: Vec<f64>,
    out: [f64; 3],
    scratch: Vec<f64>,
}

impl<'a> Compensator<'a> {
    /// A compensator for `robot` and, optionally, a residual predictor fitted on it (joint
    /// values in, three residual components out).
    pub fn new(
        robot: &'a Robot,
        predictor: Option<&'a dyn FittedPredictor>,
        options: CompensationOptions,
    ) -> Result<Self> {
        if let Some(p) = predictor {
            let nq = robot.tree().nq();
            if p.n_inputs() != nq || p.n_outputs() != 3 {
                return Err(Error::Input(format!(
                    "the fitted predictor takes {} inputs and gives {} outputs; compensating `{}` needs {nq} joint values in and a position residual (3) out",
                    p.n_inputs(),
                    p.n_outputs(),
                    robot.file.name
                )));
            }
        }
        Ok(Compensator {
            robot,
            predictor,
            base_from_meas: robot.t_meas_base().rotation.inverse(),
            options,
            ik: IkWorkspace::new(robot),
            start: vec![0.0; robot.tree().nq()],
            out: [0.0; 3],
            scratch: Vec::new(),
        })
    }

    /// The robot's own fitted predictor, if its file carries one.
    pub fn for_model(robot: &'a Robot, options: CompensationOptions) -> Result<Self> {
        Self::new(robot, robot.file.fitted_predictor.as_deref(), options)
    }

    /// The joint command of the last [`compensate`](Compensator::compensate).
    pub fn q(&self) -> &[f64] {
        self.ik.q()
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
        let mut corrected = *target;
        let mut report = self.solve(&corrected, q0)?;
        let mut residual = Vector3::zeros();
        let mut shifts = 0;
        if self.predictor.is_none() {
            return Ok(Compensation {
                corrected_target: corrected,
                residual,
                ik: report,
                shifts,
            });
        }
        let max_shifts = match mode {
            CompensationMode::Paper => 1,
            CompensationMode::Exact => self.options.max_shifts,
        };
        while shifts < max_shifts {
            residual = self.residual_at_command();
            let next = target - residual;
            let moved = (next - corrected).norm();
            corrected = next;
            shifts += 1;
            self.start.copy_from_slice(self.ik.q());
            let start = std::mem::take(&mut self.start);
            let solved = self.solve(&corrected, &start);
            self.start = start;
            report = solved?;
            if moved < self.options.shift_tolerance {
                break;
            }
        }
        Ok(Compensation {
            corrected_target: corrected,
            residual,
            ik: report,
            shifts,
        })
    }

    /// Predictive standard deviation of the residual at the last command (m, measurement
    /// frame), for predictors that have one.
    pub fn residual_std(&mut self) -> Option<Vector3<f64>> {
        let p = self.predictor?;
        p.predict_std_into(self.ik.q(), &mut self.out, &mut self.scratch)
            .then(|| Vector3::from(self.out))
    }

    fn solve(&mut self, target: &Vector3<f64>, q0: &[f64]) -> std::result::Result<IkReport, IkError> {
        let tool = self.robot.tool();
        solve_ik(
            self.robot,
            tool,
            &IkTarget::Position(*target),
            q0,
            &self.options.ik,
            &mut self.ik,
        )
    }

    /// The predicted residual at the current command, rotated into the base frame.
    fn residual_at_command(&mut self) -> Vector3<f64> {
        let Some(p) = self.predictor else {
            return Vector3::zeros();
        };
        p.predict_into(self.ik.q(), &mut self.out, &mut self.scratch);
        self.base_from_meas * Vector3::from(self.out)
    }
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
