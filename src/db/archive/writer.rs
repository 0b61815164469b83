//! Writing an archive in one pass over the tiles of every pyramid level.

use std::collections::BTreeMap;
use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, PoisonError};

use super::index::{Directory, encode_page, encode_table, page_grid, page_tiles};
use super::partial::partial_path;
use super::{Header, IndexEntry, LevelEntry, PAGE_SIDE, PageRef, TOP_BYTES, TOP_MAX_TILES};
use crate::db::dem::FillStats;
use crate::db::grid::{Grid, Pyramid, TileId};
use crate::error::{Error, Result};

/// One tile's stored chunks, `None` for an absent tile.
type Chunks = Option<Vec<Vec<u8>>>;

/// Writes an archive: header and directory placeholders first, then each level's tiles in
/// row-major order (each its progressive chunks, coarse first, contiguous; levels interleaved
/// as the build finishes them) and each block's index page as soon as its tiles are written;
/// the coarsest levels, which the top may hold, are kept until [`finish`] chooses the top and
/// writes it contiguously, then the page tables, the directory and the header. The file
/// appears under its final name only when [`finish`] succeeds.
///
/// Memory: the entries of one row of pages per level, each level's page table (16 bytes per
/// [`PAGE_SIDE`]² tiles), and the coarsest levels' tiles (at most [`TOP_MAX_TILES`]).
///
/// [`finish`]: ArchiveWriter::finish
pub struct ArchiveWriter {
    path: PathBuf,
    partial: PathBuf,
    /// `None` once finished; a writer dropped before that removes its partial file.
    file: Option<BufWriter<File>>,
    header: Header,
    pyramid: Pyramid,
    levels: Vec<LevelPages>,
    /// Levels from this one up are kept in memory for the top.
    held_from: u8,
    held: BTreeMap<TileId, Chunks>,
    position: u64,
}

/// One level's index as it is written.
struct LevelPages {
    grid: Grid,
    /// The next tile expected, counted row-major.
    next: u64,
    /// The entries of the row of pages being filled, per tile of those rows.
    row: BTreeMap<TileId, IndexEntry>,
    /// The page table so far, row-major.
    refs: Vec<PageRef>,
}

impl ArchiveWriter {
    /// Creates a temporary file beside `path` for an archive described by `header` (its height
    /// range, absent tiles, top and length are counted and filled in by
    /// [`ArchiveWriter::finish`]). The
    /// temporary name is unique to this writer (`.NAME.PID-N.partial`, created exclusively), so
    /// builds to the same path at once never write into each other's file; the last to finish
    /// wins, whole.
    pub fn create(path: &Path, header: Header) -> Result<Self> {
        // A lock taken once per archive, not an `AtomicU64`, which ARMv5TE lacks.
        static WRITERS: Mutex<u64> = Mutex::new(0);
        // What the writer counts and places itself.
        let header = Header {
            absent_tiles: 0,
            top_offset: 0,
            top_len: 0,
            archive_len: 0,
            ..header
        };
        let shown = path.display().to_string();
        if path.is_dir() {
            return Err(Error::invalid(
                &shown,
                "is a directory, not an archive file",
            ));
        }
        let n = {
            let mut writers = WRITERS.lock().unwrap_or_else(PoisonError::into_inner);
            *writers += 1;
            *writers - 1
        };
        let partial = partial_path(path, std::process::id(), n)
            .ok_or_else(|| Error::invalid(&shown, "names no file"))?;
        let name = partial.display().to_string();
        let file = File::options()
            .write(true)
            .create_new(true)
            .open(&partial)
            .map_err(|e| Error::io(&name, e))?;
        let mut file = BufWriter::with_capacity(1 << 20, file);
        let start = header.payload_start();
        file.write_all(&vec![0; start as usize])
            .map_err(|e| Error::io(&name, e))?;
        let pyramid = Pyramid::new(header.tiles_x, header.tiles_y)?;
        let levels = (0..pyramid.levels())
            .map(|k| LevelPages {
                grid: pyramid.grid(k as u8),
                next: 0,
                row: BTreeMap::new(),
                refs: Vec::new(),
            })
            .collect();
        // The coarsest levels that the top may hold, all of them together at most
        // TOP_MAX_TILES tiles.
        let mut held_from = pyramid.levels() as u8 - 1;
        let mut count = 1;
        while held_from > 0 {
            count += pyramid.grid(held_from - 1).tile_count();
            if count > TOP_MAX_TILES as u64 {
                break;
            }
            held_from -= 1;
        }
        Ok(ArchiveWriter {
            path: path.to_path_buf(),
            partial,
            file: Some(file),
            header,
            pyramid,
            levels,
            held_from,
            held: BTreeMap::new(),
            position: start,
        })
    }

    /// Appends the stored (compressed) chunks of tile `id`, one per progressive level, coarse
    /// first. Each level's tiles come in row-major order.
    pub fn write_tile(&mut self, id: TileId, chunks: Vec<Vec<u8>>) -> Result<()> {
        if chunks.len() != self.header.levels() {
            return Err(Error::invalid(
                self.name(),
                format!(
                    "{id} has {} chunks, the archive {} levels",
                    chunks.len(),
                    self.header.levels()
                ),
            ));
        }
        self.put(id, Some(chunks))
    }

    /// Records tile `id` as absent: every sample of it is nodata, nothing is stored.
    pub fn write_absent(&mut self, id: TileId) -> Result<()> {
        self.put(id, None)
    }

    fn name(&self) -> String {
        self.partial.display().to_string()
    }

    /// Takes tile `id` in its level's order: kept for the top, or written with its entry.
    fn put(&mut self, id: TileId, chunks: Chunks) -> Result<()> {
        let name = self.name();
        let level = self
            .levels
            .get_mut(usize::from(id.level))
            .filter(|l| l.grid.contains(id))
            .ok_or_else(|| Error::invalid(&name, format!("{id} is not a tile of the pyramid")))?;
        let at = u64::from(id.y) * u64::from(level.grid.tiles_x()) + u64::from(id.x);
        if at != level.next {
            return Err(Error::invalid(
                &name,
                format!("{id} written out of row-major order"),
            ));
        }
        level.next += 1;
        if id.level >= self.held_from {
            self.held.insert(id, chunks);
            return Ok(());
        }
        let entry = self.append(id, chunks.as_deref())?;
        self.levels[usize::from(id.level)].row.insert(id, entry);
        let grid = self.levels[usize::from(id.level)].grid;
        let last_of_row = id.x + 1 == grid.tiles_x()
            && ((id.y + 1).is_multiple_of(PAGE_SIDE) || id.y + 1 == grid.tiles_y());
        if last_of_row {
            self.flush_pages(id.level)?;
        }
        Ok(())
    }

    /// Writes `chunks` of tile `id` at the end of the file; returns its entry (absent for
    /// `None`).
    fn append(&mut self, id: TileId, chunks: Option<&[Vec<u8>]>) -> Result<IndexEntry> {
        let Some(chunks) = chunks else {
            if id.level == 0 {
                self.header.absent_tiles += 1;
            }
            return Ok(IndexEntry::absent(self.header.levels()));
        };
        let name = self.name();
        let file = self.file.as_mut().expect("writer not finished");
        let mut end = 0u64;
        let mut levels = Vec::with_capacity(chunks.len());
        for chunk in chunks {
            file.write_all(chunk).map_err(|e| Error::io(&name, e))?;
            end += chunk.len() as u64;
            levels.push(LevelEntry {
                end: u32::try_from(end)
                    .map_err(|_| Error::invalid(&name, format!("{id} is over 4 GiB stored")))?,
                crc32: crc32fast::hash(chunk),
            });
        }
        let entry = IndexEntry {
            offset: self.position,
            levels,
        };
        self.position += end;
        Ok(entry)
    }

    /// Writes the pages of the row of pages of `level` just completed, and their references.
    fn flush_pages(&mut self, level: u8) -> Result<()> {
        let pages = &mut self.levels[usize::from(level)];
        let grid = pages.grid;
        let row = std::mem::take(&mut pages.row);
        let (pages_x, _) = page_grid(grid);
        let first = pages.refs.len() as u64;
        let mut refs = Vec::with_capacity(pages_x as usize);
        for page in first..first + pages_x {
            let entries: Vec<IndexEntry> = page_tiles(grid, page)
                .into_iter()
                .map(|id| {
                    row.get(&id)
                        .cloned()
                        .expect("a completed page row holds its tiles")
                })
                .collect();
            refs.push(self.write_page(&entries)?);
        }
        self.levels[usize::from(level)].refs.extend(refs);
        Ok(())
    }

    /// Writes one page (nothing when all its tiles are absent); returns its reference.
    fn write_page(&mut self, entries: &[IndexEntry]) -> Result<PageRef> {
        if entries.iter().all(IndexEntry::is_absent) {
            return Ok(PageRef::default());
        }
        let bytes = encode_page(entries);
        let name = self.name();
        let file = self.file.as_mut().expect("writer not finished");
        file.write_all(&bytes).map_err(|e| Error::io(&name, e))?;
        let page = PageRef {
            offset: self.position,
            len: bytes.len() as u32,
            crc32: crc32fast::hash(&bytes),
        };
        self.position += bytes.len() as u64;
        Ok(page)
    }

    /// Chooses the top — the root and every level below it while their stored bytes fit
    /// [`TOP_BYTES`] — writes the kept levels below it, then the top contiguously, the page
    /// tables, the directory and the header with the height range and the nodata the build
    /// filled, and renames the file into place. Returns the header as written (its
    /// [`Header::archive_len`] is the file's length).
    pub fn finish(mut self, min_height: f32, max_height: f32, nodata: FillStats) -> Result<Header> {
        let name = self.name();
        if let Some(l) = self.levels.iter().find(|l| l.next != l.grid.tile_count()) {
            return Err(Error::invalid(
                &name,
                format!(
                    "level {} has {} of its {} tiles",
                    l.grid.level(),
                    l.next,
                    l.grid.tile_count()
                ),
            ));
        }
        let root = self.pyramid.root().level;
        let stored = |held: &BTreeMap<TileId, Chunks>, k: u8| -> u64 {
            held.iter()
                .filter(|(id, _)| id.level == k)
                .flat_map(|(_, c)| c.iter().flatten())
                .map(|c| c.len() as u64)
                .sum()
        };
        let mut top_level = root;
        let mut top_bytes = stored(&self.held, root);
        while top_level > self.held_from {
            let more = stored(&self.held, top_level - 1);
            if top_bytes + more > TOP_BYTES {
                break;
            }
            top_bytes += more;
            top_level -= 1;
        }
        let held = std::mem::take(&mut self.held);
        let mut entries: BTreeMap<TileId, IndexEntry> = BTreeMap::new();
        for (&id, chunks) in held.iter().filter(|(id, _)| id.level < top_level) {
            entries.insert(id, self.append(id, chunks.as_deref())?);
        }
        self.header.top_level = u32::from(top_level);
        self.header.top_offset = self.position;
        let top_tiles = Directory::top_tiles(&self.header);
        for &id in &top_tiles {
            let entry = self.append(id, held[&id].as_deref())?;
            entries.insert(id, entry);
        }
        self.header.top_len = self.position - self.header.top_offset;
        if self.header.top_len == 0 {
            self.header.top_offset = 0;
        }
        for k in self.held_from..=root {
            let grid = self.pyramid.grid(k);
            let (pages_x, pages_y) = page_grid(grid);
            for page in 0..pages_x * pages_y {
                let page_entries: Vec<IndexEntry> = page_tiles(grid, page)
                    .into_iter()
                    .map(|id| entries[&id].clone())
                    .collect();
                let r = self.write_page(&page_entries)?;
                self.levels[usize::from(k)].refs.push(r);
            }
        }
        let mut tables = Vec::with_capacity(self.levels.len());
        for k in 0..self.levels.len() {
            let bytes = encode_table(&self.levels[k].refs);
            tables.push(self.position);
            let file = self.file.as_mut().expect("writer not finished");
            file.write_all(&bytes).map_err(|e| Error::io(&name, e))?;
            self.position += bytes.len() as u64;
        }
        let directory = Directory {
            tables,
            top: top_tiles
                .iter()
                .map(|id| (*id, entries[id].clone()))
                .collect(),
        };
        self.header.min_height = min_height;
        self.header.max_height = max_height;
        self.header.nodata_filled = nodata.filled;
        self.header.nodata_flattened = nodata.flattened;
        self.header.archive_len = self.position;
        self.header.validate(&name)?;
        let directory = directory.to_bytes();
        debug_assert!(
            self.header.header_len() as u64 + directory.len() as u64 <= self.header.payload_start()
        );
        let io = |e| Error::io(&name, e);
        // From here the file is ours to remove on every failure (`Drop` no longer sees it),
        // after the file is closed: the guard is dropped after it.
        let discard = Discard(&self.partial);
        let mut file = self.file.take().expect("writer not finished");
        file.seek(SeekFrom::Start(0)).map_err(io)?;
        file.write_all(&self.header.to_bytes()).map_err(io)?;
        file.write_all(&directory).map_err(io)?;
        let file = file.into_inner().map_err(|e| io(e.into_error()))?;
        file.sync_all().map_err(io)?;
        drop(file);
        std::fs::rename(&self.partial, &self.path)
            .map_err(|e| Error::io(self.path.display().to_string(), e))?;
        std::mem::forget(discard);
        Ok(self.header.clone())
    }
}

/// Removes a partial file when dropped, unless forgotten: the failures of
/// [`ArchiveWriter::finish`].
struct Discard<'a>(&'a Path);

impl Drop for Discard<'_> {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(self.0);
    }
}

impl Drop for ArchiveWriter {
    fn drop(&mut self) {
        if self.file.take().is_some() {
            // An unfinished archive is useless; do not leave it behind.
            let _ = std::fs::remove_file(&self.partial);
        }
    }
}
