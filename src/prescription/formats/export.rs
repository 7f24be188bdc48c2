//! Writers for other programs' lens formats: Zemax `.zmx` and pbrt `.dat`.
//!
//! Each writes the surfaces lensbake holds so that its own reader (and the program's) gives them
//! back: every number in Rust's shortest exact form, so a file read back by lensbake has the
//! same f64s. What a format cannot hold is refused, never approximated: the error names the
//! surface and what is missing.
//!
//! Zemax: `MODE SEQ`, `UNIT MM`, `GCAT` (the catalogues of the glasses used), the aperture
//! (`ENPD`, `FNUM`, `OBNA`, `FLOA`; `FLOA`, wide open, where the lens states none), fields
//! (`FTYP`, `XFLN`, `YFLN`, `FWGN`; the axis where none are stated), wavelengths (`WAVM`,
//! `PWAV`; the design wavelength where none are stated), the object surface (`DISZ` its
//! distance), then per surface `TYPE STANDARD`, `EVENASPH` or `ODDASPHE`, `CURV`, `CONI`,
//! `PARM 1..8`, `DISZ`, `GLAS` (a catalogue name, or `___BLANK` with nd and Vd for a model glass
//! or a constant index), `DIAM` and `CLAP 0 r` (the clear semi-aperture: CLAP is the Zemax
//! aperture that clips, as lensbake's does), `OBSC 0 r` (a central obscuration), `GLAS MIRROR`
//! (a mirror; thicknesses keep their signs), `STOP`. Refused: even-asphere terms beyond r^16 and
//! odd-asphere terms beyond r^8 (both types have PARM 1..8), a medium given by coefficients or a
//! table (a Zemax file names catalogue glasses), a non-air object space, two glasses of one name
//! from different catalogues. A working F-number (CODE V `FNO` of a finite object) has no Zemax
//! keyword and is left out, with the rest of the conditions kept
//! (`analysis::stated_as_analysed` restates it as the pupil diameter it gives).
//!
//! pbrt (`RealisticCamera`, pbrt-v3): one row per surface from the object side, `radius
//! thickness ior aperture-diameter` in mm, thickness to the next surface, the stop a row of
//! radius 0 and ior 0. pbrt holds spheres and one constant index per medium: the index is
//! written at the lens's design wavelength. Refused: conics and aspheres, a plane refracting
//! surface (pbrt reads radius 0 as the stop), a curved stop or one between different media, a
//! non-air object space, mirrors and central obscurations.

use crate::glass::{Dispersion, lookup};
use crate::prescription::DEFAULT_WAVELENGTH_NM;
use crate::prescription::error::Problem;
use crate::prescription::model::{
    ApertureSpec, FieldKind, FieldSpec, Medium, Prescription, RayAiming, Shape, Surface,
};

/// Terms the Zemax even asphere holds: PARM 1..8 multiply r^2 .. r^16.
const ZEMAX_ASPHERE_TERMS: usize = 8;

/// A number as Rust's shortest exact text: lensbake and the programs read back the same f64.
fn num(value: f64) -> String {
    if value != 0.0 && (value.abs() < 1e-4 || value.abs() >= 1e12) {
        format!("{value:e}")
    } else {
        format!("{value}")
    }
}

fn refuse<T>(what: String) -> Result<T, Problem> {
    Err(Problem::Unsupported(what))
}

/// pbrt's RealisticCamera has neither mirrors nor obscurations: refused rather than dropped.
fn not_reflecting_or_obscured(s: &Surface, surface: usize) -> Result<(), Problem> {
    if s.medium == Medium::Mirror || s.obscuration.is_some() {
        return refuse(format!(
            "surface {surface}: a mirror or a central obscuration; pbrt's RealisticCamera \
             refracts through open spheres only"
        ));
    }
    Ok(())
}

fn object_in_air(p: &Prescription, format: &str) -> Result<(), Problem> {
    if p.object_medium != Medium::Air {
        return refuse(format!("a {format} file has air in object space"));
    }
    Ok(())
}

/// The Zemax `.zmx` text of `p` (see the module docs for what it holds).
pub fn write_zemax(p: &Prescription) -> Result<String, Problem> {
    object_in_air(p, "Zemax")?;
    let mut glass_lines = Vec::new();
    let mut catalogues: Vec<&str> = Vec::new();
    let mut names: Vec<(&str, &str)> = Vec::new();
    for (i, s) in p.surfaces.iter().enumerate() {
        let surface = i + 1;
        glass_lines.push(match &s.medium {
            Medium::Air => None,
            Medium::Glass(name) => {
                let glass = lookup(name)?;
                if names
                    .iter()
                    .any(|(n, maker)| *n == glass.name && *maker != glass.maker)
                {
                    return refuse(format!(
                        "surface {surface}: two glasses named {} from different catalogues in \
                         one Zemax file",
                        glass.name
                    ));
                }
                names.push((glass.name, glass.maker));
                if !catalogues.contains(&glass.maker) {
                    catalogues.push(glass.maker);
                }
                Some(format!(
                    "GLAS {} 0 0 {} {}",
                    glass.name,
                    num(glass.nd),
                    num(glass.vd)
                ))
            }
            Medium::Model { nd, vd } => {
                Some(format!("GLAS ___BLANK 1 0 {} {}", num(*nd), num(*vd)))
            }
            Medium::Index(n) => Some(format!("GLAS ___BLANK 1 0 {} 0", num(*n))),
            Medium::Mirror => Some("GLAS MIRROR 0 0 1.5 40".to_string()),
            Medium::Sellmeier { .. } | Medium::PowerSeries { .. } | Medium::Table { .. } => {
                return refuse(format!(
                    "surface {surface}: a medium given by its own coefficients or table; a Zemax \
                     file names catalogue glasses"
                ));
            }
        });
        if s.shape.aspheric_coefficients().len() > ZEMAX_ASPHERE_TERMS {
            let (kind, type_name, last) = match s.shape {
                Shape::OddAsphere { .. } => ("odd", "ODDASPHE", 8),
                _ => ("even", "EVENASPH", 16),
            };
            return refuse(format!(
                "surface {surface}: {kind}-asphere terms beyond r^{last} (Zemax {type_name} \
                 holds PARM 1..8)"
            ));
        }
    }

    let mut out = String::new();
    let mut line = |text: String| {
        out.push_str(&text);
        out.push('\n');
    };
    line("MODE SEQ".into());
    line(format!(
        "NAME {}",
        p.provenance.title.replace(['\n', '\r'], " ")
    ));
    line("UNIT MM X W X CM MR CPMM".into());
    if !catalogues.is_empty() {
        line(format!("GCAT {}", catalogues.join(" ")));
    }
    let conditions = p.provenance.conditions.clone().unwrap_or_default();
    match conditions.aperture {
        Some(ApertureSpec::EntrancePupilDiameter(d)) => line(format!("ENPD {}", num(d))),
        Some(ApertureSpec::FNumber(f)) => line(format!("FNUM {} 0", num(f))),
        Some(ApertureSpec::ObjectNumericalAperture(na)) => line(format!("OBNA {} 0", num(na))),
        // Without a stated aperture lensbake opens the lens wide, which is Zemax's "float by
        // stop size"; programs that read the file need an aperture.
        Some(ApertureSpec::FloatByStop) | None => line("FLOA".into()),
        Some(ApertureSpec::WorkingFNumber(_)) => {}
    }
    let design_nm = p
        .provenance
        .design_wavelength_nm
        .unwrap_or(DEFAULT_WAVELENGTH_NM);
    let wavelengths = if conditions.wavelengths_nm.is_empty() {
        vec![design_nm]
    } else {
        conditions.wavelengths_nm.clone()
    };
    // Without stated fields, the axis alone (lensbake then picks the field by its rule).
    let fields = conditions.fields.clone().unwrap_or(FieldSpec {
        kind: FieldKind::AngleDeg,
        x: vec![0.0],
        y: vec![0.0],
        weights: vec![1.0],
    });
    {
        let fields = &fields;
        let kind = match fields.kind {
            FieldKind::AngleDeg => 0,
            FieldKind::ObjectHeight => 1,
            FieldKind::ParaxialImageHeight => 2,
            FieldKind::RealImageHeight => 3,
        };
        let list = |values: &[f64]| values.iter().map(|v| num(*v)).collect::<Vec<_>>().join(" ");
        line(format!(
            "FTYP {kind} 0 {} {} 0 0 0",
            fields.x.len(),
            wavelengths.len()
        ));
        line(format!("XFLN {}", list(&fields.x)));
        line(format!("YFLN {}", list(&fields.y)));
        if fields.weights.len() == fields.x.len() {
            line(format!("FWGN {}", list(&fields.weights)));
        }
    }
    for (k, nm) in wavelengths.iter().enumerate() {
        let weight = conditions.wavelength_weights.get(k).copied().unwrap_or(1.0);
        line(format!(
            "WAVM {} {} {}",
            k + 1,
            num(nm / 1000.0),
            num(weight)
        ));
    }
    // Stated wavelengths without a primary are analysed at the first, as the file written must
    // be (the design wavelength's place in the list made a RON lens analysed at 656.3 nm come
    // back analysed at 587.6).
    line(format!("PWAV {}", conditions.primary.unwrap_or(0) + 1));
    match conditions.ray_aiming {
        Some(RayAiming::Real) => line("RAIM 0 2 1 1 0 0 0 0 0".into()),
        Some(RayAiming::Paraxial) => line("RAIM 0 0 1 1 0 0 0 0 0".into()),
        None => {}
    }
    line("SURF 0".into());
    line("  TYPE STANDARD".into());
    line("  CURV 0".into());
    line(match conditions.object_distance_mm {
        Some(d) => format!("  DISZ {}", num(d)),
        None => "  DISZ INFINITY".into(),
    });
    for (i, (s, glass)) in p.surfaces.iter().zip(&glass_lines).enumerate() {
        line(format!("SURF {}", i + 1));
        if s.stop.is_some() {
            line("  STOP".into());
        }
        let terms = s.shape.aspheric_coefficients();
        line(match s.shape {
            Shape::IdealLens { .. } => "  TYPE PARAXIAL".into(),
            _ if terms.is_empty() => "  TYPE STANDARD".into(),
            Shape::OddAsphere { .. } => "  TYPE ODDASPHE".into(),
            _ => "  TYPE EVENASPH".into(),
        });
        line(format!("  CURV {}", num(s.shape.curvature())));
        if let Shape::IdealLens { focal_length } = s.shape {
            line(format!("  PARM 1 {}", num(focal_length)));
        }
        if s.shape.conic() != 0.0 {
            line(format!("  CONI {}", num(s.shape.conic())));
        }
        for (k, a) in terms.iter().enumerate() {
            line(format!("  PARM {} {}", k + 1, num(*a)));
        }
        line(format!("  DISZ {}", num(s.thickness)));
        if let Some(glass) = glass {
            line(format!("  {glass}"));
        }
        line(format!("  DIAM {} 1 0 0 1 \"\"", num(s.semi_aperture)));
        line(format!("  CLAP 0 {} 0", num(s.semi_aperture)));
        if let Some(radius) = s.obscuration {
            line(format!("  OBSC 0 {} 0", num(radius)));
        }
    }
    line(format!("SURF {}", p.surfaces.len() + 1));
    line("  TYPE STANDARD".into());
    line("  CURV 0".into());
    line("  DISZ 0".into());
    Ok(out)
}

/// The pbrt `.dat` text of `p`, indices at `wavelength_nm` (see the module docs).
pub fn write_pbrt(p: &Prescription, wavelength_nm: f64) -> Result<String, Problem> {
    object_in_air(p, "pbrt")?;
    let mut out = format!(
        "# {}\n# written by lensbake: indices at {wavelength_nm} nm; pbrt's RealisticCamera \
         reads radius, thickness to the next surface, index, aperture diameter (mm)\n\
         # radius\tthickness\tior\taperture\n",
        p.provenance.title.replace(['\n', '\r'], " ")
    );
    let mut before = &p.object_medium;
    for (i, s) in p.surfaces.iter().enumerate() {
        let surface = i + 1;
        not_reflecting_or_obscured(s, surface)?;
        let radius = match s.shape {
            // A sphere whose radius does not fit an f64 (curvature 0, -0 or subnormal) is a
            // plane to pbrt too; its reciprocal written out (`inf`) made a file no reader takes.
            Shape::Sphere { curvature } if (1.0 / curvature).is_finite() => 1.0 / curvature,
            Shape::Sphere { .. } | Shape::Plane if s.stop.is_some() => 0.0,
            Shape::Sphere { .. } | Shape::Plane => {
                return refuse(format!(
                    "surface {surface}: a plane refracting surface; pbrt reads radius 0 as the \
                     aperture stop"
                ));
            }
            Shape::Conic { .. } | Shape::EvenAsphere { .. } | Shape::OddAsphere { .. } => {
                return refuse(format!(
                    "surface {surface}: a conic or aspheric surface; pbrt holds spheres"
                ));
            }
            Shape::IdealLens { .. } => {
                return refuse(format!(
                    "surface {surface}: an ideal lens (Zemax paraxial surface); pbrt traces \
                     spheres only"
                ));
            }
        };
        let index = if s.stop.is_some() {
            if radius != 0.0 || s.medium != *before {
                return refuse(format!(
                    "surface {surface}: the stop is curved or lies between two media; pbrt's \
                     stop is a plane in one medium"
                ));
            }
            "0".to_string()
        } else {
            let n = Dispersion::of(&s.medium)?.checked_index(wavelength_nm)?;
            num(n)
        };
        out.push_str(&format!(
            "{}\t{}\t{}\t{}\n",
            num(radius),
            num(s.thickness),
            index,
            num(2.0 * s.semi_aperture)
        ));
        before = &s.medium;
    }
    Ok(out)
}
