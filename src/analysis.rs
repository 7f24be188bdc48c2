//! The `analyze` report: first-order data, pupils, paraxial rays and Seidel sums of one lens
//! at one wavelength, field, aperture and object distance, as one serialisable value.

mod afocal;
mod conditions;
pub mod placed;

pub use afocal::{
    AfocalAnalysis, AfocalSeidel, AfocalWaveField, AngularAberrations, ApparentFieldPoint,
    analyze_afocal, is_afocal_lens,
};
pub use conditions::{
    ConditionOverrides, DesignConditions, FIELD_FRACTIONS, FileDefaults, FocusFrom, Origin,
    RULE_MAX_FIELD_DEG, rule_field_deg, stated_as_analysed,
};

use crate::paraxial::{Paraxial, ParaxialError, Pupil, RayAtSurface, StopChoice};
use crate::prescription::{PrescriptionError, RayAiming};
use crate::seidel::{IndexDifferences, Seidel};
use crate::system::LensSystem;
use crate::trace::analyses::{RealRays, RealReport};
use serde::Serialize;

/// What to analyse; `None` takes the lens's design conditions ([`DesignConditions`]: the
/// file's stated conditions, else the source's claims, else the rule of docs/conditions.md).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct AnalyzeOptions {
    /// Default: the file's primary wavelength, else the design wavelength (587.56 nm when the
    /// lens states none).
    pub wavelength_nm: Option<f64>,
    /// Half-field angle; default: the file's largest field (angle, object height or paraxial
    /// image height), else the source's claimed half field, else the largest angle whose real
    /// chief ray passes every clear aperture, at most 45 degrees.
    pub field_deg: Option<f64>,
    /// Entrance-pupil diameter; default: the file's aperture (EPD, F-number or object NA), else
    /// the source's claimed f-number where the stop allows it, else the stop's clear aperture
    /// imaged to object space.
    pub epd_mm: Option<f64>,
    /// Object distance from surface 1; default: the file's, else infinity.
    pub object_distance_mm: Option<f64>,
    pub stop: StopChoice,
    /// How the real rays of distortion and LSA aim a pupil coordinate; default: the file's
    /// (Zemax `RAIM`), else paraxial.
    pub ray_aiming: Option<RayAiming>,
}

#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum AnalysisError {
    #[error(transparent)]
    Limit(#[from] crate::limits::LimitError),
    #[error(transparent)]
    Wavelength(#[from] PrescriptionError),
    #[error(transparent)]
    Paraxial(#[from] ParaxialError),
    /// A condition the lens file states cannot be used, located where the file states it
    /// ([`LensSystem::condition_locations`]).
    #[error("{}the lens file's {}: {error}", at.prefix(), condition.describe())]
    Stated {
        condition: crate::prescription::StatedCondition,
        at: crate::prescription::Location,
        #[source]
        error: Box<AnalysisError>,
    },
    #[error("{reason}")]
    UnusableAperture { reason: String },
    #[error("real ray aiming: {0}")]
    Aiming(#[from] crate::trace::analyses::RealRayError),
    #[error(
        "an afocal system is analysed with a collimated beam from infinity; the object lies \
         {distance} mm in front of surface 1 (give no object distance, or analyse the system \
         with a focusing lens after it)"
    )]
    AfocalFiniteObject { distance: f64 },
    #[error("{quantity} is not finite: the lens is too close to a degenerate case to analyse")]
    NonFinite { quantity: String },
}

/// First-order data as `lensbake analyze --json` prints it (mm, absolute z in the lens frame).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FirstOrderReport {
    pub efl: f64,
    pub bfl: f64,
    pub ffl: f64,
    pub z_front_focal: f64,
    pub z_rear_focal: f64,
    pub z_front_principal: f64,
    pub z_rear_principal: f64,
    pub z_front_nodal: f64,
    pub z_rear_nodal: f64,
    pub z_paraxial_image: f64,
    /// 1-based.
    pub stop_surface: usize,
    pub entrance_pupil: Pupil,
    /// null when the exit pupil is at infinity (image-space telecentric).
    pub exit_pupil: Option<Pupil>,
    pub f_number: f64,
    pub lagrange_invariant: f64,
    /// 1/mm.
    pub power: f64,
    pub fl_object: f64,
    pub working_f_number: f64,
    /// Lateral magnification; null for an object at infinity.
    pub magnification: Option<f64>,
    /// Paraxial chief-ray height in the paraxial image plane.
    pub image_height: f64,
    /// Height of the object point at the analysed field; null for an object at infinity.
    pub object_height: Option<f64>,
    /// Largest half field whose paraxial chief ray passes every clear aperture; null when no
    /// aperture limits it.
    pub max_field_deg_paraxial: Option<f64>,
    pub object_index: f64,
    pub image_index: f64,
    pub z_last_vertex: f64,
}

/// Paraxial marginal and chief ray at every surface.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RaysReport {
    pub marginal: Vec<RayAtSurface>,
    pub chief: Vec<RayAtSurface>,
}

/// Everything `lensbake analyze` reports.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Analysis {
    pub lens: String,
    /// The conditions analysed, each with where it came from.
    pub conditions: DesignConditions,
    pub wavelength_nm: f64,
    pub field_deg: f64,
    /// null for an object at infinity.
    pub object_distance_mm: Option<f64>,
    pub first_order: FirstOrderReport,
    pub seidel: Seidel,
    pub paraxial_rays: RaysReport,
    /// Real-ray distortion and longitudinal spherical aberration.
    pub real: RealReport,
}

impl AnalyzeOptions {
    /// The same choices as overrides of the lens's design conditions.
    pub fn overrides(&self) -> ConditionOverrides {
        ConditionOverrides {
            wavelengths_nm: self.wavelength_nm.into_iter().collect(),
            field_deg: self.field_deg,
            epd_mm: self.epd_mm,
            object_distance_mm: self.object_distance_mm,
            stop: self.stop,
            ray_aiming: self.ray_aiming,
        }
    }
}

/// Analyses `system` under `options` ([`AnalyzeOptions::default`]: the lens's own design
/// conditions). The report's `lens` is the prescription's title; set the field to name the lens
/// otherwise (the command line puts the file or bundled name there).
///
/// ```
/// use lensbake::{AnalyzeOptions, LoadOptions, analyze, load_lens};
///
/// let lens = load_lens("cooke-triplet", &LoadOptions::default())?;
/// let wide_open = analyze(&lens.system, &AnalyzeOptions::default())?;
/// let stopped = analyze(&lens.system, &AnalyzeOptions { epd_mm: Some(5.0), ..Default::default() })?;
/// // EFL does not depend on the aperture; the f-number is EFL / EPD.
/// assert_eq!(wide_open.first_order.efl, stopped.first_order.efl);
/// assert!((stopped.first_order.f_number - stopped.first_order.efl / 5.0).abs() < 1e-12);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn analyze(system: &LensSystem, options: &AnalyzeOptions) -> Result<Analysis, AnalysisError> {
    // A pupil that is not a positive number is the paraxial module's error; the limit bounds
    // the sizes it would accept.
    if let Some(epd) = options.epd_mm.filter(|epd| epd.is_finite() && *epd > 0.0) {
        crate::limits::check_length("the entrance-pupil diameter (mm)", epd)?;
    }
    let conditions = DesignConditions::resolve(system, &options.overrides())?;
    let wavelength_nm = conditions.reference_nm;
    let at = system.at_checked(wavelength_nm)?;
    let paraxial = Paraxial::new(&at, &conditions.paraxial_options())?;
    let colour = IndexDifferences::fraunhofer(system);
    let seidel = Seidel::new(&at, &paraxial, colour.as_ref());
    let mut real_rays = RealRays::new(&at, paraxial.clone());
    let aiming = conditions.aiming_stop_radius(&real_rays);
    if let Ok(Some(radius)) = aiming {
        real_rays = real_rays.aimed_at_stop(radius);
    }
    let mut real = RealReport::new(&real_rays);
    if let Err(error) = aiming {
        real.notes.push(format!(
            "real ray aiming: {error}; distortion and LSA are traced with paraxial aiming"
        ));
    }
    let f = &paraxial.first_order;
    let analysis = Analysis {
        lens: system.prescription.provenance.title.clone(),
        conditions,
        wavelength_nm,
        field_deg: paraxial.field_angle_deg,
        object_distance_mm: paraxial.object_distance,
        first_order: FirstOrderReport {
            efl: f.efl,
            bfl: f.bfl,
            ffl: f.ffl,
            z_front_focal: f.z_front_focal,
            z_rear_focal: f.z_rear_focal,
            z_front_principal: f.z_front_principal,
            z_rear_principal: f.z_rear_principal,
            z_front_nodal: f.z_front_nodal,
            z_rear_nodal: f.z_rear_nodal,
            z_paraxial_image: paraxial.z_image,
            stop_surface: paraxial.stop_surface(),
            entrance_pupil: paraxial.entrance_pupil,
            exit_pupil: paraxial.exit_pupil,
            f_number: paraxial.f_number,
            lagrange_invariant: paraxial.lagrange_invariant,
            power: f.power,
            fl_object: f.fl_object,
            working_f_number: paraxial.working_f_number,
            magnification: paraxial.magnification,
            image_height: paraxial.image_height,
            object_height: paraxial.object_height,
            max_field_deg_paraxial: paraxial.max_field_angle_deg,
            object_index: f.object_index,
            image_index: f.image_index,
            z_last_vertex: f.z_last_vertex,
        },
        seidel,
        paraxial_rays: RaysReport {
            marginal: paraxial.marginal.surfaces.clone(),
            chief: paraxial.chief.surfaces.clone(),
        },
        real,
    };
    match first_non_finite(&analysis) {
        Some(quantity) => Err(AnalysisError::NonFinite { quantity }),
        None => Ok(analysis),
    }
}

/// Path of the first NaN or infinite number in `value`, if any. JSON cannot carry such values
/// (serde_json prints them as null, indistinguishable from a missing value), so the report is
/// checked as a whole: RON keeps them as NaN/inf and its value tree names where they sit.
fn first_non_finite(value: &impl Serialize) -> Option<String> {
    fn walk(value: &ron::Value, path: &str) -> Option<String> {
        match value {
            ron::Value::Number(n) => (!n.into_f64().is_finite()).then(|| path.to_string()),
            ron::Value::Option(Some(inner)) => walk(inner, path),
            ron::Value::Seq(items) => items
                .iter()
                .enumerate()
                .find_map(|(i, v)| walk(v, &format!("{path}[{i}]"))),
            ron::Value::Map(map) => map.iter().find_map(|(key, v)| {
                let key = match key {
                    ron::Value::String(s) => s.clone(),
                    other => format!("{other:?}"),
                };
                walk(v, &format!("{path}.{key}"))
            }),
            _ => None,
        }
    }
    // A report that cannot be checked is treated as failing the check.
    let tree = ron::to_string(value)
        .map_err(|e| e.to_string())
        .and_then(|text| ron::from_str::<ron::Value>(&text).map_err(|e| e.to_string()));
    match tree {
        Ok(tree) => walk(&tree, "analysis"),
        Err(e) => Some(format!("analysis (unreadable for the check: {e})")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[derive(Serialize)]
    struct Sample {
        good: f64,
        nested: Vec<Option<f64>>,
    }

    #[test]
    fn non_finite_numbers_are_found_with_their_path() {
        let finite = Sample {
            good: 1.5,
            nested: vec![None, Some(2.0)],
        };
        assert_eq!(first_non_finite(&finite), None);
        for bad in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            let sample = Sample {
                good: 1.5,
                nested: vec![None, Some(bad)],
            };
            assert_eq!(
                first_non_finite(&sample).as_deref(),
                Some("analysis.nested[1]")
            );
        }
    }
}
