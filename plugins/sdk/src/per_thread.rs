//! Buffers reused between calls, one set per thread. Calls on one plugin handle run on several
//! threads at once (ABI version 4), so what a call writes cannot live in the handle, and a lock
//! around it would serialise them.

use std::cell::Cell;
use std::thread::LocalKey;

/// Runs `f` with this thread's buffers from `key` (default ones on the thread's first call),
/// then keeps them for its next call. Should `f` panic, the buffers are dropped and the next
/// call starts afresh.
pub(crate) fn with_buffers<T: Default, R>(key: &'static LocalKey<Cell<Option<T>>>, f: impl FnOnce(&mut T) -> R) -> R {
    let mut buffers = key.take().unwrap_or_default();
    let result = f(&mut buffers);
    key.set(Some(buffers));
    result
}
