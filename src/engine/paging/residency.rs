//! What a pager holds: the ledger of accounted bytes, the resident tiles, the viewpoint's tile
//! and square, and the counters.

use std::collections::BTreeMap;
use std::time::Instant;

use crate::db::grid::{Grid, Pyramid, TileId, TileMap};
use crate::engine::paging::pager::Arrivals;
use crate::engine::paging::{Failure, Fetch, Ledger, Link, PagerConfig, PagerMode, Request};
use crate::error::Error;

/// Where a tile stands, for display (the HUD minimap colours tiles by this).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TileState {
    /// Resident and part of the complete square of belts.
    Square,
    /// Resident outside the complete square: a cache kept until memory is needed.
    Cached,
    /// Not resident, being fetched.
    Fetching,
    /// Not resident, its last fetch failed (it waits for a retry, or was given up).
    Failed,
    /// Not resident.
    Absent,
}

/// Counters of a pager, for the HUD and the per-frame statistics.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PagerStats {
    /// Accounted bytes now: resident tiles plus reservations of fetches in flight.
    pub memory_bytes: usize,
    /// The highest `memory_bytes` so far.
    pub memory_peak_bytes: usize,
    /// The limit.
    pub memory_limit_bytes: usize,
    /// Resident tiles.
    pub loaded_tiles: usize,
    /// Fetches in flight.
    pub fetching: usize,
    /// `d_c`: belts `0..=d_c` around the current tile are complete; `None` while the current
    /// tile itself is missing or the viewpoint is off the terrain (with `nearest_when_off` off).
    pub complete_belts: Option<u32>,
    /// The square is as large as memory allows: the next belt (or request) does not fit.
    pub memory_bound: bool,
    /// Bytes received.
    pub downloaded_bytes: u64,
    /// Fetches that arrived and were accounted.
    pub fetches: u64,
    /// Fetches cancelled on their way once their tile stopped mattering (never drawn; what they
    /// downloaded before they stopped is in `downloaded_bytes`).
    pub cancelled: u64,
    /// Resident tiles dropped to make room.
    pub evictions: u64,
    /// Failed fetches (and loader contract violations).
    pub errors: u64,
    /// Tiles whose last fetch failed.
    pub failed_tiles: usize,
    /// Tiles of the top resident (0 before it arrived, or without one).
    pub top_tiles: usize,
    /// Bytes the top holds, or has reserved while on its way (part of `memory_bytes`).
    pub top_bytes: usize,
    /// Bytes set aside for the archive's index pages (part of `memory_bytes`).
    pub index_bytes: usize,
}

/// What a pager holds, whichever its strategy: the ledger, the resident tiles and the top,
/// where the viewpoint is, the pager's clock and its counters.
pub struct Residency<T> {
    pub(super) ledger: Ledger,
    pub(super) tiles: BTreeMap<TileId, T>,
    /// The top of the pyramid, once it arrived ([`top`]).
    pub(super) top: BTreeMap<TileId, T>,
    /// Per tile, how many tiles below it are resident (paged or in the top): where a view may
    /// find something to draw under a tile that is not resident itself.
    pub(super) covered: TileMap<u32>,
    pub(super) mode: PagerMode,
    pub(super) nearest_when_off: bool,
    pub(super) center: Option<TileId>,
    pub(super) complete: Option<u32>,
    pub(super) memory_bound: bool,
    /// Updates so far: the ledger's clock for retries.
    pub(super) now: u64,
    /// The time set for the deterministic modes, seconds.
    pub(super) time: f64,
    pub(super) started: Instant,
    pub(super) downloaded_bytes: u64,
    pub(super) fetches: u64,
    pub(super) cancelled: u64,
    pub(super) evictions: u64,
    pub(super) errors: u64,
    pub(super) last_error: Option<String>,
    /// The first [`FIRST_ERRORS`] errors, for a summary that says what went wrong from the start.
    pub(super) first_errors: Vec<String>,
}

/// How many of a pager's first errors it keeps, beside the count and the last one.
pub const FIRST_ERRORS: usize = 5;

impl<T> Residency<T> {
    /// The belt the square grows into next: one past the complete square (0 when none is).
    pub(super) fn next_belt(&self) -> u32 {
        self.complete.map_or(0, |d| d + 1)
    }

    pub(super) fn new(pyramid: Pyramid, config: &PagerConfig) -> Self {
        Residency {
            ledger: Ledger::new(pyramid, config.memory_limit_bytes, config.retry),
            tiles: BTreeMap::new(),
            top: BTreeMap::new(),
            covered: TileMap::default(),
            mode: config.mode,
            nearest_when_off: config.nearest_when_off,
            center: None,
            complete: None,
            memory_bound: false,
            now: 0,
            time: 0.0,
            started: Instant::now(),
            downloaded_bytes: 0,
            fetches: 0,
            cancelled: 0,
            evictions: 0,
            errors: 0,
            last_error: None,
            first_errors: Vec::new(),
        }
    }

    /// The tile under the viewpoint at the last update (the nearest one when off the terrain
    /// and `nearest_when_off`).
    pub fn current_tile(&self) -> Option<TileId> {
        self.center
    }

    /// The paged tiles, by level then row-major: the complete square, the cache and the far
    /// field (not the top).
    pub fn tiles(&self) -> impl Iterator<Item = (TileId, &T)> {
        self.tiles.iter().map(|(id, t)| (*id, t))
    }

    /// The best copy of `id` there is: paged, or else from the top.
    pub fn get(&self, id: TileId) -> Option<&T> {
        self.tiles.get(&id).or_else(|| self.top.get(&id))
    }

    /// The paged copy of `id`, if any.
    pub fn paged(&self, id: TileId) -> Option<&T> {
        self.tiles.get(&id)
    }

    /// The top's copy of `id`, if the top has arrived and holds it.
    pub fn top_tile(&self, id: TileId) -> Option<&T> {
        self.top.get(&id)
    }

    /// The top's tiles.
    pub fn top(&self) -> impl Iterator<Item = (TileId, &T)> {
        self.top.iter().map(|(id, t)| (*id, t))
    }

    /// Tiles below `id` (of any level) that are resident.
    pub fn covered(&self, id: TileId) -> u32 {
        self.covered.get(&id).copied().unwrap_or(0)
    }

    /// Counts `id` (just made resident, `+1`, or dropped, `-1`) in its ancestors' coverage.
    pub(super) fn count(&mut self, id: TileId, change: i32) {
        let root = self.ledger.pyramid().root().level;
        for level in id.level + 1..=root {
            let ancestor = id.ancestor(level);
            let n = self.covered.entry(ancestor).or_default();
            *n = n.saturating_add_signed(change);
            if *n == 0 {
                self.covered.remove(&ancestor);
            }
        }
    }

    /// Whether some copy of `id` (paged or top) is resident.
    pub(super) fn holds(&self, id: TileId) -> bool {
        self.tiles.contains_key(&id) || self.top.contains_key(&id)
    }

    /// Makes `tiles` the top, in place of what it held.
    pub(super) fn set_top(&mut self, tiles: Vec<(TileId, T)>) {
        let old: Vec<TileId> = self.top.keys().copied().collect();
        for id in old {
            self.top.remove(&id);
            if !self.holds(id) {
                self.count(id, -1);
            }
        }
        for (id, tile) in tiles {
            if !self.holds(id) {
                self.count(id, 1);
            }
            self.top.insert(id, tile);
        }
    }

    /// Makes `tile` the paged copy of `id`.
    pub(super) fn insert(&mut self, id: TileId, tile: T) {
        if !self.holds(id) {
            self.count(id, 1);
        }
        self.tiles.insert(id, tile);
    }

    /// Drops the paged copy of `id`.
    pub(super) fn remove(&mut self, id: TileId) {
        if self.tiles.remove(&id).is_some() && !self.holds(id) {
            self.count(id, -1);
        }
    }

    /// The accounting: what every tile holds or has reserved.
    pub fn ledger(&self) -> &Ledger {
        &self.ledger
    }

    /// The message of the last error (a failed fetch names its tile), if any.
    pub fn last_error(&self) -> Option<&str> {
        self.last_error.as_deref()
    }

    /// The messages of the first [`FIRST_ERRORS`] errors, oldest first.
    pub fn first_errors(&self) -> &[String] {
        &self.first_errors
    }

    /// Seconds on the pager's clock: the wall clock when threaded, else the time set.
    pub fn time(&self) -> f64 {
        match self.mode {
            PagerMode::Threaded { .. } => self.started.elapsed().as_secs_f64(),
            PagerMode::Stepped { .. } | PagerMode::Simulated { .. } => self.time,
        }
    }

    /// Whether `id` is a level-0 tile of the complete square of belts around the current tile.
    pub fn in_square(&self, id: TileId) -> bool {
        match (self.center, self.complete) {
            (Some(c), Some(d)) => id.level == 0 && Grid::ring(c, id) <= d,
            _ => false,
        }
    }

    /// The belt of `id` around the viewpoint at `id`'s level: its Chebyshev distance from the
    /// tile of its level under the viewpoint (0 without a viewpoint).
    pub fn ring(&self, id: TileId) -> u32 {
        self.center
            .map_or(0, |c| Grid::ring(c.ancestor(id.level), id))
    }

    /// Where `id` stands: what it shows first (a resident copy, even while a finer one is on its
    /// way), then why it shows nothing.
    pub fn state(&self, id: TileId) -> TileState {
        let record = self.ledger.record(id);
        if record.loaded.is_some() {
            if self.in_square(id) {
                TileState::Square
            } else {
                TileState::Cached
            }
        } else if record.fetch.is_some() {
            TileState::Fetching
        } else if record.failure.is_some() {
            TileState::Failed
        } else {
            TileState::Absent
        }
    }

    /// The counters.
    pub fn stats(&self) -> PagerStats {
        PagerStats {
            memory_bytes: self.ledger.memory(),
            memory_peak_bytes: self.ledger.peak(),
            memory_limit_bytes: self.ledger.limit(),
            loaded_tiles: self.tiles.len(),
            fetching: self.ledger.fetching(),
            complete_belts: self.complete,
            memory_bound: self.memory_bound,
            downloaded_bytes: self.downloaded_bytes,
            fetches: self.fetches,
            cancelled: self.cancelled,
            evictions: self.evictions,
            errors: self.errors,
            failed_tiles: self.ledger.failed_tiles(),
            top_tiles: self.top.len(),
            top_bytes: self.ledger.top(),
            index_bytes: self.ledger.index(),
        }
    }

    /// Sets the time for the deterministic modes, seconds (never moves it back).
    pub(super) fn set_time(&mut self, seconds: f64) {
        self.time = self.time.max(seconds);
    }

    /// The start of an update: counts it and finds the tile under `viewer` (in tile units).
    pub(super) fn begin(&mut self, viewer: (f64, f64)) {
        self.now += 1;
        self.center = self.ledger.grid().locate(viewer, self.nearest_when_off);
    }

    /// Takes in every result `link` delivered, failing what a stopped fetch thread lost and
    /// counting the bytes of cancelled requests that came back, then lets failed tiles whose
    /// wait is over be tried again. Returns the arrivals, and the cancelled requests with their
    /// bytes.
    pub(super) fn receive<R: Request, P: Send + 'static>(
        &mut self,
        link: &mut Link<R, P>,
    ) -> Arrivals<R, P> {
        let received = link.receive(self.time);
        if received.lost {
            self.ledger.fail_in_flight(self.now);
        }
        for e in received.errors {
            self.record_error(e.to_string());
        }
        self.downloaded_bytes += received.cut.iter().map(|&(_, b)| b).sum::<u64>();
        self.ledger.tick(self.now);
        (received.arrivals, received.cut)
    }

    /// The fetch of `id` on its way was cancelled after `crossed` bytes of it arrived: its
    /// reservation is released and nothing counts against the tile.
    pub(super) fn cancel(&mut self, id: TileId, crossed: u64) {
        self.ledger.cancel(id);
        self.downloaded_bytes += crossed;
        self.cancelled += 1;
    }

    /// Accounts the reservation of `fetch`, or records why not.
    pub(super) fn reserve(&mut self, fetch: Fetch, adds: bool) -> bool {
        let reserved = if adds {
            self.ledger.reserve_addition(fetch)
        } else {
            self.ledger.reserve(fetch)
        };
        match reserved {
            Ok(()) => true,
            Err(e) => {
                self.record_error(e.to_string());
                false
            }
        }
    }

    /// A fetch of `id` arrived holding `bytes` after downloading `downloaded`: the tile becomes
    /// resident, unless it holds more than was reserved (then it is dropped, the error counted).
    pub(super) fn accept(&mut self, id: TileId, tile: T, bytes: usize, downloaded: u64) -> bool {
        self.downloaded_bytes += downloaded;
        match self.ledger.arrive(id, bytes, self.now) {
            Ok(()) => {
                self.insert(id, tile);
                self.fetches += 1;
                true
            }
            Err(e) => {
                self.record_error(e.to_string());
                false
            }
        }
    }

    /// A fetch of `id` (`what` it asked for) failed with `error`: its reservation is released
    /// and the failure counted under the retry policy.
    pub(super) fn fail(&mut self, id: TileId, what: &str, error: &Error) {
        self.ledger.fail(id, self.now);
        let outcome = match self.ledger.record(id).failure {
            Some(Failure::GaveUp) => "given up",
            _ => "will retry",
        };
        self.record_error(format!("{id} ({what}, {outcome}): {error}"));
    }

    /// Drops the resident copy of `id` to make room.
    pub(super) fn evict(&mut self, id: TileId) {
        self.ledger.evict(id);
        self.remove(id);
        self.evictions += 1;
    }

    /// The resident copy of `id` now holds `bytes` (serving `ring`) after the loader dropped
    /// detail from it; a copy that grew instead is evicted, the error counted.
    pub(super) fn shrunk(&mut self, id: TileId, bytes: usize, ring: u32) {
        if let Err(e) = self.ledger.shrink(id, bytes, ring) {
            self.record_error(e.to_string());
            self.evict(id);
        }
    }

    /// Accounts what each of `sizes` (tile, bytes) holds after a refit, shrinking tiles first
    /// so that growth finds the room they freed; a tile whose growth does not fit is evicted.
    pub(super) fn resize(&mut self, mut sizes: Vec<(TileId, usize)>) {
        let loaded = |ledger: &Ledger, id| ledger.record(id).loaded.map_or(0, |l| l.bytes);
        sizes.sort_by_key(|&(id, bytes)| bytes > loaded(&self.ledger, id));
        for (id, bytes) in sizes {
            if let Err(e) = self.ledger.resize_loaded(id, bytes) {
                self.record_error(e.to_string());
                self.evict(id);
            }
        }
    }

    pub(super) fn record_error(&mut self, message: String) {
        self.errors += 1;
        if self.first_errors.len() < FIRST_ERRORS {
            self.first_errors.push(message.clone());
        }
        self.last_error = Some(message);
    }
}
