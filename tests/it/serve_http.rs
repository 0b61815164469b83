//! `serve` speaks HTTP/1.1 as RFC 9110 and 9112 say: answers to `HEAD` carry no body whatever
//! their status (so kept-alive connections stay in step), header lines the RFC rejects are
//! answered 400 and nothing after them is taken for a request, every answer about the archive
//! carries its validators, and conditional requests (`If-Match`, `If-None-Match`,
//! `If-Modified-Since`, `If-Range`) are honoured. Every test talks to a server on 127.0.0.1.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::path::{Path, PathBuf};
use std::time::Duration;

use stripmask::db::server::Server;
use stripmask::db::source::throttle::LinkProfile;

use crate::support::cli::plain_archive;

fn archive(dir: &Path) -> PathBuf {
    let out = dir.join("plain.smdb");
    plain_archive(&out);
    out
}

fn serve(archive: &Path, profile: LinkProfile) -> Server {
    let loopback: SocketAddr = "127.0.0.1:0".parse().unwrap();
    Server::start(archive, loopback, profile).unwrap()
}

fn path_of(server: &Server) -> String {
    let url = server.url();
    url[url.rfind('/').unwrap()..].to_string()
}

fn connect(server: &Server) -> TcpStream {
    let s = TcpStream::connect(server.addr()).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
    s
}

/// One answer read off a connection: its status, headers (names in lower case) and body.
#[derive(Debug)]
struct Answer {
    status: u16,
    headers: Vec<(String, String)>,
    body: Vec<u8>,
}

impl Answer {
    /// The next answer on `r`, to a request that was a `HEAD` or not; `None` at the end.
    fn read(r: &mut impl BufRead, to_head: bool) -> Option<Answer> {
        let mut line = String::new();
        if r.read_line(&mut line).ok()? == 0 {
            return None;
        }
        let status = line.split(' ').nth(1)?.parse().ok()?;
        let mut headers = Vec::new();
        loop {
            let mut line = String::new();
            r.read_line(&mut line).ok()?;
            let line = line.trim_end();
            if line.is_empty() {
                break;
            }
            let (name, value) = line.split_once(':')?;
            headers.push((name.to_ascii_lowercase(), value.trim().to_string()));
        }
        let mut answer = Answer {
            status,
            headers,
            body: Vec::new(),
        };
        if !to_head && status != 304 {
            let len: usize = answer.header("content-length")?.parse().ok()?;
            answer.body = vec![0; len];
            r.read_exact(&mut answer.body).ok()?;
        }
        Some(answer)
    }

    fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }
}

/// Sends `requests` at once on one connection and reads an answer to each, in order.
fn pipelined(server: &Server, requests: &[(&str, &str)]) -> (Vec<Answer>, TcpStream) {
    let mut s = connect(server);
    let all: String = requests
        .iter()
        .map(|(line, headers)| format!("{line} HTTP/1.1\r\nHost: x\r\n{headers}\r\n"))
        .collect();
    s.write_all(all.as_bytes()).unwrap();
    let mut reader = BufReader::new(s.try_clone().unwrap());
    let answers = requests
        .iter()
        .map(|(line, _)| {
            Answer::read(&mut reader, line.starts_with("HEAD"))
                .unwrap_or_else(|| panic!("no answer to {line}"))
        })
        .collect();
    (answers, s)
}

/// Whether anything more than the answers read arrives on `s` within a moment.
fn has_excess(s: &mut TcpStream) -> bool {
    s.set_read_timeout(Some(Duration::from_millis(300)))
        .unwrap();
    matches!(s.read(&mut [0u8; 64]), Ok(n) if n > 0)
}

#[test]
fn head_answers_carry_no_body_whatever_their_status() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path());
    let bytes = std::fs::read(&path).unwrap();
    let len = bytes.len();
    let server = serve(&path, LinkProfile::default());
    let p = path_of(&server);
    let past_end = format!("Range: bytes={len}-\r\n");
    let (answers, mut s) = pipelined(
        &server,
        &[
            ("HEAD /nope", ""),
            (&format!("HEAD {p}"), "If-Match: \"other\"\r\n"),
            (&format!("HEAD {p}"), &past_end),
            (&format!("GET {p}"), &past_end),
            (&format!("POST {p}"), "Content-Length: 0\r\n"),
            (&format!("GET {p}"), "Range: bytes=0-9\r\n"),
        ],
    );
    let statuses: Vec<u16> = answers.iter().map(|a| a.status).collect();
    // HEAD ignores Range (RFC 9110 section 14.2): it describes the whole file.
    assert_eq!(statuses, [404, 412, 200, 416, 405, 206]);
    assert_eq!(answers[2].header("content-length"), Some(&*len.to_string()));
    assert_eq!(answers[5].body, &bytes[..10]);
    assert!(!has_excess(&mut s), "bytes after the last answer");

    // Dropped by the simulated link: 503, with a body for GET only.
    let dead = serve(
        &path,
        LinkProfile {
            drop_rate: 1.0,
            ..LinkProfile::default()
        },
    );
    let p = path_of(&dead);
    let (answers, mut s) = pipelined(
        &dead,
        &[(&format!("HEAD {p}"), ""), (&format!("GET {p}"), "")],
    );
    assert_eq!((answers[0].status, answers[1].status), (503, 503));
    assert!(answers[1].body.starts_with(b"dropped"));
    assert!(!has_excess(&mut s));
}

#[test]
fn header_lines_the_rfc_rejects_are_answered_400_and_nothing_after_them_is_a_request() {
    let dir = tempfile::tempdir().unwrap();
    let server = serve(&archive(dir.path()), LinkProfile::default());
    let p = path_of(&server);
    let smuggled = format!("GET {p} HTTP/1.1\r\nHost: x\r\n\r\n");
    for (what, line) in [
        (
            "whitespace before the colon",
            format!("Content-Length : {}", smuggled.len()),
        ),
        ("an obs-fold", "X-A: a\r\n folded".to_string()),
        ("a bare CR", "X-A: a\rb".to_string()),
        ("a NUL in a name", "X\0A: a".to_string()),
        ("a line without a colon", "X-A a".to_string()),
    ] {
        let mut s = connect(&server);
        let request = format!("GET {p} HTTP/1.1\r\nHost: x\r\n{line}\r\n\r\n{smuggled}");
        s.write_all(request.as_bytes()).unwrap();
        let mut all = String::new();
        let _ = s.read_to_string(&mut all);
        assert!(all.starts_with("HTTP/1.1 400 "), "{what}: {all:?}");
        assert_eq!(all.matches("HTTP/1.1 ").count(), 1, "{what}: {all:?}");
    }
}

#[test]
fn every_answer_about_the_archive_carries_its_validators_and_preconditions_hold() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path());
    let len = std::fs::metadata(&path).unwrap().len();
    let server = serve(&path, LinkProfile::default());
    let p = path_of(&server);
    let (first, _) = pipelined(&server, &[(&format!("HEAD {p}"), "")]);
    let etag = first[0].header("etag").unwrap().to_string();
    let date = first[0].header("last-modified").unwrap().to_string();
    assert!(etag.starts_with('"') && etag.ends_with('"'), "{etag}");
    let cases = [
        ("GET", String::new(), 200),
        ("GET", "Range: bytes=0-9\r\n".to_string(), 206),
        ("GET", format!("Range: bytes={len}-\r\n"), 416),
        ("GET", format!("If-None-Match: {etag}\r\n"), 304),
        ("HEAD", format!("If-None-Match: W/{etag}\r\n"), 304),
        ("GET", format!("If-Modified-Since: {date}\r\n"), 304),
        ("GET", "If-Match: \"other\"\r\n".to_string(), 412),
        ("GET", format!("If-Match: \"other\", {etag}\r\n"), 200),
        (
            "GET",
            "If-Unmodified-Since: Sat, 01 Jan 2000 00:00:00 GMT\r\n".to_string(),
            412,
        ),
    ];
    for (method, headers, status) in cases {
        let line = format!("{method} {p}");
        let (answers, _) = pipelined(&server, &[(&line, &headers)]);
        let a = &answers[0];
        assert_eq!(a.status, status, "{method} {headers:?}");
        assert_eq!(a.header("etag"), Some(&*etag), "{method} {headers:?}");
        assert_eq!(
            a.header("last-modified"),
            Some(&*date),
            "{method} {headers:?}"
        );
        if status == 304 {
            assert!(a.body.is_empty());
        }
    }
}

#[test]
fn if_range_sends_the_range_only_of_the_version_it_names() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path());
    let bytes = std::fs::read(&path).unwrap();
    let server = serve(&path, LinkProfile::default());
    let p = path_of(&server);
    let (first, _) = pipelined(&server, &[(&format!("HEAD {p}"), "")]);
    let etag = first[0].header("etag").unwrap().to_string();
    let date = first[0].header("last-modified").unwrap().to_string();
    for (if_range, status) in [
        (etag.clone(), 206),
        (format!("W/{etag}"), 200),
        ("\"other\"".to_string(), 200),
        (date, 206),
        ("Sat, 01 Jan 2000 00:00:00 GMT".to_string(), 200),
    ] {
        let headers = format!("Range: bytes=5-14\r\nIf-Range: {if_range}\r\n");
        let (answers, _) = pipelined(&server, &[(&format!("GET {p}"), &headers)]);
        let a = &answers[0];
        assert_eq!(a.status, status, "If-Range: {if_range}");
        let expected = if status == 206 {
            &bytes[5..15]
        } else {
            &bytes[..]
        };
        assert_eq!(a.body, expected, "If-Range: {if_range}");
    }
}

#[test]
fn a_replaced_archive_is_served_with_a_new_validator() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path());
    let server = serve(&path, LinkProfile::default());
    let p = path_of(&server);
    let head = format!("HEAD {p}");
    let (before, _) = pipelined(&server, &[(&head, "")]);
    let old = before[0].header("etag").unwrap().to_string();
    // A new build of the same name, renamed into place as builds do.
    let other = dir.path().join("other").join("plain.smdb");
    std::fs::create_dir(other.parent().unwrap()).unwrap();
    plain_archive(&other);
    let mut bytes = std::fs::read(&other).unwrap();
    bytes.extend_from_slice(b"appended");
    std::fs::write(&other, &bytes).unwrap();
    std::fs::rename(&other, &path).unwrap();
    let (after, _) = pipelined(
        &server,
        &[
            (&head, ""),
            (&format!("GET {p}"), &format!("If-Match: {old}\r\n")),
        ],
    );
    assert_ne!(after[0].header("etag"), Some(&*old));
    assert_eq!(
        after[0].header("content-length"),
        Some(&*bytes.len().to_string())
    );
    assert_eq!(after[1].status, 412);
}
