//! Placing a frame on an output of another size: which output pixel shows which frame pixel.
//!
//! [`Fit`] is the choice, in every build (a command names it before it knows which presenters
//! it has); the placement it makes exists where a window or the framebuffer does.

/// How a frame is placed on an output of a different size. Either way the frame is centred and
/// the output outside it is black.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Fit {
    /// One frame pixel per output pixel: a smaller frame is centred, a larger one is cropped
    /// to its centre.
    #[default]
    Center,
    /// Scaled with nearest-neighbour sampling, up or down, to the largest size that fits the
    /// output with the frame's aspect ratio.
    Scale,
}

/// The output rectangle a frame covers and, for each of its columns and rows, the frame
/// column or row it shows.
#[cfg(any(feature = "window", all(feature = "fbdev", target_os = "linux")))]
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) struct Placement {
    /// The frame size (width, height) this placement is for.
    pub frame: (u32, u32),
    /// The output size (width, height) this placement is for.
    pub output: (u32, u32),
    /// Left edge on the output.
    pub x: u32,
    /// Top edge on the output.
    pub y: u32,
    /// Frame column of each covered output column.
    pub columns: Vec<u32>,
    /// Frame row of each covered output row.
    pub rows: Vec<u32>,
}

#[cfg(any(feature = "window", all(feature = "fbdev", target_os = "linux")))]
impl Placement {
    /// Places a `frame` (width, height) on an `output` (width, height); both non-zero.
    pub fn new(frame: (u32, u32), output: (u32, u32), fit: Fit) -> Self {
        let (fw, fh) = frame;
        let (ow, oh) = output;
        let (w, h) = match fit {
            Fit::Center => (fw.min(ow), fh.min(oh)),
            Fit::Scale => {
                // Compare the aspect ratios exactly: fw / fh >= ow / oh.
                if u64::from(fw) * u64::from(oh) >= u64::from(ow) * u64::from(fh) {
                    (ow, scaled(fh, ow, fw).clamp(1, oh))
                } else {
                    (scaled(fw, oh, fh).clamp(1, ow), oh)
                }
            }
        };
        let axis = |size: u32, covered: u32| -> Vec<u32> {
            match fit {
                Fit::Center => {
                    let crop = (size - covered) / 2;
                    (crop..crop + covered).collect()
                }
                // The frame pixel under the centre of each output pixel.
                Fit::Scale => (0..covered)
                    .map(|i| scaled(2 * i + 1, size, 2 * covered))
                    .collect(),
            }
        };
        Self {
            frame,
            output,
            x: (ow - w) / 2,
            y: (oh - h) / 2,
            columns: axis(fw, w),
            rows: axis(fh, h),
        }
    }
}

/// `a * b / c`, rounded down, without overflow.
#[cfg(any(feature = "window", all(feature = "fbdev", target_os = "linux")))]
fn scaled(a: u32, b: u32, c: u32) -> u32 {
    (u64::from(a) * u64::from(b) / u64::from(c)) as u32
}

#[cfg(all(
    test,
    any(feature = "window", all(feature = "fbdev", target_os = "linux"))
))]
mod tests {
    use super::*;

    #[test]
    fn a_frame_of_the_output_size_maps_one_to_one_in_both_modes() {
        for fit in [Fit::Center, Fit::Scale] {
            let p = Placement::new((7, 5), (7, 5), fit);
            assert_eq!((p.x, p.y), (0, 0));
            assert_eq!(p.columns, (0..7).collect::<Vec<_>>());
            assert_eq!(p.rows, (0..5).collect::<Vec<_>>());
        }
    }

    #[test]
    fn center_puts_a_small_frame_in_the_middle_and_crops_a_large_one() {
        let p = Placement::new((4, 2), (10, 7), Fit::Center);
        assert_eq!((p.x, p.y, p.columns.len(), p.rows.len()), (3, 2, 4, 2));
        let p = Placement::new((10, 9), (4, 3), Fit::Center);
        assert_eq!((p.x, p.y), (0, 0));
        assert_eq!(p.columns, [3, 4, 5, 6]);
        assert_eq!(p.rows, [3, 4, 5]);
    }

    #[test]
    fn scale_keeps_the_aspect_ratio_and_samples_pixel_centres() {
        // 8x4 onto 4x4: halves to 4x2, letterboxed one row top and bottom.
        let p = Placement::new((8, 4), (4, 4), Fit::Scale);
        assert_eq!((p.x, p.y), (0, 1));
        assert_eq!(p.columns, [1, 3, 5, 7]);
        assert_eq!(p.rows, [1, 3]);
        // 2x3 onto 9x6: doubles to 4x6, pillarboxed.
        let p = Placement::new((2, 3), (9, 6), Fit::Scale);
        assert_eq!((p.x, p.y), (2, 0));
        assert_eq!(p.columns, [0, 0, 1, 1]);
        assert_eq!(p.rows, [0, 0, 1, 1, 2, 2]);
    }

    #[test]
    fn scale_never_collapses_a_thin_frame_to_nothing() {
        let p = Placement::new((1000, 1), (10, 10), Fit::Scale);
        assert_eq!((p.columns.len(), p.rows.len()), (10, 1));
        assert!(p.columns.iter().all(|&c| c < 1000));
    }
}
