//! Code shared by the integration tests and benchmarks.

pub mod golden;
pub mod scene;
