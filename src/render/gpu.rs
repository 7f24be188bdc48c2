//! The wgpu backend: runs `shaders/ibrt.wgsl` as a compute shader.

use super::RenderError;
use super::gpu_types::{FrameParams, LayerData};
use wgpu::util::DeviceExt;

pub const IBRT_SHADER: &str = include_str!("shaders/ibrt.wgsl");

/// Samples per pixel per dispatch: keeps each submission short on slow (software) adapters.
const SAMPLES_PER_DISPATCH: u32 = 32;
const WORKGROUP_SIZE: u32 = 8;

/// A device with the IBRT pipeline built.
pub struct GpuRenderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    /// The adapter's name and backend, for reports.
    pub adapter_description: String,
}

impl GpuRenderer {
    /// Opens the first GPU adapter wgpu finds (honouring WGPU_BACKEND and friends), or
    /// `RenderError::NoAdapter` when there is none.
    pub fn new() -> Result<GpuRenderer, RenderError> {
        let descriptor = wgpu::InstanceDescriptor::new_without_display_handle().with_env();
        let instance = wgpu::Instance::new(descriptor);
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        }))
        .map_err(|e| RenderError::NoAdapter(e.to_string()))?;
        let info = adapter.get_info();
        let adapter_description = format!("{} ({:?})", info.name, info.backend);
        let limits = adapter.limits();
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("lensbake ibrt"),
            required_limits: wgpu::Limits {
                max_storage_buffer_binding_size: limits.max_storage_buffer_binding_size,
                max_buffer_size: limits.max_buffer_size,
                ..wgpu::Limits::downlevel_defaults()
            },
            ..Default::default()
        }))
        .map_err(|e| RenderError::Gpu(e.to_string()))?;
        // Capture validation errors instead of letting wgpu's default handler panic.
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("ibrt.wgsl"),
            source: wgpu::ShaderSource::Wgsl(IBRT_SHADER.into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("ibrt"),
            layout: None,
            module: &module,
            entry_point: Some("render"),
            compilation_options: Default::default(),
            cache: None,
        });
        if let Some(error) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Gpu(format!(
                "building the IBRT pipeline: {error}"
            )));
        }
        Ok(GpuRenderer {
            device,
            queue,
            pipeline,
            adapter_description,
        })
    }

    /// Runs every sample of `frame` over `layers`; returns the per-pixel sum of weighted radiance
    /// (RGBA, alpha unused), exactly what the CPU twin's `accumulate` produces.
    pub fn accumulate(
        &self,
        frame: &FrameParams,
        layers: &LayerData,
    ) -> Result<Vec<[f32; 4]>, RenderError> {
        let storage = |label: &str, contents: &[u8]| {
            self.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents,
                    usage: wgpu::BufferUsages::STORAGE,
                })
        };
        let depths = storage("layer depths", bytemuck::cast_slice(&layers.depths));
        let colours = storage("layer colours", bytemuck::cast_slice(&layers.colours));
        let bounds = storage("depth bounds", bytemuck::cast_slice(&layers.depth_bounds));
        let pixels = (frame.width * frame.height) as u64;
        let output_bytes = pixels * 16;
        let output = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("radiance sum"),
            size: output_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: output_bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let mut offset = 0;
        while offset < frame.samples_per_pixel {
            let chunk = FrameParams {
                sample_offset: offset,
                sample_count: SAMPLES_PER_DISPATCH.min(frame.samples_per_pixel - offset),
                ..*frame
            };
            let uniform = self
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("frame"),
                    contents: bytemuck::bytes_of(&chunk),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
            let bind_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("ibrt"),
                layout: &self.pipeline.get_bind_group_layout(0),
                entries: &[
                    wgpu::BindGroupEntry {
                        binding: 0,
                        resource: uniform.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 1,
                        resource: depths.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 2,
                        resource: colours.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 3,
                        resource: bounds.as_entire_binding(),
                    },
                    wgpu::BindGroupEntry {
                        binding: 4,
                        resource: output.as_entire_binding(),
                    },
                ],
            });
            let mut encoder = self.device.create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_compute_pass(&Default::default());
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &bind_group, &[]);
                pass.dispatch_workgroups(
                    frame.width.div_ceil(WORKGROUP_SIZE),
                    frame.height.div_ceil(WORKGROUP_SIZE),
                    1,
                );
            }
            self.queue.submit([encoder.finish()]);
            offset += chunk.sample_count;
        }
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&output, 0, &readback, 0, output_bytes);
        self.queue.submit([encoder.finish()]);
        if let Some(error) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Gpu(format!("dispatching IBRT: {error}")));
        }
        readback.map_async(wgpu::MapMode::Read, .., |_| {});
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| RenderError::Gpu(e.to_string()))?;
        let view = readback
            .get_mapped_range(..)
            .map_err(|e| RenderError::Gpu(e.to_string()))?;
        Ok(bytemuck::cast_slice(&view).to_vec())
    }
}
