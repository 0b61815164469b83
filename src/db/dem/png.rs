//! Grayscale PNG height maps (8 or 16 bits), decoded a row at a time.

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use png::{BitDepth, ColorType, Transformations};

use super::{DemInfo, DemReader, check_claim, check_dimensions};
use crate::error::{Error, Result};

/// The most a PNG's samples may outweigh its file: zlib's DEFLATE stays under 1032 to 1.
const MAX_EXPANSION: u64 = 1032;

/// The largest interlaced image decoded whole (512 MiB).
const MAX_INTERLACED_BYTES: usize = 512 << 20;

/// Streams rows of a grayscale PNG. Interlaced files are decoded whole (the rows of an Adam7
/// image arrive out of order), non-interlaced ones one row at a time.
pub struct PngReader {
    info: DemInfo,
    decoder: png::Reader<BufReader<File>>,
    sixteen_bit: bool,
    /// The whole image, for interlaced files only.
    frame: Option<Vec<u8>>,
    next_row: usize,
}

impl PngReader {
    /// Opens `path` and reads its header.
    pub fn open(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        let file = File::open(path).map_err(|e| Error::io(&name, e))?;
        let file_len = file.metadata().map_err(|e| Error::io(&name, e))?.len();
        let mut decoder = png::Decoder::new(BufReader::new(file));
        decoder.set_transformations(Transformations::EXPAND);
        decoder.set_ignore_text_chunk(true);
        let mut reader = decoder
            .read_info()
            .map_err(|e| Error::invalid(&name, format!("not a readable PNG: {e}")))?;
        let (color, depth) = reader.output_color_type();
        if color != ColorType::Grayscale {
            return Err(Error::invalid(
                &name,
                format!(
                    "PNG colour type {color:?} is not a height map; it must be one grayscale channel"
                ),
            ));
        }
        let sixteen_bit = match depth {
            BitDepth::Sixteen => true,
            BitDepth::Eight => false,
            other => {
                return Err(Error::invalid(
                    &name,
                    format!("unsupported PNG bit depth {other:?}"),
                ));
            }
        };
        let (width, height) = (reader.info().width as usize, reader.info().height as usize);
        check_dimensions(&name, width, height)?;
        let row_bytes = width as u64 * if sixteen_bit { 2 } else { 1 };
        check_claim(&name, row_bytes * height as u64, file_len, MAX_EXPANSION)?;
        let frame = if reader.info().interlaced {
            let size = reader
                .output_buffer_size()
                .filter(|&n| n <= MAX_INTERLACED_BYTES)
                .ok_or_else(|| {
                    Error::invalid(&name, "interlaced PNG too large to decode in memory")
                })?;
            let mut buf = vec![0; size];
            reader
                .next_frame(&mut buf)
                .map_err(|e| Error::invalid(&name, format!("corrupt PNG data: {e}")))?;
            Some(buf)
        } else {
            None
        };
        Ok(PngReader {
            info: DemInfo {
                name,
                width,
                height,
                spacing_hint: None,
                origin_hint: None,
            },
            decoder: reader,
            sixteen_bit,
            frame,
            next_row: 0,
        })
    }
}

impl DemReader for PngReader {
    fn info(&self) -> &DemInfo {
        &self.info
    }

    fn read_row(&mut self, row: &mut [f32]) -> Result<()> {
        let bytes_per_sample = if self.sixteen_bit { 2 } else { 1 };
        let line = self.info.width * bytes_per_sample;
        let data: &[u8] = match &self.frame {
            Some(frame) => frame
                .get(self.next_row * line..(self.next_row + 1) * line)
                .ok_or_else(|| Error::invalid(&self.info.name, "read past the last row"))?,
            None => match self.decoder.next_row() {
                Ok(Some(r)) => r.data(),
                Ok(None) => {
                    return Err(Error::invalid(
                        &self.info.name,
                        format!(
                            "PNG ends after {} of {} rows",
                            self.next_row, self.info.height
                        ),
                    ));
                }
                Err(e) => {
                    return Err(Error::invalid(
                        &self.info.name,
                        format!("corrupt PNG data at row {}: {e}", self.next_row),
                    ));
                }
            },
        };
        if data.len() < line {
            return Err(Error::invalid(&self.info.name, "short PNG row"));
        }
        if self.sixteen_bit {
            for (v, b) in row.iter_mut().zip(data.chunks_exact(2)) {
                *v = f32::from(u16::from_be_bytes([b[0], b[1]]));
            }
        } else {
            for (v, b) in row.iter_mut().zip(data) {
                *v = f32::from(*b);
            }
        }
        self.next_row += 1;
        Ok(())
    }
}
