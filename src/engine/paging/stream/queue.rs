//! The bounded request queue of progressive streaming (the 2009 follow-up's queue): at most
//! `capacity` (tile, level) requests wait to be sent, re-prioritised every frame by the screen
//! error their tiles show now. A waiting request that is no longer among the best — its tile
//! left the belts, the viewer turned away, or better requests arrived — is cancelled before it
//! is sent, so a slow link spends its bytes only on what the next frames need.

use std::cmp::Ordering;
use std::collections::HashSet;

use crate::db::grid::TileId;

/// Why a request was made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Reason {
    /// The current view needs it.
    #[default]
    View,
    /// Only the predicted view needs it.
    Predicted,
    /// No view needs it yet: the coarse square of belts grows.
    Belt,
}

/// One request: bring tile `id` to `levels` held progressive levels, from the levels it holds,
/// with one range request.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelRequest {
    /// The tile.
    pub id: TileId,
    /// Progressive levels the tile holds once the request arrives (1: the coarsest level).
    pub levels: usize,
    /// Higher goes first: absent tiles the view needs, then refinements by the error their
    /// tiles show, then the coarse belt fill.
    pub priority: f64,
    /// Why it was made.
    pub reason: Reason,
}

impl LevelRequest {
    /// The order of the queue: priority, highest first; ties by tile and level, so the queue
    /// is deterministic.
    fn order(&self, other: &LevelRequest) -> Ordering {
        other
            .priority
            .total_cmp(&self.priority)
            .then(self.levels.cmp(&other.levels))
            .then(self.id.cmp(&other.id))
    }

    fn same(&self, other: &LevelRequest) -> bool {
        self.id == other.id && self.levels == other.levels
    }
}

/// The waiting requests, best first.
#[derive(Clone, Debug)]
pub struct RequestQueue {
    capacity: usize,
    waiting: Vec<LevelRequest>,
}

impl RequestQueue {
    /// An empty queue holding at most `capacity` requests (at least 1).
    pub fn new(capacity: usize) -> Self {
        RequestQueue {
            capacity: capacity.max(1),
            waiting: Vec::new(),
        }
    }

    /// The most requests that wait at once.
    pub fn capacity(&self) -> usize {
        self.capacity
    }

    /// The waiting requests, best first.
    pub fn waiting(&self) -> &[LevelRequest] {
        &self.waiting
    }

    /// Replaces the waiting requests with the best `capacity` of `candidates` (this frame's
    /// wishes with this frame's priorities; at most one per tile and level is kept). Returns
    /// the requests that waited and are dropped now: cancelled before they were sent.
    pub fn reprioritise(&mut self, mut candidates: Vec<LevelRequest>) -> Vec<LevelRequest> {
        candidates.sort_by(LevelRequest::order);
        let mut seen = HashSet::new();
        candidates.retain(|c| seen.insert((c.id, c.levels)));
        candidates.truncate(self.capacity);
        let cancelled = self
            .waiting
            .iter()
            .filter(|w| !candidates.iter().any(|c| c.same(w)))
            .copied()
            .collect();
        self.waiting = candidates;
        cancelled
    }

    /// Takes the best waiting request for sending.
    pub fn pop(&mut self) -> Option<LevelRequest> {
        (!self.waiting.is_empty()).then(|| self.waiting.remove(0))
    }

    /// Takes out the waiting requests `rest` says should wait unsent this frame, best first;
    /// they go back with [`RequestQueue::push_back`].
    pub fn set_aside(&mut self, rest: impl Fn(&LevelRequest) -> bool) -> Vec<LevelRequest> {
        let (aside, kept) = self.waiting.iter().partition(|r| rest(r));
        self.waiting = kept;
        aside
    }

    /// Puts a request back at its place (it could not be sent yet: no memory or link).
    pub fn push_back(&mut self, request: LevelRequest) {
        let at = self
            .waiting
            .partition_point(|w| w.order(&request) == Ordering::Less);
        self.waiting.insert(at, request);
        self.waiting.truncate(self.capacity);
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    fn request(x: u32, levels: usize, priority: f64) -> LevelRequest {
        LevelRequest {
            id: TileId::new(x, 0),
            levels,
            priority,
            reason: Reason::View,
        }
    }

    #[test]
    fn keeps_the_best_and_cancels_what_fell_out() {
        let mut q = RequestQueue::new(2);
        let cancelled = q.reprioritise(vec![
            request(0, 1, 0.1),
            request(1, 1, 0.9),
            request(2, 1, 0.5),
        ]);
        assert!(cancelled.is_empty());
        assert_eq!(q.waiting(), [request(1, 1, 0.9), request(2, 1, 0.5)]);
        // The viewer turned: tile 2 no longer matters, tile 3 does.
        let cancelled = q.reprioritise(vec![request(3, 2, 0.7), request(1, 1, 0.2)]);
        assert_eq!(cancelled, [request(2, 1, 0.5)]);
        assert_eq!(q.pop(), Some(request(3, 2, 0.7)));
        q.push_back(request(3, 2, 0.7));
        assert_eq!(q.waiting()[0], request(3, 2, 0.7));
        assert_eq!(q.pop().map(|r| r.id.x), Some(3));
        assert_eq!(q.pop().map(|r| r.id.x), Some(1));
        assert_eq!(q.pop(), None);
    }

    proptest! {
        #[test]
        fn the_queue_is_bounded_ordered_and_loses_only_what_it_reports(
            frames in prop::collection::vec(
                prop::collection::vec((0u32..12, 1usize..4, 0.0f64..1.0), 0..20), 1..8),
            capacity in 1usize..6,
        ) {
            let mut q = RequestQueue::new(capacity);
            for frame in frames {
                let before = q.waiting().to_vec();
                let candidates: Vec<_> =
                    frame.iter().map(|&(x, l, p)| request(x, l, p)).collect();
                let cancelled = q.reprioritise(candidates.clone());
                prop_assert!(q.waiting().len() <= capacity);
                prop_assert!(q.waiting().windows(2).all(|w| w[0].priority >= w[1].priority));
                // Every request that waited is either still waiting or reported cancelled.
                for b in &before {
                    let kept = q.waiting().iter().any(|w| w.same(b));
                    let dropped = cancelled.iter().any(|c| c.same(b));
                    prop_assert!(kept != dropped);
                }
                // Nothing better than the worst kept request was left out.
                if let Some(worst) = q.waiting().last() {
                    for c in &candidates {
                        if !q.waiting().iter().any(|w| w.same(c)) {
                            prop_assert!(c.priority <= worst.priority);
                        }
                    }
                }
            }
        }
    }
}
