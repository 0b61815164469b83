//! A fixed-point triangle-strip rasterizer for CPUs without a GPU (or an FPU), with an f32
//! reference twin behind the same API.
//!
//! Think of it as a tiny OpenGL ES 1.x that draws indexed triangle strips into a [`Framebuffer`],
//! or into memory the caller owns (a mapped `/dev/fb0`, a toolkit's buffer) as a [`Surface`]:
//! build a [`Transform`] from the host's f64 matrix once per draw, describe the vertices and
//! indices as a [`Mesh`], name the features the draw uses in a [`RenderState`], and call
//! [`Rasterizer::draw`]. The state picks a specialised inner loop, so depth, texture, shading or
//! fog that a draw does not use cost nothing. Everything is deterministic: the same draws give the
//! same bytes on any thread count.
//!
//! Exactness: vertices snap to a 1/256-pixel grid, coverage is decided by exact integer edge
//! functions with the top-left rule (no cracks, no double hits on shared edges), triangles are
//! clipped in homogeneous space against near/far planes and a guard band, and no finite input
//! can overflow an integer (the widths are derived in [`fixed_point`]).
//!
//! ```
//! use stripmask_raster::*;
//! let mut fb = Framebuffer::new(64, 64, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
//! let v = [
//!     Vertex::new([-1, -1, 0], [0.0, 0.0], [255, 0, 0]),
//!     Vertex::new([1, -1, 0], [1.0, 0.0], [0, 255, 0]),
//!     Vertex::new([-1, 1, 0], [0.0, 1.0], [0, 0, 255]),
//!     Vertex::new([1, 1, 0], [1.0, 1.0], [255, 255, 255]),
//! ];
//! let mesh = Mesh { vertices: &v, indices: Indices::U16(&[0, 1, 2, 3]), topology: Topology::TriangleStrip };
//! let ortho = glam::dcamera::rh::proj::directx::orthographic(-1.0, 1.0, -1.0, 1.0, -1.0, 1.0);
//! let state = RenderState { shading: Shading::Gouraud, ..RenderState::default() };
//! let stats = Rasterizer::new().draw(&mut fb, &mesh, &Transform::new(ortho).unwrap(), &state).unwrap();
//! assert_eq!(stats.fragments, 64 * 64);
//! ```

mod attributes;
mod batch;
mod bin;
mod clip;
mod depth_buffer;
mod edge;
mod error;
pub mod fixed_point;
mod fragments;
mod framebuffer;
mod isa;
mod lanes;
mod layout;
mod lines;
mod matrix;
mod pending;
mod pipeline;
mod pixel;
mod rasterizer;
mod sampler;
mod setup;
mod shade;
mod small;
mod state;
mod surface;
mod target;
mod texture;
mod tile_view;
mod vertex;

pub use batch::Batch;
pub use depth_buffer::{DepthBuffer, DepthFormat};
pub use error::{RasterError, SurfaceError};
pub use framebuffer::{ColorBuffer, ColorFormat, Framebuffer};
pub use isa::InstructionSet;
pub use layout::PixelLayout;
pub use lines::{LineDepth, LineState, LineStats};
pub use matrix::{FixedMat4, MAX_ORIGIN, Transform};
pub use pixel::{rgb_to_rgb565, rgb565_to_rgb};
pub use rasterizer::{DrawStats, Rasterizer};
pub use state::{
    Compare, CullMode, DepthMode, Fog, FrontFace, Perspective, Precision, Rect, RenderState,
    Shading, TextureBinding,
};
pub use surface::{AsSurface, Surface};
pub use target::{DrawBatch, DrawTarget, RasterTarget, count_triangles};
pub use texture::{
    Filter, MipFilter, MipLevel, Sampler, Texels, Texture, TextureFormat, Wrap, box_mip_chain,
};
pub use vertex::{Indices, Mesh, Topology, Vertex};
