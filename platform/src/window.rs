//! A desktop window through minifb's X11 backend. Xlib is loaded at run time, so building
//! needs no X11 development packages and a machine without X fails with an error, not a crash.

use minifb::{Key, KeyRepeat, MouseButton, MouseMode, ScaleMode, Window, WindowOptions};
use stripmask_raster::Framebuffer;

use crate::compose::RowReader;
use crate::fit::{Fit, Placement};
use crate::{Command, Input, Motion, Overlay, PlatformError, Presenter};

/// The key that sends each command.
const COMMAND_KEYS: &[(Key, Command)] = &[
    (Key::Equal, Command::SpeedUp),
    (Key::NumPadPlus, Command::SpeedUp),
    (Key::Minus, Command::SpeedDown),
    (Key::NumPadMinus, Command::SpeedDown),
    (Key::P, Command::Pause),
    (Key::K, Command::CrackMode),
    (Key::L, Command::Wireframe),
    (Key::F, Command::Precision),
    (Key::RightBracket, Command::BudgetUp),
    (Key::LeftBracket, Command::BudgetDown),
    (Key::H, Command::Hud),
    (Key::I, Command::Importance),
];

/// A resizable window showing frames, scaled to fit (nearest neighbour, aspect kept) when
/// the frame and the window differ in size. Input comes from its keyboard and mouse.
pub struct WindowPresenter {
    window: Window,
    display: String,
    /// The window's pixels, 0RGB.
    buffer: Vec<u32>,
    /// Where the last frame went.
    placement: Option<Placement>,
    /// The last window size reported through input.
    reported_size: (usize, usize),
    /// Whether the window processed events since the last poll.
    pumped: bool,
    /// Input gathered since the last poll.
    pending: Input,
    /// Mouse position at the last event pump while the left button was held.
    drag_from: Option<(f32, f32)>,
}

impl std::fmt::Debug for WindowPresenter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WindowPresenter")
            .field("display", &self.display)
            .field("size", &self.window.get_size())
            .finish_non_exhaustive()
    }
}

impl WindowPresenter {
    /// Opens a resizable window of `width` x `height` pixels on the X display named by DISPLAY.
    pub fn open(title: &str, width: u32, height: u32) -> Result<Self, PlatformError> {
        let display = std::env::var("DISPLAY").unwrap_or_default();
        if display.is_empty() {
            return Err(PlatformError::NoDisplay);
        }
        let options = WindowOptions {
            resize: true,
            scale_mode: ScaleMode::UpperLeft,
            ..WindowOptions::default()
        };
        let mut window =
            Window::new(title, width as usize, height as usize, options).map_err(|e| {
                PlatformError::Window {
                    display: display.clone(),
                    message: e.to_string(),
                }
            })?;
        // The engine paces frames itself: minifb must not sleep.
        window.set_target_fps(0);
        let size = window.get_size();
        Ok(Self {
            window,
            display,
            buffer: Vec::new(),
            placement: None,
            reported_size: size,
            pumped: false,
            pending: Input::default(),
            drag_from: None,
        })
    }

    /// The window's inner size in pixels.
    pub fn size(&self) -> (u32, u32) {
        let (w, h) = self.window.get_size();
        (w as u32, h as u32)
    }

    /// Gathers what happened in the event pump that just ran: each pump is followed by exactly
    /// one gather, so a key press is reported once.
    fn gather(&mut self) {
        self.pumped = true;
        let input = &mut self.pending;
        for key in self.window.get_keys_pressed(KeyRepeat::No) {
            if key == Key::Escape {
                input.quit = true;
            }
            input.commands.extend(
                COMMAND_KEYS
                    .iter()
                    .filter(|(k, _)| *k == key)
                    .map(|(_, c)| *c),
            );
        }
        if !self.window.is_open() {
            input.quit = true;
        }
        let size = self.window.get_size();
        if size != self.reported_size {
            self.reported_size = size;
            input.resized = Some((size.0 as u32, size.1 as u32));
        }
        let pos = self.window.get_mouse_pos(MouseMode::Pass);
        if self.window.get_mouse_down(MouseButton::Left) {
            if let (Some((x0, y0)), Some((x, y))) = (self.drag_from, pos) {
                input.drag.0 += x - x0;
                input.drag.1 += y - y0;
            }
            self.drag_from = pos;
        } else {
            self.drag_from = None;
        }
    }

    fn motion(&self) -> Motion {
        let down = |keys: &[Key]| keys.iter().any(|&k| self.window.is_key_down(k));
        Motion {
            forward: down(&[Key::W, Key::Up]),
            back: down(&[Key::S, Key::Down]),
            left: down(&[Key::A, Key::Left]),
            right: down(&[Key::D, Key::Right]),
            up: down(&[Key::Space, Key::PageUp]),
            down: down(&[Key::C, Key::PageDown]),
        }
    }
}

impl Presenter for WindowPresenter {
    fn present(&mut self, frame: &Framebuffer, hud: Option<&Overlay>) -> Result<(), PlatformError> {
        let frame_size = (frame.width(), frame.height());
        let (w, h) = self.window.get_size();
        let (w, h) = (w.max(1), h.max(1));
        let output = (w as u32, h as u32);
        if self
            .placement
            .as_ref()
            .is_none_or(|p| p.frame != frame_size || p.output != output)
        {
            self.buffer.clear();
            self.buffer.resize(w * h, 0);
            self.placement = Some(Placement::new(frame_size, output, Fit::Scale));
        }
        let placement = self.placement.as_ref().expect("placed above");
        let mut reader = RowReader::new(frame, hud);
        for (dy, &sy) in placement.rows.iter().enumerate() {
            let src = reader.row(sy);
            let start = (placement.y as usize + dy) * w + placement.x as usize;
            let out = &mut self.buffer[start..start + placement.columns.len()];
            for (px, &sx) in out.iter_mut().zip(&placement.columns) {
                let [r, g, b] = src[sx as usize];
                *px = (u32::from(r) << 16) | (u32::from(g) << 8) | u32::from(b);
            }
        }
        let result = self.window.update_with_buffer(&self.buffer, w, h);
        self.gather();
        result.map_err(|e| PlatformError::Window {
            display: self.display.clone(),
            message: e.to_string(),
        })
    }

    fn poll_input(&mut self) -> Input {
        if !self.pumped {
            self.window.update();
            self.gather();
        }
        self.pumped = false;
        Input {
            motion: self.motion(),
            ..std::mem::take(&mut self.pending)
        }
    }
}
