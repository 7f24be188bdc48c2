//! Many rays at once: a structure-of-arrays batch traced in parallel with rayon.

use super::lanes::{Block, Finish, Isa, STRIDE, with_widest_isa};
use super::{Admit, Apertures, Outcome, Ray, RayError, Traced, Tracer, Travel, Vec3};
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

/// Where [`Tracer::trace_rows_into`] writes, one entry per ray: the final ray as
/// [`BatchTrace`] holds it (see [`super::Traced`]) and the outcome as [`Outcome::code`] gives it.
/// Rows and plain codes are the layout callers in other languages hold arrays in (NumPy's
/// n x 3, a C array of structs), so results go there without a copy.
pub struct RowResults<'a> {
    pub positions: &'a mut [Vec3],
    pub directions: &'a mut [Vec3],
    /// [`Outcome::CODE_OK`] and the other kinds.
    pub outcome_kinds: &'a mut [u8],
    /// 1-based surface where the ray stopped; 0 for a ray that crossed every surface.
    pub outcome_surfaces: &'a mut [u32],
}

/// Why [`Tracer::trace_rows_into`] traced nothing.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RowsError {
    #[error("{what} has {len} rows where the positions have {expected}: give one per ray")]
    Length {
        what: &'static str,
        len: usize,
        expected: usize,
    },
    #[error("ray {row}: {source}")]
    Ray { row: usize, source: RayError },
}

/// A block's results as rows and codes, staged as the block trace finishes its rays (in the
/// order they stop) and written out a block at a time, in ray order: with streaming stores
/// where the batch is large (see [`STREAM_RESULTS_FROM_RAYS`]), a plain copy otherwise. Rows
/// written where each ray stopped, and rows gathered from staged columns afterwards, were both
/// slower (see [`Tracer::trace_rows_into`]).
#[repr(C, align(64))]
struct StagedRows {
    positions: [Vec3; GROUP_RAYS],
    directions: [Vec3; GROUP_RAYS],
    kinds: [u8; GROUP_RAYS],
    surfaces: [u32; GROUP_RAYS],
    streamed: bool,
}

impl Finish for StagedRows {
    #[inline(always)]
    fn finish(&mut self, id: usize, traced: Traced) {
        let j = id % GROUP_RAYS;
        self.positions[j] = traced.ray.position;
        self.directions[j] = traced.ray.direction;
        (self.kinds[j], self.surfaces[j]) = traced.outcome.code();
    }
}

impl StagedRows {
    fn new(streamed: bool) -> StagedRows {
        StagedRows {
            positions: [[0.0; 3]; GROUP_RAYS],
            directions: [[0.0; 3]; GROUP_RAYS],
            kinds: [0; GROUP_RAYS],
            surfaces: [0; GROUP_RAYS],
            streamed,
        }
    }

    /// Writes the staged rows into `out` from row `first` on, as many as `out` holds from
    /// there up to a block.
    fn store(&self, first: usize, out: RowResults<'_>) {
        let len = (out.positions.len() - first).min(GROUP_RAYS);
        let window = first..first + len;
        if let (true, Ok(positions), Ok(directions), Ok(kinds), Ok(surfaces)) = (
            self.streamed,
            <&mut [Vec3; GROUP_RAYS]>::try_from(&mut out.positions[window.clone()]),
            <&mut [Vec3; GROUP_RAYS]>::try_from(&mut out.directions[window.clone()]),
            <&mut [u8; GROUP_RAYS]>::try_from(&mut out.outcome_kinds[window.clone()]),
            <&mut [u32; GROUP_RAYS]>::try_from(&mut out.outcome_surfaces[window.clone()]),
        ) {
            store_streaming(positions, &self.positions);
            store_streaming(directions, &self.directions);
            store_streaming(kinds, &self.kinds);
            store_streaming(surfaces, &self.surfaces);
            return;
        }
        out.positions[window.clone()].copy_from_slice(&self.positions[..len]);
        out.directions[window.clone()].copy_from_slice(&self.directions[..len]);
        out.outcome_kinds[window.clone()].copy_from_slice(&self.kinds[..len]);
        out.outcome_surfaces[window].copy_from_slice(&self.surfaces[..len]);
    }
}

/// Rows into a block's columns, each made a ray as [`Ray::new`] makes it, then admitted by
/// `admit`; the first row is number `first_row` in errors. Copied whole first, then normalised
/// in place in one branch-free pass over the columns, which the compiler runs in vector lanes
/// (inlined where [`with_widest_isa`] compiles it, with fused multiply-adds); a block holding
/// any ray that is not a common one goes again ray by ray, the careful way. Made one by one,
/// each ray's parts went through the stack and waited there on stores of other sizes, and the
/// per-ray branches and divisions kept the loop out of vector lanes (see
/// [`Tracer::trace_rows_into`]).
#[inline(always)]
fn load_rows(
    columns: &mut [[f64; GROUP_RAYS]; 6],
    positions: &[Vec3],
    directions: &[Vec3],
    first_row: usize,
    admit: &impl Admit,
) -> Result<(), RowsError> {
    let [x, y, z, dx, dy, dz] = columns;
    let len = positions.len().min(GROUP_RAYS);
    for (j, (&[px, py, pz], &[ux, uy, uz])) in positions.iter().zip(directions).enumerate() {
        [x[j], y[j], z[j], dx[j], dy[j], dz[j]] = [px, py, pz, ux, uy, uz];
    }
    let refused = |j: usize| {
        move |source| RowsError::Ray {
            row: first_row + j,
            source,
        }
    };
    let mut all_common = true;
    for j in 0..len {
        let direction = [dx[j], dy[j], dz[j]];
        let (length, common) = Ray::common_length([x[j], y[j], z[j]], direction);
        all_common &= common;
        [dx[j], dy[j], dz[j]] = direction.map(|v| v / length);
    }
    if !all_common {
        for (j, (&position, &direction)) in positions.iter().zip(directions).enumerate() {
            [dx[j], dy[j], dz[j]] = Ray::new(position, direction).map_err(refused(j))?.direction;
        }
    }
    // Folded without an early exit, so the compare runs in vector lanes too.
    let all_admitted = admit.admitted_beyond().is_some_and(|(side, beyond)| {
        z[..len]
            .iter()
            .fold(true, |all, &z| all & (side * z >= beyond))
    });
    if !all_admitted {
        for j in 0..len {
            let ray = Ray::from_parts([x[j], y[j], z[j]], [dx[j], dy[j], dz[j]]);
            admit.admit(&ray).map_err(refused(j))?;
        }
    }
    Ok(())
}

impl Tracer {
    /// Traces rays given as rows of positions and directions (a direction of any non-zero
    /// length, normalised as [`Ray::new`] does) on the current rayon thread pool, each first
    /// passed to `admit` (a [`super::StartCheck`], or a closure: `|_: &Ray| Ok(())` admits every ray),
    /// and writes the results into `out` without allocating. Returns the number of ray-surface
    /// intersections computed.
    ///
    /// The rows are checked, gathered into the tracer's columns and traced a block at a time,
    /// so no intermediate [`RayBatch`] is built: for a caller whose arrays are rows, this is
    /// the trace with nothing around it. Made a ray at a time and written where each stopped,
    /// 1M rows took about 2.2x the batch trace of the same rays; loaded column-wise and staged
    /// as rows per block, 1.36-1.54x; with the load in vector lanes and the block admitted on
    /// the start check's bound, 1.12-1.20x (one thread, process CPU time, best of 9, loaded
    /// machine). What is left is the check and normalisation of each input ray, which the
    /// batch trace's rays, already made, skip.
    ///
    /// When a row is refused, one refusal (not necessarily the lowest row's) is returned and
    /// `out` holds partial results.
    ///
    /// ```
    /// use lensbake::trace::{RowResults, StartCheck};
    /// use lensbake::{Apertures, LoadOptions, Outcome, Tracer, Travel, load_lens};
    ///
    /// let system = load_lens("dgauss-50mm", &LoadOptions::default())?.system;
    /// let at = system.at(system.design_wavelength_nm());
    /// let tracer = Tracer::new(&at);
    /// let positions = [[0.0, 1.0, -10.0], [0.0, 40.0, -10.0]];
    /// let directions = [[0.0, 0.0, 1.0], [0.0, 0.0, 2.0]];
    /// let (mut end_positions, mut end_directions) = ([[0.0; 3]; 2], [[0.0; 3]; 2]);
    /// let (mut kinds, mut surfaces) = ([0u8; 2], [0u32; 2]);
    /// let out = RowResults {
    ///     positions: &mut end_positions,
    ///     directions: &mut end_directions,
    ///     outcome_kinds: &mut kinds,
    ///     outcome_surfaces: &mut surfaces,
    /// };
    /// let starts = StartCheck::new(&at, Travel::Forward);
    /// tracer.trace_rows_into(&positions, &directions, Travel::Forward, Apertures::Checked, &starts, out)?;
    /// // The ray 1 mm off axis crosses every surface and leaves converging towards the axis;
    /// // the one 40 mm off axis passes beside surface 1's
    /// // sphere (radius 29.475 mm) and misses it.
    /// assert_eq!((kinds[0], surfaces[0]), Outcome::Ok.code());
    /// assert_eq!((kinds[1], surfaces[1]), Outcome::Missed { surface: 1 }.code());
    /// assert!(end_directions[0][1] < 0.0 && end_positions[0][1] > 0.0);
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn trace_rows_into(
        &self,
        positions: &[Vec3],
        directions: &[Vec3],
        travel: Travel,
        apertures: Apertures,
        admit: &impl Admit,
        out: RowResults<'_>,
    ) -> Result<u64, RowsError> {
        let expected = positions.len();
        for (what, len) in [
            ("directions", directions.len()),
            ("the positions out", out.positions.len()),
            ("the directions out", out.directions.len()),
            ("the outcome kinds out", out.outcome_kinds.len()),
            ("the outcome surfaces out", out.outcome_surfaces.len()),
        ] {
            if len != expected {
                return Err(RowsError::Length {
                    what,
                    len,
                    expected,
                });
            }
        }
        let check = apertures == Apertures::Checked;
        let isa = Isa::detect();
        let streamed = cfg!(target_arch = "x86_64") && expected >= STREAM_RESULTS_FROM_RAYS;
        positions
            .par_chunks(CHUNK)
            .zip(directions.par_chunks(CHUNK))
            .zip(out.positions.par_chunks_mut(CHUNK))
            .zip(out.directions.par_chunks_mut(CHUNK))
            .zip(out.outcome_kinds.par_chunks_mut(CHUNK))
            .zip(out.outcome_surfaces.par_chunks_mut(CHUNK))
            .enumerate()
            .map_init(
                || (GroupBlock::new(), [[0.0; GROUP_RAYS]; 6], StagedRows::new(streamed)),
                |(block, columns, rows_out),
                 (chunk, (((((positions, directions), ends), headings), kinds), surfaces))| {
                    let mut count = 0;
                    for first in (0..positions.len()).step_by(GROUP_RAYS) {
                        let rays = first..positions.len().min(first + GROUP_RAYS);
                        with_widest_isa(
                            #[inline(always)]
                            |_| {
                            load_rows(
                                columns,
                                &positions[rays.clone()],
                                &directions[rays.clone()],
                                chunk * CHUNK + first,
                                admit,
                            )
                        })?;
                        let group = columns.each_ref().map(|column| &column[..rays.len()]);
                        count += self.trace_columns_on(isa, block, group, travel, check, rows_out);
                        rows_out.store(
                            first,
                            RowResults {
                                positions: ends,
                                directions: headings,
                                outcome_kinds: kinds,
                                outcome_surfaces: surfaces,
                            },
                        );
                    }
                    if rows_out.streamed {
                        fence_streaming_stores();
                    }
                    Ok(count)
                },
            )
            .try_reduce(|| 0, |a, b| Ok(a + b))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lenses::load;
    use crate::prescription::formats::LoadOptions;
    use crate::trace::{FieldBundle, StartCheck};

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

    /// Storage for a rows trace's results.
    struct RowStorage {
        ends: Vec<Vec3>,
        headings: Vec<Vec3>,
        kinds: Vec<u8>,
        surfaces: Vec<u32>,
    }

    impl RowStorage {
        fn new(n: usize) -> RowStorage {
            RowStorage {
                ends: vec![[0.0; 3]; n],
                headings: vec![[0.0; 3]; n],
                kinds: vec![9; n],
                surfaces: vec![9; n],
            }
        }

        fn results(&mut self) -> RowResults<'_> {
            RowResults {
                positions: &mut self.ends,
                directions: &mut self.headings,
                outcome_kinds: &mut self.kinds,
                outcome_surfaces: &mut self.surfaces,
            }
        }
    }

    /// The forward rows trace of `positions` and `directions` through `tracer`, admitted by
    /// `admit`, with apertures, into new storage; and its count of ray-surface intersections.
    fn trace_rows(
        tracer: &Tracer,
        positions: &[Vec3],
        directions: &[Vec3],
        admit: &impl Admit,
    ) -> (RowStorage, u64) {
        let mut out = RowStorage::new(positions.len());
        let results = out.results();
        let count = tracer
            .trace_rows_into(
                positions,
                directions,
                Travel::Forward,
                Apertures::Checked,
                admit,
                results,
            )
            .unwrap();
        (out, count)
    }

    #[test]
    fn rows_trace_as_the_batch_does() {
        // Enough rays for several chunks and a short last block, at a few direction lengths,
        // with one block holding directions whose squared length overflows and one whose
        // squared length is subnormal (the careful normalisation): every row's result must be
        // bit for bit the batch trace's of the normalised ray, admitted by a closure (ray by
        // ray) and by the start check (a block at a time, on its bound).
        let system = load("dgauss-50mm", &LoadOptions::default()).unwrap().system;
        let at = system.at(system.design_wavelength_nm());
        let tracer = Tracer::new(&at);
        let bundle = FieldBundle::over_traceable_field(&tracer).unwrap();
        let n = 3 * CHUNK + GROUP_RAYS + 17;
        let rays = bundle.sample(n, 3);
        let positions: Vec<Vec3> = rays.iter().map(|r| r.position).collect();
        let scale = |k: usize| match (k / GROUP_RAYS, k % 7) {
            (2, 0) => 1e200,
            (5, 0) => 1e-160,
            _ => (1 + k % 3) as f64,
        };
        let directions: Vec<Vec3> = rays
            .iter()
            .enumerate()
            .map(|(k, r)| r.direction.map(|v| v * scale(k)))
            .collect();
        let normalised: RayBatch = positions
            .iter()
            .zip(&directions)
            .map(|(&p, &d)| Ray::new(p, d).unwrap())
            .collect();
        let batch = tracer.trace_batch(&normalised, Travel::Forward, Apertures::Checked);
        let starts = StartCheck::new(&at, Travel::Forward);
        let every_ray = |_: &Ray| Ok(());
        let traced = [
            trace_rows(&tracer, &positions, &directions, &every_ray),
            trace_rows(&tracer, &positions, &directions, &starts),
        ];
        for (out, count) in traced {
            assert_eq!(count, batch.ray_surfaces);
            for k in 0..n {
                let ray = batch.rays.get(k).unwrap();
                assert_eq!(
                    (out.kinds[k], out.surfaces[k]),
                    batch.outcomes[k].code(),
                    "ray {k}"
                );
                assert_eq!(
                    (out.ends[k], out.headings[k]),
                    (ray.position, ray.direction),
                    "ray {k}"
                );
            }
            assert!(out.kinds.contains(&Outcome::CODE_VIGNETTED));
        }
    }

    #[test]
    fn the_start_check_refuses_the_row_that_starts_inside_among_admitted_blocks() {
        // Every block but one lies wholly beyond the check's bound and passes on it; the ray
        // behind surface 1's vertex must still be found, with its row.
        let system = load("dgauss-50mm", &LoadOptions::default()).unwrap().system;
        let at = system.at(system.design_wavelength_nm());
        let tracer = Tracer::new(&at);
        let n = CHUNK + 3 * GROUP_RAYS;
        let mut positions = vec![[0.0, 1.0, at.surfaces[0].vertex_z - 10.0]; n];
        let inside = CHUNK + GROUP_RAYS + 9;
        positions[inside][2] = at.surfaces[0].vertex_z + 1.0;
        let directions = vec![[0.0, 0.0, 1.0]; n];
        let mut out = RowStorage::new(n);
        let starts = StartCheck::new(&at, Travel::Forward);
        let refused = tracer.trace_rows_into(
            &positions,
            &directions,
            Travel::Forward,
            Apertures::Checked,
            &starts,
            out.results(),
        );
        assert!(
            matches!(
                refused,
                Err(RowsError::Ray {
                    row,
                    source: RayError::StartsInside { surface: 1, .. }
                }) if row == inside
            ),
            "{refused:?}"
        );
    }

    #[test]
    fn rows_name_the_refused_row_and_mismatched_lengths() {
        let system = load("dgauss-50mm", &LoadOptions::default()).unwrap().system;
        let tracer = Tracer::new(&system.at(system.design_wavelength_nm()));
        let n = 2 * CHUNK;
        let positions = vec![[0.0, 0.0, -10.0]; n];
        let mut directions = vec![[0.0, 0.0, 1.0]; n];
        directions[CHUNK + 5] = [0.0, 0.0, 0.0];
        let mut out = RowStorage::new(n);
        let refused = tracer.trace_rows_into(
            &positions,
            &directions,
            Travel::Forward,
            Apertures::Checked,
            &|_: &Ray| Ok(()),
            out.results(),
        );
        assert_eq!(
            refused,
            Err(RowsError::Ray {
                row: CHUNK + 5,
                source: RayError::ZeroDirection([0.0; 3])
            })
        );
        let short = tracer.trace_rows_into(
            &positions[1..],
            &directions[1..],
            Travel::Forward,
            Apertures::Checked,
            &|_: &Ray| Ok(()),
            out.results(),
        );
        assert!(matches!(
            short,
            Err(RowsError::Length {
                what: "the positions out",
                ..
            })
        ));
    }

    #[test]
    fn the_start_check_admits_without_the_sag_only_what_the_sag_admits() {
        // Rays from twice the sag bound in front of the start surface to twice it behind, at
        // heights past the rim, on every bundled lens (spheres, aspheres, mirrors) both ways:
        // the shortcut may only skip the sag where the sag would admit the ray too.
        use crate::trace::UnitDraws;
        let mut draws = UnitDraws::new(11);
        let mut shortcut_taken = 0;
        for lens in crate::lenses::BUNDLED {
            let system = load(lens.name, &LoadOptions::default()).unwrap().system;
            let at = system.at(system.design_wavelength_nm());
            for travel in [Travel::Forward, Travel::Backward] {
                let check = StartCheck::new(&at, travel);
                let Some((_, surface)) = check.surface else {
                    continue;
                };
                let rim = surface.geometric_semi_aperture;
                let reach = 2.0 * surface.shape.sag_bound(rim).unwrap_or(1.0) + 1e-3;
                for _ in 0..2000 {
                    let [h, phi, t] = [draws.next(), draws.next(), draws.next()];
                    let height = 1.5 * rim * h;
                    let z = surface.vertex_z + reach * (2.0 * t - 1.0);
                    let (s, c) = (std::f64::consts::TAU * phi).sin_cos();
                    let ray = Ray::new([height * c, height * s, z], [0.0, 0.0, 1.0]).unwrap();
                    let full = check.check_at_height(&ray).is_ok();
                    assert_eq!(
                        check.check(&ray).is_ok(),
                        full,
                        "{} {travel:?} {ray:?}",
                        lens.name
                    );
                    shortcut_taken += usize::from(check.side * z >= check.admitted_beyond);
                }
            }
        }
        assert!(
            shortcut_taken > 1000,
            "{shortcut_taken} rays took the shortcut"
        );
    }
}
