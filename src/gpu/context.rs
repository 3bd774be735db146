//! A headless wgpu device for the preview, its tests and benchmarks.
//!
//! Backends: Vulkan and GL (the `WGPU_BACKEND` environment variable narrows them, as wgpu
//! documents); the adapter is the first wgpu offers for high performance; on a machine with no GPU
//! that is Mesa's software Vulkan (lavapipe, "llvmpipe"). The device gets the adapter's own limits,
//! so large bakes fit wherever the hardware allows, and [`super::GpuPreview`] checks each buffer
//! against them.
//!
//! Inputs: none (environment variables). Outputs: [`GpuContext`]. Invariants: no window, no
//! surface; failures are [`GpuError`]s.

use super::GpuError;

/// A device, its queue and a description of the adapter.
#[derive(Debug, Clone)]
pub struct GpuContext {
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
}

impl GpuContext {
    /// Opens a headless device on the best adapter.
    pub fn headless() -> Result<Self, GpuError> {
        // Vulkan first; GL only when Vulkan has no adapter (probing EGL is noisy without a
        // display).
        let mut tried = Vec::new();
        for backends in [wgpu::Backends::VULKAN, wgpu::Backends::GL] {
            let mut desc = wgpu::InstanceDescriptor::new_without_display_handle();
            desc.backends = backends;
            let desc = desc.with_env();
            if desc.backends.is_empty() {
                continue;
            }
            tried.push(format!("{:?}", desc.backends));
            let instance = wgpu::Instance::new(desc);
            let options = wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                ..Default::default()
            };
            let Ok(adapter) = pollster::block_on(instance.request_adapter(&options)) else {
                continue;
            };
            let info = adapter.get_info();
            let limits = adapter.limits();
            let (device, queue) =
                pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
                    label: Some("glint preview"),
                    required_features: wgpu::Features::empty(),
                    required_limits: limits.clone(),
                    ..Default::default()
                }))
                .map_err(|e| GpuError::Device {
                    adapter: info.name.clone(),
                    reason: e.to_string(),
                })?;
            return Ok(Self {
                device,
                queue,
                info,
                limits,
            });
        }
        Err(GpuError::NoAdapter {
            backends: tried.join(", "),
        })
    }

    /// "name (backend, device type)", for reports.
    pub fn describe(&self) -> String {
        format!(
            "{} ({:?}, {:?})",
            self.info.name, self.info.backend, self.info.device_type
        )
    }
}
