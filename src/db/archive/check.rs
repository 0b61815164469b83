//! Verifying a whole archive: every tile fetched, checked against its checksums and decoded.

use std::time::Instant;

use serde::Serialize;

use super::{ArchiveReader, base_range};
use crate::db::source::TileSource;
use crate::error::{Error, Result};

/// What [`ArchiveReader::check`] read, and how fast.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CheckReport {
    /// Tiles verified and decoded: all of them.
    pub tiles: usize,
    /// Stored bytes read: every tile's, then the coarse base's.
    pub bytes: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Tiles verified and decoded per second.
    pub tiles_per_second: f64,
    /// Stored mebibytes (2^20 bytes) read per second.
    pub mebibytes_per_second: f64,
}

impl<S: TileSource> ArchiveReader<S> {
    /// Fetches every tile in row-major order, checks each chunk against its crc32 and decodes
    /// the tile, then the coarse base; the first piece that fails is the error. Bytes after the
    /// archive's end (something appended to the file) are an error too: the archive itself
    /// would read, but the file is not what `build` wrote.
    pub fn check(&self) -> Result<CheckReport> {
        let started = Instant::now();
        let (tiles_x, tiles_y) = (
            self.header().tiles_x as usize,
            self.header().tiles_y as usize,
        );
        let mut bytes = 0;
        for ty in 0..tiles_y {
            for tx in 0..tiles_x {
                self.tile(tx, ty)?;
                bytes += self.index()[ty * tiles_x + tx].stored_len();
            }
        }
        let (_, base_bytes) = self.base()?;
        bytes += base_bytes;
        let (base_offset, base_len) = base_range(self.index(), self.header().base_levels as usize);
        let end = base_offset + base_len;
        if self.file_len() > end {
            return Err(Error::invalid(
                self.name(),
                format!(
                    "{} bytes after the archive's end at byte {end} (appended to the file?)",
                    self.file_len() - end
                ),
            ));
        }
        let seconds = started.elapsed().as_secs_f64().max(1e-9);
        let tiles = tiles_x * tiles_y;
        Ok(CheckReport {
            tiles,
            bytes,
            seconds,
            tiles_per_second: tiles as f64 / seconds,
            mebibytes_per_second: bytes as f64 / seconds / (1024.0 * 1024.0),
        })
    }
}
