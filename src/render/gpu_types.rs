//! The one place where f64 optics become the f32 data the kernels read. Structs here are shared
//! byte for byte with `shaders/ibrt.wgsl`; their layout is checked against naga's in the tests.

use super::RenderError;
use super::camera::Camera;
use super::layers::LayeredDepthImage;
use bytemuck::{Pod, Zeroable};

/// Inverse depth stored for "no surface" in a packed layer (any negative value means empty).
pub const EMPTY_INVERSE_DEPTH: f32 = -1.0;
/// Pyramid bounds of a region with no surface at all: min above max.
pub const EMPTY_BOUNDS: [f32; 2] = [1e30, -1e30];
/// Which lens function the kernel applies (`FrameParams::model`).
pub const MODEL_PARAXIAL: u32 = 0;

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
    pub pupil_z: f32,
    pub pupil_radius: f32,
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
        model: MODEL_PARAXIAL,
        film_origin_x: origin[0] as f32,
        film_origin_y: origin[1] as f32,
        film_step_x: step[0] as f32,
        film_step_y: step[1] as f32,
        film_z: camera.film_z as f32,
        pupil_z: lens.exit_pupil_z as f32,
        pupil_radius: lens.exit_pupil_radius_mm as f32,
        // Uniform sampling of the whole exit pupil: the pdf cancels the pupil's solid angle.
        pupil_weight: 1.0,
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
