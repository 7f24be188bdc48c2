//! Rays in blocks, surface by surface, for throughput.
//!
//! One ray's trace is a chain of dependent square roots and divisions, so a single ray keeps
//! the floating-point units mostly waiting. A [`Block`] holds up to 256 rays as columns
//! (structure of arrays) and crosses one surface with all of them before the next, so the
//! processor overlaps independent chains and the straight-line kernels below pack [`STRIDE`]
//! rays into vector instructions. After each surface the rays that stopped are reported, and
//! once enough have stopped to free a whole stride the survivors are packed to the front of
//! the block, so rays vignetted at surface 3 cost little at surfaces 4..N: the kernels only
//! run over the strides in use. Which rays travel is a bit per slot ([`Slots`]).
//!
//! Spheres, planes and conics (almost every surface of a real lens) have kernels; aspheres are
//! met in vector lanes ([`intersect::AsphereLanes::meet`]) and then go through the aperture and bend
//! one ray at a time; mirrors, obscured surfaces and the bladed stop use the one-ray code
//! ([`Tracer::cross`]) for each live ray. The kernels and lanes call the same branch-free
//! arithmetic as the one-ray path (`*_candidate` in `intersect` and `refract`, or for a sphere
//! the stages those are made of, each run over the whole block in a loop of its own: every
//! multiply-add fused the same way), so both give bit-identical results (tested).
//!
//! The whole block trace is compiled three times, for AVX-512, for AVX2 with FMA and for the
//! baseline instruction set, and picked at run time ([`Isa::detect`]). Fused multiply-adds and
//! vector square roots and divisions are rounded exactly, so the three give the same bits; on
//! a processor without FMA, `f64::mul_add` is a (slow, correctly rounded) library call.

use super::aperture::Diaphragm;
use super::intersect::{self, LaneHits, Lanes, NEWTON_LANES, clamped_sqrt, radius_sq};
use super::refract;
use super::{
    Event, FlatSurface, Outcome, Profile, Ray, Traced, Tracer, Travel, Vec3, in_vertex_frame,
    unbent,
};

/// Rays one vector instruction holds at most (eight f64 with AVX-512). Kernels run over whole
/// strides; slots of stopped rays, and past the last ray, compute numbers nobody reads.
pub(crate) const STRIDE: usize = 8;

/// Rays of a small group: the renderer's samples of one pixel, the bake's table nodes.
pub(crate) const LANES: usize = 2 * STRIDE;

/// A group of at most [`LANES`] rays.
pub(crate) type Group = Block<{ LANES / STRIDE }>;

/// What a kernel says about each ray; 64-bit so that the codes live in the same vector lanes as
/// the f64 comparisons they come from.
const CROSSED: u64 = 0;
const MISSED: u64 = 1;
const VIGNETTED: u64 = 2;
/// Met inside the apertures, but the bend gave no direction: total internal reflection, or an
/// ideal lens's tangents past what f64 holds (which the one-ray path reports as a miss at the
/// hit point).
const NOT_BENT: u64 = 3;

/// A set of a block's slots, one bit per slot in 64-bit words (blocks hold at most
/// [`Slots::CAPACITY`] rays). The block's bookkeeping (which rays stopped at a surface, which
/// holes packing fills) works on these bits a stride or a whole block at a time instead of slot
/// by slot.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Slots([u64; SLOT_WORDS]);

/// The words of a [`Slots`].
const SLOT_WORDS: usize = 4;

impl Slots {
    const CAPACITY: usize = 64 * SLOT_WORDS;

    /// Slots `0..n`.
    fn first(n: usize) -> Slots {
        debug_assert!(n <= Slots::CAPACITY);
        Slots(std::array::from_fn(|w| {
            let bits = n.saturating_sub(64 * w).min(64);
            u64::MAX.checked_shr(64 - bits as u32).unwrap_or(0)
        }))
    }

    pub fn contains(self, slot: usize) -> bool {
        (self.0[slot / 64] >> (slot % 64)) & 1 != 0
    }

    fn len(self) -> usize {
        self.0.iter().map(|w| w.count_ones() as usize).sum()
    }

    fn is_empty(self) -> bool {
        self.0.iter().all(|&w| w == 0)
    }

    fn and(self, other: Slots) -> Slots {
        Slots(std::array::from_fn(|w| self.0[w] & other.0[w]))
    }

    fn without(self, other: Slots) -> Slots {
        Slots(std::array::from_fn(|w| self.0[w] & !other.0[w]))
    }

    /// The set whose `w`th word is the `w`th of `words` (the words `words` does not reach are
    /// empty).
    fn from_words(words: impl Iterator<Item = u64>) -> Slots {
        let mut slots = Slots::default();
        for (word, bits) in slots.0.iter_mut().zip(words) {
            *word = bits;
        }
        slots
    }

    /// The slots in increasing order.
    fn iter(self) -> SlotIter {
        SlotIter {
            words: self.0,
            word: 0,
        }
    }
}

/// The slots of a [`Slots`], lowest first, found 64 bits at a time (with 128-bit scans and
/// borrows the trace was about 3 % slower, criterion).
struct SlotIter {
    words: [u64; SLOT_WORDS],
    /// The word being scanned: the ones before it are empty.
    word: usize,
}

impl Iterator for SlotIter {
    type Item = usize;

    #[inline(always)]
    fn next(&mut self) -> Option<usize> {
        while self.word < SLOT_WORDS {
            let bits = &mut self.words[self.word];
            if *bits != 0 {
                let slot = 64 * self.word + bits.trailing_zeros() as usize;
                *bits &= *bits - 1;
                return Some(slot);
            }
            self.word += 1;
        }
        None
    }
}

/// Positions and directions of a block's slots: six columns (x, y, z, then dx, dy, dz), each
/// in strides of [`STRIDE`]. Each stride on a cache line of its own: the kernels read and write a
/// stride with one 64-byte access per column, and where a block happened to sit 8 bytes off a
/// line on the stack every such access was split across two lines.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct Columns<const STRIDES: usize> {
    values: [[[f64; STRIDE]; STRIDES]; 6],
}

impl<const STRIDES: usize> Columns<STRIDES> {
    const ZERO: Columns<STRIDES> = Columns {
        values: [[[0.0; STRIDE]; STRIDES]; 6],
    };

    fn column(&self, k: usize) -> &[f64] {
        self.values[k].as_flattened()
    }

    fn column_mut(&mut self, k: usize) -> &mut [f64] {
        self.values[k].as_flattened_mut()
    }

    fn get(&self, k: usize, slot: usize) -> f64 {
        self.values[k][slot / STRIDE][slot % STRIDE]
    }

    fn position(&self, slot: usize) -> Vec3 {
        [0, 1, 2].map(|k| self.get(k, slot))
    }

    fn set(&mut self, slot: usize, ray: Ray) {
        let values = ray.position.into_iter().chain(ray.direction);
        for (k, value) in values.enumerate() {
            self.values[k][slot / STRIDE][slot % STRIDE] = value;
        }
    }

    fn move_slot(&mut self, from: usize, to: usize) {
        for k in 0..6 {
            let column = self.column_mut(k);
            column[to] = column[from];
        }
    }
}

/// Up to `STRIDES` x [`STRIDE`] rays in flight, each with the caller's number for it.
///
/// In C order so that the codes, a cache line a stride, follow the line-aligned columns.
#[derive(Clone, Debug)]
#[repr(C)]
pub(crate) struct Block<const STRIDES: usize> {
    /// Two copies of the columns: a kernel reads one and writes the other, so a ray that stops
    /// still has the state it arrived with.
    columns: [Columns<STRIDES>; 2],
    /// Code per slot from the last kernel.
    events: [[u64; STRIDE]; STRIDES],
    /// The caller's number of the ray in each slot.
    ids: [[u32; STRIDE]; STRIDES],
    /// Rays loaded (they fill the first slots of `columns[0]`).
    loaded: usize,
}

impl<const STRIDES: usize> Block<STRIDES> {
    pub const CAPACITY: usize = STRIDES * STRIDE;

    pub fn new() -> Block<STRIDES> {
        const {
            assert!(
                Self::CAPACITY <= Slots::CAPACITY,
                "a block's slots fit one Slots"
            )
        };
        Block {
            columns: [Columns::ZERO; 2],
            ids: [[0; STRIDE]; STRIDES],
            events: [[CROSSED; STRIDE]; STRIDES],
            loaded: 0,
        }
    }

    /// Loads `rays` (at most [`Block::CAPACITY`]), numbered from 0 in order.
    pub fn load(&mut self, rays: &[Ray]) {
        debug_assert!(rays.len() <= Self::CAPACITY);
        for (slot, ray) in rays.iter().enumerate() {
            self.columns[0].set(slot, *ray);
        }
        self.number(rays.len());
    }

    /// Loads the rays of six columns (x, y, z, dx, dy, dz) of equal length (at most
    /// [`Block::CAPACITY`]), numbered from 0 in order.
    fn load_columns(&mut self, columns: [&[f64]; 6]) {
        let len = columns[0].len();
        debug_assert!(len <= Self::CAPACITY);
        for (k, column) in columns.into_iter().enumerate() {
            self.columns[0].column_mut(k)[..len].copy_from_slice(column);
        }
        self.number(len);
    }

    /// Loads the rays of a group in columns (x, y, z, dx, dy, dz) whose lanes `chosen` marks
    /// (at most [`Block::CAPACITY`] of them), each numbered by its lane.
    #[cfg(any(test, feature = "render"))]
    pub fn load_chosen<const G: usize>(&mut self, columns: &[[f64; G]; 6], chosen: &[bool]) {
        let mut slot = 0;
        for (lane, _) in chosen.iter().enumerate().filter(|(_, chosen)| **chosen) {
            debug_assert!(slot < Self::CAPACITY);
            for (k, column) in columns.iter().enumerate() {
                self.columns[0].values[k][slot / STRIDE][slot % STRIDE] = column[lane];
            }
            self.ids[slot / STRIDE][slot % STRIDE] = lane as u32;
            slot += 1;
        }
        self.loaded = slot;
    }

    fn number(&mut self, len: usize) {
        for (slot, id) in self.ids.as_flattened_mut()[..len].iter_mut().enumerate() {
            *id = slot as u32;
        }
        self.loaded = len;
    }
}

/// The instruction sets the block trace is compiled for, narrowest first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Isa {
    /// Whatever the build targets (SSE2 on x86-64); `mul_add` may be a library call.
    Portable,
    #[cfg(target_arch = "x86_64")]
    Avx2Fma,
    #[cfg(target_arch = "x86_64")]
    Avx512,
}

impl Isa {
    /// The widest set this processor runs, or the narrower one the environment variable
    /// `LENSBAKE_ISA` names (`portable`, `avx2`, `avx512`), for measurements; never one the
    /// processor lacks. Found once per process.
    pub fn detect() -> Isa {
        static CHOSEN: std::sync::OnceLock<Isa> = std::sync::OnceLock::new();
        *CHOSEN.get_or_init(|| {
            let widest = Isa::widest();
            let asked = match std::env::var("LENSBAKE_ISA").as_deref() {
                Ok("portable") => Isa::Portable,
                #[cfg(target_arch = "x86_64")]
                Ok("avx2") => Isa::Avx2Fma,
                _ => widest,
            };
            asked.min(widest)
        })
    }

    fn widest() -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            let avx2_set = Isa::has_avx2_set();
            if avx2_set && has!("avx512f") && has!("avx512dq") && has!("avx512vl") {
                return Isa::Avx512;
            }
            if avx2_set {
                return Isa::Avx2Fma;
            }
        }
        Isa::Portable
    }

    /// Whether this processor has the AVX2 set: AVX2, FMA, and F16C, POPCNT, BMI1 and BMI2,
    /// which every AVX2 processor has too. They are asked for so that the table's f16 widening
    /// and its interpolation inline into code compiled for the set, and a block's slot sets are
    /// counted and scanned in one instruction each (the baseline set counts bits in software).
    #[cfg(target_arch = "x86_64")]
    pub(crate) fn has_avx2_set() -> bool {
        use std::arch::is_x86_feature_detected as has;
        has!("avx2")
            && has!("fma")
            && has!("f16c")
            && has!("popcnt")
            && has!("bmi1")
            && has!("bmi2")
    }

    /// Whether multiply-adds are single instructions.
    pub fn fused(self) -> bool {
        self != Isa::Portable
    }

    /// Whether the set has AVX2 and F16C (every set but the portable one: [`Isa::widest`]
    /// requires them), so code compiled for it may use their intrinsics.
    pub fn has_avx2_f16c(self) -> bool {
        self != Isa::Portable
    }
}

/// Runs `body` compiled for the widest instruction set this processor has (see [`Isa`]):
/// `body` and everything it calls that is `inline(always)` is compiled once per set, which lets
/// branch-free loops over lanes use the widest vectors. `body` is handed the set, a constant in
/// each copy, so code it inlines can pick intrinsics for that set (the table's interpolation)
/// instead of asking the processor again. The values are the same on every set: no
/// multiply-add is fused unless written as one.
#[inline(always)]
pub(crate) fn with_widest_isa<R>(body: impl FnOnce(Isa) -> R) -> R {
    match Isa::detect() {
        Isa::Portable => body(Isa::Portable),
        #[cfg(target_arch = "x86_64")]
        // SAFETY: `detect` names only sets the processor has.
        Isa::Avx2Fma => unsafe { run_avx2_fma(body) },
        #[cfg(target_arch = "x86_64")]
        // SAFETY: as above.
        Isa::Avx512 => unsafe { run_avx512(body) },
    }
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma,f16c,popcnt,bmi1,bmi2")]
fn run_avx2_fma<R>(body: impl FnOnce(Isa) -> R) -> R {
    body(Isa::Avx2Fma)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,fma,f16c,popcnt,bmi1,bmi2")]
fn run_avx512<R>(body: impl FnOnce(Isa) -> R) -> R {
    body(Isa::Avx512)
}

/// What a visitor sees after each surface: the surface's 0-based index and, for every slot in
/// use, the number of the ray in it, whether that ray is still travelling (in `travelling`)
/// and its hit point on the surface (x and y, lens frame). Slots of rays that have stopped hold
/// meaningless numbers.
pub(crate) trait LaneVisitor {
    fn crossed(&mut self, surface: usize, ids: &[u32], travelling: Slots, x: &[f64], y: &[f64]);
}

/// Where a block trace's results go: each ray's number (its index among the rays loaded) and
/// result.
pub(crate) trait Finish {
    /// A ray's result.
    fn finish(&mut self, id: usize, traced: Traced);
}

impl<F: FnMut(usize, Traced)> Finish for F {
    #[inline(always)]
    fn finish(&mut self, id: usize, traced: Traced) {
        self(id, traced)
    }
}

/// The visitor of a plain trace.
pub(crate) struct NoVisit;

impl LaneVisitor for NoVisit {
    #[inline(always)]
    fn crossed(&mut self, _: usize, _: &[u32], _: Slots, _: &[f64], _: &[f64]) {}
}

/// Where a block's rays are before its first surface.
#[derive(Clone, Copy)]
enum Start<'a> {
    /// In the block's own columns.
    Loaded,
    /// In the caller's columns (x, y, z, dx, dy, dz, whole strides of them), which the first
    /// kernel reads in place. Copying them into the block was 9 % of a batch trace's profile;
    /// read in place, `bench trace` runs 3-5 % faster.
    Columns([&'a [f64]; 6]),
}

impl Tracer {
    /// Traces up to [`LANES`] rays together on this thread: `finish` gets each ray's number
    /// (its index in `rays`) and its result, bit for bit what [`Tracer::trace_with`] gives, and
    /// `visit` sees every surface crossed.
    pub(crate) fn trace_group_visiting(
        &self,
        rays: &[Ray],
        travel: Travel,
        check_apertures: bool,
        visit: &mut impl LaneVisitor,
        finish: &mut impl FnMut(usize, Traced),
    ) {
        let mut group = Group::new();
        group.load(rays);
        self.trace_block(&mut group, travel, check_apertures, visit, finish);
    }

    /// Traces a loaded block through every surface in `travel` order with the widest
    /// instruction set the processor has. `finish` gets every ray's number and result (in no
    /// particular order); returns the number of ray-surface intersections computed.
    pub(crate) fn trace_block<const STRIDES: usize>(
        &self,
        block: &mut Block<STRIDES>,
        travel: Travel,
        check_apertures: bool,
        visit: &mut impl LaneVisitor,
        finish: &mut impl Finish,
    ) -> u64 {
        self.trace_block_on(Isa::detect(), block, travel, check_apertures, visit, finish)
    }

    /// [`Tracer::trace_block`] with the code compiled for `isa`, which the processor must run.
    pub(crate) fn trace_block_on<const STRIDES: usize>(
        &self,
        isa: Isa,
        block: &mut Block<STRIDES>,
        travel: Travel,
        check_apertures: bool,
        visit: &mut impl LaneVisitor,
        finish: &mut impl Finish,
    ) -> u64 {
        let start = Start::Loaded;
        self.trace_from(isa, block, start, travel, check_apertures, visit, finish)
    }

    /// Traces the rays of six columns (x, y, z, dx, dy, dz) of equal length, at most
    /// [`Block::CAPACITY`], numbered from 0 in order, in `block` with the code compiled for
    /// `isa` (as [`Tracer::trace_block_on`], with no visitor).
    pub(crate) fn trace_columns_on<const STRIDES: usize>(
        &self,
        isa: Isa,
        block: &mut Block<STRIDES>,
        columns: [&[f64]; 6],
        travel: Travel,
        check_apertures: bool,
        finish: &mut impl Finish,
    ) -> u64 {
        let len = columns[0].len();
        // The kernels cross whole strides, and without surfaces the survivors are read from
        // the block's columns.
        if !len.is_multiple_of(STRIDE) || self.surfaces.is_empty() {
            block.load_columns(columns);
            return self.trace_block_on(isa, block, travel, check_apertures, &mut NoVisit, finish);
        }
        block.number(len);
        let start = Start::Columns(columns);
        self.trace_from(
            isa,
            block,
            start,
            travel,
            check_apertures,
            &mut NoVisit,
            finish,
        )
    }

    #[allow(clippy::too_many_arguments)]
    fn trace_from<const STRIDES: usize>(
        &self,
        isa: Isa,
        block: &mut Block<STRIDES>,
        start: Start<'_>,
        travel: Travel,
        check_apertures: bool,
        visit: &mut impl LaneVisitor,
        finish: &mut impl Finish,
    ) -> u64 {
        // SAFETY (each machine): callers pass an `isa` no wider than `Isa::widest` found on
        // this processor (`Isa::detect` never is).
        unsafe {
            match isa {
                Isa::Portable => self.on_machine::<Portable, STRIDES>(
                    block,
                    start,
                    travel,
                    check_apertures,
                    visit,
                    finish,
                ),
                #[cfg(target_arch = "x86_64")]
                Isa::Avx2Fma => self.on_machine::<Avx2Fma, STRIDES>(
                    block,
                    start,
                    travel,
                    check_apertures,
                    visit,
                    finish,
                ),
                #[cfg(target_arch = "x86_64")]
                Isa::Avx512 => self.on_machine::<Avx512, STRIDES>(
                    block,
                    start,
                    travel,
                    check_apertures,
                    visit,
                    finish,
                ),
            }
        }
    }

    /// # Safety
    /// The processor runs machine `M`'s instructions.
    unsafe fn on_machine<M: Machine, const STRIDES: usize>(
        &self,
        block: &mut Block<STRIDES>,
        start: Start<'_>,
        travel: Travel,
        check_apertures: bool,
        visit: &mut impl LaneVisitor,
        finish: &mut impl Finish,
    ) -> u64 {
        // SAFETY: passed on from the caller.
        unsafe {
            match travel {
                Travel::Forward => {
                    M::trace::<true, STRIDES>(self, block, start, check_apertures, visit, finish)
                }
                Travel::Backward => {
                    M::trace::<false, STRIDES>(self, block, start, check_apertures, visit, finish)
                }
            }
        }
    }

    #[inline(always)]
    fn block_body<const FORWARD: bool, const STRIDES: usize, M: Machine>(
        &self,
        block: &mut Block<STRIDES>,
        mut start: Start<'_>,
        check_apertures: bool,
        visit: &mut impl LaneVisitor,
        finish: &mut impl Finish,
    ) -> u64 {
        let Block {
            columns: [first, second],
            ids,
            events,
            loaded,
        } = block;
        let ids = ids.as_flattened_mut();
        let (mut current, mut next) = (first, second);
        // Slots in use (a prefix), and the rays among them still travelling.
        let mut occupied = *loaded;
        let mut travelling = Slots::first(occupied);
        let mut ray_surfaces = 0u64;
        let n = self.surfaces.len();
        for step in 0..n {
            if travelling.is_empty() {
                break;
            }
            let arriving = match start {
                Start::Columns(columns) => columns,
                Start::Loaded => current
                    .values
                    .each_ref()
                    .map(|column| column.as_flattened()),
            };
            start = Start::Loaded;
            ray_surfaces += travelling.len() as u64;
            let i = if FORWARD { step } else { n - 1 - step };
            let s = &self.surfaces[i];
            let strides = occupied.div_ceil(STRIDE);
            // The kernel of a crossing type for what the surface does to the direction.
            macro_rules! bending {
                ($crossing:ident) => {
                    Some(match Bend::of(s) {
                        Bend::Refract => M::kernel::<$crossing<FORWARD, REFRACT>, STRIDES>,
                        Bend::Straight => M::kernel::<$crossing<FORWARD, STRAIGHT>, STRIDES>,
                        Bend::Reflect => M::kernel::<$crossing<FORWARD, REFLECT>, STRIDES>,
                    })
                };
            }
            let kernel: Option<Kernel<STRIDES>> = match s.profile {
                Profile::Sphere { .. } => bending!(SphereCrossing),
                Profile::Plane => bending!(PlaneCrossing),
                Profile::Conic { .. } => bending!(ConicCrossing),
                Profile::IdealLens { .. } => Some(M::kernel::<IdealLensCrossing<FORWARD>, STRIDES>),
                Profile::Asphere { .. } => None,
            };
            let blades = self
                .diaphragm
                .as_ref()
                .filter(|_| s.bladed && check_apertures);
            match kernel {
                Some(kernel) => {
                    let [px, py, pz, dx, dy, dz] = arriving;
                    // SAFETY: the block trace runs on machine `M` only where its caller found
                    // the processor runs `M`'s instructions.
                    unsafe {
                        kernel(
                            s,
                            px,
                            py,
                            pz,
                            dx,
                            dy,
                            dz,
                            next,
                            events,
                            strides,
                            KernelApertures {
                                check: check_apertures,
                                blades,
                            },
                        )
                    }
                }
                None => self.cross_asphere::<FORWARD, STRIDES>(
                    s,
                    arriving,
                    travelling,
                    check_apertures,
                    blades,
                    next,
                    events,
                    strides,
                ),
            }
            // SAFETY: as above.
            let stopped = unsafe { M::stopped_slots(events, strides) }.and(travelling);
            report(
                i,
                unbent(s.profile.ideal_power()),
                arriving,
                next,
                events.as_flattened(),
                ids,
                stopped,
                finish,
            );
            travelling = travelling.without(stopped);
            // Packing costs a copy per hole filled, worth it only when the kernels then run over
            // fewer strides.
            let count = travelling.len();
            if !stopped.is_empty() && count.div_ceil(STRIDE) < strides {
                pack(next, ids, travelling, count);
                travelling = Slots::first(count);
                occupied = count;
            }
            std::mem::swap(&mut current, &mut next);
            let (x, y) = (
                &current.column(0)[..occupied],
                &current.column(1)[..occupied],
            );
            visit.crossed(i, &ids[..occupied], travelling, x, y);
        }
        let survivors = current
            .values
            .each_ref()
            .map(|column| column.as_flattened());
        for slot in travelling.iter() {
            let ray = ray_at(survivors, slot);
            finish.finish(
                ids[slot] as usize,
                Traced {
                    outcome: Outcome::Ok,
                    ray,
                },
            );
        }
        ray_surfaces
    }
}

impl Tracer {
    /// [`Tracer::cross`] of the `travelling` rays of `arriving` at the asphere `s`, each slot's
    /// leaving ray to `next` and its code to `events`, as a kernel leaves them:
    /// [`intersect::NEWTON_LANES`] rays at a time, met side by side in vector lanes
    /// ([`intersect::AsphereLanes::meet`], the same bits as one ray's search), then through the
    /// aperture and bent in lanes ([`leave_lanes`]), then through the `blades` over the first
    /// `strides` strides.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn cross_asphere<const FORWARD: bool, const STRIDES: usize>(
        &self,
        s: &FlatSurface,
        arriving: [&[f64]; 6],
        travelling: Slots,
        check_apertures: bool,
        blades: Option<&Diaphragm>,
        next: &mut Columns<STRIDES>,
        events: &mut [[u64; STRIDE]; STRIDES],
        strides: usize,
    ) {
        const L: usize = intersect::NEWTON_LANES;
        let Profile::Asphere {
            curvature,
            conic_factor,
            terms,
        } = s.profile
        else {
            unreachable!("only aspheres are met in lanes")
        };
        let asphere = intersect::AsphereLanes {
            curvature,
            conic_factor,
            terms: &self.asphere_terms[terms],
            sense: s.sense::<FORWARD>(),
        };
        let common = Common::new::<FORWARD>(s, check_apertures);
        let bend = Bend::of(s);
        let mut slots = travelling.iter();
        let mut hits = LaneHits::default();
        loop {
            let mut chosen = [0; L];
            let count = chosen
                .iter_mut()
                .zip(&mut slots)
                .map(|(chosen, slot)| *chosen = slot)
                .count();
            if count == 0 {
                break;
            }
            let mut lines = intersect::LaneLines {
                p: [[0.0; L]; 3],
                d: [[0.0; L]; 3],
            };
            // Lanes past the last ray repeat it. (The rays in an array built by
            // `array::from_fn` cost a call per lane where the compiler stopped inlining it.)
            for l in 0..L {
                let ray = ray_at(arriving, chosen[l.min(count - 1)]);
                let (position, direction, _) = in_vertex_frame::<FORWARD>(s, &ray);
                for axis in 0..3 {
                    lines.p[axis][l] = position[axis];
                    lines.d[axis][l] = direction[axis];
                }
            }
            asphere.meet(&lines, &mut hits);
            let (codes, directions) = leave_lanes(&common, bend, &lines.d, &hits);
            let [x, y, z] = &hits.points;
            for (l, &slot) in chosen[..count].iter().enumerate() {
                next.set(
                    slot,
                    Ray::from_parts(
                        [x[l], y[l], z[l] + s.vertex_z],
                        [directions[0][l], directions[1][l], directions[2][l]],
                    ),
                );
                events[slot / STRIDE][slot % STRIDE] = codes[l];
            }
        }
        if let Some(blades) = blades {
            vignette_outside_blades(blades, next, events, strides);
        }
    }
}

/// A kernel compiled for one machine ([`Machine::kernel`]): the surface, the arriving columns
/// (x, y, z, dx, dy, dz), the columns it writes, the event codes, the strides crossed and
/// the apertures it tests.
// Each arriving column is a parameter of its own: passed as an array of the six slices, by
// value or by reference, most of the AVX2 kernels' arithmetic compiled to scalar instructions
// (580 scalar multiply-adds and 364 scalar multiplies, against none and 4) and the batch trace
// ran twice as slow; by my reading, only slices that are parameters are known not to overlap
// `next`.
type Kernel<const STRIDES: usize> = unsafe fn(
    &FlatSurface,
    &[f64],
    &[f64],
    &[f64],
    &[f64],
    &[f64],
    &[f64],
    &mut Columns<STRIDES>,
    &mut [[u64; STRIDE]; STRIDES],
    usize,
    KernelApertures<'_>,
);

/// The slots of the first `strides` strides whose code is not [`CROSSED`], found a stride at a
/// time (a vector compare and its mask).
#[inline(always)]
fn stopped_slots<const STRIDES: usize>(events: &[[u64; STRIDE]; STRIDES], strides: usize) -> Slots {
    // A 64-bit word per 64 slots: into one u128, each stride's bits took a two-word shift by
    // a variable count (see `stopped_slots_avx2`).
    let word = |strides: &[[u64; STRIDE]]| {
        let mut slots = 0u64;
        for (k, stride) in strides.iter().enumerate() {
            let bits = stride.iter().enumerate().fold(0u64, |bits, (lane, &code)| {
                bits | (u64::from(code != CROSSED) << lane)
            });
            slots |= bits << (k * STRIDE);
        }
        slots
    };
    Slots::from_words(events[..strides].chunks(64 / STRIDE).map(word))
}

/// [`stopped_slots`] with AVX2 instructions.
///
/// # Safety
/// The processor has AVX2; inlined into code compiled for it.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
unsafe fn stopped_slots_avx2<const STRIDES: usize>(
    events: &[[u64; STRIDE]; STRIDES],
    strides: usize,
) -> Slots {
    use std::arch::x86_64::{
        _mm256_castsi256_pd, _mm256_cmpeq_epi64, _mm256_loadu_si256, _mm256_movemask_pd,
        _mm256_setzero_si256,
    };
    const { assert!(CROSSED == 0, "a crossed ray's code is all zero bits") };
    let codes = &events.as_flattened()[..strides * STRIDE];
    // Each 64 slots gathered in a 64-bit register of their own, shifted by one instruction:
    // into one u128, each four codes' bits took a two-word shift by a variable count and its
    // fix-up for counts past 63 (`bench trace` 2.6 % slower, medians of 21). Or-ed into an
    // array indexed by the word, the bits went through memory, each four codes waiting for the
    // store before them.
    let word = |codes: &[u64]| {
        let mut stopped = 0u64;
        for (k, four) in codes.chunks_exact(4).enumerate() {
            // SAFETY: `four` holds four u64 (32 bytes); AVX2 is the caller's to ensure.
            let crossed = unsafe {
                let four = _mm256_loadu_si256(four.as_ptr().cast());
                _mm256_movemask_pd(_mm256_castsi256_pd(_mm256_cmpeq_epi64(
                    four,
                    _mm256_setzero_si256(),
                )))
            };
            stopped |= u64::from(!crossed as u8 & 0xf) << (4 * k);
        }
        stopped
    };
    // Filled in a loop here, not through `Slots::from_words`: the closure, compiled for AVX2,
    // was then called from the iterator's code compiled without it, and the batch trace ran
    // 38 % slower (double Gauss 0.0442 against 0.0320 s, medians of 11).
    let mut words = [0u64; SLOT_WORDS];
    for (w, chunk) in codes.chunks(64).enumerate() {
        words[w] = word(chunk);
    }
    Slots(words)
}

/// Marks vignetted the lanes of the first `strides` strides whose hit points (`next`'s x and y)
/// the kernel let through the stop's circle but `blades` stop, as the one-ray path tests the
/// blades after the circle and before the bend: a lane it could not bend is vignetted too.
#[inline(always)]
fn vignette_outside_blades<const STRIDES: usize>(
    blades: &Diaphragm,
    next: &Columns<STRIDES>,
    events: &mut [[u64; STRIDE]; STRIDES],
    strides: usize,
) {
    let [x, y, ..] = &next.values;
    for ((codes, x), y) in events[..strides].iter_mut().zip(x).zip(y) {
        let inside = blades.contains_each(x, y);
        for (code, inside) in codes.iter_mut().zip(inside) {
            let met = (*code == CROSSED) | (*code == NOT_BENT);
            *code = if met & !inside { VIGNETTED } else { *code };
        }
    }
}

/// [`Tracer::leave`] up to the blades, for lanes of lines along `d` that met an asphere as
/// `hits` says: each lane's code, as a kernel's, and its leaving direction (meaningless unless
/// crossed). The same tests in the same order (the hit, the aperture and the obscuration, the
/// bend) with the same arithmetic, so the same bits as one ray at a time.
#[inline(always)]
fn leave_lanes(
    common: &Common,
    bend: Bend,
    d: &[Lanes<f64>; 3],
    hits: &LaneHits,
) -> (Lanes<u64>, [Lanes<f64>; 3]) {
    // A loop per bend, so that no lane loop branches on it.
    match bend {
        Bend::Refract => bend_lanes(common, d, hits, |d, normal| {
            let (direction, radicand) = refract::refract_candidate(d, normal, common.mu);
            (direction, radicand >= 0.0)
        }),
        Bend::Straight => bend_lanes(common, d, hits, |d, _| (d, true)),
        Bend::Reflect => bend_lanes(common, d, hits, |d, normal| {
            (refract::reflect(d, normal), true)
        }),
    }
}

/// [`leave_lanes`] for one bend: `bent(d, normal)` the leaving direction and whether there is
/// one.
#[inline(always)]
fn bend_lanes(
    common: &Common,
    d: &[Lanes<f64>; 3],
    hits: &LaneHits,
    bent: impl Fn(Vec3, Vec3) -> (Vec3, bool),
) -> (Lanes<u64>, [Lanes<f64>; 3]) {
    let mut codes = [CROSSED; NEWTON_LANES];
    let mut directions = [[0.0; NEWTON_LANES]; 3];
    let LaneHits {
        met,
        points,
        normals,
    } = hits;
    for l in 0..NEWTON_LANES {
        let point = [points[0][l], points[1][l], points[2][l]];
        let normal = [normals[0][l], normals[1][l], normals[2][l]];
        let hit = met[l] & point.iter().fold(true, |all, v| all & v.is_finite());
        let (direction, passes) = bent([d[0][l], d[1][l], d[2][l]], normal);
        [directions[0][l], directions[1][l], directions[2][l]] = direction;
        codes[l] = event_code(hit, common.inside(point), passes);
    }
    (codes, directions)
}

/// Reports the rays in `stopped`, which the last kernel stopped at surface `i` (0-based), with
/// the ray the one-ray path reports (the ray before the surface for a miss; the hit point and
/// arriving direction otherwise); a ray the surface could not bend as `not_bent`.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn report<const STRIDES: usize>(
    i: usize,
    not_bent: Event,
    arriving: [&[f64]; 6],
    next: &Columns<STRIDES>,
    events: &[u64],
    ids: &[u32],
    stopped: Slots,
    finish: &mut impl Finish,
) {
    for slot in stopped.iter() {
        let arrived = ray_at(arriving, slot);
        let (outcome, ray) = match events[slot] {
            MISSED => (Outcome::Missed { surface: i + 1 }, arrived),
            code => {
                let outcome = if code == VIGNETTED {
                    Outcome::Vignetted { surface: i + 1 }
                } else {
                    debug_assert_eq!(code, NOT_BENT);
                    not_bent.outcome(i + 1)
                };
                let ray = Ray::from_parts(next.position(slot), arrived.direction);
                (outcome, ray)
            }
        };
        finish.finish(ids[slot] as usize, Traced { outcome, ray });
    }
}

/// Moves the travelling rays in slots `count..` into the holes (slots of stopped rays) below
/// `count`, so that the `count` travelling rays occupy the first `count` slots (in no
/// particular order: each carries its number). Moves only as many rays as there are holes.
#[inline(always)]
fn pack<const STRIDES: usize>(
    columns: &mut Columns<STRIDES>,
    ids: &mut [u32],
    travelling: Slots,
    count: usize,
) {
    let below = Slots::first(count);
    let holes = below.without(travelling);
    let movers = travelling.without(below);
    debug_assert_eq!(holes.len(), movers.len());
    for (hole, source) in holes.iter().zip(movers.iter()) {
        columns.move_slot(source, hole);
        ids[hole] = ids[source];
    }
}

/// The ray in `slot` of six columns (x, y, z, dx, dy, dz).
#[inline(always)]
fn ray_at(columns: [&[f64]; 6], slot: usize) -> Ray {
    let [x, y, z, dx, dy, dz] = columns;
    Ray::from_parts([x[slot], y[slot], z[slot]], [dx[slot], dy[slot], dz[slot]])
}

/// What a surface does to a ray's direction, as the kernels' const parameter `BEND` (one of
/// [`REFRACT`], [`STRAIGHT`], [`REFLECT`]).
#[derive(Clone, Copy)]
enum Bend {
    Refract,
    /// Between equal media: the one-ray path leaves the direction as it is there.
    Straight,
    Reflect,
}

impl Bend {
    fn of(s: &FlatSurface) -> Bend {
        if s.reflects {
            Bend::Reflect
        } else if s.index_before != s.index_after {
            Bend::Refract
        } else {
            Bend::Straight
        }
    }
}

const REFRACT: u8 = Bend::Refract as u8;
const STRAIGHT: u8 = Bend::Straight as u8;
const REFLECT: u8 = Bend::Reflect as u8;

/// One surface's arithmetic for a block's lanes, written without branches on ray data so that
/// the loops over lanes become vector instructions.
trait Crossing {
    fn new(s: &FlatSurface, check_apertures: bool) -> Self;
    /// Crosses every lane of `lanes`.
    fn cross(&self, lanes: LaneColumns<'_>);
}

/// A kernel's columns, each cut to the lanes it crosses: the arriving positions `p` and
/// directions `d`, the leaving positions `q` and directions `e`, and the event codes. `q` and
/// `e` are the kernel's scratch space until its last loop writes them.
struct LaneColumns<'a> {
    p: [&'a [f64]; 3],
    d: [&'a [f64]; 3],
    q: [&'a mut [f64]; 3],
    e: [&'a mut [f64]; 3],
    codes: &'a mut [u64],
}

impl LaneColumns<'_> {
    fn strides(&self) -> usize {
        self.codes.len() / STRIDE
    }

    /// The stride that pipeline stage `stage` crosses at step `step` (stride `step - stage`),
    /// if there is one.
    #[inline(always)]
    fn stage_stride(&mut self, step: usize, stage: usize) -> Option<StrideColumns<'_>> {
        let k = step.checked_sub(stage).filter(|&k| k < self.strides())?;
        let [px, py, pz] = &self.p;
        let [dx, dy, dz] = &self.d;
        let [qx, qy, qz] = &mut self.q;
        let [ex, ey, ez] = &mut self.e;
        Some(StrideColumns {
            p: [px, py, pz].map(|column| &column.as_chunks().0[k]),
            d: [dx, dy, dz].map(|column| &column.as_chunks().0[k]),
            q: [qx, qy, qz].map(|column| &mut column.as_chunks_mut().0[k]),
            e: [ex, ey, ez].map(|column| &mut column.as_chunks_mut().0[k]),
            codes: &mut self.codes.as_chunks_mut().0[k],
        })
    }

    /// The [`clamped_sqrt`] of `e`'s last column (the discriminant or the radicand) over the
    /// stride of stage `stage` at step `step`; zeros where there is no such stride.
    #[inline(always)]
    fn stage_roots(&mut self, step: usize, stage: usize) -> [f64; STRIDE] {
        let mut roots = [0.0; STRIDE];
        if let Some(stride) = self.stage_stride(step, stage) {
            for (root, &value) in roots.iter_mut().zip(stride.e[2].iter()) {
                *root = clamped_sqrt(value);
            }
        }
        roots
    }
}

/// One stride of a kernel's [`LaneColumns`].
struct StrideColumns<'a> {
    p: [&'a [f64; STRIDE]; 3],
    d: [&'a [f64; STRIDE]; 3],
    q: [&'a mut [f64; STRIDE]; 3],
    e: [&'a mut [f64; STRIDE]; 3],
    codes: &'a mut [u64; STRIDE],
}

/// The numbers every kernel needs of a surface.
#[derive(Clone, Copy)]
struct Common {
    vertex_z: f64,
    semi_aperture_sq: f64,
    obscuration_sq: f64,
    check_apertures: bool,
    /// The sense along z (+1 or -1) the rays meet the surface in, the way they travel (behind a
    /// mirror a forward ray travels -z), and the Snell ratio that way.
    sense: f64,
    mu: f64,
}

impl Common {
    #[inline(always)]
    fn new<const FORWARD: bool>(s: &FlatSurface, check_apertures: bool) -> Common {
        Common {
            vertex_z: s.vertex_z,
            semi_aperture_sq: s.semi_aperture_sq,
            obscuration_sq: s.obscuration_sq,
            check_apertures,
            sense: s.sense::<FORWARD>(),
            mu: if FORWARD { s.mu_forward } else { s.mu_backward },
        }
    }

    #[inline(always)]
    fn inside(&self, q: Vec3) -> bool {
        let r_sq = radius_sq(q);
        !self.check_apertures | ((r_sq <= self.semi_aperture_sq) & (r_sq >= self.obscuration_sq))
    }

    /// Crosses every lane of `lanes` in one loop, for a surface met in closed form:
    /// `meet(arriving, d)` gives the point (vertex frame) and whether it is a crossing,
    /// `bend(point, d)` the leaving direction and whether the ray gets through (false on total
    /// internal reflection), used where `BENDS`.
    #[inline(always)]
    fn cross_in_one_loop<const BENDS: bool>(
        &self,
        lanes: LaneColumns<'_>,
        meet: impl Fn(Vec3, Vec3) -> (Vec3, bool),
        bend: impl Fn(Vec3, Vec3) -> (Vec3, bool),
    ) {
        let LaneColumns { p, d, q, e, codes } = lanes;
        let [px, py, pz] = p;
        let [dx, dy, dz] = d;
        let [qx, qy, qz] = q;
        let [ex, ey, ez] = e;
        for l in 0..codes.len() {
            let d = [dx[l], dy[l], dz[l]];
            let arriving = [px[l], py[l], pz[l] - self.vertex_z];
            let (point, crosses) = meet(arriving, d);
            let hit = crosses & point.iter().fold(true, |all, v| all & v.is_finite());
            let (direction, passes) = if BENDS { bend(point, d) } else { (d, true) };
            [qx[l], qy[l], qz[l]] = [point[0], point[1], point[2] + self.vertex_z];
            [ex[l], ey[l], ez[l]] = direction;
            codes[l] = event_code(hit, self.inside(point), passes);
        }
    }
}

/// [`intersect::sphere_candidate`], the aperture test and the bend `BEND`
/// ([`refract::refract_candidate`], none, or [`refract::reflect`]).
struct SphereCrossing<const FORWARD: bool, const BEND: u8> {
    common: Common,
    curvature: f64,
}

impl<const FORWARD: bool, const BEND: u8> Crossing for SphereCrossing<FORWARD, BEND> {
    #[inline(always)]
    fn new(s: &FlatSurface, check_apertures: bool) -> Self {
        let Profile::Sphere { curvature } = s.profile else {
            unreachable!("the sphere kernel runs on spheres only")
        };
        let common = Common::new::<FORWARD>(s, check_apertures);
        SphereCrossing { common, curvature }
    }

    /// A sphere's lane is a chain of a square root, a division and another square root, each
    /// behind a dozen multiply-adds. In one pass over the lanes the processor's window held too
    /// few lanes to keep the divider busy; in four passes, one per stage (multiply-adds, root
    /// and division, multiply-adds, root), the divider idled through the multiply-add passes
    /// and the multiply-add units through the others. So the stages run as a pipeline over
    /// strides: each step crosses one stride in every stage (stride `k` in the first, `k - 1` in
    /// the second, ...), independent work the processor overlaps. The stages' results wait in
    /// `q` and `e`, each lane's read before it is overwritten.
    ///
    /// Each step takes its two square roots first and uses them last: the divider works on
    /// them while the multiply-add stages run, instead of their dependents waiting in the
    /// scheduler ahead of that work (`bench trace` 1.4-1.8 % faster; the division moved up
    /// before the hit points was about 4 % slower than this).
    #[inline(always)]
    fn cross(&self, mut lanes: LaneColumns<'_>) {
        let refracts = BEND == REFRACT;
        let stages = if refracts { 4 } else { 3 };
        for step in 0..lanes.strides() + stages - 1 {
            let disc_roots = lanes.stage_roots(step, 1);
            let radicand_roots = if refracts {
                lanes.stage_roots(step, 3)
            } else {
                [0.0; STRIDE]
            };
            if let Some(stride) = lanes.stage_stride(step, 0) {
                self.quadratic(stride);
            }
            if let Some(stride) = lanes.stage_stride(step, 2) {
                self.meet(stride);
            }
            if let Some(stride) = lanes.stage_stride(step, 1) {
                self.distance(stride, &disc_roots);
            }
            if refracts && let Some(stride) = lanes.stage_stride(step, 3) {
                self.refraction(stride, &radicand_roots);
            }
        }
    }
}

impl<const FORWARD: bool, const BEND: u8> SphereCrossing<FORWARD, BEND> {
    /// The start points go to `q`; B, C and the discriminant to `e`.
    #[inline(always)]
    fn quadratic(&self, stride: StrideColumns<'_>) {
        let StrideColumns { p, d, q, e, .. } = stride;
        for l in 0..STRIDE {
            let arriving = [p[0][l], p[1][l], p[2][l] - self.common.vertex_z];
            let direction = [d[0][l], d[1][l], d[2][l]];
            let quadratic = intersect::SphereQuadratic::new(arriving, direction, self.curvature);
            [q[0][l], q[1][l], q[2][l]] = quadratic.start;
            [e[0][l], e[1][l], e[2][l]] = [quadratic.b, quadratic.c, quadratic.disc];
        }
    }

    /// The distance along the ray replaces B, from the discriminant's `roots`.
    #[inline(always)]
    fn distance(&self, stride: StrideColumns<'_>, roots: &[f64; STRIDE]) {
        let [b, c, _] = stride.e;
        for l in 0..STRIDE {
            b[l] = intersect::root_given(self.curvature, b[l], c[l], roots[l], self.common.sense);
        }
    }

    /// The hit points (relative to the vertex) to `q`, whether each ray hits to its code;
    /// refracting, the normal's z, the cosine and the radicand to `e`.
    #[inline(always)]
    fn meet(&self, stride: StrideColumns<'_>) {
        let (c, common) = (self.curvature, &self.common);
        let StrideColumns { d, q, e, codes, .. } = stride;
        for l in 0..STRIDE {
            let d = [d[0][l], d[1][l], d[2][l]];
            let start = [q[0][l], q[1][l], q[2][l]];
            let (point, nz, crosses) = intersect::sphere_meet(start, e[2][l], d, c, e[0][l]);
            let hit = crosses & point[0].is_finite() & point[1].is_finite() & point[2].is_finite();
            let normal = [c * point[0], c * point[1], nz];
            if BEND == REFRACT {
                [q[0][l], q[1][l], q[2][l]] = point;
                let (cos_signed, radicand) = refract::refraction_radicand(d, normal, common.mu);
                [e[0][l], e[1][l], e[2][l]] = [nz, cos_signed, radicand];
                codes[l] = u64::from(hit);
            } else {
                [q[0][l], q[1][l], q[2][l]] = [point[0], point[1], point[2] + common.vertex_z];
                [e[0][l], e[1][l], e[2][l]] = if BEND == REFLECT {
                    refract::reflect(d, normal)
                } else {
                    d
                };
                codes[l] = event_code(hit, common.inside(point), true);
            }
        }
    }

    /// The refracted directions (from the radicand's `roots`) to `e`, the leaving points to
    /// `q`, the codes.
    #[inline(always)]
    fn refraction(&self, stride: StrideColumns<'_>, roots: &[f64; STRIDE]) {
        let (c, common) = (self.curvature, &self.common);
        let StrideColumns { d, q, e, codes, .. } = stride;
        for l in 0..STRIDE {
            let point = [q[0][l], q[1][l], q[2][l]];
            let normal = [c * point[0], c * point[1], e[0][l]];
            let radicand = e[2][l];
            let d = [d[0][l], d[1][l], d[2][l]];
            [e[0][l], e[1][l], e[2][l]] =
                refract::refracted_given(d, normal, common.mu, e[1][l], roots[l]);
            q[2][l] = point[2] + common.vertex_z;
            codes[l] = event_code(codes[l] == 1, common.inside(point), radicand >= 0.0);
        }
    }
}

/// [`intersect::plane_candidate`], the aperture test and the bend `BEND`
/// ([`refract::refract_plane_candidate`], none, or [`refract::reflect`]).
struct PlaneCrossing<const FORWARD: bool, const BEND: u8> {
    common: Common,
}

impl<const FORWARD: bool, const BEND: u8> Crossing for PlaneCrossing<FORWARD, BEND> {
    #[inline(always)]
    fn new(s: &FlatSurface, check_apertures: bool) -> Self {
        let common = Common::new::<FORWARD>(s, check_apertures);
        PlaneCrossing { common }
    }

    /// A plane's lane has one division and one square root: one loop.
    #[inline(always)]
    fn cross(&self, lanes: LaneColumns<'_>) {
        let (sense, mu) = (self.common.sense, self.common.mu);
        let meet = |arriving, d| intersect::plane_candidate(arriving, d, sense);
        let common = &self.common;
        match BEND {
            REFRACT => common.cross_in_one_loop::<true>(lanes, meet, |_, d| {
                let (direction, radicand) = refract::refract_plane_candidate(d, mu);
                (direction, radicand >= 0.0)
            }),
            REFLECT => common.cross_in_one_loop::<true>(lanes, meet, |_, d| {
                (refract::reflect(d, refract::PLANE_NORMAL), true)
            }),
            _ => common.cross_in_one_loop::<false>(lanes, meet, |_, d| (d, true)),
        }
    }
}

/// [`intersect::plane_candidate`], the aperture test and [`refract::ideal_lens_candidate`] (an
/// ideal lens lies in air and never reflects: the prescription's checks refuse one that would).
struct IdealLensCrossing<const FORWARD: bool> {
    common: Common,
    power: f64,
}

impl<const FORWARD: bool> Crossing for IdealLensCrossing<FORWARD> {
    #[inline(always)]
    fn new(s: &FlatSurface, check_apertures: bool) -> Self {
        let Some(power) = s.profile.ideal_power() else {
            unreachable!("the ideal lens kernel runs on ideal lenses only")
        };
        debug_assert!(!s.reflects);
        let common = Common::new::<FORWARD>(s, check_apertures);
        IdealLensCrossing { common, power }
    }

    /// One division and one square root, as a refracting plane: one loop.
    #[inline(always)]
    fn cross(&self, lanes: LaneColumns<'_>) {
        let (sense, power) = (self.common.sense, self.power);
        self.common.cross_in_one_loop::<true>(
            lanes,
            |arriving, d| intersect::plane_candidate(arriving, d, sense),
            |point, d| refract::ideal_lens_candidate(d, [point[0], point[1]], power),
        );
    }
}

/// [`intersect::conic_candidate`] and its normal, the aperture test and the bend `BEND`
/// ([`refract::refract_candidate`], none, or [`refract::reflect`]).
struct ConicCrossing<const FORWARD: bool, const BEND: u8> {
    common: Common,
    curvature: f64,
    conic_factor: f64,
}

impl<const FORWARD: bool, const BEND: u8> Crossing for ConicCrossing<FORWARD, BEND> {
    #[inline(always)]
    fn new(s: &FlatSurface, check_apertures: bool) -> Self {
        let Profile::Conic {
            curvature,
            conic_factor,
        } = s.profile
        else {
            unreachable!("the conic kernel runs on conics only")
        };
        let common = Common::new::<FORWARD>(s, check_apertures);
        ConicCrossing {
            common,
            curvature,
            conic_factor,
        }
    }

    /// A conic's lane is a square root and a division, then the normal's square root and
    /// division, then the refraction's square root: one loop, as for a plane.
    #[inline(always)]
    fn cross(&self, lanes: LaneColumns<'_>) {
        let (c, e) = (self.curvature, self.conic_factor);
        let (sense, mu) = (self.common.sense, self.common.mu);
        let meet = |arriving, d| intersect::conic_candidate(arriving, d, c, e, sense);
        let common = &self.common;
        match BEND {
            REFRACT => common.cross_in_one_loop::<true>(lanes, meet, |point, d| {
                let normal = intersect::conic_normal(point, c, e);
                let (direction, radicand) = refract::refract_candidate(d, normal, mu);
                (direction, radicand >= 0.0)
            }),
            REFLECT => common.cross_in_one_loop::<true>(lanes, meet, |point, d| {
                (
                    refract::reflect(d, intersect::conic_normal(point, c, e)),
                    true,
                )
            }),
            _ => common.cross_in_one_loop::<false>(lanes, meet, |_, d| (d, true)),
        }
    }
}

/// One compiled copy of the block trace and its kernels per instruction set. Each kernel is a
/// function of its own (never inlined into the block loop, whose two column sets swap places
/// every surface): there its arguments are known not to overlap, which the compiler needs to
/// vectorise it.
trait Machine {
    /// [`Tracer::trace_block`] compiled for this machine.
    ///
    /// # Safety
    /// The processor runs this machine's instructions.
    unsafe fn trace<const FORWARD: bool, const STRIDES: usize>(
        tracer: &Tracer,
        block: &mut Block<STRIDES>,
        start: Start<'_>,
        check_apertures: bool,
        visit: &mut impl LaneVisitor,
        finish: &mut impl Finish,
    ) -> u64;

    /// The slots of the first `strides` strides whose code is not [`CROSSED`].
    ///
    /// # Safety
    /// The processor runs this machine's instructions.
    #[inline(always)]
    unsafe fn stopped_slots<const STRIDES: usize>(
        events: &[[u64; STRIDE]; STRIDES],
        strides: usize,
    ) -> Slots {
        stopped_slots(events, strides)
    }

    /// [`kernel`] compiled for this machine.
    ///
    /// # Safety
    /// The processor runs this machine's instructions.
    #[allow(clippy::too_many_arguments)]
    unsafe fn kernel<K: Crossing, const STRIDES: usize>(
        s: &FlatSurface,
        px: &[f64],
        py: &[f64],
        pz: &[f64],
        dx: &[f64],
        dy: &[f64],
        dz: &[f64],
        next: &mut Columns<STRIDES>,
        events: &mut [[u64; STRIDE]; STRIDES],
        strides: usize,
        apertures: KernelApertures<'_>,
    );
}

/// The build's own instruction set (SSE2 on x86-64).
struct Portable;

impl Machine for Portable {
    unsafe fn trace<const FORWARD: bool, const STRIDES: usize>(
        tracer: &Tracer,
        block: &mut Block<STRIDES>,
        start: Start<'_>,
        check_apertures: bool,
        visit: &mut impl LaneVisitor,
        finish: &mut impl Finish,
    ) -> u64 {
        tracer.block_body::<FORWARD, STRIDES, Portable>(
            block,
            start,
            check_apertures,
            visit,
            finish,
        )
    }

    #[inline(never)]
    #[allow(clippy::too_many_arguments)]
    unsafe fn kernel<K: Crossing, const STRIDES: usize>(
        s: &FlatSurface,
        px: &[f64],
        py: &[f64],
        pz: &[f64],
        dx: &[f64],
        dy: &[f64],
        dz: &[f64],
        next: &mut Columns<STRIDES>,
        events: &mut [[u64; STRIDE]; STRIDES],
        strides: usize,
        apertures: KernelApertures<'_>,
    ) {
        kernel::<K, STRIDES>(s, px, py, pz, dx, dy, dz, next, events, strides, apertures)
    }
}

/// An x86-64 machine whose block trace and kernels are compiled with `$features` (everything
/// they call is `inline(always)`, so it is compiled with the features too).
macro_rules! x86_machine {
    ($(#[$doc:meta])* $machine:ident, $features:tt) => {
        $(#[$doc])*
        #[cfg(target_arch = "x86_64")]
        struct $machine;

        #[cfg(target_arch = "x86_64")]
        impl $machine {
            #[target_feature(enable = $features)]
            #[inline(never)]
            fn trace_compiled<const FORWARD: bool, const STRIDES: usize>(
                tracer: &Tracer,
                block: &mut Block<STRIDES>,
                start: Start<'_>,
                check_apertures: bool,
                visit: &mut impl LaneVisitor,
                finish: &mut impl Finish,
            ) -> u64 {
                tracer.block_body::<FORWARD, STRIDES, $machine>(block, start, check_apertures, visit, finish)
            }

            #[target_feature(enable = $features)]
            #[inline(never)]
            #[allow(clippy::too_many_arguments)]
            fn kernel_compiled<K: Crossing, const STRIDES: usize>(
                s: &FlatSurface,
                px: &[f64],
                py: &[f64],
                pz: &[f64],
                dx: &[f64],
                dy: &[f64],
                dz: &[f64],
                next: &mut Columns<STRIDES>,
                events: &mut [[u64; STRIDE]; STRIDES],
                strides: usize,
                apertures: KernelApertures<'_>,
            ) {
                kernel::<K, STRIDES>(s, px, py, pz, dx, dy, dz, next, events, strides, apertures)
            }
        }

        #[cfg(target_arch = "x86_64")]
        impl Machine for $machine {
            #[inline(always)]
            unsafe fn trace<const FORWARD: bool, const STRIDES: usize>(
                tracer: &Tracer,
                block: &mut Block<STRIDES>,
                start: Start<'_>,
                check_apertures: bool,
                visit: &mut impl LaneVisitor,
                finish: &mut impl Finish,
            ) -> u64 {
                // SAFETY: passed on from the caller.
                unsafe {
                    Self::trace_compiled::<FORWARD, STRIDES>(tracer, block, start, check_apertures, visit, finish)
                }
            }

            /// Four codes at a time, a vector compare and its sign mask (the portable loop
            /// compiled to shuffles and 128-bit shifts, about 5 % of the trace).
            #[inline(always)]
            unsafe fn stopped_slots<const STRIDES: usize>(
                events: &[[u64; STRIDE]; STRIDES],
                strides: usize,
            ) -> Slots {
                // SAFETY: every x86-64 machine's set includes AVX2.
                unsafe { stopped_slots_avx2(events, strides) }
            }

            #[inline(always)]
            #[allow(clippy::too_many_arguments)]
            unsafe fn kernel<K: Crossing, const STRIDES: usize>(
                s: &FlatSurface,
                px: &[f64],
                py: &[f64],
                pz: &[f64],
                dx: &[f64],
                dy: &[f64],
                dz: &[f64],
                next: &mut Columns<STRIDES>,
                events: &mut [[u64; STRIDE]; STRIDES],
                strides: usize,
                apertures: KernelApertures<'_>,
            ) {
                // SAFETY: passed on from the caller.
                unsafe {
                    Self::kernel_compiled::<K, STRIDES>(s, px, py, pz, dx, dy, dz, next, events, strides, apertures)
                }
            }
        }
    };
}

x86_machine!(
    /// AVX2 with fused multiply-adds: a stride is two vector registers.
    Avx2Fma,
    "avx2,fma,popcnt,bmi1,bmi2"
);
x86_machine!(
    /// AVX-512 (foundation, doubleword/quadword and vector-length extensions): a stride is one
    /// vector register.
    Avx512,
    "avx512f,avx512dq,avx512vl,avx2,fma,popcnt,bmi1,bmi2"
);

/// Crosses surface `s` with the first `strides` strides of the arriving columns, writing `next`
/// and the event codes.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn kernel<K: Crossing, const STRIDES: usize>(
    s: &FlatSurface,
    px: &[f64],
    py: &[f64],
    pz: &[f64],
    dx: &[f64],
    dy: &[f64],
    dz: &[f64],
    next: &mut Columns<STRIDES>,
    events: &mut [[u64; STRIDE]; STRIDES],
    strides: usize,
    apertures: KernelApertures<'_>,
) {
    // Every slice is cut to `n` here, in straight code: sliced inside an array `map` (a call
    // the compiler kept), their lengths were unknown in the kernels' loops, whose last stride
    // then ran as scalar code behind the bounds checks (a third of the sphere kernel's time).
    let n = strides * STRIDE;
    let [qx, qy, qz, ex, ey, ez] = &mut next.values;
    K::new(s, apertures.check).cross(LaneColumns {
        p: [&px[..n], &py[..n], &pz[..n]],
        d: [&dx[..n], &dy[..n], &dz[..n]],
        q: [
            &mut qx.as_flattened_mut()[..n],
            &mut qy.as_flattened_mut()[..n],
            &mut qz.as_flattened_mut()[..n],
        ],
        e: [
            &mut ex.as_flattened_mut()[..n],
            &mut ey.as_flattened_mut()[..n],
            &mut ez.as_flattened_mut()[..n],
        ],
        codes: &mut events.as_flattened_mut()[..n],
    });
    if let Some(blades) = apertures.blades {
        vignette_outside_blades(blades, next, events, strides);
    }
}

/// What a kernel tests a ray's hit point against: with `check`, the clear aperture and the
/// central obscuration; `blades`, the stop's, where the surface is a bladed stop and apertures
/// are checked. The blades
/// are tested in the kernel's call, not the block loop: a call in the loop made the compiler
/// keep less of the loop's state in registers, and the batch trace of an unbladed lens ran
/// about a fifth slower.
#[derive(Clone, Copy)]
struct KernelApertures<'a> {
    check: bool,
    blades: Option<&'a Diaphragm>,
}

/// The first failing test in the one-ray path's order: intersection, aperture, refraction.
#[inline(always)]
fn event_code(hit: bool, inside: bool, passes: bool) -> u64 {
    if !hit {
        MISSED
    } else if !inside {
        VIGNETTED
    } else if !passes {
        NOT_BENT
    } else {
        CROSSED
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::prescription::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
    use crate::system::LensSystem;
    use crate::trace::{Apertures, GROUP_RAYS, GroupBlock, RayBatch};

    /// Every instruction set this processor runs, the portable one included.
    fn runnable() -> Vec<Isa> {
        let mut isas = vec![Isa::Portable];
        #[cfg(target_arch = "x86_64")]
        match Isa::widest() {
            Isa::Avx512 => isas.extend([Isa::Avx2Fma, Isa::Avx512]),
            Isa::Avx2Fma => isas.push(Isa::Avx2Fma),
            Isa::Portable => {}
        }
        isas
    }

    /// Spheres and planes (kernels; one of each between equal indices, which does not refract)
    /// around an ideal lens and a conic (kernels too) and an even and an odd asphere (met in
    /// lanes), with apertures small enough that rays stop at several surfaces, so blocks are
    /// compacted.
    fn tracer() -> Tracer {
        let surface = |shape, thickness, n: f64, stop| Surface {
            stop,
            ..Surface::open(shape, thickness, Medium::Index(n), 9.0)
        };
        let conic = Shape::Conic {
            curvature: -0.02,
            conic: -0.6,
        };
        // Strong enough terms that the searches take different numbers of steps (1 to 7
        // evaluations over this test's rays, counted once).
        let even_asphere = Shape::EvenAsphere {
            curvature: 0.03,
            conic: -0.5,
            coefficients: vec![0.0, -4e-4, 2e-6, -1e-8],
        };
        let odd_asphere = Shape::OddAsphere {
            curvature: -0.02,
            conic: 0.0,
            coefficients: vec![1e-3, 2e-3, -3e-4, 1e-5],
        };
        let prescription = Prescription {
            provenance: Provenance::default(),
            object_medium: Medium::Air,
            surfaces: vec![
                surface(Shape::Sphere { curvature: 0.04 }, 4.0, 1.7, None),
                surface(Shape::Sphere { curvature: -0.03 }, 1.0, 1.7, None),
                surface(Shape::Plane, 3.0, 1.0, Some(StopShape::Circle)),
                surface(Shape::IdealLens { focal_length: 25.0 }, 1.0, 1.0, None),
                surface(Shape::Plane, 2.0, 1.0, None),
                surface(Shape::Plane, 3.0, 1.5, None),
                surface(conic, 2.0, 1.5, None),
                surface(even_asphere, 2.0, 1.6, None),
                surface(odd_asphere, 3.0, 1.6, None),
                surface(Shape::Sphere { curvature: -0.05 }, 30.0, 1.0, None),
            ],
        };
        let system = LensSystem::from_prescription(prescription).unwrap();
        Tracer::new(&system.at(550.0))
    }

    fn rays(n: usize) -> Vec<Ray> {
        (0..n)
            .map(|i| {
                let a = i as f64 * 0.37;
                let d = [
                    0.3 * a.sin(),
                    0.3 * (1.3 * a).cos(),
                    1.0 - 0.2 * (0.7 * a).sin(),
                ];
                Ray::new([8.0 * a.cos(), 8.0 * (0.5 * a).sin(), -5.0], d).unwrap()
            })
            .collect()
    }

    /// A folded lens: a sphere with a central obscuration, a bladed stop, a plane mirror, elements crossed
    /// travelling -z, a conic mirror (a paraboloid), elements crossed travelling +z again, a
    /// spherical mirror and a plane crossed travelling -z. `aspheric`: the obscured surface, the
    /// stop and the last mirror even aspheres instead of spheres.
    fn folded_tracer(aspheric: bool) -> Tracer {
        let surface = Surface::open;
        let sphere = |curvature| Shape::Sphere { curvature };
        let curved = |curvature| match aspheric {
            true => Shape::EvenAsphere {
                curvature,
                conic: -0.3,
                coefficients: vec![0.0, 2e-5, -3e-8],
            },
            false => sphere(curvature),
        };
        let paraboloid = Shape::Conic {
            curvature: -0.01,
            conic: -1.0,
        };
        let prescription = Prescription {
            provenance: Provenance::default(),
            object_medium: Medium::Air,
            surfaces: vec![
                Surface {
                    obscuration: Some(4.0),
                    ..surface(curved(0.02), 4.0, Medium::Index(1.6), 10.0)
                },
                Surface {
                    stop: Some(StopShape::Blades {
                        count: 5,
                        rotation_deg: 12.0,
                        blade_curvature: 0.4,
                    }),
                    ..surface(curved(-0.01), 30.0, Medium::Air, 10.0)
                },
                surface(Shape::Plane, -20.0, Medium::Mirror, 12.0),
                surface(sphere(0.01), -4.0, Medium::Index(1.5), 10.0),
                surface(sphere(-0.02), -5.0, Medium::Air, 10.0),
                surface(paraboloid, 12.0, Medium::Mirror, 12.0),
                surface(sphere(-0.02), 3.0, Medium::Index(1.5), 10.0),
                surface(Shape::Plane, 10.0, Medium::Air, 10.0),
                surface(curved(0.005), -6.0, Medium::Mirror, 14.0),
                surface(Shape::Plane, -10.0, Medium::Air, 12.0),
            ],
        };
        let system = LensSystem::from_prescription(prescription).unwrap();
        Tracer::new(&system.at(550.0))
    }

    /// [`rays`] mirrored to start behind the lens and travel back through it.
    fn backward_rays(n: usize) -> Vec<Ray> {
        rays(n)
            .into_iter()
            .map(|ray| {
                let ([x, y, _], [dx, dy, dz]) = (ray.position, ray.direction);
                Ray::new([x, y, 60.0], [dx, dy, -dz]).unwrap()
            })
            .collect()
    }

    /// Slot sets across their words' borders: the first `n` slots, and the ones a pattern of
    /// words holds, in order.
    #[test]
    fn slot_sets_count_and_list_every_word() {
        for n in 0..=Slots::CAPACITY {
            let first = Slots::first(n);
            assert_eq!(first.len(), n);
            assert_eq!(first.is_empty(), n == 0);
            assert!(first.iter().eq(0..n), "first {n}");
            assert!((0..Slots::CAPACITY).all(|slot| first.contains(slot) == (slot < n)));
        }
        let words = [1 << 63 | 1, 0, u64::MAX, 1 << 5];
        let set = Slots::from_words(words.into_iter());
        let listed: Vec<usize> = set.iter().collect();
        let expected: Vec<usize> = [0, 63].into_iter().chain(128..192).chain([197]).collect();
        assert_eq!(listed, expected);
        let upper = set.without(Slots::first(128));
        assert!(upper.iter().eq((128..192).chain([197])));
        assert_eq!(set.and(Slots::first(64)).len(), 2);
        assert_eq!(Slots::from_words([7].into_iter()), Slots::first(3));
    }

    /// Every stride of a block's columns and codes starts a cache line, wherever the block is,
    /// so that no kernel's 64-byte access is split across two lines.
    #[test]
    fn block_strides_start_cache_lines() {
        fn check<const STRIDES: usize>() {
            let blocks = vec![Block::<STRIDES>::new(), Block::<STRIDES>::new()];
            for block in &blocks {
                let columns = block
                    .columns
                    .iter()
                    .flat_map(|set| set.values.iter().flatten());
                let codes = block.events.iter().map(|codes| codes.as_ptr() as usize);
                for address in columns.map(|stride| stride.as_ptr() as usize).chain(codes) {
                    assert_eq!(address % 64, 0, "a block of {STRIDES} strides");
                }
            }
        }
        check::<1>();
        check::<16>();
        check::<{ GROUP_RAYS / STRIDE }>();
    }

    /// The block trace compiled for each instruction set (the portable code is what processors
    /// without AVX2 and FMA run) against the one-ray path compiled for each, bit for bit, in
    /// both directions.
    #[test]
    fn every_instruction_set_traces_blocks_bit_for_bit_as_one_ray() {
        let tracer = tracer();
        for (travel, rays) in [
            (Travel::Forward, rays(3 * GROUP_RAYS + 5)),
            (Travel::Backward, backward_rays(3 * GROUP_RAYS + 5)),
        ] {
            blocks_trace_as_one_ray(&tracer, travel, &rays);
        }
    }

    /// Mirrors (plane, sphere and conic), an obscured surface and a bladed stop in the kernels,
    /// and an aspheric mirror, obscured surface and bladed stop met in lanes, bit for bit as one
    /// ray at a time, both ways; enough rays get past every mirror, and stop at the obscuration
    /// and the blades, for a wrong reflection or aperture to show.
    #[test]
    fn every_instruction_set_traces_mirrors_obscurations_and_blades_bit_for_bit_as_one_ray() {
        for aspheric in [false, true] {
            folded_lens_traces_blocks_as_one_ray(&folded_tracer(aspheric));
        }
    }

    fn folded_lens_traces_blocks_as_one_ray(tracer: &Tracer) {
        // Over the first (forward) or last (backward) surface's clear aperture, most tilted a
        // little, every fifth steeply (these miss a surface or are reflected totally inside an
        // element).
        let rays = |z: f64, sense: f64| -> Vec<Ray> {
            (0..3 * GROUP_RAYS + 5)
                .map(|i| {
                    let (a, r) = (i as f64 * 0.37, 9.5 * ((i % 97) as f64 / 97.0).sqrt());
                    let tilt = if i % 5 == 0 { 1.5 } else { 0.02 };
                    let d = [tilt * a.sin(), tilt * (1.3 * a).cos(), sense];
                    Ray::new([r * a.cos(), r * a.sin(), z], d).unwrap()
                })
                .collect()
        };
        for (travel, rays, got_past) in [
            (
                Travel::Forward,
                rays(-5.0, 1.0),
                (|s| s > 9) as fn(usize) -> bool,
            ),
            (Travel::Backward, rays(0.0, 1.0), |s| s < 3),
        ] {
            let traced: Vec<_> = rays.iter().map(|&ray| tracer.trace(ray, travel)).collect();
            let past_mirrors = traced
                .iter()
                .filter(|t| t.outcome.surface().is_none_or(got_past))
                .count();
            assert!(
                past_mirrors > 30,
                "{travel:?}: {past_mirrors} past every mirror"
            );
            let obscured = traced
                .iter()
                .filter(|t| t.outcome == Outcome::Vignetted { surface: 1 })
                .count();
            assert!(obscured > 0, "{travel:?}: none obscured");
            let bladed = traced
                .iter()
                .filter(|t| t.outcome == Outcome::Vignetted { surface: 2 })
                .count();
            assert!(bladed > 0, "{travel:?}: none stopped by the blades");
            blocks_trace_as_one_ray(tracer, travel, &rays);
        }
    }

    /// An asphere from glass into air, met steeply enough that rays are reflected totally
    /// inside: the lanes report TIR there, as the one-ray path does.
    #[test]
    fn an_asphere_reflects_totally_as_one_ray() {
        let asphere = Shape::EvenAsphere {
            curvature: -0.06,
            conic: -0.5,
            coefficients: vec![0.0, -1e-4, 2e-7],
        };
        let prescription = Prescription {
            provenance: Provenance::default(),
            object_medium: Medium::Air,
            surfaces: vec![
                Surface {
                    stop: Some(StopShape::Circle),
                    ..Surface::open(Shape::Plane, 4.0, Medium::Index(1.8), 9.0)
                },
                Surface::open(asphere, 10.0, Medium::Air, 9.0),
            ],
        };
        let system = LensSystem::from_prescription(prescription).unwrap();
        let tracer = Tracer::new(&system.at(550.0));
        let rays: Vec<Ray> = (0..3 * GROUP_RAYS + 5)
            .map(|i| {
                let (a, r) = (i as f64 * 0.37, 8.5 * ((i % 97) as f64 / 97.0).sqrt());
                let tilt = 1.2 * ((i % 7) as f64 / 6.0);
                let d = [tilt * a.sin(), tilt * (1.3 * a).cos(), 1.0];
                Ray::new([r * a.cos(), r * a.sin(), -1.0], d).unwrap()
            })
            .collect();
        let reflected = rays
            .iter()
            .filter(|&&ray| {
                tracer.trace(ray, Travel::Forward).outcome == Outcome::Tir { surface: 2 }
            })
            .count();
        assert!(
            reflected > 10,
            "{reflected} reflected totally at the asphere"
        );
        blocks_trace_as_one_ray(&tracer, Travel::Forward, &rays);
    }

    /// An ideal lens met by a ray so nearly parallel to it that the deflected tangents
    /// overflow: the lanes report the miss at the hit point, as the one-ray path does, beside
    /// rays it deflects, vignettes, or that miss the surface after it.
    #[test]
    fn an_ideal_lens_misses_the_rays_it_cannot_bend_as_one_ray() {
        let prescription = Prescription {
            provenance: Provenance::default(),
            object_medium: Medium::Air,
            surfaces: vec![
                Surface::open(
                    Shape::IdealLens { focal_length: 20.0 },
                    5.0,
                    Medium::Air,
                    9.0,
                ),
                Surface {
                    stop: Some(StopShape::Circle),
                    ..Surface::open(Shape::Sphere { curvature: 0.1 }, 5.0, Medium::Air, 9.0)
                },
            ],
        };
        let system = LensSystem::from_prescription(prescription).unwrap();
        let tracer = Tracer::new(&system.at(550.0));
        let grazing = Ray::new([1.0, 2.0, 0.0], [1.0, 0.0, 1e-300]).unwrap();
        let rays: Vec<Ray> = std::iter::repeat_n(grazing, 3)
            .chain(rays(3 * GROUP_RAYS + 2).into_iter().map(|ray| {
                let [x, y, _] = ray.position;
                Ray::new([x, y, -1.0], ray.direction).unwrap()
            }))
            .collect();
        let one = tracer.trace_with(grazing, Travel::Forward, Apertures::Checked);
        assert_eq!(one.outcome, Outcome::Missed { surface: 1 });
        assert_eq!(one.ray.position, grazing.position);
        blocks_trace_as_one_ray(&tracer, Travel::Forward, &rays);
    }

    /// The blade test after a kernel: a lane the kernel let through the circle (crossed, or
    /// totally reflected, which the one-ray path tests after the aperture) is vignetted outside
    /// the blades and kept inside; a miss or a lane already vignetted stays as it was.
    #[test]
    fn blades_vignette_lanes_through_the_circle_outside_them() {
        let shape = StopShape::Blades {
            count: 6,
            rotation_deg: 0.0,
            blade_curvature: 0.0,
        };
        let blades = Diaphragm::new(&shape, 10.0).unwrap();
        // Corners at 0, 60, ... degrees, 10 mm out; edge middles 8.66 mm out.
        let (inside, outside) = ([0.0, 8.5], [0.0, 9.5]);
        assert!(blades.contains(inside[0], inside[1]) && !blades.contains(outside[0], outside[1]));
        let mut next = Columns::<1>::ZERO;
        let points = [
            inside, outside, inside, outside, inside, outside, outside, inside,
        ];
        let codes = [
            CROSSED, CROSSED, NOT_BENT, NOT_BENT, MISSED, MISSED, VIGNETTED, VIGNETTED,
        ];
        for (slot, [x, y]) in points.into_iter().enumerate() {
            next.values[0][0][slot] = x;
            next.values[1][0][slot] = y;
        }
        let mut events = [codes];
        vignette_outside_blades(&blades, &next, &mut events, 1);
        let expected = [
            CROSSED, VIGNETTED, NOT_BENT, VIGNETTED, MISSED, MISSED, VIGNETTED, VIGNETTED,
        ];
        assert_eq!(events, [expected]);
    }

    fn blocks_trace_as_one_ray(tracer: &Tracer, travel: Travel, rays: &[Ray]) {
        let n = tracer.surfaces.len();
        let mut outcomes = std::collections::HashSet::new();
        for check in [true, false] {
            let apertures = if check {
                Apertures::Checked
            } else {
                Apertures::Ignored
            };
            let single: Vec<_> = rays
                .iter()
                .map(|&ray| tracer.trace_with(ray, travel, apertures))
                .collect();
            for isa in runnable() {
                for (k, &ray) in rays.iter().enumerate() {
                    let (one, _) = tracer.run_on(isa, ray, travel, 0..n, apertures, &mut |_, _| {});
                    assert_eq!(one, single[k], "{travel:?}, {isa:?}, one ray {k}");
                }
                // Loaded into the block, and read in place from columns (the last chunk, 5
                // rays, is not whole strides and is copied in).
                for ((b, chunk), from_columns) in rays
                    .chunks(GROUP_RAYS)
                    .enumerate()
                    .flat_map(|chunk| [(chunk, false), (chunk, true)])
                {
                    let mut block = GroupBlock::new();
                    let mut seen = vec![false; chunk.len()];
                    let mut finish = |id: usize, traced: Traced| {
                        assert!(!seen[id], "ray {id} reported twice");
                        seen[id] = true;
                        assert_eq!(
                            traced,
                            single[GROUP_RAYS * b + id],
                            "{travel:?}, {isa:?}, ray {id}, from columns: {from_columns}"
                        );
                        outcomes.insert(traced.outcome.status());
                    };
                    let count = if from_columns {
                        let batch: RayBatch = chunk.iter().copied().collect();
                        let columns = batch.columns();
                        tracer.trace_columns_on(
                            isa,
                            &mut block,
                            columns,
                            travel,
                            check,
                            &mut finish,
                        )
                    } else {
                        block.load(chunk);
                        tracer.trace_block_on(
                            isa,
                            &mut block,
                            travel,
                            check,
                            &mut NoVisit,
                            &mut finish,
                        )
                    };
                    assert!(seen.iter().all(|&s| s));
                    // A ray stopped at surface s (1-based) crossed s surfaces forward, n + 1 - s
                    // backward.
                    let expected: usize = single[GROUP_RAYS * b..GROUP_RAYS * b + chunk.len()]
                        .iter()
                        .map(|t| match (t.outcome.surface(), travel) {
                            (None, _) => n,
                            (Some(s), Travel::Forward) => s,
                            (Some(s), Travel::Backward) => n + 1 - s,
                        })
                        .sum();
                    assert_eq!(count, expected as u64);
                }
            }
        }
        assert!(
            outcomes.len() >= 3,
            "{travel:?}: a mix of outcomes: {outcomes:?}"
        );
    }

    /// A group traced from its columns reports exactly the chosen lanes, each by its lane and
    /// with what the one-ray trace gives, in a fresh block and in one a group with other rays
    /// and other lanes went through before.
    #[test]
    fn a_group_from_columns_traces_the_chosen_lanes_as_one_ray() {
        let tracer = tracer();
        let rays = rays(2 * GROUP_RAYS);
        let mut block = GroupBlock::new();
        // Every third lane left out, then every fifth, and the lanes past `count` not offered.
        for (group, skipped, count) in [(1, 3, GROUP_RAYS - 5), (0, 5, GROUP_RAYS - 9)] {
            let rays = &rays[group * GROUP_RAYS..][..GROUP_RAYS];
            let mut columns = [[0.0; GROUP_RAYS]; 6];
            for (lane, ray) in rays.iter().enumerate() {
                for (axis, value) in ray.position.into_iter().chain(ray.direction).enumerate() {
                    columns[axis][lane] = value;
                }
            }
            let chosen: Vec<bool> = (0..count).map(|lane| lane % skipped != 1).collect();
            let mut seen = [false; GROUP_RAYS];
            tracer.trace_group(
                &mut block,
                &columns,
                &chosen,
                Travel::Forward,
                |lane, traced| {
                    assert!(chosen[lane] && !seen[lane], "lane {lane}");
                    seen[lane] = true;
                    let one = tracer.trace_with(rays[lane], Travel::Forward, Apertures::Checked);
                    assert_eq!(traced, one, "group {group}, lane {lane}");
                },
            );
            assert_eq!(seen[..count], chosen[..]);
            assert!(seen[count..].iter().all(|&s| !s));
        }
    }

    /// The visitor sees each travelling ray's hit point on every surface, as the one-ray path
    /// records it, and no ray after it stopped.
    #[test]
    fn visitor_sees_the_survivors_hit_points() {
        struct Record(Vec<(usize, u32, f64, f64)>);
        impl LaneVisitor for Record {
            fn crossed(
                &mut self,
                surface: usize,
                ids: &[u32],
                travelling: Slots,
                x: &[f64],
                y: &[f64],
            ) {
                for k in (0..ids.len()).filter(|&k| travelling.contains(k)) {
                    self.0.push((surface, ids[k], x[k], y[k]));
                }
            }
        }
        let tracer = tracer();
        let rays = rays(LANES);
        let mut record = Record(Vec::new());
        tracer.trace_group_visiting(&rays, Travel::Forward, true, &mut record, &mut |_, _| {});
        let mut expected = Vec::new();
        for (id, &ray) in rays.iter().enumerate() {
            for crossing in tracer
                .trace_path(ray, Travel::Forward, Apertures::Checked)
                .crossings
            {
                let [x, y, _] = crossing.point;
                expected.push((crossing.surface - 1, id as u32, x, y));
            }
        }
        record.0.sort_by_key(|a| (a.0, a.1));
        expected.sort_by_key(|a| (a.0, a.1));
        assert_eq!(record.0, expected);
        // Rays cross several surfaces, the aspheres (surfaces 7 and 8) among them, and some stop.
        let surfaces = tracer.surfaces.len();
        assert!(expected.len() > 2 * LANES && expected.len() < surfaces * LANES);
        assert!(expected.iter().any(|&(surface, ..)| surface == 7));
    }
}
