//! Skirts: a band of vertical triangles hanging from each tile border, deep enough to close any
//! gap a neighbour at another level leaves, textured by stretching the border texels.
//!
//! A tile in skirts mode holds `4 s` more vertices after its `s x s` grid: for each side in
//! [`Side::ALL`] order, a copy of its `s` border vertices (same uv, same colour) lowered by the
//! tile's skirt depth; vertex `s² + side · s + t` hangs under border sample `t` of `side`
//! (counted along increasing `i` or `j`). At level `l` the skirt joins the border samples `l`
//! keeps, so one index buffer per level — the mask's strips followed by four skirt strips —
//! serves every tile. Skirts face outwards (clockwise seen from outside the tile); from inside
//! they are back faces and cost nothing.
//!
//! Depth: where two tiles meet, each border is within its level's error of the true border, so
//! the gap is at most the sum of both errors. A skirt hangs twice the tile's largest level error
//! plus one quantum, which closes the gap when the neighbour's error is no larger.

use std::sync::OnceLock;

use stripmask_raster::Vertex;

use super::Side;
use crate::db::mask_level::{kept_indices, level_count};
use crate::engine::masks::{MaskIndices, MaskSet};

/// Extra vertices a tile of `tile_size` samples per side holds for its skirts.
pub fn vertex_count(tile_size: usize) -> usize {
    4 * tile_size
}

/// Skirt depth in height quanta of a tile whose mask levels have `level_errors` metres of error,
/// with `quantum` metres per quantum.
pub fn depth_quanta(level_errors: &[f32], quantum: f32) -> i32 {
    let worst = level_errors.iter().copied().fold(0.0f32, f32::max);
    (2.0 * worst / quantum).ceil() as i32 + 1
}

/// Appends the skirt vertices of a tile of `s x s` `vertices` (row-major), `depth` quanta below
/// its border vertices.
pub fn append_vertices(vertices: &mut Vec<Vertex>, s: usize, depth: i32) {
    debug_assert_eq!(vertices.len(), s * s);
    for side in Side::ALL {
        for t in 0..s {
            let mut v = vertices[border_vertex(s, side, t)];
            v.position[1] -= depth;
            vertices.push(v);
        }
    }
}

/// Gives the skirt vertex under every `step`-th border sample of a tile of `s x s` grid
/// vertices (row-major, then its skirts) the colour of that border vertex: the skirts of a
/// tile relit for a coarser level.
pub fn copy_border_colors(vertices: &mut [Vertex], s: usize, step: usize) {
    for side in Side::ALL {
        for t in (0..s).step_by(step) {
            vertices[skirt_vertex(s, side, t)].color = vertices[border_vertex(s, side, t)].color;
        }
    }
}

/// The grid vertex of border sample `t` of `side`.
fn border_vertex(s: usize, side: Side, t: usize) -> usize {
    match side {
        Side::North => t,
        Side::East => t * s + s - 1,
        Side::South => (s - 1) * s + t,
        Side::West => t * s,
    }
}

/// The skirt vertex under border sample `t` of `side`.
fn skirt_vertex(s: usize, side: Side, t: usize) -> usize {
    s * s + side as usize * s + t
}

/// The strip masks with skirts, one index buffer per level, built lazily and shared by every
/// tile. `Sync`, like [`MaskSet`].
#[derive(Debug)]
pub struct SkirtSet {
    tile_size: usize,
    indices: Vec<OnceLock<MaskIndices>>,
}

impl SkirtSet {
    /// The skirted masks of tiles with `tile_size` samples per side.
    pub fn new(tile_size: usize) -> SkirtSet {
        SkirtSet {
            tile_size,
            indices: (0..level_count(tile_size))
                .map(|_| OnceLock::new())
                .collect(),
        }
    }

    /// The strips of `level` (draw with `Topology::TriangleStrip`): the mask of `masks`, then
    /// the four skirts. Built on first use.
    pub fn indices(&self, masks: &MaskSet, level: usize) -> &MaskIndices {
        self.indices[level].get_or_init(|| {
            let s = self.tile_size;
            let mut out: Vec<usize> = match masks.indices(level) {
                MaskIndices::U16(i) => i.iter().map(|&v| restart_or(v == u16::MAX, v)).collect(),
                MaskIndices::U32(i) => i.iter().map(|&v| restart_or(v == u32::MAX, v)).collect(),
            };
            for side in Side::ALL {
                out.push(usize::MAX);
                out.extend(strip(s, level, side));
            }
            MaskIndices::narrowest(s * s + vertex_count(s), out)
        })
    }
}

fn restart_or(restart: bool, v: impl Into<u32>) -> usize {
    if restart {
        usize::MAX
    } else {
        v.into() as usize
    }
}

/// The skirt strip of `side` at `level`: border and skirt vertices in turn at every kept sample,
/// ordered so that the triangles face outwards. North and east run (border, skirt); south and
/// west, mirrors of them, run (skirt, border).
fn strip(s: usize, level: usize, side: Side) -> Vec<usize> {
    let mirrored = matches!(side, Side::South | Side::West);
    kept_indices(s, level)
        .into_iter()
        .flat_map(|t| {
            let (b, k) = (border_vertex(s, side, t), skirt_vertex(s, side, t));
            if mirrored { [k, b] } else { [b, k] }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use glam::DVec3;
    use stripmask_raster::{
        ColorFormat, CullMode, DepthFormat, DepthMode, Framebuffer, Indices, Mesh, Rasterizer,
        RenderState, Topology, Transform,
    };

    use super::*;
    use crate::engine::masks::{FRONT_FACE, LevelSet};

    fn tile(s: usize, depth: i32) -> Vec<Vertex> {
        let mut v: Vec<Vertex> = (0..s * s)
            .map(|k| {
                let (i, j) = (k % s, k / s);
                let uv = [i as f32 / (s - 1) as f32, j as f32 / (s - 1) as f32];
                Vertex::new([i as i32, ((i + 2 * j) % 3) as i32, j as i32], uv, [200; 3])
            })
            .collect();
        append_vertices(&mut v, s, depth);
        v
    }

    #[test]
    fn skirt_vertices_copy_the_border_lowered_by_the_depth() {
        let s = 5;
        let v = tile(s, 7);
        assert_eq!(v.len(), s * s + vertex_count(s));
        for side in Side::ALL {
            for t in 0..s {
                let (b, k) = (v[border_vertex(s, side, t)], v[skirt_vertex(s, side, t)]);
                assert_eq!(
                    k.position,
                    [b.position[0], b.position[1] - 7, b.position[2]]
                );
                assert_eq!((k.uv, k.color), (b.uv, b.color));
            }
        }
        assert_eq!(v[border_vertex(s, Side::East, 1)].position, [4, 0, 1]);
        assert_eq!(v[border_vertex(s, Side::South, 1)].position, [1, 0, 4]);
        assert_eq!(depth_quanta(&[0.0, 0.3, 1.2, 0.7], 0.25), 11);
    }

    /// Pixels drawn when the skirt of `side` at `level` alone is seen horizontally from far out
    /// along `from`, at the skirt's height, back faces culled.
    fn skirt_seen_from(s: usize, level: usize, side: Side, from: DVec3) -> u64 {
        let vertices = tile(s, 40);
        let indices: Vec<u16> = strip(s, level, side).iter().map(|&v| v as u16).collect();
        let mesh = Mesh {
            vertices: &vertices,
            indices: Indices::U16(&indices),
            topology: Topology::TriangleStrip,
        };
        let c = (s - 1) as f64 / 2.0;
        let centre = DVec3::new(c, -20.0, c);
        let view = glam::dcamera::rh::view::look_at_mat4(centre + 100.0 * from, centre, DVec3::Y);
        let proj = glam::dcamera::rh::proj::directx::orthographic(-c, c, -22.0, 22.0, 1.0, 200.0);
        let mut fb = Framebuffer::new(64, 64, ColorFormat::Rgba8888, DepthFormat::None).unwrap();
        let state = RenderState {
            cull: CullMode::Back,
            front_face: FRONT_FACE,
            depth: DepthMode::NONE,
            ..RenderState::default()
        };
        let stats = Rasterizer::new()
            .draw(
                &mut fb,
                &mesh,
                &Transform::new(proj * view).unwrap(),
                &state,
            )
            .unwrap();
        assert_eq!(
            stats.triangles as usize,
            2 * (kept_indices(s, level).len() - 1)
        );
        stats.fragments
    }

    #[test]
    fn each_skirt_faces_outwards_and_covers_its_side() {
        let s = 9;
        for level in [0, 1, 2, 7] {
            for (side, outward) in
                Side::ALL
                    .into_iter()
                    .zip([DVec3::NEG_Z, DVec3::X, DVec3::Z, DVec3::NEG_X])
            {
                // From outside, the skirt fills 40 (border height 0 to 2) of the 44 quanta framed
                // across the whole width; from inside it is a back face.
                let drawn = skirt_seen_from(s, level, side, outward);
                let at = format!("{side:?} at level {level}");
                assert!(
                    (64 * 38 / 44..=64 * 42 / 44).contains(&(drawn / 64)),
                    "{at}: {drawn}"
                );
                assert_eq!(skirt_seen_from(s, level, side, -outward), 0, "{at}");
            }
        }
    }

    #[test]
    fn a_level_draws_its_mask_then_its_four_skirts() {
        let s = 9;
        let masks = MaskSet::new(s, LevelSet::All);
        let skirts = SkirtSet::new(s);
        for level in 0..s - 1 {
            let MaskIndices::U16(all) = skirts.indices(&masks, level) else {
                panic!("81 + 36 vertices take u16 indices")
            };
            let MaskIndices::U16(mask) = masks.indices(level) else {
                panic!("81 vertices take u16 indices")
            };
            assert_eq!(&all[..mask.len()], &mask[..]);
            let rest: Vec<usize> = all[mask.len()..].iter().map(|&v| v as usize).collect();
            let want: Vec<usize> = Side::ALL
                .into_iter()
                .flat_map(|side| {
                    std::iter::once(usize::MAX as u16 as usize).chain(strip(s, level, side))
                })
                .collect();
            assert_eq!(rest, want, "level {level}");
        }
    }
}
