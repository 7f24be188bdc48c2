//! The interactive viewer's core (`lensbake view`): the settings, the progressive accumulation,
//! the actions a key, a click, a dropped file or a script line applies, and the scripted session
//! loop. The window ([`window`]) and the headless run share all of it; they differ only in how a
//! frame is shown.
//!
//! Accumulation spreads one render's lattice over frames: with `T` samples per pixel in all and
//! `N` a frame, frame `k` takes lattice points `o, o + T/N, o + 2T/N, ...` (a stratified share of
//! the lens) with `o` the `k`-th offset in bit-reversed order ([`crate::render::spread_order`]),
//! so the first frames together already cover the lens like a render with their samples; after
//! `T/N` frames the viewer holds exactly the samples `lensbake render --spp T` sums (only the
//! order of the f32 additions differs) and stops. Any change of settings restarts.
//!
//! A baked model's table is loaded or baked on a worker thread; the traced model is shown until
//! it is ready, so baking never blocks the window.

pub mod gpu_display;
pub mod hud;
pub mod keys;
pub mod script;
pub mod window;

use crate::job::{
    BackendChoice, BackendUsed, FocalSurfaceSpec, FocusMode, FocusPointSpec, FocusTarget, JobError,
    ModelChoice, Orbit, PreparedRender, RenderJob, RenderLens, SceneSpec, traced_twin,
};
use crate::lenses::{self, LensError};
use crate::lrtf::bake::BakeProgress;
use crate::model::{AberrationScale, FirstOrderModels, ModelKind};
use crate::paraxial::{CannotFocus, ObjectPosition};
use crate::prescription::StopShape;
use crate::prescription::formats::{LoadNote, LoadOptions};
use crate::render::camera::Camera;
use crate::render::chromatic::ChromaticMode;
use crate::render::focal_surface::DEFAULT_BETA;
use crate::render::focus::focus_zone;
use crate::render::gpu::{GpuRenderer, ResidentRender};
use crate::render::gpu_types::{LayerData, LayerIndex};
use crate::render::image::{RgbImage, srgb8, write_rgb8_png};
use crate::render::layers::LayeredDepthImage;
use crate::render::{Backend, RenderError, SampleShare, accumulate_share, resident_render};
use script::{Action, ScriptError, ScriptLine};
use std::borrow::Cow;
use std::cell::RefCell;
use std::collections::VecDeque;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Why the viewer could not do something.
#[derive(Debug, thiserror::Error)]
pub enum ViewError {
    #[error(transparent)]
    Job(#[from] JobError),
    #[error(transparent)]
    Render(#[from] RenderError),
    #[error(transparent)]
    Lens(#[from] LensError),
    #[error(transparent)]
    Script(#[from] ScriptError),
    #[error("pixel ({x}, {y}) is outside the {width}x{height} render")]
    OutsideRender {
        x: u32,
        y: u32,
        width: u32,
        height: u32,
    },
    #[error("the table bake's worker thread stopped without a result")]
    BakeWorker,
    #[error("{}:{line}: {cause}", file.display())]
    AtLine {
        file: PathBuf,
        line: usize,
        cause: Box<ViewError>,
    },
    #[error("window: {0}")]
    Window(String),
}

/// One render being accumulated: the prepared camera and layers (with the kernels' index of
/// them, derived once) and the running sums, on the CPU or held on the GPU (uploaded with the
/// render's first frame there, read back only when the CPU needs the image).
struct Accumulating {
    camera: Camera,
    layers: Arc<LayeredDepthImage>,
    index: Arc<LayerIndex>,
    sums: Vec<[f32; 4]>,
    resident: Option<ResidentRender>,
    /// The resident sums last read back and the frame count they hold: the HUD's comparison and
    /// the shown frame read them once a frame between them.
    read_back: RefCell<Option<(u32, Vec<[f32; 4]>)>>,
}

impl Accumulating {
    fn new(prepared: PreparedRender) -> Result<Accumulating, ViewError> {
        let index = LayerIndex::of(&prepared.layers)?;
        Ok(Accumulating {
            camera: prepared.camera,
            layers: Arc::new(prepared.layers),
            index: Arc::new(index),
            sums: Vec::new(),
            resident: None,
            read_back: RefCell::new(None),
        })
    }

    fn twin(&self, camera: Camera) -> Accumulating {
        Accumulating {
            camera,
            layers: self.layers.clone(),
            index: self.index.clone(),
            sums: Vec::new(),
            resident: None,
            read_back: RefCell::new(None),
        }
    }
}

/// A table loading or baking on a worker thread.
struct PendingBake {
    worker: JoinHandle<Result<PreparedRender, JobError>>,
    done: Arc<AtomicUsize>,
    total: Arc<AtomicUsize>,
}

/// Something the viewer did that its caller may want to tell the user about.
#[derive(Clone, Debug, PartialEq)]
pub enum ViewEvent {
    Screenshot(PathBuf),
    /// The baked model is ready (`baked_now`: its table was baked rather than found).
    TableReady {
        dir: PathBuf,
        baked_now: bool,
    },
    /// The background bake failed; the traced model stays on screen.
    BakeFailed(String),
    /// An interactive action was refused (the viewer kept its settings).
    Refused(String),
    /// An action was taken as near as the lens allows to what it asked (an f-number faster
    /// than wide open, a focus nearer than the lens reaches): what was done instead.
    Note(String),
}

/// The viewer: its settings (a [`RenderJob`] whose `samples_per_pixel` is the accumulation
/// target), what it is accumulating, and the renderer it holds.
pub struct Viewer {
    job: RenderJob,
    /// Samples per pixel asked for in all; the job's is this rounded up to a multiple of
    /// `spp_per_frame`.
    target_spp: u32,
    spp_per_frame: u32,
    split: bool,
    overlay: bool,
    /// Exposure of the shown image (EV): its radiance times 2^EV (display only, so changing it
    /// keeps the accumulation).
    exposure_ev: f64,
    /// Tint the pixels in the zone of focus ([`Viewer::focus_zone`]).
    zone: bool,
    gpu: Option<GpuRenderer>,
    backend: BackendUsed,
    /// The main view: the model asked for, or the traced model while a table bakes; in the
    /// split view, the baked (left) half.
    view: Accumulating,
    /// The split view's traced half, drawing the baked half's lens samples.
    twin: Option<Accumulating>,
    bake: Option<PendingBake>,
    frames_done: u32,
    /// Accumulations restarted since the viewer opened (a settings change restarts).
    restarts: u64,
    last_frame: Duration,
    /// Frames rendered since the viewer opened, and their time (whatever restarted since).
    rendered: (u64, Duration),
    /// Renders prepared since the viewer opened (film placed, pupil fitted, scene peeled).
    preparations: u64,
    events: Vec<ViewEvent>,
}

/// The model names in the order the `M` key steps through them.
pub const MODEL_CYCLE: [ModelKind; 5] = [
    ModelKind::Thin,
    ModelKind::Thick,
    ModelKind::Seidel,
    ModelKind::Traced,
    ModelKind::Baked,
];

impl Viewer {
    /// A viewer of `job` (its `samples_per_pixel` the accumulation target), rendering
    /// `spp_per_frame` samples per pixel a frame on the GPU the job's backend choice asks for (the
    /// CPU twin when `Auto` finds none; [`Viewer::backend`] says which, and why).
    pub fn new(mut job: RenderJob, spp_per_frame: u32) -> Result<Viewer, ViewError> {
        let (gpu, backend) = job.renderer()?;
        job.backend = match gpu {
            Some(_) => BackendChoice::Gpu,
            None => BackendChoice::Cpu,
        };
        let target_spp = job.settings.samples_per_pixel;
        let spp_per_frame = spp_per_frame.max(1);
        job.settings.samples_per_pixel = round_up(target_spp, spp_per_frame);
        job.settings.check()?;
        let (view, twin, bake) = build(&job, false)?;
        let mut viewer = Viewer {
            job,
            target_spp,
            spp_per_frame,
            split: false,
            overlay: false,
            exposure_ev: 0.0,
            zone: false,
            gpu,
            backend,
            view,
            twin,
            bake,
            frames_done: 0,
            restarts: 0,
            last_frame: Duration::ZERO,
            rendered: (0, Duration::ZERO),
            preparations: 1,
            events: Vec::new(),
        };
        viewer.restart();
        Ok(viewer)
    }

    /// The settings the viewer renders with.
    pub fn job(&self) -> &RenderJob {
        &self.job
    }

    pub fn backend(&self) -> &BackendUsed {
        &self.backend
    }

    pub fn spp_per_frame(&self) -> u32 {
        self.spp_per_frame
    }

    pub fn split(&self) -> bool {
        self.split
    }

    pub fn overlay(&self) -> bool {
        self.overlay
    }

    pub fn exposure_ev(&self) -> f64 {
        self.exposure_ev
    }

    pub fn zone(&self) -> bool {
        self.zone
    }

    /// Which pixels of the main view see a surface whose paraxial blur spot is under one pixel
    /// across (row-major): the zone of focus the overlay tints ([`focus_zone`]).
    pub fn focus_zone(&self) -> Result<Vec<bool>, ViewError> {
        let settings = &self.job.settings;
        Ok(focus_zone(
            &self.view.camera,
            &self.view.layers,
            settings.width,
            settings.height,
        )?)
    }

    /// The camera of the main view (the baked half in the split view).
    pub fn camera(&self) -> &Camera {
        &self.view.camera
    }

    /// The model on screen: the traced one while a baked model's table is on its way.
    pub fn shown_model(&self) -> ModelKind {
        self.view.camera.model.kind()
    }

    /// Samples per pixel accumulated so far, and the target.
    pub fn samples(&self) -> (u32, u32) {
        (
            self.frames_done * self.spp_per_frame,
            self.job.settings.samples_per_pixel,
        )
    }

    pub fn converged(&self) -> bool {
        self.frames_done >= self.shares()
    }

    /// Progress of a background bake (nodes done, nodes in all), if one is running.
    pub fn bake_progress(&self) -> Option<(usize, usize)> {
        self.bake.as_ref().map(|b| {
            (
                b.done.load(Ordering::Relaxed),
                b.total.load(Ordering::Relaxed),
            )
        })
    }

    /// Time the last frame took.
    pub fn last_frame(&self) -> Duration {
        self.last_frame
    }

    /// Mean time of the frames rendered since the viewer opened (None before the first).
    pub fn mean_frame(&self) -> Option<Duration> {
        let (frames, time) = self.rendered;
        (frames > 0).then(|| time / frames as u32)
    }

    /// Events since the last call.
    pub fn take_events(&mut self) -> Vec<ViewEvent> {
        std::mem::take(&mut self.events)
    }

    /// The object distance in focus (mm from the first vertex; None: infinity) on the film of
    /// the model on screen, by that model's own first-order equation (a thin model's film is
    /// not where the real lens's conjugates put it); None for a film no real object is focused
    /// on.
    pub fn focus_distance_mm(&self) -> Option<Option<f64>> {
        let camera = &self.view.camera;
        Some(
            match camera.model.paraxial().object_in_focus(camera.film_z)? {
                ObjectPosition::Infinite => None,
                ObjectPosition::Finite { distance } => Some(distance),
            },
        )
    }

    /// How many renders the viewer has prepared (placed the film, fitted the pupil, peeled the
    /// scene) since it opened: the costly part of a change of settings, which actions that
    /// change none of those inputs (samples per frame, the overlay, a value already set) skip.
    pub fn preparations(&self) -> u64 {
        self.preparations
    }

    /// A focal surface that starts from the plane in focus: a point at the image centre at the
    /// current focus distance, and `point`.
    fn surface_from_focus(&self, point: FocusPointSpec) -> FocalSurfaceSpec {
        let settings = &self.job.settings;
        let centre = FocusPointSpec {
            pixel: [settings.width / 2, settings.height / 2],
            target: match self.focus_distance_mm().flatten() {
                Some(mm) => FocusTarget::Distance(mm),
                None => FocusTarget::Distance(f64::INFINITY),
            },
            weight: 1.0,
        };
        FocalSurfaceSpec {
            points: vec![centre, point],
            beta: DEFAULT_BETA,
        }
    }

    /// The bundled lens after the one on screen (the first for a lens file or an ideal lens):
    /// what the window's L key loads.
    pub fn next_bundled_lens(&self) -> Action {
        let current = match &self.job.lens {
            RenderLens::Real(real) => real.source.origin.name(),
            RenderLens::Ideal { .. } => String::new(),
        };
        let at = lenses::BUNDLED.iter().position(|b| b.name == current);
        let next = at.map_or(0, |i| (i + 1) % lenses::BUNDLED.len());
        Action::Lens(lenses::BUNDLED[next].name.to_string())
    }

    /// The zoom position on screen and the lens's count of them ((1, 1) for a lens that does not
    /// zoom).
    pub fn zoom_position(&self) -> (usize, usize) {
        zoom_of(&self.job.lens)
    }

    fn shares(&self) -> u32 {
        self.job.settings.samples_per_pixel / self.spp_per_frame
    }

    fn restart(&mut self) {
        let pixels = match self.gpu {
            Some(_) => 0,
            None => self.job.settings.width as usize * self.job.settings.height as usize,
        };
        self.frames_done = 0;
        self.restarts += 1;
        for acc in std::iter::once(&mut self.view).chain(self.twin.as_mut()) {
            acc.sums.clear();
            acc.sums.resize(pixels, [0.0; 4]);
            acc.resident = None;
            acc.read_back.take();
        }
    }

    /// Renders the next frame's share of samples into every view; false when accumulation is
    /// complete (nothing rendered). Picks up a finished background bake first.
    pub fn frame(&mut self) -> Result<bool, ViewError> {
        self.poll_bake(false)?;
        if self.converged() {
            return Ok(false);
        }
        let started = Instant::now();
        let share = SampleShare::interleaved(
            self.frames_done,
            self.shares(),
            self.job.settings.samples_per_pixel,
        );
        let settings = &self.job.settings;
        for acc in std::iter::once(&mut self.view).chain(self.twin.as_mut()) {
            let layers = LayerData::with_index(&acc.layers, Cow::Borrowed(&acc.index));
            let tan_half = acc.layers.view.tan_half;
            match &self.gpu {
                Some(gpu) => {
                    let resident = match acc.resident.take() {
                        Some(resident) => resident,
                        None => resident_render(&acc.camera, &layers, tan_half, settings, gpu)?,
                    };
                    gpu.accumulate_resident(&resident, share.offset, share.count, share.stride)?;
                    acc.resident = Some(resident);
                }
                None => accumulate_share(
                    &acc.camera,
                    &layers,
                    tan_half,
                    settings,
                    share,
                    Backend::Cpu,
                    None,
                    &mut acc.sums,
                )?,
            }
        }
        self.frames_done += 1;
        self.last_frame = started.elapsed();
        self.rendered.0 += 1;
        self.rendered.1 += self.last_frame;
        Ok(true)
    }

    /// Blocks until a background bake finishes (scripts use it to make runs repeatable).
    pub fn wait_bake(&mut self) -> Result<(), ViewError> {
        self.poll_bake(true)
    }

    fn poll_bake(&mut self, wait: bool) -> Result<(), ViewError> {
        let finished = self
            .bake
            .as_ref()
            .is_some_and(|b| wait || b.worker.is_finished());
        if !finished {
            return Ok(());
        }
        let Some(pending) = self.bake.take() else {
            return Ok(());
        };
        let result = pending.worker.join().map_err(|_| ViewError::BakeWorker)?;
        match result {
            Ok(prepared) => {
                self.preparations += 1;
                let table = prepared.table.clone();
                let view = Accumulating::new(prepared)?;
                let twin = match self.split {
                    true => {
                        let camera = traced_twin(&self.job.lens, self.job.f_number, &view.camera)?;
                        Some(view.twin(camera))
                    }
                    false => None,
                };
                self.view = view;
                self.twin = twin;
                if let Some(table) = table {
                    self.events.push(ViewEvent::TableReady {
                        dir: table.dir,
                        baked_now: table.baked_now,
                    });
                }
                self.restart();
            }
            Err(error) => self.events.push(ViewEvent::BakeFailed(error.to_string())),
        }
        Ok(())
    }

    /// Applies a settings action (not `frames`, `wait-bake`, `screenshot` or `quit`, which the
    /// session loop runs). On an error the viewer keeps its previous settings and image. An
    /// f-number faster than the lens opens it wide open, and a focus nearer than the lens
    /// reaches (a lens switched to at a distance it cannot focus) goes to its nearest focus,
    /// each with a [`ViewEvent::Note`]. Only what the action changes is redone: samples per
    /// frame restart the accumulation on the prepared render, a value already set does nothing.
    pub fn apply(&mut self, action: &Action) -> Result<(), ViewError> {
        let mut job = self.job.clone();
        let mut split = self.split;
        let mut spp_per_frame = self.spp_per_frame;
        match action {
            Action::SppPerFrame(n) => spp_per_frame = *n,
            Action::Click(pixel) => {
                self.inside_render(*pixel)?;
                job.focus = FocusMode::Pixel(*pixel);
            }
            Action::FNumber(f) => job.f_number = self.within_lens(&job.lens, *f)?,
            Action::SeidelScale(factors) => {
                job.aberration_scale =
                    AberrationScale::from_array(*factors).map_err(JobError::from)?;
            }
            Action::FocalSurface(Some(spec)) => job.focus = FocusMode::Surface(spec.clone()),
            Action::FocalSurface(None) => {
                if matches!(job.focus, FocusMode::Surface(_)) {
                    let focus = self.focus_distance_mm().flatten().unwrap_or(f64::INFINITY);
                    job.focus = FocusMode::Distance(focus);
                }
            }
            Action::FocusPoint(point) => {
                self.inside_render(point.pixel)?;
                job.focus = FocusMode::Surface(match &job.focus {
                    FocusMode::Surface(spec) => {
                        let mut spec = spec.clone();
                        spec.points.push(*point);
                        spec
                    }
                    // The plane in focus now stays in focus at the image centre.
                    _ => self.surface_from_focus(*point),
                });
            }
            Action::Focus(mm) => job.focus = FocusMode::Distance(*mm),
            Action::Model(kind) => job.model = ModelChoice::Model(*kind),
            Action::Split(on) => split = *on,
            Action::ErrorOverlay(on) => {
                self.overlay = *on;
                return Ok(());
            }
            Action::Exposure(ev) => {
                self.exposure_ev = *ev;
                return Ok(());
            }
            Action::ZoneOverlay(on) => {
                self.zone = *on;
                return Ok(());
            }
            Action::SensorWidth(mm) => job.film_width_mm = Some(*mm),
            Action::Orbit(angles) => {
                job.orbit = (*angles != [0.0, 0.0]).then(|| Orbit {
                    // About what is in focus on the axis (2 m when the focus is at infinity).
                    pivot_mm: self
                        .focus_distance_mm()
                        .flatten()
                        .unwrap_or(crate::job::DEFAULT_FOCUS_MM),
                    angles_deg: *angles,
                });
            }
            Action::Blades(blades) => {
                let RenderLens::Real(real) = &job.lens else {
                    return Err(JobError::IdealHasNoSurfaces.into());
                };
                let shape = match *blades {
                    Some((count, rotation_deg, blade_curvature)) => StopShape::Blades {
                        count,
                        rotation_deg,
                        blade_curvature,
                    },
                    None => StopShape::Circle,
                };
                let lens = real.with_stop_shape(shape).map_err(LensError::from)?;
                job.lens = RenderLens::Real(Box::new(lens));
            }
            Action::Chromatic(on) => {
                job.chromatic = if *on {
                    ChromaticMode::On
                } else {
                    ChromaticMode::Off
                }
            }
            Action::Shift(mm) => job.shift_mm = *mm,
            Action::Tilt(deg) => job.tilt_deg = *deg,
            Action::Lens(spec) => {
                let lens = lenses::load(spec, &LoadOptions::default())?;
                job.lens = RenderLens::Real(Box::new(lens));
                job.f_number = None;
            }
            // The position on screen: nothing to read again (K on a lens with one position).
            Action::Zoom(position) if *position == zoom_of(&job.lens).0 => return Ok(()),
            Action::Zoom(position) => {
                let lens = at_zoom(&job.lens, *position)?;
                job.lens = RenderLens::Real(Box::new(lens));
                // The asked f-number stays where the new position reaches it.
                if let Some(f) = job.f_number {
                    job.f_number = self.within_lens(&job.lens, f)?;
                }
            }
            Action::Scene(spec) => job.scene = SceneSpec::parse(spec),
            Action::Frames(_)
            | Action::FocusPull { .. }
            | Action::WaitBake
            | Action::Screenshot(_)
            | Action::WindowSize(_)
            | Action::Minimise(_)
            | Action::Quit => {
                return Ok(());
            }
        }
        job.settings.samples_per_pixel = round_up(self.target_spp, spp_per_frame);
        job.settings.check()?;
        if split == self.split && job == self.job {
            if spp_per_frame != self.spp_per_frame {
                // The camera and the layers stay; only the lattice's shares change.
                self.spp_per_frame = spp_per_frame;
                self.restart();
            }
            return Ok(());
        }
        let (view, twin, bake) = match build(&job, split) {
            Err(ViewError::Job(error)) if error.cannot_focus().is_some() => {
                let refused = error.cannot_focus().cloned();
                let nearest = refused.and_then(|r| nearest_focus(&job, &r));
                let Some((refused, nearest_mm)) = refused.zip(nearest) else {
                    return Err(ViewError::Job(error));
                };
                job.focus = FocusMode::Distance(nearest_mm);
                let built = build(&job, split)?;
                self.events.push(ViewEvent::Note(format!(
                    "{} cannot focus at {} mm (its front focal point is {:.1} mm out); opened \
                     at its nearest focus, {nearest_mm:.1} mm (1:1)",
                    lens_name(&job.lens),
                    crate::limits::short(refused.distance_mm),
                    refused.front_focal_mm
                )));
                built
            }
            other => other?,
        };
        self.preparations += 1;
        self.job = job;
        self.split = split;
        self.spp_per_frame = spp_per_frame;
        self.view = view;
        self.twin = twin;
        // A bake for the old settings is left to finish on its own (its table stays on disk).
        self.bake = bake;
        self.restart();
        Ok(())
    }

    /// Refuses a pixel outside the render.
    fn inside_render(&self, [x, y]: [u32; 2]) -> Result<(), ViewError> {
        let [width, height] = [self.job.settings.width, self.job.settings.height];
        if x >= width || y >= height {
            return Err(ViewError::OutsideRender {
                x,
                y,
                width,
                height,
            });
        }
        Ok(())
    }

    /// Refuses an action that would fail whatever the settings when its turn comes: a lens
    /// that does not load, a scene file or a screenshot folder that does not exist, a click
    /// outside the render. A script is checked whole this way before its first frame.
    pub fn check(&self, action: &Action) -> Result<(), ViewError> {
        match action {
            Action::Lens(spec) => {
                lenses::load(spec, &LoadOptions::default())?;
            }
            Action::Scene(spec) => match SceneSpec::parse(spec) {
                SceneSpec::Demo => {}
                SceneSpec::Gltf(path) | SceneSpec::Exr(path) => {
                    std::fs::metadata(&path).map_err(|e| RenderError::Read {
                        path: path.clone(),
                        reason: e.to_string(),
                    })?;
                }
            },
            Action::Screenshot(path) => {
                let folder = path.parent().filter(|p| !p.as_os_str().is_empty());
                if folder.is_some_and(|folder| !folder.is_dir()) {
                    return Err(RenderError::Write {
                        path: path.clone(),
                        reason: "its folder does not exist".to_string(),
                    }
                    .into());
                }
            }
            Action::Click(pixel) => self.inside_render(*pixel)?,
            Action::FocusPoint(point) => self.inside_render(point.pixel)?,
            Action::FocalSurface(Some(spec)) => {
                for point in &spec.points {
                    self.inside_render(point.pixel)?;
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// The f-number to render `lens` at for an asked `f_number`: None (wide open) where it is
    /// faster than the lens, with a note (the HUD rounds, so even its own `f/2.03` can be a
    /// hair faster than the f/2.0304 it shows).
    fn within_lens(&mut self, lens: &RenderLens, f_number: f64) -> Result<Option<f64>, ViewError> {
        let Some(real) = lens.real() else {
            return Ok(Some(f_number));
        };
        let wide_open = FirstOrderModels::of(&real.system, None)
            .map_err(JobError::from)?
            .wide_open_f_number;
        if f_number >= wide_open {
            return Ok(Some(f_number));
        }
        self.events.push(ViewEvent::Note(format!(
            "f/{} is faster than {} wide open (f/{wide_open:.4}); using wide open",
            crate::limits::short(f_number),
            lens_name(lens)
        )));
        Ok(None)
    }

    /// Renders from now on with `gpu` (a renderer on the device the window presents with, so
    /// frames are composed where the sums are held) where the viewer renders on a GPU; on the
    /// CPU twin it changes nothing.
    pub fn render_on(&mut self, gpu: GpuRenderer) {
        if self.gpu.is_some() {
            self.gpu = Some(gpu);
            self.restart();
        }
    }

    /// The renderer, where the viewer renders on a GPU.
    pub fn gpu(&self) -> Option<&GpuRenderer> {
        self.gpu.as_ref()
    }

    /// Accumulations restarted since the viewer opened: what the shown image depends on besides
    /// its samples changes only with this.
    pub fn restarts(&self) -> u64 {
        self.restarts
    }

    /// The running sums held on the GPU: the main view's and the split view's traced twin's
    /// (None until each has rendered a frame there, and on the CPU).
    fn resident_sums(&self) -> Option<(&ResidentRender, Option<&ResidentRender>)> {
        let view = self.view.resident.as_ref()?;
        match &self.twin {
            Some(twin) => Some((view, Some(twin.resident.as_ref()?))),
            None => Some((view, None)),
        }
    }

    /// The factor from a pixel's running sum to the radiance shown: the exposure's 2^EV over
    /// the samples accumulated.
    fn display_scale(&self) -> f32 {
        let samples = (self.frames_done * self.spp_per_frame).max(1) as f32;
        2f64.powf(self.exposure_ev) as f32 / samples
    }

    /// The mean radiance accumulated so far in `acc` (read back from the GPU where it is held
    /// there).
    fn mean(&self, acc: &Accumulating) -> Result<RgbImage, ViewError> {
        let settings = &self.job.settings;
        let pixels = settings.width as usize * settings.height as usize;
        let scale = self.display_scale();
        let shown = |sums: &[[f32; 4]]| RgbImage {
            width: settings.width,
            height: settings.height,
            pixels: sums
                .iter()
                .map(|s| [s[0] * scale, s[1] * scale, s[2] * scale])
                .collect(),
        };
        match (&self.gpu, &acc.resident) {
            (Some(gpu), Some(resident)) => {
                let mut read_back = acc.read_back.borrow_mut();
                let fresh = read_back
                    .as_ref()
                    .is_some_and(|(frames, _)| *frames == self.frames_done);
                if !fresh {
                    *read_back = Some((self.frames_done, gpu.read_sums(resident)?));
                }
                Ok(shown(read_back.as_ref().map_or(&[], |(_, sums)| sums)))
            }
            (Some(_), None) => Ok(shown(&vec![[0.0; 4]; pixels])),
            (None, _) => Ok(shown(&acc.sums)),
        }
    }

    /// The accumulated render of the main view (the baked half's model in the split view), its
    /// radiance times the exposure's 2^EV. On the GPU this reads the sums back.
    pub fn image(&self) -> Result<RgbImage, ViewError> {
        self.mean(&self.view)
    }

    /// The accumulated traced twin of the split view, once the table is ready.
    pub fn twin_image(&self) -> Result<Option<RgbImage>, ViewError> {
        self.twin.as_ref().map(|twin| self.mean(twin)).transpose()
    }

    /// What the viewer shows, as 8-bit sRGB: the render tone-mapped as `render` writes its PNG;
    /// in the split view the baked render's left half beside the traced render's right half,
    /// a grey column between them;
    /// with the error overlay the error map of [`hud::error_map`]. Also the overlay's scale
    /// (radiance at the top of the colour bar) when it is on.
    pub fn display(&self) -> Result<(Vec<u8>, Option<f32>), ViewError> {
        let (mut bytes, scale) = self.composed()?;
        if self.zone {
            // A failed lookup shows no tint rather than no frame.
            let zone = self.focus_zone().unwrap_or_default();
            for (rgb, _) in bytes.chunks_mut(3).zip(zone).filter(|(_, sharp)| *sharp) {
                rgb.copy_from_slice(&zone_tint(rgb));
            }
        }
        Ok((bytes, scale))
    }

    /// [`Viewer::display`] before the zone-of-focus tint.
    fn composed(&self) -> Result<(Vec<u8>, Option<f32>), ViewError> {
        let width = self.job.settings.width as usize;
        let baked = self.image()?;
        let Some(traced) = self.twin_image()? else {
            return Ok((srgb8(&baked, 1.0), None));
        };
        if self.overlay {
            let (bytes, scale) = hud::error_map(&baked, &traced);
            return Ok((bytes, Some(scale)));
        }
        let mut pixels = baked.pixels;
        for (i, p) in pixels.iter_mut().enumerate() {
            if i % width >= width / 2 {
                *p = traced.pixels[i];
            }
        }
        let composed = RgbImage { pixels, ..baked };
        let mut bytes = srgb8(&composed, 1.0);
        // A grey line down the middle marks the split.
        for row in bytes.chunks_mut(width * 3) {
            row[width / 2 * 3..width / 2 * 3 + 3].fill(SPLIT_LINE);
        }
        Ok((bytes, None))
    }

    /// Writes [`Viewer::display`] as a PNG.
    pub fn screenshot(&mut self, path: &Path) -> Result<(), ViewError> {
        let (bytes, _) = self.display()?;
        write_rgb8_png(
            &bytes,
            self.job.settings.width,
            self.job.settings.height,
            path,
        )?;
        self.events.push(ViewEvent::Screenshot(path.to_path_buf()));
        Ok(())
    }

    /// The HUD's lines: frame time, samples, model, f-number, focus, lens, adapter.
    pub fn hud_lines(&self) -> Vec<String> {
        hud::lines(self)
    }
}

/// The nearest focus of `job`'s lens when `refused` says it cannot focus as near as asked: the
/// object at unit magnification, one focal length beyond the front focal point (a lens file
/// holds no focusing mechanism, so the limit is the usual macro one, the film one focal length
/// behind the rear focal plane).
fn nearest_focus(job: &RenderJob, refused: &CannotFocus) -> Option<f64> {
    let (first_order, _) = job.lens.first_order(job.f_number).ok()?;
    let focal_length_mm = first_order.thick.focal_length_mm;
    let nearest = refused.front_focal_mm + focal_length_mm;
    (nearest.is_finite() && nearest > refused.distance_mm).then_some(nearest)
}

/// The zoom position `lens` was read at and its count of positions; (1, 1) for a lens that does
/// not zoom.
fn zoom_of(lens: &RenderLens) -> (usize, usize) {
    lens.real()
        .and_then(|real| {
            real.source.loaded.notes.iter().find_map(|note| match note {
                LoadNote::ZoomPosition {
                    position, count, ..
                } => Some((*position, *count)),
                _ => None,
            })
        })
        .unwrap_or((1, 1))
}

/// `lens` read again from its file at zoom `position`, its stop's shape as the viewer set it.
fn at_zoom(lens: &RenderLens, position: usize) -> Result<crate::lenses::LoadedLens, ViewError> {
    let Some(real) = lens.real() else {
        return Err(JobError::IdealHasNoSurfaces.into());
    };
    let spec = match &real.source.origin {
        lenses::LensOrigin::File(path) => path.to_string_lossy().into_owned(),
        lenses::LensOrigin::Bundled(name) => (*name).to_string(),
    };
    let options = LoadOptions {
        format: Some(real.source.loaded.format),
        zoom_position: Some(position),
        ..LoadOptions::default()
    };
    let zoomed = lenses::load(&spec, &options)?;
    Ok(match real.stop_shape() {
        Some(shape) if zoomed.stop_shape() != Some(shape) => zoomed
            .with_stop_shape(shape.clone())
            .map_err(LensError::from)?,
        _ => zoomed,
    })
}

/// A lens's name for a note: the bundled name or file, or `ideal:<EFL>`.
fn lens_name(lens: &RenderLens) -> String {
    match lens {
        RenderLens::Ideal { focal_length_mm } => format!("ideal:{focal_length_mm}"),
        RenderLens::Real(real) => real.source.origin.name(),
    }
}

/// The split view's dividing column (8-bit grey).
const SPLIT_LINE: u8 = 128;

/// `value` rounded up to a multiple of `step`.
fn round_up(value: u32, step: u32) -> u32 {
    value.div_ceil(step).saturating_mul(step)
}

type Built = (Accumulating, Option<Accumulating>, Option<PendingBake>);

/// The views for `job`: its model, prepared now; or, for a baked model or the split view, the
/// traced model now and the baked one on a worker thread.
/// A pixel of the zone of focus: half way to green, so the image stays readable under it.
fn zone_tint(rgb: &[u8]) -> [u8; 3] {
    [rgb[0] / 2, rgb[1] / 2 + 128, rgb[2] / 2]
}

fn build(job: &RenderJob, split: bool) -> Result<Built, ViewError> {
    let asked = match job.model {
        ModelChoice::Model(kind) => kind,
        ModelChoice::ErrorBudgetPx(_) => ModelKind::Traced,
    };
    let mut job = job.clone();
    if split {
        // The traced twin draws the baked model's monochrome lens samples.
        job.chromatic = ChromaticMode::Off;
    }
    if asked != ModelKind::Baked && !split {
        let view = Accumulating::new(job.prepare(&|_| {})?)?;
        return Ok((view, None, None));
    }
    let traced = RenderJob {
        model: ModelChoice::Model(ModelKind::Traced),
        ..job.clone()
    };
    let view = Accumulating::new(traced.prepare(&|_| {})?)?;
    let baked = RenderJob {
        model: ModelChoice::Model(ModelKind::Baked),
        ..job
    };
    let done = Arc::new(AtomicUsize::new(0));
    let total = Arc::new(AtomicUsize::new(0));
    let (worker_done, worker_total) = (done.clone(), total.clone());
    let worker = std::thread::spawn(move || {
        baked.prepare(&|p: BakeProgress| {
            worker_done.store(p.done, Ordering::Relaxed);
            worker_total.store(p.total, Ordering::Relaxed);
        })
    });
    let pending = PendingBake {
        worker,
        done,
        total,
    };
    Ok((view, None, Some(pending)))
}

/// What one step of a [`Session`] did.
#[derive(Clone, Debug, PartialEq)]
pub enum Step {
    /// Rendered a frame (or, with accumulation complete, had nothing left to render).
    Frame { rendered: bool },
    /// Ran a script action.
    Action,
    /// The script said `quit`, or the frame limit is reached.
    Quit,
    /// The script is done and nothing is left to render or wait for.
    Idle,
    /// The script asks the window for a size or to be minimised (headless runs go on).
    Window(Action),
}

/// A viewer driven by a script and a frame limit: the one loop the window and the headless run
/// share.
pub struct Session {
    pub viewer: Viewer,
    script: VecDeque<ScriptLine>,
    script_file: PathBuf,
    frames_owed: u32,
    /// The distances (mm) a focus pull has still to render a frame at, next first.
    pull: VecDeque<f64>,
    frame_limit: Option<u64>,
    frames: u64,
}

impl Session {
    /// A session running `script` (read from `script_file`, which errors name) on `viewer`,
    /// checked whole first ([`Viewer::check`]): a line that would fail when its turn comes is
    /// refused before anything renders.
    pub fn new(
        viewer: Viewer,
        script: Vec<ScriptLine>,
        script_file: PathBuf,
        frame_limit: Option<u64>,
    ) -> Result<Session, ViewError> {
        for line in &script {
            viewer
                .check(&line.action)
                .map_err(|cause| ViewError::AtLine {
                    file: script_file.clone(),
                    line: line.line,
                    cause: Box::new(cause),
                })?;
        }
        Ok(Session {
            viewer,
            script: script.into(),
            script_file,
            frames_owed: 0,
            pull: VecDeque::new(),
            frame_limit,
            frames: 0,
        })
    }

    /// Frames rendered so far (including those with nothing left to accumulate).
    pub fn frames(&self) -> u64 {
        self.frames
    }

    /// Whether the script still has actions or owed frames.
    pub fn scripted(&self) -> bool {
        self.frames_owed > 0 || !self.pull.is_empty() || !self.script.is_empty()
    }

    /// Does the next thing: a frame the script owes, else the script's next action, else (with
    /// the script done) a frame while there is anything left to accumulate or a table baking.
    pub fn step(&mut self) -> Result<Step, ViewError> {
        if self.frame_limit.is_some_and(|limit| self.frames >= limit) {
            return Ok(Step::Quit);
        }
        if self.frames_owed > 0 {
            self.frames_owed -= 1;
            return self.frame();
        }
        if let Some(mm) = self.pull.pop_front() {
            self.viewer.apply(&Action::Focus(mm))?;
            return self.frame();
        }
        if let Some(next) = self.script.pop_front() {
            return self.run(&next).map_err(|cause| ViewError::AtLine {
                file: self.script_file.clone(),
                line: next.line,
                cause: Box::new(cause),
            });
        }
        if self.viewer.converged() && self.viewer.bake.is_none() {
            return Ok(if self.frame_limit.is_some() {
                self.frame()?
            } else {
                Step::Idle
            });
        }
        self.frame()
    }

    fn frame(&mut self) -> Result<Step, ViewError> {
        let rendered = self.viewer.frame()?;
        self.frames += 1;
        Ok(Step::Frame { rendered })
    }

    fn run(&mut self, line: &ScriptLine) -> Result<Step, ViewError> {
        match &line.action {
            Action::Frames(n) => self.frames_owed = *n,
            Action::FocusPull {
                from_mm,
                to_mm,
                frames,
            } => self.pull = focus_pull(*from_mm, *to_mm, *frames),
            Action::WaitBake => self.viewer.wait_bake()?,
            Action::Screenshot(path) => self.viewer.screenshot(path)?,
            Action::Quit => return Ok(Step::Quit),
            Action::WindowSize(_) | Action::Minimise(_) => {
                return Ok(Step::Window(line.action.clone()));
            }
            other => self.viewer.apply(other)?,
        }
        Ok(Step::Action)
    }
}

/// The distances (mm) of a focus pull's `frames` frames from `from_mm` to `to_mm`, both ends
/// included, evenly spaced in dioptres: the film moves nearly evenly (exactly so for a thin
/// lens far from macro), as a follow-focus wheel turns.
fn focus_pull(from_mm: f64, to_mm: f64, frames: u32) -> VecDeque<f64> {
    let steps = f64::from(frames.max(2) - 1);
    (0..frames.max(2))
        .map(|k| {
            let t = f64::from(k) / steps;
            1.0 / ((1.0 - t) / from_mm + t / to_mm)
        })
        .collect()
}
