//! Single-band GeoTIFF (and plain TIFF) elevation grids, read one strip or one row of tiles at a
//! time: DEFLATE, LZW and PackBits with the `tiff` crate, ZSTD and LERC (alone, or inside
//! DEFLATE or ZSTD) with [`tiff_codecs`]; horizontal and floating-point predictors.

#[path = "tiff_codecs.rs"]
mod tiff_codecs;

use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use tiff::ColorType;
use tiff::decoder::{ChunkType, Decoder, DecodingResult};
use tiff::tags::{ByteOrder, Tag};

use tiff_codecs::{ChunkCodec, Codec, LERC_PARAMETERS, SampleLayout};

use super::placement::{FOOT, Placement, US_SURVEY_FOOT, Units, WEB_MERCATOR};
use super::{DemInfo, DemReader, check_claim, check_dimensions};
use crate::error::{Error, Result};

/// Streams rows of a single-band TIFF. Holds one chunk row: one strip, or one row of tiles.
pub struct TiffReader {
    info: DemInfo,
    decoder: Decoder<BufReader<File>>,
    nodata: Option<f64>,
    /// GDAL's scale and offset of the band: a height is `raw * scale + offset`.
    scaling: Scaling,
    /// Per chunk, whether the file stores no bytes for it (a sparse file's nodata chunk).
    empty: Vec<bool>,
    /// The decoder of chunks compressed with a codec the `tiff` crate lacks (ZSTD, LERC),
    /// read from their stored bytes at `chunks`.
    codec: Option<ChunkCodec>,
    /// Per chunk, the offset and byte count of its stored bytes, when `codec` reads them.
    chunks: Vec<(u64, u64)>,
    chunk_width: usize,
    chunk_height: usize,
    chunks_across: usize,
    /// The current chunk row, `band_rows * width` samples.
    band: Vec<f32>,
    band_rows: usize,
    band_first_row: usize,
    next_row: usize,
}

impl TiffReader {
    /// Opens `path` and reads its first image's tags.
    pub fn open(path: &Path) -> Result<Self> {
        let name = path.display().to_string();
        let bad = |e: tiff::TiffError| Error::invalid(&name, format!("not a readable TIFF: {e}"));
        let file = File::open(path).map_err(|e| Error::io(&name, e))?;
        let file_len = file.metadata().map_err(|e| Error::io(&name, e))?.len();
        let mut decoder = Decoder::new(BufReader::new(file)).map_err(bad)?;
        let (w, h) = decoder.dimensions().map_err(bad)?;
        let (width, height) = (w as usize, h as usize);
        check_dimensions(&name, width, height)?;
        match decoder.colortype().map_err(bad)? {
            ColorType::Gray(8 | 16 | 32 | 64) => {}
            other => {
                return Err(Error::invalid(
                    &name,
                    format!(
                        "unsupported TIFF sample layout {other:?}; an elevation grid has one band of 8, 16, 32 or 64 bits"
                    ),
                ));
            }
        }
        let nodata = match decoder.find_tag(Tag::GdalNodata) {
            Ok(Some(v)) => v
                .into_string()
                .ok()
                .and_then(|s| s.trim_matches(char::from(0)).trim().parse::<f64>().ok()),
            _ => None,
        };
        let mut info = DemInfo::new(&name, width, height);
        let scaling = match decoder.find_tag(Tag::Unknown(GDAL_METADATA)) {
            Ok(Some(v)) => match v.into_string() {
                Ok(xml) => gdal_scaling(&xml).map_err(|e| {
                    Error::invalid(&name, format!("unreadable GDAL_METADATA tag: {e}"))
                })?,
                Err(_) => Scaling::default(),
            },
            _ => Scaling::default(),
        };
        if scaling != Scaling::default() {
            info.notes.push(format!(
                "GDAL scale {} and offset {} applied: a height is the raw value times the scale plus the offset",
                scaling.scale, scaling.offset
            ));
        }
        let vertical = georeference(&mut decoder, &mut info);
        let scaling = Scaling {
            scale: scaling.scale * vertical,
            offset: scaling.offset * vertical,
        };
        let (cw, ch) = decoder.chunk_dimensions();
        let (chunk_width, chunk_height) = (cw as usize, ch as usize);
        if chunk_width == 0 || chunk_height == 0 {
            return Err(Error::invalid(
                &name,
                "TIFF has an empty strip or tile size",
            ));
        }
        let bits = match decoder.colortype().map_err(bad)? {
            ColorType::Gray(b) => u64::from(b),
            _ => 64,
        };
        let first_short = |decoder: &mut Decoder<BufReader<File>>, tag, default| {
            match decoder.find_tag(tag) {
                Ok(Some(v)) => v.into_u16_vec().ok().and_then(|v| v.first().copied()),
                _ => None,
            }
            .unwrap_or(default)
        };
        let compression = first_short(&mut decoder, Tag::Compression, 1);
        let predictor = first_short(&mut decoder, Tag::Predictor, 1);
        let lerc_parameters = match decoder.find_tag(Tag::Unknown(LERC_PARAMETERS)) {
            Ok(Some(v)) => v.into_u32_vec().map_err(bad)?,
            _ => Vec::new(),
        };
        let unsupported = |e: String| Error::invalid(&name, format!("unsupported TIFF: {e}"));
        let codec = match Codec::from_tags(compression, predictor, &lerc_parameters)
            .map_err(unsupported)?
        {
            Some(codec) => {
                let format = first_short(&mut decoder, Tag::SampleFormat, 1);
                let big_endian = decoder.byte_order() == ByteOrder::BigEndian;
                let layout =
                    SampleLayout::new(format, bits as u8, big_endian).map_err(unsupported)?;
                Some(ChunkCodec::new(codec, layout).map_err(unsupported)?)
            }
            None => None,
        };
        // GDAL's sparse files store no bytes for a chunk that is all nodata.
        let mut empty = Vec::new();
        let mut chunks = Vec::new();
        for (offsets, counts) in [
            (Tag::StripOffsets, Tag::StripByteCounts),
            (Tag::TileOffsets, Tag::TileByteCounts),
        ] {
            let list = |decoder: &mut Decoder<BufReader<File>>, tag| -> Result<Vec<u64>> {
                match decoder.find_tag(tag).map_err(bad)? {
                    Some(v) => v.into_u64_vec().map_err(bad),
                    None => Ok(Vec::new()),
                }
            };
            let offsets = list(&mut decoder, offsets)?;
            let counts = list(&mut decoder, counts)?;
            check_chunks(&name, &offsets, &counts, file_len)?;
            if !counts.is_empty() {
                empty = counts.iter().map(|&c| c == 0).collect();
                if codec.is_some() {
                    chunks = offsets.into_iter().zip(counts).collect();
                }
            }
        }
        // The samples the stored chunks decode to must come from the file's bytes; a sparse
        // file's empty chunks decode to nothing, but its band of rows is still allocated.
        let stored = empty.iter().filter(|e| !**e).count() as u64;
        let chunk_bytes = chunk_width as u64 * chunk_height as u64 * bits / 8;
        let claimed = if stored == empty.len() as u64 {
            width as u64 * height as u64 * bits / 8
        } else {
            stored * chunk_bytes
        };
        let expansion = codec.map_or(MAX_EXPANSION, ChunkCodec::max_expansion);
        check_claim(&name, claimed, file_len, expansion)?;
        let band_bytes = width as u64 * chunk_height as u64 * 4;
        if stored < empty.len() as u64 && band_bytes > MAX_SPARSE_BAND_BYTES {
            return Err(Error::invalid(
                &name,
                format!(
                    "a sparse TIFF whose rows of chunks take {} MiB each, more than the {} MiB read at a time",
                    band_bytes >> 20,
                    MAX_SPARSE_BAND_BYTES >> 20
                ),
            ));
        }
        Ok(TiffReader {
            info,
            decoder,
            nodata,
            scaling,
            empty,
            codec,
            chunks,
            chunk_width,
            chunk_height,
            chunks_across: width.div_ceil(chunk_width),
            band: Vec::new(),
            band_rows: 0,
            band_first_row: 0,
            next_row: 0,
        })
    }

    /// Decodes chunk row `chunk_row` into `band`.
    fn load_band(&mut self, chunk_row: usize) -> Result<()> {
        let name = &self.info.name;
        let width = self.info.width;
        let first = chunk_row * self.chunk_height;
        let rows = self.chunk_height.min(self.info.height - first);
        for c in 0..self.chunks_across {
            let index = u32::try_from(chunk_row * self.chunks_across + c)
                .map_err(|_| Error::invalid(name, "too many TIFF chunks"))?;
            let corrupt = |e: &dyn std::fmt::Display| {
                Error::invalid(name, format!("corrupt TIFF chunk {index}: {e}"))
            };
            let (samples, stride) = if self.empty.get(index as usize).copied().unwrap_or(false) {
                (vec![f32::NAN; self.chunk_width * rows], self.chunk_width)
            } else if let Some(codec) = self.codec {
                let at = self.chunks.get(index as usize).copied();
                let at = at.ok_or_else(|| corrupt(&"the file lists no bytes for it"))?;
                // A tile is stored whole, a strip at its rows.
                let stored_rows = match self.decoder.get_chunk_type() {
                    ChunkType::Tile => self.chunk_height,
                    ChunkType::Strip => rows,
                };
                let dims = (self.chunk_width, stored_rows);
                let chunk = codec
                    .read(self.decoder.inner(), at, dims)
                    .map_err(|e| corrupt(&e))?;
                (to_f32(chunk, self.nodata, self.scaling), self.chunk_width)
            } else {
                let chunk = self.decoder.read_chunk(index).map_err(|e| corrupt(&e))?;
                let samples = to_f32(chunk, self.nodata, self.scaling);
                let stride = samples.len() / rows;
                (samples, stride)
            };
            if c == 0 {
                // Sized only after the decoder (and its limits) accepted a chunk of this row.
                self.band.clear();
                self.band.resize(rows * width, f32::NAN);
            }
            let x0 = c * self.chunk_width;
            let cw = self.chunk_width.min(width - x0);
            if samples.len() < cw * rows {
                return Err(Error::invalid(
                    name,
                    format!(
                        "TIFF chunk {index} holds {} samples, {cw} x {rows} expected",
                        samples.len()
                    ),
                ));
            }
            for r in 0..rows {
                self.band[r * width + x0..r * width + x0 + cw]
                    .copy_from_slice(&samples[r * stride..r * stride + cw]);
            }
        }
        self.band_rows = rows;
        self.band_first_row = first;
        Ok(())
    }
}

/// The TIFF tag in which GDAL writes its metadata as XML, the band's scale and offset among it.
const GDAL_METADATA: u16 = 42112;

/// GDAL's linear transform of a band's raw values (`SCALE`, `OFFSET`; how GDAL stores
/// decimetres in integers, say).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Scaling {
    scale: f64,
    offset: f64,
}

impl Default for Scaling {
    fn default() -> Self {
        Scaling {
            scale: 1.0,
            offset: 0.0,
        }
    }
}

/// The scale and offset of the first band in GDAL's metadata XML (items with the role
/// `scale` and `offset` of sample 0, or of no sample); the identity when it has none.
fn gdal_scaling(xml: &str) -> std::result::Result<Scaling, String> {
    let doc = roxmltree::Document::parse(xml.trim_matches(char::from(0)).trim())
        .map_err(|e| e.to_string())?;
    let mut scaling = Scaling::default();
    let items = doc.descendants().filter(|n| n.has_tag_name("Item"));
    for item in items.filter(|n| n.attribute("sample").is_none_or(|s| s == "0")) {
        let value = || {
            let text = item.text().unwrap_or("").trim();
            text.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| {
                    format!(
                        "{} is not a number: {text:?}",
                        item.attribute("role").unwrap_or("")
                    )
                })
        };
        match item.attribute("role") {
            Some("scale") => scaling.scale = value()?,
            Some("offset") => scaling.offset = value()?,
            _ => {}
        }
    }
    if scaling.scale == 0.0 {
        return Err("its scale is 0".into());
    }
    Ok(scaling)
}

/// Converts decoded samples to `f32` heights (`raw * scale + offset`), nodata (a raw value,
/// as GDAL compares it) as `NaN`.
fn to_f32(chunk: DecodingResult, nodata: Option<f64>, scaling: Scaling) -> Vec<f32> {
    fn map<T>(v: Vec<T>, nodata: Option<f64>, s: Scaling, f: impl Fn(T) -> f64) -> Vec<f32> {
        v.into_iter()
            .map(|x| {
                let x = f(x);
                if Some(x) == nodata {
                    f32::NAN
                } else {
                    (x * s.scale + s.offset) as f32
                }
            })
            .collect()
    }
    let (n, s) = (nodata, scaling);
    match chunk {
        DecodingResult::U8(v) => map(v, n, s, f64::from),
        DecodingResult::U16(v) => map(v, n, s, f64::from),
        DecodingResult::U32(v) => map(v, n, s, f64::from),
        DecodingResult::U64(v) => map(v, n, s, |x| x as f64),
        DecodingResult::I8(v) => map(v, n, s, f64::from),
        DecodingResult::I16(v) => map(v, n, s, f64::from),
        DecodingResult::I32(v) => map(v, n, s, f64::from),
        DecodingResult::I64(v) => map(v, n, s, |x| x as f64),
        DecodingResult::F16(v) => map(v, n, s, f64::from),
        DecodingResult::F32(v) => {
            // Compare at f32 precision: GDAL writes the nodata text of the f32 value.
            let nd = nodata.map(|n| n as f32);
            let identity = scaling == Scaling::default();
            v.into_iter()
                .map(|x| match x {
                    x if Some(x) == nd => f32::NAN,
                    x if identity => x,
                    x => (f64::from(x) * scaling.scale + scaling.offset) as f32,
                })
                .collect()
        }
        DecodingResult::F64(v) => map(v, n, s, |x| x),
    }
}

/// Spacing (metres) and origin from the GeoTIFF pixel-scale, tie-point and GeoKey tags, into
/// `info`; a geographic grid (degrees) gets metres on both axes ([`Placement`]).
fn georeference(decoder: &mut Decoder<BufReader<File>>, info: &mut DemInfo) -> f64 {
    let scale = decoder.get_tag_f64_vec(Tag::ModelPixelScaleTag).ok();
    let tie = decoder.get_tag_f64_vec(Tag::ModelTiepointTag).ok();
    let keys = decoder
        .get_tag_u16_vec(Tag::GeoKeyDirectoryTag)
        .unwrap_or_default();
    let key = |id: u16| {
        keys.chunks_exact(4)
            .skip(1)
            .find(|k| k[0] == id && k[1] == 0)
            .map(|k| k[3])
    };
    let geographic = key(1024) == Some(2);
    let pixel_is_point = key(1025) == Some(2);
    let vertical = vertical_unit(info, key(4099));
    let Some(scale) = scale.filter(|s| s.len() >= 2 && s[0] > 0.0 && s[1] > 0.0) else {
        return vertical;
    };
    // The tie point's world position of sample (0, 0)'s centre, in the file's units.
    let first = match tie {
        Some(t) if t.len() >= 6 => {
            let half = if pixel_is_point { 0.0 } else { 0.5 };
            Some((
                t[3] + (half - t[0]) * scale[0],
                t[4] - (half - t[1]) * scale[1],
            ))
        }
        _ => None,
    };
    let (crs, units) = if geographic {
        (crs_name(key(2048), "geographic"), Units::Degrees)
    } else {
        let crs = crs_name(key(3072), "projected");
        let unit = key(3076).unwrap_or(9001);
        let Some((to_metres, _)) = metres_per_unit(unit) else {
            info.spacing_problem = Some(format!(
                "{crs} in linear unit {unit} (GeoTIFF ProjLinearUnitsGeoKey), neither metres nor \
                 feet; pass --spacing METRES"
            ));
            return vertical;
        };
        match key(3072) {
            Some(code) if WEB_MERCATOR.contains(&u32::from(code)) => {
                (crs, Units::WebMercator(to_metres))
            }
            _ => (crs, Units::Linear(to_metres)),
        }
    };
    let cell = (scale[0], scale[1]);
    match first {
        Some(first) => Placement {
            crs,
            named: [1024, 2048, 3072].into_iter().any(|id| key(id).is_some()),
            units,
            cell,
            first,
        }
        .apply(info),
        None => match units {
            Units::Degrees => {
                info.spacing_problem = Some(format!(
                    "a geographic grid of {} x {} degree cells without a tie point, so its \
                     latitude (and metres east-west) is unknown; pass --spacing METRES",
                    cell.0, cell.1
                ));
            }
            Units::Linear(to_metres) | Units::WebMercator(to_metres) => {
                info.spacing_hint = Some(cell.1 * to_metres).filter(|s| s.is_finite() && *s > 0.0);
                if (cell.0 - cell.1).abs() > 1e-9 * cell.1 {
                    info.east_west_scale = cell.0 / cell.1;
                }
            }
        },
    }
    vertical
}

/// The CRS a GeoTIFF key names: `EPSG:code`, or a user-defined one of `kind`.
fn crs_name(code: Option<u16>, kind: &str) -> String {
    match code {
        Some(c) if c != USER_DEFINED => format!("EPSG:{c}"),
        _ => format!("a user-defined {kind} CRS"),
    }
}

/// GeoTIFF's key value for a CRS that the file defines itself rather than by EPSG code.
const USER_DEFINED: u16 = 32767;

/// Metres per unit of the linear units GeoTIFF names by EPSG code: metre, foot, US survey foot.
fn metres_per_unit(code: u16) -> Option<(f64, &'static str)> {
    match code {
        9001 => Some((1.0, "metres")),
        9002 => Some((FOOT, "feet")),
        9003 => Some((US_SURVEY_FOOT, "US survey feet")),
        _ => None,
    }
}

/// The heights' metres per unit from the vertical units key (`VerticalUnitsGeoKey`), with a note
/// when they are not metres; 1 when the file does not say.
fn vertical_unit(info: &mut DemInfo, code: Option<u16>) -> f64 {
    let Some(code) = code else { return 1.0 };
    match metres_per_unit(code) {
        Some((1.0, _)) => 1.0,
        Some((factor, unit)) => {
            info.notes.push(format!(
                "heights in {unit} (the file's vertical unit): converted to metres (x {factor:.7})"
            ));
            factor
        }
        None => {
            info.notes.push(format!(
                "vertical unit code {code} unknown: heights taken as metres (--vertical-scale sets metres per unit)"
            ));
            1.0
        }
    }
}

impl DemReader for TiffReader {
    fn info(&self) -> &DemInfo {
        &self.info
    }

    fn read_row(&mut self, row: &mut [f32]) -> Result<()> {
        if self.next_row >= self.info.height {
            return Err(Error::invalid(&self.info.name, "read past the last row"));
        }
        if self.next_row >= self.band_first_row + self.band_rows || self.band_rows == 0 {
            self.load_band(self.next_row / self.chunk_height)?;
        }
        let r = self.next_row - self.band_first_row;
        let w = self.info.width;
        row.copy_from_slice(&self.band[r * w..(r + 1) * w]);
        self.next_row += 1;
        Ok(())
    }
}

/// The largest row of chunks of a sparse TIFF held at once: its empty chunks cost no file bytes
/// to bound it by.
const MAX_SPARSE_BAND_BYTES: u64 = 512 << 20;

/// The most a TIFF's samples may outweigh its file with the `tiff` crate's codecs: LZW, the
/// most compressing of them, stays under 4096 to 1 (DEFLATE under 1032 to 1); ZSTD and LERC
/// files have their own bounds ([`ChunkCodec`]).
const MAX_EXPANSION: u64 = 4096;

/// Refuses strips or tiles outside the file or sharing bytes: each chunk must have bytes of
/// its own, or one stored chunk could be decoded over and over as many.
fn check_chunks(name: &str, offsets: &[u64], counts: &[u64], file_len: u64) -> Result<()> {
    if offsets.len() != counts.len() {
        return Err(Error::invalid(
            name,
            format!(
                "the TIFF lists {} chunk offsets but {} byte counts",
                offsets.len(),
                counts.len()
            ),
        ));
    }
    let mut ranges: Vec<(u64, u64, usize)> = offsets
        .iter()
        .zip(counts)
        .enumerate()
        .filter(|(_, (_, count))| **count > 0)
        .map(|(i, (&offset, &count))| (offset, offset.saturating_add(count), i))
        .collect();
    ranges.sort_unstable();
    if let Some(&(_, end, i)) = ranges.iter().find(|r| r.1 > file_len) {
        return Err(Error::invalid(
            name,
            format!("TIFF chunk {i} ends at byte {end}, past the file's {file_len}"),
        ));
    }
    for pair in ranges.windows(2) {
        let ((_, end, a), (start, _, b)) = (pair[0], pair[1]);
        if start < end {
            return Err(Error::invalid(
                name,
                format!(
                    "TIFF chunks {a} and {b} share bytes (a decompression bomb or a corrupt file)"
                ),
            ));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gdal_scaling_reads_band_one_and_refuses_what_is_not_a_number() {
        let xml = r#"<GDALMetadata>
  <Item name="OFFSET" sample="0" role="offset">-200</Item>
  <Item name="SCALE" sample="0" role="scale">0.1</Item>
  <Item name="SCALE" sample="1" role="scale">5</Item>
  <Item name="AREA_OR_POINT">Area</Item>
</GDALMetadata>"#;
        let band_one = Scaling {
            scale: 0.1,
            offset: -200.0,
        };
        assert_eq!(gdal_scaling(xml), Ok(band_one));
        let none = r#"<GDALMetadata><Item name="AREA_OR_POINT">Point</Item></GDALMetadata>"#;
        assert_eq!(gdal_scaling(none), Ok(Scaling::default()));
        for bad in [
            r#"<GDALMetadata><Item role="scale">x</Item></GDALMetadata>"#,
            r#"<GDALMetadata><Item role="scale">0</Item></GDALMetadata>"#,
            r#"<GDALMetadata><Item role="offset">inf</Item></GDALMetadata>"#,
            "<GDALMetadata>",
        ] {
            assert!(gdal_scaling(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn heights_are_scaled_after_nodata_is_compared_on_the_raw_value() {
        let s = Scaling {
            scale: 0.1,
            offset: -200.0,
        };
        let h = to_f32(DecodingResult::U16(vec![0, 10, 65535]), Some(65535.0), s);
        assert_eq!(h[..2], [-200.0, -199.0]);
        assert!(h[2].is_nan());
        let f = to_f32(
            DecodingResult::F32(vec![1.5, -9999.0]),
            Some(-9999.0),
            Scaling::default(),
        );
        assert_eq!(f[0], 1.5);
        assert!(f[1].is_nan());
    }
}
