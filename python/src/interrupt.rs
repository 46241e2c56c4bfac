//! Long calls run on a worker thread with the GIL released while the calling thread watches
//! for Ctrl-C: on `KeyboardInterrupt` it asks the computation to stop
//! ([`armcomp_core::support::interrupt`]), waits for it to return at its next check, and raises.

use std::sync::{Condvar, Mutex, PoisonError};
use std::time::Duration;

use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

/// How often the calling thread looks for a pending signal.
const POLL: Duration = Duration::from_millis(50);

/// Runs `work` without the GIL, interruptible by Ctrl-C in the calling (main) thread.
pub fn run<T: Send>(py: Python<'_>, work: impl FnOnce() -> T + Send) -> PyResult<T> {
    let done = (Mutex::new(false), Condvar::new());
    std::thread::scope(|s| {
        let worker = s.spawn(|| {
            let out = work();
            *done.0.lock().unwrap_or_else(PoisonError::into_inner) = true;
            done.1.notify_all();
            out
        });
        let finished = || {
            let guard = done.0.lock().unwrap_or_else(PoisonError::into_inner);
            let (guard, _) = done
                .1
                .wait_timeout_while(guard, POLL, |d| !*d)
                .unwrap_or_else(PoisonError::into_inner);
            *guard || worker.is_finished()
        };
        let mut signal = None;
        while !py.detach(finished) {
            if let Err(e) = py.check_signals() {
                armcomp_core::support::interrupt::request();
                signal = Some(e);
                break;
            }
        }
        let joined = py.detach(|| worker.join());
        if let Some(e) = signal {
            armcomp_core::support::interrupt::clear();
            return Err(e);
        }
        joined.map_err(|_| PyRuntimeError::new_err("armcomp panicked; this is a bug, please report it"))
    })
}
