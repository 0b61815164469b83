//! Reading an archive through any [`TileSource`], with checksums and retries; a chunk that
//! fails its checksum is reported to the source, which may find that the archive changed.

use std::ops::Range;
use std::time::Duration;

use super::{HEADER_LEN, Header, IndexEntry, base_range, decompress, parse_index};
use crate::db::backoff::Backoff;
use crate::db::source::{CancelToken, TileSource};
use crate::db::tile::Tile;
use crate::error::{Error, Result};

/// Reads an archive through a [`TileSource`]: header and index once, then ranges of tile levels
/// on demand, each in one source read, every chunk checked against its crc32 and the range
/// fetched again (up to `attempts` times) when one fails.
///
/// A remote source's retries wait as [`RETRY_BACKOFF`] says; a request that timed out is not
/// asked again at once (the server already had its whole timeout): the error goes back to the
/// caller, and the pager tries the tile again later.
pub struct ArchiveReader<S> {
    source: S,
    header: Header,
    index: Vec<IndexEntry>,
    /// Attempts at a tile's levels or the base.
    attempts: u32,
    /// The source's size in bytes, for [`ArchiveReader::check`]'s end-of-archive test.
    file_len: u64,
}

/// How many times a reader fetches a piece (header, index, tile levels) before giving up.
pub const DEFAULT_ATTEMPTS: u32 = 4;

/// The waits between a reader's attempts at a piece of a remote archive, seconds: 0.1 doubling
/// up to 2, with jitter (three retries wait 0.35 to 0.7 s in all).
pub const RETRY_BACKOFF: Backoff = Backoff {
    first: 0.1,
    max: 2.0,
    seed: 0x5d_b0ff,
};

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
        let remote = source.is_remote();
        let header = retry(attempts, remote, 0, |_| {
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
        let index = retry(attempts, remote, HEADER_LEN as u64, |_| {
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

    /// From now on, fetches a tile's levels or the base `attempts` times at most (at least 1).
    /// The engine's pager sets 1: it tries a failed fetch again itself, later and backing off,
    /// and retries in both places would multiply.
    pub fn with_fetch_attempts(mut self, attempts: u32) -> Self {
        self.attempts = attempts.max(1);
        self
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
        self.fetch(i, 0..self.header.levels(), &CancelToken::new())
    }

    /// The raw chunks of `levels` of tile `(x, y)`, fetched with one source read (one HTTP
    /// Range request), each chunk checked against its crc32 and decompressed on its own.
    pub fn read_levels(&self, x: usize, y: usize, levels: Range<usize>) -> Result<LevelBytes> {
        self.read_levels_cancellable(x, y, levels, &CancelToken::new())
    }

    /// [`ArchiveReader::read_levels`] that stops with [`Error::Cancelled`] once `cancel` is
    /// raised, where the source can stop a read under way
    /// ([`TileSource::read_range_cancellable`]); a cancelled read is not tried again.
    pub fn read_levels_cancellable(
        &self,
        x: usize,
        y: usize,
        levels: Range<usize>,
        cancel: &CancelToken,
    ) -> Result<LevelBytes> {
        let i = self.tile_number(x, y)?;
        let all = self.header.levels();
        if levels.start > levels.end || levels.end > all {
            return Err(Error::invalid(
                self.name(),
                format!("levels {levels:?} of tile ({x}, {y}) are outside 0..{all}"),
            ));
        }
        let stored = self.fetch(i, levels.clone(), cancel)?;
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
        let stored = retry(self.attempts, self.source.is_remote(), offset, |_| {
            let bytes = self.read_whole("base", offset, length, &CancelToken::new())?;
            let mut at = 0usize;
            for (i, entry) in self.index.iter().enumerate() {
                for g in 0..levels {
                    let len = entry.range(g..g + 1).1 as usize;
                    let actual = crc32fast::hash(&bytes[at..at + len]);
                    let expected = entry.levels[g].crc32;
                    if actual != expected {
                        self.source.checksum_failed()?;
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

    /// Bytes `offset .. offset + length`, all of them, unless `cancel` stops the read: a short
    /// answer is an error naming `what` was read.
    fn read_whole(
        &self,
        what: &str,
        offset: u64,
        length: u64,
        cancel: &CancelToken,
    ) -> Result<Vec<u8>> {
        let bytes = self.source.read_range_cancellable(offset, length, cancel)?;
        if bytes.len() as u64 != length {
            return Err(Error::invalid(
                self.source.name(),
                format!(
                    "{what}: read {} bytes at offset {offset}, {length} expected",
                    bytes.len()
                ),
            ));
        }
        Ok(bytes)
    }

    /// The stored bytes of `levels` of tile `i` in one source read per attempt, returned once
    /// every chunk matches its crc32.
    fn fetch(&self, i: usize, levels: Range<usize>, cancel: &CancelToken) -> Result<Vec<u8>> {
        let name = self.source.name();
        let entry = &self.index[i];
        let (offset, length) = entry.range(levels.clone());
        retry(self.attempts, self.source.is_remote(), offset, |attempt| {
            let bytes = self.read_whole(&format!("tile {i}"), offset, length, cancel)?;
            let failed = levels.clone().find_map(|g| {
                let (at, len) = entry.range(g..g + 1);
                let at = (at - offset) as usize;
                let actual = crc32fast::hash(&bytes[at..at + len as usize]);
                let expected = entry.levels[g].crc32;
                (actual != expected).then_some((g, expected, actual))
            });
            match failed {
                None => Ok(bytes),
                Some((level, expected, actual)) => {
                    self.source.checksum_failed()?;
                    Err(Error::Checksum {
                        name: name.to_string(),
                        tile: i,
                        level,
                        expected,
                        actual,
                        attempts: attempt,
                    })
                }
            }
        })
    }
}

/// Runs `f` (given the attempt's number, from 1) up to `attempts` times until it succeeds and
/// returns the last error, except that a timeout, a cancellation or a changed archive ends the
/// tries at once. Before each retry of a `remote` source it waits as [`RETRY_BACKOFF`] says
/// for the piece at `key` (its offset).
fn retry<T>(
    attempts: u32,
    remote: bool,
    key: u64,
    mut f: impl FnMut(u32) -> Result<T>,
) -> Result<T> {
    let mut attempt = 1;
    loop {
        match f(attempt) {
            Err(e)
                if attempt < attempts
                    && !matches!(
                        e,
                        Error::TimedOut { .. }
                            | Error::Cancelled { .. }
                            | Error::ArchiveChanged { .. }
                    ) =>
            {
                if remote {
                    std::thread::sleep(Duration::from_secs_f64(RETRY_BACKOFF.wait(key, attempt)));
                }
                attempt += 1;
            }
            result => return result,
        }
    }
}

#[cfg(test)]
mod tests {
    use std::time::Instant;

    use super::*;

    fn timed_out() -> Error {
        Error::TimedOut {
            url: "http://x/a.smdb".into(),
            request: "GET bytes 0-95".into(),
            seconds: 10.0,
            by_deadline: false,
        }
    }

    #[test]
    fn a_timeout_or_a_cancellation_is_not_asked_again_other_failures_are_up_to_the_attempts() {
        let mut calls = 0;
        let r: Result<()> = retry(4, true, 0, |_| {
            calls += 1;
            Err(timed_out())
        });
        assert!(matches!(r, Err(Error::TimedOut { .. })));
        assert_eq!(calls, 1);
        let mut calls = 0;
        let r: Result<()> = retry(4, true, 0, |_| {
            calls += 1;
            Err(crate::db::source::cancelled("a.smdb", 0, 96, 10))
        });
        assert!(matches!(r, Err(Error::Cancelled { .. })));
        assert_eq!(calls, 1, "a cancelled read is not asked again");
        let mut calls = 0;
        let r: Result<()> = retry(4, false, 0, |n| {
            calls += 1;
            Err(Error::invalid("a.smdb", format!("attempt {n}")))
        });
        assert_eq!(calls, 4);
        assert!(r.unwrap_err().to_string().contains("attempt 4"));
    }

    #[test]
    fn retries_of_a_remote_source_back_off() {
        let started = Instant::now();
        let mut calls = 0;
        let r = retry(3, true, 7, |n| {
            calls += 1;
            if n < 3 {
                Err(Error::invalid("a.smdb", "dropped"))
            } else {
                Ok(n)
            }
        });
        assert_eq!((r.unwrap(), calls), (3, 3));
        let least = RETRY_BACKOFF.wait(7, 1) + RETRY_BACKOFF.wait(7, 2);
        assert!(least >= 0.15);
        assert!(started.elapsed().as_secs_f64() >= least);
    }
}
