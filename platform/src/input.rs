//! What the user did since the last frame, in the engine's terms rather than a backend's keys.

/// Movement keys held down when input was polled: the camera moves while they are held.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Motion {
    /// W or Up arrow.
    pub forward: bool,
    /// S or Down arrow.
    pub back: bool,
    /// A or Left arrow.
    pub left: bool,
    /// D or Right arrow.
    pub right: bool,
    /// Space or Page Up.
    pub up: bool,
    /// C or Page Down.
    pub down: bool,
}

/// A one-shot command: reported once per key press.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Command {
    /// Fly faster (`+` or `=`, keypad `+`).
    SpeedUp,
    /// Fly slower (`-`, keypad `-`).
    SpeedDown,
    /// Pause or resume the flight (P).
    Pause,
    /// Next crack-hiding mode (K).
    CrackMode,
    /// Wireframe on or off (L).
    Wireframe,
    /// Fixed-point or float pipeline (F).
    Precision,
    /// Raise the triangle budget (`]`).
    BudgetUp,
    /// Lower the triangle budget (`[`).
    BudgetDown,
    /// HUD on or off (H).
    Hud,
    /// Visual-importance overlay on the minimap on or off (I).
    Importance,
}

/// Input gathered since the previous poll.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Input {
    /// Movement keys held now.
    pub motion: Motion,
    /// Commands in the order they were pressed.
    pub commands: Vec<Command>,
    /// Mouse movement while the left button was held, in window pixels (x right, y down).
    pub drag: (f32, f32),
    /// The output's new size in pixels, if it changed: re-create the framebuffer at this size.
    pub resized: Option<(u32, u32)>,
    /// The user asked to stop: Esc, the window closed, or Ctrl-C on the framebuffer console.
    pub quit: bool,
}
