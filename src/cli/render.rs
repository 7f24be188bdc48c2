//! `lensbake render`: depth of field through a lens model by image-based ray tracing.

use anyhow::{Context, bail};
use clap::{Args, ValueEnum};
use lensbake::render::camera::{Camera, Film, Focus, LensModel, ParaxialLens};
use lensbake::render::gpu::GpuRenderer;
use lensbake::render::image::{read_exr_rgbz, write_exr, write_png};
use lensbake::render::layers::LayeredDepthImage;
use lensbake::render::scene::Scene;
use lensbake::render::{Backend, RenderError, RenderSettings, layer_view, render_layers};
use std::path::PathBuf;
use std::time::Instant;

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum ModelArg {
    Thin,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, ValueEnum)]
pub enum BackendArg {
    Gpu,
    Cpu,
    Auto,
}

#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Lens: `ideal:<EFL_MM>` for an ideal thin lens of that focal length.
    #[arg(long)]
    lens: String,
    #[arg(long, value_enum, default_value = "thin")]
    model: ModelArg,
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
    #[arg(long, default_value_t = 2.8)]
    f_number: f64,
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

fn lens_model(args: &RenderArgs) -> anyhow::Result<LensModel> {
    let Some(efl) = args.lens.strip_prefix("ideal:") else {
        bail!(
            "lens `{}`: only `ideal:<EFL_MM>` is supported by render so far (thin and thick \
             models of prescriptions need the paraxial stage)",
            args.lens
        );
    };
    let efl: f64 = efl
        .parse()
        .with_context(|| format!("lens `{}`: bad focal length", args.lens))?;
    match args.model {
        ModelArg::Thin => Ok(LensModel::Thin(ParaxialLens::thin(efl, args.f_number)?)),
    }
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
    let model = lens_model(&args)?;
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
