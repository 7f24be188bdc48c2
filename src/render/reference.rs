//! The accuracy yardstick: a CPU distribution ray tracer in f64 that follows each lens ray into
//! the scene's true geometry (its panels, not their depth-peeled layers). It draws exactly the
//! samples the IBRT kernel draws, so the difference between the two images is the cost of the
//! layered representation, not sampling noise.

use super::camera::Camera;
use super::chromatic::{ChannelLenses, Chromatic, inside_exit_pupil};
use super::image::RgbImage;
use super::kernel::{PixelScrambles, concentric_disc};
use super::mesh_trace::TracedMesh;
use super::scene::Scene;
use super::{RenderError, RenderSettings};
use crate::lrtf::{self, Lookup};
use crate::model::{BakedLens, LensModel, ParaxialLens};
use crate::trace::{Tracer, Travel};
use rayon::prelude::*;

/// A point on an object ray and the direction light travels along it (towards +z).
type ObjectRay = ([f64; 3], [f64; 3]);

fn paraxial_object_ray(lens: &ParaxialLens, film: [f64; 3], pupil: [f64; 3]) -> ObjectRay {
    let (origin, slope) = lens.object_ray(film, pupil);
    (origin, [slope[0], slope[1], 1.0])
}

fn traced_object_ray(tracer: &Tracer, film: [f64; 3], pupil: [f64; 3]) -> Option<ObjectRay> {
    let towards = [pupil[0] - film[0], pupil[1] - film[1], pupil[2] - film[2]];
    let ray = crate::trace::Ray::new(film, towards).ok()?;
    let traced = tracer.trace(ray, Travel::Backward);
    traced
        .outcome
        .is_ok()
        .then(|| (traced.ray.position(), traced.ray.direction().map(|v| -v)))
}

fn baked_object_ray(
    lens: &BakedLens,
    layer: usize,
    film: [f64; 3],
    pupil: [f64; 3],
) -> Option<ObjectRay> {
    let towards = [pupil[0] - film[0], pupil[1] - film[1], pupil[2] - film[2]];
    let length = (towards[0].powi(2) + towards[1].powi(2) + towards[2].powi(2)).sqrt();
    let ray = lrtf::Ray {
        origin: film,
        direction: towards.map(|v| v / length),
    };
    match lens.table.lookup_layer(layer, &ray, lens.stop_radius) {
        Lookup::Passes(out) => Some((out.origin, out.direction.map(|v| -v))),
        Lookup::Blocked | Lookup::OutsideDomain => None,
    }
}

/// The object ray for the film-side ray from `film` through `pupil`, by the camera's model in
/// f64; None when the lens blocks it.
fn object_ray(model: &LensModel, film: [f64; 3], pupil: [f64; 3]) -> Option<ObjectRay> {
    match model {
        LensModel::Thin(lens) | LensModel::Thick(lens) => {
            Some(paraxial_object_ray(lens, film, pupil))
        }
        LensModel::Seidel(lens) => lens
            .object_ray(film, pupil)
            .map(|(origin, slope)| (origin, [slope[0], slope[1], 1.0])),
        LensModel::Traced(lens) => traced_object_ray(&lens.tracer, film, pupil),
        LensModel::Baked(lens) => baked_object_ray(lens, lens.layer, film, pupil),
    }
}

/// Channel `channel`'s object ray in a chromatic render (paraxial channels pass only rays inside
/// their own exit pupil, as the kernel's do).
fn channel_object_ray(
    model: &LensModel,
    chromatic: &Chromatic,
    channel: usize,
    film: [f64; 3],
    pupil: [f64; 3],
) -> Option<ObjectRay> {
    match (&chromatic.lenses, model) {
        (ChannelLenses::Paraxial(lenses), _) => {
            let lens = &lenses[channel];
            inside_exit_pupil(lens, film, pupil).then(|| paraxial_object_ray(lens, film, pupil))
        }
        (ChannelLenses::Traced(lenses), _) => {
            traced_object_ray(&lenses[channel].tracer, film, pupil)
        }
        (ChannelLenses::Baked(layers), LensModel::Baked(lens)) => {
            baked_object_ray(lens, layers[channel], film, pupil)
        }
        (ChannelLenses::Baked(_), _) => None,
    }
}

/// Scene geometry the reference can follow a ray into.
pub trait TrueGeometry: Sync {
    /// The radiance seen along the object-space ray through `origin` with `direction` (light
    /// travelling towards +z), followed back into the scene.
    fn radiance_along(&self, origin: [f64; 3], direction: [f64; 3]) -> [f32; 3];
}

impl TrueGeometry for Scene {
    fn radiance_along(&self, origin: [f64; 3], direction: [f64; 3]) -> [f32; 3] {
        Scene::radiance_along(self, origin, direction)
    }
}

impl TrueGeometry for TracedMesh<'_> {
    fn radiance_along(&self, origin: [f64; 3], direction: [f64; 3]) -> [f32; 3] {
        self.radiance_towards(origin, direction.map(|d| -d))
    }
}

/// Lens samples per film point in [`ray_reach_tangents`]: the sampling circle's centre and this
/// many points on its rim.
const REACH_RIM_SAMPLES: usize = 16;

/// The largest |x| / depth and |y| / depth, seen from the eye, that the model's object rays reach
/// at depths from `nearest_depth_mm` to infinity, over rays from the film's corners and edge
/// midpoints through the centre and the rim of their pupil circle (f64, `object_ray`). The
/// extremes of a ray's x / depth lie at the nearest depth or at infinity (it is linear in
/// 1 / depth), and a radially monotonic lens sends its outermost rays from the film's rim.
pub fn ray_reach_tangents(camera: &Camera, nearest_depth_mm: f64) -> [f64; 2] {
    let sampling = camera.pupil_sampling();
    let bound = sampling.off_plane_bound();
    let eye_z = camera.eye_z();
    let f = &camera.film;
    let nearest = nearest_depth_mm.max(1e-3);
    let mut reach = [0.0f64; 2];
    for (sx, sy) in [
        (-1, -1),
        (-1, 0),
        (-1, 1),
        (0, -1),
        (0, 1),
        (1, -1),
        (1, 0),
        (1, 1),
    ] {
        // A hair inside the rim, as every pixel sample lies: a table covering exactly this film
        // must not find its own corner outside its domain by rounding.
        let inside = 1.0 - 1e-9;
        let film = f.point(
            camera.film_z,
            0.5 * f.width_mm * sx as f64 * inside,
            0.5 * f.height_mm * sy as f64 * inside,
        );
        let (centre, radius) = sampling.disc_for(&bound, film, camera.film_z);
        let rim = (0..REACH_RIM_SAMPLES).map(|k| {
            let angle = std::f64::consts::TAU * k as f64 / REACH_RIM_SAMPLES as f64;
            [angle.cos(), angle.sin()]
        });
        for disc in std::iter::once([0.0, 0.0]).chain(rim) {
            let pupil = [
                centre[0] + radius * disc[0],
                centre[1] + radius * disc[1],
                sampling.z,
            ];
            let Some((origin, direction)) = object_ray(&camera.model, film, pupil) else {
                continue;
            };
            // Rays that do not travel into the scene reach no depth.
            if direction[2] > 0.0 {
                let t = (eye_z - nearest - origin[2]) / direction[2];
                for axis in 0..2 {
                    let at_infinity = (direction[axis] / direction[2]).abs();
                    let at_nearest = (origin[axis] + t * direction[axis]).abs() / nearest;
                    if at_infinity.is_finite() && at_nearest.is_finite() {
                        reach[axis] = reach[axis].max(at_infinity).max(at_nearest);
                    }
                }
            }
        }
    }
    reach
}

/// Renders `scene` through `camera` with `settings.samples_per_pixel` samples per pixel, in f64,
/// with the kernel's samples and weights (pupil circle per film radius, widened off the fitted
/// plane; the disc's projected solid angle times the sensor's cosine, relative to the paraxial
/// exit pupil). With a traced camera this is the exact lens against the true geometry: the
/// yardstick for every model and for the layers.
pub fn render_reference(
    camera: &Camera,
    scene: &(impl TrueGeometry + ?Sized),
    settings: &RenderSettings,
) -> Result<RgbImage, RenderError> {
    settings.check()?;
    if let Some(chromatic) = &camera.chromatic {
        chromatic.check_matches(&camera.model)?;
    }
    let lens = camera.model.paraxial();
    let sampling = camera.pupil_sampling();
    let exit_distance = camera.film_z - lens.exit_pupil_z;
    let reference_solid_angle =
        std::f64::consts::PI * lens.exit_pupil_radius_mm.powi(2) / exit_distance.powi(2);
    let weight_scale = std::f64::consts::PI / reference_solid_angle;
    let bound = sampling.off_plane_bound();
    let normal = camera.film.axes().normal;
    let (width, height, spp) = (settings.width, settings.height, settings.samples_per_pixel);
    let pixels = (0..width * height)
        .into_par_iter()
        .map(|pixel| {
            let (x, y) = (pixel % width, pixel / width);
            let scrambles = PixelScrambles::new(settings.seed, pixel);
            let mut sum = [0.0f64; 3];
            for index in 0..spp {
                let (lens_u, jitter) = scrambles.sample(index, spp);
                let film = camera.film_point(
                    width,
                    height,
                    x as f64 + jitter[0] as f64,
                    y as f64 + jitter[1] as f64,
                );
                let (centre, radius) = sampling.disc_for(&bound, film, camera.film_z);
                let disc = concentric_disc(lens_u);
                let pupil = [
                    centre[0] + radius * disc[0] as f64,
                    centre[1] + radius * disc[1] as f64,
                    sampling.z,
                ];
                let d = [pupil[0] - film[0], pupil[1] - film[1], pupil[2] - film[2]];
                let distance_sq = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
                // Disc area times cos(at the pupil) cos(at the sensor) / distance^2.
                let cosines = d[2].abs()
                    * (d[0] * normal[0] + d[1] * normal[1] + d[2] * normal[2]).abs()
                    / distance_sq;
                let weight = weight_scale * radius * radius * cosines / distance_sq;
                match &camera.chromatic {
                    None => {
                        let Some((origin, direction)) = object_ray(&camera.model, film, pupil)
                        else {
                            continue;
                        };
                        let radiance = scene.radiance_along(origin, direction);
                        for (acc, c) in sum.iter_mut().zip(radiance) {
                            *acc += weight * c as f64;
                        }
                    }
                    Some(chromatic) => {
                        for (channel, acc) in sum.iter_mut().enumerate() {
                            let ray =
                                channel_object_ray(&camera.model, chromatic, channel, film, pupil);
                            if let Some((origin, direction)) = ray {
                                let radiance = scene.radiance_along(origin, direction);
                                *acc += weight * radiance[channel] as f64;
                            }
                        }
                    }
                }
            }
            sum.map(|s| (s / spp as f64) as f32)
        })
        .collect();
    Ok(RgbImage {
        width,
        height,
        pixels,
    })
}

/// Peak signal-to-noise ratio (dB) of `image` against `reference`, peak = 1 after clamping both
/// to [0, 1] (the display range; emitters saturate in both).
/// [`psnr`] as reports print it: dB to one decimal, or `identical` for images without a
/// difference (an infinite PSNR, which no table or line should show as `inf`).
pub fn psnr_text(db: f64) -> String {
    if db.is_finite() {
        format!("{db:.1} dB")
    } else {
        "identical".into()
    }
}

pub fn psnr(image: &RgbImage, reference: &RgbImage) -> f64 {
    let mut squared = 0.0;
    for (a, b) in image.pixels.iter().zip(&reference.pixels) {
        for c in 0..3 {
            let d = a[c].clamp(0.0, 1.0) as f64 - b[c].clamp(0.0, 1.0) as f64;
            squared += d * d;
        }
    }
    let mse = squared / (3 * image.pixels.len()).max(1) as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        -10.0 * mse.log10()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn psnr_is_printed_as_decibels_or_identical() {
        let image = |value: f32| RgbImage {
            width: 2,
            height: 1,
            pixels: vec![[value; 3]; 2],
        };
        let same = psnr(&image(0.5), &image(0.5));
        assert_eq!(same, f64::INFINITY);
        assert_eq!(psnr_text(same), "identical");
        // A difference of 0.1 everywhere: MSE 0.01, 20 dB.
        let db = psnr(&image(0.6), &image(0.5));
        assert!((db - 20.0).abs() < 1e-5, "{db}");
        assert_eq!(psnr_text(db), "20.0 dB");
    }
}
