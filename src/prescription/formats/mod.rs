//! Lens file formats in, canonical RON out.
//!
//! | format | extensions | module |
//! |---|---|---|
//! | native RON ([`Format::Ron`]) | `.ron` | `native` |
//! | pbrt lens table ([`Format::Pbrt`]) | `.dat` | `columns` |
//! | plain table as printed in papers ([`Format::Table`]) | `.txt`, `.tsv`, `.csv`, `.tab`, `.lens` | `columns` |
//! | CODE V sequence file ([`Format::CodeV`]) | `.seq` | `codev` |
//! | Zemax sequential file ([`Format::Zemax`]) | `.zmx` | `zemax` |
//!
//! The pbrt and plain-table formats share one column reader because they share one layout
//! (radius, thickness, index, aperture diameter); they differ in what marks the stop, what a zero
//! radius means and which thickness readings they allow. A `.dat` file whose stop row says `N/A`
//! (the Kolb table as distributed with this project) is therefore read as pbrt without fuss.
//!
//! Every reader returns the prescription exactly as the file describes it plus a [`SourceMap`]
//! (surface -> line), so validation errors found later still cite the line. Readers never guess:
//! anything a reader cannot honour is refused with [`Problem::Unsupported`] naming it, and facts
//! the user should know about the reading (a derived clear aperture, a suspicious pbrt first
//! row) come back as [`LoadNote`]s for the caller to show.

mod apertures;
mod codev;
mod columns;
mod export;
mod native;
mod placement;
mod zemax;

pub use export::{write_pbrt, write_zemax};
pub use placement::{ApertureOutline, Frame, OutlineShape, PlacedLens};

use super::error::{Location, PrescriptionError, Problem};
use super::model::{MAX_ASPHERE_TERMS, Medium, Prescription, Shape};
use super::validate::SourceMap;
use std::fmt;
use std::path::Path;
use std::str::FromStr;

/// A lens file format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    /// lensbake's own RON serialisation of [`Prescription`]; the only format written.
    Ron,
    /// pbrt `RealisticCamera` lens table: radius, thickness, index, aperture diameter.
    Pbrt,
    /// A plain surface table as printed in papers (e.g. Kolb et al. 1995, seed 000 Table 2.1).
    Table,
    /// CODE V sequence file (`.seq`), common sequential subset.
    CodeV,
    /// Zemax OpticStudio sequential file (`.zmx`), common subset.
    Zemax,
}

impl Format {
    pub const ALL: [Format; 5] = [
        Format::Ron,
        Format::Pbrt,
        Format::Table,
        Format::CodeV,
        Format::Zemax,
    ];

    /// The short name used on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Format::Ron => "ron",
            Format::Pbrt => "pbrt",
            Format::Table => "table",
            Format::CodeV => "codev",
            Format::Zemax => "zemax",
        }
    }

    /// A human description for summaries.
    pub fn describe(self) -> &'static str {
        match self {
            Format::Ron => "lensbake RON",
            Format::Pbrt => "pbrt lens table",
            Format::Table => "plain lens table",
            Format::CodeV => "CODE V sequence file",
            Format::Zemax => "Zemax sequential file",
        }
    }

    /// The format a file name implies, from its extension (case-insensitive).
    pub fn from_path(path: &Path) -> Result<Format, Problem> {
        let extension = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        let format = match extension.as_deref() {
            Some("ron") => Some(Format::Ron),
            Some("dat") => Some(Format::Pbrt),
            Some("txt" | "tsv" | "csv" | "tab" | "lens") => Some(Format::Table),
            Some("seq") => Some(Format::CodeV),
            Some("zmx") => Some(Format::Zemax),
            _ => None,
        };
        format.ok_or(Problem::UnknownFormat { extension })
    }
}

impl fmt::Display for Format {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for Format {
    type Err = String;

    /// Accepts the format names and, as aliases, their usual extensions.
    fn from_str(s: &str) -> Result<Format, String> {
        match s.to_ascii_lowercase().as_str() {
            "ron" => Ok(Format::Ron),
            "pbrt" | "dat" => Ok(Format::Pbrt),
            "table" | "txt" | "tsv" | "csv" => Ok(Format::Table),
            "codev" | "code-v" | "seq" => Ok(Format::CodeV),
            "zemax" | "zmx" => Ok(Format::Zemax),
            _ => Err(format!(
                "unknown lens format `{s}`; expected one of ron, pbrt, table, codev, zemax"
            )),
        }
    }
}

/// How the thickness column of a pbrt `.dat` file is read. Both readings exist in the wild and
/// a file does not say which it uses, so the caller chooses; nothing switches automatically.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum PbrtThickness {
    /// pbrt's own reading (and that of the scaled `*.NNmm.dat` files): each row's thickness is
    /// the distance from this vertex to the NEXT one.
    #[default]
    ToNext,
    /// The `axpos` column of the unscaled pbrt-v4-scenes files (`dgauss.dat`, `wide.dat`, ...):
    /// each row's value is the distance from the PREVIOUS vertex, the first row's is 0, and the
    /// gap after the last surface is unknown (taken as 0, as in the scaled files).
    FromPrevious,
}

/// Choices the caller makes when reading a lens file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// Overrides the format the extension implies.
    pub format: Option<Format>,
    /// Only meaningful for [`Format::Pbrt`]; asking for [`PbrtThickness::FromPrevious`] with any
    /// other format is an error rather than silently ignored.
    pub pbrt_thickness: PbrtThickness,
    /// The zoom position to read (1-based): a CODE V zoom file's `ZOO` position, or a Zemax
    /// multi-configuration file's configuration (only the active one, whose values the surface
    /// table holds). None reads position 1 (CODE V) or the active configuration (Zemax). Any
    /// other position of a file without zoom positions is an error, as is a position the file
    /// does not have.
    pub zoom_position: Option<usize>,
}

/// Something the user should know about how a file was read; not an error.
#[derive(Clone, Debug, PartialEq)]
pub enum LoadNote {
    /// A pbrt file read thickness-to-next whose first row has thickness 0: surfaces 1 and 2 share
    /// a vertex, which is typical of an unscaled `axpos` file read the wrong way.
    PbrtFirstThicknessZero,
    /// The file gave no clear aperture for these surfaces (1-based); they were derived from
    /// the paraxial marginal and chief rays of the file's beams (CODE V and Zemax files only).
    /// `limited_at_edge` lists those whose paraxial height lay beyond where the surface ends (a
    /// sphere at |R|, or where it meets its neighbour): their aperture ends there, and rays
    /// beyond it miss the surface.
    AperturesDerived {
        surfaces: Vec<usize>,
        limited_at_edge: Vec<usize>,
    },
    /// Surfaces (1-based) whose Zemax `DIAM`, the envelope OpticStudio computed for the file's
    /// beams, reaches past the height where the surface meets its neighbour (a lens whose edge
    /// thickness the envelope makes negative), with the semi-aperture (mm) they were cut to
    /// there: no glass lies beyond it, so rays beyond it are vignetted.
    EnvelopesCut { surfaces: Vec<(usize, f64)> },
    /// Keywords the file uses that change nothing lensbake models (display, merit function,
    /// tolerancing, coatings, ...), skipped; listed once, sorted.
    SkippedKeywords { keywords: Vec<String> },
    /// Zemax header keywords (before the surface table) lensbake does not know, skipped; listed
    /// once, sorted. The header keywords that define the lens, its aperture, fields, wavelengths
    /// and units are all known, so these are settings of a newer OpticStudio, but lensbake cannot
    /// vouch for them.
    UnknownHeaderKeywords { keywords: Vec<String> },
    /// CODE V paraxial solves (`PIM`, `CUM`, ...) the file uses; the lens is read with the
    /// curvatures and thicknesses the file writes, which CODE V writes as the solves left them.
    SolvesAsWritten { solves: Vec<String> },
    /// The file decentres or tilts surfaces, and the lens read is the centred one they describe
    /// exactly: `folds` (1-based) are tilted plane mirrors unfolded into planes; every other
    /// decentre or tilt cancels or moves only a plane that bends no ray.
    Centred { folds: Vec<usize> },
    /// A Zemax multi-configuration file (`MNUM count active`), read as configuration `active`:
    /// OpticStudio saves the active configuration's values in the surface table, and the other
    /// configurations' values (the configuration records after it) are not applied.
    ActiveConfiguration { active: usize, count: usize },
    /// Fields (1-based) whose vignetting factors (Zemax `VDX`/`VDY`/`VCX`/`VCY`, CODE V
    /// `VUY`/`VLY`/`VUX`/`VLX`) trim their pupil. lensbake traces the whole pupil at every field
    /// and lets the clear apertures vignette it; the factors only size clear apertures the file
    /// does not give.
    VignettingNotApplied { fields: Vec<usize> },
    /// A CODE V zoom file (`ZOO n`), read at `position` of `count`: zoomed thicknesses, radii,
    /// curvatures, conics, the object distance, EPD, FNO, fields and vignetting factors take
    /// that position's `ZOO` value, and the pickups of that position apply; the zoomed items in
    /// `as_written` (titles, clear apertures, ...) are read as the lens data write them.
    ZoomPosition {
        position: usize,
        count: usize,
        as_written: Vec<String>,
    },
    /// Glass names no catalogue here holds, each read as the model glass of the nd and Vd the
    /// file writes beside it (OpticStudio's own fallback): n = A + B / l^2 through nd at the d
    /// line with (nd - 1) / (nF - nC) = Vd ([`crate::glass::Dispersion::model`]).
    ModelGlasses { glasses: Vec<ModelGlassNote> },
    /// The file names glasses no catalogue here holds, but the nd and Vd it writes beside a
    /// glass the catalogues do hold are not that glass's (a writer's placeholder), so the
    /// numbers beside the unknown names are not taken for theirs and those glasses stay unknown.
    WrittenGlassDataContradicted(ContradictedGlassData),
    /// Media whose index table ends short of a wavelength the file uses, by no more than
    /// [`crate::glass::TABLE_EXTRAPOLATION`] of its span: the index there is the table
    /// continued, as OpticStudio and CODE V continue it ([`crate::glass::Dispersion::checked_index`]).
    IndicesExtrapolated { media: Vec<ExtrapolatedIndex> },
}

/// One medium's index continued beyond its table at one wavelength ([`LoadNote::IndicesExtrapolated`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ExtrapolatedIndex {
    /// Surface (1-based; 0 is the object space) whose medium it is.
    pub surface: usize,
    /// The glass's name, or a description of a private table.
    pub medium: String,
    pub wavelength_nm: f64,
    /// The first and last wavelength (nm) of the table.
    pub range_nm: (f64, f64),
}

/// The media of `prescription` whose table is continued at one of its file's wavelengths.
fn extrapolated_indices(prescription: &Prescription) -> Vec<ExtrapolatedIndex> {
    let mut wavelengths: Vec<f64> = prescription
        .provenance
        .conditions
        .as_ref()
        .map(|c| c.wavelengths_nm.clone())
        .unwrap_or_default();
    wavelengths.extend(prescription.provenance.design_wavelength_nm);
    wavelengths.sort_by(f64::total_cmp);
    wavelengths.dedup();
    let media = std::iter::once(&prescription.object_medium)
        .chain(prescription.surfaces.iter().map(|s| &s.medium));
    let mut found = Vec::new();
    for (surface, medium) in media.enumerate() {
        // A name no catalogue holds is reported when the lens is resolved.
        let Ok(dispersion) = crate::glass::Dispersion::of(medium) else {
            continue;
        };
        for &nm in &wavelengths {
            if let Some(range_nm) = dispersion.extrapolated_range_nm(nm) {
                found.push(ExtrapolatedIndex {
                    surface,
                    medium: medium.describe(),
                    wavelength_nm: nm,
                    range_nm,
                });
            }
        }
    }
    found
}

impl fmt::Display for LoadNote {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            LoadNote::Centred { folds } if folds.is_empty() => write!(
                f,
                "the file's decentres and tilts leave every surface that bends light on the axis \
                 (they cancel, or move only planes between equal media); read as the centred lens"
            ),
            LoadNote::Centred { folds } => write!(
                f,
                "fold mirror{} {} unfolded: read as the centred lens the fold{} straighten{} \
                 (exact for every ray; the image is seen through the mirrors, so it may be \
                 mirror-reversed)",
                plural(folds),
                list_ranges(folds),
                plural(folds),
                if folds.len() == 1 { "s" } else { "" }
            ),
            LoadNote::PbrtFirstThicknessZero => write!(
                f,
                "the first row's thickness is 0, so surfaces 1 and 2 share a vertex; if this is an \
                 unscaled pbrt-v4-scenes file whose thickness column is the distance from the \
                 previous surface (axpos), read it with the distance-from-previous option \
                 (--pbrt-from-previous)"
            ),
            LoadNote::AperturesDerived {
                surfaces,
                limited_at_edge,
            } => {
                write!(
                    f,
                    "the file gives no clear aperture for surface{} {}; derived from paraxial \
                     marginal and chief rays at the file's entrance pupil, fields and vignetting \
                     factors (real-ray clear apertures, as CODE V or Zemax compute them, can \
                     differ by several percent at wide fields)",
                    plural(surfaces),
                    list_ranges(surfaces)
                )?;
                if !limited_at_edge.is_empty() {
                    write!(
                        f,
                        "; on surface{} {} those rays reach beyond where the surface ends (the \
                         rim of a sphere or conic, or where it meets its neighbour), so the \
                         aperture ends there and rays beyond it are vignetted",
                        plural(limited_at_edge),
                        list_ranges(limited_at_edge)
                    )?;
                }
                Ok(())
            }
            LoadNote::EnvelopesCut { surfaces } => {
                let cuts: Vec<String> = surfaces
                    .iter()
                    .map(|(surface, radius)| format!("surface {surface} at {radius:.3} mm"))
                    .collect();
                write!(
                    f,
                    "DIAM envelopes reach past where the surface meets its neighbour, so the \
                     aperture ends there and rays beyond it are vignetted: {}",
                    cuts.join(", ")
                )
            }
            LoadNote::ModelGlasses { glasses } => {
                let named: Vec<String> = glasses
                    .iter()
                    .map(|g| {
                        let place = medium_place(g.surface);
                        format!("{place} {} (nd {}, Vd {})", g.name, g.glass.nd, g.glass.vd)
                    })
                    .collect();
                write!(
                    f,
                    "glass{} in no catalogue lensbake holds, read as model glass{} from the nd and \
                     Vd the file writes (n = A + B/l^2: nd at the d line, Vd from the F and C \
                     lines; other wavelengths approximate): {}",
                    if glasses.len() == 1 { "" } else { "es" },
                    if glasses.len() == 1 { "" } else { "es" },
                    named.join(", ")
                )
            }
            LoadNote::WrittenGlassDataContradicted(c) => write!(
                f,
                "no model glass made from the nd and Vd the file writes beside glass names: on \
                 line {} it writes {} as nd {}, Vd {} where the catalogue has nd {}, Vd {}, so \
                 its numbers are not the glasses' own",
                c.line, c.name, c.written.nd, c.written.vd, c.catalogue.nd, c.catalogue.vd
            ),
            LoadNote::SkippedKeywords { keywords } => write!(
                f,
                "skipped keywords that change nothing lensbake models: {}",
                keywords.join(", ")
            ),
            LoadNote::VignettingNotApplied { fields } => write!(
                f,
                "the vignetting factors of field{} {} are not applied: the fans, spots and wave \
                 figures trace the whole pupil and the clear apertures vignette it, where the \
                 program that wrote the file traces the part the factors keep",
                plural(fields),
                list_ranges(fields)
            ),
            LoadNote::ActiveConfiguration { active, count } => write!(
                f,
                "multi-configuration file: read as configuration {active} of {count}, the active \
                 one, whose values the surface table holds; the other configurations are not \
                 applied"
            ),
            LoadNote::ZoomPosition {
                position,
                count,
                as_written,
            } => {
                write!(
                    f,
                    "zoom file: read at position {position} of {count} (each zoomed thickness, \
                     radius, conic, object distance, EPD, FNO, field and vignetting factor takes \
                     its value there)"
                )?;
                if !as_written.is_empty() {
                    write!(
                        f,
                        "; zoomed {} read as the lens data write them",
                        as_written.join(", ")
                    )?;
                }
                write!(f, "; another position is read by asking for it")
            }
            LoadNote::SolvesAsWritten { solves } => write!(
                f,
                "solves {} read as the file writes their results (CODE V writes each solved \
                 curvature and thickness in place); they are not solved again",
                solves.join(", ")
            ),
            LoadNote::IndicesExtrapolated { media } => {
                let named: Vec<String> = media
                    .iter()
                    .map(|m| {
                        let place = medium_place(m.surface);
                        format!(
                            "{place} {} at {} nm (table {}-{} nm)",
                            m.medium, m.wavelength_nm, m.range_nm.0, m.range_nm.1
                        )
                    })
                    .collect();
                write!(
                    f,
                    "index{} continued beyond the glass data, the table's end segment extended \
                     in a straight line (up to {}% of its span beyond either end; farther is \
                     refused): {}",
                    if media.len() == 1 { "" } else { "es" },
                    crate::glass::TABLE_EXTRAPOLATION * 100.0,
                    named.join(", ")
                )
            }
            LoadNote::UnknownHeaderKeywords { keywords } => write!(
                f,
                "skipped header keyword{} lensbake does not know: {} (lensbake applies every \
                 header keyword it knows to define the surfaces, units, aperture, fields or \
                 wavelengths; check these set none of them)",
                if keywords.len() == 1 { "" } else { "s" },
                keywords.join(", ")
            ),
        }
    }
}

/// Whose medium a note names: "object space" for 0, else "surface k".
fn medium_place(surface: usize) -> String {
    match surface {
        0 => "object space".to_string(),
        k => format!("surface {k}"),
    }
}

fn plural(list: &[usize]) -> &'static str {
    if list.len() == 1 { "" } else { "s" }
}

/// "1-4, 6, 9-11" for [1, 2, 3, 4, 6, 9, 10, 11].
fn list_ranges(numbers: &[usize]) -> String {
    let mut parts = Vec::new();
    let mut i = 0;
    while i < numbers.len() {
        let mut j = i;
        while j + 1 < numbers.len() && numbers[j + 1] == numbers[j] + 1 {
            j += 1;
        }
        parts.push(if i == j {
            numbers[i].to_string()
        } else {
            format!("{}-{}", numbers[i], numbers[j])
        });
        i = j + 1;
    }
    parts.join(", ")
}

/// A prescription read from a file, with where each surface came from.
#[derive(Clone, Debug, PartialEq)]
pub struct Loaded {
    pub prescription: Prescription,
    pub map: SourceMap,
    /// The format the text was read as.
    pub format: Format,
    pub notes: Vec<LoadNote>,
}

/// Reads a prescription from text in a known format. `file` only labels error locations.
/// The result is parsed, not validated: pass it to [`crate::system::LensSystem::new`].
pub fn read_str(
    text: &str,
    file: Option<&Path>,
    format: Format,
    options: &LoadOptions,
) -> Result<Loaded, PrescriptionError> {
    let source = Source { file };
    if options.pbrt_thickness == PbrtThickness::FromPrevious && format != Format::Pbrt {
        return Err(source.error(
            None,
            Problem::Unsupported(format!(
                "the distance-from-previous thickness reading applies only to pbrt .dat files, \
                 not to a {}",
                format.describe()
            )),
        ));
    }
    let mut loaded = match format {
        Format::Ron => native::read(text, &source)?,
        Format::Pbrt => columns::read(
            text,
            &source,
            columns::Dialect::Pbrt(options.pbrt_thickness),
        )?,
        Format::Table => columns::read(text, &source, columns::Dialect::Table)?,
        Format::CodeV => codev::read(text, &source, options.zoom_position)?,
        Format::Zemax => zemax::read(text, &source)?,
    };
    if format != Format::CodeV {
        check_configuration(&loaded, options.zoom_position, &source)?;
    }
    loaded.map.file = file.map(Path::to_path_buf);
    let extrapolated = extrapolated_indices(&loaded.prescription);
    if !extrapolated.is_empty() {
        loaded.notes.push(LoadNote::IndicesExtrapolated {
            media: extrapolated,
        });
    }
    Ok(loaded)
}

/// Refuses a zoom position that a file other than a CODE V one does not hold: a Zemax
/// multi-configuration file is read as its active configuration (the other configurations'
/// operands are not applied), any other file has position 1 only.
fn check_configuration(
    loaded: &Loaded,
    asked: Option<usize>,
    source: &Source,
) -> Result<(), PrescriptionError> {
    let Some(asked) = asked else {
        return Ok(());
    };
    let configuration = loaded.notes.iter().find_map(|note| match note {
        LoadNote::ActiveConfiguration { active, count } => Some((*active, *count)),
        _ => None,
    });
    let refusal = match configuration {
        Some((active, _)) if active == asked => return Ok(()),
        None if asked == 1 => return Ok(()),
        Some((active, count)) => format!(
            "zoom position {asked} of a Zemax multi-configuration file ({count} \
             configurations): lensbake reads the active configuration, {active}, whose values \
             the surface table holds; make configuration {asked} active in OpticStudio and save"
        ),
        None => format!(
            "zoom position {asked} of a {} without zoom positions (position 1 is the lens)",
            loaded.format.describe()
        ),
    };
    let field = if configuration.is_some() {
        "MNUM"
    } else {
        "zoom position"
    };
    Err(PrescriptionError::new(
        source.location(None).with_field(field),
        Problem::Unsupported(refusal),
    ))
}

/// Reads a prescription from raw file contents: UTF-8 (with or without a byte-order mark),
/// UTF-16 little- or big-endian with a byte-order mark (OpticStudio writes `.zmx` files that
/// way), or, for Zemax and CODE V files that are not UTF-8, Latin-1.
pub fn read_bytes(
    bytes: &[u8],
    file: Option<&Path>,
    format: Format,
    options: &LoadOptions,
) -> Result<Loaded, PrescriptionError> {
    let text = match decode_text(bytes) {
        Ok(text) => text,
        // OpticStudio and CODE V write their files in the Windows code page of the machine they
        // ran on; every byte is a Latin-1 character (only names and comments use them).
        Err(_) if matches!(format, Format::Zemax | Format::CodeV) => {
            bytes.iter().map(|&b| char::from(b)).collect()
        }
        Err((line, problem)) => return Err(Source { file }.error(line, problem)),
    };
    read_str(&text, file, format, options)
}

/// Reads a lens file, choosing the format from `options.format` or else the extension.
pub fn read_file(path: &Path, options: &LoadOptions) -> Result<Loaded, PrescriptionError> {
    // Read first: a directory or a device is that, whatever its name says about a format.
    let bytes = crate::limits::read_input_within(path, crate::limits::MAX_LENS_FILE_BYTES)
        .map_err(|e| PrescriptionError::new(Location::file(path), Problem::Io(e.to_string())))?;
    let format = match options.format {
        Some(format) => format,
        None => Format::from_path(path)
            .map_err(|problem| PrescriptionError::new(Location::file(path), problem))?,
    };
    read_bytes(&bytes, Some(path), format, options)
}

/// The canonical RON text of a prescription: pretty, stable, and exact (reading it back gives
/// the same prescription, every f64 bit for bit).
pub fn write_ron(p: &Prescription) -> String {
    native::write(p)
}

/// Writes the canonical RON of `p` to `path` atomically: the text goes to a temporary file in the
/// same directory, which then replaces `path` in one rename, so a reader never sees half a file.
pub fn write_ron_file(path: &Path, p: &Prescription) -> Result<(), PrescriptionError> {
    crate::output::write_bytes(path, write_ron(p).as_bytes()).map_err(|error| {
        PrescriptionError::new(Location::file(path), Problem::Write(error.cause()))
    })
}

/// Decodes file bytes to text; on failure, the 1-based line of the first bad byte.
fn decode_text(bytes: &[u8]) -> Result<String, (Option<usize>, Problem)> {
    let utf16 = |units: Vec<u16>| {
        String::from_utf16(&units).map_err(|_| (None, Problem::NotText { byte_offset: 0 }))
    };
    if let Some(rest) = bytes.strip_prefix(&[0xFF, 0xFE]) {
        return utf16(
            rest.chunks(2)
                .map(|c| u16::from_le_bytes([c[0], *c.get(1).unwrap_or(&0)]))
                .collect(),
        );
    }
    if let Some(rest) = bytes.strip_prefix(&[0xFE, 0xFF]) {
        return utf16(
            rest.chunks(2)
                .map(|c| u16::from_be_bytes([c[0], *c.get(1).unwrap_or(&0)]))
                .collect(),
        );
    }
    let bytes = bytes.strip_prefix(&[0xEF, 0xBB, 0xBF]).unwrap_or(bytes);
    match std::str::from_utf8(bytes) {
        Ok(text) => Ok(text.to_string()),
        Err(e) => {
            let offset = e.valid_up_to();
            let line = 1 + bytes[..offset].iter().filter(|&&b| b == b'\n').count();
            Err((
                Some(line),
                Problem::NotText {
                    byte_offset: offset,
                },
            ))
        }
    }
}

/// The file being read, for building locations.
struct Source<'a> {
    file: Option<&'a Path>,
}

impl Source<'_> {
    fn location(&self, line: Option<usize>) -> Location {
        Location {
            file: self.file.map(Path::to_path_buf),
            line,
            ..Location::default()
        }
    }

    fn error(&self, line: Option<usize>, problem: Problem) -> PrescriptionError {
        PrescriptionError::new(self.location(line), problem)
    }

    /// The title to use when the file states none: its name without extension.
    fn default_title(&self) -> String {
        self.file
            .and_then(|f| f.file_stem())
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default()
    }

    fn file_name(&self) -> Option<String> {
        self.file
            .and_then(|f| f.file_name())
            .map(|s| s.to_string_lossy().into_owned())
    }
}

/// Parses a number; infinities and NaN parse too (see [`finite`]).
fn number(text: &str, at: &Location) -> Result<f64, PrescriptionError> {
    text.trim().parse::<f64>().map_err(|_| {
        PrescriptionError::new(
            at.clone(),
            Problem::NotANumber {
                text: text.to_string(),
            },
        )
    })
}

/// Parses a number that must be finite.
fn finite(text: &str, at: &Location) -> Result<f64, PrescriptionError> {
    let value = number(text, at)?;
    if value.is_finite() {
        Ok(value)
    } else {
        Err(PrescriptionError::new(
            at.clone(),
            Problem::NonFinite { value },
        ))
    }
}

/// Refuses a file as soon as it holds more surfaces than lensbake models
/// ([`crate::limits::MAX_SURFACES`], the limit validation applies to a whole lens), so that a
/// file of hundreds of thousands of surfaces costs no more to refuse than its first few hundred.
/// `at` is the line of the surface that passes the limit.
fn check_surface_count(count: usize, at: Location) -> Result<(), PrescriptionError> {
    crate::limits::check(
        "the number of surfaces",
        count as u64,
        crate::limits::MAX_SURFACES,
    )
    .map_err(|e| PrescriptionError::new(at, e.into()))
}

/// A number that must be above 0 and finite (an aperture a file states: its pupil diameter,
/// f-number or numerical aperture), refused where it is written; the design conditions would
/// otherwise drop it without a word and take the stop's own.
fn positive(text: &str, at: &Location) -> Result<f64, PrescriptionError> {
    let value = finite(text, at)?;
    let what = at.field.clone().unwrap_or_else(|| "the value".into());
    crate::limits::check_positive(&what, value)
        .map_err(|e| PrescriptionError::new(at.clone(), e.into()))?;
    Ok(value)
}

/// The simplest shape that describes a surface with even-asphere terms (on r^2, r^4, ...): a
/// plane when flat without them, a sphere without conic or terms, and so on. Trailing zero
/// terms are dropped.
fn shape(curvature: f64, conic: f64, coefficients: &[f64]) -> Shape {
    let used = coefficients
        .iter()
        .rposition(|&a| a != 0.0)
        .map_or(0, |last| last + 1);
    if used > 0 {
        Shape::EvenAsphere {
            curvature,
            conic,
            coefficients: coefficients[..used].to_vec(),
        }
    } else if curvature == 0.0 {
        // A conic constant changes nothing on a flat surface.
        Shape::Plane
    } else if conic != 0.0 {
        Shape::Conic { curvature, conic }
    } else {
        Shape::Sphere { curvature }
    }
}

/// [`shape`] for odd-asphere terms (on r, r^2, r^3, ...): the same simplest shape, its terms
/// read in powers of r.
fn odd_shape(curvature: f64, conic: f64, coefficients: &[f64]) -> Shape {
    match shape(curvature, conic, coefficients) {
        Shape::EvenAsphere {
            curvature,
            conic,
            coefficients,
        } => Shape::OddAsphere {
            curvature,
            conic,
            coefficients,
        },
        simpler => simpler,
    }
}

/// Converts a prescription given in some length unit to mm; `mm_per_unit` is 1 for mm.
/// An aspheric term a r^j is a length, so its coefficient scales as unit^(1-j).
fn scale_to_mm(p: &mut Prescription, mm_per_unit: f64) {
    if mm_per_unit == 1.0 {
        return;
    }
    for s in &mut p.surfaces {
        s.thickness *= mm_per_unit;
        s.semi_aperture *= mm_per_unit;
        s.obscuration = s.obscuration.map(|r| r * mm_per_unit);
        // Every length scales by mm_per_unit: c by its inverse, the coefficient of r^j by
        // mm_per_unit^(1-j).
        s.shape = s.shape.map_terms(
            |c| c / mm_per_unit,
            |power, a| a * mm_per_unit.powi(1 - power),
        );
    }
}

/// The nd and Vd a file writes for a glass (Zemax `GLAS name code x nd vd ...`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelGlass {
    pub nd: f64,
    pub vd: f64,
}

impl ModelGlass {
    /// Whether the numbers describe a dispersing glass a model can stand for: nd a finite
    /// index above air's and Vd finite and positive. A file that writes `0 0` beside a name
    /// says nothing about the glass, and a Vd of 0 would be a constant index, not the glass.
    fn describes_a_glass(self) -> bool {
        self.nd.is_finite() && self.nd > 1.0 && self.vd.is_finite() && self.vd > 0.0
    }
}

/// A glass name no catalogue here holds, read as the model glass of the nd and Vd its file
/// writes beside it ([`LoadNote::ModelGlasses`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ModelGlassNote {
    /// Surface (1-based; 0 is the object space) whose medium it is.
    pub surface: usize,
    /// The name as the file writes it.
    pub name: String,
    pub glass: ModelGlass,
}

/// A catalogue glass whose nd and Vd as a file writes them are not the catalogue's
/// ([`LoadNote::WrittenGlassDataContradicted`]).
#[derive(Clone, Debug, PartialEq)]
pub struct ContradictedGlassData {
    /// The line that names the glass.
    pub line: usize,
    pub name: String,
    pub written: ModelGlass,
    pub catalogue: ModelGlass,
}

/// The medium a glass name in a CODE V or Zemax file stands for, and the model glass it was
/// read as where no catalogue holds the name. Names the catalogues know are stored under the
/// catalogue's spelling ("NSSK2_SCHOTT" -> "N-SSK2"), with the maker appended where another
/// catalogue has a glass of the same name ("SK16_HIKARI"), so the file's catalogue preference
/// (`preferred`, e.g. Zemax `GCAT`) survives into the RON. An unknown name becomes the model
/// glass of the nd and Vd the file writes beside it (`written`), as OpticStudio reads a glass its
/// catalogues lack; without usable numbers it is kept as written, so that resolving the lens
/// reports it with suggestions.
fn named_medium(
    name: &str,
    preferred: &[String],
    written: Option<ModelGlass>,
) -> (Medium, Option<ModelGlass>) {
    let name = name.trim().trim_matches(|c| c == '\'' || c == '"');
    if name.is_empty() || name.eq_ignore_ascii_case("AIR") {
        return (Medium::Air, None);
    }
    match crate::glass::lookup_in(name, preferred) {
        Ok(glass) => (Medium::Glass(glass.unambiguous_name()), None),
        Err(_) => match written.filter(|glass| glass.describes_a_glass()) {
            Some(glass) => (
                Medium::Model {
                    nd: glass.nd,
                    vd: glass.vd,
                },
                Some(glass),
            ),
            None => (Medium::Glass(name.to_string()), None),
        },
    }
}

/// Room for every even-asphere term the model holds (r^2 .. r^20).
type AsphereTerms = [f64; MAX_ASPHERE_TERMS];

/// A file's field weights for its `count` fields: none when it gives none, else one per field,
/// those it leaves out weighing 1 (the programs' default).
fn field_weights(given: &[f64], count: usize) -> Vec<f64> {
    if given.is_empty() {
        return Vec::new();
    }
    (0..count)
        .map(|k| given.get(k).copied().unwrap_or(1.0))
        .collect()
}
