//! First-order models: a lens reduced to its power, principal planes and pupils (the thin and
//! thick models, and the first-order part of every other model).

use super::ModelError;
use crate::paraxial::{
    CannotFocus, Field, ObjectPosition, Paraxial, ParaxialError, ParaxialOptions,
};
use crate::system::{LensSystem, SystemAt};

/// A lens reduced to first order: power and unit-magnification principal planes, with its pupils.
/// A thin lens is the case where both principal planes and both pupils coincide.
#[derive(Clone, Debug, PartialEq)]
pub struct ParaxialLens {
    pub focal_length_mm: f64,
    pub front_principal_z: f64,
    pub rear_principal_z: f64,
    pub entrance_pupil_z: f64,
    pub entrance_pupil_radius_mm: f64,
    pub exit_pupil_z: f64,
    pub exit_pupil_radius_mm: f64,
}

impl ParaxialLens {
    /// An ideal thin lens at z = 0 with its aperture in the lens plane.
    pub fn thin(focal_length_mm: f64, f_number: f64) -> Result<ParaxialLens, ModelError> {
        if !(focal_length_mm.is_finite() && focal_length_mm > 0.0) {
            return Err(ModelError::FocalLength(focal_length_mm));
        }
        if !(f_number.is_finite() && f_number > 0.0) {
            return Err(ModelError::FNumber(f_number));
        }
        let [shortest, longest] = crate::limits::FOCAL_LENGTH_RANGE_MM;
        crate::limits::check_range("the focal length (mm)", focal_length_mm, shortest, longest)?;
        crate::limits::check_range("the f-number", f_number, 0.5, crate::limits::MAX_F_NUMBER)?;
        let radius = focal_length_mm / (2.0 * f_number);
        Ok(ParaxialLens {
            focal_length_mm,
            front_principal_z: 0.0,
            rear_principal_z: 0.0,
            entrance_pupil_z: 0.0,
            entrance_pupil_radius_mm: radius,
            exit_pupil_z: 0.0,
            exit_pupil_radius_mm: radius,
        })
    }

    /// Film position (lens-frame z) that focuses an object `distance_mm` in front of the first
    /// vertex (Gaussian lens equation about the principal planes).
    pub fn film_z_for_object(&self, distance_mm: f64) -> Result<f64, ModelError> {
        let image_distance = self
            .image_distance(self.front_principal_z + distance_mm)
            .ok_or(ModelError::CannotFocus(CannotFocus {
                distance_mm,
                front_focal_mm: self.focal_length_mm - self.front_principal_z,
            }))?;
        Ok(self.rear_principal_z + image_distance)
    }

    /// The object in focus on a film at lens-frame `film_z`, by the same Gaussian equation
    /// [`ParaxialLens::film_z_for_object`] focuses with (so each model names its own focus: a
    /// thin lens's film is not where the real lens's conjugates put it); None when the film is
    /// nearer than the rear focal plane, where no real object is in focus.
    ///
    /// ```
    /// use lensbake::model::ParaxialLens;
    /// use lensbake::paraxial::ObjectPosition;
    /// let lens = ParaxialLens::thin(50.0, 2.0).unwrap();
    /// let film_z = lens.film_z_for_object(6000.0).unwrap();
    /// let Some(ObjectPosition::Finite { distance }) = lens.object_in_focus(film_z) else {
    ///     panic!("a film behind the focal plane has a real object in focus")
    /// };
    /// assert!((distance - 6000.0).abs() < 1e-6);
    /// assert_eq!(lens.object_in_focus(50.0), Some(ObjectPosition::Infinite));
    /// assert_eq!(lens.object_in_focus(40.0), None);
    /// ```
    pub fn object_in_focus(&self, film_z: f64) -> Option<ObjectPosition> {
        let image_distance = film_z - self.rear_principal_z;
        let f = self.focal_length_mm;
        // 1/s = 1/f - 1/s': the object's vergence, zero (to rounding) on the focal plane.
        let vergence = 1.0 / f - 1.0 / image_distance;
        if image_distance <= 0.0 || vergence < -1e-12 / f {
            return None;
        }
        if vergence <= 1e-12 / f {
            return Some(ObjectPosition::Infinite);
        }
        Some(ObjectPosition::Finite {
            distance: 1.0 / vergence - self.front_principal_z,
        })
    }

    /// The Gaussian image distance (behind the rear principal plane) of an object
    /// `object_distance` in front of the front one; None unless it lies beyond the focal length.
    fn image_distance(&self, object_distance: f64) -> Option<f64> {
        (object_distance > self.focal_length_mm)
            .then(|| 1.0 / (1.0 / self.focal_length_mm - 1.0 / object_distance))
    }

    /// The paraxial image of the lens-frame point `object` (in front of the front focal point):
    /// the Gaussian equation about the principal planes along z, lateral magnification
    /// -s'/s across it. Paraxial imaging maps planes to planes, so the images of three points
    /// fix the image of the plane through them (the Scheimpflug rule).
    pub fn image_of(&self, object: [f64; 3]) -> Result<[f64; 3], ModelError> {
        let object_distance = self.front_principal_z - object[2];
        let image_distance =
            self.image_distance(object_distance)
                .ok_or(ModelError::InsideFocalLength {
                    z: object[2],
                    front_focal_mm: self.focal_length_mm - self.front_principal_z,
                })?;
        let magnification = -image_distance / object_distance;
        Ok([
            magnification * object[0],
            magnification * object[1],
            self.rear_principal_z + image_distance,
        ])
    }

    /// The object-space ray for the film-side ray from `film` towards `pupil` (both lens-frame
    /// points): returns a point on the ray and its slopes dx/dz, dy/dz. The f64 statement of what
    /// the shader's `paraxial_lens_ray` computes.
    pub fn object_ray(&self, film: [f64; 3], pupil: [f64; 3]) -> ([f64; 3], [f64; 2]) {
        let t = (self.rear_principal_z - film[2]) / (pupil[2] - film[2]);
        let h = [
            film[0] + t * (pupil[0] - film[0]),
            film[1] + t * (pupil[1] - film[1]),
        ];
        let image_distance = film[2] - self.rear_principal_z;
        let slope = [
            (film[0] - h[0]) / image_distance + h[0] / self.focal_length_mm,
            (film[1] - h[1]) / image_distance + h[1] / self.focal_length_mm,
        ];
        ([h[0], h[1], self.front_principal_z], slope)
    }
}

/// The first-order models of a lens at its design wavelength, stopped down to `f_number`.
#[derive(Clone, Debug, PartialEq)]
pub struct FirstOrderModels {
    /// Focal length EFL, one plane at the entrance pupil holding both principal planes and both
    /// pupils (radius EFL / 2N).
    pub thin: ParaxialLens,
    /// Principal planes and real pupil positions and sizes.
    pub thick: ParaxialLens,
    /// f-number of the lens wide open (paraxial, object at infinity).
    pub wide_open_f_number: f64,
    /// The f-number the models are stopped down to.
    pub f_number: f64,
}

impl FirstOrderModels {
    /// The models at `f_number`, wide open when None.
    pub fn of(system: &LensSystem, f_number: Option<f64>) -> Result<FirstOrderModels, ModelError> {
        if !system.images_behind() {
            return Err(ModelError::ImageInFront);
        }
        let at = system.at(system.design_wavelength_nm());
        let paraxial = wide_open_at_infinity(&at)?;
        paraxial.first_order.require_converging()?;
        let wide_open = paraxial.f_number;
        let f_number = f_number.unwrap_or(wide_open);
        if !(f_number.is_finite() && f_number >= wide_open * (1.0 - 1e-9)) {
            return Err(ModelError::FasterThanLens {
                f_number,
                wide_open,
            });
        }
        crate::limits::check_f_number(f_number, wide_open)?;
        // Pupils scale with the stop, as 1 / f-number.
        let thick = thick_model(&paraxial, wide_open / f_number)?;
        let z = paraxial.entrance_pupil.z;
        let radius = paraxial.first_order.efl / (2.0 * f_number);
        let thin = ParaxialLens {
            focal_length_mm: paraxial.first_order.efl,
            front_principal_z: z,
            rear_principal_z: z,
            entrance_pupil_z: z,
            entrance_pupil_radius_mm: radius,
            exit_pupil_z: z,
            exit_pupil_radius_mm: radius,
        };
        Ok(FirstOrderModels {
            thin,
            thick,
            wide_open_f_number: wide_open,
            f_number,
        })
    }

    /// These models at another wavelength, with the same stop: thick from the paraxial data at
    /// `wavelength_nm` (focal length, principal planes, pupils), thin keeping its plane and
    /// aperture with the focal length at `wavelength_nm` (an ideal thin lens has its stop in
    /// the lens, so only its power disperses).
    pub fn at_wavelength(
        &self,
        system: &LensSystem,
        wavelength_nm: f64,
    ) -> Result<FirstOrderModels, ModelError> {
        let at = system.at_checked(wavelength_nm)?;
        let paraxial = wide_open_at_infinity(&at)?;
        let thick = thick_model(&paraxial, self.wide_open_f_number / self.f_number)?;
        let thin = ParaxialLens {
            focal_length_mm: paraxial.first_order.efl,
            ..self.thin.clone()
        };
        Ok(FirstOrderModels {
            thin,
            thick,
            wide_open_f_number: self.wide_open_f_number,
            f_number: self.f_number,
        })
    }
}

/// The paraxial data of `system` wide open with the object at infinity. The models take their
/// power, principal planes and pupils from it, none of which depends on a field, so it is
/// traced on axis: a lens whose apertures set no largest field (its one surface is the stop)
/// still has its models.
fn wide_open_at_infinity(system: &SystemAt) -> Result<Paraxial, ParaxialError> {
    Paraxial::new(
        system,
        &ParaxialOptions {
            field: Field::Angle { deg: 0.0 },
            ..ParaxialOptions::default()
        },
    )
}

/// The thick model of `paraxial` with its pupils scaled by `pupil_scale` (the stop's).
fn thick_model(paraxial: &Paraxial, pupil_scale: f64) -> Result<ParaxialLens, ModelError> {
    let exit = paraxial
        .exit_pupil
        .as_ref()
        .ok_or(ModelError::ExitPupilAtInfinity)?;
    let first = &paraxial.first_order;
    Ok(ParaxialLens {
        focal_length_mm: first.efl,
        front_principal_z: first.z_front_principal,
        rear_principal_z: first.z_rear_principal,
        entrance_pupil_z: paraxial.entrance_pupil.z,
        entrance_pupil_radius_mm: paraxial.entrance_pupil.diameter / 2.0 * pupil_scale,
        exit_pupil_z: exit.z,
        exit_pupil_radius_mm: exit.diameter / 2.0 * pupil_scale,
    })
}
