//! Ridge and kNN against exact answers.

use armcomp_core::{PredictorSpec, TrainingSet};
use armcomp_learn::{KnnSpec, KnnWeighting, RidgeSpec};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::common::Data;

/// An affine map with λ = 0 is recovered to rounding, with and without the extra features.
#[test]
fn ridge_recovers_linear_function() {
    let mut rng = StdRng::seed_from_u64(5);
    let (n, d, k) = (60, 4, 3);
    let a: Vec<f64> = (0..k * d).map(|_| rng.random_range(-2.0..2.0)).collect();
    let b = [0.3, -1.0, 2.5];
    let x: Vec<f64> = (0..n * d).map(|_| rng.random_range(-1.0..1.0)).collect();
    let linear = |r: &[f64]| -> Vec<f64> {
        (0..k)
            .map(|c| b[c] + (0..d).map(|j| a[c * d + j] * r[j]).sum::<f64>())
            .collect()
    };
    let y: Vec<f64> = x.chunks(d).flat_map(linear).collect();
    let set = TrainingSet {
        inputs: &x,
        targets: &y,
        n_inputs: d,
        n_outputs: k,
        input_ranges: &[],
    };
    for (degree, trig) in [(1, false), (2, true)] {
        let model = RidgeSpec {
            lambda: 0.0,
            degree,
            trig,
        }
        .fit(&set)
        .unwrap();
        let mut out = [0.0; 3];
        let mut scratch = Vec::new();
        for _ in 0..20 {
            let q: Vec<f64> = (0..d).map(|_| rng.random_range(-1.0..1.0)).collect();
            model.predict_into(&q, &mut out, &mut scratch);
            for (o, e) in out.iter().zip(linear(&q)) {
                assert!((o - e).abs() < 1e-9, "degree {degree}, trig {trig}: {o} vs {e}");
            }
        }
    }
}

/// With k = 1 every training input returns its own target, bit for bit.
#[test]
fn knn_one_neighbour_returns_training_targets() {
    let data = Data::residuals(100, 9);
    for weighting in [KnnWeighting::Uniform, KnnWeighting::InverseDistance] {
        let model = KnnSpec { k: 1, weighting }.fit(&data.set(7, 3)).unwrap();
        let mut out = [0.0; 3];
        let mut scratch = Vec::new();
        for i in 0..100 {
            model.predict_into(&data.inputs[i * 7..(i + 1) * 7], &mut out, &mut scratch);
            assert_eq!(out, data.targets[i * 3..(i + 1) * 3], "row {i}");
        }
    }
}

/// With k = 3 and uniform weights, the prediction is the mean of the three closest rows.
#[test]
fn knn_averages_nearest_rows() {
    let x = [0.0, 1.0, 2.0, 10.0, 11.0];
    let y = [1.0, 2.0, 6.0, 100.0, 200.0];
    let model = KnnSpec {
        k: 3,
        weighting: KnnWeighting::Uniform,
    }
    .fit(&TrainingSet {
        inputs: &x,
        targets: &y,
        n_inputs: 1,
        n_outputs: 1,
        input_ranges: &[],
    })
    .unwrap();
    let mut out = [0.0];
    model.predict_into(&[0.9], &mut out, &mut Vec::new());
    assert_eq!(out[0], 3.0);
}
