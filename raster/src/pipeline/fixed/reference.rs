//! The scalar row loop the row step and the colour stage replaced, pixel by pixel: the reference
//! the tests hold them to, byte for byte.

use std::cell::Cell;

use super::division::{advance, div_small};
use super::*;
use crate::fixed_point::{ATTR_FRAC_BITS, SUBPIXEL_HALF, SUBPIXEL_ONE};
use crate::pipeline::TexMode;
use crate::pixel::{fog_blend, modulate};
use crate::sampler::{Filtering, LevelView};
use crate::state::Compare;

thread_local! {
    static ON: Cell<bool> = const { Cell::new(false) };
}

/// True while `with` runs on this thread: the fixed pipeline then shades with `shade_row`.
pub fn enabled() -> bool {
    ON.with(Cell::get)
}

/// Runs `f` with the reference row loop on this thread (draws on one thread only).
pub fn with<R>(f: impl FnOnce() -> R) -> R {
    ON.with(|on| on.set(true));
    let r = f();
    ON.with(|on| on.set(false));
    r
}

/// Shades a span of a row. Every value at a pixel follows from the triangle and the run's start
/// `x0` alone (perspective chunks are counted from `x0`), never from `xs`: a run cut by a tile
/// edge gives the bytes it gives whole. Returns the fragments that passed the depth test.
#[inline]
pub(crate) fn shade_row<
    P: PixelFormat,
    D: DepthStorage,
    T: Filtering,
    const SHADE: bool,
    const FOG: bool,
>(
    tri: &FixedTriangle,
    planes: &[AttrPlane],
    span: Span<'_, P, D>,
    view: Option<&LevelView<'_, T::Texel>>,
    a: &Attributes,
) -> u64 {
    let planes = &planes[tri.planes as usize..];
    match (tri.narrow, SHADE && tri.grey) {
        (false, false) => {
            shade_span::<P, D, T, SHADE, false, FOG, false>(tri, planes, span, view, a)
        }
        (false, true) => shade_span::<P, D, T, true, true, FOG, false>(tri, planes, span, view, a),
        (true, true) => shade_span::<P, D, T, true, true, FOG, true>(tri, planes, span, view, a),
        (true, false) => shade_span::<P, D, T, SHADE, false, FOG, true>(tri, planes, span, view, a),
    }
}

/// `shade_row` for one variant of the triangle: `GREY` steps one colour channel for all three,
/// `NARROW` starts the row from `AttrPlane::at_pixel` (see `FixedTriangle::narrow`).
#[inline(always)]
fn shade_span<
    P: PixelFormat,
    D: DepthStorage,
    T: Filtering,
    const SHADE: bool,
    const GREY: bool,
    const FOG: bool,
    const NARROW: bool,
>(
    tri: &FixedTriangle,
    planes: &[AttrPlane],
    span: Span<'_, P, D>,
    view: Option<&LevelView<'_, T::Texel>>,
    a: &Attributes,
) -> u64 {
    // The triangle's planes in their order: depth, colour, fog, texture.
    let color_at = D::ENABLED as usize;
    let fog_at = color_at
        + if !SHADE {
            0
        } else if GREY {
            1
        } else {
            3
        };
    let tex_at = fog_at + FOG as usize;
    let Span {
        y,
        x0,
        x1,
        xs,
        color,
        depth,
    } = span;
    let xe = xs + color.len() as i64;
    debug_assert!(x0 <= xs && xs < xe && xe <= x1);
    debug_assert!(!D::ENABLED || depth.len() == color.len());
    let channels = if GREY { 1 } else { 3 };
    let perspective = matches!(tri.tex_mode, TexMode::Perspective(_));
    let origin = tri.coverage.origin();
    let corner = tri.coverage.corner();
    let ox = x0 * SUBPIXEL_ONE + SUBPIXEL_HALF - origin[0];
    let oy = y * SUBPIXEL_ONE + SUBPIXEL_HALF - origin[1];
    // A plane's value at pixel `x` of the run, as stepping from `x0` reaches it.
    let at = |p: &AttrPlane, x: i64| {
        if NARROW {
            p.at_pixel(x - corner[0], y - corner[1])
        } else {
            p.at(ox, oy).wrapping_add(p.dx.wrapping_mul(x - x0))
        }
    };
    let (mut z, dz) = if D::ENABLED {
        (at(&planes[0], xs), planes[0].dx)
    } else {
        (0, 0)
    };
    let mut c = [0i64; 3];
    let mut dc = [0i64; 3];
    if SHADE {
        for k in 0..channels {
            c[k] = at(&planes[color_at + k], xs);
            dc[k] = planes[color_at + k].dx;
        }
    }
    let (mut f, df) = if FOG {
        (at(&planes[fog_at], xs), planes[fog_at].dx)
    } else {
        (0, 0)
    };
    // Texture state: accumulators for s, t, q (or u, v) at the chunk start `cs`, the chunk
    // length, and (u, v) in 16.32 at `cs`.
    let mut acc = [0i64; 3];
    let mut dacc = [0i64; 3];
    let chunk = match tri.tex_mode {
        TexMode::Perspective(n) => n as i64,
        _ => i64::MAX,
    };
    let mut cs = xs;
    let (mut u, mut v) = (0i64, 0i64);
    if T::ENABLED {
        if perspective {
            let k = (xs - x0) / chunk;
            cs = x0 + k * chunk;
            for j in 0..3 {
                let p = &planes[tex_at + j];
                dacc[j] = p.dx;
                acc[j] = advance(at(p, x0), dacc[j].saturating_mul(chunk), k);
            }
            (u, v) = divide(acc[0], acc[1], acc[2]);
        } else {
            for j in 0..2 {
                acc[j] = at(&planes[tex_at + j], xs);
                dacc[j] = planes[tex_at + j].dx;
            }
            (u, v) = (acc[0], acc[1]);
        }
    }
    let mut passed = 0;
    let mut x = xs;
    while x < xe {
        let ce = if perspective {
            (cs + chunk).min(x1)
        } else {
            x1
        };
        let (mut du, mut dv) = (0i64, 0i64);
        let mut chunk_end = (0i64, 0i64);
        if T::ENABLED {
            if perspective {
                let n = ce - cs;
                for k in 0..3 {
                    acc[k] = acc[k].saturating_add(dacc[k].saturating_mul(n));
                }
                chunk_end = divide(acc[0], acc[1], acc[2]);
                du = div_small(chunk_end.0 - u, n);
                dv = div_small(chunk_end.1 - v, n);
            } else {
                (du, dv) = (dacc[0], dacc[1]);
            }
        }
        let (mut cu, mut cv) = (
            u.wrapping_add(du.wrapping_mul(x - cs)),
            v.wrapping_add(dv.wrapping_mul(x - cs)),
        );
        let end = ce.min(xe);
        for i in (x - xs) as usize..(end - xs) as usize {
            let visible = if D::ENABLED {
                let d = D::quantise((z >> ATTR_FRAC_BITS).clamp(0, u32::MAX as i64) as u32);
                let stored = depth[i];
                let pass = match a.compare {
                    Compare::Always => true,
                    Compare::Less => d < stored,
                    Compare::LessEqual => d <= stored,
                };
                if pass && a.depth_write {
                    depth[i] = d;
                }
                pass
            } else {
                true
            };
            if visible {
                let mut rgb = if GREY {
                    [(c[0] >> ATTR_FRAC_BITS).clamp(0, 255) as u8; 3]
                } else if SHADE {
                    c.map(|ch| (ch >> ATTR_FRAC_BITS).clamp(0, 255) as u8)
                } else {
                    a.flat
                };
                if T::ENABLED {
                    let view = view.expect("texture view bound with texturing on");
                    rgb = modulate(T::sample(view, cu >> 16, cv >> 16), rgb);
                }
                if FOG {
                    rgb = fog_blend(rgb, a.fog_color, (f >> ATTR_FRAC_BITS).clamp(0, 256) as u32);
                }
                color[i] = P::pack(rgb);
                passed += 1;
            }
            if D::ENABLED {
                z = z.wrapping_add(dz);
            }
            if SHADE {
                for k in 0..channels {
                    c[k] = c[k].wrapping_add(dc[k]);
                }
            }
            if FOG {
                f = f.wrapping_add(df);
            }
            cu = cu.wrapping_add(du);
            cv = cv.wrapping_add(dv);
        }
        if perspective {
            (u, v) = chunk_end;
        }
        cs = ce;
        x = end;
    }
    passed
}
