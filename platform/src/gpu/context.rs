//! Finding an adapter and opening a device, with wgpu's asynchronous errors caught instead of
//! panicking: a machine without a usable adapter gets [`PlatformError::NoGpuAdapter`].

use std::sync::{Arc, Mutex};

use crate::PlatformError;

/// An open device, its queue, and the first error wgpu reported on it since the last check.
pub(crate) struct Context {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    /// Adapter name, driver and backend, e.g. `llvmpipe (LLVM 15.0.6, 256 bits) (Mesa 22.3.6, Vulkan)`.
    pub adapter: String,
    errors: Arc<Mutex<Option<String>>>,
}

impl Context {
    /// The default adapter (a real GPU where there is one; `WGPU_BACKEND`, `WGPU_ADAPTER_NAME` and
    /// the other wgpu environment variables apply) with its own limits, so that textures as large
    /// as the adapter takes are accepted.
    pub fn open() -> Result<Self, PlatformError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter =
            pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default()))
                .map_err(|e| PlatformError::NoGpuAdapter {
                detail: e.to_string(),
            })?;
        let info = adapter.get_info();
        let name = format!(
            "{} ({}{}, {:?})",
            info.name,
            info.driver,
            if info.driver_info.is_empty() {
                String::new()
            } else {
                format!(" {}", info.driver_info)
            },
            info.backend
        );
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("stripmask comparison"),
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| PlatformError::Gpu {
            adapter: name.clone(),
            message: format!("cannot open the device: {e}"),
        })?;
        let errors = Arc::new(Mutex::new(None));
        let sink = Arc::clone(&errors);
        device.on_uncaptured_error(Arc::new(move |e: wgpu::Error| {
            let mut first = sink.lock().unwrap_or_else(|p| p.into_inner());
            first.get_or_insert_with(|| e.to_string());
        }));
        Ok(Self {
            device,
            queue,
            adapter: name,
            errors,
        })
    }

    /// The first error wgpu reported since the last call, as a [`PlatformError::Gpu`].
    pub fn take_error(&self) -> Result<(), PlatformError> {
        let error = self.errors.lock().unwrap_or_else(|p| p.into_inner()).take();
        match error {
            Some(message) => Err(PlatformError::Gpu {
                adapter: self.adapter.clone(),
                message,
            }),
            None => Ok(()),
        }
    }
}
