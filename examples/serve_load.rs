//! Load on `stripmask serve`'s server over loopback: C clients, each on its own kept-alive
//! connection, ask for N random byte ranges of an archive; prints requests per second, errors
//! and the 50th and 99th percentile latencies (the figure in docs/security.md).
//!
//! ```sh
//! cargo run --release --example serve_load                # 8 clients x 500 ranges
//! cargo run --release --example serve_load -- 16 1000
//! ```

use std::path::Path;
use std::time::{Duration, Instant};

use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{MemoryReader, NodataFill};
use stripmask::db::server::Server;
use stripmask::db::source::throttle::LinkProfile;

/// The most clients and ranges each this accepts: the run stays bounded in count and time.
const MAX_CLIENTS: usize = 256;
const MAX_RANGES: usize = 100_000;

fn main() {
    let mut args = std::env::args().skip(1).map(|a| a.parse::<usize>());
    let (clients, ranges) = match (args.next(), args.next()) {
        (None, None) => (8, 500),
        (Some(Ok(c)), Some(Ok(n)))
            if (1..=MAX_CLIENTS).contains(&c) && (1..=MAX_RANGES).contains(&n) =>
        {
            (c, n)
        }
        _ => {
            eprintln!("usage: serve_load [CLIENTS (1..=256) RANGES_PER_CLIENT (1..=100000)]");
            std::process::exit(2);
        }
    };
    let dir = std::env::temp_dir().join(format!("serve_load_{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    let archive = dir.join("load.smdb");
    let len = make_archive(&archive);
    let server = Server::start(
        &archive,
        "127.0.0.1:0".parse().expect("an address"),
        LinkProfile::default(),
    )
    .expect("the server starts");
    let url = server.url().to_string();

    let start = Instant::now();
    let results: Vec<(Vec<Duration>, usize)> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..clients)
            .map(|c| {
                let url = &url;
                s.spawn(move || client(url, len, ranges, c as u64 + 1))
            })
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().expect("a client"))
            .collect()
    });
    let wall = start.elapsed();
    drop(server);
    let _ = std::fs::remove_dir_all(&dir);

    let errors: usize = results.iter().map(|r| r.1).sum();
    let mut latencies: Vec<Duration> = results.into_iter().flat_map(|r| r.0).collect();
    latencies.sort();
    let total = clients * ranges;
    let pct = |p: f64| {
        latencies
            .get(((latencies.len() as f64 * p).ceil() as usize).saturating_sub(1))
            .map_or(0.0, |d| d.as_secs_f64() * 1e3)
    };
    println!(
        "{clients} clients x {ranges} random ranges of a {len}-byte archive on loopback: \
         {:.0} req/s, {errors} errors, p50 {:.2} ms, p99 {:.2} ms",
        total as f64 / wall.as_secs_f64(),
        pct(0.50),
        pct(0.99)
    );
}

/// An archive of a 1025 x 1025 synthetic DEM in 65-sample tiles; its length.
fn make_archive(path: &Path) -> u64 {
    let side = 1025;
    let samples = (0..side * side)
        .map(|k| {
            let (x, y) = ((k % side) as f32, (k / side) as f32);
            (x * 0.01).sin() * 300.0 + (y * 0.013).cos() * 200.0
        })
        .collect();
    let reader = MemoryReader::new("load", side, side, samples).expect("a DEM");
    build(
        NodataFill::new(reader, None),
        path,
        &BuildOptions::default(),
        &|_, _| {},
    )
    .expect("the build");
    std::fs::metadata(path).expect("the archive").len()
}

/// One client: `ranges` GETs of up to 64 KiB at random offsets (seeded), on one connection;
/// each request's latency and the number that failed.
fn client(url: &str, len: u64, ranges: usize, seed: u64) -> (Vec<Duration>, usize) {
    let agent: ureq::Agent = ureq::Agent::config_builder()
        .http_status_as_error(false)
        .timeout_global(Some(Duration::from_secs(10)))
        .build()
        .into();
    let mut state = seed;
    let mut next = move || {
        // SplitMix64.
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    };
    let mut latencies = Vec::with_capacity(ranges);
    let mut errors = 0;
    for _ in 0..ranges {
        let first = next() % len;
        let last = (first + next() % 65_536).min(len - 1);
        let t = Instant::now();
        let ok = agent
            .get(url)
            .header("Range", &format!("bytes={first}-{last}"))
            .call()
            .ok()
            .filter(|r| r.status().as_u16() == 206)
            .and_then(|mut r| r.body_mut().with_config().limit(1 << 20).read_to_vec().ok())
            .is_some_and(|body| body.len() as u64 == last - first + 1);
        latencies.push(t.elapsed());
        errors += usize::from(!ok);
    }
    (latencies, errors)
}
