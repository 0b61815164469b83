//! The evdev keyboard of the framebuffer viewer against a regular file of recorded
//! `struct input_event`s: held keys, one-shot commands, Esc, auto-repeat and other events
//! skipped, records split across reads, and the error for a missing device.

#![cfg(all(feature = "fbdev", target_os = "linux"))]

use std::fs::OpenOptions;
use std::io::Write;

use stripmask_platform::{Command, EvdevInput, Motion, PlatformError};

const EVENT_BYTES: usize = std::mem::size_of::<libc::input_event>();

/// One record: a zero timestamp, then type, code and value in native byte order.
fn event(kind: u16, code: u16, value: i32) -> Vec<u8> {
    let mut r = vec![0u8; EVENT_BYTES - 8];
    r.extend_from_slice(&kind.to_ne_bytes());
    r.extend_from_slice(&code.to_ne_bytes());
    r.extend_from_slice(&value.to_ne_bytes());
    r
}

fn key(code: u16, value: i32) -> Vec<u8> {
    event(1, code, value)
}

const SYN: (u16, u16, i32) = (0, 0, 0);
const KEY_W: u16 = 17;
const KEY_D: u16 = 32;
const KEY_K: u16 = 37;
const KEY_L: u16 = 38;
const KEY_Q: u16 = 16;
const KEY_ESC: u16 = 1;

#[test]
fn recorded_key_events_become_motion_and_commands() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("event0");
    let mut file = std::fs::File::create(&path).unwrap();
    let mut input = EvdevInput::open(&path).unwrap();
    assert_eq!(input.poll().unwrap(), Default::default(), "nothing yet");

    let recorded: Vec<u8> = [
        key(KEY_W, 1),
        event(SYN.0, SYN.1, SYN.2),
        key(KEY_K, 1),
        key(KEY_K, 0),
        key(KEY_L, 1),
        key(KEY_L, 2),  // auto-repeat: not a second press
        key(KEY_Q, 1),  // not in the table
        event(2, 0, 5), // EV_REL: skipped
        key(KEY_D, 1),
    ]
    .concat();
    file.write_all(&recorded).unwrap();
    let got = input.poll().unwrap();
    assert_eq!(got.commands, [Command::CrackMode, Command::Wireframe]);
    assert_eq!(
        got.motion,
        Motion {
            forward: true,
            right: true,
            ..Motion::default()
        }
    );
    assert!(!got.quit);
    let right = Motion {
        right: true,
        ..Motion::default()
    };

    // Held keys stay held across polls; a record split across writes is read once whole.
    let release = [key(KEY_W, 0), key(KEY_ESC, 1)].concat();
    file.write_all(&release[..EVENT_BYTES + 5]).unwrap();
    let got = input.poll().unwrap();
    assert_eq!(got.motion, right, "W released, D still held");
    assert!(got.commands.is_empty() && !got.quit);
    let mut tail = OpenOptions::new().append(true).open(&path).unwrap();
    tail.write_all(&release[EVENT_BYTES + 5..]).unwrap();
    let got = input.poll().unwrap();
    assert!(got.quit, "Esc");
    assert_eq!(got.motion, right);
}

#[test]
fn a_missing_input_device_is_a_clear_error() {
    let err = EvdevInput::open(std::path::Path::new("/nonexistent/event9")).unwrap_err();
    assert!(matches!(err, PlatformError::InputOpen { .. }));
    let message = err.to_string();
    assert!(
        message.contains("/nonexistent/event9") && message.contains("input device"),
        "{message}"
    );
}
