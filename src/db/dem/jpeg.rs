//! 8-bit JPEG height maps: grayscale, or colour whose three channels are equal up to the
//! codec's rounding. JPEG has no row-by-row decoder here, so the image is decoded whole (one
//! byte per sample, bounded by [`MAX_JPEG_BYTES`]).

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use image::codecs::jpeg::JpegDecoder;
use image::{DynamicImage, ImageDecoder, Limits};

use super::png::EIGHT_BIT_NOTE;
use super::{DemInfo, DemReader, check_dimensions};
use crate::error::{Error, Result};

/// The largest decoded image accepted (512 MiB of pixels).
pub const MAX_JPEG_BYTES: u64 = 512 << 20;

/// How far apart the channels of a colour JPEG of a gray image may be: its chroma is rounded
/// to 8 bits and subsampled, which moves each channel by a step or two.
const CHANNEL_TOLERANCE: u8 = 3;

/// Rows of a decoded JPEG, one height per pixel.
pub struct JpegReader {
    info: DemInfo,
    samples: Vec<u8>,
    next_row: usize,
}

impl JpegReader {
    /// Opens and decodes `path`.
    pub fn open(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        let bad = |e: image::ImageError| Error::invalid(&name, format!("not a readable JPEG: {e}"));
        let file = File::open(path).map_err(|e| Error::io(&name, e))?;
        let mut decoder = JpegDecoder::new(BufReader::new(file)).map_err(bad)?;
        let mut limits = Limits::default();
        limits.max_alloc = Some(MAX_JPEG_BYTES);
        decoder.set_limits(limits).map_err(bad)?;
        let (w, h) = decoder.dimensions();
        let (width, height) = (w as usize, h as usize);
        check_dimensions(&name, width, height)?;
        let samples = match DynamicImage::from_decoder(decoder).map_err(bad)? {
            DynamicImage::ImageLuma8(gray) => gray.into_raw(),
            DynamicImage::ImageRgb8(rgb) => gray_of(&name, width, &rgb.into_raw())?,
            other => {
                return Err(Error::invalid(
                    &name,
                    format!(
                        "JPEG colour layout {:?} is not a height map; it must be grayscale \
                         (or RGB with equal channels)",
                        other.color()
                    ),
                ));
            }
        };
        let mut info = DemInfo::new(&name, width, height);
        info.notes.push(EIGHT_BIT_NOTE.to_string());
        Ok(JpegReader {
            info,
            samples,
            next_row: 0,
        })
    }
}

/// The gray value of every RGB pixel of a `width`-wide image, refusing a colour image.
fn gray_of(name: &str, width: usize, rgb: &[u8]) -> Result<Vec<u8>> {
    rgb.chunks_exact(3)
        .enumerate()
        .map(|(k, p)| {
            let (lo, hi) = (p.iter().min(), p.iter().max());
            match (lo, hi) {
                (Some(&lo), Some(&hi)) if hi - lo <= CHANNEL_TOLERANCE => {
                    Ok(((u16::from(p[0]) + u16::from(p[1]) + u16::from(p[2]) + 1) / 3) as u8)
                }
                _ => Err(Error::invalid(
                    name,
                    format!(
                        "pixel ({}, {}) has red {}, green {}, blue {}: a colour image, not a \
                         height map (its three channels must be equal)",
                        k % width,
                        k / width,
                        p[0],
                        p[1],
                        p[2]
                    ),
                )),
            }
        })
        .collect()
}

impl DemReader for JpegReader {
    fn info(&self) -> &DemInfo {
        &self.info
    }

    fn read_row(&mut self, row: &mut [f32]) -> Result<()> {
        let w = self.info.width;
        let line = self
            .samples
            .get(self.next_row * w..(self.next_row + 1) * w)
            .ok_or_else(|| Error::invalid(&self.info.name, "read past the last row"))?;
        for (v, b) in row.iter_mut().zip(line) {
            *v = f32::from(*b);
        }
        self.next_row += 1;
        Ok(())
    }
}
