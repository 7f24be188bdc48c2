//! The CPU twin of `shaders/ibrt.wgsl`: the same algorithm and the same f32 arithmetic.
//!
//! It is the test oracle for the GPU path and the fallback where no adapter exists. Each
//! function here has a namesake in the shader; change both together. Where the shader works one
//! sample at a time without a loop of its own (drawing the samples, building the film-side rays,
//! a ray's span over the layer image), the twin works on groups of samples, of one pixel or
//! several, side by side in vector lanes: the same operations on each, choices made by selecting
//! instead of branching, so the values are the shader's. The one deliberate difference: the
//! traced and baked lens functions are not f32 ports here but the library's own f64 tracer
//! ([`crate::trace`]) and table sampler ([`LrtfTable::lookup_layer`]), so the CPU twin *is* the oracle
//! the shader's ports are measured against.

use super::RenderError;
use super::chromatic::{CHANNELS, ChannelLenses, Chromatic};
use super::gpu_types::{ChannelParams, FrameParams, LayerData, LensData, SeidelParams};
use crate::lrtf::{LOOKUP_GROUP, Lookup, LookupScratch, LrtfTable};
use crate::model::{LensModel, SEIDEL_CONVERGED_MM, SEIDEL_INVERSE_STEPS, SEIDEL_SETTLED_MM};
use crate::trace::{GROUP_RAYS, GroupBlock, Tracer, Travel, with_widest_isa};
use rayon::prelude::*;

const PI: f32 = std::f32::consts::PI;
/// How often the segment is shrunk to the depths the pyramid holds under its footprint before
/// the march. Once is a cheap global cut; each further one is a chain of dependent loads and a
/// division, and the march skips the same space cell by cell: with three the march took 1.6x
/// the time it takes with one, with none 1.9x (perf, demo scene; README, Performance).
pub(crate) const FOOTPRINT_CLAMP_ITERATIONS: u32 = 1;
pub(crate) const DEPTH_TOLERANCE: f32 = 1e-5;
/// Rounding of an inverse depth interpolated along the march, in units of the march's end
/// values (four f32 ulps): a far layer's w is a small difference of the near end's large w, so a
/// relative tolerance alone missed a background at 100 km behind a subject at 2 m.
pub(crate) const DEPTH_SLACK: f32 = 4.0 * f32::EPSILON;
pub(crate) const NO_CROSSING: f32 = 1e30;
/// The shader's `MONOCHROME_SAMPLING_BLOCK`: a monochrome render's sampling pupil follows the
/// coordinate pupil's block.
pub(crate) const MONOCHROME_SAMPLING_BLOCK: u32 = 1;
/// The multipliers of the integer hash `mix_bits` (Wellons' lowbias32).
pub(crate) const HASH_MULTIPLIER_1: u32 = 0x7feb_352d;
pub(crate) const HASH_MULTIPLIER_2: u32 = 0x846c_a68b;
/// 2^32 / golden ratio: the lattice's second coordinate steps by it.
pub(crate) const LATTICE_GOLDEN: u32 = 0x9e37_79b9;

type Vec2 = [f32; 2];
type Vec3 = [f32; 3];

/// WGSL's `mix`: a * (1 - t) + b * t.
#[inline(always)]
fn mix3(a: Vec3, b: Vec3, t: f32) -> Vec3 {
    let u = 1.0 - t;
    [
        a[0] * u + b[0] * t,
        a[1] * u + b[1] * t,
        a[2] * u + b[2] * t,
    ]
}

pub(crate) fn mix_bits(x: u32) -> u32 {
    let mut h = x;
    h ^= h >> 16;
    h = h.wrapping_mul(HASH_MULTIPLIER_1);
    h ^= h >> 15;
    h = h.wrapping_mul(HASH_MULTIPLIER_2);
    h ^= h >> 16;
    h
}

#[inline(always)]
fn unit_from_bits(bits: u32) -> f32 {
    // 24 bits fit an i32, whose conversion every vector instruction set has (the u32 one needs
    // AVX-512); the value is the same.
    ((bits >> 8) as i32) as f32 * (1.0 / 16_777_216.0)
}

/// Rank-1 lattice point `index` of `count`, shifted modulo 1 by the scrambles (see the shader).
#[inline(always)]
pub(crate) fn lattice_point(index: u32, count: u32, scramble_x: u32, scramble_y: u32) -> Vec2 {
    let stratum = 0xffff_ffff / count.max(1);
    let x_bits = index.wrapping_mul(stratum).wrapping_add(scramble_x);
    let y_bits = index.wrapping_mul(LATTICE_GOLDEN).wrapping_add(scramble_y);
    [unit_from_bits(x_bits), unit_from_bits(y_bits)]
}

/// Shirley and Chiu's concentric map from the unit square to the unit disc, without branches
/// (the samples of a group go through it side by side in vector lanes): the angle within the
/// octant is `QUARTER_PI` times the smaller coordinate over the larger, and the larger one's axis
/// decides whether its cosine or its sine is the point's x.
#[inline(always)]
pub(crate) fn concentric_disc(u: Vec2) -> Vec2 {
    let a = [2.0 * u[0] - 1.0, 2.0 * u[1] - 1.0];
    let x_dominant = a[0].abs() > a[1].abs();
    let (r, ratio) = if x_dominant {
        (a[0], a[1] / a[0])
    } else {
        (a[1], a[0] / a[1])
    };
    let (sin, cos) = sin_cos_octant(QUARTER_PI * ratio);
    let disc = if x_dominant {
        [r * cos, r * sin]
    } else {
        [r * sin, r * cos]
    };
    // The centre of the square (0 / 0 above) is the centre of the disc.
    if r == 0.0 { [0.0, 0.0] } else { disc }
}

pub(crate) const QUARTER_PI: f32 = PI / 4.0;

/// Taylor coefficients of sin(x) / x and cos(x) in x^2 (1/3!, 1/5!, ... and 1/2!, 1/4!, ...,
/// alternating in sign): through x^9 and x^10, whose remainders on |x| <= pi/4 (below 2e-9 and
/// 2e-10) are far under half an f32 ulp of the results (0.7 there: 3e-8).
pub(crate) const SIN_TAYLOR: [f32; 4] = [-1.0 / 6.0, 1.0 / 120.0, -1.0 / 5040.0, 1.0 / 362_880.0];
pub(crate) const COS_TAYLOR: [f32; 5] = [
    -1.0 / 2.0,
    1.0 / 24.0,
    -1.0 / 720.0,
    1.0 / 40_320.0,
    -1.0 / 3_628_800.0,
];

/// sin(x) and cos(x) for |x| <= pi/4 (the shader's `sin_cos_octant`): polynomials by Horner's
/// rule, plain multiplies and adds, so the twin and the shader evaluate the same arithmetic and
/// the compiler vectorises it (libm's `sincosf` is a call per sample; the shader's builtins
/// differ from device to device).
#[inline(always)]
pub(crate) fn sin_cos_octant(x: f32) -> (f32, f32) {
    let x2 = x * x;
    let [s1, s2, s3, s4] = SIN_TAYLOR;
    let [c1, c2, c3, c4, c5] = COS_TAYLOR;
    let sin_tail = ((s4 * x2 + s3) * x2 + s2) * x2 + s1;
    let cos_tail = (((c5 * x2 + c4) * x2 + c3) * x2 + c2) * x2 + c1;
    (x + x * x2 * sin_tail, 1.0 + x2 * cos_tail)
}

#[derive(Clone, Copy, Debug)]
struct ObjectRay {
    origin: Vec3,
    direction: Vec3,
    valid: bool,
}

fn paraxial_lens_ray(frame: &FrameParams, film: Vec3, pupil: Vec3) -> ObjectRay {
    paraxial_map(
        frame.focal_length,
        frame.front_principal_z,
        frame.rear_principal_z,
        film,
        pupil,
    )
}

/// Thin or thick lens: unit magnification between the principal planes, power 1/f.
fn paraxial_map(
    focal_length: f32,
    front_principal_z: f32,
    rear_principal_z: f32,
    film: Vec3,
    pupil: Vec3,
) -> ObjectRay {
    let to_pupil = [pupil[0] - film[0], pupil[1] - film[1], pupil[2] - film[2]];
    let t = (rear_principal_z - film[2]) / to_pupil[2];
    let height = [film[0] + t * to_pupil[0], film[1] + t * to_pupil[1]];
    let image_distance = film[2] - rear_principal_z;
    let image_slope = [
        (film[0] - height[0]) / image_distance,
        (film[1] - height[1]) / image_distance,
    ];
    let object_slope = [
        image_slope[0] + height[0] / focal_length,
        image_slope[1] + height[1] / focal_length,
    ];
    ObjectRay {
        origin: [height[0], height[1], front_principal_z],
        direction: [object_slope[0], object_slope[1], 1.0],
        valid: true,
    }
}

fn blocked_ray() -> ObjectRay {
    ObjectRay {
        origin: [0.0; 3],
        direction: [0.0, 0.0, 1.0],
        valid: false,
    }
}

/// Paraxial channel `channel` of a chromatic render: blocked outside the channel's exit pupil,
/// else the channel's thin or thick lens.
fn channel_paraxial_ray(
    channels: &ChannelParams,
    channel: usize,
    film: Vec3,
    pupil: Vec3,
) -> ObjectRay {
    let to_pupil = [pupil[0] - film[0], pupil[1] - film[1], pupil[2] - film[2]];
    let t = (channels.exit_pupil_z[channel] - film[2]) / to_pupil[2];
    let crossing = [film[0] + t * to_pupil[0], film[1] + t * to_pupil[1]];
    if crossing[0] * crossing[0] + crossing[1] * crossing[1] > channels.exit_pupil_limit_sq[channel]
    {
        return blocked_ray();
    }
    paraxial_map(
        channels.focal_length[channel],
        channels.front_principal_z[channel],
        channels.rear_principal_z[channel],
        film,
        pupil,
    )
}

/// The shader's `seidel_aberration`: transverse aberration (mm) of the ray to Gaussian image
/// point `g` through normalised exit-pupil point `p`.
#[inline(always)]
fn seidel_aberration(s: &SeidelParams, g: Vec2, p: Vec2) -> Vec2 {
    let radius = (g[0] * g[0] + g[1] * g[1]).sqrt();
    let u = if radius > 0.0 {
        [g[0] / radius, g[1] / radius]
    } else {
        [1.0, 0.0]
    };
    let v = [-u[1], u[0]];
    let h = radius * s.inverse_chief_height;
    let py = p[0] * u[0] + p[1] * u[1];
    let px = p[0] * v[0] + p[1] * v[1];
    let rho2 = px * px + py * py;
    let ex = s.spherical * rho2 * px + 2.0 * s.coma * h * px * py + s.sagittal * h * h * px;
    let ey = s.spherical * rho2 * py
        + s.coma * h * (rho2 + 2.0 * py * py)
        + s.tangential * h * h * py
        + s.distortion * h * h * h;
    [ey * u[0] + ex * v[0], ey * u[1] + ex * v[1]]
}

/// The shader's `seidel_lens_ray` (the Gaussian image point whose aberrated ray through the
/// film-side ray's exit-pupil point lands where the film-side ray does, a fixed point, then the
/// thick lens's ray from it; blocked where the fixed point does not settle) for the first
/// `out.len()` samples of `samples` (film point k through pupil point k) into `out[k]`, side by
/// side in vector lanes: each step of the fixed point taken by every lane, a lane's point and
/// step kept from the step where the shader's loop stops on, and the steps ended once every
/// sample's loop would have; so each ray is bit for bit the shader's one-sample loop's (tested).
/// One sample at a time, the Seidel model's frame took twice the traced model's on the CPU.
#[inline(always)]
fn seidel_lens_rays(
    frame: &FrameParams,
    s: &SeidelParams,
    samples: &SampleLanes,
    out: &mut [ObjectRay],
) {
    const G: usize = SAMPLE_GROUP;
    let mut exit = [[0.0f32; G]; 2];
    let mut landing = [[0.0f32; G]; 2];
    let mut p = [[0.0f32; G]; 2];
    for k in 0..G {
        let (film, pupil) = (samples.film(k), samples.pupil(k));
        let d = [pupil[0] - film[0], pupil[1] - film[1], pupil[2] - film[2]];
        let t_exit = (s.exit_pupil_z - film[2]) / d[2];
        let t_image = (s.image_z - film[2]) / d[2];
        for axis in 0..2 {
            exit[axis][k] = film[axis] + t_exit * d[axis];
            landing[axis][k] = film[axis] + t_image * d[axis];
            p[axis][k] = exit[axis][k] * s.inverse_marginal_height;
        }
    }
    let mut g = landing;
    let mut step = [0.0f32; G];
    // Lanes past the samples count as stopped, so their numbers never keep the steps going.
    let mut stopped: [bool; G] = std::array::from_fn(|k| k >= out.len());
    for _ in 0..SEIDEL_INVERSE_STEPS {
        let mut all_stopped = true;
        for k in 0..G {
            let eps = seidel_aberration(s, [g[0][k], g[1][k]], [p[0][k], p[1][k]]);
            let next = [landing[0][k] - eps[0], landing[1][k] - eps[1]];
            let moved = [next[0] - g[0][k], next[1] - g[1][k]];
            let length = (moved[0] * moved[0] + moved[1] * moved[1]).sqrt();
            let going = !stopped[k];
            for axis in 0..2 {
                g[axis][k] = if going { next[axis] } else { g[axis][k] };
            }
            step[k] = if going { length } else { step[k] };
            stopped[k] |= going & (length <= SEIDEL_CONVERGED_MM as f32);
            all_stopped &= stopped[k];
        }
        if all_stopped {
            break;
        }
    }
    for (k, o) in out.iter_mut().enumerate() {
        // Written so that NaN fails the test too.
        *o = if step[k] <= SEIDEL_SETTLED_MM as f32 {
            paraxial_lens_ray(
                frame,
                [g[0][k], g[1][k], s.image_z],
                [exit[0][k], exit[1][k], s.exit_pupil_z],
            )
        } else {
            blocked_ray()
        };
    }
}

#[inline(always)]
fn project(frame: &FrameParams, ray: &ObjectRay, depth: f32) -> Vec3 {
    let z = frame.eye_z - depth;
    let t = (z - ray.origin[2]) / ray.direction[2];
    let p = [
        ray.origin[0] + t * ray.direction[0],
        ray.origin[1] + t * ray.direction[1],
    ];
    let inverse_depth = 1.0 / depth;
    let column = (p[0] * inverse_depth / frame.tan_half_x + 1.0) * 0.5 * frame.layer_width as f32;
    let row = (1.0 - p[1] * inverse_depth / frame.tan_half_y) * 0.5 * frame.layer_height as f32;
    [column, row, inverse_depth]
}

/// Width and height in texels of level `level` of the depth pyramid.
#[inline(always)]
fn level_size(frame: &FrameParams, level: u32) -> [u32; 2] {
    [
        (frame.layer_width + (1 << level) - 1) >> level,
        (frame.layer_height + (1 << level) - 1) >> level,
    ]
}

/// Where each level of the depth pyramid starts in `depth_bounds`, and its width in texels.
/// A side of under 2^31 pixels halves to one in at most 31 steps, so 32 levels hold every
/// pyramid (a layer image 2^31 pixels wide would need 32 GiB of depths).
struct PyramidLevels {
    offsets: [u32; 32],
    widths: [u32; 32],
}

impl PyramidLevels {
    #[inline(always)]
    fn of(frame: &FrameParams) -> PyramidLevels {
        let mut levels = PyramidLevels {
            offsets: [0; 32],
            widths: [0; 32],
        };
        let mut offset = 0;
        for level in 0..frame.pyramid_levels.min(32) {
            let [w, h] = level_size(frame, level);
            levels.offsets[level as usize] = offset;
            levels.widths[level as usize] = w;
            offset += w * h;
        }
        levels
    }

    /// The start and width of `level` (below 32).
    #[inline(always)]
    fn level(&self, level: u32) -> (u32, u32) {
        let at = (level % 32) as usize;
        (self.offsets[at], self.widths[at])
    }
}

/// The pyramid level at which the footprint of columns `c` and rows `r` (first and last of
/// each) is at most two texels wide and high, or the top of `levels`: the shader's climb one
/// level at a time. The box is wider at the finest levels and not from some level up (a span
/// of at most one stays so at the next level), so the level is the number of levels below the
/// top where it is wider: a binary search for where that ends, the same five steps in every
/// lane (32 levels hold every pyramid, see [`PyramidLevels`]).
#[inline(always)]
fn footprint_level(c: [u32; 2], r: [u32; 2], levels: u32) -> u32 {
    let wide = |l: u32| ((c[1] >> l) - (c[0] >> l) > 1) | ((r[1] >> l) - (r[0] >> l) > 1);
    let mut level = 0;
    for step in [16, 8, 4, 2, 1] {
        if level + step < levels && wide(level + step - 1) {
            level += step;
        }
    }
    level
}

/// The nearest layer at `pixel` whose inverse depth lies in `window` ([lower, upper], see
/// [`Segment::depth_window`]), as its index into `layers.surfels`.
#[inline(always)]
fn hit_in_pixel(layers: &LayerData, pixel: u32, window: Vec2) -> Option<u32> {
    let end = layers.starts[pixel as usize + 1];
    for index in layers.starts[pixel as usize]..end {
        let w = layers.inverse_depths[index as usize];
        if w < window[0] {
            return None;
        }
        if w <= window[1] {
            return Some(index);
        }
    }
    None
}

/// The part of `range` (parameters from 0 at `a` to 1 at `b`) inside [0, extent] along one
/// axis; empty ([1, 0]) or all of `range` when the run is parallel to the axis. Both cases are
/// computed and one chosen, so the group's segments are set up in vector lanes.
#[inline(always)]
fn clip_axis(a: f32, b: f32, extent: f32, range: Vec2) -> Vec2 {
    let d = b - a;
    let t0 = (0.0 - a) / d;
    let t1 = (extent - a) / d;
    let clipped = [range[0].max(t0.min(t1)), range[1].min(t0.max(t1))];
    let outside = (a < 0.0) | (a > extent);
    let parallel = if outside { [1.0, 0.0] } else { range };
    if d == 0.0 { parallel } else { clipped }
}

/// The shader's `clamp(floor(v), 0, last)` taken as a whole number (its `u32(...)` and
/// `i32(...)` of it): above 0 floor is truncation, and everything else (NaN too) ends at 0, so
/// no floor is computed (baseline x86-64 has no floor instruction, and libm's costs a call per
/// use). The value is clamped in f32 first, to the largest f32 below 2^31 (beyond every layer
/// image: one that wide would need 32 GiB of depths), so the truncation is one signed
/// conversion with no saturation to handle: a saturating `as` is taken apart into scalar
/// conversions and fix-ups, lane by lane.
#[inline(always)]
fn floor_clamped(v: f32, last: u32) -> u32 {
    const BELOW_2_POW_31: f32 = 2_147_483_520.0;
    // `max` returns 0 for NaN, so the value is finite and in [0, 2^31) (`clamp` would keep
    // the NaN).
    #[allow(clippy::manual_clamp)]
    let clamped = v.max(0.0).min(BELOW_2_POW_31);
    // SAFETY: `clamped` is finite and its truncation fits an i32 (above).
    let whole: i32 = unsafe { clamped.to_int_unchecked() };
    (whole as u32).min(last)
}

/// The stretch of an object ray the march walks: its points `a` at the near depth and `b` at
/// the far depth in layer-image coordinates (column, row, inverse depth), between which the
/// image and the depth pyramid leave the parameters `range` (0 at a, 1 at b), and the depth
/// tests' absolute slack.
#[derive(Clone, Copy, Debug)]
struct Segment {
    a: Vec3,
    b: Vec3,
    range: Vec2,
    slack: f32,
}

impl Segment {
    /// The inverse depths [lower, upper] a layer must lie within to be hit while the march
    /// passes the parameters s_in to s_out. Monotone in both, so a window over a longer stretch
    /// holds the window of every part of it.
    #[inline(always)]
    fn depth_window(&self, s_in: f32, s_out: f32) -> Vec2 {
        let dw = self.b[2] - self.a[2];
        let w_in = self.a[2] + s_in * dw;
        let w_out = self.a[2] + s_out * dw;
        [
            w_out * (1.0 - DEPTH_TOLERANCE) - self.slack,
            w_in * (1.0 + DEPTH_TOLERANCE) + self.slack,
        ]
    }

    /// The layer pixel the march starts in.
    #[inline(always)]
    fn first_pixel(&self, frame: &FrameParams) -> [i32; 2] {
        let start = mix3(self.a, self.b, self.range[0]);
        [
            floor_clamped(start[0], frame.layer_width - 1) as i32,
            floor_clamped(start[1], frame.layer_height - 1) as i32,
        ]
    }
}

/// The ray's stretch between the near and far depth clipped to the layer image, and whether
/// anything is left of it (the ray is valid, travels towards the scene and crosses the image):
/// the first part of the segment a ray marches, without branches, so a group's rays get theirs
/// side by side in vector lanes.
#[inline(always)]
fn image_span(frame: &FrameParams, ray: &ObjectRay) -> (Segment, bool) {
    let a = project(frame, ray, frame.near_depth);
    let b = project(frame, ray, frame.far_depth);
    let lw = frame.layer_width as f32;
    let lh = frame.layer_height as f32;
    let mut range = clip_axis(a[0], b[0], lw, [0.0, 1.0]);
    range = clip_axis(a[1], b[1], lh, range);
    let slack = DEPTH_SLACK * (a[2].abs() + b[2].abs());
    let open = ray.valid & (ray.direction[2] > 0.0) & (range[0] < range[1]);
    (Segment { a, b, range, slack }, open)
}

/// One image axis of a march: the segment's coordinate at its near end, the inverse of its run
/// from near to far end (0 where the run is too short to cross a grid line before
/// `NO_CROSSING`), and the way it steps, +1 or -1. Grid line k is the edge between pixels k - 1
/// and k; every crossing is computed from its line alone, so the crossing of a line is the same
/// number at every pyramid level.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Axis {
    start: f32,
    inverse_run: f32,
    step: i32,
}

impl Axis {
    #[inline(always)]
    fn new(a: f32, b: f32) -> Axis {
        let run = b - a;
        let inverse_run = if run.abs() * NO_CROSSING > 1.0 {
            1.0 / run
        } else {
            0.0
        };
        Axis::with_inverse_run(a, b, inverse_run)
    }

    /// The axis from `a` to `b` whose inverse run [`Axis::new`] found already.
    #[inline(always)]
    fn with_inverse_run(a: f32, b: f32, inverse_run: f32) -> Axis {
        Axis {
            start: a,
            inverse_run,
            step: if b > a { 1 } else { -1 },
        }
    }

    /// The parameter where the segment crosses grid line `line`.
    #[inline(always)]
    fn crossing(self, line: i32) -> f32 {
        if self.inverse_run == 0.0 {
            return NO_CROSSING;
        }
        (line as f32 - self.start) * self.inverse_run
    }

    /// The grid line the march leaves the cell of `level` holding `pixel` through.
    #[inline(always)]
    fn line_ahead(self, pixel: i32, level: u32) -> i32 {
        let cell = pixel >> level;
        if self.step > 0 {
            (cell + 1) << level
        } else {
            cell << level
        }
    }

    /// The pixel the march enters by crossing `line`.
    #[inline(always)]
    fn pixel_past(self, line: i32) -> i32 {
        if self.step > 0 { line } else { line - 1 }
    }

    /// The pixel the march is in along this axis once it has crossed every grid line in the
    /// cell of `level` holding `pixel` that it crosses before parameter `until` (at `until`
    /// too where `inclusive`): a binary search (crossings grow along the step), at most `level`
    /// crossings.
    #[inline(always)]
    fn advance(self, pixel: i32, level: u32, until: f32, inclusive: bool) -> i32 {
        let first = (pixel >> level) << level;
        let last = first + (1 << level) - 1;
        let mut reached = pixel;
        for k in (0..level).rev() {
            let candidate = reached + (self.step << k);
            let line = if self.step > 0 {
                candidate
            } else {
                candidate + 1
            };
            let s = self.crossing(line);
            if candidate >= first && candidate <= last && (s < until || (inclusive && s == until)) {
                reached = candidate;
            }
        }
        reached
    }
}

/// One step of a march in the cell of `level` holding `pixel`, entered at parameter `s_in`:
/// the grid lines it leaves the cell through, the parameters where it crosses them, where it
/// leaves the cell or the segment ends, and the depth window of the stretch.
#[derive(Clone, Copy, Debug, PartialEq)]
struct CellExit {
    line: [i32; 2],
    next: Vec2,
    s_out: f32,
    window: Vec2,
}

impl CellExit {
    #[inline(always)]
    fn of(axes: [Axis; 2], segment: &Segment, pixel: [i32; 2], level: u32, s_in: f32) -> CellExit {
        let [x, y] = axes;
        let line = [x.line_ahead(pixel[0], level), y.line_ahead(pixel[1], level)];
        let next = [x.crossing(line[0]), y.crossing(line[1])];
        let s_out = next[0].min(next[1]).min(segment.range[1]);
        CellExit {
            line,
            next,
            s_out,
            window: segment.depth_window(s_in, s_out),
        }
    }
}

/// A march's first step: the segment's axes, its first pixel and the step out of that pixel.
/// Without branches, so a group's starts are found side by side in vector lanes
/// ([`MarchStarts`]): a march takes 1.6 steps on average (the demo scene at 64 spp through
/// dgauss-50mm), so its first step and the divisions before it are most of its work.
#[derive(Clone, Copy, Debug, PartialEq)]
struct MarchStart {
    axes: [Axis; 2],
    pixel: [i32; 2],
    exit: CellExit,
}

impl MarchStart {
    #[inline(always)]
    fn of(frame: &FrameParams, segment: &Segment) -> MarchStart {
        let axes = [
            Axis::new(segment.a[0], segment.b[0]),
            Axis::new(segment.a[1], segment.b[1]),
        ];
        let pixel = segment.first_pixel(frame);
        MarchStart {
            axes,
            pixel,
            exit: CellExit::of(axes, segment, pixel, 0, segment.range[0]),
        }
    }
}

/// The first layer the segment hits, as its index into `layers.surfels`, marching from `start`
/// (the segment's [`MarchStart`]).
///
/// A DDA over the cells of the depth pyramid. It starts at the segment's first pixel; in each
/// cell it forms the depth window of the stretch from where it is to where it leaves the cell,
/// and descends into the cell where the cell's depth bounds meet that window, else leaves it
/// in one step, climbing a level when that takes it into another parent cell. At the bottom it
/// tests the pixel's layers. A pixel-by-pixel DDA (`pixel_march` in the tests) takes the
/// smaller of the next column and next row crossing, a row on a tie; leaving a cell, this
/// march takes the crossing through its edge the same way, and puts itself on the other axis
/// where that DDA would be (`Axis::advance`), so it tests the same pixels in the same order
/// with the same windows, less those whose cell ruled a hit out, and returns the same layer.
#[inline(always)]
fn march(
    frame: &FrameParams,
    layers: &LayerData,
    segment: &Segment,
    start: MarchStart,
) -> Option<u32> {
    let [x, y] = start.axes;
    let last_column = frame.layer_width as i32 - 1;
    let last_row = frame.layer_height as i32 - 1;
    let mut pixel = start.pixel;
    let mut exit = start.exit;
    let mut s_in = segment.range[0];
    let mut level = 0;
    let mut level_offset = 0;
    let mut level_width = frame.layer_width;
    loop {
        let CellExit {
            line,
            next,
            s_out,
            window,
        } = exit;
        if level == 0 {
            let found = hit_in_pixel(
                layers,
                pixel[1] as u32 * frame.layer_width + pixel[0] as u32,
                window,
            );
            if found.is_some() {
                return found;
            }
        } else {
            let texel = level_offset
                + (pixel[1] >> level) as u32 * level_width
                + (pixel[0] >> level) as u32;
            let bounds = layers.depth_bounds[texel as usize];
            if bounds[0] <= window[1] && bounds[1] >= window[0] {
                level -= 1;
                let [w, h] = level_size(frame, level);
                level_offset -= w * h;
                level_width = w;
                exit = CellExit::of(start.axes, segment, pixel, level, s_in);
                continue;
            }
        }
        if s_out >= segment.range[1] {
            return None;
        }
        let before = pixel;
        if next[0] < next[1] {
            pixel = [
                x.pixel_past(line[0]),
                y.advance(pixel[1], level, next[0], true),
            ];
            s_in = next[0];
        } else {
            pixel = [
                x.advance(pixel[0], level, next[1], false),
                y.pixel_past(line[1]),
            ];
            s_in = next[1];
        }
        if pixel[0] < 0 || pixel[0] > last_column || pixel[1] < 0 || pixel[1] > last_row {
            return None;
        }
        let parent = level + 1;
        if parent < frame.pyramid_levels
            && (pixel[0] >> parent != before[0] >> parent
                || pixel[1] >> parent != before[1] >> parent)
        {
            let [w, h] = level_size(frame, level);
            level_offset += w * h;
            level = parent;
            level_width = level_size(frame, level)[0];
        }
        exit = CellExit::of(start.axes, segment, pixel, level, s_in);
    }
}

/// The per-pixel sample decorrelation: lens and pixel-jitter scrambles from the seed and the
/// pixel index, so every backend and lens model draws the same samples.
pub(crate) struct PixelScrambles {
    lens: [u32; 2],
    jitter: [u32; 2],
}

impl PixelScrambles {
    pub(crate) fn new(seed: u32, pixel: u32) -> PixelScrambles {
        let key = mix_bits(pixel ^ mix_bits(seed));
        PixelScrambles {
            lens: [mix_bits(key.wrapping_add(1)), mix_bits(key.wrapping_add(2))],
            jitter: [mix_bits(key.wrapping_add(3)), mix_bits(key.wrapping_add(4))],
        }
    }

    /// Sample `index` of `count`: (unit-square lens sample, jitter within the pixel).
    #[inline(always)]
    pub(crate) fn sample(&self, index: u32, count: u32) -> (Vec2, Vec2) {
        let lens_u = lattice_point(index, count, self.lens[0], self.lens[1]);
        let j = lattice_point(index, count, self.jitter[0], self.jitter[1]);
        (lens_u, [j[1], j[0]])
    }
}

/// How the CPU twin turns film-side rays into object rays.
#[derive(Clone, Copy, Debug)]
pub enum LensRays<'a> {
    /// The shader's `paraxial_lens_ray`, in f32.
    Paraxial,
    /// The exact f64 trace.
    Traced(&'a Tracer),
    /// The f64 table sampler on layer `layer`, through a stop of `stop_radius` mm.
    Baked {
        table: &'a LrtfTable,
        stop_radius: f64,
        layer: usize,
    },
    /// The shader's `seidel_lens_ray`, in f32.
    Seidel(SeidelParams),
}

impl LensRays<'_> {
    pub fn of(model: &LensModel) -> LensRays<'_> {
        match model {
            LensModel::Thin(_) | LensModel::Thick(_) => LensRays::Paraxial,
            LensModel::Traced(lens) => LensRays::Traced(&lens.tracer),
            LensModel::Baked(lens) => LensRays::Baked {
                table: &lens.table,
                stop_radius: lens.stop_radius,
                layer: lens.layer,
            },
            LensModel::Seidel(lens) => LensRays::Seidel(SeidelParams::of(lens)),
        }
    }

    /// The lens functions of `chromatic`'s channels, R, G, B, for a camera with `model`
    /// (paraxial channels read [`ChannelParams`] instead).
    pub fn channels<'a>(
        chromatic: &'a Chromatic,
        model: &'a LensModel,
    ) -> Result<[LensRays<'a>; CHANNELS], RenderError> {
        chromatic.check_matches(model)?;
        Ok(match (&chromatic.lenses, model) {
            (ChannelLenses::Traced(lenses), _) => {
                lenses.each_ref().map(|l| LensRays::Traced(&l.tracer))
            }
            (ChannelLenses::Baked(layers), LensModel::Baked(lens)) => {
                layers.map(|layer| LensRays::Baked {
                    table: &lens.table,
                    stop_radius: lens.stop_radius,
                    layer,
                })
            }
            _ => [LensRays::Paraxial; CHANNELS],
        })
    }
}

/// The object-space ray that leaves the lens from `origin` along the film-to-object
/// `direction` (f64, from the tracer or the table): light travels towards +z, against it.
fn leaving(origin: [f64; 3], direction: [f64; 3]) -> ObjectRay {
    ObjectRay {
        origin: origin.map(|v| v as f32),
        direction: direction.map(|v| -v as f32),
        valid: true,
    }
}

/// The object-space ray for the film-side ray from `film` through `pupil`; invalid when the lens
/// blocks it (vignetted, TIR, missed; or outside the table).
fn lens_ray(frame: &FrameParams, rays: LensRays, film: Vec3, pupil: Vec3) -> ObjectRay {
    let mut one = [blocked_ray()];
    let samples = SampleLanes::one(film, pupil);
    lens_rays(frame, rays, &samples, &mut LensScratch::new(), &mut one);
    one[0]
}

/// Samples that go through the lens together, a run's pixels one after the other (four pixels
/// to a group at 64 samples a pixel): the traced model runs them through the block kernels
/// ([`Tracer::trace_group`], the same bits as one ray at a time) instead of one scalar trace per
/// sample, in blocks as large as a batch's. A pixel's 64 samples alone in a group, the traced
/// frame was 11 % slower (200 x 150 at 64 samples, dgauss-50mm, one Zen 4 core: 0.128 against
/// 0.114 s), and at a few samples a pixel, as the viewer draws them, most lanes were empty (at 4
/// samples 7.5x slower). The structs that hold a group's columns are line-aligned
/// (`repr(align(64))`), as a trace block is, so that no placement splits a vector access of a
/// column across two cache lines.
const SAMPLE_GROUP: usize = GROUP_RAYS;

/// What [`lens_rays`] works in, kept by a thread from group to group and run to run: the
/// film-side rays' columns (a group's for the traced model, a lookup's share for the baked one),
/// the traced model's block and the baked model's lookup columns, which every group overwrites.
/// A fresh copy per group (then of a pixel's samples) was a clear of 10 KB, and a traced frame
/// ran 3 % slower.
#[repr(align(64))]
struct LensScratch {
    columns: [[f64; SAMPLE_GROUP]; 6],
    share: [[f64; LOOKUP_GROUP]; 6],
    block: GroupBlock,
    lookup: LookupScratch,
}

impl LensScratch {
    fn new() -> LensScratch {
        LensScratch {
            columns: [[0.0; SAMPLE_GROUP]; 6],
            share: [[0.0; LOOKUP_GROUP]; 6],
            block: GroupBlock::new(),
            lookup: LookupScratch::new(),
        }
    }
}

/// [`lens_ray`] for the first `out.len()` samples of `samples` (film point k through pupil
/// point k) into `out[k]`.
fn lens_rays(
    frame: &FrameParams,
    rays: LensRays,
    samples: &SampleLanes,
    scratch: &mut LensScratch,
    out: &mut [ObjectRay],
) {
    let LensScratch {
        columns,
        share,
        block,
        lookup,
    } = scratch;
    let count = out.len();
    match rays {
        LensRays::Paraxial => {
            for (k, o) in out.iter_mut().enumerate() {
                *o = paraxial_lens_ray(frame, samples.film(k), samples.pupil(k));
            }
        }
        LensRays::Seidel(seidel) => with_widest_isa(
            #[inline(always)]
            |_| seidel_lens_rays(frame, &seidel, samples, out),
        ),
        LensRays::Traced(tracer) => {
            // Rays that cannot be built (a zero direction) stay blocked and are not traced.
            let mut built = [false; SAMPLE_GROUP];
            with_widest_isa(
                #[inline(always)]
                |_| film_side_rays::<true, SAMPLE_GROUP>(samples, 0, columns, &mut built),
            );
            out.fill(blocked_ray());
            let chosen = &built[..count];
            tracer.trace_group(block, columns, chosen, Travel::Backward, |k, traced| {
                if traced.outcome.is_ok() {
                    out[k] = leaving(traced.ray.position(), traced.ray.direction());
                }
            });
        }
        LensRays::Baked {
            table,
            stop_radius,
            layer,
        } => {
            // A lookup takes fewer rays than a group holds: the group a lookup's share at a
            // time, each share's rays looked up together, so their table reads overlap (its
            // film-side rays built straight into the share's columns: built for the whole
            // group and copied a share at a time, the copies were 4 % of a baked frame). A ray
            // that cannot be built has no direction, which no table holds (it falls outside). A
            // lookup reads only the line of a ray, so the directions are not made unit.
            for first in (0..count).step_by(LOOKUP_GROUP) {
                with_widest_isa(
                    #[inline(always)]
                    |_| {
                        let unused = &mut [false; LOOKUP_GROUP];
                        film_side_rays::<false, LOOKUP_GROUP>(samples, first, share, unused)
                    },
                );
                let n = (count - first).min(LOOKUP_GROUP);
                table.lookup_columns(layer, share, n, stop_radius, lookup, |k, looked| {
                    out[first + k] = match looked {
                        Lookup::Passes(ray) => leaving(ray.origin, ray.direction),
                        Lookup::Blocked | Lookup::OutsideDomain => blocked_ray(),
                    };
                });
            }
        }
    }
}

/// The f64 film-side rays of lanes `first..first + N` of `samples` (from the film point towards
/// the pupil point, the direction made unit when `UNIT`) into `columns`, a column per coordinate
/// (x, y, z, dx, dy, dz), and whether each could be built into `built`: with `UNIT`, what
/// [`crate::trace::Ray::new`] makes of them, bit for bit, side by side in vector lanes. From f32
/// points a direction's squared length can neither overflow nor underflow f64, so `Ray::new`
/// divides by the length, as here; it refuses only non-finite values and a zero direction.
/// Written into the caller's columns: returned by value, they were copied once more.
#[inline(always)]
fn film_side_rays<const UNIT: bool, const N: usize>(
    samples: &SampleLanes,
    first: usize,
    columns: &mut [[f64; N]; 6],
    built: &mut [bool; N],
) {
    let [fx, fy, fz] = samples
        .film
        .each_ref()
        .map(|column| lanes::<N>(column, first));
    let [px, py, pz] = samples
        .pupil
        .each_ref()
        .map(|column| lanes::<N>(column, first));
    for k in 0..N {
        let position = [fx[k], fy[k], fz[k]].map(f64::from);
        let d = [px[k] - fx[k], py[k] - fy[k], pz[k] - fz[k]].map(f64::from);
        let length = crate::trace::dot(d, d).sqrt();
        let finite = position
            .iter()
            .chain(&d)
            .fold(true, |all, v| all & v.is_finite());
        built[k] = finite & (length > 0.0);
        for axis in 0..3 {
            columns[axis][k] = position[axis];
            columns[3 + axis][k] = if UNIT { d[axis] / length } else { d[axis] };
        }
    }
}

/// Lanes `first..first + N` of a group's column.
#[inline(always)]
fn lanes<const N: usize>(column: &[f32; SAMPLE_GROUP], first: usize) -> &[f32; N] {
    column[first..]
        .first_chunk::<N>()
        .expect("the lanes lie in the group")
}

/// The kernel's lens function alone: the object-space ray (a point on it, and the direction the
/// light travels, towards +z, not normalised) for the film-side ray from `film` through `pupil`,
/// or None where the model blocks it. The hook tests compare each model's port with its f64
/// statement through.
pub fn object_ray(
    frame: &FrameParams,
    rays: LensRays,
    film: [f32; 3],
    pupil: [f32; 3],
) -> Option<([f32; 3], [f32; 3])> {
    let ray = lens_ray(frame, rays, film, pupil);
    ray.valid.then_some((ray.origin, ray.direction))
}

/// The sampling pupil's circles of one dispatch (the shader's `lrtf_sampling_pupil_at` with
/// what does not depend on the film point worked out once): the rows of circles at the two
/// focus nodes around the render's focus, from block `block` of the pupil buffer on, and the
/// weight of the farther one.
struct SamplingCircles<'a> {
    near: &'a [Vec2],
    far: &'a [Vec2],
    focus_fraction: f32,
    /// The film radius of the last circle, and the intervals between circles: 1 and 0 with a
    /// single circle (or no film radius to spread over), which put every film radius on the
    /// first circle, as the shader's guard does.
    max_film_radius: f32,
    intervals: f32,
}

impl SamplingCircles<'_> {
    /// # Panics
    /// When `lens` holds no sampling circle (every model's [`LensData`] holds one at least).
    fn new(lens: &LensData, block: u32) -> SamplingCircles<'_> {
        let p = &lens.lrtf;
        let n = p.sampling_count;
        assert!(n > 0, "a sampling pupil has a circle");
        let (mut j, mut g) = (0, 0.0);
        if p.focus_count > 1 {
            let s = p.focus_coordinate.clamp(0.0, (p.focus_count - 1) as f32);
            j = floor_clamped(s, p.focus_count - 2);
            g = s - j as f32;
        }
        let j1 = (j + 1).min(p.focus_count - 1);
        let first = (block * p.pupil_count) as usize;
        let row = |node: u32| {
            let start = first + (node * n) as usize;
            &lens.pupil[start..start + n as usize]
        };
        let spread = n > 1 && p.sampling_max_film_radius > 0.0;
        SamplingCircles {
            near: row(j),
            far: row(j1),
            focus_fraction: g,
            max_film_radius: if spread {
                p.sampling_max_film_radius
            } else {
                1.0
            },
            intervals: if spread { (n - 1) as f32 } else { 0.0 },
        }
    }

    /// The circle (centre_x, radius) at `film_radius`: bilinear in film radius and focus.
    #[inline(always)]
    fn at(&self, film_radius: f32) -> Vec2 {
        let last = self.near.len() - 1;
        let t = (film_radius / self.max_film_radius).clamp(0.0, 1.0) * self.intervals;
        let i = floor_clamped(t, (last as u32).saturating_sub(1)) as usize;
        let f = t - i as f32;
        let (i0, i1) = (i.min(last), (i + 1).min(last));
        // SAFETY: both rows hold last + 1 circles (`new` cut them to the same length), and
        // i0, i1 <= last. Unchecked, so a group's lanes load them without a branch each.
        let corner = |row: &[Vec2], k: usize| unsafe { *row.get_unchecked(k) };
        let mix2 =
            |a: Vec2, b: Vec2, t: f32| [a[0] * (1.0 - t) + b[0] * t, a[1] * (1.0 - t) + b[1] * t];
        let near = mix2(corner(self.near, i0), corner(self.near, i1), f);
        let far = mix2(corner(self.far, i0), corner(self.far, i1), f);
        mix2(near, far, self.focus_fraction)
    }
}

/// A lens sample (the shader's `pupil_sample`): the point on the sampling plane for unit-square
/// sample `lens_u` from `film`, uniform over the film radius's circle of `circles` (widened
/// for a film point off the plane the circles were fitted on, see `model::OffPlaneBound`), and
/// its weight: the disc's area times cos(at the pupil) cos(at the sensor) / distance^2,
/// relative to the paraxial exit pupil seen from the film centre (cos^4 times the circle's
/// projected solid angle on an untilted film). Without branches, for the vector lanes of
/// [`sample_lanes`].
///
/// Only the circle's centre turns with the film point's azimuth; the disc sample itself does
/// not (the circle is symmetric), so neighbouring pixels on either side of the axis keep the
/// same stratification.
#[inline(always)]
fn pupil_sample(
    frame: &FrameParams,
    circles: &SamplingCircles,
    film: Vec3,
    lens_u: Vec2,
) -> (Vec3, f32) {
    let film_radius = (film[0] * film[0] + film[1] * film[1]).sqrt();
    let azimuth = if film_radius > 0.0 {
        [film[0] / film_radius, film[1] / film_radius]
    } else {
        [1.0, 0.0]
    };
    let circle = circles.at(film_radius);
    let centre = [azimuth[0] * circle[0], azimuth[1] * circle[0]];
    let growth = frame.pupil_lipschitz * (film[2] - frame.film_z).abs() / (film[2] - frame.pupil_z);
    let drift = ((centre[0] - film[0]) * (centre[0] - film[0])
        + (centre[1] - film[1]) * (centre[1] - film[1]))
        .sqrt();
    let widened = (circle[1] + growth * drift + frame.pupil_centre_slack) / (1.0 - growth);
    let radius = if film[2] != frame.film_z {
        widened
    } else {
        circle[1]
    };
    let disc = concentric_disc(lens_u);
    let pupil = [
        centre[0] + radius * disc[0],
        centre[1] + radius * disc[1],
        frame.pupil_z,
    ];
    let to_pupil = [pupil[0] - film[0], pupil[1] - film[1], pupil[2] - film[2]];
    let length =
        (to_pupil[0] * to_pupil[0] + to_pupil[1] * to_pupil[1] + to_pupil[2] * to_pupil[2]).sqrt();
    let cos_pupil = to_pupil[2].abs() / length;
    let cos_film = (to_pupil[0] * frame.film_normal_x
        + to_pupil[1] * frame.film_normal_y
        + to_pupil[2] * frame.film_normal_z)
        .abs()
        / length;
    let reach = (frame.film_z - frame.pupil_z) / length;
    (
        pupil,
        frame.pupil_weight * radius * radius * cos_pupil * cos_film * reach * reach,
    )
}

/// Sample `index` of output pixel (x, y): its film point (moved by the pixel's entry of
/// `film_shift` under a focal surface) and unit-square lens sample (the shader's
/// `pixel_sample`).
#[inline(always)]
fn pixel_sample(
    frame: &FrameParams,
    scrambles: &PixelScrambles,
    film_shift: &[[f32; 4]],
    x: u32,
    y: u32,
    index: u32,
) -> (Vec3, Vec2) {
    let (lens_u, jitter) = scrambles.sample(index, frame.samples_per_pixel);
    let film = film_point(frame, [x as f32 + jitter[0], y as f32 + jitter[1]]);
    let shift = pixel_film_shift(film_shift, y * frame.width + x);
    (
        [film[0] + shift[0], film[1] + shift[1], film[2] + shift[2]],
        lens_u,
    )
}

/// The shader's `pixel_film_shift`: output pixel `pixel`'s film shift, the last entry's past the
/// end (the GPU binds one zero entry when there is no focal surface; the CPU an empty slice).
#[inline(always)]
fn pixel_film_shift(film_shift: &[[f32; 4]], pixel: u32) -> [f32; 4] {
    match film_shift.len() {
        0 => [0.0; 4],
        n => film_shift[(pixel as usize).min(n - 1)],
    }
}

/// The shader's `film_point`: the film point at pixel coordinates `p` (pixel + jitter).
#[inline(always)]
fn film_point(frame: &FrameParams, p: Vec2) -> Vec3 {
    [
        frame.film_origin_x + p[0] * frame.film_step_x + p[1] * frame.film_step_y_x,
        frame.film_origin_y + p[0] * frame.film_step_x_y + p[1] * frame.film_step_y,
        frame.film_origin_z + p[0] * frame.film_step_x_z + p[1] * frame.film_step_y_z,
    ]
}

/// One group of samples: film points, pupil points and weights, a column per coordinate (so the
/// lanes' loop stores whole vectors).
#[repr(align(64))]
struct SampleLanes {
    film: [[f32; SAMPLE_GROUP]; 3],
    pupil: [[f32; SAMPLE_GROUP]; 3],
    weight: [f32; SAMPLE_GROUP],
}

impl SampleLanes {
    const EMPTY: SampleLanes = SampleLanes {
        film: [[0.0; SAMPLE_GROUP]; 3],
        pupil: [[0.0; SAMPLE_GROUP]; 3],
        weight: [0.0; SAMPLE_GROUP],
    };

    /// A group of one sample, in lane 0 (the other lanes hold zeros, never used).
    fn one(film: Vec3, pupil: Vec3) -> SampleLanes {
        let mut lanes = SampleLanes::EMPTY;
        for axis in 0..3 {
            lanes.film[axis][0] = film[axis];
            lanes.pupil[axis][0] = pupil[axis];
        }
        lanes
    }

    fn film(&self, k: usize) -> Vec3 {
        [0, 1, 2].map(|axis| self.film[axis][k])
    }

    fn pupil(&self, k: usize) -> Vec3 {
        [0, 1, 2].map(|axis| self.pupil[axis][k])
    }
}

/// Which sample of which pixel each lane of a group draws, a column per value: a run's pixels
/// one after the other, each pixel's samples in order, so that a group spans pixels when a
/// pixel has fewer samples than a group has lanes. A pixel's column, row and scrambles are
/// worked out once for the pixel and copied into its lanes, rather than found from its index in
/// every lane (a division and five hashes a sample).
#[repr(align(64))]
struct LaneDraws {
    /// The pixel's place in its run.
    slot: [u32; SAMPLE_GROUP],
    /// The pixel's column and row.
    pixel: [[u32; SAMPLE_GROUP]; 2],
    /// The sample's number among the pixel's samples of this dispatch.
    sample: [u32; SAMPLE_GROUP],
    /// The pixel's [`PixelScrambles`]: lens, then jitter.
    scrambles: [[u32; SAMPLE_GROUP]; 4],
}

impl LaneDraws {
    fn new() -> LaneDraws {
        LaneDraws {
            slot: [0; SAMPLE_GROUP],
            pixel: [[0; SAMPLE_GROUP]; 2],
            sample: [0; SAMPLE_GROUP],
            scrambles: [[0; SAMPLE_GROUP]; 4],
        }
    }

    /// Lanes `lanes` draw the samples numbered from `first` on of pixel `[x, y]`, the run's
    /// pixel `slot`.
    fn draw(
        &mut self,
        lanes: std::ops::Range<usize>,
        slot: u32,
        [x, y]: [u32; 2],
        first: u32,
        scrambles: &PixelScrambles,
    ) {
        let keys = [
            scrambles.lens[0],
            scrambles.lens[1],
            scrambles.jitter[0],
            scrambles.jitter[1],
        ];
        let start = lanes.start;
        for k in lanes {
            self.slot[k] = slot;
            self.pixel[0][k] = x;
            self.pixel[1][k] = y;
            self.sample[k] = first.wrapping_add((k - start) as u32);
            for (column, key) in self.scrambles.iter_mut().zip(keys) {
                column[k] = key;
            }
        }
    }
}

/// The samples `draws` names, all of them side by side (lanes past the group's last draw are
/// computed and not used): the loop has no branches and writes only its own columns, so
/// compiled for the widest instruction set it runs in vector lanes.
#[inline(always)]
fn sample_lanes(
    frame: &FrameParams,
    circles: &SamplingCircles,
    film_shift: &[[f32; 4]],
    draws: &LaneDraws,
) -> SampleLanes {
    let mut lanes = SampleLanes::EMPTY;
    for k in 0..SAMPLE_GROUP {
        let index = frame
            .sample_offset
            .wrapping_add(draws.sample[k].wrapping_mul(frame.sample_stride));
        let scrambles = PixelScrambles {
            lens: [draws.scrambles[0][k], draws.scrambles[1][k]],
            jitter: [draws.scrambles[2][k], draws.scrambles[3][k]],
        };
        let [x, y] = [draws.pixel[0][k], draws.pixel[1][k]];
        let (film, lens_u) = pixel_sample(frame, &scrambles, film_shift, x, y, index);
        let (pupil, weight) = pupil_sample(frame, circles, film, lens_u);
        for axis in 0..3 {
            lanes.film[axis][k] = film[axis];
            lanes.pupil[axis][k] = pupil[axis];
        }
        lanes.weight[k] = weight;
    }
    lanes
}

/// This dispatch's samples of the output pixels `pixels` (row-major indices), [`SAMPLE_GROUP`]
/// at a time, handed to `group` in order (pixel by pixel, each pixel's samples in order) with
/// each lane's pixel (its place in `pixels`) and the number of lanes that hold samples.
fn for_sample_groups(
    frame: &FrameParams,
    lens: &LensData,
    sampling_block: u32,
    pixels: &[u32],
    mut group: impl FnMut(&SampleLanes, &[u32; SAMPLE_GROUP], usize),
) {
    let circles = SamplingCircles::new(lens, sampling_block);
    let mut draws = LaneDraws::new();
    let mut drawn = |draws: &LaneDraws, count: usize| {
        let lanes = with_widest_isa(
            #[inline(always)]
            |_| sample_lanes(frame, &circles, &lens.film_shift, draws),
        );
        group(&lanes, &draws.slot, count);
    };
    let mut filled = 0;
    for (slot, &pixel) in (0u32..).zip(pixels) {
        let xy = [pixel % frame.width, pixel / frame.width];
        let scrambles = PixelScrambles::new(frame.seed, pixel);
        let mut first = 0;
        while first < frame.sample_count {
            let count = (frame.sample_count - first).min((SAMPLE_GROUP - filled) as u32);
            let lanes = filled..filled + count as usize;
            draws.draw(lanes.clone(), slot, xy, first, &scrambles);
            (filled, first) = (lanes.end, first + count);
            if filled == SAMPLE_GROUP {
                drawn(&draws, filled);
                filled = 0;
            }
        }
    }
    if filled > 0 {
        drawn(&draws, filled);
    }
}

/// Hands `add` each sample's lane, its weight and the colour its object ray meets in the layers,
/// in lane order (samples whose ray meets nothing are skipped). The rays' spans over the layer
/// image are set up side by side in vector lanes, then each is marched; all of it compiled for
/// the widest instruction set, which the march's scalar code gains from too (three-operand
/// forms, cheaper conversions).
fn march_group(
    frame: &FrameParams,
    layers: &LayerData,
    object: &[ObjectRay; SAMPLE_GROUP],
    count: usize,
    weight: &[f32],
    mut add: impl FnMut(usize, f32, Vec3),
) {
    with_widest_isa(
        #[inline(always)]
        |_| {
            let mut spans = ImageSpans::of(frame, object, count);
            spans.cut_to_footprints(frame, layers);
            let starts = MarchStarts::of(frame, &spans);
            for (k, &w) in weight.iter().enumerate().take(count) {
                let segment = spans.get(k);
                if spans.open[k]
                    && let Some(layer) = march(frame, layers, &segment, starts.get(k, &segment))
                {
                    add(k, w, layers.surfels[layer as usize].radiance);
                }
            }
        },
    );
}

/// A group's [`image_span`]s, a column per value.
#[repr(align(64))]
struct ImageSpans {
    ends: [[f32; SAMPLE_GROUP]; 6],
    range: [[f32; SAMPLE_GROUP]; 2],
    slack: [f32; SAMPLE_GROUP],
    open: [bool; SAMPLE_GROUP],
}

impl ImageSpans {
    /// The spans of the first `count` rays of `object`; the lanes past them are closed (what
    /// they hold is computed and not used: read in place, a group is not copied into a fresh
    /// array of blocked rays, which cost a fill and a copy of 1.8 KB per group).
    #[inline(always)]
    fn of(frame: &FrameParams, object: &[ObjectRay; SAMPLE_GROUP], count: usize) -> ImageSpans {
        let mut spans = ImageSpans {
            ends: [[0.0; SAMPLE_GROUP]; 6],
            range: [[0.0; SAMPLE_GROUP]; 2],
            slack: [0.0; SAMPLE_GROUP],
            open: [false; SAMPLE_GROUP],
        };
        for (k, ray) in object.iter().enumerate() {
            let (span, open) = image_span(frame, ray);
            for axis in 0..3 {
                spans.ends[axis][k] = span.a[axis];
                spans.ends[3 + axis][k] = span.b[axis];
            }
            spans.range[0][k] = span.range[0];
            spans.range[1][k] = span.range[1];
            spans.slack[k] = span.slack;
            spans.open[k] = open & (k < count);
        }
        spans
    }

    /// Every open span shrunk to the depths the pyramid holds under its footprint,
    /// `FOOTPRINT_CLAMP_ITERATIONS` times, and closed where nothing is left. The footprints'
    /// texels are found in vector lanes, read one ray at a time, and the cuts made in lanes
    /// again; a closed lane's numbers are computed and not used.
    #[inline(always)]
    fn cut_to_footprints(&mut self, frame: &FrameParams, layers: &LayerData) {
        let bounds = &layers.depth_bounds;
        let Some(last_texel) = bounds.len().checked_sub(1) else {
            self.open = [false; SAMPLE_GROUP];
            return;
        };
        let pyramid = PyramidLevels::of(frame);
        let mut texels = [[0; SAMPLE_GROUP]; 4];
        for _ in 0..FOOTPRINT_CLAMP_ITERATIONS {
            self.footprint_texels(frame, &pyramid, &mut texels);
            let mut lower = [0.0; SAMPLE_GROUP];
            let mut upper = [0.0; SAMPLE_GROUP];
            for k in 0..SAMPLE_GROUP {
                // Every texel is inside the pyramid; the bound keeps the reads free of checks.
                // Written out: through `array::map` the compiler kept a call per lane.
                let texel = |t: usize| bounds[(texels[t][k] as usize).min(last_texel)];
                let (a, b, c, d) = (texel(0), texel(1), texel(2), texel(3));
                lower[k] = a[0].min(b[0]).min(c[0].min(d[0]));
                upper[k] = a[1].max(b[1]).max(c[1].max(d[1]));
            }
            for k in 0..SAMPLE_GROUP {
                let (aw, dw) = (self.ends[2][k], self.ends[5][k] - self.ends[2][k]);
                let slack = self.slack[k];
                let enter = (upper[k] * (1.0 + DEPTH_TOLERANCE) + slack - aw) / dw;
                let leave = (lower[k] * (1.0 - DEPTH_TOLERANCE) - slack - aw) / dw;
                let range = [self.range[0][k].max(enter), self.range[1][k].min(leave)];
                // No layer under the footprint, or none within the span's depths.
                let empty = (lower[k] > upper[k]) | (range[0] > range[1]);
                self.range[0][k] = range[0];
                self.range[1][k] = range[1];
                self.open[k] &= !empty;
            }
        }
    }

    /// The four pyramid texels (indices into `depth_bounds`) at the corners of each span's
    /// footprint, the bounding box of its pixels from the range's start to its end, at the
    /// finest level where the box is at most two texels wide and high (or the top level).
    #[inline(always)]
    fn footprint_texels(
        &self,
        frame: &FrameParams,
        pyramid: &PyramidLevels,
        texels: &mut [[u32; SAMPLE_GROUP]; 4],
    ) {
        let last_column = frame.layer_width - 1;
        let last_row = frame.layer_height - 1;
        for k in 0..SAMPLE_GROUP {
            let Segment { a, b, range, .. } = self.get(k);
            let (p, q) = (mix3(a, b, range[0]), mix3(a, b, range[1]));
            let c = [
                floor_clamped(p[0].min(q[0]), last_column),
                floor_clamped(p[0].max(q[0]), last_column),
            ];
            let r = [
                floor_clamped(p[1].min(q[1]), last_row),
                floor_clamped(p[1].max(q[1]), last_row),
            ];
            let level = footprint_level(c, r, frame.pyramid_levels);
            let (offset, width) = pyramid.level(level);
            let corners = [[c[0], r[0]], [c[1], r[0]], [c[0], r[1]], [c[1], r[1]]];
            for (texel, [column, row]) in texels.iter_mut().zip(corners) {
                texel[k] = offset + (row >> level) * width + (column >> level);
            }
        }
    }

    #[inline(always)]
    fn get(&self, k: usize) -> Segment {
        Segment {
            a: [self.ends[0][k], self.ends[1][k], self.ends[2][k]],
            b: [self.ends[3][k], self.ends[4][k], self.ends[5][k]],
            range: [self.range[0][k], self.range[1][k]],
            slack: self.slack[k],
        }
    }
}

/// A group's [`MarchStart`]s, a column per value (a closed span's start is computed and not
/// used).
#[repr(align(64))]
struct MarchStarts {
    inverse_run: [[f32; SAMPLE_GROUP]; 2],
    pixel: [[i32; SAMPLE_GROUP]; 2],
    next: [[f32; SAMPLE_GROUP]; 2],
    s_out: [f32; SAMPLE_GROUP],
    window: [[f32; SAMPLE_GROUP]; 2],
}

impl MarchStarts {
    #[inline(always)]
    fn of(frame: &FrameParams, spans: &ImageSpans) -> MarchStarts {
        let mut starts = MarchStarts {
            inverse_run: [[0.0; SAMPLE_GROUP]; 2],
            pixel: [[0; SAMPLE_GROUP]; 2],
            next: [[0.0; SAMPLE_GROUP]; 2],
            s_out: [0.0; SAMPLE_GROUP],
            window: [[0.0; SAMPLE_GROUP]; 2],
        };
        for k in 0..SAMPLE_GROUP {
            let start = MarchStart::of(frame, &spans.get(k));
            for axis in 0..2 {
                starts.inverse_run[axis][k] = start.axes[axis].inverse_run;
                starts.pixel[axis][k] = start.pixel[axis];
                starts.next[axis][k] = start.exit.next[axis];
                starts.window[axis][k] = start.exit.window[axis];
            }
            starts.s_out[k] = start.exit.s_out;
        }
        starts
    }

    /// Lane `k`'s start, whose span is `segment`. The axes' starts and steps and the grid
    /// lines ahead are found again rather than stored: with all thirteen values in columns the
    /// traced frame was 3-6 % slower than marching without lanes (its lens kernels slowed),
    /// with these nine it is faster.
    #[inline(always)]
    fn get(&self, k: usize, segment: &Segment) -> MarchStart {
        let pair = |values: &[[f32; SAMPLE_GROUP]; 2]| [values[0][k], values[1][k]];
        let pixel = [self.pixel[0][k], self.pixel[1][k]];
        let axis =
            |a: usize| Axis::with_inverse_run(segment.a[a], segment.b[a], self.inverse_run[a][k]);
        let axes = [axis(0), axis(1)];
        MarchStart {
            axes,
            pixel,
            exit: CellExit {
                line: [
                    axes[0].line_ahead(pixel[0], 0),
                    axes[1].line_ahead(pixel[1], 0),
                ],
                next: pair(&self.next),
                s_out: self.s_out[k],
                window: pair(&self.window),
            },
        }
    }
}

/// Weighted radiance summed over this dispatch's samples into `sums[i]` for output pixel
/// `pixels[i]`: the body of the shader's `render` entry point (which takes a pixel's samples one
/// at a time; each pixel's sum is the same, added in the same order).
fn render_pixels(
    frame: &FrameParams,
    layers: &LayerData,
    lens: &LensData,
    rays: LensRays,
    scratch: &mut LensScratch,
    pixels: &[u32],
    sums: &mut [Vec3],
) {
    let mut object = [blocked_ray(); SAMPLE_GROUP];
    for_sample_groups(
        frame,
        lens,
        MONOCHROME_SAMPLING_BLOCK,
        pixels,
        |samples, slots, count| {
            lens_rays(frame, rays, samples, scratch, &mut object[..count]);
            march_group(
                frame,
                layers,
                &object,
                count,
                &samples.weight[..count],
                |k, w, colour| {
                    for (acc, c) in sums[slots[k] as usize].iter_mut().zip(colour) {
                        *acc += w * c;
                    }
                },
            );
        },
    );
}

/// The shader's `channel_lens_ray` for a group of samples: channel `channel`'s object rays in a
/// chromatic render.
fn channel_lens_rays(
    frame: &FrameParams,
    channels: &ChannelParams,
    channel: usize,
    rays: LensRays,
    samples: &SampleLanes,
    scratch: &mut LensScratch,
    out: &mut [ObjectRay],
) {
    match rays {
        LensRays::Paraxial => {
            for (k, o) in out.iter_mut().enumerate() {
                *o = channel_paraxial_ray(channels, channel, samples.film(k), samples.pupil(k));
            }
        }
        _ => lens_rays(frame, rays, samples, scratch, out),
    }
}

/// The body of the shader's `render_chromatic` for the output pixels `pixels` into `sums`: each
/// sample's film and pupil point traced once per colour channel through that channel's lens,
/// each channel keeping its own colour (each pixel's channel sums get their samples in the
/// shader's order).
#[allow(clippy::too_many_arguments)]
fn render_pixels_chromatic(
    frame: &FrameParams,
    layers: &LayerData,
    lens: &LensData,
    channels: &ChannelParams,
    rays: &[LensRays; CHANNELS],
    scratch: &mut LensScratch,
    pixels: &[u32],
    sums: &mut [Vec3],
) {
    let mut object = [blocked_ray(); SAMPLE_GROUP];
    for_sample_groups(
        frame,
        lens,
        channels.sampling_block,
        pixels,
        |samples, slots, count| {
            for (channel, channel_rays) in rays.iter().enumerate() {
                channel_lens_rays(
                    frame,
                    channels,
                    channel,
                    *channel_rays,
                    samples,
                    scratch,
                    &mut object[..count],
                );
                march_group(
                    frame,
                    layers,
                    &object,
                    count,
                    &samples.weight[..count],
                    |k, w, colour| {
                        sums[slots[k] as usize][channel] += w * colour[channel];
                    },
                );
            }
        },
    );
}

/// The order the CPU twin draws pixels in. Each pixel's sum is its own, so no value depends on
/// it; only which memory neighbouring pixels share does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum PixelOrder {
    /// Row by row: neighbouring pixels read neighbouring texels of the layer image.
    Rows,
    /// Ring by ring outwards from the lens axis ([`pixels_by_film_ring`]), for a baked lens.
    FilmRings,
}

impl PixelOrder {
    /// Rings where any lens is a table (whose first coordinate is the film radius), else rows.
    fn for_lenses(rays: &[LensRays]) -> PixelOrder {
        if rays.iter().any(|r| matches!(r, LensRays::Baked { .. })) {
            PixelOrder::FilmRings
        } else {
            PixelOrder::Rows
        }
    }
}

/// Rings of the film, over its largest pixel radius, that [`pixels_by_film_ring`] visits one
/// after the other: about a pixel wide on a small frame, about a node wide in a 128^3 table.
const FILM_RINGS: usize = 128;

/// The output pixels (row-major indices) ring by ring outwards from the lens axis, in rows
/// within a ring (a counting sort, so the order costs a pass over the pixels, not a sort). A
/// table's first coordinate is the film radius, so the pixels drawn one after the other read
/// a few slabs of it, which stay in the last-level cache; in rows, every row sweeps the whole
/// table, and one larger than that cache is read from memory row after row.
fn pixels_by_film_ring(frame: &FrameParams) -> Vec<u32> {
    let width = frame.width;
    let radius = |x: f32, y: f32| {
        let film = film_point(frame, [x, y]);
        (film[0] * film[0] + film[1] * film[1]).sqrt()
    };
    // The film point is affine in the pixel and its radius convex, so the largest radius is at
    // a corner pixel (a pixel a rounding beyond it falls in the last ring all the same).
    let [right, bottom] = [width - 1, frame.height - 1].map(|last| last as f32 + 0.5);
    let largest = [(0.5, 0.5), (right, 0.5), (0.5, bottom), (right, bottom)]
        .into_iter()
        .fold(0.0f32, |m, (x, y)| m.max(radius(x, y)));
    let rings_per_mm = if largest > 0.0 {
        FILM_RINGS as f32 / largest
    } else {
        0.0
    };
    let ring = |i: u32| {
        let r = radius((i % width) as f32 + 0.5, (i / width) as f32 + 0.5);
        floor_clamped(r * rings_per_mm, FILM_RINGS as u32 - 1) as usize
    };
    let count = width * frame.height;
    let mut next = [0usize; FILM_RINGS + 1];
    for i in 0..count {
        next[ring(i) + 1] += 1;
    }
    for k in 1..=FILM_RINGS {
        next[k] += next[k - 1];
    }
    let mut order = vec![0u32; count as usize];
    for i in 0..count {
        let slot = &mut next[ring(i)];
        order[*slot] = i;
        *slot += 1;
    }
    order
}

/// Output pixels rendered together, one after the other in the pixel order: a group of samples
/// spans pixels where a pixel has fewer samples than a group has lanes, so the lens kernels and
/// the march's lanes run on full groups but for a run's last. As many pixels as a group has
/// lanes, so that even one sample a pixel fills groups: with 64-pixel runs a frame of one
/// sample a pixel took 1.75x as long (4.9 against 2.8 ms, 200 x 150, dgauss-50mm, one core);
/// from 4 samples on the same.
const PIXEL_RUN: usize = SAMPLE_GROUP;

/// Adds what `pixels(run, sums)` sums for each run of output pixels (row-major indices) into
/// `radiance_sum` (one RGBA entry per output pixel, row-major), runs in parallel, the pixels in
/// `order`.
fn accumulate_pixels(
    frame: &FrameParams,
    order: PixelOrder,
    radiance_sum: &mut [[f32; 4]],
    pixels: impl Fn(&mut LensScratch, &[u32], &mut [Vec3]) + Sync,
) {
    let add = |out: &mut [f32; 4], s: Vec3| {
        out[0] += s[0];
        out[1] += s[1];
        out[2] += s[2];
    };
    let run_sums = |scratch: &mut LensScratch, run: &[u32]| {
        let mut sums = [[0.0; 3]; PIXEL_RUN];
        pixels(scratch, run, &mut sums[..run.len()]);
        sums
    };
    match order {
        PixelOrder::Rows => radiance_sum
            .par_chunks_mut(PIXEL_RUN)
            .enumerate()
            .for_each_init(LensScratch::new, |scratch, (run, out)| {
                let first = (run * PIXEL_RUN) as u32;
                let run: [u32; PIXEL_RUN] = std::array::from_fn(|k| first + k as u32);
                let sums = run_sums(scratch, &run[..out.len()]);
                for (out, s) in out.iter_mut().zip(sums) {
                    add(out, s);
                }
            }),
        PixelOrder::FilmRings => {
            let order = pixels_by_film_ring(frame);
            let sums: Vec<[Vec3; PIXEL_RUN]> = order
                .par_chunks(PIXEL_RUN)
                .map_init(LensScratch::new, run_sums)
                .collect();
            for (run, sums) in order.chunks(PIXEL_RUN).zip(&sums) {
                for (&i, s) in run.iter().zip(sums) {
                    add(&mut radiance_sum[i as usize], *s);
                }
            }
        }
    }
}

/// Adds this dispatch's weighted samples into `radiance_sum` (one RGBA entry per output pixel,
/// row-major), in parallel.
pub fn accumulate(
    frame: &FrameParams,
    layers: &LayerData,
    lens: &LensData,
    rays: LensRays,
    radiance_sum: &mut [[f32; 4]],
) {
    let order = PixelOrder::for_lenses(&[rays]);
    accumulate_pixels(frame, order, radiance_sum, |scratch, pixels, sums| {
        render_pixels(frame, layers, lens, rays, scratch, pixels, sums)
    });
}

/// [`accumulate`] for a chromatic render: `lens` and `channels` from [`LensData::chromatic`],
/// `rays` from [`LensRays::channels`].
pub fn accumulate_chromatic(
    frame: &FrameParams,
    layers: &LayerData,
    lens: &LensData,
    channels: &ChannelParams,
    rays: [LensRays; CHANNELS],
    radiance_sum: &mut [[f32; 4]],
) {
    let order = PixelOrder::for_lenses(&rays);
    accumulate_pixels(frame, order, radiance_sum, |scratch, pixels, sums| {
        render_pixels_chromatic(frame, layers, lens, channels, &rays, scratch, pixels, sums)
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::trace::Ray;

    /// The segment a ray marches and the march's start (None where nothing is left of the
    /// segment), as the renderer finds them in vector lanes; the start is checked against the
    /// one found alone.
    fn layer_segment(
        frame: &FrameParams,
        layers: &LayerData,
        ray: &ObjectRay,
    ) -> Option<(Segment, MarchStart)> {
        let mut group = [blocked_ray(); SAMPLE_GROUP];
        group[0] = *ray;
        let mut spans = ImageSpans::of(frame, &group, 1);
        spans.cut_to_footprints(frame, layers);
        let starts = MarchStarts::of(frame, &spans);
        spans.open[0].then(|| {
            let segment = spans.get(0);
            let start = starts.get(0, &segment);
            assert_eq!(start, MarchStart::of(frame, &segment), "{segment:?}");
            (segment, start)
        })
    }
    use crate::model::{ModelKind, ParaxialLens};
    use crate::render::camera::{Camera, Film, Focus};
    use crate::render::gpu_types::frame_params;
    use crate::render::layers::{LayeredDepthImage, Surfel, View};
    use crate::render::scene::Scene;
    use crate::render::{RenderSettings, layer_view};

    /// The march the hierarchical one must agree with: every pixel the segment crosses, one
    /// after the other, the smaller crossing first (a row on a tie), until the segment ends or
    /// leaves the image.
    fn pixel_march(frame: &FrameParams, layers: &LayerData, segment: &Segment) -> Option<u32> {
        let x = Axis::new(segment.a[0], segment.b[0]);
        let y = Axis::new(segment.a[1], segment.b[1]);
        let mut pixel = segment.first_pixel(frame);
        let mut s_in = segment.range[0];
        loop {
            let ahead = |axis: Axis, p: i32| axis.crossing(if axis.step > 0 { p + 1 } else { p });
            let next = [ahead(x, pixel[0]), ahead(y, pixel[1])];
            let s_out = next[0].min(next[1]).min(segment.range[1]);
            let index = pixel[1] as u32 * frame.layer_width + pixel[0] as u32;
            let found = hit_in_pixel(layers, index, segment.depth_window(s_in, s_out));
            if found.is_some() || s_out >= segment.range[1] {
                return found;
            }
            if next[0] < next[1] {
                pixel[0] += x.step;
                s_in = next[0];
            } else {
                pixel[1] += y.step;
                s_in = next[1];
            }
            if pixel[0] < 0
                || pixel[0] >= frame.layer_width as i32
                || pixel[1] < 0
                || pixel[1] >= frame.layer_height as i32
            {
                return None;
            }
        }
    }

    fn random_unit(key: u32) -> f32 {
        unit_from_bits(mix_bits(key))
    }

    fn thin_camera() -> Camera {
        let lens = ParaxialLens::thin(50.0, 2.0).unwrap();
        Camera::new(
            LensModel::Thin(lens),
            Film::full_frame_for(96, 64),
            Focus::ObjectDistance(2000.0),
        )
        .unwrap()
    }

    /// Object rays from a 50 mm wide pupil: half converge on random points at random depths
    /// inside and beyond the view (the defocused cones a lens sends out), half leave in random
    /// directions up to 80 degrees off axis.
    fn random_rays(eye_z: f32, tan_half: [f32; 2], count: u32) -> Vec<ObjectRay> {
        (0..count)
            .map(|i| {
                let u = |k: u32| random_unit(i.wrapping_mul(8).wrapping_add(k));
                let origin = [50.0 * u(0) - 25.0, 50.0 * u(1) - 25.0, eye_z];
                let direction = if i % 2 == 0 {
                    let depth = 100.0 * 1e4f32.powf(u(2));
                    let target = [
                        (2.6 * u(3) - 1.3) * tan_half[0] * depth,
                        (2.6 * u(4) - 1.3) * tan_half[1] * depth,
                    ];
                    [
                        (origin[0] - target[0]) / depth,
                        (origin[1] - target[1]) / depth,
                        1.0,
                    ]
                } else {
                    [11.4 * u(5) - 5.7, 11.4 * u(6) - 5.7, 1.0]
                };
                ObjectRay {
                    origin,
                    direction,
                    valid: true,
                }
            })
            .collect()
    }

    /// Runs both marches over `rays`; returns the hits per layer (index = layer) and the misses.
    fn compare_marches(layers: &LayerData, frame: &FrameParams, rays: &[ObjectRay]) -> Vec<u32> {
        let mut per_layer = vec![0; frame.layer_count as usize + 1];
        for (i, ray) in rays.iter().enumerate() {
            let Some((segment, start)) = layer_segment(frame, layers, ray) else {
                per_layer[frame.layer_count as usize] += 1;
                continue;
            };
            let found = march(frame, layers, &segment, start);
            assert_eq!(
                found,
                pixel_march(frame, layers, &segment),
                "ray {i}: {ray:?}"
            );
            match found {
                Some(index) => {
                    // The surfel's layer: how many of its pixel's surfels come before it.
                    let pixel = layers.starts.partition_point(|&start| start <= index) - 1;
                    per_layer[(index - layers.starts[pixel]) as usize] += 1
                }
                None => per_layer[frame.layer_count as usize] += 1,
            }
        }
        per_layer
    }

    /// The demo scene's layers (at most `max_layers`) and one-sample frame at `width` x
    /// `height` through the thin camera.
    fn demo_frame(width: u32, height: u32, max_layers: usize) -> (LayeredDepthImage, FrameParams) {
        let camera = thin_camera();
        let settings = RenderSettings {
            width,
            height,
            samples_per_pixel: 1,
            seed: 1,
            max_layers,
        };
        let scene = Scene::demo();
        let view = layer_view(&camera, &settings, scene.nearest_distance_mm().unwrap());
        let ldi = scene.peel(view, max_layers);
        let frame = frame_params(
            &camera,
            &LayerData::pack(&ldi).unwrap(),
            view.tan_half,
            width,
            height,
            1,
            1,
        );
        (ldi, frame)
    }

    #[test]
    fn hierarchical_march_finds_the_pixel_marchs_layer_on_the_demo_scene() {
        let (ldi, frame) = demo_frame(93, 61, 8);
        let layers = LayerData::pack(&ldi).unwrap();
        assert!(layers.pyramid_levels >= 7 && frame.layer_count >= 3);
        let tan_half = [frame.tan_half_x, frame.tan_half_y];
        let per_layer =
            compare_marches(&layers, &frame, &random_rays(frame.eye_z, tan_half, 40_000));
        // Hits on the nearest layer, on layers behind it and misses, so the comparison covers
        // both answers and occluded layers.
        let count = frame.layer_count as usize;
        let behind: u32 = per_layer[1..count].iter().sum();
        assert!(
            per_layer[0] > 5000 && behind > 200 && per_layer[count] > 5000,
            "{per_layer:?}"
        );
    }

    #[test]
    fn hierarchical_march_finds_the_pixel_marchs_layer_on_random_layers() {
        // Odd sizes (partial pyramid cells at the edges), up to six layers a pixel (two depth
        // groups), holes, and depths from 150 mm to 1 km in clumps, so windows and bounds
        // nearly touch.
        let camera = thin_camera();
        let (width, height) = (61, 37);
        let view = View {
            eye_z: camera.eye_z(),
            tan_half: [0.35, 0.21],
            width,
            height,
        };
        let lists = (0..width * height)
            .map(|p| {
                let u = |k: u32| random_unit(0x5eed_0000 ^ (p * 16 + k));
                let count = (u(0) * 7.0) as u32;
                (0..count)
                    .map(|k| Surfel {
                        depth_mm: 150.0
                            * 2f32.powi((u(1 + k) * 4.0) as i32 * 3)
                            * (1.0 + 0.01 * u(8 + k)),
                        radiance: [u(14), k as f32, 1.0],
                    })
                    .collect()
            })
            .collect();
        let ldi = LayeredDepthImage::from_pixel_lists(view, lists, 6);
        let layers = LayerData::pack(&ldi).unwrap();
        let frame = frame_params(&camera, &layers, view.tan_half, 96, 64, 1, 1);
        assert!(frame.layer_count == 6);
        let tan_half = [frame.tan_half_x, frame.tan_half_y];
        let per_layer =
            compare_marches(&layers, &frame, &random_rays(frame.eye_z, tan_half, 40_000));
        assert!(per_layer[..4].iter().all(|&n| n > 100), "{per_layer:?}");
        // Segments through grid corners (whole-pixel ends, runs in ratios 1:1, 1:2, 2:1, 0:1), where
        // column and row crossings tie and the tie rule decides which pixel comes next.
        let mut hits = 0;
        for i in 0..20_000u32 {
            let u = |k: u32| random_unit(0xc0de_0000 ^ (i * 8 + k));
            let a = [(u(0) * 61.0).floor(), (u(1) * 37.0).floor(), 1.0 / 140.0];
            let [rx, ry] = [[1.0, 1.0], [1.0, 2.0], [2.0, 1.0], [0.0, 1.0]][(u(2) * 4.0) as usize];
            let length = 1.0 + (u(3) * 40.0).floor();
            let sign = |k: u32| if u(k) < 0.5 { -1.0 } else { 1.0 };
            let b = [
                a[0] + sign(4) * rx * length,
                a[1] + sign(5) * ry * length,
                1.0 / 1.3e6,
            ];
            let mut range = clip_axis(a[0], b[0], 61.0, [0.0, 1.0]);
            range = clip_axis(a[1], b[1], 37.0, range);
            if range[0] >= range[1] {
                continue;
            }
            let slack = DEPTH_SLACK * (a[2] + b[2]);
            let segment = Segment { a, b, range, slack };
            let found = march(&frame, &layers, &segment, MarchStart::of(&frame, &segment));
            assert_eq!(found, pixel_march(&frame, &layers, &segment), "{segment:?}");
            hits += found.is_some() as u32;
        }
        assert!(hits > 5000, "{hits}");
    }

    #[test]
    fn film_rings_visit_every_pixel_once_outwards_in_rows() {
        let (_, frame) = demo_frame(57, 38, 2);
        let order = pixels_by_film_ring(&frame);
        let mut seen = vec![false; 57 * 38];
        for &i in &order {
            assert!(
                !std::mem::replace(&mut seen[i as usize], true),
                "pixel {i} twice"
            );
        }
        assert!(seen.iter().all(|&s| s), "a pixel left out");
        let radius = |i: u32| {
            let film = film_point(&frame, [(i % 57) as f32 + 0.5, (i / 57) as f32 + 0.5]);
            film[0].hypot(film[1])
        };
        let largest = (0..57 * 38).map(radius).fold(0.0f32, f32::max);
        let ring =
            |i: u32| ((radius(i) / largest * FILM_RINGS as f32) as usize).min(FILM_RINGS - 1);
        // Rings never step inwards (a ring's width of slack for the rounding of the radius), and
        // within a ring the pixels stay in row-major order.
        let mut rings_seen = 0;
        for pair in order.windows(2) {
            let (a, b) = (ring(pair[0]), ring(pair[1]));
            assert!(b + 1 >= a, "ring {a} then {b}");
            if a == b {
                assert!(
                    pair[1] > pair[0],
                    "pixels {pair:?} out of row order in ring {a}"
                );
            } else {
                rings_seen += 1;
            }
        }
        assert!(rings_seen > 20, "only {rings_seen} ring changes");
        assert_eq!(
            PixelOrder::for_lenses(&[LensRays::Paraxial]),
            PixelOrder::Rows
        );
    }

    #[test]
    fn lattice_points_are_one_per_shifted_stratum() {
        // x is i/N shifted modulo 1: sorted, consecutive points sit exactly 1/N apart, so each
        // of N equal strata (shifted with the points) holds one point.
        let n = 64;
        let mut xs: Vec<f32> = (0..n)
            .map(|i| lattice_point(i, n, 0x1234_5678, 99)[0])
            .collect();
        xs.sort_by(f32::total_cmp);
        assert!(xs.iter().all(|x| (0.0..1.0).contains(x)));
        for pair in xs.windows(2) {
            assert!(
                (pair[1] - pair[0] - 1.0 / n as f32).abs() < 1e-6,
                "{pair:?}"
            );
        }
        assert!((xs[0] + 1.0 - xs[n as usize - 1] - 1.0 / n as f32).abs() < 1e-6);
    }

    #[test]
    fn footprint_level_is_the_shaders_climb() {
        // The shader's `footprint_bounds` climbs while the box is wider than two texels.
        let climb = |c: [u32; 2], r: [u32; 2], levels: u32| {
            let mut level = 0;
            while level + 1 < levels
                && (((c[1] >> level) - (c[0] >> level)) > 1
                    || ((r[1] >> level) - (r[0] >> level)) > 1)
            {
                level += 1;
            }
            level
        };
        // Every box within 70 x 70 pixels (levels 0 to 6 and the caps below them), then boxes
        // anywhere in the largest image sides (up to 2^31 - 1, 32 levels).
        for levels in 1..=8 {
            for c0 in 0..70 {
                for c1 in c0..70 {
                    for (r0, r1) in [(0, 0), (3, 4), (5, 69), (31, 33), (c0, c1)] {
                        let (c, r) = ([c0, c1], [r0, r1]);
                        assert_eq!(footprint_level(c, r, levels), climb(c, r, levels));
                    }
                }
            }
        }
        for i in 0..100_000u32 {
            let bits =
                |k: u32| mix_bits(i.wrapping_mul(4).wrapping_add(k)) >> (mix_bits(k ^ i) % 32);
            let ([a, b], [d, e]) = ([bits(0), bits(1)], [bits(2), bits(3)]);
            let (c, r) = ([a.min(b), a.max(b)], [d.min(e), d.max(e)]);
            for levels in [1, 9, 15, 29, 32] {
                assert_eq!(
                    footprint_level(c, r, levels),
                    climb(c, r, levels),
                    "{c:?} {r:?}"
                );
            }
        }
    }

    #[test]
    fn floor_clamped_is_the_shaders_clamped_floor() {
        let specials = [
            0.0,
            -0.0,
            0.5,
            -0.5,
            -1.0,
            1.0 - f32::EPSILON / 2.0,
            -(1.0 - f32::EPSILON / 2.0),
            8_388_607.5,
            -8_388_607.5,
            8_388_608.0,
            4_294_967_296.0,
            1e30,
            -1e30,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        // Plus a sweep of every magnitude, both signs, with fractions, against limits from 0 on.
        let sweep = (0..4000).map(|k| (k as f32 * 0.37 - 700.0) * 1.013f32.powi(k % 97));
        for v in specials.into_iter().chain(sweep) {
            for last in [0u32, 1, 7, 199, 4095] {
                let as_u32 = v.floor().clamp(0.0, last as f32) as u32;
                let as_i32 = (v.floor() as i32).clamp(0, last as i32);
                assert_eq!(floor_clamped(v, last), as_u32, "{v} {last}");
                assert_eq!(floor_clamped(v, last) as i32, as_i32, "{v} {last}");
            }
        }
    }

    #[test]
    fn octant_sine_and_cosine_are_within_an_ulp_and_a_half() {
        let ulp = |v: f64| {
            let v = (v as f32).abs();
            (f32::from_bits(v.to_bits() + 1) - v) as f64
        };
        let steps = 100_000;
        for k in -steps..=steps {
            let x = QUARTER_PI * k as f32 / steps as f32;
            let (sin, cos) = sin_cos_octant(x);
            let exact = (x as f64).sin_cos();
            // Below the smallest normal the sine is x itself.
            assert!(
                (sin as f64 - exact.0).abs()
                    <= 1.5 * ulp(exact.0).max(f64::from(f32::MIN_POSITIVE)),
                "sin {x}: {sin} against {}",
                exact.0
            );
            assert!(
                (cos as f64 - exact.1).abs() <= 1.5 * ulp(exact.1),
                "cos {x}: {cos} against {}",
                exact.1
            );
        }
    }

    #[test]
    fn concentric_disc_is_the_polar_map_of_the_octants() {
        // Against the map written with libm's sine and cosine of the angle in each octant.
        let steps = 200;
        for i in 0..=steps {
            for j in 0..=steps {
                let u = [i as f32 / steps as f32, j as f32 / steps as f32];
                let a = [2.0 * u[0] as f64 - 1.0, 2.0 * u[1] as f64 - 1.0];
                let expected = if a == [0.0, 0.0] {
                    [0.0, 0.0]
                } else if a[0].abs() > a[1].abs() {
                    let phi = std::f64::consts::FRAC_PI_4 * a[1] / a[0];
                    [a[0] * phi.cos(), a[0] * phi.sin()]
                } else {
                    let phi =
                        std::f64::consts::FRAC_PI_2 - std::f64::consts::FRAC_PI_4 * a[0] / a[1];
                    [a[1] * phi.cos(), a[1] * phi.sin()]
                };
                let d = concentric_disc(u);
                for (got, want) in d.iter().zip(expected) {
                    assert!(
                        (*got as f64 - want).abs() < 3e-7,
                        "{u:?}: {d:?} against {expected:?}"
                    );
                }
            }
        }
    }

    /// The demo scene through dgauss-50mm's `kind` model, `width` x `height`, focused at 2 m,
    /// as a render job prepares it: the camera, the packed layers and the view's half-field
    /// tangents.
    fn dgauss_demo(kind: ModelKind, width: u32, height: u32) -> (Camera, LayeredDepthImage) {
        use crate::job::{BackendChoice, ModelChoice, RenderJob, RenderLens};
        let lens = crate::lenses::load("dgauss-50mm", &Default::default()).unwrap();
        let mut job = RenderJob::new(RenderLens::Real(Box::new(lens)));
        job.model = ModelChoice::Model(kind);
        job.backend = BackendChoice::Cpu;
        job.settings.width = width;
        job.settings.height = height;
        job.settings.max_layers = 4;
        let prepared = job.prepare(&|_| {}).unwrap();
        (prepared.camera, prepared.layers)
    }

    /// A pixel's sum is the same, bit for bit, whichever pixels share its groups of samples:
    /// the traced double Gauss's pixels rendered in one run against each in a run of its own,
    /// at sample counts that fill a group with many pixels, split a pixel across groups, or
    /// leave a run's last group part-full, in rows and in a shuffled order.
    #[test]
    fn a_pixels_sum_does_not_depend_on_the_pixels_sharing_its_groups() {
        let (camera, ldi) = dgauss_demo(ModelKind::Traced, 24, 16);
        let (layers, tan_half) = (LayerData::pack(&ldi).unwrap(), ldi.view.tan_half);
        let lens = LensData::of(&camera.model, super::super::gpu_types::TableTexels::Omitted);
        let rays = LensRays::of(&camera.model);
        let pixels: Vec<u32> = (0..24 * 16).collect();
        let shuffled: Vec<u32> = (0..24 * 16).map(|i| (i * 97) % (24 * 16)).collect();
        for samples in [1, 5, 64, 300] {
            let frame = FrameParams {
                sample_count: samples,
                ..frame_params(&camera, &layers, tan_half, 24, 16, samples, 7)
            };
            let mut scratch = LensScratch::new();
            let mut render = |run: &[u32], sums: &mut [Vec3]| {
                render_pixels(&frame, &layers, &lens, rays, &mut scratch, run, sums)
            };
            let mut alone = vec![[0.0; 3]; pixels.len()];
            for (&pixel, sum) in pixels.iter().zip(&mut alone) {
                render(&[pixel], std::slice::from_mut(sum));
            }
            assert!(
                alone.iter().any(|s| s[0] > 0.0),
                "{samples} samples: something is seen"
            );
            for order in [&pixels, &shuffled] {
                let mut together = vec![[0.0; 3]; order.len()];
                render(order, &mut together);
                for (&pixel, sum) in order.iter().zip(&together) {
                    let expected = alone[pixel as usize];
                    assert_eq!(
                        sum.map(f32::to_bits),
                        expected.map(f32::to_bits),
                        "{samples} samples, pixel {pixel}"
                    );
                }
            }
        }
    }

    /// The shader's `seidel_lens_ray` as it is written there, one sample at a time: what
    /// [`seidel_lens_rays`] must give in every lane.
    fn seidel_lens_ray(
        frame: &FrameParams,
        s: &SeidelParams,
        film: Vec3,
        pupil: Vec3,
    ) -> ObjectRay {
        let d = [pupil[0] - film[0], pupil[1] - film[1], pupil[2] - film[2]];
        let t_exit = (s.exit_pupil_z - film[2]) / d[2];
        let exit = [film[0] + t_exit * d[0], film[1] + t_exit * d[1]];
        let t_image = (s.image_z - film[2]) / d[2];
        let landing = [film[0] + t_image * d[0], film[1] + t_image * d[1]];
        let p = [
            exit[0] * s.inverse_marginal_height,
            exit[1] * s.inverse_marginal_height,
        ];
        let mut g = landing;
        let mut step = 0.0f32;
        for _ in 0..SEIDEL_INVERSE_STEPS {
            let eps = seidel_aberration(s, g, p);
            let next = [landing[0] - eps[0], landing[1] - eps[1]];
            let moved = [next[0] - g[0], next[1] - g[1]];
            step = (moved[0] * moved[0] + moved[1] * moved[1]).sqrt();
            g = next;
            if step <= SEIDEL_CONVERGED_MM as f32 {
                break;
            }
        }
        // Written so that NaN fails the test too.
        if step <= SEIDEL_SETTLED_MM as f32 {
            return paraxial_lens_ray(
                frame,
                [g[0], g[1], s.image_z],
                [exit[0], exit[1], s.exit_pupil_z],
            );
        }
        blocked_ray()
    }

    /// The Seidel model's rays in vector lanes are the shader's one-sample loop's, bit for bit,
    /// compiled for the baseline and the widest instruction set, for full and part-full groups:
    /// film points over a full frame through pupil points far outside the pupil, on the lens's
    /// sums and on aberrations 30 times as strong, so lanes stop at different steps and some
    /// never settle; and a lane with a NaN film point and one whose ray never leaves the film
    /// plane.
    #[test]
    fn seidel_rays_in_lanes_are_the_one_sample_loops_bit_for_bit() {
        let (camera, ldi) = dgauss_demo(ModelKind::Seidel, 96, 64);
        let (layers, tan_half) = (LayerData::pack(&ldi).unwrap(), ldi.view.tan_half);
        let LensRays::Seidel(params) = LensRays::of(&camera.model) else {
            panic!("a Seidel camera has Seidel rays");
        };
        let frame = frame_params(&camera, &layers, tan_half, 96, 64, 1, 1);
        let mut samples = SampleLanes::EMPTY;
        for k in 0..SAMPLE_GROUP {
            let u = |a: f32| (a * k as f32).fract() - 0.5;
            let film = [36.0 * u(0.618_034), 24.0 * u(0.381_966), frame.film_z];
            let pupil = [120.0 * u(0.414_214), 120.0 * u(0.732_051), frame.pupil_z];
            for axis in 0..3 {
                samples.film[axis][k] = film[axis];
                samples.pupil[axis][k] = pupil[axis];
            }
        }
        samples.film[0][5] = f32::NAN;
        samples.pupil[2][6] = samples.film[2][6];
        let same = |a: &ObjectRay, b: &ObjectRay| {
            a.valid == b.valid
                && a.origin
                    .iter()
                    .chain(&a.direction)
                    .map(|v| v.to_bits())
                    .eq(b.origin.iter().chain(&b.direction).map(|v| v.to_bits()))
        };
        let mut outcomes = [0; 2];
        // The lens's own sums, and the same aberrations 30 times as strong, whose fixed points
        // take many steps or never settle.
        for scale in [1.0, 30.0] {
            let params = SeidelParams {
                spherical: params.spherical * scale,
                coma: params.coma * scale,
                sagittal: params.sagittal * scale,
                tangential: params.tangential * scale,
                distortion: params.distortion * scale,
                ..params
            };
            for count in [1, 7, 100, SAMPLE_GROUP] {
                let expected: Vec<ObjectRay> = (0..count)
                    .map(|k| seidel_lens_ray(&frame, &params, samples.film(k), samples.pupil(k)))
                    .collect();
                let mut lanes = vec![blocked_ray(); count];
                seidel_lens_rays(&frame, &params, &samples, &mut lanes);
                let mut widest = vec![blocked_ray(); count];
                with_widest_isa(
                    #[inline(always)]
                    |_| seidel_lens_rays(&frame, &params, &samples, &mut widest),
                );
                for k in 0..count {
                    let lane = format!("x{scale}, {count} lanes, lane {k}");
                    assert!(same(&lanes[k], &expected[k]), "{lane}");
                    assert!(same(&widest[k], &expected[k]), "{lane}, widest");
                    outcomes[usize::from(expected[k].valid)] += 1;
                }
            }
        }
        // Both answers: rays that settle and rays blocked.
        assert!(outcomes[0] > 20 && outcomes[1] > 100, "{outcomes:?}");
    }

    #[test]
    fn concentric_disc_preserves_area_fraction() {
        // The map is area-preserving: the inner square of half side 0.5 (a quarter of the area)
        // lands inside radius 0.5 (a quarter of the disc).
        for &(u, expect) in &[([0.75, 0.5], 0.5), ([1.0, 1.0], 1.0), ([0.5, 0.5], 0.0)] {
            let d = concentric_disc(u);
            let r = (d[0] * d[0] + d[1] * d[1]).sqrt();
            assert!((r - expect).abs() < 1e-6, "{u:?} -> {d:?}");
        }
    }

    /// The traced model's film-side rays are the rays `Ray::new` makes of the same f32 points,
    /// bit for bit, and a lane is built exactly where `Ray::new` succeeds: in ordinary lanes and
    /// in lanes with a zero direction, a non-finite point, a difference that overflows f32 and
    /// one that is subnormal. Compiled both for the baseline and the widest instruction set.
    #[test]
    fn film_side_rays_are_what_ray_new_makes_bit_for_bit() {
        let mut samples = SampleLanes::EMPTY;
        let mut set = |k: usize, film: Vec3, pupil: Vec3| {
            for axis in 0..3 {
                samples.film[axis][k] = film[axis];
                samples.pupil[axis][k] = pupil[axis];
            }
        };
        for k in 0..SAMPLE_GROUP {
            let u = |a: f32| (a * k as f32).fract() - 0.5;
            let film = [36.0 * u(0.618_034), 24.0 * u(0.381_966), 69.4];
            let pupil = [20.0 * u(0.414_214), 20.0 * u(0.732_051), 40.0 + u(0.5)];
            set(k, film, pupil);
        }
        set(0, [1.0, 2.0, 3.0], [1.0, 2.0, 3.0]);
        set(1, [f32::INFINITY, 0.0, 69.0], [0.0, 0.0, 40.0]);
        set(2, [f32::MAX, 0.0, 69.0], [-f32::MAX, 0.0, 40.0]);
        set(3, [0.0, 0.0, 1e-39], [0.0, 0.0, 0.0]);
        let check = |columns: &[[f64; SAMPLE_GROUP]; 6], built: &[bool; SAMPLE_GROUP]| {
            for k in 0..SAMPLE_GROUP {
                let (film, pupil) = (samples.film(k), samples.pupil(k));
                let position = film.map(f64::from);
                let direction = [0, 1, 2].map(|axis| f64::from(pupil[axis] - film[axis]));
                match Ray::new(position, direction) {
                    Ok(ray) => {
                        assert!(built[k], "lane {k} not built");
                        let made = ray.position().into_iter().chain(ray.direction());
                        for (axis, value) in made.enumerate() {
                            let lane = columns[axis][k];
                            assert_eq!(lane.to_bits(), value.to_bits(), "lane {k}, column {axis}");
                        }
                    }
                    Err(_) => assert!(!built[k], "lane {k} built"),
                }
            }
        };
        let (mut columns, mut built) = ([[0.0; SAMPLE_GROUP]; 6], [false; SAMPLE_GROUP]);
        film_side_rays::<true, SAMPLE_GROUP>(&samples, 0, &mut columns, &mut built);
        check(&columns, &built);
        let (mut columns, mut built) = ([[0.0; SAMPLE_GROUP]; 6], [false; SAMPLE_GROUP]);
        with_widest_isa(
            #[inline(always)]
            |_| film_side_rays::<true, SAMPLE_GROUP>(&samples, 0, &mut columns, &mut built),
        );
        check(&columns, &built);
        assert_eq!(built.iter().filter(|&&b| !b).count(), 3, "lanes 0, 1 and 2");
        // A lookup's share of the lanes, as the baked model builds them (directions not made
        // unit), holds the same rays as those lanes of the whole group.
        let (mut whole, mut whole_built) = ([[0.0; SAMPLE_GROUP]; 6], [false; SAMPLE_GROUP]);
        film_side_rays::<false, SAMPLE_GROUP>(&samples, 0, &mut whole, &mut whole_built);
        for first in (0..SAMPLE_GROUP).step_by(LOOKUP_GROUP) {
            let (mut share, mut built) = ([[0.0; LOOKUP_GROUP]; 6], [false; LOOKUP_GROUP]);
            film_side_rays::<false, LOOKUP_GROUP>(&samples, first, &mut share, &mut built);
            for k in 0..LOOKUP_GROUP {
                assert_eq!(built[k], whole_built[first + k], "lane {}", first + k);
                for axis in 0..6 {
                    let (lane, expected) = (share[axis][k], whole[axis][first + k]);
                    assert_eq!(lane.to_bits(), expected.to_bits(), "lane {}", first + k);
                }
            }
        }
    }
}
