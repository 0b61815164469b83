//! The row step of the fixed pipeline: a run's depth test and write, pixel by pixel in scalar
//! integers, and the values its colour needs (texture coordinates, shading, fog), stored in the
//! fragment buffer for the colour stage (`crate::fragments`).

use super::division::{advance, div_small, divide};
use super::{AttrPlane, FixedTriangle};
use crate::fixed_point::{ATTR_FRAC_BITS, SUBPIXEL_HALF, SUBPIXEL_ONE, TEXCOORD_LIMIT};
use crate::fragments::{CAPACITY, Fragments};
use crate::pipeline::{Attributes, TexMode};
use crate::pixel::DepthStorage;
use crate::sampler::{Filtering, UvRange, clamp_coord};
use crate::state::Compare;
use std::ops::Range;

/// Where a run of fragments lies: row `y`, owned pixels `x0..x1`, of which the row step takes
/// `xs..xe` (a tile's part of the run, in pieces that fit the fragment buffer), whose first
/// pixel is index `at` of the tile's buffers.
#[derive(Clone, Copy, Debug)]
pub(crate) struct RunPiece {
    pub y: i64,
    pub x0: i64,
    pub x1: i64,
    pub xs: i64,
    pub xe: i64,
    pub at: usize,
}

/// A draw's depth test as one comparison: a fragment at depth `d` passes when
/// `d < stored + bias` (0 for less, 1 for less-or-equal, `2^32` for always), and is stored when
/// it passes and the draw writes depth.
#[derive(Clone, Copy, Debug)]
pub(crate) struct DepthTest {
    bias: u64,
    write: bool,
}

impl DepthTest {
    pub fn new(a: &Attributes) -> Self {
        Self {
            bias: match a.compare {
                Compare::Less => 0,
                Compare::LessEqual => 1,
                Compare::Always => 1 << 32,
            },
            write: a.depth_write,
        }
    }

    /// Tests depth `d` against `*stored`, writes it if it passes and the draw writes depth;
    /// returns whether it passed.
    #[inline(always)]
    pub fn apply<D: DepthStorage>(self, d: D::Value, stored: &mut D::Value) -> bool {
        let s = *stored;
        let pass = D::widen(d) < D::widen(s) + D::bias(self.bias);
        *stored = if pass && self.write { d } else { s };
        pass
    }
}

/// Where a triangle's planes of each kind start among its planes, which come in this order:
/// depth (if tested), colour (one plane when `GREY`, none without shading), fog, texture.
#[inline(always)]
pub(crate) fn plane_offsets<
    D: DepthStorage,
    const SHADE: bool,
    const GREY: bool,
    const FOG: bool,
>() -> (usize, usize, usize) {
    let color_at = D::ENABLED as usize;
    let colors = match (SHADE, GREY) {
        (false, _) => 0,
        (true, true) => 1,
        (true, false) => 3,
    };
    let fog_at = color_at + colors;
    (color_at, fog_at, fog_at + FOG as usize)
}

/// Whether rows without clamps step colour, fog and texture coordinates in 32-bit words: on
/// 32-bit cores, where an i64 is two registers and two adds. A 64-bit core steps them as
/// cheaply in i64, in lanes where it has them, and the words' offsets would cost it more than
/// they save (docs/optimisation-notes.md).
pub(crate) const WORDS: bool = cfg!(target_pointer_width = "32");

/// The stepped values of a row's pixel: depth, colour (one channel when `GREY`), fog.
struct Stepped<const GREY: bool> {
    z: i64,
    dz: i64,
    c: [i64; 3],
    dc: [i64; 3],
    f: i64,
    df: i64,
}

impl<const GREY: bool> Stepped<GREY> {
    /// One pixel to the right (the unused values step by 0).
    #[inline(always)]
    fn step(&mut self) {
        self.z = self.z.wrapping_add(self.dz);
        for k in 0..if GREY { 1 } else { 3 } {
            self.c[k] = self.c[k].wrapping_add(self.dc[k]);
        }
        self.f = self.f.wrapping_add(self.df);
    }
}

/// The row step: depth test and write of the pixels of `piece` (`depth` holds them, empty
/// without a depth test), and the values their colour needs held in `frags` for each pixel that
/// passes (its room checked by the caller). Every value at a pixel follows from the triangle and
/// the run's start `x0` alone (perspective chunks are counted from `x0`), never from `xs`: a run
/// cut by a tile edge or the buffer gives the bytes it gives whole.
///
/// `GREY` steps one colour channel for all three, `NARROW` starts the row from
/// `AttrPlane::at_pixel` (see `FixedTriangle::narrow`).
///
/// A piece whose stepped values lie inside their ranges at its first and last pixel takes the
/// pixels without clamps: each steps linearly, so every pixel between lies between the two.
/// Most pieces do; the clamps are for the rounding at a triangle's edges.
#[inline(always)]
pub(crate) fn run_fragments<
    D: DepthStorage,
    T: Filtering,
    const SHADE: bool,
    const GREY: bool,
    const FOG: bool,
    const NARROW: bool,
>(
    tri: &FixedTriangle,
    planes: &[AttrPlane],
    piece: RunPiece,
    depth: &mut [D::Value],
    frags: &mut Fragments,
    test: DepthTest,
) {
    let planes = &planes[tri.planes as usize..];
    let (color_at, fog_at, tex_at) = plane_offsets::<D, SHADE, GREY, FOG>();
    let RunPiece { y, x0, xs, xe, .. } = piece;
    let n = (xe - xs) as usize;
    debug_assert!(x0 <= xs && xs < xe && xe <= piece.x1 && n <= frags.room());
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
    let mut px = Stepped::<GREY> {
        z: 0,
        dz: 0,
        c: [0; 3],
        dc: [0; 3],
        f: 0,
        df: 0,
    };
    if D::ENABLED {
        (px.z, px.dz) = (at(&planes[0], xs), planes[0].dx);
    }
    if SHADE {
        for k in 0..if GREY { 1 } else { 3 } {
            px.c[k] = at(&planes[color_at + k], xs);
            px.dc[k] = planes[color_at + k].dx;
        }
    }
    if FOG {
        (px.f, px.df) = (at(&planes[fog_at], xs), planes[fog_at].dx);
    }
    let tex = match tri.tex_mode {
        TexMode::Perspective(chunk) if T::ENABLED => {
            // Accumulators for s, t, q at pixel `xs` (`Exact`) or at the chunk start.
            let chunk = chunk as i64;
            // In 32 bits (both are small and not negative): the i64 division is a library call
            // on a 32-bit core. A run that starts in the tile (most do) starts at its first chunk.
            let k0 = match xs - x0 {
                0 => 0,
                d => (d as u32 / chunk as u32) as i64,
            };
            let mut acc = [0i64; 3];
            let mut dacc = [0i64; 3];
            for j in 0..3 {
                let p = &planes[tex_at + j];
                dacc[j] = p.dx;
                acc[j] = match k0 {
                    0 => at(p, x0),
                    _ => advance(at(p, x0), dacc[j].saturating_mul(chunk), k0),
                };
            }
            RunTex::Perspective {
                acc,
                dacc,
                chunk,
                start: x0 + k0 * chunk,
            }
        }
        TexMode::Affine if T::ENABLED => {
            let (pu, pv) = (&planes[tex_at], &planes[tex_at + 1]);
            RunTex::Affine {
                uv: [at(pu, xs), at(pv, xs)],
                duv: [pu.dx, pv.dx],
            }
        }
        _ => RunTex::Off,
    };
    // The last pixel's value, exact in i64: a piece holds fewer than 2^6 pixels (`CAPACITY`)
    // and the ranges lie within 2^49 of 0, so a step below 2^56 keeps the product below 2^62
    // and the sum below 2^63 (checked products are library calls on a 32-bit core).
    let last = n as i64 - 1;
    debug_assert!(n <= CAPACITY);
    let linear_in = |v: i64, d: i64, range: Range<i64>| {
        range.contains(&v) && d.unsigned_abs() < 1 << 56 && range.contains(&(v + d * last))
    };
    let channels = if GREY { 1 } else { 3 };
    let in_range = (!D::ENABLED || linear_in(px.z, px.dz, 0..1 << 48))
        && (!SHADE || (0..channels).all(|k| linear_in(px.c[k], px.dc[k], CHANNEL)))
        && (!FOG || linear_in(px.f, px.df, SHARE))
        && match tex {
            RunTex::Affine { uv, duv } => (0..2).all(|k| linear_in(uv[k], duv[k], COORD)),
            _ => true,
        };
    let run = Run {
        piece,
        tex,
        depth: &mut depth[..if D::ENABLED { n } else { 0 }],
        test,
    };
    // Exact perspective divides at every pixel, which a pass over the fragments that passed
    // would not make cheaper.
    let words = WORDS && !matches!(tex, RunTex::Perspective { chunk: 1, .. });
    match in_range {
        true if words => pixels_in_words::<D, T, GREY, SHADE, FOG>(run, px, frags),
        true => pixels::<D, T, GREY, SHADE, FOG, false>(run, px, frags),
        false => pixels::<D, T, GREY, SHADE, FOG, true>(run, px, frags),
    }
}

/// The values whose integer parts (`>> ATTR_FRAC_BITS`) a row step keeps without a clamp: a
/// colour channel's `0..=255`, a fog share's `0..=256`, a texture coordinate's
/// `-TEXCOORD_LIMIT..=TEXCOORD_LIMIT` (16.16, so the same shift).
const CHANNEL: Range<i64> = 0..256 << ATTR_FRAC_BITS;
const SHARE: Range<i64> = 0..257 << ATTR_FRAC_BITS;
const COORD: Range<i64> = -TEXCOORD_LIMIT << 16..(TEXCOORD_LIMIT + 1) << 16;

/// A run's texture coordinates at its piece's first pixel: affine `u, v` (16.16) and their
/// steps, or the perspective accumulators `s, t, q` at the first chunk's start `start`.
#[derive(Clone, Copy)]
enum RunTex {
    Off,
    Affine {
        uv: [i64; 2],
        duv: [i64; 2],
    },
    Perspective {
        acc: [i64; 3],
        dacc: [i64; 3],
        chunk: i64,
        start: i64,
    },
}

/// What `pixels` draws: a piece, its texture coordinates, its depth values and test.
struct Run<'d, D: DepthStorage> {
    piece: RunPiece,
    tex: RunTex,
    depth: &'d mut [D::Value],
    test: DepthTest,
}

/// The pixels of `run_fragments`' piece from the stepped values `px` at its first pixel; with
/// `CLAMP` false every value is known to lie in its range, so none is clamped.
#[inline(always)]
fn pixels<
    D: DepthStorage,
    T: Filtering,
    const GREY: bool,
    const SHADE: bool,
    const FOG: bool,
    const CLAMP: bool,
>(
    run: Run<'_, D>,
    mut px: Stepped<GREY>,
    frags: &mut Fragments,
) {
    let Run {
        piece,
        tex,
        depth,
        test,
    } = run;
    let RunPiece {
        xs, xe, at: first, ..
    } = piece;
    let n = (xe - xs) as usize;
    // Pixel `k` of the piece, with texture coordinates `uv`: held when it passes the test.
    let mut kept = frags.held();
    let mut emit = |k: usize, uv: (i32, i32), px: &mut Stepped<GREY>| {
        let i = Fragments::slot(kept);
        frags.at[i] = (first + k) as u32;
        if T::ENABLED {
            (frags.u[i], frags.v[i]) = uv;
        }
        let visible = if D::ENABLED {
            let d = if CLAMP {
                D::from_z(px.z)
            } else {
                D::from_z_in_range(px.z)
            };
            test.apply::<D>(d, &mut depth[k])
        } else {
            true
        };
        let whole = |v: i64| v >> ATTR_FRAC_BITS;
        if SHADE {
            let channel = |c: i64| if CLAMP { whole(c).clamp(0, 255) } else { whole(c) } as u16;
            frags.c[0][i] = channel(px.c[0]);
            if !GREY {
                frags.c[1][i] = channel(px.c[1]);
                frags.c[2][i] = channel(px.c[2]);
            }
        }
        if FOG {
            frags.f[i] = if CLAMP {
                whole(px.f).clamp(0, 256)
            } else {
                whole(px.f)
            } as u16;
        }
        px.step();
        kept += visible as usize;
    };
    let coord = |c: i64| {
        if CLAMP {
            clamp_coord(c >> 16) as i32
        } else {
            (c >> 16) as i32
        }
    };
    match tex {
        RunTex::Perspective {
            mut acc,
            dacc,
            chunk,
            start,
        } => {
            if chunk == 1 {
                // Exact: one division per pixel, as stepping chunks of one pixel gives.
                for k in 0..n {
                    let (u, v) = divide(acc[0], acc[1], acc[2]);
                    emit(k, ((u >> 16) as i32, (v >> 16) as i32), &mut px);
                    for j in 0..3 {
                        acc[j] = acc[j].saturating_add(dacc[j]);
                    }
                }
            } else {
                for chunk in Chunks::new(acc, dacc, chunk, start, &piece) {
                    let Chunk {
                        ks,
                        c: [mut cu, mut cv],
                        d: [du, dv],
                        ..
                    } = chunk;
                    // `divide` keeps the chunk's ends in range, but the rounded-down steps
                    // between them can stray past the low end: the chunk's part of the piece
                    // goes without clamps where its first and last coordinates lie inside.
                    if inside([cu, cv], [du, dv], ks.len()) {
                        for k in ks {
                            emit(k, ((cu >> 16) as i32, (cv >> 16) as i32), &mut px);
                            cu = cu.wrapping_add(du);
                            cv = cv.wrapping_add(dv);
                        }
                    } else {
                        for k in ks {
                            let clamped = |c: i64| clamp_coord(c >> 16) as i32;
                            emit(k, (clamped(cu), clamped(cv)), &mut px);
                            cu = cu.wrapping_add(du);
                            cv = cv.wrapping_add(dv);
                        }
                    }
                }
            }
        }
        RunTex::Affine {
            uv: [mut cu, mut cv],
            duv: [du, dv],
        } => {
            for k in 0..n {
                emit(k, (coord(cu), coord(cv)), &mut px);
                cu = cu.wrapping_add(du);
                cv = cv.wrapping_add(dv);
            }
        }
        RunTex::Off => {
            for k in 0..n {
                emit(k, (0, 0), &mut px);
            }
        }
    }
    frags.keep(kept);
}

/// A run's perspective chunks of more than one pixel over a piece, one `Chunk` at a time: `u, v`
/// exact at each chunk's ends (from the accumulators `s, t, q` there) and linear between.
struct Chunks {
    /// The accumulators at the current chunk's start `cs`, their steps, and a whole chunk's.
    acc: [i64; 3],
    dacc: [i64; 3],
    chunk_steps: [i64; 3],
    chunk: i64,
    cs: i64,
    /// `u, v` (16.32) at `cs`.
    uv: (i64, i64),
    /// The next pixel, the piece's first and end, and the run's end.
    x: i64,
    xs: i64,
    xe: i64,
    x1: i64,
}

/// `d * m` saturated, for a chunk of `m < 256` pixels (`TexMode::Perspective` holds it in a
/// byte): the plain product where `d` lies within 2^55 of 0 keeps it in i64, as it mostly
/// does; the saturating product is a dozen instructions on a 32-bit core. There the test is
/// whether `d`'s bits from 55 up are all its sign (`-2^55 <= d < 2^55`), in its high word alone.
#[inline(always)]
fn saturating_times(d: i64, m: i64) -> i64 {
    debug_assert!((0..256).contains(&m));
    #[cfg(target_pointer_width = "64")]
    let plain = d.unsigned_abs() < 1 << 55;
    #[cfg(not(target_pointer_width = "64"))]
    let plain = d >> 55 == d >> 63;
    if plain { d * m } else { d.saturating_mul(m) }
}

/// One chunk's pixels of a piece (`Chunks`).
struct Chunk {
    /// The pixels, counted from the piece's first.
    ks: Range<usize>,
    /// `u, v` (16.32) at the first of them, and their step.
    c: [i64; 2],
    d: [i64; 2],
    /// The least and the greatest value each takes in the chunk: the steps, rounded down,
    /// stray below the line between the exact ends by less than one a pixel.
    bounds: [(i64, i64); 2],
}

impl Chunks {
    /// The chunks of the piece `xs..xe` of the run ending at `x1`, from the accumulators `acc`
    /// at the chunk start `start` and their steps `dacc`.
    #[inline(always)]
    fn new(acc: [i64; 3], dacc: [i64; 3], chunk: i64, start: i64, piece: &RunPiece) -> Self {
        Self {
            acc,
            dacc,
            // A whole chunk's steps, once a run.
            chunk_steps: dacc.map(|d| saturating_times(d, chunk)),
            chunk,
            cs: start,
            uv: divide(acc[0], acc[1], acc[2]),
            x: piece.xs,
            xs: piece.xs,
            xe: piece.xe,
            x1: piece.x1,
        }
    }
}

impl Iterator for Chunks {
    type Item = Chunk;

    #[inline(always)]
    fn next(&mut self) -> Option<Chunk> {
        if self.x >= self.xe {
            return None;
        }
        let (x, cs, (u, v)) = (self.x, self.cs, self.uv);
        let ce = (cs + self.chunk).min(self.x1);
        let m = ce - cs;
        for j in 0..3 {
            let step = if m == self.chunk {
                self.chunk_steps[j]
            } else {
                saturating_times(self.dacc[j], m)
            };
            self.acc[j] = self.acc[j].saturating_add(step);
        }
        let end = divide(self.acc[0], self.acc[1], self.acc[2]);
        let (du, dv) = (div_small(end.0 - u, m), div_small(end.1 - v, m));
        let stop = ce.min(self.xe);
        let bounds = |a: i64, b: i64| (a.min(b) - m, a.max(b));
        (self.uv, self.cs, self.x) = (end, ce, stop);
        Some(Chunk {
            ks: (x - self.xs) as usize..(stop - self.xs) as usize,
            c: [
                u.wrapping_add(du.wrapping_mul(x - cs)),
                v.wrapping_add(dv.wrapping_mul(x - cs)),
            ],
            d: [du, dv],
            bounds: [bounds(u, end.0), bounds(v, end.1)],
        })
    }
}

/// True when texture coordinates `c` stepped by `d` lie inside the range at the first and the
/// last of `n` pixels, and so at every pixel between.
#[inline(always)]
fn inside(c: [i64; 2], d: [i64; 2], n: usize) -> bool {
    let last = n as i64 - 1;
    (0..2).all(|k| COORD.contains(&c[k]) && COORD.contains(&(c[k] + d[k] * last)))
}

/// `pixels` without clamps on a 32-bit core, in two passes over each stretch of the piece whose
/// texture coordinates step alike (the piece, or a perspective chunk's part of it): the depth
/// test, which holds the pixels that pass, then their colour, fog and texture coordinates, each
/// the value at the piece's first pixel plus its step times the pixel's place. One loop over
/// both keeps more values live than a 32-bit core has registers, and here a pixel that fails
/// the test costs no values.
///
/// In words: wrapping products and sums are exact modulo 2^32, and every colour and fog value
/// of the piece lies in its range (below 2^25), so its word is the integer itself; texture
/// coordinates take words from an offset where the stretch's spread allows (`UvWords`).
#[inline(always)]
fn pixels_in_words<
    D: DepthStorage,
    T: Filtering,
    const GREY: bool,
    const SHADE: bool,
    const FOG: bool,
>(
    run: Run<'_, D>,
    px: Stepped<GREY>,
    frags: &mut Fragments,
) {
    let Run {
        piece,
        tex,
        depth,
        test,
    } = run;
    let RunPiece { xs, xe, at, .. } = piece;
    let n = (xe - xs) as usize;
    let first = at as u32;
    let values = ValueWords::<GREY>::new(&px, first);
    let (mut z, dz) = (px.z, px.dz);
    match tex {
        RunTex::Perspective {
            acc,
            dacc,
            chunk,
            start,
        } => {
            for Chunk { ks, c, d, bounds } in Chunks::new(acc, dacc, chunk, start, &piece) {
                let (from, n) = (ks.start, ks.len());
                let range = || Some(uv_range(bounds));
                let slots;
                (slots, z) = depth_pass::<D>(ks, first, (z, dz), test, depth, frags, range);
                match UvWords::new(c, d, first + from as u32, bounds) {
                    Some(w) => values.put::<T, SHADE, FOG>(slots, frags, |at| w.at(at)),
                    // As `pixels` steps them, clamped where the chunk strays.
                    None if inside(c, d, n) => values.put::<T, SHADE, FOG>(slots, frags, |at| {
                        let j = (at - first) as i64 - from as i64;
                        let coord =
                            |i: usize| (c[i].wrapping_add(d[i].wrapping_mul(j)) >> 16) as i32;
                        (coord(0), coord(1))
                    }),
                    None => values.put::<T, SHADE, FOG>(slots, frags, |at| {
                        let j = (at - first) as i64 - from as i64;
                        let coord = |i: usize| {
                            clamp_coord(c[i].wrapping_add(d[i].wrapping_mul(j)) >> 16) as i32
                        };
                        (coord(0), coord(1))
                    }),
                }
            }
        }
        RunTex::Affine { uv, duv } => {
            let last = n as i64 - 1;
            let bounds = move || {
                [0, 1].map(|k| {
                    let end = uv[k] + duv[k] * last;
                    (uv[k].min(end), uv[k].max(end))
                })
            };
            let range = || Some(uv_range(bounds()));
            let (slots, _) = depth_pass::<D>(0..n, first, (z, dz), test, depth, frags, range);
            let bounds = bounds();
            match UvWords::new(uv, duv, first, bounds) {
                Some(w) => values.put::<T, SHADE, FOG>(slots, frags, |at| w.at(at)),
                // In range at every pixel (`run_fragments`).
                None => values.put::<T, SHADE, FOG>(slots, frags, |at| {
                    let k = (at - first) as i64;
                    let coord =
                        |i: usize| (uv[i].wrapping_add(duv[i].wrapping_mul(k)) >> 16) as i32;
                    (coord(0), coord(1))
                }),
            }
        }
        RunTex::Off => {
            let (slots, _) = depth_pass::<D>(0..n, first, (z, dz), test, depth, frags, || None);
            values.put::<T, SHADE, FOG>(slots, frags, |_| (0, 0));
        }
    }
}

/// The range of the 16.16 texture coordinates `c >> 16` of 16.32 values `c` within `bounds`,
/// and of their clamps (`clamp_coord`) too: the bounds' ends lie within the coordinate range
/// (a chunk's ends are quotients `divide` clamped there) but for the least, which may lie up
/// to a chunk's pixels below it, so the shifted ends are words, and a value clamped up to the
/// range's end stays above the least.
#[inline(always)]
fn uv_range(bounds: [(i64, i64); 2]) -> UvRange {
    UvRange {
        lo: bounds.map(|b| (b.0 >> 16) as i32),
        hi: bounds.map(|b| (b.1 >> 16) as i32),
    }
}

/// The depth pass of `pixels_in_words` over pixels `ks` of the piece (`first` the index of
/// its first pixel in the tile's buffers, `depth` its depth values) from depth `z` at pixel
/// `ks.start` and its step: the slots of the pixels that passed, and the depth after the last.
/// Everything the loop reads is a local here: the stores to the fragments' arrays would
/// otherwise have it read again from memory at every pixel. `range`: where the fragments'
/// texture coordinates lie, if known, worked out only where the colour stage asks
/// (`Fragments::keep_within`).
#[inline(always)]
fn depth_pass<D: DepthStorage>(
    ks: Range<usize>,
    first: u32,
    (mut z, dz): (i64, i64),
    test: DepthTest,
    depth: &mut [D::Value],
    frags: &mut Fragments,
    range: impl FnOnce() -> Option<UvRange>,
) -> (Range<usize>, i64) {
    let held = frags.held();
    let mut kept = held;
    if D::ENABLED {
        for (k, stored) in (ks.start as u32..).zip(&mut depth[ks]) {
            frags.at[Fragments::slot(kept)] = first + k;
            let pass = test.apply::<D>(D::from_z_in_range(z), stored);
            z = z.wrapping_add(dz);
            kept += pass as usize;
        }
    } else {
        for k in ks.start as u32..ks.end as u32 {
            frags.at[Fragments::slot(kept)] = first + k;
            kept += 1;
        }
    }
    frags.keep_within(kept, range);
    (held..kept, z)
}

/// Colour and fog in words (`pixels_in_words`) and their steps, the words as the steps would
/// reach index 0 of the tile's buffers from the piece's first pixel (at index `first`): a
/// fragment's values are then the words plus the steps times its own index.
struct ValueWords<const GREY: bool> {
    c: [i32; 3],
    dc: [i32; 3],
    f: i32,
    df: i32,
}

impl<const GREY: bool> ValueWords<GREY> {
    #[inline(always)]
    fn new(px: &Stepped<GREY>, first: u32) -> Self {
        let back = |v: i64, d: i64| (v as i32).wrapping_sub((d as i32).wrapping_mul(first as i32));
        Self {
            c: [0, 1, 2].map(|k| back(px.c[k], px.dc[k])),
            dc: px.dc.map(|d| d as i32),
            f: back(px.f, px.df),
            df: px.df as i32,
        }
    }

    /// The values pass: texture coordinates (`uv` of the index of the fragment's pixel),
    /// colour and fog of the fragments held in `slots`, in a loop for the coordinates and one
    /// for the rest, each of which a 32-bit core holds in its registers.
    #[inline(always)]
    fn put<T: Filtering, const SHADE: bool, const FOG: bool>(
        &self,
        slots: Range<usize>,
        frags: &mut Fragments,
        uv: impl Fn(u32) -> (i32, i32),
    ) {
        if T::ENABLED {
            for s in slots.clone() {
                let i = Fragments::slot(s);
                (frags.u[i], frags.v[i]) = uv(frags.at[i]);
            }
        }
        if !(SHADE || FOG) {
            return;
        }
        for s in slots {
            let i = Fragments::slot(s);
            let at = frags.at[i] as i32;
            let value =
                |v: i32, d: i32| (v.wrapping_add(d.wrapping_mul(at)) >> ATTR_FRAC_BITS) as u16;
            if SHADE {
                frags.c[0][i] = value(self.c[0], self.dc[0]);
                if !GREY {
                    frags.c[1][i] = value(self.c[1], self.dc[1]);
                    frags.c[2][i] = value(self.c[2], self.dc[2]);
                }
            }
            if FOG {
                frags.f[i] = value(self.f, self.df);
            }
        }
    }
}

/// Texture coordinates of a stretch of pixels in words: a coordinate whose values over the
/// stretch lie in `o..o + 2^31`, `o` their least rounded down to a multiple of `2^16`, is
/// exact as the word `c - o` in wrapping arithmetic, and `c >> 16` is
/// `((c - o) >> 16) + (o >> 16)`. A chunk spreads that little unless its texture is minified
/// past half a repeat.
struct UvWords {
    /// The words as the steps would reach index 0 of the tile's buffers (wrapping).
    w: [i32; 2],
    step: [i32; 2],
    /// `o >> 16`.
    high: [i32; 2],
}

impl UvWords {
    /// The words of coordinates `c` (16.32) at the pixel of index `from` in the tile's
    /// buffers, stepped by `d` along the row, whose values over the stretch lie within
    /// `bounds` (least, greatest); `None` where either spreads too far or leaves the range
    /// (where `pixels` clamps).
    #[inline(always)]
    fn new(c: [i64; 2], d: [i64; 2], from: u32, bounds: [(i64, i64); 2]) -> Option<Self> {
        let offset = |(lo, hi): (i64, i64)| {
            let o = lo & !((1 << 16) - 1);
            (lo >= COORD.start && hi < COORD.end && hi - o < 1 << 31).then_some(o)
        };
        let o = [offset(bounds[0])?, offset(bounds[1])?];
        let step = d.map(|d| d as i32);
        Some(Self {
            w: [0, 1]
                .map(|k| ((c[k] - o[k]) as i32).wrapping_sub(step[k].wrapping_mul(from as i32))),
            step,
            high: o.map(|o| (o >> 16) as i32),
        })
    }

    /// The coordinates at the pixel of index `at` in the tile's buffers.
    #[inline(always)]
    fn at(&self, at: u32) -> (i32, i32) {
        let at = |i: usize| {
            (self.w[i].wrapping_add(self.step[i].wrapping_mul(at as i32)) >> 16) + self.high[i]
        };
        (at(0), at(1))
    }
}

/// A narrow triangle's planes for the rows of `small_run`: copies of those its draw uses.
#[derive(Clone, Copy, Debug)]
pub(crate) struct NarrowPlanes {
    pub z: AttrPlane,
    pub c: [AttrPlane; 3],
    pub f: AttrPlane,
    /// `u, v` (affine) or `s, t, q` (perspective).
    pub tex: [AttrPlane; 3],
    pub tex_mode: TexMode,
}

impl NarrowPlanes {
    /// The planes of `tri` (narrow: `FixedTriangle::narrow`), in the order of `run_fragments`.
    #[inline(always)]
    pub fn new<
        D: DepthStorage,
        T: Filtering,
        const SHADE: bool,
        const GREY: bool,
        const FOG: bool,
    >(
        tri: &FixedTriangle,
        planes: &[AttrPlane],
    ) -> Self {
        debug_assert!(tri.narrow);
        let planes = &planes[tri.planes as usize..];
        let (color_at, fog_at, tex_at) = plane_offsets::<D, SHADE, GREY, FOG>();
        let none = AttrPlane::default();
        let mut p = Self {
            z: none,
            c: [none; 3],
            f: none,
            tex: [none; 3],
            tex_mode: if T::ENABLED {
                tri.tex_mode
            } else {
                TexMode::Off
            },
        };
        if D::ENABLED {
            p.z = planes[0];
        }
        if SHADE {
            let n = if GREY { 1 } else { 3 };
            p.c[..n].copy_from_slice(&planes[color_at..color_at + n]);
        }
        if FOG {
            p.f = planes[fog_at];
        }
        match p.tex_mode {
            TexMode::Off => {}
            TexMode::Affine => p.tex[..2].copy_from_slice(&planes[tex_at..tex_at + 2]),
            TexMode::Perspective(_) => p.tex.copy_from_slice(&planes[tex_at..tex_at + 3]),
        }
        p
    }

    /// True when `small_run` can draw the triangle's rows: its texture, if any, is affine or
    /// exact per pixel (`Spans(n)` of a triangle wider than `n` needs `run_fragments`' chunks).
    #[inline(always)]
    pub fn per_pixel(&self) -> bool {
        matches!(
            self.tex_mode,
            TexMode::Off | TexMode::Affine | TexMode::Perspective(1)
        )
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;

    /// The steps around the plain product's ends, and the extremes.
    const EDGES: [i64; 9] = [
        0,
        1,
        -1,
        (1 << 55) - 1,
        1 << 55,
        -(1 << 55),
        -(1 << 55) - 1,
        i64::MAX,
        i64::MIN,
    ];

    #[test]
    fn chunk_products_at_their_edges_saturate_as_the_saturating_product() {
        for d in EDGES {
            for m in [0, 1, 2, 127, 255] {
                assert_eq!(saturating_times(d, m), d.saturating_mul(m), "{d} * {m}");
            }
        }
    }

    proptest! {
        #[test]
        fn chunk_products_saturate_as_the_saturating_product(
            d in any::<i64>(),
            bits in 0u32..64,
            m in 0i64..256,
        ) {
            prop_assert_eq!(saturating_times(d >> bits, m), (d >> bits).saturating_mul(m));
        }
    }
}
