//! CODE V sequence files (`.seq`), the common sequential subset.
//!
//! Commands are separated by `;` or line ends; a line ending in `&` continues on the next; `!`
//! starts a comment; quoted strings keep spaces.
//!
//! Read: `RDM` (Y or no argument = radii; N = curvatures; without `RDM`, radii: see
//! [`RadiusMode`]), `TITLE` (or `TIT`), `DIM` (M, C, I:
//! converted to mm), `EPD`, `FNO`, `NAO` (the aperture), `WL` (nm) with `WTW` (weights) and `REF`
//! (the design wavelength; the first `WL` when `REF` is absent, as rayoptics reads it), fields as
//! `XAN`/`YAN` (angles), `XOB`/`YOB` (object heights), `XIM`/`YIM` (paraxial image heights) or
//! `XRI`/`YRI` (real image heights) with `WTF` (weights), `VUY`/`VLY`/`VUX`/`VLX` (vignetting
//! factors), `SO` (object: distance, medium), `S value thickness [glass]`, `SI` (image), `STO`
//! or `STOP` (without either, surface 1 is the stop, as in CODE V), `CIR` (clear aperture radius; `CIR OBS`
//! and `CIR HOL` a central obscuration or hole, which both take the rays inside it off the
//! sequential path; `CIR EDG` the mechanical edge, skipped), `REFL` as a glass (a mirror: light
//! turns back into the medium it came from; thicknesses after it are negative while it travels
//! -z, as CODE V writes them), `K`
//! (conic), `A` `B` `C` `D` `E` `F` `G` `H` `J` (even-asphere terms r^4 .. r^20), `RDY`, `CUY`,
//! `THI`, `GLA`, `CUF 0` (written into every ASP block), pickups `PIK` of `RDY`, `CUY`, `THI`
//! and `K` with scale and offset (evaluated after the last surface, those of the zoom position
//! read), `GO` (end of input). Object distance, aperture, fields and wavelengths become the
//! prescription's [`crate::prescription::Conditions`].
//!
//! Skipped as harmless (they change no surface) and listed in one note: see `HARMLESS`.
//!
//! Decentres and tilts (`XDE`, `YDE`, `ZDE`, `ADE`, `BDE`, `CDE`, with `DAR`, `BEN`, `REV`) on lens
//! surfaces and `SI` are read; `placement` turns them into the centred lens they describe (fold
//! mirrors unfolded) or refuses the lens.
//!
//! Paraxial solves (`PIM`, `CUM`, `CUC`, `THM`, `THC`, `RED`, and the long forms `CUY UMY`,
//! `THI HMY` and their kin) keep the values the file writes: see `SOLVES`.
//!
//! Rectangular apertures (`REX`, `REY`), elliptical ones (`ELX`, `ELY`; with equal semi-axes
//! the circle `CIR` states) and aperture decentres (`ADX`, `ADY`) are read and, like a tilted
//! surface, leave the lens to the 3-D trace (`placement`).
//!
//! Zoom files (`ZOO n`) are read at one position, the first unless the caller asks for another
//! ([`super::LoadOptions::zoom_position`]): see `Reader::zoom`.
//!
//! Refused with a message naming the command and line: every other command (other pickups, a `CUF` other than 0, other solves, other aperture forms (`ARO`), private glasses given by a formula other than `LAU` Laurent coefficients), a curved object or image surface, and
//! other `CIR` forms (several values). Image-height fields and
//! numerical apertures are refused only when a clear aperture must be derived from them (see
//! `apertures`).
//!
//! Glass names stay names ([`crate::prescription::Medium::Glass`]); the catalogue resolves them
//! when the lens system is built, and reports unknown ones with suggestions. A fictitious glass
//! code `NNNNNN.VVVV` is a model glass with nd = 1.NNNNNN and Vd = VV.VV. Six-digit glass codes
//! without a fraction (which CODE V looks up in its catalogues) are refused.
//!
//! When a surface has no `CIR`, its clear aperture is derived (see `apertures`), which needs the
//! index of every medium at the design wavelength: the catalogue is consulted then, and an unknown
//! glass is reported by the reader, with the line of its surface.

use super::apertures::{self, BeamSpec, INFINITE_OBJECT_MM};
use super::placement::{
    self, ApertureOutline, Asymmetry, OutlineShape, Placement, PlacementKind, StatedOutline,
};
use super::{
    AsphereTerms, Format, LoadNote, Loaded, Source, check_surface_count, finite, named_medium,
    number, positive, scale_to_mm, shape,
};
use crate::prescription::DEFAULT_WAVELENGTH_NM;
use crate::prescription::error::{Location, PrescriptionError, Problem, RadiusModeContradiction};
use crate::prescription::model::{
    ApertureSpec, Conditions, FieldKind, FieldSpec, MAX_ASPHERE_TERMS, Medium, Prescription,
    Provenance, Shape, StatedCondition, StopShape, Surface,
};
use crate::prescription::validate::SourceMap;
use std::collections::{BTreeMap, BTreeSet};

/// One command with its words; quoted strings are single words without their quotes.
struct Command {
    line: usize,
    name: String,
    args: Vec<String>,
}

/// Lines with CODE V's continuation joined: a line whose text (before any `!` comment) ends in
/// `&` goes on in the next line. Each joined line keeps the number of its first physical line.
fn logical_lines(text: &str) -> impl Iterator<Item = (usize, String)> + '_ {
    let mut lines = text.lines().enumerate();
    std::iter::from_fn(move || {
        let mut pending: Option<(usize, String)> = None;
        for (index, raw) in lines.by_ref() {
            let code = raw.split('!').next().unwrap_or("").trim_end();
            let (line, mut joined) = pending.take().unwrap_or((index + 1, String::new()));
            match code.strip_suffix('&') {
                Some(head) => {
                    joined.push_str(head);
                    joined.push(' ');
                    pending = Some((line, joined));
                }
                None => {
                    joined.push_str(raw);
                    return Some((line, joined));
                }
            }
        }
        pending
    })
}

/// The file's commands in order, read one logical line at a time, so a reader that stops early
/// (at `GO`, or at an error) never tokenises the rest of the file.
fn commands(text: &str) -> impl Iterator<Item = Command> + '_ {
    logical_lines(text).flat_map(|(line, raw)| line_commands(line, &raw))
}

/// The commands of one logical line (`;` separates commands on a line).
fn line_commands(line: usize, raw: &str) -> Vec<Command> {
    let mut out = Vec::new();
    let mut words: Vec<String> = Vec::new();
    let mut word = String::new();
    let mut in_word = false;
    let mut quote: Option<char> = None;
    let flush = |words: &mut Vec<String>, word: &mut String, in_word: &mut bool| {
        if *in_word {
            words.push(std::mem::take(word));
            *in_word = false;
        }
    };
    let mut end_command = |words: &mut Vec<String>| {
        if let Some((name, args)) = words.split_first() {
            out.push(Command {
                line,
                name: name.to_ascii_uppercase(),
                args: args.to_vec(),
            });
        }
        words.clear();
    };
    for c in raw.chars() {
        match quote {
            Some(q) if c == q => quote = None,
            Some(_) => word.push(c),
            None => match c {
                '\'' | '"' => {
                    quote = Some(c);
                    in_word = true;
                }
                '!' => break,
                ';' => {
                    flush(&mut words, &mut word, &mut in_word);
                    end_command(&mut words);
                }
                c if c.is_whitespace() => flush(&mut words, &mut word, &mut in_word),
                c => {
                    word.push(c);
                    in_word = true;
                }
            },
        }
    }
    flush(&mut words, &mut word, &mut in_word);
    end_command(&mut words);
    out
}

struct SeqSurface {
    line: usize,
    /// Radius or curvature, as `radius_mode` says.
    value: f64,
    radius_mode: bool,
    thickness: f64,
    medium: Medium,
    conic: f64,
    terms: AsphereTerms,
    clear_radius: Option<f64>,
    /// Radius inside which the surface blocks rays (`CIR OBS`, `CIR HOL`).
    obscuration: Option<f64>,
    /// `REX`, `REY`: half width and half height of a rectangular clear aperture.
    rectangle: [Option<f64>; 2],
    /// `ELX`, `ELY`: the semi-axes of an elliptical clear aperture.
    ellipse: [Option<f64>; 2],
    /// `ADX`, `ADY`: where the surface's apertures are centred.
    aperture_decentre: [f64; 2],
    /// The line and command that made the aperture other than a centred circle.
    outline_line: Option<(usize, &'static str)>,
    stop: bool,
    placement: Option<Placement>,
}

impl SeqSurface {
    /// The profile the surface's value gives in the radius mode it was written in.
    fn shape_as_read(&self) -> Shape {
        let curvature = match (self.radius_mode, self.value) {
            (false, c) => c,
            (true, 0.0) => 0.0,
            (true, r) => 1.0 / r,
        };
        shape(curvature, self.conic, &self.terms)
    }

    /// An ellipse with equal semi-axes and no other stated aperture is the circle `CIR` states;
    /// centred, it leaves the surface symmetric.
    fn settle_round_ellipse(&mut self) {
        if let [Some(a), Some(b)] = self.ellipse
            && a == b
            && self.clear_radius.is_none()
            && self.rectangle == [None, None]
        {
            self.clear_radius = Some(a);
            self.ellipse = [None, None];
            if self.aperture_decentre == [0.0, 0.0] {
                self.outline_line = None;
            }
        }
    }

    /// The clear aperture where it is rectangular or decentred; a decentre of no stated
    /// aperture is none. Refused: half a rectangle, or a rectangle and a `CIR` on one surface.
    fn outline(&self, source: &Source) -> Result<Option<StatedOutline>, PrescriptionError> {
        let Some((line, command)) = self.outline_line else {
            return Ok(None);
        };
        let refuse = |what: &str| {
            Err(PrescriptionError::new(
                source.location(Some(line)).with_field(command),
                Problem::Unsupported(what.to_string()),
            ))
        };
        let shape = match (self.rectangle, self.ellipse, self.clear_radius) {
            ([Some(_), None] | [None, Some(_)], _, _) => {
                return refuse("a rectangular aperture needs both REX and REY");
            }
            (_, [Some(_), None] | [None, Some(_)], _) => {
                return refuse("an elliptical aperture needs both ELX and ELY");
            }
            ([Some(_), Some(_)], [Some(_), Some(_)], _) => {
                return refuse("a surface with both a rectangular and an elliptical aperture");
            }
            ([Some(_), Some(_)], _, Some(_)) | (_, [Some(_), Some(_)], Some(_)) => {
                return refuse(
                    "a surface with both a CIR and a rectangular or elliptical aperture",
                );
            }
            ([Some(half_width), Some(half_height)], _, None) => OutlineShape::Rectangle {
                half_width,
                half_height,
            },
            (_, [Some(half_width), Some(half_height)], None) => OutlineShape::Ellipse {
                half_width,
                half_height,
            },
            ([None, None], [None, None], Some(radius)) => OutlineShape::Circle { radius },
            ([None, None], [None, None], None) => return Ok(None),
        };
        Ok(Some(StatedOutline {
            outline: ApertureOutline {
                shape,
                centre: self.aperture_decentre,
            },
            line,
            keyword: command.to_string(),
        }))
    }
}

#[derive(Clone, Copy, PartialEq)]
enum Current {
    Nothing,
    Object,
    Surface(usize),
    Image,
}

/// Commands that change no surface: `LEN` (new lens), `INI` (designer), `POL` (polarisation),
/// `CCY`, `GLC`, `KC`, `AC` .. `JC` (optimisation variable codes of curvature, thickness,
/// glass, conic and aspheric terms), `CLS` (plot colours of the wavelengths), `DER`, `SLB` (labels), `SPH`, `CON`, `ASP` (surface-type
/// words whose data arrive through `K` and `A`..`J`), `TEM`, `PRE` (temperature and pressure:
/// the catalogue indices are the makers' at their reference conditions), `COM`. (`ZOO`, which
/// a zoom file uses, is read: see `Reader::zoom`.)
const HARMLESS: &[&str] = &[
    "LEN", "INI", "POL", "CCY", "GLC", "KC", "AC", "BC", "CC", "DC", "EC", "FC", "GC", "HC", "JC",
    "CLS", "DER", "SLB", "SPH", "CON", "ASP", "TEM", "PRE", "COM",
];

/// Paraxial solves: `PIM` (image at the paraxial focus), `CUM`, `CUC` (curvature solves on the
/// marginal and chief rays), `THM`, `THC` (thickness solves on them). CODE V writes every solved
/// curvature and thickness in place, as the lens stood when it saved the file, so the values
/// written are the lens and are kept. They are not re-solved: `questar35.seq` (CODE V 10.7)
/// writes `CUM 0.0; THM 0.601` on a primary mirror whose written curvature gives the marginal
/// ray slope 0.223 and height 0.354 in at the secondary, and that written lens is the Questar
/// 3.5" (EFL 1282.7 mm, f/14.4), so what CODE V solves for is not what those names suggest.
///
/// `RED` (on the object) solves the object distance for a reduction ratio, the magnification;
/// CODE V wrote the solved distance on the `SO` line, which is kept the same way.
const SOLVES: &[&str] = &["PIM", "CUM", "CUC", "THM", "THC", "RED"];

/// Aperture outline commands: a rectangle's half widths in x and y, an ellipse's semi-axes in x
/// and y, an aperture decentre in x and y.
const APERTURE_COMMANDS: [&str; 6] = ["REX", "REY", "ELX", "ELY", "ADX", "ADY"];

/// Thickness solves written after `THI`: the marginal or chief ray's height in y or x.
const THICKNESS_SOLVES: &[&str] = &["HMY", "HCY", "HMX", "HCX"];

/// The solves written after `command` (`CUY` or `THI`).
fn long_form_solves(command: &str) -> &'static [&'static str] {
    if command == "CUY" {
        CURVATURE_SOLVES
    } else {
        THICKNESS_SOLVES
    }
}

/// Curvature solves written after `CUY` (the long form of `CUM` and `CUC`): the marginal or
/// chief ray's angle after the surface (`U`) or its angle of incidence (`I`), in y or x. As for
/// the other solves, the file writes the solved curvature on the surface line, which is kept.
const CURVATURE_SOLVES: &[&str] = &["UMY", "UCY", "UMX", "UCX", "IMY", "ICY", "IMX", "ICX"];

const ASPHERE_LETTERS: [&str; MAX_ASPHERE_TERMS - 1] =
    ["A", "B", "C", "D", "E", "F", "G", "H", "J"];

/// The commands that state fields: angles, object heights, paraxial and real image heights.
/// The decentre commands, by axis.
const DECENTRES: [&str; 3] = ["XDE", "YDE", "ZDE"];
const FIELD_COMMANDS: [&str; 8] = ["XAN", "YAN", "XOB", "YOB", "XIM", "YIM", "XRI", "YRI"];

#[derive(Default)]
struct Reader {
    radius_mode: bool,
    mode_stated: RadiusMode,
    mm_per_unit: f64,
    title: Option<String>,
    epd: Option<f64>,
    f_number: Option<f64>,
    object_na: Option<f64>,
    unusable_aperture: Option<String>,
    wavelengths: Vec<f64>,
    reference: Option<(usize, usize)>,
    /// The line and command of the object distance, the aperture and the fields, the last
    /// written.
    condition_lines: BTreeMap<StatedCondition, (usize, &'static str)>,
    /// The line and command of each surface field set after its `S` line, by surface.
    field_lines: BTreeMap<(usize, &'static str), (usize, &'static str)>,
    /// Field kind and x, y values (YAN/XAN angles, YOB/XOB object heights, YIM/XIM paraxial and
    /// YRI/XRI real image heights), and weights (WTF).
    field_kind: Option<FieldKind>,
    x_fields: Vec<f64>,
    y_fields: Vec<f64>,
    field_weights: Vec<f64>,
    wavelength_weights: Vec<f64>,
    skipped: BTreeSet<String>,
    /// Solves whose results the file writes in place (see [`SOLVES`]).
    solves: BTreeSet<String>,
    /// Private glasses (PRV ... END) by name, and the open PRV block's wavelengths (PWL).
    private: Vec<(String, Medium)>,
    private_block: Option<Vec<f64>>,
    /// VUY, VLY, VUX, VLX per field.
    vignetting: [Vec<f64>; 4],
    object_distance: Option<f64>,
    object_medium: Option<Medium>,
    surfaces: Vec<SeqSurface>,
    /// The image surface's line and decentre (`SI` followed by `YDE`, `ADE`, ...).
    image_line: Option<usize>,
    image_placement: Option<Placement>,
    current: Option<Current>,
    /// Pickups (`PIK`), applied in file order once every surface is read.
    pickups: Vec<Pickup>,
    /// The zoom position read (1-based).
    position: usize,
    /// `ZOO n`: the number of zoom positions, and its line.
    zoom_positions: Option<(usize, usize)>,
    /// The read position's values of zoomed surface and field items (`ZOO THI S3 v1 v2 ..`,
    /// `ZOO YAN F2 ..`), applied once every surface and field is read.
    zoomed: Vec<ZoomedItem>,
    /// Zoomed items read as the lens and system data write them (`ZOO YAN F2 ..`).
    zoomed_as_written: BTreeSet<String>,
}

/// The read position's value of a zoomed surface or field item: `ZOO item Sk v1 v2 ..` or
/// `ZOO item Fk v1 v2 ..`.
struct ZoomedItem {
    line: usize,
    target: ZoomTarget,
    value: f64,
}

/// What a zoomed value sets.
#[derive(Clone, Copy)]
enum ZoomTarget {
    /// A surface's item (1-based surface).
    Surface { item: PickupItem, surface: usize },
    /// One field's value (1-based field) in the list a field command (its index in
    /// [`FIELD_COMMANDS`]) or a vignetting command (`VUY`, `VLY`, `VUX`, `VLX`: 0..4, offset by
    /// the field commands) states.
    Field { list: usize, field: usize },
}

/// The vignetting commands in the order of `Reader::vignetting`.
const VIGNETTING_COMMANDS: [&str; 4] = ["VUY", "VLY", "VUX", "VLX"];

/// Lens data a pickup copies between surfaces.
#[derive(Clone, Copy, PartialEq)]
enum PickupItem {
    Radius,
    Curvature,
    Thickness,
    Conic,
}

/// `PIK item Sk [Zm] item Sj [Zm] [scale [offset]]`: item of surface k = scale * (item of
/// surface j) + offset, as CODE V defines a pickup (both items the same), at zoom position m
/// (every position where none is written, unless the file gives that item its own pickup there).
struct Pickup {
    line: usize,
    position: Option<usize>,
    item: PickupItem,
    target: usize,
    source: usize,
    scale: f64,
    offset: f64,
}

/// How the file chose between radii and curvatures after `S`. Without `RDM`, lensbake reads
/// radii, as optiland 0.6.3 writes its files (without `RDM`, in radii). CODE V itself and
/// rayoptics read such a file as curvatures, and rayoptics' test files are written so
/// (`singlet.seq`: `s 0.1 1`, `s -.05 15`, radii 10 and -20 mm as curvatures). Where the values
/// read as radii give a surface smaller than the beam or clear aperture it must pass, the file is
/// refused with the advice to state the mode ([`Reader::radius_mode_contradicted`]), never read
/// as a lens of 0.1 mm radii.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
enum RadiusMode {
    /// No `RDM`: radii.
    #[default]
    RadiiByDefault,
    /// `RDM` on this line.
    Stated { line: usize },
}

pub(super) fn read(
    text: &str,
    source: &Source,
    position: Option<usize>,
) -> Result<Loaded, PrescriptionError> {
    let mut reader = Reader {
        radius_mode: true,
        mm_per_unit: 1.0,
        position: position.unwrap_or(1),
        current: Some(Current::Nothing),
        ..Reader::default()
    };
    for command in commands(text) {
        if command.name == "GO" {
            break;
        }
        reader.apply(&command, source)?;
        reader.note_field_line(&command);
    }
    reader.finish(source)
}

/// What a `CIR` command states: the clear aperture, a radius inside which rays are blocked
/// (`CIR OBS r`, an obscuration; `CIR HOL r`, a hole, as in a Cassegrain primary), or the
/// lens's mechanical edge (`CIR EDG`), which clips no ray.
#[derive(Clone, Copy, PartialEq)]
enum CircleKind {
    ClearAperture,
    BlocksInside,
    Edge,
}

impl CircleKind {
    fn of(args: &[String]) -> CircleKind {
        match args.first() {
            Some(first) if first.eq_ignore_ascii_case("EDG") => CircleKind::Edge,
            Some(first)
                if first.eq_ignore_ascii_case("OBS") || first.eq_ignore_ascii_case("HOL") =>
            {
                CircleKind::BlocksInside
            }
            _ => CircleKind::ClearAperture,
        }
    }
}

/// The field of lensbake's surface a surface command after `S` sets, as its checks name it
/// (see [`SourceMap::field_lines`]), with the command.
fn validated_field(command: &Command) -> Option<(&'static str, &'static str)> {
    Some(match command.name.as_str() {
        "CIR" => match CircleKind::of(&command.args) {
            CircleKind::Edge => return None,
            CircleKind::BlocksInside => ("obscuration", "CIR"),
            CircleKind::ClearAperture => ("semi_aperture", "CIR"),
        },
        "REX" => ("semi_aperture", "REX"),
        "REY" => ("semi_aperture", "REY"),
        "ELX" => ("semi_aperture", "ELX"),
        "ELY" => ("semi_aperture", "ELY"),
        "STO" | "STOP" => ("stop", "STO"),
        "K" => ("conic", "K"),
        "RDY" => ("curvature", "RDY"),
        "CUY" => ("curvature", "CUY"),
        "THI" => ("thickness", "THI"),
        "GLA" => ("medium", "GLA"),
        letter => (
            "coefficients",
            ASPHERE_LETTERS.iter().find(|l| **l == letter)?,
        ),
    })
}

impl Reader {
    fn current(&self) -> Current {
        self.current.unwrap_or(Current::Nothing)
    }

    fn location(&self, source: &Source, command: &Command, field: &str) -> Location {
        let mut location = source.location(Some(command.line)).with_field(field);
        if let Current::Surface(i) = self.current() {
            location = location.with_surface(i + 1);
        }
        location
    }

    fn apply(&mut self, c: &Command, source: &Source) -> Result<(), PrescriptionError> {
        let surface = match self.current() {
            Current::Surface(i) => Some(i + 1),
            _ => None,
        };
        let at = |field: &str| {
            let mut location = source.location(Some(c.line)).with_field(field);
            location.surface = surface;
            location
        };
        let unsupported =
            |what: String| PrescriptionError::new(at(&c.name), Problem::Unsupported(what));
        let count = |expected: &str, found: usize| {
            PrescriptionError::new(
                at(&c.name),
                Problem::WrongColumnCount {
                    expected: format!("{expected} after {}", c.name),
                    found,
                },
            )
        };
        let one = |field: &str| -> Result<f64, PrescriptionError> {
            match c.args.as_slice() {
                [value] => finite(value, &at(field)),
                other => Err(count("1 value", other.len())),
            }
        };
        let list = |field: &str| -> Result<Vec<f64>, PrescriptionError> {
            c.args.iter().map(|a| finite(a, &at(field))).collect()
        };
        let stated_aperture = |field: &str| -> Result<f64, PrescriptionError> {
            match c.args.as_slice() {
                [value] => positive(value, &at(field)),
                other => Err(count("1 value", other.len())),
            }
        };
        let name = c.name.as_str();
        if let Some(wavelengths) = &self.private_block {
            match name {
                "PWL" => self.private_block = Some(list("PWL")?),
                "END" => self.private_block = None,
                glass
                    if c.args
                        .first()
                        .is_some_and(|f| f.eq_ignore_ascii_case("LAU")) =>
                {
                    let a: [f64; 6] = c.args[1..]
                        .iter()
                        .map(|v| finite(v, &at(glass)))
                        .collect::<Result<Vec<f64>, _>>()?
                        .try_into()
                        .map_err(|found: Vec<f64>| {
                            count("6 Laurent coefficients after LAU", found.len())
                        })?;
                    let medium = Medium::PowerSeries { a };
                    crate::glass::Dispersion::of(&medium)
                        .map_err(|problem| PrescriptionError::new(at(glass), problem))?;
                    self.private.push((glass.to_string(), medium));
                }
                glass => {
                    let indices = c
                        .args
                        .iter()
                        .map(|a| finite(a, &at(glass)))
                        .collect::<Result<Vec<f64>, _>>()
                        .map_err(|_| {
                            unsupported(format!(
                                "private glass {glass} given as {} (indices at the PWL \
                                 wavelengths and LAU Laurent coefficients are read)",
                                c.args.first().map_or("nothing", String::as_str)
                            ))
                        })?;
                    if indices.len() != wavelengths.len() {
                        return Err(count(
                            &format!("{} indices (one per PWL wavelength)", wavelengths.len()),
                            indices.len(),
                        ));
                    }
                    let mut points: Vec<(f64, f64)> =
                        wavelengths.iter().copied().zip(indices).collect();
                    points.sort_by(|a, b| a.0.total_cmp(&b.0));
                    let medium = Medium::Table {
                        wavelengths_nm: points.iter().map(|p| p.0).collect(),
                        indices: points.iter().map(|p| p.1).collect(),
                    };
                    crate::glass::Dispersion::of(&medium)
                        .map_err(|problem| PrescriptionError::new(at(glass), problem))?;
                    self.private.push((glass.to_string(), medium));
                }
            }
            return Ok(());
        }
        match name {
            "PRV" => self.private_block = Some(Vec::new()),
            "RDM" => {
                self.mode_stated = RadiusMode::Stated { line: c.line };
                self.radius_mode = match c.args.first().map(|a| a.to_ascii_uppercase()).as_deref() {
                    None | Some("Y" | "YES") => true,
                    Some("N" | "NO") => false,
                    Some(other) => return Err(unsupported(format!("RDM {other}"))),
                }
            }
            // `TIT Zk 'name'` names zoom position k.
            "TIT" if c.args.first().is_some_and(|a| is_zoom_position(a)) => {
                self.zoomed_as_written.insert("TIT".into());
            }
            "TITLE" | "TIT" => self.title = Some(c.args.join(" ")),
            "DIM" => {
                // CODE V reads the unit by its first letter (files write `MM` too).
                self.mm_per_unit = match c.args.first().map(|a| a.to_ascii_uppercase()).as_deref() {
                    Some("M" | "MM") => 1.0,
                    Some("C" | "CM") => 10.0,
                    Some("I" | "IN") => 25.4,
                    Some(other) => return Err(unsupported(format!("DIM {other}"))),
                    None => return Err(count("1 unit letter", 0)),
                }
            }
            "EPD" => {
                self.epd = Some(stated_aperture("EPD")?);
                self.stated(StatedCondition::Aperture, c.line, "EPD");
            }
            "FNO" => {
                self.f_number = Some(stated_aperture("FNO")?);
                self.stated(StatedCondition::Aperture, c.line, "FNO");
            }
            "NAO" => {
                self.object_na = Some(stated_aperture("NAO")?);
                self.stated(StatedCondition::Aperture, c.line, "NAO");
            }
            "NA" => self.unusable_aperture = Some(format!("the aperture is given as {name}")),
            "WL" => {
                let wavelengths = list("WL")?;
                // Checked on their line: later checks see the design wavelength without one.
                for &nm in &wavelengths {
                    crate::limits::check_wavelength(nm)
                        .map_err(|e| PrescriptionError::new(at("WL"), e.into()))?;
                }
                self.wavelengths = wavelengths;
            }
            "WTW" => self.wavelength_weights = list("WTW")?,
            "WTF" => self.field_weights = list("WTF")?,
            "REF" => {
                let value = one("REF")?;
                if value.fract() != 0.0 || value < 1.0 {
                    return Err(PrescriptionError::new(
                        at("REF"),
                        Problem::Syntax(format!(
                            "REF must name a wavelength by its number, got {value}"
                        )),
                    ));
                }
                self.reference = Some((value as usize, c.line));
            }
            name if FIELD_COMMANDS.contains(&name) => {
                let kind = match &name[1..] {
                    "AN" => FieldKind::AngleDeg,
                    "OB" => FieldKind::ObjectHeight,
                    "IM" => FieldKind::ParaxialImageHeight,
                    _ => FieldKind::RealImageHeight,
                };
                if self.field_kind.is_some_and(|k| k != kind) {
                    return Err(unsupported(format!(
                        "{name} after fields of another kind: one file gives one kind of field"
                    )));
                }
                self.field_kind = Some(kind);
                let values = list(name)?;
                let keyword = FIELD_COMMANDS
                    .iter()
                    .find(|k| **k == name)
                    .expect("matched above");
                self.stated(StatedCondition::Fields, c.line, keyword);
                if name.starts_with('X') {
                    self.x_fields = values;
                } else {
                    self.y_fields = values;
                }
            }
            "VUY" => self.vignetting[0] = list(name)?,
            "VLY" => self.vignetting[1] = list(name)?,
            "VUX" => self.vignetting[2] = list(name)?,
            "VLX" => self.vignetting[3] = list(name)?,
            "SO" => {
                let (value, thickness, medium) = self.surface_words(c, source)?;
                if value != 0.0 {
                    return Err(unsupported("a curved object surface".into()));
                }
                self.object_distance = Some(thickness);
                self.stated(StatedCondition::Object, c.line, "SO");
                self.object_medium = medium;
                self.current = Some(Current::Object);
            }
            "S" => {
                if self.current() == Current::Image {
                    return Err(PrescriptionError::new(
                        at("S"),
                        Problem::Syntax("a surface after the image surface (SI)".into()),
                    ));
                }
                check_surface_count(self.surfaces.len() + 1, at("S"))?;
                self.current = Some(Current::Surface(self.surfaces.len()));
                let (value, thickness, medium) = self.surface_words(c, source)?;
                self.surfaces.push(SeqSurface {
                    line: c.line,
                    value,
                    radius_mode: self.radius_mode,
                    thickness,
                    medium: medium.unwrap_or(Medium::Air),
                    conic: 0.0,
                    terms: [0.0; MAX_ASPHERE_TERMS],
                    clear_radius: None,
                    obscuration: None,
                    rectangle: [None; 2],
                    ellipse: [None; 2],
                    aperture_decentre: [0.0; 2],
                    outline_line: None,
                    stop: false,
                    placement: None,
                });
            }
            "SI" => {
                let (value, _, _) = self.surface_words(c, source)?;
                if value != 0.0 {
                    return Err(unsupported("a curved image surface".into()));
                }
                self.current = Some(Current::Image);
                self.image_line = Some(c.line);
            }
            // CODE V reads a command by its first three letters; files write STOP for STO too.
            "STO" | "STOP" => match self.current() {
                Current::Surface(i) => self.surfaces[i].stop = true,
                _ => {
                    return Err(PrescriptionError::new(
                        at(name),
                        Problem::Syntax(format!("{name} must follow a lens surface (S)")),
                    ));
                }
            },
            "CIR" => {
                if c.args.is_empty() {
                    return Err(count("1 value", 0));
                }
                let kind = CircleKind::of(&c.args);
                if kind == CircleKind::Edge {
                    self.skipped.insert("CIR EDG".into());
                    return Ok(());
                }
                // An obscuration and a hole both take the rays inside r off the sequential
                // path; an aperture label (L'A') names the aperture and changes nothing.
                let blocks_inside = kind == CircleKind::BlocksInside;
                let values: Vec<&String> = c
                    .args
                    .iter()
                    .skip(usize::from(blocks_inside))
                    .filter(|a| !is_aperture_label(a))
                    .collect();
                let [value] = values.as_slice() else {
                    return Err(unsupported(format!(
                        "CIR {} (only a radius, CIR OBS r, CIR HOL r and CIR EDG are read)",
                        c.args.join(" ")
                    )));
                };
                let radius = finite(value, &at("CIR"))?;
                if let Current::Surface(i) = self.current() {
                    if blocks_inside {
                        self.surfaces[i].obscuration = Some(radius);
                    } else {
                        self.surfaces[i].clear_radius = Some(radius);
                    }
                }
            }
            // A rectangular aperture's half widths, an elliptical one's semi-axes and an aperture
            // decentre (x, y).
            "REX" | "REY" | "ELX" | "ELY" | "ADX" | "ADY" => {
                let value = one(name)?;
                let k = APERTURE_COMMANDS
                    .iter()
                    .position(|command| *command == name)
                    .expect("matched above");
                let (rectangle, ellipse, axis) = (k < 2, (2..4).contains(&k), k % 2);
                if (rectangle || ellipse) && !(value > 0.0) {
                    return Err(PrescriptionError::new(
                        at(name),
                        Problem::Syntax(format!(
                            "{name} {value} passes no ray: a half width must be positive"
                        )),
                    ));
                }
                let line = c.line;
                self.on_surface(
                    c,
                    source,
                    "an aperture outline on the object or image surface",
                    true,
                    |s| {
                        if rectangle {
                            s.rectangle[axis] = Some(value);
                        } else if ellipse {
                            s.ellipse[axis] = Some(value);
                        } else {
                            s.aperture_decentre[axis] = value;
                        }
                        if rectangle || ellipse || value != 0.0 {
                            s.outline_line.get_or_insert((line, APERTURE_COMMANDS[k]));
                        }
                    },
                )?;
            }
            "K" => {
                let value = one("K")?;
                self.on_surface(
                    c,
                    source,
                    "a conic object or image surface",
                    value != 0.0,
                    |s| s.conic = value,
                )?;
            }
            letter if ASPHERE_LETTERS.contains(&letter) => {
                let value = one(letter)?;
                let term = 1 + ASPHERE_LETTERS
                    .iter()
                    .position(|l| *l == letter)
                    .unwrap_or_default();
                self.on_surface(
                    c,
                    source,
                    "an aspheric object or image surface",
                    value != 0.0,
                    |s| s.terms[term] = value,
                )?;
            }
            // `CUY UMY -0.1` solves the curvature for a marginal ray angle of -0.1 after the
            // surface, `THI HMY 0` the thickness for a marginal ray height of 0 on the next
            // surface; CODE V wrote the solved value on the surface line, which is kept as for
            // the other solves.
            "CUY" | "THI"
                if c.args.len() == 2
                    && long_form_solves(name)
                        .contains(&c.args[0].to_ascii_uppercase().as_str()) =>
            {
                finite(&c.args[1], &at(name))?;
                self.solves
                    .insert(format!("{name} {}", c.args[0].to_ascii_uppercase()));
            }
            "CUY" | "THI" if c.args.len() == 2 && c.args[0].parse::<f64>().is_err() => {
                return Err(unsupported(format!(
                    "CODE V solve `{name} {}` (read after {name}: {})",
                    c.args[0],
                    long_form_solves(name).join(", ")
                )));
            }
            "RDY" | "CUY" => {
                let value = one(name)?;
                let radius_mode = name == "RDY";
                self.on_surface(
                    c,
                    source,
                    "a curved object or image surface",
                    value != 0.0,
                    |s| {
                        s.value = value;
                        s.radius_mode = radius_mode;
                    },
                )?;
            }
            "THI" => {
                let value = match c.args.as_slice() {
                    [value] => object_distance(value, &at("THI"))?,
                    other => return Err(count("1 value", other.len())),
                };
                match self.current() {
                    Current::Object => {
                        self.object_distance = Some(value);
                        self.stated(StatedCondition::Object, c.line, "THI");
                    }
                    Current::Surface(i) => {
                        self.surfaces[i].thickness = finite(&c.args[0], &at("THI"))?;
                    }
                    // The image surface's thickness is a defocus, not part of the lens.
                    Current::Image | Current::Nothing => {}
                }
            }
            "GLA" => {
                let medium = match c.args.as_slice() {
                    [glass] => glass_medium(glass, &self.private, &at("GLA"))?,
                    other => return Err(count("1 glass name", other.len())),
                };
                match self.current() {
                    Current::Object => self.object_medium = Some(medium),
                    Current::Surface(i) => self.surfaces[i].medium = medium,
                    Current::Image | Current::Nothing => {}
                }
            }
            // CODE V writes `CUF 0.0` into every ASP block; zero leaves the profile as K and
            // A..J give it. lensbake does not model another value.
            "CUF" => {
                let value = one("CUF")?;
                if value != 0.0 {
                    return Err(unsupported(format!(
                        "CUF {value} (only the CUF 0 that CODE V writes in every ASP block is read)"
                    )));
                }
                self.skipped.insert("CUF 0".into());
            }
            "ZOO" => self.zoom(c, source)?,
            "PIK" => {
                let pickup = pickup(c).map_err(|why| {
                    unsupported(format!("pickup `PIK {}`: {why}", c.args.join(" ")))
                })?;
                self.pickups.push(pickup);
            }
            "XDE" | "YDE" | "ZDE" | "ADE" | "BDE" | "CDE" | "DAR" | "BEN" | "REV" => {
                let value = if matches!(name, "DAR" | "BEN" | "REV") {
                    if !c.args.is_empty() {
                        return Err(count("no value", c.args.len()));
                    }
                    0.0
                } else {
                    one(name)?
                };
                let line = c.line;
                let placement = match self.current() {
                    Current::Surface(i) => &mut self.surfaces[i].placement,
                    Current::Image => &mut self.image_placement,
                    Current::Object | Current::Nothing => {
                        return Err(unsupported(format!(
                            "{name} before the first lens surface (a decentred object)"
                        )));
                    }
                };
                let placement = placement
                    .get_or_insert_with(|| Placement::new(PlacementKind::Basic, line, name));
                match name {
                    "DAR" => placement.kind = PlacementKind::DecentreAndReturn,
                    "BEN" => placement.kind = PlacementKind::Bend,
                    "REV" => placement.kind = PlacementKind::Reverse,
                    // CODE V's alpha and beta turn left-handed, gamma right-handed.
                    "ADE" => placement.tilt_deg[0] = -value,
                    "BDE" => placement.tilt_deg[1] = -value,
                    "CDE" => placement.tilt_deg[2] = value,
                    _ => {
                        let axis = usize::from(name.as_bytes()[0] - b'X');
                        placement.decentre[axis] = value;
                        placement.decentre_at[axis] = Some((line, DECENTRES[axis]));
                    }
                }
            }
            // `CA` alone, in the system data (rayoptics' table of CODE V commands files it
            // there), chooses how CODE V's own analyses use the clear apertures; lensbake
            // clips at every stated one.
            "CA" if c.args.is_empty() => {
                self.skipped.insert("CA".to_string());
            }
            harmless if HARMLESS.contains(&harmless) => {
                self.skipped.insert(harmless.to_string());
            }
            solve if SOLVES.contains(&solve) => {
                self.solves.insert(solve.to_string());
            }
            // `DIF DOE` (or `DIF HOE`) makes the surface diffractive: `HOR` the order, `HWL` the
            // construction wavelength, `HCT` the phase's form (R: a polynomial in r^2, `HCO C1`
            // on r^2, C2 on r^4, ...: C1 alone is a paraxial power of 2 |C1| m l / HWL), `HCO`
            // its coefficients. No lensbake tracer bends rays by a phase, so it is refused by
            // name.
            "DIF" => {
                return Err(unsupported(format!(
                    "a diffractive surface (`DIF {}`: a phase added to the surface, with HOR, \
                     HWL, HCT, HCO); lensbake traces no diffractive phase",
                    c.args.join(" ")
                )));
            }
            other => return Err(unsupported(format!("CODE V command `{other}`"))),
        }
        Ok(())
    }

    /// `S value thickness [glass]` and its relatives `SO` and `SI`.
    /// Records the line of a surface command that sets one field of the current surface.
    fn note_field_line(&mut self, command: &Command) {
        if let (Current::Surface(i), Some((field, keyword))) =
            (self.current(), validated_field(command))
        {
            self.field_lines.insert((i, field), (command.line, keyword));
        }
    }

    fn stated(&mut self, condition: StatedCondition, line: usize, keyword: &'static str) {
        self.condition_lines.insert(condition, (line, keyword));
    }

    fn surface_words(
        &self,
        c: &Command,
        source: &Source,
    ) -> Result<(f64, f64, Option<Medium>), PrescriptionError> {
        let at = |field: &str| self.location(source, c, field);
        if !(2..=3).contains(&c.args.len()) {
            return Err(PrescriptionError::new(
                at(&c.name),
                Problem::WrongColumnCount {
                    expected: format!(
                        "2 or 3 values after {} ({}, thickness, optional glass)",
                        c.name,
                        if self.radius_mode {
                            "radius"
                        } else {
                            "curvature"
                        }
                    ),
                    found: c.args.len(),
                },
            ));
        }
        let value_field = if self.radius_mode {
            "radius"
        } else {
            "curvature"
        };
        let value = finite(&c.args[0], &at(value_field))?;
        // The object distance may be infinite; anything else must be finite.
        let thickness = if c.name == "SO" {
            object_distance(&c.args[1], &at("thickness"))?
        } else {
            finite(&c.args[1], &at("thickness"))?
        };
        let medium = match c.args.get(2) {
            Some(glass) => Some(glass_medium(glass, &self.private, &at("glass"))?),
            None => None,
        };
        Ok((value, thickness, medium))
    }

    /// Applies a surface modifier to the current lens surface; on the object or image surface a
    /// non-trivial value is refused as `what`.
    fn on_surface(
        &mut self,
        c: &Command,
        source: &Source,
        what: &str,
        nontrivial: bool,
        change: impl FnOnce(&mut SeqSurface),
    ) -> Result<(), PrescriptionError> {
        match self.current() {
            Current::Surface(i) => {
                change(&mut self.surfaces[i]);
                Ok(())
            }
            Current::Object | Current::Image if nontrivial => Err(PrescriptionError::new(
                self.location(source, c, &c.name),
                Problem::Unsupported(what.to_string()),
            )),
            Current::Object | Current::Image => Ok(()),
            Current::Nothing => Err(PrescriptionError::new(
                self.location(source, c, &c.name),
                Problem::Syntax(format!("{} before the first surface", c.name)),
            )),
        }
    }

    fn finish(mut self, source: &Source) -> Result<Loaded, PrescriptionError> {
        if self.surfaces.is_empty() {
            return Err(source.error(None, Problem::Empty));
        }
        self.check_position(source)?;
        self.apply_zoomed(source)?;
        self.apply_pickups(source)?;
        for s in &mut self.surfaces {
            s.settle_round_ellipse();
        }
        let wavelength = match self.reference {
            Some((reference, line)) => match self.wavelengths.get(reference - 1) {
                Some(&nm) => Some(nm),
                None => {
                    return Err(PrescriptionError::new(
                        source.location(Some(line)).with_field("REF"),
                        Problem::Syntax(format!(
                            "REF {reference} names no wavelength; WL lists {}",
                            self.wavelengths.len()
                        )),
                    ));
                }
            },
            None => self.wavelengths.first().copied(),
        };
        self.check_stated_apertures(source)?;
        // CODE V's default: without STO, surface 1 is the stop.
        let stop_given = self.surfaces.iter().any(|s| s.stop);
        let surfaces: Vec<Surface> = self
            .surfaces
            .iter()
            .enumerate()
            .map(|(i, s)| Surface {
                shape: s.shape_as_read(),
                thickness: s.thickness,
                medium: s.medium.clone(),
                semi_aperture: s.clear_radius.unwrap_or(0.0),
                stop: (s.stop || (!stop_given && i == 0)).then_some(StopShape::Circle),
                obscuration: s.obscuration,
            })
            .collect();
        let mut missing: Vec<usize> = (0..surfaces.len())
            .filter(|&i| self.surfaces[i].clear_radius.is_none())
            .collect();
        let mm = self.mm_per_unit;
        let conditions = self.conditions(wavelength);

        let mut prescription = Prescription {
            provenance: Provenance {
                title: self.title.clone().unwrap_or_else(|| source.default_title()),
                source: source.file_name(),
                design_wavelength_nm: wavelength,
                claimed_f_number: self.f_number,
                notes: (!missing.is_empty()).then(|| {
                    "clear apertures not in the file were derived by lensbake from paraxial rays"
                        .to_string()
                }),
                conditions: Some(conditions.clone()),
                ..Provenance::default()
            },
            object_medium: self.object_medium.clone().unwrap_or(Medium::Air),
            surfaces,
        };
        scale_to_mm(&mut prescription, mm);
        let placements: Vec<Option<Placement>> =
            self.surfaces.iter().map(|s| s.placement.clone()).collect();
        let lines: Vec<usize> = self.surfaces.iter().map(|s| s.line).collect();
        let asymmetries = self
            .surfaces
            .iter()
            .map(|s| {
                s.outline(source).map(|outline| Asymmetry {
                    outline,
                    toroid: None,
                })
            })
            .collect::<Result<Vec<_>, _>>()?;
        let centred = placement::centre_if_placed(
            &mut prescription,
            &placements,
            self.image_placement.as_ref(),
            &asymmetries,
            &mut missing,
            &[],
            mm,
            &lines,
            self.image_line.unwrap_or(lines[lines.len() - 1]),
            source,
        )?;
        let map = SourceMap {
            file: source.file.map(|f| f.to_path_buf()),
            surface_lines: self.surfaces.iter().map(|s| Some(s.line)).collect(),
            condition_lines: self.condition_lines.clone(),
            field_lines: self.field_lines.clone(),
        };
        let pupils: Vec<_> = (0..conditions.fields.as_ref().map_or(0, |f| f.x.len()))
            .map(|k| {
                let get = |list: &[f64]| list.get(k).copied().unwrap_or(0.0);
                let [vuy, vly, vux, vlx] = [0, 1, 2, 3].map(|v| get(&self.vignetting[v]));
                ((-(1.0 - vlx), 1.0 - vux), (-(1.0 - vly), 1.0 - vuy))
            })
            .collect();
        let trimmed = apertures::trimmed_fields(&pupils);
        let beams = BeamSpec::from_conditions(
            &conditions,
            &pupils,
            self.unusable_aperture
                .clone()
                .unwrap_or_else(|| "the file has neither CIR nor EPD, FNO or NAO".into()),
            wavelength.unwrap_or(DEFAULT_WAVELENGTH_NM),
        );
        let mut loaded =
            apertures::complete(prescription, &missing, &[], &beams, map, Format::CodeV)?;
        if self.mode_stated == RadiusMode::RadiiByDefault {
            for &i in &missing {
                let surface = &loaded.prescription.surfaces[i];
                let rim = surface.shape.rim_radius();
                if rim.is_some_and(|rim| surface.semi_aperture >= rim * (1.0 - 1e-12)) {
                    return Err(self.radius_mode_contradicted(
                        i,
                        source,
                        "the paraxial beam of the file's aperture and fields reaches past that \
                         rim"
                        .to_string(),
                        rim.unwrap_or_default(),
                    ));
                }
            }
        }
        loaded.notes.extend(centred);
        if !trimmed.is_empty() {
            loaded
                .notes
                .push(LoadNote::VignettingNotApplied { fields: trimmed });
        }
        if !self.skipped.is_empty() {
            loaded.notes.push(LoadNote::SkippedKeywords {
                keywords: self.skipped.into_iter().collect(),
            });
        }
        if !self.solves.is_empty() {
            loaded.notes.push(LoadNote::SolvesAsWritten {
                solves: self.solves.into_iter().collect(),
            });
        }
        if let Some((count, _)) = self.zoom_positions.filter(|&(n, _)| n > 1) {
            loaded.notes.push(LoadNote::ZoomPosition {
                position: self.position,
                count,
                as_written: self.zoomed_as_written.into_iter().collect(),
            });
        }
        Ok(loaded)
    }

    /// A clear aperture (`CIR`) larger than where the surface as read ends (a sphere at |R|, a
    /// conic at 1 / (|c| sqrt(1 + k))): the values after `S` were read in the wrong radius mode.
    fn check_stated_apertures(&self, source: &Source) -> Result<(), PrescriptionError> {
        for (i, s) in self.surfaces.iter().enumerate() {
            let (Some(aperture), Some(rim)) = (s.clear_radius, s.shape_as_read().rim_radius())
            else {
                continue;
            };
            if aperture > rim {
                return Err(self.radius_mode_contradicted(
                    i,
                    source,
                    format!(
                        "the file states a clear aperture of {} (CIR)",
                        crate::limits::short(aperture)
                    ),
                    rim,
                ));
            }
        }
        Ok(())
    }

    /// The error for surface `i` (0-based) whose value, read in the file's radius mode, gives a
    /// surface that ends at `rim` (file units) where the file needs more.
    fn radius_mode_contradicted(
        &self,
        i: usize,
        source: &Source,
        needed: String,
        rim: f64,
    ) -> PrescriptionError {
        let s = &self.surfaces[i];
        let (read_as, field) = if s.radius_mode {
            ("a radius", "radius")
        } else {
            ("a curvature", "curvature")
        };
        let (why, suggestion) = match (self.mode_stated, s.radius_mode) {
            (RadiusMode::RadiiByDefault, _) => (
                "the file has no RDM, and lensbake reads radii without it".to_string(),
                "if the file's values are curvatures (as CODE V reads a file without RDM), add \
                 `RDM N` before the surfaces",
            ),
            (RadiusMode::Stated { line }, true) => (
                format!("RDM on line {line}"),
                "if the file's values are curvatures, write `RDM N`",
            ),
            (RadiusMode::Stated { line }, false) => (
                format!("RDM N on line {line}"),
                "if the file's values are radii, write `RDM Y`",
            ),
        };
        let mut location = source.location(Some(s.line)).with_field(field);
        location.surface = Some(i + 1);
        PrescriptionError::new(
            location,
            Problem::RadiusModeContradicted(Box::new(RadiusModeContradiction {
                read_as,
                why,
                radius: rim,
                needed,
                suggestion,
            })),
        )
    }

    /// `ZOO n` (the number of zoom positions) or `ZOO item [Sk | Fk] v1 v2 .. vn` (an item's
    /// value at each position). lensbake reads one position, k: a surface's thickness, radius,
    /// curvature and conic, the object distance (`THI S0`), EPD, FNO, a field's value
    /// (`YAN F2`, ...) and its vignetting factors (`VUY F2`, ...) take their k-th value; any
    /// other zoomed item (titles, clear apertures, glasses, labels, variable codes) is read as
    /// the lens and system data write it, and named in the note. A line without a k-th value
    /// is refused where it stands.
    fn zoom(&mut self, c: &Command, source: &Source) -> Result<(), PrescriptionError> {
        let at = |field: &str| source.location(Some(c.line)).with_field(field);
        let words: Vec<String> = c.args.iter().map(|w| w.to_ascii_uppercase()).collect();
        let Some(item) = words.first() else {
            return Err(PrescriptionError::new(
                at("ZOO"),
                Problem::WrongColumnCount {
                    expected: "a position count or an item after ZOO".into(),
                    found: 0,
                },
            ));
        };
        if let Ok(count) = item.parse::<usize>() {
            if count == 0 || words.len() > 1 {
                return Err(PrescriptionError::new(
                    at("ZOO"),
                    Problem::Syntax(format!(
                        "`ZOO {}` is not a count of positions",
                        c.args.join(" ")
                    )),
                ));
            }
            self.zoom_positions = Some((count, c.line));
            // Refused here, before a zoomed item's line lacks the value.
            return self.check_position(source);
        }
        let target = words.get(1).filter(|w| {
            w.strip_prefix(['S', 'F'])
                .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
        });
        let field = format!("ZOO {item}");
        let values = &words[if target.is_some() { 2 } else { 1 }..];
        // The k-th value, once the item is known to be one lensbake applies.
        let position = self.position;
        let value_here = || -> Result<&String, PrescriptionError> {
            position
                .checked_sub(1)
                .and_then(|i| values.get(i))
                .ok_or_else(|| {
                    PrescriptionError::new(
                        at(&field),
                        Problem::WrongColumnCount {
                            expected: format!(
                                "a value for zoom position {} after {field}{}",
                                position,
                                target.map_or(String::new(), |t| format!(" {t}"))
                            ),
                            found: values.len(),
                        },
                    )
                })
        };
        let surface_item = match item.as_str() {
            "THI" => Some(PickupItem::Thickness),
            "RDY" => Some(PickupItem::Radius),
            "CUY" => Some(PickupItem::Curvature),
            "K" => Some(PickupItem::Conic),
            _ => None,
        };
        let field_list = FIELD_COMMANDS
            .iter()
            .chain(&VIGNETTING_COMMANDS)
            .position(|command| *command == item.as_str());
        let number_of = |t: &str| -> Result<usize, PrescriptionError> {
            t[1..].parse::<usize>().map_err(|_| {
                PrescriptionError::new(
                    at(&field),
                    Problem::Syntax(format!("`{t}` is not a number")),
                )
            })
        };
        let zoomed = match (item.as_str(), surface_item, field_list, target) {
            ("THI", _, _, Some(t)) if t == "S0" => {
                self.object_distance = Some(object_distance(value_here()?, &at(&field))?);
                self.stated(StatedCondition::Object, c.line, "ZOO THI S0");
                return Ok(());
            }
            (_, Some(item), _, Some(t)) if t.starts_with('S') => ZoomTarget::Surface {
                item,
                surface: number_of(t)?,
            },
            (_, _, Some(list), Some(t)) if t.starts_with('F') => ZoomTarget::Field {
                list,
                field: number_of(t)?,
            },
            ("EPD", _, _, None) => {
                self.epd = Some(positive(value_here()?, &at(&field))?);
                self.stated(StatedCondition::Aperture, c.line, "ZOO EPD");
                return Ok(());
            }
            ("FNO", _, _, None) => {
                self.f_number = Some(positive(value_here()?, &at(&field))?);
                self.stated(StatedCondition::Aperture, c.line, "ZOO FNO");
                return Ok(());
            }
            _ => {
                self.zoomed_as_written.insert(item.clone());
                return Ok(());
            }
        };
        self.zoomed.push(ZoomedItem {
            line: c.line,
            target: zoomed,
            value: finite(value_here()?, &at(&field))?,
        });
        Ok(())
    }

    /// Refuses a zoom position the file does not have, at its `ZOO n` line.
    fn check_position(&self, source: &Source) -> Result<(), PrescriptionError> {
        let (count, line) = match self.zoom_positions {
            Some((count, line)) => (count, Some(line)),
            None => (1, None),
        };
        if (1..=count).contains(&self.position) {
            return Ok(());
        }
        let what = match line {
            Some(_) => format!("the file has zoom positions 1 to {count}"),
            None => "the file has no zoom positions (no ZOO n): position 1 is the lens".into(),
        };
        Err(PrescriptionError::new(
            source.location(line).with_field("ZOO"),
            Problem::Unsupported(format!("zoom position {}; {what}", self.position)),
        ))
    }

    /// Sets each zoomed surface and field item to its value at the position read.
    fn apply_zoomed(&mut self, source: &Source) -> Result<(), PrescriptionError> {
        for zoomed in std::mem::take(&mut self.zoomed) {
            let (item, number) = match zoomed.target {
                ZoomTarget::Field { list, field } => {
                    let values = match list.checked_sub(FIELD_COMMANDS.len()) {
                        Some(v) => &mut self.vignetting[v],
                        None if FIELD_COMMANDS[list].starts_with('X') => &mut self.x_fields,
                        None => &mut self.y_fields,
                    };
                    let Some(value) = field.checked_sub(1).and_then(|i| values.get_mut(i)) else {
                        return Err(PrescriptionError::new(
                            source.location(Some(zoomed.line)).with_field("ZOO"),
                            Problem::Syntax(format!(
                                "ZOO names field {field}; the file states {} values there",
                                values.len()
                            )),
                        ));
                    };
                    *value = zoomed.value;
                    continue;
                }
                ZoomTarget::Surface { item, surface } => (item, surface),
            };
            let Some(s) = number.checked_sub(1).and_then(|i| self.surfaces.get_mut(i)) else {
                return Err(PrescriptionError::new(
                    source.location(Some(zoomed.line)).with_field("ZOO"),
                    Problem::Syntax(format!(
                        "ZOO names surface {number}; the file has surfaces 1..{}",
                        self.surfaces.len()
                    )),
                ));
            };
            match item {
                PickupItem::Thickness => s.thickness = zoomed.value,
                PickupItem::Conic => s.conic = zoomed.value,
                PickupItem::Radius | PickupItem::Curvature => {
                    s.value = zoomed.value;
                    s.radius_mode = item == PickupItem::Radius;
                }
            }
        }
        Ok(())
    }

    /// Evaluates the pickups of the position read in file order, so a pickup may read what an
    /// earlier one wrote: those written for it (`Zk`), and those written for no position whose
    /// item the file does not pick up for this position on its own.
    fn apply_pickups(&mut self, source: &Source) -> Result<(), PrescriptionError> {
        let pickups = std::mem::take(&mut self.pickups);
        let position = self.position;
        let own = |p: &Pickup| {
            pickups
                .iter()
                .any(|q| q.position == Some(position) && q.item == p.item && q.target == p.target)
        };
        let here: Vec<&Pickup> = pickups
            .iter()
            .filter(|p| match p.position {
                Some(k) => k == position,
                None => !own(p),
            })
            .collect();
        for pickup in here {
            let count = self.surfaces.len();
            for k in [pickup.target, pickup.source] {
                if !(1..=count).contains(&k) {
                    return Err(PrescriptionError::new(
                        source.location(Some(pickup.line)).with_field("PIK"),
                        Problem::Unsupported(format!(
                            "a pickup naming surface S{k}; the lens has surfaces S1..S{count}"
                        )),
                    ));
                }
            }
            let from = &self.surfaces[pickup.source - 1];
            let curvature = match (from.radius_mode, from.value) {
                (false, c) => c,
                (true, 0.0) => 0.0,
                (true, r) => 1.0 / r,
            };
            let picked = |value: f64| pickup.scale * value + pickup.offset;
            let value = match pickup.item {
                PickupItem::Radius if curvature == 0.0 => 0.0,
                PickupItem::Radius => picked(1.0 / curvature),
                PickupItem::Curvature => picked(curvature),
                PickupItem::Thickness => picked(from.thickness),
                PickupItem::Conic => picked(from.conic),
            };
            let to = &mut self.surfaces[pickup.target - 1];
            match pickup.item {
                PickupItem::Radius | PickupItem::Curvature => {
                    to.value = value;
                    to.radius_mode = pickup.item == PickupItem::Radius;
                }
                PickupItem::Thickness => to.thickness = value,
                PickupItem::Conic => to.conic = value,
            }
        }
        Ok(())
    }

    /// Object distance, aperture, fields and wavelengths as the file states them, in mm and nm.
    fn conditions(&self, primary_nm: Option<f64>) -> Conditions {
        let mm = self.mm_per_unit;
        let kind = self.field_kind.unwrap_or(FieldKind::AngleDeg);
        let unit = if kind == FieldKind::AngleDeg { 1.0 } else { mm };
        let count = self.x_fields.len().max(self.y_fields.len());
        let component = |list: &[f64]| -> Vec<f64> {
            (0..count)
                .map(|k| list.get(k).copied().unwrap_or(0.0) * unit)
                .collect()
        };
        let object_distance_mm = self
            .object_distance
            .map(|d| d * mm)
            .filter(|d| d.abs() < INFINITE_OBJECT_MM);
        let finite_object = object_distance_mm.is_some();
        let aperture = match (self.epd, self.f_number, self.object_na) {
            (Some(epd), _, _) => Some(ApertureSpec::EntrancePupilDiameter(epd * mm)),
            // CODE V's FNO is the image-space F-number at the lens's conjugates.
            (None, Some(f), _) if finite_object => Some(ApertureSpec::WorkingFNumber(f)),
            (None, Some(f), _) => Some(ApertureSpec::FNumber(f)),
            (None, None, Some(na)) => Some(ApertureSpec::ObjectNumericalAperture(na)),
            (None, None, None) => None,
        };
        let weights = &self.wavelength_weights;
        Conditions {
            object_distance_mm,
            aperture,
            fields: (count > 0).then(|| FieldSpec {
                kind,
                x: component(&self.x_fields),
                y: component(&self.y_fields),
                weights: super::field_weights(&self.field_weights, count),
            }),
            primary: primary_nm.and_then(|nm| self.wavelengths.iter().position(|w| *w == nm)),
            wavelength_weights: if weights.len() == self.wavelengths.len() {
                weights.clone()
            } else {
                vec![1.0; self.wavelengths.len()]
            },
            wavelengths_nm: self.wavelengths.clone(),
            // No CODE V command this reader applies states one.
            ray_aiming: None,
        }
    }
}

/// Parses `PIK item Sk [Zm] item Sj [Zm] [scale [offset]]` (a source without its own position
/// is read at the target's); the error says which part is not read.
fn pickup(c: &Command) -> Result<Pickup, String> {
    let upper: Vec<String> = c.args.iter().map(|w| w.to_ascii_uppercase()).collect();
    let mut words = upper.into_iter().peekable();
    let (item, target, position) = item_and_surface(&mut words)?;
    let (source_item, source, source_position) = item_and_surface(&mut words)?;
    if source_item != item {
        return Err("a pickup between different items".into());
    }
    if source_position.is_some() && source_position != position {
        return Err("a pickup between zoom positions".into());
    }
    let mut number = |name: &str, default: f64| match words.next() {
        None => Ok(default),
        Some(w) => w
            .parse::<f64>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| format!("the {name} `{w}` is not a finite number")),
    };
    let scale = number("scale", 1.0)?;
    let offset = number("offset", 0.0)?;
    if words.next().is_some() {
        return Err("more words than item, surface, item, surface, scale and offset".into());
    }
    Ok(Pickup {
        line: c.line,
        position,
        item,
        target,
        source,
        scale,
        offset,
    })
}

type Words = std::iter::Peekable<std::vec::IntoIter<String>>;

/// Whether `word` names a zoom position: `Zk`.
fn is_zoom_position(word: &str) -> bool {
    zoom_position(word).is_some()
}

/// The k of a zoom position `Zk`.
fn zoom_position(word: &str) -> Option<usize> {
    let upper = word.to_ascii_uppercase();
    upper
        .strip_prefix('Z')?
        .parse::<usize>()
        .ok()
        .filter(|&k| k > 0)
}

/// One `item Sk [Zm]` of a pickup, with its zoom position (None where none is written).
fn item_and_surface(words: &mut Words) -> Result<(PickupItem, usize, Option<usize>), String> {
    let item = match words.next().as_deref() {
        Some("RDY") => PickupItem::Radius,
        Some("CUY") => PickupItem::Curvature,
        Some("THI") => PickupItem::Thickness,
        Some("K") => PickupItem::Conic,
        Some(other) => return Err(format!("item {other} is not read (RDY, CUY, THI, K are)")),
        None => return Err("an item and a surface are missing".into()),
    };
    let surface = words.next().ok_or("a surface (Sk) is missing")?;
    let k = surface
        .strip_prefix('S')
        .and_then(|k| k.parse::<usize>().ok())
        .ok_or_else(|| format!("`{surface}` is not a surface Sk"))?;
    let position = match words.next_if(|w| w.starts_with('Z')) {
        Some(zoom) => Some(
            zoom_position(&zoom).ok_or_else(|| format!("`{zoom}` is not a zoom position Zk"))?,
        ),
        None => None,
    };
    Ok((item, k, position))
}

/// An object distance: a number, possibly infinite, never NaN.
fn object_distance(text: &str, at: &Location) -> Result<f64, PrescriptionError> {
    let value = number(text, at)?;
    if value.is_nan() {
        return Err(PrescriptionError::new(
            at.clone(),
            Problem::NonFinite { value },
        ));
    }
    Ok(value)
}

/// The medium a glass word names: a catalogue name, or a CODE V fictitious glass code
/// `NNNNNN.VVVV` (nd = 1.NNNNNN, Vd = VV.VV; Vd 0 means a constant index).
fn glass_medium(
    glass: &str,
    private: &[(String, Medium)],
    at: &Location,
) -> Result<Medium, PrescriptionError> {
    if let Some((_, medium)) = private
        .iter()
        .find(|(name, _)| name.eq_ignore_ascii_case(glass))
    {
        return Ok(medium.clone());
    }
    let refuse = |what: String| {
        Err(PrescriptionError::new(
            at.clone(),
            Problem::Unsupported(what),
        ))
    };
    if glass.eq_ignore_ascii_case("REFL") {
        return Ok(Medium::Mirror);
    }
    // A model glass written as nd:vd ("1.5168:64.17").
    if let Some((nd, vd)) = glass.split_once(':')
        && let (Ok(nd), Ok(vd)) = (nd.parse::<f64>(), vd.parse::<f64>())
    {
        if !(nd.is_finite() && vd.is_finite()) {
            return refuse(format!(
                "model glass {glass} with a value that is not finite"
            ));
        }
        return Ok(if vd == 0.0 {
            Medium::Index(nd)
        } else {
            Medium::Model { nd, vd }
        });
    }
    let all_digits = |s: &str| !s.is_empty() && s.bytes().all(|b| b.is_ascii_digit());
    match glass.split_once('.') {
        Some((index_digits, abbe_digits))
            if all_digits(index_digits) && all_digits(abbe_digits) =>
        {
            // Digit strings behind "1." and "0." always parse as f64.
            let nd = format!("1.{index_digits}")
                .parse::<f64>()
                .unwrap_or(f64::NAN);
            let vd = format!("0.{abbe_digits}")
                .parse::<f64>()
                .unwrap_or(f64::NAN)
                * 100.0;
            Ok(if vd == 0.0 {
                Medium::Index(nd)
            } else {
                Medium::Model { nd, vd }
            })
        }
        None if all_digits(glass) => refuse(format!(
            "six-digit glass code {glass}; name the glass, or give a fictitious glass as nnnnnn.vvvv"
        )),
        _ => Ok(named_medium(glass, &[], None).0),
    }
}

/// An aperture's label: `L'A'` in `CIR OBS L'A' 0.38`, which reaches the reader as `LA` (quotes
/// are removed when commands are split).
fn is_aperture_label(word: &str) -> bool {
    word.len() > 1 && word[..1].eq_ignore_ascii_case("L") && word.parse::<f64>().is_err()
}
