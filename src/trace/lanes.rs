//! Several rays in lockstep, for throughput.
//!
//! One ray's trace is a chain of dependent square roots and divisions, so a single ray keeps
//! the floating-point units mostly waiting. Tracing [`LANES`] rays surface by surface gives the
//! processor independent chains to overlap, and the straight-line lane loops below are written
//! so the compiler packs them into vector instructions (AVX2 where the processor has it).
//! Spheres and planes (almost every surface of a real lens) have lane kernels; conics,
//! aspheres and the bladed stop fall back to the one-ray code for each live lane. The lane
//! kernels repeat the one-ray arithmetic operation for operation, so both paths give
//! bit-identical results (tested).

use super::{Event, FlatSurface, Outcome, Profile, Ray, Tracer};

pub(crate) const LANES: usize = 16;

/// Per-lane event codes; 64-bit so that they live in the same vector lanes as the f64 masks.
const CROSSED: u64 = 0;
const MISSED: u64 = 1;
const VIGNETTED: u64 = 2;
const TIR: u64 = 3;

/// Positions and directions of every lane.
#[derive(Clone, Copy, Debug)]
struct State {
    position: [[f64; LANES]; 3],
    direction: [[f64; LANES]; 3],
}

impl State {
    fn ray(&self, l: usize) -> Ray {
        Ray {
            position: [
                self.position[0][l],
                self.position[1][l],
                self.position[2][l],
            ],
            direction: [
                self.direction[0][l],
                self.direction[1][l],
                self.direction[2][l],
            ],
        }
    }

    fn set(&mut self, l: usize, ray: Ray) {
        for k in 0..3 {
            self.position[k][l] = ray.position[k];
            self.direction[k][l] = ray.direction[k];
        }
    }
}

/// [`LANES`] rays in flight.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Lanes {
    /// Two copies of the state: a kernel reads one and writes the other (so that every store
    /// is a plain one), and `front` says which holds the current rays.
    states: [State; 2],
    front: usize,
    /// Event code per lane from the last kernel.
    events: [u64; LANES],
    /// All ones for a lane still travelling, zero once an event ended it (and for unused lanes).
    live: [u64; LANES],
    outcome: [Outcome; LANES],
    /// For ended lanes: the ray as the one-ray path reports it.
    ended: [Option<Ray>; LANES],
    /// Ray-surface intersections computed per lane.
    crossed: [u32; LANES],
}

impl Lanes {
    /// Up to [`LANES`] rays; lanes left over stay unused.
    pub fn new(rays: impl IntoIterator<Item = Ray>) -> Lanes {
        let idle = State {
            position: [[0.0; LANES]; 3],
            direction: [[0.0; LANES], [0.0; LANES], [1.0; LANES]],
        };
        let mut lanes = Lanes {
            states: [idle; 2],
            front: 0,
            events: [CROSSED; LANES],
            live: [0; LANES],
            outcome: [Outcome::Ok; LANES],
            ended: [None; LANES],
            crossed: [0; LANES],
        };
        for (l, ray) in rays.into_iter().take(LANES).enumerate() {
            lanes.states[0].set(l, ray);
            lanes.live[l] = u64::MAX;
        }
        lanes
    }

    /// Lane `l`'s outcome, final ray and intersection count.
    pub fn result(&self, l: usize) -> (Outcome, Ray, u32) {
        let ray = self.ended[l].unwrap_or_else(|| self.states[self.front].ray(l));
        (self.outcome[l], ray, self.crossed[l])
    }

    fn any_live(&self) -> bool {
        self.live.iter().fold(0, |any, &l| any | l) != 0
    }

    fn end(&mut self, l: usize, event: Event, surface: usize, at: Ray) {
        self.live[l] = 0;
        self.outcome[l] = event.outcome(surface + 1);
        self.ended[l] = Some(at);
    }

    /// Ends the lanes the last kernel stopped, with the ray the one-ray path reports (the ray
    /// before the surface for a miss; the hit point and arriving direction otherwise), and makes
    /// the kernel's output the current state. Ended lanes carry on with meaningless numbers that
    /// are never read.
    fn commit(&mut self, surface: usize) {
        let stopped = self
            .events
            .iter()
            .zip(&self.live)
            .fold(0, |any, (&e, &l)| any | (e & l));
        if stopped != 0 {
            let (before, after) = (self.front, 1 - self.front);
            for l in 0..LANES {
                if self.events[l] & self.live[l] == 0 {
                    continue;
                }
                let arriving = self.states[before].ray(l);
                let (event, at) = match self.events[l] {
                    MISSED => (Event::Missed, arriving),
                    code => {
                        let event = if code == VIGNETTED {
                            Event::Vignetted
                        } else {
                            Event::Tir
                        };
                        let hit = self.states[after].ray(l).position;
                        (event, Ray::from_parts(hit, arriving.direction))
                    }
                };
                self.end(l, event, surface, at);
            }
        }
        self.front = 1 - self.front;
    }

    /// Shows `visit` the current positions: the hit points on surface `i` just crossed.
    #[inline(always)]
    fn show(&self, i: usize, visit: &mut impl LaneVisitor) {
        let position = &self.states[self.front].position;
        visit.crossed(i, &position[0], &position[1]);
    }

    /// The current state to read and the other one to write.
    fn split(&mut self) -> (&State, &mut State) {
        let [a, b] = &mut self.states;
        if self.front == 0 { (a, b) } else { (b, a) }
    }
}

/// What a lane visitor sees after each surface: the surface's 0-based index and every lane's
/// hit point on it (x and y, lens frame). Lanes that have ended hold meaningless numbers.
pub(crate) trait LaneVisitor {
    fn crossed(&mut self, surface: usize, x: &[f64; LANES], y: &[f64; LANES]);
}

/// The visitor of a plain trace.
struct NoVisit;

impl LaneVisitor for NoVisit {
    #[inline(always)]
    fn crossed(&mut self, _: usize, _: &[f64; LANES], _: &[f64; LANES]) {}
}

impl Tracer {
    /// Traces the live lanes through every surface in `FORWARD` order.
    pub(crate) fn run_lanes<const FORWARD: bool>(&self, lanes: &mut Lanes, check_apertures: bool) {
        self.run_lanes_visiting::<FORWARD>(lanes, check_apertures, &mut NoVisit)
    }

    /// [`Tracer::run_lanes`], showing `visit` every surface's hit points as the lanes cross it.
    pub(crate) fn run_lanes_visiting<const FORWARD: bool>(
        &self,
        lanes: &mut Lanes,
        check_apertures: bool,
        visit: &mut impl LaneVisitor,
    ) {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            return self.lanes_body::<FORWARD, true>(lanes, check_apertures, visit);
        }
        self.lanes_body::<FORWARD, false>(lanes, check_apertures, visit)
    }

    /// `AVX2` is true only when the processor has been checked to support it.
    #[inline(always)]
    fn lanes_body<const FORWARD: bool, const AVX2: bool>(
        &self,
        lanes: &mut Lanes,
        check_apertures: bool,
        visit: &mut impl LaneVisitor,
    ) {
        let n = self.surfaces.len();
        for step in 0..n {
            if !lanes.any_live() {
                break;
            }
            for l in 0..LANES {
                lanes.crossed[l] += (lanes.live[l] & 1) as u32;
            }
            let i = if FORWARD { step } else { n - 1 - step };
            let s = &self.surfaces[i];
            let refracts = s.index_before != s.index_after;
            match (s.profile, s.bladed || !s.plain(), refracts) {
                (Profile::Sphere { .. }, false, true) => {
                    launch::<AVX2, SphereKernel<FORWARD, true>>(s, lanes, check_apertures)
                }
                (Profile::Sphere { .. }, false, false) => {
                    launch::<AVX2, SphereKernel<FORWARD, false>>(s, lanes, check_apertures)
                }
                (Profile::Plane, false, true) => {
                    launch::<AVX2, PlaneKernel<FORWARD, true>>(s, lanes, check_apertures)
                }
                (Profile::Plane, false, false) => {
                    launch::<AVX2, PlaneKernel<FORWARD, false>>(s, lanes, check_apertures)
                }
                _ => {
                    self.lanes_one_by_one::<FORWARD>(s, i, lanes, check_apertures);
                    lanes.show(i, visit);
                    continue;
                }
            }
            lanes.commit(i);
            lanes.show(i, visit);
        }
    }

    /// Surfaces without a lane kernel: the one-ray code for each live lane.
    fn lanes_one_by_one<const FORWARD: bool>(
        &self,
        s: &FlatSurface,
        i: usize,
        lanes: &mut Lanes,
        check_apertures: bool,
    ) {
        for l in 0..LANES {
            if lanes.live[l] == 0 {
                continue;
            }
            let state = &mut lanes.states[lanes.front];
            match self.cross::<FORWARD>(s, &state.ray(l), check_apertures) {
                Ok(next) => state.set(l, next),
                Err((event, at)) => lanes.end(l, event, i, at),
            }
        }
    }
}

/// A lane kernel: crosses one surface with every lane of `current`, writing each lane's hit
/// point (lens frame) and new direction to `next` and its event code to `events`. Dead lanes are
/// computed too and ignored afterwards.
trait Kernel {
    fn cross(
        s: &FlatSurface,
        current: &State,
        next: &mut State,
        events: &mut [u64; LANES],
        check_apertures: bool,
    );
}

struct SphereKernel<const FORWARD: bool, const REFRACTS: bool>;
struct PlaneKernel<const FORWARD: bool, const REFRACTS: bool>;

impl<const FORWARD: bool, const REFRACTS: bool> Kernel for SphereKernel<FORWARD, REFRACTS> {
    #[inline(always)]
    fn cross(
        s: &FlatSurface,
        current: &State,
        next: &mut State,
        events: &mut [u64; LANES],
        check_apertures: bool,
    ) {
        sphere_lanes::<FORWARD, REFRACTS>(s, current, next, events, check_apertures)
    }
}

impl<const FORWARD: bool, const REFRACTS: bool> Kernel for PlaneKernel<FORWARD, REFRACTS> {
    #[inline(always)]
    fn cross(
        s: &FlatSurface,
        current: &State,
        next: &mut State,
        events: &mut [u64; LANES],
        check_apertures: bool,
    ) {
        plane_lanes::<FORWARD, REFRACTS>(s, current, next, events, check_apertures)
    }
}

/// Runs kernel `K` on the lanes and keeps its event codes.
#[inline(always)]
fn launch<const AVX2: bool, K: Kernel>(s: &FlatSurface, lanes: &mut Lanes, check_apertures: bool) {
    let mut events = [CROSSED; LANES];
    let (current, next) = lanes.split();
    #[cfg(target_arch = "x86_64")]
    if AVX2 {
        // SAFETY: AVX2 is only true after the processor was found to support it.
        unsafe { with_avx2::<K>(s, current, next, &mut events, check_apertures) };
    } else {
        K::cross(s, current, next, &mut events, check_apertures);
    }
    #[cfg(not(target_arch = "x86_64"))]
    K::cross(s, current, next, &mut events, check_apertures);
    lanes.events = events;
}

/// Runs a kernel compiled for AVX2. The kernel is a static call to an `inline(always)` function,
/// so its body is compiled here, with the feature (a kernel passed as a closure or function value
/// was not inlined and ran as SSE2 code). Only the vector width changes: Rust never fuses a
/// multiply and an add on its own, and vector square roots and divisions round exactly as scalar
/// ones, so the results stay bit-identical to the one-ray path.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[inline(never)]
fn with_avx2<K: Kernel>(
    s: &FlatSurface,
    current: &State,
    next: &mut State,
    events: &mut [u64; LANES],
    check_apertures: bool,
) {
    K::cross(s, current, next, events, check_apertures)
}

/// The sphere kernel: [`super::intersect::sphere`], the aperture test and
/// [`super::refract::refract`] for every lane, without branches on lane data. `REFRACTS` is
/// false where the media on both sides are the same, as the one-ray path skips refraction there.
#[inline(always)]
fn sphere_lanes<const FORWARD: bool, const REFRACTS: bool>(
    s: &FlatSurface,
    current: &State,
    next: &mut State,
    events: &mut [u64; LANES],
    check_apertures: bool,
) {
    let Profile::Sphere { curvature: c } = s.profile else {
        unreachable!("the sphere kernel runs on spheres only")
    };
    let sense = if FORWARD { 1.0 } else { -1.0 };
    let mu = if FORWARD { s.mu_forward } else { s.mu_backward };
    for l in 0..LANES {
        let [dx, dy, dz] = [
            current.direction[0][l],
            current.direction[1][l],
            current.direction[2][l],
        ];
        let [px, py, pz] = [
            current.position[0][l],
            current.position[1][l],
            current.position[2][l] - s.vertex_z,
        ];
        // As the one-ray solver does: start from the line's point nearest the vertex.
        let along = px * dx + py * dy + pz * dz;
        let [px, py, pz] = [px - along * dx, py - along * dy, pz - along * dz];
        let b = dz - c * (px * dx + py * dy + pz * dz);
        let cc = c * (px * px + py * py + pz * pz) - 2.0 * pz;
        let disc = b * b - c * cc;
        let root = disc.max(0.0).sqrt();
        let near = sense * b >= 0.0;
        let numerator = if near { cc } else { b - sense * root };
        let denominator = if near { b + sense * root } else { c };
        let t = numerator / denominator;
        let (qx, qy, qz) = (px + t * dx, py + t * dy, pz + t * dz);
        let nz = c * qz - 1.0;
        let hit = (disc >= 0.0)
            & t.is_finite()
            & (nz < 0.0)
            & qx.is_finite()
            & qy.is_finite()
            & qz.is_finite();
        let inside = !check_apertures | (qx * qx + qy * qy <= s.semi_aperture_sq);
        let (out, passes) = if REFRACTS {
            let (nx, ny) = (c * qx, c * qy);
            let cos_signed = nx * dx + ny * dy + nz * dz;
            let radicand = 1.0 - mu * mu * (1.0 - cos_signed * cos_signed);
            let along = radicand.max(0.0).sqrt().copysign(cos_signed) - mu * cos_signed;
            (
                [
                    mu * dx + along * nx,
                    mu * dy + along * ny,
                    mu * dz + along * nz,
                ],
                radicand >= 0.0,
            )
        } else {
            ([dx, dy, dz], true)
        };
        next.position[0][l] = qx;
        next.position[1][l] = qy;
        next.position[2][l] = qz + s.vertex_z;
        for k in 0..3 {
            next.direction[k][l] = out[k];
        }
        events[l] = event_code(hit, inside, passes);
    }
}

/// The plane kernel: [`super::intersect::plane`], the aperture test and
/// [`super::refract::refract_plane`] for every lane.
#[inline(always)]
fn plane_lanes<const FORWARD: bool, const REFRACTS: bool>(
    s: &FlatSurface,
    current: &State,
    next: &mut State,
    events: &mut [u64; LANES],
    check_apertures: bool,
) {
    let sense = if FORWARD { 1.0 } else { -1.0 };
    let mu = if FORWARD { s.mu_forward } else { s.mu_backward };
    for l in 0..LANES {
        let [dx, dy, dz] = [
            current.direction[0][l],
            current.direction[1][l],
            current.direction[2][l],
        ];
        let pz = current.position[2][l] - s.vertex_z;
        let t = -pz / dz;
        let qx = current.position[0][l] + t * dx;
        let qy = current.position[1][l] + t * dy;
        let hit = (dz * sense > 0.0) & qx.is_finite() & qy.is_finite();
        let inside = !check_apertures | (qx * qx + qy * qy <= s.semi_aperture_sq);
        let (out, passes) = if REFRACTS {
            let (x, y) = (mu * dx, mu * dy);
            let radicand = 1.0 - (x * x + y * y);
            (
                [x, y, radicand.max(0.0).sqrt().copysign(dz)],
                radicand >= 0.0,
            )
        } else {
            ([dx, dy, dz], true)
        };
        next.position[0][l] = qx;
        next.position[1][l] = qy;
        next.position[2][l] = s.vertex_z;
        for k in 0..3 {
            next.direction[k][l] = out[k];
        }
        events[l] = event_code(hit, inside, passes);
    }
}

/// The first failing test in the one-ray path's order: intersection, aperture, refraction.
#[inline(always)]
fn event_code(hit: bool, inside: bool, passes: bool) -> u64 {
    if !hit {
        MISSED
    } else if !inside {
        VIGNETTED
    } else if !passes {
        TIR
    } else {
        CROSSED
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::prescription::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
    use crate::system::LensSystem;
    use crate::trace::{Apertures, Travel};

    /// The portable kernels (the ones non-x86 processors and x86 without AVX2 run) against the
    /// one-ray path, since the machines that run the tests mostly take the AVX2 branch.
    #[test]
    fn portable_lanes_match_one_ray_path() {
        let surface = |shape, thickness, n: f64, stop| Surface {
            shape,
            thickness,
            medium: Medium::Index(n),
            semi_aperture: 9.0,
            stop,
            obscuration: None,
        };
        let prescription = Prescription {
            provenance: Provenance::default(),
            object_medium: Medium::Air,
            surfaces: vec![
                surface(Shape::Sphere { curvature: 0.04 }, 4.0, 1.7, None),
                surface(Shape::Plane, 3.0, 1.0, Some(StopShape::Circle)),
                surface(Shape::Plane, 3.0, 1.5, None),
                surface(Shape::Sphere { curvature: -0.05 }, 30.0, 1.0, None),
            ],
        };
        let system = LensSystem::from_prescription(prescription).unwrap();
        let tracer = Tracer::new(&system.at(550.0));
        let rays: Vec<Ray> = (0..LANES * 8)
            .map(|i| {
                let a = i as f64 * 0.37;
                let d = [
                    0.3 * a.sin(),
                    0.3 * (1.3 * a).cos(),
                    1.0 - 0.2 * (0.7 * a).sin(),
                ];
                Ray::new([8.0 * a.cos(), 8.0 * (0.5 * a).sin(), -5.0], d).unwrap()
            })
            .collect();
        let mut outcomes = std::collections::HashSet::new();
        for check in [true, false] {
            for group in rays.chunks(LANES) {
                let mut lanes = Lanes::new(group.iter().copied());
                tracer.lanes_body::<true, false>(&mut lanes, check, &mut NoVisit);
                for (l, ray) in group.iter().enumerate() {
                    let apertures = if check {
                        Apertures::Checked
                    } else {
                        Apertures::Ignored
                    };
                    let single = tracer.trace_with(*ray, Travel::Forward, apertures);
                    let (outcome, end, _) = lanes.result(l);
                    assert_eq!((outcome, end), (single.outcome, single.ray));
                    outcomes.insert(outcome.status());
                }
            }
        }
        assert!(outcomes.len() >= 2, "a mix of outcomes: {outcomes:?}");
    }
}
