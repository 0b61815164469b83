//! A simulated network link: latency before the first byte, a bandwidth cap, and requests that
//! fail at a given rate, decided by a seeded random generator so a run can be repeated.
//!
//! [`LinkProfile`] is shared by [`SimulatedLink`] (a [`TileSource`] wrapper, no network at all)
//! and by `stripmask serve`, which paces its answers with [`PacedReader`].

use std::io::Read;
use std::sync::Mutex;
use std::time::{Duration, Instant};

use super::TileSource;
use crate::error::{Error, Result};

/// Latency, bandwidth and drop rate of a link.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LinkProfile {
    /// Bandwidth in kilobits (1000 bits) per second; `None` is unlimited.
    pub bandwidth_kbps: Option<f64>,
    /// Delay before the first byte of every answer.
    pub latency: Duration,
    /// Fraction of requests that fail, 0 ..= 1.
    pub drop_rate: f64,
    /// Seed of the drop decisions.
    pub seed: u64,
}

impl Default for LinkProfile {
    fn default() -> Self {
        LinkProfile {
            bandwidth_kbps: None,
            latency: Duration::ZERO,
            drop_rate: 0.0,
            seed: 1,
        }
    }
}

impl LinkProfile {
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
        let mut s = self.state.lock().unwrap_or_else(|p| p.into_inner());
        *s = s.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = *s;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        ((z >> 11) as f64 / (1u64 << 53) as f64) < self.rate
    }
}

/// A reader that never delivers faster than the link's bandwidth.
pub struct PacedReader<R> {
    inner: R,
    bytes_per_second: Option<f64>,
    start: Option<Instant>,
    sent: u64,
}

impl<R> PacedReader<R> {
    /// Paces `inner` at `profile`'s bandwidth.
    pub fn new(inner: R, profile: &LinkProfile) -> Self {
        PacedReader {
            inner,
            bytes_per_second: profile.bytes_per_second(),
            start: None,
            sent: 0,
        }
    }
}

impl<R: Read> Read for PacedReader<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let Some(bps) = self.bytes_per_second else {
            return self.inner.read(buf);
        };
        let start = *self.start.get_or_insert_with(Instant::now);
        // Small chunks (at most ~20 ms of data) keep the pace smooth.
        let chunk = ((bps / 50.0) as usize).clamp(1, buf.len().max(1));
        let take = chunk.min(buf.len());
        let n = self.inner.read(&mut buf[..take])?;
        self.sent += n as u64;
        let due = Duration::from_secs_f64(self.sent as f64 / bps);
        if let Some(wait) = due.checked_sub(start.elapsed()) {
            std::thread::sleep(wait);
        }
        Ok(n)
    }
}

/// A [`TileSource`] behind a simulated link: every read waits for the latency and the transfer
/// time, and a dropped read fails (as a lost connection would).
pub struct SimulatedLink<S> {
    inner: S,
    profile: LinkProfile,
    dice: DropDice,
}

impl<S: TileSource> SimulatedLink<S> {
    /// Wraps `inner` with `profile`.
    pub fn new(inner: S, profile: LinkProfile) -> Self {
        SimulatedLink {
            dice: DropDice::new(profile.drop_rate, profile.seed),
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

    fn read_range(&self, offset: u64, len: u64) -> Result<Vec<u8>> {
        std::thread::sleep(self.profile.latency + self.profile.transfer_time(len));
        if self.dice.roll() {
            return Err(Error::invalid(
                self.inner.name(),
                format!("simulated link dropped the request for bytes {offset}+{len}"),
            ));
        }
        self.inner.read_range(offset, len)
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
    fn paced_reader_takes_the_transfer_time() {
        let profile = LinkProfile {
            bandwidth_kbps: Some(800.0),
            ..LinkProfile::default()
        };
        let data = vec![7u8; 5000];
        let t = Instant::now();
        let mut out = Vec::new();
        PacedReader::new(&data[..], &profile)
            .read_to_end(&mut out)
            .unwrap();
        assert_eq!(out, data);
        // 5000 bytes at 100 000 bytes/s = 50 ms.
        assert!(
            t.elapsed() >= Duration::from_millis(45),
            "{:?}",
            t.elapsed()
        );
    }
}
