//! Compensation latency per target in exact mode: the rock-drill twin's nominal deflection
//! model with a GP fitted on 900 measured poses of its hidden truth.

use std::hint::black_box;
use std::time::Duration;

use armcomp_core::FitControl;
use armcomp_core::algorithms::compensate::{CompensationMode, CompensationParams, Compensator, mid_range};
use armcomp_core::algorithms::evaluate::fit_residual_predictor;
use armcomp_core::algorithms::simulate::{SimulateParams, simulate};
use armcomp_core::model::sampling::{Sampler, configurations};
use armcomp_learn::GpSpec;
use armcomp_repro::twins::Twin;
use criterion::{Criterion, criterion_group, criterion_main};

fn bench(c: &mut Criterion) {
    // Links the built-in plugins, whose registrations the twins' robot files name.
    armcomp_api::registry::plugins();
    let robot = |name: &str| Twin::get(name).expect("built in").robot().expect("twin builds");
    let truth = robot("rock-drill-truth");
    let model = robot("rock-drill-deflection");
    let poses = configurations(truth.tree(), Sampler::Sobol, 900, 1).expect("poses");
    let data = simulate(
        &truth,
        &poses,
        SimulateParams {
            noise_std: 5e-4,
            seed: 2,
        },
    )
    .expect("data");
    let gp =
        fit_residual_predictor(&model, &GpSpec::default(), &data.samples, &FitControl::default()).expect("GP fits");
    let targets: Vec<_> = configurations(truth.tree(), Sampler::Halton, 64, 3)
        .expect("targets")
        .iter()
        .map(|q| {
            truth.forward(q).expect("q in limits").point[truth.tool()]
                .translation
                .vector
        })
        .collect();
    let q0 = mid_range(&model);
    let mut comp = Compensator::new(&model, Some(gp.as_ref()), CompensationParams::default()).expect("sizes match");
    // What a target costs: chord solves after the first model solve, and the final mismatch.
    let mut shifts = std::collections::BTreeMap::new();
    let mut worst: f64 = 0.0;
    for t in &targets {
        let r = comp.compensate(t, &q0, CompensationMode::Exact).expect("reachable");
        *shifts.entry(r.shifts).or_insert(0) += 1;
        worst = worst.max(r.mismatch);
    }
    eprintln!("targets by chord solves (solves: targets): {shifts:?}; largest mismatch {worst:.1e} m");
    let mut i = 0;
    c.bench_function("compensate exact, GP (900 samples), per target", |b| {
        b.iter(|| {
            i = (i + 1) % targets.len();
            let r = comp.compensate(black_box(&targets[i]), &q0, CompensationMode::Exact);
            black_box(r.expect("reachable"));
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(30).measurement_time(Duration::from_secs(3));
    targets = bench
}
criterion_main!(benches);
