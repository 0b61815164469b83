//! stripmask: adaptive streaming and CPU rendering of large terrains with strip masks.
//!
//! The terrain database side: [`dem`] readers stream elevation rows from PNG, GeoTIFF, SRTM
//! `.hgt`, ESRI ASCII grids and raw files; [`builder`] cuts them into tiles of `2^n + 1` samples
//! with shared borders ([`tiling`]), encodes each [`tile`] (quantised heights, per-level errors,
//! an RGB565 texture with mipmaps) and writes a single-file [`archive`]. A [`source`] reads that
//! archive back from a local file or over HTTP range requests, and [`serve`] is a small static
//! server for it.
//!
//! The client side, the paper's engine: a [`pager`] keeps the largest complete square of
//! [`belts`] of [`resident`] tiles that fits a memory limit (fetched by the [`loader`] on a fetch
//! thread); each frame the [`engine`] culls tiles against the [`frustum`], weighs them by visual
//! [`importance`], shares a triangle [`budget`] that holds a target frame rate, picks a strip mask
//! per tile from the shared [`masks`], and [`render`]s them through `stripmask-raster` with one
//! eye-relative matrix. [`camera`], [`flight`] paths, [`stats`], the [`fly`] command and the
//! interactive [`viewer`] drive it. [`cracks`] hides the gaps between tiles at different
//! levels, [`geomorph`] optionally morphs the vertices coarser levels drop, and [`popping`]
//! measures how much the picture jumps when a tile switches level.
#![warn(missing_docs)]

pub mod archive;
pub mod belts;
pub mod budget;
pub mod builder;
pub mod camera;
pub mod cracks;
pub mod dem;
pub mod demo;
pub mod engine;
pub mod error;
pub mod flight;
pub mod fly;
pub mod frustum;
pub mod geomorph;
pub mod held_meshes;
pub mod importance;
pub mod level_error;
pub mod loader;
pub mod mask_level;
pub mod masks;
pub mod pager;
pub mod paging;
pub mod popping;
pub mod profile;
pub mod render;
pub mod report;
pub mod resident;
pub mod rgb565;
pub mod serve;
pub mod simclock;
pub mod source;
pub mod stats;
pub mod stream;
pub mod terrain;
pub mod texture_gen;
pub mod tile;
pub mod tiling;
pub mod tradeoff;
pub mod viewer;

pub use error::{Error, Result};
