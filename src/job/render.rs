//! [`RenderJob`]: a depth-of-field render from plain settings, with every decision on the way
//! (focus, colour, table, backend, model under an error budget) returned beside the image.

use super::focal::FocalSurfaceSpec;
use super::tables::{BakeFallback, TableNeeds, chromatic_table_dir, default_table_dir};
use super::{
    BudgetChoice, JobError, RenderLens, choose_for_render, find_covering_table, focus_of_film,
    load_or_bake,
};
use crate::lenses::LoadedLens;
use crate::lrtf::bake::{BakeProgress, chief_ray_film_radius};
use crate::lrtf::focus::distance_text;
use crate::lrtf::io::prescription_hash;
use crate::model::{
    AberrationScale, BakedLens, FirstOrderModels, LensModel, ModelError, ModelKind, PupilSampling,
    SeidelLens, TracedLens, pupil_film_radius,
};
use crate::paraxial::{FirstOrder, ImageInsideLens, ParaxialError};
use crate::realtime::layered::DEFAULT_LAYERS;
use crate::realtime::{
    KernelKey, KernelOrigin, KernelSettings, LayeredSettings, LensKernels, PostfxPath, layered,
    stored_or_traced,
};
use crate::render::camera::{Camera, FULL_FRAME_MM, Film, Focus};
use crate::render::chromatic::{
    CHANNELS, Chromatic, ChromaticMode, ColourSpread, default_wavelengths, wants_chromatic,
};
use crate::render::focal_surface::FocalSurface;
use crate::render::focus::{
    SensorPlacement, film_z_for_pixel, paraxial_focus_plane, real_ray_focus_plane,
    scene_point_under, spot_rms_on_sensor,
};
use crate::render::gltf_scene::{gltf_path, load_gltf};
use crate::render::gpu::{GpuRenderer, gpu_worth_using};
use crate::render::gpu_peel::GpuPeeler;
use crate::render::image::{RgbImage, read_exr_rgbz};
use crate::render::layers::LayeredDepthImage;
use crate::render::mesh::MeshScene;
use crate::render::raster::{Peeling, mesh_layer_view, peel_mesh};
use crate::render::scene::Scene;
use crate::render::{Backend, RenderError, RenderSettings, check_render_memory, render_layers};
use crate::trace::Tracer;
use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Film radii at which a traced render fits its effective pupil.
const PUPIL_NODES: usize = 32;

/// Object distance in focus when no focus mode is given (mm): the demo scene's chart.
pub const DEFAULT_FOCUS_MM: f64 = 2000.0;

/// Which model renders: one by name, or the cheapest within an image-error budget.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ModelChoice {
    Model(ModelKind),
    /// The cheapest model (and table size and precision) whose p99 image error, in pixels of this
    /// render, stays under this for the scene's depth range, film use and f-number.
    ErrorBudgetPx(f64),
}

/// What is rendered.
#[derive(Clone, Debug, PartialEq)]
pub enum SceneSpec {
    /// The built-in demo scene, as meshes.
    Demo,
    /// A glTF 2.0 file (.gltf or .glb; metres, seen from its first camera node).
    Gltf(PathBuf),
    /// An OpenEXR file with R, G, B and Z (mm from the entrance pupil) channels.
    Exr(PathBuf),
}

impl SceneSpec {
    /// `demo`, a glTF file by its extension, or else an RGB + Z EXR.
    pub fn parse(text: &str) -> SceneSpec {
        match (text, gltf_path(text)) {
            ("demo", _) => SceneSpec::Demo,
            (_, Some(path)) => SceneSpec::Gltf(path),
            _ => SceneSpec::Exr(PathBuf::from(text)),
        }
    }
}

/// Depth peeling of mesh scenes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PeelMode {
    /// Keep every surface.
    Plain,
    /// Skip surfaces hidden from the whole entrance pupil behind a nearer layer's pixel.
    Umbra,
}

/// Where the kernel (and the peeling of mesh scenes) runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum BackendChoice {
    Gpu,
    Cpu,
    /// The GPU when the best adapter is a hardware one, else the CPU twin (see
    /// [`gpu_worth_using`]); [`BackendUsed`] says which and why.
    Auto,
}

/// Where the film goes.
#[derive(Clone, Debug, PartialEq)]
pub enum FocusMode {
    /// Focus on the plane this far in front of the first vertex (mm).
    Distance(f64),
    /// The film this far behind the first vertex (mm).
    Sensor(f64),
    /// Focus on the nearest surface under output pixel (x, y), keeping the sensor's tilt.
    Pixel([u32; 2]),
    /// Tilt the sensor to focus on the plane through the scene points under three pixels,
    /// picked in the untilted frame focused at infinity (replaces the job's tilt).
    Points([[u32; 2]; 3]),
    /// Focus set per pixel by a focal surface through focus points (seed 004), their scene
    /// distances looked up in the frame focused at infinity; the film plane itself is focused
    /// where the surface passes the image centre (see [`crate::render::camera::PixelFocus`]).
    Surface(FocalSurfaceSpec),
}

/// A render: the lens, the model, the scene, the camera and the output, as plain data.
/// [`RenderJob::new`] fills in the command line's defaults.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderJob {
    pub lens: RenderLens,
    pub model: ModelChoice,
    /// Table directory for a baked model; None: the first table under
    /// `<tables_root>/<lens>/` that covers the render, else the default directory, baked there
    /// when missing.
    pub table: Option<PathBuf>,
    pub tables_root: PathBuf,
    /// Nodes per axis when a table has to be baked.
    pub bake_resolution: usize,
    pub scene: SceneSpec,
    pub peel: PeelMode,
    pub backend: BackendChoice,
    pub settings: RenderSettings,
    /// None: the lens wide open (f/2.8 for an ideal lens).
    pub f_number: Option<f64>,
    pub focus: FocusMode,
    /// Sensor width (mm), its height following the image's aspect; None: full frame, or the
    /// largest frame inside the lens's image circle where that circle is smaller than half a
    /// full frame's height ([`FilmSize`]).
    pub film_width_mm: Option<f64>,
    pub shift_mm: [f64; 2],
    /// See [`Film::tilt_deg`].
    pub tilt_deg: [f64; 2],
    pub chromatic: ChromaticMode,
    /// R, G, B; None: the C line, the design wavelength, the F line.
    pub wavelengths_nm: Option<[f64; CHANNELS]>,
    /// Which statement of the postfx gather renders (the model postfx only).
    pub postfx_path: PostfxPath,
    /// Depth layers of the layered model (the model layered only).
    pub layers: usize,
    /// Factors on the Seidel sums, for effect (the Seidel model only: the traced and baked
    /// models take their aberrations from the surfaces, see docs/focal-surface.md).
    pub aberration_scale: AberrationScale,
    /// The camera orbited about a point on its axis (mesh scenes: the demo and glTF files).
    pub orbit: Option<Orbit>,
}

/// A camera orbit: `angles_deg` (yaw to the camera's right, pitch up) about the point on the
/// axis `pivot_mm` in front of the first vertex ([`MeshScene::orbited`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Orbit {
    pub pivot_mm: f64,
    pub angles_deg: [f64; 2],
}

impl RenderJob {
    /// The traced model of `lens` on the demo scene, 800 x 600 at 64 samples per pixel, focused
    /// at 2 m, wide open, colour decided automatically, on the GPU when there is one.
    pub fn new(lens: RenderLens) -> RenderJob {
        RenderJob {
            lens,
            model: ModelChoice::Model(ModelKind::Traced),
            table: None,
            tables_root: PathBuf::from(super::tables::DEFAULT_TABLES_ROOT),
            bake_resolution: 64,
            scene: SceneSpec::Demo,
            peel: PeelMode::Umbra,
            backend: BackendChoice::Auto,
            settings: RenderSettings {
                width: 800,
                height: 600,
                samples_per_pixel: 64,
                seed: 1,
                max_layers: 8,
            },
            f_number: None,
            focus: FocusMode::Distance(DEFAULT_FOCUS_MM),
            film_width_mm: None,
            shift_mm: [0.0, 0.0],
            tilt_deg: [0.0, 0.0],
            chromatic: ChromaticMode::Auto,
            wavelengths_nm: None,
            postfx_path: PostfxPath::Fast,
            layers: DEFAULT_LAYERS,
            aberration_scale: AberrationScale::AS_DESIGNED,
            orbit: None,
        }
    }
}

/// How the sensor's size was chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum FilmSize {
    /// The job's `film_width_mm`.
    Asked,
    /// Full frame, cropped to the image's aspect.
    FullFrame,
    /// The largest frame inside the lens's image circle, `diameter_mm` across at infinity focus
    /// (the real chief ray at the largest field it passes), which is smaller than half a full
    /// frame's height: a phone or machine-vision lens would light a speck of a full frame.
    ImageCircle { diameter_mm: f64 },
}

/// The scene as the job peeled it.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneReport {
    /// Triangles of a mesh scene (None for an EXR).
    pub triangles: Option<usize>,
    /// The GPU adapter that peeled a mesh scene; None: the CPU (or an EXR, which is not peeled).
    pub peeled_on_gpu: Option<String>,
}

/// The sensor plane through three picked scene points.
#[derive(Clone, Debug, PartialEq)]
pub struct FocusPlaneReport {
    /// The scene points under the picked pixels (lens frame, mm).
    pub objects: [[f64; 3]; 3],
    /// The placement used.
    pub placement: SensorPlacement,
    /// For a traced or baked model of a real lens: the real-ray and the paraxial placements,
    /// each with the RMS spot radius (um) of the three points on it.
    pub compared: Option<[(SensorPlacement, [f64; 3]); 2]>,
}

/// Why the render is or is not chromatic.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ChromaticReason {
    /// Asked off.
    Off,
    /// The Seidel model is monochrome.
    SeidelModel,
    /// The real-time models' kernels are traced at the design wavelength.
    RealtimeModel(ModelKind),
    /// An ideal lens has no glass.
    IdealLens,
    /// The lens's colour spread on this film, in output pixels.
    Spread {
        lateral_px: f64,
        axial_blur_px: f64,
        disperses: bool,
    },
}

/// The colour decision: R, G, B wavelengths when chromatic, and why.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChromaticDecision {
    pub wavelengths_nm: Option<[f64; CHANNELS]>,
    pub reason: ChromaticReason,
}

/// The table a baked render read.
#[derive(Clone, Debug, PartialEq)]
pub struct TableUse {
    pub dir: PathBuf,
    /// Baked by this job (it was missing).
    pub baked_now: bool,
    /// Film radius the table covers, and the one the sensor reaches (mm): rays from beyond the
    /// table's render black.
    pub covered_film_radius_mm: f64,
    pub needed_film_radius_mm: f64,
}

/// The layers the kernel traced.
#[derive(Clone, Debug, PartialEq)]
pub struct PeelReport {
    pub layers: usize,
    pub view_size: [u32; 2],
    /// For a mesh scene: how it was peeled and the surfels kept.
    pub mesh: Option<(PeelMode, usize)>,
    pub time: Duration,
}

/// Where the kernel ran.
#[derive(Clone, Debug, PartialEq)]
pub enum BackendUsed {
    Gpu {
        adapter: String,
    },
    /// The CPU twin; `gpu_unavailable` says why when the GPU was wanted if present.
    Cpu {
        gpu_unavailable: Option<String>,
    },
}

/// A finished render and what it decided.
#[derive(Clone, Debug)]
pub struct Rendered {
    pub image: RgbImage,
    /// The camera, the layers and every decision before the kernel ran.
    pub prepared: PreparedRender,
    pub backend: BackendUsed,
    pub trace_time: Duration,
}

/// A job made ready to render: its camera, its peeled layers and every decision but the backend
/// ([`RenderJob::prepare`]). A progressive viewer keeps one and renders its samples a share at a
/// time on a renderer it holds; [`RenderJob::run`] renders all of them at once.
#[derive(Clone, Debug)]
pub struct PreparedRender {
    /// The camera rendered through (model, film and its placement, colour channels).
    pub camera: Camera,
    pub film_size: FilmSize,
    pub layers: LayeredDepthImage,
    pub scene: SceneReport,
    pub focus_plane: Option<FocusPlaneReport>,
    pub budget: Option<BudgetChoice>,
    pub chromatic: ChromaticDecision,
    pub table: Option<TableUse>,
    pub peel: PeelReport,
    /// For the real-time models: the lens kernels for this camera and these layers.
    pub kernels: Option<PreparedKernels>,
}

/// The real-time models' lens kernels: traced once per lens, f-number, focus, view and depth
/// range, and kept under the tables root (`<tables>/<lens>/kernels/`) for the next render.
#[derive(Clone, Debug)]
pub struct PreparedKernels {
    /// The real-time model that filters with them.
    pub model: ModelKind,
    pub kernels: LensKernels,
    /// Time to read or trace them.
    pub time: Duration,
    pub origin: KernelOrigin,
}

impl PreparedRender {
    /// The model that renders: the camera's, or the real-time model the job traced lens
    /// kernels for.
    pub fn kind(&self) -> ModelKind {
        match &self.kernels {
            Some(prepared) => prepared.model,
            None => self.camera.model.kind(),
        }
    }
}

enum SceneSource {
    /// The demo (as meshes) or a glTF file, peeled by rasterisation.
    Mesh {
        scene: MeshScene,
        peel: PeelMode,
        gpu: Option<GpuPeeler>,
    },
    Exr(PathBuf),
}

impl SceneSource {
    fn layers(
        &self,
        camera: &Camera,
        settings: &RenderSettings,
    ) -> Result<LayeredDepthImage, RenderError> {
        match self {
            SceneSource::Mesh { scene, peel, gpu } => {
                let peeling = match peel {
                    PeelMode::Plain => Peeling::Plain,
                    PeelMode::Umbra => Peeling::umbra_for(camera),
                };
                let view = mesh_layer_view(camera, settings, scene)?;
                check_render_memory(settings, &view, 0)?;
                let layers = peel_mesh(scene, view, peeling, settings.max_layers, gpu.as_ref())?;
                if layers.depth_range().is_none() {
                    return Err(RenderError::NothingInView(scene.why_unseen(&view)));
                }
                Ok(layers)
            }
            SceneSource::Exr(path) => {
                read_exr_rgbz(path, camera.eye_z(), camera.half_field_tangents())
            }
        }
    }
}

impl RenderJob {
    /// Runs the job: places the film, decides colour and (under a budget) the model, finds or
    /// bakes a table, peels the scene and renders it.
    pub fn run(&self) -> Result<Rendered, JobError> {
        let prepared = self.prepare(&|_| {})?;
        let (gpu, backend) = self.renderer()?;
        // Pipelines are built before the clock starts.
        if let Some(g) = &gpu {
            match prepared.camera.chromatic {
                Some(_) => g.prepare_chromatic()?,
                None => g.prepare()?,
            }
        }
        let started = Instant::now();
        let kernel = match gpu {
            Some(_) => Backend::Gpu,
            None => Backend::Cpu,
        };
        let image = match &prepared.kernels {
            Some(prepared_kernels) if prepared_kernels.model == ModelKind::Layered => layered(
                &prepared.camera,
                &prepared.layers,
                &prepared_kernels.kernels,
                &LayeredSettings {
                    layers: self.layers,
                    peeled_to: self.settings.max_layers,
                },
                self.settings.width,
                self.settings.height,
            )?,
            Some(prepared_kernels) => self.postfx_path.render(
                &prepared.camera,
                &prepared.layers,
                &prepared_kernels.kernels,
                self.settings.width,
                self.settings.height,
            )?,
            None => render_layers(
                &prepared.camera,
                &prepared.layers,
                &self.settings,
                kernel,
                gpu.as_ref(),
            )?,
        };
        Ok(Rendered {
            image,
            prepared,
            backend,
            trace_time: started.elapsed(),
        })
    }

    /// Everything [`RenderJob::run`] does before the kernel runs: the film placed, colour and
    /// model decided, the table found or baked (reporting to `progress`), the scene peeled.
    pub fn prepare(
        &self,
        progress: &(dyn Fn(BakeProgress) + Sync),
    ) -> Result<PreparedRender, JobError> {
        // Focus is found, and the budget chosen, with the model asked for (traced by default).
        let asked = match self.model {
            ModelChoice::Model(kind) => kind,
            ModelChoice::ErrorBudgetPx(_) => ModelKind::Traced,
        };
        if matches!(self.lens, RenderLens::Ideal { .. }) && asked.needs_surfaces() {
            return Err(JobError::IdealHasNoSurfaces);
        }
        let (first_order, f_number) = self.lens.first_order(self.f_number)?;
        // Focus is found with the first-order model; the other models use the thick one.
        let model = match asked {
            ModelKind::Thin => LensModel::Thin(first_order.thin.clone()),
            _ => LensModel::Thick(first_order.thick.clone()),
        };
        let settings = &self.settings;
        let (sized, film_size) = self.film(&first_order)?;
        let film = Film {
            shift_mm: self.shift_mm,
            tilt_deg: self.tilt_deg,
            ..sized
        };
        let (source, scene) = self.scene_source()?;
        let (focus, film, focus_plane, surface) =
            self.place_film(&model, film, &source, &first_order, f_number, asked)?;
        // The focal surface's shifts are relative to the plane focused at the reference.
        let with_surface = |camera: Camera| -> Result<Camera, RenderError> {
            match (&surface, focus) {
                (Some(surface), Focus::ObjectDistance(reference_mm)) => {
                    camera.with_focal_surface(surface.clone(), reference_mm)
                }
                _ => Ok(camera),
            }
        };
        let camera = with_surface(Camera::new(model, film, focus)?)?;
        // A budget measures every model against the exact trace (`asked`), which needs the film
        // behind the lens as much as a traced render does.
        if !matches!(asked, ModelKind::Thin | ModelKind::Thick)
            && let Some(real) = self.lens.real()
        {
            film_behind_lens(real, camera.film_z, focus)?;
        }
        // An ideal lens under a budget was refused above: it has nothing to trace.
        let budget = match (self.model, self.lens.real()) {
            (ModelChoice::Model(_), _) | (_, None) => None,
            (ModelChoice::ErrorBudgetPx(budget), Some(real)) => {
                let layers = source.layers(&camera, settings)?;
                Some(choose_for_render(
                    real,
                    &camera,
                    &layers,
                    settings.width,
                    f_number,
                    budget,
                )?)
            }
        };
        let kind = budget.as_ref().map_or(asked, |b| b.choice.model);
        let chromatic = self.chromatic_decision(kind, &first_order, &camera)?;
        let wavelengths = chromatic.wavelengths_nm;
        let chosen_table = budget.as_ref().and_then(|b| b.choice.table.clone());
        let (camera, table) = match (kind, &self.lens) {
            (ModelKind::Thin, _) => (
                Camera::new(LensModel::Thin(first_order.thin.clone()), film, focus)?,
                None,
            ),
            (ModelKind::Thick, _) => (
                Camera::new(LensModel::Thick(first_order.thick.clone()), film, focus)?,
                None,
            ),
            (_, RenderLens::Ideal { .. }) => return Err(JobError::IdealHasNoSurfaces),
            (
                ModelKind::Traced | ModelKind::Postfx | ModelKind::Layered,
                RenderLens::Real(real),
            ) => {
                let traced = TracedLens::fitted(
                    &real.system,
                    &first_order,
                    f_number,
                    camera.film_z,
                    sensor_film_radius(real, &camera),
                    PUPIL_NODES,
                )?;
                let model = LensModel::Traced(Box::new(traced));
                (Camera::new(model, film, Focus::FilmZ(camera.film_z))?, None)
            }
            (ModelKind::Seidel, RenderLens::Real(real)) => {
                let focus_mm = focus_of_film(real, camera.film_z)?;
                let seidel = SeidelLens::in_focus(&real.system, &first_order, focus_mm)?
                    .scaled(self.aberration_scale);
                let model = LensModel::Seidel(Box::new(seidel));
                (Camera::new(model, film, Focus::FilmZ(camera.film_z))?, None)
            }
            (ModelKind::Baked, RenderLens::Real(real)) => {
                // The error budget's table holds the design wavelength for the untilted film; a
                // chromatic render or a tilted sensor needs its own.
                let chosen = chosen_table
                    .filter(|_| wavelengths.is_none() && camera.film_off_plane() == 0.0);
                let (baked, table) = self.baked_lens(
                    real,
                    &first_order,
                    f_number,
                    &camera,
                    wavelengths,
                    chosen,
                    progress,
                )?;
                let film_z = baked.film_z();
                let model = LensModel::Baked(Box::new(baked));
                let camera = Camera::new(model, film, Focus::FilmZ(film_z))
                    .inspect_err(|_| discard_if_baked_now(Some(&table)))?;
                (camera, Some(table))
            }
        };
        let camera = with_surface(camera).inspect_err(|_| discard_if_baked_now(table.as_ref()))?;
        let peeled = || -> Result<_, JobError> {
            let camera = match (wavelengths, &self.lens) {
                (Some(nm), RenderLens::Real(real)) => {
                    let channels = Chromatic::for_camera(
                        &camera,
                        &real.system,
                        &first_order,
                        nm,
                        PUPIL_NODES,
                    )?;
                    camera.with_chromatic(channels)?
                }
                _ => camera,
            };
            let started = Instant::now();
            let ldi = source.layers(&camera, settings)?;
            Ok((camera, ldi, started.elapsed()))
        };
        let (camera, ldi, peel_time) =
            peeled().inspect_err(|_| discard_if_baked_now(table.as_ref()))?;
        let peel = PeelReport {
            layers: ldi.layer_count(),
            view_size: [ldi.view.width, ldi.view.height],
            mesh: match &source {
                SceneSource::Mesh { peel, .. } => Some((*peel, ldi.surfel_count())),
                SceneSource::Exr(_) => None,
            },
            time: peel_time,
        };
        let kernels = match (kind, &self.lens) {
            (ModelKind::Postfx | ModelKind::Layered, RenderLens::Real(real)) => {
                let started = Instant::now();
                let [near, far] = ldi.depth_range().ok_or(RenderError::EmptyScene)?;
                let key = KernelKey {
                    prescription_hash: prescription_hash(&real.system.prescription),
                    f_number,
                    film_z: camera.film_z,
                    view: ldi.view,
                    depth_range_mm: [near as f64, far as f64],
                    settings: KernelSettings::default(),
                };
                let folder = self
                    .tables_root
                    .join(real.source.origin.name())
                    .join("kernels");
                let (kernels, origin) = stored_or_traced(&key, &folder, || {
                    LensKernels::trace(&camera, &ldi.view, key.depth_range_mm, &key.settings)
                })?;
                Some(PreparedKernels {
                    model: kind,
                    kernels,
                    time: started.elapsed(),
                    origin,
                })
            }
            _ => None,
        };
        Ok(PreparedRender {
            camera,
            film_size,
            layers: ldi,
            scene,
            focus_plane,
            budget,
            chromatic,
            table,
            peel,
            kernels,
        })
    }

    /// The sensor's size ([`RenderJob::film_width_mm`]), untilted and unshifted.
    fn film(&self, first_order: &FirstOrderModels) -> Result<(Film, FilmSize), JobError> {
        let [width, height] = [self.settings.width, self.settings.height];
        if let Some(width_mm) = self.film_width_mm {
            crate::limits::check_length("the film width (mm)", width_mm)
                .map_err(RenderError::from)?;
            return Ok((Film::of_width(width_mm, width, height), FilmSize::Asked));
        }
        let full_frame = (Film::full_frame_for(width, height), FilmSize::FullFrame);
        let RenderLens::Real(real) = &self.lens else {
            return Ok(full_frame);
        };
        let design = real.system.at(real.system.design_wavelength_nm());
        let thick = &first_order.thick;
        let focal_plane = thick.rear_principal_z + thick.focal_length_mm;
        let diameter_mm = 2.0 * chief_ray_film_radius(&Tracer::new(&design), &design, focal_plane);
        Ok(
            if diameter_mm > 0.0 && diameter_mm < 0.5 * FULL_FRAME_MM[1] {
                (
                    Film::inside_circle(diameter_mm, width, height),
                    FilmSize::ImageCircle { diameter_mm },
                )
            } else {
                full_frame
            },
        )
    }

    fn scene_source(&self) -> Result<(SceneSource, SceneReport), JobError> {
        let mesh = match &self.scene {
            SceneSpec::Demo => MeshScene::from_panels(&Scene::demo()),
            SceneSpec::Gltf(path) => load_gltf(path)?,
            SceneSpec::Exr(_) if self.orbit.is_some() => {
                return Err(RenderError::InvalidSetting(
                    "an RGB + Z EXR scene is one view of the scene: it cannot be orbited".into(),
                )
                .into());
            }
            SceneSpec::Exr(path) => {
                let report = SceneReport {
                    triangles: None,
                    peeled_on_gpu: None,
                };
                return Ok((SceneSource::Exr(path.clone()), report));
            }
        };
        let mesh = match self.orbit {
            Some(orbit) => mesh.orbited(orbit.pivot_mm, orbit.angles_deg),
            None => mesh,
        };
        // Peel where the kernel runs; the CPU twin when there is no adapter.
        let gpu = match self.backend {
            BackendChoice::Cpu => None,
            BackendChoice::Gpu => Some(GpuPeeler::new()?),
            BackendChoice::Auto => gpu_worth_using().ok().and_then(|()| GpuPeeler::new().ok()),
        };
        let report = SceneReport {
            triangles: Some(mesh.triangles.len()),
            peeled_on_gpu: gpu.as_ref().map(|g| g.adapter_description.clone()),
        };
        let source = SceneSource::Mesh {
            scene: mesh,
            peel: self.peel,
            gpu,
        };
        Ok((source, report))
    }

    /// The film's focus and placement for the job's focus mode, `model` the first-order model
    /// focus is found with.
    fn place_film(
        &self,
        model: &LensModel,
        film: Film,
        source: &SceneSource,
        first_order: &FirstOrderModels,
        f_number: f64,
        asked: ModelKind,
    ) -> Result<(Focus, Film, Option<FocusPlaneReport>, Option<FocalSurface>), JobError> {
        let [width, height] = [self.settings.width, self.settings.height];
        // Picked pixels are looked up in a frame focused at infinity.
        let probe = |film: Film| -> Result<(Camera, LayeredDepthImage), JobError> {
            let lens = model.paraxial();
            let infinity = Focus::FilmZ(lens.rear_principal_z + lens.focal_length_mm);
            let probe = Camera::new(model.clone(), film, infinity)?;
            let ldi = source.layers(&probe, &self.settings)?;
            Ok((probe, ldi))
        };
        Ok(match &self.focus {
            FocusMode::Points(pixels) => {
                let untilted = Film {
                    tilt_deg: [0.0, 0.0],
                    ..film
                };
                let (probe, ldi) = probe(untilted)?;
                let mut objects = [[0.0; 3]; 3];
                for (object, pixel) in objects.iter_mut().zip(pixels) {
                    *object = scene_point_under(&probe, &ldi, width, height, *pixel)?;
                }
                let report =
                    focus_plane(&self.lens, first_order, f_number, &untilted, objects, asked)?;
                let film = Film {
                    tilt_deg: report.placement.tilt_deg,
                    ..film
                };
                (
                    Focus::FilmZ(report.placement.film_z),
                    film,
                    Some(report),
                    None,
                )
            }
            FocusMode::Distance(d) => (Focus::ObjectDistance(*d), film, None, None),
            FocusMode::Sensor(z) => (Focus::FilmZ(*z), film, None, None),
            FocusMode::Pixel(pixel) => {
                let (probe, ldi) = probe(film)?;
                let film_z = film_z_for_pixel(&probe, &ldi, width, height, *pixel)?;
                (Focus::FilmZ(film_z), film, None, None)
            }
            FocusMode::Surface(spec) => {
                let (probe, ldi) = probe(film)?;
                // The lens-frame z of the point under the pixel is minus its distance in front
                // of the first vertex.
                let surface = spec.resolve(|pixel| {
                    Ok(-scene_point_under(&probe, &ldi, width, height, pixel)?[2])
                })?;
                let centre = [width as f64 / 2.0, height as f64 / 2.0];
                let reference = Focus::ObjectDistance(surface.distance_at(centre));
                (reference, film, None, Some(surface))
            }
        })
    }

    /// Whether the render traces its channels at their own wavelengths, through a model of
    /// `kind` on `camera`'s film.
    fn chromatic_decision(
        &self,
        kind: ModelKind,
        first_order: &FirstOrderModels,
        camera: &Camera,
    ) -> Result<ChromaticDecision, JobError> {
        let off = |reason| {
            Ok(ChromaticDecision {
                wavelengths_nm: None,
                reason,
            })
        };
        let real = match (&self.lens, self.chromatic) {
            (_, ChromaticMode::Off) => return off(ChromaticReason::Off),
            (_, ChromaticMode::On) if kind == ModelKind::Seidel => {
                return Err(JobError::SeidelIsMonochrome);
            }
            (_, ChromaticMode::Auto) if kind == ModelKind::Seidel => {
                return off(ChromaticReason::SeidelModel);
            }
            (_, ChromaticMode::On) if kind.is_realtime() => {
                return Err(JobError::RealtimeIsMonochrome(kind));
            }
            (_, ChromaticMode::Auto) if kind.is_realtime() => {
                return off(ChromaticReason::RealtimeModel(kind));
            }
            (RenderLens::Ideal { .. }, ChromaticMode::On) => {
                return Err(JobError::IdealDoesNotDisperse);
            }
            (RenderLens::Ideal { .. }, ChromaticMode::Auto) => {
                return off(ChromaticReason::IdealLens);
            }
            (RenderLens::Real(real), _) => real,
        };
        let system = &real.system;
        let wavelengths = self
            .wavelengths_nm
            .unwrap_or_else(|| default_wavelengths(system));
        let spread = ColourSpread::of(
            system,
            first_order,
            wavelengths,
            camera.film_z,
            camera.film_corner_radius(),
        )?;
        let pitch = camera.film.width_mm / self.settings.width as f64;
        let on = wants_chromatic(self.chromatic, system, &spread, pitch);
        Ok(ChromaticDecision {
            wavelengths_nm: on.then_some(wavelengths),
            reason: ChromaticReason::Spread {
                lateral_px: spread.lateral_mm / pitch,
                axial_blur_px: spread.axial_blur_mm / pitch,
                disperses: system.disperses(),
            },
        })
    }

    /// The baked lens of `real` for `camera`'s film: `chosen` (a table the error budget baked),
    /// else the job's table directory, else the first covering table, else a new bake.
    #[allow(clippy::too_many_arguments)]
    fn baked_lens(
        &self,
        real: &LoadedLens,
        first_order: &FirstOrderModels,
        f_number: f64,
        camera: &Camera,
        wavelengths: Option<[f64; CHANNELS]>,
        chosen: Option<crate::lrtf::LrtfTable>,
        progress: &(dyn Fn(BakeProgress) + Sync),
    ) -> Result<(BakedLens, TableUse), JobError> {
        let focus_mm = focus_of_film(real, camera.film_z)?;
        let film_radius = sensor_film_radius(real, camera);
        let dir = self.table.clone().unwrap_or_else(|| {
            let base = default_table_dir(&self.tables_root, &real.source.origin.name(), focus_mm);
            let needs = TableNeeds {
                film_z: camera.film_z,
                f_number,
                film_radius,
                wavelengths_nm: wavelengths
                    .map_or(vec![real.system.design_wavelength_nm()], Vec::from),
            };
            find_covering_table(real, &self.tables_root, &needs).unwrap_or_else(
                || match wavelengths {
                    Some(nm) => chromatic_table_dir(&base, nm),
                    None => base,
                },
            )
        });
        let (table, baked_now) = match chosen {
            Some(table) => (table, false),
            None => {
                let fallback = BakeFallback {
                    focus_mm,
                    max_film_radius: film_radius,
                    resolution: self.bake_resolution,
                    wavelengths_nm: wavelengths.map(Vec::from).unwrap_or_default(),
                };
                load_or_bake(real, &dir, &fallback, progress)?
            }
        };
        let covered = table.layers[0].sampling.max_film_radius();
        // The monochrome reading of the table: the design layer, or in a chromatic render the
        // green channel's (the channels pick their own layers).
        let green = wavelengths.map_or(real.system.design_wavelength_nm(), |nm| nm[1]);
        let baked = BakedLens::focused(table, first_order, f_number, camera.film_z)?
            .with_wavelength(green)?;
        let table = TableUse {
            dir,
            baked_now,
            covered_film_radius_mm: covered,
            needed_film_radius_mm: film_radius,
        };
        Ok((baked, table))
    }

    /// The GPU renderer the backend choice asks for (its pipelines built on first use), and what
    /// was used.
    pub fn renderer(&self) -> Result<(Option<GpuRenderer>, BackendUsed), JobError> {
        let realtime = match self.model {
            ModelChoice::Model(kind) if kind.is_realtime() => Some(kind),
            _ => None,
        };
        if let Some(kind) = realtime
            && self.backend == BackendChoice::Gpu
        {
            return Err(JobError::RealtimeOnGpu(kind));
        }
        if let Some(kind) = realtime {
            let gpu_unavailable = (self.backend == BackendChoice::Auto)
                .then(|| format!("the {kind} model has no GPU twin yet"));
            return Ok((None, BackendUsed::Cpu { gpu_unavailable }));
        }
        let gpu = match self.backend {
            BackendChoice::Cpu => {
                return Ok((
                    None,
                    BackendUsed::Cpu {
                        gpu_unavailable: None,
                    },
                ));
            }
            BackendChoice::Gpu => GpuRenderer::open()?,
            BackendChoice::Auto => match gpu_worth_using()
                .and_then(|()| GpuRenderer::open().map_err(|e| e.to_string()))
            {
                Ok(gpu) => gpu,
                Err(why) => {
                    let used = BackendUsed::Cpu {
                        gpu_unavailable: Some(why),
                    };
                    return Ok((None, used));
                }
            },
        };
        let used = BackendUsed::Gpu {
            adapter: gpu.adapter_description.clone(),
        };
        Ok((Some(gpu), used))
    }
}

/// Removes the table a render baked when the render cannot go on, so that a refused command
/// leaves nothing behind; a table found on disk stays.
fn discard_if_baked_now(table: Option<&TableUse>) {
    if let Some(table) = table.filter(|t| t.baked_now) {
        // Best effort: the render's own error is the one to report.
        let _ = std::fs::remove_dir_all(&table.dir);
    }
}

/// The film radius on `camera`'s film plane that a traced or baked model's effective pupil must
/// cover (see [`pupil_film_radius`]).
fn sensor_film_radius(real: &LoadedLens, camera: &Camera) -> f64 {
    let design = real.system.at(real.system.design_wavelength_nm());
    pupil_film_radius(
        &design,
        camera.film_z,
        camera.film_corner_radius(),
        camera.film_off_plane(),
    )
}

/// The sensor placement focusing the plane through `objects`: paraxial (Scheimpflug) for an
/// ideal lens and the thin, thick and Seidel models, the plane through the real-ray best-focus
/// points for a traced or baked model of a real lens (compared with the paraxial one).
fn focus_plane(
    lens: &RenderLens,
    first_order: &FirstOrderModels,
    f_number: f64,
    film: &Film,
    objects: [[f64; 3]; 3],
    kind: ModelKind,
) -> Result<FocusPlaneReport, JobError> {
    let paraxial_lens = match kind {
        ModelKind::Thin => &first_order.thin,
        _ => &first_order.thick,
    };
    let paraxial = paraxial_focus_plane(paraxial_lens, film, objects)?;
    let (placement, compared) = match (kind.needs_surfaces(), lens) {
        (true, RenderLens::Real(real)) => {
            let no_pupil = PupilSampling::disc(0.0, 0.0).circles;
            let traced = TracedLens::new(&real.system, first_order, f_number, no_pupil);
            let real_ray = real_ray_focus_plane(&traced, film, objects)?;
            let blur = |p: &SensorPlacement| -> Result<[f64; 3], RenderError> {
                let mut um = [0.0; 3];
                for (r, o) in um.iter_mut().zip(objects) {
                    *r = spot_rms_on_sensor(&traced, film, p, o)? * 1e3;
                }
                Ok(um)
            };
            let compared = [(real_ray, blur(&real_ray)?), (paraxial, blur(&paraxial)?)];
            (real_ray, Some(compared))
        }
        _ => (paraxial, None),
    };
    Ok(FocusPlaneReport {
        objects,
        placement,
        compared,
    })
}

/// The film of a model that follows the lens's surfaces (traced, Seidel, baked) lies behind its
/// last vertex: a focus whose image falls inside the lens is refused naming the distance (or the
/// sensor), before a pupil is fitted on a plane no ray reaches.
fn film_behind_lens(real: &LoadedLens, film_z: f64, focus: Focus) -> Result<(), JobError> {
    let first = FirstOrder::of(&real.system.at(real.system.design_wavelength_nm()))?;
    if first.ahead_of_last_vertex(film_z) {
        return Ok(());
    }
    let last_vertex_z = first.z_last_vertex;
    Err(match focus {
        Focus::ObjectDistance(distance) => ModelError::ImageInsideLens(ImageInsideLens {
            focus: distance_text(Some(distance)),
            film_z,
            last_vertex_z,
        })
        .into(),
        Focus::FilmZ(z_sensor) => ParaxialError::SensorInsideLens {
            z_sensor,
            z_last_vertex: last_vertex_z,
        }
        .into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lenses;
    use crate::prescription::formats::LoadOptions;

    #[test]
    fn a_baked_render_bakes_its_table_once_then_finds_it() {
        let lens = lenses::load("dgauss-50mm", &LoadOptions::default()).unwrap();
        let root = std::env::temp_dir().join(format!("lensbake-job-{}", std::process::id()));
        let mut job = RenderJob::new(RenderLens::Real(Box::new(lens)));
        job.model = ModelChoice::Model(ModelKind::Baked);
        job.backend = BackendChoice::Cpu;
        job.tables_root = root.clone();
        job.bake_resolution = 8;
        job.settings = RenderSettings {
            width: 32,
            height: 24,
            samples_per_pixel: 2,
            seed: 1,
            max_layers: 4,
        };
        let first = job.run().unwrap();
        let baked = first.prepared.table.clone().unwrap();
        assert!(baked.baked_now);
        assert_eq!(baked.dir, root.join("dgauss-50mm").join("focus-2000mm"));
        assert!(baked.covered_film_radius_mm >= baked.needed_film_radius_mm * (1.0 - 1e-9));
        // The second run reads the table the first one wrote, and renders the same image.
        let second = job.run().unwrap();
        let found = second.prepared.table.clone().unwrap();
        assert!(!found.baked_now);
        assert_eq!(found.dir, baked.dir);
        assert_eq!(second.image.pixels, first.image.pixels);
        assert_eq!(second.prepared.camera.model.kind(), ModelKind::Baked);
        std::fs::remove_dir_all(&root).unwrap();
    }
}
