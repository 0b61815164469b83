//! Code shared by the integration tests.

pub mod cli;
pub mod crack_scene;
pub mod golden;
pub mod hills;
