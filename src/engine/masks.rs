//! Strip masks: one precomputed index buffer per mask level, shared by every tile.
//!
//! Mask level `l` of a tile of `s x s` samples joins the samples that
//! [`mask_level::keeps_index`] keeps in both directions (multiples of `l + 1`, plus the last row
//! and column) into triangle strips over the tile's row-major vertex array (vertex `j * s + i`).
//! Each row pair of the kept grid is one strip, going east, and strips are joined by restart
//! markers, which never draw and cost no triangle. Every cell, from `(i0, j0)` to `(i1, j1)`, is
//! split along its north-west to south-east diagonal, so a mask draws exactly the surface whose
//! error [`crate::db::level_error`] measures.
//!
//! Winding: with world X = `i` (east), Z = `j` (south) and Y up, a row strip with that diagonal
//! is clockwise seen from above, so the renderer culls back faces with [`FRONT_FACE`]
//! (`FrontFace::Cw`), not the rasterizer's default.
//!
//! As in the paper, one [`MaskSet`] serves every tile of an archive: a level's indices are built
//! the first time it is asked for, and choosing the finest level that fits a tile's triangle
//! budget is one table look-up ([`MaskSet::finest_level_for`]).

use std::sync::OnceLock;

use stripmask_raster::{FrontFace, Indices};

use crate::db::mask_level::{self, level_count};

/// The winding of mask triangles seen from above; the renderer sets it as the front face when it
/// culls back faces.
pub const FRONT_FACE: FrontFace = FrontFace::Cw;

/// The number of samples per side that mask level `level` keeps: the multiples of `level + 1`
/// in `0..tile_size`, plus the last index when it is not one of them.
pub fn kept_count(tile_size: usize, level: usize) -> usize {
    (tile_size - 1).div_ceil(level + 1) + 1
}

/// Triangles of mask level `level` without building it: `2 (k - 1)^2` with `k` samples kept per
/// side.
pub fn triangle_count(tile_size: usize, level: usize) -> usize {
    let cells = kept_count(tile_size, level) - 1;
    2 * cells * cells
}

/// Which levels a [`MaskSet`] may choose from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum LevelSet {
    /// Every level `0 ..= s - 2` (the paper's strip masks).
    #[default]
    All,
    /// Only levels `l` with `l + 1` a power of two: geometrical mipmapping, to compare with.
    PowerOfTwo,
}

impl LevelSet {
    fn contains(self, level: usize) -> bool {
        match self {
            LevelSet::All => true,
            LevelSet::PowerOfTwo => (level + 1).is_power_of_two(),
        }
    }
}

/// The index buffer of one mask level, in the narrowest width that can address the tile.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum MaskIndices {
    /// Tiles with at most 65,535 vertices; restart marker `0xFFFF`.
    U16(Vec<u16>),
    /// Larger tiles; restart marker `0xFFFF_FFFF`.
    U32(Vec<u32>),
}

impl MaskIndices {
    /// `indices` into a buffer of `vertex_count` vertices in the narrowest width that leaves the
    /// restart marker free; `usize::MAX` becomes that width's restart marker.
    pub fn narrowest(vertex_count: usize, indices: Vec<usize>) -> MaskIndices {
        if vertex_count <= u16::MAX as usize {
            MaskIndices::U16(indices.into_iter().map(|v| v as u16).collect())
        } else {
            MaskIndices::U32(indices.into_iter().map(|v| v as u32).collect())
        }
    }

    /// The indices as the rasterizer takes them (draw with `Topology::TriangleStrip`).
    pub fn as_indices(&self) -> Indices<'_> {
        match self {
            MaskIndices::U16(i) => Indices::U16(i),
            MaskIndices::U32(i) => Indices::U32(i),
        }
    }

    /// Number of indices, restart markers included.
    pub fn len(&self) -> usize {
        match self {
            MaskIndices::U16(i) => i.len(),
            MaskIndices::U32(i) => i.len(),
        }
    }

    /// True for a buffer without indices (never the case for a built mask).
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The strip masks of every tile of one size, built lazily, and the budget-to-level table.
///
/// `Sync`: share one by reference across threads; a level is built once even when several
/// threads ask for it at the same time.
#[derive(Debug)]
pub struct MaskSet {
    tile_size: usize,
    level_set: LevelSet,
    /// The levels of the set, finest first.
    levels: Vec<usize>,
    /// `by_budget[b]`: the finest level of the set with at most `b` triangles (the coarsest one
    /// below its count), for `b` up to the level-0 count.
    by_budget: Vec<u16>,
    /// `counts[l]`: the triangles of level `l`, for every level `0 ..= s - 2`. The budget asks
    /// thousands of times a frame, and on a core without a divider `triangle_count`'s division
    /// is a library call.
    counts: Vec<usize>,
    /// One slot per level `0 ..= s - 2`, filled on first use.
    indices: Vec<OnceLock<MaskIndices>>,
}

impl MaskSet {
    /// The masks of tiles with `tile_size` samples per side.
    ///
    /// The look-up table holds one `u16` per possible budget, `2 (s - 1)^2 + 1` entries (64 KiB
    /// for `s = 129`). Panics unless `2 <= tile_size <= 65_535`.
    pub fn new(tile_size: usize, level_set: LevelSet) -> Self {
        assert!(
            (2..=65_535).contains(&tile_size),
            "strip masks need 2 to 65535 samples per side, not {tile_size}"
        );
        let levels: Vec<usize> = (0..level_count(tile_size))
            .filter(|&l| level_set.contains(l))
            .collect();
        let counts: Vec<usize> = (0..level_count(tile_size))
            .map(|l| triangle_count(tile_size, l))
            .collect();
        let max = counts[0];
        let mut by_budget = vec![0u16; max + 1];
        // Counts never grow with the level, so walking finest first gives each level the
        // budgets from its count up to the next finer count; an equal count leaves the range
        // to the finer level.
        let mut upper = max + 1;
        for &level in &levels {
            let count = counts[level];
            if count < upper {
                by_budget[count..upper].fill(level as u16);
                upper = count;
            }
        }
        let coarsest = *levels.last().expect("level 0 is in every set");
        by_budget[..upper].fill(coarsest as u16);
        Self {
            tile_size,
            level_set,
            levels,
            by_budget,
            counts,
            indices: (0..level_count(tile_size))
                .map(|_| OnceLock::new())
                .collect(),
        }
    }

    /// Samples per side of the tiles these masks draw.
    pub fn tile_size(&self) -> usize {
        self.tile_size
    }

    /// Which levels the set chooses from.
    pub fn level_set(&self) -> LevelSet {
        self.level_set
    }

    /// The levels of the set, finest (0) first.
    pub fn levels(&self) -> &[usize] {
        &self.levels
    }

    /// The coarsest level of the set: what a tile gets when its budget is smaller than any mask.
    pub fn coarsest_level(&self) -> usize {
        *self.levels.last().expect("level 0 is in every set")
    }

    /// Triangles drawn by `level` (closed form, from a table; nothing is built).
    pub fn triangle_count(&self, level: usize) -> usize {
        self.counts
            .get(level)
            .copied()
            .unwrap_or_else(|| triangle_count(self.tile_size, level))
    }

    /// The finest level of the set with at most `budget` triangles, the coarsest level when no
    /// level fits. Of levels with equal counts the finer wins. O(1).
    pub fn finest_level_for(&self, budget: usize) -> usize {
        self.by_budget[budget.min(self.by_budget.len() - 1)] as usize
    }

    /// The strip indices of `level` (any level `0 ..= s - 2`, in the set or not), built on first
    /// use.
    pub fn indices(&self, level: usize) -> &MaskIndices {
        self.indices[level].get_or_init(|| build(self.tile_size, level))
    }
}

/// Builds the strips of `level`: one per row pair `(j0, j1)` of the kept grid, each going east
/// as `(i, j1), (i, j0)` for every kept column `i`, so that the strip's diagonals join
/// `(i0, j0)` to `(i1, j1)`.
fn build(s: usize, level: usize) -> MaskIndices {
    let kept = mask_level::kept_indices(s, level);
    let mut out = Vec::with_capacity((kept.len() - 1) * (2 * kept.len() + 1));
    for (r, rows) in kept.windows(2).enumerate() {
        if r > 0 {
            out.push(usize::MAX);
        }
        for &i in &kept {
            out.push(rows[1] * s + i);
            out.push(rows[0] * s + i);
        }
    }
    MaskIndices::narrowest(s * s, out)
}

#[cfg(test)]
pub(crate) mod tests {
    use std::collections::BTreeSet;

    use glam::{DMat4, DVec3};
    use stripmask_raster::{
        ColorFormat, CullMode, DepthFormat, DepthMode, Framebuffer, Mesh, Rasterizer, RenderState,
        Topology, Transform, Vertex,
    };

    use super::*;
    use crate::db::mask_level::kept_indices;

    /// The triangles of a strip buffer in drawing order, with the rasterizer's rules: restart
    /// markers start a new strip, odd triangles of a strip swap their first two vertices, and
    /// degenerate triangles are dropped.
    fn triangles(indices: &MaskIndices) -> Vec<[usize; 3]> {
        let flat: Vec<Option<usize>> = match indices {
            MaskIndices::U16(i) => i
                .iter()
                .map(|&v| (v != u16::MAX).then_some(v as usize))
                .collect(),
            MaskIndices::U32(i) => i
                .iter()
                .map(|&v| (v != u32::MAX).then_some(v as usize))
                .collect(),
        };
        let mut out = vec![];
        for strip in flat.split(Option::is_none) {
            let strip: Vec<usize> = strip.iter().map(|v| v.unwrap()).collect();
            for (t, w) in strip.windows(3).enumerate() {
                if w[0] != w[1] && w[1] != w[2] && w[0] != w[2] {
                    out.push(if t % 2 == 0 {
                        [w[0], w[1], w[2]]
                    } else {
                        [w[1], w[0], w[2]]
                    });
                }
            }
        }
        out
    }

    /// Twice the signed area of a triangle in the (i, j) plane; positive is counter-clockwise
    /// with j growing downwards, i.e. clockwise seen from above.
    fn doubled_area(s: usize, t: [usize; 3]) -> i64 {
        let p = t.map(|k| ((k % s) as i64, (k / s) as i64));
        (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[1].1 - p[0].1) * (p[2].0 - p[0].0)
    }

    #[test]
    fn triangle_counts_match_the_closed_form_and_the_built_strips() {
        for s in (2..=40).chain([65, 129, 255, 256, 257]) {
            let masks = MaskSet::new(s, LevelSet::All);
            assert_eq!(masks.levels().len(), s - 1);
            for level in 0..s - 1 {
                let k = kept_indices(s, level).len();
                assert_eq!(kept_count(s, level), k, "s {s} level {level}");
                assert_eq!(masks.triangle_count(level), 2 * (k - 1) * (k - 1));
                if s <= 40 || level % 17 == 0 {
                    let built = triangles(masks.indices(level));
                    assert_eq!(built.len(), masks.triangle_count(level), "s {s} l {level}");
                    // (k - 1) strips of 2k indices and k - 2 restarts between them.
                    assert_eq!(masks.indices(level).len(), (k - 1) * (2 * k + 1) - 1);
                }
            }
        }
    }

    #[test]
    fn masks_split_every_kept_cell_along_its_north_west_diagonal_with_one_winding() {
        for s in [2, 3, 6, 9, 17, 33] {
            let masks = MaskSet::new(s, LevelSet::All);
            for level in 0..s - 1 {
                let tris = triangles(masks.indices(level));
                let areas: Vec<i64> = tris.iter().map(|&t| doubled_area(s, t)).collect();
                assert!(areas.iter().all(|&a| a > 0), "s {s} level {level}");
                let total: i64 = areas.iter().sum();
                assert_eq!(total, 2 * ((s - 1) * (s - 1)) as i64, "s {s} level {level}");

                let got: BTreeSet<[usize; 3]> = tris
                    .iter()
                    .map(|t| {
                        let mut t = *t;
                        t.sort();
                        t
                    })
                    .collect();
                let kept = kept_indices(s, level);
                let mut want = BTreeSet::new();
                for j in kept.windows(2) {
                    for i in kept.windows(2) {
                        let v = |ii: usize, jj: usize| jj * s + ii;
                        let (nw, ne) = (v(i[0], j[0]), v(i[1], j[0]));
                        let (sw, se) = (v(i[0], j[1]), v(i[1], j[1]));
                        want.insert([nw, ne, se]);
                        want.insert([nw, sw, se]);
                    }
                }
                assert_eq!(got, want, "s {s} level {level}");
                assert_eq!(got.len(), tris.len());
            }
        }
    }

    /// The paper's example: a 6 x 6 tile, where levels 2 and 3 both have 8 triangles.
    #[test]
    fn paper_six_by_six_example() {
        let masks = MaskSet::new(6, LevelSet::All);
        let counts: Vec<usize> = (0..5).map(|l| masks.triangle_count(l)).collect();
        assert_eq!(counts, [50, 18, 8, 8, 2]);
        for budget in 8..=17 {
            assert_eq!(masks.finest_level_for(budget), 2, "budget {budget}");
        }
        assert_eq!(masks.finest_level_for(18), 1);
        assert_eq!(masks.finest_level_for(49), 1);
        assert_eq!(masks.finest_level_for(50), 0);
        assert_eq!(masks.finest_level_for(1_000_000), 0);
        assert_eq!(masks.finest_level_for(7), 4);
        assert_eq!(masks.finest_level_for(0), 4);
        assert_eq!(masks.coarsest_level(), 4);
    }

    #[test]
    fn power_of_two_set_chooses_only_its_levels() {
        let masks = MaskSet::new(6, LevelSet::PowerOfTwo);
        assert_eq!(masks.levels(), [0, 1, 3]);
        assert_eq!(masks.coarsest_level(), 3);
        for budget in 0..=17 {
            assert_eq!(masks.finest_level_for(budget), 3, "budget {budget}");
        }
        assert_eq!(masks.finest_level_for(18), 1);
        assert_eq!(masks.finest_level_for(50), 0);

        let masks = MaskSet::new(65, LevelSet::PowerOfTwo);
        assert_eq!(masks.levels(), [0, 1, 3, 7, 15, 31, 63]);
    }

    #[test]
    fn finest_level_for_is_the_finest_level_that_fits() {
        for s in [2, 5, 6, 17, 33, 50, 65] {
            for set in [LevelSet::All, LevelSet::PowerOfTwo] {
                let masks = MaskSet::new(s, set);
                let coarsest = masks.coarsest_level();
                for budget in 0..=masks.triangle_count(0) + 3 {
                    let want = masks
                        .levels()
                        .iter()
                        .copied()
                        .find(|&l| masks.triangle_count(l) <= budget)
                        .unwrap_or(coarsest);
                    assert_eq!(masks.finest_level_for(budget), want, "s {s} {budget}");
                }
            }
        }
    }

    #[test]
    fn index_width_follows_the_vertex_count() {
        assert!(matches!(
            MaskSet::new(255, LevelSet::All).indices(3),
            MaskIndices::U16(_)
        ));
        let big = MaskSet::new(256, LevelSet::All);
        let MaskIndices::U32(i) = big.indices(0) else {
            panic!("65,536 vertices need u32 indices");
        };
        assert_eq!(i.iter().filter(|&&v| v == u32::MAX).count(), 254);
        assert_eq!(i.iter().filter(|&&v| v != u32::MAX).max(), Some(&65_535));
    }

    #[test]
    fn a_level_is_built_once_across_threads() {
        let masks = MaskSet::new(129, LevelSet::All);
        let built: Vec<&MaskIndices> = std::thread::scope(|scope| {
            let handles: Vec<_> = (0..4).map(|_| scope.spawn(|| masks.indices(5))).collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        assert!(built.windows(2).all(|w| std::ptr::eq(w[0], w[1])));
        assert_eq!(triangles(masks.indices(5)).len(), masks.triangle_count(5));
    }

    /// A tile with some relief, vertex `j * s + i` at `(i, h, j)`.
    pub(crate) fn tile_vertices(s: usize) -> Vec<Vertex> {
        (0..s * s)
            .map(|k| {
                let (i, j) = (k % s, k / s);
                let h = ((i * 7 + j * 13) % 5) as i32;
                Vertex::new([i as i32, h, j as i32], [0.0, 0.0], [255, 255, 255])
            })
            .collect()
    }

    /// An orthographic camera over (or under) the tile, north up, framing it exactly.
    fn top_view(s: usize, from_below: bool) -> Transform {
        let c = (s - 1) as f64 / 2.0;
        let (eye_y, up) = if from_below {
            (-100.0, DVec3::Z)
        } else {
            (100.0, DVec3::NEG_Z)
        };
        let view = glam::dcamera::rh::view::look_at_mat4(
            DVec3::new(c, eye_y, c),
            DVec3::new(c, 0.0, c),
            up,
        );
        let proj: DMat4 = glam::dcamera::rh::proj::directx::orthographic(-c, c, -c, c, 1.0, 200.0);
        Transform::new(proj * view).unwrap()
    }

    fn draw(s: usize, level: usize, front: FrontFace, from_below: bool) -> (u64, Framebuffer) {
        const W: u32 = 64;
        let masks = MaskSet::new(s, LevelSet::All);
        let vertices = tile_vertices(s);
        let mesh = Mesh {
            vertices: &vertices,
            indices: masks.indices(level).as_indices(),
            topology: Topology::TriangleStrip,
        };
        let mut fb = Framebuffer::new(W, W, ColorFormat::Rgba8888, DepthFormat::None).unwrap();
        let state = RenderState {
            cull: CullMode::Back,
            front_face: front,
            depth: DepthMode::NONE,
            ..RenderState::default()
        };
        let stats = Rasterizer::new()
            .draw(&mut fb, &mesh, &top_view(s, from_below), &state)
            .unwrap();
        assert_eq!(stats.triangles, masks.triangle_count(level) as u64);
        (stats.fragments, fb)
    }

    #[test]
    fn rasterized_from_above_every_pixel_is_covered_once_with_back_faces_culled() {
        for (s, level) in [
            (2, 0),
            (6, 0),
            (6, 1),
            (6, 2),
            (6, 3),
            (6, 4),
            (17, 0),
            (17, 5),
        ] {
            let (fragments, fb) = draw(s, level, FRONT_FACE, false);
            assert_eq!(fragments, 64 * 64, "s {s} level {level}");
            for y in 0..64 {
                for x in 0..64 {
                    assert_eq!(fb.pixel(x, y), [255; 3], "s {s} level {level} ({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn every_mask_triangle_is_a_back_face_from_below_or_with_the_other_winding() {
        let other = match FRONT_FACE {
            FrontFace::Cw => FrontFace::Ccw,
            FrontFace::Ccw => FrontFace::Cw,
        };
        for (s, level) in [(6, 0), (6, 2), (17, 3)] {
            assert_eq!(draw(s, level, other, false).0, 0, "s {s} level {level}");
            assert_eq!(draw(s, level, FRONT_FACE, true).0, 0, "s {s} level {level}");
            assert_eq!(
                draw(s, level, other, true).0,
                64 * 64,
                "s {s} level {level}"
            );
        }
    }
}
