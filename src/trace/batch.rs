//! Many rays at once: a structure-of-arrays batch traced in parallel with rayon.

use super::lanes::{Block, Finish, Isa, STRIDE};
use super::{Apertures, Outcome, Ray, Traced, Tracer, Travel};
use crate::pages::{Pages, fence_streaming_stores, resize_on, store_streaming};
use rayon::prelude::*;
use std::ops::IndexMut;

/// Rays per parallel work item: large enough to amortise scheduling, small enough to balance
/// two to a few dozen cores on batches of a few thousand rays.
const CHUNK: usize = 1024;

/// Rays traced together, by [`Tracer::trace_batch`] a block at a time and by the renderer's CPU
/// twin a group of samples at a time ([`Tracer::trace_group`]): 256, enough that the survivors
/// of a block fill whole vector strides after the edge rays of the field have been vignetted,
/// and that a block's cost per surface besides its rays' work (its kernel call and bookkeeping,
/// about 100 cycles) is spread over many rays. Against 128-ray blocks, 1M rays on a Zen 4
/// (32 KiB first-level cache, which the block's two states, 24 KiB, and a streamed batch's
/// staged results, 16 KiB, together pass): double Gauss 3-4 % faster, singlet 10 %,
/// asph-50mm-f1.8 6 %, tessar 2 %, telephoto and wide 1 %, triplet the same.
pub(crate) const GROUP_RAYS: usize = 256;

/// The block [`Tracer::trace_batch`] and [`Tracer::trace_group`] trace in: a caller that traces
/// group after group keeps one and passes it each time, since clearing a fresh block per group
/// was 2 % of a traced frame's profile. What a trace leaves in it does not change the next
/// one's results.
pub(crate) type GroupBlock = Block<{ GROUP_RAYS / STRIDE }>;

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

    /// The rays `make(0)`, `make(1)`, .. `make(n - 1)`, made on the current rayon thread pool
    /// and stored in that order; when any is refused, one refusal (not necessarily the
    /// lowest index's) is returned instead. For building large batches from arrays.
    ///
    /// ```
    /// use lensbake::{Ray, RayBatch};
    ///
    /// let heights = [0.0, 1.0, 2.0];
    /// let batch = RayBatch::try_from_fn(3, |k| Ray::new([0.0, heights[k], -5.0], [0.0, 0.0, 2.0]))?;
    /// assert_eq!(batch.get(2), Some(Ray::new([0.0, 2.0, -5.0], [0.0, 0.0, 1.0])?));
    /// assert!(RayBatch::try_from_fn(3, |k| Ray::new([0.0, 0.0, -5.0], [0.0, 0.0, k as f64])).is_err());
    /// # Ok::<(), lensbake::trace::RayError>(())
    /// ```
    pub fn try_from_fn<E: Send>(
        n: usize,
        make: impl Fn(usize) -> Result<Ray, E> + Sync,
    ) -> Result<RayBatch, E> {
        let mut batch = RayBatch::new();
        batch.resize(n);
        let RayBatch {
            x,
            y,
            z,
            dx,
            dy,
            dz,
        } = &mut batch;
        x.par_chunks_mut(CHUNK)
            .zip(y.par_chunks_mut(CHUNK))
            .zip(z.par_chunks_mut(CHUNK))
            .zip(dx.par_chunks_mut(CHUNK))
            .zip(dy.par_chunks_mut(CHUNK))
            .zip(dz.par_chunks_mut(CHUNK))
            .enumerate()
            .try_for_each(|(chunk, (((((x, y), z), dx), dy), dz))| {
                for i in 0..x.len() {
                    let ray = make(chunk * CHUNK + i)?;
                    [x[i], y[i], z[i]] = ray.position;
                    [dx[i], dy[i], dz[i]] = ray.direction;
                }
                Ok(())
            })?;
        Ok(batch)
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

    /// Makes every column `n` long, keeping the storage (new entries are zero; new storage on
    /// huge pages, see [`crate::pages`]).
    fn resize(&mut self, n: usize) {
        for column in [
            &mut self.x,
            &mut self.y,
            &mut self.z,
            &mut self.dx,
            &mut self.dy,
            &mut self.dz,
        ] {
            resize_on(Pages::Huge, column, n, 0.0);
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
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BatchTrace {
    pub outcomes: Vec<Outcome>,
    pub rays: RayBatch,
    pub ray_surfaces: u64,
}

/// One block's share of a batch's results, as a block trace fills them: entry `id` of each
/// window is the result of the block's ray numbered `id`. Windows of exactly a block's size let
/// the seven stores of a ray go without a bounds check each (a ray's number is below the
/// block's size), where slices of the chunk took seven, against lengths reloaded from the stack.
struct BlockResults<'a> {
    outcomes: &'a mut [Outcome; GROUP_RAYS],
    /// x, y, z, dx, dy, dz.
    columns: [&'a mut [f64; GROUP_RAYS]; 6],
}

impl BlockResults<'_> {
    /// Writes what `staged` holds into these windows with streaming stores.
    fn store_streaming(&mut self, staged: &StagedResults) {
        store_streaming(self.outcomes, &staged.outcomes);
        for (window, column) in self.columns.iter_mut().zip(&staged.columns) {
            store_streaming(window, column);
        }
    }
}

/// Batches of at least this many rays write their results through [`StagedResults`]: their
/// results (64 bytes a ray) and rays (48) outgrow the caches, and reading each result line into
/// the cache before writing it, as ordinary stores do, is then a third of the memory traffic.
/// Measured on an AMD Zen 4 (1 MiB second-level cache), one core, a batch traced over and over:
/// cooke-triplet 50k rays the same (22.6 against 22.5 ns a ray), 100k 9 % faster, 400k and 1M
/// 8-13 %; double Gauss 20k rays, whose results stay in cache, 5-14 % slower streamed.
const STREAM_RESULTS_FROM_RAYS: usize = 1 << 16;

/// A block's results gathered on the stack, where the block trace's scattered stores (a ray's
/// result when it stops) stay in the first-level cache, then streamed to the batch's results a
/// window at a time ([`BlockResults::store_streaming`]).
#[repr(C, align(64))]
struct StagedResults {
    outcomes: [Outcome; GROUP_RAYS],
    /// x, y, z, dx, dy, dz.
    columns: [[f64; GROUP_RAYS]; 6],
}

impl StagedResults {
    fn new() -> StagedResults {
        StagedResults {
            outcomes: [Outcome::Ok; GROUP_RAYS],
            columns: [[0.0; GROUP_RAYS]; 6],
        }
    }

    fn results(&mut self) -> BlockResults<'_> {
        let [x, y, z, dx, dy, dz] = &mut self.columns;
        BlockResults {
            outcomes: &mut self.outcomes,
            columns: [x, y, z, dx, dy, dz],
        }
    }
}

impl Finish for BlockResults<'_> {
    #[inline(always)]
    fn finish(&mut self, id: usize, traced: Traced) {
        let j = id % GROUP_RAYS;
        self.outcomes[j] = traced.outcome;
        store_ray(&mut self.columns, j, traced.ray);
    }
}

/// Writes `ray` into entry `j` of six columns (x, y, z, dx, dy, dz).
#[inline(always)]
fn store_ray<C: IndexMut<usize, Output = f64> + ?Sized>(
    columns: &mut [&mut C; 6],
    j: usize,
    ray: Ray,
) {
    let values = ray.position.into_iter().chain(ray.direction);
    for (column, value) in columns.iter_mut().zip(values) {
        column[j] = value;
    }
}

impl Tracer {
    /// Traces the rays of a group in columns (x, y, z, dx, dy, dz) whose lanes `chosen` marks
    /// together on this thread, apertures checked: `finish` gets each one's lane and result, bit
    /// for bit what [`Tracer::trace`] gives. For callers that make their rays a few dozen at a
    /// time, side by side (the renderer's samples of one pixel); the rays go from their columns
    /// into `block`'s without being assembled one by one in between.
    #[cfg(any(test, feature = "render"))]
    pub(crate) fn trace_group(
        &self,
        block: &mut GroupBlock,
        columns: &[[f64; GROUP_RAYS]; 6],
        chosen: &[bool],
        travel: Travel,
        mut finish: impl FnMut(usize, Traced),
    ) {
        block.load_chosen(columns, chosen);
        self.trace_block(block, travel, true, &mut super::lanes::NoVisit, &mut finish);
    }

    /// Traces every ray of `rays` on the current rayon thread pool.
    pub fn trace_batch(&self, rays: &RayBatch, travel: Travel, apertures: Apertures) -> BatchTrace {
        let mut out = BatchTrace::default();
        self.trace_batch_into(rays, travel, apertures, &mut out);
        out
    }

    /// [`Tracer::trace_batch`] into `out`, reusing its storage: a caller that traces batch
    /// after batch allocates the results (and the system maps their pages) once, not per call.
    pub fn trace_batch_into(
        &self,
        rays: &RayBatch,
        travel: Travel,
        apertures: Apertures,
        out: &mut BatchTrace,
    ) {
        let n = rays.len();
        resize_on(Pages::Huge, &mut out.outcomes, n, Outcome::Ok);
        out.rays.resize(n);
        let check = apertures == Apertures::Checked;
        let columns = rays.columns();
        let ended = &mut out.rays;
        let isa = Isa::detect();
        // Elsewhere `store_streaming` is an ordinary copy, which staging would only add.
        let streamed = cfg!(target_arch = "x86_64") && n >= STREAM_RESULTS_FROM_RAYS;
        out.ray_surfaces = out
            .outcomes
            .par_chunks_mut(CHUNK)
            .zip(ended.x.par_chunks_mut(CHUNK))
            .zip(ended.y.par_chunks_mut(CHUNK))
            .zip(ended.z.par_chunks_mut(CHUNK))
            .zip(ended.dx.par_chunks_mut(CHUNK))
            .zip(ended.dy.par_chunks_mut(CHUNK))
            .zip(ended.dz.par_chunks_mut(CHUNK))
            .enumerate()
            // A block and its staged results kept from chunk to chunk of a thread's share (what
            // a trace leaves in them does not change the next one's results): made afresh per
            // chunk, 43 KiB cleared per 1,024 rays, the trace was 1.5-4 % slower.
            .map_init(
                || (GroupBlock::new(), streamed.then(StagedResults::new)),
                |(block, staged), (chunk, ((((((outcomes, x), y), z), dx), dy), dz))| {
                    let start = chunk * CHUNK;
                    let chunk_len = outcomes.len();
                    let rays_from = |first: usize| {
                        let rays = start + first..start + first + GROUP_RAYS.min(chunk_len - first);
                        columns.map(|column| &column[rays.clone()])
                    };
                    let (outcome_blocks, outcomes_left) = outcomes.as_chunks_mut::<GROUP_RAYS>();
                    let [x, y, z, dx, dy, dz] =
                        [x, y, z, dx, dy, dz].map(|column| column.as_chunks_mut::<GROUP_RAYS>());
                    let mut trace_block = |k: usize, results: &mut BlockResults<'_>| {
                        let rays = rays_from(k * GROUP_RAYS);
                        self.trace_columns_on(isa, block, rays, travel, check, results)
                    };
                    let mut count = 0;
                    for (k, outcomes) in outcome_blocks.iter_mut().enumerate() {
                        let mut windows = BlockResults {
                            outcomes,
                            columns: [
                                &mut x.0[k],
                                &mut y.0[k],
                                &mut z.0[k],
                                &mut dx.0[k],
                                &mut dy.0[k],
                                &mut dz.0[k],
                            ],
                        };
                        count += match staged {
                            Some(staged) => {
                                let traced = trace_block(k, &mut staged.results());
                                windows.store_streaming(staged);
                                traced
                            }
                            None => trace_block(k, &mut windows),
                        };
                    }
                    if streamed {
                        fence_streaming_stores();
                    }
                    // A chunk's last, shorter block (a batch's last chunk) writes its slices
                    // directly, bounds checked: it runs once a batch.
                    if !outcomes_left.is_empty() {
                        let mut left = [x.1, y.1, z.1, dx.1, dy.1, dz.1];
                        let mut finish = |id: usize, traced: Traced| {
                            outcomes_left[id] = traced.outcome;
                            store_ray(&mut left, id, traced.ray);
                        };
                        let rays = rays_from(outcome_blocks.len() * GROUP_RAYS);
                        count +=
                            self.trace_columns_on(isa, block, rays, travel, check, &mut finish);
                    }
                    count
                },
            )
            .sum();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lenses::load;
    use crate::prescription::formats::LoadOptions;
    use crate::trace::FieldBundle;

    #[test]
    fn streamed_results_equal_single_rays() {
        // Large enough to take the streamed path, with a short last chunk and block; traced
        // into storage that held another batch's results, so every entry must be rewritten.
        let system = load("dgauss-50mm", &LoadOptions::default()).unwrap().system;
        let tracer = Tracer::new(&system.at(system.design_wavelength_nm()));
        let bundle = FieldBundle::over_traceable_field(&tracer).unwrap();
        let n = STREAM_RESULTS_FROM_RAYS + 1001;
        let mut out = tracer.trace_batch(&bundle.sample(n, 1), Travel::Forward, Apertures::Checked);
        let rays = bundle.sample(n, 2);
        tracer.trace_batch_into(&rays, Travel::Forward, Apertures::Checked, &mut out);
        let mut vignetted = 0;
        for (i, ray) in rays.iter().enumerate() {
            let single = tracer.trace(ray, Travel::Forward);
            assert_eq!(out.outcomes[i], single.outcome, "ray {i}");
            assert_eq!(out.rays.get(i).unwrap(), single.ray, "ray {i}");
            vignetted += usize::from(!single.outcome.is_ok());
        }
        assert!(
            vignetted > n / 10 && vignetted < n / 2,
            "{vignetted} vignetted"
        );
    }
}
