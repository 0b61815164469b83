//! What the tests of the integer pipeline's set-up share: the extent of a small triangle and
//! a screen that cuts nothing.

use crate::edge::PixelRect;
use crate::fixed_point::{MAX_DIMENSION, SUBPIXEL_ONE};

/// The last sub-pixel of the 17 pixel columns (rows) a small triangle's vertices lie in.
pub(super) const EDGE: i64 = 17 * SUBPIXEL_ONE - 1;

/// The largest screen: triangles on it are cut by no scissor.
pub(super) const SCREEN: PixelRect = PixelRect {
    x0: 0,
    y0: 0,
    x1: MAX_DIMENSION as i32,
    y1: MAX_DIMENSION as i32,
};
