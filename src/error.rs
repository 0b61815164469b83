//! The crate's one error type: every message names the file (or URL) and the problem.

use std::io;

/// Errors from reading DEMs, building and reading archives, and fetching tiles.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An operating-system I/O error on a named file or URL.
    #[error("{name}: {source}")]
    Io {
        /// The file or URL.
        name: String,
        /// The underlying error.
        #[source]
        source: io::Error,
    },
    /// The content of a named file or URL is malformed, truncated or unsupported.
    #[error("{name}: {problem}")]
    Invalid {
        /// The file or URL.
        name: String,
        /// What is wrong, in words.
        problem: String,
    },
    /// A tile's progressive chunk does not match the checksum in the index, after all retries.
    #[error(
        "{name}: tile {tile} level {level} failed its checksum (expected crc32 {expected:08x}, got {actual:08x}) after {attempts} attempt(s)"
    )]
    Checksum {
        /// The archive file or URL.
        name: String,
        /// The tile's index in the archive.
        tile: usize,
        /// The progressive level whose chunk failed (the first that did).
        level: usize,
        /// The crc32 stored in the index.
        expected: u32,
        /// The crc32 of the bytes received last.
        actual: u32,
        /// How many times the tile was fetched.
        attempts: u32,
    },
    /// An HTTP request failed (transport error or an unexpected status).
    #[error("{url}: {problem}")]
    Http {
        /// The URL requested.
        url: String,
        /// What went wrong.
        problem: String,
    },
    /// The command line or build options are inconsistent.
    #[error("{0}")]
    Usage(String),
}

/// Result with the crate's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// An [`Error::Io`] for `name`.
    pub fn io(name: impl Into<String>, source: io::Error) -> Self {
        Error::Io {
            name: name.into(),
            source,
        }
    }

    /// An [`Error::Invalid`] for `name` with the problem in words.
    pub fn invalid(name: impl Into<String>, problem: impl Into<String>) -> Self {
        Error::Invalid {
            name: name.into(),
            problem: problem.into(),
        }
    }
}
