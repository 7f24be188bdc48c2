//! The wgpu backend: runs `shaders/ibrt.wgsl` as a compute shader (modules assembled by
//! [`super::wgsl`]).

use super::RenderError;
use super::gpu_types::{ChannelParams, FrameParams, LayerData, LensData, LensParams, LensSurface};
use super::wgsl::{ibrt_shader, lens_trace_shader};
use std::sync::OnceLock;
use std::sync::atomic::{AtomicU64, Ordering};
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
    let (device, queue) = request_device(&adapter, label)?;
    Ok((device, queue, describe(&adapter.get_info())))
}

/// A device on `adapter` with the limits the renderer and the peeler need (a window's presenter
/// opens its device here too, so the renderer can draw on it).
pub(crate) fn request_device(
    adapter: &wgpu::Adapter,
    label: &str,
) -> Result<(wgpu::Device, wgpu::Queue), RenderError> {
    let limits = adapter.limits();
    pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
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
    .map_err(|e| RenderError::Gpu(e.to_string()))
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

pub(crate) fn describe(info: &wgpu::AdapterInfo) -> String {
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
    /// The monochrome `render` pipeline, built on first use (see [`GpuRenderer::open`]).
    pipeline: OnceLock<wgpu::ComputePipeline>,
    /// The ray-by-ray harness `trace_lens_rays`, built on first use (only tests ask for it).
    trace_pipeline: OnceLock<wgpu::ComputePipeline>,
    /// `render_chromatic`, built on first use so monochrome work never compiles it.
    chromatic_pipeline: OnceLock<wgpu::ComputePipeline>,
    /// The adapter's name and backend, for reports.
    pub adapter_description: String,
    transfers: Transfers,
}

impl GpuRenderer {
    /// Opens the first GPU adapter wgpu finds (honouring WGPU_BACKEND and friends), or
    /// `RenderError::NoAdapter` when there is none, and builds the IBRT pipeline.
    pub fn new() -> Result<GpuRenderer, RenderError> {
        let renderer = GpuRenderer::open()?;
        renderer.prepare()?;
        Ok(renderer)
    }

    /// [`GpuRenderer::new`] without building the IBRT pipeline, which is built on the first
    /// render: the viewer opens its renderer so, since its window may give it another device
    /// before the first frame (the pipeline takes seconds to build on a software adapter).
    pub fn open() -> Result<GpuRenderer, RenderError> {
        let (device, queue, adapter_description) = open_device("lensbake ibrt")?;
        Ok(GpuRenderer::on_device(device, queue, adapter_description))
    }

    /// A renderer on a device opened elsewhere with [`request_device`]'s limits (the viewer's
    /// window draws the renderer's sums on its own device this way); its pipelines are built on
    /// first use.
    pub(crate) fn on_device(
        device: wgpu::Device,
        queue: wgpu::Queue,
        adapter_description: String,
    ) -> GpuRenderer {
        GpuRenderer {
            device,
            queue,
            pipeline: OnceLock::new(),
            trace_pipeline: OnceLock::new(),
            chromatic_pipeline: OnceLock::new(),
            adapter_description,
            transfers: Transfers::default(),
        }
    }

    /// Builds the monochrome `render` pipeline now rather than on the first render (callers
    /// that time renders build it first).
    pub fn prepare(&self) -> Result<(), RenderError> {
        self.render_pipeline().map(|_| ())
    }

    /// The monochrome `render` pipeline, built the first time it is asked for.
    fn render_pipeline(&self) -> Result<&wgpu::ComputePipeline, RenderError> {
        self.pipeline_once(&self.pipeline, ibrt_shader(), "render")
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
        self.transfers.readbacks.fetch_add(1, Ordering::Relaxed);
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
        let resident = self.resident(frame, layers, lens, channels)?;
        self.accumulate_resident(
            &resident,
            frame.sample_offset,
            frame.sample_count,
            frame.sample_stride,
        )?;
        self.read_sums(&resident)
    }

    /// Uploads a render's layers and lens once, with running sums of zero on the GPU, so a
    /// progressive view adds each frame's samples ([`GpuRenderer::accumulate_resident`]) with no
    /// upload and reads the sums back only when it needs them on the CPU
    /// ([`GpuRenderer::read_sums`]). `frame`'s sample offset, count and stride are ignored.
    pub fn resident(
        &self,
        frame: &FrameParams,
        layers: &LayerData,
        lens: &LensData,
        channels: Option<&ChannelParams>,
    ) -> Result<ResidentRender, RenderError> {
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
            None => self.render_pipeline()?,
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
        let sums = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("radiance sum"),
            size: pixels * 16,
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
        // The frame uniform is written before each dispatch; the layer group binds it once.
        let frame_uniform = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame"),
            size: std::mem::size_of::<FrameParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let channel_uniform = channels.map(|c| self.uniform("channels", bytemuck::bytes_of(c)));
        let mut layer_entries = vec![
            frame_uniform.as_entire_binding(),
            starts.as_entire_binding(),
            inverse_depths.as_entire_binding(),
            surfels.as_entire_binding(),
            bounds.as_entire_binding(),
            sums.as_entire_binding(),
        ];
        if let Some(channel_uniform) = &channel_uniform {
            layer_entries.push(channel_uniform.as_entire_binding());
        }
        let layer_group = self.bind_group(pipeline, 1, &layer_entries);
        if let Some(error) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Gpu(format!("uploading a render: {error}")));
        }
        self.transfers.uploads.fetch_add(1, Ordering::Relaxed);
        Ok(ResidentRender {
            pipeline: pipeline.clone(),
            frame: *frame,
            frame_uniform,
            groups: [lrtf_group, layer_group, lens_group, seidel_group],
            sums,
            pixels,
        })
    }

    /// Adds `count` samples per pixel (lattice points `offset, offset + stride, ..`) to the
    /// resident render's sums, in dispatches of at most SAMPLES_PER_DISPATCH, each starting
    /// where the last one stopped, and returns when they are done. Only the frame's small
    /// uniform is written.
    pub fn accumulate_resident(
        &self,
        resident: &ResidentRender,
        offset: u32,
        count: u32,
        stride: u32,
    ) -> Result<(), RenderError> {
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let mut done = 0;
        while done < count {
            let chunk = FrameParams {
                sample_offset: offset + done * stride,
                sample_count: SAMPLES_PER_DISPATCH.min(count - done),
                sample_stride: stride,
                ..resident.frame
            };
            self.queue
                .write_buffer(&resident.frame_uniform, 0, bytemuck::bytes_of(&chunk));
            let mut encoder = self.device.create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_compute_pass(&Default::default());
                pass.set_pipeline(&resident.pipeline);
                for (i, group) in resident.groups.iter().enumerate() {
                    pass.set_bind_group(i as u32, group, &[]);
                }
                pass.dispatch_workgroups(
                    resident.frame.width.div_ceil(WORKGROUP_SIZE),
                    resident.frame.height.div_ceil(WORKGROUP_SIZE),
                    1,
                );
            }
            self.queue.submit([encoder.finish()]);
            done += chunk.sample_count;
        }
        if let Some(error) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Gpu(format!("dispatching IBRT: {error}")));
        }
        // Wait for the samples: a caller timing its frames times the GPU's work, and a viewer
        // submitting faster than the GPU renders would queue frames without bound.
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| RenderError::Gpu(e.to_string()))?;
        Ok(())
    }

    /// The resident render's per-pixel sums, read back to the CPU.
    pub fn read_sums(&self, resident: &ResidentRender) -> Result<Vec<[f32; 4]>, RenderError> {
        self.read_back(&resident.sums, resident.pixels * 16)
    }

    /// Bulk uploads (a render's layers and lens) and readbacks since this renderer opened: a
    /// progressive view that keeps its render resident does one upload per render and no
    /// readback per frame.
    pub fn transfers(&self) -> (u64, u64) {
        (
            self.transfers.uploads.load(Ordering::Relaxed),
            self.transfers.readbacks.load(Ordering::Relaxed),
        )
    }

    /// The device and queue, for work on the same device as the renderer's buffers (the
    /// viewer's window composes its frame from a resident render's sums this way).
    pub fn device(&self) -> (&wgpu::Device, &wgpu::Queue) {
        (&self.device, &self.queue)
    }
}

/// A render held on the GPU: its bind groups (layers, lens, table) and its running sums.
pub struct ResidentRender {
    pipeline: wgpu::ComputePipeline,
    frame: FrameParams,
    frame_uniform: wgpu::Buffer,
    groups: [wgpu::BindGroup; 4],
    sums: wgpu::Buffer,
    pixels: u64,
}

impl ResidentRender {
    /// The running sums (RGBA f32 per pixel, row-major), for a pass that reads them in place.
    pub fn sums(&self) -> &wgpu::Buffer {
        &self.sums
    }
}

/// Counts of bulk transfers, for [`GpuRenderer::transfers`].
#[derive(Default)]
struct Transfers {
    uploads: AtomicU64,
    readbacks: AtomicU64,
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
