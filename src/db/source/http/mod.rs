//! An archive behind any static HTTP server, read with `Range: bytes=a-b` requests by
//! `HttpSource` (the `http` feature), and the options that bound its requests, which a flight
//! carries whether or not the client is built.
//!
//! Every request, connection and whole body included, ends within [`HttpOptions::timeout`]
//! and never after [`HttpOptions::deadline`]: a server that accepts and never answers, or stops
//! in the middle of a body, costs one timeout, and a run with a deadline ends on time. The
//! source itself never retries; the reader and the pager do, backing off ([`crate::db::backoff`]).
//! A read whose [`super::CancelToken`] is raised stops between pieces of its body and closes its
//! connection, unless less than `FINISH_BELOW` bytes are left.
//!
//! A source pins the archive it opened: the first answer's total size and validators (`ETag`,
//! `Last-Modified`) are kept, every range request carries them as a precondition (`If-Match`
//! for a strong `ETag`, else `If-Unmodified-Since`), and every answer's `Content-Range` total
//! and validators are compared with them. When they differ, or the server answers 412, the
//! archive changed under the reader: this read and every later one fail with
//! [`crate::error::Error::ArchiveChanged`] instead of fetching bytes the index no longer
//! describes.

#[cfg(feature = "http")]
mod client;

use std::time::{Duration, Instant};

#[cfg(feature = "http")]
pub use client::{BODY_PIECE, FINISH_BELOW, HttpSource};

/// How long requests may take.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HttpOptions {
    /// The time limit of one request: connecting, the answer's head and its whole body.
    pub timeout: Duration,
    /// The instant by which every request must have ended, whatever its timeout: a request
    /// that would outlive it is cut short there, and one asked for after it fails at once.
    pub deadline: Option<Instant>,
}

impl Default for HttpOptions {
    /// Ten seconds a request, no deadline.
    fn default() -> Self {
        HttpOptions {
            timeout: Duration::from_secs(10),
            deadline: None,
        }
    }
}
