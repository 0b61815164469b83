//! Digital elevation models: readers that stream rows of samples, and the nodata fill.
//!
//! Every reader yields rows top (north) to bottom (south), left (west) to right (east), as `f32`
//! raw units; a sample that is nodata (the format's nodata value, or NaN) comes out as `NaN`.
//! [`NodataFill`] then replaces every `NaN` with a defined value, so no `NaN` enters the engine.
//! Readers hold at most one strip (or one row of TIFF tiles) of the file at a time.

mod asc;
mod geotiff;
mod hgt;
mod png;
mod raw;

use std::path::Path;

use crate::error::{Error, Result};
use crate::named::named_enum;

/// What a DEM file says about itself before its samples are read.
#[derive(Clone, Debug, PartialEq)]
pub struct DemInfo {
    /// The file name, for error messages.
    pub name: String,
    /// Samples per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Horizontal spacing between samples in metres, when the file says (approximately, for
    /// geographic grids).
    pub spacing_hint: Option<f64>,
    /// World position (x east, y north) of sample (0, 0), when the file says.
    pub origin_hint: Option<(f64, f64)>,
}

/// A reader that yields a DEM one row at a time.
pub trait DemReader {
    /// Dimensions and georeferencing hints.
    fn info(&self) -> &DemInfo;
    /// Reads the next row into `row` (length `info().width`), nodata as `NaN`.
    fn read_row(&mut self, row: &mut [f32]) -> Result<()>;
}

impl<R: DemReader + ?Sized> DemReader for Box<R> {
    fn info(&self) -> &DemInfo {
        (**self).info()
    }
    fn read_row(&mut self, row: &mut [f32]) -> Result<()> {
        (**self).read_row(row)
    }
}

/// Sample types of raw/BIL files.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleType {
    /// Unsigned 8-bit.
    U8,
    /// Signed 16-bit.
    I16,
    /// Unsigned 16-bit.
    U16,
    /// Signed 32-bit.
    I32,
    /// IEEE 32-bit float.
    F32,
}

impl SampleType {
    /// Bytes per sample.
    pub fn size(self) -> usize {
        match self {
            SampleType::U8 => 1,
            SampleType::I16 | SampleType::U16 => 2,
            SampleType::I32 | SampleType::F32 => 4,
        }
    }

    /// Decodes one sample from its bytes (`size()` of them).
    pub fn decode(self, b: &[u8], big_endian: bool) -> f32 {
        macro_rules! conv {
            ($t:ty, $n:literal) => {{
                let a: [u8; $n] = b[..$n].try_into().expect("sample bytes");
                (if big_endian {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }) as f32
            }};
        }
        match self {
            SampleType::U8 => f32::from(b[0]),
            SampleType::I16 => conv!(i16, 2),
            SampleType::U16 => conv!(u16, 2),
            SampleType::I32 => conv!(i32, 4),
            SampleType::F32 => conv!(f32, 4),
        }
    }
}

named_enum!(SampleType, "sample type", {
    U8 => "u8",
    I16 => "i16",
    U16 => "u16",
    I32 => "i32",
    F32 => "f32",
});

/// The DEM formats `build` reads.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DemFormat {
    /// 8- or 16-bit grayscale PNG.
    Png,
    /// GeoTIFF (single band; Int16, UInt16, Int32, Float32 and more).
    Tiff,
    /// SRTM `.hgt` (big-endian i16, square).
    Hgt,
    /// ESRI ASCII grid.
    Asc,
    /// Headerless raw samples or BIL (needs width, height and sample type).
    Raw,
}

impl DemFormat {
    /// Guesses the format from a file extension.
    pub fn from_path(path: &Path) -> Option<DemFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "png" => DemFormat::Png,
            "tif" | "tiff" => DemFormat::Tiff,
            "hgt" => DemFormat::Hgt,
            "asc" => DemFormat::Asc,
            "raw" | "bil" | "bin" | "r16" | "r32" => DemFormat::Raw,
            _ => return None,
        })
    }
}

named_enum!(DemFormat, "DEM format", {
    Png => "png",
    Tiff => "tiff",
    Hgt => "hgt",
    Asc => "asc",
    Raw => "raw",
});

/// Metres per degree of latitude, to turn a geographic sample size into an approximate spacing.
pub(crate) const METRES_PER_DEGREE: f64 = 111_320.0;

/// Layout of a raw/BIL file, which does not describe itself.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RawLayout {
    /// Samples per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// Sample type.
    pub sample_type: SampleType,
    /// Big-endian samples (BIL from many tools is little-endian; `.hgt` is big-endian).
    pub big_endian: bool,
    /// Bytes to skip at the start of the file.
    pub header_bytes: u64,
}

/// How to read a DEM file.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OpenOptions {
    /// The format; `None` guesses it from the extension.
    pub format: Option<DemFormat>,
    /// The layout of raw files.
    pub raw: Option<RawLayout>,
    /// A nodata value that overrides (or adds to) what the file says.
    pub nodata: Option<f32>,
}

/// Opens a DEM file for streaming, with the nodata fill applied.
pub fn open(path: &Path, options: &OpenOptions) -> Result<NodataFill<Box<dyn DemReader>>> {
    let name = path.display().to_string();
    let format = match options.format.or_else(|| DemFormat::from_path(path)) {
        Some(f) => f,
        None => {
            return Err(Error::invalid(
                name,
                "cannot tell the DEM format from the extension; pass --format",
            ));
        }
    };
    let reader: Box<dyn DemReader> = match format {
        DemFormat::Png => Box::new(png::PngReader::open(path)?),
        DemFormat::Tiff => Box::new(geotiff::TiffReader::open(path)?),
        DemFormat::Hgt => Box::new(hgt::open(path)?),
        DemFormat::Asc => Box::new(asc::AscReader::open(path)?),
        DemFormat::Raw => {
            let layout = options.raw.ok_or_else(|| {
                Error::invalid(
                    name.clone(),
                    "a raw/BIL file needs --width, --height and --sample-type",
                )
            })?;
            Box::new(raw::RawReader::open(path, layout)?)
        }
    };
    Ok(NodataFill::new(reader, options.nodata))
}

/// Replaces nodata with a defined value while streaming rows.
///
/// The rule, which needs only the previous row: a nodata sample takes the value of the nearest
/// valid sample in its own row (the left one on a tie); a row without any valid sample copies the
/// previous output row; rows before the first valid sample are 0.
pub struct NodataFill<R> {
    inner: R,
    nodata: Option<f32>,
    previous: Option<Vec<f32>>,
}

impl<R: DemReader> NodataFill<R> {
    /// Wraps `inner`; `nodata` is an extra value to treat as missing.
    pub fn new(inner: R, nodata: Option<f32>) -> Self {
        NodataFill {
            inner,
            nodata,
            previous: None,
        }
    }

    /// Dimensions and hints of the underlying file.
    pub fn info(&self) -> &DemInfo {
        self.inner.info()
    }

    /// Reads the next row with every nodata sample filled.
    pub fn read_row(&mut self, row: &mut [f32]) -> Result<()> {
        self.inner.read_row(row)?;
        if let Some(nd) = self.nodata {
            for v in row.iter_mut() {
                if *v == nd {
                    *v = f32::NAN;
                }
            }
        }
        for v in row.iter_mut() {
            if v.is_infinite() {
                *v = f32::NAN;
            }
        }
        if !fill_row_from_nearest(row) {
            match &self.previous {
                Some(p) => row.copy_from_slice(p),
                None => row.fill(0.0),
            }
        }
        match &mut self.previous {
            Some(p) => p.copy_from_slice(row),
            None => self.previous = Some(row.to_vec()),
        }
        Ok(())
    }

    /// Reads the whole DEM into memory (for small files and tests).
    pub fn read_all(mut self) -> Result<Dem> {
        let (w, h) = (self.info().width, self.info().height);
        let mut samples = vec![0.0; w * h];
        for row in samples.chunks_exact_mut(w.max(1)).take(h) {
            self.read_row(row)?;
        }
        Ok(Dem {
            width: w,
            height: h,
            samples,
        })
    }
}

/// Fills NaNs in `row` from the nearest valid sample in the row; false if the row has none.
fn fill_row_from_nearest(row: &mut [f32]) -> bool {
    if !row.iter().any(|v| v.is_nan()) {
        return true;
    }
    let n = row.len();
    // Distance to and value of the nearest valid sample on the left, then on the right.
    let mut left = vec![(usize::MAX, 0.0f32); n];
    let mut last: Option<(usize, f32)> = None;
    for (i, v) in row.iter().enumerate() {
        if !v.is_nan() {
            last = Some((i, *v));
        }
        if let Some((j, lv)) = last {
            left[i] = (i - j, lv);
        }
    }
    let mut any = false;
    let mut next: Option<(usize, f32)> = None;
    for i in (0..n).rev() {
        if !row[i].is_nan() {
            next = Some((i, row[i]));
            any = true;
            continue;
        }
        let right = next.map(|(j, v)| (j - i, v)).unwrap_or((usize::MAX, 0.0));
        row[i] = if left[i].0 <= right.0 {
            left[i].1
        } else {
            right.1
        };
    }
    any
}

/// A whole DEM in memory, raw units, row-major, no NaN.
#[derive(Clone, Debug, PartialEq)]
pub struct Dem {
    /// Samples per row.
    pub width: usize,
    /// Rows.
    pub height: usize,
    /// `width * height` samples, row-major from the north-west corner.
    pub samples: Vec<f32>,
}

impl Dem {
    /// The sample at column `i`, row `j`.
    pub fn at(&self, i: usize, j: usize) -> f32 {
        self.samples[j * self.width + i]
    }
}

/// A reader over a [`Dem`] in memory, for synthetic inputs and tests.
pub struct MemoryReader {
    info: DemInfo,
    samples: Vec<f32>,
    next_row: usize,
}

impl MemoryReader {
    /// A reader named `name` over `width * height` row-major samples (`NaN` = nodata).
    pub fn new(name: &str, width: usize, height: usize, samples: Vec<f32>) -> Result<Self> {
        if width == 0 || height == 0 || samples.len() != width * height {
            return Err(Error::invalid(
                name,
                format!(
                    "{} samples do not make a {width} x {height} grid",
                    samples.len()
                ),
            ));
        }
        Ok(MemoryReader {
            info: DemInfo {
                name: name.to_string(),
                width,
                height,
                spacing_hint: None,
                origin_hint: None,
            },
            samples,
            next_row: 0,
        })
    }
}

impl DemReader for MemoryReader {
    fn info(&self) -> &DemInfo {
        &self.info
    }

    fn read_row(&mut self, row: &mut [f32]) -> Result<()> {
        let w = self.info.width;
        if self.next_row >= self.info.height {
            return Err(Error::invalid(&self.info.name, "read past the last row"));
        }
        row.copy_from_slice(&self.samples[self.next_row * w..(self.next_row + 1) * w]);
        self.next_row += 1;
        Ok(())
    }
}

/// Checks DEM dimensions are usable (non-zero, and not absurdly large).
pub(crate) fn check_dimensions(name: &str, width: usize, height: usize) -> Result<()> {
    const MAX_SIDE: usize = 1 << 20;
    if width < 2 || height < 2 {
        return Err(Error::invalid(
            name,
            format!("a DEM needs at least 2 x 2 samples, this one is {width} x {height}"),
        ));
    }
    if width > MAX_SIDE || height > MAX_SIDE {
        return Err(Error::invalid(
            name,
            format!("{width} x {height} samples is larger than the {MAX_SIDE} per side supported"),
        ));
    }
    Ok(())
}

/// Refuses a compressed DEM whose `decoded` bytes of samples cannot come from a file of
/// `file_len` bytes compressed at most `max_expansion` to 1: a decompression bomb or a corrupt
/// header, refused before anything is allocated or written.
pub(crate) fn check_claim(
    name: &str,
    decoded: u64,
    file_len: u64,
    max_expansion: u64,
) -> Result<()> {
    if decoded > file_len.saturating_mul(max_expansion) {
        return Err(Error::invalid(
            name,
            format!(
                "the header claims {decoded} bytes of samples, more than {max_expansion} times \
                 the file's {file_len} bytes: a decompression bomb or a corrupt file"
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fill_takes_the_nearest_valid_sample_in_the_row() {
        let mut row = [f32::NAN, 1.0, f32::NAN, f32::NAN, f32::NAN, 5.0, f32::NAN];
        assert!(fill_row_from_nearest(&mut row));
        assert_eq!(row, [1.0, 1.0, 1.0, 1.0, 5.0, 5.0, 5.0]);
    }

    #[test]
    fn an_all_nodata_row_copies_the_previous_row() {
        let nan = f32::NAN;
        let r = MemoryReader::new("m", 2, 3, vec![nan, nan, 1.0, nan, nan, nan]).unwrap();
        let dem = NodataFill::new(r, None).read_all().unwrap();
        assert_eq!(dem.samples, vec![0.0, 0.0, 1.0, 1.0, 1.0, 1.0]);
    }
}
