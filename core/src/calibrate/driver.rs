//! The calibration driver: checks the inputs, starts (registering the measurement frames),
//! decides what the data can determine, fits in stages with restarts and reweighting, and
//! reports.

use nalgebra::{DMatrix, DVector, Vector3};
use rand::SeedableRng;
use rand::rngs::StdRng;
use rand_distr::{Distribution, StandardNormal};

use super::identifiability::assess;
use super::identifiability::{normal_equations, prior_normal_matrix};
use super::jacobian::to_meas;
use super::jacobian::typical_size;
use super::registration::register_base;
use super::registration::unit_mistake;
use super::robust::gross_errors_by_kind;
use super::robust::{Drift, Loss, Outlier, drift};
use super::robust::{MAX_REWEIGHTS, WEIGHT_TOLERANCE};
use super::space::apply;
use super::space::prior_space;
use super::{
    Assessment, Calibration, CalibrationParams, CalibrationReport, FAR_ABOVE_NOISE, IdentifiabilityReport,
    IterationInfo, JacobianForm, Linearisation, Noise, PRIOR_BOX, ParamGroup, ParamResult, ParameterCovariance,
    ParameterSpace, PredictorCarried, Problem, RESTART_ABOVE_NOISE, RestartMoves, Stage, StageOutcome,
    mixes_fixed_points,
};
use crate::algorithms::evaluate::{AngleStats, ErrorStats, per_station};
use crate::data::measurement::{Sample, SampleKind};
use crate::error::{Error, Result};
use crate::model::param::Quantity;
use crate::robot::Robot;
use crate::robot::robot_file::PredictorFrame;

/// Identifies the parameters chosen by `params.identify` from `samples` (measured positions
/// in the measurement frame). `observer` sees every iteration (for a progress display).
///
/// The fit is staged so that a poor guess of the measurement frame cannot leak into the chain:
/// when the whole base frame is identified it is first registered in closed form (the
/// measured points against the nominal model's), then the measurement frame and markers are
/// fitted alone, and only then everything selected, each stage starting where the last ended.
/// Parameters the data cannot determine are reported and held (see the module documentation);
/// when the iteration limit is reached the best parameters found are kept and the report says
/// it did not converge.
pub fn calibrate(
    robot: &Robot,
    samples: &[Sample],
    params: &CalibrationParams,
    observer: &mut dyn FnMut(&IterationInfo),
) -> Result<Calibration> {
    check_inputs(robot, samples, params)?;
    check_measurement_kinds(robot, samples)?;
    let space = prior_space(robot, params, samples);
    let selected = space.select(robot, &params.identify)?;
    let problem = Problem::new(robot, &space, samples, Noise::of(params));
    let start = problem.starting_point(params, &selected)?;
    let (d, e) = (&start.stage.d, &start.stage.e);
    // Identifiability at the start decides what is held.
    let jac0 = problem.jacobian(&start.theta0, d, e, &selected, JacobianForm::Exact)?;
    let Assessment {
        report: mut identifiability,
        free,
        held,
    } = assess(&space, &jac0, &selected, params.rank_tolerance);
    note_measurement_kinds(robot, &space, &selected, &mut identifiability);
    let held_space = space.held_near(&held, &start.theta0);
    let mut problem = Problem {
        space: &held_space,
        ..problem
    };
    let fit = problem.fit(start.stage, &start.theta0, &free, params, observer)?;
    problem.outcome(
        Fitted {
            start: Start {
                stage: fit.stage,
                ..start
            },
            space: &space,
            selected: &selected,
            free,
            identifiability,
            outcome: fit.outcome,
            restarts_rms_mm: fit.restarts_rms_mm,
        },
        params,
    )
}

/// Refuses what no calibration can start from: no samples, a noise or prior scale that is not
/// positive, an empty entry of what to identify, samples the robot cannot evaluate.
fn check_inputs(robot: &Robot, samples: &[Sample], params: &CalibrationParams) -> Result<()> {
    let invalid = |what: String, reason: String| Err(Error::InvalidArgument { what, reason });
    if samples.is_empty() {
        return invalid("measurements".into(), "calibration needs at least one".into());
    }
    if !(params.measurement_std.is_finite() && params.measurement_std > 0.0) {
        return invalid(
            "measurement noise".into(),
            format!("must be positive, got {} m", params.measurement_std),
        );
    }
    if !(params.orientation_std.is_finite() && params.orientation_std > 0.0) {
        return invalid(
            "orientation noise".into(),
            format!("must be positive, got {} rad", params.orientation_std),
        );
    }
    if let Some(s) = params.fixed_point_std.filter(|s| !(s.is_finite() && *s > 0.0)) {
        return invalid("fixed-point noise".into(), format!("must be positive, got {s} m"));
    }
    if params.identify.iter().any(|w| w.trim().is_empty()) {
        return invalid(
            "what to identify".into(),
            "has an empty entry; name what to identify (base, markers, geometry, offsets, errors, all, an error model \
             type or a parameter pattern such as `j2.*`)"
                .into(),
        );
    }
    if params.prior_scale.is_nan() || params.prior_scale <= 0.0 {
        return invalid(
            "prior scale".into(),
            format!(
                "must be positive (or infinite for no priors), got {}",
                params.prior_scale
            ),
        );
    }
    for (i, s) in samples.iter().enumerate() {
        let what = format!("sample {}", i + 1);
        if s.station >= robot.n_stations() {
            return invalid(
                what,
                format!(
                    "it belongs to station {} but the robot has {} measurement frame(s): the data's `station` column \
                     (or its --data files, one station each) names stations the robot was not given",
                    s.station + 1,
                    robot.n_stations()
                ),
            );
        }
        if let Err(e) = robot.tree().check_q(&s.q) {
            return invalid(what, e.to_string());
        }
        if s.point >= robot.tree().points().len() {
            return invalid(what, format!("point index {} does not exist", s.point));
        }
    }
    Ok(())
}

/// Refuses data with a station whose measured positions are too few to fix its measurement
/// frame: six unknowns need at least three points not in line (or one pose), and a
/// calibration that had to find them from fewer would search a space the data leave flat.
/// For the commands' whole data, not a fold's (a fold may leave a station few rows).
pub fn check_station_rows(robot: &Robot, samples: &[Sample]) -> Result<()> {
    let stations = robot.stations();
    if stations.len() < 2 {
        return Ok(());
    }
    let mut positions = vec![0usize; stations.len()];
    let mut oriented = vec![false; stations.len()];
    for s in samples.iter().filter(|s| s.kind() == SampleKind::Position) {
        positions[s.station] += 1;
        oriented[s.station] |= s.orientation.is_some();
    }
    let thin: Vec<usize> = (0..stations.len())
        .filter(|&k| (1..3).contains(&positions[k]) && !oriented[k])
        .collect();
    let Some(&k) = thin.first() else {
        return Ok(());
    };
    Err(Error::InvalidArgument {
        what: format!("station `{}`", crate::support::text::shown(&stations[k].name)),
        reason: format!(
            "has {} measured position(s), and {} of the {} stations have fewer than three: a station's measurement \
             frame has six unknowns, which need at least three poses not in line at each station (does the \
             `station` column name a set-up, not a row?)",
            positions[k],
            thin.len(),
            stations.len()
        ),
    })
}

/// Where the fit starts, and the model's errors there.
struct Start {
    /// The priors' centre: the robot's values, the measurement frames as registered.
    theta0: Vec<f64>,
    /// The first iterate: `theta0`, or the caller's warm start.
    stage: Stage,
    before: ErrorStats,
    before_orientation: Option<AngleStats>,
    /// Whether every station's frame was registered in closed form.
    registered: bool,
}

/// The fit of the free parameters, however it ended.
struct Fit {
    stage: Stage,
    outcome: StageOutcome,
    /// The RMS (mm) each restart reached.
    restarts_rms_mm: Vec<f64>,
}

/// Everything a finished fit reports from.
struct Fitted<'s> {
    start: Start,
    space: &'s ParameterSpace,
    selected: &'s [usize],
    free: Vec<usize>,
    identifiability: IdentifiabilityReport,
    outcome: StageOutcome,
    restarts_rms_mm: Vec<f64>,
}

impl ParameterSpace {
    /// This space with each of `held` boxed within [`PRIOR_BOX`] prior deviations of `centre`.
    fn held_near(&self, held: &[usize], centre: &[f64]) -> ParameterSpace {
        let mut space = self.clone();
        for &k in held {
            let info = &mut space.params[k].info;
            info.lower = info.lower.max(centre[k] - PRIOR_BOX * info.sigma);
            info.upper = info.upper.min(centre[k] + PRIOR_BOX * info.sigma);
        }
        space
    }
}

impl Problem<'_> {
    /// The priors' centre with each fully identified station registered in closed form, the
    /// first iterate, and the errors before the fit.
    fn starting_point(&self, params: &CalibrationParams, selected: &[usize]) -> Result<Start> {
        let (samples, space) = (self.samples, self.space);
        let mut theta0 = self.start()?;
        let (d0, e0, pred) = self.predict(&theta0)?;
        // A model whose residuals overflow cannot be fitted; say which value to look at.
        if let Some(i) = (0..samples.len()).find(|&i| !(pred[i] - samples[i].position).norm_squared().is_finite()) {
            return Err(Error::InvalidArgument {
                what: "robot model".into(),
                reason: format!(
                    "it puts sample {}'s point at {:?} m, too far for a finite residual; a value in the robot file is \
                     out of range",
                    i + 1,
                    pred[i].as_slice()
                ),
            });
        }
        let before = stats(&self.targets(&d0, &pred), &pred);
        let before_orientation = self.orientation_stats(&d0, &e0);
        // Each station whose whole frame is identified is registered on its own samples.
        let stations: Vec<usize> = (0..space.n_stations)
            .filter(|&k| space.station_params(k).all(|i| selected.contains(&i)))
            .collect();
        // Every station is registered, whatever another's outcome.
        let unregistered = (stations.iter())
            .filter(|&&k| !register_base(space, &mut theta0, k, samples, &pred))
            .count();
        // Fixed points of mixed data start where the registered frame sees the model put them.
        if unregistered < stations.len() {
            self.start_fixed_points(&mut theta0)?;
        }
        let theta = match &params.start {
            Some(start) if start.len() == theta0.len() => start.clone(),
            Some(start) => {
                return Err(Error::Dimension {
                    what: "calibration start".into(),
                    expected: theta0.len(),
                    got: start.len(),
                });
            }
            None => theta0.clone(),
        };
        let (d, e, _) = self.predict(&theta)?;
        Ok(Start {
            theta0,
            stage: Stage {
                theta,
                d,
                e,
                iterations: 0,
                exact_jacobian: None,
            },
            before,
            before_orientation,
            registered: !stations.is_empty() && unregistered == 0,
        })
    }

    /// Fits the `free` parameters from `stage`: the measurement frames and markers first (from
    /// a cold start), then everything; restarts where another minimum is likely; Huber's
    /// reweighting when asked for.
    fn fit(
        &mut self,
        mut stage: Stage,
        theta0: &[f64],
        free: &[usize],
        params: &CalibrationParams,
        observer: &mut dyn FnMut(&IterationInfo),
    ) -> Result<Fit> {
        let frames: Vec<usize> = (free.iter().copied())
            .filter(|&k| {
                matches!(
                    self.space.params[k].group,
                    ParamGroup::Base | ParamGroup::Marker(_) | ParamGroup::FixedPoint(_)
                )
            })
            .collect();
        let mut outcome = StageOutcome {
            converged: free.is_empty(),
            stop_reason: "nothing to identify".into(),
        };
        // A warm start has its frame already: the stage that protects the chain from a poor
        // guess of it would only cost time.
        if !frames.is_empty() && frames.len() < free.len() && params.start.is_none() {
            self.levenberg_marquardt(&mut stage, theta0, &frames, params, observer)?;
        }
        let huber = params.loss == Loss::Huber && self.constraints.is_none() && !free.is_empty();
        // A warm start (the evidence's next round) is near the robust fit already: weighed as
        // there, its fit need not first walk to the least-squares one and back.
        if huber && params.start.is_some() {
            self.weights = self.huber_weights(&stage);
        }
        if !free.is_empty() {
            outcome = self.levenberg_marquardt(&mut stage, theta0, free, params, observer)?;
        }
        let mut fit = Fit {
            stage,
            outcome,
            restarts_rms_mm: Vec::new(),
        };
        self.restart(&mut fit, theta0, free, params, observer)?;
        if huber {
            self.reweight(&mut fit, theta0, free, params, observer)?;
        }
        Ok(fit)
    }

    /// Fits again from random starts around the fit when it may sit in another minimum's
    /// basin, keeping the cheapest.
    fn restart(
        &self,
        fit: &mut Fit,
        theta0: &[f64],
        free: &[usize],
        params: &CalibrationParams,
        observer: &mut dyn FnMut(&IterationInfo),
    ) -> Result<()> {
        let space = self.space;
        let moved = |k: usize| params.restart_moves == RestartMoves::Every || space.params[k].info.multimodal;
        let another_minimum_likely =
            // A stalled fit counts as converged: it is not in another minimum's basin, its model
            // cannot explain the data.
            (params.restart_converged
                || !fit.outcome.converged
                || free.iter().any(|&k| space.params[k].info.multimodal))
                && free.iter().any(|&k| moved(k));
        if free.is_empty() || !another_minimum_likely || self.rms_over_noise(&fit.stage) <= RESTART_ABOVE_NOISE {
            return Ok(());
        }
        let mut best_cost = self.cost(&fit.stage, theta0, free);
        let mut rng = StdRng::seed_from_u64(params.seed);
        for _ in 0..params.restarts {
            let mut start = fit.stage.theta.clone();
            for &k in free {
                // One draw per parameter whether used or not, so that two fits sharing their
                // first parameters (a baseline and a candidate) start from the same geometry.
                let z: f64 = StandardNormal.sample(&mut rng);
                let info = &space.params[k].info;
                let spread = if info.multimodal {
                    typical_size(info)
                } else {
                    info.sigma
                };
                if spread.is_finite() && moved(k) {
                    start[k] = (start[k] + z * spread).clamp(info.lower, info.upper);
                }
            }
            let Ok((d, e, _)) = self.predict(&start) else {
                continue;
            };
            let mut trial = Stage {
                theta: start,
                d,
                e,
                iterations: 0,
                exact_jacobian: None,
            };
            let trial_outcome = self.levenberg_marquardt(&mut trial, theta0, free, params, observer)?;
            fit.restarts_rms_mm
                .push(self.rms_over_noise(&trial) * 3f64.sqrt() * params.measurement_std * 1e3);
            let cost = self.cost(&trial, theta0, free);
            if cost < best_cost {
                (best_cost, fit.stage, fit.outcome) = (cost, trial, trial_outcome);
            }
        }
        Ok(())
    }

    /// Huber's loss by reweighting: each round fits least squares with the weights of where
    /// the last ended, until no weight changes.
    fn reweight(
        &mut self,
        fit: &mut Fit,
        theta0: &[f64],
        free: &[usize],
        params: &CalibrationParams,
        observer: &mut dyn FnMut(&IterationInfo),
    ) -> Result<()> {
        for _ in 0..MAX_REWEIGHTS {
            let weights = self.huber_weights(&fit.stage);
            let change = (weights.iter().enumerate())
                .map(|(i, w)| (w - self.weights.get(i).unwrap_or(&1.0)).abs())
                .fold(0.0, f64::max);
            self.weights = weights;
            fit.stage.exact_jacobian = None;
            if change < WEIGHT_TOLERANCE {
                break;
            }
            fit.outcome = self.levenberg_marquardt(&mut fit.stage, theta0, free, params, observer)?;
        }
        Ok(())
    }

    /// The calibrated robot, its report and the linearisation at the solution.
    fn outcome(&self, fitted: Fitted<'_>, params: &CalibrationParams) -> Result<Calibration> {
        let (robot, samples) = (self.robot, self.samples);
        let Fitted {
            start,
            space,
            selected,
            free,
            mut identifiability,
            outcome,
            restarts_rms_mm,
        } = fitted;
        let downweighted = self.weights.iter().filter(|&&w| w < 1.0).count();
        let Stage {
            theta,
            d,
            e,
            iterations,
            exact_jacobian,
        } = start.stage;
        let pred = to_meas(&d.frames, samples, &e.world);
        let r = self.residuals(&d, &e);
        // The fit's last iteration computed it when its convergence test needed it.
        let j = match exact_jacobian {
            Some((columns, j)) if columns == free => j,
            _ => self.jacobian(&theta, &d, &e, &free, JacobianForm::Exact)?,
        };
        let (condition_number_free, covariance) = covariance(space, &free, &r, &j);
        let std: Vec<f64> = covariance.diagonal().iter().map(|v| v.max(0.0).sqrt()).collect();
        let covariance = ParameterCovariance {
            names: free.iter().map(|&k| space.params[k].info.name.clone()).collect(),
            matrix: covariance,
        };
        identifiability.condition_number_free = condition_number_free;
        let params_out = self.parameter_results(space, selected, &free, &theta, &start.theta0, &std);
        // Measured minus modelled, once for the statistics, the gross errors and the trend.
        let residual_vectors = measured_minus_modelled(&self.targets(&d, &pred), &pred);
        let after = ErrorStats::from_errors(&residual_vectors);
        let (outliers, trend) = self.gross_errors_and_drift(&residual_vectors);
        // The RMS the noise gives: √3 σ in 3-D, σ for a plane's height.
        let chi2: f64 = (residual_vectors.iter().enumerate())
            .map(|(i, e)| (e.norm() / self.position_sigma(i)).powi(2))
            .sum();
        let rms_over_noise = (chi2 / self.position_rows().max(1) as f64).sqrt();
        // Mislabelled units are looked for whatever the fit reached: with enough freedom a fit
        // can shrink the arm onto positions read a thousand times too small.
        let unit_mistake = unit_mistake(self, &start.theta0)?;
        let units_mislabelled = unit_mistake.is_some();
        let mut warnings = fit_warnings(rms_over_noise, &after, params, unit_mistake);
        // A value no real robot has says the model explains the data with the wrong effect.
        warnings.extend(
            (selected.iter())
                .filter(|&&k| free.contains(&k))
                .filter_map(|&k| self.space.params[k].info.implausibility(theta[k])),
        );
        let (calibrated, fitted_predictor) = carry_predictor(robot, apply(robot, space, &theta)?, space, selected)?;
        let linearisation = Linearisation {
            prior_sigma: free.iter().map(|&k| space.params[k].info.sigma).collect(),
            groups: free.iter().map(|&k| space.prior_group(robot, k)).collect(),
            free,
            theta,
            centre: start.theta0,
            noise: params.measurement_std,
            orientation_noise: params.orientation_std,
            fixed_point_noise: mixes_fixed_points(samples).then_some(self.sigma_fixed),
            fixed_point_samples: self.fixed.iter().map(Option::is_some).collect(),
            own_std_samples: (0..samples.len()).map(|i| self.own_std(i).is_some()).collect(),
            position_rows: self.position_rows(),
            position_row_of: (0..samples.len())
                .flat_map(|i| {
                    let plane = self.plane[i].is_some();
                    self.position_range(i)
                        .enumerate()
                        .map(move |(a, _)| (i, (!plane).then_some(a)))
                })
                .collect(),
            distance_rows: self.distances.len(),
            residuals: r,
            jacobian: j,
        };
        Ok(Calibration {
            robot: calibrated,
            linearisation,
            report: CalibrationReport {
                n_samples: samples.len(),
                measured_chain: robot.measured_joint_names(),
                csv_joints: robot.csv_joint_names(),
                registered: start.registered,
                prior_scale: params.use_priors.then_some(params.prior_scale),
                identifiability,
                params: params_out,
                iterations,
                restarts_rms_mm,
                converged: outcome.converged,
                stop_reason: outcome.stop_reason,
                before: start.before,
                per_station: per_station(robot, samples, &residual_vectors),
                after,
                before_orientation: start.before_orientation,
                after_orientation: self.orientation_stats(&d, &e),
                rms_over_noise,
                units_mislabelled,
                implausible: None,
                warnings,
                outliers,
                drift: trend,
                loss: params.loss,
                downweighted,
                fitted_predictor,
                covariance,
            },
        })
    }

    /// Each selected parameter's value and standard deviation (`std` per free parameter).
    fn parameter_results(
        &self,
        space: &ParameterSpace,
        selected: &[usize],
        free: &[usize],
        theta: &[f64],
        theta0: &[f64],
        std: &[f64],
    ) -> Vec<ParamResult> {
        // A fixed point starts where the data put it (no file holds it).
        let mut initial = space.initial();
        for (k, p) in space.params.iter().enumerate() {
            if matches!(p.group, ParamGroup::FixedPoint(_)) {
                initial[k] = theta0[k];
            }
        }
        (selected.iter())
            .map(|&k| {
                // The bounds the fit kept, the prior's box included.
                let info = &self.space.params[k].info;
                let c = free.iter().position(|&f| f == k);
                ParamResult {
                    name: info.name.clone(),
                    quantity: info.quantity,
                    unit: info.quantity.si_unit(),
                    initial: initial[k],
                    value: theta[k],
                    std: c.map_or(0.0, |c| std[c]),
                    fixed: c.is_none(),
                    at_bound: c.is_some() && (theta[k] <= info.lower || theta[k] >= info.upper),
                    plausible: info.is_plausible(theta[k]),
                }
            })
            .collect()
    }

    /// The rows far beyond their kind's noise, and a trend with row order of the measured
    /// positions.
    fn gross_errors_and_drift(&self, residuals: &[Vector3<f64>]) -> (Vec<Outlier>, Option<Drift>) {
        let kinds: Vec<SampleKind> = self.samples.iter().map(Sample::kind).collect();
        // A drift is the tracker's: the measured positions' alone.
        let measured: Vec<Vector3<f64>> = (residuals.iter().zip(&kinds))
            .filter(|(_, k)| **k == SampleKind::Position)
            .map(|(e, _)| *e)
            .collect();
        (gross_errors_by_kind(residuals, &kinds), drift(&measured))
    }
}

/// The condition number of the free parameters' normal equations (priors of `space`
/// included) and their linearised covariance at the solution, scaled by the fit's own
/// residual variance (SI units).
fn covariance(space: &ParameterSpace, free: &[usize], r: &DVector<f64>, j: &DMatrix<f64>) -> (f64, DMatrix<f64>) {
    // `j` holds the free parameters' columns alone.
    let a = prior_normal_matrix(space, j, free, free);
    let dof = (r.len() as f64 - free.len() as f64).max(1.0);
    let s2 = r.norm_squared() / dof;
    let (condition_number_free, inverse) = normal_equations(&a);
    (condition_number_free, inverse * s2)
}

/// What the fit's residuals say against the declared noise.
fn fit_warnings(
    rms_over_noise: f64,
    after: &ErrorStats,
    params: &CalibrationParams,
    unit_mistake: Option<String>,
) -> Vec<String> {
    let mut warnings = Vec::new();
    if rms_over_noise > FAR_ABOVE_NOISE || rms_over_noise.is_nan() {
        warnings.push(format!(
            "the fit's RMS ({:.4} mm) is {rms_over_noise:.0} times what the declared noise ({} mm per axis) gives \
             (√3·σ = {:.4} mm)",
            after.rms_mm,
            params.measurement_std * 1e3,
            3f64.sqrt() * params.measurement_std * 1e3
        ));
        if unit_mistake.is_none() {
            warnings.push(
                "likely causes: wrong units in the data or the robot file, measurements of another point than the \
                 markers (or rows mixed up), the noise declared too small, or an effect the model lacks (the \
                 diagnosis looks for it)"
                    .into(),
            );
        }
    }
    warnings.extend(unit_mistake);
    warnings
}

/// `calibrated` with the fitted predictor of `robot`, the model it was calibrated from, when
/// the fit moved only what a predictor in the base frame does not depend on (the measurement
/// frames, fixed points, planes); else without it. Says which and why.
fn carry_predictor(
    robot: &Robot,
    calibrated: Robot,
    space: &ParameterSpace,
    selected: &[usize],
) -> Result<(Robot, Option<PredictorCarried>)> {
    let Some(fitted) = robot.predictor() else {
        return Ok((calibrated, None));
    };
    let dropped = |reason: &str| {
        Some(PredictorCarried {
            kept: false,
            reason: reason.into(),
        })
    };
    let frames_only = selected.iter().all(|&k| {
        matches!(
            space.params[k].group,
            ParamGroup::Base | ParamGroup::FixedPoint(_) | ParamGroup::Plane(_)
        )
    });
    if !frames_only {
        return Ok((
            calibrated,
            dropped("the fit changed the model whose residuals it predicts; fit the predictor again on the new model"),
        ));
    }
    if robot.predictor_frame() == PredictorFrame::Measurement {
        return Ok((
            calibrated,
            dropped(
                "it predicts residuals in the old measurement frame (a model file from before predictors were \
                 fitted in the base frame); fit the predictor again",
            ),
        ));
    }
    // Fitted predictors are not clonable trait objects; the JSON they are stored as copies them.
    let copy = serde_json::to_value(fitted).and_then(serde_json::from_value);
    let Ok(copy) = copy else {
        return Ok((
            calibrated,
            dropped("it could not be copied into the new model; fit it again"),
        ));
    };
    let mut file = calibrated.to_file();
    file.fitted_predictor = Some(copy);
    file.predictor_frame = Some(PredictorFrame::Base);
    let kept = calibrated.rebuild(file)?;
    Ok((
        kept,
        Some(PredictorCarried {
            kept: true,
            reason: "only the measurement frame moved, and the predictor's residuals are in the robot's base frame"
                .into(),
        }),
    ))
}

/// Each sample's target (see [`Problem::target`]) minus its modelled point.
pub(super) fn measured_minus_modelled(targets: &[Vector3<f64>], predicted: &[Vector3<f64>]) -> Vec<Vector3<f64>> {
    targets.iter().zip(predicted).map(|(t, p)| t - p).collect()
}

fn stats(targets: &[Vector3<f64>], predicted: &[Vector3<f64>]) -> ErrorStats {
    ErrorStats::from_errors(&measured_minus_modelled(targets, predicted))
}

/// Refuses samples without a plane on a robot of plane contacts, plane contacts on a robot of
/// fixed points, samples without a fixed point on a robot of fixed points, known distances
/// naming a fixed point the samples lack, and a frame link on a robot with error models (whose
/// deformation of the frame link's path the Jacobian leaves out). Plane contacts and fixed
/// points may join measured positions (mixed data).
fn check_measurement_kinds(robot: &Robot, samples: &[Sample]) -> Result<()> {
    let planes = robot.measures_planes();
    let wrong = |s: &Sample| {
        if planes {
            s.plane.is_none()
        } else {
            s.plane.is_some() && robot.measures_fixed_points()
        }
    };
    if let Some(i) = samples.iter().position(wrong) {
        return Err(Error::InvalidArgument {
            what: format!("sample {}", i + 1),
            reason: if planes {
                "names no plane, but the robot file measures plane contacts only (`kind = \"plane\"`); for data that \
                 mix measured positions with plane contacts set `kind = \"point\"` (or `\"pose\"`)"
                    .into()
            } else {
                "names a plane, but the robot file measures fixed points (`kind = \"fixed_point\"`)".into()
            },
        });
    }
    if robot.frame_link().is_some() && !robot.error_models().is_empty() {
        return Err(Error::InvalidArgument {
            what: "measurement.frame_link".into(),
            reason: "calibrating in a frame link's frame supports rigid models only; remove the error models or the \
                     frame link"
                .into(),
        });
    }
    // Fixed-point samples may join measured positions (mixed data); a robot of fixed points
    // measures nothing else.
    if robot.measures_fixed_points()
        && let Some(i) = samples.iter().position(|s| s.fixed_point.is_none())
    {
        return Err(Error::InvalidArgument {
            what: format!("sample {}", i + 1),
            reason: "names no fixed point, but the robot file measures fixed points only (`kind = \"fixed_point\"`); \
                     for data that mix measured positions with fixed points set `kind = \"point\"` (or `\"pose\"`)"
                .into(),
        });
    }
    for (i, d) in robot.known_distances().iter().enumerate() {
        for name in &d.between {
            if !samples.iter().any(|s| s.fixed_point.as_deref() == Some(name)) {
                let mut names: Vec<&str> = samples.iter().filter_map(|s| s.fixed_point.as_deref()).collect();
                names.sort_unstable();
                names.dedup();
                return Err(Error::InvalidArgument {
                    what: format!("measurement.distances[{i}]"),
                    reason: format!(
                        "`{name}` is no fixed point of the data; its `fixed_point` column names {}",
                        crate::data::measurement::listed(&names)
                    ),
                });
            }
        }
    }
    Ok(())
}

/// Says in the identifiability report what fixed-point measurements cannot see: the base frame
/// (a robot moved with every fixed point leaves every residual as it was) and, without a known
/// distance, the robot's scale (lengths and fixed points scaled together scale the residuals,
/// which a fit then shrinks).
///
/// For plane contacts: a plane cannot see in-plane translation nor rotation about its normal
/// (the robot shifted along it or turned about its normal touches it the same way), and plane
/// contacts alone cannot see the scale (every length and the planes' heights scaled together
/// leave every contact on its plane).
pub(super) fn note_measurement_kinds(
    robot: &Robot,
    space: &ParameterSpace,
    selected: &[usize],
    report: &mut IdentifiabilityReport,
) {
    let lengths = selected
        .iter()
        .any(|&k| space.params[k].group == ParamGroup::Geometry && space.params[k].info.quantity == Quantity::Length);
    let mut notes = Vec::new();
    if robot.measures_planes() {
        notes.push(
            "a plane cannot see in-plane translation nor rotation about its normal: the robot shifted along a plane or \
             turned about its normal touches it the same way, so base.x … base.yaw keep the robot file's values and \
             each plane is identified by its height and two tilts only"
                .to_string(),
        );
        if robot.plane_constraints().tilts() == 2 {
            notes.push(
                "with flush contact the contact point's offset within its own x-y plane and its turn about its own z \
                 axis move it within the plane, which no contact sees"
                    .into(),
            );
        }
        if lengths {
            notes.push(
                "plane contacts alone cannot see the robot's scale: every length and each plane's height scaled \
                 together leave every contact on its plane, so only the priors hold the lengths' common scale"
                    .into(),
            );
        }
    }
    if robot.measures_fixed_points() {
        notes.push(
            "a fixed-point-only calibration cannot see the base frame: moving the robot together with every fixed \
             point changes no residual, so base.x … base.yaw keep the robot file's values"
                .to_string(),
        );
    }
    if robot.measures_fixed_points() && robot.known_distances().is_empty() && lengths {
        notes.push(
            "without a known distance between two fixed points ([[measurement.distances]]) the robot's scale is not \
             observable: only the priors hold its lengths"
                .into(),
        );
    }
    for note in notes {
        let sep = if report.message.is_empty() { "" } else { "; " };
        report.message.push_str(&format!("{sep}{note}"));
    }
}
