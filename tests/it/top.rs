//! The top of the pyramid: the root and the levels stored with it, fetched first and resident
//! for good, so that no view of the terrain has a hole once it arrived — with whole-tile belts
//! that reach only a few tiles, and with progressive streaming; accounted under the limit before
//! it is fetched; tile fetches wait for it; a failing top is retried, then given up, while tiles
//! page on.

use std::sync::Mutex;
use std::sync::atomic::{AtomicU32, Ordering};

use stripmask::Error;
use stripmask::Viewport;
use stripmask::db::archive::ArchiveReader;
use stripmask::db::grid::{Pyramid, TileId};
use stripmask::db::source;
use stripmask::engine::paging::stream::{StreamSettings, Streaming};
use stripmask::engine::paging::{
    BeltPager, PagerConfig, PagerMode, ResidentLoader, RetryPolicy, TileLoader,
};
use stripmask::engine::{Engine, EngineSettings, FrameTiming};
use stripmask::sim::flight::{Builtin, Flight};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

use crate::support::hills;

/// Frames of the diagonal flight over the 16 x 16-tile hills archive with room for the top and
/// a 5 x 5 square of whole tiles: (frames drawn after the top arrived with a hole, frames
/// before with a hole, frames with the top, frames).
fn holes_on_the_diagonal(streaming: Streaming, keep_top: bool) -> [usize; 4] {
    let dir = tempfile::tempdir().unwrap();
    let path = hills::archive(dir.path(), 17);
    let settings = EngineSettings {
        memory_limit_bytes: 400_000,
        pager_mode: PagerMode::Stepped {
            fetches_per_update: 2,
        },
        threads: 1,
        streaming,
        keep_top,
        frame_timing: FrameTiming::Told,
        lift_to_clearance: true,
        ..EngineSettings::default()
    };
    let source = source::open(path.to_str().unwrap()).unwrap();
    let mut engine = Engine::new(source, settings, Viewport::new(160, 120)).unwrap();
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
        let top = stats.top_tiles > 0;
        based += usize::from(top);
        if report.holes > 0 {
            if top {
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
fn with_whole_tile_belts_no_frame_has_a_hole_once_the_top_arrived() {
    let [after, before, based, frames] = holes_on_the_diagonal(Streaming::Belts, true);
    assert_eq!(
        based, frames,
        "stepped: the top arrives with the first update"
    );
    assert_eq!(after + before, 0, "frames with holes, of {frames}");
    // Without the top the belts reach only part of the view.
    let [_, without, based, frames] = holes_on_the_diagonal(Streaming::Belts, false);
    assert_eq!(based, 0);
    assert!(
        without > 0,
        "{without} of {frames} frames have holes without the top"
    );
}

#[test]
fn with_progressive_streaming_no_frame_has_a_hole_once_the_top_arrived() {
    let progressive = Streaming::Progressive(StreamSettings::default());
    let [after, before, based, frames] = holes_on_the_diagonal(progressive, true);
    assert_eq!(
        based, frames,
        "stepped: the top arrives with the first update"
    );
    assert_eq!(after + before, 0, "frames with holes, of {frames}");
}

#[test]
fn the_top_is_reserved_before_it_is_fetched_and_tiles_wait_for_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = hills::archive(dir.path(), 33);
    let settings = EngineSettings {
        memory_limit_bytes: 4 << 20,
        pager_mode: PagerMode::Simulated { queue_depth: 4 },
        threads: 1,
        frame_timing: FrameTiming::Told,
        lift_to_clearance: true,
        ..EngineSettings::default()
    };
    let stored = ArchiveReader::open(source::open(path.to_str().unwrap()).unwrap())
        .unwrap()
        .directory()
        .top
        .len();
    let source = source::open(path.to_str().unwrap()).unwrap();
    let mut engine = Engine::new(source, settings, Viewport::new(160, 120)).unwrap();
    let mut fb = Framebuffer::new(160, 120, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
    let flight = Flight::builtin(Builtin::Overview, engine.terrain());
    let (eye, target) = flight.at(0.0);
    let camera = engine.camera(eye, target, true);
    // Update 1 sends the top; without a transfer clock it arrives at the next update.
    let first = engine.render(&camera, &mut fb).unwrap();
    assert_eq!(first.pager.top_tiles, 0);
    assert!(first.pager.top_bytes > 0, "reserved before it arrives");
    assert_eq!(
        first.pager.memory_bytes,
        first.pager.top_bytes + first.pager.index_bytes
    );
    assert_eq!(first.pager.fetching, 0, "tiles wait for the top");
    assert!(first.holes > 0);
    let second = engine.render(&camera, &mut fb).unwrap();
    assert_eq!(
        second.pager.top_tiles, stored,
        "every tile of the archive's top"
    );
    assert!(second.pager.top_bytes <= first.pager.top_bytes);
    assert_eq!(second.holes, 0);
    assert!(second.rendered_tiles > 0);
    assert!(second.pager.fetching > 0, "then the tiles come");
}

/// A loader of fake whole tiles whose top (the root and the 2 x 2 tiles below it of a 3 x 3
/// grid) fails a given number of times.
struct FailingTop {
    top_failures: AtomicU32,
    top_loads: AtomicU32,
    tiles: Mutex<Vec<TileId>>,
}

impl ResidentLoader for FailingTop {
    type Loaded = usize;

    fn loaded_bytes(&self, tile: &usize) -> usize {
        *tile
    }

    fn top_bytes(&self) -> usize {
        5 * 10
    }

    fn load_top(&self) -> stripmask::Result<(Vec<(TileId, usize)>, u64)> {
        self.top_loads.fetch_add(1, Ordering::Relaxed);
        let left = self.top_failures.load(Ordering::Relaxed);
        if left > 0 {
            self.top_failures.store(left - 1, Ordering::Relaxed);
            return Err(Error::invalid("fake top", "simulated failure"));
        }
        let mut tiles = vec![(TileId::at(2, 0, 0), 10)];
        tiles.extend((0..4).map(|k| (TileId::at(1, k % 2, k / 2), 10)));
        Ok((tiles, 50))
    }
}

impl TileLoader for FailingTop {
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

fn failing_top_pager(failures: u32) -> BeltPager<FailingTop> {
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
    let loader = FailingTop {
        top_failures: AtomicU32::new(failures),
        top_loads: AtomicU32::new(0),
        tiles: Mutex::new(Vec::new()),
    };
    BeltPager::new(loader, Pyramid::new(3, 3).unwrap(), config).unwrap()
}

#[test]
fn a_failing_top_is_retried_and_tiles_page_meanwhile() {
    let mut p = failing_top_pager(1);
    p.update((1.5, 1.5));
    let stats = p.resident().stats();
    assert_eq!(stats.top_tiles, 0);
    assert_eq!(
        stats.top_bytes, 0,
        "a failed top gives its reservation back"
    );
    assert!(p.resident().last_error().unwrap().contains("will retry"));
    // Tiles no longer wait once the first attempt came back.
    p.update((1.5, 1.5));
    assert!(!p.loader().tiles.lock().unwrap().is_empty());
    for _ in 0..3 {
        p.update((1.5, 1.5));
    }
    let stats = p.resident().stats();
    assert_eq!(p.loader().top_loads.load(Ordering::Relaxed), 2);
    assert_eq!((stats.top_tiles, stats.top_bytes), (5, 50));
    let held: usize = p.resident().tiles().map(|(_, t)| *t).sum();
    assert_eq!(stats.memory_bytes, held + 50);
    assert!(p.resident().get(TileId::at(1, 1, 1)).is_some());
    // The root covers every resident tile below it.
    assert_eq!(
        p.resident().covered(TileId::at(2, 0, 0)) as usize,
        4 + stats.loaded_tiles
    );
}

#[test]
fn a_top_that_always_fails_is_given_up_after_the_retry_policy() {
    let mut p = failing_top_pager(u32::MAX);
    for _ in 0..20 {
        p.update((1.5, 1.5));
    }
    assert_eq!(p.loader().top_loads.load(Ordering::Relaxed), 3);
    assert!(p.resident().last_error().is_some());
    let stats = p.resident().stats();
    assert_eq!((stats.top_tiles, stats.top_bytes), (0, 0));
    assert_eq!(stats.loaded_tiles, 9, "the tiles paged regardless");
}
