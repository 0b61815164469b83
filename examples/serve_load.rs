//! Load on `stripmask serve`'s server over loopback: C clients, each on its own kept-alive
//! connection, ask for N random byte ranges of an archive; prints requests per second, errors
//! and the 50th and 99th percentile latencies (the figures in docs/security.md).
//!
//! With `attack`, the server is attacked instead: reconnecting slowloris connections (a byte a
//! second), slow readers of the whole file (the archive followed by zeros up to 64 MiB; 4 KiB
//! every 5 s) and idle connections are opened and kept, and meanwhile a normal client asks for
//! a 64 KiB range once a second for 20 s, each on a new connection; prints how long it waited,
//! the process's threads, and the memory the attack cost.
//!
//! ```sh
//! cargo run --release --example serve_load                # 8 clients x 500 ranges
//! cargo run --release --example serve_load -- 16 1000
//! cargo run --release --example serve_load -- attack      # 1000 slowloris, 200 slow readers, 1000 idle
//! cargo run --release --example serve_load -- attack 100 70 200
//! ```

#[path = "support/attack.rs"]
mod attack;

use std::path::Path;
use std::time::{Duration, Instant};

use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{MemoryReader, NodataFill};
use stripmask::db::server::Server;
use stripmask::db::source::throttle::LinkProfile;

use self::attack::{Attack, Kind};

/// The most clients and ranges each this accepts: the run stays bounded in count and time.
const MAX_CLIENTS: usize = 256;
const MAX_RANGES: usize = 100_000;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    if args.first().map(String::as_str) == Some("attack") {
        match numbers(&args[1..], [1000, 200, 1000], MAX_ATTACKERS) {
            Some([slowloris, slow, idle]) => under_attack(slowloris, slow, idle),
            None => usage(),
        }
        return;
    }
    let Some([clients, ranges]) =
        numbers(&args, [8, 500], MAX_RANGES).filter(|[c, _]| (1..=MAX_CLIENTS).contains(c))
    else {
        usage()
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
    let total = clients * ranges;
    let (p50, p99) = (
        percentile(&mut latencies, 0.50),
        percentile(&mut latencies, 0.99),
    );
    println!(
        "{clients} clients x {ranges} random ranges of a {len}-byte archive on loopback: \
         {:.0} req/s, {errors} errors, p50 {p50:.2} ms, p99 {p99:.2} ms",
        total as f64 / wall.as_secs_f64(),
    );
}

/// The most attacking connections of each kind this opens.
const MAX_ATTACKERS: usize = 5000;

/// `args` as whole numbers, each in `1..=max`, or `defaults` when there are none.
fn numbers<const N: usize>(
    args: &[String],
    defaults: [usize; N],
    max: usize,
) -> Option<[usize; N]> {
    if args.is_empty() {
        return Some(defaults);
    }
    let parsed: Vec<usize> = args
        .iter()
        .map(|a| a.parse().ok().filter(|n| (1..=max).contains(n)))
        .collect::<Option<_>>()?;
    parsed.try_into().ok()
}

fn usage() -> ! {
    eprintln!(
        "usage: serve_load [CLIENTS (1..=256) RANGES_PER_CLIENT (1..=100000)]\n       \
         serve_load attack [SLOWLORIS SLOW_READERS IDLE (each 1..=5000)]"
    );
    std::process::exit(2);
}

/// The `p` quantile of `latencies` (sorted here), milliseconds.
fn percentile(latencies: &mut [Duration], p: f64) -> f64 {
    latencies.sort();
    latencies
        .get(((latencies.len() as f64 * p).ceil() as usize).saturating_sub(1))
        .map_or(0.0, |d| d.as_secs_f64() * 1e3)
}

/// A normal client's 64 KiB ranges, one a second for 20 s, each on a new connection, while
/// `slowloris`, `slow` readers and `idle` connections attack the server.
fn under_attack(slowloris: usize, slow: usize, idle: usize) {
    let dir = std::env::temp_dir().join(format!("serve_attack_{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("a temporary directory");
    let archive = dir.join("load.smdb");
    make_archive(&archive);
    // Zeros after the archive, up to 64 MiB (sparse): a whole answer outlasts the socket
    // buffers of a slow reader.
    std::fs::OpenOptions::new()
        .write(true)
        .open(&archive)
        .and_then(|f| f.set_len(64 << 20))
        .expect("the archive grows");
    let before = resident_kib();
    let server = Server::start(
        &archive,
        "127.0.0.1:0".parse().expect("an address"),
        LinkProfile::default(),
    )
    .expect("the server starts");
    let (addr, path) = (server.addr(), "/load.smdb");
    let idle_server = resident_kib();
    let started = Instant::now();
    let attacks = [
        Attack::start(
            addr,
            path,
            Kind::Slowloris {
                every: Duration::from_secs(1),
            },
            slowloris,
        ),
        Attack::start(
            addr,
            path,
            Kind::SlowReader {
                piece: 4096,
                every: Duration::from_secs(5),
            },
            slow,
        ),
        Attack::start(addr, path, Kind::Idle, idle),
    ];
    println!(
        "{slowloris} slowloris, {slow} slow readers and {idle} idle connections opened in {:.1} s",
        started.elapsed().as_secs_f64()
    );
    let mut waits = Vec::new();
    let mut errors = 0;
    let mut peak_threads = 0;
    let mut peak_kib = 0;
    let mut peak_tcp_pages = 0;
    for _ in 0..20 {
        let asked = Instant::now();
        let agent: ureq::Agent = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .timeout_global(Some(Duration::from_secs(10)))
            .build()
            .into();
        let ok = agent
            .get(server.url())
            .header("Range", "bytes=0-65535")
            .call()
            .ok()
            .filter(|r| r.status().as_u16() == 206)
            .and_then(|mut r| r.body_mut().read_to_vec().ok())
            .is_some_and(|body| body.len() == 65536);
        waits.push(asked.elapsed());
        errors += usize::from(!ok);
        peak_threads = peak_threads.max(threads());
        peak_kib = peak_kib.max(resident_kib());
        peak_tcp_pages = peak_tcp_pages.max(tcp_pages());
        std::thread::sleep(Duration::from_secs(1).saturating_sub(asked.elapsed()));
    }
    let reconnects: Vec<u64> = attacks.iter().map(Attack::reconnects).collect();
    drop(attacks);
    drop(server);
    let _ = std::fs::remove_dir_all(&dir);
    let max = waits.iter().max().map_or(0.0, |d| d.as_secs_f64() * 1e3);
    println!(
        "a normal client, 20 requests of 64 KiB on new connections: p50 {:.2} ms, max {max:.2} ms, \
         {errors} errors; reconnects forced (slowloris, slow, idle): {reconnects:?}; threads of the \
         process at most {peak_threads}; resident memory {:.1} MB before the server, {:.1} MB \
         with it idle, at most {:.1} MB under attack; the system's TCP buffers at most {:.1} MB",
        percentile(&mut waits, 0.5),
        before as f64 / 1024.0,
        idle_server as f64 / 1024.0,
        peak_kib as f64 / 1024.0,
        peak_tcp_pages as f64 * 4096.0 / 1e6,
    );
}

/// A line of `/proc/self/status` as a number (0 where there is none).
fn status_number(field: &str) -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines()
                .find_map(|l| l.strip_prefix(field))
                .and_then(|v| v.split_whitespace().next()?.parse().ok())
        })
        .unwrap_or(0)
}

/// The process's resident memory, KiB.
fn resident_kib() -> u64 {
    status_number("VmRSS:")
}

/// The pages the system's TCP buffers take (`/proc/net/sockstat`), both ends of every
/// loopback connection included.
fn tcp_pages() -> u64 {
    std::fs::read_to_string("/proc/net/sockstat")
        .ok()
        .and_then(|s| {
            let tcp = s.lines().find_map(|l| l.strip_prefix("TCP:"))?;
            let mut words = tcp.split_whitespace();
            words.find(|w| *w == "mem")?;
            words.next()?.parse().ok()
        })
        .unwrap_or(0)
}

/// The process's threads.
fn threads() -> u64 {
    status_number("Threads:")
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
