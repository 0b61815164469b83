//! The f32 reference twin: the same stages as `fixed`, in floating point, with every attribute
//! evaluated from its plane at each pixel (no accumulated steps). Coverage uses the same snapped
//! sub-pixel grid and the same exact walker, so both paths share the fill rule.

use glam::Vec4;

use crate::clip::{ClipVertex, Plane};
use crate::edge::Coverage;
use crate::fixed_point::{GUARD_BAND_PX, SUBPIXEL_ONE, TEXCOORD_LIMIT};
use crate::matrix::Transform;
use crate::pipeline::fixed::Span;
use crate::pipeline::{Attributes, Pipeline, Setup, TexMode, Viewport};
use crate::pixel::{DepthStorage, PixelFormat, fog_blend, modulate};
use crate::sampler::{Bilinear, Filtering, Nearest, ViewOf};
use crate::state::{Compare, Fog};
use crate::texture::{Filter, MipLevel, Sampler, Texels};
use crate::vertex::Vertex;

/// Smallest `w` that is projected.
const W_MIN: f32 = 1e-30;

/// Guard band in the float clip test.
pub(crate) struct FloatSpace {
    width: f32,
    height: f32,
}

impl FloatSpace {
    pub fn new(vp: &Viewport) -> Self {
        Self {
            width: vp.width as f32,
            height: vp.height as f32,
        }
    }
}

/// A vertex in clip space.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct FloatClip {
    clip: Vec4,
    uv: [f32; 2],
    color: [f32; 3],
}

impl FloatClip {
    pub fn from_vertex(v: &Vertex, m: &Transform) -> Self {
        let limit = (TEXCOORD_LIMIT >> 16) as f32;
        Self {
            clip: m.transform_float(v.position),
            uv: v.uv.map(|c| c.to_num::<f32>().clamp(-limit, limit)),
            color: v.color.map(f32::from),
        }
    }

    fn distance(&self, plane: Plane, s: &FloatSpace) -> f32 {
        let [x, y, z, w] = self.clip.to_array();
        let g = 2.0 * GUARD_BAND_PX as f32 * w;
        match plane {
            Plane::WMin => w - W_MIN,
            Plane::Near => z,
            Plane::Far => w - z,
            Plane::Left => g + s.width * x,
            Plane::Right => g - s.width * x,
            Plane::Bottom => g + s.height * y,
            Plane::Top => g - s.height * y,
        }
    }
}

impl ClipVertex for FloatClip {
    type Space = FloatSpace;

    #[inline]
    fn inside(&self, plane: Plane, s: &FloatSpace) -> bool {
        // NaN (from non-finite input) counts as outside, so it is clipped away, never drawn.
        self.distance(plane, s) >= 0.0
    }

    fn intersect(a: &Self, b: &Self, plane: Plane, s: &FloatSpace) -> Self {
        let (da, db) = (a.distance(plane, s), b.distance(plane, s));
        let t = (da / (da - db)).clamp(0.0, 1.0);
        let lerp = |p: f32, q: f32| p + (q - p) * t;
        let mut v = Self {
            clip: a.clip + (b.clip - a.clip) * t,
            uv: [0, 1].map(|k| lerp(a.uv[k], b.uv[k])),
            color: [0, 1, 2].map(|k| lerp(a.color[k], b.color[k])),
        };
        match plane {
            Plane::WMin => v.clip.w = v.clip.w.max(W_MIN),
            Plane::Near => v.clip.z = 0.0,
            Plane::Far => v.clip.z = v.clip.w,
            _ => {}
        }
        v
    }
}

/// The f32 reference pipeline's stages.
pub(crate) struct FloatPipeline;

/// What the float vertex stage of one draw needs.
pub(crate) struct FloatConsts {
    transform: Transform,
    vp: Viewport,
    space: FloatSpace,
    fog: Option<Fog>,
}

impl Pipeline for FloatPipeline {
    type Clip = FloatClip;
    type Screen = FloatScreen;
    type Triangle = FloatTriangle;
    /// The reference twin keeps its planes in the triangle.
    type Plane = FloatPlane;
    type Consts = FloatConsts;

    fn consts(transform: &Transform, vp: &Viewport, fog: Option<Fog>) -> FloatConsts {
        FloatConsts {
            transform: *transform,
            vp: *vp,
            space: FloatSpace::new(vp),
            fog,
        }
    }

    fn space(c: &FloatConsts) -> &FloatSpace {
        &c.space
    }

    fn clip(c: &FloatConsts, v: &Vertex) -> FloatClip {
        FloatClip::from_vertex(v, &c.transform)
    }

    fn project(c: &FloatConsts, clip: &FloatClip) -> FloatScreen {
        FloatScreen::project(clip, &c.vp, c.fog)
    }

    fn xy(s: &FloatScreen) -> [i64; 2] {
        s.xy
    }

    fn triangle(
        v: [&FloatScreen; 3],
        area2: i64,
        coverage: Coverage,
        attrs: &Attributes,
        draw: u32,
        _planes: &mut Vec<FloatPlane>,
    ) -> FloatTriangle {
        FloatTriangle::new(v, area2, coverage, attrs, draw)
    }
}

/// A projected vertex.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct FloatScreen {
    /// Snapped sub-pixel position, shared with the coverage walker.
    pub xy: [i64; 2],
    depth: f32,
    inv_w: f32,
    uv: [f32; 2],
    color: [f32; 3],
    fog: f32,
}

impl FloatScreen {
    pub fn project(v: &FloatClip, vp: &Viewport, fog: Option<Fog>) -> Self {
        let w = v.clip.w.max(W_MIN);
        let inv_w = 1.0 / w;
        let sx = (v.clip.x * inv_w * 0.5 + 0.5) * vp.width as f32;
        let sy = (0.5 - v.clip.y * inv_w * 0.5) * vp.height as f32;
        let snap = |c: f32| (c * SUBPIXEL_ONE as f32).round() as i64;
        let fog = match fog {
            Some(f) if f.end > f.start => {
                ((f.end as f32 - w) / (f.end - f.start) as f32).clamp(0.0, 1.0)
            }
            Some(f) => {
                if (w as f64) < f.end {
                    1.0
                } else {
                    0.0
                }
            }
            None => 1.0,
        };
        Self {
            xy: vp.clamp_to_guard_band([snap(sx), snap(sy)]),
            depth: (v.clip.z * inv_w).clamp(0.0, 1.0),
            inv_w,
            uv: v.uv,
            color: v.color,
            fog,
        }
    }
}

/// An attribute plane in pixels: `value(x, y) = base + dx * (x - x0) + dy * (y - y0)`.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct FloatPlane {
    base: f32,
    dx: f32,
    dy: f32,
}

impl FloatPlane {
    #[inline]
    fn at(&self, ox: f32, oy: f32) -> f32 {
        self.base + self.dx * ox + self.dy * oy
    }
}

/// A triangle ready for its rows.
#[derive(Clone, Copy, Debug)]
pub(crate) struct FloatTriangle {
    pub coverage: Coverage,
    origin: [f32; 2],
    depth: FloatPlane,
    color: [FloatPlane; 3],
    fog: FloatPlane,
    tex: [FloatPlane; 3],
    /// This triangle's texture interpolation (see `Attributes::tex_mode_for`).
    tex_mode: TexMode,
    level: u8,
    /// The draw it belongs to.
    draw: u32,
}

impl FloatTriangle {
    pub fn new(
        v: [&FloatScreen; 3],
        area2: i64,
        coverage: Coverage,
        a: &Attributes,
        draw: u32,
    ) -> Self {
        let px = |s: &FloatScreen| {
            [
                s.xy[0] as f32 / SUBPIXEL_ONE as f32,
                s.xy[1] as f32 / SUBPIXEL_ONE as f32,
            ]
        };
        let p = v.map(px);
        let d1 = [p[1][0] - p[0][0], p[1][1] - p[0][1]];
        let d2 = [p[2][0] - p[0][0], p[2][1] - p[0][1]];
        let area = area2 as f32 / (SUBPIXEL_ONE * SUBPIXEL_ONE) as f32;
        let plane = |q: [f32; 3]| {
            let (a1, a2) = (q[1] - q[0], q[2] - q[0]);
            FloatPlane {
                base: q[0],
                dx: (a1 * d2[1] - a2 * d1[1]) / area,
                dy: (a2 * d1[0] - a1 * d2[0]) / area,
            }
        };
        let pick = |f: fn(&FloatScreen) -> f32| plane([f(v[0]), f(v[1]), f(v[2])]);
        let empty = FloatPlane::default();
        let tex_mode = a.tex_mode_for([v[0].xy, v[1].xy, v[2].xy], coverage.is_small());
        let (tex, level) = match tex_mode {
            TexMode::Off => ([empty; 3], 0),
            TexMode::Affine => (
                [pick(|s| s.uv[0]), pick(|s| s.uv[1]), empty],
                a.level(texel_area_bits(&v), area2),
            ),
            TexMode::Perspective(_) => (
                [
                    pick(|s| s.uv[0] * s.inv_w),
                    pick(|s| s.uv[1] * s.inv_w),
                    pick(|s| s.inv_w),
                ],
                a.level(texel_area_bits(&v), area2),
            ),
        };
        Self {
            coverage,
            origin: p[0],
            depth: pick(|s| s.depth),
            color: [
                pick(|s| s.color[0]),
                pick(|s| s.color[1]),
                pick(|s| s.color[2]),
            ],
            fog: pick(|s| s.fog),
            tex,
            tex_mode,
            level,
            draw,
        }
    }
}

/// Bit length of the doubled texture-space area in 16.16 repeats squared, as the fixed path
/// measures it.
fn texel_area_bits(v: &[&FloatScreen; 3]) -> u32 {
    let d = |i: usize, k: usize| (v[i].uv[k] - v[0].uv[k]) as f64;
    let area = ((d(1, 0) * d(2, 1) - d(2, 0) * d(1, 1)).abs() * 4294967296.0) as i128;
    128 - area.leading_zeros()
}

impl Setup for FloatTriangle {
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

/// Samples any level with a run-time filter: the reference path is not specialised.
pub(crate) fn sample(level: &MipLevel, sampler: Sampler, u: i64, v: i64) -> [u8; 3] {
    fn with<T: ViewOf>(level: &MipLevel, sampler: Sampler, u: i64, v: i64) -> [u8; 3] {
        let view = T::view(level, sampler.wrap).expect("texel type matches the level");
        match sampler.filter {
            Filter::Nearest => Nearest::<T>::sample(&view, u, v),
            Filter::Bilinear => Bilinear::<T>::sample(&view, u, v),
        }
    }
    match level.texels() {
        Texels::Rgb565(_) => with::<u16>(level, sampler, u, v),
        Texels::Rgba8888(_) => with::<[u8; 4]>(level, sampler, u, v),
    }
}

/// Texture coordinate in 16.16 from a float in repeats.
#[inline]
fn to_q16(u: f32) -> i64 {
    (u * 65536.0) as i64
}

/// Shades a span of a row (see `fixed::run_fragments`: values depend on the run `x0..x1`, not on
/// the part drawn). Returns the fragments that passed the depth test.
pub(crate) fn shade_row<P: PixelFormat, D: DepthStorage>(
    tri: &FloatTriangle,
    span: Span<'_, P, D>,
    texture: Option<(&MipLevel, Sampler)>,
    a: &Attributes,
) -> u64 {
    let Span {
        y,
        x0,
        x1,
        xs,
        color,
        depth,
    } = span;
    let oy = y as f32 + 0.5 - tri.origin[1];
    let ox = |x: i64| x as f32 + 0.5 - tri.origin[0];
    let exact_uv = |x: i64| {
        let o = ox(x);
        let q = tri.tex[2].at(o, oy);
        (tri.tex[0].at(o, oy) / q, tri.tex[1].at(o, oy) / q)
    };
    let mut passed = 0;
    for (i, x) in (xs..xs + color.len() as i64).enumerate() {
        let o = ox(x);
        if D::ENABLED {
            let d =
                D::quantise((tri.depth.at(o, oy).clamp(0.0, 1.0) as f64 * u32::MAX as f64) as u32);
            let pass = match a.compare {
                Compare::Always => true,
                Compare::Less => d < depth[i],
                Compare::LessEqual => d <= depth[i],
            };
            if !pass {
                continue;
            }
            if a.depth_write {
                depth[i] = d;
            }
        }
        let mut rgb = if a.shade {
            tri.color
                .map(|c| c.at(o, oy).round().clamp(0.0, 255.0) as u8)
        } else {
            a.flat
        };
        if let Some((level, sampler)) = texture {
            let (u, v) = match tri.tex_mode {
                TexMode::Affine => (tri.tex[0].at(o, oy), tri.tex[1].at(o, oy)),
                TexMode::Perspective(1) | TexMode::Off => exact_uv(x),
                TexMode::Perspective(n) => {
                    // Exact at multiples of n from the span start, linear in between.
                    let n = n as i64;
                    let start = x0 + (x - x0) / n * n;
                    let end = (start + n).min(x1);
                    let (u0, v0) = exact_uv(start);
                    let (u1, v1) = exact_uv(end);
                    let t = (x - start) as f32 / (end - start) as f32;
                    (u0 + (u1 - u0) * t, v0 + (v1 - v0) * t)
                }
            };
            rgb = modulate(sample(level, sampler, to_q16(u), to_q16(v)), rgb);
        }
        if a.fog {
            rgb = fog_blend(
                rgb,
                a.fog_color,
                (tri.fog.at(o, oy).clamp(0.0, 1.0) * 256.0) as u32,
            );
        }
        color[i] = P::pack(rgb);
        passed += 1;
    }
    passed
}
