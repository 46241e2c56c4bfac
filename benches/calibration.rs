//! Time to calibrate the rock-drill boom with its elastic models: 58 parameters (MDH geometry,
//! beam rigidity scales, joint and lateral compliances, base frame, marker) from 900 poses.

use std::hint::black_box;
use std::time::Duration;

use armcomp_core::algorithms::simulate::{SimulateParams, simulate};
use armcomp_core::calibrate::{CalibrationParams, ParameterSpace, calibrate};
use armcomp_core::model::sampling::{Sampler, configurations};
use armcomp_core::robot::robot_file::{Format, SourceFile};
use armcomp_core::support::io::InputLimits;
use armcomp_core::{Robot, RobotFile};
use criterion::{Criterion, criterion_group, criterion_main};

const MODELS: &str = r#"
[[error_models]]
type = "cantilever_deflection"

[[error_models]]
type = "joint_compliance"
compliance = { j1 = 1e-6, j2 = 1e-6, j3 = 1e-6, j4 = 1e-6, j5 = 1e-6, j6 = 1e-6, j7 = 1e-6 }

[[error_models]]
type = "lateral_compliance"
compliance = { j2 = [1e-6, 1e-6], j4 = [1e-6, 1e-6], j5 = [1e-6, 1e-6] }
"#;

fn nominal() -> Robot {
    armcomp_api::registry::plugins();
    let text = format!("{}\n{MODELS}", include_str!("../robots/rock-drill.toml"));
    let src = SourceFile {
        path: "rock-drill.toml".into(),
        text,
        format: Format::Toml,
    };
    let file: RobotFile = src.parse().expect("bench robot parses");
    Robot::from_source(file, &src, InputLimits::default()).expect("bench robot builds")
}

fn bench(c: &mut Criterion) {
    let nominal = nominal();
    let space = ParameterSpace::new(&nominal);
    // A truth 1 mm / 0.1° off in every geometric parameter, with stiffer and softer links.
    let mut theta = space.initial();
    for (k, p) in space.params.iter().enumerate() {
        theta[k] += match p.info.quantity {
            armcomp_core::Quantity::Length => 1e-3 * ((k % 3) as f64 - 1.0),
            armcomp_core::Quantity::Angle => 0.1f64.to_radians() * ((k % 5) as f64 - 2.0) / 2.0,
            armcomp_core::Quantity::Dimensionless => 0.2,
            armcomp_core::Quantity::Compliance => 1e-6,
            _ => 0.0,
        };
    }
    let truth = space.apply(&nominal, &theta).expect("truth builds");
    let poses = configurations(truth.tree(), Sampler::Sobol, 900, 1).expect("poses");
    let data = simulate(
        &truth,
        &poses,
        SimulateParams {
            noise_std: 0.05e-3,
            seed: 2,
        },
    )
    .expect("simulation")
    .samples;
    let params = CalibrationParams {
        identify: vec!["all".into()],
        measurement_std: 0.05e-3,
        ..CalibrationParams::default()
    };
    let report = calibrate(&nominal, &data, &params, &mut |_| {})
        .expect("calibration")
        .report;
    eprintln!(
        "{} parameters, {} poses: {} iterations, converged {}, RMS {:.4} → {:.4} mm ({})",
        report.params.len(),
        data.len(),
        report.iterations,
        report.converged,
        report.before.rms_mm,
        report.after.rms_mm,
        report.stop_reason
    );
    let mut group = c.benchmark_group("calibration");
    group.sample_size(10).measurement_time(Duration::from_secs(20));
    group.bench_function("rock_drill_58_params_900_poses", |b| {
        b.iter(|| calibrate(&nominal, black_box(&data), &params, &mut |_| {}).expect("calibration"))
    });
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
