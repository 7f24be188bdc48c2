//! Depth peeling of triangle meshes by rasterisation from the entrance-pupil centre, and the CPU
//! twin of `shaders/peel.wgsl`.
//!
//! Both rasterisers read one [`PeelData`]. Coverage is decided at pixel centres; the GPU
//! decides it with its fixed-function rasteriser (vertices snapped to its sub-pixel grid, 8 bits
//! on lavapipe), the twin exactly in f64 with the top-left rule, so the two may disagree on a
//! pixel whose centre lies within about 1/256 pixel of a triangle edge. Everything a covered
//! pixel gets — depth, texture coordinates, radiance — is computed from the pixel centre's ray
//! and the triangle's plane by the same f32 statements on both sides (functions here have
//! namesakes in the shader), and the nearest fragment wins with ties going to the earlier
//! triangle, as the GPU's LESS depth test in primitive order does.
//!
//! Peeling (seed 004, section 3.1): layer k holds, per pixel, the nearest fragment deeper than
//! layer k-1's threshold. Plain peeling sets the threshold just beyond layer k-1. Umbra peeling
//! pushes it to the end of the umbra that layer k-1's sample casts when the entrance pupil is
//! seen as a light source: a sample of width s at depth d hides, from every point of an
//! aperture of diameter E, the stretch d .. d + d s / (E - s) behind its centre (all of it once
//! s >= E). The IBRT tests a ray against a sample wherever the ray crosses the sample's pixel,
//! so a sample is one pixel wide (`sample_pixels` = 1, the default); seed 004 widens it to the
//! neighbouring pixel centres (2), which is safe only when silhouettes are widened in the tracer
//! too, which ours does not do.

use super::RenderError;
use super::camera::Camera;
use super::gpu_types::{
    FILTER_NEAREST, NO_TEXTURE, PEEL_UMBRA, PeelData, PeelParams, PeelTexture, PeelTriangle,
    WRAP_CLAMP, WRAP_REPEAT,
};
use super::layers::{LayerBuilder, LayeredDepthImage, Surfel, View};
use super::mesh::MeshScene;
use super::{RenderSettings, layer_view};
use rayon::prelude::*;

/// Plain peeling separates layers by this relative depth: the IBRT's own depth tolerance, below
/// which two layers are one surface to it.
pub const PEEL_SEPARATION: f64 = 1e-5;
/// Depth returned for "beyond everything" (the end of an unbounded umbra); above any fragment.
pub(crate) const BEYOND_ALL: f32 = 3.0e38;
/// A fragment deeper than this is a grazing hit's overflow, not a surface.
pub(crate) const MAX_DEPTH: f32 = 1.0e30;
/// Texture coordinates are clamped to +-2^24 texels before indexing (exact in f32 and i32).
pub(crate) const TEXEL_LIMIT: f32 = 16_777_216.0;
/// Mesh layer views size their margin for geometry no nearer than this many entrance-pupil
/// radii; nearer geometry is so blurred that its border pixels may miss a little of it.
pub const MARGIN_DEPTH_PUPIL_RADII: f64 = 20.0;

/// How each layer's start depth follows from the previous layer's.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Peeling {
    /// Just beyond the previous layer ([`PEEL_SEPARATION`]).
    Plain,
    /// Beyond the previous sample's umbra for an aperture of `aperture_diameter_mm` (the
    /// entrance pupil), the sample being `sample_pixels` pixel pitches wide.
    Umbra {
        aperture_diameter_mm: f64,
        sample_pixels: f64,
    },
}

impl Peeling {
    /// Umbra peeling for `camera`'s entrance pupil, one-pixel samples.
    pub fn umbra_for(camera: &Camera) -> Peeling {
        Peeling::Umbra {
            aperture_diameter_mm: 2.0 * camera.model.paraxial().entrance_pupil_radius_mm,
            sample_pixels: 1.0,
        }
    }
}

/// The layer view for a mesh scene: [`layer_view`] with the margin of its nearest corner,
/// counted no nearer than [`MARGIN_DEPTH_PUPIL_RADII`] entrance-pupil radii.
pub fn mesh_layer_view(
    camera: &Camera,
    settings: &RenderSettings,
    scene: &MeshScene,
) -> Result<View, RenderError> {
    let nearest = scene.nearest_distance_mm().ok_or(RenderError::EmptyScene)? + camera.eye_z();
    let floor = MARGIN_DEPTH_PUPIL_RADII * camera.model.paraxial().entrance_pupil_radius_mm;
    Ok(layer_view(camera, settings, nearest.max(floor)))
}

/// Tangents of the ray through framebuffer point (x, y) (pixel centres at half-integers).
pub(crate) fn pixel_ray(params: &PeelParams, x: f32, y: f32) -> [f32; 3] {
    [
        (2.0 * x / params.width as f32 - 1.0) * params.tan_half_x,
        (1.0 - 2.0 * y / params.height as f32) * params.tan_half_y,
        1.0,
    ]
}

/// Depth at which `ray` meets the triangle's plane; None when it meets it behind the eye,
/// edge-on or absurdly far (the shader discards those fragments).
fn fragment_depth(triangle: &PeelTriangle, ray: [f32; 3]) -> Option<f32> {
    let p = triangle.plane;
    let along = p[0] * ray[0] + p[1] * ray[1] + p[2] * ray[2];
    if along.is_nan() || along <= 0.0 {
        return None;
    }
    let depth = p[3] / along;
    (depth > 0.0 && depth < MAX_DEPTH).then_some(depth)
}

/// The depth a fragment must exceed to belong to the layer after one at `previous`.
fn peel_threshold(params: &PeelParams, previous: f32) -> f32 {
    let plain = previous * (1.0 + params.separation);
    if params.peeling != PEEL_UMBRA {
        return plain;
    }
    let sample = params.pixel_tangent * params.umbra_pixels * previous;
    if sample >= params.aperture_diameter {
        return BEYOND_ALL;
    }
    plain.max(previous + previous * sample / (params.aperture_diameter - sample))
}

/// The depth-buffer value of a fragment: exact (power-of-two scale), at most 1.
fn depth_buffer_value(params: &PeelParams, depth: f32) -> f32 {
    (depth * params.inverse_depth_scale).min(1.0)
}

fn wrap_index(i: i32, size: i32, mode: u32) -> i32 {
    if mode == WRAP_REPEAT {
        return ((i % size) + size) % size;
    }
    if mode == WRAP_CLAMP {
        return i.clamp(0, size - 1);
    }
    let period = 2 * size;
    let m = ((i % period) + period) % period;
    if m >= size { period - 1 - m } else { m }
}

fn texel(texels: &[[f32; 4]], texture: &PeelTexture, column: i32, row: i32) -> [f32; 3] {
    let x = wrap_index(column, texture.width as i32, texture.wrap_u);
    let y = wrap_index(row, texture.height as i32, texture.wrap_v);
    let t = texels[(texture.offset + y as u32 * texture.width + x as u32) as usize];
    [t[0], t[1], t[2]]
}

fn mix3(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    let u = 1.0 - t;
    [
        a[0] * u + b[0] * t,
        a[1] * u + b[1] * t,
        a[2] * u + b[2] * t,
    ]
}

/// RGB of `texture` at texture coordinates `uv` (glTF: v down the image), no mipmaps.
pub(crate) fn sample_texture(texels: &[[f32; 4]], texture: &PeelTexture, uv: [f32; 2]) -> [f32; 3] {
    let size = [texture.width as f32, texture.height as f32];
    let scaled = |k: usize| (uv[k] * size[k]).clamp(-TEXEL_LIMIT, TEXEL_LIMIT);
    if texture.filter_mode == FILTER_NEAREST {
        return texel(
            texels,
            texture,
            scaled(0).floor() as i32,
            scaled(1).floor() as i32,
        );
    }
    let x = scaled(0) - 0.5;
    let y = scaled(1) - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (c, r) = (x0 as i32, y0 as i32);
    let top = mix3(
        texel(texels, texture, c, r),
        texel(texels, texture, c + 1, r),
        fx,
    );
    let bottom = mix3(
        texel(texels, texture, c, r + 1),
        texel(texels, texture, c + 1, r + 1),
        fx,
    );
    mix3(top, bottom, fy)
}

/// Radiance of the triangle's surface where `ray` meets it at `depth`.
fn shade(data: &PeelData, triangle: &PeelTriangle, ray: [f32; 3], depth: f32) -> [f32; 3] {
    let p = [ray[0] * depth, ray[1] * depth, depth];
    let affine = |m: [f32; 4]| m[0] * p[0] + m[1] * p[1] + m[2] * p[2] + m[3];
    let uv = [affine(triangle.u_map), affine(triangle.v_map)];
    let material = &data.materials[triangle.material as usize];
    let base = if material.texture == NO_TEXTURE {
        [1.0; 3]
    } else {
        sample_texture(&data.texels, &data.textures[material.texture as usize], uv)
    };
    [
        material.base_colour[0] * base[0] + material.emissive[0],
        material.base_colour[1] * base[1] + material.emissive[1],
        material.base_colour[2] * base[2] + material.emissive[2],
    ]
}

/// A covered pixel centre: depth-buffer value, draw order, depth.
#[derive(Clone, Copy, Debug)]
struct Fragment {
    pixel: u32,
    key: f32,
    order: u32,
    depth: f32,
}

/// Rows of the view the CPU peel rasterises at a time. Only one band's fragments are held
/// besides the layers built so far: the whole view's fragments, bucketed and copied, were most
/// of a 4096x4096 render's memory (4.75 GB resident).
const PEEL_BAND_ROWS: u32 = 64;

/// Clipped triangle `order` on the screen: its corners (counter-clockwise in y-down pixel
/// coordinates, so the inside is where every edge function is positive), or None when it has
/// no area.
fn screen_triangle(data: &PeelData, order: usize) -> Option<[[f64; 2]; 3]> {
    let params = &data.params;
    let (width, height) = (params.width as f64, params.height as f64);
    let (tan_x, tan_y) = (params.tan_half_x as f64, params.tan_half_y as f64);
    let mut screen = [0, 1, 2].map(|k| {
        let [x, y, depth] = data.vertices[3 * order + k].position.map(f64::from);
        [
            (x / (depth * tan_x) + 1.0) * 0.5 * width,
            (1.0 - y / (depth * tan_y)) * 0.5 * height,
        ]
    });
    let area = edge_function(screen[0], screen[1], screen[2]);
    if area.is_nan() || area == 0.0 {
        return None;
    }
    if area < 0.0 {
        screen.swap(1, 2);
    }
    Some(screen)
}

fn edge_function(a: [f64; 2], b: [f64; 2], p: [f64; 2]) -> f64 {
    (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
}

/// The first pixel centre at or after `v` along one axis.
fn first_centre(v: f64) -> i64 {
    (v - 0.5).ceil().max(0.0) as i64
}

/// The last pixel centre at or before `v` along an axis of `size` pixels (-1: none).
fn last_centre(v: f64, size: u32) -> i64 {
    ((v - 0.5).floor().min(size as f64 - 1.0)).max(-1.0) as i64
}

/// The rows whose centres `screen` may cover, first and last (empty when first > last).
fn covered_rows(screen: &[[f64; 2]; 3], height: u32) -> [i64; 2] {
    let lo = screen.iter().map(|s| s[1]).fold(f64::INFINITY, f64::min);
    let hi = screen
        .iter()
        .map(|s| s[1])
        .fold(f64::NEG_INFINITY, f64::max);
    [first_centre(lo), last_centre(hi, height)]
}

/// Pixel-centre coverage of clipped triangle `order` within rows `rows` (first and last),
/// exact in f64 on the f32 vertices, with the top-left rule for centres exactly on an edge
/// (each shared edge's centres go to exactly one of its triangles). Fragments' pixels count
/// from the first row's first pixel.
fn rasterise_triangle(data: &PeelData, order: usize, rows: [i64; 2]) -> Vec<Fragment> {
    let params = &data.params;
    let Some(screen) = screen_triangle(data, order) else {
        return Vec::new();
    };
    // With y down and positive area, the inside is where every edge function is positive; a
    // top edge runs in +x with dy = 0, a left edge has dy < 0.
    let top_left = |a: [f64; 2], b: [f64; 2]| {
        let (dx, dy) = (b[0] - a[0], b[1] - a[1]);
        dy < 0.0 || (dy == 0.0 && dx > 0.0)
    };
    let edges = [(0, 1), (1, 2), (2, 0)]
        .map(|(i, j)| (screen[i], screen[j], top_left(screen[i], screen[j])));
    let lo = screen.iter().map(|s| s[0]).fold(f64::INFINITY, f64::min);
    let hi = screen
        .iter()
        .map(|s| s[0])
        .fold(f64::NEG_INFINITY, f64::max);
    let [top, bottom] = covered_rows(&screen, params.height);
    let triangle = &data.triangles[data.vertices[3 * order].triangle as usize];
    let mut fragments = Vec::new();
    for row in top.max(rows[0])..=bottom.min(rows[1]) {
        for column in first_centre(lo)..=last_centre(hi, params.width) {
            let centre = [column as f64 + 0.5, row as f64 + 0.5];
            let inside = edges.iter().all(|&(a, b, top_left)| {
                let e = edge_function(a, b, centre);
                e > 0.0 || (e == 0.0 && top_left)
            });
            if !inside {
                continue;
            }
            let ray = pixel_ray(params, centre[0] as f32, centre[1] as f32);
            if let Some(depth) = fragment_depth(triangle, ray) {
                fragments.push(Fragment {
                    pixel: (row - rows[0]) as u32 * params.width + column as u32,
                    key: depth_buffer_value(params, depth),
                    order: order as u32,
                    depth,
                });
            }
        }
    }
    fragments
}

/// The CPU twin of [`super::gpu_peel::GpuPeeler::peel`]: the same layers from the same data,
/// a band of layer rows at a time (`PEEL_BAND_ROWS`), so the fragments of a whole view never
/// exist at once.
pub fn peel_cpu(data: &PeelData, view: View, max_layers: usize) -> LayeredDepthImage {
    peel_in_bands(data, view, max_layers, PEEL_BAND_ROWS)
}

/// [`peel_cpu`], `band_rows` rows at a time.
fn peel_in_bands(
    data: &PeelData,
    view: View,
    max_layers: usize,
    band_rows: u32,
) -> LayeredDepthImage {
    let params = &data.params;
    let triangles = data.vertices.len() / 3;
    // Each triangle's rows, found once, so a band rasterises only the triangles reaching it.
    let rows: Vec<[i64; 2]> = (0..triangles)
        .into_par_iter()
        .map(|order| {
            screen_triangle(data, order).map_or([0, -1], |s| covered_rows(&s, params.height))
        })
        .collect();
    let mut layers = LayerBuilder::new(view, max_layers);
    for first_row in (0..params.height).step_by(band_rows as usize) {
        let band = [
            first_row as i64,
            (first_row + band_rows).min(params.height) as i64 - 1,
        ];
        let band_pixels = (band[1] - band[0] + 1) as usize * params.width as usize;
        let per_triangle: Vec<Vec<Fragment>> = (0..triangles)
            .into_par_iter()
            .filter(|&order| rows[order][0] <= band[1] && rows[order][1] >= band[0])
            .map(|order| rasterise_triangle(data, order, band))
            .collect();
        for mut surfels in peel_band(data, band, band_pixels, per_triangle, max_layers) {
            layers.push_pixel(&mut surfels);
        }
    }
    layers.finish()
}

/// Each pixel's peeled surfels (nearest first, at most `max_layers`) of the rows `band`, from
/// the fragments its triangles cover there.
fn peel_band(
    data: &PeelData,
    band: [i64; 2],
    band_pixels: usize,
    per_triangle: Vec<Vec<Fragment>>,
    max_layers: usize,
) -> Vec<Vec<Surfel>> {
    let params = &data.params;
    // Bucket by pixel, keeping draw order within each pixel.
    let mut starts = vec![0usize; band_pixels + 1];
    for f in per_triangle.iter().flatten() {
        starts[f.pixel as usize + 1] += 1;
    }
    for i in 0..band_pixels {
        starts[i + 1] += starts[i];
    }
    let mut fill = starts.clone();
    let mut sorted = vec![
        Fragment {
            pixel: 0,
            key: 0.0,
            order: 0,
            depth: 0.0
        };
        starts[band_pixels]
    ];
    for f in per_triangle.into_iter().flatten() {
        sorted[fill[f.pixel as usize]] = f;
        fill[f.pixel as usize] += 1;
    }
    (0..band_pixels)
        .into_par_iter()
        .map(|pixel| {
            let mut fragments = sorted[starts[pixel]..starts[pixel + 1]].to_vec();
            // Stable: equal depth-buffer values stay in draw order, as under LESS.
            fragments.sort_by(|a, b| a.key.total_cmp(&b.key));
            let column = (pixel as u32 % params.width) as f32 + 0.5;
            let row = (band[0] as u32 + pixel as u32 / params.width) as f32 + 0.5;
            let ray = pixel_ray(params, column, row);
            let mut surfels: Vec<Surfel> = Vec::new();
            while surfels.len() < max_layers {
                let threshold = surfels.last().map(|s| peel_threshold(params, s.depth_mm));
                let Some(f) = fragments
                    .iter()
                    .find(|f| threshold.is_none_or(|t| f.depth > t))
                else {
                    break;
                };
                let triangle =
                    &data.triangles[data.vertices[3 * f.order as usize].triangle as usize];
                surfels.push(Surfel {
                    depth_mm: f.depth,
                    radiance: shade(data, triangle, ray, f.depth),
                });
            }
            surfels
        })
        .collect()
}

/// Depth-peels `scene` from the eye of `view` into at most `max_layers` layers, as many as the
/// scene needs: on the GPU when `gpu` is given, else on the CPU twin.
pub fn peel_mesh(
    scene: &MeshScene,
    view: View,
    peeling: Peeling,
    max_layers: usize,
    gpu: Option<&super::gpu_peel::GpuPeeler>,
) -> Result<LayeredDepthImage, RenderError> {
    let data = PeelData::of(scene, &view, peeling);
    match gpu {
        Some(peeler) => peeler.peel(&data, view, max_layers),
        None => Ok(peel_cpu(&data, view, max_layers)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::gpu_types::{FILTER_LINEAR, WRAP_MIRROR};

    fn texture(wrap: u32, filter: u32) -> PeelTexture {
        PeelTexture {
            offset: 0,
            width: 2,
            height: 1,
            wrap_u: wrap,
            wrap_v: wrap,
            filter_mode: filter,
            pad: [0; 2],
        }
    }

    #[test]
    fn peeling_in_bands_gives_the_layers_of_one_pass() {
        // The demo at 150 rows: bands of 64 and of 7 rows cut through every panel, and the
        // last band is partial.
        let scene = MeshScene::from_panels(&crate::render::scene::Scene::demo());
        let view = View {
            eye_z: 0.0,
            tan_half: [0.4, 0.3],
            width: 200,
            height: 150,
        };
        let data = PeelData::of(&scene, &view, Peeling::Plain);
        let whole = peel_in_bands(&data, view, 8, view.height);
        assert!(whole.layer_count() >= 3 && whole.surfel_count() > 200 * 150);
        for band_rows in [PEEL_BAND_ROWS, 7] {
            assert_eq!(
                peel_in_bands(&data, view, 8, band_rows),
                whole,
                "{band_rows} rows"
            );
        }
    }

    #[test]
    fn wrap_modes_follow_gltf() {
        // Repeat: period 3; clamp: edges; mirrored: 0 1 2 2 1 0 0 1 ...
        let repeat: Vec<i32> = (-4..5).map(|i| wrap_index(i, 3, WRAP_REPEAT)).collect();
        assert_eq!(repeat, [2, 0, 1, 2, 0, 1, 2, 0, 1]);
        let clamp: Vec<i32> = (-2..5).map(|i| wrap_index(i, 3, WRAP_CLAMP)).collect();
        assert_eq!(clamp, [0, 0, 0, 1, 2, 2, 2]);
        let mirror: Vec<i32> = (-3..9).map(|i| wrap_index(i, 3, WRAP_MIRROR)).collect();
        assert_eq!(mirror, [2, 1, 0, 0, 1, 2, 2, 1, 0, 0, 1, 2]);
    }

    #[test]
    fn linear_filter_interpolates_between_texel_centres() {
        // Texels 0 and 1 of a 2-texel row sit at u = 0.25 and 0.75.
        let texels = [[0.0, 0.0, 0.0, 1.0], [1.0, 2.0, 4.0, 1.0]];
        let clamp = texture(WRAP_CLAMP, FILTER_LINEAR);
        let at = |u: f32| sample_texture(&texels, &clamp, [u, 0.5]);
        assert_eq!(at(0.25), [0.0; 3]);
        assert_eq!(at(0.75), [1.0, 2.0, 4.0]);
        assert_eq!(at(0.5), [0.5, 1.0, 2.0]);
        assert_eq!(at(0.0), [0.0; 3], "clamped to the edge texel");
        // Repeat wraps the left neighbour of texel 0 to texel 1.
        let repeat = texture(WRAP_REPEAT, FILTER_LINEAR);
        assert_eq!(
            sample_texture(&texels, &repeat, [0.0, 0.5]),
            [0.5, 1.0, 2.0]
        );
        let nearest = texture(WRAP_REPEAT, FILTER_NEAREST);
        assert_eq!(sample_texture(&texels, &nearest, [1.49, 0.5]), [0.0; 3]);
        assert_eq!(
            sample_texture(&texels, &nearest, [1.51, 0.5]),
            [1.0, 2.0, 4.0]
        );
    }

    #[test]
    fn top_left_rule_covers_each_centre_of_a_split_square_once() {
        use crate::render::mesh::{Material, Triangle};
        // An 8 x 8 view of tangent half-width 1 at depth 1000: screen = (x / 1000 + 1) * 4, so
        // the square's corners and diagonal lie exactly on pixel centres (k + 0.5).
        let at = |s: f64| 1000.0 * (s / 4.0 - 1.0);
        let corner = |sx: f64, sy: f64| [at(sx), -at(sy), -1000.0];
        let (a, b, c, d) = (
            corner(0.5, 0.5),
            corner(6.5, 0.5),
            corner(6.5, 6.5),
            corner(0.5, 6.5),
        );
        let triangle = |corners| Triangle {
            corners,
            uvs: [[0.0; 2]; 3],
            material: 0,
        };
        let scene = MeshScene {
            triangles: vec![triangle([a, c, b]), triangle([a, d, c])],
            materials: vec![Material::emitter([1.0; 3])],
            images: Vec::new(),
        };
        let view = View {
            eye_z: 0.0,
            tan_half: [1.0, 1.0],
            width: 8,
            height: 8,
        };
        let data = PeelData::of(&scene, &view, Peeling::Plain);
        let mut covered: Vec<u32> = (0..2)
            .flat_map(|t| rasterise_triangle(&data, t, [0, 7]))
            .map(|f| f.pixel)
            .collect();
        let count = covered.len();
        covered.sort();
        covered.dedup();
        assert_eq!(
            covered.len(),
            count,
            "a centre on the diagonal covered twice"
        );
        // Left and top edges are in, right and bottom out: centres 0.5 ..= 5.5 on each axis.
        let expected: Vec<u32> = (0..6)
            .flat_map(|r| (0..6).map(move |c| r * 8 + c))
            .collect();
        assert_eq!(covered, expected);
    }

    #[test]
    fn umbra_threshold_matches_the_similar_triangles() {
        // A sample of width s at depth d hides the points behind it from an aperture E while
        // (E / 2) t / (d + t) <= s / 2, i.e. up to t = d s / (E - s).
        let params = PeelParams {
            peeling: PEEL_UMBRA,
            pixel_tangent: 1e-3,
            umbra_pixels: 1.0,
            aperture_diameter: 25.0,
            separation: 1e-5,
            ..bytemuck::Zeroable::zeroed()
        };
        let d = 5000.0f32;
        let s = 5.0;
        let expected = d + d * s / (25.0 - s);
        assert!((peel_threshold(&params, d) - expected).abs() <= 1e-6 * expected);
        // A sample wider than the aperture hides everything behind it.
        assert_eq!(peel_threshold(&params, 30_000.0), BEYOND_ALL);
        // Very near the eye the umbra is shorter than the plain separation, which then rules.
        let near = 0.1f32;
        assert_eq!(peel_threshold(&params, near), near * (1.0 + 1e-5));
    }
}
