//! Bad archives give errors that name the file and the problem, never a panic.

use std::path::{Path, PathBuf};

use stripmask::Error;
use stripmask::db::archive::{ArchiveReader, HEADER_LEN, base_range, index_to_bytes};
use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{MemoryReader, NodataFill};
use stripmask::db::source::file::FileSource;

fn small_archive(dir: &Path) -> PathBuf {
    let (w, h) = (33, 33);
    let samples = (0..w * h).map(|k| ((k * 7919) % 1000) as f32).collect();
    let reader = MemoryReader::new("noise", w, h, samples).unwrap();
    let out = dir.join("small.smdb");
    let options = BuildOptions {
        tile_size: 17,
        ..BuildOptions::default()
    };
    build(NodataFill::new(reader, None), &out, &options, &|_, _| {}).unwrap();
    out
}

fn open_err(path: &Path) -> String {
    match ArchiveReader::open(FileSource::open(path).unwrap()) {
        Ok(_) => panic!("{} opened", path.display()),
        Err(e) => e.to_string(),
    }
}

fn rewrite(path: &Path, f: impl FnOnce(&mut Vec<u8>)) {
    let mut bytes = std::fs::read(path).unwrap();
    f(&mut bytes);
    std::fs::write(path, bytes).unwrap();
}

#[test]
fn bad_magic_wrong_version_and_corrupt_header_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_archive(dir.path());
    let name = path.display().to_string();
    let good = std::fs::read(&path).unwrap();

    rewrite(&path, |b| b[0] = b'X');
    let e = open_err(&path);
    assert!(e.contains(&name) && e.contains("bad magic"), "{e}");

    std::fs::write(&path, &good).unwrap();
    rewrite(&path, |b| b[8] = 9);
    let e = open_err(&path);
    assert!(e.contains(&name) && e.contains("version 9"), "{e}");

    // Older archives (whole-tile payloads, no apron, no nodata record) are refused with what
    // to do about them.
    for version in [2, 4, 5] {
        std::fs::write(&path, &good).unwrap();
        rewrite(&path, |b| b[8] = version);
        let e = open_err(&path);
        assert!(
            e.contains(&name)
                && e.contains(&format!("archive version {version}"))
                && e.contains("stripmask build"),
            "{e}"
        );
    }

    std::fs::write(&path, &good).unwrap();
    rewrite(&path, |b| b[20] ^= 1);
    let e = open_err(&path);
    assert!(e.contains("header checksum"), "{e}");
}

#[test]
fn truncated_files_and_corrupt_index_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_archive(dir.path());
    let good = std::fs::read(&path).unwrap();

    std::fs::write(&path, &good[..50]).unwrap();
    let e = open_err(&path);
    assert!(e.contains("truncated"), "{e}");

    std::fs::write(&path, &good[..HEADER_LEN + 20]).unwrap();
    let e = open_err(&path);
    assert!(e.contains("truncated index"), "{e}");

    std::fs::write(&path, &good).unwrap();
    rewrite(&path, |b| b[HEADER_LEN + 3] ^= 0x40);
    let e = open_err(&path);
    assert!(e.contains("index checksum"), "{e}");

    // Cut inside the base, which follows the payloads.
    std::fs::write(&path, &good[..good.len() - 10]).unwrap();
    let e = open_err(&path);
    assert!(e.contains("truncated base"), "{e}");

    // Cut inside the payloads: the index now points past the end.
    std::fs::write(&path, &good).unwrap();
    let reader = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
    let payload_end = reader
        .index()
        .iter()
        .map(|e| e.offset + e.stored_len())
        .max()
        .unwrap();
    drop(reader);
    std::fs::write(&path, &good[..payload_end as usize - 10]).unwrap();
    let e = open_err(&path);
    assert!(e.contains("points outside"), "{e}");
}

#[test]
fn a_tile_whose_bytes_changed_fails_its_checksum_and_others_still_read() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_archive(dir.path());
    let reader = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
    let check = reader.check().unwrap();
    let stored: u64 = reader.index().iter().map(|e| e.stored_len()).sum();
    let (_, base) = base_range(reader.index(), reader.header().base_levels as usize);
    assert!(base > 0);
    assert_eq!(
        (check.tiles, check.bytes),
        (reader.index().len(), stored + base)
    );
    // A byte of tile 1's level-2 chunk.
    let (offset, _) = reader.level_range(1, 0, 2..3);
    drop(reader);
    rewrite(&path, |b| b[offset as usize + 1] ^= 0xff);
    let reader = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
    match reader.tile(1, 0) {
        Err(Error::Checksum {
            tile,
            level,
            attempts,
            ..
        }) => {
            assert_eq!((tile, level), (1, 2));
            assert_eq!(attempts, 4);
        }
        other => panic!("expected a checksum error, got {other:?}"),
    }
    let msg = reader.tile(1, 0).unwrap_err().to_string();
    assert!(
        msg.contains(&path.display().to_string()) && msg.contains("tile 1 level 2"),
        "{msg}"
    );
    // The levels before the corrupt chunk still read: a coarser tile 1 is still there.
    let (coarse, _) = reader.tile_levels(1, 0, 2).unwrap();
    assert_eq!(coarse.levels, 2);
    assert!(reader.read_levels(1, 0, 3..5).is_ok());
    assert!(reader.read_levels(1, 0, 1..3).is_err());
    for (tx, ty) in [(0, 0), (0, 1), (1, 1)] {
        reader.tile(tx, ty).unwrap();
    }
    assert!(
        matches!(reader.check(), Err(Error::Checksum { tile: 1, .. })),
        "checking the whole archive stops at the corrupt tile"
    );
}

#[test]
fn a_changed_byte_of_the_base_fails_its_checksum_by_tile_and_level() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_archive(dir.path());
    let len = std::fs::metadata(&path).unwrap().len() as usize;
    // The last byte of the file is the last tile's base chunk.
    rewrite(&path, |b| b[len - 1] ^= 0x5a);
    let reader = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
    let last = reader.index().len() - 1;
    match reader.base() {
        Err(Error::Checksum { tile, level, .. }) => assert_eq!((tile, level), (last, 0)),
        other => panic!("expected a checksum error, got {other:?}"),
    }
    // The tile's own chunk, in the payloads, is intact.
    let x = last % reader.header().tiles_x as usize;
    let y = last / reader.header().tiles_x as usize;
    assert!(reader.tile(x, y).is_ok());
}

#[test]
fn index_entries_that_share_bytes_are_refused_on_open() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_archive(dir.path());
    let name = path.display().to_string();
    let reader = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
    let header = reader.header().clone();
    let mut index = reader.index().to_vec();
    drop(reader);
    // Every tile pointing at tile 0's payload, checksums and the index's crc32 all valid: each
    // entry alone passes, together they would decode one payload once per tile.
    let first = index[0].clone();
    index.iter_mut().for_each(|e| *e = first.clone());
    let bytes = index_to_bytes(&index);
    rewrite(&path, |b| {
        b[HEADER_LEN..HEADER_LEN + bytes.len()].copy_from_slice(&bytes)
    });
    let e = open_err(&path);
    assert!(
        e.contains(&name) && e.contains("index entries 0 and 1 overlap"),
        "{e}"
    );
    assert_eq!(header.index_len(), bytes.len());
}

#[test]
fn bytes_appended_to_an_archive_fail_its_check_but_not_its_reading() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_archive(dir.path());
    let name = path.display().to_string();
    let reader = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
    reader.check().unwrap();
    drop(reader);
    rewrite(&path, |b| b.extend_from_slice(b"appended junk"));
    let reader = ArchiveReader::open(FileSource::open(&path).unwrap()).unwrap();
    reader.tile(0, 0).unwrap();
    let e = reader.check().unwrap_err().to_string();
    assert!(
        e.contains(&name) && e.contains("13 bytes after the archive's end"),
        "{e}"
    );
}
