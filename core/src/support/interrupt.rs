//! A process-wide stop request. Long computations (calibration iterations, diagnosis rounds,
//! predictor training, batches of targets) check it between steps and return
//! [`Error::Interrupted`], so that a host that cannot kill a thread (a Python session's Ctrl-C)
//! can end them early. Nothing sets it in the command line, where Ctrl-C ends the process.

use std::sync::atomic::{AtomicBool, Ordering};

use crate::error::{Error, Result};

static REQUESTED: AtomicBool = AtomicBool::new(false);

/// Asks every running computation of the process to stop at its next check.
pub fn request() {
    REQUESTED.store(true, Ordering::Relaxed);
}

/// Withdraws the request, once the interrupted computations have returned.
pub fn clear() {
    REQUESTED.store(false, Ordering::Relaxed);
}

/// Whether a stop is requested (for loops that end early and let their caller [`check`]).
pub fn requested() -> bool {
    REQUESTED.load(Ordering::Relaxed)
}

/// `Err(Error::Interrupted)` while a stop is requested.
pub fn check() -> Result<()> {
    if requested() { Err(Error::Interrupted) } else { Ok(()) }
}

/// `Ok(None)` for a computation a stop request ended, so that a search can keep what its other
/// computations finished; other errors stay errors.
pub fn finished<T>(result: Result<T>) -> Result<Option<T>> {
    match result {
        Ok(v) => Ok(Some(v)),
        Err(Error::Interrupted) => Ok(None),
        Err(e) => Err(e),
    }
}
