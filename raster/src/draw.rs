//! A draw call end to end: assembly, vertex stage once per vertex, triangle setup, then rows in
//! parallel bands with a specialised row function.
//!
//! Determinism: every row is computed from its triangle's set-up data alone (edge steppers and
//! attribute planes are evaluated exactly at the band's first row), and each band draws the
//! triangles in submission order, so any band split, and so any thread count, gives the same bytes.

use rayon::prelude::*;

use crate::RasterError;
use crate::clip::{ClipVertex, MAX_POLYGON, clip_triangle};
use crate::edge::Coverage;
use crate::framebuffer::{ColorBuffer, DepthBuffer, Framebuffer};
use crate::matrix::Transform;
use crate::pipeline::fixed::{self, FixedClip, FixedFog, FixedScreen, FixedSpace, FixedTriangle};
use crate::pipeline::float::{self, FloatClip, FloatScreen, FloatSpace, FloatTriangle};
use crate::pipeline::{Attributes, RowTarget, Setup, TexMode, Viewport};
use crate::pixel::{Depth16, Depth32, DepthFormat, NoDepth, PixelFormat, Rgb565, Rgba8888};
use crate::sampler::{Bilinear, Filtering, LevelView, Nearest, NoTexture, ViewOf};
use crate::state::{CullMode, FrontFace, Precision, Rect, RenderState};
use crate::texture::{Filter, TextureFormat};
use crate::vertex::{Mesh, Vertex, assemble};

/// Triangles per unit of parallel set-up work.
const SETUP_CHUNK: usize = 512;
/// Triangles set up before their rows are drawn: enough to keep every thread busy, few enough that
/// the set-up data stays in cache.
const RASTER_CHUNK: usize = 4096;
/// Below this many vertices or triangles, a stage runs on the calling thread.
const PARALLEL_MIN: usize = 4096;

/// What a draw did, for statistics and benchmarks.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DrawStats {
    /// Non-degenerate triangles assembled from the indices.
    pub triangles: u64,
    /// Triangles (after clipping, a clipped triangle may count several) that reached the rows.
    pub rasterized: u64,
    /// Pixels written (that passed the depth test).
    pub fragments: u64,
}

impl std::ops::AddAssign for DrawStats {
    fn add_assign(&mut self, o: Self) {
        self.triangles += o.triangles;
        self.rasterized += o.rasterized;
        self.fragments += o.fragments;
    }
}

/// A vertex after the vertex stage: clip-space copy, outcode, and (inside the guard band and the
/// depth range) its projection.
#[derive(Clone, Copy, Debug)]
struct Transformed<C, S> {
    clip: C,
    outcode: u8,
    screen: S,
}

/// The rasterizer with its scratch buffers, reused from draw to draw.
#[derive(Debug, Default)]
pub struct Rasterizer {
    /// Per-vertex stamp of the draw that last referenced it.
    stamp: Vec<u32>,
    /// Per-vertex position in `used`, valid where the stamp is current.
    slot: Vec<u32>,
    generation: u32,
    used: Vec<u32>,
    triangles: Vec<[u32; 3]>,
    fixed_vertices: Vec<Transformed<FixedClip, FixedScreen>>,
    float_vertices: Vec<Transformed<FloatClip, FloatScreen>>,
    threads: Option<usize>,
}

impl Rasterizer {
    /// A rasterizer that uses the current rayon pool.
    pub fn new() -> Self {
        Self::default()
    }

    /// A rasterizer that runs on at most `threads` threads of the current rayon pool (1 draws on
    /// the calling thread). The picture does not depend on it.
    pub fn with_threads(threads: usize) -> Self {
        Self {
            threads: Some(threads.max(1)),
            ..Self::default()
        }
    }

    fn thread_count(&self) -> usize {
        self.threads
            .unwrap_or_else(rayon::current_num_threads)
            .min(rayon::current_num_threads())
            .max(1)
    }

    /// Draws `mesh` into `fb`.
    pub fn draw(
        &mut self,
        fb: &mut Framebuffer,
        mesh: &Mesh,
        transform: &Transform,
        state: &RenderState,
    ) -> Result<DrawStats, RasterError> {
        let scissor = Rect::scissor_on(state.scissor, fb.width(), fb.height())?;
        self.gather(mesh)?;
        let mut stats = DrawStats {
            triangles: self.triangles.len() as u64,
            ..DrawStats::default()
        };
        if self.triangles.is_empty() || scissor.x0 == scissor.x1 || scissor.y0 == scissor.y1 {
            return Ok(stats);
        }
        let vp = Viewport {
            width: fb.width(),
            height: fb.height(),
        };
        let has_depth = !matches!(fb.depth(), DepthBuffer::None);
        let attrs = Attributes::new(state, has_depth);
        let job = Job {
            vp,
            scissor,
            attrs,
            state,
            threads: self.thread_count(),
        };
        let (rasterized, fragments) = match state.precision {
            Precision::Fixed => {
                let fog = state.fog.map(|f| FixedFog {
                    start: transform.fixed.scale_length(f.start),
                    end: transform.fixed.scale_length(f.end),
                });
                let stages = Stages {
                    space: FixedSpace::new(&vp),
                    clip: |v: &Vertex| FixedClip::from_vertex(v, &transform.fixed),
                    project: |c: &FixedClip| FixedScreen::project(c, &vp, fog),
                    make: FixedTriangle::new,
                    rows: dispatch_fixed,
                };
                run(
                    &mut self.fixed_vertices,
                    &self.used,
                    &self.triangles,
                    mesh,
                    fb,
                    &job,
                    stages,
                )
            }
            Precision::Float => {
                let stages = Stages {
                    space: FloatSpace::new(&vp),
                    clip: |v: &Vertex| FloatClip::from_vertex(v, transform),
                    project: |c: &FloatClip| FloatScreen::project(c, &vp, state.fog),
                    make: FloatTriangle::new,
                    rows: dispatch_float,
                };
                run(
                    &mut self.float_vertices,
                    &self.used,
                    &self.triangles,
                    mesh,
                    fb,
                    &job,
                    stages,
                )
            }
        };
        stats.rasterized = rasterized;
        stats.fragments = fragments;
        Ok(stats)
    }

    /// Assembles the triangles and numbers the vertices they use, each once.
    fn gather(&mut self, mesh: &Mesh) -> Result<(), RasterError> {
        let n = mesh.vertices.len();
        if self.stamp.len() < n {
            self.stamp.resize(n, 0);
            self.slot.resize(n, 0);
        }
        self.generation = self.generation.wrapping_add(1);
        if self.generation == 0 {
            self.stamp.fill(0);
            self.generation = 1;
        }
        let (stamp, slot, used, generation) = (
            &mut self.stamp,
            &mut self.slot,
            &mut self.used,
            self.generation,
        );
        used.clear();
        self.triangles.clear();
        let triangles = &mut self.triangles;
        assemble(mesh, |t| {
            triangles.push(t.map(|v| {
                let v = v as usize;
                if stamp[v] != generation {
                    stamp[v] = generation;
                    slot[v] = used.len() as u32;
                    used.push(v as u32);
                }
                slot[v]
            }))
        })
        .map_err(|(position, value)| RasterError::IndexOutOfRange {
            position,
            value,
            vertices: n,
        })
    }
}

/// The per-draw constants every stage reads.
struct Job<'s, 't> {
    vp: Viewport,
    scissor: Rect,
    attrs: Attributes<'t>,
    state: &'s RenderState<'t>,
    threads: usize,
}

/// One pipeline's stages, so that both precisions share the draw's control flow.
struct Stages<Sp, Cf, Pf, Mf, Rf> {
    space: Sp,
    clip: Cf,
    project: Pf,
    make: Mf,
    rows: Rf,
}

/// Vertex stage once per used vertex, then set-up and rows chunk by chunk. Returns the
/// triangles rasterized and the fragments written.
fn run<C, S, T, Cf, Pf, Mf, Rf>(
    vertices: &mut Vec<Transformed<C, S>>,
    used: &[u32],
    triangles: &[[u32; 3]],
    mesh: &Mesh,
    fb: &mut Framebuffer,
    job: &Job,
    st: Stages<C::Space, Cf, Pf, Mf, Rf>,
) -> (u64, u64)
where
    C: ClipVertex + Send + Sync,
    C::Space: Sync,
    S: Projected + Send,
    T: Send,
    Cf: Fn(&Vertex) -> C + Sync,
    Pf: Fn(&C) -> S + Sync,
    Mf: Fn([&S; 3], i64, Coverage, &Attributes) -> T + Sync,
    Rf: Fn(&mut Framebuffer, &[T], &Job) -> u64,
{
    transform_vertices(vertices, used, job.threads, |i| {
        let clip = (st.clip)(&mesh.vertices[i]);
        let outcode = clip.outcode(&st.space);
        let screen = if outcode == 0 {
            (st.project)(&clip)
        } else {
            S::default()
        };
        Transformed {
            clip,
            outcode,
            screen,
        }
    });
    let (mut rasterized, mut fragments) = (0, 0);
    let mut tris = Vec::new();
    for chunk in triangles.chunks(RASTER_CHUNK) {
        set_up(
            chunk,
            vertices,
            job,
            &st.space,
            &mut tris,
            &st.project,
            &st.make,
        );
        rasterized += tris.len() as u64;
        fragments += (st.rows)(fb, &tris, job);
    }
    (rasterized, fragments)
}

/// Runs the vertex stage over the used vertices, in parallel when it pays.
fn transform_vertices<T: Send>(
    out: &mut Vec<T>,
    used: &[u32],
    threads: usize,
    f: impl Fn(usize) -> T + Sync + Send,
) {
    out.clear();
    if threads > 1 && used.len() >= PARALLEL_MIN {
        used.par_iter()
            .map(|&i| f(i as usize))
            .collect_into_vec(out);
    } else {
        out.extend(used.iter().map(|&i| f(i as usize)));
    }
}

/// Clips, culls and sets up `triangles` into `out` (replacing its contents), in order.
fn set_up<C, S, T>(
    triangles: &[[u32; 3]],
    vertices: &[Transformed<C, S>],
    job: &Job,
    space: &C::Space,
    out: &mut Vec<T>,
    project: impl Fn(&C) -> S + Sync,
    make: impl Fn([&S; 3], i64, Coverage, &Attributes) -> T + Sync,
) where
    C: ClipVertex + Sync,
    C::Space: Sync,
    S: Projected,
    T: Send,
{
    let rows = (job.scissor.y0 as i64, job.scissor.y1 as i64);
    let cull = job.state.cull;
    let ccw_front = job.state.front_face == FrontFace::Ccw;
    let setup_one = |s: [&S; 3], out: &mut Vec<T>| {
        let p = s.each_ref().map(|v| v.xy());
        let area2 =
            (p[1][0] - p[0][0]) * (p[2][1] - p[0][1]) - (p[2][0] - p[0][0]) * (p[1][1] - p[0][1]);
        if area2 == 0 {
            return;
        }
        // Screen y points down, so a triangle counter-clockwise in NDC has negative area here.
        let front = (area2 < 0) == ccw_front;
        if (cull == CullMode::Back && !front) || (cull == CullMode::Front && front) {
            return;
        }
        let (s, p, area2) = if area2 < 0 {
            ([s[0], s[2], s[1]], [p[0], p[2], p[1]], -area2)
        } else {
            (s, p, area2)
        };
        if let Some(cov) = Coverage::new(p, rows) {
            out.push(make(s, area2, cov, &job.attrs));
        }
    };
    let set_up_into = |tris: &[[u32; 3]], out: &mut Vec<T>| {
        for t in tris {
            let v = t.map(|i| &vertices[i as usize]);
            let and = v[0].outcode & v[1].outcode & v[2].outcode;
            let or = v[0].outcode | v[1].outcode | v[2].outcode;
            if and != 0 {
                continue;
            }
            if or == 0 {
                setup_one(v.map(|v| &v.screen), out);
                continue;
            }
            let poly = clip_triangle(v.map(|v| v.clip), or, space);
            let mut screen = [S::default(); MAX_POLYGON];
            for (s, c) in screen.iter_mut().zip(&poly.vertices[..poly.len]) {
                *s = project(c);
            }
            for k in 1..poly.len.saturating_sub(1) {
                setup_one([&screen[0], &screen[k], &screen[k + 1]], out);
            }
        }
    };
    out.clear();
    if job.threads > 1 && triangles.len() > SETUP_CHUNK {
        out.par_extend(triangles.par_chunks(SETUP_CHUNK).flat_map_iter(|c| {
            let mut part = Vec::with_capacity(c.len());
            set_up_into(c, &mut part);
            part
        }));
    } else {
        set_up_into(triangles, out);
    }
}

/// A projected vertex of either pipeline.
trait Projected: Copy + Default + Sync {
    /// Snapped sub-pixel position.
    fn xy(&self) -> [i64; 2];
}

impl Projected for FixedScreen {
    fn xy(&self) -> [i64; 2] {
        self.xy
    }
}

impl Projected for FloatScreen {
    fn xy(&self) -> [i64; 2] {
        self.xy
    }
}

/// One band's colour rows and depth rows (empty without a depth test).
type BandSlices<'a, P, D> = (
    &'a mut [<P as PixelFormat>::Pixel],
    &'a mut [<D as DepthFormat>::Value],
);

/// Draws the set-up triangles band by band; `row` shades one span of one row.
fn raster_bands<T, P, D>(
    tris: &[T],
    color: &mut [P::Pixel],
    depth: &mut [D::Value],
    job: &Job,
    row: impl Fn(&T, &mut RowTarget<'_, P, D>, i64, i64, i64) -> u64 + Sync,
) -> u64
where
    T: Setup,
    P: PixelFormat,
    D: DepthFormat,
{
    let width = job.vp.width as usize;
    let (y0, y1) = (job.scissor.y0 as usize, job.scissor.y1 as usize);
    let cols = (job.scissor.x0 as i64, job.scissor.x1 as i64);
    let bands = if job.threads > 1 { job.threads * 4 } else { 1 };
    let band_rows = (y1 - y0).div_ceil(bands).max(1);
    let color = &mut color[y0 * width..y1 * width];
    let depth = if D::ENABLED {
        &mut depth[y0 * width..y1 * width]
    } else {
        depth
    };
    let draw_band = |(band, (color, depth)): (usize, BandSlices<'_, P, D>)| {
        let top = (y0 + band * band_rows) as i64;
        let bottom = top + (color.len() / width) as i64;
        let mut fragments = 0;
        for t in tris {
            t.coverage().for_each_span(top, bottom, cols, |y, a, b| {
                let r = (y - top) as usize * width;
                let mut target = RowTarget {
                    color: &mut color[r..r + width],
                    depth: if D::ENABLED {
                        &mut depth[r..r + width]
                    } else {
                        &mut []
                    },
                };
                fragments += row(t, &mut target, y, a, b);
            });
        }
        fragments
    };
    let color_bands = color.chunks_mut(band_rows * width);
    let pairs: Vec<BandSlices<'_, P, D>> = if D::ENABLED {
        color_bands
            .zip(depth.chunks_mut(band_rows * width))
            .collect()
    } else {
        color_bands.map(|c| (c, &mut [][..])).collect()
    };
    if bands > 1 {
        pairs.into_par_iter().enumerate().map(draw_band).sum()
    } else {
        pairs.into_iter().enumerate().map(draw_band).sum()
    }
}

/// Picks the pixel and depth formats of the target, then hands typed slices to `f`.
macro_rules! with_target {
    ($fb:expr, $depth_on:expr, $f:ident, $($arg:expr),*) => {{
        let (color, depth) = $fb.buffers_mut();
        match (color, depth) {
            (ColorBuffer::Rgb565(c), d) => with_target!(@depth Rgb565, c, d, $depth_on, $f, $($arg),*),
            (ColorBuffer::Rgba8888(c), d) => with_target!(@depth Rgba8888, c, d, $depth_on, $f, $($arg),*),
        }
    }};
    (@depth $p:ty, $c:expr, $d:expr, $depth_on:expr, $f:ident, $($arg:expr),*) => {
        match $d {
            DepthBuffer::D16(d) if $depth_on => $f::<$p, Depth16>($c, d, $($arg),*),
            DepthBuffer::D32(d) if $depth_on => $f::<$p, Depth32>($c, d, $($arg),*),
            _ => $f::<$p, NoDepth>($c, &mut [], $($arg),*),
        }
    };
}

fn dispatch_fixed(fb: &mut Framebuffer, tris: &[FixedTriangle], job: &Job) -> u64 {
    with_target!(fb, job.attrs.depth, fixed_texture, tris, job)
}

/// Chooses the texture filter and texel type.
fn fixed_texture<P: PixelFormat, D: DepthFormat>(
    color: &mut [P::Pixel],
    depth: &mut [D::Value],
    tris: &[FixedTriangle],
    job: &Job,
) -> u64 {
    let Some(binding) = job.state.texture.filter(|_| job.attrs.tex != TexMode::Off) else {
        return fixed_flags::<P, D, NoTexture>(color, depth, tris, job, &[]);
    };
    fn go<P: PixelFormat, D: DepthFormat, F: Filtering>(
        color: &mut [P::Pixel],
        depth: &mut [D::Value],
        tris: &[FixedTriangle],
        job: &Job,
    ) -> u64 {
        let b = job.state.texture.expect("texture bound");
        let views: Vec<LevelView<'_, F::Texel>> = b
            .texture
            .levels()
            .iter()
            .map(|l| F::Texel::view(l, b.sampler.wrap).expect("one texel type per texture"))
            .collect();
        fixed_flags::<P, D, F>(color, depth, tris, job, &views)
    }
    match (binding.sampler.filter, binding.texture.format()) {
        (Filter::Nearest, TextureFormat::Rgb565) => {
            go::<P, D, Nearest<u16>>(color, depth, tris, job)
        }
        (Filter::Nearest, TextureFormat::Rgba8888) => {
            go::<P, D, Nearest<[u8; 4]>>(color, depth, tris, job)
        }
        (Filter::Bilinear, TextureFormat::Rgb565) => {
            go::<P, D, Bilinear<u16>>(color, depth, tris, job)
        }
        (Filter::Bilinear, TextureFormat::Rgba8888) => {
            go::<P, D, Bilinear<[u8; 4]>>(color, depth, tris, job)
        }
    }
}

/// Chooses the shading and fog specialisation and runs the bands.
fn fixed_flags<P: PixelFormat, D: DepthFormat, F: Filtering>(
    color: &mut [P::Pixel],
    depth: &mut [D::Value],
    tris: &[FixedTriangle],
    job: &Job,
    views: &[LevelView<'_, F::Texel>],
) -> u64 {
    fn run<P: PixelFormat, D: DepthFormat, F: Filtering, const SHADE: bool, const FOG: bool>(
        color: &mut [P::Pixel],
        depth: &mut [D::Value],
        tris: &[FixedTriangle],
        job: &Job,
        views: &[LevelView<'_, F::Texel>],
    ) -> u64 {
        let attrs = &job.attrs;
        raster_bands::<_, P, D>(tris, color, depth, job, |t, row, y, a, b| {
            fixed::shade_row::<P, D, F, SHADE, FOG>(t, row, views.get(t.level()), attrs, y, a, b)
        })
    }
    match (job.attrs.shade, job.attrs.fog) {
        (false, false) => run::<P, D, F, false, false>(color, depth, tris, job, views),
        (true, false) => run::<P, D, F, true, false>(color, depth, tris, job, views),
        (false, true) => run::<P, D, F, false, true>(color, depth, tris, job, views),
        (true, true) => run::<P, D, F, true, true>(color, depth, tris, job, views),
    }
}

fn dispatch_float(fb: &mut Framebuffer, tris: &[FloatTriangle], job: &Job) -> u64 {
    fn go<P: PixelFormat, D: DepthFormat>(
        color: &mut [P::Pixel],
        depth: &mut [D::Value],
        tris: &[FloatTriangle],
        job: &Job,
    ) -> u64 {
        let texture = job.state.texture.filter(|_| job.attrs.tex != TexMode::Off);
        let attrs = &job.attrs;
        raster_bands::<_, P, D>(tris, color, depth, job, |t, row, y, a, b| {
            let tex = texture.map(|b| (&b.texture.levels()[t.level()], b.sampler));
            float::shade_row::<P, D>(t, row, tex, attrs, y, a, b)
        })
    }
    with_target!(fb, job.attrs.depth, go, tris, job)
}
