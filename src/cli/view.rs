//! `lensbake view`: the real-time viewer, in a window or headless (`--offscreen`), optionally
//! driven by a script. Parses the arguments into a [`RenderJob`] and a [`Session`] and prints
//! what the session reports.

use super::lens::ReadArgs;
use super::render::{BackendArg, ChromaticArg, backend_line};
use anyhow::Context;
use clap::Args;
use lensbake::job::{DEFAULT_FOCUS_MM, FocusMode, ModelChoice, RenderJob, SceneSpec};
use lensbake::limits::read_input_text;
use lensbake::model::ModelKind;
use lensbake::render::RenderSettings;
use lensbake::view::keys::keys_help;
use lensbake::view::script::parse_script;
use lensbake::view::window::run_window;
use lensbake::view::{Session, Step, ViewEvent, Viewer};
use std::path::PathBuf;

#[derive(Args, Debug)]
#[command(after_help = format!("Keys in the window: {}.", keys_help()))]
pub struct ViewArgs {
    /// Lens: a lens file, a bundled lens name (`lensbake lens list`) or `ideal:<EFL_MM>`.
    #[arg(long)]
    lens: String,
    #[command(flatten)]
    read: ReadArgs,
    /// `demo`, a glTF 2.0 file (.gltf or .glb) or an OpenEXR file with R, G, B and Z.
    #[arg(long, default_value = "demo")]
    scene: String,
    /// Lens model: thin, thick, seidel, traced or baked (a table is baked on a worker thread
    /// when none covers the view; the traced model is shown meanwhile); not postfx yet.
    #[arg(long, default_value = "traced", value_parser = super::lens::model_parser())]
    model: ModelKind,
    #[arg(long, default_value_t = 800)]
    width: u32,
    #[arg(long, default_value_t = 600)]
    height: u32,
    /// Samples per pixel accumulated in all (rounded up to a multiple of --spp-per-frame); the
    /// finished image has exactly the samples of `lensbake render --spp` with this value.
    #[arg(long, default_value_t = 256)]
    spp: u32,
    /// Samples per pixel rendered each frame.
    #[arg(long, default_value_t = 4)]
    spp_per_frame: u32,
    /// f-number; default: the lens wide open (f/2.8 for `ideal:`).
    #[arg(long)]
    f_number: Option<f64>,
    /// Focus on the plane this far in front of the first vertex (mm) at the start.
    #[arg(long, default_value_t = DEFAULT_FOCUS_MM)]
    focus_mm: f64,
    /// Sensor width (mm), as `render --film-mm` [default: full frame, or the largest frame
    /// inside the image circle of a lens whose circle is smaller than half its height].
    #[arg(long)]
    film_mm: Option<f64>,
    #[arg(long, value_enum, default_value = "auto")]
    backend: BackendArg,
    #[arg(long, value_enum, default_value = "off")]
    chromatic: ChromaticArg,
    #[arg(long, default_value_t = 1)]
    seed: u32,
    /// Most depth-peeled layers per pixel.
    #[arg(long, default_value_t = 8)]
    max_layers: usize,
    /// Nodes per axis when a table has to be baked.
    #[arg(long, default_value_t = 64)]
    bake_resolution: usize,
    /// Where tables are found and baked (a folder per lens inside).
    #[arg(long, default_value = "tables")]
    tables_root: PathBuf,
    /// A script, one action a line: spp-per-frame N, click X Y, fnumber F, model NAME,
    /// split on|off, overlay on|off, chromatic on|off, shift X Y, tilt X Y, lens NAME|FILE,
    /// scene demo|FILE, frames N, wait-bake, screenshot PATH, window W H, minimise on|off, quit.
    #[arg(long)]
    script: Option<PathBuf>,
    /// Run the same loop without a window (tests, CI, machines without a display); with no
    /// script and no --frames it renders until --spp samples are in.
    #[arg(long)]
    offscreen: bool,
    /// Exit after this many frames.
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=lensbake::limits::MAX_VIEW_FRAMES))]
    frames: Option<u64>,
}

pub fn run(args: ViewArgs) -> anyhow::Result<()> {
    if args.model.is_realtime() {
        let model = args.model;
        anyhow::bail!(
            "--model {model}: the viewer accumulates sample passes and {model} has none; render \
             it with `lensbake render --model {model}`"
        );
    }
    // The script is read and parsed whole before anything renders.
    let script = match &args.script {
        Some(path) => {
            let text = read_input_text(path)
                .with_context(|| format!("cannot read the script {}", path.display()))?;
            parse_script(&text, path)?
        }
        None => Vec::new(),
    };
    let lens = super::lens::render_lens(&args.lens, &args.read)?;
    let job = RenderJob {
        model: ModelChoice::Model(args.model),
        bake_resolution: args.bake_resolution,
        tables_root: args.tables_root.clone(),
        scene: SceneSpec::parse(&args.scene),
        backend: args.backend.into(),
        settings: RenderSettings {
            width: args.width,
            height: args.height,
            samples_per_pixel: args.spp,
            seed: args.seed,
            max_layers: args.max_layers,
        },
        f_number: args.f_number,
        focus: FocusMode::Distance(args.focus_mm),
        film_width_mm: args.film_mm,
        chromatic: args.chromatic.into(),
        ..RenderJob::new(lens)
    };
    let viewer = Viewer::new(job, args.spp_per_frame)?;
    say!("{}", backend_line(viewer.backend()));
    let script_file = args.script.clone().unwrap_or_default();
    let mut session = Session::new(viewer, script, script_file, args.frames)?;
    let mut report = |event: &ViewEvent| match event {
        ViewEvent::Screenshot(path) => say!("wrote {}", path.display()),
        ViewEvent::TableReady { dir, baked_now } => say!(
            "table {} {}",
            dir.display(),
            if *baked_now { "baked" } else { "loaded" }
        ),
        ViewEvent::BakeFailed(why) => say!("note: the bake failed ({why}); showing traced"),
        ViewEvent::Refused(why) | ViewEvent::Note(why) => say!("note: {why}"),
    };
    if args.offscreen {
        loop {
            let step = session.step()?;
            for event in session.viewer.take_events() {
                report(&event);
            }
            if matches!(step, Step::Quit | Step::Idle) {
                break;
            }
        }
    } else {
        run_window(&mut session, &session_title(&args), &mut report)?;
    }
    for line in session.viewer.hud_lines() {
        say!("hud: {line}");
    }
    let (samples, target) = session.viewer.samples();
    let mean = session.viewer.mean_frame().unwrap_or_default();
    say!(
        "{} frames, {samples}/{target} samples per pixel, {:.1} ms per rendered frame (mean)",
        session.frames(),
        mean.as_secs_f64() * 1e3
    );
    if let Some(gpu) = session.viewer.gpu() {
        let (uploads, readbacks) = gpu.transfers();
        say!("GPU transfers: {uploads} render uploads, {readbacks} readbacks");
    }
    Ok(())
}

fn session_title(args: &ViewArgs) -> String {
    format!("lensbake view: {}", args.lens)
}
