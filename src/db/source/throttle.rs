//! A simulated network link: latency before the first byte (varying by up to a jitter), a
//! bandwidth cap, and requests that fail at a given rate, decided by seeded random generators so
//! a run can be repeated.
//!
//! [`LinkProfile`] is shared by [`SimulatedLink`] (a [`TileSource`] wrapper, no network at all),
//! by the simulated clock's metered link, and by `stripmask serve`, whose link layer delays each
//! answer by [`LatencyDice`], drops with [`DropDice`] and paces the body at the bandwidth.

use std::sync::Mutex;
use std::time::Duration;

use super::{CancelToken, TileSource};
use crate::error::{Error, Result};

/// Latency, jitter, bandwidth and drop rate of a link.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkProfile {
    /// Bandwidth in kilobits (1000 bits) per second; `None` is unlimited.
    pub bandwidth_kbps: Option<f64>,
    /// Mean delay before the first byte of every answer.
    pub latency: Duration,
    /// Each request's delay is drawn uniformly from `latency ± jitter` (never below zero), so
    /// that answers do not arrive like clockwork.
    pub jitter: Duration,
    /// Fraction of requests that fail, 0 ..= 1.
    pub drop_rate: f64,
    /// Seed of the drop decisions.
    pub seed: u64,
}

impl Default for LinkProfile {
    fn default() -> Self {
        Self::UNLIMITED
    }
}

impl LinkProfile {
    /// No bandwidth cap, no latency, no drops (seed 1): tiles come as from the source itself.
    pub const UNLIMITED: LinkProfile = LinkProfile {
        bandwidth_kbps: None,
        latency: Duration::ZERO,
        jitter: Duration::ZERO,
        drop_rate: 0.0,
        seed: 1,
    };

    /// The slowest bandwidth a link may have, kbit/s: slower, one tile would take days, and
    /// transfer times overflow what a clock can wait.
    pub const MIN_BANDWIDTH_KBPS: f64 = 0.1;
    /// The longest latency or jitter a link may have.
    pub const MAX_DELAY: Duration = Duration::from_secs(3600);

    /// The profile when every number is one a link can have: a finite bandwidth of at least
    /// [`Self::MIN_BANDWIDTH_KBPS`], latency and jitter up to [`Self::MAX_DELAY`], a drop rate
    /// in 0 ..= 1.
    pub fn validate(&self) -> Result<()> {
        if let Some(b) = self.bandwidth_kbps
            && !(b.is_finite() && b >= Self::MIN_BANDWIDTH_KBPS)
        {
            return Err(Error::setting(
                "--bandwidth-kbps",
                b,
                format!("a finite number of at least {}", Self::MIN_BANDWIDTH_KBPS),
            ));
        }
        for (name, d) in [("--latency-ms", self.latency), ("--jitter-ms", self.jitter)] {
            if d > Self::MAX_DELAY {
                return Err(Error::setting(
                    name,
                    d.as_secs_f64() * 1e3,
                    format!("at most {} ms", Self::MAX_DELAY.as_millis()),
                ));
            }
        }
        if !(0.0..=1.0).contains(&self.drop_rate) {
            return Err(Error::setting(
                "--drop-rate",
                self.drop_rate,
                "a fraction between 0 and 1",
            ));
        }
        Ok(())
    }

    /// Whether the link changes nothing: no bandwidth cap, no delay, no drops.
    pub fn is_unlimited(&self) -> bool {
        self.bandwidth_kbps.is_none()
            && self.latency.is_zero()
            && self.jitter.is_zero()
            && self.drop_rate == 0.0
    }

    /// Bytes per second, or `None` when unlimited.
    pub fn bytes_per_second(&self) -> Option<f64> {
        self.bandwidth_kbps
            .filter(|k| *k > 0.0)
            .map(|k| k * 1000.0 / 8.0)
    }

    /// Time to send `bytes` at this link's bandwidth, latency excluded.
    pub fn transfer_time(&self, bytes: u64) -> Duration {
        match self.bytes_per_second() {
            Some(bps) => Duration::from_secs_f64(bytes as f64 / bps),
            None => Duration::ZERO,
        }
    }
}

/// The next number of a SplitMix64 stream, uniform in `[0, 1)`.
fn next_unit(state: &Mutex<u64>) -> f64 {
    let mut s = state.lock().unwrap_or_else(|p| p.into_inner());
    *s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *s;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^= z >> 31;
    (z >> 11) as f64 / (1u64 << 53) as f64
}

/// Deterministic drop decisions (SplitMix64 from the profile's seed).
pub struct DropDice {
    rate: f64,
    state: Mutex<u64>,
}

impl DropDice {
    /// Dice that fail `rate` of the rolls.
    pub fn new(rate: f64, seed: u64) -> Self {
        DropDice {
            rate: rate.clamp(0.0, 1.0),
            state: Mutex::new(seed),
        }
    }

    /// Whether the next request is dropped.
    pub fn roll(&self) -> bool {
        if self.rate <= 0.0 {
            return false;
        }
        next_unit(&self.state) < self.rate
    }
}

/// Deterministic per-request delays: uniform in `latency ± jitter`, never below zero. The
/// stream is derived from the profile's seed but is not the drop dice' stream, so adding jitter
/// to a link leaves its drop decisions as they were.
pub struct LatencyDice {
    latency: Duration,
    jitter: Duration,
    state: Mutex<u64>,
}

impl LatencyDice {
    /// The delays of `profile`'s requests.
    pub fn new(profile: &LinkProfile) -> Self {
        LatencyDice {
            latency: profile.latency,
            jitter: profile.jitter,
            state: Mutex::new(profile.seed ^ 0x6A09_E667_F3BC_C908),
        }
    }

    /// The next request's delay before its first byte.
    pub fn next(&self) -> Duration {
        if self.jitter.is_zero() {
            return self.latency;
        }
        let offset = self.jitter.as_secs_f64() * (2.0 * next_unit(&self.state) - 1.0);
        Duration::from_secs_f64((self.latency.as_secs_f64() + offset).max(0.0))
    }
}

/// A [`TileSource`] behind a simulated link: every read waits for its delay (latency ± jitter)
/// and the transfer time, and a dropped read fails (as a lost connection would).
pub struct SimulatedLink<S> {
    inner: S,
    profile: LinkProfile,
    dice: DropDice,
    delays: LatencyDice,
}

impl<S: TileSource> SimulatedLink<S> {
    /// Wraps `inner` with `profile`.
    pub fn new(inner: S, profile: LinkProfile) -> Self {
        SimulatedLink {
            dice: DropDice::new(profile.drop_rate, profile.seed),
            delays: LatencyDice::new(&profile),
            inner,
            profile,
        }
    }
}

impl<S: TileSource> TileSource for SimulatedLink<S> {
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
        self.read_range_cancellable(offset, len, &CancelToken::new())
    }

    /// Waits out the delay and the transfer, then reads from the inner source with `cancel`.
    fn read_range_cancellable(
        &self,
        offset: u64,
        len: u64,
        cancel: &CancelToken,
    ) -> Result<Vec<u8>> {
        std::thread::sleep(self.delays.next() + self.profile.transfer_time(len));
        if self.dice.roll() {
            return Err(Error::invalid(
                self.inner.name(),
                format!("simulated link dropped the request for bytes {offset}+{len}"),
            ));
        }
        self.inner.read_range_cancellable(offset, len, cancel)
    }

    fn checksum_failed(&self) -> Result<()> {
        self.inner.checksum_failed()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dice_are_deterministic_and_near_their_rate() {
        let a: Vec<bool> = (0..1000)
            .map({
                let d = DropDice::new(0.25, 7);
                move |_| d.roll()
            })
            .collect();
        let b: Vec<bool> = (0..1000)
            .map({
                let d = DropDice::new(0.25, 7);
                move |_| d.roll()
            })
            .collect();
        assert_eq!(a, b);
        let drops = a.iter().filter(|&&x| x).count();
        assert!((200..300).contains(&drops), "{drops}");
        assert!(!DropDice::new(0.0, 7).roll());
    }

    #[test]
    fn jittered_delays_repeat_spread_over_the_range_and_keep_the_drops() {
        let profile = LinkProfile {
            latency: Duration::from_millis(50),
            jitter: Duration::from_millis(20),
            drop_rate: 0.25,
            seed: 9,
            ..LinkProfile::default()
        };
        let delays = |p: &LinkProfile| {
            let dice = LatencyDice::new(p);
            (0..1000).map(|_| dice.next()).collect::<Vec<_>>()
        };
        let a = delays(&profile);
        assert_eq!(a, delays(&profile));
        let (lo, hi) = (Duration::from_millis(30), Duration::from_millis(70));
        assert!(a.iter().all(|d| (lo..=hi).contains(d)));
        let ms: Vec<f64> = a.iter().map(|d| d.as_secs_f64() * 1e3).collect();
        let mean = ms.iter().sum::<f64>() / ms.len() as f64;
        assert!((mean - 50.0).abs() < 1.5, "mean {mean}");
        assert!(ms.iter().any(|&m| m < 35.0) && ms.iter().any(|&m| m > 65.0));
        // Never below zero; no jitter is the latency itself.
        let wide = LinkProfile {
            latency: Duration::from_millis(5),
            jitter: Duration::from_millis(50),
            ..profile
        };
        assert!(delays(&wide).contains(&Duration::ZERO));
        let steady = LinkProfile {
            jitter: Duration::ZERO,
            ..profile
        };
        assert!(delays(&steady).iter().all(|d| *d == profile.latency));
        // The drop decisions do not depend on the jitter.
        let drops = |p: &LinkProfile| {
            let dice = DropDice::new(p.drop_rate, p.seed);
            (0..200).map(|_| dice.roll()).collect::<Vec<_>>()
        };
        assert_eq!(drops(&profile), drops(&steady));
    }
}
