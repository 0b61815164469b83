//! Progressive streaming: the paper's future work ("fetch tile levels only when needed, load
//! farther tiles at their lowest resolution") as its 2009 follow-up did it.
//!
//! The unit of work is a (tile, level) pair, not a whole tile: a request brings a tile from the
//! `k` progressive levels it holds to `m > k` with one range request ([`crate::db::tile`] stores
//! each level as a separate chunk, coarse first, so levels `k..m` are contiguous bytes). The
//! engine asks for as many levels as the mask the budget buys it (no finer than the error bound
//! τ needs) uses. Each frame:
//!
//! 1. [`StreamPager::update`] takes in what arrived (merging a finer level into the resident
//!    tile) and finds `d_c`, the complete square of belts held at the coarsest level at least;
//! 2. the engine culls and weighs the held tiles, asks the budget which mask each would get if
//!    it held every level, and tells [`StreamPager::request`] how many levels each wants and how
//!    much it matters (the screen error it shows now; the predicted view's wishes count half),
//!    and which absent tiles of the belts the view (or the predicted view) meets;
//! 3. the pager passes the wishes through [`Wishes`] (hysteresis: a wish rises at once and falls
//!    only after the frames asked for less during [`HOLD_SECONDS`]; meanwhile its request waits
//!    unsent in frames that ask for less) and turns them into requests — a tile over which the view
//!    has nothing to draw comes above everything, a tile under one drawn too coarse by that tile's
//!    error, in one range request up to the levels it is wished; a held tile comes up to its wish
//!    in one range request, the worst-looking first; and, when
//!    [`StreamSettings::square_share`] allows it, the coarse level of each tile of belt
//!    `d_c + 1` (Algorithm 1 at the coarsest level) comes when nothing a view asks for waits —
//!    cancels the requests on their way that bring more than their tile is
//!    still wished, or whose tile no view asks for and whose transfer has not started (where the
//!    link can: the simulated link drops the transfer), re-prioritises its bounded [`RequestQueue`]
//!    with them, cancelling what fell out before it was sent, and sends the best while the link has
//!    room;
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
mod wishes;

use std::collections::BTreeMap;
use std::fmt;
use std::marker::PhantomData;
use std::sync::Arc;

pub use predict::{PredictedView, PredictionSettings, Predictor};
pub use queue::{LevelRequest, Reason, RequestQueue};
pub use stats::{Delivery, HIT_WINDOW, RENDER_WINDOW, StreamStats};
pub use wishes::{HOLD_SECONDS, Wishes};

use super::belts;
use super::ledger::{Fetch, Ledger};
use super::worker::Job;
use super::{Pager, PagerConfig, PagerMode, ResidentLoader, Strategy};
use crate::db::grid::{Grid, Pyramid, TileId, TileMap};
use crate::db::source::CancelToken;
use crate::error::{Error, Result};
use crate::named::Named;

/// How tiles come in.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Streaming {
    /// The paper's way: whole tiles, belt by belt ([`super::BeltPager`]).
    #[default]
    Belts,
    /// Progressive levels as the view needs them ([`StreamPager`]).
    Progressive(StreamSettings),
}

/// `belts`, and `progressive` with [`StreamSettings::default`].
impl Named for Streaming {
    const KIND: &'static str = "streaming";

    fn all() -> Vec<Self> {
        vec![
            Streaming::Belts,
            Streaming::Progressive(StreamSettings::default()),
        ]
    }

    fn name(&self) -> &'static str {
        match self {
            Streaming::Belts => "belts",
            Streaming::Progressive(_) => "progressive",
        }
    }
}

/// The settings of progressive streaming an engine is built with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreamSettings {
    /// Requests waiting to be sent, at most.
    pub queue_capacity: usize,
    /// The most of the memory limit the coarse square of belts may take while it fills ahead
    /// of the view at the coarsest level; 0, the default, fills nothing: the archive's top
    /// already covers every view, and the fill's levels are seldom drawn within a second.
    pub square_share: f64,
    /// Prefetching for the predicted view, or none (the default: a guess that misses spends
    /// bytes no frame draws, docs/streaming.md).
    pub prediction: Option<PredictionSettings>,
}

impl Default for StreamSettings {
    fn default() -> Self {
        StreamSettings {
            queue_capacity: 32,
            square_share: 0.0,
            prediction: None,
        }
    }
}

/// Priority of the coarsest level of a belt tile no view needs yet, at ring `ring`: below any
/// refinement a view asks for (a wish's priority, the error its tile shows, is never
/// negative), so on a slow link the square grows while the link would otherwise idle, never
/// instead of the detail on screen; nearer rings first.
fn belt_priority(ring: u32) -> f64 {
    -f64::from(1 + ring)
}

/// What the engine gives the stream pager: level costs known before fetching, fetching a range
/// of levels, and merging them into the resident tile.
pub trait LevelLoader: ResidentLoader {
    /// Fetched levels not yet merged (made on the fetch thread).
    type Piece: Send + 'static;
    /// Progressive levels of a whole tile.
    fn levels(&self) -> usize;
    /// Bytes a tile holding `levels` progressive levels holds.
    fn predicted_bytes(&self, levels: usize) -> usize;
    /// Fetches levels `have..want` of `id` with one range request, stopping with
    /// [`Error::Cancelled`] once `cancel` is raised where the source can; returns them and the
    /// bytes downloaded.
    fn fetch(
        &self,
        id: TileId,
        have: usize,
        want: usize,
        cancel: &CancelToken,
    ) -> Result<(Self::Piece, u64)>;
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
    /// Whether a resident tile is absent (every sample nodata; it holds every level at once).
    fn is_absent(&self, tile: &Self::Loaded) -> bool;
    /// Keeps only the first `levels` levels; returns the bytes held now.
    fn drop_levels(&self, tile: &mut Self::Loaded, levels: usize) -> usize;
    /// Brings a tile to the loader's current settings (see [`StreamPager::refit`]); returns its
    /// bytes.
    fn refit(&self, tile: &mut Self::Loaded) -> usize {
        self.loaded_bytes(tile)
    }
}

/// One tile's wish this frame: `levels` progressive levels, mattering `priority` (the screen
/// error in pixels it shows at the levels it holds, never negative). A tile may have several
/// (the current and the predicted view's).
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
    /// Whether the frame draws it: dropping it would show a coarser tile in its place, so a
    /// wish for another tile never evicts it.
    pub drawn: bool,
}

/// Why a step of [`StreamPager::make_room`] may drop what it drops, in the order they go.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum RoomClass {
    /// A level finer than its tile is asked for.
    Unasked,
    /// A level of a tile that matters less than the request.
    LessImportant,
    /// A whole tile of the cache outside the square.
    Cache,
}

/// One way to make room: drop `level` of tile `id` (level 1: the whole tile), saving `saved`
/// bytes.
struct RoomStep {
    class: RoomClass,
    priority: f64,
    ring: u32,
    id: TileId,
    level: usize,
    saved: usize,
}

/// A request on its way: bring `id` from `have` to `want` levels, asked for `reason`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LevelFetch {
    id: TileId,
    have: usize,
    want: usize,
    reason: Reason,
}

impl fmt::Display for LevelFetch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} levels {}..{}", self.id, self.have, self.want)
    }
}

/// The progressive strategy's own state: the bounded request queue, the wishes it acts on, each
/// request in flight and why it was made, and the streaming counters.
pub struct Progressive<L> {
    square_share: f64,
    queue: RequestQueue,
    wishes: Wishes,
    /// Each request on its way, why it was made and when it was sent.
    flights: TileMap<(LevelFetch, Reason, f64)>,
    /// When the last two updates were: the frame interval the link is paced by.
    updates: (Option<f64>, Option<f64>),
    stats: StreamStats,
    loader: PhantomData<fn() -> L>,
}

/// Streams tiles level by level around the viewpoint under a memory limit (see the module doc).
pub type StreamPager<L> = Pager<Progressive<L>>;

impl<L: LevelLoader> Strategy for Progressive<L> {
    type Loader = L;
    type Tile = L::Loaded;
    type Request = LevelFetch;
    type Piece = L::Piece;

    fn job(loader: Arc<L>) -> Job<LevelFetch, L::Piece> {
        Arc::new(move |f: LevelFetch, cancel: &CancelToken| {
            loader.fetch(f.id, f.have, f.want, cancel)
        })
    }

    fn refit_top(loader: &L, tile: &mut L::Loaded) -> usize {
        loader.refit(tile)
    }

    /// Before culling: takes in what arrived and finds the complete square.
    fn update(pager: &mut StreamPager<L>, viewer: (f64, f64)) {
        let updates = &mut pager.strategy.updates;
        *updates = (updates.1, Some(pager.resident.time()));
        let (arrivals, cut) = pager.begin(viewer);
        for (fetch, result) in arrivals {
            pager.integrate(fetch, result);
        }
        for (fetch, bytes) in cut {
            pager.strategy.stats.crossed(bytes, fetch.reason);
        }
        let now = pager.resident.time();
        pager.strategy.stats.settle(now);
        // `d_c` at the coarsest level: every level-0 tile of belts `0..=d_c` holds a level (or
        // was given up). With one cost at every ring no held tile counts as needing an upgrade.
        let r = &mut pager.resident;
        r.complete = r
            .center
            .and_then(|c| belts::complete_belts(&r.ledger, c, |_, _| 0));
    }

    /// Refits every resident tile and accounts what it holds now, dropping the finest levels of
    /// the farthest tiles while the total would exceed the limit.
    fn refit(pager: &mut StreamPager<L>) {
        let r = &mut pager.resident;
        let mut ids: Vec<TileId> = r.tiles.keys().copied().collect();
        ids.sort_by_key(|&id| std::cmp::Reverse(r.ring(id)));
        let mut sizes: Vec<(TileId, usize)> = ids
            .iter()
            .map(|&id| {
                let tile = r.tiles.get_mut(&id).expect("listed");
                (id, pager.loader.refit(tile))
            })
            .collect();
        let loaded = |ledger: &Ledger, id| ledger.record(id).loaded.map_or(0, |l| l.bytes);
        let mut total: usize = r.ledger.memory()
            - sizes
                .iter()
                .map(|&(id, _)| loaded(&r.ledger, id))
                .sum::<usize>()
            + sizes.iter().map(|&(_, b)| b).sum::<usize>();
        for (id, bytes) in &mut sizes {
            if total <= r.ledger.limit() {
                break;
            }
            let tile = r.tiles.get_mut(id).expect("listed");
            let smaller = pager.loader.drop_levels(tile, 1);
            total -= *bytes - smaller;
            *bytes = smaller;
        }
        r.resize(sizes);
    }

    fn request(pager: &mut StreamPager<L>, wants: &[Want]) {
        if !pager.top_pending() {
            pager.request(wants);
        }
    }

    fn drawn(pager: &mut StreamPager<L>, drawn: &[(TileId, usize)]) {
        pager.drawn(drawn.iter().copied());
    }

    fn stream_stats(pager: &StreamPager<L>) -> Option<&StreamStats> {
        Some(&pager.strategy.stats)
    }
}

impl<L: LevelLoader> StreamPager<L> {
    /// A pager for the tiles of `pyramid` with nothing loaded, sharing its memory and queue as
    /// `settings` say; starts the fetch thread in threaded mode.
    pub fn new(
        loader: L,
        pyramid: Pyramid,
        config: PagerConfig,
        settings: StreamSettings,
    ) -> Result<Self> {
        if !(0.0..=1.0).contains(&settings.square_share) {
            return Err(Error::setting(
                "the coarse square's share of memory",
                settings.square_share,
                "a share in [0, 1]",
            ));
        }
        let strategy = Progressive {
            square_share: settings.square_share,
            queue: RequestQueue::new(settings.queue_capacity),
            wishes: Wishes::default(),
            flights: TileMap::default(),
            updates: (None, None),
            stats: StreamStats::default(),
            loader: PhantomData,
        };
        Pager::with_strategy(loader, pyramid, config, strategy)
    }

    /// Once per frame, after the engine weighed the held tiles: turns `wants` (through the
    /// hysteresis of [`Wishes`]) and the belt fill into requests, cancels what is on its way
    /// and no longer wished for where the link allows, re-prioritises the queue and sends what
    /// fits.
    pub fn request(&mut self, wants: &[Want]) {
        let now = self.resident.time();
        let interval = match self.strategy.updates {
            (Some(before), Some(last)) if last > before => Some(last - before),
            _ => None,
        };
        let mut wanted = self.strategy.wishes.update(wants, now);
        // What this frame asks for; a held wish beyond it keeps its request waiting unsent.
        let mut asks: TileMap<usize> = TileMap::default();
        // Levels the current view alone asks for: a request beyond them is the prediction's.
        let mut view: TileMap<usize> = TileMap::default();
        for (id, w) in wishes::merge(wants) {
            asks.insert(id, w.levels);
            if self.held_levels(id) == 0 {
                // A tile nobody holds comes up to its wish in its first request.
                let levels = wanted.get(&id).map_or(0, |h| h.levels).max(w.levels);
                wanted.insert(id, Want { levels, ..w });
            }
        }
        for w in wants.iter().filter(|w| !w.predicted) {
            let levels = view.entry(w.id).or_default();
            *levels = (*levels).max(w.levels);
        }
        // A wish the view made and still holds is the view's, even in a frame asking for less.
        for (id, w) in wanted.iter().filter(|(_, w)| !w.predicted) {
            let levels = view.entry(*id).or_default();
            *levels = (*levels).max(w.levels);
        }
        self.cancel_unwanted(&wanted, &asks, now);
        let candidates = self.candidates(&wanted, &view);
        let cancelled = self.strategy.queue.reprioritise(candidates);
        self.strategy.stats.cancelled += cancelled.len() as u64;
        // A held wish's request waits unsent while this frame asks for nothing more than its
        // tile holds; once the frame asks for more, it goes, up to what the frame asks: levels
        // beyond it would arrive for frames that may not draw them.
        let short: TileMap<usize> = asks
            .iter()
            .filter(|&(&id, &levels)| levels > self.held_levels(id))
            .map(|(&id, &levels)| (id, levels))
            .collect();
        let resting = self
            .strategy
            .queue
            .set_aside(|r| r.reason != Reason::Belt && !short.contains_key(&r.id));
        let stepped = matches!(self.mode, PagerMode::Stepped { .. });
        let mut room = self.mode.room(self.resident.ledger.fetching());
        while room > 0 && self.send_next(&wanted, &short) {
            room = if stepped {
                room - 1
            } else {
                self.mode.room(self.resident.ledger.fetching())
            };
        }
        // Past the queue depth a request still goes while the link would deliver everything it
        // carries before the next frame (a frame interval from now), up to the queue's capacity:
        // on a fast link a view's levels come in one round trip however many tiles need them,
        // and on a slow one no request waits on the link longer than the depth alone lets it.
        if let Some(interval) = interval.filter(|_| !stepped) {
            while self.resident.ledger.fetching() < self.strategy.queue.capacity()
                && self.link.backlog(now).is_some_and(|b| b < interval)
                && self.send_next(&wanted, &short)
            {}
        }
        for r in resting {
            self.strategy.queue.push_back(r);
        }
    }

    /// Cancels, where the link allows, every request on its way that brings more levels than
    /// its tile is wished now, and every one not started yet whose tile this frame does not
    /// ask for at all (`asks`: it left the views, and bytes that arrive while it is out of
    /// them are not drawn; cancelling a transfer not started costs nothing): its reservation
    /// is released, and the bytes that had crossed the link count as received and never drawn.
    /// The belt fill, which no view asks for, is cancelled once its tile is past the belt the
    /// square grows into.
    fn cancel_unwanted(&mut self, wanted: &TileMap<Want>, asks: &TileMap<usize>, now: f64) {
        let link = &self.link;
        // The belt the coarse square grows into, around the current tile.
        let filling = self.resident.center.map(|c| (c, self.resident.next_belt()));
        let mut unwanted: Vec<(LevelFetch, Reason, f64)> = self
            .strategy
            .flights
            .values()
            .filter(|(f, reason, _)| {
                if *reason == Reason::Belt && !wanted.contains_key(&f.id) {
                    // No view asks for the square's fill: it goes on while its tile is within
                    // the belt being filled.
                    return filling.is_none_or(|(c, next)| Grid::ring(c, f.id) > next);
                }
                wanted.get(&f.id).map_or(0, |w| w.levels) < f.want
                    || (!asks.contains_key(&f.id) && link.started(f, now) == Some(false))
            })
            .copied()
            .collect();
        unwanted.sort_by_key(|(f, _, _)| f.id);
        for (fetch, reason, _) in unwanted {
            let Some(crossed) = self.link.cancel(&fetch, now) else {
                continue;
            };
            self.strategy.flights.remove(&fetch.id);
            self.resident.cancel(fetch.id, crossed);
            self.strategy.stats.cut(crossed, reason);
        }
    }

    /// Tells the pager which levels the frame drew: `(tile, levels)` for each drawn tile, the
    /// progressive levels its mask used.
    pub fn drawn(&mut self, drawn: impl IntoIterator<Item = (TileId, usize)>) {
        let now = self.resident.time();
        for (id, levels) in drawn {
            self.strategy.stats.rendered(id, levels, now);
        }
    }

    /// The waiting requests, best first.
    pub fn queue(&self) -> &RequestQueue {
        &self.strategy.queue
    }

    /// The streaming counters: requests, cancellations, bytes rendered within a second,
    /// prediction hits.
    pub fn stream_stats(&self) -> &StreamStats {
        &self.strategy.stats
    }

    /// Progressive levels `id` holds, in its paged copy or the top (0 when absent).
    pub fn held_levels(&self, id: TileId) -> usize {
        self.resident
            .get(id)
            .map_or(0, |t| self.loader.held_levels(t))
    }

    /// Progressive levels of the paged copy of `id` (0 without one).
    fn paged_levels(&self, id: TileId) -> usize {
        self.resident
            .paged(id)
            .map_or(0, |t| self.loader.held_levels(t))
    }

    /// Progressive levels the top holds of `id` (0 when the top does not hold it).
    fn top_levels(&self, id: TileId) -> usize {
        self.resident
            .top_tile(id)
            .map_or(0, |t| self.loader.held_levels(t))
    }

    /// This frame's requests: the coarse level of belt `d_c + 1` while the coarse square fits
    /// its share, and each wished-for tile (`wanted`, held wishes) up to its wish, by priority;
    /// `view` holds the levels the current view alone asks for.
    fn candidates(&mut self, wanted: &TileMap<Want>, view: &TileMap<usize>) -> Vec<LevelRequest> {
        let mut out = Vec::new();
        self.resident.memory_bound = false;
        if let Some(center) = self
            .resident
            .center
            .filter(|_| self.strategy.square_share > 0.0)
        {
            let grid = self.resident.ledger.grid();
            let next = self.resident.next_belt();
            if next <= grid.max_ring(center) {
                let square: usize = (0..=next).map(|d| grid.belt(center, d).len()).sum();
                let coarse = square.saturating_mul(self.loader.predicted_bytes(1));
                let share = self.strategy.square_share * self.resident.ledger.limit() as f64;
                if coarse as f64 <= share {
                    for id in grid.belt(center, next) {
                        if self.can_request(id) && self.resident.get(id).is_none() {
                            out.push(LevelRequest {
                                id,
                                levels: 1,
                                priority: belt_priority(next),
                                reason: Reason::Belt,
                            });
                        }
                    }
                } else {
                    self.resident.memory_bound = true;
                }
            }
        }
        // A tile nobody holds comes in one request up to the levels it is wished (one range
        // request: the levels are contiguous); a held tile comes up to its wish; each by its
        // wish's priority.
        let mut ids: Vec<&TileId> = wanted.keys().collect();
        ids.sort();
        for id in ids {
            let w = wanted[id];
            let have = self.held_levels(w.id);
            if !self.can_request(w.id) {
                continue;
            }
            // A tile over which the view has nothing to draw comes with an infinite priority;
            // a tile under one the view draws too coarse, with that tile's error.
            let priority = w.priority;
            let levels = w.levels.min(self.loader.levels());
            if have < levels {
                out.push(LevelRequest {
                    id: w.id,
                    levels,
                    priority,
                    reason: if levels > view.get(id).copied().unwrap_or(0) {
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
        let r = self.resident.ledger.record(id);
        r.fetch.is_none() && r.failure.is_none() && self.resident.ledger.pyramid().contains(id)
    }

    /// Sends the best waiting request that is still valid, up to no more levels than this frame
    /// asks for its tile (`asked`) when it asks for any more than the tile holds; false when
    /// there is none or it does not fit in memory even after making room (it waits then).
    fn send_next(&mut self, wanted: &TileMap<Want>, asked: &TileMap<usize>) -> bool {
        while let Some(waiting) = self.strategy.queue.pop() {
            let request = LevelRequest {
                levels: asked
                    .get(&waiting.id)
                    .map_or(waiting.levels, |&levels| waiting.levels.min(levels)),
                ..waiting
            };
            let have = self.held_levels(request.id);
            if request.levels <= have || !self.can_request(request.id) {
                continue;
            }
            // A paged copy grows; without one, the new copy holds every level it asks for.
            let paged = self.paged_levels(request.id);
            let bytes = self.loader.predicted_bytes(request.levels)
                - if paged == 0 {
                    0
                } else {
                    self.loader.predicted_bytes(paged)
                };
            if !self.make_room(bytes, &request, wanted) {
                // It waits as it was made: the wish, not this frame's part of it.
                self.strategy.queue.push_back(waiting);
                self.resident.memory_bound = true;
                return false;
            }
            let ring = self.resident.ring(request.id);
            let fetch = Fetch {
                id: request.id,
                ring,
                bytes,
            };
            if !self.resident.reserve(fetch, paged > 0) {
                return false;
            }
            self.strategy.stats.requests += 1;
            let level_fetch = LevelFetch {
                id: request.id,
                have,
                want: request.levels,
                reason: request.reason,
            };
            let sent = self.resident.time();
            self.strategy
                .flights
                .insert(request.id, (level_fetch, request.reason, sent));
            if let Some((fetch, result)) = self.start(level_fetch) {
                self.integrate(fetch, result);
            }
            return true;
        }
        false
    }

    /// Frees memory for `bytes` more: fine levels of tiles holding more than asked, then fine
    /// levels of tiles that matter less than `request`, farthest first, then whole cached tiles
    /// outside the square. Changes nothing and returns false when all of that is not enough.
    fn make_room(&mut self, bytes: usize, request: &LevelRequest, wanted: &TileMap<Want>) -> bool {
        let r = &self.resident;
        let mut free = r.ledger.limit().saturating_sub(r.ledger.memory());
        if free >= bytes {
            return true;
        }
        // Levels each tile keeps: only a tile's finest remaining level can go, so levels leave
        // finest first, and a tile leaves whole once none of its finer levels is left.
        let mut keep: BTreeMap<TileId, usize> = BTreeMap::new();
        for step in self.room_steps(request, wanted) {
            if free >= bytes {
                break;
            }
            let kept = keep.entry(step.id).or_insert(self.paged_levels(step.id));
            if *kept != step.level {
                continue;
            }
            *kept = step.level - 1;
            free += step.saved;
        }
        if free < bytes {
            return false;
        }
        for (id, levels) in keep {
            if levels <= self.top_levels(id) {
                self.resident.evict(id);
                continue;
            }
            let Some(tile) = self.resident.tiles.get_mut(&id) else {
                continue;
            };
            let bytes = self.loader.drop_levels(tile, levels);
            self.strategy.stats.dropped_levels += 1;
            let ring = self.resident.ring(id);
            self.resident.shrunk(id, bytes, ring);
        }
        true
    }

    /// What could go to make room for `request`, in the order it should go: each step drops one
    /// level (its finest first) of a tile holding more than it is asked for, then of a tile
    /// that matters less than `request` (least important, then farthest, first), then a whole
    /// tile of the cache outside the square that nobody asks for.
    fn room_steps(&self, request: &LevelRequest, wanted: &TileMap<Want>) -> Vec<RoomStep> {
        let r = &self.resident;
        let ring = |id: TileId| r.ring(id);
        let square = r.next_belt();
        let predicted = |levels| self.loader.predicted_bytes(levels);
        let mut steps = Vec::new();
        for (id, tile) in r.tiles() {
            if id == request.id || r.ledger.record(id).fetch.is_some() {
                continue;
            }
            let held = self.loader.held_levels(tile);
            let want = wanted.get(&id);
            let (asked, priority) = want.map_or((0, 0.0), |w| (w.levels, w.priority));
            // A paged copy goes whole once it would hold no more than the top.
            let floor = self.top_levels(id);
            for level in (floor.max(1) + 1..=held).rev() {
                let class = if level > asked {
                    RoomClass::Unasked
                } else if priority < request.priority {
                    RoomClass::LessImportant
                } else {
                    continue;
                };
                let saved = predicted(level) - predicted(level - 1);
                steps.push(RoomStep {
                    class,
                    priority,
                    ring: ring(id),
                    id,
                    level,
                    saved,
                });
            }
            let outside = id.level > 0 || ring(id) > square;
            if floor == 0 && outside && want.is_none() {
                // Its finer levels are steps of their own (it is asked for none), so evicting
                // it saves what is left once they are gone.
                let fine = predicted(held) - predicted(1);
                let saved = r
                    .ledger
                    .record(id)
                    .loaded
                    .map_or(0, |l| l.bytes.saturating_sub(fine));
                let (class, priority, level) = (RoomClass::Cache, 0.0, 1);
                steps.push(RoomStep {
                    class,
                    priority,
                    ring: ring(id),
                    id,
                    level,
                    saved,
                });
            }
        }
        steps.sort_by(|a, b| {
            a.class
                .cmp(&b.class)
                .then(a.priority.total_cmp(&b.priority))
                .then(b.ring.cmp(&a.ring))
                .then(a.id.cmp(&b.id))
                .then(b.level.cmp(&a.level))
        });
        steps
    }

    fn integrate(&mut self, fetch: LevelFetch, result: Result<(L::Piece, u64)>) {
        let id = fetch.id;
        let now = self.resident.time();
        let reason = match self.strategy.flights.remove(&id) {
            Some((_, reason, sent)) => {
                self.strategy.stats.arrived_after(now - sent);
                reason
            }
            None => Reason::default(),
        };
        let merged = result.and_then(|(piece, downloaded)| {
            let mut tile = self.loader.merge(id, self.resident.get(id), piece)?;
            let levels = self.loader.held_levels(&tile);
            // An absent tile holds every level at once: nothing is stored of any.
            if levels != fetch.want && !self.loader.is_absent(&tile) {
                return Err(Error::invalid(
                    id.to_string(),
                    format!("it holds {levels} levels after a fetch of {}", fetch.want),
                ));
            }
            let bytes = self.loader.refit(&mut tile);
            Ok((tile, bytes, downloaded))
        });
        match merged {
            Ok((tile, bytes, downloaded)) => {
                if self.resident.accept(id, tile, bytes, downloaded) {
                    self.strategy.stats.received(Delivery {
                        id,
                        levels: fetch.want,
                        bytes: downloaded,
                        at: self.resident.time(),
                        reason,
                    });
                }
            }
            Err(e) => {
                let what = format!("levels {}..{}", fetch.have, fetch.want);
                self.resident.fail(id, &what, &e);
            }
        }
    }
}
