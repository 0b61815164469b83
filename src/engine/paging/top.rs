//! The top: the root of the pyramid and the levels below it that the archive stores together —
//! a coarse copy of the whole terrain in a few tiles — fetched with one request before
//! anything else and resident for good, so that wherever the view meets the terrain there is
//! something to draw while the detail streams in, whatever the model's size.
//!
//! The top's bytes are reserved in the ledger before it is fetched, like any fetch, and stay
//! accounted while it is resident: paging works in what the limit leaves. Tile fetches wait for
//! the first attempt to come back, so on a slow link the top arrives first. A failed fetch is
//! retried under the pager's retry policy, and tiles page as usual meanwhile.

use std::fmt;
use std::sync::Arc;

use super::link::Link;
use super::worker::Job;
use super::{PagerMode, Residency, RetryPolicy, TransferClock};
use crate::db::grid::TileId;
use crate::error::Result;

/// The request for the top.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TopRequest;

impl fmt::Display for TopRequest {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("the top")
    }
}

/// The top's key in the retry policy's jitter (no tile has it).
const TOP_KEY: u64 = u64::MAX;

/// The top's tiles.
pub type TopTiles<T> = Vec<(TileId, T)>;

/// Where the top stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Not asked for yet, or asked for again from the given update on after `attempts` failed.
    Waiting { attempts: u32, from: u64 },
    /// On its way: attempt number `attempt`, counted from 1.
    InFlight { attempt: u32 },
    /// Resident.
    Arrived,
    /// None: it is not kept, or it does not fit, or every attempt failed.
    Unavailable,
}

/// Fetches the top and hands it to the [`Residency`].
pub struct TopFetch<T> {
    link: Option<Link<TopRequest, TopTiles<T>>>,
    /// Bytes the top will hold, reserved while it is on its way.
    bytes: usize,
    retry: RetryPolicy,
    state: State,
}

impl<T: Send + 'static> TopFetch<T> {
    /// A fetch of a top of `bytes` (0: none is kept) by `job`, over a link of its own in
    /// `mode`.
    pub fn new(
        job: Job<TopRequest, TopTiles<T>>,
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
        Ok(TopFetch {
            link,
            bytes,
            retry,
            state,
        })
    }

    /// Times the top's transfer in [`PagerMode::Simulated`], as the tiles' are.
    pub fn set_transfer_clock(&mut self, clock: Arc<dyn TransferClock>) {
        if let Some(link) = &mut self.link {
            link.set_transfer_clock(clock);
        }
    }

    /// Whether tile fetches wait: the top's first attempt has not come back.
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
            if let Err(e) = resident.ledger.set_top(self.bytes) {
                resident.record_error(format!("the top is left out: {e}"));
                self.state = State::Unavailable;
                return;
            }
            self.state = State::InFlight {
                attempt: attempts + 1,
            };
            if let Some((_, result)) = link.start(TopRequest, resident.time) {
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
        result: Result<(TopTiles<T>, u64)>,
        tile_bytes: &impl Fn(&T) -> usize,
    ) {
        let State::InFlight { attempt } = self.state else {
            return;
        };
        let accepted = result.and_then(|(tiles, downloaded)| {
            let bytes: usize = tiles.iter().map(|(_, t)| tile_bytes(t)).sum();
            if bytes > self.bytes {
                return Err(crate::error::Error::invalid(
                    "the top",
                    format!("it holds {bytes} bytes, {} were predicted", self.bytes),
                ));
            }
            resident.ledger.set_top(bytes)?;
            Ok((tiles, downloaded))
        });
        match accepted {
            Ok((tiles, downloaded)) => {
                resident.downloaded_bytes += downloaded;
                resident.set_top(tiles);
                self.state = State::Arrived;
            }
            Err(e) => {
                // Releasing a reservation always fits.
                let _ = resident.ledger.set_top(0);
                let outcome = if attempt >= self.retry.max_attempts {
                    self.state = State::Unavailable;
                    "given up"
                } else {
                    self.state = State::Waiting {
                        attempts: attempt,
                        from: resident
                            .now
                            .saturating_add(self.retry.delay(TOP_KEY, attempt)),
                    };
                    "will retry"
                };
                resident.record_error(format!("the top ({outcome}): {e}"));
            }
        }
    }
}

fn lost() -> crate::error::Error {
    crate::error::Error::invalid("the top", "the fetch thread stopped while fetching it")
}
