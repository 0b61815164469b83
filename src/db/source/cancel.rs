//! A signal that a read is no longer wanted. The pager raises it when the tile a request was
//! for stops mattering; a source that reads a body piece by piece checks it between pieces and
//! stops there, so an HTTP range under way is not downloaded to its end.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

/// One read's cancellation flag, shared by whoever may cancel it and the read itself: clones
/// share the flag.
#[derive(Clone, Debug, Default)]
pub struct CancelToken(Arc<AtomicBool>);

impl CancelToken {
    /// A flag not raised.
    pub fn new() -> Self {
        CancelToken::default()
    }

    /// Asks the read to stop; it may still finish if it is almost done.
    pub fn cancel(&self) {
        self.0.store(true, Ordering::Relaxed);
    }

    /// Whether [`CancelToken::cancel`] was called on this flag or a clone of it.
    pub fn is_cancelled(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }

    /// Whether `other` is this flag or a clone of it (not merely a flag in the same state).
    pub fn is(&self, other: &CancelToken) -> bool {
        Arc::ptr_eq(&self.0, &other.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clones_share_the_flag_and_only_they_are_the_same_token() {
        let a = CancelToken::new();
        let b = a.clone();
        let other = CancelToken::new();
        assert!(!b.is_cancelled());
        a.cancel();
        assert!(b.is_cancelled() && !other.is_cancelled());
        assert!(a.is(&b) && !a.is(&other));
    }
}
