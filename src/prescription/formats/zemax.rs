//! Zemax OpticStudio sequential files (`.zmx`), the common subset.
//!
//! One keyword per line. `SURF n` opens surface n; surface 0 is the object (its `DISZ` is the
//! object distance, `INFINITY` allowed) and the last surface is the image, so the lens is
//! surfaces 1..N-1.
//!
//! Read: `MODE SEQ`, `NAME` (title), `UNIT` (MM, CM, IN, METER: converted to mm), `ENPD`, `FNUM`,
//! `FLOA` (aperture), `FTYP` (field type; angles only), `XFLN`/`YFLN` (fields),
//! `VDXN`/`VDYN`/`VCXN`/`VCYN` and the older `ZVDX`/`ZVDY`/`ZVCX`/`ZVCY` (vignetting decentre and
//! compression), `WAVM`/`WAVN`/`WAVL` (µm) with `PWAV` (design wavelength), `MNUM 1`; per surface:
//! `TYPE STANDARD` or `TYPE EVENASPH`, `CURV`, `CONI`, `PARM 1..8` (even-asphere r^2 .. r^16),
//! `DISZ`, `GLAS` (a name, or `___BLANK` with nd and Vd: a model glass), `DIAM` (semi-diameter),
//! `CLAP 0 r` (circular aperture, preferred over `DIAM`), `STOP`.
//!
//! Ignored as harmless (display, coating, tolerancing, solver and environment data): see
//! `HARMLESS_TOP` and `HARMLESS_SURFACE` below.
//!
//! Refused with a message naming the keyword and line: other surface types (coordinate breaks,
//! toroids, paraxial, ...), mirrors, multi-configuration files, annular, obscuring or
//! non-circular apertures, a curved image surface, non-sequential mode, and every keyword not
//! listed here.

use super::apertures::{self, BeamSpec, FieldPoint, INFINITE_OBJECT_MM, PupilSize};
use super::{Format, Loaded, Source, finite, named_medium, number, scale_to_mm, shape};
use crate::prescription::DEFAULT_WAVELENGTH_NM;
use crate::prescription::error::{PrescriptionError, Problem};
use crate::prescription::model::{
    MAX_ASPHERE_TERMS, Medium, Prescription, Provenance, StopShape, Surface,
};
use crate::prescription::validate::SourceMap;

const HARMLESS_TOP: &[&str] = &[
    "VERS", "NOTE", "PFIL", "LANG", "ENVD", "GFAC", "GCAT", "SDMA", "OMMA", "ROPD", "HYPR", "PICB",
    "FWGN", "FWGT", "WWGN", "WWGT", "VANN", "ZVAN", "POLS", "GLRS", "GSTD", "NSCD", "COFN", "RAIM",
    "PUSH", "BLNK", "TOL", "DMFS", "MOFF",
];

const HARMLESS_SURFACE: &[&str] = &[
    "FIMP", "HIDE", "MIRR", "SLAB", "MEMA", "POPS", "COMM", "FLAP", "COAT", "MAZH", "PZUP", "VCRV",
    "VPAR", "VDSZ", "VCON", "XDAT",
];

/// OpticStudio holds at most 24 wavelengths; the bound also keeps a corrupt number from
/// allocating without limit.
const MAX_WAVELENGTHS: usize = 24;

/// Even-asphere terms a Zemax EVENASPH surface holds (PARM 1..8: r^2 .. r^16).
const PARM_TERMS: usize = 8;

#[derive(Clone, Copy, PartialEq)]
enum SurfaceType {
    Standard,
    EvenAsphere,
}

struct Block {
    line: usize,
    kind: SurfaceType,
    curvature: f64,
    thickness: f64,
    medium: Option<Medium>,
    conic: f64,
    parms: [f64; PARM_TERMS],
    semi_diameter: Option<f64>,
    clear_radius: Option<f64>,
    stop: Option<usize>,
}

impl Block {
    fn new(line: usize) -> Block {
        Block {
            line,
            kind: SurfaceType::Standard,
            curvature: 0.0,
            thickness: 0.0,
            medium: None,
            conic: 0.0,
            parms: [0.0; PARM_TERMS],
            semi_diameter: None,
            clear_radius: None,
            stop: None,
        }
    }
}

#[derive(Default)]
struct Reader {
    mm_per_unit: f64,
    title: Option<String>,
    pupil: Option<PupilSize>,
    unusable_fields: Option<String>,
    x_fields: Vec<f64>,
    y_fields: Vec<f64>,
    /// VDX, VDY, VCX, VCY per field.
    vignetting: [Vec<f64>; 4],
    /// Wavelengths in µm by number (1-based in the file).
    wavelengths: Vec<f64>,
    primary: Option<(usize, usize)>,
    blocks: Vec<Block>,
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
        reader.apply(line, &keyword, &args, rest, source)?;
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
            self.blocks.push(Block::new(line));
            return Ok(());
        }
        if let Some(block) = self.blocks.last_mut() {
            let handled = match keyword {
                "TYPE" => {
                    block.kind = match arg(0, "a surface type")?.to_ascii_uppercase().as_str() {
                        "STANDARD" => SurfaceType::Standard,
                        "EVENASPH" => SurfaceType::EvenAsphere,
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
                    block.medium = Some(if name.eq_ignore_ascii_case("MIRROR") {
                        return Err(unsupported(
                            "mirrors (GLAS MIRROR): lensbake models refracting lenses only".into(),
                        ));
                    } else if name.eq_ignore_ascii_case("___BLANK") {
                        let (nd, vd) = (value(3)?, value(4)?);
                        if vd == 0.0 {
                            Medium::Index(nd)
                        } else {
                            Medium::Model { nd, vd }
                        }
                    } else {
                        named_medium(name)
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
                    }
                    true
                }
                "DIAM" => {
                    block.semi_diameter = Some(value(0)?);
                    true
                }
                "CLAP" => {
                    let (inner, outer) = (value(0)?, value(1)?);
                    if inner != 0.0 {
                        return Err(unsupported(format!(
                            "an annular aperture (CLAP {inner} {outer})"
                        )));
                    }
                    block.clear_radius = Some(outer);
                    true
                }
                "STOP" => {
                    block.stop = Some(line);
                    true
                }
                "OBSC" | "SQAP" | "ELAP" | "SQOB" | "ELOB" | "UDAP" | "UDAD" => {
                    return Err(unsupported(format!("Zemax aperture type {keyword}")));
                }
                k => HARMLESS_SURFACE.contains(&k),
            };
            if handled {
                return Ok(());
            }
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
            "ENPD" => self.pupil = Some(PupilSize::Diameter(value(0)?)),
            "FNUM" => self.pupil = Some(PupilSize::FNumber(value(0)?)),
            "FLOA" => self.pupil = Some(PupilSize::FloatByStop),
            "OBNA" | "OBSA" | "EFNO" => {
                self.pupil = Some(PupilSize::Unusable(format!(
                    "the aperture is given as {keyword}"
                )))
            }
            "FTYP" => {
                let kind = index(0)?;
                self.unusable_fields = (kind != 0)
                    .then(|| format!("the fields are of type {kind} (FTYP), not angles"));
            }
            "XFLN" => self.x_fields = list()?,
            "YFLN" => self.y_fields = list()?,
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
                if self.wavelengths.len() < number {
                    self.wavelengths.resize(number, f64::NAN);
                }
                self.wavelengths[number - 1] = um;
            }
            "WAVN" | "WAVL" => self.wavelengths = list()?,
            "PWAV" => self.primary = Some((index(0)?, line)),
            "MNUM" => {
                let configurations = index(0)?;
                if configurations > 1 {
                    return Err(unsupported(format!(
                        "multi-configuration files (MNUM {configurations})"
                    )));
                }
            }
            k if HARMLESS_TOP.contains(&k) => {}
            other => return Err(unsupported(format!("Zemax keyword `{other}`"))),
        }
        Ok(())
    }

    fn finish(self, source: &Source) -> Result<Loaded, PrescriptionError> {
        if self.blocks.len() < 3 {
            return Err(source.error(None, Problem::Empty));
        }
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
        if image.curvature != 0.0 {
            return Err(PrescriptionError::new(
                source.location(Some(image.line)).with_field("CURV"),
                Problem::Unsupported("a curved image surface".into()),
            ));
        }
        let wavelength_nm = match self.primary {
            Some((primary, line)) => match self.wavelengths.get(primary.wrapping_sub(1)) {
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
        let surfaces: Vec<Surface> = lens
            .iter()
            .map(|b| {
                let mut terms = [0.0; MAX_ASPHERE_TERMS];
                if b.kind == SurfaceType::EvenAsphere {
                    terms[..PARM_TERMS].copy_from_slice(&b.parms);
                }
                Surface {
                    shape: shape(b.curvature, b.conic, &terms),
                    thickness: b.thickness,
                    medium: b.medium.clone().unwrap_or(Medium::Air),
                    semi_aperture: b.clear_radius.or(b.semi_diameter).unwrap_or(0.0),
                    stop: b.stop.map(|_| StopShape::Circle),
                }
            })
            .collect();
        let missing: Vec<usize> = (0..lens.len())
            .filter(|&i| lens[i].clear_radius.is_none() && lens[i].semi_diameter.is_none())
            .collect();
        let mm = self.mm_per_unit;
        let object_distance = Some(object.thickness * mm).filter(|d| d.abs() < INFINITE_OBJECT_MM);

        let mut prescription = Prescription {
            provenance: Provenance {
                title: self.title.clone().unwrap_or_else(|| source.default_title()),
                source: source.file_name(),
                design_wavelength_nm: wavelength_nm,
                notes: (!missing.is_empty())
                    .then(|| "clear apertures not in the file were derived by lensbake from paraxial rays".to_string()),
                ..Provenance::default()
            },
            object_medium: object.medium.clone().unwrap_or(Medium::Air),
            surfaces,
        };
        scale_to_mm(&mut prescription, mm);
        let map = SourceMap {
            file: source.file.map(|f| f.to_path_buf()),
            surface_lines: lens.iter().map(|b| Some(b.line)).collect(),
        };
        let beams = BeamSpec {
            pupil: match &self.pupil {
                Some(PupilSize::Diameter(d)) => PupilSize::Diameter(d * mm),
                Some(other) => other.clone(),
                None => PupilSize::Unusable(
                    "the file has neither DIAM nor an aperture (ENPD, FNUM, FLOA)".into(),
                ),
            },
            object_distance,
            fields: self.field_points(),
            wavelength_nm: wavelength_nm.unwrap_or(DEFAULT_WAVELENGTH_NM),
        };
        apertures::complete(prescription, &missing, &beams, map, Format::Zemax)
    }

    fn field_points(&self) -> Result<Vec<FieldPoint>, String> {
        if let Some(reason) = &self.unusable_fields {
            return Err(reason.clone());
        }
        let count = self.x_fields.len().max(self.y_fields.len());
        let get = |list: &[f64], k: usize| list.get(k).copied().unwrap_or(0.0);
        Ok((0..count)
            .map(|k| {
                let (tx, ty) = (
                    get(&self.x_fields, k).to_radians().tan(),
                    get(&self.y_fields, k).to_radians().tan(),
                );
                let [vdx, vdy, vcx, vcy] = [0, 1, 2, 3].map(|v| get(&self.vignetting[v], k));
                // Zemax maps a pupil coordinate p to vd + p (1 - vc).
                FieldPoint {
                    angle_deg: tx.hypot(ty).atan().to_degrees(),
                    pupil_y: (vdy - (1.0 - vcy), vdy + (1.0 - vcy)),
                    pupil_x: (vdx - (1.0 - vcx), vdx + (1.0 - vcx)),
                }
            })
            .collect())
    }
}
