//! Line segments: wireframes and overlays drawn over (or instead of) shaded triangles.
//!
//! A line goes through the same front end as a triangle of the fixed pipeline: the exact i64
//! transform, the same homogeneous clipper (`w > 0`, near, far and the guard band; a cut is
//! computed from the inside endpoint, so a line along a triangle edge is cut where the triangle
//! is) and the same projection and 1/256-pixel snap, so a mesh's wireframe lands on its
//! triangles' edges. Lines are always drawn by the integer pipeline, whatever the precision of
//! the triangles under them.
//!
//! Pixels: a line whose x extent is at least its y extent lights, in every pixel column whose
//! centre `cx` lies in `[x0, x1)` (endpoints ordered by x), the pixel containing the exact point
//! of the line at `cx` (an exact integer division); steeper lines the same with rows. One pixel
//! per column (or row), no gaps, the same pixels whichever way the segment is given, and no
//! float anywhere: the same bytes on every machine. Depth is affine in screen space, so it is
//! interpolated exactly the same way; [`LineDepth::Biased`] compares it with the surface beside
//! the line as well, so that lines on a surface are not hidden by the surface itself.

use crate::RasterError;
use crate::clip::{ClipVertex, PLANES};
use crate::fixed_point::{SUBPIXEL_BITS, SUBPIXEL_HALF, SUBPIXEL_ONE, ceil_div, floor_div};
use crate::layout::{rgba_to_xbgr, rgba_to_xrgb, swap_565};
use crate::matrix::Transform;
use crate::pipeline::Viewport;
use crate::pipeline::fixed::{FixedClip, FixedScreen, FixedSpace};
use crate::pixel::{Depth16, Depth32, DepthStorage, NoDepth, PixelFormat, Rgb565, Rgba8888};
use crate::rasterizer::Rasterizer;
use crate::state::Rect;
use crate::surface::{AsSurface, ColorMut, DepthMut, Surface};
use crate::vertex::{Mesh, Vertex, assemble};

/// How a line draw uses the depth buffer. Lines never write depth: a wireframe does not hide
/// the surface it outlines, nor its own other edges.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum LineDepth {
    /// Drawn over everything; the depth buffer is not read.
    Always,
    /// Drawn where the line's depth, less this bias (0.32 depth units, as in the buffer's top
    /// bits), is not behind the stored depth plus the surface's slope there: the larger depth
    /// change from the pixel to the two pixels beside it across the line. The line's depth is
    /// taken on the exact line, the surface's at the pixel centre up to half a pixel away, so
    /// on a steep surface or in a valley's crease the two differ by up to half a pixel's slope.
    /// Lines on a surface show whatever its slope; lines behind it by more than a pixel's worth
    /// of its slope do not.
    Biased(u32),
}

impl LineDepth {
    /// A bias of 2 steps of a 16-bit depth buffer, for the rounding of both depths: the edges
    /// of a mesh drawn with [`crate::DepthMode::LESS_WRITE`] show over it.
    pub const ON_SURFACE: Self = Self::Biased(2 << 16);
}

/// Everything a line draw needs besides geometry and transform.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LineState {
    /// The lines' one colour.
    pub color: [u8; 3],
    /// Depth test.
    pub depth: LineDepth,
    /// Pixels outside this rectangle are never written; `None` means the whole framebuffer.
    pub scissor: Option<Rect>,
}

impl Default for LineState {
    /// White lines on the surface they outline.
    fn default() -> Self {
        Self {
            color: [255; 3],
            depth: LineDepth::ON_SURFACE,
            scissor: None,
        }
    }
}

/// What a line draw did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LineStats {
    /// Segments given (for a mesh: distinct edges of its non-degenerate triangles).
    pub lines: u64,
    /// Segments left after clipping with a nonzero length on screen.
    pub rasterized: u64,
    /// Pixels written (that passed the depth test).
    pub fragments: u64,
}

impl std::ops::AddAssign for LineStats {
    fn add_assign(&mut self, o: Self) {
        self.lines += o.lines;
        self.rasterized += o.rasterized;
        self.fragments += o.fragments;
    }
}

/// A projected endpoint: snapped sub-pixel position and depth (0.32).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Endpoint {
    xy: [i64; 2],
    depth: i64,
}

impl Rasterizer {
    /// Draws the segments `lines` (pairs of indices into `vertices`) into `fb` (a
    /// [`crate::Framebuffer`] or a [`Surface`]). Vertex uv and colour are ignored: every line
    /// has `state.color`.
    pub fn draw_lines(
        &mut self,
        fb: &mut impl AsSurface,
        vertices: &[Vertex],
        lines: &[[u32; 2]],
        transform: &Transform,
        state: &LineState,
    ) -> Result<LineStats, RasterError> {
        let mut fb = fb.as_surface();
        let scissor = Rect::scissor_on(state.scissor, fb.width(), fb.height())?;
        for (k, line) in lines.iter().enumerate() {
            if let Some(&v) = line.iter().find(|&&v| v as usize >= vertices.len()) {
                return Err(RasterError::IndexOutOfRange {
                    position: 2 * k,
                    value: v,
                    vertices: vertices.len(),
                });
            }
        }
        let vp = Viewport {
            width: fb.width(),
            height: fb.height(),
        };
        let space = FixedSpace::new(&vp);
        let mut stats = LineStats {
            lines: lines.len() as u64,
            ..LineStats::default()
        };
        let segments: Vec<[Endpoint; 2]> = lines
            .iter()
            .filter_map(|l| {
                let [a, b] =
                    l.map(|v| FixedClip::from_vertex(&vertices[v as usize], &transform.fixed));
                clip_segment(a, b, &space).map(|s| s.map(|c| project(&c, &vp)))
            })
            .filter(|[a, b]| a.xy != b.xy)
            .collect();
        stats.rasterized = segments.len() as u64;
        if scissor.x0 < scissor.x1 && scissor.y0 < scissor.y1 {
            stats.fragments = rasterize(&mut fb, &segments, scissor, state);
        }
        Ok(stats)
    }

    /// Draws the edges of `mesh`'s triangles (a wireframe), each shared edge once: the mesh is
    /// assembled as [`Rasterizer::draw`] assembles it, degenerate triangles dropped.
    pub fn draw_edges(
        &mut self,
        fb: &mut impl AsSurface,
        mesh: &Mesh,
        transform: &Transform,
        state: &LineState,
    ) -> Result<LineStats, RasterError> {
        let mut edges = Vec::with_capacity(mesh.indices.len() * 2);
        assemble(mesh, |[a, b, c]| {
            for (p, q) in [(a, b), (b, c), (c, a)] {
                edges.push([p.min(q), p.max(q)]);
            }
        })
        .map_err(|(position, value)| RasterError::IndexOutOfRange {
            position,
            value,
            vertices: mesh.vertices.len(),
        })?;
        edges.sort_unstable();
        edges.dedup();
        self.draw_lines(fb, mesh.vertices, &edges, transform, state)
    }
}

/// The scissor rectangle of a draw, checked against the framebuffer.
/// Clips segment `a b` against every plane either endpoint is outside of, cutting from the
/// inside endpoint as the triangle clipper does; `None` when nothing is left.
fn clip_segment(a: FixedClip, b: FixedClip, space: &FixedSpace) -> Option<[FixedClip; 2]> {
    let (oa, ob) = (a.outcode(space), b.outcode(space));
    if oa & ob != 0 {
        return None;
    }
    let (mut a, mut b) = (a, b);
    for plane in PLANES.into_iter().filter(|&p| (oa | ob) & p as u8 != 0) {
        match (a.inside(plane, space), b.inside(plane, space)) {
            (true, true) => {}
            (false, false) => return None,
            (true, false) => b = FixedClip::intersect(&a, &b, plane, space),
            (false, true) => a = FixedClip::intersect(&b, &a, plane, space),
        }
    }
    Some([a, b])
}

fn project(c: &FixedClip, vp: &Viewport) -> Endpoint {
    let s = FixedScreen::project(c, vp, None);
    Endpoint {
        xy: s.xy,
        depth: s.depth(),
    }
}

/// Picks the pixel layout and depth format of the target and draws every segment.
fn rasterize(fb: &mut Surface, segments: &[[Endpoint; 2]], r: Rect, state: &LineState) -> u64 {
    let width = fb.width() as usize;
    let bias = match state.depth {
        LineDepth::Always => None,
        LineDepth::Biased(b) => Some(i64::from(b)),
    };
    let (rgb565, rgba) = (Rgb565::pack(state.color), Rgba8888::pack(state.color));
    macro_rules! go {
        ($c:expr, $pixel:expr) => {{
            let color = (&mut *$c.pixels, $c.stride, $pixel);
            match (&mut fb.depth, bias) {
                (DepthMut::D16(d), Some(b)) => {
                    draw_all::<_, Depth16>(color, d, width, segments, r, b)
                }
                (DepthMut::D32(d), Some(b)) => {
                    draw_all::<_, Depth32>(color, d, width, segments, r, b)
                }
                _ => draw_all::<_, NoDepth>(color, &mut [], width, segments, r, 0),
            }
        }};
    }
    match &mut fb.color {
        ColorMut::Rgb565(c) => go!(c, rgb565),
        ColorMut::Bgr565(c) => go!(c, swap_565(rgb565)),
        ColorMut::Xrgb8888(c) => go!(c, rgba_to_xrgb(rgba)),
        ColorMut::Xbgr8888(c) => go!(c, rgba_to_xbgr(rgba)),
        ColorMut::Rgba8888(c) => go!(c, rgba),
    }
}

/// Draws `segments` in order as `pixel` into `color` (its rows `stride` apart), testing against
/// `depth` (`width` to a row), within `r`.
fn draw_all<T: Copy, D: DepthStorage>(
    (color, stride, pixel): (&mut [T], usize, T),
    depth: &mut [D::Value],
    width: usize,
    segments: &[[Endpoint; 2]],
    r: Rect,
    bias: i64,
) -> u64
where
    D::Value: Into<u64>,
{
    let height = if D::ENABLED { depth.len() / width } else { 0 };
    let mut fragments = 0;
    for &[a, b] in segments {
        walk(a, b, r, |x, y, z, x_major| {
            let i = y as usize * width + x as usize;
            if D::ENABLED {
                // The pixels beside this one across the line, where they exist.
                let (before, after, step) = if x_major {
                    (y > 0, (y as usize) + 1 < height, width)
                } else {
                    (x > 0, (x as usize) + 1 < width, 1)
                };
                // The surface's depth change to the pixels beside, one pixel's worth of slope.
                let here: u64 = depth[i].into();
                let mut slope = 0;
                if before {
                    slope = slope.max(here.abs_diff(depth[i - step].into()));
                }
                if after {
                    slope = slope.max(here.abs_diff(depth[i + step].into()));
                }
                let pulled = (z - bias).clamp(0, u32::MAX as i64) as u32;
                if D::quantise(pulled).into() > here + slope {
                    return;
                }
            }
            color[y as usize * stride + x as usize] = pixel;
            fragments += 1;
        });
    }
    fragments
}

/// Calls `plot(x, y, depth, x_major)` for every pixel of segment `a b` inside `r` (see the
/// module doc); `x_major` tells whether the line steps along x.
fn walk(a: Endpoint, b: Endpoint, r: Rect, mut plot: impl FnMut(i64, i64, i64, bool)) {
    let (dx, dy) = (b.xy[0] - a.xy[0], b.xy[1] - a.xy[1]);
    // The major axis, then the other one.
    let (major, minor) = if dx.abs() >= dy.abs() { (0, 1) } else { (1, 0) };
    let (a, b) = if a.xy[major] <= b.xy[major] {
        (a, b)
    } else {
        (b, a)
    };
    let along = b.xy[major] - a.xy[major];
    if along == 0 {
        return;
    }
    let across = b.xy[minor] - a.xy[minor];
    let deep = b.depth - a.depth;
    let span = |k: usize| {
        if k == 0 {
            (i64::from(r.x0), i64::from(r.x1))
        } else {
            (i64::from(r.y0), i64::from(r.y1))
        }
    };
    let (lo, hi) = span(major);
    let (mlo, mhi) = span(minor);
    // Pixels whose centre c = p * ONE + HALF lies in [a, b) on the major axis.
    let first = ceil_div(a.xy[major] - SUBPIXEL_HALF, SUBPIXEL_ONE).max(lo);
    let last = ceil_div(b.xy[major] - SUBPIXEL_HALF, SUBPIXEL_ONE).min(hi);
    for p in first..last {
        // Inside the guard band every coordinate is below 2^24 sub-pixels, so `t` and `across`
        // stay below 2^25 and their product below 2^50; depth deltas (below 2^32) times `t`
        // stay below 2^57.
        let t = (p << SUBPIXEL_BITS) + SUBPIXEL_HALF - a.xy[major];
        let q = floor_div(a.xy[minor] + floor_div(t * across, along), SUBPIXEL_ONE);
        if q < mlo || q >= mhi {
            continue;
        }
        let z = a.depth + floor_div(t * deep, along);
        if major == 0 {
            plot(p, q, z, true);
        } else {
            plot(q, p, z, false);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn end(x: f64, y: f64) -> Endpoint {
        Endpoint {
            xy: [x, y].map(|c| (c * SUBPIXEL_ONE as f64) as i64),
            depth: 0,
        }
    }

    fn pixels(a: Endpoint, b: Endpoint) -> Vec<(i64, i64)> {
        let r = Rect {
            x0: 0,
            y0: 0,
            x1: 16,
            y1: 16,
        };
        let mut out = Vec::new();
        walk(a, b, r, |x, y, _, _| out.push((x, y)));
        out.sort_unstable();
        out
    }

    #[test]
    fn a_horizontal_line_lights_the_columns_whose_centres_it_covers() {
        // From x = 1.5 (a centre: in) to x = 5.5 (a centre: out), through row 2.
        let p = pixels(end(1.5, 2.25), end(5.5, 2.25));
        assert_eq!(p, vec![(1, 2), (2, 2), (3, 2), (4, 2)]);
        assert_eq!(
            pixels(end(5.5, 2.25), end(1.5, 2.25)),
            p,
            "either direction"
        );
    }

    #[test]
    fn a_diagonal_lights_one_pixel_per_column_on_the_exact_line() {
        let p = pixels(end(0.0, 0.0), end(8.0, 8.0));
        assert_eq!(p, (0..8).map(|k| (k, k)).collect::<Vec<_>>());
        // Steep: one pixel per row.
        let p = pixels(end(2.0, 0.0), end(4.0, 8.0));
        assert_eq!(p.len(), 8);
        assert!(p.iter().enumerate().all(|(k, &(_, y))| y == k as i64));
        assert_eq!(
            p.iter().map(|&(x, _)| x).collect::<Vec<_>>(),
            [2, 2, 2, 2, 3, 3, 3, 3]
        );
    }

    #[test]
    fn depth_is_interpolated_exactly_along_the_major_axis() {
        let (mut a, mut b) = (end(0.5, 0.5), end(4.5, 0.5));
        a.depth = 1000;
        b.depth = 5000;
        let r = Rect {
            x0: 0,
            y0: 0,
            x1: 16,
            y1: 16,
        };
        let mut z = Vec::new();
        walk(a, b, r, |_, _, d, _| z.push(d));
        assert_eq!(z, [1000, 2000, 3000, 4000]);
    }
}
