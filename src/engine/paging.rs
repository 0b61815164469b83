//! The engine's pager, either kind: the paper's whole-tile belts ([`Pager`]) or progressive
//! streaming ([`StreamPager`]), behind one face for the engine, the viewer and the reports.

use std::collections::BTreeMap;
use std::sync::Arc;

use crate::db::grid::TileId;
use crate::engine::belts::Ledger;
use crate::engine::loader::ArchiveLoader;
use crate::engine::pager::{Pager, PagerStats, TileState, TransferClock};
use crate::engine::resident::ResidentTile;
use crate::engine::stream::{StreamPager, StreamStats, Want};

/// Whole tiles in belts, or progressive levels.
pub enum Paging {
    /// Algorithm 1 with whole tiles.
    Belts(Box<Pager<ArchiveLoader>>),
    /// (tile, level) requests by importance.
    Stream(Box<StreamPager<ArchiveLoader>>),
}

impl Paging {
    /// Start of a frame: takes in arrivals and plans (see each pager's `update`).
    pub fn update(&mut self, viewer: (f64, f64)) {
        match self {
            Paging::Belts(p) => p.update(viewer),
            Paging::Stream(p) => p.update(viewer),
        }
    }

    /// The resident tiles, row-major.
    pub fn tiles(&self) -> impl Iterator<Item = (TileId, &ResidentTile)> {
        self.resident().iter().map(|(id, t)| (*id, t))
    }

    /// The resident copy of `id`, if any.
    pub fn get(&self, id: TileId) -> Option<&ResidentTile> {
        self.resident().get(&id)
    }

    fn resident(&self) -> &BTreeMap<TileId, ResidentTile> {
        match self {
            Paging::Belts(p) => p.resident(),
            Paging::Stream(p) => p.resident(),
        }
    }

    /// The tile under the viewpoint at the last update.
    pub fn current_tile(&self) -> Option<TileId> {
        match self {
            Paging::Belts(p) => p.current_tile(),
            Paging::Stream(p) => p.current_tile(),
        }
    }

    /// Where `id` stands.
    pub fn state(&self, id: TileId) -> TileState {
        match self {
            Paging::Belts(p) => p.state(id),
            Paging::Stream(p) => p.state(id),
        }
    }

    /// The counters.
    pub fn stats(&self) -> PagerStats {
        match self {
            Paging::Belts(p) => p.stats(),
            Paging::Stream(p) => p.stats(),
        }
    }

    /// The streaming counters, when streaming progressively.
    pub fn stream_stats(&self) -> Option<&StreamStats> {
        match self {
            Paging::Belts(_) => None,
            Paging::Stream(p) => Some(p.stream_stats()),
        }
    }

    /// The message of the last error, if any.
    pub fn last_error(&self) -> Option<&str> {
        match self {
            Paging::Belts(p) => p.last_error(),
            Paging::Stream(p) => p.last_error(),
        }
    }

    /// The accounting.
    pub fn ledger(&self) -> &Ledger {
        match self {
            Paging::Belts(p) => p.ledger(),
            Paging::Stream(p) => p.ledger(),
        }
    }

    /// The loader.
    pub fn loader(&self) -> &ArchiveLoader {
        match self {
            Paging::Belts(p) => p.loader(),
            Paging::Stream(p) => p.loader(),
        }
    }

    /// Sets the simulated time, seconds.
    pub fn set_time(&mut self, seconds: f64) {
        match self {
            Paging::Belts(p) => p.set_time(seconds),
            Paging::Stream(p) => p.set_time(seconds),
        }
    }

    /// Times transfers in simulated mode.
    pub fn set_transfer_clock(&mut self, clock: Arc<dyn TransferClock>) {
        match self {
            Paging::Belts(p) => p.set_transfer_clock(clock),
            Paging::Stream(p) => p.set_transfer_clock(clock),
        }
    }

    /// Refits every resident tile after the loader's settings changed.
    pub fn refit(&mut self) {
        match self {
            Paging::Belts(p) => p.refit(),
            Paging::Stream(p) => p.refit(),
        }
    }

    /// Hands this frame's wishes to the stream pager (nothing for whole-tile belts).
    pub fn request(&mut self, wants: &[Want]) {
        if let Paging::Stream(p) = self {
            p.request(wants);
        }
    }

    /// Tells the stream pager which levels the frame drew (nothing for whole-tile belts).
    pub fn drawn(&mut self, drawn: impl IntoIterator<Item = (TileId, usize)>) {
        if let Paging::Stream(p) = self {
            p.drawn(drawn);
        }
    }

    /// Seconds on the pager's clock (the stream pager's; 0 for whole-tile belts).
    pub fn time(&self) -> f64 {
        match self {
            Paging::Belts(_) => 0.0,
            Paging::Stream(p) => p.time(),
        }
    }
}
