//! Code shared by the integration tests (and, through `#[path]`, the benchmarks).

pub mod crack_scene;
pub mod golden;
pub mod hills;
pub mod scene;
