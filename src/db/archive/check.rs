//! Verifying a whole archive: every tile of every level fetched, checked against its checksums
//! and decoded.

use std::time::Instant;

use serde::Serialize;

use super::ArchiveReader;
use crate::db::grid::TileId;
use crate::db::source::{CancelToken, TileSource};
use crate::error::{Error, Result};

/// What [`ArchiveReader::check`] read, and how fast.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CheckReport {
    /// Tiles verified and decoded: all present tiles of every level.
    pub tiles: u64,
    /// Tiles stored as absent, of every level.
    pub absent: u64,
    /// Stored bytes read: every index page and tile, then the top.
    pub bytes: u64,
    /// Stored bytes per progressive level, mean over every present tile of every level.
    pub stored_level_bytes_mean: Vec<f64>,
    /// Wall-clock seconds.
    pub seconds: f64,
    /// Tiles verified and decoded per second.
    pub tiles_per_second: f64,
    /// Stored mebibytes (2^20 bytes) read per second.
    pub mebibytes_per_second: f64,
}

impl<S: TileSource> ArchiveReader<S> {
    /// Fetches every tile of every level in row-major order (through its index page), checks
    /// each chunk against its crc32 and decodes the tile, then the top; the first piece that
    /// fails is the error. Bytes after the archive's end (something appended to the file) are
    /// an error too: the archive itself would read, but the file is not what `build` wrote.
    pub fn check(&self) -> Result<CheckReport> {
        let started = Instant::now();
        let (mut tiles, mut absent, mut bytes, mut level0_absent) = (0u64, 0u64, 0u64, 0u64);
        let mut level_bytes = vec![0u64; self.header().levels()];
        let pyramid = self.pyramid().clone();
        let cancel = CancelToken::new();
        for k in 0..pyramid.levels() {
            let grid = pyramid.grid(k as u8);
            for y in 0..grid.tiles_y() {
                for x in 0..grid.tiles_x() {
                    let id = TileId::at(k as u8, x, y);
                    let (entry, read) = self.entry(id, &cancel)?;
                    bytes += read;
                    if entry.is_absent() {
                        absent += 1;
                        level0_absent += u64::from(k == 0);
                        continue;
                    }
                    self.tile(id)?;
                    bytes += entry.stored_len();
                    tiles += 1;
                    for (g, sum) in level_bytes.iter_mut().enumerate() {
                        *sum += entry.range(g..g + 1).1;
                    }
                }
            }
        }
        let (_, top_bytes) = self.top()?;
        bytes += top_bytes;
        let end = self.header().archive_len;
        if self.file_len() > end {
            return Err(Error::invalid(
                self.name(),
                format!(
                    "{} bytes after the archive's end at byte {end} (appended to the file?)",
                    self.file_len() - end
                ),
            ));
        }
        if level0_absent != self.header().absent_tiles {
            return Err(Error::invalid(
                self.name(),
                format!(
                    "{level0_absent} level-0 tiles are absent, the header says {}",
                    self.header().absent_tiles
                ),
            ));
        }
        let seconds = started.elapsed().as_secs_f64().max(1e-9);
        Ok(CheckReport {
            tiles,
            absent,
            bytes,
            stored_level_bytes_mean: level_bytes
                .iter()
                .map(|&b| b as f64 / tiles.max(1) as f64)
                .collect(),
            seconds,
            tiles_per_second: tiles as f64 / seconds,
            mebibytes_per_second: bytes as f64 / seconds / (1024.0 * 1024.0),
        })
    }
}
