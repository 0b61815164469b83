//! What the engine draws for: the screen's size and the vertical field of view, given once
//! when the engine is made (the texture mips it keeps and the errors it allows depend on them)
//! and checked against every target it draws into.

use crate::error::{Error, Result};

/// A screen of `width` × `height` pixels seen with a vertical field of view `fov_y`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Viewport {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Vertical field of view, radians.
    pub fov_y: f64,
}

impl Viewport {
    /// A `width` × `height` screen with a 60° vertical field of view.
    pub fn new(width: u32, height: u32) -> Viewport {
        Viewport {
            width,
            height,
            fov_y: 60f64.to_radians(),
        }
    }

    /// The same screen with a vertical field of view of `fov_y` radians.
    pub fn with_fov_y(self, fov_y: f64) -> Viewport {
        Viewport { fov_y, ..self }
    }

    /// Width over height.
    pub fn aspect(&self) -> f64 {
        f64::from(self.width) / f64::from(self.height)
    }

    /// The focal length in pixels: a metre seen from a metre away spans this many pixels.
    pub fn focal_px(&self) -> f64 {
        f64::from(self.height) / (2.0 * (self.fov_y / 2.0).tan())
    }

    /// Refuses an empty screen and a field of view that is not an angle between 0 and 180°.
    pub fn check(&self) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(Error::setting(
                "viewport (pixels)",
                format!("{}x{}", self.width, self.height),
                "at least 1x1",
            ));
        }
        if !(self.fov_y > 0.0 && self.fov_y < std::f64::consts::PI) {
            return Err(Error::setting(
                "vertical field of view (radians)",
                self.fov_y,
                "between 0 and π",
            ));
        }
        Ok(())
    }

    /// Refuses a target of another size than the viewport.
    pub fn check_target(&self, size: (u32, u32)) -> Result<()> {
        if size == (self.width, self.height) {
            return Ok(());
        }
        Err(Error::setting(
            "target size (pixels)",
            format!("{}x{}", size.0, size.1),
            format!(
                "the engine's viewport, {}x{} (make the engine for the target's size)",
                self.width, self.height
            ),
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_metre_at_the_focal_length_spans_a_pixel_per_metre_of_distance() {
        let v = Viewport::new(320, 240).with_fov_y(90f64.to_radians());
        assert!((v.focal_px() - 120.0).abs() < 1e-9);
        assert!((v.aspect() - 4.0 / 3.0).abs() < 1e-12);
    }

    #[test]
    fn empty_screens_bad_angles_and_other_targets_are_refused_by_name() {
        assert!(Viewport::new(320, 240).check().is_ok());
        let e = Viewport::new(0, 240).check().unwrap_err().to_string();
        assert!(e.contains("viewport") && e.contains("0x240"), "{e}");
        for fov in [0.0, -1.0, 4.0, f64::NAN] {
            let e = Viewport::new(8, 8)
                .with_fov_y(fov)
                .check()
                .unwrap_err()
                .to_string();
            assert!(e.contains("field of view"), "{e}");
        }
        let e = Viewport::new(320, 240)
            .check_target((640, 480))
            .unwrap_err()
            .to_string();
        assert!(e.contains("640x480") && e.contains("320x240"), "{e}");
    }
}
