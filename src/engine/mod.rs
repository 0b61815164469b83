//! The client: pages tiles in belts under a memory limit, cuts each frame's view through the
//! pyramid of tiles and draws it with a strip mask per tile under a triangle budget.

pub mod allocation;
pub mod budget;
pub mod camera;
mod client;
pub mod cracks;
pub mod cut;
pub mod error_bound;
pub mod frustum;
pub mod geomorph;
pub mod importance;
pub mod masks;
pub mod paging;
pub mod partial_meshes;
pub mod render;
pub mod resident;
pub mod terrain;

pub use client::*;
