//! The wgpu comparison backend against the CPU rasterizer: the same draws on both, compared by
//! PSNR and by the share of pixels off by more than a threshold (coverage rules, sub-pixel
//! precision, mip selection and perspective correction differ slightly by design, so the tests
//! bound the difference instead of asking for equality). A machine without a usable adapter skips
//! every test with a message on stderr.

#[path = "../../../raster/tests/it/scene.rs"]
mod scene;

use std::io::Write;

use glam::{DMat4, DVec3};
use image::RgbaImage;
use stripmask_platform::{GpuTarget, PlatformError};
use stripmask_raster::*;

/// Writes past the test harness's capture, so that CI logs show which adapter ran (or why not).
fn note(message: &str) {
    let _ = writeln!(std::io::stderr(), "{message}");
}

/// A GPU target, or `None` (with a message) on a machine without an adapter.
fn gpu(width: u32, height: u32, color: ColorFormat, depth: DepthFormat) -> Option<GpuTarget> {
    match GpuTarget::new(width, height, color, depth) {
        Ok(target) => {
            note(&format!("gpu_compare: adapter {}", target.adapter_name()));
            Some(target)
        }
        Err(e @ PlatformError::NoGpuAdapter { .. }) => {
            note(&format!("gpu_compare: skipped, {e}"));
            None
        }
        Err(e) => panic!("GPU target: {e}"),
    }
}

/// How far two pictures are apart.
#[derive(Debug)]
struct Difference {
    /// Peak signal-to-noise ratio over RGB, dB.
    psnr: f64,
    /// Share of pixels with a channel off by more than `OFF`.
    off: f64,
}

/// A channel difference above this is a visibly different pixel, not a rounding difference.
const OFF: i32 = 40;

fn compare(a: &RgbaImage, b: &RgbaImage) -> Difference {
    assert_eq!(a.dimensions(), b.dimensions());
    let (mut squared, mut off) = (0.0f64, 0usize);
    for (p, q) in a.pixels().zip(b.pixels()) {
        let d = [0, 1, 2].map(|k| i32::from(p.0[k]) - i32::from(q.0[k]));
        squared += d.iter().map(|&v| f64::from(v * v)).sum::<f64>();
        off += usize::from(d.iter().any(|v| v.abs() > OFF));
    }
    let n = f64::from(a.width() * a.height());
    let mse = squared / (3.0 * n);
    Difference {
        psnr: if mse == 0.0 {
            f64::INFINITY
        } else {
            10.0 * (255.0 * 255.0 / mse).log10()
        },
        off: off as f64 / n,
    }
}

/// Draws `draws` on the CPU and on `gpu` into pictures of the same formats, after clearing both
/// to `sky`, and returns both pictures.
fn render_both(
    gpu: &mut GpuTarget,
    color: ColorFormat,
    depth: DepthFormat,
    sky: [u8; 3],
    draws: &[(Mesh, Transform, RenderState)],
) -> (RgbaImage, RgbaImage) {
    let (w, h) = gpu.size();
    let mut fb = Framebuffer::new(w, h, color, depth).unwrap();
    let mut rasterizer = Rasterizer::new();
    let mut cpu = RasterTarget::new(&mut fb, &mut rasterizer);
    cpu.clear(sky);
    gpu.clear(sky);
    for (mesh, transform, state) in draws {
        let on_cpu = cpu.draw(mesh, transform, state).unwrap();
        let on_gpu = gpu.draw(mesh, transform, state).unwrap();
        assert_eq!(on_gpu.triangles, on_cpu.triangles);
    }
    (fb.to_rgba_image(), gpu.read_image().unwrap())
}

#[test]
fn the_terrain_frame_matches_the_cpu_in_both_target_formats() {
    for (color, depth) in [
        (ColorFormat::Rgb565, DepthFormat::D16),
        (ColorFormat::Rgba8888, DepthFormat::D32),
    ] {
        let Some(mut gpu) = gpu(320, 240, color, depth) else {
            return;
        };
        let s = scene::terrain(72, 320, 240);
        let (cpu, gpu) = render_both(
            &mut gpu,
            color,
            depth,
            [150, 180, 220],
            &[(s.mesh(), s.transform, s.state())],
        );
        let d = compare(&cpu, &gpu);
        note(&format!("gpu_compare: terrain {color:?}/{depth:?}: {d:?}"));
        // Measured on llvmpipe: 38.6 dB and 0.03 % (RGB565), 40.5 dB and 0.03 % (RGBA8888).
        assert!(d.psnr > 34.0 && d.off < 0.003, "{color:?}: {d:?}");
    }
}

/// A unit quad in x/y at depth `z`, as a strip, with a colour per corner and texture
/// coordinates spanning `repeats`.
fn quad(z: i32, colors: [[u8; 3]; 4], repeats: f32) -> Vec<Vertex> {
    let r = repeats;
    vec![
        Vertex::new([-60, -40, z], [0.0, r], colors[0]),
        Vertex::new([60, -40, z], [r, r], colors[1]),
        Vertex::new([-60, 40, z], [0.0, 0.0], colors[2]),
        Vertex::new([60, 40, z], [r, 0.0], colors[3]),
    ]
}

/// A checkerboard of 8x8-texel squares with a colour ramp, in `format`, with mipmaps.
fn checker(format: TextureFormat) -> Texture {
    let side = 64u32;
    let img = RgbaImage::from_fn(side, side, |x, y| {
        let on = ((x / 8) + (y / 8)) % 2 == 0;
        let v = (x * 4) as u8;
        image::Rgba(if on {
            [v, 200, 40, 255]
        } else {
            [30, 60, 255 - v, 255]
        })
    });
    Texture::from_image(&img, format).unwrap().with_mipmaps()
}

/// A tilted view of the quads: perspective, so that texture correction and depth matter.
fn tilted() -> Transform {
    let projection = glam::dcamera::rh::proj::directx::perspective(1.0, 4.0 / 3.0, 10.0, 1000.0);
    let view = glam::dcamera::rh::view::look_at_mat4(
        DVec3::new(0.0, -90.0, 70.0),
        DVec3::new(0.0, 10.0, 0.0),
        DVec3::Z,
    );
    Transform::new(projection * view * DMat4::IDENTITY).unwrap()
}

#[test]
fn every_render_feature_matches_the_cpu() {
    let Some(mut gpu_rgb565) = gpu(160, 120, ColorFormat::Rgb565, DepthFormat::D16) else {
        return;
    };
    let mut gpu_rgba = gpu(160, 120, ColorFormat::Rgba8888, DepthFormat::D32).unwrap();
    let colors = [[255, 40, 40], [40, 255, 40], [40, 40, 255], [250, 250, 250]];
    let vertices = quad(0, colors, 3.0);
    let strip16 = [0u16, 1, 2, 3];
    let strip32 = [0u32, 1, 2, 3];
    let list = [0u32, 1, 2, 2, 1, 3];
    let rgb565 = checker(TextureFormat::Rgb565);
    let rgba = checker(TextureFormat::Rgba8888);
    let transform = tilted();
    fn textured(texture: &Texture, sampler: Sampler) -> RenderState<'_> {
        RenderState {
            shading: Shading::Gouraud,
            texture: Some(TextureBinding::new(texture, sampler)),
            perspective: Perspective::Exact,
            ..RenderState::default()
        }
    }
    let repeat = |filter, mip| Sampler {
        filter,
        mip,
        wrap: Wrap::Repeat,
    };
    // The bound of every case is (PSNR above, share of pixels off below). Measured on llvmpipe:
    // 42-56 dB with no pixel off, except the mipmapped case (31 dB, 1.7 % off: the GPU picks
    // the level per pixel, the CPU per triangle, and this quad has two large triangles).
    let exact = (38.0, 0.001);
    type Case<'a> = (&'a str, Indices<'a>, Topology, RenderState<'a>, (f64, f64));
    let cases: Vec<Case> = vec![
        (
            "flat colour, no depth test",
            Indices::U16(&strip16),
            Topology::TriangleStrip,
            RenderState {
                shading: Shading::Flat([200, 120, 30]),
                depth: DepthMode::NONE,
                ..RenderState::default()
            },
            exact,
        ),
        (
            "Gouraud, u32 strip",
            Indices::U32(&strip32),
            Topology::TriangleStrip,
            RenderState {
                shading: Shading::Gouraud,
                ..RenderState::default()
            },
            exact,
        ),
        (
            "Gouraud, list, back faces culled",
            Indices::U32(&list),
            Topology::TriangleList,
            RenderState {
                shading: Shading::Gouraud,
                cull: CullMode::Back,
                ..RenderState::default()
            },
            exact,
        ),
        (
            "RGB565 texture, nearest, repeat",
            Indices::U16(&strip16),
            Topology::TriangleStrip,
            textured(&rgb565, repeat(Filter::Nearest, MipFilter::None)),
            exact,
        ),
        (
            "RGBA texture, bilinear, repeat, mipmapped",
            Indices::U16(&strip16),
            Topology::TriangleStrip,
            textured(&rgba, repeat(Filter::Bilinear, MipFilter::Nearest)),
            (28.0, 0.03),
        ),
        (
            "RGB565 texture, bilinear, clamp, affine",
            Indices::U16(&strip16),
            Topology::TriangleStrip,
            RenderState {
                perspective: Perspective::Affine,
                ..textured(&rgb565, Sampler::BILINEAR)
            },
            exact,
        ),
        (
            "texture, flat colour and fog",
            Indices::U16(&strip16),
            Topology::TriangleStrip,
            RenderState {
                shading: Shading::Flat([255, 220, 200]),
                fog: Some(Fog {
                    color: [90, 90, 160],
                    start: 80.0,
                    end: 200.0,
                }),
                ..textured(&rgb565, repeat(Filter::Bilinear, MipFilter::None))
            },
            exact,
        ),
    ];
    for (name, indices, topology, state, (psnr, off)) in cases {
        let mesh = Mesh {
            vertices: &vertices,
            indices,
            topology,
        };
        for (gpu, color, depth) in [
            (&mut gpu_rgb565, ColorFormat::Rgb565, DepthFormat::D16),
            (&mut gpu_rgba, ColorFormat::Rgba8888, DepthFormat::D32),
        ] {
            let (cpu, gpu) = render_both(gpu, color, depth, [0, 0, 0], &[(mesh, transform, state)]);
            let d = compare(&cpu, &gpu);
            note(&format!("gpu_compare: {name} ({color:?}): {d:?}"));
            assert!(d.psnr > psnr && d.off < off, "{name} ({color:?}): {d:?}");
        }
    }
}

#[test]
fn culling_winding_and_depth_order_agree_with_the_cpu() {
    let Some(mut gpu) = gpu(96, 64, ColorFormat::Rgba8888, DepthFormat::D16) else {
        return;
    };
    let ortho =
        glam::dcamera::rh::proj::directx::orthographic(-80.0, 80.0, -50.0, 50.0, -100.0, 100.0);
    let transform = Transform::new(ortho).unwrap();
    let near = quad(40, [[255, 0, 0]; 4], 1.0);
    let far = quad(-40, [[0, 0, 255]; 4], 1.0);
    let strip = [0u16, 1, 2, 3];
    let mesh = |v| Mesh {
        vertices: v,
        indices: Indices::U16(&strip),
        topology: Topology::TriangleStrip,
    };
    for (cull, front_face) in [
        (CullMode::Back, FrontFace::Ccw),
        (CullMode::Front, FrontFace::Ccw),
        (CullMode::Back, FrontFace::Cw),
        (CullMode::None, FrontFace::Ccw),
    ] {
        let state = RenderState {
            shading: Shading::Gouraud,
            cull,
            front_face,
            ..RenderState::default()
        };
        // The near quad first, then the far one: only the depth test keeps the near one in front.
        let (cpu, gpu) = render_both(
            &mut gpu,
            ColorFormat::Rgba8888,
            DepthFormat::D16,
            [0, 0, 0],
            &[
                (mesh(&far[..]), transform, state),
                (mesh(&near[..]), transform, state),
            ],
        );
        let d = compare(&cpu, &gpu);
        assert!(d.off < 0.01, "{cull:?} {front_face:?}: {d:?}");
        let centre = |img: &RgbaImage| img.get_pixel(48, 32).0;
        assert_eq!(centre(&cpu), centre(&gpu), "{cull:?} {front_face:?}");
    }
}

#[test]
fn a_clear_alone_gives_the_same_bytes_and_scissors_crop_alike() {
    let Some(mut gpu) = gpu(40, 30, ColorFormat::Rgb565, DepthFormat::D16) else {
        return;
    };
    let mut fb = Framebuffer::new(40, 30, ColorFormat::Rgb565, DepthFormat::D16).unwrap();
    assert_eq!(
        gpu.read_image().unwrap(),
        fb.to_rgba_image(),
        "initial black"
    );
    fb.clear([123, 45, 67]);
    gpu.clear([123, 45, 67]);
    assert_eq!(gpu.read_image().unwrap(), fb.to_rgba_image(), "cleared");

    let ortho = glam::dcamera::rh::proj::directx::orthographic(-60.0, 60.0, -40.0, 40.0, -1.0, 1.0);
    let vertices = quad(0, [[250, 250, 250]; 4], 1.0);
    let scissor = Rect {
        x0: 5,
        y0: 7,
        x1: 21,
        y1: 19,
    };
    let state = RenderState {
        scissor: Some(scissor),
        ..RenderState::default()
    };
    let mesh = Mesh {
        vertices: &vertices,
        indices: Indices::U16(&[0, 1, 2, 3]),
        topology: Topology::TriangleStrip,
    };
    let (cpu, gpu_image) = render_both(
        &mut gpu,
        ColorFormat::Rgb565,
        DepthFormat::D16,
        [0, 0, 0],
        &[(mesh, Transform::new(ortho).unwrap(), state)],
    );
    assert_eq!(gpu_image, cpu, "a full-screen quad cut by the scissor");
}

#[test]
fn bad_input_is_refused_as_the_cpu_refuses_it() {
    let Some(mut gpu) = gpu(16, 16, ColorFormat::Rgb565, DepthFormat::None) else {
        return;
    };
    let vertices = quad(0, [[0; 3]; 4], 1.0);
    let transform = Transform::new(DMat4::IDENTITY).unwrap();
    let mesh = Mesh {
        vertices: &vertices,
        indices: Indices::U32(&[0, 1, 2, 4]),
        topology: Topology::TriangleStrip,
    };
    let mut fb = Framebuffer::new(16, 16, ColorFormat::Rgb565, DepthFormat::None).unwrap();
    let cpu = Rasterizer::new()
        .draw(&mut fb, &mesh, &transform, &RenderState::default())
        .unwrap_err();
    match gpu.draw(&mesh, &transform, &RenderState::default()) {
        Err(PlatformError::Raster(e)) => assert_eq!(e, cpu),
        other => panic!("{other:?}"),
    }
    let state = RenderState {
        scissor: Some(Rect {
            x0: 0,
            y0: 0,
            x1: 17,
            y1: 4,
        }),
        ..RenderState::default()
    };
    assert!(matches!(
        gpu.draw(&mesh, &transform, &state),
        Err(PlatformError::Raster(RasterError::Scissor { .. }))
    ));
    assert!(matches!(
        GpuTarget::new(0, 16, ColorFormat::Rgb565, DepthFormat::D16),
        Err(PlatformError::Raster(RasterError::FramebufferSize { .. }))
    ));
}

#[test]
fn a_redraw_repeats_the_last_frame() {
    let Some(mut gpu) = gpu(320, 240, ColorFormat::Rgba8888, DepthFormat::D32) else {
        return;
    };
    let s = scene::terrain(72, 320, 240);
    let (_, first) = render_both(
        &mut gpu,
        ColorFormat::Rgba8888,
        DepthFormat::D32,
        [150, 180, 220],
        &[(s.mesh(), s.transform, s.state())],
    );
    gpu.redraw().unwrap();
    assert!(gpu.read_image().unwrap() == first, "the same frame again");
    gpu.redraw().unwrap();
    gpu.redraw().unwrap();
    assert!(gpu.read_image().unwrap() == first, "and again");
}
