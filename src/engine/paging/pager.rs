//! The pager both strategies share: the loader, what is resident, the link and the strategy's
//! own state, and the face the engine drives it through.

use std::sync::Arc;

use crate::db::grid::{Pyramid, TileId};
use crate::db::source::CancelToken;
use crate::engine::paging::stream::{self, StreamStats};
use crate::engine::paging::top::{TopFetch, TopRequest, TopTiles};
use crate::engine::paging::{
    ArchiveLoader, Job, Link, PagerConfig, PagerMode, Request, Residency, TransferClock,
};
use crate::engine::resident::ResidentTile;
use crate::error::Result;

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
/// [`Pager`] that differs between whole tiles in belts ([`Belts`](crate::engine::paging::Belts)) and progressive levels
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
pub(super) type Outcome<S> = (
    <S as Strategy>::Request,
    Result<(<S as Strategy>::Piece, u64)>,
);

/// What a link delivered: requests and their results, and cancelled requests that came back
/// with the bytes they downloaded.
pub(super) type Arrivals<R, P> = (Vec<(R, Result<(P, u64)>)>, Vec<(R, u64)>);

/// A pager: the loader, what is resident, the link, and the strategy's own state.
pub struct Pager<S: Strategy> {
    pub(super) loader: Arc<S::Loader>,
    pub(super) mode: PagerMode,
    pub(super) resident: Residency<S::Tile>,
    pub(super) link: Link<S::Request, S::Piece>,
    pub(super) top: TopFetch<S::Tile>,
    pub(super) strategy: S,
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
    pub(super) fn top_pending(&self) -> bool {
        self.top.first_pending()
    }

    /// The start of an update: finds the tile under `viewer` and takes in every result the
    /// link delivered; returns the arrivals for the strategy to integrate, and the cancelled
    /// requests that came back with their bytes (already counted as downloaded).
    pub(super) fn begin(&mut self, viewer: (f64, f64)) -> Arrivals<S::Request, S::Piece> {
        self.resident.begin(viewer);
        let loader = &*self.loader;
        self.top
            .poll(&mut self.resident, |t| loader.loaded_bytes(t));
        self.resident.receive(&mut self.link)
    }

    /// Starts `request` on the link (its reservation made); a result that is already there
    /// comes back to integrate at once.
    pub(super) fn start(&mut self, request: S::Request) -> Option<Outcome<S>> {
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
