//! `lensbake lens ...`: check, convert and list lens prescriptions.

use anyhow::Context;
use clap::builder::{PossibleValuesParser, TypedValueParser};
use clap::{Args, Subcommand};
use lensbake::analysis::{AnalysisError, ConditionOverrides, DesignConditions};
use lensbake::job::RenderLens;
use lensbake::lenses::{self, BUNDLED, LensError, LensSource, LoadedLens};
use lensbake::model::ModelKind;
use lensbake::prescription::formats::{Format, LoadNote, LoadOptions, PbrtThickness, read_str};
use lensbake::prescription::formats::{OutlineShape, PlacedLens};
use lensbake::prescription::{DEFAULT_WAVELENGTH_NM, Location, PrescriptionError, Problem, Shape};
use lensbake::system::LensSystem;
use lensbake::trace::placed::{PlacedBeam, PlacedBeamError, PlacedTracer, PupilFrom, SPOT_GRID};
use std::path::{Path, PathBuf};

#[derive(Subcommand, Debug)]
pub enum LensCommand {
    /// Read and validate a lens, then print a one-screen summary of it.
    Check(LensArgs),
    /// Convert a lens to lensbake's RON, Zemax .zmx or pbrt .dat (validated first; written
    /// atomically; what a format cannot hold is refused).
    Convert {
        #[command(flatten)]
        input: LensArgs,
        /// Output file: .ron, .zmx or .dat (pbrt).
        #[arg(value_name = "OUT.ron")]
        output: PathBuf,
        /// Write each medium as its constant index at this wavelength (nm), which becomes the
        /// lens's design wavelength; air and mirrors stay as they are. A pbrt file is written
        /// at this wavelength instead of the design wavelength.
        #[arg(long, value_name = "NM")]
        indices_at_nm: Option<f64>,
        /// Allow OUT to be the input file itself. Refused without it: the written file does
        /// not carry the keywords the reader skipped (notes, display settings, ...), so writing
        /// over the input would lose them.
        #[arg(long)]
        overwrite_input: bool,
    },
    /// List the bundled lenses.
    List,
}

/// A lens argument as every subcommand that takes a lens accepts it.
/// `--ray-aiming`: how a relative pupil coordinate becomes a real ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum AimingArg {
    /// At that point of the paraxial entrance pupil (Zemax's ray aiming off).
    Paraxial,
    /// The real ray through that point of the stop (Zemax's real ray aiming).
    Real,
}

impl From<AimingArg> for lensbake::prescription::RayAiming {
    fn from(arg: AimingArg) -> Self {
        match arg {
            AimingArg::Paraxial => lensbake::prescription::RayAiming::Paraxial,
            AimingArg::Real => lensbake::prescription::RayAiming::Real,
        }
    }
}

#[derive(Args, Debug, Clone)]
pub struct LensArgs {
    /// A lens file (.ron, .dat, .txt/.tsv/.csv, .seq, .zmx) or the name of a bundled lens.
    #[arg(value_name = "LENS")]
    pub lens: String,
    #[command(flatten)]
    pub read: ReadArgs,
}

/// How to read a lens file.
#[derive(Args, Debug, Clone, Default)]
pub struct ReadArgs {
    /// Read the file as this format instead of the one its extension implies
    /// (ron, pbrt, table, codev, zemax).
    #[arg(long, value_name = "FORMAT", value_parser = parse_format)]
    pub format: Option<Format>,
    /// pbrt .dat files only: the thickness column is the distance from the PREVIOUS surface
    /// (first row 0), as in the unscaled pbrt-v4-scenes files (dgauss.dat, wide.dat, ...).
    #[arg(long)]
    pub pbrt_from_previous: bool,
    /// Zoom lenses: read this position (1-based) of a CODE V zoom file (`ZOO`), or of a Zemax
    /// multi-configuration file (its active configuration only); position 1 by default.
    #[arg(long, value_name = "K", value_parser = clap::value_parser!(u32).range(1..))]
    pub zoom_position: Option<u32>,
}

fn parse_format(text: &str) -> Result<Format, String> {
    text.parse()
}

impl ReadArgs {
    pub fn options(&self) -> LoadOptions {
        LoadOptions {
            format: self.format,
            pbrt_thickness: if self.pbrt_from_previous {
                PbrtThickness::FromPrevious
            } else {
                PbrtThickness::ToNext
            },
            zoom_position: self.zoom_position.map(|k| k as usize),
        }
    }
}

impl LensArgs {
    /// Reads and validates the lens. A failure carries the reading notes (e.g. the pbrt
    /// thickness hint) after the error itself.
    pub fn load(&self) -> anyhow::Result<LoadedLens> {
        let options = self.read.options();
        validated(lenses::read(&self.lens, &options).map_err(with_hint)?)
    }

    /// Reads the lens for a command that also traces lenses placed off one axis in 3-D.
    pub fn load_or_placed(&self) -> anyhow::Result<Readable> {
        match lenses::read(&self.lens, &self.read.options()) {
            Err(LensError::Prescription(PrescriptionError {
                location,
                problem: Problem::NotRotationallySymmetric { offence, lens },
            })) => Ok(Readable::Placed {
                offence,
                location: *location,
                lens,
            }),
            read => {
                validated(read.map_err(with_hint)?).map(|lens| Readable::Centred(Box::new(lens)))
            }
        }
    }
}

/// A surface's radius for the tables: `flat` for a plane, an ideal lens, or a sphere whose
/// radius does not fit an f64 (curvature 0 or subnormal), which printed as `inf`.
fn radius_text(shape: &Shape) -> String {
    let radius = shape.radius();
    match shape {
        Shape::Plane | Shape::IdealLens { .. } => "flat".to_string(),
        _ if !radius.is_finite() => "flat".to_string(),
        _ => format!("{radius:.4}"),
    }
}

/// A lens as `lens check` and `trace` read it: centred and validated, or placed off one axis
/// (what no centred lens describes; only the 3-D trace reads it).
pub enum Readable {
    Centred(Box<LoadedLens>),
    Placed {
        offence: String,
        location: Location,
        lens: Box<PlacedLens>,
    },
}

/// The lens `source` holds, validated; a failure's reading notes (the pbrt thickness hint
/// among them) follow the error line.
fn validated(source: LensSource) -> anyhow::Result<LoadedLens> {
    match LensSystem::new(source.loaded.prescription.clone(), &source.loaded.map) {
        Ok(system) => Ok(LoadedLens { source, system }),
        Err(error) => {
            note_reading(&source);
            Err(error.into())
        }
    }
}

/// `lens`'s system with every medium's index at `nm` made constant; a medium without an index
/// there is named with its line in the file.
fn at_constant_indices(lens: &LoadedLens, nm: f64) -> anyhow::Result<LensSystem> {
    let map = &lens.source.loaded.map;
    let frozen = lens
        .system
        .prescription
        .with_indices_at(nm)
        .map_err(|e| {
            let location = match (e.location.surface, &e.location.field) {
                (Some(surface), _) => map.surface(surface - 1, "medium"),
                // The object space's medium: the file, and the field's name.
                (None, Some(field)) => map.whole_file().with_field(field.as_str()),
                // The wavelength asked for: no place in the file.
                (None, None) => *e.location,
            };
            PrescriptionError::new(location, e.problem)
        })
        .with_context(|| format!("no constant indices at {nm} nm"))?;
    Ok(LensSystem::new(frozen, map)?)
}

/// The notes of reading `source`, each as a `note:` line naming the lens.
pub(super) fn note_reading(source: &LensSource) {
    for text in &source.loaded.notes {
        note!("{}: {text}", source.origin);
    }
}

/// A render's lens as the command line names it: a lens file or bundled lens, or
/// `ideal:<EFL_MM>` for an ideal thin lens of that focal length.
pub fn render_lens(spec: &str, read: &ReadArgs) -> anyhow::Result<RenderLens> {
    if let Some(efl) = spec.strip_prefix("ideal:") {
        let focal_length_mm = efl
            .parse()
            .with_context(|| format!("lens `{spec}`: bad focal length"))?;
        return Ok(RenderLens::Ideal { focal_length_mm });
    }
    let lens = LensArgs {
        lens: spec.to_string(),
        read: read.clone(),
    }
    .load()?;
    Ok(RenderLens::Real(Box::new(lens)))
}

/// The command line's one parser of lens-model names: the library's, offering its names.
pub fn model_parser() -> impl TypedValueParser<Value = ModelKind> {
    PossibleValuesParser::new(ModelKind::NAMES).try_map(|name| name.parse())
}

fn with_hint(error: LensError) -> anyhow::Error {
    match error {
        LensError::NotFound { .. } => {
            note!("`lensbake lens list` shows the bundled lenses");
            error.into()
        }
        other => other.into(),
    }
}

pub fn run(command: LensCommand) -> anyhow::Result<()> {
    match command {
        LensCommand::Check(args) => {
            match args.load_or_placed()? {
                Readable::Centred(lens) => say_raw!("{}", summary(&lens)?),
                Readable::Placed {
                    offence,
                    location,
                    lens,
                } => say_raw!(
                    "{}",
                    placed_summary(&args.lens, &location, &offence, &lens)?
                ),
            }
            Ok(())
        }
        LensCommand::Convert {
            input,
            output,
            indices_at_nm,
            overwrite_input,
        } => {
            if !overwrite_input && same_file(Path::new(&input.lens), &output) {
                anyhow::bail!(
                    "{}: the output is the input file; writing it would drop what lensbake \
                     does not read (notes, display settings, ...): name another output, or pass \
                     --overwrite-input to replace it",
                    output.display()
                );
            }
            convert(&input, &output, indices_at_nm)
        }
        LensCommand::List => list(),
    }
}

fn convert(input: &LensArgs, output: &Path, indices_at_nm: Option<f64>) -> anyhow::Result<()> {
    let mut lens = input.load()?;
    if let Some(nm) = indices_at_nm {
        lens.system = at_constant_indices(&lens, nm)?;
    }
    let p = &lens.system.prescription;
    if lenses::write_lens(&lens.system, output)? == Format::Pbrt {
        note!(
            "pbrt holds one index per medium: written at {} nm",
            lens.system.design_wavelength_nm()
        );
    }
    note_reading(&lens.source);
    let dropped = skipped_keywords(&lens.source.loaded.notes);
    if !dropped.is_empty() {
        note!(
            "{} does not carry the keywords lensbake skipped reading {}: {}",
            output.display(),
            lens.source.origin,
            dropped.join(", ")
        );
    }
    say!(
        "wrote {} ({} surfaces, from {})",
        output.display(),
        p.surfaces.len(),
        lens.source.origin
    );
    Ok(())
}

/// Whether two paths name one existing file (through links, `..` or a second hard link).
fn same_file(a: &Path, b: &Path) -> bool {
    let (Ok(a_meta), Ok(b_meta)) = (std::fs::metadata(a), std::fs::metadata(b)) else {
        return false;
    };
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        a_meta.dev() == b_meta.dev() && a_meta.ino() == b_meta.ino()
    }
    #[cfg(not(unix))]
    {
        let _ = (a_meta, b_meta);
        matches!(
            (std::fs::canonicalize(a), std::fs::canonicalize(b)),
            (Ok(x), Ok(y)) if x == y
        )
    }
}

/// The keywords a reading skipped (harmless or unknown), which no written file carries.
fn skipped_keywords(notes: &[LoadNote]) -> Vec<&str> {
    let mut keywords: Vec<&str> = notes
        .iter()
        .flat_map(|note| match note {
            LoadNote::SkippedKeywords { keywords }
            | LoadNote::UnknownHeaderKeywords { keywords } => keywords.as_slice(),
            _ => &[],
        })
        .map(String::as_str)
        .collect();
    keywords.sort_unstable();
    keywords.dedup();
    keywords
}

fn list() -> anyhow::Result<()> {
    if BUNDLED.is_empty() {
        say!("no bundled lenses");
    }
    let width = BUNDLED.iter().map(|l| l.name.len()).max().unwrap_or(0);
    for lens in BUNDLED {
        let label = PathBuf::from(format!("lenses/{}.ron", lens.name));
        let loaded = read_str(lens.ron, Some(&label), Format::Ron, &LoadOptions::default())
            .with_context(|| format!("bundled lens `{}`", lens.name))?;
        say!(
            "{:width$}  {}",
            lens.name,
            loaded.prescription.provenance.title
        );
    }
    Ok(())
}

/// The one-screen summary `lens check` prints. A condition the file states that no analysis
/// can use fails the check, as it would fail `analyze`.
fn summary(lens: &LoadedLens) -> anyhow::Result<String> {
    let system = &lens.system;
    let conditions = match DesignConditions::resolve(system, &ConditionOverrides::default()) {
        Err(error @ AnalysisError::Stated { .. }) => {
            note_reading(&lens.source);
            return Err(error.into());
        }
        resolved => resolved,
    };
    let p = &system.prescription;
    let wavelength_nm = system.design_wavelength_nm();
    let wavelength = printed_nm(wavelength_nm);
    let mut out = String::new();
    let mut line = |text: String| {
        out.push_str(&text);
        out.push('\n');
    };
    line(title(p));
    line(format!(
        "  read from:   {} ({})",
        lens.source.origin,
        lens.source.loaded.format.describe()
    ));
    if let Some(source) = &p.provenance.source {
        line(format!("  source:      {source}"));
    }
    let stated = if p.provenance.design_wavelength_nm.is_some() {
        "design"
    } else {
        "none stated; d line"
    };
    line(format!("  wavelength:  {wavelength} nm ({stated})"));
    // Where a medium's formula does not hold at this wavelength, its value there is an
    // extrapolation no analysis uses (they refuse the wavelength): none is printed.
    let index_text =
        |dispersion: &lensbake::glass::Dispersion| match dispersion.checked_index(wavelength_nm) {
            Ok(n) => format!("{n:.6}"),
            Err(_) => "outside".to_string(),
        };
    line(format!(
        "  object:      {} (n = {})",
        p.object_medium.describe(),
        index_text(&system.object_dispersion)
    ));
    if let Some(f) = p.provenance.claimed_focal_length_mm {
        line(format!("  claimed EFL: {f} mm"));
    }
    if let Some(n) = p.provenance.claimed_f_number {
        line(format!("  claimed F/#: {n}"));
    }
    line(String::new());
    line(format!(
        "  {:>3} {:4} {:>12} {:>11} {:11} {:16} {:>9} {:>9}",
        "#",
        "",
        "radius",
        "thickness",
        "shape",
        "medium after",
        format!("n@{wavelength}"),
        "semi-ap"
    ));
    for (i, s) in p.surfaces.iter().enumerate() {
        let radius = radius_text(&s.shape);
        let kind = shape_name(&s.shape);
        let index = index_text(&system.dispersions[i]);
        line(format!(
            "  {:>3} {:4} {:>12} {:>11.4} {:11} {:16} {:>9} {:>9.4}",
            i + 1,
            if s.stop.is_some() { "STO" } else { "" },
            radius,
            s.thickness,
            kind,
            s.medium.describe(),
            index,
            s.semi_aperture
        ));
    }
    line(String::new());
    for (i, s) in p.surfaces.iter().enumerate() {
        if let Shape::IdealLens { focal_length } = s.shape {
            line(format!(
                "  ideal lens:  surface {}, focal length {focal_length:.4} mm",
                i + 1
            ));
        }
    }
    let stop = &p.surfaces[system.stop];
    line(format!(
        "  stop:        surface {} ({}), semi-aperture {:.4} mm",
        system.stop + 1,
        match &stop.stop {
            Some(lensbake::prescription::StopShape::Blades { count, .. }) =>
                format!("{count} blades"),
            _ => "circle".to_string(),
        },
        stop.semi_aperture
    ));
    let last = p.surfaces.last().expect("a validated lens has surfaces");
    line(format!(
        "  total track: {:.4} mm (vertex 1 to vertex {}); last gap {:.4} mm",
        p.total_track(),
        p.surfaces.len(),
        last.thickness
    ));
    line(String::new());
    match conditions {
        Ok(conditions) => {
            line("  conditions (what analyze, plot and report use without flags):".into());
            for (what, value, origin) in conditions.summary_rows() {
                line(format!("    {what:24} {value} ({origin})"));
            }
            for note in &conditions.notes {
                line(format!("    note: {note}"));
            }
        }
        Err(error) => line(format!("  conditions:  none resolve: {error}")),
    }
    for note in &lens.source.loaded.notes {
        line(format!("note: {note}"));
    }
    Ok(out)
}

/// The beam `lens`'s file describes, or the one line that says what the 3-D trace takes instead.
pub(super) fn placed_beam(
    spec: &str,
    offence: &str,
    lens: &PlacedLens,
    tracer: &PlacedTracer,
) -> anyhow::Result<PlacedBeam> {
    PlacedBeam::of(lens, tracer).map_err(|e| match e {
        PlacedBeamError::NotTaken { takes } => anyhow::anyhow!(
            "{spec}: {offence}, so it is traced in three dimensions, which takes {takes}"
        ),
        other => anyhow::anyhow!("{spec}: {other}"),
    })
}

/// `lens check` for a lens its file places off one common axis: where each surface sits, and
/// the exact 3-D trace of the file's fields (chief ray and spot on the image plane).
fn placed_summary(
    spec: &str,
    location: &Location,
    offence: &str,
    lens: &PlacedLens,
) -> anyhow::Result<String> {
    let p = &lens.prescription;
    let wavelength = p
        .provenance
        .design_wavelength_nm
        .unwrap_or(DEFAULT_WAVELENGTH_NM);
    let tracer = PlacedTracer::new(lens, wavelength).map_err(|e| anyhow::anyhow!("{spec}: {e}"))?;
    let beam = placed_beam(spec, offence, lens, &tracer)?;
    let (fields, pupil_diameter) = (beam.fields_deg, beam.pupil_diameter);
    let sized_by = match beam.pupil_from {
        PupilFrom::File => String::new(),
        PupilFrom::FNumber {
            focal_length,
            f_number,
        } => format!(" = EFL {focal_length:.6} mm / F-number {f_number}"),
        PupilFrom::StopSize { semi_aperture } => {
            format!(", filling the stop's semi-aperture {semi_aperture} mm")
        }
    };

    let mut out = String::new();
    let mut line = |text: String| {
        out.push_str(&text);
        out.push('\n');
    };
    line(title(p));
    line(format!("  read from:   {spec}"));
    line(format!("  off the axis: {offence} at {location}"));
    line(
        "                first-order data, Seidel sums, pupils, wave optics, bake and render need \
         a rotationally symmetric lens; below is the exact 3-D trace"
            .to_string(),
    );
    line(format!("  wavelength:  {} nm", printed_nm(wavelength)));
    line(String::new());
    line(format!(
        "  {:>3} {:4} {:>12} {:11} {:16} {:>12} {:>12} {:>12} {:>9} {:>9}",
        "#",
        "",
        "radius",
        "shape",
        "medium after",
        "vertex x",
        "vertex y",
        "vertex z",
        "tilt deg",
        "clear"
    ));
    for (i, (s, frame)) in p.surfaces.iter().zip(&lens.frames).enumerate() {
        let radius = radius_text(&s.shape);
        let axis = frame.axis();
        let tilt = axis[0].hypot(axis[1]).atan2(axis[2]).to_degrees();
        let clear = if lens.outlines[i].is_some() {
            "below".to_string()
        } else if lens.clips[i] {
            format!("{:.4}", s.semi_aperture)
        } else {
            "-".to_string()
        };
        line(format!(
            "  {:>3} {:4} {:>12} {:11} {:16} {:>12.4} {:>12.4} {:>12.4} {:>9.4} {:>9}",
            i + 1,
            if s.stop.is_some() { "STO" } else { "" },
            radius,
            match lens.rotation_radii[i] {
                Some(r) if r.is_infinite() => "cylinder",
                Some(_) => "toroid",
                None => shape_name(&s.shape),
            },
            s.medium.describe(),
            frame.origin[0],
            frame.origin[1],
            frame.origin[2],
            tilt,
            clear
        ));
    }
    for (i, radius) in lens.rotation_radii.iter().enumerate() {
        if let Some(radius) = radius.filter(|r| r.is_finite()) {
            line(format!(
                "  toroid:      surface {}, y-z curve turned on a radius of {radius:.4} mm",
                i + 1
            ));
        }
    }
    for (i, outline) in lens.outlines.iter().enumerate() {
        let Some(outline) = outline else { continue };
        let shape = match outline.shape {
            OutlineShape::Circle { radius } => format!("circle of radius {radius:.4} mm"),
            OutlineShape::Rectangle {
                half_width,
                half_height,
            } => format!("rectangle {half_width:.4} x {half_height:.4} mm (half widths)"),
            OutlineShape::Ellipse {
                half_width,
                half_height,
            } => format!("ellipse {half_width:.4} x {half_height:.4} mm (semi-axes)"),
        };
        line(format!(
            "  aperture:    surface {}, {shape} centred at ({:.4}, {:.4}) mm",
            i + 1,
            outline.centre[0] + 0.0,
            outline.centre[1] + 0.0
        ));
    }
    line(String::new());
    line(format!(
        "  object at infinity, entrance pupil {pupil_diameter} mm{sized_by} \
         ({SPOT_GRID}x{SPOT_GRID} grid); image-plane coordinates (mm):"
    ));
    line(format!(
        "  {:>10} {:>10}  {:>14} {:>14}  {:>11}  {:>10}",
        "field x", "y (deg)", "chief ray x", "chief ray y", "rays in", "RMS um"
    ));
    for field in fields {
        // A field whose chief ray cannot be traced is reported in its row; the others still are.
        let spot = match tracer.collimated_spot(field, pupil_diameter, SPOT_GRID) {
            Ok(spot) => spot,
            Err(e) => {
                line(format!(
                    "  {:>10.4} {:>10.4}  not traced: {e}",
                    field[0], field[1]
                ));
                continue;
            }
        };
        line(format!(
            "  {:>10.4} {:>10.4}  {:>14.6} {:>14.6}  {:>5}/{:<5}  {:>10}",
            field[0],
            field[1],
            // + 0.0: a chief ray on the axis prints 0, not -0.
            spot.chief[0] + 0.0,
            spot.chief[1] + 0.0,
            spot.arrived,
            spot.launched,
            spot.rms_radius
                .map_or("-".to_string(), |r| format!("{:.3}", r * 1000.0))
        ));
    }
    Ok(out)
}

/// A wavelength as a reader would write it: at most six decimals, trailing zeros dropped (a
/// Zemax file's 0.5875618 µm is 587.5618000000001 nm in f64).
pub(super) fn printed_nm(nm: f64) -> String {
    let fixed = format!("{nm:.6}");
    fixed
        .trim_end_matches('0')
        .trim_end_matches('.')
        .to_string()
}

fn shape_name(shape: &Shape) -> &'static str {
    match shape {
        Shape::Plane => "plane",
        Shape::Sphere { .. } => "sphere",
        Shape::Conic { .. } => "conic",
        Shape::EvenAsphere { .. } => "asphere",
        Shape::OddAsphere { .. } => "odd asphere",
        Shape::IdealLens { .. } => "ideal",
    }
}

/// A summary's first line: the lens's title.
fn title(p: &lensbake::prescription::Prescription) -> String {
    if p.provenance.title.is_empty() {
        "(untitled lens)".to_string()
    } else {
        p.provenance.title.clone()
    }
}
