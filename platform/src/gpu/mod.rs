//! The wgpu comparison backend: the rasterizer's draws through a conformant GPU rasterizer, to an
//! offscreen texture read back as an image. It is a reference for accuracy and a peer for speed;
//! on a machine without a GPU it runs on Mesa's lavapipe ("llvmpipe", a JIT-compiled,
//! multi-threaded SIMD rasterizer).
//!
//! What maps one to one: meshes (strips with restarts, lists, u16/u32 indices), the transform (the
//! f32 matrix with the model origin added in i64 as the float pipeline does), culling and
//! winding, depth test and write (16-bit unorm or 32-bit float depth), flat or Gouraud colour and
//! fog interpolated linearly in screen space, textures with their mip chains, nearest or bilinear,
//! clamp or repeat, and the scissor. What differs by design: the GPU's own coverage rule and
//! sub-pixel precision, perspective correction always exact (`Spans(n)` is drawn as `Exact`;
//! `Affine` is affine), the mip level chosen per pixel instead of per triangle, RGB565 textures
//! filtered after expansion to 8 bits, and `Precision` ignored (the GPU computes in f32). RGB565
//! targets are rendered in 8 bits and truncated to 5-6-5 on readback, as the CPU packs them.
//!
//! Draws are recorded as they come (inputs uploaded at once, so the caller's borrows end with the
//! call) and run in one render pass when the picture is needed ([`GpuTarget::flush`],
//! [`GpuTarget::read_image`]).

mod context;
mod pipelines;
mod upload;

use std::sync::mpsc;

use image::RgbaImage;
use stripmask_raster::fixed_point::MAX_DIMENSION;
use stripmask_raster::{
    ColorFormat, DepthFormat, DrawStats, DrawTarget, LineState, LineStats, Mesh, RasterError, Rect,
    RenderState, Shading, Transform, count_triangles, rgb565_to_rgb,
};

use crate::PlatformError;
use context::Context;
use pipelines::{PipelineKey, Pipelines};

/// Bytes of the per-draw uniform block (`Draw` in `shader.wgsl`).
const UNIFORM_BYTES: usize = 64 + 4 * 16;

/// A recorded draw: its uploaded inputs and fixed-function state.
struct PendingDraw {
    key: PipelineKey,
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    format: wgpu::IndexFormat,
    count: u32,
    bind_group: wgpu::BindGroup,
    scissor: Rect,
}

/// An offscreen GPU picture that takes the same draws as the CPU rasterizer's
/// [`stripmask_raster::RasterTarget`].
pub struct GpuTarget {
    ctx: Context,
    pipelines: Pipelines,
    width: u32,
    height: u32,
    color_format: ColorFormat,
    color: wgpu::Texture,
    color_view: wgpu::TextureView,
    depth_view: Option<wgpu::TextureView>,
    /// A white texel bound to untextured draws.
    white: wgpu::TextureView,
    readback: wgpu::Buffer,
    /// The clear colour the next pass starts with (`None`: keep the picture).
    pending_clear: Option<[u8; 3]>,
    draws: Vec<PendingDraw>,
    /// The draws run since the last clear, with that clear, kept for [`GpuTarget::redraw`].
    drawn: Vec<PendingDraw>,
    drawn_clear: Option<[u8; 3]>,
}

/// Bytes per row of the readback buffer: 4 per pixel, padded as copies require.
fn padded_row(width: u32) -> u32 {
    (4 * width).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT
}

impl GpuTarget {
    /// A black `width` x `height` picture with depth at the far plane, like
    /// [`stripmask_raster::Framebuffer::new`], on the default adapter. A machine without a usable
    /// adapter gets [`PlatformError::NoGpuAdapter`].
    pub fn new(
        width: u32,
        height: u32,
        color: ColorFormat,
        depth: DepthFormat,
    ) -> Result<Self, PlatformError> {
        if width == 0 || height == 0 || width > MAX_DIMENSION || height > MAX_DIMENSION {
            return Err(RasterError::FramebufferSize { width, height }.into());
        }
        let ctx = Context::open()?;
        let device = &ctx.device;
        let size = wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        };
        let texture = |format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: None,
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let color_texture = texture(
            wgpu::TextureFormat::Rgba8Unorm,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        let depth_format = match depth {
            DepthFormat::None => None,
            DepthFormat::D16 => Some(wgpu::TextureFormat::Depth16Unorm),
            DepthFormat::D32 => Some(wgpu::TextureFormat::Depth32Float),
        };
        let depth_view = depth_format.map(|f| {
            texture(f, wgpu::TextureUsages::RENDER_ATTACHMENT)
                .create_view(&wgpu::TextureViewDescriptor::default())
        });
        let white = stripmask_raster::Texture::from_rgba8(1, 1, vec![[255; 4]])?;
        let white = upload::texture(device, &ctx.queue, &white, 0, &ctx.adapter)?;
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("stripmask readback"),
            size: u64::from(padded_row(width)) * u64::from(height),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let pipelines = Pipelines::new(device, wgpu::TextureFormat::Rgba8Unorm, depth_format);
        ctx.take_error()?;
        Ok(Self {
            pipelines,
            width,
            height,
            color_format: color,
            color_view: color_texture.create_view(&wgpu::TextureViewDescriptor::default()),
            color: color_texture,
            depth_view,
            white,
            readback,
            pending_clear: Some([0; 3]),
            draws: Vec::new(),
            drawn: Vec::new(),
            drawn_clear: None,
            ctx,
        })
    }

    /// The adapter that draws, with its driver and backend: `llvmpipe (...)` on lavapipe.
    pub fn adapter_name(&self) -> &str {
        &self.ctx.adapter
    }

    /// Runs the recorded draws and waits for the GPU to finish them.
    pub fn flush(&mut self) -> Result<(), PlatformError> {
        if self.pending_clear.is_none() && self.draws.is_empty() {
            return Ok(());
        }
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        self.encode_pass(&mut encoder);
        self.ctx.queue.submit([encoder.finish()]);
        self.wait()
    }

    /// Runs the last frame again (after the draws still pending): its clear and every draw
    /// since, with the vertices, indices and textures uploaded when they were drawn, and waits
    /// for the GPU. A frame without uploads, for measuring the drawing alone against a renderer
    /// that keeps its inputs.
    pub fn redraw(&mut self) -> Result<(), PlatformError> {
        self.flush()?;
        self.draws = std::mem::take(&mut self.drawn);
        self.pending_clear = self.drawn_clear;
        self.flush()
    }

    /// The picture as an RGBA image, after the recorded draws (RGB565 targets truncated to
    /// 5-6-5 and expanded again, as [`stripmask_raster::Framebuffer::to_rgba_image`] shows them).
    pub fn read_image(&mut self) -> Result<RgbaImage, PlatformError> {
        let mut encoder = self
            .ctx
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor::default());
        self.encode_pass(&mut encoder);
        let row = padded_row(self.width);
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &self.color,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &self.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(row),
                    rows_per_image: None,
                },
            },
            wgpu::Extent3d {
                width: self.width,
                height: self.height,
                depth_or_array_layers: 1,
            },
        );
        self.ctx.queue.submit([encoder.finish()]);
        let (sender, receiver) = mpsc::channel();
        self.readback
            .map_async(wgpu::MapMode::Read, .., move |r| drop(sender.send(r)));
        self.wait()?;
        let mapped = receiver.recv().ok().and_then(Result::ok);
        let pixels = mapped.and_then(|()| {
            let view = self.readback.get_mapped_range(..).ok()?;
            let mut out = Vec::with_capacity(4 * self.width as usize * self.height as usize);
            for line in view.chunks_exact(row as usize) {
                out.extend_from_slice(&line[..4 * self.width as usize]);
            }
            Some(out)
        });
        self.readback.unmap();
        let mut pixels = pixels.ok_or_else(|| PlatformError::Gpu {
            adapter: self.ctx.adapter.clone(),
            message: "the readback buffer could not be mapped".to_string(),
        })?;
        if self.color_format == ColorFormat::Rgb565 {
            for p in pixels.chunks_exact_mut(4) {
                let packed = (u16::from(p[0] >> 3) << 11)
                    | (u16::from(p[1] >> 2) << 5)
                    | u16::from(p[2] >> 3);
                p[..3].copy_from_slice(&rgb565_to_rgb(packed));
            }
        }
        Ok(RgbaImage::from_raw(self.width, self.height, pixels).expect("one RGBA texel per pixel"))
    }

    /// Waits for the submitted work and reports any error wgpu raised on the way.
    fn wait(&self) -> Result<(), PlatformError> {
        let polled = self.ctx.device.poll(wgpu::PollType::wait_indefinitely());
        self.ctx.take_error()?;
        polled.map(drop).map_err(|e| PlatformError::Gpu {
            adapter: self.ctx.adapter.clone(),
            message: e.to_string(),
        })
    }

    /// Encodes one render pass with the pending clear and draws (none when there is nothing to
    /// do), and forgets them.
    fn encode_pass(&mut self, encoder: &mut wgpu::CommandEncoder) {
        let clear = self.pending_clear.take();
        if clear.is_none() && self.draws.is_empty() {
            return;
        }
        let load = clear.map_or(wgpu::LoadOp::Load, |[r, g, b]| {
            let c = |v: u8| f64::from(v) / 255.0;
            wgpu::LoadOp::Clear(wgpu::Color {
                r: c(r),
                g: c(g),
                b: c(b),
                a: 1.0,
            })
        });
        let depth_load = if clear.is_some() {
            wgpu::LoadOp::Clear(1.0)
        } else {
            wgpu::LoadOp::Load
        };
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("stripmask frame"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &self.color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load,
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: self.depth_view.as_ref().map(|view| {
                wgpu::RenderPassDepthStencilAttachment {
                    view,
                    depth_ops: Some(wgpu::Operations {
                        load: depth_load,
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        for d in &self.draws {
            let pipeline = self.pipelines.get(&d.key).expect("prepared at draw time");
            pass.set_pipeline(pipeline);
            pass.set_bind_group(0, &d.bind_group, &[]);
            pass.set_vertex_buffer(0, d.vertices.slice(..));
            pass.set_index_buffer(d.indices.slice(..), d.format);
            let s = d.scissor;
            pass.set_scissor_rect(s.x0, s.y0, s.x1 - s.x0, s.y1 - s.y0);
            pass.draw_indexed(0..d.count, 0, 0..1);
        }
        drop(pass);
        if clear.is_some() {
            self.drawn.clear();
            self.drawn_clear = clear;
        }
        self.drawn.append(&mut self.draws);
    }

    /// The per-draw uniforms, laid out as `Draw` in `shader.wgsl`.
    fn uniforms(transform: &Transform, state: &RenderState) -> Vec<u8> {
        let mut u = Vec::with_capacity(UNIFORM_BYTES);
        for v in transform.float.to_cols_array() {
            u.extend_from_slice(&v.to_le_bytes());
        }
        let rgb = |c: [u8; 3]| [c[0], c[1], c[2], 255].map(|v| f32::from(v) / 255.0);
        let (gouraud, flat) = match state.shading {
            Shading::Gouraud => (1u32, [255; 3]),
            Shading::Flat(c) => (0, c),
        };
        let fog = state
            .fog
            .map_or([0.0; 4], |f| [f.start as f32, f.end as f32, 1.0, 0.0]);
        let fog_color = state.fog.map_or([0; 3], |f| f.color);
        let affine = u32::from(state.perspective == stripmask_raster::Perspective::Affine);
        for v in rgb(flat).into_iter().chain(rgb(fog_color)).chain(fog) {
            u.extend_from_slice(&v.to_le_bytes());
        }
        for v in [gouraud, affine, 0, 0] {
            u.extend_from_slice(&v.to_le_bytes());
        }
        debug_assert_eq!(u.len(), UNIFORM_BYTES);
        u
    }
}

impl DrawTarget for GpuTarget {
    type Error = PlatformError;

    fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    fn clear(&mut self, color: [u8; 3]) {
        self.draws.clear();
        self.pending_clear = Some(color);
    }

    /// Refused: this backend is a reference for the terrain's triangles, and the wireframe is a
    /// viewing aid drawn by the CPU rasterizer's own line path (`Rasterizer::draw_edges`).
    fn draw_edges(
        &mut self,
        _mesh: &Mesh,
        _transform: &Transform,
        _state: &LineState,
    ) -> Result<LineStats, PlatformError> {
        Err(PlatformError::Gpu {
            adapter: self.adapter_name().to_string(),
            message:
                "wireframe lines are drawn by the CPU rasterizer only; turn the wireframe off \
                      to render on the GPU"
                    .into(),
        })
    }

    /// Records the draw. Its [`DrawStats::triangles`] are counted as the CPU counts them; the
    /// GPU does not report clipped triangles or fragments per draw, so those stay 0.
    fn draw(
        &mut self,
        mesh: &Mesh,
        transform: &Transform,
        state: &RenderState,
    ) -> Result<DrawStats, PlatformError> {
        let scissor = Rect::scissor_on(state.scissor, self.width, self.height)?;
        let triangles = count_triangles(mesh)?;
        let stats = DrawStats {
            triangles,
            ..DrawStats::default()
        };
        if triangles == 0 || scissor.x0 == scissor.x1 || scissor.y0 == scissor.y1 {
            return Ok(stats);
        }
        let device = &self.ctx.device;
        let indices = upload::index_data(mesh);
        let key = PipelineKey::new(mesh, state, indices.format);
        self.pipelines.prepare(device, key);
        let texture_view = match state.texture {
            Some(b) => Some(upload::texture(
                device,
                &self.ctx.queue,
                b.texture,
                b.finest_level,
                &self.ctx.adapter,
            )?),
            None => None,
        };
        let sampler = self.pipelines.sampler(
            device,
            state
                .texture
                .map_or(stripmask_raster::Sampler::NEAREST, |b| b.sampler),
        );
        let uniforms = upload::buffer(
            device,
            &Self::uniforms(transform, state),
            wgpu::BufferUsages::UNIFORM,
        );
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &self.pipelines.bind_group_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: uniforms.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::TextureView(
                        texture_view.as_ref().unwrap_or(&self.white),
                    ),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::Sampler(&sampler),
                },
            ],
        });
        self.draws.push(PendingDraw {
            key,
            vertices: upload::buffer(
                device,
                &upload::vertex_bytes(mesh.vertices, transform.origin),
                wgpu::BufferUsages::VERTEX,
            ),
            indices: upload::buffer(device, &indices.bytes, wgpu::BufferUsages::INDEX),
            format: indices.format,
            count: indices.count,
            bind_group,
            scissor,
        });
        Ok(stats)
    }
}
