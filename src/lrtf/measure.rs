//! What a table costs in accuracy: the table's answer against the exact trace for random rays
//! drawn the way a renderer draws them (film point uniform over the film disk, rear point uniform
//! over that film radius's effective-pupil circle), and how tight the pupil bound is.

use glam::DVec3;
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::bake::exact_transfer;
use super::param::Ray;
use super::table::{Corners, Lookup, LrtfTable};
use crate::pupil::PupilTable;
use crate::trace::{Tracer, UnitDraws};

/// Median, 99th percentile and maximum of a sample.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Stats {
    pub median: f64,
    pub p99: f64,
    pub max: f64,
}

impl Stats {
    pub fn of(mut values: Vec<f64>) -> Stats {
        if values.is_empty() {
            return Stats::default();
        }
        values.sort_by(f64::total_cmp);
        let at = |q: f64| values[((values.len() - 1) as f64 * q).round() as usize];
        Stats {
            median: at(0.5),
            p99: at(0.99),
            max: values[values.len() - 1],
        }
    }
}

/// Errors of one table layer against the exact trace.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TableError {
    pub rays: usize,
    /// Rays where exactly one of table and trace says the ray passes, over all rays.
    pub validity_mismatch: f64,
    /// Angle between table and exact outgoing directions (mrad), rays both say pass.
    pub direction_mrad: Stats,
    /// Distance from the exact exit point to the table's outgoing line (um), measured in the
    /// plane through the exact exit point perpendicular to the exact ray.
    pub position_um: Stats,
    /// Direction error mapped to the image: EFL * angle / pixel pitch (pixels).
    pub image_px: Stats,
}

/// One row of a measurement sweep (notebooks-out/lrtf/lrtf-error.json): a baked table's cost
/// and its error against the exact trace.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct SweepRow {
    pub lens: String,
    pub parameterisation: String,
    /// Nodes per table axis (the table has resolution^3 entries).
    pub resolution: usize,
    pub precision: String,
    pub bake_seconds: f64,
    /// Bytes of the entries as stored.
    pub bytes: usize,
    /// Focal length used to map direction error to the image (mm).
    pub efl: f64,
    pub max_film_radius: f64,
    pub error: TableError,
}

/// Issue 6's accuracy target: p99 image error below this many pixels of a 1920-pixel frame.
pub const IMAGE_ERROR_TARGET_PX: f64 = 0.5;

/// Pixel pitch (mm) of a 3:2 frame `pixels` wide inscribed in the image circle of `film_radius`.
pub fn pixel_pitch(film_radius: f64, pixels: f64) -> f64 {
    2.0 * film_radius * 3.0 / 13f64.sqrt() / pixels
}

/// `count` film-side rays of the renderer's distribution for one layer, in the lens frame.
pub fn renderer_rays(
    pupil: &PupilTable,
    max_film_radius: f64,
    film_z: f64,
    rear_z: f64,
    count: usize,
    seed: u64,
) -> Vec<Ray> {
    let mut rng = UnitDraws::new(seed);
    (0..count)
        .map(|_| {
            let film_radius = max_film_radius * rng.next().sqrt();
            let azimuth = std::f64::consts::TAU * rng.next();
            let sample = pupil.sample(film_radius, [rng.next(), rng.next()]);
            let (c, s) = (azimuth.cos(), azimuth.sin());
            let rotate = |p: [f64; 2]| [c * p[0] - s * p[1], s * p[0] + c * p[1]];
            let film = rotate([film_radius, 0.0]);
            let rear = rotate(sample.point);
            let d = [rear[0] - film[0], rear[1] - film[1], rear_z - film_z];
            let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            Ray {
                origin: [film[0], film[1], film_z],
                direction: [d[0] / n, d[1] / n, d[2] / n],
            }
        })
        .collect()
}


/// Angle between unit vectors, accurate for tiny angles.
pub fn angle_between(a: [f64; 3], b: [f64; 3]) -> f64 {
    let (a, b) = (DVec3::from(a), DVec3::from(b));
    a.cross(b).length().atan2(a.dot(b))
}

/// Distance from `point` to the line through `origin` along unit `direction`.
pub fn distance_to_line(point: [f64; 3], origin: [f64; 3], direction: [f64; 3]) -> f64 {
    (DVec3::from(point) - DVec3::from(origin))
        .cross(DVec3::from(direction))
        .length()
}

/// Table layer `layer` against `tracer` (the same lens and wavelength, stop as baked) over
/// `count` renderer rays; image error for a frame `pixels` wide with focal length `efl`.
pub fn table_error(
    table: &LrtfTable,
    layer: usize,
    tracer: &Tracer,
    efl: f64,
    pixels: f64,
    count: usize,
    seed: u64,
) -> TableError {
    table_error_from(table, layer, tracer, efl, pixels, count, seed, Corners::All)
}

/// [`table_error`] with the sampler's values interpolated from `corners`.
#[allow(clippy::too_many_arguments)]
pub fn table_error_from(
    table: &LrtfTable,
    layer: usize,
    tracer: &Tracer,
    efl: f64,
    pixels: f64,
    count: usize,
    seed: u64,
    corners: Corners,
) -> TableError {
    let film_z = table.layers[layer].frame.film_plane_z;
    measure_on(
        table, layer, film_z, tracer, efl, pixels, count, seed, corners,
    )
}

/// [`table_error`] for a render focused on the film plane `film_z` of the table's focus range:
/// film points up to the film radius baked, on that plane, rear points in its sampling pupil.
#[allow(clippy::too_many_arguments)]
pub fn table_error_focused(
    table: &LrtfTable,
    layer: usize,
    film_z: f64,
    tracer: &Tracer,
    efl: f64,
    pixels: f64,
    count: usize,
    seed: u64,
) -> TableError {
    measure_on(
        table,
        layer,
        film_z,
        tracer,
        efl,
        pixels,
        count,
        seed,
        Corners::All,
    )
}

#[allow(clippy::too_many_arguments)]
fn measure_on(
    table: &LrtfTable,
    layer: usize,
    film_z: f64,
    tracer: &Tracer,
    efl: f64,
    pixels: f64,
    count: usize,
    seed: u64,
    corners: Corners,
) -> TableError {
    let l = &table.layers[layer];
    let max_film_radius = l.sampling.max_film_radius();
    let rays = renderer_rays(
        &l.sampling.at_film_z(film_z),
        max_film_radius,
        film_z,
        l.frame.rear_plane_z,
        count,
        seed,
    );
    let stop = l.stop_semi_aperture;
    let results: Vec<(bool, Option<(f64, f64)>)> = rays
        .par_iter()
        .map(|ray| {
            let (exact, passes) = exact_transfer(tracer, ray);
            let looked = table.lookup_from(layer, ray, stop, corners);
            match (passes.then_some(exact).flatten(), looked) {
                (Some(t), Lookup::Passes(r)) => (
                    false,
                    Some((
                        angle_between(t.exit_direction, r.direction),
                        distance_to_line(t.exit_point, r.origin, r.direction),
                    )),
                ),
                (None, Lookup::Passes(_)) | (Some(_), _) => (true, None),
                (None, _) => (false, None),
            }
        })
        .collect();
    let mismatches = results.iter().filter(|r| r.0).count();
    let angles: Vec<f64> = results.iter().filter_map(|r| r.1.map(|e| e.0)).collect();
    let pitch = pixel_pitch(max_film_radius, pixels);
    TableError {
        rays: count,
        validity_mismatch: mismatches as f64 / count as f64,
        direction_mrad: Stats::of(angles.iter().map(|a| a * 1e3).collect()),
        position_um: Stats::of(
            results
                .iter()
                .filter_map(|r| r.1.map(|e| e.1 * 1e3))
                .collect(),
        ),
        image_px: Stats::of(angles.iter().map(|a| efl.abs() * a / pitch).collect()),
    }
}

/// Fraction of rays that pass among rays sampled uniformly in three kinds of bound.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Tightness {
    /// Uniform over the whole rear clear aperture.
    pub rear_element: f64,
    /// pbrt-style axis-aligned box per radial bin (64 bins).
    pub box_per_bin: f64,
    /// This crate's interpolated effective-pupil circle.
    pub pupil_circle: f64,
    /// Passing rays found outside the circle (a conservative bound has none).
    pub passing_outside_circle: usize,
}

/// Measures the pupil bound's tightness for one lens at one wavelength. `passes(film_radius,
/// rear_point)` is the exact test; rays per method `count`.
pub fn pupil_tightness(
    pupil: &PupilTable,
    rear_semi_aperture: f64,
    passes: &(dyn Fn(f64, [f64; 2]) -> bool + Sync),
    count: usize,
    seed: u64,
) -> Tightness {
    const BINS: usize = 64;
    let max_r = pupil.max_film_radius;
    // pbrt's bounds: per bin, the box around passing points of a rear-element grid for a few film
    // radii in the bin, grown by one grid step.
    let grid = 64;
    let step = 2.0 * rear_semi_aperture / (grid - 1) as f64;
    let boxes: Vec<Option<[f64; 4]>> = (0..BINS)
        .into_par_iter()
        .map(|b| {
            let mut bounds: Option<[f64; 4]> = None;
            for k in 0..4 {
                let r = max_r * (b as f64 + k as f64 / 3.0) / BINS as f64;
                for i in 0..grid {
                    for j in 0..grid {
                        let p = [
                            -rear_semi_aperture + i as f64 * step,
                            -rear_semi_aperture + j as f64 * step,
                        ];
                        if p[0].hypot(p[1]) <= rear_semi_aperture && passes(r, p) {
                            let b = bounds.get_or_insert([p[0], p[0], p[1], p[1]]);
                            *b = [
                                b[0].min(p[0]),
                                b[1].max(p[0]),
                                b[2].min(p[1]),
                                b[3].max(p[1]),
                            ];
                        }
                    }
                }
            }
            bounds.map(|b| [b[0] - step, b[1] + step, b[2] - step, b[3] + step])
        })
        .collect();
    let trial = |method: usize, i: usize| -> (bool, bool) {
        let mut rng =
            UnitDraws::new(seed ^ (i as u64).wrapping_mul(0x2545_f491_4f6c_dd1d) ^ method as u64);
        let r = max_r * rng.next().sqrt();
        let u = [rng.next(), rng.next()];
        match method {
            0 => {
                let d = crate::pupil::concentric_disk(u);
                (
                    passes(r, [d[0] * rear_semi_aperture, d[1] * rear_semi_aperture]),
                    false,
                )
            }
            1 => match boxes[((r / max_r * BINS as f64) as usize).min(BINS - 1)] {
                Some(b) => (
                    passes(
                        r,
                        [b[0] + u[0] * (b[1] - b[0]), b[2] + u[1] * (b[3] - b[2])],
                    ),
                    false,
                ),
                None => (false, false),
            },
            _ => {
                let s = pupil.sample(r, u);
                // A passing point just outside the circle shows a non-conservative bound.
                let d = crate::pupil::concentric_disk([rng.next(), rng.next()]);
                let probe = [
                    d[0] * rear_semi_aperture * 1.2,
                    d[1] * rear_semi_aperture * 1.2,
                ];
                let outside = pupil.pdf(r, probe) == 0.0 && passes(r, probe);
                (passes(r, s.point), outside)
            }
        }
    };
    let fraction = |method: usize| {
        let hits: Vec<(bool, bool)> = (0..count)
            .into_par_iter()
            .map(|i| trial(method, i))
            .collect();
        (
            hits.iter().filter(|h| h.0).count() as f64 / count as f64,
            hits.iter().filter(|h| h.1).count(),
        )
    };
    let (pupil_circle, passing_outside_circle) = fraction(2);
    Tightness {
        rear_element: fraction(0).0,
        box_per_bin: fraction(1).0,
        pupil_circle,
        passing_outside_circle,
    }
}
