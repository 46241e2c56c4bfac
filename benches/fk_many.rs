//! Forward kinematics of 10,000 configurations, the reference for the Python package's
//! `Robot.fk_many` (`python/bench/fk_many.py` times the same robots and batch): the plain loop
//! of `Robot::forward_into` with the point positions copied out, and the batch call
//! `point_positions_many_into` that `fk_many` hands its numpy arrays to. Then the rigid
//! kinematics of one point (the UR5's tool, TALOS' left-gripper marker) per configuration:
//! the whole tree's FK, the point's path alone (`PointKinematics`), each with the 6 × n pose
//! Jacobian, one configuration per call and the batches.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use armcomp_core::support::io::InputLimits;
use armcomp_core::{PointKinematics, Robot, TreeWorkspace};
use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use nalgebra::{IsometryMatrix3, Matrix6xX};
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
        let robot = armcomp_api::read_robot(
            &root.join("robots").join(format!("{name}.toml")),
            InputLimits::default(),
        )
        .expect("robot builds");
        let nq = robot.tree().nq();
        let width = robot.tree().points().len() * 3;
        let qs = configurations(&robot);
        let mut out = vec![0.0; N * width];
        let mut ws = robot.workspace();
        let mut batch = robot.batch_workspace();
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
                    .point_positions_many_into(N, black_box(&qs), &mut out, &mut batch)
                    .expect("sizes match");
                black_box(&out);
            })
        });
    }
    group.finish();
}

/// Per configuration, rigid FK and the pose Jacobian of one point: the whole tree against the
/// point's path, a call per configuration against the batches.
fn point(c: &mut Criterion) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut group = c.benchmark_group("point_kinematics");
    group.sample_size(20).measurement_time(Duration::from_secs(3));
    group.throughput(Throughput::Elements(N as u64));
    for (name, path) in [
        ("ur5", "tests/data/urdf/ur5_robot.urdf"),
        ("talos-left-arm", "robots/talos-left-arm.toml"),
    ] {
        let robot = armcomp_api::read_robot(&root.join(path), InputLimits::default()).expect("robot builds");
        let tree = robot.tree();
        let (nq, tool) = (tree.nq(), robot.tool());
        let qs = configurations(&robot);
        let plan = PointKinematics::for_points(tree, &[tool]).expect("the tool exists");
        let mut full = TreeWorkspace::new(tree);
        let mut ws = plan.workspace();
        let mut jacobian = Matrix6xX::zeros(nq);
        group.bench_function(format!("{name}/tree_forward_into"), |b| {
            b.iter(|| {
                for q in qs.chunks_exact(nq) {
                    tree.forward_into(black_box(q), &mut full);
                    black_box(&full.point[tool]);
                }
            })
        });
        group.bench_function(format!("{name}/path_forward_into"), |b| {
            b.iter(|| {
                for q in qs.chunks_exact(nq) {
                    plan.forward_into(black_box(q), &mut ws);
                    black_box(&ws);
                }
            })
        });
        group.bench_function(format!("{name}/tree_forward_and_jacobian"), |b| {
            b.iter(|| {
                for q in qs.chunks_exact(nq) {
                    tree.forward_into(black_box(q), &mut full);
                    tree.pose_jacobian_into(&full, tool, &mut jacobian);
                    black_box(&jacobian);
                }
            })
        });
        group.bench_function(format!("{name}/path_forward_and_jacobian"), |b| {
            b.iter(|| {
                for q in qs.chunks_exact(nq) {
                    plan.forward_into(black_box(q), &mut ws);
                    plan.pose_jacobian_into(&ws, 0, &mut jacobian);
                    black_box(&jacobian);
                }
            })
        });
        let mut many = plan.many_workspace();
        let mut poses = vec![IsometryMatrix3::identity(); N];
        group.bench_function(format!("{name}/forward_many_into"), |b| {
            b.iter(|| {
                plan.forward_many_into(N, black_box(&qs), &mut poses, &mut many)
                    .expect("sizes match");
                black_box(&poses);
            })
        });
        let mut jacobians = vec![0.0; N * 6 * nq];
        group.bench_function(format!("{name}/pose_jacobian_many_into"), |b| {
            b.iter(|| {
                plan.pose_jacobian_many_into(N, black_box(&qs), 0, &mut jacobians, &mut many)
                    .expect("sizes match");
                black_box(&jacobians);
            })
        });
    }
    group.finish();
}

criterion_group!(benches, bench, point);
criterion_main!(benches);
