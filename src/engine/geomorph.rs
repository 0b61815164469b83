//! Geomorphing: vertices that coarser levels drop glide onto the coarser surface with distance,
//! so that a mask switch moves them a little instead of all at once.
//!
//! The morph follows the power-of-two hierarchy of a tile of `s = 2^n + 1` samples: every
//! sample that is not a corner *splits* a segment of the next coarser power-of-two grid, of
//! `step` samples (1, 2, 4, …): horizontally, vertically, or along the north-west to south-east
//! diagonal that the masks split cells on. [`MorphTree`] lists those splits, coarsest first.
//! A vertex's morphed height is `h + f (p - h)`, where `p` is the mean of its two parents'
//! *morphed* heights, so a morph factor of 1 at every vertex finer than some step leaves exactly
//! the piecewise-linear surface of that coarser grid. Vertex colours (the lighting) morph the
//! same way.
//!
//! The factor depends only on the vertex's world position, its step and the camera
//! ([`Geomorph::Distance`], as in CDLOD): a vertex whose step projects to fewer than `pixels`
//! pixels is fully morphed, one whose step spans twice that or more not at all, and in between
//! the factor grows linearly with distance. A border vertex has the same global position, step,
//! parents and height in both tiles that share it, so both tiles morph it to the same integer
//! and [`crate::engine::cracks::CrackMode::Stitch`] stays crack-free. A per-tile factor (say, a morph
//! over the frames after a tile's switch) would give the two tiles different border heights and
//! reopen the cracks, which is why there is no such mode.
//!
//! Everything is integer: morphed positions count [`SUBDIVISION`]ths of a grid step and of a
//! height quantum, factors [`FACTOR_ONE`]ths. Factor 0 gives the tile's own heights exactly,
//! factor 1 the parents' mean exactly as long as the hierarchy is at most 8 steps deep (tiles of
//! up to 257 samples; finer ones round the deepest midpoints down by 1/256 quantum).
//!
//! The tile data are not touched: the engine morphs each drawn tile into one scratch buffer per
//! frame, so geomorphing costs no memory per tile, and nothing at all when it is off.
//!
//! A partial tile (a progressive tile holding its first levels: the grid of
//! every `stride`-th sample) morphs in its own grid, whose hierarchy is the whole tile's
//! restricted to the samples it holds, with each factor taken at the whole-tile position and
//! step: it gives every held sample exactly the whole tile's morphed value
//! ([`MorphView::morph_tile`]).
//!
//! A tile pays only for what changes its picture ([`MorphView::morph_tile`]): the samples its
//! own mask uses (its stitches, against any neighbour, use a subset of them) and the ancestors
//! their morph needs (a tile drawn at mask level 4 reads 196 of its 4,225 samples, whose morph
//! needs 646), visited from a list kept per level, and of those, per step, the per-vertex factor
//! only where the tile's nearest and farthest points give factors on both sides of 0 and 1.
//! Steps whose factor is 0 over the whole tile are skipped, and steps fully morphed over the
//! whole tile take the parents' mean without a distance; a vertex's factor takes a square root
//! only where its distance puts it strictly between 0 and 1. The result is exactly the full
//! morph's on every sample drawn.

use std::sync::OnceLock;

use glam::DVec3;
use stripmask_raster::Vertex;

use crate::db::grid::TileId;
use crate::db::mask_level::keeps_index;
use crate::engine::camera::View;
use crate::engine::partial_meshes::compact_level;
use crate::engine::terrain::TerrainFrame;
use crate::named::Named;

/// Morphed vertices count positions in 1/256 of a grid step and of a height quantum.
pub const SUBDIVISION: i32 = 256;

/// A morph factor of 1: factors are integers `0 ..= FACTOR_ONE`.
pub const FACTOR_ONE: i32 = 256;

/// Whether, and how, vertices that coarser levels drop are morphed.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Geomorph {
    /// Vertices keep their heights: a mask switch pops.
    #[default]
    Off,
    /// By distance: a vertex is fully on the coarser surface where its step spans fewer than
    /// `pixels` pixels on screen, untouched where it spans `2 pixels` or more.
    Distance {
        /// Projected step length, pixels, below which a vertex is fully morphed.
        pixels: f64,
    },
}

impl Geomorph {
    /// The distance morph with the projected step of [`Geomorph::DEFAULT_PIXELS`].
    pub const DISTANCE: Geomorph = Geomorph::Distance {
        pixels: Geomorph::DEFAULT_PIXELS,
    };

    /// The default threshold of [`Geomorph::Distance`]: a 4-pixel step is close to what the
    /// eye tells from a plane at 320x240, and 8-pixel steps keep all their relief.
    pub const DEFAULT_PIXELS: f64 = 4.0;
}

/// `off`, and `distance` with [`Geomorph::DEFAULT_PIXELS`].
impl Named for Geomorph {
    const KIND: &'static str = "geomorph";

    fn all() -> Vec<Self> {
        vec![Geomorph::Off, Geomorph::DISTANCE]
    }

    fn name(&self) -> &'static str {
        match self {
            Geomorph::Off => "off",
            Geomorph::Distance { .. } => "distance",
        }
    }
}

/// One sample of a tile and the two samples of the next coarser grid whose segment it splits.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Split {
    /// The sample, `j * s + i`.
    pub vertex: usize,
    /// The ends of the segment it splits.
    pub parents: [usize; 2],
    /// Its distance to each parent along a grid axis, samples (a power of two).
    pub step: usize,
}

/// The splits of every non-corner sample of one tile size, coarsest first: the order in which
/// morphing can use the parents' morphed heights.
#[derive(Clone, Debug)]
pub struct MorphTree {
    tile_size: usize,
    splits: Vec<Split>,
    /// Per step, coarsest first: the step and the end of its splits in `splits`.
    groups: Vec<(usize, usize)>,
    /// Per mask level, built on first use: the samples the level's mask reads and every
    /// ancestor their morph needs ([`MorphTree::needs`]), and their splits.
    needed: Vec<OnceLock<Needed>>,
}

/// What a morph of one mask level's samples touches.
#[derive(Clone, Debug)]
struct Needed {
    /// A bit per sample (`j * s + i`).
    bits: Vec<u64>,
    /// The splits of the set samples, coarsest first, as indices into [`MorphTree::splits`].
    splits: Vec<u32>,
    /// Per step of [`MorphTree::groups`], the end of its splits in `splits`.
    ends: Vec<usize>,
}

impl MorphTree {
    /// The hierarchy of tiles of `tile_size = 2^n + 1` samples per side (2, corners only, has no
    /// splits); `None` for any other size.
    pub fn new(tile_size: usize) -> Option<MorphTree> {
        let s = tile_size;
        if s < 2 || !(s - 1).is_power_of_two() {
            return None;
        }
        let v = |i: usize, j: usize| j * s + i;
        let mut splits = Vec::with_capacity(s * s - 4);
        let mut groups = Vec::new();
        let mut step = (s - 1) / 2;
        while step >= 1 {
            for j in (0..s).step_by(step) {
                for i in (0..s).step_by(step) {
                    let (odd_i, odd_j) = ((i / step) % 2 == 1, (j / step) % 2 == 1);
                    let parents = match (odd_i, odd_j) {
                        (false, false) => continue,
                        (true, false) => [v(i - step, j), v(i + step, j)],
                        (false, true) => [v(i, j - step), v(i, j + step)],
                        (true, true) => [v(i - step, j - step), v(i + step, j + step)],
                    };
                    splits.push(Split {
                        vertex: v(i, j),
                        parents,
                        step,
                    });
                }
            }
            groups.push((step, splits.len()));
            step /= 2;
        }
        Some(MorphTree {
            tile_size: s,
            splits,
            groups,
            needed: (0..s - 1).map(|_| OnceLock::new()).collect(),
        })
    }

    /// The samples a morph of the samples mask `level` keeps needs, a bit per sample: those
    /// samples and, recursively, the parents of each (their morphed heights are its target).
    pub fn needs(&self, level: usize) -> &[u64] {
        &self.needed(level).bits
    }

    /// [`MorphTree::needs`] of `level` with its splits, built on first use.
    fn needed(&self, level: usize) -> &Needed {
        self.needed[level].get_or_init(|| {
            let s = self.tile_size;
            let mut bits = vec![0u64; (s * s).div_ceil(64)];
            let set = |bits: &mut Vec<u64>, k: usize| bits[k / 64] |= 1 << (k % 64);
            for j in (0..s).filter(|&j| keeps_index(s, level, j)) {
                for i in (0..s).filter(|&i| keeps_index(s, level, i)) {
                    set(&mut bits, j * s + i);
                }
            }
            // Finest first: a split's children come before it, so one pass closes the set.
            for split in self.splits.iter().rev() {
                if is_set(&bits, split.vertex) {
                    for p in split.parents {
                        set(&mut bits, p);
                    }
                }
            }
            let mut splits = Vec::new();
            let mut ends = Vec::with_capacity(self.groups.len());
            let mut start = 0;
            for &(_, end) in &self.groups {
                splits.extend(
                    (start..end)
                        .filter(|&k| is_set(&bits, self.splits[k].vertex))
                        .map(|k| k as u32),
                );
                ends.push(splits.len());
                start = end;
            }
            Needed { bits, splits, ends }
        })
    }

    /// Samples per tile side.
    pub fn tile_size(&self) -> usize {
        self.tile_size
    }

    /// Every non-corner sample's split, coarsest first.
    pub fn splits(&self) -> &[Split] {
        &self.splits
    }

    /// Writes into `out` (emptied first) `vertices` in [`SUBDIVISION`] units with every split
    /// sample morphed by `factor(split)` (`0 ..= FACTOR_ONE`) towards its parents' morphed mean.
    /// Vertices beyond the grid (a crack mode's extras) are scaled and kept as they are.
    pub fn morph(
        &self,
        vertices: &[Vertex],
        factor: impl FnMut(&Split) -> i32,
        out: &mut Vec<Vertex>,
    ) {
        self.scale(vertices, None, out);
        morph_splits(&self.splits, factor, out);
    }

    /// Makes `out` as long as `vertices` and writes into it, in [`SUBDIVISION`] units, the
    /// samples whose bits are set in `samples` (every sample when `None`) and the vertices
    /// beyond the grid; returns the lowest and highest height among those samples, quanta.
    /// Other entries keep what they held: the draw does not read them.
    fn scale(
        &self,
        vertices: &[Vertex],
        samples: Option<&[u64]>,
        out: &mut Vec<Vertex>,
    ) -> (i32, i32) {
        let s = self.tile_size;
        debug_assert!(vertices.len() >= s * s);
        out.resize(vertices.len(), Vertex::default());
        let scaled = |v: &Vertex| Vertex {
            position: v.position.map(|c| c.saturating_mul(SUBDIVISION)),
            ..*v
        };
        let mut range = (i32::MAX, i32::MIN);
        let mut copy = |k: usize| {
            let y = vertices[k].position[1];
            range = (range.0.min(y), range.1.max(y));
            out[k] = scaled(&vertices[k]);
        };
        match samples {
            None => (0..s * s).for_each(&mut copy),
            Some(bits) => {
                for (w, &word) in bits.iter().enumerate() {
                    let mut word = word;
                    while word != 0 {
                        copy(w * 64 + word.trailing_zeros() as usize);
                        word &= word - 1;
                    }
                }
            }
        }
        for (o, v) in out[s * s..].iter_mut().zip(&vertices[s * s..]) {
            *o = scaled(v);
        }
        range
    }

    /// Each step's splits that `needed` holds, coarsest first: `(step, splits)`.
    fn groups<'a>(
        &'a self,
        needed: &'a Needed,
    ) -> impl Iterator<Item = (usize, impl Iterator<Item = &'a Split> + Clone)> {
        let starts = std::iter::once(0).chain(needed.ends.iter().copied());
        self.groups
            .iter()
            .zip(starts.zip(&needed.ends))
            .map(move |(&(step, _), (start, &end))| {
                let splits = needed.splits[start..end]
                    .iter()
                    .map(|&k| &self.splits[k as usize]);
                (step, splits)
            })
    }
}

/// Whether bit `k` is set.
fn is_set(bits: &[u64], k: usize) -> bool {
    bits[k / 64] & (1 << (k % 64)) != 0
}

/// Morphs the samples of `splits` (parents before children) in `out` by `factor(split)`.
fn morph_splits<'a>(
    splits: impl IntoIterator<Item = &'a Split>,
    mut factor: impl FnMut(&Split) -> i32,
    out: &mut [Vertex],
) {
    for split in splits {
        let f = i64::from(factor(split).clamp(0, FACTOR_ONE));
        if f == 0 {
            continue;
        }
        let [a, b] = split.parents.map(|p| out[p]);
        let v = &mut out[split.vertex];
        let towards = |own: i64, a: i64, b: i64| {
            let target = (a + b).div_euclid(2);
            own + ((target - own) * f + i64::from(FACTOR_ONE / 2)).div_euclid(i64::from(FACTOR_ONE))
        };
        let y = i64::from(v.position[1]);
        v.position[1] = towards(y, a.position[1].into(), b.position[1].into()) as i32;
        for c in 0..3 {
            let own = i64::from(v.color[c]);
            v.color[c] = towards(own, a.color[c].into(), b.color[c].into()) as u8;
        }
    }
}

/// What a frame's distance morph needs: the eye and the scale from metres to pixels.
#[derive(Clone, Copy, Debug)]
pub struct MorphView {
    /// The eye relative to the terrain's origin, metres.
    eye: DVec3,
    spacing: f64,
    quantum: f64,
    tile_cells: i64,
    /// `2 pixels / (spacing * focal)`: a vertex's factor is `distance * this / step - 1`.
    scale: f64,
}

impl MorphView {
    /// The distance morph with threshold `pixels` ([`Geomorph::Distance`]) for `view` over
    /// `terrain`.
    pub fn new(pixels: f64, view: &View, terrain: &TerrainFrame) -> MorphView {
        let focal = view.viewport.focal_px();
        MorphView {
            eye: view.camera.position - terrain.origin,
            spacing: terrain.spacing,
            quantum: terrain.quantum,
            tile_cells: terrain.tile_size as i64 - 1,
            scale: 2.0 * pixels / (terrain.spacing * focal),
        }
    }

    /// The morph factor (`0 ..= FACTOR_ONE`) of the sample at global grid position `(gx, gz)`
    /// with height `quanta` and step `step`. Computed from integers and the eye only, so every
    /// tile holding the sample gets the same factor.
    ///
    /// The factor is `distance × scale / step − 1`, clamped to `0 ..= 1` and rounded to
    /// 1/[`FACTOR_ONE`]; a sample nearer than `step / scale` or farther than twice that (by a
    /// relative margin far wider than rounding, and far narrower than half a factor step) is
    /// 0 or [`FACTOR_ONE`] from its squared distance, without a square root.
    pub fn factor(&self, gx: i64, gz: i64, quanta: i32, step: usize) -> i32 {
        let at = DVec3::new(
            gx as f64 * self.spacing,
            f64::from(quanta) * self.quantum,
            gz as f64 * self.spacing,
        );
        let squared = (at - self.eye).length_squared();
        let untouched = step as f64 / self.scale;
        if squared < untouched * untouched * (1.0 - 1e-9) {
            return 0;
        }
        if squared > 4.0 * untouched * untouched * (1.0 + 1e-9) {
            return FACTOR_ONE;
        }
        let f = squared.sqrt() * self.scale / step as f64 - 1.0;
        // Rounds half up: the factor is never negative here.
        (f.clamp(0.0, 1.0) * f64::from(FACTOR_ONE) + 0.5) as i32
    }

    /// Writes into `out` the vertices of tile `(x, y)` morphed for this view, as far as a draw
    /// at mask `level` of `tree` reads them: the samples the mask keeps and their ancestors
    /// ([`MorphTree::needs`]), exactly as [`MorphTree::morph`] with [`MorphView::factor`] gives
    /// them; other samples are left as `out` held them. Every crack mode's indices read only
    /// samples the tile's own mask keeps (a stitched edge keeps those both levels keep), so the
    /// neighbours' levels do not widen the set.
    ///
    /// `vertices` is the grid of every `stride`-th sample of the whole tile (1: the whole
    /// tile; a partial tile holding its first levels has a coarser one), and `tree` and `level`
    /// are that grid's. The grid's hierarchy is the whole tile's restricted to its samples —
    /// the sample `(i, j)` is the whole tile's `(stride i, stride j)`, its step `stride` times
    /// its own, and its parents, one step away, are samples of the grid too — so each sample
    /// morphs to exactly the value the whole tile's morph gives it.
    pub fn morph_tile(
        &self,
        tree: &MorphTree,
        vertices: &[Vertex],
        id: TileId,
        (level, stride): (usize, usize),
        out: &mut Vec<Vertex>,
    ) {
        let s = tree.tile_size();
        let needed = tree.needed(level);
        let heights = tree.scale(vertices, Some(&needed.bits), out);
        let span = id.span() as usize;
        let (gx0, gz0) = (
            i64::from(id.x) * i64::from(id.span()) * self.tile_cells,
            i64::from(id.y) * i64::from(id.span()) * self.tile_cells,
        );
        let stride = stride * span;
        let (near, far) = self.reach((gx0, gz0), (s - 1) * stride, heights);
        for (step, splits) in tree.groups(needed) {
            let step = step * stride;
            let factor = |d: f64| d * self.scale / step as f64 - 1.0;
            if factor(far) <= 0.0 {
                continue;
            }
            if factor(near) >= 1.0 {
                morph_splits(splits, |_| FACTOR_ONE, out);
                continue;
            }
            morph_splits(
                splits,
                |split| {
                    let (i, j) = ((split.vertex % s) * stride, (split.vertex / s) * stride);
                    let quanta = vertices[split.vertex].position[1];
                    self.factor(gx0 + i as i64, gz0 + j as i64, quanta, split.step * stride)
                },
                out,
            );
        }
    }

    /// The nearest and farthest distance from the eye of the box of a tile whose first sample is
    /// at global grid position `(gx0, gz0)`, `cells` grid steps a side, with heights within
    /// `heights` quanta, shrunk and grown by a relative margin so that every sample's own
    /// distance ([`MorphView::factor`]) lies between them despite rounding.
    fn reach(&self, (gx0, gz0): (i64, i64), cells: usize, heights: (i32, i32)) -> (f64, f64) {
        let cells = cells as f64;
        let lo = DVec3::new(
            gx0 as f64 * self.spacing,
            f64::from(heights.0) * self.quantum,
            gz0 as f64 * self.spacing,
        );
        let hi = lo
            + DVec3::new(
                cells * self.spacing,
                f64::from(heights.1 - heights.0) * self.quantum,
                cells * self.spacing,
            );
        let near = (lo - self.eye).max(self.eye - hi).max(DVec3::ZERO).length();
        let far = (lo - self.eye).abs().max((hi - self.eye).abs()).length();
        (near * (1.0 - 1e-9), far * (1.0 + 1e-9))
    }
}

/// The engine's morph state: the hierarchy of each grid size drawn (whole tiles, and partial
/// tiles holding their first levels) and one scratch buffer that each drawn tile is morphed
/// into in turn.
#[derive(Clone, Debug)]
pub struct Morpher {
    pixels: f64,
    tile_size: usize,
    /// One hierarchy per grid size drawn so far, built on first use (at most one per
    /// progressive level).
    trees: Vec<MorphTree>,
    scratch: Vec<Vertex>,
}

impl Morpher {
    /// The morph state of `geomorph` for tiles of `tile_size` samples; `None` when it is off
    /// (or the size is not `2^n + 1`, which archives never have).
    pub fn new(geomorph: Geomorph, tile_size: usize) -> Option<Morpher> {
        let Geomorph::Distance { pixels } = geomorph else {
            return None;
        };
        Some(Morpher {
            pixels,
            tile_size,
            trees: vec![MorphTree::new(tile_size)?],
            scratch: Vec::new(),
        })
    }

    /// This frame's view of the morph.
    pub fn view(&self, view: &View, terrain: &TerrainFrame) -> MorphView {
        MorphView::new(self.pixels, view, terrain)
    }

    /// Tile `(x, y)`'s `vertices` morphed for `view`, in [`SUBDIVISION`] units, as far as a
    /// draw at (whole-tile) mask `level` reads them. `vertices` is the grid of every
    /// `stride`-th sample (1: a whole tile; `level + 1` a multiple of `stride`): a partial tile
    /// morphs to exactly what the whole tile gives the samples it holds.
    pub fn tile(
        &mut self,
        view: &MorphView,
        vertices: &[Vertex],
        at: TileId,
        level: usize,
        stride: usize,
    ) -> &[Vertex] {
        debug_assert_eq!((level + 1) % stride, 0, "level {level}, stride {stride}");
        let side = (self.tile_size - 1) / stride + 1;
        let k = match self.trees.iter().position(|t| t.tile_size() == side) {
            Some(k) => k,
            None => {
                let tree = MorphTree::new(side).expect("a held grid is 2^g + 1 samples a side");
                self.trees.push(tree);
                self.trees.len() - 1
            }
        };
        let level = compact_level(level, stride);
        view.morph_tile(
            &self.trees[k],
            vertices,
            at,
            (level, stride),
            &mut self.scratch,
        );
        &self.scratch
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::db::grid::TileId;
    use crate::db::mask_level::keeps_index;
    use crate::engine::camera::Camera;
    use crate::engine::viewport::Viewport;

    fn grid(s: usize, height: impl Fn(usize, usize) -> i32) -> Vec<Vertex> {
        (0..s * s)
            .map(|k| {
                let (i, j) = (k % s, k / s);
                let c = (height(i, j).rem_euclid(200) + 20) as u8;
                Vertex::new(
                    [i as i32, height(i, j), j as i32],
                    [0.0, 0.0],
                    [c, c / 2, 255 - c],
                )
            })
            .collect()
    }

    fn bumpy(i: usize, j: usize) -> i32 {
        ((i * 37 + j * 91) % 53) as i32 * 17 - 300 + (i * j) as i32
    }

    #[test]
    fn every_sample_but_the_corners_splits_one_segment_coarsest_first() {
        for s in [2, 3, 5, 9, 17, 65] {
            let tree = MorphTree::new(s).unwrap();
            let mut seen = vec![false; s * s];
            let last = s - 1;
            for k in [0, last, last * s, last * s + last] {
                seen[k] = true;
            }
            for split in tree.splits() {
                assert!(!seen[split.vertex], "s {s}: split twice");
                assert!(
                    split.parents.iter().all(|&p| seen[p]),
                    "s {s}: parent after child"
                );
                let (i, j) = (split.vertex % s, split.vertex / s);
                for p in split.parents {
                    let (pi, pj) = (p % s, p / s);
                    assert_eq!(pi.abs_diff(i).max(pj.abs_diff(j)), split.step);
                }
                seen[split.vertex] = true;
            }
            assert!(seen.iter().all(|&v| v), "s {s}");
        }
        assert!(MorphTree::new(10).is_none());
        assert!(MorphTree::new(1).is_none());
        assert!(MorphTree::new(2).unwrap().splits().is_empty());
    }

    #[test]
    fn a_level_needs_the_samples_it_keeps_and_every_ancestor_of_them_only() {
        let s = 65;
        let tree = MorphTree::new(s).unwrap();
        for level in 0..s - 1 {
            let bits = tree.needs(level);
            let kept = |k: usize| keeps_index(s, level, k % s) && keeps_index(s, level, k / s);
            let mut parents = vec![false; s * s];
            for split in tree.splits() {
                if is_set(bits, split.vertex) {
                    for p in split.parents {
                        assert!(is_set(bits, p), "level {level}: parent {p} missing");
                        parents[p] = true;
                    }
                }
            }
            for (k, &parent) in parents.iter().enumerate() {
                // Set exactly when kept or the parent of a needed sample.
                assert_eq!(is_set(bits, k), kept(k) || parent, "level {level}: {k}");
            }
        }
        let count =
            |level: usize| -> u32 { tree.needs(level).iter().map(|w| w.count_ones()).sum() };
        assert_eq!(
            [count(0), count(2), count(4), count(7)],
            [4225, 1304, 646, 81]
        );
    }

    /// Why `ResidentTile::lit_vertices` lights only the grid a partial tile holds: a level drawn
    /// from a grid of every `g`-th sample (`level + 1` a multiple of `g`) needs, ancestors
    /// included, no sample off that grid.
    #[test]
    fn a_level_needs_only_samples_of_the_grid_it_is_drawn_from() {
        let s = 65;
        let tree = MorphTree::new(s).unwrap();
        for g in [2, 4, 8, 16, 32, 64] {
            for level in (g - 1..s - 1).step_by(g) {
                let bits = tree.needs(level);
                for k in (0..s * s).filter(|&k| is_set(bits, k)) {
                    let (i, j) = (k % s, k / s);
                    assert!(
                        i % g == 0 && j % g == 0,
                        "level {level} needs ({i}, {j}), off the grid of every {g}th sample"
                    );
                }
            }
        }
    }

    /// Why a tile morphs only what its own level needs: whatever its neighbours' levels, no
    /// crack mode's indices read a sample of the grid beyond it.
    #[test]
    fn every_crack_mode_reads_only_the_samples_its_own_level_needs() {
        use crate::engine::cracks::{CrackMode, TileIndices};
        use crate::engine::masks::{LevelSet, MaskSet};
        use stripmask_raster::Indices;
        let s = 17;
        let tree = MorphTree::new(s).unwrap();
        let masks = MaskSet::new(s, LevelSet::All);
        let others = [0, 1, 2, 3, 5, 7, 15];
        for mode in [
            CrackMode::None,
            CrackMode::Shadow,
            CrackMode::Skirts,
            CrackMode::Stitch,
        ] {
            let mut cracks = TileIndices::new(mode, s);
            for level in 0..s - 1 {
                let bits = tree.needs(level);
                for (k, &n) in others.iter().enumerate() {
                    let m = others[(k * 3 + 1) % others.len()];
                    for neighbours in [[n; 4], [n, m, level, n], [m, level, n, m]] {
                        let (indices, _) = cracks.tile(&masks, level, neighbours);
                        let read: Vec<usize> = match indices {
                            Indices::U16(i) => i
                                .iter()
                                .filter(|&&v| v != u16::MAX)
                                .map(|&v| v as usize)
                                .collect(),
                            Indices::U32(i) => i
                                .iter()
                                .filter(|&&v| v != u32::MAX)
                                .map(|&v| v as usize)
                                .collect(),
                        };
                        for v in read.into_iter().filter(|&v| v < s * s) {
                            assert!(
                                is_set(bits, v),
                                "{mode:?} level {level} neighbours {neighbours:?}: sample {v}"
                            );
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn factor_zero_keeps_the_tile_exactly() {
        let s = 17;
        let vertices = grid(s, bumpy);
        let mut out = Vec::new();
        MorphTree::new(s).unwrap().morph(&vertices, |_| 0, &mut out);
        for (m, v) in out.iter().zip(&vertices) {
            assert_eq!(m.position, v.position.map(|c| c * SUBDIVISION));
            assert_eq!(m.color, v.color);
            assert_eq!(m.uv, v.uv);
        }
    }

    /// The height of the coarse grid of `step` samples at `(i, j)`, in SUBDIVISION units:
    /// bilinear on its edges, on the north-west to south-east diagonal split inside its cells.
    fn coarse_surface(vertices: &[Vertex], s: usize, step: usize, i: usize, j: usize) -> i64 {
        let h = |i: usize, j: usize| i64::from(vertices[j * s + i].position[1]) * 256;
        let (i0, j0) = (
            (i / step * step).min(s - 1 - step),
            (j / step * step).min(s - 1 - step),
        );
        let (u, v) = ((i - i0) as i64, (j - j0) as i64);
        let d = step as i64;
        let (h00, h10, h01, h11) = (
            h(i0, j0),
            h(i0 + step, j0),
            h(i0, j0 + step),
            h(i0 + step, j0 + step),
        );
        let sum = if u >= v {
            h00 * d + (h10 - h00) * u + (h11 - h10) * v
        } else {
            h00 * d + (h01 - h00) * v + (h11 - h01) * u
        };
        assert_eq!(
            sum % d,
            0,
            "midpoints of a hierarchy up to 8 deep are exact"
        );
        sum / d
    }

    #[test]
    fn factor_one_below_a_step_gives_exactly_that_coarse_grid_surface() {
        for s in [9, 33, 257] {
            let vertices = grid(s, bumpy);
            let tree = MorphTree::new(s).unwrap();
            let mut out = Vec::new();
            for coarse in [2, 4, 8] {
                tree.morph(
                    &vertices,
                    |split| if split.step < coarse { FACTOR_ONE } else { 0 },
                    &mut out,
                );
                let level = coarse - 1;
                for j in 0..s {
                    for i in 0..s {
                        let y = i64::from(out[j * s + i].position[1]);
                        if keeps_index(s, level, i) && keeps_index(s, level, j) {
                            // The samples of the coarse mask keep their own heights…
                            assert_eq!(y, i64::from(vertices[j * s + i].position[1]) * 256);
                        }
                        // …and every sample lies on the coarse mask's surface.
                        assert_eq!(
                            y,
                            coarse_surface(&vertices, s, coarse, i, j),
                            "s {s} ({i}, {j})"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn a_partial_factor_lands_between_the_own_height_and_the_parents_mean() {
        let s = 3;
        let vertices = grid(s, |i, j| if (i, j) == (1, 0) { 100 } else { 0 });
        let mut out = Vec::new();
        MorphTree::new(s)
            .unwrap()
            .morph(&vertices, |_| FACTOR_ONE / 4, &mut out);
        // (1, 0) splits the north edge between two corners at 0: three quarters of 100 quanta.
        assert_eq!(out[1].position[1], 75 * 256);
    }

    proptest::proptest! {
        /// What a tile's mask reads is morphed exactly as the full morph of the whole tile
        /// morphs it, whether the tile is whole or holds only every `stride`-th sample.
        #[test]
        fn a_tile_morphs_what_its_level_reads_exactly_as_the_full_morph(
            eye in (-200.0..600.0f64, 0.0..300.0f64, -200.0..600.0f64),
            level in 0usize..16,
            stride in proptest::sample::select(vec![1usize, 2, 4, 8, 16]),
            (x, y) in (0u32..4, 0u32..4),
            pixels in 1.0..16.0f64,
        ) {
            let s = 17;
            let terrain = TerrainFrame {
                tiles_x: 4,
                tiles_y: 4,
                tile_size: s,
                spacing: 10.0,
                quantum: 0.25,
                heights: (-100.0, 100.0),
                origin: DVec3::new(1e7, 0.0, -3e6),
                source_samples: (4 * 16 + 1, 4 * 16 + 1),
                archive_origin: (0.0, 0.0),
            };
            let eye = terrain.origin + DVec3::new(eye.0, eye.1, eye.2);
            let camera = Camera::looking_at(eye, eye + DVec3::X);
            let mut morpher = Morpher::new(Geomorph::Distance { pixels }, s).unwrap();
            let view = morpher.view(&View::new(camera, Viewport::new(320, 240), 1.0, 1e5), &terrain);
            let vertices = grid(s, bumpy);
            let tree = MorphTree::new(s).unwrap();
            let (gx0, gz0) = (i64::from(x) * 16, i64::from(y) * 16);
            let mut full = Vec::new();
            tree.morph(
                &vertices,
                |split| {
                    let (i, j) = (split.vertex % s, split.vertex / s);
                    let quanta = vertices[split.vertex].position[1];
                    view.factor(gx0 + i as i64, gz0 + j as i64, quanta, split.step)
                },
                &mut full,
            );
            // The partial grid: every `stride`-th sample, in whole-tile units.
            let side = (s - 1) / stride + 1;
            let held: Vec<Vertex> = (0..side * side)
                .map(|k| vertices[(k / side) * stride * s + (k % side) * stride])
                .collect();
            // A level the held grid draws, and a scratch buffer that held another tile.
            let level = (level / stride + 1) * stride - 1;
            morpher.scratch = vec![Vertex::default(); s * s];
            let out = morpher
                .tile(&view, &held, TileId::new(x, y), level, stride)
                .to_vec();
            for j in (0..s).filter(|&j| keeps_index(s, level, j)) {
                for i in (0..s).filter(|&i| keeps_index(s, level, i)) {
                    let k = (j / stride) * side + i / stride;
                    proptest::prop_assert_eq!(
                        out[k], full[j * s + i], "level {} stride {} ({}, {})", level, stride, i, j
                    );
                }
            }
        }
    }

    #[test]
    fn the_factor_grows_with_distance_from_untouched_to_full() {
        let terrain = TerrainFrame {
            tiles_x: 4,
            tiles_y: 4,
            tile_size: 9,
            spacing: 10.0,
            quantum: 0.25,
            heights: (0.0, 100.0),
            origin: DVec3::new(1e7, 0.0, -3e6),
            source_samples: (33, 33),
            archive_origin: (0.0, 0.0),
        };
        let camera = Camera::looking_at(terrain.origin, terrain.origin + DVec3::X);
        let viewport = Viewport::new(200, 200).with_fov_y(90f64.to_radians());
        // focal = 100 px on a 200 px screen; a 1-sample step (10 m) spans 4 px at 250 m.
        let view = MorphView::new(4.0, &View::new(camera, viewport, 1.0, 1e5), &terrain);
        assert_eq!(view.factor(12, 0, 0, 1), 0, "120 m: 8.3 px");
        assert_eq!(view.factor(25, 0, 0, 1), FACTOR_ONE, "250 m: 4 px");
        assert_eq!(view.factor(50, 0, 0, 1), FACTOR_ONE);
        assert_eq!(view.factor(25, 0, 0, 2), 0, "a 2-sample step spans 8 px");
        let mid = view.factor(0, 18, 3 * 4 * 4 * 2, 1);
        assert!(mid > 0 && mid < FACTOR_ONE, "{mid}");
        assert!(Morpher::new(Geomorph::Off, 9).is_none());
        assert!(Morpher::new(Geomorph::DISTANCE, 9).is_some());
    }
}
