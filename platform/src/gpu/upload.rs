//! The rasterizer's inputs in the GPU's formats: vertices with the model origin applied as the
//! float pipeline applies it, index buffers as given (strips restart at the all-ones index on the
//! GPU too), and textures as RGBA8 mip chains (RGB565 expanded by bit replication, as the CPU
//! reads it).

use stripmask_raster::fixed_point::TEXCOORD_LIMIT;
use stripmask_raster::{Indices, Mesh, Texels, Texture, Topology, Vertex, rgb565_to_rgb};
use wgpu::util::DeviceExt;

use crate::PlatformError;

/// Bytes per GPU vertex: position f32x3, texture coordinates f32x2, colour unorm8x4.
pub(crate) const VERTEX_STRIDE: u64 = 24;

/// The vertex buffer layout matching [`vertex_bytes`] and the shader's `VertexIn`.
pub(crate) const VERTEX_ATTRIBUTES: [wgpu::VertexAttribute; 3] =
    wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x2, 2 => Unorm8x4];

/// The vertices as the GPU reads them. The position plus `origin` is summed in i64 and converted
/// once, and texture coordinates are clamped to the pipeline's limit, both exactly as
/// `Transform::transform_float` and the float pipeline do.
pub(crate) fn vertex_bytes(vertices: &[Vertex], origin: [i32; 3]) -> Vec<u8> {
    let limit = (TEXCOORD_LIMIT >> 16) as f32;
    let mut out = Vec::with_capacity(vertices.len() * VERTEX_STRIDE as usize);
    for v in vertices {
        for (p, o) in v.position.into_iter().zip(origin) {
            out.extend_from_slice(&((i64::from(p) + i64::from(o)) as f32).to_le_bytes());
        }
        for c in v.uv {
            out.extend_from_slice(&c.to_num::<f32>().clamp(-limit, limit).to_le_bytes());
        }
        out.extend_from_slice(&[v.color[0], v.color[1], v.color[2], 255]);
    }
    out
}

/// An index buffer ready to draw: bytes, format and index count.
pub(crate) struct IndexData {
    pub bytes: Vec<u8>,
    pub format: wgpu::IndexFormat,
    pub count: u32,
}

/// The mesh's indices in its own width. Strips go as they are (the GPU restarts at the same
/// all-ones index); a list loses the triangles that hold a restart index, which the CPU skips.
pub(crate) fn index_data(mesh: &Mesh) -> IndexData {
    match (mesh.indices, mesh.topology) {
        (Indices::U16(i), Topology::TriangleStrip) => IndexData {
            bytes: i.iter().flat_map(|v| v.to_le_bytes()).collect(),
            format: wgpu::IndexFormat::Uint16,
            count: i.len() as u32,
        },
        (Indices::U32(i), Topology::TriangleStrip) => IndexData {
            bytes: i.iter().flat_map(|v| v.to_le_bytes()).collect(),
            format: wgpu::IndexFormat::Uint32,
            count: i.len() as u32,
        },
        (indices, Topology::TriangleList) => {
            let all: Vec<Option<u32>> = match indices {
                Indices::U16(i) => i
                    .iter()
                    .map(|&v| (v != u16::MAX).then_some(u32::from(v)))
                    .collect(),
                Indices::U32(i) => i.iter().map(|&v| (v != u32::MAX).then_some(v)).collect(),
            };
            let kept: Vec<u32> = all
                .chunks_exact(3)
                .filter_map(|t| Some([t[0]?, t[1]?, t[2]?]))
                .flatten()
                .collect();
            IndexData {
                bytes: kept.iter().flat_map(|v| v.to_le_bytes()).collect(),
                format: wgpu::IndexFormat::Uint32,
                count: kept.len() as u32,
            }
        }
    }
}

/// A buffer holding `bytes` (padded as wgpu requires).
pub(crate) fn buffer(
    device: &wgpu::Device,
    bytes: &[u8],
    usage: wgpu::BufferUsages,
) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: None,
        contents: bytes,
        usage,
    })
}

/// `texture` with all its levels as an RGBA8 texture viewed from `finest_level` on, or an error
/// naming the adapter's limit.
pub(crate) fn texture(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    texture: &Texture,
    finest_level: u8,
    adapter: &str,
) -> Result<wgpu::TextureView, PlatformError> {
    let levels = texture.levels();
    let (width, height) = (levels[0].width(), levels[0].height());
    let limit = device.limits().max_texture_dimension_2d;
    if width > limit || height > limit {
        return Err(PlatformError::Gpu {
            adapter: adapter.to_string(),
            message: format!(
                "texture {width}x{height} exceeds the adapter's limit of {limit} texels per side"
            ),
        });
    }
    let gpu = device.create_texture(&wgpu::TextureDescriptor {
        label: None,
        size: wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
        mip_level_count: levels.len() as u32,
        sample_count: 1,
        dimension: wgpu::TextureDimension::D2,
        format: wgpu::TextureFormat::Rgba8Unorm,
        usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
        view_formats: &[],
    });
    for (mip, level) in levels.iter().enumerate() {
        let rgba: Vec<u8> = match level.texels() {
            Texels::Rgb565(t) => t
                .iter()
                .flat_map(|&p| {
                    let [r, g, b] = rgb565_to_rgb(p);
                    [r, g, b, 255]
                })
                .collect(),
            Texels::Rgba8888(t) => t.iter().flatten().copied().collect(),
        };
        queue.write_texture(
            wgpu::TexelCopyTextureInfo {
                texture: &gpu,
                mip_level: mip as u32,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            &rgba,
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(4 * level.width()),
                rows_per_image: None,
            },
            wgpu::Extent3d {
                width: level.width(),
                height: level.height(),
                depth_or_array_layers: 1,
            },
        );
    }
    // The binding's finest level is the view's base level, as the CPU clamps its choice.
    Ok(gpu.create_view(&wgpu::TextureViewDescriptor {
        base_mip_level: u32::from(finest_level).min(levels.len() as u32 - 1),
        ..wgpu::TextureViewDescriptor::default()
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn vertices_carry_the_origin_and_clamped_coordinates() {
        let v = [Vertex::new([i32::MAX, -5, 7], [1000.0, 0.5], [1, 2, 3])];
        let bytes = vertex_bytes(&v, [1 << 24, 0, -7]);
        assert_eq!(bytes.len(), VERTEX_STRIDE as usize);
        let f = |k: usize| f32::from_le_bytes(bytes[4 * k..4 * k + 4].try_into().unwrap());
        assert_eq!(f(0), (i32::MAX as i64 + (1 << 24)) as f32);
        assert_eq!([f(1), f(2)], [-5.0, 0.0]);
        assert_eq!([f(3), f(4)], [256.0, 0.5]);
        assert_eq!(&bytes[20..], &[1, 2, 3, 255]);
    }

    #[test]
    fn lists_drop_triangles_with_a_restart_index_and_strips_keep_them() {
        let v = [Vertex::default(); 4];
        let list = Mesh {
            vertices: &v,
            indices: Indices::U16(&[0, 1, 2, 0xFFFF, 1, 2, 1, 2, 3]),
            topology: Topology::TriangleList,
        };
        let d = index_data(&list);
        assert_eq!((d.count, d.format), (6, wgpu::IndexFormat::Uint32));
        let strip = Mesh {
            topology: Topology::TriangleStrip,
            ..list
        };
        let d = index_data(&strip);
        assert_eq!((d.count, d.format), (9, wgpu::IndexFormat::Uint16));
        assert_eq!(&d.bytes[6..8], &[0xFF, 0xFF]);
    }
}
