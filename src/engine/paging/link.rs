//! What both pagers send their requests over: a fetch thread ([`PagerMode::Threaded`]), or, in
//! the deterministic modes, this thread — with [`PagerMode::Simulated`] each result held back
//! until the simulated time passes the end of its transfer on a link that carries one request at
//! a time, as timed by a [`TransferClock`].

use std::collections::VecDeque;
use std::sync::Arc;

use super::worker::{self, Arrival, Job, Request, Worker};
use super::{PagerMode, TransferClock};
use crate::error::{Error, Result};

/// A result that arrives at `due` simulated seconds, after a transfer of `took` seconds asked
/// for at `sent`.
struct Pending<R, T> {
    due: f64,
    sent: f64,
    took: f64,
    request: R,
    result: Result<(T, u64)>,
}

/// What arrived since the last look.
pub struct Received<R, T> {
    /// Requests and their results, in arrival order.
    pub arrivals: Vec<(R, Result<(T, u64)>)>,
    /// What went wrong with the fetch thread: it stopped (a new thread was started), and
    /// starting the new one failed.
    pub errors: Vec<Error>,
    /// Whether the requests in flight were lost with a stopped fetch thread: they never arrive.
    pub lost: bool,
}

/// A fetch thread or this thread, and the simulated link's clock.
pub struct Link<R: Request, T> {
    job: Job<R, T>,
    mode: PagerMode,
    worker: Option<Worker<R, T>>,
    transfer_clock: Option<Arc<dyn TransferClock>>,
    pending: VecDeque<Pending<R, T>>,
    free_at: f64,
}

impl<R: Request, T: Send + 'static> Link<R, T> {
    /// Runs `job` for each request the way `mode` says: on a fetch thread when threaded.
    pub fn new(job: Job<R, T>, mode: PagerMode) -> Result<Self> {
        let worker = if matches!(mode, PagerMode::Threaded { .. }) {
            Some(Worker::spawn(Arc::clone(&job))?)
        } else {
            None
        };
        Ok(Link {
            job,
            mode,
            worker,
            transfer_clock: None,
            pending: VecDeque::new(),
            free_at: 0.0,
        })
    }

    /// Times simulated transfers; without a clock they take no time.
    pub fn set_transfer_clock(&mut self, clock: Arc<dyn TransferClock>) {
        self.transfer_clock = Some(clock);
    }

    /// Starts `request` the way the link runs: queued on the fetch thread, scheduled on the
    /// simulated link (at `time` or when it is free), or, stepped, run now. A result that is
    /// already there (a stepped fetch, or a send to a stopped thread) comes back at once.
    pub fn start(&mut self, request: R, time: f64) -> Option<(R, Result<(T, u64)>)> {
        match self.mode {
            PagerMode::Threaded { .. } => self.send(request).err().map(|e| (request, Err(e))),
            PagerMode::Simulated { .. } => {
                self.schedule(request, time);
                None
            }
            PagerMode::Stepped { .. } => Some((request, self.run_now(request))),
        }
    }

    /// Queues `request` on the fetch thread.
    fn send(&self, request: R) -> Result<()> {
        match &self.worker {
            Some(worker) => worker.send(request),
            None => Err(Error::invalid(
                request.to_string(),
                "no fetch thread is running",
            )),
        }
    }

    /// Runs `request` on this thread now.
    fn run_now(&self, request: R) -> Result<(T, u64)> {
        worker::run(&*self.job, request)
    }

    /// Runs `request` now and holds its result back until the end of its transfer, which
    /// starts at `time` or when the link is free, whichever is later.
    fn schedule(&mut self, request: R, time: f64) {
        let busy = |clock: &Option<Arc<dyn TransferClock>>| {
            clock.as_ref().map_or(0.0, |c| c.busy_seconds())
        };
        let before = busy(&self.transfer_clock);
        let result = self.run_now(request);
        let took = (busy(&self.transfer_clock) - before).max(0.0);
        let due = self.free_at.max(time) + took;
        self.free_at = due;
        self.pending.push_back(Pending {
            due,
            sent: time,
            took,
            request,
            result,
        });
    }

    /// Whether the transfer of `request` on the simulated link has started by `time` (`None`
    /// when the link holds no such transfer: a fetch thread's, or none).
    pub fn started(&self, request: &R, time: f64) -> Option<bool>
    where
        R: PartialEq,
    {
        let p = self.pending.iter().find(|p| p.request == *request)?;
        Some(p.due - p.took < time)
    }

    /// Drops the transfer of `request` on the simulated link at `time`: one not yet started
    /// never crosses the link, one under way stops now, and the transfers behind it move up.
    /// Returns the bytes that had crossed the link, or `None` when the link cannot cancel it
    /// (a fetch thread runs what it was sent; a stepped fetch has already arrived) or holds no
    /// such transfer.
    pub fn cancel(&mut self, request: &R, time: f64) -> Option<u64>
    where
        R: PartialEq,
    {
        let i = self.pending.iter().position(|p| p.request == *request)?;
        let p = self.pending.remove(i).expect("found");
        let start = p.due - p.took;
        let crossed = match p.result {
            Ok((_, bytes)) if start < time && p.took > 0.0 => {
                (bytes as f64 * ((time - start) / p.took).min(1.0)) as u64
            }
            _ => 0,
        };
        // The link is free from the cancelled transfer's start (or now, if it was under way).
        let mut free = start.max(time.min(p.due));
        for q in self.pending.iter_mut().skip(i) {
            q.due = free.max(q.sent) + q.took;
            free = q.due;
        }
        self.free_at = self.pending.back().map_or(free, |q| q.due);
        Some(crossed)
    }

    /// Every scheduled result due by `time`, then every result the fetch thread sent. If the
    /// thread is gone, its requests in flight are lost and a new thread starts.
    pub fn receive(&mut self, time: f64) -> Received<R, T> {
        let mut received = Received {
            arrivals: Vec::new(),
            errors: Vec::new(),
            lost: false,
        };
        while self.pending.front().is_some_and(|p| p.due <= time) {
            let p = self.pending.pop_front().expect("checked");
            received.arrivals.push((p.request, p.result));
        }
        if let Some(worker) = &self.worker {
            loop {
                match worker.try_recv() {
                    Ok(Some(Arrival { request, result })) => {
                        received.arrivals.push((request, result))
                    }
                    Ok(None) => break,
                    Err(e) => {
                        received.errors.push(e);
                        break;
                    }
                }
            }
        }
        if !received.errors.is_empty() {
            received.lost = true;
            match Worker::spawn(Arc::clone(&self.job)) {
                Ok(worker) => self.worker = Some(worker),
                Err(e) => {
                    self.worker = None;
                    received.errors.push(e);
                }
            }
        }
        received
    }
}
