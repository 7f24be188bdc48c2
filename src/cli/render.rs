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
use lensbake::render::gpu::GpuRenderer;
use lensbake::render::image::{read_exr_rgbz, write_exr, write_png};
use lensbake::render::layers::LayeredDepthImage;
use lensbake::render::models::{BakedLens, FirstOrderModels, TracedLens};
use lensbake::render::scene::Scene;
use lensbake::render::{Backend, RenderError, RenderSettings, layer_view, render_layers};
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
}

/// Film radii at which a traced render fits its effective pupil.
const PUPIL_NODES: usize = 32;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BackendArg {
    Gpu,
    Cpu,
    Auto,
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Lens: a lens file or bundled lens name (see `lensbake lens list`), or `ideal:<EFL_MM>`
    /// for an ideal thin lens of that focal length (thin and thick models only).
    #[arg(long)]
    lens: String,
    #[command(flatten)]
    read: ReadArgs,
    /// Lens model: thin and thick from the paraxial data, traced (the exact trace in the
    /// kernel), baked (an LRTF table lookup).
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
    /// `demo` or an OpenEXR file with R, G, B and Z (mm from the entrance pupil) channels.
    #[arg(long, default_value = "demo")]
    scene: String,
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
    #[arg(long, default_value_t = 1)]
    seed: u32,
    /// Most depth-peeled layers per pixel.
    #[arg(long, default_value_t = 8)]
    max_layers: usize,
    /// Output OpenEXR (linear R, G, B); a tone-mapped PNG is written beside it.
    #[arg(long)]
    out: PathBuf,
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
/// no slower than `f_number`, over film radii up to at least `film_radius`: a focus-range table
/// serves every focus inside its range without a rebake. Only sidecars are read.
pub fn find_covering_table(
    lens: &LoadedLens,
    film_z: f64,
    f_number: f64,
    film_radius: f64,
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
        ..BakeRequest::default()
    };
    let table = bake(&lens.system, &request, progress)?;
    write_table(&table, &lens.source.origin.name(), prescription, dir)?;
    Ok((table, true))
}

enum SceneSource {
    Demo(Scene),
    Exr(PathBuf),
}

impl SceneSource {
    fn layers(
        &self,
        camera: &Camera,
        settings: &RenderSettings,
    ) -> Result<LayeredDepthImage, RenderError> {
        match self {
            SceneSource::Demo(scene) => {
                let nearest = scene.nearest_distance_mm().unwrap_or(1000.0) + camera.eye_z();
                Ok(scene.peel(layer_view(camera, settings, nearest), settings.max_layers))
            }
            SceneSource::Exr(path) => {
                read_exr_rgbz(path, camera.eye_z(), camera.half_field_tangents())
            }
        }
    }
}

pub fn run(args: RenderArgs) -> anyhow::Result<()> {
    let lens = RenderLens::parse(&args.lens, &args.read)?;
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
    let film = Film {
        shift_mm: [args.shift_mm.0, args.shift_mm.1],
        ..Film::full_frame_for(args.width, args.height)
    };
    let source = match args.scene.as_str() {
        "demo" => SceneSource::Demo(Scene::demo()),
        path => SceneSource::Exr(PathBuf::from(path)),
    };
    let focus = match (args.focus_mm, args.focus_pixel, args.sensor_mm) {
        (Some(d), _, _) => Focus::ObjectDistance(d),
        (_, _, Some(z)) => Focus::FilmZ(z),
        (_, Some((x, y)), _) => {
            if x >= args.width || y >= args.height {
                bail!(
                    "focus pixel {x},{y} lies outside the {}x{} image",
                    args.width,
                    args.height
                );
            }
            // Peel once focused at infinity to find what lies under the pixel.
            let lens = model.paraxial();
            let probe = Camera::new(
                model.clone(),
                film,
                Focus::FilmZ(lens.rear_principal_z + lens.focal_length_mm),
            )?;
            let ldi = source.layers(&probe, &settings)?;
            let field = probe.half_field_tangents();
            let to_layer = |p: u32, size: u32, half: f64, layer_half: f64, layer_size: u32| {
                let tan = half * (2.0 * (p as f64 + 0.5) / size as f64 - 1.0);
                ((tan / layer_half + 1.0) / 2.0 * layer_size as f64).floor() as u32
            };
            let lx = to_layer(
                x,
                settings.width,
                field[0],
                ldi.view.tan_half[0],
                ldi.view.width,
            );
            let ly = to_layer(
                y,
                settings.height,
                field[1],
                ldi.view.tan_half[1],
                ldi.view.height,
            );
            let depth = ldi
                .nearest_depth(lx, ly)
                .with_context(|| format!("nothing under pixel {x},{y} to focus on"))?;
            Focus::ObjectDistance(depth as f64 - probe.eye_z())
        }
        (None, None, None) => Focus::ObjectDistance(2000.0),
    };
    let camera = Camera::new(model, film, focus)?;
    let camera = match (args.model, &lens) {
        (ModelArg::Thin | ModelArg::Thick, _) => camera,
        (_, RenderLens::Ideal { .. }) => {
            bail!("`--lens ideal:...` has no surfaces to trace or bake: use --model thin or thick")
        }
        (ModelArg::Traced, RenderLens::Real(real)) => {
            let traced = TracedLens::fitted(
                &real.system,
                &first_order,
                f_number,
                camera.film_z,
                camera.film_corner_radius(),
                PUPIL_NODES,
            )?;
            Camera::new(
                LensModel::Traced(Box::new(traced)),
                film,
                Focus::FilmZ(camera.film_z),
            )?
        }
        (ModelArg::Baked, RenderLens::Real(real)) => {
            let design = real.system.at(real.system.design_wavelength_nm());
            let focus_mm = match object_in_focus(&design, camera.film_z)? {
                ObjectPosition::Infinite => None,
                ObjectPosition::Finite { distance } => Some(distance),
            };
            let dir = args.table.clone().unwrap_or_else(|| {
                find_covering_table(real, camera.film_z, f_number, camera.film_corner_radius())
                    .unwrap_or_else(|| default_table_dir(&real.source.origin.name(), focus_mm))
            });
            let (table, baked) = load_or_bake(
                real,
                &dir,
                focus_mm,
                camera.film_corner_radius(),
                args.bake_resolution,
                &|_| {},
            )?;
            if baked {
                println!("baked {}", dir.display());
            }
            let baked = BakedLens::focused(table, &first_order, f_number, camera.film_z)?;
            let film_z = baked.film_z();
            Camera::new(
                LensModel::Baked(Box::new(baked)),
                film,
                Focus::FilmZ(film_z),
            )?
        }
    };
    let started = Instant::now();
    let ldi = source.layers(&camera, &settings)?;
    let peel_time = started.elapsed();

    let gpu = match args.backend {
        BackendArg::Cpu => None,
        BackendArg::Gpu => Some(GpuRenderer::new()?),
        BackendArg::Auto => match GpuRenderer::new() {
            Ok(gpu) => Some(gpu),
            Err(e) => {
                println!("backend: cpu ({e})");
                None
            }
        },
    };
    let backend = match &gpu {
        Some(g) => {
            println!("backend: gpu ({})", g.adapter_description);
            Backend::Gpu
        }
        None => {
            if args.backend == BackendArg::Cpu {
                println!("backend: cpu");
            }
            Backend::Cpu
        }
    };
    let started = Instant::now();
    let image = render_layers(&camera, &ldi, &settings, backend, gpu.as_ref())?;
    let trace_time = started.elapsed();
    write_exr(&image, &args.out)?;
    let png = args.out.with_extension("png");
    write_png(&image, 1.0, &png)?;
    println!(
        "model {}, film at z = {:.3} mm, {} layers ({}x{}), {} spp: peel {:.1} ms, trace {:.1} ms",
        camera.model.name(),
        camera.film_z,
        ldi.layers.len(),
        ldi.view.width,
        ldi.view.height,
        settings.samples_per_pixel,
        peel_time.as_secs_f64() * 1e3,
        trace_time.as_secs_f64() * 1e3
    );
    println!("wrote {} and {}", args.out.display(), png.display());
    Ok(())
}
