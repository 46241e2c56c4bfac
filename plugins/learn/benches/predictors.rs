//! Training time of every predictor at 300 and 900 samples (7 inputs, 3 outputs, the synthetic
//! boom residual of the tests) and prediction latency per query.

use std::hint::black_box;
use std::time::Duration;

use armcomp_core::PredictorSpec;
use armcomp_learn::{GpSpec, GradientMethod, KnnSpec, MlpSpec, RidgeSpec, SsaBpSpec, TrainingParams};
use criterion::{BenchmarkId, Criterion, criterion_group, criterion_main};

#[path = "../tests/common/residual.rs"]
mod residual;

use residual::Data;

/// Every predictor with its default settings (ridge with its quadratic and trigonometric
/// features), plus the MLP trained by Levenberg–Marquardt.
fn specs() -> Vec<(&'static str, Box<dyn PredictorSpec>)> {
    vec![
        ("ssa_bp", Box::new(SsaBpSpec::default())),
        ("mlp_adam", Box::new(MlpSpec::default())),
        (
            "mlp_lm",
            Box::new(MlpSpec {
                training: TrainingParams {
                    method: GradientMethod::LevenbergMarquardt,
                    max_epochs: 100,
                    patience: 10,
                    ..TrainingParams::default()
                },
                ..MlpSpec::default()
            }),
        ),
        ("gp", Box::new(GpSpec::default())),
        (
            "ridge",
            Box::new(RidgeSpec {
                degree: 2,
                trig: true,
                ..RidgeSpec::default()
            }),
        ),
        ("knn", Box::new(KnnSpec::default())),
    ]
}

fn training(c: &mut Criterion) {
    let mut group = c.benchmark_group("train");
    group
        .sample_size(10)
        .warm_up_time(Duration::from_millis(200))
        .measurement_time(Duration::from_secs(3));
    for n in [300, 900] {
        let data = Data::residuals(n, 1);
        for (name, spec) in specs() {
            group.bench_with_input(BenchmarkId::new(name, n), &data, |b, data| {
                b.iter(|| spec.fit(&data.set(7, 3)).expect("fits"))
            });
        }
    }
    group.finish();
}

fn prediction(c: &mut Criterion) {
    let data = Data::residuals(900, 1);
    let queries = Data::residuals(64, 2);
    let mut group = c.benchmark_group("predict_900");
    group.sample_size(30).measurement_time(Duration::from_secs(2));
    for (name, spec) in specs() {
        let model = spec.fit(&data.set(7, 3)).expect("fits");
        let mut out = [0.0; 3];
        let mut scratch = Vec::new();
        let mut q = queries.inputs.chunks(7).cycle();
        group.bench_function(format!("{name}/mean"), |b| {
            b.iter(|| model.predict_into(black_box(q.next().expect("cycle")), &mut out, &mut scratch))
        });
        if model.predict_std_into(&queries.inputs[..7], &mut out, &mut scratch) {
            group.bench_function(format!("{name}/mean_and_std"), |b| {
                b.iter(|| {
                    let x = black_box(q.next().expect("cycle"));
                    model.predict_into(x, &mut out, &mut scratch);
                    model.predict_std_into(x, &mut out, &mut scratch)
                })
            });
        }
    }
    group.finish();
}

criterion_group!(benches, training, prediction);
criterion_main!(benches);
