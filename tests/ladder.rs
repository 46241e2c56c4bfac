//! `armcomp fit`'s choice among levels, prior schemes and predictors, against simulated truths
//! whose best choice is known: a truth whose parameters lie well inside their priors is fitted
//! with tight priors, one far outside them with loose ones, and a clear case gets the same
//! choice on every fold seed.

use armcomp_core::Robot;
use armcomp_core::analysis::ladder::{Ladder, LadderParams, PriorScheme, Rung, climb};
use armcomp_core::calibrate::{CalibrationParams, PriorGroup};

use crate::common::robot;
use crate::evidence::{measure, truth};

fn ladder(nominal: &Robot, samples: &[armcomp_core::data::measurement::Sample], seed: u64) -> Ladder {
    let params = LadderParams {
        seed,
        ..LadderParams::new(CalibrationParams::default(), false)
    };
    climb(nominal, samples, &params, &|_| {}).unwrap()
}

/// Geometry errors of a twentieth of the file's prior standard deviations (tight) and of five
/// times them (loose), 12 rows at 0.05 mm (as many equations as the frame, marker and geometry
/// have parameters, so the priors decide what the rows cannot), on three seeds: a tight truth is never fitted with
/// the file's priors widened or dropped, a loose one never with them at or below the file's;
/// the choice adapts (the evidence) or follows the truth, and the model records it.
#[test]
fn tight_and_loose_truths_get_tight_and_loose_priors() {
    let nominal = robot("industrial-6dof.toml");
    let chain = |scale: f64| {
        move |g: PriorGroup| match g {
            PriorGroup::JointOffsets | PriorGroup::Lengths | PriorGroup::Angles => scale,
            _ => 0.0,
        }
    };
    for seed in 1..=3 {
        for (scale, tight) in [(0.05, true), (5.0, false)] {
            let truth = truth(&nominal, chain(scale), seed);
            let samples = measure(&truth, 12, 0.05e-3, 10 + seed);
            let fit = ladder(&nominal, &samples, seed);
            let chosen = fit.report.chosen;
            let what = format!(
                "seed {seed}, truth at ×{scale}: chose {}: {:?}",
                chosen.label(),
                fit.report
                    .candidates
                    .iter()
                    .filter(|c| c.candidate.rung == chosen.rung && !c.candidate.predictor)
                    .map(|c| (c.label.clone(), c.rms_mm, c.within_noise, c.not_sound.clone()))
                    .collect::<Vec<_>>()
            );
            assert!(chosen.rung >= Rung::JointOffsets, "{what}");
            let wrong = match chosen.prior {
                PriorScheme::Evidence(_) => false,
                PriorScheme::File(s) => (tight && s > 1.0) || (!tight && s <= 1.0),
                PriorScheme::None => tight,
            };
            assert!(!wrong, "{what}");
            let record = fit.robot.built_from().fitted.as_ref().expect("fit writes a record");
            if fit.report.stack.is_empty() {
                assert_eq!(record.prior, chosen.prior.label(), "{what}");
            } else {
                assert!(record.prior.starts_with("stack: "), "{what}: {}", record.prior);
                let total: f64 = fit.report.stack.iter().map(|m| m.weight).sum();
                assert!((total - 1.0).abs() < 1e-9, "{what}: weights sum to {total}");
            }
            assert_eq!(record.use_priors, chosen.prior != PriorScheme::None, "{what}");
        }
    }
}

/// Joint offsets of half a degree and an exact geometry otherwise, 60 rows: the same
/// candidate is chosen on five fold seeds, the joint offsets without a predictor.
#[test]
fn a_clear_case_gets_the_same_choice_on_every_fold_seed() {
    let nominal = robot("industrial-6dof.toml");
    let offsets = |g: PriorGroup| if g == PriorGroup::JointOffsets { 0.5 } else { 0.0 };
    let truth = truth(&nominal, offsets, 4);
    let samples = measure(&truth, 60, 0.05e-3, 5);
    let reports: Vec<_> = (0..5).map(|seed| ladder(&nominal, &samples, seed).report).collect();
    let choices: Vec<_> = reports.iter().map(|r| r.chosen).collect();
    let unsound: Vec<Vec<(String, Option<String>, bool)>> = reports
        .iter()
        .map(|r| {
            r.candidates
                .iter()
                .filter(|c| c.candidate.rung == Rung::JointOffsets && !c.candidate.predictor)
                .map(|c| (c.label.clone(), c.not_sound.clone(), c.within_noise))
                .collect()
        })
        .collect();
    assert!(choices.iter().all(|c| *c == choices[0]), "{choices:?} {unsound:#?}");
    assert_eq!(choices[0].rung, Rung::JointOffsets, "{choices:?}");
}

/// A fit stopped early (three iterations, far from converged), with the noise and priors of
/// the evidence and with the file's priors: the model it writes, read back, gives on the same
/// rows the RMS its report prints (to 1e-6 mm).
#[test]
fn a_fit_that_stops_early_writes_the_model_it_reports() {
    use armcomp_core::algorithms::evaluate::{ErrorStats, position_errors};
    use armcomp_core::calibrate::evidence::{EvidenceParams, calibrate_with_evidence};
    let nominal = robot("industrial-6dof.toml");
    let truth = truth(&nominal, |_| 3.0, 2);
    let samples = measure(&truth, 40, 0.05e-3, 3);
    let dir = tempfile::tempdir().unwrap();
    for estimate_priors in [true, false] {
        let params = CalibrationParams {
            identify: vec!["base".into(), "markers".into(), "geometry".into()],
            max_iterations: 3,
            ..CalibrationParams::default()
        };
        let evidence = EvidenceParams {
            estimate_priors,
            ..EvidenceParams::default()
        };
        let (fit, _) = calibrate_with_evidence(&nominal, &samples, &params, &evidence, &mut |_| {}).unwrap();
        assert!(!fit.report.converged, "the case is meant to stop early");
        let path = dir.path().join("model.toml");
        std::fs::write(&path, fit.robot.to_text_for(&path).unwrap()).unwrap();
        let written = Robot::from_path(&path).unwrap();
        let rms = ErrorStats::from_errors(&position_errors(&written, &samples)).rms_mm;
        assert!(
            (rms - fit.report.after.rms_mm).abs() < 1e-6,
            "priors estimated: {estimate_priors}: the file gives {rms} mm, the report {} mm",
            fit.report.after.rms_mm
        );
    }
}

/// A stop request anywhere in the last part of the cross-validation (from 40 % of the fits
/// on) ends it with the candidates whose folds were all fitted: the choice among them is
/// fitted on all rows and returned, marked interrupted, and its model evaluates to the
/// report's figure (a stop in the last repeat once indexed the unscored draw and panicked).
#[test]
fn a_stop_request_late_in_the_search_keeps_the_best_model_so_far() {
    use armcomp_core::algorithms::evaluate::{ErrorStats, position_errors};
    use armcomp_core::support::cancel::Cancel;
    let nominal = robot("industrial-6dof.toml");
    let truth = truth(&nominal, |_| 3.0, 4);
    let samples = measure(&truth, 24, 0.05e-3, 5);
    for percent in [40, 70, 90, 99] {
        let cancel = Cancel::new();
        let params = LadderParams {
            seed: 1,
            ..LadderParams::new(
                CalibrationParams {
                    cancel: cancel.clone(),
                    ..CalibrationParams::default()
                },
                false,
            )
        };
        // One request, as one Ctrl-C: a second would stop the final fit too.
        let stop = |p: armcomp_core::calibrate::FitsProgress| {
            if 100 * p.done >= percent * p.total && !cancel.is_cancelled() {
                cancel.cancel();
            }
        };
        let fit = climb(&nominal, &samples, &params, &stop).unwrap_or_else(|e| panic!("stopped at {percent} %: {e}"));
        assert!(fit.report.interrupted, "stopped at {percent} %");
        assert!(!fit.report.candidates.is_empty(), "stopped at {percent} %");
        let rms = ErrorStats::from_errors(&position_errors(&fit.robot, &samples)).rms_mm;
        assert!(
            // A stack's model or a predictor's is not the one calibration's report describes.
            (rms - fit.calibration.report.after.rms_mm).abs() < 1e-6
                || fit.report.chosen.predictor
                || !fit.report.stack.is_empty(),
            "stopped at {percent} %: the model gives {rms} mm, the report {} mm",
            fit.calibration.report.after.rms_mm
        );
    }
}

/// A loose geometry truth (×3 the file's priors) on 24 rows, where the priors matter: on three
/// seeds, `diagnose` and `learn` on the model `fit` wrote score the model as `fit` did. The
/// diagnosis' held-out RMS of the model as given, and learn's with the physical model fitted
/// again in every fold, come within 20 % of the chosen candidate's cross-validated RMS (their
/// folds are drawn once, fit's three times, so they agree only within the folds' noise). Both
/// fit again from where `fit` started: from its answer, which has seen every row, a fold's fit
/// would score lower.
#[test]
fn diagnose_and_learn_on_fits_model_reproduce_fits_figure() {
    use armcomp_api::ops::diagnose::calibration_for;
    use armcomp_core::analysis::diagnose::DiagnoseParams;
    use armcomp_core::data::measurement::MeasurementSet;
    let nominal = robot("industrial-6dof.toml");
    for seed in 1..=3 {
        let truth = truth(&nominal, |g| if g == PriorGroup::Frame { 0.0 } else { 3.0 }, seed);
        let samples = measure(&truth, 24, 0.05e-3, 20 + seed);
        let params = LadderParams {
            seed,
            predictor: Some(Box::new(armcomp_learn::GpSpec::default())),
            ..LadderParams::new(CalibrationParams::default(), false)
        };
        let fit = climb(&nominal, &samples, &params, &|_| {}).unwrap();
        let chosen = fit.report.chosen;
        let score = |predictor: bool| {
            let c = (fit.report.candidates.iter())
                .find(|c| c.candidate == armcomp_core::analysis::ladder::Candidate { predictor, ..chosen })
                .unwrap();
            c.rms_mm
        };
        let what = format!("seed {seed}: {}", chosen.label());
        let data = MeasurementSet {
            samples: samples.clone(),
            ..MeasurementSet::default()
        };
        let (calibration, _) = calibration_for(&fit.robot, &data, CalibrationParams::default(), false).unwrap();
        let diagnosis = armcomp_api::ops::diagnose::run(
            &fit.robot,
            &data,
            &DiagnoseParams {
                calibration,
                max_steps: 0,
                seed,
                ..DiagnoseParams::default()
            },
            armcomp_api::ops::diagnose::LearnableBy::None,
            &|_| {},
        )
        .unwrap();
        let diagnosed = diagnosis.report.initial.rms_mm;
        assert!(
            (diagnosed / score(false) - 1.0).abs() < 0.2,
            "{what}: diagnose {diagnosed:.4} mm, fit {:.4} mm",
            score(false)
        );
        let learned = armcomp_api::ops::learn::run(
            &fit.robot,
            fit.robot.to_file(),
            &samples,
            Some(Box::new(armcomp_learn::GpSpec::default())),
            None,
            &armcomp_core::FitControl::default(),
        )
        .unwrap();
        let refitted = learned
            .refitted
            .expect("a model with a fit record is fitted again in the folds");
        for (got, predictor) in [(refitted.model.rms_mm, false), (refitted.with_predictor.rms_mm, true)] {
            assert!(
                (got / score(predictor) - 1.0).abs() < 0.2,
                "{what}: learn {got:.4} mm, fit {:.4} mm (predictor {predictor})",
                score(predictor)
            );
        }
    }
}

/// The expected error is the choice's own cross-validated score, not the best candidate's:
/// over three seeds of 30 rows from a loose truth, its mean ratio to the RMS on 400 fresh rows
/// of the same truth lies within 25 %, and it is never below the best candidate's score.
#[test]
fn the_expected_error_is_close_to_the_error_on_new_rows() {
    use armcomp_core::algorithms::evaluate::{ErrorStats, position_errors};
    let nominal = robot("industrial-6dof.toml");
    let mut ratios = Vec::new();
    for seed in 1..=3 {
        let truth = truth(&nominal, |g| if g == PriorGroup::Frame { 0.0 } else { 2.0 }, seed);
        let samples = measure(&truth, 30, 0.05e-3, 30 + seed);
        let fit = ladder(&nominal, &samples, seed);
        let fresh = measure(&truth, 400, 0.05e-3, 90 + seed);
        let actual = ErrorStats::from_errors(&position_errors(&fit.robot, &fresh)).rms_mm;
        let best = (fit.report.candidates.iter())
            .map(|c| c.rms_mm)
            .fold(f64::INFINITY, f64::min);
        assert!(fit.report.expected_rms_mm >= best - 1e-12, "seed {seed}");
        ratios.push(fit.report.expected_rms_mm / actual);
    }
    let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
    assert!((mean - 1.0).abs() < 0.25, "expected / actual per seed: {ratios:?}");
}
