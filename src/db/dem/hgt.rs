//! SRTM `.hgt` tiles: square grids of big-endian i16, -32768 = void; read as raw grids whose
//! side comes from the file length. A tile spans one degree; its name (`N47W123.hgt`,
//! `N47W123.SRTMGL1.hgt.zip` as distributed) gives its south-west corner, hence its latitude
//! and the east-west spacing.

use std::fs::File;
use std::io::{BufReader, Cursor, Read};
use std::path::Path;

use super::placement::{Placement, Units};
use super::raw::RawReader;
use super::{METRES_PER_DEGREE, RawLayout, SampleType, check_dimensions};
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
    let side = side(&name, len)?;
    Ok(place(RawReader::open(path, layout(side))?, side, path))
}

/// The largest side of a zipped tile, which is held whole once unzipped (100 MiB).
const MAX_ZIPPED_SIDE: usize = 7201;

/// Opens an SRTM tile as distributed, zipped (`N46W122.SRTMGL1.hgt.zip`): the one `.hgt` file
/// inside, unzipped into memory, placed by the zip's name (or the file's inside).
pub fn open_zip(path: &Path) -> Result<RawReader> {
    let name = path.display().to_string();
    let file = File::open(path).map_err(|e| Error::io(&name, e))?;
    let bad = |e: zip::result::ZipError| Error::invalid(&name, format!("not a readable zip: {e}"));
    let mut archive = zip::ZipArchive::new(BufReader::new(file)).map_err(bad)?;
    let tiles: Vec<String> = archive
        .file_names()
        .filter(|n| n.to_ascii_lowercase().ends_with(".hgt"))
        .map(String::from)
        .collect();
    let [inner] = tiles.as_slice() else {
        return Err(Error::invalid(
            &name,
            format!(
                "a zipped SRTM tile holds one .hgt file, this zip holds {}",
                tiles.len()
            ),
        ));
    };
    let mut entry = archive.by_name(inner).map_err(bad)?;
    let len = entry.size();
    let side = self::side(&name, len)?;
    if side > MAX_ZIPPED_SIDE {
        return Err(Error::invalid(
            &name,
            format!(
                "{inner} is {side} x {side} samples, more than a zipped tile is read whole ({MAX_ZIPPED_SIDE} x {MAX_ZIPPED_SIDE})"
            ),
        ));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    (&mut entry)
        .take(len)
        .read_to_end(&mut bytes)
        .map_err(|e| Error::invalid(&name, format!("corrupt zip entry {inner}: {e}")))?;
    if bytes.len() as u64 != len {
        return Err(Error::invalid(
            &name,
            format!("{inner} ends after {} of its {len} bytes", bytes.len()),
        ));
    }
    let reader = RawReader::from_read(&name, Box::new(Cursor::new(bytes)), layout(side));
    let named = if south_west(path).is_some() {
        path
    } else {
        Path::new(inner.as_str())
    };
    Ok(place(reader, side, named))
}

/// The side of a square grid of 16-bit samples `len` bytes long.
fn side(name: &str, len: u64) -> Result<usize> {
    let samples = len / 2;
    let side = (samples as f64).sqrt().round() as u64;
    if !len.is_multiple_of(2) || side * side != samples || side < 2 {
        return Err(Error::invalid(
            name,
            format!(
                "{len} bytes is not a square grid of 16-bit samples (SRTM3 is 1201 x 1201, SRTM1 3601 x 3601)"
            ),
        ));
    }
    check_dimensions(name, side as usize, side as usize)?;
    Ok(side as usize)
}

/// The layout of an SRTM tile of `side` x `side` samples.
fn layout(side: usize) -> RawLayout {
    RawLayout {
        width: side,
        height: side,
        sample_type: SampleType::I16,
        big_endian: true,
        header_bytes: 0,
    }
}

/// Marks SRTM voids and places the tile by the name `path` gives it.
fn place(reader: RawReader, side: usize, path: &Path) -> RawReader {
    // 1201 samples span 1 degree at 3 arc-seconds (~90 m); 3601 at 1 arc-second (~30 m).
    let mut reader = reader.with_void(f32::from(HGT_VOID));
    let cell = 1.0 / (side.max(2) - 1) as f64;
    let info = reader.info_mut();
    match south_west(path) {
        // SRTM heights are on WGS 84.
        Some((south, west)) => Placement {
            crs: "EPSG:4326".into(),
            named: true,
            units: Units::Degrees,
            cell: (cell, cell),
            first: (west, south + 1.0),
        }
        .apply(info),
        None => {
            info.spacing_hint = Some(cell * METRES_PER_DEGREE);
            info.notes.push(
                "the file name does not say where the tile lies (SRTM names it like \
                 N47W123.hgt), so east-west spacing is taken equal to north-south; \
                 pass --spacing to set it"
                    .to_string(),
            );
        }
    }
    reader
}

/// The south-west corner (latitude, longitude) an SRTM file name such as `N47W123.hgt` gives,
/// when it is plausible.
fn south_west(path: &Path) -> Option<(f64, f64)> {
    let stem = path.file_stem()?.to_str()?.to_ascii_uppercase();
    let b = stem.as_bytes();
    if b.len() < 7 || !b[1..3].iter().chain(&b[4..7]).all(u8::is_ascii_digit) {
        return None;
    }
    let lat: f64 = stem[1..3].parse().ok()?;
    let lon: f64 = stem[4..7].parse().ok()?;
    let lat = match b[0] {
        b'N' => lat,
        b'S' => -lat,
        _ => return None,
    };
    let lon = match b[3] {
        b'E' => lon,
        b'W' => -lon,
        _ => return None,
    };
    (lat.abs() < 85.0 && lon.abs() <= 180.0).then_some((lat, lon))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn srtm_names_give_the_south_west_corner() {
        assert_eq!(south_west(Path::new("x/N47W123.hgt")), Some((47.0, -123.0)));
        assert_eq!(south_west(Path::new("s34e018.hgt")), Some((-34.0, 18.0)));
        assert_eq!(south_west(Path::new("puget.hgt")), None);
        assert_eq!(south_west(Path::new("N47X123.hgt")), None);
    }
}
