//! HUD properties, without golden images: off costs nothing and changes nothing; on, it changes
//! only pixels inside its panels; minimap cells show their states' colours; the same input
//! gives the same bytes; RGB565 and RGBA8888 frames get the same HUD.

use crate::common;

use proptest::prelude::*;
use stripmask_platform::{Hud, HudInfo, Minimap, MinimapCell, Overlay, compose_rgba};
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer};

const STATES: [MinimapCell; 5] = [
    MinimapCell::Empty,
    MinimapCell::Cached,
    MinimapCell::Loaded,
    MinimapCell::Fetching,
    MinimapCell::Rendered,
];

fn frame(width: u32, height: u32, format: ColorFormat, color: [u8; 3]) -> Framebuffer {
    let mut fb = Framebuffer::new(width, height, format, DepthFormat::None).unwrap();
    fb.clear_color(color);
    fb
}

fn minimap() -> impl Strategy<Value = Minimap> {
    (1u32..12, 1u32..12).prop_flat_map(|(w, h)| {
        let n = (w * h) as usize;
        (
            prop::collection::vec(0usize..5, n),
            (-2.0f32..14.0, -2.0f32..14.0),
            -7.0f32..7.0,
            prop::option::of(prop::collection::vec(0.0f32..1.0, n)),
            prop::option::of((-1.0f32..14.0, -1.0f32..14.0)),
        )
            .prop_map(
                move |(cells, viewer, heading, importance, extent)| Minimap {
                    width: w,
                    height: h,
                    cells: cells.into_iter().map(|i| STATES[i]).collect(),
                    viewer,
                    heading,
                    importance,
                    extent,
                },
            )
    })
}

fn hud_info() -> impl Strategy<Value = HudInfo> {
    (
        (0.0f32..500.0, 1.0f32..120.0),
        (any::<u32>(), any::<u32>()),
        (any::<u64>(), any::<u64>()),
        (0u32..10_000, 0u32..10_000),
        prop::option::of(minimap()),
    )
        .prop_map(|(fps, tris, mem, tiles, minimap)| HudInfo {
            fps: fps.0,
            target_fps: fps.1,
            triangles: u64::from(tris.0),
            budget: u64::from(tris.1),
            memory_bytes: mem.0,
            memory_limit_bytes: mem.1,
            tiles_loaded: tiles.0,
            tiles_rendered: tiles.1,
            holes: tiles.0 % 3,
            minimap,
            ..HudInfo::default()
        })
}

fn format() -> impl Strategy<Value = ColorFormat> {
    prop_oneof![Just(ColorFormat::Rgb565), Just(ColorFormat::Rgba8888)]
}

fn inside_a_panel(overlay: &Overlay, x: u32, y: u32) -> bool {
    overlay.panels().any(|r| r.contains(x, y))
}

#[test]
fn off_the_hud_draws_nothing_and_the_frame_is_shown_as_it_is() {
    let mut hud = Hud::new(false);
    let info = HudInfo {
        minimap: Some(Minimap {
            width: 2,
            height: 2,
            ..Minimap::default()
        }),
        ..HudInfo::default()
    };
    assert!(hud.render(&info, 320, 240).is_none());
    for format in [ColorFormat::Rgb565, ColorFormat::Rgba8888] {
        let fb = common::painted(9, 7, format, common::pattern);
        assert_eq!(compose_rgba(&fb, None), fb.to_rgba_image());
    }
    hud.apply(stripmask_platform::Command::Hud);
    assert!(hud.render(&info, 320, 240).is_some());
}

/// A frame with holes says how many on the statistics panel, which grows to hold the words.
#[test]
fn holes_are_shown_when_there_are_some() {
    let width = |holes| {
        let mut hud = Hud::new(true);
        let info = HudInfo {
            tiles_loaded: 40,
            holes,
            ..HudInfo::default()
        };
        let overlay = hud.render(&info, 320, 240).unwrap();
        overlay.panels().map(|r| r.width).max().unwrap()
    };
    assert!(width(3) > width(0));
}

#[test]
fn on_a_patterned_frame_only_panel_pixels_change() {
    let fb = common::painted(120, 90, ColorFormat::Rgba8888, common::pattern);
    let mut hud = Hud::new(true);
    let info = HudInfo {
        fps: 12.5,
        minimap: Some(Minimap {
            width: 5,
            height: 5,
            cells: vec![MinimapCell::Loaded; 25],
            viewer: (2.5, 2.5),
            ..Minimap::default()
        }),
        ..HudInfo::default()
    };
    let overlay = hud.render(&info, 120, 90).unwrap();
    assert_eq!(overlay.panels().count(), 2);
    let plain = compose_rgba(&fb, None);
    let with = compose_rgba(&fb, Some(overlay));
    for (x, y, px) in with.enumerate_pixels() {
        let changed = px != plain.get_pixel(x, y);
        assert_eq!(changed, inside_a_panel(overlay, x, y), "pixel ({x}, {y})");
    }
}

proptest! {
    #[test]
    fn changes_stay_inside_the_panels(
        info in hud_info(),
        (w, h) in (8u32..400, 8u32..300),
        format in format(),
        color in any::<[u8; 3]>(),
    ) {
        let fb = frame(w, h, format, color);
        let mut hud = Hud::new(true);
        let overlay = hud.render(&info, w, h).unwrap();
        let plain = compose_rgba(&fb, None);
        let with = compose_rgba(&fb, Some(overlay));
        for (x, y, px) in with.enumerate_pixels() {
            if px != plain.get_pixel(x, y) {
                prop_assert!(inside_a_panel(overlay, x, y), "pixel ({}, {}) changed outside the panels", x, y);
            }
        }
    }

    #[test]
    fn minimap_cells_show_their_colours_at_their_centres(
        mut map in minimap(),
        show_importance in any::<bool>(),
        (w, h) in (64u32..1400, 48u32..1000),
    ) {
        // Keep the viewer's arrow off the map: this test is about the cells.
        map.viewer = (-100.0, -100.0);
        let mut hud = Hud::new(true);
        hud.set_show_importance(show_importance);
        let info = HudInfo { minimap: Some(map.clone()), ..HudInfo::default() };
        let overlay = hud.render(&info, w, h).unwrap();
        let shown = compose_rgba(&frame(w, h, ColorFormat::Rgba8888, [1, 2, 3]), Some(overlay));
        for row in 0..map.height {
            for column in 0..map.width {
                // A cell lies within the model's extent, cut there, or is not drawn at all.
                let Some(cell) = overlay.minimap_cell(column, row) else {
                    let (ex, ey) = map.extent.expect("without an extent every cell is drawn");
                    prop_assert!(ex <= column as f32 + 1.0 || ey <= row as f32 + 1.0);
                    continue;
                };
                if let Some((ex, ey)) = map.extent {
                    prop_assert!((column as f32) < ex && (row as f32) < ey);
                }
                let (cx, cy) = (cell.x + cell.width / 2, cell.y + cell.height / 2);
                if cx >= w || cy >= h {
                    continue;
                }
                let px = shown.get_pixel(cx, cy).0;
                prop_assert_eq!([px[0], px[1], px[2]], map.cell_color(column, row, show_importance));
                if !show_importance || map.importance.is_none() {
                    let state = map.cells[(row * map.width + column) as usize];
                    prop_assert_eq!([px[0], px[1], px[2]], state.color());
                }
            }
        }
        prop_assert!(overlay.minimap_cell(map.width, 0).is_none());
    }

    #[test]
    fn the_same_input_gives_the_same_bytes(info in hud_info(), format in format()) {
        let fb = frame(320, 240, format, [90, 120, 30]);
        let first = compose_rgba(&fb, Hud::new(true).render(&info, 320, 240));
        let mut reused = Hud::new(true);
        reused.render(&HudInfo::default(), 640, 480);
        let second = compose_rgba(&fb, reused.render(&info, 320, 240));
        prop_assert_eq!(first, second);
    }

    #[test]
    fn rgb565_and_rgba8888_frames_get_the_same_hud(info in hud_info(), white in any::<bool>()) {
        // Black and white are exact in both formats, so the composites must agree.
        let color = if white { [255; 3] } else { [0; 3] };
        let mut hud = Hud::new(true);
        let overlay = hud.render(&info, 200, 150);
        let a = compose_rgba(&frame(200, 150, ColorFormat::Rgb565, color), overlay);
        let b = compose_rgba(&frame(200, 150, ColorFormat::Rgba8888, color), overlay);
        prop_assert_eq!(a, b);
    }
}

#[test]
fn the_importance_overlay_colours_the_most_important_cell_yellow() {
    let map = Minimap {
        width: 2,
        height: 1,
        cells: vec![MinimapCell::Rendered, MinimapCell::Cached],
        viewer: (-50.0, -50.0),
        importance: Some(vec![0.8, 0.0]),
        ..Minimap::default()
    };
    let info = HudInfo {
        minimap: Some(map),
        ..HudInfo::default()
    };
    let fb = frame(320, 240, ColorFormat::Rgb565, [0; 3]);
    let mut hud = Hud::new(true);
    for (importance, first) in [
        (false, MinimapCell::Rendered.color()),
        (true, [255, 240, 80]),
    ] {
        hud.set_show_importance(importance);
        let overlay = hud.render(&info, 320, 240).unwrap();
        let shown = compose_rgba(&fb, Some(overlay));
        let at = |column| {
            let c = overlay.minimap_cell(column, 0).unwrap();
            let px = shown.get_pixel(c.x + c.width / 2, c.y + c.height / 2).0;
            [px[0], px[1], px[2]]
        };
        assert_eq!(at(0), first);
        assert_eq!(at(1), MinimapCell::Cached.color());
    }
}

#[test]
fn the_statistics_are_written_in_white() {
    let fb = frame(320, 240, ColorFormat::Rgba8888, [0; 3]);
    let mut hud = Hud::new(true);
    let overlay = hud.render(&HudInfo::default(), 320, 240).unwrap();
    let stats = overlay.panels().next().unwrap();
    let shown = compose_rgba(&fb, Some(overlay));
    let white = (stats.y..stats.y + stats.height)
        .flat_map(|y| (stats.x..stats.x + stats.width).map(move |x| (x, y)))
        .filter(|&(x, y)| shown.get_pixel(x, y).0 == [255, 255, 255, 255])
        .count();
    // "FPS 0.0 / 0", "TRIS 0 / 0", "MEM 0.0 / 0.0 MB", "TILES 0 LOADED 0 DRAWN": hundreds of
    // font pixels, and far fewer than the panel.
    assert!(
        white > 200 && white < (stats.width * stats.height / 2) as usize,
        "{white}"
    );
}
