//! The pixel-error bound τ: detail the picture needs, beside the detail time allows.
//!
//! The triangle budget ([`crate::engine::budget`]) caps detail when time is short. τ caps it
//! when the picture is already exact enough: no tile is drawn finer than the coarsest mask level
//! whose geometric error (the largest height difference to the full tile, from the archive,
//! [`crate::db::level_error`]), seen from the tile's nearest point, spans at most τ pixels
//! (Schneider & Westermann 2006). What a tile does not spend stays in the pool for the others.
//!
//! The default is 1 pixel: below that a coarser mask moves no silhouette or shading edge by a
//! whole pixel, so the picture is as good as the full tiles' to the eye, and a fast machine
//! stops spending triangles (and battery) the screen cannot show. `0` turns the bound off.

use crate::engine::masks::MaskSet;
use crate::error::{Error, Result};

/// The largest screen-space geometric error a tile may be drawn with, when time allows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ErrorBound {
    /// No bound: the budget alone decides (every tile as fine as it affords).
    Off,
    /// At most this many pixels (positive, finite).
    Pixels(f64),
}

impl Default for ErrorBound {
    /// One pixel: see the module documentation.
    fn default() -> Self {
        ErrorBound::Pixels(Self::DEFAULT_PIXELS)
    }
}

impl ErrorBound {
    /// The default bound, pixels.
    pub const DEFAULT_PIXELS: f64 = 1.0;

    /// The bound of `pixels` (`0`: off); an [`Error::InvalidSetting`] named `name` for a
    /// negative or non-finite value.
    pub fn from_pixels(name: &'static str, pixels: f64) -> Result<Self> {
        if pixels == 0.0 {
            Ok(ErrorBound::Off)
        } else if pixels > 0.0 && pixels.is_finite() {
            Ok(ErrorBound::Pixels(pixels))
        } else {
            Err(Error::setting(
                name,
                pixels,
                "0 (off) or a positive number of pixels",
            ))
        }
    }

    /// The bound in pixels, `0` when off (as the command line and `stats.csv` spell it).
    pub fn pixels(&self) -> f64 {
        match *self {
            ErrorBound::Off => 0.0,
            ErrorBound::Pixels(px) => px,
        }
    }

    /// The coarsest level of `masks`' set whose error (`errors[level]`, metres) spans at most
    /// the bound at `pixels_per_metre`: the finest a tile needs. Level 0 when the bound is off.
    pub fn coarsest_level(&self, errors: &[f32], masks: &MaskSet, pixels_per_metre: f64) -> usize {
        let ErrorBound::Pixels(tau) = *self else {
            return 0;
        };
        let within = Within::new(tau, pixels_per_metre);
        masks
            .levels()
            .iter()
            .rev()
            .copied()
            .find(|&l| errors.get(l).is_some_and(|&e| within.holds(e)))
            .unwrap_or(0)
    }
}

/// `f64::from(e) * pixels_per_metre <= tau` for many errors `e`: the product's rounding is
/// monotone in `e`, so the non-negative errors that pass are those up to the largest `f32`
/// that passes, found once (a division and a few products) and compared by their bits, which
/// order non-negative floats as integers. On a core without an FPU each product and
/// comparison is a library call, and a tile asks for every level.
struct Within {
    tau: f64,
    pixels_per_metre: f64,
    /// The bits of the largest `f32` that passes, where there is one and it was found.
    largest: Option<u32>,
}

impl Within {
    fn new(tau: f64, pixels_per_metre: f64) -> Self {
        let passes = |bits: u32| f64::from(f32::from_bits(bits)) * pixels_per_metre <= tau;
        let usable =
            pixels_per_metre > 0.0 && pixels_per_metre.is_finite() && tau.is_finite() && passes(0);
        let largest = usable.then(|| {
            // Within an ulp or two of the quotient (its magnitude: τ may be -0): a few steps
            // find the boundary.
            let quotient = ((tau / pixels_per_metre) as f32).to_bits() & !(1 << 31);
            let mut b = quotient.min(f32::MAX.to_bits());
            for _ in 0..8 {
                if !passes(b) {
                    b -= 1;
                } else if b < f32::MAX.to_bits() && passes(b + 1) {
                    b += 1;
                } else {
                    return Some(b);
                }
            }
            None
        });
        Within {
            tau,
            pixels_per_metre,
            largest: largest.flatten(),
        }
    }

    /// Whether error `e` spans at most τ pixels.
    fn holds(&self, e: f32) -> bool {
        match self.largest {
            Some(b) if e.is_sign_positive() => e.to_bits() <= b,
            _ => f64::from(e) * self.pixels_per_metre <= self.tau,
        }
    }
}

/// What capped a frame's detail.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Bound {
    /// The triangle budget: some tile draws coarser than τ (or full resolution) asks.
    Budget,
    /// τ: every tile is as fine as the error bound asks, with triangles to spare.
    Error,
    /// τ is off and every tile draws as fine as it can: nothing finer exists.
    Full,
}

impl Bound {
    /// Its name in the HUD and `stats.csv`.
    pub fn name(&self) -> &'static str {
        match self {
            Bound::Budget => "budget",
            Bound::Error => "tau",
            Bound::Full => "full",
        }
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::engine::masks::LevelSet;

    #[test]
    fn the_coarsest_level_within_the_bound_wins_even_past_a_worse_one() {
        let masks = MaskSet::new(5, LevelSet::All);
        // Levels 0..=3; level 2 is worse than level 3 (errors need not grow with the level).
        let errors = [0.0, 1.0, 5.0, 2.0];
        let tau = ErrorBound::Pixels(2.0);
        assert_eq!(tau.coarsest_level(&errors, &masks, 1.0), 3);
        assert_eq!(tau.coarsest_level(&errors, &masks, 1.5), 1);
        assert_eq!(tau.coarsest_level(&errors, &masks, 100.0), 0);
        assert_eq!(ErrorBound::Off.coarsest_level(&errors, &masks, 1e-9), 0);
        let pow2 = MaskSet::new(5, LevelSet::PowerOfTwo);
        assert_eq!(tau.coarsest_level(&errors, &pow2, 1.0), 3);
        assert_eq!(tau.coarsest_level(&errors, &pow2, 1.5), 1);
    }

    /// An error: ordinary, tiny, huge, special, or next to `f32::MAX`.
    fn error() -> impl Strategy<Value = f32> {
        prop_oneof![
            8 => 0.0..1e4f32,
            1 => any::<f32>(),
            1 => prop::sample::select(vec![0.0, -0.0, f32::MIN_POSITIVE, f32::MAX, f32::INFINITY, f32::NAN, -1.0]),
        ]
    }

    proptest! {
        /// The bound by the bits of the largest error within it answers as the product does,
        /// for errors at and around that largest one and anywhere.
        #[test]
        fn errors_within_the_bound_by_their_bits_are_those_by_the_product(
            tau in prop_oneof![4 => 1e-3..1e2f64, 1 => any::<f64>()],
            ppm in prop_oneof![4 => 1e-6..1e6f64, 1 => any::<f64>()],
            e in error(),
            near in -3i32..=3,
        ) {
            let within = Within::new(tau, ppm);
            let exact = |e: f32| f64::from(e) * ppm <= tau;
            prop_assert_eq!(within.holds(e), exact(e));
            // The neighbours of the quotient, where the answer changes.
            let q = ((tau / ppm) as f32).to_bits().wrapping_add_signed(near);
            let e = f32::from_bits(q);
            prop_assert_eq!(within.holds(e), exact(e), "{}", e);
        }
    }

    #[test]
    fn the_largest_error_within_the_bound_is_found_for_ordinary_views() {
        for (tau, ppm) in [(1.0, 0.37), (1.0, 3.0), (0.5, 1e-4), (2.0, 812.5)] {
            let within = Within::new(tau, ppm);
            let b = within.largest.expect("found");
            assert!(f64::from(f32::from_bits(b)) * ppm <= tau);
            assert!(f64::from(f32::from_bits(b + 1)) * ppm > tau);
        }
    }

    #[test]
    fn zero_is_off_and_bad_values_are_refused_by_name() {
        assert_eq!(ErrorBound::from_pixels("τ", 0.0).unwrap(), ErrorBound::Off);
        assert_eq!(
            ErrorBound::from_pixels("τ", 0.5).unwrap(),
            ErrorBound::Pixels(0.5)
        );
        for bad in [-1.0, f64::NAN, f64::INFINITY] {
            let e = ErrorBound::from_pixels("--max-error-px", bad).unwrap_err();
            assert!(e.to_string().contains("--max-error-px"), "{e}");
        }
        assert_eq!(ErrorBound::default().pixels(), 1.0);
    }
}
