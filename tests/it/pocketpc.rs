//! The PocketPC mirror: simulated-clock flights that repeat byte for byte, hold the target frame
//! rate, stay inside the memory limit, download a tile once per visit and survive a lossy link;
//! the report's plots; the demo.

use std::collections::BTreeMap;
use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use stripmask::Viewport;
use stripmask::db::archive::ArchiveReader;
use stripmask::db::grid::TileId;
use stripmask::db::source::CancelToken;
use stripmask::db::source::throttle::LinkProfile;
use stripmask::db::source::{self, TileSource};
use stripmask::engine::paging::PagerMode;
use stripmask::engine::terrain::TerrainFrame;
use stripmask::engine::{Engine, EngineSettings, FrameTiming};
use stripmask::sim::clock::{Clock, CostModel, MeteredLink};
use stripmask::sim::demo::{DemoOptions, run, run_live};
use stripmask::sim::device::DeviceProfile;
use stripmask::sim::flight::{Builtin, Flight};
use stripmask::sim::fly::{FlyOptions, FlySummary, Length, LiveView, fly};
use stripmask::sim::report::{PLOT_FILES, PLOT_SIZE, StatsTable, draw};
use stripmask::sim::stats::{FrameRecord, StatsCsv};
use stripmask_platform::{Input, Overlay, PlatformError, Presenter};
use stripmask_raster::Framebuffer;

use crate::support::hills;
use hills::archive;

fn simulated(p: &DeviceProfile) -> Clock {
    Clock::Simulated {
        model: CostModel::HOST,
        slowdown: p.cpu_slowdown,
    }
}

fn engine_settings(p: &DeviceProfile) -> EngineSettings {
    let mut engine = EngineSettings {
        memory_limit_bytes: p.memory_limit_bytes(),
        threads: p.threads,
        frame_timing: FrameTiming::Told,
        lift_to_clearance: true,
        ..EngineSettings::default()
    };
    engine.budget.target_fps = p.target_fps;
    engine
}

/// Flies the diagonal over `archive` as `p` on the simulated clock for `frames` frames.
fn fly_as(p: &DeviceProfile, archive: &Path, out: &Path, frames: u64) -> FlySummary {
    let reader = ArchiveReader::open(source::open(archive.to_str().unwrap()).unwrap()).unwrap();
    let terrain = TerrainFrame::new(reader.header());
    fly(&FlyOptions {
        source: archive.display().to_string(),
        flight: Flight::builtin(Builtin::Diagonal, &terrain),
        length: Some(Length::Frames(frames)),
        size: (p.width, p.height),
        color: p.color,
        depth: p.depth,
        engine: engine_settings(p),
        out: out.to_path_buf(),
        every: 0,
        hud: false,
        progress: false,
        clock: simulated(p),
        link: Some(LinkProfile { seed: 7, ..p.link }),
        plots: false,
        http: stripmask::db::source::http::HttpOptions::default(),
    })
    .unwrap()
}

#[test]
fn the_simulated_clock_gives_the_same_stats_csv_twice() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    let p = DeviceProfile::pocketpc();
    let (a, b) = (dir.path().join("a"), dir.path().join("b"));
    let first = fly_as(&p, &path, &a, 60);
    let second = fly_as(&p, &path, &b, 60);
    let csv = |d: &Path| std::fs::read(d.join("stats.csv")).unwrap();
    assert_eq!(csv(&a), csv(&b));
    assert_eq!(first.repeatable(), second.repeatable());
    assert!(first.downloaded_bytes > 0 && first.seconds > 1.0);
    // No tile can be drawn before the first transfer's latency has passed on the simulated link.
    assert!(first.holes.first_frame_s.unwrap() >= p.link.latency.as_secs_f64());
}

#[test]
fn a_jittery_simulated_link_repeats_byte_for_byte_and_changes_the_arrivals() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    let steady = DeviceProfile::pocketpc();
    let mut jittery = steady.clone();
    jittery.link.jitter = Duration::from_millis(40);
    let run = |p: &DeviceProfile, name: &str| {
        let out = dir.path().join(name);
        let summary = fly_as(p, &path, &out, 60);
        (summary, std::fs::read(out.join("stats.csv")).unwrap())
    };
    let (a, csv_a) = run(&jittery, "a");
    let (b, csv_b) = run(&jittery, "b");
    let (c, csv_c) = run(&steady, "c");
    assert_eq!((a.repeatable(), &csv_a), (b.repeatable(), &csv_b));
    assert_ne!(csv_a, csv_c, "jitter moves the arrivals");
    assert!(c.downloaded_bytes > 0);
    let earliest = (jittery.link.latency - jittery.link.jitter).as_secs_f64();
    assert!(a.holes.first_frame_s.unwrap() >= earliest);
}

#[test]
fn a_simulated_pocketpc_flight_holds_its_target_fps_within_40_frames_and_its_memory_limit() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    // A limit the hills' 64 tiles do not fit in, so that the pager must choose.
    let p = DeviceProfile {
        memory_mb: 1.0,
        ..DeviceProfile::pocketpc()
    };
    let out = dir.path().join("run");
    let summary = fly_as(&p, &path, &out, 200);
    let table = StatsTable::read(&out.join("stats.csv")).unwrap();
    let fps = table.column("fps").unwrap();
    // Within 12%: with a few tiles on screen, the power-of-two masks of tiles meeting a tile of
    // another pyramid level make the triangles a frame can hold a coarse scale.
    let settled = (0..fps.len())
        .find(|&k| {
            fps[k..]
                .iter()
                .all(|f| (f / p.target_fps - 1.0).abs() <= 0.12)
        })
        .unwrap();
    assert!(
        settled <= 40,
        "fps settles within 12% of the target only from frame {settled}"
    );
    let memory = table.column("memory_bytes").unwrap();
    let limit = p.memory_limit_bytes() as f64;
    assert!(memory.iter().all(|&m| m <= limit));
    assert!(summary.peak_memory_bytes <= p.memory_limit_bytes());
    assert!(
        summary.peak_memory_bytes as f64 > 0.8 * limit,
        "the limit binds"
    );
}

/// A source that counts successful reads per byte offset and failed reads.
struct Counting<S> {
    inner: S,
    reads: Arc<Mutex<BTreeMap<u64, u32>>>,
    failures: Arc<Mutex<u32>>,
}

impl<S: TileSource> TileSource for Counting<S> {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn size(&self) -> stripmask::Result<u64> {
        self.inner.size()
    }
    fn read_range(&self, offset: u64, len: u64) -> stripmask::Result<Vec<u8>> {
        let result = self.inner.read_range(offset, len);
        match &result {
            Ok(_) => *self.reads.lock().unwrap().entry(offset).or_default() += 1,
            Err(_) => *self.failures.lock().unwrap() += 1,
        }
        result
    }
}

/// An engine on the simulated clock behind a metered link with `drop_rate`, and its counters.
struct Rig {
    engine: Engine,
    clock: Clock,
    flight: Flight,
    tile_at: BTreeMap<u64, TileId>,
    reads: Arc<Mutex<BTreeMap<u64, u32>>>,
    failures: Arc<Mutex<u32>>,
    fb: Framebuffer,
    t: f64,
}

impl Rig {
    fn new(path: &Path, p: &DeviceProfile, drop_rate: f64) -> Rig {
        let name = path.to_str().unwrap();
        let reader = ArchiveReader::open(source::open(name).unwrap()).unwrap();
        let h = reader.header().clone();
        let pyramid = reader.pyramid().clone();
        let tile_at = (0..pyramid.levels() as u8)
            .flat_map(|k| {
                let grid = pyramid.grid(k);
                (0..grid.tiles_y())
                    .flat_map(move |y| (0..grid.tiles_x()).map(move |x| TileId::at(k, x, y)))
            })
            .map(|id| {
                let (e, _) = reader.entry(id, &CancelToken::new()).unwrap();
                (e.offset, id)
            })
            .collect();
        let link = LinkProfile {
            drop_rate,
            seed: 3,
            ..p.link
        };
        let (metered, meter) = MeteredLink::new(source::open(name).unwrap(), link);
        let reads = Arc::default();
        let failures = Arc::default();
        let counting = Counting {
            inner: metered,
            reads: Arc::clone(&reads),
            failures: Arc::clone(&failures),
        };
        let settings = EngineSettings {
            pager_mode: PagerMode::Simulated { queue_depth: 4 },
            ..engine_settings(p)
        };
        let mut engine = Engine::new(
            Box::new(counting),
            settings,
            Viewport::new(p.width, p.height),
        )
        .unwrap();
        engine.set_transfer_clock(meter);
        Rig {
            flight: Flight::builtin(Builtin::Diagonal, &TerrainFrame::new(&h)),
            engine,
            clock: simulated(p),
            tile_at,
            reads,
            failures,
            fb: Framebuffer::new(p.width, p.height, p.color, p.depth).unwrap(),
            t: 0.0,
        }
    }

    /// One frame at flight time `at` (clamped to the flight); returns the tiles read during it.
    fn frame(&mut self, at: f64) -> BTreeMap<TileId, u32> {
        let before = self.reads.lock().unwrap().clone();
        let (eye, target) = self.flight.at(at);
        let camera = self.engine.camera(eye, target, self.flight.above_ground);
        self.engine.set_time(self.t);
        let report = self.engine.render(&camera, &mut self.fb).unwrap();
        let seconds = self.clock.frame_seconds(&report);
        self.engine
            .record_frame(seconds, report.draw.triangles as usize);
        self.t += seconds;
        let after = self.reads.lock().unwrap().clone();
        after
            .iter()
            .filter_map(|(offset, n)| {
                let id = *self.tile_at.get(offset)?;
                let new = n - before.get(offset).copied().unwrap_or(0);
                (new > 0).then_some((id, new))
            })
            .collect()
    }

    fn all_tiles(&self) -> impl Iterator<Item = TileId> + '_ {
        self.tile_at.values().copied()
    }
}

#[test]
fn a_simulated_flight_downloads_each_tile_at_most_once_per_visit() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    let p = DeviceProfile {
        memory_mb: 1.0,
        ..DeviceProfile::pocketpc()
    };
    let mut rig = Rig::new(&path, &p, 0.0);
    let mut downloads = 0;
    let mut refetches = 0;
    while rig.t < rig.flight.duration() {
        let ledger_before: Vec<_> = rig
            .all_tiles()
            .map(|id| (id, rig.engine.pager().ledger().record(id)))
            .collect();
        let read = rig.frame(rig.t);
        for (id, before) in ledger_before {
            let Some(&n) = read.get(&id) else { continue };
            assert_eq!(n, 1, "{id} was read {n} times in one frame");
            downloads += 1;
            assert!(before.fetch.is_none(), "{id} was fetched while in flight");
            let after = rig.engine.pager().ledger().record(id);
            let ring = after.fetch.map(|f| f.ring).or(after.loaded.map(|h| h.ring));
            if let (Some(held), Some(now)) = (before.loaded, ring) {
                // Downloaded again while held: only to upgrade to a nearer belt's detail.
                assert!(now < held.ring, "{id} re-downloaded for ring {now}");
                refetches += 1;
            }
        }
    }
    assert!(downloads > 20, "{downloads} downloads");
    assert!(
        refetches < downloads,
        "{refetches} of {downloads} were upgrades"
    );
}

#[test]
fn a_flight_over_a_link_dropping_10_percent_completes_with_every_visited_tile_loaded() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    let p = DeviceProfile::pocketpc();
    let mut rig = Rig::new(&path, &p, 0.1);
    let mut visited = std::collections::BTreeSet::new();
    while rig.t < rig.flight.duration() {
        rig.frame(rig.t);
        visited.extend(rig.engine.pager().current_tile());
    }
    // Hover at the end until the pager is done.
    let end = rig.flight.duration();
    for _ in 0..200 {
        rig.frame(end);
    }
    assert!(
        *rig.failures.lock().unwrap() > 0,
        "the link dropped requests"
    );
    let pager = rig.engine.pager();
    let stats = pager.stats();
    assert_eq!(stats.failed_tiles, 0, "{:?}", pager.last_error());
    assert_eq!(stats.fetching, 0);
    // 20 MB holds the whole 8 x 8 archive: every tile of the flight's belts ends up loaded.
    for id in rig.all_tiles() {
        assert!(pager.get(id).is_some(), "{id} is not loaded");
    }
    assert!(visited.len() > 4);
}

fn write_stats(dir: &Path, frames: u64, triangles: impl Fn(u64) -> u64) {
    let mut csv = StatsCsv::create(&dir.join("stats.csv")).unwrap();
    for frame in 0..frames {
        csv.write(&FrameRecord {
            frame,
            time_s: frame as f64 / 7.0,
            frame_ms: 140.0,
            fps: 7.1,
            target_fps: 7.0,
            budget: 3000,
            triangles: triangles(frame),
            rendered_tiles: 10,
            loaded_tiles: 20 + frame / 4,
            memory_bytes: 1_000_000 + 10_000 * frame,
            memory_limit_bytes: 2_000_000,
            downloads: frame / 3,
            ..FrameRecord::default()
        })
        .unwrap();
    }
    csv.finish().unwrap();
}

#[test]
fn report_plots_are_pngs_of_the_stated_size_that_follow_the_data() {
    let dir = tempfile::tempdir().unwrap();
    write_stats(dir.path(), 70, |f| 2900 + f);
    let paths = draw(dir.path()).unwrap();
    assert_eq!(paths.len(), PLOT_FILES.len());
    let first: Vec<Vec<u8>> = paths.iter().map(|p| std::fs::read(p).unwrap()).collect();
    for (path, bytes) in paths.iter().zip(&first) {
        let image = image::load_from_memory_with_format(bytes, image::ImageFormat::Png)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        assert_eq!((image.width(), image.height()), PLOT_SIZE);
    }
    write_stats(dir.path(), 70, |f| 2900 + 20 * (f % 5));
    assert_eq!(draw(dir.path()).unwrap(), paths);
    let second: Vec<Vec<u8>> = paths.iter().map(|p| std::fs::read(p).unwrap()).collect();
    let changed: Vec<&str> = PLOT_FILES
        .iter()
        .zip(first.iter().zip(&second))
        .filter(|(_, (a, b))| a != b)
        .map(|(name, _)| *name)
        .collect();
    assert_eq!(changed, ["triangles.png"]);
    std::fs::write(dir.path().join("stats.csv"), "frame,fps\n0,7\n").unwrap();
    let e = draw(dir.path()).unwrap_err().to_string();
    assert!(e.contains("stats.csv") && e.contains("time_s"), "{e}");
}

/// A screen that counts what it is shown and asks to quit after `quit_after` polls.
struct Screen {
    shown: u64,
    with_hud: u64,
    polls: u64,
    quit_after: u64,
}

impl Screen {
    fn new(quit_after: u64) -> Self {
        Screen {
            shown: 0,
            with_hud: 0,
            polls: 0,
            quit_after,
        }
    }
}

impl Presenter for Screen {
    fn present(&mut self, _: &Framebuffer, hud: Option<&Overlay>) -> Result<(), PlatformError> {
        self.shown += 1;
        self.with_hud += u64::from(hud.is_some());
        Ok(())
    }

    fn poll_input(&mut self) -> Input {
        self.polls += 1;
        Input {
            quit: self.polls > self.quit_after,
            ..Input::default()
        }
    }
}

#[test]
fn the_live_demo_shows_every_frame_writes_the_same_outputs_and_stops_on_quit() {
    let dir = tempfile::tempdir().unwrap();
    let options = DemoOptions {
        out: dir.path().join("demo"),
        length: Some(Length::Frames(12)),
        every: 4,
        progress: false,
        ..DemoOptions::default()
    };
    let stats = || std::fs::read_to_string(options.out.join("stats.csv")).unwrap();
    let headless = run(&options).unwrap();
    let csv = stats();
    let mut screen = Screen::new(u64::MAX);
    let live = LiveView {
        presenter: &mut screen,
        real_time: false,
    };
    let shown = run_live(&options, Some(live)).unwrap();
    assert_eq!((screen.shown, screen.with_hud), (12, 12));
    assert_eq!(shown.fly.repeatable(), headless.fly.repeatable());
    assert_eq!(stats(), csv, "showing the flight changes nothing in it");
    // Quitting after five frames: the flight stops there, and what was flown is written.
    let mut screen = Screen::new(5);
    let live = LiveView {
        presenter: &mut screen,
        real_time: false,
    };
    let cut = run_live(&options, Some(live)).unwrap();
    assert_eq!((cut.fly.frames, screen.shown), (5, 5));
    assert_eq!(stats().lines().count(), 1 + 5);
    for file in PLOT_FILES {
        assert!(options.out.join(file).is_file(), "{file}");
    }
}

#[test]
fn the_demo_builds_flies_and_reuses_its_archive() {
    let dir = tempfile::tempdir().unwrap();
    let options = DemoOptions {
        out: dir.path().join("demo"),
        length: Some(Length::Frames(30)),
        every: 10,
        progress: false,
        ..DemoOptions::default()
    };
    let first = run(&options).unwrap();
    let model = first.built_from.as_deref().unwrap();
    assert!(model.contains("built in"), "{model}");
    for file in PLOT_FILES.iter().chain(&["stats.csv", "puget.smdb"]) {
        assert!(options.out.join(file).is_file(), "{file}");
    }
    assert_eq!(
        std::fs::read_dir(options.out.join("frames"))
            .unwrap()
            .count(),
        3
    );
    let text = first.to_string();
    assert!(
        text.contains("pocketpc") && text.contains("first frame"),
        "{text}"
    );
    let csv = std::fs::read(options.out.join("stats.csv")).unwrap();
    let second = run(&options).unwrap();
    assert_eq!(second.built_from, None);
    assert_eq!(std::fs::read(options.out.join("stats.csv")).unwrap(), csv);
    assert_eq!(first.fly.repeatable(), second.fly.repeatable());
}
