//! `lensbake plot` and `lensbake report`.

use anyhow::bail;
use clap::Args;
use lensbake::lenses::{self, BUNDLED, LensOrigin};
use lensbake::plot::write_plot;
use lensbake::prescription::formats::LoadOptions;
use lensbake::report::{FigureOptions, PlotKind, figure, write_report};
use lensbake::system::LensSystem;
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct PlotArgs {
    /// layout, ray-fan, spot, lsa, field-curves, distortion, lateral-color, vignetting, seidel,
    /// lrtf-error.
    kind: String,
    /// A lens file or the name of a bundled lens; for lrtf-error the measurement table
    /// (lrtf-error.json, written by the lrtf_sweep example).
    lens: String,
    /// Output file; .png or .svg.
    #[arg(long)]
    out: PathBuf,
    /// Largest half-field angle to plot (degrees; default: the largest traceable field).
    #[arg(long)]
    field_deg: Option<f64>,
    /// Wavelengths to draw (nm), comma separated (default: F, d, C or the design wavelength).
    #[arg(long, value_delimiter = ',', num_args = 1..)]
    wavelength_nm: Vec<f64>,
}

#[derive(Args, Debug)]
pub struct ReportArgs {
    /// A lens file or the name of a bundled lens.
    #[arg(required_unless_present = "all", conflicts_with = "all")]
    lens: Option<String>,
    /// Report every bundled lens, each in its own directory under --out.
    #[arg(long)]
    all: bool,
    /// Output directory (default: notebooks-out/<lens>/; with --all, the parent directory).
    #[arg(long)]
    out: Option<PathBuf>,
}

pub fn run_plot(args: PlotArgs) -> anyhow::Result<()> {
    if args.kind == "lrtf-error" {
        return super::lrtf::plot_error(Path::new(&args.lens), &args.out);
    }
    let kind: PlotKind = args.kind.parse()?;
    let (name, system) = load_lens(&args.lens)?;
    let options = FigureOptions {
        field_deg: args.field_deg,
        wavelengths_nm: args.wavelength_nm,
    };
    check_options(&options)?;
    let view = figure(kind, &name, &system, &options)?;
    let drawn = write_plot(&view, &args.out)?;
    for message in drawn.messages() {
        eprintln!("note: {message}");
    }
    say!("{}", args.out.display());
    Ok(())
}

pub fn run_report(args: ReportArgs) -> anyhow::Result<()> {
    let lenses: Vec<String> = match &args.lens {
        Some(lens) => vec![lens.clone()],
        None => BUNDLED.iter().map(|b| b.name.to_string()).collect(),
    };
    if lenses.is_empty() {
        bail!("no bundled lenses in this build");
    }
    for lens in lenses {
        let (name, system) = load_lens(&lens)?;
        let directory = match (&args.out, args.all) {
            (Some(out), false) => out.clone(),
            (Some(out), true) => out.join(&name),
            (None, _) => Path::new("notebooks-out").join(&name),
        };
        let written = write_report(&name, &system, &FigureOptions::default(), &directory)?;
        for (kind, reason) in &written.skipped {
            eprintln!("note: {name}: {kind} skipped: {reason}");
        }
        say!("{}", written.directory.display());
    }
    Ok(())
}

fn check_options(options: &FigureOptions) -> anyhow::Result<()> {
    if let Some(field) = options.field_deg
        && !(field.is_finite() && (0.0..90.0).contains(&field))
    {
        bail!("--field-deg must be in [0, 90), got {field}");
    }
    Ok(())
}

/// The lens `spec` names (a file or a bundled lens) and the name its plots carry.
fn load_lens(spec: &str) -> anyhow::Result<(String, LensSystem)> {
    let lens = lenses::load(spec, &LoadOptions::default())?;
    for note in &lens.source.loaded.notes {
        eprintln!("note: {}: {note}", lens.source.origin);
    }
    let name = match &lens.source.origin {
        LensOrigin::Bundled(name) => name.to_string(),
        LensOrigin::File(path) => path
            .file_stem()
            .map_or_else(|| spec.to_string(), |s| s.to_string_lossy().into_owned()),
    };
    Ok((name, lens.system))
}
