//! The integration tests of `stripmask`, one module per behaviour, linked into one binary.
//! `cargo test --test it MODULE` runs one module.

mod support;

mod allocation;
mod archive_changed;
mod archive_corrupt;
mod archive_fuzz;
mod archive_levels;
mod archive_roundtrip;
mod archive_texture_codecs;
#[cfg(unix)]
mod boards;
mod build_safety;
mod cli_build_info;
mod cli_demo;
mod cli_flags;
mod cli_serve;
mod crack_switch;
mod cracks;
mod dem_big;
mod dem_bombs;
mod dem_formats;
mod dem_fuzz;
mod dem_geographic;
mod dem_mosaic;
mod dem_nodata;
mod embed;
mod engine;
mod error_bound;
mod extremes_engine;
mod fetch_cancel;
mod fetch_deadline;
mod fly_holes;
mod geomorph;
mod georef;
#[cfg(feature = "wgpu")]
mod gpu_engine;
mod layers;
mod lean_library;
mod nginx;
mod padding;
mod pager_archive;
mod pager_flight;
mod pager_simulated;
mod partial_tiles;
mod pocketpc;
mod pocketpc_http;
mod pyramid_cracks;
mod seams;
mod serve_attacks;
mod serve_http;
mod serve_limits;
mod source_http;
mod stream_compare;
mod stream_engine;
mod stream_pager;
mod top;
mod tradeoff;
mod wireframe;
