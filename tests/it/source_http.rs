//! The HTTP range source against `serve`'s server on 127.0.0.1, plain and throttled.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use stripmask::Error;
use stripmask::db::archive::ArchiveReader;
use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{MemoryReader, NodataFill};
use stripmask::db::grid::TileId;
use stripmask::db::server::Server;
use stripmask::db::source::CancelToken;
use stripmask::db::source::TileSource;
use stripmask::db::source::file::FileSource;
use stripmask::db::source::http::HttpSource;
use stripmask::db::source::throttle::{LinkProfile, SimulatedLink};

fn loopback() -> SocketAddr {
    "127.0.0.1:0".parse().unwrap()
}

fn archive(dir: &Path) -> PathBuf {
    let (w, h) = (65, 49);
    let samples = (0..w * h)
        .map(|k| ((k % w) as f32 * 0.2).sin() * 80.0 + (k / w) as f32)
        .collect();
    let reader = MemoryReader::new("hills", w, h, samples).unwrap();
    let out = dir.join("hills.smdb");
    let options = BuildOptions {
        tile_size: 17,
        ..BuildOptions::default()
    };
    build(NodataFill::new(reader, None), &out, &options, &|_, _| {}).unwrap();
    out
}

fn agent() -> ureq::Agent {
    ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(Duration::from_secs(10)))
        .build()
        .into()
}

#[test]
fn http_source_reads_the_same_tiles_as_the_file_source() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path());
    let server = Server::start(&path, loopback(), LinkProfile::default()).unwrap();
    assert!(server.addr().ip().is_loopback());
    assert!(server.url().ends_with("/hills.smdb"));
    let http = ArchiveReader::open(HttpSource::new(server.url())).unwrap();
    let file = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
    assert_eq!(http.header(), file.header());
    assert_eq!(http.directory(), file.directory());
    let all = file.header().levels();
    for id in file.pyramid().tiles() {
        let cancel = CancelToken::new();
        assert_eq!(
            http.entry(id, &cancel).unwrap().0,
            file.entry(id, &cancel).unwrap().0
        );
        assert_eq!(
            http.read_levels(id, 0..all).unwrap(),
            file.read_levels(id, 0..all).unwrap()
        );
    }
    assert_eq!(http.top().unwrap(), file.top().unwrap());
}

#[test]
fn server_answers_ranges_head_and_refuses_everything_else() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path());
    let len = std::fs::metadata(&path).unwrap().len();
    let bytes = std::fs::read(&path).unwrap();
    let server = Server::start(&path, loopback(), LinkProfile::default()).unwrap();
    let url = server.url().to_string();
    let base = format!("http://{}", server.addr());
    let a = agent();

    let mut r = a.get(&url).header("Range", "bytes=10-19").call().unwrap();
    assert_eq!(r.status().as_u16(), 206);
    assert_eq!(
        r.headers()["content-range"].to_str().unwrap(),
        format!("bytes 10-19/{len}")
    );
    assert_eq!(r.body_mut().read_to_vec().unwrap(), &bytes[10..20]);

    let mut r = a.get(&url).header("Range", "bytes=-5").call().unwrap();
    assert_eq!(r.status().as_u16(), 206);
    assert_eq!(
        r.body_mut().read_to_vec().unwrap(),
        &bytes[bytes.len() - 5..]
    );

    let r = a
        .get(&url)
        .header("Range", &format!("bytes={len}-"))
        .call()
        .unwrap();
    assert_eq!(r.status().as_u16(), 416);
    assert_eq!(
        r.headers()["content-range"].to_str().unwrap(),
        format!("bytes */{len}")
    );

    let mut r = a.get(&format!("{base}/")).call().unwrap();
    assert_eq!(r.status().as_u16(), 200);
    assert_eq!(
        r.body_mut()
            .with_config()
            .limit(1 << 24)
            .read_to_vec()
            .unwrap(),
        bytes
    );

    let r = a.head(&url).call().unwrap();
    assert_eq!(r.status().as_u16(), 200);
    assert_eq!(
        r.headers()["content-length"].to_str().unwrap(),
        len.to_string()
    );
    assert_eq!(r.headers()["accept-ranges"].to_str().unwrap(), "bytes");

    for path in [
        "/other.smdb",
        "/../hills.smdb",
        "/%2e%2e/etc/passwd",
        "/hills.smdb/x",
    ] {
        let r = a.get(&format!("{base}{path}")).call().unwrap();
        assert_eq!(r.status().as_u16(), 404, "{path}");
    }
    let r = a.post(&url).send("x").unwrap();
    assert_eq!(r.status().as_u16(), 405);
}

#[test]
fn a_lossy_link_is_survived_by_retries_and_a_dead_one_gives_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path());
    let lossy = LinkProfile {
        drop_rate: 0.3,
        seed: 42,
        ..LinkProfile::default()
    };
    let server = Server::start(&path, loopback(), lossy).unwrap();
    let reader = ArchiveReader::open_with_attempts(HttpSource::new(server.url()), 12).unwrap();
    let file = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
    for id in file.pyramid().tiles() {
        assert_eq!(reader.tile(id).unwrap(), file.tile(id).unwrap());
    }
    drop(server);

    let dead = LinkProfile {
        drop_rate: 1.0,
        ..LinkProfile::default()
    };
    let server = Server::start(&path, loopback(), dead).unwrap();
    let e = match ArchiveReader::open_with_attempts(HttpSource::new(server.url()), 3) {
        Ok(_) => panic!("opened through a dead link"),
        Err(e) => e.to_string(),
    };
    assert!(e.contains(server.url()) && e.contains("503"), "{e}");
}

#[test]
fn a_corrupt_tile_on_the_server_fails_its_checksum_by_url() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path());
    let id = TileId::new(2, 0);
    let (entry, _) = ArchiveReader::open(FileSource::open(&path).unwrap())
        .unwrap()
        .entry(id, &CancelToken::new())
        .unwrap();
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[entry.offset as usize] ^= 0x55;
    std::fs::write(&path, bytes).unwrap();
    let server = Server::start(&path, loopback(), LinkProfile::default()).unwrap();
    let reader = ArchiveReader::open_with_attempts(HttpSource::new(server.url()), 2).unwrap();
    match reader.tile(id) {
        Err(Error::Checksum {
            name,
            tile,
            attempts: 2,
            ..
        }) => assert_eq!(
            (name.as_str(), tile.as_str()),
            (server.url(), "tile (2, 0)")
        ),
        other => panic!("{other:?}"),
    }
    reader.tile(TileId::new(1, 0)).unwrap();
}

#[test]
fn latency_and_bandwidth_shape_the_served_link() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path());
    let len = std::fs::metadata(&path).unwrap().len();
    let slow = LinkProfile {
        bandwidth_kbps: Some(160.0),
        latency: Duration::from_millis(60),
        ..LinkProfile::default()
    };
    let server = Server::start(&path, loopback(), slow).unwrap();
    let source = HttpSource::new(server.url());
    let t = Instant::now();
    source.read_range(0, 10).unwrap();
    assert!(
        t.elapsed() >= Duration::from_millis(60),
        "{:?}",
        t.elapsed()
    );
    // The whole file at 20 000 bytes/s, on top of the latency.
    let expected = Duration::from_secs_f64(len as f64 / 20_000.0) + Duration::from_millis(60);
    let t = Instant::now();
    assert_eq!(source.read_range(0, len).unwrap().len() as u64, len);
    assert!(
        t.elapsed() >= expected.mul_f64(0.95),
        "{:?} < {expected:?}",
        t.elapsed()
    );
}

#[test]
fn large_answers_keep_their_content_length() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("big.smdb");
    let (w, h) = (129, 129);
    let samples = (0..w * h).map(|k| ((k * 7919) % 4000) as f32).collect();
    let reader = MemoryReader::new("big", w, h, samples).unwrap();
    build(
        NodataFill::new(reader, None),
        &path,
        &BuildOptions {
            codec: stripmask::db::archive::Codec::None,
            ..BuildOptions::default()
        },
        &|_, _| {},
    )
    .unwrap();
    let len = std::fs::metadata(&path).unwrap().len();
    assert!(len > 64 * 1024);
    let server = Server::start(&path, loopback(), LinkProfile::default()).unwrap();
    let source = HttpSource::new(server.url());
    assert_eq!(source.size().unwrap(), len);
    let r = agent()
        .get(server.url())
        .header("Range", "bytes=0-49999")
        .call()
        .unwrap();
    assert_eq!(r.headers()["content-length"].to_str().unwrap(), "50000");
    let reader = ArchiveReader::open(source).unwrap();
    reader.tile(TileId::new(0, 0)).unwrap();
}

#[test]
fn simulated_link_without_a_network_drops_and_delays_deterministically() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path());
    let profile = LinkProfile {
        latency: Duration::from_millis(5),
        drop_rate: 0.5,
        seed: 3,
        ..LinkProfile::default()
    };
    let link = SimulatedLink::new(FileSource::open(&path).unwrap(), profile);
    let outcomes: Vec<bool> = (0..20).map(|_| link.read_range(0, 4).is_ok()).collect();
    assert!(outcomes.iter().any(|&ok| ok) && outcomes.iter().any(|&ok| !ok));
    let again = SimulatedLink::new(FileSource::open(&path).unwrap(), profile);
    let replay: Vec<bool> = (0..20).map(|_| again.read_range(0, 4).is_ok()).collect();
    assert_eq!(outcomes, replay);
    let reader = ArchiveReader::open_with_attempts(link, 16).unwrap();
    reader.tile(TileId::new(0, 0)).unwrap();
}
