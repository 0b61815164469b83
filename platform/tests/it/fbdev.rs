//! The framebuffer presenter against regular files standing in for devices: bytes written for
//! each pixel format, stride and screen size, compared with bytes computed here from the
//! format's definition; and the errors for devices that are missing or are not framebuffers.
#![cfg(all(feature = "fbdev", target_os = "linux"))]

use crate::common;

use std::io::Write;

use stripmask_platform::{
    Bitfield, FbPresenter, Fit, Hud, HudInfo, PlatformError, Presenter, ScreenInfo, compose_rgba,
};
use stripmask_raster::{
    ColorFormat, DepthBuffer, DepthFormat, Framebuffer, Indices, Mesh, Rasterizer, RenderState,
    Shading, Topology, Transform, Vertex,
};

/// What the file holds before the presenter writes: bytes outside the visible area keep it.
const UNTOUCHED: u8 = 0xA5;

/// A pixel format: bits per pixel and (offset, length) of red, green, blue and alpha.
struct Format {
    name: &'static str,
    bpp: u32,
    channels: [(u32, u32); 4],
}

const FORMATS: &[Format] = &[
    Format {
        name: "RGB565",
        bpp: 16,
        channels: [(11, 5), (5, 6), (0, 5), (0, 0)],
    },
    Format {
        name: "BGR565",
        bpp: 16,
        channels: [(0, 5), (5, 6), (11, 5), (0, 0)],
    },
    Format {
        name: "XRGB8888",
        bpp: 32,
        channels: [(16, 8), (8, 8), (0, 8), (0, 0)],
    },
    Format {
        name: "ARGB8888",
        bpp: 32,
        channels: [(16, 8), (8, 8), (0, 8), (24, 8)],
    },
    Format {
        name: "XBGR8888",
        bpp: 32,
        channels: [(0, 8), (8, 8), (16, 8), (0, 0)],
    },
    Format {
        name: "RGB888",
        bpp: 24,
        channels: [(16, 8), (8, 8), (0, 8), (0, 0)],
    },
    Format {
        name: "BGR888",
        bpp: 24,
        channels: [(0, 8), (8, 8), (16, 8), (0, 0)],
    },
];

/// A screen: visible size, panning offsets and row padding in bytes.
struct Screen {
    width: u32,
    height: u32,
    xoffset: u32,
    yoffset: u32,
    padding: u32,
}

impl Screen {
    fn info(&self, f: &Format) -> ScreenInfo {
        let field = |(offset, length)| Bitfield::new(offset, length);
        ScreenInfo {
            width: self.width,
            height: self.height,
            xoffset: self.xoffset,
            yoffset: self.yoffset,
            bits_per_pixel: f.bpp,
            line_length: (self.xoffset + self.width) * f.bpp / 8 + self.padding,
            red: field(f.channels[0]),
            green: field(f.channels[1]),
            blue: field(f.channels[2]),
            transp: field(f.channels[3]),
        }
    }
}

/// The pixel value of `c` in format `f`, as `bpp / 8` bytes in the machine's order.
fn pixel_bytes(f: &Format, c: [u8; 3]) -> Vec<u8> {
    let mut v: u32 = 0;
    for (k, &(offset, length)) in f.channels[..3].iter().enumerate() {
        v |= (u32::from(c[k]) >> (8 - length)) << offset;
    }
    let (offset, length) = f.channels[3];
    if length > 0 {
        v |= ((1 << length) - 1) << offset;
    }
    match f.bpp {
        16 => (v as u16).to_ne_bytes().to_vec(),
        24 if cfg!(target_endian = "little") => v.to_le_bytes()[..3].to_vec(),
        24 => v.to_be_bytes()[1..].to_vec(),
        _ => v.to_ne_bytes().to_vec(),
    }
}

/// The frame pixel shown at visible screen pixel (`sx`, `sy`), worked out from the definition
/// of each fit rather than from the crate's placement code.
fn source(fit: Fit, frame: (u32, u32), screen: (u32, u32), sx: u32, sy: u32) -> Option<(u32, u32)> {
    let (fw, fh) = (f64::from(frame.0), f64::from(frame.1));
    let (sw, sh) = (f64::from(screen.0), f64::from(screen.1));
    let (x, y) = (f64::from(sx), f64::from(sy));
    let (fx, fy) = match fit {
        Fit::Center => (x - ((sw - fw) / 2.0).trunc(), y - ((sh - fh) / 2.0).trunc()),
        Fit::Scale => {
            // The largest size with the frame's aspect ratio that fits, in whole pixels.
            let (dw, dh) = if sw * fh <= sh * fw {
                (sw, (fh * sw / fw).floor().max(1.0))
            } else {
                ((fw * sh / fh).floor().max(1.0), sh)
            };
            let (x0, y0) = (((sw - dw) / 2.0).floor(), ((sh - dh) / 2.0).floor());
            if x < x0 || y < y0 || x >= x0 + dw || y >= y0 + dh {
                return None;
            }
            (
                ((x - x0 + 0.5) * fw / dw).floor(),
                ((y - y0 + 0.5) * fh / dh).floor(),
            )
        }
    };
    (fx >= 0.0 && fy >= 0.0 && fx < fw && fy < fh).then_some((fx as u32, fy as u32))
}

/// Presents `frame` on a stand-in file for `screen` in format `f` and checks every byte.
fn check(f: &Format, screen: &Screen, fit: Fit, frame: &Framebuffer) {
    let info = screen.info(f);
    let len = (info.line_length * (screen.yoffset + screen.height)) as usize;
    let mut file = tempfile::NamedTempFile::new().unwrap();
    file.write_all(&vec![UNTOUCHED; len]).unwrap();
    let mut p = FbPresenter::with_screen_info(file.path(), info, fit).unwrap();
    assert_eq!(p.size(), (screen.width, screen.height));
    p.present(frame, None).unwrap();
    drop(p);

    let bytes = std::fs::read(file.path()).unwrap();
    let bpp = (f.bpp / 8) as usize;
    let mut expected = vec![UNTOUCHED; len];
    for sy in 0..screen.height {
        for sx in 0..screen.width {
            let c = source(
                fit,
                (frame.width(), frame.height()),
                (screen.width, screen.height),
                sx,
                sy,
            )
            .map_or([0, 0, 0], |(fx, fy)| frame.pixel(fx, fy));
            let at = ((screen.yoffset + sy) * info.line_length) as usize
                + (screen.xoffset + sx) as usize * bpp;
            expected[at..at + bpp].copy_from_slice(&pixel_bytes(f, c));
        }
    }
    if bytes != expected {
        let first = bytes
            .iter()
            .zip(&expected)
            .position(|(a, b)| a != b)
            .unwrap();
        panic!(
            "{} on {}x{}+{}+{} (+{} bytes per row), {fit:?}, {:?} {}x{} frame: first difference at byte {first} (row {}, byte {} of the row)",
            f.name,
            screen.width,
            screen.height,
            screen.xoffset,
            screen.yoffset,
            screen.padding,
            frame.color_format(),
            frame.width(),
            frame.height(),
            first / info.line_length as usize,
            first % info.line_length as usize,
        );
    }
}

/// A quad of four colours drawn over a clear, into `target`.
fn draw_quad(target: &mut impl stripmask_raster::AsSurface) {
    let v = [
        Vertex::new([-1, -1, 0], [0.0, 0.0], [255, 0, 0]),
        Vertex::new([1, -1, 0], [1.0, 0.0], [0, 255, 0]),
        Vertex::new([-1, 1, 0], [0.0, 1.0], [0, 0, 255]),
        Vertex::new([1, 1, 0], [1.0, 1.0], [255, 255, 255]),
    ];
    let mesh = Mesh {
        vertices: &v,
        indices: Indices::U16(&[0, 1, 2, 3]),
        topology: Topology::TriangleStrip,
    };
    let m = glam::dcamera::rh::proj::directx::orthographic(-1.2, 0.9, -1.1, 1.3, -1.0, 1.0);
    let state = RenderState {
        shading: Shading::Gouraud,
        ..RenderState::default()
    };
    Rasterizer::with_threads(1)
        .draw(target, &mesh, &Transform::new(m).unwrap(), &state)
        .unwrap();
}

/// Screens whose format the rasterizer draws lend their memory: a frame drawn into it gets
/// the bytes the format's definition gives the same frame drawn into our buffer (an X or alpha
/// byte 0xFF), and nothing outside the visible area is written. Other formats lend nothing.
#[test]
fn drawable_formats_are_drawn_straight_into_screen_memory() {
    let screen = Screen {
        width: 23,
        height: 17,
        xoffset: 3,
        yoffset: 2,
        padding: 8,
    };
    for f in FORMATS {
        let info = screen.info(f);
        let len = (info.line_length * (screen.yoffset + screen.height)) as usize;
        let mut file = tempfile::NamedTempFile::new().unwrap();
        file.write_all(&vec![UNTOUCHED; len]).unwrap();
        let mut p = FbPresenter::with_screen_info(file.path(), info, Fit::Center).unwrap();
        let mut depth = DepthBuffer::new(screen.width, screen.height, DepthFormat::D16);
        assert!(
            p.surface(&mut depth).unwrap().is_none(),
            "lent only when asked"
        );
        let mut p = p.with_in_place(true);
        let Some(mut surface) = p.surface(&mut depth).unwrap() else {
            assert_eq!(f.bpp, 24, "{} is drawn through a copy", f.name);
            continue;
        };
        surface.clear([9, 99, 199]);
        draw_quad(&mut surface);
        drop(p);

        let format = if f.bpp == 16 {
            ColorFormat::Rgb565
        } else {
            ColorFormat::Rgba8888
        };
        let mut ours =
            Framebuffer::new(screen.width, screen.height, format, DepthFormat::D16).unwrap();
        ours.clear([9, 99, 199]);
        draw_quad(&mut ours);
        let bytes = std::fs::read(file.path()).unwrap();
        let bpp = (f.bpp / 8) as usize;
        let mut expected = vec![UNTOUCHED; len];
        for sy in 0..screen.height {
            for sx in 0..screen.width {
                let mut px = pixel_bytes(f, ours.pixel(sx, sy));
                if bpp == 4 {
                    px = (u32::from_ne_bytes(px.try_into().unwrap()) | 0xFF00_0000)
                        .to_ne_bytes()
                        .to_vec();
                }
                let at = ((screen.yoffset + sy) * info.line_length) as usize
                    + (screen.xoffset + sx) as usize * bpp;
                expected[at..at + bpp].copy_from_slice(&px);
            }
        }
        assert!(bytes == expected, "{}", f.name);
    }
}

#[test]
fn every_format_with_padded_rows_at_the_frame_size() {
    for frame_format in [ColorFormat::Rgb565, ColorFormat::Rgba8888] {
        let frame = common::painted(7, 5, frame_format, common::pattern);
        let screen = Screen {
            width: 7,
            height: 5,
            xoffset: 0,
            yoffset: 0,
            padding: 12,
        };
        for f in FORMATS {
            for fit in [Fit::Center, Fit::Scale] {
                check(f, &screen, fit, &frame);
            }
        }
    }
}

#[test]
fn a_larger_panned_screen_centres_or_scales_the_frame() {
    let frame = common::painted(6, 4, ColorFormat::Rgba8888, common::pattern);
    let screen = Screen {
        width: 20,
        height: 10,
        xoffset: 3,
        yoffset: 2,
        padding: 4,
    };
    for f in FORMATS {
        for fit in [Fit::Center, Fit::Scale] {
            check(f, &screen, fit, &frame);
        }
    }
}

#[test]
fn a_smaller_screen_crops_or_scales_the_frame_down() {
    let frame = common::painted(16, 12, ColorFormat::Rgb565, common::pattern);
    for (w, h) in [(8, 6), (5, 7), (3, 3)] {
        let screen = Screen {
            width: w,
            height: h,
            xoffset: 0,
            yoffset: 0,
            padding: 2,
        };
        for f in FORMATS {
            for fit in [Fit::Center, Fit::Scale] {
                check(f, &screen, fit, &frame);
            }
        }
    }
}

#[test]
fn a_new_frame_size_clears_what_the_old_frame_left() {
    let f = &FORMATS[2];
    let screen = Screen {
        width: 10,
        height: 8,
        xoffset: 0,
        yoffset: 0,
        padding: 0,
    };
    let info = screen.info(f);
    let mut file = tempfile::NamedTempFile::new().unwrap();
    file.write_all(&vec![0; (info.line_length * 8) as usize])
        .unwrap();
    let mut p = FbPresenter::with_screen_info(file.path(), info, Fit::Center).unwrap();
    let big = common::painted(10, 8, ColorFormat::Rgba8888, |_, _| [255, 255, 255]);
    let small = common::painted(2, 2, ColorFormat::Rgba8888, |_, _| [255, 0, 0]);
    p.present(&big, None).unwrap();
    p.present(&small, None).unwrap();
    drop(p);
    let bytes = std::fs::read(file.path()).unwrap();
    let lit: Vec<usize> = bytes
        .chunks_exact(4)
        .enumerate()
        .filter(|(_, px)| px.iter().any(|&b| b != 0))
        .map(|(i, _)| i)
        .collect();
    // Only the 2x2 red frame in the middle (columns 4-5, rows 3-4) is left.
    assert_eq!(lit, [34, 35, 44, 45]);
}

#[test]
fn the_hud_is_composited_on_the_screen() {
    let frame = common::painted(64, 48, ColorFormat::Rgb565, common::pattern);
    let mut hud = Hud::new(true);
    let overlay = hud.render(&HudInfo::default(), 64, 48).unwrap();
    let f = &FORMATS[3];
    let screen = Screen {
        width: 64,
        height: 48,
        xoffset: 0,
        yoffset: 0,
        padding: 0,
    };
    let info = screen.info(f);
    let mut file = tempfile::NamedTempFile::new().unwrap();
    file.write_all(&vec![0; (info.line_length * 48) as usize])
        .unwrap();
    let mut p = FbPresenter::with_screen_info(file.path(), info, Fit::Center).unwrap();
    p.present(&frame, Some(overlay)).unwrap();
    drop(p);
    let expected: Vec<u8> = compose_rgba(&frame, Some(overlay))
        .pixels()
        .flat_map(|px| pixel_bytes(f, [px[0], px[1], px[2]]))
        .collect();
    assert_eq!(std::fs::read(file.path()).unwrap(), expected);
    assert_ne!(
        compose_rgba(&frame, Some(overlay)),
        compose_rgba(&frame, None)
    );
}

#[test]
fn a_missing_device_is_named_in_the_error() {
    let err = FbPresenter::open("/dev/stripmask-no-such-fb", Fit::Center).unwrap_err();
    assert!(matches!(err, PlatformError::DeviceOpen { .. }), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("/dev/stripmask-no-such-fb"), "{msg}");
    assert!(msg.contains("No such file"), "{msg}");
}

#[test]
fn a_regular_file_refuses_the_screen_info_ioctl_with_enotty() {
    let file = tempfile::NamedTempFile::new().unwrap();
    let err = FbPresenter::open(file.path(), Fit::Center).unwrap_err();
    let msg = err.to_string();
    match err {
        PlatformError::Ioctl {
            device,
            request,
            source,
        } => {
            assert_eq!(device, file.path());
            assert_eq!(request, "FBIOGET_VSCREENINFO");
            assert_eq!(source.raw_os_error(), Some(libc::ENOTTY));
        }
        other => panic!("expected an ioctl error, got {other:?}"),
    }
    assert!(msg.contains(&file.path().display().to_string()), "{msg}");
    assert!(msg.contains("FBIOGET_VSCREENINFO"), "{msg}");
}

#[test]
fn unsupported_formats_and_short_files_are_refused_with_the_reason() {
    let mut file = tempfile::NamedTempFile::new().unwrap();
    file.write_all(&[0; 64]).unwrap();
    let screen = Screen {
        width: 4,
        height: 4,
        xoffset: 0,
        yoffset: 0,
        padding: 0,
    };
    let mut palette = screen.info(&FORMATS[0]);
    palette.bits_per_pixel = 8;
    let err = FbPresenter::with_screen_info(file.path(), palette, Fit::Center).unwrap_err();
    let msg = err.to_string();
    assert!(msg.contains(&file.path().display().to_string()), "{msg}");
    assert!(msg.contains("8 bits per pixel"), "{msg}");

    let too_big = Screen {
        height: 5,
        ..screen
    }
    .info(&FORMATS[2]);
    let err = FbPresenter::with_screen_info(file.path(), too_big, Fit::Center).unwrap_err();
    assert!(
        err.to_string().contains("64 bytes are fewer than the 80"),
        "{err}"
    );
}
