//! The integration tests of `stripmask-raster`, one module per behaviour, linked into one binary.

mod common;

mod determinism;
mod extremes;
mod finest_level;
mod lines;
mod watertight;
