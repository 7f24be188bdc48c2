//! First-order optics: system matrices, cardinal points, stop and pupils, paraxial rays and
//! focusing, all computed from one [`SystemAt`](crate::system::SystemAt).
//!
//! Sign conventions (those of the oracle data and of CODE V): z along the axis, light towards
//! +z, origin at the vertex of surface 1; slopes positive when a ray climbs; a field angle
//! theta means a chief ray of object-space slope tan(theta) through the entrance-pupil centre,
//! so a positive angle images an object point below the axis to a point above it.

mod afocal;
mod focus;
mod matrix;
mod pupils;
mod rays;

pub use afocal::{AFOCAL_RELATIVE_POWER, AfocalParaxial, is_afocal};
pub use focus::{CannotFocus, ImageInsideLens, object_in_focus, sensor_z};
pub use matrix::{
    FirstOrder, from_vertex, paraxial_curvature, refraction, surface_power, system_matrix,
    to_vertex, transfer,
};
pub use pupils::{
    Aperture, Field, Paraxial, ParaxialOptions, Pupil, StopChoice, entrance_pupil, exit_pupil,
    limiting_surface, max_field_angle_deg,
};
pub use rays::{ParaxialRay, RayAtSurface};

/// Where the object is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ObjectPosition {
    Infinite,
    /// Object plane `distance` mm in front of the vertex of surface 1 (at z = -distance).
    Finite {
        distance: f64,
    },
}

impl ObjectPosition {
    /// The object in focus at `focus_mm` in front of surface 1, or at infinity for None.
    pub fn in_focus(focus_mm: Option<f64>) -> ObjectPosition {
        focus_mm.map_or(ObjectPosition::Infinite, |distance| {
            ObjectPosition::Finite { distance }
        })
    }
}

impl ObjectPosition {
    /// Distance from the vertex of surface 1, None at infinity.
    pub fn distance(&self) -> Option<f64> {
        match self {
            ObjectPosition::Infinite => None,
            ObjectPosition::Finite { distance } => Some(*distance),
        }
    }

    /// Checks that a finite object lies in front of surface 1 at a finite distance: a real
    /// object, the only kind a sensor can be focused on.
    fn checked(self) -> Result<ObjectPosition, ParaxialError> {
        match self {
            ObjectPosition::Finite { distance } if !(distance.is_finite() && distance > 0.0) => {
                Err(ParaxialError::ObjectNotInFront { distance })
            }
            other => Ok(other),
        }
    }

    /// Checks that a finite object lies at a finite distance off the first vertex: in front of
    /// it (real), or behind it (virtual: a beam converging on a point behind surface 1, as a
    /// relay or an eyepiece receives it), which the analyses take too.
    fn checked_real_or_virtual(self) -> Result<ObjectPosition, ParaxialError> {
        match self {
            ObjectPosition::Finite { distance } if !(distance.is_finite() && distance != 0.0) => {
                Err(ParaxialError::InvalidObjectDistance { distance })
            }
            other => Ok(other),
        }
    }
}

/// Why a first-order quantity does not exist for this lens or these conjugates.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ParaxialError {
    #[error("the system is afocal (zero power): it has no focal points")]
    Afocal,
    #[error(
        "the system has power (EFL {efl:.6e} mm): the afocal analysis takes a system whose \
         power is zero"
    )]
    NotAfocal { efl: f64 },
    #[error(
        "the lens diverges (EFL {efl:.6} mm): cameras, tables and renders need a lens of positive \
         focal length"
    )]
    Diverging { efl: f64 },
    #[error(
        "the entrance pupil is at infinity (object-space telecentric stop): the stop cannot \
         define an axial beam from an object at infinity"
    )]
    EntrancePupilAtInfinity,
    #[error(
        "object distance must be positive and finite (the object lies in front of surface 1), got {distance} mm"
    )]
    ObjectNotInFront { distance: f64 },
    #[error(
        "object distance must be finite and not zero (negative for a virtual object behind \
         surface 1), got {distance} mm"
    )]
    InvalidObjectDistance { distance: f64 },
    #[error("the object lies in the entrance-pupil plane, so no chief or marginal ray joins them")]
    ObjectAtEntrancePupil,
    #[error("the object lies in the front focal plane: its image is at infinity")]
    ObjectAtFrontFocalPlane,
    #[error(
        "the image of this object is virtual (z = {z_image:.6} mm, not behind the last vertex at \
         {z_last_vertex:.6} mm): the object is inside the front focal length or the lens diverges"
    )]
    VirtualImage { z_image: f64, z_last_vertex: f64 },
    #[error(
        "the sensor at z = {z_sensor} mm is not behind the last vertex (z = {z_last_vertex:.6} mm)"
    )]
    SensorInsideLens { z_sensor: f64, z_last_vertex: f64 },
    #[error(
        "no real object is in focus on a sensor at z = {z_sensor:.6} mm: its conjugate lies at \
         z = {z_object:.6} mm, behind the front vertex (sensor nearer than the rear focal point?)"
    )]
    NoRealObject { z_sensor: f64, z_object: f64 },
    #[error("half-field angle must be finite and below 90 degrees, got {deg}")]
    InvalidFieldAngle { deg: f64 },
    #[error("object height must be finite, got {height} mm")]
    InvalidObjectHeight { height: f64 },
    #[error("a field given as an object height needs an object at a finite distance")]
    ObjectHeightAtInfinity,
    #[error("entrance-pupil diameter must be positive and finite, got {diameter} mm")]
    InvalidEntrancePupilDiameter { diameter: f64 },
    #[error("no surface limits the axial beam (it meets every surface on the axis)")]
    NoLimitingAperture,
    #[error(
        "no clear aperture limits the chief ray, so the lens has no largest field: give the \
         field as an angle or an object height"
    )]
    UnlimitedField,
}
