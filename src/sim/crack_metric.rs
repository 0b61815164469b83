//! The crack metric: views in which the terrain covers the whole screen, drawn over a background
//! colour that terrain never has, so that every background pixel is a crack.
//!
//! [`CrackScene`] is the standard measurement: a hilly synthetic archive of small tiles (9
//! samples, so 8 levels) whose levels are pinned by [`pair_pattern`] so that every pair of levels
//! meets across some border, seen from a grid of oblique views with the horizon out of frame.
//! [`CrackScene::measure`] renders every view in one crack mode and reports crack pixels,
//! triangles and drawing time; the views are checked to include every level pair.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::time::Duration;

use glam::{DVec3, DVec4};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

use crate::db::builder::{BuildOptions, build};
use crate::db::dem::{MemoryReader, NodataFill};
use crate::db::grid::TileId;
use crate::db::source;
use crate::engine::camera::View;
use crate::engine::cracks::CrackMode;
use crate::engine::error_bound::ErrorBound;
use crate::engine::paging::PagerMode;
use crate::engine::viewport::Viewport;
use crate::engine::{Engine, EngineSettings, FrameTiming};
use crate::error::Result;

/// The background of crack views: pure magenta, exact in RGB565, never a terrain colour.
pub const BACKGROUND: [u8; 3] = [255, 0, 255];

/// Pixels of `fb` that show the background.
pub fn crack_pixels(fb: &Framebuffer) -> usize {
    (0..fb.height())
        .flat_map(|y| (0..fb.width()).map(move |x| (x, y)))
        .filter(|&(x, y)| fb.pixel(x, y) == BACKGROUND)
        .count()
}

/// Mask levels for tiles such that, in every block of `2 levels` by `levels` tiles, each
/// ordered pair `(a, b)` of levels below `levels` meets across an east-west border: in row `y`
/// the even columns are at level `y` and column `2 k + 1` at level `k` (both mod `levels`).
pub fn pair_pattern(levels: usize) -> impl Fn(TileId) -> usize + Send + 'static {
    move |id: TileId| {
        let (x, y) = (id.x as usize, id.y as usize);
        if x % 2 == 0 {
            y % levels
        } else {
            (x / 2) % levels
        }
    }
}

/// The unordered level pairs `(low, high)` of neighbouring tiles whose shared edge has its
/// midpoint on screen in `view` (a frame's view; its matrix is eye-relative).
pub fn pairs_in_view(
    engine: &Engine,
    view: &View,
    level_of: &dyn Fn(TileId) -> usize,
) -> BTreeSet<(usize, usize)> {
    let terrain = engine.terrain();
    let view_projection = view.view_projection();
    let side = terrain.tile_metres();
    let mut pairs = BTreeSet::new();
    for y in 0..terrain.tiles_y {
        for x in 0..terrain.tiles_x {
            let here = TileId::new(x, y);
            let neighbours = [
                (x + 1 < terrain.tiles_x)
                    .then(|| (TileId::new(x + 1, y), DVec3::new(side, 0.0, side / 2.0))),
                (y + 1 < terrain.tiles_y)
                    .then(|| (TileId::new(x, y + 1), DVec3::new(side / 2.0, 0.0, side))),
            ];
            for (there, offset) in neighbours.into_iter().flatten() {
                let mut mid = terrain.tile_origin(here) + offset;
                let Some(ground) = engine.ground(mid) else {
                    continue;
                };
                mid.y = ground;
                let clip = view_projection * DVec4::from((mid - view.camera.position, 1.0));
                let ndc = clip.truncate() / clip.w;
                if clip.w > 0.0 && ndc.x.abs() < 1.0 && ndc.y.abs() < 1.0 {
                    let (a, b) = (level_of(here), level_of(there));
                    pairs.insert((a.min(b), a.max(b)));
                }
            }
        }
    }
    pairs
}

/// Samples per tile side of the crack scene.
pub const TILE_SIZE: usize = 9;
const TILES_X: usize = 19;
const TILES_Y: usize = 13;
const SPACING: f64 = 30.0;
/// The scene's vertical field of view: narrow, so that the tiles' borders span many pixels.
const FOV_Y: f64 = 40.0 * (std::f64::consts::PI / 180.0);

/// The crack scene: an archive and its views.
#[derive(Clone, Debug)]
pub struct CrackScene {
    /// The archive file.
    pub archive: PathBuf,
    /// Eye and target of each view, terrain-frame metres.
    pub views: Vec<(DVec3, DVec3)>,
}

/// What one crack mode gives on the crack scene.
#[derive(Clone, Debug, PartialEq)]
pub struct CrackMeasurement {
    /// The mode measured.
    pub mode: CrackMode,
    /// Background pixels over all views.
    pub crack_pixels: usize,
    /// Triangles assembled over all views (masks plus the mode's extra geometry).
    pub triangles: u64,
    /// Triangles the plain strip masks of the same levels hold over all views.
    pub mask_triangles: u64,
    /// Drawing time summed over the views, each view's the median of its repeats.
    pub draw_time: Duration,
    /// The level pairs whose shared edges the views show.
    pub pairs: BTreeSet<(usize, usize)>,
}

impl CrackScene {
    /// Writes the scene's archive into `dir`: `19 x 13` tiles of 9 samples, 30 m apart, over
    /// hills with ridges a few samples wide, so that coarse levels err by tens of metres.
    pub fn build(dir: &Path) -> Result<CrackScene> {
        let (w, h) = (TILES_X * (TILE_SIZE - 1) + 1, TILES_Y * (TILE_SIZE - 1) + 1);
        let samples = (0..w * h)
            .map(|k| {
                let (i, j) = ((k % w) as f32, (k / w) as f32);
                300.0
                    + 150.0 * (i * 0.35).sin() * (j * 0.27).cos()
                    + 60.0 * (i * 1.3 + j * 0.9).sin()
            })
            .collect();
        let reader = MemoryReader::new("crack-scene", w, h, samples)?;
        let archive = dir.join("crack-scene.smdb");
        let options = BuildOptions {
            tile_size: TILE_SIZE,
            spacing: Some(SPACING),
            texture_factor: 4,
            ..BuildOptions::default()
        };
        build(
            NodataFill::new(reader, None),
            &archive,
            &options,
            &|_, _| {},
        )?;
        let tile = (TILE_SIZE - 1) as f64 * SPACING;
        // 190 m above the highest hill, looking north and down at 59 degrees with a 40 degree
        // field of view: the frustum's top edge meets the ground within about 3 tiles even in
        // the deepest valley, and the sides stay within 2 tiles.
        let mut views = Vec::new();
        for vy in 0..4 {
            for vx in 0..8 {
                let eye = DVec3::new(
                    (2.5 + 2.0 * vx as f64) * tile,
                    700.0,
                    (4.5 + 2.4 * vy as f64) * tile,
                );
                let target = eye + DVec3::new(0.0, -250.0, -150.0);
                views.push((eye, target));
            }
        }
        Ok(CrackScene { archive, views })
    }

    /// A grazing view, where the paper's shadows fail: the eye 380 m up in a valley, below the
    /// hills it looks at (terrain still covers the screen).
    pub fn grazing_view() -> (DVec3, DVec3) {
        let tile = (TILE_SIZE - 1) as f64 * SPACING;
        (
            DVec3::new(9.5 * tile, 380.0, 7.5 * tile),
            DVec3::new(9.5 * tile, 250.0, 6.8 * tile),
        )
    }

    /// The engine settings of a measurement in `mode`: fixed point, RGB565-friendly background,
    /// no fog, a 40 degree field of view, one rasterizer thread, every tile of the scene
    /// resident, and the cut at full resolution (τ off), so that every view draws level-0 tiles
    /// alone and the levels met are mask levels.
    pub fn settings(mode: CrackMode) -> EngineSettings {
        let mut settings = EngineSettings {
            cracks: mode,
            memory_limit_bytes: 64 << 20,
            pager_mode: PagerMode::Stepped {
                fetches_per_update: 256,
            },
            threads: 1,
            max_error: ErrorBound::Off,
            // The scene's frames are measured at the budgets they are given.
            frame_timing: FrameTiming::Told,
            ..EngineSettings::default()
        };
        settings.render.sky = BACKGROUND;
        settings.render.fog = false;
        settings
    }

    /// An engine over the scene in `mode`, every tile loaded and levels pinned by
    /// [`pair_pattern`], for frames of `size`.
    pub fn engine(&self, mode: CrackMode, size: (u32, u32)) -> Result<Engine> {
        self.engine_with(Self::settings(mode), size)
    }

    /// The same with `settings` (e.g. [`CrackScene::settings`] with geomorphing on).
    pub fn engine_with(&self, settings: EngineSettings, size: (u32, u32)) -> Result<Engine> {
        let source = source::open(&self.archive.display().to_string())?;
        let viewport = Viewport::new(size.0, size.1).with_fov_y(FOV_Y);
        let mut engine = Engine::new(source, settings, viewport)?;
        engine.force_levels(Some(Box::new(pair_pattern(TILE_SIZE - 1))));
        let mut fb = Framebuffer::new(size.0, size.1, ColorFormat::Rgb565, DepthFormat::D16)?;
        // The whole scene from high above at full resolution: the cut asks for every tile of
        // every level, which come a level a frame.
        let tile = (TILE_SIZE - 1) as f64 * SPACING;
        let centre = DVec3::new(
            TILES_X as f64 * tile / 2.0,
            0.0,
            TILES_Y as f64 * tile / 2.0,
        );
        let bound = engine.settings().max_error;
        engine.set_max_error(ErrorBound::Off);
        for _ in 0..8 {
            let camera = engine.camera(centre + DVec3::new(0.0, 20_000.0, 1.0), centre, false);
            engine.render(&camera, &mut fb)?;
        }
        engine.set_max_error(bound);
        Ok(engine)
    }

    /// Renders view `view` in `engine` into `fb`; returns the frame's report.
    pub fn render(
        &self,
        engine: &mut Engine,
        view: usize,
        fb: &mut Framebuffer,
    ) -> Result<crate::engine::FrameReport> {
        let (eye, target) = self.views[view];
        let camera = engine.camera(eye, target, false);
        engine.render(&camera, fb)
    }

    /// Renders every view in `mode` at `size`, `repeats` times each, and measures it.
    pub fn measure(
        &self,
        mode: CrackMode,
        size: (u32, u32),
        repeats: usize,
    ) -> Result<CrackMeasurement> {
        self.measure_with(Self::settings(mode), size, repeats)
    }

    /// The same with `settings` (e.g. [`CrackScene::settings`] with geomorphing on).
    pub fn measure_with(
        &self,
        settings: EngineSettings,
        size: (u32, u32),
        repeats: usize,
    ) -> Result<CrackMeasurement> {
        let mode = settings.cracks;
        let mut engine = self.engine_with(settings, size)?;
        let mut fb = Framebuffer::new(size.0, size.1, ColorFormat::Rgb565, DepthFormat::D16)?;
        let level_of = pair_pattern(TILE_SIZE - 1);
        let mut m = CrackMeasurement {
            mode,
            crack_pixels: 0,
            triangles: 0,
            mask_triangles: 0,
            draw_time: Duration::ZERO,
            pairs: BTreeSet::new(),
        };
        for view in 0..self.views.len() {
            let mut times = Vec::with_capacity(repeats.max(1));
            for _ in 0..repeats.max(1) {
                let report = self.render(&mut engine, view, &mut fb)?;
                times.push(Duration::from_secs_f64(report.draw_seconds));
                if times.len() == 1 {
                    m.crack_pixels += crack_pixels(&fb);
                    m.triangles += report.draw.triangles;
                    m.mask_triangles += report.triangles as u64;
                    m.pairs
                        .extend(pairs_in_view(&engine, &report.view, &level_of));
                }
            }
            times.sort();
            m.draw_time += times[times.len() / 2];
        }
        Ok(m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_pattern_puts_every_ordered_level_pair_side_by_side() {
        let levels = 8;
        let level_of = pair_pattern(levels);
        let mut pairs = BTreeSet::new();
        for y in 0..levels as u32 {
            for x in 0..2 * levels as u32 {
                pairs.insert((level_of(TileId::new(x, y)), level_of(TileId::new(x + 1, y))));
            }
        }
        assert_eq!(pairs.len(), levels * levels);
    }
}
