//! The coarse base: every tile's first level, fetched first and resident for good, so that no
//! view of the terrain has a hole once it arrived — with whole-tile belts that reach only a few
//! tiles, and with progressive streaming; accounted under the limit before it is fetched; tile
//! fetches wait for it; a failing base is retried, then given up, while tiles page on.

use std::sync::Mutex;
use std::sync::atomic::{AtomicU32, Ordering};

use stripmask::Error;
use stripmask::db::grid::{Grid, TileId};
use stripmask::db::source;
use stripmask::engine::paging::stream::{StreamSettings, Streaming};
use stripmask::engine::paging::{
    BeltPager, PagerConfig, PagerMode, ResidentLoader, RetryPolicy, TileLoader,
};
use stripmask::engine::{Engine, EngineSettings};
use stripmask::sim::flight::{Builtin, Flight};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

use crate::support::hills;

/// Frames of the diagonal flight over the 16 x 16-tile hills archive with room for the base and
/// a 5 x 5 square of whole tiles: (frames drawn after the base arrived with a hole, frames
/// before with a hole, frames with the base, frames).
fn holes_on_the_diagonal(streaming: Streaming, coarse_base: bool) -> [usize; 4] {
    let dir = tempfile::tempdir().unwrap();
    let path = hills::archive(dir.path(), 17);
    let settings = EngineSettings {
        memory_limit_bytes: 400_000,
        pager_mode: PagerMode::Stepped {
            fetches_per_update: 2,
        },
        threads: 1,
        streaming,
        coarse_base,
        ..EngineSettings::default()
    };
    let source = source::open(path.to_str().unwrap()).unwrap();
    let mut engine = Engine::new(source, settings, 120).unwrap();
    let flight = Flight::builtin(Builtin::Diagonal, engine.terrain());
    let mut fb = Framebuffer::new(160, 120, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
    let (mut after, mut before, mut based, mut frames) = (0, 0, 0, 0);
    let mut t = 0.0;
    while t < flight.duration() {
        let (eye, target) = flight.at(t);
        let camera = engine.camera(eye, target, true);
        let report = engine.render(&camera, &mut fb).unwrap();
        let stats = report.pager;
        assert!(stats.memory_peak_bytes <= stats.memory_limit_bytes);
        let base = stats.base_tiles > 0;
        based += usize::from(base);
        if report.holes > 0 {
            if base {
                after += 1;
            } else {
                before += 1;
            }
        }
        frames += 1;
        t += 0.25;
    }
    [after, before, based, frames]
}

#[test]
fn with_whole_tile_belts_no_frame_has_a_hole_once_the_base_arrived() {
    let [after, before, based, frames] = holes_on_the_diagonal(Streaming::Belts, true);
    assert_eq!(
        based, frames,
        "stepped: the base arrives with the first update"
    );
    assert_eq!(after + before, 0, "frames with holes, of {frames}");
    // Without the base the belts reach only part of the view.
    let [_, without, based, frames] = holes_on_the_diagonal(Streaming::Belts, false);
    assert_eq!(based, 0);
    assert!(
        without > frames / 4,
        "{without} of {frames} frames have holes without the base"
    );
}

#[test]
fn with_progressive_streaming_no_frame_has_a_hole_once_the_base_arrived() {
    let progressive = Streaming::Progressive(StreamSettings::default());
    let [after, before, based, frames] = holes_on_the_diagonal(progressive, true);
    assert_eq!(
        based, frames,
        "stepped: the base arrives with the first update"
    );
    assert_eq!(after + before, 0, "frames with holes, of {frames}");
}

#[test]
fn the_base_is_reserved_before_it_is_fetched_and_tiles_wait_for_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = hills::archive(dir.path(), 33);
    let settings = EngineSettings {
        memory_limit_bytes: 4 << 20,
        pager_mode: PagerMode::Simulated { queue_depth: 4 },
        threads: 1,
        ..EngineSettings::default()
    };
    let source = source::open(path.to_str().unwrap()).unwrap();
    let mut engine = Engine::new(source, settings, 120).unwrap();
    let mut fb = Framebuffer::new(160, 120, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
    let flight = Flight::builtin(Builtin::Overview, engine.terrain());
    let (eye, target) = flight.at(0.0);
    let camera = engine.camera(eye, target, true);
    // Update 1 sends the base; without a transfer clock it arrives at the next update.
    let first = engine.render(&camera, &mut fb).unwrap();
    assert_eq!(first.pager.base_tiles, 0);
    assert!(first.pager.base_bytes > 0, "reserved before it arrives");
    assert_eq!(first.pager.memory_bytes, first.pager.base_bytes);
    assert_eq!(first.pager.fetching, 0, "tiles wait for the base");
    assert!(first.holes > 0);
    let second = engine.render(&camera, &mut fb).unwrap();
    assert_eq!(second.pager.base_tiles, 64, "every tile of the 8 x 8 grid");
    assert!(second.pager.base_bytes <= first.pager.base_bytes);
    assert_eq!(second.holes, 0);
    assert!(second.rendered_tiles > 0);
    assert!(second.pager.fetching > 0, "then the tiles come");
}

/// A loader of fake whole tiles whose base fails a given number of times.
struct FailingBase {
    base_failures: AtomicU32,
    base_loads: AtomicU32,
    tiles: Mutex<Vec<TileId>>,
}

impl ResidentLoader for FailingBase {
    type Loaded = usize;

    fn loaded_bytes(&self, tile: &usize) -> usize {
        *tile
    }

    fn base_bytes(&self) -> usize {
        9 * 10
    }

    fn load_base(&self) -> stripmask::Result<(Vec<(TileId, usize)>, u64)> {
        self.base_loads.fetch_add(1, Ordering::Relaxed);
        let left = self.base_failures.load(Ordering::Relaxed);
        if left > 0 {
            self.base_failures.store(left - 1, Ordering::Relaxed);
            return Err(Error::invalid("fake base", "simulated failure"));
        }
        let tiles = (0..9).map(|k| (TileId::new(k % 3, k / 3), 10)).collect();
        Ok((tiles, 90))
    }
}

impl TileLoader for FailingBase {
    fn predicted_bytes(&self, _: TileId, _: u32) -> usize {
        100
    }

    fn load(&self, id: TileId, _: u32) -> stripmask::Result<(usize, u64)> {
        self.tiles.lock().unwrap().push(id);
        Ok((100, 100))
    }

    fn shrink(&self, tile: &mut usize, _: u32) -> usize {
        *tile
    }
}

fn failing_base_pager(failures: u32) -> BeltPager<FailingBase> {
    let mut config = PagerConfig::new(
        10_000,
        PagerMode::Stepped {
            fetches_per_update: 1,
        },
    );
    config.retry = RetryPolicy {
        max_attempts: 3,
        delay_updates: 2,
        ..RetryPolicy::default()
    };
    let loader = FailingBase {
        base_failures: AtomicU32::new(failures),
        base_loads: AtomicU32::new(0),
        tiles: Mutex::new(Vec::new()),
    };
    BeltPager::new(loader, Grid::new(3, 3).unwrap(), config).unwrap()
}

#[test]
fn a_failing_base_is_retried_and_tiles_page_meanwhile() {
    let mut p = failing_base_pager(1);
    p.update((1.5, 1.5));
    let stats = p.resident().stats();
    assert_eq!(stats.base_tiles, 0);
    assert_eq!(
        stats.base_bytes, 0,
        "a failed base gives its reservation back"
    );
    assert!(p.resident().last_error().unwrap().contains("will retry"));
    // Tiles no longer wait once the first attempt came back.
    p.update((1.5, 1.5));
    assert!(!p.loader().tiles.lock().unwrap().is_empty());
    for _ in 0..3 {
        p.update((1.5, 1.5));
    }
    let stats = p.resident().stats();
    assert_eq!(p.loader().base_loads.load(Ordering::Relaxed), 2);
    assert_eq!((stats.base_tiles, stats.base_bytes), (9, 90));
    let held: usize = p.resident().tiles().map(|(_, t)| *t).sum();
    assert_eq!(stats.memory_bytes, held + 90);
    assert!(p.resident().get(TileId::new(2, 2)).is_some());
}

#[test]
fn a_base_that_always_fails_is_given_up_after_the_retry_policy() {
    let mut p = failing_base_pager(u32::MAX);
    for _ in 0..20 {
        p.update((1.5, 1.5));
    }
    assert_eq!(p.loader().base_loads.load(Ordering::Relaxed), 3);
    assert!(p.resident().last_error().is_some());
    let stats = p.resident().stats();
    assert_eq!((stats.base_tiles, stats.base_bytes), (0, 0));
    assert_eq!(stats.loaded_tiles, 9, "the tiles paged regardless");
}
