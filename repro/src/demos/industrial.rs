//! The ANN paper's Sec. 4 on the industrial twin. As in the paper the tool keeps one orientation
//! and every point is a position in the task's workspace, turned into joint values by the
//! nominal inverse kinematics: a 2000-point pool from a quasi-random sequence (Sobol) or a
//! pseudo-random one; geometric identification with POE and with DH on the pool's first 80
//! points; then an ANN for what joint stiffness under the payload leaves, trained on 500 pool
//! points near a U-shaped assembly path (50 path points, each with its 10 nearest pool points)
//! or on 500 arbitrary pool points, measured with the identified model in the controller.
//! Tested at 50 targets along the path, which every model commands at the task's orientation.

use armcomp_core::algorithms::compensate::CompensationMode;
use armcomp_core::algorithms::evaluate::fit_residual_predictor;
use armcomp_core::algorithms::ik::IkWorkspace;
use armcomp_core::algorithms::plan::{resample_by_arc_length, trajectory_similar};
use armcomp_core::algorithms::simulate::{SimulateParams, simulate};
use armcomp_core::calibrate::{CalibrationParams, calibrate};
use armcomp_core::data::measurement::Sample;
use armcomp_core::model::sampling::{Sampler, unit_points};
use armcomp_core::{FitControl, Result, Robot};
use armcomp_learn::MlpSpec;
use nalgebra::{UnitQuaternion, Vector3};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::{PaperMetric, PaperValue, Row, Table, TaughtTask, TestBench, pose_command, timed};
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
    /// Pool points taken per path point in the trajectory-similar selection (10).
    pub per_path_point: usize,
    /// Test targets along the path (50).
    pub targets: usize,
    /// The task's workspace, where the pools' points lie (m, base frame: x forward, z up, origin
    /// on the shoulder axis), per axis from..to.
    pub workspace_m: [[f64; 2]; 3],
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
            per_path_point: 10,
            targets: 50,
            workspace_m: WORKSPACE_M,
        }
    }
}

/// The task's workspace of [`Config::paper`]: a box in front of the arm from 0.6 m below to
/// 0.4 m above the shoulder, as far as the arm reaches it (points the tool cannot reach at the
/// task's orientation are skipped), so the pool spans the arm's whole working range.
pub const WORKSPACE_M: [[f64; 2]; 3] = [[0.15, 0.80], [-0.70, 0.70], [-0.60, 0.40]];

/// The U-shaped assembly path (m, base frame): from the pick point down, across, and up to the
/// place point.
pub const U_PATH_M: [[f64; 3]; 4] = [
    [0.45, -0.25, -0.15],
    [0.45, -0.25, -0.40],
    [0.45, 0.25, -0.40],
    [0.45, 0.25, -0.15],
];

/// The task's tool orientation: pointing down (its orientation at q = 0), tilted by a roll about
/// the base x axis and a pitch about the base y axis (deg), as a tool reaching into a fixture.
/// The tilt keeps the wrist away from its singular stretched pose.
pub const TOOL_TILT_DEG: [f64; 2] = [10.0, 20.0];

/// The task's tool orientation (base frame).
fn task_orientation(robot: &Robot) -> Result<UnitQuaternion<f64>> {
    let home = vec![0.0; robot.tree().nq()];
    let [roll, pitch] = TOOL_TILT_DEG.map(f64::to_radians);
    Ok(UnitQuaternion::from_euler_angles(roll, pitch, 0.0) * robot.forward(&home)?.point[robot.tool()].rotation)
}

/// Where the task's inverse kinematics starts (deg): elbow up, wrist bent forward.
const TASK_START_DEG: [f64; 6] = [0.0, -30.0, 20.0, 0.0, 45.0, 0.0];

/// Joint values and tool positions on the task's branch of the inverse kinematics.
struct Poses {
    /// Tool positions (m, base frame).
    positions: Vec<Vector3<f64>>,
    /// Joint values (rad).
    q: Vec<Vec<f64>>,
}

/// Solves the nominal inverse kinematics at the task's tool orientation for each position,
/// each from `start`, or from the previous solution when `chain` is set (a path). Solutions off
/// the start's branch (the wrist flipped: j5 of the other sign) and positions it cannot reach
/// are left out, up to `n` kept.
fn inverse(
    robot: &Robot,
    positions: impl IntoIterator<Item = Vector3<f64>>,
    start: &[f64],
    n: usize,
    chain: bool,
) -> Result<Poses> {
    let orientation = task_orientation(robot)?;
    let mut ik = IkWorkspace::new(robot);
    let mut out = Poses {
        positions: Vec::with_capacity(n),
        q: Vec::with_capacity(n),
    };
    let mut from = start.to_vec();
    for p in positions {
        if out.q.len() == n {
            break;
        }
        match pose_command(robot, &p, &orientation, &from, &mut ik) {
            Some(q) if q[4] * start[4] > 0.0 => {
                if chain {
                    from.copy_from_slice(&q);
                }
                out.positions.push(p);
                out.q.push(q);
            }
            _ => {}
        }
    }
    Ok(out)
}

/// `n` reachable workspace positions from `sampler` (at most `20 n` are tried), solved from
/// `start`.
fn pool(
    robot: &Robot,
    workspace: &[[f64; 2]; 3],
    sampler: Sampler,
    n: usize,
    seed: u64,
    start: &[f64],
) -> Result<Poses> {
    let points = unit_points(sampler, n.saturating_mul(20), 3, seed)?;
    let positions = points
        .into_iter()
        .map(|u| Vector3::from_fn(|k, _| workspace[k][0] + u[k] * (workspace[k][1] - workspace[k][0])));
    let poses = inverse(robot, positions, start, n, false)?;
    if poses.q.len() < n {
        return Err(armcomp_core::Error::InvalidArgument {
            what: "task workspace".into(),
            reason: format!(
                "only {} of {n} workspace points are reachable at the task's tool orientation",
                poses.q.len()
            ),
        });
    }
    Ok(poses)
}

/// `n` points evenly along the U path with their taught configurations.
fn along_path(robot: &Robot, n: usize) -> Result<Poses> {
    let corners: Vec<Vector3<f64>> = U_PATH_M.iter().map(|p| Vector3::from(*p)).collect();
    let start = TASK_START_DEG.map(f64::to_radians);
    let poses = inverse(robot, resample_by_arc_length(&corners, n), &start, n, true)?;
    if poses.q.len() < n {
        return Err(armcomp_core::Error::InvalidArgument {
            what: "task path".into(),
            reason: "the U path leaves the reachable workspace".into(),
        });
    }
    Ok(poses)
}

/// Runs the protocol on the built-in truth and returns the table.
pub fn run(config: &Config) -> Result<Table> {
    run_on(&Twin::build("industrial-truth")?, config)
}

/// Runs the protocol with `truth` as the arm that is measured and commanded.
pub fn run_on(truth: &Robot, config: &Config) -> Result<Table> {
    let poe = Twin::build("industrial-poe")?;
    let dh = Twin::build("industrial-dh")?;
    let mut rng = StdRng::seed_from_u64(config.seed);
    let noise = |seed: u64| SimulateParams {
        noise_std: config.noise_mm * 1e-3,
        seed,
    };
    let path = along_path(&poe, 200)?;
    // Pool points are solved from the middle of the path, on its branch.
    let middle = path.q[path.q.len() / 2].clone();
    let qrs = pool(
        &poe,
        &config.workspace_m,
        Sampler::Sobol,
        config.pool,
        rng.random(),
        &middle,
    )?;
    let random = pool(
        &poe,
        &config.workspace_m,
        Sampler::Random,
        config.pool,
        rng.random(),
        &middle,
    )?;
    let targets = along_path(&poe, config.targets)?;
    let orientation = task_orientation(&poe)?;
    let bench = TestBench {
        truth,
        targets: targets.positions,
        noise: noise(rng.random()),
        task: Some(TaughtTask {
            taught: targets.q,
            orientation: truth.t_meas_base().rotation * orientation,
        }),
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
    // Geometric identification on the first points of a pool, which spread over the workspace
    // as evenly as the pool's sequence does.
    let mut identify = |model: &Robot, pool: &Poses| -> Result<(Robot, Vec<Sample>, f64)> {
        let ident = simulate(
            truth,
            &pool.q[..config.identification.min(pool.q.len())],
            noise(rng.random()),
        )?
        .samples;
        let (calibrated, s) = timed(|| calibrate(model, &ident, &params, &mut |_| {}));
        Ok((calibrated?.robot, ident, s))
    };
    let (poe_qrs, ident, s_poe) = identify(&poe, &qrs)?;
    let (dh_qrs, _, s_dh) = identify(&dh, &qrs)?;
    let (poe_random, _, s_poe_random) = identify(&poe, &random)?;
    let n_ident = ident.len();
    let mut rows: Vec<Row> = vec![
        bench.row("before (nominal)", &poe, None, exact, (0, 0.0), paper(5.12))?,
        bench.row(
            "POE identification",
            &poe_qrs,
            None,
            exact,
            (n_ident, s_poe),
            paper(1.81),
        )?,
        bench.row("DH identification", &dh_qrs, None, exact, (n_ident, s_dh), paper(2.27))?,
    ];

    // ANN training sets: trajectory-similar or arbitrary picks from a QRS or pseudo-random pool.
    let spec = MlpSpec {
        seed: rng.random(),
        ..MlpSpec::default()
    };
    let path_points = config.training / config.per_path_point.max(1);
    let mut ann_row = |name: &str, model: &Robot, s_model: f64, pool: &Poses, similar: bool, paper_value: f64| {
        let picks: Vec<usize> = if similar {
            trajectory_similar(&poe, &path.q, &pool.positions, path_points, config.per_path_point)?
        } else {
            rand::seq::index::sample(&mut rng, pool.q.len(), config.training.min(pool.q.len())).into_vec()
        };
        // Measured after the identified model is in the controller: it commands the pool's
        // positions at the task's orientation.
        let mut ik = IkWorkspace::new(model);
        let q: Vec<Vec<f64>> = picks
            .iter()
            .map(|&i| {
                pose_command(model, &pool.positions[i], &orientation, &pool.q[i], &mut ik)
                    .unwrap_or_else(|| pool.q[i].clone())
            })
            .collect();
        let data: Vec<Sample> = simulate(truth, &q, noise(rng.random()))?.samples;
        let (fitted, s) = timed(|| fit_residual_predictor(model, &spec, &data, &FitControl::default()));
        bench.row(
            name,
            model,
            Some(fitted?.as_ref()),
            exact,
            (n_ident + data.len(), s_model + s),
            paper(paper_value),
        )
    };
    rows.push(ann_row(
        "POE + ANN, trajectory-similar points, QRS pool",
        &poe_qrs,
        s_poe,
        &qrs,
        true,
        1.23,
    )?);
    rows.push(ann_row(
        "POE + ANN, arbitrary points, QRS pool",
        &poe_qrs,
        s_poe,
        &qrs,
        false,
        1.57,
    )?);
    rows.push(ann_row(
        "POE + ANN, trajectory-similar points, random pool",
        &poe_random,
        s_poe_random,
        &random,
        true,
        1.53,
    )?);
    Ok(Table {
        title: "industrial twin: the ANN paper's Sec. 4".into(),
        setup: format!(
            "tool pointing down, tilted {:.0}° about x and {:.0}° about y; {}-point pools of workspace positions (QRS or pseudo-random) in x {:.2}..{:.2}, y {:.2}..{:.2}, z {:.2}..{:.2} m; {} identification points (the pool's first), {} ANN training points, {} targets along a U-shaped path (seed {}); the paper's column is its 3-D mean accuracy; the random-pool row identifies on the random pool too",
            TOOL_TILT_DEG[0],
            TOOL_TILT_DEG[1],
            config.pool,
            config.workspace_m[0][0],
            config.workspace_m[0][1],
            config.workspace_m[1][0],
            config.workspace_m[1][1],
            config.workspace_m[2][0],
            config.workspace_m[2][1],
            config.identification,
            config.training,
            config.targets,
            config.seed
        ),
        noise_mm: config.noise_mm,
        noise_mean_abs_z_mm: config.noise_mm * (2.0 / std::f64::consts::PI).sqrt(),
        paper_metric: PaperMetric::Mean3d,
        rows,
    })
}
