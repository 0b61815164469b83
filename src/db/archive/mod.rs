//! The `.smdb` archive: one file with a header, a small directory, the tile payloads of every
//! level of the pyramid, the index pages that locate them, and the top of the pyramid.
//!
//! All integers and floats are little-endian. The byte-level description, enough for another
//! implementation, is in `docs/archive-format.md`; in short:
//!
//! * header, [`HEADER_LEN`] bytes: magic, version, the level-0 grid (tiles across/down, tile
//!   size, texture size), payload codec, source dimensions, the top's place, spacing, vertical
//!   scale, origin, height range of the valid samples, the nodata the build filled, the absent
//!   tiles, the archive's length, crc32; then, for an archive built from a georeferenced
//!   DEM, the georeferencing ([`Georef`]: the CRS and where the samples lie in it), which the
//!   header's length counts;
//! * the directory: per pyramid level the offset of its page table, then the index entries of
//!   the top's tiles, then a crc32 ([`index::Directory`]);
//! * the payloads: each present tile's progressive chunks ([`crate::db::tile`]), coarse first,
//!   each compressed on its own as the header's codec says, so any one range decodes alone;
//! * index pages: the entries of a block of [`PAGE_SIDE`]² tiles of one level, found through
//!   the level's page table (chunks of entries, each with its crc32);
//! * the top: the payloads of the root and the levels below it that fit a small allowance,
//!   contiguous, so that a client holds a coarse copy of the whole terrain after one request.
//!
//! Opening an archive reads the header and the directory: a few kilobytes, whatever the model's
//! size. Everything else is read by region: a tile's entry comes with its index page (one table
//! chunk and one page, each cached), its levels with one more range request.

mod check;
mod georef_block;
mod index;
mod index_cache;
mod locate;
pub mod partial;
mod reader;
mod writer;

use std::ops::Range;

use serde::Serialize;

use crate::db::georef::Georef;
use crate::db::grid::Pyramid;
use crate::db::tile::{MAX_TEXTURE_SIZE, level_payload_size, progressive_levels};
use crate::db::tiling::is_valid_tile_size;
use crate::error::{Error, Result};
use crate::named::named_enum;

pub use check::CheckReport;
pub use index::{
    Directory, IndexEntry, LevelEntry, PageRef, PageSlot, TABLE_CHUNK_ENTRIES, page_count, page_of,
    page_tiles, parse_page, parse_table_chunk, table_chunk,
};
pub use locate::Located;
pub use reader::{ArchiveReader, DEFAULT_ATTEMPTS, LevelBytes, RETRY_BACKOFF};
pub use writer::ArchiveWriter;

/// The first 8 bytes of every archive.
pub const MAGIC: [u8; 8] = *b"SMDB\r\n\x1a\n";
/// The format version this crate writes and reads (older archives are refused with what to do).
pub const VERSION: u32 = 7;

/// What an archive of an older `version` lacks, when it is one this crate knows.
fn older_version(version: u32) -> Option<&'static str> {
    match version {
        2 => Some("stores whole-tile payloads"),
        3 | 4 => Some("has no apron, so tile borders would be lit from one side"),
        5 => Some("does not record the nodata its build filled"),
        6 => Some(
            "has no pyramid of overview tiles and an index read whole, so its cost grows with \
             its size",
        ),
        _ => None,
    }
}
/// Bytes in the header's fixed part: the whole header of an archive without georeferencing.
pub const HEADER_LEN: usize = 156;
/// The most bytes a header may have: the fixed part and the longest georeferencing.
pub const MAX_HEADER_LEN: usize = HEADER_LEN + georef_block::MAX_LEN;
/// Tiles per side of the block one index page holds.
pub const PAGE_SIDE: u32 = 8;
/// The most tiles the top may hold: the root and three levels below it.
pub const TOP_MAX_TILES: usize = 1 + 4 + 16 + 64;
/// The stored bytes the top may take beyond the root: the root and every level below it whose
/// tiles fit this allowance together are fetched with one request before anything else.
pub const TOP_BYTES: u64 = 96 << 10;
/// The most tiles across or down level 0 may have (the Earth at 30 m in tiles of 65 is about
/// 20,000 x 10,000).
pub const MAX_TILES_PER_SIDE: u32 = 1 << 24;
/// The widest spacing between samples an archive may have, metres.
pub const MAX_SPACING: f64 = 1e5;
/// The narrowest spacing between samples an archive may have, metres (a millimetre): below it,
/// a terrain is too small for a camera to fly over in f64.
pub const MIN_SPACING: f64 = 1e-3;
/// The finest height quantum an archive may have, metres.
pub const MIN_QUANTUM: f64 = 1e-6;
/// The farthest a terrain may reach, metres: its origin from zero, and its extent.
pub const MAX_EXTENT: f64 = 1e9;
/// The largest height (and vertical scale, and height quantum) an archive may hold, in size.
pub const MAX_HEIGHT: f64 = 1e6;

/// How tile payloads are stored.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Codec {
    /// Uncompressed.
    None,
    /// One LZ4 block per chunk (no frame, no size prefix; the size follows from the header).
    Lz4,
    /// One raw DEFLATE stream per chunk (RFC 1951, no zlib header), level 6: smaller, slower
    /// to decode.
    Deflate,
}

named_enum!(Codec, "codec", {
    None => "none",
    Lz4 => "lz4",
    Deflate => "deflate",
});

impl Codec {
    fn id(self) -> u32 {
        match self {
            Codec::None => 0,
            Codec::Lz4 => 1,
            Codec::Deflate => 2,
        }
    }

    fn from_id(id: u32) -> Option<Codec> {
        match id {
            0 => Some(Codec::None),
            1 => Some(Codec::Lz4),
            2 => Some(Codec::Deflate),
            _ => None,
        }
    }
}

/// The archive header: the grid description.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Header {
    /// Level-0 tiles across (west to east).
    pub tiles_x: u32,
    /// Level-0 tiles down (north to south).
    pub tiles_y: u32,
    /// Samples per tile side, `2^n + 1`, the same at every pyramid level.
    pub tile_size: u32,
    /// Texels per tile texture side (finest mip), a power of two.
    pub texture_size: u32,
    /// How payloads are stored.
    pub codec: Codec,
    /// Samples per row of the source DEM (before padding).
    pub source_width: u32,
    /// Rows of the source DEM (before padding).
    pub source_height: u32,
    /// Metres between neighbouring samples of level 0.
    pub spacing: f64,
    /// Metres per raw height unit that the build applied.
    pub vertical_scale: f64,
    /// World x (east, metres) of sample (0, 0), the north-west corner.
    pub origin_x: f64,
    /// World y (north, metres) of sample (0, 0); row j lies at `origin_y - j * spacing`.
    pub origin_y: f64,
    /// Lowest height in the archive, metres.
    pub min_height: f32,
    /// Highest height in the archive, metres.
    pub max_height: f32,
    /// Metres per height quantum, the same in every tile (see [`crate::db::tile`]).
    pub height_quantum: f32,
    /// Nodata samples of the source that the build filled from their nearest valid neighbours,
    /// so that `info` can say how much of the terrain was made up.
    pub nodata_filled: u64,
    /// Nodata samples in large nodata areas, far from any valid one, that the build drew flat
    /// at the lowest valid height around them.
    pub nodata_flattened: u64,
    /// Level-0 tiles whose every sample is nodata, stored as absent: no payload, nothing drawn.
    pub absent_tiles: u64,
    /// The finest pyramid level of the top: levels `top_level ..` up to the root.
    pub top_level: u32,
    /// Offset of the top's payloads, contiguous.
    pub top_offset: u64,
    /// Stored bytes of the top's payloads.
    pub top_len: u64,
    /// Bytes of the whole archive: a file of another length is truncated or grown.
    pub archive_len: u64,
    /// Where the samples lie on the Earth, when the build's DEM said: stored after the fixed
    /// part of the header.
    pub georef: Option<Georef>,
}

impl Header {
    /// The pyramid over the level-0 grid (validated headers only: the grid is not empty).
    pub fn pyramid(&self) -> Pyramid {
        Pyramid::new(self.tiles_x, self.tiles_y).expect("a validated header has tiles")
    }

    /// Pyramid levels, the root's included.
    pub fn pyramid_levels(&self) -> usize {
        pyramid_levels(self.tiles_x, self.tiles_y)
    }

    /// Level-0 tiles.
    pub fn tile_count(&self) -> u64 {
        u64::from(self.tiles_x) * u64::from(self.tiles_y)
    }

    /// Progressive levels (payload chunks) of every tile.
    pub fn levels(&self) -> usize {
        progressive_levels(self.tile_size as usize)
    }

    /// Bytes per index entry: the offset, then an end and a crc32 per level.
    pub fn index_entry_len(&self) -> usize {
        8 + 8 * self.levels()
    }

    /// Tiles of the top: every tile of levels `top_level ..= root`.
    pub fn top_tiles(&self) -> usize {
        let pyramid = self.pyramid();
        (self.top_level as usize..pyramid.levels())
            .map(|k| pyramid.grid(k as u8).tile_count() as usize)
            .sum()
    }

    /// Bytes of the header: the fixed part and the georeferencing after it. The directory
    /// follows.
    pub fn header_len(&self) -> usize {
        HEADER_LEN + self.georef.as_ref().map_or(0, georef_block::len)
    }

    /// Bytes of the directory: the page tables' offsets, the top's entries and a crc32.
    pub fn directory_len(&self) -> usize {
        8 * self.pyramid_levels() + self.top_tiles() * self.index_entry_len() + 4
    }

    /// Offset of the first payload byte: after the header and the room the directory may
    /// take (a top of [`TOP_MAX_TILES`] tiles).
    pub fn payload_start(&self) -> u64 {
        (self.header_len() + 8 * self.pyramid_levels() + TOP_MAX_TILES * self.index_entry_len() + 4)
            as u64
    }

    /// Uncompressed bytes of progressive chunk `level` of every tile.
    pub fn level_payload_size(&self, level: usize) -> usize {
        level_payload_size(level, self.tile_size as usize, self.texture_size as usize)
    }

    /// Uncompressed payload bytes of every whole tile (all its chunks).
    pub fn payload_size(&self) -> usize {
        (0..self.levels()).map(|g| self.level_payload_size(g)).sum()
    }

    /// Serialises the header: [`Header::header_len`] bytes.
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut b = Vec::with_capacity(self.header_len());
        b.extend_from_slice(&MAGIC);
        for v in [
            VERSION,
            self.header_len() as u32,
            self.tiles_x,
            self.tiles_y,
            self.tile_size,
            self.texture_size,
            self.codec.id(),
            self.source_width,
            self.source_height,
            self.top_level,
            self.top_tiles() as u32,
            PAGE_SIDE,
        ] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        for v in [
            self.spacing,
            self.vertical_scale,
            self.origin_x,
            self.origin_y,
        ] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&self.min_height.to_le_bytes());
        b.extend_from_slice(&self.max_height.to_le_bytes());
        b.extend_from_slice(&self.height_quantum.to_le_bytes());
        b.extend_from_slice(&(self.directory_len() as u32).to_le_bytes());
        for v in [
            self.nodata_filled,
            self.nodata_flattened,
            self.absent_tiles,
            self.top_offset,
            self.top_len,
            self.archive_len,
        ] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        let crc = crc32fast::hash(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        if let Some(g) = &self.georef {
            b.extend_from_slice(&georef_block::to_bytes(g));
        }
        b
    }

    /// Checks every number of the header against what a reader (and the engine after it) can
    /// work with: tile counts, levels, texture size, the top, and finite, bounded spacing,
    /// extent, origin and heights. The reader calls it on every header it parses, and `build`
    /// before it writes anything, so a build never writes what a reader would refuse.
    pub fn validate(&self, name: &str) -> Result<()> {
        self.check_layout()
            .and_then(|()| self.check_numbers())
            .map_err(|problem| Error::invalid(name, problem))
    }

    /// Tile counts, sizes and the top: what the reader allocates by.
    fn check_layout(&self) -> std::result::Result<(), String> {
        self.check_layout_grid()?;
        let t = self.texture_size as usize;
        if !t.is_power_of_two() || t > MAX_TEXTURE_SIZE {
            return Err(format!(
                "texture size {t} is not a power of two up to {MAX_TEXTURE_SIZE}"
            ));
        }
        let samples = u64::from(self.source_width) * u64::from(self.source_height);
        let nodata = self.nodata_filled.checked_add(self.nodata_flattened);
        if nodata.is_none_or(|n| n > samples) {
            return Err(format!(
                "{} nodata samples filled and {} flattened, more than the {samples} samples \
                 of the {} x {} model",
                self.nodata_filled, self.nodata_flattened, self.source_width, self.source_height
            ));
        }
        if self.absent_tiles > self.tile_count() {
            return Err(format!(
                "{} absent tiles of {}",
                self.absent_tiles,
                self.tile_count()
            ));
        }
        let top_end = self.top_offset.checked_add(self.top_len);
        if top_end.is_none_or(|end| end > self.archive_len)
            || (self.top_len > 0 && self.top_offset < self.payload_start())
        {
            return Err(format!(
                "the top ({} bytes at offset {}) lies outside the {}-byte archive's payloads",
                self.top_len, self.top_offset, self.archive_len
            ));
        }
        Ok(())
    }

    /// Spacing, origin and heights: finite, positive where they divide, and within the bounds
    /// the engine's arithmetic is proven for.
    fn check_numbers(&self) -> std::result::Result<(), String> {
        let finite = [
            self.spacing,
            self.vertical_scale,
            self.origin_x,
            self.origin_y,
        ]
        .iter()
        .all(|v| v.is_finite());
        if !finite
            || self.spacing <= 0.0
            || !(self.height_quantum.is_finite() && self.height_quantum > 0.0)
        {
            return Err(
                "spacing, vertical scale, origin or height quantum is not a finite number \
                 (or spacing or quantum is not positive)"
                    .into(),
            );
        }
        if !(MIN_SPACING..=MAX_SPACING).contains(&self.spacing) {
            return Err(format!(
                "spacing {} m is outside {MIN_SPACING} ..= {MAX_SPACING} m",
                self.spacing
            ));
        }
        if f64::from(self.height_quantum) < MIN_QUANTUM {
            return Err(format!(
                "height quantum {} m is finer than {MIN_QUANTUM} m",
                self.height_quantum
            ));
        }
        let cells = (self.tile_size - 1) as f64;
        let side = (f64::from(self.tiles_x.max(self.tiles_y)) * cells)
            .max(f64::from(self.source_width.max(self.source_height)));
        let extent = self.spacing * side;
        if extent > MAX_EXTENT
            || self.origin_x.abs() > MAX_EXTENT
            || self.origin_y.abs() > MAX_EXTENT
        {
            return Err(format!(
                "the terrain spans {extent} m from origin ({}, {}); each must be within \
                 {MAX_EXTENT} m",
                self.origin_x, self.origin_y
            ));
        }
        let heights = [
            f64::from(self.min_height),
            f64::from(self.max_height),
            self.vertical_scale,
            f64::from(self.height_quantum),
        ];
        if heights
            .iter()
            .any(|v| !v.is_finite() || v.abs() > MAX_HEIGHT)
            || self.vertical_scale == 0.0
            || self.min_height > self.max_height
        {
            return Err(format!(
                "heights {} ..= {} m, vertical scale {} or quantum {}: each must be finite, \
                 within {MAX_HEIGHT} in size, the scale non-zero and the range in order",
                self.min_height, self.max_height, self.vertical_scale, self.height_quantum
            ));
        }
        Ok(())
    }

    /// Parses and validates a whole header (its [`Header::header_len`] bytes, or more);
    /// `name` labels errors.
    pub fn parse(bytes: &[u8], name: &str) -> Result<Header> {
        let (header, georef_len) = Header::parse_fixed(bytes, name)?;
        let end = HEADER_LEN + georef_len;
        if bytes.len() < end {
            return Err(Error::invalid(
                name,
                format!("truncated header: {} of {end} bytes", bytes.len()),
            ));
        }
        header.with_georef(&bytes[HEADER_LEN..end], name)
    }

    /// This header with the georeferencing `block` holds (nothing when it is empty),
    /// validated again with it; `name` labels errors.
    pub fn with_georef(mut self, block: &[u8], name: &str) -> Result<Header> {
        if !block.is_empty() {
            self.georef = Some(georef_block::parse(block).map_err(|p| Error::invalid(name, p))?);
        }
        self.validate(name)?;
        Ok(self)
    }

    /// Parses and validates the header's fixed part (the first [`HEADER_LEN`] bytes of
    /// `bytes`), and returns it without georeferencing with the bytes of the georeferencing
    /// that follows it ([`Header::with_georef`] reads them); `name` labels errors.
    pub fn parse_fixed(bytes: &[u8], name: &str) -> Result<(Header, usize)> {
        let bad = |p: String| Error::invalid(name, p);
        let n = bytes.len().min(MAGIC.len());
        if bytes[..n] != MAGIC[..n] {
            return Err(bad("bad magic: not a stripmask archive (.smdb)".into()));
        }
        let u = |k: usize| u32::from_le_bytes(bytes[k..k + 4].try_into().expect("4 bytes"));
        if bytes.len() >= 12 {
            let version = u(8);
            if let Some(why) = older_version(version) {
                return Err(bad(format!(
                    "archive version {version} {why}; this build reads version {VERSION}: \
                     rebuild it with `stripmask build`"
                )));
            }
            if version != VERSION {
                return Err(bad(format!(
                    "archive version {version}, this build reads version {VERSION}"
                )));
            }
        }
        if bytes.len() < HEADER_LEN {
            return Err(bad(format!(
                "truncated header: {} of {HEADER_LEN} bytes",
                bytes.len()
            )));
        }
        let f = |k: usize| f64::from_le_bytes(bytes[k..k + 8].try_into().expect("8 bytes"));
        let g = |k: usize| f32::from_le_bytes(bytes[k..k + 4].try_into().expect("4 bytes"));
        let l = |k: usize| u64::from_le_bytes(bytes[k..k + 8].try_into().expect("8 bytes"));
        let len = u(12) as usize;
        let georef_len = len.wrapping_sub(HEADER_LEN);
        if len != HEADER_LEN
            && !(HEADER_LEN + georef_block::MIN_LEN..=MAX_HEADER_LEN).contains(&len)
        {
            return Err(bad(format!(
                "header length {len} is neither {HEADER_LEN} nor {} ..= {MAX_HEADER_LEN} (with \
                 georeferencing)",
                HEADER_LEN + georef_block::MIN_LEN
            )));
        }
        let crc = crc32fast::hash(&bytes[..HEADER_LEN - 4]);
        if crc != u(HEADER_LEN - 4) {
            return Err(bad("header checksum mismatch (corrupt header)".into()));
        }
        let codec =
            Codec::from_id(u(32)).ok_or_else(|| bad(format!("unknown payload codec {}", u(32))))?;
        if u(52) != PAGE_SIDE {
            return Err(bad(format!(
                "index pages of {} tiles a side, this build reads {PAGE_SIDE}",
                u(52)
            )));
        }
        let h = Header {
            tiles_x: u(16),
            tiles_y: u(20),
            tile_size: u(24),
            texture_size: u(28),
            codec,
            source_width: u(36),
            source_height: u(40),
            top_level: u(44),
            spacing: f(56),
            vertical_scale: f(64),
            origin_x: f(72),
            origin_y: f(80),
            min_height: g(88),
            max_height: g(92),
            height_quantum: g(96),
            nodata_filled: l(104),
            nodata_flattened: l(112),
            absent_tiles: l(120),
            top_offset: l(128),
            top_len: l(136),
            archive_len: l(144),
            georef: None,
        };
        // The grid first: the top's size below is computed from it.
        h.check_layout_grid().map_err(&bad)?;
        if u(48) as usize != h.top_tiles() || u(100) as usize != h.directory_len() {
            return Err(bad(format!(
                "a top of {} tiles and a directory of {} bytes, where levels {} .. of a {} x {} \
                 grid make {} tiles and {} bytes",
                u(48),
                u(100),
                h.top_level,
                h.tiles_x,
                h.tiles_y,
                h.top_tiles(),
                h.directory_len()
            )));
        }
        h.validate(name)?;
        Ok((h, if len == HEADER_LEN { 0 } else { georef_len }))
    }

    /// The part of [`Header::check_layout`] that the top's size depends on.
    fn check_layout_grid(&self) -> std::result::Result<(), String> {
        let per_side = 1..=MAX_TILES_PER_SIDE;
        if !per_side.contains(&self.tiles_x) || !per_side.contains(&self.tiles_y) {
            return Err(format!(
                "{} x {} tiles: each must be within 1 ..= {MAX_TILES_PER_SIDE}",
                self.tiles_x, self.tiles_y
            ));
        }
        if !is_valid_tile_size(self.tile_size as usize) {
            return Err(format!("tile size {} is not 2^n + 1", self.tile_size));
        }
        if self.top_level as usize >= self.pyramid_levels() {
            return Err(format!(
                "the top starts at level {}, beyond the root at level {}",
                self.top_level,
                self.pyramid_levels() - 1
            ));
        }
        if self.top_tiles() > TOP_MAX_TILES {
            return Err(format!(
                "a top of {} tiles, more than {TOP_MAX_TILES}",
                self.top_tiles()
            ));
        }
        Ok(())
    }
}

/// Pyramid levels over `tiles_x x tiles_y` level-0 tiles (both at least 1), the root's included.
pub fn pyramid_levels(tiles_x: u32, tiles_y: u32) -> usize {
    let widest = tiles_x.max(tiles_y).max(1);
    (widest.next_power_of_two().ilog2() + 1) as usize
}

/// The most bytes a stored chunk of `raw` bytes may take (the codec's worst case).
fn stored_bound(codec: Codec, raw: usize) -> usize {
    match codec {
        Codec::None => raw,
        Codec::Lz4 => lz4_flex::block::get_maximum_output_size(raw),
        // Stored blocks add 5 bytes per 64 KiB block at worst.
        Codec::Deflate => raw + 5 * (raw / 65_535 + 1) + 16,
    }
}

/// Compresses one raw progressive chunk with `codec`.
pub fn compress(raw: &[u8], codec: Codec) -> Vec<u8> {
    match codec {
        Codec::None => raw.to_vec(),
        Codec::Lz4 => lz4_flex::block::compress(raw),
        Codec::Deflate => miniz_oxide::deflate::compress_to_vec(raw, 6),
    }
}

/// Decompresses the stored bytes of one chunk into its `size` raw bytes; `name` labels errors.
pub fn decompress(stored: &[u8], codec: Codec, size: usize, name: &str) -> Result<Vec<u8>> {
    let wrong = |n: usize| {
        Error::invalid(
            name,
            format!("chunk decompresses to {n} bytes, {size} expected"),
        )
    };
    match codec {
        Codec::None if stored.len() == size => Ok(stored.to_vec()),
        Codec::None => Err(wrong(stored.len())),
        Codec::Lz4 => {
            let mut out = vec![0; size];
            match lz4_flex::block::decompress_into(stored, &mut out) {
                Ok(n) if n == size => Ok(out),
                Ok(n) => Err(wrong(n)),
                Err(e) => Err(Error::invalid(name, format!("corrupt LZ4 chunk: {e}"))),
            }
        }
        Codec::Deflate => match miniz_oxide::inflate::decompress_to_vec_with_limit(stored, size) {
            Ok(out) if out.len() == size => Ok(out),
            Ok(out) => Err(wrong(out.len())),
            Err(e) => Err(Error::invalid(name, format!("corrupt DEFLATE chunk: {e}"))),
        },
    }
}

/// The level range `levels` of a tile with `all` progressive levels, or an error naming it.
fn check_levels(levels: &Range<usize>, all: usize, what: &str, name: &str) -> Result<()> {
    if levels.start > levels.end || levels.end > all {
        return Err(Error::invalid(
            name,
            format!("levels {levels:?} of {what} are outside 0..{all}"),
        ));
    }
    Ok(())
}
