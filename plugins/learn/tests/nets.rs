//! The networks on the synthetic boom residual, and the sparrow search against random search.

use armcomp_core::PredictorSpec;
use armcomp_learn::{GradientMethod, MlpSpec, SparrowParams, SsaBpSpec, TrainingParams, sparrow_search};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::common::{Data, assert_fits};

#[test]
fn mlp_adam_fits_boom_residual() {
    let (train, test) = (Data::residuals(300, 1), Data::residuals(200, 2));
    let model = MlpSpec::default().fit(&train.set(7, 3)).unwrap();
    assert_fits("mlp adam", model.as_ref(), &test, 0.2);
}

#[test]
fn mlp_levenberg_marquardt_fits_boom_residual() {
    let (train, test) = (Data::residuals(300, 1), Data::residuals(200, 2));
    let spec = MlpSpec {
        hidden: vec![10],
        training: TrainingParams {
            method: GradientMethod::LevenbergMarquardt,
            max_epochs: 100,
            patience: 10,
            ..TrainingParams::default()
        },
        seed: 4,
    };
    let model = spec.fit(&train.set(7, 3)).unwrap();
    assert_fits("mlp lm", model.as_ref(), &test, 0.1);
}

#[test]
fn ssa_bp_fits_boom_residual() {
    let (train, test) = (Data::residuals(300, 1), Data::residuals(200, 2));
    let spec = SsaBpSpec {
        search: SparrowParams {
            iterations: 40,
            ..SparrowParams::default()
        },
        ..SsaBpSpec::default()
    };
    let model = spec.fit(&train.set(7, 3)).unwrap();
    assert_fits("ssa_bp", model.as_ref(), &test, 0.2);
}

/// Best value random search finds with `evaluations` uniform draws in `[-bound, bound]^dim`.
fn random_search(dim: usize, bound: f64, evaluations: usize, seed: u64, f: impl Fn(&[f64]) -> f64) -> f64 {
    let mut rng = StdRng::seed_from_u64(seed);
    let mut x = vec![0.0; dim];
    (0..evaluations)
        .map(|_| {
            x.iter_mut().for_each(|v| *v = rng.random_range(-bound..=bound));
            f(&x)
        })
        .fold(f64::INFINITY, f64::min)
}

/// The sparrow search alone against random search with the same number of evaluations, on a
/// sphere whose minimum is away from the origin (SSA's producers contract towards the origin,
/// so a centred sphere would flatter it) and on the standard Rastrigin function, 10-D, 5 seeds.
#[test]
fn sparrow_search_beats_random_search() {
    let shifted_sphere = |x: &[f64]| x.iter().map(|v| (v - 1.7).powi(2)).sum::<f64>();
    let rastrigin = |x: &[f64]| {
        10.0 * x.len() as f64
            + x.iter()
                .map(|v| v * v - 10.0 * (2.0 * std::f64::consts::PI * v).cos())
                .sum::<f64>()
    };
    let params = SparrowParams {
        bound: 5.12,
        ..SparrowParams::default()
    };
    let functions: [(&str, &dyn Fn(&[f64]) -> f64); 2] = [("shifted sphere", &shifted_sphere), ("rastrigin", &rastrigin)];
    for (name, f) in functions {
        for seed in 0..5 {
            let mut rng = StdRng::seed_from_u64(seed);
            let mut count = 0;
            let report = sparrow_search(10, &params, &mut rng, |x| {
                count += 1;
                f(x)
            })
            .unwrap();
            assert_eq!(count, report.evaluations);
            assert_eq!(count, params.evaluations());
            let random = random_search(10, params.bound, count, seed + 100, f);
            assert!(
                report.fitness < 0.25 * random,
                "{name}, seed {seed}: sparrows {} vs random search {random} ({count} evaluations)",
                report.fitness
            );
        }
    }
}
