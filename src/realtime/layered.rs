//! `layered`: seed 002's layered depth of field (Schedl 2011, after Kraus and Strengert 2007)
//! over the layered depth image, each layer blurred by the lens's own kernels
//! ([`LensKernels`]) instead of Gaussians.
//!
//! Steps: (1) the visible surface of every pixel and one hidden surface behind it, the first
//! that lies beyond the far boundary of the visible surface's layer (the seed ties the peeling
//! bias to the layer boundaries: a hidden surface inside the visible one's layer is covered
//! there anyway); (2) K layers whose nodes are equal circle-of-confusion steps apart, one on the
//! plane in focus (a defocus spot's size is linear in inverse depth, so the steps are equal in
//! inverse depth: Kraus and Strengert's z_i = z_focus / (1 +- d_pix(i) / d_max)); every surface
//! goes whole into the layer its depth falls in, and trapezoidal mattes carry it across the
//! boundary in front of it: a surface within the first half step behind a boundary also enters
//! the layer in front, fading from 1 at the boundary to 0, wherever that layer holds visible
//! surface nearby (a surface crossing the boundary: the layer in front then has no hard edge
//! at the seam, and the layer behind lies under it, so nothing behind shows through; an
//! isolated object is not copied, so it keeps its own light once); (3) each layer, premultiplied
//! colour and alpha, is reduced to the pyramid level its smallest spot allows and spread there
//! by every source's own lens kernel (the kernel at its depth and field radius, turned to its
//! azimuth, narrowed by the variance the level's reduction and upsampling add: the seed's
//! per-layer kernel would blur a layer's depth range by its node, and a kernel fitted per
//! source costs nothing more, since kernels change with the field radius anyway); (4) the
//! layers are composited back to front with premultiplied "over" on the black beyond the last
//! surface of every complete pixel stack, and divided by the coverage where it sums below 1
//! (hidden surfaces the one peeled layer did not hold, the layer view's border).
//!
//! The seed's own mattes (its equations 5.5 to 5.8) rise over the step in front of a layer and
//! fall over the step behind it, so a surface lands in three layers with weights summing to 2;
//! "over" hides the surplus inside an opaque surface but not at the rim of one smaller than its
//! blur, which gains up to the whole surplus (a point light nearly doubles). Its fall term is
//! also misprinted ((z_k - z) / (z_k - z_{k+1}) is 0 at z_k and 1 at z_{k+1}: the inverse of a
//! fall).

use super::kernels::LensKernels;
use super::postfx::{OutputToLayer, first_layer_untilted, layer_pixel_aspect};
use crate::paraxial::ObjectPosition;
use crate::render::RenderError;
use crate::render::camera::Camera;
use crate::render::image::RgbImage;
use crate::render::layers::{LayeredDepthImage, Surfel};
use rayon::prelude::*;

/// Layers when none are asked for: the seed's dragon scene needed 15 ("increasing K to 15
/// layers is enough for the same scene", section 6.3, where 5 blurred the near cone too little).
pub const DEFAULT_LAYERS: usize = 15;
/// Fewest layers: one in front of the plane in focus, one on it, one behind.
pub const LEAST_LAYERS: usize = 3;
/// Most layers (a tile's layer mask is one 64-bit word).
pub const MOST_LAYERS: usize = 64;
/// Share of a step behind each boundary over which the matte of the layer in front fades out.
const RAMP_STEPS: f64 = 0.5;
/// Side (layer pixels) of the tiles that say where a layer holds visible surface.
const MATTE_TILE: usize = 8;
/// A layer is reduced to the coarsest level whose reduction and upsampling add at most this
/// share of the variance of its smallest spot.
const LEVEL_VARIANCE_SHARE: f64 = 0.4;
/// Coarsest pyramid level (texels of 2^5 = 32 pixels).
const MOST_LEVELS: u32 = 5;
/// Share of a kernel's light inside the reach a source spreads over (the rest, a halo's faint
/// outer rays, is left out and the weights renormalised: the flux is kept).
const REACH_SHARE: f64 = 0.99;
/// Rows of source texels a thread spreads into its own buffer at a time.
const BAND_ROWS: usize = 16;

/// How `layered` splits a frame.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct LayeredSettings {
    /// Depth layers (K), [`LEAST_LAYERS`] to [`MOST_LAYERS`].
    pub layers: usize,
    /// Most surfels per pixel the layered depth image was peeled to: behind a pixel that holds
    /// fewer there is nothing (the black the ray tracer sees), behind one that holds this many
    /// there may be more.
    pub peeled_to: usize,
}

/// The layers' nodes, in inverse depth (1/mm from the eye), nearest first: equal steps, one
/// node on the plane in focus, covering the depth range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LayerPlan {
    /// Inverse depth of node 0 (the nearest layer's).
    pub nearest: f64,
    /// Inverse-depth step from one node to the next (positive).
    pub step: f64,
    pub count: usize,
    /// Index of the node on the plane in focus.
    pub focus: usize,
}

impl LayerPlan {
    /// At most `layers` nodes, one at the plane in focus (`focus_inverse`, 1/mm from the eye;
    /// 0 at infinity), spanning `depth_range_mm` (near, far; mm from the eye).
    ///
    /// ```
    /// use lensbake::realtime::layered::LayerPlan;
    /// // Focus at 2 m, surfaces from 1 m to 4 m: 1/1000 - 1/2000 in front of the focus node and
    /// // 1/2000 - 1/4000 behind it, in steps of (1/1000 - 1/4000) / (K - 2).
    /// let plan = LayerPlan::new(1.0 / 2000.0, [1000.0, 4000.0], 5).unwrap();
    /// assert!((plan.step - 0.00025).abs() < 1e-12);
    /// assert_eq!((plan.count, plan.focus), (4, 2));
    /// assert!((1.0 / plan.node(plan.focus) - 2000.0).abs() < 1e-9);
    /// // A surface at 1 m is the nearest layer's.
    /// assert_eq!(plan.locate(1.0 / 1000.0).0, 0);
    /// ```
    pub fn new(
        focus_inverse: f64,
        depth_range_mm: [f64; 2],
        layers: usize,
    ) -> Result<LayerPlan, RenderError> {
        let [near, far] = depth_range_mm;
        if !(LEAST_LAYERS..=MOST_LAYERS).contains(&layers) {
            return Err(RenderError::InvalidSetting(format!(
                "layered needs {LEAST_LAYERS} to {MOST_LAYERS} layers, got {layers}"
            )));
        }
        if !(near > 0.0 && far >= near && far.is_finite() && focus_inverse >= 0.0) {
            return Err(RenderError::InvalidSetting(format!(
                "layered needs a depth range 0 < near <= far and a focus in front of the eye, \
                 got {near} .. {far} mm, focus at 1 / {focus_inverse} mm"
            )));
        }
        let focus = focus_inverse;
        let hi = focus.max(1.0 / near);
        let lo = focus.min(1.0 / far);
        // K - 2 steps for a span of K - 1: the rounding of either side to whole steps takes at
        // most one more.
        let step = ((hi - lo) / (layers - 2) as f64).max(hi * 1e-9);
        let whole = |span: f64| (span / step - 1e-9).ceil().max(0.0) as usize;
        let (front, back) = (whole(hi - focus), whole(focus - lo));
        Ok(LayerPlan {
            nearest: focus + front as f64 * step,
            step,
            count: front + back + 1,
            focus: front,
        })
    }

    /// Inverse depth of node `j`.
    pub fn node(&self, j: usize) -> f64 {
        self.nearest - j as f64 * self.step
    }

    /// The layer holding inverse depth `inverse` and how far behind that layer's front
    /// boundary it lies, in steps (below 0 in front of the first layer's).
    pub fn locate(&self, inverse: f64) -> (usize, f64) {
        let at = (self.nearest - inverse) / self.step + 0.5;
        let j = (at.floor().max(0.0) as usize).min(self.count - 1);
        (j, at - j as f64)
    }
}

/// One surface's share of one layer at one layer pixel.
#[derive(Clone, Copy, Debug)]
struct Placement {
    layer: u8,
    pixel: u32,
    weight: f32,
    surfel: Surfel,
}

/// A layer spread at pyramid level `level`: premultiplied colour and coverage over a window of
/// texels.
struct SpreadLayer {
    /// Texel side in layer pixels (2^level).
    side: usize,
    /// Window origin (texels) and size.
    origin: [isize; 2],
    width: usize,
    height: usize,
    /// Premultiplied RGB and coverage.
    texels: Vec<[f32; 4]>,
}

impl SpreadLayer {
    /// Bilinear value at layer-pixel coordinates `p` (pixel centres at integers); zero outside.
    fn at(&self, p: [f64; 2]) -> [f32; 4] {
        let s = self.side as f64;
        let gx = (p[0] - 0.5 * (s - 1.0)) / s - self.origin[0] as f64;
        let gy = (p[1] - 0.5 * (s - 1.0)) / s - self.origin[1] as f64;
        let (w, h) = (self.width as f64, self.height as f64);
        if !(gx > -1.0 && gy > -1.0 && gx < w && gy < h) {
            return [0.0; 4];
        }
        let (x0, y0) = (gx.floor(), gy.floor());
        let (fx, fy) = ((gx - x0) as f32, (gy - y0) as f32);
        let texel = |x: f64, y: f64| -> [f32; 4] {
            if x < 0.0 || y < 0.0 || x >= w || y >= h {
                return [0.0; 4];
            }
            self.texels[y as usize * self.width + x as usize]
        };
        let (a, b) = (texel(x0, y0), texel(x0 + 1.0, y0));
        let (c, d) = (texel(x0, y0 + 1.0), texel(x0 + 1.0, y0 + 1.0));
        std::array::from_fn(|k| {
            let top = a[k] + fx * (b[k] - a[k]);
            let bottom = c[k] + fx * (d[k] - c[k]);
            top + fy * (bottom - top)
        })
    }
}

/// Inverse depth (1/mm from the eye) of the plane `camera`'s film is focused on, paraxially
/// (0 where the film lies at or inside the focal length: focused at infinity). It places the
/// layers' nodes only; every source is spread by the kernel traced at its own depth.
fn focus_inverse_depth(camera: &Camera) -> f64 {
    match camera.model.paraxial().object_in_focus(camera.film_z) {
        // The object plane lies at z = -distance, the eye (the entrance pupil) at eye_z.
        Some(ObjectPosition::Finite { distance }) => 1.0 / (camera.eye_z() + distance),
        Some(ObjectPosition::Infinite) | None => 0.0,
    }
}

/// Variance (layer pixels squared, both axes together) that reducing to texels of `side`
/// pixels and upsampling back bilinearly add to a spot: per axis, the box over `side` pixel
/// centres adds (side^2 - 1) / 12, the bilinear tent sampled at pixel centres (2 side^2 + 1) /
/// 12 (none at full resolution).
fn level_variance(side: usize) -> f64 {
    if side <= 1 {
        return 0.0;
    }
    let s2 = (side * side) as f64;
    2.0 * ((s2 - 1.0) / 12.0 + (2.0 * s2 + 1.0) / 12.0)
}

/// Renders `ldi` (seen from `camera`'s eye) at `width` x `height` through the lens kernels
/// `kernels` by seed 002's layered method, in `settings.layers` layers about the plane in focus
/// at `focus_depth_mm` from the eye.
pub fn layered(
    camera: &Camera,
    ldi: &LayeredDepthImage,
    kernels: &LensKernels,
    settings: &LayeredSettings,
    width: u32,
    height: u32,
) -> Result<RgbImage, RenderError> {
    first_layer_untilted(camera, ldi)?;
    let view = ldi.view;
    let range = ldi.depth_range().ok_or(RenderError::EmptyScene)?;
    let plan = LayerPlan::new(
        focus_inverse_depth(camera),
        [range[0] as f64, range[1] as f64],
        settings.layers,
    )?;
    let (lw, lh) = (view.width as usize, view.height as usize);
    let layer_of = |s: &Surfel| plan.locate(1.0 / s.depth_mm as f64);

    // 1. Where each layer holds visible surface, tile by tile, dilated by one tile.
    let (tw, th) = (lw.div_ceil(MATTE_TILE), lh.div_ceil(MATTE_TILE));
    let tile_of = |pixel: usize| (pixel / lw / MATTE_TILE) * tw + (pixel % lw) / MATTE_TILE;
    let mut held = vec![0u64; tw * th];
    for (pixel, surfel) in ldi.layer(0).samples().enumerate() {
        if let Some(s) = surfel {
            held[tile_of(pixel)] |= 1 << layer_of(&s).0;
        }
    }
    let near_held: Vec<u64> = (0..tw * th)
        .map(|t| {
            let (x, y) = (t % tw, t / tw);
            let mut mask = 0;
            for ny in y.saturating_sub(1)..(y + 2).min(th) {
                for nx in x.saturating_sub(1)..(x + 2).min(tw) {
                    mask |= held[ny * tw + nx];
                }
            }
            mask
        })
        .collect();

    // 2. Mattes: every pixel's visible surface and its hidden one, each whole in its own layer
    //    and fading into the layer in front across the boundary: at most four placements a
    //    pixel, kept on the stack (a vector per pixel was an allocation per pixel).
    let mut void = vec![true; view.pixels()];
    let placements: Vec<Placement> = (0..view.pixels())
        .into_par_iter()
        .zip(void.par_iter_mut())
        .flat_map_iter(|(pixel, void)| {
            let stack = ldi.pixel_surfels(pixel);
            let mut out = [None; 4];
            let Some(visible) = stack.first() else {
                return out.into_iter().flatten();
            };
            let tile = tile_of(pixel);
            let mut count = 0;
            let mut place = |surfel: &Surfel, in_front_of: Option<usize>| -> usize {
                let (j, behind) = layer_of(surfel);
                let mut put = |layer: usize, weight: f64| {
                    out[count] = Some(Placement {
                        layer: layer as u8,
                        pixel: pixel as u32,
                        weight: weight as f32,
                        surfel: *surfel,
                    });
                    count += 1;
                };
                put(j, 1.0);
                if let Some(front) = j.checked_sub(1)
                    && (0.0..RAMP_STEPS).contains(&behind)
                    && in_front_of.is_none_or(|v| front > v)
                    && near_held[tile] & (1 << front) != 0
                {
                    put(front, 1.0 - behind / RAMP_STEPS);
                }
                j
            };
            let visible_layer = place(visible, None);
            let hidden = stack[1..]
                .iter()
                .position(|s| layer_of(s).0 > visible_layer)
                .map(|i| i + 1);
            let last = match hidden {
                Some(i) => {
                    place(&stack[i], Some(visible_layer));
                    i
                }
                None => 0,
            };
            // Nothing behind the last surface used where the stack is whole and it is the last.
            *void = stack.len() < settings.peeled_to && last + 1 == stack.len();
            out.into_iter().flatten()
        })
        .collect();
    let mut by_layer: Vec<Vec<Placement>> = vec![Vec::new(); plan.count];
    for p in placements {
        by_layer[p.layer as usize].push(p);
    }

    // 3. Each layer reduced and spread by its sources' kernels. A node kernel's reach (the
    //    radius holding all but its faintest rays, plus the pixel) is the same for every
    //    layer: a sort of the kernel's values, found once per frame.
    let aspect = layer_pixel_aspect(ldi, kernels) as f64;
    let reach_of: Vec<f64> = kernels
        .kernels
        .par_iter()
        .map(|k| k.radius_holding(REACH_SHARE) + std::f64::consts::FRAC_1_SQRT_2)
        .collect();
    let spread: Vec<Option<SpreadLayer>> = by_layer
        .iter()
        .map(|placed| {
            (!placed.is_empty()).then(|| {
                // The layer's surface nearest the plane in focus has its smallest spots.
                let focus = plan.node(plan.focus);
                let sharpest = placed
                    .iter()
                    .map(|p| 1.0 / p.surfel.depth_mm as f64)
                    .min_by(|a, b| (a - focus).abs().total_cmp(&(b - focus).abs()))
                    .unwrap_or(focus);
                let size = kernels.spread(1.0 / sharpest, [0.0, 0.0]).size as f64;
                let level = (0..=MOST_LEVELS)
                    .take_while(|&l| level_variance(1 << l) <= LEVEL_VARIANCE_SHARE * size * size)
                    .last()
                    .unwrap_or(0);
                spread_layer(placed, 1 << level, ldi, kernels, &reach_of, aspect)
            })
        })
        .collect();

    // 4. Back to front over the black behind complete stacks; divided by the coverage where
    //    it falls short.
    let map = OutputToLayer::of(camera, ldi, width, height);
    let (w, h) = (width as usize, height as usize);
    let pixels = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let p = map.at((i % w) as u32, (i / w) as u32);
            let (sx, sy) = (p[0].round(), p[1].round());
            let inside = sx >= 0.0 && sy >= 0.0 && (sx as usize) < lw && (sy as usize) < lh;
            let mut coverage = match inside && void[sy as usize * lw + sx as usize] {
                true => 1.0f32,
                false => 0.0,
            };
            let mut colour = [0.0f32; 3];
            for layer in spread.iter().rev().flatten() {
                let [r, g, b, a] = layer.at(p);
                let behind = 1.0 - a;
                colour = [
                    r + behind * colour[0],
                    g + behind * colour[1],
                    b + behind * colour[2],
                ];
                coverage = a + behind * coverage;
            }
            if coverage > 1e-4 && coverage < 1.0 {
                colour = colour.map(|c| c / coverage);
            }
            colour
        })
        .collect();
    Ok(RgbImage {
        width,
        height,
        pixels,
    })
}

/// A source texel's light as the spread reads it.
struct Source {
    /// Texel index in the layer's source window.
    index: usize,
    /// Premultiplied colour times the spot's flux, and coverage (texel averages).
    colour: [f32; 3],
    coverage: f32,
    /// The node kernel and the affine map from an offset (dx, dy) in texels (rows down) to the
    /// kernel's grid coordinates: x = m[0] dx + m[1] dy + m[2], y = m[3] dx + m[4] dy + m[5].
    node: u32,
    map: [f64; 6],
    /// Farthest offset (texels) the spot reaches.
    reach: i32,
}

/// One layer's placements reduced to texels of `side` x `side` layer pixels (premultiplied
/// colour, coverage and coverage-weighted inverse depth, averaged) and spread: every source
/// texel's light goes to the texels around it by its own lens kernel, narrowed by the variance
/// the reduction and the upsampling add, its weights summing to the spot's flux (the coverage
/// by the same weights over the flux, so that it sums to the source's). `reach_of`: each node
/// kernel's reach (pixels from its centroid).
fn spread_layer(
    placed: &[Placement],
    side: usize,
    ldi: &LayeredDepthImage,
    kernels: &LensKernels,
    reach_of: &[f64],
    aspect: f64,
) -> SpreadLayer {
    let view = ldi.view;
    let lw = view.width as usize;
    let texel_of = |pixel: u32| [(pixel as usize % lw) / side, (pixel as usize / lw) / side];
    let (mut lo, mut hi) = ([usize::MAX; 2], [0usize; 2]);
    for p in placed {
        let t = texel_of(p.pixel);
        for k in 0..2 {
            lo[k] = lo[k].min(t[k]);
            hi[k] = hi[k].max(t[k]);
        }
    }
    let (sw, sh) = (hi[0] - lo[0] + 1, hi[1] - lo[1] + 1);
    // Premultiplied colour, coverage and coverage times inverse depth, summed per texel.
    let mut sums = vec![[0.0f32; 5]; sw * sh];
    for p in placed {
        let t = texel_of(p.pixel);
        let cell = &mut sums[(t[1] - lo[1]) * sw + t[0] - lo[0]];
        for (sum, radiance) in cell.iter_mut().zip(p.surfel.radiance) {
            *sum += p.weight * radiance;
        }
        cell[3] += p.weight;
        cell[4] += p.weight / p.surfel.depth_mm;
    }
    let per_texel = 1.0 / (side * side) as f32;
    let pipeline = level_variance(side);
    let step = side as f64;
    let sources: Vec<Source> = sums
        .par_iter()
        .enumerate()
        .filter(|(_, cell)| cell[3] > 0.0)
        .map(|(index, cell)| {
            let centre = |t: usize| (t * side) as f64 + 0.5 * (step - 1.0) + 0.5;
            let tan = [
                view.tan_half[0] * (2.0 * centre(lo[0] + index % sw) / view.width as f64 - 1.0),
                view.tan_half[1] * (1.0 - 2.0 * centre(lo[1] + index / sw) / view.height as f64),
            ];
            let spread = kernels.spread((cell[3] / cell[4]) as f64, tan);
            let size2 = (spread.size as f64).powi(2);
            let narrowed = (size2 - pipeline).max((1.0 - LEVEL_VARIANCE_SHARE) * size2);
            let scale = spread.node_size as f64 / narrowed.sqrt();
            let [c, s] = spread.azimuth.map(f64::from);
            // Source to output in the kernels' pitch, +y up: (step dx, -step aspect dy),
            // turned by the azimuth into the kernel frame and scaled about the centroid.
            let (x, y) = (scale * step, scale * step * aspect);
            let [nc, cc] = [spread.node_centroid, spread.centroid].map(|v| v.map(f64::from));
            let kernel = &kernels.kernels[spread.node as usize];
            // To the node kernel's grid coordinates.
            let (x, y) = (x / kernel.spacing, y / kernel.spacing);
            let grid = |k: usize| (nc[k] - cc[k] * scale - kernel.origin[k]) / kernel.spacing;
            let reach_pixels = cc[0].hypot(cc[1]) + reach_of[spread.node as usize] / scale;
            Source {
                index,
                colour: std::array::from_fn(|k| cell[k] * per_texel * spread.flux),
                coverage: cell[3] * per_texel,
                node: spread.node,
                map: [c * x, -s * y, grid(0), -s * x, -c * y, grid(1)],
                reach: (reach_pixels.min(spread.support as f64) / step).ceil() as i32 + 1,
            }
        })
        .collect();
    let reach = sources.iter().map(|s| s.reach).max().unwrap_or(0).max(0) as usize;
    let (ow, oh) = (sw + 2 * reach, sh + 2 * reach);
    // Bands of source rows, each spread into its own rows of the output window.
    let bands: Vec<(usize, Vec<[f32; 4]>)> = sources
        .par_chunk_by(|a, b| a.index / sw / BAND_ROWS == b.index / sw / BAND_ROWS)
        .map(|band| {
            let first_row = band[0].index / sw / BAND_ROWS * BAND_ROWS;
            let rows = (BAND_ROWS + 2 * reach).min(oh - first_row);
            let mut out = vec![[0.0f32; 4]; rows * ow];
            let mut weights: Vec<(usize, f32)> = Vec::new();
            for source in band {
                let (sx, sy) = (source.index % sw, source.index / sw);
                let kernel = &kernels.kernels[source.node as usize];
                let m = &source.map;
                weights.clear();
                let r = source.reach;
                for dy in -r..=r {
                    for dx in -r..=r {
                        let (fx, fy) = (dx as f64, dy as f64);
                        if dx * dx + dy * dy > r * r {
                            continue;
                        }
                        let v = kernel
                            .at_node([m[0] * fx + m[1] * fy + m[2], m[3] * fx + m[4] * fy + m[5]])
                            as f32;
                        if v > 0.0 {
                            let ox = (sx + reach) as isize + dx as isize;
                            let oy = (sy + reach - first_row) as isize + dy as isize;
                            weights.push((oy as usize * ow + ox as usize, v));
                        }
                    }
                }
                let total: f32 = weights.iter().map(|w| w.1).sum();
                let norm = if total > 0.0 {
                    1.0 / total
                } else {
                    // A spot narrower than the lattice: all of it on its own texel.
                    weights.clear();
                    weights.push(((sy + reach - first_row) * ow + sx + reach, 1.0));
                    1.0
                };
                for &(at, v) in &weights {
                    let w = v * norm;
                    let texel = &mut out[at];
                    for (sum, colour) in texel.iter_mut().zip(source.colour) {
                        *sum += w * colour;
                    }
                    texel[3] += w * source.coverage;
                }
            }
            (first_row, out)
        })
        .collect();
    let mut texels = vec![[0.0f32; 4]; ow * oh];
    for (first_row, band) in bands {
        let start = first_row * ow;
        for (to, from) in texels[start..start + band.len()].iter_mut().zip(band) {
            for k in 0..4 {
                to[k] += from[k];
            }
        }
    }
    SpreadLayer {
        side,
        origin: [
            lo[0] as isize - reach as isize,
            lo[1] as isize - reach as isize,
        ],
        width: ow,
        height: oh,
        texels,
    }
}
