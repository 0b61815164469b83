//! Views show no line along tile borders: the luminance second difference across a tile border
//! is within 1.2x of its value on lines of the same kind inside the tiles, on a real model (Puget
//! Sound) and on a smooth synthetic surface, top-down and oblique, with the vertex lighting alone
//! and with the hill-shaded texture under it (the default rendering). A texture shaded from each
//! tile's own samples alone, as a tile cannot help but do at its borders without its neighbours,
//! fails the same measure. Texels show as much detail on a border as inside a tile, and the
//! two tiles sharing a border hold the same texels on it. Tiles holding the same level, whole
//! or partial, light the vertices they share alike.
//!
//! `cargo test --profile suite --test it seams -- --nocapture` prints the ratios docs/cracks.md
//! quotes.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use glam::{DVec3, DVec4};
use stripmask::Viewport;
use stripmask::db::archive::{ArchiveReader, ArchiveWriter, compress};
use stripmask::db::builder::{BuildOptions, build};
use stripmask::db::dem::{self, FillStats, OpenOptions};
use stripmask::db::grid::TileId;
use stripmask::db::rgb565::mip_chain;
use stripmask::db::source;
use stripmask::db::source::file::FileSource;
use stripmask::db::texture_gen::shaded;
use stripmask::db::tile::{PartialGrid, Tile};
use stripmask::engine::camera::View;
use stripmask::engine::cracks::CrackMode;
use stripmask::engine::paging::PagerMode;
use stripmask::engine::resident::ResidentTile;
use stripmask::engine::shading::Light;
use stripmask::engine::{Engine, EngineSettings, FrameReport, FrameTiming};
use stripmask_raster::{ColorFormat, DepthBuffer, DepthFormat, Framebuffer, rgb565_to_rgb};

use crate::support::hills::synthetic;

const WIDTH: u32 = 480;
const HEIGHT: u32 = 360;

/// The ratio no view may exceed.
const MAX_RATIO: f64 = 1.2;

/// A model and the two views of it the measure looks at.
struct Model {
    path: PathBuf,
    /// Metres between samples.
    spacing: f64,
    /// Cells per tile side.
    cells: i64,
    /// Texels per tile texture side.
    texels: i64,
    /// What the views look at, and how high above it they are.
    centre: DVec3,
    height: f64,
}

impl Model {
    /// The top-down and the oblique eye.
    fn eyes(&self) -> [(&'static str, DVec3); 2] {
        let h = self.height;
        [
            ("top-down", self.centre + DVec3::new(0.0, h, 0.0)),
            (
                "oblique",
                self.centre + DVec3::new(-0.4 * h, 0.6 * h, 1.4 * h),
            ),
        ]
    }
}

/// The Puget Sound model (1025², 160 m apart) in tiles of 65 samples: 16 x 16 tiles of 10 km,
/// textures of 64 texels; the views span about three tiles across.
fn puget(dir: &Path) -> Model {
    let input =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/data/puget_sound_1k_height.png");
    let open = OpenOptions::default();
    let path = dir.join("puget.smdb");
    let options = BuildOptions {
        tile_size: 65,
        spacing: Some(160.0),
        vertical_scale: 0.1,
        height_quantum: Some(0.125),
        ..BuildOptions::default()
    };
    build(
        dem::open(&input, &open).unwrap(),
        &path,
        &options,
        &|_, _| {},
    )
    .unwrap();
    let tile = 64.0 * 160.0;
    Model {
        path,
        spacing: 160.0,
        cells: 64,
        texels: 64,
        centre: DVec3::new(5.5 * tile, 0.0, 7.5 * tile),
        height: 26_000.0,
    }
}

/// A smooth surface of long swells, 257², 30 m apart, in tiles of 33 samples (8 x 8 tiles),
/// textures of 32 texels.
fn swells(dir: &Path) -> Model {
    let options = BuildOptions {
        tile_size: 33,
        spacing: Some(30.0),
        ..BuildOptions::default()
    };
    let path = synthetic(dir, "swells", (257, 257), &options, |x, z| {
        let (x, z) = (x as f32, z as f32);
        300.0 + 120.0 * (x / 23.0).sin() * (z / 31.0).cos() + 40.0 * ((x + z) / 17.0).sin()
    });
    let tile = 32.0 * 30.0;
    Model {
        path,
        spacing: 30.0,
        cells: 32,
        texels: 32,
        centre: DVec3::new(4.5 * tile, 300.0, 3.5 * tile),
        height: 2_800.0,
    }
}

/// `model` with every tile's texture hill-shaded from the tile's own samples alone: one-sided
/// gradients at its borders, so that the two tiles sharing a border hold different texels on
/// it, at every level of the pyramid. Everything else (heights, aprons, errors) is as built.
fn seamed(model: Model, dir: &Path) -> Model {
    let archive = ArchiveReader::open(FileSource::open(&model.path).unwrap()).unwrap();
    let header = archive.header().clone();
    let (s, t) = (header.tile_size as usize, header.texture_size as usize);
    let path = dir.join("seamed.smdb");
    let mut writer = ArchiveWriter::create(&path, header.clone()).unwrap();
    let pyramid = archive.pyramid().clone();
    for k in 0..pyramid.levels() as u8 {
        let grid = pyramid.grid(k);
        let spacing = header.spacing as f32 * f32::from(1u16 << k);
        for ty in 0..grid.tiles_y() {
            for tx in 0..grid.tiles_x() {
                let id = TileId::at(k, tx, ty);
                let mut tile = archive.tile(id).unwrap().unwrap();
                let own = shaded(s, spacing, t / (s - 1), |i, j| {
                    match (usize::try_from(i), usize::try_from(j)) {
                        (Ok(i), Ok(j)) if i < s && j < s => Some(tile.height(i, j)),
                        _ => None,
                    }
                });
                tile.texture_mips = mip_chain(&own, t);
                let chunks: Vec<Vec<u8>> = (0..tile.levels)
                    .map(|g| compress(&tile.encode_level(g), header.codec))
                    .collect();
                writer.write_tile(id, chunks).unwrap();
            }
        }
    }
    let nodata = FillStats {
        filled: header.nodata_filled,
        flattened: header.nodata_flattened,
    };
    writer
        .finish(header.min_height, header.max_height, nodata)
        .unwrap();
    Model { path, ..model }
}

/// What a view draws.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Rendering {
    /// The vertex lighting alone.
    Lit,
    /// The hill-shaded texture alone: the default.
    Textured,
    /// The hill-shaded texture under the vertex lighting.
    LitTextured,
}

/// Every tile whole and drawn at mask level 0, so that what differs at a border is the lighting
/// and the texture alone, not two levels meeting.
fn engine(path: &Path, rendering: Rendering) -> Engine {
    engine_with(path, rendering, Some(Box::new(|_| 0)))
}

/// The same with the levels `levels` pins (`None`: the engine's own, by τ and the budget).
fn engine_with(
    path: &Path,
    rendering: Rendering,
    levels: Option<Box<dyn Fn(TileId) -> usize + Send>>,
) -> Engine {
    let settings = EngineSettings {
        memory_limit_bytes: 512 << 20,
        pager_mode: PagerMode::Stepped {
            fetches_per_update: 1024,
        },
        threads: 1,
        frame_timing: FrameTiming::Told,
        ..EngineSettings::default()
    };
    let mut engine = Engine::new(
        source::open(path.to_str().unwrap()).unwrap(),
        settings,
        Viewport::new(WIDTH, HEIGHT),
    )
    .unwrap();
    engine.force_levels(levels);
    match rendering {
        Rendering::Lit => engine.render_settings_mut().sampler = None,
        Rendering::Textured => {}
        Rendering::LitTextured => engine.render_settings_mut().lighting = true,
    }
    engine
}

/// The view from `eye` to `target`, rendered until every tile in it is loaded; returns the
/// frame and its report (with the camera it was drawn with).
fn view(engine: &mut Engine, eye: DVec3, target: DVec3) -> (Framebuffer, FrameReport) {
    let mut fb = Framebuffer::new(WIDTH, HEIGHT, ColorFormat::Rgba8888, DepthFormat::D32).unwrap();
    let mut drawn = None;
    for k in 0..30 {
        engine.set_time(f64::from(k));
        let camera = engine.camera(eye, target, false);
        let report = engine.render(&camera, &mut fb).unwrap();
        assert!(report.rendered_tiles > 0);
        let settled = report.pager.fetching == 0 && report.holes == 0;
        drawn = Some(report);
        if settled && k > 3 {
            break;
        }
    }
    (fb, drawn.unwrap())
}

/// The lines a border is compared with: lines inside the tiles where the picture bends as it
/// does on a border, so that what differs is the border alone.
struct Lines {
    /// Lines per sample step (the lines are the integers of sample coordinates times this).
    per_sample: f64,
    /// Lines per tile: every `period`-th line is a border.
    period: i64,
    /// The interior lines compared with, `1..period`.
    interior: Vec<i64>,
}

impl Lines {
    /// For the vertex lighting, which bends on the sample lines: the sample line halfway across
    /// a tile.
    fn halfway_sample(model: &Model) -> Lines {
        Lines {
            per_sample: 1.0,
            period: model.cells,
            interior: vec![model.cells / 2],
        }
    }

    /// For the bilinear texture, which bends at its texel centres: a border is one (its texels
    /// lie on it), the sample lines inside a tile mostly are not (`t` texels span `t` cells, so
    /// the centres are `t / (t - 1)` cells apart). The seven texel-centre lines nearest to an
    /// eighth, a quarter, ... of the way across a tile.
    fn texel_centres(model: &Model) -> Lines {
        let period = model.texels - 1;
        Lines {
            per_sample: period as f64 / model.cells as f64,
            period,
            interior: (1..8).map(|k| (k * period + 4) / 8).collect(),
        }
    }
}

/// Mean absolute luminance second difference at pixels whose two neighbours (along a screen
/// row or column) lie on the two sides of one line of `lines` and of no other, at pixels where
/// that line is a tile border and where it is one of `lines.interior`: lines of the same kind,
/// spacing and distance from the eye, one between tiles, the others inside them. Where the
/// neighbours are several lines apart (far away, the texture minified) the picture no longer
/// bends on single lines, and a few high-contrast pixels (a coastline) would decide the mean.
/// A pixel's place on the ground comes from its depth.
fn second_differences(
    fb: &Framebuffer,
    view: &View,
    model: &Model,
    lines: &Lines,
) -> (f64, f64, usize) {
    let (w, h) = (WIDTH as usize, HEIGHT as usize);
    let DepthBuffer::D32(depth) = fb.depth() else {
        panic!("a 32-bit depth buffer")
    };
    let unproject = view.view_projection().inverse();
    // The lines before the pixel's place on the ground, west-east and north-south.
    let place = |x: usize, y: usize| -> Option<[i64; 2]> {
        let d = depth[y * w + x];
        (d != u32::MAX).then(|| {
            let ndc = DVec4::new(
                2.0 * (x as f64 + 0.5) / w as f64 - 1.0,
                1.0 - 2.0 * (y as f64 + 0.5) / h as f64,
                f64::from(d) / 4_294_967_296.0,
                1.0,
            );
            let p = unproject * ndc;
            let world = p.truncate() / p.w + view.camera.position;
            [world.x, world.z].map(|c| (c / model.spacing * lines.per_sample).floor() as i64)
        })
    };
    // The line between the places `a` and `b`, across a tile, when there is exactly one.
    let between = |a: [i64; 2], b: [i64; 2]| {
        let mut crossed = (0..2).flat_map(|k| a[k].min(b[k]) + 1..=a[k].max(b[k]));
        match (crossed.next(), crossed.next()) {
            (Some(line), None) => Some(line.rem_euclid(lines.period)),
            _ => None,
        }
    };
    let luminance = |x: usize, y: usize| {
        let [r, g, b] = fb.pixel(x as u32, y as u32);
        0.299 * f64::from(r) + 0.587 * f64::from(g) + 0.114 * f64::from(b)
    };
    let (mut border, mut interior) = ((0.0, 0usize), (0.0, 0usize));
    for y in 2..h - 2 {
        for x in 2..w - 2 {
            for (dx, dy) in [(1isize, 0isize), (0, 1)] {
                let at = |k: isize| {
                    let (px, py) = (
                        (x as isize + k * dx) as usize,
                        (y as isize + k * dy) as usize,
                    );
                    place(px, py).map(|c| (c, luminance(px, py)))
                };
                let Some(line) = (-2..=2).map(at).collect::<Option<Vec<_>>>() else {
                    continue;
                };
                let d2 = (line[1].1 - 2.0 * line[2].1 + line[3].1).abs();
                match between(line[1].0, line[3].0) {
                    Some(0) => {
                        border.0 += d2;
                        border.1 += 1;
                    }
                    Some(l) if lines.interior.contains(&l) => {
                        interior.0 += d2;
                        interior.1 += 1;
                    }
                    _ => {}
                }
            }
        }
    }
    assert!(
        border.1 > 200 && interior.1 > border.1 / 2,
        "{border:?} {interior:?}"
    );
    (
        border.0 / border.1 as f64,
        interior.0 / interior.1 as f64,
        border.1,
    )
}

/// The border-to-interior ratios of the top-down and the oblique view of `model` drawn as
/// `rendering` says, against the halfway sample line for the lighting alone and against
/// texel-centre lines with the texture.
fn seam_ratios(model: &Model, rendering: Rendering) -> [f64; 2] {
    seam_ratios_of(model, rendering, engine(&model.path, rendering))
}

/// The same drawn by `engine`.
fn seam_ratios_of(model: &Model, rendering: Rendering, mut engine: Engine) -> [f64; 2] {
    let lines = match rendering {
        Rendering::Lit => Lines::halfway_sample(model),
        Rendering::Textured | Rendering::LitTextured => Lines::texel_centres(model),
    };
    model.eyes().map(|(name, eye)| {
        let (fb, report) = view(&mut engine, eye, model.centre);
        let (border, interior, pixels) = second_differences(&fb, &report.view, model, &lines);
        let ratio = border / interior;
        println!(
            "{}, {rendering:?}, {name}: border {border:.3} over {pixels} px, interior \
             {interior:.3}, ratio {ratio:.3}",
            model.path.display()
        );
        ratio
    })
}

/// Asserts that both views of `model`, lit alone, textured and both, have a border-to-interior
/// ratio of at most `MAX_RATIO`.
fn assert_no_seams(model: &Model) {
    for rendering in [Rendering::Lit, Rendering::Textured, Rendering::LitTextured] {
        let ratios = seam_ratios(model, rendering);
        assert!(
            ratios.iter().all(|&r| r <= MAX_RATIO),
            "{rendering:?}: border/interior {ratios:.3?} (top-down, oblique)"
        );
    }
}

#[test]
fn views_of_a_real_model_show_no_line_along_tile_borders() {
    let dir = tempfile::tempdir().unwrap();
    assert_no_seams(&puget(dir.path()));
}

#[test]
fn views_of_a_smooth_surface_show_no_line_along_tile_borders() {
    let dir = tempfile::tempdir().unwrap();
    assert_no_seams(&swells(dir.path()));
}

#[test]
fn a_texture_shaded_one_sided_at_the_borders_fails_the_measure() {
    let dir = tempfile::tempdir().unwrap();
    let model = seamed(puget(dir.path()), dir.path());
    let ratios = seam_ratios(&model, Rendering::Textured);
    assert!(
        ratios.iter().all(|&r| r > MAX_RATIO),
        "border/interior {ratios:.3?} (top-down, oblique)"
    );
}

#[test]
fn texels_show_as_much_detail_on_a_border_as_inside_a_tile() {
    // A tile's texels lie on its samples only at its borders (t texels span t cells): shading
    // interpolated between the samples and read at the texel centres gave the border texels
    // 1.17 times the second difference of the texels inside, 0.88 halfway across.
    let dir = tempfile::tempdir().unwrap();
    let model = puget(dir.path());
    let archive = ArchiveReader::open(FileSource::open(&model.path).unwrap()).unwrap();
    let (nx, ny) = (
        archive.header().tiles_x as usize,
        archive.header().tiles_y as usize,
    );
    let tiles: Vec<Tile> = (0..nx * ny)
        .map(|k| {
            let id = TileId::new((k % nx) as u32, (k / nx) as u32);
            archive.tile(id).unwrap().unwrap()
        })
        .collect();
    let t = tiles[0].texture_size;
    // The two tiles sharing a border hold the same texels on it, at every mip but the last
    // (one texel, the tile's mean).
    for (k, tile) in tiles.iter().enumerate() {
        let (east, south) = (tiles.get(k + 1), tiles.get(k + nx));
        for (mip, texels) in tile.texture_mips.iter().enumerate() {
            let side = t >> mip;
            if side == 1 {
                continue;
            }
            for a in 0..side {
                if let Some(east) = east.filter(|_| k % nx + 1 < nx) {
                    assert_eq!(
                        texels[a * side + side - 1],
                        east.texture_mips[mip][a * side]
                    );
                }
                if let Some(south) = south {
                    assert_eq!(texels[(side - 1) * side + a], south.texture_mips[mip][a]);
                }
            }
        }
    }
    // The mean second difference of texel luminance along the rows of mip 0, the rows
    // continued across the borders, by texel position across a tile (0: on a border).
    let luminance = |p: u16| {
        let [r, g, b] = rgb565_to_rgb(p);
        0.299 * f64::from(r) + 0.587 * f64::from(g) + 0.114 * f64::from(b)
    };
    let (mut sum, mut count) = (vec![0.0; t - 1], vec![0usize; t - 1]);
    for ty in 0..ny {
        for v in 0..t {
            let row: Vec<f64> = (0..nx)
                .flat_map(|tx| {
                    let end = if tx + 1 == nx { t } else { t - 1 };
                    let texels = &tiles[ty * nx + tx].texture_mips[0][v * t..v * t + end];
                    texels.iter().map(|&p| luminance(p))
                })
                .collect();
            for g in 1..row.len() - 1 {
                sum[g % (t - 1)] += (row[g - 1] - 2.0 * row[g] + row[g + 1]).abs();
                count[g % (t - 1)] += 1;
            }
        }
    }
    let detail: Vec<f64> = sum.iter().zip(&count).map(|(s, &n)| s / n as f64).collect();
    let inside = detail[1..].iter().sum::<f64>() / (t - 2) as f64;
    let ratio = detail[0] / inside;
    println!("texel detail on the borders against inside: {ratio:.3}");
    assert!(
        (0.95..=1.05).contains(&ratio),
        "border/inside {ratio:.3}: {detail:.2?}"
    );
}

#[test]
fn neighbours_holding_the_same_level_light_their_shared_border_alike() {
    let dir = tempfile::tempdir().unwrap();
    let model = puget(dir.path());
    let archive = ArchiveReader::open(FileSource::open(&model.path).unwrap()).unwrap();
    let resident = |tx, ty, levels| {
        let tile = archive
            .tile(TileId::new(tx, ty))
            .unwrap()
            .unwrap()
            .truncated(levels);
        ResidentTile::new(&tile, 0, 160.0, Some(&Light::default()), CrackMode::None)
    };
    for levels in 1..=7 {
        let (west, east, south) = (
            resident(5, 7, levels),
            resident(6, 7, levels),
            resident(5, 8, levels),
        );
        let side = west.side();
        for k in 0..side {
            let n = |t: &ResidentTile, i: usize, j: usize| t.normals[j * side + i];
            assert_eq!(
                n(&west, side - 1, k),
                n(&east, 0, k),
                "{levels} levels, row {k}"
            );
            assert_eq!(
                n(&west, k, side - 1),
                n(&south, k, 0),
                "{levels} levels, column {k}"
            );
            let lit = |t: &ResidentTile, i: usize, j: usize| t.vertices[j * side + i].color;
            assert_eq!(lit(&west, side - 1, k), lit(&east, 0, k));
        }
    }
}

/// Views whose tiles the engine draws at the levels τ = 1 px asks — mask levels from the full
/// tile to its corners, and two levels of the pyramid side by side — show no line along the
/// borders where levels meet in the default rendering: the hill-shaded texture, its mip chosen
/// per triangle, shades both sides alike. The vertex lighting of each level's own grid would
/// not (printed, not asserted: docs/cracks.md quotes it).
#[test]
fn views_where_levels_differ_show_no_line_along_their_borders() {
    let dir = tempfile::tempdir().unwrap();
    let mut pyramid_levels = BTreeSet::new();
    for model in [puget(dir.path()), swells(dir.path())] {
        let mut engine = engine_with(&model.path, Rendering::Textured, None);
        for (name, eye) in model.eyes() {
            let (_, report) = view(&mut engine, eye, model.centre);
            let masks: BTreeSet<usize> = report.rendered.iter().map(|t| t.level).collect();
            assert!(
                masks.len() > 2,
                "{name}: the view draws masks {masks:?} only"
            );
            let levels: BTreeSet<u8> = report.rendered.iter().map(|t| t.id.level).collect();
            pyramid_levels.insert(levels.len());
        }
        let ratios = seam_ratios_of(&model, Rendering::Textured, engine);
        assert!(
            ratios.iter().all(|&r| r <= MAX_RATIO),
            "border/interior {ratios:.3?} (top-down, oblique)"
        );
        let lit = engine_with(&model.path, Rendering::LitTextured, None);
        seam_ratios_of(&model, Rendering::LitTextured, lit);
    }
    assert!(
        pyramid_levels.iter().any(|&n| n > 1),
        "no view draws two levels of the pyramid"
    );
}
