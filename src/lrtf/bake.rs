//! Baking: fix the domain (film plane, film radius, aperture, wavelengths), fit the effective
//! pupil, then trace one exact ray per table node.
//!
//! Each node stores the ray's transfer *through the lens with apertures ignored* (the geometric
//! continuation, a smooth function across every vignetting edge) plus a validity channel from the
//! trace with apertures on, plus the stop crossing. So interpolated transfer values never mix in a
//! sentinel, and validity is interpolated on its own. Nodes where even the unapertured ray fails
//! (TIR, missed surface) get values diffused from their neighbours; their validity is 0.

use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use super::param::{CHANNELS, Frame, Parameterisation, Ray, Transfer, VALID};
use super::table::{Layer, LrtfTable, Precision, TableInfo};
use crate::paraxial::{Field, ObjectPosition, Paraxial, ParaxialError, ParaxialOptions};
use crate::prescription::PrescriptionError;
use crate::pupil::{self, PupilFitSettings, PupilTable};
use crate::system::{LensSystem, SystemAt};
use crate::trace::{Apertures, Tracer, Travel};

/// What to bake. `None` fields take the defaults of issue 6: film at the paraxial image plane
/// for an object at infinity, film radius up to the real chief ray's image height at the largest
/// traceable field, the lens wide open, the design wavelength.
#[derive(Clone, Debug, PartialEq)]
pub struct BakeRequest {
    pub parameterisation: Parameterisation,
    pub resolution: [usize; 3],
    pub precision: Precision,
    /// One wavelength, or three (R, G, B) for chromatic aberration; empty = design wavelength.
    pub wavelengths_nm: Vec<f64>,
    pub f_number: Option<f64>,
    /// Object distance in focus, mm in front of surface 1; None = infinity.
    pub focus_mm: Option<f64>,
    pub max_film_radius: Option<f64>,
    /// Film radii at which pupil circles are stored; None = the table's film-radius nodes, which
    /// keeps the pupil-planes rear coordinate exactly linear in film radius inside every cell
    /// (measured: 64 pupil nodes under a 32-node table gave 0.2 mm exit-position errors).
    pub pupil_nodes: Option<usize>,
    pub pupil_fit: PupilFitSettings,
}

impl Default for BakeRequest {
    fn default() -> Self {
        BakeRequest {
            parameterisation: Parameterisation::PupilPlanes,
            resolution: [128, 128, 128],
            precision: Precision::F32,
            wavelengths_nm: Vec::new(),
            f_number: None,
            focus_mm: None,
            max_film_radius: None,
            pupil_nodes: None,
            pupil_fit: PupilFitSettings::default(),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum BakeError {
    #[error("first-order optics of the lens: {0}")]
    Paraxial(#[from] ParaxialError),
    #[error("cannot bake at this wavelength: {0}")]
    Wavelength(#[from] PrescriptionError),
    #[error("f-number {asked} is faster than the lens wide open (f/{wide_open:.3})")]
    FNumber { asked: f64, wide_open: f64 },
    #[error("resolution {0:?} needs at least 2 nodes on every axis")]
    Resolution([usize; 3]),
    #[error("{0} wavelengths asked; a table holds 1 or 3")]
    WavelengthCount(usize),
    #[error("no ray from the film at radius {film_radius} mm passes the lens")]
    NothingPasses { film_radius: f64 },
    #[error("film plane z = {film_z} mm is not behind the last vertex (z = {rear_z} mm)")]
    FilmPlane { film_z: f64, rear_z: f64 },
}

/// Progress of a bake: nodes done out of all nodes of all layers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BakeProgress {
    pub done: usize,
    pub total: usize,
}

/// The exact transfer of one film-side ray: the continuation through the unapertured lens (None
/// when even that fails) and whether the ray passes `tracer`'s apertures.
///
/// A ray that passes the apertures is its own continuation, so it is traced once; only a blocked
/// ray is traced again with apertures ignored. Neither trace allocates.
pub fn exact_transfer(tracer: &Tracer, ray: &Ray) -> (Option<Transfer>, bool) {
    let Ok(start) = crate::trace::Ray::new(ray.origin, ray.direction) else {
        return (None, false);
    };
    let stop = tracer.stop_surface() - 1;
    let surfaces = 0..tracer.surface_count();
    let mut stop_point = None;
    let mut record_stop = |i: usize, at: &crate::trace::Ray| {
        if i == stop {
            let p = at.position();
            stop_point = Some([p[0], p[1]]);
        }
    };
    let (checked, _) = tracer.run(
        start,
        Travel::Backward,
        surfaces.clone(),
        Apertures::Checked,
        &mut record_stop,
    );
    let passes = checked.outcome.is_ok();
    let exit = if passes {
        checked.ray
    } else {
        let (continued, _) = tracer.run(
            start,
            Travel::Backward,
            surfaces,
            Apertures::Ignored,
            &mut record_stop,
        );
        if !continued.outcome.is_ok() {
            return (None, false);
        }
        continued.ray
    };
    let Some(stop_point) = stop_point else {
        return (None, false);
    };
    (
        Some(Transfer {
            exit_point: exit.position(),
            exit_direction: exit.direction(),
            stop_point,
        }),
        passes,
    )
}

/// Whether the ray from film point (film_radius, 0, film_z) through rear-plane point `rear`
/// passes the lens with apertures on.
pub fn passes_from_film(
    tracer: &Tracer,
    film_radius: f64,
    film_z: f64,
    rear_z: f64,
    rear: [f64; 2],
) -> bool {
    let direction = [rear[0] - film_radius, rear[1], rear_z - film_z];
    crate::trace::Ray::new([film_radius, 0.0, film_z], direction)
        .is_ok_and(|ray| tracer.trace(ray, Travel::Backward).outcome.is_ok())
}

/// Radius of the rear-plane disk searched for passing rays: the last clear aperture plus room
/// for rays that cross the rear plane outside it but meet the curved surface inside.
pub fn rear_search_radius(system: &SystemAt) -> f64 {
    let last = system
        .surfaces
        .last()
        .expect("a validated lens has surfaces");
    1.25 * last.semi_aperture
}

/// The real chief ray's film radius at the largest traceable field: the largest film radius
/// whose meridional ray through the stop centre still passes (bisection on the film radius; the
/// chief ray itself by bisection on its rear-plane crossing).
pub fn chief_ray_film_radius(tracer: &Tracer, system: &SystemAt, film_z: f64) -> f64 {
    let rear_z = system.last_vertex_z();
    let search = rear_search_radius(system);
    let stop = tracer.stop_surface();
    // Stop-plane height of the meridional ray from the film point through rear point x.
    let stop_height = |film_radius: f64, x: f64| {
        let ray = crate::trace::Ray::new(
            [film_radius, 0.0, film_z],
            [x - film_radius, 0.0, rear_z - film_z],
        )
        .ok()?;
        let t = tracer.trace_to(ray, Travel::Backward, stop, Apertures::Ignored);
        t.outcome.is_ok().then(|| t.ray.position()[0])
    };
    let chief_passes = |film_radius: f64| {
        // Bisection needs a sign change of the stop height between two traceable rear points;
        // scan the rear disk for the first such pair.
        let samples: Vec<(f64, f64)> = (0..=64)
            .filter_map(|k| {
                let x = -search + 2.0 * search * k as f64 / 64.0;
                stop_height(film_radius, x).map(|h| (x, h))
            })
            .collect();
        let Some(pair) = samples
            .windows(2)
            .find(|w| w[0].1.signum() != w[1].1.signum())
        else {
            return false;
        };
        let (mut lo, mut hi, h_lo) = (pair[0].0, pair[1].0, pair[0].1);
        for _ in 0..60 {
            let mid = 0.5 * (lo + hi);
            match stop_height(film_radius, mid) {
                Some(h) if h.signum() == h_lo.signum() => lo = mid,
                Some(_) => hi = mid,
                None => return false,
            }
        }
        passes_from_film(tracer, film_radius, film_z, rear_z, [0.5 * (lo + hi), 0.0])
    };
    let mut hi = search.max(1.0);
    while chief_passes(hi) && hi < 1e4 {
        hi *= 2.0;
    }
    let mut lo = 0.0;
    for _ in 0..40 {
        let mid = 0.5 * (lo + hi);
        if chief_passes(mid) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Stop radius standing for "no stop" when the stop is left to the sampler (mm).
const OPEN_STOP: f64 = 1e6;

/// The lens at `wavelength_nm` with its stop closed down to `stop_semi_aperture`
/// ([`SystemAt::stopped_down`]: the stop surface's geometry stays).
pub fn stopped_down(system: &LensSystem, wavelength_nm: f64, stop_semi_aperture: f64) -> SystemAt {
    system.at(wavelength_nm).stopped_down(stop_semi_aperture)
}

/// The paraxial model the bake works from: the design wavelength, the marked stop filled, the
/// object at infinity or `focus_mm` in front of surface 1 (EFL, wide-open f-number = EFL / EPD,
/// paraxial image plane).
pub fn first_order(system: &SystemAt, focus_mm: Option<f64>) -> Result<Paraxial, ParaxialError> {
    let object = ObjectPosition::in_focus(focus_mm);
    Paraxial::new(
        system,
        &ParaxialOptions {
            object,
            field: Field::Angle { deg: 0.0 },
            ..ParaxialOptions::default()
        },
    )
}

/// Bakes a table; `progress` is called from worker threads as nodes complete.
pub fn bake(
    system: &LensSystem,
    request: &BakeRequest,
    progress: &(dyn Fn(BakeProgress) + Sync),
) -> Result<LrtfTable, BakeError> {
    if request.resolution.iter().any(|&n| n < 2) {
        return Err(BakeError::Resolution(request.resolution));
    }
    let wavelengths = if request.wavelengths_nm.is_empty() {
        vec![system.design_wavelength_nm()]
    } else {
        request.wavelengths_nm.clone()
    };
    if wavelengths.len() != 1 && wavelengths.len() != 3 {
        return Err(BakeError::WavelengthCount(wavelengths.len()));
    }
    // Every layer is traced through `stopped_down`, which trusts the wavelength: refuse the ones
    // where a medium's dispersion formula no longer gives an index.
    for &nm in &wavelengths {
        system.at_checked(nm)?;
    }
    let design = system.at_checked(system.design_wavelength_nm())?;
    let first = first_order(&design, request.focus_mm)?;
    let wide_open = first.f_number;
    let f_number = request.f_number.unwrap_or(wide_open);
    if f_number < wide_open * (1.0 - 1e-9) {
        return Err(BakeError::FNumber {
            asked: f_number,
            wide_open,
        });
    }
    // The stop scales as 1 / f-number (the entrance pupil is its paraxial image).
    let stop_semi_aperture = design.surfaces[design.stop].semi_aperture * wide_open / f_number;
    // One physical film plane for every wavelength: the design wavelength's image plane.
    let film_z = first.z_image;
    let rear_z = design.last_vertex_z();
    if film_z <= rear_z {
        return Err(BakeError::FilmPlane { film_z, rear_z });
    }
    let design_tracer = Tracer::new(&stopped_down(
        system,
        system.design_wavelength_nm(),
        stop_semi_aperture,
    ));
    let max_film_radius = request
        .max_film_radius
        .unwrap_or_else(|| chief_ray_film_radius(&design_tracer, &design, film_z));
    let nodes_per_layer: usize = request.resolution.iter().product();
    let total = nodes_per_layer * wavelengths.len();
    let done = AtomicUsize::new(0);
    let mut layers = Vec::with_capacity(wavelengths.len());
    for &wavelength_nm in &wavelengths {
        let at = stopped_down(system, wavelength_nm, stop_semi_aperture);
        let tracer = Tracer::new(&at);
        let search = rear_search_radius(&at);
        let fit = |film_radius: f64| {
            let passes =
                |rear: [f64; 2]| passes_from_film(&tracer, film_radius, film_z, rear_z, rear);
            pupil::fit_pupil(&passes, search, &request.pupil_fit)
        };
        let pupil_nodes = request.pupil_nodes.unwrap_or(request.resolution[0]);
        // Pupils fitted between nodes make the interpolated circles conservative. From 64 nodes
        // on an interval spans under 2 % of the film radius and one check at its middle, where a
        // linear interpolant strays furthest from a smooth curve, suffices (measured: no passing
        // ray outside the circle over 200k rays for the three bundled test lenses).
        let between = if pupil_nodes >= 64 { 1 } else { 2 };
        let pupil = pupil::build_table(&fit, max_film_radius, pupil_nodes, between);
        if pupil.circles[0].radius <= 0.0 {
            return Err(BakeError::NothingPasses { film_radius: 0.0 });
        }
        let max_rear_radius = pupil.max_extent();
        let frame = Frame {
            rear_plane_z: rear_z,
            film_plane_z: film_z,
            max_film_radius,
            max_rear_radius,
            max_polar_angle: ((max_rear_radius + max_film_radius) / (film_z - rear_z)).atan(),
        };
        // A circular stop is tested by the sampler against the interpolated stop crossing (smooth,
        // so its edge comes out sharper than thresholded validity); the validity channel then
        // records every other aperture. A bladed stop stays in the validity channel.
        let circular_stop = matches!(
            at.surfaces[at.stop].stop,
            Some(crate::prescription::StopShape::Circle)
        );
        let validity_tracer = if circular_stop {
            Tracer::new(&stopped_down(system, wavelength_nm, OPEN_STOP))
        } else {
            tracer.clone()
        };
        let entries = bake_entries(request, &validity_tracer, &frame, &pupil, &|n| {
            let d = done.fetch_add(n, Ordering::Relaxed) + n;
            progress(BakeProgress { done: d, total });
        });
        layers.push(Layer {
            wavelength_nm,
            frame,
            pupil,
            stop_semi_aperture,
            entries,
        });
    }
    Ok(LrtfTable {
        info: TableInfo {
            parameterisation: request.parameterisation,
            resolution: request.resolution,
            precision: request.precision,
            f_number,
            focus_mm: request.focus_mm,
        },
        layers,
    })
}

fn bake_entries(
    request: &BakeRequest,
    tracer: &Tracer,
    frame: &Frame,
    pupil: &PupilTable,
    report: &(dyn Fn(usize) + Sync),
) -> Vec<[f32; CHANNELS]> {
    let [n0, n1, n2] = request.resolution;
    let param = request.parameterisation;
    let node = |k: usize, n: usize| k as f64 / (n - 1) as f64;
    let slab = n0 * n1;
    let mut entries = vec![[0.0f32; CHANNELS]; slab * n2];
    let mut defined = vec![false; slab * n2];
    // One work item per i2 slab, written in place: no per-node or per-row allocation.
    entries
        .par_chunks_mut(slab)
        .zip(defined.par_chunks_mut(slab))
        .enumerate()
        .for_each(|(i2, (entries, defined))| {
            for i1 in 0..n1 {
                for i0 in 0..n0 {
                    let coords = [node(i0, n0), node(i1, n1), node(i2, n2)];
                    let ray = param.ray_at(frame, pupil, coords);
                    if let (Some(transfer), passes) = exact_transfer(tracer, &ray) {
                        let k = i0 + n0 * i1;
                        entries[k] = param.encode(&transfer, passes).map(|v| v as f32);
                        defined[k] = true;
                    }
                }
            }
            report(slab);
        });
    fill_holes(&mut entries, &mut defined, request.resolution);
    for entry in &mut entries {
        *entry = entry.map(|v| request.precision.round(v));
    }
    entries
}

/// Gives every node without a transfer (even the unapertured ray failed) the mean of its defined
/// face neighbours, growing inwards from the defined region; its validity stays 0.
fn fill_holes(entries: &mut [[f32; CHANNELS]], defined: &mut [bool], dims: [usize; 3]) {
    let [n0, n1, n2] = dims;
    let index = |i0: usize, i1: usize, i2: usize| i0 + n0 * (i1 + n1 * i2);
    if !defined.contains(&true) {
        return;
    }
    loop {
        let mut filled = Vec::new();
        for i2 in 0..n2 {
            for i1 in 0..n1 {
                for i0 in 0..n0 {
                    if defined[index(i0, i1, i2)] {
                        continue;
                    }
                    let mut sum = [0.0f64; CHANNELS];
                    let mut count = 0.0;
                    let neighbours = [
                        (i0 > 0).then(|| index(i0 - 1, i1, i2)),
                        (i0 + 1 < n0).then(|| index(i0 + 1, i1, i2)),
                        (i1 > 0).then(|| index(i0, i1 - 1, i2)),
                        (i1 + 1 < n1).then(|| index(i0, i1 + 1, i2)),
                        (i2 > 0).then(|| index(i0, i1, i2 - 1)),
                        (i2 + 1 < n2).then(|| index(i0, i1, i2 + 1)),
                    ];
                    for k in neighbours.into_iter().flatten().filter(|&k| defined[k]) {
                        for (s, v) in sum.iter_mut().zip(entries[k]) {
                            *s += f64::from(v);
                        }
                        count += 1.0;
                    }
                    if count > 0.0 {
                        let mut mean = sum.map(|s| (s / count) as f32);
                        mean[VALID] = 0.0;
                        filled.push((index(i0, i1, i2), mean));
                    }
                }
            }
        }
        if filled.is_empty() {
            return;
        }
        for (k, v) in filled {
            entries[k] = v;
            defined[k] = true;
        }
    }
}
