//! Zemax OpticStudio sequential files (`.zmx`), the common subset.
//!
//! One keyword per line. `SURF n` opens surface n; surface 0 is the object (its `DISZ` is the
//! object distance, `INFINITY` allowed) and the last surface is the image, so the lens is
//! surfaces 1..N-1.
//!
//! Read: `MODE SEQ`, `NAME` (title), `UNIT` (MM, CM, IN, METER: converted to mm), `GCAT` (the
//! glass catalogues, in the order they resolve a name several makers use), the aperture (`ENPD`
//! entrance-pupil diameter, `FNUM` image-space F-number, `OBNA` object-space NA, `FLOA` float by
//! stop size), `FTYP` (field type: angle, object height, paraxial or real image height; numbers of
//! fields and wavelengths), `XFLN`/`YFLN` and `FWGN`/`FWGT` (fields and weights),
//! `VDXN`/`VDYN`/`VCXN`/`VCYN` and the older `ZVDX`/`ZVDY`/`ZVCX`/`ZVCY` (vignetting decentre and
//! compression), `WAVM` (number, µm, weight) or `WAVN`/`WAVL` with `WWGT`, `PWAV` (primary),
//! `MNUM` (a multi-configuration file, `MNUM n k` with n > 1, is read as its active
//! configuration k, whose values OpticStudio saves in the surface table: see
//! [`LoadNote::ActiveConfiguration`]); per surface: `TYPE STANDARD`, `TYPE EVENASPH` or
//! `TYPE ODDASPHE`, `CURV`, `CONI`, `PARM 1..8` (even-asphere r^2 .. r^16; odd-asphere
//! r .. r^8), `DISZ` (`SURF 0 DISZ` is the object distance), `GLAS` (a name, or
//! `___BLANK` with nd and Vd: a model glass; `MIRROR`: the surface reflects), `DIAM`, `CLAP 0 r`,
//! `OBSC 0 r` (a central obscuration), `CLAP r R` with r > 0 (an annular aperture: clear
//! aperture R with a central obscuration r), `STOP`. After a mirror OpticStudio writes thicknesses
//! negative while light travels back (-z); the model keeps that convention.
//!
//! The object distance, aperture, fields and wavelengths become the prescription's
//! [`crate::prescription::Conditions`], the defaults of `analyze` and the other commands.
//!
//! Apertures as OpticStudio defines them: `DIAM` is a semi-diameter, the envelope OpticStudio
//! computed for the file's beams, and never clips a ray; `CLAP` (a circular aperture) does. The
//! model has one clear semi-aperture per surface, so `CLAP` gives it where present, else a
//! non-zero `DIAM` (rays of the file's beams pass it, as in OpticStudio; ended where the
//! surface meets its neighbour, should the envelope reach past a lens's edge), else it is
//! derived from paraxial rays of the file's beams (a dummy surface's `DIAM 0`).
//!
//! Keywords that change nothing lensbake models (display, coating, tolerancing, merit function,
//! solver, environment and bookkeeping data: `HARMLESS_TOP`, `HARMLESS_SURFACE`) are skipped and
//! listed in one [`LoadNote::SkippedKeywords`]; so is any unknown keyword of the trailer, the
//! unindented lines after the surface table, where OpticStudio writes merit-function and
//! tolerance operands (`TRAC`, `REAX`, `GLCB`, ...). The trailer opens at an unindented keyword
//! OpticStudio writes at the top level, or at any unindented keyword after a surface whose lines
//! are indented (files written by other programs may indent nothing). An unknown keyword of the header (before `SURF 0`) is skipped too, but
//! named in its own [`LoadNote::UnknownHeaderKeywords`]: OpticStudio adds header settings with
//! its releases (`STUD`, `FSVY`), and every header keyword that defines the lens, its aperture,
//! fields, wavelengths or units is one this reader applies or refuses by name. Coordinate breaks (`TYPE COORDBRK`, with `PPAR` pickups of their
//! parameters) are read as planes in the medium before them that move the later surfaces; the
//! lens they describe is centred by `placement` (fold mirrors unfolded) or refused there, as is
//! one with a rectangular (`SQAP`), elliptical (`ELAP`; with equal semi-axes it is the circle
//! `CLAP` states) or decentred (`OBDC`) clear aperture. A surface's own tilt and decentre
//! (`SCBD 1 order 0 dx dy tx ty tz`, OpticStudio's "tilt/decenter before surface", which moves
//! the surface and every later one as a coordinate break before it would) is read the same
//! way; one after the surface (`SCBD` other than 1) is refused unless it is zero. Any
//! other keyword is refused, naming keyword, line and surface: other surface types (gratings,
//! ...), annular obscurations, rectangular and elliptical
//! obscurations, user-defined apertures, ignored surfaces, a curved image surface,
//! non-sequential mode, and every unknown keyword inside the surface table.

use super::apertures::{self, BeamSpec, INFINITE_OBJECT_MM};
use super::placement::{
    self, ApertureOutline, Asymmetry, OutlineShape, Placement, PlacementKind, StatedOutline,
    StatedToroid,
};
use super::{
    ContradictedGlassData, Format, LoadNote, Loaded, ModelGlass, ModelGlassNote, Source,
    check_surface_count, finite, named_medium, number, odd_shape, positive, scale_to_mm, shape,
};
use crate::limits;
use crate::prescription::DEFAULT_WAVELENGTH_NM;
use crate::prescription::error::{PrescriptionError, Problem};
use crate::prescription::model::{
    ApertureSpec, Conditions, FieldKind, FieldSpec, MAX_ASPHERE_TERMS, Medium, Prescription,
    Provenance, RayAiming, Shape, StatedCondition, StopShape, Surface,
};
use crate::prescription::validate::SourceMap;
use std::collections::{BTreeMap, BTreeSet};

/// Header and trailer keywords that change no surface, beam or medium: file bookkeeping
/// (VERS, NOTE, AUTH, LUID, DBDT, ...), display and analysis settings (PFIL, SDMA, ROPD, PICB,
/// POLS, GLRS, GSTD, ...), environment data (ENVD, GFAC; lensbake's indices are
/// the catalogue's at its reference temperature), non-sequential settings, coatings, and the
/// merit-function and tolerance data (TOL, MOFF, DMFS, EERA, IWDP, EFLY, REAY, TCMM, OEMA, ...).
const HARMLESS_TOP: &[&str] = &[
    "VERS", "NOTE", "PFIL", "LANG", "ENVD", "GFAC", "SDMA", "OMMA", "ROPD", "HYPR", "PICB", "VANN",
    "ZVAN", "POLS", "GLRS", "GSTD", "NSCD", "COFN", "PUSH", "BLNK", "TOL", "DMFS", "MOFF", "AUTH",
    "EERA", "IWDP", "LUID", "SSID", "EFLY", "REAY", "TCMM", "DBDT", "OEMA", "BLNK", "SCOL", "PUCN",
    "CONF", "FLOA2", "XFIE", "WWGN",
];

/// Header keywords this reader applies; seen after the surface table, they open the trailer.
const TOP_APPLIED: &[&str] = &[
    "MODE", "NAME", "UNIT", "GCAT", "ENPD", "FNUM", "OBNA", "FLOA", "OBSA", "EFNO", "FTYP", "XFLN",
    "XFLD", "YFLN", "YFLD", "FWGN", "FWGT", "VDXN", "ZVDX", "VDYN", "ZVDY", "VCXN", "ZVCX", "VCYN",
    "ZVCY", "WAVM", "WAVN", "WAVL", "WWGT", "PWAV", "MNUM", "RAIM",
];

/// The condition a header keyword states, with the keyword.
fn stated_condition(keyword: &str) -> Option<(StatedCondition, &'static str)> {
    Some(match keyword {
        "ENPD" => (StatedCondition::Aperture, "ENPD"),
        "FNUM" => (StatedCondition::Aperture, "FNUM"),
        "OBNA" => (StatedCondition::Aperture, "OBNA"),
        "FLOA" => (StatedCondition::Aperture, "FLOA"),
        "XFLN" | "XFLD" => (StatedCondition::Fields, "XFLN"),
        "YFLN" | "YFLD" => (StatedCondition::Fields, "YFLN"),
        _ => return None,
    })
}

/// The field of lensbake's surface a surface keyword sets, as its checks name it (see
/// [`SourceMap::field_lines`]), with the keyword.
fn validated_field(keyword: &str) -> Option<(&'static str, &'static str)> {
    Some(match keyword {
        "CURV" => ("curvature", "CURV"),
        "DISZ" => ("thickness", "DISZ"),
        "GLAS" => ("medium", "GLAS"),
        "CONI" => ("conic", "CONI"),
        "PARM" => ("coefficients", "PARM"),
        "DIAM" => ("semi_aperture", "DIAM"),
        "CLAP" => ("semi_aperture", "CLAP"),
        "SQAP" => ("semi_aperture", "SQAP"),
        "ELAP" => ("semi_aperture", "ELAP"),
        "OBSC" => ("obscuration", "OBSC"),
        "STOP" => ("stop", "STOP"),
        _ => return None,
    })
}

/// Surface keywords that change no surface lensbake models: display (HIDE, SLAB, MIRR, the
/// substrate drawing of a mirror), coating and physical-optics data (COAT, POPS), comments,
/// solve and variable flags (VCRV, VPAR, VDSZ, VCON, PZUP, and TOLE, a thickness solve for the
/// length to a later surface: the solved values are in CURV, DISZ, ...), and data the surface
/// types lensbake reads do not use (FIMP, MEMA, MAZH, TCE; XDAT, but for a toroid's item 1).
const HARMLESS_SURFACE: &[&str] = &[
    "FIMP", "HIDE", "MIRR", "SLAB", "MEMA", "POPS", "COMM", "FLAP", "COAT", "MAZH", "PZUP", "VCRV",
    "VPAR", "VDSZ", "VCON", "TCE", "OEMA", "BLNK", "TOLE",
];

/// OpticStudio holds at most 24 wavelengths; the bound also keeps a corrupt number from
/// allocating without limit.
const MAX_WAVELENGTHS: usize = 24;
/// OpticStudio holds at most 200 fields (12 before version 18); the bound keeps a corrupt
/// count from allocating the fields without limit.
const MAX_FIELDS: usize = 200;

/// Even-asphere terms a Zemax EVENASPH surface holds (PARM 1..8: r^2 .. r^16).
const PARM_TERMS: usize = 8;

#[derive(Clone, Copy, PartialEq)]
enum SurfaceType {
    Standard,
    EvenAsphere,
    /// PARM 1..8 are the coefficients on r .. r^8.
    OddAsphere,
    /// A coordinate break: PARM 1..6 are decentre x, y, tilts about x, y, z, order flag.
    CoordinateBreak,
    /// An ideal thin lens: PARM 1 is its focal length, PARM 2 how OpticStudio computes its
    /// optical path (which moves no ray).
    Paraxial,
    /// A toroid: CURV, CONI and PARM 2..9 (coefficients on y^2 .. y^16) give the y-z curve, PARM
    /// 1 the radius it turns on about a line parallel to y (0: none, a cylinder); XDAT 1 counts
    /// Zernike terms added to it.
    Toroidal,
}

struct Block {
    line: usize,
    kind: SurfaceType,
    curvature: f64,
    thickness: f64,
    conic: f64,
    parms: [f64; PARM_TERMS],
    /// PARM 9, which only a toroid uses (its y^16 coefficient).
    parm9: f64,
    /// XDAT 1: the Zernike terms a toroid adds to its y-z curve.
    zernike_terms: f64,
    semi_diameter: Option<f64>,
    clear_radius: Option<f64>,
    /// Radius of a central obscuration (`OBSC 0 r`, or the inner radius of `CLAP r R`).
    obscuration: Option<f64>,
    /// `SQAP` or `ELAP`: a rectangular or elliptical clear aperture.
    shaped: Option<OutlineShape>,
    /// `OBDC`: where the surface's apertures are centred.
    aperture_decentre: [f64; 2],
    /// The line and keyword that made the aperture other than a centred circle.
    outline_line: Option<(usize, &'static str)>,
    stop: Option<usize>,
    /// Glass as written: a name (resolved once the file's catalogues are known) or a medium.
    glass: Option<Glass>,
    /// Parameter pickups `PPAR n surface scale offset`: PARM n = scale * (PARM n of that
    /// surface) + offset, with the line.
    pickups: Vec<(usize, usize, f64, f64, usize)>,
    /// The line and keyword of each validated field (see [`validated_field`]), the last one
    /// written for the field.
    field_lines: BTreeMap<&'static str, (usize, &'static str)>,
    /// `SCBD 1 ...`: the surface's own tilt and decentre, before it.
    tilt_before: Option<Placement>,
}

enum Glass {
    /// A glass name, with the nd and Vd the file writes beside it (OpticStudio saves the
    /// catalogue's values there), which stand in for a glass no catalogue here holds.
    Name {
        name: String,
        written: Option<ModelGlass>,
        line: usize,
    },
    Medium(Medium),
}

impl Block {
    /// The clear aperture where it is rectangular or decentred; a decentred `DIAM` (the beam's
    /// extent, which clips nothing) is none.
    fn outline(&self) -> Option<StatedOutline> {
        let (line, keyword) = self.outline_line?;
        let shape = match (self.shaped, self.clear_radius) {
            (Some(shape), _) => shape,
            (None, Some(radius)) => OutlineShape::Circle { radius },
            (None, None) => return None,
        };
        Some(StatedOutline {
            outline: ApertureOutline {
                shape,
                centre: self.aperture_decentre,
            },
            line,
            keyword: keyword.to_string(),
        })
    }

    /// Blocks rays nearer the axis than `radius` (0: none), with any obscuration already read.
    fn obscure(&mut self, radius: f64) {
        if radius > 0.0 {
            self.obscuration = Some(self.obscuration.map_or(radius, |r| r.max(radius)));
        }
    }

    fn new(line: usize) -> Block {
        Block {
            line,
            kind: SurfaceType::Standard,
            curvature: 0.0,
            thickness: 0.0,
            conic: 0.0,
            parms: [0.0; PARM_TERMS],
            parm9: 0.0,
            zernike_terms: 0.0,
            semi_diameter: None,
            clear_radius: None,
            obscuration: None,
            shaped: None,
            aperture_decentre: [0.0; 2],
            outline_line: None,
            stop: None,
            glass: None,
            pickups: Vec::new(),
            field_lines: BTreeMap::new(),
            tilt_before: None,
        }
    }
}

#[derive(Default)]
struct Reader {
    mm_per_unit: f64,
    /// A catalogue glass whose nd and Vd as the file writes them are not the catalogue's (a
    /// writer's placeholder such as `1.5 40` beside every name): the numbers beside an unknown
    /// name are then no glass's either, and no model glass is made from them.
    contradicted_glass_data: Option<ContradictedGlassData>,
    title: Option<String>,
    catalogues: Vec<String>,
    aperture: Option<ApertureSpec>,
    /// Why the aperture cannot be used, when the file gives one lensbake does not model.
    unusable_aperture: Option<String>,
    field_kind: Option<FieldKind>,
    /// Field and wavelength counts from FTYP (OpticStudio writes every slot of its tables).
    field_count: Option<usize>,
    wavelength_count: Option<usize>,
    x_fields: Vec<f64>,
    y_fields: Vec<f64>,
    field_weights: Vec<f64>,
    /// VDX, VDY, VCX, VCY per field.
    vignetting: [Vec<f64>; 4],
    /// Wavelengths in µm by number (1-based in the file), and their weights.
    wavelengths: Vec<f64>,
    /// The line and keyword each wavelength was given on, by number.
    wavelength_lines: Vec<(usize, &'static str)>,
    wavelength_weights: Vec<f64>,
    primary: Option<(usize, usize)>,
    ray_aiming: Option<RayAiming>,
    /// The line and keyword of the aperture and the fields, the last written.
    condition_lines: BTreeMap<StatedCondition, (usize, &'static str)>,
    blocks: Vec<Block>,
    /// Whether an unindented keyword other than SURF followed a surface: the trailer.
    in_trailer: bool,
    /// Whether a keyword line of the current surface was indented, as OpticStudio writes them;
    /// then an unindented keyword no surface has opens the trailer.
    surface_lines_indented: bool,
    unindented_line: bool,
    skipped: BTreeSet<String>,
    /// Header keywords this reader does not know, skipped (see [`LoadNote::UnknownHeaderKeywords`]).
    unknown_header: BTreeSet<String>,
    /// `MNUM n k` with n > 1: the active configuration k of n, whose values the surface table
    /// holds.
    configuration: Option<(usize, usize)>,
}

pub(super) fn read(text: &str, source: &Source) -> Result<Loaded, PrescriptionError> {
    let mut reader = Reader {
        mm_per_unit: 1.0,
        ..Reader::default()
    };
    for (index, raw) in text.lines().enumerate() {
        let line = index + 1;
        let mut words = raw.split_whitespace();
        let Some(keyword) = words.next() else {
            continue;
        };
        let keyword = keyword.to_ascii_uppercase();
        let args: Vec<&str> = words.collect();
        let rest = raw.trim_start()[keyword.len().min(raw.trim_start().len())..].trim();
        let indented = raw.starts_with([' ', '\t']);
        if keyword == "SURF" {
            reader.surface_lines_indented = false;
        } else if !reader.blocks.is_empty()
            && !indented
            && (HARMLESS_TOP.contains(&keyword.as_str()) || TOP_APPLIED.contains(&keyword.as_str()))
        {
            reader.in_trailer = true;
        }
        reader.unindented_line = !indented;
        reader.apply(line, &keyword, &args, rest, source)?;
        reader.surface_lines_indented |= indented && !reader.blocks.is_empty();
    }
    reader.finish(source)
}

impl Reader {
    fn apply(
        &mut self,
        line: usize,
        keyword: &str,
        args: &[&str],
        rest: &str,
        source: &Source,
    ) -> Result<(), PrescriptionError> {
        // SURF n is lens surface n; the object (SURF 0) has no lens surface number.
        let surface = self.blocks.len().checked_sub(1).filter(|&n| n > 0);
        let at = |field: &str| {
            let mut location = source.location(Some(line)).with_field(field);
            location.surface = surface;
            location
        };
        let unsupported =
            |what: String| PrescriptionError::new(at(keyword), Problem::Unsupported(what));
        let arg = |k: usize, expected: &str| -> Result<&str, PrescriptionError> {
            args.get(k).copied().ok_or_else(|| {
                PrescriptionError::new(
                    at(keyword),
                    Problem::WrongColumnCount {
                        expected: format!("{expected} after {keyword}"),
                        found: args.len(),
                    },
                )
            })
        };
        let value = |k: usize| -> Result<f64, PrescriptionError> {
            finite(arg(k, &format!("{} value(s)", k + 1))?, &at(keyword))
        };
        let list = || -> Result<Vec<f64>, PrescriptionError> {
            args.iter().map(|a| finite(a, &at(keyword))).collect()
        };
        let stated_aperture =
            || -> Result<f64, PrescriptionError> { positive(arg(0, "1 value(s)")?, &at(keyword)) };
        let index = |k: usize| -> Result<usize, PrescriptionError> {
            let text = arg(k, &format!("{} value(s)", k + 1))?;
            text.parse::<usize>().map_err(|_| {
                PrescriptionError::new(
                    at(keyword),
                    Problem::NotANumber {
                        text: text.to_string(),
                    },
                )
            })
        };

        if keyword == "SURF" {
            let number = index(0)?;
            if number != self.blocks.len() {
                return Err(PrescriptionError::new(
                    at("SURF"),
                    Problem::Syntax(format!(
                        "expected SURF {}, found SURF {number}",
                        self.blocks.len()
                    )),
                ));
            }
            // The object and image blocks are no lens surfaces.
            check_surface_count(self.blocks.len().saturating_sub(1), at("SURF"))?;
            self.blocks.push(Block::new(line));
            self.in_trailer = false;
            return Ok(());
        }
        let in_trailer = self.in_trailer;
        if let Some(block) = self.blocks.last_mut().filter(|_| !in_trailer) {
            let handled = match keyword {
                "TYPE" => {
                    block.kind = match arg(0, "a surface type")?.to_ascii_uppercase().as_str() {
                        "STANDARD" => SurfaceType::Standard,
                        "EVENASPH" => SurfaceType::EvenAsphere,
                        "ODDASPHE" => SurfaceType::OddAsphere,
                        "COORDBRK" => SurfaceType::CoordinateBreak,
                        "PARAXIAL" => SurfaceType::Paraxial,
                        "TOROIDAL" => SurfaceType::Toroidal,
                        // PARM 1 lines per um, PARM 2 the order: the ray's tangential
                        // direction gains m l / d along the grating vector, which no lensbake
                        // tracer applies yet.
                        "DGRATING" => {
                            return Err(unsupported(
                                "a diffraction grating (TYPE DGRATING: PARM 1 lines per um, \
                                 PARM 2 the order); lensbake traces no grating"
                                    .into(),
                            ));
                        }
                        other => return Err(unsupported(format!("Zemax surface type {other}"))),
                    };
                    true
                }
                "CURV" => {
                    block.curvature = value(0)?;
                    true
                }
                "DISZ" => {
                    let text = arg(0, "1 value")?;
                    block.thickness = if text.eq_ignore_ascii_case("INFINITY") {
                        f64::INFINITY
                    } else {
                        let v = number(text, &at("DISZ"))?;
                        if v.is_nan() {
                            return Err(PrescriptionError::new(
                                at("DISZ"),
                                Problem::NonFinite { value: v },
                            ));
                        }
                        v
                    };
                    true
                }
                "GLAS" => {
                    let name = arg(0, "a glass name")?;
                    block.glass = Some(if name.eq_ignore_ascii_case("MIRROR") {
                        Glass::Medium(Medium::Mirror)
                    } else if name.eq_ignore_ascii_case("___BLANK") {
                        let (nd, vd) = (value(3)?, value(4)?);
                        Glass::Medium(if vd == 0.0 {
                            Medium::Index(nd)
                        } else {
                            Medium::Model { nd, vd }
                        })
                    } else {
                        let written = match (args.get(3), args.get(4)) {
                            (Some(_), Some(_)) => Some(ModelGlass {
                                nd: value(3)?,
                                vd: value(4)?,
                            }),
                            _ => None,
                        };
                        Glass::Name {
                            name: name.to_string(),
                            written,
                            line,
                        }
                    });
                    true
                }
                "CONI" => {
                    block.conic = value(0)?;
                    true
                }
                "PARM" => {
                    let term = index(0)?;
                    let v = value(1)?;
                    if (1..=PARM_TERMS).contains(&term) {
                        block.parms[term - 1] = v;
                    } else if term == PARM_TERMS + 1 {
                        block.parm9 = v;
                    }
                    true
                }
                "PPAR" => {
                    let (term, from) = (index(0)?, index(1)?);
                    if !(1..=PARM_TERMS).contains(&term) {
                        return Err(unsupported(format!("a pickup of parameter {term} (PPAR)")));
                    }
                    // A fifth field names the column picked from (0: the same parameter). From
                    // another column (a thickness, say) the file already holds the value the
                    // pickup gave, as it does for every solve, so it is read as written.
                    let from_column = if args.len() > 4 { value(4)? } else { 0.0 };
                    if from_column == 0.0 {
                        block.pickups.push((term, from, value(2)?, value(3)?, line));
                    }
                    true
                }
                // OpticStudio's aperture decentre; zero changes nothing.
                "OBDC" => {
                    let centre = [value(0)?, value(1)?];
                    if centre == [0.0, 0.0] {
                        self.skipped.insert("OBDC 0 0".into());
                    } else {
                        block.aperture_decentre = centre;
                        block.outline_line.get_or_insert((line, "OBDC"));
                    }
                    true
                }
                // A rectangular or elliptical clear aperture: half widths (semi-axes) in x and
                // y, then flags that are 0 for a plain aperture. An ellipse with equal axes is
                // the circle CLAP states.
                "SQAP" | "ELAP" => {
                    let (half_width, half_height) = (value(0)?, value(1)?);
                    let rectangle = keyword == "SQAP";
                    if !(half_width > 0.0 && half_height > 0.0) {
                        return Err(PrescriptionError::new(
                            at(keyword),
                            Problem::Syntax(format!(
                                "the {} aperture {keyword} {half_width} {half_height} passes no \
                                 ray: both half widths must be positive",
                                if rectangle {
                                    "rectangular"
                                } else {
                                    "elliptical"
                                }
                            )),
                        ));
                    }
                    for k in 2..args.len() {
                        if value(k)? != 0.0 {
                            return Err(unsupported(format!(
                                "{keyword} with a non-zero field {} ({})",
                                k + 1,
                                args[k]
                            )));
                        }
                    }
                    if rectangle {
                        block.shaped = Some(OutlineShape::Rectangle {
                            half_width,
                            half_height,
                        });
                        block.outline_line = Some((line, "SQAP"));
                    } else if half_width == half_height {
                        block.clear_radius = Some(half_width);
                    } else {
                        block.shaped = Some(OutlineShape::Ellipse {
                            half_width,
                            half_height,
                        });
                        block.outline_line = Some((line, "ELAP"));
                    }
                    true
                }
                "DIAM" => {
                    block.semi_diameter = Some(value(0)?);
                    true
                }
                // Surface tilt/decenter data: which side (1: before the surface), the order
                // (0: decentre then tilt, 1: tilt then decentre), a third flag, then decentre x,
                // y and tilts about x, y, z in degrees. The OAP file in the corpus tilts its
                // image plane 90 degrees about x this way, facing the beam its mirror turns.
                "SCBD" => {
                    let (side, order, flag) = (value(0)?, value(1)?, value(2)?);
                    let moves = [value(3)?, value(4)?, value(5)?, value(6)?, value(7)?];
                    if moves == [0.0; 5] {
                        self.skipped.insert("SCBD 0".into());
                    } else if side != 1.0 || flag != 0.0 || !(order == 0.0 || order == 1.0) {
                        return Err(unsupported(format!(
                            "surface tilt/decenter data `SCBD {}` (lensbake reads a tilt and \
                             decentre before the surface: SCBD 1, order 0 or 1, flag 0)",
                            args.join(" ")
                        )));
                    } else if block.kind == SurfaceType::CoordinateBreak {
                        return Err(unsupported(
                            "a coordinate break with its own tilt/decenter data (SCBD)".into(),
                        ));
                    } else {
                        let [dx, dy, tx, ty, tz] = moves;
                        let kind = if order == 0.0 {
                            PlacementKind::Basic
                        } else {
                            PlacementKind::TiltThenDecentre
                        };
                        block.tilt_before = Some(Placement {
                            decentre: [dx, dy, 0.0],
                            tilt_deg: [tx, ty, tz],
                            decentre_at: [Some((line, "SCBD")), Some((line, "SCBD")), None],
                            ..Placement::new(kind, line, "SCBD")
                        });
                    }
                    true
                }
                // Extra data; only item 1 of a toroid (its count of Zernike terms) is read.
                "XDAT" => {
                    if index(0)? == 1 {
                        block.zernike_terms = value(1)?;
                    }
                    self.skipped.insert("XDAT".into());
                    true
                }
                // An annular aperture passes inner <= r <= outer: the clear aperture with a
                // central obscuration.
                "CLAP" => {
                    let (inner, outer) = (value(0)?, value(1)?);
                    if !(0.0..outer).contains(&inner) {
                        return Err(PrescriptionError::new(
                            at("CLAP"),
                            Problem::Syntax(format!(
                                "the aperture CLAP {inner} {outer} passes no ray: its inner \
                                 radius must lie in 0 .. outer"
                            )),
                        ));
                    }
                    block.clear_radius = Some(outer);
                    block.obscure(inner);
                    true
                }
                "STOP" => {
                    block.stop = Some(line);
                    true
                }
                "OBSC" => {
                    let (inner, outer) = (value(0)?, value(1)?);
                    if inner != 0.0 {
                        return Err(unsupported(format!(
                            "an annular obscuration (OBSC {inner} {outer})"
                        )));
                    }
                    block.obscure(outer);
                    true
                }
                "SQOB" | "ELOB" | "UDAP" | "UDAD" => {
                    return Err(unsupported(format!(
                        "Zemax aperture type {keyword} (rectangular, elliptical and \
                         user-defined obscurations and user-defined apertures are not modelled)"
                    )));
                }
                "IGNR" => {
                    return Err(unsupported(
                        "an ignored surface (IGNR): remove it or clear the flag".into(),
                    ));
                }
                k if HARMLESS_SURFACE.contains(&k) => {
                    self.skipped.insert(k.to_string());
                    true
                }
                k if TOP_APPLIED.contains(&k) || HARMLESS_TOP.contains(&k) => false,
                _ if self.unindented_line && self.surface_lines_indented => {
                    self.in_trailer = true;
                    false
                }
                _ => {
                    return Err(unsupported(format!(
                        "Zemax surface keyword `{keyword}` (not one lensbake knows to be harmless)"
                    )));
                }
            };
            if handled {
                if let Some((field, keyword)) = validated_field(keyword) {
                    // A clear aperture (CLAP, or ELAP as a circle) decides the semi-aperture
                    // over the beam's extent (DIAM) in whichever order they come.
                    let beam_extent_after_clear_aperture = keyword == "DIAM"
                        && block
                            .field_lines
                            .get(field)
                            .is_some_and(|(_, k)| *k != "DIAM");
                    if !beam_extent_after_clear_aperture {
                        block.field_lines.insert(field, (line, keyword));
                    }
                }
                return Ok(());
            }
        }
        if let Some(stated) = stated_condition(keyword) {
            self.condition_lines.insert(stated.0, (line, stated.1));
        }
        match keyword {
            "MODE" => {
                let mode = arg(0, "a mode")?;
                if !mode.eq_ignore_ascii_case("SEQ") {
                    return Err(unsupported(format!(
                        "MODE {mode} (only sequential files are read)"
                    )));
                }
            }
            "NAME" => self.title = Some(rest.to_string()).filter(|t| !t.is_empty()),
            "UNIT" => {
                self.mm_per_unit = match arg(0, "a unit")?.to_ascii_uppercase().as_str() {
                    "MM" => 1.0,
                    "CM" => 10.0,
                    "IN" => 25.4,
                    "METER" | "M" => 1000.0,
                    other => return Err(unsupported(format!("UNIT {other}"))),
                }
            }
            "GCAT" => self.catalogues = args.iter().map(|a| a.to_ascii_uppercase()).collect(),
            "ENPD" => self.set_aperture(ApertureSpec::EntrancePupilDiameter(stated_aperture()?)),
            "FNUM" => self.set_aperture(ApertureSpec::FNumber(stated_aperture()?)),
            "OBNA" => self.set_aperture(ApertureSpec::ObjectNumericalAperture(stated_aperture()?)),
            "FLOA" => self.set_aperture(ApertureSpec::FloatByStop),
            // RAIM's second number is the aiming: 0 off and 1 paraxial both aim at the paraxial
            // entrance pupil, 2 aims real rays at the stop.
            "RAIM" => {
                self.ray_aiming = Some(match index(1)? {
                    0 | 1 => RayAiming::Paraxial,
                    2 => RayAiming::Real,
                    other => {
                        return Err(unsupported(format!(
                            "ray aiming {other} (RAIM): lensbake reads 0 (off), 1 (paraxial) \
                             and 2 (real)"
                        )));
                    }
                })
            }
            "OBSA" | "EFNO" => {
                self.aperture = None;
                self.unusable_aperture = Some(format!("the aperture is given as {keyword}"));
            }
            "FTYP" => {
                self.field_kind = Some(match index(0)? {
                    0 => FieldKind::AngleDeg,
                    1 => FieldKind::ObjectHeight,
                    2 => FieldKind::ParaxialImageHeight,
                    3 => FieldKind::RealImageHeight,
                    other => {
                        return Err(unsupported(format!(
                            "field type {other} (FTYP): lensbake reads angles, object heights \
                             and image heights"
                        )));
                    }
                });
                // OpticStudio 14 and later: FTYP type normalisation fields wavelengths ...
                if args.len() >= 4 {
                    let (fields, wavelengths) = (index(2)?, index(3)?);
                    for (count, what, most) in [
                        (fields, "field", MAX_FIELDS),
                        (wavelengths, "wavelength", MAX_WAVELENGTHS),
                    ] {
                        if count > most {
                            return Err(PrescriptionError::new(
                                at("FTYP"),
                                Problem::Syntax(format!(
                                    "{count} {what}s (FTYP): OpticStudio holds at most {most}"
                                )),
                            ));
                        }
                    }
                    self.field_count = Some(fields);
                    self.wavelength_count = Some(wavelengths);
                }
            }
            "XFLN" | "XFLD" => self.x_fields = list()?,
            "YFLN" | "YFLD" => self.y_fields = list()?,
            "FWGN" | "FWGT" => self.field_weights = list()?,
            "VDXN" | "ZVDX" => self.vignetting[0] = list()?,
            "VDYN" | "ZVDY" => self.vignetting[1] = list()?,
            "VCXN" | "ZVCX" => self.vignetting[2] = list()?,
            "VCYN" | "ZVCY" => self.vignetting[3] = list()?,
            "WAVM" => {
                let number = index(0)?;
                let um = value(1)?;
                if !(1..=MAX_WAVELENGTHS).contains(&number) {
                    return Err(PrescriptionError::new(
                        at("WAVM"),
                        Problem::Syntax(format!(
                            "wavelength number {number} is outside 1..={MAX_WAVELENGTHS}"
                        )),
                    ));
                }
                // Older files also carry WAVL/WAVN and WWGT lists, which may be shorter or
                // longer than the WAVM table: size both to hold this entry.
                let len = number
                    .max(self.wavelengths.len())
                    .max(self.wavelength_weights.len());
                self.wavelengths.resize(len, f64::NAN);
                self.wavelength_lines.resize(len, (line, "WAVM"));
                self.wavelength_weights.resize(len, 1.0);
                self.wavelengths[number - 1] = um;
                self.wavelength_lines[number - 1] = (line, "WAVM");
                if args.len() > 2 {
                    self.wavelength_weights[number - 1] = value(2)?;
                }
            }
            "WAVN" | "WAVL" => {
                self.wavelengths = list()?;
                let keyword = if keyword == "WAVN" { "WAVN" } else { "WAVL" };
                self.wavelength_lines = vec![(line, keyword); self.wavelengths.len()];
                self.wavelength_weights.resize(self.wavelengths.len(), 1.0);
            }
            "WWGT" => self.wavelength_weights = list()?,
            "PWAV" => self.primary = Some((index(0)?, line)),
            "MNUM" => {
                let count = index(0)?;
                let active = if args.len() > 1 { index(1)? } else { 1 };
                if count > 1 {
                    if !(1..=count).contains(&active) {
                        return Err(PrescriptionError::new(
                            at(keyword),
                            Problem::Syntax(format!(
                                "the active configuration {active} is not one of the file's \
                                 {count}"
                            )),
                        ));
                    }
                    self.configuration = Some((active, count));
                }
            }
            k if HARMLESS_TOP.contains(&k) || self.in_trailer => {
                self.skipped.insert(k.to_string());
            }
            k if self.blocks.is_empty() => {
                self.unknown_header.insert(k.to_string());
            }
            other => return Err(unsupported(format!("Zemax keyword `{other}`"))),
        }
        Ok(())
    }

    /// Evaluates parameter pickups in file order, so one may read what an earlier one wrote.
    fn apply_pickups(&mut self, source: &Source) -> Result<(), PrescriptionError> {
        for target in 0..self.blocks.len() {
            for (term, from, scale, offset, line) in
                std::mem::take(&mut self.blocks[target].pickups)
            {
                let Some(picked) = self.blocks.get(from).map(|b| b.parms[term - 1]) else {
                    return Err(PrescriptionError::new(
                        source.location(Some(line)).with_field("PPAR"),
                        Problem::Syntax(format!(
                            "the pickup names surface {from}; the file has surfaces 0..{}",
                            self.blocks.len() - 1
                        )),
                    ));
                };
                self.blocks[target].parms[term - 1] = scale * picked + offset;
            }
        }
        Ok(())
    }

    fn set_aperture(&mut self, aperture: ApertureSpec) {
        self.aperture = Some(aperture);
        self.unusable_aperture = None;
    }

    fn finish(mut self, source: &Source) -> Result<Loaded, PrescriptionError> {
        if self.blocks.len() < 3 {
            return Err(source.error(None, Problem::Empty));
        }
        self.contradicted_glass_data = self.first_contradicted_glass();
        self.apply_pickups(source)?;
        let (object, rest) = self.blocks.split_first().expect("at least three blocks");
        let (image, lens) = rest
            .split_last()
            .expect("at least two blocks after the object");
        for (block, name) in [(object, "object"), (image, "image")] {
            if let Some(line) = block.stop {
                return Err(PrescriptionError::new(
                    source.location(Some(line)).with_field("STOP"),
                    Problem::Syntax(format!(
                        "the stop is on the {name} surface; it must be a lens surface"
                    )),
                ));
            }
        }
        if let Some(tilt) = &object.tilt_before {
            return Err(PrescriptionError::new(
                source.location(Some(tilt.line)).with_field("SCBD"),
                Problem::Unsupported("a tilted or decentred object surface (SCBD)".into()),
            ));
        }
        if image.curvature != 0.0 {
            return Err(PrescriptionError::new(
                source.location(Some(image.line)).with_field("CURV"),
                Problem::Unsupported("a curved image surface".into()),
            ));
        }
        // Wavelength numbers are 1-based; PWAV 0 wraps to an index no list has.
        let design = self
            .primary
            .map_or(0, |(primary, _)| primary.wrapping_sub(1));
        let wavelength_nm = match self.primary {
            Some((primary, line)) => match self.wavelengths.get(design) {
                Some(um) if um.is_finite() => Some(um * 1000.0),
                _ => {
                    return Err(PrescriptionError::new(
                        source.location(Some(line)).with_field("PWAV"),
                        Problem::Syntax(format!("PWAV {primary} names no wavelength")),
                    ));
                }
            },
            None => self
                .wavelengths
                .first()
                .filter(|um| um.is_finite())
                .map(|um| um * 1000.0),
        };
        // Checked here, where the line each was written on is known (later checks see the
        // numbers without their lines): the design wavelength and every one in use.
        let used = self.wavelength_count.unwrap_or(self.wavelengths.len());
        for (k, (um, &(line, keyword))) in self
            .wavelengths
            .iter()
            .zip(&self.wavelength_lines)
            .enumerate()
        {
            if (k < used || k == design) && um.is_finite() {
                limits::check_wavelength(um * 1000.0).map_err(|e| {
                    PrescriptionError::new(
                        source.location(Some(line)).with_field(keyword),
                        e.into(),
                    )
                })?;
            }
        }
        if image.kind == SurfaceType::CoordinateBreak {
            return Err(PrescriptionError::new(
                source.location(Some(image.line)).with_field("TYPE"),
                Problem::Unsupported("a coordinate break as the image surface".into()),
            ));
        }
        if let Some(b) = lens.iter().find(|b| {
            b.kind == SurfaceType::Paraxial
                && (b.curvature != 0.0 || b.conic != 0.0 || b.parms[2..].iter().any(|&p| p != 0.0))
        }) {
            return Err(PrescriptionError::new(
                source.location(Some(b.line)).with_field("TYPE PARAXIAL"),
                Problem::Unsupported(
                    "a paraxial surface with a curvature, conic or parameter beyond PARM 1 \
                     (focal length) and PARM 2 (OPD mode)"
                        .into(),
                ),
            ));
        }
        // A coordinate break bends no ray: light stays in the medium it was in (the one before
        // the last mirror when it follows one).
        let mut medium_before = self.medium(object);
        let surfaces: Vec<Surface> = lens
            .iter()
            .map(|b| {
                let mut terms = [0.0; MAX_ASPHERE_TERMS];
                match b.kind {
                    SurfaceType::EvenAsphere | SurfaceType::OddAsphere => {
                        terms[..PARM_TERMS].copy_from_slice(&b.parms)
                    }
                    // The y-z curve's terms (the 3-D trace reads the shape in y).
                    SurfaceType::Toroidal => {
                        terms[..PARM_TERMS - 1].copy_from_slice(&b.parms[1..]);
                        terms[PARM_TERMS - 1] = b.parm9;
                    }
                    _ => {}
                }
                let (profile, medium) = match b.kind {
                    SurfaceType::CoordinateBreak => (Shape::Plane, medium_before.clone()),
                    SurfaceType::Paraxial => (
                        Shape::IdealLens {
                            focal_length: b.parms[0],
                        },
                        self.medium(b),
                    ),
                    SurfaceType::OddAsphere => {
                        (odd_shape(b.curvature, b.conic, &terms), self.medium(b))
                    }
                    _ => (shape(b.curvature, b.conic, &terms), self.medium(b)),
                };
                if medium != Medium::Mirror {
                    medium_before = medium.clone();
                }
                Surface {
                    shape: profile,
                    thickness: b.thickness,
                    medium,
                    semi_aperture: b.clear_radius.or(b.semi_diameter).unwrap_or(0.0),
                    stop: b.stop.map(|_| StopShape::Circle),
                    obscuration: b.obscuration,
                }
            })
            .collect();
        let placements: Vec<Option<Placement>> = lens
            .iter()
            .map(|b| {
                if b.tilt_before.is_some() {
                    return b.tilt_before.clone();
                }
                (b.kind == SurfaceType::CoordinateBreak).then(|| {
                    let [dx, dy, tx, ty, tz, order, ..] = b.parms;
                    let kind = if order == 0.0 {
                        PlacementKind::Basic
                    } else {
                        PlacementKind::TiltThenDecentre
                    };
                    Placement {
                        decentre: [dx, dy, 0.0],
                        tilt_deg: [tx, ty, tz],
                        decentre_at: [Some((b.line, "PARM 1")), Some((b.line, "PARM 2")), None],
                        ..Placement::new(kind, b.line, "TYPE COORDBRK")
                    }
                })
            })
            .collect();
        // A DIAM of 0 (a dummy surface OpticStudio never sized) is no aperture at all; any other
        // DIAM is the envelope of the file's beams, which clips no ray in OpticStudio.
        let (mut missing, envelopes): (Vec<usize>, Vec<usize>) = (0..lens.len())
            .filter(|&i| lens[i].clear_radius.is_none())
            .partition(|&i| lens[i].semi_diameter.is_none_or(|d| d <= 0.0));
        let mm = self.mm_per_unit;
        let conditions = self.conditions(object, wavelength_nm);

        let mut prescription = Prescription {
            provenance: Provenance {
                title: self.title.clone().unwrap_or_else(|| source.default_title()),
                source: source.file_name(),
                design_wavelength_nm: wavelength_nm,
                conditions: Some(conditions.clone()),
                ..Provenance::default()
            },
            object_medium: self.medium(object),
            surfaces,
        };
        scale_to_mm(&mut prescription, mm);
        if let Some(b) = lens
            .iter()
            .find(|b| b.kind == SurfaceType::Toroidal && b.zernike_terms != 0.0)
        {
            return Err(PrescriptionError::new(
                source.location(Some(b.line)).with_field("XDAT"),
                Problem::Unsupported(format!(
                    "a toroid with {} Zernike terms (XDAT 1)",
                    b.zernike_terms
                )),
            ));
        }
        let asymmetries: Vec<Asymmetry> = lens
            .iter()
            .map(|b| Asymmetry {
                outline: b.outline(),
                toroid: (b.kind == SurfaceType::Toroidal).then(|| StatedToroid {
                    // PARM 1 = 0 is OpticStudio's infinite radius: a cylinder.
                    rotation_radius: if b.parms[0] == 0.0 {
                        f64::INFINITY
                    } else {
                        b.parms[0]
                    },
                    line: b.line,
                }),
            })
            .collect();
        let centred = placement::centre_if_placed(
            &mut prescription,
            &placements,
            image.tilt_before.as_ref(),
            &asymmetries,
            &mut missing,
            &envelopes,
            mm,
            &lens.iter().map(|b| b.line).collect::<Vec<_>>(),
            image.line,
            source,
        )?;
        if !missing.is_empty() {
            prescription.provenance.notes = Some(
                "clear apertures not in the file were derived by lensbake from paraxial rays"
                    .to_string(),
            );
        }
        let map = SourceMap {
            file: source.file.map(|f| f.to_path_buf()),
            surface_lines: lens.iter().map(|b| Some(b.line)).collect(),
            field_lines: lens
                .iter()
                .enumerate()
                .flat_map(|(i, b)| {
                    b.field_lines
                        .iter()
                        .map(move |(&field, &at)| ((i, field), at))
                })
                .collect(),
            condition_lines: self
                .condition_lines
                .iter()
                .map(|(&c, &at)| (c, at))
                .chain(
                    object
                        .field_lines
                        .get("thickness")
                        .map(|&at| (StatedCondition::Object, at)),
                )
                .collect(),
        };
        let pupils: Vec<_> = (0..conditions.fields.as_ref().map_or(0, |f| f.x.len()))
            .map(|k| {
                let get = |list: &[f64]| list.get(k).copied().unwrap_or(0.0);
                let [vdx, vdy, vcx, vcy] = [0, 1, 2, 3].map(|v| get(&self.vignetting[v]));
                // Zemax maps a pupil coordinate p to vd + p (1 - vc).
                (
                    (vdx - (1.0 - vcx), vdx + (1.0 - vcx)),
                    (vdy - (1.0 - vcy), vdy + (1.0 - vcy)),
                )
            })
            .collect();
        let trimmed = apertures::trimmed_fields(&pupils);
        let beams = BeamSpec::from_conditions(
            &conditions,
            &pupils,
            self.unusable_aperture.clone().unwrap_or_else(|| {
                "the file has neither DIAM nor an aperture (ENPD, FNUM, OBNA, FLOA)".into()
            }),
            wavelength_nm.unwrap_or(DEFAULT_WAVELENGTH_NM),
        );
        let mut loaded = apertures::complete(
            prescription,
            &missing,
            &envelopes,
            &beams,
            map,
            Format::Zemax,
        )?;
        loaded.notes.extend(centred);
        let model_glasses = self.model_glasses(lens.len());
        if !model_glasses.is_empty() {
            loaded.notes.push(LoadNote::ModelGlasses {
                glasses: model_glasses,
            });
        }
        if let Some(contradicted) = self.contradicted_glass_data.clone()
            && self.names_an_unknown_glass()
        {
            loaded
                .notes
                .push(LoadNote::WrittenGlassDataContradicted(contradicted));
        }
        if !trimmed.is_empty() {
            loaded
                .notes
                .push(LoadNote::VignettingNotApplied { fields: trimmed });
        }
        if let Some((active, count)) = self.configuration {
            loaded
                .notes
                .push(LoadNote::ActiveConfiguration { active, count });
        }
        if !self.skipped.is_empty() {
            loaded.notes.push(LoadNote::SkippedKeywords {
                keywords: self.skipped.into_iter().collect(),
            });
        }
        if !self.unknown_header.is_empty() {
            loaded.notes.push(LoadNote::UnknownHeaderKeywords {
                keywords: self.unknown_header.into_iter().collect(),
            });
        }
        Ok(loaded)
    }

    /// A block's medium, glass names resolved in the file's catalogue order (GCAT).
    fn medium(&self, block: &Block) -> Medium {
        match &block.glass {
            None => Medium::Air,
            Some(Glass::Medium(medium)) => medium.clone(),
            Some(Glass::Name { name, written, .. }) => {
                named_medium(name, &self.catalogues, self.trusted(*written)).0
            }
        }
    }

    /// The nd and Vd written beside a glass name, unless the file's numbers beside the glasses
    /// the catalogues hold show they are not the glasses' own.
    fn trusted(&self, written: Option<ModelGlass>) -> Option<ModelGlass> {
        written.filter(|_| self.contradicted_glass_data.is_none())
    }

    /// The first catalogue glass whose written nd or Vd is not the catalogue's: nd off by more
    /// than 0.005 or Vd by more than 1, far beyond the changes between catalogue editions
    /// (1e-4 in nd, 0.1 in Vd) and far below the gap to a writer's placeholder.
    fn first_contradicted_glass(&self) -> Option<ContradictedGlassData> {
        self.blocks.iter().find_map(|block| {
            let Some(Glass::Name {
                name,
                written: Some(written),
                line,
            }) = &block.glass
            else {
                return None;
            };
            let glass = crate::glass::lookup_in(name, &self.catalogues).ok()?;
            let contradicted =
                !((written.nd - glass.nd).abs() <= 0.005 && (written.vd - glass.vd).abs() <= 1.0);
            contradicted.then(|| ContradictedGlassData {
                line: *line,
                name: name.clone(),
                written: *written,
                catalogue: ModelGlass {
                    nd: glass.nd,
                    vd: glass.vd,
                },
            })
        })
    }

    /// Whether a glass name the file writes numbers beside is in no catalogue here.
    fn names_an_unknown_glass(&self) -> bool {
        self.blocks.iter().any(|block| {
            matches!(&block.glass, Some(Glass::Name { name, written: Some(_), .. })
                if matches!(named_medium(name, &self.catalogues, None).0, Medium::Glass(ref known)
                    if crate::glass::lookup(known).is_err()))
        })
    }

    /// The glasses read as model glasses from the nd and Vd written beside their names, each
    /// with its surface (0: the object space).
    fn model_glasses(&self, lens_surfaces: usize) -> Vec<ModelGlassNote> {
        self.blocks
            .iter()
            .take(lens_surfaces + 1)
            .enumerate()
            .filter_map(|(surface, block)| match &block.glass {
                Some(Glass::Name { name, written, .. }) => {
                    let (_, model) = named_medium(name, &self.catalogues, self.trusted(*written));
                    model.map(|glass| ModelGlassNote {
                        surface,
                        name: name.clone(),
                        glass,
                    })
                }
                _ => None,
            })
            .collect()
    }

    /// Object distance, aperture, fields and wavelengths as the file states them, in mm and nm.
    fn conditions(&self, object: &Block, primary_nm: Option<f64>) -> Conditions {
        let mm = self.mm_per_unit;
        let used = |list: &[f64], count: Option<usize>| -> Vec<f64> {
            list.iter()
                .take(count.unwrap_or(usize::MAX))
                .copied()
                .collect()
        };
        let kind = self.field_kind.unwrap_or(FieldKind::AngleDeg);
        let unit = if kind == FieldKind::AngleDeg { 1.0 } else { mm };
        let count = self
            .field_count
            .unwrap_or(self.x_fields.len().max(self.y_fields.len()));
        let component = |list: &[f64]| -> Vec<f64> {
            (0..count)
                .map(|k| list.get(k).copied().unwrap_or(0.0) * unit)
                .collect()
        };
        let wavelengths: Vec<f64> = used(&self.wavelengths, self.wavelength_count)
            .iter()
            .map(|um| um * 1000.0)
            .collect();
        let weights = used(&self.wavelength_weights, Some(wavelengths.len()));
        Conditions {
            object_distance_mm: Some(object.thickness * mm)
                .filter(|d| d.abs() < INFINITE_OBJECT_MM),
            aperture: self.aperture.clone().map(|a| match a {
                ApertureSpec::EntrancePupilDiameter(d) => {
                    ApertureSpec::EntrancePupilDiameter(d * mm)
                }
                other => other,
            }),
            fields: (count > 0).then(|| FieldSpec {
                kind,
                x: component(&self.x_fields),
                y: component(&self.y_fields),
                weights: super::field_weights(&self.field_weights, count),
            }),
            primary: primary_nm.and_then(|nm| wavelengths.iter().position(|w| *w == nm)),
            wavelength_weights: if weights.len() == wavelengths.len() {
                weights
            } else {
                vec![1.0; wavelengths.len()]
            },
            wavelengths_nm: wavelengths,
            ray_aiming: self.ray_aiming,
        }
    }
}
