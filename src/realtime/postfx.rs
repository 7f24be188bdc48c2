//! `postfx`: the gather post-process of seed 001 chapter 5 (after Jimenez 2014 and Tan et al.
//! 2022) over the pinhole colour and depth, its taps weighted by the lens's own kernels
//! ([`LensKernels`]) instead of discs. The CPU statement of the method.
//!
//! Passes: (1) every pinhole pixel gets its spread (kernel node, centroid, size, flux);
//! (2) tiles of 32 x 32 pinhole pixels keep their nearest depth and largest reach, dilated by as
//! many tiles as the largest reach spans (the seed's 3 x 3 is enough only while no spot is wider
//! than a tile); (3) a box pyramid of the colour is the prefilter: a tap reads the level whose
//! texel matches the patch it stands for; (4) each output pixel gathers up to four rings of
//! taps (1 + 8 + 16 + 24 + 32 = 81, the count of Tan et al.) scaled to its tile's reach, each
//! tap weighted by its pixel's kernel at the offset to the output pixel (widened to the tap's
//! patch), split into foreground (nearer and wider-spread than the centre, seen through
//! partially) and background (hidden beyond the centre's own reach); (5) a 3 x 3 median, edges
//! clamped (not black-padded: see GUIDE.md's errata), where the taps were sparse.

use super::kernels::{LensKernels, PixelSpread};
use crate::render::RenderError;
use crate::render::camera::Camera;
use crate::render::image::RgbImage;
use crate::render::layers::{Layer, LayeredDepthImage};
use rayon::prelude::*;

/// Side of a tile (pinhole pixels).
pub const TILE: usize = 32;
/// Most rings of taps around the centre.
pub const MAX_RINGS: usize = 4;
/// Tap spacing the rings aim for (pinhole pixels): closer spacing adds taps, up to `MAX_RINGS`.
const TARGET_SPACING: f32 = 1.5;
/// Largest gather, in pinhole pixels, that reads every pixel within reach instead of rings of
/// random taps: exact (no sampling noise) where spots are small, which is most of a frame.
const DENSE_PIXELS: f32 = 200.0;
/// A tap more than this wider-spread (pinhole pixels of reach) than the centre counts as
/// another depth layer, in front or behind.
const LAYER_REACH_STEP: f32 = 1.0;
/// The median smooths pixels whose taps stand for patches wider than this (pinhole pixels).
const MEDIAN_FROM_SPACING: f32 = 2.0;

/// One pinhole pixel as the gather reads it.
#[derive(Clone, Copy, Debug)]
struct Source {
    depth: f32,
    spread: PixelSpread,
}

/// The affine map from output pixel centres to pinhole (layer) index coordinates, pixel centres
/// at integers: exact for an untilted film, whose chief-ray tangents are linear in the film
/// point.
#[derive(Clone, Copy, Debug)]
pub(super) struct OutputToLayer {
    origin: [f64; 2],
    column_step: [f64; 2],
    row_step: [f64; 2],
}

impl OutputToLayer {
    pub(super) fn of(
        camera: &Camera,
        ldi: &LayeredDepthImage,
        width: u32,
        height: u32,
    ) -> OutputToLayer {
        let view = &ldi.view;
        let layer_at = |x: f64, y: f64| {
            let t = camera.chief_ray_tangents(camera.film_point(width, height, x, y));
            [
                (t[0] / view.tan_half[0] + 1.0) * 0.5 * view.width as f64 - 0.5,
                (1.0 - t[1] / view.tan_half[1]) * 0.5 * view.height as f64 - 0.5,
            ]
        };
        let origin = layer_at(0.5, 0.5);
        let right = layer_at(1.5, 0.5);
        let down = layer_at(0.5, 1.5);
        OutputToLayer {
            origin,
            column_step: [right[0] - origin[0], right[1] - origin[1]],
            row_step: [down[0] - origin[0], down[1] - origin[1]],
        }
    }

    pub(super) fn at(&self, x: u32, y: u32) -> [f64; 2] {
        let (x, y) = (x as f64, y as f64);
        [
            self.origin[0] + x * self.column_step[0] + y * self.row_step[0],
            self.origin[1] + x * self.column_step[1] + y * self.row_step[1],
        ]
    }
}

/// A box pyramid of the pinhole colour (empty pixels black): level k averages 2^k x 2^k pixels.
pub(super) struct Pyramid {
    levels: Vec<(usize, usize, Vec<[f32; 3]>)>,
}

impl Pyramid {
    pub(super) fn of(width: usize, height: usize, colour: Vec<[f32; 3]>, levels: usize) -> Pyramid {
        let mut all = vec![(width, height, colour)];
        for _ in 1..levels {
            let (w, h, below) = all.last().expect("level 0 is there");
            let (nw, nh) = (w.div_ceil(2), h.div_ceil(2));
            let (w, h) = (*w, *h);
            let mut next = vec![[0.0f32; 3]; nw * nh];
            for (i, texel) in next.iter_mut().enumerate() {
                let (x, y) = (i % nw, i / nw);
                for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                    let (sx, sy) = ((2 * x + dx).min(w - 1), (2 * y + dy).min(h - 1));
                    let c = below[sy * w + sx];
                    for k in 0..3 {
                        texel[k] += 0.25 * c[k];
                    }
                }
            }
            all.push((nw, nh, next));
        }
        Pyramid { levels: all }
    }

    /// Colour of the texel of level `level` holding level-0 index coordinates `p` (inside the
    /// level-0 grid).
    pub(super) fn nearest(&self, level: usize, p: [f32; 2]) -> [f32; 3] {
        let (w, h, texels) = &self.levels[level.min(self.levels.len() - 1)];
        let shift = level.min(self.levels.len() - 1);
        let x = ((p[0] + 0.5) as usize >> shift).min(w - 1);
        let y = ((p[1] + 0.5) as usize >> shift).min(h - 1);
        texels[y * w + x]
    }

    /// Bilinear colour of level `level` at level-0 index coordinates `p`.
    pub(super) fn at(&self, level: usize, p: [f32; 2]) -> [f32; 3] {
        let (w, h, texels) = &self.levels[level.min(self.levels.len() - 1)];
        let scale = 1.0 / (1u32 << level) as f32;
        let gx = ((p[0] + 0.5) * scale - 0.5).clamp(0.0, *w as f32 - 1.0);
        let gy = ((p[1] + 0.5) * scale - 0.5).clamp(0.0, *h as f32 - 1.0);
        let (x0, y0) = (gx as usize, gy as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (gx - x0 as f32, gy - y0 as f32);
        let texel = |x: usize, y: usize| texels[y * w + x];
        let mut out = [0.0; 3];
        for (k, o) in out.iter_mut().enumerate() {
            let top = texel(x0, y0)[k] * (1.0 - fx) + texel(x1, y0)[k] * fx;
            let bottom = texel(x0, y1)[k] * (1.0 - fx) + texel(x1, y1)[k] * fx;
            *o = top * (1.0 - fy) + bottom * fy;
        }
        out
    }
}

/// Per tile: the nearest depth and the largest reach, dilated.
pub(super) struct Tiles {
    columns: usize,
    rows: usize,
    /// Side of a tile, in the grid's cells; reaches are in cells too.
    side: usize,
    pub(super) reach: Vec<f32>,
    nearest: Vec<f32>,
}

impl Tiles {
    /// Tiles of `side` x `side` cells over a `width` x `height` grid of `cells`, each its
    /// (reach, depth) or None where empty.
    pub(super) fn of(
        cells: impl Iterator<Item = Option<(f32, f32)>>,
        width: usize,
        height: usize,
        side: usize,
    ) -> Tiles {
        let (columns, rows) = (width.div_ceil(side), height.div_ceil(side));
        let mut reach = vec![0.0f32; columns * rows];
        let mut nearest = vec![f32::INFINITY; columns * rows];
        for (i, cell) in cells.enumerate() {
            if let Some((cell_reach, depth)) = cell {
                let tile = (i / width / side) * columns + (i % width) / side;
                reach[tile] = reach[tile].max(cell_reach);
                nearest[tile] = nearest[tile].min(depth);
            }
        }
        // Each tile hands its reach and nearest depth to every tile its pixels can reach (as
        // many tiles as its own reach spans: the seed's 3 x 3 misses spots wider than a tile,
        // and one span for all would send the widest spot's reach over the whole frame).
        let mut dilated = vec![0.0f32; columns * rows];
        let mut dilated_nearest = vec![f32::INFINITY; columns * rows];
        for t in 0..columns * rows {
            if reach[t] <= 0.0 {
                continue;
            }
            let (tx, ty) = (t % columns, t / columns);
            let span = (reach[t] / side as f32).ceil() as usize;
            for y in ty.saturating_sub(span)..(ty + span + 1).min(rows) {
                for x in tx.saturating_sub(span)..(tx + span + 1).min(columns) {
                    let to = y * columns + x;
                    dilated[to] = dilated[to].max(reach[t]);
                    dilated_nearest[to] = dilated_nearest[to].min(nearest[t]);
                }
            }
        }
        Tiles {
            columns,
            rows,
            side,
            reach: dilated,
            nearest: dilated_nearest,
        }
    }

    /// The dilated reach and nearest depth of the tile holding grid point `p`.
    pub(super) fn at(&self, p: [f64; 2]) -> (f32, f32) {
        let tx = (p[0].max(0.0) as usize / self.side).min(self.columns - 1);
        let ty = (p[1].max(0.0) as usize / self.side).min(self.rows - 1);
        let t = ty * self.columns + tx;
        (self.reach[t], self.nearest[t])
    }
}

/// Which taps a gather pass keeps.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Pass {
    /// The centre's own surface and what lies behind it within the centre's reach.
    Own,
    /// Nearer, wider-spread surfaces seen partly over the centre.
    Front,
}

/// A small integer hash (for each output pixel's ring rotation).
pub(super) fn hash(mut v: u32) -> u32 {
    v ^= v >> 16;
    v = v.wrapping_mul(0x7feb_352d);
    v ^= v >> 15;
    v = v.wrapping_mul(0x846c_a68b);
    v ^ (v >> 16)
}

/// The layer both paths filter: the first, seen through an untilted film (whose chief-ray
/// tangents are linear in the film point, as `OutputToLayer` assumes).
pub(super) fn first_layer_untilted<'a>(
    camera: &Camera,
    ldi: &'a LayeredDepthImage,
) -> Result<Layer<'a>, RenderError> {
    if camera.film_off_plane() != 0.0 {
        return Err(RenderError::InvalidSetting(
            "the real-time models need a film square to the axis; the sensor is tilted".into(),
        ));
    }
    Ok(ldi.layer(0))
}

/// A layer pixel's height in units of the kernels' pitch (the tangent one pixel spans): what
/// scales a kernel's vertical offsets into layer rows, for both paths.
pub(super) fn layer_pixel_aspect(ldi: &LayeredDepthImage, kernels: &LensKernels) -> f32 {
    let view = ldi.view;
    ((2.0 * view.tan_half[1] / view.height as f64) / kernels.pixel_tangent) as f32
}

/// Renders the pinhole layer of `ldi` (seen from `camera`'s eye) at `width` x `height` through
/// the lens kernels `kernels` by the gather post-process.
pub fn postfx(
    camera: &Camera,
    ldi: &LayeredDepthImage,
    kernels: &LensKernels,
    width: u32,
    height: u32,
) -> Result<RgbImage, RenderError> {
    let front = first_layer_untilted(camera, ldi)?;
    let view = ldi.view;
    let (lw, lh) = (view.width as usize, view.height as usize);
    let aspect = layer_pixel_aspect(ldi, kernels);
    let sources: Vec<Option<Source>> = (0..view.pixels())
        .into_par_iter()
        .map(|i| (i, front.get(i)))
        .map(|(i, sample)| {
            sample.map(|s| Source {
                depth: s.depth_mm,
                spread: kernels.spread(
                    s.depth_mm as f64,
                    view.pixel_tangents((i % lw) as u32, (i / lw) as u32),
                ),
            })
        })
        .collect();
    let colour: Vec<[f32; 3]> = front
        .samples()
        .map(|s| s.map_or([0.0; 3], |s| s.radiance))
        .collect();
    let tiles = Tiles::of(
        sources
            .iter()
            .map(|s| s.map(|s| (s.spread.support, s.depth))),
        lw,
        lh,
        TILE,
    );
    let widest = tiles.reach.iter().copied().fold(0.0f32, f32::max);
    let spacing_of = |reach: f32| {
        let rings = ((reach / TARGET_SPACING - 0.5).ceil().max(1.0) as usize).min(MAX_RINGS);
        (rings, reach / (rings as f32 + 0.5))
    };
    let levels = (spacing_of(widest).1.max(1.0).log2().ceil() as usize + 1).max(1);
    let pyramid = Pyramid::of(lw, lh, colour, levels);
    let map = OutputToLayer::of(camera, ldi, width, height);

    let gather = |x: u32, y: u32| -> ([f32; 3], f32) {
        let p = map.at(x, y);
        let (tile_reach, tile_nearest) = tiles.at(p);
        if tile_reach <= 0.0 {
            return ([0.0; 3], 0.0);
        }
        let centre = {
            let (cx, cy) = (p[0].round(), p[1].round());
            (cx >= 0.0 && cy >= 0.0 && (cx as usize) < lw && (cy as usize) < lh)
                .then(|| sources[cy as usize * lw + cx as usize])
                .flatten()
        };
        let (centre_depth, centre_reach) =
            centre.map_or((f32::INFINITY, 0.0), |c| (c.depth, c.spread.support));
        // Every tap lies at a random point of its own patch (a stratified estimate of the
        // patch's integral): fixed ring radii would see some pixels' offsets and never others.
        let mut state = hash(x.wrapping_mul(0x9e37_79b9) ^ y);
        let mut uniform = move || {
            state = hash(state);
            state as f32 * (1.0 / 4_294_967_296.0)
        };
        let (mut sums, mut coverage) = ([[0.0f32; 3]; 2], 0.0f32);
        let mut tap = |pass: Pass, offset: [f32; 2], area: f32, level: usize| {
            // `offset`: tap from the output pixel, pinhole pixels, +y up.
            let at = [p[0] as f32 + offset[0], p[1] as f32 - offset[1] / aspect];
            // Nearest pixel by truncation of the shifted coordinate (libm's round is a call
            // per tap); left of or above the layer is out.
            let (sx, sy) = (at[0] + 0.5, at[1] + 0.5);
            if sx < 0.0 || sy < 0.0 || sx as usize >= lw || sy as usize >= lh {
                return;
            }
            let index = sy as usize * lw + sx as usize;
            let Some(source) = sources[index] else {
                return;
            };
            let in_front = source.depth < centre_depth
                && (centre.is_none() || source.spread.support > centre_reach + LAYER_REACH_STEP);
            if in_front != (pass == Pass::Front) {
                return;
            }
            let w = kernels.weight(&source.spread, [-offset[0], -offset[1]], area) * area;
            if w <= 0.0 {
                return;
            }
            // Full resolution reads the tap's own pixel: a bilinear colour would fade the
            // pixel's edges that the nearest-pixel spread lookup has already cut (an object
            // would lose a half-pixel rim of light).
            let c = match level {
                0 => pyramid.levels[0].2[index],
                _ => pyramid.at(level, at),
            };
            if in_front {
                coverage += w / source.spread.flux;
            }
            let sum = &mut sums[in_front as usize];
            for k in 0..3 {
                sum[k] += w * c[k];
            }
        };
        // One disc of taps: every pixel where that is cheap, else rings of random taps.
        let mut disc = |pass: Pass, reach: f32| -> f32 {
            let reach_pixels = reach + 0.5;
            if std::f32::consts::PI * reach_pixels * reach_pixels <= DENSE_PIXELS {
                let (cx, cy) = (p[0].round() as f32, p[1].round() as f32);
                let from = [cx - p[0] as f32, (p[1] as f32 - cy) * aspect];
                let span = reach_pixels.ceil() as i32;
                for dy in -span..=span {
                    for dx in -span..=span {
                        let offset = [from[0] + dx as f32, from[1] - dy as f32 * aspect];
                        if offset[0] * offset[0] + offset[1] * offset[1]
                            <= reach_pixels * reach_pixels
                        {
                            tap(pass, offset, 1.0, 0);
                        }
                    }
                }
                return 1.0;
            }
            let (rings, spacing) = spacing_of(reach);
            // Each tap stands for an equal patch: a ring i of 8i taps covers the annulus
            // (i -+ 1/2) spacing, the centre tap the disc of half a spacing; it reads the
            // pyramid level whose texel is at least that patch.
            let area = std::f32::consts::FRAC_PI_4 * spacing * spacing;
            let level = area.sqrt().max(1.0).log2().ceil() as usize;
            for ring in 0..=rings {
                let count = (8 * ring).max(1);
                let inner = (ring as f32 - 0.5).max(0.0) * spacing;
                let outer = (ring as f32 + 0.5) * spacing;
                for k in 0..count {
                    let radius =
                        (inner * inner + uniform() * (outer * outer - inner * inner)).sqrt();
                    let angle = std::f32::consts::TAU * (k as f32 + uniform()) / count as f32;
                    let (s, c) = angle.sin_cos();
                    tap(pass, [radius * c, radius * s], area, level);
                }
            }
            spacing
        };
        // The centre's own layer gathers over its own reach only: farther surfaces beyond it
        // are hidden by the centre's surface, and a sharp centre stays sharp beside a blurred
        // foreground.
        let own_spacing = match centre {
            Some(_) => disc(Pass::Own, centre_reach),
            None => 0.0,
        };
        // The tiles' nearest depth says whether anything nearer can spread over this pixel.
        let front_spacing = if tile_nearest < centre_depth {
            disc(Pass::Front, tile_reach)
        } else {
            0.0
        };
        let behind = 1.0 - coverage.min(1.0);
        let [own, front] = sums;
        let out = std::array::from_fn(|k| front[k] + behind * own[k]);
        (out, own_spacing.max(front_spacing))
    };
    let (w, h) = (width as usize, height as usize);
    let gathered: Vec<([f32; 3], f32)> = (0..w * h)
        .into_par_iter()
        .map(|i| gather((i % w) as u32, (i / w) as u32))
        .collect();
    let pixels = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (colour, spacing) = gathered[i];
            if spacing <= MEDIAN_FROM_SPACING {
                return colour;
            }
            let (x, y) = (i % w, i / w);
            std::array::from_fn(|k| {
                let mut window = [0.0f32; 9];
                for (n, v) in window.iter_mut().enumerate() {
                    let nx = (x + n % 3).saturating_sub(1).min(w - 1);
                    let ny = (y + n / 3).saturating_sub(1).min(h - 1);
                    *v = gathered[ny * w + nx].0[k];
                }
                window.sort_by(f32::total_cmp);
                window[4]
            })
        })
        .collect();
    Ok(RgbImage {
        width,
        height,
        pixels,
    })
}
