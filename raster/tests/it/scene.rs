//! A synthetic terrain scene shared by the golden-image tests and the benchmarks: a height field
//! of `grid x grid` vertices drawn as triangle strips (one per row pair, joined by restarts),
//! lit per vertex, with a height-ramp texture, seen obliquely as from a low-flying aircraft.

#![allow(dead_code)] // each including target uses a different part

use glam::{DMat4, DVec3};
use stripmask_raster::*;

/// Geometry, texture and camera of one scene.
pub struct Scene {
    pub vertices: Vec<Vertex>,
    pub indices: Vec<u32>,
    pub texture: Texture,
    pub transform: Transform,
}

impl Scene {
    /// Triangles the strips describe.
    pub fn triangles(grid: u32) -> u64 {
        2 * (grid as u64 - 1) * (grid as u64 - 1)
    }

    pub fn mesh(&self) -> Mesh<'_> {
        Mesh {
            vertices: &self.vertices,
            indices: Indices::U32(&self.indices),
            topology: Topology::TriangleStrip,
        }
    }

    /// The default state: everything on, as the terrain renderer uses it.
    pub fn state(&self) -> RenderState<'_> {
        RenderState {
            cull: CullMode::Back,
            shading: Shading::Gouraud,
            texture: Some(TextureBinding::new(&self.texture, Sampler::BILINEAR_MIPMAP)),
            perspective: Perspective::Spans(16),
            ..RenderState::default()
        }
    }

    /// The state of the peer benchmark (`../shared/anchorbench`), drawn into RGBA8888 colour
    /// and 32-bit depth: bilinear without mipmaps, repeating, exact perspective, no culling.
    pub fn peers_state(&self) -> RenderState<'_> {
        let sampler = Sampler {
            wrap: Wrap::Repeat,
            ..Sampler::BILINEAR
        };
        RenderState {
            shading: Shading::Gouraud,
            texture: Some(TextureBinding::new(&self.texture, sampler)),
            perspective: Perspective::Exact,
            ..RenderState::default()
        }
    }

    /// The peer benchmark's state and the terrain default, each named and with the colour and
    /// depth formats it is drawn into: what the thread examples measure.
    pub fn both_states(&self) -> [(&'static str, ColorFormat, DepthFormat, RenderState<'_>); 2] {
        [
            (
                "peers' state",
                ColorFormat::Rgba8888,
                DepthFormat::D32,
                self.peers_state(),
            ),
            (
                "terrain default",
                ColorFormat::Rgb565,
                DepthFormat::D16,
                self.state(),
            ),
        ]
    }
}

fn height(x: f64, y: f64) -> f64 {
    // Rolling hills plus ridges, in model units (one unit = 1/64 of a grid cell vertically).
    let h = (x * 0.11).sin() * (y * 0.07).cos() * 300.0
        + (x * 0.031 + y * 0.023).sin() * 900.0
        + ((x * 0.37).sin() * (y * 0.41).sin()).abs() * 120.0;
    h + 1300.0
}

/// Builds the scene for a `width x height` target.
pub fn terrain(grid: u32, width: u32, height_px: u32) -> Scene {
    let g = grid as usize;
    // The grid always spans the same 160 x 160 cells, so any `grid` shows the same landscape.
    let span = 160.0;
    let cell = span / (g - 1) as f64;
    let units_per_cell = 1024.0;
    let mut vertices = Vec::with_capacity(g * g);
    let light = DVec3::new(-0.5, 0.8, -0.3).normalize();
    for j in 0..g {
        for i in 0..g {
            let (x, y) = (i as f64 * cell, j as f64 * cell);
            let h = height(x, y);
            let e = 0.5;
            let n = DVec3::new(
                height(x - e, y) - height(x + e, y),
                2.0 * e * 64.0,
                height(x, y - e) - height(x, y + e),
            )
            .normalize();
            let lum = (60.0 + 195.0 * n.dot(light).max(0.0)) as u8;
            vertices.push(Vertex::new(
                [
                    (x * units_per_cell) as i32,
                    (h * 16.0) as i32,
                    (y * units_per_cell) as i32,
                ],
                [(x / span) as f32 * 4.0, (y / span) as f32 * 4.0],
                [lum, lum, lum],
            ));
        }
    }
    let mut indices = Vec::with_capacity((g - 1) * (2 * g + 1));
    for j in 0..g - 1 {
        for i in 0..g {
            indices.push((j * g + i) as u32);
            indices.push(((j + 1) * g + i) as u32);
        }
        indices.push(u32::MAX);
    }
    let side = 256u32;
    let texels = (0..side * side)
        .map(|k| {
            let (x, y) = (k % side, k / side);
            let check = ((x / 32) + (y / 32)) % 2 == 0;
            let base = if check {
                [110, 150, 70]
            } else {
                [150, 130, 90]
            };
            let grain = ((x * 7 + y * 13) % 17) as u8;
            rgb_to_rgb565([base[0] + grain, base[1] + grain, base[2] + grain])
        })
        .collect();
    let texture = Texture::from_rgb565(side, side, texels)
        .unwrap()
        .with_mipmaps();
    let s = units_per_cell;
    let eye = DVec3::new(80.0 * s, 4200.0 * 16.0, 175.0 * s);
    let target = DVec3::new(80.0 * s, 0.0, 40.0 * s);
    let projection = glam::dcamera::rh::proj::directx::perspective(
        1.0,
        width as f64 / height_px as f64,
        1000.0,
        600.0 * s,
    );
    let view = glam::dcamera::rh::view::look_at_mat4(eye, target, DVec3::Y);
    let transform = Transform::new(projection * view * DMat4::IDENTITY).unwrap();
    Scene {
        vertices,
        indices,
        texture,
        transform,
    }
}
