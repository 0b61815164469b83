//! The pager in `PagerMode::Simulated` with a loader whose transfers cost known simulated time:
//! tiles arrive exactly when their transfers end on a link that carries one at a time, in the
//! order they were planned, never more than the queue depth in flight, and the memory limit,
//! reservations included, is never overspent.

use std::sync::{Arc, Mutex};

use stripmask::db::grid::TileId;
use stripmask::db::grid::{Grid, Pyramid};
use stripmask::engine::paging::{
    BeltPager, PagerConfig, PagerMode, ResidentLoader, TileLoader, TransferClock,
};

/// Seconds of transfer so far, as exact binary fractions so that due times compare exactly.
#[derive(Default)]
struct Meter(Mutex<f64>);

impl TransferClock for Meter {
    fn busy_seconds(&self) -> f64 {
        *self.0.lock().unwrap()
    }
}

#[derive(Debug)]
struct Tile {
    bytes: usize,
}

/// Every tile holds `bytes` and its transfer takes `seconds` on the meter; loads are logged.
struct Timed {
    bytes: usize,
    seconds: f64,
    meter: Arc<Meter>,
    log: Arc<Mutex<Vec<TileId>>>,
}

impl ResidentLoader for Timed {
    type Loaded = Tile;

    fn loaded_bytes(&self, tile: &Tile) -> usize {
        tile.bytes
    }
}

impl TileLoader for Timed {
    fn predicted_bytes(&self, _: TileId, _: u32) -> usize {
        self.bytes
    }

    fn load(&self, id: TileId, _: u32) -> stripmask::Result<(Tile, u64)> {
        *self.meter.0.lock().unwrap() += self.seconds;
        self.log.lock().unwrap().push(id);
        Ok((Tile { bytes: self.bytes }, self.bytes as u64))
    }

    fn shrink(&self, tile: &mut Tile, _: u32) -> usize {
        tile.bytes
    }
}

struct Rig {
    pager: BeltPager<Timed>,
    log: Arc<Mutex<Vec<TileId>>>,
}

fn rig(grid: (u32, u32), limit: usize, queue_depth: usize, seconds: f64) -> Rig {
    let meter = Arc::new(Meter::default());
    let log = Arc::new(Mutex::new(Vec::new()));
    let loader = Timed {
        bytes: 1000,
        seconds,
        meter: Arc::clone(&meter),
        log: Arc::clone(&log),
    };
    let config = PagerConfig::new(limit, PagerMode::Simulated { queue_depth });
    let mut pager = BeltPager::new(loader, Pyramid::new(grid.0, grid.1).unwrap(), config).unwrap();
    pager.set_transfer_clock(meter);
    Rig { pager, log }
}

fn loaded(p: &BeltPager<Timed>) -> Vec<TileId> {
    p.resident().tiles().map(|(id, _)| id).collect()
}

/// Memory (loaded tiles plus reservations) within the limit, and at most `depth` in flight.
fn check(p: &BeltPager<Timed>, depth: usize) {
    let s = p.resident().stats();
    assert!(s.memory_bytes <= s.memory_limit_bytes, "{s:?}");
    assert!(s.memory_peak_bytes <= s.memory_limit_bytes, "{s:?}");
    let reserved: usize = p
        .resident()
        .ledger()
        .records()
        .filter_map(|(_, r)| r.fetch)
        .map(|f| f.bytes)
        .sum();
    assert_eq!(1000 * s.loaded_tiles + reserved, s.memory_bytes);
    assert!(s.fetching <= depth, "{} in flight", s.fetching);
}

#[test]
fn tiles_arrive_when_their_transfers_end_one_after_the_other_in_planned_order() {
    // 1/8 s per tile, updates every 1/32 s (exact binary fractions: no rounding at the edges).
    let (depth, step, transfer) = (3, 1.0 / 32.0, 0.125);
    let mut r = rig((5, 5), 100_000, depth, transfer);
    let viewer = (2.5, 2.5);
    // Each transfer is planned at some update; the link takes them one at a time, so one ends at
    // max(the previous one's end, the time it was planned) + 1/8 s.
    let mut due: Vec<(TileId, f64)> = Vec::new();
    let mut link_free: f64 = 0.0;
    let mut arrived: Vec<(TileId, f64)> = Vec::new();
    for n in 0..=200u32 {
        let time = f64::from(n) * step;
        r.pager.set_time(time);
        let before = loaded(&r.pager);
        r.pager.update(viewer);
        check(&r.pager, depth);
        let new: Vec<TileId> = loaded(&r.pager)
            .into_iter()
            .filter(|id| !before.contains(id))
            .collect();
        assert!(
            new.len() <= 1,
            "one link: one arrival per 1/8 s, got {new:?}"
        );
        arrived.extend(new.into_iter().map(|id| (id, time)));
        let log = r.log.lock().unwrap();
        for &id in &log[due.len()..] {
            link_free = link_free.max(time) + transfer;
            due.push((id, link_free));
        }
    }
    assert_eq!(arrived.len(), 25, "the whole 5 x 5 grid arrives");
    assert_eq!(due.len(), 25, "each tile is transferred once");
    for (k, &(id, at)) in arrived.iter().enumerate() {
        let (planned, end) = due[k];
        assert_eq!(id, planned, "arrivals follow the planned order");
        assert!(
            at >= end && at - step < end,
            "{id} arrived at {at} s, its transfer ended at {end} s"
        );
    }
    // The link was kept busy within each belt: 25 transfers took under 25/8 s plus idle gaps
    // between belts (two of them: centre, belt 1, belt 2).
    assert!(
        link_free <= 25.0 * transfer + 2.0 * step * 4.0,
        "{link_free}"
    );
    // Planned nearest belt first: the ring of the arrivals never goes down.
    let centre = TileId::new(2, 2);
    let rings: Vec<u32> = arrived
        .iter()
        .map(|&(id, _)| Grid::ring(centre, id))
        .collect();
    assert!(rings.windows(2).all(|w| w[0] <= w[1]), "{rings:?}");
    assert_eq!(r.pager.resident().stats().fetching, 0);
}

#[test]
fn an_idle_link_starts_the_next_transfer_at_the_time_it_is_planned() {
    // One tile in flight at a time, 1/4 s each; the viewer waits 1 s on a 1 x 2 grid, so the
    // second tile, planned only when the first arrives, ends 1/4 s after that arrival.
    let mut r = rig((2, 1), 100_000, 1, 0.25);
    r.pager.update((0.5, 0.5));
    r.pager.set_time(1.0);
    r.pager.update((0.5, 0.5));
    assert_eq!(loaded(&r.pager), [TileId::new(0, 0)]);
    assert_eq!(r.pager.resident().stats().fetching, 1);
    r.pager.set_time(1.24);
    r.pager.update((0.5, 0.5));
    assert_eq!(loaded(&r.pager).len(), 1, "not before 1.25 s");
    r.pager.set_time(1.25);
    r.pager.update((0.5, 0.5));
    assert_eq!(loaded(&r.pager).len(), 2);
}

#[test]
fn a_simulated_flight_under_a_binding_limit_never_overspends_it() {
    // 12 tiles of 1000 bytes fit; the flight crosses a 12 x 12 grid and back.
    let (depth, limit) = (4, 12_000);
    let mut r = rig((12, 12), limit, depth, 0.05);
    let mut t = 0.0;
    let path: Vec<(f64, f64)> = (0..=110)
        .map(|k| f64::from(k) * 0.1 + 0.5)
        .chain((0..=110).rev().map(|k| f64::from(k) * 0.1 + 0.5))
        .map(|v| (v, 0.5 + v * 0.9))
        .collect();
    let mut peak = 0;
    for viewer in path {
        t += 0.04;
        r.pager.set_time(t);
        r.pager.update(viewer);
        check(&r.pager, depth);
        peak = peak.max(r.pager.resident().stats().memory_bytes);
    }
    let s = r.pager.resident().stats();
    assert!(s.evictions > 0, "the limit binds: {s:?}");
    assert!(peak > limit * 8 / 10, "peak {peak}");
    assert_eq!(s.errors, 0, "{:?}", r.pager.resident().last_error());
}
