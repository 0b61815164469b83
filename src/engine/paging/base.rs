//! The base: a coarse copy of every tile — the archive's first progressive levels of each —
//! fetched with one request before anything else and resident for good, so that wherever the
//! view meets the terrain there is something to draw while the detail streams in.
//!
//! The base's bytes are reserved in the ledger before it is fetched, like any fetch, and stay
//! accounted while it is resident: paging works in what the limit leaves. Tile fetches wait for
//! the first attempt to come back, so on a slow link the base arrives first. A failed fetch is
//! retried under the pager's retry policy, and tiles page as usual meanwhile.

use std::fmt;
use std::sync::Arc;

use super::link::Link;
use super::worker::Job;
use super::{PagerMode, Residency, RetryPolicy, TransferClock};
use crate::db::grid::TileId;
use crate::error::Result;

/// The request for the base.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BaseRequest;

impl fmt::Display for BaseRequest {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("the base")
    }
}

/// The base's key in the retry policy's jitter (no tile has it).
const BASE_KEY: u64 = u64::MAX;

/// Every tile's coarse copy, and the bytes downloaded for them.
pub type BaseTiles<T> = Vec<(TileId, T)>;

/// Where the base stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Not asked for yet, or asked for again from the given update on after `attempts` failed.
    Waiting { attempts: u32, from: u64 },
    /// On its way: attempt number `attempt`, counted from 1.
    InFlight { attempt: u32 },
    /// Resident.
    Arrived,
    /// None: the archive has none, or it does not fit, or every attempt failed.
    Unavailable,
}

/// Fetches the base and hands it to the [`Residency`].
pub struct BaseFetch<T> {
    link: Option<Link<BaseRequest, BaseTiles<T>>>,
    /// Bytes the base will hold, reserved while it is on its way.
    bytes: usize,
    retry: RetryPolicy,
    state: State,
}

impl<T: Send + 'static> BaseFetch<T> {
    /// A fetch of a base of `bytes` (0: there is none) by `job`, over a link of its own in
    /// `mode`.
    pub fn new(
        job: Job<BaseRequest, BaseTiles<T>>,
        bytes: usize,
        mode: PagerMode,
        retry: RetryPolicy,
    ) -> Result<Self> {
        let (link, state) = if bytes == 0 {
            (None, State::Unavailable)
        } else {
            let link = mode.link(job)?;
            (
                Some(link),
                State::Waiting {
                    attempts: 0,
                    from: 0,
                },
            )
        };
        Ok(BaseFetch {
            link,
            bytes,
            retry,
            state,
        })
    }

    /// Times the base's transfer in [`PagerMode::Simulated`], as the tiles' are.
    pub fn set_transfer_clock(&mut self, clock: Arc<dyn TransferClock>) {
        if let Some(link) = &mut self.link {
            link.set_transfer_clock(clock);
        }
    }

    /// Whether tile fetches wait: the base's first attempt has not come back.
    pub fn first_pending(&self) -> bool {
        matches!(
            self.state,
            State::Waiting { attempts: 0, .. } | State::InFlight { attempt: 1 }
        )
    }

    /// Once per update, after [`Residency::begin`]: starts (or retries) the fetch when it is
    /// due, and takes in what arrived, accounted at `tile_bytes` per tile.
    pub fn poll(&mut self, resident: &mut Residency<T>, tile_bytes: impl Fn(&T) -> usize) {
        let Some(link) = &mut self.link else {
            return;
        };
        if let State::Waiting { attempts, from } = self.state
            && resident.now >= from
        {
            if let Err(e) = resident.ledger.set_base(self.bytes) {
                resident.record_error(format!("the base is left out: {e}"));
                self.state = State::Unavailable;
                return;
            }
            self.state = State::InFlight {
                attempt: attempts + 1,
            };
            if let Some((_, result)) = link.start(BaseRequest, resident.time) {
                self.arrive(resident, result, &tile_bytes);
            }
            return;
        }
        if let State::InFlight { .. } = self.state {
            let received = link.receive(resident.time);
            for e in received.errors {
                resident.record_error(e.to_string());
            }
            if received.lost {
                self.arrive(resident, Err(lost()), &tile_bytes);
            }
            for (_, result) in received.arrivals {
                self.arrive(resident, result, &tile_bytes);
            }
        }
    }

    fn arrive(
        &mut self,
        resident: &mut Residency<T>,
        result: Result<(BaseTiles<T>, u64)>,
        tile_bytes: &impl Fn(&T) -> usize,
    ) {
        let State::InFlight { attempt } = self.state else {
            return;
        };
        let accepted = result.and_then(|(tiles, downloaded)| {
            let bytes: usize = tiles.iter().map(|(_, t)| tile_bytes(t)).sum();
            if bytes > self.bytes {
                return Err(crate::error::Error::invalid(
                    "the base",
                    format!("it holds {bytes} bytes, {} were predicted", self.bytes),
                ));
            }
            resident.ledger.set_base(bytes)?;
            Ok((tiles, downloaded))
        });
        match accepted {
            Ok((tiles, downloaded)) => {
                resident.downloaded_bytes += downloaded;
                resident.base = tiles.into_iter().collect();
                self.state = State::Arrived;
            }
            Err(e) => {
                // Releasing a reservation always fits.
                let _ = resident.ledger.set_base(0);
                let outcome = if attempt >= self.retry.max_attempts {
                    self.state = State::Unavailable;
                    "given up"
                } else {
                    self.state = State::Waiting {
                        attempts: attempt,
                        from: resident
                            .now
                            .saturating_add(self.retry.delay(BASE_KEY, attempt)),
                    };
                    "will retry"
                };
                resident.record_error(format!("the base ({outcome}): {e}"));
            }
        }
    }
}

fn lost() -> crate::error::Error {
    crate::error::Error::invalid("the base", "the fetch thread stopped while fetching it")
}
