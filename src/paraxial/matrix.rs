//! Reduced paraxial matrices and the cardinal points they give.
//!
//! A paraxial ray is the column (y, n·u): height in mm and optical slope (index times the real
//! slope, positive when the ray climbs towards +z). In these variables refraction and transfer
//! are unimodular 2x2 matrices:
//!
//! ```text
//! refraction by power K = c (n' - n):   [1  0; -K  1]
//! transfer over thickness t in index n: [1  t/n; 0  1]     (+t/n: seed 001 prints -d/n)
//! ```
//!
//! and a system is their product. With M = [A B; C D] from the vertex of surface 1 (object
//! side) to the last vertex (image side), the power is -C and every cardinal point follows from
//! A, C and D alone (see [`FirstOrder::from_matrix`]).

use super::ParaxialError;
use crate::prescription::Shape;
use crate::system::SystemAt;
use nalgebra::Matrix2;

/// Curvature the paraxial region of a surface sees (1/mm).
///
/// An asphere's r^2 coefficient a bends the vertex like a sphere would: its sag starts
/// c r^2 / 2 + a r^2, so the vertex curvature is c + 2 a. The exact tracer follows the full
/// sag, so paraxial optics must use this sum to be its small-aperture limit. (An odd asphere's
/// r term, a cone at the vertex, has no paraxial limit and is left out, as it is by the
/// third-order sums.)
pub fn paraxial_curvature(shape: &Shape) -> f64 {
    shape.curvature() + 2.0 * shape.aspheric_term(2)
}

/// Refraction by a surface of power `power` (1/mm).
pub fn refraction(power: f64) -> Matrix2<f64> {
    Matrix2::new(1.0, 0.0, -power, 1.0)
}

/// Transfer over `thickness` (mm) through a medium of index `index`.
pub fn transfer(thickness: f64, index: f64) -> Matrix2<f64> {
    Matrix2::new(1.0, thickness / index, 0.0, 1.0)
}

/// Power c (n' - n) of surface `i` (0-based), in 1/mm; an ideal lens's is 1/f
/// ([`Shape::IdealLens`]), which in reduced slopes holds whichever way light crosses it.
pub fn surface_power(system: &SystemAt, i: usize) -> f64 {
    let s = &system.surfaces[i];
    paraxial_curvature(&s.shape) * (s.index_after - system.index_before(i)) + s.shape.ideal_power()
}

/// Matrix from the vertex plane of surface 1 (object side) to the vertex plane of surface
/// `surface` (0-based), before that surface refracts. Identity for surface 0.
pub fn to_vertex(system: &SystemAt, surface: usize) -> Matrix2<f64> {
    (0..surface).fold(Matrix2::identity(), |m, i| {
        let s = &system.surfaces[i];
        transfer(s.thickness, s.index_after) * refraction(surface_power(system, i)) * m
    })
}

/// Matrix from the vertex plane of surface `surface` (0-based), before it refracts, to the
/// image side of the last vertex.
pub fn from_vertex(system: &SystemAt, surface: usize) -> Matrix2<f64> {
    let last = system.surfaces.len() - 1;
    (surface..=last).fold(Matrix2::identity(), |m, i| {
        let refracted = refraction(surface_power(system, i)) * m;
        if i == last {
            refracted
        } else {
            let s = &system.surfaces[i];
            transfer(s.thickness, s.index_after) * refracted
        }
    })
}

/// The system matrix: object side of surface 1 to image side of the last surface.
pub fn system_matrix(system: &SystemAt) -> Matrix2<f64> {
    from_vertex(system, 0)
}

/// First-order (Gaussian) properties of a lens at one wavelength. Points are absolute z in the
/// lens frame; lengths in mm.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FirstOrder {
    /// Power in 1/mm.
    pub power: f64,
    pub object_index: f64,
    pub image_index: f64,
    /// Image-side (effective) focal length n'/power.
    pub efl: f64,
    /// Object-side focal length n/power (positive for a converging lens).
    pub fl_object: f64,
    /// Back focal length: last vertex to rear focal point, signed.
    pub bfl: f64,
    /// Front focal length: vertex of surface 1 to front focal point, signed (negative when the
    /// focal point lies in object space).
    pub ffl: f64,
    pub z_front_focal: f64,
    pub z_rear_focal: f64,
    pub z_front_principal: f64,
    pub z_rear_principal: f64,
    pub z_front_nodal: f64,
    pub z_rear_nodal: f64,
    pub z_last_vertex: f64,
}

impl FirstOrder {
    /// +1 when light leaves the lens travelling +z, -1 after an odd number of mirrors: the sign
    /// of the image-space index.
    pub fn image_sense(&self) -> f64 {
        self.image_index.signum()
    }

    /// Refuses a lens whose focal length, taken in the sense light leaves it, is negative. Lens
    /// models, tables and renders take the f-number as EFL / EPD and stop a lens down by
    /// comparing it with the wide-open one, which a negative EFL turns around (a mutated file
    /// of EFL -2.5 mm was refused as `f-number -4.96 is faster than the lens wide open`).
    pub fn require_converging(&self) -> Result<(), ParaxialError> {
        if self.efl * self.image_sense() > 0.0 {
            Ok(())
        } else {
            Err(ParaxialError::Diverging { efl: self.efl })
        }
    }

    /// Whether a point at `z` in image space lies ahead of the last vertex in the sense light
    /// leaves it, where a real image can form.
    pub fn ahead_of_last_vertex(&self, z: f64) -> bool {
        (z - self.z_last_vertex) * self.image_sense() > 0.0
    }

    /// Cardinal points of `system`; an afocal system (zero power to rounding,
    /// [`super::is_afocal`]) has none.
    pub fn of(system: &SystemAt) -> Result<FirstOrder, ParaxialError> {
        // A power that is the rounding residue of surface powers designed to cancel would put
        // the focal points 1e17 mm away: such a system is afocal.
        if super::is_afocal(system) {
            return Err(ParaxialError::Afocal);
        }
        FirstOrder::from_matrix(
            &system_matrix(system),
            system.object_index,
            system.image_index(),
            system.last_vertex_z(),
        )
    }

    /// Cardinal points from a system matrix [A B; C D] (surface-1 vertex to last vertex).
    ///
    /// A ray entering parallel at height 1 leaves with height A and optical slope C, so it
    /// crosses the axis n' A / (-C) behind the last vertex; a ray leaving parallel entered with
    /// n u = -C y / D, so it came from n D / C in front of surface 1. The principal points sit a
    /// focal length inside the focal points; the nodal points are shifted from them by
    /// (n' - n) / power.
    pub fn from_matrix(
        m: &Matrix2<f64>,
        object_index: f64,
        image_index: f64,
        z_last_vertex: f64,
    ) -> Result<FirstOrder, ParaxialError> {
        let (a, c, d) = (m[(0, 0)], m[(1, 0)], m[(1, 1)]);
        let power = -c;
        let efl = image_index / power;
        let fl_object = object_index / power;
        if power == 0.0 || !efl.is_finite() || !fl_object.is_finite() {
            return Err(ParaxialError::Afocal);
        }
        let bfl = a * efl;
        let ffl = -d * fl_object;
        let z_rear_focal = z_last_vertex + bfl;
        let z_front_focal = ffl;
        let z_front_principal = z_front_focal + fl_object;
        let z_rear_principal = z_rear_focal - efl;
        Ok(FirstOrder {
            power,
            object_index,
            image_index,
            efl,
            fl_object,
            bfl,
            ffl,
            z_front_focal,
            z_rear_focal,
            z_front_principal,
            z_rear_principal,
            z_front_nodal: z_front_focal + efl,
            z_rear_nodal: z_rear_focal - fl_object,
            z_last_vertex,
        })
    }

    /// The thick-lens equivalent: where the Gaussian lens formula n'/s' - n/s = power, with s
    /// and s' measured from the principal points, images an axial point at `z_object`.
    /// None when the object lies in the front focal plane (image at infinity).
    pub fn image_z(&self, z_object: f64) -> Option<f64> {
        let s = z_object - self.z_front_principal;
        let vergence = cancelled_sum(self.power, self.object_index / s)?;
        Some(self.z_rear_principal + self.image_index / vergence)
    }

    /// Inverse of [`FirstOrder::image_z`]: the axial point imaged at `z_image`. None when
    /// `z_image` is the rear focal plane (object at infinity).
    pub fn object_z(&self, z_image: f64) -> Option<f64> {
        let s_image = z_image - self.z_rear_principal;
        let vergence = cancelled_sum(self.image_index / s_image, -self.power)?;
        Some(self.z_front_principal + self.object_index / vergence)
    }

    /// Lateral magnification of the thick-lens equivalent between conjugate planes (n s' / n' s
    /// from the principal points).
    pub fn magnification(&self, z_object: f64, z_image: f64) -> f64 {
        let s = z_object - self.z_front_principal;
        let s_image = z_image - self.z_rear_principal;
        (self.object_index * s_image) / (self.image_index * s)
    }
}

/// a + b, or None when it cancels to within rounding: a conjugate more than ~1e12 focal lengths
/// away is one at infinity, and a sum that rounding alone keeps from zero would place it there
/// at a meaningless, sign-random distance.
fn cancelled_sum(a: f64, b: f64) -> Option<f64> {
    let sum = a + b;
    (sum.abs() > 1e-12 * (a.abs() + b.abs()) && sum.is_finite()).then_some(sum)
}
