//! How a pager is set: how its fetches run, its memory limit, its retries and its far field.

use crate::engine::paging::{Job, Link, Request, RetryPolicy};
use crate::error::{Error, Result};

/// How fetches run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PagerMode {
    /// A fetch thread; each update queues fetches so that at most `queue_depth` (at least 1)
    /// are in flight, and takes in what arrived, never waiting.
    Threaded {
        /// Fetches in flight at most.
        queue_depth: usize,
    },
    /// No thread: each update runs up to `fetches_per_update` fetches synchronously, one after
    /// the other (0 pauses fetching). Deterministic.
    Stepped {
        /// Fetches per update at most.
        fetches_per_update: usize,
    },
    /// No thread: fetches run synchronously when planned, at most `queue_depth` (at least 1) in
    /// flight, and each tile arrives at the first update whose simulated time is past the end
    /// of its transfer. Deterministic.
    Simulated {
        /// Fetches in flight at most.
        queue_depth: usize,
    },
}

impl PagerMode {
    /// The link requests go over in this mode, running `job` for each; refuses a queue depth
    /// of 0 in threaded and simulated modes.
    pub fn link<R: Request, T: Send + 'static>(self, job: Job<R, T>) -> Result<Link<R, T>> {
        match self {
            PagerMode::Threaded { queue_depth: 0 } | PagerMode::Simulated { queue_depth: 0 } => {
                Err(Error::setting(
                    "pager queue depth",
                    0,
                    "at least 1 in threaded and simulated modes",
                ))
            }
            _ => Link::new(job, self),
        }
    }

    /// Requests that may start in one update with `fetching` in flight.
    pub fn room(self, fetching: usize) -> usize {
        match self {
            PagerMode::Threaded { queue_depth } | PagerMode::Simulated { queue_depth } => {
                queue_depth.saturating_sub(fetching)
            }
            PagerMode::Stepped { fetches_per_update } => fetches_per_update,
        }
    }
}

/// The time a link spent on transfers, for [`PagerMode::Simulated`]: the pager reads it before
/// and after each fetch, and the difference is that fetch's transfer time.
pub trait TransferClock: Send + Sync {
    /// Seconds of transfers so far (never decreasing).
    fn busy_seconds(&self) -> f64;
}

/// What both pagers are set with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PagerConfig {
    /// The limit on accounted bytes (see [`memory_limit_from_available`](crate::engine::paging::memory_limit_from_available) for a percentage).
    pub memory_limit_bytes: usize,
    /// A viewpoint off the terrain uses the nearest tile; when false, nothing new is fetched
    /// while the viewpoint is off the terrain (what is loaded stays, as cache).
    pub nearest_when_off: bool,
    /// Threaded, stepped or simulated fetching.
    pub mode: PagerMode,
    /// How failed tiles are tried again.
    pub retry: RetryPolicy,
    /// The share of the memory limit the belt pager keeps for the far field, the tiles of the
    /// pyramid's levels above 0 that the frames' cuts ask for (`far.rs`).
    pub far_share: f64,
}

impl PagerConfig {
    /// `memory_limit_bytes` in `mode`, using the nearest tile off the terrain, default retries,
    /// no far field.
    pub fn new(memory_limit_bytes: usize, mode: PagerMode) -> Self {
        PagerConfig {
            memory_limit_bytes,
            nearest_when_off: true,
            mode,
            retry: RetryPolicy::default(),
            far_share: 0.0,
        }
    }
}
