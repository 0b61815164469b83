//! Code shared by the integration tests.

pub mod cli;
pub mod crack_scene;
pub mod fake_http;
pub mod golden;
pub mod hills;
