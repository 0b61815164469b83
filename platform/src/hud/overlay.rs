//! What the HUD hands a presenter: premultiplied RGBA panels at frame positions, blended over
//! frame rows as they are converted.

use tiny_skia::Pixmap;

use super::minimap::MinimapLayout;

/// A panel's place on the frame, in frame pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PanelRect {
    /// Left edge.
    pub x: u32,
    /// Top edge.
    pub y: u32,
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
}

impl PanelRect {
    /// Whether the pixel (`x`, `y`) lies inside.
    pub fn contains(&self, x: u32, y: u32) -> bool {
        x >= self.x && y >= self.y && x - self.x < self.width && y - self.y < self.height
    }
}

/// One drawn panel.
#[derive(Clone, Debug)]
pub(crate) struct Panel {
    pub rect: PanelRect,
    pub pixmap: Pixmap,
}

/// The HUD of one frame: panels that cover only their own rectangles. Parts of a panel past
/// the frame's edge are not shown.
#[derive(Clone, Debug, Default)]
pub struct Overlay {
    pub(crate) panels: Vec<Panel>,
    pub(crate) minimap: Option<MinimapLayout>,
}

impl Overlay {
    /// Where the panels are.
    pub fn panels(&self) -> impl Iterator<Item = PanelRect> + '_ {
        self.panels.iter().map(|p| p.rect)
    }

    /// Where minimap cell (`column`, `row`) is drawn, without its grid line and cut at the
    /// model's extent; `None` when there is no minimap, no such cell, or the cell is wholly
    /// padding.
    pub fn minimap_cell(&self, column: u32, row: u32) -> Option<PanelRect> {
        let (x, y, width, height) = self.minimap?.cell_rect(column, row)?;
        Some(PanelRect {
            x,
            y,
            width,
            height,
        })
    }

    /// Blends the panels over row `y` of a frame (8-bit RGB, one entry per column): source-over
    /// with the panels' premultiplied alpha, rounded to nearest.
    pub fn blend_row(&self, y: u32, row: &mut [[u8; 3]]) {
        for panel in &self.panels {
            let r = panel.rect;
            if y < r.y || y - r.y >= r.height || r.x as usize >= row.len() {
                continue;
            }
            let start = ((y - r.y) * r.width) as usize;
            let src = &panel.pixmap.pixels()[start..start + r.width as usize];
            for (dst, s) in row[r.x as usize..].iter_mut().zip(src) {
                let keep = 255 - u16::from(s.alpha());
                let mix = |d: u8, s: u8| (u16::from(s) + (u16::from(d) * keep + 127) / 255) as u8;
                *dst = [
                    mix(dst[0], s.red()),
                    mix(dst[1], s.green()),
                    mix(dst[2], s.blue()),
                ];
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use tiny_skia::{Color, Paint, Rect, Transform};

    #[test]
    fn blending_follows_source_over_and_stays_inside_the_panel() {
        let mut pixmap = Pixmap::new(2, 1).unwrap();
        pixmap.fill(Color::from_rgba8(0, 0, 0, 128));
        let mut paint = Paint::default();
        paint.set_color_rgba8(255, 255, 255, 255);
        pixmap.fill_rect(
            Rect::from_xywh(1.0, 0.0, 1.0, 1.0).unwrap(),
            &paint,
            Transform::identity(),
            None,
        );
        let overlay = Overlay {
            panels: vec![Panel {
                rect: PanelRect {
                    x: 1,
                    y: 3,
                    width: 2,
                    height: 1,
                },
                pixmap,
            }],
            minimap: None,
        };
        let mut row = [[200, 100, 0]; 4];
        overlay.blend_row(2, &mut row);
        assert_eq!(row, [[200, 100, 0]; 4]);
        overlay.blend_row(3, &mut row);
        // 50% black over (200, 100, 0): keep 127/255 of the colour.
        let half = |v: u16| ((v * 127 + 127) / 255) as u8;
        assert_eq!(
            row,
            [
                [200, 100, 0],
                [half(200), half(100), 0],
                [255, 255, 255],
                [200, 100, 0]
            ]
        );
        let mut short = [[9, 9, 9]; 2];
        overlay.blend_row(3, &mut short);
        assert_eq!(short[0], [9, 9, 9]);
    }
}
