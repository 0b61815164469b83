//! The far field of the belt pager: the tiles of the pyramid's levels above 0 that the frame's
//! cut asks for (the children of tiles it would refine, the ancestors it passes through), whole,
//! within a share of the memory limit. Algorithm 1 keeps the near field in belts of level-0
//! tiles; beyond it the view draws coarser tiles, down to the top, and these bring the detail
//! the horizon needs.
//!
//! A far tile asked for and not held is fetched, the most visible first (by the screen error
//! of the tile the cut drew instead); when the share is full, far tiles no frame asked for
//! lately go first, the longest unasked and the farthest first.

use super::ledger::Fetch;
use super::{Residency, stream::Want};
use crate::db::grid::{TileId, TileMap, TileSet};

/// The share of the memory limit the engine's far field takes at least: a quarter holds the
/// few dozen tiles that reach from the near field to the horizon (a ring of each level).
pub const FAR_SHARE: f64 = 0.25;

/// Whole tiles the far field holds at least: those it draws near the eye and the children a
/// refinement needs at once.
const FAR_TILES: usize = 16;

/// Whole tiles per pyramid level between the top and the belts that a cut down to the eye
/// needs at once: a tile is replaced by its four children or not at all.
const CHAIN_TILES: usize = 4;

/// The largest share of the memory limit the far field takes, whatever its tiles weigh: the
/// belts keep the rest, at least a square of 3 x 3 tiles on the devices it was set for.
const FAR_MAX_SHARE: f64 = 0.6;

/// The far field's share of `limit` bytes when a whole far tile takes `tile_bytes` and
/// `chain` pyramid levels lie between the top and the belts' level 0: [`FAR_SHARE`], or room
/// for 16 tiles or four a level of the chain when that is more, at most six tenths of the limit.
/// Without the room, a view of large tiles on a small device keeps a coarse tile near the eye
/// for want of room for the children of every level down to it.
pub fn far_share(limit: usize, tile_bytes: usize, chain: usize) -> f64 {
    let tiles = FAR_TILES.max(CHAIN_TILES * chain);
    let needed = (tiles * tile_bytes) as f64 / limit.max(1) as f64;
    needed.clamp(FAR_SHARE, FAR_MAX_SHARE)
}

/// The error on screen, pixels, of a tile the cut drew instead of a far tile it asked for,
/// beyond which that far tile is fetched before the belts grow: a coarse tile so wrong (the
/// root near the eye at the start of a flight) matters more than the near field's next ring.
pub const URGENT_PX: f64 = 16.0;

/// How much less visible a wished far tile must be than another wish to make room for it:
/// tiles about as visible never trade places back and forth.
const VICTIM_RATIO: f64 = 0.5;

/// What the frames asked of the far field, and when.
#[derive(Debug, Default)]
pub struct FarField {
    /// The share of the memory limit it may take.
    share: f64,
    /// The last frame's wishes for tiles above level 0, by id: their priority.
    wants: TileMap<f64>,
    /// The tiles above level 0 the last frame drew.
    drawn: TileSet,
    /// The update each far tile was last asked for in.
    asked: TileMap<u64>,
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
        self.drawn.clear();
        for w in wants.iter().filter(|w| w.id.level > 0 && !w.predicted) {
            if w.drawn {
                self.drawn.insert(w.id);
            }
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

    /// The next at most `max_fetches` far tiles to fetch whose priority is at least
    /// `min_priority`, the most visible first, each with the ring it is fetched for and its
    /// predicted bytes; evicts (from `resident`) far tiles not asked for lately to make room
    /// within the share and the limit. Sets `resident.memory_bound` when a wished tile does
    /// not fit.
    pub fn plan<T>(
        &mut self,
        resident: &mut Residency<T>,
        max_fetches: usize,
        min_priority: f64,
        predicted: impl Fn(TileId, u32) -> usize,
    ) -> Vec<Fetch> {
        let now = resident.now;
        self.asked
            .retain(|id, _| resident.ledger.record(*id) != Default::default());
        let mut wished: Vec<(TileId, f64)> = self
            .wants
            .iter()
            .filter(|&(_, &p)| p >= min_priority)
            .map(|(&id, &p)| (id, p))
            .collect();
        wished.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        let share = self.share(resident.ledger.limit());
        let mut far = FarField::bytes(resident);
        let mut fetches = Vec::new();
        for (id, priority) in wished {
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
                let Some(victim) = self.victim(resident, now, priority) else {
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

    /// The far tile to evict first for one wished with `priority`: held, not on its way, not
    /// drawn, and either not asked for in the last two updates or asked for this one with a
    /// priority [`VICTIM_RATIO`] as large or less — so that the share settles on the most visible wishes instead of
    /// trading them for each other — the unasked first (the longest unasked), then the least
    /// visible, then the farthest, then the finest.
    fn victim<T>(&self, resident: &Residency<T>, now: u64, priority: f64) -> Option<TileId> {
        resident
            .ledger
            .records()
            .filter(|(id, r)| id.level > 0 && r.loaded.is_some() && r.fetch.is_none())
            .filter(|(id, _)| !self.drawn.contains(id))
            .filter_map(|(id, _)| match self.wants.get(&id) {
                Some(&p) => (p < VICTIM_RATIO * priority).then_some((id, now, p)),
                None => {
                    let asked = self.asked.get(&id).copied().unwrap_or(0);
                    (asked + 1 < now).then_some((id, asked, f64::NEG_INFINITY))
                }
            })
            .min_by(|a, b| {
                (a.1.cmp(&b.1))
                    .then(a.2.total_cmp(&b.2))
                    .then(resident.ring(b.0).cmp(&resident.ring(a.0)))
                    .then(a.0.level.cmp(&b.0.level))
                    .then(a.0.cmp(&b.0))
            })
            .map(|(id, _, _)| id)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::db::grid::Pyramid;
    use crate::engine::paging::{PagerConfig, PagerMode};

    /// Bytes of every far tile.
    const TILE: usize = 100;

    /// A residency of 16 x 16 level-0 tiles whose far field holds four tiles.
    fn residency() -> Residency<()> {
        let config = PagerConfig::new(
            16 * TILE,
            PagerMode::Stepped {
                fetches_per_update: 1,
            },
        );
        let mut r = Residency::new(Pyramid::new(16, 16).unwrap(), &config);
        r.now = 10;
        r
    }

    fn far() -> FarField {
        FarField::new(0.25)
    }

    fn at(level: u8, x: u32, y: u32) -> TileId {
        TileId::at(level, x, y)
    }

    fn want(id: TileId, priority: f64, drawn: bool) -> Want {
        Want {
            id,
            levels: 1,
            priority,
            predicted: false,
            drawn,
        }
    }

    /// Plans and lets every fetch arrive; returns the tiles fetched.
    fn step(far: &mut FarField, r: &mut Residency<()>, wants: &[Want]) -> Vec<TileId> {
        far.hear(wants, r.now);
        let fetches = far.plan(r, 8, 0.0, |_, _| TILE);
        for f in &fetches {
            r.ledger.reserve(*f).unwrap();
            r.ledger.arrive(f.id, f.bytes, r.now).unwrap();
        }
        r.now += 1;
        fetches.iter().map(|f| f.id).collect()
    }

    fn held(r: &Residency<()>, id: TileId) -> bool {
        r.ledger.record(id).loaded.is_some()
    }

    #[test]
    fn the_share_holds_sixteen_whole_tiles_or_four_a_level_within_a_quarter_and_six_tenths() {
        assert_eq!(far_share(1000, 10, 2), FAR_SHARE);
        assert_eq!(far_share(1600, 30, 2), 0.3);
        assert_eq!(far_share(2000, 30, 6), 0.36);
        assert_eq!(far_share(1000, 100, 2), FAR_MAX_SHARE);
    }

    #[test]
    fn a_wish_never_evicts_a_drawn_tile_and_evicts_a_much_less_visible_one() {
        let (mut far, mut r) = (far(), residency());
        let drawn = [at(2, 0, 0), at(2, 1, 0)];
        let faint = [at(2, 0, 1), at(2, 1, 1)];
        let wants: Vec<Want> = drawn
            .iter()
            .map(|&id| want(id, 3.0, true))
            .chain(faint.iter().map(|&id| want(id, 1.0, false)))
            .collect();
        assert_eq!(step(&mut far, &mut r, &wants).len(), 4);
        // Two children of a drawn tile, much more visible than the faint wishes: they take
        // the faint tiles' room, never the drawn tiles'.
        let children = [at(1, 0, 0), at(1, 1, 0)];
        let mut next: Vec<Want> = wants.clone();
        next.extend(children.iter().map(|&id| want(id, 40.0, false)));
        assert_eq!(step(&mut far, &mut r, &next), children.to_vec());
        assert!(drawn.iter().chain(&children).all(|&id| held(&r, id)));
        assert!(faint.iter().all(|&id| !held(&r, id)));
        // A third child finds no room: everything held is drawn or as visible as it.
        next.push(want(at(1, 0, 1), 40.0, false));
        assert!(step(&mut far, &mut r, &next).is_empty());
        assert!(r.memory_bound);
    }

    #[test]
    fn wishes_about_as_visible_do_not_trade_places() {
        let (mut far, mut r) = (far(), residency());
        let first: Vec<Want> = (0..4).map(|x| want(at(1, x, 0), 10.0, false)).collect();
        assert_eq!(step(&mut far, &mut r, &first).len(), 4);
        let mut both = first.clone();
        both.extend((0..4).map(|x| want(at(1, x, 1), 12.0, false)));
        for _ in 0..3 {
            assert!(step(&mut far, &mut r, &both).is_empty(), "no thrashing");
        }
        assert!(first.iter().all(|w| held(&r, w.id)));
    }

    #[test]
    fn tiles_no_one_asked_for_lately_go_first() {
        let (mut far, mut r) = (far(), residency());
        let old: Vec<Want> = (0..4).map(|x| want(at(1, x, 0), 50.0, false)).collect();
        assert_eq!(step(&mut far, &mut r, &old).len(), 4);
        // Two updates without them, then a faint wish: the unasked tiles make room for it.
        step(&mut far, &mut r, &[]);
        let faint = [want(at(1, 0, 1), 0.5, false)];
        assert_eq!(step(&mut far, &mut r, &faint), vec![at(1, 0, 1)]);
    }
}
