//! An application that embeds the engine: it opens an archive, makes an engine for its own
//! viewport, and each frame gives the engine its own camera (a pose: position, heading, pitch,
//! roll) and its own pixels — here a 32-bit XRGB screen whose rows are padded, as a mapped
//! framebuffer's or a toolkit's often are. The engine times its frames and holds the target
//! frame rate.
//!
//! ```sh
//! cargo run --release -- demo --frames 1          # builds stripmask-demo/puget.smdb
//! cargo run --release --example embed -- stripmask-demo/puget.smdb embed.png
//! ```
//!
//! It circles the model's centre banking into the turn, prints each tenth frame's report and
//! writes the last frame to the PNG.

use std::time::{Duration, Instant};

use stripmask::{
    Camera, DVec3, DepthBuffer, DepthFormat, Engine, EngineSettings, PixelLayout, Surface,
    Viewport, open_source,
};

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// The application's screen: 320x240 pixels, rows of 336 pixels (16 of them padding).
const WIDTH: u32 = 320;
const HEIGHT: u32 = 240;
const STRIDE_PIXELS: usize = 336;
const FRAMES: u32 = 60;
/// The application's frame period: it shows a frame at 30 Hz, and tiles stream in meanwhile.
const PERIOD: Duration = Duration::from_millis(33);

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [archive, png] = args.as_slice() else {
        eprintln!("usage: embed ARCHIVE OUT.png   (an archive file or http:// URL)");
        std::process::exit(2);
    };
    // One engine per viewport: the screen's size and its field of view, given once.
    let viewport = Viewport::new(WIDTH, HEIGHT).with_fov_y(50f64.to_radians());
    let mut engine = Engine::new(open_source(archive)?, EngineSettings::default(), viewport)?;
    // The application's memory: XRGB words (so aligned for them) and a depth buffer it keeps.
    let mut screen = vec![0u32; STRIDE_PIXELS * HEIGHT as usize];
    let mut depth = DepthBuffer::new(WIDTH, HEIGHT, DepthFormat::D16);
    let (east, south) = engine.terrain().source_extent();
    let centre = engine.terrain().origin + DVec3::new(east / 2.0, 0.0, south / 2.0);
    let (_, highest) = engine.terrain().heights;
    let (mut ready, mut settled) = (None, None);
    for k in 0..FRAMES {
        let camera = circling(centre, east.min(south) / 3.0, highest + 1500.0, k);
        let started = Instant::now();
        let mut surface = Surface::new(
            bytemuck::cast_slice_mut(&mut screen),
            WIDTH,
            HEIGHT,
            STRIDE_PIXELS * 4,
            PixelLayout::Xrgb8888,
        )?
        .with_depth(&mut depth)?;
        let report = engine.render(&camera, &mut surface)?;
        std::thread::sleep(PERIOD.saturating_sub(started.elapsed()));
        // The first frame without sky where terrain belongs, and the first as the engine
        // wants it (the camera moves, so later frames may wait for tiles again).
        ready = ready.or(report.ready().then_some(k + 1));
        settled = settled.or(report.settled().then_some(k + 1));
        if k % 10 == 9 {
            println!(
                "frame {:2}: {} tiles, {} triangles of a budget of {}, worst error {:.1} px, {} holes",
                k + 1,
                report.rendered_tiles,
                report.draw.triangles,
                report.budget,
                report.max_error_px,
                report.holes
            );
        }
    }
    println!("first ready frame {ready:?}, first settled frame {settled:?}");
    image::RgbImage::from_fn(WIDTH, HEIGHT, |x, y| {
        // XRGB8888: the word 0xXXRRGGBB.
        let word = screen[y as usize * STRIDE_PIXELS + x as usize];
        image::Rgb([(word >> 16) as u8, (word >> 8) as u8, word as u8])
    })
    .save(png)?;
    println!("{png}: the last frame");
    Ok(())
}

/// The application's camera at frame `k`: circling `centre` at `radius` metres and `altitude`,
/// looking 20° down along its path and banked 15° into the turn.
fn circling(centre: DVec3, radius: f64, altitude: f64, k: u32) -> Camera {
    let angle = f64::from(k) * 0.02;
    let position = centre + DVec3::new(radius * angle.cos(), altitude, radius * angle.sin());
    // Clockwise on the map (east, then south, then west): the heading is the circle's tangent
    // (east is +x, south +z), and the turn is to the right.
    let heading = (-angle.sin()).atan2(-angle.cos());
    Camera::from_attitude(position, heading, -20f64.to_radians(), 15f64.to_radians())
}
