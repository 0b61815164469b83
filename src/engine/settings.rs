//! Everything a run can set, and the checks that refuse settings under which nothing could be
//! drawn.

use crate::db::grid::TileId;
use crate::engine::allocation::Allocation;
use crate::engine::budget::BudgetSettings;
use crate::engine::cracks::CrackMode;
use crate::engine::error_bound::ErrorBound;
use crate::engine::geomorph::{Geomorph, SUBDIVISION};
use crate::engine::importance::Weights;
use crate::engine::masks::LevelSet;
use crate::engine::paging::stream::{LevelLoader, Streaming};
use crate::engine::paging::{ArchiveLoader, PagerMode, ResidentLoader, TileLoader};
use crate::engine::render::RenderSettings;
use crate::engine::shading::Light;
use crate::engine::terrain::TerrainFrame;
use crate::error::{Error, Result};

/// Where the triangle budget learns how long frames take.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FrameTiming {
    /// [`Engine::render`](crate::engine::Engine::render) times itself, from taking in arrived
    /// tiles to the last pixel, and the budget follows: the target frame rate is the rate at
    /// which the engine alone could draw.
    #[default]
    Measured,
    /// Each frame's time is told with
    /// [`Engine::record_frame`](crate::engine::Engine::record_frame): a simulated device's
    /// modelled time, or a whole frame as the application times it. Until told, the budget
    /// stays where it is, so runs repeat exactly.
    Told,
}

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
    /// Where the frame-rate controller learns how long frames take.
    pub frame_timing: FrameTiming,
    /// The pixel-error bound τ: no tile finer than its projected error needs.
    pub max_error: ErrorBound,
    /// How the tiles in view share the triangle budget: by importance or by projected error.
    pub allocation: Allocation,
    /// Sun direction and ambient light.
    pub light: Light,
    /// How near the eye comes to the ground, metres: no tile is refined for a view nearer than
    /// this, and [`Engine::camera`](crate::engine::Engine::camera) places the eye at least this
    /// high above the held ground.
    pub clearance: f64,
    /// Whether a camera is lifted to `clearance` above the ground when tiles arrive under it
    /// and find it lower (a flight placed over ground that was not held yet). Off, every
    /// camera is drawn exactly where its caller put it.
    pub lift_to_clearance: bool,
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
            frame_timing: FrameTiming::Measured,
            max_error: ErrorBound::default(),
            allocation: Allocation::default(),
            light: Light::default(),
            clearance: 20.0,
            lift_to_clearance: false,
            threads: 0,
            streaming: Streaming::Belts,
            keep_top: true,
            fit_cut_to_budget: true,
        }
    }
}

/// Refuses a memory limit under which nothing could ever be drawn: no top fits it, nor the
/// smallest copy of one tile the pager loads (a whole tile beside the viewer, or one level).
pub(super) fn check_memory_holds_something(
    loader: &ArchiveLoader,
    settings: &EngineSettings,
) -> Result<()> {
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
pub(super) fn check_progressive(settings: &EngineSettings) -> Result<()> {
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
pub(super) fn check_morph_range(
    settings: &EngineSettings,
    terrain: &TerrainFrame,
    name: &str,
) -> Result<()> {
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
