//! The accuracy yardstick: a CPU distribution ray tracer in f64 that follows each lens ray into
//! the scene's true geometry (its panels, not their depth-peeled layers). It draws exactly the
//! samples the IBRT kernel draws, so the difference between the two images is the cost of the
//! layered representation, not sampling noise.

use super::camera::Camera;
use super::image::RgbImage;
use super::kernel::{PixelScrambles, concentric_disc};
use super::scene::Scene;
use super::{RenderError, RenderSettings};
use rayon::prelude::*;

/// Renders `scene` through `camera` with `settings.samples_per_pixel` samples per pixel.
pub fn render_reference(
    camera: &Camera,
    scene: &Scene,
    settings: &RenderSettings,
) -> Result<RgbImage, RenderError> {
    settings.check()?;
    let lens = camera.model.paraxial();
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
                let disc = concentric_disc(lens_u);
                let pupil = [
                    disc[0] as f64 * lens.exit_pupil_radius_mm,
                    disc[1] as f64 * lens.exit_pupil_radius_mm,
                    lens.exit_pupil_z,
                ];
                let d = [pupil[0] - film[0], pupil[1] - film[1], pupil[2] - film[2]];
                let cos_theta = d[2].abs() / (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                let weight = cos_theta.powi(4);
                let (origin, slope) = lens.object_ray(film, pupil);
                let radiance = scene.radiance_along(origin, [slope[0], slope[1], 1.0]);
                for (acc, c) in sum.iter_mut().zip(radiance) {
                    *acc += weight * c as f64;
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
