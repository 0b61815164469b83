//! Triangle set-up of the integer pipeline: the planes a draw's attributes need, the
//! texture level, and whether the rows may skip their clamps or start on the pixel grid.

use super::planes::{
    AttrPlane, Geometry, Made, SMALL_NARROW_GRADIENT, grid_offset, reach_gradient,
};
use super::projection::{FixedScreen, Inner};
use crate::edge::Coverage;
use crate::fixed_point::Q_BITS;
use crate::pipeline::{Attributes, Setup, TexMode};

/// A triangle ready for its rows: 64 bytes, with its attribute planes beside it in the set-up
/// chunk's plane list, only those its draw uses, in the order depth, colour (one plane for grey
/// vertices, else three), fog, texture (`u, v`, or `s, t, q` under perspective).
#[derive(Clone, Copy, Debug)]
pub(crate) struct FixedTriangle {
    pub coverage: Coverage,
    /// Index of its first plane in the chunk's planes.
    pub(super) planes: u32,
    /// This triangle's texture interpolation (see `Attributes::tex_mode_for`).
    pub(super) tex_mode: TexMode,
    level: u8,
    /// One colour plane serves the three channels (grey vertices): rows step one channel.
    pub(crate) grey: bool,
    /// Every plane is narrow (below `NARROW_GRADIENT`, or `SMALL_NARROW_GRADIENT` for a small
    /// triangle) and on its rectangle's pixel grid: rows start from `AttrPlane::at_pixel`
    /// (otherwise from `AttrPlane::at`).
    pub(crate) narrow: bool,
    /// A small triangle whose planes give every pixel it owns a value inside the range the row
    /// step clamps it to, from the values at its vertices (`Inner`), so that its rows need no
    /// clamps (`small::small_triangle`; perspective quotients are bounded there).
    ///
    /// Bounds: an owned pixel centre lies in the triangle, where the exact interpolation of the
    /// vertices' values lies between the least and the greatest of them. A small triangle's
    /// gradient is `g (1 - e) + r` for the exact gradient `g`, one `e < 2^-31` for all its planes
    /// (the floor of the area's reciprocal, `Geometry::inv_area` in `(2^31, 2^32]`) and the
    /// rounding `|r| <= 1/2`; the value at an offset `o` from the origin vertex (sub-pixels,
    /// `|o| < 17 * 256` on each axis for a pixel centre inside a small triangle, `SMALL_EDGE`)
    /// rounds `(dx ox + dy oy) / 256`. So it strays from the exact value by at most `e` times
    /// the vertices' spread, plus `(|ox| + |oy|) / 512 + 1/2 < 18`: the margins of
    /// `Inner::of`. Planes whose gradients leave i64 are flat at the origin vertex's value,
    /// inside the range too.
    pub(crate) bounded: bool,
    /// The draw it belongs to.
    draw: u32,
}

impl FixedTriangle {
    /// Sets up `v` (positive orientation, `area2 > 0`), appending its planes to `planes`.
    #[inline(always)]
    pub fn new(
        v: [&FixedScreen; 3],
        area2: i64,
        coverage: Coverage,
        a: &Attributes,
        draw: u32,
        planes: &mut Vec<AttrPlane>,
    ) -> Self {
        let first = planes.len();
        let mut t = Self {
            coverage,
            planes: first as u32,
            tex_mode: TexMode::Off,
            level: 0,
            grey: true,
            narrow: true,
            bounded: false,
            draw,
        };
        if !a.interpolates() {
            return t;
        }
        let g = Geometry::new(&v, area2, coverage.is_small());
        let limit = if coverage.is_small() {
            SMALL_NARROW_GRADIENT
        } else {
            reach_gradient(&coverage)
        };
        // Each plane is tested and moved onto the pixel grid as it is made, while it is in
        // registers; the moves are taken back below where one of them is not narrow (rare).
        let offset = grid_offset(v[0].xy, coverage.corner());
        let mut narrow = true;
        let mut put = |m: Made| {
            narrow &= m.narrow || m.plane.narrow_below(limit);
            planes.push(m.plane.on_grid(offset));
        };
        let pick = |f: fn(&FixedScreen) -> i64| g.plane([f(v[0]), f(v[1]), f(v[2])]);
        let share = |f: fn(&FixedScreen) -> i64| g.plane_of_share([f(v[0]), f(v[1]), f(v[2])]);
        if a.depth {
            put(pick(|s| s.depth));
        }
        if a.shade {
            t.grey = v[0].grey & v[1].grey & v[2].grey;
            put(share(|s| s.color[0]));
            if !t.grey {
                put(share(|s| s.color[1]));
                put(share(|s| s.color[2]));
            }
        }
        if a.fog {
            put(share(|s| s.fog));
        }
        t.tex_mode = a.tex_mode_for([v[0].xy, v[1].xy, v[2].xy], coverage.is_small());
        match t.tex_mode {
            TexMode::Off => {}
            TexMode::Affine => {
                put(pick(|s| s.uv[0]));
                put(pick(|s| s.uv[1]));
                t.level = a.level(texel_area_bits(&v), area2);
            }
            TexMode::Perspective(_) => {
                // 1/w of the three vertices on one scale, below 2^Q_BITS.
                let smin = v.iter().map(|s| s.w_shift).min().expect("3 vertices");
                let q = v.map(|s| {
                    let d = (s.w_shift - smin) as u32 + (32 - Q_BITS);
                    (s.inv_w.checked_shr(d).unwrap_or(0)).max(1)
                });
                let st =
                    |k: usize| g.plane([v[0].uv[k] * q[0], v[1].uv[k] * q[1], v[2].uv[k] * q[2]]);
                put(st(0));
                put(st(1));
                put(g.plane(q));
                t.level = a.level(texel_area_bits(&v), area2);
            }
        }
        t.bounded = coverage.is_small() && Inner::all(&v, Inner::needed(a, t.tex_mode));
        t.narrow = narrow;
        if !narrow {
            for p in &mut planes[first..] {
                *p = p.off_grid(offset);
            }
        }
        t
    }
}

/// Bit length of the doubled texture-space area in 16.16 repeats squared. In i64: coordinates
/// stay within `TEXCOORD_LIMIT` (2^24), so differences below 2^25 and their products below 2^50.
fn texel_area_bits(v: &[&FixedScreen; 3]) -> u32 {
    let d = |i: usize, k: usize| v[i].uv[k] - v[0].uv[k];
    64 - (d(1, 0) * d(2, 1) - d(2, 0) * d(1, 1))
        .unsigned_abs()
        .leading_zeros()
}

impl Setup for FixedTriangle {
    fn coverage(&self) -> &Coverage {
        &self.coverage
    }
    fn level(&self) -> usize {
        self.level as usize
    }
    fn draw(&self) -> u32 {
        self.draw
    }
}

#[cfg(test)]
mod tests {
    use super::super::projection::is_grey;
    use super::super::test_support::{EDGE, SCREEN};
    use super::*;
    use crate::fixed_point::{
        ATTR_FRAC_BITS, DEPTH_ONE, SUBPIXEL_HALF, SUBPIXEL_ONE, TEXCOORD_LIMIT,
    };
    use crate::state::Fog;

    /// A vertex's values: depth (0.32), colour, fog share, texture coordinates (16.16).
    type Values = (i64, [i64; 3], i64, [i64; 2]);

    /// Sets up the triangle `xy` (sub-pixels) with `values` at its vertices, depth-tested,
    /// shaded, fogged and textured without perspective. For a small triangle, returns whether
    /// it is `bounded`, and the first of its planes' values at the pixels it owns that lies
    /// outside the range its pixels are clamped to.
    fn strays(xy: [[i64; 2]; 3], values: [Values; 3]) -> Option<(bool, Option<String>)> {
        let texture = crate::Texture::from_rgba8(2, 2, vec![[9; 4]; 4]).expect("a texture");
        let state = crate::RenderState {
            shading: crate::Shading::Gouraud,
            fog: Some(Fog {
                color: [0; 3],
                start: 0.0,
                end: 1.0,
            }),
            texture: Some(crate::TextureBinding::new(
                &texture,
                crate::Sampler::default(),
            )),
            perspective: crate::Perspective::Affine,
            ..crate::RenderState::default()
        };
        let a = Attributes::new(&state, true);
        let mut v = [0, 1, 2].map(|i| {
            let (depth, color, fog, uv) = values[i];
            FixedScreen {
                xy: xy[i],
                depth,
                color,
                grey: is_grey(color),
                fog,
                uv,
                inner: Inner::of(depth, color, fog, uv),
                ..FixedScreen::default()
            }
        });
        let d = |v: &[FixedScreen; 3], i: usize| [v[i].xy[0] - v[0].xy[0], v[i].xy[1] - v[0].xy[1]];
        let area2 = |v: &[FixedScreen; 3]| d(v, 1)[0] * d(v, 2)[1] - d(v, 2)[0] * d(v, 1)[1];
        if area2(&v) < 0 {
            v.swap(1, 2);
        }
        let cov = Coverage::new(v.map(|s| s.xy), SCREEN).filter(|c| c.is_small())?;
        if area2(&v) == 0 {
            return None;
        }
        let mut planes = Vec::new();
        let t = FixedTriangle::new([&v[0], &v[1], &v[2]], area2(&v), cov, &a, 0, &mut planes);
        let one = 1i64 << ATTR_FRAC_BITS;
        let coord = TEXCOORD_LIMIT << 16;
        let mut ranges = vec![(0, 1 << 48)];
        ranges.extend(std::iter::repeat_n(
            (0, 256 * one),
            if t.grey { 1 } else { 3 },
        ));
        ranges.extend([(0, 257 * one), (-coord, coord + one), (-coord, coord + one)]);
        assert_eq!(planes.len(), ranges.len());
        let (origin, corner) = (cov.origin(), cov.corner());
        let mut stray = None;
        cov.for_each_span(i64::MIN, i64::MAX, |y, x0, x1| {
            for x in x0..x1 {
                for (p, &(lo, hi)) in planes.iter().zip(&ranges) {
                    let value = if t.narrow {
                        p.at_pixel(x - corner[0], y - corner[1])
                    } else {
                        let centre = |c: i64, o: i64| c * SUBPIXEL_ONE + SUBPIXEL_HALF - o;
                        p.at(centre(x, origin[0]), centre(y, origin[1]))
                    };
                    if !(lo..hi).contains(&value) && stray.is_none() {
                        stray = Some(format!("{value} outside {lo}..{hi} at ({x}, {y}): {p:?}"));
                    }
                }
            }
        });
        Some((t.bounded, stray))
    }

    /// `strays`, asserting that a bounded triangle's planes stay in range; for a small
    /// triangle, returns whether it is bounded and whether a value strayed.
    fn check_bounded(xy: [[i64; 2]; 3], values: [Values; 3]) -> Option<(bool, bool)> {
        let (bounded, stray) = strays(xy, values)?;
        if bounded {
            assert_eq!(stray, None, "{xy:?} {values:?}");
        }
        Some((bounded, stray.is_some()))
    }

    /// Values well inside every range, and at the high end of every range.
    const MIDDLE: Values = (1 << 31, [128; 3], 128, [0; 2]);
    const HIGH: Values = (DEPTH_ONE - 1, [255; 3], 256, [TEXCOORD_LIMIT; 2]);
    /// Values whose differences from the ends are no round numbers.
    const UNEVEN: Values = (DEPTH_ONE - 12345, [201, 202, 203], 177, [5_604_617, 777]);

    #[test]
    fn vertices_at_the_low_end_of_a_range_stray_past_it_and_are_not_bounded() {
        let l = TEXCOORD_LIMIT;
        // One kind of attribute at the low end of its range, the others in the middle.
        let ends: [Values; 4] = [
            (0, MIDDLE.1, MIDDLE.2, MIDDLE.3),
            (MIDDLE.0, [0; 3], MIDDLE.2, MIDDLE.3),
            (MIDDLE.0, MIDDLE.1, 0, MIDDLE.3),
            (MIDDLE.0, MIDDLE.1, MIDDLE.2, [-l; 2]),
        ];
        let centre = |k: i64| k * SUBPIXEL_ONE + SUBPIXEL_HALF;
        for end in ends {
            // Two vertices at the end, on pixel centres: the pixels on the edge between them are
            // exactly at the end, and the planes' rounding takes some of them past it. Each pair
            // of the vertices takes its turn (the orientation swaps two).
            let mut strayed = 0;
            for (ax, ay) in (0..=12).flat_map(|x| (0..=12).map(move |y| (x, y))) {
                for (bx, by) in (-2..=14).flat_map(|x| (-2..=14).map(move |y| (x, y))) {
                    let (a, b) = ([centre(0), centre(0)], [centre(ax), centre(ay)]);
                    let off = [bx * 97 + 5, by * 89 + 3];
                    for other in [HIGH, UNEVEN] {
                        for (xy, values) in [
                            ([a, b, off], [end, end, other]),
                            ([off, a, b], [other, end, end]),
                        ] {
                            strayed += matches!(check_bounded(xy, values), Some((_, true))) as u32;
                        }
                    }
                }
            }
            assert!(strayed > 0, "{end:?}");
        }
    }

    #[test]
    fn bounded_small_triangles_keep_every_owned_pixel_in_range_at_the_extremes() {
        let m = Inner::DEPTH_MARGIN;
        let low: Values = (m, [1; 3], 1, [-TEXCOORD_LIMIT + 1; 2]);
        let high: Values = (DEPTH_ONE - 1 - m, [255; 3], 256, [TEXCOORD_LIMIT; 2]);
        let mixed: Values = (m, [255, 1, 255], 256, [-TEXCOORD_LIMIT + 1, TEXCOORD_LIMIT]);
        let (mut checked, mut at) = (0, 0);
        for (lo, hi) in [
            (0, 15 * SUBPIXEL_ONE),
            (SUBPIXEL_ONE - 1, 16 * SUBPIXEL_ONE - 1),
            (3, 2 * SUBPIXEL_ONE + 77),
        ] {
            let shapes = [
                [[lo, lo], [hi, lo], [lo, hi]],
                [[hi, hi], [lo, hi], [hi, lo]],
                [[hi, lo], [lo, hi], [hi, hi]],
                [[lo, lo], [hi, hi], [lo + 1, hi]],
                [[lo, lo], [hi, lo + 1], [hi, hi]],
            ];
            for shape in shapes {
                for a in [low, high, mixed] {
                    for b in [low, high, mixed] {
                        for c in [low, high, mixed] {
                            at += 1;
                            checked +=
                                matches!(check_bounded(shape, [a, b, c]), Some((true, _))) as u32;
                        }
                    }
                }
            }
        }
        assert!(checked * 2 > at, "{checked} of {at}");
    }

    #[test]
    fn a_triangle_is_bounded_when_every_vertex_has_every_bit_it_needs() {
        let state = crate::RenderState {
            shading: crate::Shading::Gouraud,
            ..crate::RenderState::default()
        };
        let a = Attributes::new(&state, true);
        let needed = Inner::needed(&a, TexMode::Off);
        assert_eq!(needed, Inner(Inner::DEPTH | Inner::COLOR));
        let vertex = |values: Values| FixedScreen {
            inner: Inner::of(values.0, values.1, values.2, values.3),
            ..FixedScreen::default()
        };
        let (inside, dark) = (vertex(MIDDLE), vertex((1 << 31, [9, 0, 9], 0, [0; 2])));
        assert!(Inner::all(&[&inside, &inside, &inside], needed));
        for k in 0..3 {
            let mut v = [&inside; 3];
            v[k] = &dark;
            assert!(!Inner::all(&v, needed), "vertex {k}");
        }
        // The fog share is not needed here: a vertex at its end does not count.
        let fogless = vertex((1 << 31, [9; 3], 0, [0; 2]));
        assert!(Inner::all(&[&fogless, &inside, &fogless], needed));
    }

    /// Values of a vertex over their whole ranges, their ends more often than the rest.
    fn any_values() -> impl proptest::strategy::Strategy<Value = Values> {
        use proptest::prelude::*;
        let ends = |lo: i64, hi: i64| prop_oneof![lo..=lo + 4, hi - 4..=hi, lo..=hi];
        let l = TEXCOORD_LIMIT;
        (
            ends(0, DEPTH_ONE - 1),
            [ends(0, 255), ends(0, 255), ends(0, 255)],
            ends(0, 256),
            [ends(-l, l), ends(-l, l)],
        )
    }

    proptest::proptest! {
        /// Where `Inner` calls a small triangle bounded, its planes stay inside the ranges at
        /// every pixel it owns; vertices at the very ends of the ranges are not bounded.
        #[test]
        fn bounded_small_triangles_keep_every_owned_pixel_in_range(
            at in (0i64..1 << 20, 0i64..1 << 20),
            v in proptest::collection::vec(0..=EDGE, 6),
            a in any_values(),
            b in any_values(),
            c in any_values(),
        ) {
            let xy = [0, 1, 2].map(|i| [at.0 + v[2 * i], at.1 + v[2 * i + 1]]);
            check_bounded(xy, [a, b, c]);
        }
    }
}
