//! One frame of the paper's client, end to end: page belts in, cut through the pyramid to the
//! tiles in view, weigh them by visual importance, share the triangle budget, pick a strip mask
//! per tile, draw.
//!
//! ```text
//! camera ──> cut (frustum, τ) ──> importance ──> budget ──> mask per tile ──> draw list ──> raster
//!               ^
//!        pager (top, belts, far field | levels) <── tile source
//! ```

use std::collections::{BinaryHeap, HashMap, HashSet};
use std::sync::Arc;
use std::time::Instant;

use glam::DVec3;
use stripmask_raster::{DrawStats, DrawTarget, Framebuffer, LineStats, RasterTarget, Rasterizer};

use crate::db::archive::ArchiveReader;
use crate::db::grid::{Pyramid, TileId};
use crate::db::source::TileSource;
use crate::db::tile::{PartialGrid, finest_mask_for_levels, levels_for_mask, progressive_levels};
use crate::engine::allocation::{Allocation, TileErrors};
use crate::engine::budget::{
    BudgetController, BudgetSettings, FrameCost, TileAllocation, drawable_level,
};
use crate::engine::camera::Camera;
use crate::engine::cracks::CrackMode;
use crate::engine::cracks::TileIndices;
use crate::engine::cracks::neighbours::{
    Neighbourhood, conform, neighbour_levels, pyramid_borders,
};
use crate::engine::cut::{Cut, CutSettings, LastFrame, SPLIT_SHARE, cut};
use crate::engine::error_bound::{Bound, ErrorBound};
use crate::engine::frustum::{Aabb, Frustum};
use crate::engine::geomorph::{Geomorph, Morpher, SUBDIVISION};
use crate::engine::importance::{Importance, TileMeasure, Weights, visual_importance};
use crate::engine::masks::{LevelSet, MaskSet};
use crate::engine::paging::stream::{
    LevelLoader, PredictedView, Predictor, StreamPager, StreamSettings, Streaming, Want,
};
use crate::engine::paging::{
    ArchiveLoader, BeltPager, PagerConfig, PagerMode, PagerStats, Paging, Residency,
    ResidentLoader, StreamStats, TileLoader, TransferClock, far_share,
};
use crate::engine::partial_meshes::PartialMeshes;
use crate::engine::render::{RenderSettings, TileDraw, TileMeshes, draw_tiles};
use crate::engine::resident::Light;
use crate::engine::resident::ResidentTile;
use crate::engine::terrain::TerrainFrame;
use crate::error::{Error, Result};

/// Everything a run can set.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EngineSettings {
    /// Rendering knobs.
    pub render: RenderSettings,
    /// Memory limit on loaded tiles, bytes.
    pub memory_limit_bytes: usize,
    /// Of that, the most the textures of the complete square may take (`None`: no separate cap).
    pub texture_budget_bytes: Option<usize>,
    /// Threaded (real runs), stepped or simulated (deterministic) fetching.
    pub pager_mode: PagerMode,
    /// A viewpoint off the terrain pages around the nearest tile.
    pub nearest_when_off: bool,
    /// All mask levels, or powers of two only (geometrical mipmapping).
    pub level_set: LevelSet,
    /// How cracks between tiles at different levels are hidden.
    pub cracks: CrackMode,
    /// Whether vertices that coarser levels drop glide onto the coarser surface with distance.
    pub geomorph: Geomorph,
    /// Importance weights (distance, height).
    pub weights: Weights,
    /// The frame-rate controller.
    pub budget: BudgetSettings,
    /// The pixel-error bound τ: no tile finer than its projected error needs.
    pub max_error: ErrorBound,
    /// How the tiles in view share the triangle budget: by importance or by projected error.
    pub allocation: Allocation,
    /// Sun direction and ambient light.
    pub light: Light,
    /// Vertical field of view, radians.
    pub fov_y: f64,
    /// The eye never goes lower than this above the ground, metres.
    pub clearance: f64,
    /// Rasterizer threads (0: all cores).
    pub threads: usize,
    /// Whole tiles in belts (the paper) or progressive levels as the view needs them.
    pub streaming: Streaming,
    /// Keep the archive's top (the pyramid's root and the levels stored with it) resident,
    /// fetched first and drawn wherever no finer tile is held, so that no view of the terrain
    /// is empty, whatever the model's size.
    pub keep_top: bool,
    /// Whether the cut goes no deeper than the budget can use ([`crate::engine::cut`]): when
    /// the last frame's budget left more error on screen than τ, tiles that showed little of it
    /// are not replaced by their children (fewer tiles, the same error). Off, the cut follows
    /// τ alone, so that frames of one view under different budgets draw the same tiles. With
    /// belts only: progressive streaming asks for the levels of the tiles drawn, and a cut that
    /// moved with the budget would ask for levels that the next frames do not draw.
    pub fit_cut_to_budget: bool,
}

impl Default for EngineSettings {
    fn default() -> Self {
        EngineSettings {
            render: RenderSettings::default(),
            memory_limit_bytes: 64 << 20,
            texture_budget_bytes: None,
            pager_mode: PagerMode::Threaded { queue_depth: 4 },
            nearest_when_off: true,
            level_set: LevelSet::All,
            cracks: CrackMode::default(),
            geomorph: Geomorph::default(),
            weights: Weights::default(),
            budget: BudgetSettings::default(),
            max_error: ErrorBound::default(),
            allocation: Allocation::default(),
            light: Light::default(),
            fov_y: 60f64.to_radians(),
            clearance: 20.0,
            threads: 0,
            streaming: Streaming::Belts,
            keep_top: true,
            fit_cut_to_budget: true,
        }
    }
}

/// What one frame did.
#[derive(Clone, Debug, PartialEq)]
pub struct FrameReport {
    /// The camera as drawn (near and far planes set by the engine).
    pub camera: Camera,
    /// The triangle budget of this frame.
    pub budget: usize,
    /// Triangles the chosen masks hold.
    pub triangles: usize,
    /// Tiles in the view frustum among the loaded ones: the tiles drawn.
    pub rendered_tiles: usize,
    /// What capped the frame's detail: the budget (time) or the error bound τ.
    pub bound: Bound,
    /// The rule that shared the budget among the tiles.
    pub allocation: Allocation,
    /// The largest geometric error of a drawn tile on screen, pixels (see
    /// [`RenderedTile::error_px`]).
    pub max_error_px: f64,
    /// The drawn tiles with their visual importance and mask level.
    pub rendered: Vec<RenderedTile>,
    /// Holes: parts of the terrain the view meets with nothing to draw — tiles of the pyramid
    /// in view with no resident copy and nothing resident over or under them (none once the
    /// top is resident).
    pub holes: usize,
    /// Tiles the view wants that are not resident yet, drawn meanwhile from a coarser tile
    /// over them: none once the view has settled.
    pub waiting: usize,
    /// What the rasterizer did.
    pub draw: DrawStats,
    /// What the wireframe's lines did (zero when it is off).
    pub wireframe: LineStats,
    /// Seconds the pager's update took at the frame's start: taking in arrived tiles and
    /// planning fetches — and, when the pager fetches on the frame's thread (stepped and
    /// simulated modes), the fetches themselves.
    pub paging_seconds: f64,
    /// Seconds spent on the cut, importance, budget, masks and the draw list.
    pub bookkeeping_seconds: f64,
    /// Seconds spent drawing.
    pub draw_seconds: f64,
    /// The pager's counters after this frame's update.
    pub pager: PagerStats,
}

impl FrameReport {
    /// Whether the frame drew terrain wherever the view meets some: no holes. Until the first
    /// such frame an engine draws sky where the tiles have not arrived.
    pub fn ready(&self) -> bool {
        self.holes == 0
    }

    /// Whether the frame drew the view as the engine wants it: ready, and no tile waiting.
    pub fn settled(&self) -> bool {
        self.ready() && self.waiting == 0
    }
}

/// One drawn tile.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderedTile {
    /// Which tile.
    pub id: TileId,
    /// Its visual importance this frame (the drawn tiles' values sum to 1).
    pub importance: f64,
    /// The strip-mask level it was drawn at.
    pub level: usize,
    /// Its level's geometric error on screen: the height error (metres, from the archive)
    /// times pixels per metre at its bounding box's distance from the eye; 0 for an exact
    /// level, infinite for a level without a known error, as the budget's allocation counts it.
    pub error_px: f64,
    /// Whether it drew coarser than the budget offered because it holds too few levels.
    pub capped: bool,
    /// Whether it drew finer than the budget and τ gave it, to stitch to a tile of another
    /// level of the pyramid ([`conform`]).
    pub conformed: bool,
}

/// The engine: an archive, its pager, the shared strip masks and the budget controller.
pub struct Engine {
    terrain: TerrainFrame,
    pager: Box<dyn Paging>,
    pyramid: Pyramid,
    /// The viewpoint predictor when streaming progressively: it extrapolates the view to
    /// where requests arrive and, with prediction, a second ahead.
    predictor: Option<Predictor>,
    masks: MaskSet,
    cracks: TileIndices,
    /// The masks and crack pieces of partial tiles, built per held side on first use.
    partial: PartialMeshes,
    /// The geomorph state, `None` when geomorphing is off.
    morpher: Option<Morpher>,
    /// Levels pinned per tile instead of the budget's choice (for measurements).
    forced_levels: Option<Box<dyn Fn(TileId) -> usize + Send>>,
    budget: BudgetController,
    /// The last frame's need when the error bound (not the budget) capped it, for the
    /// controller ([`BudgetController::record_needing`]).
    need: Option<usize>,
    /// The error the last frame's budget left on screen, when the budget capped it (see
    /// [`FramePlan::water_px`]): the next frame's cut goes no deeper than it can use.
    water_px: Option<f64>,
    /// What the last frame drew, for the next frame's cut when the budget capped it.
    last_frame: LastFrame,
    settings: EngineSettings,
    rasterizer: Rasterizer,
}

impl Engine {
    /// Opens `source` for a screen `height` pixels tall.
    pub fn new(
        source: Box<dyn TileSource>,
        mut settings: EngineSettings,
        height: u32,
    ) -> Result<Self> {
        // The pager retries failed fetches, backing off: the reader tries each once.
        let reader = ArchiveReader::open(source)?.with_fetch_attempts(1);
        reader.set_index_cache_limit(index_allowance(settings.memory_limit_bytes));
        let header = reader.header().clone();
        let terrain = TerrainFrame::new(&header);
        let pyramid = reader.pyramid().clone();
        check_morph_range(&settings, &terrain, reader.name())?;
        let focal_px = f64::from(height) / (2.0 * (settings.fov_y / 2.0).tan());
        let mut loader = ArchiveLoader::new(reader, settings.light, focal_px, settings.cracks);
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

    /// Sets the simulated time for a pager in [`PagerMode::Simulated`], seconds.
    pub fn set_time(&mut self, seconds: f64) {
        self.pager.set_time(seconds);
    }

    /// Times tile transfers for a pager in [`PagerMode::Simulated`].
    pub fn set_transfer_clock(&mut self, clock: Arc<dyn TransferClock>) {
        self.pager.set_transfer_clock(clock);
    }

    /// The strip masks.
    pub fn masks(&self) -> &MaskSet {
        &self.masks
    }

    /// Pins every drawn tile's mask level to `level_of(tile)` instead of the budget's choice
    /// (`None` gives the choice back to the budget): views with known level pairs, for
    /// measuring cracks. A partial tile draws no finer than it holds, and while any drawn tile
    /// is partial the pinned levels snap to powers of two ([`drawable_level`]).
    pub fn force_levels(&mut self, level_of: Option<Box<dyn Fn(TileId) -> usize + Send>>) {
        self.forced_levels = level_of;
    }

    /// The settings in force.
    pub fn settings(&self) -> &EngineSettings {
        &self.settings
    }

    /// The rendering settings, changeable between frames.
    pub fn render_settings_mut(&mut self) -> &mut RenderSettings {
        &mut self.settings.render
    }

    /// Whether the view of `camera` on a `screen` of (width, height) pixels has everything it
    /// should draw with any of `budgets` triangles within `radius` level-0 tiles of the current
    /// one: its cut lacks no tile there (no tile it would refine misses a child), and every
    /// tile of the cut there holds at least the progressive levels of the coarsest mask level
    /// any of the budgets gives it if every tile in view held all its levels and that budget
    /// were shared among them (by the engine's allocation, no finer than τ needs, without the
    /// bonus of freshly fetched levels). It depends on the camera, the archive, what is
    /// resident and `budgets` only, not on the budgets the frames were drawn by, so paging
    /// strategies can be compared by it (`stream-compare`'s first complete view). Without
    /// budgets, the cut need only lack nothing.
    pub fn holds_view(
        &self,
        camera: &Camera,
        screen: (u32, u32),
        radius: u32,
        budgets: &[usize],
    ) -> bool {
        let aspect = f64::from(screen.0) / f64::from(screen.1);
        let resident = self.pager.resident();
        let Some(center) = resident.current_tile() else {
            return false;
        };
        let near = |id: TileId| {
            let span = id.span();
            let gap = |c: u32, t: u32| {
                let (lo, hi) = (t * span, t * span + span - 1);
                lo.saturating_sub(c).max(c.saturating_sub(hi))
            };
            gap(center.x, id.x).max(gap(center.y, id.y)) <= radius
        };
        let no_kept = HashMap::new();
        let inputs = FrameInputs {
            pager: &*self.pager,
            terrain: &self.terrain,
            pyramid: &self.pyramid,
            masks: &self.masks,
            weights: self.settings.weights,
            // The view's plan does not depend on the budget: each of `budgets` is shared below.
            budget: 0,
            forced_levels: None,
            max_error: self.settings.max_error,
            allocation: self.settings.allocation,
            cracks: self.settings.cracks,
            height: screen.1,
            clearance: self.settings.clearance,
            kept: &no_kept,
            water_px: None,
            last: &LastFrame::default(),
        };
        let view = plan_view(&inputs, camera, aspect);
        if view.cut.missing.iter().any(|&(id, _)| near(id)) {
            return false;
        }
        if budgets.is_empty() {
            return true;
        }
        let levels = progressive_levels(self.terrain.tile_size);
        // Per tile in reach, the fewest levels any of the budgets would have it draw: the
        // levels each budget offers the tiles in view had they held them all.
        let mut needed: HashMap<TileId, usize> = HashMap::new();
        for &budget in budgets {
            for (&(id, _, _), o) in view.cut.tiles.iter().zip(view.offer(&inputs, budget)) {
                if near(id) {
                    let l = levels_for_mask(o.level, levels);
                    needed
                        .entry(id)
                        .and_modify(|n| *n = (*n).min(l))
                        .or_insert(l);
                }
            }
        }
        needed
            .iter()
            .all(|(&id, &n)| resident.get(id).is_some_and(|t| t.levels >= n))
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

    /// A camera for an eye and gaze in terrain-frame metres. With `above_ground`, heights count
    /// from the ground under the eye (the archive's lowest height where no tile is loaded). The
    /// eye is kept `clearance` metres above loaded ground.
    pub fn camera(&self, eye: DVec3, target: DVec3, above_ground: bool) -> Camera {
        let (eye, target) = (eye + self.terrain.origin, target + self.terrain.origin);
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
        let mut camera = Camera::looking_at(eye, target);
        camera.fov_y = self.settings.fov_y;
        camera
    }

    /// Renders one frame into `fb` from `camera` (its near and far planes are set here).
    pub fn render(&mut self, camera: &Camera, fb: &mut Framebuffer) -> Result<FrameReport> {
        // The engine's rasterizer is lent to the frame's target: moving it out (no allocation)
        // lets `render_to` borrow the whole engine.
        let mut rasterizer = std::mem::take(&mut self.rasterizer);
        let report = self.render_to(camera, &mut RasterTarget::new(fb, &mut rasterizer));
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
        let started = Instant::now();
        let placed_on_ground = self.ground(camera.position).is_some();
        self.pager
            .update(self.terrain.tile_position(camera.position));
        let paging_seconds = started.elapsed().as_secs_f64();
        let started = Instant::now();
        let mut camera = *camera;
        if !placed_on_ground {
            self.stand_on_arrived_ground(&mut camera);
        }
        self.fit_depth_range(&mut camera);
        let (width, height) = target.size();
        let aspect = f64::from(width) / f64::from(height);
        let (predicted, arrival) = self.predict(&camera);
        let kept = self.kept_levels();
        let inputs = FrameInputs {
            pager: &*self.pager,
            terrain: &self.terrain,
            pyramid: &self.pyramid,
            masks: &self.masks,
            weights: self.settings.weights,
            budget: self.budget.budget(),
            forced_levels: self.forced_levels.as_deref(),
            max_error: self.settings.max_error,
            allocation: self.settings.allocation,
            cracks: self.settings.cracks,
            height,
            clearance: self.settings.clearance,
            kept: &kept,
            water_px: self.water_px,
            last: &self.last_frame,
        };
        let plan = plan_frame(&inputs, &camera, aspect);
        let wants = frame_wants(
            &inputs,
            &plan,
            Ahead {
                arrival: arrival.as_ref(),
                predicted: predicted.as_ref(),
            },
            aspect,
        );
        let rendered = plan.rendered();
        let (holes, waiting) = (plan.holes, plan.cut.missing.len());
        let mut draws = plan.draws(self.terrain.tile_size);
        let bookkeeping_seconds = started.elapsed().as_secs_f64();

        let drawing = Instant::now();
        let drawn = draw_tiles(
            target,
            &camera,
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
        Ok(FrameReport {
            camera,
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
    fn kept_levels(&self) -> HashMap<TileId, usize> {
        let Some(stats) = self.pager.stream_stats() else {
            return HashMap::new();
        };
        let levels = progressive_levels(self.terrain.tile_size);
        let mut kept: HashMap<TileId, usize> = HashMap::new();
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

    /// Sets the next frame's budget to `triangles`, where it stays until a recorded frame moves
    /// it: measurements at a fixed budget (the tradeoff report) bypass the frame-rate controller.
    pub fn hold_budget(&mut self, triangles: usize) {
        self.water_px = None;
        let settings = *self.budget.settings();
        self.budget = BudgetController::new(BudgetSettings {
            initial_budget: triangles,
            min_budget: settings.min_budget.min(triangles),
            max_budget: settings.max_budget.max(triangles),
            expected: None,
            ..settings
        });
    }

    /// Feeds the time a frame took (as the target device would have spent it) to the budget
    /// controller; returns the next frame's budget. After a frame the error bound capped, the
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

    /// Near plane from the height above the ground (depth precision where it matters), far
    /// plane at the farthest point of the terrain (nothing beyond it can be drawn). The near
    /// plane stays below the eye's height, or the ground under the lower screen edge would be
    /// clipped away (down to a millimetre: an eye a centimetre above the ground still sees the
    /// ground).
    fn fit_depth_range(&self, camera: &mut Camera) {
        let ground = self.ground(camera.position).unwrap_or(self.lowest_height());
        let height = (camera.position.y - ground).max(0.0);
        camera.near = (0.25 * height).clamp(1e-3, 1000.0);
        let (lo, hi) = self.terrain.tile_box(
            self.pyramid.root(),
            self.terrain.heights.0,
            self.terrain.heights.1,
        );
        let far = (lo - camera.position)
            .abs()
            .max((hi - camera.position).abs())
            .length();
        camera.far = far.max(camera.near * 4.0);
    }
}

/// What a frame's plan is made from.
struct FrameInputs<'e> {
    pager: &'e dyn Paging,
    terrain: &'e TerrainFrame,
    pyramid: &'e Pyramid,
    masks: &'e MaskSet,
    weights: Weights,
    /// This frame's triangle budget: the frame draws by it, and streaming wishes by it.
    budget: usize,
    /// Levels pinned per tile instead of the budget's choice.
    forced_levels: Option<&'e (dyn Fn(TileId) -> usize + Send)>,
    /// The pixel-error bound τ.
    max_error: ErrorBound,
    /// How the tiles share the budget.
    allocation: Allocation,
    /// How cracks are hidden: stitching asks tiles of two levels of the pyramid to meet.
    cracks: CrackMode,
    /// The screen's height, pixels.
    height: u32,
    /// No tile is seen from nearer than this (the eye's clearance), metres.
    clearance: f64,
    /// The level each tile should keep if the budget allows (see [`Engine::kept_levels`]).
    kept: &'e HashMap<TileId, usize>,
    /// The error the last frame's budget left on screen, if it capped the frame.
    water_px: Option<f64>,
    /// What the last frame drew.
    last: &'e LastFrame,
}

impl FrameInputs<'_> {
    /// Pixels per metre of height error at `distance` from the eye, no nearer than the
    /// clearance: a tile whose box holds the eye (distance 0) is not seen from closer than the
    /// eye keeps above the ground.
    fn pixels_per_metre(&self, camera: &Camera, distance: f64) -> f64 {
        camera.pixels_per_metre(distance.max(self.clearance), self.height)
    }

    /// The coarsest level of every tile whose error seen from `distance` is within τ.
    fn needed_levels<'t>(
        &self,
        camera: &Camera,
        tiles: impl Iterator<Item = (&'t ResidentTile, f64)>,
    ) -> Vec<usize> {
        tiles
            .map(|(tile, distance)| {
                let ppm = self.pixels_per_metre(camera, distance);
                self.max_error
                    .coarsest_level(&tile.level_errors, self.masks, ppm)
            })
            .collect()
    }

    /// Each tile's level errors, its pixels per metre at `distance` and its kept level: what
    /// sharing the budget by error weighs, for the frame and for the predicted view alike.
    fn tile_errors<'t>(
        &self,
        camera: &Camera,
        tiles: impl Iterator<Item = (TileId, &'t ResidentTile, f64)>,
    ) -> Vec<TileErrors<'t>> {
        tiles
            .map(|(id, tile, distance)| TileErrors {
                metres: &tile.level_errors,
                pixels_per_metre: self.pixels_per_metre(camera, distance),
                kept: self.kept.get(&id).copied(),
            })
            .collect()
    }

    /// What decides how deep the cut of a view goes: τ (none when it is off), the error the
    /// last frame's budget left when it capped the frame, and the screen.
    fn cut_settings(&self) -> CutSettings {
        CutSettings {
            max_error_px: match self.max_error {
                ErrorBound::Off => None,
                ErrorBound::Pixels(_) => Some(self.max_error.pixels()),
            },
            water_px: self.water_px,
            height: self.height,
            clearance: self.clearance,
        }
    }

    /// The cut of the view of `camera` at `aspect` through the resident tiles.
    fn cut<'p>(&self, camera: &Camera, aspect: f64) -> Cut<'p>
    where
        Self: 'p,
    {
        cut(
            self.pager.resident(),
            self.terrain,
            self.pyramid,
            camera,
            aspect,
            &self.cut_settings(),
            self.last,
        )
    }
}

/// One frame's plan: the tiles of the cut, their importance, and the mask level each draws and
/// would draw if it held every level.
struct FramePlan<'p> {
    /// The cut: the tiles drawn (each with its resident copy and its box's distance from the
    /// eye), what the view lacks, the tiles gone through.
    cut: Cut<'p>,
    importance: Vec<f64>,
    /// The levels drawn.
    allocation: Vec<TileAllocation>,
    /// The levels the budget offered: a tile drawn coarser is capped by what it holds, and
    /// streaming asks for what they lack.
    offered: Vec<TileAllocation>,
    /// Per tile, pixels per metre of height error at its distance.
    pixels_per_metre: Vec<f64>,
    budget: usize,
    /// Triangles of every tile at the level τ asks (full resolution when τ is off).
    need: usize,
    /// What capped the detail.
    bound: Bound,
    /// Parts of the view with nothing to draw.
    holes: usize,
    /// Per tile, whether stitching to another pyramid level made its level finer.
    conformed: Vec<bool>,
    /// Which drawn tiles border which.
    neighbourhood: Neighbourhood,
    /// When the budget capped the frame, the largest error on screen among the tiles it kept
    /// coarser than they could draw: the error the budget affords everywhere.
    water_px: Option<f64>,
}

/// What a frame's plan takes from the view alone, whatever its budget: the cut, the tiles'
/// importance, the levels τ needs and each tile's errors.
struct ViewPlan<'p> {
    /// The cut: the tiles in view to draw, what the view lacks, the tiles gone through.
    cut: Cut<'p>,
    importance: Importance,
    /// Per tile drawn, the coarsest level whose error is within τ.
    needed: Vec<usize>,
    /// Triangles the needed levels take.
    need: usize,
    /// Per tile drawn, the finest level it can draw: its held levels' finest, no finer than
    /// it needs.
    finest: Vec<usize>,
    errors: Vec<TileErrors<'p>>,
    /// Some tile in view holds only part of its levels.
    partial: bool,
    /// Which drawn tiles border which.
    neighbourhood: Neighbourhood,
}

/// Cuts through the pyramid and weighs the tiles in view (Algorithm 2), with the levels τ
/// needs: the part of the frame's plan its budget does not change (see [`ViewPlan`]).
fn plan_view<'p>(inputs: &FrameInputs<'p>, camera: &Camera, aspect: f64) -> ViewPlan<'p> {
    let cut = inputs.cut(camera, aspect);
    let measures: Vec<TileMeasure> = cut
        .tiles
        .iter()
        .map(|&(_, tile, distance)| TileMeasure {
            distance,
            height: f64::from(tile.max - tile.min),
        })
        .collect();
    let importance = visual_importance(&measures, inputs.weights);
    let partial = cut.tiles.iter().any(|(_, tile, _)| !tile.is_complete());
    // Partial tiles holding more than their corners draw powers-of-two levels only, which the
    // engine's masks are whenever such tiles are resident (see `Engine::new`): a level whose
    // `l + 1` is not a multiple of a drawn neighbour's stride needs border samples that
    // neighbour lacks.
    debug_assert!(
        inputs.masks.level_set() == LevelSet::PowerOfTwo
            || cut
                .tiles
                .iter()
                .all(|(_, t, _)| t.is_complete() || t.levels == 1)
    );
    let needed = inputs.needed_levels(camera, cut.tiles.iter().map(|&(_, t, d)| (t, d)));
    let need = needed.iter().map(|&l| inputs.masks.triangle_count(l)).sum();
    let finest = cut
        .tiles
        .iter()
        .zip(&needed)
        .map(|((_, tile, _), &level)| tile.finest_mask_level().max(level))
        .collect();
    let errors = inputs.tile_errors(camera, cut.tiles.iter().copied());
    let ids: Vec<TileId> = cut.tiles.iter().map(|t| t.0).collect();
    ViewPlan {
        neighbourhood: Neighbourhood::of(&ids),
        cut,
        importance,
        needed,
        need,
        finest,
        errors,
        partial,
    }
}

impl ViewPlan<'_> {
    /// `budget` shared among the tiles in view, none finer than `caps`.
    fn share(&self, inputs: &FrameInputs, budget: usize, caps: &[usize]) -> Vec<TileAllocation> {
        inputs
            .allocation
            .share(budget, &self.importance, inputs.masks, &self.errors, caps)
    }

    /// The levels `budget` offers the tiles in view had they held every level.
    fn offer(&self, inputs: &FrameInputs, budget: usize) -> Vec<TileAllocation> {
        let caps = if self.partial {
            &self.needed
        } else {
            &self.finest
        };
        self.share(inputs, budget, caps)
    }
}

/// The levels a share of the budget gives the tiles drawn, the levels it offers them, and which
/// tiles conforming made finer.
type Levels = (Vec<TileAllocation>, Vec<TileAllocation>, Vec<bool>);

/// The levels `budget` gives the tiles of `view` — forced when the engine pins them — and the
/// levels it offers them, conformed at the borders between pyramid levels when stitching; and
/// which tiles conforming made finer.
fn levels(inputs: &FrameInputs, view: &ViewPlan, budget: usize) -> Levels {
    let mut allocation = view.share(inputs, budget, &view.finest);
    let mut offered = if view.partial {
        view.offer(inputs, budget)
    } else {
        allocation.clone()
    };
    if let Some(level_of) = inputs.forced_levels {
        for ((a, o), &(id, tile, _)) in allocation.iter_mut().zip(&mut offered).zip(&view.cut.tiles)
        {
            let pinned = level_of(id);
            o.level = drawable_level(pinned, 0, view.partial);
            a.level = drawable_level(pinned, tile.finest_mask_level(), view.partial);
            a.triangles = inputs.masks.triangle_count(a.level);
        }
    }
    let conformed = if inputs.cracks == CrackMode::Stitch {
        conform_levels(inputs, view, &mut allocation, &mut offered)
    } else {
        vec![false; allocation.len()]
    };
    (allocation, offered, conformed)
}

/// How much of the budget's error the cut keeps in view after a frame the budget did not bind.
const WATER_DECAY: f64 = 0.8;

/// How many times a frame shares its budget again, less what conforming added, before it
/// searches from nothing for the share that fits.
const CONFORM_PASSES: usize = 4;

/// Cuts, weighs (Algorithm 2) and shares the budget, no tile finer than τ needs, the levels of
/// tiles meeting a tile of another pyramid level conformed when stitching: the frame's plan.
/// What conforming adds is taken from the budget the others share.
fn plan_frame<'p>(inputs: &FrameInputs<'p>, camera: &Camera, aspect: f64) -> FramePlan<'p> {
    let view = plan_view(inputs, camera, aspect);
    let bound = match inputs.max_error {
        _ if view.need > inputs.budget || inputs.forced_levels.is_some() => Bound::Budget,
        ErrorBound::Off => Bound::Full,
        ErrorBound::Pixels(_) => Bound::Error,
    };
    let mut plan = levels(inputs, &view, inputs.budget);
    let drawn = |plan: &Levels| plan.0.iter().map(|a| a.triangles).sum::<usize>();
    if drawn(&plan) > inputs.budget && inputs.forced_levels.is_none() {
        // Conforming added what the share did not count: share that much less, a few times
        // (each pass lands close), then search between the last share over the budget and
        // the first within it for the largest that fits; then spend what is left where it
        // ties nothing.
        let (mut over, mut share) = (inputs.budget, inputs.budget);
        let mut fitting = None;
        for _ in 0..CONFORM_PASSES {
            let excess = drawn(&plan).saturating_sub(inputs.budget);
            if excess == 0 {
                fitting = Some(share);
                break;
            }
            over = share;
            share = share.saturating_sub(excess + inputs.budget / 256);
            plan = levels(inputs, &view, share);
        }
        let mut fits = match fitting {
            Some(share) => share,
            None if drawn(&plan) <= inputs.budget => share,
            None => {
                over = share;
                plan = levels(inputs, &view, 0);
                0
            }
        };
        while over - fits > (inputs.budget / 128).max(1) {
            let mid = fits + (over - fits) / 2;
            let tried = levels(inputs, &view, mid);
            if drawn(&tried) <= inputs.budget {
                (fits, plan) = (mid, tried);
            } else {
                over = mid;
            }
        }
        top_up(inputs, &view, &mut plan, inputs.budget);
    }
    let (allocation, offered, conformed) = plan;
    let water_px = (bound == Bound::Budget && inputs.forced_levels.is_none())
        .then(|| {
            allocation
                .iter()
                .zip(&view.finest)
                .zip(&view.errors)
                .filter(|((a, finest), _)| a.level > **finest)
                .map(|((a, _), e)| e.pixels(a.level))
                .fold(None, |m: Option<f64>, e| Some(m.map_or(e, |m| m.max(e))))
        })
        .flatten();
    FramePlan {
        neighbourhood: view.neighbourhood,
        water_px,
        conformed,
        pixels_per_metre: view.errors.iter().map(|e| e.pixels_per_metre).collect(),
        holes: view.cut.holes.len(),
        cut: view.cut,
        importance: view.importance.values,
        allocation,
        offered,
        budget: inputs.budget,
        need: view.need,
        bound,
    }
}

/// Spends what conforming left of `budget` on the tiles away from the borders between pyramid
/// levels, whose levels stitching does not tie: a level finer at a time, the tile showing the
/// largest error first, none finer than its cap.
fn top_up(inputs: &FrameInputs, view: &ViewPlan, plan: &mut Levels, budget: usize) {
    let (allocation, offered, _) = plan;
    let border = pyramid_borders(&view.neighbourhood);
    let mut left = budget.saturating_sub(allocation.iter().map(|a| a.triangles).sum());
    let finer = |level: usize| {
        inputs
            .masks
            .levels()
            .iter()
            .rev()
            .find(|&&l| l < level)
            .copied()
    };
    let mut heap: BinaryHeap<(OrderedError, usize)> = (0..allocation.len())
        .filter(|&k| !border[k] && allocation[k].level > view.finest[k])
        .map(|k| (OrderedError(view.errors[k].pixels(allocation[k].level)), k))
        .collect();
    while let Some((_, k)) = heap.pop() {
        let a = &mut allocation[k];
        let Some(next) = finer(a.level).filter(|&l| l >= view.finest[k]) else {
            continue;
        };
        let cost = inputs
            .masks
            .triangle_count(next)
            .saturating_sub(a.triangles);
        if cost > left {
            continue;
        }
        left -= cost;
        a.level = next;
        a.triangles += cost;
        offered[k].level = offered[k].level.min(next);
        if next > view.finest[k] {
            heap.push((OrderedError(view.errors[k].pixels(next)), k));
        }
    }
}

/// A screen error ordered as a number (never NaN: errors are finite or infinite).
#[derive(Clone, Copy, Debug, PartialEq)]
struct OrderedError(f64);

impl Eq for OrderedError {}

impl PartialOrd for OrderedError {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for OrderedError {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&other.0)
    }
}

/// Makes the levels of tiles that meet a tile of another pyramid level stitch ([`conform`]):
/// finer where needed, the offers with them (a tile holding too few levels for its conformed
/// mask is then asked for them). Returns which tiles changed.
fn conform_levels(
    inputs: &FrameInputs,
    view: &ViewPlan,
    allocation: &mut [TileAllocation],
    offered: &mut [TileAllocation],
) -> Vec<bool> {
    let cut = &view.cut;
    let mut levels: Vec<usize> = allocation.iter().map(|a| a.level).collect();
    let finest: Vec<usize> = cut
        .tiles
        .iter()
        .map(|(_, t, _)| t.finest_mask_level())
        .collect();
    let error = |k: usize, level: usize| {
        let metres = cut.tiles[k].1.level_errors.get(level).copied();
        metres.map_or(f64::INFINITY, f64::from)
    };
    let mut changed = vec![false; levels.len()];
    let tile_size = inputs.terrain.tile_size;
    if !conform(
        &view.neighbourhood,
        &mut levels,
        tile_size,
        |k| finest[k],
        error,
    ) {
        return changed;
    }
    for (((a, o), level), c) in allocation
        .iter_mut()
        .zip(offered.iter_mut())
        .zip(levels)
        .zip(&mut changed)
    {
        if level != a.level {
            *c = true;
            a.level = level;
            a.triangles = inputs.masks.triangle_count(level);
        }
        o.level = o.level.min(level);
    }
    changed
}

impl<'p> FramePlan<'p> {
    /// Triangles the chosen masks hold.
    fn triangles(&self) -> usize {
        self.allocation.iter().map(|a| a.triangles).sum()
    }

    /// The draw list: each tile with its level and its neighbours' levels (for crack hiding).
    fn draws(&self, tile_size: usize) -> Vec<TileDraw<'p>> {
        let levels: Vec<usize> = self.allocation.iter().map(|a| a.level).collect();
        self.cut
            .tiles
            .iter()
            .zip(neighbour_levels(&self.neighbourhood, &levels, tile_size))
            .zip(&levels)
            .map(|((&(id, tile, distance), neighbours), &level)| TileDraw {
                id,
                tile,
                level,
                neighbours,
                distance,
            })
            .collect()
    }

    /// The report's drawn tiles, with each level's geometric error on screen
    /// ([`FrameInputs::pixels_per_metre`]).
    fn rendered(&self) -> Vec<RenderedTile> {
        self.cut
            .tiles
            .iter()
            .zip(self.allocation.iter().zip(&self.offered))
            .zip(self.importance.iter().zip(&self.pixels_per_metre))
            .zip(&self.conformed)
            .map(
                |(((&(id, tile, _), (a, o)), (&importance, &ppm)), &conformed)| RenderedTile {
                    id,
                    importance,
                    level: a.level,
                    error_px: error_px(tile, a.level, ppm),
                    capped: a.level > o.level,
                    conformed,
                },
            )
            .collect()
    }
}

/// The views ahead of the frame that streaming asks for.
#[derive(Clone, Copy)]
struct Ahead<'a> {
    /// The camera when this frame's requests arrive: a tile out of its view by then would
    /// not draw what it asked for.
    arrival: Option<&'a Camera>,
    /// The predicted view, with prediction.
    predicted: Option<&'a PredictedView>,
}

/// What the pager should fetch for this frame: the levels the frame's budget offers each tile
/// drawn (no more than it holds for a tile that will have left the view when they arrive), the
/// tiles its cut lacks (the coarsest level; over a hole above everything) and the tiles it went
/// through (their coarsest level, which keeps the drawn tiles reachable); and the same for the
/// predicted view at half weight. The belt pager takes from them the tiles of the pyramid's
/// levels above 0; a progressive pager, all.
fn frame_wants(
    inputs: &FrameInputs<'_>,
    plan: &FramePlan<'_>,
    ahead: Ahead<'_>,
    aspect: f64,
) -> Vec<Want> {
    let levels = progressive_levels(inputs.terrain.tile_size);
    let arrival = ahead.arrival.map(|c| {
        (
            c.position,
            Frustum::from_view_projection(&c.view_projection(aspect)),
        )
    });
    // A tile whose children the cut asks for is about to be replaced by them: its own finer
    // levels would arrive to be drawn no more.
    let refined: HashSet<TileId> = plan
        .cut
        .missing
        .iter()
        .filter(|&&(id, _)| id.level < inputs.pyramid.root().level)
        .map(|&(id, _)| id.parent())
        .collect();
    let mut wants: Vec<Want> = plan
        .cut
        .tiles
        .iter()
        .zip(&plan.offered)
        .zip(&plan.pixels_per_metre)
        .map(|((&(id, tile, _), o), &ppm)| {
            let wished = levels_for_mask(o.level, levels);
            let stays = !refined.contains(&id)
                && arrival.as_ref().is_none_or(|(eye, frustum)| {
                    frustum.intersects(&held_box(inputs.terrain, id, tile, *eye))
                });
            Want {
                id,
                levels: if stays {
                    wished
                } else {
                    wished.min(tile.levels)
                },
                priority: shown_error_px(tile, ppm),
                predicted: false,
                drawn: true,
            }
        })
        .collect();
    wants.extend(cut_wants(&plan.cut, false));
    if let Some(view) = ahead.predicted {
        wants.extend(predicted_wants(inputs, view, aspect));
    }
    wants
}

/// The wishes a cut makes beyond its drawn tiles: the coarsest level of each tile it lacks, of
/// each tile it went through and of each absent tile it met, with their priorities (halved for
/// the predicted view's).
fn cut_wants(cut: &Cut<'_>, predicted: bool) -> Vec<Want> {
    let weight = if predicted { 0.5 } else { 1.0 };
    // The tiles gone through come last: they spare work, they add no detail.
    let through = cut.through.iter().map(|&id| (id, 0.0));
    let wants = cut
        .missing
        .iter()
        .chain(&cut.passed)
        .copied()
        .chain(through)
        .map(|(id, priority)| Want {
            id,
            levels: 1,
            priority: weight * priority,
            predicted,
            drawn: false,
        });
    // An absent tile in view is drawn as nothing, and kept as a drawn tile is: without it,
    // the tile above could not be replaced by its children and would draw over all of them.
    let absent = cut.absent.iter().map(|&id| Want {
        id,
        levels: 1,
        priority: 0.0,
        predicted,
        drawn: !predicted,
    });
    wants.chain(absent).collect()
}

/// The box of resident tile `id` between its lowest and highest held heights, relative to `eye`.
fn held_box(terrain: &TerrainFrame, id: TileId, tile: &ResidentTile, eye: DVec3) -> Aabb {
    let (lo, hi) = terrain.tile_box(id, f64::from(tile.min), f64::from(tile.max));
    Aabb::new(lo - eye, hi - eye)
}

/// The predicted view's wishes: the tiles of its (pulled-back) cut, weighed from the predicted
/// eye, given the levels this frame's budget would buy them there, at half the error they would
/// show there (a guess counts less than what is on screen), and what that cut lacks.
fn predicted_wants(inputs: &FrameInputs<'_>, view: &PredictedView, aspect: f64) -> Vec<Want> {
    let terrain = inputs.terrain;
    let seen = inputs.cut(&view.cull, aspect);
    let measures: Vec<TileMeasure> = seen
        .tiles
        .iter()
        .map(|&(id, tile, _)| TileMeasure {
            distance: held_box(terrain, id, tile, view.camera.position).distance(DVec3::ZERO),
            height: f64::from(tile.max - tile.min),
        })
        .collect();
    let importance = visual_importance(&measures, inputs.weights);
    let needed = inputs.needed_levels(
        &view.camera,
        seen.tiles
            .iter()
            .zip(&measures)
            .map(|(s, m)| (s.1, m.distance)),
    );
    // The predicted view shares the budget the way the frame does, so that what it asks for
    // ahead is what the frame will draw when the eye gets there.
    let errors = inputs.tile_errors(
        &view.camera,
        seen.tiles
            .iter()
            .zip(&measures)
            .map(|(s, m)| (s.0, s.1, m.distance)),
    );
    let offered =
        inputs
            .allocation
            .share(inputs.budget, &importance, inputs.masks, &errors, &needed);
    let levels = progressive_levels(terrain.tile_size);
    let mut wants: Vec<Want> = seen
        .tiles
        .iter()
        .zip(&offered)
        .zip(&errors)
        .map(|((&(id, tile, _), o), e)| Want {
            id,
            levels: levels_for_mask(o.level, levels),
            priority: 0.5 * shown_error_px(tile, e.pixels_per_metre),
            predicted: true,
            drawn: false,
        })
        .collect();
    wants.extend(cut_wants(&seen, true));
    wants
}

/// The screen error `tile` shows at the finest mask its held levels draw, in pixels at
/// `pixels_per_metre` (as the allocation counts it, [`TileErrors::pixels`]): the priority of
/// its wish, so that the pager fetches the worst-looking tile first, the tile under a low eye
/// before the far ones. The visual importance, a share among the tiles in view that differs
/// little between them, would fetch them in almost arbitrary order.
fn shown_error_px(tile: &ResidentTile, pixels_per_metre: f64) -> f64 {
    error_px(tile, tile.finest_mask_level(), pixels_per_metre)
}

/// The screen error of `tile`'s mask level `level` at `pixels_per_metre`, as the allocation
/// counts it ([`TileErrors::pixels`]): what the report shows and what the pager ranks by agree
/// with what shared the budget, a level without a known error included.
fn error_px(tile: &ResidentTile, level: usize, pixels_per_metre: f64) -> f64 {
    TileErrors {
        metres: &tile.level_errors,
        pixels_per_metre,
        kept: None,
    }
    .pixels(level)
}

/// The most of the memory limit the top may take: the rest is for paging.
const TOP_SHARE: usize = 4;

/// The most of the memory limit set aside for the archive's index pages, and at most
/// [`MAX_INDEX_BYTES`]: a view's pages, a few kilobytes each.
const INDEX_SHARE: usize = 16;

/// The most bytes set aside for the archive's index pages: a few hundred pages.
const MAX_INDEX_BYTES: usize = 1 << 20;

/// The bytes the engine sets aside for the archive's index pages under a memory limit of
/// `limit` bytes.
pub fn index_allowance(limit: usize) -> usize {
    (limit / INDEX_SHARE).min(MAX_INDEX_BYTES)
}

/// Which levels of the archive's top the engine keeps: all of them, fewer (the root and the
/// levels just below it) while they would take more than a quarter of the memory limit, none
/// when even the root would.
fn choose_top(loader: &mut ArchiveLoader, settings: &EngineSettings, pyramid: &Pyramid) {
    let root = pyramid.root().level;
    let mut level = loader.use_top(Some(0));
    while let Some(l) = level {
        if loader.top_bytes() <= settings.memory_limit_bytes / TOP_SHARE {
            return;
        }
        level = if l < root {
            loader.use_top(Some(l + 1))
        } else {
            loader.use_top(None)
        };
    }
}

/// Refuses a memory limit under which nothing could ever be drawn: no top fits it, nor the
/// smallest copy of one tile the pager loads (a whole tile beside the viewer, or one level).
fn check_memory_holds_something(loader: &ArchiveLoader, settings: &EngineSettings) -> Result<()> {
    if loader.top_bytes() > 0 {
        return Ok(());
    }
    let smallest = match settings.streaming {
        Streaming::Progressive(_) => LevelLoader::predicted_bytes(loader, 1),
        Streaming::Belts => TileLoader::predicted_bytes(loader, TileId::new(0, 0), 0),
    } + loader.index_bytes();
    if settings.memory_limit_bytes >= smallest {
        return Ok(());
    }
    Err(Error::setting(
        "memory limit (bytes)",
        settings.memory_limit_bytes,
        format!(
            "at least {smallest} bytes: the smallest copy of one tile of {} and its index \
             pages (the top of its pyramid does not fit either), or nothing is ever drawn",
            loader.reader().name()
        ),
    ))
}

/// Progressive streaming's textures follow the levels importance asks for, which a separate
/// texture budget would contradict.
fn check_progressive(settings: &EngineSettings) -> Result<()> {
    if settings.texture_budget_bytes.is_some() {
        return Err(Error::Conflict {
            first: "progressive streaming",
            second: "a texture budget",
            reason: "progressive streaming holds exactly the texture mips of the levels it \
                     holds: a separate texture budget does not apply (drop --texture-mb)"
                .into(),
        });
    }
    Ok(())
}

/// Morphed heights count 1/[`SUBDIVISION`] quanta in an i32: refuses an archive whose heights
/// would not fit when geomorphing is on.
fn check_morph_range(settings: &EngineSettings, terrain: &TerrainFrame, name: &str) -> Result<()> {
    let limit = f64::from(i32::MAX / SUBDIVISION - i32::from(u16::MAX));
    let reach = terrain.heights.0.abs().max(terrain.heights.1.abs()) / terrain.quantum;
    if settings.geomorph != Geomorph::Off && reach >= limit {
        return Err(Error::invalid(
            name,
            format!(
                "heights up to {reach:.0} quanta are beyond the {limit:.0} that geomorphing \
                 can count in 1/{SUBDIVISION} quanta: turn geomorphing off"
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_absent_tile_in_view_is_wished_as_a_drawn_tile_and_a_predicted_one_is_not() {
        let sea = TileId::at(2, 1, 1);
        let cut = Cut {
            absent: vec![sea],
            ..Cut::default()
        };
        let now = cut_wants(&cut, false);
        assert_eq!(now.len(), 1);
        assert!(now[0].id == sea && now[0].drawn && !now[0].predicted && now[0].levels == 1);
        let ahead = cut_wants(&cut, true);
        assert!(ahead[0].id == sea && !ahead[0].drawn && ahead[0].predicted);
    }
}
