//! Digital elevation models: readers that stream rows of samples, and the nodata fill.
//!
//! Every reader yields rows top (north) to bottom (south), left (west) to right (east), as `f32`
//! raw units; a sample that is nodata (the format's nodata value, or NaN) comes out as `NaN`.
//! [`NodataFill`] then replaces every `NaN` with a defined value, so no `NaN` enters the engine.
//! Readers hold at most one strip (or one row of TIFF tiles) of the file at a time.

mod asc;
mod geographic;
mod geotiff;
mod hgt;
mod jpeg;
mod mosaic;
mod placement;
mod png;
mod raw;
mod resample;
mod vrt;
mod wkt;

use std::collections::VecDeque;
use std::path::{Path, PathBuf};

pub use mosaic::{Mosaic, expand};
pub use placement::{Placement, Units};
pub use resample::EastWest;

use crate::error::{Error, Result};
use crate::named::{Named, named_enum};

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
    /// East-west spacing over [`Self::spacing_hint`] (the north-south one): 1 for projected
    /// grids, the cosine of the latitude (times the cells' aspect) for grids in degrees. `build`
    /// resamples columns to square cells when it is not 1.
    pub east_west_scale: f64,
    /// Why the file has no usable spacing, when it has none and the user must give one.
    pub spacing_problem: Option<String>,
    /// What the reader assumed about the file, for `build` to print.
    pub notes: Vec<String>,
    /// Where the grid lies in its own CRS, when the file says: what a mosaic places it by.
    pub placement: Option<Placement>,
}

impl DemInfo {
    /// A grid with nothing known but its name and size: square cells, no georeferencing.
    pub fn new(name: &str, width: usize, height: usize) -> DemInfo {
        DemInfo {
            name: name.to_string(),
            width,
            height,
            spacing_hint: None,
            origin_hint: None,
            east_west_scale: 1.0,
            spacing_problem: None,
            notes: Vec::new(),
            placement: None,
        }
    }
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
    /// 8- or 16-bit grayscale PNG (or RGB with equal channels).
    Png,
    /// 8-bit JPEG, grayscale (or RGB with equal channels).
    Jpeg,
    /// GeoTIFF (single band; Int16, UInt16, Int32, Float32 and more).
    Tiff,
    /// SRTM `.hgt` (big-endian i16, square).
    Hgt,
    /// ESRI ASCII grid.
    Asc,
    /// Headerless raw samples or BIL (needs width, height and sample type).
    Raw,
    /// A GDAL virtual mosaic (`.vrt`) of files of the other formats.
    Vrt,
}

impl DemFormat {
    /// Guesses the format from a file extension.
    pub fn from_path(path: &Path) -> Option<DemFormat> {
        let ext = path.extension()?.to_str()?.to_ascii_lowercase();
        Some(match ext.as_str() {
            "png" => DemFormat::Png,
            "jpg" | "jpeg" => DemFormat::Jpeg,
            "tif" | "tiff" => DemFormat::Tiff,
            "hgt" => DemFormat::Hgt,
            // SRTM tiles as distributed: `N46W122.SRTMGL1.hgt.zip`.
            "zip"
                if path
                    .file_stem()?
                    .to_str()?
                    .to_ascii_lowercase()
                    .ends_with(".hgt") =>
            {
                DemFormat::Hgt
            }
            "asc" => DemFormat::Asc,
            "raw" | "bil" | "bin" | "r16" | "r32" => DemFormat::Raw,
            "vrt" => DemFormat::Vrt,
            _ => return None,
        })
    }

    /// Whether a folder given to `build` contributes files of this format to its mosaic: the
    /// formats whose files say where they lie (a VRT is a mosaic of its own, given alone).
    pub fn found_in_folders(self) -> bool {
        matches!(self, DemFormat::Tiff | DemFormat::Hgt | DemFormat::Asc)
    }
}

named_enum!(DemFormat, "DEM format", {
    Png => "png",
    Jpeg => "jpeg",
    Tiff => "tiff",
    Hgt => "hgt",
    Asc => "asc",
    Raw => "raw",
    Vrt => "vrt",
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

/// How heights are stored in an image's pixels.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum HeightEncoding {
    /// One gray level a height unit (or RGB with equal channels).
    #[default]
    Gray,
    /// Mapbox Terrain-RGB: `-10000 + (R × 65536 + G × 256 + B) × 0.1` metres.
    TerrainRgb,
    /// Mapzen / AWS Terrarium: `R × 256 + G + B / 256 − 32768` metres.
    Terrarium,
}

named_enum!(HeightEncoding, "height encoding", {
    Gray => "gray",
    TerrainRgb => "terrain-rgb",
    Terrarium => "terrarium",
});

impl HeightEncoding {
    /// The height in metres of an 8-bit pixel `rgb` (red for gray).
    pub fn decode(self, [r, g, b]: [u8; 3]) -> f32 {
        let (r, g, b) = (f64::from(r), f64::from(g), f64::from(b));
        let metres = match self {
            HeightEncoding::Gray => r,
            HeightEncoding::TerrainRgb => -10_000.0 + (r * 65_536.0 + g * 256.0 + b) * 0.1,
            HeightEncoding::Terrarium => r * 256.0 + g + b / 256.0 - 32_768.0,
        };
        metres as f32
    }
}

/// How to read a DEM file.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct OpenOptions {
    /// The format; `None` guesses it from the extension.
    pub format: Option<DemFormat>,
    /// The layout of raw files.
    pub raw: Option<RawLayout>,
    /// A nodata value that overrides (or adds to) what the file says.
    pub nodata: Option<f32>,
    /// How a PNG's pixels hold heights.
    pub encoding: HeightEncoding,
}

/// Opens a DEM file (or a GDAL VRT mosaic) for streaming, with the nodata fill applied.
pub fn open(path: &Path, options: &OpenOptions) -> Result<NodataFill<Box<dyn DemReader>>> {
    Ok(NodataFill::new(
        open_reader(path, options, 0)?,
        options.nodata,
    ))
}

/// Opens what `build`'s inputs name as one DEM, with the nodata fill applied: one file as
/// [`open`] does, or many (files, folders, glob patterns; see [`expand`]) as a mosaic placed by
/// their georeferencing ([`Mosaic`]).
pub fn open_inputs(
    inputs: &[PathBuf],
    options: &OpenOptions,
) -> Result<NodataFill<Box<dyn DemReader>>> {
    let files = expand(inputs)?;
    let reader: Box<dyn DemReader> = match files.as_slice() {
        [] => return Err(Error::invalid("build", "no input DEM given")),
        [one] => open_reader(one, options, 0)?,
        many => Box::new(Mosaic::placed(many, options, 0)?),
    };
    Ok(NodataFill::new(reader, options.nodata))
}

/// How many VRTs deep a source may lie (a VRT listing VRTs); deeper is a loop, or a mistake.
const MAX_VRT_DEPTH: usize = 4;

/// Opens one DEM file without the nodata fill, `depth` VRTs deep.
pub(crate) fn open_reader(
    path: &Path,
    options: &OpenOptions,
    depth: usize,
) -> Result<Box<dyn DemReader>> {
    let name = path.display().to_string();
    let format = match options.format.or_else(|| DemFormat::from_path(path)) {
        Some(f) => f,
        None => {
            let names: Vec<&str> = DemFormat::all().iter().map(|f| f.name()).collect();
            return Err(Error::invalid(
                name,
                format!(
                    "cannot tell the DEM format from the extension; pass --format (one of {})",
                    names.join(", ")
                ),
            ));
        }
    };
    if options.encoding != HeightEncoding::Gray && format != DemFormat::Png {
        return Err(Error::invalid(
            name,
            format!(
                "--encoding {} is for PNG height tiles, and this is a {} file",
                options.encoding.name(),
                format.name()
            ),
        ));
    }
    Ok(match format {
        DemFormat::Png => Box::new(png::PngReader::open(path)?.with_encoding(options.encoding)?),
        DemFormat::Jpeg => Box::new(jpeg::JpegReader::open(path)?),
        DemFormat::Tiff => Box::new(geotiff::TiffReader::open(path)?),
        DemFormat::Hgt if is_zip(path) => Box::new(hgt::open_zip(path)?),
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
        DemFormat::Vrt if depth >= MAX_VRT_DEPTH => {
            return Err(Error::invalid(
                name,
                format!("a VRT more than {MAX_VRT_DEPTH} VRTs deep (do they list each other?)"),
            ));
        }
        DemFormat::Vrt => {
            // A VRT's sources are read as their extensions say, whatever --format forced.
            let sources = OpenOptions {
                format: None,
                ..*options
            };
            Box::new(vrt::open(path, &sources, depth)?)
        }
    })
}

/// Whether `path` names a zip file.
fn is_zip(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("zip"))
}

/// Opens a grayscale PNG held in the program itself (the demo's model), called `name` in
/// messages, with the nodata fill applied.
pub fn open_png_bytes(name: &str, bytes: &'static [u8]) -> Result<NodataFill<Box<dyn DemReader>>> {
    let reader: Box<dyn DemReader> = Box::new(png::PngReader::from_bytes(name, bytes)?);
    Ok(NodataFill::new(reader, None))
}

/// How far (in samples) the nodata fill looks for valid data: holes narrower than twice this
/// take the nearest valid sample; samples farther from any valid one lie in a large nodata area.
pub const FILL_RADIUS: usize = 32;

/// What the nodata fill did, for the build's report.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct FillStats {
    /// Nodata samples that took the value of the nearest valid sample (in 2-D).
    pub filled: u64,
    /// Nodata samples more than [`FILL_RADIUS`] samples from any valid one: drawn flat at the
    /// lowest valid height around them.
    pub flattened: u64,
}

/// One raw row held by the fill: its samples (NaN = nodata) and, per column, the distance to
/// and value of the nearest valid sample in the same row. `None` when the row has no valid
/// sample (such rows cost no memory, however many there are).
type HeldRow = Option<(Vec<f32>, Vec<(u32, f32)>)>;

/// Replaces nodata with a defined value while streaming rows.
///
/// A nodata sample takes the value of the nearest valid sample in 2-D (Euclidean distance in
/// samples, looked for within [`FILL_RADIUS`] rows above and below); one with no valid sample
/// that close lies in a large nodata area and is set to the lowest valid height within
/// [`FILL_RADIUS`] samples around (or, failing that, in the rows held), so large holes draw as
/// flat ground at the local minimum instead of walls or spikes. Memory: `2 * FILL_RADIUS + 1`
/// rows with valid data, however many rows without any lie between them.
pub struct NodataFill<R> {
    inner: R,
    nodata: Option<f32>,
    /// Raw rows `first ..` as read; the rows above the next output row are kept only as far
    /// as [`FILL_RADIUS`].
    held: VecDeque<HeldRow>,
    first: usize,
    rows_read: usize,
    next_out: usize,
    stats: FillStats,
    /// The lowest valid height of the last row read with data: the floor of a nodata band
    /// that runs to the DEM's end (the sea south of a coast), farther than the held rows reach.
    last_low: f32,
}

impl<R: DemReader> NodataFill<R> {
    /// Wraps `inner`; `nodata` is an extra value to treat as missing.
    pub fn new(inner: R, nodata: Option<f32>) -> Self {
        NodataFill {
            inner,
            nodata,
            held: VecDeque::new(),
            first: 0,
            rows_read: 0,
            next_out: 0,
            stats: FillStats::default(),
            last_low: f32::INFINITY,
        }
    }

    /// Dimensions and hints of the underlying file.
    pub fn info(&self) -> &DemInfo {
        self.inner.info()
    }

    /// What the fill has done so far.
    pub fn stats(&self) -> FillStats {
        self.stats
    }

    /// Reads one more raw row into `held`.
    fn read_raw(&mut self) -> Result<()> {
        let mut row = vec![0.0; self.info().width];
        self.inner.read_row(&mut row)?;
        for v in row.iter_mut() {
            if Some(*v) == self.nodata || v.is_infinite() {
                *v = f32::NAN;
            }
        }
        self.rows_read += 1;
        let held = nearest_in_row(&row).map(|near| (row, near));
        if let Some((row, _)) = &held {
            self.last_low = row
                .iter()
                .filter(|v| !v.is_nan())
                .fold(f32::INFINITY, |m, v| m.min(*v));
        }
        self.held.push_back(held);
        Ok(())
    }

    /// Reads the next row with every nodata sample filled.
    pub fn read_row(&mut self, out: &mut [f32]) -> Result<()> {
        self.read_row_marking(out, None)
    }

    /// [`NodataFill::read_row`], also setting `nodata[i]` to whether sample `i` was nodata in
    /// the file (before the fill).
    pub fn read_row_marking(&mut self, out: &mut [f32], nodata: Option<&mut [bool]>) -> Result<()> {
        let (j, height) = (self.next_out, self.info().height);
        while self.rows_read < height.min(j + FILL_RADIUS + 1) {
            self.read_raw()?;
        }
        // A row deep in a nodata band waits for the first row with data, however far.
        while self.rows_read < height && !self.held.iter().any(Option::is_some) {
            self.read_raw()?;
        }
        if !self.held.iter().any(Option::is_some) && !self.last_low.is_finite() {
            return Err(Error::invalid(
                &self.info().name,
                "every sample of the DEM is nodata",
            ));
        }
        if let Some(marks) = nodata {
            match &self.held[j - self.first] {
                Some((row, _)) => marks.iter_mut().zip(row).for_each(|(m, v)| *m = v.is_nan()),
                None => marks.fill(true),
            }
        }
        match &self.held[j - self.first] {
            Some((row, _)) if !row.iter().any(|v| v.is_nan()) => out.copy_from_slice(row),
            _ => self.fill_row(j, out),
        }
        self.next_out += 1;
        while self.first + FILL_RADIUS < self.next_out {
            self.held.pop_front();
            self.first += 1;
        }
        Ok(())
    }

    /// Fills output row `j` (held) from the held rows around it.
    fn fill_row(&mut self, j: usize, out: &mut [f32]) {
        let w = out.len();
        let lo = j.saturating_sub(FILL_RADIUS).max(self.first);
        let hi = (j + FILL_RADIUS).min(self.first + self.held.len() - 1);
        if (lo..=hi).all(|k| self.held[k - self.first].is_none()) {
            // Deep in a nodata band (an ocean, the outside of a mosaic): no sample within the
            // radius, so the whole row lies flat, at the cost of a row, not of a search per sample.
            out.fill(self.floor());
            self.stats.flattened += w as u64;
            return;
        }
        let mut far = Vec::new();
        for (i, o) in out.iter_mut().enumerate() {
            let own = self.held[j - self.first].as_ref().map(|(row, _)| row[i]);
            if let Some(v) = own.filter(|v| !v.is_nan()) {
                *o = v;
                continue;
            }
            match self.nearest(i, j) {
                Some(v) => {
                    *o = v;
                    self.stats.filled += 1;
                }
                None => far.push(i),
            }
        }
        if far.is_empty() {
            return;
        }
        self.stats.flattened += far.len() as u64;
        // The lowest valid height per column over the rows within the radius, then per sample
        // over the columns within the radius.
        let mut column_min = vec![f32::INFINITY; w];
        let rows = || (lo..=hi).filter_map(|k| self.held[k - self.first].as_ref());
        for (row, _) in rows() {
            for (m, v) in column_min.iter_mut().zip(row) {
                if !v.is_nan() {
                    *m = m.min(*v);
                }
            }
        }
        let floor = self.floor();
        for i in far {
            let around = &column_min[i.saturating_sub(FILL_RADIUS)..(i + FILL_RADIUS + 1).min(w)];
            let m = around.iter().fold(f32::INFINITY, |m, v| m.min(*v));
            out[i] = if m.is_finite() { m } else { floor };
        }
    }

    /// The height of a sample with no valid one within the radius: the lowest valid height of
    /// the rows held, or of the last row with data when none is held.
    fn floor(&self) -> f32 {
        let held_min = self
            .held
            .iter()
            .flatten()
            .flat_map(|(row, _)| row.iter().filter(|v| !v.is_nan()))
            .fold(f32::INFINITY, |m, v| m.min(*v));
        if held_min.is_finite() {
            held_min
        } else {
            self.last_low
        }
    }

    /// The value of the nearest valid sample to column `i` of row `j` within [`FILL_RADIUS`]
    /// (the first found, rows nearer `j` first and above before below, on a tie).
    fn nearest(&self, i: usize, j: usize) -> Option<f32> {
        let limit = (FILL_RADIUS * FILL_RADIUS) as u64;
        let mut best: Option<(u64, f32)> = None;
        for dk in 0..=FILL_RADIUS {
            let dk2 = (dk * dk) as u64;
            if best.is_some_and(|(d, _)| dk2 >= d) || dk2 > limit {
                break;
            }
            let candidates = [j.checked_sub(dk), (dk > 0).then_some(j + dk)];
            for k in candidates.into_iter().flatten() {
                let Some(Some((_, near))) =
                    k.checked_sub(self.first).and_then(|r| self.held.get(r))
                else {
                    continue;
                };
                let (dx, v) = near[i];
                let d = dk2 + u64::from(dx) * u64::from(dx);
                if d <= limit && best.is_none_or(|(b, _)| d < b) {
                    best = Some((d, v));
                }
            }
        }
        best.map(|(_, v)| v)
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

/// Per column of `row`, the distance to and value of the nearest valid sample in the row (the
/// left one on a tie); `None` if the row has no valid sample.
fn nearest_in_row(row: &[f32]) -> Option<Vec<(u32, f32)>> {
    let n = row.len();
    let mut near = vec![(u32::MAX, f32::NAN); n];
    let mut last: Option<(usize, f32)> = None;
    for (i, v) in row.iter().enumerate() {
        if !v.is_nan() {
            last = Some((i, *v));
        }
        if let Some((k, lv)) = last {
            near[i] = ((i - k) as u32, lv);
        }
    }
    last?;
    let mut next: Option<(usize, f32)> = None;
    for i in (0..n).rev() {
        if !row[i].is_nan() {
            next = Some((i, row[i]));
        }
        if let Some((k, v)) = next.filter(|(k, _)| ((k - i) as u32) < near[i].0) {
            near[i] = ((k - i) as u32, v);
        }
    }
    Some(near)
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
            info: DemInfo::new(name, width, height),
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

    fn filled(w: usize, h: usize, samples: Vec<f32>) -> (Vec<f32>, FillStats) {
        let mut fill = NodataFill::new(MemoryReader::new("m", w, h, samples).unwrap(), None);
        let mut out = vec![0.0; w * h];
        for row in out.chunks_exact_mut(w) {
            fill.read_row(row).unwrap();
        }
        (out, fill.stats())
    }

    #[test]
    fn nearest_in_row_takes_the_left_sample_on_a_tie() {
        let row = [f32::NAN, 1.0, f32::NAN, f32::NAN, f32::NAN, 5.0, f32::NAN];
        let near = nearest_in_row(&row).unwrap();
        let values: Vec<f32> = near.iter().map(|n| n.1).collect();
        assert_eq!(values, [1.0, 1.0, 1.0, 1.0, 5.0, 5.0, 5.0]);
        assert_eq!(near[3].0, 2);
        assert!(nearest_in_row(&[f32::NAN; 3]).is_none());
    }

    #[test]
    fn a_nodata_first_row_takes_the_row_below() {
        let nan = f32::NAN;
        let (out, stats) = filled(
            3,
            3,
            vec![nan, nan, nan, 141.0, 150.0, 160.0, 170.0, 180.0, 190.0],
        );
        assert_eq!(out[..3], [141.0, 150.0, 160.0]);
        assert_eq!(
            stats,
            FillStats {
                filled: 3,
                flattened: 0
            }
        );
    }

    #[test]
    fn the_fill_is_nearest_in_two_dimensions() {
        // A hole in the middle of a column of 7s, with 1s far along its row: the nearest valid
        // samples are above and below, not along the row.
        let nan = f32::NAN;
        let w = 9;
        let mut samples = vec![7.0; w * 3];
        samples[..3].fill(1.0);
        samples[w + 4] = nan;
        samples[w] = 1.0;
        let (out, _) = filled(w, 3, samples);
        assert_eq!(out[w + 4], 7.0);
    }

    #[test]
    fn a_large_nodata_area_is_flat_at_the_local_minimum() {
        let nan = f32::NAN;
        let (w, h) = (4, 3 * FILL_RADIUS);
        let mut samples = vec![nan; w * h];
        for (k, v) in samples[(h - 1) * w..].iter_mut().enumerate() {
            *v = 100.0 + k as f32;
        }
        let (out, stats) = filled(w, h, samples);
        assert!(out[..w].iter().all(|&v| v == 100.0), "{:?}", &out[..w]);
        assert_eq!(out[(h - 2) * w..(h - 1) * w], [100.0, 101.0, 102.0, 103.0]);
        assert!(stats.flattened > 0 && stats.filled > 0);
        assert_eq!(stats.filled + stats.flattened, (w * (h - 1)) as u64);
    }

    #[test]
    fn a_nodata_band_to_the_end_lies_flat_at_the_last_data_row_lowest() {
        // Two rows with data, then a band of nodata far taller than the fill looks.
        let rows = 2 + 3 * FILL_RADIUS;
        let mut samples = vec![f32::NAN; 3 * rows];
        samples[..6].copy_from_slice(&[5.0, 7.0, 9.0, 4.0, 6.0, 8.0]);
        let r = MemoryReader::new("coast.asc", 3, rows, samples).unwrap();
        let mut fill = NodataFill::new(r, None);
        let mut samples = vec![0.0; 3 * rows];
        for row in samples.chunks_exact_mut(3) {
            fill.read_row(row).unwrap();
        }
        assert_eq!(&samples[..6], &[5.0, 7.0, 9.0, 4.0, 6.0, 8.0]);
        assert!(samples[3 * (rows - 1)..].iter().all(|&v| v == 4.0));
        assert_eq!(
            fill.stats().filled + fill.stats().flattened,
            3 * (rows as u64 - 2)
        );
    }

    #[test]
    fn a_dem_without_valid_samples_is_an_error() {
        let r = MemoryReader::new("void.asc", 2, 2, vec![f32::NAN; 4]).unwrap();
        let e = NodataFill::new(r, None).read_all().unwrap_err().to_string();
        assert!(e.contains("void.asc") && e.contains("nodata"), "{e}");
    }
}
