//! Drawing into borrowed memory (`Surface`): every layout, with padded rows, gets exactly the
//! pixels of the owned framebuffer of its kind (RGBA8888 for the 32-bit layouts, RGB565 for the
//! 16-bit ones, channels where the DRM fourcc puts them), on one thread or two, through
//! `Rasterizer::draw`, `draw_edges` and a `RasterTarget` batch; the bytes between rows are
//! never touched.

use crate::common::cases;
use crate::scene::{Scene, terrain};

use proptest::prelude::*;
use stripmask_raster::*;

/// What the bytes between rows and around the surface hold before drawing.
const CANARY: u8 = 0xA5;
const CLEAR: [u8; 3] = [30, 60, 90];

/// The scene's triangles and their wireframe drawn into `fb` by `r`.
fn draw(r: &mut Rasterizer, fb: &mut impl AsSurface, scene: &Scene) {
    let lines = LineState {
        color: [250, 20, 140],
        depth: LineDepth::ON_SURFACE,
        scissor: None,
    };
    r.draw(fb, &scene.mesh(), &scene.transform, &scene.state())
        .unwrap();
    r.draw_edges(fb, &scene.mesh(), &scene.transform, &lines)
        .unwrap();
}

/// A rasterizer on `threads` threads that splits even a small scene between them.
fn rasterizer(threads: usize) -> Rasterizer {
    Rasterizer::with_threads(threads)
        .with_split_from(0)
        .with_tile_size(16)
}

/// The owned framebuffer a layout is compared with: RGB565 for the 16-bit layouts, RGBA8888
/// for the others.
fn owned_format(layout: PixelLayout) -> ColorFormat {
    match layout {
        PixelLayout::Rgb565 | PixelLayout::Bgr565 => ColorFormat::Rgb565,
        _ => ColorFormat::Rgba8888,
    }
}

/// Pixel `i` of `fb` as `layout` stores it, by the DRM fourcc's definition (words in the
/// machine's byte order).
fn expected_bytes(fb: &Framebuffer, i: usize, layout: PixelLayout) -> Vec<u8> {
    match (fb.color(), layout) {
        (ColorBuffer::Rgb565(p), PixelLayout::Rgb565) => p[i].to_ne_bytes().to_vec(),
        (ColorBuffer::Rgb565(p), PixelLayout::Bgr565) => {
            let (r, g, b) = (p[i] >> 11, (p[i] >> 5) & 63, p[i] & 31);
            ((b << 11) | (g << 5) | r).to_ne_bytes().to_vec()
        }
        (ColorBuffer::Rgba8888(p), PixelLayout::Xrgb8888) => {
            let [r, g, b, _] = p[i].map(u32::from);
            (0xFF00_0000 | r << 16 | g << 8 | b).to_ne_bytes().to_vec()
        }
        (ColorBuffer::Rgba8888(p), PixelLayout::Xbgr8888) => {
            let [r, g, b, _] = p[i].map(u32::from);
            (0xFF00_0000 | b << 16 | g << 8 | r).to_ne_bytes().to_vec()
        }
        (ColorBuffer::Rgba8888(p), PixelLayout::Rgba8888) => p[i].to_vec(),
        (c, l) => unreachable!("{l:?} is not compared with {c:?}"),
    }
}

/// Draws `scene` into a `width x height` surface of `layout` whose rows are `pad` bytes longer
/// than the pixels, in memory with a canary byte before it, and checks every byte against the
/// owned framebuffer drawn on one thread: drawn directly on `threads` threads, and through a
/// `RasterTarget` batch.
fn check(
    scene: &Scene,
    (width, height): (u32, u32),
    layout: PixelLayout,
    pad: usize,
    threads: usize,
) {
    let depth = DepthFormat::D16;
    let mut owned = Framebuffer::new(width, height, owned_format(layout), depth).unwrap();
    owned.clear(CLEAR);
    draw(&mut rasterizer(1), &mut owned, scene);

    let bpp = layout.bytes_per_pixel();
    let stride = width as usize * bpp + pad;
    let len = stride * height as usize;
    // Words, for the alignment; the surface starts one word in, after a canary word.
    let mut words = vec![u32::from_ne_bytes([CANARY; 4]); len.div_ceil(4) + 2];
    let mut expected: Vec<u8> = bytemuck::cast_slice(&words).to_vec();
    for y in 0..height as usize {
        for x in 0..width as usize {
            let at = 4 + y * stride + x * bpp;
            let i = y * width as usize + x;
            expected[at..at + bpp].copy_from_slice(&expected_bytes(&owned, i, layout));
        }
    }
    let mut z = DepthBuffer::new(width, height, depth);
    for through_target in [false, true] {
        let memory: &mut [u8] = bytemuck::cast_slice_mut(&mut words);
        memory.fill(CANARY);
        let mut surface = Surface::new(&mut memory[4..4 + len], width, height, stride, layout)
            .unwrap()
            .with_depth(&mut z)
            .unwrap();
        surface.clear(CLEAR);
        let mut r = rasterizer(threads);
        if through_target {
            let mut target = RasterTarget::new(surface, &mut r);
            let lines = LineState {
                color: [250, 20, 140],
                depth: LineDepth::ON_SURFACE,
                scissor: None,
            };
            target
                .batch(|b| {
                    b.draw(&scene.mesh(), &scene.transform, &scene.state())?;
                    b.draw_edges(&scene.mesh(), &scene.transform, &lines)
                })
                .unwrap();
        } else {
            draw(&mut r, &mut surface, scene);
        }
        let memory: &[u8] = bytemuck::cast_slice(&words);
        assert!(
            memory == expected.as_slice(),
            "{layout:?} {width}x{height}, {pad} bytes of padding, {threads} threads, \
             through a target: {through_target}"
        );
    }
}

/// On a pool of `threads` threads.
fn on_pool(threads: usize, f: impl FnOnce() + Send) {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f);
}

#[test]
fn every_layout_with_padded_rows_gets_the_owned_framebuffers_pixels_on_one_or_two_threads() {
    let (width, height) = (97, 61);
    let scene = terrain(40, width, height);
    for threads in [1, 2] {
        on_pool(threads, || {
            for layout in PixelLayout::ALL {
                check(&scene, (width, height), layout, 12, threads);
            }
        });
    }
}

#[test]
fn a_drawn_pixel_reads_back_as_the_owned_framebuffers() {
    let scene = terrain(12, 20, 10);
    let mut owned = Framebuffer::new(20, 10, ColorFormat::Rgba8888, DepthFormat::D32).unwrap();
    owned.clear(CLEAR);
    draw(&mut rasterizer(1), &mut owned, &scene);
    let mut words = vec![0u32; 24 * 10];
    let mut z = DepthBuffer::new(20, 10, DepthFormat::D32);
    let mut surface = Surface::new(
        bytemuck::cast_slice_mut(&mut words),
        20,
        10,
        24 * 4,
        PixelLayout::Xbgr8888,
    )
    .unwrap()
    .with_depth(&mut z)
    .unwrap();
    surface.clear(CLEAR);
    draw(&mut rasterizer(1), &mut surface, &scene);
    for (x, y) in [(0, 0), (19, 9), (7, 3), (12, 8)] {
        assert_eq!(surface.pixel(x, y), owned.pixel(x, y), "pixel {x},{y}");
    }
    assert_eq!(surface.stride(), 96);
    assert_eq!(surface.depth_format(), DepthFormat::D32);
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(cases(24)))]

    #[test]
    fn any_size_stride_and_layout_gets_the_owned_pixels(
        width in 1u32..48,
        height in 1u32..24,
        pad_pixels in 0usize..4,
        layout in proptest::sample::select(PixelLayout::ALL.to_vec()),
        threads in 1usize..3,
    ) {
        let scene = terrain(9, width, height);
        let pad = pad_pixels * layout.bytes_per_pixel();
        on_pool(threads, || check(&scene, (width, height), layout, pad, threads));
    }
}
