//! `stripmask serve`: one archive over HTTP/1.1 (hyper on a small tokio runtime), with byte
//! ranges, validators and conditional requests, and an optional simulated link (latency with
//! jitter, bandwidth, drops) for experiments.
//!
//! It answers `GET` and `HEAD` for `/` and `/<file name>` only; every other path is 404 and
//! every other method 405, so nothing but the archive can be read (no listing, no traversal).
//! `Range: bytes=a-b`, `bytes=a-` and `bytes=-n` give 206 with `Content-Range`; an unsatisfiable
//! range gives 416; a request without a (single, parseable) range gets the whole file with 200.
//! Every answer about the archive carries its validators (`ETag` from its size and modification
//! time, `Last-Modified`), and `If-Match`, `If-Unmodified-Since` (412), `If-None-Match`,
//! `If-Modified-Since` (304) and `If-Range` are honoured. hyper reads the requests: a malformed
//! head is answered 400, one over the size limit 431, and a `HEAD` answer never has a body.
//!
//! The simulated link is a layer around the archive's service ([`LinkProfile`]): every answer
//! waits for its delay, a dropped request is answered 503, and bodies are paced at the
//! bandwidth.
//!
//! One client cannot stop it ([`Limits`], docs/security.md): every connection is a task, so
//! idle and slow clients cost memory, not threads; a request head must arrive whole in time and
//! an answer must be sent in time; and at the connection limit the connection that has waited
//! longest for a request head makes room for the new one.

mod archive;
mod body;
mod connections;
mod link;
mod range;
mod validator;

use std::net::SocketAddr;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

pub use range::{RangeRequest, parse_range};

use self::archive::Archive;
use self::connections::Connections;
use self::link::LinkLayer;
use crate::db::archive::ArchiveReader;
use crate::db::source::file::FileSource;
use crate::db::source::throttle::LinkProfile;
use crate::error::{Error, Result};

/// What one server allows its clients: the bounds that keep a client (or many) from exhausting
/// its memory or its time, or keeping other clients out.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Connections open at once. At the limit, a new connection closes the one that has waited
    /// longest for a request head; when every connection is in the middle of an answer, the
    /// new one is answered 503. Never more than the process's file descriptors allow.
    pub max_connections: usize,
    /// Requests one connection may send; the last answer says `Connection: close`.
    pub max_requests_per_connection: usize,
    /// The longest request head (request line and headers), bytes; a longer one is answered 431.
    pub max_header_bytes: usize,
    /// Time a request head has to arrive whole, from when the connection is ready for it (so
    /// also how long an idle kept-alive connection is kept); then the connection is closed.
    pub request_timeout: Duration,
    /// Time an answer has to be sent whole, on top of its length at
    /// [`Limits::min_send_rate`] and at the simulated link's bandwidth
    /// ([`Limits::time_to_send`]); then the connection is closed.
    pub response_timeout: Duration,
    /// The slowest a client may read an answer, bytes per second.
    pub min_send_rate: u64,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_connections: 4096,
            max_requests_per_connection: 1000,
            max_header_bytes: 8 * 1024,
            request_timeout: Duration::from_secs(10),
            response_timeout: Duration::from_secs(30),
            min_send_rate: 64 * 1024,
        }
    }
}

impl Limits {
    /// The limits when each is within what a server can work with.
    pub fn validate(&self) -> Result<()> {
        if !(1..=65536).contains(&self.max_connections) {
            return Err(Error::setting(
                "--max-connections",
                self.max_connections,
                "1 ..= 65536",
            ));
        }
        if self.max_requests_per_connection == 0 {
            return Err(Error::setting("requests per connection", 0, "at least 1"));
        }
        if !(256..=1 << 20).contains(&self.max_header_bytes) {
            return Err(Error::setting(
                "header size limit",
                self.max_header_bytes,
                "256 bytes ..= 1 MiB",
            ));
        }
        for (name, t) in [
            ("request timeout", self.request_timeout),
            ("response timeout", self.response_timeout),
        ] {
            if !(Duration::from_millis(1)..=Duration::from_secs(86_400)).contains(&t) {
                return Err(Error::setting(name, format!("{t:?}"), "1 ms ..= 1 day"));
            }
        }
        if self.min_send_rate == 0 {
            return Err(Error::setting("minimum send rate", 0, "at least 1 byte/s"));
        }
        Ok(())
    }

    /// The time an answer of `len` bytes has to be sent over `link`:
    /// [`Limits::response_timeout`], plus `len` at [`Limits::min_send_rate`], plus `len` at
    /// the link's bandwidth.
    pub fn time_to_send(&self, len: u64, link: &LinkProfile) -> Duration {
        self.response_timeout
            + Duration::from_secs_f64(len as f64 / self.min_send_rate as f64)
            + link.transfer_time(len)
    }
}

/// A running server; dropping it (or [`Server::stop`]) shuts it down.
pub struct Server {
    addr: SocketAddr,
    url: String,
    runtime: Option<tokio::runtime::Runtime>,
    accept: Option<tokio::task::JoinHandle<()>>,
}

/// What every connection reads: the archive behind its link, the limits, the open connections.
struct Shared {
    service: LinkLayer<Archive>,
    profile: LinkProfile,
    limits: Limits,
    connections: Arc<Connections>,
}

impl Server {
    /// Serves `archive` (checked to be a valid archive first) on `listen` (port 0 picks a free
    /// port) over a link shaped by `profile`, with the default [`Limits`].
    pub fn start(archive: &Path, listen: SocketAddr, profile: LinkProfile) -> Result<Server> {
        Server::start_with(archive, listen, profile, Limits::default())
    }

    /// [`Server::start`] with the given limits.
    pub fn start_with(
        archive: &Path,
        listen: SocketAddr,
        profile: LinkProfile,
        limits: Limits,
    ) -> Result<Server> {
        profile.validate()?;
        limits.validate()?;
        // Refuse anything that is not a readable archive (checks the header and the index).
        ArchiveReader::open(FileSource::open(archive)?)?;
        let file_name = served_name(archive)?;
        let cannot = |what: &str, e: std::io::Error| Error::Http {
            url: format!("http://{listen}"),
            problem: format!("cannot {what}: {e}"),
        };
        let runtime = runtime().map_err(|e| cannot("start the server's threads", e))?;
        let listener = {
            let _entered = runtime.enter();
            bind(listen).map_err(|e| cannot("listen", e))?
        };
        let addr = listener.local_addr().map_err(|e| cannot("listen", e))?;
        let cap = limits.max_connections.min(descriptor_room());
        let shared = Arc::new(Shared {
            service: LinkLayer::new(
                Archive::new(archive.to_path_buf(), format!("/{file_name}")),
                &profile,
            ),
            profile,
            limits,
            connections: Arc::new(Connections::new(cap)),
        });
        let accept = runtime.spawn(accept_loop(listener, shared));
        Ok(Server {
            addr,
            url: format!("http://{addr}/{file_name}"),
            runtime: Some(runtime),
            accept: Some(accept),
        })
    }

    /// The archive's URL.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// The bound address.
    pub fn addr(&self) -> SocketAddr {
        self.addr
    }

    /// Blocks until the server stops (for the CLI, which runs until killed).
    pub fn wait(mut self) {
        if let (Some(runtime), Some(accept)) = (self.runtime.as_ref(), self.accept.take()) {
            let _ = runtime.block_on(accept);
        }
    }

    /// Stops accepting requests and closes the open connections.
    pub fn stop(self) {
        drop(self);
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        if let Some(runtime) = self.runtime.take() {
            // Dropping every task closes the listener and every connection.
            if tokio::runtime::Handle::try_current().is_ok() {
                runtime.shutdown_background();
            } else {
                runtime.shutdown_timeout(Duration::from_secs(1));
            }
        }
    }
}

/// The server's runtime: as many workers as cores, two at least and four at most. Its
/// threads never grow with requests or connections.
fn runtime() -> std::io::Result<tokio::runtime::Runtime> {
    let cores = std::thread::available_parallelism().map_or(2, |n| n.get());
    tokio::runtime::Builder::new_multi_thread()
        .worker_threads(cores.clamp(2, 4))
        .max_blocking_threads(1)
        .thread_name("serve")
        .enable_io()
        .enable_time()
        .build()
}

/// Connections the system may hold for the server before it accepts them. A burst of
/// connections (clients reconnecting all at once) over the backlog has its SYNs dropped, and a
/// client whose SYN is dropped tries again a second later.
const BACKLOG: u32 = 4096;

/// The send buffer of every connection, bytes (Linux doubles it for its own bookkeeping). The
/// system would otherwise grow it to megabytes for a client that does not read, so that 200
/// slow readers would hold most of a gigabyte of kernel memory; this much still carries
/// 512 KiB per round trip (40 Mbit/s at 100 ms).
const SEND_BUFFER: u32 = 256 * 1024;

/// A listener on `addr` (port 0 picks a free port) with room for [`BACKLOG`] connections, whose
/// connections inherit its [`SEND_BUFFER`].
fn bind(addr: SocketAddr) -> std::io::Result<tokio::net::TcpListener> {
    let socket = match addr {
        SocketAddr::V4(_) => tokio::net::TcpSocket::new_v4()?,
        SocketAddr::V6(_) => tokio::net::TcpSocket::new_v6()?,
    };
    // As the standard library's listeners: a restarted server can take its port back at once.
    #[cfg(unix)]
    socket.set_reuseaddr(true)?;
    socket.set_send_buffer_size(SEND_BUFFER)?;
    socket.bind(addr)?;
    socket.listen(BACKLOG)
}

/// Accepts connections until the server stops. A failed accept (out of descriptors, a
/// connection reset before it was accepted) never stops serving: it waits a moment.
async fn accept_loop(listener: tokio::net::TcpListener, shared: Arc<Shared>) {
    loop {
        match listener.accept().await {
            Ok((stream, _)) => connections::accept(stream, &shared),
            Err(_) => tokio::time::sleep(Duration::from_millis(10)).await,
        }
    }
}

/// How many connections the process's file descriptors leave room for (Linux: the soft limit
/// of `/proc/self/limits`, less a reserve for the archive, the listener and the rest), so that
/// the connection limit is reached, and makes room, before accepting fails.
fn descriptor_room() -> usize {
    const RESERVE: usize = 64;
    let limit = std::fs::read_to_string("/proc/self/limits")
        .ok()
        .and_then(|limits| {
            limits
                .lines()
                .find_map(|l| l.strip_prefix("Max open files"))
                .and_then(|rest| rest.split_whitespace().next())
                .and_then(|soft| soft.parse::<usize>().ok())
        });
    limit.map_or(usize::MAX, |soft| soft.saturating_sub(RESERVE).max(1))
}

/// The archive's file name, which becomes its URL path: plain ASCII only, so that no request
/// path needs decoding.
fn served_name(archive: &Path) -> Result<String> {
    archive
        .file_name()
        .and_then(|n| n.to_str())
        .filter(|n| {
            n.bytes()
                .all(|b| b.is_ascii_alphanumeric() || b"._-".contains(&b))
        })
        .map(str::to_string)
        .ok_or_else(|| {
            Error::invalid(
                archive.display().to_string(),
                "serve needs a file name of ASCII letters, digits, '.', '_' or '-'",
            )
        })
}
