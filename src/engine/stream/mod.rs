//! Progressive streaming: the paper's future work ("fetch tile levels only when needed, load
//! farther tiles at their lowest resolution") as its 2009 follow-up did it.
//!
//! The unit of work is a (tile, level) pair, not a whole tile: a request brings a tile from the
//! `k` progressive levels it holds to `m > k` with one range request ([`crate::db::tile`] stores
//! each level as a separate chunk, coarse first, so levels `k..m` are contiguous bytes). The
//! engine asks for levels: the coarsest first, then as many as the mask its importance buys
//! needs. Each frame:
//!
//! 1. [`StreamPager::update`] takes in what arrived (merging a finer level into the resident
//!    tile) and finds `d_c`, the complete square of belts held at the coarsest level at least;
//! 2. the engine culls and weighs the held tiles, asks the budget which mask each would get if
//!    it held every level, and tells [`StreamPager::request`] how many levels each wants and how
//!    much it matters (its visual importance; the predicted view's wishes count half), and which
//!    absent tiles of the belts the view (or the predicted view) meets;
//! 3. the pager turns wishes into requests — a tile the view needs and nobody holds comes at its
//!    coarsest level first, above everything; a held tile comes up to the levels it is asked
//!    for in one range request, by importance; and the coarse level of each tile of belt
//!    `d_c + 1` (Algorithm 1 at the coarsest level, while the coarse square takes at most
//!    [`StreamConfig::square_share`] of the memory) comes when nothing a view asks for waits —
//!    re-prioritises its bounded [`RequestQueue`] with them, cancelling what fell out before it
//!    was sent, and sends the best while the link has room;
//! 4. [`StreamPager::drawn`] hears which levels the frame used, for the share of received
//!    bytes rendered within a second.
//!
//! Memory: every held level is accounted at its exact resident bytes and every request reserves
//! its growth before it is sent, so the limit is never overspent. When a request does not fit,
//! room is made first by dropping fine levels — of tiles holding more than they are asked for,
//! then of tiles that matter less than the request, farthest first — and only then by evicting
//! whole tiles from the cache outside the square.

mod predict;
mod queue;
mod stats;

use std::collections::{BTreeMap, HashMap};
use std::sync::Arc;
use std::time::Instant;

pub use predict::{PredictedView, PredictionSettings, Predictor};
pub use queue::{LevelRequest, Reason, RequestQueue};
pub use stats::{Delivery, StreamStats};

use crate::db::grid::TileId;
use crate::engine::belts::{Failure, Fetch, Grid, Ledger, RetryPolicy};
use crate::engine::pager::worker::{Job, Request};
use crate::engine::pager::{Link, PagerMode, PagerStats, TileState, TransferClock};
use crate::error::{Error, Result};

/// How tiles come in.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Streaming {
    /// The paper's way: whole tiles, belt by belt (`crate::engine::pager`).
    #[default]
    Belts,
    /// Progressive levels by importance ([`StreamPager`]).
    Progressive(StreamSettings),
}

/// The settings of progressive streaming an engine is built with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreamSettings {
    /// Requests waiting to be sent, at most.
    pub queue_capacity: usize,
    /// The most of the memory limit the coarse square may take.
    pub square_share: f64,
    /// Prefetching for the predicted view, or none.
    pub prediction: Option<PredictionSettings>,
}

impl Default for StreamSettings {
    fn default() -> Self {
        StreamSettings {
            queue_capacity: 32,
            square_share: 0.5,
            prediction: Some(PredictionSettings::default()),
        }
    }
}

/// Priority of the coarsest level of a tile the view needs: above every refinement (importance
/// is at most 1).
const COARSE_PRIORITY: f64 = 2.0;

/// Priority of the coarsest level of a belt tile no view needs yet, at ring 0 (divided by
/// `1 + ring`): below any refinement a view asks for, so on a slow link the square grows while
/// the link would otherwise idle, never instead of the detail on screen.
const BELT_PRIORITY: f64 = 1e-3;

/// What the engine gives the stream pager: level costs known before fetching, fetching a range
/// of levels, and merging them into the resident tile.
pub trait LevelLoader: Send + Sync + 'static {
    /// A resident tile.
    type Loaded: Send + 'static;
    /// Fetched levels not yet merged (made on the fetch thread).
    type Piece: Send + 'static;
    /// Progressive levels of a whole tile.
    fn levels(&self) -> usize;
    /// Bytes a tile holding `levels` progressive levels holds.
    fn predicted_bytes(&self, levels: usize) -> usize;
    /// Fetches levels `have..want` of `id` with one range request; returns them and the bytes
    /// downloaded.
    fn fetch(&self, id: TileId, have: usize, want: usize) -> Result<(Self::Piece, u64)>;
    /// The resident tile that `held` (`None` when the piece starts at the coarsest level) and
    /// `piece` make; `held` stays as it was if this fails.
    fn merge(
        &self,
        id: TileId,
        held: Option<&Self::Loaded>,
        piece: Self::Piece,
    ) -> Result<Self::Loaded>;
    /// Progressive levels a resident tile holds.
    fn held_levels(&self, tile: &Self::Loaded) -> usize;
    /// Bytes a resident tile holds: at most [`LevelLoader::predicted_bytes`] of its levels.
    fn held_bytes(&self, tile: &Self::Loaded) -> usize;
    /// Keeps only the first `levels` levels; returns the bytes held now.
    fn drop_levels(&self, tile: &mut Self::Loaded, levels: usize) -> usize;
    /// Brings a tile to the loader's current settings (see `Pager::refit`); returns its bytes.
    fn refit(&self, tile: &mut Self::Loaded) -> usize {
        self.held_bytes(tile)
    }
}

/// One tile's wish this frame: `levels` progressive levels, mattering `priority` (its visual
/// importance, 0 ..= 1). A tile may have several (the current and the predicted view's).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Want {
    /// The tile.
    pub id: TileId,
    /// Progressive levels the chosen mask needs.
    pub levels: usize,
    /// How much it matters.
    pub priority: f64,
    /// Whether only the predicted view asks for it.
    pub predicted: bool,
}

/// Settings of a [`StreamPager`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreamConfig {
    /// The limit on accounted bytes.
    pub memory_limit_bytes: usize,
    /// Requests waiting to be sent, at most (the bounded queue).
    pub queue_capacity: usize,
    /// Threaded, stepped or simulated fetching, as for the belt pager; the queue depth is the
    /// number of requests on the link at once.
    pub mode: PagerMode,
    /// The most of the memory limit the coarse square of belts may take: the rest is kept for
    /// finer levels.
    pub square_share: f64,
    /// A viewpoint off the terrain uses the nearest tile.
    pub nearest_when_off: bool,
    /// How failed requests are tried again.
    pub retry: RetryPolicy,
}

impl StreamConfig {
    /// `memory_limit_bytes` in `mode`, a queue of 32, half the memory for the coarse square.
    pub fn new(memory_limit_bytes: usize, mode: PagerMode) -> Self {
        StreamConfig {
            memory_limit_bytes,
            queue_capacity: 32,
            mode,
            square_share: 0.5,
            nearest_when_off: true,
            retry: RetryPolicy::default(),
        }
    }
}

/// A request on its way: bring `id` from `have` to `want` levels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct LevelFetch {
    id: TileId,
    have: usize,
    want: usize,
}

impl Request for LevelFetch {
    fn tile(&self) -> TileId {
        self.id
    }
}

/// Streams tiles level by level around the viewpoint under a memory limit (see the module doc).
pub struct StreamPager<L: LevelLoader> {
    loader: Arc<L>,
    config: StreamConfig,
    ledger: Ledger,
    tiles: BTreeMap<TileId, L::Loaded>,
    queue: RequestQueue,
    /// Why each request in flight was made.
    reasons: HashMap<TileId, Reason>,
    link: Link<LevelFetch, L::Piece>,
    started: Instant,
    time: f64,
    center: Option<TileId>,
    complete: Option<u32>,
    memory_bound: bool,
    now: u64,
    stats: StreamStats,
    fetches: u64,
    evictions: u64,
    errors: u64,
    last_error: Option<String>,
}

impl<L: LevelLoader> StreamPager<L> {
    /// A pager for `grid` with nothing loaded; starts the fetch thread in threaded mode.
    pub fn new(loader: L, grid: Grid, config: StreamConfig) -> Result<Self> {
        let loader = Arc::new(loader);
        let link = config.mode.link(fetch_job(Arc::clone(&loader)))?;
        if !(config.square_share > 0.0 && config.square_share <= 1.0) {
            return Err(Error::Usage(format!(
                "the coarse square's share of memory must be in (0, 1], not {}",
                config.square_share
            )));
        }
        Ok(StreamPager {
            loader,
            config,
            ledger: Ledger::new(grid, config.memory_limit_bytes, config.retry),
            tiles: BTreeMap::new(),
            queue: RequestQueue::new(config.queue_capacity),
            reasons: HashMap::new(),
            link,
            started: Instant::now(),
            time: 0.0,
            center: None,
            complete: None,
            memory_bound: false,
            now: 0,
            stats: StreamStats::default(),
            fetches: 0,
            evictions: 0,
            errors: 0,
            last_error: None,
        })
    }

    /// Sets the time, seconds, for simulated and stepped modes (never moves it back); threaded
    /// mode runs on the wall clock.
    pub fn set_time(&mut self, seconds: f64) {
        self.time = self.time.max(seconds);
    }

    /// Times transfers in [`PagerMode::Simulated`].
    pub fn set_transfer_clock(&mut self, clock: Arc<dyn TransferClock>) {
        self.link.set_transfer_clock(clock);
    }

    /// Seconds since the pager started: the wall clock when threaded, else the time set.
    pub fn time(&self) -> f64 {
        match self.config.mode {
            PagerMode::Threaded { .. } => self.started.elapsed().as_secs_f64(),
            PagerMode::Stepped { .. } | PagerMode::Simulated { .. } => self.time,
        }
    }

    /// Once per frame, before culling: takes in what arrived and finds the complete square.
    /// `viewer` is the viewpoint in tile units, as for the belt pager.
    pub fn update(&mut self, viewer: (f64, f64)) {
        self.now += 1;
        self.center = self
            .ledger
            .grid()
            .locate(viewer, self.config.nearest_when_off);
        self.receive();
        self.ledger.tick(self.now);
        let now = self.time();
        self.stats.settle(now);
        // `d_c` at the coarsest level: every tile of belts `0..=d_c` holds a level (or was
        // given up). With one cost at every ring no held tile counts as needing an upgrade.
        self.complete = self
            .center
            .and_then(|c| self.ledger.complete_belts(c, |_, _| 0));
    }

    /// Once per frame, after the engine weighed the held tiles: turns `wants` and the belt
    /// fill into requests, re-prioritises the queue and sends what fits.
    pub fn request(&mut self, wants: &[Want]) {
        let candidates = self.candidates(wants);
        let cancelled = self.queue.reprioritise(candidates);
        self.stats.cancelled += cancelled.len() as u64;
        // Each tile's strongest wish: the most levels and the highest priority asked.
        let mut wanted: HashMap<TileId, Want> = HashMap::new();
        for w in wants {
            wanted
                .entry(w.id)
                .and_modify(|m| {
                    m.levels = m.levels.max(w.levels);
                    m.priority = m.priority.max(w.priority);
                })
                .or_insert(*w);
        }
        match self.config.mode {
            PagerMode::Threaded { queue_depth } | PagerMode::Simulated { queue_depth } => {
                while self.ledger.fetching() < queue_depth {
                    if !self.send_next(&wanted) {
                        break;
                    }
                }
            }
            PagerMode::Stepped { fetches_per_update } => {
                for _ in 0..fetches_per_update {
                    if !self.send_next(&wanted) {
                        break;
                    }
                }
            }
        }
    }

    /// Tells the pager which levels the frame drew: `(tile, levels)` for each drawn tile, the
    /// progressive levels its mask used.
    pub fn drawn(&mut self, drawn: impl IntoIterator<Item = (TileId, usize)>) {
        let now = self.time();
        for (id, levels) in drawn {
            self.stats.rendered(id, levels, now);
        }
    }

    /// After the loader's settings changed (the crack mode): refits every resident tile and
    /// accounts what it holds now, dropping the finest levels of the farthest tiles while the
    /// total would exceed the limit.
    pub fn refit(&mut self) {
        let center = self.center;
        let mut ids: Vec<TileId> = self.tiles.keys().copied().collect();
        ids.sort_by_key(|&id| std::cmp::Reverse(center.map_or(0, |c| Grid::ring(c, id))));
        let mut sizes: Vec<(TileId, usize)> = ids
            .iter()
            .map(|&id| {
                let tile = self.tiles.get_mut(&id).expect("listed");
                (id, self.loader.refit(tile))
            })
            .collect();
        let held = |ledger: &Ledger, id| ledger.record(id).held.map_or(0, |h| h.bytes);
        let mut total: usize = self.ledger.memory()
            - sizes
                .iter()
                .map(|&(id, _)| held(&self.ledger, id))
                .sum::<usize>()
            + sizes.iter().map(|&(_, b)| b).sum::<usize>();
        for (id, bytes) in &mut sizes {
            if total <= self.config.memory_limit_bytes {
                break;
            }
            let tile = self.tiles.get_mut(id).expect("listed");
            let smaller = self.loader.drop_levels(tile, 1);
            total -= *bytes - smaller;
            *bytes = smaller;
        }
        sizes.sort_by_key(|&(id, bytes)| bytes > held(&self.ledger, id));
        for (id, bytes) in sizes {
            if let Err(e) = self.ledger.resize_held(id, bytes) {
                self.record_error(e.to_string());
                self.ledger.evict(id);
                self.tiles.remove(&id);
                self.evictions += 1;
            }
        }
    }

    /// The tile under the viewpoint at the last update.
    pub fn current_tile(&self) -> Option<TileId> {
        self.center
    }

    /// The resident tiles, row-major.
    pub fn tiles(&self) -> impl Iterator<Item = (TileId, &L::Loaded)> {
        self.tiles.iter().map(|(id, t)| (*id, t))
    }

    /// The resident copies by tile.
    pub fn resident(&self) -> &BTreeMap<TileId, L::Loaded> {
        &self.tiles
    }

    /// The resident copy of `id`, if any.
    pub fn get(&self, id: TileId) -> Option<&L::Loaded> {
        self.tiles.get(&id)
    }

    /// The waiting requests, best first.
    pub fn queue(&self) -> &RequestQueue {
        &self.queue
    }

    /// Where `id` stands.
    pub fn state(&self, id: TileId) -> TileState {
        let record = self.ledger.record(id);
        let in_square = match (self.center, self.complete) {
            (Some(c), Some(d)) => Grid::ring(c, id) <= d,
            _ => false,
        };
        if record.fetch.is_some() {
            TileState::Fetching
        } else if record.held.is_some() && in_square {
            TileState::Square
        } else if record.held.is_some() {
            TileState::Cached
        } else if record.failure.is_some() {
            TileState::Failed
        } else {
            TileState::Absent
        }
    }

    /// The counters shared with the belt pager.
    pub fn stats(&self) -> PagerStats {
        PagerStats {
            memory_bytes: self.ledger.memory(),
            memory_peak_bytes: self.ledger.peak(),
            memory_limit_bytes: self.ledger.limit(),
            loaded_tiles: self.tiles.len(),
            fetching: self.ledger.fetching(),
            complete_belts: self.complete,
            memory_bound: self.memory_bound,
            downloaded_bytes: self.stats.received_bytes,
            fetches: self.fetches,
            evictions: self.evictions,
            errors: self.errors,
            failed_tiles: self.ledger.failed_tiles(),
        }
    }

    /// The streaming counters: requests, cancellations, bytes rendered within a second,
    /// prediction hits.
    pub fn stream_stats(&self) -> &StreamStats {
        &self.stats
    }

    /// The message of the last error, if any.
    pub fn last_error(&self) -> Option<&str> {
        self.last_error.as_deref()
    }

    /// The accounting.
    pub fn ledger(&self) -> &Ledger {
        &self.ledger
    }

    /// The loader.
    pub fn loader(&self) -> &L {
        &self.loader
    }

    /// Progressive levels `id` holds (0 when absent).
    pub fn held_levels(&self, id: TileId) -> usize {
        self.tiles
            .get(&id)
            .map_or(0, |t| self.loader.held_levels(t))
    }

    /// This frame's requests: the coarse level of belt `d_c + 1` while the coarse square fits
    /// its share, and each wished-for tile's next level.
    fn candidates(&mut self, wants: &[Want]) -> Vec<LevelRequest> {
        let mut out = Vec::new();
        self.memory_bound = false;
        if let Some(center) = self.center {
            let grid = self.ledger.grid();
            let next = self.complete.map_or(0, |d| d + 1);
            if next <= grid.max_ring(center) {
                let square: usize = (0..=next).map(|d| grid.belt(center, d).len()).sum();
                let coarse = square.saturating_mul(self.loader.predicted_bytes(1));
                if coarse as f64 <= self.config.square_share * self.config.memory_limit_bytes as f64
                {
                    for id in grid.belt(center, next) {
                        if self.can_request(id) && !self.tiles.contains_key(&id) {
                            out.push(LevelRequest {
                                id,
                                levels: 1,
                                priority: BELT_PRIORITY / f64::from(1 + next),
                                reason: Reason::Belt,
                            });
                        }
                    }
                } else {
                    self.memory_bound = true;
                }
            }
        }
        // Levels the current view alone asks for: a request beyond them is the prediction's.
        let mut now_levels: HashMap<TileId, usize> = HashMap::new();
        for w in wants.iter().filter(|w| !w.predicted) {
            let l = now_levels.entry(w.id).or_default();
            *l = (*l).max(w.levels);
        }
        // A tile the view needs comes at its coarsest level first, then in one request up to
        // the levels asked for (one range request: the levels are contiguous).
        for w in wants {
            let have = self.held_levels(w.id);
            let asked = w.levels.min(self.loader.levels());
            if have < asked && self.can_request(w.id) {
                let (levels, priority) = if have == 0 {
                    (1, COARSE_PRIORITY)
                } else {
                    (asked, w.priority)
                };
                out.push(LevelRequest {
                    id: w.id,
                    levels,
                    priority,
                    reason: if levels > now_levels.get(&w.id).copied().unwrap_or(0) {
                        Reason::Predicted
                    } else {
                        Reason::View
                    },
                });
            }
        }
        out
    }

    /// Whether a request for `id` may be made now: none in flight, not failed or waiting.
    fn can_request(&self, id: TileId) -> bool {
        let r = self.ledger.record(id);
        r.fetch.is_none() && r.failure.is_none() && self.ledger.grid().contains(id)
    }

    /// Sends the best waiting request that is still valid; false when there is none or it does
    /// not fit in memory even after making room (it waits then).
    fn send_next(&mut self, wanted: &HashMap<TileId, Want>) -> bool {
        while let Some(request) = self.queue.pop() {
            let have = self.held_levels(request.id);
            if request.levels <= have || !self.can_request(request.id) {
                continue;
            }
            let bytes = self.loader.predicted_bytes(request.levels)
                - if have == 0 {
                    0
                } else {
                    self.loader.predicted_bytes(have)
                };
            if !self.make_room(bytes, &request, wanted) {
                self.queue.push_back(request);
                self.memory_bound = true;
                return false;
            }
            let ring = self.center.map_or(0, |c| Grid::ring(c, request.id));
            let fetch = Fetch {
                id: request.id,
                ring,
                bytes,
            };
            let reserved = if have == 0 {
                self.ledger.reserve(fetch)
            } else {
                self.ledger.reserve_addition(fetch)
            };
            if let Err(e) = reserved {
                self.record_error(e.to_string());
                return false;
            }
            self.stats.requests += 1;
            self.reasons.insert(request.id, request.reason);
            let level_fetch = LevelFetch {
                id: request.id,
                have,
                want: request.levels,
            };
            match self.config.mode {
                PagerMode::Threaded { .. } => {
                    if let Err(e) = self.link.send(level_fetch) {
                        self.ledger.fail(level_fetch.id, self.now);
                        self.record_error(e.to_string());
                    }
                }
                PagerMode::Simulated { .. } => self.link.schedule(level_fetch, self.time),
                PagerMode::Stepped { .. } => {
                    let result = self.link.run_now(level_fetch);
                    self.integrate(level_fetch, result);
                }
            }
            return true;
        }
        false
    }

    /// Frees memory for `bytes` more: fine levels of tiles holding more than asked, then fine
    /// levels of tiles that matter less than `request`, farthest first, then whole cached tiles
    /// outside the square. Changes nothing and returns false when all of that is not enough.
    fn make_room(
        &mut self,
        bytes: usize,
        request: &LevelRequest,
        wanted: &HashMap<TileId, Want>,
    ) -> bool {
        let limit = self.config.memory_limit_bytes;
        let mut free = limit.saturating_sub(self.ledger.memory());
        if free >= bytes {
            return true;
        }
        let center = self.center;
        let ring = |id: TileId| center.map_or(0, |c| Grid::ring(c, id));
        let square = self.complete.map_or(0, |d| d + 1);
        // (class, priority, farther first, tile, finer first) -> drop one level or the tile.
        let mut steps = Vec::new();
        for (&id, tile) in &self.tiles {
            if id == request.id || self.ledger.record(id).fetch.is_some() {
                continue;
            }
            let held = self.loader.held_levels(tile);
            let want = wanted.get(&id);
            let (asked, priority) = want.map_or((0, 0.0), |w| (w.levels, w.priority));
            for level in (2..=held).rev() {
                let class = if level > asked {
                    0
                } else if priority < request.priority {
                    1
                } else {
                    continue;
                };
                let saved =
                    self.loader.predicted_bytes(level) - self.loader.predicted_bytes(level - 1);
                steps.push((class, priority, ring(id), id, level, saved));
            }
            if ring(id) > square && want.is_none() {
                // Its finer levels are steps of their own (it is asked for none), so evicting
                // it saves what is left once they are gone.
                let fine = self.loader.predicted_bytes(held) - self.loader.predicted_bytes(1);
                let saved = self
                    .ledger
                    .record(id)
                    .held
                    .map_or(0, |h| h.bytes.saturating_sub(fine));
                steps.push((2, 0.0, ring(id), id, 1, saved));
            }
        }
        steps.sort_by(|a, b| {
            a.0.cmp(&b.0)
                .then(a.1.total_cmp(&b.1))
                .then(b.2.cmp(&a.2))
                .then(a.3.cmp(&b.3))
                .then(b.4.cmp(&a.4))
        });
        let mut keep: BTreeMap<TileId, usize> = BTreeMap::new();
        for &(_, _, _, id, level, saved) in &steps {
            if free >= bytes {
                break;
            }
            // Only a tile's finest remaining level can go, so levels leave finest first.
            let kept = keep.entry(id).or_insert(self.held_levels(id));
            if *kept != level {
                continue;
            }
            *kept = level - 1;
            free += saved;
        }
        if free < bytes {
            return false;
        }
        for (id, levels) in keep {
            let ring = ring(id);
            if levels == 0 {
                self.ledger.evict(id);
                self.tiles.remove(&id);
                self.evictions += 1;
                continue;
            }
            let Some(tile) = self.tiles.get_mut(&id) else {
                continue;
            };
            let held = self.loader.drop_levels(tile, levels);
            self.stats.dropped_levels += 1;
            if let Err(e) = self.ledger.shrink(id, held, ring) {
                self.record_error(e.to_string());
                self.ledger.evict(id);
                self.tiles.remove(&id);
                self.evictions += 1;
            }
        }
        true
    }

    /// Takes in every result the fetch thread sent, or every simulated transfer that ended.
    fn receive(&mut self) {
        let received = self.link.receive(self.time, &mut self.ledger, self.now);
        for (fetch, result) in received.arrivals {
            self.integrate(fetch, result);
        }
        for e in received.errors {
            self.record_error(e.to_string());
        }
    }

    fn integrate(&mut self, fetch: LevelFetch, result: Result<(L::Piece, u64)>) {
        let id = fetch.id;
        let reason = self.reasons.remove(&id).unwrap_or_default();
        let merged = result.and_then(|(piece, downloaded)| {
            let mut tile = self.loader.merge(id, self.tiles.get(&id), piece)?;
            let levels = self.loader.held_levels(&tile);
            if levels != fetch.want {
                return Err(Error::invalid(
                    id.to_string(),
                    format!("it holds {levels} levels after a fetch of {}", fetch.want),
                ));
            }
            let bytes = self.loader.refit(&mut tile);
            Ok((tile, bytes, downloaded))
        });
        match merged {
            Ok((tile, bytes, downloaded)) => match self.ledger.arrive(id, bytes, self.now) {
                Ok(()) => {
                    self.tiles.insert(id, tile);
                    self.fetches += 1;
                    let now = self.time();
                    self.stats.received(Delivery {
                        id,
                        levels: fetch.want,
                        bytes: downloaded,
                        at: now,
                        reason,
                    });
                }
                Err(e) => self.record_error(e.to_string()),
            },
            Err(e) => {
                self.ledger.fail(id, self.now);
                let outcome = match self.ledger.record(id).failure {
                    Some(Failure::GaveUp) => "given up",
                    _ => "will retry",
                };
                self.record_error(format!(
                    "{id} (levels {}..{}, {outcome}): {e}",
                    fetch.have, fetch.want
                ));
            }
        }
    }

    fn record_error(&mut self, message: String) {
        self.errors += 1;
        self.last_error = Some(message);
    }
}

/// The stream pager's job: the loader's fetch of a level range.
fn fetch_job<L: LevelLoader>(loader: Arc<L>) -> Job<LevelFetch, L::Piece> {
    Arc::new(move |f: LevelFetch| loader.fetch(f.id, f.have, f.want))
}
