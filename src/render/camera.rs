//! The camera: a lens model, the film, and where the film sits. All f64, lengths in mm, in the
//! lens frame (z along the axis, light towards +z, origin at the first vertex).

use super::RenderError;
use super::chromatic::Chromatic;
use super::focal_surface::FocalSurface;
use crate::model::{LensModel, MAX_PUPIL_BOUND_GROWTH, ParaxialLens, PupilSampling};

/// How the film position is chosen.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Focus {
    /// Lens-frame z of the film plane.
    FilmZ(f64),
    /// Distance of the in-focus object plane in front of the first vertex (mm).
    ObjectDistance(f64),
}

/// The sensor: its size, its shift off the axis (mm), and its tilt about its centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Film {
    pub width_mm: f64,
    pub height_mm: f64,
    pub shift_mm: [f64; 2],
    /// Right-handed rotations (degrees) about the lens-frame x axis, then the y axis, through
    /// the sensor centre: x > 0 moves the sensor's +y half (the bottom of the output image)
    /// away from the lens, y > 0 moves its +x half (the left of the image) towards it.
    pub tilt_deg: [f64; 2],
}

/// The sensor's orientation: its in-plane axes (along +x and +y of an untilted sensor) and its
/// normal (towards +z), all unit lens-frame vectors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilmAxes {
    pub across: [f64; 3],
    pub up: [f64; 3],
    pub normal: [f64; 3],
}

/// Steepest sensor tilt accepted (degrees from the axis): beyond it film points near the edge
/// can reach the lens and a sensor that steep is no longer imaging anything sensible.
pub const MAX_TILT_DEG: f64 = 45.0;

impl FilmAxes {
    /// The axes of a sensor rotated by `tilt_deg` (see [`Film::tilt_deg`]): R = R_y(y) R_x(x).
    pub fn of(tilt_deg: [f64; 2]) -> FilmAxes {
        let (sx, cx) = tilt_deg[0].to_radians().sin_cos();
        let (sy, cy) = tilt_deg[1].to_radians().sin_cos();
        FilmAxes {
            across: [cy, 0.0, -sy],
            up: [sy * sx, cx, cy * sx],
            normal: [sy * cx, -sx, cy * cx],
        }
    }

    /// The tilt (degrees) whose sensor normal is `normal` (any length, pointing either way
    /// along the axis): the inverse of [`FilmAxes::of`].
    pub fn tilt_deg_for_normal(normal: [f64; 3]) -> [f64; 2] {
        let length = (normal[0].powi(2) + normal[1].powi(2) + normal[2].powi(2)).sqrt();
        let sign = if normal[2] < 0.0 { -1.0 } else { 1.0 };
        let n = normal.map(|v| sign * v / length);
        [
            (-n[1]).clamp(-1.0, 1.0).asin().to_degrees(),
            n[0].atan2(n[2]).to_degrees(),
        ]
    }
}

/// A full-frame sensor, width and height in mm.
pub const FULL_FRAME_MM: [f64; 2] = [36.0, 24.0];

impl Film {
    /// A full-frame sensor cropped to the aspect ratio of `width` x `height` pixels.
    pub fn full_frame_for(width: u32, height: u32) -> Film {
        let aspect = width as f64 / height as f64;
        let [full_width, full_height] = FULL_FRAME_MM;
        let (width_mm, height_mm) = if aspect >= full_width / full_height {
            (full_width, full_width / aspect)
        } else {
            (full_height * aspect, full_height)
        };
        Film {
            width_mm,
            height_mm,
            shift_mm: [0.0, 0.0],
            tilt_deg: [0.0, 0.0],
        }
    }

    /// An untilted, unshifted sensor `width_mm` across with the aspect ratio of `width` x
    /// `height` pixels.
    pub fn of_width(width_mm: f64, width: u32, height: u32) -> Film {
        Film {
            width_mm,
            height_mm: width_mm * height as f64 / width as f64,
            shift_mm: [0.0, 0.0],
            tilt_deg: [0.0, 0.0],
        }
    }

    /// The largest sensor with the aspect ratio of `width` x `height` pixels whose corners lie
    /// on a circle `diameter_mm` across.
    pub fn inside_circle(diameter_mm: f64, width: u32, height: u32) -> Film {
        let (w, h) = (width as f64, height as f64);
        Film::of_width(diameter_mm * w / w.hypot(h), width, height)
    }

    pub fn axes(&self) -> FilmAxes {
        FilmAxes::of(self.tilt_deg)
    }

    /// The lens-frame point at sensor coordinates (across, up) mm from the centre, the centre at
    /// lens-frame z `centre_z`.
    pub fn point(&self, centre_z: f64, across: f64, up: f64) -> [f64; 3] {
        let axes = self.axes();
        let centre = [self.shift_mm[0], self.shift_mm[1], centre_z];
        std::array::from_fn(|i| centre[i] + across * axes.across[i] + up * axes.up[i])
    }

    /// The four sensor corners for a centre at z `centre_z`.
    pub fn corners(&self, centre_z: f64) -> [[f64; 3]; 4] {
        let (a, b) = (self.width_mm / 2.0, self.height_mm / 2.0);
        [[-a, -b], [a, -b], [-a, b], [a, b]].map(|[u, v]| self.point(centre_z, u, v))
    }
}

/// Everything about the camera that the renderer needs.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    pub model: LensModel,
    pub film: Film,
    pub film_z: f64,
    /// Each colour channel's lens at its own wavelength; None renders every channel through
    /// `model` (the monochrome path).
    pub chromatic: Option<Chromatic>,
    /// A focus set per pixel ([`Camera::with_focal_surface`]); None focuses the whole sensor
    /// where `film_z` puts it.
    pub pixel_focus: Option<PixelFocus>,
}

/// A focal surface as a camera applies it: each pixel's film point moves along its chief ray
/// (through the paraxial exit-pupil centre, so the pixel keeps looking at the same scene point)
/// until it lies `shift(v) = z'(v) - z'(reference)` further along the axis, z'(v) the paraxial
/// image distance of the focus vergence v the surface gives the pixel and `reference_mm` the
/// distance the film plane itself is focused on.
///
/// For the thin and thick models this is exact: their film-to-scene map is the Gaussian one, so a
/// film point at z'(v) is in focus at exactly 1/v. For Seidel, traced and baked it moves the
/// sensor point by the paraxial difference of image distances, and the model's own map (the
/// exact trace, the table's free-space propagation to its start plane, or the Seidel polynomial
/// of the film plane's conjugate) takes the ray from there: the focus reached is 1/v to the
/// accuracy with which the paraxial difference of image distances matches the real one (the
/// real lens's focus shift with conjugate), and a Seidel model keeps the aberrations of the
/// reference conjugate.
#[derive(Clone, Debug, PartialEq)]
pub struct PixelFocus {
    pub surface: FocalSurface,
    pub reference_mm: f64,
    /// The nearest and furthest axial film shifts (mm) over the surface: those of its points'
    /// vergences, the shift being monotonic in vergence.
    pub shift_range_mm: [f64; 2],
}

/// How far along the axis the film must move from where it focuses `reference_mm` to focus
/// the vergence `vergence` (1/mm, 0 at infinity) instead: the difference of the two paraxial
/// image positions.
fn axial_shift(lens: &ParaxialLens, reference_mm: f64, vergence: f64) -> Result<f64, RenderError> {
    Ok(lens.film_z_for_object(1.0 / vergence)? - lens.film_z_for_object(reference_mm)?)
}

impl Camera {
    pub fn new(model: LensModel, film: Film, focus: Focus) -> Result<Camera, RenderError> {
        let film_z = match focus {
            Focus::FilmZ(z) => z,
            Focus::ObjectDistance(d) => model.paraxial().film_z_for_object(d)?,
        };
        crate::limits::check_position("the film's z (mm)", film_z)?;
        crate::limits::check_length("the film width (mm)", film.width_mm)?;
        crate::limits::check_length("the film height (mm)", film.height_mm)?;
        for shift in film.shift_mm {
            crate::limits::check_position("the film shift (mm)", shift)?;
        }
        let rear = model.paraxial().rear_principal_z;
        if !(film_z.is_finite() && film_z > rear) {
            return Err(RenderError::InvalidSetting(format!(
                "film at z = {film_z} mm is not behind the rear principal plane (z = {rear} mm)"
            )));
        }
        let camera = Camera {
            model,
            film,
            film_z,
            chromatic: None,
            pixel_focus: None,
        };
        camera.check_tilt()?;
        Ok(camera)
    }

    /// This camera with each colour channel traced through its own wavelength's lens; refused
    /// when the channels are of another kind of model than `model`.
    pub fn with_chromatic(self, chromatic: Chromatic) -> Result<Camera, RenderError> {
        chromatic.check_matches(&self.model)?;
        // The channels' common pupil is wider than the model's: the tilt check sees it.
        let camera = Camera {
            chromatic: Some(chromatic),
            ..self
        };
        camera.check_tilt()?;
        Ok(camera)
    }

    /// This camera with its focus set per pixel by `surface`, the film plane being focused at
    /// `reference_mm` (see [`PixelFocus`]). Refused where a point's focus is nearer than the lens
    /// can focus, or moves the sensor into the lens or too far off the plane the pupil bound was
    /// fitted on.
    pub fn with_focal_surface(
        self,
        surface: FocalSurface,
        reference_mm: f64,
    ) -> Result<Camera, RenderError> {
        let lens = self.model.paraxial();
        let [low, high] = surface.vergence_range();
        // A nearer focus (higher vergence) puts the film further back.
        let shift_range_mm = [
            axial_shift(lens, reference_mm, low)?,
            axial_shift(lens, reference_mm, high)?,
        ];
        let camera = Camera {
            pixel_focus: Some(PixelFocus {
                surface,
                reference_mm,
                shift_range_mm,
            }),
            ..self
        };
        camera.check_tilt()?;
        Ok(camera)
    }

    /// Each output pixel's film shift (lens-frame mm, x, y, z and a zero) for a `width` x
    /// `height` image, row-major; empty without a focal surface. See [`PixelFocus`].
    pub fn film_shifts(&self, width: u32, height: u32) -> Result<Vec<[f32; 4]>, RenderError> {
        let Some(focus) = &self.pixel_focus else {
            return Ok(Vec::new());
        };
        let lens = self.model.paraxial();
        let mut shifts = Vec::with_capacity(width as usize * height as usize);
        for y in 0..height {
            for x in 0..width {
                let centre = [x as f64 + 0.5, y as f64 + 0.5];
                let vergence = focus.surface.vergence_at(centre);
                let axial = axial_shift(lens, focus.reference_mm, vergence)?;
                let film = self.film_point(width, height, centre[0], centre[1]);
                let along = axial / (film[2] - lens.exit_pupil_z);
                let shift = [film[0] * along, film[1] * along, axial];
                shifts.push([shift[0] as f32, shift[1] as f32, shift[2] as f32, 0.0]);
            }
        }
        Ok(shifts)
    }

    /// Where lens samples are drawn: the channels' common (conservative) pupil in a chromatic
    /// render, the model's otherwise.
    pub fn pupil_sampling(&self) -> PupilSampling {
        match &self.chromatic {
            Some(chromatic) => chromatic.sampling.clone(),
            None => self.model.pupil_sampling(),
        }
    }

    /// A tilted sensor must stay behind the lens everywhere, and its points off the plane the
    /// effective pupil was fitted on must stay within reach of the pupil bound.
    fn check_tilt(&self) -> Result<(), RenderError> {
        let tilt = self.film.tilt_deg;
        if !(tilt
            .iter()
            .all(|t| t.is_finite() && t.abs() <= MAX_TILT_DEG))
        {
            return Err(RenderError::InvalidSetting(format!(
                "sensor tilt {tilt:?} degrees: each angle must lie within +-{MAX_TILT_DEG}"
            )));
        }
        let sampling = self.pupil_sampling();
        let behind = self.model.paraxial().rear_principal_z.max(sampling.z);
        let bound = sampling.off_plane_bound();
        // A focal surface moves each film point along the axis by a shift within its range (and
        // across by the chief ray's slope, which changes neither test).
        let corners = self
            .film
            .corners(self.film_z)
            .into_iter()
            .flat_map(|corner| {
                self.focus_shift_range()
                    .map(|shift| [corner[0], corner[1], corner[2] + shift])
            });
        for corner in corners {
            if corner[2] <= behind {
                // Untilted, the whole sensor sits there: the focus put it inside the lens (a
                // catadioptric lens forms its image among its surfaces), not a tilt.
                let (sensor, advice) = if self.pixel_focus.is_some() {
                    (
                        "the focal surface's nearest film point",
                        " (focus points less far apart)",
                    )
                } else if tilt == [0.0, 0.0] {
                    ("the sensor", "")
                } else {
                    ("the tilted sensor's corner", " (tilt less)")
                };
                return Err(RenderError::InvalidSetting(format!(
                    "{sensor} at z = {:.3} mm reaches the lens: it must stay behind z = \
                     {behind:.3} mm, the rear principal plane or the plane the exit rays are \
                     sampled on, whichever is further back{advice}",
                    corner[2]
                )));
            }
            if bound.growth(corner[2], self.film_z, sampling.z) > MAX_PUPIL_BOUND_GROWTH {
                return Err(RenderError::InvalidSetting(format!(
                    "the sensor corner at z = {:.3} mm lies {:.3} mm off the film plane the \
                     effective pupil was fitted on (z = {:.3} mm): too far for a useful \
                     conservative pupil bound; tilt less",
                    corner[2],
                    corner[2] - self.film_z,
                    self.film_z
                )));
            }
        }
        Ok(())
    }

    /// The nearest and furthest axial film shifts of the focal surface ([0, 0] without one).
    fn focus_shift_range(&self) -> [f64; 2] {
        self.pixel_focus
            .as_ref()
            .map_or([0.0, 0.0], |focus| focus.shift_range_mm)
    }

    /// Largest distance of a film point from the axis (a film corner, shift and tilt included,
    /// and a focal surface's widening along the chief rays).
    pub fn film_corner_radius(&self) -> f64 {
        let exit_z = self.model.paraxial().exit_pupil_z;
        let furthest = self.focus_shift_range()[0]
            .max(self.focus_shift_range()[1])
            .max(0.0);
        self.film
            .corners(self.film_z)
            .iter()
            .map(|c| c[0].hypot(c[1]) * (1.0 + furthest / (c[2] - exit_z)))
            .fold(0.0, f64::max)
    }

    /// Largest distance of a film point from the film plane z = `film_z` along the axis (zero
    /// for an untilted sensor without a focal surface).
    pub fn film_off_plane(&self) -> f64 {
        let [near, far] = self.focus_shift_range();
        let focus = near.abs().max(far.abs());
        self.film
            .corners(self.film_z)
            .iter()
            .map(|c| (c[2] - self.film_z).abs() + focus)
            .fold(0.0, f64::max)
    }

    /// Lens-frame z of the eye: the entrance-pupil centre, the point layers are peeled from.
    pub fn eye_z(&self) -> f64 {
        self.model.paraxial().entrance_pupil_z
    }

    /// Film point of output pixel coordinate (x, y) in pixels, (0, 0) the top-left corner.
    /// The lens inverts the image, so the top-left output pixel lies at +x, -y on the film.
    pub fn film_point(&self, width: u32, height: u32, x: f64, y: f64) -> [f64; 3] {
        let f = &self.film;
        f.point(
            self.film_z,
            f.width_mm * (0.5 - x / width as f64),
            f.height_mm * (y / height as f64 - 0.5),
        )
    }

    /// Tangents (x/depth, y/depth) of the direction from the eye towards what the film point
    /// `film` sees along its first-order chief ray (through the exit-pupil centre).
    pub fn chief_ray_tangents(&self, film: [f64; 3]) -> [f64; 2] {
        let lens = self.model.paraxial();
        let (_, slope) = lens.object_ray(film, [0.0, 0.0, lens.exit_pupil_z]);
        // Light travels along +z with this slope, so the scene lies at minus it.
        [-slope[0], -slope[1]]
    }

    /// Tangents of the half field of view (x, y) seen from the eye by chief rays from the film
    /// corners: a chief-ray tangent is a linear-fractional function of the film point, so its
    /// extremes over the sensor lie at corners.
    pub fn half_field_tangents(&self) -> [f64; 2] {
        self.film
            .corners(self.film_z)
            .iter()
            .map(|&corner| self.chief_ray_tangents(corner).map(f64::abs))
            .fold([0.0, 0.0], |m, t| [m[0].max(t[0]), m[1].max(t[1])])
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

    #[test]
    fn film_axes_are_orthonormal_and_invert_to_their_tilt() {
        for tilt in [
            [0.0, 0.0],
            [12.0, 0.0],
            [0.0, -20.0],
            [7.5, 31.0],
            [-40.0, 3.0],
        ] {
            let a = FilmAxes::of(tilt);
            let dot = |u: [f64; 3], v: [f64; 3]| u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
            for (u, v, want) in [
                (a.across, a.across, 1.0),
                (a.up, a.up, 1.0),
                (a.normal, a.normal, 1.0),
                (a.across, a.up, 0.0),
                (a.across, a.normal, 0.0),
                (a.up, a.normal, 0.0),
            ] {
                assert!((dot(u, v) - want).abs() < 1e-15, "{tilt:?}");
            }
            // Right-handed: across x up = normal.
            let c = [
                a.across[1] * a.up[2] - a.across[2] * a.up[1],
                a.across[2] * a.up[0] - a.across[0] * a.up[2],
                a.across[0] * a.up[1] - a.across[1] * a.up[0],
            ];
            assert!((0..3).all(|i| (c[i] - a.normal[i]).abs() < 1e-15));
            let back = FilmAxes::tilt_deg_for_normal(a.normal.map(|v| -3.0 * v));
            assert!((back[0] - tilt[0]).abs() < 1e-12 && (back[1] - tilt[1]).abs() < 1e-12);
        }
        // The documented senses: x > 0 takes +y away from the lens, y > 0 takes +x towards it.
        assert!(FilmAxes::of([10.0, 0.0]).up[2] > 0.0);
        assert!(FilmAxes::of([0.0, 10.0]).across[2] < 0.0);
    }

    #[test]
    fn tilted_sensor_turns_about_its_shifted_centre() {
        let lens = ParaxialLens::thin(50.0, 2.0).unwrap();
        let film = Film {
            width_mm: 36.0,
            height_mm: 24.0,
            shift_mm: [3.0, -2.0],
            tilt_deg: [6.0, -9.0],
        };
        let camera = Camera::new(LensModel::Thin(lens), film, Focus::FilmZ(52.0)).unwrap();
        let centre = camera.film_point(360, 240, 180.0, 120.0);
        assert!((centre[0] - 3.0).abs() < 1e-12 && (centre[1] + 2.0).abs() < 1e-12);
        assert!((centre[2] - 52.0).abs() < 1e-12);
        // Every film point lies on the plane through the centre with the sensor's normal, and
        // the corners keep the sensor's size.
        let n = film.axes().normal;
        for (x, y) in [(0.0, 0.0), (360.0, 0.0), (0.0, 240.0), (97.0, 13.0)] {
            let p = camera.film_point(360, 240, x, y);
            let d = [p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]];
            assert!((d[0] * n[0] + d[1] * n[1] + d[2] * n[2]).abs() < 1e-12);
        }
        let a = camera.film_point(360, 240, 0.0, 0.0);
        let b = camera.film_point(360, 240, 360.0, 240.0);
        let diagonal =
            ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
        assert!((diagonal - 36.0f64.hypot(24.0)).abs() < 1e-12);
    }

    #[test]
    fn untilted_film_points_are_the_plain_grid() {
        let lens = ParaxialLens::thin(50.0, 2.0).unwrap();
        let film = Film {
            shift_mm: [1.5, 0.25],
            ..Film::full_frame_for(300, 200)
        };
        let camera = Camera::new(LensModel::Thin(lens), film, Focus::FilmZ(55.0)).unwrap();
        let p = camera.film_point(300, 200, 12.25, 190.5);
        assert_eq!(
            p,
            [
                1.5 + 36.0 * (0.5 - 12.25 / 300.0),
                0.25 + 24.0 * (190.5 / 200.0 - 0.5),
                55.0
            ]
        );
    }

    #[test]
    fn a_sensor_tilted_into_the_lens_is_refused() {
        let lens = ParaxialLens::thin(50.0, 2.0).unwrap();
        let film = Film {
            tilt_deg: [0.0, 40.0],
            ..Film::full_frame_for(300, 200)
        };
        // The +x edge swings 18 sin 40 = 11.6 mm towards the lens from 52 mm: still behind it.
        assert!(Camera::new(LensModel::Thin(lens.clone()), film, Focus::FilmZ(52.0)).is_ok());
        // From 10 mm behind the lens plane it would cross it.
        let err = Camera::new(LensModel::Thin(lens.clone()), film, Focus::FilmZ(10.0));
        assert!(
            matches!(err, Err(RenderError::InvalidSetting(m)) if m.contains("reaches the lens"))
        );
        let steep = Film {
            tilt_deg: [60.0, 0.0],
            ..film
        };
        assert!(Camera::new(LensModel::Thin(lens), steep, Focus::FilmZ(52.0)).is_err());
    }

    #[test]
    fn paraxial_image_agrees_with_the_rays_through_it() {
        let mut lens = ParaxialLens::thin(50.0, 2.0).unwrap();
        lens.front_principal_z = 10.0;
        lens.rear_principal_z = 25.0;
        lens.exit_pupil_z = 30.0;
        let object = [40.0, -25.0, -700.0];
        let image = lens.image_of(object).unwrap();
        // The film-side rays from the image point all leave towards the object point.
        for pupil in [[0.0, 0.0], [6.0, -2.0], [-3.0, 5.0]] {
            let (o, s) = lens.object_ray(image, [pupil[0], pupil[1], lens.exit_pupil_z]);
            let t = object[2] - o[2];
            assert!((o[0] + s[0] * t - object[0]).abs() < 1e-9);
            assert!((o[1] + s[1] * t - object[1]).abs() < 1e-9);
        }
        assert!(lens.image_of([0.0, 0.0, -30.0]).is_err());
    }
}
