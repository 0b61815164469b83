//! stripmask: adaptive streaming and CPU rendering of large terrains with strip masks.
//!
//! Three layers, each using only those below it:
//!
//! - [`db`], the terrain database: [`db::dem`] readers stream elevation rows from PNG, GeoTIFF,
//!   SRTM `.hgt`, ESRI ASCII grids and raw files; [`db::builder`] cuts them into tiles of
//!   `2^n + 1` samples with shared borders (`db::tiling`), encodes each [`db::tile`]
//!   (quantised heights, per-level errors, an RGB565 texture with mipmaps) and writes a
//!   single-file [`db::archive`]. A [`db::source`] reads that archive back from a local file or
//!   over HTTP range requests, and [`db::server`] is a small static server for it.
//! - [`engine`], the paper's client: a pager keeps the largest complete square of belts of
//!   resident tiles that fits a memory limit; each frame the engine culls tiles against the
//!   frustum, weighs them by visual importance, shares a triangle budget that holds a target
//!   frame rate, picks a strip mask per tile and renders them through `stripmask-raster` with
//!   one eye-relative matrix, hiding the cracks between tiles at different levels.
//! - [`sim`], the laboratory: device profiles, a simulated clock and link, flight paths,
//!   per-frame statistics and reports, the `fly` runner and the interactive viewer, the
//!   speed/accuracy trade-off, popping and crack metrics, the streaming comparison and the demo.
//!
//! The items re-exported here are the library's surface: build an archive from an elevation
//! model, open it from a file or URL, fly an [`Engine`] over it and draw frames into a
//! `stripmask_raster::Framebuffer`, or run a whole recorded flight with [`fly`]. The layer
//! modules stay public for tools and tests that reach into one algorithm (the belts, the
//! masks, the budget); their other items follow the code, not a compatibility promise.

pub mod db;
pub mod engine;
pub mod error;
pub mod named;
pub mod sim;

pub use db::archive::{ArchiveReader, Codec, Header};
pub use db::builder::{BuildOptions, BuildReport, build, build_file};
pub use db::dem::{DemFormat, OpenOptions, open as open_dem};
pub use db::grid::TileId;
pub use db::server::Server;
pub use db::source::{TileSource, open as open_source};
pub use engine::allocation::Allocation;
pub use engine::camera::Camera;
pub use engine::cracks::CrackMode;
pub use engine::error_bound::{Bound, ErrorBound};
pub use engine::geomorph::Geomorph;
pub use engine::paging::PagerMode;
pub use engine::paging::stream::{StreamSettings, Streaming};
pub use engine::terrain::TerrainFrame;
pub use engine::{Engine, EngineSettings, FrameReport, RenderedTile};
pub use error::{Error, Result};
pub use named::Named;
pub use sim::clock::Clock;
pub use sim::device::DeviceProfile;
pub use sim::flight::{Builtin, Flight};
pub use sim::fly::{FlyOptions, FlySummary, fly};
pub use sim::viewer::{ViewerOptions, ViewerSummary, run as run_viewer};
