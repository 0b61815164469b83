//! SRTM `.hgt` tiles: square grids of big-endian i16, -32768 = void.

use std::fs::File;
use std::io::{BufReader, Read};
use std::path::Path;

use super::{DemInfo, DemReader, check_dimensions};
use crate::error::{Error, Result};

/// The SRTM void value.
pub const HGT_VOID: i16 = -32768;

/// Streams rows of an `.hgt` file; the side (1201 for SRTM3, 3601 for SRTM1, or any other
/// square) comes from the file length.
pub struct HgtReader {
    info: DemInfo,
    file: BufReader<File>,
    buf: Vec<u8>,
}

impl HgtReader {
    /// Opens `path` and derives the side from its length.
    pub fn open(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        let file = File::open(path).map_err(|e| Error::io(&name, e))?;
        let len = file.metadata().map_err(|e| Error::io(&name, e))?.len();
        let samples = len / 2;
        let side = (samples as f64).sqrt().round() as u64;
        if len % 2 != 0 || side * side != samples {
            return Err(Error::invalid(
                &name,
                format!(
                    "{len} bytes is not a square grid of 16-bit samples (SRTM3 is 1201 x 1201, SRTM1 3601 x 3601)"
                ),
            ));
        }
        let side = side as usize;
        check_dimensions(&name, side, side)?;
        // 1201 samples span 1 degree at 3 arc-seconds (~90 m); 3601 at 1 arc-second (~30 m).
        let spacing_hint = Some(111_320.0 / (side - 1) as f64);
        Ok(HgtReader {
            info: DemInfo {
                name,
                width: side,
                height: side,
                spacing_hint,
                origin_hint: None,
            },
            file: BufReader::new(file),
            buf: vec![0; side * 2],
        })
    }
}

impl DemReader for HgtReader {
    fn info(&self) -> &DemInfo {
        &self.info
    }

    fn read_row(&mut self, row: &mut [f32]) -> Result<()> {
        self.file
            .read_exact(&mut self.buf)
            .map_err(|e| Error::io(&self.info.name, e))?;
        for (v, b) in row.iter_mut().zip(self.buf.chunks_exact(2)) {
            let h = i16::from_be_bytes([b[0], b[1]]);
            *v = if h == HGT_VOID {
                f32::NAN
            } else {
                f32::from(h)
            };
        }
        Ok(())
    }
}
