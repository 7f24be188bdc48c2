//! The wgpu depth peeler: `shaders/peel.wgsl` as a render pipeline, one pass per layer.

use super::RenderError;
use super::gpu_types::{PeelData, PeelParams, PeelVertex};
use super::layers::{LayeredDepthImage, Surfel, View};
use wgpu::util::DeviceExt;

/// Radiance in rgb, depth in a: the layer format both the target and the previous layer use.
const LAYER_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// A device with the peeling pipeline built.
pub struct GpuPeeler {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    max_dimension: u32,
    /// The adapter's name and backend, for reports.
    pub adapter_description: String,
}

impl GpuPeeler {
    /// Opens the first GPU adapter (as [`super::gpu::GpuRenderer::new`] does) and builds the
    /// pipeline.
    pub fn new() -> Result<GpuPeeler, RenderError> {
        let (device, queue, adapter_description) = super::gpu::open_device("lensbake peel")?;
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let storage = |binding| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only: true },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("peel"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: None,
                    },
                    count: None,
                },
                storage(1),
                storage(2),
                storage(3),
                storage(4),
                wgpu::BindGroupLayoutEntry {
                    binding: 5,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        // Read with textureLoad only: rgba32float needs no filtering feature.
                        sample_type: wgpu::TextureSampleType::Float { filterable: false },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("peel"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("peel"),
            source: wgpu::ShaderSource::Wgsl(super::wgsl::peel_shader().into()),
        });
        let attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Uint32];
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("peel"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("peel_vertex"),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<PeelVertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &attributes,
                })],
            },
            // Facing was settled on the CPU (single-sided triangles seen from behind are gone).
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("peel_fragment"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: LAYER_FORMAT,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        if let Some(error) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Gpu(format!(
                "building the peeling pipeline: {error}"
            )));
        }
        let max_dimension = device.limits().max_texture_dimension_2d;
        Ok(GpuPeeler {
            device,
            queue,
            pipeline,
            layout,
            max_dimension,
            adapter_description,
        })
    }

    fn storage(&self, label: &str, contents: &[u8], usage: wgpu::BufferUsages) -> wgpu::Buffer {
        self.device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
    }

    fn target(&self, label: &str, format: wgpu::TextureFormat, view: &View) -> wgpu::Texture {
        self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width: view.width,
                height: view.height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        })
    }

    /// Peels `data` into at most `max_layers` layers of `view`, stopping at the first empty
    /// layer; exactly what [`super::raster::peel_cpu`] computes, up to the coverage of pixel
    /// centres within the GPU's sub-pixel snapping of an edge.
    pub fn peel(
        &self,
        data: &PeelData,
        view: View,
        max_layers: usize,
    ) -> Result<LayeredDepthImage, RenderError> {
        if view.width > self.max_dimension || view.height > self.max_dimension {
            return Err(RenderError::InvalidSetting(format!(
                "the layer view ({}x{}) exceeds this GPU's largest texture ({}); \
                 peel on the CPU or render smaller",
                view.width, view.height, self.max_dimension
            )));
        }
        let pixels = (view.width * view.height) as usize;
        if data.vertices.is_empty() {
            return Ok(LayeredDepthImage::from_layers(view, &[]));
        }
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let usage = wgpu::BufferUsages::STORAGE;
        let vertices = self.storage(
            "peel vertices",
            bytemuck::cast_slice(&data.vertices),
            wgpu::BufferUsages::VERTEX,
        );
        let triangles = self.storage(
            "peel triangles",
            bytemuck::cast_slice(&data.triangles),
            usage,
        );
        let materials = self.storage(
            "peel materials",
            bytemuck::cast_slice(&data.materials),
            usage,
        );
        let textures = self.storage("peel textures", bytemuck::cast_slice(&data.textures), usage);
        let texels = self.storage("peel texels", bytemuck::cast_slice(&data.texels), usage);
        let params = self.storage(
            "peel params",
            bytemuck::bytes_of(&data.params),
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        // Ping-pong: pass k draws into targets[k % 2] and reads the other.
        let targets = [
            self.target("layer a", LAYER_FORMAT, &view),
            self.target("layer b", LAYER_FORMAT, &view),
        ];
        let target_views = targets
            .each_ref()
            .map(|t| t.create_view(&Default::default()));
        let depth = self.target("peel depth", DEPTH_FORMAT, &view);
        let depth_view = depth.create_view(&Default::default());
        let groups = [1, 0].map(|previous: usize| {
            self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("peel"),
                layout: &self.layout,
                entries: &[
                    (0, params.as_entire_binding()),
                    (1, triangles.as_entire_binding()),
                    (2, materials.as_entire_binding()),
                    (3, textures.as_entire_binding()),
                    (4, texels.as_entire_binding()),
                    (
                        5,
                        wgpu::BindingResource::TextureView(&target_views[previous]),
                    ),
                ]
                .map(|(binding, resource)| wgpu::BindGroupEntry { binding, resource }),
            })
        });
        let row_bytes = (view.width * 16).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let readback = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("peel readback"),
            size: row_bytes as u64 * view.height as u64,
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut layers = Vec::new();
        for pass in 0..max_layers {
            let target = pass % 2;
            let pass_params = PeelParams {
                pass_index: pass as u32,
                ..data.params
            };
            self.queue
                .write_buffer(&params, 0, bytemuck::bytes_of(&pass_params));
            let mut encoder = self.device.create_command_encoder(&Default::default());
            {
                let mut render = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                    label: Some("peel pass"),
                    color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                        view: &target_views[target],
                        depth_slice: None,
                        resolve_target: None,
                        ops: wgpu::Operations {
                            load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                            store: wgpu::StoreOp::Store,
                        },
                    })],
                    depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                        view: &depth_view,
                        depth_ops: Some(wgpu::Operations {
                            load: wgpu::LoadOp::Clear(1.0),
                            store: wgpu::StoreOp::Discard,
                        }),
                        stencil_ops: None,
                    }),
                    timestamp_writes: None,
                    occlusion_query_set: None,
                    multiview_mask: None,
                });
                render.set_pipeline(&self.pipeline);
                render.set_bind_group(0, &groups[target], &[]);
                render.set_vertex_buffer(0, vertices.slice(..));
                render.draw(0..data.vertices.len() as u32, 0..1);
            }
            encoder.copy_texture_to_buffer(
                targets[target].as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: &readback,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(row_bytes),
                        rows_per_image: Some(view.height),
                    },
                },
                wgpu::Extent3d {
                    width: view.width,
                    height: view.height,
                    depth_or_array_layers: 1,
                },
            );
            self.queue.submit([encoder.finish()]);
            readback.map_async(wgpu::MapMode::Read, .., |_| {});
            self.device
                .poll(wgpu::PollType::wait_indefinitely())
                .map_err(|e| RenderError::Gpu(e.to_string()))?;
            let layer = {
                let mapped = readback
                    .get_mapped_range(..)
                    .map_err(|e| RenderError::Gpu(e.to_string()))?;
                let texels: &[[f32; 4]] = bytemuck::cast_slice(&mapped);
                let stride = (row_bytes / 16) as usize;
                let samples: Vec<Option<Surfel>> = (0..pixels)
                    .map(|pixel| {
                        let (x, y) = (pixel % view.width as usize, pixel / view.width as usize);
                        let t = texels[y * stride + x];
                        (t[3] > 0.0).then_some(Surfel {
                            depth_mm: t[3],
                            radiance: [t[0], t[1], t[2]],
                        })
                    })
                    .collect();
                samples
            };
            readback.unmap();
            if layer.iter().all(Option::is_none) {
                break;
            }
            layers.push(layer);
        }
        if let Some(error) = pollster::block_on(scope.pop()) {
            return Err(RenderError::Gpu(format!("peeling: {error}")));
        }
        Ok(LayeredDepthImage::from_layers(view, &layers))
    }
}
