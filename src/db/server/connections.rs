//! The open connections: how many there may be, what each is doing, and how long it may take.
//!
//! Each connection is a task on the runtime, so an idle or slow client costs memory (a few
//! kilobytes), never a thread. A connection is always either waiting for a request head, which
//! must arrive whole within [`Limits::request_timeout`] of the connection being ready for it
//! (idle time included), or answering, which must end within [`Limits::time_to_send`]; a
//! watchdog closes it past either. At [`Limits::max_connections`] a new connection closes the
//! one that has waited longest for a request head, so idle and trickling connections can never
//! keep a client out; only when every connection is answering is the new one answered 503.

use std::collections::HashMap;
use std::convert::Infallible;
use std::future::Future;
use std::io;
use std::pin::Pin;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::task::{Context, Poll};
use std::time::Duration;

use bytes::Bytes;
use http_body::{Body as HttpBody, Frame, SizeHint};
use hyper::body::Incoming;
use hyper::header::{self, HeaderValue};
use hyper::server::conn::http1;
use hyper::service::Service;
use hyper::{Method, Request, Response, StatusCode};
use hyper_util::rt::TokioIo;
use tokio::net::TcpStream;
use tokio::sync::watch;
use tokio::time::Instant;

use super::body::{Answer, Body, text};
use super::link::Paced;
use super::{Limits, Shared};

/// Refused connections answered at once at the most; more are closed unanswered.
const MAX_REFUSING: usize = 256;
/// The time a refused connection gets to send its request and read its 503.
const REFUSE_TIME: Duration = Duration::from_secs(1);
/// The time a closing connection gets to send what it still sends before it is closed, so that
/// closing with unread bytes does not reset the connection before the client read its answers.
const LINGER: Duration = Duration::from_secs(1);

/// What a connection is doing.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Waiting for a request head since then.
    Waiting(Instant),
    /// Answering a request: preparing the answer (no deadline: the simulated link's delay is
    /// the server's own), or sending it by the deadline.
    Answering(Option<Instant>),
    /// Closed to make room for a new connection.
    Evicted,
}

/// The open connections and their number.
pub(super) struct Connections {
    /// Open at once, at most.
    cap: usize,
    open: Mutex<Open>,
    refusing: AtomicUsize,
}

/// The open connections by id, and the next id, under one lock.
#[derive(Default)]
struct Open {
    by_id: HashMap<u64, Arc<watch::Sender<State>>>,
    // Under the lock that admitting takes anyway, not an `AtomicU64`, which ARMv5TE lacks.
    next_id: u64,
}

impl Connections {
    /// Room for `cap` connections.
    pub(super) fn new(cap: usize) -> Self {
        Connections {
            cap,
            open: Mutex::new(Open::default()),
            refusing: AtomicUsize::new(0),
        }
    }

    fn open(&self) -> MutexGuard<'_, Open> {
        self.open.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// A slot for a new connection, making room by evicting the connection that has waited
    /// longest for a request head when all are taken; `None` when every one is answering.
    fn admit(self: &Arc<Self>) -> Option<Slot> {
        let mut open = self.open();
        if open.by_id.len() >= self.cap {
            let (_, oldest) = open
                .by_id
                .iter()
                .filter_map(|(id, state)| match *state.borrow() {
                    State::Waiting(since) => Some((since, *id)),
                    _ => None,
                })
                .min()?;
            if let Some(state) = open.by_id.remove(&oldest) {
                state.send_replace(State::Evicted);
            }
        }
        let id = open.next_id;
        open.next_id += 1;
        let state = Arc::new(watch::channel(State::Waiting(Instant::now())).0);
        open.by_id.insert(id, Arc::clone(&state));
        Some(Slot {
            id,
            state,
            connections: Arc::clone(self),
        })
    }
}

/// One connection's place among the open ones, given up when it is dropped.
struct Slot {
    id: u64,
    state: Arc<watch::Sender<State>>,
    connections: Arc<Connections>,
}

impl Slot {
    /// Moves to `state`, unless the connection was evicted.
    fn set(&self, state: State) {
        self.state.send_if_modified(|s| {
            let change = *s != State::Evicted;
            if change {
                *s = state;
            }
            change
        });
    }
}

impl Drop for Slot {
    fn drop(&mut self) {
        self.connections.open().by_id.remove(&self.id);
    }
}

/// Serves `stream` until the client closes it, a limit closes it, or it is evicted.
pub(super) fn accept(stream: TcpStream, shared: &Arc<Shared>) {
    // Without it, the last partial segment of an answer on a kept-alive connection waits for
    // the client's delayed ACK: 40 ms per tile on loopback.
    let _ = stream.set_nodelay(true);
    let Some(slot) = shared.connections.admit() else {
        refuse(stream, shared);
        return;
    };
    let shared = Arc::clone(shared);
    tokio::spawn(async move {
        let slot = Arc::new(slot);
        let watch = slot.state.subscribe();
        let service = Tracked {
            slot: Arc::clone(&slot),
            shared: Arc::clone(&shared),
            served: AtomicUsize::new(0),
        };
        let connection = builder(&shared.limits)
            .serve_connection(TokioIo::new(stream), service)
            .without_shutdown();
        tokio::select! {
            done = connection => {
                if let Ok(parts) = done {
                    linger(parts.io.into_inner()).await;
                }
            }
            () = watchdog(watch, shared.limits.request_timeout) => {}
        }
    });
}

/// HTTP/1.1 with the limits on request heads.
fn builder(limits: &Limits) -> http1::Builder {
    let mut builder = http1::Builder::new();
    builder
        .keep_alive(true)
        .max_header_size(limits.max_header_bytes)
        .max_buf_size(limits.max_header_bytes.max(8192));
    builder
}

/// Ends when the connection must close: evicted, or past the deadline of what it is doing.
async fn watchdog(mut state: watch::Receiver<State>, request_timeout: Duration) {
    loop {
        let deadline = match *state.borrow_and_update() {
            State::Evicted => return,
            State::Waiting(since) => Some(since + request_timeout),
            State::Answering(deadline) => deadline,
        };
        match deadline {
            Some(deadline) => tokio::select! {
                () = tokio::time::sleep_until(deadline) => {
                    if !state.has_changed().unwrap_or(true) {
                        return;
                    }
                }
                changed = state.changed() => {
                    if changed.is_err() {
                        return;
                    }
                }
            },
            None => {
                if state.changed().await.is_err() {
                    return;
                }
            }
        }
    }
}

/// Answers a connection over the limit with 503 (its request read first, so that closing
/// does not reset the connection under the answer), within [`REFUSE_TIME`]; past
/// [`MAX_REFUSING`] refusals under way, closes it unanswered.
fn refuse(stream: TcpStream, shared: &Shared) {
    let connections = Arc::clone(&shared.connections);
    if connections.refusing.fetch_add(1, Ordering::AcqRel) >= MAX_REFUSING {
        connections.refusing.fetch_sub(1, Ordering::AcqRel);
        return;
    }
    let mut builder = builder(&shared.limits);
    builder.keep_alive(false);
    tokio::spawn(async move {
        let service = hyper::service::service_fn(|request: Request<Incoming>| async move {
            let head = request.method() == Method::HEAD;
            let mut answer = text(
                StatusCode::SERVICE_UNAVAILABLE,
                "too many connections, try again later\n",
                head,
            );
            answer
                .headers_mut()
                .insert(header::RETRY_AFTER, HeaderValue::from_static("1"));
            Ok::<_, Infallible>(answer)
        });
        let connection = builder.serve_connection(TokioIo::new(stream), service);
        let _ = tokio::time::timeout(REFUSE_TIME, connection).await;
        connections.refusing.fetch_sub(1, Ordering::AcqRel);
    });
}

/// Closes `stream` gently: stops writing, then reads and drops what the client still sends
/// for [`LINGER`] at most, or until it closes.
async fn linger(mut stream: TcpStream) {
    use tokio::io::AsyncWrite;
    let shut = std::future::poll_fn(|cx| Pin::new(&mut stream).poll_shutdown(cx));
    if shut.await.is_err() {
        return;
    }
    let drain = async {
        let mut sink = [0u8; 4096];
        loop {
            if stream.readable().await.is_err() {
                return;
            }
            match stream.try_read(&mut sink) {
                Ok(0) => return,
                Ok(_) => {}
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => {}
                Err(_) => return,
            }
        }
    };
    let _ = tokio::time::timeout(LINGER, drain).await;
}

/// A connection's service: the server's, with the connection's state kept and its requests
/// counted (the last one allowed is answered with `Connection: close`).
struct Tracked {
    slot: Arc<Slot>,
    shared: Arc<Shared>,
    served: AtomicUsize,
}

impl Service<Request<Incoming>> for Tracked {
    type Response = Response<Sending>;
    type Error = Infallible;
    type Future = Pin<Box<dyn Future<Output = Answer<Sending>> + Send>>;

    fn call(&self, request: Request<Incoming>) -> Self::Future {
        self.slot.set(State::Answering(None));
        let served = self.served.fetch_add(1, Ordering::Relaxed) + 1;
        let last = served >= self.shared.limits.max_requests_per_connection;
        let answer = self.shared.service.call(request);
        let slot = Arc::clone(&self.slot);
        let shared = Arc::clone(&self.shared);
        Box::pin(async move {
            let mut answer = answer.await?;
            if last {
                answer
                    .headers_mut()
                    .insert(header::CONNECTION, HeaderValue::from_static("close"));
            }
            let hint = answer.body().size_hint();
            let len = hint.upper().unwrap_or(hint.lower());
            let deadline = Instant::now() + shared.limits.time_to_send(len, &shared.profile);
            slot.set(State::Answering(Some(deadline)));
            Ok(answer.map(|body| Sending { body, slot }))
        })
    }
}

/// An answer's body on its way: when it is done with (sent, or dropped because the
/// connection ended), its connection waits for the next request head.
struct Sending {
    body: Paced<Body>,
    slot: Arc<Slot>,
}

impl HttpBody for Sending {
    type Data = Bytes;
    type Error = io::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, io::Error>>> {
        Pin::new(&mut self.body).poll_frame(cx)
    }

    fn is_end_stream(&self) -> bool {
        self.body.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        self.body.size_hint()
    }
}

impl Drop for Sending {
    fn drop(&mut self) {
        self.slot.set(State::Waiting(Instant::now()));
    }
}
