//! Checks a prescription before anything computes with it.

use super::error::{Location, PrescriptionError, Problem};
use super::model::{
    MAX_ASPHERE_TERMS, MAX_INDEX, MIN_ABBE_NUMBER, MIN_INDEX, Medium, Prescription, Shape,
    StatedCondition, StopShape,
};
use crate::limits;
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Where each surface came from in its file, so errors found after parsing still cite lines.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SourceMap {
    pub file: Option<PathBuf>,
    /// 1-based line of each surface's row, by 0-based surface index.
    pub surface_lines: Vec<Option<usize>>,
    /// Fields a format writes on lines of their own (Zemax: one keyword per line), by 0-based
    /// surface index and lensbake's field name: the line and the keyword the file used, so an
    /// error names the line a reader has to edit rather than the surface's first line.
    pub field_lines: BTreeMap<(usize, &'static str), (usize, &'static str)>,
    /// The line and keyword of each condition the file states, for errors found when an
    /// analysis uses it.
    pub condition_lines: BTreeMap<StatedCondition, (usize, &'static str)>,
}

impl SourceMap {
    pub fn for_file(file: impl Into<PathBuf>) -> SourceMap {
        SourceMap {
            file: Some(file.into()),
            ..SourceMap::default()
        }
    }

    /// Location of surface `index` (0-based) and one of its fields: the field's own line and
    /// keyword where the file wrote it apart, else the surface's line.
    pub fn surface(&self, index: usize, field: &str) -> Location {
        // The surface's own entries only: validation asks for a location of every surface.
        let own_line = self
            .field_lines
            .range((index, "")..(index + 1, ""))
            .find(|((_, name), _)| *name == field)
            .map(|(_, &at)| at);
        let mut location = Location {
            file: self.file.clone(),
            ..Location::default()
        }
        .with_surface(index + 1)
        .with_field(own_line.map_or(field, |(_, keyword)| keyword));
        location.line = own_line
            .map(|(line, _)| line)
            .or_else(|| self.surface_lines.get(index).copied().flatten());
        location
    }

    /// Location of a stated condition: the file, and its line and keyword where known.
    pub fn condition(&self, condition: StatedCondition) -> Location {
        let mut location = self.whole_file();
        if let Some(&(line, keyword)) = self.condition_lines.get(&condition) {
            location.line = Some(line);
            location.field = Some(keyword.to_string());
        }
        location
    }

    pub fn whole_file(&self) -> Location {
        Location {
            file: self.file.clone(),
            ..Location::default()
        }
    }
}

/// Number of radial samples used to compare neighbouring sags; fine enough to catch a crossing
/// anywhere but at a knife edge, which the rim check catches.
const CROSSING_SAMPLES: usize = 64;

/// Overlap of neighbouring surfaces (mm) accepted as touching; larger overlaps are refused as
/// crossing surfaces, unless within `CROSSING_RELATIVE_TOLERANCE` (1e-5) of the lens's largest
/// clear diameter.
pub const CROSSING_TOLERANCE_MM: f64 = 1e-6;

/// Overlap accepted as touching, as a fraction of the lens's largest clear diameter.
///
/// Published tables print lengths to about six significant figures of the lens's size (ISET's
/// tables: 2.160 mm gaps, 133.930 mm radii, 160 mm apertures at the 50 mm scale), and rounding a
/// gap to its last printed digit moves two surfaces by up to half of it, 5e-6 of the size: edges
/// that touch by design may cross by that much. A manufacturing tolerance is 1e-4 to 1e-3 of a
/// lens's size, a hundred times more, so an overlap under 1e-5 of it is rounding, not glass. Real
/// crossings stay refused: rayoptics' lens_reflection_test.seq (0.033 mm, 1.9% of its 1.75 mm
/// element) and ISET's fisheye, whose surfaces 6 and 7 overlap 0.15 mm at the 29 mm rim of
/// surface 7 (1e-3 of its 160 mm aperture; a first-failing sample at 28.09 mm once reported
/// 0.0007 mm).
pub const CROSSING_RELATIVE_TOLERANCE: f64 = 1e-5;

/// Validates the prescription, returning the first problem found.
pub fn validate(p: &Prescription, map: &SourceMap) -> Result<(), PrescriptionError> {
    if p.surfaces.is_empty() {
        return Err(PrescriptionError::new(map.whole_file(), Problem::Empty));
    }
    limits::check(
        "the number of surfaces",
        p.surfaces.len() as u64,
        limits::MAX_SURFACES,
    )
    .map_err(|e| PrescriptionError::new(map.whole_file(), e.into()))?;
    let object_medium = Location {
        file: map.file.clone(),
        field: Some("object_medium".into()),
        ..Location::default()
    };
    if p.object_medium == Medium::Mirror {
        return Err(PrescriptionError::new(
            object_medium,
            Problem::Unsupported("object space cannot be a mirror".into()),
        ));
    }
    check_medium(&p.object_medium, object_medium)?;
    check_provenance(p, map)?;
    check_stated_spectrum_and_fields(p, map)?;
    for (i, s) in p.surfaces.iter().enumerate() {
        check_surface(i, s, map)?;
        check_ideal_lens(p, i, map)?;
    }
    check_stop(p, map)?;
    check_crossings(p, map)
}

/// The numbers a file claims about itself are printed and compared against: each must be finite
/// (an f-number positive), and the design wavelength one lensbake can trace at.
fn check_provenance(p: &Prescription, map: &SourceMap) -> Result<(), PrescriptionError> {
    let field = |name: &str| Location {
        file: map.file.clone(),
        field: Some(format!("provenance.{name}")),
        ..Location::default()
    };
    // A diverging lens claims a negative focal length; an f-number is positive and at most
    // the slowest a command takes (a claimed f/1e300 set a pupil so small that the PSF plot's
    // axes spanned 1e297 mm and `report` never finished them), and a half field an angle a
    // chief ray can have, above 0 and below 90 degrees.
    if let Some(efl) = p.provenance.claimed_focal_length_mm {
        finite(efl, field("claimed_focal_length_mm"))?;
    }
    for (name, value, most) in [
        (
            "claimed_f_number",
            p.provenance.claimed_f_number,
            limits::MAX_F_NUMBER,
        ),
        (
            "claimed_half_field_deg",
            p.provenance.claimed_half_field_deg,
            89.999,
        ),
    ] {
        if let Some(value) = value {
            limits::check_positive(name, value)
                .and_then(|()| limits::check_range(name, value, 0.0, most))
                .map_err(|e| PrescriptionError::new(field(name), e.into()))?;
        }
    }
    if let Some(nm) = p.provenance.design_wavelength_nm {
        limits::check_wavelength(nm)
            .map_err(|e| PrescriptionError::new(field("design_wavelength_nm"), e.into()))?;
    }
    Ok(())
}

/// The wavelengths and weights a lens states are lensbake's to trace and sum: each wavelength in
/// the traceable range, each weight finite and not negative, one weight per wavelength or
/// field point where weights are given, the primary one of the wavelengths, and one x per y.
/// The Zemax and CODE V readers check their numbers on their lines; a RON file's come here
/// whole (a RON lens drew a wavelength of -480 nm).
fn check_stated_spectrum_and_fields(
    p: &Prescription,
    map: &SourceMap,
) -> Result<(), PrescriptionError> {
    let Some(conditions) = &p.provenance.conditions else {
        return Ok(());
    };
    let at = |name: &str| Location {
        file: map.file.clone(),
        field: Some(format!("provenance.conditions.{name}")),
        ..Location::default()
    };
    let mismatch =
        |name: &str, what: String| Err(PrescriptionError::new(at(name), Problem::Syntax(what)));
    for &nm in &conditions.wavelengths_nm {
        limits::check_wavelength(nm)
            .map_err(|e| PrescriptionError::new(at("wavelengths_nm"), e.into()))?;
    }
    let weights = [(
        "wavelength_weights",
        &conditions.wavelength_weights,
        conditions.wavelengths_nm.len(),
    )]
    .into_iter()
    .chain(
        conditions
            .fields
            .as_ref()
            .map(|f| ("fields.weights", &f.weights, f.y.len())),
    );
    for (name, weights, count) in weights {
        if !weights.is_empty() && weights.len() != count {
            return mismatch(
                name,
                format!("{} weights for {count} entries", weights.len()),
            );
        }
        for &weight in weights.iter() {
            if !(weight.is_finite() && weight >= 0.0) {
                return mismatch(name, format!("weight {weight} is not a finite number >= 0"));
            }
        }
    }
    if let Some(primary) = conditions.primary
        && primary >= conditions.wavelengths_nm.len()
    {
        return mismatch(
            "primary",
            format!(
                "primary wavelength {primary} (counted from 0) of {} wavelengths",
                conditions.wavelengths_nm.len()
            ),
        );
    }
    if let Some(fields) = &conditions.fields
        && fields.x.len() != fields.y.len()
    {
        return mismatch(
            "fields",
            format!(
                "{} x values for {} y values",
                fields.x.len(),
                fields.y.len()
            ),
        );
    }
    Ok(())
}

fn finite(value: f64, location: Location) -> Result<(), PrescriptionError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(PrescriptionError::new(
            location,
            Problem::NonFinite { value },
        ))
    }
}

fn check_medium(medium: &Medium, location: Location) -> Result<(), PrescriptionError> {
    match medium {
        Medium::Air | Medium::Glass(_) | Medium::Mirror => Ok(()),
        Medium::Index(n) => {
            finite(*n, location.clone())?;
            check_index(*n, location)
        }
        Medium::Sellmeier { b, c } => {
            for v in b.iter().chain(c) {
                finite(*v, location.clone())?;
            }
            Ok(())
        }
        Medium::PowerSeries { a } => {
            for v in a {
                finite(*v, location.clone())?;
            }
            Ok(())
        }
        Medium::Table {
            wavelengths_nm,
            indices,
        } => {
            if wavelengths_nm.len() != indices.len() {
                return Err(PrescriptionError::new(
                    location,
                    Problem::BadIndexTable {
                        reason: format!(
                            "{} wavelengths but {} indices",
                            wavelengths_nm.len(),
                            indices.len()
                        ),
                    },
                ));
            }
            let points = wavelengths_nm.iter().copied().zip(indices.iter().copied());
            crate::glass::Dispersion::tabulated(points.collect())
                .map(|_| ())
                .map_err(|problem| PrescriptionError::new(location, problem))
        }
        Medium::Model { nd, vd } => {
            finite(*nd, location.clone())?;
            finite(*vd, location.clone())?;
            if *vd != 0.0 && *vd < MIN_ABBE_NUMBER {
                return Err(PrescriptionError::new(
                    location,
                    Problem::AbbeNumberBelowLimit { vd: *vd },
                ));
            }
            check_index(*nd, location)
        }
    }
}

fn check_index(n: f64, location: Location) -> Result<(), PrescriptionError> {
    if n < MIN_INDEX {
        Err(PrescriptionError::new(
            location,
            Problem::IndexBelowVacuum { index: n },
        ))
    } else if n > MAX_INDEX {
        Err(PrescriptionError::new(
            location,
            Problem::IndexAboveLimit { index: n },
        ))
    } else {
        Ok(())
    }
}

/// An ideal lens's focal length is a finite length of at least [`crate::limits::MIN_LENGTH_MM`]
/// (its power 1/f times a height must stay a number), and it lies in air with air after
/// it: its power 1/f is defined for air (a Zemax paraxial surface in glass has no published
/// meaning lensbake could follow), and it cannot reflect.
fn check_ideal_lens(p: &Prescription, i: usize, map: &SourceMap) -> Result<(), PrescriptionError> {
    let s = &p.surfaces[i];
    let Shape::IdealLens { focal_length } = s.shape else {
        return Ok(());
    };
    finite(focal_length, map.surface(i, "focal_length"))?;
    if focal_length.abs() < crate::limits::MIN_LENGTH_MM {
        return Err(PrescriptionError::new(
            map.surface(i, "focal_length"),
            Problem::Unsupported(format!(
                "an ideal lens of focal length {focal_length:e} mm (shorter than {:e} mm bends \
                 rays past what the trace can hold)",
                crate::limits::MIN_LENGTH_MM
            )),
        ));
    }
    let before = p.medium_before(i);
    if !(before.is_air() && s.medium.is_air()) {
        return Err(PrescriptionError::new(
            map.surface(i, "medium"),
            Problem::Unsupported(format!(
                "an ideal lens between {} and {}: lensbake models ideal lenses in air",
                before.describe(),
                s.medium.describe()
            )),
        ));
    }
    Ok(())
}

fn check_surface(i: usize, s: &Surface, map: &SourceMap) -> Result<(), PrescriptionError> {
    let curvature = s.shape.curvature();
    finite(curvature, map.surface(i, "curvature"))?;
    finite(s.shape.conic(), map.surface(i, "conic"))?;
    let terms = s.shape.aspheric_coefficients();
    if terms.len() > MAX_ASPHERE_TERMS {
        return Err(PrescriptionError::new(
            map.surface(i, "coefficients"),
            Problem::TooManyAsphereTerms { found: terms.len() },
        ));
    }
    for a in terms {
        finite(*a, map.surface(i, "coefficients"))?;
    }
    finite(s.thickness, map.surface(i, "thickness"))?;
    // A gap of 1e300 mm gave Seidel sums no analysis could print, and an unlocated error.
    limits::check_position("the thickness (mm)", s.thickness)
        .map_err(|e| PrescriptionError::new(map.surface(i, "thickness"), e.into()))?;
    finite(s.semi_aperture, map.surface(i, "semi_aperture"))?;
    // Below a nanometre the bake's pupil search divides by squares that underflow (a 1e-300 mm
    // aperture baked a table of NaN margins).
    limits::check_length("the semi-aperture", s.semi_aperture)
        .map_err(|e| PrescriptionError::new(map.surface(i, "semi_aperture"), e.into()))?;
    check_medium(&s.medium, map.surface(i, "medium"))?;
    if let Some(radius) = s.obscuration {
        finite(radius, map.surface(i, "obscuration"))?;
        if !(radius > 0.0 && radius < s.semi_aperture) {
            return Err(PrescriptionError::new(
                map.surface(i, "obscuration"),
                Problem::ObscurationOutOfRange {
                    radius,
                    semi_aperture: s.semi_aperture,
                },
            ));
        }
    }

    if let Some(limit) = s.shape.rim_radius().filter(|&rim| s.semi_aperture > rim) {
        let problem = if matches!(s.shape, Shape::Sphere { .. }) {
            Problem::ApertureExceedsRadius {
                semi_aperture: s.semi_aperture,
                radius: limit,
            }
        } else {
            Problem::ApertureExceedsConic {
                semi_aperture: s.semi_aperture,
                limit,
            }
        };
        return Err(PrescriptionError::new(
            map.surface(i, "semi_aperture"),
            problem,
        ));
    }
    if let Some(StopShape::Blades {
        count,
        rotation_deg,
        blade_curvature,
    }) = &s.stop
    {
        if *count < 3 {
            return Err(PrescriptionError::new(
                map.surface(i, "stop"),
                Problem::TooFewBlades { count: *count },
            ));
        }
        limits::check("the stop's blade count", *count as u64, limits::MAX_BLADES)
            .map_err(|e| PrescriptionError::new(map.surface(i, "stop"), e.into()))?;
        finite(*rotation_deg, map.surface(i, "stop"))?;
        finite(*blade_curvature, map.surface(i, "stop"))?;
        if !(0.0..=1.0).contains(blade_curvature) {
            return Err(PrescriptionError::new(
                map.surface(i, "stop"),
                Problem::BladeCurvatureOutOfRange {
                    value: *blade_curvature,
                },
            ));
        }
    }
    Ok(())
}

use super::model::Surface;

pub(crate) fn check_stop(p: &Prescription, map: &SourceMap) -> Result<(), PrescriptionError> {
    let stops: Vec<usize> = p
        .surfaces
        .iter()
        .enumerate()
        .filter(|(_, s)| s.stop.is_some())
        .map(|(i, _)| i + 1)
        .collect();
    match stops.len() {
        0 => Err(PrescriptionError::new(map.whole_file(), Problem::NoStop)),
        1 => Ok(()),
        _ => Err(PrescriptionError::new(
            map.surface(stops[1] - 1, "stop"),
            Problem::MultipleStops { surfaces: stops },
        )),
    }
}

/// Neighbouring surfaces must not cross within the smaller of their clear apertures: the gap
/// z_next(r) - z_this(r), measured in the sense light travels between them (-z after an odd
/// number of mirrors), stays non-negative for every sampled r.
///
/// A reference plane ([`Prescription::is_reference_plane`]) is exempt: it is a place where rays
/// are measured, not a piece of glass, and optimisers leave one a hair inside a curved neighbour.
fn check_crossings(p: &Prescription, map: &SourceMap) -> Result<(), PrescriptionError> {
    let z = p.vertex_z();
    let travel = p.travel_after();
    let lens_diameter = 2.0
        * p.surfaces
            .iter()
            .map(|s| s.semi_aperture)
            .filter(|r| r.is_finite())
            .fold(0.0, f64::max);
    for i in 0..p.surfaces.len().saturating_sub(1) {
        if p.is_reference_plane(i) || p.is_reference_plane(i + 1) {
            continue;
        }
        let (a, b) = (&p.surfaces[i], &p.surfaces[i + 1]);
        let sense = travel[i];
        let r_max = a.semi_aperture.min(b.semi_aperture);
        // Inside a central hole or obscuration no ray passes between the two surfaces (a
        // Cassegrain's secondary may sit in its primary's hole), so only the ring outside the
        // larger of them must be clear.
        let r_min = a
            .obscuration
            .into_iter()
            .chain(b.obscuration)
            .fold(0.0, f64::max);
        if r_min >= r_max {
            continue;
        }
        // The deepest overlap over the samples, so the error states how far the surfaces
        // cross, not where they first pass the tolerance.
        let mut deepest: Option<(f64, f64)> = None;
        for k in 0..=CROSSING_SAMPLES {
            let r = r_min + (r_max - r_min) * k as f64 / CROSSING_SAMPLES as f64;
            let (Some(sag_a), Some(sag_b)) = (a.shape.sag(r), b.shape.sag(r)) else {
                continue;
            };
            let gap = sense * ((z[i + 1] + sag_b) - (z[i] + sag_a));
            if deepest.is_none_or(|(_, worst)| gap < worst) {
                deepest = Some((r, gap));
            }
        }
        // Touching edges (a cemented flat rim) pass, and so does the overlap of up to
        // CROSSING_TOLERANCE_MM that design programs leave behind (an optimiser's -1e-8 mm air
        // gap) or that a printed table's rounding leaves (CROSSING_RELATIVE_TOLERANCE): it is
        // far below any manufacturing tolerance and moves no ray measurably.
        let tolerance = CROSSING_TOLERANCE_MM
            .max(1e-9 * (1.0 + z[i + 1].abs()))
            .max(CROSSING_RELATIVE_TOLERANCE * lens_diameter);
        if let Some((radius, gap)) = deepest.filter(|(_, gap)| *gap < -tolerance) {
            return Err(PrescriptionError::new(
                map.surface(i, "thickness"),
                Problem::SurfacesCross {
                    next: i + 2,
                    radius,
                    gap,
                },
            ));
        }
    }
    Ok(())
}
