//! stripmask: adaptive streaming and CPU rendering of large terrains with strip masks.
//!
//! Three layers, each using only those below it:
//!
//! - [`db`], the terrain database: [`db::dem`] readers stream elevation rows from PNG, GeoTIFF,
//!   SRTM `.hgt`, ESRI ASCII grids and raw files; [`db::builder`] cuts them into tiles of
//!   `2^n + 1` samples with shared borders (`db::tiling`), encodes each [`db::tile`]
//!   (quantised heights, per-level errors, an RGB565 texture with mipmaps) and writes a
//!   single-file [`db::archive`]. A [`db::source`] reads that archive back from a local file or
//!   over HTTP range requests (the `http` feature), and `db::server` (the `server` feature) is a
//!   small static server for it.
//! - [`engine`], the paper's client: a pager keeps the largest complete square of belts of
//!   resident tiles that fits a memory limit; each frame the engine culls tiles against the
//!   frustum, weighs them by visual importance, shares a triangle budget that holds a target
//!   frame rate, picks a strip mask per tile and renders them through `stripmask-raster` with
//!   one eye-relative matrix, hiding the cracks between tiles at different levels.
//! - [`sim`], the laboratory: device profiles, a simulated clock and link, flight paths, and
//!   with the `lab` feature per-frame statistics and reports, the `fly` runner and the
//!   interactive viewer, the speed/accuracy trade-off, popping and crack metrics, the streaming
//!   comparison and the demo.
//!
//! The items re-exported here are the library's surface: build an archive from an elevation
//! model, open it from a file or URL, fly an [`Engine`] over it and draw frames into a
//! [`Framebuffer`], or (with the `lab` feature) run a whole recorded flight with `fly`. The layer
//! modules stay public for tools and tests that reach into one algorithm (the belts, the
//! masks, the budget); their other items follow the code, not a compatibility promise.
//!
//! An application draws terrain into its own framebuffer with its own camera
//! (`examples/embed.rs` is the same as a program):
//!
//! ```
//! use stripmask::{Camera, ColorFormat, DVec3, DepthFormat, Engine, EngineSettings, Framebuffer};
//! use stripmask::{PagerMode, Viewport, open_source};
//! # use stripmask::db::dem::{MemoryReader, NodataFill};
//! # let dir = tempfile::tempdir()?;
//! # let path = dir.path().join("hills.smdb");
//! # let hills = (0..129 * 129).map(|k| 300.0 * ((k % 129) as f32 / 20.0).sin()).collect();
//! # let options = stripmask::BuildOptions { tile_size: 33, spacing: Some(30.0), ..Default::default() };
//! # let hills = NodataFill::new(MemoryReader::new("hills", 129, 129, hills)?, None);
//! # stripmask::build(hills, &path, &options, &|_, _| {})?;
//! # let archive = path.to_str().unwrap();
//! // An engine for a 320x240 viewport; tiles fetched a few a frame on this thread.
//! let settings = EngineSettings {
//!     pager_mode: PagerMode::Stepped { fetches_per_update: 16 },
//!     ..EngineSettings::default()
//! };
//! let mut engine = Engine::new(open_source(archive)?, settings, Viewport::new(320, 240))?;
//! let mut frame = Framebuffer::new(320, 240, ColorFormat::Rgb565, DepthFormat::D16)?;
//! // The caller's camera: 2 km above the model's north-west corner, looking south-east and
//! // banking 10° right; the engine draws it as given.
//! let eye = DVec3::new(0.0, 2000.0, 0.0);
//! let camera = Camera { roll: 0.17, ..Camera::looking_at(eye, DVec3::new(2000.0, 0.0, 2000.0)) };
//! // Frames until the view has settled: the first are sky where tiles have not arrived
//! // (`ready` says when none is), the next sharpen as finer tiles come (`settled`).
//! let mut frames = 0;
//! loop {
//!     // The engine times the frame; its budget holds the target frame rate.
//!     let report = engine.render(&camera, &mut frame)?;
//!     assert_eq!(report.view.camera, camera);
//!     frames += 1;
//!     if report.settled() {
//!         assert!(report.ready() && report.rendered_tiles > 0);
//!         break;
//!     }
//!     assert!(frames < 100, "the view settles");
//! }
//! # Ok::<(), Box<dyn std::error::Error>>(())
//! ```

#![forbid(unsafe_code)]

pub mod db;
pub mod engine;
pub mod error;
pub mod named;
pub mod sim;

pub use db::archive::{ArchiveReader, Codec, Header};
pub use db::builder::{BuildOptions, BuildReport, build, build_file};
pub use db::dem::{DemFormat, OpenOptions, open as open_dem};
pub use db::grid::TileId;
#[cfg(feature = "server")]
pub use db::server::Server;
pub use db::source::{TileSource, open as open_source};
pub use engine::allocation::Allocation;
pub use engine::camera::{Camera, View};
pub use engine::cracks::CrackMode;
pub use engine::error_bound::{Bound, ErrorBound};
pub use engine::geomorph::Geomorph;
pub use engine::paging::PagerMode;
pub use engine::paging::stream::{StreamSettings, Streaming};
pub use engine::terrain::TerrainFrame;
pub use engine::viewport::Viewport;
pub use engine::{Engine, EngineSettings, FrameReport, FrameTiming, RenderedTile};
pub use error::{Error, Result};
/// The vector types of the library's API (camera positions, terrain coordinates).
pub use glam;
pub use glam::DVec3;
pub use named::Named;
pub use sim::clock::Clock;
pub use sim::device::DeviceProfile;
pub use sim::flight::{Builtin, Flight};
#[cfg(feature = "lab")]
pub use sim::fly::{FlyOptions, FlySummary, fly};
#[cfg(feature = "lab")]
pub use sim::viewer::{ViewerOptions, ViewerSummary, run as run_viewer};
pub use stripmask_raster::{
    AsSurface, ColorFormat, DepthBuffer, DepthFormat, DrawTarget, Framebuffer, PixelLayout,
    RasterTarget, Surface,
};
