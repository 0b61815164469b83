//! Writing an archive in one pass over the tiles.

use std::fs::File;
use std::io::{BufWriter, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use super::partial::partial_path;
use super::{Header, IndexEntry, LevelEntry, index_to_bytes};
use crate::db::dem::FillStats;
use crate::error::{Error, Result};

/// Writes an archive: header and index placeholders first, then tiles in any order (each its
/// progressive chunks, coarse first, contiguous), then the base (the first chunks of every
/// tile, kept until then) and the real index and header. The file appears under its final name
/// only when [`finish`] succeeds.
///
/// [`finish`]: ArchiveWriter::finish
pub struct ArchiveWriter {
    path: PathBuf,
    partial: PathBuf,
    /// `None` once finished; a writer dropped before that removes its partial file.
    file: Option<BufWriter<File>>,
    header: Header,
    entries: Vec<Option<IndexEntry>>,
    /// Each tile's first `header.base_levels` stored chunks, for the base.
    base: Vec<Vec<u8>>,
    position: u64,
}

impl ArchiveWriter {
    /// Creates a temporary file beside `path` for an archive described by `header` (its height
    /// range is filled in by [`ArchiveWriter::finish`]). The temporary name is unique to this
    /// writer (`.NAME.PID-N.partial`, created exclusively), so builds to the same path at once
    /// never write into each other's file; the last to finish wins, whole.
    pub fn create(path: &Path, header: Header) -> Result<Self> {
        static WRITERS: AtomicU64 = AtomicU64::new(0);
        let shown = path.display().to_string();
        if path.is_dir() {
            return Err(Error::invalid(
                &shown,
                "is a directory, not an archive file",
            ));
        }
        let partial = partial_path(
            path,
            std::process::id(),
            WRITERS.fetch_add(1, Ordering::Relaxed),
        )
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
        Ok(ArchiveWriter {
            path: path.to_path_buf(),
            partial,
            file: Some(file),
            entries: vec![None; header.tile_count()],
            base: vec![Vec::new(); header.tile_count()],
            header,
            position: start,
        })
    }

    /// Appends the stored (compressed) chunks of tile `index`, one per progressive level,
    /// coarse first.
    pub fn write_tile(&mut self, index: usize, chunks: &[Vec<u8>]) -> Result<()> {
        let name = self.partial.display().to_string();
        if chunks.len() != self.header.levels() {
            return Err(Error::invalid(
                &name,
                format!(
                    "tile {index} has {} chunks, the archive {} levels",
                    chunks.len(),
                    self.header.levels()
                ),
            ));
        }
        let file = self.file.as_mut().expect("writer not finished");
        let mut end = 0u64;
        let mut levels = Vec::with_capacity(chunks.len());
        for chunk in chunks {
            file.write_all(chunk).map_err(|e| Error::io(&name, e))?;
            end += chunk.len() as u64;
            levels.push(LevelEntry {
                end: u32::try_from(end).map_err(|_| {
                    Error::invalid(&name, format!("tile {index} is over 4 GiB stored"))
                })?,
                crc32: crc32fast::hash(chunk),
            });
        }
        self.base[index] = chunks[..self.header.base_levels as usize].concat();
        self.entries[index] = Some(IndexEntry {
            offset: self.position,
            levels,
        });
        self.position += end;
        Ok(())
    }

    /// Writes the base, the index and the header with the height range and the nodata the build
    /// filled, and renames the file into place. Returns the archive's length in bytes.
    pub fn finish(mut self, min_height: f32, max_height: f32, nodata: FillStats) -> Result<u64> {
        let name = self.partial.display().to_string();
        let entries: Vec<IndexEntry> = self
            .entries
            .iter_mut()
            .enumerate()
            .map(|(i, e)| {
                e.take()
                    .ok_or_else(|| Error::invalid(&name, format!("tile {i} was never written")))
            })
            .collect::<Result<_>>()?;
        self.header.min_height = min_height;
        self.header.max_height = max_height;
        self.header.nodata_filled = nodata.filled;
        self.header.nodata_flattened = nodata.flattened;
        self.header.validate(&name)?;
        let io = |e| Error::io(&name, e);
        // From here the file is ours to remove on every failure (`Drop` no longer sees it),
        // after the file is closed: the guard is dropped after it.
        let discard = Discard(&self.partial);
        let mut file = self.file.take().expect("writer not finished");
        for base in &self.base {
            file.write_all(base).map_err(io)?;
            self.position += base.len() as u64;
        }
        file.seek(SeekFrom::Start(0)).map_err(io)?;
        file.write_all(&self.header.to_bytes()).map_err(io)?;
        file.write_all(&index_to_bytes(&entries)).map_err(io)?;
        let file = file.into_inner().map_err(|e| io(e.into_error()))?;
        file.sync_all().map_err(io)?;
        drop(file);
        std::fs::rename(&self.partial, &self.path)
            .map_err(|e| Error::io(self.path.display().to_string(), e))?;
        std::mem::forget(discard);
        Ok(self.position)
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
