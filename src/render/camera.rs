//! Lens models as the renderer sees them, the film, and focusing. All f64, lengths in mm, in the
//! lens frame (z along the axis, light towards +z, origin at the first vertex).

use super::RenderError;
use super::models::{BakedLens, PupilSampling, TracedLens};

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
    pub fn thin(focal_length_mm: f64, f_number: f64) -> Result<ParaxialLens, RenderError> {
        if !(focal_length_mm.is_finite() && focal_length_mm > 0.0) {
            return Err(RenderError::InvalidSetting(format!(
                "focal length must be a positive number of mm, got {focal_length_mm}"
            )));
        }
        if !(f_number.is_finite() && f_number > 0.0) {
            return Err(RenderError::InvalidSetting(format!(
                "f-number must be positive, got {f_number}"
            )));
        }
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
    pub fn film_z_for_object(&self, distance_mm: f64) -> Result<f64, RenderError> {
        let object_distance = self.front_principal_z + distance_mm;
        if !(object_distance > self.focal_length_mm) {
            return Err(RenderError::InvalidSetting(format!(
                "cannot focus at {distance_mm} mm: the object must lie beyond the front focal \
                 point ({:.3} mm in front of the first vertex)",
                self.focal_length_mm - self.front_principal_z
            )));
        }
        let image_distance = 1.0 / (1.0 / self.focal_length_mm - 1.0 / object_distance);
        Ok(self.rear_principal_z + image_distance)
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

/// Which approximation of the lens turns film-side rays into scene rays.
#[derive(Clone, Debug, PartialEq)]
pub enum LensModel {
    /// Ideal thin lens: one principal plane, aperture in it.
    Thin(ParaxialLens),
    /// First-order thick lens: separate principal planes and real pupil positions.
    Thick(ParaxialLens),
    /// The exact sequential trace through every surface.
    Traced(Box<TracedLens>),
    /// A baked lens ray transfer function table.
    Baked(Box<BakedLens>),
}

impl LensModel {
    pub fn name(&self) -> &'static str {
        match self {
            LensModel::Thin(_) => "thin",
            LensModel::Thick(_) => "thick",
            LensModel::Traced(_) => "traced",
            LensModel::Baked(_) => "baked",
        }
    }

    /// The first-order description: the model itself for thin and thick, the thick model of the
    /// lens for traced and baked (it places the eye and sizes the field and layer margins).
    pub fn paraxial(&self) -> &ParaxialLens {
        match self {
            LensModel::Thin(lens) | LensModel::Thick(lens) => lens,
            LensModel::Traced(lens) => &lens.paraxial,
            LensModel::Baked(lens) => &lens.paraxial,
        }
    }

    /// Where lens samples are drawn: the exit pupil for thin and thick, the effective pupil on
    /// the rear vertex plane for traced and baked.
    pub fn pupil_sampling(&self) -> PupilSampling {
        match self {
            LensModel::Thin(lens) | LensModel::Thick(lens) => {
                PupilSampling::disc(lens.exit_pupil_z, lens.exit_pupil_radius_mm)
            }
            LensModel::Traced(lens) => PupilSampling {
                z: lens.rear_plane_z,
                circles: lens.pupil.clone(),
            },
            LensModel::Baked(lens) => PupilSampling {
                z: lens.table.layers[0].frame.rear_plane_z,
                circles: lens.pupil(),
            },
        }
    }
}

/// How the film position is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Focus {
    /// Lens-frame z of the film plane.
    FilmZ(f64),
    /// Distance of the in-focus object plane in front of the first vertex (mm).
    ObjectDistance(f64),
}

/// The sensor: its size, and its shift off the axis (mm).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Film {
    pub width_mm: f64,
    pub height_mm: f64,
    pub shift_mm: [f64; 2],
}

impl Film {
    /// A full-frame sensor cropped to the aspect ratio of `width` x `height` pixels.
    pub fn full_frame_for(width: u32, height: u32) -> Film {
        let aspect = width as f64 / height as f64;
        let (w, h) = if aspect >= 1.5 {
            (36.0, 36.0 / aspect)
        } else {
            (24.0 * aspect, 24.0)
        };
        Film {
            width_mm: w,
            height_mm: h,
            shift_mm: [0.0, 0.0],
        }
    }
}

/// Everything about the camera that the renderer needs.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    pub model: LensModel,
    pub film: Film,
    pub film_z: f64,
}

impl Camera {
    pub fn new(model: LensModel, film: Film, focus: Focus) -> Result<Camera, RenderError> {
        let film_z = match focus {
            Focus::FilmZ(z) => z,
            Focus::ObjectDistance(d) => model.paraxial().film_z_for_object(d)?,
        };
        let rear = model.paraxial().rear_principal_z;
        if !(film_z.is_finite() && film_z > rear) {
            return Err(RenderError::InvalidSetting(format!(
                "film at z = {film_z} mm is not behind the rear principal plane (z = {rear} mm)"
            )));
        }
        Ok(Camera {
            model,
            film,
            film_z,
        })
    }

    /// Largest distance of a film point from the axis (the film corner, shift included).
    pub fn film_corner_radius(&self) -> f64 {
        let f = &self.film;
        (f.width_mm / 2.0 + f.shift_mm[0].abs()).hypot(f.height_mm / 2.0 + f.shift_mm[1].abs())
    }

    /// Lens-frame z of the eye: the entrance-pupil centre, the point layers are peeled from.
    pub fn eye_z(&self) -> f64 {
        self.model.paraxial().entrance_pupil_z
    }

    /// Film point of output pixel coordinate (x, y) in pixels, (0, 0) the top-left corner.
    /// The lens inverts the image, so the top-left output pixel lies at +x, -y on the film.
    pub fn film_point(&self, width: u32, height: u32, x: f64, y: f64) -> [f64; 3] {
        let f = &self.film;
        [
            f.shift_mm[0] + f.width_mm * (0.5 - x / width as f64),
            f.shift_mm[1] + f.height_mm * (y / height as f64 - 0.5),
            self.film_z,
        ]
    }

    /// Tangents of the half field of view (x, y) seen from the eye by chief rays from the film
    /// corners farthest from the axis.
    pub fn half_field_tangents(&self) -> [f64; 2] {
        let lens = self.model.paraxial();
        let f = &self.film;
        let corner = [
            f.width_mm / 2.0 + f.shift_mm[0].abs(),
            f.height_mm / 2.0 + f.shift_mm[1].abs(),
            self.film_z,
        ];
        let (_, slope) = lens.object_ray(corner, [0.0, 0.0, lens.exit_pupil_z]);
        [slope[0].abs(), slope[1].abs()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thin_lens_focus_obeys_gaussian_equation() {
        let lens = ParaxialLens::thin(50.0, 2.0).unwrap();
        let z = lens.film_z_for_object(2000.0).unwrap();
        assert!((1.0 / z + 1.0 / 2000.0 - 1.0 / 50.0).abs() < 1e-15);
        assert!(lens.film_z_for_object(40.0).is_err());
    }

    #[test]
    fn rays_from_one_film_point_meet_at_its_conjugate() {
        // Every ray from a film point must pass through the conjugate object point, whatever
        // the pupil point: the defining property of a perfect (paraxial) lens.
        let mut lens = ParaxialLens::thin(50.0, 2.0).unwrap();
        lens.front_principal_z = 10.0;
        lens.rear_principal_z = 25.0;
        lens.exit_pupil_z = 30.0;
        let film_z = lens.film_z_for_object(1000.0).unwrap();
        let object_z = -1000.0;
        let film = [3.0, -2.0, film_z];
        let mut meet = Vec::new();
        for pupil in [[0.0, 0.0], [5.0, 1.0], [-4.0, 3.0]] {
            let (o, s) = lens.object_ray(film, [pupil[0], pupil[1], lens.exit_pupil_z]);
            let t = object_z - o[2];
            meet.push([o[0] + s[0] * t, o[1] + s[1] * t]);
        }
        for p in &meet[1..] {
            assert!((p[0] - meet[0][0]).abs() < 1e-9 && (p[1] - meet[0][1]).abs() < 1e-9);
        }
        // Lateral magnification -s_o/s' about the principal planes.
        let m = -(1000.0 + 10.0) / (film_z - 25.0);
        assert!((meet[0][0] - 3.0 * m).abs() < 1e-9);
    }
}
