//! Reading one HTTP/1.x request head from a connection, bounded in size and in time, so that a
//! client can neither make the server hold a huge header nor keep a worker waiting forever.

use std::io::{self, BufRead, BufReader, Read};
use std::net::TcpStream;
use std::time::{Duration, Instant};

/// A request head: what the server needs of it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(super) struct Head {
    /// The method, as sent (`GET`, `HEAD`, ...).
    pub(super) method: String,
    /// The request target's path, query removed.
    pub(super) path: String,
    /// The `Range` header's value, when there is one.
    pub(super) range: Option<String>,
    /// Whether the client wants the connection kept open after the answer.
    pub(super) keep_alive: bool,
    /// Whether a body follows the head (the server reads none, so the connection must close).
    pub(super) has_body: bool,
}

/// Why no head could be read.
#[derive(Debug)]
pub(super) enum HeadError {
    /// The connection closed (or timed out) before the first byte of a request: nothing to answer.
    Closed,
    /// The head took longer than allowed to arrive: 408.
    TimedOut,
    /// The head is larger than allowed: 431.
    TooLarge,
    /// Not an HTTP/1.x request head: 400.
    Malformed,
}

/// A socket reader whose every read ends at one deadline: a client that trickles bytes cannot
/// stretch a read past it, however slowly it sends.
pub(super) struct DeadlineReader {
    stream: TcpStream,
    deadline: Instant,
}

impl DeadlineReader {
    /// Reads `stream` with no deadline set yet (one is set before each head).
    pub(super) fn new(stream: TcpStream) -> Self {
        DeadlineReader {
            stream,
            deadline: Instant::now(),
        }
    }

    /// The socket, for writing answers.
    pub(super) fn stream(&self) -> &TcpStream {
        &self.stream
    }
}

impl Read for DeadlineReader {
    fn read(&mut self, buf: &mut [u8]) -> io::Result<usize> {
        let left = self.deadline.saturating_duration_since(Instant::now());
        if left < Duration::from_millis(1) {
            return Err(io::ErrorKind::TimedOut.into());
        }
        self.stream.set_read_timeout(Some(left))?;
        self.stream.read(buf)
    }
}

/// Reads the next request head: it must arrive whole within `timeout` and be at most
/// `max_bytes` long (request line and headers together).
pub(super) fn read_head(
    reader: &mut BufReader<DeadlineReader>,
    max_bytes: usize,
    timeout: Duration,
) -> Result<Head, HeadError> {
    reader.get_mut().deadline = Instant::now() + timeout;
    let mut lines = Vec::new();
    let mut total = 0usize;
    loop {
        let mut line = Vec::new();
        let limit = (max_bytes - total) as u64;
        let read = reader.by_ref().take(limit).read_until(b'\n', &mut line);
        match read {
            Ok(0) if lines.is_empty() && line.is_empty() => return Err(HeadError::Closed),
            Ok(_) => {}
            Err(e) if lines.is_empty() && line.is_empty() && is_timeout(&e) => {
                return Err(HeadError::Closed);
            }
            Err(e) if is_timeout(&e) => return Err(HeadError::TimedOut),
            Err(_) => return Err(HeadError::Closed),
        }
        total += line.len();
        if line.last() != Some(&b'\n') {
            return Err(if total >= max_bytes {
                HeadError::TooLarge
            } else if lines.is_empty() && line.is_empty() {
                HeadError::Closed
            } else {
                HeadError::Malformed
            });
        }
        while matches!(line.last(), Some(b'\n' | b'\r')) {
            line.pop();
        }
        // Empty lines before the request line are allowed (RFC 9112 section 2.2).
        if line.is_empty() && lines.is_empty() {
            continue;
        }
        if line.is_empty() {
            break;
        }
        lines.push(String::from_utf8(line).map_err(|_| HeadError::Malformed)?);
    }
    parse(&lines).ok_or(HeadError::Malformed)
}

fn is_timeout(e: &io::Error) -> bool {
    matches!(
        e.kind(),
        io::ErrorKind::TimedOut | io::ErrorKind::WouldBlock
    )
}

/// The head of `lines`: the request line, then `Name: value` headers.
fn parse(lines: &[String]) -> Option<Head> {
    let (request, headers) = lines.split_first()?;
    let mut parts = request.split(' ');
    let (method, target, version) = (parts.next()?, parts.next()?, parts.next()?);
    if parts.next().is_some() || method.is_empty() || !target.starts_with('/') {
        return None;
    }
    let http11 = match version {
        "HTTP/1.1" => true,
        "HTTP/1.0" => false,
        _ => return None,
    };
    let mut head = Head {
        method: method.to_string(),
        path: target.split('?').next().unwrap_or("").to_string(),
        range: None,
        keep_alive: http11,
        has_body: false,
    };
    for line in headers {
        let (name, value) = line.split_once(':')?;
        let value = value.trim();
        if name.eq_ignore_ascii_case("range") {
            head.range = Some(value.to_string());
        } else if name.eq_ignore_ascii_case("connection") {
            let has = |token: &str| {
                value
                    .split(',')
                    .any(|t| t.trim().eq_ignore_ascii_case(token))
            };
            if has("close") {
                head.keep_alive = false;
            } else if has("keep-alive") {
                head.keep_alive = true;
            }
        } else if name.eq_ignore_ascii_case("transfer-encoding") {
            head.has_body = true;
        } else if name.eq_ignore_ascii_case("content-length") {
            head.has_body |= value != "0";
        }
    }
    Some(head)
}

#[cfg(test)]
mod tests {
    use super::parse;

    fn lines(text: &str) -> Vec<String> {
        text.lines().map(str::to_string).collect()
    }

    #[test]
    fn heads_parse_and_malformed_ones_do_not() {
        let h = parse(&lines(
            "GET /a.smdb?x=1 HTTP/1.1\nRange: bytes=0-9\nHost: h",
        ))
        .unwrap();
        assert_eq!((h.method.as_str(), h.path.as_str()), ("GET", "/a.smdb"));
        assert_eq!(h.range.as_deref(), Some("bytes=0-9"));
        assert!(h.keep_alive && !h.has_body);
        let h = parse(&lines("HEAD / HTTP/1.0")).unwrap();
        assert!(!h.keep_alive);
        let h = parse(&lines("GET / HTTP/1.1\nConnection: Close")).unwrap();
        assert!(!h.keep_alive);
        let h = parse(&lines("POST / HTTP/1.1\ncontent-length: 1")).unwrap();
        assert!(h.has_body);
        for bad in [
            "GET /",
            "GET / HTTP/2",
            "GET x HTTP/1.1",
            "GET / HTTP/1.1\nnocolon",
        ] {
            assert!(parse(&lines(bad)).is_none(), "{bad}");
        }
    }
}
