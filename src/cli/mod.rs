//! One module per subcommand; each turns parsed arguments into library calls and prints.

/// A `note:` line on stderr, through [`notes`] (held until the command releases them).
macro_rules! note {
    ($($arg:tt)*) => {
        $crate::cli::notes::note(format!($($arg)*))
    };
}

/// `println!` through [`stdout`]: a closed stdout never panics or stops the job.
macro_rules! say {
    ($($arg:tt)*) => {
        $crate::cli::stdout::write(format_args!($($arg)*), true)
    };
}

/// `print!` through [`stdout`].
macro_rules! say_raw {
    ($($arg:tt)*) => {
        $crate::cli::stdout::write(format_args!($($arg)*), false)
    };
}

mod analyze;
mod analyze_afocal;
mod analyze_placed;
mod bench;
mod bench_render;
mod demo;
mod export;
mod glass;
mod lens;
mod lrtf;
pub mod notes;
mod plot;
mod render;
pub mod stdout;
mod trace;
mod tradeoff;
mod view;
mod wave;

use clap::{Parser, Subcommand};

#[derive(Parser, Debug)]
#[command(
    name = "lensbake",
    version,
    about = "Lens design analysis and LRTF precomputation"
)]
pub struct Cli {
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Read, validate, convert and list lens prescriptions.
    #[command(subcommand)]
    Lens(lens::LensCommand),
    /// List the built-in glass catalogues or show one glass.
    #[command(subcommand)]
    Glass(glass::GlassCommand),
    /// First-order data, pupils and Seidel sums of a lens.
    Analyze(analyze::AnalyzeArgs),
    /// Render depth of field through a lens model (image-based ray tracing).
    Render(render::RenderArgs),
    /// The main job: analyse the default lens, bake its table, render traced and baked, and
    /// write images, error map, timings and plots to notebooks-out/demo/.
    Demo(demo::DemoArgs),
    /// Draw one aberration plot of a lens as PNG or SVG.
    Plot(plot::PlotArgs),
    /// Write a lens's report (tables and every plot) to a directory.
    Report(plot::ReportArgs),
    /// Bake a lens ray transfer function table and its effective-pupil bounds.
    Bake(lrtf::BakeArgs),
    /// Take a lens into another engine: the sampler, lens trace and renderer as GLSL, HLSL,
    /// MSL, SPIR-V or WGSL, and a baked table packed for the sampler (docs/engines.md).
    #[command(subcommand)]
    Export(export::ExportCommand),
    /// Evaluate or describe baked LRTF tables.
    #[command(subcommand)]
    Lrtf(lrtf::LrtfCommand),
    /// Trace exact rays through a lens (JSON in, JSON out).
    Trace(trace::TraceArgs),
    /// Measure throughput.
    #[command(subcommand)]
    Bench(bench::BenchCommand),
    /// Every lens model's cost and error side by side, with a Pareto plot.
    Tradeoff(tradeoff::TradeoffArgs),
    /// Wavefront error of one field point: OPD RMS and peak-to-valley, Strehl, Zernike fit.
    Wavefront(wave::WavefrontArgs),
    /// Diffraction MTF (tangential, sagittal, diffraction limit) of one field point.
    Mtf(wave::MtfArgs),
    /// Point spread function of one field point, written as OpenEXR or PNG.
    Psf(wave::PsfArgs),
    /// A real-time viewer: progressive IBRT through a lens with click-to-focus, live model
    /// switching and a baked-versus-traced split view; scripted and headless runs for tests.
    View(view::ViewArgs),
}

pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Lens(command) => lens::run(command),
        Command::Glass(command) => glass::run(command),
        Command::Analyze(args) => analyze::run(args),
        Command::Render(args) => render::run(args),
        Command::Demo(args) => demo::run(args),
        Command::Plot(args) => plot::run_plot(args),
        Command::Report(args) => plot::run_report(args),
        Command::Bake(args) => lrtf::run_bake(args),
        Command::Export(command) => export::run(command),
        Command::Lrtf(command) => lrtf::run(command),
        Command::Trace(args) => trace::run(args),
        Command::Bench(command) => bench::run(command),
        Command::Tradeoff(args) => tradeoff::run(args),
        Command::Wavefront(args) => wave::run_wavefront(args),
        Command::Mtf(args) => wave::run_mtf(args),
        Command::Psf(args) => wave::run_psf(args),
        Command::View(args) => view::run(args),
    }
}
