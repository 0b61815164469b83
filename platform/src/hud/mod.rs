//! The heads-up display: frame statistics and the minimap of the belts, drawn with tiny-skia
//! into panels that a presenter blends over the frame.

mod font;
mod minimap;
mod overlay;

use minimap::MinimapLayout;
pub use minimap::{Minimap, MinimapCell};
pub(crate) use overlay::Panel;
pub use overlay::{Overlay, PanelRect};

use tiny_skia::{Color, Paint, Pixmap};

use crate::Command;

/// What the HUD shows, filled in by the engine every frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct HudInfo {
    /// Frames per second, measured.
    pub fps: f32,
    /// The frame rate the budget aims at.
    pub target_fps: f32,
    /// Triangles drawn this frame.
    pub triangles: u64,
    /// The global triangle budget.
    pub budget: u64,
    /// Bytes of tile memory in use.
    pub memory_bytes: u64,
    /// The tile memory limit, in bytes.
    pub memory_limit_bytes: u64,
    /// Tiles in memory.
    pub tiles_loaded: u32,
    /// Tiles drawn this frame.
    pub tiles_rendered: u32,
    /// Holes this frame: tiles in view with nothing to draw (shown only when there are some).
    pub holes: u32,
    /// The largest geometric error of a drawn tile on screen, pixels.
    pub max_error_px: f32,
    /// What capped the frame's detail (`budget`, `tau` or `full`; empty: not shown).
    pub bound: &'static str,
    /// The belts around the viewer, if the engine has them.
    pub minimap: Option<Minimap>,
    /// A last line, when there is something more to say (a pose feed's state).
    pub status: Option<String>,
}

impl HudInfo {
    /// The statistics panel's lines.
    fn lines(&self) -> Vec<String> {
        // MB of 10^6 bytes, as the command line counts them.
        const MB: f64 = 1e6;
        let mut lines = vec![
            format!("FPS {:.1} / {:.0}", self.fps, self.target_fps),
            format!("TRIS {} / {}", self.triangles, self.budget),
            format!(
                "MEM {:.1} / {:.1} MB",
                self.memory_bytes as f64 / MB,
                self.memory_limit_bytes as f64 / MB
            ),
            match self.holes {
                0 => format!(
                    "TILES {} LOADED {} DRAWN",
                    self.tiles_loaded, self.tiles_rendered
                ),
                holes => format!(
                    "TILES {} LOADED {} DRAWN {holes} HOLES",
                    self.tiles_loaded, self.tiles_rendered
                ),
            },
            format!(
                "ERR {:.1} PX BOUND {}",
                self.max_error_px,
                self.bound.to_uppercase()
            ),
        ];
        lines.extend(self.status.clone());
        lines
    }
}

/// Panel background: black, alpha 160 of 255.
const BACKGROUND_ALPHA: u8 = 160;

/// The HUD: a switch, the importance-overlay switch, and the panels of the last frame.
/// Off, [`Hud::render`] does no work and returns no overlay.
#[derive(Clone, Debug, Default)]
pub struct Hud {
    enabled: bool,
    show_importance: bool,
    overlay: Overlay,
}

impl Hud {
    /// A HUD, on or off; the importance overlay starts off.
    pub fn new(enabled: bool) -> Self {
        Self {
            enabled,
            ..Self::default()
        }
    }

    /// Whether the HUD is drawn.
    pub fn is_enabled(&self) -> bool {
        self.enabled
    }

    /// Turns the HUD on or off.
    pub fn set_enabled(&mut self, on: bool) {
        self.enabled = on;
    }

    /// Whether the minimap colours cells by visual importance.
    pub fn shows_importance(&self) -> bool {
        self.show_importance
    }

    /// Colours minimap cells by visual importance (where the engine supplies it) or by state.
    pub fn set_show_importance(&mut self, on: bool) {
        self.show_importance = on;
    }

    /// Takes the HUD's own commands ([`Command::Hud`], [`Command::Importance`]); returns whether
    /// `command` was one of them.
    pub fn apply(&mut self, command: Command) -> bool {
        match command {
            Command::Hud => self.enabled = !self.enabled,
            Command::Importance => self.show_importance = !self.show_importance,
            _ => return false,
        }
        true
    }

    /// Draws the panels for a frame of `width` x `height` pixels, or returns `None` at no cost
    /// when the HUD is off. The same input gives the same pixels.
    pub fn render(&mut self, info: &HudInfo, width: u32, height: u32) -> Option<&Overlay> {
        if !self.enabled {
            return None;
        }
        let scale = (width / 320).min(height / 240).clamp(1, 4);
        let pad = 3 * scale;
        let margin = 2 * scale;
        self.overlay.panels.clear();
        self.overlay.minimap = None;

        let lines = info.lines();
        let text_w = lines
            .iter()
            .map(|l| font::text_width(l, scale))
            .max()
            .unwrap_or(0);
        let text_h = (lines.len() as u32 * font::LINE_HEIGHT - 2) * scale;
        let mut stats = panel(text_w + 2 * pad, text_h + 2 * pad);
        let mut ink = Paint {
            anti_alias: false,
            ..Paint::default()
        };
        ink.set_color_rgba8(255, 255, 255, 255);
        for (i, line) in lines.iter().enumerate() {
            let y = pad + i as u32 * font::LINE_HEIGHT * scale;
            font::draw_text(&mut stats, line, pad, y, scale, &ink);
        }
        self.push(margin, margin, stats);

        if let Some(map) = info
            .minimap
            .as_ref()
            .filter(|m| m.width > 0 && m.height > 0)
        {
            let cell = MinimapLayout::cell_size(map.width, map.height, width, height, scale);
            let gap = u32::from(cell >= 4);
            // The panel ends where the model does: padding gets no background either.
            let layout = MinimapLayout::new(map, pad, pad, cell, gap);
            let (map_w, map_h) = layout.extent;
            let mut pixmap = panel(map_w + 2 * pad, map_h + 2 * pad);
            minimap::draw(&mut pixmap, map, &layout, self.show_importance);
            let x = width.saturating_sub(margin + pixmap.width());
            self.overlay.minimap = Some(MinimapLayout {
                x: x + pad,
                y: margin + pad,
                ..layout
            });
            self.push(x, margin, pixmap);
        }
        Some(&self.overlay)
    }

    fn push(&mut self, x: u32, y: u32, pixmap: Pixmap) {
        let rect = PanelRect {
            x,
            y,
            width: pixmap.width(),
            height: pixmap.height(),
        };
        self.overlay.panels.push(Panel { rect, pixmap });
    }
}

/// A panel of the given size filled with the background.
fn panel(width: u32, height: u32) -> Pixmap {
    let mut pixmap = Pixmap::new(width.max(1), height.max(1)).expect("HUD panels are small");
    pixmap.fill(Color::from_rgba8(0, 0, 0, BACKGROUND_ALPHA));
    pixmap
}
