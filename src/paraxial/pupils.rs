//! Aperture stop, pupils, the marginal and chief rays, and what they give: f-numbers, the
//! Lagrange invariant, the paraxial image and the largest unvignetted field.

use super::matrix::{FirstOrder, from_vertex, to_vertex};
use super::rays::ParaxialRay;
use super::{ObjectPosition, ParaxialError};
use crate::system::SystemAt;
use serde::Serialize;

/// Which surface is the aperture stop.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum StopChoice {
    /// The surface the prescription marks.
    #[default]
    Marked,
    /// The surface whose clear aperture limits the axial beam from the object.
    LimitingAxialBeam,
}

/// Size of the axial beam.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Aperture {
    /// The stop's clear semi-aperture, filled: EPD is the stop diameter imaged to object space.
    #[default]
    StopClearAperture,
    /// An explicit entrance-pupil diameter (mm).
    EntrancePupilDiameter(f64),
}

/// Where the chief ray comes from.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum Field {
    /// Object-space chief-ray slope tan(deg) through the entrance-pupil centre.
    Angle { deg: f64 },
    /// Height of the object point (finite objects only), mm.
    ObjectHeight { mm: f64 },
    /// The largest angle whose paraxial chief ray passes every clear aperture
    /// ([`max_field_angle_deg`]).
    #[default]
    LargestUnvignetted,
}

/// Everything that fixes the two paraxial rays besides the lens.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ParaxialOptions {
    pub object: ObjectPosition,
    pub aperture: Aperture,
    pub field: Field,
    pub stop: StopChoice,
}

impl Default for ParaxialOptions {
    fn default() -> ParaxialOptions {
        ParaxialOptions {
            object: ObjectPosition::Infinite,
            aperture: Aperture::default(),
            field: Field::default(),
            stop: StopChoice::default(),
        }
    }
}

/// A pupil: absolute z of its centre in the lens frame and its diameter (mm).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Pupil {
    pub z: f64,
    pub diameter: f64,
}

/// Image of the stop in object space, as (z of the entrance pupil, stop-to-pupil scale): a
/// height h in the stop plane is imaged to h / scale in the entrance pupil.
///
/// With M = [A B; C D] from the surface-1 vertex to the stop, the stop centre is reached by
/// rays through z = n B / A, and M maps the pupil plane to the stop with magnification A.
pub fn entrance_pupil(system: &SystemAt, stop: usize) -> Result<(f64, f64), ParaxialError> {
    let m = to_vertex(system, stop);
    let (a, b) = (m[(0, 0)], m[(0, 1)]);
    let z = system.object_index * b / a;
    if a == 0.0 || !z.is_finite() {
        return Err(ParaxialError::EntrancePupilAtInfinity);
    }
    Ok((z, a))
}

/// Image of the stop in image space, as (z of the exit pupil, stop-to-pupil magnification);
/// None when it lies at infinity (image-space telecentric).
///
/// With M = [A B; C D] from the stop to the last vertex, the ray from the stop centre leaves
/// with height B w and optical slope D w, crossing the axis n' B / D before the last vertex;
/// the stop-to-pupil magnification is 1 / D.
pub fn exit_pupil(system: &SystemAt, stop: usize) -> Option<(f64, f64)> {
    let m = from_vertex(system, stop);
    let (b, d) = (m[(0, 1)], m[(1, 1)]);
    let z = system.last_vertex_z() - system.image_index() * b / d;
    let magnification = 1.0 / d;
    (z.is_finite() && magnification.is_finite()).then_some((z, magnification))
}

/// The surface (0-based) whose clear aperture first limits an axial beam from `object`: the
/// smallest ratio of semi-aperture to the height of any axial ray.
pub fn limiting_surface(system: &SystemAt, object: ObjectPosition) -> Result<usize, ParaxialError> {
    let axial = match object.checked_real_or_virtual()? {
        ObjectPosition::Infinite => ParaxialRay::trace(system, 1.0, 0.0),
        ObjectPosition::Finite { distance } => ParaxialRay::trace(system, 1.0, 1.0 / distance),
    };
    axial
        .surfaces
        .iter()
        .zip(&system.surfaces)
        .enumerate()
        .filter(|(_, (ray, _))| ray.y != 0.0)
        .map(|(i, (ray, surface))| (i, surface.semi_aperture / ray.y.abs()))
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(i, _)| i)
        .ok_or(ParaxialError::NoLimitingAperture)
}

/// The largest half-field angle (degrees) whose paraxial chief ray passes every clear
/// semi-aperture; None when no surface limits it.
///
/// This is the paraxial estimate: chief-ray heights grow linearly with tan(theta), so the
/// bound is the smallest semi-aperture / height over the surfaces. The real chief ray is
/// traced by the exact tracer, which gives the traceable limit.
pub fn max_field_angle_deg(system: &SystemAt, stop: usize) -> Result<Option<f64>, ParaxialError> {
    let (z_entrance, _) = entrance_pupil(system, stop)?;
    let unit_chief = ParaxialRay::trace(system, -z_entrance, 1.0);
    let max_tan = unit_chief
        .surfaces
        .iter()
        .zip(&system.surfaces)
        .enumerate()
        .filter(|(i, (ray, _))| *i != stop && ray.y != 0.0)
        .map(|(_, (ray, surface))| surface.semi_aperture / ray.y.abs())
        .min_by(f64::total_cmp);
    Ok(max_tan.map(|t| t.atan().to_degrees()))
}

/// The first-order model of a lens for one object, aperture and field.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Paraxial {
    pub wavelength_nm: f64,
    pub first_order: FirstOrder,
    /// Object distance from surface 1 (mm); None at infinity.
    pub object_distance: Option<f64>,
    /// 0-based index of the aperture stop.
    pub stop: usize,
    pub entrance_pupil: Pupil,
    /// None when the exit pupil lies at infinity (image-space telecentric).
    pub exit_pupil: Option<Pupil>,
    /// From the axial object point through the rim of the entrance pupil.
    pub marginal: ParaxialRay,
    /// From the edge of the field through the centre of the entrance pupil (and of the stop).
    pub chief: ParaxialRay,
    /// Object-space half-field angle of the chief ray, degrees.
    pub field_angle_deg: f64,
    /// Height of the object point the chief ray starts from (finite objects).
    pub object_height: Option<f64>,
    /// The largest paraxially unvignetted half field (see [`max_field_angle_deg`]).
    pub max_field_angle_deg: Option<f64>,
    /// H = n (y ubar - ybar u), from the rays at surface 1 (positive for a positive field
    /// angle through a converging lens at infinity).
    pub lagrange_invariant: f64,
    /// EFL / entrance-pupil diameter.
    pub f_number: f64,
    /// 1 / (2 n' |u'|) with u' the image-space marginal slope (equals fl_object / EPD for an
    /// object at infinity).
    pub working_f_number: f64,
    /// Absolute z of the paraxial image of the object.
    pub z_image: f64,
    /// Chief-ray height in the paraxial image plane.
    pub image_height: f64,
    /// Lateral magnification n u / (n' u') of the marginal ray (finite objects).
    pub magnification: Option<f64>,
}

impl Paraxial {
    /// Builds the model; fails where a pupil, the image or the field does not exist.
    pub fn new(system: &SystemAt, options: &ParaxialOptions) -> Result<Paraxial, ParaxialError> {
        let object = options.object.checked_real_or_virtual()?;
        let first_order = FirstOrder::of(system)?;
        let stop = match options.stop {
            StopChoice::Marked => system.stop,
            StopChoice::LimitingAxialBeam => limiting_surface(system, object)?,
        };
        let (z_entrance, stop_scale) = entrance_pupil(system, stop)?;
        let entrance_radius = match options.aperture {
            Aperture::StopClearAperture => system.surfaces[stop].semi_aperture / stop_scale.abs(),
            Aperture::EntrancePupilDiameter(diameter) => {
                if !(diameter.is_finite() && diameter > 0.0) {
                    return Err(ParaxialError::InvalidEntrancePupilDiameter { diameter });
                }
                diameter / 2.0
            }
        };
        let max_field = max_field_angle_deg(system, stop)?;

        // Marginal ray: axial object point to the entrance-pupil rim.
        let marginal = match object {
            ObjectPosition::Infinite => ParaxialRay::trace(system, entrance_radius, 0.0),
            ObjectPosition::Finite { distance } => {
                let u = entrance_radius / (z_entrance + distance);
                if !u.is_finite() {
                    return Err(ParaxialError::ObjectAtEntrancePupil);
                }
                ParaxialRay::trace(system, u * distance, u)
            }
        };

        // Chief ray: a line through the entrance-pupil centre with the field's slope.
        let chief_slope = match (options.field, object) {
            (Field::Angle { deg }, _) => angle_slope(deg)?,
            (Field::LargestUnvignetted, _) => {
                angle_slope(max_field.ok_or(ParaxialError::UnlimitedField)?)?
            }
            (Field::ObjectHeight { .. }, ObjectPosition::Infinite) => {
                return Err(ParaxialError::ObjectHeightAtInfinity);
            }
            (Field::ObjectHeight { mm }, ObjectPosition::Finite { distance }) => {
                if !mm.is_finite() {
                    return Err(ParaxialError::InvalidObjectHeight { height: mm });
                }
                let u = -mm / (z_entrance + distance);
                if !u.is_finite() {
                    return Err(ParaxialError::ObjectAtEntrancePupil);
                }
                u
            }
        };
        let chief = ParaxialRay::trace(system, -z_entrance * chief_slope, chief_slope);

        // The thick-lens equivalent detects an object in the front focal plane reliably,
        // where the marginal ray's exit slope would only be a rounding residue.
        let z_image = match object {
            ObjectPosition::Infinite => first_order.z_rear_focal,
            ObjectPosition::Finite { distance } => first_order
                .image_z(-distance)
                .ok_or(ParaxialError::ObjectAtFrontFocalPlane)?,
        };
        let n_object = system.object_index;
        let n_image = system.image_index();
        let lagrange_invariant = n_object
            * (marginal.first_height() * chief.object_slope()
                - chief.first_height() * marginal.object_slope());
        let exit_pupil = exit_pupil(system, stop).map(|(z, magnification)| Pupil {
            z,
            // The beam fills the stop to the marginal-ray height there, whatever set its size.
            diameter: 2.0 * (entrance_radius * stop_scale * magnification).abs(),
        });
        let image_slope = marginal.image_slope();
        Ok(Paraxial {
            wavelength_nm: system.wavelength_nm,
            object_distance: object.distance(),
            stop,
            entrance_pupil: Pupil {
                z: z_entrance,
                diameter: 2.0 * entrance_radius,
            },
            exit_pupil,
            field_angle_deg: chief_slope.atan().to_degrees(),
            object_height: object.distance().map(|d| chief.object_space_height(-d)),
            max_field_angle_deg: max_field,
            lagrange_invariant,
            // Focal length and index in the sense light leaves the lens: an odd number of
            // mirrors makes both negative, and a converging mirror's f-number positive.
            f_number: first_order.efl * first_order.image_sense() / (2.0 * entrance_radius),
            working_f_number: 1.0 / (2.0 * n_image.abs() * image_slope.abs()),
            z_image,
            image_height: chief.image_space_height(z_image),
            magnification: object
                .distance()
                .map(|_| n_object * marginal.object_slope() / (n_image * image_slope)),
            first_order,
            marginal,
            chief,
        })
    }

    /// 1-based number of the stop surface, as printed in tables.
    pub fn stop_surface(&self) -> usize {
        self.stop + 1
    }

    /// The field value the real-ray analyses take ([`crate::trace::analyses::RealRays`]) for
    /// the field point whose chief ray makes `field_deg` with the axis at the entrance-pupil
    /// centre: that angle at infinity; for a finite object, the height of the object point,
    /// below the axis for a positive angle, as a collimated beam rising at that angle comes
    /// from below.
    pub fn field_at_angle(&self, field_deg: f64) -> f64 {
        match self.object_distance {
            None => field_deg,
            Some(distance) => -field_deg.to_radians().tan() * (distance + self.entrance_pupil.z),
        }
    }
}

fn angle_slope(deg: f64) -> Result<f64, ParaxialError> {
    if deg.is_finite() && deg.abs() < 90.0 {
        Ok(deg.to_radians().tan())
    } else {
        Err(ParaxialError::InvalidFieldAngle { deg })
    }
}
