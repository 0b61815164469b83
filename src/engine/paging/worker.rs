//! The fetch thread: takes requests over a channel, runs a job on each, and sends the results
//! back, so that the frame loop never waits on I/O. The belt pager's requests are whole-tile
//! fetches; the stream pager's are (tile, level) requests. Each request travels with a
//! [`CancelToken`] the job reads with, so that the pager can stop a request under way.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};
use std::time::Instant;

use crate::db::source::CancelToken;
use crate::error::{Error, Result};

/// A request the fetch thread can run; its display names what it fetches (errors say it).
pub trait Request: Copy + Send + std::fmt::Display + 'static {}

impl<R: Copy + Send + std::fmt::Display + 'static> Request for R {}

/// What the fetch thread sends back for one request.
pub struct Arrival<R, T> {
    /// The request.
    pub request: R,
    /// The token it was sent with: whether it was cancelled, and which sending it answers.
    pub cancel: CancelToken,
    /// What the job made of it, and the bytes it downloaded.
    pub result: Result<(T, u64)>,
    /// Seconds the job ran: how long the link took over the request.
    pub took: f64,
}

/// What the fetch thread runs for each request, reading with its cancel token (a job that
/// cannot stop a read under way ignores it).
pub type JobFn<R, T> = dyn Fn(R, &CancelToken) -> Result<(T, u64)> + Send + Sync;

/// A job, shared by the fetch thread and the frame's thread.
pub type Job<R, T> = Arc<JobFn<R, T>>;

/// A fetch thread and its two channels. Dropping it tells the thread to stop after the request
/// it is running, if any, without starting the requests still queued, and does not wait for it:
/// a request blocked on a server that does not answer is abandoned (it ends at its timeout or
/// deadline, see [`crate::db::source::http::HttpOptions`]), so it never holds up the frame loop
/// or the end of the process.
pub struct Worker<R, T> {
    requests: Option<Sender<(R, CancelToken)>>,
    arrivals: Receiver<Arrival<R, T>>,
    stop: Arc<AtomicBool>,
}

impl<R: Request, T: Send + 'static> Worker<R, T> {
    /// Starts the fetch thread running `job` on each request; a panic in `job` becomes an error
    /// naming the tile.
    pub fn spawn(job: Job<R, T>) -> Result<Self> {
        let (requests, queue) = channel::<(R, CancelToken)>();
        let (done, arrivals) = channel();
        let stop = Arc::new(AtomicBool::new(false));
        let stopped = Arc::clone(&stop);
        std::thread::Builder::new()
            .name("stripmask-fetch".into())
            .spawn(move || {
                for (request, cancel) in queue {
                    if stopped.load(Ordering::Relaxed) {
                        break;
                    }
                    let started = Instant::now();
                    let result = run(&*job, request, &cancel);
                    let arrival = Arrival {
                        request,
                        cancel,
                        result,
                        took: started.elapsed().as_secs_f64(),
                    };
                    if done.send(arrival).is_err() {
                        break;
                    }
                }
            })
            .map_err(|e| Error::io("the fetch thread", e))?;
        Ok(Worker {
            requests: Some(requests),
            arrivals,
            stop,
        })
    }

    /// Queues a request, to be read with `cancel`; fails when the thread is gone.
    pub fn send(&self, request: R, cancel: CancelToken) -> Result<()> {
        let sent = self.requests.as_ref().map(|r| r.send((request, cancel)));
        match sent {
            Some(Ok(())) => Ok(()),
            _ => Err(Error::invalid(
                request.to_string(),
                "the fetch thread has stopped",
            )),
        }
    }

    /// The next result that arrived, without waiting; an error when the thread is gone.
    pub fn try_recv(&self) -> Result<Option<Arrival<R, T>>> {
        match self.arrivals.try_recv() {
            Ok(arrival) => Ok(Some(arrival)),
            Err(TryRecvError::Empty) => Ok(None),
            Err(TryRecvError::Disconnected) => Err(Error::invalid(
                "the fetch thread",
                "it stopped with fetches in flight",
            )),
        }
    }
}

impl<R, T> Drop for Worker<R, T> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        // Closing the queue ends the thread once its request, if any, returns.
        self.requests = None;
    }
}

/// Runs `job` for one request read with `cancel`, turning a panic into an error that names the
/// tile.
pub fn run<R: Request, T>(job: &JobFn<R, T>, request: R, cancel: &CancelToken) -> Result<(T, u64)> {
    catch_unwind(AssertUnwindSafe(|| job(request, cancel))).unwrap_or_else(|_| {
        Err(Error::invalid(
            request.to_string(),
            "the loader panicked while fetching it",
        ))
    })
}

#[cfg(test)]
mod tests {
    use std::sync::mpsc::sync_channel;
    use std::time::{Duration, Instant};

    use super::*;

    #[test]
    fn dropping_a_worker_does_not_wait_for_a_request_that_hangs() {
        let (release, hang) = sync_channel::<()>(0);
        let hang = std::sync::Mutex::new(hang);
        let job: Job<u32, ()> = Arc::new(move |_, _| {
            // Blocks until the test releases it, as a read from a server that never answers.
            let _ = hang.lock().unwrap().recv_timeout(Duration::from_secs(60));
            Ok(((), 0))
        });
        let worker = Worker::spawn(job).unwrap();
        worker.send(1, CancelToken::new()).unwrap();
        std::thread::sleep(Duration::from_millis(50));
        let started = Instant::now();
        drop(worker);
        let took = started.elapsed();
        let _ = release.try_send(());
        assert!(took < Duration::from_secs(30), "drop waited {took:?}");
    }
}
