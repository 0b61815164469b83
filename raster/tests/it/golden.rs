//! Golden images of the rasterizer, one per behaviour, in `raster/tests/golden/`, compared byte
//! for byte (rendering is deterministic, on every CPU). Re-bless after an intended change with
//! `STRIPMASK_BLESS=1 cargo test -p stripmask-raster --profile suite --test it golden` and explain
//! the change in the commit; on a mismatch the new picture is written to
//! `raster/target/golden-failures/` for inspection.

use std::path::Path;

use glam::DVec3;
use stripmask_raster::*;

use crate::golden_check::check_in;
use crate::scene;

/// Compares `fb` with `raster/tests/golden/{name}.png`.
fn check(name: &str, fb: &Framebuffer) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    check_in(
        &root.join("tests/golden"),
        &root.join("target/golden-failures"),
        name,
        fb,
    );
}

fn terrain(
    precision: Precision,
    color: ColorFormat,
    depth: DepthFormat,
    edit: impl Fn(&mut RenderState),
) -> Framebuffer {
    let s = scene::terrain(72, 320, 240);
    let mut fb = Framebuffer::new(320, 240, color, depth).unwrap();
    fb.clear([150, 180, 220]);
    let mut state = RenderState {
        precision,
        ..s.state()
    };
    edit(&mut state);
    Rasterizer::new()
        .draw(&mut fb, &s.mesh(), &s.transform, &state)
        .unwrap();
    fb
}

#[test]
fn pocketpc_frame_fixed_rgb565_depth16() {
    check(
        "pocketpc_frame_fixed_rgb565_depth16",
        &terrain(
            Precision::Fixed,
            ColorFormat::Rgb565,
            DepthFormat::D16,
            |_| {},
        ),
    );
}

#[test]
fn pocketpc_frame_float_reference_rgba8888_depth32() {
    check(
        "pocketpc_frame_float_reference_rgba8888_depth32",
        &terrain(
            Precision::Float,
            ColorFormat::Rgba8888,
            DepthFormat::D32,
            |_| {},
        ),
    );
}

#[test]
fn fog_blends_distance_towards_the_sky() {
    let fb = terrain(
        Precision::Fixed,
        ColorFormat::Rgba8888,
        DepthFormat::D16,
        |s| {
            s.fog = Some(Fog {
                color: [150, 180, 220],
                start: 40_000.0,
                end: 220_000.0,
            })
        },
    );
    check("fog_blends_distance_towards_the_sky", &fb);
}

/// A checkerboard floor receding to the horizon: shows what each perspective mode gets wrong.
fn floor(perspective: Perspective, sampler: Sampler) -> Framebuffer {
    let side = 64;
    let texels = (0..side * side)
        .map(|k| {
            if (k % side / 8 + k / side / 8) % 2 == 0 {
                0xFFFF
            } else {
                0x001F
            }
        })
        .collect();
    let tex = Texture::from_rgb565(side, side, texels)
        .unwrap()
        .with_mipmaps();
    let e = 1000;
    let v = [[-e, 0, -20 * e], [e, 0, -20 * e], [-e, 0, 0], [e, 0, 0]].map(|p| {
        Vertex::new(
            p,
            [
                (p[0] + e) as f32 / (2 * e) as f32 * 2.0,
                -p[2] as f32 / e as f32,
            ],
            [255; 3],
        )
    });
    let m = glam::dcamera::rh::proj::directx::perspective(1.0, 1.0, 10.0, 1e6)
        * glam::dcamera::rh::view::look_at_mat4(
            DVec3::new(0.0, 300.0, 200.0),
            DVec3::new(0.0, 0.0, -3000.0),
            DVec3::Y,
        );
    let mut fb = Framebuffer::new(128, 128, ColorFormat::Rgba8888, DepthFormat::None).unwrap();
    let state = RenderState {
        perspective,
        texture: Some(TextureBinding::new(
            &tex,
            Sampler {
                wrap: Wrap::Repeat,
                ..sampler
            },
        )),
        ..RenderState::default()
    };
    let mesh = Mesh {
        vertices: &v,
        indices: Indices::U16(&[0, 2, 1, 3]),
        topology: Topology::TriangleStrip,
    };
    Rasterizer::new()
        .draw(&mut fb, &mesh, &Transform::new(m).unwrap(), &state)
        .unwrap();
    fb
}

#[test]
fn perspective_exact_keeps_checkers_straight() {
    check(
        "perspective_exact_keeps_checkers_straight",
        &floor(Perspective::Exact, Sampler::NEAREST),
    );
}

#[test]
fn perspective_spans_of_16_bend_checkers_slightly() {
    check(
        "perspective_spans_of_16_bend_checkers_slightly",
        &floor(Perspective::Spans(16), Sampler::NEAREST),
    );
}

#[test]
fn perspective_affine_bends_checkers_along_the_diagonal() {
    check(
        "perspective_affine_bends_checkers_along_the_diagonal",
        &floor(Perspective::Affine, Sampler::NEAREST),
    );
}

#[test]
fn mipmapping_removes_far_aliasing() {
    check(
        "mipmapping_removes_far_aliasing",
        &floor(Perspective::Exact, Sampler::BILINEAR_MIPMAP),
    );
}

#[test]
fn depth_test_resolves_interpenetrating_triangles() {
    let v = [
        Vertex::new([-800, -600, -1000], [0.0, 0.0], [255, 40, 40]),
        Vertex::new([800, -600, -3000], [0.0, 0.0], [255, 40, 40]),
        Vertex::new([0, 700, -2000], [0.0, 0.0], [255, 200, 40]),
        Vertex::new([-800, 600, -3000], [0.0, 0.0], [40, 40, 255]),
        Vertex::new([800, 600, -1000], [0.0, 0.0], [40, 40, 255]),
        Vertex::new([0, -700, -2000], [0.0, 0.0], [40, 200, 255]),
    ];
    let m = glam::dcamera::rh::proj::directx::perspective(1.0, 1.0, 100.0, 1e4);
    for (name, depth) in [
        (
            "depth16_resolves_interpenetrating_triangles",
            DepthFormat::D16,
        ),
        (
            "depth32_resolves_interpenetrating_triangles",
            DepthFormat::D32,
        ),
    ] {
        let mut fb = Framebuffer::new(96, 96, ColorFormat::Rgb565, depth).unwrap();
        let state = RenderState {
            shading: Shading::Gouraud,
            ..RenderState::default()
        };
        let mesh = Mesh {
            vertices: &v,
            indices: Indices::U16(&[0, 1, 2, 3, 4, 5]),
            topology: Topology::TriangleList,
        };
        Rasterizer::new()
            .draw(&mut fb, &mesh, &Transform::new(m).unwrap(), &state)
            .unwrap();
        check(name, &fb);
    }
}
