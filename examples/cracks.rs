//! Measures every crack mode on the crack scene and prints the table of `docs/cracks.md`.
//!
//! ```sh
//! cargo run --release --example cracks            # 320x240, 7 repeats per view
//! cargo run --release --example cracks -- 640x480 15
//! ```

#[path = "support/args.rs"]
mod args;

use stripmask::engine::cracks::CrackMode;
use stripmask::sim::crack_metric::CrackScene;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let (size, repeats) = args::size_and_repeats();
    let dir = tempfile::tempdir()?;
    let scene = CrackScene::build(dir.path())?;
    let modes = [
        CrackMode::None,
        CrackMode::Shadow,
        CrackMode::Skirts,
        CrackMode::Stitch,
    ];
    let measured = modes
        .iter()
        .map(|&mode| scene.measure(mode, size, repeats))
        .collect::<stripmask::Result<Vec<_>>>()?;
    let none = &measured[0];
    println!(
        "{} views at {}x{}, levels pinned so that all {} level pairs meet; draw time: the median of {repeats} renders per view, summed",
        scene.views.len(),
        size.0,
        size.1,
        none.pairs.len()
    );
    println!();
    println!(
        "| mode | crack pixels | vs none | triangles | extra vs masks | draw time | vs none |"
    );
    println!("| --- | ---: | ---: | ---: | ---: | ---: | ---: |");
    for m in &measured {
        let extra = m.triangles as f64 / m.mask_triangles as f64 - 1.0;
        println!(
            "| {:?} | {} | {:.1} % | {} | {:+.1} % | {:.1} ms | {:.2} |",
            m.mode,
            m.crack_pixels,
            100.0 * m.crack_pixels as f64 / none.crack_pixels.max(1) as f64,
            m.triangles,
            100.0 * extra,
            1e3 * m.draw_time.as_secs_f64(),
            m.draw_time.as_secs_f64() / none.draw_time.as_secs_f64(),
        );
    }
    Ok(())
}
