//! `lensbake tradeoff`: every lens model's cost and error side by side, and the error-budget
//! choice behind `lensbake bake --error-budget-px` (`render --error-budget-px` is the library's
//! `RenderJob`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context;
use clap::Args;
use serde::Serialize;

use super::lens::LensArgs;
use lensbake::job::tables::{DEFAULT_TABLES_ROOT, default_table_dir};
use lensbake::lenses::LoadedLens;
use lensbake::limits;
use lensbake::lrtf::io::write_table;
use lensbake::model::ModelKind;
use lensbake::output::write_bytes;
use lensbake::plot::{ParetoPlot, ParetoPoint, write_plot};
use lensbake::render::reference::psnr_text;
use lensbake::render::scene::Scene;
use lensbake::tradeoff::choose::{Choice, choose_model};
use lensbake::tradeoff::render::RenderBench;
use lensbake::tradeoff::{Domain, Entry, Measured, SceneRequirements, tradeoff};

/// What the scene asks of the lens (shared by `tradeoff` and `bake --error-budget-px`).
#[derive(Args, Debug, Clone, Default)]
pub struct SceneArgs {
    /// `demo`: the renderer's demo scene (focus 2000 mm, its nearest panel). Explicit options
    /// below override it.
    #[arg(long)]
    pub scene: Option<String>,
    /// Nearest scene surface, mm in front of surface 1 (default: far away).
    #[arg(long)]
    pub nearest_mm: Option<f64>,
    /// Fraction of the default film radius the image uses, in (0, 1].
    #[arg(long)]
    pub film_fraction: Option<f64>,
}

impl SceneArgs {
    /// Whether any of the scene's options is given.
    pub fn any(&self) -> bool {
        self.scene.is_some() || self.nearest_mm.is_some() || self.film_fraction.is_some()
    }

    fn requirements(
        &self,
        focus_mm: Option<f64>,
        f_number: Option<f64>,
    ) -> anyhow::Result<SceneRequirements> {
        let mut req = SceneRequirements {
            focus_mm,
            f_number,
            ..SceneRequirements::default()
        };
        match self.scene.as_deref() {
            None => {}
            Some("demo") => {
                req.focus_mm = req.focus_mm.or(Some(2000.0));
                req.nearest_mm = Scene::demo().nearest_distance_mm();
            }
            Some(other) => anyhow::bail!("--scene {other}: only `demo` is known"),
        }
        req.nearest_mm = self.nearest_mm.or(req.nearest_mm);
        req.film_fraction = self.film_fraction.unwrap_or(req.film_fraction);
        Ok(req)
    }
}

#[derive(Args, Debug)]
pub struct TradeoffArgs {
    #[command(flatten)]
    pub lens: LensArgs,
    #[command(flatten)]
    pub scene: SceneArgs,
    /// Object distance in focus, mm in front of surface 1 (default: the lens file's object
    /// distance, else infinity).
    #[arg(long)]
    pub focus_mm: Option<f64>,
    /// f-number [default: the lens file's aperture where the stop allows it, else wide open].
    #[arg(long)]
    pub f_number: Option<f64>,
    /// Random film-side rays every model is measured on.
    #[arg(long, default_value_t = 20_000)]
    pub rays: usize,
    /// Width in pixels of the demo-scene frame each model renders (CPU twin).
    #[arg(long, default_value_t = 160)]
    pub render_width: u32,
    #[arg(long, default_value_t = 120)]
    pub render_height: u32,
    #[arg(long, default_value_t = 16)]
    pub render_spp: u32,
    /// Frames timed per model (the cost is their median).
    #[arg(long, default_value_t = 3)]
    pub render_frames: usize,
    /// Print {"entries": [...]} instead of the table (the files in --out are written either way).
    #[arg(long)]
    pub json: bool,
    /// Output directory (default: notebooks-out/tradeoff/<lens>/).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

#[derive(Serialize)]
struct Entries<'a> {
    entries: Vec<&'a Entry>,
}

fn markdown(
    lens: &str,
    domain: &Domain,
    measured: &[Measured],
    rays: usize,
    bench: &RenderBench,
) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Speed against accuracy: {lens}\n");
    let _ = writeln!(
        s,
        "Domain: film at z = {:.4} mm, film radius {:.3} mm (default {:.3} mm), f/{:.3}, EFL {:.3} mm, \
         focus {}, nearest scene surface {}, {:.2} nm. {rays} random film-side rays drawn as the \
         renderer draws them; errors over the rays both the model and the exact trace pass. \
         Image error: EFL x angle / pixel pitch ({:.2} um, a 3:2 frame 1920 px wide in the image \
         circle){}.\n",
        domain.film_z,
        domain.film_radius,
        domain.full_film_radius,
        domain.f_number,
        domain.efl,
        domain
            .focus_mm
            .map_or("infinity".into(), |d| format!("{d} mm")),
        domain
            .nearest_mm
            .map_or("far".into(), |d| format!("{d} mm")),
        domain.wavelength_nm,
        domain.pixel_pitch * 1e3,
        if domain.nearest_mm.is_some() {
            ", plus the rays' offset over the nearest depth"
        } else {
            ""
        }
    );
    let _ = writeln!(
        s,
        "| model | bake s | bytes | render ms/frame | image PSNR vs traced | direction p99 mrad | direction max mrad | image p50 px | image p99 px | image max px | validity mismatch | rays compared |"
    );
    let _ = writeln!(
        s,
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    );
    for m in measured {
        let e = &m.entry;
        let _ = writeln!(
            s,
            "| {} | {:.4} | {} | {:.1} | {} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} | {:.4} % | {} |",
            m.label,
            e.bake_seconds,
            e.table_bytes,
            e.render_ms_per_frame,
            m.render.psnr_db.map_or("reference".into(), psnr_text),
            e.ray_error_p99_mrad,
            m.error.direction_mrad.max,
            m.error.image_px.median,
            e.image_error_px_p99,
            m.error.image_px.max,
            100.0 * m.error.validity_mismatch,
            m.error.compared,
        );
    }
    let _ = writeln!(
        s,
        "\nNotes:\n\n- traced is the reference: the exact backward trace, zero error by definition.\n\
         - thin, thick and Seidel have no apertures: their validity mismatch counts the rays the real \
         lens vignettes (a renderer samples their own exit pupil instead).\n\
         - f16 tables are the f32 bake rounded to f16, exactly what `bake --precision f16` stores; \
         they share its bake time.\n\
         - bytes: the model's data in memory (table entries for baked tables, the surface records \
         for traced).\n\
         - render ms/frame: median wall clock of {frames} frame(s) of the demo scene, {w}x{h} \
         pixels, {spp} samples per pixel, seed {seed}, on the CPU twin of the IBRT kernel (2 \
         shared cores: indicative, not a benchmark); every model renders the same layers with \
         the same seed, the film a {w}:{h} frame inscribed in the domain's image circle, and \
         traced and baked draw identical lens samples on the largest table's effective pupil.\n\
         - image PSNR: the frame against the traced frame (display range 0..1). It is a separate \
         image error; image p99 px stays the ray-derived error above. thin, thick and Seidel \
         sample their own exit pupil; the Seidel frame is blank where its inverse map does not \
         settle.",
        frames = bench.frames.max(1),
        w = bench.width,
        h = bench.height,
        spp = bench.samples_per_pixel,
        seed = bench.seed,
    );
    s
}

fn pareto(lens: &str, measured: &[Measured], bench: &RenderBench) -> ParetoPlot {
    let points = measured
        .iter()
        .filter(|m| m.entry.image_error_px_p99 > 0.0)
        .map(|m| ParetoPoint {
            label: m.label.clone(),
            group: match m.entry.precision {
                Some(p) => format!("baked {p}"),
                None => m.entry.model.name().to_string(),
            },
            cost: m.entry.render_ms_per_frame,
            error: m.entry.image_error_px_p99,
        })
        .collect();
    ParetoPlot {
        title: format!("{lens}: render time against image error (p99, 1920 px)"),
        cost_label: format!(
            "render ms/frame ({}x{}, {} spp, CPU twin, log)",
            bench.width, bench.height, bench.samples_per_pixel
        ),
        error_label: "image error p99 (px at 1920 px, log)".into(),
        points,
        notes: vec![format!(
            "traced: the reference (zero error, not on log axes), {} ms/frame",
            measured
                .iter()
                .find(|m| m.entry.model == ModelKind::Traced)
                .map_or("n/a".into(), |m| format!(
                    "{:.1}",
                    m.entry.render_ms_per_frame
                ))
        )],
    }
}

pub fn run(args: TradeoffArgs) -> anyhow::Result<()> {
    let loaded = args.lens.load()?;
    let name = loaded.source.origin.name();
    let (f_number, file_focus) =
        super::lrtf::stated_choices(&loaded, args.f_number, args.focus_mm.is_some())?;
    let req = args
        .scene
        .requirements(args.focus_mm.or(file_focus), f_number)?;
    if args.rays == 0 {
        anyhow::bail!("--rays must be positive");
    }
    limits::check("--rays", args.rays as u64, limits::MAX_RAYS)?;
    if args.render_frames == 0 {
        anyhow::bail!("--render-frames must be at least 1 (the cost is their median)");
    }
    let bench = RenderBench {
        width: args.render_width,
        height: args.render_height,
        samples_per_pixel: args.render_spp,
        frames: args.render_frames,
        ..RenderBench::default()
    };
    let progress = super::demo::stage(&format!(
        "measuring every model of {name} (bakes, traces and renders)"
    ));
    let measured = tradeoff(&loaded.system, &req, args.rays, 7, &bench);
    progress.finish_and_clear();
    let (domain, measured) = measured?;
    let finite = measured.iter().all(|m| {
        let e = &m.entry;
        e.bake_seconds.is_finite()
            && e.ray_error_p99_mrad.is_finite()
            && e.image_error_px_p99.is_finite()
            && e.render_ms_per_frame.is_finite()
            && m.render.psnr_db.is_none_or(|db| !db.is_nan())
    });
    if !finite {
        anyhow::bail!("a model produced a non-finite error; nothing written");
    }
    let entries = Entries {
        entries: measured.iter().map(|m| &m.entry).collect(),
    };
    let json = serde_json::to_string_pretty(&entries)?;
    let out = args
        .out
        .unwrap_or_else(|| Path::new("notebooks-out/tradeoff").join(&name));
    std::fs::create_dir_all(&out).with_context(|| format!("creating {}", out.display()))?;
    write_bytes(&out.join("tradeoff.json"), format!("{json}\n").as_bytes())?;
    let md = markdown(&name, &domain, &measured, args.rays, &bench);
    write_bytes(&out.join("tradeoff.md"), md.as_bytes())?;
    write_plot(&pareto(&name, &measured, &bench), &out.join("pareto.png"))?;
    if args.json {
        say!("{json}");
    } else {
        say_raw!("{md}");
        say!(
            "\nwrote tradeoff.md, tradeoff.json and pareto.png to {}",
            out.display()
        );
    }
    Ok(())
}

/// Prints a choice: the model, its domain, and predicted against measured error.
fn report(choice: &Choice) {
    say!(
        "chose {} for a {:.3} px budget: predicted {:.3} px, measured {:.3} px (p99, 1920 px)",
        choice.label,
        choice.budget_px,
        choice.predicted_px,
        choice.measured_px
    );
    say!(
        "  domain: film radius {:.3} of {:.3} mm, f/{:.3}, focus {}, wavelengths {:?} nm (lateral colour {:.3} px)",
        choice.domain.film_radius,
        choice.domain.full_film_radius,
        choice.domain.f_number,
        choice
            .domain
            .focus_mm
            .map_or("infinity".into(), |d| format!("{d} mm")),
        choice.wavelengths_nm,
        choice.lateral_colour_px
    );
    for c in &choice.considered {
        say!(
            "  considered {}: predicted {:.3} px, {}",
            c.label,
            c.predicted_px,
            c.measured_px
                .map_or("not built".into(), |m| format!("measured {m:.3} px"))
        );
    }
}

/// `bake --error-budget-px`: bake the cheapest table meeting the budget, or say that no table
/// is needed (a first-order or Seidel model meets it) or that only the trace does.
pub fn bake_within_budget(
    lens: &LoadedLens,
    budget_px: f64,
    scene: &SceneArgs,
    focus_mm: Option<f64>,
    f_number: Option<f64>,
    out: Option<PathBuf>,
) -> anyhow::Result<()> {
    let name = lens.source.origin.name();
    let req = scene.requirements(focus_mm, f_number)?;
    let choice = choose_model(&lens.system, &req, budget_px)?;
    report(&choice);
    match &choice.table {
        Some(table) => {
            // Where a plain `bake` at this focus would put it, so a later bake at another
            // focus does not overwrite it and the renderer finds it by its focus.
            let out = out.unwrap_or_else(|| {
                default_table_dir(
                    Path::new(DEFAULT_TABLES_ROOT),
                    &name,
                    choice.domain.focus_mm,
                )
            });
            write_table(table, &name, &lens.system.prescription, &out)?;
            say!("wrote {}", out.display());
        }
        None => say!("no table written: the {} model needs none", choice.label),
    }
    Ok(())
}
