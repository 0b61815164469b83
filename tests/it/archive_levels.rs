//! Progressive levels through the archive: any range of a tile's levels reads back in one source
//! read once its index page is held, decodes to exactly the coarser tile, and is located in
//! O(1) by the index.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};

use stripmask::Result;
use stripmask::db::archive::{ArchiveReader, Codec};
use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{MemoryReader, NodataFill};
use stripmask::db::grid::TileId;
use stripmask::db::source::file::FileSource;
use stripmask::db::source::{CancelToken, TileSource};
use stripmask::db::tile::Tile;

/// A source that counts its range reads and the bytes they return.
struct Counting {
    inner: FileSource,
    reads: Arc<AtomicUsize>,
    bytes: Arc<AtomicUsize>,
}

impl TileSource for Counting {
    fn name(&self) -> &str {
        self.inner.name()
    }
    fn size(&self) -> Result<u64> {
        self.inner.size()
    }
    fn read_range(&self, offset: u64, len: u64) -> Result<Vec<u8>> {
        self.reads.fetch_add(1, Ordering::SeqCst);
        self.bytes.fetch_add(len as usize, Ordering::SeqCst);
        self.inner.read_range(offset, len)
    }
}

/// A 3 x 2-tile archive of 17-sample tiles (5 levels), `factor` texels per grid cell.
fn archive(dir: &Path, codec: Codec, factor: usize) -> PathBuf {
    let (w, h) = (49, 33);
    let samples = (0..w * h)
        .map(|k| {
            let (i, j) = ((k % w) as f32, (k / w) as f32);
            500.0 + 200.0 * (i * 0.3).sin() * (j * 0.2).cos() + ((k * 7919) % 13) as f32
        })
        .collect();
    let reader = MemoryReader::new("levels", w, h, samples).unwrap();
    let out = dir.join(format!("levels-{codec:?}-{factor}.smdb"));
    let options = BuildOptions {
        tile_size: 17,
        texture_factor: factor,
        codec,
        ..BuildOptions::default()
    };
    build(NodataFill::new(reader, None), &out, &options, &|_, _| {}).unwrap();
    out
}

/// The reader, and counters of its source's reads and bytes read.
fn open(path: &Path) -> (ArchiveReader<Counting>, Arc<AtomicUsize>, Arc<AtomicUsize>) {
    let source = Counting {
        inner: FileSource::open(path).unwrap(),
        reads: Arc::default(),
        bytes: Arc::default(),
    };
    let (reads, bytes) = (source.reads.clone(), source.bytes.clone());
    (ArchiveReader::open(source).unwrap(), reads, bytes)
}

#[test]
fn every_level_range_reads_back_in_one_request_and_decodes_to_the_coarser_tile() {
    let dir = tempfile::tempdir().unwrap();
    for (codec, factor) in [(Codec::Lz4, 1), (Codec::None, 2), (Codec::Deflate, 1)] {
        let path = archive(dir.path(), codec, factor);
        let (reader, reads, bytes) = open(&path);
        let count = || (reads.load(Ordering::SeqCst), bytes.load(Ordering::SeqCst));
        let h = reader.header().clone();
        let (s, t, levels) = (h.tile_size as usize, h.texture_size as usize, h.levels());
        assert_eq!(levels, 5);
        for y in 0..h.tiles_y {
            for x in 0..h.tiles_x {
                let id = TileId::new(x, y);
                let (entry, _) = reader.entry(id, &CancelToken::new()).unwrap();
                let full = reader.tile(id).unwrap().unwrap();
                let all = reader.read_levels(id, 0..levels).unwrap().chunks;
                for a in 0..=levels {
                    for b in a..=levels {
                        let before = count();
                        let got = reader.read_levels(id, a..b).unwrap();
                        let after = count();
                        assert_eq!(after.0 - before.0, 1, "one read for {a}..{b}");
                        let (offset, length) = entry.range(a..b);
                        assert_eq!(after.1 - before.1, length as usize);
                        assert_eq!(got.stored_bytes, length);
                        assert_eq!(got.chunks[..], all[a..b], "{codec:?} ({x}, {y}) {a}..{b}");
                        // Neighbouring ranges abut: the index is one contiguous run per tile.
                        let (before, len) = entry.range(0..a);
                        assert_eq!(before + len, offset);
                    }
                }
                for k in 1..=levels {
                    let (tile, stored) = reader.tile_levels(id, k).unwrap();
                    let tile = tile.unwrap();
                    assert_eq!(tile, full.truncated(k), "{codec:?} ({x}, {y}) {k} levels");
                    assert_eq!(stored, entry.range(0..k).1);
                    // Refining a prefix with the next chunk gives the next prefix.
                    if let Some(next) = all.get(k) {
                        let mut refined = tile.clone();
                        refined.refine(next, "r").unwrap();
                        assert_eq!(refined, full.truncated(k + 1));
                    }
                }
                let chunks: Vec<&[u8]> = all.iter().map(Vec::as_slice).collect();
                assert_eq!(Tile::from_levels(&chunks, s, t, "f").unwrap(), full);
            }
        }
    }
}

#[test]
fn bad_level_requests_are_named_errors() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), Codec::Lz4, 1);
    let (reader, _, _) = open(&path);
    let name = path.display().to_string();
    let e = reader
        .read_levels(TileId::new(0, 0), 2..6)
        .unwrap_err()
        .to_string();
    assert!(e.contains(&name) && e.contains("outside 0..5"), "{e}");
    let e = reader
        .read_levels(TileId::new(3, 0), 0..1)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&name) && e.contains("outside level 0's 3 x 2 grid"),
        "{e}"
    );
    let e = reader
        .read_levels(TileId::at(5, 0, 0), 0..1)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains(&name) && e.contains("level 5 does not exist"),
        "{e}"
    );
    let e = reader
        .tile_levels(TileId::new(0, 0), 0)
        .unwrap_err()
        .to_string();
    assert!(e.contains(&name) && e.contains("no levels"), "{e}");
}
