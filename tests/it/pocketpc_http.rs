//! The PocketPC mirror over real HTTP: the engine flies over an archive that `serve`'s server
//! hands out on 127.0.0.1 through a throttled link (bandwidth, latency with jitter, drops).

use std::collections::BTreeSet;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use stripmask::Viewport;
use stripmask::db::archive::ArchiveReader;
use stripmask::db::server::Server;
use stripmask::db::source::TileSource;
use stripmask::db::source::http::HttpSource;
use stripmask::db::source::throttle::LinkProfile;
use stripmask::engine::paging::PagerMode;
use stripmask::engine::terrain::TerrainFrame;
use stripmask::engine::{Engine, EngineSettings, FrameTiming};
use stripmask::sim::flight::{Builtin, Flight};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

use crate::support::hills;

/// What the client saw of each request.
#[derive(Default)]
struct Log {
    /// Bytes and wall time of every successful read.
    reads: Vec<(u64, Duration)>,
    /// Failed reads (dropped by the server).
    failures: u32,
}

/// A source that times every read on the client side.
struct Timed<S> {
    inner: S,
    log: Arc<Mutex<Log>>,
}

impl<S: TileSource> TileSource for Timed<S> {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn size(&self) -> stripmask::Result<u64> {
        self.inner.size()
    }
    fn read_range(&self, offset: u64, len: u64) -> stripmask::Result<Vec<u8>> {
        let started = Instant::now();
        let result = self.inner.read_range(offset, len);
        let took = started.elapsed();
        let mut log = self.log.lock().unwrap();
        match &result {
            Ok(bytes) => log.reads.push((bytes.len() as u64, took)),
            Err(_) => log.failures += 1,
        }
        result
    }
}

#[test]
fn a_flight_over_a_throttled_lossy_http_link_loads_every_visited_tile_at_the_links_rate() {
    let dir = tempfile::tempdir().unwrap();
    // Hills in 4 x 4 tiles of 65: few requests, so that the time a request costs whatever its
    // size (latency, and a loaded machine's scheduling) stays small beside the bandwidth's.
    let path = hills::archive(dir.path(), 65);
    let archive_bytes = std::fs::metadata(&path).unwrap().len();
    let link = LinkProfile {
        bandwidth_kbps: Some(BANDWIDTH_KBPS),
        latency: Duration::from_millis(10),
        jitter: Duration::from_millis(5),
        drop_rate: 0.1,
        seed: 5,
    };
    let bytes_per_second = link.bytes_per_second().unwrap();
    // The archive takes over a second at this rate: unthrottled, loopback moves it in
    // milliseconds, so the rate bound below cannot be met by accident.
    assert!(archive_bytes as f64 / bytes_per_second > 1.0);
    let server = Server::start(&path, "127.0.0.1:0".parse().unwrap(), link).unwrap();
    let log = Arc::new(Mutex::new(Log::default()));
    let source = Timed {
        inner: HttpSource::new(server.url()),
        log: Arc::clone(&log),
    };
    let mut settings = EngineSettings {
        memory_limit_bytes: 20_000_000,
        pager_mode: PagerMode::Threaded { queue_depth: 4 },
        threads: 1,
        frame_timing: FrameTiming::Told,
        lift_to_clearance: true,
        ..EngineSettings::default()
    };
    settings.budget.target_fps = 7.0;
    let (w, h) = (160, 120);
    let mut engine = Engine::new(Box::new(source), settings, Viewport::new(w, h)).unwrap();
    let header = ArchiveReader::open(stripmask::db::source::open(path.to_str().unwrap()).unwrap())
        .unwrap()
        .header()
        .clone();
    let flight = Flight::builtin(Builtin::Diagonal, &TerrainFrame::new(&header));
    let mut fb = Framebuffer::new(w, h, ColorFormat::Rgb565, DepthFormat::D16).unwrap();

    // The flight takes 1.5 s of wall time, then the viewer hovers at its end until the pager is
    // done (with a deadline far beyond what the link needs, so a stall fails instead of hanging).
    let flight_wall = 1.5;
    let started = Instant::now();
    let deadline = Duration::from_secs(60);
    let mut visited = BTreeSet::new();
    let mut frames = 0;
    loop {
        let progress = started.elapsed().as_secs_f64() / flight_wall;
        let (eye, target) = flight.at(progress.min(1.0) * flight.duration());
        let camera = engine.camera(eye, target, flight.above_ground);
        let frame_started = Instant::now();
        let report = engine.render(&camera, &mut fb).unwrap();
        engine.record_frame(
            frame_started.elapsed().as_secs_f64(),
            report.draw.triangles as usize,
        );
        frames += 1;
        visited.extend(engine.pager().current_tile());
        let pager = engine.pager();
        let done = progress >= 1.0
            && pager.stats().fetching == 0
            && visited.iter().all(|&id| pager.get(id).is_some());
        if done {
            break;
        }
        assert!(
            started.elapsed() < deadline,
            "stalled: {:?}, last error {:?}",
            pager.stats(),
            pager.last_error()
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    let stats = engine.pager().stats();
    assert!(visited.len() >= 4, "{visited:?}");
    assert_eq!(stats.failed_tiles, 0, "{:?}", engine.pager().last_error());
    assert!(frames > 20);
    let log = log.lock().unwrap();
    assert!(
        log.failures > 0,
        "the link dropped requests (and they were retried)"
    );
    // Every read waited at least the latency less the jitter before its first byte, and the
    // rest of the reads' time moved the bytes no faster than the bandwidth.
    let min_delay = link.latency - link.jitter;
    assert!(log.reads.iter().all(|&(_, took)| took >= min_delay));
    let bytes: u64 = log.reads.iter().map(|&(b, _)| b).sum();
    let seconds: f64 = log
        .reads
        .iter()
        .map(|&(_, took)| (took - min_delay).as_secs_f64())
        .sum();
    assert!(bytes >= stats.downloaded_bytes);
    assert!(
        bytes as f64 / bytes_per_second > 0.5,
        "{bytes} bytes moved: too few for the bound to mean anything"
    );
    assert!(
        bytes as f64 / seconds <= bytes_per_second,
        "{bytes} bytes in {seconds:.3} s of reads beat the link's {bytes_per_second} bytes/s"
    );
}

/// Low enough that the archive takes over a second to cross the link (unthrottled, loopback
/// moves it in a fraction of that even on a loaded machine).
const BANDWIDTH_KBPS: f64 = 1600.0;
