//! What a frame costs with each model the renderer has a kernel for, and how far that frame is
//! from the traced one: the demo scene rendered on the CPU twin of the IBRT kernel, every model
//! with the same size, samples per pixel, seed and layers, through the tables and domain the ray
//! errors were measured in.
//!
//! The image error of a frame is its PSNR against the traced frame ([`psnr`]): the two share
//! every lens sample (traced and baked draw the same effective-pupil circles), so the difference
//! is the model's, not noise. Thin, thick and Seidel sample their own exit pupil.

use std::time::Instant;

use serde::Serialize;

use super::{Built, Domain, TradeoffError};
use crate::lrtf::LrtfTable;
use crate::model::{FirstOrderModels, LensModel, TracedLens};
use crate::render::camera::{Camera, Film, Focus};
use crate::render::image::RgbImage;
use crate::render::layers::LayeredDepthImage;
use crate::render::reference::psnr;
use crate::render::scene::Scene;
use crate::render::{Backend, RenderSettings, layer_view, render_layers};
use crate::system::LensSystem;

/// The frame every model renders, and how many times it is timed.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct RenderBench {
    pub width: u32,
    pub height: u32,
    pub samples_per_pixel: u32,
    /// Frames timed per model; the cost is their median.
    pub frames: usize,
    pub seed: u32,
}

impl Default for RenderBench {
    fn default() -> RenderBench {
        RenderBench {
            width: 160,
            height: 120,
            samples_per_pixel: 16,
            frames: 3,
            seed: 1,
        }
    }
}

/// One model's frame: its cost and its distance from the traced frame.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RenderCost {
    /// Median wall-clock milliseconds per frame on the CPU twin.
    pub ms_per_frame: f64,
    /// PSNR (dB, display range 0..1) against the traced frame; None for the traced frame itself.
    pub psnr_db: Option<f64>,
}

/// A film of the frame's aspect ratio inscribed in the domain's image circle, so that every
/// film point lies in the baked tables' domain.
fn inscribed_film(radius: f64, width: u32, height: u32) -> Film {
    let diagonal = (width as f64).hypot(height as f64);
    Film {
        width_mm: 2.0 * radius * width as f64 / diagonal,
        height_mm: 2.0 * radius * height as f64 / diagonal,
        shift_mm: [0.0, 0.0],
        tilt_deg: [0.0, 0.0],
    }
}

/// The renderer's camera for `built`, on the film plane its ray map used; the traced lens sits
/// on `probe`'s film plane instead and samples `probe`'s effective pupil, as the baked tables do.
fn camera_for(
    built: &Built,
    system: &LensSystem,
    domain: &Domain,
    first: &FirstOrderModels,
    probe: &LrtfTable,
    film: Film,
) -> Result<Camera, TradeoffError> {
    let (model, film_z) = match &built.model {
        LensModel::Traced(_) => {
            // The design wavelength's layer: a colour probe lists C, design, F.
            let probe_layer = &probe.layers[super::design_layer(probe, domain.wavelength_nm)];
            let traced = TracedLens::new(system, first, domain.f_number, probe_layer.pupil.clone());
            (
                LensModel::Traced(Box::new(traced)),
                probe_layer.frame.film_plane_z,
            )
        }
        model => (model.clone(), built.film_z),
    };
    Ok(Camera::new(model, film, Focus::FilmZ(film_z))?)
}

/// The last frame and the median milliseconds of `frames` renders of `ldi` through `camera`.
fn timed_frames(
    camera: &Camera,
    ldi: &LayeredDepthImage,
    settings: &RenderSettings,
    frames: usize,
) -> Result<(RgbImage, f64), TradeoffError> {
    let mut ms = Vec::with_capacity(frames.max(1));
    let mut image = None;
    for _ in 0..frames.max(1) {
        let started = Instant::now();
        image = Some(render_layers(camera, ldi, settings, Backend::Cpu, None)?);
        ms.push(started.elapsed().as_secs_f64() * 1e3);
    }
    ms.sort_by(f64::total_cmp);
    let image = image.expect("at least one frame was rendered");
    Ok((image, ms[ms.len() / 2]))
}

/// The render cost of each of `built`, in the same order. `probe` is a table of `domain`: its film plane and effective pupil place
/// the traced camera.
pub fn render_costs(
    system: &LensSystem,
    domain: &Domain,
    built: &[Built],
    probe: &LrtfTable,
    bench: &RenderBench,
) -> Result<Vec<RenderCost>, TradeoffError> {
    let first = FirstOrderModels::of(system, Some(domain.f_number))?;
    let film = inscribed_film(domain.film_radius, bench.width, bench.height);
    let cameras = built
        .iter()
        .map(|b| camera_for(b, system, domain, &first, probe, film))
        .collect::<Result<Vec<_>, _>>()?;
    let is_traced = |c: &Camera| matches!(c.model, LensModel::Traced(_));
    let reference = cameras
        .iter()
        .find(|c| is_traced(c))
        .ok_or_else(|| TradeoffError::Invalid("no traced model to render against".into()))?;
    let settings = RenderSettings {
        width: bench.width,
        height: bench.height,
        samples_per_pixel: bench.samples_per_pixel,
        seed: bench.seed,
        max_layers: 8,
    };
    settings.check()?;
    crate::limits::check(
        "the frames timed per model",
        bench.frames as u64,
        crate::limits::MAX_RENDER_FRAMES,
    )
    .map_err(crate::render::RenderError::from)?;
    let scene = Scene::demo();
    let nearest = scene.nearest_distance_mm().unwrap_or(1000.0) + reference.eye_z();
    // Every model shares the traced camera's eye (the entrance pupil), so one set of layers.
    let ldi = scene.peel(
        layer_view(reference, &settings, nearest),
        settings.max_layers,
    );
    let (traced_image, traced_ms) = timed_frames(reference, &ldi, &settings, bench.frames)?;
    cameras
        .iter()
        .map(|camera| {
            if is_traced(camera) {
                return Ok(RenderCost {
                    ms_per_frame: traced_ms,
                    psnr_db: None,
                });
            }
            let (image, ms) = timed_frames(camera, &ldi, &settings, bench.frames)?;
            Ok(RenderCost {
                ms_per_frame: ms,
                psnr_db: Some(psnr(&image, &traced_image)),
            })
        })
        .collect()
}
