//! Many rays at once: a structure-of-arrays batch traced in parallel with rayon.

use super::lanes::{LANES, Lanes};
use super::{Apertures, Outcome, Ray, Tracer, Travel};
use rayon::prelude::*;

/// Rays per parallel work item: large enough to amortise scheduling, small enough to balance
/// two to a few dozen cores on batches of a few thousand rays.
const CHUNK: usize = 1024;

/// Rays stored as six columns (position x, y, z and direction x, y, z). Built only from
/// [`Ray`]s, so every entry is finite with a unit direction.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RayBatch {
    x: Vec<f64>,
    y: Vec<f64>,
    z: Vec<f64>,
    dx: Vec<f64>,
    dy: Vec<f64>,
    dz: Vec<f64>,
}

impl RayBatch {
    pub fn new() -> RayBatch {
        RayBatch::default()
    }

    pub fn with_capacity(n: usize) -> RayBatch {
        let column = || Vec::with_capacity(n);
        RayBatch {
            x: column(),
            y: column(),
            z: column(),
            dx: column(),
            dy: column(),
            dz: column(),
        }
    }

    pub fn push(&mut self, ray: Ray) {
        let (p, d) = (ray.position, ray.direction);
        self.x.push(p[0]);
        self.y.push(p[1]);
        self.z.push(p[2]);
        self.dx.push(d[0]);
        self.dy.push(d[1]);
        self.dz.push(d[2]);
    }

    pub fn len(&self) -> usize {
        self.x.len()
    }

    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// The ray at `index`; None past the end.
    pub fn get(&self, index: usize) -> Option<Ray> {
        (index < self.len()).then(|| Ray {
            position: [self.x[index], self.y[index], self.z[index]],
            direction: [self.dx[index], self.dy[index], self.dz[index]],
        })
    }

    pub fn iter(&self) -> impl ExactSizeIterator<Item = Ray> + '_ {
        (0..self.len()).map(|i| Ray {
            position: [self.x[i], self.y[i], self.z[i]],
            direction: [self.dx[i], self.dy[i], self.dz[i]],
        })
    }

    /// The columns: position x, y, z, then direction x, y, z.
    pub fn columns(&self) -> [&[f64]; 6] {
        [&self.x, &self.y, &self.z, &self.dx, &self.dy, &self.dz]
    }

    fn zeroed(n: usize) -> RayBatch {
        let column = || vec![0.0; n];
        RayBatch {
            x: column(),
            y: column(),
            z: column(),
            dx: column(),
            dy: column(),
            dz: column(),
        }
    }
}

impl FromIterator<Ray> for RayBatch {
    fn from_iter<I: IntoIterator<Item = Ray>>(iter: I) -> RayBatch {
        let iter = iter.into_iter();
        let mut batch = RayBatch::with_capacity(iter.size_hint().0);
        for ray in iter {
            batch.push(ray);
        }
        batch
    }
}

/// The result of tracing a batch: per ray its outcome and final ray (see
/// [`super::Traced`] for what the final ray is when the outcome is not ok), and the number of
/// ray-surface intersections computed.
#[derive(Clone, Debug, PartialEq)]
pub struct BatchTrace {
    pub outcomes: Vec<Outcome>,
    pub rays: RayBatch,
    pub ray_surfaces: u64,
}

impl Tracer {
    /// Traces up to [`LANES`] rays in lockstep on this thread, apertures checked: `traced[i]`
    /// gets ray `i`'s result, bit for bit what [`Tracer::trace`] gives. For callers that make
    /// their rays a few at a time (the renderer's samples of one pixel).
    pub(crate) fn trace_group(&self, rays: &[Ray], travel: Travel, traced: &mut [super::Traced]) {
        debug_assert!(rays.len() <= LANES && traced.len() >= rays.len());
        let mut lanes = Lanes::new(rays.iter().copied());
        match travel {
            Travel::Forward => self.run_lanes::<true>(&mut lanes, true),
            Travel::Backward => self.run_lanes::<false>(&mut lanes, true),
        }
        for (l, out) in traced.iter_mut().enumerate().take(rays.len()) {
            let (outcome, ray, _) = lanes.result(l);
            *out = super::Traced { outcome, ray };
        }
    }

    /// Traces every ray of `rays` on the current rayon thread pool.
    pub fn trace_batch(&self, rays: &RayBatch, travel: Travel, apertures: Apertures) -> BatchTrace {
        let n = rays.len();
        let mut out = RayBatch::zeroed(n);
        let mut outcomes = vec![Outcome::Ok; n];
        let check = apertures == Apertures::Checked;
        let ray_surfaces = outcomes
            .par_chunks_mut(CHUNK)
            .zip(out.x.par_chunks_mut(CHUNK))
            .zip(out.y.par_chunks_mut(CHUNK))
            .zip(out.z.par_chunks_mut(CHUNK))
            .zip(out.dx.par_chunks_mut(CHUNK))
            .zip(out.dy.par_chunks_mut(CHUNK))
            .zip(out.dz.par_chunks_mut(CHUNK))
            .enumerate()
            .map(|(chunk, ((((((outcome, x), y), z), dx), dy), dz))| {
                let start = chunk * CHUNK;
                let mut count = 0u64;
                for group in (0..outcome.len()).step_by(LANES) {
                    let width = LANES.min(outcome.len() - group);
                    let first = start + group;
                    let mut lanes = Lanes::new(
                        (first..first + width)
                            .map(|i| rays.get(i).expect("output chunks mirror the input")),
                    );
                    match travel {
                        Travel::Forward => self.run_lanes::<true>(&mut lanes, check),
                        Travel::Backward => self.run_lanes::<false>(&mut lanes, check),
                    }
                    for l in 0..width {
                        let j = group + l;
                        let (ended, ray, crossed) = lanes.result(l);
                        count += u64::from(crossed);
                        outcome[j] = ended;
                        let (p, d) = (ray.position, ray.direction);
                        (x[j], y[j], z[j]) = (p[0], p[1], p[2]);
                        (dx[j], dy[j], dz[j]) = (d[0], d[1], d[2]);
                    }
                }
                count
            })
            .sum();
        BatchTrace {
            outcomes,
            rays: out,
            ray_surfaces,
        }
    }
}
