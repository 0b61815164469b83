//! Crack hiding on the crack scene (`stripmask::sim::crack_metric`): views with every pair of
//! levels side by side, the terrain covering the screen, magenta behind it. Golden images of
//! one view per mode follow `tests/it/golden.rs` (re-bless with `STRIPMASK_BLESS=1`).

use crate::support;

use crate::support::crack_scene;

use crack_scene::scene;
use stripmask::engine::cracks::CrackMode;
use stripmask::sim::crack_metric::{CrackMeasurement, CrackScene, TILE_SIZE, crack_pixels};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};
use support::golden::check;

const SIZE: (u32, u32) = (320, 240);
/// The view of the golden images: cracks of many level pairs in the open.
const GOLDEN_VIEW: usize = 9;

fn measure(mode: CrackMode) -> CrackMeasurement {
    let m = scene().measure(mode, SIZE, 1).unwrap();
    let levels = TILE_SIZE - 1;
    assert_eq!(
        m.pairs.len(),
        levels * (levels + 1) / 2,
        "{mode:?}: the views must show every level pair, not only {:?}",
        m.pairs
    );
    m
}

#[test]
fn without_crack_hiding_the_views_show_cracks() {
    let none = measure(CrackMode::None);
    assert!(none.crack_pixels > 1000, "{none:?}");
    assert_eq!(none.triangles, none.mask_triangles);
}

#[test]
fn stitch_leaves_no_crack_pixel_on_views_with_every_level_pair() {
    let stitch = measure(CrackMode::Stitch);
    assert_eq!(stitch.crack_pixels, 0, "{stitch:?}");
    assert!(stitch.triangles <= stitch.mask_triangles, "{stitch:?}");
}

#[test]
fn skirts_cut_crack_pixels_by_at_least_ninety_percent() {
    let none = measure(CrackMode::None);
    let skirts = measure(CrackMode::Skirts);
    assert!(
        skirts.crack_pixels * 10 <= none.crack_pixels,
        "skirts {} against none {}",
        skirts.crack_pixels,
        none.crack_pixels
    );
}

/// One view of the crack scene in `mode`, for the golden images.
fn golden_view(mode: CrackMode) -> Framebuffer {
    let scene = scene();
    let mut engine = scene.engine(mode, SIZE).unwrap();
    let mut fb = Framebuffer::new(SIZE.0, SIZE.1, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
    scene.render(&mut engine, GOLDEN_VIEW, &mut fb).unwrap();
    fb
}

#[test]
fn golden_cracks_none_shows_magenta_between_levels() {
    check(
        "cracks_none_shows_magenta_between_levels",
        &golden_view(CrackMode::None),
    );
}

#[test]
fn golden_cracks_skirts_hang_under_the_borders() {
    check(
        "cracks_skirts_hang_under_the_borders",
        &golden_view(CrackMode::Skirts),
    );
}

#[test]
fn golden_cracks_stitch_closes_every_border() {
    check(
        "cracks_stitch_closes_every_border",
        &golden_view(CrackMode::Stitch),
    );
}

#[test]
fn shadows_cut_crack_pixels_by_at_least_ninety_percent() {
    let none = measure(CrackMode::None);
    let shadow = measure(CrackMode::Shadow);
    assert!(
        shadow.crack_pixels * 10 <= none.crack_pixels,
        "shadow {} against none {}",
        shadow.crack_pixels,
        none.crack_pixels
    );
    assert!(
        shadow.triangles > shadow.mask_triangles,
        "two triangles per quad drawn"
    );
}

#[test]
fn golden_cracks_shadow_fills_them_with_the_projected_tile() {
    check(
        "cracks_shadow_fills_them_with_the_projected_tile",
        &golden_view(CrackMode::Shadow),
    );
}

/// The grazing view in `mode`.
fn grazing(mode: CrackMode) -> Framebuffer {
    let mut scene = scene().clone();
    scene.views = vec![CrackScene::grazing_view()];
    let mut engine = scene.engine(mode, SIZE).unwrap();
    let mut fb = Framebuffer::new(SIZE.0, SIZE.1, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
    scene.render(&mut engine, 0, &mut fb).unwrap();
    fb
}

#[test]
fn shadows_fail_at_grazing_angles_where_stitch_does_not() {
    let none = crack_pixels(&grazing(CrackMode::None));
    let shadow = grazing(CrackMode::Shadow);
    assert!(
        crack_pixels(&shadow) * 2 > none,
        "the eye below the hills skips their shadows: {} of {none} crack pixels remain",
        crack_pixels(&shadow)
    );
    assert_eq!(crack_pixels(&grazing(CrackMode::Stitch)), 0);
    check("cracks_shadow_fails_at_grazing_angles", &shadow);
}
