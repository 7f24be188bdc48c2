//! `postfx`'s fast path: the same gather at half resolution with a bounded number of taps, each
//! tap one affine map and one kernel read (seed 001 chapter 5's shape: half-resolution
//! prefilter, tiles of nearest depth and largest reach, at most 81 taps in rings, separate
//! foreground and background sums, then an upsample that keeps in-focus pixels at full
//! resolution).
//!
//! Where [`super::postfx()`] fits each tap's kernel on the fly (bracketing, rotating and scaling,
//! about 50 to 100 ns a tap), this path fits every source texel's kernel once: the map from a
//! tap's offset (in texels) to the node kernel's grid is affine, so it is folded into six
//! numbers per texel, and a tap is four multiply-adds and one table read.
//!
//! The half-resolution pipeline blurs by a known amount: a texel's sources lie within +-1/2 pixel
//! of its centre (variance 1/4 per axis) and the bilinear upsampling spreads each half-resolution
//! value over offsets -1/2 and 3/2 with weights 3/4 and 1/4 (variance 3/4 per axis). The kernels
//! are narrowed by that variance ([`PIPELINE_VARIANCE`]), so a spot's second moment is the
//! lens's; spots too small to narrow are the sharp pixels, which come from the full-resolution
//! pinhole image instead.

use super::kernels::{Kernel, LensKernels};
use super::postfx::{
    OutputToLayer, Pyramid, Tiles, first_layer_untilted, hash, layer_pixel_aspect,
};
use crate::render::RenderError;
use crate::render::camera::Camera;
use crate::render::image::RgbImage;
use crate::render::layers::LayeredDepthImage;
use rayon::prelude::*;

/// Side of a tile, in texels (16 pinhole pixels: half the seed's tile, so that the foreground
/// pass, which runs wherever a tile's dilated neighbourhood holds a nearer surface, covers a
/// quarter of the area around a blurred foreground that 32-pixel tiles gave it).
const TILE_TEXELS: usize = 8;
/// Rows of output texels the gather hands to a thread at a time.
const BAND_TEXELS: usize = 8;
/// Most rings of taps (1 + 8 + 16 + 24 = 49 taps, the low end of Tan et al.'s 48 to 81).
const MAX_RINGS: usize = 3;
/// Directions a ring tap can take: a table instead of a sine and cosine per tap.
const DIRECTIONS: usize = 256;
/// A disc of at most this many texels is read whole (no sampling noise); wider ones by rings.
const DENSE_TEXELS: f32 = 81.0;
/// Variance (pinhole pixels squared, both axes together) that the half-resolution prefilter and
/// the bilinear upsampling add to every spot: 2 x (1/4 + 3/4).
pub const PIPELINE_VARIANCE: f32 = 2.0;
/// Variance the 2-pixel output box adds over the 1-pixel one (both axes): 2 x (4 - 1) / 12.
const WIDER_BOX_VARIANCE: f32 = 0.5;
/// A node's kernel is shrunk to at least this share of its size before its box is widened
/// (spots that would need more are small, and the full-resolution pinhole pixels draw them).
const LEAST_NODE_SCALE: f64 = 0.5;
/// Between nodes a pixel's kernel is the node's scaled to the pixel's size; it is narrowed to at
/// most this share of the node's variance: the scaling also narrows the 2-pixel box in it, whose
/// sums over the texel lattice are exact only at its own width.
const MOST_NARROWING: f32 = 0.6;
/// Below this spot size (RMS radius with the pixel box, pinhole pixels) a pixel's own colour is
/// the full-resolution pinhole pixel's; above `BLURRED_SIZE` the half-resolution gather's;
/// linear between.
const SHARP_SIZE: f32 = 1.5;
const BLURRED_SIZE: f32 = 2.5;
/// A tap counts as a nearer layer only this much nearer than the centre (a slanted surface's
/// own pixels differ by less across a tile).
const NEARER_LAYER: f32 = 0.95;
/// A tap more than this wider-spread (texels of reach) than the centre counts as another depth
/// layer, in front or behind (the exact path's one pinhole pixel).
const LAYER_REACH_STEP: f32 = 0.5;

/// One half-resolution source texel: the nearest surface of its 2 x 2 pinhole pixels, with its
/// kernel fitted once. Everything a tap reads, in one 64-byte cache line: the gather is bound by
/// these loads.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Texel {
    /// Depth (mm) of the nearest surface; infinite where the texel is empty.
    depth: f32,
    /// Farthest reach of its spot, texels.
    reach: f32,
    /// Kernel grid coordinates of a tap at offset (dx, dy) texels from the output texel:
    /// gx = m[0] dx + m[1] dy + m[2], gy = m[3] dx + m[4] dy + m[5].
    map: [f32; 6],
    /// The prefiltered colour times the spot's flux (the pyramid's level 0, kept here so a
    /// tap reads one record).
    colour: [f32; 3],
    /// A dense tap's weight per kernel value, over the spot's flux: the share of the spot
    /// that one kernel value over a texel's patch stands for. Colour and weight are both per
    /// unit of flux, so a foreground weight is directly the coverage it adds.
    weight: f32,
    /// The narrowed spot's variance (pinhole pixels squared) and its centroid on the kernel's
    /// grid: a sparse tap widens the kernel about it.
    variance: f32,
    centroid_on_grid: [f32; 2],
    /// Where the node's kernel starts in the [`KernelTable`].
    kernel: u32,
}

const EMPTY: Texel = Texel {
    depth: f32::INFINITY,
    reach: 0.0,
    map: [0.0; 6],
    colour: [0.0; 3],
    weight: 0.0,
    variance: 0.0,
    centroid_on_grid: [0.0; 2],
    kernel: 0,
};

/// The kernels over the 2-pixel box, each in a square of one common side with a border of
/// zeros (beyond its own grid too), so a tap's lookup clamps its indices into the square instead
/// of testing them: a tap off a kernel reads a zero of its border.
struct KernelTable {
    values: Vec<f32>,
    side: usize,
}

impl KernelTable {
    /// Nodes of zeros before each kernel's grid, in x and in y.
    const BORDER: f32 = 1.0;

    fn of(wide: &[Kernel]) -> KernelTable {
        let side = wide.iter().map(|k| k.side).max().unwrap_or(0) + 2;
        let mut values = vec![0.0f32; wide.len() * side * side];
        for (slot, kernel) in values.chunks_mut(side * side).zip(wide) {
            for (row, source) in kernel.values.chunks(kernel.side.max(1)).enumerate() {
                let start = (row + 1) * side + 1;
                slot[start..start + source.len()].copy_from_slice(source);
            }
        }
        KernelTable { values, side }
    }

    /// The value at table coordinates (gx, gy) of the kernel starting at `start`, nearest node
    /// (coordinates carry +1/2); zero off the kernel (a negative or NaN coordinate converts to
    /// index 0, a large one clamps to the last, both on the border).
    #[inline(always)]
    fn at(&self, start: u32, gx: f32, gy: f32) -> f32 {
        let last = self.side - 1;
        let (ix, iy) = ((gx as usize).min(last), (gy as usize).min(last));
        self.values[start as usize + iy * self.side + ix]
    }
}

/// What the full-resolution upsampling needs of a texel's spot besides the tap record.
#[derive(Clone, Copy, Debug)]
struct Spot {
    /// The spot's flux (relative illumination).
    flux: f32,
    /// Its size (RMS radius with the pixel box, pinhole pixels), before narrowing.
    size: f32,
    /// Depth (mm) of the texel's surface; infinite where it is empty.
    depth: f32,
}

const NO_SPOT: Spot = Spot {
    flux: 0.0,
    size: 0.0,
    depth: f32::INFINITY,
};

/// What the half-resolution gather leaves per texel: the sums of the centre's own layer and of
/// nearer layers spread over it, and how much of the centre those cover.
#[derive(Clone, Copy, Debug, Default)]
struct Gathered {
    own: [f32; 3],
    front: [f32; 3],
    coverage: f32,
}

impl Gathered {
    /// The texel's colour: the nearer layers over what they leave of its own. Composited per
    /// texel, before upsampling: mixing the sums first would dim a surface's edge texels by
    /// the coverage of its own light spreading over the empty texels beside it (3 % of an
    /// emitter's flux).
    fn composited(&self) -> [f32; 3] {
        let behind = 1.0 - self.coverage.min(1.0);
        std::array::from_fn(|k| self.front[k] + behind * self.own[k])
    }
}

/// Renders the pinhole layer of `ldi` (seen from `camera`'s eye) at `width` x `height` through
/// the lens kernels `kernels`, by the half-resolution gather.
pub fn postfx_fast(
    camera: &Camera,
    ldi: &LayeredDepthImage,
    kernels: &LensKernels,
    width: u32,
    height: u32,
) -> Result<RgbImage, RenderError> {
    let front = first_layer_untilted(camera, ldi)?;
    let view = ldi.view;
    let (lw, lh) = (view.width as usize, view.height as usize);
    let (tw, th) = (lw.div_ceil(2), lh.div_ceil(2));
    let aspect = layer_pixel_aspect(ldi, kernels);
    let (wide, wide_variance): (Vec<Kernel>, Vec<f32>) = kernels
        .kernels
        .par_iter()
        .map(half_resolution_kernel)
        .unzip();
    let table = KernelTable::of(&wide);

    // 1. Prefilter: each texel keeps the nearest surface of its 2 x 2 pixels, its colour the
    //    patch's sum of that surface's pixels over four (premultiplied by coverage).
    //    Collected in parallel: a buffer filled first on one thread takes its page faults
    //    there, serially.
    let (mut texels, mut spots) = (Vec::new(), Vec::new());
    (0..tw * th)
        .into_par_iter()
        .map(|t| {
            let (tx, ty) = (t % tw, t / tw);
            let pixels = [(0, 0), (1, 0), (0, 1), (1, 1)].map(|(dx, dy)| {
                let (x, y) = (2 * tx + dx, 2 * ty + dy);
                (x < lw && y < lh).then(|| front.get(y * lw + x)).flatten()
            });
            let nearest = pixels
                .iter()
                .flatten()
                .fold(f32::INFINITY, |n, s| n.min(s.depth_mm));
            if !nearest.is_finite() {
                return (EMPTY, NO_SPOT);
            }
            let mut colour = [0.0f32; 3];
            for s in pixels.iter().flatten() {
                if same_surface(s.depth_mm, nearest) {
                    for (c, r) in colour.iter_mut().zip(s.radiance) {
                        *c += 0.25 * r;
                    }
                }
            }
            let centre = [2.0 * tx as f64 + 1.0, 2.0 * ty as f64 + 1.0];
            let tan = [
                view.tan_half[0] * (2.0 * centre[0] / lw as f64 - 1.0),
                view.tan_half[1] * (1.0 - 2.0 * centre[1] / lh as f64),
            ];
            let (texel, spot) = fit(kernels, &wide, &wide_variance, &table, nearest, tan, aspect);
            let colour = colour.map(|c| c * spot.flux);
            (Texel { colour, ..texel }, spot)
        })
        .unzip_into_vecs(&mut texels, &mut spots);

    // 2. Tiles: nearest depth and largest reach, each tile handed to every tile its texels
    //    can reach.
    let tiles = Tiles::of(
        texels
            .iter()
            .map(|t| t.depth.is_finite().then_some((t.reach, t.depth))),
        tw,
        th,
        TILE_TEXELS,
    );
    let widest = tiles.reach.iter().copied().fold(0.0f32, f32::max);
    let levels = (rings_for(widest).1.max(1.0).log2().ceil() as usize + 1).max(1);
    let pyramid = Pyramid::of(tw, th, texels.iter().map(|t| t.colour).collect(), levels);

    // 3. The half-resolution gather, over the texels the output reads.
    let map = OutputToLayer::of(camera, ldi, width, height);
    let corners = [
        map.at(0, 0),
        map.at(width - 1, 0),
        map.at(0, height - 1),
        map.at(width - 1, height - 1),
    ];
    let texel_of = |v: f64| (v - 0.5) * 0.5;
    let span = |axis: usize, size: usize| {
        let lo = corners
            .iter()
            .map(|c| texel_of(c[axis]))
            .fold(f64::INFINITY, f64::min);
        let hi = corners
            .iter()
            .map(|c| texel_of(c[axis]))
            .fold(f64::NEG_INFINITY, f64::max);
        let lo = (lo.floor().max(0.0) as usize).min(size - 1);
        let hi = (hi.ceil().max(0.0) as usize + 1).min(size - 1);
        (lo, hi - lo + 1)
    };
    let (x0, gw) = span(0, tw);
    let (y0, gh) = span(1, th);
    let depth_reach: Vec<[f32; 2]> = texels.par_iter().map(|t| [t.depth, t.reach]).collect();
    let gatherer = Gatherer {
        table: &table,
        texels: &texels,
        depth_reach: &depth_reach,
        pyramid: &pyramid,
        tiles: &tiles,
        directions: (0..DIRECTIONS)
            .map(|i| {
                let (s, c) =
                    (std::f32::consts::TAU * (i as f32 + 0.5) / DIRECTIONS as f32).sin_cos();
                [c, s]
            })
            .collect(),
        width: tw,
        height: th,
    };
    // Bands of rows to a thread: a band's taps read a strip of texels that stays in cache,
    // where rayon's split of a row-major range down to single rows spreads one thread's reads
    // over more rows than the cache holds.
    let gathered: Vec<Gathered> = (0..gw * gh)
        .into_par_iter()
        .with_min_len(gw * BAND_TEXELS)
        .map(|i| gatherer.at(x0 + i % gw, y0 + i / gw))
        .collect();

    // 4. Upsample: the composited colour bilinear from the gather; where a pixel's own surface
    //    is sharp, its own layer from the full-resolution pinhole pixel under the nearer
    //    layers' bilinear sum and coverage.
    let (w, h) = (width as usize, height as usize);
    let pixels = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let p = map.at((i % w) as u32, (i / w) as u32);
            let u = [
                (texel_of(p[0]) as f32 - x0 as f32).clamp(0.0, (gw - 1) as f32),
                (texel_of(p[1]) as f32 - y0 as f32).clamp(0.0, (gh - 1) as f32),
            ];
            let (ix, iy) = (u[0] as usize, u[1] as usize);
            let (fx, fy) = (u[0] - ix as f32, u[1] - iy as f32);
            let (jx, jy) = ((ix + 1).min(gw - 1), (iy + 1).min(gh - 1));
            let corners = [
                (iy * gw + ix, (1.0 - fx) * (1.0 - fy)),
                (iy * gw + jx, fx * (1.0 - fy)),
                (jy * gw + ix, (1.0 - fx) * fy),
                (jy * gw + jx, fx * fy),
            ];
            let mut colour = [0.0f32; 3];
            for &(c, wt) in &corners {
                for (o, b) in colour.iter_mut().zip(gathered[c].composited()) {
                    *o += wt * b;
                }
            }
            let (sx, sy) = (p[0] + 0.5, p[1] + 0.5);
            if !(sx >= 0.0 && sy >= 0.0 && (sx as usize) < lw && (sy as usize) < lh) {
                return colour;
            }
            let (sx, sy) = (sx as usize, sy as usize);
            let spot = spots[(sy / 2) * tw + sx / 2];
            if spot.size >= BLURRED_SIZE {
                return colour;
            }
            let Some(sample) = front.get(sy * lw + sx) else {
                return colour;
            };
            if !same_surface(sample.depth_mm, spot.depth) {
                return colour;
            }
            let blend = ((spot.size - SHARP_SIZE) / (BLURRED_SIZE - SHARP_SIZE)).clamp(0.0, 1.0);
            let mut mixed = Gathered::default();
            for &(c, wt) in &corners {
                let g = &gathered[c];
                for k in 0..3 {
                    mixed.front[k] += wt * g.front[k];
                }
                mixed.coverage += wt * g.coverage;
            }
            mixed.own = sample.radiance.map(|c| c * spot.flux);
            let sharp = mixed.composited();
            std::array::from_fn(|k| sharp[k] + blend * (colour[k] - sharp[k]))
        })
        .collect();
    Ok(RgbImage {
        width,
        height,
        pixels,
    })
}

/// Two depths of one surface for the prefilter: within 1 % (a texel's 2 x 2 pixels of one
/// surface differ by far less; a silhouette by far more).
fn same_surface(depth: f32, nearest: f32) -> bool {
    depth <= nearest * 1.01
}

/// A node's kernel as the half-resolution gather samples it, and its variance (both axes,
/// pinhole pixels squared): shrunk about its centroid by the variance the pipeline adds
/// ([`PIPELINE_VARIANCE`]) and by the wider box's, then taken over the 2-pixel box. Shrinking
/// before widening keeps the box exactly 2 pixels wide, so the kernel's sum over the texel
/// lattice stays a quarter of its flux at any phase (shrinking the widened kernel shrank its
/// box too and lost up to 3 % of an emitter's flux).
fn half_resolution_kernel(kernel: &Kernel) -> (Kernel, f32) {
    if kernel.side == 0 {
        return (kernel.clone(), 0.0);
    }
    let size2 = kernel.size() * kernel.size();
    let added = (PIPELINE_VARIANCE + WIDER_BOX_VARIANCE) as f64;
    let scale = ((size2 - added) / size2)
        .max(LEAST_NODE_SCALE * LEAST_NODE_SCALE)
        .sqrt();
    let variance = scale * scale * size2 + WIDER_BOX_VARIANCE as f64;
    (kernel.scaled(scale).over_two_pixel_box(), variance as f32)
}

/// The texel at `depth_mm` seen at tangents `tan`: its spread fitted once into an affine map
/// from tap offsets (texels) to the node kernel's grid, scaled to the pixel's own size less
/// what the pipeline adds.
fn fit(
    kernels: &LensKernels,
    wide: &[Kernel],
    wide_variance: &[f32],
    table: &KernelTable,
    depth_mm: f32,
    tan: [f64; 2],
    aspect: f32,
) -> (Texel, Spot) {
    let spread = kernels.spread(depth_mm as f64, tan);
    let kernel = &wide[spread.node as usize];
    let dark = Texel {
        depth: depth_mm,
        ..EMPTY
    };
    if kernel.side == 0 || spread.flux <= 0.0 {
        let spot = Spot {
            depth: depth_mm,
            ..NO_SPOT
        };
        return (dark, spot);
    }
    // The node's kernel is scaled to the pixel's variance less what the pipeline adds.
    let natural = wide_variance[spread.node as usize];
    let wanted = spread.size * spread.size - PIPELINE_VARIANCE;
    let narrowed = wanted.max(MOST_NARROWING * natural);
    let scale = (natural / narrowed).sqrt();
    let per_node = scale / kernel.spacing as f32;
    let [c, s] = spread.azimuth;
    // A tap at (dx, dy) texels (rows down) from the output lies at layer offset (2 dx, 2 dy);
    // the kernel's offset, source to output with +y up, is (-2 dx, 2 aspect dy), turned by the
    // azimuth into the kernel frame and scaled about the centroid.
    let centroid_on_grid = [
        (spread.node_centroid[0] - kernel.origin[0] as f32) / kernel.spacing as f32,
        (spread.node_centroid[1] - kernel.origin[1] as f32) / kernel.spacing as f32,
    ];
    let base = [
        centroid_on_grid[0] - per_node * spread.centroid[0],
        centroid_on_grid[1] - per_node * spread.centroid[1],
    ];
    let texel = Texel {
        depth: depth_mm,
        reach: 0.5 * (spread.support + std::f32::consts::FRAC_1_SQRT_2),
        // +1/2: the table's nearest node by truncation; the border: where the grid starts.
        map: [
            -2.0 * c * per_node,
            2.0 * aspect * s * per_node,
            base[0] + 0.5 + KernelTable::BORDER,
            2.0 * s * per_node,
            2.0 * aspect * c * per_node,
            base[1] + 0.5 + KernelTable::BORDER,
        ],
        colour: [0.0; 3],
        // A dense tap stands for one texel: 4 pinhole pixels of patch.
        weight: 4.0 * scale * scale * spread.flux_ratio / spread.flux,
        variance: narrowed,
        centroid_on_grid: centroid_on_grid.map(|g| g + 0.5 + KernelTable::BORDER),
        kernel: (spread.node as usize * table.side * table.side) as u32,
    };
    let spot = Spot {
        flux: spread.flux,
        size: spread.size,
        depth: depth_mm,
    };
    (texel, spot)
}

/// Rings and their spacing (texels) for a disc of `reach` texels.
fn rings_for(reach: f32) -> (usize, f32) {
    let rings = ((reach - 0.5).ceil().max(1.0) as usize).min(MAX_RINGS);
    (rings, reach / (rings as f32 + 0.5))
}

/// Which layer a gather pass keeps.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Pass {
    Own,
    Front,
}

struct Gatherer<'a> {
    table: &'a KernelTable,
    texels: &'a [Texel],
    /// Each texel's depth and reach, as in its record.
    depth_reach: &'a [[f32; 2]],
    pyramid: &'a Pyramid,
    tiles: &'a Tiles,
    /// Unit vectors at the centres of [`DIRECTIONS`] equal sectors of the circle.
    directions: Vec<[f32; 2]>,
    width: usize,
    height: usize,
}

/// Which sources a pass keeps: those in front of the centre (`Pass::Front`) or the others.
/// A source is in front when it is at least [`NEARER_LAYER`] nearer and spreads at least
/// [`LAYER_REACH_STEP`] wider than the centre (any nearer source, where the centre is empty).
#[derive(Clone, Copy)]
struct Layering {
    nearer_than: f32,
    wider_than: f32,
}

impl Layering {
    #[inline(always)]
    fn in_front(&self, depth: f32, reach: f32) -> bool {
        depth < self.nearer_than && reach > self.wider_than
    }
}

impl Gatherer<'_> {
    /// The gather at texel (x, y).
    fn at(&self, x: usize, y: usize) -> Gathered {
        let mut out = Gathered::default();
        let (tile_reach, tile_nearest) = self.tiles.at([x as f64, y as f64]);
        if tile_reach <= 0.0 {
            return out;
        }
        let centre = &self.texels[y * self.width + x];
        let covered = centre.depth.is_finite();
        let layering = Layering {
            nearer_than: NEARER_LAYER * centre.depth,
            wider_than: match covered {
                true => centre.reach + LAYER_REACH_STEP,
                false => f32::NEG_INFINITY,
            },
        };
        let mut state = hash((x as u32).wrapping_mul(0x9e37_79b9) ^ y as u32);
        if covered {
            self.disc(
                Pass::Own,
                layering,
                [x, y],
                centre.reach,
                &mut state,
                &mut out,
            );
        }
        // Only a nearer surface that spreads wider than the centre counts as in front, and no
        // texel of the tile spreads wider than the tile's reach.
        if tile_nearest < layering.nearer_than && tile_reach > layering.wider_than {
            self.disc(
                Pass::Front,
                layering,
                [x, y],
                tile_reach,
                &mut state,
                &mut out,
            );
        }
        out
    }

    /// One disc of taps of `reach` texels around `at`: every texel where that is at most
    /// [`DENSE_TEXELS`], else rings of taps at random points of equal patches.
    fn disc(
        &self,
        pass: Pass,
        layering: Layering,
        at: [usize; 2],
        reach: f32,
        state: &mut u32,
        out: &mut Gathered,
    ) {
        let radius = reach + 0.5;
        if std::f32::consts::PI * radius * radius <= DENSE_TEXELS {
            self.dense(pass == Pass::Front, layering, at, radius, out);
            return;
        }
        let (rings, spacing) = rings_for(reach);
        let area = std::f32::consts::FRAC_PI_4 * spacing * spacing;
        let level = area.sqrt().max(1.0).log2().ceil() as usize;
        let mut uniform = || {
            *state = hash(*state);
            *state as f32 * (1.0 / 4_294_967_296.0)
        };
        for ring in 0..=rings {
            let count = (8 * ring).max(1);
            let inner = (ring as f32 - 0.5).max(0.0) * spacing;
            let outer = (ring as f32 + 0.5) * spacing;
            for k in 0..count {
                let r = (inner * inner + uniform() * (outer * outer - inner * inner)).sqrt();
                let turn = (k as f32 + uniform()) / count as f32;
                let [c, s] = self.directions[(turn * DIRECTIONS as f32) as usize % DIRECTIONS];
                self.sparse_tap(pass, layering, at, [r * c, r * s], area, level, out);
            }
        }
    }

    /// Every texel within `radius` of `at` (integer offsets (dx, dy) with dx^2 + dy^2 <=
    /// radius^2), row by row: the loop the frame spends most of its time in, so each row's
    /// span is clipped once and a tap is a record read, a layer test, a kernel read and four
    /// multiply-adds.
    #[inline(always)]
    fn dense(
        &self,
        front: bool,
        layering: Layering,
        at: [usize; 2],
        radius: f32,
        out: &mut Gathered,
    ) {
        let (x, y) = (at[0] as isize, at[1] as isize);
        let (w, h) = (self.width as isize, self.height as isize);
        let span = radius as isize;
        let (mut sums, mut coverage) = ([0.0f32; 3], 0.0f32);
        for dy in (-span).max(-y)..=span.min(h - 1 - y) {
            let half = (radius * radius - (dy * dy) as f32).max(0.0).sqrt() as isize;
            let (lo, hi) = ((-half).max(-x), half.min(w - 1 - x));
            if lo > hi {
                continue;
            }
            let row = ((y + dy) * w + x) as usize;
            let sources = &self.texels[(row as isize + lo) as usize..=(row as isize + hi) as usize];
            let fy = dy as f32;
            for (dx, source) in (lo..=hi).zip(sources) {
                if layering.in_front(source.depth, source.reach) != front {
                    continue;
                }
                let fx = dx as f32;
                let m = &source.map;
                let value = self.table.at(
                    source.kernel,
                    m[0] * fx + m[1] * fy + m[2],
                    m[3] * fx + m[4] * fy + m[5],
                );
                let weight = value * source.weight;
                coverage += weight;
                for (sum, c) in sums.iter_mut().zip(source.colour) {
                    *sum += weight * c;
                }
            }
        }
        let sum = match front {
            true => {
                out.coverage += coverage;
                &mut out.front
            }
            false => &mut out.own,
        };
        for (o, s) in sum.iter_mut().zip(sums) {
            *o += s;
        }
    }

    /// One tap at `offset` texels from `at` standing for `area` texels, its colour from
    /// pyramid level `level`, its kernel widened to the patch (a spot evaluated at one point
    /// for the whole patch).
    #[allow(clippy::too_many_arguments)]
    #[inline]
    fn sparse_tap(
        &self,
        pass: Pass,
        layering: Layering,
        at: [usize; 2],
        offset: [f32; 2],
        area: f32,
        level: usize,
        out: &mut Gathered,
    ) {
        let (px, py) = (at[0] as f32 + offset[0], at[1] as f32 + offset[1]);
        let (sx, sy) = (px + 0.5, py + 0.5);
        if sx < 0.0 || sy < 0.0 || sx as usize >= self.width || sy as usize >= self.height {
            return;
        }
        // The depth and reach first, from their own small array: a sparse tap lands far from
        // the last one, and most foreground-pass taps land on surfaces that are not in front,
        // so most of them never read the 64-byte record.
        let index = sy as usize * self.width + sx as usize;
        let [depth, reach] = self.depth_reach[index];
        let in_front = layering.in_front(depth, reach);
        if !depth.is_finite() || in_front != (pass == Pass::Front) {
            return;
        }
        let source = &self.texels[index];
        // Widened about the centroid by the patch's variance beyond a texel's (pinhole pixels
        // squared: a texel is 4 of them): offsets shrink, the weight grows by the square to
        // keep the flux.
        let m = &source.map;
        let shrink = (source.variance / (source.variance + 4.0 * (area - 1.0) / 6.0)).sqrt();
        let [cx, cy] = source.centroid_on_grid;
        let gx = cx + (m[0] * offset[0] + m[1] * offset[1] + m[2] - cx) * shrink;
        let gy = cy + (m[3] * offset[0] + m[4] * offset[1] + m[5] - cy) * shrink;
        let value = shrink * shrink * self.table.at(source.kernel, gx, gy);
        if value <= 0.0 {
            return;
        }
        let w = value * source.weight * area;
        let c = match level {
            0 => source.colour,
            _ => self.pyramid.nearest(level, [px, py]),
        };
        let sum = match in_front {
            true => {
                out.coverage += w;
                &mut out.front
            }
            false => &mut out.own,
        };
        for k in 0..3 {
            sum[k] += w * c[k];
        }
    }
}

#[cfg(test)]
mod tests {
    /// A tap's record fills one cache line and no more.
    #[test]
    fn a_texel_is_one_cache_line() {
        assert_eq!(std::mem::size_of::<super::Texel>(), 64);
    }
}
