//! Views for the crack-hiding unit tests: a tile from straight above, and two neighbouring tiles
//! with rough relief seen obliquely across their shared edge.

use glam::{DMat4, DVec3};
use stripmask_raster::{
    ColorFormat, CullMode, DepthFormat, DepthMode, Framebuffer, Mesh, Rasterizer, RenderState,
    Topology, Transform, Vertex,
};

use crate::engine::masks::{FRONT_FACE, MaskIndices};

/// Side of the square top view, pixels.
const SIDE: u32 = 64;
/// Pixels of the top view.
pub const PIXELS: u64 = (SIDE * SIDE) as u64;
const BACKGROUND: [u8; 3] = [255, 0, 255];

/// Draws `mesh` (a tile of `s` samples, vertex `(i, h, j)`) from straight above, framing the
/// tile exactly, back faces culled with `front` as the front face. Returns the fragments drawn
/// and the pixels covered.
pub fn draw_from_above(s: usize, mesh: &Mesh, front: stripmask_raster::FrontFace) -> (u64, u64) {
    let c = (s - 1) as f64 / 2.0;
    let view = glam::dcamera::rh::view::look_at_mat4(
        DVec3::new(c, 100.0, c),
        DVec3::new(c, 0.0, c),
        DVec3::NEG_Z,
    );
    let proj: DMat4 = glam::dcamera::rh::proj::directx::orthographic(-c, c, -c, c, 1.0, 200.0);
    let mut fb = Framebuffer::new(SIDE, SIDE, ColorFormat::Rgba8888, DepthFormat::None).unwrap();
    fb.clear(BACKGROUND);
    let state = RenderState {
        cull: CullMode::Back,
        front_face: front,
        depth: DepthMode::NONE,
        ..RenderState::default()
    };
    let stats = Rasterizer::new()
        .draw(&mut fb, mesh, &Transform::new(proj * view).unwrap(), &state)
        .unwrap();
    (stats.fragments, (PIXELS as usize - holes(&fb)) as u64)
}

/// Height of grid sample `(gi, gj)` of the two-tile terrain, in 1/16 of a grid step: ridges one
/// or two samples wide, so that coarse levels miss a lot.
fn height(gi: usize, gj: usize) -> i32 {
    let (x, z) = (gi as f64, gj as f64);
    (20.0 * (1.0 + (1.9 * x).sin() * (1.3 * z).cos())).round() as i32
}

/// The vertices of tile `tx` (0 west, 1 east) of the two-tile terrain.
fn tile_vertices(s: usize, tx: usize) -> Vec<Vertex> {
    (0..s * s)
        .map(|k| {
            let (i, j) = (k % s, k / s);
            let h = height(tx * (s - 1) + i, j);
            Vertex::new([i as i32, h, j as i32], [0.0, 0.0], [255; 3])
        })
        .collect()
}

/// Background pixels when two tiles of `s` samples, side by side, are drawn with `west` and
/// `east` as index buffers, seen obliquely across their shared edge (the terrain covers the
/// whole view).
fn holes_between(s: usize, tiles: [(&MaskIndices, Topology); 2]) -> usize {
    let edge = (s - 1) as f64;
    let view = glam::dcamera::rh::view::look_at_mat4(
        DVec3::new(edge + 2.5, 5.0, 0.5 * edge + 2.5),
        DVec3::new(edge, 0.0, 0.5 * edge),
        DVec3::Y,
    );
    let proj = glam::dcamera::rh::proj::directx::perspective(0.5, 1.0, 0.1, 100.0);
    let model = DMat4::from_scale(DVec3::new(1.0, 1.0 / 16.0, 1.0));
    let base = Transform::new(proj * view * model).unwrap();
    let mut fb = Framebuffer::new(96, 96, ColorFormat::Rgba8888, DepthFormat::None).unwrap();
    fb.clear(BACKGROUND);
    let state = RenderState {
        cull: CullMode::Back,
        front_face: FRONT_FACE,
        depth: DepthMode::NONE,
        ..RenderState::default()
    };
    let mut rasterizer = Rasterizer::new();
    for (tx, (indices, topology)) in tiles.into_iter().enumerate() {
        let vertices = tile_vertices(s, tx);
        let mesh = Mesh {
            vertices: &vertices,
            indices: indices.as_indices(),
            topology,
        };
        let transform = base.with_origin([(tx * (s - 1)) as i32, 0, 0]).unwrap();
        rasterizer.draw(&mut fb, &mesh, &transform, &state).unwrap();
    }
    holes(&fb)
}

/// [`holes_between`] two stitched tiles (triangle lists).
pub fn holes_between_two_tiles(s: usize, west: &MaskIndices, east: &MaskIndices) -> usize {
    holes_between(
        s,
        [
            (west, Topology::TriangleList),
            (east, Topology::TriangleList),
        ],
    )
}

/// [`holes_between`] two tiles drawn with plain strip masks.
pub fn holes_between_two_strip_tiles(s: usize, west: &MaskIndices, east: &MaskIndices) -> usize {
    holes_between(
        s,
        [
            (west, Topology::TriangleStrip),
            (east, Topology::TriangleStrip),
        ],
    )
}

fn holes(fb: &Framebuffer) -> usize {
    fb.to_rgba_image()
        .pixels()
        .filter(|p| p.0[..3] == BACKGROUND)
        .count()
}
