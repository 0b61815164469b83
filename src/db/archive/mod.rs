//! The `.smdb` archive: one file with a header, an index and the tile payloads.
//!
//! All integers and floats are little-endian. The byte-level description, enough for another
//! implementation, is in `docs/archive-format.md`; in short:
//!
//! * header, [`HEADER_LEN`] bytes: magic, version, grid (tiles across/down, tile size, texture
//!   size), payload codec, source dimensions, spacing, vertical scale, origin, height range of the
//!   valid samples, the nodata samples the build filled and flattened, crc32;
//! * index, one entry per tile in row-major tile order: offset u64, then per progressive level
//!   the end u32 of its chunk (stored bytes from the tile's offset) and the crc32 u32 of the
//!   chunk's stored bytes; then the crc32 of the index;
//! * the payloads: each tile's progressive chunks ([`crate::db::tile`]), coarse first, each
//!   compressed on its own as the header's codec says, so any one range decodes alone;
//! * the base: the first [`Header::base_levels`] chunks of every tile again, in tile order, so
//!   that a client gets a coarse copy of the whole terrain with one more request.
//!
//! A client reads the header and the index (the paper's "main file") in two range requests, the
//! base in one, then any range of levels of any tile in one more: tile `(tx, ty)` is entry
//! `ty * tiles_x + tx`.

mod check;
pub mod partial;
mod reader;
mod writer;

use std::ops::Range;

use serde::Serialize;

use crate::db::tile::{MAX_TEXTURE_SIZE, level_payload_size, progressive_levels};
use crate::db::tiling::is_valid_tile_size;
use crate::error::{Error, Result};
use crate::named::named_enum;

pub use check::CheckReport;
pub use reader::{ArchiveReader, DEFAULT_ATTEMPTS, LevelBytes, RETRY_BACKOFF};
pub use writer::ArchiveWriter;

/// The first 8 bytes of every archive.
pub const MAGIC: [u8; 8] = *b"SMDB\r\n\x1a\n";
/// The format version this crate writes and reads (older archives are refused with what to do).
pub const VERSION: u32 = 6;

/// What an archive of an older `version` lacks, when it is one this crate knows.
fn older_version(version: u32) -> Option<&'static str> {
    match version {
        2 => Some("stores whole-tile payloads"),
        3 | 4 => Some("has no apron, so tile borders would be lit from one side"),
        5 => Some("does not record the nodata its build filled"),
        _ => None,
    }
}
/// Bytes in the header.
pub const HEADER_LEN: usize = 112;
/// The most tiles an archive may hold.
pub const MAX_TILES: usize = 1 << 24;
/// The largest index a reader accepts (bounds what it allocates: 256 MiB).
pub const MAX_INDEX_LEN: usize = 1 << 28;
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
    /// Tiles across (west to east).
    pub tiles_x: u32,
    /// Tiles down (north to south).
    pub tiles_y: u32,
    /// Samples per tile side, `2^n + 1`.
    pub tile_size: u32,
    /// Texels per tile texture side (finest mip), a power of two.
    pub texture_size: u32,
    /// How payloads are stored.
    pub codec: Codec,
    /// Samples per row of the source DEM (before padding).
    pub source_width: u32,
    /// Rows of the source DEM (before padding).
    pub source_height: u32,
    /// Metres between neighbouring samples.
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
    /// Progressive levels of every tile stored again after the payloads, as the base (0: no
    /// base).
    pub base_levels: u32,
    /// Nodata samples of the source that the build filled from their nearest valid neighbours,
    /// so that `info` can say how much of the terrain was made up.
    pub nodata_filled: u64,
    /// Nodata samples in large nodata areas, far from any valid one, that the build drew flat
    /// at the lowest valid height around them.
    pub nodata_flattened: u64,
}

impl Header {
    /// Number of tiles.
    pub fn tile_count(&self) -> usize {
        self.tiles_x as usize * self.tiles_y as usize
    }

    /// Progressive levels (payload chunks) of every tile.
    pub fn levels(&self) -> usize {
        progressive_levels(self.tile_size as usize)
    }

    /// Bytes per index entry: the offset, then an end and a crc32 per level.
    pub fn index_entry_len(&self) -> usize {
        8 + 8 * self.levels()
    }

    /// Bytes of the index including its trailing crc32.
    pub fn index_len(&self) -> usize {
        self.tile_count() * self.index_entry_len() + 4
    }

    /// Offset of the first payload byte.
    pub fn payload_start(&self) -> u64 {
        (HEADER_LEN + self.index_len()) as u64
    }

    /// Uncompressed bytes of progressive chunk `level` of every tile.
    pub fn level_payload_size(&self, level: usize) -> usize {
        level_payload_size(level, self.tile_size as usize, self.texture_size as usize)
    }

    /// Uncompressed payload bytes of every whole tile (all its chunks).
    pub fn payload_size(&self) -> usize {
        (0..self.levels()).map(|g| self.level_payload_size(g)).sum()
    }

    /// Serialises the header.
    pub fn to_bytes(&self) -> [u8; HEADER_LEN] {
        let mut b = Vec::with_capacity(HEADER_LEN);
        b.extend_from_slice(&MAGIC);
        for v in [
            VERSION,
            HEADER_LEN as u32,
            self.tiles_x,
            self.tiles_y,
            self.tile_size,
            self.texture_size,
            self.codec.id(),
            self.source_width,
            self.source_height,
            self.base_levels,
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
        b.extend_from_slice(&self.nodata_filled.to_le_bytes());
        b.extend_from_slice(&self.nodata_flattened.to_le_bytes());
        let crc = crc32fast::hash(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        b.try_into().expect("header is HEADER_LEN bytes")
    }

    /// Checks every number of the header against what a reader (and the engine after it) can
    /// work with: tile counts, index size, levels, texture size, and finite, bounded spacing,
    /// extent, origin and heights. The reader calls it on every header it parses, and `build`
    /// before it writes anything, so a build never writes what a reader would refuse.
    pub fn validate(&self, name: &str) -> Result<()> {
        self.check_layout()
            .and_then(|()| self.check_numbers())
            .map_err(|problem| Error::invalid(name, problem))
    }

    /// Tile counts, sizes, the index and the base: what the reader allocates by.
    fn check_layout(&self) -> std::result::Result<(), String> {
        let count = self.tiles_x as usize * self.tiles_y as usize;
        if count == 0 || count > MAX_TILES {
            return Err(format!(
                "{} x {} tiles is outside 1 ..= {MAX_TILES}",
                self.tiles_x, self.tiles_y
            ));
        }
        if !is_valid_tile_size(self.tile_size as usize) {
            return Err(format!("tile size {} is not 2^n + 1", self.tile_size));
        }
        if self.index_len() > MAX_INDEX_LEN {
            return Err(format!(
                "the index of {} x {} tiles would take {} bytes, more than {MAX_INDEX_LEN}",
                self.tiles_x,
                self.tiles_y,
                self.index_len()
            ));
        }
        if self.base_levels as usize > self.levels() {
            return Err(format!(
                "a base of {} levels, but tiles have {}",
                self.base_levels,
                self.levels()
            ));
        }
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
        let side = f64::from(
            self.source_width
                .max(self.source_height)
                .max(self.tile_size),
        );
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

    /// Parses and validates a header; `name` labels errors.
    pub fn parse(bytes: &[u8], name: &str) -> Result<Header> {
        let bad = |p: String| Error::invalid(name, p);
        let n = bytes.len().min(MAGIC.len());
        if bytes[..n] != MAGIC[..n] {
            return Err(bad("bad magic: not a stripmask archive (.smdb)".into()));
        }
        if bytes.len() < HEADER_LEN {
            return Err(bad(format!(
                "truncated header: {} of {HEADER_LEN} bytes",
                bytes.len()
            )));
        }
        let u = |k: usize| u32::from_le_bytes(bytes[k..k + 4].try_into().expect("4 bytes"));
        let f = |k: usize| f64::from_le_bytes(bytes[k..k + 8].try_into().expect("8 bytes"));
        let g = |k: usize| f32::from_le_bytes(bytes[k..k + 4].try_into().expect("4 bytes"));
        let l = |k: usize| u64::from_le_bytes(bytes[k..k + 8].try_into().expect("8 bytes"));
        let version = u(8);
        if let Some(why) = older_version(version) {
            return Err(bad(format!(
                "archive version {version} {why}; this build reads version {VERSION}: rebuild \
                 it with `stripmask build`"
            )));
        }
        if version != VERSION {
            return Err(bad(format!(
                "archive version {version}, this build reads version {VERSION}"
            )));
        }
        if u(12) as usize != HEADER_LEN {
            return Err(bad(format!("header length {} is not {HEADER_LEN}", u(12))));
        }
        let crc = crc32fast::hash(&bytes[..HEADER_LEN - 4]);
        if crc != u(HEADER_LEN - 4) {
            return Err(bad("header checksum mismatch (corrupt header)".into()));
        }
        let codec =
            Codec::from_id(u(32)).ok_or_else(|| bad(format!("unknown payload codec {}", u(32))))?;
        let h = Header {
            tiles_x: u(16),
            tiles_y: u(20),
            tile_size: u(24),
            texture_size: u(28),
            codec,
            source_width: u(36),
            source_height: u(40),
            spacing: f(48),
            vertical_scale: f(56),
            origin_x: f(64),
            origin_y: f(72),
            min_height: g(80),
            max_height: g(84),
            height_quantum: g(88),
            base_levels: u(44),
            nodata_filled: l(92),
            nodata_flattened: l(100),
        };
        h.validate(name)?;
        Ok(h)
    }
}

/// Where one tile's stored chunks are: chunk `g` is bytes `[end(g - 1), end(g))` after the
/// tile's offset, so the bytes of any range of levels are one contiguous range.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
pub struct IndexEntry {
    /// Offset of chunk 0 from the start of the file.
    pub offset: u64,
    /// One entry per progressive level, coarse first.
    pub levels: Vec<LevelEntry>,
}

/// Where one progressive chunk of a tile ends, and its checksum.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub struct LevelEntry {
    /// Stored bytes from the tile's offset through this chunk.
    pub end: u32,
    /// crc32 (IEEE) of this chunk's stored bytes.
    pub crc32: u32,
}

impl IndexEntry {
    /// Stored bytes of the first `levels` chunks (what the base holds of this tile).
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
}

/// Where the base lies, given the index: right after the last payload, each tile's first
/// `base_levels` chunks in tile order. Returns (file offset, length).
pub fn base_range(index: &[IndexEntry], base_levels: usize) -> (u64, u64) {
    let end = index
        .iter()
        .map(|e| e.offset + e.stored_len())
        .max()
        .unwrap_or(0);
    let len = index.iter().map(|e| e.prefix_len(base_levels)).sum();
    (end, len)
}

/// Serialises the index with its trailing crc32.
pub fn index_to_bytes(entries: &[IndexEntry]) -> Vec<u8> {
    let mut b = Vec::new();
    for e in entries {
        b.extend_from_slice(&e.offset.to_le_bytes());
        for l in &e.levels {
            b.extend_from_slice(&l.end.to_le_bytes());
            b.extend_from_slice(&l.crc32.to_le_bytes());
        }
    }
    let crc = crc32fast::hash(&b);
    b.extend_from_slice(&crc.to_le_bytes());
    b
}

/// Parses and validates the index of `header`; `file_len`, when known, bounds the entries.
pub fn parse_index(
    bytes: &[u8],
    header: &Header,
    file_len: Option<u64>,
    name: &str,
) -> Result<Vec<IndexEntry>> {
    let (n, entry_len) = (header.tile_count(), header.index_entry_len());
    if bytes.len() < header.index_len() {
        return Err(Error::invalid(
            name,
            format!(
                "truncated index: {} of {} bytes",
                bytes.len(),
                header.index_len()
            ),
        ));
    }
    let body = &bytes[..n * entry_len];
    let stored = u32::from_le_bytes(bytes[n * entry_len..][..4].try_into().expect("4"));
    if crc32fast::hash(body) != stored {
        return Err(Error::invalid(
            name,
            "index checksum mismatch (corrupt index)",
        ));
    }
    let bounds: Vec<u64> = (0..header.levels())
        .map(|g| stored_bound(header.codec, header.level_payload_size(g)) as u64)
        .collect();
    let u32_at = |e: &[u8], k: usize| u32::from_le_bytes(e[k..k + 4].try_into().expect("4"));
    body.chunks_exact(entry_len)
        .enumerate()
        .map(|(i, e)| {
            let entry = IndexEntry {
                offset: u64::from_le_bytes(e[..8].try_into().expect("8")),
                levels: (0..header.levels())
                    .map(|g| LevelEntry {
                        end: u32_at(e, 8 + 8 * g),
                        crc32: u32_at(e, 12 + 8 * g),
                    })
                    .collect(),
            };
            let outside = |problem: String| {
                Error::invalid(
                    name,
                    format!(
                        "index entry {i} (offset {}) points outside the payloads: {problem}",
                        entry.offset
                    ),
                )
            };
            if entry.offset < header.payload_start() {
                return Err(outside("it starts inside the index".into()));
            }
            let mut start = 0u64;
            for (g, level) in entry.levels.iter().enumerate() {
                let end = u64::from(level.end);
                if end <= start || end - start > bounds[g] {
                    return Err(outside(format!(
                        "level {g} ends at {end} after starting at {start}, more than the \
                         codec's {} bytes or nothing",
                        bounds[g]
                    )));
                }
                start = end;
            }
            let end = entry.offset.checked_add(entry.stored_len());
            match (end, file_len) {
                (Some(end), Some(len)) if end > len => Err(outside(format!(
                    "it ends at byte {end} of a {len}-byte file"
                ))),
                (None, _) => Err(outside("its end overflows".into())),
                _ => Ok(entry),
            }
        })
        .collect::<Result<Vec<_>>>()
        .and_then(|entries| disjoint(entries, name))
}

/// `entries` if no two of them share a byte: an index whose entries overlap (or repeat) would
/// make readers decode one payload many times over, a decompression bomb of the index.
fn disjoint(entries: Vec<IndexEntry>, name: &str) -> Result<Vec<IndexEntry>> {
    let mut spans: Vec<(u64, u64, usize)> = entries
        .iter()
        .enumerate()
        .map(|(i, e)| (e.offset, e.offset + e.stored_len(), i))
        .collect();
    spans.sort_unstable();
    for pair in spans.windows(2) {
        let ((start_a, end_a, a), (start_b, end_b, b)) = (pair[0], pair[1]);
        if start_b < end_a {
            return Err(Error::invalid(
                name,
                format!(
                    "index entries {a} and {b} overlap: bytes {start_a}..{end_a} and \
                     {start_b}..{end_b} (an index must give every tile its own bytes)"
                ),
            ));
        }
    }
    Ok(entries)
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
