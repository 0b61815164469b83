//! How flight time advances: by each frame's measured cost (the wall clock), or by its modelled
//! cost (the simulated clock), either one times the device's CPU slowdown.
//!
//! On the simulated clock nothing is measured: a frame costs
//! `slowdown × (frame + triangle × triangles + fragment × fragments)` seconds
//! ([`CostModel`]), and a tile transfer costs `latency ± jitter + bytes / bandwidth` on a link
//! that carries one request at a time ([`LinkMeter`], read by the pager in
//! [`PagerMode::Simulated`]). The same command therefore gives the same `stats.csv`, byte for
//! byte.
//!
//! On the wall clock the frame's measured bookkeeping and drawing time is multiplied by the
//! slowdown, and a simulated link really waits — `slowdown` times faster than its profile says,
//! so that in flight time (which runs `slowdown` times faster than the wall) it has the
//! profile's bandwidth and latency.

use std::sync::{Arc, Mutex, PoisonError};

use crate::db::source::TileSource;
use crate::db::source::throttle::{DropDice, LatencyDice, LinkProfile, SimulatedLink};
use crate::engine::FrameReport;
use crate::engine::budget::FrameCost;
use crate::engine::paging::{PagerMode, TransferClock};
use crate::error::Result;
use crate::named::Named;

/// What one frame costs, in seconds of one core of this machine, as a function of what it drew.
///
/// One core whatever the device's thread count: a handheld's frame is below the rasterizer's
/// split point and stays on one thread, and what a second thread gives a larger frame depends
/// on the machine's load, not on the device (`examples/thread_cost.rs`, docs/pocketpc.md).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CostModel {
    /// Seconds per frame whatever it draws (clearing, culling, importance, set-up).
    pub frame_s: f64,
    /// Seconds per triangle assembled (transform, set-up, edge walk).
    pub triangle_s: f64,
    /// Seconds per pixel written (texture, shading, depth).
    pub fragment_s: f64,
}

impl CostModel {
    /// One core of this machine (a shared AMD EPYC core) rendering the PocketPC frame
    /// (320x240 RGB565, 16-bit depth, textured, Gouraud, fixed point) in `fly`, fitted to 28,000
    /// measured frames; the measurement and its limits are in `docs/pocketpc.md`.
    pub const HOST: CostModel = CostModel {
        frame_s: 0.4e-3,
        triangle_s: 0.65e-6,
        fragment_s: 20e-9,
    };

    /// Modelled seconds of a frame that drew `triangles` triangles and wrote `fragments` pixels.
    pub fn seconds(&self, triangles: u64, fragments: u64) -> f64 {
        self.frame_s + self.triangle_s * triangles as f64 + self.fragment_s * fragments as f64
    }
}

/// Share of the screen a flyover's terrain covers: the pixels a frame writes whatever its
/// triangle count (53,000–54,000 of the 76,800 at 320x240, `docs/pocketpc.md`).
pub const FLYOVER_COVERAGE: f64 = 0.7;

/// Where a frame's cost comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Clock {
    /// Measured bookkeeping and drawing time times `slowdown`.
    Wall {
        /// The device's CPU slowdown.
        slowdown: f64,
    },
    /// `model` times `slowdown`: deterministic.
    Simulated {
        /// The host's frame cost.
        model: CostModel,
        /// The device's CPU slowdown.
        slowdown: f64,
    },
}

impl Default for Clock {
    fn default() -> Self {
        Clock::Wall { slowdown: 1.0 }
    }
}

/// `wall` and `simulated` (on [`CostModel::HOST`]), with no slowdown.
impl Named for Clock {
    const KIND: &'static str = "clock";

    fn all() -> Vec<Self> {
        vec![
            Clock::Wall { slowdown: 1.0 },
            Clock::Simulated {
                model: CostModel::HOST,
                slowdown: 1.0,
            },
        ]
    }

    fn name(&self) -> &'static str {
        match self {
            Clock::Wall { .. } => "wall",
            Clock::Simulated { .. } => "simulated",
        }
    }
}

impl Clock {
    /// The same clock for a device whose CPU is `slowdown` times slower than this machine's.
    pub fn with_slowdown(self, slowdown: f64) -> Clock {
        match self {
            Clock::Wall { .. } => Clock::Wall { slowdown },
            Clock::Simulated { model, .. } => Clock::Simulated { model, slowdown },
        }
    }

    /// What a frame of a flyover on a `width` x `height` screen is expected to cost in device
    /// time before any is timed: the clock's cost model (on the wall clock, the one fitted to
    /// this machine, [`CostModel::HOST`]) with [`FLYOVER_COVERAGE`] of the screen written, times
    /// the slowdown. The budget controller starts from it ([`FrameCost`]).
    pub fn expected_cost(&self, width: u32, height: u32) -> FrameCost {
        let (model, slowdown) = match *self {
            Clock::Wall { slowdown } => (CostModel::HOST, slowdown),
            Clock::Simulated { model, slowdown } => (model, slowdown),
        };
        let pixels = FLYOVER_COVERAGE * f64::from(width) * f64::from(height);
        FrameCost {
            overhead_s: slowdown * (model.frame_s + model.fragment_s * pixels),
            triangle_s: slowdown * model.triangle_s,
        }
    }

    /// Seconds of device time the frame of `report` took.
    pub fn frame_seconds(&self, report: &FrameReport) -> f64 {
        match *self {
            Clock::Wall { slowdown } => {
                slowdown
                    * (report.paging_seconds + report.bookkeeping_seconds + report.draw_seconds)
            }
            Clock::Simulated { model, slowdown } => {
                slowdown * model.seconds(report.draw.triangles, report.draw.fragments)
            }
        }
    }

    /// Flight seconds a frame that cost `cost` occupies: its cost, but on the wall clock no less
    /// than a frame at twice `target_fps`, the wall waiting out the difference — no display
    /// shows frames faster, and a flight waiting for its tiles would otherwise spin through
    /// empty frames by the hundred thousand. The simulated clock's frames cost what they draw
    /// and are never paced, so its flights stay reproducible.
    pub fn pace(&self, cost: f64, target_fps: f64) -> f64 {
        let Clock::Wall { slowdown } = *self else {
            return cost;
        };
        if !(target_fps.is_finite() && target_fps > 0.0) {
            return cost;
        }
        let shortest = 0.5 / target_fps;
        if cost < shortest {
            // Flight time runs `slowdown` times faster than the wall.
            std::thread::sleep(std::time::Duration::from_secs_f64(
                (shortest - cost) / slowdown.max(f64::MIN_POSITIVE),
            ));
            shortest
        } else {
            cost
        }
    }

    /// Whether this clock is the simulated one.
    pub fn is_simulated(&self) -> bool {
        matches!(self, Clock::Simulated { .. })
    }

    /// The pager mode that goes with the clock: a fetch thread on the wall clock, fetches that
    /// complete at their simulated transfer time on the simulated clock.
    pub fn pager_mode(&self, queue_depth: usize) -> PagerMode {
        match self {
            Clock::Wall { .. } => PagerMode::Threaded { queue_depth },
            Clock::Simulated { .. } => PagerMode::Simulated { queue_depth },
        }
    }
}

/// The busy time of a simulated link that does not wait: every request adds its latency and
/// transfer time, in whole nanoseconds so that sums never depend on order or rounding.
#[derive(Debug, Default)]
pub struct LinkMeter {
    // Locked per tile read and per backlog query, never contended: a `Mutex`, not an
    // `AtomicU64`, which ARMv5TE lacks (and an `AtomicU32` of nanoseconds ends at 4.3 s).
    nanos: Mutex<u64>,
}

impl LinkMeter {
    fn nanos(&self) -> std::sync::MutexGuard<'_, u64> {
        self.nanos.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn add(&self, seconds: f64) {
        *self.nanos() += (seconds * 1e9).round() as u64;
    }
}

impl TransferClock for LinkMeter {
    fn busy_seconds(&self) -> f64 {
        *self.nanos() as f64 * 1e-9
    }
}

/// A [`TileSource`] behind a link that costs simulated time instead of waiting: each read adds
/// its delay (`latency ± jitter`, seeded) and `len / bandwidth` to its [`LinkMeter`], and dropped
/// reads (seeded dice, as in [`SimulatedLink`]) cost the same and fail. The pager reads in a
/// fixed order on the simulated clock, so the same seed gives the same delays and drops.
pub struct MeteredLink<S> {
    inner: S,
    profile: LinkProfile,
    dice: DropDice,
    delays: LatencyDice,
    meter: Arc<LinkMeter>,
}

impl<S: TileSource> MeteredLink<S> {
    /// Wraps `inner` with `profile`; the meter is shared with the pager.
    pub fn new(inner: S, profile: LinkProfile) -> (Self, Arc<LinkMeter>) {
        let meter = Arc::new(LinkMeter::default());
        let link = MeteredLink {
            inner,
            dice: DropDice::new(profile.drop_rate, profile.seed),
            delays: LatencyDice::new(&profile),
            profile,
            meter: Arc::clone(&meter),
        };
        (link, meter)
    }
}

impl<S: TileSource> TileSource for MeteredLink<S> {
    fn name(&self) -> &str {
        self.inner.name()
    }

    fn size(&self) -> Result<u64> {
        self.inner.size()
    }

    fn is_remote(&self) -> bool {
        self.inner.is_remote()
    }

    fn read_range(&self, offset: u64, len: u64) -> Result<Vec<u8>> {
        let seconds = self.delays.next() + self.profile.transfer_time(len);
        self.meter.add(seconds.as_secs_f64());
        if self.dice.roll() {
            return Err(crate::error::Error::invalid(
                self.inner.name(),
                format!("simulated link dropped the request for bytes {offset}+{len}"),
            ));
        }
        self.inner.read_range(offset, len)
    }

    fn checksum_failed(&self) -> Result<()> {
        self.inner.checksum_failed()
    }
}

/// Puts `source` behind `link` as `clock` needs it: metered (no waiting) on the simulated clock,
/// waiting `slowdown` times faster than the profile on the wall clock. Returns the source and,
/// on the simulated clock, the meter for the pager.
pub fn connect(
    source: Box<dyn TileSource>,
    link: Option<LinkProfile>,
    clock: &Clock,
) -> (Box<dyn TileSource>, Option<Arc<LinkMeter>>) {
    match (link, clock) {
        (None, _) => (source, None),
        (Some(profile), Clock::Simulated { .. }) => {
            let (link, meter) = MeteredLink::new(source, profile);
            (Box::new(link), Some(meter))
        }
        (Some(profile), Clock::Wall { slowdown }) => {
            let fast = LinkProfile {
                bandwidth_kbps: profile.bandwidth_kbps.map(|b| b * slowdown),
                latency: profile.latency.div_f64(*slowdown),
                jitter: profile.jitter.div_f64(*slowdown),
                ..profile
            };
            (Box::new(SimulatedLink::new(source, fast)), None)
        }
    }
}

#[cfg(test)]
mod tests {
    use std::time::Duration;

    use super::*;

    struct Bytes(Vec<u8>);

    impl TileSource for Bytes {
        fn name(&self) -> &str {
            "bytes"
        }
        fn size(&self) -> Result<u64> {
            Ok(self.0.len() as u64)
        }
        fn read_range(&self, offset: u64, len: u64) -> Result<Vec<u8>> {
            Ok(self.0[offset as usize..(offset + len) as usize].to_vec())
        }
    }

    #[test]
    fn a_metered_link_adds_latency_and_transfer_time_without_waiting() {
        let profile = LinkProfile {
            bandwidth_kbps: Some(8.0),
            latency: Duration::from_millis(50),
            ..LinkProfile::default()
        };
        let (link, meter) = MeteredLink::new(Bytes(vec![1; 4000]), profile);
        let started = std::time::Instant::now();
        assert_eq!(link.read_range(0, 1000).unwrap().len(), 1000);
        assert_eq!(link.read_range(1000, 500).unwrap().len(), 500);
        // 8 kbit/s = 1000 bytes/s: 1.05 s + 0.55 s.
        assert!(
            (meter.busy_seconds() - 1.6).abs() < 1e-9,
            "{}",
            meter.busy_seconds()
        );
        assert!(started.elapsed() < Duration::from_millis(500));
    }

    #[test]
    fn a_jittered_metered_link_costs_the_same_every_run_and_about_its_mean() {
        let profile = LinkProfile {
            latency: Duration::from_millis(50),
            jitter: Duration::from_millis(30),
            seed: 11,
            ..LinkProfile::default()
        };
        let run = |p: LinkProfile| {
            let (link, meter) = MeteredLink::new(Bytes(vec![0; 10]), p);
            let mut steps = Vec::new();
            for _ in 0..400 {
                let before = meter.busy_seconds();
                link.read_range(0, 10).unwrap();
                steps.push(meter.busy_seconds() - before);
            }
            steps
        };
        let a = run(profile);
        assert_eq!(a, run(profile));
        assert!(a.iter().all(|s| (0.02 - 1e-9..=0.08 + 1e-9).contains(s)));
        let mean = a.iter().sum::<f64>() / a.len() as f64;
        assert!((mean - 0.05).abs() < 0.003, "{mean}");
        assert_ne!(
            a,
            run(LinkProfile {
                seed: 12,
                ..profile
            })
        );
    }

    #[test]
    fn dropped_requests_cost_time_and_fail_the_same_way_every_run() {
        let profile = LinkProfile {
            latency: Duration::from_millis(10),
            drop_rate: 0.3,
            seed: 5,
            ..LinkProfile::default()
        };
        let run = || {
            let (link, meter) = MeteredLink::new(Bytes(vec![0; 10]), profile);
            let outcomes: Vec<bool> = (0..50).map(|_| link.read_range(0, 10).is_ok()).collect();
            (outcomes, meter.busy_seconds())
        };
        let (a, seconds) = run();
        assert_eq!(run().0, a);
        assert!(a.iter().any(|ok| !ok) && a.iter().any(|ok| *ok));
        assert!((seconds - 0.5).abs() < 1e-9);
    }

    #[test]
    fn the_simulated_clock_scales_the_model_and_ignores_measurements() {
        let model = CostModel {
            frame_s: 1e-3,
            triangle_s: 1e-6,
            fragment_s: 1e-8,
        };
        assert!((model.seconds(1000, 100_000) - 3e-3).abs() < 1e-12);
        let clock = Clock::Simulated {
            model,
            slowdown: 10.0,
        };
        assert!(clock.is_simulated());
        assert_eq!(clock.pager_mode(4), PagerMode::Simulated { queue_depth: 4 });
        assert_eq!(
            Clock::Wall { slowdown: 2.0 }.pager_mode(3),
            PagerMode::Threaded { queue_depth: 3 }
        );
    }
}
