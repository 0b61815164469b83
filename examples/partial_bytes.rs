//! Resident bytes of a tile by progressive levels held, as the memory limit accounts them
//! (`stripmask::engine::resident::predicted_bytes`, exact for every level count, crack mode and
//! lighting): unlit as drawn by default, and lit (vertex lighting on); prints the table of
//! docs/streaming.md's partial-tiles section.
//!
//! ```sh
//! cargo run --release --example partial_bytes            # 65-sample tiles, 64-texel textures
//! cargo run --release --example partial_bytes -- 129 128
//! ```

use stripmask::db::tile::{level_side, progressive_levels};
use stripmask::engine::cracks::CrackMode;
use stripmask::engine::resident::predicted_bytes;

fn main() {
    let mut args = std::env::args().skip(1).map(|a| a.parse::<usize>());
    let (s, t) = match (args.next(), args.next()) {
        (None, None) => (65, 64),
        (Some(Ok(s)), Some(Ok(t))) if (s - 1).is_power_of_two() && t.is_power_of_two() => (s, t),
        _ => {
            eprintln!("usage: partial_bytes [TILE_SIZE (2^n + 1) TEXTURE_SIZE (2^m)]");
            std::process::exit(2);
        }
    };
    let all = progressive_levels(s);
    let whole = predicted_bytes(s, t, 0, all, CrackMode::Stitch, false);
    println!("tile {s} samples, texture {t} texels, texture from mip 0 (or the first held)");
    println!(
        "| levels held | grid | finest mask level | bytes (stitch) | of whole | bytes (skirts) | bytes lit (stitch) |"
    );
    println!("| ---: | ---: | ---: | ---: | ---: | ---: | ---: |");
    for levels in (1..=all).rev() {
        let side = level_side(levels - 1);
        let stitch = predicted_bytes(s, t, 0, levels, CrackMode::Stitch, false);
        let skirts = predicted_bytes(s, t, 0, levels, CrackMode::Skirts, false);
        let lit = predicted_bytes(s, t, 0, levels, CrackMode::Stitch, true);
        println!(
            "| {levels} | {side} x {side} | {} | {stitch} | {:.1} % | {skirts} | {lit} |",
            (s - 1) / (side - 1) - 1,
            100.0 * stitch as f64 / whole as f64
        );
    }
}
