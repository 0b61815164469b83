//! Frame rows as 8-bit RGB with the HUD overlay blended in: the one place every presenter
//! reads frame pixels from.

use image::RgbaImage;
use stripmask_raster::{ColorBuffer, Framebuffer, rgb565_to_rgb};

use crate::Overlay;

/// Reads frame rows, composited with an optional overlay, into a reused row buffer.
pub(crate) struct RowReader<'a> {
    frame: &'a Framebuffer,
    overlay: Option<&'a Overlay>,
    row: Vec<[u8; 3]>,
    current: Option<u32>,
}

impl<'a> RowReader<'a> {
    /// A reader over `frame` with `overlay` blended in.
    pub fn new(frame: &'a Framebuffer, overlay: Option<&'a Overlay>) -> Self {
        Self {
            frame,
            overlay,
            row: vec![[0; 3]; frame.width() as usize],
            current: None,
        }
    }

    /// Row `y` of the composited frame (re-read only when `y` changes, so a scaled output that
    /// shows a row twice converts it once).
    pub fn row(&mut self, y: u32) -> &[[u8; 3]] {
        if self.current != Some(y) {
            let w = self.frame.width() as usize;
            let start = y as usize * w;
            match self.frame.color() {
                ColorBuffer::Rgb565(p) => {
                    for (out, &v) in self.row.iter_mut().zip(&p[start..start + w]) {
                        *out = rgb565_to_rgb(v);
                    }
                }
                ColorBuffer::Rgba8888(p) => {
                    for (out, v) in self.row.iter_mut().zip(&p[start..start + w]) {
                        *out = [v[0], v[1], v[2]];
                    }
                }
            }
            if let Some(overlay) = self.overlay {
                overlay.blend_row(y, &mut self.row);
            }
            self.current = Some(y);
        }
        &self.row
    }
}

/// The frame with the overlay composited, as an opaque RGBA image: what every presenter shows
/// for a frame of the output's size.
pub fn compose_rgba(frame: &Framebuffer, overlay: Option<&Overlay>) -> RgbaImage {
    let mut reader = RowReader::new(frame, overlay);
    let mut raw = Vec::with_capacity(frame.width() as usize * frame.height() as usize * 4);
    for y in 0..frame.height() {
        raw.extend(reader.row(y).iter().flat_map(|&[r, g, b]| [r, g, b, 255]));
    }
    RgbaImage::from_raw(frame.width(), frame.height(), raw).expect("one RGBA pixel per frame pixel")
}
