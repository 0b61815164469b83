//! The integer pipeline: what a device without an FPU runs, and the fast path everywhere.
//!
//! Vertex stage: exact i64 transform (see `matrix`), outcodes, projection with one reciprocal per
//! vertex (of a normalised `w`, `fixed_point::reciprocal`). Triangle setup: attribute planes from
//! one reciprocal of the area. Pixels: monomorphised row loops that step i64 accumulators (a
//! small triangle's in 32-bit words on a 32-bit core, `small::rows_of`).

use crate::clip::{ClipVertex, Plane, outcode_by_planes};
use crate::edge::Coverage;
use crate::fixed_point::{
    ATTR_FRAC_BITS, DEPTH_ONE, GUARD_BAND_PX, MAX_DIMENSION, Q_BITS, SUBPIXEL_BITS, SUBPIXEL_HALF,
    SUBPIXEL_ONE, TEXCOORD_LIMIT, normalise_positive, reciprocal, saturate_i64, shift_round,
};
use crate::matrix::{FixedMat4, Transform};
use crate::pipeline::{Attributes, Pipeline, Setup, TexMode, Viewport};
use crate::pixel::{DepthFormat, PixelFormat};
use crate::state::Fog;
use crate::vertex::Vertex;

/// Most fractional bits of the clip-interpolation parameter.
const T_BITS_MAX: i32 = 61;

/// Guard band and viewport in the integer clip test `|x| * W <= 2 * GUARD_BAND_PX * w`.
pub(crate) struct FixedSpace {
    width: i128,
    height: i128,
}

impl FixedSpace {
    pub fn new(vp: &Viewport) -> Self {
        Self {
            width: vp.width as i128,
            height: vp.height as i128,
        }
    }
}

/// A vertex in clip space, exact integer clip coordinates plus attributes.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct FixedClip {
    clip: [i64; 4],
    uv: [i64; 2],
    color: [i64; 3],
}

impl FixedClip {
    #[inline]
    pub fn from_vertex(v: &Vertex, m: &FixedMat4) -> Self {
        Self {
            clip: m.transform(v.position),
            uv: v
                .uv
                .map(|c| (c.to_bits() as i64).clamp(-TEXCOORD_LIMIT, TEXCOORD_LIMIT)),
            color: v.color.map(i64::from),
        }
    }

    fn distance(&self, plane: Plane, s: &FixedSpace) -> i128 {
        let [x, y, z, w] = self.clip.map(i128::from);
        let g = 2 * GUARD_BAND_PX as i128 * w;
        match plane {
            Plane::WMin => w - 1,
            Plane::Near => z,
            Plane::Far => w - z,
            Plane::Left => g + s.width * x,
            Plane::Right => g - s.width * x,
            Plane::Bottom => g + s.height * y,
            Plane::Top => g - s.height * y,
        }
    }
}

/// Clip coordinates below this (in magnitude) take `FixedClip::outcode`'s i64 test: with them
/// `2 * GUARD_BAND_PX * w` stays below 2^62 and `side * x` below `2^13 * 2^46 = 2^59`
/// (`MAX_DIMENSION` is 2^13), so every distance fits in i64.
const NARROW_CLIP: u64 = 1 << 46;

impl ClipVertex for FixedClip {
    type Space = FixedSpace;

    /// The distances of `distance` in i64 when the coordinates allow it (every vertex of a
    /// terrain view: the transform's block floating point keeps its largest entry near 2^29),
    /// else plane by plane in i128. The same bits either way (tested).
    #[inline]
    fn outcode(&self, s: &FixedSpace) -> u8 {
        let [x, y, z, w] = self.clip;
        if (x.unsigned_abs() | y.unsigned_abs() | z.unsigned_abs() | w.unsigned_abs())
            >= NARROW_CLIP
        {
            return outcode_by_planes(self, s);
        }
        let g = 2 * GUARD_BAND_PX * w;
        let (sx, sy) = (s.width as i64 * x, s.height as i64 * y);
        let out = |outside: bool, p: Plane| outside as u8 * p as u8;
        out(w < 1, Plane::WMin)
            | out(z < 0, Plane::Near)
            | out(w - z < 0, Plane::Far)
            | out(g + sx < 0, Plane::Left)
            | out(g - sx < 0, Plane::Right)
            | out(g + sy < 0, Plane::Bottom)
            | out(g - sy < 0, Plane::Top)
    }

    #[inline]
    fn inside(&self, plane: Plane, s: &FixedSpace) -> bool {
        self.distance(plane, s) >= 0
    }

    fn intersect(a: &Self, b: &Self, plane: Plane, s: &FixedSpace) -> Self {
        let (da, db) = (a.distance(plane, s), b.distance(plane, s));
        // t = da / (da - db) in 0..=1, with as many fraction bits as keep `da << bits` and
        // `(q - p) * t` (|q - p| < 2^64) inside i128: a cut far along a long segment stays exact.
        let bits = (T_BITS_MAX)
            .min(125 - (128 - da.leading_zeros()) as i32)
            .max(0);
        let t = (da << bits) / (da - db);
        let lerp = |p: i64, q: i64| (p as i128 + (((q as i128 - p as i128) * t) >> bits)) as i64;
        let mut v = Self {
            clip: [0, 1, 2, 3].map(|k| lerp(a.clip[k], b.clip[k])),
            uv: [0, 1].map(|k| lerp(a.uv[k], b.uv[k])),
            color: [0, 1, 2].map(|k| lerp(a.color[k], b.color[k])),
        };
        // Land exactly on the planes whose violation would break the divide or the depth range.
        match plane {
            Plane::WMin => v.clip[3] = v.clip[3].max(1),
            Plane::Near => v.clip[2] = 0,
            Plane::Far => v.clip[2] = v.clip[3],
            _ => {}
        }
        v
    }
}

/// A projected vertex: snapped position and everything triangle setup needs.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct FixedScreen {
    /// Sub-pixel position.
    pub xy: [i64; 2],
    /// Depth, 0.32.
    depth: i64,
    /// `1/w ≈ inv_w * 2^-(62 + w_shift)`.
    inv_w: i64,
    w_shift: i32,
    uv: [i64; 2],
    color: [i64; 3],
    /// Share of the surface colour against fog, 0..=256.
    fog: i64,
    /// Which of its attributes lie inside their ranges by a small triangle's margin
    /// (`Inner::of`).
    inner: Inner,
}

impl FixedScreen {
    /// Depth, 0.32 (for the line path, which shares this projection).
    pub(crate) fn depth(&self) -> i64 {
        self.depth
    }
}

/// A vertex's attributes that lie inside the ranges their pixel values are clamped to by more
/// than a small triangle's planes can stray from the exact interpolation, one bit per kind:
/// a small triangle whose three vertices have the bits its planes need draws every pixel it owns
/// without the clamps (`FixedTriangle::bounded`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Inner(u8);

impl Inner {
    const DEPTH: u8 = 1;
    const COLOR: u8 = 2;
    const FOG: u8 = 4;
    const UV: u8 = 8;

    /// Depth (0.32) this far inside `0..DEPTH_ONE`: a depth plane of a small triangle strays
    /// by less than `2^-31` of its vertices' spread (below `2^48` with the plane's 16 fraction
    /// bits, so below `2^17`) plus 18, and 3 units are `3 * 2^16`.
    const DEPTH_MARGIN: i64 = 3;

    /// The bits of a vertex with these values: depth at least `DEPTH_MARGIN` inside its range,
    /// every colour channel and the fog share at least 1 (their ranges end at 255 and 256, a
    /// whole unit above the largest value a vertex holds), both texture coordinates above
    /// `-TEXCOORD_LIMIT` (the range ends one 16.16 unit above the largest, `TEXCOORD_LIMIT`).
    fn of(depth: i64, color: [i64; 3], fog: i64, uv: [i64; 2]) -> Self {
        let bit = |inside: bool, b: u8| inside as u8 * b;
        Self(
            bit(
                (Self::DEPTH_MARGIN..DEPTH_ONE - Self::DEPTH_MARGIN).contains(&depth),
                Self::DEPTH,
            ) | bit(color.iter().all(|&c| c >= 1), Self::COLOR)
                | bit(fog >= 1, Self::FOG)
                | bit(uv.iter().all(|&c| c > -TEXCOORD_LIMIT), Self::UV),
        )
    }

    /// The bits a triangle's planes need: those of the attributes its draw interpolates, the
    /// texture coordinates when they are affine (perspective quotients are bounded per visit,
    /// `small::quotients_in_range`).
    fn needed(a: &Attributes, tex: TexMode) -> Self {
        let bit = |used: bool, b: u8| used as u8 * b;
        Self(
            bit(a.depth, Self::DEPTH)
                | bit(a.shade, Self::COLOR)
                | bit(a.fog, Self::FOG)
                | bit(tex == TexMode::Affine, Self::UV),
        )
    }

    /// True when all three vertices have every bit of `needed`.
    fn all(v: &[&FixedScreen; 3], needed: Self) -> bool {
        v[0].inner.0 & v[1].inner.0 & v[2].inner.0 & needed.0 == needed.0
    }
}

/// Fog distances on the clip `w` scale.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FixedFog {
    pub start: i64,
    pub end: i64,
}

/// The integer pipeline's stages.
pub(crate) struct FixedPipeline;

/// What the fixed vertex stage of one draw needs.
pub(crate) struct FixedConsts {
    matrix: FixedMat4,
    vp: Viewport,
    space: FixedSpace,
    fog: Option<FixedFog>,
}

impl Pipeline for FixedPipeline {
    type Clip = FixedClip;
    type Screen = FixedScreen;
    type Triangle = FixedTriangle;
    type Plane = AttrPlane;
    type Consts = FixedConsts;

    fn consts(transform: &Transform, vp: &Viewport, fog: Option<Fog>) -> FixedConsts {
        FixedConsts {
            matrix: transform.fixed,
            vp: *vp,
            space: FixedSpace::new(vp),
            fog: fog.map(|f| FixedFog {
                start: transform.fixed.scale_length(f.start),
                end: transform.fixed.scale_length(f.end),
            }),
        }
    }

    fn space(c: &FixedConsts) -> &FixedSpace {
        &c.space
    }

    #[inline]
    fn clip(c: &FixedConsts, v: &Vertex) -> FixedClip {
        FixedClip::from_vertex(v, &c.matrix)
    }

    /// Always inlined into the vertex stage's loop: out of line, the call and its saved
    /// registers cost 0.07M instructions per PocketPC frame (`pocketpc_frames`, callgrind).
    #[inline(always)]
    fn project(c: &FixedConsts, clip: &FixedClip) -> FixedScreen {
        FixedScreen::project(clip, &c.vp, c.fog)
    }

    #[inline]
    fn xy(s: &FixedScreen) -> [i64; 2] {
        s.xy
    }

    /// Always inlined into the set-up loop: out of line, the call per triangle cost more than
    /// the copies of the loop it saves.
    #[inline(always)]
    fn triangle(
        v: [&FixedScreen; 3],
        area2: i64,
        coverage: Coverage,
        attrs: &Attributes,
        draw: u32,
        planes: &mut Vec<AttrPlane>,
    ) -> FixedTriangle {
        FixedTriangle::new(v, area2, coverage, attrs, draw, planes)
    }
}

impl FixedScreen {
    #[inline(always)]
    pub fn project(v: &FixedClip, vp: &Viewport, fog: Option<FixedFog>) -> Self {
        let w = v.clip[3].max(1);
        let (xy, depth, inv_w, shift) = project_narrow(v.clip, w, vp).unwrap_or_else(|| {
            let (xy, depth, inv_w, shift) = project_wide(v.clip, vp);
            (vp.clamp_to_guard_band(xy), depth, inv_w, shift)
        });
        let fog = match fog {
            Some(f) if f.end > f.start => (((f.end as i128 - w as i128) * 256)
                / (f.end as i128 - f.start as i128))
                .clamp(0, 256) as i64,
            Some(f) => {
                if w < f.end {
                    256
                } else {
                    0
                }
            }
            None => 256,
        };
        Self {
            xy,
            depth,
            inv_w,
            w_shift: shift,
            uv: v.uv,
            color: v.color,
            fog,
            inner: Inner::of(depth, v.color, fog, v.uv),
        }
    }
}

/// What the projection gives: the snapped position (inside the guard band), depth (0.32),
/// `1/w` and its shift (see `FixedScreen::inv_w`).
type Projected = ([i64; 2], i64, i64, i32);

/// The projection in i64 products and one widening multiplication per coordinate, for the
/// vertices where the bounds allow it (almost all: those within 8 viewport half-sizes of the
/// centre and inside the depth range); `None` for the others.
///
/// Bounds: `x' = x * 2^-shift` (rounded down when `shift > 0`, exact otherwise), as
/// `project_wide` scales it; `|x'| < 2^34` and a viewport side up to 2^13 keep
/// `x' * SUBPIXEL_HALF * side` below `2^34 * 2^7 * 2^13 = 2^54`, and that times `inv_w <= 2^32`
/// below 2^86 (one widening multiplication, rounded in i128 as `shift_round` does). Depth
/// needs `0 <= z <= w`, so `0 <= z' <= wn` and `z' * inv_w <= wn * 2^62 / wn = 2^62`: an i64
/// product whose rounding half cannot overflow. The result is `project_wide`'s to the bit
/// (tested at the extremes and at random).
#[inline]
fn project_narrow(clip: [i64; 4], w: i64, vp: &Viewport) -> Option<Projected> {
    debug_assert!(w > 0 && vp.width <= MAX_DIMENSION && vp.height <= MAX_DIMENSION);
    const LIMIT: u32 = 34;
    let [x, y, z, _] = clip;
    if z < 0 || z > w {
        return None;
    }
    // `normalise_positive` of `w` in i64: `wn` in `[2^30, 2^31)`, `shift` in `-30..=32`.
    let shift = 33 - w.leading_zeros() as i32;
    let (wn, x, y, z) = if shift >= 0 {
        (w >> shift, x >> shift, y >> shift, z >> shift)
    } else {
        let up = -shift as u32;
        if (x.unsigned_abs() | y.unsigned_abs()) >> (LIMIT - up) != 0 {
            return None;
        }
        (w << up, x << up, y << up, z << up)
    };
    if (x.unsigned_abs() | y.unsigned_abs()) >> LIMIT != 0 {
        return None;
    }
    let inv_w = reciprocal(wn); // (2^31, 2^32]
    let half_w = vp.width as i64 * SUBPIXEL_HALF;
    let half_h = vp.height as i64 * SUBPIXEL_HALF;
    let offset = |c: i64, half: i64| ((c * half) as i128 * inv_w as i128 + (1 << 61)) >> 62;
    let sx = half_w + offset(x, half_w) as i64;
    let sy = half_h - offset(y, half_h) as i64;
    let depth = ((z * inv_w + (1 << 29)) >> 30).min(DEPTH_ONE - 1);
    Some((vp.clamp_to_guard_band([sx, sy]), depth, inv_w, shift))
}

/// The projection of any clip position (`w` taken as at least 1) in 128-bit products: the
/// position before the guard band's clamp.
fn project_wide(clip: [i64; 4], vp: &Viewport) -> Projected {
    let [x, y, z, w] = clip.map(i128::from);
    let w = w.max(1);
    let (wn, shift) = normalise_positive(w);
    let scale = |c: i128| if shift > 0 { c >> shift } else { c << -shift };
    let inv_w = reciprocal(wn); // (2^31, 2^32]
    let half_w = vp.width as i128 * SUBPIXEL_HALF as i128;
    let half_h = vp.height as i128 * SUBPIXEL_HALF as i128;
    // Inside the guard band |x'| < 2^48, so the products stay below 2^100.
    let sx = half_w + shift_round(scale(x) * inv_w as i128 * half_w, 62);
    let sy = half_h - shift_round(scale(y) * inv_w as i128 * half_h, 62);
    let depth = shift_round(scale(z) * inv_w as i128, 30).clamp(0, DEPTH_ONE as i128 - 1) as i64;
    ([saturate_i64(sx), saturate_i64(sy)], depth, inv_w, shift)
}

/// An attribute as a plane over the triangle: per-pixel gradients and a base, all with
/// `ATTR_FRAC_BITS` extra fraction. The base is the value at the origin vertex, or, once the plane
/// is moved onto the pixel grid (`on_grid`), the value at the centre of pixel `(0, 0)`.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct AttrPlane {
    base: i64,
    pub(crate) dx: i64,
    pub(crate) dy: i64,
}

/// Gradients below this keep every product of the fast path inside i64 (offsets stay below 2^26
/// inside the guard band, the base below 2^61).
const NARROW_GRADIENT: u64 = 1 << 36;

/// Gradients below this keep a small triangle's planes inside i64 once they are on its pixel
/// grid (`AttrPlane::on_grid`), where they are only ever evaluated inside its rectangle.
///
/// Bounds: a small triangle's rectangle starts at the pixel column of its leftmost vertex (or
/// right of it, cut by the scissor) and at its first row whose centre lies between its top and
/// bottom vertex, and its vertices lie within 17 pixel columns and rows (`SMALL_EDGE`), so the
/// offset from the origin vertex to the centre of the rectangle's first pixel is below
/// `17 * 256 + 128 < 2^13` sub-pixels on each axis. Then `dx * ox + dy * oy + 128` stays below
/// `2 * 2^49 * 2^13 = 2^63`, and the base moves by less than 2^55 (after the shift by 8). Inside
/// the rectangle (at most 16 pixels a side) `dx * col + dy * row` stays below `2^54`: with the
/// base below 2^61, every value and sum of the small loop and the row step stays below 2^62.
const SMALL_NARROW_GRADIENT: u64 = 1 << 49;

/// The gradient below which a triangle's planes stay inside i64 on its pixel grid, from how far
/// its rectangle's pixel centres lie from its origin vertex (`reach`, in sub-pixels, below
/// `2^b`): at least `NARROW_GRADIENT` (which holds anywhere in the guard band), and `2^(61 - b)`
/// where that is more. Then `dx * ox + dy * oy + 128` in `on_grid` stays below `2^62`, the base
/// moves by less than 2^54, and inside the rectangle (`256 * col` and `256 * row` at most twice
/// the reach) `dx * col + dy * row` stays below 2^55: with the base below 2^61, every value and
/// sum of the row step stays below 2^62, as for a small triangle (`SMALL_NARROW_GRADIENT`). A
/// triangle of a few dozen pixels thus gets narrow texture planes under exact perspective, whose
/// gradients pass `NARROW_GRADIENT`, and its rows start in i64 instead of 128-bit products.
///
/// Out of line: only triangles beyond 16x16 pixels ask, and inlined it made the set-up loop of
/// the small ones 0.05M instructions per PocketPC frame dearer (`pocketpc_frames`, callgrind).
#[inline(never)]
fn reach_gradient(c: &Coverage) -> u64 {
    let origin = c.origin();
    let (first, last) = (c.corner(), [c.rect.x1 as i64 - 1, c.rect.y1 as i64 - 1]);
    let centre = |p: i64| p * SUBPIXEL_ONE + SUBPIXEL_HALF;
    let reach = (0..2)
        .map(|k| {
            let (a, b) = (centre(first[k]) - origin[k], centre(last[k]) - origin[k]);
            a.unsigned_abs().max(b.unsigned_abs())
        })
        .max()
        .unwrap_or(0);
    let bits = 64 - reach.leading_zeros();
    NARROW_GRADIENT.max(1 << (61 - bits.min(61)))
}

impl AttrPlane {
    /// True when the plane's gradients are below `limit` (`NARROW_GRADIENT`, or
    /// `SMALL_NARROW_GRADIENT` for a small triangle's).
    #[inline]
    fn narrow_below(&self, limit: u64) -> bool {
        (self.dx.unsigned_abs() | self.dy.unsigned_abs()) < limit
    }

    /// True when the plane's gradients are small enough for i64 evaluation anywhere in the
    /// guard band.
    #[inline]
    fn narrow(&self) -> bool {
        self.narrow_below(NARROW_GRADIENT)
    }

    /// Moves a narrow plane's base from the origin vertex at `origin` (sub-pixels) to the centre
    /// of pixel `corner` (the first pixel of the triangle's rectangle). At pixel
    /// `corner + (col, row)` the offset is `(256 col + ox, 256 row + oy)` with `(ox, oy)` the
    /// offset of the corner's centre, so the rounded product `(dx * off_x + dy * off_y + 128) >> 8`
    /// of `at` splits exactly into `dx * col + dy * row` plus the same expression at the corner:
    /// a row start then costs two multiplications and no rounding (`at_pixel`). The offsets stay
    /// small inside the rectangle, which is what lets a small triangle's planes be narrow up to
    /// `SMALL_NARROW_GRADIENT`.
    fn on_grid(self, origin: [i64; 2], corner: [i64; 2]) -> Self {
        let half = 1 << (SUBPIXEL_BITS - 1);
        let ox = corner[0] * SUBPIXEL_ONE + SUBPIXEL_HALF - origin[0];
        let oy = corner[1] * SUBPIXEL_ONE + SUBPIXEL_HALF - origin[1];
        Self {
            base: self.base + ((self.dx * ox + self.dy * oy + half) >> SUBPIXEL_BITS),
            ..self
        }
    }

    /// Value at the centre of pixel `(col, row)` of the triangle's rectangle (counted from its
    /// first pixel) of a plane `on_grid`, equal to `at` there.
    #[inline]
    pub(crate) fn at_pixel(&self, col: i64, row: i64) -> i64 {
        self.base + self.dx * col + self.dy * row
    }

    /// Value at the sub-pixel offset `(ox, oy)` from the origin vertex.
    #[inline]
    fn at(&self, ox: i64, oy: i64) -> i64 {
        // Offsets stay below 2^26 inside the guard band, so gradients below 2^36 keep both
        // products and their sum inside i64, and the base (below 2^61) cannot overflow either:
        // the common case needs no 128-bit arithmetic. Same rounding as the wide path.
        if self.narrow() {
            let half = 1 << (SUBPIXEL_BITS - 1);
            return self.base + ((self.dx * ox + self.dy * oy + half) >> SUBPIXEL_BITS);
        }
        let d = self.dx as i128 * ox as i128 + self.dy as i128 * oy as i128;
        saturate_i64(self.base as i128 + shift_round(d, SUBPIXEL_BITS as i32))
    }
}

/// Per-triangle reciprocal of the doubled area, and the edge vectors from vertex 0.
///
/// Kept as i64 (edge vectors below 2^26, the reciprocal below 2^33) and widened per product, so
/// that every product of two of them is one widening multiplication.
struct Geometry {
    d1: [i64; 2],
    d2: [i64; 2],
    inv_area: i64,
    shift: i32,
    /// Half of `2^shift`, the rounding of `plane_small`'s products (once per triangle, not per
    /// plane); 0 for a triangle that is not small.
    half: i64,
    /// Edge vectors below `SMALL_EDGE` (a small triangle): the planes take `plane_small`.
    small: bool,
}

/// Edge vectors of a triangle within 16x16 pixels (`Coverage::is_small`) stay below this many
/// sub-pixels: its extreme vertices lie in 17 pixel columns and rows, `|d| < 17 * 256 = 4352`.
///
/// With them, a plane needs no 128-bit sum (see `Geometry::plane_small`): attribute differences
/// stay below 2^45 (`s, t` under perspective: 2^24 texture units times `q < 2^20`, doubled),
/// so `nx = a1 * d2y - a2 * d1y` stays below 2 * 2^45 * 2^13 = 2^59; the doubled area below
/// `4352^2 < 2^25`, so it is shifted up by at least 6 to normalise it, and the plane's shift lies
/// in 8..=32.
const SMALL_EDGE: i64 = 1 << 13;

impl Geometry {
    /// The geometry of `v` (`small`: within 16x16 pixels, `Coverage::is_small`).
    fn new(v: &[&FixedScreen; 3], area2: i64, small: bool) -> Self {
        let d = |i: usize| [v[i].xy[0] - v[0].xy[0], v[i].xy[1] - v[0].xy[1]];
        let (d1, d2) = (d(1), d(2));
        debug_assert!(!small || d1.iter().chain(&d2).all(|c| c.abs() < SMALL_EDGE));
        let (an, ash) = if small {
            // `normalise_positive` without 128-bit shifts: the area is below 2^25.
            debug_assert!(area2 > 0 && area2 < 1 << 25);
            let up = (area2 as u64).leading_zeros() as i32 - 33;
            (area2 << up, -up)
        } else {
            normalise_positive(area2 as i128)
        };
        // gradient per pixel, with ATTR_FRAC_BITS = num * 2^(SUBPIXEL_BITS + ATTR_FRAC_BITS) / area2
        let shift = 62 - (SUBPIXEL_BITS + ATTR_FRAC_BITS) as i32 + ash;
        Self {
            d1,
            d2,
            inv_area: reciprocal(an),
            shift,
            // The shift lies in 8..=32 for a small triangle (see `SMALL_EDGE`).
            half: if small { 1 << ((shift - 1) & 63) } else { 0 },
            small,
        }
    }

    #[inline(always)]
    fn plane(&self, a: [i64; 3]) -> AttrPlane {
        let (dx, dy) = if self.small {
            self.plane_small(a)
        } else {
            self.plane_wide(a)
        };
        AttrPlane {
            base: a[0] << ATTR_FRAC_BITS,
            dx,
            dy,
        }
    }

    /// The gradients of a small triangle's plane: the products of `plane_wide` in i64, the
    /// scaled ones as one widening multiplication each (see `SMALL_EDGE` for the bounds). The
    /// same integers as `plane_wide`, so the same pixels.
    #[inline(always)]
    fn plane_small(&self, a: [i64; 3]) -> (i64, i64) {
        let (a1, a2) = (a[1] - a[0], a[2] - a[0]);
        debug_assert!(a1.abs() < 1 << 46 && a2.abs() < 1 << 46);
        let nx = a1 * self.d2[1] - a2 * self.d1[1];
        let ny = a2 * self.d1[0] - a1 * self.d2[0];
        debug_assert!((8..=32).contains(&self.shift));
        // Masked: the compiler then knows the shift is below 64; the rounding half is below
        // 2^63, a 64-bit value added to the 128-bit product.
        let s = self.shift as u32 & 63;
        let half = self.half as i128;
        let inv = self.inv_area as i128;
        let wide = |n: i64| i64::try_from((n as i128 * inv + half) >> s).ok();
        // A 32-bit core builds the 128-bit product from many words: there the gradients come
        // from 32x32-bit products where they lie below 2^62 (all but the steepest).
        #[cfg(not(target_pointer_width = "64"))]
        let wide = |n: i64| scale_in_words(n, self.inv_area, s).or_else(|| wide(n));
        match (wide(nx), wide(ny)) {
            (Some(dx), Some(dy)) => (dx, dy),
            _ => (0, 0),
        }
    }

    /// The gradients of a plane, in 128-bit products.
    fn plane_wide(&self, a: [i64; 3]) -> (i64, i64) {
        let wide = |x: i64, y: i64| x as i128 * y as i128;
        // Attribute differences stay below 2^62 (depth 2^32, s and t 2^44, colour 2^8).
        let (a1, a2) = (a[1] - a[0], a[2] - a[0]);
        let nx = wide(a1, self.d2[1]) - wide(a2, self.d1[1]);
        let ny = wide(a2, self.d1[0]) - wide(a1, self.d2[0]);
        let inv = self.inv_area as i128;
        let (dx, dy) = (
            shift_round(nx * inv, self.shift),
            shift_round(ny * inv, self.shift),
        );
        match (i64::try_from(dx), i64::try_from(dy)) {
            (Ok(dx), Ok(dy)) => (dx, dy),
            // A gradient beyond i64 means the triangle is thinner than 2^-15 pixel across this
            // attribute's range: it can own at most isolated pixels, which take vertex 0's value.
            _ => (0, 0),
        }
    }
}

/// `(n * inv + 2^(s - 1)) >> s`, `plane_small`'s rounded product, in 32x32-bit products, for
/// `|n| < 2^60`, `inv` in `(2^31, 2^32]` (`Geometry::inv_area`) and `s` in `8..=32`, where the
/// result lies within `2^62` (`None` otherwise).
///
/// With `inv = 2^32 - c` (`c < 2^31`) and `n = 2^32 hi + lo` (`lo` its low word, unsigned),
/// `n inv + 2^(s - 1) = 2^32 h + l` with `h = n - hi c` and `l = 2^(s - 1) - lo c`: two products
/// of words (`hi c` below 2^59, `lo c` below 2^63), `|h| < 2^61`. As `s <= 32`, `2^s` divides
/// `2^32 h`, so the shifted sum is exactly `h 2^(32 - s) + (l >> s)`; where `|h| < 2^(30 + s)`
/// the first term lies within 2^62 and the second below 2^55, so neither the terms nor the sum
/// leave i64.
#[cfg(any(test, not(target_pointer_width = "64")))]
#[inline(always)]
fn scale_in_words(n: i64, inv: i64, s: u32) -> Option<i64> {
    debug_assert!(n.unsigned_abs() < 1 << 60 && (1 << 31) < inv && inv <= 1 << 32);
    debug_assert!((8..=32).contains(&s));
    let c = ((1i64 << 32) - inv) as i32;
    let (hi, lo) = ((n >> 32) as i32, n as u32);
    let h = n - hi as i64 * c as i64;
    let l = (1i64 << (s - 1)) - (lo as u64 * c as u64) as i64;
    // `|h| < 2^(30 + s)` read off its high word (`2^32` divides `2^(30 + s)`).
    let top = (h >> 32) as i32;
    // Shifts by less than 32 (masked so that the compiler knows it): a few instructions on
    // a 32-bit core, where a shift by any amount below 64 takes a dozen.
    let within = (top.wrapping_add(1 << ((s - 2) & 31)) as u32) < 1 << ((s - 1) & 31);
    within.then(|| (h << ((32 - s) & 31)) + ((l >> 1) >> ((s - 1) & 31)))
}

/// A triangle ready for its rows: 64 bytes, with its attribute planes beside it in the set-up
/// chunk's plane list, only those its draw uses, in the order depth, colour (one plane for grey
/// vertices, else three), fog, texture (`u, v`, or `s, t, q` under perspective).
#[derive(Clone, Copy, Debug)]
pub(crate) struct FixedTriangle {
    pub coverage: Coverage,
    /// Index of its first plane in the chunk's planes.
    planes: u32,
    /// This triangle's texture interpolation (see `Attributes::tex_mode_for`).
    tex_mode: TexMode,
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
        let pick = |f: fn(&FixedScreen) -> i64| g.plane([f(v[0]), f(v[1]), f(v[2])]);
        if a.depth {
            planes.push(pick(|s| s.depth));
        }
        if a.shade {
            // Terrain lighting is grey (r = g = b at every vertex): one plane serves all three.
            t.grey = v
                .iter()
                .all(|s| s.color[1] == s.color[0] && s.color[2] == s.color[0]);
            planes.push(pick(|s| s.color[0]));
            if !t.grey {
                planes.push(pick(|s| s.color[1]));
                planes.push(pick(|s| s.color[2]));
            }
        }
        if a.fog {
            planes.push(pick(|s| s.fog));
        }
        t.tex_mode = a.tex_mode_for([v[0].xy, v[1].xy, v[2].xy], coverage.is_small());
        match t.tex_mode {
            TexMode::Off => {}
            TexMode::Affine => {
                planes.push(pick(|s| s.uv[0]));
                planes.push(pick(|s| s.uv[1]));
                t.level = a.level(texel_area(&v), area2);
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
                planes.push(st(0));
                planes.push(st(1));
                planes.push(g.plane(q));
                t.level = a.level(texel_area(&v), area2);
            }
        }
        t.bounded = coverage.is_small() && Inner::all(&v, Inner::needed(a, t.tex_mode));
        let mine = &mut planes[first..];
        let limit = if coverage.is_small() {
            SMALL_NARROW_GRADIENT
        } else {
            reach_gradient(&coverage)
        };
        t.narrow = mine.iter().all(|p| p.narrow_below(limit));
        if t.narrow {
            let corner = coverage.corner();
            for p in mine {
                *p = p.on_grid(v[0].xy, corner);
            }
        }
        t
    }
}

/// Doubled texture-space area in 16.16 repeats squared. In i64: coordinates stay within
/// `TEXCOORD_LIMIT` (2^24), so differences below 2^25 and their products below 2^50.
fn texel_area(v: &[&FixedScreen; 3]) -> i128 {
    let d = |i: usize, k: usize| v[i].uv[k] - v[0].uv[k];
    (d(1, 0) * d(2, 1) - d(2, 0) * d(1, 1)).abs() as i128
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

/// `(u, v)` in 16.32 at a point from the perspective accumulators: one division per call.
/// Clamped to the texture-coordinate range, which extrapolation past a span end can leave.
#[inline]
pub(crate) fn divide(s: i64, t: i64, q: i64) -> (i64, i64) {
    let r = ((1u64 << 63) / q.max(1) as u64) as i128;
    let limit = (TEXCOORD_LIMIT as i128) << 16;
    let uv = |a: i64| ((a as i128 * r) >> 47).clamp(-limit, limit) as i64;
    (uv(s), uv(t))
}

/// `divide` where the quotients are known to be inside the range (`q >= 2` and
/// `|s|, |t| <= q * TEXCOORD_LIMIT`, so `|s| * 2^16 / q <= TEXCOORD_LIMIT << 16`): the same
/// values without the clamps, each a 64x64-bit product and a shift (`q >= 2` keeps the
/// reciprocal below 2^63, in i64).
#[inline(always)]
pub(crate) fn divide_in_range(s: i64, t: i64, q: i64) -> (i64, i64) {
    debug_assert!(
        q >= 2
            && s.unsigned_abs().max(t.unsigned_abs()) as u128 <= q as u128 * TEXCOORD_LIMIT as u128
    );
    let r = ((1u64 << 63) / q as u64) as i64;
    let uv = |a: i64| ((a as i128 * r as i128) >> 47) as i64;
    let out = (uv(s), uv(t));
    debug_assert_eq!(out, divide(s, t, q));
    out
}

/// `2^32 / n` for span lengths `n` in `1..=64`, rounded up.
const RECIPROCALS: [i64; 65] = {
    let mut t = [0i64; 65];
    let mut n = 1;
    while n <= 64 {
        t[n] = ((1i64 << 32) + n as i64 - 1) / n as i64;
        n += 1;
    }
    t
};

/// `d / n` for a span length `n <= 64` by a multiplication: a division per span would cost more
/// than the span's pixels. Exact for the `|d| < 2^41` of texture-coordinate differences.
#[inline]
fn div_small(d: i64, n: i64) -> i64 {
    ((d as i128 * RECIPROCALS[n as usize] as i128) >> 32) as i64
}

/// A plane's accumulator `k` chunks of `step` after `start`, as repeated saturating additions
/// would leave it (the steps share one sign, so the sum saturates once and stays there).
#[inline]
fn advance(start: i64, step: i64, k: i64) -> i64 {
    saturate_i64(start as i128 + step as i128 * k as i128)
}

/// One row's run of a triangle: it owns pixels `x0..x1` of row `y`, and `color` and `depth`
/// (empty without a depth test) hold pixels `xs..` of them (a tile's part of the run).
pub(crate) struct Span<'a, P: PixelFormat, D: DepthFormat> {
    pub y: i64,
    pub x0: i64,
    pub x1: i64,
    pub xs: i64,
    pub color: &'a mut [P::Pixel],
    pub depth: &'a mut [D::Value],
}

#[cfg(test)]
pub(crate) mod reference;
mod rows;

pub(crate) use rows::{DepthTest, NarrowPlanes, RunPiece, plane_offsets, run_fragments};

#[cfg(test)]
mod tests {
    use super::*;
    use crate::edge::PixelRect;

    /// The geometry `Geometry::new` makes of the triangle `v` (sub-pixels), if its orientation
    /// is positive.
    fn geometry(v: [[i64; 2]; 3], small: bool) -> Option<Geometry> {
        let d = |i: usize| [v[i][0] - v[0][0], v[i][1] - v[0][1]];
        let area2 = d(1)[0] * d(2)[1] - d(2)[0] * d(1)[1];
        let screen = v.map(|xy| FixedScreen {
            xy,
            ..FixedScreen::default()
        });
        (area2 > 0).then(|| Geometry::new(&[&screen[0], &screen[1], &screen[2]], area2, small))
    }

    /// `project_narrow`, where it applies, against `project_wide`.
    fn check_projection(clip: [i64; 4], vp: &Viewport) -> bool {
        let w = clip[3].max(1);
        let Some(narrow) = project_narrow(clip, w, vp) else {
            return false;
        };
        let (xy, depth, inv_w, shift) = project_wide(clip, vp);
        assert_eq!(
            narrow,
            (vp.clamp_to_guard_band(xy), depth, inv_w, shift),
            "{clip:?} {vp:?}"
        );
        true
    }

    #[test]
    fn narrow_projection_equals_128_bit_products_at_the_extremes() {
        let ws = [
            1i64,
            (1 << 30) - 1,
            1 << 30,
            (1 << 31) - 1,
            1 << 31,
            (1 << 31) + 1,
            1 << 47,
            (1 << 61) + 12345,
            (1 << 62) - 1,
        ];
        let (mut narrow, mut all) = (0, 0);
        for size in [1u32, 320, MAX_DIMENSION] {
            let vp = Viewport {
                width: size,
                height: (size / 2).max(1),
            };
            for &w in &ws {
                let shift = 33 - w.leading_zeros() as i32;
                // The largest x the narrow path takes, one past it, the guard band's edge, and
                // the ends of i64.
                let edge = if shift >= 0 {
                    ((1i128 << 34) << shift) - 1
                } else {
                    ((1i128 << 34) >> -shift) - 1
                };
                let band = w as i128 * 2 * GUARD_BAND_PX as i128 / size as i128;
                let [edge, band] = [edge, band].map(|c| c.min(i64::MAX as i128 - 1) as i64);
                let xs = [0, 1, edge, edge + 1, band, band + 1, i64::MAX];
                let zs = [
                    0,
                    1,
                    w / 2,
                    w - 1,
                    w,
                    w + 1,
                    w + (1 << shift.max(0)),
                    -1,
                    i64::MIN,
                ];
                for &x in &xs {
                    for sign in [1, -1] {
                        for &z in &zs {
                            let c = sign * x;
                            for clip in [[c, -c / 3, z, w], [c / 5, c, z, w]] {
                                narrow += check_projection(clip, &vp) as u32;
                                all += 1;
                            }
                        }
                    }
                }
            }
        }
        assert!(narrow > 1000 && narrow < all, "{narrow} of {all}");
    }

    proptest::proptest! {
        /// Random vertices inside and around the guard band project as in 128 bits.
        #[test]
        fn narrow_projection_equals_128_bit_products(
            w in 1i64..1 << 62,
            x in -(1i64 << 40)..1 << 40,
            y in -(1i64 << 40)..1 << 40,
            z in -(1i64 << 10)..1 << 33,
            size in 1u32..=MAX_DIMENSION,
        ) {
            let vp = Viewport { width: size, height: size };
            // Coordinates as multiples of w / 2^32 (z up to twice w).
            let at = |c: i64| ((c as i128 * w as i128) >> 32) as i64;
            check_projection([at(x), at(y), at(z), w], &vp);
        }
    }

    /// The i64 outcode against the 128-bit distances, plane by plane.
    fn check_outcode(clip: [i64; 4], size: u32) {
        let vp = Viewport {
            width: size,
            height: (size / 3).max(1),
        };
        let s = FixedSpace::new(&vp);
        let v = FixedClip {
            clip,
            ..FixedClip::default()
        };
        assert_eq!(v.outcode(&s), outcode_by_planes(&v, &s), "{clip:?} {size}");
    }

    #[test]
    fn outcodes_in_i64_equal_128_bit_distances_at_the_bounds() {
        let n = NARROW_CLIP as i64;
        let at = [0, 1, 2, n / 2, n - 1, n, i64::MAX, i64::MIN, i64::MIN + 1];
        let coords: Vec<i64> = at.iter().flat_map(|&c| [c, c.saturating_neg()]).collect();
        for size in [1, 320, MAX_DIMENSION] {
            for &w in &coords {
                // Points on and beside the guard band's planes for this w, and the bounds.
                let band = (2 * GUARD_BAND_PX as i128 * w as i128 / size as i128)
                    .clamp(i64::MIN as i128 + 2, i64::MAX as i128 - 2)
                    as i64;
                let xs: Vec<i64> = coords
                    .iter()
                    .copied()
                    .chain([band - 1, band, band + 1, -band - 1, -band, -band + 1])
                    .collect();
                for &x in &xs {
                    for &z in &[0, -1, w, w.saturating_add(1), w.saturating_sub(1), x] {
                        check_outcode([x, x.saturating_neg() / 3, z, w], size);
                        check_outcode([x / 7, x, z, w], size);
                    }
                }
            }
        }
    }

    proptest::proptest! {
        /// Random clip coordinates on both sides of the i64 test's bound give the outcode of the
        /// 128-bit distances.
        #[test]
        fn outcodes_in_i64_equal_128_bit_distances(
            x in -(1i64 << 48)..1 << 48,
            y in -(1i64 << 48)..1 << 48,
            z in -(1i64 << 48)..1 << 48,
            w in -(1i64 << 20)..1 << 48,
            size in 1u32..=MAX_DIMENSION,
        ) {
            check_outcode([x, y, z, w], size);
            // Scaled towards the guard band's planes, where the sign of a distance is close.
            let band = 2 * GUARD_BAND_PX * (w >> 17) / size as i64;
            check_outcode([band + x % 3, -band - y % 3, z, w >> 17], size);
        }
    }

    /// The largest attribute difference a plane meets: `s, t` under perspective.
    const MAX_ATTR: i64 = 1 << 45;
    /// The last sub-pixel of the 17 pixel columns (rows) a small triangle's vertices lie in.
    const EDGE: i64 = 17 * SUBPIXEL_ONE - 1;

    /// `scale_in_words` against the 128-bit product, where it gives a value.
    fn check_scale(n: i64, inv: i64, s: u32) -> bool {
        let wide = i64::try_from((n as i128 * inv as i128 + (1i128 << (s - 1))) >> s).ok();
        let words = scale_in_words(n, inv, s);
        if words.is_some() {
            assert_eq!(words, wide, "{n} {inv} {s}");
        }
        words.is_some()
    }

    #[test]
    fn products_in_words_equal_128_bit_products_at_the_bounds() {
        let (mut given, mut all) = (0, 0);
        let top = (1i64 << 60) - 1;
        for s in 8..=32 {
            // Around the words' bound on `h` (about `n`), and the ends.
            let bound = 1i64 << (30 + s);
            let ns = [
                0,
                1,
                2,
                (1 << 31) - 1,
                1 << 31,
                1 << 32,
                bound - 1,
                bound,
                bound + 1,
                top,
            ];
            for n in ns.iter().flat_map(|&n| [n.min(top), -n.min(top)]) {
                for inv in [
                    (1i64 << 31) + 1,
                    (1 << 31) + 12345,
                    3 << 30,
                    (1 << 32) - 1,
                    1 << 32,
                ] {
                    given += check_scale(n, inv, s) as u32;
                    all += 1;
                }
            }
        }
        assert!(given * 4 > all * 3 && given < all, "{given} of {all}");
    }

    proptest::proptest! {
        #[test]
        fn products_in_words_equal_128_bit_products(
            n in -(1i64 << 60) + 1..1 << 60,
            inv in (1i64 << 31) + 1..=1 << 32,
            s in 8u32..=32,
            bits in 0u32..61,
        ) {
            check_scale(n, inv, s);
            check_scale(n >> bits, inv, s);
        }
    }

    #[test]
    fn small_planes_equal_wide_planes_at_the_bounds() {
        let at = [0, 1, EDGE / 3, EDGE / 2 + 7, EDGE - 1, EDGE];
        let points: Vec<[i64; 2]> = at.iter().flat_map(|&x| at.map(|y| [x, y])).collect();
        let attrs = [-MAX_ATTR, -(1 << 32), -255, 0, 1, 1 << 24, MAX_ATTR];
        let (mut checked, mut largest) = (0, 0);
        for &a in &points {
            for &b in &points {
                for &c in &points {
                    let (Some(small), Some(wide)) =
                        (geometry([a, b, c], true), geometry([a, b, c], false))
                    else {
                        continue;
                    };
                    assert_eq!((small.inv_area, small.shift), (wide.inv_area, wide.shift));
                    largest = largest.max(small.shift);
                    for a1 in attrs {
                        for a2 in attrs {
                            let q = [0, a1, a2];
                            assert_eq!(small.plane_small(q), wide.plane_wide(q));
                            checked += 1;
                        }
                    }
                }
            }
        }
        // The largest area (a right angle on the box's corners) has the largest shift.
        assert_eq!(largest, 32);
        assert!(checked > 100_000, "{checked} planes");
    }

    proptest::proptest! {
        /// The small triangles' planes (i64 products) are the integers of the 128-bit ones.
        #[test]
        fn small_planes_equal_wide_planes(
            v in proptest::collection::vec(0..=EDGE, 6),
            a in proptest::collection::vec(-MAX_ATTR / 2..=MAX_ATTR / 2, 3),
        ) {
            let v = [[v[0], v[1]], [v[2], v[3]], [v[4], v[5]]];
            if let (Some(small), Some(wide)) = (geometry(v, true), geometry(v, false)) {
                let a = [a[0], a[1], a[2]];
                proptest::prop_assert_eq!(small.plane_small(a), wide.plane_wide(a));
            }
        }
    }

    proptest::proptest! {
        /// Rows of narrow triangles start from the plane moved onto the pixel grid: it must give
        /// the very value `at` gives from the origin vertex, at every pixel centre.
        #[test]
        fn a_plane_on_the_pixel_grid_equals_the_plane_at_every_pixel(
            base in -(1i64 << 60)..1 << 60,
            dx in -(1i64 << 36) + 1..1 << 36,
            dy in -(1i64 << 36) + 1..1 << 36,
            origin in (-(1i64 << 23)..1 << 23, -(1i64 << 23)..1 << 23),
            corner in (0i64..4096, 0i64..4096),
            pixel in (0i64..4096, 0i64..4096),
        ) {
            let plane = AttrPlane { base, dx, dy };
            let origin = [origin.0, origin.1];
            let corner = [corner.0, corner.1];
            let (x, y) = (corner[0] + pixel.0, corner[1] + pixel.1);
            let ox = x * SUBPIXEL_ONE + SUBPIXEL_HALF - origin[0];
            let oy = y * SUBPIXEL_ONE + SUBPIXEL_HALF - origin[1];
            let on_grid = plane.on_grid(origin, corner);
            proptest::prop_assert_eq!(on_grid.at_pixel(pixel.0, pixel.1), plane.at(ox, oy));
        }
    }

    /// The value of `plane` (based at the origin vertex) at the centre of pixel `(x, y)`, in
    /// 128-bit products: what the rows of a plane that is not narrow start from.
    fn at_in_128_bits(plane: &AttrPlane, origin: [i64; 2], x: i64, y: i64) -> i128 {
        let ox = (x * SUBPIXEL_ONE + SUBPIXEL_HALF - origin[0]) as i128;
        let oy = (y * SUBPIXEL_ONE + SUBPIXEL_HALF - origin[1]) as i128;
        plane.base as i128 + shift_round(plane.dx as i128 * ox + plane.dy as i128 * oy, 8)
    }

    /// Checks a small triangle's plane on its pixel grid against the 128-bit evaluation at every
    /// pixel of its rectangle (with overflow checks on, an overflow on the way panics). Returns
    /// false when `v` is not a small triangle owning a row inside `clip`.
    fn check_small_plane(v: [[i64; 2]; 3], plane: AttrPlane, clip: PixelRect) -> bool {
        let Some((origin, cov)) = covered(v, clip).filter(|(_, c)| c.is_small()) else {
            return false;
        };
        assert!(plane.narrow_below(SMALL_NARROW_GRADIENT));
        let r = cov.rect;
        let pixels = (r.y0 as i64..r.y1 as i64)
            .flat_map(|y| (r.x0 as i64..r.x1 as i64).map(move |x| (x, y)));
        assert_on_grid(plane, origin, &cov, pixels);
        true
    }

    /// The largest screen: triangles on it are cut by no scissor.
    const SCREEN: PixelRect = PixelRect {
        x0: 0,
        y0: 0,
        x1: MAX_DIMENSION as i32,
        y1: MAX_DIMENSION as i32,
    };

    /// The origin vertex of `v` in positive orientation and its coverage inside `clip`, when it
    /// has an area and owns a row there.
    fn covered(v: [[i64; 2]; 3], clip: PixelRect) -> Option<([i64; 2], Coverage)> {
        let d = |i: usize| [v[i][0] - v[0][0], v[i][1] - v[0][1]];
        let area2 = d(1)[0] * d(2)[1] - d(2)[0] * d(1)[1];
        let v = if area2 < 0 { [v[0], v[2], v[1]] } else { v };
        Coverage::new(v, clip)
            .filter(|_| area2 != 0)
            .map(|c| (v[0], c))
    }

    /// Asserts that `plane` (based at `origin`) moved onto the pixel grid of `cov` gives the
    /// 128-bit value at each of `pixels`, and that the value stays below 2^62.
    fn assert_on_grid(
        plane: AttrPlane,
        origin: [i64; 2],
        cov: &Coverage,
        pixels: impl IntoIterator<Item = (i64, i64)>,
    ) {
        let corner = cov.corner();
        let on_grid = plane.on_grid(origin, corner);
        for (x, y) in pixels {
            let got = on_grid.at_pixel(x - corner[0], y - corner[1]);
            let wide = at_in_128_bits(&plane, origin, x, y);
            assert!(
                wide.unsigned_abs() < 1 << 62,
                "{origin:?} {plane:?} ({x}, {y})"
            );
            assert_eq!(got as i128, wide, "{origin:?} {plane:?} ({x}, {y})");
        }
    }

    #[test]
    fn small_planes_on_the_pixel_grid_equal_128_bit_products_at_the_extremes() {
        let cut = PixelRect {
            x0: 7,
            y0: 7,
            x1: 9,
            y1: 9,
        };
        let g = SMALL_NARROW_GRADIENT as i64 - 1;
        let gradients = [-g, -(1 << 36), -1, 0, 1, g];
        let bases = [-(1i64 << 60), 0, (1 << 60) - 1];
        // Vertices at the far ends of the 16 pixel columns and rows a small triangle's vertices
        // lie in (at either side of a pixel), with the origin vertex at either end.
        let (mut checked, mut at) = (0, 0);
        for (lo, hi) in [
            (0, 15 * SUBPIXEL_ONE),
            (SUBPIXEL_ONE - 1, 16 * SUBPIXEL_ONE - 1),
        ] {
            let shapes = [
                [[lo, lo], [hi, lo], [lo, hi]],
                [[hi, hi], [lo, hi], [hi, lo]],
                [[hi, lo], [lo, hi], [hi, hi]],
                [[lo, hi], [hi, hi], [lo, lo]],
                [[lo, lo], [hi, hi], [lo + 1, hi]],
            ];
            for shape in shapes {
                for clip in [SCREEN, cut] {
                    for dx in gradients {
                        for dy in gradients {
                            for base in bases {
                                let plane = AttrPlane { base, dx, dy };
                                at += 1;
                                checked += check_small_plane(shape, plane, clip) as u32;
                            }
                        }
                    }
                }
            }
        }
        assert!(checked * 4 > at, "{checked} of {at}");
    }

    proptest::proptest! {
        /// A small triangle anywhere in the guard band, with gradients up to the small bound: its
        /// planes on its pixel grid give the 128-bit values at every pixel of its rectangle.
        #[test]
        fn small_planes_on_the_pixel_grid_equal_128_bit_products(
            at in (-(1i64 << 23)..1 << 23, -(1i64 << 23)..1 << 23),
            v in proptest::collection::vec(0..16 * SUBPIXEL_ONE, 6),
            base in -(1i64 << 60)..1 << 60,
            dx in -(SMALL_NARROW_GRADIENT as i64) + 1..SMALL_NARROW_GRADIENT as i64,
            dy in -(SMALL_NARROW_GRADIENT as i64) + 1..SMALL_NARROW_GRADIENT as i64,
            clip in (0i32..8192, 0i32..8192, 1i32..8192, 1i32..8192),
        ) {
            // Some triangles on screen, inside the scissor; the others wherever `at` puts them.
            let near = (at.0 & 1) == 0;
            let origin = if near {
                [(clip.0 as i64 - 4) * SUBPIXEL_ONE, (clip.1 as i64 - 4) * SUBPIXEL_ONE]
            } else {
                [at.0, at.1]
            };
            let v = [0, 1, 2].map(|i| [origin[0] + v[2 * i], origin[1] + v[2 * i + 1]]);
            let clip = PixelRect {
                x0: clip.0,
                y0: clip.1,
                x1: (clip.0 + clip.2).min(MAX_DIMENSION as i32),
                y1: (clip.1 + clip.3).min(MAX_DIMENSION as i32),
            };
            check_small_plane(v, AttrPlane { base, dx, dy }, clip);
        }
    }

    /// Checks a triangle's plane with gradients at its reach bound (`reach_gradient`) on its
    /// pixel grid against the 128-bit evaluation at the corners of its rectangle, where an affine
    /// function is extreme (with overflow checks on, an overflow on the way panics). Returns false
    /// when `v` owns no row inside `clip` or is small (`SMALL_NARROW_GRADIENT` covers those).
    fn check_reach_plane(v: [[i64; 2]; 3], base: i64, signs: [i64; 2], clip: PixelRect) -> bool {
        let Some((origin, cov)) = covered(v, clip).filter(|(_, c)| !c.is_small()) else {
            return false;
        };
        let g = reach_gradient(&cov) as i64 - 1;
        let plane = AttrPlane {
            base,
            dx: signs[0] * g,
            dy: signs[1] * g,
        };
        assert!(plane.narrow_below(reach_gradient(&cov)));
        let r = cov.rect;
        let (xs, ys) = ([r.x0, r.x1 - 1], [r.y0, r.y1 - 1]);
        let corners = ys
            .into_iter()
            .flat_map(|y| xs.map(|x| (x as i64, y as i64)));
        assert_on_grid(plane, origin, &cov, corners);
        true
    }

    #[test]
    fn planes_at_their_reach_bound_equal_128_bit_products_at_the_extremes() {
        let cut = PixelRect {
            x0: 100,
            y0: 100,
            x1: 140,
            y1: 120,
        };
        let band = GUARD_BAND_PX * SUBPIXEL_ONE;
        let (far, edge) = (MAX_DIMENSION as i64 * SUBPIXEL_ONE + band - 1, -band);
        let (mut checked, mut at) = (0, 0);
        // From a 17-pixel triangle to one across the whole guard band, with the origin vertex at
        // either end, on screen and cut by a scissor.
        for size in [
            17 * SUBPIXEL_ONE,
            40 * SUBPIXEL_ONE,
            1 << 16,
            1 << 20,
            far - edge,
        ] {
            for (lo, hi) in [(0, size), (edge, edge + size), (far - size, far)] {
                let shapes = [
                    [[lo, lo], [hi, lo], [lo, hi]],
                    [[hi, hi], [lo, hi], [hi, lo]],
                    [[lo, lo], [hi, hi], [lo + 1, hi]],
                ];
                for shape in shapes {
                    for clip in [SCREEN, cut] {
                        for signs in [[1, 1], [1, -1], [-1, 1], [-1, -1]] {
                            for base in [-(1i64 << 61) + 1, 0, (1 << 61) - 1] {
                                at += 1;
                                checked += check_reach_plane(shape, base, signs, clip) as u32;
                            }
                        }
                    }
                }
            }
        }
        assert!(checked * 4 > at, "{checked} of {at}");
    }

    proptest::proptest! {
        /// A triangle of any size anywhere in the guard band, with gradients at its reach bound:
        /// its planes on its pixel grid give the 128-bit values at the corners of its rectangle.
        #[test]
        fn planes_at_their_reach_bound_equal_128_bit_products(
            v in proptest::collection::vec(-(1i64 << 23)..3 << 22, 6),
            base in -(1i64 << 61) + 1..1 << 61,
            signs in (proptest::bool::ANY, proptest::bool::ANY),
            clip in (0i32..8192, 0i32..8192, 1i32..8192, 1i32..8192),
        ) {
            let v = [0, 1, 2].map(|i| [v[2 * i], v[2 * i + 1]]);
            let sign = |b: bool| if b { 1 } else { -1 };
            let clip = PixelRect {
                x0: clip.0,
                y0: clip.1,
                x1: (clip.0 + clip.2).min(MAX_DIMENSION as i32),
                y1: (clip.1 + clip.3).min(MAX_DIMENSION as i32),
            };
            check_reach_plane(v, base, [sign(signs.0), sign(signs.1)], clip);
        }
    }

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
