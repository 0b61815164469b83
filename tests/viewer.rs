//! The interactive viewer driven by a scripted presenter: input reaches the camera, the HUD and
//! the framebuffer, and quitting ends the loop.

use std::collections::VecDeque;

use stripmask::builder::{BuildOptions, build};
use stripmask::dem::{MemoryReader, NodataFill};
use stripmask::engine::EngineSettings;
use stripmask::flight::{Builtin, Flight};
use stripmask::pager::PagerMode;
use stripmask::simclock::Clock;
use stripmask::viewer::{ViewerOptions, run};
use stripmask_platform::{Command, Input, Motion, Overlay, PlatformError, Presenter};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

/// Plays back a list of inputs, one per frame, and records what it was shown.
struct Script {
    inputs: VecDeque<Input>,
    shown: Vec<(u32, u32, bool, Vec<u8>)>,
}

impl Presenter for Script {
    fn present(&mut self, frame: &Framebuffer, hud: Option<&Overlay>) -> Result<(), PlatformError> {
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

#[test]
fn input_steers_the_view_toggles_the_hud_resizes_and_quits() {
    let dir = tempfile::tempdir().unwrap();
    let n = 129;
    let samples = (0..n * n)
        .map(|k| 200.0 + 120.0 * ((k % n) as f32 * 0.1).sin() * ((k / n) as f32 * 0.08).cos())
        .collect();
    let reader = MemoryReader::new("waves", n, n, samples).unwrap();
    let path = dir.path().join("waves.smdb");
    let options = BuildOptions {
        tile_size: 33,
        spacing: Some(20.0),
        ..BuildOptions::default()
    };
    build(NodataFill::new(reader, None), &path, &options, &|_, _| {}).unwrap();
    let terrain = stripmask::terrain::TerrainFrame::new(
        stripmask::archive::ArchiveReader::open(
            stripmask::source::open(path.to_str().unwrap()).unwrap(),
        )
        .unwrap()
        .header(),
    );

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
    let options = ViewerOptions {
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
        flight: Flight::builtin(Builtin::Overview, &terrain),
        frames: None,
        clock: Clock::default(),
    };
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
