//! The pager over a real archive: a synthetic DEM built into `.smdb`, read through `FileSource`
//! and `ArchiveReader` by a loader that keeps coarser texture mips for farther belts.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use stripmask::db::archive::{ArchiveReader, Codec};
use stripmask::db::builder::BuildOptions;
use stripmask::db::grid::TileId;
use stripmask::db::grid::{Grid, Pyramid};
use stripmask::db::source::CancelToken;
use stripmask::db::source::file::FileSource;
use stripmask::db::tile::Tile;
use stripmask::engine::paging::{
    BeltPager, PagerConfig, PagerMode, ResidentLoader, TileLoader, TileState,
};

use crate::support::hills::synthetic;

/// Builds an 8 x 6 tile archive of 17-sample tiles (129 x 97 samples) with 16-texel textures.
fn build_archive(dir: &Path) -> PathBuf {
    let options = BuildOptions {
        tile_size: 17,
        spacing: Some(30.0),
        codec: Codec::Lz4,
        ..BuildOptions::default()
    };
    synthetic(dir, "pager", (129, 97), &options, |i, j| {
        let (i, j) = (i as f32, j as f32);
        800.0 + 200.0 * (i * 0.11).sin() * (j * 0.05).cos() + i - 0.5 * j
    })
}

/// Decodes tiles and keeps texture mips from level `ring - 1` down (all of them in belts 0 and
/// 1, at least the 1 x 1 one), counting 2 bytes per height and per texel.
struct ArchiveLoader {
    reader: ArchiveReader<FileSource>,
}

impl ArchiveLoader {
    fn mips(&self) -> usize {
        self.reader.header().texture_size.ilog2() as usize + 1
    }

    /// The first mip level kept at `ring`.
    fn first_mip(&self, ring: u32) -> usize {
        (ring as usize).saturating_sub(1).min(self.mips() - 1)
    }
}

impl ResidentLoader for ArchiveLoader {
    type Loaded = Tile;

    fn loaded_bytes(&self, tile: &Tile) -> usize {
        2 * tile.heights.len() + 2 * tile.texture_mips.iter().map(Vec::len).sum::<usize>()
    }
}

impl TileLoader for ArchiveLoader {
    fn predicted_bytes(&self, _: TileId, ring: u32) -> usize {
        let h = self.reader.header();
        let (s, t) = (h.tile_size as usize, h.texture_size as usize);
        let texels: usize = (self.first_mip(ring)..self.mips())
            .map(|l| (t >> l) * (t >> l))
            .sum();
        2 * s * s + 2 * texels
    }

    fn load(&self, id: TileId, ring: u32) -> stripmask::Result<(Tile, u64)> {
        let (tile, stored) = self.reader.tile_levels(id, self.reader.header().levels())?;
        let mut tile = tile.expect("no tile of this archive is absent");
        tile.texture_mips.drain(..self.first_mip(ring));
        Ok((tile, stored))
    }

    fn shrink(&self, tile: &mut Tile, ring: u32) -> usize {
        let drop = tile.texture_mips.len() - (self.mips() - self.first_mip(ring));
        tile.texture_mips.drain(..drop);
        self.loaded_bytes(tile)
    }
}

fn open(path: &Path) -> ArchiveLoader {
    ArchiveLoader {
        reader: ArchiveReader::open(FileSource::open(path).unwrap()).unwrap(),
    }
}

fn grid_of(loader: &ArchiveLoader) -> Pyramid {
    loader.reader.pyramid().clone()
}

#[test]
fn a_stepped_pager_fills_the_largest_square_that_fits_from_an_archive() {
    let dir = tempfile::tempdir().unwrap();
    let path = build_archive(dir.path());
    let loader = open(&path);
    let h = loader.reader.header().clone();
    assert_eq!(
        (h.tiles_x, h.tiles_y, h.tile_size, h.texture_size),
        (8, 6, 17, 16)
    );
    // 17^2 heights = 578 bytes; texture mips of 256, 64, 16, 4, 1 texels.
    let cost: Vec<usize> = (0..4)
        .map(|r| loader.predicted_bytes(TileId::new(0, 0), r))
        .collect();
    assert_eq!(cost, [578 + 682, 578 + 682, 578 + 170, 578 + 42]);
    // Around (3, 3): belts 0..=2 are 9 near tiles and 16 at ring 2 (23,308 bytes); belt 3 adds
    // 17 tiles at 620 (33,848 in all).
    let grid = grid_of(&loader);
    let c = TileId::new(3, 3);
    let limit = 30_000;
    let mut pager = BeltPager::new(
        loader,
        grid,
        PagerConfig::new(
            limit,
            PagerMode::Stepped {
                fetches_per_update: 4,
            },
        ),
    )
    .unwrap();
    for _ in 0..20 {
        pager.update((3.5, 3.5));
        assert!(pager.resident().stats().memory_bytes <= limit);
    }
    let s = pager.resident().stats();
    assert_eq!(s.complete_belts, Some(2));
    assert!(s.memory_bound);
    assert_eq!((s.loaded_tiles, s.memory_bytes, s.errors), (25, 23_308, 0));
    let check = open(&path);
    let mut downloaded = 0;
    for (id, tile) in pager.resident().tiles() {
        let ring = Grid::ring(c, id);
        assert_eq!(pager.resident().state(id), TileState::Square);
        assert_eq!(
            pager.loader().loaded_bytes(tile),
            pager.loader().predicted_bytes(id, ring)
        );
        let truth = check.reader.tile(id).unwrap().unwrap();
        assert_eq!(tile.heights, truth.heights, "{id}");
        assert_eq!(
            tile.texture_mips[..],
            truth.texture_mips[ring.saturating_sub(1) as usize..]
        );
        let (entry, _) = check.reader.entry(id, &CancelToken::new()).unwrap();
        downloaded += entry.stored_len();
    }
    // The tiles' bytes, and the index pages read to find them (none for the tiles of the top,
    // which the directory lists).
    let index = pager.loader().reader.index_bytes_read();
    assert_eq!(s.downloaded_bytes, downloaded + index);
    // One tile west: belt 2 around (2, 3) misses the column x = 0; tiles leaving belt 1 shrink.
    for _ in 0..20 {
        pager.update((2.5, 3.5));
        assert!(pager.resident().stats().memory_bytes <= limit);
    }
    assert_eq!(pager.resident().stats().complete_belts, Some(2));
    let shrunk = pager.resident().get(TileId::new(4, 3)).unwrap();
    assert_eq!(shrunk.texture_mips.len(), 4);
    let upgraded = pager.resident().get(TileId::new(1, 3)).unwrap();
    assert_eq!(upgraded.texture_mips.len(), 5);
}

#[test]
fn a_threaded_pager_flies_the_archive_corner_to_corner_within_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let path = build_archive(dir.path());
    let loader = open(&path);
    let grid = grid_of(&loader);
    let limit = 16_000;
    let mut pager = BeltPager::new(
        loader,
        grid,
        PagerConfig::new(limit, PagerMode::Threaded { queue_depth: 3 }),
    )
    .unwrap();
    // Corners hold belts 0..=3 in 4 near tiles, 5 at ring 2 and 7 at ring 3 (13,120 bytes);
    // belt 4 would add 9 tiles at 588 (18,412 in all).
    settle(&mut pager, (0.5, 0.5));
    for k in 0..=200 {
        let t = f64::from(k) / 200.0;
        pager.update((0.5 + 7.0 * t, 0.5 + 5.0 * t));
        let s = pager.resident().stats();
        assert!(
            s.memory_bytes <= limit && s.memory_peak_bytes <= limit,
            "{s:?}"
        );
        std::thread::sleep(Duration::from_millis(1));
    }
    settle(&mut pager, (7.5, 5.5));
    let s = pager.resident().stats();
    assert_eq!(s.errors, 0, "{:?}", pager.resident().last_error());
    assert!(s.memory_bound);
    // Both corners' 16 tiles were fetched (however far the fetch thread kept up in between),
    // and the first corner's had to leave to make room for the second's.
    assert!(s.fetches >= 32 && s.evictions >= 16, "{s:?}");
    assert!(s.memory_peak_bytes <= limit);
}

/// Updates the pager at `eye` until belts 0..=3 are complete and nothing is in flight.
fn settle<L: TileLoader>(pager: &mut BeltPager<L>, eye: (f64, f64)) {
    let start = Instant::now();
    while pager.resident().stats().complete_belts != Some(3)
        || pager.resident().stats().fetching > 0
    {
        assert!(
            start.elapsed() < Duration::from_secs(20),
            "{:?}",
            pager.resident().stats()
        );
        pager.update(eye);
        std::thread::sleep(Duration::from_millis(1));
    }
}
