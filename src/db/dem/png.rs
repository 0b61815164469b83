//! PNG height maps (8 or 16 bits), decoded a row at a time: grayscale (with or without alpha),
//! or RGB(A) whose three colour channels are equal in every pixel, or 8-bit RGB(A) tiles of
//! the web maps' height encodings (Terrain-RGB, Terrarium); alpha is ignored.

use std::fs::File;
use std::io::{BufRead, BufReader, Cursor, Seek};
use std::path::Path;

use png::{BitDepth, ColorType, Transformations};

use super::{DemInfo, DemReader, HeightEncoding, check_claim, check_dimensions};
use crate::error::{Error, Result};
use crate::named::Named;

/// What `build` says about an 8-bit height map: 256 levels, scaled by `--vertical-scale`.
pub(crate) const EIGHT_BIT_NOTE: &str =
    "8-bit samples: 256 height levels of --vertical-scale metres each (1 m unless given)";

/// The most a PNG's samples may outweigh its file: zlib's DEFLATE stays under 1032 to 1.
const MAX_EXPANSION: u64 = 1032;

/// The largest interlaced image decoded whole (512 MiB).
const MAX_INTERLACED_BYTES: usize = 512 << 20;

/// Streams rows of a grayscale PNG, from a file or from bytes in memory. Interlaced files are
/// decoded whole (the rows of an Adam7 image arrive out of order), non-interlaced ones one row
/// at a time.
pub struct PngReader<R: BufRead + Seek = BufReader<File>> {
    info: DemInfo,
    decoder: png::Reader<R>,
    sixteen_bit: bool,
    /// Samples per pixel: 1 gray, 2 gray + alpha, 3 RGB, 4 RGBA.
    channels: usize,
    /// How the pixels hold heights.
    encoding: HeightEncoding,
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
        PngReader::from_reader(name, BufReader::new(file), file_len)
    }
}

impl PngReader<Cursor<&'static [u8]>> {
    /// Reads a PNG held in the program itself, called `name` in messages.
    pub fn from_bytes(name: &str, bytes: &'static [u8]) -> Result<Self> {
        PngReader::from_reader(name.to_string(), Cursor::new(bytes), bytes.len() as u64)
    }
}

impl<R: BufRead + Seek> PngReader<R> {
    /// Reads the header of the PNG that `input` yields, `input_len` bytes long.
    fn from_reader(name: String, input: R, input_len: u64) -> Result<Self> {
        let mut decoder = png::Decoder::new(input);
        decoder.set_transformations(Transformations::EXPAND);
        decoder.set_ignore_text_chunk(true);
        let mut reader = decoder
            .read_info()
            .map_err(|e| Error::invalid(&name, format!("not a readable PNG: {e}")))?;
        let (color, depth) = reader.output_color_type();
        let channels = match color {
            ColorType::Grayscale => 1,
            ColorType::GrayscaleAlpha => 2,
            ColorType::Rgb => 3,
            ColorType::Rgba => 4,
            ColorType::Indexed => {
                return Err(Error::invalid(
                    &name,
                    "a palette PNG is not a height map; it must be grayscale (or RGB with \
                     equal channels)",
                ));
            }
        };
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
        let row_bytes = (width * channels) as u64 * if sixteen_bit { 2 } else { 1 };
        check_claim(&name, row_bytes * height as u64, input_len, MAX_EXPANSION)?;
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
        let mut info = DemInfo::new(&name, width, height);
        if !sixteen_bit {
            info.notes.push(EIGHT_BIT_NOTE.to_string());
        }
        Ok(PngReader {
            info,
            decoder: reader,
            sixteen_bit,
            channels,
            encoding: HeightEncoding::Gray,
            frame,
            next_row: 0,
        })
    }

    /// Reads heights stored as `encoding` (8-bit RGB for the web maps' encodings).
    pub fn with_encoding(mut self, encoding: HeightEncoding) -> Result<Self> {
        if encoding != HeightEncoding::Gray {
            if self.channels < 3 || self.sixteen_bit {
                return Err(Error::invalid(
                    &self.info.name,
                    format!(
                        "a {} PNG has 8-bit red, green and blue channels; this one has {} {}-bit channel(s)",
                        encoding.name(),
                        self.channels,
                        if self.sixteen_bit { 16 } else { 8 }
                    ),
                ));
            }
            self.info.notes.retain(|n| n != EIGHT_BIT_NOTE);
            self.info.notes.push(format!(
                "heights decoded from {} pixels, in metres",
                encoding.name()
            ));
        }
        self.encoding = encoding;
        Ok(self)
    }
}

impl<R: BufRead + Seek> DemReader for PngReader<R> {
    fn info(&self) -> &DemInfo {
        &self.info
    }

    fn read_row(&mut self, row: &mut [f32]) -> Result<()> {
        let bytes_per_sample = if self.sixteen_bit { 2 } else { 1 };
        let pixel = bytes_per_sample * self.channels;
        let line = self.info.width * pixel;
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
        let sixteen_bit = self.sixteen_bit;
        let sample = |b: &[u8]| {
            if sixteen_bit {
                f32::from(u16::from_be_bytes([b[0], b[1]]))
            } else {
                f32::from(b[0])
            }
        };
        if self.encoding != HeightEncoding::Gray {
            for (v, p) in row.iter_mut().zip(data.chunks_exact(pixel)) {
                *v = self.encoding.decode([p[0], p[1], p[2]]);
            }
            self.next_row += 1;
            return Ok(());
        }
        for (i, (v, p)) in row.iter_mut().zip(data.chunks_exact(pixel)).enumerate() {
            *v = sample(p);
            if self.channels >= 3 {
                let (g, b) = (
                    sample(&p[bytes_per_sample..]),
                    sample(&p[2 * bytes_per_sample..]),
                );
                if g != *v || b != *v {
                    return Err(Error::invalid(
                        &self.info.name,
                        format!(
                            "pixel ({i}, {}) has red {v}, green {g}, blue {b}: a colour image, \
                             not a height map (its three channels must be equal)",
                            self.next_row
                        ),
                    ));
                }
            }
        }
        self.next_row += 1;
        Ok(())
    }
}
