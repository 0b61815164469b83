//! What geomorphing costs a frame along a flight: engines with geomorphing off and on fly the
//! same frames of a built-in flight over one archive, with every tile loaded, the triangle
//! budget held and one rasterizer thread (as `stripmask tradeoff` has them), taking turns to go first so that the
//! machine's noise falls on all alike. Prints each setting's median process CPU time per frame
//! and the median of its per-frame ratios to the first setting.
//!
//! ```sh
//! cargo run --release -- demo -q --frames 1    # builds stripmask-demo/puget.smdb
//! cargo run --release --example geomorph_cost -- stripmask-demo/puget.smdb 300 0.04 off,4,16
//! ```
//!
//! Arguments: the archive, the frames, the flight seconds between frames (0 repeats the first
//! frame), the settings (`off` or a pixel threshold), and the flight (overview, diagonal, low).
//! With one setting it renders only that engine: run it under
//! `valgrind --tool=callgrind --toggle-collect='geomorph_cost::fly'` to count a frame's
//! instructions.

use cpu_time::ProcessTime;
use stripmask::Viewport;
use stripmask::db::archive::ArchiveReader;
use stripmask::db::source;
use stripmask::engine::geomorph::Geomorph;
use stripmask::engine::paging::PagerMode;
use stripmask::engine::terrain::TerrainFrame;
use stripmask::engine::{Engine, EngineSettings, FrameTiming};
use stripmask::named::Named;
use stripmask::sim::flight::{Builtin, Flight};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

#[path = "support/median.rs"]
mod median;
use median::median;

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// The size and budget of `stripmask tradeoff`'s frames.
const SIZE: (u32, u32) = (320, 240);
const BUDGET: usize = 20_000;

fn parse_setting(s: &str) -> Result<Geomorph> {
    if s == "off" {
        return Ok(Geomorph::Off);
    }
    let pixels: f64 = s
        .parse()
        .map_err(|_| format!("setting {s:?} is neither off nor a pixel threshold"))?;
    Ok(Geomorph::Distance { pixels })
}

fn engine(archive: &str, geomorph: Geomorph) -> Result<Engine> {
    let settings = EngineSettings {
        geomorph,
        threads: 1,
        memory_limit_bytes: 1 << 30,
        pager_mode: PagerMode::Stepped {
            fetches_per_update: usize::MAX,
        },
        frame_timing: FrameTiming::Told,
        ..EngineSettings::default()
    };
    let mut engine = Engine::new(
        source::open(archive)?,
        settings,
        Viewport::new(SIZE.0, SIZE.1),
    )?;
    engine.hold_budget(BUDGET);
    Ok(engine)
}

/// Loads every tile into every engine and settles its pager: the first frame of `flight`,
/// twice, untimed.
fn settle(engines: &mut [Engine], fb: &mut Framebuffer, flight: &Flight) -> Result<()> {
    let (eye, target) = flight.at(0.0);
    for engine in engines {
        let camera = engine.camera(eye, target, flight.above_ground);
        for _ in 0..2 {
            engine.render(&camera, fb)?;
        }
    }
    Ok(())
}

/// Renders `frames` frames of `flight`, `dt` flight seconds apart, in every engine in turn;
/// returns each engine's process CPU seconds per frame and the triangles of the last engine.
#[inline(never)]
fn fly(
    engines: &mut [Engine],
    fb: &mut Framebuffer,
    flight: &Flight,
    frames: usize,
    dt: f64,
) -> Result<(Vec<Vec<f64>>, Vec<u64>)> {
    let mut times = vec![Vec::with_capacity(frames); engines.len()];
    let mut triangles = Vec::with_capacity(frames);
    for k in 0..frames {
        let (eye, target) = flight.at((k as f64 * dt) % flight.duration());
        let n = engines.len();
        for i in (0..n).map(|i| (i + k) % n) {
            let engine = &mut engines[i];
            let camera = engine.camera(eye, target, flight.above_ground);
            let cpu = ProcessTime::now();
            let report = engine.render(&camera, fb)?;
            times[i].push(cpu.elapsed().as_secs_f64());
            if i == n - 1 {
                triangles.push(report.draw.triangles);
            }
        }
    }
    Ok((times, triangles))
}

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let archive = args
        .next()
        .unwrap_or_else(|| "stripmask-demo/puget.smdb".into());
    let frames: usize = match args.next() {
        Some(n) => n
            .parse()
            .map_err(|_| format!("frames {n:?} is not a count"))?,
        None => 300,
    };
    let dt: f64 = match args.next() {
        Some(s) => s
            .parse()
            .map_err(|_| format!("seconds {s:?} is not a number"))?,
        None => 0.04,
    };
    let settings = args.next().unwrap_or_else(|| "off,4,16".into());
    let settings = settings
        .split(',')
        .map(parse_setting)
        .collect::<Result<Vec<_>>>()?;
    let builtin = match args.next() {
        Some(name) => Builtin::from_name(&name)?,
        None => Builtin::Diagonal,
    };
    let reader = ArchiveReader::open(source::open(&archive)?)?;
    let flight = Flight::builtin(builtin, &TerrainFrame::new(reader.header()));
    let mut engines = settings
        .iter()
        .map(|&g| engine(&archive, g))
        .collect::<Result<Vec<_>>>()?;
    let mut fb = Framebuffer::new(SIZE.0, SIZE.1, ColorFormat::Rgb565, DepthFormat::D16)?;
    settle(&mut engines, &mut fb, &flight)?;
    let (mut times, triangles) = fly(&mut engines, &mut fb, &flight, frames, dt)?;
    let mean_triangles = triangles.iter().sum::<u64>() as f64 / frames.max(1) as f64;
    println!(
        "{} over {archive}: {frames} frames {dt} s apart at {}x{}, budget {BUDGET}, {mean_triangles:.0} triangles drawn per frame",
        flight.name, SIZE.0, SIZE.1
    );
    let base: Vec<f64> = times[0].clone();
    for (g, t) in settings.iter().zip(&mut times) {
        let mut ratios: Vec<f64> = t.iter().zip(&base).map(|(a, b)| a / b).collect();
        let name = match g {
            Geomorph::Off => "off".to_string(),
            Geomorph::Distance { pixels } => format!("{} {pixels} px", g.name()),
        };
        println!(
            "{name:<16} {:.3} ms CPU per frame (median), {:.3} ms mean; per-frame ratio to the first setting {:.3} (median)",
            median(t) * 1e3,
            t.iter().sum::<f64>() / t.len().max(1) as f64 * 1e3,
            median(&mut ratios)
        );
    }
    Ok(())
}
