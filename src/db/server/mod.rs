//! `stripmask serve`: a small static HTTP server for one archive, with byte ranges and an
//! optional simulated link (latency with jitter, bandwidth, drops) for experiments.
//!
//! It answers `GET` and `HEAD` for `/` and `/<file name>` only; every other path is 404 and
//! every other method 405, so nothing but the archive can be read (no listing, no traversal).
//! `Range: bytes=a-b`, `bytes=a-` and `bytes=-n` give 206 with `Content-Range`; an unsatisfiable
//! range gives 416; a request without a (single, parseable) range gets the whole file with 200.
//! Every answer waits for its delay (`latency ± jitter`, [`LatencyDice`]) and is paced at the
//! bandwidth per connection; a dropped request (see [`LinkProfile::drop_rate`]) is answered 503.
//!
//! One client cannot stop it ([`Limits`], docs/security.md): a fixed pool of workers serves one
//! connection each, so threads and memory do not grow with requests; a connection over the pool
//! is answered 503 at once; a connection serves a bounded number of requests, each of whose head
//! must arrive whole, within a size limit (431) and a time limit (408); writes time out; and no
//! client's failure ends anything but its own connection.

mod answer;
mod head;
mod range;

use std::collections::HashMap;
use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr, TcpListener, TcpStream};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, SyncSender, TrySendError, sync_channel};
use std::sync::{Arc, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::Duration;

pub use range::{RangeRequest, parse_range};

use crate::db::archive::ArchiveReader;
use crate::db::source::file::FileSource;
use crate::db::source::throttle::{DropDice, LatencyDice, LinkProfile};
use crate::error::{Error, Result};

/// What one server allows its clients: the bounds that keep a client (or many) from exhausting
/// its threads, memory or time.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Connections served at once, one worker thread each (a fixed pool); a connection over
    /// this is answered 503.
    pub max_connections: usize,
    /// Requests one connection may send; the last answer says `Connection: close`.
    pub max_requests_per_connection: usize,
    /// The longest request head (request line and headers), bytes; a longer one is answered 431.
    pub max_header_bytes: usize,
    /// Time a request head has to arrive whole, from when the connection is ready for it (so
    /// also how long an idle kept-alive connection is kept); a slower one is answered 408.
    pub request_timeout: Duration,
    /// Time one write of an answer may block on a client that does not read.
    pub write_timeout: Duration,
    /// Time spent on a refused connection (reading its request, writing the 503).
    pub refuse_timeout: Duration,
}

impl Default for Limits {
    fn default() -> Self {
        Limits {
            max_connections: 64,
            max_requests_per_connection: 1000,
            max_header_bytes: 8 * 1024,
            request_timeout: Duration::from_secs(10),
            write_timeout: Duration::from_secs(30),
            refuse_timeout: Duration::from_millis(200),
        }
    }
}

impl Limits {
    /// The limits when each is within what a server can work with.
    pub fn validate(&self) -> Result<()> {
        if !(1..=4096).contains(&self.max_connections) {
            return Err(Error::setting(
                "--max-connections",
                self.max_connections,
                "1 ..= 4096",
            ));
        }
        if self.max_requests_per_connection == 0 {
            return Err(Error::setting("requests per connection", 0, "at least 1"));
        }
        if self.max_header_bytes < 256 {
            return Err(Error::setting(
                "header size limit",
                self.max_header_bytes,
                "at least 256 bytes",
            ));
        }
        for (name, t) in [
            ("request timeout", self.request_timeout),
            ("write timeout", self.write_timeout),
            ("refuse timeout", self.refuse_timeout),
        ] {
            if t < Duration::from_millis(1) {
                return Err(Error::setting(name, format!("{t:?}"), "at least 1 ms"));
            }
        }
        Ok(())
    }
}

/// A running server; dropping it (or [`Server::stop`]) shuts it down.
pub struct Server {
    addr: SocketAddr,
    url: String,
    shared: Arc<Shared>,
    accept: Option<JoinHandle<()>>,
}

/// What every worker reads: the archive, the link and the limits, and the open connections
/// (so that stopping can close them).
struct Shared {
    path: PathBuf,
    url_path: String,
    profile: LinkProfile,
    dice: DropDice,
    delays: LatencyDice,
    limits: Limits,
    stop: AtomicBool,
    open: Mutex<HashMap<u64, TcpStream>>,
}

impl Shared {
    fn stopping(&self) -> bool {
        self.stop.load(Ordering::Acquire)
    }

    fn open(&self) -> std::sync::MutexGuard<'_, HashMap<u64, TcpStream>> {
        self.open.lock().unwrap_or_else(PoisonError::into_inner)
    }
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
        let cannot_listen = |e: std::io::Error| Error::Http {
            url: format!("http://{listen}"),
            problem: format!("cannot listen: {e}"),
        };
        let listener = TcpListener::bind(listen).map_err(cannot_listen)?;
        disable_nagle(&listener);
        let addr = listener.local_addr().map_err(cannot_listen)?;
        let shared = Arc::new(Shared {
            path: archive.to_path_buf(),
            url_path: format!("/{file_name}"),
            dice: DropDice::new(profile.drop_rate, profile.seed),
            delays: LatencyDice::new(&profile),
            profile,
            limits,
            stop: AtomicBool::new(false),
            open: Mutex::new(HashMap::new()),
        });
        let accept = spawn_threads(listener, &shared, addr)?;
        Ok(Server {
            addr,
            url: format!("http://{addr}/{file_name}"),
            shared,
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
        if let Some(handle) = self.accept.take() {
            let _ = handle.join();
        }
    }

    /// Stops accepting requests, closes the open connections and waits for the accept loop
    /// to end.
    pub fn stop(self) {
        drop(self);
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Release);
        // Wake the accept loop with a connection of our own.
        let wake = match self.addr {
            SocketAddr::V4(a) if a.ip().is_unspecified() => {
                SocketAddr::from((Ipv4Addr::LOCALHOST, a.port()))
            }
            SocketAddr::V6(a) if a.ip().is_unspecified() => {
                SocketAddr::from((Ipv6Addr::LOCALHOST, a.port()))
            }
            a => a,
        };
        let _ = TcpStream::connect_timeout(&wake, Duration::from_secs(1));
        for stream in self.shared.open().values() {
            let _ = stream.shutdown(std::net::Shutdown::Both);
        }
        if let Some(handle) = self.accept.take() {
            let _ = handle.join();
        }
    }
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

/// Starts the pool (one worker per connection served at once, all started now, so that no
/// request ever needs a new thread), the thread that answers refused connections, and the
/// accept loop, whose handle is returned.
fn spawn_threads(
    listener: TcpListener,
    shared: &Arc<Shared>,
    addr: SocketAddr,
) -> Result<JoinHandle<()>> {
    let limits = shared.limits;
    let spawn_failed = |e: std::io::Error| Error::Http {
        url: format!("http://{addr}"),
        problem: format!("cannot start the server's threads: {e}"),
    };
    let (work, jobs) = sync_channel::<(u64, TcpStream)>(limits.max_connections);
    let jobs = Arc::new(Mutex::new(jobs));
    for i in 0..limits.max_connections {
        let (jobs, shared) = (Arc::clone(&jobs), Arc::clone(shared));
        std::thread::Builder::new()
            .name(format!("serve-{i}"))
            .spawn(move || work_loop(&jobs, &shared))
            .map_err(spawn_failed)?;
    }
    let (refusals, refused) = sync_channel::<TcpStream>(limits.max_connections);
    std::thread::Builder::new()
        .name("serve-refuse".into())
        .spawn(move || {
            for stream in refused {
                answer::refuse(stream, &limits);
            }
        })
        .map_err(spawn_failed)?;
    let shared = Arc::clone(shared);
    std::thread::Builder::new()
        .name("serve-accept".into())
        .spawn(move || accept_loop(&listener, &shared, &work, &refusals))
        .map_err(spawn_failed)
}

/// Accepts connections until the server stops: each goes to a worker when one is free, or to
/// the refuser (503) when all are busy; a connection neither can take is closed.
fn accept_loop(
    listener: &TcpListener,
    shared: &Shared,
    work: &SyncSender<(u64, TcpStream)>,
    refusals: &SyncSender<TcpStream>,
) {
    let ids = AtomicU64::new(0);
    for stream in listener.incoming() {
        if shared.stopping() {
            return;
        }
        let stream = match stream {
            Ok(s) => s,
            Err(_) => {
                // Out of descriptors or a connection reset before accept: never a reason to
                // stop serving; give the system a moment.
                std::thread::sleep(Duration::from_millis(10));
                continue;
            }
        };
        let id = ids.fetch_add(1, Ordering::Relaxed);
        let mut open = shared.open();
        if open.len() >= shared.limits.max_connections {
            drop(open);
            if let Err(TrySendError::Full(s) | TrySendError::Disconnected(s)) =
                refusals.try_send(stream)
            {
                drop(s);
            }
            continue;
        }
        let Ok(clone) = stream.try_clone() else {
            continue;
        };
        open.insert(id, clone);
        drop(open);
        if work.send((id, stream)).is_err() {
            return;
        }
    }
}

/// A worker: serves one connection at a time until the accept loop ends.
fn work_loop(jobs: &Mutex<Receiver<(u64, TcpStream)>>, shared: &Shared) {
    loop {
        let job = jobs.lock().unwrap_or_else(PoisonError::into_inner).recv();
        let Ok((id, stream)) = job else { return };
        // A bug in answering one client ends that connection only, never the worker.
        let _ = catch_unwind(AssertUnwindSafe(|| {
            answer::serve_connection(stream, shared)
        }));
        shared.open().remove(&id);
    }
}

/// Sets `TCP_NODELAY` on the listening socket, which Linux passes on to accepted connections.
/// Without it, the last partial segment of an answer on a kept-alive connection waits for the
/// client's delayed ACK: 40 ms per tile on loopback.
#[cfg(unix)]
fn disable_nagle(listener: &TcpListener) {
    use std::os::fd::AsRawFd;
    let one: libc::c_int = 1;
    // SAFETY: a valid socket descriptor and a pointer to a c_int of the size given.
    unsafe {
        libc::setsockopt(
            listener.as_raw_fd(),
            libc::IPPROTO_TCP,
            libc::TCP_NODELAY,
            (&one as *const libc::c_int).cast(),
            std::mem::size_of::<libc::c_int>() as libc::socklen_t,
        );
    }
}

#[cfg(not(unix))]
fn disable_nagle(_listener: &TcpListener) {}
