//! Progress callbacks into Python, called with the GIL from whichever thread does the work.

use pyo3::prelude::*;

/// Calls `callback(stage, done, total)` when there is one. A callback that raises is reported
/// as unraisable, never allowed to end the computation it watches.
pub fn report(callback: Option<&Py<PyAny>>, stage: &str, done: usize, total: usize) {
    if let Some(callback) = callback {
        Python::attach(|py| {
            if let Err(e) = callback.call1(py, (stage, done, total)) {
                e.write_unraisable(py, None);
            }
        });
    }
}
