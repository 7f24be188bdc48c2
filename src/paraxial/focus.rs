//! Focusing by moving the sensor: the paraxial conjugates of the thick-lens equivalent.

use super::matrix::FirstOrder;
use super::{ObjectPosition, ParaxialError};
use crate::system::SystemAt;

/// An object nearer than the lens's front focal point, whose image is virtual: no film behind
/// the lens catches it. The renderer's models and the bake refuse such a focus alike.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error(
    "cannot focus at {} mm: the object must lie beyond the front focal point \
     ({front_focal_mm:.3} mm in front of the first vertex)",
    crate::limits::short(*.distance_mm)
)]
pub struct CannotFocus {
    pub distance_mm: f64,
    pub front_focal_mm: f64,
}

/// An object whose paraxial image falls inside the lens, in front of its last vertex, so no
/// film behind the lens catches it: a lens whose rear focal point lies inside it, focused on
/// anything but near objects. `focus` names the distance ("2000 mm", "infinity").
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error(
    "cannot focus at {focus}: its image plane z = {film_z:.6} mm is not behind the last vertex \
     (z = {last_vertex_z:.6} mm)"
)]
pub struct ImageInsideLens {
    pub focus: String,
    pub film_z: f64,
    pub last_vertex_z: f64,
}

/// Absolute z of the sensor plane that images `object` sharply (paraxially).
///
/// Fails when the image is at infinity (object in the front focal plane) or virtual (object
/// inside the front focal length, or a diverging lens), since no sensor can catch it.
pub fn sensor_z(system: &SystemAt, object: ObjectPosition) -> Result<f64, ParaxialError> {
    let first = FirstOrder::of(system)?;
    let z_image = match object.checked()? {
        ObjectPosition::Infinite => first.z_rear_focal,
        ObjectPosition::Finite { distance } => first
            .image_z(-distance)
            .ok_or(ParaxialError::ObjectAtFrontFocalPlane)?,
    };
    if !first.ahead_of_last_vertex(z_image) {
        return Err(ParaxialError::VirtualImage {
            z_image,
            z_last_vertex: first.z_last_vertex,
        });
    }
    Ok(z_image)
}

/// The object in focus on a sensor at absolute `z_sensor`: infinity when the sensor is in the
/// rear focal plane, else a real object in front of surface 1.
pub fn object_in_focus(system: &SystemAt, z_sensor: f64) -> Result<ObjectPosition, ParaxialError> {
    let first = FirstOrder::of(system)?;
    if !(z_sensor.is_finite() && first.ahead_of_last_vertex(z_sensor)) {
        return Err(ParaxialError::SensorInsideLens {
            z_sensor,
            z_last_vertex: first.z_last_vertex,
        });
    }
    match first.object_z(z_sensor) {
        None => Ok(ObjectPosition::Infinite),
        Some(z_object) if z_object < 0.0 => Ok(ObjectPosition::Finite {
            distance: -z_object,
        }),
        Some(z_object) => Err(ParaxialError::NoRealObject { z_sensor, z_object }),
    }
}
