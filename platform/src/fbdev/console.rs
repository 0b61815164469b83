//! The text console behind the framebuffer: switched to graphics mode while frames are shown,
//! so that its text and blinking cursor stay off the screen, and switched back on drop.

use std::fs::File;

use super::ioctl::{self, KdMode};

/// KD_GRAPHICS from linux/kd.h.
const KD_GRAPHICS: KdMode = KdMode(1);

/// A virtual terminal put in graphics mode; its previous mode comes back on drop.
#[derive(Debug)]
pub(crate) struct Console {
    tty: File,
    previous: KdMode,
}

impl Console {
    /// Puts the controlling terminal in graphics mode, if it is a virtual terminal.
    pub fn take_over() -> Option<Self> {
        let tty = File::options()
            .read(true)
            .write(true)
            .open("/dev/tty")
            .ok()?;
        Self::take_over_tty(tty)
    }

    /// Puts `tty` in graphics mode; `None` when it is not a virtual terminal (a pseudo-terminal
    /// over ssh, a serial line, a regular file) or refuses.
    pub fn take_over_tty(tty: File) -> Option<Self> {
        let previous = ioctl::get::<KdMode>(&tty).ok()?;
        ioctl::set_kd_mode(&tty, KD_GRAPHICS).ok()?;
        Some(Self { tty, previous })
    }
}

impl Drop for Console {
    fn drop(&mut self) {
        // Nothing more can be done if the terminal refuses now; the next login resets it.
        let _ = ioctl::set_kd_mode(&self.tty, self.previous);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_that_is_not_a_virtual_terminal_is_left_alone() {
        let path = std::env::temp_dir().join(format!("stripmask-tty-{}", std::process::id()));
        std::fs::write(&path, b"").unwrap();
        let file = File::options().read(true).write(true).open(&path).unwrap();
        assert!(Console::take_over_tty(file).is_none());
        std::fs::remove_file(&path).unwrap();
    }
}
