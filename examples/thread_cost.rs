//! What a second rasterizer thread buys the engine's frames: the measurement behind the
//! simulated clock charging one core's cost whatever the thread count (docs/pocketpc.md).
//!
//! Two engines fly the diagonal over the same archive, one on one thread and one on two. Both
//! feed their budget controller the simulated clock's one-core cost, so they choose the same
//! budgets and draw the same triangles and pixels (rendering is deterministic); only their
//! measured frame times differ. They take turns to go first, so that the machine's noise falls
//! on both alike. For the PocketPC scene and the workstation scene it prints the median frame
//! times, the median per-frame ratio, and the efficiency `e` of the second core on the row stage
//! that a thread-aware cost model would need to predict that ratio (`frame + triangles` stay on
//! one core, and `pixels` would take `1 / (1 + e)` of their time on two). It also prints the
//! raster share of a frame: the median of the engine's own `draw_seconds` (the tiles' draw
//! calls and their pixels) over the median frame time, on one thread and on two.
//!
//! ```sh
//! cargo run --release -- demo -q --frames 1    # builds stripmask-demo/puget.smdb
//! cargo run --release --example thread_cost -- stripmask-demo/puget.smdb 200
//! ```

use std::time::Instant;

use stripmask::Viewport;
use stripmask::db::archive::ArchiveReader;
use stripmask::db::source;
use stripmask::engine::paging::PagerMode;
use stripmask::engine::terrain::TerrainFrame;
use stripmask::engine::{Engine, EngineSettings, FrameTiming};
use stripmask::sim::clock::CostModel;
use stripmask::sim::device::DeviceProfile;
use stripmask::sim::flight::{Builtin, Flight};
use stripmask_raster::Framebuffer;

#[path = "support/median.rs"]
mod median;
use median::median;

fn engine(archive: &str, p: &DeviceProfile, threads: usize) -> Result<Engine> {
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
        source::open(archive)?,
        settings,
        Viewport::new(p.width, p.height),
    )?)
}

type Result<T> = std::result::Result<T, Box<dyn std::error::Error>>;

fn scene(archive: &str, p: &DeviceProfile, frames: usize) -> Result<()> {
    let reader = ArchiveReader::open(source::open(archive)?)?;
    let flight = Flight::builtin(Builtin::Diagonal, &TerrainFrame::new(reader.header()));
    let mut engines = [engine(archive, p, 1)?, engine(archive, p, 2)?];
    let new_fb = || Framebuffer::new(p.width, p.height, p.color, p.depth);
    let mut fbs = [new_fb()?, new_fb()?];
    let model = CostModel::HOST;
    let (mut t, mut times) = (0.0, [Vec::new(), Vec::new()]);
    let mut draws = [Vec::new(), Vec::new()];
    let (mut ratios, mut triangles, mut fragments) = (Vec::new(), 0.0, 0.0);
    let warm_up = 5;
    for k in 0..frames + warm_up {
        let (eye, target) = flight.at(t % flight.duration());
        let mut measured = [0.0; 2];
        let mut drawing = [0.0; 2];
        let mut drawn = [(0, 0); 2];
        let order = if k % 2 == 0 { [0, 1] } else { [1, 0] };
        for i in order {
            let camera = engines[i].camera(eye, target, flight.above_ground);
            let started = Instant::now();
            let report = engines[i].render(&camera, &mut fbs[i])?;
            measured[i] = started.elapsed().as_secs_f64();
            drawing[i] = report.draw_seconds;
            drawn[i] = (report.draw.triangles, report.draw.fragments);
        }
        assert_eq!(drawn[0], drawn[1], "both engines draw the same frame");
        let (tris, frags) = drawn[0];
        let seconds = p.cpu_slowdown * model.seconds(tris, frags);
        for e in &mut engines {
            e.record_frame(seconds, tris as usize);
        }
        t += seconds;
        if k >= warm_up {
            times[0].push(measured[0]);
            times[1].push(measured[1]);
            draws[0].push(drawing[0]);
            draws[1].push(drawing[1]);
            ratios.push(measured[0] / measured[1]);
            triangles += tris as f64 / frames as f64;
            fragments += frags as f64 / frames as f64;
        }
    }
    let (t1, t2) = (median(&mut times[0]), median(&mut times[1]));
    let (d1, d2) = (median(&mut draws[0]), median(&mut draws[1]));
    let r = median(&mut ratios);
    let serial = model.frame_s + model.triangle_s * triangles;
    let rows = model.fragment_s * fragments;
    let e = rows / ((serial + rows) / r - serial) - 1.0;
    println!(
        "{:<12} {}x{}, {frames} frames, {triangles:.0} triangles and {fragments:.0} pixels per frame",
        p.name, p.width, p.height
    );
    println!(
        "             1 thread {:.3} ms, 2 threads {:.3} ms (medians); median ratio {r:.3}",
        t1 * 1e3,
        t2 * 1e3
    );
    println!(
        "             drawing (raster) 1 thread {:.3} ms = {:.0}% of the frame, 2 threads {:.3} ms = {:.0}%; drawing ratio {:.3}",
        d1 * 1e3,
        100.0 * d1 / t1,
        d2 * 1e3,
        100.0 * d2 / t2,
        d1 / d2
    );
    println!(
        "             model on one core: {:.3} ms serial + {:.3} ms rows; second core's row efficiency e = {e:.2}",
        serial * 1e3,
        rows * 1e3
    );
    Ok(())
}

fn main() -> Result<()> {
    let mut args = std::env::args().skip(1);
    let archive = args
        .next()
        .unwrap_or_else(|| "stripmask-demo/puget.smdb".into());
    let frames = match args.next() {
        Some(n) => n
            .parse()
            .map_err(|_| format!("frames {n:?} is not a count"))?,
        None => 200,
    };
    println!("rayon threads available: {}", rayon::current_num_threads());
    for p in [DeviceProfile::pocketpc(), DeviceProfile::workstation()] {
        scene(&archive, &p, frames)?;
    }
    Ok(())
}
