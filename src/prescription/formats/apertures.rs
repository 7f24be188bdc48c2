//! Clear apertures for CODE V and Zemax files that give none.
//!
//! CODE V and OpticStudio compute clear apertures themselves, from real rays: for every field,
//! the chief ray and the rays at the edges of the (vignetted) entrance pupil, in the meridional
//! and sagittal directions; a surface's clear aperture is the largest height any of them reaches
//! there. Their files therefore often carry none (`ag_dblgauss.seq` has no `CIR`).
//!
//! A reader cannot trace real rays (that needs the validated system this reader feeds), so it
//! traces the same ray set paraxially: marginal ray y (axial object point, pupil edge) and chief
//! ray ȳ (field angle, pupil centre), combined linearly. For pupil point (px, py) at one field the
//! height is hypot(px y, ȳ + py y). Paraxial heights differ from real ones where the beam is fast
//! and the field wide; for the F/2, 14° CODE V double Gauss the derived apertures lie within about
//! 10% of the real-ray ones (documented in tests/formats.rs). Apertures the file gives are kept.
//!
//! For reference: the semi-apertures in tests/data/truth/oracle/codev_ag_dblgauss.json (28.18,
//! 27.14, 24.63, ...) are rayoptics 0.9.8's real-ray clear apertures for that ray set (28.1719,
//! 27.1359, 24.6262, ... mm, chief rays aimed at the stop centre) rounded up to 0.01 mm. Matching
//! them needs the real-ray trace, which runs on a validated system; a later stage can refine the
//! derived apertures that way (the `AperturesDerived` note says which surfaces to refine).

use super::{Format, LoadNote, Loaded};
use crate::glass::Dispersion;
use crate::prescription::error::{PrescriptionError, Problem};
use crate::prescription::model::{ApertureSpec, Conditions, FieldKind, Prescription};
use crate::prescription::validate::{SourceMap, check_stop};

/// How big the entrance pupil is.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum PupilSize {
    Diameter(f64),
    /// Image-space F-number: EPD = EFL / F at any object distance.
    FNumber(f64),
    /// Working F-number 1 / (2 n' u') of the axial marginal ray at the object distance.
    WorkingFNumber(f64),
    /// The stop's own semi-aperture sets the beam (Zemax "float by stop size").
    FloatByStop,
    /// Object-space numerical aperture n sin u (finite objects).
    ObjectNumericalAperture(f64),
    /// No usable aperture specification; the reason, as a sentence fragment for the error.
    Unusable(String),
}

/// One field point: its angle and the part of the entrance pupil it fills (relative pupil
/// coordinates, lower edge <= 0 <= upper edge; 1 means the full pupil radius).
#[derive(Clone, Debug, PartialEq)]
pub(super) struct FieldPoint {
    pub position: FieldPosition,
    pub pupil_y: (f64, f64),
    pub pupil_x: (f64, f64),
}

/// Where a field point's chief ray comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum FieldPosition {
    /// Object-space angle, degrees.
    AngleDeg(f64),
    /// Object height, mm (finite objects only).
    ObjectHeight(f64),
    /// Paraxial image height, mm (objects at infinity only).
    ImageHeight(f64),
}

/// The filled part of one field's pupil, from its vignetting factors: x from..to, then y
/// from..to, as fractions of the pupil radius.
pub(super) type PupilFill = ((f64, f64), (f64, f64));

/// The fields (1-based) whose vignetting factors trim the pupil, for
/// [`super::LoadNote::VignettingNotApplied`].
pub(super) fn trimmed_fields(pupils: &[PupilFill]) -> Vec<usize> {
    pupils
        .iter()
        .enumerate()
        .filter(|(_, fill)| **fill != ((-1.0, 1.0), (-1.0, 1.0)))
        .map(|(k, _)| k + 1)
        .collect()
}

/// What the file says about the beams, in mm and nm.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct BeamSpec {
    pub pupil: PupilSize,
    /// Distance from the object to surface 1; None for an object at infinity.
    pub object_distance: Option<f64>,
    /// Field points; an empty list means the axial beam only.
    pub fields: Vec<FieldPoint>,
    pub wavelength_nm: f64,
}

impl BeamSpec {
    /// The beams a file's stated conditions describe. `pupils` gives each field's (x, y) filled
    /// part of the pupil (vignetting factors); `no_aperture` says why there is no aperture when
    /// the conditions hold none.
    pub fn from_conditions(
        conditions: &Conditions,
        pupils: &[PupilFill],
        no_aperture: String,
        wavelength_nm: f64,
    ) -> BeamSpec {
        let pupil = match &conditions.aperture {
            Some(ApertureSpec::EntrancePupilDiameter(d)) => PupilSize::Diameter(*d),
            Some(ApertureSpec::FNumber(f)) => PupilSize::FNumber(*f),
            Some(ApertureSpec::WorkingFNumber(f)) => PupilSize::WorkingFNumber(*f),
            Some(ApertureSpec::ObjectNumericalAperture(na)) => {
                PupilSize::ObjectNumericalAperture(*na)
            }
            Some(ApertureSpec::FloatByStop) => PupilSize::FloatByStop,
            None => PupilSize::Unusable(no_aperture),
        };
        let fields = match &conditions.fields {
            None => Vec::new(),
            Some(spec) => {
                let position = |x: f64, y: f64| match spec.kind {
                    FieldKind::AngleDeg => FieldPosition::AngleDeg(
                        x.to_radians()
                            .tan()
                            .hypot(y.to_radians().tan())
                            .atan()
                            .to_degrees(),
                    ),
                    FieldKind::ObjectHeight => FieldPosition::ObjectHeight(x.hypot(y)),
                    // Real image heights are taken as paraxial ones here: the derived apertures
                    // are paraxial estimates whatever the field type.
                    FieldKind::ParaxialImageHeight | FieldKind::RealImageHeight => {
                        FieldPosition::ImageHeight(x.hypot(y))
                    }
                };
                spec.x
                    .iter()
                    .zip(&spec.y)
                    .enumerate()
                    .map(|(k, (x, y))| {
                        let (pupil_x, pupil_y) =
                            pupils.get(k).copied().unwrap_or(((-1.0, 1.0), (-1.0, 1.0)));
                        FieldPoint {
                            position: position(*x, *y),
                            pupil_x,
                            pupil_y,
                        }
                    })
                    .collect()
            }
        };
        BeamSpec {
            pupil,
            object_distance: conditions.object_distance_mm,
            fields,
            wavelength_nm,
        }
    }
}

/// Object distances at least this large (mm) are infinite: the analysis's own bound (files
/// write 1e10 for infinity, as CODE V and rayoptics read it). At 1e10 a `SO 0 5e9` was a
/// finite object to the reader, which took its `FNO` as a working f-number, and infinite to
/// the analysis.
pub(super) const INFINITE_OBJECT_MM: f64 = crate::limits::MAX_LENGTH_MM;

/// Sets the semi-aperture of each surface in `missing` (0-based) from paraxial boundary rays,
/// and lowers those and the `envelopes` (apertures the file gives as the extent of its beams,
/// not as a stop to rays) to where their surface meets a neighbour. Wraps the result, noting
/// which surfaces were derived or cut so `lens check` can say so.
pub(super) fn complete(
    mut prescription: Prescription,
    missing: &[usize],
    envelopes: &[usize],
    beams: &BeamSpec,
    map: SourceMap,
    format: Format,
) -> Result<Loaded, PrescriptionError> {
    let mut at_edge = derive(&mut prescription, missing, beams, &map)?;
    let cuttable: Vec<usize> = missing.iter().chain(envelopes).copied().collect();
    let (derived_cut, envelopes_cut): (Vec<usize>, Vec<usize>) =
        cut_where_neighbours_meet(&mut prescription, &cuttable)
            .into_iter()
            .partition(|i| missing.contains(i));
    at_edge.extend(derived_cut);
    at_edge.sort_unstable();
    at_edge.dedup();
    let mut notes = Vec::new();
    if !missing.is_empty() {
        notes.push(LoadNote::AperturesDerived {
            surfaces: missing.iter().map(|i| i + 1).collect(),
            limited_at_edge: at_edge.iter().map(|i| i + 1).collect(),
        });
    }
    if !envelopes_cut.is_empty() {
        notes.push(LoadNote::EnvelopesCut {
            surfaces: envelopes_cut
                .iter()
                .map(|&i| (i + 1, prescription.surfaces[i].semi_aperture))
                .collect(),
        });
    }
    Ok(Loaded {
        prescription,
        map,
        format,
        notes,
    })
}

/// Derives the missing apertures; returns the surfaces (0-based) limited where they end.
fn derive(
    p: &mut Prescription,
    missing: &[usize],
    beams: &BeamSpec,
    map: &SourceMap,
) -> Result<Vec<usize>, PrescriptionError> {
    let Some(&first) = missing.first() else {
        return Ok(Vec::new());
    };
    let mut at_edge = Vec::new();
    let cannot = |reason: String| {
        PrescriptionError::new(
            map.surface(first, "semi_aperture"),
            Problem::CannotDeriveApertures { reason },
        )
    };
    check_stop(p, map)?;
    let stop = p.stop_index().expect("check_stop found exactly one stop");
    let indices = indices(p, beams.wavelength_nm, map)?;
    let fields = &beams.fields;

    // Heights are linear in (y1, u0): trace the two unit rays once.
    let unit_height = trace(p, &indices, 1.0, 0.0);
    let unit_slope = trace(p, &indices, 0.0, 1.0);
    let (a, b) = (unit_height.heights[stop], unit_slope.heights[stop]);
    if a == 0.0 || !a.is_finite() || !b.is_finite() {
        return Err(cannot(
            "a ray parallel to the axis never reaches the stop off axis".into(),
        ));
    }
    // The entrance pupil: a ray with slope 1 crosses the axis at z = b/a and passes the stop centre.
    let pupil_z = b / a;

    // Image-space slope of a ray from the axial object point with object-space slope 1 (at
    // infinity: of a ray parallel to the axis at height 1), and the paraxial magnification.
    let axial = match beams.object_distance {
        None => unit_height.final_slope,
        Some(distance) => trace(p, &indices, distance, 1.0).final_slope,
    };
    let image_index = indices[indices.len() - 1];
    let from_slope = |y_per_unit: f64, u_per_unit: f64, slope: f64| {
        if axial == 0.0 || !axial.is_finite() {
            return Err(cannot("an F-number needs a lens with focal power".into()));
        }
        let scale = slope / axial.abs();
        Ok((y_per_unit * scale, u_per_unit * scale))
    };
    // The axial marginal ray (y1, u0) through the rim of an entrance pupil of diameter d.
    let through_pupil = |d: f64| match beams.object_distance {
        None => Ok((d / 2.0, 0.0)),
        Some(distance) => {
            let reach = pupil_z + distance;
            if reach <= 0.0 {
                return Err(cannot("the entrance pupil lies before the object".into()));
            }
            let u = d / 2.0 / reach;
            Ok((u * distance, u))
        }
    };
    // The axial marginal ray as (y1, u0).
    let (y1, u0) = match (&beams.pupil, beams.object_distance) {
        (PupilSize::Diameter(d), _) => through_pupil(*d)?,
        (PupilSize::FNumber(f), _) => {
            let final_slope = unit_height.final_slope;
            if final_slope == 0.0 || !final_slope.is_finite() {
                return Err(cannot("an F-number needs a lens with focal power".into()));
            }
            through_pupil((1.0 / final_slope).abs() / f)?
        }
        (PupilSize::WorkingFNumber(f), None) => {
            from_slope(1.0, 0.0, 1.0 / (2.0 * image_index * f))?
        }
        (PupilSize::WorkingFNumber(f), Some(distance)) => {
            from_slope(distance, 1.0, 1.0 / (2.0 * image_index * f))?
        }
        (PupilSize::FloatByStop, distance) => {
            let stop_radius = p.surfaces[stop].semi_aperture;
            if missing.contains(&stop) || stop_radius <= 0.0 {
                return Err(cannot(
                    "the aperture floats by stop size but the stop has no size (give the stop \
                     its semi-aperture, e.g. Zemax's DIAM, or state the aperture another way, \
                     e.g. ENPD)"
                        .into(),
                ));
            }
            match distance {
                None => (stop_radius / a, 0.0),
                Some(distance) => {
                    let u = stop_radius / (a * distance + b);
                    (u * distance, u)
                }
            }
        }
        (PupilSize::ObjectNumericalAperture(na), Some(distance)) => {
            let n = indices[0];
            if !(*na > 0.0 && *na < n) {
                return Err(cannot(format!(
                    "object-space NA {na} is not below the index {n}"
                )));
            }
            let u = (na / n).asin().tan();
            (u * distance, u)
        }
        (PupilSize::ObjectNumericalAperture(_), None) => {
            return Err(cannot(
                "an object-space NA needs an object at a finite distance".into(),
            ));
        }
        (PupilSize::Unusable(reason), _) => return Err(cannot(reason.clone())),
    };
    let marginal = trace(p, &indices, y1, u0).heights;
    let mut chiefs = Vec::new();
    for field in fields {
        let slope = match (field.position, beams.object_distance) {
            (FieldPosition::AngleDeg(deg), _) => deg.to_radians().tan(),
            (FieldPosition::ObjectHeight(h), Some(distance)) => h / (distance + pupil_z),
            (FieldPosition::ObjectHeight(_), None) => {
                return Err(cannot(
                    "the fields are object heights but the object is at infinity".into(),
                ));
            }
            // At infinity the paraxial image height is EFL tan(angle).
            (FieldPosition::ImageHeight(h), None) => {
                let power = -unit_height.final_slope;
                if power == 0.0 || !power.is_finite() {
                    return Err(cannot("image-height fields need a lens with power".into()));
                }
                h * power
            }
            // A finite object: the object height the paraxial magnification
            // m = n u / (n' u') images to that height.
            (FieldPosition::ImageHeight(h), Some(distance)) => {
                let magnification = indices[0] / (image_index * axial);
                if magnification == 0.0 || !magnification.is_finite() {
                    return Err(cannot("the object is imaged to infinity".into()));
                }
                h / magnification.abs() / (distance + pupil_z)
            }
        };
        chiefs.push((field, trace(p, &indices, -pupil_z * slope, slope).heights));
    }

    for &i in missing {
        let y = marginal[i];
        let mut radius = y.abs();
        for (field, chief) in &chiefs {
            let ybar = chief[i];
            for px in [field.pupil_x.0, field.pupil_x.1] {
                radius = radius.max((px * y).hypot(ybar));
            }
            for py in [field.pupil_y.0, field.pupil_y.1] {
                radius = radius.max((ybar + py * y).abs());
            }
        }
        if !(radius.is_finite() && radius > 0.0) {
            return Err(PrescriptionError::new(
                map.surface(i, "semi_aperture"),
                Problem::CannotDeriveApertures {
                    reason: format!("the paraxial rays give height {radius} here"),
                },
            ));
        }
        // Rays this far out would miss the surface: a sphere ends at |R|, a conic (k > -1) at
        // 1 / (|c| sqrt(1 + k)). The paraxial estimate knows no such end; the surface does.
        if let Some(rim) = p.surfaces[i].shape.rim_radius().filter(|&rim| radius > rim) {
            radius = rim;
            at_edge.push(i);
        }
        p.surfaces[i].semi_aperture = radius;
    }
    Ok(at_edge)
}

/// Lowers each aperture in `cuttable` (0-based) that goes on past the height where its surface
/// meets a neighbour (an element's knife edge, or two elements touching): no glass, or no room,
/// lies beyond it. Returns the surfaces cut. Lowering an aperture never makes another pair
/// cross, since pairs are checked within the smaller one. A reference plane meets no
/// neighbour: rays reach it wherever it lies along them.
fn cut_where_neighbours_meet(p: &mut Prescription, cuttable: &[usize]) -> Vec<usize> {
    let mut cut = Vec::new();
    for i in 0..p.surfaces.len().saturating_sub(1) {
        let may_cut = [cuttable.contains(&i), cuttable.contains(&(i + 1))];
        if may_cut == [false, false] || p.is_reference_plane(i) || p.is_reference_plane(i + 1) {
            continue;
        }
        if let Some(meet) = meeting_height(p, i) {
            for (k, may) in [i, i + 1].into_iter().zip(may_cut) {
                if may && p.surfaces[k].semi_aperture > meet {
                    p.surfaces[k].semi_aperture = meet;
                    cut.push(k);
                }
            }
        }
    }
    cut.sort_unstable();
    cut.dedup();
    cut
}

/// Samples of the gap between two surfaces in the search for where they meet.
const MEETING_SAMPLES: usize = 512;

/// The smallest height, within the smaller of the two apertures, at which surface `i` and the
/// next meet (their gap falls to zero), if they do; None when they stay apart there, or already
/// cross on the axis (validation reports that).
fn meeting_height(p: &Prescription, i: usize) -> Option<f64> {
    let (a, b) = (&p.surfaces[i], &p.surfaces[i + 1]);
    let gap = |r: f64| Some(a.thickness + b.shape.sag(r)? - a.shape.sag(r)?);
    if !(a.thickness > 0.0) {
        return None;
    }
    let r_max = a.semi_aperture.min(b.semi_aperture);
    let mut apart = 0.0;
    for k in 1..=MEETING_SAMPLES {
        let r = r_max * k as f64 / MEETING_SAMPLES as f64;
        if gap(r)? >= 0.0 {
            apart = r;
            continue;
        }
        // The gap changes sign between `apart` and r: bisect to the meeting height.
        let mut crossed = r;
        for _ in 0..60 {
            let middle = 0.5 * (apart + crossed);
            if gap(middle)? >= 0.0 {
                apart = middle;
            } else {
                crossed = middle;
            }
        }
        return Some(apart);
    }
    None
}

/// Index before surface 1 (entry 0) and after each surface, at one wavelength, signed as
/// [`crate::system::SurfaceAt::index_after`] is: a mirror keeps the medium and turns the sign.
fn indices(
    p: &Prescription,
    wavelength_nm: f64,
    map: &SourceMap,
) -> Result<Vec<f64>, PrescriptionError> {
    let object = Dispersion::of(&p.object_medium).map_err(|problem| {
        let mut location = map.whole_file();
        location.field = Some("object medium".into());
        PrescriptionError::new(location, problem)
    })?;
    let mut n = vec![object.index(wavelength_nm)];
    for ((i, s), travel) in p.surfaces.iter().enumerate().zip(p.travel_after()) {
        let index = match s.medium {
            crate::prescription::Medium::Mirror => n[i].abs(),
            _ => Dispersion::of(&s.medium)
                .map_err(|problem| PrescriptionError::new(map.surface(i, "medium"), problem))?
                .index(wavelength_nm),
        };
        n.push(travel * index);
    }
    Ok(n)
}

struct Trace {
    /// Height at each surface.
    heights: Vec<f64>,
    /// Slope after the last surface.
    final_slope: f64,
}

/// Paraxial y-u trace from height `y` at surface 1 with slope `u` before it.
fn trace(p: &Prescription, n: &[f64], mut y: f64, mut u: f64) -> Trace {
    let mut heights = Vec::with_capacity(p.surfaces.len());
    for (i, s) in p.surfaces.iter().enumerate() {
        heights.push(y);
        let (before, after) = (n[i], n[i + 1]);
        let power = s.shape.curvature() * (after - before) + s.shape.ideal_power();
        u = (before * u - y * power) / after;
        y += s.thickness * u;
    }
    Trace {
        heights,
        final_slope: u,
    }
}
