//! Sampling and simulation: low discrepancy, determinism, the noise that was asked for.

use std::process::Command;

use armcomp_core::algorithms::simulate::{SimulateParams, simulate};
use armcomp_core::data::measurement::parse_csv;
use armcomp_core::model::sampling::{Sampler, unit_points};

use crate::common::{Scratch, random_configurations, robot, root};

/// Warnock's closed form of the L2-star discrepancy of points in [0, 1)^d.
fn l2_star_discrepancy(points: &[Vec<f64>]) -> f64 {
    let n = points.len() as f64;
    let d = points[0].len() as i32;
    let mut a = 0.0;
    for p in points {
        a += p.iter().map(|x| 1.0 - x * x).product::<f64>();
    }
    let mut b = 0.0;
    for p in points {
        for q in points {
            b += p.iter().zip(q).map(|(x, y)| 1.0 - x.max(*y)).product::<f64>();
        }
    }
    (3f64.powi(-d) - 2f64.powi(1 - d) / n * a + b / (n * n)).sqrt()
}

#[test]
fn quasi_random_sets_have_lower_discrepancy_than_pseudo_random() {
    for (n, d) in [(128, 2), (256, 7)] {
        let random: f64 = (0..5)
            .map(|s| l2_star_discrepancy(&unit_points(Sampler::Random, n, d, s).unwrap()))
            .sum::<f64>()
            / 5.0;
        for s in [Sampler::Sobol, Sampler::Halton] {
            let q = l2_star_discrepancy(&unit_points(s, n, d, 1).unwrap());
            assert!(q < random, "{s:?} n={n} d={d}: {q} is not below pseudo-random {random}");
        }
    }
}

#[test]
fn grid_covers_the_corners_and_stays_in_the_cube() {
    let g = unit_points(Sampler::Grid, 9, 2, 0).unwrap();
    assert_eq!(g.len(), 9);
    assert!(g.contains(&vec![0.0, 0.0]) && g.contains(&vec![1.0, 1.0]) && g.contains(&vec![0.5, 0.5]));
}

#[test]
fn simulated_noise_has_the_requested_spread() {
    let r = robot("industrial-6dof.toml");
    let poses = random_configurations(&r, 2000, 11);
    let clean = simulate(
        &r,
        &poses,
        SimulateParams {
            noise_std: 0.0,
            seed: 1,
        },
    )
    .unwrap();
    let noisy = simulate(
        &r,
        &poses,
        SimulateParams {
            noise_std: 0.5e-3,
            seed: 1,
        },
    )
    .unwrap();
    let d: Vec<f64> = clean
        .samples
        .iter()
        .zip(&noisy.samples)
        .flat_map(|(a, b)| (b.position - a.position).iter().copied().collect::<Vec<_>>())
        .collect();
    let n = d.len() as f64;
    let mean = d.iter().sum::<f64>() / n;
    let std = (d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / (n - 1.0)).sqrt();
    // 6000 draws: the sample std is within ~3% of sigma with overwhelming probability.
    assert!((std - 0.5e-3).abs() < 0.03 * 0.5e-3, "std {std}");
    assert!(mean.abs() < 4.0 * 0.5e-3 / n.sqrt(), "mean {mean}");
    // Without noise, the measurement is exactly the forward kinematics of the tool.
    let f = r.forward(&poses[0]).unwrap();
    assert!((clean.samples[0].position - f.point[r.tool()].translation.vector).norm() < 1e-15);
}

fn simulate_cli(out: &std::path::Path, seed: &str) -> Vec<u8> {
    let status = Command::new(env!("CARGO_BIN_EXE_armcomp"))
        .current_dir(root())
        .args([
            "simulate",
            "--robot",
            "robots/rock-drill.toml",
            "--n",
            "50",
            "--sampler",
            "sobol",
            "--noise-mm",
            "0.3",
            "--seed",
            seed,
            "--out",
        ])
        .arg(out)
        .status()
        .unwrap();
    assert!(status.success());
    std::fs::read(out).unwrap()
}

#[test]
fn simulate_is_byte_identical_for_a_seed_and_reads_back() {
    let s = Scratch::new("simulate");
    let a = simulate_cli(&s.0.join("a.csv"), "5");
    let b = simulate_cli(&s.0.join("b.csv"), "5");
    let c = simulate_cli(&s.0.join("c.csv"), "6");
    assert_eq!(a, b);
    assert_ne!(a, c);
    let r = robot("rock-drill.toml");
    let set = parse_csv(
        std::str::from_utf8(&a).unwrap(),
        std::path::Path::new("a.csv"),
        &armcomp_core::data::measurement::CsvLayout::strict(r.tree(), r.units(), r.tool()),
    )
    .unwrap();
    assert_eq!(set.samples.len(), 50);
    assert!(
        set.warnings.is_empty(),
        "sampled poses stay inside the limits: {:?}",
        set.warnings
    );
    // Refuses to overwrite its input.
    let st = Command::new(env!("CARGO_BIN_EXE_armcomp"))
        .current_dir(root())
        .args([
            "simulate",
            "--robot",
            "robots/rock-drill.toml",
            "--out",
            "robots/rock-drill.toml",
        ])
        .output()
        .unwrap();
    assert!(!st.status.success() && String::from_utf8_lossy(&st.stderr).contains("refusing to overwrite"));
}
