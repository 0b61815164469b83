//! Reading an archive through any [`TileSource`], with checksums and retries.

use super::{HEADER_LEN, Header, IndexEntry, decompress, parse_index};
use crate::error::{Error, Result};
use crate::source::TileSource;
use crate::tile::Tile;

/// Reads an archive through a [`TileSource`]: header and index once, then tiles on demand, each
/// checked against its crc32 and fetched again (up to `attempts` times) when it fails.
pub struct ArchiveReader<S> {
    source: S,
    header: Header,
    index: Vec<IndexEntry>,
    attempts: u32,
}

/// How many times a reader fetches a piece (header, index, tile) before giving up.
pub const DEFAULT_ATTEMPTS: u32 = 4;

impl<S: TileSource> ArchiveReader<S> {
    /// Fetches and validates the header and the index.
    pub fn open(source: S) -> Result<Self> {
        Self::open_with_attempts(source, DEFAULT_ATTEMPTS)
    }

    /// [`ArchiveReader::open`] with a bound on fetch attempts per piece (at least 1).
    pub fn open_with_attempts(source: S, attempts: u32) -> Result<Self> {
        let attempts = attempts.max(1);
        let name = source.name().to_string();
        let file_len = source.size()?;
        let header = retry(attempts, || {
            let bytes = source.read_range(0, file_len.min(HEADER_LEN as u64))?;
            Header::parse(&bytes, &name)
        })?;
        if file_len < header.payload_start() {
            return Err(Error::invalid(
                &name,
                format!(
                    "truncated index: the file is {file_len} bytes, the index ends at {}",
                    header.payload_start()
                ),
            ));
        }
        let index = retry(attempts, || {
            let bytes = source.read_range(HEADER_LEN as u64, header.index_len() as u64)?;
            parse_index(&bytes, &header, Some(file_len), &name)
        })?;
        Ok(ArchiveReader {
            source,
            header,
            index,
            attempts,
        })
    }

    /// The header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// The index, one entry per tile in row-major order.
    pub fn index(&self) -> &[IndexEntry] {
        &self.index
    }

    /// The source's name (file path or URL).
    pub fn name(&self) -> &str {
        self.source.name()
    }

    /// The stored bytes of tile `i` (row-major), verified against the index checksum.
    pub fn tile_bytes(&self, i: usize) -> Result<Vec<u8>> {
        let name = self.source.name();
        let entry = *self.index.get(i).ok_or_else(|| {
            Error::invalid(
                name,
                format!("tile {i} does not exist ({} tiles)", self.index.len()),
            )
        })?;
        let mut last = None;
        for attempt in 1..=self.attempts {
            match self
                .source
                .read_range(entry.offset, u64::from(entry.length))
            {
                Ok(bytes) => {
                    let actual = crc32fast::hash(&bytes);
                    if actual == entry.crc32 && bytes.len() == entry.length as usize {
                        return Ok(bytes);
                    }
                    last = Some(Error::Checksum {
                        name: name.to_string(),
                        tile: i,
                        expected: entry.crc32,
                        actual,
                        attempts: attempt,
                    });
                }
                Err(e) => last = Some(e),
            }
        }
        Err(last.expect("at least one attempt"))
    }

    /// Tile `(tx, ty)`, fetched, verified and decoded.
    pub fn tile(&self, tx: usize, ty: usize) -> Result<Tile> {
        let name = self.source.name();
        if tx >= self.header.tiles_x as usize || ty >= self.header.tiles_y as usize {
            return Err(Error::invalid(
                name,
                format!(
                    "tile ({tx}, {ty}) is outside the {} x {} grid",
                    self.header.tiles_x, self.header.tiles_y
                ),
            ));
        }
        let i = ty * self.header.tiles_x as usize + tx;
        let label = format!("{name} tile {i}");
        let raw = decompress(&self.tile_bytes(i)?, &self.header, &label)?;
        let tile = Tile::decode(
            &raw,
            self.header.tile_size as usize,
            self.header.texture_size as usize,
            &label,
        )?;
        if tile.quantum != self.header.height_quantum {
            return Err(Error::invalid(
                &label,
                format!(
                    "height quantum {} differs from the archive's {}",
                    tile.quantum, self.header.height_quantum
                ),
            ));
        }
        Ok(tile)
    }
}

/// Runs `f` up to `attempts` times until it succeeds; returns the last error.
fn retry<T>(attempts: u32, mut f: impl FnMut() -> Result<T>) -> Result<T> {
    let mut result = f();
    for _ in 1..attempts {
        if result.is_ok() {
            break;
        }
        result = f();
    }
    result
}
