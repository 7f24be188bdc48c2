//! `lensbake demo`: the main job. Analyse the default lens, bake its table, render the demo
//! scene through the exact (traced) and the baked lens, and write the images, the error map
//! between them, timings and the lens report to notebooks-out/demo/.

use super::lens::ReadArgs;
use clap::Args;
use indicatif::{ProgressBar, ProgressStyle};
use lensbake::job::tables::DEFAULT_TABLES_ROOT;
use lensbake::job::tables::chromatic_table_dir;
use lensbake::job::{RenderLens, TracedAndBaked, default_table_dir};
use lensbake::plot::{ErrorMapPlot, write_plot};
use lensbake::render::camera::{Camera, Film};
use lensbake::render::chromatic::default_wavelengths;
use lensbake::render::gpu::{GpuRenderer, gpu_worth_using};
use lensbake::render::image::{RgbImage, write_exr, write_png};
use lensbake::render::reference::{psnr, psnr_text};
use lensbake::render::scene::{DEMO_LENS, DEMO_SIZE, Scene};
use lensbake::render::{Backend, RenderSettings, layer_view, render_layers};
use lensbake::report::{FigureOptions, write_report};
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

#[derive(Args, Debug)]
pub struct DemoArgs {
    /// Lens file or bundled lens name (the default is a 50 mm of real glasses, so the render
    /// shows colour).
    #[arg(long, default_value = DEMO_LENS)]
    lens: String,
    #[command(flatten)]
    read: ReadArgs,
    #[arg(long, default_value_t = DEMO_SIZE.0)]
    width: u32,
    #[arg(long, default_value_t = DEMO_SIZE.1)]
    height: u32,
    /// Render one wavelength even when the lens disperses (by default a dispersive lens renders
    /// R, G and B at the C line, its design wavelength and the F line).
    #[arg(long)]
    monochrome: bool,
    #[arg(long, default_value_t = 64)]
    spp: u32,
    /// Table nodes per axis (64^3 bakes in about 1.5 s on two cores).
    #[arg(long, default_value_t = 64)]
    bake_resolution: usize,
    /// Focus distance in front of the first vertex (mm): the demo scene's chart.
    #[arg(long, default_value_t = 2000.0)]
    focus_mm: f64,
    /// `gpu`, `cpu` or `auto` (a GPU adapter when there is one).
    #[arg(long, default_value = "auto")]
    backend: String,
    #[arg(long, default_value_t = 1)]
    seed: u32,
    #[arg(long, default_value = "notebooks-out/demo")]
    out: PathBuf,
}

#[derive(Serialize)]
struct Timings {
    lens: String,
    backend: String,
    width: u32,
    height: u32,
    samples_per_pixel: u32,
    bake_resolution: usize,
    table_baked_now: bool,
    analysis_seconds: f64,
    bake_or_load_seconds: f64,
    /// R, G, B wavelengths (nm) of a chromatic render; null for a monochrome one.
    wavelengths_nm: Option<[f64; 3]>,
    peel_seconds: f64,
    layers: usize,
    traced_render_seconds: f64,
    baked_render_seconds: f64,
    baked_speedup: f64,
    psnr_baked_vs_traced_db: f64,
    mean_abs_error: f64,
    max_abs_error: f64,
}

/// A spinner on stderr naming a long stage, with its elapsed time. indicatif draws it only when
/// stderr is a terminal, so piped and captured output stays as it was.
pub(super) fn stage(message: &str) -> ProgressBar {
    let bar = ProgressBar::new_spinner();
    bar.set_style(ProgressStyle::with_template("{spinner} {msg} {elapsed}").expect("template"));
    bar.set_message(message.to_string());
    bar.enable_steady_tick(Duration::from_millis(200));
    bar
}

fn done(bar: ProgressBar, what: &str, started: Instant) -> f64 {
    let seconds = started.elapsed().as_secs_f64();
    bar.finish_and_clear();
    say!("{what}: {seconds:.2} s");
    seconds
}

/// Per-pixel |a - b| averaged over R, G and B (linear radiance), row-major.
fn error_values(a: &RgbImage, b: &RgbImage) -> Vec<f64> {
    a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| (0..3).map(|c| (p[c] - q[c]).abs() as f64).sum::<f64>() / 3.0)
        .collect()
}

/// The top of the error map's colour scale: the 99.9th percentile of the errors rounded up to
/// 1, 2 or 5 times a power of ten, so the rare largest errors (a vignetting edge, a silhouette)
/// do not flatten the rest into the bottom colour.
fn error_scale(values: &[f64]) -> f64 {
    let mut sorted: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    sorted.sort_by(f64::total_cmp);
    let p999 = sorted
        .get(((sorted.len() as f64 * 0.999) as usize).min(sorted.len().saturating_sub(1)))
        .copied()
        .unwrap_or(0.0)
        .max(1e-6);
    let decade = 10f64.powf(p999.log10().floor());
    [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * decade)
        .find(|&top| top >= p999)
        .unwrap_or(10.0 * decade)
}

/// Writes `text` to `path` through the one atomic writer.
pub(super) fn write_text(path: &Path, text: &str) -> anyhow::Result<()> {
    Ok(lensbake::output::write_bytes(path, text.as_bytes())?)
}

/// Publishes the whole output directory or nothing: a run that fails or is killed part way
/// leaves the previous demo's files as they were.
pub fn run(args: DemoArgs) -> anyhow::Result<()> {
    let (report_files, speedup, psnr) =
        lensbake::output::publish_dir(&args.out, |staging| run_into(&args, staging))?;
    say!(
        "wrote {} ({report_files} report files): baked {speedup:.2}x faster than traced, PSNR {}",
        args.out.display(),
        psnr_text(psnr),
    );
    Ok(())
}

/// The demo, writing into `staging`; returns the report's file count, the baked speed-up and the
/// PSNR of baked against traced.
fn run_into(args: &DemoArgs, staging: &Path) -> anyhow::Result<(usize, f64, f64)> {
    let lens = super::lens::render_lens(&args.lens, &args.read)?;
    let RenderLens::Real(real) = &lens else {
        anyhow::bail!("the demo needs a real lens (a file or bundled name), not `ideal:`");
    };
    let name = real.source.origin.name();
    let (first_order, f_number) = lens.first_order(None)?;

    let started = Instant::now();
    let bar = stage(&format!("analysing {name}"));
    let report = write_report(
        &name,
        &real.system,
        &FigureOptions::default(),
        &staging.join("analysis"),
    )?;
    let analysis_seconds = done(bar, "analysis and plots", started);

    let film = Film::full_frame_for(args.width, args.height);
    let wavelengths_nm =
        (real.system.disperses() && !args.monochrome).then(|| default_wavelengths(&real.system));
    let mono_dir = default_table_dir(Path::new(DEFAULT_TABLES_ROOT), &name, Some(args.focus_mm));
    let table_dir = match wavelengths_nm {
        Some(nm) => chromatic_table_dir(&mono_dir, nm),
        None => mono_dir,
    };
    let started = Instant::now();
    let bar = ProgressBar::new(1);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {percent}% {elapsed}").expect("template"),
    );
    bar.set_message(format!("table {}", table_dir.display()));
    let cameras = TracedAndBaked::new(
        real,
        &first_order,
        f_number,
        film,
        args.focus_mm,
        &table_dir,
        args.bake_resolution,
        wavelengths_nm,
        &|p| {
            bar.set_length(p.total as u64);
            bar.set_position(p.done as u64);
        },
    )?;
    let bake_seconds = done(
        bar,
        if cameras.baked_now {
            "bake and camera set-up"
        } else {
            "table load and camera set-up"
        },
        started,
    );
    let TracedAndBaked {
        traced,
        baked,
        baked_now,
        ..
    } = cameras;

    let settings = RenderSettings {
        width: args.width,
        height: args.height,
        samples_per_pixel: args.spp,
        seed: args.seed,
        max_layers: 8,
    };
    let scene = Scene::demo();
    let started = Instant::now();
    let bar = stage("peeling the demo scene");
    let nearest = scene.nearest_distance_mm().unwrap_or(1000.0) + traced.eye_z();
    let ldi = scene.peel(layer_view(&traced, &settings, nearest), settings.max_layers);
    let peel_seconds = done(bar, "depth peeling", started);

    let (gpu, gpu_passed_over) = match args.backend.as_str() {
        "cpu" => (None, None),
        "gpu" => (Some(GpuRenderer::new()?), None),
        "auto" => {
            match gpu_worth_using().and_then(|()| GpuRenderer::new().map_err(|e| e.to_string())) {
                Ok(gpu) => (Some(gpu), None),
                Err(why) => (None, Some(why)),
            }
        }
        other => anyhow::bail!("--backend {other}: expected gpu, cpu or auto"),
    };
    if let Some(g) = &gpu
        && wavelengths_nm.is_some()
    {
        g.prepare_chromatic()?;
    }
    let (backend, backend_name) = match (&gpu, gpu_passed_over) {
        (Some(g), _) => (Backend::Gpu, format!("gpu ({})", g.adapter_description)),
        (None, Some(why)) => (Backend::Cpu, format!("cpu ({why})")),
        (None, None) => (Backend::Cpu, "cpu".to_string()),
    };
    say!("backend: {backend_name}");
    let render = |camera: &Camera| -> anyhow::Result<(RgbImage, f64)> {
        let started = Instant::now();
        let bar = stage(&format!("rendering {}", camera.model.name()));
        let image = render_layers(camera, &ldi, &settings, backend, gpu.as_ref())?;
        let seconds = done(bar, &format!("{} render", camera.model.name()), started);
        Ok((image, seconds))
    };
    let (traced_image, traced_seconds) = render(&traced)?;
    let (baked_image, baked_seconds) = render(&baked)?;

    let errors = error_values(&baked_image, &traced_image);
    let mean_abs_error = errors.iter().sum::<f64>() / errors.len() as f64;
    let max_abs_error = errors.iter().copied().fold(0.0, f64::max);
    for (image, file) in [(&traced_image, "traced"), (&baked_image, "baked")] {
        write_exr(image, &staging.join(format!("{file}.exr")))?;
        write_png(image, 1.0, &staging.join(format!("{file}.png")))?;
    }
    let scale = error_scale(&errors);
    write_plot(
        &ErrorMapPlot {
            title: format!("{name}: |baked - traced|, mean over R, G, B"),
            width: args.width as usize,
            height: args.height as usize,
            values: errors,
            range: (0.0, scale),
            bar_label: "abs difference (linear radiance)".into(),
        },
        &staging.join("error-map.png"),
    )?;
    let timings = Timings {
        lens: name.clone(),
        backend: backend_name,
        width: args.width,
        height: args.height,
        samples_per_pixel: args.spp,
        bake_resolution: args.bake_resolution,
        table_baked_now: baked_now,
        analysis_seconds,
        bake_or_load_seconds: bake_seconds,
        wavelengths_nm,
        peel_seconds,
        layers: ldi.layer_count(),
        traced_render_seconds: traced_seconds,
        baked_render_seconds: baked_seconds,
        baked_speedup: traced_seconds / baked_seconds,
        psnr_baked_vs_traced_db: psnr(&baked_image, &traced_image),
        mean_abs_error,
        max_abs_error,
    };
    write_text(
        &staging.join("timings.json"),
        &serde_json::to_string_pretty(&timings)?,
    )?;
    let t = &timings;
    let markdown = format!(
        "# lensbake demo: {lens}\n\n\
         `lensbake demo` renders the built-in scene (checkered wall at 6 m, chart at 2 m, a post \
         and bar in front, HDR emitters at 5 m, 1.2 m and 0.3 m whose defocus blur shows the \
         lens's bokeh discs) through the {lens} at f/{f_number:.2}, focused at {focus:.0} mm, \
         {w}x{h} pixels, {spp} samples per pixel, {colour}, on the {backend} backend. The \
         traced image runs the exact sequential trace per sample; the baked one looks rays up \
         in a {res}^3 LRTF table baked for this focus. Both draw the same lens samples on the \
         table's effective-pupil circles, so their difference is the table's error; the error \
         map's colour bar gives its scale in linear radiance.\n\n\
         | traced | baked | abs(baked - traced) |\n|---|---|---|\n\
         | ![traced](traced.png) | ![baked](baked.png) | ![error](error-map.png) |\n\n\
         PSNR baked vs traced: {psnr}; mean abs difference {mean:.2e}, max {max:.2e} (linear \
         radiance, display range 0..1). The analysis and plots are in analysis/. Each stage's \
         wall-clock seconds and the baked/traced speed ratio are printed by the run and written \
         to timings.json, which is not committed: they change from run to run and machine to \
         machine, and this page does not, so a fresh clone stays clean after `lensbake demo`.\n",
        lens = t.lens,
        focus = args.focus_mm,
        w = t.width,
        h = t.height,
        spp = t.samples_per_pixel,
        backend = t.backend,
        res = t.bake_resolution,
        colour = match t.wavelengths_nm {
            Some([r, g, b]) => format!("R, G, B traced at {r:.1}, {g:.1} and {b:.1} nm"),
            None => "one wavelength".to_string(),
        },
        psnr = psnr_text(t.psnr_baked_vs_traced_db),
        mean = t.mean_abs_error,
        max = t.max_abs_error,
    );
    write_text(&staging.join("README.md"), &markdown)?;
    Ok((
        report.files.len(),
        t.baked_speedup,
        t.psnr_baked_vs_traced_db,
    ))
}
