//! `stripmask serve`: one archive over HTTP with byte ranges.

use std::io::Write;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

use clap::Args;
use stripmask::db::server::{Limits, Server};
use stripmask::db::source::throttle::LinkProfile;
use stripmask::error::Result;

/// `serve`'s arguments: the archive, the address, and the simulated link.
#[derive(Args, Debug)]
pub(super) struct ServeArgs {
    /// The archive to serve.
    file: PathBuf,
    /// Address to listen on (port 0 picks a free port).
    #[arg(long, default_value = "127.0.0.1:0")]
    listen: SocketAddr,
    /// Simulated bandwidth per connection, kilobits per second.
    #[arg(long, allow_negative_numbers = true)]
    bandwidth_kbps: Option<f64>,
    /// Simulated latency before each answer, milliseconds.
    #[arg(long, default_value_t = LinkProfile::default().latency.as_millis() as u64)]
    latency_ms: u64,
    /// Each answer's latency varies within ± this many milliseconds.
    #[arg(long, default_value_t = LinkProfile::default().jitter.as_millis() as u64)]
    jitter_ms: u64,
    /// Fraction of requests answered 503, 0..1.
    #[arg(long, default_value_t = LinkProfile::default().drop_rate, allow_negative_numbers = true)]
    drop_rate: f64,
    /// Seed of the latency and drop decisions.
    #[arg(long, default_value_t = LinkProfile::default().seed)]
    seed: u64,
    /// Connections open at once; at the limit a new one closes the connection that has waited
    /// longest for a request, and is answered 503 only when every connection is answering.
    #[arg(long, default_value_t = Limits::default().max_connections)]
    max_connections: usize,
}

/// Serves until the process is stopped, after printing the URL.
pub(super) fn run(a: ServeArgs) -> Result<()> {
    let profile = LinkProfile {
        bandwidth_kbps: a.bandwidth_kbps,
        latency: Duration::from_millis(a.latency_ms),
        jitter: Duration::from_millis(a.jitter_ms),
        drop_rate: a.drop_rate,
        seed: a.seed,
    };
    let limits = Limits {
        max_connections: a.max_connections,
        ..Limits::default()
    };
    let server = Server::start_with(&a.file, a.listen, profile, limits)?;
    say!("{}", server.url());
    let _ = std::io::stdout().flush();
    server.wait();
    Ok(())
}
