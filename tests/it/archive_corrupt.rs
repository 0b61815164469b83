//! Bad archives give errors that name the file and the problem, never a panic: a bad header,
//! directory, page table, index page, tile or top, a truncated or grown file.

use std::path::{Path, PathBuf};

use stripmask::Error;
use stripmask::db::archive::{ArchiveReader, HEADER_LEN, PAGE_SIDE, TABLE_CHUNK_ENTRIES, page_of};
use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{MemoryReader, NodataFill};
use stripmask::db::grid::TileId;
use stripmask::db::source::CancelToken;
use stripmask::db::source::file::FileSource;

/// A 257 x 257 model of noise in tiles of 17: 16 x 16 tiles at level 0, whose index pages and
/// payloads lie outside the top.
fn small_archive(dir: &Path) -> PathBuf {
    let (w, h) = (257, 257);
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

fn open(path: &Path) -> ArchiveReader<FileSource> {
    ArchiveReader::open(FileSource::open(path).unwrap()).unwrap()
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

/// Where level-0 tile `id`'s page table chunk and page lie: (chunk offset, entries in the
/// chunk, the page's slot in the chunk, page offset, page length).
fn page_of_tile(path: &Path, id: TileId) -> (usize, usize, usize, usize, usize) {
    let reader = open(path);
    let grid = reader.pyramid().grid(0);
    let slot = page_of(grid, id);
    let pages = (grid.tiles_x().div_ceil(PAGE_SIDE) * grid.tiles_y().div_ceil(PAGE_SIDE)) as usize;
    let per = TABLE_CHUNK_ENTRIES;
    let chunk = slot.page as usize / per;
    let chunk_offset = reader.directory().tables[0] as usize + chunk * (per * 16 + 4);
    let entries = (pages - chunk * per).min(per);
    let bytes = std::fs::read(path).unwrap();
    let at = chunk_offset + (slot.page as usize % per) * 16;
    let offset = u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap()) as usize;
    let len = u32::from_le_bytes(bytes[at + 8..at + 12].try_into().unwrap()) as usize;
    (chunk_offset, entries, slot.page as usize % per, offset, len)
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

    // Older archives (whole-tile payloads, no apron, no nodata record, no pyramid) are
    // refused with what to do about them.
    for version in [2, 4, 5, 6] {
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
    rewrite(&path, |b| b[8] = 6);
    assert!(open_err(&path).contains("no pyramid"));

    std::fs::write(&path, &good).unwrap();
    rewrite(&path, |b| b[20] ^= 1);
    let e = open_err(&path);
    assert!(e.contains("header checksum"), "{e}");
}

#[test]
fn truncated_files_and_a_corrupt_directory_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_archive(dir.path());
    let good = std::fs::read(&path).unwrap();

    std::fs::write(&path, &good[..50]).unwrap();
    let e = open_err(&path);
    assert!(e.contains("truncated header"), "{e}");

    std::fs::write(&path, &good[..HEADER_LEN + 20]).unwrap();
    let e = open_err(&path);
    assert!(e.contains("truncated archive"), "{e}");

    std::fs::write(&path, &good[..good.len() - 10]).unwrap();
    let e = open_err(&path);
    assert!(e.contains("truncated archive"), "{e}");

    std::fs::write(&path, &good).unwrap();
    rewrite(&path, |b| b[HEADER_LEN + 3] ^= 0x40);
    let e = open_err(&path);
    assert!(e.contains("directory checksum"), "{e}");
}

#[test]
fn a_corrupt_page_table_or_index_page_is_named_when_a_tile_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_archive(dir.path());
    let name = path.display().to_string();
    let good = std::fs::read(&path).unwrap();
    let id = TileId::new(9, 3);
    let (chunk, entries, _, page, _) = page_of_tile(&path, id);

    rewrite(&path, |b| b[chunk + 5] ^= 0x10);
    let reader = open(&path);
    let e = reader.tile(id).unwrap_err().to_string();
    assert!(
        e.contains(&name) && e.contains("page table chunk 0 of level 0") && e.contains("corrupt"),
        "{e}"
    );
    // The table chunk's bytes hold its entries and a crc32.
    assert!(entries * 16 + 4 <= good.len() - chunk);

    std::fs::write(&path, &good).unwrap();
    rewrite(&path, |b| b[page + 9] ^= 0x01);
    let reader = open(&path);
    let e = reader.tile(id).unwrap_err().to_string();
    assert!(
        e.contains(&name) && e.contains("index page") && e.contains("corrupt index page"),
        "{e}"
    );
    // Tiles of other pages still read.
    reader.tile(TileId::new(0, 15)).unwrap().unwrap();
}

#[test]
fn a_tile_whose_bytes_changed_fails_its_checksum_and_others_still_read() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_archive(dir.path());
    let reader = open(&path);
    let check = reader.check().unwrap();
    assert_eq!(
        (check.tiles, check.absent),
        (reader.pyramid().tile_count(), 0)
    );
    let id = TileId::new(1, 0);
    let (entry, _) = reader.entry(id, &CancelToken::new()).unwrap();
    // A byte of the tile's level-2 chunk.
    let (offset, _) = entry.range(2..3);
    drop(reader);
    rewrite(&path, |b| b[offset as usize + 1] ^= 0xff);
    let reader = open(&path);
    match reader.tile(id) {
        Err(Error::Checksum {
            tile,
            level,
            attempts,
            ..
        }) => {
            assert_eq!((tile.as_str(), level), ("tile (1, 0)", 2));
            assert_eq!(attempts, 4);
        }
        other => panic!("expected a checksum error, got {other:?}"),
    }
    let msg = reader.tile(id).unwrap_err().to_string();
    assert!(
        msg.contains(&path.display().to_string()) && msg.contains("tile (1, 0) level 2"),
        "{msg}"
    );
    // The levels before the corrupt chunk still read: a coarser tile is still there.
    let (coarse, _) = reader.tile_levels(id, 2).unwrap();
    assert_eq!(coarse.unwrap().levels, 2);
    assert!(reader.read_levels(id, 3..5).is_ok());
    assert!(reader.read_levels(id, 1..3).is_err());
    for (tx, ty) in [(0, 0), (0, 1), (1, 1)] {
        reader.tile(TileId::new(tx, ty)).unwrap();
    }
    assert!(
        matches!(reader.check(), Err(Error::Checksum { tile, .. }) if tile == "tile (1, 0)"),
        "checking the whole archive stops at the corrupt tile"
    );
}

#[test]
fn a_changed_byte_of_the_top_fails_its_checksum_by_tile_and_level() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_archive(dir.path());
    let reader = open(&path);
    let (offset, len) = (reader.header().top_offset, reader.header().top_len);
    let last = reader.directory().top.last().unwrap().0;
    drop(reader);
    // The last byte of the top is its last tile's finest chunk.
    rewrite(&path, |b| b[(offset + len) as usize - 1] ^= 0x5a);
    let reader = open(&path);
    let levels = reader.header().levels();
    match reader.top() {
        Err(Error::Checksum { tile, level, .. }) => {
            assert_eq!((tile, level), (last.to_string(), levels - 1));
        }
        other => panic!("expected a checksum error, got {other:?}"),
    }
}

#[test]
fn index_entries_that_share_bytes_are_refused_when_their_page_is_read() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_archive(dir.path());
    let name = path.display().to_string();
    let id = TileId::new(2, 2);
    let (chunk, entries, slot, page, len) = page_of_tile(&path, id);
    let entry = len / (PAGE_SIDE * PAGE_SIDE) as usize;
    // Every tile of the page pointing at its first tile's payload, the page's crc32 and the
    // table chunk's valid: each entry alone passes, together they would decode one payload
    // once per tile.
    rewrite(&path, |b| {
        let first = b[page..page + entry].to_vec();
        for k in 1..len / entry {
            b[page + k * entry..page + (k + 1) * entry].copy_from_slice(&first);
        }
        let crc = crc32fast::hash(&b[page..page + len]);
        let at = chunk + slot * 16 + 12;
        b[at..at + 4].copy_from_slice(&crc.to_le_bytes());
        let refs = entries * 16;
        let crc = crc32fast::hash(&b[chunk..chunk + refs]);
        b[chunk + refs..chunk + refs + 4].copy_from_slice(&crc.to_le_bytes());
    });
    let reader = open(&path);
    let e = reader.tile(id).unwrap_err().to_string();
    assert!(e.contains(&name) && e.contains("overlap"), "{e}");
}

#[test]
fn bytes_appended_to_an_archive_fail_its_check_but_not_its_reading() {
    let dir = tempfile::tempdir().unwrap();
    let path = small_archive(dir.path());
    let name = path.display().to_string();
    let reader = open(&path);
    reader.check().unwrap();
    drop(reader);
    rewrite(&path, |b| b.extend_from_slice(b"appended junk"));
    let reader = open(&path);
    reader.tile(TileId::new(0, 0)).unwrap();
    let e = reader.check().unwrap_err().to_string();
    assert!(
        e.contains(&name) && e.contains("13 bytes after the archive's end"),
        "{e}"
    );
}
