//! `lensbake plot` and `lensbake report`.

use anyhow::bail;
use clap::Args;

use super::lens::{AimingArg, LensArgs, ReadArgs};
use lensbake::lenses::{self, BUNDLED, LensError, LensOrigin};
use lensbake::plot::write_plot;
use lensbake::prescription::{PrescriptionError, Problem};
use lensbake::report::{FigureOptions, PlotKind, figure, placed_spot_plot, write_report};
use lensbake::system::LensSystem;
use std::path::{Path, PathBuf};

#[derive(Args, Debug)]
pub struct PlotArgs {
    #[arg(help = kind_help())]
    kind: String,
    /// A lens file or the name of a bundled lens; for lrtf-error the measurement table
    /// (lrtf-error.json, written by the lrtf_sweep example).
    lens: String,
    /// Output file; .png or .svg.
    #[arg(long)]
    out: PathBuf,
    #[command(flatten)]
    read: ReadArgs,
    #[command(flatten)]
    conditions: ConditionArgs,
}

/// The kinds `plot` draws, listed from [`PlotKind::ALL`] so the help cannot fall behind it.
fn kind_help() -> String {
    format!("{}, lrtf-error", PlotKind::names())
}

/// The design-condition flags `plot` and `report` share with `analyze`: each overrides the
/// lens's design conditions (docs/conditions.md) in every plot and table alike.
#[derive(Args, Debug, Default)]
pub struct ConditionArgs {
    /// Top half-field angle in degrees [default: the lens file's largest field, else the
    /// source's claimed half field, else the largest whose real chief ray passes, at most 45].
    #[arg(long)]
    field_deg: Option<f64>,
    /// Wavelengths to draw (nm), comma separated, the first the reference [default: the lens
    /// file's, else F, d, C for a dispersive lens, else the design wavelength].
    #[arg(long, value_delimiter = ',', num_args = 1..)]
    wavelength_nm: Vec<f64>,
    /// Entrance-pupil diameter in mm [default: the lens file's aperture, else the source's
    /// claimed f-number where the stop allows it, else the stop wide open].
    #[arg(long)]
    epd_mm: Option<f64>,
    /// Object distance from the first vertex in mm [default: the lens file's, else infinity];
    /// a finite object's points are traced where they are, and named by the angle their chief
    /// ray makes at the entrance-pupil centre; negative for a virtual object.
    #[arg(long, allow_negative_numbers = true)]
    object_distance_mm: Option<f64>,
    /// How a relative pupil coordinate becomes a real ray in the fans, spots, LSA and wave
    /// plots: at that point of the paraxial entrance pupil, or through that point of the stop
    /// [default: the lens file's (Zemax RAIM), else paraxial].
    #[arg(long, value_enum)]
    ray_aiming: Option<AimingArg>,
}

impl ConditionArgs {
    fn options(&self) -> anyhow::Result<FigureOptions> {
        let options = FigureOptions {
            field_deg: self.field_deg,
            wavelengths_nm: self.wavelength_nm.clone(),
            epd_mm: self.epd_mm,
            object_distance_mm: self.object_distance_mm,
            ray_aiming: self.ray_aiming.map(Into::into),
        };
        check_options(&options)?;
        Ok(options)
    }
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
    #[command(flatten)]
    read: ReadArgs,
    #[command(flatten)]
    conditions: ConditionArgs,
}

pub fn run_plot(args: PlotArgs) -> anyhow::Result<()> {
    if args.kind == "lrtf-error" {
        return super::lrtf::plot_error(Path::new(&args.lens), &args.out);
    }
    let kind: PlotKind = args.kind.parse()?;
    let options = args.conditions.options()?;
    // A lens placed off one axis has spot diagrams from the 3-D trace; every other plot needs a
    // rotationally symmetric lens, and loading says so.
    if kind == PlotKind::Spot
        && let Err(LensError::Prescription(PrescriptionError {
            problem: Problem::NotRotationallySymmetric { lens, .. },
            ..
        })) = lenses::read(&args.lens, &args.read.options())
    {
        let view = placed_spot_plot(&plot_name(&args.lens), &lens, &options)?;
        let drawn = write_plot(&view, &args.out)?;
        for message in drawn.messages() {
            note!("{message}");
        }
        say!("{}", args.out.display());
        return Ok(());
    }
    let (name, system) = load_lens(&args.lens, &args.read)?;
    let view = figure(kind, &name, &system, &options)?;
    let drawn = write_plot(&view, &args.out)?;
    // The figure resolved these conditions already, so they resolve here too.
    if let Ok(conditions) = options.conditions(&system) {
        for message in &conditions.notes {
            note!("{message}");
        }
    }
    for message in drawn.messages() {
        note!("{message}");
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
    let options = args.conditions.options()?;
    for lens in lenses {
        let (name, system) = load_lens(&lens, &args.read)?;
        let directory = match (&args.out, args.all) {
            (Some(out), false) => out.clone(),
            (Some(out), true) => out.join(&name),
            (None, _) => Path::new("notebooks-out").join(&name),
        };
        let progress = super::demo::stage(&format!("writing the report of {name}"));
        let written = write_report(&name, &system, &options, &directory);
        progress.finish_and_clear();
        let written = written?;
        for (kind, reason) in &written.skipped {
            note!("{name}: {kind} skipped: {reason}");
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
    // The lengths every other command takes (the wave commands' `--epd-mm` too).
    if let Some(epd) = options.epd_mm {
        lensbake::limits::check_length("--epd-mm", epd)?;
    }
    Ok(())
}

/// The lens `spec` names (a file or a bundled lens) and the name its plots carry.
fn load_lens(spec: &str, read: &ReadArgs) -> anyhow::Result<(String, LensSystem)> {
    let lens = LensArgs {
        lens: spec.to_string(),
        read: read.clone(),
    }
    .load()?;
    super::lens::note_reading(&lens.source);
    let name = match &lens.source.origin {
        LensOrigin::Bundled(name) => name.to_string(),
        LensOrigin::File(_) => plot_name(spec),
    };
    Ok((name, lens.system))
}

/// The name a lens file's plots carry: its file name without the extension.
fn plot_name(spec: &str) -> String {
    Path::new(spec)
        .file_stem()
        .map_or_else(|| spec.to_string(), |s| s.to_string_lossy().into_owned())
}
