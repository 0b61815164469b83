//! The HTTP client (ureq) of `HttpSource`: the behaviour the parent module describes.

use std::io::Read;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use super::HttpOptions;
use crate::db::source::{CancelToken, TileSource, cancelled};
use crate::error::{Error, Result};

/// The most of a body read at once: a cancelled read stops within one piece.
pub const BODY_PIECE: usize = 8 * 1024;

/// A cancelled read with fewer bytes than this still to come runs to its end. Stopping closes
/// the connection, so the next request pays for a new one, and what the server has already
/// pushed into the socket buffers arrives whatever the client does: on the paper's line (1
/// Mbit/s, 50 ms) a new connection and its request take two round trips before the first
/// byte, in which 12.5 kB would have arrived, more with TLS. 16 KiB (130 ms at 1 Mbit/s) is
/// about what reconnecting costs, so a smaller rest is cheaper to finish.
pub const FINISH_BELOW: u64 = 16 * 1024;

impl HttpOptions {
    /// The time a request starting now may take, and whether the deadline set it.
    fn budget(&self) -> (Duration, bool) {
        match self.deadline {
            Some(at) => {
                let left = at.saturating_duration_since(Instant::now());
                if left < self.timeout {
                    (left, true)
                } else {
                    (self.timeout, false)
                }
            }
            None => (self.timeout, false),
        }
    }
}

/// An archive at an HTTP URL. The server must answer range requests with 206.
pub struct HttpSource {
    url: String,
    agent: ureq::Agent,
    options: HttpOptions,
    /// The archive opened, from the first answer.
    pinned: OnceLock<Pinned>,
    /// What showed that the archive changed, once something did.
    changed: OnceLock<String>,
}

/// What identifies the archive a source opened: its size and the server's validators.
#[derive(Clone, Debug, PartialEq, Eq)]
struct Pinned {
    len: u64,
    etag: Option<String>,
    last_modified: Option<String>,
}

impl Pinned {
    /// What an answer says of the archive, given its total size.
    fn of(len: u64, response: &ureq::http::Response<ureq::Body>) -> Self {
        let header = |name: &str| {
            response
                .headers()
                .get(name)
                .and_then(|v| v.to_str().ok())
                .map(|v| v.trim().to_string())
        };
        Pinned {
            len,
            etag: header("etag"),
            last_modified: header("last-modified"),
        }
    }

    /// How `seen` differs from this, in words; `None` when it describes the same archive (a
    /// validator the answer leaves out tells nothing).
    fn difference(&self, seen: &Pinned) -> Option<String> {
        if seen.len != self.len {
            return Some(format!(
                "its size went from {} to {} bytes",
                self.len, seen.len
            ));
        }
        for (name, before, now) in [
            ("ETag", &self.etag, &seen.etag),
            ("Last-Modified", &self.last_modified, &seen.last_modified),
        ] {
            if let (Some(before), Some(now)) = (before, now)
                && before != now
            {
                return Some(format!("its {name} went from {before} to {now}"));
            }
        }
        None
    }

    /// The precondition a range request sends: `If-Match` with a strong `ETag` (a weak one
    /// never matches by strong comparison), else `If-Unmodified-Since` with `Last-Modified`.
    fn precondition(&self) -> Option<(&'static str, &str)> {
        match (&self.etag, &self.last_modified) {
            (Some(etag), _) if !etag.starts_with("W/") => Some(("If-Match", etag)),
            (_, Some(date)) => Some(("If-Unmodified-Since", date)),
            _ => None,
        }
    }
}

/// The first, last and total of a `Content-Range: bytes a-b/total` value.
fn content_range(value: &str) -> Option<(u64, u64, u64)> {
    let (range, total) = value.trim().strip_prefix("bytes ")?.split_once('/')?;
    let (first, last) = range.split_once('-')?;
    Some((
        first.trim().parse().ok()?,
        last.trim().parse().ok()?,
        total.trim().parse().ok()?,
    ))
}

impl HttpSource {
    /// A source for `url` with the default [`HttpOptions`]; nothing is fetched until the first
    /// read.
    pub fn new(url: &str) -> Self {
        Self::with_options(url, HttpOptions::default())
    }

    /// A source for `url` whose requests end as `options` say.
    pub fn with_options(url: &str, options: HttpOptions) -> Self {
        let agent = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .build()
            .into();
        HttpSource {
            url: url.to_string(),
            agent,
            options,
            pinned: OnceLock::new(),
            changed: OnceLock::new(),
        }
    }

    fn error(&self, problem: impl Into<String>) -> Error {
        Error::Http {
            url: self.url.clone(),
            problem: problem.into(),
        }
    }

    /// The [`Error::ArchiveChanged`] of this source, after the first thing that showed the
    /// change (`what`, when nothing did before).
    fn changed(&self, what: String) -> Error {
        Error::ArchiveChanged {
            name: self.url.clone(),
            what: self.changed.get_or_init(|| what).clone(),
        }
    }

    /// The error of a source whose archive is known to have changed.
    fn refuse_changed(&self) -> Result<()> {
        match self.changed.get() {
            Some(what) => Err(self.changed(what.clone())),
            None => Ok(()),
        }
    }

    /// Pins `seen` when nothing is pinned yet, or checks it against what is.
    fn pin(&self, seen: Pinned) -> Result<u64> {
        let pinned = self.pinned.get_or_init(|| seen.clone());
        match pinned.difference(&seen) {
            Some(what) => Err(self.changed(what)),
            None => Ok(pinned.len),
        }
    }

    /// Checks a 206 answer for `offset ..= last`: its `Content-Range` must be that range, and
    /// its total and validators those of the archive pinned.
    fn check_part(
        &self,
        response: &ureq::http::Response<ureq::Body>,
        offset: u64,
        last: u64,
    ) -> Result<()> {
        let range = response
            .headers()
            .get("content-range")
            .and_then(|v| v.to_str().ok())
            .ok_or_else(|| self.error("a 206 answer without Content-Range"))?;
        let (first, end, total) = content_range(range)
            .ok_or_else(|| self.error(format!("unreadable Content-Range {range:?}")))?;
        self.pin(Pinned::of(total, response))?;
        if (first, end) != (offset, last) {
            return Err(self.error(format!(
                "asked for bytes {offset}-{last}, the answer holds {first}-{end}"
            )));
        }
        Ok(())
    }

    /// The time `request` may take, or the error of a deadline already past.
    fn budget(&self, request: &str) -> Result<(Duration, bool)> {
        let (time, by_deadline) = self.options.budget();
        if time.is_zero() {
            return Err(self.timed_out(request, time, by_deadline));
        }
        Ok((time, by_deadline))
    }

    fn timed_out(&self, request: &str, time: Duration, by_deadline: bool) -> Error {
        Error::TimedOut {
            url: self.url.clone(),
            request: request.to_string(),
            seconds: (time.as_secs_f64() * 10.0).round() / 10.0,
            by_deadline,
        }
    }

    /// The error of a failed call or body read: a timeout as [`Error::TimedOut`], anything
    /// else as [`Error::Http`] with `what` failed.
    fn failed(&self, request: &str, budget: (Duration, bool), e: ureq::Error) -> Error {
        let timed_out = match &e {
            ureq::Error::Timeout(_) => true,
            ureq::Error::Io(io) => matches!(
                io.kind(),
                std::io::ErrorKind::TimedOut | std::io::ErrorKind::WouldBlock
            ),
            _ => false,
        };
        if timed_out {
            self.timed_out(request, budget.0, budget.1)
        } else {
            self.error(format!("{request} failed: {e}"))
        }
    }
}

impl TileSource for HttpSource {
    fn name(&self) -> &str {
        &self.url
    }

    fn is_remote(&self) -> bool {
        true
    }

    fn size(&self) -> Result<u64> {
        if let Some(pinned) = self.pinned.get() {
            return Ok(pinned.len);
        }
        let budget = self.budget("HEAD")?;
        let response = self
            .agent
            .head(&self.url)
            .config()
            .timeout_global(Some(budget.0))
            .build()
            .call()
            .map_err(|e| self.failed("HEAD", budget, e))?;
        let status = response.status().as_u16();
        if status != 200 {
            return Err(self.error(format!("HEAD answered status {status}")));
        }
        let len = response
            .headers()
            .get("content-length")
            .and_then(|v| v.to_str().ok())
            .and_then(|v| v.trim().parse::<u64>().ok())
            .ok_or_else(|| self.error("HEAD answer has no Content-Length"))?;
        self.pin(Pinned::of(len, &response))
    }

    fn read_range(&self, offset: u64, len: u64) -> Result<Vec<u8>> {
        self.read_range_cancellable(offset, len, &CancelToken::new())
    }

    /// Reads the body [`BODY_PIECE`] bytes at a time and, once `cancel` is raised with at
    /// least [`FINISH_BELOW`] bytes still to come, stops: the response is dropped unread, which
    /// closes its connection (ureq returns a connection to its pool only after a whole body),
    /// so the server stops sending.
    fn read_range_cancellable(
        &self,
        offset: u64,
        len: u64,
        cancel: &CancelToken,
    ) -> Result<Vec<u8>> {
        if len == 0 {
            return Ok(Vec::new());
        }
        let last = offset
            .checked_add(len - 1)
            .ok_or_else(|| self.error("range overflows"))?;
        if cancel.is_cancelled() {
            return Err(cancelled(&self.url, offset, len, 0));
        }
        self.refuse_changed()?;
        let request = format!("GET bytes {offset}-{last}");
        let budget = self.budget(&request)?;
        let mut call = self
            .agent
            .get(&self.url)
            .config()
            .timeout_global(Some(budget.0))
            .build()
            .header("Range", &format!("bytes={offset}-{last}"));
        let precondition = self.pinned.get().and_then(Pinned::precondition);
        if let Some((name, value)) = precondition {
            call = call.header(name, value);
        }
        let mut response = call.call().map_err(|e| self.failed(&request, budget, e))?;
        let status = response.status().as_u16();
        match status {
            206 => self.check_part(&response, offset, last)?,
            412 => {
                let (name, value) = precondition.unwrap_or(("a precondition", ""));
                return Err(self.changed(format!("the server answered 412 to {name}: {value}")));
            }
            200 => {
                return Err(self.error(
                    "the server ignored the Range header (status 200); it must support range requests",
                ));
            }
            416 => {
                let total = response
                    .headers()
                    .get("content-range")
                    .and_then(|v| v.to_str().ok())
                    .and_then(|v| v.trim().strip_prefix("bytes */"))
                    .and_then(|v| v.parse::<u64>().ok());
                if let Some(total) = total {
                    self.pin(Pinned::of(total, &response))?;
                }
                return Err(self.error(format!(
                    "truncated: bytes {offset}-{last} are past the end (status 416)"
                )));
            }
            other => return Err(self.error(format!("{request}: status {other}"))),
        }
        let mut reader = response.body_mut().with_config().limit(len + 1).reader();
        let mut body = Vec::with_capacity(len.min(BODY_PIECE as u64 * 64) as usize);
        let mut piece = vec![0; BODY_PIECE];
        loop {
            let left = len.saturating_sub(body.len() as u64);
            if cancel.is_cancelled() && left >= FINISH_BELOW {
                return Err(cancelled(&self.url, offset, len, body.len() as u64));
            }
            match reader.read(&mut piece) {
                Ok(0) => break,
                Ok(n) => body.extend_from_slice(&piece[..n]),
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(self.failed(&request, budget, ureq::Error::from(e))),
            }
        }
        if body.len() as u64 != len {
            return Err(self.error(format!(
                "asked for {len} bytes at {offset}, received {}",
                body.len()
            )));
        }
        Ok(body)
    }
}
