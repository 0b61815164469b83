//! One frame of the paper's client, end to end: page belts in, cut through the pyramid to the
//! tiles in view, weigh them by visual importance, share the triangle budget, pick a strip mask
//! per tile, draw.
//!
//! ```text
//! camera ──> cut (frustum, τ) ──> importance ──> budget ──> mask per tile ──> draw list ──> raster
//!               ^
//!        pager (top, belts, far field | levels) <── tile source
//! ```

use std::time::Instant;

use glam::DVec3;
use stripmask_raster::{AsSurface, DrawTarget, RasterTarget, Rasterizer};

use crate::db::archive::{ArchiveReader, Header};
use crate::db::grid::{Pyramid, TileId, TileMap};
use crate::db::source::TileSource;
use crate::db::tile::{finest_mask_for_levels, levels_for_mask, progressive_levels};
use crate::engine::allocation::Allocation;
use crate::engine::budget::{BudgetController, BudgetSettings, FrameCost};
use crate::engine::camera::{Camera, View};
use crate::engine::cracks::CrackMode;
use crate::engine::cracks::TileIndices;
use crate::engine::cut::{LastFrame, SPLIT_SHARE};
use crate::engine::error_bound::{Bound, ErrorBound};
use crate::engine::geomorph::Morpher;
use crate::engine::masks::{LevelSet, MaskSet};
use crate::engine::memory::{choose_top, index_allowance};
use crate::engine::paging::stream::{
    PredictedView, Predictor, StreamPager, StreamSettings, Streaming, Want,
};
use crate::engine::paging::{
    ArchiveLoader, BeltPager, PagerConfig, Paging, Residency, StreamStats, TileLoader, far_share,
};
use crate::engine::partial_meshes::PartialMeshes;
use crate::engine::plan::{FrameInputs, WATER_DECAY, plan_frame};
use crate::engine::render::{RenderSettings, TileMeshes, draw_tiles};
use crate::engine::report::{FrameReport, RenderedTile};
use crate::engine::resident::ResidentTile;
use crate::engine::settings::{
    EngineSettings, FrameTiming, check_memory_holds_something, check_morph_range, check_progressive,
};
use crate::engine::terrain::TerrainFrame;
use crate::engine::viewport::Viewport;
use crate::engine::wants::{Ahead, frame_wants};
use crate::error::{Error, Result};

/// The engine: an archive, its pager, the shared strip masks and the budget controller.
pub struct Engine {
    pub(super) terrain: TerrainFrame,
    pub(super) pager: Box<dyn Paging>,
    pub(super) pyramid: Pyramid,
    /// The viewpoint predictor when streaming progressively: it extrapolates the view to
    /// where requests arrive and, with prediction, a second ahead.
    pub(super) predictor: Option<Predictor>,
    pub(super) masks: MaskSet,
    pub(super) cracks: TileIndices,
    /// The masks and crack pieces of partial tiles, built per held side on first use.
    pub(super) partial: PartialMeshes,
    /// The geomorph state, `None` when geomorphing is off.
    pub(super) morpher: Option<Morpher>,
    /// Levels pinned per tile instead of the budget's choice (for measurements).
    pub(super) forced_levels: Option<Box<dyn Fn(TileId) -> usize + Send>>,
    pub(super) budget: BudgetController,
    /// The last frame's need when the error bound (not the budget) capped it, for the
    /// controller ([`BudgetController::record_needing`]).
    pub(super) need: Option<usize>,
    /// The error the last frame's budget left on screen, when the budget capped it (see
    /// [`FramePlan::water_px`]): the next frame's cut goes no deeper than it can use.
    pub(super) water_px: Option<f64>,
    /// What the last frame drew, for the next frame's cut when the budget capped it.
    pub(super) last_frame: LastFrame,
    pub(super) settings: EngineSettings,
    pub(super) rasterizer: Rasterizer,
    /// The screen and the field of view every frame is drawn for.
    pub(super) viewport: Viewport,
    /// The archive's header and name, which place latitudes and longitudes.
    pub(super) archive: (Header, String),
}

impl Engine {
    /// Opens `source` to draw frames of `viewport`: the targets it draws into have the
    /// viewport's size, and every frame its field of view.
    pub fn new(
        source: Box<dyn TileSource>,
        mut settings: EngineSettings,
        viewport: Viewport,
    ) -> Result<Self> {
        viewport.check()?;
        // The pager retries failed fetches, backing off: the reader tries each once.
        let reader = ArchiveReader::open(source)?.with_fetch_attempts(1);
        reader.set_index_cache_limit(index_allowance(settings.memory_limit_bytes));
        let header = reader.header().clone();
        let name = reader.name().to_string();
        let terrain = TerrainFrame::new(&header);
        let pyramid = reader.pyramid().clone();
        check_morph_range(&settings, &terrain, reader.name())?;
        let light = (settings.light, settings.render.lights_vertices());
        let mut loader = ArchiveLoader::new(reader, light, viewport.focal_px(), settings.cracks);
        if let Some(budget) = settings.texture_budget_bytes {
            loader.fit_texture_budget(settings.memory_limit_bytes, budget);
        }
        if settings.keep_top {
            choose_top(&mut loader, &settings, &pyramid);
        }
        check_memory_holds_something(&loader, &settings)?;
        let mut config = PagerConfig::new(settings.memory_limit_bytes, settings.pager_mode);
        config.nearest_when_off = settings.nearest_when_off;
        if pyramid.levels() > 1 {
            let whole = TileLoader::predicted_bytes(&loader, pyramid.root(), 1);
            // The levels between the top (or the root) and level 0.
            let chain = header.top_level.clamp(1, u32::from(pyramid.root().level)) as usize - 1;
            config.far_share = far_share(settings.memory_limit_bytes, whole, chain);
        }
        let (pager, predictor): (Box<dyn Paging>, _) = match settings.streaming {
            Streaming::Belts => (
                Box::new(BeltPager::new(loader, pyramid.clone(), config)?),
                None,
            ),
            Streaming::Progressive(stream) => {
                check_progressive(&settings)?;
                settings.fit_cut_to_budget = false;
                // Partial tiles draw powers-of-two masks only (see `plan_frame`): every frame
                // does, so a view does not change set when its last tile completes.
                settings.level_set = LevelSet::PowerOfTwo;
                (
                    Box::new(StreamPager::new(loader, pyramid.clone(), config, stream)?),
                    Some(Predictor::new(stream.prediction.unwrap_or_default())),
                )
            }
        };
        let rasterizer = if settings.threads == 0 {
            Rasterizer::new()
        } else {
            Rasterizer::with_threads(settings.threads)
        };
        Ok(Engine {
            terrain,
            pager,
            pyramid,
            predictor,
            masks: MaskSet::new(header.tile_size as usize, settings.level_set),
            cracks: TileIndices::new(settings.cracks, header.tile_size as usize),
            morpher: Morpher::new(settings.geomorph, header.tile_size as usize),
            partial: PartialMeshes::new(),
            forced_levels: None,
            budget: BudgetController::new(settings.budget),
            need: None,
            water_px: None,
            last_frame: LastFrame::default(),
            settings,
            rasterizer,
            viewport,
            archive: (header, name),
        })
    }

    /// Where the terrain is.
    pub fn terrain(&self) -> &TerrainFrame {
        &self.terrain
    }

    /// Moves the terrain in the world (e.g. 10^7 m from the origin); cameras move with it.
    pub fn place_terrain(&mut self, origin: DVec3) {
        self.terrain.origin = origin;
    }

    /// What the pager holds: its tiles, their states and the counters.
    pub fn pager(&self) -> &Residency<ResidentTile> {
        self.pager.resident()
    }

    /// The streaming counters, when tiles stream progressively.
    pub fn stream_stats(&self) -> Option<&StreamStats> {
        self.pager.stream_stats()
    }

    /// The strip masks.
    pub fn masks(&self) -> &MaskSet {
        &self.masks
    }

    /// The settings in force.
    pub fn settings(&self) -> &EngineSettings {
        &self.settings
    }

    /// The rendering settings, changeable between frames.
    pub fn render_settings_mut(&mut self) -> &mut RenderSettings {
        &mut self.settings.render
    }

    /// The archive's lowest height in the engine's frame: the ground assumed where none is held.
    fn lowest_height(&self) -> f64 {
        self.terrain.heights.0 + self.terrain.origin.y
    }

    /// The ground height under `position` in the finest resident tile that holds it.
    pub fn ground(&self, position: DVec3) -> Option<f64> {
        let (px, py) = self.terrain.tile_position(position);
        if !(px >= 0.0 && py >= 0.0) {
            return None;
        }
        let resident = self.pager.resident();
        (0..self.pyramid.levels() as u8).find_map(|level| {
            let span = f64::from(1u32 << level);
            let id = TileId::at(level, (px / span) as u32, (py / span) as u32);
            let tile = resident.get(id)?;
            self.terrain.ground_in(tile, id, position)
        })
    }

    /// A camera placed over the terrain, for an eye and gaze in world metres. With
    /// `above_ground`, heights count from the ground under the eye (the archive's lowest height
    /// where no tile is loaded). The eye is kept `clearance` metres above loaded ground.
    pub fn camera(&self, eye: DVec3, target: DVec3, above_ground: bool) -> Camera {
        let ground = self.ground(eye);
        let lift = if above_ground {
            ground.unwrap_or(self.lowest_height())
        } else {
            0.0
        };
        let mut eye = eye + DVec3::Y * lift;
        let target = target + DVec3::Y * lift;
        if let Some(g) = ground {
            eye.y = eye.y.max(g + self.settings.clearance);
        }
        Camera::looking_at(eye, target)
    }

    /// The world point at `latitude` and `longitude` (degrees, on the archive's datum) and
    /// `altitude` metres above the vertical datum of the model the archive was built from, with
    /// the bearing of the archive's north from true north there (radians: UTM's grid
    /// convergence, 0 on geographic and Web Mercator archives). An archive that stores no
    /// georeferencing, or a CRS latitudes cannot be placed on, is an error naming it.
    pub fn locate(&self, latitude: f64, longitude: f64, altitude: f64) -> Result<(DVec3, f64)> {
        let (header, name) = &self.archive;
        let at = header.locate(latitude, longitude, name)?;
        let position = self.terrain.from_archive(at.east, at.north, altitude);
        Ok((position, at.convergence))
    }

    /// A camera at `latitude`, `longitude` and `altitude` (as [`Engine::locate`] places them)
    /// with an aircraft's attitude: `heading` clockwise from true north, `pitch` up from the
    /// horizon, `roll` banking right, radians.
    pub fn camera_at(
        &self,
        (latitude, longitude, altitude): (f64, f64, f64),
        heading: f64,
        pitch: f64,
        roll: f64,
    ) -> Result<Camera> {
        let (position, convergence) = self.locate(latitude, longitude, altitude)?;
        Ok(Camera::from_attitude(
            position,
            heading - convergence,
            pitch,
            roll,
        ))
    }

    /// The archive's header: its grid, heights and georeferencing.
    pub fn header(&self) -> &Header {
        &self.archive.0
    }

    /// The archive's name, as errors give it.
    pub fn archive_name(&self) -> &str {
        &self.archive.1
    }

    /// The viewport the engine draws for.
    pub fn viewport(&self) -> &Viewport {
        &self.viewport
    }

    /// Draws the next frames into targets of `width` × `height` pixels, with the same field of
    /// view (a resized window). Tiles keep the texture mips chosen for the viewport the engine
    /// was made for.
    pub fn resize(&mut self, width: u32, height: u32) -> Result<()> {
        let viewport = Viewport {
            width,
            height,
            ..self.viewport
        };
        viewport.check()?;
        self.viewport = viewport;
        Ok(())
    }

    /// Renders one frame from `camera`, through the engine's viewport, between depth planes
    /// fitted to the terrain (the report's `view`), into `picture`: a
    /// [`Framebuffer`](stripmask_raster::Framebuffer) or the
    /// caller's own memory lent as a [`Surface`](stripmask_raster::Surface) (a mapped screen, a
    /// toolkit's buffer, rows a stride apart in any of the layouts of
    /// [`PixelLayout`](stripmask_raster::PixelLayout)).
    pub fn render(&mut self, camera: &Camera, picture: &mut impl AsSurface) -> Result<FrameReport> {
        // The engine's rasterizer is lent to the frame's target: moving it out (no allocation)
        // lets `render_to` borrow the whole engine.
        let mut rasterizer = std::mem::take(&mut self.rasterizer);
        let mut target = RasterTarget::new(picture.as_surface(), &mut rasterizer);
        let report = self.render_to(camera, &mut target);
        self.rasterizer = rasterizer;
        report
    }

    /// Renders one frame from `camera` into any [`DrawTarget`]: the same draw list goes to the
    /// CPU rasterizer ([`Engine::render`]) or to another backend, such as the wgpu comparison
    /// target of `stripmask-platform`.
    pub fn render_to<T: DrawTarget>(
        &mut self,
        camera: &Camera,
        target: &mut T,
    ) -> Result<FrameReport>
    where
        Error: From<T::Error>,
    {
        // Before anything changes: a target of the wrong size leaves the engine as it was.
        self.viewport.check_target(target.size())?;
        let frame_started = Instant::now();
        let placed_on_ground = self.ground(camera.position).is_some();
        self.hold_lighting_as_drawn();
        self.pager
            .update(self.terrain.tile_position(camera.position));
        let paging_seconds = frame_started.elapsed().as_secs_f64();
        let started = Instant::now();
        let mut camera = *camera;
        if !placed_on_ground && self.settings.lift_to_clearance {
            self.stand_on_arrived_ground(&mut camera);
        }
        let view = self.view_of(&camera);
        let (predicted, arrival) = self.predict(&camera);
        let kept = self.kept_levels();
        let inputs = FrameInputs {
            holdings: self.pager.resident(),
            terrain: &self.terrain,
            pyramid: &self.pyramid,
            masks: &self.masks,
            weights: self.settings.weights,
            budget: self.budget.budget(),
            forced_levels: self.forced_levels.as_deref(),
            max_error: self.settings.max_error,
            allocation: self.settings.allocation,
            cracks: self.settings.cracks,
            clearance: self.settings.clearance,
            kept: &kept,
            water_px: self.water_px,
            last: &self.last_frame,
        };
        let plan = plan_frame(&inputs, &view);
        let wants = frame_wants(
            &inputs,
            &plan,
            Ahead {
                arrival: arrival.as_ref(),
                predicted: predicted.as_ref(),
            },
            &view,
        );
        let rendered = plan.rendered();
        let (holes, waiting) = (plan.holes, plan.cut.missing.len());
        let mut draws = plan.draws(self.terrain.tile_size);
        let bookkeeping_seconds = started.elapsed().as_secs_f64();

        let drawing = Instant::now();
        let drawn = draw_tiles(
            target,
            &view,
            &self.terrain,
            &mut draws,
            TileMeshes {
                masks: &self.masks,
                cracks: &mut self.cracks,
                partial: Some(&mut self.partial),
                morph: self.morpher.as_mut(),
            },
            &self.settings.render,
        )?;
        let draw_seconds = drawing.elapsed().as_secs_f64();
        let rendered_tiles = draws.len();
        let (budget, triangles, bound) = (plan.budget, plan.triangles(), plan.bound);
        self.need = (bound != Bound::Budget).then_some(plan.need);
        // A frame the budget did not bind lets the cut deepen again, a little at a time: a cut
        // that jumped back to τ would bind the budget again the next frame, and the frames
        // would alternate between two cuts.
        self.water_px = match plan.water_px {
            Some(water) => Some(water),
            None => self
                .water_px
                .map(|w| w * WATER_DECAY)
                .filter(|&w| w * SPLIT_SHARE > self.settings.max_error.pixels().max(0.5)),
        }
        .filter(|_| self.settings.fit_cut_to_budget);
        drop(draws);
        drop(plan);
        self.last_frame =
            LastFrame::new(rendered.iter().map(|t| (t.id, t.error_px)), &self.pyramid);
        self.tell_pager(&wants, &rendered);
        let max_error_px = rendered.iter().map(|t| t.error_px).fold(0.0, f64::max);
        if self.settings.frame_timing == FrameTiming::Measured {
            let seconds = frame_started.elapsed().as_secs_f64();
            self.budget
                .record_needing(seconds, drawn.triangles.triangles as usize, self.need);
        }
        Ok(FrameReport {
            view,
            budget,
            triangles,
            rendered_tiles,
            bound,
            allocation: self.settings.allocation,
            max_error_px,
            rendered,
            holes,
            waiting,
            draw: drawn.triangles,
            wireframe: drawn.lines,
            paging_seconds,
            bookkeeping_seconds,
            draw_seconds,
            pager: self.pager.resident().stats(),
        })
    }

    /// Lifts the eye of `camera`, placed while the ground under it was not held, when that
    /// ground arrived in this frame's update and the eye is under it (or within the clearance):
    /// [`Engine::camera`] stood it on the archive's lowest height, so it goes up by the
    /// ground's height over that, where [`Engine::camera`] places it now, and at least
    /// `clearance` above the ground. Without this, the first frame the top arrives for would
    /// be drawn, and its levels wished, from under the terrain.
    fn stand_on_arrived_ground(&self, camera: &mut Camera) {
        let Some(ground) = self.ground(camera.position) else {
            return;
        };
        let floor = ground + self.settings.clearance;
        if camera.position.y < floor {
            camera.position.y = (camera.position.y + ground - self.lowest_height()).max(floor);
        }
    }

    /// When streaming progressively, the camera extrapolated to when this frame's requests
    /// will arrive ([`StreamStats::round_trip`]), and with prediction the view the predictor
    /// expects a second ahead; the predictor hears this frame's camera first.
    fn predict(&mut self, camera: &Camera) -> (Option<PredictedView>, Option<Camera>) {
        let Some(predictor) = self.predictor.as_mut() else {
            return (None, None);
        };
        predictor.observe(self.pager.resident().time(), *camera);
        let arrival = self
            .pager
            .stream_stats()
            .and_then(StreamStats::round_trip)
            .and_then(|seconds| predictor.ahead(seconds));
        let prefetch = matches!(
            self.settings.streaming,
            Streaming::Progressive(StreamSettings {
                prediction: Some(_),
                ..
            })
        );
        (prefetch.then(|| predictor.predict()).flatten(), arrival)
    }

    /// Tells the pager what the frame wished for and which progressive levels it drew (a
    /// progressive pager fetches by them; the belt pager plans by itself).
    fn tell_pager(&mut self, wants: &[Want], rendered: &[RenderedTile]) {
        let levels = progressive_levels(self.terrain.tile_size);
        let drawn: Vec<(TileId, usize)> = rendered
            .iter()
            .map(|r| (r.id, levels_for_mask(r.level, levels)))
            .collect();
        self.pager.request(wants);
        self.pager.drawn(&drawn);
    }

    /// The level each tile should keep if the budget allows, when streaming progressively:
    /// the finest mask its levels that arrived within the last second allow. A fetched level
    /// is worth drawing for a second: the budget shifts a little every frame and would
    /// otherwise draw a tile one level coarser than it just fetched.
    fn kept_levels(&self) -> TileMap<usize> {
        let Some(stats) = self.pager.stream_stats() else {
            return TileMap::default();
        };
        let levels = progressive_levels(self.terrain.tile_size);
        let mut kept: TileMap<usize> = TileMap::default();
        for (id, held) in stats.fresh() {
            let level = finest_mask_for_levels(held, levels);
            kept.entry(id)
                .and_modify(|l| *l = (*l).min(level))
                .or_insert(level);
        }
        kept
    }

    /// Switches the crack mode between frames. Loaded tiles are refit in place (skirt vertices
    /// added or dropped; no fetch) and re-accounted, evicting the farthest tiles if the new mode
    /// holds more than the memory limit allows ([`BeltPager::refit`]); fetches in flight are refit
    /// when they arrive. The next frame draws exactly what an engine started in `mode` would
    /// draw with the same tiles loaded.
    pub fn set_cracks(&mut self, mode: CrackMode) {
        if mode == self.settings.cracks {
            return;
        }
        self.settings.cracks = mode;
        self.pager.loader().set_cracks(mode);
        self.pager.refit();
        self.cracks = TileIndices::new(mode, self.terrain.tile_size);
    }

    /// Lights the resident tiles, or drops their lighting, when the render settings changed
    /// whether the surface is lit ([`RenderSettings::lights_vertices`]): tiles hold normals
    /// and shades only while they are drawn. Refit like a change of crack mode.
    fn hold_lighting_as_drawn(&mut self) {
        let lit = self.settings.render.lights_vertices();
        if lit != self.pager.loader().lit() {
            self.pager.loader().set_lit(lit);
            self.pager.refit();
        }
    }

    /// Changes the frame rate the budget aims at (a lower target allows more triangles).
    pub fn set_target_fps(&mut self, fps: f64) {
        let mut settings = *self.budget.settings();
        settings.target_fps = fps;
        self.settings.budget.target_fps = fps;
        let budget = self.budget.budget();
        let learned = self.budget.cost_per_triangle().map(|triangle_s| FrameCost {
            overhead_s: self.budget.overhead(),
            triangle_s,
        });
        self.budget = BudgetController::new(BudgetSettings {
            initial_budget: budget,
            expected: learned.or(settings.expected),
            ..settings
        });
    }

    /// Tells the budget how long a frame took (the whole frame as the application timed it, or
    /// as a simulated device would have spent it), for an engine whose [`FrameTiming`] is
    /// `Told`; returns the next frame's budget. After a frame the error bound capped, the
    /// budget does not grow ([`BudgetController::record_needing`]).
    pub fn record_frame(&mut self, seconds: f64, triangles: usize) -> usize {
        self.budget.record_needing(seconds, triangles, self.need)
    }

    /// Changes the pixel-error bound τ between frames (the next cut follows it alone: what the
    /// last budget left says nothing of the new bound).
    pub fn set_max_error(&mut self, bound: ErrorBound) {
        self.settings.max_error = bound;
        self.water_px = None;
    }

    /// Changes how the tiles share the triangle budget between frames (the next cut follows τ
    /// alone).
    pub fn set_allocation(&mut self, allocation: Allocation) {
        self.settings.allocation = allocation;
        self.water_px = None;
    }

    /// The view of `camera` through the viewport. Near plane from the height above the ground
    /// (depth precision where it matters), far
    /// plane at the farthest point of the terrain (nothing beyond it can be drawn). The near
    /// plane stays below the eye's height, or the ground under the lower screen edge would be
    /// clipped away (down to a millimetre: an eye a centimetre above the ground still sees the
    /// ground).
    pub(super) fn view_of(&self, camera: &Camera) -> View {
        let ground = self.ground(camera.position).unwrap_or(self.lowest_height());
        let height = (camera.position.y - ground).max(0.0);
        let near = (0.25 * height).clamp(1e-3, 1000.0);
        let (lo, hi) = self.terrain.tile_box(
            self.pyramid.root(),
            self.terrain.heights.0,
            self.terrain.heights.1,
        );
        let far = (lo - camera.position)
            .abs()
            .max((hi - camera.position).abs())
            .length();
        View::new(*camera, self.viewport, near, far.max(near * 4.0))
    }
}
