//! How the visible tiles share the triangle budget: by visual importance (the paper's
//! Algorithm 2, [`crate::engine::budget::allocate_capped`]) or by projected error.
//!
//! Importance weighs a tile by its distance and relief shares, so on a flight low over the
//! ground the tiles nearest the eye, whose errors span the most pixels, may stay coarse while
//! farther ones refine. [`allocate_by_error`] shares the budget the other way round: every tile
//! starts at its coarsest mask, and the tile whose level's error spans the most pixels on
//! screen moves to its next finer level with a smaller error, again and again, while the pool
//! affords the move. The result minimises the largest projected error a frame draws with its
//! budget (see [`allocate_by_error`]); the triangles it leaves are spent in importance order
//! on finer levels that add no error.
//!
//! Cost: every move is one pop and one push on a heap of at most one entry per tile, a tile
//! moves at most once per distinct triangle count of the mask set (15 for tiles of 65 samples,
//! whatever the levels), and the scans for a tile's moves cover its levels about once, so a
//! frame costs `O(tiles × (levels + counts × log tiles))`, against `O(tiles)` for the
//! importance share. A frame shares several budgets on one view: [`ErrorDescent`] descends once
//! and each budget replays its moves, `O(tiles × counts)` without the heap.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use crate::engine::budget::{TileAllocation, allocate_capped};
use crate::engine::importance::Importance;
use crate::engine::masks::MaskSet;
use crate::named::named_enum;

/// Which rule shares the triangle budget among the tiles in view.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Allocation {
    /// The paper's: in decreasing visual importance (distance and relief shares).
    Importance,
    /// The tile whose error spans the most pixels refines first: the largest projected error
    /// of the frame is as small as the budget allows. The default: over the Puget Sound
    /// flights it halves the mean worst error of the low flight as the PocketPC and never does
    /// worse than importance on another (`docs/tradeoff.md`).
    #[default]
    Error,
}

named_enum!(Allocation, "allocation", {
    Importance => "importance",
    Error => "error",
});

/// What the error allocation knows of one tile: its levels' geometric errors, how many pixels
/// a metre of error spans at its distance, and the level it should keep if it can.
#[derive(Clone, Copy, Debug)]
pub struct TileErrors<'a> {
    /// Per mask level, the largest height difference to the full tile, metres (the archive's
    /// level errors, [`crate::db::level_error`]).
    pub metres: &'a [f32],
    /// Pixels per metre of height error at the tile's distance from the eye.
    pub pixels_per_metre: f64,
    /// The level the tile was drawn at last, or holds fresh and has not drawn yet: moves up to
    /// it count its error [`KEEP_BONUS`] larger, so a budget that shifts a little from frame to
    /// frame takes its triangles from other tiles first (`None`: no preference).
    pub kept: Option<usize>,
}

/// How much larger a move towards a tile's kept level counts its error: the hysteresis of the
/// drawn level. The budget moves by a few percent from frame to frame, and the last move it
/// affords flips with it; with the bonus, a tile keeps its level unless another tile's error is
/// this much larger, and the largest error drawn is at most this much above the smallest the
/// budget allows.
pub const KEEP_BONUS: f64 = 0.5;

impl TileErrors<'_> {
    /// Level `level`'s error on screen, pixels; a level without a known error counts as
    /// infinitely wrong, and a level without error as exact even when seen from nowhere.
    pub fn pixels(&self, level: usize) -> f64 {
        match self.metres.get(level) {
            Some(&e) if e <= 0.0 => 0.0,
            Some(&e) => {
                let px = f64::from(e) * self.pixels_per_metre;
                if px.is_nan() { f64::INFINITY } else { px }
            }
            None => f64::INFINITY,
        }
    }

    /// Whether [`Self::key`] may order this tile's levels by their errors in metres: for a
    /// normal positive pixels per metre whose products with `f32`s neither overflow nor fall
    /// to subnormals, two distinct errors (2^-24 apart at least) stay apart after the product
    /// rounds (by 2^-53).
    fn ordered_by_metres(&self) -> bool {
        (1e-200..=1e200).contains(&self.pixels_per_metre)
    }

    /// An integer that orders this tile's levels as [`Self::pixels`] orders them: with
    /// `by_metres` ([`Self::ordered_by_metres`]) the bits of the error in metres, no product
    /// of floats (on a core without an FPU each is a library call), else the bits of the
    /// pixels.
    fn key(&self, level: usize, by_metres: bool) -> i64 {
        if !by_metres {
            return order_key(self.pixels(level));
        }
        // On the bits alone: comparing floats is a library call there too.
        const INFINITE: u32 = 0x7F80_0000;
        let Some(bits) = self.metres.get(level).map(|e| e.to_bits()) else {
            return i64::MAX;
        };
        let magnitude = bits & !(1 << 31);
        if magnitude >= INFINITE && (magnitude > INFINITE || bits >> 31 == 0) {
            i64::MAX // NaN or +∞: an infinite error, as `pixels` reads them
        } else if magnitude == 0 || bits >> 31 == 1 {
            0 // no error, or below none
        } else {
            i64::from(bits)
        }
    }
}

/// An integer that orders errors (never NaN) as `<` orders them: the bits of a float ordered
/// as [`f64::total_cmp`] orders them, with -0 read as 0, which `<` does not tell apart.
fn order_key(px: f64) -> i64 {
    let bits = if px == 0.0 { 0 } else { px.to_bits() as i64 };
    bits ^ (((bits >> 63) as u64) >> 1) as i64
}

impl Allocation {
    /// Shares `budget` among the tiles of `importance` (drawn with `masks`), tile `t` never
    /// finer than level `finest[t]`: one allocation per tile, in the tiles' input order.
    pub fn share(
        self,
        budget: usize,
        importance: &Importance,
        masks: &MaskSet,
        errors: &[TileErrors<'_>],
        finest: &[usize],
    ) -> Vec<TileAllocation> {
        match self {
            Allocation::Importance => allocate_capped(budget, importance, masks, finest),
            Allocation::Error => allocate_by_error(budget, importance, masks, errors, finest),
        }
    }
}

/// One tile's next move on the heap: the error it has now, larger by [`KEEP_BONUS`] for a move
/// towards its kept level (the largest moves first), then its rank in importance order (the
/// more important first).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Move {
    error_px: f64,
    rank: usize,
    tile: usize,
    to: usize,
}

impl Eq for Move {}

impl Ord for Move {
    fn cmp(&self, other: &Self) -> Ordering {
        self.error_px
            .total_cmp(&other.error_px)
            .then(other.rank.cmp(&self.rank))
    }
}

impl PartialOrd for Move {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

/// Shares `budget` triangles by projected error: tile `t`'s levels err by
/// `errors[t].pixels(level)` on screen, and it is never drawn finer than `finest[t]`.
///
/// Every tile starts at the coarsest mask of the set (as with [`allocate_capped`], the sum
/// exceeds `budget` only when the coarsest masks alone do). Then, repeatedly, the tile with the
/// largest error makes the cheapest move that lowers it — to the fewest triangles of a level of
/// the set finer than its own, within its cap, with a smaller error, and of the levels with
/// that count the one with the smallest error — when what is left of the budget pays for the
/// move; a tile whose move the pool cannot pay keeps its level. This gives
/// the smallest largest error of any allocation within the budget and the caps: each move was
/// forced for any allocation whose largest error is below the current one, and the move that
/// ends the descent is unaffordable. What the pool holds then goes, in importance order, to the
/// finest affordable level within each cap whose error is no larger (finer texture and shading
/// at no cost in error). A tile with a kept level ([`TileErrors::kept`]) moves towards it as if
/// its error were [`KEEP_BONUS`] larger, so the largest error is then at most that much above
/// the smallest.
pub fn allocate_by_error(
    budget: usize,
    importance: &Importance,
    masks: &MaskSet,
    errors: &[TileErrors<'_>],
    finest: &[usize],
) -> Vec<TileAllocation> {
    let order = LevelOrder::new(masks, errors);
    let (tiles, pool) = descend(
        pool_of(budget, importance, masks),
        importance,
        masks,
        errors,
        finest,
        &order,
        |_| {},
    );
    spend_leftovers(tiles, pool, importance, masks, finest, &order, errors)
}

/// The error descent of one view: every move [`allocate_by_error`] makes when its pool pays
/// for them all, in the order it makes them. A frame shares several budgets on one view (again
/// after conforming levels, then in a search for the share that fits), and each replays these
/// moves instead of descending again. The replay makes the moves the descent would: a tile's
/// moves come off the heap in falling order (its error falls, and the [`KEEP_BONUS`] goes to its
/// first moves), so the heap makes all moves in the order of their priorities, and a smaller
/// budget only stops tiles (a tile whose move the pool cannot pay moves no more), which takes
/// their later moves out and leaves the order of the others as it was.
#[derive(Clone, Debug)]
pub struct ErrorDescent {
    order: LevelOrder,
    /// Per move: the tile, its level after the move and the triangles the move adds.
    moves: Vec<(usize, usize, usize)>,
}

impl ErrorDescent {
    /// The moves of the descent for these tiles, caps and errors.
    pub fn new(
        importance: &Importance,
        masks: &MaskSet,
        errors: &[TileErrors<'_>],
        finest: &[usize],
    ) -> Self {
        let order = LevelOrder::new(masks, errors);
        let mut moves = Vec::new();
        descend(
            usize::MAX,
            importance,
            masks,
            errors,
            finest,
            &order,
            |step| moves.push(step),
        );
        Self { order, moves }
    }

    /// What [`allocate_by_error`] gives for `budget` and the tiles, caps and errors the
    /// descent was made for.
    pub fn share(
        &self,
        budget: usize,
        importance: &Importance,
        masks: &MaskSet,
        errors: &[TileErrors<'_>],
        finest: &[usize],
    ) -> Vec<TileAllocation> {
        let n = importance.order.len();
        let mut tiles = coarsest(n, masks);
        let mut pool = pool_of(budget, importance, masks);
        let mut stopped = vec![false; n];
        for &(t, level, cost) in &self.moves {
            if stopped[t] {
                continue;
            }
            if cost > pool {
                stopped[t] = true;
                continue;
            }
            pool -= cost;
            tiles[t] = TileAllocation {
                level,
                triangles: tiles[t].triangles + cost,
            };
        }
        spend_leftovers(tiles, pool, importance, masks, finest, &self.order, errors)
    }
}

/// Every tile at the coarsest mask of the set.
fn coarsest(n: usize, masks: &MaskSet) -> Vec<TileAllocation> {
    let level = masks.coarsest_level();
    vec![
        TileAllocation {
            level,
            triangles: masks.triangle_count(level),
        };
        n
    ]
}

/// What `budget` leaves once every tile has its coarsest mask.
fn pool_of(budget: usize, importance: &Importance, masks: &MaskSet) -> usize {
    budget.saturating_sub(importance.order.len() * masks.triangle_count(masks.coarsest_level()))
}

/// The levels of a mask set and how each tile's errors order them.
#[derive(Clone, Debug)]
struct LevelOrder {
    /// The levels of the set, coarsest first.
    levels: Vec<usize>,
    /// Per tile, [`TileErrors::ordered_by_metres`].
    by_metres: Vec<bool>,
}

impl LevelOrder {
    fn new(masks: &MaskSet, errors: &[TileErrors<'_>]) -> Self {
        Self {
            levels: masks.levels().iter().rev().copied().collect(),
            by_metres: errors.iter().map(TileErrors::ordered_by_metres).collect(),
        }
    }

    /// Tile `t`'s [`TileErrors::key`] of `level`.
    fn key(&self, errors: &[TileErrors<'_>], t: usize, level: usize) -> i64 {
        errors[t].key(level, self.by_metres[t])
    }
}

/// The descent of [`allocate_by_error`] from every tile at the coarsest mask with `pool`
/// triangles to spend: `made` hears every move made (tile, level, triangles added). Returns
/// the levels and what is left of the pool.
fn descend(
    mut pool: usize,
    importance: &Importance,
    masks: &MaskSet,
    errors: &[TileErrors<'_>],
    finest: &[usize],
    order: &LevelOrder,
    mut made: impl FnMut((usize, usize, usize)),
) -> (Vec<TileAllocation>, usize) {
    let n = importance.order.len();
    debug_assert!(errors.len() == n && finest.len() == n);
    let mut tiles = coarsest(n, masks);
    let levels = &order.levels;
    let key = |t: usize, level: usize| order.key(errors, t, level);
    // The cheapest move that lowers tile `t`'s error from level `from`: the fewest triangles
    // of a finer level with a smaller error, and of the levels with that count the smallest
    // error (the finest of equals), so that moves between levels of equal cost are one move.
    let next = |t: usize, from: usize| -> Option<Move> {
        let now = key(t, from);
        let mut best: Option<(usize, i64, usize)> = None;
        // The levels finer than `from` and within the cap, coarsest first: `levels` falls, so
        // they start where its levels drop below `from` and end at the cap, and the walk skips
        // the coarser ones instead of testing each on every move.
        let finer = &levels[levels.partition_point(|&l| l >= from)..];
        for &l in finer.iter().take_while(|&&l| l >= finest[t]) {
            let count = masks.triangle_count(l);
            if best.is_some_and(|(_, _, c)| count != c) {
                break;
            }
            let e = key(t, l);
            if e < now && best.is_none_or(|(_, least, _)| e <= least) {
                best = Some((l, e, count));
            }
        }
        best.map(|(to, _, _)| {
            let now = errors[t].pixels(from);
            Move {
                // A move no finer than the kept level is one the tile made before.
                error_px: if errors[t].kept.is_some_and(|k| to >= k) {
                    now * (1.0 + KEEP_BONUS)
                } else {
                    now
                },
                rank: 0,
                tile: t,
                to,
            }
        })
    };
    let mut heap = BinaryHeap::with_capacity(n);
    let start = masks.coarsest_level();
    for (rank, &t) in importance.order.iter().enumerate() {
        if let Some(m) = next(t, start) {
            heap.push(Move { rank, ..m });
        }
    }
    while let Some(m) = heap.pop() {
        let current = tiles[m.tile];
        let triangles = masks.triangle_count(m.to);
        let cost = triangles - current.triangles;
        if cost > pool {
            continue;
        }
        pool -= cost;
        tiles[m.tile] = TileAllocation {
            level: m.to,
            triangles,
        };
        made((m.tile, m.to, cost));
        if let Some(following) = next(m.tile, m.to) {
            heap.push(Move {
                rank: m.rank,
                ..following
            });
        }
    }
    (tiles, pool)
}

/// What the pool holds after the descent, in importance order: each tile's finest affordable
/// level within its cap whose error is no larger than its own.
fn spend_leftovers(
    mut tiles: Vec<TileAllocation>,
    mut pool: usize,
    importance: &Importance,
    masks: &MaskSet,
    finest: &[usize],
    order: &LevelOrder,
    errors: &[TileErrors<'_>],
) -> Vec<TileAllocation> {
    let levels = &order.levels;
    for &t in &importance.order {
        let current = tiles[t];
        let now = order.key(errors, t, current.level);
        // The levels finer than the tile's and within its cap, coarsest first, so with ever
        // more triangles: the affordable ones lead.
        let from = levels.partition_point(|&l| l >= current.level);
        let finer = &levels[from..levels.partition_point(|&l| l >= finest[t]).max(from)];
        let affordable = &finer
            [..finer.partition_point(|&l| masks.triangle_count(l) <= current.triangles + pool)];
        let finer = affordable
            .iter()
            .rev()
            .copied()
            .find(|&l| order.key(errors, t, l) <= now);
        if let Some(level) = finer {
            let triangles = masks.triangle_count(level);
            pool -= triangles - current.triangles;
            tiles[t] = TileAllocation { level, triangles };
        }
    }
    tiles
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::engine::budget::tests::check_allocation;
    use crate::engine::importance::{TileMeasure, Weights, visual_importance};
    use crate::engine::masks::LevelSet;
    use crate::named::Named;

    /// The largest projected error of an allocation.
    fn worst(a: &[TileAllocation], errors: &[TileErrors<'_>]) -> f64 {
        a.iter()
            .zip(errors)
            .map(|(t, e)| e.pixels(t.level))
            .fold(0.0, f64::max)
    }

    #[test]
    fn the_nearest_tile_refines_first_even_when_importance_ranks_it_last() {
        // 9 x 9 tiles: levels 0..=7 with 128, 32, 18, 8, 8, 8, 8, 2 triangles.
        let masks = MaskSet::new(9, LevelSet::All);
        let rugged = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0];
        // A near flat tile the importance puts last, and a far tall one it puts first.
        let imp = Importance {
            values: vec![0.1, 0.9],
            order: vec![1, 0],
        };
        let errors = [
            TileErrors {
                metres: &rugged,
                pixels_per_metre: 10.0,
                kept: None,
            },
            TileErrors {
                metres: &rugged,
                pixels_per_metre: 1.0,
                kept: None,
            },
        ];
        let by_importance = allocate_capped(40, &imp, &masks, &[0, 0]);
        assert_eq!((by_importance[0].level, by_importance[1].level), (3, 1));
        let by_error = allocate_by_error(40, &imp, &masks, &errors, &[0, 0]);
        assert_eq!((by_error[0].level, by_error[1].level), (1, 3));
        assert!(worst(&by_error, &errors) < worst(&by_importance, &errors));
    }

    #[test]
    fn a_move_that_lowers_no_error_waits_for_the_leftovers() {
        let masks = MaskSet::new(9, LevelSet::All);
        // Levels 7 down to 3 have the same error: the first move that lowers it is to level 2.
        let plateau = [0.0, 0.5, 1.0, 4.0, 4.0, 4.0, 4.0, 4.0];
        let imp = Importance {
            values: vec![1.0],
            order: vec![0],
        };
        let errors = [TileErrors {
            metres: &plateau,
            pixels_per_metre: 1.0,
            kept: None,
        }];
        // 10 triangles: levels 6 to 3 (8) are affordable but no better than 7, level 2 (18)
        // is not.
        let a = allocate_by_error(10, &imp, &masks, &errors, &[0]);
        assert_eq!(
            a[0].level, 3,
            "the leftovers buy the finest level as good as the coarsest"
        );
        let a = allocate_by_error(20, &imp, &masks, &errors, &[0]);
        assert_eq!(a[0].level, 2);
        let a = allocate_by_error(40, &imp, &masks, &errors, &[0]);
        assert_eq!(a[0].level, 1);
        // Capped at level 3: never finer, whatever the budget.
        let a = allocate_by_error(1_000, &imp, &masks, &errors, &[3]);
        assert_eq!(a[0].level, 3);
        let a = allocate_by_error(1_000, &imp, &masks, &errors, &[0]);
        assert_eq!(a[0].level, 0);
    }

    #[test]
    fn a_tile_keeps_a_fresh_level_when_the_budget_dips_below_both_moves() {
        // 9 x 9 tiles: both tiles reach level 3 (8 triangles) with 16; the next move of
        // either, to level 2 (18), costs 10 more, and 26 pays for one of them only.
        let masks = MaskSet::new(9, LevelSet::All);
        let rugged = [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 8.0];
        let imp = Importance {
            values: vec![0.5, 0.5],
            order: vec![0, 1],
        };
        let errors = |kept: Option<usize>| {
            [
                // Tile 0's errors span a little more: without a preference it refines first.
                TileErrors {
                    metres: &rugged,
                    pixels_per_metre: 1.05,
                    kept: None,
                },
                TileErrors {
                    metres: &rugged,
                    pixels_per_metre: 1.0,
                    kept,
                },
            ]
        };
        let levels = |a: Vec<TileAllocation>| (a[0].level, a[1].level);
        let none = errors(None);
        assert_eq!(
            levels(allocate_by_error(26, &imp, &masks, &none, &[0, 0])),
            (2, 3)
        );
        // Tile 1 holds level 2 fresh: it keeps it, and tile 0 waits.
        let kept = errors(Some(2));
        let a = allocate_by_error(26, &imp, &masks, &kept, &[0, 0]);
        assert!(
            worst(&a, &kept)
                <= (1.0 + KEEP_BONUS)
                    * worst(&allocate_by_error(26, &imp, &masks, &none, &[0, 0]), &none)
        );
        assert_eq!(levels(a), (3, 2));
        // A budget that pays for both moves refines both, kept or not.
        assert_eq!(
            levels(allocate_by_error(36, &imp, &masks, &kept, &[0, 0])),
            (2, 2)
        );
    }

    #[test]
    fn names_round_trip() {
        for a in Allocation::all() {
            assert_eq!(Allocation::from_name(a.name()).unwrap(), a);
        }
        assert_eq!(Allocation::default().name(), "error");
        assert!(Allocation::from_name("distance").is_err());
    }

    /// Per tile: distance, relief, pixels per metre and the seed of its level errors.
    type Tiles = Vec<(f64, f64, f64, u64)>;

    fn frame() -> impl Strategy<Value = (usize, LevelSet, Tiles)> {
        (
            prop::sample::select(vec![3usize, 9, 17, 33, 65]),
            prop::sample::select(vec![LevelSet::All, LevelSet::PowerOfTwo]),
            prop::collection::vec(
                (0.0..1e4f64, 0.0..500.0f64, 0.0..50.0f64, any::<u64>()),
                0..40,
            ),
        )
    }

    /// Level errors of a tile of `s` samples from `seed`: growing with the level on the whole,
    /// not always (errors of coarser levels may be smaller).
    fn level_errors(s: usize, seed: u64) -> Vec<f32> {
        let mut state = seed;
        (0..s - 1)
            .map(|l| {
                state = state
                    .wrapping_mul(6_364_136_223_846_793_005)
                    .wrapping_add(1_442_695_040_888_963_407);
                if l == 0 {
                    0.0
                } else {
                    l as f32 * (0.5 + (state >> 40) as f32 / (1u64 << 24) as f32)
                }
            })
            .collect()
    }

    proptest! {
        #[test]
        fn level_keys_order_as_the_pixels(
            metres in prop::collection::vec(prop_oneof![
                Just(0.0f32), Just(-0.0), Just(-1.0), Just(f32::INFINITY), Just(f32::NEG_INFINITY),
                Just(f32::NAN), Just(-f32::NAN),
                Just(f32::MIN_POSITIVE / 8.0), Just(f32::MAX), any::<f32>(), 0f32..100.0,
            ], 2..6),
            pixels_per_metre in prop_oneof![
                Just(0.0), Just(1e-200), Just(1e200), Just(f64::INFINITY), Just(f64::NAN),
                Just(-3.0), any::<f64>(), 1e-6f64..1e6,
            ],
        ) {
            let tile = TileErrors { metres: &metres, pixels_per_metre, kept: None };
            let by_metres = tile.ordered_by_metres();
            for a in 0..=metres.len() {
                for b in 0..=metres.len() {
                    let (ka, kb) = (tile.key(a, by_metres), tile.key(b, by_metres));
                    let (pa, pb) = (tile.pixels(a), tile.pixels(b));
                    prop_assert_eq!(ka < kb, pa < pb, "{} {}", a, b);
                    prop_assert_eq!(ka <= kb, pa <= pb, "{} {}", a, b);
                }
            }
        }

        #[test]
        fn the_descent_replayed_shares_every_budget_as_the_descent_does(
            (s, set, tiles) in frame(),
            fractions in prop::collection::vec(0.0..1.3f64, 1..6),
            caps in prop::collection::vec(0usize..64, 40),
            kept in prop::collection::vec(prop::option::of(0usize..64), 40),
            ties in any::<bool>(),
        ) {
            let masks = MaskSet::new(s, set);
            let measures: Vec<TileMeasure> = tiles
                .iter()
                .map(|&(distance, height, _, _)| TileMeasure { distance, height })
                .collect();
            let imp = visual_importance(&measures, Weights::default());
            // With `ties`, every tile has the same errors, so that moves tie on the heap.
            let metres: Vec<Vec<f32>> = tiles
                .iter()
                .map(|t| level_errors(s, if ties { 1 } else { t.3 }))
                .collect();
            let levels = masks.levels();
            let errors: Vec<TileErrors> = tiles
                .iter()
                .zip(&metres)
                .zip(&kept)
                .map(|((t, m), k)| TileErrors {
                    metres: m,
                    pixels_per_metre: if ties { 1.0 } else { t.2 },
                    kept: k.map(|k| levels[k % levels.len()]),
                })
                .collect();
            let finest: Vec<usize> = (0..tiles.len())
                .map(|t| levels[caps[t] % levels.len()])
                .collect();
            let descent = ErrorDescent::new(&imp, &masks, &errors, &finest);
            let all = tiles.len() * masks.triangle_count(0);
            for fraction in fractions {
                let budget = (all as f64 * fraction) as usize;
                prop_assert_eq!(
                    descent.share(budget, &imp, &masks, &errors, &finest),
                    allocate_by_error(budget, &imp, &masks, &errors, &finest),
                    "budget {}", budget
                );
            }
        }

        #[test]
        fn within_the_budget_and_the_caps_and_never_worse_than_importance_at_its_worst(
            (s, set, tiles) in frame(),
            fraction in 0.0..1.3f64,
            caps in prop::collection::vec(0usize..64, 40),
            kept in prop::collection::vec(prop::option::of(0usize..64), 40),
        ) {
            let masks = MaskSet::new(s, set);
            let measures: Vec<TileMeasure> = tiles
                .iter()
                .map(|&(distance, height, _, _)| TileMeasure { distance, height })
                .collect();
            let imp = visual_importance(&measures, Weights::default());
            let metres: Vec<Vec<f32>> =
                tiles.iter().map(|t| level_errors(s, t.3)).collect();
            let errors: Vec<TileErrors> = tiles
                .iter()
                .zip(&metres)
                .map(|(t, m)| TileErrors { metres: m, pixels_per_metre: t.2, kept: None })
                .collect();
            let levels = masks.levels();
            let finest: Vec<usize> = (0..tiles.len())
                .map(|t| levels[caps[t] % levels.len()])
                .collect();
            let all = tiles.len() * masks.triangle_count(0);
            let budget = (all as f64 * fraction) as usize;
            let a = allocate_by_error(budget, &imp, &masks, &errors, &finest);
            prop_assert_eq!(a.len(), tiles.len());
            check_allocation(&a, budget, &masks, &finest)?;
            let by_importance = allocate_capped(budget, &imp, &masks, &finest);
            prop_assert!(
                worst(&a, &errors) <= worst(&by_importance, &errors),
                "error {} against importance {}", worst(&a, &errors), worst(&by_importance, &errors)
            );
            // Kept levels: still within the budget and the caps, and the largest error at
            // most the bonus above the smallest.
            let keeping: Vec<TileErrors> = errors
                .iter()
                .zip(&kept)
                .map(|(e, k)| TileErrors { kept: k.map(|k| levels[k % levels.len()]), ..*e })
                .collect();
            let k = allocate_by_error(budget, &imp, &masks, &keeping, &finest);
            check_allocation(&k, budget, &masks, &finest)?;
            prop_assert!(
                worst(&k, &errors) <= (1.0 + KEEP_BONUS) * worst(&a, &errors) * (1.0 + 1e-9),
                "kept {} against {}", worst(&k, &errors), worst(&a, &errors)
            );
            if budget >= all {
                // Every tile as exact as its cap allows.
                for (t, alloc) in a.iter().enumerate() {
                    let best = levels
                        .iter()
                        .filter(|&&l| l >= finest[t])
                        .map(|&l| errors[t].pixels(l))
                        .fold(f64::INFINITY, f64::min);
                    prop_assert_eq!(errors[t].pixels(alloc.level), best);
                }
            }
        }
    }
}
