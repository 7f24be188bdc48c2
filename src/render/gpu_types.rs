//! The one place where f64 optics become the f32 data the kernels read. Structs here are shared
//! byte for byte with `shaders/ibrt.wgsl`; their layout is checked against naga's in the tests.

use super::RenderError;
use super::camera::{Camera, LensModel};
use super::layers::LayeredDepthImage;
use crate::lrtf::GpuParams;
use bytemuck::{Pod, Zeroable};

/// Inverse depth stored for "no surface" in a packed layer (any negative value means empty).
pub const EMPTY_INVERSE_DEPTH: f32 = -1.0;
/// Pyramid bounds of a region with no surface at all: min above max.
pub const EMPTY_BOUNDS: [f32; 2] = [1e30, -1e30];
/// Which lens function the kernel applies (`FrameParams::model`).
pub const MODEL_PARAXIAL: u32 = 0;
pub const MODEL_TRACED: u32 = 1;
pub const MODEL_BAKED: u32 = 2;
/// Surface profiles (`LensSurface::kind`).
pub const SURFACE_PLANE: u32 = 0;
pub const SURFACE_SPHERE: u32 = 1;
pub const SURFACE_CONIC: u32 = 2;
pub const SURFACE_ASPHERE: u32 = 3;
/// Outcome codes of the shader's `trace_lens` (`TracedRay::status`), in the order of
/// [`crate::trace::Outcome`].
pub const TRACE_OK: u32 = 0;
pub const TRACE_VIGNETTED: u32 = 1;
pub const TRACE_TIR: u32 = 2;
pub const TRACE_MISSED: u32 = 3;

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
    pub layer_groups: u32,
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
}

/// The layers as the kernel reads them: four inverse depths per pixel per group, one colour per
/// pixel per layer, and the min/max inverse-depth pyramid (level 0 first).
#[derive(Clone, Debug, PartialEq)]
pub struct LayerData {
    pub width: u32,
    pub height: u32,
    pub layer_count: u32,
    pub depths: Vec<[f32; 4]>,
    pub colours: Vec<[f32; 4]>,
    pub depth_bounds: Vec<[f32; 2]>,
    pub pyramid_levels: u32,
    /// Nearest and farthest surfel depth (mm from the eye).
    pub depth_range: [f32; 2],
}

impl LayerData {
    pub fn layer_groups(&self) -> u32 {
        self.layer_count.div_ceil(4)
    }

    /// Packs layers four to a vec4 of inverse depths and builds the bounds pyramid.
    pub fn pack(ldi: &LayeredDepthImage) -> Result<LayerData, RenderError> {
        let depth_range = ldi.depth_range().ok_or(RenderError::EmptyScene)?;
        let (width, height) = (ldi.view.width, ldi.view.height);
        let pixels = (width * height) as usize;
        let layer_count = ldi.layers.len() as u32;
        let groups = layer_count.div_ceil(4) as usize;
        let mut depths = vec![[EMPTY_INVERSE_DEPTH; 4]; groups * pixels];
        let mut colours = vec![[0.0; 4]; layer_count as usize * pixels];
        let mut level0 = vec![EMPTY_BOUNDS; pixels];
        for (l, layer) in ldi.layers.iter().enumerate() {
            for (pixel, sample) in layer.samples.iter().enumerate() {
                if let Some(s) = sample {
                    let w = 1.0 / s.depth_mm;
                    depths[(l / 4) * pixels + pixel][l % 4] = w;
                    colours[l * pixels + pixel] =
                        [s.radiance[0], s.radiance[1], s.radiance[2], 1.0];
                    let b = &mut level0[pixel];
                    b[0] = b[0].min(w);
                    b[1] = b[1].max(w);
                }
            }
        }
        let (depth_bounds, pyramid_levels) = build_pyramid(level0, width, height);
        Ok(LayerData {
            width,
            height,
            layer_count,
            depths,
            colours,
            depth_bounds,
            pyramid_levels,
            depth_range,
        })
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
/// `sample_offset`/`sample_count` select this dispatch's share of the pixel's samples.
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
    let step = [
        -camera.film.width_mm / width as f64,
        camera.film.height_mm / height as f64,
    ];
    let sampling = camera.model.pupil_sampling();
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
        layer_groups: layers.layer_groups(),
        pyramid_levels: layers.pyramid_levels,
        sample_offset: 0,
        sample_count: samples_per_pixel,
        model: match camera.model {
            LensModel::Thin(_) | LensModel::Thick(_) => MODEL_PARAXIAL,
            LensModel::Traced(_) => MODEL_TRACED,
            LensModel::Baked(_) => MODEL_BAKED,
        },
        film_origin_x: origin[0] as f32,
        film_origin_y: origin[1] as f32,
        film_step_x: step[0] as f32,
        film_step_y: step[1] as f32,
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
    }
}

/// One lens surface as `trace_lens` in the shader reads it (storage buffer, 88 bytes).
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
    /// Asphere Newton search bound (twice the clear semi-aperture).
    pub search_radius: f32,
    pub kind: u32,
    pub asphere_terms: u32,
    /// 1 when both sides have the same index (no refraction).
    pub same_medium: u32,
    /// 1 on the stop when its blades must be tested.
    pub bladed: u32,
    pub pad: [u32; 2],
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
}

impl LensData {
    pub fn of(model: &LensModel) -> LensData {
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
            pad: 0,
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
                let g = lens.table.gpu_params(0, lens.stop_radius, lens.film_z());
                let layer = &lens.table.layers[0];
                let split = |range: std::ops::Range<usize>| -> Vec<[f32; 4]> {
                    layer
                        .entries
                        .iter()
                        .map(|e| {
                            [
                                e[range.start],
                                e[range.start + 1],
                                e[range.start + 2],
                                e[range.start + 3],
                            ]
                        })
                        .collect()
                };
                LensData {
                    params,
                    surfaces,
                    lrtf: g,
                    pupil: lens.table.gpu_pupil(0),
                    transfer: split(0..4),
                    aux: split(4..8),
                    dims: g.dims,
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
            },
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
            let mut out = LensSurface {
                vertex_z: s.vertex_z as f32,
                semi_aperture_sq: (s.semi_aperture * s.semi_aperture) as f32,
                mu: (index_after / index_before) as f32,
                search_radius: (2.0 * s.semi_aperture) as f32,
                conic_factor: 1.0,
                same_medium: u32::from(index_before == index_after),
                ..LensSurface::zeroed()
            };
            match &s.shape {
                Shape::Plane => out.kind = SURFACE_PLANE,
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
                Shape::EvenAsphere {
                    curvature,
                    conic,
                    coefficients,
                } => {
                    out.kind = SURFACE_ASPHERE;
                    out.curvature = *curvature as f32;
                    out.conic_factor = (1.0 + conic) as f32;
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
            {
                if i == system.stop {
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
            }
            out
        })
        .collect();
    (params, surfaces)
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
