//! Paging: which tiles are resident, fetched beside the frame loop under a memory limit.
//!
//! Two strategies share one core. [`BeltPager`] is the paper's: Algorithm 1 ([`belts`]) keeps
//! the largest complete square of belts of whole level-0 tiles that fits the limit — the near
//! field — and the tiles of the pyramid's levels above that the frame's cut asks for come
//! whole beside it (`far.rs`). [`StreamPager`] streams progressive levels of the tiles of every
//! level as the view needs them ([`stream`]). Both keep the top of the pyramid resident
//! (`top.rs`), and both hold a [`Residency`] — the [`Ledger`] that accounts every byte before it
//! is fetched, the resident tiles, the viewpoint's tile and square, and the counters — and send
//! their requests over a [`Link`]: a fetch thread ([`PagerMode::Threaded`]) or,
//! deterministically, this thread ([`PagerMode::Stepped`], [`PagerMode::Simulated`]). Each
//! keeps only what differs: what to fetch next and how an arrival joins the resident tile. The
//! engine drives either through the [`Paging`] trait.

mod belt_pager;
pub mod belts;
mod far;
mod ledger;
mod link;
mod loader;
mod meminfo;
pub mod stream;
mod top;
mod worker;

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;
use std::time::Instant;

pub use belt_pager::{BeltPager, Belts, TileLoader};
pub use far::{FAR_SHARE, far_share};
pub use ledger::{Failure, Fetch, Ledger, Loaded, Record, Reservation, RetryPolicy};
pub use link::{Link, Received};
pub use loader::ArchiveLoader;
pub use meminfo::{memory_limit_from_available, parse_mem_available};
pub use stream::{Progressive, StreamPager, StreamStats};
pub use worker::{Job, Request};

use crate::db::grid::{Grid, Pyramid, TileId};
use crate::db::source::CancelToken;
use crate::engine::resident::ResidentTile;
use crate::error::{Error, Result};
use top::{TopFetch, TopRequest, TopTiles};

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
    /// The limit on accounted bytes (see [`memory_limit_from_available`] for a percentage).
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
    ledger: Ledger,
    tiles: BTreeMap<TileId, T>,
    /// The top of the pyramid, once it arrived ([`top`]).
    top: BTreeMap<TileId, T>,
    /// Per tile, how many tiles below it are resident (paged or in the top): where a view may
    /// find something to draw under a tile that is not resident itself.
    covered: HashMap<TileId, u32>,
    mode: PagerMode,
    nearest_when_off: bool,
    center: Option<TileId>,
    complete: Option<u32>,
    memory_bound: bool,
    /// Updates so far: the ledger's clock for retries.
    now: u64,
    /// The time set for the deterministic modes, seconds.
    time: f64,
    started: Instant,
    downloaded_bytes: u64,
    fetches: u64,
    cancelled: u64,
    evictions: u64,
    errors: u64,
    last_error: Option<String>,
    /// The first [`FIRST_ERRORS`] errors, for a summary that says what went wrong from the start.
    first_errors: Vec<String>,
}

/// How many of a pager's first errors it keeps, beside the count and the last one.
pub const FIRST_ERRORS: usize = 5;

impl<T> Residency<T> {
    /// The belt the square grows into next: one past the complete square (0 when none is).
    fn next_belt(&self) -> u32 {
        self.complete.map_or(0, |d| d + 1)
    }

    fn new(pyramid: Pyramid, config: &PagerConfig) -> Self {
        Residency {
            ledger: Ledger::new(pyramid, config.memory_limit_bytes, config.retry),
            tiles: BTreeMap::new(),
            top: BTreeMap::new(),
            covered: HashMap::new(),
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
    fn count(&mut self, id: TileId, change: i32) {
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
    fn holds(&self, id: TileId) -> bool {
        self.tiles.contains_key(&id) || self.top.contains_key(&id)
    }

    /// Makes `tiles` the top, in place of what it held.
    fn set_top(&mut self, tiles: Vec<(TileId, T)>) {
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
    fn insert(&mut self, id: TileId, tile: T) {
        if !self.holds(id) {
            self.count(id, 1);
        }
        self.tiles.insert(id, tile);
    }

    /// Drops the paged copy of `id`.
    fn remove(&mut self, id: TileId) {
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
    fn set_time(&mut self, seconds: f64) {
        self.time = self.time.max(seconds);
    }

    /// The start of an update: counts it and finds the tile under `viewer` (in tile units).
    fn begin(&mut self, viewer: (f64, f64)) {
        self.now += 1;
        self.center = self.ledger.grid().locate(viewer, self.nearest_when_off);
    }

    /// Takes in every result `link` delivered, failing what a stopped fetch thread lost and
    /// counting the bytes of cancelled requests that came back, then lets failed tiles whose
    /// wait is over be tried again. Returns the arrivals, and the cancelled requests with their
    /// bytes.
    fn receive<R: Request, P: Send + 'static>(&mut self, link: &mut Link<R, P>) -> Arrivals<R, P> {
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
    fn cancel(&mut self, id: TileId, crossed: u64) {
        self.ledger.cancel(id);
        self.downloaded_bytes += crossed;
        self.cancelled += 1;
    }

    /// Accounts the reservation of `fetch`, or records why not.
    fn reserve(&mut self, fetch: Fetch, adds: bool) -> bool {
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
    fn accept(&mut self, id: TileId, tile: T, bytes: usize, downloaded: u64) -> bool {
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
    fn fail(&mut self, id: TileId, what: &str, error: &Error) {
        self.ledger.fail(id, self.now);
        let outcome = match self.ledger.record(id).failure {
            Some(Failure::GaveUp) => "given up",
            _ => "will retry",
        };
        self.record_error(format!("{id} ({what}, {outcome}): {error}"));
    }

    /// Drops the resident copy of `id` to make room.
    fn evict(&mut self, id: TileId) {
        self.ledger.evict(id);
        self.remove(id);
        self.evictions += 1;
    }

    /// The resident copy of `id` now holds `bytes` (serving `ring`) after the loader dropped
    /// detail from it; a copy that grew instead is evicted, the error counted.
    fn shrunk(&mut self, id: TileId, bytes: usize, ring: u32) {
        if let Err(e) = self.ledger.shrink(id, bytes, ring) {
            self.record_error(e.to_string());
            self.evict(id);
        }
    }

    /// Accounts what each of `sizes` (tile, bytes) holds after a refit, shrinking tiles first
    /// so that growth finds the room they freed; a tile whose growth does not fit is evicted.
    fn resize(&mut self, mut sizes: Vec<(TileId, usize)>) {
        let loaded = |ledger: &Ledger, id| ledger.record(id).loaded.map_or(0, |l| l.bytes);
        sizes.sort_by_key(|&(id, bytes)| bytes > loaded(&self.ledger, id));
        for (id, bytes) in sizes {
            if let Err(e) = self.ledger.resize_loaded(id, bytes) {
                self.record_error(e.to_string());
                self.evict(id);
            }
        }
    }

    fn record_error(&mut self, message: String) {
        self.errors += 1;
        if self.first_errors.len() < FIRST_ERRORS {
            self.first_errors.push(message.clone());
        }
        self.last_error = Some(message);
    }
}

/// What the loaders of both strategies share: the size of a resident tile and the top.
pub trait ResidentLoader: Send + Sync + 'static {
    /// A resident tile.
    type Loaded: Send + 'static;
    /// Bytes a resident tile holds: at most what the loader predicted for what it holds (a tile
    /// holding more is refused as an error).
    fn loaded_bytes(&self, tile: &Self::Loaded) -> usize;
    /// Bytes the top will hold (the pyramid's root and the levels kept with it, resident for
    /// good), known before it is fetched; 0, the default, when none is kept.
    fn top_bytes(&self) -> usize {
        0
    }
    /// Fetches the top, and the bytes downloaded.
    fn load_top(&self) -> Result<(TopTiles<Self::Loaded>, u64)> {
        Ok((Vec::new(), 0))
    }
    /// Bytes set aside for the archive's index pages: accounted under the limit for good, as
    /// the reader caches pages up to them.
    fn index_bytes(&self) -> usize {
        0
    }
}

/// How a pager decides what to fetch and how an arrival joins the resident tile: the part of a
/// [`Pager`] that differs between whole tiles in belts ([`Belts`]) and progressive levels
/// ([`stream::Progressive`]).
pub trait Strategy: Sized + Send + 'static {
    /// What fetches and prepares tiles.
    type Loader: ResidentLoader<Loaded = Self::Tile>;
    /// A resident tile.
    type Tile: Send + 'static;
    /// A request on the link.
    type Request: Request;
    /// What a request brings.
    type Piece: Send + 'static;
    /// The fetch thread's job for `loader`.
    fn job(loader: Arc<Self::Loader>) -> Job<Self::Request, Self::Piece>;
    /// Brings a tile of the top to the loader's current settings; returns its bytes.
    fn refit_top(loader: &Self::Loader, tile: &mut Self::Tile) -> usize;
    /// Once per frame: takes in arrivals and plans.
    fn update(pager: &mut Pager<Self>, viewer: (f64, f64));
    /// Refits every resident tile after the loader's settings changed.
    fn refit(pager: &mut Pager<Self>);
    /// Hears the frame's wishes (a pager that plans by itself ignores them).
    fn request(pager: &mut Pager<Self>, wants: &[stream::Want]) {
        let _ = (pager, wants);
    }
    /// Hears which progressive levels the frame drew of each tile.
    fn drawn(pager: &mut Pager<Self>, drawn: &[(TileId, usize)]) {
        let _ = (pager, drawn);
    }
    /// The streaming counters, for a pager that streams levels.
    fn stream_stats(pager: &Pager<Self>) -> Option<&StreamStats> {
        let _ = pager;
        None
    }
}

/// A request and what came of it: the piece and the bytes downloaded, or why not.
type Outcome<S> = (
    <S as Strategy>::Request,
    Result<(<S as Strategy>::Piece, u64)>,
);

/// What a link delivered: requests and their results, and cancelled requests that came back
/// with the bytes they downloaded.
type Arrivals<R, P> = (Vec<(R, Result<(P, u64)>)>, Vec<(R, u64)>);

/// A pager: the loader, what is resident, the link, and the strategy's own state.
pub struct Pager<S: Strategy> {
    loader: Arc<S::Loader>,
    mode: PagerMode,
    resident: Residency<S::Tile>,
    link: Link<S::Request, S::Piece>,
    top: TopFetch<S::Tile>,
    strategy: S,
}

impl<S: Strategy> Pager<S> {
    /// A pager for `pyramid` with nothing resident, following `strategy`; starts the fetch
    /// thread in threaded mode.
    pub fn with_strategy(
        loader: S::Loader,
        pyramid: Pyramid,
        config: PagerConfig,
        strategy: S,
    ) -> Result<Self> {
        let loader = Arc::new(loader);
        let link = config.mode.link(S::job(Arc::clone(&loader)))?;
        let top_loader = Arc::clone(&loader);
        let top = TopFetch::new(
            Arc::new(move |_: TopRequest, _: &CancelToken| top_loader.load_top()),
            loader.top_bytes(),
            config.mode,
            config.retry,
        )?;
        let mut resident = Residency::new(pyramid, &config);
        resident.ledger.set_index(loader.index_bytes())?;
        Ok(Pager {
            loader,
            mode: config.mode,
            resident,
            link,
            top,
            strategy,
        })
    }

    /// What the pager holds, and its counters.
    pub fn resident(&self) -> &Residency<S::Tile> {
        &self.resident
    }

    /// The loader.
    pub fn loader(&self) -> &S::Loader {
        &self.loader
    }

    /// Sets the time for the deterministic modes, seconds (never moves it back); threaded mode
    /// runs on the wall clock.
    pub fn set_time(&mut self, seconds: f64) {
        self.resident.set_time(seconds);
    }

    /// Times transfers in [`PagerMode::Simulated`]; without one they take no time and a tile
    /// arrives at the update after its fetch.
    pub fn set_transfer_clock(&mut self, clock: Arc<dyn TransferClock>) {
        self.top.set_transfer_clock(Arc::clone(&clock));
        self.link.set_transfer_clock(clock);
    }

    /// Once per frame, before drawing: `viewer` is the viewpoint in tile units (tile `(x, y)`
    /// covers `[x, x + 1) x [y, y + 1)`, `x` east, `y` south). Never waits on I/O in threaded
    /// mode.
    pub fn update(&mut self, viewer: (f64, f64)) {
        S::update(self, viewer);
    }

    /// After the loader's settings changed (for example the crack mode): refits every resident
    /// tile and the top and accounts what they hold now, never above the limit (a top that
    /// no longer fits is dropped).
    pub fn refit(&mut self) {
        S::refit(self);
        let r = &mut self.resident;
        let bytes: usize = r
            .top
            .values_mut()
            .map(|tile| S::refit_top(&self.loader, tile))
            .sum();
        // The top comes first: paged tiles, farthest first, make room for its growth.
        let mut farthest: Vec<TileId> = r
            .tiles
            .keys()
            .copied()
            .filter(|&id| r.ledger.record(id).fetch.is_none())
            .collect();
        farthest.sort_by_key(|&id| (r.ring(id), std::cmp::Reverse(id.level)));
        while r.ledger.set_top(bytes).is_err() {
            let Some(id) = farthest.pop() else {
                r.set_top(Vec::new());
                // Releasing the top always fits.
                let _ = r.ledger.set_top(0);
                r.record_error(format!(
                    "the top was dropped: its {bytes} bytes in this mode do not fit the limit"
                ));
                break;
            };
            r.evict(id);
        }
    }

    /// Whether tile fetches wait for the top's first attempt to come back.
    fn top_pending(&self) -> bool {
        self.top.first_pending()
    }

    /// The start of an update: finds the tile under `viewer` and takes in every result the
    /// link delivered; returns the arrivals for the strategy to integrate, and the cancelled
    /// requests that came back with their bytes (already counted as downloaded).
    fn begin(&mut self, viewer: (f64, f64)) -> Arrivals<S::Request, S::Piece> {
        self.resident.begin(viewer);
        let loader = &*self.loader;
        self.top
            .poll(&mut self.resident, |t| loader.loaded_bytes(t));
        self.resident.receive(&mut self.link)
    }

    /// Starts `request` on the link (its reservation made); a result that is already there
    /// comes back to integrate at once.
    fn start(&mut self, request: S::Request) -> Option<Outcome<S>> {
        self.link.start(request, self.resident.time)
    }
}

/// What the engine needs of a pager, whichever way its tiles come in.
pub trait Paging: Send {
    /// Start of a frame: takes in arrivals and plans. `viewer` is the viewpoint in tile units.
    fn update(&mut self, viewer: (f64, f64));
    /// What the pager holds, and its counters.
    fn resident(&self) -> &Residency<ResidentTile>;
    /// The loader, whose settings the engine changes between frames.
    fn loader(&self) -> &ArchiveLoader;
    /// Refits every resident tile after the loader's settings changed.
    fn refit(&mut self);
    /// Sets the time for the deterministic modes, seconds.
    fn set_time(&mut self, seconds: f64);
    /// Times transfers in [`PagerMode::Simulated`].
    fn set_transfer_clock(&mut self, clock: Arc<dyn TransferClock>);
    /// After the frame: what it wished for (levels per tile, by importance).
    fn request(&mut self, wants: &[stream::Want]);
    /// After the frame: the progressive levels it drew of each tile.
    fn drawn(&mut self, drawn: &[(TileId, usize)]);
    /// The streaming counters, when tiles stream level by level.
    fn stream_stats(&self) -> Option<&StreamStats>;
}

impl<S: Strategy<Loader = ArchiveLoader, Tile = ResidentTile>> Paging for Pager<S> {
    fn update(&mut self, viewer: (f64, f64)) {
        S::update(self, viewer);
    }

    fn resident(&self) -> &Residency<ResidentTile> {
        &self.resident
    }

    fn loader(&self) -> &ArchiveLoader {
        &self.loader
    }

    fn refit(&mut self) {
        Pager::refit(self);
    }

    fn set_time(&mut self, seconds: f64) {
        self.resident.set_time(seconds);
    }

    fn set_transfer_clock(&mut self, clock: Arc<dyn TransferClock>) {
        Pager::set_transfer_clock(self, clock);
    }

    fn request(&mut self, wants: &[stream::Want]) {
        S::request(self, wants);
    }

    fn drawn(&mut self, drawn: &[(TileId, usize)]) {
        S::drawn(self, drawn);
    }

    fn stream_stats(&self) -> Option<&StreamStats> {
        S::stream_stats(self)
    }
}
