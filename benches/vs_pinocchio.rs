//! armcomp's rigid kinematics against pinocchio 4.1 (C++), in one process, on the same URDFs
//! and the same 10,000 seeded configurations (`benches/pinocchio/README.md`).
//!
//! pinocchio comes in through the C ABI of `benches/pinocchio/shim.cpp`, loaded at run time from
//! the path in `ARMCOMP_PINOCCHIO_SHIM`; without it the bench says how to build the library and
//! exits successfully, so neither building nor running it needs pinocchio. With it, the two
//! implementations are first checked to agree on every configuration (tool pose and link
//! positions within 1e-9 m, Jacobians within 1e-9), then timed in alternation, round after round.

use std::ffi::{CStr, CString, OsString, c_char, c_int, c_void};
use std::hint::black_box;
use std::ops::Range;
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

use armcomp_core::robot::robot_file::PointSpec;
use armcomp_core::support::io::InputLimits;
use armcomp_core::{KinematicTree, PointKinematics, PointKinematicsWorkspace, Robot, TreeWorkspace};
use libloading::Library;
use nalgebra::{IsometryMatrix3, Matrix6xX};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

/// Configurations per robot.
const N: usize = 10_000;
/// Timed rounds; each times every row once on both sides.
const ROUNDS: usize = 25;
/// Configurations timed at a time (see [`time`]).
const BLOCK: usize = 250;
/// Largest difference accepted between the two (m for positions, 1 for rotation matrix entries
/// and Jacobian entries, which are m/rad or 1).
const TOLERANCE: f64 = 1e-9;
const SHIM_VARIABLE: &str = "ARMCOMP_PINOCCHIO_SHIM";

/// URDFs of `tests/data/urdf` and the link each robot's tool point sits on.
const ROBOTS: [(&str, &str); 3] = [
    ("ur5_robot.urdf", "tool0"),
    ("panda.urdf", "panda_hand_tcp"),
    ("talos_full_v2.urdf", "gripper_left_base_link"),
];

fn main() -> ExitCode {
    let Some(shim) = std::env::var_os(SHIM_VARIABLE) else {
        println!(
            "vs_pinocchio: skipped. Build the pinocchio library with `benches/pinocchio/build.sh` \
             and set {SHIM_VARIABLE} to the path it prints (benches/pinocchio/README.md)."
        );
        return ExitCode::SUCCESS;
    };
    match run(shim) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("vs_pinocchio: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(shim: OsString) -> Result<(), String> {
    let shim = Shim::open(&shim)?;
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/urdf");
    println!("vs_pinocchio: {N} configurations per robot, {ROUNDS} rounds, per-configuration times in ns");
    println!("median [quartiles] over rounds of each side's median over blocks of {BLOCK} configurations;");
    println!("ratio = armcomp / pinocchio per round, then its median [quartiles]");
    for (file, tool_link) in ROBOTS {
        let bench = Bench::new(&shim, &dir.join(file), tool_link).map_err(|e| format!("{file}: {e}"))?;
        let (position, entry) = bench
            .check()
            .map_err(|e| format!("{file}: armcomp and pinocchio disagree: {e}"))?;
        println!(
            "\n{file} (nq {}, tool at `{tool_link}`): agree on every configuration, largest differences \
             {position:.1e} m (positions), {entry:.1e} (rotation and Jacobian entries)",
            bench.nq
        );
        println!(
            "{:<24} {:>26} {:>26} {:>24}",
            "", "armcomp", "pinocchio", "armcomp/pinocchio"
        );
        for row in time(bench.rows())? {
            println!("{row}");
        }
    }
    Ok(())
}

/// One robot loaded by both, with its configurations in each one's coordinates.
struct Bench<'s> {
    /// The tool's path of the robot file of a URDF robot with one point, at the tool link, fixed joints folded: what FK to the tool and its Jacobian run.
    plan: PointKinematics,
    /// The bare URDF robot: a point at every link.
    links: Robot,
    pin: PinModel<'s>,
    nq: usize,
    /// armcomp's configurations, `N × nq`.
    qs: Vec<f64>,
    /// The same in pinocchio's q, `N × pin.nq`.
    pin_qs: Vec<f64>,
    /// pinocchio's Jacobian column of each armcomp coordinate.
    pin_column: Vec<usize>,
    /// pinocchio's frame of the tool link, and of each link in the order of `links`' points.
    tool_frame: usize,
    link_frames: Vec<usize>,
}

impl<'s> Bench<'s> {
    /// armcomp's robots as the command line builds them from the URDF; pinocchio's model with
    /// `<mimic>` joints following the joint they name, as armcomp's do.
    fn new(shim: &'s Shim, urdf: &Path, tool_link: &str) -> Result<Self, String> {
        let _ = armcomp_urdf::plugins();
        let links = armcomp_urdf::robot_from_urdf(urdf, InputLimits::default()).map_err(|e| e.to_string())?;
        let mut file = armcomp_urdf::robot_file_for_urdf(urdf, InputLimits::default()).map_err(|e| e.to_string())?;
        file.points = vec![PointSpec {
            name: "tool".into(),
            link: tool_link.into(),
            xyz: [0.0; 3],
            rpy: [0.0; 3],
        }];
        file.tool = "tool".into();
        let dir = urdf.parent().unwrap_or(Path::new("."));
        let tool = Robot::build(file, dir, InputLimits::default())
            .map_err(|issues| issues.iter().map(|i| i.in_file(urdf)).collect::<Vec<_>>().join("\n"))?;
        let pin = PinModel::load(shim, urdf)?;

        let tree = tool.tree();
        let nq = tree.nq();
        let mut rng = StdRng::seed_from_u64(23);
        let qs: Vec<f64> = (0..N)
            .flat_map(|_| tree.coordinate_limits().to_vec())
            .map(|l| match l {
                Some(l) => rng.random_range(l.lower..=l.upper),
                None => rng.random_range(-std::f64::consts::PI..=std::f64::consts::PI),
            })
            .collect();

        // Map by joint name; every q value and velocity of pinocchio must be one of armcomp's.
        let mut q_slots = Vec::with_capacity(nq);
        let mut pin_column = Vec::with_capacity(nq);
        let mut q_covered = vec![false; pin.nq];
        let mut v_covered = vec![false; pin.nv];
        for name in tree.coordinate_names() {
            let j = pin.joint(name)?;
            if j.nv != 1 || !(j.nq == 1 || j.nq == 2) {
                return Err(format!(
                    "pinocchio's joint `{name}` has {} q values and {} velocities",
                    j.nq, j.nv
                ));
            }
            q_covered[j.idx_q..j.idx_q + j.nq].fill(true);
            v_covered[j.idx_v] = true;
            q_slots.push((j.idx_q, j.nq));
            pin_column.push(j.idx_v);
        }
        if let Some(i) = q_covered.iter().position(|c| !c) {
            return Err(format!("pinocchio's q value {i} belongs to no joint armcomp moves"));
        }
        if let Some(i) = v_covered.iter().position(|c| !c) {
            return Err(format!("pinocchio's velocity {i} belongs to no joint armcomp moves"));
        }
        let mut pin_qs = vec![0.0; N * pin.nq];
        for (q, p) in qs.chunks_exact(nq).zip(pin_qs.chunks_exact_mut(pin.nq)) {
            for (&v, &(i, width)) in q.iter().zip(&q_slots) {
                // A continuous joint is (cos, sin) in pinocchio's q.
                if width == 2 {
                    p[i..i + 2].copy_from_slice(&[v.cos(), v.sin()]);
                } else {
                    p[i] = v;
                }
            }
        }
        let tool_frame = pin.frame_id(tool_link)?;
        let link_frames = links
            .tree()
            .points()
            .iter()
            .map(|p| pin.frame_id(&p.name))
            .collect::<Result<_, _>>()?;
        let plan = PointKinematics::for_points(tool.tree(), &[tool.tool()]).map_err(|e| e.to_string())?;
        Ok(Bench {
            plan,
            links,
            pin,
            nq,
            qs,
            pin_qs,
            pin_column,
            tool_frame,
            link_frames,
        })
    }

    /// Every configuration's results from both sides, compared: the largest differences of
    /// positions (m) and of rotation and Jacobian entries.
    fn check(&self) -> Result<(f64, f64), String> {
        let (nq, nv, plan) = (self.nq, self.pin.nv, &self.plan);
        let mut ws = plan.workspace();
        let mut many = plan.many_workspace();
        let mut jac = Matrix6xX::zeros(nq);
        let (mut position, mut entry) = (0.0f64, 0.0f64);

        let mut p = vec![0.0; N * POSE];
        self.pin.fk_frame(self.tool_frame, &self.pin_qs, &mut p, POSE)?;
        let mut one = vec![0.0; N * POSE];
        fk_tool(plan, &self.qs, &mut ws, &mut one, POSE);
        let mut poses = vec![IsometryMatrix3::identity(); N];
        plan.forward_many_into(N, &self.qs, &mut poses, &mut many)
            .map_err(|e| e.to_string())?;
        let mut batch = vec![0.0; N * POSE];
        for (pose, o) in poses.iter().zip(batch.chunks_exact_mut(POSE)) {
            write_pose(pose, o);
        }
        for (what, a) in [("FK to the tool", &one), ("FK to the tool, batch", &batch)] {
            for (i, (a, p)) in a.chunks_exact(POSE).zip(p.chunks_exact(POSE)).enumerate() {
                let d = max_difference(&a[..3], &p[..3]);
                let dr = max_difference(&a[3..], &p[3..]);
                if d > TOLERANCE || dr > TOLERANCE {
                    return Err(format!(
                        "{what}, configuration {i}: position {d:e} m, rotation {dr:e} apart"
                    ));
                }
                (position, entry) = (position.max(d), entry.max(dr));
            }
        }

        let width = 3 * self.link_frames.len();
        let mut links_ws = TreeWorkspace::new(self.links.tree());
        let (mut a, mut p) = (vec![0.0; N * width], vec![0.0; N * width]);
        fk_all(self.links.tree(), &self.qs, &mut links_ws, &mut a, width);
        self.pin.fk_all(&self.link_frames, &self.pin_qs, &mut p, width)?;
        for (i, (a, p)) in a.chunks_exact(width).zip(p.chunks_exact(width)).enumerate() {
            let d = max_difference(a, p);
            if d > TOLERANCE {
                return Err(format!("all frames, configuration {i}: a link position {d:e} m apart"));
            }
            position = position.max(d);
        }

        let (mut a, mut p) = (vec![0.0; N * 6 * nq], vec![0.0; N * 6 * nv]);
        fk_jacobian(plan, &self.qs, &mut ws, &mut jac, &mut a, 6 * nq);
        let mut batch = vec![0.0; N * 6 * nq];
        plan.pose_jacobian_many_into(N, &self.qs, 0, &mut batch, &mut many)
            .map_err(|e| e.to_string())?;
        let compare = |what: &str, a: &[f64], p: &[f64]| {
            let mut largest = 0.0f64;
            for (i, (a, p)) in a.chunks_exact(6 * nq).zip(p.chunks_exact(6 * nv)).enumerate() {
                for (c, &pc) in self.pin_column.iter().enumerate() {
                    let d = max_difference(&a[6 * c..6 * c + 6], &p[6 * pc..6 * pc + 6]);
                    if d > TOLERANCE {
                        return Err(format!("{what}, configuration {i}, column {c}: {d:e} apart"));
                    }
                    largest = largest.max(d);
                }
            }
            Ok(largest)
        };
        self.pin.frame_jacobian(self.tool_frame, &self.pin_qs, &mut p, 6 * nv)?;
        entry = entry.max(compare("Jacobian from q (computeFrameJacobian)", &a, &p)?);
        entry = entry.max(compare("batched Jacobian against computeFrameJacobian", &batch, &p)?);
        p.fill(f64::NAN);
        self.pin
            .joint_jacobians_then_frame(self.tool_frame, &self.pin_qs, &mut p, 6 * nv)?;
        entry = entry.max(compare("Jacobian after FK (getFrameJacobian)", &a, &p)?);
        Ok((position, entry))
    }

    /// The timed rows. Each side is a loop over every configuration writing one result slot
    /// (stride 0), the same functions as [`check`](Self::check) runs.
    fn rows(&self) -> Vec<Row<'_>> {
        let (nq, pnq, nv) = (self.nq, self.pin.nq, self.pin.nv);
        let (qs, pin_qs, pin, plan) = (&self.qs, &self.pin_qs, &self.pin, &self.plan);
        let links_tree = self.links.tree();
        let frame = self.tool_frame;
        let links = &self.link_frames;
        // Each closure owns its buffers.
        let ws = || plan.workspace();
        let jac = || Matrix6xX::<f64>::zeros(nq);
        // pinocchio's loops, each the reference of a single-call row and of a batch row.
        let pin_fk_tool = || {
            let mut out = [0.0; POSE];
            Work::Loop(Box::new(move |r| {
                pin.fk_frame(frame, black_box(rows(pin_qs, pnq, r)), &mut out, 0)
            }))
        };
        let pin_frame_jacobian = || {
            let mut out = vec![0.0; 6 * nv];
            Work::Loop(Box::new(move |r| {
                pin.frame_jacobian(frame, black_box(rows(pin_qs, pnq, r)), &mut out, 0)
            }))
        };
        vec![
            Row {
                name: "FK to the tool",
                armcomp: Work::Loop(Box::new({
                    let (mut ws, mut out) = (ws(), [0.0; POSE]);
                    move |r| {
                        fk_tool(plan, black_box(rows(qs, nq, r)), &mut ws, &mut out, 0);
                        black_box(&out);
                        Ok(())
                    }
                })),
                pinocchio: pin_fk_tool(),
            },
            Row {
                name: "all frames",
                armcomp: Work::Loop(Box::new({
                    let (mut ws, mut out) = (TreeWorkspace::new(links_tree), vec![0.0; 3 * links.len()]);
                    move |r| {
                        fk_all(links_tree, black_box(rows(qs, nq, r)), &mut ws, &mut out, 0);
                        black_box(&out);
                        Ok(())
                    }
                })),
                pinocchio: Work::Loop(Box::new({
                    let mut out = vec![0.0; 3 * links.len()];
                    move |r| pin.fk_all(links, black_box(rows(pin_qs, pnq, r)), &mut out, 0)
                })),
            },
            Row {
                name: "6×n Jacobian from q",
                armcomp: Work::Loop(Box::new({
                    let (mut ws, mut jac, mut out) = (ws(), jac(), vec![0.0; 6 * nq]);
                    move |r| {
                        fk_jacobian(plan, black_box(rows(qs, nq, r)), &mut ws, &mut jac, &mut out, 0);
                        black_box(&out);
                        Ok(())
                    }
                })),
                pinocchio: pin_frame_jacobian(),
            },
            // FK with the Jacobian minus FK alone: each library's own preparation (armcomp's
            // FK; pinocchio's computeJointJacobians, which getFrameJacobian reads) is left out.
            Row {
                name: "Jacobian alone",
                armcomp: Work::Extra(
                    Box::new({
                        let (mut ws, mut jac, mut out) = (ws(), jac(), vec![0.0; 6 * nq]);
                        move |r| {
                            fk_jacobian(plan, black_box(rows(qs, nq, r)), &mut ws, &mut jac, &mut out, 0);
                            black_box(&out);
                            Ok(())
                        }
                    }),
                    Box::new({
                        let mut ws = ws();
                        move |r| {
                            for q in black_box(rows(qs, nq, r)).chunks_exact(nq) {
                                plan.forward_into(q, &mut ws);
                            }
                            black_box(&ws);
                            Ok(())
                        }
                    }),
                ),
                pinocchio: Work::Extra(
                    Box::new({
                        let mut out = vec![0.0; 6 * nv];
                        move |r| pin.joint_jacobians_then_frame(frame, black_box(rows(pin_qs, pnq, r)), &mut out, 0)
                    }),
                    Box::new(move |r| pin.joint_jacobians(black_box(rows(pin_qs, pnq, r)))),
                ),
            },
            // armcomp's batches against pinocchio's loop, which has no batch call.
            Row {
                name: "FK to the tool, batch",
                armcomp: Work::Loop(Box::new({
                    let (mut many, mut out) = (plan.many_workspace(), vec![IsometryMatrix3::identity(); BLOCK]);
                    move |r| {
                        let n = r.len();
                        plan.forward_many_into(n, black_box(rows(qs, nq, r)), &mut out[..n], &mut many)
                            .map_err(|e| e.to_string())?;
                        black_box(&out);
                        Ok(())
                    }
                })),
                pinocchio: pin_fk_tool(),
            },
            Row {
                name: "6×n Jacobian from q, batch",
                armcomp: Work::Loop(Box::new({
                    let (mut many, mut out) = (plan.many_workspace(), vec![0.0; BLOCK * 6 * nq]);
                    move |r| {
                        let n = r.len();
                        plan.pose_jacobian_many_into(
                            n,
                            black_box(rows(qs, nq, r)),
                            0,
                            &mut out[..n * 6 * nq],
                            &mut many,
                        )
                        .map_err(|e| e.to_string())?;
                        black_box(&out);
                        Ok(())
                    }
                })),
                pinocchio: pin_frame_jacobian(),
            },
        ]
    }
}

/// Values per pose: position, then the rotation matrix column by column (pinocchio's layout).
const POSE: usize = 12;

/// Writes `pose` as [`POSE`] values.
fn write_pose(pose: &IsometryMatrix3<f64>, o: &mut [f64]) {
    o[..3].copy_from_slice(pose.translation.vector.as_slice());
    o[3..POSE].copy_from_slice(pose.rotation.matrix().as_slice());
}

/// FK of the tool's path at every configuration (`qs`, `nq` each), writing the tool's pose to
/// `out + i · stride`.
fn fk_tool(plan: &PointKinematics, qs: &[f64], ws: &mut PointKinematicsWorkspace, out: &mut [f64], stride: usize) {
    for (i, q) in qs.chunks_exact(plan.nq()).enumerate() {
        plan.forward_into(q, ws);
        write_pose(&ws.point_pose(0), &mut out[i * stride..]);
    }
}

/// FK of every configuration, writing every point's position to `out + i · stride`.
fn fk_all(tree: &KinematicTree, qs: &[f64], ws: &mut TreeWorkspace, out: &mut [f64], stride: usize) {
    for (i, q) in qs.chunks_exact(tree.nq()).enumerate() {
        tree.forward_into(q, ws);
        for (p, o) in ws.point.iter().zip(out[i * stride..].chunks_exact_mut(3)) {
            o.copy_from_slice(p.translation.vector.as_slice());
        }
    }
}

/// FK and the tool's 6 × n pose Jacobian of every configuration, written column-major to
/// `out + i · stride`.
fn fk_jacobian(
    plan: &PointKinematics,
    qs: &[f64],
    ws: &mut PointKinematicsWorkspace,
    jac: &mut Matrix6xX<f64>,
    out: &mut [f64],
    stride: usize,
) {
    let width = jac.len();
    for (i, q) in qs.chunks_exact(plan.nq()).enumerate() {
        plan.forward_into(q, ws);
        plan.pose_jacobian_into(ws, 0, jac);
        out[i * stride..i * stride + width].copy_from_slice(jac.as_slice());
    }
}

fn max_difference(a: &[f64], b: &[f64]) -> f64 {
    // A NaN on either side counts as a disagreement.
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, |m, d| if d.is_nan() { f64::INFINITY } else { m.max(d) })
}

/// Configurations `r` of `qs` (`width` values each).
fn rows(qs: &[f64], width: usize, r: Range<usize>) -> &[f64] {
    &qs[r.start * width..r.end * width]
}

/// A loop over the configurations in the range.
type Loop<'a> = Box<dyn FnMut(Range<usize>) -> Result<(), String> + 'a>;

/// What one side of a row times.
enum Work<'a> {
    /// One loop.
    Loop(Loop<'a>),
    /// The first loop's time less the second's, where the first does the second's work and one
    /// more step: the time of that step.
    Extra(Loop<'a>, Loop<'a>),
}

impl Work<'_> {
    /// Seconds for configurations `r`.
    fn run(&mut self, r: Range<usize>) -> Result<f64, String> {
        let once = |f: &mut Loop, r: Range<usize>| -> Result<f64, String> {
            let start = Instant::now();
            f(r)?;
            Ok(start.elapsed().as_secs_f64())
        };
        match self {
            Work::Loop(f) => once(f, r),
            Work::Extra(with, without) => Ok(once(with, r.clone())? - once(without, r)?),
        }
    }
}

/// One line of the comparison. A batched armcomp call against pinocchio's loop is one more
/// `Row` whose armcomp side calls the batch API once for the range's configurations.
struct Row<'a> {
    name: &'static str,
    armcomp: Work<'a>,
    pinocchio: Work<'a>,
}

/// A row's results: per-configuration times (ns) of each round, both sides, and their ratios.
struct Timing {
    name: &'static str,
    armcomp: Vec<f64>,
    pinocchio: Vec<f64>,
    ratio: Vec<f64>,
}

/// Times every row `ROUNDS` times after one warm-up round. A round runs all `N` configurations
/// in blocks of `BLOCK`, armcomp and pinocchio alternating block by block (and which goes
/// first); a side's time in the round is the median of its blocks, so a block during which the
/// process was descheduled does not count.
fn time(mut rows: Vec<Row<'_>>) -> Result<Vec<Timing>, String> {
    let mut timings: Vec<Timing> = rows
        .iter()
        .map(|r| Timing {
            name: r.name,
            armcomp: Vec::new(),
            pinocchio: Vec::new(),
            ratio: Vec::new(),
        })
        .collect();
    let (mut a, mut p) = (Vec::with_capacity(N / BLOCK), Vec::with_capacity(N / BLOCK));
    for round in 0..=ROUNDS {
        for (row, timing) in rows.iter_mut().zip(&mut timings) {
            a.clear();
            p.clear();
            for (k, start) in (0..N).step_by(BLOCK).enumerate() {
                let r = start..(start + BLOCK).min(N);
                let per = 1e9 / r.len() as f64;
                if k % 2 == 0 {
                    a.push(row.armcomp.run(r.clone())? * per);
                    p.push(row.pinocchio.run(r)? * per);
                } else {
                    p.push(row.pinocchio.run(r.clone())? * per);
                    a.push(row.armcomp.run(r)? * per);
                }
            }
            if round > 0 {
                let (a, p) = (quartiles(&a)[0], quartiles(&p)[0]);
                timing.armcomp.push(a);
                timing.pinocchio.push(p);
                timing.ratio.push(a / p);
            }
        }
    }
    Ok(timings)
}

/// Median and quartiles.
fn quartiles(v: &[f64]) -> [f64; 3] {
    let mut v = v.to_vec();
    v.sort_by(f64::total_cmp);
    let at = |f: f64| {
        let x = f * (v.len() - 1) as f64;
        let (i, t) = (x.floor() as usize, x.fract());
        v[i] + t * (v[(i + 1).min(v.len() - 1)] - v[i])
    };
    [at(0.5), at(0.25), at(0.75)]
}

impl std::fmt::Display for Timing {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let [a, a1, a3] = quartiles(&self.armcomp);
        let [p, p1, p3] = quartiles(&self.pinocchio);
        let [r, r1, r3] = quartiles(&self.ratio);
        write!(
            f,
            "{:<24} {:>26} {:>26} {:>24}",
            self.name,
            format!("{a:.1} [{a1:.1}, {a3:.1}]"),
            format!("{p:.1} [{p1:.1}, {p3:.1}]"),
            format!("{r:.3} [{r1:.3}, {r3:.3}]"),
        )
    }
}

type Load = unsafe extern "C" fn(*const c_char, c_int, *mut *mut c_void) -> c_int;
type Free = unsafe extern "C" fn(*mut c_void);
type LastError = unsafe extern "C" fn() -> *const c_char;
type Dims = unsafe extern "C" fn(*const c_void, *mut usize, *mut usize, *mut usize) -> c_int;
type JointIndex =
    unsafe extern "C" fn(*const c_void, *const c_char, *mut usize, *mut usize, *mut usize, *mut usize) -> c_int;
type FrameId = unsafe extern "C" fn(*const c_void, *const c_char, *mut usize) -> c_int;
/// `(handle, frame, n, qs, out, out_stride)`.
type FrameLoop = unsafe extern "C" fn(*mut c_void, usize, usize, *const f64, *mut f64, usize) -> c_int;
/// `(handle, frames, frame count, n, qs, out, out_stride)`.
type FramesLoop = unsafe extern "C" fn(*mut c_void, *const usize, usize, usize, *const f64, *mut f64, usize) -> c_int;
/// `(handle, n, qs)`.
type PlainLoop = unsafe extern "C" fn(*mut c_void, usize, *const f64) -> c_int;

/// The functions of `shim.cpp`, with the library that holds them.
struct Shim {
    load: Load,
    free: Free,
    last_error: LastError,
    dims: Dims,
    joint: JointIndex,
    frame_id: FrameId,
    fk_frame: FrameLoop,
    fk_all: FramesLoop,
    frame_jacobian: FrameLoop,
    joint_jacobians: PlainLoop,
    joint_jacobians_then_frame: FrameLoop,
    /// Kept loaded while the function pointers above are used.
    _library: Library,
}

impl Shim {
    fn open(path: &OsString) -> Result<Shim, String> {
        let shown = Path::new(path).display().to_string();
        // SAFETY: loading runs the library's initialisers; it is the shim the user built and named.
        let library =
            unsafe { Library::new(path) }.map_err(|e| format!("{SHIM_VARIABLE}={shown}: {}", with_source(&e)))?;
        macro_rules! symbol {
            ($name:literal) => {
                // SAFETY: shim.cpp defines the symbol with this signature.
                *unsafe { library.get(concat!($name, "\0").as_bytes()) }.map_err(|e| {
                    format!(
                        "{shown} is not the shim of benches/pinocchio: {}",
                        with_source(&e)
                    )
                })?
            };
        }
        Ok(Shim {
            load: symbol!("pinshim_load"),
            free: symbol!("pinshim_free"),
            last_error: symbol!("pinshim_last_error"),
            dims: symbol!("pinshim_dims"),
            joint: symbol!("pinshim_joint"),
            frame_id: symbol!("pinshim_frame_id"),
            fk_frame: symbol!("pinshim_fk_frame"),
            fk_all: symbol!("pinshim_fk_all"),
            frame_jacobian: symbol!("pinshim_frame_jacobian"),
            joint_jacobians: symbol!("pinshim_joint_jacobians"),
            joint_jacobians_then_frame: symbol!("pinshim_joint_jacobians_then_frame"),
            _library: library,
        })
    }

    /// Turns a shim return code into a result carrying pinocchio's message.
    fn status(&self, code: c_int, what: &str) -> Result<(), String> {
        if code == 0 {
            return Ok(());
        }
        // SAFETY: the shim returns a NUL-terminated string owned by the calling thread.
        let message = unsafe { CStr::from_ptr((self.last_error)()) }
            .to_string_lossy()
            .into_owned();
        Err(format!("pinocchio, {what}: {message} (code {code})"))
    }
}

/// Where a joint sits in pinocchio's q and velocity.
struct PinJoint {
    idx_q: usize,
    nq: usize,
    idx_v: usize,
    nv: usize,
}

/// A pinocchio model and its data, owned by the shim.
struct PinModel<'s> {
    shim: &'s Shim,
    handle: *mut c_void,
    nq: usize,
    nv: usize,
    nframes: usize,
}

impl<'s> PinModel<'s> {
    fn load(shim: &'s Shim, urdf: &Path) -> Result<Self, String> {
        let path = c_string(&urdf.display().to_string())?;
        let mut handle = std::ptr::null_mut();
        // SAFETY: a NUL-terminated path and a place for the handle.
        shim.status(
            unsafe { (shim.load)(path.as_ptr(), 1, &mut handle) },
            "reading the URDF",
        )?;
        let mut model = PinModel {
            shim,
            handle,
            nq: 0,
            nv: 0,
            nframes: 0,
        };
        // SAFETY: a live handle and three places for its sizes.
        let code = unsafe { (shim.dims)(handle, &mut model.nq, &mut model.nv, &mut model.nframes) };
        shim.status(code, "model sizes")?;
        Ok(model)
    }

    fn joint(&self, name: &str) -> Result<PinJoint, String> {
        let c = c_string(name)?;
        let mut j = PinJoint {
            idx_q: 0,
            nq: 0,
            idx_v: 0,
            nv: 0,
        };
        // SAFETY: a live handle, a NUL-terminated name and four places for the answer.
        let code = unsafe {
            (self.shim.joint)(
                self.handle,
                c.as_ptr(),
                &mut j.idx_q,
                &mut j.nq,
                &mut j.idx_v,
                &mut j.nv,
            )
        };
        self.shim.status(code, &format!("joint `{name}`"))?;
        if j.idx_q + j.nq > self.nq || j.idx_v + j.nv > self.nv {
            return Err(format!("pinocchio's joint `{name}` lies outside its q or velocity"));
        }
        Ok(j)
    }

    fn frame_id(&self, link: &str) -> Result<usize, String> {
        let c = c_string(link)?;
        let mut id = 0;
        // SAFETY: a live handle, a NUL-terminated name and a place for the id.
        let code = unsafe { (self.shim.frame_id)(self.handle, c.as_ptr(), &mut id) };
        self.shim.status(code, &format!("frame of link `{link}`"))?;
        Ok(id)
    }

    /// The number of configurations in `qs`, checking that `out` holds every result at `stride`.
    fn count(&self, qs: &[f64], out: &[f64], width: usize, stride: usize) -> Result<usize, String> {
        let n = qs.len() / self.nq;
        if qs.len() != n * self.nq || n == 0 || out.len() < (n - 1) * stride + width {
            return Err(format!(
                "{} q values or {} outputs for {n} configurations",
                qs.len(),
                out.len()
            ));
        }
        Ok(n)
    }

    fn check_frame(&self, frame: usize) -> Result<(), String> {
        if frame >= self.nframes {
            return Err(format!("frame {frame} of {}", self.nframes));
        }
        Ok(())
    }

    fn frame_loop(
        &self,
        f: FrameLoop,
        frame: usize,
        qs: &[f64],
        out: &mut [f64],
        width: usize,
        stride: usize,
    ) -> Result<(), String> {
        self.check_frame(frame)?;
        let n = self.count(qs, out, width, stride)?;
        // SAFETY: sizes checked above: `qs` holds n configurations and `out` n results at `stride`.
        let code = unsafe { f(self.handle, frame, n, qs.as_ptr(), out.as_mut_ptr(), stride) };
        self.shim.status(code, "a timed loop")
    }

    /// forwardKinematics + updateFramePlacement: position and column-major rotation.
    fn fk_frame(&self, frame: usize, qs: &[f64], out: &mut [f64], stride: usize) -> Result<(), String> {
        self.frame_loop(self.shim.fk_frame, frame, qs, out, 12, stride)
    }

    /// framesForwardKinematics: the positions of `frames`.
    fn fk_all(&self, frames: &[usize], qs: &[f64], out: &mut [f64], stride: usize) -> Result<(), String> {
        for &f in frames {
            self.check_frame(f)?;
        }
        let n = self.count(qs, out, 3 * frames.len(), stride)?;
        // SAFETY: frames exist; `qs` holds n configurations and `out` n results at `stride`.
        let code = unsafe {
            (self.shim.fk_all)(
                self.handle,
                frames.as_ptr(),
                frames.len(),
                n,
                qs.as_ptr(),
                out.as_mut_ptr(),
                stride,
            )
        };
        self.shim.status(code, "all frames")
    }

    /// computeFrameJacobian, LOCAL_WORLD_ALIGNED, column-major 6 × nv.
    fn frame_jacobian(&self, frame: usize, qs: &[f64], out: &mut [f64], stride: usize) -> Result<(), String> {
        self.frame_loop(self.shim.frame_jacobian, frame, qs, out, 6 * self.nv, stride)
    }

    /// computeJointJacobians, then getFrameJacobian as [`frame_jacobian`](Self::frame_jacobian).
    fn joint_jacobians_then_frame(
        &self,
        frame: usize,
        qs: &[f64],
        out: &mut [f64],
        stride: usize,
    ) -> Result<(), String> {
        self.frame_loop(
            self.shim.joint_jacobians_then_frame,
            frame,
            qs,
            out,
            6 * self.nv,
            stride,
        )
    }

    /// computeJointJacobians alone.
    fn joint_jacobians(&self, qs: &[f64]) -> Result<(), String> {
        self.count(qs, &[], 0, 0)?;
        // SAFETY: `qs` holds whole configurations.
        let code = unsafe { (self.shim.joint_jacobians)(self.handle, qs.len() / self.nq, qs.as_ptr()) };
        self.shim.status(code, "computeJointJacobians")
    }
}

impl Drop for PinModel<'_> {
    fn drop(&mut self) {
        // SAFETY: the handle came from `load` and is freed once.
        unsafe { (self.shim.free)(self.handle) }
    }
}

/// libloading's message and the system's reason under it.
fn with_source(e: &libloading::Error) -> String {
    match std::error::Error::source(e) {
        Some(s) => format!("{e}: {s}"),
        None => e.to_string(),
    }
}

fn c_string(s: &str) -> Result<CString, String> {
    CString::new(s).map_err(|_| format!("`{s}` holds a NUL byte"))
}
