//! A calibration stage as a least-squares problem for the shared Levenberg–Marquardt loop
//! ([`crate::support::least_squares`]): the free parameters with their bounds and priors, the fast
//! Jacobian form while it makes progress, the iterations reported to the observer.

use std::ops::ControlFlow;

use nalgebra::{DMatrix, DVector};

use super::{
    CalibrationParams, Decoded, Evaluation, IterationInfo, JacobianForm, ParamGroup, Problem, STALL_ABOVE_NOISE,
    STALL_GAIN, Stage, StageOutcome,
};
use crate::error::Result;
use crate::support::least_squares::{
    ConvergenceParams, LeastSquares, LmIteration, LmParams, LmStop, SmallStep, StallParams, levenberg_marquardt,
};

/// One stage's fit over the parameters `free` of the full vector `stage.theta`.
struct StageFit<'s, 'p> {
    problem: &'s Problem<'p>,
    stage: &'s mut Stage,
    free: &'s [usize],
    /// The priors' centres and standard deviations, and the bounds, of the free parameters.
    centre: Vec<f64>,
    sigma: Vec<f64>,
    lower: Vec<f64>,
    upper: Vec<f64>,
    /// The last point evaluated, kept for the Jacobian if the loop moves there.
    trial: Option<(Vec<f64>, Decoded, Evaluation)>,
    /// Iterations before this stage (one budget over all stages).
    before: usize,
    /// What the deformation's change added to the geometry columns at the fit's first exact
    /// Jacobian ([`Problem::jacobian_parts`]).
    deformation_part: Option<DMatrix<f64>>,
    params: &'s CalibrationParams,
    observer: &'s mut dyn FnMut(&IterationInfo),
}

impl LeastSquares for StageFit<'_, '_> {
    fn n_params(&self) -> usize {
        self.free.len()
    }

    fn n_residuals(&self) -> usize {
        self.problem.n_residuals()
    }

    fn residuals_into(&mut self, x: &[f64], r: &mut DVector<f64>) -> Result<()> {
        let mut theta = self.stage.theta.clone();
        for (&k, &v) in self.free.iter().zip(x) {
            theta[k] = v;
        }
        let (d, e, _) = self.problem.predict(&theta)?;
        *r = self.problem.residuals(&d, &e);
        self.trial = Some((theta, d, e));
        Ok(())
    }

    /// The exact form is computed in full once per fit; later iterations add the deformation
    /// part of that one to the held form, since the models' re-evaluation for every geometry
    /// column is most of a deformed robot's fit.
    fn jacobian_into(&mut self, _x: &[f64], approximate: bool, j: &mut DMatrix<f64>) -> Result<()> {
        let Stage { theta, d, e, .. } = &*self.stage;
        if approximate {
            *j = self
                .problem
                .jacobian(theta, d, e, self.free, JacobianForm::HeldDeformation)?;
            return Ok(());
        }
        *j = match &self.deformation_part {
            Some(part) => self
                .problem
                .jacobian(theta, d, e, self.free, JacobianForm::HeldPlus(part))?,
            None => {
                let (j, part) = self
                    .problem
                    .jacobian_parts(theta, d, e, self.free, JacobianForm::Exact)?;
                self.deformation_part = part;
                j
            }
        };
        self.stage.exact_jacobian = Some((self.free.to_vec(), j.clone()));
        Ok(())
    }

    /// Deformed robots iterate on the fast form while it makes progress, and finish on the
    /// exact one, so the minimum and the convergence test are those of the true model. Error
    /// models that deform nothing and stay so (none of their parameters free) leave the two
    /// forms the same.
    fn has_approximate_jacobian(&self) -> bool {
        let space = self.problem.space;
        self.problem.robot.deforms_at(&self.stage.d.errors)
            || self
                .free
                .iter()
                .any(|&k| matches!(space.params[k].group, ParamGroup::ErrorModel(_)))
    }

    fn bounds(&self) -> Option<(&[f64], &[f64])> {
        Some((&self.lower, &self.upper))
    }

    fn prior(&self) -> Option<(&[f64], &[f64])> {
        Some((&self.centre, &self.sigma))
    }

    fn accept(&mut self, _x: &[f64]) {
        if let Some((theta, d, e)) = self.trial.take() {
            (self.stage.theta, self.stage.d, self.stage.e) = (theta, d, e);
            self.stage.exact_jacobian = None;
        }
    }

    fn iteration(&mut self, it: &LmIteration<'_>) -> ControlFlow<()> {
        let n = self.problem.samples.len();
        // A plane contact gives one row here, its height; a position three.
        let rows = self.problem.position_rows();
        (self.observer)(&IterationInfo {
            iteration: self.before + it.iteration,
            max_iterations: self.params.max_iterations,
            rms: (it.residuals.rows(0, rows).norm_squared() / n as f64).sqrt() * self.params.measurement_std,
            lambda: it.damping,
        });
        ControlFlow::Continue(())
    }
}

impl Problem<'_> {
    /// Levenberg–Marquardt over the parameters `free`, from `stage`, with priors centred at
    /// `theta0`; leaves the best parameters found in `stage`.
    pub(super) fn levenberg_marquardt(
        &self,
        stage: &mut Stage,
        theta0: &[f64],
        free: &[usize],
        params: &CalibrationParams,
        observer: &mut dyn FnMut(&IterationInfo),
    ) -> Result<StageOutcome> {
        let info = |k: usize| &self.space.params[k].info;
        let mut x: Vec<f64> = free.iter().map(|&k| stage.theta[k]).collect();
        let before = stage.iterations;
        // The loop's defaults are calibration's (scaled damping, the exact Jacobian once a step
        // gains less than the noise can tell apart); the budget and tests are the caller's.
        let lm = LmParams {
            max_iterations: params.max_iterations.saturating_sub(before),
            convergence: Some(ConvergenceParams {
                tolerance: params.tolerance,
                min_improvement: params.min_improvement,
                min_step: params.min_step,
            }),
            stall: (params.stall_iterations > 0).then(|| StallParams {
                iterations: params.stall_iterations,
                gain: STALL_GAIN,
                above_cost: 0.5 * STALL_ABOVE_NOISE.powi(2) * self.n_residuals() as f64,
            }),
            cancel: params.cancel.clone(),
            ..LmParams::default()
        };
        let mut fit = StageFit {
            problem: self,
            stage: &mut *stage,
            free,
            centre: free.iter().map(|&k| theta0[k]).collect(),
            sigma: free.iter().map(|&k| info(k).sigma).collect(),
            lower: free.iter().map(|&k| info(k).lower).collect(),
            upper: free.iter().map(|&k| info(k).upper).collect(),
            trial: None,
            before,
            deformation_part: None,
            params,
            observer,
        };
        let report = levenberg_marquardt(&mut fit, &mut x, &lm)?;
        stage.iterations += report.iterations;
        let newton = report.newton_step.unwrap_or(f64::NAN);
        let stop_reason = match report.stop {
            LmStop::Converged(step) => {
                let step = match step {
                    SmallStep::Improvement(improvement) => {
                        format!("the last step improved ½χ² by only {improvement:.2e}")
                    }
                    SmallStep::Moved(moved) => format!(
                        "the last step moved no parameter by more than {:.1}% of its standard deviation",
                        100.0 * moved
                    ),
                };
                format!("{step}, and the Newton step is {newton:.1e} standard deviations")
            }
            LmStop::IterationLimit => format!(
                "iteration limit ({}) reached; the Newton step is {newton:.1e} standard deviations",
                params.max_iterations
            ),
            LmStop::NoDescent if report.converged => {
                format!("no step lowers the cost further; the Newton step is {newton:.1e} standard deviations")
            }
            LmStop::NoDescent => format!(
                "no step lowers the cost, but the Newton step is {newton:.1e} standard deviations (cost {:.3e}): \
                 not a minimum",
                report.cost
            ),
            // The observer cannot stop the loop.
            LmStop::Stopped => "stopped".into(),
            LmStop::Stalled => format!(
                "stopped early: the RMS is over {STALL_ABOVE_NOISE} times what the noise gives and each of the last \
                 {} steps lowered the cost by less than {}%, so the model cannot explain the data (an effect it \
                 lacks, or the noise declared too small); the Newton step is {newton:.1e} standard deviations",
                params.stall_iterations,
                100.0 * STALL_GAIN
            ),
        };
        // A stalled fit has settled as far as its model can: it counts as converged, and its
        // stop reason says why it ended.
        Ok(StageOutcome {
            converged: report.converged || report.stop == LmStop::Stalled,
            stop_reason,
        })
    }
}
