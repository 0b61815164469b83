//! The line path (`Rasterizer::draw_lines`, `draw_edges`): exact pixels for known endpoints,
//! clipping against near and the guard band, the depth test with its bias, a mesh's wireframe
//! edge count, and no panic or wrap for any finite input.

use crate::common;

use std::collections::BTreeSet;

use common::*;
use glam::{DMat4, DVec3};
use proptest::prelude::*;
use stripmask_raster::*;

/// Model units per pixel in [`pixels_transform`].
const UNIT: i32 = 4;

/// Model (x, y) in quarter pixels lands on screen pixel (x / 4, y / 4), y down, depth `z / 1024`.
fn pixels_transform(w: u32, h: u32) -> Transform {
    let (w, h) = (f64::from(w), f64::from(h));
    let u = f64::from(UNIT);
    let m = DMat4::from_cols_array(&[
        2.0 / (u * w),
        0.0,
        0.0,
        0.0,
        0.0,
        -2.0 / (u * h),
        0.0,
        0.0,
        0.0,
        0.0,
        1.0 / 1024.0,
        0.0,
        -1.0,
        1.0,
        0.0,
        1.0,
    ]);
    Transform::new(m).unwrap()
}

fn quarter(x: f64, y: f64, z: i32) -> Vertex {
    let q = |c: f64| (c * f64::from(UNIT)).round() as i32;
    Vertex::new([q(x), q(y), z], [0.0, 0.0], [0, 0, 0])
}

const RED: [u8; 3] = [255, 0, 0];
const BLACK: [u8; 3] = [0, 0, 0];

fn lit(fb: &Framebuffer, color: [u8; 3]) -> BTreeSet<(u32, u32)> {
    (0..fb.height())
        .flat_map(|y| (0..fb.width()).map(move |x| (x, y)))
        .filter(|&(x, y)| fb.pixel(x, y) == color)
        .collect()
}

fn lines(
    size: (u32, u32),
    v: &[Vertex],
    l: &[[u32; 2]],
    m: &Transform,
    state: LineState,
) -> (Framebuffer, LineStats) {
    let mut fb = Framebuffer::new(size.0, size.1, ColorFormat::Rgba8888, DepthFormat::D16).unwrap();
    fb.clear(BLACK);
    let s = Rasterizer::new()
        .draw_lines(&mut fb, v, l, m, &state)
        .unwrap();
    (fb, s)
}

fn red(depth: LineDepth) -> LineState {
    LineState {
        color: RED,
        depth,
        scissor: None,
    }
}

/// The rule, written out with exact rationals: for each column whose centre lies in
/// [x0, x1), the pixel containing the line's point there (x-major lines).
fn expected_x_major(a: (f64, f64), b: (f64, f64)) -> BTreeSet<(u32, u32)> {
    let (a, b) = if a.0 <= b.0 { (a, b) } else { (b, a) };
    (0..64)
        .filter(|&p| {
            let c = f64::from(p) + 0.5;
            a.0 <= c && c < b.0
        })
        .map(|p| {
            let c = f64::from(p) + 0.5;
            let y = a.1 + (c - a.0) * (b.1 - a.1) / (b.0 - a.0);
            (p, y.floor() as u32)
        })
        .collect()
}

#[test]
fn known_endpoints_light_exactly_the_pixels_of_the_rule() {
    let m = pixels_transform(32, 24);
    let v = [
        quarter(1.5, 2.25, 0),
        quarter(5.5, 2.25, 0),
        quarter(3.25, 20.75, 0),
        quarter(29.0, 9.5, 0),
    ];
    let (fb, s) = lines((32, 24), &v, &[[0, 1]], &m, red(LineDepth::Always));
    let want: BTreeSet<_> = [(1, 2), (2, 2), (3, 2), (4, 2)].into();
    assert_eq!(lit(&fb, RED), want);
    assert_eq!((s.lines, s.rasterized, s.fragments), (1, 1, 4));

    let (fb, s) = lines((32, 24), &v, &[[3, 2]], &m, red(LineDepth::Always));
    let want = expected_x_major((3.25, 20.75), (29.0, 9.5));
    assert_eq!(want.len(), 26);
    assert_eq!(lit(&fb, RED), want);
    assert_eq!(s.fragments, 26);
    let (reversed, _) = lines((32, 24), &v, &[[2, 3]], &m, red(LineDepth::Always));
    assert_eq!(lit(&reversed, RED), want, "the same pixels either way");

    // A steep line: one pixel per row, rows 0..=23 whose centres lie in [0.2, 23.8).
    let v = [quarter(10.0, 0.25, 0), quarter(14.0, 23.75, 0)];
    let (fb, s) = lines((32, 24), &v, &[[0, 1]], &m, red(LineDepth::Always));
    let got = lit(&fb, RED);
    assert_eq!(s.fragments, 24);
    let rows: BTreeSet<u32> = got.iter().map(|&(_, y)| y).collect();
    assert_eq!(rows.len(), 24);
    for &(x, y) in &got {
        let exact = 10.0 + (f64::from(y) + 0.5 - 0.25) * 4.0 / 23.5;
        assert_eq!(x, exact.floor() as u32, "row {y}");
    }
}

#[test]
fn the_scissor_and_the_screen_edges_cut_lines_without_moving_them() {
    let m = pixels_transform(32, 24);
    let v = [quarter(-40.5, 3.25, 0), quarter(70.5, 15.75, 0)];
    let (full, _) = lines((32, 24), &v, &[[0, 1]], &m, red(LineDepth::Always));
    let on_screen = expected_x_major((-40.5, 3.25), (70.5, 15.75))
        .into_iter()
        .filter(|&(x, y)| x < 32 && y < 24)
        .collect::<BTreeSet<_>>();
    assert_eq!(lit(&full, RED), on_screen);
    let scissor = Rect {
        x0: 8,
        y0: 0,
        x1: 20,
        y1: 24,
    };
    let (cut, _) = lines(
        (32, 24),
        &v,
        &[[0, 1]],
        &m,
        LineState {
            scissor: Some(scissor),
            ..red(LineDepth::Always)
        },
    );
    let inside: BTreeSet<_> = on_screen
        .iter()
        .copied()
        .filter(|&(x, _)| (8..20).contains(&x))
        .collect();
    assert_eq!(lit(&cut, RED), inside);
    let mut fb = Framebuffer::new(32, 24, ColorFormat::Rgb565, DepthFormat::None).unwrap();
    let bad = LineState {
        scissor: Some(Rect {
            x0: 0,
            y0: 0,
            x1: 33,
            y1: 24,
        }),
        ..red(LineDepth::Always)
    };
    assert!(matches!(
        Rasterizer::new().draw_lines(&mut fb, &v, &[[0, 1]], &m, &bad),
        Err(RasterError::Scissor { .. })
    ));
    assert!(matches!(
        Rasterizer::new().draw_lines(&mut fb, &v, &[[0, 2]], &m, &red(LineDepth::Always)),
        Err(RasterError::IndexOutOfRange { value: 2, .. })
    ));
}

#[test]
fn lines_through_the_near_plane_and_beyond_the_guard_band_are_clipped() {
    // A camera 10 units above a ground plane looking along -z, 64 x 48.
    let m = Transform::new(
        glam::dcamera::rh::proj::directx::perspective(1.0, 4.0 / 3.0, 1.0, 1e6)
            * glam::dcamera::rh::view::look_at_mat4(
                DVec3::new(0.0, 10.0, 0.0),
                DVec3::new(0.0, 10.0, -1.0),
                DVec3::Y,
            ),
    )
    .unwrap();
    let ground = |x: i32, z: i32| Vertex::new([x, 0, z], [0.0, 0.0], [0; 3]);
    // From far ahead to far behind the eye, along the ground under it: the part ahead shows as
    // a vertical line in the middle column going down from the horizon.
    let v = [ground(0, -1_000_000), ground(0, 1_000_000)];
    let (fb, s) = lines((64, 48), &v, &[[0, 1]], &m, red(LineDepth::Always));
    let got = lit(&fb, RED);
    assert_eq!(s.rasterized, 1);
    assert!(got.len() >= 20, "{got:?}");
    assert!(got.iter().all(|&(x, y)| x == 32 && y >= 24), "{got:?}");
    // Entirely behind the eye: nothing.
    let v = [ground(-5, 10), ground(5, 1000)];
    let (fb, s) = lines((64, 48), &v, &[[0, 1]], &m, red(LineDepth::Always));
    assert_eq!((s.rasterized, s.fragments), (0, 0));
    assert!(lit(&fb, RED).is_empty());
    // Far across the view, beyond the guard band on both sides: the screen-wide middle row of
    // a horizon-level line at eye height.
    let eye_level = |x: i32| Vertex::new([x, 10, -100], [0.0, 0.0], [0; 3]);
    let v = [eye_level(-2_000_000_000), eye_level(2_000_000_000)];
    let (fb, s) = lines((64, 48), &v, &[[0, 1]], &m, red(LineDepth::Always));
    assert_eq!(s.fragments, 64);
    assert!(lit(&fb, RED).iter().all(|&(_, y)| y == 23 || y == 24));
}

/// An `n x n` grid of quads as strips with restarts, two triangles per quad.
fn grid_strip(n: u32) -> Vec<u32> {
    let s = n + 1;
    let mut idx = Vec::new();
    for j in 0..n {
        for i in 0..s {
            idx.push(j * s + i);
            idx.push((j + 1) * s + i);
        }
        idx.push(u32::MAX);
    }
    idx
}

#[test]
fn a_wireframe_draws_each_edge_of_a_strip_grid_once() {
    let n = 3;
    let s = n + 1;
    let v: Vec<Vertex> = (0..s * s)
        .map(|k| {
            quarter(
                4.0 + 8.0 * f64::from(k % s),
                2.0 + 6.0 * f64::from(k / s),
                0,
            )
        })
        .collect();
    let idx = grid_strip(n);
    let mesh = Mesh {
        vertices: &v,
        indices: Indices::U32(&idx),
        topology: Topology::TriangleStrip,
    };
    let m = pixels_transform(32, 24);
    let mut fb = Framebuffer::new(32, 24, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
    fb.clear(BLACK);
    let stats = Rasterizer::new()
        .draw_edges(&mut fb, &mesh, &m, &red(LineDepth::Always))
        .unwrap();
    // Euler for a triangulated disc: E = V + F - 1.
    let (vertices, faces) = (u64::from(s * s), u64::from(2 * n * n));
    assert_eq!(stats.lines, vertices + faces - 1);
    // Horizontal edges: 4 rows of 24 px; vertical ones: 4 columns of 18 px; diagonals of
    // 8 x 6 px quads: 8 columns each, 9 quads. Pixels where lines cross count once in the
    // picture and once per line in the fragments.
    let got = lit(&fb, [255, 0, 0]);
    let expected: BTreeSet<(u32, u32)> = (0..s)
        .flat_map(|j| (4..28).map(move |x| (x, 2 + 6 * j)))
        .chain((0..s).flat_map(|i| (2..20).map(move |y| (4 + 8 * i, y))))
        .chain((0..n * n).flat_map(|q| {
            let (x0, y0) = (4 + 8 * (q % n), 2 + 6 * (q / n));
            // Strips here run from (i, j + 1) to (i + 1, j): the diagonal rises to the east.
            (0..8).map(move |k| {
                let y = f64::from(y0) + 6.0 - (f64::from(k) + 0.5) * 6.0 / 8.0;
                (x0 + k, y.floor() as u32)
            })
        }))
        .collect();
    assert_eq!(got, expected);
    assert_eq!(
        stats.fragments,
        4 * 24 + 4 * 18 + 9 * 8,
        "every edge drawn once"
    );
}

#[test]
fn biased_depth_shows_lines_on_a_surface_and_hides_lines_behind_it() {
    let m = pixels_transform(32, 24);
    // A tilted quad covering the screen, depth rising from 0.25 to 0.75 left to right.
    let d = |x: f64| (256.0 + 512.0 * x / 32.0) as i32;
    let quad = [
        quarter(0.0, 0.0, d(0.0)),
        quarter(32.0, 0.0, d(32.0)),
        quarter(0.0, 24.0, d(0.0)),
        quarter(32.0, 24.0, d(32.0)),
    ];
    let mesh = Mesh {
        vertices: &quad,
        indices: Indices::U16(&[0, 2, 1, 3]),
        topology: Topology::TriangleStrip,
    };
    let mut r = Rasterizer::new();
    for depth in [DepthFormat::D16, DepthFormat::D32] {
        let mut fb = Framebuffer::new(32, 24, ColorFormat::Rgb565, depth).unwrap();
        fb.clear(BLACK);
        let state = RenderState {
            shading: Shading::Flat([0, 0, 255]),
            cull: CullMode::None,
            ..RenderState::default()
        };
        let drawn = r.draw(&mut fb, &mesh, &m, &state).unwrap();
        assert_eq!(drawn.fragments, 32 * 24);
        // On the surface: its own diagonal and an edge-to-edge line at the surface's depth.
        let on = [
            quarter(0.0, 24.0, d(0.0)),
            quarter(32.0, 0.0, d(32.0)),
            quarter(0.0, 5.5, d(0.0)),
            quarter(32.0, 17.5, d(32.0)),
        ];
        let s = r
            .draw_lines(
                &mut fb,
                &on,
                &[[0, 1], [2, 3]],
                &m,
                &red(LineDepth::ON_SURFACE),
            )
            .unwrap();
        assert_eq!(s.fragments, 64, "{depth:?}: both lines whole");
        // Behind it by a tenth of the depth range: hidden, unless the depth test is off.
        let behind: Vec<Vertex> = on
            .iter()
            .map(|v| Vertex {
                position: [v.position[0], v.position[1], v.position[2] + 100],
                ..*v
            })
            .collect();
        let s = r
            .draw_lines(
                &mut fb,
                &behind,
                &[[0, 1], [2, 3]],
                &m,
                &red(LineDepth::ON_SURFACE),
            )
            .unwrap();
        assert_eq!(s.fragments, 0, "{depth:?}: hidden");
        let s = r
            .draw_lines(
                &mut fb,
                &behind,
                &[[0, 1], [2, 3]],
                &m,
                &red(LineDepth::Always),
            )
            .unwrap();
        assert_eq!(s.fragments, 64, "{depth:?}: over everything");
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: cases(256), ..ProptestConfig::default() })]

    /// Any finite matrix and any i32 positions: drawn or clipped, never a panic or a wrap,
    /// at most one pixel per column or row of the target per line, the same bytes twice.
    #[test]
    fn arbitrary_finite_lines_never_panic(
        m in finite_matrix(),
        pos in prop::collection::vec(prop::array::uniform3(any::<i32>()), 2..10),
        size in (1u32..80, 1u32..80),
    ) {
        let v: Vec<Vertex> = pos.iter().map(|p| Vertex::new(*p, [0.0, 0.0], [0; 3])).collect();
        let n = v.len() as u32;
        let segs: Vec<[u32; 2]> = (0..n).map(|k| [k, (k + 1) % n]).collect();
        let t = Transform::new(m).unwrap();
        for (color, depth) in [(ColorFormat::Rgba8888, DepthFormat::D16), (ColorFormat::Rgb565, DepthFormat::D32)] {
            let mut pictures = Vec::new();
            for _ in 0..2 {
                let mut fb = Framebuffer::new(size.0, size.1, color, depth).unwrap();
                let s = Rasterizer::new().draw_lines(&mut fb, &v, &segs, &t, &red(LineDepth::ON_SURFACE)).unwrap();
                prop_assert!(s.fragments <= u64::from(size.0.max(size.1)) * s.rasterized);
                pictures.push(fb.to_rgba_image().into_raw());
            }
            prop_assert_eq!(&pictures[0], &pictures[1]);
        }
    }
}

fn finite_matrix() -> impl Strategy<Value = DMat4> {
    prop::collection::vec(
        prop_oneof![-1e12f64..1e12, -1.0f64..1.0, -1e-9f64..1e-9, Just(0.0)],
        16,
    )
    .prop_map(|v| DMat4::from_cols_slice(&v))
}

#[test]
fn a_line_in_a_valley_crease_shows_though_the_pixel_centres_beside_it_are_nearer() {
    let m = pixels_transform(32, 24);
    // A V-shaped valley: depth 0.25 at the left and right edges, 0.75 along the crease x = 16.
    let v: Vec<Vertex> = [(0.0, 256), (16.0, 768), (32.0, 256)]
        .iter()
        .flat_map(|&(x, z)| [quarter(x, 0.0, z), quarter(x, 24.0, z)])
        .collect();
    let mesh = Mesh {
        vertices: &v,
        indices: Indices::U16(&[0, 1, 2, 3, 4, 5]),
        topology: Topology::TriangleStrip,
    };
    for depth in [DepthFormat::D16, DepthFormat::D32] {
        let mut fb = Framebuffer::new(32, 24, ColorFormat::Rgb565, depth).unwrap();
        fb.clear(BLACK);
        let state = RenderState {
            cull: CullMode::None,
            ..RenderState::default()
        };
        let mut r = Rasterizer::new();
        assert_eq!(
            r.draw(&mut fb, &mesh, &m, &state).unwrap().fragments,
            32 * 24
        );
        let crease = [quarter(16.0, 0.0, 768), quarter(16.0, 24.0, 768)];
        let s = r
            .draw_lines(&mut fb, &crease, &[[0, 1]], &m, &red(LineDepth::ON_SURFACE))
            .unwrap();
        assert_eq!(s.fragments, 24, "{depth:?}: the whole crease");
        // Four pixels' worth of slope behind the crease: hidden.
        let deeper = [
            quarter(16.0, 0.0, 768 + 128),
            quarter(16.0, 24.0, 768 + 128),
        ];
        let s = r
            .draw_lines(&mut fb, &deeper, &[[0, 1]], &m, &red(LineDepth::ON_SURFACE))
            .unwrap();
        assert_eq!(s.fragments, 0, "{depth:?}: behind the valley floor");
    }
}
