//! The wireframe (`RenderSettings::wireframe`, the viewer's L key) on the crack scene: every
//! drawn tile's triangle edges, each once, over the shaded terrain or over a white one; off, the
//! frame is untouched. Golden image as in `tests/it/golden.rs` (re-bless with `STRIPMASK_BLESS=1`).

use crate::support;

use crate::support::crack_scene;

use std::collections::BTreeSet;

use crack_scene::scene;
use stripmask::db::mask_level::kept_indices;
use stripmask::engine::cracks::CrackMode;
use stripmask::engine::render::Wireframe;
use stripmask::engine::{Engine, FrameReport};
use stripmask::sim::crack_metric::{BACKGROUND, TILE_SIZE};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};
use support::golden::check;

const SIZE: (u32, u32) = (320, 240);
const VIEW: usize = 9;

fn render(engine: &mut Engine, wireframe: Wireframe) -> (Framebuffer, FrameReport) {
    engine.render_settings_mut().wireframe = wireframe;
    let mut fb = Framebuffer::new(SIZE.0, SIZE.1, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
    let report = scene().render(engine, VIEW, &mut fb).unwrap();
    (fb, report)
}

fn pixels(fb: &Framebuffer) -> Vec<[u8; 3]> {
    (0..fb.height())
        .flat_map(|y| (0..fb.width()).map(move |x| fb.pixel(x, y)))
        .collect()
}

#[test]
fn the_wireframe_draws_every_edge_of_every_drawn_tile_once() {
    let mut engine = scene().engine(CrackMode::None, SIZE).unwrap();
    for level in [0, 2, 5] {
        engine.force_levels(Some(Box::new(move |_| level)));
        let (_, report) = render(&mut engine, Wireframe::Over);
        // A strip mask is a triangulated square of k x k kept samples: E = V + F - 1.
        let k = kept_indices(TILE_SIZE, level).len() as u64;
        let edges = k * k + 2 * (k - 1) * (k - 1) - 1;
        assert!(report.rendered_tiles > 10);
        assert_eq!(
            report.wireframe.lines,
            edges * report.rendered_tiles as u64,
            "level {level}"
        );
        assert!(report.wireframe.fragments > 0);
        let (_, off) = render(&mut engine, Wireframe::Off);
        assert_eq!(off.wireframe, Default::default(), "off: no line");
        assert_eq!(off.draw, report.draw, "the triangles are the same");
    }
}

#[test]
fn over_the_terrain_only_line_pixels_change_and_most_edges_show() {
    let mut engine = scene().engine(CrackMode::Stitch, SIZE).unwrap();
    let (plain, _) = render(&mut engine, Wireframe::Off);
    let (wired, report) = render(&mut engine, Wireframe::Over);
    let changed: Vec<[u8; 3]> = pixels(&plain)
        .into_iter()
        .zip(pixels(&wired))
        .filter(|(a, b)| a != b)
        .map(|(_, b)| b)
        .collect();
    assert!(changed.iter().all(|&c| c == Wireframe::OVER_COLOR));
    // Lines cross at vertices, and terrain hides some edges: still most line pixels show.
    assert!(
        changed.len() as u64 * 2 > report.wireframe.fragments,
        "{} changed pixels for {:?}",
        changed.len(),
        report.wireframe
    );
    assert!(changed.len() > 1000, "{}", changed.len());
    check("wireframe_over_stitched_terrain", &wired);
    let (again, _) = render(&mut engine, Wireframe::Off);
    assert!(
        pixels(&again) == pixels(&plain),
        "off again: the frame as before"
    );
}

#[test]
fn wireframe_only_draws_white_terrain_and_dark_edges() {
    let mut engine = scene().engine(CrackMode::Stitch, SIZE).unwrap();
    let (fb, report) = render(&mut engine, Wireframe::Only);
    let colors: BTreeSet<[u8; 3]> = pixels(&fb).into_iter().collect();
    assert!(colors.contains(&[255, 255, 255]), "{colors:?}");
    assert!(!colors.contains(&BACKGROUND), "stitched: no crack");
    assert_eq!(colors.len(), 2, "white and the line colour: {colors:?}");
    assert!(report.wireframe.fragments > 0);
}
