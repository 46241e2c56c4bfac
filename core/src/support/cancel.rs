//! Cancellation of one computation, passed in with its parameters. Long computations
//! (calibration iterations, diagnosis rounds, predictor training, batches of targets) check
//! their token between steps and return [`Error::Interrupted`], so that a host that cannot
//! kill a thread (a Python session's Ctrl-C) ends the computation it started, and only that
//! one: computations with different tokens never stop each other.

use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use crate::error::{Error, Result};

/// A cancellation token. Clones share the requests; the default token is never cancelled and
/// costs nothing to check.
///
/// A search that a stop request ended may still fit what it found: it does so with
/// [`renewed`](Self::renewed), a token that only a further request stops.
#[derive(Debug, Clone, Default)]
pub struct Cancel(Option<(Arc<AtomicUsize>, usize)>);

impl Cancel {
    /// A token that [`cancel`](Self::cancel) can set.
    pub fn new() -> Self {
        Cancel(Some((Arc::new(AtomicUsize::new(0)), 0)))
    }

    /// Asks every computation holding this token (or a clone, or a renewal) to stop at its next
    /// check; a no-op on the default token.
    pub fn cancel(&self) {
        if let Some((requests, _)) = &self.0 {
            requests.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Whether a stop is requested (for loops that end early and let their caller
    /// [`check`](Self::check)).
    pub fn is_cancelled(&self) -> bool {
        self.0
            .as_ref()
            .is_some_and(|(requests, seen)| requests.load(Ordering::Relaxed) > *seen)
    }

    /// `Err(Error::Interrupted)` once a stop is requested.
    pub fn check(&self) -> Result<()> {
        if self.is_cancelled() {
            Err(Error::Interrupted)
        } else {
            Ok(())
        }
    }

    /// A token sharing this one's requests that is not stopped by those made so far: for the
    /// last step of a search a request ended (fitting the best choice found), which the next
    /// request stops.
    pub fn renewed(&self) -> Self {
        Cancel(
            self.0
                .as_ref()
                .map(|(requests, _)| (Arc::clone(requests), requests.load(Ordering::Relaxed))),
        )
    }

    /// A token for the last step of a search (fitting the choice it found): when a request
    /// ended the search, as [`renewed`](Self::renewed); when none did, one that the first
    /// request does not stop either, so that a stop asked for during that step still gets its
    /// result (the caller sees the request on `self`). Only a further request stops it.
    pub fn for_last_step(&self) -> Self {
        let pending = usize::from(!self.is_cancelled());
        Cancel(
            self.0
                .as_ref()
                .map(|(requests, _)| (Arc::clone(requests), requests.load(Ordering::Relaxed) + pending)),
        )
    }
}

/// Two tokens are equal when the same requests stop them (or both are the default): settings
/// that hold one compare equal only when they would stop together.
impl PartialEq for Cancel {
    fn eq(&self, other: &Self) -> bool {
        match (&self.0, &other.0) {
            (None, None) => true,
            (Some((a, m)), Some((b, n))) => Arc::ptr_eq(a, b) && m == n,
            _ => false,
        }
    }
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_token_stops_its_clones_and_no_other() {
        let (a, b) = (Cancel::new(), Cancel::new());
        let a_clone = a.clone();
        a.cancel();
        assert!(a_clone.is_cancelled() && matches!(a_clone.check(), Err(Error::Interrupted)));
        assert!(!b.is_cancelled() && b.check().is_ok());
        let never = Cancel::default();
        never.cancel();
        assert!(!never.is_cancelled());
        assert!(a == a_clone && a != b && never == Cancel::default());
    }

    #[test]
    fn a_renewed_token_stops_only_at_the_next_request() {
        let a = Cancel::new();
        a.cancel();
        let renewed = a.renewed();
        assert!(a.is_cancelled() && !renewed.is_cancelled() && renewed != a);
        a.cancel();
        assert!(renewed.is_cancelled());
        assert!(!Cancel::default().renewed().is_cancelled());
    }

    #[test]
    fn a_last_steps_token_outlives_the_first_request_only() {
        // No request yet: the first one (made during the last step) leaves it running.
        let a = Cancel::new();
        let last = a.for_last_step();
        a.cancel();
        assert!(a.is_cancelled() && !last.is_cancelled());
        a.cancel();
        assert!(last.is_cancelled());
        // A request ended the search: the next one stops the last step.
        let b = Cancel::new();
        b.cancel();
        let last = b.for_last_step();
        assert!(!last.is_cancelled());
        b.cancel();
        assert!(last.is_cancelled());
        assert!(!Cancel::default().for_last_step().is_cancelled());
    }
}
