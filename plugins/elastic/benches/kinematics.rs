//! Per-call cost of forward kinematics (rigid and deformed), the tool Jacobian and IK of a
//! 7-joint rock-drill boom and a 6-axis arm.

use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

use armcomp_core::support::io::InputLimits;
use armcomp_core::{IkParams, IkTarget, IkWorkspace, Robot, RobotFile, solve_ik};
use criterion::{Criterion, criterion_group, criterion_main};
use nalgebra::Matrix6xX;

#[path = "../tests/common/robots.rs"]
mod robots;

fn build(src: &str) -> Robot {
    let _ = armcomp_chains::plugins();
    let _ = armcomp_elastic::plugins();
    let file: RobotFile = toml::from_str(src).expect("bench robot parses");
    Robot::build(file, Path::new("."), InputLimits::default()).expect("bench robot builds")
}

fn mid(r: &Robot) -> Vec<f64> {
    r.tree()
        .coordinate_limits()
        .iter()
        .map(|l| l.map_or(0.0, |l| 0.5 * (l.lower + l.upper)))
        .collect()
}

fn bench_robot(c: &mut Criterion, name: &str, r: &Robot, pose: bool) {
    let q = mid(r);
    let tool = r.tool();
    let mut ws = r.workspace();
    c.bench_function(&format!("{name}/fk_rigid"), |b| {
        b.iter(|| r.tree().forward_into(black_box(&q), &mut ws.rigid))
    });
    c.bench_function(&format!("{name}/fk_deflected"), |b| {
        b.iter(|| r.forward_into(black_box(&q), None, &mut ws))
    });
    let mut jac = Matrix6xX::zeros(q.len());
    r.forward_into(&q, None, &mut ws);
    c.bench_function(&format!("{name}/tool_jacobian"), |b| {
        b.iter(|| r.tree().pose_jacobian_into(black_box(&ws.frames), tool, &mut jac))
    });
    // IK from the middle of the ranges to a target reached by a nearby configuration.
    let goal_q: Vec<f64> = q
        .iter()
        .zip(r.tree().coordinate_limits())
        .map(|(v, l)| {
            let l = l.expect("limits");
            v + 0.1 * (l.upper - l.lower)
        })
        .collect();
    r.forward_into(&goal_q, None, &mut ws);
    let goal = ws.frames.point[tool];
    let target = if pose {
        IkTarget::Pose(goal)
    } else {
        IkTarget::Position(goal.translation.vector)
    };
    let mut ik = IkWorkspace::new(r);
    let opts = IkParams::default();
    let report = solve_ik(r, tool, &target, &q, &opts, &mut ik).expect("reachable");
    eprintln!(
        "{name}: IK in {} iterations, position error {:.1e} m, orientation error {:.1e} rad",
        report.iterations, report.position_error, report.orientation_error
    );
    c.bench_function(&format!("{name}/ik"), |b| {
        b.iter(|| solve_ik(r, tool, black_box(&target), &q, &opts, &mut ik).expect("reachable"))
    });
}

fn benches(c: &mut Criterion) {
    let boom = build(&robots::rock_drill(robots::ROCK_DRILL_MODELS));
    bench_robot(c, "rock_drill_7", &boom, false);
    let rigid = build(&robots::six_axis(""));
    bench_robot(c, "six_axis_rigid", &rigid, true);
    let arm = build(&robots::six_axis(robots::SIX_AXIS_MODELS));
    bench_robot(c, "six_axis", &arm, true);
}

criterion_group! {
    name = group;
    config = Criterion::default().warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(2)).sample_size(30);
    targets = benches
}
criterion_main!(group);
