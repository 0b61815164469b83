//! The client: pages tiles in belts under a memory limit, cuts each frame's view through the
//! pyramid of tiles and draws it with a strip mask per tile under a triangle budget.

pub mod allocation;
pub mod budget;
pub mod camera;
mod client;
pub mod cracks;
pub mod cut;
pub mod error_bound;
#[cfg(test)]
mod fake_holdings;
pub mod frustum;
pub mod geomorph;
pub mod importance;
#[cfg(feature = "lab")]
mod instruments;
pub mod masks;
mod memory;
mod normals;
pub mod paging;
pub mod partial_meshes;
mod plan;
pub mod render;
mod report;
pub mod resident;
mod settings;
pub mod shading;
pub mod terrain;
pub mod viewport;
mod wants;

pub use client::Engine;
pub use memory::index_allowance;
pub use report::{FrameReport, RenderedTile};
pub use settings::{EngineSettings, FrameTiming};
