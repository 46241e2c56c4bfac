//! armcomp-ffi: compensation for controllers through a C ABI.
//!
//! A controller loads a model file (a robot or model file, or a bare URDF) once with
//! [`armcomp_model_load`], then turns each target point or pose into joint commands with
//! [`armcomp_compensate`]: the model's chain, its error models and its fitted residual
//! predictor, solved as `armcomp compensate` solves them in its default `exact` mode (the
//! same [`Compensator`] and settings). The header `include/armcomp.h` is generated from this
//! file with cbindgen; a test fails when the committed one is stale.
//!
//! Real time: loading allocates and reads files; after it, a call that succeeds allocates
//! nothing and takes no lock (the handle holds every workspace, sized by a first solve at
//! load), so it may run in a real-time thread. A handle is used by one thread at a time; the
//! caller serialises calls on it (one handle per thread for parallel use). A failed call may
//! allocate while it builds the core's report of the failure. Errors come back as an
//! [`ArmcompStatus`] with a message written into the caller's buffer, truncated to fit and
//! always NUL-terminated; no panic crosses the boundary.
#![warn(missing_docs)]
// The C ABI needs `unsafe` (raw pointers from the caller); each block says why it is sound.
#![deny(clippy::undocumented_unsafe_blocks)]

use std::ffi::{CStr, CString, c_char};
use std::fmt::Write as _;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

use armcomp_api::ops::compensate::{Target, ik_target, options};
use armcomp_core::Robot;
use armcomp_core::algorithms::compensate::{CompensationMode, CompensationParams, Compensator, default_start};
use armcomp_core::algorithms::ik::IkError;
use armcomp_core::support::io::InputLimits;
use nalgebra::{Isometry3, Vector3};

/// What a call did.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArmcompStatus {
    /// Success; the outputs are written.
    Ok = 0,
    /// A pointer that must not be null was null.
    NullArgument = 1,
    /// An argument has the wrong value: a length, a frame, a non-finite number, a quaternion
    /// that is not a unit one.
    InvalidArgument = 2,
    /// The model file could not be read or built (the message names the file and why).
    LoadFailed = 3,
    /// The inverse kinematics reached no command that puts the tool on the target; the
    /// command is not written.
    Unreachable = 4,
    /// The command is written but the model with its predicted residual still misses the
    /// target by more than the tolerance (the message says by how much).
    NotConverged = 5,
    /// An internal error (a bug); the handle should be freed.
    Internal = 6,
}

/// Targets are in the measurement (tracker) frame, as in measurement files and `armcomp
/// compensate --frame measurement`.
pub const ARMCOMP_FRAME_MEASUREMENT: i32 = 0;
/// Targets are in the robot base frame.
pub const ARMCOMP_FRAME_BASE: i32 = 1;

self_cell::self_cell!(
    /// The robot and the compensator that borrows it.
    struct Loaded {
        owner: Robot,
        #[covariant]
        dependent: Compensator,
    }
);

/// A loaded model with the workspaces of its calls (opaque to C).
pub struct ArmcompModel {
    loaded: Loaded,
    /// Where a call without a start configuration starts (as `armcomp compensate` without
    /// `--start`).
    default_start: Vec<f64>,
    /// Coordinate names, for [`armcomp_model_joint_name`].
    joint_names: Vec<CString>,
    /// From the measurement frame to the base.
    base_from_measurement: Isometry3<f64>,
    params: CompensationParams,
}

impl ArmcompModel {
    /// Reads and builds the model at `path` and sizes every workspace with one solve.
    fn load(path: &Path) -> Result<Self, (ArmcompStatus, String)> {
        let failed = |e: &dyn std::fmt::Display| (ArmcompStatus::LoadFailed, e.to_string());
        // Links the built-in plugins, whose registrations robot files name by `type`.
        armcomp_api::registry::builtin_plugins();
        let robot = armcomp_api::read_robot(path, InputLimits::default()).map_err(|e| failed(&e))?;
        let params = options();
        let joint_names = robot
            .tree()
            .coordinate_names()
            .iter()
            .map(|n| CString::new(n.as_str()).map_err(|e| failed(&e)))
            .collect::<Result<_, _>>()?;
        let default_start = default_start(&robot);
        let base_from_measurement = robot.t_meas_base().inverse();
        let loaded = Loaded::try_new(robot, |robot| Compensator::for_model(robot, params)).map_err(|e| failed(&e))?;
        let mut model = ArmcompModel {
            loaded,
            default_start,
            joint_names,
            base_from_measurement,
            params,
        };
        model.warm_up();
        Ok(model)
    }

    /// Compensates the tool's own position at the default start once, so that the buffers
    /// the predictor and the solver grow on first use have their size before the first call.
    fn warm_up(&mut self) {
        let start = &self.default_start;
        self.loaded.with_dependent_mut(|robot, comp| {
            let Ok(frames) = robot.forward(start) else {
                return;
            };
            let at = frames.point[robot.tool()].translation.vector;
            // Its outcome does not matter, only the sizes it leaves.
            let _ = comp.compensate(&at, start, CompensationMode::Exact);
        });
    }

    fn nq(&self) -> usize {
        self.default_start.len()
    }

    /// The command for `target` (in `frame`) from `start` (else the default start) into `q`.
    fn compensate(
        &mut self,
        target: &Target,
        frame: i32,
        start: Option<&[f64]>,
        q: &mut [f64],
        message: &mut Message<'_>,
    ) -> ArmcompStatus {
        let to_base = match frame {
            ARMCOMP_FRAME_MEASUREMENT => self.base_from_measurement,
            ARMCOMP_FRAME_BASE => Isometry3::identity(),
            other => {
                let _ = write!(
                    message,
                    "frame {other} is neither ARMCOMP_FRAME_MEASUREMENT (0) nor ARMCOMP_FRAME_BASE (1)"
                );
                return ArmcompStatus::InvalidArgument;
            }
        };
        let start = start.unwrap_or(&self.default_start);
        let tolerance = self.params.tolerance;
        self.loaded.with_dependent_mut(|robot, comp| {
            if let Err(e) = robot.tree().check_q(start) {
                let _ = write!(message, "start configuration: {e}");
                return ArmcompStatus::InvalidArgument;
            }
            match comp.compensate_target(&ik_target(target, &to_base), start, CompensationMode::Exact) {
                Ok(c) => {
                    q.copy_from_slice(comp.q());
                    if c.mismatch > tolerance {
                        let _ = write!(
                            message,
                            "the model with its predicted residual misses the target by {:.3e} m (tolerance {tolerance:.1e} m) after {} shifts",
                            c.mismatch, c.shifts
                        );
                        return ArmcompStatus::NotConverged;
                    }
                    ArmcompStatus::Ok
                }
                Err(e @ IkError::Unreachable { .. }) => {
                    let _ = write!(message, "{e}");
                    ArmcompStatus::Unreachable
                }
                Err(e @ IkError::Input(_)) => {
                    let _ = write!(message, "{e}");
                    ArmcompStatus::InvalidArgument
                }
            }
        })
    }
}

/// The caller's message buffer: text is copied in as far as it fits (whole characters), and
/// the buffer is always NUL-terminated; formatting into it allocates nothing.
struct Message<'a> {
    buffer: &'a mut [u8],
    len: usize,
}

impl<'a> Message<'a> {
    fn new(buffer: &'a mut [u8]) -> Self {
        if let Some(first) = buffer.first_mut() {
            *first = 0;
        }
        Message { buffer, len: 0 }
    }
}

impl std::fmt::Write for Message<'_> {
    fn write_str(&mut self, s: &str) -> std::fmt::Result {
        // One byte stays for the terminating NUL.
        let room = self.buffer.len().saturating_sub(self.len + 1);
        let mut take = s.len().min(room);
        while !s.is_char_boundary(take) {
            take -= 1;
        }
        self.buffer[self.len..self.len + take].copy_from_slice(&s.as_bytes()[..take]);
        self.len += take;
        if let Some(end) = self.buffer.get_mut(self.len) {
            *end = 0;
        }
        Ok(())
    }
}

/// The caller's message buffer, or an empty one for a null pointer.
///
/// # Safety
/// `message` is null or points to `len` writable bytes.
unsafe fn message_buffer<'a>(message: *mut c_char, len: usize) -> Message<'a> {
    if message.is_null() || len == 0 {
        return Message::new(&mut []);
    }
    // SAFETY: the caller guarantees `len` writable bytes at the non-null `message`, which
    // nothing else touches during the call.
    Message::new(unsafe { std::slice::from_raw_parts_mut(message.cast::<u8>(), len) })
}

/// Runs `f`, turning a panic into [`ArmcompStatus::Internal`] with a message.
fn guarded(message: *mut c_char, message_len: usize, f: impl FnOnce() -> ArmcompStatus) -> ArmcompStatus {
    catch_unwind(AssertUnwindSafe(f)).unwrap_or_else(|_| {
        // SAFETY: the entry points' contract: `message` is null or has `message_len` bytes.
        let mut m = unsafe { message_buffer(message, message_len) };
        let _ = m.write_str("internal error (a panic in armcomp); free this handle");
        ArmcompStatus::Internal
    })
}

/// Loads the model file at `path` (NUL-terminated, UTF-8): a robot or model file (TOML or
/// JSON) or a bare URDF. On success `*model` is a new handle (free it with
/// [`armcomp_model_free`]); otherwise `*model` is null and `message` says why. Run-time plugin
/// libraries are not loaded.
///
/// # Safety
/// `path` is null or a NUL-terminated string; `model` is null or writable; `message` is null
/// or points to `message_len` writable bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn armcomp_model_load(
    path: *const c_char,
    model: *mut *mut ArmcompModel,
    message: *mut c_char,
    message_len: usize,
) -> ArmcompStatus {
    guarded(message, message_len, || {
        // SAFETY: the contract above.
        let mut m = unsafe { message_buffer(message, message_len) };
        if model.is_null() {
            let _ = m.write_str("model: the pointer to receive the handle is null");
            return ArmcompStatus::NullArgument;
        }
        // SAFETY: `model` is non-null and writable (the contract above).
        unsafe { *model = std::ptr::null_mut() };
        if path.is_null() {
            let _ = m.write_str("path: null");
            return ArmcompStatus::NullArgument;
        }
        // SAFETY: `path` is a non-null NUL-terminated string (the contract above).
        let Ok(path) = unsafe { CStr::from_ptr(path) }.to_str() else {
            let _ = m.write_str("path: not UTF-8");
            return ArmcompStatus::InvalidArgument;
        };
        match ArmcompModel::load(Path::new(path)) {
            Ok(loaded) => {
                // SAFETY: as above; the handle is owned by the caller until freed.
                unsafe { *model = Box::into_raw(Box::new(loaded)) };
                ArmcompStatus::Ok
            }
            Err((status, text)) => {
                let _ = m.write_str(&text);
                status
            }
        }
    })
}

/// Frees a handle from [`armcomp_model_load`]; null is ignored.
///
/// # Safety
/// `model` is null or a handle from [`armcomp_model_load`] not yet freed, used by no other
/// call now or later.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn armcomp_model_free(model: *mut ArmcompModel) {
    if !model.is_null() {
        // SAFETY: the contract above: the handle came from `Box::into_raw` and is freed once.
        drop(unsafe { Box::from_raw(model) });
    }
}

/// The number of joint values a command has (the model's independent coordinates); 0 for a
/// null handle.
///
/// # Safety
/// `model` is null or a live handle.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn armcomp_model_joint_count(model: *const ArmcompModel) -> usize {
    // SAFETY: the contract above.
    unsafe { model.as_ref() }.map_or(0, ArmcompModel::nq)
}

/// The name of joint value `index` (NUL-terminated, owned by the handle and valid until it is
/// freed), in the order of commands; null for a null handle or an index out of range.
///
/// # Safety
/// `model` is null or a live handle.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn armcomp_model_joint_name(model: *const ArmcompModel, index: usize) -> *const c_char {
    // SAFETY: the contract above.
    unsafe { model.as_ref() }
        .and_then(|m| m.joint_names.get(index))
        .map_or(std::ptr::null(), |n| n.as_ptr())
}

/// The joint command (SI: rad, m; [`armcomp_model_joint_count`] values into `q_out`) that
/// puts the model's tool on `position` (3 values, m) and, when `orientation_wxyz` is not null,
/// keeps the tool at that orientation (unit quaternion w, x, y, z). Both are in `frame`
/// ([`ARMCOMP_FRAME_MEASUREMENT`] or [`ARMCOMP_FRAME_BASE`]). It starts from `q_start` (the
/// controller's current joints, `q_len` values) or, when null, where `armcomp compensate`
/// starts without `--start`; joints that do not move the tool keep their start values.
/// Allocates nothing and takes no lock when it succeeds. On [`ArmcompStatus::NotConverged`]
/// the command is written and the message says how far it misses.
///
/// # Safety
/// `model` is null or a live handle no other thread uses during the call; `position` is null
/// or points to 3 values, `orientation_wxyz` to 4 (or is null), `q_start` to `q_len` values
/// (or is null), `q_out` to `q_len` writable values (or is null); `message` is null or points
/// to `message_len` writable bytes.
#[unsafe(no_mangle)]
#[allow(clippy::too_many_arguments)] // the plain C signature: pointers with their lengths
pub unsafe extern "C" fn armcomp_compensate(
    model: *mut ArmcompModel,
    position: *const f64,
    orientation_wxyz: *const f64,
    frame: i32,
    q_start: *const f64,
    q_out: *mut f64,
    q_len: usize,
    message: *mut c_char,
    message_len: usize,
) -> ArmcompStatus {
    guarded(message, message_len, || {
        // SAFETY: the contract above.
        let mut m = unsafe { message_buffer(message, message_len) };
        // SAFETY: `model` is null or a live handle used only by this call (the contract above).
        let Some(model) = (unsafe { model.as_mut() }) else {
            let _ = m.write_str("model: null");
            return ArmcompStatus::NullArgument;
        };
        if position.is_null() || q_out.is_null() {
            let _ = m.write_str(if position.is_null() {
                "position: null"
            } else {
                "q_out: null"
            });
            return ArmcompStatus::NullArgument;
        }
        let nq = model.nq();
        if q_len != nq {
            let _ = write!(m, "q_len is {q_len}; the model has {nq} joint values");
            return ArmcompStatus::InvalidArgument;
        }
        // SAFETY: `position` points to 3 values (the contract above).
        let p = unsafe { std::slice::from_raw_parts(position, 3) };
        if let Some(c) = p.iter().position(|v| !v.is_finite()) {
            let _ = write!(m, "position[{c}] is {}, not a finite number", p[c]);
            return ArmcompStatus::InvalidArgument;
        }
        let orientation = if orientation_wxyz.is_null() {
            None
        } else {
            // SAFETY: a non-null `orientation_wxyz` points to 4 values (the contract above).
            let w = unsafe { std::slice::from_raw_parts(orientation_wxyz, 4) };
            match armcomp_api::ops::compensate::orientation([w[0], w[1], w[2], w[3]]) {
                Ok(r) => Some(r),
                Err(e) => {
                    let _ = write!(m, "orientation_wxyz: {e}");
                    return ArmcompStatus::InvalidArgument;
                }
            }
        };
        let start = (!q_start.is_null()).then(|| {
            // SAFETY: a non-null `q_start` points to `q_len` values (the contract above).
            unsafe { std::slice::from_raw_parts(q_start, q_len) }
        });
        // SAFETY: `q_out` points to `q_len` writable values no one else reads during the call.
        let q = unsafe { std::slice::from_raw_parts_mut(q_out, q_len) };
        let target = Target {
            position: Vector3::new(p[0], p[1], p[2]),
            orientation,
        };
        model.compensate(&target, frame, start, q, &mut m)
    })
}

#[cfg(test)]
mod tests;
