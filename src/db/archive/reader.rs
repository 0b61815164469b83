//! Reading an archive through any [`TileSource`], by region, with checksums and retries; bytes
//! that fail their checksum are reported to the source, which may find that the archive changed.

use std::ops::Range;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use super::index::{
    Directory, level_grid, page_count, page_of, parse_page, parse_table_chunk, table_chunk,
};
use super::index_cache::{Held, IndexCache, Piece};
use super::{
    HEADER_LEN, Header, IndexEntry, PageRef, TABLE_CHUNK_ENTRIES, check_levels, decompress,
};
use crate::db::backoff::Backoff;
use crate::db::grid::{Pyramid, TileId, TileMap};
use crate::db::source::{CancelToken, TileSource};
use crate::db::tile::Tile;
use crate::error::{Error, Result};

/// Reads an archive through a [`TileSource`]: the header and the directory when opened, then
/// index pages and ranges of tile levels on demand, each in one source read, every piece
/// checked against its crc32 and fetched again (up to `attempts` times) when it fails.
///
/// The index pages read are cached up to a byte limit ([`ArchiveReader::set_index_cache_limit`]),
/// so a reader's memory depends on what it was asked for, not on the archive's size.
///
/// A remote source's retries wait as [`RETRY_BACKOFF`] says; a request that timed out is not
/// asked again at once (the server already had its whole timeout): the error goes back to the
/// caller, and the pager tries the tile again later.
pub struct ArchiveReader<S> {
    source: S,
    header: Header,
    pyramid: Pyramid,
    directory: Directory,
    /// The top's tiles: their place in the directory's list.
    top: TileMap<usize>,
    cache: Mutex<IndexCache>,
    /// Attempts at a tile's levels, an index page or the top.
    attempts: u32,
    /// The source's size in bytes.
    file_len: u64,
}

/// How many times a reader fetches a piece (header, directory, index page, tile levels) before
/// giving up.
pub const DEFAULT_ATTEMPTS: u32 = 4;

/// The index bytes a reader caches unless told otherwise: a few hundred pages.
pub const DEFAULT_INDEX_CACHE: usize = 1 << 20;

/// The waits between a reader's attempts at a piece of a remote archive, seconds: 0.1 doubling
/// up to 2, with jitter (three retries wait 0.35 to 0.7 s in all).
pub const RETRY_BACKOFF: Backoff = Backoff {
    first: 0.1,
    max: 2.0,
    seed: 0x5d_b0ff,
};

/// The top's tiles, each decoded or `None` when absent, in the directory's order.
pub type TopTiles = Vec<(TileId, Option<Tile>)>;

/// The decompressed chunks of a range of one tile's progressive levels.
#[derive(Clone, Debug, PartialEq)]
pub struct LevelBytes {
    /// The raw chunks, coarse first, one per level of the range; none for an absent tile.
    pub chunks: Vec<Vec<u8>>,
    /// Stored bytes read from the source for them: the chunks, and the index pages read to
    /// find them.
    pub stored_bytes: u64,
    /// Whether the tile is absent (every sample nodata): nothing is stored for it.
    pub absent: bool,
}

impl<S: TileSource> ArchiveReader<S> {
    /// Fetches and validates the header and the directory: a few kilobytes, whatever the
    /// archive's size.
    pub fn open(source: S) -> Result<Self> {
        Self::open_with_attempts(source, DEFAULT_ATTEMPTS)
    }

    /// [`ArchiveReader::open`] with a bound on fetch attempts per piece (at least 1).
    pub fn open_with_attempts(source: S, attempts: u32) -> Result<Self> {
        let attempts = attempts.max(1);
        let name = source.name().to_string();
        let file_len = source.size()?;
        let remote = source.is_remote();
        let (header, georef_len) = retry(attempts, remote, 0, |_| {
            let bytes = source.read_range(0, file_len.min(HEADER_LEN as u64))?;
            Header::parse_fixed(&bytes, &name)
        })?;
        if file_len < header.archive_len {
            return Err(Error::invalid(
                &name,
                format!(
                    "truncated archive: the file is {file_len} bytes, the archive {}",
                    header.archive_len
                ),
            ));
        }
        // The georeferencing (when there is one) and the directory, in one read.
        let (header, directory) = retry(attempts, remote, HEADER_LEN as u64, |_| {
            let len = georef_len + header.directory_len();
            let bytes = source.read_range(HEADER_LEN as u64, len as u64)?;
            let (georef, directory) = bytes.split_at(georef_len);
            let header = header.clone().with_georef(georef, &name)?;
            let directory = Directory::parse(directory, &header, &name)?;
            Ok((header, directory))
        })?;
        let top = directory
            .top
            .iter()
            .enumerate()
            .map(|(k, (id, _))| (*id, k))
            .collect();
        Ok(ArchiveReader {
            source,
            pyramid: header.pyramid(),
            header,
            directory,
            top,
            cache: Mutex::new(IndexCache::new(DEFAULT_INDEX_CACHE)),
            attempts,
            file_len,
        })
    }

    /// From now on, fetches a tile's levels, an index page or the top `attempts` times at
    /// most (at least 1). The engine's pager sets 1: it tries a failed fetch again itself,
    /// later and backing off, and retries in both places would multiply.
    pub fn with_fetch_attempts(mut self, attempts: u32) -> Self {
        self.attempts = attempts.max(1);
        self
    }

    /// The header.
    pub fn header(&self) -> &Header {
        &self.header
    }

    /// The pyramid of tiles.
    pub fn pyramid(&self) -> &Pyramid {
        &self.pyramid
    }

    /// The directory: the page tables' places and the top's entries.
    pub fn directory(&self) -> &Directory {
        &self.directory
    }

    /// Bytes an open reads: the header and the directory.
    pub fn opening_bytes(&self) -> u64 {
        (self.header.header_len() + self.header.directory_len()) as u64
    }

    /// The source's size in bytes.
    pub fn file_len(&self) -> u64 {
        self.file_len
    }

    /// The source's name (file path or URL).
    pub fn name(&self) -> &str {
        self.source.name()
    }

    /// Caches at most `bytes` of index pages from now on (the least recently used go first).
    pub fn set_index_cache_limit(&self, bytes: usize) {
        self.cache().set_limit(bytes);
    }

    /// The most bytes of index pages kept.
    pub fn index_cache_limit(&self) -> usize {
        self.cache().limit()
    }

    /// Bytes of index pages and page tables held now.
    pub fn index_cache_bytes(&self) -> usize {
        self.cache().bytes()
    }

    /// Stored bytes of index pages and page tables read so far.
    pub fn index_bytes_read(&self) -> u64 {
        self.cache().read()
    }

    fn cache(&self) -> std::sync::MutexGuard<'_, IndexCache> {
        // A panic while the lock was held leaves a cache that is still consistent.
        self.cache.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The index entry of tile `id` and the stored bytes read to find it (0 when its page was
    /// cached or it is in the top): from the directory for the top's tiles, else from its
    /// level's index page, found through the page table.
    pub fn entry(&self, id: TileId, cancel: &CancelToken) -> Result<(IndexEntry, u64)> {
        let name = self.name();
        let grid = level_grid(&self.pyramid, id.level, name)?;
        if !grid.contains(id) {
            return Err(Error::invalid(
                name,
                format!(
                    "{id} is outside level {}'s {} x {} grid",
                    id.level,
                    grid.tiles_x(),
                    grid.tiles_y()
                ),
            ));
        }
        if let Some(&k) = self.top.get(&id) {
            return Ok((self.directory.top[k].1.clone(), 0));
        }
        let slot = page_of(grid, id);
        let (page, mut read) = self.page_ref(id.level, slot.page, cancel)?;
        if page.is_absent() {
            return Ok((IndexEntry::absent(self.header.levels()), read));
        }
        let piece = Piece::Page {
            level: id.level,
            page: slot.page,
        };
        let cached = self.cache().get(piece);
        let entries = match cached {
            Some(Held::Page(entries)) => entries,
            _ => {
                let label = format!("{name}: index page {} of level {}", slot.page, id.level);
                let entries: Arc<[IndexEntry]> =
                    retry(self.attempts, self.source.is_remote(), page.offset, |_| {
                        let bytes =
                            self.read_whole(&label, page.offset, page.len.into(), cancel)?;
                        if crc32fast::hash(&bytes) != page.crc32 {
                            self.source.checksum_failed()?;
                            return Err(Error::invalid(
                                &label,
                                "checksum mismatch (corrupt index page)",
                            ));
                        }
                        parse_page(&bytes, &self.header, grid, slot.page, &label)
                    })?
                    .into();
                read += u64::from(page.len);
                self.cache()
                    .put(piece, Held::Page(Arc::clone(&entries)), page.len.into());
                entries
            }
        };
        Ok((entries[slot.slot].clone(), read))
    }

    /// Where page `page` of level `level` is, from the cached chunk of its page table or a
    /// fetch of it; and the bytes read.
    fn page_ref(&self, level: u8, page: u64, cancel: &CancelToken) -> Result<(PageRef, u64)> {
        let per = TABLE_CHUNK_ENTRIES as u64;
        let chunk = page / per;
        let piece = Piece::Table { level, chunk };
        let cached = self.cache().get(piece);
        if let Some(Held::Table(refs)) = cached {
            return Ok((refs[(page % per) as usize], 0));
        }
        let grid = self.pyramid.grid(level);
        let pages = page_count(grid);
        let (offset, len, entries) =
            table_chunk(self.directory.tables[usize::from(level)], pages, chunk);
        let label = format!("{}: page table chunk {chunk} of level {level}", self.name());
        let refs: Arc<[PageRef]> = retry(self.attempts, self.source.is_remote(), offset, |_| {
            let bytes = self.read_whole(&label, offset, len, cancel)?;
            let parsed =
                parse_table_chunk(&bytes, &self.header, grid, chunk * per, entries, &label);
            if parsed.is_err() {
                // Its checksum or its references: either may mean the archive changed.
                self.source.checksum_failed()?;
            }
            parsed
        })?
        .into();
        self.cache().put(piece, Held::Table(Arc::clone(&refs)), len);
        Ok((refs[(page % per) as usize], len))
    }

    /// The raw chunks of `levels` of tile `id`, fetched with one source read (one HTTP Range
    /// request) after its index page, each chunk checked against its crc32 and decompressed on
    /// its own.
    pub fn read_levels(&self, id: TileId, levels: Range<usize>) -> Result<LevelBytes> {
        self.read_levels_cancellable(id, levels, &CancelToken::new())
    }

    /// [`ArchiveReader::read_levels`] that stops with [`Error::Cancelled`] once `cancel` is
    /// raised, where the source can stop a read under way
    /// ([`TileSource::read_range_cancellable`]); a cancelled read is not tried again.
    pub fn read_levels_cancellable(
        &self,
        id: TileId,
        levels: Range<usize>,
        cancel: &CancelToken,
    ) -> Result<LevelBytes> {
        check_levels(&levels, self.header.levels(), &id.to_string(), self.name())?;
        let (entry, index_read) = self.entry(id, cancel)?;
        if entry.is_absent() {
            return Ok(LevelBytes {
                chunks: Vec::new(),
                stored_bytes: index_read,
                absent: true,
            });
        }
        let stored = self.fetch(id, &entry, levels.clone(), cancel)?;
        let base = entry.range(levels.start..levels.start).0;
        let chunks = levels
            .map(|g| {
                let (offset, len) = entry.range(g..g + 1);
                let at = (offset - base) as usize;
                let label = format!("{} {id} level {g}", self.name());
                decompress(
                    &stored[at..at + len as usize],
                    self.header.codec,
                    self.header.level_payload_size(g),
                    &label,
                )
            })
            .collect::<Result<_>>()?;
        Ok(LevelBytes {
            chunks,
            stored_bytes: stored.len() as u64 + index_read,
            absent: false,
        })
    }

    /// The coarser tile made of the first `levels` progressive levels of tile `id` (the whole
    /// tile for `header().levels()`), `None` for an absent tile, and the stored bytes read.
    pub fn tile_levels(&self, id: TileId, levels: usize) -> Result<(Option<Tile>, u64)> {
        if levels == 0 {
            return Err(Error::invalid(
                self.name(),
                format!("{id} asked for with no levels"),
            ));
        }
        let read = self.read_levels(id, 0..levels)?;
        if read.absent {
            return Ok((None, read.stored_bytes));
        }
        let label = format!("{} {id}", self.name());
        let chunks: Vec<&[u8]> = read.chunks.iter().map(Vec::as_slice).collect();
        Ok((Some(self.decode(&chunks, &label)?), read.stored_bytes))
    }

    /// Tile `id` whole, `None` when it is absent.
    pub fn tile(&self, id: TileId) -> Result<Option<Tile>> {
        Ok(self.tile_levels(id, self.header.levels())?.0)
    }

    /// The tile that `chunks` (raw, coarse first from level 0) make, in the archive's height
    /// quantum; `label` names it in errors.
    pub fn decode(&self, chunks: &[&[u8]], label: &str) -> Result<Tile> {
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

    /// The top: the root and the levels below it that the build put there, whole, fetched
    /// with one source read (one HTTP Range request), every chunk checked against its crc32 in
    /// the directory; `None` for an absent tile. And the stored bytes read.
    pub fn top(&self) -> Result<(TopTiles, u64)> {
        let (offset, length) = (self.header.top_offset, self.header.top_len);
        let name = self.name();
        let stored = retry(self.attempts, self.source.is_remote(), offset, |_| {
            let bytes = self.read_whole("the top", offset, length, &CancelToken::new())?;
            for (id, entry) in self.directory.top.iter().filter(|(_, e)| !e.is_absent()) {
                self.verify(*id, entry, 0..self.header.levels(), &bytes, offset, 1)?;
            }
            Ok(bytes)
        })?;
        let all = 0..self.header.levels();
        let tiles = self
            .directory
            .top
            .iter()
            .map(|(id, entry)| {
                if entry.is_absent() {
                    return Ok((*id, None));
                }
                let label = format!("{name} top {id}");
                let chunks = all
                    .clone()
                    .map(|g| {
                        let (at, len) = entry.range(g..g + 1);
                        let at = (at - offset) as usize;
                        decompress(
                            &stored[at..at + len as usize],
                            self.header.codec,
                            self.header.level_payload_size(g),
                            &label,
                        )
                    })
                    .collect::<Result<Vec<_>>>()?;
                let chunks: Vec<&[u8]> = chunks.iter().map(Vec::as_slice).collect();
                Ok((*id, Some(self.decode(&chunks, &label)?)))
            })
            .collect::<Result<Vec<_>>>()?;
        Ok((tiles, length))
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

    /// Checks the chunks of `levels` of tile `id` (at `entry`) in `bytes`, which start at file
    /// offset `start`, against their crc32s; a mismatch is reported to the source first, which
    /// may find that the archive changed.
    fn verify(
        &self,
        id: TileId,
        entry: &IndexEntry,
        levels: Range<usize>,
        bytes: &[u8],
        start: u64,
        attempts: u32,
    ) -> Result<()> {
        for g in levels {
            let (at, len) = entry.range(g..g + 1);
            let at = (at - start) as usize;
            let actual = crc32fast::hash(&bytes[at..at + len as usize]);
            let expected = entry.levels[g].crc32;
            if actual != expected {
                self.source.checksum_failed()?;
                return Err(Error::Checksum {
                    name: self.name().to_string(),
                    tile: id.to_string(),
                    level: g,
                    expected,
                    actual,
                    attempts,
                });
            }
        }
        Ok(())
    }

    /// The stored bytes of `levels` of tile `id` (at `entry`) in one source read per attempt,
    /// returned once every chunk matches its crc32.
    fn fetch(
        &self,
        id: TileId,
        entry: &IndexEntry,
        levels: Range<usize>,
        cancel: &CancelToken,
    ) -> Result<Vec<u8>> {
        let (offset, length) = entry.range(levels.clone());
        retry(self.attempts, self.source.is_remote(), offset, |attempt| {
            let bytes = self.read_whole(&id.to_string(), offset, length, cancel)?;
            self.verify(id, entry, levels.clone(), &bytes, offset, attempt)?;
            Ok(bytes)
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
