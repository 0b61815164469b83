//! The stream pager with a synthetic loader: what the view needs and nobody holds comes first, in
//! one request up to the levels it is wished, finer levels follow importance, the belts fill at
//! the coarsest level, wishes have hysteresis, the bounded queue cancels what no longer matters
//! (and the simulated link what is on its way), the memory limit holds through any flight, and
//! cancelling never loses a tile.

use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Mutex};

use proptest::prelude::*;
use stripmask::db::grid::Pyramid;
use stripmask::db::grid::TileId;
use stripmask::db::source::CancelToken;
use stripmask::engine::paging::stream::{
    HOLD_SECONDS, LevelLoader, StreamPager, StreamSettings, Want,
};
use stripmask::engine::paging::{PagerConfig, PagerMode, ResidentLoader, TransferClock};
use stripmask::error::{Error, Result};

/// Levels per tile and the bytes a tile holding `k` of them takes: 100 * 4^(k-1).
const LEVELS: usize = 5;

fn bytes_at(levels: usize) -> usize {
    100 * 4usize.pow(levels as u32 - 1)
}

/// A tile holding `levels` levels.
#[derive(Debug)]
struct Held {
    id: TileId,
    levels: usize,
}

/// Loads nothing but keeps the contract: levels arrive in order, bytes as predicted.
#[derive(Default)]
struct Synthetic {
    fetched: Arc<AtomicU32>,
    /// Tiles whose fetches fail.
    broken: Mutex<Vec<TileId>>,
}

impl ResidentLoader for Synthetic {
    type Loaded = Held;

    fn loaded_bytes(&self, tile: &Held) -> usize {
        bytes_at(tile.levels)
    }
}

impl LevelLoader for Synthetic {
    type Piece = (TileId, usize, usize);

    fn levels(&self) -> usize {
        LEVELS
    }

    fn predicted_bytes(&self, levels: usize) -> usize {
        bytes_at(levels)
    }

    fn fetch(
        &self,
        id: TileId,
        have: usize,
        want: usize,
        _: &CancelToken,
    ) -> Result<(Self::Piece, u64)> {
        if self.broken.lock().unwrap().contains(&id) {
            return Err(Error::invalid(id.to_string(), "broken on purpose"));
        }
        self.fetched.fetch_add(1, Ordering::Relaxed);
        let bytes = (bytes_at(want) - if have == 0 { 0 } else { bytes_at(have) }) as u64;
        Ok(((id, have, want), bytes))
    }

    fn merge(&self, id: TileId, held: Option<&Held>, piece: Self::Piece) -> Result<Held> {
        let (piece_id, have, want) = piece;
        assert_eq!(piece_id, id);
        assert_eq!(held.map_or(0, |h| h.levels), have, "levels arrive in order");
        Ok(Held { id, levels: want })
    }

    fn held_levels(&self, tile: &Held) -> usize {
        tile.levels
    }

    fn drop_levels(&self, tile: &mut Held, levels: usize) -> usize {
        tile.levels = tile.levels.min(levels.max(1));
        bytes_at(tile.levels)
    }

    fn is_absent(&self, _: &Held) -> bool {
        false
    }
}

/// The settings of these tests: the coarse square fills, so that tiles come with no view asking.
const FILL: StreamSettings = StreamSettings {
    queue_capacity: 32,
    square_share: 0.5,
    prediction: None,
};

fn pager(limit: usize, tiles: u32, fetches_per_update: usize) -> StreamPager<Synthetic> {
    StreamPager::new(
        Synthetic::default(),
        Pyramid::new(tiles, tiles).unwrap(),
        PagerConfig::new(limit, PagerMode::Stepped { fetches_per_update }),
        FILL,
    )
    .unwrap()
}

fn want(x: u32, y: u32, levels: usize, priority: f64) -> Want {
    Want {
        id: TileId::new(x, y),
        levels,
        priority,
        predicted: false,
        drawn: true,
    }
}

/// Accounted bytes equal what the tiles hold when nothing is in flight.
fn check_accounting(p: &StreamPager<Synthetic>) {
    let stats = p.resident().stats();
    assert!(stats.memory_bytes <= stats.memory_limit_bytes, "{stats:?}");
    assert!(
        stats.memory_peak_bytes <= stats.memory_limit_bytes,
        "{stats:?}"
    );
    if stats.fetching == 0 {
        let held: usize = p.resident().tiles().map(|(_, t)| bytes_at(t.levels)).sum();
        assert_eq!(held, stats.memory_bytes);
    }
    for (id, t) in p.resident().tiles() {
        assert_eq!(id, t.id);
    }
}

#[test]
fn what_the_view_needs_comes_first_and_belts_fill_at_the_coarsest_level() {
    let mut p = pager(1 << 20, 7, 2);
    let center = (3.5, 3.5);
    let mut order = Vec::new();
    for _ in 0..40 {
        p.update(center);
        let before: Vec<(TileId, usize)> =
            p.resident().tiles().map(|(id, t)| (id, t.levels)).collect();
        p.request(&[want(3, 3, LEVELS, 0.9)]);
        for (id, t) in p.resident().tiles() {
            if !before.contains(&(id, t.levels)) {
                order.push((id, t.levels));
            }
        }
        check_accounting(&p);
    }
    // The wanted tile first, in one request up to the levels it is wished, then the belts.
    assert_eq!(order[0], (TileId::new(3, 3), LEVELS), "{order:?}");
    assert!(order[1..].iter().all(|&(_, l)| l == 1), "{order:?}");
    assert_eq!(order.len(), 49, "one request per tile: {order:?}");
    assert_eq!(p.resident().stats().complete_belts, Some(3));
    assert_eq!(p.held_levels(TileId::new(3, 3)), LEVELS);
    assert!(
        p.resident()
            .tiles()
            .all(|(id, t)| t.levels == 1 || id == TileId::new(3, 3))
    );
}

#[test]
fn refinements_follow_importance_and_stop_at_what_is_asked() {
    let mut p = pager(1 << 20, 3, 1);
    // The belts fill at the coarsest level first: every tile is held when the wishes come.
    for _ in 0..9 {
        p.update((1.5, 1.5));
        p.request(&[]);
    }
    assert_eq!(p.resident().tiles().count(), 9);
    let wants = [want(0, 0, 3, 0.2), want(2, 2, 4, 0.7), want(1, 1, 2, 0.1)];
    let mut refined = Vec::new();
    for _ in 0..40 {
        p.update((1.5, 1.5));
        let before: Vec<(TileId, usize)> =
            p.resident().tiles().map(|(id, t)| (id, t.levels)).collect();
        p.request(&wants);
        for (id, t) in p.resident().tiles() {
            if t.levels > 1 && !before.contains(&(id, t.levels)) {
                refined.push((id.x, t.levels));
            }
        }
    }
    // One range request brings a tile to what it asks for; the most important tile goes first.
    assert_eq!(refined, [(2, 4), (0, 3), (1, 2)]);
    assert_eq!(p.held_levels(TileId::new(2, 2)), 4);
    assert_eq!(p.stream_stats().requests, 9 + 3);
}

#[test]
fn a_request_that_stops_mattering_is_cancelled_before_it_is_sent() {
    // The link is paused (no fetch per update): requests only wait in the queue.
    let mut p = pager(1 << 20, 4, 0);
    p.update((0.5, 0.5));
    p.request(&[]);
    assert_eq!(p.queue().waiting().len(), 1, "belt 0 at the coarse level");
    p.request(&[]);
    assert_eq!(p.stream_stats().cancelled, 0, "still wanted: still waiting");
    // The viewer jumps to the far corner: the old belt 0 is no longer needed.
    p.update((3.5, 3.5));
    p.request(&[]);
    assert_eq!(p.stream_stats().cancelled, 1);
    assert_eq!(p.queue().waiting()[0].id, TileId::new(3, 3));

    // A refinement the view asked for (it waits: no memory for it yet), then turned away from.
    let mut q = pager(250, 1, 1);
    q.update((0.5, 0.5));
    q.request(&[]);
    assert_eq!(q.held_levels(TileId::new(0, 0)), 1);
    q.request(&[want(0, 0, 3, 0.5)]);
    assert_eq!(q.queue().waiting().len(), 1);
    assert!(q.resident().stats().memory_bound);
    q.set_time(1.0);
    q.request(&[]);
    assert_eq!(
        q.stream_stats().cancelled,
        0,
        "the wish is held for a while"
    );
    q.set_time(1.0 + HOLD_SECONDS);
    q.request(&[]);
    assert_eq!(q.stream_stats().cancelled, 1);
    assert!(q.queue().waiting().is_empty());
    assert_eq!(
        q.loader().fetched.load(Ordering::Relaxed),
        1,
        "only the coarse level"
    );
}

#[test]
fn under_pressure_fine_levels_of_far_tiles_go_before_whole_tiles() {
    // Room for the 9 coarse tiles (900) and one tile at level 4 (6,400 - 100) plus a little.
    let limit = 900 + 6_300 + 1_000;
    let mut p = pager(limit, 3, 4);
    for _ in 0..10 {
        p.update((0.5, 0.5));
        p.request(&[want(2, 2, 4, 0.5)]);
        check_accounting(&p);
    }
    assert_eq!(p.held_levels(TileId::new(2, 2)), 4);
    // The viewer now cares about the opposite corner more: (2, 2) gives its fine levels back.
    for _ in 0..10 {
        p.update((0.5, 0.5));
        p.request(&[want(0, 0, 4, 0.9), want(2, 2, 4, 0.1)]);
        check_accounting(&p);
    }
    assert_eq!(p.held_levels(TileId::new(0, 0)), 4);
    assert!(p.held_levels(TileId::new(2, 2)) < 4);
    assert_eq!(p.resident().tiles().count(), 9, "no whole tile was evicted");
    assert!(p.stream_stats().dropped_levels > 0);
    assert!(p.resident().stats().memory_bound);
}

#[test]
fn a_broken_tile_is_retried_then_given_up_without_stopping_the_square() {
    let loader = Synthetic::default();
    loader.broken.lock().unwrap().push(TileId::new(1, 0));
    let mut p = StreamPager::new(
        loader,
        Pyramid::new(3, 3).unwrap(),
        PagerConfig::new(
            1 << 20,
            PagerMode::Stepped {
                fetches_per_update: 4,
            },
        ),
        FILL,
    )
    .unwrap();
    for _ in 0..200 {
        p.update((1.5, 1.5));
        p.request(&[]);
    }
    assert_eq!(p.resident().stats().complete_belts, Some(1));
    assert_eq!(p.resident().stats().failed_tiles, 1);
    assert!(
        p.resident()
            .last_error()
            .unwrap()
            .contains("broken on purpose")
    );
}

#[test]
fn the_first_request_for_an_absent_tile_covers_the_wished_levels() {
    let mut p = pager(1 << 20, 3, 1);
    p.update((1.5, 1.5));
    p.request(&[want(2, 0, 4, 0.3)]);
    assert_eq!(p.stream_stats().requests, 1);
    assert_eq!(
        p.held_levels(TileId::new(2, 0)),
        4,
        "one range request brings every level it is wished"
    );
    assert_eq!(p.loader().fetched.load(Ordering::Relaxed), 1);
}

#[test]
fn a_tile_oscillating_across_a_level_boundary_asks_once() {
    // Room for the coarse level only: a finer request waits in the queue.
    let mut p = pager(250, 1, 1);
    p.update((0.5, 0.5));
    p.request(&[]);
    assert_eq!(p.held_levels(TileId::new(0, 0)), 1);
    let mut asked = Vec::new();
    for k in 0..30 {
        p.set_time(0.1 * k as f64);
        let levels = if k < 2 || k % 2 == 1 { 3 } else { 2 };
        p.request(&[want(0, 0, levels, 0.5)]);
        asked.extend(p.queue().waiting().iter().map(|r| (r.id, r.levels)));
    }
    asked.dedup();
    assert_eq!(
        asked,
        [(TileId::new(0, 0), 3)],
        "one request, never churned"
    );
    assert_eq!(p.stream_stats().cancelled, 0);
}

/// A simulated link on which every fetch takes the same seconds.
struct PerFetch(Arc<AtomicU32>, f64);

/// Seconds a fetch takes on the slow link most tests use.
const SECONDS_PER_FETCH: f64 = 3.0;

impl TransferClock for PerFetch {
    fn busy_seconds(&self) -> f64 {
        self.1 * f64::from(self.0.load(Ordering::Relaxed))
    }
}

/// A pager over `tiles` x 1 tiles on a simulated link carrying `queue_depth` requests, each
/// taking [`SECONDS_PER_FETCH`].
fn simulated(tiles: u32, queue_depth: usize) -> StreamPager<Synthetic> {
    link_of(tiles, queue_depth, SECONDS_PER_FETCH, FILL)
}

/// A pager over `tiles` x 1 tiles with `settings` on a simulated link carrying `queue_depth`
/// requests, each taking `seconds`.
fn link_of(
    tiles: u32,
    queue_depth: usize,
    seconds: f64,
    settings: StreamSettings,
) -> StreamPager<Synthetic> {
    let loader = Synthetic::default();
    let clock = PerFetch(Arc::clone(&loader.fetched), seconds);
    let config = PagerConfig::new(1 << 20, PagerMode::Simulated { queue_depth });
    let mut p =
        StreamPager::new(loader, Pyramid::new(tiles, 1).unwrap(), config, settings).unwrap();
    p.set_transfer_clock(Arc::new(clock));
    p
}

/// One frame at `t` seconds with the viewer on tile (0, 0), wishing `wants`.
fn frame(p: &mut StreamPager<Synthetic>, t: f64, wants: &[Want]) {
    p.set_time(t);
    p.update((0.5, 0.5));
    p.request(wants);
}

/// Five tiles asked for 3 levels each, a frame after their coarsest levels arrived, at a frame
/// interval of 0.25 s on a link carrying `queue_depth` requests whose fetches take `seconds`,
/// with a queue of `capacity`; returns how many of the five requests went out in that frame.
fn sent_in_one_frame(queue_depth: usize, seconds: f64, capacity: usize) -> usize {
    let settings = StreamSettings {
        queue_capacity: capacity,
        ..FILL
    };
    let mut p = link_of(5, queue_depth, seconds, settings);
    let mut t = 0.0;
    while (0..5).any(|x| p.held_levels(TileId::new(x, 0)) == 0) {
        frame(&mut p, t, &[]);
        t += 0.25;
        assert!(t < 100.0, "the belts never brought the coarsest levels");
    }
    let before = p.stream_stats().requests;
    let wants: Vec<Want> = (0..5)
        .map(|x| want(x, 0, 3, 1.0 - 0.1 * f64::from(x)))
        .collect();
    frame(&mut p, t, &wants);
    check_accounting(&p);
    (p.stream_stats().requests - before) as usize
}

#[test]
fn a_link_that_delivers_within_a_frame_takes_more_than_the_queue_depth() {
    // 20 ms a fetch, 250 ms a frame: all five go at once, past a depth of 2.
    assert_eq!(sent_in_one_frame(2, 0.02, 32), 5);
    // 100 ms a fetch: the third starts at 0.2 s, within the frame, and the link is then busy
    // past the next one: three go.
    assert_eq!(sent_in_one_frame(2, 0.1, 32), 3);
    // 3 s a fetch: no more than the depth.
    assert_eq!(sent_in_one_frame(2, SECONDS_PER_FETCH, 32), 2);
    // A link that takes no time stops at the queue's capacity.
    assert_eq!(sent_in_one_frame(1, 0.0, 3), 3);
}

#[test]
fn the_belt_fill_goes_on_over_a_link_slower_than_a_frame() {
    // Each coarsest level takes 3 s, frames come every 0.25 s and no view asks for anything:
    // the fill's requests stay on the link until they arrive.
    let mut p = simulated(3, 1);
    let mut t = 0.0;
    while t <= 3.0 * SECONDS_PER_FETCH + 0.5 {
        frame(&mut p, t, &[]);
        t += 0.25;
    }
    for x in 0..3 {
        assert_eq!(p.held_levels(TileId::new(x, 0)), 1, "tile {x}");
    }
    assert_eq!(p.stream_stats().cancelled, 0);
    check_accounting(&p);
}

#[test]
fn a_request_on_its_way_is_cancelled_once_its_tile_stops_mattering() {
    let mut p = simulated(1, 1);
    frame(&mut p, 0.0, &[]);
    frame(&mut p, SECONDS_PER_FETCH, &[want(0, 0, 4, 0.5)]);
    assert_eq!(p.held_levels(TileId::new(0, 0)), 1);
    let sent = SECONDS_PER_FETCH + 0.1;
    frame(&mut p, sent, &[want(0, 0, 4, 0.5)]);
    assert_eq!(p.resident().stats().fetching, 1, "levels 1..4 on their way");
    // The tile leaves the view: held for a second, then cancelled on its way.
    frame(&mut p, sent + 0.4, &[]);
    assert_eq!(p.resident().stats().fetching, 1);
    frame(&mut p, sent + 0.4 + HOLD_SECONDS, &[]);
    let stats = p.stream_stats();
    assert_eq!(stats.cancelled_in_flight, 1);
    let whole = (bytes_at(4) - bytes_at(1)) as u64;
    assert!(stats.cut_bytes > 0 && stats.cut_bytes < whole, "{stats:?}");
    assert_eq!(p.resident().stats().fetching, 0);
    assert_eq!(
        p.resident().stats().memory_bytes,
        bytes_at(1),
        "reservation released"
    );
    frame(&mut p, sent + 2.0 * SECONDS_PER_FETCH, &[]);
    assert_eq!(p.held_levels(TileId::new(0, 0)), 1, "nothing arrives");
    assert_eq!(p.resident().stats().errors, 0);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 48, ..ProptestConfig::default() })]

    /// Random flights with random wishes under a tight limit: the accounting always holds, and
    /// once the viewer stops, every tile it asks for reaches the level it asks for.
    #[test]
    fn cancelling_and_reprioritising_never_lose_a_tile(
        path in prop::collection::vec((0.0f64..6.0, 0.0f64..6.0), 1..12),
        wishes in prop::collection::vec(
            prop::collection::vec((0u32..6, 0u32..6, 1usize..=LEVELS, 0.0f64..1.0), 0..8),
            1..12),
        rest in prop::collection::vec((0u32..6, 0u32..6, 1usize..=LEVELS), 1..4),
        capacity in 1usize..6,
    ) {
        let limit = 36 * bytes_at(1) + rest.len() * bytes_at(LEVELS);
        let config = PagerConfig::new(limit, PagerMode::Stepped { fetches_per_update: 2 });
        let settings = StreamSettings { queue_capacity: capacity, ..FILL };
        let mut p =
            StreamPager::new(Synthetic::default(), Pyramid::new(6, 6).unwrap(), config, settings)
                .unwrap();
        for (k, &viewer) in path.iter().enumerate() {
            p.set_time(0.25 * k as f64);
            p.update(viewer);
            let wants: Vec<Want> = wishes[k % wishes.len()]
                .iter()
                .map(|&(x, y, l, pr)| want(x, y, l, pr))
                .collect();
            p.request(&wants);
            check_accounting(&p);
        }
        let last = *path.last().unwrap();
        let wants: Vec<Want> = rest.iter().map(|&(x, y, l)| want(x, y, l, 0.5)).collect();
        for k in 0..400 {
            p.set_time(0.25 * (path.len() + k) as f64);
            p.update(last);
            p.request(&wants);
            check_accounting(&p);
        }
        for w in &wants {
            prop_assert!(p.held_levels(w.id) >= w.levels, "{:?} holds {}", w, p.held_levels(w.id));
        }
        prop_assert_eq!(p.resident().stats().errors, 0, "{:?}", p.resident().last_error());
    }
}

/// Three frames of nothing asked, one fetch apart: the belts bring two tiles' coarsest levels,
/// one after the other.
fn belts_bring_the_coarsest_levels(p: &mut StreamPager<Synthetic>) {
    for k in 0..3 {
        frame(p, SECONDS_PER_FETCH * f64::from(k), &[]);
    }
}

#[test]
fn a_transfer_not_started_is_cancelled_as_soon_as_its_tile_leaves_the_views() {
    let mut p = simulated(2, 2);
    belts_bring_the_coarsest_levels(&mut p);
    assert_eq!(p.held_levels(TileId::new(1, 0)), 1);
    // Both tiles are asked up to 4 levels: the link carries the first, the second waits.
    let sent = 3.0 * SECONDS_PER_FETCH;
    frame(&mut p, sent, &[want(0, 0, 4, 0.9), want(1, 0, 4, 0.5)]);
    assert_eq!(p.resident().stats().fetching, 2);
    // Tile (1, 0) leaves the view at once: its transfer had not started, so it goes now,
    // without waiting for the hold, and no byte of it crossed the link.
    frame(&mut p, sent + 0.1, &[want(0, 0, 4, 0.9)]);
    let stats = p.stream_stats();
    assert_eq!(stats.cancelled_in_flight, 1, "{stats:?}");
    assert_eq!(stats.cut_bytes, 0);
    assert_eq!(p.resident().stats().fetching, 1);
    // Tile (0, 0)'s transfer is under way: it stays through the hold.
    frame(&mut p, sent + 0.2, &[]);
    assert_eq!(p.resident().stats().fetching, 1);
    frame(&mut p, sent + SECONDS_PER_FETCH, &[]);
    assert_eq!(p.held_levels(TileId::new(0, 0)), 4);
    assert_eq!(p.held_levels(TileId::new(1, 0)), 1);
    check_accounting(&p);
}

#[test]
fn a_held_wish_waiting_unsent_goes_as_far_as_the_first_frame_asking_for_more_than_its_tile_holds() {
    let mut p = simulated(2, 1);
    belts_bring_the_coarsest_levels(&mut p);
    assert_eq!(p.held_levels(TileId::new(0, 0)), 1);
    // Tile (1, 0) takes the link; tile (0, 0)'s request for 4 levels waits.
    let busy = 2.0 * SECONDS_PER_FETCH;
    frame(&mut p, busy, &[want(1, 0, 2, 0.9), want(0, 0, 4, 0.5)]);
    assert_eq!(p.resident().stats().fetching, 1);
    assert_eq!(p.queue().waiting().len(), 1);
    // The link is free when a frame asks tile (0, 0) for fewer levels than its held wish, but
    // for more than it holds: the request goes, for the levels the frame asks (a level
    // beyond them would arrive for frames that may not draw it).
    let free = busy + SECONDS_PER_FETCH;
    frame(&mut p, free, &[want(0, 0, 3, 0.5)]);
    assert_eq!(p.held_levels(TileId::new(1, 0)), 2);
    assert_eq!(
        p.resident().stats().fetching,
        1,
        "sent in the frame asking for 3"
    );
    frame(&mut p, free + 0.5, &[want(0, 0, 3, 0.5)]);
    frame(&mut p, free + SECONDS_PER_FETCH, &[want(0, 0, 3, 0.5)]);
    assert_eq!(p.held_levels(TileId::new(0, 0)), 3);
    assert_eq!(p.stream_stats().cancelled, 0, "nothing sent was cut");
    assert_eq!(p.resident().stats().fetching, 0);
    check_accounting(&p);
}
