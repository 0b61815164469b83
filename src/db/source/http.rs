//! An archive behind any static HTTP server, read with `Range: bytes=a-b` requests (ureq).

use std::sync::OnceLock;
use std::time::Duration;

use super::TileSource;
use crate::error::{Error, Result};

/// The time limit of one request, connection included.
const REQUEST_TIMEOUT: Duration = Duration::from_secs(30);

/// An archive at an HTTP URL. The server must answer range requests with 206.
pub struct HttpSource {
    url: String,
    agent: ureq::Agent,
    len: OnceLock<u64>,
}

impl HttpSource {
    /// A source for `url`; nothing is fetched until the first read.
    pub fn new(url: &str) -> Self {
        let agent = ureq::Agent::config_builder()
            .http_status_as_error(false)
            .timeout_global(Some(REQUEST_TIMEOUT))
            .build()
            .into();
        HttpSource {
            url: url.to_string(),
            agent,
            len: OnceLock::new(),
        }
    }

    fn error(&self, problem: impl Into<String>) -> Error {
        Error::Http {
            url: self.url.clone(),
            problem: problem.into(),
        }
    }
}

impl TileSource for HttpSource {
    fn name(&self) -> &str {
        &self.url
    }

    fn size(&self) -> Result<u64> {
        if let Some(&len) = self.len.get() {
            return Ok(len);
        }
        let response = self
            .agent
            .head(&self.url)
            .call()
            .map_err(|e| self.error(format!("HEAD failed: {e}")))?;
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
        if len == 0 {
            return Ok(Vec::new());
        }
        let last = offset
            .checked_add(len - 1)
            .ok_or_else(|| self.error("range overflows"))?;
        let mut response = self
            .agent
            .get(&self.url)
            .header("Range", &format!("bytes={offset}-{last}"))
            .call()
            .map_err(|e| self.error(format!("GET bytes {offset}-{last} failed: {e}")))?;
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
            other => return Err(self.error(format!("GET bytes {offset}-{last}: status {other}"))),
        }
        let body = response
            .body_mut()
            .with_config()
            .limit(len + 1)
            .read_to_vec()
            .map_err(|e| self.error(format!("reading bytes {offset}-{last}: {e}")))?;
        if body.len() as u64 != len {
            return Err(self.error(format!(
                "asked for {len} bytes at {offset}, received {}",
                body.len()
            )));
        }
        Ok(body)
    }
}
