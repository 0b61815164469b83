//! The paper's pager: Algorithm 1 of [`super::belts`] driving a [`TileLoader`], beside the frame
//! loop, with whole tiles.
//!
//! Call [`Pager::update`] once at the start of every frame with the viewpoint: it takes in the
//! tiles that arrived, shrinks tiles that moved to a farther belt, evicts cache and starts the
//! next fetches of belt `d_c + 1`, all without waiting on I/O in [`PagerMode::Threaded`]. The
//! frame then draws the resident tiles. [`PagerMode::Stepped`] runs a fixed number of fetches
//! synchronously inside each update instead, which makes a run reproducible.
//! [`PagerMode::Simulated`] is reproducible too and also models the link: each fetch runs when it
//! is planned, but its tile arrives only once the simulated time ([`Pager::set_time`]) passes the
//! moment its transfer would end on a link that carries one request at a time, as timed by a
//! [`TransferClock`]. Either way the accounted memory, reservations of fetches in flight
//! included, never exceeds the limit.

use std::marker::PhantomData;
use std::sync::Arc;

use super::belts::{self, Plan};
use super::far::{FarField, URGENT_PX};
use super::ledger::Fetch;
use super::stream::Want;
use super::worker::Job;
use super::{Pager, PagerConfig, PagerMode, ResidentLoader, Strategy};
use crate::db::grid::{Pyramid, TileId};
use crate::db::source::CancelToken;
use crate::error::Result;

/// What the engine gives the pager: costs known before fetching, fetching itself, and shrinking.
pub trait TileLoader: ResidentLoader {
    /// Bytes a tile will hold once loaded for belt distance `ring` (known before fetching).
    fn predicted_bytes(&self, id: TileId, ring: u32) -> usize;
    /// Fetches and decodes a tile for belt distance `ring` (on the fetch thread in threaded
    /// mode). Returns the tile and the bytes downloaded.
    fn load(&self, id: TileId, ring: u32) -> Result<(Self::Loaded, u64)>;
    /// Drops detail a tile no longer needs at the larger belt distance `ring` (for example its
    /// finest texture mips); returns the bytes it holds now, never more than before.
    fn shrink(&self, tile: &mut Self::Loaded, ring: u32) -> usize;
    /// Brings a tile loaded (or fetched) under earlier settings of this loader to its current
    /// ones, for belt distance `ring`; returns the bytes it holds now, which may be more than
    /// before (see [`Pager::refit`]). A loader whose settings never change keeps the default,
    /// which changes nothing.
    fn refit(&self, tile: &mut Self::Loaded, ring: u32) -> usize {
        let _ = ring;
        self.loaded_bytes(tile)
    }
}

/// The paper's strategy: whole tiles, Algorithm 1 choosing the next level-0 fetches (the
/// ledger says everything it needs), and the far field the tiles of the levels above that the
/// frame's cut asks for.
pub struct Belts<L> {
    far: FarField,
    loader: PhantomData<fn() -> L>,
}

/// Pages whole tiles in belts around the viewpoint under a memory limit (see the module doc).
pub type BeltPager<L> = Pager<Belts<L>>;

impl<L: TileLoader> Strategy for Belts<L> {
    type Loader = L;
    type Tile = L::Loaded;
    type Request = Fetch;
    type Piece = L::Loaded;

    fn job(loader: Arc<L>) -> Job<Fetch, L::Loaded> {
        Arc::new(move |fetch: Fetch, _: &CancelToken| loader.load(fetch.id, fetch.ring))
    }

    fn refit_top(loader: &L, tile: &mut L::Loaded) -> usize {
        loader.refit(tile, 0)
    }

    /// Takes in arrived tiles, shrinks tiles that are now farther, evicts and schedules.
    fn update(pager: &mut BeltPager<L>, viewer: (f64, f64)) {
        // The belt pager never cancels: nothing comes back cut.
        let (arrivals, _) = pager.begin(viewer);
        for (fetch, result) in arrivals {
            pager.integrate(fetch, result);
        }
        pager.shrink();
        if pager.top_pending() {
            // The top comes first.
        } else if let PagerMode::Stepped { fetches_per_update } = pager.mode {
            // One fetch at a time, re-planning after each arrival: a run is reproducible.
            for _ in 0..fetches_per_update {
                let Some(fetch) = pager.next_fetch() else {
                    break;
                };
                pager.fetch(fetch);
            }
        } else {
            // The urgent far tiles, then Algorithm 1's, then the rest of the far field's.
            let room = pager.mode.room(pager.resident.ledger.fetching());
            for fetch in pager.plan_far(room, URGENT_PX) {
                pager.fetch(fetch);
            }
            let plan = pager.plan(pager.mode.room(pager.resident.ledger.fetching()));
            for &fetch in &plan.fetch {
                pager.fetch(fetch);
            }
            let room = pager.mode.room(pager.resident.ledger.fetching());
            for fetch in pager.plan_far(room, 0.0) {
                pager.fetch(fetch);
            }
        }
        let loader = &*pager.loader;
        let r = &mut pager.resident;
        r.complete = r.center.and_then(|c| {
            belts::complete_belts(&r.ledger, c, |id, ring| loader.predicted_bytes(id, ring))
        });
    }

    /// Hears which tiles of the levels above 0 the frame's cut asks for.
    fn request(pager: &mut BeltPager<L>, wants: &[Want]) {
        let now = pager.resident.now;
        pager.strategy.far.hear(wants, now);
    }

    /// Refits every loaded tile ([`TileLoader::refit`]) and accounts what it holds now,
    /// evicting the tiles farthest from the current one while the total would exceed the limit,
    /// then re-reserves every fetch in flight at the new prediction where that fits. A fetch
    /// whose grown reservation does not fit keeps its old one: its tile, refit on arrival,
    /// holds more than reserved and is refused and fetched again later, so the accounted bytes
    /// never exceed the limit. Tiles loaded under the old settings that arrive later are refit
    /// on arrival.
    fn refit(pager: &mut BeltPager<L>) {
        let r = &mut pager.resident;
        let mut resized = Vec::new();
        for (&id, tile) in &mut r.tiles {
            let loaded = r
                .ledger
                .record(id)
                .loaded
                .expect("a resident tile is loaded");
            resized.push((id, loaded.bytes, pager.loader.refit(tile, loaded.ring)));
        }
        resized.sort_by_key(|&(id, _, _)| std::cmp::Reverse(r.ring(id)));
        let grown: usize = resized
            .iter()
            .map(|&(_, old, new)| new.saturating_sub(old))
            .sum();
        let shrunk: usize = resized
            .iter()
            .map(|&(_, old, new)| old.saturating_sub(new))
            .sum();
        let mut total = r.ledger.memory() + grown - shrunk;
        let mut kept = Vec::new();
        for (id, _, new) in resized {
            if total > r.ledger.limit() {
                total -= new;
                r.evict(id);
            } else {
                kept.push((id, new));
            }
        }
        r.resize(kept);
        let fetching: Vec<(TileId, u32)> = r
            .ledger
            .records()
            .filter_map(|(id, rec)| rec.fetch.map(|f| (id, f.ring)))
            .collect();
        for (id, ring) in fetching {
            // Too large to fit: keeps the old reservation, as documented above.
            let _ = r
                .ledger
                .resize_reservation(id, pager.loader.predicted_bytes(id, ring));
        }
    }
}

impl<L: TileLoader> BeltPager<L> {
    /// A pager for the tiles of `pyramid` with nothing loaded; starts the fetch thread in
    /// threaded mode.
    pub fn new(loader: L, pyramid: Pyramid, config: PagerConfig) -> Result<Self> {
        let strategy = Belts {
            far: FarField::new(config.far_share),
            loader: PhantomData,
        };
        Pager::with_strategy(loader, pyramid, config, strategy)
    }

    /// Algorithm 1's next step for at most `max_fetches` fetches, leaving the far field its
    /// share; evicts what it says.
    fn plan(&mut self, max_fetches: usize) -> Plan {
        let loader = &*self.loader;
        let share = self.strategy.far.share(self.resident.ledger.limit());
        let reserved = share.saturating_sub(FarField::bytes(&self.resident));
        let plan = belts::plan(
            &self.resident.ledger,
            self.resident.center,
            max_fetches,
            reserved,
            |id, ring| loader.predicted_bytes(id, ring),
        );
        self.resident.memory_bound = plan.full;
        for &id in &plan.evict {
            self.resident.evict(id);
        }
        plan
    }

    /// The next single fetch: an urgent far tile's, else Algorithm 1's, else the far field's.
    fn next_fetch(&mut self) -> Option<Fetch> {
        let urgent = self.plan_far(1, URGENT_PX).first().copied();
        urgent
            .or_else(|| self.plan(1).fetch.first().copied())
            .or_else(|| self.plan_far(1, 0.0).first().copied())
    }

    /// The far field's next at most `max_fetches` fetches of at least `min_priority` (it
    /// evicts what it makes room with).
    fn plan_far(&mut self, max_fetches: usize, min_priority: f64) -> Vec<Fetch> {
        let loader = &*self.loader;
        self.strategy
            .far
            .plan(&mut self.resident, max_fetches, min_priority, |id, ring| {
                loader.predicted_bytes(id, ring)
            })
    }

    /// Reserves a planned fetch and starts it.
    fn fetch(&mut self, fetch: Fetch) {
        if self.resident.reserve(fetch, false)
            && let Some((fetch, result)) = self.start(fetch)
        {
            self.integrate(fetch, result);
        }
    }

    fn integrate(&mut self, fetch: Fetch, result: Result<(L::Loaded, u64)>) {
        let ring = self
            .resident
            .ledger
            .record(fetch.id)
            .fetch
            .map_or(0, |f| f.ring);
        match result {
            Ok((mut tile, downloaded)) => {
                let bytes = self.loader.refit(&mut tile, ring);
                self.resident.accept(fetch.id, tile, bytes, downloaded);
            }
            Err(e) => self.resident.fail(fetch.id, &format!("ring {ring}"), &e),
        }
    }

    /// Shrinks every loaded tile that is now in a farther belt (of its level) than the one it
    /// holds detail for.
    fn shrink(&mut self) {
        let r = &mut self.resident;
        if r.center.is_none() {
            return;
        }
        let farther: Vec<(TileId, u32)> = r
            .ledger
            .records()
            .filter_map(|(id, rec)| {
                let ring = r.ring(id);
                rec.loaded.filter(|l| ring > l.ring).map(|_| (id, ring))
            })
            .collect();
        for (id, ring) in farther {
            let Some(tile) = r.tiles.get_mut(&id) else {
                continue;
            };
            let bytes = self.loader.shrink(tile, ring);
            r.shrunk(id, bytes, ring);
        }
    }
}
