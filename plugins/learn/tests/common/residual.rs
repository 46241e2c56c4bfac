//! A synthetic residual like what a deflection model leaves on a 7-joint boom: smooth sums of
//! sines and cosines of the joints, millimetre scale (values in m), on the rock-drill's ranges.

use std::f64::consts::{FRAC_PI_3, FRAC_PI_4, FRAC_PI_6, PI};

use armcomp_core::TrainingSet;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// Joint ranges (rad, m): J1 ±15°, J2 0..30°, J3 0..105 mm, J4 0..60°, J5 -45..0°, J6 ±30°,
/// J7 0..63 mm.
pub const RANGES: [(f64, f64); 7] = [
    (-PI / 12.0, PI / 12.0),
    (0.0, FRAC_PI_6),
    (0.0, 0.105),
    (0.0, FRAC_PI_3),
    (-FRAC_PI_4, 0.0),
    (-FRAC_PI_6, FRAC_PI_6),
    (0.0, 0.063),
];

/// The residual position error (m) at joint values `q`.
pub fn residual(q: &[f64]) -> [f64; 3] {
    [
        0.004 * (3.0 * q[0] + q[3]).sin() + 0.002 * (2.0 * q[4]).cos() + 0.02 * q[2],
        0.003 * (q[1] + 2.0 * q[5]).cos() * (1.0 + 5.0 * q[6]) + 0.002 * (2.0 * q[3]).sin(),
        -0.005 * (q[1] + q[3]).sin() - 0.003 * (q[4] - q[5]).cos() + 0.03 * q[2] * q[1],
    ]
}

/// `n` seeded uniform joint configurations and their residuals, row-major.
pub struct Data {
    pub inputs: Vec<f64>,
    pub targets: Vec<f64>,
}

impl Data {
    pub fn residuals(n: usize, seed: u64) -> Self {
        let mut rng = StdRng::seed_from_u64(seed);
        let mut inputs = Vec::with_capacity(n * 7);
        let mut targets = Vec::with_capacity(n * 3);
        for _ in 0..n {
            let q: Vec<f64> = RANGES.iter().map(|&(lo, hi)| rng.random_range(lo..=hi)).collect();
            targets.extend(residual(&q));
            inputs.extend(q);
        }
        Data { inputs, targets }
    }

    pub fn set(&self, n_inputs: usize, n_outputs: usize) -> TrainingSet<'_> {
        TrainingSet {
            inputs: &self.inputs,
            targets: &self.targets,
            n_inputs,
            n_outputs,
            input_ranges: &[],
        }
    }
}
