//! One connection's life on a worker: request heads read one after the other (pipelined or
//! kept alive), each answered in turn, until the client closes, goes idle, misbehaves or has
//! sent as many requests as one connection may.

use std::fs::File;
use std::io::{self, BufReader, Read, Seek, SeekFrom, Write};
use std::net::TcpStream;

use super::head::{DeadlineReader, Head, HeadError, read_head};
use super::range::{RangeRequest, parse_range};
use super::{Limits, Shared};
use crate::db::source::throttle::PacedReader;

/// Serves `stream` until it is done with; every failure ends only this connection.
pub(super) fn serve_connection(stream: TcpStream, shared: &Shared) {
    let limits = &shared.limits;
    if stream
        .set_write_timeout(Some(limits.write_timeout))
        .is_err()
    {
        return;
    }
    let mut reader = BufReader::with_capacity(limits.max_header_bytes, DeadlineReader::new(stream));
    for served in 1..=limits.max_requests_per_connection {
        if shared.stopping() {
            return;
        }
        let head = match read_head(&mut reader, limits.max_header_bytes, limits.request_timeout) {
            Ok(head) => head,
            Err(HeadError::Closed) => return,
            Err(e) => {
                let (status, text) = match e {
                    HeadError::TimedOut => (408, "request head took too long\n"),
                    HeadError::TooLarge => (431, "request head too large\n"),
                    _ => (400, "malformed request\n"),
                };
                let stream = reader.get_ref().stream();
                let _ = plain(stream, status, text, &[], false);
                close_gracefully(stream, limits.refuse_timeout);
                return;
            }
        };
        let keep = head.keep_alive && !head.has_body && served < limits.max_requests_per_connection;
        match answer(reader.get_ref().stream(), &head, shared, keep) {
            Ok(()) if keep => {}
            Ok(()) => {
                // The client may have pipelined more requests than are answered.
                close_gracefully(reader.get_ref().stream(), limits.refuse_timeout);
                return;
            }
            Err(_) => return,
        }
    }
}

/// Writes the answer to one request.
fn answer(out: &TcpStream, head: &Head, shared: &Shared, keep: bool) -> io::Result<()> {
    if head.path != "/" && head.path != shared.url_path {
        return plain(out, 404, "not found\n", &[], keep);
    }
    let is_head = match head.method.as_str() {
        "GET" => false,
        "HEAD" => true,
        _ => {
            return plain(
                out,
                405,
                "only GET and HEAD\n",
                &[("Allow", "GET, HEAD")],
                keep,
            );
        }
    };
    std::thread::sleep(shared.delays.next());
    if shared.dice.roll() {
        return plain(out, 503, "dropped by the simulated link\n", &[], keep);
    }
    let Ok(mut file) = File::open(&shared.path) else {
        return plain(out, 500, "archive unreadable\n", &[], keep);
    };
    let len = file.metadata().map(|m| m.len()).unwrap_or(0);
    let range = head
        .range
        .as_deref()
        .map(|v| parse_range(v, len))
        .unwrap_or(RangeRequest::Whole);
    let (status, first, count, content_range) = match range {
        RangeRequest::Unsatisfiable => {
            let all = format!("bytes */{len}");
            return plain(
                out,
                416,
                "range not satisfiable\n",
                &[("Content-Range", &all)],
                keep,
            );
        }
        RangeRequest::Whole => (200, 0, len, None),
        RangeRequest::Part(a, b) => (206, a, b - a + 1, Some(format!("bytes {a}-{b}/{len}"))),
    };
    if file.seek(SeekFrom::Start(first)).is_err() {
        return plain(out, 500, "archive unreadable\n", &[], keep);
    }
    let mut extra = vec![
        ("Content-Type", "application/octet-stream"),
        ("Accept-Ranges", "bytes"),
    ];
    if let Some(r) = &content_range {
        extra.push(("Content-Range", r));
    }
    let mut out = io::BufWriter::with_capacity(64 * 1024, out);
    write_head(&mut out, status, count, &extra, keep)?;
    if !is_head {
        let copied = io::copy(
            &mut PacedReader::new(file.take(count), &shared.profile),
            &mut out,
        )?;
        if copied != count {
            // The file shrank under us: the promised length cannot be kept, so end the connection.
            return Err(io::ErrorKind::UnexpectedEof.into());
        }
    }
    out.flush()
}

/// A short plain-text answer.
pub(super) fn plain(
    out: &TcpStream,
    status: u16,
    text: &str,
    extra: &[(&str, &str)],
    keep: bool,
) -> io::Result<()> {
    let mut all = vec![("Content-Type", "text/plain; charset=utf-8")];
    all.extend_from_slice(extra);
    let mut out = io::BufWriter::new(out);
    write_head(&mut out, status, text.len() as u64, &all, keep)?;
    out.write_all(text.as_bytes())?;
    out.flush()
}

fn write_head(
    out: &mut impl Write,
    status: u16,
    content_length: u64,
    headers: &[(&str, &str)],
    keep: bool,
) -> io::Result<()> {
    write!(out, "HTTP/1.1 {status} {}\r\n", reason(status))?;
    for (name, value) in headers {
        write!(out, "{name}: {value}\r\n")?;
    }
    let connection = if keep { "keep-alive" } else { "close" };
    write!(
        out,
        "Content-Length: {content_length}\r\nConnection: {connection}\r\n\r\n"
    )
}

fn reason(status: u16) -> &'static str {
    match status {
        200 => "OK",
        206 => "Partial Content",
        400 => "Bad Request",
        404 => "Not Found",
        405 => "Method Not Allowed",
        408 => "Request Timeout",
        416 => "Range Not Satisfiable",
        431 => "Request Header Fields Too Large",
        500 => "Internal Server Error",
        503 => "Service Unavailable",
        _ => "Error",
    }
}

/// The answer to a connection over [`Limits::max_connections`]: 503 and close, after reading
/// what the client sent (closing with unread bytes would reset the connection and lose the
/// answer), for a short time at most.
pub(super) fn refuse(stream: TcpStream, limits: &Limits) {
    let _ = stream.set_read_timeout(Some(limits.refuse_timeout));
    let _ = stream.set_write_timeout(Some(limits.refuse_timeout));
    let mut head = [0u8; 4096];
    let _ = (&stream).read(&mut head);
    let _ = plain(
        &stream,
        503,
        "too many connections, try again later\n",
        &[("Retry-After", "1")],
        false,
    );
    close_gracefully(&stream, limits.refuse_timeout);
}

/// Ends a connection whose client may still be sending: the answer is out, so stop writing,
/// then read and drop what arrives for a short `while` (closing with unread bytes would reset
/// the connection, and the client could lose the answer before reading it).
fn close_gracefully(mut stream: &TcpStream, within: std::time::Duration) {
    let _ = stream.shutdown(std::net::Shutdown::Write);
    let end = std::time::Instant::now() + within;
    let mut sink = [0u8; 16 * 1024];
    loop {
        let left = end.saturating_duration_since(std::time::Instant::now());
        if left.is_zero() || stream.set_read_timeout(Some(left)).is_err() {
            return;
        }
        match stream.read(&mut sink) {
            Ok(0) | Err(_) => return,
            Ok(_) => {}
        }
    }
}
