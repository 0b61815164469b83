//! Writes a large elevation model made by mirror-tiling the bundled Puget Sound map (1025²
//! samples): `SIDE x SIDE` unsigned 16-bit samples (0.1 m each), little-endian, row by row, as a
//! raw grid `stripmask build` reads with `--width SIDE --height SIDE --sample-type u16`. The
//! north-west 1025² samples are the map itself, whatever the size, and the mirrored copies meet
//! without a step, so every model has the same terrain under the same flight.
//!
//! ```sh
//! cargo run --release --example mirror_model -- 4097 /tmp/puget4k.r16
//! ```
//!
//! `benches/scale.sh` makes its models with it; nothing it writes belongs in the repository.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (side, out) = match args.as_slice() {
        [side, out] => match side.parse::<usize>() {
            Ok(side) if side >= 2 => (side, out.clone()),
            _ => usage(),
        },
        _ => usage(),
    };
    if let Err(e) = write(side, Path::new(&out)) {
        eprintln!("mirror_model: {out}: {e}");
        std::process::exit(1);
    }
}

fn usage() -> ! {
    eprintln!("usage: mirror_model SIDE OUT.r16   (SIDE samples a side, at least 2)");
    std::process::exit(2);
}

/// Writes the `side x side` mirror-tiled model to `out`.
fn write(side: usize, out: &Path) -> Result<(), Box<dyn std::error::Error>> {
    let map = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/data/puget_sound_1k_height.png");
    let map = image::open(&map)?.into_luma16();
    let n = map.width() as usize;
    // Sample `i` of the model is sample `mirror(i)` of the map: 0 .. n-1, then back down.
    let period = 2 * (n - 1);
    let mirror = |i: usize| {
        let k = i % period;
        if k < n { k } else { period - k }
    };
    let columns: Vec<usize> = (0..side).map(mirror).collect();
    let mut file = BufWriter::with_capacity(1 << 22, File::create(out)?);
    let mut row = Vec::with_capacity(2 * side);
    for j in 0..side {
        let y = mirror(j) as u32;
        row.clear();
        for &x in &columns {
            row.extend_from_slice(&map.get_pixel(x as u32, y)[0].to_le_bytes());
        }
        file.write_all(&row)?;
    }
    file.flush()?;
    Ok(())
}
