//! What the HUD shows of a frame: the paper's Figure 2 (tile states around the viewer) and
//! Figure 3 (visual importance of the drawn tiles), for the viewer and `fly`'s frames.

use stripmask_platform::{HudInfo, Minimap, MinimapCell};

use crate::db::grid::TileId;
use crate::engine::allocation::Allocation;
use crate::engine::error_bound::Bound;
use crate::engine::paging::TileState;
use crate::engine::{Engine, FrameReport};

/// The largest minimap side in cells; bigger grids show the part around the viewer.
const MINIMAP_CELLS: u32 = 32;

/// The HUD's numbers and minimap for a frame: the paper's Figure 2 (tile states around the
/// viewer) and Figure 3 (visual importance of the drawn tiles).
pub fn hud_info(engine: &Engine, report: &FrameReport, fps: f64) -> HudInfo {
    let terrain = engine.terrain();
    // The map's frame is the model's own extent: its north-west corner is the grid's, and
    // tiles padded to whole size are cut at its east and south edges.
    let (px, py) = terrain.tile_position(report.view.camera.position);
    let (ex, ey) = terrain.source_extent();
    let (ex, ey) = (ex / terrain.tile_metres(), ey / terrain.tile_metres());
    let cells = |extent: f64, tiles: u32| (extent.ceil() as u32).clamp(1, tiles);
    let (gw, gh) = (cells(ex, terrain.tiles_x), cells(ey, terrain.tiles_y));
    let (mw, mh) = (gw.min(MINIMAP_CELLS), gh.min(MINIMAP_CELLS));
    let corner = |p: f64, size: u32, cells: u32| {
        ((p.floor() as i64 - i64::from(cells / 2)).clamp(0, i64::from(size - cells))) as u32
    };
    let (x0, y0) = (corner(px, gw, mw), corner(py, gh, mh));
    let mut cells = Vec::with_capacity((mw * mh) as usize);
    let mut importance = vec![0.0f32; (mw * mh) as usize];
    for y in y0..y0 + mh {
        for x in x0..x0 + mw {
            cells.push(match engine.pager().state(TileId::new(x, y)) {
                TileState::Square => MinimapCell::Loaded,
                TileState::Cached => MinimapCell::Cached,
                TileState::Fetching => MinimapCell::Fetching,
                TileState::Failed | TileState::Absent => MinimapCell::Empty,
            });
        }
    }
    // A drawn tile of pyramid level k covers 2^k x 2^k cells of the map, each shown with its
    // importance.
    for r in &report.rendered {
        let span = u64::from(r.id.span());
        let clip = |t: u32, start: u32, cells: u32| {
            let (lo, hi) = (u64::from(t) * span, (u64::from(t) + 1) * span);
            let (a, b) = (u64::from(start), u64::from(start + cells));
            (lo.max(a)..hi.min(b)).map(move |c| (c - a) as u32)
        };
        for y in clip(r.id.y, y0, mh) {
            for x in clip(r.id.x, x0, mw) {
                let k = (y * mw + x) as usize;
                cells[k] = MinimapCell::Rendered;
                importance[k] = r.importance as f32;
            }
        }
    }
    HudInfo {
        fps: fps as f32,
        target_fps: engine.settings().budget.target_fps as f32,
        triangles: report.draw.triangles,
        budget: report.budget as u64,
        memory_bytes: report.pager.memory_bytes as u64,
        memory_limit_bytes: report.pager.memory_limit_bytes as u64,
        tiles_loaded: report.pager.loaded_tiles as u32,
        tiles_rendered: report.rendered_tiles as u32,
        holes: report.holes as u32,
        max_error_px: report.max_error_px as f32,
        bound: bound_name(report),
        minimap: Some(Minimap {
            width: mw,
            height: mh,
            cells,
            viewer: ((px - f64::from(x0)) as f32, (py - f64::from(y0)) as f32),
            heading: report.view.camera.heading() as f32,
            importance: Some(importance),
            extent: Some(((ex - f64::from(x0)) as f32, (ey - f64::from(y0)) as f32)),
        }),
        status: None,
    }
}

/// What bounded the frame, and when the budget did, how it was shared: the HUD's error line.
fn bound_name(report: &FrameReport) -> &'static str {
    match (report.bound, report.allocation) {
        (Bound::Budget, Allocation::Importance) => "budget by importance",
        (Bound::Budget, Allocation::Error) => "budget by error",
        (bound, _) => bound.name(),
    }
}
