//! Headerless raw grids and BIL files: the caller gives width, height and sample type.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::path::Path;

use super::{DemInfo, DemReader, RawLayout, check_dimensions};
use crate::error::{Error, Result};

/// Streams rows of a raw file laid out as [`RawLayout`] says.
pub struct RawReader {
    info: DemInfo,
    layout: RawLayout,
    /// A sample value that the format itself reserves for "no data" (e.g. SRTM's -32768).
    void: Option<f32>,
    file: Box<dyn Read + Send>,
    buf: Vec<u8>,
}

impl RawReader {
    /// Opens `path`, checking that its length matches the layout exactly.
    pub fn open(path: &Path, layout: RawLayout) -> Result<Self> {
        let name = path.display().to_string();
        check_dimensions(&name, layout.width, layout.height)?;
        let mut file = File::open(path).map_err(|e| Error::io(&name, e))?;
        let len = file.metadata().map_err(|e| Error::io(&name, e))?.len();
        check_length(&name, len, layout)?;
        file.seek(SeekFrom::Start(layout.header_bytes))
            .map_err(|e| Error::io(&name, e))?;
        Ok(RawReader::from_read(
            &name,
            Box::new(BufReader::new(file)),
            layout,
        ))
    }

    /// Reads the samples `input` yields, called `name` in messages; the caller has checked
    /// that it holds exactly the layout's bytes after its header (which is skipped already).
    pub(crate) fn from_read(name: &str, input: Box<dyn Read + Send>, layout: RawLayout) -> Self {
        RawReader {
            info: DemInfo::new(name, layout.width, layout.height),
            layout,
            void: None,
            file: input,
            buf: vec![0; layout.width * layout.sample_type.size()],
        }
    }
}

/// Checks that `len` bytes are exactly what `layout` needs.
pub(crate) fn check_length(name: &str, len: u64, layout: RawLayout) -> Result<()> {
    let expected = (layout.width as u64)
        .checked_mul(layout.height as u64)
        .and_then(|n| n.checked_mul(layout.sample_type.size() as u64))
        .and_then(|n| n.checked_add(layout.header_bytes))
        .ok_or_else(|| Error::invalid(name, "dimensions overflow"))?;
    if len != expected {
        return Err(Error::invalid(
            name,
            format!(
                "file is {len} bytes but {} x {} {:?} samples after a {}-byte header need {expected}",
                layout.width, layout.height, layout.sample_type, layout.header_bytes
            ),
        ));
    }
    Ok(())
}

impl RawReader {
    /// Reads `void` samples as missing (NaN), for formats that reserve a value.
    pub fn with_void(mut self, void: f32) -> Self {
        self.void = Some(void);
        self
    }

    /// The description, for formats that know more than the raw layout says.
    pub(crate) fn info_mut(&mut self) -> &mut DemInfo {
        &mut self.info
    }
}

impl DemReader for RawReader {
    fn info(&self) -> &DemInfo {
        &self.info
    }

    fn read_row(&mut self, row: &mut [f32]) -> Result<()> {
        self.file
            .read_exact(&mut self.buf)
            .map_err(|e| Error::io(&self.info.name, e))?;
        let t = self.layout.sample_type;
        for (v, b) in row.iter_mut().zip(self.buf.chunks_exact(t.size())) {
            let h = t.decode(b, self.layout.big_endian);
            *v = if Some(h) == self.void { f32::NAN } else { h };
        }
        Ok(())
    }
}
