//! Extremes: huge coordinates, the guard band, the near plane and `w` near zero, sub-pixel and
//! degenerate triangles, 1x1 and 4096x4096 targets. Nothing may panic or wrap (the test profile
//! keeps overflow checks on), and coverage must stay right.

use crate::common;

use common::*;
use glam::{DMat4, DVec3};
use proptest::prelude::*;
use stripmask_raster::*;

const BOTH: [Precision; 2] = [Precision::Fixed, Precision::Float];

fn draw(
    size: (u32, u32),
    v: &[Vertex],
    idx: &[u32],
    m: DMat4,
    precision: Precision,
) -> (Framebuffer, DrawStats) {
    let mut fb = Framebuffer::new(size.0, size.1, ColorFormat::Rgb565, DepthFormat::D32).unwrap();
    // Coverage only: no depth test (f32 depth cannot tell 1 - 1e-9 from the cleared far plane).
    let state = RenderState {
        precision,
        depth: DepthMode::NONE,
        shading: Shading::Flat([255, 255, 255]),
        ..RenderState::default()
    };
    let mesh = Mesh {
        vertices: v,
        indices: Indices::U32(idx),
        topology: Topology::TriangleStrip,
    };
    let stats = Rasterizer::new()
        .draw(&mut fb, &mesh, &Transform::new(m).unwrap(), &state)
        .unwrap();
    (fb, stats)
}

fn camera(eye: DVec3, target: DVec3, near: f64, far: f64, aspect: f64) -> DMat4 {
    glam::dcamera::rh::proj::directx::perspective(1.0, aspect, near, far)
        * glam::dcamera::rh::view::look_at_mat4(eye, target, DVec3::Y)
}

fn quad(p: [[i32; 3]; 4]) -> Vec<Vertex> {
    p.iter()
        .map(|&q| Vertex::new(q, [0.0, 0.0], [255; 3]))
        .collect()
}

#[test]
fn a_wall_at_a_billion_units_fills_the_screen() {
    let b = 2_000_000_000;
    let v = quad([
        [-b, -b, -1_000_000_000],
        [b, -b, -1_000_000_000],
        [-b, b, -1_000_000_000],
        [b, b, -1_000_000_000],
    ]);
    let m = camera(DVec3::ZERO, -DVec3::Z, 1.0, 1e10, 4.0 / 3.0);
    for p in BOTH {
        let (_, s) = draw((64, 48), &v, &[0, 1, 2, 3], m, p);
        assert_eq!(s.fragments, 64 * 48, "{p:?}");
    }
}

#[test]
fn a_ground_plane_through_the_eye_plane_covers_exactly_below_the_horizon() {
    let e = 1_000_000;
    let v = quad([[-e, 0, -e], [e, 0, -e], [-e, 0, e], [e, 0, e]]);
    // Eye 1 unit above the plane, looking at the horizon: the plane spans behind and ahead.
    let m = camera(
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::new(0.0, 1.0, -1.0),
        0.01,
        1e7,
        1.0,
    );
    for p in BOTH {
        let (fb, s) = draw((64, 64), &v, &[0, 1, 2, 3], m, p);
        assert!(
            s.rasterized >= 2,
            "{p:?}: near-plane clipping yields triangles"
        );
        for y in 0..64 {
            let covered = (0..64).filter(|&x| fb.pixel(x, y) != [0, 0, 0]).count();
            if y < 30 {
                assert_eq!(covered, 0, "{p:?}: sky row {y}");
            } else if y >= 34 {
                assert_eq!(covered, 64, "{p:?}: ground row {y}");
            }
        }
    }
}

#[test]
fn a_vertex_on_the_eye_plane_is_clipped_not_divided_by_zero() {
    let v = quad([[0, 0, 0], [10, 0, -10], [-10, 5, -10], [10, 5, -10]]);
    let m = camera(DVec3::ZERO, -DVec3::Z, 1e-3, 1e6, 1.0);
    for p in BOTH {
        let (_, s) = draw((32, 32), &v, &[0, 1, 2, 3], m, p);
        assert!(s.fragments > 0, "{p:?}");
    }
}

#[test]
fn triangles_far_past_the_guard_band_are_clipped_to_full_coverage() {
    let big = 1 << 30;
    let v = quad([
        [-big, -big, 0],
        [big, -big, 0],
        [-big, big, 0],
        [big, big, 0],
    ]);
    let m = glam::dcamera::rh::proj::directx::orthographic(-1.0, 1.0, -1.0, 1.0, -1.0, 1.0);
    for size in [(1, 1), (3, 2), (257, 129)] {
        for p in BOTH {
            let (_, s) = draw(size, &v, &[0, 1, 2, 3], m, p);
            assert_eq!(s.fragments, (size.0 * size.1) as u64, "{p:?} {size:?}");
        }
    }
}

#[test]
fn the_largest_target_is_covered_exactly() {
    let v = quad([[-1, -1, 0], [1, -1, 0], [-1, 1, 0], [1, 1, 0]]);
    let m = glam::dcamera::rh::proj::directx::orthographic(-1.0, 1.0, -1.0, 1.0, -1.0, 1.0);
    let (_, s) = draw((4096, 4096), &v, &[0, 1, 2, 3], m, Precision::Fixed);
    assert_eq!(s.fragments, 4096 * 4096);
}

#[test]
fn sub_pixel_and_degenerate_triangles() {
    // Orthographic over 0..16 pixels: one model unit is 1/256 pixel.
    let m = glam::dcamera::rh::proj::directx::orthographic(
        0.0,
        16.0 * 256.0,
        16.0 * 256.0,
        0.0,
        -1.0,
        1.0,
    );
    let tri = |p: [[i32; 2]; 3]| {
        p.iter()
            .map(|q| Vertex::new([q[0], q[1], 0], [0.0, 0.0], [255; 3]))
            .collect::<Vec<_>>()
    };
    for p in BOTH {
        // A tiny triangle around the centre of pixel (3, 3) owns it; one beside it owns nothing.
        let (_, s) = draw(
            (16, 16),
            &tri([[890, 890], [910, 890], [900, 910]]),
            &[0, 1, 2],
            m,
            p,
        );
        assert_eq!(s.fragments, 1, "{p:?} around a centre");
        let (_, s) = draw(
            (16, 16),
            &tri([[800, 800], [820, 800], [810, 820]]),
            &[0, 1, 2],
            m,
            p,
        );
        assert_eq!(s.fragments, 0, "{p:?} between centres");
        // Collinear and repeated-index triangles draw nothing.
        let (_, s) = draw(
            (16, 16),
            &tri([[0, 0], [2000, 2000], [4000, 4000]]),
            &[0, 1, 2],
            m,
            p,
        );
        assert_eq!(s.fragments, 0, "{p:?} collinear");
        let (_, s) = draw(
            (16, 16),
            &tri([[0, 0], [4000, 0], [0, 4000]]),
            &[0, 0, 1, 1, 2, 2],
            m,
            p,
        );
        assert_eq!(s.fragments, 0, "{p:?} degenerate strip");
    }
}

fn finite_matrix() -> impl Strategy<Value = DMat4> {
    prop::collection::vec(
        prop_oneof![-1e12f64..1e12, -1.0f64..1.0, -1e-9f64..1e-9, Just(0.0)],
        16,
    )
    .prop_map(|v| DMat4::from_cols_slice(&v))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(256), ..ProptestConfig::default() })]

    /// Any finite matrix and any i32 positions: drawn or clipped, never a panic or a wrap.
    #[test]
    fn arbitrary_finite_input_never_panics(
        m in finite_matrix(),
        pos in prop::collection::vec(prop::array::uniform3(any::<i32>()), 3..12),
        size in (1u32..80, 1u32..80),
        uv in prop::collection::vec(prop::array::uniform2(-1e6f32..1e6), 12),
    ) {
        let v: Vec<Vertex> = pos.iter().zip(&uv).map(|(p, t)| Vertex::new(*p, *t, [200, 100, 50])).collect();
        let idx: Vec<u32> = (0..v.len() as u32).collect();
        let tex = Texture::from_rgb565(4, 4, vec![0x1234; 16]).unwrap().with_mipmaps();
        for precision in BOTH {
            for perspective in [Perspective::Exact, Perspective::Spans(8), Perspective::Affine] {
                let mut fb = Framebuffer::new(size.0, size.1, ColorFormat::Rgba8888, DepthFormat::D16).unwrap();
                let state = RenderState {
                    precision,
                    perspective,
                    shading: Shading::Gouraud,
                    texture: Some(TextureBinding::new(&tex, Sampler { wrap: Wrap::Repeat, ..Sampler::BILINEAR_MIPMAP })),
                    fog: Some(Fog { color: [1, 2, 3], start: 1.0, end: 1e6 }),
                    ..RenderState::default()
                };
                let mesh = Mesh { vertices: &v, indices: Indices::U32(&idx), topology: Topology::TriangleStrip };
                let s = Rasterizer::new().draw(&mut fb, &mesh, &Transform::new(m).unwrap(), &state).unwrap();
                prop_assert!(s.fragments <= (size.0 * size.1) as u64 * s.rasterized.max(1));
            }
        }
    }
}
