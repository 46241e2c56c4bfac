//! Big inputs: `armcomp validate` of a robot file with 200 000 points and `armcomp evaluate` of
//! 100 000 measurements (reading the CSV, the model's errors, their statistics). Both grew
//! quadratically once (a duplicate check per point, a repeat check per row).

use std::fmt::Write as _;
use std::path::Path;

use armcomp_core::Robot;
use armcomp_core::algorithms::evaluate::{ErrorStats, position_errors};
use armcomp_core::algorithms::simulate::{SimulateParams, simulate};
use armcomp_core::data::measurement::{read_csv, write_csv};
use armcomp_core::model::sampling::{Sampler, configurations};
use armcomp_core::support::io::InputLimits;
use criterion::{Criterion, criterion_group, criterion_main};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn big_inputs(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let mut text = std::fs::read_to_string(root().join("robots/rock-drill.toml")).unwrap();
    for i in 0..200_000 {
        let (x, y, z) = (i % 97, i % 89, i % 83);
        // Writing to a String cannot fail.
        let _ = write!(
            text,
            "\n[[points]]\nname = \"m{i}\"\nlink = \"feed\"\nxyz = [{x}.5, {y}.25, {z}.125]\n"
        );
    }
    let big_robot = dir.path().join("points.toml");
    std::fs::write(&big_robot, text).unwrap();
    let schema = armcomp_api::robot_schema();
    assert_eq!(
        armcomp_api::validate_file(&big_robot, &schema, InputLimits::default()),
        vec![]
    );
    c.bench_function("validate, 200 000 points", |b| {
        b.iter(|| armcomp_api::validate_file(&big_robot, &schema, InputLimits::default()))
    });

    let robot = Robot::from_path(&root().join("robots/rock-drill.toml")).unwrap();
    let poses = configurations(robot.tree(), Sampler::Sobol, 100_000, 1).unwrap();
    let set = simulate(
        &robot,
        &poses,
        SimulateParams {
            noise_std: 5e-5,
            seed: 2,
        },
    )
    .unwrap();
    let data = dir.path().join("data.csv");
    std::fs::write(&data, write_csv(&set, robot.tree(), robot.units())).unwrap();
    let layout = robot.csv_layout();
    c.bench_function("evaluate, 100 000 rows", |b| {
        b.iter(|| {
            let set = read_csv(&data, &layout, InputLimits::default()).unwrap();
            ErrorStats::from_errors(&position_errors(&robot, &set.samples))
        })
    });
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(10);
    targets = big_inputs
}
criterion_main!(benches);
