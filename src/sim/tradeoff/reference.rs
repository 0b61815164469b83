//! The images settings are measured against. A reference renders the same view from the same
//! engine (tiles, masks, textures, camera); the report measures every setting against each
//! reference it is given, so a second one (a GPU render of the same draw list) plugs in beside
//! the CPU float render without touching the sweep.

use image::RgbaImage;
use stripmask_raster::{ColorFormat, DepthFormat, Framebuffer, Perspective, Precision, Sampler};

use crate::engine::Engine;
use crate::engine::camera::Camera;
use crate::error::Result;

/// A renderer of reference images.
pub trait Reference {
    /// Short name for tables and CSV columns, e.g. `cpu-float`.
    fn name(&self) -> String;
    /// Renders `camera`'s view of `engine`'s terrain at `size`, with the engine's rendering
    /// features (lighting, fog, depth test, sky) as they are set. The engine's render settings
    /// and pinned levels may be changed; the caller sets its own before the next frame.
    fn render(
        &mut self,
        engine: &mut Engine,
        camera: &Camera,
        size: (u32, u32),
    ) -> Result<RgbaImage>;
}

/// The most accurate render this engine can make: every tile at full resolution, the f32
/// pipeline, exact perspective, bilinear mipmapped texels, 32-bit depth, 8-bit colour.
#[derive(Clone, Copy, Debug, Default)]
pub struct CpuFloat;

impl Reference for CpuFloat {
    fn name(&self) -> String {
        "cpu-float".into()
    }

    fn render(
        &mut self,
        engine: &mut Engine,
        camera: &Camera,
        size: (u32, u32),
    ) -> Result<RgbaImage> {
        let render = engine.render_settings_mut();
        render.precision = Precision::Float;
        render.perspective = Perspective::Exact;
        if render.sampler.is_some() {
            render.sampler = Some(Sampler::BILINEAR_MIPMAP);
        }
        engine.force_levels(Some(Box::new(|_| 0)));
        let mut fb = Framebuffer::new(size.0, size.1, ColorFormat::Rgba8888, DepthFormat::D32)?;
        engine.render(camera, &mut fb)?;
        Ok(fb.to_rgba_image())
    }
}

/// The same reference draw list rendered by wgpu (lavapipe's llvmpipe without a GPU): a
/// conformant rasterizer to measure the CPU pipelines against, independent of their rounding.
#[cfg(feature = "wgpu")]
pub struct Gpu {
    target: stripmask_platform::GpuTarget,
}

#[cfg(feature = "wgpu")]
impl Gpu {
    /// A wgpu target of `size`, or the reason there is none (no adapter: the error says which
    /// packages provide one).
    pub fn new(size: (u32, u32)) -> std::result::Result<Gpu, stripmask_platform::PlatformError> {
        let target = stripmask_platform::GpuTarget::new(
            size.0,
            size.1,
            ColorFormat::Rgba8888,
            DepthFormat::D32,
        )?;
        Ok(Gpu { target })
    }

    /// The adapter that renders, as wgpu names it.
    pub fn adapter(&self) -> &str {
        self.target.adapter_name()
    }
}

#[cfg(feature = "wgpu")]
impl Reference for Gpu {
    fn name(&self) -> String {
        "wgpu".into()
    }

    fn render(
        &mut self,
        engine: &mut Engine,
        camera: &Camera,
        size: (u32, u32),
    ) -> Result<RgbaImage> {
        use stripmask_raster::DrawTarget;
        if self.target.size() != size {
            *self = Gpu::new(size)?;
        }
        let render = engine.render_settings_mut();
        render.perspective = Perspective::Exact;
        if render.sampler.is_some() {
            render.sampler = Some(Sampler::BILINEAR_MIPMAP);
        }
        engine.force_levels(Some(Box::new(|_| 0)));
        engine.render_to(camera, &mut self.target)?;
        Ok(self.target.read_image()?)
    }
}
