//! Cracks where tiles of different pyramid levels meet: a hilly model seen from high up and
//! obliquely, so that the cut draws coarser pyramid levels towards the far edge of the screen,
//! with the terrain covering the whole screen over magenta. Stitching conforms both sides of
//! such a border to masks that share its vertices, skirts hang under it; without either, the
//! coarser tile's long border segments leave the finer tile's vertices in the air.

use std::collections::BTreeSet;
use std::path::Path;

use glam::DVec3;
use stripmask::Viewport;
use stripmask::db::builder::BuildOptions;
use stripmask::db::source;
use stripmask::engine::cracks::CrackMode;
use stripmask::engine::error_bound::ErrorBound;
use stripmask::engine::paging::PagerMode;
use stripmask::engine::{Engine, EngineSettings, FrameReport, FrameTiming};
use stripmask::sim::crack_metric::{BACKGROUND, crack_pixels};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

use crate::support::hills::synthetic;

/// Samples per tile side: a texture of 32 texels per tile lets a tile of any level be drawn
/// once it is under 48 pixels wide, so the pixel error decides the levels.
const S: usize = 33;
const TILES: usize = 48;
const SPACING: f64 = 30.0;
const SIZE: (u32, u32) = (320, 240);

/// Writes the model: hills furrowed north to south, 300 m deep from one sample column to the
/// next, so that a tile of any level above 0 (which keeps every other column) errs by 300 m
/// and the borders between levels open by as much.
fn model(dir: &Path) -> std::path::PathBuf {
    let n = TILES * (S - 1) + 1;
    let options = BuildOptions {
        tile_size: S,
        spacing: Some(SPACING),
        texture_factor: 1,
        ..BuildOptions::default()
    };
    synthetic(dir, "pyramid-cracks", (n, n), &options, |i, j| {
        let furrow = if i % 2 == 0 { 150.0 } else { -150.0 };
        let (i, j) = (i as f32, j as f32);
        1000.0 + 300.0 * (i * 0.031).sin() * (j * 0.023).cos() + furrow
    })
}

/// Eye and target of the views: over the south half, looking north and down, the top of the
/// screen meeting the ground well inside the model.
fn views() -> Vec<(DVec3, DVec3)> {
    let side = (TILES * (S - 1)) as f64 * SPACING;
    [
        (0.35, 14000.0),
        (0.5, 20000.0),
        (0.6, 17000.0),
        (0.45, 11000.0),
    ]
    .into_iter()
    .map(|(x, height)| {
        let eye = DVec3::new(x * side, height, 0.98 * side);
        (eye, eye + DVec3::new(0.0, -1.0, -0.8))
    })
    .collect()
}

fn engine(archive: &Path, mode: CrackMode) -> Engine {
    let mut settings = EngineSettings {
        cracks: mode,
        memory_limit_bytes: 256 << 20,
        pager_mode: PagerMode::Stepped {
            fetches_per_update: 4096,
        },
        threads: 1,
        max_error: ErrorBound::Pixels(16.0),
        frame_timing: FrameTiming::Told,
        ..EngineSettings::default()
    };
    settings.render.sky = BACKGROUND;
    settings.render.fog = false;
    let source = source::open(&archive.display().to_string()).unwrap();
    let mut engine = Engine::new(
        source,
        settings,
        Viewport::new(SIZE.0, SIZE.1).with_fov_y(40f64.to_radians()),
    )
    .unwrap();
    // Every tile at its full mask: the only cracks left are where pyramid levels meet.
    engine.force_levels(Some(Box::new(|_| 0)));
    engine
}

/// Renders view `(eye, target)` until the resident tiles no longer change what is drawn.
fn settle(engine: &mut Engine, fb: &mut Framebuffer, (eye, target): (DVec3, DVec3)) -> FrameReport {
    let camera = engine.camera(eye, target, false);
    let mut report = engine.render(&camera, fb).unwrap();
    for _ in 0..8 {
        let next = engine.render(&camera, fb).unwrap();
        let same = next
            .rendered
            .iter()
            .map(|t| (t.id, t.level))
            .eq(report.rendered.iter().map(|t| (t.id, t.level)));
        report = next;
        if same {
            break;
        }
    }
    report
}

/// The pairs of pyramid levels that meet across a border between two drawn tiles.
fn level_borders(report: &FrameReport) -> BTreeSet<(u8, u8)> {
    let cells = (S - 1) as i64;
    // Each tile's extent in level-0 cells: x0, y0, x1, y1.
    let extent = |id: stripmask::db::grid::TileId| {
        let span = cells << id.level;
        let (x, y) = (i64::from(id.x) * span, i64::from(id.y) * span);
        (x, y, x + span, y + span)
    };
    let mut pairs = BTreeSet::new();
    for a in &report.rendered {
        for b in &report.rendered {
            let (ea, eb) = (extent(a.id), extent(b.id));
            let touch_x = (ea.2 == eb.0) && ea.1 < eb.3 && eb.1 < ea.3;
            let touch_y = (ea.3 == eb.1) && ea.0 < eb.2 && eb.0 < ea.2;
            if (touch_x || touch_y) && a.id.level != b.id.level {
                pairs.insert((a.id.level.min(b.id.level), a.id.level.max(b.id.level)));
            }
        }
    }
    pairs
}

/// Crack pixels over the views in `mode`, and the pyramid level pairs the views show.
fn measure(archive: &Path, mode: CrackMode) -> (usize, BTreeSet<(u8, u8)>) {
    let mut engine = engine(archive, mode);
    let mut fb = Framebuffer::new(SIZE.0, SIZE.1, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
    let mut cracks = 0;
    let mut pairs = BTreeSet::new();
    for view in views() {
        let report = settle(&mut engine, &mut fb, view);
        assert_eq!(report.holes, 0);
        cracks += crack_pixels(&fb);
        pairs.extend(level_borders(&report));
    }
    (cracks, pairs)
}

#[test]
fn stitch_and_skirts_close_the_borders_between_pyramid_levels() {
    let dir = tempfile::tempdir().unwrap();
    let archive = model(dir.path());
    let (none, pairs) = measure(&archive, CrackMode::None);
    assert!(
        pairs.contains(&(0, 1)) && pairs.contains(&(1, 2)),
        "the views must show borders between pyramid levels 0 and 1 and 1 and 2, not only \
         {pairs:?}"
    );
    assert!(
        none > 100,
        "{none} crack pixels without crack hiding: the scene proves nothing"
    );
    for mode in [CrackMode::Stitch, CrackMode::Skirts] {
        let (cracks, _) = measure(&archive, mode);
        assert_eq!(
            cracks, 0,
            "{mode:?} leaves crack pixels where pyramid levels meet"
        );
    }
}
