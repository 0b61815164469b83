//! Watertightness in the style of the dEQP fill-rule tests: meshes that tile a region, drawn one
//! triangle at a time; every pixel must be written exactly once — no holes, no double hits — in
//! both pipelines, including projected meshes with random `w` and meshes reaching past the guard
//! band (so that side clipping runs).

use crate::common;

use common::*;
use proptest::prelude::*;
use stripmask_raster::*;

const SIZE: (u32, u32) = (48, 40);

/// A grid covering more than the screen: border vertices at `±outer` in NDC, interior vertices
/// jittered by at most a fifth of a cell (so every cell stays convex and neither diagonal folds),
/// each with its own `w`.
fn mesh(n: u32, outer: f64, jitter: &[(f64, f64)], ws: &[f64]) -> Vec<Vertex> {
    let mut v = vec![];
    for j in 0..n {
        for i in 0..n {
            let k = (j * n + i) as usize;
            let border = i == 0 || j == 0 || i == n - 1 || j == n - 1;
            let cell = 2.0 / (n - 3) as f64; // interior spans NDC -1..1
            let (nx, ny) = if border {
                let f = |c: u32| {
                    if c == 0 {
                        -outer
                    } else if c == n - 1 {
                        outer
                    } else {
                        -1.0 + (c - 1) as f64 * cell
                    }
                };
                (f(i), f(j))
            } else {
                let (jx, jy) = jitter[k];
                (
                    -1.0 + (i - 1) as f64 * cell + jx * 0.2 * cell,
                    -1.0 + (j - 1) as f64 * cell + jy * 0.2 * cell,
                )
            };
            v.push(at(nx, ny, ws[k]));
        }
    }
    v
}

fn assert_exactly_once(counts: &[u32], what: &str) {
    let holes = counts.iter().filter(|&&c| c == 0).count();
    let doubles = counts.iter().filter(|&&c| c > 1).count();
    assert!(
        holes == 0 && doubles == 0,
        "{what}: {holes} holes, {doubles} double hits"
    );
}

proptest! {
    // PROPTEST_CASES raises the count for a long run.
    #![proptest_config(ProptestConfig { cases: cases(48), ..ProptestConfig::default() })]

    #[test]
    fn projected_jittered_grids_cover_every_pixel_once(
        n in 5u32..9,
        jitter in prop::collection::vec((-1.0f64..1.0, -1.0f64..1.0), 81),
        ws in prop::collection::vec(0.05f64..50.0, 81),
        outer in prop::sample::select(vec![1.5, 40.0, 5000.0]),
        flips in prop::collection::vec(any::<bool>(), 81),
    ) {
        let v = mesh(n, outer, &jitter, &ws);
        let tris = grid_triangles(n, n, |i, j| flips[(j * n + i) as usize]);
        for p in [Precision::Fixed, Precision::Float] {
            assert_exactly_once(&hit_counts(SIZE, &v, &tris, p), &format!("{p:?} n={n} outer={outer}"));
        }
    }
}

#[test]
fn fan_around_a_pixel_centre_owns_it_once() {
    // Eight triangles meeting at the centre of pixel (24, 20), with edges along the pixel grid
    // diagonals and axes: every edge passes exactly through pixel centres.
    let c = (24.5 / 24.0 - 1.0, 1.0 - 20.5 / 20.0);
    let mut v = vec![at(c.0, c.1, 1.0)];
    let ring = [
        (-3.0, -3.0),
        (0.0, -3.0),
        (3.0, -3.0),
        (3.0, 0.0),
        (3.0, 3.0),
        (0.0, 3.0),
        (-3.0, 3.0),
        (-3.0, 0.0),
    ];
    for (dx, dy) in ring {
        v.push(at(c.0 + dx, c.1 + dy, 1.0));
    }
    let tris: Vec<[u32; 3]> = (0..8).map(|k| [0, 1 + k, 1 + (k + 1) % 8]).collect();
    for p in [Precision::Fixed, Precision::Float] {
        assert_exactly_once(&hit_counts(SIZE, &v, &tris, p), &format!("fan {p:?}"));
    }
}

#[test]
fn strips_and_lists_of_the_same_grid_draw_the_same_pixels() {
    let n = 9u32;
    let v = mesh(n, 1.5, &vec![(0.3, -0.2); 81], &vec![1.0; 81]);
    let mut strip = vec![];
    for j in 0..n - 1 {
        for i in 0..n {
            strip.push(j * n + i);
            strip.push((j + 1) * n + i);
        }
        strip.push(u32::MAX);
    }
    let transform = projective();
    let state = RenderState {
        depth: DepthMode::NONE,
        shading: Shading::Flat([255, 255, 255]),
        ..RenderState::default()
    };
    let mut a = Framebuffer::new(SIZE.0, SIZE.1, ColorFormat::Rgb565, DepthFormat::None).unwrap();
    let mut b = a.clone();
    let mut r = Rasterizer::new();
    let sa = r
        .draw(
            &mut a,
            &Mesh {
                vertices: &v,
                indices: Indices::U32(&strip),
                topology: Topology::TriangleStrip,
            },
            &transform,
            &state,
        )
        .unwrap();
    let list: Vec<u32> = grid_triangles(n, n, |_, _| false).concat();
    let sb = r
        .draw(
            &mut b,
            &Mesh {
                vertices: &v,
                indices: Indices::U32(&list),
                topology: Topology::TriangleList,
            },
            &transform,
            &state,
        )
        .unwrap();
    assert_eq!(a, b);
    assert_eq!(
        sa.fragments,
        (SIZE.0 * SIZE.1) as u64,
        "a strip mesh covering the screen writes each pixel once"
    );
    assert_eq!(sa.fragments, sb.fragments);
}
