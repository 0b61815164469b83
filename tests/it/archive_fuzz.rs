//! Property-based fuzzing of the archive reader: random and mutated headers, directories, page
//! tables, index pages, the top and progressive tile chunks must give `Err` naming the file,
//! never a panic. `PROPTEST_CASES=100000` runs a long campaign.

use std::path::PathBuf;
use std::sync::OnceLock;

use proptest::prelude::*;
use stripmask::db::archive::{
    ArchiveReader, Directory, HEADER_LEN, Header, TABLE_CHUNK_ENTRIES, decompress, page_count,
    page_tiles, parse_page, parse_table_chunk, table_chunk,
};
use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{MemoryReader, NodataFill};
use stripmask::db::grid::TileId;
use stripmask::db::source::CancelToken;
use stripmask::db::source::file::FileSource;
use stripmask::db::tile::Tile;
use stripmask::engine::terrain::TerrainFrame;
use stripmask::sim::flight::{Builtin, Flight};
use stripmask::{Error, Named};

fn cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(64)
}

/// A valid archive of 16 x 8 tiles of 9 samples at level 0 (whose index pages lie outside the
/// top) and four levels above, built once.
fn valid() -> &'static (tempfile::TempDir, PathBuf, Vec<u8>) {
    static VALID: OnceLock<(tempfile::TempDir, PathBuf, Vec<u8>)> = OnceLock::new();
    VALID.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (129, 65);
        let samples = (0..w * h).map(|k| ((k * 37) % 101) as f32).collect();
        let reader = MemoryReader::new("fuzz", w, h, samples).unwrap();
        let out = dir.path().join("fuzz.smdb");
        let options = BuildOptions {
            tile_size: 9,
            ..BuildOptions::default()
        };
        build(NodataFill::new(reader, None), &out, &options, &|_, _| {}).unwrap();
        let bytes = std::fs::read(&out).unwrap();
        (dir, out, bytes)
    })
}

/// Byte edits: (position as a fraction of the length, new byte), and a truncation fraction.
fn mutations() -> impl Strategy<Value = (Vec<(f64, u8)>, Option<f64>)> {
    (
        proptest::collection::vec((0.0..1.0f64, any::<u8>()), 1..8),
        proptest::option::of(0.0..1.0f64),
    )
}

fn mutate(bytes: &[u8], edits: &[(f64, u8)], cut: Option<f64>) -> Vec<u8> {
    let mut b = bytes.to_vec();
    for &(at, v) in edits {
        let i = ((at * b.len() as f64) as usize).min(b.len() - 1);
        b[i] = v;
    }
    if let Some(c) = cut {
        b.truncate((c * b.len() as f64) as usize);
    }
    b
}

/// Restores every checksum after an edit — the header's, the directory's, each page table
/// chunk's and each index page's, as far as the edited archive still says where they are — so
/// that the edit reaches the validation behind them.
fn fix_checksums(b: &mut [u8]) {
    if b.len() < HEADER_LEN {
        return;
    }
    let crc = crc32fast::hash(&b[..HEADER_LEN - 4]);
    b[HEADER_LEN - 4..HEADER_LEN].copy_from_slice(&crc.to_le_bytes());
    let Ok(header) = Header::parse(&b[..HEADER_LEN], "fix") else {
        return;
    };
    let end = HEADER_LEN + header.directory_len();
    if end > b.len() {
        return;
    }
    let crc = crc32fast::hash(&b[HEADER_LEN..end - 4]);
    b[end - 4..end].copy_from_slice(&crc.to_le_bytes());
    let Ok(directory) = Directory::parse(&b[HEADER_LEN..end], &header, "fix") else {
        return;
    };
    let pyramid = header.pyramid();
    for (k, &table) in directory.tables.iter().enumerate() {
        let pages = page_count(pyramid.grid(k as u8)).min(1 << 12);
        for chunk in 0..pages.div_ceil(TABLE_CHUNK_ENTRIES as u64) {
            let (offset, len, entries) = table_chunk(table, pages, chunk);
            let (at, refs) = (offset as usize, entries * 16);
            if at + len as usize > b.len() {
                return;
            }
            for r in 0..entries {
                let e = at + r * 16;
                let page = u64::from_le_bytes(b[e..e + 8].try_into().unwrap()) as usize;
                let plen = u32::from_le_bytes(b[e + 8..e + 12].try_into().unwrap()) as usize;
                if page > 0 && page.saturating_add(plen) <= b.len() {
                    let crc = crc32fast::hash(&b[page..page + plen]);
                    b[e + 12..e + 16].copy_from_slice(&crc.to_le_bytes());
                }
            }
            let crc = crc32fast::hash(&b[at..at + refs]);
            b[at + refs..at + refs + 4].copy_from_slice(&crc.to_le_bytes());
        }
    }
}

/// Opens `bytes` as an archive and reads what it can: the top, and every tile (at most a few
/// hundred of each level) whole, its first level and its finer levels.
fn read_everything(bytes: &[u8]) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.smdb");
    std::fs::write(&path, bytes).unwrap();
    if let Ok(reader) = ArchiveReader::open_with_attempts(FileSource::open(&path).unwrap(), 1) {
        let h = reader.header().clone();
        let _ = reader.top();
        let pyramid = reader.pyramid().clone();
        for k in 0..pyramid.levels().min(8) as u8 {
            let grid = pyramid.grid(k);
            for ty in 0..grid.tiles_y().min(16) {
                for tx in 0..grid.tiles_x().min(16) {
                    let id = TileId::at(k, tx, ty);
                    let _ = reader.tile(id);
                    let _ = reader.tile_levels(id, 1);
                    let _ = reader.read_levels(id, 1..h.levels());
                }
            }
        }
        let _ = reader.check();
    }
}

/// The header's numbers: (offset, width in bytes) of spacing, vertical scale, origin x and y
/// (f64), min and max height and the height quantum (f32).
const NUMBERS: [(usize, usize); 7] = [
    (56, 8),
    (64, 8),
    (72, 8),
    (80, 8),
    (88, 4),
    (92, 4),
    (96, 4),
];

/// Numbers no terrain has, and ordinary ones: non-finite, huge, tiny, negative.
fn extreme() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(f64::MAX),
        Just(-f64::MAX),
        Just(1e300),
        Just(1e38),
        Just(3.5e38),
        Just(1e12),
        Just(1e-300),
        Just(0.0),
        Just(-1.0),
        -1e7..1e7f64,
    ]
}

/// `good`'s header with number `field` set to `value`, its checksum restored.
fn header_with(good: &[u8], field: usize, value: f64) -> Vec<u8> {
    let mut b = good[..HEADER_LEN].to_vec();
    let (at, width) = NUMBERS[field];
    if width == 8 {
        b[at..at + 8].copy_from_slice(&value.to_le_bytes());
    } else {
        b[at..at + 4].copy_from_slice(&(value as f32).to_le_bytes());
    }
    let crc = crc32fast::hash(&b[..HEADER_LEN - 4]);
    b[HEADER_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
    b
}

#[test]
fn a_header_with_an_infinite_height_is_refused_though_its_checksum_holds() {
    let (_, _, good) = valid();
    let mut bytes = good.clone();
    bytes[..HEADER_LEN].copy_from_slice(&header_with(good, 5, f64::INFINITY));
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("inf.smdb");
    std::fs::write(&path, bytes).unwrap();
    match ArchiveReader::open(FileSource::open(&path).unwrap()) {
        Err(Error::Invalid { name, problem }) => {
            assert!(
                name.ends_with("inf.smdb") && problem.contains("inf"),
                "{problem}"
            );
        }
        Err(e) => panic!("{e}"),
        Ok(_) => panic!("opened an archive whose max height is infinite"),
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases()))]

    /// Every header number set to an extreme value, with a valid checksum: the header is refused,
    /// or its numbers are finite and every built-in flight can be laid over it.
    #[test]
    fn extreme_header_numbers_are_refused_or_fly(
        values in proptest::collection::vec((0usize..NUMBERS.len(), extreme()), 1..4),
    ) {
        let (_, _, good) = valid();
        let mut bytes = good[..HEADER_LEN].to_vec();
        for &(field, value) in &values {
            bytes = header_with(&bytes, field, value);
        }
        if let Ok(h) = Header::parse(&bytes, "extreme") {
            let numbers = [h.spacing, h.vertical_scale, h.origin_x, h.origin_y];
            prop_assert!(numbers.iter().all(|v| v.is_finite()));
            prop_assert!(h.min_height.is_finite() && h.max_height.is_finite());
            for which in Builtin::all() {
                let flight = Flight::builtin(which, &TerrainFrame::new(&h));
                prop_assert!(flight.duration().is_finite());
            }
        }
    }

    /// Any nodata counts with a valid checksum: the header is refused naming them, or they add
    /// up to at most the model's samples and read back as written.
    #[test]
    fn nodata_counts_are_refused_or_within_the_model(
        filled in prop_oneof![Just(u64::MAX), Just(0u64), 0u64..1200, any::<u64>()],
        flattened in prop_oneof![Just(u64::MAX), Just(0u64), 0u64..1200, any::<u64>()],
    ) {
        let (_, _, good) = valid();
        let mut bytes = good[..HEADER_LEN].to_vec();
        bytes[104..112].copy_from_slice(&filled.to_le_bytes());
        bytes[112..120].copy_from_slice(&flattened.to_le_bytes());
        let crc = crc32fast::hash(&bytes[..HEADER_LEN - 4]);
        bytes[HEADER_LEN - 4..].copy_from_slice(&crc.to_le_bytes());
        match Header::parse(&bytes, "nodata") {
            Ok(h) => {
                prop_assert_eq!((h.nodata_filled, h.nodata_flattened), (filled, flattened));
                let samples = u64::from(h.source_width) * u64::from(h.source_height);
                prop_assert!(u128::from(filled) + u128::from(flattened) <= u128::from(samples));
            }
            Err(e) => {
                let text = e.to_string();
                prop_assert!(text.contains("nodata") && text.contains(&filled.to_string()), "{}", text);
                prop_assert!(u128::from(filled) + u128::from(flattened) > 129 * 65);
            }
        }
    }

    #[test]
    fn mutated_archives_never_panic((edits, cut) in mutations(), fix in any::<bool>()) {
        let (_, _, good) = valid();
        let mut bytes = mutate(good, &edits, cut);
        if fix {
            fix_checksums(&mut bytes);
        }
        read_everything(&bytes);
    }

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
        read_everything(&bytes);
        let _ = Header::parse(&bytes, "random");
    }

    #[test]
    fn mutated_directories_tables_and_pages_parse_or_fail_cleanly(
        (edits, cut) in mutations(),
        page in 0u64..2,
    ) {
        let (_, path, good) = valid();
        let reader = ArchiveReader::open(FileSource::open(path).unwrap()).unwrap();
        let h = reader.header().clone();
        let grid = reader.pyramid().grid(0);
        let directory = &good[HEADER_LEN..HEADER_LEN + h.directory_len()];
        let _ = Directory::parse(&mutate(directory, &edits, cut), &h, "m");
        let pages = page_count(grid);
        let (offset, len, entries) = table_chunk(reader.directory().tables[0], pages, 0);
        let chunk = &good[offset as usize..(offset + len) as usize];
        let mut bytes = mutate(chunk, &edits, cut);
        let refs = entries * 16;
        if bytes.len() == refs + 4 {
            let crc = crc32fast::hash(&bytes[..refs]);
            bytes[refs..].copy_from_slice(&crc.to_le_bytes());
        }
        let _ = parse_table_chunk(&bytes, &h, grid, 0, entries, "m");
        let refs = parse_table_chunk(chunk, &h, grid, 0, entries, "m").unwrap();
        let r = refs[page as usize];
        let stored = &good[r.offset as usize..(r.offset + u64::from(r.len)) as usize];
        prop_assert_eq!(page_tiles(grid, page).len() * h.index_entry_len(), stored.len());
        if let Err(e) = parse_page(&mutate(stored, &edits, cut), &h, grid, page, "m.smdb page") {
            prop_assert!(e.to_string().starts_with("m.smdb page"), "{}", e);
        }
    }

    #[test]
    fn mutated_chunks_decode_or_fail_cleanly(
        (edits, cut) in mutations(),
        index in 0usize..6,
        level in 0usize..4,
    ) {
        let (_, path, _) = valid();
        let reader = ArchiveReader::open(FileSource::open(path).unwrap()).unwrap();
        let h = reader.header().clone();
        let (s, t) = (h.tile_size as usize, h.texture_size as usize);
        let id = TileId::new(index as u32 % h.tiles_x, index as u32 / h.tiles_x);
        let good = reader.read_levels(id, 0..h.levels()).unwrap().chunks;
        // Stored bytes mutated, then decompressed.
        let (entry, _) = reader.entry(id, &CancelToken::new()).unwrap();
        let (offset, len) = entry.range(level..level + 1);
        let stored = std::fs::read(path).unwrap();
        let at = offset as usize;
        let chunk = mutate(&stored[at..at + len as usize], &edits, cut);
        if let Ok(raw) = decompress(&chunk, h.codec, h.level_payload_size(level), "m") {
            check_decodes(&good, level, &raw, s, t);
        }
        // Raw chunk bytes mutated.
        check_decodes(&good, level, &mutate(&good[level], &edits, cut), s, t);
    }

    #[test]
    fn arbitrary_chunks_never_panic_and_errors_name_the_file(
        chunks in proptest::collection::vec(proptest::collection::vec(any::<u8>(), 0..600), 0..5),
        size in prop_oneof![Just((3usize, 1usize)), Just((5, 2)), Just((9, 8)), Just((9, 16))],
    ) {
        let (s, t) = size;
        let refs: Vec<&[u8]> = chunks.iter().map(Vec::as_slice).collect();
        if let Err(e) = Tile::from_levels(&refs, s, t, "arbitrary.smdb tile 7") {
            prop_assert!(e.to_string().starts_with("arbitrary.smdb tile 7: "), "{}", e);
        }
    }
}

/// Decodes the good chunks with chunk `level` replaced by `raw`, both at once and by
/// refinement; either succeeds or fails with an error naming the file, and both agree.
fn check_decodes(good: &[Vec<u8>], level: usize, raw: &[u8], s: usize, t: usize) {
    let mut chunks: Vec<&[u8]> = good.iter().map(Vec::as_slice).collect();
    chunks[level] = raw;
    let whole = Tile::from_levels(&chunks, s, t, "m tile");
    let refined = Tile::from_levels(&chunks[..1], s, t, "m tile").and_then(|mut tile| {
        for chunk in &chunks[1..] {
            tile.refine(chunk, "m tile")?;
        }
        Ok(tile)
    });
    match (whole, refined) {
        (Ok(a), Ok(b)) => assert_eq!(a, b),
        (Err(a), Err(b)) => {
            assert!(a.to_string().starts_with("m tile: "), "{a}");
            assert_eq!(a.to_string(), b.to_string());
        }
        (a, b) => panic!("from_levels {a:?} but refine {b:?}"),
    }
}
