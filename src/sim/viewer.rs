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
use stripmask_platform::{Command, Hud, Input, Presenter};
use stripmask_raster::{ColorFormat, DepthBuffer, DepthFormat, Framebuffer, Precision};

use crate::db::source;
use crate::engine::camera::Camera;
use crate::engine::viewport::Viewport;
use crate::engine::{Engine, EngineSettings, FrameTiming};
use crate::error::Result;
use crate::sim::clock::Clock;
use crate::sim::flight::Flight;
use crate::sim::hud::hud_info;
use crate::sim::pose::line::PoseDecoder;
use crate::sim::pose::{PoseFeed, PoseSource};

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
    /// [`PagerMode::Simulated`](crate::engine::paging::PagerMode::Simulated)
    /// ([`Clock::pager_mode`]) for tiles to arrive at reproducible frames too.
    pub clock: Clock,
    /// A feed of poses that steers the camera instead of the flight and the keys; the HUD says
    /// how old its pose is.
    pub poses: Option<PoseSource>,
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

/// Where the view comes from: the flight path until the first movement input, then the user's
/// own camera; with the speed and pause the keys set.
struct Pilot {
    /// The user's camera, once they have taken over.
    free: Option<FreeCamera>,
    /// Metres per second the user's camera moves; the flight path runs at `speed` over a
    /// tile's width times its own pace.
    speed: f64,
    /// Time along the flight path, seconds.
    t: f64,
    paused: bool,
}

impl Pilot {
    fn new(speed: f64) -> Self {
        Pilot {
            free: None,
            speed,
            t: 0.0,
            paused: false,
        }
    }

    /// Applies a key that is not the HUD's: to the pilot, or to the engine's settings.
    fn command(&mut self, command: Command, engine: &mut Engine) {
        match command {
            Command::SpeedUp => self.speed *= 1.5,
            Command::SpeedDown => self.speed /= 1.5,
            Command::Pause => self.paused = !self.paused,
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

    /// The camera of a frame `dt` seconds after the last: steered by `input` once the user has
    /// moved, along `flight` (looping) until then.
    fn camera(&mut self, engine: &Engine, flight: &Flight, input: &Input, dt: f64) -> Camera {
        let moved = input.motion != Default::default() || input.drag != (0.0, 0.0);
        if moved && self.free.is_none() {
            let (eye, target) = flight.at(self.t);
            let camera = engine.camera(eye, target, flight.above_ground);
            self.free = Some(FreeCamera::from_pose(
                camera.position - engine.terrain().origin,
                camera.position + camera.forward - engine.terrain().origin,
            ));
        }
        match self.free.as_mut() {
            Some(f) => {
                if !self.paused {
                    f.steer(input, dt, self.speed);
                }
                engine.camera(f.position, f.position + f.forward(), false)
            }
            None => {
                if !self.paused {
                    self.t += dt * self.speed / engine.terrain().tile_metres();
                }
                let (eye, target) = flight.at(self.t % flight.duration().max(1e-9));
                engine.camera(eye, target, flight.above_ground)
            }
        }
    }
}

/// Runs the viewer until the user quits (or `frames` are shown).
pub fn run(presenter: &mut dyn Presenter, o: &ViewerOptions) -> Result<ViewerSummary> {
    let (mut w, mut h) = o.size;
    let new_fb = |w: u32, h: u32| Framebuffer::new(w, h, o.color, o.depth);
    let mut fb = new_fb(w, h)?;
    // The depth buffer of frames drawn straight into the screen, kept from frame to frame;
    // dropped the first time the presenter lends no screen.
    let mut screen_depth = Some(DepthBuffer::new(w, h, o.depth));
    // The viewer tells the budget each frame's time by its clock: the device's, or the host's.
    let settings = EngineSettings {
        frame_timing: FrameTiming::Told,
        lift_to_clearance: true,
        ..o.engine
    };
    let mut engine = Engine::new(source::open(&o.source)?, settings, Viewport::new(w, h))?;
    // The feed places latitudes and longitudes by the archive's header.
    let feed = match &o.poses {
        Some(poses) => {
            let decoder = PoseDecoder::new(engine.archive_name(), engine.header().clone());
            Some(PoseFeed::open(poses, decoder)?)
        }
        None => None,
    };
    let mut hud = Hud::new(o.hud);
    let mut pilot = Pilot::new(engine.terrain().tile_metres());
    let mut frames = 0u64;
    let started = Instant::now();
    let mut last = Instant::now();
    // On the simulated clock: the modelled cost of the last frame, and their sum.
    let (mut simulated_dt, mut simulated_t) = (0.0, 0.0);
    while o.frames.is_none_or(|n| frames < n) {
        let input = presenter.poll_input();
        if input.quit {
            break;
        }
        if let Some((nw, nh)) = input.resized.filter(|&(nw, nh)| nw > 0 && nh > 0) {
            (w, h) = (nw, nh);
            fb = new_fb(w, h)?;
            engine.resize(w, h)?;
            if screen_depth.is_some() {
                screen_depth = Some(DepthBuffer::new(w, h, o.depth));
            }
        }
        for &command in &input.commands {
            if !hud.apply(command) {
                pilot.command(command, &mut engine);
            }
        }
        let dt = if o.clock.is_simulated() {
            simulated_dt
        } else {
            last.elapsed().as_secs_f64()
        };
        last = Instant::now();
        // The feed's time: the simulated clock's, or the wall clock's since the start.
        let now = if o.clock.is_simulated() {
            simulated_t
        } else {
            started.elapsed().as_secs_f64()
        };
        if let Some(f) = &feed {
            f.check()?;
        }
        let camera = match feed.as_ref().and_then(|f| f.at(now)) {
            Some((pose, _)) => pose.camera(&engine),
            None => pilot.camera(&engine, &o.flight, &input, dt),
        };
        let frame_start = Instant::now();
        if o.clock.is_simulated() {
            engine.set_time(simulated_t);
        }
        // Without a HUD to composite, a frame the size of the screen is drawn straight into
        // the screen's memory when the presenter lends it (the framebuffer's mapped pages).
        let mut refused = false;
        let direct = match screen_depth.as_mut().filter(|_| !hud.is_enabled()) {
            Some(depth) => match presenter.surface(depth)? {
                Some(mut screen) => Some(engine.render(&camera, &mut screen)?),
                None => {
                    refused = true;
                    None
                }
            },
            None => None,
        };
        if refused {
            screen_depth = None;
        }
        let report = match direct {
            Some(report) => report,
            None => {
                let report = engine.render(&camera, &mut fb)?;
                let mut info = hud_info(&engine, &report, 1.0 / dt.max(1e-6));
                info.status = feed.as_ref().map(|f| f.status(now));
                let overlay = hud.render(&info, w, h);
                presenter.present(&fb, overlay)?;
                report
            }
        };
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

/// The viewer driven by a scripted presenter: input reaches the camera, the HUD and the
/// framebuffer, and quitting ends the loop.
#[cfg(test)]
mod tests {
    use std::collections::VecDeque;

    use super::{Clock, ViewerOptions, run};
    use crate::db::builder::{BuildOptions, build};
    use crate::db::dem::{MemoryReader, NodataFill};
    use crate::engine::EngineSettings;
    use crate::engine::paging::PagerMode;
    use crate::sim::flight::{Builtin, Flight};
    use stripmask_platform::{Command, Input, Motion, Overlay, PlatformError, Presenter};
    use stripmask_raster::{
        ColorFormat, DepthBuffer, DepthFormat, Framebuffer, PixelLayout, Surface, rgb565_to_rgb,
    };

    /// Plays back a list of inputs, one per frame, and records what it was shown.
    struct Script {
        inputs: VecDeque<Input>,
        shown: Vec<(u32, u32, bool, Vec<u8>)>,
    }

    impl Presenter for Script {
        fn present(
            &mut self,
            frame: &Framebuffer,
            hud: Option<&Overlay>,
        ) -> Result<(), PlatformError> {
            let pixels = frame.to_rgba_image().into_raw();
            self.shown
                .push((frame.width(), frame.height(), hud.is_some(), pixels));
            Ok(())
        }

        fn poll_input(&mut self) -> Input {
            self.inputs.pop_front().unwrap_or(Input {
                quit: true,
                ..Input::default()
            })
        }
    }

    /// A screen whose memory the viewer draws into: RGB565 rows of 168 pixels, 8 of them
    /// padding; `present` is never needed.
    struct Screen {
        pixels: Vec<u16>,
        frames: usize,
    }

    impl Presenter for Screen {
        fn present(&mut self, _: &Framebuffer, _: Option<&Overlay>) -> Result<(), PlatformError> {
            panic!("a frame drawn into the screen is not presented")
        }

        fn surface<'a>(
            &'a mut self,
            depth: &'a mut DepthBuffer,
        ) -> Result<Option<Surface<'a>>, PlatformError> {
            if self.frames == 4 {
                return Ok(None);
            }
            self.frames += 1;
            let memory = bytemuck::cast_slice_mut(&mut self.pixels);
            Ok(Some(
                Surface::new(memory, 160, 120, 168 * 2, PixelLayout::Rgb565)?.with_depth(depth)?,
            ))
        }

        fn poll_input(&mut self) -> Input {
            Input {
                quit: self.frames == 4,
                ..Input::default()
            }
        }
    }

    #[test]
    fn without_a_hud_frames_are_drawn_straight_into_a_lent_screen() {
        let dir = tempfile::tempdir().unwrap();
        let (path, terrain) = waves(dir.path());
        let poses = dir.path().join("poses.txt");
        std::fs::write(&poses, "0 1280 -1280 600 45 -60 20\n").unwrap();
        let o = ViewerOptions {
            hud: false,
            poses: Some(super::PoseSource::File(poses)),
            ..options(&path, &terrain)
        };
        let mut screen = Screen {
            pixels: vec![0xABCD; 168 * 120],
            frames: 0,
        };
        run(&mut screen, &o).unwrap();
        let mut script = Script {
            inputs: std::iter::repeat_n(Input::default(), 4).collect(),
            shown: Vec::new(),
        };
        run(&mut script, &o).unwrap();
        let presented = &script.shown[3].3;
        for (y, row) in screen.pixels.chunks(168).enumerate() {
            assert!(row[160..].iter().all(|&p| p == 0xABCD), "row {y}'s padding");
            for (x, &p) in row[..160].iter().enumerate() {
                let k = 4 * (y * 160 + x);
                assert_eq!(rgb565_to_rgb(p), presented[k..k + 3], "pixel ({x}, {y})");
            }
        }
    }

    /// A 129² archive of waves, 20 m apart, in 33-sample tiles, in `dir`; and its frame.
    fn waves(dir: &std::path::Path) -> (std::path::PathBuf, crate::engine::terrain::TerrainFrame) {
        let n = 129;
        let samples = (0..n * n)
            .map(|k| 200.0 + 120.0 * ((k % n) as f32 * 0.1).sin() * ((k / n) as f32 * 0.08).cos())
            .collect();
        let reader = MemoryReader::new("waves", n, n, samples).unwrap();
        let path = dir.join("waves.smdb");
        let options = BuildOptions {
            tile_size: 33,
            spacing: Some(20.0),
            ..BuildOptions::default()
        };
        build(NodataFill::new(reader, None), &path, &options, &|_, _| {}).unwrap();
        let terrain = crate::engine::terrain::TerrainFrame::new(
            crate::db::archive::ArchiveReader::open(
                crate::db::source::open(path.to_str().unwrap()).unwrap(),
            )
            .unwrap()
            .header(),
        );
        (path, terrain)
    }

    /// The options of a viewer of `path` at 160x120 with a stepped pager and one thread.
    fn options(
        path: &std::path::Path,
        terrain: &crate::engine::terrain::TerrainFrame,
    ) -> ViewerOptions {
        ViewerOptions {
            source: path.display().to_string(),
            size: (160, 120),
            color: ColorFormat::Rgb565,
            depth: DepthFormat::D16,
            engine: EngineSettings {
                pager_mode: PagerMode::Stepped {
                    fetches_per_update: 64,
                },
                threads: 1,
                ..EngineSettings::default()
            },
            hud: true,
            flight: Flight::builtin(Builtin::Overview, terrain),
            frames: None,
            clock: Clock::default(),
            poses: None,
        }
    }

    #[test]
    fn a_recording_of_poses_steers_the_camera_and_a_roll_banks_the_view() {
        let dir = tempfile::tempdir().unwrap();
        let (path, terrain) = waves(dir.path());
        // Over the middle of the 2,560 m square, 600 m up, looking north-east and down.
        let fly = |name: &str, lines: &str| {
            let poses = dir.path().join(name);
            std::fs::write(&poses, lines).unwrap();
            let mut script = Script {
                inputs: std::iter::repeat_n(Input::default(), 4).collect(),
                shown: Vec::new(),
            };
            let o = ViewerOptions {
                poses: Some(super::PoseSource::File(poses)),
                ..options(&path, &terrain)
            };
            run(&mut script, &o).unwrap();
            script.shown
        };
        let sky = [150u8, 180, 215];
        let ground = |pixels: &[u8]| {
            pixels
                .chunks_exact(4)
                .filter(|p| p[..3].iter().zip(sky).any(|(&a, b)| a.abs_diff(b) > 8))
                .count()
        };
        let down = fly("down.txt", "0 1280 -1280 600 45 -60 0\n");
        let again = fly(
            "again.txt",
            "0 1280 -1280 600 45 -60 0\n3600 1280 -1280 600 45 -60 0\n",
        );
        let banked = fly("banked.txt", "0 1280 -1280 600 45 -60 40\n");
        let up = fly("up.txt", "0 1280 -1280 600 45 60 0\n");
        assert_eq!(down.len(), 4);
        assert!(down.iter().all(|s| s.2), "the HUD shows the feed's state");
        assert_eq!(down[3].3, again[3].3, "the same pose draws the same frame");
        assert_ne!(down[3].3, banked[3].3, "a roll banks the view");
        assert!(
            ground(&down[3].3) > 160 * 120 * 9 / 10,
            "looking down: ground"
        );
        assert!(ground(&up[3].3) < 160 * 120 / 10, "looking up: sky");
    }

    #[test]
    fn input_steers_the_view_toggles_the_hud_resizes_and_quits() {
        let dir = tempfile::tempdir().unwrap();
        let (path, terrain) = waves(dir.path());
        let idle = Input::default();
        let forward = Input {
            motion: Motion {
                forward: true,
                ..Motion::default()
            },
            ..Input::default()
        };
        let hud_off = Input {
            commands: vec![Command::Hud],
            ..Input::default()
        };
        let resize = Input {
            resized: Some((200, 100)),
            ..Input::default()
        };
        let mut script = Script {
            inputs: [
                idle.clone(),
                idle.clone(),
                idle.clone(),
                forward.clone(),
                forward,
                hud_off,
                resize,
                idle,
            ]
            .into(),
            shown: Vec::new(),
        };
        let options = options(&path, &terrain);
        let summary = run(&mut script, &options).unwrap();
        assert_eq!(summary.frames, 8, "the ninth poll quits");
        let shown = &script.shown;
        assert_eq!(shown.len(), 8);
        assert!(shown[..5].iter().all(|s| s.2), "HUD on until H");
        assert!(shown[5..].iter().all(|s| !s.2), "HUD off after H");
        assert_eq!((shown[5].0, shown[5].1), (160, 120));
        assert_eq!((shown[6].0, shown[6].1), (200, 100), "resized framebuffer");
        assert_ne!(shown[3].3, shown[4].3, "moving forward changes the view");
        let sky = [150u8, 180, 215];
        let terrain_pixels = shown[2]
            .3
            .chunks_exact(4)
            .filter(|p| p[..3].iter().zip(sky).any(|(&a, b)| a.abs_diff(b) > 8))
            .count();
        assert!(
            terrain_pixels > 160 * 120 / 4,
            "terrain drawn: {terrain_pixels}"
        );

        let mut bounded = Script {
            inputs: VecDeque::new(),
            shown: Vec::new(),
        };
        bounded
            .inputs
            .extend(std::iter::repeat_n(Input::default(), 10));
        let summary = run(
            &mut bounded,
            &ViewerOptions {
                frames: Some(3),
                ..options
            },
        )
        .unwrap();
        assert_eq!(summary.frames, 3);
    }
}
