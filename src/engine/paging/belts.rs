//! Adaptive tiling by belts under a memory limit: the paper's Algorithm 1 (Pouderoux & Marvie
//! 2005), as pure synchronous logic with no threads and no I/O.
//!
//! Belt `d` around the current tile `c` holds the tiles at Chebyshev distance exactly `d` from `c`
//! (belt 0 is `c`); near the grid border belts are clipped, so the square becomes a rectangle.
//! `d_c` is the largest `d` such that belts `0..=d` are all loaded: the complete square.
//! Algorithm 1, as the paper states it:
//!
//! 1. keep the largest complete square of belts that fits the memory limit;
//! 2. fetch the missing tiles of belt `d_c + 1`, one belt at a time;
//! 3. when over the limit, remove the farthest partial belt if it is farther than the farthest
//!    complete one, and never a belt that contributes to the complete square;
//! 4. partial belts left behind after the viewer moved stay as a cache until memory is needed.
//!
//! Beyond the paper, [`plan`] decides *before* fetching whether belt `d_c + 1` fits: it counts
//! the bytes every missing tile of the belt will hold, evicts cache (farthest first, so always a
//! partial belt farther than `d_c`) to make room for what it fetches now, and fetches nothing when
//! the belt would not fit even with all evictable cache gone. The [`Ledger`] accounts a fetch's
//! bytes when it is planned, so the accounted memory never exceeds the limit, not even
//! transiently.
//!
//! A tile's cost may depend on its belt distance (its "ring"), so far tiles can hold coarser
//! detail. A tile held for a larger ring than its current one, and predicted to hold more at the
//! current ring, counts as missing for its belt and is fetched again (an upgrade: the new copy is
//! accounted before it is fetched and replaces the old one when it arrives). With
//! ring-independent costs this is exactly the paper's algorithm.

use std::cmp::Reverse;

use super::ledger::{Failure, Fetch, Ledger, Loaded, Record};
use crate::db::grid::{Grid, TileId, distance2};

/// `d_c` around `center`: the largest `d` such that every tile of belts `0..=d` is complete
/// (see [`is_complete`]); `None` while the center itself is not.
pub fn complete_belts(
    ledger: &Ledger,
    center: TileId,
    predicted: impl Fn(TileId, u32) -> usize,
) -> Option<u32> {
    let mut complete = None;
    for d in 0..=ledger.grid().max_ring(center) {
        let belt = ledger.grid().belt(center, d);
        if !belt
            .iter()
            .all(|&t| is_complete(&ledger.record(t), t, d, &predicted))
        {
            break;
        }
        complete = Some(d);
    }
    complete
}

/// Whether a tile counts as loaded for belt `ring`: it holds a copy whose detail serves that ring
/// (no upgrade needed), or it was given up (a hole that must not stop the square from growing).
pub fn is_complete(
    record: &Record,
    id: TileId,
    ring: u32,
    predicted: impl Fn(TileId, u32) -> usize,
) -> bool {
    if record.failure == Some(Failure::GaveUp) {
        return true;
    }
    record
        .loaded
        .is_some_and(|h| !needs_upgrade(h, id, ring, &predicted))
}

/// A copy loaded for a larger ring than `ring` and predicted to hold more at `ring`.
fn needs_upgrade(
    loaded: Loaded,
    id: TileId,
    ring: u32,
    predicted: impl Fn(TileId, u32) -> usize,
) -> bool {
    ring < loaded.ring && predicted(id, ring) > predicted(id, loaded.ring)
}

/// What to do now: evict these resident copies, then reserve and start these fetches.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Plan {
    /// `d_c` before the plan runs (see [`complete_belts`]).
    pub complete: Option<u32>,
    /// Resident copies to drop, farthest first.
    pub evict: Vec<TileId>,
    /// Tiles to fetch, all of belt `d_c + 1`, nearest first.
    pub fetch: Vec<Fetch>,
    /// Whether belt `d_c + 1` does not fit even with all evictable cache gone: the complete
    /// square is as large as memory allows.
    pub full: bool,
}

/// Algorithm 1 for one step: the next at most `max_fetches` missing tiles of belt `d_c + 1`
/// around `center`, and the cache to evict first so that the accounted memory stays within the
/// limit, less `reserved` bytes kept free for others, once they are reserved.
/// `predicted(id, ring)` is the loader's cost of a tile at a ring. Without a center (a
/// viewpoint off the terrain) nothing is fetched or evicted. Only level-0 tiles take part:
/// tiles of the pyramid's other levels are neither belts nor cache here.
pub fn plan(
    ledger: &Ledger,
    center: Option<TileId>,
    max_fetches: usize,
    reserved: usize,
    predicted: impl Fn(TileId, u32) -> usize,
) -> Plan {
    let Some(center) = center.filter(|&c| ledger.grid().contains(c)) else {
        return Plan::default();
    };
    let complete = complete_belts(ledger, center, &predicted);
    let next = complete.map_or(0, |d| d + 1);
    if next > ledger.grid().max_ring(center) {
        return Plan {
            complete,
            ..Plan::default()
        };
    }
    // Bytes still needed to complete the next belt (fetches in flight are reserved already),
    // and the tiles that can be fetched now.
    let mut outstanding = 0usize;
    let mut missing = Vec::new();
    for id in ledger.grid().belt(center, next) {
        let record = ledger.record(id);
        if record.fetch.is_some() || is_complete(&record, id, next, &predicted) {
            continue;
        }
        let bytes = predicted(id, next);
        outstanding = outstanding.saturating_add(bytes);
        if record.failure.is_none() {
            missing.push(Fetch {
                id,
                ring: next,
                bytes,
            });
        }
    }
    let evictable = evictable(ledger, center, next, &predicted);
    let mut free = ledger
        .limit()
        .saturating_sub(ledger.memory())
        .saturating_sub(reserved);
    let reclaimable: usize = evictable.iter().map(|&(_, bytes)| bytes).sum();
    if outstanding > free.saturating_add(reclaimable) {
        return Plan {
            complete,
            full: true,
            ..Plan::default()
        };
    }
    let mut plan = Plan {
        complete,
        ..Plan::default()
    };
    let mut victims = evictable.into_iter();
    let mut needed = 0usize;
    for fetch in missing.into_iter().take(max_fetches) {
        needed = needed.saturating_add(fetch.bytes);
        while free < needed {
            let Some((victim, bytes)) = victims.next() else {
                return plan;
            };
            plan.evict.push(victim);
            free += bytes;
        }
        plan.fetch.push(fetch);
    }
    plan
}

/// Resident copies that may go to make room for belt `next`, in eviction order: first the cache
/// (tiles beyond belt `next`, so never a belt of the complete square), farthest belt first; then,
/// as a last resort, old copies in belt `next` waiting for an upgrade. Copies with a fetch in
/// flight stay until it arrives.
fn evictable(
    ledger: &Ledger,
    center: TileId,
    next: u32,
    predicted: impl Fn(TileId, u32) -> usize,
) -> Vec<(TileId, usize)> {
    let mut candidates: Vec<_> = ledger
        .records()
        .filter(|(id, r)| id.level == 0 && r.fetch.is_none())
        .filter_map(|(id, r)| {
            let held = r.loaded?;
            let ring = Grid::ring(center, id);
            let cache = ring > next;
            let stale = ring == next && needs_upgrade(held, id, ring, &predicted);
            (cache || stale).then_some((id, held.bytes, ring))
        })
        .collect();
    candidates.sort_by_key(|&(id, _, ring)| {
        (
            ring == next,
            Reverse(ring),
            Reverse(distance2(center, id)),
            Reverse(id),
        )
    });
    candidates
        .into_iter()
        .map(|(id, bytes, _)| (id, bytes))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::db::grid::Pyramid;
    use crate::engine::paging::RetryPolicy;

    const NOW: u64 = 0;

    fn id(x: u32, y: u32) -> TileId {
        TileId::new(x, y)
    }

    fn uniform(bytes: usize) -> impl Fn(TileId, u32) -> usize {
        move |_, _| bytes
    }

    fn ledger(w: u32, h: u32, limit: usize) -> Ledger {
        Ledger::new(Pyramid::new(w, h).unwrap(), limit, RetryPolicy::default())
    }

    /// Applies one plan with every fetch arriving at once, holding its prediction.
    fn apply(ledger: &mut Ledger, plan: &Plan) {
        for &victim in &plan.evict {
            ledger.evict(victim);
        }
        for &fetch in &plan.fetch {
            ledger.reserve(fetch).unwrap();
            assert!(ledger.memory() <= ledger.limit());
        }
        for fetch in &plan.fetch {
            ledger.arrive(fetch.id, fetch.bytes, NOW).unwrap();
        }
    }

    /// Plans and applies until nothing is left to fetch; returns every plan.
    fn settle(
        ledger: &mut Ledger,
        center: TileId,
        max_fetches: usize,
        cost: &impl Fn(TileId, u32) -> usize,
    ) -> Vec<Plan> {
        let mut plans = Vec::new();
        loop {
            assert!(plans.len() < 1000, "no steady state after 1000 plans");
            let plan = plan(ledger, Some(center), max_fetches, 0, cost);
            if plan.fetch.is_empty() {
                plans.push(plan);
                return plans;
            }
            apply(ledger, &plan);
            plans.push(plan);
        }
    }

    #[test]
    fn belts_hold_the_tiles_at_each_chebyshev_distance_nearest_first() {
        let grid = Grid::new(11, 11).unwrap();
        let c = id(5, 5);
        assert_eq!(grid.belt(c, 0), vec![c]);
        assert_eq!(
            grid.belt(c, 1),
            vec![
                id(5, 4),
                id(4, 5),
                id(6, 5),
                id(5, 6),
                id(4, 4),
                id(6, 4),
                id(4, 6),
                id(6, 6)
            ]
        );
        let belt2 = grid.belt(c, 2);
        assert_eq!(belt2.len(), 16);
        assert_eq!(&belt2[..4], &[id(5, 3), id(3, 5), id(7, 5), id(5, 7)]);
        assert_eq!(&belt2[12..], &[id(3, 3), id(7, 3), id(3, 7), id(7, 7)]);
        let mut seen = std::collections::BTreeSet::new();
        for d in 0..=grid.max_ring(c) {
            for t in grid.belt(c, d) {
                assert_eq!(Grid::ring(c, t), d, "{t} in belt {d}");
                assert!(seen.insert(t), "{t} twice");
            }
        }
        assert_eq!(seen.len(), 121);
        assert_eq!(grid.max_ring(c), 5);
        assert!(grid.belt(c, 6).is_empty());
    }

    #[test]
    fn belts_are_clipped_to_rectangles_at_the_border() {
        let grid = Grid::new(6, 4).unwrap();
        let c = id(0, 1);
        assert_eq!(grid.max_ring(c), 5);
        assert_eq!(
            grid.belt(c, 1),
            vec![id(0, 0), id(1, 1), id(0, 2), id(1, 0), id(1, 2)]
        );
        assert_eq!(grid.belt(c, 2).len(), 4 * 3 - 2 * 3);
        assert_eq!(
            grid.belt(c, 4),
            vec![id(4, 1), id(4, 0), id(4, 2), id(4, 3)]
        );
        // The complete square of 2 belts is the 3 x 4 rectangle x in 0..=2, y in 0..=3.
        let mut l = ledger(6, 4, 12 * 10);
        settle(&mut l, c, 100, &uniform(10));
        assert_eq!(complete_belts(&l, c, uniform(10)), Some(2));
        let held: Vec<TileId> = l.records().map(|(t, _)| t).collect();
        let rectangle: Vec<TileId> = (0..4).flat_map(|y| (0..3).map(move |x| id(x, y))).collect();
        assert_eq!(held, rectangle);
    }

    #[test]
    fn a_viewpoint_off_the_grid_uses_the_nearest_tile_only_when_asked() {
        let grid = Grid::new(4, 3).unwrap();
        assert_eq!(grid.locate((2.5, 1.99), false), Some(id(2, 1)));
        assert_eq!(grid.locate((-0.01, 1.0), false), None);
        assert_eq!(grid.locate((4.0, 1.0), false), None);
        assert_eq!(grid.locate((-7.0, 1.5), true), Some(id(0, 1)));
        assert_eq!(grid.locate((9.0, 30.0), true), Some(id(3, 2)));
        assert_eq!(grid.locate((f64::NAN, 1.0), true), None);
        assert_eq!(grid.locate((f64::INFINITY, 1.0), true), None);
        assert!(Grid::new(0, 3).is_err());
    }

    #[test]
    fn fetches_go_belt_by_belt_one_belt_at_a_time_nearest_first() {
        let grid = Grid::new(7, 7).unwrap();
        let c = id(3, 3);
        let mut l = ledger(7, 7, usize::MAX);
        let plans = settle(&mut l, c, 100, &uniform(1));
        // One plan per belt: each plan fetches exactly the whole next belt, in belt order.
        for (d, plan) in plans.iter().take(4).enumerate() {
            let d = d as u32;
            assert_eq!(plan.complete, d.checked_sub(1));
            let ids: Vec<TileId> = plan.fetch.iter().map(|f| f.id).collect();
            assert_eq!(ids, grid.belt(c, d), "belt {d}");
            assert!(plan.fetch.iter().all(|f| f.ring == d));
        }
        assert_eq!(plans.len(), 5);
        assert_eq!(plans[4].complete, Some(3));
        // While a fetch of belt 1 is in flight, nothing of belt 2 is planned.
        let mut l = ledger(7, 7, usize::MAX);
        let first = plan(&l, Some(c), 100, 0, uniform(1));
        apply(&mut l, &first);
        let belt1 = plan(&l, Some(c), 3, 0, uniform(1));
        assert_eq!(belt1.fetch.len(), 3);
        for &f in &belt1.fetch {
            l.reserve(f).unwrap();
        }
        let rest = plan(&l, Some(c), 100, 0, uniform(1));
        let ids: Vec<TileId> = rest.fetch.iter().map(|f| f.id).collect();
        assert_eq!(ids, grid.belt(c, 1)[3..]);
        for &f in &rest.fetch {
            l.reserve(f).unwrap();
        }
        assert!(plan(&l, Some(c), 100, 0, uniform(1)).fetch.is_empty());
    }

    #[test]
    fn the_square_grows_to_exactly_the_largest_size_that_fits() {
        // 9 x 9 grid, 100 bytes a tile: belts 0..=d around the centre cost 100 (2d + 1)^2.
        let c = id(4, 4);
        for (limit, expected) in [
            (99, None),
            (100, Some(0)),
            (899, Some(0)),
            (900, Some(1)),
            (2_499, Some(1)),
            (2_500, Some(2)),
            (4_899, Some(2)),
            (4_900, Some(3)),
            (8_100, Some(4)),
            (1 << 30, Some(4)),
        ] {
            let mut l = ledger(9, 9, limit);
            let plans = settle(&mut l, c, 5, &uniform(100));
            let last = plans.last().unwrap();
            assert_eq!(last.complete, expected, "limit {limit}");
            assert_eq!(last.full, expected != Some(4), "limit {limit}");
            let side = expected.map_or(0, |d| 2 * d as usize + 1);
            assert_eq!(l.resident(), side * side, "limit {limit}");
            assert!(l.peak() <= limit);
        }
        // In a corner the square is (d + 1)^2 tiles: 400 bytes hold d = 1, 900 hold d = 2.
        for (limit, expected) in [
            (399, Some(0)),
            (400, Some(1)),
            (899, Some(1)),
            (900, Some(2)),
        ] {
            let mut l = ledger(9, 9, limit);
            settle(&mut l, id(0, 0), 1, &uniform(100));
            assert_eq!(complete_belts(&l, id(0, 0), uniform(100)), expected);
        }
    }

    /// A 9 x 9 grid at 1 byte a tile with the centre's square of 1 belt complete, belt 2 partly
    /// loaded (its west column) and cache at rings 3 and 4 west of the centre.
    fn partial_belts(limit: usize) -> Ledger {
        let mut l = ledger(9, 9, limit);
        let c = id(4, 4);
        let mut load = |t: TileId, ring: u32| {
            l.reserve(Fetch {
                id: t,
                ring,
                bytes: 1,
            })
            .unwrap();
            l.arrive(t, 1, NOW).unwrap();
        };
        for t in Grid::new(9, 9).unwrap().belt(c, 0) {
            load(t, 0);
        }
        for y in 3..=5 {
            for x in 3..=5 {
                if (x, y) != (4, 4) {
                    load(id(x, y), 1);
                }
            }
        }
        for y in 2..=6 {
            load(id(2, y), 2);
        }
        for y in 3..=5 {
            load(id(1, y), 3);
            load(id(0, y), 4);
        }
        l
    }

    #[test]
    fn cache_goes_farthest_belt_first_and_only_as_much_as_the_next_belt_needs() {
        let c = id(4, 4);
        // 9 + 5 + 3 + 3 = 20 bytes held; belt 2 misses 11 tiles.
        let l = partial_belts(20 + 11 - 2);
        assert_eq!(complete_belts(&l, c, uniform(1)), Some(1));
        let p = plan(&l, Some(c), 100, 0, uniform(1));
        let ids: Vec<TileId> = p.fetch.iter().map(|f| f.id).collect();
        assert_eq!(ids.len(), 11);
        assert!(ids.iter().all(|&t| Grid::ring(c, t) == 2));
        // Two bytes short: the two farthest cache tiles of ring 4 go, ring 3 stays.
        assert_eq!(p.evict.len(), 2);
        assert!(p.evict.iter().all(|&t| Grid::ring(c, t) == 4));
        // Six bytes short: all of ring 4, then all of ring 3.
        let l = partial_belts(20 + 11 - 6);
        let p = plan(&l, Some(c), 100, 0, uniform(1));
        let rings: Vec<u32> = p.evict.iter().map(|&t| Grid::ring(c, t)).collect();
        assert_eq!(rings, [4, 4, 4, 3, 3, 3]);
        assert_eq!(p.fetch.len(), 11);
        // Fetching part of the belt evicts only what that part needs.
        let l = partial_belts(25);
        let p = plan(&l, Some(c), 6, 0, uniform(1));
        assert_eq!((p.fetch.len(), p.evict.len()), (6, 1));
        assert_eq!(Grid::ring(c, p.evict[0]), 4);
    }

    #[test]
    fn when_the_next_belt_cannot_fit_nothing_is_evicted_and_the_square_stays() {
        let c = id(4, 4);
        // Without all its cache the ledger still holds 14 bytes; belt 2 needs 11 more.
        let l = partial_belts(14 + 11 - 1);
        let p = plan(&l, Some(c), 100, 0, uniform(1));
        assert!(p.full);
        assert!(p.evict.is_empty() && p.fetch.is_empty());
        assert_eq!(p.complete, Some(1));
        // Moving one tile east makes ring 3 of the old centre part of the new square's
        // neighbourhood; no plan ever evicts a tile of the complete square.
        let mut l = partial_belts(22);
        for center in [id(4, 4), id(5, 4), id(5, 5), id(3, 4), id(8, 8)] {
            for _ in 0..30 {
                let p = plan(&l, Some(center), 1, 0, uniform(1));
                if let Some(d) = p.complete {
                    assert!(p.evict.iter().all(|&t| Grid::ring(center, t) > d + 1));
                }
                apply(&mut l, &p);
            }
        }
    }

    #[test]
    fn a_far_jump_turns_the_old_square_into_cache_evicted_farthest_first() {
        let mut l = ledger(32, 32, 25);
        settle(&mut l, id(3, 3), 4, &uniform(1));
        assert_eq!(complete_belts(&l, id(3, 3), uniform(1)), Some(2));
        let far = id(28, 28);
        let p = plan(&l, Some(far), 1, 0, uniform(1));
        assert_eq!(p.complete, None);
        assert_eq!(p.fetch[0].id, far);
        assert_eq!(p.evict, vec![id(1, 1)]);
        settle(&mut l, far, 4, &uniform(1));
        assert_eq!(complete_belts(&l, far, uniform(1)), Some(2));
        assert!(l.records().all(|(t, _)| Grid::ring(far, t) <= 2));
    }

    #[test]
    fn upgrades_are_accounted_before_fetching_and_replace_the_old_copy() {
        // 1000 bytes in belts 0 and 1, 100 beyond; room for everything.
        let cost = |_: TileId, ring: u32| if ring <= 1 { 1000 } else { 100 };
        let mut l = ledger(9, 9, usize::MAX);
        settle(&mut l, id(4, 4), 3, &cost);
        assert_eq!(complete_belts(&l, id(4, 4), cost), Some(4));
        let all = 9 * 1000 + 72 * 100;
        assert_eq!(l.memory(), all);
        // One tile east, x = 6 moves to ring 1 but holds the coarse copy: it is missing there.
        let east = id(5, 4);
        assert_eq!(complete_belts(&l, east, cost), Some(0));
        assert!(!is_complete(&l.record(id(6, 4)), id(6, 4), 1, cost));
        assert!(is_complete(&l.record(id(4, 4)), id(4, 4), 1, cost));
        let p = plan(&l, Some(east), 1, 0, cost);
        assert_eq!(
            p.fetch,
            vec![Fetch {
                id: id(6, 4),
                ring: 1,
                bytes: 1000
            }]
        );
        assert!(p.evict.is_empty());
        // The new copy is accounted beside the old one until it arrives, then replaces it.
        l.reserve(p.fetch[0]).unwrap();
        assert_eq!(l.memory(), all + 1000);
        assert_eq!(l.record(id(6, 4)).loaded.unwrap().bytes, 100);
        l.arrive(id(6, 4), 1000, NOW).unwrap();
        assert_eq!(
            l.record(id(6, 4)).loaded,
            Some(Loaded {
                bytes: 1000,
                ring: 1
            })
        );
        assert_eq!(l.memory(), all + 900);
        settle(&mut l, east, 1, &cost);
        assert_eq!(complete_belts(&l, east, cost), Some(5));
        assert_eq!(l.memory(), all + 3 * 900);
        // Under a tight limit the stale coarse copies of belt 1 go last, after all cache: here
        // belt 1 holds only coarse copies (100 bytes, loaded for ring 2) and one cache tile sits
        // in ring 2; the 8000 bytes of belt 1 fit only without both.
        let mut l = ledger(9, 9, 9000);
        let mut load = |t: TileId, ring: u32, bytes: usize| {
            l.reserve(Fetch { id: t, ring, bytes }).unwrap();
            l.arrive(t, bytes, NOW).unwrap();
        };
        let c = id(4, 4);
        load(c, 0, 1000);
        for t in Grid::new(9, 9).unwrap().belt(c, 1) {
            load(t, 2, 100);
        }
        load(id(2, 2), 2, 100);
        let p = plan(&l, Some(c), 8, 0, cost);
        assert_eq!(p.fetch.len(), 8);
        assert_eq!(p.evict.len(), 9);
        assert_eq!(p.evict[0], id(2, 2));
        assert!(p.evict[1..].iter().all(|&t| Grid::ring(c, t) == 1));
        apply(&mut l, &p);
        assert_eq!(l.memory(), 9000);
        assert_eq!(complete_belts(&l, c, cost), Some(1));
        // With costs independent of the ring, moving needs no upgrade (the paper's behaviour).
        let mut l = ledger(9, 9, usize::MAX);
        settle(&mut l, id(4, 4), 3, &uniform(100));
        assert_eq!(complete_belts(&l, id(5, 4), uniform(100)), Some(5));
        assert!(
            plan(&l, Some(id(5, 4)), 9, 0, uniform(100))
                .fetch
                .is_empty()
        );
    }

    #[test]
    fn the_ledger_refuses_overspending_oversized_arrivals_and_growing_shrinks() {
        let mut l = ledger(4, 4, 100);
        let fetch = |x, bytes| Fetch {
            id: id(x, 0),
            ring: 0,
            bytes,
        };
        assert!(l.reserve(fetch(0, 101)).is_err());
        l.reserve(fetch(0, 60)).unwrap();
        assert!(
            l.reserve(fetch(0, 10)).is_err(),
            "a second fetch of one tile"
        );
        assert!(l.reserve(fetch(1, 41)).is_err());
        l.reserve(fetch(1, 40)).unwrap();
        assert_eq!((l.memory(), l.peak()), (100, 100));
        let e = l.arrive(id(1, 0), 41, 5).unwrap_err().to_string();
        assert!(e.contains("tile (1, 0)") && e.contains("41"), "{e}");
        assert_eq!(l.memory(), 60);
        assert_eq!(
            l.record(id(1, 0)).failure,
            Some(Failure::Waiting {
                retry_at: 5 + RetryPolicy::default().tile_delay(id(1, 0), 1)
            })
        );
        l.arrive(id(0, 0), 50, 5).unwrap();
        assert_eq!(l.memory(), 50);
        assert!(l.shrink(id(0, 0), 51, 2).is_err());
        l.shrink(id(0, 0), 20, 2).unwrap();
        assert_eq!(l.memory(), 20);
        assert!(l.arrive(id(3, 3), 1, 5).is_err());
        assert!(l.shrink(id(3, 3), 1, 5).is_err());
        assert_eq!(l.evict(id(0, 0)), 20);
        assert_eq!((l.memory(), l.peak()), (0, 100));
    }

    #[test]
    fn evicting_a_copy_whose_upgrade_was_given_up_makes_the_tile_fetchable_again() {
        let retry = RetryPolicy {
            max_attempts: 1,
            delay_updates: 1,
            ..RetryPolicy::default()
        };
        let mut l = Ledger::new(Pyramid::new(3, 1).unwrap(), 100, retry);
        let t = id(0, 0);
        l.reserve(Fetch {
            id: t,
            ring: 2,
            bytes: 10,
        })
        .unwrap();
        l.arrive(t, 10, NOW).unwrap();
        l.reserve(Fetch {
            id: t,
            ring: 0,
            bytes: 50,
        })
        .unwrap();
        l.fail(t, NOW);
        assert_eq!(l.record(t).failure, Some(Failure::GaveUp));
        assert_eq!(l.memory(), 10);
        assert_eq!(l.evict(t), 10);
        assert_eq!(l.record(t), Record::default());
        assert!(
            l.reserve(Fetch {
                id: t,
                ring: 0,
                bytes: usize::MAX
            })
            .is_err()
        );
    }

    #[test]
    fn failed_tiles_wait_then_retry_then_become_holes_the_square_grows_past() {
        let retry = RetryPolicy {
            max_attempts: 2,
            delay_updates: 3,
            ..RetryPolicy::default()
        };
        let mut l = Ledger::new(Pyramid::new(3, 3).unwrap(), usize::MAX, retry);
        let c = id(1, 1);
        let center = plan(&l, Some(c), 9, 0, uniform(1));
        apply(&mut l, &center);
        let belt = plan(&l, Some(c), 9, 0, uniform(1));
        for &f in &belt.fetch {
            l.reserve(f).unwrap();
        }
        let bad = belt.fetch[0].id;
        l.fail(bad, 10);
        for f in &belt.fetch[1..] {
            l.arrive(f.id, 1, 10).unwrap();
        }
        assert_eq!(l.memory(), 8);
        assert!(plan(&l, Some(c), 9, 0, uniform(1)).fetch.is_empty());
        let wait = retry.tile_delay(bad, 1);
        assert!((2..=3).contains(&wait), "{wait}");
        l.tick(10 + wait - 1);
        assert!(plan(&l, Some(c), 9, 0, uniform(1)).fetch.is_empty());
        l.tick(10 + wait);
        let again = plan(&l, Some(c), 9, 0, uniform(1));
        assert_eq!(again.fetch.len(), 1);
        l.reserve(again.fetch[0]).unwrap();
        l.fail(bad, 13);
        assert_eq!(l.record(bad).failure, Some(Failure::GaveUp));
        assert_eq!(complete_belts(&l, c, uniform(1)), Some(1));
        l.tick(1000);
        assert!(plan(&l, Some(c), 9, 0, uniform(1)).fetch.is_empty());
    }

    #[test]
    fn without_a_center_nothing_is_planned() {
        let l = partial_belts(100);
        assert_eq!(plan(&l, None, 10, 0, uniform(1)), Plan::default());
        assert_eq!(plan(&l, Some(id(9, 0)), 10, 0, uniform(1)), Plan::default());
    }
}
