//! A run's view of its source: how many reads were refused for their checksums, and whether the
//! archive changed under it, so that a run that read a damaged or replaced archive can say so
//! and end with an error instead of ending as if nothing had happened.

use std::sync::{Arc, Mutex, OnceLock, PoisonError};

use super::{CancelToken, TileSource};
use crate::error::{Error, Result};

/// What [`Watched`] has seen; shared with whoever reports on the run.
#[derive(Debug, Default)]
pub struct Watch {
    // Locked once per refused read and once per report: a `Mutex`, not an `AtomicU64`,
    // which ARMv5TE lacks.
    refused: Mutex<u64>,
    changed: OnceLock<String>,
}

impl Watch {
    /// Reads whose bytes failed their checksums so far.
    pub fn refused(&self) -> u64 {
        *self.refused.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// What showed that the archive changed, once a read or a check did.
    pub fn changed(&self) -> Option<&str> {
        self.changed.get().map(String::as_str)
    }

    /// Notes what `result` says of the archive.
    fn note<T>(&self, result: Result<T>) -> Result<T> {
        if let Err(Error::ArchiveChanged { what, .. }) = &result {
            let _ = self.changed.set(what.clone());
        }
        result
    }
}

/// A [`TileSource`] whose refused reads and changes are counted in a [`Watch`].
pub struct Watched<S> {
    inner: S,
    watch: Arc<Watch>,
}

impl<S: TileSource> Watched<S> {
    /// `inner`, watched; the watch to read from.
    pub fn new(inner: S) -> (Self, Arc<Watch>) {
        let watch = Arc::new(Watch::default());
        let watched = Watched {
            inner,
            watch: Arc::clone(&watch),
        };
        (watched, watch)
    }
}

impl<S: TileSource> TileSource for Watched<S> {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn size(&self) -> Result<u64> {
        self.watch.note(self.inner.size())
    }

    fn read_range(&self, offset: u64, len: u64) -> Result<Vec<u8>> {
        self.watch.note(self.inner.read_range(offset, len))
    }

    fn read_range_cancellable(
        &self,
        offset: u64,
        len: u64,
        cancel: &CancelToken,
    ) -> Result<Vec<u8>> {
        self.watch
            .note(self.inner.read_range_cancellable(offset, len, cancel))
    }

    fn is_remote(&self) -> bool {
        self.inner.is_remote()
    }

    fn checksum_failed(&self) -> Result<()> {
        *self
            .watch
            .refused
            .lock()
            .unwrap_or_else(PoisonError::into_inner) += 1;
        self.watch.note(self.inner.checksum_failed())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Bytes that fail every checksum, from an archive that changed once asked.
    struct Changing;

    impl TileSource for Changing {
        fn name(&self) -> &str {
            "x.smdb"
        }
        fn size(&self) -> Result<u64> {
            Ok(10)
        }
        fn read_range(&self, _: u64, len: u64) -> Result<Vec<u8>> {
            Ok(vec![0; len as usize])
        }
        fn checksum_failed(&self) -> Result<()> {
            Err(Error::ArchiveChanged {
                name: "x.smdb".into(),
                what: "its size went from 10 to 4 bytes".into(),
            })
        }
    }

    #[test]
    fn refusals_are_counted_and_the_first_change_kept() {
        let (source, watch) = Watched::new(Changing);
        source.read_range(0, 4).unwrap();
        assert_eq!((watch.refused(), watch.changed()), (0, None));
        assert!(matches!(
            source.checksum_failed(),
            Err(Error::ArchiveChanged { .. })
        ));
        source.checksum_failed().unwrap_err();
        assert_eq!(watch.refused(), 2);
        assert_eq!(watch.changed(), Some("its size went from 10 to 4 bytes"));
    }
}
