//! The exact trace of a lens its file places off one common axis ([`PlacedLens`]): tilted or
//! decentred lenses and curved mirrors, off-axis segments, tilted image planes.
//!
//! Rays live in the lens's global frame (the object side's axis is z). At each surface the ray
//! is carried into the surface's own frame, met, clipped and bent there by the same intersection,
//! refraction and reflection code as the centred [`super::Tracer`], and carried back. The sense
//! in which a ray meets a surface is the sign of its direction along the surface's own axis, so
//! mirrors and negative thicknesses need no bookkeeping.
//!
//! Toroids (a y-z curve turned about a line parallel to y; cylinders) exist only here: they are
//! met by Newton's method on their implicit form (`intersect::toroid`).
//!
//! A plane that bends and clips nothing (a Zemax coordinate break, a CODE V dummy) only places
//! the surfaces after it: no ray is tested against it, as in OpticStudio, so a ray parallel to
//! it is not lost there.
//!
//! Nothing here is paraxial: a field's chief ray is aimed at the stop's centre by Newton steps on
//! real rays, and its beam fills the file's entrance-pupil diameter in object space.

use super::intersect::{self, AsphereTerms, Profile};
use super::{Event, Outcome, Vec3, bend, meet, profile_of};
use crate::glass::Dispersion;
use crate::prescription::formats::{ApertureOutline, Frame, OutlineShape, PlacedLens};
use crate::prescription::{
    ApertureSpec, FieldKind, Location, Medium, PrescriptionError, Problem, Shape,
};

/// One surface as the 3-D trace reads it.
#[derive(Clone, Debug, PartialEq)]
struct PlacedSurface {
    frame: Frame,
    form: Form,
    /// The clear aperture that clips (a stated circle, or a rectangular or decentred outline);
    /// None where the file states none.
    aperture: Option<ApertureOutline>,
    obscuration_sq: f64,
    reflects: bool,
    equal_indices: bool,
    /// n before / n after, and n after (a mirror's is the index it reflects in).
    mu: f64,
    index_after: f64,
    /// False for a plane that bends and clips nothing: rays pass it untested.
    met: bool,
}

/// What a surface is, as the crossing code reads it.
#[derive(Clone, Debug, PartialEq)]
enum Form {
    /// A surface of revolution, met by the centred tracer's code.
    Revolved(Profile),
    Toroid(Toroid),
}

/// A toroid as [`intersect::toroid`] reads it.
#[derive(Clone, Debug, PartialEq)]
struct Toroid {
    curvature: f64,
    conic_factor: f64,
    terms: AsphereTerms,
    rotation_radius: f64,
}

impl Toroid {
    /// The toroid whose y-z curve is `shape` read in y.
    fn new(shape: &Shape, rotation_radius: f64, search_radius: f64) -> Toroid {
        Toroid {
            curvature: shape.curvature(),
            conic_factor: 1.0 + shape.conic(),
            terms: AsphereTerms::of(shape, search_radius),
            rotation_radius,
        }
    }
}

impl PlacedSurface {
    /// Whether a hit at `q` (the surface's frame) passes its clear aperture and obscuration
    /// (centred with the aperture).
    fn passes(&self, q: Vec3) -> bool {
        let Some(aperture) = &self.aperture else {
            return q[0].mul_add(q[0], q[1] * q[1]) >= self.obscuration_sq;
        };
        let (u, v) = (q[0] - aperture.centre[0], q[1] - aperture.centre[1]);
        aperture.passes(q[0], q[1]) && u.mul_add(u, v * v) >= self.obscuration_sq
    }
}

/// A placed lens at one wavelength, ready to trace.
#[derive(Clone, Debug, PartialEq)]
pub struct PlacedTracer {
    surfaces: Vec<PlacedSurface>,
    asphere_terms: Vec<AsphereTerms>,
    image: Frame,
    /// 0-based stop index.
    stop: usize,
    /// Largest distance of a vertex from the global origin plus the largest stated aperture
    /// (mm): the length rounding errors in global coordinates scale with.
    extent: f64,
    /// Refractive index of the object and of the image space.
    object_index: f64,
    image_index: f64,
}

/// Where a ray crosses one surface it meets, and how it leaves (global frame).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PathPoint {
    /// 1-based surface number.
    pub surface: usize,
    pub position: Vec3,
    /// The unit direction after the surface, the index of the medium it then travels in, and
    /// whether the surface reflected it.
    pub direction: Vec3,
    pub index: f64,
    pub reflects: bool,
}

/// A ray's whole path: every surface it met, where it ended and its optical path (mm) from the
/// start to there (each segment counted along the ray's direction, so a virtual segment, met
/// behind the ray, counts negative).
#[derive(Clone, Debug, PartialEq)]
pub struct PlacedPath {
    pub ray: PlacedRay,
    pub points: Vec<PathPoint>,
    pub optical_path: f64,
}

/// Where a ray ended, in the global frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlacedRay {
    pub outcome: Outcome,
    pub position: Vec3,
    pub direction: Vec3,
}

/// Why a field's beam could not be traced.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PlacedBeamError {
    #[error(
        "no ray of field ({:.6}, {:.6}) deg could be aimed at the stop's centre: {why}",
        .field_deg[0],
        .field_deg[1]
    )]
    ChiefRay { field_deg: [f64; 2], why: String },
    #[error(
        "the chief ray of field ({:.6}, {:.6}) deg {}",
        .field_deg[0],
        .field_deg[1],
        stopped(*.outcome)
    )]
    ChiefRayStopped {
        field_deg: [f64; 2],
        outcome: Outcome,
    },
    #[error("the field angle ({}, {}) deg is not a finite number", .0[0], .0[1])]
    FieldAngle([f64; 2]),
    /// The file's conditions ask for a beam the 3-D trace does not take; `takes` says what it
    /// takes instead.
    #[error("the 3-D trace takes {takes}")]
    NotTaken { takes: String },
}

/// Rays across the entrance pupil's diameter in the square grid `lens check` and the spot
/// diagrams launch ([`PlacedTracer::collimated_spot`]; the points inside the pupil's circle).
pub const SPOT_GRID: usize = 32;

/// The beam a file describes for a lens placed off one axis, as the 3-D trace takes it: an
/// object at infinity, fields as angles (x, y; the axis when the file gives none) and the
/// entrance pupil the file states or, for a lens whose surfaces all sit on the axis, the one its
/// F-number gives.
#[derive(Clone, Debug, PartialEq)]
pub struct PlacedBeam {
    pub fields_deg: Vec<[f64; 2]>,
    /// Entrance-pupil diameter (mm).
    pub pupil_diameter: f64,
    /// Where the diameter comes from.
    pub pupil_from: PupilFrom,
}

/// What sizes a placed lens's entrance pupil.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PupilFrom {
    /// The file states the diameter.
    File,
    /// The file's F-number, with the focal length (mm) of the lens, centred but for its
    /// apertures or image plane.
    FNumber { focal_length: f64, f_number: f64 },
    /// The stop's semi-aperture (mm), filled by the on-axis beam (the file's aperture floats by
    /// the stop's size): the diameter is 2 r / m for the stop's magnification m of the pupil
    /// about the chief ray, the larger of its x and y values.
    StopSize { semi_aperture: f64 },
}

impl PlacedBeam {
    /// The beam of `lens`'s file; `tracer` traces it at the design wavelength (an F-number
    /// needs its focal length).
    pub fn of(lens: &PlacedLens, tracer: &PlacedTracer) -> Result<PlacedBeam, PlacedBeamError> {
        let not_taken = |takes: String| PlacedBeamError::NotTaken { takes };
        let conditions = lens
            .prescription
            .provenance
            .conditions
            .clone()
            .unwrap_or_default();
        if conditions.object_distance_mm.is_some() {
            return Err(not_taken(
                "an object at infinity; this file's is at a finite distance".into(),
            ));
        }
        let fields_deg = match &conditions.fields {
            None => vec![[0.0, 0.0]],
            Some(f) if f.kind == FieldKind::AngleDeg => {
                f.x.iter().zip(&f.y).map(|(&x, &y)| [x, y]).collect()
            }
            Some(f) => {
                return Err(not_taken(format!(
                    "fields as angles; this file gives {:?}",
                    f.kind
                )));
            }
        };
        let (pupil_diameter, pupil_from) = match conditions.aperture {
            Some(ApertureSpec::EntrancePupilDiameter(d)) => (d, PupilFrom::File),
            Some(ApertureSpec::FNumber(n)) => match tracer.centred_focal_length() {
                Some(f) => (
                    f.abs() / n,
                    PupilFrom::FNumber {
                        focal_length: f.abs(),
                        f_number: n,
                    },
                ),
                None => {
                    return Err(not_taken(
                        "an entrance-pupil diameter (an F-number needs the focal length of a \
                         centred lens)"
                            .into(),
                    ));
                }
            },
            Some(ApertureSpec::FloatByStop) => {
                let semi_aperture = lens.prescription.surfaces[tracer.stop].semi_aperture;
                (
                    tracer.stop_filling_pupil(semi_aperture)?,
                    PupilFrom::StopSize { semi_aperture },
                )
            }
            other => {
                return Err(not_taken(format!(
                    "an entrance-pupil diameter, an F-number or the stop's size; this file sizes \
                     the beam by {other:?}"
                )));
            }
        };
        Ok(PlacedBeam {
            fields_deg,
            pupil_diameter,
            pupil_from,
        })
    }
}

/// |a x b|: the sine of the angle between unit vectors a and b.
fn cross_length(a: Vec3, b: Vec3) -> f64 {
    let c = super::cross(a, b);
    c[0].mul_add(c[0], c[1].mul_add(c[1], c[2] * c[2])).sqrt()
}

/// The unit direction of field angles `field_deg` (x, y): (tan x, tan y, 1) normalised.
pub fn field_direction(field_deg: [f64; 2]) -> Result<Vec3, PlacedBeamError> {
    // Every finite angle has a finite tangent (no f64 is exactly a right angle).
    if !field_deg.iter().all(|a| a.is_finite()) {
        return Err(PlacedBeamError::FieldAngle(field_deg));
    }
    Ok(tangent_direction(field_deg.map(|a| a.to_radians().tan())))
}

/// The unit direction (tx, ty, 1) normalised.
pub fn tangent_direction([tx, ty]: [f64; 2]) -> Vec3 {
    let length = tx.mul_add(tx, ty.mul_add(ty, 1.0)).sqrt();
    [tx / length, ty / length, 1.0 / length]
}

/// How a ray stopped, in words.
fn stopped(outcome: Outcome) -> String {
    match outcome {
        Outcome::Ok => "reaches the image plane".to_string(),
        Outcome::Missed { surface } => format!("misses surface {surface}"),
        Outcome::Vignetted { surface } => format!("is clipped at surface {surface}"),
        Outcome::Tir { surface } => format!("is totally reflected at surface {surface}"),
    }
}

/// One field's beam at the image plane, in the image plane's own frame (mm).
#[derive(Clone, Debug, PartialEq)]
pub struct PlacedSpot {
    /// Where the chief ray (through the stop's centre) crosses the plane z = 0 of the global
    /// frame, and where it meets the image plane.
    pub chief_launch: [f64; 2],
    pub chief: [f64; 2],
    /// Rays launched over the entrance pupil, and those that reach the image plane.
    pub launched: usize,
    pub arrived: usize,
    /// Centroid and RMS radius about it of the rays that arrive (mm); None when none does.
    pub centroid: Option<[f64; 2]>,
    pub rms_radius: Option<f64>,
    /// Where each ray that arrives meets the image plane.
    pub points: Vec<[f64; 2]>,
    /// n' sin θ for the largest angle θ between an arriving ray and the chief ray in image
    /// space (n' its index): the beam's numerical aperture about the chief ray, from which the
    /// Airy disk's radius is 0.61 λ / NA.
    pub image_numerical_aperture: f64,
}

/// Newton steps allowed to aim a chief ray, and the stop-plane miss (relative to the lens's
/// extent and the pupil radius) that counts as the centre: a few ulps of the coordinates.
const AIM_STEPS: usize = 40;
const AIM_TOLERANCE: f64 = 1e-12;

impl PlacedTracer {
    /// The lens at `wavelength_nm`, refused where it has no single stop or a medium has no index
    /// there.
    pub fn new(lens: &PlacedLens, wavelength_nm: f64) -> Result<PlacedTracer, PrescriptionError> {
        let p = &lens.prescription;
        let at_surface =
            |i: usize, field: &str| Location::default().with_surface(i + 1).with_field(field);
        let stop = p
            .stop_index()
            .ok_or_else(|| PrescriptionError::new(Location::default(), Problem::NoStop))?;
        crate::limits::check_wavelength(wavelength_nm)
            .map_err(|e| PrescriptionError::new(Location::default(), e.into()))?;
        let index_of = |medium: &Medium, location: Location| {
            Dispersion::of(medium)
                .and_then(|d| d.checked_index(wavelength_nm))
                .map_err(|problem| PrescriptionError::new(location, problem))
        };
        let object_index = index_of(
            &p.object_medium,
            Location::default().with_field("object_medium"),
        )?;
        let mut index_before = object_index;
        // The Newton search of an asphere stays within twice the largest stated aperture.
        let outline_reach = lens.outlines.iter().flatten().map(ApertureOutline::reach);
        let search_radius = 2.0
            * p.surfaces
                .iter()
                .map(|s| s.semi_aperture)
                .chain(outline_reach)
                .filter(|r| r.is_finite())
                .fold(1.0, f64::max);
        let mut asphere_terms = Vec::new();
        let mut surfaces = Vec::with_capacity(p.surfaces.len());
        for (i, s) in p.surfaces.iter().enumerate() {
            let reflects = s.medium == Medium::Mirror;
            let index_after = if reflects {
                index_before
            } else {
                index_of(&s.medium, at_surface(i, "medium"))?
            };
            let aperture = lens.outlines.get(i).copied().flatten().or_else(|| {
                lens.clips
                    .get(i)
                    .copied()
                    .unwrap_or(false)
                    .then_some(ApertureOutline {
                        shape: OutlineShape::Circle {
                            radius: s.semi_aperture,
                        },
                        centre: [0.0; 2],
                    })
            });
            let form = match lens.rotation_radii.get(i).copied().flatten() {
                Some(r) => Form::Toroid(Toroid::new(&s.shape, r, search_radius)),
                None => Form::Revolved(profile_of(&s.shape, search_radius, &mut asphere_terms)),
            };
            let equal_indices = index_before == index_after;
            surfaces.push(PlacedSurface {
                frame: lens.frames[i],
                met: i == stop
                    || reflects
                    || aperture.is_some()
                    || s.obscuration.is_some()
                    || !equal_indices
                    || form != Form::Revolved(Profile::Plane),
                form,
                aperture,
                obscuration_sq: s.obscuration.map_or(0.0, |r| r * r),
                reflects,
                equal_indices,
                mu: index_before / index_after,
                index_after,
            });
            index_before = index_after;
        }
        let extent = lens
            .frames
            .iter()
            .chain([&lens.image])
            .map(|f| f.origin.iter().fold(0.0_f64, |m, v| m.max(v.abs())))
            .fold(0.0, f64::max)
            + search_radius / 2.0;
        Ok(PlacedTracer {
            surfaces,
            asphere_terms,
            image: lens.image,
            stop,
            extent,
            object_index,
            image_index: index_before,
        })
    }

    /// Traces a ray from `position` along unit `direction` (global frame) through surfaces
    /// `0..end`; `clip` says whether clear apertures and obscurations stop it.
    fn trace_through(&self, position: Vec3, direction: Vec3, end: usize, clip: bool) -> PlacedRay {
        self.trace_visiting(position, direction, end, clip, &mut |_| {})
    }

    /// [`PlacedTracer::trace_through`], handing `visit` each surface the ray leaves.
    fn trace_visiting(
        &self,
        position: Vec3,
        direction: Vec3,
        end: usize,
        clip: bool,
        visit: &mut dyn FnMut(PathPoint),
    ) -> PlacedRay {
        let mut ray = PlacedRay {
            outcome: Outcome::Ok,
            position,
            direction,
        };
        for (i, s) in self.surfaces[..end].iter().enumerate() {
            if !s.met {
                continue;
            }
            let p = s.frame.point_to_local(ray.position);
            let d = s.frame.direction_to_local(ray.direction);
            let stopped = |event: Event, ray: PlacedRay| PlacedRay {
                outcome: event.outcome(i + 1),
                ..ray
            };
            let sense = if d[2] < 0.0 { -1.0 } else { 1.0 };
            let (crossing, ideal_power) = match &s.form {
                Form::Toroid(t) => (
                    intersect::toroid(
                        p,
                        d,
                        t.curvature,
                        t.conic_factor,
                        &t.terms,
                        t.rotation_radius,
                        sense,
                    )
                    .map(|hit| (hit.point, Some(hit.normal))),
                    None,
                ),
                Form::Revolved(profile) => (
                    meet(profile, &self.asphere_terms, p, d, sense),
                    profile.ideal_power(),
                ),
            };
            let Some((q, normal)) = crossing.filter(|(q, _)| q.iter().all(|v| v.is_finite()))
            else {
                return stopped(Event::Missed, ray);
            };
            ray.position = s.frame.point_to_parent(q);
            if clip && !s.passes(q) {
                return stopped(Event::Vignetted, ray);
            }
            match bend(ideal_power, s.reflects, q, normal, d, s.equal_indices, s.mu) {
                Ok(bent) => ray.direction = s.frame.direction_to_parent(bent),
                Err(event) => return stopped(event, ray),
            }
            visit(PathPoint {
                surface: i + 1,
                position: ray.position,
                direction: ray.direction,
                index: s.index_after,
                reflects: s.reflects,
            });
        }
        ray
    }

    /// Traces a ray (global frame, unit direction) through every surface, clear apertures
    /// clipping, onto the image plane. On [`Outcome::Ok`] the position is on the image plane; a
    /// ray that does not cross it ends [`Outcome::Missed`] at surface N + 1.
    pub fn trace(&self, position: Vec3, direction: Vec3) -> PlacedRay {
        let ray = self.trace_through(position, direction, self.surfaces.len(), true);
        self.onto_image(ray)
    }

    /// A ray that left the last surface carried onto the image plane; one that does not cross
    /// it ends [`Outcome::Missed`] at surface N + 1.
    fn onto_image(&self, mut ray: PlacedRay) -> PlacedRay {
        if ray.outcome.is_ok() {
            match self.meet_image(&ray) {
                Some(q) => ray.position = self.image.point_to_parent(q),
                None => {
                    ray.outcome = Outcome::Missed {
                        surface: self.surfaces.len() + 1,
                    };
                }
            }
        }
        ray
    }

    /// A ray's whole path ([`PlacedPath`]) onto the image plane; `clip` says whether clear
    /// apertures and obscurations stop it (first-order data about a ray that an obscuration
    /// blocks, such as the axis ray of a Cassegrain, are still defined).
    pub fn trace_path(&self, position: Vec3, direction: Vec3, clip: bool) -> PlacedPath {
        let mut points = Vec::with_capacity(self.surfaces.len());
        let ray = self.onto_image(self.trace_visiting(
            position,
            direction,
            self.surfaces.len(),
            clip,
            &mut |point| points.push(point),
        ));
        let mut optical_path = 0.0;
        let (mut from, mut along, mut index) = (position, direction, self.object_index);
        let ends = points
            .iter()
            .map(|p| (p.position, p.direction, p.index))
            .chain(
                ray.outcome
                    .is_ok()
                    .then_some((ray.position, ray.direction, index)),
            );
        for (to, leaving, index_after) in ends {
            let step: f64 = (0..3).map(|k| (to[k] - from[k]) * along[k]).sum();
            optical_path += index * step;
            (from, along, index) = (to, leaving, index_after);
        }
        PlacedPath {
            ray,
            points,
            optical_path,
        }
    }

    /// Refractive index of the object space and of the image space.
    pub fn indices(&self) -> [f64; 2] {
        [self.object_index, self.image_index]
    }

    /// 0-based index of the stop surface.
    pub fn stop_index(&self) -> usize {
        self.stop
    }

    /// Where a ray crosses the stop (the stop's frame, apertures not clipping), None when it
    /// does not get there; public for the differential rays of [`crate::analysis::placed`].
    pub fn stop_crossing(&self, position: Vec3, direction: Vec3) -> Option<[f64; 2]> {
        self.at_stop(position, direction)
    }

    /// The start on the plane z = 0 and the unit direction of field `field_deg`'s chief ray
    /// (through the stop's centre), for an entrance pupil of radius `pupil_radius` mm.
    pub fn chief_ray(
        &self,
        field_deg: [f64; 2],
        pupil_radius: f64,
    ) -> Result<(Vec3, Vec3), PlacedBeamError> {
        let direction = field_direction(field_deg)?;
        Ok((
            self.aim_chief(direction, pupil_radius, field_deg)?,
            direction,
        ))
    }

    /// Where a ray that left the last surface meets the image plane, in the plane's frame.
    fn meet_image(&self, ray: &PlacedRay) -> Option<Vec3> {
        let p = self.image.point_to_local(ray.position);
        let d = self.image.direction_to_local(ray.direction);
        let sense = if d[2] < 0.0 { -1.0 } else { 1.0 };
        meet(&Profile::Plane, &[], p, d, sense)
            .map(|(q, _)| q)
            .filter(|q| q.iter().all(|v| v.is_finite()))
    }

    /// The image plane's normal (global frame).
    pub fn image_normal(&self) -> Vec3 {
        self.image.axis()
    }

    /// A global point in the image plane's own frame (x, y).
    pub fn image_coordinates(&self, point: Vec3) -> [f64; 2] {
        let q = self.image.point_to_local(point);
        [q[0], q[1]]
    }

    /// The effective focal length (mm) where every surface that is met sits on the global axis
    /// facing along it (a centred lens with rectangular or decentred apertures, or a decentred
    /// image plane): from a real ray parallel to the axis at a height of 1e-6 of the lens's
    /// extent, f = -h / tan(u') (the paraxial limit to about 1e-12, rounding to about 1e-10).
    /// None for a lens that is tilted or decentred, or when that ray does not leave the lens.
    pub fn centred_focal_length(&self) -> Option<f64> {
        let on_axis = |f: &Frame| {
            let axis = f.axis();
            axis[0].hypot(axis[1]) <= 1e-12 && f.origin[0].hypot(f.origin[1]) <= 1e-10 * self.extent
        };
        if !self
            .surfaces
            .iter()
            .filter(|s| s.met)
            .all(|s| on_axis(&s.frame))
        {
            return None;
        }
        let height = 1e-6 * self.extent;
        let ray = self.trace_through(
            [0.0, height, 0.0],
            [0.0, 0.0, 1.0],
            self.surfaces.len(),
            false,
        );
        let slope = ray.direction[1] / ray.direction[2];
        (ray.outcome.is_ok() && slope != 0.0 && slope.is_finite()).then(|| -height / slope)
    }

    /// Where a ray crosses the stop, in the stop's frame, apertures not clipping; None when it
    /// does not get there.
    fn at_stop(&self, position: Vec3, direction: Vec3) -> Option<[f64; 2]> {
        let ray = self.trace_through(position, direction, self.stop + 1, false);
        ray.outcome.is_ok().then(|| {
            let q = self.surfaces[self.stop].frame.point_to_local(ray.position);
            [q[0], q[1]]
        })
    }

    /// The beam of an object point at infinity seen at field angles `field_deg` (x, y; the
    /// direction is (tan x, tan y, 1) normalised), filling an entrance pupil of diameter
    /// `pupil_diameter` mm perpendicular to the object side's axis, centred on the chief ray, on
    /// a square grid of `grid` x `grid` points (those inside the circle are launched).
    pub fn collimated_spot(
        &self,
        field_deg: [f64; 2],
        pupil_diameter: f64,
        grid: usize,
    ) -> Result<PlacedSpot, PlacedBeamError> {
        let direction = field_direction(field_deg)?;
        let chief_start = self.aim_chief(direction, pupil_diameter / 2.0, field_deg)?;
        let chief = self.trace(chief_start, direction);
        if !chief.outcome.is_ok() {
            return Err(PlacedBeamError::ChiefRayStopped {
                field_deg,
                outcome: chief.outcome,
            });
        }
        let radius = pupil_diameter / 2.0;
        let mut launched = 0;
        let mut points = Vec::new();
        // sin of the largest angle to the chief ray (both directions are unit vectors).
        let mut widest: f64 = 0.0;
        for row in 0..grid {
            for column in 0..grid {
                let along = |k: usize| (2.0 * k as f64 + 1.0) / grid as f64 - 1.0;
                let (u, v) = (along(column), along(row));
                if u.mul_add(u, v * v) > 1.0 {
                    continue;
                }
                launched += 1;
                let start = [
                    u.mul_add(radius, chief_start[0]),
                    v.mul_add(radius, chief_start[1]),
                    chief_start[2],
                ];
                let ray = self.trace(start, direction);
                if ray.outcome.is_ok() {
                    points.push(self.image_coordinates(ray.position));
                    widest = widest.max(cross_length(ray.direction, chief.direction));
                }
            }
        }
        let arrived = points.len();
        let centroid = (arrived > 0).then(|| {
            let sum = points
                .iter()
                .fold([0.0, 0.0], |s, p| [s[0] + p[0], s[1] + p[1]]);
            [sum[0] / arrived as f64, sum[1] / arrived as f64]
        });
        let rms_radius = centroid.map(|c| {
            let sum: f64 = points
                .iter()
                .map(|p| (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2))
                .sum();
            (sum / arrived as f64).sqrt()
        });
        Ok(PlacedSpot {
            chief_launch: [chief_start[0], chief_start[1]],
            chief: self.image_coordinates(chief.position),
            launched,
            arrived,
            centroid,
            rms_radius,
            points,
            image_numerical_aperture: self.image_index * widest.min(1.0),
        })
    }

    /// The entrance-pupil diameter (mm) of the on-axis beam that fills a stop of semi-aperture
    /// `stop_radius`: 2 r / m, where m is how far a ray beside the chief ray moves on the stop
    /// per mm it moves in the pupil (finite differences of a millionth of r in x and in y; the
    /// larger, which fills the stop first). For a centred lens this is the paraxial entrance
    /// pupil.
    pub fn stop_filling_pupil(&self, stop_radius: f64) -> Result<f64, PlacedBeamError> {
        let direction = [0.0, 0.0, 1.0];
        let field_deg = [0.0, 0.0];
        let chief = self.aim_chief(direction, stop_radius, field_deg)?;
        let fail = |why: &str| PlacedBeamError::ChiefRay {
            field_deg,
            why: why.to_string(),
        };
        let at = |dx: f64, dy: f64| {
            self.at_stop([chief[0] + dx, chief[1] + dy, 0.0], direction)
                .ok_or_else(|| fail("a ray beside the chief ray misses the stop"))
        };
        let step = 1e-6 * stop_radius;
        let centre = at(0.0, 0.0)?;
        let moved = |p: [f64; 2]| (p[0] - centre[0]).hypot(p[1] - centre[1]) / step;
        let magnification = moved(at(step, 0.0)?).max(moved(at(0.0, step)?));
        let diameter = 2.0 * stop_radius / magnification;
        if !(diameter.is_finite() && diameter > 0.0) {
            return Err(fail("the stop does not see the pupil (no magnification)"));
        }
        Ok(diameter)
    }

    /// The start, on the plane z = 0 of the global frame, of the ray along `direction` through
    /// the stop's centre: Newton steps on the launch point with a finite-difference Jacobian
    /// (step a millionth of the pupil radius), from the axis.
    fn aim_chief(
        &self,
        direction: Vec3,
        pupil_radius: f64,
        field_deg: [f64; 2],
    ) -> Result<Vec3, PlacedBeamError> {
        let fail = |why: &str| PlacedBeamError::ChiefRay {
            field_deg,
            why: why.to_string(),
        };
        let step = 1e-6 * pupil_radius.max(f64::MIN_POSITIVE);
        let scale = pupil_radius + self.extent;
        let at = |x: f64, y: f64| self.at_stop([x, y, 0.0], direction);
        let (mut x, mut y) = (0.0, 0.0);
        for _ in 0..AIM_STEPS {
            let miss = at(x, y).ok_or_else(|| fail("a ray on the way misses the stop"))?;
            if miss[0].hypot(miss[1]) <= AIM_TOLERANCE * scale {
                return Ok([x, y, 0.0]);
            }
            let (Some(dx), Some(dy)) = (at(x + step, y), at(x, y + step)) else {
                return Err(fail("a ray beside the chief ray misses the stop"));
            };
            let j = [
                [(dx[0] - miss[0]) / step, (dy[0] - miss[0]) / step],
                [(dx[1] - miss[1]) / step, (dy[1] - miss[1]) / step],
            ];
            let det = j[0][0] * j[1][1] - j[0][1] * j[1][0];
            if det == 0.0 || !det.is_finite() {
                return Err(fail(
                    "the stop does not see the launch plane (singular aim)",
                ));
            }
            x -= (j[1][1] * miss[0] - j[0][1] * miss[1]) / det;
            y -= (j[0][0] * miss[1] - j[1][0] * miss[0]) / det;
        }
        Err(fail("Newton steps did not settle"))
    }
}
