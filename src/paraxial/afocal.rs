//! First-order optics of an afocal system (zero power: a telescope, a beam expander, a plate or
//! a fold mirror): a collimated beam leaves collimated, so there are no focal points, and what
//! a user asks for is the angular magnification, the pupils and the apparent field.
//!
//! With the system matrix M = [A B; C D] in reduced variables (y, n u), an afocal system has
//! C = 0, and det M = 1 makes A D = 1. A ray entering at optical slope n u leaves at
//! n' u' = D n u (C y vanishes), so tangents of angles scale by
//!
//! ```text
//! angular magnification  gamma = u' / u = n D / n'      (A = 1 / D scales beam heights)
//! ```
//!
//! taken in the sense light travels (|n'|: after an odd number of mirrors the lens-frame slope
//! flips sign without the ray turning). Two thin lenses f1, f2 a distance f1 + f2 apart give
//! D = -f1 / f2, the textbook -f_objective / f_eyepiece.

use super::matrix::{surface_power, system_matrix};
use super::pupils::{Pupil, StopChoice, entrance_pupil, exit_pupil, max_field_angle_deg};
use super::rays::ParaxialRay;
use super::{ObjectPosition, ParaxialError};
use crate::system::SystemAt;
use serde::Serialize;

/// |C| at most this fraction of the summed surface powers is zero power: the products that
/// form C cancel to rounding in a system designed afocal (a Keplerian telescope of printed
/// focal lengths gives C ~ 1e-18 /mm, a rear focal point 1e17 mm away).
pub const AFOCAL_RELATIVE_POWER: f64 = 1e-12;

/// Whether `system` is afocal at its wavelength: its power is zero to within rounding of the
/// surface powers that make it up ([`AFOCAL_RELATIVE_POWER`]).
pub fn is_afocal(system: &SystemAt) -> bool {
    let c = system_matrix(system)[(1, 0)];
    let scale: f64 = (0..system.surfaces.len())
        .map(|i| surface_power(system, i).abs())
        .sum();
    c.abs() <= AFOCAL_RELATIVE_POWER * scale
}

/// First-order model of an afocal system for a collimated object beam.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct AfocalParaxial {
    pub wavelength_nm: f64,
    pub object_index: f64,
    /// Signed: negative after an odd number of mirrors.
    pub image_index: f64,
    /// tan(theta') / tan(theta) of the paraxial chief ray, both angles in the sense light
    /// travels: negative for an inverting (Keplerian) telescope.
    pub angular_magnification: f64,
    /// Exit beam height over entrance beam height (A = 1 / D of the system matrix).
    pub beam_magnification: f64,
    /// The system matrix's C, 1/mm: zero, or its rounding residue.
    pub residual_power: f64,
    /// 0-based index of the aperture stop.
    pub stop: usize,
    pub entrance_pupil: Pupil,
    /// Where the eye goes; None when the stop's image lies at infinity.
    pub exit_pupil: Option<Pupil>,
    /// Exit pupil minus last vertex, in the sense light leaves (negative: the pupil is virtual,
    /// inside the system, as in a Galilean telescope).
    pub eye_relief: Option<f64>,
    /// Object-space half-field angle of the chief ray, degrees.
    pub field_angle_deg: f64,
    /// Image-space half-field angle of the paraxial chief ray (the apparent field), degrees.
    pub apparent_field_deg: f64,
    /// The largest paraxially unvignetted object-space half field.
    pub max_field_angle_deg: Option<f64>,
    /// H = n (y ubar - ybar u) at surface 1.
    pub lagrange_invariant: f64,
    pub marginal: ParaxialRay,
    pub chief: ParaxialRay,
}

impl AfocalParaxial {
    /// The model for an entrance pupil of `epd_mm` (None: the stop's clear aperture imaged to
    /// object space) and a half field of `field_deg`; fails where `system` has power.
    pub fn new(
        system: &SystemAt,
        epd_mm: Option<f64>,
        field_deg: f64,
        stop: StopChoice,
    ) -> Result<AfocalParaxial, ParaxialError> {
        let m = system_matrix(system);
        if !is_afocal(system) {
            return Err(ParaxialError::NotAfocal {
                efl: system.image_index() / -m[(1, 0)],
            });
        }
        let stop = match stop {
            StopChoice::Marked => system.stop,
            StopChoice::LimitingAxialBeam => {
                super::pupils::limiting_surface(system, ObjectPosition::Infinite)?
            }
        };
        let (z_entrance, stop_scale) = entrance_pupil(system, stop)?;
        let entrance_radius = match epd_mm {
            None => system.surfaces[stop].semi_aperture / stop_scale.abs(),
            Some(diameter) if diameter.is_finite() && diameter > 0.0 => diameter / 2.0,
            Some(diameter) => {
                return Err(ParaxialError::InvalidEntrancePupilDiameter { diameter });
            }
        };
        if !(field_deg.is_finite() && field_deg.abs() < 90.0) {
            return Err(ParaxialError::InvalidFieldAngle { deg: field_deg });
        }
        let slope = field_deg.to_radians().tan();
        let marginal = ParaxialRay::trace(system, entrance_radius, 0.0);
        let chief = ParaxialRay::trace(system, -z_entrance * slope, slope);
        let (n, n_image) = (system.object_index, system.image_index());
        let sense = n_image.signum();
        let exit_pupil = exit_pupil(system, stop).map(|(z, magnification)| Pupil {
            z,
            diameter: 2.0 * (entrance_radius * stop_scale * magnification).abs(),
        });
        let z_last = system.last_vertex_z();
        Ok(AfocalParaxial {
            wavelength_nm: system.wavelength_nm,
            object_index: n,
            image_index: n_image,
            angular_magnification: n * m[(1, 1)] / n_image.abs(),
            beam_magnification: m[(0, 0)],
            residual_power: -m[(1, 0)],
            stop,
            entrance_pupil: Pupil {
                z: z_entrance,
                diameter: 2.0 * entrance_radius,
            },
            eye_relief: exit_pupil.map(|p| (p.z - z_last) * sense),
            exit_pupil,
            field_angle_deg: field_deg,
            apparent_field_deg: (chief.image_slope() * sense).atan().to_degrees(),
            max_field_angle_deg: max_field_angle_deg(system, stop)?,
            lagrange_invariant: n
                * (marginal.first_height() * chief.object_slope()
                    - chief.first_height() * marginal.object_slope()),
            marginal,
            chief,
        })
    }

    /// Half-height of the collimated beam leaving the last surface (the marginal ray's, which
    /// leaves parallel to the axis), mm.
    pub fn exit_beam_radius(&self) -> f64 {
        self.marginal.last_height().abs()
    }
}
