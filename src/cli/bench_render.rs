//! `lensbake bench render`: time per frame and error against the exact reference for every lens
//! model, backend and sample count, on the demo scene (issue 7, item 8).
//!
//! Results accumulate in `<out>/timings.json` across runs of the same frame (lens, size, focus,
//! layers), a row per (model, backend, samples per pixel), so the expensive cells can be measured
//! in separate runs; `<out>/timings.md` is rewritten from all rows each time.

use super::demo::{stage, write_text};
use super::lens::ReadArgs;
use anyhow::Context;
use clap::Args;
use lensbake::job::tables::DEFAULT_TABLES_ROOT;
use lensbake::job::{RenderLens, TracedAndBaked, default_table_dir};
use lensbake::limits;
use lensbake::model::ModelKind;
use lensbake::realtime::layered::DEFAULT_LAYERS;
use lensbake::realtime::{KernelSettings, LayeredSettings, LensKernels, PostfxPath, layered};
use lensbake::render::camera::{Camera, Film};
use lensbake::render::gpu::GpuRenderer;
use lensbake::render::image::RgbImage;
use lensbake::render::reference::{psnr, psnr_text, render_reference};
use lensbake::render::scene::Scene;
use lensbake::render::{Backend, RenderSettings, layer_view, render_layers};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use std::time::Instant;

#[derive(Args, Debug)]
pub struct RenderBenchArgs {
    /// Lens file or bundled lens name.
    #[arg(long, default_value = "dgauss-50mm")]
    lens: String,
    #[command(flatten)]
    read: ReadArgs,
    /// Lens models to time.
    #[arg(long, value_delimiter = ',', default_value = "thin,thick,traced,baked",
          value_parser = super::lens::model_parser())]
    models: Vec<ModelKind>,
    /// Backends to time: cpu (the rayon twin), gpu (wgpu; lavapipe where no GPU exists).
    #[arg(long, value_delimiter = ',', default_value = "cpu,gpu")]
    backends: Vec<String>,
    /// Samples per pixel, one frame per value.
    #[arg(long, value_delimiter = ',', default_value = "64,256,1024")]
    spp: Vec<u32>,
    #[arg(long, default_value_t = 800)]
    width: u32,
    #[arg(long, default_value_t = 600)]
    height: u32,
    /// Focus distance in front of the first vertex (mm): the demo scene's chart.
    #[arg(long, default_value_t = 2000.0)]
    focus_mm: f64,
    /// Table directory (the baked model's table, whose effective pupil also gives the reference
    /// and every model its lens samples), baked there when missing; default
    /// tables/<lens>/focus-<D>mm/.
    #[arg(long)]
    table: Option<PathBuf>,
    /// Nodes per axis when the table has to be baked.
    #[arg(long, default_value_t = 64)]
    bake_resolution: usize,
    /// Most depth-peeled layers per pixel.
    #[arg(long, default_value_t = 4)]
    max_layers: usize,
    #[arg(long, default_value_t = 1)]
    seed: u32,
    /// Frames rendered per model and backend; the fastest is the row's time (a busy machine
    /// slows single frames by chance; the reference is rendered once).
    #[arg(long, default_value_t = 1)]
    repeats: u32,
    #[arg(long, default_value = "notebooks-out/render")]
    out: PathBuf,
}

/// What every row of one timings file shares; rows of another frame are not mixed in.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Frame {
    lens: String,
    width: u32,
    height: u32,
    focus_mm: f64,
    f_number: f64,
    layers: usize,
    /// Nodes per axis of the baked model's table.
    table_resolution: [usize; 3],
}

#[derive(Clone, Debug, Serialize, Deserialize)]
struct Row {
    model: String,
    /// `cpu`, `gpu (<adapter>)`, or `reference` (the f64 tracer against the true geometry).
    backend: String,
    samples_per_pixel: u32,
    seconds: f64,
    /// PSNR (dB) against the reference at the same samples per pixel; None for the reference.
    psnr_vs_reference_db: Option<f64>,
    /// Mean over pixels and channels of |image - reference| (linear radiance).
    mean_abs_error: Option<f64>,
    /// Unix time of the measurement, to tell runs apart.
    measured_at: u64,
}

#[derive(Serialize, Deserialize)]
struct Timings {
    frame: Frame,
    rows: Vec<Row>,
}

fn mean_abs_error(image: &RgbImage, reference: &RgbImage) -> f64 {
    let sum: f64 = image
        .pixels
        .iter()
        .zip(&reference.pixels)
        .map(|(a, b)| (0..3).map(|c| (a[c] - b[c]).abs() as f64).sum::<f64>())
        .sum();
    sum / (3 * image.pixels.len()).max(1) as f64
}

fn now_unix() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.as_secs())
        .unwrap_or(0)
}

pub fn run(args: RenderBenchArgs) -> anyhow::Result<()> {
    // Every setting is checked before a table is loaded or baked or a file written.
    let base = RenderSettings {
        width: args.width,
        height: args.height,
        samples_per_pixel: 1,
        seed: args.seed,
        max_layers: args.max_layers,
    };
    limits::check(
        "the number of --spp values",
        args.spp.len() as u64,
        limits::MAX_RENDER_FRAMES,
    )?;
    for &spp in &args.spp {
        RenderSettings {
            samples_per_pixel: spp,
            ..base
        }
        .check()?;
    }
    if let Some(other) = args
        .backends
        .iter()
        .find(|b| !["cpu", "gpu"].contains(&b.as_str()))
    {
        anyhow::bail!("--backends: `{other}` is not cpu or gpu");
    }
    // Made before the table, so an unusable destination is refused before a bake; removed
    // again if the run fails before it saved a row (a folder with rows keeps them).
    let made_here = !args.out.exists();
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let measured = measure(&args, base);
    if measured.is_err() && made_here {
        let _ = std::fs::remove_dir(&args.out);
    }
    measured
}

/// The frames `args` asks for, each saved to `<out>/timings.json` as it is measured.
fn measure(args: &RenderBenchArgs, base: RenderSettings) -> anyhow::Result<()> {
    let lens = super::lens::render_lens(&args.lens, &args.read)?;
    let RenderLens::Real(real) = &lens else {
        anyhow::bail!("bench render needs a real lens (a file or bundled name), not `ideal:`");
    };
    let (first_order, f_number) = lens.first_order(None)?;
    let film = Film::full_frame_for(args.width, args.height);
    let table_dir = args.table.clone().unwrap_or_else(|| {
        default_table_dir(
            Path::new(DEFAULT_TABLES_ROOT),
            &real.source.origin.name(),
            Some(args.focus_mm),
        )
    });
    let matched = TracedAndBaked::new(
        real,
        &first_order,
        f_number,
        film,
        args.focus_mm,
        &table_dir,
        args.bake_resolution,
        None,
        &|_| {},
    )?;
    let mut cameras: Vec<(ModelKind, Camera)> = Vec::new();
    for &kind in &args.models {
        let camera = matched.camera(kind, real, &first_order, film, args.focus_mm)?;
        cameras.push((kind, camera));
    }
    let gpu = if args.backends.iter().any(|b| b == "gpu") {
        Some(GpuRenderer::new()?)
    } else {
        None
    };
    // The names are cpu or gpu (checked above), and the GPU renderer exists where one is gpu.
    let backends: Vec<(Backend, String)> = args
        .backends
        .iter()
        .map(|name| match &gpu {
            Some(g) if name == "gpu" => (Backend::Gpu, format!("gpu ({})", g.adapter_description)),
            _ => (Backend::Cpu, "cpu".to_string()),
        })
        .collect();

    let scene = Scene::demo();
    let reference_camera = &matched.traced;
    // Every model's camera puts its eye at the entrance pupil of the same lens: one set of layers.
    let nearest = scene.nearest_distance_mm().unwrap_or(1000.0) + reference_camera.eye_z();
    let ldi = scene.peel(
        layer_view(reference_camera, &base, nearest),
        base.max_layers,
    );
    // The real-time models' kernels are traced once for the frame (per lens, focus and depth
    // range, not per frame): timed apart from their frames.
    let kernels = match args.models.iter().any(|kind| kind.is_realtime()) {
        true => {
            let [near, far] = ldi
                .depth_range()
                .map(|r| r.map(f64::from))
                .unwrap_or([1.0, 1.0]);
            let started = Instant::now();
            let kernels = LensKernels::trace(
                reference_camera,
                &ldi.view,
                [near, far],
                &KernelSettings::default(),
            )?;
            say!(
                "real-time lens kernels: {} traced in {:.2} s",
                kernels.kernels.len(),
                started.elapsed().as_secs_f64()
            );
            Some(kernels)
        }
        false => None,
    };
    let frame = Frame {
        lens: real.source.origin.name(),
        width: args.width,
        height: args.height,
        focus_mm: args.focus_mm,
        f_number,
        layers: ldi.layer_count(),
        table_resolution: matched.table_resolution,
    };

    let json_path = args.out.join("timings.json");
    for &spp in &args.spp {
        let settings = RenderSettings {
            samples_per_pixel: spp,
            ..base
        };
        let bar = stage(&format!("reference, {spp} spp"));
        let started = Instant::now();
        let reference = render_reference(reference_camera, &scene, &settings)?;
        let seconds = started.elapsed().as_secs_f64();
        bar.finish_and_clear();
        say!("reference {spp} spp: {seconds:.1} s");
        save(
            &args.out,
            &frame,
            Row {
                model: ModelKind::Traced.name().into(),
                backend: "reference".into(),
                samples_per_pixel: spp,
                seconds,
                psnr_vs_reference_db: None,
                mean_abs_error: None,
                measured_at: now_unix(),
            },
        )?;
        // The real-time models have a CPU path only so far; postfx in two statements: the fast
        // default and the exact one.
        let mut runs: Vec<(String, Filter, &Camera, Backend, &String)> = Vec::new();
        for (backend, backend_name) in &backends {
            for (kind, camera) in &cameras {
                let filters = match kind {
                    _ if kind.is_realtime() && *backend != Backend::Cpu => vec![],
                    ModelKind::Postfx => vec![
                        (kind.name().to_string(), Filter::Postfx(PostfxPath::Fast)),
                        (format!("{kind} exact"), Filter::Postfx(PostfxPath::Exact)),
                    ],
                    ModelKind::Layered => vec![(kind.name().to_string(), Filter::Layered)],
                    _ => vec![(kind.name().to_string(), Filter::Sampled)],
                };
                for (name, filter) in filters {
                    runs.push((name, filter, camera, *backend, backend_name));
                }
            }
        }
        for (model, filter, camera, backend, backend_name) in runs {
            let image_of = || -> anyhow::Result<RgbImage> {
                Ok(match (filter, &kernels) {
                    (Filter::Postfx(path), Some(kernels)) => {
                        path.render(camera, &ldi, kernels, settings.width, settings.height)?
                    }
                    (Filter::Layered, Some(kernels)) => layered(
                        camera,
                        &ldi,
                        kernels,
                        &LayeredSettings {
                            layers: DEFAULT_LAYERS,
                            peeled_to: settings.max_layers,
                        },
                        settings.width,
                        settings.height,
                    )?,
                    _ => render_layers(camera, &ldi, &settings, backend, gpu.as_ref())?,
                })
            };
            let bar = stage(&format!("{model} on {backend_name}, {spp} spp"));
            let mut seconds = f64::INFINITY;
            let mut image = None;
            for _ in 0..args.repeats.max(1) {
                let started = Instant::now();
                image = Some(image_of()?);
                seconds = seconds.min(started.elapsed().as_secs_f64());
            }
            let image = image.expect("at least one frame");
            bar.finish_and_clear();
            let db = psnr(&image, &reference);
            let row = Row {
                model: model.clone(),
                backend: backend_name.clone(),
                samples_per_pixel: spp,
                seconds,
                psnr_vs_reference_db: Some(db),
                mean_abs_error: Some(mean_abs_error(&image, &reference)),
                measured_at: now_unix(),
            };
            say!(
                "{model} on {backend_name}, {spp} spp: {:.1} ms, PSNR {} against the reference",
                seconds * 1e3,
                psnr_text(db)
            );
            // Saved after every frame: a long run stopped part-way keeps what it measured.
            save(&args.out, &frame, row)?;
        }
    }
    say!("wrote {} and timings.md", json_path.display());
    Ok(())
}

/// Adds `row` to `<out>/timings.json` (rows of another frame are dropped) and rewrites
/// timings.md. Runs into one directory at the same time take turns (a lock on the folder), each
/// re-reading the file, so no run loses another's rows.
fn save(out: &Path, frame: &Frame, row: Row) -> anyhow::Result<()> {
    let _turn = lensbake::output::lock_folder(out)?;
    let json_path = out.join("timings.json");
    let mut timings = lensbake::limits::read_input_text(&json_path)
        .ok()
        .and_then(|text| serde_json::from_str::<Timings>(&text).ok())
        .filter(|t| t.frame == *frame)
        .unwrap_or_else(|| Timings {
            frame: frame.clone(),
            rows: Vec::new(),
        });
    record(&mut timings, row);
    write_text(&json_path, &serde_json::to_string_pretty(&timings)?)?;
    write_text(&out.join("timings.md"), &markdown(&timings))?;
    Ok(())
}

/// Replaces the row of the same model, backend and sample count, or appends.
fn record(timings: &mut Timings, row: Row) {
    let key = |r: &Row| (r.model.clone(), r.backend.clone(), r.samples_per_pixel);
    match timings.rows.iter_mut().find(|r| key(r) == key(&row)) {
        Some(existing) => *existing = row,
        None => timings.rows.push(row),
    }
}

fn markdown(timings: &Timings) -> String {
    let f = &timings.frame;
    let mut rows = timings.rows.clone();
    rows.sort_by(|a, b| {
        (
            a.backend.as_str(),
            a.samples_per_pixel,
            model_rank(&a.model),
        )
            .cmp(&(
                b.backend.as_str(),
                b.samples_per_pixel,
                model_rank(&b.model),
            ))
    });
    let mut text = format!(
        "# Render timings: {lens}, {w}x{h}\n\n\
         Demo scene, focused at {focus:.0} mm, f/{fnum:.2} (wide open), {layers} depth-peeled \
         layers, baked table {res} nodes, f32. Seconds are wall clock for the whole frame (the kernel, \
         plus upload and read-back on the GPU; layer peeling excluded). The error is against the \
         reference: the f64 exact trace through the lens into the scene's true geometry (not its \
         layers), drawing the same lens samples as traced and baked, so for those two the \
         difference is the model's and the layers', not noise; thin and thick sample their own \
         exit pupil, so their error also holds sampling noise.\n\n\
         Reproduce: `lensbake bench render --models M --backends B --spp N` (rows accumulate in \
         timings.json).\n\n\
         | backend | spp | model | seconds | PSNR vs reference | mean abs error |\n\
         |---|---|---|---|---|---|\n",
        lens = f.lens,
        w = f.width,
        h = f.height,
        focus = f.focus_mm,
        fnum = f.f_number,
        layers = f.layers,
        res = f.table_resolution.map(|n| n.to_string()).join("x"),
    );
    for r in &rows {
        let db = r.psnr_vs_reference_db.map_or("-".to_string(), psnr_text);
        let mae = r
            .mean_abs_error
            .map_or("-".to_string(), |v| format!("{v:.2e}"));
        text += &format!(
            "| {} | {} | {} | {:.2} | {db} | {mae} |\n",
            r.backend, r.samples_per_pixel, r.model, r.seconds
        );
    }
    text
}

/// How a bench frame is made from the layers: sampled through the lens, or filtered by a
/// real-time model's kernels.
#[derive(Clone, Copy)]
enum Filter {
    Sampled,
    Postfx(PostfxPath),
    Layered,
}

/// Rows sort cheapest model first, as [`ModelKind`] lists them.
fn model_rank(model: &str) -> usize {
    model
        .parse::<ModelKind>()
        .map_or(ModelKind::ALL.len(), |kind| kind as usize)
}
