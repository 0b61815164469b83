//! `stripmask serve` against clients that try to stop it: a flood of pipelined requests, a huge
//! request head, a head that never ends, and a link it cannot simulate. Every test talks to a
//! `serve` process on 127.0.0.1 and ends in bounded time (many connections at once:
//! `serve_attacks`).

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use crate::support::cli::{plain_archive, run_bounded, stripmask};

fn archive(dir: &Path) -> PathBuf {
    let out = dir.join("plain.smdb");
    plain_archive(&out);
    out
}

/// A `serve` process, killed when dropped.
struct Serve {
    child: Child,
    addr: String,
    path: String,
}

impl Serve {
    fn start(archive: &Path, extra: &[&str]) -> Serve {
        let mut child = stripmask()
            .arg("serve")
            .arg(archive)
            .args(extra)
            .stdout(Stdio::piped())
            .spawn()
            .unwrap();
        let mut url = String::new();
        BufReader::new(child.stdout.take().unwrap())
            .read_line(&mut url)
            .unwrap();
        let rest = url.trim().strip_prefix("http://").unwrap().to_string();
        let (addr, path) = rest.split_once('/').unwrap();
        Serve {
            addr: addr.to_string(),
            path: format!("/{path}"),
            child,
        }
    }

    fn connect(&self) -> TcpStream {
        let s = TcpStream::connect(&self.addr).unwrap();
        s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
        s
    }

    /// The status of one GET of bytes 0-9 on a new connection.
    fn status(&self) -> u16 {
        let mut s = self.connect();
        let request = format!(
            "GET {} HTTP/1.1\r\nHost: x\r\nRange: bytes=0-9\r\nConnection: close\r\n\r\n",
            self.path
        );
        s.write_all(request.as_bytes()).unwrap();
        status_of(&mut s)
    }

    fn threads(&self) -> usize {
        let status = std::fs::read_to_string(format!("/proc/{}/status", self.child.id())).unwrap();
        status
            .lines()
            .find_map(|l| l.strip_prefix("Threads:"))
            .unwrap()
            .trim()
            .parse()
            .unwrap()
    }

    fn alive(&mut self) -> bool {
        self.child.try_wait().unwrap().is_none()
    }
}

impl Drop for Serve {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The status code of the answer on `s` (0 when the connection ends without one).
fn status_of(s: &mut TcpStream) -> u16 {
    let mut line = String::new();
    let _ = BufReader::new(s).read_line(&mut line);
    line.split(' ')
        .nth(1)
        .and_then(|c| c.parse().ok())
        .unwrap_or(0)
}

#[cfg(target_os = "linux")]
#[test]
fn pipelined_requests_take_no_new_threads_and_the_server_lives_on() {
    let dir = tempfile::tempdir().unwrap();
    let mut serve = Serve::start(&archive(dir.path()), &[]);
    assert_eq!(serve.status(), 206);
    let idle = serve.threads();

    let s = serve.connect();
    let request = format!(
        "HEAD {} HTTP/1.1\r\nHost: x\r\nRange: bytes=0-9\r\n\r\n",
        serve.path
    );
    let mut w = s.try_clone().unwrap();
    let writer = std::thread::spawn(move || {
        let all = request.repeat(2000);
        let _ = w.write_all(all.as_bytes());
    });
    let mut peak = idle;
    let mut answers = 0;
    for line in BufReader::new(s).lines() {
        let Ok(line) = line else { break };
        if line.starts_with("HTTP/1.1 ") {
            answers += 1;
            if answers % 50 == 0 {
                peak = peak.max(serve.threads());
            }
        }
    }
    writer.join().unwrap();
    assert!(answers >= 1000, "{answers} answers");
    assert_eq!(peak, idle, "threads grew with pipelined requests");
    assert!(serve.alive());
    assert_eq!(serve.status(), 206);
}

#[test]
fn a_huge_request_head_is_refused_with_431() {
    let dir = tempfile::tempdir().unwrap();
    let serve = Serve::start(&archive(dir.path()), &[]);
    let mut s = serve.connect();
    let mut w = s.try_clone().unwrap();
    let head = format!(
        "GET {} HTTP/1.1\r\nX-Big: {}\r\n\r\n",
        serve.path,
        "a".repeat(1 << 20)
    );
    let writer = std::thread::spawn(move || {
        let _ = w.write_all(head.as_bytes());
    });
    assert_eq!(status_of(&mut s), 431);
    writer.join().unwrap();
    assert_eq!(serve.status(), 206);
}

#[test]
fn a_request_head_that_never_ends_is_timed_out() {
    let dir = tempfile::tempdir().unwrap();
    let serve = Serve::start(&archive(dir.path()), &[]);
    let mut s = serve.connect();
    s.set_read_timeout(Some(Duration::from_millis(500)))
        .unwrap();
    let start = Instant::now();
    s.write_all(format!("GET {} HTTP/1.1\r\n", serve.path).as_bytes())
        .unwrap();
    let mut buf = [0u8; 64];
    // One header byte every half second, forever; the server must end it.
    let ended = loop {
        assert!(
            start.elapsed() < Duration::from_secs(30),
            "a trickling client was never timed out"
        );
        if s.write_all(b"X").is_err() {
            break String::new();
        }
        match s.read(&mut buf) {
            Ok(0) => break String::new(),
            Ok(n) => break String::from_utf8_lossy(&buf[..n]).into_owned(),
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => {}
            Err(_) => break String::new(),
        }
    };
    assert!(
        ended.is_empty() || ended.starts_with("HTTP/1.1 408"),
        "{ended}"
    );
    assert_eq!(serve.status(), 206);
}

#[test]
fn a_link_serve_cannot_simulate_is_a_usage_error() {
    for (flag, value) in [
        ("--bandwidth-kbps", "1e-300"),
        ("--bandwidth-kbps", "inf"),
        ("--bandwidth-kbps", "nan"),
        ("--max-connections", "0"),
    ] {
        let (code, err) = run_bounded(&["serve", "Cargo.toml", flag, value]);
        assert_eq!(code, Some(2), "{flag} {value}: {err}");
        assert!(err.contains(flag), "{err}");
    }
}
