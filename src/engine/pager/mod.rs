//! The pager: Algorithm 1 of [`crate::engine::belts`] driving a [`TileLoader`], beside the frame loop.
//!
//! Call [`Pager::update`] once at the start of every frame with the viewpoint: it takes in the
//! tiles that arrived, shrinks tiles that moved to a farther belt, evicts cache and starts the
//! next fetches of belt `d_c + 1`, all without waiting on I/O in [`PagerMode::Threaded`]. The
//! frame then draws [`Pager::tiles`]. [`PagerMode::Stepped`] runs a fixed number of fetches
//! synchronously inside each update instead, which makes a run reproducible.
//! [`PagerMode::Simulated`] is reproducible too and also models the link: each fetch runs when it
//! is planned, but its tile arrives only once the simulated time ([`Pager::set_time`]) passes the
//! moment its transfer would end on a link that carries one request at a time, as timed by a
//! [`TransferClock`]. Either way the accounted memory, reservations of fetches in flight
//! included, never exceeds the limit.

mod link;
mod meminfo;
pub mod worker;

use std::collections::BTreeMap;
use std::sync::Arc;

pub use meminfo::{memory_limit_from_available, parse_mem_available};

use crate::db::grid::TileId;
use crate::engine::belts::{self, Failure, Fetch, Grid, Ledger, Plan, RetryPolicy};
use crate::error::{Error, Result};
pub use link::{Link, Received};
use worker::{Job, Request, load_job};

/// What the engine gives the pager: costs known before fetching, fetching itself, and shrinking.
pub trait TileLoader: Send + Sync + 'static {
    /// A loaded tile.
    type Loaded: Send + 'static;
    /// Bytes a tile will hold once loaded for belt distance `ring` (known before fetching).
    fn predicted_bytes(&self, id: TileId, ring: u32) -> usize;
    /// Fetches and decodes a tile for belt distance `ring` (on the fetch thread in threaded
    /// mode). Returns the tile and the bytes downloaded.
    fn load(&self, id: TileId, ring: u32) -> Result<(Self::Loaded, u64)>;
    /// Bytes a loaded tile holds; at most what [`TileLoader::predicted_bytes`] said for the ring
    /// it was loaded for (a tile holding more is refused as an error).
    fn held_bytes(&self, tile: &Self::Loaded) -> usize;
    /// Drops detail a tile no longer needs at the larger belt distance `ring` (for example its
    /// finest texture mips); returns the bytes it holds now, never more than before.
    fn shrink(&self, tile: &mut Self::Loaded, ring: u32) -> usize;
    /// Brings a tile loaded (or fetched) under earlier settings of this loader to its current
    /// ones, for belt distance `ring`; returns the bytes it holds now, which may be more than
    /// before (see [`Pager::refit`]). A loader whose settings never change keeps the default,
    /// which changes nothing.
    fn refit(&self, tile: &mut Self::Loaded, ring: u32) -> usize {
        let _ = ring;
        self.held_bytes(tile)
    }
}

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
    /// the other, re-planning after each (0 pauses fetching). Deterministic.
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
                Err(Error::Usage(
                    "a threaded or simulated pager needs a queue depth of at least 1".into(),
                ))
            }
            PagerMode::Threaded { .. } => Link::new(job, true),
            PagerMode::Stepped { .. } | PagerMode::Simulated { .. } => Link::new(job, false),
        }
    }
}

/// The time a link spent on transfers, for [`PagerMode::Simulated`]: the pager reads it before
/// and after each fetch, and the difference is that fetch's transfer time.
pub trait TransferClock: Send + Sync {
    /// Seconds of transfers so far (never decreasing).
    fn busy_seconds(&self) -> f64;
}

/// Settings of a [`Pager`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PagerConfig {
    /// The limit on accounted bytes (see [`memory_limit_from_available`] for a percentage).
    pub memory_limit_bytes: usize,
    /// A viewpoint off the terrain uses the nearest tile; when false, nothing new is fetched
    /// while the viewpoint is off the terrain (what is loaded stays, as cache).
    pub nearest_when_off: bool,
    /// Threaded or stepped fetching.
    pub mode: PagerMode,
    /// How failed tiles are tried again.
    pub retry: RetryPolicy,
}

impl PagerConfig {
    /// `memory_limit_bytes` in `mode`, using the nearest tile off the terrain, default retries.
    pub fn new(memory_limit_bytes: usize, mode: PagerMode) -> Self {
        PagerConfig {
            memory_limit_bytes,
            nearest_when_off: true,
            mode,
            retry: RetryPolicy::default(),
        }
    }
}

/// Where a tile stands, for display (the HUD minimap colours tiles by this).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum TileState {
    /// Loaded and part of the complete square of belts.
    Square,
    /// Being fetched (possibly an upgrade of a copy held for a farther belt).
    Fetching,
    /// Loaded outside the complete square: a cache kept until memory is needed.
    Cached,
    /// Its last fetch failed (it waits for a retry, or was given up).
    Failed,
    /// Not loaded.
    Absent,
}

/// Counters of a [`Pager`], for the HUD and the per-frame statistics.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PagerStats {
    /// Accounted bytes now: loaded tiles plus reservations of fetches in flight.
    pub memory_bytes: usize,
    /// The highest `memory_bytes` so far.
    pub memory_peak_bytes: usize,
    /// The limit.
    pub memory_limit_bytes: usize,
    /// Tiles with a loaded copy.
    pub loaded_tiles: usize,
    /// Fetches in flight.
    pub fetching: usize,
    /// `d_c`: belts `0..=d_c` around the current tile are complete; `None` while the current
    /// tile itself is missing or the viewpoint is off the terrain (with `nearest_when_off` off).
    pub complete_belts: Option<u32>,
    /// The last plan found that belt `d_c + 1` does not fit the limit even without cache: the
    /// square is as large as memory allows.
    pub memory_bound: bool,
    /// Bytes the loader reported downloaded.
    pub downloaded_bytes: u64,
    /// Tiles fetched and accounted.
    pub fetches: u64,
    /// Loaded copies dropped to make room.
    pub evictions: u64,
    /// Failed fetches (and loader contract violations).
    pub errors: u64,
    /// Tiles whose last fetch failed.
    pub failed_tiles: usize,
}

/// Pages tiles in belts around the viewpoint under a memory limit (see the module doc).
pub struct Pager<L: TileLoader> {
    loader: Arc<L>,
    config: PagerConfig,
    ledger: Ledger,
    tiles: BTreeMap<TileId, L::Loaded>,
    link: Link<Fetch, L::Loaded>,
    time: f64,
    center: Option<TileId>,
    complete: Option<u32>,
    memory_bound: bool,
    now: u64,
    downloaded_bytes: u64,
    fetches: u64,
    evictions: u64,
    errors: u64,
    last_error: Option<String>,
}

impl<L: TileLoader> Pager<L> {
    /// A pager for `grid` with nothing loaded; starts the fetch thread in threaded mode.
    pub fn new(loader: L, grid: Grid, config: PagerConfig) -> Result<Self> {
        let loader = Arc::new(loader);
        let link = config.mode.link(load_job(Arc::clone(&loader)))?;
        Ok(Pager {
            loader,
            config,
            ledger: Ledger::new(grid, config.memory_limit_bytes, config.retry),
            tiles: BTreeMap::new(),
            link,
            time: 0.0,
            center: None,
            complete: None,
            memory_bound: false,
            now: 0,
            downloaded_bytes: 0,
            fetches: 0,
            evictions: 0,
            errors: 0,
            last_error: None,
        })
    }

    /// Sets the simulated time, seconds, for [`PagerMode::Simulated`] (never moves it back).
    pub fn set_time(&mut self, seconds: f64) {
        self.time = self.time.max(seconds);
    }

    /// Times transfers in [`PagerMode::Simulated`]; without one they take no time and a tile
    /// arrives at the update after its fetch.
    pub fn set_transfer_clock(&mut self, clock: Arc<dyn TransferClock>) {
        self.link.set_transfer_clock(clock);
    }

    /// Once per frame, before drawing: `viewer` is the viewpoint in tile units (tile `(x, y)`
    /// covers `[x, x + 1) x [y, y + 1)`, `x` east, `y` south). Takes in arrived tiles, shrinks
    /// tiles that are now farther, evicts and schedules. Never waits on I/O in threaded mode.
    pub fn update(&mut self, viewer: (f64, f64)) {
        self.now += 1;
        self.center = self
            .ledger
            .grid()
            .locate(viewer, self.config.nearest_when_off);
        self.receive();
        self.ledger.tick(self.now);
        self.shrink();
        match self.config.mode {
            PagerMode::Threaded { queue_depth } => {
                let room = queue_depth.saturating_sub(self.ledger.fetching());
                let plan = self.plan(room);
                self.evict(&plan);
                for fetch in plan.fetch {
                    self.dispatch(fetch);
                }
            }
            PagerMode::Stepped { fetches_per_update } => {
                for _ in 0..fetches_per_update {
                    let plan = self.plan(1);
                    self.evict(&plan);
                    let Some(&fetch) = plan.fetch.first() else {
                        break;
                    };
                    if self.reserve(fetch) {
                        let result = self.link.run_now(fetch);
                        self.integrate(fetch.id, result);
                    }
                }
            }
            PagerMode::Simulated { queue_depth } => {
                let room = queue_depth.saturating_sub(self.ledger.fetching());
                let plan = self.plan(room);
                self.evict(&plan);
                for fetch in plan.fetch {
                    self.schedule(fetch);
                }
            }
        }
        let loader = &*self.loader;
        self.complete = self.center.and_then(|c| {
            self.ledger
                .complete_belts(c, |id, ring| loader.predicted_bytes(id, ring))
        });
    }

    /// After the loader's settings changed (for example the crack mode): refits every loaded
    /// tile ([`TileLoader::refit`]) and accounts what it holds now, evicting the tiles farthest
    /// from the current one while the total would exceed the limit, then re-reserves every
    /// fetch in flight at the new prediction where that fits. A fetch whose grown reservation
    /// does not fit keeps its old one: its tile, refit on arrival, holds more than reserved and
    /// is refused and fetched again later, so the accounted bytes never exceed the limit.
    /// Tiles loaded under the old settings that arrive later are refit on arrival.
    pub fn refit(&mut self) {
        let mut resized = Vec::new();
        for (&id, tile) in &mut self.tiles {
            let held = self.ledger.record(id).held.expect("a loaded tile is held");
            resized.push((id, held.bytes, self.loader.refit(tile, held.ring)));
        }
        let center = self.center;
        resized
            .sort_by_key(|&(id, _, _)| std::cmp::Reverse(center.map_or(0, |c| Grid::ring(c, id))));
        let grown: usize = resized
            .iter()
            .map(|&(_, old, new)| new.saturating_sub(old))
            .sum();
        let shrunk: usize = resized
            .iter()
            .map(|&(_, old, new)| old.saturating_sub(new))
            .sum();
        let mut total = self.ledger.memory() + grown - shrunk;
        let mut kept = Vec::new();
        for (id, old, new) in resized {
            if total > self.config.memory_limit_bytes {
                total -= new;
                self.ledger.evict(id);
                self.tiles.remove(&id);
                self.evictions += 1;
            } else {
                kept.push((id, old, new));
            }
        }
        kept.sort_by_key(|&(_, old, new)| new > old);
        for (id, _, new) in kept {
            if let Err(e) = self.ledger.resize_held(id, new) {
                self.record_error(e.to_string());
            }
        }
        let fetching: Vec<(TileId, u32)> = self
            .ledger
            .records()
            .filter_map(|(id, r)| r.fetch.map(|f| (id, f.ring)))
            .collect();
        for (id, ring) in fetching {
            // Too large to fit: keeps the old reservation, as documented above.
            let _ = self
                .ledger
                .resize_reservation(id, self.loader.predicted_bytes(id, ring));
        }
    }

    /// The tile under the viewpoint at the last update (the nearest one when off the terrain
    /// and `nearest_when_off`).
    pub fn current_tile(&self) -> Option<TileId> {
        self.center
    }

    /// The loaded tiles, row-major: the complete square and the cache.
    pub fn tiles(&self) -> impl Iterator<Item = (TileId, &L::Loaded)> {
        self.tiles.iter().map(|(id, t)| (*id, t))
    }

    /// The loaded copies by tile.
    pub fn resident(&self) -> &BTreeMap<TileId, L::Loaded> {
        &self.tiles
    }

    /// The loaded copy of `id`, if any.
    pub fn get(&self, id: TileId) -> Option<&L::Loaded> {
        self.tiles.get(&id)
    }

    /// Where `id` stands.
    pub fn state(&self, id: TileId) -> TileState {
        let record = self.ledger.record(id);
        let in_square = match (self.center, self.complete) {
            (Some(c), Some(d)) => Grid::ring(c, id) <= d,
            _ => false,
        };
        if record.held.is_some() && in_square {
            TileState::Square
        } else if record.fetch.is_some() {
            TileState::Fetching
        } else if record.held.is_some() {
            TileState::Cached
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
            evictions: self.evictions,
            errors: self.errors,
            failed_tiles: self.ledger.failed_tiles(),
        }
    }

    /// The message of the last error (a failed fetch names its tile), if any.
    pub fn last_error(&self) -> Option<&str> {
        self.last_error.as_deref()
    }

    /// The accounting: what every tile holds or has reserved.
    pub fn ledger(&self) -> &Ledger {
        &self.ledger
    }

    /// The loader.
    pub fn loader(&self) -> &L {
        &self.loader
    }

    fn plan(&mut self, max_fetches: usize) -> Plan {
        let loader = &*self.loader;
        let plan = belts::plan(&self.ledger, self.center, max_fetches, |id, ring| {
            loader.predicted_bytes(id, ring)
        });
        self.memory_bound = plan.full;
        plan
    }

    fn evict(&mut self, plan: &Plan) {
        for &id in &plan.evict {
            self.ledger.evict(id);
            self.tiles.remove(&id);
            self.evictions += 1;
        }
    }

    /// Accounts a planned fetch; false (with the error recorded) if the ledger refuses it.
    fn reserve(&mut self, fetch: Fetch) -> bool {
        match self.ledger.reserve(fetch) {
            Ok(()) => true,
            Err(e) => {
                self.record_error(e.to_string());
                false
            }
        }
    }

    fn dispatch(&mut self, fetch: Fetch) {
        if !self.reserve(fetch) {
            return;
        }
        let sent = self.link.send(fetch);
        if let Err(e) = sent {
            self.ledger.fail(fetch.id, self.now);
            self.record_error(e.to_string());
        }
    }

    /// Runs a fetch now and queues its result until the end of its transfer, which starts when
    /// the link is free and takes what the transfer clock says.
    fn schedule(&mut self, fetch: Fetch) {
        if !self.reserve(fetch) {
            return;
        }
        self.link.schedule(fetch, self.time);
    }

    /// Takes in every result the fetch thread sent, or every simulated transfer that has ended.
    /// If the thread is gone, its fetches in flight fail and a new thread starts.
    fn receive(&mut self) {
        let received = self.link.receive(self.time, &mut self.ledger, self.now);
        for (fetch, result) in received.arrivals {
            self.integrate(fetch.id, result);
        }
        for e in received.errors {
            self.record_error(e.to_string());
        }
    }

    fn integrate(&mut self, id: TileId, result: Result<(L::Loaded, u64)>) {
        match result {
            Ok((mut tile, downloaded)) => {
                self.downloaded_bytes += downloaded;
                let ring = self.ledger.record(id).fetch.map_or(0, |f| f.ring);
                let held = self.loader.refit(&mut tile, ring);
                match self.ledger.arrive(id, held, self.now) {
                    Ok(()) => {
                        self.tiles.insert(id, tile);
                        self.fetches += 1;
                    }
                    Err(e) => self.record_error(e.to_string()),
                }
            }
            Err(e) => {
                let ring = self.ledger.record(id).fetch.map_or(0, |f| f.ring);
                self.ledger.fail(id, self.now);
                let outcome = match self.ledger.record(id).failure {
                    Some(Failure::GaveUp) => "given up",
                    _ => "will retry",
                };
                self.record_error(format!("{id} (ring {ring}, {outcome}): {e}"));
            }
        }
    }

    /// Shrinks every loaded tile that is now in a farther belt than the one it holds detail for.
    fn shrink(&mut self) {
        let Some(center) = self.center else {
            return;
        };
        let grown: Vec<(TileId, u32)> = self
            .ledger
            .records()
            .filter_map(|(id, r)| {
                let ring = Grid::ring(center, id);
                r.held.filter(|h| ring > h.ring).map(|_| (id, ring))
            })
            .collect();
        for (id, ring) in grown {
            let Some(tile) = self.tiles.get_mut(&id) else {
                continue;
            };
            let bytes = self.loader.shrink(tile, ring);
            if let Err(e) = self.ledger.shrink(id, bytes, ring) {
                self.record_error(e.to_string());
                self.ledger.evict(id);
                self.tiles.remove(&id);
                self.evictions += 1;
            }
        }
    }

    fn record_error(&mut self, message: String) {
        self.errors += 1;
        self.last_error = Some(message);
    }
}
