//! The `analyze` report of an afocal system (a telescope, a beam expander, a window or a fold
//! mirror): angular magnification, pupils and eye relief, object and apparent field, Seidel
//! sums with their angular forms, real-ray angular distortion and wave optics at infinity.
//!
//! Conditions, each with where it came from as in [`super::DesignConditions`]: the wavelength
//! as there; the object at infinity (a collimated beam is what an afocal system takes); the
//! entrance pupil from the flag, else the file's EPD, else the stop's clear aperture; the half
//! field from the flag, else the file's largest angle, else the source's claim, else the
//! largest paraxially unvignetted one (at most [`RULE_MAX_FIELD_DEG`]).

use super::conditions::reference_wavelength;
use super::{AnalysisError, AnalyzeOptions, Origin, RULE_MAX_FIELD_DEG, first_non_finite};
use crate::paraxial::{AfocalParaxial, Pupil, is_afocal};
use crate::prescription::{ApertureSpec, FieldKind};
use crate::seidel::{
    ColourTerms, IndexDifferences, SeidelTerms, SurfaceTerms, WavefrontCoefficients, surface_terms,
};
use crate::system::{LensSystem, SystemAt};
use crate::trace::{Apertures, RaySource, Tracer, Travel, aim_at_stop};
use crate::wave::{AngularMtf, Sampling, afocal_wavefront, frequencies_to};
use serde::Serialize;

/// Fractions of the field at which the real chief ray's apparent angle is reported.
const REPORT_FIELD_FRACTIONS: [f64; 4] = [0.25, 0.5, 0.75, 1.0];
/// MTF frequencies reported, as fractions of the cutoff.
const MTF_POINTS: usize = 6;

/// Whether `analyze` should take `system` as afocal under `options`: its power at the analysis
/// wavelength is zero to rounding ([`is_afocal`]).
pub fn is_afocal_lens(
    system: &LensSystem,
    options: &AnalyzeOptions,
) -> Result<bool, AnalysisError> {
    let (wavelength_nm, _) = reference_wavelength(system, &options.overrides());
    Ok(is_afocal(&system.at_checked(wavelength_nm)?))
}

/// Third-order sums of an afocal system and their angular forms.
///
/// The sums S_I..S_V and the wavefront coefficients are Welford's, as for a focal lens. A focal
/// lens's transverse forms divide by the image-space marginal slope, which is zero here; the
/// angular forms replace them: a wavefront error W(ρ) over an exit beam of half-height h' turns
/// a ray by δu' = -(1/(n' h')) dW/dρ, so each transverse coefficient 1/(2 n' u') becomes
/// -1/(2 n' h') (n' and h' signed, the slopes those of the lens frame).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AfocalSeidel {
    pub surfaces: Vec<SurfaceTerms>,
    pub sums: SeidelTerms,
    pub wavefront: WavefrontCoefficients,
    /// Sum of c Δ(1/n), 1/mm (CODE V PTZ).
    pub ptz: f64,
    pub colour: Option<ColourTerms>,
    pub colour_wavelengths_nm: Option<[f64; 2]>,
    /// Angular ray errors at the pupil edge and the analysed field, mrad.
    pub angular: AngularAberrations,
}

/// Third-order angular ray errors in image space, mrad: spherical, tangential coma, tangential
/// and sagittal astigmatic focus (each with Petzval), Petzval, distortion, and the primary
/// colours (short minus long wavelength).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct AngularAberrations {
    pub spherical: f64,
    pub tangential_coma: f64,
    pub tangential_astigmatism: f64,
    pub sagittal_astigmatism: f64,
    pub petzval: f64,
    pub distortion: f64,
    pub axial_colour: Option<f64>,
    pub lateral_colour: Option<f64>,
}

/// The real chief ray of one field: its apparent angle against the paraxial one.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ApparentFieldPoint {
    pub field_deg: f64,
    /// Real chief ray's angle with the axis after the last surface, in the sense light travels.
    pub apparent_deg: f64,
    /// atan(gamma tan(field)).
    pub paraxial_apparent_deg: f64,
    /// 100 (tan(real) - gamma tan(field)) / (gamma tan(field)).
    pub distortion_percent: f64,
}

/// Wave optics at infinity of one field.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AfocalWaveField {
    pub field_deg: f64,
    pub rms_waves: f64,
    pub pv_waves: f64,
    pub strehl: f64,
    pub rms_angular_spot_mrad: f64,
    pub mtf: AngularMtf,
}

/// Everything `lensbake analyze` reports for an afocal system.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AfocalAnalysis {
    pub lens: String,
    /// Always true: tells this report from a focal one in JSON.
    pub afocal: bool,
    pub wavelength_nm: f64,
    pub wavelength_from: Origin,
    pub epd_mm: f64,
    pub aperture_from: Origin,
    pub field_deg: f64,
    pub field_from: Origin,
    pub notes: Vec<String>,
    pub angular_magnification: f64,
    pub beam_magnification: f64,
    pub residual_power: f64,
    /// 1-based.
    pub stop_surface: usize,
    pub entrance_pupil: Pupil,
    pub exit_pupil: Option<Pupil>,
    pub eye_relief: Option<f64>,
    pub apparent_field_deg: f64,
    pub max_field_deg_paraxial: Option<f64>,
    pub lagrange_invariant: f64,
    pub object_index: f64,
    pub image_index: f64,
    pub z_last_vertex: f64,
    pub seidel: AfocalSeidel,
    pub apparent_field: Vec<ApparentFieldPoint>,
    /// On axis and at the analysed field; empty when the wave optics cannot be traced (a note
    /// says why).
    pub wave: Vec<AfocalWaveField>,
}

/// Analyses an afocal `system` under `options` (the object at infinity). Fails with
/// [`crate::paraxial::ParaxialError::NotAfocal`] where the system has power ([`crate::analysis::analyze`]
/// takes it).
///
/// ```
/// use lensbake::analysis::{AnalyzeOptions, analyze_afocal};
/// use lensbake::prescription::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
/// use lensbake::system::LensSystem;
///
/// // A 10x Keplerian telescope of two ideal lenses, f = 100 and 10 mm, the stop on the first.
/// let telescope = Prescription {
///     surfaces: vec![
///         Surface { stop: Some(StopShape::Circle), ..Surface::open(Shape::IdealLens { focal_length: 100.0 }, 110.0, Medium::Air, 10.0) },
///         Surface::open(Shape::IdealLens { focal_length: 10.0 }, 20.0, Medium::Air, 5.0),
///     ],
///     provenance: Provenance::default(),
///     object_medium: Medium::Air,
/// };
/// let system = LensSystem::from_prescription(telescope)?;
/// let options = AnalyzeOptions { epd_mm: Some(20.0), field_deg: Some(1.0), ..Default::default() };
/// let a = analyze_afocal(&system, &options)?;
/// assert!((a.angular_magnification + 10.0).abs() < 1e-12);
/// // The eye goes where the eyepiece images the objective: 11 mm behind it, 2 mm across.
/// assert!((a.eye_relief.unwrap() - 11.0).abs() < 1e-12);
/// assert!((a.exit_pupil.unwrap().diameter - 2.0).abs() < 1e-12);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn analyze_afocal(
    system: &LensSystem,
    options: &AnalyzeOptions,
) -> Result<AfocalAnalysis, AnalysisError> {
    let overrides = options.overrides();
    let (wavelength_nm, wavelength_from) = reference_wavelength(system, &overrides);
    let at = system.at_checked(wavelength_nm)?;
    let stated = system.prescription.provenance.conditions.as_ref();
    let mut notes = Vec::new();
    if let Some(distance) = options.object_distance_mm {
        return Err(AnalysisError::AfocalFiniteObject { distance });
    }
    if let Some(distance) = stated.and_then(|c| c.object_distance_mm) {
        notes.push(format!(
            "the file's object lies {}: an afocal system is analysed with a collimated beam \
             from infinity, which it returns collimated",
            crate::limits::object_place(distance, 3)
        ));
    }

    let (epd_mm, aperture_from) = match (options.epd_mm, stated.and_then(|c| c.aperture.as_ref())) {
        (Some(epd), _) => (Some(epd), Origin::Flag),
        (None, Some(ApertureSpec::EntrancePupilDiameter(epd))) => (Some(*epd), Origin::File),
        (None, Some(ApertureSpec::FloatByStop) | None) => (None, Origin::Rule),
        (None, Some(other)) => {
            notes.push(format!(
                "the file's aperture ({other:?}) needs a focal length or a finite object, which \
                 an afocal system has not: the stop's clear aperture sets the beam"
            ));
            (None, Origin::Rule)
        }
    };
    if let Some(epd) = epd_mm.filter(|epd| epd.is_finite() && *epd > 0.0) {
        crate::limits::check_length("the entrance-pupil diameter (mm)", epd)?;
    }
    let probe = AfocalParaxial::new(&at, epd_mm, 0.0, options.stop)?;
    // The stop's own pupil: the probe's, unless an EPD was asked for.
    let open = match epd_mm {
        None => probe.entrance_pupil.diameter,
        Some(_) => {
            AfocalParaxial::new(&at, None, 0.0, options.stop)?
                .entrance_pupil
                .diameter
        }
    };
    if probe.entrance_pupil.diameter > open * (1.0 + 1e-9) {
        notes.push(format!(
            "the {} {:.3} mm entrance pupil is larger than the stop's {open:.3} mm: the paraxial \
             data are for the larger pupil, and real rays beyond the stop's own pupil are \
             vignetted at the stop",
            aperture_from.describe(),
            probe.entrance_pupil.diameter
        ));
    }
    let (field_deg, field_from) = afocal_field(system, options, &probe, &mut notes);
    let paraxial = AfocalParaxial::new(&at, epd_mm, field_deg, options.stop)?;

    let colour = IndexDifferences::fraunhofer(system);
    let seidel = afocal_seidel(&at, &paraxial, colour.as_ref());
    let apparent_field = apparent_field(&at, &paraxial, &mut notes);
    let wave = wave_fields(&at, &paraxial, &mut notes);
    let analysis = AfocalAnalysis {
        lens: system.prescription.provenance.title.clone(),
        afocal: true,
        wavelength_nm,
        wavelength_from,
        epd_mm: paraxial.entrance_pupil.diameter,
        aperture_from,
        field_deg,
        field_from,
        notes,
        angular_magnification: paraxial.angular_magnification,
        beam_magnification: paraxial.beam_magnification,
        residual_power: paraxial.residual_power,
        stop_surface: paraxial.stop + 1,
        entrance_pupil: paraxial.entrance_pupil,
        exit_pupil: paraxial.exit_pupil,
        eye_relief: paraxial.eye_relief,
        apparent_field_deg: paraxial.apparent_field_deg,
        max_field_deg_paraxial: paraxial.max_field_angle_deg,
        lagrange_invariant: paraxial.lagrange_invariant,
        object_index: paraxial.object_index,
        image_index: paraxial.image_index,
        z_last_vertex: at.last_vertex_z(),
        seidel,
        apparent_field,
        wave,
    };
    match first_non_finite(&analysis) {
        Some(quantity) => Err(AnalysisError::NonFinite { quantity }),
        None => Ok(analysis),
    }
}

/// The analysed half field and where it came from.
fn afocal_field(
    system: &LensSystem,
    options: &AnalyzeOptions,
    probe: &AfocalParaxial,
    notes: &mut Vec<String>,
) -> (f64, Origin) {
    if let Some(deg) = options.field_deg {
        return (deg, Origin::Flag);
    }
    let provenance = &system.prescription.provenance;
    match provenance
        .conditions
        .as_ref()
        .and_then(|c| c.fields.as_ref())
    {
        Some(fields) if fields.kind == FieldKind::AngleDeg => {
            let largest = fields
                .x
                .iter()
                .zip(&fields.y)
                .map(|(x, y)| {
                    x.to_radians()
                        .tan()
                        .hypot(y.to_radians().tan())
                        .atan()
                        .to_degrees()
                })
                .fold(0.0, f64::max);
            if largest > 0.0 {
                return (largest, Origin::File);
            }
        }
        Some(fields) => notes.push(format!(
            "the file's {:?} fields need a focal length or a finite object: the field comes \
             from the next source",
            fields.kind
        )),
        None => {}
    }
    if let Some(deg) = provenance.claimed_half_field_deg {
        return (deg, Origin::Source);
    }
    let deg = probe
        .max_field_angle_deg
        .map_or(RULE_MAX_FIELD_DEG, |d| d.min(RULE_MAX_FIELD_DEG));
    (deg, Origin::Rule)
}

fn afocal_seidel(
    at: &SystemAt,
    paraxial: &AfocalParaxial,
    colour: Option<&IndexDifferences>,
) -> AfocalSeidel {
    let surfaces = surface_terms(
        at,
        &paraxial.marginal,
        &paraxial.chief,
        paraxial.lagrange_invariant,
        colour,
    );
    let sums: SeidelTerms = surfaces.iter().map(|s| s.terms).sum();
    let colour_sums: Option<ColourTerms> =
        colour.map(|_| surfaces.iter().filter_map(|s| s.colour).sum());
    // The angular forms are the transverse ones with the image-space slope u' replaced by
    // -h' (in thousandths, for mrad).
    let u_equivalent = -paraxial.marginal.last_height() / 1e3;
    let n_image = at.image_index();
    let t = sums.transverse(n_image, u_equivalent);
    let colour_angular = colour_sums.map(|c| c.transverse(n_image, u_equivalent));
    AfocalSeidel {
        wavefront: sums.wavefront(at.wavelength_nm),
        ptz: surfaces.iter().map(|s| s.ptz).sum(),
        colour: colour_sums,
        colour_wavelengths_nm: colour.map(|dn| [dn.short_nm, dn.long_nm]),
        angular: AngularAberrations {
            spherical: t.tsa,
            tangential_coma: t.tco,
            tangential_astigmatism: t.tas,
            sagittal_astigmatism: t.sas,
            petzval: t.ptb,
            distortion: t.dst,
            axial_colour: colour_angular.map(|c| c.ax),
            lateral_colour: colour_angular.map(|c| c.lat),
        },
        sums,
        surfaces,
    }
}

/// The real chief ray's apparent angle at fractions of the field; a field whose chief ray
/// cannot be aimed or traced is left out with a note.
fn apparent_field(
    at: &SystemAt,
    paraxial: &AfocalParaxial,
    notes: &mut Vec<String>,
) -> Vec<ApparentFieldPoint> {
    let tracer = Tracer::new(at);
    let gamma = paraxial.angular_magnification;
    REPORT_FIELD_FRACTIONS
        .iter()
        .map(|f| f * paraxial.field_angle_deg)
        .filter(|deg| *deg != 0.0)
        .filter_map(|field_deg| {
            let source = RaySource::collimated(field_deg, tracer.front_start_z());
            let traced = aim_at_stop(&tracer, &source, [0.0, 0.0])
                .map_err(|e| e.to_string())
                .and_then(|ray| {
                    let traced = tracer.trace_with(ray, Travel::Forward, Apertures::Ignored);
                    if traced.outcome.is_ok() {
                        Ok(traced.ray.direction())
                    } else {
                        Err(format!("{:?}", traced.outcome))
                    }
                });
            match traced {
                Ok(d) => {
                    let tan_real = d[1] / d[2].abs();
                    let tan_paraxial = gamma * field_deg.to_radians().tan();
                    Some(ApparentFieldPoint {
                        field_deg,
                        apparent_deg: tan_real.atan().to_degrees(),
                        paraxial_apparent_deg: tan_paraxial.atan().to_degrees(),
                        distortion_percent: 100.0 * (tan_real - tan_paraxial) / tan_paraxial,
                    })
                }
                Err(why) => {
                    notes.push(format!(
                        "the real chief ray at {field_deg:.4} deg does not pass ({why}): no \
                         apparent angle there"
                    ));
                    None
                }
            }
        })
        .collect()
}

/// Wave optics on axis and at the analysed field.
fn wave_fields(
    at: &SystemAt,
    paraxial: &AfocalParaxial,
    notes: &mut Vec<String>,
) -> Vec<AfocalWaveField> {
    let mut fields = vec![0.0];
    if paraxial.field_angle_deg != 0.0 {
        fields.push(paraxial.field_angle_deg);
    }
    let mut out = Vec::new();
    for field_deg in fields {
        let measured =
            afocal_wavefront(at, paraxial, field_deg, Sampling::default()).and_then(|wave| {
                let frequencies = frequencies_to(wave.cutoff_per_mrad, MTF_POINTS);
                Ok(AfocalWaveField {
                    field_deg,
                    rms_waves: wave.stats.rms_waves,
                    pv_waves: wave.stats.pv_waves,
                    strehl: wave.stats.strehl,
                    rms_angular_spot_mrad: wave.rms_angular_spot_mrad,
                    mtf: wave.mtf(&frequencies)?,
                })
            });
        match measured {
            Ok(field) => out.push(field),
            Err(error) => notes.push(format!("wave optics at {field_deg:.4} deg: {error}")),
        }
    }
    out
}
