//! Reading an archive through any [`TileSource`], with checksums and retries.

use std::ops::Range;

use super::{HEADER_LEN, Header, IndexEntry, base_range, decompress, parse_index};
use crate::db::source::TileSource;
use crate::db::tile::Tile;
use crate::error::{Error, Result};

/// Reads an archive through a [`TileSource`]: header and index once, then ranges of tile levels
/// on demand, each in one source read, every chunk checked against its crc32 and the range
/// fetched again (up to `attempts` times) when one fails.
pub struct ArchiveReader<S> {
    source: S,
    header: Header,
    index: Vec<IndexEntry>,
    attempts: u32,
    /// The source's size in bytes, for [`ArchiveReader::check`]'s end-of-archive test.
    file_len: u64,
}

/// How many times a reader fetches a piece (header, index, tile levels) before giving up.
pub const DEFAULT_ATTEMPTS: u32 = 4;

/// The decompressed chunks of a range of one tile's progressive levels.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelBytes {
    /// The raw chunks, coarse first, one per level of the range.
    pub chunks: Vec<Vec<u8>>,
    /// Stored (compressed) bytes read from the source for them.
    pub stored_bytes: u64,
}

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
        let (base_offset, base_len) = base_range(&index, header.base_levels as usize);
        if base_offset
            .checked_add(base_len)
            .is_none_or(|end| end > file_len)
        {
            return Err(Error::invalid(
                &name,
                format!(
                    "truncated base: {base_len} bytes at offset {base_offset} of a \
                     {file_len}-byte file"
                ),
            ));
        }
        Ok(ArchiveReader {
            source,
            header,
            index,
            attempts,
            file_len,
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

    /// The source's size in bytes.
    pub fn file_len(&self) -> u64 {
        self.file_len
    }

    /// The source's name (file path or URL).
    pub fn name(&self) -> &str {
        self.source.name()
    }

    /// The byte range (file offset, length) holding `levels` of tile `(x, y)`: what one HTTP
    /// Range request for them asks, found in O(1). Panics when the tile is outside the grid or
    /// the levels outside `0..header().levels()`.
    pub fn level_range(&self, x: usize, y: usize, levels: Range<usize>) -> (u64, u64) {
        let (tiles_x, tiles_y) = (self.header.tiles_x as usize, self.header.tiles_y as usize);
        assert!(
            x < tiles_x && y < tiles_y,
            "tile ({x}, {y}) is outside the {tiles_x} x {tiles_y} grid"
        );
        self.index[y * tiles_x + x].range(levels)
    }

    /// The stored bytes of tile `i` (row-major), every chunk verified against its checksum.
    pub fn tile_bytes(&self, i: usize) -> Result<Vec<u8>> {
        let name = self.source.name();
        if i >= self.index.len() {
            return Err(Error::invalid(
                name,
                format!("tile {i} does not exist ({} tiles)", self.index.len()),
            ));
        }
        self.fetch(i, 0..self.header.levels())
    }

    /// The raw chunks of `levels` of tile `(x, y)`, fetched with one source read (one HTTP
    /// Range request), each chunk checked against its crc32 and decompressed on its own.
    pub fn read_levels(&self, x: usize, y: usize, levels: Range<usize>) -> Result<LevelBytes> {
        let i = self.tile_number(x, y)?;
        let all = self.header.levels();
        if levels.start > levels.end || levels.end > all {
            return Err(Error::invalid(
                self.name(),
                format!("levels {levels:?} of tile ({x}, {y}) are outside 0..{all}"),
            ));
        }
        let stored = self.fetch(i, levels.clone())?;
        let entry = &self.index[i];
        let base = entry.range(levels.start..levels.start).0;
        let chunks = levels
            .map(|g| {
                let (offset, len) = entry.range(g..g + 1);
                let at = (offset - base) as usize;
                let label = format!("{} tile {i} level {g}", self.name());
                let size = self.header.level_payload_size(g);
                decompress(
                    &stored[at..at + len as usize],
                    self.header.codec,
                    size,
                    &label,
                )
            })
            .collect::<Result<_>>()?;
        Ok(LevelBytes {
            chunks,
            stored_bytes: stored.len() as u64,
        })
    }

    /// The coarser tile made of the first `levels` progressive levels of tile `(x, y)` (the
    /// whole tile for `header().levels()`), and the stored bytes read for it.
    pub fn tile_levels(&self, x: usize, y: usize, levels: usize) -> Result<(Tile, u64)> {
        let i = self.tile_number(x, y)?;
        if levels == 0 {
            return Err(Error::invalid(
                self.name(),
                format!("tile ({x}, {y}) asked for with no levels"),
            ));
        }
        let read = self.read_levels(x, y, 0..levels)?;
        let label = format!("{} tile {i}", self.name());
        let chunks: Vec<&[u8]> = read.chunks.iter().map(Vec::as_slice).collect();
        Ok((self.decode(&chunks, &label)?, read.stored_bytes))
    }

    /// The tile that `chunks` (raw, coarse first from level 0) make, in the archive's height
    /// quantum; `label` names it in errors.
    fn decode(&self, chunks: &[&[u8]], label: &str) -> Result<Tile> {
        let tile = Tile::from_levels(
            chunks,
            self.header.tile_size as usize,
            self.header.texture_size as usize,
            label,
        )?;
        if tile.quantum != self.header.height_quantum {
            return Err(Error::invalid(
                label,
                format!(
                    "height quantum {} differs from the archive's {}",
                    tile.quantum, self.header.height_quantum
                ),
            ));
        }
        Ok(tile)
    }

    /// The base: the first [`Header::base_levels`] levels of every tile, row-major, fetched
    /// with one source read (one HTTP Range request), every chunk checked against its crc32 in
    /// the index, and the stored bytes read. Empty when the archive has no base.
    pub fn base(&self) -> Result<(Vec<Tile>, u64)> {
        let levels = self.header.base_levels as usize;
        if levels == 0 {
            return Ok((Vec::new(), 0));
        }
        let (offset, length) = base_range(&self.index, levels);
        let name = self.name();
        let stored = retry(self.attempts, || {
            let bytes = self.source.read_range(offset, length)?;
            if bytes.len() as u64 != length {
                return Err(Error::invalid(
                    name,
                    format!(
                        "base: read {} bytes at offset {offset}, {length} expected",
                        bytes.len()
                    ),
                ));
            }
            let mut at = 0usize;
            for (i, entry) in self.index.iter().enumerate() {
                for g in 0..levels {
                    let len = entry.range(g..g + 1).1 as usize;
                    let actual = crc32fast::hash(&bytes[at..at + len]);
                    let expected = entry.levels[g].crc32;
                    if actual != expected {
                        return Err(Error::Checksum {
                            name: name.to_string(),
                            tile: i,
                            level: g,
                            expected,
                            actual,
                            attempts: 1,
                        });
                    }
                    at += len;
                }
            }
            Ok(bytes)
        })?;
        let mut at = 0usize;
        let mut tiles = Vec::with_capacity(self.index.len());
        for (i, entry) in self.index.iter().enumerate() {
            let label = format!("{name} base tile {i}");
            let chunks = (0..levels)
                .map(|g| {
                    let len = entry.range(g..g + 1).1 as usize;
                    let raw = decompress(
                        &stored[at..at + len],
                        self.header.codec,
                        self.header.level_payload_size(g),
                        &label,
                    );
                    at += len;
                    raw
                })
                .collect::<Result<Vec<_>>>()?;
            let chunks: Vec<&[u8]> = chunks.iter().map(Vec::as_slice).collect();
            tiles.push(self.decode(&chunks, &label)?);
        }
        Ok((tiles, length))
    }

    /// Tile `(x, y)` whole, fetched in one source read, verified and decoded.
    pub fn tile(&self, x: usize, y: usize) -> Result<Tile> {
        Ok(self.tile_levels(x, y, self.header.levels())?.0)
    }

    /// The row-major number of tile `(x, y)`, or an error naming the grid.
    fn tile_number(&self, x: usize, y: usize) -> Result<usize> {
        let (tiles_x, tiles_y) = (self.header.tiles_x as usize, self.header.tiles_y as usize);
        if x >= tiles_x || y >= tiles_y {
            return Err(Error::invalid(
                self.name(),
                format!("tile ({x}, {y}) is outside the {tiles_x} x {tiles_y} grid"),
            ));
        }
        Ok(y * tiles_x + x)
    }

    /// The stored bytes of `levels` of tile `i` in one source read per attempt, returned once
    /// every chunk matches its crc32.
    fn fetch(&self, i: usize, levels: Range<usize>) -> Result<Vec<u8>> {
        let name = self.source.name();
        let entry = &self.index[i];
        let (offset, length) = entry.range(levels.clone());
        let mut last = None;
        for attempt in 1..=self.attempts {
            match self.source.read_range(offset, length) {
                Ok(bytes) if bytes.len() as u64 != length => {
                    last = Some(Error::invalid(
                        name,
                        format!(
                            "tile {i}: read {} bytes at offset {offset}, {length} expected",
                            bytes.len()
                        ),
                    ));
                }
                Ok(bytes) => {
                    let failed = levels.clone().find_map(|g| {
                        let (at, len) = entry.range(g..g + 1);
                        let at = (at - offset) as usize;
                        let actual = crc32fast::hash(&bytes[at..at + len as usize]);
                        let expected = entry.levels[g].crc32;
                        (actual != expected).then_some((g, expected, actual))
                    });
                    let Some((level, expected, actual)) = failed else {
                        return Ok(bytes);
                    };
                    last = Some(Error::Checksum {
                        name: name.to_string(),
                        tile: i,
                        level,
                        expected,
                        actual,
                        attempts: attempt,
                    });
                }
                Err(e) => last = Some(e),
            }
        }
        Err(last.expect("at least one attempt"))
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
