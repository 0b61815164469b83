//! Code shared by the integration tests.

#[path = "../../../examples/support/attack.rs"]
pub mod attack;
pub mod cli;
pub mod crack_scene;
pub mod fake_http;
pub mod golden;
pub mod hills;
pub mod tiff_writer;
