//! A server that accepts and never answers, or stops in the middle of a body, costs one request
//! timeout or the run's deadline, never minutes: `fly --seconds 3` ends on time and says what
//! failed, opening an archive fails within the request timeout, and a failed tile is fetched
//! again only by the pager's retries (with back-off), not by the pager's times the reader's.

use std::io::{BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use stripmask::Viewport;
use stripmask::db::archive::ArchiveReader;
use stripmask::db::source::TileSource;
use stripmask::db::source::file::FileSource;
use stripmask::engine::paging::{PagerMode, RetryPolicy};
use stripmask::engine::terrain::TerrainFrame;
use stripmask::engine::{Engine, EngineSettings, FrameTiming};
use stripmask::sim::flight::{Builtin, Flight};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

use crate::support::cli::{fly_quietly, plain_archive, run_timed};
use crate::support::fake_http::next_range;

/// How a fake server misbehaves.
#[derive(Clone, Copy)]
enum Hang {
    /// Accepts connections and never reads or answers.
    Silent,
    /// Answers HEAD and the ranges below `whole_below` whole; of any other range it sends the
    /// head and half the body, then nothing more.
    MidBody { whole_below: u64 },
}

/// A loopback server over `archive` that hangs as `hang` says; returns its URL. Its connections
/// are kept open (never answered further) for the life of the test process.
fn hung_server(archive: &Path, hang: Hang) -> String {
    let bytes = Arc::new(std::fs::read(archive).unwrap());
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("http://{}/a.smdb", listener.local_addr().unwrap());
    let held = Arc::new(Mutex::new(Vec::new()));
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            match hang {
                Hang::Silent => held.lock().unwrap().push(stream),
                Hang::MidBody { whole_below } => {
                    let (bytes, held) = (Arc::clone(&bytes), Arc::clone(&held));
                    std::thread::spawn(move || answer(stream, &bytes, whole_below, &held));
                }
            }
        }
    });
    url
}

/// Answers requests on `stream` until one is cut in the middle of its body.
fn answer(stream: TcpStream, bytes: &[u8], whole_below: u64, held: &Mutex<Vec<TcpStream>>) {
    let mut writer = stream.try_clone().unwrap();
    let mut reader = BufReader::new(stream);
    while let Some((a, b)) = next_range(&mut reader, &mut writer, bytes.len()) {
        let body = &bytes[a..=b];
        if (b as u64) < whole_below {
            writer.write_all(body).unwrap();
        } else {
            writer.write_all(&body[..body.len() / 2]).unwrap();
            held.lock().unwrap().push(writer);
            return;
        }
    }
}

/// `fly URL --seconds 3` (and `extra`) into `out`.
fn fly_3s(url: &str, out: &Path, extra: &[&str]) -> (Option<i32>, String, Duration) {
    let mut args = vec!["--seconds", "3"];
    args.extend(extra);
    fly_quietly(url, out, &args)
}

/// The bound on a three-second flight against a hung server: a generous margin over 3 s plus
/// the grace of the deadline, far below the minutes of a timeout per retry.
const BOUND: Duration = Duration::from_secs(15);

/// Bytes of the archive's header and index.
fn payload_start(archive: &Path) -> u64 {
    let reader = ArchiveReader::open(FileSource::open(archive).unwrap()).unwrap();
    reader.header().payload_start()
}

#[test]
fn a_flight_against_a_server_that_never_answers_ends_on_time_and_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let archive = dir.path().join("a.smdb");
    plain_archive(&archive);
    let url = hung_server(&archive, Hang::Silent);
    let (code, err, took) = fly_3s(&url, &dir.path().join("out"), &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(took < BOUND, "took {took:?}: {err}");
    assert!(
        err.contains(&url) && err.contains("no whole answer") && err.contains("deadline"),
        "{err}"
    );
}

#[test]
fn a_flight_against_a_server_that_hangs_mid_body_ends_on_time_and_says_what_failed() {
    let dir = tempfile::tempdir().unwrap();
    let archive = dir.path().join("a.smdb");
    plain_archive(&archive);
    let url = hung_server(
        &archive,
        Hang::MidBody {
            whole_below: payload_start(&archive),
        },
    );
    let (code, err, took) = fly_3s(&url, &dir.path().join("out"), &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(took < BOUND, "took {took:?}: {err}");
    assert!(
        err.contains(&url)
            && err.contains("no terrain could be drawn")
            && err.contains("still on their way"),
        "{err}"
    );
    // On the simulated clock the fetches run on the flight's own thread: the deadline given
    // cuts the hung ones, and every later one fails at once.
    let (code, err, took) = fly_3s(
        &url,
        &dir.path().join("simulated"),
        &["--clock", "simulated", "--deadline", "3"],
    );
    assert_eq!(code, Some(1), "{err}");
    assert!(took < BOUND, "took {took:?}: {err}");
    assert!(
        err.contains("no terrain could be drawn") && err.contains("deadline"),
        "{err}"
    );
}

#[test]
fn opening_an_archive_on_a_server_that_never_answers_fails_within_the_request_timeout() {
    let dir = tempfile::tempdir().unwrap();
    let archive = dir.path().join("a.smdb");
    plain_archive(&archive);
    for hang in [
        Hang::Silent,
        Hang::MidBody {
            whole_below: stripmask::db::archive::HEADER_LEN as u64 - 1,
        },
    ] {
        let url = hung_server(&archive, hang);
        let (code, err, took) = run_timed(&["info", &url], Duration::from_secs(60));
        assert_eq!(code, Some(1), "{err}");
        // One request timeout (10 s), not one per retry.
        assert!(took < BOUND, "took {took:?}: {err}");
        assert!(
            err.contains(&url) && err.contains("the request timeout"),
            "{err}"
        );
    }
}

/// A file source whose tile reads (past the header and index) all fail, counting each.
struct FailingTiles {
    inner: FileSource,
    payload_start: u64,
    reads: Arc<AtomicUsize>,
}

impl TileSource for FailingTiles {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn size(&self) -> stripmask::Result<u64> {
        self.inner.size()
    }
    fn read_range(&self, offset: u64, len: u64) -> stripmask::Result<Vec<u8>> {
        if offset < self.payload_start {
            return self.inner.read_range(offset, len);
        }
        self.reads.fetch_add(1, Ordering::SeqCst);
        Err(stripmask::Error::invalid(self.name(), "connection reset"))
    }
}

#[test]
fn a_failing_fetch_is_tried_as_often_as_the_pager_says_not_times_the_readers_attempts() {
    let dir = tempfile::tempdir().unwrap();
    let archive = dir.path().join("a.smdb");
    plain_archive(&archive);
    let reads = Arc::new(AtomicUsize::new(0));
    let source = FailingTiles {
        inner: FileSource::open(&archive).unwrap(),
        payload_start: payload_start(&archive),
        reads: Arc::clone(&reads),
    };
    let settings = EngineSettings {
        memory_limit_bytes: 20_000_000,
        pager_mode: PagerMode::Stepped {
            fetches_per_update: 16,
        },
        threads: 1,
        frame_timing: FrameTiming::Told,
        ..EngineSettings::default()
    };
    let mut engine = Engine::new(Box::new(source), settings, Viewport::new(80, 60)).unwrap();
    let header = ArchiveReader::open(FileSource::open(&archive).unwrap())
        .unwrap()
        .header()
        .clone();
    let flight = Flight::builtin(Builtin::Overview, &TerrainFrame::new(&header));
    let (eye, target) = flight.at(0.0);
    let mut fb = Framebuffer::new(80, 60, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
    let retry = RetryPolicy::default();
    // Long enough for every wait of the policy to pass.
    let updates = 4 * retry.max_delay_updates;
    for _ in 0..updates {
        let camera = engine.camera(eye, target, flight.above_ground);
        engine.render(&camera, &mut fb).unwrap();
    }
    let stats = engine.pager().stats();
    let fetched = (header.pyramid().tile_count() as usize + 1) * retry.max_attempts as usize;
    assert!(stats.errors > 0);
    assert!(
        reads.load(Ordering::SeqCst) <= fetched,
        "{} reads for {} tiles and the top, {} attempts each",
        reads.load(Ordering::SeqCst),
        header.pyramid().tile_count(),
        retry.max_attempts
    );
    assert_eq!(stats.top_tiles, 0);
}
