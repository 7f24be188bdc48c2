//! Exact sequential ray trace in f64.
//!
//! A [`Tracer`] is a [`SystemAt`] (the lens at one wavelength) flattened into one small array of
//! surfaces with everything the inner loop needs precomputed. The same array serves both travel
//! directions: forward rays start in object space travelling +z and meet surfaces 1..N; backward
//! rays start on the film side travelling -z (the renderer's direction, as in pbrt) and meet
//! surfaces N..1 with the media on each side swapped.
//!
//! Every ray ends with a typed [`Outcome`]. At each surface the tracer intersects (a miss is
//! [`Outcome::Missed`]), checks the hit against the clear semi-aperture and, on the stop, the
//! diaphragm's shape (outside is [`Outcome::Vignetted`]), and only then refracts (a negative
//! Snell radicand is [`Outcome::Tir`]). Every intermediate value that could turn into NaN or
//! infinity is tested before it is used, so no NaN ever leaves the tracer.

mod aim;
pub mod analyses;
mod aperture;
mod batch;
mod bundle;
mod intersect;
mod lanes;
pub mod placed;
mod refract;

pub use aim::{
    AimError, RaySource, StopAim, aim_at_stop, traceable_field_deg, traceable_field_deg_from,
};
pub use batch::{BatchTrace, RayBatch, RowResults, RowsError};
#[cfg(any(test, feature = "render"))]
pub(crate) use batch::{GROUP_RAYS, GroupBlock};
pub use bundle::FieldBundle;
pub(crate) use bundle::UnitDraws;
#[cfg(feature = "render")]
pub(crate) use intersect::ASPHERE_MAX_STEPS;
pub(crate) use intersect::{cross, dot, normalised};
pub(crate) use lanes::{Isa, LANES, LaneVisitor, NoVisit, Slots, with_widest_isa};

use crate::paraxial::Pupil;
use crate::prescription::Shape;
use crate::system::{LensSystem, SystemAt};
use aperture::Diaphragm;
use intersect::{AsphereTerms, Profile};

/// A point or direction in the lens frame (mm; z along the axis, origin at surface 1's vertex).
pub type Vec3 = [f64; 3];

/// A ray: a finite position and a unit direction, both in the lens frame. The crate's public
/// ray ([`crate::Ray`]); [`crate::lrtf::Ray`] is the sampler's unchecked form of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    position: Vec3,
    direction: Vec3,
}

/// Why a ray could not be built.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RayError {
    #[error("ray {what} {value:?} has a component that is not a finite number")]
    NonFinite { what: &'static str, value: Vec3 },
    #[error("ray direction {0:?} has zero length")]
    ZeroDirection(Vec3),
    #[error(
        "ray starts at z = {z} mm, {} surface {surface} (z = {surface_z} mm at its height): a {} ray must start {} the lens",
        if *.forward { "behind" } else { "in front of" },
        if *.forward { "forward" } else { "backward" },
        if *.forward { "in front of" } else { "behind" }
    )]
    StartsInside {
        z: f64,
        surface: usize,
        surface_z: f64,
        forward: bool,
    },
}

/// Refuses a ray that starts on the wrong side of the lens for its travel: a forward ray must
/// start in front of surface 1 (at or below its z at the ray's height, the rim's z beyond the
/// clear aperture), a backward ray behind the last surface. The tracer looks only for crossings
/// ahead of the ray, so a ray starting inside the glass would otherwise be traced as if it
/// started outside. For many rays, [`StartCheck`] finds what the check needs once.
pub fn check_start(system: &SystemAt, ray: &Ray, travel: Travel) -> Result<(), RayError> {
    StartCheck::new(system, travel).check(ray)
}

/// [`check_start`] for the rays of one system and travel.
pub struct StartCheck<'a> {
    /// The surface a ray must start outside of, 0-based, with its index; None without surfaces.
    surface: Option<(usize, &'a crate::system::SurfaceAt)>,
    forward: bool,
    /// +1 where a ray must start at a larger z than the surface's, -1 at a smaller one.
    side: f64,
    /// A ray whose z is at least this far to its side (`side * z >= admitted_beyond`) starts
    /// outside at any height: the surface's sag is bounded there ([`Shape::sag_bound`]). Most
    /// rays pass here without the sag's square root and division (a 1M-ray check took as long
    /// as a third of the trace).
    admitted_beyond: f64,
}

impl<'a> StartCheck<'a> {
    pub fn new(system: &'a SystemAt, travel: Travel) -> StartCheck<'a> {
        let forward = travel == Travel::Forward;
        let index = if forward {
            0
        } else {
            system.surfaces.len().saturating_sub(1)
        };
        // Light leaving the last surface travels +z unless an odd number of mirrors turned it.
        let side = if forward {
            -1.0
        } else {
            system.image_index().signum()
        };
        let surface = system.surfaces.get(index);
        let admitted_beyond = surface
            .and_then(|s| {
                let bound = s.shape.sag_bound(s.geometric_semi_aperture)?;
                // Beyond the largest z the sum vertex + sag can round to.
                let slack = 1e-9 * (bound + s.vertex_z.abs());
                Some(side * s.vertex_z + bound + slack)
            })
            .unwrap_or(f64::INFINITY);
        StartCheck {
            surface: surface.map(|s| (index, s)),
            forward,
            side,
            admitted_beyond,
        }
    }

    #[inline]
    pub fn check(&self, ray: &Ray) -> Result<(), RayError> {
        if self.side * ray.position[2] >= self.admitted_beyond {
            return Ok(());
        }
        self.check_at_height(ray)
    }

    /// [`StartCheck::check`] of a ray near the surface: against its z at the ray's height.
    fn check_at_height(&self, ray: &Ray) -> Result<(), RayError> {
        let [x, y, z] = ray.position;
        let Some((index, surface)) = self.surface else {
            return Ok(());
        };
        // Not `hypot`, whose care for overflow cost most of a 1M-ray check: a square that
        // overflows gives an infinite height, which the clamp to the rim handles alike.
        let height = (x * x + y * y).sqrt().min(surface.geometric_semi_aperture);
        let surface_z = surface.vertex_z + surface.shape.sag(height).unwrap_or(0.0);
        if (z - surface_z) * self.side < 0.0 {
            return Err(RayError::StartsInside {
                z,
                surface: index + 1,
                surface_z,
                forward: self.forward,
            });
        }
        Ok(())
    }
}

/// What a rows trace ([`Tracer::trace_rows_into`]) asks of each ray before tracing it: a
/// [`StartCheck`], or any `Fn(&Ray) -> Result<(), RayError>` (`|_: &Ray| Ok(())` admits every ray).
pub trait Admit: Sync {
    /// Ok where the ray may be traced; the reason where not.
    fn admit(&self, ray: &Ray) -> Result<(), RayError>;

    /// `(side, beyond)` where every ray with `side * z >= beyond` is admitted whatever the
    /// rest of it: a block of such rays then passes on one vector compare of its z column,
    /// without a call per ray. None where no such bound is known.
    fn admitted_beyond(&self) -> Option<(f64, f64)> {
        None
    }
}

impl<F: Fn(&Ray) -> Result<(), RayError> + Sync> Admit for F {
    #[inline(always)]
    fn admit(&self, ray: &Ray) -> Result<(), RayError> {
        self(ray)
    }
}

impl Admit for StartCheck<'_> {
    #[inline(always)]
    fn admit(&self, ray: &Ray) -> Result<(), RayError> {
        self.check(ray)
    }

    fn admitted_beyond(&self) -> Option<(f64, f64)> {
        Some((self.side, self.admitted_beyond))
    }
}

impl Ray {
    /// From the origin along +z: a filler for fixed-size arrays of rays.
    pub(crate) const ALONG_AXIS: Ray = Ray {
        position: [0.0; 3],
        direction: [0.0, 0.0, 1.0],
    };

    /// A ray from `position` along `direction` (any non-zero length; it is normalised).
    #[inline]
    pub fn new(position: Vec3, direction: Vec3) -> Result<Ray, RayError> {
        match Ray::common_length(position, direction) {
            // Dividing by a length of exactly 1 leaves the direction as it is.
            (length, true) => Ok(Ray {
                position,
                direction: direction.map(|v| v / length),
            }),
            (_, false) => Ray::new_careful(position, direction),
        }
    }

    /// The direction's length, and whether the ray is a common one, which [`Ray::new`]
    /// normalises by one division per component: every component finite (their sum times 0 is
    /// 0 only then; finite parts that sum past f64::MAX also go the careful way) and a squared
    /// length that neither overflows nor is zero or subnormal. The others go to
    /// [`Ray::new_careful`]. Without a branch, so a loop over many rays can run it in vector
    /// lanes (see `load_rows` in the batch trace); the length of an uncommon ray means nothing.
    #[inline(always)]
    pub(crate) fn common_length(position: Vec3, direction: Vec3) -> (f64, bool) {
        let [px, py, pz] = position;
        let [dx, dy, dz] = direction;
        let finite = (px + py + pz + dx + dy + dz) * 0.0 == 0.0;
        let length_sq = dot(direction, direction);
        // `is_normal` for a square, which is never negative; NaN fails both comparisons. Two
        // compares joined by `&`, not a range's `contains`, to say the loop has no branch.
        #[allow(clippy::manual_range_contains)]
        let normal = (length_sq >= f64::MIN_POSITIVE) & (length_sq <= f64::MAX);
        (length_sq.sqrt(), finite & normal)
    }

    /// [`Ray::new`] for any input: refuses what is not finite or has no length, and normalises
    /// directions whose squared length overflows or underflows.
    #[cold]
    pub(crate) fn new_careful(position: Vec3, direction: Vec3) -> Result<Ray, RayError> {
        for (what, value) in [("position", position), ("direction", direction)] {
            if !value.iter().all(|v| v.is_finite()) {
                return Err(RayError::NonFinite { what, value });
            }
        }
        // Scaled first, so a direction such as (1e308, 0, 0) is not mistaken for zero length
        // when its squared length overflows.
        let largest = direction.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        if largest == 0.0 {
            return Err(RayError::ZeroDirection(direction));
        }
        let length = dot(direction, direction).sqrt();
        let direction = if length == 1.0 {
            direction
        } else if length.is_finite() && length > f64::MIN_POSITIVE {
            direction.map(|v| v / length)
        } else {
            let scaled = direction.map(|v| v / largest);
            let scaled_length = dot(scaled, scaled).sqrt();
            scaled.map(|v| v / scaled_length)
        };
        Ok(Ray {
            position,
            direction,
        })
    }

    /// A ray from parts already known to be finite with a unit direction.
    pub(crate) fn from_parts(position: Vec3, direction: Vec3) -> Ray {
        Ray {
            position,
            direction,
        }
    }

    pub fn position(&self) -> Vec3 {
        self.position
    }

    /// Unit direction cosines.
    pub fn direction(&self) -> Vec3 {
        self.direction
    }

    /// Where the ray's line crosses the plane z = `z`; None when it runs parallel to the plane.
    pub fn point_at_z(&self, z: f64) -> Option<Vec3> {
        let t = (z - self.position[2]) / self.direction[2];
        t.is_finite().then(|| {
            [
                self.position[0] + t * self.direction[0],
                self.position[1] + t * self.direction[1],
                z,
            ]
        })
    }
}

/// How a ray's trace ended. Surfaces are numbered 1..N from the object side, whatever the
/// travel direction. Serialises as {"status": "ok"} or {"status": "vignetted", "surface": 3}.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(tag = "status", rename_all = "lowercase")]
pub enum Outcome {
    /// Crossed every surface.
    Ok,
    /// Hit `surface` outside its clear semi-aperture (or, at the stop, outside the blades).
    Vignetted { surface: usize },
    /// Total internal reflection at `surface`.
    Tir { surface: usize },
    /// No crossing with `surface` in the travel sense (the line misses it, or meets only the
    /// far sheet of a sphere or conic, or an asphere search failed).
    Missed { surface: usize },
}

/// As a sentence's end: `vignetted at surface 3`, `missed surface 9`.
impl std::fmt::Display for Outcome {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Outcome::Ok => f.write_str("crossed every surface"),
            Outcome::Vignetted { surface } => write!(f, "vignetted at surface {surface}"),
            Outcome::Tir { surface } => {
                write!(f, "totally internally reflected at surface {surface}")
            }
            Outcome::Missed { surface } => write!(f, "missed surface {surface}"),
        }
    }
}

impl Outcome {
    pub fn is_ok(self) -> bool {
        self == Outcome::Ok
    }

    /// The surface where the ray stopped; None for [`Outcome::Ok`].
    pub fn surface(self) -> Option<usize> {
        match self {
            Outcome::Ok => None,
            Outcome::Vignetted { surface }
            | Outcome::Tir { surface }
            | Outcome::Missed { surface } => Some(surface),
        }
    }

    /// [`Outcome::code`] of [`Outcome::Ok`].
    pub const CODE_OK: u8 = 0;
    /// [`Outcome::code`] of [`Outcome::Vignetted`].
    pub const CODE_VIGNETTED: u8 = 1;
    /// [`Outcome::code`] of [`Outcome::Tir`].
    pub const CODE_TIR: u8 = 2;
    /// [`Outcome::code`] of [`Outcome::Missed`].
    pub const CODE_MISSED: u8 = 3;

    /// The outcome as two plain numbers, for arrays handed to other languages (NumPy, C): its
    /// kind ([`Outcome::CODE_OK`] ..) and the 1-based surface where the ray stopped (0 for ok).
    pub fn code(self) -> (u8, u32) {
        let (kind, surface) = match self {
            Outcome::Ok => (Outcome::CODE_OK, 0),
            Outcome::Vignetted { surface } => (Outcome::CODE_VIGNETTED, surface),
            Outcome::Tir { surface } => (Outcome::CODE_TIR, surface),
            Outcome::Missed { surface } => (Outcome::CODE_MISSED, surface),
        };
        // Surfaces are numbered below limits::MAX_SURFACES, far inside u32.
        (kind, surface as u32)
    }

    /// Lower-case name used in JSON output: ok, vignetted, tir, missed.
    pub fn status(self) -> &'static str {
        match self {
            Outcome::Ok => "ok",
            Outcome::Vignetted { .. } => "vignetted",
            Outcome::Tir { .. } => "tir",
            Outcome::Missed { .. } => "missed",
        }
    }
}

/// Which way rays run through the lens.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Travel {
    /// Object space to image space (+z), surfaces 1..N.
    Forward,
    /// Image space to object space (-z), surfaces N..1: the renderer's direction.
    Backward,
}

/// Whether clear apertures and the stop shape stop rays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Apertures {
    #[default]
    Checked,
    /// Pure geometry: rays pass any height a surface exists at (for aiming and diagnostics).
    Ignored,
}

/// A traced ray. For [`Outcome::Ok`] `ray` is the ray just after the last surface crossed
/// (surface N forward, surface 1 backward). For vignetting and TIR it is the hit point on the
/// surface where it happened with the direction arriving there; for a miss it is the ray after
/// the last surface it did cross (the input ray if that was none).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Traced {
    pub outcome: Outcome,
    pub ray: Ray,
}

/// One surface crossed on a recorded path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Crossing {
    /// 1-based surface number.
    pub surface: usize,
    /// Hit point in the lens frame.
    pub point: Vec3,
    /// Unit direction after refraction.
    pub direction: Vec3,
}

/// A traced ray with every surface it crossed, in travel order.
#[derive(Clone, Debug, PartialEq)]
pub struct TracedPath {
    pub traced: Traced,
    pub crossings: Vec<Crossing>,
}

/// The wavelengths (nm) of [`rgb_tracers`]: the ISO 7944 secondary lines F' (cadmium, blue),
/// e (mercury, green) and C' (cadmium, red), in R, G, B order. They are the standard lens-design
/// lines of the visible band, near the dominant wavelengths of sRGB's primaries, and catalogue
/// glasses quote indices at exactly these lines.
pub const RGB_WAVELENGTHS_NM: [f64; 3] = [643.8469, 546.0740, 479.9914];

/// One tracer per colour channel at [`RGB_WAVELENGTHS_NM`], for rendering lateral and axial
/// colour.
pub fn rgb_tracers(system: &LensSystem) -> [Tracer; 3] {
    RGB_WAVELENGTHS_NM.map(|nm| Tracer::new(&system.at(nm)))
}

/// The relative margin (16 f64 ulps) by which a hit's squared radius may exceed the squared
/// clear semi-aperture and still pass. A ray aimed at the rim (a spot diagram's outer ring, a
/// marginal ray through a stop at the first surface) arrives there within a few ulps either side,
/// so without it the rounding of its last digits decided whether it passed, and a change in
/// the order of operations moved a spot diagram's edge rays in and out (1.8e-14 mm at a 10 mm
/// rim: no ray a physical aperture would treat differently).
const RIM_ROUNDING: f64 = 16.0 * f64::EPSILON;

/// One surface as the inner loop reads it.
#[derive(Clone, Copy, Debug, PartialEq)]
struct FlatSurface {
    vertex_z: f64,
    profile: Profile,
    /// The clear semi-aperture (mm).
    semi_aperture: f64,
    /// The squared radius a hit may reach: the clear semi-aperture's square widened by
    /// [`RIM_ROUNDING`].
    semi_aperture_sq: f64,
    /// [`crate::system::SurfaceAt::geometric_semi_aperture`]: where the shape ends, whatever
    /// the stop is closed to.
    geometric_semi_aperture: f64,
    /// Physical (positive) indices on each side.
    index_before: f64,
    index_after: f64,
    /// n_before / n_after, the Snell ratio going forward (its inverse going backward).
    mu_forward: f64,
    mu_backward: f64,
    /// Whether the stop's blades must be tested here.
    bladed: bool,
    /// Whether the surface reflects instead of refracting.
    reflects: bool,
    /// Squared radius of the central obscuration (0 for none).
    obscuration_sq: f64,
    /// Sense along z (+1 or -1) in which a forward ray meets this surface; a backward ray meets
    /// it in `sense_backward`, the opposite of the forward ray's sense on leaving it.
    sense_forward: f64,
    sense_backward: f64,
}

impl FlatSurface {
    /// The sense along z (+1 or -1) in which a ray travelling forward (`FORWARD`) or backward
    /// meets the surface.
    #[inline(always)]
    fn sense<const FORWARD: bool>(&self) -> f64 {
        if FORWARD {
            self.sense_forward
        } else {
            self.sense_backward
        }
    }
}

/// A lens at one wavelength, flattened for tracing.
#[derive(Clone, Debug, PartialEq)]
pub struct Tracer {
    surfaces: Vec<FlatSurface>,
    asphere_terms: Vec<AsphereTerms>,
    diaphragm: Option<Diaphragm>,
    /// 0-based stop index.
    stop: usize,
    /// The stop's paraxial image in object space; None when it lies at infinity.
    stop_image: Option<StopImage>,
    wavelength_nm: f64,
}

/// The paraxial entrance pupil as [`crate::paraxial::entrance_pupil`] gives it: its z, and the
/// scale that maps stop heights to pupil heights (divide by it).
#[derive(Clone, Copy, Debug, PartialEq)]
struct StopImage {
    z: f64,
    scale: f64,
}

impl Tracer {
    pub fn new(system: &SystemAt) -> Tracer {
        let mut asphere_terms = Vec::new();
        let mut diaphragm = None;
        let surfaces = system
            .path()
            .map(|(i, s, index_before, index_after)| {
                // The signed indices say which way light travels on each side.
                let (sense_forward, sense_backward) =
                    (index_before.signum(), -index_after.signum());
                let (index_before, index_after) = (index_before.abs(), index_after.abs());
                let profile = profile_of(
                    &s.shape,
                    2.0 * s.geometric_semi_aperture,
                    &mut asphere_terms,
                );
                let blades = s
                    .stop
                    .as_ref()
                    .and_then(|shape| Diaphragm::new(shape, s.semi_aperture));
                let bladed = blades.is_some();
                if bladed {
                    diaphragm = blades;
                }
                debug_assert!(!bladed || i == system.stop);
                FlatSurface {
                    vertex_z: s.vertex_z,
                    profile,
                    semi_aperture: s.semi_aperture,
                    semi_aperture_sq: s.semi_aperture * s.semi_aperture * (1.0 + RIM_ROUNDING),
                    geometric_semi_aperture: s.geometric_semi_aperture,
                    index_before,
                    index_after,
                    mu_forward: index_before / index_after,
                    mu_backward: index_after / index_before,
                    bladed,
                    reflects: s.mirror,
                    obscuration_sq: s.obscuration.map_or(0.0, |r| r * r),
                    sense_forward,
                    sense_backward,
                }
            })
            .collect();
        let stop_image = crate::paraxial::entrance_pupil(system, system.stop)
            .ok()
            .map(|(z, scale)| StopImage { z, scale });
        Tracer {
            surfaces,
            asphere_terms,
            diaphragm,
            stop: system.stop,
            stop_image,
            wavelength_nm: system.wavelength_nm,
        }
    }

    pub fn wavelength_nm(&self) -> f64 {
        self.wavelength_nm
    }

    /// This lens with its central obscurations removed, for reference rays. The chief ray of an
    /// obscured lens (a reflex lens, a Cassegrain) runs through the secondary mirror's shadow;
    /// design programs still trace it as the axis of the beam, through every clear aperture.
    /// Borrowed as it is when nothing is obscured.
    pub fn unobscured(&self) -> std::borrow::Cow<'_, Tracer> {
        if self.surfaces.iter().all(|s| s.obscuration_sq == 0.0) {
            return std::borrow::Cow::Borrowed(self);
        }
        let mut clear = self.clone();
        for s in &mut clear.surfaces {
            s.obscuration_sq = 0.0;
        }
        std::borrow::Cow::Owned(clear)
    }

    /// Number of surfaces N.
    pub fn surface_count(&self) -> usize {
        self.surfaces.len()
    }

    /// 1-based number of the stop surface.
    pub fn stop_surface(&self) -> usize {
        self.stop + 1
    }

    /// Whether the point (x, y) of the stop surface lies inside its clear semi-aperture and,
    /// for a bladed stop, inside the blades.
    pub fn stop_admits(&self, x: f64, y: f64) -> bool {
        let inside = x * x + y * y <= self.surfaces[self.stop].semi_aperture_sq;
        inside
            && self
                .diaphragm
                .as_ref()
                .is_none_or(|blades| blades.contains(x, y))
    }

    /// Lens-frame z of the last surface's vertex (the rear vertex plane).
    pub fn last_vertex_z(&self) -> f64 {
        self.surfaces.last().map_or(0.0, |s| s.vertex_z)
    }

    /// Clear semi-aperture of 0-based surface `i` (mm).
    pub(crate) fn semi_aperture(&self, i: usize) -> f64 {
        self.surfaces[i].semi_aperture
    }

    /// Central obscuration radius of 0-based surface `i` (mm; 0 for none).
    pub(crate) fn obscuration(&self, i: usize) -> f64 {
        self.surfaces[i].obscuration_sq.sqrt()
    }

    /// How far inside the stop's blades the stop-plane point (x, y) lies (mm, negative
    /// outside); None for a stop without blades.
    pub(crate) fn blade_margin(&self, x: f64, y: f64) -> Option<f64> {
        self.diaphragm.as_ref().map(|blades| blades.margin(x, y))
    }

    /// The paraxial entrance pupil that the stop's clear aperture fills; None when it lies at
    /// infinity.
    pub fn paraxial_entrance_pupil(&self) -> Option<Pupil> {
        self.stop_image.map(|image| Pupil {
            z: image.z,
            diameter: 2.0 * self.surfaces[self.stop].semi_aperture / image.scale.abs(),
        })
    }

    /// Traces through every surface with apertures checked.
    pub fn trace(&self, ray: Ray, travel: Travel) -> Traced {
        self.trace_with(ray, travel, Apertures::Checked)
    }

    pub fn trace_with(&self, ray: Ray, travel: Travel, apertures: Apertures) -> Traced {
        let (traced, _) = self.run(
            ray,
            travel,
            0..self.surfaces.len(),
            apertures,
            &mut |_, _| {},
        );
        traced
    }

    /// Traces from the first surface in travel order up to and including surface `last`
    /// (1-based); the ray returned for [`Outcome::Ok`] is the one leaving `last`.
    pub fn trace_to(&self, ray: Ray, travel: Travel, last: usize, apertures: Apertures) -> Traced {
        let n = self.surfaces.len();
        let last = last.clamp(1, n);
        let steps = match travel {
            Travel::Forward => 0..last,
            Travel::Backward => 0..n + 1 - last,
        };
        self.run(ray, travel, steps, apertures, &mut |_, _| {}).0
    }

    /// Traces and records every surface crossed.
    pub fn trace_path(&self, ray: Ray, travel: Travel, apertures: Apertures) -> TracedPath {
        let mut crossings = Vec::with_capacity(self.surfaces.len());
        let (traced, _) = self.run(
            ray,
            travel,
            0..self.surfaces.len(),
            apertures,
            &mut |i, ray| {
                crossings.push(Crossing {
                    surface: i + 1,
                    point: ray.position,
                    direction: ray.direction,
                })
            },
        );
        TracedPath { traced, crossings }
    }

    /// Traces over `steps` (positions in travel order) and returns the result with the number of
    /// ray-surface intersections computed. `visit` sees each surface crossed (0-based index and
    /// the ray leaving it).
    #[inline]
    pub(crate) fn run(
        &self,
        ray: Ray,
        travel: Travel,
        steps: std::ops::Range<usize>,
        apertures: Apertures,
        visit: &mut impl FnMut(usize, &Ray),
    ) -> (Traced, u32) {
        self.run_on(lanes::Isa::detect(), ray, travel, steps, apertures, visit)
    }

    /// [`Tracer::run`] compiled for `isa`, which the processor must run: with FMA the
    /// multiply-adds are single instructions, without it library calls; the bits are the same.
    #[inline]
    fn run_on(
        &self,
        isa: lanes::Isa,
        ray: Ray,
        travel: Travel,
        steps: std::ops::Range<usize>,
        apertures: Apertures,
        visit: &mut impl FnMut(usize, &Ray),
    ) -> (Traced, u32) {
        let check = apertures == Apertures::Checked;
        #[cfg(target_arch = "x86_64")]
        if isa.fused() {
            // SAFETY: a fused `isa` is one `Isa::widest` allows on this processor: it has FMA.
            return unsafe { self.run_fma(ray, travel, steps, check, visit) };
        }
        self.run_travel(ray, travel, steps, check, visit)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2,fma")]
    fn run_fma(
        &self,
        ray: Ray,
        travel: Travel,
        steps: std::ops::Range<usize>,
        check_apertures: bool,
        visit: &mut impl FnMut(usize, &Ray),
    ) -> (Traced, u32) {
        self.run_travel(ray, travel, steps, check_apertures, visit)
    }

    #[inline(always)]
    fn run_travel(
        &self,
        ray: Ray,
        travel: Travel,
        steps: std::ops::Range<usize>,
        check_apertures: bool,
        visit: &mut impl FnMut(usize, &Ray),
    ) -> (Traced, u32) {
        match travel {
            Travel::Forward => self.run_in::<true>(ray, steps, check_apertures, visit),
            Travel::Backward => self.run_in::<false>(ray, steps, check_apertures, visit),
        }
    }

    #[inline(always)]
    fn run_in<const FORWARD: bool>(
        &self,
        mut ray: Ray,
        steps: std::ops::Range<usize>,
        check_apertures: bool,
        visit: &mut impl FnMut(usize, &Ray),
    ) -> (Traced, u32) {
        let n = self.surfaces.len();
        let mut count = 0u32;
        for step in steps {
            let i = if FORWARD { step } else { n - 1 - step };
            let s = &self.surfaces[i];
            count += 1;
            match self.cross::<FORWARD>(s, &ray, check_apertures) {
                Ok(next) => {
                    ray = next;
                    visit(i, &ray);
                }
                Err((event, at)) => {
                    let outcome = event.outcome(i + 1);
                    return (Traced { outcome, ray: at }, count);
                }
            }
        }
        (
            Traced {
                outcome: Outcome::Ok,
                ray,
            },
            count,
        )
    }

    /// One surface: intersect, check the aperture, refract.
    #[inline(always)]
    fn cross<const FORWARD: bool>(
        &self,
        s: &FlatSurface,
        ray: &Ray,
        check_apertures: bool,
    ) -> Result<Ray, (Event, Ray)> {
        let (p, d, sense) = in_vertex_frame::<FORWARD>(s, ray);
        let met = meet(&s.profile, &self.asphere_terms, p, d, sense);
        self.leave::<FORWARD>(s, ray, met, check_apertures)
    }

    /// The rest of [`Tracer::cross`] once the surface is `met` (the point in the vertex frame
    /// and the normal, None where the ray misses it): the aperture, then the bend.
    #[inline(always)]
    fn leave<const FORWARD: bool>(
        &self,
        s: &FlatSurface,
        ray: &Ray,
        met: Option<(Vec3, Option<Vec3>)>,
        check_apertures: bool,
    ) -> Result<Ray, (Event, Ray)> {
        let d = ray.direction;
        let Some((q, normal)) = met else {
            return Err((Event::Missed, *ray));
        };
        // A hit far enough out to overflow is no hit.
        if !(q[0].is_finite() && q[1].is_finite() && q[2].is_finite()) {
            return Err((Event::Missed, *ray));
        }
        let at = Ray {
            position: [q[0], q[1], q[2] + s.vertex_z],
            direction: d,
        };
        if check_apertures {
            let r_sq = intersect::radius_sq(q);
            if r_sq > s.semi_aperture_sq || r_sq < s.obscuration_sq {
                return Err((Event::Vignetted, at));
            }
            if s.bladed
                && !self
                    .diaphragm
                    .as_ref()
                    .is_some_and(|b| b.contains(q[0], q[1]))
            {
                return Err((Event::Vignetted, at));
            }
        }
        let (n_in, n_out, mu) = if FORWARD {
            (s.index_before, s.index_after, s.mu_forward)
        } else {
            (s.index_after, s.index_before, s.mu_backward)
        };
        let ideal_power = s.profile.ideal_power();
        match bend(ideal_power, s.reflects, q, normal, d, n_in == n_out, mu) {
            Ok(direction) => Ok(Ray {
                position: at.position,
                direction,
            }),
            Err(event) => Err((event, at)),
        }
    }
}

/// A ray arriving at surface `s` in the surface's vertex frame: its position and direction,
/// and the travel sense along z.
#[inline(always)]
fn in_vertex_frame<const FORWARD: bool>(s: &FlatSurface, ray: &Ray) -> (Vec3, Vec3, f64) {
    let sense = s.sense::<FORWARD>();
    let p = [
        ray.position[0],
        ray.position[1],
        ray.position[2] - s.vertex_z,
    ];
    (p, ray.direction, sense)
}

/// A prescription shape as the tracers read it; an asphere's coefficients go to `asphere_terms`,
/// its Newton search bounded by `search_radius` (mm from the axis).
fn profile_of(shape: &Shape, search_radius: f64, asphere_terms: &mut Vec<AsphereTerms>) -> Profile {
    match shape {
        Shape::Plane => Profile::Plane,
        Shape::IdealLens { .. } => Profile::IdealLens {
            power: shape.ideal_power(),
        },
        Shape::Sphere { curvature } if *curvature == 0.0 => Profile::Plane,
        Shape::Sphere { curvature } => Profile::Sphere {
            curvature: *curvature,
        },
        Shape::Conic { curvature, conic } => Profile::Conic {
            curvature: *curvature,
            conic_factor: 1.0 + conic,
        },
        Shape::EvenAsphere { .. } | Shape::OddAsphere { .. } => {
            asphere_terms.push(AsphereTerms::of(shape, search_radius));
            Profile::Asphere {
                curvature: shape.curvature(),
                conic_factor: 1.0 + shape.conic(),
                terms: asphere_terms.len() - 1,
            }
        }
    }
}

/// Where a ray (`p`, `d` in the surface's vertex frame, travelling along z in `sense`) meets the
/// profile, and the unit normal there (None on a plane, whose normal is the axis).
#[inline(always)]
fn meet(
    profile: &Profile,
    asphere_terms: &[AsphereTerms],
    p: Vec3,
    d: Vec3,
    sense: f64,
) -> Option<(Vec3, Option<Vec3>)> {
    match *profile {
        Profile::Plane | Profile::IdealLens { .. } => {
            intersect::plane(p, d, sense).map(|q| (q, None))
        }
        Profile::Sphere { curvature } => {
            intersect::sphere(p, d, curvature, sense).map(|hit| (hit.point, Some(hit.normal)))
        }
        Profile::Conic {
            curvature,
            conic_factor,
        } => intersect::conic(p, d, curvature, conic_factor, sense)
            .map(|hit| (hit.point, Some(hit.normal))),
        Profile::Asphere {
            curvature,
            conic_factor,
            terms,
        } => intersect::asphere(p, d, curvature, conic_factor, &asphere_terms[terms], sense)
            .map(|hit| (hit.point, Some(hit.normal))),
    }
}

/// The direction a ray travelling along `d` leaves a surface in, met at `q` (vertex frame) with
/// `normal` there: reflected, deflected by an ideal lens of `ideal_power`, or refracted with
/// Snell ratio `mu` (unchanged between equal indices).
#[inline(always)]
fn bend(
    ideal_power: Option<f64>,
    reflects: bool,
    q: Vec3,
    normal: Option<Vec3>,
    d: Vec3,
    equal_indices: bool,
    mu: f64,
) -> Result<Vec3, Event> {
    if reflects {
        return Ok(refract::reflect(d, normal.unwrap_or(refract::PLANE_NORMAL)));
    }
    if let Some(power) = ideal_power {
        return refract::ideal_lens(d, [q[0], q[1]], power).ok_or(unbent(ideal_power));
    }
    if equal_indices {
        return Ok(d);
    }
    match normal {
        None => refract::refract_plane(d, mu),
        Some(normal) => refract::refract(d, normal, mu),
    }
    .ok_or(unbent(ideal_power))
}

/// What a surface whose bend gives a ray no direction reports (the block trace's kernels too):
/// an ideal lens (of `ideal_power`) whose deflected tangents pass what f64 holds, a miss, since
/// no later surface is met; a refraction, total internal reflection.
#[inline(always)]
fn unbent(ideal_power: Option<f64>) -> Event {
    if ideal_power.is_some() {
        Event::Missed
    } else {
        Event::Tir
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Event {
    Missed,
    Vignetted,
    Tir,
}

impl Event {
    /// The outcome of this event at 1-based `surface`.
    fn outcome(self, surface: usize) -> Outcome {
        match self {
            Event::Missed => Outcome::Missed { surface },
            Event::Vignetted => Outcome::Vignetted { surface },
            Event::Tir => Outcome::Tir { surface },
        }
    }
}
