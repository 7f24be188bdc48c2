//! Depth-of-field rendering through a lens model by image-based ray tracing (IBRT) over layered
//! depth images (seed 000 chapter 4, seed 004 section 3).
//!
//! Data flows one way: a [`mesh::MeshScene`] (a glTF file via [`gltf_scene`], or the demo's
//! panels) is depth-peeled from the entrance-pupil centre by rasterisation ([`raster`], on the
//! GPU by [`gpu_peel`]) into a [`layers::LayeredDepthImage`] (panel scenes and RGB + Z EXRs
//! have their own exact paths); [`gpu_types`] packs it and the
//! f64 [`camera::Camera`] into the f32 structs the kernel reads; the kernel runs on the GPU
//! ([`gpu`], `shaders/ibrt.wgsl`) or on its CPU twin ([`kernel`]); the sum becomes an
//! [`image::RgbImage`].

pub mod camera;
pub mod chromatic;
pub mod focal_surface;
pub mod focus;
pub mod gltf_scene;
pub mod gpu;
pub mod gpu_peel;
pub mod gpu_types;
pub mod image;
pub mod kernel;
pub mod layers;
pub mod mesh;
pub mod mesh_trace;
pub mod raster;
pub mod reference;
pub mod scene;
pub mod wgsl;

use crate::limits;
use camera::Camera;
use gpu_types::{
    ChannelParams, FrameParams, LayerData, LayerIndex, LensData, TableTexels, frame_params,
};
use image::RgbImage;
use layers::{LayeredDepthImage, View};
use std::path::PathBuf;

#[derive(Debug, thiserror::Error)]
pub enum RenderError {
    #[error("{0}")]
    InvalidSetting(String),
    #[error(transparent)]
    Limit(#[from] crate::limits::LimitError),
    #[error(transparent)]
    Model(#[from] crate::model::ModelError),
    #[error("the scene has no surface in view")]
    EmptyScene,
    #[error("no surface of the scene is in view: {0}")]
    NothingInView(String),
    #[error("no GPU adapter: {0}")]
    NoAdapter(String),
    #[error("GPU failure: {0}")]
    Gpu(String),
    #[error("cannot read {path}: {reason}")]
    Read { path: PathBuf, reason: String },
    #[error("cannot write {path}: {reason}")]
    Write { path: PathBuf, reason: String },
}

/// Where the kernel runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Backend {
    Gpu,
    Cpu,
}

/// Output size and sampling.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderSettings {
    pub width: u32,
    pub height: u32,
    pub samples_per_pixel: u32,
    pub seed: u32,
    /// Most layers peeled per pixel.
    pub max_layers: usize,
}

impl RenderSettings {
    /// Refuses settings that are zero or over the size policy ([`crate::limits`]), before anything
    /// is allocated for them.
    pub fn check(&self) -> Result<(), RenderError> {
        if self.width == 0
            || self.height == 0
            || self.samples_per_pixel == 0
            || self.max_layers == 0
        {
            return Err(RenderError::InvalidSetting(format!(
                "width, height, samples per pixel and layer cap must be positive (got {}x{}, {} spp, {} layers)",
                self.width, self.height, self.samples_per_pixel, self.max_layers
            )));
        }
        let pixels = limits::product(&[self.width as u64, self.height as u64]);
        for (what, value, limit) in [
            ("the image width", self.width as u64, limits::MAX_IMAGE_SIDE),
            (
                "the image height",
                self.height as u64,
                limits::MAX_IMAGE_SIDE,
            ),
            ("the pixel count", pixels, limits::MAX_IMAGE_PIXELS),
            (
                "samples per pixel",
                self.samples_per_pixel as u64,
                limits::MAX_SAMPLES_PER_PIXEL,
            ),
            (
                "samples per image (pixels x samples per pixel)",
                limits::product(&[pixels, self.samples_per_pixel as u64]),
                limits::MAX_RENDER_SAMPLES,
            ),
            ("the layer cap", self.max_layers as u64, limits::MAX_LAYERS),
        ] {
            limits::check(what, value, limit)?;
        }
        Ok(())
    }
}

/// Bytes a render of `settings` holds at its peak when its layer view `layers` (width,
/// height) holds `surfels` surfels: the layers with the kernels' index of them and the
/// running sums while it traces, then the layers, the sums and the image they become. The
/// size policy refuses a render by this, before the layers are peeled (with the surfels not yet
/// known, none) and again before the index and sums are allocated.
///
/// ```
/// use lensbake::render::{RenderSettings, render_footprint_bytes};
/// let settings = RenderSettings { width: 4096, height: 4096, samples_per_pixel: 1, seed: 1, max_layers: 8 };
/// // The demo at 4096^2: a 4780^2 layer view holding 33.7 M surfels.
/// let bytes = render_footprint_bytes(&settings, [4780, 4780], 33_689_826);
/// assert!(bytes < 1_300_000_000, "{bytes}");
/// ```
pub fn render_footprint_bytes(settings: &RenderSettings, layers: [u32; 2], surfels: u64) -> u64 {
    let pixels = limits::product(&[settings.width as u64, settings.height as u64]);
    let sums = limits::product(&[pixels, std::mem::size_of::<[f32; 4]>() as u64]);
    let image = limits::product(&[pixels, std::mem::size_of::<[f32; 3]>() as u64]);
    let tracing = LayerIndex::footprint_bytes(layers[0], layers[1], surfels).saturating_add(sums);
    let layer_pixels = limits::product(&[layers[0] as u64, layers[1] as u64]);
    LayeredDepthImage::footprint_bytes(layer_pixels, surfels)
        .saturating_add(tracing.max(sums.saturating_add(image)))
}

/// Refuses a render whose [`render_footprint_bytes`] is more than the memory available.
pub fn check_render_memory(
    settings: &RenderSettings,
    layers: &View,
    surfels: usize,
) -> Result<(), RenderError> {
    Ok(limits::check_memory(
        "the render (layers, their index, the sums and the image)",
        render_footprint_bytes(settings, [layers.width, layers.height], surfels as u64),
    )?)
}

/// Largest tangent a layer view covers (87 degrees): a plane seen from the eye cannot hold rays
/// nearer to perpendicular, and the view's pixel count grows as the tangent.
const MAX_LAYER_TANGENT: f64 = 20.0;
/// Largest layer view, in multiples of the output's pixels per axis.
const MAX_LAYER_UPSCALE: f64 = 8.0;

/// The pinhole view to peel layers for `camera`: the image's field plus a margin wide enough
/// for out-of-focus rays from the border pixels, at the output's pixel pitch; and at least as
/// far as the model's own rays from the film's rim reach ([`reference::ray_reach_tangents`]):
/// with distortion and pupil aberration a real lens's rays can leave well outside the paraxial
/// field (a fisheye's film corner looks out at 75 degrees where its paraxial field ends at 53).
pub fn layer_view(camera: &Camera, settings: &RenderSettings, nearest_depth_mm: f64) -> View {
    let field = camera.half_field_tangents();
    let lens = camera.model.paraxial();
    // A ray through the pupil edge departs from the chief ray by at most r / depth in tangent.
    let margin = lens.entrance_pupil_radius_mm / nearest_depth_mm.max(1e-3);
    let reach = reference::ray_reach_tangents(camera, nearest_depth_mm);
    let grow = |tan: f64, reach: f64, pixels: u32| {
        let tan_layer = (tan + margin).max(reach).min(MAX_LAYER_TANGENT.max(tan));
        let size = (pixels as f64 * tan_layer / tan).min(MAX_LAYER_UPSCALE * pixels as f64);
        let size = size.ceil() as u32;
        // Keep the pixel pitch equal to the image's by snapping the field to the pixel count
        // (coarser only where the upscale cap binds).
        (tan_layer.max(tan * size as f64 / pixels as f64), size)
    };
    let (tan_x, width) = grow(field[0], reach[0], settings.width);
    let (tan_y, height) = grow(field[1], reach[1], settings.height);
    View {
        eye_z: camera.eye_z(),
        tan_half: [tan_x, tan_y],
        width,
        height,
    }
}

/// Which of a render's `samples_per_pixel` lattice points one pass takes: `count` of them,
/// starting at `offset`, every `stride`-th. [`SampleShare::all`] is a whole render; a
/// progressive viewer splits the lattice into `stride` interleaved shares (each one stratified
/// over the lens) that sum to the whole render.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SampleShare {
    pub offset: u32,
    pub count: u32,
    pub stride: u32,
}

impl SampleShare {
    /// Every sample of `settings`.
    pub fn all(settings: &RenderSettings) -> SampleShare {
        SampleShare {
            offset: 0,
            count: settings.samples_per_pixel,
            stride: 1,
        }
    }

    /// Share `index` of `shares` interleaved shares of a lattice of `samples_per_pixel`, which
    /// `shares` must divide. The shares are taken in [`spread_order`], so that the first few
    /// of them together are spread over the whole lens like a render with as many samples (in
    /// lattice order, the first shares all fell on one sliver of the lens: 16 frames of one
    /// sample out of 256 left 8% of the demo's pixels black).
    pub fn interleaved(index: u32, shares: u32, samples_per_pixel: u32) -> SampleShare {
        debug_assert!(shares > 0 && samples_per_pixel.is_multiple_of(shares) && index < shares);
        SampleShare {
            offset: spread_order(index, shares),
            count: samples_per_pixel / shares,
            stride: shares,
        }
    }
}

/// The `index`-th of `0..count` in bit-reversed (van der Corput) order, skipping the values
/// past `count` when it is not a power of two: a permutation of `0..count` whose every prefix
/// of `2^m` entries has one value in each of `2^m` equal runs (for a power of two exactly,
/// otherwise to within one). `index` must be below `count`.
///
/// ```
/// use lensbake::render::spread_order;
/// let order: Vec<u32> = (0..8).map(|i| spread_order(i, 8)).collect();
/// assert_eq!(order, [0, 4, 2, 6, 1, 5, 3, 7]);
/// let order: Vec<u32> = (0..5).map(|i| spread_order(i, 5)).collect();
/// assert_eq!(order, [0, 4, 2, 1, 3]);
/// ```
pub fn spread_order(index: u32, count: u32) -> u32 {
    if count <= 1 {
        return 0;
    }
    let bits = u32::BITS - (count - 1).leading_zeros();
    let reversed = |k: u64| ((k as u32).reverse_bits() >> (u32::BITS - bits)) as u64;
    // Entries past `count` are skipped; fewer than half of the 2^bits are, so this ends within
    // 2 * count steps.
    (0..1u64 << bits)
        .map(reversed)
        .filter(|&value| value < count as u64)
        .nth(index as usize)
        .map_or(index, |value| value as u32)
}

/// Adds the weighted radiance of `share` of `settings`' samples of `layers` (packed from a layer
/// view with half-field tangents `view_tan_half`) through `camera` to `radiance_sum` (one RGBA
/// entry per output pixel, row-major; alpha unused).
#[allow(clippy::too_many_arguments)]
pub fn accumulate_share(
    camera: &Camera,
    layers: &LayerData,
    view_tan_half: [f64; 2],
    settings: &RenderSettings,
    share: SampleShare,
    backend: Backend,
    gpu: Option<&gpu::GpuRenderer>,
    radiance_sum: &mut [[f32; 4]],
) -> Result<(), RenderError> {
    settings.check()?;
    let pixels = settings.width as usize * settings.height as usize;
    let last = share.offset as u64 + (share.count.max(1) as u64 - 1) * share.stride as u64;
    if radiance_sum.len() != pixels
        || share.stride == 0
        || (share.count > 0 && last >= settings.samples_per_pixel as u64)
    {
        return Err(RenderError::InvalidSetting(format!(
            "a share of samples (offset {}, count {}, stride {}) of {} per pixel into {} sums for \
             {} pixels",
            share.offset,
            share.count,
            share.stride,
            settings.samples_per_pixel,
            radiance_sum.len(),
            pixels
        )));
    }
    let texels = match backend {
        Backend::Gpu => TableTexels::Packed,
        Backend::Cpu => TableTexels::Omitted,
    };
    let (frame, lens, channels) = frame_inputs(camera, layers, view_tan_half, settings, texels)?;
    let frame = FrameParams {
        sample_offset: share.offset,
        sample_count: share.count,
        sample_stride: share.stride,
        ..frame
    };
    match (backend, gpu) {
        (Backend::Gpu, gpu) => {
            let opened;
            let renderer = match gpu {
                Some(renderer) => renderer,
                None => {
                    opened = gpu::GpuRenderer::new()?;
                    &opened
                }
            };
            let sums = renderer.accumulate_channels(&frame, layers, &lens, channels.as_ref())?;
            for (total, s) in radiance_sum.iter_mut().zip(sums) {
                for c in 0..3 {
                    total[c] += s[c];
                }
            }
        }
        (Backend::Cpu, _) => match (&camera.chromatic, &channels) {
            (Some(chromatic), Some(channels)) => {
                let rays = kernel::LensRays::channels(chromatic, &camera.model)?;
                kernel::accumulate_chromatic(&frame, layers, &lens, channels, rays, radiance_sum);
            }
            _ => {
                let rays = kernel::LensRays::of(&camera.model);
                kernel::accumulate(&frame, layers, &lens, rays, radiance_sum);
            }
        },
    }
    Ok(())
}

/// The frame parameters (every sample of `settings`), the lens data and, for a chromatic
/// camera, the channel parameters the kernels take for `camera` over `layers`.
fn frame_inputs(
    camera: &Camera,
    layers: &LayerData,
    view_tan_half: [f64; 2],
    settings: &RenderSettings,
    texels: TableTexels,
) -> Result<(FrameParams, LensData, Option<ChannelParams>), RenderError> {
    let frame = frame_params(
        camera,
        layers,
        view_tan_half,
        settings.width,
        settings.height,
        settings.samples_per_pixel,
        settings.seed,
    );
    let (lens, channels) = match &camera.chromatic {
        Some(chromatic) => {
            let (lens, channels) = LensData::chromatic(camera, chromatic, texels)?;
            (lens, Some(channels))
        }
        None => (LensData::of(&camera.model, texels), None),
    };
    let lens = LensData {
        film_shift: camera.film_shifts(settings.width, settings.height)?,
        ..lens
    };
    Ok((frame, lens, channels))
}

/// `settings`' render of `layers` through `camera` uploaded to `gpu` with sums of zero, for a
/// progressive view that adds shares of samples with [`gpu::GpuRenderer::accumulate_resident`]
/// (the lattice of `settings.samples_per_pixel`, as [`accumulate_share`] takes it).
pub fn resident_render(
    camera: &Camera,
    layers: &LayerData,
    view_tan_half: [f64; 2],
    settings: &RenderSettings,
    gpu: &gpu::GpuRenderer,
) -> Result<gpu::ResidentRender, RenderError> {
    settings.check()?;
    let (frame, lens, channels) =
        frame_inputs(camera, layers, view_tan_half, settings, TableTexels::Packed)?;
    gpu.resident(&frame, layers, &lens, channels.as_ref())
}

/// Renders `ldi` through `camera`. Returns the image; radiance is the mean over samples.
pub fn render_layers(
    camera: &Camera,
    ldi: &LayeredDepthImage,
    settings: &RenderSettings,
    backend: Backend,
    gpu: Option<&gpu::GpuRenderer>,
) -> Result<RgbImage, RenderError> {
    settings.check()?;
    check_render_memory(settings, &ldi.view, ldi.surfel_count())?;
    let layers = LayerData::pack(ldi)?;
    let mut sums = vec![[0.0f32; 4]; (settings.width * settings.height) as usize];
    accumulate_share(
        camera,
        &layers,
        ldi.view.tan_half,
        settings,
        SampleShare::all(settings),
        backend,
        gpu,
        &mut sums,
    )?;
    // The index is not needed for the image: freed before the image is allocated.
    drop(layers);
    let scale = 1.0 / settings.samples_per_pixel as f32;
    Ok(RgbImage {
        width: settings.width,
        height: settings.height,
        pixels: sums
            .into_iter()
            .map(|s| [s[0] * scale, s[1] * scale, s[2] * scale])
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::scene::Scene;

    #[test]
    fn the_footprint_counts_what_the_layers_and_their_index_hold() {
        // The demo's layers at 301 x 203 (odd sizes: partial pyramid cells): the bytes the
        // image and its index really hold against the estimate the size policy refuses by.
        let view = View {
            eye_z: 0.0,
            tan_half: [0.4, 0.27],
            width: 301,
            height: 203,
        };
        let ldi = Scene::demo().peel(view, 8);
        let index = LayerIndex::of(&ldi).unwrap();
        let surfels = ldi.surfel_count() as u64;
        let held = 4 * ldi.starts().len() + 16 * ldi.surfels().len();
        let indexed = 4 * index.inverse_depths.len() + 8 * index.depth_bounds.len();
        let estimate = (
            LayeredDepthImage::footprint_bytes(view.pixels() as u64, surfels),
            LayerIndex::footprint_bytes(view.width, view.height, surfels),
        );
        assert_eq!(estimate, (held as u64, indexed as u64));
    }
}
