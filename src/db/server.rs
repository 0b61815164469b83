//! `stripmask serve`: a small static HTTP server for one archive, with byte ranges and an
//! optional simulated link (latency with jitter, bandwidth, drops) for experiments.
//!
//! It answers `GET` and `HEAD` for `/` and `/<file name>` only; every other path is 404 and
//! every other method 405, so nothing but the archive can be read (no listing, no traversal).
//! `Range: bytes=a-b`, `bytes=a-` and `bytes=-n` give 206 with `Content-Range`; an unsatisfiable
//! range gives 416; a request without a (single, parseable) range gets the whole file with 200.
//! Every answer waits for its delay (`latency ± jitter`, [`LatencyDice`]) and is paced at the
//! bandwidth per connection; a dropped request (see [`LinkProfile::drop_rate`]) is answered 503.

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::net::{SocketAddr, TcpListener};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::thread::JoinHandle;

use tiny_http::{Header, Method, Request, Response, StatusCode};

use crate::db::archive::ArchiveReader;
use crate::db::source::file::FileSource;
use crate::db::source::throttle::{DropDice, LatencyDice, LinkProfile, PacedReader};
use crate::error::{Error, Result};

/// A running server; dropping it (or [`Server::stop`]) shuts it down.
pub struct Server {
    addr: SocketAddr,
    url: String,
    http: Arc<tiny_http::Server>,
    accept: Option<JoinHandle<()>>,
}

struct Shared {
    path: PathBuf,
    url_path: String,
    profile: LinkProfile,
    dice: DropDice,
    delays: LatencyDice,
}

impl Server {
    /// Serves `archive` (checked to be a valid archive first) on `listen` (port 0 picks a free port) over a link shaped by `profile`.
    pub fn start(archive: &Path, listen: SocketAddr, profile: LinkProfile) -> Result<Server> {
        let name = archive.display().to_string();
        // Refuse anything that is not a readable archive (checks the header and the index).
        ArchiveReader::open(FileSource::open(archive)?)?;
        let file_name = archive
            .file_name()
            .and_then(|n| n.to_str())
            .filter(|n| {
                n.bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b"._-".contains(&b))
            })
            .ok_or_else(|| {
                Error::invalid(
                    &name,
                    "serve needs a file name of ASCII letters, digits, '.', '_' or '-'",
                )
            })?
            .to_string();
        let cannot_listen = |e: String| Error::Http {
            url: format!("http://{listen}"),
            problem: format!("cannot listen: {e}"),
        };
        let listener = TcpListener::bind(listen).map_err(|e| cannot_listen(e.to_string()))?;
        disable_nagle(&listener);
        let http = tiny_http::Server::from_listener(listener, None)
            .map_err(|e| cannot_listen(e.to_string()))?;
        let addr = http.server_addr().to_ip().ok_or_else(|| Error::Http {
            url: format!("http://{listen}"),
            problem: "not an IP listener".into(),
        })?;
        let http = Arc::new(http);
        let shared = Arc::new(Shared {
            path: archive.to_path_buf(),
            url_path: format!("/{file_name}"),
            dice: DropDice::new(profile.drop_rate, profile.seed),
            delays: LatencyDice::new(&profile),
            profile,
        });
        let accept = {
            let http = Arc::clone(&http);
            std::thread::spawn(move || {
                for request in http.incoming_requests() {
                    let shared = Arc::clone(&shared);
                    std::thread::spawn(move || answer(request, &shared));
                }
            })
        };
        Ok(Server {
            addr,
            url: format!("http://{addr}/{file_name}"),
            http,
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

    /// Stops accepting requests and waits for the accept loop to end.
    pub fn stop(self) {
        drop(self);
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        self.http.unblock();
        if let Some(handle) = self.accept.take() {
            let _ = handle.join();
        }
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

fn header(name: &str, value: &str) -> Header {
    Header::from_bytes(name.as_bytes(), value.as_bytes()).expect("valid header")
}

fn plain(status: u16, text: &str) -> Response<std::io::Cursor<Vec<u8>>> {
    Response::from_string(text)
        .with_status_code(StatusCode(status))
        .with_header(header("Content-Type", "text/plain; charset=utf-8"))
}

/// What a `Range` header asks of a file.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RangeRequest {
    /// No usable single range: send the whole file.
    Whole,
    /// Bytes `first ..= last`.
    Part(u64, u64),
    /// A range that starts past the end: 416.
    Unsatisfiable,
}

/// Parses a `Range` header value against a file of `len` bytes.
pub fn parse_range(value: &str, len: u64) -> RangeRequest {
    parse_single_range(value, len).unwrap_or(RangeRequest::Whole)
}

fn parse_single_range(value: &str, len: u64) -> Option<RangeRequest> {
    let spec = value.trim().strip_prefix("bytes=")?;
    if spec.contains(',') {
        return None;
    }
    let (a, b) = spec.split_once('-')?;
    let (a, b) = (a.trim(), b.trim());
    let range = if a.is_empty() {
        let n = b.parse::<u64>().ok()?;
        if n == 0 || len == 0 {
            return Some(RangeRequest::Unsatisfiable);
        }
        (len.saturating_sub(n), len - 1)
    } else {
        let first = a.parse::<u64>().ok()?;
        let last = if b.is_empty() {
            len.saturating_sub(1)
        } else {
            match b.parse::<u64>() {
                Ok(l) if l >= first => l.min(len.saturating_sub(1)),
                _ => return None,
            }
        };
        if first >= len {
            return Some(RangeRequest::Unsatisfiable);
        }
        (first, last)
    };
    Some(RangeRequest::Part(range.0, range.1))
}

fn answer(request: Request, shared: &Shared) {
    let path = request.url().split('?').next().unwrap_or("");
    if path != "/" && path != shared.url_path {
        let _ = request.respond(plain(404, "not found\n"));
        return;
    }
    if !matches!(request.method(), Method::Get | Method::Head) {
        let _ = request
            .respond(plain(405, "only GET and HEAD\n").with_header(header("Allow", "GET, HEAD")));
        return;
    }
    std::thread::sleep(shared.delays.next());
    if shared.dice.roll() {
        let _ = request.respond(plain(503, "dropped by the simulated link\n"));
        return;
    }
    let mut file = match File::open(&shared.path) {
        Ok(f) => f,
        Err(_) => {
            let _ = request.respond(plain(500, "archive unreadable\n"));
            return;
        }
    };
    let len = file.metadata().map(|m| m.len()).unwrap_or(0);
    let range = request
        .headers()
        .iter()
        .find(|h| h.field.equiv("Range"))
        .map(|h| parse_range(h.value.as_str(), len))
        .unwrap_or(RangeRequest::Whole);
    let mut headers = vec![
        header("Content-Type", "application/octet-stream"),
        header("Accept-Ranges", "bytes"),
    ];
    let (status, first, count) = match range {
        RangeRequest::Unsatisfiable => {
            let _ = request.respond(
                plain(416, "range not satisfiable\n")
                    .with_header(header("Content-Range", &format!("bytes */{len}"))),
            );
            return;
        }
        RangeRequest::Whole => (200, 0, len),
        RangeRequest::Part(a, b) => {
            headers.push(header("Content-Range", &format!("bytes {a}-{b}/{len}")));
            (206, a, b - a + 1)
        }
    };
    if file.seek(SeekFrom::Start(first)).is_err() {
        let _ = request.respond(plain(500, "archive unreadable\n"));
        return;
    }
    let body = PacedReader::new(file.take(count), &shared.profile);
    // Always a Content-Length: tiny_http switches to chunked encoding above 32 KiB, and a HEAD
    // answer would then not say how long the archive is.
    let response = Response::new(
        StatusCode(status),
        headers,
        body,
        Some(count as usize),
        None,
    )
    .with_chunked_threshold(usize::MAX);
    let _ = request.respond(response);
}

#[cfg(test)]
mod tests {
    use super::{RangeRequest::*, parse_range};

    #[test]
    fn ranges_follow_rfc_9110() {
        assert_eq!(parse_range("bytes=0-9", 100), Part(0, 9));
        assert_eq!(parse_range("bytes=90-", 100), Part(90, 99));
        assert_eq!(parse_range("bytes=-10", 100), Part(90, 99));
        assert_eq!(parse_range("bytes=95-200", 100), Part(95, 99));
        assert_eq!(parse_range("bytes=100-", 100), Unsatisfiable);
        assert_eq!(parse_range("bytes=0-1,5-6", 100), Whole);
        assert_eq!(parse_range("items=0-1", 100), Whole);
        assert_eq!(parse_range("bytes=5-1", 100), Whole);
    }
}
