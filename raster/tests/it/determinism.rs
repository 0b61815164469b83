//! The same draws give the same bytes on 1, 2 and 4 threads, and from run to run.

use glam::{DMat4, DVec3};
use stripmask_raster::*;

fn scene() -> (Vec<Vertex>, Vec<u32>, Texture) {
    let g = 120usize;
    let mut v = vec![];
    for j in 0..g {
        for i in 0..g {
            let h = ((i as f64 * 0.2).sin() * (j as f64 * 0.13).cos() * 600.0) as i32;
            let c = (128.0 + 120.0 * (i as f64 * 0.05 + j as f64 * 0.07).sin()) as u8;
            v.push(Vertex::new(
                [i as i32 * 100, h, j as i32 * 100],
                [i as f32 / 30.0, j as f32 / 30.0],
                [c, 255 - c, 200],
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
    let texels = (0..64 * 64)
        .map(|k| [(k % 64 * 4) as u8, (k / 64 * 4) as u8, 90, 255])
        .collect();
    (
        v,
        idx,
        Texture::from_rgba8(64, 64, texels).unwrap().with_mipmaps(),
    )
}

fn render(
    threads: usize,
    precision: Precision,
    color: ColorFormat,
    depth: DepthFormat,
) -> Framebuffer {
    let (v, idx, tex) = scene();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let m = glam::dcamera::rh::proj::directx::perspective(1.1, 1.5, 10.0, 1e5)
            * glam::dcamera::rh::view::look_at_mat4(
                DVec3::new(6000.0, 4000.0, 14000.0),
                DVec3::new(6000.0, 0.0, 4000.0),
                DVec3::Y,
            )
            * DMat4::IDENTITY;
        let mut fb = Framebuffer::new(240, 160, color, depth).unwrap();
        fb.clear([10, 20, 30]);
        let state = RenderState {
            precision,
            shading: Shading::Gouraud,
            texture: Some(TextureBinding::new(
                &tex,
                Sampler {
                    wrap: Wrap::Repeat,
                    ..Sampler::BILINEAR_MIPMAP
                },
            )),
            fog: Some(Fog {
                color: [10, 20, 30],
                start: 4000.0,
                end: 16000.0,
            }),
            ..RenderState::default()
        };
        let mesh = Mesh {
            vertices: &v,
            indices: Indices::U32(&idx),
            topology: Topology::TriangleStrip,
        };
        // Split from the first triangle: a flush this small is otherwise drawn on one thread.
        Rasterizer::new()
            .with_split_from(0)
            .draw(&mut fb, &mesh, &Transform::new(m).unwrap(), &state)
            .unwrap();
        fb
    })
}

#[test]
fn thread_count_and_repetition_do_not_change_a_byte() {
    for precision in [Precision::Fixed, Precision::Float] {
        for (color, depth) in [
            (ColorFormat::Rgb565, DepthFormat::D16),
            (ColorFormat::Rgba8888, DepthFormat::D32),
        ] {
            let one = render(1, precision, color, depth);
            assert!(
                one.to_rgba_image()
                    .pixels()
                    .any(|p| p.0 != [10, 20, 30, 255]),
                "the scene draws something"
            );
            for threads in [2, 4, 1] {
                assert!(
                    render(threads, precision, color, depth) == one,
                    "{precision:?} {color:?} on {threads} threads"
                );
            }
        }
    }
}

/// A change to a render state.
type Edit = fn(&mut RenderState);

/// The hot loops' twins built for AVX2 and its companions (`InstructionSet::Detected`, where the
/// CPU has them) give the bytes of the baseline ones, in every specialisation the PocketPC
/// terrain reaches: both pipelines, both colour and depth formats, both filters and texel
/// types, flat, Gouraud and grey shading, fog, every perspective mode, small and larger
/// triangles, on one thread and two.
#[test]
fn instruction_sets_do_not_change_a_byte() {
    // The scene's texture is RGB565; this one gives the RGBA8888 texel type.
    let rgba = scene().2;
    for grid in [72, 34] {
        let s = crate::scene::terrain(grid, 320, 240);
        let edits: [(&str, Edit); 6] = [
            ("as it is", |_| {}),
            ("nearest", |st| {
                st.texture = st.texture.map(|b| TextureBinding {
                    sampler: Sampler {
                        filter: Filter::Nearest,
                        ..b.sampler
                    },
                    ..b
                })
            }),
            ("untextured, flat", |st| {
                st.texture = None;
                st.shading = Shading::Flat([200, 170, 120]);
            }),
            ("fogged", |st| {
                st.fog = Some(Fog {
                    color: [150, 180, 220],
                    start: 40_000.0,
                    end: 220_000.0,
                })
            }),
            ("affine", |st| st.perspective = Perspective::Affine),
            ("float", |st| st.precision = Precision::Float),
        ];
        for (name, color, depth, state) in s.both_states() {
            for (edit_name, edit) in &edits {
                for texture in [None, Some(&rgba)] {
                    let mut state = state;
                    if let (Some(t), Some(b)) = (texture, state.texture.as_mut()) {
                        b.texture = t;
                    }
                    edit(&mut state);
                    let draw = |threads: usize, set: InstructionSet| {
                        let mut fb = Framebuffer::new(320, 240, color, depth).unwrap();
                        fb.clear([150, 180, 220]);
                        Rasterizer::with_threads(threads)
                            .with_split_from(0)
                            .with_instruction_set(set)
                            .draw(&mut fb, &s.mesh(), &s.transform, &state)
                            .unwrap();
                        fb
                    };
                    let baseline = draw(1, InstructionSet::Baseline);
                    for threads in [1, 2] {
                        assert!(
                            draw(threads, InstructionSet::Detected) == baseline,
                            "grid {grid}, {name}, {edit_name}, RGBA8888 texture {}, {threads} threads",
                            texture.is_some()
                        );
                    }
                }
            }
        }
    }
}
