//! The viewer's window: winit for events, a wgpu surface to show the frame (copied into a
//! texture and drawn letterboxed by one full-screen triangle), the HUD drawn into the frame.
//! Where the viewer renders on a GPU it renders on the window's own device and the frame is
//! composed there ([`super::gpu_display`]): nothing but the HUD's text is uploaded a frame, and
//! nothing is read back but for the split view's comparison and screenshots. On the CPU twin the
//! frame is uploaded as 8-bit pixels. The
//! [`Session`] is the same one the headless run drives; keys, clicks and dropped files become
//! [`Action`]s.

use super::gpu_display::{ComposedFrame, GpuComposer};
use super::script::Action;
use super::{Session, Step, ViewError, ViewEvent, hud, keys};
use crate::job::{FocusPointSpec, FocusTarget};
use crate::render::gpu::{self, GpuRenderer};
use std::path::PathBuf;
use std::sync::Arc;
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::dpi::{PhysicalPosition, PhysicalSize};
use winit::event::{ElementState, MouseButton, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::keyboard::{Key, NamedKey};
use winit::window::{Window, WindowId};

/// Runs `session` in a window until the script quits, the frame limit is reached or the window
/// is closed. `report` hears each event (screenshots, tables ready, failed bakes, refused
/// actions) as it happens.
pub fn run_window(
    session: &mut Session,
    title: &str,
    report: &mut dyn FnMut(&ViewEvent),
) -> Result<(), ViewError> {
    let event_loop = EventLoop::new().map_err(|e| ViewError::Window(e.to_string()))?;
    let mut app = App {
        session,
        title: title.to_string(),
        report,
        window: None,
        presenter: None,
        composer: None,
        cursor: None,
        error: None,
        screenshots: 0,
        shift: false,
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| ViewError::Window(e.to_string()))?;
    match app.error {
        Some(error) => Err(error),
        None => Ok(()),
    }
}

struct App<'a> {
    session: &'a mut Session,
    title: String,
    report: &'a mut dyn FnMut(&ViewEvent),
    window: Option<Arc<Window>>,
    presenter: Option<Presenter>,
    /// Composes frames on the GPU where the viewer renders there, on the presenter's device.
    composer: Option<GpuComposer>,
    cursor: Option<PhysicalPosition<f64>>,
    error: Option<ViewError>,
    screenshots: u32,
    shift: bool,
}

impl App<'_> {
    fn open(&mut self, event_loop: &ActiveEventLoop) -> Result<(), ViewError> {
        let settings = self.session.viewer.job().settings;
        let attributes = Window::default_attributes()
            .with_title(self.title.clone())
            .with_inner_size(PhysicalSize::new(settings.width, settings.height));
        let window = Arc::new(
            event_loop
                .create_window(attributes)
                .map_err(|e| ViewError::Window(e.to_string()))?,
        );
        let presenter = Presenter::new(event_loop, window.clone())?;
        let viewer = &mut self.session.viewer;
        if viewer.gpu().is_some() {
            let renderer = presenter.renderer();
            self.composer = Some(GpuComposer::new(&renderer)?);
            viewer.render_on(renderer);
        }
        window.request_redraw();
        self.window = Some(window);
        self.presenter = Some(presenter);
        Ok(())
    }

    fn fail(&mut self, event_loop: &ActiveEventLoop, error: ViewError) {
        self.error = Some(error);
        event_loop.exit();
    }

    fn flush_events(&mut self) {
        for event in self.session.viewer.take_events() {
            (self.report)(&event);
        }
    }

    /// Applies an interactive action; a refused one is reported, not fatal.
    fn act(&mut self, action: Action) {
        let result = match &action {
            Action::Screenshot(path) => self.session.viewer.screenshot(path),
            other => self.session.viewer.apply(other),
        };
        if let Err(error) = result {
            (self.report)(&ViewEvent::Refused(error.to_string()));
        }
        self.flush_events();
        if let Some(window) = &self.window {
            window.request_redraw();
        }
    }

    fn redraw(&mut self, event_loop: &ActiveEventLoop) {
        let step = match self.session.step() {
            Ok(step) => step,
            Err(error) => return self.fail(event_loop, error),
        };
        self.flush_events();
        if step == Step::Quit {
            event_loop.exit();
            return;
        }
        if let (Step::Window(request), Some(window)) = (&step, &self.window) {
            match request {
                Action::WindowSize([width, height]) => {
                    // The reply, if any, comes as a Resized event.
                    let _ = window.request_inner_size(PhysicalSize::new(*width, *height));
                }
                Action::Minimise(on) => window.set_minimized(*on),
                _ => {}
            }
        }
        if let Err(error) = self.show() {
            return self.fail(event_loop, error);
        }
        let busy = step != Step::Idle;
        if let Some(window) = &self.window {
            if busy {
                window.request_redraw();
            } else {
                // Nothing to render: wake for input only.
                event_loop.set_control_flow(ControlFlow::Wait);
            }
        }
    }

    /// Shows the viewer's frame with the HUD: composed on the GPU where the viewer renders there,
    /// else composed on the CPU and uploaded.
    fn show(&mut self) -> Result<(), ViewError> {
        let Some(presenter) = &mut self.presenter else {
            return Ok(());
        };
        let viewer = &self.session.viewer;
        let lines = viewer.hud_lines();
        let composed = match &mut self.composer {
            Some(composer) => composer.compose(viewer, &lines)?,
            None => None,
        };
        if let Some(frame) = composed {
            return presenter.show(FrameSource::Composed(frame));
        }
        let settings = viewer.job().settings;
        let (mut rgb, _) = viewer.display()?;
        hud::draw_lines(&mut rgb, settings.width, settings.height, &lines);
        presenter.show(FrameSource::Bytes {
            rgb: &rgb,
            width: settings.width,
            height: settings.height,
        })
    }

    /// The render pixel under window position `at`, through the letterbox.
    fn pixel_at(&self, at: PhysicalPosition<f64>) -> Option<[u32; 2]> {
        let presenter = self.presenter.as_ref()?;
        let settings = self.session.viewer.job().settings;
        let [x0, y0, w, h] = presenter.letterbox(settings.width, settings.height);
        let u = (at.x as f32 - x0) / w;
        let v = (at.y as f32 - y0) / h;
        ((0.0..1.0).contains(&u) && (0.0..1.0).contains(&v)).then_some({
            [
                (u * settings.width as f32) as u32,
                (v * settings.height as f32) as u32,
            ]
        })
    }

    /// The action of a key press, through the one key map ([`keys::key_action`]).
    fn key_action(&mut self, key: &Key, shift: bool) -> Option<Action> {
        let key = match key {
            Key::Named(NamedKey::ArrowLeft) => keys::Key::Left,
            Key::Named(NamedKey::ArrowRight) => keys::Key::Right,
            Key::Named(NamedKey::ArrowUp) => keys::Key::Up,
            Key::Named(NamedKey::ArrowDown) => keys::Key::Down,
            Key::Named(NamedKey::Escape) => keys::Key::Escape,
            Key::Character(text) => {
                let mut chars = text.chars();
                match (chars.next(), chars.next()) {
                    (Some(c), None) => keys::Key::Char(c.to_ascii_lowercase()),
                    _ => return None,
                }
            }
            _ => return None,
        };
        let action = keys::key_action(&self.session.viewer, key, shift, self.screenshots + 1)?;
        if matches!(action, Action::Screenshot(_)) {
            self.screenshots += 1;
        }
        Some(action)
    }
}

/// A dropped file: a scene by its extension (glTF, GLB, EXR), else a lens file.
fn dropped(path: PathBuf) -> Action {
    let extension = path
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    let text = path.to_string_lossy().into_owned();
    match extension.as_str() {
        "gltf" | "glb" | "exr" => Action::Scene(text),
        _ => Action::Lens(text),
    }
}

impl ApplicationHandler for App<'_> {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.window.is_none()
            && let Err(error) = self.open(event_loop)
        {
            self.fail(event_loop, error);
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested | WindowEvent::Destroyed => event_loop.exit(),
            WindowEvent::Resized(size) => {
                if let Some(presenter) = &mut self.presenter {
                    presenter.resize(size);
                }
                if let Some(window) = &self.window {
                    window.request_redraw();
                }
            }
            WindowEvent::RedrawRequested => self.redraw(event_loop),
            WindowEvent::CursorMoved { position, .. } => self.cursor = Some(position),
            WindowEvent::MouseInput {
                state: ElementState::Pressed,
                button: MouseButton::Left,
                ..
            } => {
                if let Some(pixel) = self.cursor.and_then(|at| self.pixel_at(at)) {
                    // Shift+click adds a focus point of a focal surface on what is there.
                    self.act(match self.shift {
                        true => Action::FocusPoint(FocusPointSpec {
                            pixel,
                            target: FocusTarget::Scene,
                            weight: 1.0,
                        }),
                        false => Action::Click(pixel),
                    });
                }
            }
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                let shift = self.shift;
                match self.key_action(&event.logical_key, shift) {
                    Some(Action::Quit) => event_loop.exit(),
                    Some(action) => self.act(action),
                    None => {}
                }
            }
            WindowEvent::ModifiersChanged(modifiers) => {
                self.shift = modifiers.state().shift_key();
            }
            WindowEvent::DroppedFile(path) => self.act(dropped(path)),
            _ => {}
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        // While a table bakes with nothing else to render, look again now and then.
        if self.session.viewer.bake_progress().is_some()
            && let Some(window) = &self.window
        {
            event_loop.set_control_flow(ControlFlow::WaitUntil(
                Instant::now() + Duration::from_millis(100),
            ));
            window.request_redraw();
        }
    }
}

const BLIT_SHADER: &str = r#"
@group(0) @binding(0) var frame_texture: texture_2d<f32>;
@group(0) @binding(1) var frame_sampler: sampler;

struct Varyings {
    @builtin(position) position: vec4<f32>,
    @location(0) uv: vec2<f32>,
}

// One triangle covering the viewport; uv runs 0..1 over it, y down.
@vertex
fn vertex_main(@builtin(vertex_index) index: u32) -> Varyings {
    let corner = vec2<f32>(f32((index << 1u) & 2u), f32(index & 2u));
    var out: Varyings;
    out.position = vec4<f32>(corner.x * 2.0 - 1.0, 1.0 - corner.y * 2.0, 0.0, 1.0);
    out.uv = corner;
    return out;
}

@fragment
fn fragment_main(in: Varyings) -> @location(0) vec4<f32> {
    return textureSample(frame_texture, frame_sampler, in.uv);
}
"#;

/// A frame to show: composed on the GPU, or 8-bit RGB pixels to upload.
enum FrameSource<'a> {
    Composed(ComposedFrame),
    Bytes {
        rgb: &'a [u8],
        width: u32,
        height: u32,
    },
}

/// The window's surface, device and the pipeline that draws a frame into it.
struct Presenter {
    surface: wgpu::Surface<'static>,
    device: wgpu::Device,
    queue: wgpu::Queue,
    /// The adapter's name and backend, for the renderer the viewer opens on this device.
    adapter_description: String,
    config: wgpu::SurfaceConfiguration,
    pipeline: wgpu::RenderPipeline,
    sampler: wgpu::Sampler,
    texture_format: wgpu::TextureFormat,
    /// The frame texture, remade when the render size changes.
    texture: Option<(wgpu::Texture, [u32; 2])>,
}

impl Presenter {
    fn new(event_loop: &ActiveEventLoop, window: Arc<Window>) -> Result<Presenter, ViewError> {
        let fail =
            |what: &str, e: &dyn std::fmt::Display| ViewError::Window(format!("{what}: {e}"));
        let descriptor = wgpu::InstanceDescriptor::new_with_display_handle(Box::new(
            event_loop.owned_display_handle(),
        ))
        .with_env();
        let instance = wgpu::Instance::new(descriptor);
        let size = window.inner_size();
        let surface = instance
            .create_surface(window)
            .map_err(|e| fail("creating the surface", &e))?;
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            compatible_surface: Some(&surface),
            ..Default::default()
        }))
        .map_err(|e| fail("no adapter can present to this window", &e))?;
        // The renderer's limits, so the viewer can render on this device too.
        let (device, queue) = gpu::request_device(&adapter, "lensbake view")
            .map_err(|e| fail("opening the presentation device", &e))?;
        let mut config = surface
            .get_default_config(&adapter, size.width.max(1), size.height.max(1))
            .ok_or_else(|| ViewError::Window("the surface does not suit this adapter".into()))?;
        let capabilities = surface.get_capabilities(&adapter);
        // The frame is sRGB-encoded already: an sRGB surface gets it through an sRGB texture
        // (decoded, then encoded again), a linear one gets the bytes as they are.
        if let Some(srgb) = capabilities.formats.iter().find(|f| f.is_srgb()) {
            config.format = *srgb;
        }
        let texture_format = if config.format.is_srgb() {
            wgpu::TextureFormat::Rgba8UnormSrgb
        } else {
            wgpu::TextureFormat::Rgba8Unorm
        };
        config.present_mode = wgpu::PresentMode::AutoVsync;
        surface.configure(&device, &config);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("blit"),
            source: wgpu::ShaderSource::Wgsl(BLIT_SHADER.into()),
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("blit"),
            layout: None,
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vertex_main"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: Default::default(),
            depth_stencil: None,
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fragment_main"),
                compilation_options: Default::default(),
                targets: &[Some(config.format.into())],
            }),
            multiview_mask: None,
            cache: None,
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        Ok(Presenter {
            surface,
            device,
            queue,
            adapter_description: gpu::describe(&adapter.get_info()),
            config,
            pipeline,
            sampler,
            texture_format,
            texture: None,
        })
    }

    /// The renderer on this device.
    fn renderer(&self) -> GpuRenderer {
        GpuRenderer::on_device(
            self.device.clone(),
            self.queue.clone(),
            self.adapter_description.clone(),
        )
    }

    fn resize(&mut self, size: PhysicalSize<u32>) {
        // A minimised window has no area: keep the old configuration until it comes back.
        if size.width == 0 || size.height == 0 {
            return;
        }
        self.config.width = size.width;
        self.config.height = size.height;
        self.surface.configure(&self.device, &self.config);
    }

    /// Where a `width` x `height` frame sits in the window, kept in proportion: x, y, w, h.
    fn letterbox(&self, width: u32, height: u32) -> [f32; 4] {
        let [sw, sh] = [self.config.width as f32, self.config.height as f32];
        let scale = (sw / width as f32).min(sh / height as f32);
        let [w, h] = [width as f32 * scale, height as f32 * scale];
        [(sw - w) / 2.0, (sh - h) / 2.0, w.max(1.0), h.max(1.0)]
    }

    /// Shows a frame.
    fn show(&mut self, source: FrameSource) -> Result<(), ViewError> {
        let [width, height] = match &source {
            FrameSource::Composed(frame) => [frame.width, frame.height],
            FrameSource::Bytes { width, height, .. } => [*width, *height],
        };
        let frame = match self.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(frame)
            | wgpu::CurrentSurfaceTexture::Suboptimal(frame) => frame,
            // Minimised, covered or mid-resize: skip this frame.
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                return Ok(());
            }
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                self.surface.configure(&self.device, &self.config);
                return Ok(());
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                return Err(ViewError::Window(
                    "acquiring the window's frame failed".into(),
                ));
            }
        };
        if self
            .texture
            .as_ref()
            .is_none_or(|(_, size)| *size != [width, height])
        {
            let texture = self.device.create_texture(&wgpu::TextureDescriptor {
                label: Some("frame"),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format: self.texture_format,
                usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
                view_formats: &[],
            });
            self.texture = Some((texture, [width, height]));
        }
        let Some((texture, _)) = &self.texture else {
            return Ok(());
        };
        let size = wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        };
        let mut encoder = self.device.create_command_encoder(&Default::default());
        match source {
            FrameSource::Composed(frame) => encoder.copy_buffer_to_texture(
                wgpu::TexelCopyBufferInfo {
                    buffer: &frame.buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(frame.bytes_per_row),
                        rows_per_image: Some(height),
                    },
                },
                texture.as_image_copy(),
                size,
            ),
            FrameSource::Bytes { rgb, .. } => {
                let rgba: Vec<u8> = rgb
                    .chunks_exact(3)
                    .flat_map(|p| [p[0], p[1], p[2], 255])
                    .collect();
                self.queue.write_texture(
                    texture.as_image_copy(),
                    &rgba,
                    wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(width * 4),
                        rows_per_image: Some(height),
                    },
                    size,
                );
            }
        }
        let view = texture.create_view(&Default::default());
        let group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(&self.sampler),
                },
            ],
        });
        let target = frame.texture.create_view(&Default::default());
        let [x, y, w, h] = self.letterbox(width, height);
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("blit"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &target,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        load: wgpu::LoadOp::Clear(wgpu::Color {
                            r: 0.02,
                            g: 0.02,
                            b: 0.02,
                            a: 1.0,
                        }),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                ..Default::default()
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &group, &[]);
            pass.set_viewport(x, y, w, h, 0.0, 1.0);
            pass.draw(0..3, 0..1);
        }
        self.queue.submit([encoder.finish()]);
        self.queue.present(frame);
        Ok(())
    }
}
