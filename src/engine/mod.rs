//! The client: pages tiles in belts under a memory limit and draws each frame with a strip mask
//! per tile under a triangle budget.

pub mod belts;
pub mod budget;
pub mod camera;
mod client;
pub mod cracks;
pub mod frustum;
pub mod geomorph;
pub mod held_meshes;
pub mod importance;
pub mod loader;
pub mod masks;
pub mod pager;
pub mod paging;
pub mod render;
pub mod resident;
pub mod stream;
pub mod terrain;

pub use client::*;
