//! The simulated link as a layer around a service: each request waits for its delay
//! (`latency ± jitter`), a dropped one is answered 503, and every answer's body is paced at the
//! link's bandwidth. The service inside knows nothing of it.

use std::convert::Infallible;
use std::future::Future;
use std::io;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll, ready};
use std::time::Duration;

use bytes::Bytes;
use http_body::{Body as HttpBody, Frame, SizeHint};
use hyper::body::Incoming;
use hyper::service::Service;
use hyper::{Method, Request, Response, StatusCode};
use tokio::time::{Instant, Sleep};

use super::body::{Answer, Body, text};
use crate::db::source::throttle::{DropDice, LatencyDice, LinkProfile};

/// `S` behind the simulated link of a [`LinkProfile`].
pub(super) struct LinkLayer<S> {
    inner: Arc<S>,
    bytes_per_second: Option<f64>,
    drops: DropDice,
    delays: LatencyDice,
}

impl<S> LinkLayer<S> {
    /// `inner` behind `profile`'s link.
    pub(super) fn new(inner: S, profile: &LinkProfile) -> Self {
        LinkLayer {
            inner: Arc::new(inner),
            bytes_per_second: profile.bytes_per_second(),
            drops: DropDice::new(profile.drop_rate, profile.seed),
            delays: LatencyDice::new(profile),
        }
    }
}

impl<S> Service<Request<Incoming>> for LinkLayer<S>
where
    S: Service<Request<Incoming>, Response = Response<Body>, Error = Infallible>
        + Send
        + Sync
        + 'static,
    S::Future: Send,
{
    type Response = Response<Paced<Body>>;
    type Error = Infallible;
    type Future = Pin<Box<dyn Future<Output = Answer<Paced<Body>>> + Send>>;

    fn call(&self, request: Request<Incoming>) -> Self::Future {
        let delay = self.delays.next();
        let dropped = self.drops.roll();
        let bytes_per_second = self.bytes_per_second;
        let inner = Arc::clone(&self.inner);
        Box::pin(async move {
            if !delay.is_zero() {
                tokio::time::sleep(delay).await;
            }
            let answer = if dropped {
                let head = request.method() == Method::HEAD;
                text(
                    StatusCode::SERVICE_UNAVAILABLE,
                    "dropped by the simulated link\n",
                    head,
                )
            } else {
                inner.call(request).await?
            };
            Ok(answer.map(|body| Paced::new(body, bytes_per_second)))
        })
    }
}

/// A body delivered no faster than a bandwidth: in pieces of about 20 ms of data, each handed
/// over when the link would have carried it.
pub(super) struct Paced<B> {
    inner: B,
    bytes_per_second: Option<f64>,
    /// When the first piece was asked for.
    start: Option<Instant>,
    /// Bytes handed over, and the piece waiting for its time.
    sent: u64,
    held: Bytes,
    wait: Option<Pin<Box<Sleep>>>,
}

impl<B> Paced<B> {
    fn new(inner: B, bytes_per_second: Option<f64>) -> Self {
        Paced {
            inner,
            bytes_per_second,
            start: None,
            sent: 0,
            held: Bytes::new(),
            wait: None,
        }
    }
}

impl<B> HttpBody for Paced<B>
where
    B: HttpBody<Data = Bytes, Error = io::Error> + Unpin,
{
    type Data = Bytes;
    type Error = io::Error;

    fn poll_frame(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<Frame<Bytes>, io::Error>>> {
        let this = self.get_mut();
        let Some(bps) = this.bytes_per_second else {
            return Pin::new(&mut this.inner).poll_frame(cx);
        };
        loop {
            if let Some(wait) = this.wait.as_mut() {
                ready!(wait.as_mut().poll(cx));
                this.wait = None;
                let piece = ((bps / 50.0) as usize).clamp(1, this.held.len());
                this.sent += piece as u64;
                return Poll::Ready(Some(Ok(Frame::data(this.held.split_to(piece)))));
            }
            if !this.held.is_empty() {
                // The time the link has carried everything up to the end of the next piece.
                let piece = ((bps / 50.0) as usize).clamp(1, this.held.len());
                let start = *this.start.get_or_insert_with(Instant::now);
                let due = start + Duration::from_secs_f64((this.sent + piece as u64) as f64 / bps);
                this.wait = Some(Box::pin(tokio::time::sleep_until(due)));
                continue;
            }
            match ready!(Pin::new(&mut this.inner).poll_frame(cx)) {
                Some(Ok(frame)) => match frame.into_data() {
                    Ok(data) => this.held = data,
                    Err(frame) => return Poll::Ready(Some(Ok(frame))),
                },
                end => return Poll::Ready(end),
            }
        }
    }

    fn is_end_stream(&self) -> bool {
        self.held.is_empty() && self.inner.is_end_stream()
    }

    fn size_hint(&self) -> SizeHint {
        let held = self.held.len() as u64;
        let inner = self.inner.size_hint();
        let mut hint = SizeHint::new();
        hint.set_lower(inner.lower() + held);
        if let Some(upper) = inner.upper() {
            hint.set_upper(upper + held);
        }
        hint
    }
}
