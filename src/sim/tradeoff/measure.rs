//! Measuring settings: one engine per crack mode and thread count with every tile loaded,
//! frames timed round-robin over the settings (so machine noise falls on all of them alike) in
//! process CPU time (what the frame costs, whatever else runs on the machine) and wall time,
//! images compared with every reference, and the screen-space error of the chosen masks.

use std::collections::HashMap;
use std::time::Instant;

use cpu_time::ProcessTime;
use image::RgbaImage;
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

use super::knobs::{Budget, Setting};
use super::metrics::{ImageError, compare};
use super::reference::Reference;
use super::sweep::Entry;
use super::views::Viewpoint;
use crate::db::source;
use crate::engine::camera::Camera;
use crate::engine::cracks::CrackMode;
use crate::engine::error_bound::ErrorBound;
use crate::engine::geomorph::Geomorph;
use crate::engine::paging::PagerMode;
use crate::engine::viewport::Viewport;
use crate::engine::{Engine, EngineSettings, FrameReport, FrameTiming};
use crate::error::{Error, Result};

/// The most frames a view is rendered to settle: the pyramid's levels come one a frame.
const SETTLE_FRAMES: usize = 16;

/// What one setting measured over all views.
#[derive(Clone, Debug, PartialEq)]
pub struct Measurement {
    /// Median over the repeats of the mean process CPU time of a frame over the views, seconds:
    /// the cost a one-core device pays; other processes on the machine do not inflate it.
    pub frame_seconds: f64,
    /// The same in wall-clock time: what extra threads buy, and what machine load adds.
    pub wall_seconds: f64,
    /// Triangles the chosen masks hold, mean per view.
    pub triangles: f64,
    /// Error against each reference, in the order given: MSE pooled over the views, SSIM the
    /// mean of the views', pixels off summed.
    pub errors: Vec<ImageError>,
    /// The largest screen-space geometric error of a drawn tile over all views, pixels.
    pub geometric_max_px: f64,
    /// The mean over the views of each view's largest screen-space geometric error, pixels.
    pub geometric_mean_px: f64,
}

/// Engines with every tile of the archive loaded, one per crack mode, geomorph and thread count (the
/// settings an engine is built with); everything else changes between frames.
pub struct Bench {
    source: String,
    size: (u32, u32),
    engines: Vec<((CrackMode, Geomorph, usize), Engine)>,
    framebuffers: HashMap<(ColorFormat, DepthFormat), Framebuffer>,
    views: Vec<Viewpoint>,
    cameras: Vec<Camera>,
}

impl Bench {
    /// A bench over the archive `source` for frames of `size`, showing `views`.
    pub fn new(source: &str, size: (u32, u32), views: Vec<Viewpoint>) -> Result<Bench> {
        let mut bench = Bench {
            source: source.to_string(),
            size,
            engines: Vec::new(),
            framebuffers: HashMap::new(),
            views,
            cameras: Vec::new(),
        };
        // Cameras from an engine with every tile loaded, so that views following the ground
        // know where it is.
        let views = bench.views.clone();
        let engine = bench.engine(CrackMode::default(), Geomorph::Off, 1)?;
        let (w, h) = size;
        let mut fb = Framebuffer::new(w, h, ColorFormat::Rgb565, DepthFormat::D16)?;
        for v in &views {
            engine.render(&engine.camera(v.eye, v.target, v.above_ground), &mut fb)?;
        }
        bench.cameras = views
            .iter()
            .map(|v| engine.camera(v.eye, v.target, v.above_ground))
            .collect();
        Ok(bench)
    }

    /// The views, in order.
    pub fn views(&self) -> &[Viewpoint] {
        &self.views
    }

    /// Measures `entries`, `repeats` times each (at least once), against `references`;
    /// `threshold` is the channel difference that makes a pixel count as off. Returns the
    /// measurements and each reference's picture of each view. `progress` is told each view.
    ///
    /// View by view: every engine first renders the view untimed (the pager re-ranks its belts
    /// around the new position and upgrades the textures of tiles that came nearer), then the
    /// references render it, then every setting renders it `repeats` times, round-robin.
    pub fn measure(
        &mut self,
        entries: &[Entry],
        repeats: usize,
        references: &mut [Box<dyn Reference>],
        threshold: u8,
        progress: &dyn Fn(&Viewpoint),
    ) -> Result<(Vec<Measurement>, Vec<Vec<RgbaImage>>)> {
        let repeats = repeats.max(1);
        let views = self.cameras.len().max(1) as f64;
        for entry in entries {
            self.engine(
                entry.setting.cracks,
                entry.setting.geomorph,
                entry.setting.threads,
            )?;
        }
        let mut cpu = vec![vec![0.0; repeats]; entries.len()];
        let mut wall = vec![vec![0.0; repeats]; entries.len()];
        let mut scores = vec![Vec::new(); entries.len()];
        let mut pictures = vec![Vec::new(); references.len()];
        for v in 0..self.cameras.len() {
            progress(&self.views[v]);
            self.settle(v)?;
            let (size, camera) = (self.size, self.cameras[v]);
            let engine = self.engine(CrackMode::default(), Geomorph::Off, 1)?;
            let mut images = Vec::new();
            for (reference, kept) in references.iter_mut().zip(&mut pictures) {
                apply(engine, &Setting::default());
                let image = reference.render(engine, &camera, size)?;
                kept.push(image.clone());
                images.push(image);
            }
            for rep in 0..repeats {
                for (k, entry) in entries.iter().enumerate() {
                    let (elapsed, report, image) = self.frame(&entry.setting, v, rep == 0)?;
                    cpu[k][rep] += elapsed.0 / views;
                    wall[k][rep] += elapsed.1 / views;
                    if let Some(image) = image {
                        let errors: Vec<ImageError> = images
                            .iter()
                            .map(|reference| compare(&image, reference, threshold))
                            .collect();
                        let geometric = geometric_error_px(&report);
                        scores[k].push((errors, geometric, report.triangles as f64));
                    }
                }
            }
        }
        let median = |mut t: Vec<f64>| {
            t.sort_by(f64::total_cmp);
            t[t.len() / 2]
        };
        let measurements = scores
            .into_iter()
            .zip(cpu.into_iter().zip(wall))
            .map(|(per_view, (cpu, wall))| Measurement {
                frame_seconds: median(cpu),
                wall_seconds: median(wall),
                ..pooled(&per_view, references.len())
            })
            .collect();
        Ok((measurements, pictures))
    }

    /// Renders view `v`, untimed, in every engine at full resolution until nothing more
    /// arrives for it (the cut asks for the tiles of the pyramid it lacks, which come a level a
    /// frame), and checks that every level-0 tile is loaded.
    fn settle(&mut self, v: usize) -> Result<()> {
        let camera = self.cameras[v];
        let (w, h) = self.size;
        let mut fb = Framebuffer::new(w, h, ColorFormat::Rgb565, DepthFormat::D16)?;
        for (_, engine) in &mut self.engines {
            // At full resolution, the deepest cut any setting draws: every tile is there for all.
            engine.set_max_error(ErrorBound::Off);
            let mut held = None;
            for _ in 0..SETTLE_FRAMES {
                engine.render(&camera, &mut fb)?;
                let stats = engine.pager().stats();
                let now = Some(stats.loaded_tiles);
                if stats.fetching == 0 && now == held {
                    break;
                }
                held = now;
            }
            let terrain = engine.terrain();
            let all = terrain.tiles_x as usize * terrain.tiles_y as usize;
            let level0 = engine
                .pager()
                .tiles()
                .filter(|(id, _)| id.level == 0)
                .count();
            let stats = engine.pager().stats();
            if level0 != all || stats.fetching != 0 {
                let why = engine
                    .pager()
                    .last_error()
                    .unwrap_or("memory or fetch failure");
                return Err(Error::invalid(
                    &self.source,
                    format!("only {level0} of {all} tiles loaded: {why}"),
                ));
            }
        }
        Ok(())
    }

    /// Renders view `v` in `setting`; returns the process CPU and wall time `Engine::render`
    /// took, its report, and the picture when `keep`.
    fn frame(
        &mut self,
        setting: &Setting,
        v: usize,
        keep: bool,
    ) -> Result<((f64, f64), FrameReport, Option<RgbaImage>)> {
        let camera = self.cameras[v];
        let (w, h) = self.size;
        let key = (setting.color, setting.depth);
        let mut fb = match self.framebuffers.remove(&key) {
            Some(fb) => fb,
            None => Framebuffer::new(w, h, key.0, key.1)?,
        };
        let engine = self.engine(setting.cracks, setting.geomorph, setting.threads)?;
        apply(engine, setting);
        let (cpu, wall) = (ProcessTime::now(), Instant::now());
        let report = engine.render(&camera, &mut fb);
        let elapsed = (cpu.elapsed().as_secs_f64(), wall.elapsed().as_secs_f64());
        let image = keep.then(|| fb.to_rgba_image());
        self.framebuffers.insert(key, fb);
        Ok((elapsed, report?, image))
    }

    /// The engine for `cracks`, `geomorph` and `threads` (settings an engine is built with),
    /// built and filled with every tile on first use.
    fn engine(
        &mut self,
        cracks: CrackMode,
        geomorph: Geomorph,
        threads: usize,
    ) -> Result<&mut Engine> {
        let key = (cracks, geomorph, threads);
        if let Some(k) = self.engines.iter().position(|(k, _)| *k == key) {
            return Ok(&mut self.engines[k].1);
        }
        let settings = EngineSettings {
            cracks,
            geomorph,
            threads,
            memory_limit_bytes: 1 << 30,
            pager_mode: PagerMode::Stepped {
                fetches_per_update: usize::MAX,
            },
            // Every frame at a held budget.
            frame_timing: FrameTiming::Told,
            ..EngineSettings::default()
        };
        let engine = Engine::new(
            source::open(&self.source)?,
            settings,
            Viewport::new(self.size.0, self.size.1),
        )?;
        self.engines.push((key, engine));
        Ok(&mut self.engines.last_mut().expect("pushed").1)
    }
}

/// Pools one setting's per-view `(errors per reference, geometric error, triangles)`: MSE over
/// all pixels, SSIM the mean of the views', pixels off summed; geometric error max and mean.
fn pooled(per_view: &[(Vec<ImageError>, f64, f64)], references: usize) -> Measurement {
    let views = per_view.len().max(1) as f64;
    let errors = (0..references)
        .map(|r| {
            let mut total = ImageError::default();
            let mut squared = 0.0;
            for (errors, _, _) in per_view {
                let e = &errors[r];
                squared += e.mse * e.pixels as f64;
                total.ssim += e.ssim / views;
                total.pixels_off += e.pixels_off;
                total.pixels += e.pixels;
            }
            total.mse = squared / total.pixels.max(1) as f64;
            total
        })
        .collect();
    let geometric = per_view.iter().map(|p| p.1);
    Measurement {
        frame_seconds: 0.0,
        wall_seconds: 0.0,
        triangles: per_view.iter().map(|p| p.2).sum::<f64>() / views,
        errors,
        geometric_max_px: geometric.clone().fold(0.0, f64::max),
        geometric_mean_px: geometric.sum::<f64>() / views,
    }
}

/// Sets `engine` up for a frame in `setting` (the parts not fixed when the engine was built).
fn apply(engine: &mut Engine, setting: &Setting) {
    *engine.render_settings_mut() = setting.render;
    engine.set_max_error(setting.max_error);
    engine.set_allocation(setting.allocation);
    match setting.budget {
        // Full resolution: every tile of the model's own grid at its finest mask, whatever τ.
        Budget::Full => {
            engine.set_max_error(ErrorBound::Off);
            engine.force_levels(Some(Box::new(|_| 0)));
        }
        Budget::Triangles(n) => {
            engine.force_levels(None);
            engine.hold_budget(n);
        }
    }
}

/// The largest screen-space error of a drawn tile: its mask level's height error (from the
/// archive, metres) times pixels per metre at its bounding box's distance from the eye.
fn geometric_error_px(report: &FrameReport) -> f64 {
    report
        .rendered
        .iter()
        .map(|t| t.error_px)
        .fold(0.0, f64::max)
}
