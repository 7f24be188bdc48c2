//! Errors for reading and validating prescriptions. Every error says where (file, line, surface,
//! field) and what is wrong, so a user can fix the file without reading our code.

use std::fmt;
use std::path::PathBuf;

/// Where in the input a problem sits. Any part may be unknown.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Location {
    pub file: Option<PathBuf>,
    /// 1-based line in the file.
    pub line: Option<usize>,
    /// 1-based surface number.
    pub surface: Option<usize>,
    pub field: Option<String>,
}

impl Location {
    pub fn file(path: impl Into<PathBuf>) -> Location {
        Location {
            file: Some(path.into()),
            ..Location::default()
        }
    }

    pub fn with_line(mut self, line: usize) -> Location {
        self.line = Some(line);
        self
    }

    pub fn with_surface(mut self, surface: usize) -> Location {
        self.surface = Some(surface);
        self
    }

    pub fn with_field(mut self, field: impl Into<String>) -> Location {
        self.field = Some(field.into());
        self
    }
}

impl Location {
    /// `"<location>: "` to put before a message, or nothing where nothing is known.
    pub fn prefix(&self) -> String {
        if *self == Location::default() {
            String::new()
        } else {
            format!("{self}: ")
        }
    }
}

impl fmt::Display for Location {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut parts: Vec<String> = Vec::new();
        match (&self.file, self.line) {
            (Some(file), Some(line)) => parts.push(format!("{}:{line}", file.display())),
            (Some(file), None) => parts.push(file.display().to_string()),
            (None, Some(line)) => parts.push(format!("line {line}")),
            (None, None) => {}
        }
        if let Some(s) = self.surface {
            parts.push(format!("surface {s}"));
        }
        if let Some(field) = &self.field {
            parts.push(format!("field `{field}`"));
        }
        if parts.is_empty() {
            write!(f, "<input>")
        } else {
            write!(f, "{}", parts.join(", "))
        }
    }
}

/// What is wrong. Each class of bad input has its own variant so tests and callers can tell
/// them apart.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum Problem {
    #[error("cannot read file: {0}")]
    Io(String),
    #[error("cannot write file: {0}")]
    Write(String),
    #[error("the file holds no surfaces")]
    Empty,
    #[error("cannot parse `{text}` as a number")]
    NotANumber { text: String },
    #[error("value {} is not finite", crate::limits::short(*.value))]
    NonFinite { value: f64 },
    #[error("expected {expected} columns, found {found}")]
    WrongColumnCount { expected: String, found: usize },
    #[error("syntax error: {0}")]
    Syntax(String),
    #[error("unsupported: {0}")]
    Unsupported(String),
    /// A lens placed off one common axis where no centred lens describes it: refused by every
    /// reader (everything but the 3-D trace needs a rotationally symmetric lens), with the lens
    /// as the file places it for [`crate::trace::placed::PlacedTracer`].
    #[error(
        "unsupported: {offence}: lensbake models rotationally symmetric systems (fold mirrors are \
         unfolded where that is exact); its paraxial, Seidel, pupil, bake and render code need \
         one (`lensbake lens check`, `trace` and `plot spot` trace this lens in three \
         dimensions)"
    )]
    NotRotationallySymmetric {
        /// What leaves the axis, e.g. "surface 3 is tilted 16.440000 deg to the axis (moved by
        /// `TYPE COORDBRK`)".
        offence: String,
        lens: Box<super::formats::PlacedLens>,
    },
    #[error(
        "refractive index {} is below vacuum's ({} relative to air: indices are relative to air, \
         whose refractivity stays below 1e-3)",
        crate::limits::short(*.index),
        super::model::MIN_INDEX
    )]
    IndexBelowVacuum { index: f64 },
    #[error(
        "refractive index {} is above {} (no optical material comes near it)",
        crate::limits::short(*.index),
        super::model::MAX_INDEX
    )]
    IndexAboveLimit { index: f64 },
    #[error(
        "Abbe number {} is below {} (0 means no dispersion; no optical material comes near it)",
        crate::limits::short(*.vd),
        super::model::MIN_ABBE_NUMBER
    )]
    AbbeNumberBelowLimit { vd: f64 },
    #[error(
        "central obscuration radius {} mm must be positive and inside the semi-aperture {} mm",
        crate::limits::short(*.radius),
        crate::limits::short(*.semi_aperture)
    )]
    ObscurationOutOfRange { radius: f64, semi_aperture: f64 },
    #[error("semi-aperture {} mm is larger than |radius| {} mm", crate::limits::short(*.semi_aperture), crate::limits::short(*.radius))]
    ApertureExceedsRadius { semi_aperture: f64, radius: f64 },
    /// A CODE V value read in one radius mode gives a sphere smaller than the aperture the file
    /// needs there: the file's numbers contradict the mode it was read in.
    #[error("{0}")]
    RadiusModeContradicted(Box<RadiusModeContradiction>),
    #[error(
        "the conic surface is undefined beyond r = {limit} mm, inside its semi-aperture {semi_aperture} mm"
    )]
    ApertureExceedsConic { semi_aperture: f64, limit: f64 },
    #[error("more than {max} aspheric terms ({found})", max = super::model::MAX_ASPHERE_TERMS)]
    TooManyAsphereTerms { found: usize },
    #[error(
        "surface crosses the next surface {next} within the clear aperture (gap {gap:.6} mm at r = {radius:.3} mm)"
    )]
    SurfacesCross { next: usize, radius: f64, gap: f64 },
    #[error("no surface is marked as the aperture stop")]
    NoStop,
    #[error("more than one aperture stop: surfaces {surfaces:?}")]
    MultipleStops { surfaces: Vec<usize> },
    #[error("stop has {count} blades; a diaphragm needs at least 3")]
    TooFewBlades { count: u32 },
    #[error(transparent)]
    OverLimit(#[from] crate::limits::LimitError),
    #[error("blade curvature {} is outside 0 (straight edges) ..= 1 (edges on the circle)", crate::limits::short(*.value))]
    BladeCurvatureOutOfRange { value: f64 },
    #[error("unknown glass `{name}`{}", suggest(.suggestions))]
    UnknownGlass {
        name: String,
        suggestions: Vec<String>,
    },
    #[error("bad index table: {reason}")]
    BadIndexTable { reason: String },
    #[error(
        "wavelength {} nm is outside the range where this medium's dispersion formula is defined",
        crate::limits::short(*.nm)
    )]
    WavelengthOutOfRange { nm: f64 },
    #[error("the file is not text: invalid UTF-8 at byte {byte_offset}")]
    NotText { byte_offset: usize },
    #[error("cannot tell the lens format from {}; name the format (ron, pbrt, table, codev, zemax)", describe_extension(.extension))]
    UnknownFormat { extension: Option<String> },
    #[error(
        "the first row's thickness is {value}, but in the distance-from-previous (axpos) reading the first surface has no previous surface and must be 0"
    )]
    FirstAxialPositionNotZero { value: f64 },
    #[error("no clear semi-aperture is given and none can be derived: {reason}")]
    CannotDeriveApertures { reason: String },
}

fn describe_extension(extension: &Option<String>) -> String {
    match extension {
        Some(e) => format!("the extension `.{e}`"),
        None => "a file name without extension".to_string(),
    }
}

fn suggest(suggestions: &[String]) -> String {
    if suggestions.is_empty() {
        String::new()
    } else {
        format!("; did you mean {}?", suggestions.join(", "))
    }
}

/// "location: ", or nothing for a problem of no place in the input (a wavelength asked for).
fn prefix(location: &Location) -> String {
    if *location == Location::default() {
        String::new()
    } else {
        format!("{location}: ")
    }
}

/// A problem at a location.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{}{problem}", prefix(.location))]
pub struct PrescriptionError {
    /// Boxed: a location holds a path and a field name, and unboxed it made every `Result` that
    /// can carry this error (nearly all of the library's) over 128 bytes.
    pub location: Box<Location>,
    pub problem: Problem,
}

impl PrescriptionError {
    pub fn new(location: Location, problem: Problem) -> PrescriptionError {
        PrescriptionError {
            location: Box::new(location),
            problem,
        }
    }
}

/// What [`Problem::RadiusModeContradicted`] says: how the value was read, and what the file
/// needs of the surface it gives.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error(
    "read as {read_as} ({why}), this value gives a surface of |radius| {} mm, but {needed}, and \
     no such surface passes that; {suggestion}",
    crate::limits::short(*.radius)
)]
pub struct RadiusModeContradiction {
    /// "a radius" or "a curvature".
    pub read_as: &'static str,
    /// Why it was read so (the file's `RDM`, or its absence).
    pub why: String,
    /// Where the surface ends, in the file's length unit.
    pub radius: f64,
    /// What the file needs there (a stated clear aperture, the beam).
    pub needed: String,
    /// The other mode, as the file would state it.
    pub suggestion: &'static str,
}
