//! The embedding API against the command's own path: a banked view drawn into an application's
//! borrowed XRGB8888 memory, rows padded, is the view `fly` draws into its framebuffer.

use stripmask::db::source;
use stripmask::sim::clock::Clock;
use stripmask::sim::flight::{Flight, Key};
use stripmask::sim::fly::{FlyOptions, Length, fly};
use stripmask::{
    Camera, ColorFormat, DVec3, DepthBuffer, DepthFormat, Engine, EngineSettings, PixelLayout,
    Surface, Viewport,
};

use crate::support::hills::{archive, stepped};

const SIZE: (u32, u32) = (160, 120);
/// Row length of the application's screen, pixels: 8 of them padding.
const STRIDE: usize = 168;
const FRAMES: u64 = 12;
/// What the application leaves in the padding, which no frame may touch.
const PADDING: u32 = 0xDEAD_BEEF;

/// Both sides' settings: every tile fetched on the frame's thread, one rasterizer thread, and a
/// budget pinned wide open (the frames are bound by τ alone, whatever they cost).
fn settings() -> EngineSettings {
    let mut settings = EngineSettings {
        lift_to_clearance: true,
        ..stepped(64 << 20)
    };
    let wide = 1 << 22;
    settings.budget.initial_budget = wide;
    settings.budget.min_budget = wide;
    settings.budget.max_budget = wide;
    settings
}

#[test]
fn a_banked_view_in_borrowed_xrgb_memory_is_the_view_fly_draws() {
    let dir = tempfile::tempdir().unwrap();
    let path = archive(dir.path(), 33);
    let (eye, target) = (
        DVec3::new(1200.0, 1500.0, 3900.0),
        DVec3::new(4000.0, 300.0, 2000.0),
    );
    let roll = 25f64.to_radians();

    // The command's path: a flight holding the banked pose, its last frame kept as PNG.
    let hold = |t| Key {
        t,
        position: eye,
        target,
        roll,
    };
    let out = dir.path().join("fly");
    fly(&FlyOptions {
        source: path.display().to_string(),
        flight: Flight::new("banked", false, vec![hold(0.0), hold(100.0)]).unwrap(),
        length: Some(Length::Frames(FRAMES)),
        size: SIZE,
        color: ColorFormat::Rgba8888,
        depth: DepthFormat::D16,
        engine: settings(),
        out: out.clone(),
        every: FRAMES - 1,
        hud: false,
        progress: false,
        clock: Clock::default(),
        link: None,
        plots: false,
        http: stripmask::db::source::http::HttpOptions::default(),
    })
    .unwrap();
    let flown = image::open(out.join(format!("frames/frame_{:06}.png", FRAMES - 1)))
        .unwrap()
        .to_rgba8();

    // The application's path: its own memory and depth buffer, its own camera.
    let source = source::open(path.to_str().unwrap()).unwrap();
    let mut engine = Engine::new(source, settings(), Viewport::new(SIZE.0, SIZE.1)).unwrap();
    let mut screen = vec![PADDING; STRIDE * SIZE.1 as usize];
    let mut depth = DepthBuffer::new(SIZE.0, SIZE.1, DepthFormat::D16);
    for _ in 0..FRAMES {
        let camera = Camera {
            roll,
            ..engine.camera(eye, target, false)
        };
        let mut surface = Surface::new(
            bytemuck::cast_slice_mut(&mut screen),
            SIZE.0,
            SIZE.1,
            STRIDE * 4,
            PixelLayout::Xrgb8888,
        )
        .unwrap()
        .with_depth(&mut depth)
        .unwrap();
        let report = engine.render(&camera, &mut surface).unwrap();
        assert_eq!(report.view.camera.roll, roll);
    }

    let mut terrain = 0;
    for (y, row) in screen.chunks(STRIDE).enumerate() {
        assert!(
            row[SIZE.0 as usize..].iter().all(|&w| w == PADDING),
            "row {y}'s padding"
        );
        for (x, &word) in row[..SIZE.0 as usize].iter().enumerate() {
            let rgb = [(word >> 16) as u8, (word >> 8) as u8, word as u8];
            let want = flown.get_pixel(x as u32, y as u32).0;
            assert_eq!(rgb, want[..3], "pixel ({x}, {y})");
            terrain += usize::from(rgb != stripmask::engine::render::RenderSettings::default().sky);
        }
    }
    assert!(
        terrain > SIZE.0 as usize * SIZE.1 as usize / 4,
        "the view shows terrain"
    );
}
