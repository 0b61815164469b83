//! Property-based fuzzing of the archive reader: random and mutated headers, indexes and
//! progressive tile chunks must give `Err` naming the file, never a panic.
//! `PROPTEST_CASES=100000` runs a long campaign.

use std::path::PathBuf;
use std::sync::OnceLock;

use proptest::prelude::*;
use stripmask::db::archive::{ArchiveReader, HEADER_LEN, Header, decompress, parse_index};
use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{MemoryReader, NodataFill};
use stripmask::db::source::file::FileSource;
use stripmask::db::tile::{Tile, progressive_levels};
use stripmask::engine::terrain::TerrainFrame;
use stripmask::sim::flight::{Builtin, Flight};
use stripmask::{Error, Named};

fn cases() -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(64)
}

/// A valid 4 x 2-tile archive, built once.
fn valid() -> &'static (tempfile::TempDir, PathBuf, Vec<u8>) {
    static VALID: OnceLock<(tempfile::TempDir, PathBuf, Vec<u8>)> = OnceLock::new();
    VALID.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let (w, h) = (33, 17);
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

/// Restores the header and index checksums after an edit, so the edit reaches the validation
/// behind them.
fn fix_checksums(b: &mut [u8]) {
    if b.len() < HEADER_LEN {
        return;
    }
    let crc = crc32fast::hash(&b[..HEADER_LEN - 4]);
    b[HEADER_LEN - 4..HEADER_LEN].copy_from_slice(&crc.to_le_bytes());
    let field = |k: usize| u32::from_le_bytes(b[k..k + 4].try_into().unwrap()) as usize;
    let tiles = field(16) * field(20);
    let entry_len = 8 + 8 * progressive_levels(field(24).min(1 << 20));
    let end = HEADER_LEN + tiles.min(1 << 20) * entry_len;
    if end + 4 <= b.len() {
        let crc = crc32fast::hash(&b[HEADER_LEN..end]);
        b[end..end + 4].copy_from_slice(&crc.to_le_bytes());
    }
}

fn read_everything(bytes: &[u8]) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("m.smdb");
    std::fs::write(&path, bytes).unwrap();
    if let Ok(reader) = ArchiveReader::open_with_attempts(FileSource::open(&path).unwrap(), 1) {
        let h = reader.header().clone();
        for ty in 0..h.tiles_y as usize {
            for tx in 0..h.tiles_x as usize {
                let _ = reader.tile(tx, ty);
                let _ = reader.tile_levels(tx, ty, 1);
                let _ = reader.read_levels(tx, ty, 1..h.levels());
            }
        }
    }
}

/// The header's numbers: (offset, width in bytes) of spacing, vertical scale, origin x and y
/// (f64), min and max height and the height quantum (f32).
const NUMBERS: [(usize, usize); 7] = [
    (48, 8),
    (56, 8),
    (64, 8),
    (72, 8),
    (80, 4),
    (84, 4),
    (88, 4),
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
        bytes[92..100].copy_from_slice(&filled.to_le_bytes());
        bytes[100..108].copy_from_slice(&flattened.to_le_bytes());
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
                prop_assert!(u128::from(filled) + u128::from(flattened) > 33 * 17);
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
    fn mutated_headers_and_indexes_parse_or_fail_cleanly((edits, cut) in mutations()) {
        let (_, _, good) = valid();
        // 9-sample tiles: 4 levels, 40-byte entries.
        let header_and_index = &good[..HEADER_LEN + 8 * 40 + 4];
        let mut bytes = mutate(header_and_index, &edits, cut);
        fix_checksums(&mut bytes);
        if let Ok(h) = Header::parse(&bytes, "m") {
            let _ = parse_index(&bytes[HEADER_LEN.min(bytes.len())..], &h, Some(good.len() as u64), "m");
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
        let (x, y) = (index % h.tiles_x as usize, index / h.tiles_x as usize);
        let good = reader.read_levels(x, y, 0..h.levels()).unwrap().chunks;
        // Stored bytes mutated, then decompressed.
        let stored = reader.tile_bytes(index).unwrap();
        let (offset, len) = reader.level_range(x, y, level..level + 1);
        let at = (offset - reader.level_range(x, y, 0..0).0) as usize;
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
