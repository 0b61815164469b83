//! The integration tests of `stripmask-raster`, one module per behaviour, linked into one binary.

mod common;
mod golden_check;
mod scene;

mod determinism;
mod extremes;
mod finest_level;
mod golden;
mod lines;
mod surface;
mod watertight;
