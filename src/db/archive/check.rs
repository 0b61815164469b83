//! Verifying a whole archive: every tile fetched, checked against its checksums and decoded.

use std::time::Instant;

use serde::Serialize;

use super::ArchiveReader;
use crate::db::source::TileSource;
use crate::error::Result;

/// What [`ArchiveReader::check`] read, and how fast.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CheckReport {
    /// Tiles verified and decoded: all of them.
    pub tiles: usize,
    /// Stored bytes read.
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
    /// the tile; the first tile that fails is the error.
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
