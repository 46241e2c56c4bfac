//! A live object in a loaded library (an error model or a predictor): its handle, destroyed
//! with it, and the record of its last failure.

use std::os::raw::c_void;
use std::sync::Mutex;

use serde_json::Value;

use armcomp_core::Error;

use super::{PluginLibrary, lock, owned};
use crate::abi::{AbiStr, STATUS_OK, signatures};
use crate::flat::abi_str;

/// A handle of a loaded library, owned: dropping it destroys the plugin's object.
pub(super) struct PluginHandle {
    /// The library it lives in (loaded for the rest of the process).
    pub(super) library: &'static PluginLibrary,
    /// The type name, for messages.
    pub(super) model: String,
    raw: *mut c_void,
    destroy: signatures::Destroy,
    /// Why the last call the trait could not fail failed; locked only on a failure and when asked.
    failure: Mutex<Option<String>>,
}

// SAFETY: the library speaks ABI version 4 (checked when it was loaded), under which a handle is
// only read after its creation and every entry point but the destroyer may be called on it from
// any thread, several at once. The destroyer runs in `drop`, which has the only reference.
unsafe impl Send for PluginHandle {}
// SAFETY: as for `Send`.
unsafe impl Sync for PluginHandle {}

impl PluginHandle {
    /// Takes ownership of `raw`, to be destroyed with `destroy`.
    ///
    /// # Safety
    /// `raw` must be a live, non-null handle of `library` that nothing else destroys, and
    /// `destroy` that library's destroyer for its kind.
    pub(super) unsafe fn new(
        library: &'static PluginLibrary,
        model: String,
        raw: *mut c_void,
        destroy: signatures::Destroy,
    ) -> Self {
        PluginHandle {
            library,
            model,
            raw,
            destroy,
            failure: Mutex::new(None),
        }
    }

    /// The raw handle, live while `self` is.
    pub(super) fn raw(&self) -> *mut c_void {
        self.raw
    }

    /// The error of a call that returned `status`.
    pub(super) fn failure(&self, status: i32, what: &str) -> Error {
        self.library.failure(status, what)
    }

    /// Records why a call failed, for [`last_failure`](Self::last_failure).
    pub(super) fn record_failure(&self, e: &Error) {
        *lock(&self.failure) = Some(e.to_string());
    }

    /// The last recorded failure, if any.
    pub(super) fn last_failure(&self) -> Option<String> {
        lock(&self.failure).clone()
    }

    /// The JSON a call hands back as a string (`spec_with`, `save`); `call` gets the raw handle
    /// and the string to fill.
    pub(super) fn json(
        &self,
        what: &str,
        call: impl FnOnce(*mut c_void, &mut AbiStr) -> i32,
    ) -> armcomp_core::Result<Value> {
        let mut text = abi_str("");
        let status = call(self.raw, &mut text);
        if status != STATUS_OK {
            return Err(self.failure(status, what));
        }
        // SAFETY: the string is valid until the next call into the library on this thread.
        let text = unsafe { owned(text) };
        serde_json::from_str(&text).map_err(|e| self.library.unusable(format!("{what} returned invalid JSON: {e}")))
    }
}

impl std::fmt::Debug for PluginHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PluginHandle")
            .field("library", &self.library.file_name)
            .field("model", &self.model)
            .finish()
    }
}

impl Drop for PluginHandle {
    fn drop(&mut self) {
        // SAFETY: the handle is live, owned by `self` alone, and never used again.
        unsafe { (self.destroy)(self.raw) };
    }
}
