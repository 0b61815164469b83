//! SRTM `.hgt` tiles: square grids of big-endian i16, -32768 = void; read as raw grids whose
//! side comes from the file length.

use std::path::Path;

use super::raw::RawReader;
use super::{METRES_PER_DEGREE, RawLayout, SampleType};
use crate::error::{Error, Result};

/// The SRTM void value.
pub const HGT_VOID: i16 = -32768;

/// Opens an `.hgt` file; the side (1201 for SRTM3, 3601 for SRTM1, or any other square) comes
/// from its length.
pub fn open(path: &Path) -> Result<RawReader> {
    let name = path.display().to_string();
    let len = std::fs::metadata(path)
        .map_err(|e| Error::io(&name, e))?
        .len();
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
    let layout = RawLayout {
        width: side,
        height: side,
        sample_type: SampleType::I16,
        big_endian: true,
        header_bytes: 0,
    };
    // 1201 samples span 1 degree at 3 arc-seconds (~90 m); 3601 at 1 arc-second (~30 m).
    Ok(RawReader::open(path, layout)?
        .with_void(f32::from(HGT_VOID))
        .with_spacing_hint(METRES_PER_DEGREE / (side.max(2) - 1) as f64))
}
