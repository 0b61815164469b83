//! What streaming measures: requests sent and cancelled, and whether the bytes that arrived
//! were worth their transfer — the share rendered within a second of arriving (the 2009 system
//! reports 99.5%), of all bytes and of those the current view asked for (the rest are the
//! prediction's, judged by its hit rate, and the coarse belt fill's, which no view asked for).

use std::collections::VecDeque;

use crate::db::grid::TileId;
use crate::engine::paging::stream::Reason;

/// Seconds after its arrival within which a delivery must be drawn to count as rendered.
pub const RENDER_WINDOW: f64 = 1.0;

/// Seconds after its arrival within which a predicted delivery must be drawn to count as a
/// hit: the prediction looks a second ahead, so it gets that second plus the render window.
pub const HIT_WINDOW: f64 = 2.0;

/// One level that arrived.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Delivery {
    /// The tile.
    pub id: TileId,
    /// Progressive levels the tile held after it (the level that arrived is `levels - 1`).
    pub levels: usize,
    /// Bytes downloaded for it.
    pub bytes: u64,
    /// Seconds at arrival.
    pub at: f64,
    /// Why it was requested.
    pub reason: Reason,
}

/// The counters of a stream pager.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct StreamStats {
    /// Requests sent.
    pub requests: u64,
    /// Requests cancelled: before they were sent, or on their way (see `cut`).
    pub cancelled: u64,
    /// Of those, requests cancelled on their way.
    pub cancelled_in_flight: u64,
    /// Bytes that crossed the link for requests cancelled on their way (never drawn; counted
    /// in `received_bytes` and `settled_bytes`).
    pub cut_bytes: u64,
    /// Tiles whose finest levels were dropped to make room.
    pub dropped_levels: u64,
    /// Bytes received.
    pub received_bytes: u64,
    /// Of those, bytes of the coarse belt fill (no view asked for them).
    pub belt_bytes: u64,
    /// Bytes whose render window has passed.
    pub settled_bytes: u64,
    /// Of those, bytes drawn within [`RENDER_WINDOW`] of arriving.
    pub rendered_bytes: u64,
    /// Settled bytes the current view asked for.
    pub view_settled_bytes: u64,
    /// Of those, bytes drawn within [`RENDER_WINDOW`] of arriving.
    pub view_rendered_bytes: u64,
    /// Predicted deliveries whose hit window has passed.
    pub predicted_settled: u64,
    /// Of those, the ones drawn within [`HIT_WINDOW`].
    pub predicted_hits: u64,
    /// Deliveries still inside their window, with whether they were drawn yet.
    open: VecDeque<(Delivery, bool)>,
    /// The recent requests' seconds from sending to arrival, smoothed.
    round_trip: Option<f64>,
}

/// Weight of the newest arrival in the smoothed round trip.
const ROUND_TRIP_SMOOTHING: f64 = 0.25;

impl StreamStats {
    /// The share of settled received bytes that were rendered within a second (`None` before
    /// any settled).
    pub fn rendered_share(&self) -> Option<f64> {
        (self.settled_bytes > 0).then(|| self.rendered_bytes as f64 / self.settled_bytes as f64)
    }

    /// The same share for the bytes the current view asked for.
    pub fn view_rendered_share(&self) -> Option<f64> {
        (self.view_settled_bytes > 0)
            .then(|| self.view_rendered_bytes as f64 / self.view_settled_bytes as f64)
    }

    /// The share of settled predicted deliveries that were drawn in time (`None` before any).
    pub fn hit_rate(&self) -> Option<f64> {
        (self.predicted_settled > 0)
            .then(|| self.predicted_hits as f64 / self.predicted_settled as f64)
    }

    /// Seconds a request takes from being sent to arriving at a frame, smoothed over the
    /// recent arrivals (`None` before any): how far ahead a request must look to be drawn.
    pub fn round_trip(&self) -> Option<f64> {
        self.round_trip
    }

    /// A request arrived `seconds` after it was sent.
    pub fn arrived_after(&mut self, seconds: f64) {
        let seconds = seconds.max(0.0);
        self.round_trip = Some(
            self.round_trip
                .map_or(seconds, |r| r + ROUND_TRIP_SMOOTHING * (seconds - r)),
        );
    }

    /// A request made for `reason` was cancelled on its way after `bytes` of it crossed the
    /// link: they count as received and never drawn.
    pub fn cut(&mut self, bytes: u64, reason: Reason) {
        self.cancelled += 1;
        self.cancelled_in_flight += 1;
        if reason == Reason::Predicted {
            self.predicted_settled += 1;
        }
        self.crossed(bytes, reason);
    }

    /// `bytes` more of a request made for `reason` and cancelled on its way crossed the link
    /// (the fetch thread's requests tell once they stopped): received, never drawn.
    pub fn crossed(&mut self, bytes: u64, reason: Reason) {
        self.cut_bytes += bytes;
        self.received_bytes += bytes;
        self.settled_bytes += bytes;
        match reason {
            Reason::View => self.view_settled_bytes += bytes,
            Reason::Predicted => {}
            Reason::Belt => self.belt_bytes += bytes,
        }
    }

    /// Counts a delivery.
    pub fn received(&mut self, delivery: Delivery) {
        self.received_bytes += delivery.bytes;
        if delivery.reason == Reason::Belt {
            self.belt_bytes += delivery.bytes;
        }
        self.open.push_back((delivery, false));
    }

    /// A frame at `now` drew tile `id` with a mask that needs `levels` levels: every open
    /// delivery of that tile up to that level was rendered.
    pub fn rendered(&mut self, id: TileId, levels: usize, now: f64) {
        for (d, drawn) in &mut self.open {
            let window = if d.reason == Reason::Predicted {
                HIT_WINDOW
            } else {
                RENDER_WINDOW
            };
            if d.id == id && d.levels <= levels && now - d.at <= window {
                *drawn = true;
            }
        }
    }

    /// The deliveries still inside their window (drawn or not): each tile and the levels it
    /// held after the delivery. A level fetched this recently is worth keeping on screen.
    pub fn fresh(&self) -> impl Iterator<Item = (TileId, usize)> + '_ {
        self.open.iter().map(|(d, _)| (d.id, d.levels))
    }

    /// Settles the deliveries whose windows have passed at `now`.
    pub fn settle(&mut self, now: f64) {
        let mut still = VecDeque::with_capacity(self.open.len());
        for (d, drawn) in self.open.drain(..) {
            let window = if d.reason == Reason::Predicted {
                HIT_WINDOW
            } else {
                RENDER_WINDOW
            };
            if now - d.at <= window {
                still.push_back((d, drawn));
                continue;
            }
            self.settled_bytes += d.bytes;
            if drawn {
                self.rendered_bytes += d.bytes;
            }
            match d.reason {
                Reason::View => {
                    self.view_settled_bytes += d.bytes;
                    if drawn {
                        self.view_rendered_bytes += d.bytes;
                    }
                }
                Reason::Predicted => {
                    self.predicted_settled += 1;
                    self.predicted_hits += u64::from(drawn);
                }
                Reason::Belt => {}
            }
        }
        self.open = still;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn delivery(x: u32, levels: usize, bytes: u64, at: f64, predicted: bool) -> Delivery {
        let reason = if predicted {
            Reason::Predicted
        } else {
            Reason::View
        };
        Delivery {
            id: TileId::new(x, 0),
            levels,
            bytes,
            at,
            reason,
        }
    }

    #[test]
    fn bytes_count_as_rendered_only_when_drawn_at_their_level_within_a_second() {
        let mut s = StreamStats::default();
        s.received(delivery(0, 2, 100, 0.0, false));
        s.received(delivery(1, 3, 50, 0.0, false));
        s.received(delivery(2, 1, 10, 0.0, false));
        s.rendered(TileId::new(0, 0), 2, 0.5);
        s.rendered(TileId::new(1, 0), 2, 0.5); // drawn, but coarser than what arrived
        s.rendered(TileId::new(2, 0), 1, 1.5); // too late
        s.settle(0.9);
        assert_eq!(s.rendered_share(), None, "nothing settled yet");
        s.settle(2.0);
        assert_eq!((s.settled_bytes, s.rendered_bytes), (160, 100));
        assert_eq!(s.rendered_share(), Some(100.0 / 160.0));
        assert_eq!(s.received_bytes, 160);
    }

    #[test]
    fn predicted_deliveries_get_the_longer_window_and_count_as_hits() {
        let mut s = StreamStats::default();
        s.received(delivery(0, 4, 10, 0.0, true));
        s.received(delivery(1, 4, 10, 0.0, true));
        s.rendered(TileId::new(0, 0), 5, 1.8);
        s.settle(1.5);
        assert_eq!(s.hit_rate(), None);
        s.settle(2.5);
        assert_eq!(s.hit_rate(), Some(0.5));
        assert_eq!(s.predicted_settled, 2);
    }
}
