//! The ANN paper's Sec. 4 on the industrial twin: geometric identification with POE and DH on 80
//! points chosen from a 2000-point QRS pool, then an ANN for what joint stiffness and payload
//! leave, trained on 500 pool points near a U-shaped task trajectory or on 500 arbitrary ones,
//! from a QRS or a pseudo-random pool; tested at 50 targets along the trajectory.

use armcomp_core::calibrate::{CalibrationParams, calibrate};
use armcomp_core::compensate::CompensationMode;
use armcomp_core::evaluate::fit_residual_predictor;
use armcomp_core::measurement::Sample;
use armcomp_core::plan::trajectory_similar;
use armcomp_core::sampling::{Sampler, configurations};
use armcomp_core::simulate::{SimulateParams, simulate};
use armcomp_core::{Result, Robot};
use armcomp_learn::MlpSpec;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::{PaperValue, Row, Table, TestBench, timed};
use crate::twins::Twin;

/// Sizes of a run.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Config {
    /// Seed of everything random.
    pub seed: u64,
    /// Tracker noise per axis (mm).
    pub noise_mm: f64,
    /// Candidate pool size (the paper: 2000).
    pub pool: usize,
    /// Points for geometric identification (80).
    pub identification: usize,
    /// ANN training points (500).
    pub training: usize,
    /// Test targets along the trajectory (50).
    pub targets: usize,
}

impl Config {
    /// The paper's sizes.
    pub fn paper(seed: u64) -> Self {
        Config {
            seed,
            noise_mm: 0.05,
            pool: 2000,
            identification: 80,
            training: 500,
            targets: 50,
        }
    }
}

fn twin(name: &str) -> Result<Robot> {
    Twin::get(name)
        .ok_or_else(|| armcomp_core::Error::Input(format!("no built-in robot `{name}`")))?
        .robot()
}

/// A U-shaped task in joint space: down, across, up (configurations in task order).
fn u_trajectory(n: usize) -> Vec<Vec<f64>> {
    let way: [[f64; 6]; 4] = [
        [-40.0, -60.0, 150.0, 0.0, 30.0, 0.0],
        [-30.0, -30.0, 120.0, 0.0, 0.0, 0.0],
        [30.0, -30.0, 120.0, 0.0, 0.0, 0.0],
        [40.0, -60.0, 150.0, 0.0, 30.0, 0.0],
    ];
    (0..n)
        .map(|i| {
            let s = i as f64 / (n - 1).max(1) as f64 * 3.0;
            let k = (s.floor() as usize).min(2);
            let t = s - k as f64;
            (0..6)
                .map(|j| (way[k][j] * (1.0 - t) + way[k + 1][j] * t).to_radians())
                .collect()
        })
        .collect()
}

fn tool_positions(robot: &Robot, poses: &[Vec<f64>]) -> Result<Vec<nalgebra::Vector3<f64>>> {
    poses
        .iter()
        .map(|q| Ok(robot.forward(q)?.point[robot.tool()].translation.vector))
        .collect()
}

/// Runs the protocol and returns the table.
pub fn run(config: &Config) -> Result<Table> {
    let truth = twin("industrial-truth")?;
    let poe = twin("industrial-poe")?;
    let dh = twin("industrial-dh")?;
    let mut rng = StdRng::seed_from_u64(config.seed);
    let noise = |seed: u64| SimulateParams {
        noise_std: config.noise_mm * 1e-3,
        seed,
    };
    let qrs = configurations(poe.tree(), Sampler::Sobol, config.pool, rng.random())?;
    let random = configurations(poe.tree(), Sampler::Random, config.pool, rng.random())?;
    // Identification points: the first of the QRS pool, which already spread over the space.
    let ident = simulate(
        &truth,
        &qrs[..config.identification.min(qrs.len())],
        noise(rng.random()),
    )?
    .samples;
    let trajectory = u_trajectory(200);
    let targets = tool_positions(&truth, &u_trajectory(config.targets))?;
    let bench = TestBench {
        truth: &truth,
        targets,
        noise: noise(rng.random()),
    };
    let paper = |mean_mm: f64| {
        Some(PaperValue {
            mean_mm,
            variance_mm2: None,
        })
    };
    let exact = CompensationMode::Exact;
    let params = CalibrationParams {
        identify: vec!["geometry".into(), "markers".into()],
        measurement_std: config.noise_mm * 1e-3,
        ..CalibrationParams::default()
    };
    let mut rows: Vec<Row> = vec![bench.row("before (nominal)", &poe, None, exact, (0, 0.0), paper(5.12))?];
    let (poe_cal, s_poe) = timed(|| calibrate(&poe, &ident, &params, &mut |_| {}));
    let poe_cal = poe_cal?.robot;
    rows.push(bench.row(
        "POE identification",
        &poe_cal,
        None,
        exact,
        (ident.len(), s_poe),
        paper(1.81),
    )?);
    let (dh_cal, s_dh) = timed(|| calibrate(&dh, &ident, &params, &mut |_| {}));
    rows.push(bench.row(
        "DH identification",
        &dh_cal?.robot,
        None,
        exact,
        (ident.len(), s_dh),
        paper(2.27),
    )?);

    // ANN training sets: trajectory-similar or arbitrary picks from a QRS or pseudo-random pool.
    let per_point = 5;
    let points = config.training / per_point;
    let spec = MlpSpec {
        seed: rng.random(),
        ..MlpSpec::default()
    };
    let mut ann_row = |name: &str, pool: &[Vec<f64>], similar: bool, paper_value: f64| -> Result<Row> {
        let picks: Vec<Vec<f64>> = if similar {
            let positions = tool_positions(&poe_cal, pool)?;
            trajectory_similar(&poe_cal, &trajectory, &positions, points, per_point)?
                .iter()
                .map(|&i| pool[i].clone())
                .collect()
        } else {
            pool[pool.len() - config.training.min(pool.len())..].to_vec()
        };
        let data: Vec<Sample> = simulate(&truth, &picks, noise(rng.random()))?.samples;
        let (fitted, s) = timed(|| fit_residual_predictor(&poe_cal, &spec, &data));
        bench.row(
            name,
            &poe_cal,
            Some(fitted?.as_ref()),
            exact,
            (data.len(), s_poe + s),
            paper(paper_value),
        )
    };
    rows.push(ann_row(
        "POE + ANN, trajectory-similar points, QRS pool",
        &qrs,
        true,
        1.23,
    )?);
    rows.push(ann_row("POE + ANN, arbitrary points, QRS pool", &qrs, false, 1.57)?);
    rows.push(ann_row(
        "POE + ANN, trajectory-similar points, random pool",
        &random,
        true,
        1.53,
    )?);
    Ok(Table {
        title: "industrial twin: the ANN paper's Sec. 4".into(),
        setup: format!(
            "{} identification points from a {}-point QRS pool, {} ANN training points, {} targets along a U-shaped trajectory (seed {}); the paper's column is its 3-D mean accuracy",
            config.identification, config.pool, config.training, config.targets, config.seed
        ),
        noise_mm: config.noise_mm,
        noise_mean_abs_z_mm: config.noise_mm * (2.0 / std::f64::consts::PI).sqrt(),
        rows,
    })
}
