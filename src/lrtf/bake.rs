//! Baking: fix the domain (film plane, film radius, aperture, wavelengths), fit the effective
//! pupil, then trace one exact ray per table node.
//!
//! Each node stores the ray's transfer *through the lens with apertures ignored* (the geometric
//! continuation, a smooth function across every vignetting edge), the stop crossing, and a signed
//! aperture margin from the same trace (how far inside the tightest clear aperture the ray
//! stays). So interpolated transfer values never mix in a sentinel, and the margin, continuous
//! too, is interpolated on its own and thresholded at 0. Nodes where even the unapertured ray
//! fails (TIR, missed surface) get values diffused from their neighbours and a negative margin.

use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

use super::entries::Entries;
use super::focus::{FocusRange, distance_text};
use super::param::{CHANNELS, Frame, MARGIN, Parameterisation, Ray, Transfer};
use super::table::{Layer, LrtfTable, Precision, TableInfo};
use crate::paraxial::{
    CannotFocus, Field, ImageInsideLens, ObjectPosition, Paraxial, ParaxialError, ParaxialOptions,
};
use crate::prescription::PrescriptionError;
use crate::pupil::{
    self, FocusNodeSettings, FocusPupilTable, PupilCircle, PupilFitSettings, PupilTable, RearTest,
};
use crate::system::{LensSystem, SystemAt};
use crate::trace::{Apertures, LANES, LaneVisitor, Slots, Tracer, Travel};

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
    /// Object distance in focus, mm in front of surface 1; None = infinity. With
    /// `focus_near_mm` it is the far end of a focus range.
    pub focus_mm: Option<f64>,
    /// The near end of a focus range (None: one focus, `focus_mm`): the table then serves every
    /// film plane between the two foci (unit focusing, the film moves).
    pub focus_near_mm: Option<f64>,
    /// How finely a focus range's pupil is sampled along the focus.
    pub focus_nodes: FocusNodeSettings,
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
            focus_near_mm: None,
            focus_nodes: FocusNodeSettings::default(),
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
    #[error(transparent)]
    Limit(#[from] crate::limits::LimitError),
    #[error("resolution {0:?} needs at least 2 nodes on every axis")]
    Resolution([usize; 3]),
    #[error("{0} wavelengths asked; a table holds 1 or 3")]
    WavelengthCount(usize),
    #[error("no ray from the film at radius {film_radius} mm passes the lens")]
    NothingPasses { film_radius: f64 },
    #[error(
        "no chief ray from the film plane (z = {film_z:.6} mm) passes the lens: a table would \
         cover no film"
    )]
    NoChiefRay { film_z: f64 },
    #[error("the film radius a table covers must be positive, got {0} mm")]
    FilmRadius(f64),
    #[error(transparent)]
    CannotFocus(CannotFocus),
    #[error(transparent)]
    ImageInsideLens(ImageInsideLens),
    #[error(
        "an odd number of mirrors sends the light back towards the object side; a table needs a \
         lens that images behind its last surface"
    )]
    ImageInFront,
    #[error("focus range {far}..{near}: the near focus must not lie beyond the far one")]
    FocusOrder { far: String, near: String },
}

/// Progress of a bake: nodes done out of all nodes of all layers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BakeProgress {
    pub done: usize,
    pub total: usize,
}

/// The exact transfer of one film-side ray: the continuation through the unapertured lens (None
/// when even that fails) and whether the ray passes `tracer`'s apertures, from the one-ray
/// tracer with apertures checked. It is the truth the measurements compare tables against and
/// the oracle the bake's lane path is tested against.
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

/// The rays from the film point (film_radius, 0, film_z) through rear-plane points, tested with
/// apertures on, `LANES` side by side: the probe the effective-pupil fit runs thousands of
/// times per film radius.
pub struct FilmPointRays<'a> {
    pub tracer: &'a Tracer,
    pub film_radius: f64,
    pub film_z: f64,
    pub rear_z: f64,
}

impl RearTest for FilmPointRays<'_> {
    fn test(&self, points: &[[f64; 2]], passes: &mut [bool]) {
        let origin = [self.film_radius, 0.0, self.film_z];
        for (points, passes) in points.chunks(LANES).zip(passes.chunks_mut(LANES)) {
            let rays: Vec<Option<crate::trace::Ray>> = points
                .iter()
                .map(|p| {
                    let direction = [p[0] - self.film_radius, p[1], self.rear_z - self.film_z];
                    crate::trace::Ray::new(origin, direction).ok()
                })
                .collect();
            // A ray that cannot be built (non-finite input) does not pass; its lane traces a
            // stand-in.
            let stand_in = crate::trace::Ray::from_parts(origin, [0.0, 0.0, -1.0]);
            let group: Vec<crate::trace::Ray> =
                rays.iter().map(|r| r.unwrap_or(stand_in)).collect();
            self.tracer.trace_group_visiting(
                &group,
                Travel::Backward,
                true,
                &mut crate::trace::NoVisit,
                &mut |l, traced| passes[l] = rays[l].is_some() && traced.outcome.is_ok(),
            );
        }
    }
}

/// The effective-pupil circle of film radius `film_radius` on the film plane `film_z` (None
/// where nothing passes), probed with `tracer` as [`pupil::fit_pupil`] does.
pub fn fit_film_pupil(
    tracer: &Tracer,
    film_z: f64,
    search_radius: f64,
    settings: &PupilFitSettings,
    film_radius: f64,
) -> Option<PupilCircle> {
    let rays = FilmPointRays {
        tracer,
        film_radius,
        film_z,
        rear_z: tracer.last_vertex_z(),
    };
    pupil::fit_pupil(&rays, search_radius, settings)
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
/// chief ray itself by bisection on its rear-plane crossing). Central obscurations are set
/// aside, as for the traceable field ([`crate::trace::traceable_field_deg`]): every chief
/// ray of an obscured lens runs through the shadow, which would leave no film at all.
pub fn chief_ray_film_radius(tracer: &Tracer, system: &SystemAt, film_z: f64) -> f64 {
    let clear = tracer.unobscured();
    let tracer = clear.as_ref();
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
        // scan the rear disk for such pairs. With apertures ignored the height can turn back
        // towards the rim (rays far outside the clear apertures), which makes sign changes that
        // no passing ray lies in: each pair is tried, and the chief ray is the one that passes.
        let samples: Vec<(f64, f64)> = (0..=64)
            .filter_map(|k| {
                let x = -search + 2.0 * search * k as f64 / 64.0;
                stop_height(film_radius, x).map(|h| (x, h))
            })
            .collect();
        samples
            .windows(2)
            .filter(|w| w[0].1.signum() != w[1].1.signum())
            .any(|pair| {
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
            })
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

/// The lens at `wavelength_nm` with its stop closed down to `stop_semi_aperture`
/// ([`SystemAt::stopped_down`]: the stop surface's geometry stays).
pub fn stopped_down(system: &LensSystem, wavelength_nm: f64, stop_semi_aperture: f64) -> SystemAt {
    system.at(wavelength_nm).stopped_down(stop_semi_aperture)
}

/// The paraxial model the bake works from: the design wavelength, the marked stop filled, the
/// object at infinity or `focus_mm` in front of surface 1 (EFL, wide-open f-number = EFL / EPD,
/// paraxial image plane).
pub fn first_order(system: &SystemAt, focus_mm: Option<f64>) -> Result<Paraxial, ParaxialError> {
    // A table is focused on a real object; the analyses also take a virtual one (a converging
    // beam), which is no scene.
    if let Some(distance) = focus_mm.filter(|d| !(*d > 0.0)) {
        return Err(ParaxialError::ObjectNotInFront { distance });
    }
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

/// Why an object `distance` mm away (None: infinity) has no film plane behind the lens: it lies
/// inside the front focal length, so its image is virtual, or the image still falls inside the
/// lens (a rear focal point in front of the last vertex).
fn no_film_plane(distance: Option<f64>, film_z: f64, rear_z: f64, first: &Paraxial) -> BakeError {
    let front_focal_mm = -first.first_order.z_front_focal;
    match distance {
        Some(distance_mm) if distance_mm <= front_focal_mm => BakeError::CannotFocus(CannotFocus {
            distance_mm,
            front_focal_mm,
        }),
        _ => BakeError::ImageInsideLens(ImageInsideLens {
            focus: distance_text(distance),
            film_z,
            last_vertex_z: rear_z,
        }),
    }
}

/// Refuses a table over the node limit or larger than the memory available, before the bake
/// allocates it (the entries, then the same again while the file is encoded).
fn check_size(resolution: [usize; 3], layers: usize) -> Result<(), crate::limits::LimitError> {
    use crate::limits;
    let nodes = limits::product(&[
        resolution[0] as u64,
        resolution[1] as u64,
        resolution[2] as u64,
        layers as u64,
    ]);
    limits::check(
        "the table's node count (all layers)",
        nodes,
        limits::MAX_TABLE_NODES,
    )?;
    let entry_bytes = (super::param::CHANNELS * std::mem::size_of::<f32>()) as u64;
    limits::check_memory("the table", limits::product(&[nodes, entry_bytes, 2]))
}

/// What a bake decides before it traces: every check that refuses a request, made in
/// milliseconds, so that a caller can report a bad request before it starts the long work's
/// progress ([`BakePlan::bake`] then traces).
pub struct BakePlan<'a> {
    system: &'a LensSystem,
    request: &'a BakeRequest,
    wavelengths: Vec<f64>,
    first: Paraxial,
    near_mm: Option<f64>,
    f_number: f64,
    stop_semi_aperture: f64,
    /// The design wavelength's image planes of the far and near focus.
    film_z: [f64; 2],
    /// The film radius covered on every film plane of the range.
    max_film_radius: f64,
    rear_z: f64,
}

impl<'a> BakePlan<'a> {
    pub fn new(
        system: &'a LensSystem,
        request: &'a BakeRequest,
    ) -> Result<BakePlan<'a>, BakeError> {
        if request.resolution.iter().any(|&n| n < 2) {
            return Err(BakeError::Resolution(request.resolution));
        }
        if !system.images_behind() {
            return Err(BakeError::ImageInFront);
        }
        let wavelengths = if request.wavelengths_nm.is_empty() {
            vec![system.design_wavelength_nm()]
        } else {
            request.wavelengths_nm.clone()
        };
        if wavelengths.len() != 1 && wavelengths.len() != 3 {
            return Err(BakeError::WavelengthCount(wavelengths.len()));
        }
        check_size(request.resolution, wavelengths.len())?;
        // Every layer is traced through `stopped_down`, which trusts the wavelength: refuse the
        // ones where a medium's dispersion formula no longer gives an index.
        for &nm in &wavelengths {
            system.at_checked(nm)?;
        }
        let design = system.at_checked(system.design_wavelength_nm())?;
        let near_mm = request.focus_near_mm.or(request.focus_mm);
        if let (Some(near), far) = (near_mm, request.focus_mm)
            && far.is_some_and(|far| near > far)
        {
            return Err(BakeError::FocusOrder {
                far: distance_text(far),
                near: distance_text(Some(near)),
            });
        }
        let first = first_order(&design, request.focus_mm)?;
        first.first_order.require_converging()?;
        let wide_open = first.f_number;
        let f_number = request.f_number.unwrap_or(wide_open);
        if f_number < wide_open * (1.0 - 1e-9) {
            return Err(BakeError::FNumber {
                asked: f_number,
                wide_open,
            });
        }
        // The stop scales as 1 / f-number (the entrance pupil is its paraxial image).
        crate::limits::check_f_number(f_number, wide_open)?;
        let stop_semi_aperture = design.surfaces[design.stop].semi_aperture * wide_open / f_number;
        // One physical film plane per focus for every wavelength: the design wavelength's image
        // plane. The far focus's is the table's reference plane; the near focus's lies behind it.
        let film_z = [first.z_image, first_order(&design, near_mm)?.z_image];
        let rear_z = design.last_vertex_z();
        for (distance, z) in [request.focus_mm, near_mm].into_iter().zip(film_z) {
            if !first.first_order.ahead_of_last_vertex(z) {
                return Err(no_film_plane(distance, z, rear_z, &first));
            }
        }
        // The table's first node, the film centre, needs light; one fit tells (a lens that
        // passes none was refused only once the bake's progress had begun).
        let stopped = stopped_down(system, system.design_wavelength_nm(), stop_semi_aperture);
        let design_tracer = Tracer::new(&stopped);
        let search = rear_search_radius(&stopped);
        let centre = fit_film_pupil(&design_tracer, film_z[0], search, &request.pupil_fit, 0.0);
        if centre.is_none_or(|circle| circle.radius <= 0.0) {
            return Err(BakeError::NothingPasses { film_radius: 0.0 });
        }
        // The near focus magnifies: the widest of the range's film planes is the one covered.
        let max_film_radius = match request.max_film_radius {
            Some(radius) if radius > 0.0 => radius,
            Some(radius) => return Err(BakeError::FilmRadius(radius)),
            None => film_z
                .map(|z| chief_ray_film_radius(&design_tracer, &design, z))
                .into_iter()
                .fold(0.0, f64::max),
        };
        if max_film_radius <= 0.0 {
            return Err(BakeError::NoChiefRay { film_z: film_z[0] });
        }
        Ok(BakePlan {
            system,
            request,
            wavelengths,
            first,
            near_mm,
            f_number,
            stop_semi_aperture,
            film_z,
            max_film_radius,
            rear_z,
        })
    }

    /// Bakes the planned table; `progress` is called from worker threads as nodes complete.
    pub fn bake(self, progress: &(dyn Fn(BakeProgress) + Sync)) -> Result<LrtfTable, BakeError> {
        let BakePlan {
            system,
            request,
            wavelengths,
            first,
            near_mm,
            f_number,
            stop_semi_aperture,
            film_z,
            max_film_radius,
            rear_z,
        } = self;
        let nodes_per_layer: usize = request.resolution.iter().product();
        let total = nodes_per_layer * wavelengths.len();
        let done = AtomicUsize::new(0);
        let mut layers = Vec::with_capacity(wavelengths.len());
        for &wavelength_nm in &wavelengths {
            let at = stopped_down(system, wavelength_nm, stop_semi_aperture);
            let tracer = Tracer::new(&at);
            let search = rear_search_radius(&at);
            let fit = |film_radius: f64, z: f64| {
                fit_film_pupil(&tracer, z, search, &request.pupil_fit, film_radius)
            };
            let pupil_nodes = request.pupil_nodes.unwrap_or(request.resolution[0]);
            // Pupils fitted between nodes make the interpolated circles conservative. From 64 nodes
            // on an interval spans under 2 % of the film radius and one check at its middle, where a
            // linear interpolant strays furthest from a smooth curve, suffices (measured: no passing
            // ray outside the circle over 200k rays for the three bundled test lenses).
            let between = |nodes: usize| if nodes >= 64 { 1 } else { 2 };
            let (pupil, sampling) = if film_z[1] > film_z[0] {
                let sampling_nodes = pupil_nodes.min(SAMPLING_RADIUS_NODES);
                let sampling = pupil::build_focus_table(
                    &fit,
                    max_film_radius,
                    sampling_nodes,
                    between(sampling_nodes),
                    film_z,
                    &request.focus_nodes,
                );
                let reach = reference_film_radius(&sampling, rear_z);
                let pupil = pupil::build_table(
                    &|r| fit(r, film_z[0]),
                    reach,
                    pupil_nodes,
                    between(pupil_nodes),
                );
                (pupil, sampling)
            } else {
                let pupil = pupil::build_table(
                    &|r| fit(r, film_z[0]),
                    max_film_radius,
                    pupil_nodes,
                    between(pupil_nodes),
                );
                let sampling = FocusPupilTable::single(film_z[0], pupil.clone());
                (pupil, sampling)
            };
            if pupil.circles[0].radius <= 0.0 {
                return Err(BakeError::NothingPasses { film_radius: 0.0 });
            }
            let max_rear_radius = pupil.max_extent();
            let reach = pupil.max_film_radius;
            let depth = film_z[0] - rear_z;
            let frame = Frame {
                rear_plane_z: rear_z,
                film_plane_z: film_z[0],
                max_film_radius: reach,
                max_rear_radius,
                max_polar_angle: ((max_rear_radius + reach) / depth).atan(),
            };
            let entries = bake_entries(request, &tracer, &frame, &pupil, &|n| {
                let d = done.fetch_add(n, Ordering::Relaxed) + n;
                progress(BakeProgress { done: d, total });
            });
            layers.push(Layer {
                wavelength_nm,
                frame,
                pupil,
                sampling,
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
                focus: FocusRange::new(&first.first_order, request.focus_mm, near_mm),
            },
            layers,
        })
    }
}

/// Bakes the table `request` asks for (every field has a default: [`BakeRequest::default`] is
/// a 128³ f32 table of the design wavelength, wide open, focused at infinity).
///
/// ```
/// use lensbake::{BakeRequest, LoadOptions, bake, load_lens};
///
/// let lens = load_lens("dgauss-50mm", &LoadOptions::default())?;
/// let table = bake(&lens.system, &BakeRequest { resolution: [8; 3], ..BakeRequest::default() })?;
/// assert_eq!(table.layers.len(), 1);
/// # Ok::<(), Box<dyn std::error::Error>>(())
/// ```
pub fn bake(system: &LensSystem, request: &BakeRequest) -> Result<LrtfTable, BakeError> {
    bake_with_progress(system, request, &|_| {})
}

/// [`bake`], calling `progress` from worker threads as nodes complete (for a progress bar).
pub fn bake_with_progress(
    system: &LensSystem,
    request: &BakeRequest,
    progress: &(dyn Fn(BakeProgress) + Sync),
) -> Result<LrtfTable, BakeError> {
    BakePlan::new(system, request)?.bake(progress)
}

/// Film-radius nodes of a focus range's sampling pupil (the table's own count when smaller): 64
/// nodes keep each interval under 2 % of the film radius, and its film planes cost a fit per
/// node each.
const SAMPLING_RADIUS_NODES: usize = 64;

/// Relative room added to [`reference_film_radius`] for the film planes between its samples.
const REFERENCE_REACH_MARGIN: f64 = 0.005;

/// How far from the axis the rays of a focus range cross the reference (far-focus) film plane:
/// the largest |(1 - s) r + s c| + s R over film radius r, the sampling pupil's circle (c, R) of
/// that film radius and plane, and s = (z - z_ref) / (z - z_rear), the fraction of the way from
/// the film point at z to the rear plane at which the reference plane lies. On one film plane c
/// and R are linear in r inside every radius interval, so the expression is convex there and
/// the nodes bound it; across film planes it is sampled eight times per focus interval, with
/// [`REFERENCE_REACH_MARGIN`] on top.
fn reference_film_radius(sampling: &FocusPupilTable, rear_z: f64) -> f64 {
    let z_ref = sampling.film_z[0];
    let planes = 8 * sampling.nodes.len().max(2);
    let radius_nodes = sampling.nodes[0].circles.len();
    let max_r = sampling.max_film_radius();
    let mut reach: f64 = max_r;
    for i in 0..=planes {
        let z = sampling.film_z[0]
            + (sampling.film_z[1] - sampling.film_z[0]) * i as f64 / planes as f64;
        let s = (z - z_ref) / (z - rear_z);
        for k in 0..radius_nodes {
            let r = max_r * k as f64 / (radius_nodes - 1).max(1) as f64;
            let c = sampling.circle_at(r, z);
            reach = reach.max(((1.0 - s) * r + s * c.centre_x).abs() + s * c.radius);
        }
    }
    reach * (1.0 + REFERENCE_REACH_MARGIN)
}

/// The aperture margin of lanes traced with apertures ignored, accumulated surface by surface:
/// the smallest (semi-aperture - hit radius) / semi-aperture over every surface but a circular
/// stop (the sampler tests that one against the stored stop crossing), at a bladed stop the
/// blades' margin over the stop's semi-aperture too, and at a central obscuration (hit radius -
/// obscuration radius) / semi-aperture, on the stop as well. It is continuous across every vignetting
/// edge and zero on it, so its interpolant places the edge to second order in the cell size
/// where a thresholded 0/1 flag places it only to first order.
struct ApertureMargins<'a> {
    tracer: &'a Tracer,
    /// 1 / semi-aperture per surface (0-based).
    inverse_semi_aperture: Vec<f64>,
    /// Central obscuration radius per surface (0 for none).
    obscuration: Vec<f64>,
    stop: usize,
    margin: [f64; LANES],
    /// Stop-plane crossing of each lane (x, y).
    stop_point: [[f64; 2]; LANES],
}

impl<'a> ApertureMargins<'a> {
    fn new(tracer: &'a Tracer) -> ApertureMargins<'a> {
        ApertureMargins {
            tracer,
            inverse_semi_aperture: (0..tracer.surface_count())
                .map(|i| 1.0 / tracer.semi_aperture(i))
                .collect(),
            obscuration: (0..tracer.surface_count())
                .map(|i| tracer.obscuration(i))
                .collect(),
            stop: tracer.stop_surface() - 1,
            margin: [f64::INFINITY; LANES],
            stop_point: [[0.0; 2]; LANES],
        }
    }

    fn reset(&mut self) {
        self.margin = [f64::INFINITY; LANES];
    }
}

impl LaneVisitor for ApertureMargins<'_> {
    #[inline(always)]
    fn crossed(&mut self, surface: usize, ids: &[u32], travelling: Slots, x: &[f64], y: &[f64]) {
        let inverse = self.inverse_semi_aperture[surface];
        let obscuration = self.obscuration[surface];
        for slot in (0..ids.len()).filter(|&slot| travelling.contains(slot)) {
            let (l, x, y) = (ids[slot] as usize, x[slot], y[slot]);
            let radius = (x * x + y * y).sqrt();
            let mut margin = self.margin[l];
            if obscuration > 0.0 {
                margin = margin.min((radius - obscuration) * inverse);
            }
            if surface == self.stop {
                self.stop_point[l] = [x, y];
                // A circular stop is tested against the stored crossing, not the margin.
                let Some(blades) = self.tracer.blade_margin(x, y) else {
                    self.margin[l] = margin;
                    continue;
                };
                margin = margin.min(blades * inverse);
            }
            margin = margin.min(1.0 - radius * inverse);
            self.margin[l] = margin;
        }
    }
}

/// Traces every node's film-side ray once, with apertures ignored, [`LANES`] at a time: the
/// geometric continuation, the stop crossing and the aperture margin all come from that one
/// trace (a ray passes exactly when its continuation crosses every surface inside its clear
/// aperture).
fn bake_entries(
    request: &BakeRequest,
    tracer: &Tracer,
    frame: &Frame,
    pupil: &PupilTable,
    report: &(dyn Fn(usize) + Sync),
) -> Entries {
    let [n0, n1, n2] = request.resolution;
    let param = request.parameterisation;
    let node = |k: usize, n: usize| k as f64 / (n - 1) as f64;
    let slab = n0 * n1;
    let mut entries = vec![[0.0f32; CHANNELS]; slab * n2];
    let mut defined = vec![false; slab * n2];
    // One work item per i2 slab, written in place.
    entries
        .par_chunks_mut(slab)
        .zip(defined.par_chunks_mut(slab))
        .enumerate()
        .for_each(|(i2, (entries, defined))| {
            let mut margins = ApertureMargins::new(tracer);
            let mut group: Vec<(usize, crate::trace::Ray)> = Vec::with_capacity(LANES);
            for k in 0..slab {
                let coords = [node(k % n0, n0), node(k / n0, n1), node(i2, n2)];
                let ray = param.ray_at(frame, pupil, coords);
                if let Ok(ray) = crate::trace::Ray::new(ray.origin, ray.direction) {
                    group.push((k, ray));
                }
                if group.len() < LANES && k + 1 < slab {
                    continue;
                }
                let mut rays = [crate::trace::Ray::ALONG_AXIS; LANES];
                for (ray, g) in rays.iter_mut().zip(&group) {
                    *ray = g.1;
                }
                margins.reset();
                let mut exits = [None; LANES];
                tracer.trace_group_visiting(
                    &rays[..group.len()],
                    Travel::Backward,
                    false,
                    &mut margins,
                    &mut |l, traced| exits[l] = traced.outcome.is_ok().then_some(traced.ray),
                );
                for (l, &(k, _)) in group.iter().enumerate() {
                    let Some(exit) = exits[l] else {
                        continue;
                    };
                    let transfer = Transfer {
                        exit_point: exit.position(),
                        exit_direction: exit.direction(),
                        stop_point: margins.stop_point[l],
                    };
                    entries[k] = param.encode(&transfer, margins.margin[l]).map(|v| v as f32);
                    defined[k] = true;
                }
                group.clear();
            }
            report(slab);
        });
    fill_holes(&mut entries, &mut defined, request.resolution);
    Entries::from_row_major(request.resolution, request.precision, &entries)
}

/// Smallest margin a hole gets, so that it reads as blocked even where its neighbours' margins
/// average to zero (and after rounding to f16).
const HOLE_MARGIN: f32 = 1e-3;

/// Gives every node without a transfer (even the unapertured ray failed, so the ray is blocked)
/// the mean of its defined face neighbours, growing inwards from the defined region, with the
/// margin made negative (same size), so a hole reads as blocked.
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
                        mean[MARGIN] = -mean[MARGIN].abs().max(HOLE_MARGIN);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::prescription::StopShape;

    fn dgauss(stop_shape: StopShape) -> LensSystem {
        let mut prescription = crate::lenses::load("dgauss-50mm", &Default::default())
            .expect("bundled double Gauss")
            .system
            .prescription;
        for surface in &mut prescription.surfaces {
            if surface.stop.is_some() {
                surface.stop = Some(stop_shape.clone());
            }
        }
        LensSystem::from_prescription(prescription).expect("still a valid lens")
    }

    /// Every node of a small table against the one-ray oracle [`exact_transfer`]: the lane trace
    /// stores the same continuation bit for bit, and the margin's sign with the stop-crossing
    /// test says exactly whether the apertured trace passes (circular and bladed stops).
    #[test]
    fn lane_traced_nodes_match_the_one_ray_trace_and_the_margin_sign_is_passing() {
        let bladed = StopShape::Blades {
            count: 6,
            rotation_deg: 10.0,
            blade_curvature: 0.3,
        };
        for stop_shape in [StopShape::Circle, bladed] {
            let system = dgauss(stop_shape.clone());
            let request = BakeRequest {
                resolution: [9, 11, 7],
                ..BakeRequest::default()
            };
            let table = bake(&system, &request).unwrap();
            let layer = &table.layers[0];
            let at = stopped_down(&system, layer.wavelength_nm, layer.stop_semi_aperture);
            let tracer = Tracer::new(&at);
            let [n0, n1, n2] = request.resolution;
            let (mut passing, mut blocked, mut holes) = (0, 0, 0);
            for i2 in 0..n2 {
                for i1 in 0..n1 {
                    for i0 in 0..n0 {
                        let coords = [
                            i0 as f64 / (n0 - 1) as f64,
                            i1 as f64 / (n1 - 1) as f64,
                            i2 as f64 / (n2 - 1) as f64,
                        ];
                        let ray =
                            request
                                .parameterisation
                                .ray_at(&layer.frame, &layer.pupil, coords);
                        let entry = layer.entries.get([i0, i1, i2]);
                        let (exact, passes) = exact_transfer(&tracer, &ray);
                        let Some(exact) = exact else {
                            assert!(entry[MARGIN] < 0.0, "{stop_shape:?} hole at {coords:?}");
                            holes += 1;
                            continue;
                        };
                        let stored = request
                            .parameterisation
                            .encode(&exact, f64::from(entry[MARGIN]))
                            .map(|v| v as f32);
                        assert_eq!(stored, entry, "{stop_shape:?} at {coords:?}");
                        let stop = exact.stop_point;
                        let inside_stop = stop[0] * stop[0] + stop[1] * stop[1]
                            <= layer.stop_semi_aperture * layer.stop_semi_aperture;
                        if entry[MARGIN].abs() > 1e-6 {
                            assert_eq!(
                                entry[MARGIN] >= 0.0 && inside_stop,
                                passes,
                                "{stop_shape:?} at {coords:?}: margin {}",
                                entry[MARGIN]
                            );
                        }
                        if passes {
                            passing += 1;
                        } else {
                            blocked += 1;
                        }
                    }
                }
            }
            // The table spans passing and blocked rays (the pupil circle bounds a vignetted
            // pupil), so both branches were checked.
            assert!(passing > 50 && blocked > 50, "{passing} {blocked} {holes}");
        }
    }
}
