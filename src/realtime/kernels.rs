//! Lens kernels: the lens's real defocus spot for a few depths x field radii, traced forward from
//! point emitters through the exact lens (seed 000 section 3.3.2, realised).
//!
//! A kernel says how much of one pinhole pixel's radiance lands on the output pixel at each
//! offset from where the pinhole sees it. Offsets are in pinhole pixels (the layer view's
//! tangent pitch), measured with the same paraxial chief-ray map that places output pixels in
//! the pinhole image, so the real lens's distortion shows as the kernel's centroid. Values carry
//! the renderer's radiometry: an output pixel is irradiance relative to the paraxial exit pupil
//! seen from the film centre (as the image-based ray tracer's sample weights), so a kernel's sum
//! is the relative illumination of its field and depth, vignetting included.
//!
//! Kernels are stored for emitters on the +x axis of the field and turned per pixel to its
//! azimuth (a rotationally symmetric lens and an untilted film).

use crate::model::TracedLens;
use crate::render::RenderError;
use crate::render::camera::Camera;
use crate::render::layers::View;
use crate::trace::{Ray, Travel};
use rayon::prelude::*;

/// How finely the kernel set samples the lens.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KernelSettings {
    /// Depth nodes, spaced evenly in inverse depth (a defocus spot grows linearly in it).
    pub depth_nodes: usize,
    /// Field nodes, spaced evenly in chief-ray tangent from the axis to the view's corner.
    pub field_nodes: usize,
    /// Rays per side of the square grid of emitter rays over the lens's entrance side.
    pub rays_per_side: usize,
    /// Values per side of each kernel's grid.
    pub grid_side: usize,
}

impl Default for KernelSettings {
    fn default() -> KernelSettings {
        KernelSettings {
            depth_nodes: 24,
            field_nodes: 8,
            rays_per_side: 128,
            grid_side: 40,
        }
    }
}

/// One traced spot: the emitter's light per output-pixel-sized box around each grid node.
#[derive(Clone, Debug, PartialEq)]
pub struct Kernel {
    /// Offset (pinhole pixels, +x away from the axis, +y up) of grid node (0, 0) from the
    /// emitter's pinhole position.
    pub origin: [f64; 2],
    /// Distance between grid nodes (pinhole pixels).
    pub spacing: f64,
    pub side: usize,
    /// Row-major (y, then x): the emitter's relative irradiance summed over the output pixel
    /// centred on each node.
    pub values: Vec<f32>,
    /// Sum of the spot (the relative illumination it carries).
    pub flux: f64,
    /// Flux-weighted mean offset of the spot from the emitter's pinhole position.
    pub centroid: [f64; 2],
    /// RMS distance of the spot's rays from its centroid (pinhole pixels, pixel box excluded).
    pub rms_radius: f64,
    /// Farthest offset from the emitter's pinhole position at which the kernel is non-zero.
    pub support: f64,
}

impl Kernel {
    fn empty() -> Kernel {
        Kernel {
            origin: [0.0; 2],
            spacing: 1.0,
            side: 0,
            values: Vec::new(),
            flux: 0.0,
            centroid: [0.0; 2],
            rms_radius: 0.0,
            support: 0.0,
        }
    }

    /// The kernel's value at `offset` (pinhole pixels, kernel frame), bilinear between nodes.
    pub fn at(&self, offset: [f64; 2]) -> f64 {
        self.at_node([
            (offset[0] - self.origin[0]) / self.spacing,
            (offset[1] - self.origin[1]) / self.spacing,
        ])
    }

    /// The kernel's value at grid coordinates `node` (node (0, 0) at 0), bilinear.
    pub fn at_node(&self, node: [f64; 2]) -> f64 {
        let [gx, gy] = node;
        let last = self.side as f64 - 1.0;
        if !(gx >= 0.0 && gy >= 0.0 && gx < last && gy < last) {
            return 0.0;
        }
        let (ix, iy) = (gx as usize, gy as usize);
        let (fx, fy) = (gx - ix as f64, gy - iy as f64);
        let row = iy * self.side + ix;
        let v = &self.values;
        let top = v[row] as f64 * (1.0 - fx) + v[row + 1] as f64 * fx;
        let bottom = v[row + self.side] as f64 * (1.0 - fx) + v[row + self.side + 1] as f64 * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// Radius about the centroid (pinhole pixels) holding `share` of the kernel's values: a
    /// spot's faint outer rays (a halo of spherical aberration) reach far beyond its core.
    pub fn radius_holding(&self, share: f64) -> f64 {
        let mut rings: Vec<(f64, f64)> = self
            .values
            .iter()
            .enumerate()
            .map(|(i, &v)| {
                let x = self.origin[0] + (i % self.side) as f64 * self.spacing - self.centroid[0];
                let y = self.origin[1] + (i / self.side) as f64 * self.spacing - self.centroid[1];
                (x.hypot(y), v as f64)
            })
            .collect();
        rings.sort_by(|a, b| a.0.total_cmp(&b.0));
        let total: f64 = rings.iter().map(|r| r.1).sum();
        let mut held = 0.0;
        for (radius, value) in rings {
            held += value;
            if held >= share * total {
                return radius;
            }
        }
        0.0
    }

    /// Spread of the spot with the output pixel's own box added (a pixel-sized spot's RMS
    /// radius is sqrt(1/6)); interpolation scales kernels by it, so it never reaches zero.
    pub fn size(&self) -> f64 {
        (self.rms_radius * self.rms_radius + 1.0 / 6.0).sqrt()
    }
}

/// A lens's kernel set for one camera: `depth_nodes x field_nodes` traced spots.
#[derive(Clone, Debug, PartialEq)]
pub struct LensKernels {
    /// Inverse depths (1/mm from the eye) of the depth nodes, ascending.
    pub inverse_depths: Vec<f64>,
    /// Chief-ray tangents of the field nodes, from 0 ascending.
    pub field_tangents: Vec<f64>,
    /// Tangent per pinhole pixel: the unit of every offset.
    pub pixel_tangent: f64,
    /// Depth-major: kernel (depth i, field j) at `i * field_nodes + j`.
    pub kernels: Vec<Kernel>,
}

/// A kernel fitted to one pinhole pixel: the nearest node's shape, moved, scaled and weighted
/// to the pixel's interpolated centroid, size and flux, turned to its azimuth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelSpread {
    pub node: u32,
    /// The pixel's azimuth (cosine, sine): offsets turn by its inverse into the kernel frame.
    pub azimuth: [f32; 2],
    /// The pixel's interpolated centroid and the node's, kernel frame.
    pub centroid: [f32; 2],
    pub node_centroid: [f32; 2],
    /// The node's size and the pixel's interpolated one (RMS radius with the pixel box).
    pub node_size: f32,
    pub size: f32,
    /// Interpolated flux (the relative illumination of this pixel's spot) over the node's.
    pub flux_ratio: f32,
    /// The interpolated flux.
    pub flux: f32,
    /// Farthest reach of the spot from the pixel (pinhole pixels).
    pub support: f32,
}

impl LensKernels {
    /// Traces the kernel set of `camera` (whose model must be [`crate::model::LensModel::Traced`]
    /// on an untilted film) for pinhole pixels of `view` at depths from the eye in
    /// `depth_range_mm` (near, far).
    pub fn trace(
        camera: &Camera,
        view: &View,
        depth_range_mm: [f64; 2],
        settings: &KernelSettings,
    ) -> Result<LensKernels, RenderError> {
        let crate::model::LensModel::Traced(lens) = &camera.model else {
            return Err(RenderError::InvalidSetting(format!(
                "lens kernels are traced through the exact lens; the camera holds the {} model",
                camera.model.name()
            )));
        };
        if camera.film_off_plane() != 0.0 {
            return Err(RenderError::InvalidSetting(
                "lens kernels assume a film square to the axis; the sensor is tilted".into(),
            ));
        }
        let [near, far] = depth_range_mm;
        if !(near > 0.0 && far >= near && far.is_finite()) {
            return Err(RenderError::InvalidSetting(format!(
                "lens kernels need a depth range 0 < near <= far, got {near} .. {far} mm"
            )));
        }
        if settings.depth_nodes < 2 || settings.field_nodes < 2 || settings.grid_side < 4 {
            return Err(RenderError::InvalidSetting(
                "lens kernels need at least 2 depth and 2 field nodes and a 4-node grid".into(),
            ));
        }
        let pitch = [
            2.0 * view.tan_half[0] / view.width as f64,
            2.0 * view.tan_half[1] / view.height as f64,
        ];
        let pixel_tangent = pitch[0];
        let span = |lo: f64, hi: f64, n: usize| -> Vec<f64> {
            (0..n)
                .map(|i| lo + (hi - lo) * i as f64 / (n - 1) as f64)
                .collect()
        };
        // A hair beyond the range, so that rounding never puts a pixel outside the nodes.
        let inverse_depths = span(0.999 / far, 1.001 / near, settings.depth_nodes);
        let field_tangents = span(
            0.0,
            view.tan_half[0].hypot(view.tan_half[1]),
            settings.field_nodes,
        );
        let geometry = SpotGeometry::of(camera, lens, pixel_tangent)?;
        let nodes: Vec<(f64, f64)> = inverse_depths
            .iter()
            .flat_map(|&z| field_tangents.iter().map(move |&t| (1.0 / z, t)))
            .collect();
        let kernels = nodes
            .par_iter()
            .map(|&(depth, tangent)| geometry.spot(lens, depth, tangent, settings))
            .collect();
        Ok(LensKernels {
            inverse_depths,
            field_tangents,
            pixel_tangent,
            kernels,
        })
    }

    /// The kernel of depth node `i` and field node `j`.
    pub fn kernel(&self, i: usize, j: usize) -> &Kernel {
        &self.kernels[i * self.field_tangents.len() + j]
    }

    /// The spread of a pinhole pixel at `depth_mm` from the eye, seen at tangents `tan`.
    pub fn spread(&self, depth_mm: f64, tan: [f64; 2]) -> PixelSpread {
        let field = tan[0].hypot(tan[1]);
        let azimuth = if field > 0.0 {
            [tan[0] / field, tan[1] / field]
        } else {
            [1.0, 0.0]
        };
        let (i, fi) = bracket(&self.inverse_depths, 1.0 / depth_mm);
        let (j, fj) = bracket(&self.field_tangents, field);
        let corners = [
            (i, j, (1.0 - fi) * (1.0 - fj)),
            (i + 1, j, fi * (1.0 - fj)),
            (i, j + 1, (1.0 - fi) * fj),
            (i + 1, j + 1, fi * fj),
        ];
        let mut centroid = [0.0; 2];
        let (mut size, mut flux, mut support) = (0.0, 0.0, 0.0f64);
        for &(a, b, w) in &corners {
            let k = self.kernel(a, b);
            centroid[0] += w * k.centroid[0];
            centroid[1] += w * k.centroid[1];
            size += w * k.size();
            flux += w * k.flux;
            support = support.max(k.support);
        }
        let (ni, nj) = (i + (fi > 0.5) as usize, j + (fj > 0.5) as usize);
        let nearest = self.kernel(ni, nj);
        let flux_ratio = if nearest.flux > 0.0 {
            flux / nearest.flux
        } else {
            0.0
        };
        PixelSpread {
            node: (ni * self.field_tangents.len() + nj) as u32,
            azimuth: azimuth.map(|a| a as f32),
            centroid: centroid.map(|c| c as f32),
            node_centroid: nearest.centroid.map(|c| c as f32),
            node_size: nearest.size() as f32,
            size: size as f32,
            flux_ratio: flux_ratio as f32,
            flux: flux as f32,
            support: support as f32,
        }
    }

    /// The share of a pinhole pixel with spread `spread` that lands on the output pixel at
    /// `offset` from it (pinhole pixels, +x along +x tangent, +y along +y tangent), the spot
    /// widened to stand for a patch of `area` pinhole pixels (a sparse gather's tap: a spot
    /// narrower than the taps' spacing would be missed or counted many times).
    pub fn weight(&self, spread: &PixelSpread, offset: [f32; 2], area: f32) -> f32 {
        let widened = (spread.size * spread.size + (area - 1.0).max(0.0) / 6.0).sqrt();
        let scale = spread.node_size / widened;
        let [c, s] = spread.azimuth;
        let along = c * offset[0] + s * offset[1];
        let across = c * offset[1] - s * offset[0];
        let node = [
            spread.node_centroid[0] + (along - spread.centroid[0]) * scale,
            spread.node_centroid[1] + (across - spread.centroid[1]) * scale,
        ];
        let kernel = &self.kernels[spread.node as usize];
        scale * scale * spread.flux_ratio * kernel.at([node[0] as f64, node[1] as f64]) as f32
    }
}

/// Index of the node at or below `value` (clamped to the nodes) and the fraction towards the
/// next one. The nodes are evenly spaced (as [`LensKernels::trace`] lays them and
/// [`LensKernels::read`] checks), so the index is arithmetic: a per-pixel search was a tenth of
/// a postfx frame.
fn bracket(nodes: &[f64], value: f64) -> (usize, f64) {
    let last = nodes.len() - 2;
    let step = (nodes[last + 1] - nodes[0]) / (last + 1) as f64;
    let at = if step > 0.0 {
        (value - nodes[0]) / step
    } else {
        0.0
    };
    let i = (at.max(0.0) as usize).min(last);
    (i, (at - i as f64).clamp(0.0, 1.0))
}

/// What turns a traced ray's film point into a kernel offset and its weight.
struct SpotGeometry<'a> {
    camera: &'a Camera,
    eye_z: f64,
    entrance_radius: f64,
    pixel_tangent: f64,
    /// 1 / (reference solid angle x film area per unit tangent area): the weight of a ray per
    /// unit of entrance-side area times cos^4.
    weight_scale: f64,
}

/// Entrance-side region scanned for passing rays, in entrance-pupil radii (pupil aberration
/// moves the real pupil of a field point well off the paraxial one in wide lenses).
const SCAN_REACH: f64 = 3.0;
/// Rays per side of the scan that finds the passing region.
const SCAN_RAYS: usize = 24;

impl<'a> SpotGeometry<'a> {
    fn of(camera: &'a Camera, lens: &TracedLens, pixel_tangent: f64) -> Result<Self, RenderError> {
        let paraxial = &lens.paraxial;
        let exit_distance = camera.film_z - paraxial.exit_pupil_z;
        let reference =
            std::f64::consts::PI * paraxial.exit_pupil_radius_mm.powi(2) / exit_distance.powi(2);
        // The chief-ray map from an untilted film to tangents is linear: its Jacobian from two
        // steps of 1 mm.
        let at = |x: f64, y: f64| camera.chief_ray_tangents([x, y, camera.film_z]);
        let (o, ex, ey) = (at(0.0, 0.0), at(1.0, 0.0), at(0.0, 1.0));
        let tangent_area =
            ((ex[0] - o[0]) * (ey[1] - o[1]) - (ex[1] - o[1]) * (ey[0] - o[0])).abs();
        if !(reference > 0.0 && tangent_area > 0.0) {
            return Err(RenderError::InvalidSetting(
                "the lens has no exit pupil or no field to trace kernels in".into(),
            ));
        }
        Ok(SpotGeometry {
            camera,
            eye_z: camera.eye_z(),
            entrance_radius: paraxial.entrance_pupil_radius_mm,
            pixel_tangent,
            weight_scale: tangent_area / reference,
        })
    }

    /// The ray from `object` through the entrance-side point (x, y) traced to the film: the
    /// kernel offset of its film point from the emitter at tangent `tangent`, and its weight
    /// per unit entrance-side area.
    fn ray(
        &self,
        lens: &TracedLens,
        object: [f64; 3],
        x: f64,
        y: f64,
        tangent: f64,
    ) -> Option<([f64; 2], f64)> {
        let towards = [x - object[0], y - object[1], self.eye_z - object[2]];
        let ray = Ray::new(object, towards).ok()?;
        let cos = ray.direction()[2];
        let traced = lens.tracer.trace(ray, Travel::Forward);
        if !traced.outcome.is_ok() {
            return None;
        }
        let film = traced.ray.point_at_z(self.camera.film_z)?;
        let t = self.camera.chief_ray_tangents(film);
        let offset = [
            (t[0] - tangent) / self.pixel_tangent,
            t[1] / self.pixel_tangent,
        ];
        let weight = cos.powi(4) * self.weight_scale;
        (offset.iter().all(|v| v.is_finite())).then_some((offset, weight))
    }

    /// The spot of a point emitter `depth` mm in front of the eye at chief-ray tangent
    /// (`tangent`, 0).
    fn spot(
        &self,
        lens: &TracedLens,
        depth: f64,
        tangent: f64,
        settings: &KernelSettings,
    ) -> Kernel {
        let object = [tangent * depth, 0.0, self.eye_z - depth];
        // Scan a wide square for the passing region, then trace a fine grid over its bounds
        // widened by one scan cell.
        let reach = SCAN_REACH * self.entrance_radius;
        let cell = 2.0 * reach / SCAN_RAYS as f64;
        let mut bounds = [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ];
        for a in 0..SCAN_RAYS {
            for b in 0..SCAN_RAYS {
                let x = -reach + (a as f64 + 0.5) * cell;
                let y = -reach + (b as f64 + 0.5) * cell;
                if self.ray(lens, object, x, y, tangent).is_some() {
                    bounds = [
                        bounds[0].min(x),
                        bounds[1].min(y),
                        bounds[2].max(x),
                        bounds[3].max(y),
                    ];
                }
            }
        }
        if bounds[0] > bounds[2] {
            return Kernel::empty();
        }
        let lo = [bounds[0] - cell, bounds[1] - cell];
        let n = settings.rays_per_side;
        let step = [
            (bounds[2] - bounds[0] + 2.0 * cell) / n as f64,
            (bounds[3] - bounds[1] + 2.0 * cell) / n as f64,
        ];
        let area = step[0] * step[1];
        let mut hits = Vec::with_capacity(n * n);
        for a in 0..n {
            for b in 0..n {
                let x = lo[0] + (a as f64 + 0.5) * step[0];
                let y = lo[1] + (b as f64 + 0.5) * step[1];
                if let Some((offset, weight)) = self.ray(lens, object, x, y, tangent) {
                    hits.push((offset, weight * area));
                }
            }
        }
        Kernel::from_hits(&hits, settings.grid_side)
    }
}

impl Kernel {
    /// This kernel shrunk about its centroid to `scale` times its size (`scale` in (0, 1]),
    /// keeping its flux: the grid moves and narrows, each value grows by 1 / scale^2.
    pub fn scaled(&self, scale: f64) -> Kernel {
        let gain = (1.0 / (scale * scale)) as f32;
        Kernel {
            origin: [0, 1].map(|k| self.centroid[k] + (self.origin[k] - self.centroid[k]) * scale),
            spacing: self.spacing * scale,
            values: self.values.iter().map(|v| v * gain).collect(),
            rms_radius: self.rms_radius * scale,
            ..self.clone()
        }
    }

    /// This kernel for an output box of `2 x 2` pixels (values per output pixel, averaged over
    /// the box): the average of four copies shifted by half a pixel, since a 1-pixel box
    /// convolved with points at +-1/2 is the 2-pixel box. Summed over a lattice of 2-pixel
    /// pitch at any phase it gives a quarter of the flux exactly, which a point sample of the
    /// 1-pixel kernel does not (a sharp-edged spot gains or loses lattice points).
    pub fn over_two_pixel_box(&self) -> Kernel {
        if self.side == 0 {
            return self.clone();
        }
        let shift = 0.5 / self.spacing;
        let pad = shift.ceil() as usize;
        let side = self.side + 2 * pad;
        let mut grid = vec![0.0f32; side * side];
        for y in 0..self.side {
            let row = (y + pad) * side + pad;
            grid[row..row + self.side]
                .copy_from_slice(&self.values[y * self.side..(y + 1) * self.side]);
        }
        // Each axis in turn: the mean of the values half a pixel either side, linear between
        // nodes.
        let lerp = |line: &[f32], at: f64| -> f32 {
            if at < 0.0 || at > (side - 1) as f64 {
                return 0.0;
            }
            let i = (at as usize).min(side - 2);
            let f = (at - i as f64) as f32;
            line[i] * (1.0 - f) + line[i + 1] * f
        };
        let mut line = vec![0.0f32; side];
        for axis in 0..2 {
            for a in 0..side {
                let at = |b: usize| match axis {
                    0 => a * side + b,
                    _ => b * side + a,
                };
                for (b, v) in line.iter_mut().enumerate() {
                    *v = grid[at(b)];
                }
                for b in 0..side {
                    grid[at(b)] =
                        0.5 * (lerp(&line, b as f64 - shift) + lerp(&line, b as f64 + shift));
                }
            }
        }
        Kernel {
            origin: [
                self.origin[0] - pad as f64 * self.spacing,
                self.origin[1] - pad as f64 * self.spacing,
            ],
            side,
            values: grid,
            support: self.support + std::f64::consts::FRAC_1_SQRT_2,
            ..self.clone()
        }
    }

    /// The kernel of weighted film hits (offsets in pinhole pixels): each hit's weight spread
    /// over the output pixel box around it, sampled on a grid covering every box.
    fn from_hits(hits: &[([f64; 2], f64)], side: usize) -> Kernel {
        let flux: f64 = hits.iter().map(|h| h.1).sum();
        if hits.is_empty() || flux <= 0.0 {
            return Kernel::empty();
        }
        let mean = |k: usize| hits.iter().map(|h| h.0[k] * h.1).sum::<f64>() / flux;
        let centroid = [mean(0), mean(1)];
        let spread2 = hits
            .iter()
            .map(|(o, w)| w * ((o[0] - centroid[0]).powi(2) + (o[1] - centroid[1]).powi(2)))
            .sum::<f64>()
            / flux;
        let reach = hits
            .iter()
            .map(|(o, _)| (o[0] - centroid[0]).abs().max((o[1] - centroid[1]).abs()))
            .fold(0.0, f64::max);
        // Half a pixel box on each side, and one node so that bilinear lookups reach zero.
        let spacing = 2.0 * (reach + 0.5) / (side as f64 - 3.0);
        let half = 0.5 * spacing * (side as f64 - 1.0);
        let origin = [centroid[0] - half, centroid[1] - half];
        // Each hit adds a box of weight w over [o - 1/2, o + 1/2]^2: four steps per axis in a
        // difference grid, each step shared linearly between its two nearest nodes, then a
        // running sum in x and y.
        let mut diff = vec![0.0f64; side * side];
        let steps = |lo: f64, hi: f64| -> [(usize, f64); 4] {
            let split = |f: f64, sign: f64| {
                let a = f - 0.5;
                let j = a.floor() + 1.0;
                let first = j - a;
                let clamp = |j: f64| j.clamp(0.0, side as f64) as usize;
                [
                    (clamp(j), sign * first),
                    (clamp(j + 1.0), sign * (1.0 - first)),
                ]
            };
            let [a, b] = split(lo, 1.0);
            let [c, d] = split(hi, -1.0);
            [a, b, c, d]
        };
        for (o, w) in hits {
            let gx = (o[0] - origin[0]) / spacing;
            let gy = (o[1] - origin[1]) / spacing;
            let sx = steps(gx - 0.5 / spacing, gx + 0.5 / spacing);
            let sy = steps(gy - 0.5 / spacing, gy + 0.5 / spacing);
            for &(jy, ay) in &sy {
                for &(jx, ax) in &sx {
                    if jx < side && jy < side {
                        diff[jy * side + jx] += w * ax * ay;
                    }
                }
            }
        }
        for row in diff.chunks_mut(side) {
            for x in 1..side {
                row[x] += row[x - 1];
            }
        }
        for y in 1..side {
            for x in 0..side {
                diff[y * side + x] += diff[(y - 1) * side + x];
            }
        }
        let support = hits
            .iter()
            .map(|(o, _)| o[0].hypot(o[1]))
            .fold(0.0, f64::max)
            + std::f64::consts::FRAC_1_SQRT_2;
        Kernel {
            origin,
            spacing,
            side,
            values: diff.iter().map(|&v| v.max(0.0) as f32).collect(),
            flux,
            centroid,
            rms_radius: spread2.sqrt(),
            support,
        }
    }
}
