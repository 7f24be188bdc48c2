//! The one place where f64 optics become the f32 data the kernels read. Structs here are shared
//! byte for byte with `shaders/ibrt.wgsl`; their layout is checked against naga's in the tests.

use super::RenderError;
use super::camera::Camera;
use super::chromatic::{CHANNELS, ChannelLenses, Chromatic, PUPIL_EDGE_TOLERANCE};
use super::layers::{LayeredDepthImage, Surfel};
use crate::lrtf::{GpuParams, Parameterisation};
use crate::model::{LensModel, SeidelLens};
use bytemuck::{Pod, Zeroable};
use std::borrow::Cow;

/// Pyramid bounds of a region with no surface at all: min above max.
pub const EMPTY_BOUNDS: [f32; 2] = [1e30, -1e30];
/// Which lens function the kernel applies (`FrameParams::model`).
pub const MODEL_PARAXIAL: u32 = 0;
pub const MODEL_TRACED: u32 = 1;
pub const MODEL_BAKED: u32 = 2;
pub const MODEL_SEIDEL: u32 = 3;
/// Surface profiles (`LensSurface::kind`).
pub const SURFACE_PLANE: u32 = 0;
pub const SURFACE_SPHERE: u32 = 1;
pub const SURFACE_CONIC: u32 = 2;
pub const SURFACE_ASPHERE: u32 = 3;
pub const SURFACE_IDEAL_LENS: u32 = 4;
/// An asphere whose terms are in powers of r (`asphere_terms` of them from r on), not r^2.
pub const SURFACE_ODD_ASPHERE: u32 = 5;
/// Outcome codes of the shader's `trace_lens` (`TracedRay::status`), in the order of
/// [`crate::trace::Outcome`].
pub const TRACE_OK: u32 = 0;
pub const TRACE_VIGNETTED: u32 = 1;
pub const TRACE_TIR: u32 = 2;
pub const TRACE_MISSED: u32 = 3;
/// The shader's asphere search stops at these (relative) sag residual and step sizes: the f32
/// counterparts of the f64 tracer's 1e-15 and 1e-14, a few ulps of the quantities involved.
pub const ASPHERE_SAG_TOLERANCE: f32 = 4e-7;
pub const ASPHERE_STEP_TOLERANCE: f32 = 1e-6;

/// Uniform block of one dispatch. Mirrors `FrameParams` in the shader.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct FrameParams {
    pub width: u32,
    pub height: u32,
    pub samples_per_pixel: u32,
    pub seed: u32,
    pub layer_width: u32,
    pub layer_height: u32,
    pub layer_count: u32,
    pub pyramid_levels: u32,
    pub sample_offset: u32,
    pub sample_count: u32,
    pub model: u32,
    pub film_origin_x: f32,
    pub film_origin_y: f32,
    pub film_step_x: f32,
    pub film_step_y: f32,
    pub film_z: f32,
    /// Plane the lens samples lie on (exit pupil or rear vertex plane).
    pub pupil_z: f32,
    /// pi / (reference projected solid angle * (pupil_z - film_z)^2): times a circle's squared
    /// radius it is the circle's projected solid angle relative to the paraxial exit pupil's.
    pub pupil_weight: f32,
    pub focal_length: f32,
    pub front_principal_z: f32,
    pub rear_principal_z: f32,
    pub eye_z: f32,
    pub tan_half_x: f32,
    pub tan_half_y: f32,
    pub near_depth: f32,
    pub far_depth: f32,
    /// The film point of pixel (x, y) is origin + x * column step + y * row step, origin =
    /// (film_origin_x, film_origin_y, film_origin_z), column step (film_step_x,
    /// film_step_x_y, film_step_x_z), row step (film_step_y_x, film_step_y, film_step_y_z).
    /// On an untilted sensor film_origin_z = film_z and the other new components are zero;
    /// `film_z` stays the plane through the sensor centre, where the pupil circles were fitted.
    pub film_origin_z: f32,
    pub film_step_x_y: f32,
    pub film_step_x_z: f32,
    pub film_step_y_x: f32,
    pub film_step_y_z: f32,
    /// Unit sensor normal (cosine factor of the irradiance on a tilted sensor).
    pub film_normal_x: f32,
    pub film_normal_y: f32,
    pub film_normal_z: f32,
    /// The pupil circles' bound for film points off `film_z` ([`crate::model::OffPlaneBound`]).
    pub pupil_lipschitz: f32,
    pub pupil_centre_slack: f32,
    /// Sample `s` of this dispatch is lattice point `sample_offset + s * sample_stride` of
    /// `samples_per_pixel`: 1 for a render's consecutive chunks; a progressive viewer that
    /// spreads one lattice over K frames takes every K-th point, so each frame is a stratified
    /// subset and K frames together are exactly the render's samples.
    pub sample_stride: u32,
}

/// What the kernels derive from a layered depth image: each surfel's inverse depth and the
/// min/max pyramid. A renderer that draws the same layers many times (the viewer) keeps it
/// beside the image instead of deriving it each frame.
#[derive(Clone, Debug)]
pub struct LayerIndex {
    pub width: u32,
    pub height: u32,
    pub layer_count: u32,
    /// 1 / depth of each surfel, in the image's surfel order: what the march compares.
    pub inverse_depths: Vec<f32>,
    pub depth_bounds: Vec<[f32; 2]>,
    pub pyramid_levels: u32,
    /// Nearest and farthest surfel depth (mm from the eye).
    pub depth_range: [f32; 2],
}

impl LayerIndex {
    /// The inverse depths and bounds pyramid of `ldi`; an image with no surfel is refused.
    pub fn of(ldi: &LayeredDepthImage) -> Result<LayerIndex, RenderError> {
        let depth_range = ldi.depth_range().ok_or(RenderError::EmptyScene)?;
        let (width, height) = (ldi.view.width, ldi.view.height);
        let inverse_depths: Vec<f32> = ldi.surfels().iter().map(|s| 1.0 / s.depth_mm).collect();
        let level0 = ldi
            .starts()
            .windows(2)
            .map(|pixel| {
                inverse_depths[pixel[0] as usize..pixel[1] as usize]
                    .iter()
                    .fold(EMPTY_BOUNDS, |b, &w| [b[0].min(w), b[1].max(w)])
            })
            .collect();
        let (depth_bounds, pyramid_levels) = build_pyramid(level0, width, height);
        Ok(LayerIndex {
            width,
            height,
            layer_count: ldi.layer_count() as u32,
            inverse_depths,
            depth_bounds,
            pyramid_levels,
            depth_range,
        })
    }

    /// Bytes the index of a `width` x `height` layer view holding `surfels` surfels takes:
    /// the inverse depths and every level of the pyramid.
    pub fn footprint_bytes(width: u32, height: u32, surfels: u64) -> u64 {
        let (mut w, mut h) = (width.max(1) as u64, height.max(1) as u64);
        let mut pyramid_texels = w * h;
        while w > 1 || h > 1 {
            (w, h) = (w.div_ceil(2), h.div_ceil(2));
            pyramid_texels += w * h;
        }
        crate::limits::product(&[surfels, 4])
            .saturating_add(crate::limits::product(&[pyramid_texels, 8]))
    }
}

/// A layered depth image as the kernels read it: the image's own per-pixel starts and
/// surfels (borrowed, not copied) and its [`LayerIndex`] (whose fields it derefs to).
#[derive(Clone, Debug)]
pub struct LayerData<'a> {
    /// Where each pixel's surfels start in `surfels` (one entry per pixel, one past the last).
    pub starts: &'a [u32],
    /// Every surfel, pixel by pixel, nearest first: a hit's radiance is read here.
    pub surfels: &'a [Surfel],
    pub index: Cow<'a, LayerIndex>,
}

impl<'a> LayerData<'a> {
    /// `ldi` with its index derived now.
    pub fn pack(ldi: &'a LayeredDepthImage) -> Result<LayerData<'a>, RenderError> {
        Ok(LayerData::with_index(ldi, Cow::Owned(LayerIndex::of(ldi)?)))
    }

    /// `ldi` with `index`, which must be [`LayerIndex::of`] it.
    pub fn with_index(ldi: &'a LayeredDepthImage, index: Cow<'a, LayerIndex>) -> LayerData<'a> {
        LayerData {
            starts: ldi.starts(),
            surfels: ldi.surfels(),
            index,
        }
    }
}

impl std::ops::Deref for LayerData<'_> {
    type Target = LayerIndex;

    fn deref(&self) -> &LayerIndex {
        &self.index
    }
}

/// Appends 2x2 min/max reductions of `level0` down to a single texel.
fn build_pyramid(level0: Vec<[f32; 2]>, width: u32, height: u32) -> (Vec<[f32; 2]>, u32) {
    let mut all = level0;
    let (mut w, mut h, mut start, mut levels) = (width, height, 0usize, 1);
    while w > 1 || h > 1 {
        let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
        let mut next = vec![EMPTY_BOUNDS; (nw * nh) as usize];
        for y in 0..h {
            for x in 0..w {
                let b = all[start + (y * w + x) as usize];
                let n = &mut next[((y / 2) * nw + x / 2) as usize];
                n[0] = n[0].min(b[0]);
                n[1] = n[1].max(b[1]);
            }
        }
        start = all.len();
        all.extend(next);
        (w, h, levels) = (nw, nh, levels + 1);
    }
    (all, levels)
}

/// Dispatch parameters for rendering `width` x `height` pixels of `camera` over `layers`.
/// `sample_offset`/`sample_count`/`sample_stride` select this dispatch's share of the pixel's
/// samples (here all of them).
pub fn frame_params(
    camera: &Camera,
    layers: &LayerData,
    view_tan_half: [f64; 2],
    width: u32,
    height: u32,
    samples_per_pixel: u32,
    seed: u32,
) -> FrameParams {
    let lens = camera.model.paraxial();
    let origin = camera.film_point(width, height, 0.0, 0.0);
    let axes = camera.film.axes();
    let column_step = axes
        .across
        .map(|a| -a * camera.film.width_mm / width as f64);
    let row_step = axes.up.map(|a| a * camera.film.height_mm / height as f64);
    let sampling = camera.pupil_sampling();
    let bound = sampling.off_plane_bound();
    // Every model's weights are relative to the paraxial exit pupil seen from the film, so an
    // unvignetted axial pixel of a thin or thick lens gets weight cos^4 = 1.
    let exit_distance = camera.film_z - lens.exit_pupil_z;
    let reference =
        std::f64::consts::PI * lens.exit_pupil_radius_mm.powi(2) / exit_distance.powi(2);
    let sample_distance = camera.film_z - sampling.z;
    FrameParams {
        width,
        height,
        samples_per_pixel,
        seed,
        layer_width: layers.width,
        layer_height: layers.height,
        layer_count: layers.layer_count,
        pyramid_levels: layers.pyramid_levels,
        sample_offset: 0,
        sample_count: samples_per_pixel,
        sample_stride: 1,
        model: match camera.model {
            LensModel::Thin(_) | LensModel::Thick(_) => MODEL_PARAXIAL,
            LensModel::Traced(_) => MODEL_TRACED,
            LensModel::Baked(_) => MODEL_BAKED,
            LensModel::Seidel(_) => MODEL_SEIDEL,
        },
        film_origin_x: origin[0] as f32,
        film_origin_y: origin[1] as f32,
        film_step_x: column_step[0] as f32,
        film_step_y: row_step[1] as f32,
        film_z: camera.film_z as f32,
        pupil_z: sampling.z as f32,
        pupil_weight: (std::f64::consts::PI / (reference * sample_distance * sample_distance))
            as f32,
        focal_length: lens.focal_length_mm as f32,
        front_principal_z: lens.front_principal_z as f32,
        rear_principal_z: lens.rear_principal_z as f32,
        eye_z: camera.eye_z() as f32,
        tan_half_x: view_tan_half[0] as f32,
        tan_half_y: view_tan_half[1] as f32,
        // Slightly beyond the data so the first and last layers are not clipped by rounding.
        near_depth: layers.depth_range[0] * 0.999,
        far_depth: layers.depth_range[1] * 1.001,
        film_origin_z: origin[2] as f32,
        film_step_x_y: column_step[1] as f32,
        film_step_x_z: column_step[2] as f32,
        film_step_y_x: row_step[0] as f32,
        film_step_y_z: row_step[2] as f32,
        film_normal_x: axes.normal[0] as f32,
        film_normal_y: axes.normal[1] as f32,
        film_normal_z: axes.normal[2] as f32,
        pupil_lipschitz: bound.lipschitz as f32,
        pupil_centre_slack: bound.centre_slack as f32,
    }
}

/// One lens surface as `trace_lens` in the shader reads it (storage buffer, 92 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct LensSurface {
    pub vertex_z: f32,
    pub curvature: f32,
    /// 1 + conic constant.
    pub conic_factor: f32,
    pub semi_aperture_sq: f32,
    /// Snell ratio going backward: index after the surface over index before it.
    pub mu: f32,
    /// Asphere Newton search bound (twice the geometric semi-aperture, which stopping down
    /// leaves alone).
    pub search_radius: f32,
    pub kind: u32,
    pub asphere_terms: u32,
    /// 1 when both sides have the same index (no refraction).
    pub same_medium: u32,
    /// 1 on the stop when its blades must be tested.
    pub bladed: u32,
    /// 1 when the surface is a mirror.
    pub reflects: u32,
    /// Squared radius of the central obscuration (0 for none).
    pub obscuration_sq: f32,
    /// Power 1/f of an ideal lens (`SURFACE_IDEAL_LENS`), 1/mm.
    pub ideal_power: f32,
    /// Even-asphere coefficients of r^2, r^4, ...
    pub coefficients: [f32; crate::prescription::MAX_ASPHERE_TERMS],
}

/// Uniform block `LensParams`: the surface count and the stop's blades (see
/// `crate::trace` aperture notes: corners on the stop circle, edges bulging by arcs).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct LensParams {
    pub surface_count: u32,
    pub blade_count: u32,
    pub has_arc: u32,
    pub pad: u32,
    pub blade_rotation: f32,
    pub blade_apothem: f32,
    /// Distance of each edge arc's centre along the edge's outward direction.
    pub arc_centre: f32,
    pub arc_radius_sq: f32,
}

/// Everything the kernel knows about the lens: the surfaces (traced), the table (baked, else a
/// 2x2x2 placeholder so the bindings stay the same), and the pupil circles lens samples are
/// drawn in (every model).
#[derive(Clone, Debug, PartialEq)]
pub struct LensData {
    pub params: LensParams,
    /// At least one entry (a placeholder when the model traces nothing).
    pub surfaces: Vec<LensSurface>,
    pub lrtf: GpuParams,
    /// (centre_x, radius): the coordinate pupil's `lrtf.pupil_count` circles at film radii
    /// `lrtf.max_film_radius * k / (n - 1)`, then the sampling pupil's circles, focus node by
    /// focus node (see [`crate::lrtf::LrtfTable::gpu_pupil`]).
    pub pupil: Vec<[f32; 2]>,
    pub transfer: Vec<[f32; 4]>,
    pub aux: Vec<[f32; 4]>,
    pub dims: [u32; 3],
    /// The Seidel model's polynomial (zeroed for every other model).
    pub seidel: SeidelParams,
    /// Each output pixel's film shift under a focal surface (x, y, z mm and a zero, row-major;
    /// [`Camera::film_shifts`]); empty for a focused plane.
    pub film_shift: Vec<[f32; 4]>,
}

/// Whether [`LensData`] carries a baked table's textures: the GPU uploads them, the CPU twin
/// reads the table itself (packing 64 MiB of texels per frame of a 128^3 table would cost it
/// more than the lookups).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TableTexels {
    Packed,
    Omitted,
}

impl LensData {
    pub fn of(model: &LensModel, texels: TableTexels) -> LensData {
        let sampling = model.pupil_sampling();
        let pupil: Vec<[f32; 2]> = sampling
            .circles
            .circles
            .iter()
            .map(|c| [c.centre_x as f32, c.radius as f32])
            .collect();
        let placeholder_lrtf = GpuParams {
            rear_plane_z: sampling.z as f32,
            film_plane_z: 0.0,
            max_film_radius: sampling.circles.max_film_radius as f32,
            max_rear_radius: 1.0,
            max_polar_angle: 1.0,
            stop_radius_sq: 0.0,
            parameterisation: 1,
            pupil_count: pupil.len() as u32,
            dims: [2, 2, 2],
            format_version: crate::lrtf::io::FORMAT_VERSION,
            // The same circles sample lens points: one focus node.
            sampling_max_film_radius: sampling.circles.max_film_radius as f32,
            sampling_count: pupil.len() as u32,
            focus_count: 1,
            focus_coordinate: 0.0,
        };
        let pupil = [pupil.clone(), pupil].concat();
        let placeholder_texels = vec![[0.0f32; 4]; 8];
        let (params, surfaces) = match model {
            LensModel::Traced(lens) => lens_surfaces(&lens.system),
            _ => (LensParams::zeroed(), vec![LensSurface::zeroed()]),
        };
        match model {
            LensModel::Baked(lens) => {
                let g = lens
                    .table
                    .gpu_params(lens.layer, lens.stop_radius, lens.film_z());
                let (mut transfer, mut aux) = (Vec::new(), Vec::new());
                if texels == TableTexels::Packed {
                    lens.table.layers[lens.layer].append_texels(&mut transfer, &mut aux);
                }
                LensData {
                    params,
                    surfaces,
                    lrtf: g,
                    pupil: lens.table.gpu_pupil(lens.layer),
                    transfer,
                    aux,
                    dims: g.dims,
                    seidel: SeidelParams::zeroed(),
                    film_shift: Vec::new(),
                }
            }
            _ => LensData {
                params,
                surfaces,
                lrtf: placeholder_lrtf,
                pupil,
                transfer: placeholder_texels.clone(),
                aux: placeholder_texels,
                dims: [2, 2, 2],
                seidel: match model {
                    LensModel::Seidel(lens) => SeidelParams::of(lens),
                    _ => SeidelParams::zeroed(),
                },
                film_shift: Vec::new(),
            },
        }
    }
}

/// Uniform block `SeidelParams` of `shaders/seidel_lens.wgsl`: a [`SeidelLens`]'s conjugate and
/// its transverse aberration polynomial ([`crate::model::TransverseCoefficients`], mm).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct SeidelParams {
    pub image_z: f32,
    pub exit_pupil_z: f32,
    /// 1 / the chief ray's image height at field H = 1.
    pub inverse_chief_height: f32,
    /// 1 / the wide-open marginal ray's height in the exit pupil.
    pub inverse_marginal_height: f32,
    pub spherical: f32,
    pub coma: f32,
    pub sagittal: f32,
    pub tangential: f32,
    pub distortion: f32,
    pub pad: [f32; 3],
}

impl SeidelParams {
    pub fn of(lens: &SeidelLens) -> SeidelParams {
        let c = lens.coefficients();
        SeidelParams {
            image_z: lens.image_z as f32,
            exit_pupil_z: lens.thick.exit_pupil_z as f32,
            inverse_chief_height: (1.0 / lens.chief_image_height) as f32,
            inverse_marginal_height: (1.0 / lens.marginal_pupil_height) as f32,
            spherical: c.spherical as f32,
            coma: c.coma as f32,
            sagittal: c.sagittal as f32,
            tangential: c.tangential as f32,
            distortion: c.distortion as f32,
            pad: [0.0; 3],
        }
    }
}

/// The f32 surfaces and stop blades of a lens at one wavelength, in surface order.
pub fn lens_surfaces(system: &crate::system::SystemAt) -> (LensParams, Vec<LensSurface>) {
    use crate::prescription::{Shape, StopShape};
    let mut params = LensParams {
        surface_count: system.surfaces.len() as u32,
        ..LensParams::zeroed()
    };
    let surfaces = system
        .path()
        .map(|(i, s, index_before, index_after)| {
            let (index_before, index_after) = (index_before.abs(), index_after.abs());
            let mut out = LensSurface {
                vertex_z: s.vertex_z as f32,
                semi_aperture_sq: (s.semi_aperture * s.semi_aperture) as f32,
                mu: (index_after / index_before) as f32,
                search_radius: (2.0 * s.geometric_semi_aperture) as f32,
                conic_factor: 1.0,
                same_medium: u32::from(index_before == index_after),
                reflects: u32::from(s.mirror),
                obscuration_sq: s.obscuration.map_or(0.0, |r| r * r) as f32,
                ..LensSurface::zeroed()
            };
            match &s.shape {
                Shape::Plane => out.kind = SURFACE_PLANE,
                Shape::IdealLens { .. } => {
                    out.kind = SURFACE_IDEAL_LENS;
                    out.ideal_power = s.shape.ideal_power() as f32;
                }
                Shape::Sphere { curvature } if *curvature == 0.0 => out.kind = SURFACE_PLANE,
                Shape::Sphere { curvature } => {
                    out.kind = SURFACE_SPHERE;
                    out.curvature = *curvature as f32;
                }
                Shape::Conic { curvature, conic } => {
                    out.kind = SURFACE_CONIC;
                    out.curvature = *curvature as f32;
                    out.conic_factor = (1.0 + conic) as f32;
                }
                Shape::EvenAsphere { .. } | Shape::OddAsphere { .. } => {
                    out.kind = if matches!(s.shape, Shape::OddAsphere { .. }) {
                        SURFACE_ODD_ASPHERE
                    } else {
                        SURFACE_ASPHERE
                    };
                    out.curvature = s.shape.curvature() as f32;
                    out.conic_factor = (1.0 + s.shape.conic()) as f32;
                    let coefficients = s.shape.aspheric_coefficients();
                    out.asphere_terms = coefficients.len() as u32;
                    for (o, c) in out.coefficients.iter_mut().zip(coefficients) {
                        *o = *c as f32;
                    }
                }
            }
            if let Some(StopShape::Blades {
                count,
                rotation_deg,
                blade_curvature,
            }) = s.stop
                && i == system.stop
            {
                out.bladed = 1;
                let count = count.max(3);
                let half = std::f64::consts::PI / f64::from(count);
                let radius = s.semi_aperture;
                let apothem = radius * half.cos();
                params.blade_count = count;
                params.blade_rotation = rotation_deg.to_radians() as f32;
                params.blade_apothem = apothem as f32;
                let curvature = blade_curvature.clamp(0.0, 1.0) / radius;
                if curvature > 0.0 {
                    let arc_radius = 1.0 / curvature;
                    let half_chord = radius * half.sin();
                    params.has_arc = 1;
                    params.arc_centre = (apothem
                        - (arc_radius * arc_radius - half_chord * half_chord).sqrt())
                        as f32;
                    params.arc_radius_sq = (arc_radius * arc_radius) as f32;
                }
            }
            out
        })
        .collect();
    (params, surfaces)
}

/// Uniform block `ChannelParams` of `render_chromatic` (ibrt.wgsl): which pupil circles lens
/// samples are drawn from, and the paraxial channels' lenses, one lane per channel (R, G, B in
/// x, y, z; w unused). Traced and baked channels live in [`LensData`] instead.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct ChannelParams {
    /// The block of `LensData::pupil` (blocks of `lrtf.pupil_count` circles) samples come from.
    pub sampling_block: u32,
    pub pad: [u32; 3],
    pub focal_length: [f32; 4],
    pub front_principal_z: [f32; 4],
    pub rear_principal_z: [f32; 4],
    pub exit_pupil_z: [f32; 4],
    /// Squared exit-pupil radius widened by [`PUPIL_EDGE_TOLERANCE`].
    pub exit_pupil_limit_sq: [f32; 4],
}

impl LensData {
    /// The kernel's data for a chromatic render of `camera` through `chromatic`'s channels:
    /// the sampling pupil, and per channel the surfaces (traced: channel c's surfaces follow
    /// channel c - 1's) or the table layer (baked: channel c's nodes follow channel c - 1's along
    /// the textures' third axis, its coordinate circles in block c, the sampling circles from block
    /// 3 on: the union of the channels' sampling pupils on the render's film plane, one focus node).
    pub fn chromatic(
        camera: &Camera,
        chromatic: &Chromatic,
        texels: TableTexels,
    ) -> Result<(LensData, ChannelParams), RenderError> {
        chromatic.check_matches(&camera.model)?;
        let mut lens = LensData::of(&camera.model, texels);
        let mut params = ChannelParams::zeroed();
        let sampling: Vec<[f32; 2]> = chromatic
            .sampling
            .circles
            .circles
            .iter()
            .map(|c| [c.centre_x as f32, c.radius as f32])
            .collect();
        match (&chromatic.lenses, &camera.model) {
            (ChannelLenses::Paraxial(lenses), _) => {
                for (c, l) in lenses.iter().enumerate() {
                    params.focal_length[c] = l.focal_length_mm as f32;
                    params.front_principal_z[c] = l.front_principal_z as f32;
                    params.rear_principal_z[c] = l.rear_principal_z as f32;
                    params.exit_pupil_z[c] = l.exit_pupil_z as f32;
                    params.exit_pupil_limit_sq[c] =
                        (l.exit_pupil_radius_mm.powi(2) * (1.0 + PUPIL_EDGE_TOLERANCE)) as f32;
                }
                lens.lrtf.pupil_count = sampling.len() as u32;
                lens.lrtf.sampling_count = sampling.len() as u32;
                lens.pupil = sampling;
            }
            (ChannelLenses::Traced(lenses), _) => {
                lens.surfaces.clear();
                for l in lenses.iter() {
                    let (channel_params, surfaces) = lens_surfaces(&l.system);
                    if surfaces.len() as u32 != lens.params.surface_count {
                        return Err(RenderError::InvalidSetting(
                            "the channels' lenses have different surface counts".into(),
                        ));
                    }
                    lens.params = channel_params;
                    lens.surfaces.extend(surfaces);
                }
                lens.lrtf.pupil_count = sampling.len() as u32;
                lens.lrtf.sampling_count = sampling.len() as u32;
                lens.lrtf.max_film_radius = chromatic.sampling.circles.max_film_radius as f32;
                lens.lrtf.sampling_max_film_radius = lens.lrtf.max_film_radius;
                lens.pupil = sampling;
            }
            (ChannelLenses::Baked(layers), LensModel::Baked(baked)) => {
                let table = &baked.table;
                // The shader reads one frame for every layer: the planes and film radius, and
                // for the spherical parameterisation its ranges too (pupil-planes tables keep
                // their own pupil circles per layer, which is where their layers differ).
                let frame = &table.layers[layers[0]].frame;
                let spherical = table.info.parameterisation == Parameterisation::Spherical;
                let same_frame = |k: usize| {
                    let f = &table.layers[k].frame;
                    f.rear_plane_z == frame.rear_plane_z
                        && f.film_plane_z == frame.film_plane_z
                        && f.max_film_radius == frame.max_film_radius
                        && (!spherical || f == frame)
                };
                if !layers.iter().all(|&k| same_frame(k)) {
                    return Err(RenderError::InvalidSetting(
                        "the table's layers were baked with different frames (film plane, film \
                         radius or spherical ranges); a chromatic render needs one frame"
                            .into(),
                    ));
                }
                let g = table.gpu_params(layers[0], baked.stop_radius, baked.film_z());
                // The union is already the render's film plane's: one focus node.
                lens.lrtf = GpuParams {
                    sampling_max_film_radius: chromatic.sampling.circles.max_film_radius as f32,
                    sampling_count: sampling.len() as u32,
                    focus_count: 1,
                    focus_coordinate: 0.0,
                    ..g
                };
                lens.transfer.clear();
                lens.aux.clear();
                lens.pupil.clear();
                for &k in layers {
                    let layer = &table.layers[k];
                    if texels == TableTexels::Packed {
                        layer.append_texels(&mut lens.transfer, &mut lens.aux);
                    }
                    lens.pupil.extend(
                        layer
                            .pupil
                            .circles
                            .iter()
                            .map(|c| [c.centre_x as f32, c.radius as f32]),
                    );
                }
                lens.pupil.extend(sampling);
                lens.dims = [g.dims[0], g.dims[1], g.dims[2] * CHANNELS as u32];
                params.sampling_block = CHANNELS as u32;
            }
            (ChannelLenses::Baked(_), _) => {
                return Err(RenderError::InvalidSetting(format!(
                    "baked chromatic channels need a baked model, not {}",
                    camera.model.name()
                )));
            }
        }
        Ok((lens, params))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pyramid_top_bounds_everything() {
        let level0: Vec<[f32; 2]> = (0..15).map(|i| [i as f32, i as f32 + 0.5]).collect();
        let (all, levels) = build_pyramid(level0, 5, 3);
        // 5x3 -> 3x2 -> 2x1 -> 1x1
        assert_eq!(levels, 4);
        assert_eq!(all.len(), 15 + 6 + 2 + 1);
        assert_eq!(*all.last().unwrap(), [0.0, 14.5]);
        // Level 1 texel (2, 1) covers level-0 texel (4, 2) only.
        assert_eq!(all[15 + 3 + 2], [14.0, 14.5]);
    }
}

// ---- Depth peeling of triangle meshes (`shaders/peel.wgsl`, CPU twin `raster.rs`) ----

/// `PeelParams::peeling`: each layer starts just beyond the previous one.
pub const PEEL_PLAIN: u32 = 0;
/// `PeelParams::peeling`: each layer starts beyond the previous one's extended umbra.
pub const PEEL_UMBRA: u32 = 1;
/// `PeelTexture::wrap_*` codes (glTF wrap modes).
pub const WRAP_REPEAT: u32 = 0;
pub const WRAP_CLAMP: u32 = 1;
pub const WRAP_MIRROR: u32 = 2;
/// `PeelTexture::filter_mode` codes.
pub const FILTER_NEAREST: u32 = 0;
pub const FILTER_LINEAR: u32 = 1;
/// `PeelMaterial::texture` of an untextured material.
pub const NO_TEXTURE: u32 = u32::MAX;
/// Triangles are clipped this close to the eye (mm) before they reach either rasteriser, so the
/// GPU never clips and both paths see the same vertices.
pub const NEAR_CLIP_MM: f64 = 1.0;

/// Uniform block of one peel pass. Mirrors `PeelParams` in `peel.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct PeelParams {
    pub width: u32,
    pub height: u32,
    /// 0 for the nearest layer; later passes read the previous layer.
    pub pass_index: u32,
    pub peeling: u32,
    pub tan_half_x: f32,
    pub tan_half_y: f32,
    /// A power of two: depth (mm) times it is the depth-buffer value, exact and below 1.
    pub inverse_depth_scale: f32,
    /// The smaller of the view's pixel pitches, in tangent units.
    pub pixel_tangent: f32,
    /// Entrance-pupil diameter (mm): the aperture the umbra is cast from.
    pub aperture_diameter: f32,
    /// Width of a captured sample for the umbra, in pixel pitches.
    pub umbra_pixels: f32,
    /// Plain peeling keeps fragments deeper than previous * (1 + separation).
    pub separation: f32,
    pub pad: u32,
}

/// One clipped triangle corner: eye-space x, y (mm) and depth (mm in front of the eye), and the
/// index of its source triangle's record.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct PeelVertex {
    pub position: [f32; 3],
    pub triangle: u32,
}

/// What a fragment needs of its triangle, in eye space (x, y, depth): the plane
/// n . p = c with |n| = 1 and c > 0, and the affine maps p -> u and p -> v.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct PeelTriangle {
    pub plane: [f32; 4],
    pub u_map: [f32; 4],
    pub v_map: [f32; 4],
    pub material: u32,
    pub pad: [u32; 3],
}

#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct PeelMaterial {
    pub base_colour: [f32; 3],
    /// Index into the textures, or [`NO_TEXTURE`].
    pub texture: u32,
    pub emissive: [f32; 3],
    pub pad: u32,
}

/// An image inside the shared texel array, with its sampler.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
pub struct PeelTexture {
    pub offset: u32,
    pub width: u32,
    pub height: u32,
    pub wrap_u: u32,
    pub wrap_v: u32,
    pub filter_mode: u32,
    pub pad: [u32; 2],
}

impl PeelTexture {
    /// `image` sampled by `sampler`, its texels starting at `offset` in the texel array.
    pub fn of(
        image: &super::mesh::Image,
        sampler: super::mesh::Sampler,
        offset: u32,
    ) -> PeelTexture {
        use super::mesh::{Filter, Wrap};
        let wrap_code = |w: Wrap| match w {
            Wrap::Repeat => WRAP_REPEAT,
            Wrap::ClampToEdge => WRAP_CLAMP,
            Wrap::MirroredRepeat => WRAP_MIRROR,
        };
        PeelTexture {
            offset,
            width: image.width,
            height: image.height,
            wrap_u: wrap_code(sampler.wrap[0]),
            wrap_v: wrap_code(sampler.wrap[1]),
            filter_mode: match sampler.filter {
                Filter::Nearest => FILTER_NEAREST,
                Filter::Linear => FILTER_LINEAR,
            },
            pad: [0; 2],
        }
    }
}

/// Everything both rasterisers read. `triangles`, `materials`, `textures` and `texels` hold at
/// least one entry each (placeholders when the scene has none) so the GPU bindings stay valid.
#[derive(Clone, Debug, PartialEq)]
pub struct PeelData {
    pub params: PeelParams,
    /// Three per clipped triangle, in draw order.
    pub vertices: Vec<PeelVertex>,
    pub triangles: Vec<PeelTriangle>,
    pub materials: Vec<PeelMaterial>,
    pub textures: Vec<PeelTexture>,
    pub texels: Vec<[f32; 4]>,
}

/// Clips the eye-space polygon to depth >= [`NEAR_CLIP_MM`] (Sutherland-Hodgman, one plane).
fn clip_near(polygon: &[[f64; 3]]) -> Vec<[f64; 3]> {
    let mut out = Vec::with_capacity(polygon.len() + 1);
    for (i, &a) in polygon.iter().enumerate() {
        let b = polygon[(i + 1) % polygon.len()];
        let (da, db) = (a[2] - NEAR_CLIP_MM, b[2] - NEAR_CLIP_MM);
        if da >= 0.0 {
            out.push(a);
        }
        if (da >= 0.0) != (db >= 0.0) {
            let t = da / (da - db);
            out.push([
                a[0] + t * (b[0] - a[0]),
                a[1] + t * (b[1] - a[1]),
                NEAR_CLIP_MM,
            ]);
        }
    }
    out
}

impl PeelData {
    /// Converts `scene` for peeling from the eye of `view`: single-sided triangles facing away
    /// from the eye are dropped, the rest clipped to the near plane and reduced to their plane
    /// and texture maps in eye space (f64 here, f32 from here on).
    pub fn of(
        scene: &super::mesh::MeshScene,
        view: &super::layers::View,
        peeling: super::raster::Peeling,
    ) -> PeelData {
        use super::mesh::{cross3, dot3, sub3};
        use super::raster::{PEEL_SEPARATION, Peeling};
        let mut vertices = Vec::new();
        let mut triangles = Vec::new();
        let mut farthest: f64 = NEAR_CLIP_MM;
        for t in &scene.triangles {
            let normal = cross3(
                sub3(t.corners[1], t.corners[0]),
                sub3(t.corners[2], t.corners[0]),
            );
            let facing = dot3(normal, sub3([0.0, 0.0, view.eye_z], t.corners[0]));
            let seen_from_behind = facing < 0.0 && !scene.materials[t.material].double_sided;
            if !(facing.is_finite() && facing != 0.0) || seen_from_behind {
                continue;
            }
            let eye = t.corners.map(|c| [c[0], c[1], view.eye_z - c[2]]);
            let clipped = clip_near(&eye);
            if clipped.len() < 3 {
                continue;
            }
            let (e1, e2) = (sub3(eye[1], eye[0]), sub3(eye[2], eye[0]));
            let n = cross3(e1, e2);
            let nn = dot3(n, n);
            let length = nn.sqrt();
            let c = dot3(n, eye[0]) / length;
            let sign = if c > 0.0 { 1.0 } else { -1.0 };
            // Barycentric weights of corners 1 and 2 are p . a1 + b1 and p . a2 + b2.
            let a1 = cross3(e2, n).map(|v| v / nn);
            let a2 = cross3(n, e1).map(|v| v / nn);
            let map = |k: usize| -> [f32; 4] {
                let (d1, d2) = (t.uvs[1][k] - t.uvs[0][k], t.uvs[2][k] - t.uvs[0][k]);
                let row = [
                    d1 * a1[0] + d2 * a2[0],
                    d1 * a1[1] + d2 * a2[1],
                    d1 * a1[2] + d2 * a2[2],
                ];
                let offset = t.uvs[0][k] - dot3(row, eye[0]);
                [row[0] as f32, row[1] as f32, row[2] as f32, offset as f32]
            };
            let index = triangles.len() as u32;
            triangles.push(PeelTriangle {
                plane: [
                    (sign * n[0] / length) as f32,
                    (sign * n[1] / length) as f32,
                    (sign * n[2] / length) as f32,
                    (sign * c) as f32,
                ],
                u_map: map(0),
                v_map: map(1),
                material: t.material as u32,
                pad: [0; 3],
            });
            for k in 1..clipped.len() - 1 {
                for p in [clipped[0], clipped[k], clipped[k + 1]] {
                    farthest = farthest.max(p[2]);
                    vertices.push(PeelVertex {
                        position: [p[0] as f32, p[1] as f32, p[2] as f32],
                        triangle: index,
                    });
                }
            }
        }
        let mut textures = Vec::new();
        let mut texels = Vec::new();
        let mut image_offsets: Vec<Option<u32>> = vec![None; scene.images.len()];
        let materials = scene
            .materials
            .iter()
            .map(|m| PeelMaterial {
                base_colour: m.base_colour,
                texture: m.base_texture.map_or(NO_TEXTURE, |t| {
                    let image = &scene.images[t.image];
                    let offset = *image_offsets[t.image].get_or_insert_with(|| {
                        texels.extend_from_slice(&image.texels);
                        (texels.len() - image.texels.len()) as u32
                    });
                    textures.push(PeelTexture::of(image, t.sampler, offset));
                    textures.len() as u32 - 1
                }),
                emissive: m.emissive,
                pad: 0,
            })
            .collect::<Vec<_>>();
        fn placeholder<T: Zeroable>(v: &mut Vec<T>) {
            if v.is_empty() {
                v.push(T::zeroed());
            }
        }
        let mut materials = materials;
        placeholder(&mut materials);
        placeholder(&mut textures);
        placeholder(&mut triangles);
        placeholder(&mut texels);
        let (aperture_diameter, umbra_pixels, peeling) = match peeling {
            Peeling::Plain => (0.0, 0.0, PEEL_PLAIN),
            Peeling::Umbra {
                aperture_diameter_mm,
                sample_pixels,
            } => (aperture_diameter_mm, sample_pixels, PEEL_UMBRA),
        };
        let pitch = (2.0 * view.tan_half[0] / view.width as f64)
            .min(2.0 * view.tan_half[1] / view.height as f64);
        // Fragment depths can overshoot the corners' by rounding: leave a factor of two.
        let scale = (2.0 * farthest).log2().ceil().exp2();
        PeelData {
            params: PeelParams {
                width: view.width,
                height: view.height,
                pass_index: 0,
                peeling,
                tan_half_x: view.tan_half[0] as f32,
                tan_half_y: view.tan_half[1] as f32,
                inverse_depth_scale: (1.0 / scale) as f32,
                pixel_tangent: pitch as f32,
                aperture_diameter: aperture_diameter as f32,
                umbra_pixels: umbra_pixels as f32,
                separation: PEEL_SEPARATION as f32,
                pad: 0,
            },
            vertices,
            triangles,
            materials,
            textures,
            texels,
        }
    }
}
