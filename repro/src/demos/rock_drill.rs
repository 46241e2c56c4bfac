//! The deflection paper's Sec. III on the rock-drill twin: grid training sets (Sec. III.B),
//! 40 random test targets, the five control groups of Table I, then this project's pipelines.

use armcomp_core::algorithms::compensate::CompensationMode;
use armcomp_core::algorithms::evaluate::fit_residual_predictor;
use armcomp_core::algorithms::simulate::{SimulateParams, simulate};
use armcomp_core::calibrate::{CalibrationParams, calibrate};
use armcomp_core::data::measurement::Sample;
use armcomp_core::plugin::PredictorSpec;
use armcomp_core::robot::robot_file::{Format, SourceFile};
use armcomp_core::support::io::InputLimits;
use armcomp_core::{FitControl, Result, Robot};
use armcomp_learn::{GpSpec, SparrowParams, SsaBpSpec};
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use super::seed_sweep::SeedSweep;
use super::{PaperMetric, PaperValue, Row, Table, TestBench, timed};
use crate::twins::Twin;

/// Table I of the deflection paper, its rows in order: mean |Z| error (mm) and variance (mm²).
pub const PAPER_TABLE_I: [(f64, f64); 6] = [
    (17.7, 223.94),
    (15.39, 215.97),
    (5.32, 52.83),
    (12.66, 214.37),
    (5.79, 57.15),
    (9.98, 180.81),
];

/// Sizes of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct Config {
    /// Seed of everything random (pose subsets, targets, noise, predictors).
    pub seed: u64,
    /// Camera noise per axis (mm).
    pub noise_mm: f64,
    /// The large and the small training set (poses drawn from the Sec. III.B grid).
    pub large: usize,
    /// The small training set, a subset of the large one.
    pub small: usize,
    /// Random test targets.
    pub targets: usize,
    /// Sparrow search of the SSA-BP rows.
    pub search: SparrowParams,
    /// Adam epochs of the SSA-BP refinement.
    pub max_epochs: usize,
    /// Take the training poses group by group in the order they are measured (see
    /// [`collection_order`]), as the paper collected them; false draws them at random from the
    /// whole grid.
    pub grouped: bool,
}

impl Config {
    /// The paper's protocol: 900 and 300 poses collected group by group, 40 targets, SSA-BP at
    /// its default settings.
    pub fn paper(seed: u64) -> Self {
        Config {
            seed,
            noise_mm: 0.5,
            large: 900,
            small: 300,
            targets: 40,
            search: SparrowParams::default(),
            max_epochs: 1000,
            grouped: true,
        }
    }
}

/// The Sec. III.B grid: three values of each revolute joint, six combinations of the two
/// prismatic joints (deg and mm as the paper gives them), 3⁵ · 6 = 1458 poses.
pub fn paper_grid() -> Vec<Vec<f64>> {
    let r = |v: f64| v.to_radians();
    let j1 = [-15.0, 0.0, 15.0];
    let j2 = [0.0, 15.0, 30.0];
    let j4 = [0.0, 30.0, 60.0];
    let j5 = [-45.0, -25.0, 0.0];
    let j6 = [-30.0, 0.0, 30.0];
    let prismatic = [
        (0.0, 0.0),
        (0.0, 63.0),
        (60.0, 10.0),
        (53.0, 63.0),
        (104.0, 18.0),
        (105.0, 63.0),
    ];
    let mut poses = Vec::with_capacity(1458);
    for a in j1 {
        for b in j2 {
            for d in j4 {
                for e in j5 {
                    for f in j6 {
                        for (c, g) in prismatic {
                            poses.push(vec![r(a), r(b), c * 1e-3, r(d), r(e), r(f), g * 1e-3]);
                        }
                    }
                }
            }
        }
    }
    poses
}

/// Positions of the two prismatic (telescopic) joints, j3 and j7, in the grid's poses.
const TELESCOPES: [usize; 2] = [2, 6];

/// The grid in the order it is measured: group by group, a group being one setting of the two
/// prismatic joints with every revolute combination (Sec. III.B collects its training set in
/// groups); groups and poses within a group in a seeded random order. A training set cut from
/// the front then holds few extensions of the telescopic joints, and the networks extrapolate
/// to the others, as the paper's 300-pose rows suggest theirs had to.
pub fn collection_order(grid: Vec<Vec<f64>>, rng: &mut StdRng) -> Vec<Vec<f64>> {
    let mut groups: Vec<Vec<Vec<f64>>> = Vec::new();
    for q in grid {
        match groups.iter_mut().find(|g| TELESCOPES.iter().all(|&k| g[0][k] == q[k])) {
            Some(g) => g.push(q),
            None => groups.push(vec![q]),
        }
    }
    groups.shuffle(rng);
    groups
        .into_iter()
        .flat_map(|mut g| {
            g.shuffle(rng);
            g
        })
        .collect()
}

/// The model this project calibrates: the nominal deflection model plus compliances of the
/// loaded joints and the angle scales of the servo-driven revolute joints, all of them
/// identified.
fn elastic_start() -> Result<Robot> {
    let deflection = Twin::get("rock-drill-deflection").expect("built in");
    let src = SourceFile {
        path: deflection.path.into(),
        text: format!(
            "{}\n[[error_models]]\ntype = \"joint_compliance\"\ncompliance = {{ j2 = 1e-5, j3 = 1e-6, j5 = 1e-5 }}\n\n[[error_models]]\ntype = \"transmission_scale\"\nscale = {{ j1 = 0.0, j2 = 0.0, j4 = 0.0, j5 = 0.0, j6 = 0.0 }}\n",
            deflection.text
        ),
        format: Format::Toml,
    };
    Robot::from_source(src.parse()?, &src, InputLimits::default())
}

fn ssa_bp(config: &Config, seed: u64) -> SsaBpSpec {
    let mut spec = SsaBpSpec {
        search: config.search.clone(),
        seed,
        ..SsaBpSpec::default()
    };
    spec.refine.max_epochs = config.max_epochs;
    spec
}

/// Runs the protocol on the built-in truth and returns the table (rows in the paper's order,
/// then this project's).
pub fn run(config: &Config) -> Result<Table> {
    run_on(&Twin::build("rock-drill-truth")?, config)
}

/// The protocol over the `n` seeds from `config.seed` on, several seeds at a time (each run is
/// independent, so the tables are those of the seeds run one by one); `on_done` hears each seed
/// as it finishes.
pub fn sweep(config: &Config, n: usize, on_done: &(dyn Fn(u64) + Sync)) -> Result<SeedSweep> {
    if n == 0 {
        return Err(armcomp_core::Error::InvalidArgument {
            what: "seeds".into(),
            reason: "expected at least 1".into(),
        });
    }
    let seeds: Vec<u64> = (0..n as u64).map(|k| config.seed.wrapping_add(k)).collect();
    let tables = seeds
        .par_iter()
        .map(|&seed| {
            let table = run(&Config { seed, ..config.clone() });
            on_done(seed);
            table
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(SeedSweep::new(seeds, tables, |t| claims(t, config)))
}

/// The claims of docs/reproductions/deflection-ssa-bp.md on one table: the paper's findings first (its order of the rows that
/// have a paper value), then this project's targets.
pub fn claims(table: &Table, config: &Config) -> Vec<(String, bool)> {
    let (large, small) = (config.large, config.small);
    let z = |name: String| table.row(&name).map_or(f64::NAN, |r| r.mean_abs_z_mm);
    let ssa = |n: usize| z(format!("SSA-BP only, {n} poses"));
    let hybrid = |n: usize| z(format!("deflection + SSA-BP, {n} poses"));
    let best = table
        .rows
        .iter()
        .filter(|r| r.name.starts_with("calibrated") && r.training_poses == small)
        .map(|r| r.mean_abs_z_mm)
        .fold(f64::INFINITY, f64::min);
    vec![
        (
            "the nominal deflection model lowers the error".into(),
            z("deflection only".into()) < z("original".into()),
        ),
        (
            format!("every learned row beats the deflection model; {large} poses beat {small}"),
            ssa(small).max(hybrid(small)) < z("deflection only".into())
                && ssa(large) < ssa(small)
                && hybrid(large) < hybrid(small),
        ),
        (
            format!("the hybrid beats SSA-BP alone with {small} poses"),
            hybrid(small) < ssa(small),
        ),
        (
            format!("the hybrid helps most with few poses (gain at {small} > gain at {large})"),
            ssa(small) - hybrid(small) > ssa(large) - hybrid(large),
        ),
        (
            format!("best pipeline with {small} poses within twice the noise's mean |z|"),
            best <= 2.0 * table.noise_mean_abs_z_mm,
        ),
        (
            format!("best pipeline with {small} poses beats the paper's pipelines with {large}"),
            best < ssa(large).min(hybrid(large)),
        ),
    ]
}

/// Runs the protocol with `truth` as the boom that is measured and commanded.
pub fn run_on(truth: &Robot, config: &Config) -> Result<Table> {
    let rigid = Twin::build("rock-drill")?;
    let deflection = Twin::build("rock-drill-deflection")?;
    let mut rng = StdRng::seed_from_u64(config.seed);
    let mut grid = paper_grid();
    if config.grouped {
        grid = collection_order(grid, &mut rng);
    } else {
        grid.shuffle(&mut rng);
    }
    grid.truncate(config.large.min(grid.len()));
    let noise = |seed: u64| SimulateParams {
        noise_std: config.noise_mm * 1e-3,
        seed,
    };
    let large = simulate(truth, &grid, noise(rng.random()))?.samples;
    let small: Vec<Sample> = large[..config.small.min(large.len())].to_vec();

    // Random targets the truth can reach: its tool at random joint values.
    let lims = truth.tree().coordinate_limits().to_vec();
    let targets = (0..config.targets)
        .map(|_| {
            let q: Vec<f64> = lims
                .iter()
                .map(|l| l.map_or(0.0, |l| rng.random_range(l.lower..=l.upper)))
                .collect();
            Ok(truth.forward(&q)?.point[truth.tool()].translation.vector)
        })
        .collect::<Result<Vec<_>>>()?;
    let bench = TestBench {
        truth,
        targets,
        noise: noise(rng.random()),
        task: None,
    };
    let paper = |i: usize| {
        Some(PaperValue {
            mean_mm: PAPER_TABLE_I[i].0,
            variance_mm2: Some(PAPER_TABLE_I[i].1),
        })
    };
    let paper_mode = CompensationMode::Paper;
    let mut rows: Vec<Row> = vec![
        bench.row("original", &rigid, None, paper_mode, (0, 0.0), paper(0))?,
        bench.row("deflection only", &deflection, None, paper_mode, (0, 0.0), paper(1))?,
    ];
    let seed_ssa = rng.random::<u64>();
    // Table I's rows 3-6; the paper's 900 and 300 poses are `large` and `small` here.
    for (i, label, model, data) in [
        (2, "SSA-BP only", &rigid, &large),
        (3, "SSA-BP only", &rigid, &small),
        (4, "deflection + SSA-BP", &deflection, &large),
        (5, "deflection + SSA-BP", &deflection, &small),
    ] {
        let spec = ssa_bp(config, seed_ssa);
        let (fitted, s) = timed(|| fit_residual_predictor(model, &spec, data, &FitControl::default()));
        rows.push(bench.row(
            &format!("{label}, {} poses", data.len()),
            model,
            Some(fitted?.as_ref()),
            paper_mode,
            (data.len(), s),
            paper(i),
        )?);
    }

    // This project, on the small set only: identify the elastic model, then learn what it
    // leaves (the large set adds nothing measurable and triples the run time).
    let start = elastic_start()?;
    let params = CalibrationParams {
        measurement_std: config.noise_mm * 1e-3,
        ..CalibrationParams::default()
    };
    let exact = CompensationMode::Exact;
    {
        let data = &small;
        let n = data.len();
        let (calibrated, s_cal) = timed(|| calibrate(&start, data, &params, &mut |_| {}));
        let model = calibrated?.robot;
        rows.push(bench.row(
            &format!("calibrated elastic model, {n} poses"),
            &model,
            None,
            exact,
            (n, s_cal),
            None,
        )?);
        let gp = GpSpec {
            seed: seed_ssa,
            ..GpSpec::default()
        };
        let ssa = ssa_bp(config, seed_ssa);
        let predictors: [(&str, &dyn PredictorSpec); 2] = [("GP", &gp), ("SSA-BP", &ssa)];
        for (label, spec) in predictors {
            let (fitted, s) = timed(|| fit_residual_predictor(&model, spec, data, &FitControl::default()));
            let fitted = fitted?;
            rows.push(bench.row(
                &format!("calibrated elastic + {label}, {n} poses"),
                &model,
                Some(fitted.as_ref()),
                exact,
                (n, s_cal + s),
                None,
            )?);
        }
    }
    Ok(Table {
        title: "rock-drill twin: the deflection paper's Sec. III (Table I), then this project".into(),
        setup: format!(
            "training poses drawn from the Sec. III.B grid ({}, seed {}), {} random test targets; mean |z| and variance as in Table I",
            if config.grouped {
                "group by group as measured"
            } else {
                "at random"
            },
            config.seed,
            config.targets
        ),
        noise_mm: config.noise_mm,
        noise_mean_abs_z_mm: config.noise_mm * (2.0 / std::f64::consts::PI).sqrt(),
        paper_metric: PaperMetric::MeanAbsZ,
        rows,
    })
}
