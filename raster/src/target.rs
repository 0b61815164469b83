//! One draw interface for every backend: the host builds its draw list once and sends it to the
//! CPU rasterizer or to any other [`DrawTarget`] (the wgpu comparison backend of
//! `stripmask-platform`) without a second renderer.
//!
//! The trait is called once per draw, so dynamic dispatch would cost one call per draw; the hot
//! loops stay inside [`Rasterizer::draw`], monomorphised as before.

use crate::RasterError;
use crate::draw::{DrawStats, Rasterizer};
use crate::framebuffer::Framebuffer;
use crate::lines::{LineState, LineStats};
use crate::matrix::Transform;
use crate::state::RenderState;
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
}

/// The CPU rasterizer drawing into a framebuffer.
#[derive(Debug)]
pub struct RasterTarget<'a> {
    /// The picture.
    pub framebuffer: &'a mut Framebuffer,
    /// The rasterizer with its scratch buffers.
    pub rasterizer: &'a mut Rasterizer,
}

impl<'a> RasterTarget<'a> {
    /// `rasterizer` drawing into `framebuffer`.
    pub fn new(framebuffer: &'a mut Framebuffer, rasterizer: &'a mut Rasterizer) -> Self {
        Self {
            framebuffer,
            rasterizer,
        }
    }
}

impl DrawTarget for RasterTarget<'_> {
    type Error = RasterError;

    fn size(&self) -> (u32, u32) {
        (self.framebuffer.width(), self.framebuffer.height())
    }

    fn clear(&mut self, color: [u8; 3]) {
        self.framebuffer.clear(color);
    }

    fn draw(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &RenderState,
    ) -> Result<DrawStats, RasterError> {
        self.rasterizer
            .draw(self.framebuffer, mesh, transform, state)
    }

    fn draw_edges(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &LineState,
    ) -> Result<LineStats, RasterError> {
        self.rasterizer
            .draw_edges(self.framebuffer, mesh, transform, state)
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
    use crate::{ColorFormat, DepthFormat, Indices, Shading, Topology, Vertex};

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
