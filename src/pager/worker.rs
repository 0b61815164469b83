//! The fetch thread: takes fetch requests over a channel, runs the loader, and sends the results
//! back, so that the frame loop never waits on I/O.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{Receiver, Sender, TryRecvError, channel};
use std::thread::JoinHandle;

use super::TileLoader;
use crate::belts::{Fetch, TileId};
use crate::error::{Error, Result};

/// What the fetch thread sends back for one request.
pub(super) struct Arrival<T> {
    pub id: TileId,
    pub result: Result<(T, u64)>,
}

/// A fetch thread and its two channels. Dropping it stops the thread after the fetch it is
/// running, if any, without starting the requests still queued.
pub(super) struct Worker<T> {
    requests: Option<Sender<Fetch>>,
    arrivals: Receiver<Arrival<T>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl<T: Send + 'static> Worker<T> {
    /// Starts the fetch thread for `loader`.
    pub fn spawn<L: TileLoader<Loaded = T>>(loader: Arc<L>) -> Result<Self> {
        let (requests, queue) = channel::<Fetch>();
        let (done, arrivals) = channel();
        let stop = Arc::new(AtomicBool::new(false));
        let stopped = Arc::clone(&stop);
        let thread = std::thread::Builder::new()
            .name("stripmask-fetch".into())
            .spawn(move || {
                for fetch in queue {
                    if stopped.load(Ordering::Relaxed) {
                        break;
                    }
                    let result = load(&*loader, fetch);
                    if done
                        .send(Arrival {
                            id: fetch.id,
                            result,
                        })
                        .is_err()
                    {
                        break;
                    }
                }
            })
            .map_err(|e| Error::io("the fetch thread", e))?;
        Ok(Worker {
            requests: Some(requests),
            arrivals,
            stop,
            thread: Some(thread),
        })
    }

    /// Queues a fetch; fails when the thread is gone.
    pub fn send(&self, fetch: Fetch) -> Result<()> {
        let sent = self.requests.as_ref().map(|r| r.send(fetch));
        match sent {
            Some(Ok(())) => Ok(()),
            _ => Err(Error::invalid(
                fetch.id.to_string(),
                "the fetch thread has stopped",
            )),
        }
    }

    /// The next result that arrived, without waiting; an error when the thread is gone.
    pub fn try_recv(&self) -> Result<Option<Arrival<T>>> {
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

impl<T> Drop for Worker<T> {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        self.requests = None;
        if let Some(thread) = self.thread.take() {
            // A panic inside the loader is already caught in `load`; nothing else can panic.
            let _ = thread.join();
        }
    }
}

/// Runs the loader for one fetch, turning a panic into an error that names the tile.
pub(super) fn load<L: TileLoader>(loader: &L, fetch: Fetch) -> Result<(L::Loaded, u64)> {
    catch_unwind(AssertUnwindSafe(|| loader.load(fetch.id, fetch.ring))).unwrap_or_else(|_| {
        Err(Error::invalid(
            fetch.id.to_string(),
            format!(
                "the loader panicked while fetching it for ring {}",
                fetch.ring
            ),
        ))
    })
}
