//! Crack-free tiles by construction: an interior per level and border bands per (side, own
//! level, neighbour level), shared by every tile like the strip masks.
//!
//! Level `l` keeps the grid indices `K = kept(l)` (see [`crate::db::mask_level`]). Its *inner
//! rectangle* runs from the first to the last inner kept index, `K[1] ..= K[k - 2]`, in both
//! directions. The *interior* is the kept grid strictly inside it, every cell split along its
//! north-west to south-east diagonal as the masks split it. The band between a side of the tile
//! and the inner rectangle is the *border*: its outer chain is `E = kept(l) ∩ kept(ln)` along the
//! edge, corner to corner, where `ln` is the neighbour's level; the inner chain is `K[1 ..= k -
//! 2]` along the inner rectangle's side. The intersection is symmetric, so the tile on the other
//! side of the edge, drawn with the levels swapped, uses the same edge vertices: no T-junction,
//! no crack. The two chains are zipped, advancing at each step the chain whose next vertex comes
//! first along the side; both are monotone on parallel lines, so every merge is a triangulation,
//! and the corners are split along the diagonal from the tile corner to the inner corner.
//!
//! Degenerate levels: with 3 kept indices per side the inner rectangle is the single inner
//! sample, and each side fans from it; with 2 (the corners only) every edge is a single segment
//! whatever the neighbours, and the tile is the mask's two triangles, given to the north and
//! south sides.
//!
//! Everything is a triangle list (`Topology::TriangleList`), wound as the masks are: clockwise
//! seen from above. Against a neighbour at its own level a tile has exactly its mask's triangle
//! count; against any other level, `|kept(l)| - |E|` fewer on that side.

use std::sync::OnceLock;

use super::{Side, clear, extend};
use crate::db::mask_level::{keeps_index, kept_indices, level_count};
use crate::engine::masks::MaskIndices;

/// The four sides of one level against one neighbour level, in [`Side::ALL`] order.
type Borders = [MaskIndices; 4];

/// The stitched pieces of every tile of one size, built lazily.
///
/// `Sync`: share one by reference; a piece is built once even when several threads ask for it.
#[derive(Debug)]
pub struct StitchSet {
    tile_size: usize,
    /// One interior per level.
    interiors: Vec<OnceLock<MaskIndices>>,
    /// `borders[l][ln]`: the four sides of level `l` against a neighbour at `ln`; a row is
    /// allocated the first time level `l` is drawn.
    borders: Vec<OnceLock<Box<[OnceLock<Borders>]>>>,
}

impl StitchSet {
    /// The pieces of tiles with `tile_size` samples per side (2 ..= 65,535).
    pub fn new(tile_size: usize) -> StitchSet {
        assert!(
            (2..=65_535).contains(&tile_size),
            "stitched tiles need 2 to 65535 samples per side, not {tile_size}"
        );
        let levels = level_count(tile_size);
        StitchSet {
            tile_size,
            interiors: (0..levels).map(|_| OnceLock::new()).collect(),
            borders: (0..levels).map(|_| OnceLock::new()).collect(),
        }
    }

    /// The interior triangles of `level`, built on first use.
    pub fn interior(&self, level: usize) -> &MaskIndices {
        self.interiors[level].get_or_init(|| interior(self.tile_size, level))
    }

    /// The border triangles of `level` on `side` against a neighbour at `neighbour`, built on
    /// first use.
    pub fn border(&self, side: Side, level: usize, neighbour: usize) -> &MaskIndices {
        let row = self.borders[level]
            .get_or_init(|| (0..self.borders.len()).map(|_| OnceLock::new()).collect());
        &row[neighbour].get_or_init(|| borders(self.tile_size, level, neighbour))[side as usize]
    }

    /// Writes into `out` (emptied first) the triangle list of a tile at `level` whose neighbours
    /// are at `neighbours` (in [`Side::ALL`] order): its interior and its four borders.
    pub fn tile(&self, level: usize, neighbours: [usize; 4], out: &mut MaskIndices) {
        clear(out);
        extend(out, self.interior(level));
        for side in Side::ALL {
            extend(out, self.border(side, level, neighbours[side as usize]));
        }
    }

    /// An empty buffer of the width [`StitchSet::tile`] writes.
    pub fn buffer(&self) -> MaskIndices {
        MaskIndices::narrowest(self.tile_size * self.tile_size, Vec::new())
    }

    #[cfg(test)]
    /// Triangles of a tile at `level` with `neighbours` (closed form; nothing is built).
    fn triangle_count(&self, level: usize, neighbours: [usize; 4]) -> usize {
        let s = self.tile_size;
        let k = kept_indices(s, level).len();
        if k == 2 {
            return 2;
        }
        let interior = 2 * k.saturating_sub(3).pow(2);
        let sides: usize = neighbours
            .iter()
            .map(|&ln| shared_edge(s, level, ln).len() - 1 + (k - 3))
            .sum();
        interior + sides
    }
}

/// The kept indices of `level` that `neighbour` keeps too: the shared edge's vertices.
fn shared_edge(s: usize, level: usize, neighbour: usize) -> Vec<usize> {
    kept_indices(s, level)
        .into_iter()
        .filter(|&t| keeps_index(s, neighbour, t))
        .collect()
}

fn interior(s: usize, level: usize) -> MaskIndices {
    let kept = kept_indices(s, level);
    let inner = &kept[1..kept.len() - 1];
    let v = |i: usize, j: usize| j * s + i;
    let mut out = Vec::new();
    for j in inner.windows(2) {
        for i in inner.windows(2) {
            let (nw, ne) = (v(i[0], j[0]), v(i[1], j[0]));
            let (sw, se) = (v(i[0], j[1]), v(i[1], j[1]));
            out.extend([nw, ne, se, nw, se, sw]);
        }
    }
    MaskIndices::narrowest(s * s, out)
}

/// A vertex of a border band in side coordinates: `along` the side, on the tile's edge or on the
/// inner rectangle's side.
#[derive(Clone, Copy)]
enum Chain {
    Outer(usize),
    Inner(usize),
}

/// The four sides of `level` against a neighbour at `neighbour`, in [`Side::ALL`] order.
fn borders(s: usize, level: usize, neighbour: usize) -> Borders {
    let kept = kept_indices(s, level);
    let k = kept.len();
    let v = |i: usize, j: usize| j * s + i;
    if k == 2 {
        let last = s - 1;
        let (nw, ne, sw, se) = (v(0, 0), v(last, 0), v(0, last), v(last, last));
        let [north, south] = [[nw, ne, se], [nw, se, sw]].map(|t| t.to_vec());
        let empty = Vec::new;
        return [north, empty(), south, empty()].map(|t| MaskIndices::narrowest(s * s, t));
    }
    let band = band(&shared_edge(s, level, neighbour), &kept[1..k - 1]);
    let (first, last) = (kept[1], kept[k - 2]);
    Side::ALL.map(|side| {
        // Side coordinates to grid indices; north and east keep the winding of the north band,
        // south and west mirror it.
        let (place, mirrored): (&dyn Fn(Chain) -> usize, bool) = match side {
            Side::North => (
                &|c| match c {
                    Chain::Outer(t) => v(t, 0),
                    Chain::Inner(t) => v(t, first),
                },
                false,
            ),
            Side::East => (
                &|c| match c {
                    Chain::Outer(t) => v(s - 1, t),
                    Chain::Inner(t) => v(last, t),
                },
                false,
            ),
            Side::South => (
                &|c| match c {
                    Chain::Outer(t) => v(t, s - 1),
                    Chain::Inner(t) => v(t, last),
                },
                true,
            ),
            Side::West => (
                &|c| match c {
                    Chain::Outer(t) => v(0, t),
                    Chain::Inner(t) => v(first, t),
                },
                true,
            ),
        };
        let mut out = Vec::with_capacity(3 * band.len());
        for t in &band {
            let [a, b, c] = t.map(place);
            out.extend(if mirrored { [b, a, c] } else { [a, b, c] });
        }
        MaskIndices::narrowest(s * s, out)
    })
}

/// Zips the outer chain `outer` (edge, corner to corner) with the inner chain `inner` into
/// triangles wound as the north band needs (outer on row 0, inner below it). A single inner
/// vertex makes a fan.
fn band(outer: &[usize], inner: &[usize]) -> Vec<[Chain; 3]> {
    let (mut a, mut b) = (0, 0);
    let mut out = Vec::with_capacity(outer.len() + inner.len() - 2);
    while a + 1 < outer.len() || b + 1 < inner.len() {
        let advance_outer =
            b + 1 == inner.len() || (a + 1 < outer.len() && outer[a + 1] <= inner[b + 1]);
        if advance_outer {
            out.push([
                Chain::Outer(outer[a]),
                Chain::Outer(outer[a + 1]),
                Chain::Inner(inner[b]),
            ]);
            a += 1;
        } else {
            out.push([
                Chain::Outer(outer[a]),
                Chain::Inner(inner[b + 1]),
                Chain::Inner(inner[b]),
            ]);
            b += 1;
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use stripmask_raster::{FrontFace, Indices, Topology};

    use super::*;
    use crate::engine::cracks::test_view;
    use crate::engine::masks::{FRONT_FACE, triangle_count};

    fn triangles(indices: &MaskIndices) -> Vec<[usize; 3]> {
        let flat: Vec<usize> = match indices {
            MaskIndices::U16(i) => i.iter().map(|&v| v as usize).collect(),
            MaskIndices::U32(i) => i.iter().map(|&v| v as usize).collect(),
        };
        assert_eq!(flat.len() % 3, 0);
        flat.chunks(3).map(|t| [t[0], t[1], t[2]]).collect()
    }

    /// Twice the signed area in the (i, j) plane; positive is clockwise seen from above.
    fn doubled_area(s: usize, t: [usize; 3]) -> i64 {
        let p = t.map(|k| ((k % s) as i64, (k / s) as i64));
        (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[1].1 - p[0].1) * (p[2].0 - p[0].0)
    }

    /// Neighbour levels that exercise every level on some side of every tile: all four at
    /// `ln`, and a mix.
    fn neighbour_sets(levels: usize, ln: usize) -> [[usize; 4]; 2] {
        [
            [ln; 4],
            [ln, (ln + 1) % levels, (ln + 3) % levels, (ln + 5) % levels],
        ]
    }

    #[test]
    fn every_level_pair_covers_the_tile_once_with_one_winding() {
        for s in [3, 9, 17] {
            let set = StitchSet::new(s);
            let levels = level_count(s);
            let mut out = set.buffer();
            for level in 0..levels {
                for ln in 0..levels {
                    for neighbours in neighbour_sets(levels, ln) {
                        set.tile(level, neighbours, &mut out);
                        let tris = triangles(&out);
                        let areas: Vec<i64> = tris.iter().map(|&t| doubled_area(s, t)).collect();
                        let at = format!("s {s} level {level} neighbours {neighbours:?}");
                        assert!(areas.iter().all(|&a| a > 0), "{at}: {areas:?}");
                        assert_eq!(areas.iter().sum::<i64>(), 2 * ((s - 1) * (s - 1)) as i64);
                        assert_eq!(tris.len(), set.triangle_count(level, neighbours), "{at}");
                        if neighbours == [level; 4] {
                            assert_eq!(tris.len(), triangle_count(s, level), "{at}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn a_shared_edge_has_the_same_vertices_from_both_sides() {
        let s = 17;
        let set = StitchSet::new(s);
        let (mut tile, mut neighbour) = (set.buffer(), set.buffer());
        let edge = |indices: &MaskIndices, on: &dyn Fn(usize, usize) -> bool| {
            let mut e: Vec<usize> = triangles(indices)
                .concat()
                .into_iter()
                .filter(|&k| on(k % s, k / s))
                .collect();
            e.sort();
            e.dedup();
            e
        };
        for l in 0..s - 1 {
            for ln in 0..s - 1 {
                // This tile's east edge against the neighbour's west edge, as offsets along it.
                set.tile(l, [l, ln, l, l], &mut tile);
                set.tile(ln, [ln, ln, ln, l], &mut neighbour);
                let east = edge(&tile, &|i, _| i == s - 1);
                let west = edge(&neighbour, &|i, _| i == 0);
                let along = |e: Vec<usize>| e.into_iter().map(|k| k / s).collect::<Vec<_>>();
                assert_eq!(along(east), along(west), "l {l} ln {ln}");
            }
        }
    }

    #[test]
    fn rasterized_from_above_every_pixel_is_hit_once_with_back_faces_culled() {
        let s = 9;
        let set = StitchSet::new(s);
        let vertices = crate::engine::masks::tests::tile_vertices(s);
        let mut out = set.buffer();
        for level in 0..s - 1 {
            for ln in 0..s - 1 {
                for neighbours in neighbour_sets(s - 1, ln) {
                    set.tile(level, neighbours, &mut out);
                    let MaskIndices::U16(indices) = &out else {
                        panic!("81 vertices take u16 indices")
                    };
                    let mesh = stripmask_raster::Mesh {
                        vertices: &vertices,
                        indices: Indices::U16(indices),
                        topology: Topology::TriangleList,
                    };
                    let at = format!("level {level} neighbours {neighbours:?}");
                    let (fragments, covered) = test_view::draw_from_above(s, &mesh, FRONT_FACE);
                    assert_eq!(fragments, test_view::PIXELS, "{at}");
                    assert_eq!(covered, test_view::PIXELS, "{at}");
                    let other = match FRONT_FACE {
                        FrontFace::Cw => FrontFace::Ccw,
                        FrontFace::Ccw => FrontFace::Cw,
                    };
                    assert_eq!(test_view::draw_from_above(s, &mesh, other).0, 0, "{at}");
                }
            }
        }
    }

    #[test]
    fn two_neighbouring_tiles_at_any_two_levels_leave_no_background_pixel() {
        let s = 9;
        let set = StitchSet::new(s);
        let (mut west, mut east) = (set.buffer(), set.buffer());
        for l in 0..s - 1 {
            for ln in 0..s - 1 {
                set.tile(l, [l, ln, l, l], &mut west);
                set.tile(ln, [ln, ln, ln, l], &mut east);
                let holes = test_view::holes_between_two_tiles(s, &west, &east);
                assert_eq!(holes, 0, "west at {l}, east at {ln}");
            }
        }
    }

    #[test]
    fn the_views_see_cracks_between_plain_masks() {
        let s = 9;
        let masks = crate::engine::masks::MaskSet::new(s, crate::engine::masks::LevelSet::All);
        let holes: usize = (0..s - 1)
            .map(|l| {
                test_view::holes_between_two_strip_tiles(s, masks.indices(0), masks.indices(l))
            })
            .sum();
        assert!(holes > 0, "the crack views must be able to see a crack");
    }
}
