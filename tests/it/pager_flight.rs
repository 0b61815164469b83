//! The pager with a fake loader: flights through a grid in stepped and threaded mode, checking
//! the memory invariant after every update, off-terrain viewpoints, jumps, upgrades and shrinks,
//! failures, and a clean stop.

use std::collections::HashMap;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use proptest::prelude::*;
use stripmask::Error;
use stripmask::db::grid::TileId;
use stripmask::db::grid::{Grid, Pyramid};
use stripmask::engine::paging::{
    BeltPager, PagerConfig, PagerMode, ResidentLoader, TileLoader, TileState,
};
use stripmask::engine::paging::{Failure, RetryPolicy};

type Cost = Arc<dyn Fn(TileId, u32) -> usize + Send + Sync>;

/// A tile of the fake loader: what it was loaded for and what it holds.
#[derive(Debug)]
struct FakeTile {
    id: TileId,
    ring: u32,
    bytes: usize,
}

/// A loader that fabricates tiles of a given cost, optionally slowly, failing or lying.
struct Fake {
    cost: Cost,
    delay: Duration,
    /// Failures left per tile (`u32::MAX`: always).
    failures: Mutex<HashMap<TileId, u32>>,
    panic_on: Option<TileId>,
    /// Extra bytes a tile holds beyond its prediction.
    lie_on: Option<TileId>,
    /// Every load started, in order.
    log: Arc<Mutex<Vec<(TileId, u32)>>>,
}

impl Fake {
    fn new(cost: impl Fn(TileId, u32) -> usize + Send + Sync + 'static) -> Self {
        Fake {
            cost: Arc::new(cost),
            delay: Duration::ZERO,
            failures: Mutex::new(HashMap::new()),
            panic_on: None,
            lie_on: None,
            log: Arc::new(Mutex::new(Vec::new())),
        }
    }

    fn loads_of(&self, id: TileId) -> Vec<u32> {
        let log = self.log.lock().unwrap();
        log.iter()
            .filter(|(t, _)| *t == id)
            .map(|&(_, r)| r)
            .collect()
    }
}

impl ResidentLoader for Fake {
    type Loaded = FakeTile;

    fn loaded_bytes(&self, tile: &FakeTile) -> usize {
        tile.bytes
    }
}

impl TileLoader for Fake {
    fn predicted_bytes(&self, id: TileId, ring: u32) -> usize {
        (self.cost)(id, ring)
    }

    fn load(&self, id: TileId, ring: u32) -> stripmask::Result<(FakeTile, u64)> {
        self.log.lock().unwrap().push((id, ring));
        std::thread::sleep(self.delay);
        if self.panic_on == Some(id) {
            panic!("fake loader panics on {id}");
        }
        if let Some(left) = self
            .failures
            .lock()
            .unwrap()
            .get_mut(&id)
            .filter(|l| **l > 0)
        {
            *left = left.saturating_sub(if *left == u32::MAX { 0 } else { 1 });
            return Err(Error::invalid(format!("fake {id}"), "simulated failure"));
        }
        let bytes = (self.cost)(id, ring) + usize::from(self.lie_on == Some(id));
        Ok((FakeTile { id, ring, bytes }, bytes as u64 / 4))
    }

    fn shrink(&self, tile: &mut FakeTile, ring: u32) -> usize {
        tile.bytes = tile.bytes.min((self.cost)(tile.id, ring));
        tile.ring = ring;
        tile.bytes
    }
}

fn stepped(n: usize) -> PagerMode {
    PagerMode::Stepped {
        fetches_per_update: n,
    }
}

fn pager(fake: Fake, w: u32, h: u32, limit: usize, mode: PagerMode) -> BeltPager<Fake> {
    BeltPager::new(
        fake,
        Pyramid::new(w, h).unwrap(),
        PagerConfig::new(limit, mode),
    )
    .unwrap()
}

fn center_of(t: TileId) -> (f64, f64) {
    (f64::from(t.x) + 0.5, f64::from(t.y) + 0.5)
}

/// The invariants that hold after every update, in either mode.
fn check(p: &BeltPager<Fake>) {
    let s = p.resident().stats();
    assert!(
        s.memory_bytes <= s.memory_limit_bytes,
        "memory {} over the limit {}",
        s.memory_bytes,
        s.memory_limit_bytes
    );
    assert!(s.memory_peak_bytes <= s.memory_limit_bytes);
    assert!(s.memory_bytes <= s.memory_peak_bytes);
    let held: usize = p.resident().tiles().map(|(_, t)| t.bytes).sum();
    let reserved: usize = p
        .resident()
        .ledger()
        .records()
        .filter_map(|(_, r)| r.fetch)
        .map(|f| f.bytes)
        .sum();
    assert_eq!(held + reserved, s.memory_bytes, "accounting drifted");
    for (id, tile) in p.resident().tiles() {
        assert_eq!(id, tile.id);
        let record = p.resident().ledger().record(id).loaded.unwrap();
        assert_eq!((record.bytes, record.ring), (tile.bytes, tile.ring), "{id}");
    }
    assert_eq!(s.loaded_tiles, p.resident().tiles().count());
    if let (Some(c), Some(d)) = (p.resident().current_tile(), s.complete_belts) {
        let grid = p.resident().ledger().grid();
        for y in 0..grid.tiles_y() {
            for x in 0..grid.tiles_x() {
                let t = TileId::new(x, y);
                if Grid::ring(c, t) <= d
                    && p.resident().ledger().record(t).failure != Some(Failure::GaveUp)
                {
                    assert_eq!(
                        p.resident().state(t),
                        TileState::Square,
                        "{t} in belt <= {d}"
                    );
                    assert!(p.resident().get(t).is_some());
                }
            }
        }
    }
}

/// Near tiles hold 4000 bytes, belts 2 and 3 hold 1000, farther ones 250.
fn three_levels(_: TileId, ring: u32) -> usize {
    match ring {
        0 | 1 => 4000,
        2 | 3 => 1000,
        _ => 250,
    }
}

/// A long flight over a 32 x 32 grid in tile units: straight legs, turns, a pause, an
/// excursion off the west edge, a jump across the grid, a circle and a trip off the south edge.
fn long_path() -> Vec<(f64, f64)> {
    let mut path = Vec::new();
    let mut at = (3.5, 3.5);
    let leg = |path: &mut Vec<(f64, f64)>, at: &mut (f64, f64), steps: usize, d: (f64, f64)| {
        for _ in 0..steps {
            at.0 += d.0;
            at.1 += d.1;
            path.push(*at);
        }
    };
    leg(&mut path, &mut at, 20, (0.0, 0.0));
    leg(&mut path, &mut at, 40, (0.5, 0.0));
    leg(&mut path, &mut at, 30, (0.0, 0.5));
    leg(&mut path, &mut at, 30, (-0.6, -0.3));
    leg(&mut path, &mut at, 20, (-0.4, 0.0));
    leg(&mut path, &mut at, 15, (0.6, 0.1));
    at = (28.5, 27.5);
    leg(&mut path, &mut at, 25, (0.0, 0.0));
    for k in 0..60 {
        let a = f64::from(k) * std::f64::consts::TAU / 60.0;
        path.push((20.0 + 8.0 * a.cos(), 20.0 + 8.0 * a.sin()));
    }
    at = (16.0, 25.0);
    leg(&mut path, &mut at, 30, (0.1, 0.4));
    leg(&mut path, &mut at, 30, (0.0, -0.5));
    path
}

#[test]
fn a_long_stepped_flight_never_exceeds_the_limit_and_keeps_the_square_loaded() {
    let limit = 60_000;
    let fake = Fake::new(three_levels);
    let mut p = pager(fake, 32, 32, limit, stepped(3));
    let path = long_path();
    assert!(path.len() >= 300);
    let mut off_terrain = 0;
    for &viewer in &path {
        p.update(viewer);
        check(&p);
        if !(0.0..32.0).contains(&viewer.0) || !(0.0..32.0).contains(&viewer.1) {
            off_terrain += 1;
        }
    }
    assert!(off_terrain > 10);
    let s = p.resident().stats();
    assert!(s.fetches > 200 && s.evictions > 100, "{s:?}");
    assert_eq!(s.errors, 0);
    // Tiles were fetched again for a nearer belt (upgrades) and shrunk for farther ones.
    let upgraded = p.resident().tiles().any(|(id, _)| {
        let rings = p.loader().loads_of(id);
        rings.windows(2).any(|w| w[1] < w[0])
    });
    assert!(upgraded);
    // Settled in the interior: belts 0..=2 cost 4000 + 8 * 4000 + 16 * 1000 = 52,000 bytes,
    // belt 3 would add 24,000 more.
    let c = TileId::new(12, 14);
    for _ in 0..40 {
        p.update(center_of(c));
        check(&p);
    }
    assert_eq!(p.resident().stats().complete_belts, Some(2));
    assert!(p.resident().stats().memory_bound);
    let square: usize = p
        .resident()
        .tiles()
        .filter(|&(id, _)| p.resident().state(id) == TileState::Square)
        .map(|(_, t)| t.bytes)
        .sum();
    assert_eq!(square, 52_000);
}

#[test]
fn a_long_threaded_flight_never_exceeds_the_limit() {
    let limit = 60_000;
    let mut fake = Fake::new(three_levels);
    fake.delay = Duration::from_micros(300);
    let mut p = pager(fake, 32, 32, limit, PagerMode::Threaded { queue_depth: 4 });
    let mut most_in_flight = 0;
    for &viewer in &long_path() {
        p.update(viewer);
        check(&p);
        most_in_flight = most_in_flight.max(p.resident().stats().fetching);
        std::thread::sleep(Duration::from_millis(1));
    }
    assert!(most_in_flight > 1 && most_in_flight <= 4);
    let c = TileId::new(12, 14);
    let start = Instant::now();
    while p.resident().stats().complete_belts != Some(2) || p.resident().stats().fetching > 0 {
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "{:?}",
            p.resident().stats()
        );
        p.update(center_of(c));
        check(&p);
        std::thread::sleep(Duration::from_millis(1));
    }
    let s = p.resident().stats();
    assert!(s.fetches > 150 && s.evictions > 50, "{s:?}");
    assert_eq!(s.errors, 0);
    assert!(s.memory_peak_bytes <= limit);
}

#[test]
fn off_the_terrain_the_nearest_tile_is_used_when_asked() {
    // From tile (0, 2) of an 8 x 6 grid belts 0..=2 are the 3 x 5 rectangle x <= 2, y <= 4
    // (150 bytes at 10 a tile) and belts 0..=3 the 4 x 6 rectangle (240 bytes).
    let fake = Fake::new(|_, _| 10);
    let mut p = pager(fake, 8, 6, 200, stepped(100));
    for _ in 0..3 {
        p.update((-3.0, 2.5));
        check(&p);
    }
    assert_eq!(p.resident().current_tile(), Some(TileId::new(0, 2)));
    let s = p.resident().stats();
    assert_eq!(s.complete_belts, Some(2));
    assert!(s.memory_bound);
    assert_eq!((s.loaded_tiles, s.memory_bytes), (15, 150));
    assert_eq!(p.resident().state(TileId::new(2, 4)), TileState::Square);
    assert_eq!(p.resident().state(TileId::new(3, 2)), TileState::Absent);
    assert_eq!(p.resident().state(TileId::new(0, 5)), TileState::Absent);
}

#[test]
fn off_the_terrain_without_nearest_nothing_new_is_fetched_and_the_tiles_stay_as_cache() {
    let fake = Fake::new(|_, _| 10);
    let mut config = PagerConfig::new(usize::MAX, stepped(100));
    config.nearest_when_off = false;
    let mut p = BeltPager::new(fake, Pyramid::new(8, 6).unwrap(), config).unwrap();
    for _ in 0..5 {
        p.update((-3.0, 2.5));
    }
    assert_eq!(p.resident().current_tile(), None);
    assert_eq!(
        (
            p.resident().stats().fetches,
            p.resident().stats().loaded_tiles
        ),
        (0, 0)
    );
    for _ in 0..10 {
        p.update((3.5, 2.5));
    }
    let loaded = p.resident().stats();
    assert_eq!(loaded.loaded_tiles, 48);
    for viewer in [(3.5, -0.1), (8.0, 2.0), (f64::NAN, 1.0)] {
        p.update(viewer);
        check(&p);
        let s = p.resident().stats();
        assert_eq!(s.complete_belts, None);
        assert_eq!(
            (s.fetches, s.memory_bytes),
            (loaded.fetches, loaded.memory_bytes)
        );
        assert!(
            p.resident()
                .tiles()
                .all(|(id, _)| p.resident().state(id) == TileState::Cached)
        );
    }
    p.update((3.5, 2.5));
    assert_eq!(p.resident().stats().fetches, loaded.fetches);
    assert_eq!(p.resident().state(TileId::new(0, 0)), TileState::Square);
}

#[test]
fn a_far_jump_rebuilds_the_square_there_evicting_the_old_one_farthest_first() {
    let fake = Fake::new(|_, _| 10);
    let mut p = pager(fake, 32, 32, 250, stepped(1));
    for _ in 0..30 {
        p.update(center_of(TileId::new(3, 3)));
    }
    assert_eq!(p.resident().stats().complete_belts, Some(2));
    assert_eq!(p.resident().stats().memory_bytes, 250);
    let far = TileId::new(28, 28);
    p.update(center_of(far));
    check(&p);
    assert_eq!(p.resident().state(far), TileState::Square);
    assert_eq!(p.resident().state(TileId::new(1, 1)), TileState::Absent);
    assert_eq!(p.resident().state(TileId::new(5, 5)), TileState::Cached);
    for _ in 0..30 {
        p.update(center_of(far));
        check(&p);
    }
    assert_eq!(p.resident().stats().complete_belts, Some(2));
    assert!(p.resident().tiles().all(|(id, _)| Grid::ring(far, id) <= 2));
    assert_eq!(p.resident().stats().evictions, 25);
}

#[test]
fn ring_dependent_costs_upgrade_nearer_tiles_and_shrink_farther_ones() {
    let near_fine = |_: TileId, ring: u32| if ring <= 1 { 1000 } else { 100 };
    let all = 9 * 1000 + 112 * 100;
    let mut p = pager(Fake::new(near_fine), 11, 11, usize::MAX, stepped(1));
    for _ in 0..130 {
        p.update(center_of(TileId::new(5, 5)));
    }
    check(&p);
    assert_eq!(p.resident().stats().complete_belts, Some(5));
    assert_eq!(p.resident().stats().memory_bytes, all);
    // One tile east: x = 7 comes into belt 1 holding coarse copies, x = 4 leaves it.
    let east = TileId::new(6, 5);
    p.update(center_of(east));
    check(&p);
    let shrunk = p.resident().get(TileId::new(4, 5)).unwrap();
    assert_eq!((shrunk.bytes, shrunk.ring), (100, 2));
    assert_eq!(p.resident().stats().complete_belts, Some(0));
    // The first update upgraded the nearest one; the others still hold their coarse copies.
    assert_eq!(p.resident().get(TileId::new(7, 5)).unwrap().bytes, 1000);
    assert_eq!(p.resident().get(TileId::new(7, 4)).unwrap().bytes, 100);
    assert_eq!(p.resident().state(TileId::new(7, 4)), TileState::Cached);
    p.update(center_of(east));
    p.update(center_of(east));
    check(&p);
    assert_eq!(p.resident().stats().complete_belts, Some(6));
    for t in [TileId::new(7, 4), TileId::new(7, 5), TileId::new(7, 6)] {
        assert_eq!(p.loader().loads_of(t), vec![2, 1], "{t}");
        assert_eq!(p.resident().get(t).unwrap().bytes, 1000);
    }
    assert_eq!(p.resident().stats().memory_bytes, all);
    // With costs that do not depend on the ring, the same move fetches nothing.
    let mut r = pager(Fake::new(|_, _| 100), 11, 11, usize::MAX, stepped(200));
    r.update(center_of(TileId::new(5, 5)));
    let fetched = r.resident().stats().fetches;
    assert_eq!(fetched, 121);
    r.update(center_of(east));
    assert_eq!(r.resident().stats().fetches, fetched);
    assert_eq!(r.resident().stats().complete_belts, Some(6));
}

#[test]
fn failed_fetches_are_retried_then_given_up_and_the_pager_carries_on() {
    let fake = Fake::new(|_, _| 10);
    fake.failures
        .lock()
        .unwrap()
        .extend([(TileId::new(2, 2), u32::MAX), (TileId::new(1, 1), 2)]);
    let mut config = PagerConfig::new(1000, stepped(30));
    config.retry = RetryPolicy {
        max_attempts: 3,
        delay_updates: 2,
        ..RetryPolicy::default()
    };
    let mut p = BeltPager::new(fake, Pyramid::new(5, 5).unwrap(), config).unwrap();
    p.update(center_of(TileId::new(2, 2)));
    check(&p);
    assert_eq!(p.resident().state(TileId::new(2, 2)), TileState::Failed);
    assert_eq!(p.resident().stats().complete_belts, None);
    let e = p.resident().last_error().unwrap();
    assert!(e.contains("tile (2, 2)") && e.contains("will retry"), "{e}");
    for _ in 0..12 {
        p.update(center_of(TileId::new(2, 2)));
        check(&p);
    }
    let s = p.resident().stats();
    assert_eq!(s.errors, 3 + 2);
    assert_eq!(s.failed_tiles, 1);
    assert_eq!(p.resident().state(TileId::new(2, 2)), TileState::Failed);
    assert!(p.resident().get(TileId::new(2, 2)).is_none());
    assert_eq!(p.resident().state(TileId::new(1, 1)), TileState::Square);
    assert_eq!(s.complete_belts, Some(2));
    assert_eq!((s.loaded_tiles, s.memory_bytes), (24, 240));
    assert_eq!(p.loader().loads_of(TileId::new(2, 2)).len(), 3);
    assert_eq!(p.loader().loads_of(TileId::new(1, 1)).len(), 3);
}

#[test]
fn a_tile_holding_more_than_predicted_is_refused() {
    let mut fake = Fake::new(|_, _| 10);
    fake.lie_on = Some(TileId::new(1, 0));
    let mut p = pager(fake, 3, 1, 30, stepped(5));
    for _ in 0..200 {
        p.update((0.5, 0.5));
        check(&p);
    }
    assert!(p.resident().get(TileId::new(1, 0)).is_none());
    assert_eq!(p.resident().state(TileId::new(1, 0)), TileState::Failed);
    let e = p.resident().last_error().unwrap();
    assert!(e.contains("tile (1, 0)") && e.contains("11 bytes"), "{e}");
    assert_eq!(p.resident().stats().complete_belts, Some(2));
}

#[test]
fn a_panicking_loader_is_an_error_not_a_crash() {
    let mut fake = Fake::new(|_, _| 10);
    fake.panic_on = Some(TileId::new(1, 1));
    let mut p = pager(fake, 3, 3, 1000, PagerMode::Threaded { queue_depth: 2 });
    let start = Instant::now();
    while p.resident().stats().errors == 0 || p.resident().stats().fetching > 0 {
        assert!(start.elapsed() < Duration::from_secs(10));
        p.update((1.5, 1.5));
        check(&p);
        std::thread::sleep(Duration::from_millis(1));
    }
    assert!(p.resident().last_error().unwrap().contains("panicked"));
    assert_eq!(p.resident().state(TileId::new(1, 1)), TileState::Failed);
}

#[test]
fn threaded_updates_never_wait_and_dropping_stops_the_fetch_thread() {
    let mut fake = Fake::new(|_, _| 10);
    fake.delay = Duration::from_millis(300);
    let log = Arc::clone(&fake.log);
    let mut p = pager(fake, 9, 9, 10_000, PagerMode::Threaded { queue_depth: 8 });
    let start = Instant::now();
    p.update((4.5, 4.5));
    assert_eq!(p.resident().stats().fetching, 1);
    while p.resident().stats().loaded_tiles == 0 {
        let t = Instant::now();
        p.update((4.5, 4.5));
        assert!(t.elapsed() < Duration::from_millis(100));
        std::thread::sleep(Duration::from_millis(5));
    }
    // The first tile took 300 ms; the updates meanwhile returned at once.
    assert!(start.elapsed() >= Duration::from_millis(300));
    assert_eq!(p.resident().stats().fetching, 8);
    drop(p);
    let started = log.lock().unwrap().len();
    assert!(started <= 3, "{started} loads started");
    std::thread::sleep(Duration::from_millis(400));
    assert_eq!(log.lock().unwrap().len(), started);
}

/// A cost between 8 and 400 bytes per tile, fixed by `seed`, and coarser with the ring when
/// `by_ring` (non-increasing, as texture mips dropped for far tiles would be).
fn random_cost(seed: u32, by_ring: bool) -> impl Fn(TileId, u32) -> usize + Send + Sync + Clone {
    move |id: TileId, ring: u32| {
        let base = ((id.x * 7 + id.y * 13 + seed) % 50 + 1) as usize * 8;
        if by_ring { base >> ring.min(3) } else { base }
    }
}

/// The largest `d` whose belts `0..=d` around `c` fit `limit`, each tile costing its ring's.
fn largest_square(
    grid: Grid,
    c: TileId,
    limit: usize,
    cost: &impl Fn(TileId, u32) -> usize,
) -> Option<u32> {
    let mut best = None;
    let mut total = 0usize;
    for d in 0..=grid.max_ring(c) {
        total += grid.belt(c, d).iter().map(|&t| cost(t, d)).sum::<usize>();
        if total > limit {
            break;
        }
        best = Some(d);
    }
    best
}

#[derive(Clone, Debug)]
enum Step {
    Move(i8, i8),
    Jump(f64, f64),
    Stay,
}

fn step() -> impl Strategy<Value = Step> {
    prop_oneof![
        4 => (-1i8..=1, -1i8..=1).prop_map(|(dx, dy)| Step::Move(dx, dy)),
        1 => (-3.0..15.0f64, -3.0..15.0f64).prop_map(|(x, y)| Step::Jump(x, y)),
        2 => Just(Step::Stay),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn random_flights_keep_memory_within_the_limit_and_the_square_loaded(
        w in 1u32..=12,
        h in 1u32..=12,
        seed in 0u32..1000,
        by_ring: bool,
        limit in 0usize..6000,
        fetches in 1usize..=4,
        nearest: bool,
        start in (0.0..12.0f64, 0.0..12.0f64),
        steps in prop::collection::vec(step(), 1..60),
        end in (0.0..1.0f64, 0.0..1.0f64),
    ) {
        let cost = random_cost(seed, by_ring);
        let grid = Grid::new(w, h).unwrap();
        let mut config = PagerConfig::new(limit, stepped(fetches));
        config.nearest_when_off = nearest;
        let pyramid = Pyramid::new(w, h).unwrap();
        let mut p = BeltPager::new(Fake::new(cost.clone()), pyramid, config).unwrap();
        let mut at = start;
        let mut before: Option<(Option<TileId>, Vec<TileId>)> = None;
        for s in &steps {
            at = match *s {
                Step::Move(dx, dy) => (at.0 + f64::from(dx) * 0.7, at.1 + f64::from(dy) * 0.7),
                Step::Jump(x, y) => (x, y),
                Step::Stay => at,
            };
            p.update(at);
            check(&p);
            // With the same current tile, the complete square of the last update is still loaded.
            if let Some((c, square)) = &before
                && *c == p.resident().current_tile() {
                    prop_assert!(square.iter().all(|&t| p.resident().get(t).is_some()));
                }
            let square: Vec<TileId> = p
                .resident()
                .tiles()
                .map(|(t, _)| t)
                .filter(|&t| p.resident().state(t) == TileState::Square)
                .collect();
            before = Some((p.resident().current_tile(), square));
        }
        // Settle on the grid: the square grows to exactly the largest one that fits.
        let c = TileId::new(
            ((end.0 * f64::from(w)) as u32).min(w - 1),
            ((end.1 * f64::from(h)) as u32).min(h - 1),
        );
        let mut last = u64::MAX;
        for _ in 0..2000 {
            p.update(center_of(c));
            check(&p);
            if p.resident().stats().fetches == last {
                break;
            }
            last = p.resident().stats().fetches;
        }
        prop_assert_eq!(p.resident().stats().complete_belts, largest_square(grid, c, limit, &cost));
        prop_assert_eq!(p.resident().stats().errors, 0);
    }
}
