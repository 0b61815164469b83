//! Resampling rows east-west so that a grid whose columns are closer (or farther) apart than
//! its rows gets square cells, as the engine draws them.

/// Linear resampling of rows of `source_width` samples to columns `step` source columns apart.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EastWest {
    source_width: usize,
    width: usize,
    /// Source columns per output column.
    step: f64,
}

impl EastWest {
    /// Rows of `source_width` samples whose columns are `scale` times as far apart as the rows
    /// are: the output keeps the rows' spacing on both axes, as many columns as fit within the
    /// source's extent.
    pub fn new(source_width: usize, scale: f64) -> EastWest {
        let step = 1.0 / scale;
        let extent = (source_width.max(1) - 1) as f64 * scale;
        // A hair of tolerance, so that an extent of exactly n cells keeps its last column.
        let width = (extent + 1e-9).floor() as usize + 1;
        EastWest {
            source_width,
            width: width.max(2),
            step,
        }
    }

    /// Samples per output row.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Samples per input row.
    pub fn source_width(&self) -> usize {
        self.source_width
    }

    /// Writes `source` resampled into `out` (`width()` samples).
    pub fn apply(&self, source: &[f32], out: &mut [f32]) {
        let last = self.source_width - 1;
        for (k, o) in out.iter_mut().enumerate() {
            let x = (k as f64 * self.step).min(last as f64);
            let i = (x.floor() as usize).min(last.saturating_sub(1));
            let t = (x - i as f64) as f32;
            let (a, b) = (source[i], source[(i + 1).min(last)]);
            *o = a + (b - a) * t;
        }
    }

    /// Writes which samples of a resampled row come from nodata alone: an output sample is
    /// nodata when both source samples it interpolates between were.
    pub fn apply_nodata(&self, source: &[bool], out: &mut [bool]) {
        let last = self.source_width - 1;
        for (k, o) in out.iter_mut().enumerate() {
            let x = (k as f64 * self.step).min(last as f64);
            let i = (x.floor() as usize).min(last.saturating_sub(1));
            *o = source[i] && source[(i + 1).min(last)];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn half_as_far_apart_keeps_every_other_column() {
        let r = EastWest::new(9, 0.5);
        assert_eq!(r.width(), 5);
        let src: Vec<f32> = (0..9).map(|i| i as f32 * 10.0).collect();
        let mut out = vec![0.0; 5];
        r.apply(&src, &mut out);
        assert_eq!(out, [0.0, 20.0, 40.0, 60.0, 80.0]);
    }

    #[test]
    fn between_columns_interpolates_linearly() {
        let r = EastWest::new(3, 0.8);
        assert_eq!(r.width(), 2);
        let mut out = vec![0.0; 2];
        r.apply(&[0.0, 8.0, 16.0], &mut out);
        assert_eq!(out, [0.0, 10.0]);
    }
}
