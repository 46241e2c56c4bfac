//! Forward kinematics of 10,000 configurations, the reference for the Python package's
//! `Robot.fk_many` (`python/bench/fk_many.py` times the same robots and batch): the plain loop
//! of `Robot::forward_into` with the point positions copied out, and the batch call
//! `point_positions_many_into` that `fk_many` hands its numpy arrays to.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use armcomp_core::Robot;
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// The batch size the Python timing uses.
const N: usize = 10_000;

/// `N` configurations of `robot`, uniform within ±0.5 of the middle of each joint's range
/// (rad or m, inside the limits), row-major.
fn configurations(robot: &Robot) -> Vec<f64> {
    let mut rng = StdRng::seed_from_u64(1);
    let limits = robot.tree().coordinate_limits();
    (0..N)
        .flat_map(|_| {
            limits
                .iter()
                .map(|l| l.map_or(0.0, |l| 0.5 * (l.lower + l.upper)))
                .collect::<Vec<_>>()
        })
        .map(|mid| mid + rng.random_range(-0.5..0.5) * 0.1)
        .collect()
}

fn bench(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut group = c.benchmark_group("fk_many");
    group.sample_size(20).measurement_time(Duration::from_secs(5));
    group.throughput(Throughput::Elements(N as u64));
    for name in ["talos-left-arm", "industrial-6dof-truth"] {
        let robot = armcomp::read_robot(&root.join("robots").join(format!("{name}.toml"))).expect("robot builds");
        let nq = robot.tree().nq();
        let width = robot.tree().points().len() * 3;
        let qs = configurations(&robot);
        let mut out = vec![0.0; N * width];
        let mut ws = robot.workspace();
        group.bench_function(format!("{name}/loop"), |b| {
            b.iter(|| {
                for (q, o) in qs.chunks_exact(nq).zip(out.chunks_exact_mut(width)) {
                    robot.forward_into(black_box(q), None, &mut ws);
                    for (p, xyz) in ws.frames.point.iter().zip(o.chunks_exact_mut(3)) {
                        xyz.copy_from_slice(p.translation.vector.as_slice());
                    }
                }
                black_box(&out);
            })
        });
        group.bench_function(format!("{name}/point_positions_many_into"), |b| {
            b.iter(|| {
                robot
                    .point_positions_many_into(N, black_box(&qs), &mut out, &mut ws)
                    .expect("sizes match");
                black_box(&out);
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
