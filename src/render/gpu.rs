//! The wgpu backend: runs `shaders/ibrt.wgsl` as a compute shader (modules assembled by
//! [`super::wgsl`]).

use super::RenderError;
use super::gpu_types::{ChannelParams, FrameParams, LayerData, LensData, LensParams, LensSurface};
use super::wgsl::{ibrt_shader, lens_trace_shader};
use std::sync::OnceLock;
use wgpu::util::DeviceExt;

/// Samples per pixel per dispatch: keeps each submission short on slow (software) adapters.
const SAMPLES_PER_DISPATCH: u32 = 32;
const WORKGROUP_SIZE: u32 = 8;

/// Opens the first GPU adapter wgpu finds (honouring WGPU_BACKEND and friends) with the limits
/// the renderer and the peeler need: the device, its queue, and the adapter's name and backend.
///
/// Mesa's drivers print an `error:` line here when `XDG_RUNTIME_DIR` names no directory; the
/// binary sets one up first (`main.rs`), library users are told so in README.md.
pub(crate) fn open_device(label: &str) -> Result<(wgpu::Device, wgpu::Queue, String), RenderError> {
    let adapter = request_adapter()?;
    let adapter_description = describe(&adapter.get_info());
    let limits = adapter.limits();
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some(label),
        required_limits: wgpu::Limits {
            max_storage_buffer_binding_size: limits.max_storage_buffer_binding_size,
            max_buffer_size: limits.max_buffer_size,
            // Layers (4), pupil circles and lens surfaces.
            max_storage_buffers_per_shader_stage:
                limits.max_storage_buffers_per_shader_stage.max(6),
            max_bind_groups: limits.max_bind_groups.max(4),
            // Peeled layers are as wide as the layer view.
            max_texture_dimension_2d: limits.max_texture_dimension_2d,
            // A chromatic baked render stacks three tables along the third axis.
            max_texture_dimension_3d: limits.max_texture_dimension_3d,
            ..wgpu::Limits::downlevel_defaults()
        },
        ..Default::default()
    }))
    .map_err(|e| RenderError::Gpu(e.to_string()))?;
    Ok((device, queue, adapter_description))
}

/// The adapter wgpu picks (honouring WGPU_BACKEND and friends), preferring a fast one.
fn request_adapter() -> Result<wgpu::Adapter, RenderError> {
    let descriptor = wgpu::InstanceDescriptor::new_without_display_handle().with_env();
    let instance = wgpu::Instance::new(descriptor);
    pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
        power_preference: wgpu::PowerPreference::HighPerformance,
        ..Default::default()
    }))
    .map_err(|e| RenderError::NoAdapter(e.to_string()))
}

fn describe(info: &wgpu::AdapterInfo) -> String {
    format!("{} ({:?})", info.name, info.backend)
}

/// Whether an automatic backend choice should use the GPU: Ok when the best adapter is a
/// hardware one, else why not. A software rasteriser (Mesa's llvmpipe, WARP, SwiftShader:
/// device type `Cpu`) runs the kernel on the same cores as the CPU twin, only slower: `lensbake
/// bench render` measured the twin 4.8-23x faster than llvmpipe on a two-core machine
/// (notebooks-out/render).
pub fn gpu_worth_using() -> Result<(), String> {
    let adapter = request_adapter().map_err(|e| e.to_string())?;
    let info = adapter.get_info();
    if info.device_type == wgpu::DeviceType::Cpu {
        return Err(format!(
            "the only GPU adapter, {}, is a software rasteriser, slower than the CPU twin",
            describe(&info)
        ));
    }
    Ok(())
}

/// A device with the IBRT pipeline built.
pub struct GpuRenderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    /// The ray-by-ray harness `trace_lens_rays`, built on first use (only tests ask for it).
    trace_pipeline: OnceLock<wgpu::ComputePipeline>,
    /// `render_chromatic`, built on first use so monochrome work never compiles it.
    chromatic_pipeline: OnceLock<wgpu::ComputePipeline>,
    /// The adapter's name and backend, for reports.
    pub adapter_description: String,
}

impl GpuRenderer {
    /// Opens the first GPU adapter wgpu finds (honouring WGPU_BACKEND and friends), or
    /// `RenderError::NoAdapter` when there is none.
    pub fn new() -> Result<GpuRenderer, RenderError> {
        let (device, queue, adapter_description) = open_device("lensbake ibrt")?;
        // Capture validation errors instead of letting wgpu's default handler panic.
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let pipeline = compute_pipeline(&device, ibrt_shader(), "render");
        if let Some(error) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Gpu(format!(
                "building the IBRT pipeline: {error}"
            )));
        }
        Ok(GpuRenderer {
            device,
            queue,
            pipeline,
            trace_pipeline: OnceLock::new(),
            chromatic_pipeline: OnceLock::new(),
            adapter_description,
        })
    }

    /// Builds the `render_chromatic` pipeline now rather than on the first chromatic render (it
    /// takes seconds on a software adapter; callers that time renders build it first).
    pub fn prepare_chromatic(&self) -> Result<(), RenderError> {
        self.chromatic_pipeline().map(|_| ())
    }

    /// The `render_chromatic` pipeline, built the first time it is asked for.
    fn chromatic_pipeline(&self) -> Result<&wgpu::ComputePipeline, RenderError> {
        self.pipeline_once(&self.chromatic_pipeline, ibrt_shader(), "render_chromatic")
    }

    /// The `trace_lens_rays` harness pipeline, built the first time it is asked for.
    fn trace_pipeline(&self) -> Result<&wgpu::ComputePipeline, RenderError> {
        self.pipeline_once(&self.trace_pipeline, lens_trace_shader(), "trace_lens_rays")
    }

    fn pipeline_once<'a>(
        &self,
        cell: &'a OnceLock<wgpu::ComputePipeline>,
        source: &str,
        entry: &str,
    ) -> Result<&'a wgpu::ComputePipeline, RenderError> {
        if let Some(pipeline) = cell.get() {
            return Ok(pipeline);
        }
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let pipeline = compute_pipeline(&self.device, source, entry);
        if let Some(error) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Gpu(format!(
                "building the {entry} pipeline: {error}"
            )));
        }
        Ok(cell.get_or_init(|| pipeline))
    }

    fn storage(&self, label: &str, contents: &[u8]) -> wgpu::Buffer {
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::STORAGE,
            })
    }

    fn uniform(&self, label: &str, contents: &[u8]) -> wgpu::Buffer {
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage: wgpu::BufferUsages::UNIFORM,
            })
    }

    fn bind_group(
        &self,
        pipeline: &wgpu::ComputePipeline,
        group: u32,
        buffers: &[wgpu::BindingResource],
    ) -> wgpu::BindGroup {
        let entries: Vec<wgpu::BindGroupEntry> = buffers
            .iter()
            .enumerate()
            .map(|(i, resource)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource: resource.clone(),
            })
            .collect();
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(group),
            entries: &entries,
        })
    }

    /// Bind group 2: the lens surfaces and stop.
    fn lens_group(
        &self,
        pipeline: &wgpu::ComputePipeline,
        params: &LensParams,
        surfaces: &[LensSurface],
    ) -> wgpu::BindGroup {
        let surfaces = self.storage("lens surfaces", bytemuck::cast_slice(surfaces));
        let params = self.uniform("lens params", bytemuck::bytes_of(params));
        self.bind_group(
            pipeline,
            2,
            &[surfaces.as_entire_binding(), params.as_entire_binding()],
        )
    }

    fn texture_3d(&self, label: &str, dims: [u32; 3], texels: &[[f32; 4]]) -> wgpu::TextureView {
        let size = wgpu::Extent3d {
            width: dims[0],
            height: dims[1],
            depth_or_array_layers: dims[2],
        };
        let texture = self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D3,
            format: wgpu::TextureFormat::Rgba32Float,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        self.queue.write_texture(
            texture.as_image_copy(),
            bytemuck::cast_slice(texels),
            wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(dims[0] * 16),
                rows_per_image: Some(dims[1]),
            },
            size,
        );
        texture.create_view(&Default::default())
    }

    /// Reads back `buffer` (of `bytes` bytes) after the submitted work.
    fn read_back(&self, buffer: &wgpu::Buffer, bytes: u64) -> Result<Vec<[f32; 4]>, RenderError> {
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: bytes,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(buffer, 0, &readback, 0, bytes);
        self.queue.submit([encoder.finish()]);
        readback.map_async(wgpu::MapMode::Read, .., |_| {});
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| RenderError::Gpu(e.to_string()))?;
        let view = readback
            .get_mapped_range(..)
            .map_err(|e| RenderError::Gpu(e.to_string()))?;
        Ok(bytemuck::cast_slice(&view).to_vec())
    }

    /// Traces film-side rays (origin, direction; travelling -z) backward through the lens with
    /// the shader's `trace_lens`. Returns per ray (origin, status) and (direction, surface): the
    /// test hook that compares the port with the f64 tracer.
    pub fn trace_rays(
        &self,
        params: &LensParams,
        surfaces: &[LensSurface],
        rays: &[[[f32; 3]; 2]],
    ) -> Result<Vec<[[f32; 4]; 2]>, RenderError> {
        if rays.is_empty() {
            return Ok(Vec::new());
        }
        let input: Vec<[f32; 4]> = rays
            .iter()
            .flat_map(|[o, d]| [[o[0], o[1], o[2], 0.0], [d[0], d[1], d[2], 0.0]])
            .collect();
        let bytes = (input.len() * 16) as u64;
        let pipeline = self.trace_pipeline()?;
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let rays_in = self.storage("rays in", bytemuck::cast_slice(&input));
        let rays_out = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("rays out"),
            size: bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let empty = |group| self.bind_group(pipeline, group, &[]);
        let groups = [
            empty(0),
            empty(1),
            self.lens_group(pipeline, params, surfaces),
            self.bind_group(
                pipeline,
                3,
                &[rays_in.as_entire_binding(), rays_out.as_entire_binding()],
            ),
        ];
        let mut encoder = self.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(pipeline);
            for (i, group) in groups.iter().enumerate() {
                pass.set_bind_group(i as u32, group, &[]);
            }
            pass.dispatch_workgroups((rays.len() as u32).div_ceil(64), 1, 1);
        }
        self.queue.submit([encoder.finish()]);
        if let Some(error) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Gpu(format!("tracing rays: {error}")));
        }
        let out = self.read_back(&rays_out, bytes)?;
        Ok(out.chunks(2).map(|pair| [pair[0], pair[1]]).collect())
    }

    /// Runs every sample of `frame` over `layers` through `lens`; returns the per-pixel sum of
    /// weighted radiance (RGBA, alpha unused), exactly what the CPU twin's `accumulate` produces.
    pub fn accumulate(
        &self,
        frame: &FrameParams,
        layers: &LayerData,
        lens: &LensData,
    ) -> Result<Vec<[f32; 4]>, RenderError> {
        self.accumulate_channels(frame, layers, lens, None)
    }

    /// [`GpuRenderer::accumulate`], per colour channel when `channels` is given (`lens` then
    /// from [`LensData::chromatic`]): the twin of the CPU's `accumulate_chromatic`.
    pub fn accumulate_channels(
        &self,
        frame: &FrameParams,
        layers: &LayerData,
        lens: &LensData,
        channels: Option<&ChannelParams>,
    ) -> Result<Vec<[f32; 4]>, RenderError> {
        let limit = self.device.limits().max_texture_dimension_3d;
        if lens.dims.iter().any(|&n| n > limit) {
            return Err(RenderError::Gpu(format!(
                "the table's {}x{}x{} texture exceeds this adapter's 3D texture limit {limit}; \
                 bake at a lower resolution",
                lens.dims[0], lens.dims[1], lens.dims[2]
            )));
        }
        let pipeline = match channels {
            Some(_) => self.chromatic_pipeline()?,
            None => &self.pipeline,
        };
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let starts = self.storage("layer starts", bytemuck::cast_slice(layers.starts));
        let inverse_depths = self.storage(
            "surfel inverse depths",
            bytemuck::cast_slice(&layers.inverse_depths),
        );
        let surfels = self.storage("layer surfels", bytemuck::cast_slice(layers.surfels));
        let bounds = self.storage("depth bounds", bytemuck::cast_slice(&layers.depth_bounds));
        let pixels = (frame.width * frame.height) as u64;
        let output_bytes = pixels * 16;
        let output = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("radiance sum"),
            size: output_bytes,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let transfer = self.texture_3d("lrtf transfer", lens.dims, &lens.transfer);
        let aux = self.texture_3d("lrtf aux", lens.dims, &lens.aux);
        let pupil = self.storage("pupil circles", bytemuck::cast_slice(&lens.pupil));
        let lrtf = self.uniform("lrtf params", bytemuck::bytes_of(&lens.lrtf));
        let lrtf_group = self.bind_group(
            pipeline,
            0,
            &[
                wgpu::BindingResource::TextureView(&transfer),
                wgpu::BindingResource::TextureView(&aux),
                pupil.as_entire_binding(),
                lrtf.as_entire_binding(),
            ],
        );
        let lens_group = self.lens_group(pipeline, &lens.params, &lens.surfaces);
        let channel_uniform = channels.map(|c| self.uniform("channels", bytemuck::bytes_of(c)));
        let seidel = self.uniform("seidel params", bytemuck::bytes_of(&lens.seidel));
        let shift_zero = [[0.0f32; 4]];
        let shifts: &[[f32; 4]] = match lens.film_shift.as_slice() {
            [] => &shift_zero,
            shifts => shifts,
        };
        let film_shift = self.storage("film shift", bytemuck::cast_slice(shifts));
        let seidel_group = self.bind_group(
            pipeline,
            3,
            &[seidel.as_entire_binding(), film_shift.as_entire_binding()],
        );
        // The frame's samples (offset, count, stride) in dispatches of at most
        // SAMPLES_PER_DISPATCH, each starting where the last one stopped.
        let mut done = 0;
        while done < frame.sample_count {
            let chunk = FrameParams {
                sample_offset: frame.sample_offset + done * frame.sample_stride,
                sample_count: SAMPLES_PER_DISPATCH.min(frame.sample_count - done),
                ..*frame
            };
            let uniform = self.uniform("frame", bytemuck::bytes_of(&chunk));
            let mut layer_entries = vec![
                uniform.as_entire_binding(),
                starts.as_entire_binding(),
                inverse_depths.as_entire_binding(),
                surfels.as_entire_binding(),
                bounds.as_entire_binding(),
                output.as_entire_binding(),
            ];
            if let Some(channel_uniform) = &channel_uniform {
                layer_entries.push(channel_uniform.as_entire_binding());
            }
            let layer_group = self.bind_group(pipeline, 1, &layer_entries);
            let mut encoder = self.device.create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_compute_pass(&Default::default());
                pass.set_pipeline(pipeline);
                pass.set_bind_group(0, &lrtf_group, &[]);
                pass.set_bind_group(1, &layer_group, &[]);
                pass.set_bind_group(2, &lens_group, &[]);
                pass.set_bind_group(3, &seidel_group, &[]);
                pass.dispatch_workgroups(
                    frame.width.div_ceil(WORKGROUP_SIZE),
                    frame.height.div_ceil(WORKGROUP_SIZE),
                    1,
                );
            }
            self.queue.submit([encoder.finish()]);
            done += chunk.sample_count;
        }
        if let Some(error) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Gpu(format!("dispatching IBRT: {error}")));
        }
        self.read_back(&output, output_bytes)
    }
}

fn compute_pipeline(device: &wgpu::Device, source: &str, entry: &str) -> wgpu::ComputePipeline {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(entry),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(entry),
        layout: None,
        module: &module,
        entry_point: Some(entry),
        compilation_options: Default::default(),
        cache: None,
    })
}
