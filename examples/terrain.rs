//! Renders the Puget Sound elevation model with the fixed-point rasterizer and writes a PNG.
//!
//! ```text
//! cargo run --release --example terrain -- [--step N] [--size WxH] [--float] [--out terrain.png]
//! ```
//!
//! The whole 1025 x 1025 grid (2 million triangles at `--step 1`) is one set of triangle strips
//! with 32-bit indices; the texture is the database's height colour ramp in RGB565 with its mip chain, lit per
//! vertex (Gouraud) from normals computed once, with distance fog.

use std::time::Instant;

use glam::{DMat4, DVec3};
use stripmask::db::texture_gen::ramp;
use stripmask_raster::{
    ColorFormat, DepthFormat, Fog, Framebuffer, Indices, Mesh, Perspective, Precision, Rasterizer,
    RenderState, Sampler, Shading, Texture, TextureBinding, Topology, Transform, Vertex,
    rgb_to_rgb565,
};

const SPACING_M: f64 = 160.0;
const METRES_PER_UNIT: f64 = 0.1;
const EXAGGERATION: f64 = 2.0;

struct Options {
    step: usize,
    size: (u32, u32),
    precision: Precision,
    out: String,
}

fn parse() -> Result<Options, String> {
    let mut o = Options {
        step: 2,
        size: (960, 540),
        precision: Precision::Fixed,
        out: "terrain.png".into(),
    };
    let mut args = std::env::args().skip(1);
    while let Some(a) = args.next() {
        let mut value = || args.next().ok_or(format!("{a} needs a value"));
        match a.as_str() {
            "--step" => o.step = value()?.parse().map_err(|e| format!("--step: {e}"))?,
            "--size" => {
                let v = value()?;
                let (w, h) = v.split_once('x').ok_or("--size takes WxH")?;
                o.size = (
                    w.parse().map_err(|e| format!("--size: {e}"))?,
                    h.parse().map_err(|e| format!("--size: {e}"))?,
                );
            }
            "--float" => o.precision = Precision::Float,
            "--out" => o.out = value()?,
            _ => return Err(format!("unknown argument {a}")),
        }
    }
    if o.step == 0 {
        return Err("--step must be at least 1".into());
    }
    Ok(o)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let o = parse()?;
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/examples/data/puget_sound_1k_height.png"
    );
    let dem = image::open(path)
        .map_err(|e| format!("{path}: {e}"))?
        .to_luma16();
    let n = dem.width() as usize;
    let h = |i: usize, j: usize| dem.get_pixel(i as u32, j as u32).0[0];

    // Texture: the colour ramp, one texel per cell, RGB565 with mips.
    let tex_side = (n - 1).next_power_of_two() as u32;
    let texels = (0..tex_side as usize * tex_side as usize)
        .map(|k| {
            let (i, j) = (
                (k % tex_side as usize).min(n - 1),
                (k / tex_side as usize).min(n - 1),
            );
            rgb_to_rgb565(ramp((h(i, j) as f64 * METRES_PER_UNIT) as f32))
        })
        .collect();
    let texture = Texture::from_rgb565(tex_side, tex_side, texels)?.with_mipmaps();

    // Vertices on the sub-sampled grid, lit once from finest-level normals.
    let g = (n - 1) / o.step + 1;
    let light = DVec3::new(-1.0, 1.2, -0.6).normalize();
    let mut vertices = Vec::with_capacity(g * g);
    for gj in 0..g {
        for gi in 0..g {
            let (i, j) = (gi * o.step, gj * o.step);
            let dx = (h((i + 1).min(n - 1), j) as f64 - h(i.saturating_sub(1), j) as f64)
                * METRES_PER_UNIT
                * EXAGGERATION;
            let dz = (h(i, (j + 1).min(n - 1)) as f64 - h(i, j.saturating_sub(1)) as f64)
                * METRES_PER_UNIT
                * EXAGGERATION;
            let normal = DVec3::new(-dx, 2.0 * SPACING_M, -dz).normalize();
            let lum = (0.35 + 0.65 * normal.dot(light).max(0.0)) * 255.0;
            let uv = [i as f32 / (n - 1) as f32, j as f32 / (n - 1) as f32];
            vertices.push(Vertex::new(
                [i as i32, h(i, j) as i32, j as i32],
                uv,
                [lum as u8; 3],
            ));
        }
    }
    // One strip per grid row pair, joined by restarts.
    let mut indices = Vec::with_capacity((g - 1) * (2 * g + 1));
    for gj in 0..g - 1 {
        for gi in 0..g {
            indices.push((gj * g + gi) as u32);
            indices.push(((gj + 1) * g + gi) as u32);
        }
        indices.push(u32::MAX);
    }

    let extent = (n - 1) as f64 * SPACING_M;
    let eye = DVec3::new(-0.08 * extent, 0.28 * extent, 1.12 * extent);
    let target = DVec3::new(0.55 * extent, 0.0, 0.35 * extent);
    let (w, hgt) = o.size;
    let projection = glam::dcamera::rh::proj::directx::perspective(
        0.9,
        w as f64 / hgt as f64,
        100.0,
        4.0 * extent,
    );
    let view = glam::dcamera::rh::view::look_at_mat4(eye, target, DVec3::Y);
    let model = DMat4::from_scale(DVec3::new(
        SPACING_M,
        METRES_PER_UNIT * EXAGGERATION,
        SPACING_M,
    ));
    let transform = Transform::new(projection * view * model)?;

    let mut fb = Framebuffer::new(w, hgt, ColorFormat::Rgb565, DepthFormat::D16)?;
    fb.clear([135, 170, 215]);
    let state = RenderState {
        precision: o.precision,
        shading: Shading::Gouraud,
        texture: Some(TextureBinding::new(&texture, Sampler::BILINEAR_MIPMAP)),
        perspective: Perspective::Spans(16),
        fog: Some(Fog {
            color: [135, 170, 215],
            start: 0.6 * extent,
            end: 2.2 * extent,
        }),
        ..RenderState::default()
    };
    let mesh = Mesh {
        vertices: &vertices,
        indices: Indices::U32(&indices),
        topology: Topology::TriangleStrip,
    };
    let start = Instant::now();
    let stats = Rasterizer::new().draw(&mut fb, &mesh, &transform, &state)?;
    let took = start.elapsed();
    fb.to_rgba_image()
        .save(&o.out)
        .map_err(|e| format!("{}: {e}", o.out))?;
    println!(
        "{} triangles ({} rasterized), {} fragments, {:.1} ms on {} threads -> {}",
        stats.triangles,
        stats.rasterized,
        stats.fragments,
        took.as_secs_f64() * 1e3,
        rayon::current_num_threads(),
        o.out
    );
    Ok(())
}
