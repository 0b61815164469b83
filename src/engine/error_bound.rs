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
        masks
            .levels()
            .iter()
            .rev()
            .copied()
            .find(|&l| {
                errors
                    .get(l)
                    .is_some_and(|&e| f64::from(e) * pixels_per_metre <= tau)
            })
            .unwrap_or(0)
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
