//! Exponential back-off with jitter, the one rule every retry follows: the reader's between
//! attempts at one piece of a remote archive, the pager's between fetches of one tile.
//!
//! The `n`-th wait (from 1) is drawn from the upper half of `min(max, first · 2^(n-1))` ("equal
//! jitter"): waits double, so a struggling server is asked less and less often, and clients
//! that failed together do not come back together. The draw is a hash of (seed, key, n), not a
//! random number, so the same seed gives the same waits and simulated runs stay reproducible.

/// Waits that double from `first` up to `max` (in any unit: seconds, updates), with jitter.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Backoff {
    /// The ceiling of the first wait.
    pub first: f64,
    /// The ceiling of every wait.
    pub max: f64,
    /// Seeds the jitter.
    pub seed: u64,
}

impl Backoff {
    /// The wait after the `n`-th failure (from 1) of what `key` names (a tile, an offset):
    /// within `[c / 2, c]` for `c = min(max, first · 2^(n-1))`.
    pub fn wait(&self, key: u64, n: u32) -> f64 {
        let doublings = n.saturating_sub(1).min(60) as i32;
        let ceiling = (self.first * 2f64.powi(doublings)).min(self.max).max(0.0);
        let draw = mix(self.seed ^ mix(key ^ (u64::from(n) << 40)));
        // The top 53 bits as a fraction in [0, 1].
        let unit = (draw >> 11) as f64 / ((1u64 << 53) - 1) as f64;
        ceiling * (0.5 + 0.5 * unit)
    }
}

/// SplitMix64's finaliser: a well-spread 64-bit hash.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    const B: Backoff = Backoff {
        first: 1.0,
        max: 16.0,
        seed: 7,
    };

    #[test]
    fn waits_double_within_their_upper_half_up_to_the_ceiling() {
        for key in 0..200 {
            for n in 1..=8 {
                let ceiling = (2f64.powi(n as i32 - 1)).min(16.0);
                let w = B.wait(key, n);
                assert!(w >= ceiling / 2.0 && w <= ceiling, "{key} {n}: {w}");
            }
        }
        assert!(B.wait(3, u32::MAX) <= 16.0);
    }

    #[test]
    fn the_jitter_spreads_keys_and_repeats_for_a_seed() {
        let waits: Vec<f64> = (0..100).map(|k| B.wait(k, 4)).collect();
        let again: Vec<f64> = (0..100).map(|k| B.wait(k, 4)).collect();
        assert_eq!(waits, again);
        let low = waits.iter().filter(|&&w| w < 6.0).count();
        assert!((20..=80).contains(&low), "{low} of 100 in the lower half");
        let other = Backoff { seed: 8, ..B };
        assert_ne!(
            waits,
            (0..100).map(|k| other.wait(k, 4)).collect::<Vec<_>>()
        );
    }
}
