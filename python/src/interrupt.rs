//! Long calls run on a worker thread with the GIL released while the calling thread watches
//! for Ctrl-C: on `KeyboardInterrupt` it cancels the call's own token (other calls, in other
//! threads, go on), waits for the computation to return at its next check, and raises. Their
//! parallel work runs in a thread pool of the process's own, made again in a child forked
//! after the parent used one.

use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::time::Duration;

use armcomp_core::support::cancel::Cancel;
use pyo3::exceptions::PyRuntimeError;
use pyo3::prelude::*;

/// How often the calling thread looks for a pending signal.
const POLL: Duration = Duration::from_millis(50);

/// The thread pool of this process's parallel work. A fork copies the calling thread alone:
/// in a child of a parent that had used a pool, that pool's workers are not there, and work
/// given to it (as to rayon's global pool) would wait for them for ever. So the pool belongs
/// to the process that made it, and a child makes its own.
fn pool() -> PyResult<Arc<rayon::ThreadPool>> {
    static POOL: Mutex<Option<(u32, Arc<rayon::ThreadPool>)>> = Mutex::new(None);
    let pid = std::process::id();
    let mut slot = POOL.lock().unwrap_or_else(PoisonError::into_inner);
    match slot.take() {
        Some((owner, pool)) if owner == pid => {
            *slot = Some((owner, pool.clone()));
            return Ok(pool);
        }
        // The parent's: dropping it would signal workers that do not exist in this process.
        Some(inherited) => std::mem::forget(inherited),
        None => {}
    }
    let pool = Arc::new(
        rayon::ThreadPoolBuilder::new()
            .build()
            .map_err(|e| PyRuntimeError::new_err(format!("cannot start the worker threads: {e}")))?,
    );
    *slot = Some((pid, pool.clone()));
    Ok(pool)
}

/// Runs `work` without the GIL with a token of its own, which Ctrl-C in the calling (main)
/// thread cancels, its parallel work in this process's [`pool`].
pub fn run<T: Send>(py: Python<'_>, work: impl FnOnce(&Cancel) -> T + Send) -> PyResult<T> {
    let done = (Mutex::new(false), Condvar::new());
    let cancel = Cancel::new();
    let pool = pool()?;
    std::thread::scope(|s| {
        let worker = s.spawn(|| {
            let out = pool.install(|| work(&cancel));
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
