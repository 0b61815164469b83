//! Helpers shared by the rasterizer's integration tests.

#![allow(dead_code)] // each test target uses a different part

use glam::DMat4;
use stripmask_raster::*;

/// Scale from NDC to integer model units in `clip_mesh` vertices.
pub const UNIT: f64 = (1 << 16) as f64;

/// A transform under which a vertex `(x, y, w)` (integers) lands at NDC `(x / w, y / w)` with clip
/// `w = w / UNIT` and depth 0.5: lets a test place vertices on screen exactly while choosing `w`.
pub fn projective() -> Transform {
    let m = DMat4::from_cols_array(&[
        1.0 / UNIT,
        0.0,
        0.0,
        0.0, // column 0: x
        0.0,
        1.0 / UNIT,
        0.0,
        0.0, // column 1: y
        0.0,
        0.0,
        0.5 / UNIT,
        1.0 / UNIT, // column 2: the w input feeds z and w
        0.0,
        0.0,
        0.0,
        0.0,
    ]);
    Transform::new(m).unwrap()
}

/// A vertex at NDC `(nx, ny)` with clip `w`.
pub fn at(nx: f64, ny: f64, w: f64) -> Vertex {
    let p = [nx * w * UNIT, ny * w * UNIT, w * UNIT].map(|c| c.round() as i32);
    Vertex::new(p, [0.0, 0.0], [255, 255, 255])
}

/// Draws every triangle of `tris` on its own and counts, per pixel, how many triangles wrote it.
pub fn hit_counts(
    size: (u32, u32),
    vertices: &[Vertex],
    tris: &[[u32; 3]],
    precision: Precision,
) -> Vec<u32> {
    let transform = projective();
    let mut fb = Framebuffer::new(size.0, size.1, ColorFormat::Rgb565, DepthFormat::None).unwrap();
    let mut counts = vec![0u32; (size.0 * size.1) as usize];
    let mut r = Rasterizer::with_threads(1);
    let state = RenderState {
        precision,
        depth: DepthMode::NONE,
        ..RenderState::default()
    };
    for t in tris {
        fb.clear_color([0, 0, 0]);
        let mesh = Mesh {
            vertices,
            indices: Indices::U32(t),
            topology: Topology::TriangleList,
        };
        r.draw(&mut fb, &mesh, &transform, &state).unwrap();
        let ColorBuffer::Rgb565(px) = fb.color() else {
            unreachable!()
        };
        for (c, p) in counts.iter_mut().zip(px) {
            *c += (*p != 0) as u32;
        }
    }
    counts
}

/// Triangles of a `cols x rows` grid of vertices, each cell split along a chosen diagonal.
pub fn grid_triangles(cols: u32, rows: u32, flip: impl Fn(u32, u32) -> bool) -> Vec<[u32; 3]> {
    let mut out = vec![];
    for j in 0..rows - 1 {
        for i in 0..cols - 1 {
            let (a, b, c, d) = (
                j * cols + i,
                j * cols + i + 1,
                (j + 1) * cols + i,
                (j + 1) * cols + i + 1,
            );
            if flip(i, j) {
                out.push([a, b, d]);
                out.push([a, d, c]);
            } else {
                out.push([a, b, c]);
                out.push([b, d, c]);
            }
        }
    }
    out
}

/// Property-test case count: `PROPTEST_CASES` when set, else `default`.
pub fn cases(default: u32) -> u32 {
    std::env::var("PROPTEST_CASES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}
