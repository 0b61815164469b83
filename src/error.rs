//! The crate's one error type: every message names the file, URL or setting, and the problem.

use std::fmt::Display;
use std::io;

use stripmask_platform::PlatformError;
use stripmask_raster::RasterError;

/// Errors from reading DEMs, building and reading archives, fetching tiles, and from settings
/// that are out of range or do not go together.
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
        "{name}: {tile} level {level} failed its checksum (expected crc32 {expected:08x}, got {actual:08x}) after {attempts} attempt(s)"
    )]
    Checksum {
        /// The archive file or URL.
        name: String,
        /// The tile, as `tile (x, y)` or `tile (x, y) of level k`.
        tile: String,
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
    /// An HTTP request had no whole answer in time: the server accepted and then hung, or
    /// stopped in the middle of a body.
    #[error(
        "{url}: {request} had no whole answer within {seconds} s ({})",
        if *by_deadline { "the run's deadline" } else { "the request timeout" }
    )]
    TimedOut {
        /// The URL requested.
        url: String,
        /// The request, as `GET bytes a-b` or `HEAD`.
        request: String,
        /// Seconds it was given (0 when the deadline had passed before it started).
        seconds: f64,
        /// Whether the run's deadline, not the request timeout, cut it short.
        by_deadline: bool,
    },
    /// The archive behind a file or URL is no longer the one that was opened: it was replaced,
    /// rewritten, truncated or garbled while it was read. Its index no longer describes its
    /// bytes, so reading on would only fail checksums.
    #[error("the archive at {name} changed while it was read ({what}): reopen it")]
    ArchiveChanged {
        /// The file or URL.
        name: String,
        /// What gave it away: a size, a validator, an answer.
        what: String,
    },
    /// Reads of tiles failed their checksums during a run (nothing unverified was drawn): the
    /// archive is damaged, or the link damaged the bytes.
    #[error(
        "{name}: {refused} read(s) of tiles failed their checksums during the run; \
         the archive or the link is damaged"
    )]
    ChecksumsRefused {
        /// The archive file or URL.
        name: String,
        /// Reads refused.
        refused: u64,
    },
    /// A build's output is its input (or its texture image): building would replace what it
    /// reads.
    #[error("{output} is the build's {role} {input}: choose another output")]
    OutputIsInput {
        /// The output path, as given.
        output: String,
        /// What it is: `input` or `texture`.
        role: &'static str,
        /// The input's path, as given.
        input: String,
    },
    /// A read was cancelled by whoever asked for it (the pager, once its tile stopped
    /// mattering) before all its bytes arrived: nothing is wrong with the source.
    #[error("{name}: {request} cancelled after {received} of its bytes arrived")]
    Cancelled {
        /// The file or URL.
        name: String,
        /// The read, as `bytes a-b`.
        request: String,
        /// Bytes that had arrived when it stopped.
        received: u64,
    },
    /// A setting outside the values it may take: a build option, an engine or device setting,
    /// a command-line option.
    #[error("{name} {value}: expected {expected}")]
    InvalidSetting {
        /// The setting, as its user spells it (`tile size`, `--queue`).
        name: &'static str,
        /// The value given.
        value: String,
        /// What it may be, in words.
        expected: String,
    },
    /// Two settings, each valid alone, that do not go together.
    #[error("{first} and {second} do not go together: {reason}")]
    Conflict {
        /// One setting.
        first: &'static str,
        /// The other.
        second: &'static str,
        /// Why not, and what to change.
        reason: String,
    },
    /// A tile's relief does not fit 65535 height quanta: the build needs a larger quantum.
    #[error(
        "{name}: {what} spans {relief} m, more than 65535 quanta of {quantum} m: choose a larger height quantum"
    )]
    HeightRange {
        /// The DEM file.
        name: String,
        /// What spans too much: a tile, or the model, which the pyramid's root covers.
        what: String,
        /// Its highest minus its lowest height, metres.
        relief: f32,
        /// The quantum that was too fine, metres.
        quantum: f32,
    },
    /// A flight drew no terrain at all because its fetches failed: the source is unusable.
    #[error(
        "{name}: no terrain could be drawn in {frames} frame(s): {errors} fetch(es) failed, \
         {in_flight} still on their way when the flight ended; the first failures: {}",
        if first.is_empty() { "none".to_string() } else { first.join("; ") }
    )]
    NothingLoaded {
        /// The archive file or URL.
        name: String,
        /// Frames flown.
        frames: u64,
        /// Failed fetches, of tiles and of the top.
        errors: u64,
        /// The messages of the first failures, each naming its tile.
        first: Vec<String>,
        /// Fetches (tiles and the top) still unanswered at the end, abandoned.
        in_flight: usize,
    },
    /// A command this build of stripmask was made without: a cargo feature left out, or one
    /// for another platform.
    #[error("{command} needs {needs}, which this stripmask was built without")]
    Unsupported {
        /// The command, as typed (`stripmask view`).
        command: &'static str,
        /// What it needs, naming the cargo feature.
        needs: &'static str,
    },
    /// The rasterizer refused its inputs (a framebuffer size, a transform).
    #[error("rasterizer: {0}")]
    Raster(#[from] RasterError),
    /// A presenter or an input device failed: a window, the framebuffer, PNG frames, the GPU.
    #[error(transparent)]
    Platform(#[from] PlatformError),
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

    /// An [`Error::InvalidSetting`]: `name` is `value`, which is not what it may be.
    pub fn setting(name: &'static str, value: impl Display, expected: impl Into<String>) -> Self {
        Error::InvalidSetting {
            name,
            value: value.to_string(),
            expected: expected.into(),
        }
    }

    /// Whether the error is about the settings given (out of range, or not going together)
    /// rather than about a file, a link or a device: on the command line, a usage error.
    pub fn is_usage(&self) -> bool {
        matches!(self, Error::InvalidSetting { .. } | Error::Conflict { .. })
    }

    /// An [`Error::Invalid`] for `name` with the problem in words.
    pub fn invalid(name: impl Into<String>, problem: impl Into<String>) -> Self {
        Error::Invalid {
            name: name.into(),
            problem: problem.into(),
        }
    }
}
