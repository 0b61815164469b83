//! The interactive viewer behind `stripmask view` (a window) and `stripmask fb` (the Linux
//! framebuffer): the engine's frame loop driven by a [`Presenter`]'s input, with the HUD.
//!
//! Without input the viewer follows a flight path (a scripted run on a board with no keyboard);
//! the first movement key or mouse drag takes over from the path.
//!
//! On the simulated clock ([`ViewerOptions::clock`]) flight time advances by each frame's
//! modelled cost instead of the wall clock, as in `fly`: the same options and the same keys at
//! the same frames give the same pictures on every machine, so a board's screen can be compared
//! with a frame `fly` rendered elsewhere.

use std::time::Instant;

use glam::DVec3;
use stripmask_platform::{Command, Hud, HudInfo, Input, Minimap, Presenter, TileState};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer, Precision};

use crate::belts::TileId;
use crate::engine::{Engine, EngineSettings, FrameReport};
use crate::error::{Error, Result};
use crate::flight::Flight;
use crate::pager::TileState as PagerState;
use crate::simclock::Clock;
use crate::source;

/// The largest minimap side in cells; bigger grids show the part around the viewer.
const MINIMAP_CELLS: u32 = 32;

/// What the viewer shows and how.
#[derive(Clone, Debug)]
pub struct ViewerOptions {
    /// Archive path or URL.
    pub source: String,
    /// Framebuffer size (the output may scale it).
    pub size: (u32, u32),
    /// Colour format.
    pub color: ColorFormat,
    /// Depth buffer format.
    pub depth: DepthFormat,
    /// Engine settings.
    pub engine: EngineSettings,
    /// Start with the HUD on.
    pub hud: bool,
    /// The path followed until the user takes over.
    pub flight: Flight,
    /// Stop after this many frames (`None`: until the user quits).
    pub frames: Option<u64>,
    /// Where frame times come from: the wall clock (interactive), or the simulated clock, which
    /// makes the frames reproducible. Give the simulated clock a pager in
    /// [`crate::pager::PagerMode::Simulated`] ([`Clock::pager_mode`]) for tiles to arrive at
    /// reproducible frames too.
    pub clock: Clock,
}

/// What a session did.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ViewerSummary {
    /// Frames shown.
    pub frames: u64,
    /// Wall-clock seconds.
    pub seconds: f64,
}

/// A camera the user steers: position, heading clockwise from north, pitch up from level.
#[derive(Clone, Copy, Debug, PartialEq)]
struct FreeCamera {
    position: DVec3,
    heading: f64,
    pitch: f64,
}

impl FreeCamera {
    fn from_pose(eye: DVec3, target: DVec3) -> Self {
        let d = (target - eye).normalize_or(DVec3::NEG_Z);
        FreeCamera {
            position: eye,
            heading: d.x.atan2(-d.z),
            pitch: d.y.clamp(-1.0, 1.0).asin(),
        }
    }

    fn forward(&self) -> DVec3 {
        let (sh, ch) = self.heading.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        DVec3::new(sh * cp, sp, -ch * cp)
    }

    /// Applies held keys for `dt` seconds at `speed` m/s, and a mouse drag in pixels.
    fn steer(&mut self, input: &Input, dt: f64, speed: f64) {
        let m = input.motion;
        let axis = |plus: bool, minus: bool| f64::from(u8::from(plus)) - f64::from(u8::from(minus));
        let (sh, ch) = self.heading.sin_cos();
        let ahead = DVec3::new(sh, 0.0, -ch);
        let right = DVec3::new(ch, 0.0, sh);
        self.position += (ahead * axis(m.forward, m.back)
            + right * axis(m.right, m.left)
            + DVec3::Y * axis(m.up, m.down))
            * speed
            * dt;
        self.heading += f64::from(input.drag.0) * 0.005;
        self.pitch = (self.pitch - f64::from(input.drag.1) * 0.005).clamp(-1.55, 1.55);
    }
}

/// Runs the viewer until the user quits (or `frames` are shown).
pub fn run(presenter: &mut dyn Presenter, o: &ViewerOptions) -> Result<ViewerSummary> {
    let (mut w, mut h) = o.size;
    let new_fb = |w: u32, h: u32| {
        Framebuffer::new(w, h, o.color, o.depth)
            .map_err(|e| Error::Usage(format!("framebuffer {w}x{h}: {e}")))
    };
    let mut fb = new_fb(w, h)?;
    let mut engine = Engine::new(source::open(&o.source)?, o.engine, h)?;
    let mut hud = Hud::new(o.hud);
    let mut free: Option<FreeCamera> = None;
    // Flight speed as a multiple of one tile per second; exactly 1 until changed, so that on the
    // simulated clock flight time advances by exactly the frame costs, as in `fly`.
    let mut pace = 1.0;
    let (mut t, mut paused, mut frames) = (0.0, false, 0u64);
    // On the simulated clock: the modelled cost of the last frame, and their sum.
    let (mut simulated_dt, mut simulated_t) = (0.0, 0.0);
    let started = Instant::now();
    let mut last = Instant::now();
    loop {
        if o.frames.is_some_and(|n| frames >= n) {
            break;
        }
        let input = presenter.poll_input();
        if input.quit {
            break;
        }
        if let Some((nw, nh)) = input.resized.filter(|&(nw, nh)| nw > 0 && nh > 0) {
            (w, h) = (nw, nh);
            fb = new_fb(w, h)?;
        }
        for &command in &input.commands {
            if hud.apply(command) {
                continue;
            }
            match command {
                Command::SpeedUp => pace *= 1.5,
                Command::SpeedDown => pace /= 1.5,
                Command::Pause => paused = !paused,
                Command::Precision => {
                    let r = engine.render_settings_mut();
                    r.precision = match r.precision {
                        Precision::Fixed => Precision::Float,
                        Precision::Float => Precision::Fixed,
                    };
                }
                Command::BudgetUp => {
                    let fps = engine.settings().budget.target_fps / 1.25;
                    engine.set_target_fps(fps);
                }
                Command::BudgetDown => {
                    let fps = engine.settings().budget.target_fps * 1.25;
                    engine.set_target_fps(fps);
                }
                Command::CrackMode => {
                    let next = engine.settings().cracks.next();
                    engine.set_cracks(next);
                }
                Command::Wireframe => {
                    let r = engine.render_settings_mut();
                    r.wireframe = r.wireframe.next();
                }
                Command::Hud | Command::Importance => {}
            }
        }
        let dt = if o.clock.is_simulated() {
            simulated_dt
        } else {
            last.elapsed().as_secs_f64()
        };
        last = Instant::now();
        let speed = pace * engine.terrain().tile_metres();
        let moved = input.motion != Default::default() || input.drag != (0.0, 0.0);
        if moved && free.is_none() {
            let (eye, target) = o.flight.at(t);
            let camera = engine.camera(eye, target, o.flight.above_ground);
            free = Some(FreeCamera::from_pose(
                camera.position - engine.terrain().origin,
                camera.position + camera.forward - engine.terrain().origin,
            ));
        }
        let camera = match free.as_mut() {
            Some(f) => {
                if !paused {
                    f.steer(&input, dt, speed);
                }
                engine.camera(f.position, f.position + f.forward(), false)
            }
            None => {
                if !paused {
                    t += dt * pace;
                }
                let (eye, target) = o.flight.at(t % o.flight.duration().max(1e-9));
                engine.camera(eye, target, o.flight.above_ground)
            }
        };
        let frame_start = Instant::now();
        if o.clock.is_simulated() {
            engine.set_time(simulated_t);
        }
        let report = engine.render(&camera, &mut fb)?;
        let info = hud_info(&engine, &report, 1.0 / dt.max(1e-6));
        let overlay = hud.render(&info, w, h);
        presenter
            .present(&fb, overlay)
            .map_err(|e| Error::Usage(e.to_string()))?;
        let seconds = if o.clock.is_simulated() {
            o.clock.frame_seconds(&report)
        } else {
            frame_start.elapsed().as_secs_f64()
        };
        engine.record_frame(seconds, report.draw.triangles as usize);
        simulated_dt = seconds;
        simulated_t += seconds;
        frames += 1;
    }
    Ok(ViewerSummary {
        frames,
        seconds: started.elapsed().as_secs_f64(),
    })
}

/// The HUD's numbers and minimap for a frame: the paper's Figure 2 (tile states around the
/// viewer) and Figure 3 (visual importance of the drawn tiles).
pub fn hud_info(engine: &Engine, report: &FrameReport, fps: f64) -> HudInfo {
    let terrain = engine.terrain();
    let (px, py) = terrain.tile_position(report.camera.position);
    let (gw, gh) = (terrain.tiles_x, terrain.tiles_y);
    let (mw, mh) = (gw.min(MINIMAP_CELLS), gh.min(MINIMAP_CELLS));
    let corner = |p: f64, size: u32, cells: u32| {
        ((p.floor() as i64 - i64::from(cells / 2)).clamp(0, i64::from(size - cells))) as u32
    };
    let (x0, y0) = (corner(px, gw, mw), corner(py, gh, mh));
    let mut cells = Vec::with_capacity((mw * mh) as usize);
    let mut importance = vec![0.0f32; (mw * mh) as usize];
    for y in y0..y0 + mh {
        for x in x0..x0 + mw {
            cells.push(match engine.pager().state(TileId::new(x, y)) {
                PagerState::Square => TileState::Loaded,
                PagerState::Cached => TileState::Cached,
                PagerState::Fetching => TileState::Fetching,
                PagerState::Failed | PagerState::Absent => TileState::Empty,
            });
        }
    }
    for r in &report.rendered {
        let (x, y) = (r.id.x.wrapping_sub(x0), r.id.y.wrapping_sub(y0));
        if x < mw && y < mh {
            let k = (y * mw + x) as usize;
            cells[k] = TileState::Rendered;
            importance[k] = r.importance as f32;
        }
    }
    HudInfo {
        fps: fps as f32,
        target_fps: engine.settings().budget.target_fps as f32,
        triangles: report.draw.triangles,
        budget: report.budget as u64,
        memory_bytes: report.pager.memory_bytes as u64,
        memory_limit_bytes: report.pager.memory_limit_bytes as u64,
        tiles_loaded: report.pager.loaded_tiles as u32,
        tiles_rendered: report.rendered_tiles as u32,
        minimap: Some(Minimap {
            width: mw,
            height: mh,
            cells,
            viewer: ((px - f64::from(x0)) as f32, (py - f64::from(y0)) as f32),
            heading: report.camera.heading() as f32,
            importance: Some(importance),
        }),
    }
}
