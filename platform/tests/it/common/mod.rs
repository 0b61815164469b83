//! Frames with arbitrary pixels, painted through the rasterizer's public API: one flat
//! triangle over the whole target per pixel, clipped to that pixel by the scissor.

use stripmask_raster::{
    ColorFormat, DepthFormat, DepthMode, Framebuffer, Indices, Mesh, Rasterizer, Rect, RenderState,
    Shading, Topology, Transform, Vertex,
};

/// A `width` x `height` frame in `format` whose pixel (x, y) is `color(x, y)` (as the format
/// stores it).
pub fn painted(
    width: u32,
    height: u32,
    format: ColorFormat,
    color: impl Fn(u32, u32) -> [u8; 3],
) -> Framebuffer {
    let mut fb = Framebuffer::new(width, height, format, DepthFormat::None).unwrap();
    let vertices = [
        Vertex::new([-1, -1, 0], [0.0, 0.0], [255; 3]),
        Vertex::new([3, -1, 0], [0.0, 0.0], [255; 3]),
        Vertex::new([-1, 3, 0], [0.0, 0.0], [255; 3]),
    ];
    let mesh = Mesh {
        vertices: &vertices,
        indices: Indices::U16(&[0, 1, 2]),
        topology: Topology::TriangleList,
    };
    let transform = Transform::new(glam::DMat4::IDENTITY).unwrap();
    let mut raster = Rasterizer::with_threads(1);
    for y in 0..height {
        for x in 0..width {
            let state = RenderState {
                depth: DepthMode::NONE,
                shading: Shading::Flat(color(x, y)),
                scissor: Some(Rect {
                    x0: x,
                    y0: y,
                    x1: x + 1,
                    y1: y + 1,
                }),
                ..RenderState::default()
            };
            raster.draw(&mut fb, &mesh, &transform, &state).unwrap();
        }
    }
    fb
}

/// A colour that differs from its neighbours in every channel, so a misplaced pixel shows.
pub fn pattern(x: u32, y: u32) -> [u8; 3] {
    [
        (x * 37 + y * 11 + 20) as u8,
        (x * 13 + y * 71 + 90) as u8,
        (x * 101 + y * 29 + 160) as u8,
    ]
}
