//! Where every tile's chunks are, read by region: index entries, grouped in pages of
//! [`PAGE_SIDE`]² tiles of one pyramid level, found through each level's page table; and the
//! directory, which gives the tables' places and the top's entries.
//!
//! A page of a block whose tiles are all absent is not stored (its table entry is all zero), and
//! an absent tile's entry is all zero, so an extent of nodata costs a few bytes of table.

use std::ops::Range;

use serde::Serialize;

use super::{Header, PAGE_SIDE, stored_bound};
use crate::db::grid::{Grid, Pyramid, TileId};
use crate::error::{Error, Result};

/// Page references per chunk of a page table; each chunk is followed by its crc32.
pub const TABLE_CHUNK_ENTRIES: usize = 256;
/// Bytes of one page reference: offset u64, length u32, crc32 u32.
const PAGE_REF_LEN: usize = 16;

/// Where one progressive chunk of a tile ends, and its checksum.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct LevelEntry {
    /// Stored bytes from the tile's offset through this chunk.
    pub end: u32,
    /// crc32 (IEEE) of this chunk's stored bytes.
    pub crc32: u32,
}

/// Where one tile's stored chunks are: chunk `g` is bytes `[end(g - 1), end(g))` after the
/// tile's offset, so the bytes of any range of levels are one contiguous range. An absent tile
/// (every sample nodata) has offset 0 and no bytes.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct IndexEntry {
    /// Offset of chunk 0 from the start of the file; 0 for an absent tile.
    pub offset: u64,
    /// One entry per progressive level, coarse first.
    pub levels: Vec<LevelEntry>,
}

impl IndexEntry {
    /// The entry of an absent tile with `levels` progressive levels.
    pub fn absent(levels: usize) -> IndexEntry {
        IndexEntry {
            offset: 0,
            levels: vec![LevelEntry::default(); levels],
        }
    }

    /// Whether the tile is absent: every sample of it was nodata, and nothing is stored.
    pub fn is_absent(&self) -> bool {
        self.offset == 0
    }

    /// Stored bytes of the first `levels` chunks.
    pub fn prefix_len(&self, levels: usize) -> u64 {
        self.start_of(levels)
    }

    /// Stored bytes of the whole tile.
    pub fn stored_len(&self) -> u64 {
        self.levels.last().map_or(0, |l| u64::from(l.end))
    }

    /// The byte range (file offset, length) of the chunks of `levels`. Panics unless `levels`
    /// lies within the tile's levels.
    pub fn range(&self, levels: Range<usize>) -> (u64, u64) {
        let start = self.start_of(levels.start);
        let end = self.start_of(levels.end);
        assert!(start <= end, "level range {levels:?} is reversed");
        (self.offset + start, end - start)
    }

    /// Stored bytes before chunk `level` (`level` may be one past the last).
    fn start_of(&self, level: usize) -> u64 {
        match level {
            0 => 0,
            g => u64::from(self.levels[g - 1].end),
        }
    }

    fn write(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&self.offset.to_le_bytes());
        for l in &self.levels {
            out.extend_from_slice(&l.end.to_le_bytes());
            out.extend_from_slice(&l.crc32.to_le_bytes());
        }
    }

    /// Parses and validates one entry of `header`'s archive (`bytes` is exactly one entry);
    /// `what` names it in errors.
    fn parse(bytes: &[u8], header: &Header, what: &dyn Fn() -> String) -> Result<IndexEntry> {
        let u32_at = |k: usize| u32::from_le_bytes(bytes[k..k + 4].try_into().expect("4"));
        let entry = IndexEntry {
            offset: u64::from_le_bytes(bytes[..8].try_into().expect("8")),
            levels: (0..header.levels())
                .map(|g| LevelEntry {
                    end: u32_at(8 + 8 * g),
                    crc32: u32_at(12 + 8 * g),
                })
                .collect(),
        };
        let outside = |problem: String| {
            Error::invalid(
                what(),
                format!(
                    "its entry (offset {}) points outside the payloads: {problem}",
                    entry.offset
                ),
            )
        };
        if entry.is_absent() {
            if entry.levels.iter().any(|l| *l != LevelEntry::default()) {
                return Err(outside("an absent tile with chunks".into()));
            }
            return Ok(entry);
        }
        if entry.offset < header.payload_start() {
            return Err(outside("it starts inside the header".into()));
        }
        let mut start = 0u64;
        for (g, level) in entry.levels.iter().enumerate() {
            let end = u64::from(level.end);
            let bound = stored_bound(header.codec, header.level_payload_size(g)) as u64;
            if end <= start || end - start > bound {
                return Err(outside(format!(
                    "level {g} ends at {end} after starting at {start}, more than the codec's \
                     {bound} bytes or nothing"
                )));
            }
            start = end;
        }
        match entry.offset.checked_add(entry.stored_len()) {
            Some(end) if end <= header.archive_len => Ok(entry),
            Some(end) => Err(outside(format!(
                "it ends at byte {end} of a {}-byte archive",
                header.archive_len
            ))),
            None => Err(outside("its end overflows".into())),
        }
    }
}

/// Where an index page is stored: all zero for a block whose tiles are all absent.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct PageRef {
    /// Offset of the page; 0 when nothing is stored.
    pub offset: u64,
    /// Bytes of the page: its tiles' entries.
    pub len: u32,
    /// crc32 of the page's bytes.
    pub crc32: u32,
}

impl PageRef {
    /// Whether the block's tiles are all absent and no page is stored.
    pub fn is_absent(&self) -> bool {
        self.offset == 0
    }
}

/// Which page holds a tile, and where in it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PageSlot {
    /// The page's number in its level's table (row-major over the level's blocks).
    pub page: u64,
    /// The tile's entry in the page.
    pub slot: usize,
    /// Entries in the page: the block's tiles on the grid.
    pub entries: usize,
}

/// Pages across and down level `grid`.
pub fn page_grid(grid: Grid) -> (u64, u64) {
    (
        u64::from(grid.tiles_x().div_ceil(PAGE_SIDE)),
        u64::from(grid.tiles_y().div_ceil(PAGE_SIDE)),
    )
}

/// Pages of level `grid`.
pub fn page_count(grid: Grid) -> u64 {
    let (x, y) = page_grid(grid);
    x * y
}

/// The block of page `(px, py)` of `grid`: its columns and rows.
fn block(grid: Grid, px: u32, py: u32) -> (Range<u32>, Range<u32>) {
    let (x0, y0) = (px * PAGE_SIDE, py * PAGE_SIDE);
    (
        x0..(x0 + PAGE_SIDE).min(grid.tiles_x()),
        y0..(y0 + PAGE_SIDE).min(grid.tiles_y()),
    )
}

/// The page of `grid` (the level of `id`) that holds `id`'s entry.
pub fn page_of(grid: Grid, id: TileId) -> PageSlot {
    let (px, py) = (id.x / PAGE_SIDE, id.y / PAGE_SIDE);
    let (xs, ys) = block(grid, px, py);
    let (pages_x, _) = page_grid(grid);
    PageSlot {
        page: u64::from(py) * pages_x + u64::from(px),
        slot: ((id.y - ys.start) * xs.len() as u32 + (id.x - xs.start)) as usize,
        entries: xs.len() * ys.len(),
    }
}

/// The tiles of page `page` of `grid`, in the order of its entries.
pub fn page_tiles(grid: Grid, page: u64) -> Vec<TileId> {
    let (pages_x, _) = page_grid(grid);
    let (px, py) = ((page % pages_x) as u32, (page / pages_x) as u32);
    let (xs, ys) = block(grid, px, py);
    ys.flat_map(|y| xs.clone().map(move |x| TileId::at(grid.level(), x, y)))
        .collect()
}

/// Bytes of a page table of `pages` pages: its chunks, each with its crc32.
pub fn table_len(pages: u64) -> u64 {
    let chunks = pages.div_ceil(TABLE_CHUNK_ENTRIES as u64);
    pages * PAGE_REF_LEN as u64 + 4 * chunks
}

/// The byte range (offset, length) of chunk `chunk` of the page table at `table` of a level
/// with `pages` pages, and the page references it holds.
pub fn table_chunk(table: u64, pages: u64, chunk: u64) -> (u64, u64, usize) {
    let per = TABLE_CHUNK_ENTRIES as u64;
    let entries = (pages - chunk * per).min(per);
    let offset = table + chunk * (per * PAGE_REF_LEN as u64 + 4);
    (offset, entries * PAGE_REF_LEN as u64 + 4, entries as usize)
}

/// A level's page table: the references in chunks, each followed by its crc32.
pub fn encode_table(refs: &[PageRef]) -> Vec<u8> {
    let mut out = Vec::with_capacity(table_len(refs.len() as u64) as usize);
    for chunk in refs.chunks(TABLE_CHUNK_ENTRIES) {
        let start = out.len();
        for r in chunk {
            out.extend_from_slice(&r.offset.to_le_bytes());
            out.extend_from_slice(&r.len.to_le_bytes());
            out.extend_from_slice(&r.crc32.to_le_bytes());
        }
        let crc = crc32fast::hash(&out[start..]);
        out.extend_from_slice(&crc.to_le_bytes());
    }
    out
}

/// Parses one chunk of level `grid`'s page table (`entries` references and a crc32), every
/// reference checked against `header`; `label` names the chunk in errors.
pub fn parse_table_chunk(
    bytes: &[u8],
    header: &Header,
    grid: Grid,
    first_page: u64,
    entries: usize,
    label: &str,
) -> Result<Vec<PageRef>> {
    let len = entries * PAGE_REF_LEN;
    if bytes.len() != len + 4 {
        return Err(Error::invalid(
            label,
            format!("{} bytes, {} expected", bytes.len(), len + 4),
        ));
    }
    let stored = u32::from_le_bytes(bytes[len..].try_into().expect("4"));
    if crc32fast::hash(&bytes[..len]) != stored {
        return Err(Error::invalid(
            label,
            "checksum mismatch (corrupt page table)",
        ));
    }
    bytes[..len]
        .chunks_exact(PAGE_REF_LEN)
        .enumerate()
        .map(|(k, b)| {
            let r = PageRef {
                offset: u64::from_le_bytes(b[..8].try_into().expect("8")),
                len: u32::from_le_bytes(b[8..12].try_into().expect("4")),
                crc32: u32::from_le_bytes(b[12..].try_into().expect("4")),
            };
            let page = first_page + k as u64;
            if r.is_absent() {
                return if r == PageRef::default() {
                    Ok(r)
                } else {
                    Err(Error::invalid(
                        label,
                        format!("page {page}: an absent page with a length or checksum"),
                    ))
                };
            }
            let tiles = page_tiles(grid, page).len();
            let expected = (tiles * header.index_entry_len()) as u64;
            let end = r.offset.checked_add(u64::from(r.len));
            if u64::from(r.len) != expected
                || r.offset < header.payload_start()
                || end.is_none_or(|e| e > header.archive_len)
            {
                return Err(Error::invalid(
                    label,
                    format!(
                        "page {page} of level {} ({} bytes at offset {}) is not {expected} \
                         bytes within the archive's {} bytes",
                        grid.level(),
                        r.len,
                        r.offset,
                        header.archive_len
                    ),
                ));
            }
            Ok(r)
        })
        .collect()
}

/// An index page: its tiles' entries in order.
pub fn encode_page(entries: &[IndexEntry]) -> Vec<u8> {
    let mut out = Vec::new();
    for e in entries {
        e.write(&mut out);
    }
    out
}

/// Parses page `page` of level `grid` (its checksum already checked), every entry validated
/// against `header` and no two present tiles sharing a byte; `label` names it in errors.
pub fn parse_page(
    bytes: &[u8],
    header: &Header,
    grid: Grid,
    page: u64,
    label: &str,
) -> Result<Vec<IndexEntry>> {
    let tiles = page_tiles(grid, page);
    let len = header.index_entry_len();
    if bytes.len() != tiles.len() * len {
        return Err(Error::invalid(
            label,
            format!("{} bytes, {} expected", bytes.len(), tiles.len() * len),
        ));
    }
    let entries = bytes
        .chunks_exact(len)
        .zip(&tiles)
        .map(|(b, id)| IndexEntry::parse(b, header, &|| format!("{label}, {id}")))
        .collect::<Result<Vec<_>>>()?;
    disjoint(entries.iter().zip(&tiles), label)?;
    Ok(entries)
}

/// Fails unless the present `entries` share no byte: overlapping entries would make a reader
/// decode the same bytes for many tiles.
fn disjoint<'a>(
    entries: impl Iterator<Item = (&'a IndexEntry, &'a TileId)>,
    label: &str,
) -> Result<()> {
    let mut spans: Vec<(u64, u64, TileId)> = entries
        .filter(|(e, _)| !e.is_absent())
        .map(|(e, &id)| (e.offset, e.offset + e.stored_len(), id))
        .collect();
    spans.sort_unstable();
    for pair in spans.windows(2) {
        let ((start_a, end_a, a), (start_b, end_b, b)) = (pair[0], pair[1]);
        if start_b < end_a {
            return Err(Error::invalid(
                label,
                format!(
                    "the entries of {a} and {b} overlap: bytes {start_a}..{end_a} and \
                     {start_b}..{end_b} (an index must give every tile its own bytes)"
                ),
            ));
        }
    }
    Ok(())
}

/// The directory after the header: where each level's page table lies, and the top's entries.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Directory {
    /// Per pyramid level, the offset of its page table.
    pub tables: Vec<u64>,
    /// The top's tiles, root first, then each level below it row-major, with their entries.
    pub top: Vec<(TileId, IndexEntry)>,
}

impl Directory {
    /// The top's tiles of `header`'s archive in the directory's order: the root, then each
    /// level below it down to the top's finest, row-major.
    pub fn top_tiles(header: &Header) -> Vec<TileId> {
        let pyramid = header.pyramid();
        (header.top_level as usize..pyramid.levels())
            .rev()
            .flat_map(|k| {
                let grid = pyramid.grid(k as u8);
                (0..grid.tiles_y())
                    .flat_map(move |y| (0..grid.tiles_x()).map(move |x| TileId::at(k as u8, x, y)))
            })
            .collect()
    }

    /// Serialises the directory with its crc32.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = Vec::new();
        for t in &self.tables {
            out.extend_from_slice(&t.to_le_bytes());
        }
        for (_, e) in &self.top {
            e.write(&mut out);
        }
        let crc = crc32fast::hash(&out);
        out.extend_from_slice(&crc.to_le_bytes());
        out
    }

    /// Parses and validates the directory of `header` (exactly [`Header::directory_len`]
    /// bytes): every page table within the archive, every top entry inside the top, the top's
    /// tiles stored one after the other; `name` labels errors.
    pub fn parse(bytes: &[u8], header: &Header, name: &str) -> Result<Directory> {
        let bad = |p: String| Error::invalid(name, p);
        if bytes.len() != header.directory_len() {
            return Err(bad(format!(
                "truncated directory: {} of {} bytes",
                bytes.len(),
                header.directory_len()
            )));
        }
        let body = &bytes[..bytes.len() - 4];
        let stored = u32::from_le_bytes(bytes[body.len()..].try_into().expect("4"));
        if crc32fast::hash(body) != stored {
            return Err(bad("directory checksum mismatch (corrupt directory)".into()));
        }
        let pyramid = header.pyramid();
        let levels = pyramid.levels();
        let tables: Vec<u64> = body[..8 * levels]
            .chunks_exact(8)
            .map(|b| u64::from_le_bytes(b.try_into().expect("8")))
            .collect();
        for (k, &t) in tables.iter().enumerate() {
            let len = table_len(page_count(pyramid.grid(k as u8)));
            if t < header.payload_start()
                || t.checked_add(len).is_none_or(|e| e > header.archive_len)
            {
                return Err(bad(format!(
                    "the page table of level {k} ({len} bytes at offset {t}) lies outside the \
                     archive's {} bytes",
                    header.archive_len
                )));
            }
        }
        let len = header.index_entry_len();
        let top = Directory::top_tiles(header)
            .into_iter()
            .zip(body[8 * levels..].chunks_exact(len))
            .map(|(id, b)| {
                let what = || format!("{name}: the top's {id}");
                Ok((id, IndexEntry::parse(b, header, &what)?))
            })
            .collect::<Result<Vec<_>>>()?;
        let mut at = header.top_offset;
        for (id, e) in top.iter().filter(|(_, e)| !e.is_absent()) {
            if e.offset != at {
                return Err(bad(format!(
                    "the top's {id} is stored at offset {}, not right after the tile before \
                     it at {at}",
                    e.offset
                )));
            }
            at += e.stored_len();
        }
        if at != header.top_offset + header.top_len {
            return Err(bad(format!(
                "the top's tiles end at {at}, its {} bytes at {}",
                header.top_len, header.top_offset
            )));
        }
        Ok(Directory { tables, top })
    }
}

/// The pyramid of `header` and its level `level`'s grid, or an error naming the level.
pub fn level_grid(pyramid: &Pyramid, level: u8, name: &str) -> Result<Grid> {
    if usize::from(level) >= pyramid.levels() {
        return Err(Error::invalid(
            name,
            format!(
                "level {level} does not exist: the pyramid has {}",
                pyramid.levels()
            ),
        ));
    }
    Ok(pyramid.grid(level))
}
