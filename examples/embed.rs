//! An application that embeds the engine: it opens an archive, makes an engine for its own
//! viewport, and each frame gives the engine its own camera (a pose: position, heading, pitch,
//! roll) and its own framebuffer, then tells the budget how long the frame took.
//!
//! ```sh
//! cargo run --release -- demo --frames 1          # builds stripmask-demo/puget.smdb
//! cargo run --release --example embed -- stripmask-demo/puget.smdb embed.png
//! ```
//!
//! It circles the model's centre banking into the turn, prints each tenth frame's report and
//! writes the last frame to the PNG.

use std::time::{Duration, Instant};

use glam::DVec3;
use stripmask::{Camera, Engine, EngineSettings, open_source};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// The application's viewport.
const WIDTH: u32 = 320;
const HEIGHT: u32 = 240;
const FRAMES: u32 = 60;
/// The application's frame period: it shows a frame at 30 Hz, and tiles stream in meanwhile.
const PERIOD: Duration = Duration::from_millis(33);

fn main() -> Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [archive, png] = args.as_slice() else {
        eprintln!("usage: embed ARCHIVE OUT.png   (an archive file or http:// URL)");
        std::process::exit(2);
    };
    // One engine per viewport: its settings' field of view is the one the camera uses.
    let settings = EngineSettings::default();
    let mut engine = Engine::new(open_source(archive)?, settings, HEIGHT)?;
    let mut frame = Framebuffer::new(WIDTH, HEIGHT, ColorFormat::Rgb565, DepthFormat::D16)?;
    let (east, south) = engine.terrain().source_extent();
    let centre = engine.terrain().origin + DVec3::new(east / 2.0, 0.0, south / 2.0);
    let (_, highest) = engine.terrain().heights;
    let (mut ready, mut settled) = (None, None);
    for k in 0..FRAMES {
        let camera = circling(
            centre,
            east.min(south) / 3.0,
            highest + 1500.0,
            k,
            settings.fov_y,
        );
        let started = Instant::now();
        let report = engine.render(&camera, &mut frame)?;
        // The budget holds the target frame rate from the times it is told.
        let budget = engine.record_frame(
            started.elapsed().as_secs_f64(),
            report.draw.triangles as usize,
        );
        std::thread::sleep(PERIOD.saturating_sub(started.elapsed()));
        // The first frame without sky where terrain belongs, and the first as the engine
        // wants it (the camera moves, so later frames may wait for tiles again).
        ready = ready.or(report.ready().then_some(k + 1));
        settled = settled.or(report.settled().then_some(k + 1));
        if k % 10 == 9 {
            println!(
                "frame {:2}: {} tiles, {} triangles, worst error {:.1} px, {} holes; next budget {budget}",
                k + 1,
                report.rendered_tiles,
                report.draw.triangles,
                report.max_error_px,
                report.holes
            );
        }
    }
    println!("first ready frame {ready:?}, first settled frame {settled:?}");
    frame.to_rgba_image().save(png)?;
    println!("{png}: the last frame");
    Ok(())
}

/// The application's camera at frame `k`: circling `centre` at `radius` metres and `altitude`,
/// looking 20° down along its path and banked 15° into the turn.
fn circling(centre: DVec3, radius: f64, altitude: f64, k: u32, fov_y: f64) -> Camera {
    let angle = f64::from(k) * 0.02;
    let position = centre + DVec3::new(radius * angle.cos(), altitude, radius * angle.sin());
    // Clockwise on the map (east, then south, then west): the heading is the circle's tangent,
    // and the turn is to the right.
    let tangent = DVec3::new(-angle.sin(), 0.0, angle.cos());
    let forward = (tangent - DVec3::Y * 20f64.to_radians().tan()).normalize();
    Camera {
        position,
        forward,
        roll: 15f64.to_radians(),
        fov_y,
        near: 1.0,
        far: 1e5,
    }
}
