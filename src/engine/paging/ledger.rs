//! The accounting of the pagers: every tile that holds or will hold memory, its loaded copy, its
//! fetch in flight and its failures, and the accounted bytes under a fixed limit. A fetch's
//! bytes are accounted when it is planned, before it starts, so the accounted memory never
//! exceeds the limit, not even transiently.

use std::collections::BTreeMap;

use crate::db::backoff::Backoff;
use crate::db::grid::{Grid, Pyramid, TileId};
use crate::error::{Error, Result};

/// A resident copy of a tile: the bytes it holds and the ring its detail serves.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Loaded {
    /// Accounted bytes.
    pub bytes: usize,
    /// The belt distance the copy was loaded for (or shrunk to).
    pub ring: u32,
}

/// Bytes accounted for a fetch in flight, and the ring it was planned for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reservation {
    /// Bytes the loader predicted the tile will hold.
    pub bytes: usize,
    /// The belt distance the tile is fetched for.
    pub ring: u32,
    /// Whether the fetch adds to the resident copy (a finer progressive level) instead of
    /// replacing it: `bytes` is then the growth, not the whole.
    pub adds: bool,
}

/// Why a tile is not fetched although it is missing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Failure {
    /// It failed and waits until the given update before it is tried again.
    Waiting {
        /// The update number from which the tile may be fetched again.
        retry_at: u64,
    },
    /// It failed too often: it is left out (a hole) and counts as complete for its belt.
    GaveUp,
}

/// What the ledger knows about one tile.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Record {
    /// The resident copy, if any.
    pub loaded: Option<Loaded>,
    /// The fetch in flight, if any (an upgrade when `loaded` is also set).
    pub fetch: Option<Reservation>,
    /// How many fetches of this tile failed.
    pub failures: u32,
    /// The failure state, if the tile failed.
    pub failure: Option<Failure>,
}

impl Record {
    fn is_empty(&self) -> bool {
        self.loaded.is_none() && self.fetch.is_none() && self.failures == 0
    }
}

/// How often a failed tile (or the top) is tried again: the one place that retries a fetch,
/// in updates of the pager, backing off exponentially with jitter ([`Backoff`]). The jitter is
/// drawn from the seed and the tile, so the deterministic modes stay deterministic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RetryPolicy {
    /// Fetches of one tile (first try included) before it is given up.
    pub max_attempts: u32,
    /// Updates to wait after the first failure, at most (each later wait may double).
    pub delay_updates: u64,
    /// Updates to wait after any failure, at most.
    pub max_delay_updates: u64,
    /// Seeds the jitter.
    pub seed: u64,
}

impl Default for RetryPolicy {
    /// Four attempts, waiting up to 8, 16 and 32 updates between them (about 1, 2 and 4 s at
    /// 7 frames a second).
    fn default() -> Self {
        RetryPolicy {
            max_attempts: 4,
            delay_updates: 8,
            max_delay_updates: 240,
            seed: 17,
        }
    }
}

impl RetryPolicy {
    /// Updates to wait after the `failures`-th failure (from 1) of what `key` names.
    pub fn delay(&self, key: u64, failures: u32) -> u64 {
        let backoff = Backoff {
            first: self.delay_updates as f64,
            max: self.max_delay_updates as f64,
            seed: self.seed,
        };
        backoff.wait(key, failures).round() as u64
    }

    /// [`RetryPolicy::delay`] for tile `id`.
    pub fn tile_delay(&self, id: TileId, failures: u32) -> u64 {
        let key = (u64::from(id.x) << 32) | u64::from(id.y);
        self.delay(key ^ (u64::from(id.level) << 58), failures)
    }
}

/// The accounting of Algorithm 1: every tile that holds or will hold memory, the accounted bytes
/// (the top, the index pages, held copies and reservations of fetches in flight) and their
/// peak, under a fixed limit.
#[derive(Clone, Debug)]
pub struct Ledger {
    pyramid: Pyramid,
    limit: usize,
    retry: RetryPolicy,
    records: BTreeMap<TileId, Record>,
    /// Bytes of the top (the pyramid's coarsest levels), or of its fetch in flight.
    top: usize,
    /// Bytes set aside for the archive's index pages.
    index: usize,
    memory: usize,
    peak: usize,
}

impl Ledger {
    /// An empty ledger for the tiles of `pyramid` under `limit` accounted bytes.
    pub fn new(pyramid: Pyramid, limit: usize, retry: RetryPolicy) -> Self {
        Ledger {
            pyramid,
            limit,
            retry,
            records: BTreeMap::new(),
            top: 0,
            index: 0,
            memory: 0,
            peak: 0,
        }
    }

    /// Bytes accounted for the top.
    pub fn top(&self) -> usize {
        self.top
    }

    /// Bytes set aside for the index pages.
    pub fn index(&self) -> usize {
        self.index
    }

    /// Accounts `bytes` for the top instead of what it had: a reservation before it is
    /// fetched, what it holds once it arrived or was refit, 0 when it is dropped. Fails (and
    /// changes nothing) when that would take the accounted bytes over the limit.
    pub fn set_top(&mut self, bytes: usize) -> Result<()> {
        self.top = self.set_fixed(self.top, bytes, "the top")?;
        Ok(())
    }

    /// Sets `bytes` aside for the archive's index pages instead of what was set aside. Fails
    /// (and changes nothing) when that would take the accounted bytes over the limit.
    pub fn set_index(&mut self, bytes: usize) -> Result<()> {
        self.index = self.set_fixed(self.index, bytes, "the index pages")?;
        Ok(())
    }

    /// Accounts `bytes` instead of `old` for `what`, one of the fixed reservations; returns
    /// `bytes`, or fails when they do not fit.
    fn set_fixed(&mut self, old: usize, bytes: usize, what: &str) -> Result<usize> {
        let memory = (self.memory - old)
            .checked_add(bytes)
            .filter(|&m| m <= self.limit)
            .ok_or_else(|| {
                Error::invalid(
                    what,
                    format!(
                        "{bytes} bytes do not fit: {} of {} bytes are accounted without them",
                        self.memory - old,
                        self.limit
                    ),
                )
            })?;
        self.memory = memory;
        self.peak = self.peak.max(memory);
        Ok(bytes)
    }

    /// The grid of level-0 tiles, where Algorithm 1's belts lie.
    pub fn grid(&self) -> Grid {
        self.pyramid.grid(0)
    }

    /// The pyramid of tiles.
    pub fn pyramid(&self) -> &Pyramid {
        &self.pyramid
    }

    /// The memory limit in bytes.
    pub fn limit(&self) -> usize {
        self.limit
    }

    /// Accounted bytes: the top, the index pages, held copies and reservations of fetches in
    /// flight.
    pub fn memory(&self) -> usize {
        self.memory
    }

    /// The highest [`Ledger::memory`] so far.
    pub fn peak(&self) -> usize {
        self.peak
    }

    /// The record of `id` (empty when the ledger knows nothing of it).
    pub fn record(&self, id: TileId) -> Record {
        self.records.get(&id).copied().unwrap_or_default()
    }

    /// Every tile the ledger knows, row-major.
    pub fn records(&self) -> impl Iterator<Item = (TileId, &Record)> {
        self.records.iter().map(|(id, r)| (*id, r))
    }

    /// Fetches in flight.
    pub fn fetching(&self) -> usize {
        self.records.values().filter(|r| r.fetch.is_some()).count()
    }

    /// Tiles whose last fetch failed (waiting for a retry, or given up).
    pub fn failed_tiles(&self) -> usize {
        self.records
            .values()
            .filter(|r| r.failure.is_some())
            .count()
    }

    /// Tiles with a resident copy.
    pub fn resident(&self) -> usize {
        self.records.values().filter(|r| r.loaded.is_some()).count()
    }

    /// Accounts a planned fetch. Fails (and changes nothing) if the tile already has a fetch in
    /// flight or the reservation would exceed the limit.
    pub fn reserve(&mut self, fetch: Fetch) -> Result<()> {
        self.reserve_as(fetch, false)
    }

    /// Accounts a fetch that adds `fetch.bytes` to the tile's resident copy (a refinement: the
    /// copy stays and grows when it arrives). Fails like [`Ledger::reserve`], and when the tile
    /// holds no copy.
    pub fn reserve_addition(&mut self, fetch: Fetch) -> Result<()> {
        if self.record(fetch.id).loaded.is_none() {
            return Err(Error::invalid(
                fetch.id.to_string(),
                "cannot refine it: it holds no resident copy",
            ));
        }
        self.reserve_as(fetch, true)
    }

    fn reserve_as(&mut self, fetch: Fetch, adds: bool) -> Result<()> {
        let record = self.record(fetch.id);
        let memory = self
            .memory
            .checked_add(fetch.bytes)
            .filter(|&m| m <= self.limit);
        let (Some(memory), None) = (memory, record.fetch) else {
            return Err(Error::invalid(
                fetch.id.to_string(),
                format!(
                    "cannot reserve {} bytes for a fetch ({} of {} bytes accounted, fetch in flight: {})",
                    fetch.bytes,
                    self.memory,
                    self.limit,
                    record.fetch.is_some()
                ),
            ));
        };
        self.records.entry(fetch.id).or_default().fetch = Some(Reservation {
            bytes: fetch.bytes,
            ring: fetch.ring,
            adds,
        });
        self.memory = memory;
        self.peak = self.peak.max(memory);
        Ok(())
    }

    /// A fetch arrived and the tile now holds `bytes`: the new copy replaces the old one, if
    /// any (or, for a [`Ledger::reserve_addition`], the grown copy does). Fails (and releases
    /// the reservation, counting a failure) when the tile holds more than was reserved (plus
    /// the old copy, for an addition), since accounting it could overspend the limit; the
    /// caller drops the new copy then.
    pub fn arrive(&mut self, id: TileId, bytes: usize, now: u64) -> Result<()> {
        let record = self.record(id);
        let Some(reservation) = record.fetch else {
            return Err(Error::invalid(
                id.to_string(),
                "it arrived without a fetch in flight",
            ));
        };
        let old = record.loaded.map_or(0, |h| h.bytes);
        let allowed = reservation.bytes + if reservation.adds { old } else { 0 };
        if bytes > allowed {
            self.fail(id, now);
            return Err(Error::invalid(
                id.to_string(),
                format!(
                    "the loader holds {bytes} bytes, {allowed} were predicted for ring {}",
                    reservation.ring
                ),
            ));
        }
        self.memory = self.memory - reservation.bytes - old + bytes;
        let entry = self.records.entry(id).or_default();
        entry.fetch = None;
        entry.loaded = Some(Loaded {
            bytes,
            ring: reservation.ring,
        });
        entry.failures = 0;
        entry.failure = None;
        Ok(())
    }

    /// A fetch of `id` failed: releases its reservation and counts the failure under the retry
    /// policy (the tile waits, or is given up after the last attempt).
    pub fn fail(&mut self, id: TileId, now: u64) {
        let entry = self.records.entry(id).or_default();
        if let Some(reservation) = entry.fetch.take() {
            self.memory -= reservation.bytes;
        }
        entry.failures += 1;
        entry.failure = Some(if entry.failures >= self.retry.max_attempts {
            Failure::GaveUp
        } else {
            Failure::Waiting {
                retry_at: now.saturating_add(self.retry.tile_delay(id, entry.failures)),
            }
        });
    }

    /// The fetch of `id` in flight was cancelled: its reservation is released, and nothing is
    /// counted against the tile (it may be asked for again at once).
    pub fn cancel(&mut self, id: TileId) {
        if let Some(entry) = self.records.get_mut(&id) {
            if let Some(reservation) = entry.fetch.take() {
                self.memory -= reservation.bytes;
            }
            if entry.is_empty() {
                self.records.remove(&id);
            }
        }
    }

    /// Every fetch in flight failed (the fetch thread stopped with them).
    pub fn fail_in_flight(&mut self, now: u64) {
        let in_flight: Vec<TileId> = self
            .records
            .iter()
            .filter(|(_, r)| r.fetch.is_some())
            .map(|(&id, _)| id)
            .collect();
        for id in in_flight {
            self.fail(id, now);
        }
    }

    /// Makes failed tiles whose wait is over eligible for a new attempt.
    pub fn tick(&mut self, now: u64) {
        for record in self.records.values_mut() {
            if matches!(record.failure, Some(Failure::Waiting { retry_at }) if retry_at <= now) {
                record.failure = None;
            }
        }
    }

    /// Drops the resident copy of `id`; returns the bytes it held. A copy whose upgrade was
    /// given up takes its failures with it: the tile may be fetched afresh later.
    pub fn evict(&mut self, id: TileId) -> usize {
        let Some(record) = self.records.get_mut(&id) else {
            return 0;
        };
        let bytes = record.loaded.take().map_or(0, |h| h.bytes);
        self.memory -= bytes;
        if record.fetch.is_none() && bytes > 0 {
            record.failures = 0;
            record.failure = None;
        }
        if record.is_empty() {
            self.records.remove(&id);
        }
        bytes
    }

    /// A resident copy now holds `bytes`, more or fewer than before (the loader's settings
    /// changed, see `Pager::refit`). Fails (and changes nothing) when that would take the
    /// accounted bytes over the limit.
    pub fn resize_loaded(&mut self, id: TileId, bytes: usize) -> Result<()> {
        let Some(held) = self.records.get(&id).and_then(|r| r.loaded) else {
            return Err(Error::invalid(
                id.to_string(),
                "it was resized but is not resident",
            ));
        };
        self.resize(id, held.bytes, bytes, "resident copy")?;
        if let Some(h) = self.records.get_mut(&id).and_then(|r| r.loaded.as_mut()) {
            h.bytes = bytes;
        }
        Ok(())
    }

    /// The fetch of `id` in flight will hold `bytes` instead of what was reserved. Fails (and
    /// changes nothing) when that would take the accounted bytes over the limit.
    pub fn resize_reservation(&mut self, id: TileId, bytes: usize) -> Result<()> {
        let Some(fetch) = self.records.get(&id).and_then(|r| r.fetch) else {
            return Err(Error::invalid(
                id.to_string(),
                "it has no fetch in flight to resize",
            ));
        };
        self.resize(id, fetch.bytes, bytes, "reservation")?;
        if let Some(f) = self.records.get_mut(&id).and_then(|r| r.fetch.as_mut()) {
            f.bytes = bytes;
        }
        Ok(())
    }

    fn resize(&mut self, id: TileId, old: usize, new: usize, what: &str) -> Result<()> {
        let memory = self.memory - old + new;
        if memory > self.limit {
            return Err(Error::invalid(
                id.to_string(),
                format!(
                    "its {what} cannot grow from {old} to {new} bytes ({} of {} bytes accounted)",
                    self.memory, self.limit
                ),
            ));
        }
        self.memory = memory;
        self.peak = self.peak.max(memory);
        Ok(())
    }

    /// A resident copy now serves `ring` and holds `bytes` (after the loader shrank it). Fails
    /// (and changes nothing) when it would hold more than before.
    pub fn shrink(&mut self, id: TileId, bytes: usize, ring: u32) -> Result<()> {
        let Some(held) = self.records.get_mut(&id).and_then(|r| r.loaded.as_mut()) else {
            return Err(Error::invalid(
                id.to_string(),
                "it was shrunk but is not resident",
            ));
        };
        if bytes > held.bytes {
            return Err(Error::invalid(
                id.to_string(),
                format!(
                    "shrinking it for ring {ring} grew it from {} to {bytes} bytes",
                    held.bytes
                ),
            ));
        }
        self.memory -= held.bytes - bytes;
        *held = Loaded { bytes, ring };
        Ok(())
    }
}

/// One tile to fetch: its id, the ring it is fetched for and the bytes it will hold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fetch {
    /// The tile.
    pub id: TileId,
    /// Its belt distance from the current tile.
    pub ring: u32,
    /// Bytes the loader predicts it will hold at that ring.
    pub bytes: usize,
}

impl std::fmt::Display for Fetch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        self.id.fmt(f)
    }
}
