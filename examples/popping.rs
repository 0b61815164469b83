//! Measures popping (the picture's jump at a mask switch) with geomorphing off and on, and what
//! geomorphing costs, on the crack scene; prints the tables of `docs/cracks.md`.
//!
//! ```sh
//! cargo run --release --example popping            # 320x240, 7 repeats per view
//! cargo run --release --example popping -- 640x480 15
//! ```

#[path = "support/args.rs"]
mod args;

use stripmask::engine::EngineSettings;
use stripmask::engine::cracks::CrackMode;
use stripmask::engine::geomorph::Geomorph;
use stripmask::sim::crack_metric::{CrackScene, TILE_SIZE, crack_pixels};
use stripmask::sim::popping::{FrameChange, flight_popping, glide, switch_change};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer, Vertex};

fn settings(geomorph: Geomorph) -> EngineSettings {
    EngineSettings {
        geomorph,
        ..CrackScene::settings(CrackMode::Stitch)
    }
}

fn name(geomorph: Geomorph) -> String {
    match geomorph {
        Geomorph::Off => "off".into(),
        Geomorph::Distance { pixels } if pixels == Geomorph::DEFAULT_PIXELS => {
            format!("distance, {pixels} px (default)")
        }
        Geomorph::Distance { pixels } => format!("distance, {pixels} px"),
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (size, repeats) = args::size_and_repeats();
    let dir = tempfile::tempdir()?;
    let scene = CrackScene::build(dir.path())?;
    let fb = || Framebuffer::new(size.0, size.1, ColorFormat::Rgb565, DepthFormat::D16);
    let (mut a, mut b) = (fb()?, fb()?);
    let modes = [
        Geomorph::Off,
        Geomorph::DISTANCE,
        Geomorph::Distance { pixels: 16.0 },
        Geomorph::Distance { pixels: 32.0 },
    ];
    let switches = [(0, 1), (1, 3), (3, 7), (1, 2)];
    let mut plain = scene.engine_with(settings(Geomorph::Off), size)?;
    let mut c = fb()?;

    println!(
        "Whole-view switches: every tile from level a to level b, camera unchanged; mean absolute \
         change per channel (0-255) and share of pixels changed, over the {} views at {}x{}",
        scene.views.len(),
        size.0,
        size.1
    );
    println!();
    print!("| geomorph |");
    for (from, to) in switches {
        print!(" {from} → {to} |");
    }
    println!(" relief lost at level 0 |");
    println!("| --- |{}", " ---: |".repeat(switches.len() + 1));
    for geomorph in modes {
        let mut engine = scene.engine_with(settings(geomorph), size)?;
        print!("| {} |", name(geomorph));
        for (from, to) in switches {
            let mut total = FrameChange::default();
            for &(eye, target) in &scene.views {
                let camera = engine.camera(eye, target, false);
                let c = switch_change(
                    &mut engine,
                    &camera,
                    &mut a,
                    &mut b,
                    Box::new(move |_| from),
                    Box::new(move |_| to),
                )?;
                total.mean_abs += c.mean_abs / scene.views.len() as f64;
                total.changed_share += c.changed_share / scene.views.len() as f64;
            }
            print!(
                " {:.2} ({:.0} %) |",
                total.mean_abs,
                100.0 * total.changed_share
            );
        }
        // What the morph costs in fidelity: level 0 drawn morphed against level 0 plain.
        let mut lost = FrameChange::default();
        for &(eye, target) in &scene.views {
            for e in [&mut engine, &mut plain] {
                e.force_levels(Some(Box::new(|_| 0)));
            }
            let camera = engine.camera(eye, target, false);
            engine.render(&camera, &mut a)?;
            plain.render(&camera, &mut c)?;
            let d = FrameChange::between(&c, &a)?;
            lost.mean_abs += d.mean_abs / scene.views.len() as f64;
            lost.changed_share += d.changed_share / scene.views.len() as f64;
        }
        println!(
            " {:.2} ({:.0} %) |",
            lost.mean_abs,
            100.0 * lost.changed_share
        );
    }

    let flight = glide(&scene, 120);
    println!();
    println!(
        "A {}-frame glide with the budget choosing levels (initial budget {}, not adapted): mean \
         change at frames where some tile switched level, and at frames where none did",
        flight.len(),
        GLIDE_BUDGET
    );
    println!();
    println!(
        "| geomorph | switch frames | switches | change at a switch | change otherwise | the switch alone |"
    );
    println!("| --- | ---: | ---: | ---: | ---: | ---: |");
    for geomorph in modes {
        let mut s = settings(geomorph);
        s.budget.initial_budget = GLIDE_BUDGET;
        let mut engine = scene.engine_with(s, size)?;
        let p = flight_popping(&mut engine, &flight, &mut a, &mut b, &mut c)?;
        println!(
            "| {} | {} of {} | {} | {:.3} | {:.3} | {:.3} |",
            name(geomorph),
            p.switch_frames,
            p.frames,
            p.switches,
            p.at_switch,
            p.steady,
            p.switch_alone
        );
    }

    println!();
    println!(
        "Cost, on the crack views with levels pinned to every pair (stitch): each view drawn \
         {repeats} times by each setting in turn (so that load from other jobs hits all alike), \
         draw time the median per view, summed; ratios from this run"
    );
    println!();
    println!("| geomorph | crack pixels | draw time | vs off |");
    println!("| --- | ---: | ---: | ---: |");
    // Off twice, first and last: the spread between the two is the order's effect.
    let costed: Vec<Geomorph> = modes.iter().copied().chain([Geomorph::Off]).collect();
    let mut engines = costed
        .iter()
        .map(|&g| scene.engine_with(settings(g), size))
        .collect::<stripmask::Result<Vec<_>>>()?;
    let mut cracks = vec![0; costed.len()];
    let mut totals = vec![0.0; costed.len()];
    for view in 0..scene.views.len() {
        let mut times = vec![Vec::with_capacity(repeats); costed.len()];
        for repeat in 0..repeats.max(1) {
            for (k, engine) in engines.iter_mut().enumerate() {
                let report = scene.render(engine, view, &mut a)?;
                times[k].push(report.draw_seconds);
                if repeat == 0 {
                    cracks[k] += crack_pixels(&a);
                }
            }
        }
        for (total, mut t) in totals.iter_mut().zip(times) {
            t.sort_by(f64::total_cmp);
            *total += t[t.len() / 2];
        }
    }
    for (k, &geomorph) in costed.iter().enumerate() {
        println!(
            "| {} | {} | {:.1} ms | {:.2} |",
            if k + 1 == costed.len() {
                "off (again)".into()
            } else {
                name(geomorph)
            },
            cracks[k],
            1e3 * totals[k],
            totals[k] / totals[0]
        );
    }
    println!();
    println!(
        "Memory: nothing per tile; one scratch buffer of {} vertices ({} bytes) per engine",
        TILE_SIZE * TILE_SIZE,
        TILE_SIZE * TILE_SIZE * std::mem::size_of::<Vertex>()
    );
    Ok(())
}

/// The glide's triangle budget: about level 2 on average over the visible tiles, so that levels
/// switch as importance moves with the camera.
const GLIDE_BUDGET: usize = 1_200;
