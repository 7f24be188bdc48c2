//! Focusing the sensor: on the scene point under a picked pixel, and on the plane through three
//! picked scene points by tilting the sensor (the Scheimpflug rule for the paraxial models, the
//! real-ray best-focus points for the exact lens).
//!
//! A pixel is mapped to the scene along its first-order chief ray (through the exit- and
//! entrance-pupil centres) and the nearest layer of a layered depth image gives the depth there;
//! the point is unprojected through the entrance-pupil centre, the eye the layers were peeled
//! from.

use super::RenderError;
use super::camera::{Camera, Film, FilmAxes, MAX_TILT_DEG};
use super::layers::{LayeredDepthImage, View};
use crate::model::{ParaxialLens, TracedLens};
use crate::trace::{Ray, Travel};
use glam::DVec3;
use nalgebra::{Matrix3, Vector3};

/// Where the sensor sits: the lens-frame z of its centre and its tilt (see [`Film::tilt_deg`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorPlacement {
    pub film_z: f64,
    pub tilt_deg: [f64; 2],
}

/// The layer pixel (column, row) of `view` whose footprint holds the direction with tangents
/// `tan` (x/depth, y/depth); None outside the view. The inverse of `View::pixel_tangents`.
pub fn layer_pixel(view: &View, tan: [f64; 2]) -> Option<(u32, u32)> {
    let column = ((tan[0] / view.tan_half[0] + 1.0) / 2.0 * view.width as f64).floor();
    let row = ((1.0 - tan[1] / view.tan_half[1]) / 2.0 * view.height as f64).floor();
    let inside = |v: f64, size: u32| v >= 0.0 && v < size as f64;
    (inside(column, view.width) && inside(row, view.height)).then_some((column as u32, row as u32))
}

/// The scene point seen at the centre of output pixel `pixel` of a `width` x `height` frame of
/// `camera`: the nearest layer of `ldi` along the pixel's first-order chief ray, unprojected
/// through the entrance-pupil centre (lens-frame mm).
pub fn scene_point_under(
    camera: &Camera,
    ldi: &LayeredDepthImage,
    width: u32,
    height: u32,
    pixel: [u32; 2],
) -> Result<[f64; 3], RenderError> {
    let [x, y] = pixel;
    if x >= width || y >= height {
        return Err(RenderError::InvalidSetting(format!(
            "pixel {x},{y} lies outside the {width}x{height} image"
        )));
    }
    let film = camera.film_point(width, height, x as f64 + 0.5, y as f64 + 0.5);
    let tan = camera.chief_ray_tangents(film);
    let depth = layer_pixel(&ldi.view, tan)
        .and_then(|(column, row)| ldi.nearest_depth(column, row))
        .ok_or_else(|| {
            RenderError::InvalidSetting(format!("nothing under pixel {x},{y} to focus on"))
        })? as f64;
    Ok([tan[0] * depth, tan[1] * depth, camera.eye_z() - depth])
}

/// Diameter (mm) of the paraxial blur spot that an object `distance_mm` in front of the first
/// vertex makes on a film at lens-frame z `film_z`: the cone from the exit pupil to the
/// object's image, cut by the film. None where the object has no real image (inside the front
/// focal length). For a thin lens it is the textbook circle of confusion
/// A f |s - s_f| / (s (s_f - f)).
///
/// ```
/// use lensbake::model::ParaxialLens;
/// use lensbake::render::focus::blur_diameter_mm;
/// let lens = ParaxialLens::thin(50.0, 2.0).unwrap();
/// let film_z = lens.film_z_for_object(2000.0).unwrap();
/// let c = blur_diameter_mm(&lens, film_z, 6000.0).unwrap();
/// let textbook = 25.0 * 50.0 * (6000.0f64 - 2000.0).abs() / (6000.0 * (2000.0 - 50.0));
/// assert!((c - textbook).abs() < 1e-12);
/// assert_eq!(blur_diameter_mm(&lens, film_z, 2000.0), Some(0.0));
/// ```
pub fn blur_diameter_mm(lens: &ParaxialLens, film_z: f64, distance_mm: f64) -> Option<f64> {
    let image_z = lens.film_z_for_object(distance_mm).ok()?;
    Some(2.0 * lens.exit_pupil_radius_mm * (film_z - image_z).abs() / (image_z - lens.exit_pupil_z))
}

/// Which output pixels of a `width` x `height` frame of `camera` see a surface of `ldi` within
/// the zone of focus: the surface under the pixel (along its first-order chief ray) blurs to a
/// paraxial spot under one pixel across on the pixel's film point (a focal surface's shift
/// included). Row-major; false where nothing is under a pixel.
pub fn focus_zone(
    camera: &Camera,
    ldi: &LayeredDepthImage,
    width: u32,
    height: u32,
) -> Result<Vec<bool>, RenderError> {
    let shifts = camera.film_shifts(width, height)?;
    let pitch = camera.film.width_mm / width as f64;
    let lens = camera.model.paraxial();
    let mut zone = Vec::with_capacity(width as usize * height as usize);
    for y in 0..height {
        for x in 0..width {
            let film = camera.film_point(width, height, x as f64 + 0.5, y as f64 + 0.5);
            let shift = shifts
                .get((y * width + x) as usize)
                .map_or(0.0, |s| s[2] as f64);
            let tan = camera.chief_ray_tangents(film);
            let depth = layer_pixel(&ldi.view, tan).and_then(|(c, r)| ldi.nearest_depth(c, r));
            let sharp = depth.and_then(|depth| {
                // The surface's distance in front of the first vertex, from the eye's depth.
                let distance = depth as f64 - camera.eye_z();
                blur_diameter_mm(lens, film[2] + shift, distance)
            });
            zone.push(sharp.is_some_and(|c| c < pitch));
        }
    }
    Ok(zone)
}

/// The centre z that puts the lens-frame point `image` on the sensor `film` (its shift and tilt
/// kept): the plane through `image` with the sensor's normal, met at the sensor centre.
pub fn film_z_through(film: &Film, image: [f64; 3]) -> f64 {
    let n = film.axes().normal;
    image[2] + (n[0] * (image[0] - film.shift_mm[0]) + n[1] * (image[1] - film.shift_mm[1])) / n[2]
}

/// The film z that focuses `camera`'s sensor (tilt and shift kept) on the scene point under
/// output pixel `pixel`: the point's paraxial image through the camera's first-order model.
pub fn film_z_for_pixel(
    camera: &Camera,
    ldi: &LayeredDepthImage,
    width: u32,
    height: u32,
    pixel: [u32; 2],
) -> Result<f64, RenderError> {
    let object = scene_point_under(camera, ldi, width, height, pixel)?;
    let image = camera.model.paraxial().image_of(object)?;
    Ok(film_z_through(&camera.film, image))
}

/// The sensor placement (shift of `film` kept) whose plane passes through three image points.
pub fn placement_through(
    film: &Film,
    points: [[f64; 3]; 3],
) -> Result<SensorPlacement, RenderError> {
    let [p0, p1, p2] = points.map(DVec3::from);
    let (a, b) = (p1 - p0, p2 - p0);
    let normal = a.cross(b);
    // The sine of the smallest angle of the triangle the points span, near zero when collinear.
    let spread = normal.length() / (a.length() * b.length()).max(f64::MIN_POSITIVE);
    if spread.is_nan() || spread <= 1e-9 {
        return Err(RenderError::InvalidSetting(
            "the three focus points lie on one line: they fix no plane".into(),
        ));
    }
    let tilt_deg = FilmAxes::tilt_deg_for_normal(normal.to_array());
    if !(tilt_deg.iter().all(|t| t.abs() <= MAX_TILT_DEG)) {
        return Err(RenderError::InvalidSetting(format!(
            "the plane through the focus points needs a sensor tilt of ({:.2}, {:.2}) degrees, \
             beyond +-{MAX_TILT_DEG}",
            tilt_deg[0], tilt_deg[1]
        )));
    }
    let tilted = Film { tilt_deg, ..*film };
    Ok(SensorPlacement {
        film_z: film_z_through(&tilted, points[0]),
        tilt_deg,
    })
}

/// The Scheimpflug rule for a paraxial lens: paraxial imaging through the principal planes
/// maps planes to planes, so the sensor plane conjugate to the plane through three object
/// points is the plane through their images (it meets the rear principal plane on the line
/// where the object plane meets the front one).
pub fn paraxial_focus_plane(
    lens: &ParaxialLens,
    film: &Film,
    objects: [[f64; 3]; 3],
) -> Result<SensorPlacement, RenderError> {
    let images = [
        lens.image_of(objects[0])?,
        lens.image_of(objects[1])?,
        lens.image_of(objects[2])?,
    ];
    placement_through(film, images)
}

/// Points across the entrance pupil (as a fraction of its radius) that a real-ray bundle is
/// aimed at: a square grid clipped to a disc wider than the paraxial pupil, so pupil
/// aberration and vignetting are decided by the trace, not assumed.
const BUNDLE_GRID: usize = 32;
const BUNDLE_REACH: f64 = 1.5;
/// Fewest passing rays that make a bundle.
const BUNDLE_MIN_RAYS: usize = 16;

/// The image-side rays (a point on each, unit direction) of the rays from `object` that pass
/// the stopped-down lens, aimed over its entrance pupil.
fn image_bundle(lens: &TracedLens, object: [f64; 3]) -> Result<Vec<Ray>, RenderError> {
    let pupil_z = lens.paraxial.entrance_pupil_z;
    let reach = BUNDLE_REACH * lens.paraxial.entrance_pupil_radius_mm;
    let mut rays = Vec::new();
    for i in 0..BUNDLE_GRID {
        for j in 0..BUNDLE_GRID {
            let at = |k: usize| reach * (2.0 * (k as f64 + 0.5) / BUNDLE_GRID as f64 - 1.0);
            let target = [at(i), at(j), pupil_z];
            if target[0].hypot(target[1]) > reach {
                continue;
            }
            let direction = DVec3::from(target) - DVec3::from(object);
            let Ok(ray) = Ray::new(object, direction.to_array()) else {
                continue;
            };
            let traced = lens.tracer.trace(ray, Travel::Forward);
            if traced.outcome.is_ok() {
                rays.push(traced.ray);
            }
        }
    }
    if rays.len() < BUNDLE_MIN_RAYS {
        return Err(RenderError::InvalidSetting(format!(
            "only {} rays from the point ({:.1}, {:.1}, {:.1}) mm pass the lens: too few to \
             find its focus",
            rays.len(),
            object[0],
            object[1],
            object[2]
        )));
    }
    Ok(rays)
}

/// The real-ray best focus of a point: the point nearest, in the least-squares sense, to every
/// image-side ray of a bundle from `object` filling the stopped-down lens (the centre of the
/// smallest blur, aberrations included).
pub fn best_focus_point(lens: &TracedLens, object: [f64; 3]) -> Result<[f64; 3], RenderError> {
    let rays = image_bundle(lens, object)?;
    let mut normal_matrix = Matrix3::zeros();
    let mut rhs = Vector3::zeros();
    for ray in &rays {
        let d = Vector3::from(ray.direction());
        let projector = Matrix3::identity() - d * d.transpose();
        normal_matrix += projector;
        rhs += projector * Vector3::from(ray.position());
    }
    let solution = normal_matrix.lu().solve(&rhs).ok_or_else(|| {
        RenderError::InvalidSetting("the rays from a focus point are parallel: no focus".into())
    })?;
    Ok([solution[0], solution[1], solution[2]])
}

/// RMS radius (mm) of the spot that the real rays from `object` make on the sensor plane
/// through `placement` (about the spot's centroid): the residual defocus of that point.
pub fn spot_rms_on_sensor(
    lens: &TracedLens,
    film: &Film,
    placement: &SensorPlacement,
    object: [f64; 3],
) -> Result<f64, RenderError> {
    let rays = image_bundle(lens, object)?;
    let normal = DVec3::from(FilmAxes::of(placement.tilt_deg).normal);
    let centre = DVec3::new(film.shift_mm[0], film.shift_mm[1], placement.film_z);
    let hits: Vec<DVec3> = rays
        .iter()
        .map(|ray| {
            let (o, d) = (DVec3::from(ray.position()), DVec3::from(ray.direction()));
            let t = normal.dot(centre - o) / normal.dot(d);
            o + t * d
        })
        .collect();
    let count = hits.len() as f64;
    let mean = hits.iter().sum::<DVec3>() / count;
    let squared = hits
        .iter()
        .map(|h| (*h - mean).length_squared())
        .sum::<f64>();
    Ok((squared / count).sqrt())
}

/// The sensor plane through the real-ray best-focus points of three object points.
pub fn real_ray_focus_plane(
    lens: &TracedLens,
    film: &Film,
    objects: [[f64; 3]; 3],
) -> Result<SensorPlacement, RenderError> {
    let foci = [
        best_focus_point(lens, objects[0])?,
        best_focus_point(lens, objects[1])?,
        best_focus_point(lens, objects[2])?,
    ];
    placement_through(film, foci)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn thick_lens() -> ParaxialLens {
        let mut lens = ParaxialLens::thin(50.0, 2.0).unwrap();
        lens.front_principal_z = 10.0;
        lens.rear_principal_z = 25.0;
        lens.entrance_pupil_z = 12.0;
        lens.exit_pupil_z = 30.0;
        lens
    }

    /// A point of the object plane through (0, 0, -990) with z = -990 - 2.5 x + 1.2 y.
    fn on_object_plane(x: f64, y: f64) -> [f64; 3] {
        [x, y, -990.0 - 2.5 * x + 1.2 * y]
    }

    fn film() -> Film {
        Film {
            shift_mm: [1.0, -0.5],
            ..Film::full_frame_for(300, 200)
        }
    }

    #[test]
    fn paraxial_focus_plane_holds_every_image_of_the_object_plane() {
        let lens = thick_lens();
        let objects =
            [[-80.0, -40.0], [90.0, -30.0], [10.0, 70.0]].map(|[x, y]| on_object_plane(x, y));
        let placement = paraxial_focus_plane(&lens, &film(), objects).unwrap();
        let sensor = Film {
            tilt_deg: placement.tilt_deg,
            ..film()
        };
        let n = sensor.axes().normal;
        let centre = [1.0, -0.5, placement.film_z];
        // Paraxial imaging is a collineation: every other point of the plane images onto the
        // sensor plane too.
        for (x, y) in [(0.0, 0.0), (-150.0, 120.0), (200.0, 35.0), (60.0, -110.0)] {
            let image = lens.image_of(on_object_plane(x, y)).unwrap();
            let off = DVec3::from(n).dot(DVec3::from(image) - DVec3::from(centre));
            assert!(
                off.abs() < 1e-9,
                "({x}, {y}) images {off} mm off the sensor"
            );
        }
        assert!(placement.tilt_deg[0].abs() > 0.1 && placement.tilt_deg[1].abs() > 0.1);
    }

    #[test]
    fn object_and_sensor_planes_hinge_on_one_line_through_the_principal_planes() {
        // The Scheimpflug hinge rule for a thick lens: the object plane meets the front
        // principal plane on the same (x, y) line on which the sensor plane meets the rear one.
        let lens = thick_lens();
        let objects =
            [[-80.0, -40.0], [90.0, -30.0], [10.0, 70.0]].map(|[x, y]| on_object_plane(x, y));
        let placement = paraxial_focus_plane(&lens, &film(), objects).unwrap();
        let object_normal = DVec3::new(2.5, -1.2, 1.0);
        let object_line = DVec3::new(
            object_normal.x,
            object_normal.y,
            object_normal.dot(DVec3::from(objects[0])) - object_normal.z * lens.front_principal_z,
        );
        let n = DVec3::from(FilmAxes::of(placement.tilt_deg).normal);
        let centre = DVec3::new(1.0, -0.5, placement.film_z);
        let sensor_line = DVec3::new(n.x, n.y, n.dot(centre) - n.z * lens.rear_principal_z);
        // a x + b y = c for both: the coefficient vectors are parallel.
        let c = object_line.cross(sensor_line);
        let scale = object_line.length() * sensor_line.length();
        assert!(
            c.length() < 1e-12 * scale,
            "hinge lines differ: {object_line:?} vs {sensor_line:?}"
        );
    }

    #[test]
    fn collinear_or_near_points_are_refused() {
        let lens = thick_lens();
        let line = [
            on_object_plane(0.0, 0.0),
            on_object_plane(10.0, 0.0),
            on_object_plane(20.0, 0.0),
        ];
        let err = paraxial_focus_plane(&lens, &film(), line).unwrap_err();
        assert!(err.to_string().contains("one line"), "{err}");
        let too_near = [
            [0.0, 0.0, -40.0],
            on_object_plane(10.0, 0.0),
            on_object_plane(0.0, 10.0),
        ];
        assert!(paraxial_focus_plane(&lens, &film(), too_near).is_err());
    }

    #[test]
    fn layer_pixel_inverts_pixel_tangents() {
        let view = View {
            eye_z: 0.0,
            tan_half: [0.4, 0.25],
            width: 40,
            height: 30,
        };
        for (column, row) in [(0, 0), (39, 29), (17, 4)] {
            assert_eq!(
                layer_pixel(&view, view.pixel_tangents(column, row)),
                Some((column, row))
            );
        }
        assert_eq!(layer_pixel(&view, [0.41, 0.0]), None);
    }
}
