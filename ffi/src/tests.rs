//! The ABI called as C calls it: the command lands the modelled tool on the target, a call
//! allocates nothing after loading, every bad argument is a status with a message, and the
//! committed header is the one cbindgen generates.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::ffi::{CStr, CString};
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use armcomp_core::Robot;
use armcomp_core::algorithms::evaluate::position_errors;
use armcomp_core::algorithms::simulate::{SimulateParams, simulate};
use armcomp_core::data::measurement::Sample;
use nalgebra::Vector3;
use rand::{Rng, SeedableRng};

use super::*;

/// Counts the allocations of the current thread, so that other tests running at the same
/// time do not count.
struct CountingAllocator;

thread_local! {
    static ALLOCATIONS: Cell<usize> = const { Cell::new(0) };
}

// SAFETY: every call is passed on to the system allocator unchanged; counting touches only a
// thread-local cell that needs no allocation.
unsafe impl GlobalAlloc for CountingAllocator {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        // SAFETY: the caller's contract, passed on.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: the caller's contract, passed on.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        ALLOCATIONS.with(|c| c.set(c.get() + 1));
        // SAFETY: the caller's contract, passed on.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: CountingAllocator = CountingAllocator;

fn repository() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
}

/// The rock-drill deflection model with a ridge predictor learned on its truth (as `armcomp
/// learn` fits it), written once into a folder that lives as long as the test process.
fn learned_model() -> &'static Path {
    static FILE: OnceLock<(tempfile::TempDir, PathBuf)> = OnceLock::new();
    &FILE
        .get_or_init(|| {
            let robots = repository().join("robots");
            let truth = Robot::from_path(&robots.join("rock-drill-truth.toml")).unwrap();
            let model = Robot::from_path(&robots.join("rock-drill-deflection.toml")).unwrap();
            let data = simulate(
                &truth,
                &configurations(&truth, 80, 5),
                SimulateParams {
                    noise_std: 0.0,
                    seed: 1,
                },
            )
            .unwrap();
            let spec = armcomp_api::ops::learn::default_predictor("ridge").unwrap();
            let run = armcomp_api::ops::learn::run(
                &model,
                model.to_file(),
                &data.samples,
                Some(spec),
                None,
                &Default::default(),
            )
            .unwrap();
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("learned.toml");
            std::fs::write(&path, run.robot.to_text_for(&path).unwrap()).unwrap();
            (dir, path)
        })
        .1
}

/// Seeded configurations in the middle half of every joint's range.
fn configurations(robot: &Robot, n: usize, seed: u64) -> Vec<Vec<f64>> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let limits = robot.tree().coordinate_limits().to_vec();
    (0..n)
        .map(|_| {
            limits
                .iter()
                .map(|l| {
                    l.map_or(0.0, |l| {
                        0.5 * (l.lower + l.upper) + 0.25 * (l.upper - l.lower) * rng.random_range(-1.0..1.0)
                    })
                })
                .collect()
        })
        .collect()
}

/// Where the full model (chain, error models and predicted residual) puts the tool at `q`
/// (m, measurement frame), by the evaluation the other commands use.
fn modelled_tool(robot: &Robot, q: &[f64]) -> Vector3<f64> {
    let at_origin = Sample {
        q: q.to_vec(),
        point: robot.tool(),
        position: Vector3::zeros(),
        orientation: None,
        payload: None,
        temperature: None,
        torque: None,
        fixed_point: None,
        plane: None,
        sensors: Default::default(),
        position_std: None,
        station: 0,
    };
    -position_errors(robot, &[at_origin])[0]
}

/// Loads `path` through the ABI.
fn load(path: &Path) -> Result<*mut ArmcompModel, (ArmcompStatus, String)> {
    let c_path = CString::new(path.to_str().unwrap()).unwrap();
    let mut model = std::ptr::null_mut();
    let mut message = [0 as c_char; 512];
    // SAFETY: valid pointers and the message buffer's length.
    let status = unsafe { armcomp_model_load(c_path.as_ptr(), &mut model, message.as_mut_ptr(), message.len()) };
    match status {
        ArmcompStatus::Ok => Ok(model),
        s => {
            assert!(model.is_null());
            Err((s, text(&message)))
        }
    }
}

fn text(message: &[c_char]) -> String {
    // SAFETY: the ABI always NUL-terminates a non-empty buffer.
    unsafe { CStr::from_ptr(message.as_ptr()) }
        .to_string_lossy()
        .into_owned()
}

/// One `armcomp_compensate` call: its status, the command and the message.
fn compensate(
    model: *mut ArmcompModel,
    position: &[f64; 3],
    orientation: Option<&[f64; 4]>,
    frame: i32,
    start: Option<&[f64]>,
    q: &mut [f64],
    message: &mut [c_char],
) -> ArmcompStatus {
    // SAFETY: every pointer is valid for its stated length, or null where allowed.
    unsafe {
        armcomp_compensate(
            model,
            position.as_ptr(),
            orientation.map_or(std::ptr::null(), |o| o.as_ptr()),
            frame,
            start.map_or(std::ptr::null(), <[f64]>::as_ptr),
            q.as_mut_ptr(),
            q.len(),
            message.as_mut_ptr(),
            message.len(),
        )
    }
}

#[test]
fn commands_put_the_modelled_tool_on_the_target_without_allocating() {
    let path = learned_model();
    let robot = Robot::from_path(path).unwrap();
    assert!(robot.predictor().is_some() && !robot.error_model_types().is_empty());
    let model = load(path).unwrap();
    // SAFETY: a live handle.
    let nq = unsafe { armcomp_model_joint_count(model) };
    assert_eq!(nq, robot.tree().nq());
    // Targets the modelled tool reaches: its positions at other configurations.
    let targets: Vec<[f64; 3]> = configurations(&robot, 12, 9)
        .iter()
        .map(|q| modelled_tool(&robot, q).into())
        .collect();
    let mut commands = vec![vec![0.0; nq]; targets.len()];
    let mut message = [0 as c_char; 256];
    let before = ALLOCATIONS.with(Cell::get);
    for (t, q) in targets.iter().zip(&mut commands) {
        let status = compensate(model, t, None, ARMCOMP_FRAME_MEASUREMENT, None, q, &mut message);
        assert_eq!(status, ArmcompStatus::Ok, "{}", text(&message));
    }
    let allocations = ALLOCATIONS.with(Cell::get) - before;
    assert_eq!(allocations, 0, "{} calls allocated {allocations} times", targets.len());
    for (t, q) in targets.iter().zip(&commands) {
        let miss = (modelled_tool(&robot, q) - Vector3::from(*t)).norm();
        assert!(miss < options().tolerance, "the modelled tool misses by {miss:e} m");
    }
    // SAFETY: the handle from `load`, freed once.
    unsafe { armcomp_model_free(model) };
}

#[test]
fn a_pose_target_in_the_base_frame_is_reached_with_its_orientation() {
    let path = repository().join("robots/industrial-6dof.toml");
    let robot = Robot::from_path(&path).unwrap();
    let model = load(&path).unwrap();
    let nq = robot.tree().nq();
    let mut message = [0 as c_char; 256];
    for q_goal in configurations(&robot, 5, 3) {
        let pose = robot.forward(&q_goal).unwrap().point[robot.tool()];
        let p: [f64; 3] = pose.translation.vector.into();
        let r = pose.rotation.quaternion();
        let wxyz = [r.w, r.i, r.j, r.k];
        // From the middle of the ranges, as a controller would from its current joints.
        let start = armcomp_core::algorithms::compensate::mid_range(&robot);
        let mut q = vec![0.0; nq];
        let status = compensate(
            model,
            &p,
            Some(&wxyz),
            ARMCOMP_FRAME_BASE,
            Some(&start),
            &mut q,
            &mut message,
        );
        assert_eq!(status, ArmcompStatus::Ok, "{}", text(&message));
        let reached = robot.forward(&q).unwrap().point[robot.tool()];
        assert!((reached.translation.vector - pose.translation.vector).norm() < 1e-9);
        assert!(reached.rotation.angle_to(&pose.rotation) < 1e-6);
    }
    // SAFETY: the handle from `load`, freed once.
    unsafe { armcomp_model_free(model) };
}

#[test]
fn bad_arguments_are_statuses_with_messages() {
    let missing = repository().join("robots/no-such-robot.toml");
    let (status, message) = load(&missing).unwrap_err();
    assert_eq!(status, ArmcompStatus::LoadFailed);
    assert!(message.contains("no-such-robot.toml"), "{message}");

    let path = repository().join("robots/industrial-6dof.toml");
    let model = load(&path).unwrap();
    // SAFETY: a live handle.
    let nq = unsafe { armcomp_model_joint_count(model) };
    let mut message = [0 as c_char; 256];
    let mut q = vec![0.0; nq];
    let p = [1.0, 0.2, 0.5];
    let mut short = vec![0.0; nq - 1];
    assert_eq!(
        compensate(model, &p, None, ARMCOMP_FRAME_BASE, None, &mut short, &mut message),
        ArmcompStatus::InvalidArgument
    );
    assert!(text(&message).contains(&format!("q_len is {}; the model has {nq}", nq - 1)));
    assert_eq!(
        compensate(model, &p, None, 7, None, &mut q, &mut message),
        ArmcompStatus::InvalidArgument
    );
    assert!(text(&message).contains("frame 7"), "{}", text(&message));
    assert_eq!(
        compensate(
            model,
            &[f64::NAN, 0.0, 0.0],
            None,
            ARMCOMP_FRAME_BASE,
            None,
            &mut q,
            &mut message
        ),
        ArmcompStatus::InvalidArgument
    );
    assert!(text(&message).contains("position[0]"), "{}", text(&message));
    assert_eq!(
        compensate(
            model,
            &p,
            Some(&[2.0, 0.0, 0.0, 0.0]),
            ARMCOMP_FRAME_BASE,
            None,
            &mut q,
            &mut message
        ),
        ArmcompStatus::InvalidArgument
    );
    assert!(text(&message).contains("norm 2"), "{}", text(&message));
    let bad_start = vec![f64::INFINITY; nq];
    assert_eq!(
        compensate(
            model,
            &p,
            None,
            ARMCOMP_FRAME_BASE,
            Some(&bad_start),
            &mut q,
            &mut message
        ),
        ArmcompStatus::InvalidArgument
    );
    assert!(text(&message).contains("start configuration"), "{}", text(&message));
    // Far beyond the arm's reach.
    assert_eq!(
        compensate(
            model,
            &[50.0, 0.0, 0.0],
            None,
            ARMCOMP_FRAME_BASE,
            None,
            &mut q,
            &mut message
        ),
        ArmcompStatus::Unreachable
    );
    assert!(text(&message).contains("target not reached"), "{}", text(&message));
    // A message buffer too small keeps whole characters and its NUL.
    let mut tiny = [0x55 as c_char; 6];
    compensate(model, &p, None, 7, None, &mut q, &mut tiny);
    assert_eq!(text(&tiny), "frame");
    // SAFETY: null pointers where the ABI must refuse them.
    unsafe {
        assert_eq!(
            armcomp_compensate(
                std::ptr::null_mut(),
                p.as_ptr(),
                std::ptr::null(),
                0,
                std::ptr::null(),
                q.as_mut_ptr(),
                nq,
                std::ptr::null_mut(),
                0
            ),
            ArmcompStatus::NullArgument
        );
        assert_eq!(
            armcomp_model_load(std::ptr::null(), std::ptr::null_mut(), std::ptr::null_mut(), 0),
            ArmcompStatus::NullArgument
        );
        let names: Vec<String> = (0..nq)
            .map(|i| {
                CStr::from_ptr(armcomp_model_joint_name(model, i))
                    .to_string_lossy()
                    .into_owned()
            })
            .collect();
        assert_eq!(names, Robot::from_path(&path).unwrap().tree().coordinate_names());
        assert!(armcomp_model_joint_name(model, nq).is_null());
        armcomp_model_free(model);
    }
}

/// The committed header is what cbindgen generates from this crate's source;
/// `ARMCOMP_WRITE_HEADER=1` rewrites it.
#[test]
fn header_is_current() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let config = cbindgen::Config::from_file(dir.join("cbindgen.toml")).unwrap();
    let mut generated = Vec::new();
    cbindgen::Builder::new()
        .with_config(config)
        .with_src(dir.join("src/lib.rs"))
        .generate()
        .expect("cbindgen reads the crate")
        .write(&mut generated);
    let header = dir.join("include/armcomp.h");
    if std::env::var_os("ARMCOMP_WRITE_HEADER").is_some() {
        std::fs::write(&header, &generated).unwrap();
    }
    let committed = std::fs::read(&header).unwrap_or_default();
    assert!(
        committed == generated,
        "ffi/include/armcomp.h is stale: regenerate it with `ARMCOMP_WRITE_HEADER=1 cargo test -p armcomp-ffi header_is_current`"
    );
}
