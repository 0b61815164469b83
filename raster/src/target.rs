//! One draw interface for every backend: the host builds its draw list once and sends it to the
//! CPU rasterizer or to any other [`DrawTarget`] (the wgpu comparison backend of
//! `stripmask-platform`) without a second renderer.
//!
//! The trait is called once per draw, so dynamic dispatch would cost one call per draw; the hot
//! loops stay inside the rasterizer, monomorphised as before. A host that makes many draws per
//! frame hands them over in one [`DrawTarget::batch`], so that a target may draw them together
//! (the CPU rasterizer bins them into screen tiles across draws and threads).

use crate::RasterError;
use crate::batch::Batch;
use crate::lines::{LineState, LineStats};
use crate::matrix::Transform;
use crate::rasterizer::{DrawStats, Rasterizer};
use crate::state::RenderState;
use crate::surface::Surface;
use crate::vertex::{Mesh, assemble};

/// Something that draws meshes into a picture of a fixed size.
pub trait DrawTarget {
    /// What a draw can fail with; every target can at least report the rasterizer's input errors.
    type Error: From<RasterError> + std::error::Error;

    /// Width and height in pixels (the host needs the aspect ratio for its projection).
    fn size(&self) -> (u32, u32);

    /// Fills the colour with `color` and resets depth to the far plane.
    fn clear(&mut self, color: [u8; 3]);

    /// Draws `mesh` with `transform` and `state`, in submission order after earlier draws.
    fn draw(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &RenderState,
    ) -> Result<DrawStats, Self::Error>;

    /// Draws each edge of `mesh`'s triangles once as a line (a wireframe), after earlier draws.
    fn draw_edges(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &LineState,
    ) -> Result<LineStats, Self::Error>;

    /// Runs `draws`, which makes its draws through the [`DrawBatch`] it is given: one frame's
    /// draw list handed over at once, so that the target may draw them together. Returns what
    /// `draws` returned and the statistics that only the end of the batch knows (a deferring
    /// target's rasterized triangles and fragments: add them to the draws' own). The textures
    /// of the batch's draws stay borrowed until it ends.
    ///
    /// By default every draw runs at once, as [`DrawTarget::draw`] would run it.
    fn batch<'t, R>(
        &mut self,
        draws: impl FnOnce(&mut dyn DrawBatch<'t, Error = Self::Error>) -> Result<R, Self::Error>,
    ) -> Result<(R, DrawStats), Self::Error>
    where
        Self: Sized,
    {
        Ok((draws(&mut Immediate(self))?, DrawStats::default()))
    }
}

/// Draws submitted to a [`DrawTarget::batch`]: the textures of its draws live for `'t`.
pub trait DrawBatch<'t> {
    /// What a draw can fail with.
    type Error;

    /// Adds `mesh`, drawn with `transform` and `state` after the batch's earlier draws. What a
    /// deferring target has not drawn yet is counted at the end of the batch instead.
    fn draw(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &RenderState<'t>,
    ) -> Result<DrawStats, Self::Error>;

    /// Draws each edge of `mesh`'s triangles once as a line, over the batch's earlier draws.
    fn draw_edges(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &LineState,
    ) -> Result<LineStats, Self::Error>;
}

/// A target's draws made one by one, as they come: the default batch.
struct Immediate<'a, T>(&'a mut T);

impl<'t, T: DrawTarget> DrawBatch<'t> for Immediate<'_, T> {
    type Error = T::Error;

    fn draw(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &RenderState<'t>,
    ) -> Result<DrawStats, T::Error> {
        self.0.draw(mesh, transform, state)
    }

    fn draw_edges(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &LineState,
    ) -> Result<LineStats, T::Error> {
        self.0.draw_edges(mesh, transform, state)
    }
}

impl<'t> DrawBatch<'t> for Batch<'_, 't> {
    type Error = RasterError;

    fn draw(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &RenderState<'t>,
    ) -> Result<DrawStats, RasterError> {
        Batch::draw(self, mesh, transform, state)
    }

    fn draw_edges(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &LineState,
    ) -> Result<LineStats, RasterError> {
        Batch::draw_edges(self, mesh, transform, state)
    }
}

/// The CPU rasterizer drawing into a [`crate::Framebuffer`] or into a [`Surface`] of memory the
/// caller owns.
#[derive(Debug)]
pub struct RasterTarget<'a> {
    /// The picture.
    pub surface: Surface<'a>,
    /// The rasterizer with its scratch buffers.
    pub rasterizer: &'a mut Rasterizer,
}

impl<'a> RasterTarget<'a> {
    /// `rasterizer` drawing into `picture`: `&mut Framebuffer` or a [`Surface`].
    pub fn new(picture: impl Into<Surface<'a>>, rasterizer: &'a mut Rasterizer) -> Self {
        Self {
            surface: picture.into(),
            rasterizer,
        }
    }
}

impl DrawTarget for RasterTarget<'_> {
    type Error = RasterError;

    fn size(&self) -> (u32, u32) {
        (self.surface.width(), self.surface.height())
    }

    fn clear(&mut self, color: [u8; 3]) {
        self.surface.clear(color);
    }

    fn draw(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &RenderState,
    ) -> Result<DrawStats, RasterError> {
        self.rasterizer
            .draw(&mut self.surface, mesh, transform, state)
    }

    fn draw_edges(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &LineState,
    ) -> Result<LineStats, RasterError> {
        self.rasterizer
            .draw_edges(&mut self.surface, mesh, transform, state)
    }

    /// The draws go into one [`Batch`]: set up and binned across draws, their tiles drawn when
    /// `draws` returns.
    fn batch<'t, R>(
        &mut self,
        draws: impl FnOnce(&mut dyn DrawBatch<'t, Error = RasterError>) -> Result<R, RasterError>,
    ) -> Result<(R, DrawStats), RasterError> {
        let mut batch = self.rasterizer.batch(&mut self.surface);
        let r = draws(&mut batch)?;
        Ok((r, batch.finish()))
    }
}

/// The non-degenerate triangles `mesh` describes, counted as [`Rasterizer::draw`] assembles
/// them, or the first index out of range: other targets validate and count their input the same
/// way, so their [`DrawStats::triangles`] and errors match the CPU's.
pub fn count_triangles(mesh: &Mesh) -> Result<u64, RasterError> {
    let mut n = 0u64;
    assemble(mesh, |_| n += 1).map_err(|(position, value)| RasterError::IndexOutOfRange {
        position,
        value,
        vertices: mesh.vertices.len(),
    })?;
    Ok(n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{ColorFormat, DepthFormat, Framebuffer, Indices, Shading, Topology, Vertex};

    fn square() -> [Vertex; 4] {
        [
            Vertex::new([-1, -1, 0], [0.0, 0.0], [255, 0, 0]),
            Vertex::new([1, -1, 0], [1.0, 0.0], [0, 255, 0]),
            Vertex::new([-1, 1, 0], [0.0, 1.0], [0, 0, 255]),
            Vertex::new([1, 1, 0], [1.0, 1.0], [255, 255, 255]),
        ]
    }

    #[test]
    fn the_cpu_target_draws_what_the_rasterizer_draws() {
        let v = square();
        let mesh = Mesh {
            vertices: &v,
            indices: Indices::U16(&[0, 1, 2, 3]),
            topology: Topology::TriangleStrip,
        };
        let ortho = glam::dcamera::rh::proj::directx::orthographic(-1.0, 1.0, -1.0, 1.0, -1.0, 1.0);
        let transform = Transform::new(ortho).unwrap();
        let state = RenderState {
            shading: Shading::Gouraud,
            ..RenderState::default()
        };
        let mut direct = Framebuffer::new(16, 8, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
        direct.clear([9, 9, 9]);
        let expected = Rasterizer::new()
            .draw(&mut direct, &mesh, &transform, &state)
            .unwrap();

        let mut fb = Framebuffer::new(16, 8, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
        let mut rasterizer = Rasterizer::new();
        let mut target = RasterTarget::new(&mut fb, &mut rasterizer);
        assert_eq!(target.size(), (16, 8));
        target.clear([9, 9, 9]);
        assert_eq!(target.draw(&mesh, &transform, &state).unwrap(), expected);
        assert_eq!(expected.fragments, 16 * 8);
        assert_eq!(fb, direct);
    }

    #[test]
    fn a_batch_draws_what_its_draws_would_draw_one_by_one() {
        let v = square();
        let strip = [0u16, 1, 2, 3];
        let mesh = Mesh {
            vertices: &v,
            indices: Indices::U16(&strip),
            topology: Topology::TriangleStrip,
        };
        let ortho = glam::dcamera::rh::proj::directx::orthographic(-1.0, 1.0, -1.0, 1.0, -1.0, 1.0);
        let near = Transform::new(ortho).unwrap();
        let far =
            Transform::new(glam::DMat4::from_translation(glam::DVec3::new(0.25, 0.0, 0.5)) * ortho)
                .unwrap();
        let gouraud = RenderState {
            shading: Shading::Gouraud,
            ..RenderState::default()
        };
        let flat = RenderState::default();
        let mut one_by_one =
            Framebuffer::new(16, 8, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
        let mut expected = DrawStats::default();
        let mut rasterizer = Rasterizer::new();
        for (t, s) in [(&far, &flat), (&near, &gouraud), (&far, &gouraud)] {
            expected += rasterizer.draw(&mut one_by_one, &mesh, t, s).unwrap();
        }
        let mut fb = Framebuffer::new(16, 8, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
        let mut target = RasterTarget::new(&mut fb, &mut rasterizer);
        let (drawn, done) = target
            .batch(|b| {
                let mut drawn = DrawStats::default();
                for (t, s) in [(&far, &flat), (&near, &gouraud), (&far, &gouraud)] {
                    drawn += b.draw(&mesh, t, s)?;
                }
                Ok(drawn)
            })
            .unwrap();
        assert_eq!(
            drawn.fragments, 0,
            "a batch counts its fragments at its end"
        );
        let mut total = drawn;
        total += done;
        assert_eq!(total, expected);
        assert_eq!(fb, one_by_one);
    }

    #[test]
    fn triangles_are_counted_and_bad_indices_reported_as_the_rasterizer_does() {
        let v = square();
        let strip = Mesh {
            vertices: &v,
            indices: Indices::U32(&[0, 1, 2, 2, 3, u32::MAX, 1, 2, 3]),
            topology: Topology::TriangleStrip,
        };
        assert_eq!(count_triangles(&strip), Ok(2));
        let bad = Mesh {
            indices: Indices::U16(&[0, 1, 9]),
            ..strip
        };
        assert_eq!(
            count_triangles(&bad),
            Err(RasterError::IndexOutOfRange {
                position: 2,
                value: 9,
                vertices: 4
            })
        );
    }
}
