//! A binding's finest level caps texture detail exactly as a chain that starts at that level.

use glam::{DMat4, DVec3};
use stripmask_raster::*;

const SKY: [u8; 3] = [10, 20, 30];

fn grid() -> (Vec<Vertex>, Vec<u32>) {
    let g = 40usize;
    let mut v = vec![];
    for j in 0..g {
        for i in 0..g {
            let h = ((i as f64 * 0.3).sin() * (j as f64 * 0.2).cos() * 150.0) as i32;
            v.push(Vertex::new(
                [i as i32 * 100, h, j as i32 * 100],
                [i as f32 / 39.0, j as f32 / 39.0],
                [255; 3],
            ));
        }
    }
    let mut idx = vec![];
    for j in 0..g - 1 {
        for i in 0..g {
            idx.push((j * g + i) as u32);
            idx.push(((j + 1) * g + i) as u32);
        }
        idx.push(u32::MAX);
    }
    (v, idx)
}

fn checker() -> Texture {
    let texels = (0..128 * 128)
        .map(|k| {
            let (x, y) = (k % 128, k / 128);
            let on = (x / 2 + y / 2) % 2 == 0;
            [if on { 230 } else { 20 }, (x * 2) as u8, (y * 2) as u8, 255]
        })
        .collect();
    Texture::from_rgba8(128, 128, texels)
        .unwrap()
        .with_mipmaps()
}

fn tail(texture: &Texture, from: usize) -> Texture {
    Texture::from_levels(
        texture.levels()[from..]
            .iter()
            .map(|l| (l.width(), l.height(), l.texels().clone()))
            .collect(),
    )
    .unwrap()
}

fn render(binding: TextureBinding<'_>, precision: Precision) -> Vec<u8> {
    let (v, idx) = grid();
    // Close over the near edge of the grid, so its triangles ask for level 0.
    let m = glam::dcamera::rh::proj::directx::perspective(1.0, 1.5, 10.0, 1e5)
        * glam::dcamera::rh::view::look_at_mat4(
            DVec3::new(2000.0, 900.0, 4600.0),
            DVec3::new(2000.0, 0.0, 1500.0),
            DVec3::Y,
        )
        * DMat4::IDENTITY;
    let mut fb = Framebuffer::new(240, 160, ColorFormat::Rgba8888, DepthFormat::D32).unwrap();
    fb.clear(SKY);
    let state = RenderState {
        precision,
        texture: Some(binding),
        cull: CullMode::None,
        ..RenderState::default()
    };
    let mesh = Mesh {
        vertices: &v,
        indices: Indices::U32(&idx),
        topology: Topology::TriangleStrip,
    };
    Rasterizer::with_threads(1)
        .draw(&mut fb, &mesh, &Transform::new(m).unwrap(), &state)
        .unwrap();
    fb.to_rgba_image().into_raw()
}

#[test]
fn finest_level_equals_a_chain_cut_at_that_level() {
    let full = checker();
    for precision in [Precision::Fixed, Precision::Float] {
        for sampler in [Sampler::BILINEAR_MIPMAP, Sampler::NEAREST] {
            let unrestricted = render(TextureBinding::new(&full, sampler), precision);
            for finest in 1..full.levels().len() {
                let cut = tail(&full, finest);
                let capped = render(
                    TextureBinding {
                        finest_level: finest as u8,
                        ..TextureBinding::new(&full, sampler)
                    },
                    precision,
                );
                assert_eq!(
                    capped,
                    render(TextureBinding::new(&cut, sampler), precision),
                    "{precision:?} {sampler:?}: finest level {finest}"
                );
                assert_ne!(capped, unrestricted, "level {finest} changes the picture");
            }
        }
    }
}

#[test]
fn a_finest_level_beyond_the_chain_reads_the_last_level() {
    let full = checker();
    let last = full.levels().len() - 1;
    let beyond = TextureBinding {
        finest_level: u8::MAX,
        ..TextureBinding::new(&full, Sampler::BILINEAR_MIPMAP)
    };
    let at_last = TextureBinding {
        finest_level: last as u8,
        ..TextureBinding::new(&full, Sampler::BILINEAR_MIPMAP)
    };
    assert_eq!(
        render(beyond, Precision::Fixed),
        render(at_last, Precision::Fixed)
    );
}
