//! Keyboard input on a board without a window system: `struct input_event` records read from an
//! evdev device (`/dev/input/eventN`) without blocking, mapped to the same [`Motion`] and
//! [`Command`]s as the window's keys.

use std::fs::{File, OpenOptions};
use std::io::{ErrorKind, Read};
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};

use crate::error::PlatformError;
use crate::input::{Command, Input, Motion};

/// `EV_KEY` in `linux/input-event-codes.h`.
const EV_KEY: u16 = 1;
/// Bytes of one `struct input_event` on this target (24 on 64-bit Linux, 16 on 32-bit).
const EVENT_BYTES: usize = std::mem::size_of::<libc::input_event>();

/// What a key does, by its evdev code (`KEY_*` in `linux/input-event-codes.h`).
enum Action {
    Hold(fn(&mut Motion) -> &mut bool),
    Press(Command),
    Quit,
}

fn action(code: u16) -> Option<Action> {
    use Action::{Hold, Press};
    Some(match code {
        17 | 103 => Hold(|m| &mut m.forward), // W, Up
        31 | 108 => Hold(|m| &mut m.back),    // S, Down
        30 | 105 => Hold(|m| &mut m.left),    // A, Left
        32 | 106 => Hold(|m| &mut m.right),   // D, Right
        57 | 104 => Hold(|m| &mut m.up),      // Space, Page Up
        46 | 109 => Hold(|m| &mut m.down),    // C, Page Down
        13 | 78 => Press(Command::SpeedUp),   // =, keypad +
        12 | 74 => Press(Command::SpeedDown), // -, keypad -
        25 => Press(Command::Pause),          // P
        37 => Press(Command::CrackMode),      // K
        38 => Press(Command::Wireframe),      // L
        33 => Press(Command::Precision),      // F
        27 => Press(Command::BudgetUp),       // ]
        26 => Press(Command::BudgetDown),     // [
        35 => Press(Command::Hud),            // H
        23 => Press(Command::Importance),     // I
        1 => Action::Quit,                    // Esc
        _ => return None,
    })
}

/// An evdev keyboard, read without blocking.
#[derive(Debug)]
pub struct EvdevInput {
    path: PathBuf,
    file: File,
    /// Bytes of a record cut short by the last read.
    partial: Vec<u8>,
    held: Motion,
}

impl EvdevInput {
    /// Opens `path` (an evdev device such as `/dev/input/event0`, or a file of recorded
    /// events) for non-blocking reads.
    pub fn open(path: &Path) -> Result<Self, PlatformError> {
        let file = OpenOptions::new()
            .read(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(path)
            .map_err(|source| PlatformError::InputOpen {
                path: path.to_path_buf(),
                source,
            })?;
        Ok(EvdevInput {
            path: path.to_path_buf(),
            file,
            partial: Vec::new(),
            held: Motion::default(),
        })
    }

    /// Reads every event available now (never waits) and returns the keys held and the
    /// commands pressed since the last poll. Keys other than those of the viewer's table,
    /// auto-repeats and non-key events are skipped.
    pub fn poll(&mut self) -> Result<Input, PlatformError> {
        let mut input = Input::default();
        let mut buf = [0u8; 64 * EVENT_BYTES];
        loop {
            let n = match self.file.read(&mut buf) {
                Ok(0) => break,
                Ok(n) => n,
                Err(e) if e.kind() == ErrorKind::WouldBlock => break,
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(source) => {
                    return Err(PlatformError::InputRead {
                        path: self.path.clone(),
                        source,
                    });
                }
            };
            self.partial.extend_from_slice(&buf[..n]);
            let whole = self.partial.len() / EVENT_BYTES * EVENT_BYTES;
            let records: Vec<u8> = self.partial.drain(..whole).collect();
            for record in records.chunks_exact(EVENT_BYTES) {
                self.apply(record, &mut input);
            }
        }
        input.motion = self.held;
        Ok(input)
    }

    fn apply(&mut self, record: &[u8], input: &mut Input) {
        // `struct timeval time; __u16 type; __u16 code; __s32 value;`, native byte order.
        let at = EVENT_BYTES - 8;
        let kind = u16::from_ne_bytes([record[at], record[at + 1]]);
        let code = u16::from_ne_bytes([record[at + 2], record[at + 3]]);
        let value = i32::from_ne_bytes([
            record[at + 4],
            record[at + 5],
            record[at + 6],
            record[at + 7],
        ]);
        if kind != EV_KEY {
            return;
        }
        match (action(code), value) {
            (Some(Action::Hold(key)), 0 | 1) => *key(&mut self.held) = value == 1,
            (Some(Action::Press(command)), 1) => input.commands.push(command),
            (Some(Action::Quit), 1) => input.quit = true,
            _ => {}
        }
    }
}
