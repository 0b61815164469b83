//! Writes a large elevation model made by mirror-tiling the bundled Puget Sound map (1025²
//! samples): `SIDE x SIDE` unsigned 16-bit samples (0.1 m each), little-endian, row by row, as a
//! raw grid `stripmask build` reads with `--width SIDE --height SIDE --sample-type u16`. The
//! north-west 1025² samples are the map itself, whatever the size, and the mirrored copies meet
//! without a step, so every model has the same terrain under the same flight.
//!
//! With `--tiles N` it writes the same model as a mosaic of `N x N` GeoTIFF tiles instead
//! (`DIR/tile_ROW_COLUMN.tif`, UInt16, 40 m cells of UTM zone 10N, neighbours sharing their edge
//! samples as SRTM's do), which `stripmask build DIR` places by their georeferencing.
//!
//! ```sh
//! cargo run --release --example mirror_model -- 4097 /tmp/puget4k.r16
//! cargo run --release --example mirror_model -- 16385 /tmp/puget16k-tiles --tiles 4
//! ```
//!
//! `benches/scale.sh` makes its models with it; nothing it writes belongs in the repository.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (side, out, tiles) = match args.as_slice() {
        [side, out] => (side, out, None),
        [side, out, flag, n] if flag == "--tiles" => (side, out, Some(n)),
        _ => usage(),
    };
    let side = match side.parse::<usize>() {
        Ok(side) if side >= 2 => side,
        _ => usage(),
    };
    let written = match tiles.map(|n| n.parse::<usize>()) {
        None => write(side, Path::new(out)),
        Some(Ok(n)) if n >= 1 && (side - 1) % n == 0 => write_tiles(side, n, Path::new(out)),
        Some(_) => usage(),
    };
    if let Err(e) = written {
        eprintln!("mirror_model: {out}: {e}");
        std::process::exit(1);
    }
}

fn usage() -> ! {
    eprintln!(
        "usage: mirror_model SIDE OUT.r16 | mirror_model SIDE DIR --tiles N\n  \
         (SIDE samples a side, at least 2; N tiles a side, dividing SIDE - 1)"
    );
    std::process::exit(2);
}

/// The bundled map's 16-bit samples.
type Map = image::ImageBuffer<image::Luma<u16>, Vec<u16>>;

/// The bundled map, and the map sample under model sample `i` along either axis: 0 .. n-1,
/// then back down.
fn mirrored() -> Result<(Map, usize), Box<dyn std::error::Error>> {
    let map = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/data/puget_sound_1k_height.png");
    let map = image::open(&map)?.into_luma16();
    let period = 2 * (map.width() as usize - 1);
    Ok((map, period))
}

/// Sample `i` of the model is sample `mirror(i, period)` of the map.
fn mirror(i: usize, period: usize) -> u32 {
    let k = i % period;
    (if k <= period / 2 { k } else { period - k }) as u32
}

/// Writes the `side x side` mirror-tiled model to `out`.
fn write(side: usize, out: &Path) -> Result<(), Box<dyn std::error::Error>> {
    let (map, period) = mirrored()?;
    let columns: Vec<u32> = (0..side).map(|i| mirror(i, period)).collect();
    let mut file = BufWriter::with_capacity(1 << 22, File::create(out)?);
    let mut row = Vec::with_capacity(2 * side);
    for j in 0..side {
        let y = mirror(j, period);
        row.clear();
        for &x in &columns {
            row.extend_from_slice(&map.get_pixel(x, y)[0].to_le_bytes());
        }
        file.write_all(&row)?;
    }
    file.flush()?;
    Ok(())
}

/// Writes the model as `n x n` georeferenced GeoTIFF tiles in the folder `dir`.
fn write_tiles(side: usize, n: usize, dir: &Path) -> Result<(), Box<dyn std::error::Error>> {
    use tiff::encoder::{TiffEncoder, colortype::Gray16};
    use tiff::tags::Tag;
    const CELL: f64 = 40.0;
    let (west, north) = (500_000.0, 5_300_000.0);
    let (map, period) = mirrored()?;
    std::fs::create_dir_all(dir)?;
    let step = (side - 1) / n;
    for ty in 0..n {
        for tx in 0..n {
            let (x0, y0) = (tx * step, ty * step);
            let samples: Vec<u16> = (y0..=y0 + step)
                .flat_map(|j| (x0..=x0 + step).map(move |i| (i, j)))
                .map(|(i, j)| map.get_pixel(mirror(i, period), mirror(j, period))[0])
                .collect();
            let path = dir.join(format!("tile_{ty}_{tx}.tif"));
            let mut encoder = TiffEncoder::new(BufWriter::new(File::create(&path)?))?;
            let mut image = encoder.new_image::<Gray16>(step as u32 + 1, step as u32 + 1)?;
            let tags = image.encoder();
            tags.write_tag(Tag::ModelPixelScaleTag, &[CELL, CELL, 0.0][..])?;
            let corner = [west + x0 as f64 * CELL, north - y0 as f64 * CELL];
            tags.write_tag(
                Tag::ModelTiepointTag,
                &[0.0, 0.0, 0.0, corner[0], corner[1], 0.0][..],
            )?;
            // Projected (1024 = 1), WGS 84 / UTM zone 10N (3072 = 32610).
            tags.write_tag(
                Tag::GeoKeyDirectoryTag,
                &[1u16, 1, 0, 2, 1024, 0, 1, 1, 3072, 0, 1, 32610][..],
            )?;
            image.write_data(&samples)?;
        }
    }
    Ok(())
}
