//! An archive behind any static HTTP server, read with `Range: bytes=a-b` requests (ureq).
//!
//! Every request, connection and whole body included, ends within [`HttpOptions::timeout`]
//! and never after [`HttpOptions::deadline`]: a server that accepts and never answers, or stops
//! in the middle of a body, costs one timeout, and a run with a deadline ends on time. The
//! source itself never retries; the reader and the pager do, backing off ([`crate::db::backoff`]).
//! A read whose [`CancelToken`] is raised stops between pieces of its body and closes its
//! connection, unless less than [`FINISH_BELOW`] bytes are left.

use std::io::Read;
use std::sync::OnceLock;
use std::time::{Duration, Instant};

use super::{CancelToken, TileSource, cancelled};
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

/// How long requests may take.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct HttpOptions {
    /// The time limit of one request: connecting, the answer's head and its whole body.
    pub timeout: Duration,
    /// The instant by which every request must have ended, whatever its timeout: a request
    /// that would outlive it is cut short there, and one asked for after it fails at once.
    pub deadline: Option<Instant>,
}

impl Default for HttpOptions {
    /// Ten seconds a request, no deadline.
    fn default() -> Self {
        HttpOptions {
            timeout: Duration::from_secs(10),
            deadline: None,
        }
    }
}

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
    len: OnceLock<u64>,
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
            len: OnceLock::new(),
        }
    }

    fn error(&self, problem: impl Into<String>) -> Error {
        Error::Http {
            url: self.url.clone(),
            problem: problem.into(),
        }
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
        if let Some(&len) = self.len.get() {
            return Ok(len);
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
        Ok(*self.len.get_or_init(|| len))
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
        let request = format!("GET bytes {offset}-{last}");
        let budget = self.budget(&request)?;
        let mut response = self
            .agent
            .get(&self.url)
            .config()
            .timeout_global(Some(budget.0))
            .build()
            .header("Range", &format!("bytes={offset}-{last}"))
            .call()
            .map_err(|e| self.failed(&request, budget, e))?;
        let status = response.status().as_u16();
        match status {
            206 => {}
            200 => {
                return Err(self.error(
                    "the server ignored the Range header (status 200); it must support range requests",
                ));
            }
            416 => {
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
