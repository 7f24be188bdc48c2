//! The one set of design conditions (wavelengths, object, aperture, fields) a lens is
//! analysed, plotted and reported under, each with where it came from (docs/conditions.md).
//!
//! Order of precedence, the same for every condition: a flag the user gave, else what the
//! lens file states ([`crate::prescription::Conditions`], read from Zemax and CODE V files),
//! else what the source claims ([`crate::prescription::Provenance`]: design wavelength,
//! f-number, half field), else one rule. `analyze`, every plot kind and the report header call
//! [`DesignConditions::resolve`], so they cannot disagree about the field or the aperture.

use super::AnalysisError;
use crate::glass::{C_LINE_NM, F_LINE_NM};
use crate::paraxial::{
    Aperture, Field, ObjectPosition, Paraxial, ParaxialError, ParaxialOptions, StopChoice,
};
use crate::prescription::{
    ApertureSpec, FieldKind, FieldSpec, Prescription, RayAiming, StatedCondition,
};
use crate::system::{LensSystem, SystemAt};
use crate::trace::{
    RaySource, Tracer,
    analyses::{RealRayError, RealRays},
    traceable_field_deg, traceable_field_deg_from,
};
use serde::Serialize;

/// Largest half field the rule picks (degrees). A lens whose clear apertures pass the chief
/// ray almost to 90° (a singlet with its stop on the front surface) would otherwise be
/// analysed at a grazing field no design covers; tan 45° = 1 is wider than any lens here that
/// does not state its field, and the fisheye states its own.
pub const RULE_MAX_FIELD_DEG: f64 = 45.0;

/// Step of the scan for the largest field whose real chief ray passes (degrees); bisection
/// refines it.
const FIELD_SCAN_DEG: f64 = 1.0;

/// The fields of the fans, spots and layout under the rule or a single stated field: the top
/// field, 0.7 of it and the axis, top first.
pub const FIELD_FRACTIONS: [f64; 3] = [1.0, 0.7, 0.0];

/// Where one condition came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Origin {
    /// A command-line flag (or the caller's override).
    Flag,
    /// The lens file's stated conditions (Zemax, CODE V, or a RON file's `conditions`).
    File,
    /// A value the source claims (design wavelength, f-number, half field in its title).
    Source,
    /// The documented rule (docs/conditions.md).
    Rule,
}

impl Origin {
    pub fn describe(self) -> &'static str {
        match self {
            Origin::Flag => "flag",
            Origin::File => "lens file",
            Origin::Source => "source's claim",
            Origin::Rule => "rule",
        }
    }
}

/// What the caller sets; everything `None` or empty is resolved from the lens.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct ConditionOverrides {
    /// Wavelengths to draw (nm); the first is the reference (analysis) wavelength.
    pub wavelengths_nm: Vec<f64>,
    /// The top half-field angle (degrees).
    pub field_deg: Option<f64>,
    pub epd_mm: Option<f64>,
    /// Distance of the object in front of surface 1 (mm).
    pub object_distance_mm: Option<f64>,
    pub stop: StopChoice,
    pub ray_aiming: Option<RayAiming>,
}

/// The resolved conditions of one lens.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct DesignConditions {
    /// The wavelength of the paraxial analysis and of every plot's image plane.
    pub reference_nm: f64,
    pub reference_from: Origin,
    /// The wavelengths the plots draw (the reference among them).
    pub wavelengths_nm: Vec<f64>,
    pub wavelengths_from: Origin,
    /// null for an object at infinity.
    pub object_distance_mm: Option<f64>,
    pub object_from: Origin,
    /// Half-field angles the fans, spots, layout and wave plots draw, top first; the first is
    /// the analysed field. For a finite object, the angle the object point subtends at the
    /// entrance-pupil centre.
    pub fields_deg: Vec<f64>,
    pub field_from: Origin,
    pub epd_mm: f64,
    pub f_number: f64,
    pub aperture_from: Origin,
    /// How the real-ray plots and wave figures aim a relative pupil coordinate.
    pub ray_aiming: RayAiming,
    pub ray_aiming_from: Origin,
    /// Choices worth a reader's attention (a claim not used, a field kind converted).
    pub notes: Vec<String>,
    #[serde(skip)]
    paraxial_field: Field,
    #[serde(skip)]
    stop: StopChoice,
}

impl DesignConditions {
    /// Resolves every condition of `system` under `overrides` (see the module docs for the
    /// order of precedence).
    pub fn resolve(
        system: &LensSystem,
        overrides: &ConditionOverrides,
    ) -> Result<DesignConditions, AnalysisError> {
        let stated = system.prescription.provenance.conditions.as_ref();
        let claimed = &system.prescription.provenance;
        let mut notes = Vec::new();

        let (reference_nm, reference_from) = reference_wavelength(system, overrides);
        let (wavelengths_nm, wavelengths_from) = drawn_wavelengths(
            system,
            overrides,
            stated.map(|c| &c.wavelengths_nm[..]),
            reference_nm,
        );

        let (object_distance_mm, object_from) = match (
            overrides.object_distance_mm,
            stated.and_then(|c| c.object_distance_mm),
        ) {
            (Some(d), _) => (Some(d), Origin::Flag),
            (None, Some(d)) => (Some(d), Origin::File),
            // A file that states conditions states its object, at infinity here (Zemax's
            // `DISZ INFINITY`, CODE V's `SO 0 1e10`).
            (None, None) if stated.is_some() => (None, Origin::File),
            (None, None) => (None, Origin::Rule),
        };
        // One rule for a flag and a file.
        let object_distance_mm = object_distance_mm
            .map(|d| crate::limits::object_distance("the object distance (mm)", d))
            .transpose()?
            .flatten();
        let object = object_distance_mm.map_or(ObjectPosition::Infinite, |distance| {
            ObjectPosition::Finite { distance }
        });

        let at = system.at_checked(reference_nm)?;
        let wide_open = Paraxial::new(
            &at,
            &ParaxialOptions {
                object,
                aperture: Aperture::StopClearAperture,
                field: Field::Angle { deg: 0.0 },
                stop: overrides.stop,
            },
        )
        .map_err(|error| blame(system, object_from, StatedCondition::Object, error))?;
        let efl = wide_open.first_order.efl.abs();
        let open = wide_open.entrance_pupil.diameter;
        let (epd_mm, aperture_from) = if let Some(epd) = overrides.epd_mm {
            (epd, Origin::Flag)
        } else if let Some(epd) = stated
            .and_then(|c| c.aperture.as_ref())
            .map(|a| stated_epd(a, &wide_open, object_distance_mm))
            .transpose()
            .map_err(|error| stated_error(system, StatedCondition::Aperture, error))?
            .flatten()
        {
            // The same range as a flag's (`--epd-mm`): an `ENPD 1e300` or `FNUM 1e-300` would
            // reach the analysis as a pupil no number in it can hold.
            crate::limits::check_length("the entrance-pupil diameter (mm)", epd)
                .map_err(|error| stated_error(system, StatedCondition::Aperture, error))?;
            (epd, Origin::File)
        } else {
            match claimed
                .claimed_f_number
                .filter(|f| *f > 0.0 && object_distance_mm.is_none())
            {
                // A claim a little faster than the stop allows is the nominal f-number of a
                // product; the lens as built cannot open further than its stop.
                Some(f) if efl / f <= open => (efl / f, Origin::Source),
                Some(f) => {
                    notes.push(format!(
                        "the claimed f/{f} needs a {:.3} mm entrance pupil, larger than the \
                         stop's {open:.3} mm: the lens is used wide open",
                        efl / f
                    ));
                    (open, Origin::Rule)
                }
                None => (open, Origin::Rule),
            }
        };

        // A flag's or a file's pupil is used as given (OpticStudio does the same with a file's
        // ENPD), but the stop cuts it: the paraxial numbers describe a beam that does not pass.
        if matches!(aperture_from, Origin::Flag | Origin::File) && epd_mm > open * (1.0 + 1e-9) {
            notes.push(format!(
                "the {} {epd_mm:.3} mm entrance pupil is larger than the stop's {open:.3} mm: \
                 the paraxial data are for the larger pupil, and real rays beyond the stop's \
                 own pupil are vignetted at the stop",
                if aperture_from == Origin::Flag {
                    "requested"
                } else {
                    "lens file's"
                }
            ));
        }

        let file_fields = match stated.and_then(|c| c.fields.as_ref()) {
            Some(fields) if overrides.field_deg.is_none() => {
                stated_fields(fields, &wide_open, object_distance_mm, &mut notes)
                    .map_err(|error| stated_error(system, StatedCondition::Fields, error))?
            }
            _ => None,
        };
        let (fields_deg, paraxial_field, field_from) = if let Some(deg) = overrides.field_deg {
            (fractions_of(deg), Field::Angle { deg }, Origin::Flag)
        } else if let Some((fields, field)) = file_fields {
            (fields, field, Origin::File)
        } else if let Some(deg) = claimed.claimed_half_field_deg {
            (fractions_of(deg), Field::Angle { deg }, Origin::Source)
        } else {
            let deg = rule_field_deg_for(&at, &wide_open);
            (fractions_of(deg), Field::Angle { deg }, Origin::Rule)
        };

        if field_from != Origin::Rule && object_distance_mm.is_none() {
            let passes = rule_field_deg(&at);
            if let Some(&top) = fields_deg.first()
                && top > passes
                && passes < RULE_MAX_FIELD_DEG
            {
                notes.push(format!(
                    "the real chief ray at {top:.2} deg is stopped by a clear aperture (it \
                     passes up to {passes:.2} deg): plots show what reaches the image there"
                ));
            }
        }
        let (ray_aiming, ray_aiming_from) =
            match (overrides.ray_aiming, stated.and_then(|c| c.ray_aiming)) {
                (Some(aiming), _) => (aiming, Origin::Flag),
                (None, Some(aiming)) => (aiming, Origin::File),
                (None, None) => (RayAiming::Paraxial, Origin::Rule),
            };
        let chosen = Paraxial::new(
            &at,
            &ParaxialOptions {
                object,
                aperture: Aperture::EntrancePupilDiameter(epd_mm),
                field: Field::Angle { deg: 0.0 },
                stop: overrides.stop,
            },
        )
        .map_err(|error| blame(system, aperture_from, StatedCondition::Aperture, error))?;
        Ok(DesignConditions {
            reference_nm,
            reference_from,
            wavelengths_nm,
            wavelengths_from,
            object_distance_mm,
            object_from,
            fields_deg,
            field_from,
            epd_mm,
            f_number: chosen.f_number,
            aperture_from,
            ray_aiming,
            ray_aiming_from,
            notes,
            paraxial_field,
            stop: overrides.stop,
        })
    }

    /// The stop radius real ray aiming fills ([`RealRays::filled_stop_radius`]), from the
    /// reference wavelength's analyses; None under paraxial aiming.
    pub fn aiming_stop_radius(&self, reference: &RealRays) -> Result<Option<f64>, RealRayError> {
        match self.ray_aiming {
            RayAiming::Paraxial => Ok(None),
            RayAiming::Real => reference.filled_stop_radius().map(Some),
        }
    }

    /// The analysed (top) half field, degrees.
    pub fn field_deg(&self) -> f64 {
        self.fields_deg.first().copied().unwrap_or(0.0)
    }

    /// The options of the paraxial analysis under these conditions.
    pub fn paraxial_options(&self) -> ParaxialOptions {
        ParaxialOptions {
            object: self
                .object_distance_mm
                .map_or(ObjectPosition::Infinite, |distance| {
                    ObjectPosition::Finite { distance }
                }),
            aperture: Aperture::EntrancePupilDiameter(self.epd_mm),
            field: self.paraxial_field,
            stop: self.stop,
        }
    }

    /// One line per condition with its origin, for report headers.
    pub fn summary_rows(&self) -> Vec<(String, String, &'static str)> {
        let list = |values: &[f64], unit: &str| {
            values
                .iter()
                .map(|v| format!("{v:.2}"))
                .collect::<Vec<_>>()
                .join(", ")
                + unit
        };
        vec![
            (
                "half fields".into(),
                list(&self.fields_deg, " deg"),
                self.field_from.describe(),
            ),
            (
                "entrance-pupil diameter".into(),
                format!("{:.3} mm (f/{:.2})", self.epd_mm, self.f_number),
                self.aperture_from.describe(),
            ),
            (
                "object".into(),
                self.object_distance_mm
                    .map_or("at infinity".into(), |d| crate::limits::object_place(d, 3)),
                self.object_from.describe(),
            ),
            (
                "ray aiming".into(),
                self.ray_aiming.name().into(),
                self.ray_aiming_from.describe(),
            ),
            (
                "reference wavelength".into(),
                format!("{:.2} nm", self.reference_nm),
                self.reference_from.describe(),
            ),
            (
                "wavelengths drawn".into(),
                list(&self.wavelengths_nm, " nm"),
                self.wavelengths_from.describe(),
            ),
        ]
    }
}

/// What a lens file states that a bake or a render takes where the user gives no flag: the
/// f-number of the stated aperture, the stated object distance as the focus, and the stated
/// wavelengths when there are three (R, G, B: longest first). Each is None where the file
/// states none, and the command keeps its own default.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct FileDefaults {
    pub f_number: Option<f64>,
    pub focus_mm: Option<f64>,
    pub rgb_wavelengths_nm: Option<[f64; 3]>,
    /// A stated aperture wider than the stop opens (then `f_number` is None: wide open).
    pub notes: Vec<String>,
}

/// Where a bake's or a render's focus comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FocusFrom {
    /// The file's stated object distance, where it states one.
    File,
    /// The caller's flag: the file's object distance is not the focus, and where no analysis
    /// can use it, the stated aperture is read for an object at infinity instead.
    Flag,
}

impl FileDefaults {
    pub fn of(system: &LensSystem, focus: FocusFrom) -> Result<FileDefaults, AnalysisError> {
        let Some(stated) = system.prescription.provenance.conditions.as_ref() else {
            return Ok(FileDefaults::default());
        };
        // A bake and a render take no field from the file, so a field it states cannot fail
        // them (nor cost the rule's real-ray search).
        let no_field = ConditionOverrides {
            field_deg: Some(0.0),
            ..ConditionOverrides::default()
        };
        let resolved = match DesignConditions::resolve(system, &no_field) {
            // An infinite override distance is the object at infinity (`resolve` takes 1000
            // km and beyond as infinity).
            Err(AnalysisError::Stated {
                condition: StatedCondition::Object,
                ..
            }) if focus == FocusFrom::Flag => DesignConditions::resolve(
                system,
                &ConditionOverrides {
                    object_distance_mm: Some(f64::INFINITY),
                    ..no_field
                },
            )?,
            other => other?,
        };
        let mut notes = Vec::new();
        let f_number = if resolved.aperture_from == Origin::File {
            let at = system.at_checked(resolved.reference_nm)?;
            let wide_open = Paraxial::new(
                &at,
                &ParaxialOptions {
                    aperture: Aperture::StopClearAperture,
                    ..resolved.paraxial_options()
                },
            )?
            .f_number
            .abs();
            let stated = resolved.f_number.abs();
            if stated < wide_open {
                notes.push(format!(
                    "the file's aperture (f/{stated:.3}) is wider than the stop opens: the \
                     lens is used wide open, f/{wide_open:.3}"
                ));
            }
            (stated >= wide_open).then_some(stated)
        } else {
            None
        };
        let mut listed = stated.wavelengths_nm.clone();
        listed.sort_by(|a, b| b.total_cmp(a));
        listed.dedup();
        let stated_focus = resolved
            .object_distance_mm
            .filter(|_| resolved.object_from == Origin::File && focus == FocusFrom::File);
        // Bakes and renders focus on real objects; a converging beam is no scene.
        if let Some(d) = stated_focus.filter(|d| *d < 0.0) {
            notes.push(format!(
                "the file's object lies {}: a bake or a render focuses on a real object, so \
                 it is not taken as the focus",
                crate::limits::object_place(d, 3)
            ));
        }
        Ok(FileDefaults {
            f_number,
            focus_mm: stated_focus.filter(|d| *d > 0.0),
            rgb_wavelengths_nm: <[f64; 3]>::try_from(listed.as_slice()).ok(),
            notes,
        })
    }
}

/// The analysis wavelength and where it came from: the caller's first wavelength, else the
/// file's primary (or first), else the source's design wavelength, else the system's.
pub(crate) fn reference_wavelength(
    system: &LensSystem,
    overrides: &ConditionOverrides,
) -> (f64, Origin) {
    let stated_primary = system
        .prescription
        .provenance
        .conditions
        .as_ref()
        .and_then(|c| {
            c.primary
                .and_then(|i| c.wavelengths_nm.get(i).copied())
                .or_else(|| c.wavelengths_nm.first().copied())
        });
    match (
        overrides.wavelengths_nm.first(),
        stated_primary,
        system.prescription.provenance.design_wavelength_nm,
    ) {
        (Some(&w), _, _) => (w, Origin::Flag),
        (None, Some(w), _) => (w, Origin::File),
        (None, None, Some(w)) => (w, Origin::Source),
        (None, None, None) => (system.design_wavelength_nm(), Origin::Rule),
    }
}

/// `error` as the fault of the file's `condition` where the value came from the file and the
/// error is about it; a lens with no focal points (afocal) fails whatever the file states.
fn blame(
    system: &LensSystem,
    origin: Origin,
    condition: StatedCondition,
    error: ParaxialError,
) -> AnalysisError {
    let about_condition = match condition {
        StatedCondition::Object => matches!(
            error,
            ParaxialError::ObjectNotInFront { .. }
                | ParaxialError::InvalidObjectDistance { .. }
                | ParaxialError::ObjectAtEntrancePupil
                | ParaxialError::ObjectAtFrontFocalPlane
                | ParaxialError::VirtualImage { .. }
        ),
        StatedCondition::Aperture => {
            matches!(error, ParaxialError::InvalidEntrancePupilDiameter { .. })
        }
        StatedCondition::Fields => true,
    };
    if origin == Origin::File && about_condition {
        stated_error(system, condition, error)
    } else {
        error.into()
    }
}

fn stated_error(
    system: &LensSystem,
    condition: StatedCondition,
    error: impl Into<AnalysisError>,
) -> AnalysisError {
    AnalysisError::Stated {
        condition,
        at: system
            .condition_locations
            .get(&condition)
            .cloned()
            .unwrap_or_default(),
        error: Box::new(error.into()),
    }
}

/// The top field, 0.7 of it and the axis.
fn fractions_of(top_deg: f64) -> Vec<f64> {
    FIELD_FRACTIONS.iter().map(|f| f * top_deg).collect()
}

/// The lens's prescription with the conditions lensbake analyses it under stated the way any
/// lens file can state them: the claims of its source (a claimed f-number its stop allows, a
/// claimed half field at the field fractions) as stated conditions, and a working f-number
/// (CODE V `FNO` of a finite object) as the entrance-pupil diameter it gives. A format that
/// holds neither (a Zemax file) then analyses as the lens does. Unchanged where nothing needs
/// restating, or the conditions do not resolve.
pub fn stated_as_analysed(system: &LensSystem) -> Prescription {
    let mut prescription = system.prescription.clone();
    let Ok(resolved) = DesignConditions::resolve(system, &ConditionOverrides::default()) else {
        return prescription;
    };
    let claimed_f_number = prescription.provenance.claimed_f_number;
    let mut conditions = prescription
        .provenance
        .conditions
        .clone()
        .unwrap_or_default();
    let mut changed = false;
    if let (Origin::Source, Some(f)) = (resolved.aperture_from, claimed_f_number) {
        conditions.aperture = Some(ApertureSpec::FNumber(f));
        changed = true;
    }
    if let Some(ApertureSpec::WorkingFNumber(_)) = conditions.aperture {
        conditions.aperture = Some(ApertureSpec::EntrancePupilDiameter(resolved.epd_mm));
        changed = true;
    }
    if resolved.field_from == Origin::Source {
        let y: Vec<f64> = resolved.fields_deg.iter().rev().copied().collect();
        conditions.fields = Some(FieldSpec {
            kind: FieldKind::AngleDeg,
            x: vec![0.0; y.len()],
            weights: vec![1.0; y.len()],
            y,
        });
        changed = true;
    }
    if changed {
        prescription.provenance.conditions = Some(conditions);
    }
    prescription
}

/// The rule: the largest half field whose real chief ray, aimed at the stop centre, passes
/// every clear aperture at the reference wavelength, at most [`RULE_MAX_FIELD_DEG`].
pub fn rule_field_deg(at: &SystemAt) -> f64 {
    traceable_field_deg(&Tracer::new(at), FIELD_SCAN_DEG).min(RULE_MAX_FIELD_DEG)
}

/// The rule for the object of `paraxial` (computed from `at`): at infinity [`rule_field_deg`];
/// for a finite object, real or virtual, the largest angle at the entrance pupil whose object
/// point's real chief ray passes, traced from that point.
fn rule_field_deg_for(at: &SystemAt, paraxial: &Paraxial) -> f64 {
    let Some(distance) = paraxial.object_distance else {
        return rule_field_deg(at);
    };
    let tracer = Tracer::new(at);
    let start_z = tracer.front_start_z();
    traceable_field_deg_from(&tracer, FIELD_SCAN_DEG, |deg| {
        RaySource::finite_object(distance, paraxial.field_at_angle(deg), start_z)
    })
    .min(RULE_MAX_FIELD_DEG)
}

fn drawn_wavelengths(
    system: &LensSystem,
    overrides: &ConditionOverrides,
    stated: Option<&[f64]>,
    reference_nm: f64,
) -> (Vec<f64>, Origin) {
    if !overrides.wavelengths_nm.is_empty() {
        return (overrides.wavelengths_nm.clone(), Origin::Flag);
    }
    // Curves of one colour drawn three times say nothing: a lens of constant indices draws
    // its reference wavelength alone whatever the file lists.
    if !system.disperses() {
        return (vec![reference_nm], Origin::Rule);
    }
    match stated.filter(|w| !w.is_empty()) {
        Some(listed) => {
            let mut drawn = listed.to_vec();
            drawn.sort_by(f64::total_cmp);
            drawn.dedup();
            (drawn, Origin::File)
        }
        None => {
            let mut drawn = vec![F_LINE_NM, reference_nm, C_LINE_NM];
            drawn.dedup();
            (drawn, Origin::Rule)
        }
    }
}

/// The entrance-pupil diameter a stated aperture gives: none where the stop's own aperture
/// sets the beam (Zemax's float by stop size), an error where the stated value can give no
/// beam.
fn stated_epd(
    aperture: &ApertureSpec,
    probe: &Paraxial,
    object_distance_mm: Option<f64>,
) -> Result<Option<f64>, AnalysisError> {
    let unusable = |reason: String| Err(AnalysisError::UnusableAperture { reason });
    let epd = match (aperture, object_distance_mm) {
        (ApertureSpec::FloatByStop, _) => return Ok(None),
        (ApertureSpec::EntrancePupilDiameter(d), _) => *d,
        (ApertureSpec::FNumber(f), _) => probe.first_order.efl.abs() / f,
        // The marginal ray scales with the pupil: F = 1 / (2 n' u') fixes u', hence the pupil.
        (ApertureSpec::WorkingFNumber(f), _) => {
            let slope = probe.marginal.image_slope().abs();
            if !(slope > 0.0) {
                return unusable(format!(
                    "a working f-number ({f}) needs a marginal ray that converges to the image, \
                     and this lens's leaves it parallel"
                ));
            }
            // The image-space index is negative after an odd number of mirrors; the working
            // f-number 1 / (2 |n'| |u'|) is not (a paraboloid's FNO 8 gave a pupil of -25 mm).
            let wanted = 1.0 / (2.0 * probe.first_order.image_index.abs() * f);
            probe.entrance_pupil.diameter * wanted / slope
        }
        (ApertureSpec::ObjectNumericalAperture(na), Some(distance)) => {
            let n = probe.first_order.object_index;
            if !(*na < n) {
                return unusable(format!(
                    "an object-space numerical aperture of {na} needs an object-space index \
                     above it (n = {n:.6})"
                ));
            }
            2.0 * (distance + probe.entrance_pupil.z).abs() * (na / n).asin().tan()
        }
        (ApertureSpec::ObjectNumericalAperture(na), None) => {
            return unusable(format!(
                "an object-space numerical aperture ({na}) needs an object at a finite \
                 distance, and the object is at infinity"
            ));
        }
    };
    Ok(Some(epd))
}

/// The stated field points as half-field angles (top first) and the analysed paraxial field.
/// An on-axis-only list, or a kind this module cannot convert, gives none (the next source
/// decides), with a note.
fn stated_fields(
    fields: &FieldSpec,
    probe: &Paraxial,
    object_distance_mm: Option<f64>,
    notes: &mut Vec<String>,
) -> Result<Option<(Vec<f64>, Field)>, ParaxialError> {
    let radial: Vec<f64> = fields
        .x
        .iter()
        .zip(&fields.y)
        .map(|(x, y)| match fields.kind {
            // Angles combine as tangents: (x, y) is the direction (tan x, tan y, 1).
            FieldKind::AngleDeg => x
                .to_radians()
                .tan()
                .hypot(y.to_radians().tan())
                .atan()
                .to_degrees(),
            _ => x.hypot(*y),
        })
        .collect();
    let largest = radial.iter().copied().fold(0.0, f64::max);
    // Checked on the components: the tangents of 95 and 85 degrees differ only in sign. Two
    // components below 90 combine below 90 (both one ulp short of it give 89.99999999999999).
    if fields.kind == FieldKind::AngleDeg
        && let Some(&deg) = fields.x.iter().chain(&fields.y).find(|v| !(v.abs() < 90.0))
    {
        return Err(ParaxialError::InvalidFieldAngle { deg });
    }
    if !largest.is_finite() {
        return Err(ParaxialError::InvalidObjectHeight { height: largest });
    }
    if largest <= 0.0 {
        notes
            .push("the file's fields are all on axis: the field comes from the next source".into());
        return Ok(None);
    }
    let efl = probe.first_order.efl.abs();
    let pupil_z = probe.entrance_pupil.z;
    let (to_angle, field): (Box<dyn Fn(f64) -> f64>, Field) =
        match (fields.kind, object_distance_mm) {
            (FieldKind::AngleDeg, _) => (Box::new(|a| a), Field::Angle { deg: largest }),
            // A virtual object lies behind the entrance pupil: the angle is the same magnitude.
            (FieldKind::ObjectHeight, Some(d)) => (
                Box::new(move |h| (h / (d + pupil_z).abs()).atan().to_degrees()),
                Field::ObjectHeight { mm: largest },
            ),
            (FieldKind::ObjectHeight, None) => return Err(ParaxialError::ObjectHeightAtInfinity),
            (FieldKind::ParaxialImageHeight, None) => {
                let angle = move |h: f64| (h / efl).atan().to_degrees();
                (
                    Box::new(angle),
                    Field::Angle {
                        deg: angle(largest),
                    },
                )
            }
            (FieldKind::ParaxialImageHeight, Some(d)) => {
                let Some(m) = probe.magnification.filter(|m| *m != 0.0) else {
                    return Ok(None);
                };
                (
                    Box::new(move |h| (h / m.abs() / (d + pupil_z).abs()).atan().to_degrees()),
                    Field::ObjectHeight {
                        mm: largest / m.abs(),
                    },
                )
            }
            (kind, _) => {
                notes.push(format!(
                    "the file's {kind:?} fields need a real-ray search this build does not do: \
                 the field comes from the next source"
                ));
                return Ok(None);
            }
        };
    let mut angles: Vec<f64> = radial.iter().map(|&v| to_angle(v)).collect();
    angles.sort_by(|a, b| b.total_cmp(a));
    angles.dedup();
    Ok(Some((angles, field)))
}
