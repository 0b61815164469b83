//! The window presenter on a real X server (Xvfb in CI: `.ci/run` runs the suite under
//! `xvfb-run`). A frame is presented and read back with XGetImage through the same run-time
//! loaded Xlib that minifb uses; keys, resizing and closing are sent as X events. Without a
//! display the test checks that opening fails with the no-display error, and says it skipped.
#![cfg(all(feature = "window", target_os = "linux"))]

use crate::common;

use std::ffi::{CStr, c_char, c_int, c_uint};
use std::ptr;
use std::time::{Duration, Instant};

use image::RgbaImage;
use stripmask_platform::{
    Command, Hud, HudInfo, Input, Minimap, MinimapCell, PlatformError, Presenter, WindowPresenter,
    compose_rgba,
};
use stripmask_raster::ColorFormat;
use x11_dl::keysym::{XK_Escape, XK_h, XK_w};
use x11_dl::xlib::{self, Xlib};

/// The test's own connection to the X server.
struct X {
    lib: Xlib,
    display: *mut xlib::Display,
}

unsafe extern "C" fn ignore_x_errors(_: *mut xlib::Display, _: *mut xlib::XErrorEvent) -> c_int {
    0
}

impl X {
    fn open() -> Self {
        let lib = Xlib::open().expect("libX11 loads (minifb just loaded it)");
        // SAFETY: a null name opens $DISPLAY; the result is checked below.
        let display = unsafe { (lib.XOpenDisplay)(ptr::null()) };
        assert!(
            !display.is_null(),
            "XOpenDisplay failed although a window opened"
        );
        // SAFETY: the handler ignores errors (a window read while it is still being mapped),
        // instead of Xlib's default of exiting the process; it touches nothing.
        unsafe { (lib.XSetErrorHandler)(Some(ignore_x_errors)) };
        Self { lib, display }
    }

    /// The window named `title`, searched through the whole tree.
    fn find(&self, title: &str) -> Option<xlib::Window> {
        // SAFETY: the display is open; the root window always exists.
        let root = unsafe { (self.lib.XDefaultRootWindow)(self.display) };
        let mut stack = vec![root];
        while let Some(w) = stack.pop() {
            let mut name: *mut c_char = ptr::null_mut();
            // SAFETY: `w` came from XQueryTree on this display; `name` receives a string that
            // Xlib allocates (or null), read and freed right here.
            unsafe {
                if (self.lib.XFetchName)(self.display, w, &mut name) != 0 && !name.is_null() {
                    let found = CStr::from_ptr(name).to_bytes() == title.as_bytes();
                    (self.lib.XFree)(name.cast());
                    if found {
                        return Some(w);
                    }
                }
            }
            let (mut root_ret, mut parent) = (0, 0);
            let mut children: *mut xlib::Window = ptr::null_mut();
            let mut count: c_uint = 0;
            // SAFETY: out-pointers to live locals; the children array Xlib allocates is copied
            // and freed here.
            unsafe {
                if (self.lib.XQueryTree)(
                    self.display,
                    w,
                    &mut root_ret,
                    &mut parent,
                    &mut children,
                    &mut count,
                ) != 0
                    && !children.is_null()
                {
                    stack.extend_from_slice(std::slice::from_raw_parts(children, count as usize));
                    (self.lib.XFree)(children.cast());
                }
            }
        }
        None
    }

    /// What the server shows in the window's top-left `width` x `height` pixels, if it is
    /// mapped.
    fn screenshot(&self, window: xlib::Window, width: u32, height: u32) -> Option<RgbaImage> {
        // SAFETY: flushes this connection and waits for the server; no memory is passed.
        unsafe { (self.lib.XSync)(self.display, xlib::False) };
        // SAFETY: reads the window's pixels into an image Xlib allocates; null on failure.
        let image = unsafe {
            (self.lib.XGetImage)(self.display, window, 0, 0, width, height, !0, xlib::ZPixmap)
        };
        if image.is_null() {
            return None;
        }
        let mut out = RgbaImage::new(width, height);
        // SAFETY: `image` is a live XImage of `width` x `height` pixels until XDestroyImage.
        unsafe {
            let masks = [(*image).red_mask, (*image).green_mask, (*image).blue_mask];
            for (x, y, px) in out.enumerate_pixels_mut() {
                let v = (self.lib.XGetPixel)(image, x as c_int, y as c_int);
                let channel = |m: std::ffi::c_ulong| ((v & m) >> m.trailing_zeros()) as u8;
                px.0 = [channel(masks[0]), channel(masks[1]), channel(masks[2]), 255];
            }
            (self.lib.XDestroyImage)(image);
        }
        Some(out)
    }

    /// Sends a key press or release of `keysym` to `window`.
    fn key(&self, window: xlib::Window, keysym: c_uint, press: bool) {
        // SAFETY: XEvent is a C union of plain structs; all-zero is valid and the key member
        // is filled in completely before it is sent.
        unsafe {
            let mut ev: xlib::XEvent = std::mem::zeroed();
            ev.key = xlib::XKeyEvent {
                type_: if press {
                    xlib::KeyPress
                } else {
                    xlib::KeyRelease
                },
                serial: 0,
                send_event: xlib::True,
                display: self.display,
                window,
                root: (self.lib.XDefaultRootWindow)(self.display),
                subwindow: 0,
                time: xlib::CurrentTime,
                x: 1,
                y: 1,
                x_root: 1,
                y_root: 1,
                state: 0,
                keycode: c_uint::from((self.lib.XKeysymToKeycode)(self.display, keysym.into())),
                same_screen: xlib::True,
            };
            let mask = if press {
                xlib::KeyPressMask
            } else {
                xlib::KeyReleaseMask
            };
            (self.lib.XSendEvent)(self.display, window, xlib::False, mask, &mut ev);
            (self.lib.XSync)(self.display, xlib::False);
        }
    }

    /// Asks the window to close, as a window manager's close button does.
    fn close(&self, window: xlib::Window) {
        // SAFETY: as in `key`; the client-message member is filled in before sending.
        unsafe {
            let protocols = (self.lib.XInternAtom)(self.display, c"WM_PROTOCOLS".as_ptr(), 0);
            let delete = (self.lib.XInternAtom)(self.display, c"WM_DELETE_WINDOW".as_ptr(), 0);
            let mut ev: xlib::XEvent = std::mem::zeroed();
            ev.client_message.type_ = xlib::ClientMessage;
            ev.client_message.window = window;
            ev.client_message.message_type = protocols;
            ev.client_message.format = 32;
            ev.client_message
                .data
                .set_long(0, delete as std::ffi::c_long);
            (self.lib.XSendEvent)(self.display, window, xlib::False, 0, &mut ev);
            (self.lib.XSync)(self.display, xlib::False);
        }
    }

    fn resize(&self, window: xlib::Window, width: u32, height: u32) {
        // SAFETY: the window exists on this display; no memory is passed.
        unsafe {
            (self.lib.XResizeWindow)(self.display, window, width, height);
            (self.lib.XSync)(self.display, xlib::False);
        }
    }
}

impl Drop for X {
    fn drop(&mut self) {
        // SAFETY: the display was opened in `X::open` and is closed once.
        unsafe { (self.lib.XCloseDisplay)(self.display) };
    }
}

/// Polls until `done` holds for the input gathered so far, for at most five seconds.
fn poll_until(p: &mut WindowPresenter, what: &str, done: impl Fn(&Input) -> bool) -> Input {
    let start = Instant::now();
    let mut all = Input::default();
    loop {
        let input = p.poll_input();
        all.commands.extend(input.commands);
        all.motion = input.motion;
        all.resized = input.resized.or(all.resized);
        all.quit |= input.quit;
        if done(&all) {
            return all;
        }
        assert!(
            start.elapsed() < Duration::from_secs(5),
            "no {what} within 5 s: {all:?}"
        );
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Presents until the server shows `expected`, for at most five seconds.
fn present_until_shown(
    p: &mut WindowPresenter,
    x: &X,
    window: xlib::Window,
    frame: &stripmask_raster::Framebuffer,
    overlay: Option<&stripmask_platform::Overlay>,
) {
    let expected = compose_rgba(frame, overlay);
    let start = Instant::now();
    loop {
        p.present(frame, overlay).unwrap();
        let shot = x.screenshot(window, frame.width(), frame.height());
        if shot.as_ref() == Some(&expected) {
            return;
        }
        if start.elapsed() > Duration::from_secs(5) {
            let wrong = shot.map_or(usize::MAX, |s| {
                s.pixels()
                    .zip(expected.pixels())
                    .filter(|(a, b)| a != b)
                    .count()
            });
            panic!("the screen never showed the frame: {wrong} pixels differ");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

#[test]
fn the_window_shows_the_frame_reports_keys_and_resizes_and_closes() {
    let title = format!("stripmask-window-test-{}", std::process::id());
    let display = std::env::var("DISPLAY").unwrap_or_default();
    let mut p = match WindowPresenter::open(&title, 160, 120) {
        Err(PlatformError::NoDisplay) if display.is_empty() => {
            eprintln!(
                "SKIPPED: no DISPLAY; run under xvfb-run (as .ci/run does) to test the window"
            );
            return;
        }
        Err(e) => panic!("DISPLAY={display:?}: {e}"),
        Ok(p) => p,
    };
    assert_eq!(p.size(), (160, 120));
    let x = X::open();
    let window = x.find(&title).expect("the window is on the server");

    // A frame with a different colour in every pixel, in both formats, with and without the
    // HUD (which is composited at 8-bit precision over the RGB565 frame).
    let mut hud = Hud::new(true);
    let info = HudInfo {
        fps: 29.5,
        target_fps: 30.0,
        minimap: Some(Minimap {
            width: 3,
            height: 3,
            cells: vec![MinimapCell::Rendered; 9],
            viewer: (1.5, 1.5),
            ..Minimap::default()
        }),
        ..HudInfo::default()
    };
    for format in [ColorFormat::Rgb565, ColorFormat::Rgba8888] {
        let frame = common::painted(160, 120, format, common::pattern);
        present_until_shown(&mut p, &x, window, &frame, None);
        let overlay = hud.render(&info, 160, 120);
        present_until_shown(&mut p, &x, window, &frame, overlay);
    }

    x.key(window, XK_h, true);
    poll_until(&mut p, "H command", |i| i.commands == [Command::Hud]);
    x.key(window, XK_h, false);
    x.key(window, XK_w, true);
    poll_until(&mut p, "held W", |i| i.motion.forward && !i.motion.back);
    x.key(window, XK_w, false);
    poll_until(&mut p, "released W", |i| !i.motion.forward);

    x.resize(window, 100, 80);
    poll_until(&mut p, "resize", |i| i.resized == Some((100, 80)));
    let small = common::painted(100, 80, ColorFormat::Rgba8888, common::pattern);
    present_until_shown(&mut p, &x, window, &small, None);

    x.key(window, XK_Escape, true);
    poll_until(&mut p, "quit on Esc", |i| i.quit);
    x.key(window, XK_Escape, false);
    x.close(window);
    poll_until(&mut p, "quit on close", |i| i.quit);
}
