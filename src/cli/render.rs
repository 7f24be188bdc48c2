//! `lensbake render`: depth of field through a lens model by image-based ray tracing.

use super::lens::ReadArgs;
use anyhow::{Context, bail};
use clap::{Args, ValueEnum};
use lensbake::lenses::LoadedLens;
use lensbake::lrtf::bake::{BakeProgress, BakeRequest, bake};
use lensbake::lrtf::io::{SIDECAR_FILE, read_table, write_table};
use lensbake::lrtf::{LrtfTable, Precision};
use lensbake::paraxial::{ObjectPosition, object_in_focus};
use lensbake::render::camera::{Camera, Film, Focus, LensModel, ParaxialLens};
use lensbake::render::gpu::GpuRenderer;
use lensbake::render::image::{read_exr_rgbz, write_exr, write_png};
use lensbake::render::layers::LayeredDepthImage;
use lensbake::render::models::{BakedLens, FirstOrderModels, SeidelLens, TracedLens};
use lensbake::render::scene::Scene;
use lensbake::render::{Backend, RenderError, RenderSettings, layer_view, render_layers};
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
    /// Table directory for `--model baked`; default tables/<lens>/ (focused at infinity) or
    /// tables/<lens>/focus-<D>mm/, baked there when missing.
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
    /// Render with the cheapest model (and table size and precision) whose p99 image error, in
    /// pixels of this render, stays under this for the scene's depth range, film use and
    /// f-number; prints the choice with its predicted and measured error.
    #[arg(long, conflicts_with_all = ["model", "table"])]
    error_budget_px: Option<f64>,
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
        let same_focus = match (table.info.focus_mm, focus_mm) {
            (None, None) => true,
            // The render derives its focus from the film position: equal to rounding.
            (Some(a), Some(b)) => (a - b).abs() <= 1e-6 * a.abs().max(b.abs()),
            _ => false,
        };
        if !same_focus {
            bail!(
                "table {} is focused at {:?} mm, the render at {:?} mm; pass --table or rebake",
                dir.display(),
                table.info.focus_mm,
                focus_mm
            );
        }
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
    let camera = match (model_arg, &lens) {
        (ModelArg::Thin, _) => Camera::new(LensModel::Thin(first_order.thin.clone()), film, focus)?,
        (ModelArg::Thick, _) => {
            Camera::new(LensModel::Thick(first_order.thick.clone()), film, focus)?
        }
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
            let focus_mm = focus_of_film(real, camera.film_z)?;
            let dir = args
                .table
                .clone()
                .unwrap_or_else(|| default_table_dir(&real.source.origin.name(), focus_mm));
            let (table, baked) = match chosen_table.take() {
                Some(table) => (table, false),
                None => load_or_bake(
                    real,
                    &dir,
                    focus_mm,
                    camera.film_corner_radius(),
                    args.bake_resolution,
                    &|_| {},
                )?,
            };
            if baked {
                println!("baked {}", dir.display());
            }
            let baked = BakedLens::new(table, &first_order, f_number)?;
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
