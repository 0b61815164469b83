//! One shader, and a render pipeline per combination of the state that the GPU fixes at pipeline
//! creation (topology, culling, winding, depth test and write), built on first use. Shading,
//! texture, fog and perspective are per-draw uniforms.

use std::collections::HashMap;

use stripmask_raster::{
    Compare, CullMode, DepthMode, Filter, FrontFace, Mesh, MipFilter, RenderState, Sampler,
    Topology, Wrap,
};

use crate::gpu::upload::{VERTEX_ATTRIBUTES, VERTEX_STRIDE};

/// The fixed-function state of one draw.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub(crate) struct PipelineKey {
    topology: wgpu::PrimitiveTopology,
    strip_format: Option<wgpu::IndexFormat>,
    cull: Option<wgpu::Face>,
    front_face: wgpu::FrontFace,
    depth: DepthMode,
}

impl PipelineKey {
    /// The key of `mesh` drawn with `state`; `format` is the index format it is uploaded in.
    pub fn new(mesh: &Mesh, state: &RenderState, format: wgpu::IndexFormat) -> Self {
        let (topology, strip_format) = match mesh.topology {
            Topology::TriangleStrip => (wgpu::PrimitiveTopology::TriangleStrip, Some(format)),
            Topology::TriangleList => (wgpu::PrimitiveTopology::TriangleList, None),
        };
        Self {
            topology,
            strip_format,
            cull: match state.cull {
                CullMode::None => None,
                CullMode::Back => Some(wgpu::Face::Back),
                CullMode::Front => Some(wgpu::Face::Front),
            },
            front_face: match state.front_face {
                FrontFace::Ccw => wgpu::FrontFace::Ccw,
                FrontFace::Cw => wgpu::FrontFace::Cw,
            },
            depth: state.depth,
        }
    }
}

/// The shader, its layouts and the pipelines built so far, for one colour and depth format.
pub(crate) struct Pipelines {
    shader: wgpu::ShaderModule,
    pub bind_group_layout: wgpu::BindGroupLayout,
    layout: wgpu::PipelineLayout,
    color: wgpu::TextureFormat,
    depth: Option<wgpu::TextureFormat>,
    built: HashMap<PipelineKey, wgpu::RenderPipeline>,
    samplers: HashMap<Sampler, wgpu::Sampler>,
}

impl Pipelines {
    pub fn new(
        device: &wgpu::Device,
        color: wgpu::TextureFormat,
        depth: Option<wgpu::TextureFormat>,
    ) -> Self {
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("stripmask shading"),
            source: wgpu::ShaderSource::Wgsl(include_str!("shader.wgsl").into()),
        });
        let entry = |binding, visibility, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility,
            ty,
            count: None,
        };
        let bind_group_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("stripmask draw"),
            entries: &[
                entry(
                    0,
                    wgpu::ShaderStages::VERTEX_FRAGMENT,
                    wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                ),
                entry(
                    1,
                    wgpu::ShaderStages::FRAGMENT,
                    wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                ),
                entry(
                    2,
                    wgpu::ShaderStages::FRAGMENT,
                    wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                ),
            ],
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("stripmask draw"),
            bind_group_layouts: &[Some(&bind_group_layout)],
            immediate_size: 0,
        });
        Self {
            shader,
            bind_group_layout,
            layout,
            color,
            depth,
            built: HashMap::new(),
            samplers: HashMap::new(),
        }
    }

    /// Builds the pipeline for `key` unless it exists.
    pub fn prepare(&mut self, device: &wgpu::Device, key: PipelineKey) {
        if self.built.contains_key(&key) {
            return;
        }
        let depth_stencil = self.depth.map(|format| wgpu::DepthStencilState {
            format,
            depth_write_enabled: Some(key.depth.write),
            depth_compare: Some(match key.depth.compare {
                Compare::Always => wgpu::CompareFunction::Always,
                Compare::Less => wgpu::CompareFunction::Less,
                Compare::LessEqual => wgpu::CompareFunction::LessEqual,
            }),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("stripmask draw"),
            layout: Some(&self.layout),
            vertex: wgpu::VertexState {
                module: &self.shader,
                entry_point: Some("vs_main"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: VERTEX_STRIDE,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &VERTEX_ATTRIBUTES,
                })],
            },
            primitive: wgpu::PrimitiveState {
                topology: key.topology,
                strip_index_format: key.strip_format,
                front_face: key.front_face,
                cull_mode: key.cull,
                ..wgpu::PrimitiveState::default()
            },
            depth_stencil,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &self.shader,
                entry_point: Some("fs_main"),
                compilation_options: wgpu::PipelineCompilationOptions::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: self.color,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        self.built.insert(key, pipeline);
    }

    /// The pipeline [`Pipelines::prepare`] built for `key`.
    pub fn get(&self, key: &PipelineKey) -> Option<&wgpu::RenderPipeline> {
        self.built.get(key)
    }

    /// The GPU sampler reading like `sampler`: the same filter and wrap; mipmapped samplers pick
    /// the nearest level (per pixel on the GPU, per triangle on the CPU), others read level 0.
    pub fn sampler(&mut self, device: &wgpu::Device, sampler: Sampler) -> wgpu::Sampler {
        self.samplers
            .entry(sampler)
            .or_insert_with(|| {
                let filter = match sampler.filter {
                    Filter::Nearest => wgpu::FilterMode::Nearest,
                    Filter::Bilinear => wgpu::FilterMode::Linear,
                };
                let address = match sampler.wrap {
                    Wrap::Clamp => wgpu::AddressMode::ClampToEdge,
                    Wrap::Repeat => wgpu::AddressMode::Repeat,
                };
                device.create_sampler(&wgpu::SamplerDescriptor {
                    label: None,
                    address_mode_u: address,
                    address_mode_v: address,
                    address_mode_w: address,
                    mag_filter: filter,
                    min_filter: filter,
                    mipmap_filter: wgpu::MipmapFilterMode::Nearest,
                    lod_max_clamp: match sampler.mip {
                        MipFilter::None => 0.0,
                        MipFilter::Nearest => 32.0,
                    },
                    ..wgpu::SamplerDescriptor::default()
                })
            })
            .clone()
    }
}
