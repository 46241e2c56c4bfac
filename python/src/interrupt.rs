//! Long calls run on a worker thread with the GIL released while the calling thread watches
//! for Ctrl-C: on `KeyboardInterrupt` it cancels the call's own token (other calls, in other
//! threads, go on), waits for the computation to return at its next check, and raises.

use std::sync::{Condvar, Mutex, PoisonError};
use std::time::Duration;

use armcomp_core::support::cancel::Cancel;
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

/// How often the calling thread looks for a pending signal.
const POLL: Duration = Duration::from_millis(50);

/// Runs `work` without the GIL with a token of its own, which Ctrl-C in the calling (main)
/// thread cancels.
pub fn run<T: Send>(py: Python<'_>, work: impl FnOnce(&Cancel) -> T + Send) -> PyResult<T> {
    let done = (Mutex::new(false), Condvar::new());
    let cancel = Cancel::new();
    std::thread::scope(|s| {
        let worker = s.spawn(|| {
            let out = work(&cancel);
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
                cancel.cancel();
                signal = Some(e);
                break;
            }
        }
        let joined = py.detach(|| worker.join());
        if let Some(e) = signal {
            return Err(e);
        }
        joined.map_err(|_| PyRuntimeError::new_err("armcomp panicked; this is a bug, please report it"))
    })
}
