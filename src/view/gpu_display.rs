//! The window's frame composed on the GPU where the viewer renders there: the running sums stay
//! on the renderer's device, `shaders/compose.wgsl` tone-maps them (split view, zone of focus and
//! the HUD's box included) into 8-bit rows, and the window copies those into its frame texture,
//! so a frame moves neither the layers nor the image between the CPU and the GPU. Its CPU twin
//! is [`Viewer::display`] with [`hud::draw_lines`]; the error overlay, which ranks every pixel's
//! error, is shown through the CPU twin.

use super::hud::{self, HUD_SHADE};
use super::{SPLIT_LINE, ViewError, Viewer};
use crate::render::RenderError;
use crate::render::gpu::GpuRenderer;
use std::sync::OnceLock;
use wgpu::util::DeviceExt;

/// The compose kernel's uniform block (`DisplayParams` in `shaders/compose.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct DisplayParams {
    pub width: u32,
    pub height: u32,
    /// Words per row of the composed frame: the width padded to 256-byte rows.
    pub row_words: u32,
    pub split: u32,
    /// Running sum to shown radiance.
    pub scale: f32,
    pub zone: u32,
    pub hud_width: u32,
    pub hud_height: u32,
}

/// The compose kernel's source, its constants written from the CPU twin's.
pub fn compose_shader() -> &'static str {
    static SOURCE: OnceLock<String> = OnceLock::new();
    SOURCE.get_or_init(|| {
        format!(
            "const SPLIT_LINE: u32 = {SPLIT_LINE}u;\nconst HUD_SHADE: f32 = {HUD_SHADE:?};\n{}",
            include_str!("shaders/compose.wgsl")
        )
    })
}

/// A frame composed on the GPU: RGBA8 rows of `bytes_per_row` bytes, `width` x `height` pixels.
pub struct ComposedFrame {
    pub buffer: wgpu::Buffer,
    pub bytes_per_row: u32,
    pub width: u32,
    pub height: u32,
}

/// The compose pipeline and its buffers on the viewer's renderer's device.
pub struct GpuComposer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    /// The composed frame and its size.
    frame: Option<(wgpu::Buffer, [u32; 2])>,
    /// The zone-of-focus bits and the viewer's restart they were computed after: the zone moves
    /// only when the settings do.
    zone: Option<(wgpu::Buffer, u64)>,
    /// The HUD's coverage, grown to the largest box yet.
    hud: wgpu::Buffer,
    /// One zero word bound where the zone or the twin has nothing to bind.
    placeholder: wgpu::Buffer,
}

impl GpuComposer {
    /// The compose pipeline on `gpu`'s device.
    pub fn new(gpu: &GpuRenderer) -> Result<GpuComposer, ViewError> {
        let (device, queue) = gpu.device();
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("compose"),
            source: wgpu::ShaderSource::Wgsl(compose_shader().into()),
        });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("compose"),
            layout: None,
            module: &module,
            entry_point: Some("compose"),
            compilation_options: Default::default(),
            cache: None,
        });
        if let Some(error) = pollster::block_on(scope.pop()) {
            return Err(gpu_error("building the compose pipeline", &error));
        }
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("display params"),
            size: size_of::<DisplayParams>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let word = |label| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: &[0; 4],
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            })
        };
        Ok(GpuComposer {
            hud: word("hud coverage"),
            placeholder: word("placeholder"),
            device: device.clone(),
            queue: queue.clone(),
            pipeline,
            params,
            frame: None,
            zone: None,
        })
    }

    /// Composes what `viewer` shows, with `hud_lines` in its box, from the sums it holds on the
    /// GPU. None where the viewer holds none there (the CPU twin, no frame rendered yet) or shows
    /// the error overlay: the caller shows [`Viewer::display`] instead.
    pub fn compose(
        &mut self,
        viewer: &Viewer,
        hud_lines: &[String],
    ) -> Result<Option<ComposedFrame>, ViewError> {
        let Some((view, twin)) = viewer.resident_sums() else {
            return Ok(None);
        };
        if viewer.overlay() && twin.is_some() {
            return Ok(None);
        }
        let settings = viewer.job().settings;
        let [width, height] = [settings.width, settings.height];
        let row_words = width.next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT / 4);
        let frame = match &self.frame {
            Some((buffer, size)) if *size == [width, height] => buffer.clone(),
            _ => {
                let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("composed frame"),
                    size: row_words as u64 * height as u64 * 4,
                    usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                    mapped_at_creation: false,
                });
                self.frame = Some((buffer.clone(), [width, height]));
                buffer
            }
        };
        if viewer.zone()
            && self
                .zone
                .as_ref()
                .is_none_or(|(_, at)| *at != viewer.restarts())
        {
            let sharp = viewer.focus_zone()?;
            let mut bits = vec![0u32; sharp.len().div_ceil(32).max(1)];
            for (i, _) in sharp.iter().enumerate().filter(|(_, s)| **s) {
                bits[i / 32] |= 1 << (i % 32);
            }
            let buffer = self
                .device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("zone of focus"),
                    contents: bytemuck::cast_slice(&bits),
                    usage: wgpu::BufferUsages::STORAGE,
                });
            self.zone = Some((buffer, viewer.restarts()));
        }
        let ([hud_width, hud_height], coverage) =
            hud::text_coverage(hud_lines, width, height).unwrap_or_default();
        let mut words = vec![0u32; coverage.len().div_ceil(4).max(1)];
        for (i, &c) in coverage.iter().enumerate() {
            words[i / 4] |= (c as u32) << (8 * (i % 4));
        }
        let hud_bytes = words.len() as u64 * 4;
        if self.hud.size() < hud_bytes {
            self.hud = self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("hud coverage"),
                size: hud_bytes,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            });
        }
        // The HUD's text is the one thing a frame uploads: its box, a byte a pixel.
        self.queue
            .write_buffer(&self.hud, 0, bytemuck::cast_slice(&words));
        let params = DisplayParams {
            width,
            height,
            row_words,
            split: twin.is_some() as u32,
            scale: viewer.display_scale(),
            zone: viewer.zone() as u32,
            hud_width,
            hud_height,
        };
        self.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        let zone = match (&self.zone, viewer.zone()) {
            (Some((bits, _)), true) => bits,
            _ => &self.placeholder,
        };
        let resources = [
            self.params.as_entire_binding(),
            view.sums().as_entire_binding(),
            twin.unwrap_or(view).sums().as_entire_binding(),
            zone.as_entire_binding(),
            self.hud.as_entire_binding(),
            frame.as_entire_binding(),
        ];
        let entries: Vec<wgpu::BindGroupEntry> = resources
            .into_iter()
            .enumerate()
            .map(|(i, resource)| wgpu::BindGroupEntry {
                binding: i as u32,
                resource,
            })
            .collect();
        let scope = self.device.push_error_scope(wgpu::ErrorFilter::Validation);
        let group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("compose"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &entries,
        });
        let mut encoder = self.device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.dispatch_workgroups(width.div_ceil(8), height.div_ceil(8), 1);
        }
        self.queue.submit([encoder.finish()]);
        if let Some(error) = pollster::block_on(scope.pop()) {
            return Err(gpu_error("composing the frame", &error));
        }
        Ok(Some(ComposedFrame {
            buffer: frame,
            bytes_per_row: row_words * 4,
            width,
            height,
        }))
    }
}

fn gpu_error(what: &str, error: &dyn std::fmt::Display) -> ViewError {
    ViewError::Render(RenderError::Gpu(format!("{what}: {error}")))
}
