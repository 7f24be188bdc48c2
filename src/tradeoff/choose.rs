//! The cheapest model that keeps a scene's image error under a budget.
//!
//! Candidates in order of cost: thin, thick, Seidel (no table, a short fixed-point solve per ray
//! each), baked tables by bytes (16^3 f16 up to 256^3 f32; at each size f16, then u16, whose
//! 16-bit codes of each channel's range cost f16's bytes at about f32's error, then f32), then
//! the exact trace. Each candidate
//! gets a predicted error first, from cheap means, and is built and measured only when the
//! prediction meets the budget; the first whose measured error meets it is chosen:
//!
//! - thick: the third-order transverse aberration of the Seidel sums at each probe ray's field
//!   and pupil point, |eps| / pixel pitch (no real ray traced);
//! - thin: thick's prediction plus the first-order difference between the two maps;
//! - Seidel and baked: the measured error of a small probe (a 16^3 table, and 512 rays); a table
//!   of N nodes per axis is predicted from the 16^3 one by the h^2 law of trilinear interpolation,
//!   plus, for f16, the error of rounding the exact directions' encoding to f16 (u16 is predicted
//!   as f32 and its rounding left to the measurement: where that fails the budget, f32 is next).
//!
//! Colour: one wavelength when the lateral colour (C_II, F to C, at the edge of the used field)
//! stays under the budget or the scene is rendered in one wavelength
//! ([`SceneRequirements::monochrome`]), else three (C, design, F), which only baked and traced
//! models carry.

use serde::Serialize;

use super::{
    Built, Domain, RaySet, SceneRequirements, TradeoffError, analytic_models, bake_timed,
    baked_model, model_error, to_f16,
};
use crate::glass::{C_LINE_NM, F_LINE_NM};
use crate::lrtf::measure::{Stats, angle_between};
use crate::lrtf::{LrtfTable, Precision};
use crate::model::{FirstOrderModels, ModelKind, SeidelLens, paraxial_for};
use crate::seidel::{IndexDifferences, Seidel};
use crate::system::LensSystem;

/// Rays of the probe that predicts Seidel and baked errors.
const PROBE_RAYS: usize = 512;
/// Rays of the measurement that confirms a choice.
const MEASURE_RAYS: usize = 4000;
const PROBE_RESOLUTION: usize = 16;
const RESOLUTIONS: [usize; 5] = [16, 32, 64, 128, 256];

/// A candidate considered on the way to the choice.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Considered {
    pub label: String,
    pub predicted_px: f64,
    /// None when the prediction already missed the budget, so it was not built.
    pub measured_px: Option<f64>,
}

/// The chosen model and why.
#[derive(Clone, Debug, Serialize)]
pub struct Choice {
    pub label: String,
    pub model: ModelKind,
    pub resolution: Option<usize>,
    pub precision: Option<&'static str>,
    /// Wavelengths the model must carry (one: colour skipped).
    pub wavelengths_nm: Vec<f64>,
    /// Lateral colour F to C at the edge of the used field, in pixels.
    pub lateral_colour_px: f64,
    pub predicted_px: f64,
    /// p99 image error over the confirming measurement's rays.
    pub measured_px: f64,
    pub budget_px: f64,
    pub domain: Domain,
    pub considered: Vec<Considered>,
    /// The table to write when the choice is baked.
    #[serde(skip)]
    pub table: Option<LrtfTable>,
}

/// Lateral colour (mm, F minus C chief-ray height) at the edge of the used field; zero for a lens
/// that does not disperse.
fn lateral_colour_mm(system: &LensSystem, domain: &Domain) -> Result<f64, TradeoffError> {
    let Some(dn) = IndexDifferences::fraunhofer(system) else {
        return Ok(0.0);
    };
    let at = system.at(domain.wavelength_nm);
    let paraxial = paraxial_for(&at, domain.focus_mm)?;
    let lat = Seidel::new(&at, &paraxial, Some(&dn))
        .transverse_colour
        .map_or(0.0, |c| c.lat);
    // C_II is linear in the field: scale from the paraxial field edge to the used film radius.
    Ok(lat * domain.film_radius / paraxial.image_height.abs())
}

/// p99 in pixels of `f(ray)` (mm in the image) over the probe rays the exact trace passes.
fn p99_px(set: &RaySet, domain: &Domain, f: impl Fn(usize) -> f64) -> f64 {
    let values = (0..set.rays.len())
        .filter(|&k| set.exact[k].is_some())
        .map(|k| f(k) / domain.pixel_pitch)
        .collect();
    Stats::of(values).p99
}

/// Third-order prediction for the thick model (mm in the image, per probe ray).
fn third_order_mm(seidel: &SeidelLens, set: &RaySet, k: usize) -> f64 {
    let ray = &set.rays[k];
    let at = |z: f64| {
        let t = (z - ray.origin[2]) / ray.direction[2];
        [
            ray.origin[0] + t * ray.direction[0],
            ray.origin[1] + t * ray.direction[1],
        ]
    };
    let pupil = at(seidel.thick.exit_pupil_z);
    let h = seidel.marginal_pupil_height;
    let eps = seidel.aberration(at(seidel.image_z), [pupil[0] / h, pupil[1] / h]);
    eps[0].hypot(eps[1])
}

/// The f16 floor: the angle lost by rounding each exact direction's table encoding to f16.
fn f16_floor_px(table: &LrtfTable, set: &RaySet, domain: &Domain) -> f64 {
    let param = table.info.parameterisation;
    let px_per_rad = domain.efl.abs() / domain.pixel_pitch;
    let values = set
        .exact
        .iter()
        .flatten()
        .map(|e| {
            let code = param.encode_direction(e.direction);
            let rounded = code.map(|v| half::f16::from_f32(v as f32).to_f32() as f64);
            angle_between(param.decode_direction(rounded), e.direction) * px_per_rad
        })
        .collect();
    Stats::of(values).p99
}

/// Chooses the cheapest model of `system` whose measured p99 image error for `req` stays under
/// `budget_px`; the baked domain is the scene's (film radius, focus, f-number, wavelengths).
pub fn choose_model(
    system: &LensSystem,
    req: &SceneRequirements,
    budget_px: f64,
) -> Result<Choice, TradeoffError> {
    if !(budget_px.is_finite() && budget_px > 0.0) {
        return Err(TradeoffError::Invalid(format!(
            "error budget must be a positive number of pixels, got {budget_px}"
        )));
    }
    let domain = Domain::of(system, req)?;
    let lateral_colour_px = lateral_colour_mm(system, &domain)?.abs() / domain.pixel_pitch;
    let colour = !req.monochrome && lateral_colour_px >= budget_px;
    let wavelengths_nm = if colour {
        vec![C_LINE_NM, domain.wavelength_nm, F_LINE_NM]
    } else {
        Vec::new()
    };
    let mut analytic = analytic_models(system, &domain)?;
    let traced = analytic
        .pop()
        .expect("analytic_models ends with the traced model");
    let (probe_table, probe_seconds) =
        bake_timed(system, &domain, PROBE_RESOLUTION, wavelengths_nm.clone())?;
    let probe = RaySet::new(&probe_table, &traced, &domain, PROBE_RAYS, 11);
    let measure_set = RaySet::new(&probe_table, &traced, &domain, MEASURE_RAYS, 29);
    let measure = |b: &Built| model_error(b, &measure_set, &domain).image_px.p99;

    let at = system.at(domain.wavelength_nm);
    let paraxial = paraxial_for(&at, domain.focus_mm)?;
    let thick = FirstOrderModels::of(system, Some(domain.f_number))?.thick;
    let seidel = SeidelLens::new(&at, &paraxial, thick);
    let thick_predicted = p99_px(&probe, &domain, |k| third_order_mm(&seidel, &probe, k));
    let mut considered = Vec::new();
    let choose = |built: Built,
                  predicted_px: f64,
                  table: Option<LrtfTable>,
                  considered: &mut Vec<Considered>| {
        let label = built.label();
        if predicted_px > budget_px {
            considered.push(Considered {
                label,
                predicted_px,
                measured_px: None,
            });
            return None;
        }
        let measured_px = measure(&built);
        considered.push(Considered {
            label: label.clone(),
            predicted_px,
            measured_px: Some(measured_px),
        });
        (measured_px <= budget_px).then_some((built, label, predicted_px, measured_px, table))
    };

    let mut found = None;
    if !colour {
        let mut analytic = analytic.into_iter();
        let thin = analytic.next().expect("thin model");
        let thick = analytic.next().expect("thick model");
        let seidel_model = analytic.next().expect("Seidel model");
        let first_order_gap = |k: usize| {
            let (a, b) = (thin.map(&probe.rays[k]), thick.map(&probe.rays[k]));
            match (a, b) {
                (Some(a), Some(b)) => angle_between(a.direction, b.direction) * domain.efl.abs(),
                _ => 0.0,
            }
        };
        let thin_predicted = thick_predicted + p99_px(&probe, &domain, first_order_gap);
        let seidel_predicted = model_error(&seidel_model, &probe, &domain).image_px.p99;
        for (built, predicted) in [
            (thin, thin_predicted),
            (thick, thick_predicted),
            (seidel_model, seidel_predicted),
        ] {
            if found.is_none() {
                found = choose(built, predicted, None, &mut considered);
            }
        }
    }
    if found.is_none() {
        let probe_model = baked_model(system, probe_table.clone(), &domain, probe_seconds)?;
        let probe_px = model_error(&probe_model, &probe, &domain).image_px.p99;
        let floor_px = f16_floor_px(&probe_table, &probe, &domain);
        'search: for n in RESOLUTIONS {
            let scale = ((PROBE_RESOLUTION - 1) as f64 / (n - 1) as f64).powi(2);
            let f32_predicted = probe_px * scale;
            let mut f32_table: Option<(LrtfTable, f64)> = None;
            for precision in [Precision::F16, Precision::U16, Precision::F32] {
                let predicted = match precision {
                    Precision::F16 => f32_predicted + floor_px,
                    Precision::F32 | Precision::U16 => f32_predicted,
                };
                if predicted > budget_px {
                    considered.push(Considered {
                        label: format!("baked {n}^3 {}", precision.name()),
                        predicted_px: predicted,
                        measured_px: None,
                    });
                    continue;
                }
                if f32_table.is_none() {
                    f32_table = Some(if n == PROBE_RESOLUTION {
                        (probe_table.clone(), probe_seconds)
                    } else {
                        bake_timed(system, &domain, n, wavelengths_nm.clone())?
                    });
                }
                let (table, seconds) = f32_table.as_ref().expect("baked above");
                let table = match precision {
                    Precision::F16 => to_f16(table),
                    Precision::F32 => table.clone(),
                    Precision::U16 => table.to_precision(Precision::U16),
                };
                let built = baked_model(system, table.clone(), &domain, *seconds)?;
                found = choose(built, predicted, Some(table), &mut considered);
                if found.is_some() {
                    break 'search;
                }
            }
        }
    }
    let (built, label, predicted_px, measured_px, table) = match found {
        Some(found) => found,
        None => {
            // The reference meets any budget: it is what errors are measured against.
            let label = traced.label();
            considered.push(Considered {
                label: label.clone(),
                predicted_px: 0.0,
                measured_px: Some(0.0),
            });
            (traced, label, 0.0, 0.0, None)
        }
    };
    Ok(Choice {
        label,
        model: built.model.kind(),
        resolution: built.resolution,
        precision: built.precision.map(Precision::name),
        wavelengths_nm: if wavelengths_nm.is_empty() {
            vec![domain.wavelength_nm]
        } else {
            wavelengths_nm
        },
        lateral_colour_px,
        predicted_px,
        measured_px,
        budget_px,
        domain,
        considered,
        table,
    })
}
