//! The far field of the belt pager: the tiles of the pyramid's levels above 0 that the frame's
//! cut asks for (the children of tiles it would refine, the ancestors it passes through), whole,
//! within a share of the memory limit. Algorithm 1 keeps the near field in belts of level-0
//! tiles; beyond it the view draws coarser tiles, down to the top, and these bring the detail
//! the horizon needs.
//!
//! A far tile asked for and not held is fetched, the most visible first (by the screen error
//! of the tile the cut drew instead); when the share is full, far tiles no frame asked for
//! lately go first, the longest unasked and the farthest first.

use std::collections::HashMap;

use super::ledger::Fetch;
use super::{Residency, stream::Want};
use crate::db::grid::TileId;

/// The share of the memory limit the engine's far field takes: a quarter holds the few dozen
/// tiles that reach from the near field to the horizon (a ring of each level).
pub const FAR_SHARE: f64 = 0.25;

/// What the frames asked of the far field, and when.
#[derive(Debug, Default)]
pub struct FarField {
    /// The share of the memory limit it may take.
    share: f64,
    /// The last frame's wishes for tiles above level 0, by id: their priority.
    wants: HashMap<TileId, f64>,
    /// The update each far tile was last asked for in.
    asked: HashMap<TileId, u64>,
}

impl FarField {
    /// A far field taking at most `share` of the memory limit.
    pub fn new(share: f64) -> FarField {
        FarField {
            share,
            ..FarField::default()
        }
    }

    /// Hears the frame's wishes (those for level-0 tiles are Algorithm 1's business).
    pub fn hear(&mut self, wants: &[Want], now: u64) {
        self.wants.clear();
        for w in wants.iter().filter(|w| w.id.level > 0 && !w.predicted) {
            let p = self.wants.entry(w.id).or_insert(w.priority);
            *p = p.max(w.priority);
            self.asked.insert(w.id, now);
        }
    }

    /// Bytes the far field may take under `limit`.
    pub fn share(&self, limit: usize) -> usize {
        (limit as f64 * self.share) as usize
    }

    /// Bytes the far field holds or has reserved in `resident`'s ledger.
    pub fn bytes<T>(resident: &Residency<T>) -> usize {
        resident
            .ledger
            .records()
            .filter(|(id, _)| id.level > 0)
            .map(|(_, r)| r.loaded.map_or(0, |l| l.bytes) + r.fetch.map_or(0, |f| f.bytes))
            .sum()
    }

    /// The next at most `max_fetches` far tiles to fetch, the most visible first, each with the
    /// ring it is fetched for and its predicted bytes; evicts (from `resident`) far tiles not
    /// asked for lately to make room within the share and the limit. Sets
    /// `resident.memory_bound` when a wished tile does not fit.
    pub fn plan<T>(
        &mut self,
        resident: &mut Residency<T>,
        max_fetches: usize,
        predicted: impl Fn(TileId, u32) -> usize,
    ) -> Vec<Fetch> {
        let now = resident.now;
        self.asked
            .retain(|id, _| resident.ledger.record(*id) != Default::default());
        let mut wished: Vec<(TileId, f64)> = self.wants.iter().map(|(&id, &p)| (id, p)).collect();
        wished.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        let share = self.share(resident.ledger.limit());
        let mut far = FarField::bytes(resident);
        let mut fetches = Vec::new();
        for (id, _) in wished {
            if fetches.len() >= max_fetches {
                break;
            }
            let record = resident.ledger.record(id);
            let held = record.loaded.is_some() || resident.top_tile(id).is_some();
            if held || record.fetch.is_some() || record.failure.is_some() {
                continue;
            }
            let ring = resident.ring(id);
            let bytes = predicted(id, ring);
            let limit = resident.ledger.limit();
            let fits = |far: usize, memory: usize| far + bytes <= share && memory + bytes <= limit;
            while !fits(far, resident.ledger.memory()) {
                let Some(victim) = self.victim(resident, now) else {
                    break;
                };
                far -= resident.ledger.record(victim).loaded.map_or(0, |l| l.bytes);
                resident.evict(victim);
            }
            if !fits(far, resident.ledger.memory()) {
                resident.memory_bound = true;
                break;
            }
            far += bytes;
            fetches.push(Fetch { id, ring, bytes });
        }
        fetches
    }

    /// The far tile to evict first: held, not on its way, not asked for in the last update;
    /// the longest unasked, then the farthest, then the finest.
    fn victim<T>(&self, resident: &Residency<T>, now: u64) -> Option<TileId> {
        resident
            .ledger
            .records()
            .filter(|(id, r)| id.level > 0 && r.loaded.is_some() && r.fetch.is_none())
            .filter(|(id, _)| !self.wants.contains_key(id))
            .map(|(id, _)| (id, self.asked.get(&id).copied().unwrap_or(0)))
            .filter(|&(_, asked)| asked + 1 < now)
            .min_by_key(|&(id, asked)| (asked, std::cmp::Reverse(resident.ring(id)), id.level, id))
            .map(|(id, _)| id)
    }
}
