//! `lensbake render`: depth of field through a lens model by image-based ray tracing.

use super::lens::ReadArgs;
use anyhow::{Context, bail};
use clap::{Args, ValueEnum};
use lensbake::lenses::LoadedLens;
use lensbake::lrtf::bake::{BakeProgress, BakeRequest, bake};
use lensbake::lrtf::io::{SIDECAR_FILE, prescription_hash, read_sidecar, read_table, write_table};
use lensbake::lrtf::{LrtfTable, Precision};
use lensbake::paraxial::{ObjectPosition, object_in_focus};
use lensbake::render::camera::{Camera, Film, Focus, LensModel, ParaxialLens};
use lensbake::render::chromatic::{
    CHANNELS, Chromatic, ChromaticMode, ColourSpread, default_wavelengths, wants_chromatic,
};
use lensbake::render::focus::{
    SensorPlacement, film_z_for_pixel, paraxial_focus_plane, real_ray_focus_plane,
    scene_point_under, spot_rms_on_sensor,
};
use lensbake::render::gltf_scene::{gltf_path, load_gltf};
use lensbake::render::gpu::GpuRenderer;
use lensbake::render::gpu_peel::GpuPeeler;
use lensbake::render::image::{png_beside, read_exr_rgbz, write_exr, write_png};
use lensbake::render::layers::LayeredDepthImage;
use lensbake::render::mesh::MeshScene;
use lensbake::render::models::{
    BakedLens, FirstOrderModels, PupilSampling, SeidelLens, TracedLens, WAVELENGTH_MATCH_NM,
    pupil_film_radius,
};
use lensbake::render::raster::{Peeling, mesh_layer_view, peel_mesh, surfel_count};
use lensbake::render::scene::Scene;
use lensbake::render::{Backend, RenderError, RenderSettings, render_layers};
use lensbake::tradeoff::models::ModelKind;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Which lens model maps film rays to scene rays. The default is `traced`: exact, and it needs
/// no table; `baked` is the fast one once a table exists (it bakes one when missing).
#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ModelArg {
    Thin,
    Thick,
    Traced,
    Baked,
    /// The thick lens plus third-order (Seidel) transverse aberration of the plane in focus.
    Seidel,
}

/// Film radii at which a traced render fits its effective pupil.
const PUPIL_NODES: usize = 32;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BackendArg {
    Gpu,
    Cpu,
    Auto,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum PeelArg {
    Plain,
    Umbra,
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Lens: a lens file or bundled lens name (see `lensbake lens list`), or `ideal:<EFL_MM>`
    /// for an ideal thin lens of that focal length (thin and thick models only).
    #[arg(long)]
    lens: String,
    #[command(flatten)]
    read: ReadArgs,
    /// Lens model: thin and thick from the paraxial data, seidel (thick plus third-order
    /// aberration), traced (the exact trace in the kernel), baked (an LRTF table lookup).
    #[arg(long, value_enum, default_value = "traced")]
    model: ModelArg,
    /// Table directory for `--model baked`; default: the first table under tables/<lens>/ whose
    /// focus range covers the render's focus (a range table serves every focus inside it), else
    /// tables/<lens>/ (infinity) or tables/<lens>/focus-<D>mm/, baked there when missing.
    #[arg(long)]
    table: Option<PathBuf>,
    /// Nodes per axis when a table has to be baked.
    #[arg(long, default_value_t = 64)]
    bake_resolution: usize,
    /// `demo`, a glTF 2.0 file (.gltf or .glb; metres, seen from its first camera node), or an
    /// OpenEXR file with R, G, B and Z (mm from the entrance pupil) channels.
    #[arg(long, default_value = "demo")]
    scene: String,
    /// Depth peeling of mesh scenes: `umbra` skips surfaces hidden from the whole entrance
    /// pupil behind a nearer layer's pixel (fewer layers), `plain` keeps every surface.
    #[arg(long, value_enum, default_value = "umbra")]
    peel: PeelArg,
    #[arg(long, value_enum, default_value = "auto")]
    backend: BackendArg,
    /// Samples per pixel.
    #[arg(long, default_value_t = 64)]
    spp: u32,
    #[arg(long, default_value_t = 800)]
    width: u32,
    #[arg(long, default_value_t = 600)]
    height: u32,
    /// f-number; default: the lens wide open (f/2.8 for `ideal:`).
    #[arg(long)]
    f_number: Option<f64>,
    /// Focus on the plane this far in front of the first vertex (mm).
    #[arg(long, conflicts_with_all = ["focus_pixel", "sensor_mm"])]
    focus_mm: Option<f64>,
    /// Focus on the nearest surface under output pixel X,Y.
    #[arg(long, value_parser = parse_pair::<u32>, conflicts_with = "sensor_mm")]
    focus_pixel: Option<(u32, u32)>,
    /// Put the film this far behind the first vertex (mm).
    #[arg(long)]
    sensor_mm: Option<f64>,
    /// Sensor shift X,Y (mm).
    #[arg(long, value_parser = parse_pair::<f64>, default_value = "0,0")]
    shift_mm: (f64, f64),
    /// Sensor tilt X,Y (degrees): right-handed rotations about the lens-frame x axis, then the
    /// y axis, through the sensor centre. X > 0 moves the bottom edge of the image away from the
    /// lens, Y > 0 its left edge towards the lens. Focus modes place the sensor centre.
    #[arg(long, value_parser = parse_pair::<f64>, default_value = "0,0", allow_hyphen_values = true)]
    tilt_deg: (f64, f64),
    /// Tilt the sensor to focus on the plane through the scene points under three pixels,
    /// "X1,Y1;X2,Y2;X3,Y3" (quote it), picked in the untilted frame focused at infinity.
    /// Thin and thick: the paraxial (Scheimpflug) solution; traced and baked: the plane
    /// through the real-ray best-focus points. Prints the tilt and the sensor distance.
    #[arg(long, value_parser = parse_focus_points,
          conflicts_with_all = ["focus_mm", "focus_pixel", "sensor_mm", "tilt_deg"])]
    focus_points: Option<[(u32, u32); 3]>,
    #[arg(long, default_value_t = 1)]
    seed: u32,
    /// Most depth-peeled layers per pixel.
    #[arg(long, default_value_t = 8)]
    max_layers: usize,
    /// Output OpenEXR (linear R, G, B); a tone-mapped PNG is written beside it.
    #[arg(long)]
    out: PathBuf,
    /// Trace R, G and B each at its own wavelength (chromatic aberration): on, off, or auto =
    /// on when the lens disperses and its colour spread on this film reaches half a pixel.
    #[arg(long, value_enum, default_value = "auto")]
    chromatic: ChromaticArg,
    /// Wavelengths of R,G,B in nm; default: the C line, the design wavelength, the F line.
    #[arg(long, value_delimiter = ',')]
    wavelengths_nm: Option<Vec<f64>>,
    /// Render with the cheapest model (and table size and precision) whose p99 image error, in
    /// pixels of this render, stays under this for the scene's depth range, film use and
    /// f-number; prints the choice with its predicted and measured error.
    #[arg(long, conflicts_with_all = ["model", "table"])]
    error_budget_px: Option<f64>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ChromaticArg {
    On,
    Off,
    Auto,
}

impl ChromaticArg {
    fn mode(self) -> ChromaticMode {
        match self {
            ChromaticArg::On => ChromaticMode::On,
            ChromaticArg::Off => ChromaticMode::Off,
            ChromaticArg::Auto => ChromaticMode::Auto,
        }
    }
}

/// The wavelengths R, G, B of a chromatic render of `lens` through `camera`, or None for a
/// monochrome one, with the line that says why.
fn chromatic_wavelengths(
    args: &RenderArgs,
    model: ModelArg,
    lens: &RenderLens,
    first_order: &FirstOrderModels,
    camera: &Camera,
) -> anyhow::Result<(Option<[f64; CHANNELS]>, String)> {
    let wavelengths = match &args.wavelengths_nm {
        Some(list) => Some(<[f64; CHANNELS]>::try_from(list.as_slice()).map_err(|_| {
            anyhow::anyhow!(
                "--wavelengths-nm takes three wavelengths R,G,B, got {}",
                list.len()
            )
        })?),
        None => None,
    };
    let real = match (lens, args.chromatic) {
        (_, ChromaticArg::Off) => return Ok((None, "chromatic: off".into())),
        (_, ChromaticArg::On) if model == ModelArg::Seidel => {
            bail!(
                "--chromatic on: the Seidel model has its sums at the design wavelength only; use \
                 --model thin, thick, traced or baked, or --chromatic off"
            )
        }
        (_, ChromaticArg::Auto) if model == ModelArg::Seidel => {
            return Ok((
                None,
                "chromatic: off (the Seidel model is monochrome)".into(),
            ));
        }
        (RenderLens::Ideal { .. }, ChromaticArg::On) => {
            bail!("--chromatic on: an `ideal:` lens has no glass to disperse; use a lens file")
        }
        (RenderLens::Ideal { .. }, ChromaticArg::Auto) => {
            return Ok((None, "chromatic: off (ideal lens)".into()));
        }
        (RenderLens::Real(real), _) => real,
    };
    let system = &real.system;
    let wavelengths = wavelengths.unwrap_or_else(|| default_wavelengths(system));
    let spread = ColourSpread::of(
        system,
        first_order,
        wavelengths,
        camera.film_z,
        camera.film_corner_radius(),
    )?;
    let pitch = camera.film.width_mm / args.width as f64;
    let on = wants_chromatic(args.chromatic.mode(), system, &spread, pitch);
    let why = format!(
        "lateral colour {:.2} px, axial colour blur {:.2} px{}",
        spread.lateral_mm / pitch,
        spread.axial_blur_mm / pitch,
        if system.disperses() {
            ""
        } else {
            "; the lens does not disperse"
        }
    );
    let nm = wavelengths.map(|w| format!("{w:.1}")).join("/");
    Ok(if on {
        (
            Some(wavelengths),
            format!("chromatic: on, R/G/B at {nm} nm ({why})"),
        )
    } else {
        (None, format!("chromatic: off ({why})"))
    })
}

/// Where `--model baked` keeps a chromatic render's table, beside the monochrome one in `base`.
fn chromatic_table_dir(base: &Path, wavelengths_nm: [f64; CHANNELS]) -> PathBuf {
    let [r, g, b] = wavelengths_nm;
    base.join(format!("rgb-{r:.1}-{g:.1}-{b:.1}nm"))
}

fn parse_pair<T: std::str::FromStr>(text: &str) -> Result<(T, T), String> {
    let (a, b) = text
        .split_once(',')
        .ok_or_else(|| format!("expected X,Y, got `{text}`"))?;
    let parse = |s: &str| {
        s.trim()
            .parse::<T>()
            .map_err(|_| format!("not a number: `{s}`"))
    };
    Ok((parse(a)?, parse(b)?))
}

fn parse_focus_points(text: &str) -> Result<[(u32, u32); 3], String> {
    let pixels = text
        .split(';')
        .map(parse_pair::<u32>)
        .collect::<Result<Vec<_>, _>>()?;
    <[(u32, u32); 3]>::try_from(pixels)
        .map_err(|p| format!("expected three pixels X1,Y1;X2,Y2;X3,Y3, got {}", p.len()))
}

/// A lens as the command line names it.
pub enum RenderLens {
    Ideal { focal_length_mm: f64 },
    Real(Box<LoadedLens>),
}

impl RenderLens {
    pub fn parse(spec: &str, read: &ReadArgs) -> anyhow::Result<RenderLens> {
        if let Some(efl) = spec.strip_prefix("ideal:") {
            let focal_length_mm = efl
                .parse()
                .with_context(|| format!("lens `{spec}`: bad focal length"))?;
            return Ok(RenderLens::Ideal { focal_length_mm });
        }
        let lens = super::lens::LensArgs {
            lens: spec.to_string(),
            read: read.clone(),
        }
        .load()?;
        Ok(RenderLens::Real(Box::new(lens)))
    }

    /// Thin and thick first-order models and the f-number used (wide open when None).
    pub fn first_order(&self, f_number: Option<f64>) -> anyhow::Result<(FirstOrderModels, f64)> {
        match self {
            RenderLens::Ideal { focal_length_mm } => {
                let f_number = f_number.unwrap_or(2.8);
                let thin = ParaxialLens::thin(*focal_length_mm, f_number)?;
                let models = FirstOrderModels {
                    thick: thin.clone(),
                    thin,
                    wide_open_f_number: f_number,
                    f_number,
                };
                Ok((models, f_number))
            }
            RenderLens::Real(lens) => {
                let models = FirstOrderModels::of(&lens.system, f_number)?;
                let f_number = models.f_number;
                Ok((models, f_number))
            }
        }
    }
}

/// Where `--model baked` keeps the table of `lens` focused at `focus_mm` (None: infinity).
pub fn default_table_dir(lens_name: &str, focus_mm: Option<f64>) -> PathBuf {
    let base = Path::new("tables").join(lens_name);
    match focus_mm {
        None => base,
        Some(d) => base.join(format!("focus-{d:.0}mm")),
    }
}

/// The first table under tables/<lens>/ (the directory itself, then its subdirectories by name)
/// baked from this prescription whose focus range holds the film plane `film_z`, at an f-number
/// no slower than `f_number`, over film radii up to at least `film_radius`, with a layer at each
/// of `wavelengths_nm` (within [`WAVELENGTH_MATCH_NM`]): a focus-range table serves every focus
/// inside its range without a rebake. Only sidecars are read.
pub fn find_covering_table(
    lens: &LoadedLens,
    film_z: f64,
    f_number: f64,
    film_radius: f64,
    wavelengths_nm: &[f64],
) -> Option<PathBuf> {
    let base = default_table_dir(&lens.source.origin.name(), None);
    let mut subdirs: Vec<PathBuf> = std::fs::read_dir(&base)
        .into_iter()
        .flatten()
        .flatten()
        .map(|entry| entry.path())
        .filter(|path| path.is_dir())
        .collect();
    subdirs.sort();
    let hash = prescription_hash(&lens.source.loaded.prescription);
    std::iter::once(base).chain(subdirs).find(|dir| {
        read_sidecar(dir).is_ok_and(|sidecar| {
            let sampling = sidecar.layers.first().map(|l| &l.sampling_pupil);
            sidecar.prescription_hash == hash
                && sidecar.info.f_number <= f_number * (1.0 + 1e-12)
                && sidecar.info.focus.check_film_z(film_z, "").is_ok()
                && sampling.is_some_and(|s| s.max_film_radius() >= film_radius * (1.0 - 1e-9))
                && wavelengths_nm.iter().all(|nm| {
                    sidecar
                        .layers
                        .iter()
                        .any(|l| (l.wavelength_nm - nm).abs() <= WAVELENGTH_MATCH_NM)
                })
        })
    })
}

/// Loads the table in `dir`, or bakes one there (focused at `focus_mm`, covering film radii up to
/// `max_film_radius`) when the directory holds none. `progress` sees the bake's node counts.
pub fn load_or_bake(
    lens: &LoadedLens,
    dir: &Path,
    focus_mm: Option<f64>,
    max_film_radius: f64,
    resolution: usize,
    progress: &(dyn Fn(BakeProgress) + Sync),
) -> anyhow::Result<(LrtfTable, bool)> {
    load_or_bake_at(
        lens,
        dir,
        focus_mm,
        max_film_radius,
        resolution,
        Vec::new(),
        progress,
    )
}

/// [`load_or_bake`], baking the layers at `wavelengths_nm` (empty: the design wavelength).
pub fn load_or_bake_at(
    lens: &LoadedLens,
    dir: &Path,
    focus_mm: Option<f64>,
    max_film_radius: f64,
    resolution: usize,
    wavelengths_nm: Vec<f64>,
    progress: &(dyn Fn(BakeProgress) + Sync),
) -> anyhow::Result<(LrtfTable, bool)> {
    let prescription = &lens.source.loaded.prescription;
    if dir.join(SIDECAR_FILE).exists() {
        let table = read_table(dir, Some(prescription))?;
        // The render derives its focus from the film position: the range check allows rounding.
        table
            .info
            .focus
            .film_z_for(focus_mm)
            .with_context(|| format!("table {} (pass --table or rebake)", dir.display()))?;
        return Ok((table, false));
    }
    let request = BakeRequest {
        resolution: [resolution; 3],
        precision: Precision::F32,
        focus_mm,
        max_film_radius: Some(max_film_radius),
        wavelengths_nm,
        ..BakeRequest::default()
    };
    let table = bake(&lens.system, &request, progress)?;
    write_table(&table, &lens.source.origin.name(), prescription, dir)?;
    Ok((table, true))
}

/// The object distance (mm in front of surface 1; None: infinity) that the film at `film_z`
/// is focused on, paraxially at the design wavelength.
pub fn focus_of_film(lens: &LoadedLens, film_z: f64) -> anyhow::Result<Option<f64>> {
    let design = lens.system.at(lens.system.design_wavelength_nm());
    Ok(match object_in_focus(&design, film_z)? {
        ObjectPosition::Infinite => None,
        ObjectPosition::Finite { distance } => Some(distance),
    })
}

enum SceneSource {
    /// The demo (as meshes) or a glTF file, peeled by rasterisation.
    Mesh {
        scene: MeshScene,
        peel: PeelArg,
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
                    PeelArg::Plain => Peeling::Plain,
                    PeelArg::Umbra => Peeling::umbra_for(camera),
                };
                let view = mesh_layer_view(camera, settings, scene)?;
                peel_mesh(scene, view, peeling, settings.max_layers, gpu.as_ref())
            }
            SceneSource::Exr(path) => {
                read_exr_rgbz(path, camera.eye_z(), camera.half_field_tangents())
            }
        }
    }
}

pub fn run(args: RenderArgs) -> anyhow::Result<()> {
    let png = png_beside(&args.out)?;
    let lens = RenderLens::parse(&args.lens, &args.read)?;
    if matches!(lens, RenderLens::Ideal { .. })
        && matches!(args.model, ModelArg::Traced | ModelArg::Baked)
    {
        bail!("`--lens ideal:...` has no surfaces to trace or bake: use --model thin or thick");
    }
    let (first_order, f_number) = lens.first_order(args.f_number)?;
    // Focus is found with the first-order model; traced and baked use the thick one.
    let model = match args.model {
        ModelArg::Thin => LensModel::Thin(first_order.thin.clone()),
        _ => LensModel::Thick(first_order.thick.clone()),
    };
    let settings = RenderSettings {
        width: args.width,
        height: args.height,
        samples_per_pixel: args.spp,
        seed: args.seed,
        max_layers: args.max_layers,
    };
    settings.check()?;
    let film = Film {
        shift_mm: [args.shift_mm.0, args.shift_mm.1],
        tilt_deg: [args.tilt_deg.0, args.tilt_deg.1],
        ..Film::full_frame_for(args.width, args.height)
    };
    let mesh = match (args.scene.as_str(), gltf_path(&args.scene)) {
        ("demo", _) => Some(MeshScene::from_panels(&Scene::demo())),
        (_, Some(path)) => Some(load_gltf(&path)?),
        _ => None,
    };
    let source = match mesh {
        Some(scene) => {
            // Peel where the kernel runs; the CPU twin when there is no adapter.
            let gpu = match args.backend {
                BackendArg::Cpu => None,
                BackendArg::Gpu => Some(GpuPeeler::new()?),
                BackendArg::Auto => GpuPeeler::new().ok(),
            };
            say!(
                "scene: {} triangles, peeled on {}",
                scene.triangles.len(),
                gpu.as_ref().map_or("the cpu".to_string(), |g| format!(
                    "the gpu ({})",
                    g.adapter_description
                ))
            );
            SceneSource::Mesh {
                scene,
                peel: args.peel,
                gpu,
            }
        }
        None => SceneSource::Exr(PathBuf::from(&args.scene)),
    };
    // Picked pixels are looked up in a frame focused at infinity.
    let probe = |film: Film| -> anyhow::Result<(Camera, LayeredDepthImage)> {
        let lens = model.paraxial();
        let infinity = Focus::FilmZ(lens.rear_principal_z + lens.focal_length_mm);
        let probe = Camera::new(model.clone(), film, infinity)?;
        let ldi = source.layers(&probe, &settings)?;
        Ok((probe, ldi))
    };
    let (focus, film) = match (
        args.focus_points,
        args.focus_mm,
        args.focus_pixel,
        args.sensor_mm,
    ) {
        (Some(pixels), ..) => {
            let untilted = Film {
                tilt_deg: [0.0, 0.0],
                ..film
            };
            let (probe, ldi) = probe(untilted)?;
            let mut objects = [[0.0; 3]; 3];
            for (object, (x, y)) in objects.iter_mut().zip(pixels) {
                *object = scene_point_under(&probe, &ldi, args.width, args.height, [x, y])?;
            }
            let placement = focus_plane(
                &lens,
                &first_order,
                f_number,
                &untilted,
                objects,
                args.model,
            )?;
            (
                Focus::FilmZ(placement.film_z),
                Film {
                    tilt_deg: placement.tilt_deg,
                    ..film
                },
            )
        }
        (_, Some(d), _, _) => (Focus::ObjectDistance(d), film),
        (_, _, _, Some(z)) => (Focus::FilmZ(z), film),
        (_, _, Some((x, y)), _) => {
            let (probe, ldi) = probe(film)?;
            let film_z = film_z_for_pixel(&probe, &ldi, args.width, args.height, [x, y])?;
            (Focus::FilmZ(film_z), film)
        }
        (None, None, None, None) => (Focus::ObjectDistance(2000.0), film),
    };
    let camera = Camera::new(model, film, focus)?;
    let (model_arg, mut chosen_table) = match (args.error_budget_px, &lens) {
        (None, _) => (args.model, None),
        (Some(_), RenderLens::Ideal { .. }) => {
            bail!("`--lens ideal:...` is a thin lens and nothing else: drop --error-budget-px")
        }
        (Some(budget), RenderLens::Real(real)) => {
            let layers = source.layers(&camera, &settings)?;
            let choice = super::tradeoff::choose_for_render(
                real,
                &camera,
                &layers,
                settings.width,
                f_number,
                budget,
            )?;
            let model = match choice.model {
                ModelKind::Thin => ModelArg::Thin,
                ModelKind::Thick => ModelArg::Thick,
                ModelKind::Seidel => ModelArg::Seidel,
                ModelKind::Baked => ModelArg::Baked,
                ModelKind::Traced => ModelArg::Traced,
            };
            (model, choice.table)
        }
    };
    let (wavelengths, chromatic_line) =
        chromatic_wavelengths(&args, model_arg, &lens, &first_order, &camera)?;
    say!("{chromatic_line}");
    let camera = match (model_arg, &lens) {
        (ModelArg::Thin, _) => Camera::new(LensModel::Thin(first_order.thin.clone()), film, focus)?,
        (ModelArg::Thick, _) => {
            Camera::new(LensModel::Thick(first_order.thick.clone()), film, focus)?
        }
        (_, RenderLens::Ideal { .. }) => {
            bail!("`--lens ideal:...` has no surfaces to trace or bake: use --model thin or thick")
        }
        (ModelArg::Traced, RenderLens::Real(real)) => {
            let design = real.system.at(real.system.design_wavelength_nm());
            let traced = TracedLens::fitted(
                &real.system,
                &first_order,
                f_number,
                camera.film_z,
                pupil_film_radius(
                    &design,
                    camera.film_z,
                    camera.film_corner_radius(),
                    camera.film_off_plane(),
                ),
                PUPIL_NODES,
            )?;
            Camera::new(
                LensModel::Traced(Box::new(traced)),
                film,
                Focus::FilmZ(camera.film_z),
            )?
        }
        (ModelArg::Seidel, RenderLens::Real(real)) => {
            let focus_mm = focus_of_film(real, camera.film_z)?;
            let seidel = SeidelLens::in_focus(&real.system, &first_order, focus_mm)?;
            Camera::new(
                LensModel::Seidel(Box::new(seidel)),
                film,
                Focus::FilmZ(camera.film_z),
            )?
        }
        (ModelArg::Baked, RenderLens::Real(real)) => {
            let design = real.system.at(real.system.design_wavelength_nm());
            let focus_mm = focus_of_film(real, camera.film_z)?;
            let film_radius = pupil_film_radius(
                &design,
                camera.film_z,
                camera.film_corner_radius(),
                camera.film_off_plane(),
            );
            let dir = args.table.clone().unwrap_or_else(|| {
                let base = default_table_dir(&real.source.origin.name(), focus_mm);
                let wanted =
                    wavelengths.map_or(vec![real.system.design_wavelength_nm()], Vec::from);
                find_covering_table(real, camera.film_z, f_number, film_radius, &wanted)
                    .unwrap_or_else(|| match wavelengths {
                        Some(nm) => chromatic_table_dir(&base, nm),
                        None => base,
                    })
            });
            // The error budget's table holds the design wavelength for the untilted film; a
            // chromatic render or a tilted sensor needs its own.
            let chosen = chosen_table
                .take()
                .filter(|_| wavelengths.is_none() && camera.film_off_plane() == 0.0);
            let (table, baked) = match chosen {
                Some(table) => (table, false),
                None => load_or_bake_at(
                    real,
                    &dir,
                    focus_mm,
                    film_radius,
                    args.bake_resolution,
                    wavelengths.map(Vec::from).unwrap_or_default(),
                    &|_| {},
                )?,
            };
            if baked {
                say!("baked {}", dir.display());
            }
            let covered = table.layers[0].sampling.max_film_radius();
            if covered < film_radius * (1.0 - 1e-9) {
                say!(
                    "note: table {} covers film radii to {covered:.3} mm, this sensor reaches \
                     {film_radius:.3} mm: rays from beyond render black (rebake into another \
                     --table)",
                    dir.display()
                );
            }
            // The monochrome reading of the table: the design layer, or in a chromatic render
            // the green channel's (the channels pick their own layers below).
            let green = wavelengths.map_or(real.system.design_wavelength_nm(), |nm| nm[1]);
            let baked = BakedLens::focused(table, &first_order, f_number, camera.film_z)?
                .with_wavelength(green)?;
            let film_z = baked.film_z();
            Camera::new(
                LensModel::Baked(Box::new(baked)),
                film,
                Focus::FilmZ(film_z),
            )?
        }
    };
    let camera = match (wavelengths, &lens) {
        (Some(nm), RenderLens::Real(real)) => {
            let chromatic =
                Chromatic::for_camera(&camera, &real.system, &first_order, nm, PUPIL_NODES)?;
            camera.with_chromatic(chromatic)?
        }
        _ => camera,
    };
    let started = Instant::now();
    let ldi = source.layers(&camera, &settings)?;
    let peel_time = started.elapsed();
    if let SceneSource::Mesh { peel, .. } = &source {
        say!(
            "peeled {} layers ({:?}, cap {}), {} surfels",
            ldi.layers.len(),
            peel,
            settings.max_layers,
            surfel_count(&ldi)
        );
    }

    let gpu = match args.backend {
        BackendArg::Cpu => None,
        BackendArg::Gpu => Some(GpuRenderer::new()?),
        BackendArg::Auto => match GpuRenderer::new() {
            Ok(gpu) => Some(gpu),
            Err(e) => {
                say!("backend: cpu ({e})");
                None
            }
        },
    };
    let backend = match &gpu {
        Some(g) => {
            say!("backend: gpu ({})", g.adapter_description);
            if camera.chromatic.is_some() {
                g.prepare_chromatic()?;
            }
            Backend::Gpu
        }
        None => {
            if args.backend == BackendArg::Cpu {
                say!("backend: cpu");
            }
            Backend::Cpu
        }
    };
    let started = Instant::now();
    let image = render_layers(&camera, &ldi, &settings, backend, gpu.as_ref())?;
    let trace_time = started.elapsed();
    write_exr(&image, &args.out)?;
    write_png(&image, 1.0, &png)?;
    say!(
        "model {}, film centre at z = {:.3} mm, tilt ({:.3}, {:.3}) deg, {} layers ({}x{}), {} \
         spp: peel {:.1} ms, trace {:.1} ms",
        camera.model.name(),
        camera.film_z,
        camera.film.tilt_deg[0],
        camera.film.tilt_deg[1],
        ldi.layers.len(),
        ldi.view.width,
        ldi.view.height,
        settings.samples_per_pixel,
        peel_time.as_secs_f64() * 1e3,
        trace_time.as_secs_f64() * 1e3
    );
    say!("wrote {} and {}", args.out.display(), png.display());
    Ok(())
}

/// The sensor placement focusing the plane through `objects`, printed with what it leaves:
/// paraxial (Scheimpflug) for an ideal lens and the thin and thick models, the plane through
/// the real-ray best-focus points for a real lens (with the residual blur of both solutions).
fn focus_plane(
    lens: &RenderLens,
    first_order: &FirstOrderModels,
    f_number: f64,
    film: &Film,
    objects: [[f64; 3]; 3],
    model: ModelArg,
) -> anyhow::Result<SensorPlacement> {
    for (k, p) in objects.iter().enumerate() {
        say!(
            "focus point {}: ({:.1}, {:.1}, {:.1}) mm in the lens frame",
            k + 1,
            p[0],
            p[1],
            p[2]
        );
    }
    let paraxial_lens = match model {
        ModelArg::Thin => &first_order.thin,
        _ => &first_order.thick,
    };
    let paraxial = paraxial_focus_plane(paraxial_lens, film, objects)?;
    let placement = match (model, lens) {
        (ModelArg::Traced | ModelArg::Baked, RenderLens::Real(real)) => {
            let no_pupil = PupilSampling::disc(0.0, 0.0).circles;
            let traced = TracedLens::new(&real.system, first_order, f_number, no_pupil);
            let placement = real_ray_focus_plane(&traced, film, objects)?;
            for (name, p) in [("real-ray", &placement), ("paraxial", &paraxial)] {
                let blur = objects
                    .iter()
                    .map(|o| spot_rms_on_sensor(&traced, film, p, *o).map(|r| r * 1e3))
                    .collect::<Result<Vec<_>, _>>()?;
                say!(
                    "{name} focus plane: tilt ({:.3}, {:.3}) deg, centre at z = {:.3} mm; RMS \
                     spot radius of the three points {:.1}, {:.1}, {:.1} um",
                    p.tilt_deg[0],
                    p.tilt_deg[1],
                    p.film_z,
                    blur[0],
                    blur[1],
                    blur[2]
                );
            }
            placement
        }
        _ => paraxial,
    };
    say!(
        "sensor tilt ({:.3}, {:.3}) deg, sensor centre {:.3} mm behind the first vertex",
        placement.tilt_deg[0],
        placement.tilt_deg[1],
        placement.film_z
    );
    Ok(placement)
}
