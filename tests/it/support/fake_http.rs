//! The request loop of the fake HTTP servers tests run on loopback: HEAD answered, each range
//! request's head written, its body left to the test's server.

use std::io::{BufRead, Write};

/// Answers requests on `reader` for a file of `len` bytes until a range request comes, whose
/// answer head it writes to `writer`; returns its bytes `a..=b`, or `None` once the client
/// closed the connection (or a write failed).
pub fn next_range(
    reader: &mut impl BufRead,
    writer: &mut impl Write,
    len: usize,
) -> Option<(usize, usize)> {
    loop {
        let mut head = Vec::new();
        loop {
            let mut line = String::new();
            if reader.read_line(&mut line).unwrap_or(0) == 0 {
                return None;
            }
            if line == "\r\n" {
                break;
            }
            head.push(line);
        }
        if head[0].starts_with("HEAD") {
            let answer = format!("HTTP/1.1 200 OK\r\nContent-Length: {len}\r\n\r\n");
            writer.write_all(answer.as_bytes()).ok()?;
            continue;
        }
        let range = head
            .iter()
            .find_map(|l| {
                l.to_ascii_lowercase()
                    .strip_prefix("range: bytes=")
                    .map(String::from)
            })
            .unwrap();
        let (a, b) = range.trim().split_once('-').unwrap();
        let (a, b): (usize, usize) = (a.parse().unwrap(), b.parse().unwrap());
        let answer = format!(
            "HTTP/1.1 206 Partial Content\r\nContent-Length: {}\r\nContent-Range: bytes {a}-{b}/{len}\r\n\r\n",
            b + 1 - a
        );
        writer.write_all(answer.as_bytes()).ok()?;
        return Some((a, b));
    }
}
