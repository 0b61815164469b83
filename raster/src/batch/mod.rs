//! A batch of draws rasterized together: one frame's draw calls (the terrain engine makes
//! hundreds, one per tile) share the threads and the screen tiles instead of each paying for
//! its own.
//!
//! A draw call only assembles its triangles and copies the vertices they use (a lone
//! `Rasterizer::draw` reads them in place, and on several threads leaves a big mesh to be
//! assembled pass by pass in the flush). When enough triangles are pending (or the batch
//! ends) they are flushed pass by pass: each pass's vertices run the vertex stage once, set-up
//! runs in chunks on every thread and bins each triangle into the screen tiles it touches, and
//! every tile is drawn by one thread, its triangles in submission order. A
//! pixel's bytes depend only on the triangles that cover it, in that order: neither the thread
//! count nor the batching changes a byte.

mod flush;
mod loans;
mod tiles;
mod vertex_stage;

use crate::RasterError;
use crate::bin::tile_size;
use crate::lines::{LineState, LineStats};
use crate::matrix::Transform;
use crate::pipeline::fixed::FixedPipeline;
use crate::pipeline::float::FloatPipeline;
use crate::pipeline::{Attributes, TexMode};
use crate::rasterizer::{DrawStats, Rasterizer};
use crate::sampler::TexViews;
use crate::state::{Precision, Rect, RenderState};
use crate::surface::{AsSurface, DepthMut, Surface};
use crate::vertex::{Mesh, Vertex, indices_in_range};
use flush::{Source, flush_with};

/// Pending triangles that trigger a flush after a draw.
const FLUSH_TRIANGLES: usize = 1 << 16;

/// One pending draw: its state and where its vertices and triangles start.
struct PendingDraw<'t> {
    state: RenderState<'t>,
    attrs: Attributes<'t>,
    scissor: Rect,
    transform: Transform,
    views: TexViews<'t>,
    first_vertex: usize,
    first_triangle: usize,
}

/// Draws into one surface that are rasterized together (see the module documentation).
///
/// Made by [`Rasterizer::batch`]. Each [`Batch::draw`] returns the triangles it assembled;
/// the triangles rasterized and the fragments written are counted when the batch ends
/// ([`Batch::finish`], or when it is dropped). The textures of a batch's draws are borrowed
/// until then.
pub struct Batch<'r, 't> {
    rasterizer: &'r mut Rasterizer,
    fb: Surface<'r>,
    draws: Vec<PendingDraw<'t>>,
    /// The vertices of the batch's only draw when it reads them where they are instead of a
    /// copy (`Batch::draw_in_place`).
    in_place: Option<&'t [Vertex]>,
    /// The batch's only draw when its triangles are assembled pass by pass in the flush.
    deferred: Option<Mesh<'t>>,
    precision: Precision,
    done: DrawStats,
}

impl Rasterizer {
    /// Starts a batch of draws into `fb` (a [`crate::Framebuffer`] or a [`Surface`]): the
    /// draws of a frame (the engine's tiles) rasterized together, with the same bytes as
    /// drawing them one by one.
    pub fn batch<'r, 't>(&'r mut self, fb: &'r mut impl AsSurface) -> Batch<'r, 't> {
        Batch {
            rasterizer: self,
            fb: fb.as_surface(),
            draws: Vec::new(),
            in_place: None,
            deferred: None,
            precision: Precision::Fixed,
            done: DrawStats::default(),
        }
    }

    /// Draws `mesh` into `fb` (a [`crate::Framebuffer`] or a [`crate::Surface`]). A mesh with
    /// no more vertices than indices is drawn from its own vertices, not from a copy.
    pub fn draw(
        &mut self,
        fb: &mut impl AsSurface,
        mesh: &Mesh,
        transform: &Transform,
        state: &RenderState,
    ) -> Result<DrawStats, RasterError> {
        let mut batch = self.batch(fb);
        let drawn = batch.draw_in_place(mesh, transform, state)?;
        let done = batch.finish();
        // A draw assembled pass by pass counts its triangles in the flush.
        Ok(DrawStats {
            triangles: drawn.triangles + done.triangles,
            ..done
        })
    }
}

impl<'t> Batch<'_, 't> {
    /// Adds `mesh` to the batch. Returns its assembled triangles; its pixels are drawn later,
    /// in submission order. An index out of range fails the draw, and nothing of it is drawn.
    pub fn draw(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &RenderState<'t>,
    ) -> Result<DrawStats, RasterError> {
        self.add(mesh, None, transform, state)
    }

    /// `draw` for a mesh that outlives the batch: as the batch's first draw, its vertices are
    /// read where they are instead of copied (a 1280x720 frame's 220,900 vertices took 0.65 ms
    /// to copy, on every thread count). A mesh of more than one pass drawn on several threads
    /// is not assembled here but pass by pass in the flush, each pass beside the tiles of the
    /// one before (scene B's 439,922 triangles took about 1 ms to assemble, alone before any
    /// tile): its triangles are then counted in the batch's `finish`.
    pub(crate) fn draw_in_place(
        &mut self,
        mesh: &Mesh<'t>,
        transform: &Transform,
        state: &RenderState<'t>,
    ) -> Result<DrawStats, RasterError> {
        self.add(mesh, Some(*mesh), transform, state)
    }

    /// Adds a draw of `mesh`, which is `place` when it outlives the batch.
    fn add(
        &mut self,
        mesh: &Mesh,
        place: Option<Mesh<'t>>,
        transform: &Transform,
        state: &RenderState<'t>,
    ) -> Result<DrawStats, RasterError> {
        let scissor = Rect::scissor_on(state.scissor, self.fb.width(), self.fb.height())?;
        if state.precision != self.precision || self.deferred.is_some() {
            self.flush();
            self.precision = state.precision;
        }
        let r = &mut *self.rasterizer;
        let (first_vertex, first_triangle) = (r.pending.vertices.len(), r.pending.triangles.len());
        let in_place = place.is_some() && self.draws.is_empty();
        let empty = scissor.x0 == scissor.x1 || scissor.y0 == scissor.y1;
        let deferred = place.filter(|m| {
            in_place
                && !empty
                && m.vertices.len() <= m.indices.len()
                && m.indices.len() > r.pass_triangles
                && r.thread_count(m.indices.len()) > 1
                && indices_in_range(m)
        });
        let (triangles, left_in_place) = match deferred {
            Some(_) => (0, true),
            None => r.gather.append(mesh, &mut r.pending, in_place)?,
        };
        let stats = DrawStats {
            triangles: triangles as u64,
            ..DrawStats::default()
        };
        if deferred.is_none() && (triangles == 0 || empty) {
            r.pending.vertices.truncate(first_vertex);
            r.pending.triangles.truncate(first_triangle);
            return Ok(stats);
        }
        self.deferred = deferred;
        let has_depth = !matches!(self.fb.depth, DepthMut::None);
        let attrs = Attributes::new(state, has_depth);
        let views = match state.texture {
            Some(b) if attrs.tex != TexMode::Off => TexViews::new(b.texture, b.sampler.wrap),
            _ => TexViews::None,
        };
        if left_in_place {
            self.in_place = place.map(|m| m.vertices);
        }
        self.draws.push(PendingDraw {
            state: *state,
            attrs,
            scissor,
            transform: *transform,
            views,
            first_vertex,
            first_triangle,
        });
        if r.pending.triangles.len() >= FLUSH_TRIANGLES {
            self.flush();
        }
        Ok(stats)
    }

    /// Draws the edges of `mesh`'s triangles as lines (see [`Rasterizer::draw_edges`]), over
    /// everything drawn before them in the batch.
    pub fn draw_edges(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &LineState,
    ) -> Result<LineStats, RasterError> {
        self.flush();
        self.rasterizer
            .draw_edges(&mut self.fb, mesh, transform, state)
    }

    /// Draws what is pending and returns what the batch's draws rasterized: the triangles
    /// that reached the tiles and the fragments written (`triangles` is 0: each draw returned
    /// its own, but for a draw assembled in the flush, see `draw_in_place`).
    pub fn finish(mut self) -> DrawStats {
        self.flush();
        self.done
    }

    /// Draws every pending triangle.
    fn flush(&mut self) {
        if self.draws.is_empty() {
            return;
        }
        let r = &mut *self.rasterizer;
        let vertices = self.in_place.take().unwrap_or(&r.pending.vertices);
        let (source, size) = match self.deferred.take() {
            Some(mesh) => (Source::Mesh(mesh), mesh.indices.len()),
            None => (
                Source::Ready(&r.pending.triangles),
                r.pending.triangles.len(),
            ),
        };
        let geometry = (vertices, source);
        let threads = r.thread_count(size);
        let tile = r.tile_size.unwrap_or_else(|| {
            let bytes = self.fb.layout().bytes_per_pixel() + self.fb.depth_format().bytes();
            tile_size(threads, self.fb.width(), self.fb.height(), bytes as u32)
        });
        let pass = r.pass_triangles;
        let (assembled, rasterized, fragments) = match self.precision {
            Precision::Fixed => flush_with::<FixedPipeline>(
                &mut r.fixed,
                geometry,
                &self.draws,
                &mut self.fb,
                threads,
                (tile, pass, r.cpu),
            ),
            Precision::Float => flush_with::<FloatPipeline>(
                &mut r.float,
                geometry,
                &self.draws,
                &mut self.fb,
                threads,
                (tile, pass, r.cpu),
            ),
        };
        self.done.triangles += assembled;
        self.done.rasterized += rasterized;
        self.done.fragments += fragments;
        r.pending.vertices.clear();
        r.pending.triangles.clear();
        self.draws.clear();
    }
}

impl Drop for Batch<'_, '_> {
    /// A batch dropped without [`Batch::finish`] still draws its pixels.
    fn drop(&mut self) {
        self.flush();
    }
}

#[cfg(test)]
mod tests {
    use glam::{DMat4, DVec3};

    use crate::rasterizer::{PASS_TRIANGLES, SPLIT_TRIANGLES};
    use crate::{
        ColorFormat, DepthFormat, Fog, Framebuffer, Indices, Mesh, Perspective, Precision,
        Rasterizer, RenderState, Sampler, Shading, Texture, TextureBinding, Topology, Transform,
        Vertex, Wrap,
    };

    /// Hills seen from low down: triangles from a fraction of a pixel far away to a hundred
    /// pixels near the eye, so runs cross tile edges, and strips through the near plane.
    fn scene() -> (Vec<Vertex>, Vec<Vec<u32>>, Texture, Transform) {
        let g = 48usize;
        let mut v = vec![];
        for j in 0..g {
            for i in 0..g {
                let h = ((i as f64 * 0.4).sin() * (j as f64 * 0.3).cos() * 300.0) as i32;
                let c = (100.0 + 90.0 * (i as f64 * 0.2 + j as f64 * 0.1).sin()) as u8;
                let light = if (i + j) % 7 == 0 {
                    [c, 200, 255 - c]
                } else {
                    [c; 3]
                };
                v.push(Vertex::new(
                    [i as i32 * 400 - 9600, h, j as i32 * 400 - 9600],
                    [i as f32 / 6.0, j as f32 / 6.0],
                    light,
                ));
            }
        }
        // One strip per row of cells, each its own draw when the scene is split.
        let strips = (0..g - 1)
            .map(|j| {
                (0..g)
                    .flat_map(|i| [(j * g + i) as u32, ((j + 1) * g + i) as u32])
                    .collect()
            })
            .collect();
        let texels = (0..32 * 32)
            .map(|k| {
                [
                    (k % 32 * 8) as u8,
                    (k / 32 * 8) as u8,
                    ((k * 37) % 256) as u8,
                    255,
                ]
            })
            .collect();
        let texture = Texture::from_rgba8(32, 32, texels).unwrap().with_mipmaps();
        let m = glam::dcamera::rh::proj::directx::perspective(1.2, 4.0 / 3.0, 50.0, 4e4)
            * glam::dcamera::rh::view::look_at_mat4(
                DVec3::new(300.0, 700.0, 9000.0),
                DVec3::new(0.0, 0.0, 0.0),
                DVec3::Y,
            )
            * DMat4::IDENTITY;
        (v, strips, texture, Transform::new(m).unwrap())
    }

    /// The scene drawn with `tile`-pixel screen tiles and passes of `pass` triangles on
    /// `threads` threads, its strips grouped `per_draw` to a draw, all draws in one batch or
    /// (`batched` false) one by one.
    fn render(
        state: &RenderState,
        (tile, pass): (u32, usize),
        threads: usize,
        per_draw: usize,
        batched: bool,
    ) -> Framebuffer {
        let (v, strips, _, transform) = scene();
        on_threads(threads, (ColorFormat::Rgba8888, DepthFormat::D32), |fb| {
            // Split from the first triangle: a flush this small is otherwise drawn on one thread.
            let mut r = Rasterizer::new()
                .with_split_from(0)
                .with_pass_triangles(pass)
                .with_tile_size(tile);
            let draws: Vec<Vec<u32>> = strips
                .chunks(per_draw)
                .map(|group| group.join(&u32::MAX))
                .collect();
            fn mesh<'a>(v: &'a [Vertex], indices: &'a [u32]) -> Mesh<'a> {
                Mesh {
                    vertices: v,
                    indices: Indices::U32(indices),
                    topology: Topology::TriangleStrip,
                }
            }
            if batched {
                let mut batch = r.batch(fb);
                for d in &draws {
                    batch.draw(&mesh(&v, d), &transform, state).unwrap();
                }
                batch.finish();
            } else {
                for d in &draws {
                    r.draw(fb, &mesh(&v, d), &transform, state).unwrap();
                }
            }
        })
    }

    /// A 200x150 framebuffer in `formats`, cleared, after `f` drew into it on a pool of
    /// `threads` threads.
    fn on_threads(
        threads: usize,
        formats: (ColorFormat, DepthFormat),
        f: impl FnOnce(&mut Framebuffer) + Send,
    ) -> Framebuffer {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            let mut fb = Framebuffer::new(200, 150, formats.0, formats.1).unwrap();
            fb.clear([10, 20, 30]);
            f(&mut fb);
            fb
        })
    }

    #[test]
    fn tiles_batches_and_threads_do_not_change_a_byte() {
        let (_, _, texture, _) = scene();
        for precision in [Precision::Fixed, Precision::Float] {
            for perspective in [
                Perspective::Spans(8),
                Perspective::Exact,
                Perspective::Affine,
            ] {
                let state = RenderState {
                    precision,
                    perspective,
                    shading: Shading::Gouraud,
                    texture: Some(TextureBinding::new(
                        &texture,
                        Sampler {
                            wrap: Wrap::Repeat,
                            ..Sampler::BILINEAR_MIPMAP
                        },
                    )),
                    fog: Some(Fog {
                        color: [10, 20, 30],
                        start: 3000.0,
                        end: 20000.0,
                    }),
                    ..RenderState::default()
                };
                // One tile for the whole screen, one pass, one thread, one draw: no run is
                // ever cut, and every triangle is set up before any is drawn.
                let whole = render(&state, (1 << 13, usize::MAX), 1, usize::MAX, true);
                assert!(
                    whole
                        .to_rgba_image()
                        .pixels()
                        .filter(|p| p.0 != [10, 20, 30, 255])
                        .count()
                        > 200 * 150 / 2,
                    "the scene covers most of the screen"
                );
                // The scene has 4,418 triangles: passes of 97 to 1,000 are set up while the
                // pass before them is drawn, and cut draws anywhere.
                for (tile, pass, threads, per_draw, batched) in [
                    (64, PASS_TRIANGLES, 1, usize::MAX, true),
                    (128, PASS_TRIANGLES, 2, 4, true),
                    (8, PASS_TRIANGLES, 1, 1, true),
                    (16, PASS_TRIANGLES, 2, 5, true),
                    (64, PASS_TRIANGLES, 4, 3, true),
                    (32, PASS_TRIANGLES, 2, 2, false),
                    (64, 1000, 1, usize::MAX, true),
                    (64, 300, 2, usize::MAX, true),
                    (64, 300, 2, usize::MAX, false),
                    (128, PASS_TRIANGLES, 1, usize::MAX, false),
                    (16, 97, 4, 3, true),
                    (32, 1000, 2, 2, false),
                ] {
                    assert!(
                        render(&state, (tile, pass), threads, per_draw, batched) == whole,
                        "{precision:?} {perspective:?}: tiles of {tile}, passes of {pass}, \
                         {threads} threads, {per_draw} strips a draw, batched {batched}"
                    );
                }
            }
        }
    }

    /// On several threads a pass transforms only the vertices up to the largest its triangles
    /// use, beside the tiles of the pass before it: strips out of order, whose passes use
    /// vertices far behind and far ahead of the earlier passes', draw as on one thread in one pass.
    #[test]
    fn passes_out_of_vertex_order_draw_the_same_bytes() {
        let (v, strips, _, transform) = scene();
        let order = (30..strips.len()).chain(10..30).rev().chain(0..10);
        let indices: Vec<u32> = order
            .map(|j| strips[j].clone())
            .collect::<Vec<_>>()
            .join(&u32::MAX);
        let mesh = Mesh {
            vertices: &v,
            indices: Indices::U32(&indices),
            topology: Topology::TriangleStrip,
        };
        let state = RenderState {
            shading: Shading::Gouraud,
            ..RenderState::default()
        };
        let draw = |threads: usize, pass: usize| {
            on_threads(threads, (ColorFormat::Rgb565, DepthFormat::D16), |fb| {
                let mut r = Rasterizer::new()
                    .with_split_from(0)
                    .with_pass_triangles(pass);
                r.draw(fb, &mesh, &transform, &state).unwrap();
            })
        };
        let whole = draw(1, usize::MAX);
        for (threads, pass) in [(2, 97), (2, 500), (3, 1000)] {
            assert!(
                draw(threads, pass) == whole,
                "{threads} threads, passes of {pass}"
            );
        }
    }

    /// On several threads a lone draw of more than one pass is assembled pass by pass in the
    /// flush: it counts its triangles, draws its bytes and fails on an index out of range (with
    /// nothing drawn) as one assembly on one thread does. The strip ends in degenerate triangles,
    /// so its last pass assembles none.
    #[test]
    fn a_draw_assembled_pass_by_pass_counts_draws_and_fails_as_one_assembly() {
        let (v, strips, _, transform) = scene();
        let mut indices = strips.join(&u32::MAX);
        indices.push(u32::MAX);
        indices.extend([5; 300]);
        let state = RenderState {
            shading: Shading::Gouraud,
            ..RenderState::default()
        };
        let draw = |threads: usize, pass: usize, indices: &[u32]| {
            let mut result = None;
            let fb = on_threads(threads, (ColorFormat::Rgb565, DepthFormat::D16), |fb| {
                let mut r = Rasterizer::new()
                    .with_split_from(0)
                    .with_pass_triangles(pass);
                let mesh = Mesh {
                    vertices: &v,
                    indices: Indices::U32(indices),
                    topology: Topology::TriangleStrip,
                };
                result = Some(r.draw(fb, &mesh, &transform, &state));
            });
            (result.unwrap(), fb)
        };
        let (one, whole) = draw(1, usize::MAX, &indices);
        let one = one.unwrap();
        assert_eq!(one.triangles, 4418);
        assert!(one.rasterized > 1000 && one.fragments > 10_000, "{one:?}");
        for (threads, pass) in [(2, 97), (2, 4418), (3, 1000)] {
            let (stats, fb) = draw(threads, pass, &indices);
            assert_eq!(stats.unwrap(), one, "{threads} threads, passes of {pass}");
            assert!(fb == whole, "{threads} threads, passes of {pass}");
        }
        // An index one past the vertices, after thousands of good triangles.
        let at = indices.len() - 400;
        indices[at] = v.len() as u32;
        let (failed, untouched) = draw(1, usize::MAX, &indices);
        assert!(failed.is_err());
        for (threads, pass) in [(2, 97), (3, 1000)] {
            let (result, fb) = draw(threads, pass, &indices);
            assert_eq!(result, failed, "{threads} threads, passes of {pass}");
            assert!(
                fb == untouched,
                "nothing drawn: {threads} threads, passes of {pass}"
            );
        }
        let image = untouched.to_rgba_image();
        let clear = image.get_pixel(0, 0).0;
        assert!(image.pixels().all(|p| p.0 == clear));
    }

    #[test]
    fn a_flush_too_small_to_split_stays_on_the_calling_thread() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        pool.install(|| {
            let r = Rasterizer::with_threads(2);
            assert_eq!(r.thread_count(SPLIT_TRIANGLES - 1), 1);
            assert_eq!(r.thread_count(SPLIT_TRIANGLES), 2);
            let r = Rasterizer::with_threads(2).with_split_from(10);
            assert_eq!((r.thread_count(9), r.thread_count(10)), (1, 2));
            assert_eq!(Rasterizer::with_threads(1).thread_count(1 << 20), 1);
        });
    }
}
