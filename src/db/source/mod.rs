//! Where archive bytes come from: one trait, three implementations.
//!
//! [`TileSource`] reads byte ranges of an archive; [`crate::db::archive::ArchiveReader`] turns them
//! into a header, an index and verified tiles. [`file::FileSource`] reads a local file with
//! positioned reads, `http::HttpSource` (the `http` feature) fetches the same file with HTTP range
//! requests from any static server, and [`throttle::SimulatedLink`] wraps either with latency,
//! bandwidth and drops.
//! A read can be cancelled while it runs ([`CancelToken`]): an HTTP range stops downloading.
//! Both sources pin the archive they opened: a file or URL whose archive changed under them
//! fails every read after with [`Error::ArchiveChanged`], and [`watch::Watched`] counts what
//! a run's reads were refused for.

mod cancel;
pub mod file;
pub mod http;
pub mod throttle;
pub mod watch;

pub use cancel::CancelToken;

use crate::error::{Error, Result};

/// Random access to the bytes of one archive.
pub trait TileSource: Send + Sync {
    /// The file path or URL, for messages.
    fn name(&self) -> &str;
    /// Total length in bytes.
    fn size(&self) -> Result<u64>;
    /// Exactly `len` bytes starting at `offset`.
    fn read_range(&self, offset: u64, len: u64) -> Result<Vec<u8>>;
    /// [`TileSource::read_range`] that stops with [`Error::Cancelled`] once `cancel` is raised,
    /// where the source can stop a read under way (HTTP: between pieces of the body, closing
    /// the connection). By default a read is refused if cancelled before it starts and runs to
    /// its end otherwise: a local read is over too soon to be worth stopping.
    fn read_range_cancellable(
        &self,
        offset: u64,
        len: u64,
        cancel: &CancelToken,
    ) -> Result<Vec<u8>> {
        if cancel.is_cancelled() {
            return Err(cancelled(self.name(), offset, len, 0));
        }
        self.read_range(offset, len)
    }
    /// Whether the bytes come over a network, where waiting before a retry can help; a local
    /// file answers the same at once.
    fn is_remote(&self) -> bool {
        false
    }
    /// Told that bytes this source gave failed their checksum: [`Error::ArchiveChanged`] when
    /// the source finds that the archive is no longer the one it opened, `Ok` when it cannot
    /// tell (the bytes were damaged on their way, or where they are kept).
    fn checksum_failed(&self) -> Result<()> {
        Ok(())
    }
}

impl<S: TileSource + ?Sized> TileSource for Box<S> {
    fn name(&self) -> &str {
        (**self).name()
    }
    fn size(&self) -> Result<u64> {
        (**self).size()
    }
    fn read_range(&self, offset: u64, len: u64) -> Result<Vec<u8>> {
        (**self).read_range(offset, len)
    }
    fn read_range_cancellable(
        &self,
        offset: u64,
        len: u64,
        cancel: &CancelToken,
    ) -> Result<Vec<u8>> {
        (**self).read_range_cancellable(offset, len, cancel)
    }
    fn is_remote(&self) -> bool {
        (**self).is_remote()
    }
    fn checksum_failed(&self) -> Result<()> {
        (**self).checksum_failed()
    }
}

/// The [`Error::Cancelled`] of the read of `len` bytes at `offset` from `name`, stopped after
/// `received` of them.
pub fn cancelled(name: &str, offset: u64, len: u64, received: u64) -> Error {
    Error::Cancelled {
        name: name.to_string(),
        request: format!("bytes {offset}+{len}"),
        received,
    }
}

/// Opens a local path or an `http://` URL (with the `http` feature; `https://` with the `https`
/// feature) as a source, with the default [`http::HttpOptions`].
pub fn open(file_or_url: &str) -> Result<Box<dyn TileSource>> {
    open_with(file_or_url, http::HttpOptions::default())
}

/// [`open`], with `http` bounding the time of requests when it is a URL.
pub fn open_with(file_or_url: &str, http: http::HttpOptions) -> Result<Box<dyn TileSource>> {
    if file_or_url.starts_with("https://") && !cfg!(feature = "https") {
        return Err(needs_feature(file_or_url, "https"));
    }
    if file_or_url.starts_with("http://") || file_or_url.starts_with("https://") {
        remote(file_or_url, http)
    } else {
        Ok(Box::new(file::FileSource::open(std::path::Path::new(
            file_or_url,
        ))?))
    }
}

/// The archive at `url`, read with HTTP range requests.
#[cfg(feature = "http")]
fn remote(url: &str, options: http::HttpOptions) -> Result<Box<dyn TileSource>> {
    Ok(Box::new(http::HttpSource::with_options(url, options)))
}

/// Without the HTTP client, a URL is refused.
#[cfg(not(feature = "http"))]
fn remote(url: &str, _: http::HttpOptions) -> Result<Box<dyn TileSource>> {
    Err(needs_feature(url, "http"))
}

/// The error of a URL whose scheme needs a cargo feature this build lacks.
fn needs_feature(url: &str, feature: &str) -> Error {
    let scheme = url.split_once("://").map_or(url, |(scheme, _)| scheme);
    Error::Http {
        url: url.to_string(),
        problem: format!("{scheme}:// needs stripmask built with `--features {feature}`"),
    }
}

#[cfg(all(test, not(feature = "http")))]
mod tests {
    #[test]
    fn a_url_without_the_http_client_names_the_url_and_the_feature() {
        let url = "http://example.invalid/a.smdb";
        let e = super::open(url).err().expect("refused").to_string();
        assert!(e.contains(url) && e.contains("--features http"), "{e}");
    }
}
