//! The engine's own frames drawn by the project's rasterizer and, with `--features wgpu`, by
//! wgpu on the machine's adapter (Mesa's llvmpipe through lavapipe on a machine without a GPU),
//! with the ratio of their frame times.
//!
//! ```sh
//! cargo bench --bench peers                      # the rasterizer alone
//! cargo bench --features wgpu --bench peers      # and wgpu beside it
//! ```
//!
//! Frames: the Puget Sound flyover of `stripmask demo` (the built-in diagonal flight) at
//! `VIEWS` points along it, as the PocketPC profile sees it (320x240 RGB565, 16-bit depth) and as
//! the workstation profile sees it (1280x720 RGBA8888, 32-bit depth), with the engine's default
//! rendering (mipmapped bilinear textures, Gouraud light, fog, perspective spans of 16; wgpu
//! corrects perspective exactly). The budget controller is not fed, so every view draws the
//! same triangles each time.
//!
//! The CPU frame is `Engine::render`: the engine's bookkeeping and its hundreds of tile draws,
//! batched; the figure compared is its drawing (`FrameReport::draw_seconds`), and the whole
//! frame is printed beside it. The wgpu frame is a fair peer: the engine records the view's draws on the target
//! once (uploading vertices, indices and textures), and each measured frame re-runs them with
//! `GpuTarget::redraw`, uploading nothing, and waits for the GPU; `+ readback` also copies the
//! picture back. The archive is `$STRIPMASK_ARCHIVE`, else `stripmask-demo/puget.smdb`, else it
//! is built from `examples/data/` into `target/peers/` as `stripmask demo` builds it.
//! `SECS` sets the seconds per measurement (default 2).

use std::path::{Path, PathBuf};
use std::time::Instant;

use stripmask::Viewport;
use stripmask::db::source;
use stripmask::engine::camera::Camera;
use stripmask::engine::paging::PagerMode;
use stripmask::engine::terrain::TerrainFrame;
use stripmask::engine::{Engine, EngineSettings, FrameTiming};
use stripmask::sim::device::DeviceProfile;
use stripmask::sim::flight::{Builtin, Flight};
use stripmask_raster::Framebuffer;

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

/// Points along the flight.
const VIEWS: usize = 6;

fn main() -> Result<()> {
    let archive = archive()?;
    let secs: f64 = std::env::var("SECS")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2.0);
    println!(
        "peers: {} ({} rayon threads), {VIEWS} views of the diagonal flight, {secs} s per measurement",
        archive.display(),
        rayon::current_num_threads()
    );
    for p in [DeviceProfile::pocketpc(), DeviceProfile::workstation()] {
        profile(&archive, &p, secs)?;
    }
    Ok(())
}

/// The demo's archive, built when it is nowhere to be found.
fn archive() -> Result<PathBuf> {
    if let Ok(path) = std::env::var("STRIPMASK_ARCHIVE") {
        return Ok(path.into());
    }
    let demo = Path::new("stripmask-demo").join(stripmask::sim::demo::ARCHIVE);
    if demo.exists() {
        return Ok(demo);
    }
    let built = Path::new("target/peers").join(stripmask::sim::demo::ARCHIVE);
    if !built.exists() {
        std::fs::create_dir_all("target/peers")?;
        let dem = stripmask::db::dem::open_png_bytes("puget", stripmask::sim::demo::DEM_PNG)?;
        let options = stripmask::db::builder::BuildOptions {
            tile_size: stripmask::sim::demo::TILE_SIZE,
            spacing: Some(stripmask::sim::demo::SPACING),
            vertical_scale: stripmask::sim::demo::VERTICAL_SCALE,
            ..stripmask::db::builder::BuildOptions::default()
        };
        stripmask::db::builder::build(dem, &built, &options, &|_, _| {})?;
    }
    Ok(built)
}

fn engine(archive: &Path, p: &DeviceProfile, threads: usize) -> Result<Engine> {
    let mut settings = EngineSettings {
        memory_limit_bytes: 256_000_000,
        threads,
        pager_mode: PagerMode::Stepped {
            fetches_per_update: 1024,
        },
        frame_timing: FrameTiming::Told,
        ..EngineSettings::default()
    };
    settings.budget.target_fps = p.target_fps;
    Ok(Engine::new(
        source::open(&archive.to_string_lossy())?,
        settings,
        Viewport::new(p.width, p.height),
    )?)
}

/// The views' cameras, with every tile they need loaded (a frame drawn from each, twice).
fn views(archive: &Path, engine: &mut Engine, p: &DeviceProfile) -> Result<Vec<Camera>> {
    let reader =
        stripmask::db::archive::ArchiveReader::open(source::open(&archive.to_string_lossy())?)?;
    let flight = Flight::builtin(Builtin::Diagonal, &TerrainFrame::new(reader.header()));
    let cameras: Vec<Camera> = (0..VIEWS)
        .map(|k| {
            let (eye, target) = flight.at(flight.duration() * (k as f64 + 0.5) / VIEWS as f64);
            engine.camera(eye, target, flight.above_ground)
        })
        .collect();
    let mut fb = Framebuffer::new(p.width, p.height, p.color, p.depth)?;
    for _ in 0..2 {
        for c in &cameras {
            engine.render(c, &mut fb)?;
        }
    }
    Ok(cameras)
}

/// Medians over rounds of at least `secs` seconds (and 3 rounds) of one pass over the views,
/// per view, in milliseconds: of the wall time, and of the seconds `frame` reports itself.
fn measure(secs: f64, mut frame: impl FnMut(usize) -> Result<f64>) -> Result<(f64, f64)> {
    for v in 0..VIEWS {
        frame(v)?;
    }
    let (mut wall, mut own) = (Vec::new(), Vec::new());
    let started = Instant::now();
    while wall.len() < 3 || started.elapsed().as_secs_f64() < secs {
        let t = Instant::now();
        let mut reported = 0.0;
        for v in 0..VIEWS {
            reported += frame(v)?;
        }
        wall.push(t.elapsed().as_secs_f64() * 1e3 / VIEWS as f64);
        own.push(reported * 1e3 / VIEWS as f64);
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    Ok((median(&mut wall), median(&mut own)))
}

fn profile(archive: &Path, p: &DeviceProfile, secs: f64) -> Result<()> {
    let mut fb = Framebuffer::new(p.width, p.height, p.color, p.depth)?;
    let mut cpu = Vec::new();
    for threads in [1, 2] {
        let mut e = engine(archive, p, threads)?;
        let cameras = views(archive, &mut e, p)?;
        let mut drawn = stripmask_raster::DrawStats::default();
        for c in &cameras {
            drawn += e.render(c, &mut fb)?.draw;
        }
        let (frame, drawing) = measure(secs, |v| Ok(e.render(&cameras[v], &mut fb)?.draw_seconds))?;
        println!(
            "{} {}x{}, {} thread(s): {} triangles and {} pixels per view; whole frame {frame:.3} ms",
            p.name,
            p.width,
            p.height,
            threads,
            drawn.triangles / VIEWS as u64,
            drawn.fragments / VIEWS as u64
        );
        cpu.push((threads, drawing));
    }
    for (threads, ms) in &cpu {
        println!("  stripmask rasterizer, {threads} thread(s)      {ms:8.3} ms per frame");
    }
    peer(archive, p, secs, &cpu)
}

#[cfg(feature = "wgpu")]
fn peer(archive: &Path, p: &DeviceProfile, secs: f64, cpu: &[(usize, f64)]) -> Result<()> {
    use stripmask_platform::GpuTarget;
    let mut gpu = match GpuTarget::new(p.width, p.height, p.color, p.depth) {
        Ok(gpu) => gpu,
        Err(e) => {
            println!("  wgpu: skipped, {e}");
            return Ok(());
        }
    };
    let mut e = engine(archive, p, 1)?;
    let cameras = views(archive, &mut e, p)?;
    // One target per view would hold every view's uploads; recording a view just before its
    // redraws keeps one view's at a time, so measure view by view.
    let mut no_readback = 0.0;
    let mut with_readback = 0.0;
    for c in &cameras {
        e.render_to(c, &mut gpu)?;
        gpu.redraw()?;
        no_readback += measure(secs / VIEWS as f64, |_| {
            gpu.redraw()?;
            Ok(0.0)
        })?
        .0;
        with_readback += measure(secs / VIEWS as f64, |_| {
            gpu.redraw()?;
            gpu.read_image()?;
            Ok(0.0)
        })?
        .0;
    }
    println!("  wgpu on {}", gpu.adapter_name());
    let (no_readback, with_readback) = (no_readback / VIEWS as f64, with_readback / VIEWS as f64);
    println!("  wgpu, inputs uploaded once              {no_readback:8.3} ms per frame");
    println!("  wgpu, inputs uploaded once, + readback  {with_readback:8.3} ms per frame");
    for (threads, ms) in cpu {
        println!(
            "  ratio wgpu / stripmask on {threads} thread(s): {:.2} (without readback), {:.2} (with)",
            no_readback / ms,
            with_readback / ms
        );
    }
    Ok(())
}

#[cfg(not(feature = "wgpu"))]
fn peer(_: &Path, _: &DeviceProfile, _: f64, _: &[(usize, f64)]) -> Result<()> {
    println!("  wgpu: not built (cargo bench --features wgpu --bench peers)");
    Ok(())
}
