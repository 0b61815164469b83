//! The fetch thread cancels what the stream pager gives up: a large HTTP range under way stops
//! and its connection closes (the server sees the client hang up long before the range's end),
//! the abandoned levels are neither stored nor drawn, the request counts as cancelled, and the
//! tile can be asked for again at once.

use std::io::{BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use stripmask::db::archive::ArchiveReader;
use stripmask::db::builder::BuildOptions;
use stripmask::db::grid::{Pyramid, TileId};
use stripmask::db::source::http::FINISH_BELOW;
use stripmask::db::source::{self, CancelToken, TileSource};
use stripmask::engine::cracks::CrackMode;
use stripmask::engine::paging::stream::{HOLD_SECONDS, StreamPager, StreamSettings, Want};
use stripmask::engine::paging::{ArchiveLoader, PagerConfig, PagerMode};
use stripmask::engine::shading::Light;
use stripmask::error::Error;

use crate::support::fake_http::next_range;
use crate::support::hills::synthetic;

/// One tile of 257 samples of rough relief: its finer levels are ranges of many kilobytes.
fn one_large_tile(dir: &Path) -> PathBuf {
    let n = 257;
    let options = BuildOptions {
        tile_size: 257,
        spacing: Some(10.0),
        ..BuildOptions::default()
    };
    synthetic(dir, "rough", (n, n), &options, |i, j| {
        let noise = (((j * n + i) as u32).wrapping_mul(2_654_435_761) >> 20) as f32;
        let (i, j) = (i as f32, j as f32);
        300.0 + 80.0 * (i * 0.05).sin() * (j * 0.07).cos() + noise * 0.05
    })
}

/// What the server did with one range it sent slowly.
#[derive(Clone, Copy, Debug, Default)]
struct SlowRange {
    len: u64,
    written: u64,
    /// The client closed the connection before the range's end.
    hung_up: bool,
    /// The connection's thread is done with it.
    ended: bool,
}

/// A loopback server over `archive` that answers HEAD and ranges up to `FINISH_BELOW` bytes at
/// once and, while `slow` is set, larger ranges a kilobyte every 25 ms (40 kB/s), recording
/// each of those in `slow_ranges`. Returns its URL.
fn slow_server(
    archive: &Path,
    slow: Arc<AtomicBool>,
    slow_ranges: Arc<Mutex<Vec<SlowRange>>>,
) -> String {
    let bytes = Arc::new(std::fs::read(archive).unwrap());
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("http://{}/rough.smdb", listener.local_addr().unwrap());
    std::thread::spawn(move || {
        for stream in listener.incoming().flatten() {
            let (bytes, slow, ranges) = (
                Arc::clone(&bytes),
                Arc::clone(&slow),
                Arc::clone(&slow_ranges),
            );
            std::thread::spawn(move || answer(stream, &bytes, &slow, &ranges));
        }
    });
    url
}

/// Answers requests on `stream` until the client closes it.
fn answer(stream: TcpStream, bytes: &[u8], slow: &AtomicBool, ranges: &Mutex<Vec<SlowRange>>) {
    let mut writer = stream.try_clone().unwrap();
    let mut reader = BufReader::new(stream);
    while let Some((a, b)) = next_range(&mut reader, &mut writer, bytes.len()) {
        let body = &bytes[a..=b];
        if body.len() as u64 <= FINISH_BELOW || !slow.load(Ordering::Relaxed) {
            if writer.write_all(body).is_err() {
                return;
            }
            continue;
        }
        let k = {
            let mut ranges = ranges.lock().unwrap();
            ranges.push(SlowRange {
                len: body.len() as u64,
                ..SlowRange::default()
            });
            ranges.len() - 1
        };
        for piece in body.chunks(1024) {
            let sent = writer.write_all(piece).and_then(|()| writer.flush());
            let mut ranges = ranges.lock().unwrap();
            if sent.is_err() {
                ranges[k].hung_up = true;
                ranges[k].ended = true;
                return;
            }
            ranges[k].written += piece.len() as u64;
            drop(ranges);
            std::thread::sleep(Duration::from_millis(25));
        }
        ranges.lock().unwrap()[k].ended = true;
    }
}

fn want(levels: usize) -> Want {
    Want {
        id: TileId::new(0, 0),
        levels,
        priority: 1.0,
        predicted: false,
        drawn: true,
    }
}

/// Runs frames wishing `levels` of the tile, 10 ms apart, until `done` or 20 s pass.
fn frames_until(
    p: &mut StreamPager<ArchiveLoader>,
    levels: usize,
    mut done: impl FnMut(&StreamPager<ArchiveLoader>) -> bool,
) {
    let started = Instant::now();
    while !done(p) {
        assert!(
            started.elapsed() < Duration::from_secs(20),
            "waited 20 s; pager {:?}, stream {:?}, last error {:?}",
            p.resident().stats(),
            p.stream_stats(),
            p.resident().last_error()
        );
        p.update((0.5, 0.5));
        p.request(&[want(levels)]);
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn a_large_range_the_pager_gives_up_stops_downloading_and_the_tile_can_come_again() {
    let dir = tempfile::tempdir().unwrap();
    let archive = one_large_tile(dir.path());
    let slow = Arc::new(AtomicBool::new(true));
    let ranges = Arc::new(Mutex::new(Vec::new()));
    let url = slow_server(&archive, Arc::clone(&slow), Arc::clone(&ranges));
    let reader = ArchiveReader::open(source::open(&url).unwrap())
        .unwrap()
        .with_fetch_attempts(1);
    let levels = reader.header().levels();
    let (entry, _) = reader
        .entry(TileId::new(0, 0), &CancelToken::new())
        .unwrap();
    let (offset, len) = entry.range(1..levels);
    assert!(len > 4 * FINISH_BELOW, "levels 1.. take {len} bytes");
    let loader = ArchiveLoader::new(reader, (Light::default(), true), 200.0, CrackMode::Stitch);
    let config = PagerConfig::new(64 << 20, PagerMode::Threaded { queue_depth: 2 });
    let settings = StreamSettings {
        prediction: None,
        ..StreamSettings::default()
    };
    let mut p = StreamPager::new(loader, Pyramid::new(1, 1).unwrap(), config, settings).unwrap();
    let tile = TileId::new(0, 0);
    frames_until(&mut p, 1, |p| p.held_levels(tile) == 1);
    let coarse = p.resident().stats().memory_bytes;

    // The rest of the tile, sent slowly; once it is under way the view asks for less, and
    // once that wish has held for its second, the request is cancelled.
    frames_until(&mut p, levels, |_| {
        ranges
            .lock()
            .unwrap()
            .first()
            .is_some_and(|r| r.written > 0)
    });
    let asked_less = Instant::now();
    frames_until(&mut p, 1, |p| p.resident().stats().cancelled > 0);
    assert!(asked_less.elapsed().as_secs_f64() >= HOLD_SECONDS);
    frames_until(&mut p, 1, |_| ranges.lock().unwrap()[0].ended);
    let cut = ranges.lock().unwrap()[0];
    assert_eq!(
        cut.len, len,
        "the slow range is levels 1..{levels} at {offset}"
    );
    assert!(
        cut.hung_up && cut.written < len / 2,
        "the client hung up early: {cut:?} of {len} bytes"
    );
    // What the fetch thread downloaded comes back as cut, never stored.
    frames_until(&mut p, 1, |p| p.stream_stats().cut_bytes > 0);
    let stats = p.resident().stats();
    assert_eq!(
        p.held_levels(tile),
        1,
        "the abandoned levels are not stored"
    );
    assert_eq!((stats.fetching, stats.memory_bytes), (0, coarse));
    assert_eq!((stats.cancelled, stats.errors), (1, 0), "{stats:?}");
    let stream = p.stream_stats();
    assert_eq!(stream.cancelled_in_flight, 1);
    assert!(stream.cut_bytes <= cut.written, "{stream:?}, {cut:?}");

    // Asked for again, the tile comes whole.
    slow.store(false, Ordering::Relaxed);
    frames_until(&mut p, levels, |p| p.held_levels(tile) == levels);
    let stats = p.resident().stats();
    assert_eq!((stats.fetching, stats.errors), (0, 0), "{stats:?}");
    assert_eq!(ranges.lock().unwrap().len(), 1, "one slow range");
}

/// Raises `cancel` once the server has sent 4 KiB of slow range number `k`.
fn cancel_once_sent(
    cancel: &CancelToken,
    ranges: &Arc<Mutex<Vec<SlowRange>>>,
    k: usize,
) -> std::thread::JoinHandle<()> {
    let (cancel, ranges) = (cancel.clone(), Arc::clone(ranges));
    std::thread::spawn(move || {
        while ranges
            .lock()
            .unwrap()
            .get(k)
            .is_none_or(|r| r.written < 4096)
        {
            std::thread::sleep(Duration::from_millis(5));
        }
        cancel.cancel();
    })
}

#[test]
fn an_http_read_cancelled_under_way_stops_and_one_almost_done_finishes() {
    let dir = tempfile::tempdir().unwrap();
    let archive = one_large_tile(dir.path());
    let ranges = Arc::new(Mutex::new(Vec::new()));
    let url = slow_server(
        &archive,
        Arc::new(AtomicBool::new(true)),
        Arc::clone(&ranges),
    );
    let http = source::open(&url).unwrap();
    let size = std::fs::metadata(&archive).unwrap().len();
    assert!(size > 8 * FINISH_BELOW);
    // Cancelled before it starts: nothing is asked of the server.
    let cancel = CancelToken::new();
    cancel.cancel();
    let early = http.read_range_cancellable(0, 6 * FINISH_BELOW, &cancel);
    assert!(
        matches!(early, Err(Error::Cancelled { received: 0, .. })),
        "{early:?}"
    );
    assert!(ranges.lock().unwrap().is_empty());
    // Cancelled under way: the read stops with what arrived, far short of the range.
    let cancel = CancelToken::new();
    let raise = cancel_once_sent(&cancel, &ranges, 0);
    let cut = http.read_range_cancellable(0, 6 * FINISH_BELOW, &cancel);
    raise.join().unwrap();
    let received = match cut {
        Err(Error::Cancelled { received, .. }) => received,
        other => panic!("{other:?}"),
    };
    assert!((1..5 * FINISH_BELOW).contains(&received), "{received}");
    let started = Instant::now();
    while !ranges.lock().unwrap()[0].ended {
        assert!(
            started.elapsed() < Duration::from_secs(20),
            "the server still sends"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    let first = ranges.lock().unwrap()[0];
    assert!(
        first.hung_up && first.written < 3 * FINISH_BELOW,
        "{first:?}"
    );
    // Cancelled with less than FINISH_BELOW left: it runs to its end, whole and right.
    let almost = CancelToken::new();
    let len = FINISH_BELOW + 1024;
    let raise = cancel_once_sent(&almost, &ranges, 1);
    let whole = http.read_range_cancellable(100, len, &almost).unwrap();
    raise.join().unwrap();
    assert!(almost.is_cancelled());
    assert_eq!(
        whole,
        std::fs::read(&archive).unwrap()[100..100 + len as usize]
    );
}
