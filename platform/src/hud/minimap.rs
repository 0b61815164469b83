//! The minimap of the belts around the viewer: one cell per tile, coloured by its paging state
//! as in the paper's Figure 2, or by visual importance as in its Figure 3.

use tiny_skia::{FillRule, Paint, PathBuilder, Pixmap, Rect, Transform};

/// What the pager knows about one tile of the minimap.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum MinimapCell {
    /// Not in memory and not asked for.
    #[default]
    Empty,
    /// In memory but outside the complete square of belts: kept as a cache.
    Cached,
    /// In memory, inside the complete square, not drawn this frame.
    Loaded,
    /// Requested, not arrived yet.
    Fetching,
    /// Drawn this frame.
    Rendered,
}

impl MinimapCell {
    /// The colour the minimap draws this state in.
    pub fn color(self) -> [u8; 3] {
        match self {
            MinimapCell::Empty => [48, 48, 48],
            MinimapCell::Cached => [70, 110, 190],
            MinimapCell::Loaded => [60, 150, 70],
            MinimapCell::Fetching => [235, 150, 40],
            MinimapCell::Rendered => [170, 240, 120],
        }
    }
}

/// The tiles around the viewer, row-major, top row (north) first.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Minimap {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// One state per cell; missing cells are drawn as [`MinimapCell::Empty`].
    pub cells: Vec<MinimapCell>,
    /// The viewer in cell units from the map's top-left corner (x right, y down).
    pub viewer: (f32, f32),
    /// Viewing direction in radians, clockwise from up (north).
    pub heading: f32,
    /// Visual importance per cell (the paper's Algorithm 2; 0 outside the view), if computed.
    pub importance: Option<Vec<f32>>,
    /// How far the model's own samples reach, in cell units from the map's top-left corner (x
    /// right, y down): tiles padded to whole size are drawn cut there, so that no pixel shows
    /// padding, and cells wholly beyond it not at all. `None`: every cell is whole.
    pub extent: Option<(f32, f32)>,
}

impl Minimap {
    /// The colour of cell (`column`, `row`): its importance on the ramp from blue (least) over
    /// red to yellow (most important) when `show_importance` is set and the cell has a positive
    /// importance, its state's colour otherwise.
    pub fn cell_color(&self, column: u32, row: u32, show_importance: bool) -> [u8; 3] {
        let i = row as usize * self.width as usize + column as usize;
        let state = self.cells.get(i).copied().unwrap_or_default();
        let importance = self
            .importance
            .as_ref()
            .filter(|_| show_importance)
            .and_then(|imp| imp.get(i).copied())
            .filter(|v| v.is_finite() && *v > 0.0);
        match importance {
            Some(v) => importance_ramp(v / self.max_importance()),
            None => state.color(),
        }
    }

    /// The largest finite importance (1 when there is none, so that ratios stay finite).
    fn max_importance(&self) -> f32 {
        self.importance
            .iter()
            .flatten()
            .copied()
            .filter(|v| v.is_finite() && *v > 0.0)
            .fold(None, |m: Option<f32>, v| Some(m.map_or(v, |m| m.max(v))))
            .unwrap_or(1.0)
    }
}

/// Blue at 0, red at 0.5, yellow at 1 (linear between).
fn importance_ramp(t: f32) -> [u8; 3] {
    const STOPS: [[f32; 3]; 3] = [
        [40.0, 40.0, 160.0],
        [230.0, 50.0, 40.0],
        [255.0, 240.0, 80.0],
    ];
    let t = t.clamp(0.0, 1.0) * 2.0;
    let (a, b, f) = if t <= 1.0 {
        (STOPS[0], STOPS[1], t)
    } else {
        (STOPS[1], STOPS[2], t - 1.0)
    };
    [0, 1, 2].map(|k| (a[k] + (b[k] - a[k]) * f).round() as u8)
}

/// Where the cells are drawn, in pixels from a corner of the frame or of the panel.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct MinimapLayout {
    /// Top-left corner of cell (0, 0).
    pub x: u32,
    /// Top-left corner of cell (0, 0).
    pub y: u32,
    /// Cell pitch.
    pub cell: u32,
    /// Blank pixels at the right and bottom of each cell (a grid line).
    pub gap: u32,
    /// Columns.
    pub columns: u32,
    /// Rows.
    pub rows: u32,
    /// Pixels right of and below (`x`, `y`) that show the model: nothing is drawn beyond.
    pub extent: (u32, u32),
}

impl MinimapLayout {
    /// The layout of `map` with cell (0, 0) at (`x`, `y`), cells `cell` pixels apart.
    pub fn new(map: &Minimap, x: u32, y: u32, cell: u32, gap: u32) -> MinimapLayout {
        let whole = (map.width * cell, map.height * cell);
        // A pixel is drawn only if it lies wholly inside the model: round the extent down.
        let cut = |e: f32, whole: u32| {
            if e.is_nan() {
                0
            } else {
                (e.max(0.0) * cell as f32).floor().min(whole as f32) as u32
            }
        };
        let extent = map
            .extent
            .map_or(whole, |(ex, ey)| (cut(ex, whole.0), cut(ey, whole.1)));
        MinimapLayout {
            x,
            y,
            cell,
            gap,
            columns: map.width,
            rows: map.height,
            extent,
        }
    }

    /// Cell pitch for a map of `columns` x `rows` on a frame of `width` x `height` at HUD
    /// `scale`: the map takes at most a third of the width and half the height.
    pub fn cell_size(columns: u32, rows: u32, width: u32, height: u32, scale: u32) -> u32 {
        let fit = (width / 3 / columns.max(1)).min(height / 2 / rows.max(1));
        fit.clamp(1, 8 * scale)
    }

    /// The pixels cell (`column`, `row`) is drawn on, without its grid line and cut at the
    /// model's extent: (x, y, width, height), or `None` when there is no such cell or it lies
    /// wholly beyond the extent.
    pub fn cell_rect(&self, column: u32, row: u32) -> Option<(u32, u32, u32, u32)> {
        if column >= self.columns || row >= self.rows {
            return None;
        }
        let (left, top) = (column * self.cell, row * self.cell);
        let side = self.cell - self.gap;
        let width = side.min(self.extent.0.saturating_sub(left));
        let height = side.min(self.extent.1.saturating_sub(top));
        (width > 0 && height > 0).then_some((self.x + left, self.y + top, width, height))
    }
}

/// Draws the cells and the viewer's arrow where `layout` puts them.
pub(crate) fn draw(
    pixmap: &mut Pixmap,
    map: &Minimap,
    layout: &MinimapLayout,
    show_importance: bool,
) {
    let mut paint = Paint {
        anti_alias: false,
        ..Paint::default()
    };
    for row in 0..map.height {
        for column in 0..map.width {
            let Some((x, y, w, h)) = layout.cell_rect(column, row) else {
                continue;
            };
            let [r, g, b] = map.cell_color(column, row, show_importance);
            paint.set_color_rgba8(r, g, b, 255);
            if let Some(rect) = Rect::from_xywh(x as f32, y as f32, w as f32, h as f32) {
                pixmap.fill_rect(rect, &paint, Transform::identity(), None);
            }
        }
    }
    draw_viewer(pixmap, map, layout.x, layout.y, layout.cell, &mut paint);
}

/// An arrow at the viewer's position pointing along the heading.
fn draw_viewer(pixmap: &mut Pixmap, map: &Minimap, x: u32, y: u32, cell: u32, paint: &mut Paint) {
    let (vx, vy) = map.viewer;
    if !(vx.is_finite() && vy.is_finite() && map.heading.is_finite()) {
        return;
    }
    let cx = x as f32 + vx * cell as f32;
    let cy = y as f32 + vy * cell as f32;
    let r = (cell as f32).max(4.0);
    let point = |angle: f32, len: f32| {
        let a = map.heading + angle;
        (cx + a.sin() * len, cy - a.cos() * len)
    };
    let mut pb = PathBuilder::new();
    let (tx, ty) = point(0.0, r);
    pb.move_to(tx, ty);
    let (lx, ly) = point(2.5, 0.7 * r);
    pb.line_to(lx, ly);
    let (rx, ry) = point(-2.5, 0.7 * r);
    pb.line_to(rx, ry);
    pb.close();
    if let Some(path) = pb.finish() {
        paint.set_color_rgba8(255, 255, 255, 255);
        pixmap.fill_path(&path, paint, FillRule::Winding, Transform::identity(), None);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ramp_runs_from_blue_over_red_to_yellow() {
        assert_eq!(importance_ramp(0.0), [40, 40, 160]);
        assert_eq!(importance_ramp(0.5), [230, 50, 40]);
        assert_eq!(importance_ramp(1.0), [255, 240, 80]);
        assert_eq!(importance_ramp(7.0), [255, 240, 80]);
    }

    #[test]
    fn importance_colours_only_cells_with_positive_importance_and_only_when_shown() {
        let map = Minimap {
            width: 3,
            height: 1,
            cells: vec![MinimapCell::Rendered, MinimapCell::Cached],
            importance: Some(vec![0.25, 0.0, f32::NAN]),
            ..Minimap::default()
        };
        assert_eq!(map.cell_color(0, 0, true), [255, 240, 80]);
        assert_eq!(map.cell_color(0, 0, false), MinimapCell::Rendered.color());
        assert_eq!(map.cell_color(1, 0, true), MinimapCell::Cached.color());
        assert_eq!(map.cell_color(2, 0, true), MinimapCell::Empty.color());
    }

    #[test]
    fn state_colours_are_distinct() {
        let all = [
            MinimapCell::Empty,
            MinimapCell::Cached,
            MinimapCell::Loaded,
            MinimapCell::Fetching,
            MinimapCell::Rendered,
        ];
        let colours: std::collections::HashSet<_> = all.iter().map(|s| s.color()).collect();
        assert_eq!(colours.len(), all.len());
    }
}
