//! What both pagers send their requests over: a fetch thread ([`PagerMode::Threaded`]), or, in
//! the deterministic modes, this thread — with [`PagerMode::Simulated`] each result held back
//! until the simulated time passes the end of its transfer on a link that carries one request at
//! a time, as timed by a [`TransferClock`].
//!
//! Both links can cancel a request on its way. The simulated link drops the transfer at once;
//! the fetch thread's is told through the request's [`CancelToken`] (an HTTP range stops and
//! its connection closes, a request still queued is not read), and whatever comes back of it is
//! set apart from the arrivals as [`Received::cut`], so that the pager never takes in a level it
//! gave up, even while a new request for the same tile is on its way.

use std::collections::VecDeque;
use std::sync::Arc;

use super::worker::{self, Arrival, Job, Request, Worker};
use super::{PagerMode, TransferClock};
use crate::db::source::CancelToken;
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
    /// Requests the fetch thread was told to cancel that came back (stopped, or finished before
    /// they noticed), with the bytes they downloaded: none of them is an arrival.
    pub cut: Vec<(R, u64)>,
}

/// A fetch thread or this thread, and the simulated link's clock.
pub struct Link<R: Request, T> {
    job: Job<R, T>,
    mode: PagerMode,
    worker: Option<Worker<R, T>>,
    transfer_clock: Option<Arc<dyn TransferClock>>,
    pending: VecDeque<Pending<R, T>>,
    free_at: f64,
    /// Requests sent to the fetch thread and not back yet, with their cancel tokens.
    sent: Vec<(R, CancelToken)>,
    /// The fetch thread's seconds per request, smoothed over those that came back.
    per_request: Option<f64>,
}

/// How much a request's time moves the fetch thread's smoothed seconds per request.
const PER_REQUEST_SMOOTHING: f64 = 0.25;

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
            sent: Vec::new(),
            per_request: None,
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

    /// Queues `request` on the fetch thread, with a cancel token of its own.
    fn send(&mut self, request: R) -> Result<()> {
        let cancel = CancelToken::new();
        match &self.worker {
            Some(worker) => {
                worker.send(request, cancel.clone())?;
                self.sent.push((request, cancel));
                Ok(())
            }
            None => Err(Error::invalid(
                request.to_string(),
                "no fetch thread is running",
            )),
        }
    }

    /// Runs `request` on this thread now.
    fn run_now(&self, request: R) -> Result<(T, u64)> {
        worker::run(&*self.job, request, &CancelToken::new())
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

    /// Seconds from `time` until the link has delivered every request it carries: exact on the
    /// simulated link, the requests not back times the seconds one took so far on the fetch
    /// thread (`None` before any came back), `None` when stepped (fetches run when sent).
    pub fn backlog(&self, time: f64) -> Option<f64> {
        match self.mode {
            PagerMode::Simulated { .. } => Some((self.free_at - time).max(0.0)),
            PagerMode::Threaded { .. } => self.per_request.map(|s| s * self.sent.len() as f64),
            PagerMode::Stepped { .. } => None,
        }
    }

    /// Whether the transfer of `request` has started by `time` (`None` when the link holds no
    /// such request). The fetch thread runs its requests one at a time in the order they were
    /// sent, so the first of those not back yet counts as started and the others as waiting
    /// (one the thread began since the last [`Link::receive`] is then stopped as one under
    /// way would be).
    pub fn started(&self, request: &R, time: f64) -> Option<bool>
    where
        R: PartialEq,
    {
        if let Some(k) = self
            .sent
            .iter()
            .position(|(r, c)| r == request && !c.is_cancelled())
        {
            return Some(k == 0);
        }
        let p = self.pending.iter().find(|p| p.request == *request)?;
        Some(p.due - p.took < time)
    }

    /// Cancels `request` on its way at `time`. On the simulated link the transfer is dropped: one
    /// not yet started never crosses the link, one under way stops now, and the transfers
    /// behind it move up. On the fetch thread its cancel token is raised: the request never
    /// arrives, and what it downloaded comes back in [`Received::cut`]. Returns the bytes that
    /// had crossed the simulated link (0 on the fetch thread, whose bytes are counted when the
    /// request comes back), or `None` when the link holds no such request (a stepped fetch has
    /// already arrived).
    pub fn cancel(&mut self, request: &R, time: f64) -> Option<u64>
    where
        R: PartialEq,
    {
        if let Some((_, cancel)) = self
            .sent
            .iter()
            .find(|(r, c)| r == request && !c.is_cancelled())
        {
            cancel.cancel();
            return Some(0);
        }
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
            cut: Vec::new(),
        };
        while self.pending.front().is_some_and(|p| p.due <= time) {
            let p = self.pending.pop_front().expect("checked");
            received.arrivals.push((p.request, p.result));
        }
        if let Some(worker) = &self.worker {
            loop {
                match worker.try_recv() {
                    Ok(Some(Arrival {
                        request,
                        cancel,
                        result,
                        took,
                    })) => {
                        self.sent.retain(|(_, c)| !c.is(&cancel));
                        self.per_request = Some(
                            self.per_request
                                .map_or(took, |s| s + PER_REQUEST_SMOOTHING * (took - s)),
                        );
                        if cancel.is_cancelled() {
                            received.cut.push((request, downloaded(&result)));
                        } else {
                            received.arrivals.push((request, result));
                        }
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
            self.sent.clear();
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

/// The bytes a request that comes back downloaded: all of them, or those that had arrived when
/// it was cancelled (none for any other failure).
fn downloaded<T>(result: &Result<(T, u64)>) -> u64 {
    match result {
        Ok((_, bytes)) => *bytes,
        Err(Error::Cancelled { received, .. }) => *received,
        Err(_) => 0,
    }
}

#[cfg(test)]
mod tests {
    // 32 bits: ARMv5TE has no 64-bit atomics, and the test counts three fetches.
    use std::sync::atomic::{AtomicU32, Ordering};
    use std::time::{Duration, Instant};

    use super::*;

    /// A transfer clock on which every fetch takes half a second.
    struct HalfSecond(Arc<AtomicU32>);

    impl TransferClock for HalfSecond {
        fn busy_seconds(&self) -> f64 {
            0.5 * f64::from(self.0.load(Ordering::Relaxed))
        }
    }

    #[test]
    fn the_simulated_backlog_is_what_the_link_has_left_to_carry() {
        let fetched = Arc::new(AtomicU32::new(0));
        let counter = Arc::clone(&fetched);
        let job: Job<u32, ()> = Arc::new(move |_, _| {
            counter.fetch_add(1, Ordering::Relaxed);
            Ok(((), 10))
        });
        let mut link = Link::new(job, PagerMode::Simulated { queue_depth: 4 }).unwrap();
        link.set_transfer_clock(Arc::new(HalfSecond(fetched)));
        assert_eq!(link.backlog(0.0), Some(0.0));
        for r in 0..3 {
            assert!(link.start(r, 0.0).is_none());
        }
        assert_eq!(link.backlog(0.0), Some(1.5));
        assert_eq!(link.backlog(1.0), Some(0.5));
        // The last transfer, not started yet, is dropped: the link is done at 1 s.
        assert_eq!(link.cancel(&2, 0.2), Some(0));
        assert_eq!(link.backlog(0.2), Some(0.8));
        assert_eq!(link.receive(1.0).arrivals.len(), 2);
        assert_eq!(link.backlog(3.0), Some(0.0));
    }

    #[test]
    fn the_fetch_threads_backlog_counts_its_requests_at_the_time_one_took() {
        let job: Job<u32, ()> = Arc::new(|_, _| {
            std::thread::sleep(Duration::from_millis(10));
            Ok(((), 10))
        });
        let mut link = Link::new(job, PagerMode::Threaded { queue_depth: 4 }).unwrap();
        assert!(link.start(0, 0.0).is_none());
        assert_eq!(link.backlog(0.0), None, "nothing came back to time");
        let started = Instant::now();
        while link.receive(0.0).arrivals.is_empty() {
            assert!(started.elapsed() < Duration::from_secs(30), "no arrival");
            std::thread::sleep(Duration::from_millis(1));
        }
        assert_eq!(link.backlog(0.0), Some(0.0), "nothing on its way");
        for r in 1..4 {
            assert!(link.start(r, 0.0).is_none());
        }
        let backlog = link.backlog(0.0).unwrap();
        assert!(
            backlog >= 0.03,
            "three requests of at least 10 ms: {backlog}"
        );
    }

    #[test]
    fn a_stepped_link_has_no_backlog() {
        let job: Job<u32, ()> = Arc::new(|_, _| Ok(((), 10)));
        let mut link = Link::new(
            job,
            PagerMode::Stepped {
                fetches_per_update: 1,
            },
        )
        .unwrap();
        assert!(link.start(0, 0.0).is_some());
        assert_eq!(link.backlog(0.0), None);
    }
}
