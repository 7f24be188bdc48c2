//! A table's entries in memory, laid out for the sampler rather than for the file.
//!
//! The file (and the GPU texture) holds each channel as a row-major image of the 3D grid. The CPU
//! sampler reads the eight corners of one cell per lookup, all channels of each, and the renderer
//! scatters the lookups of one pixel over the whole pupil plane of its film radius. Row-major,
//! the corners of one cell lie n0 and n0 n1 nodes apart (at 128^3 f32: 4 KiB and 512 KiB), so
//! nearly every lookup touched four pages and missed the TLB as well as the cache. Here the grid
//! is cut into bricks of [`BRICK`]^3 nodes stored one after the other, a node's channels
//! together and aligned to their size (no node straddles a cache line): most cells lie inside
//! one brick (1 to 2 KiB). An f16 table stays f16 (half the bytes per node); its values are
//! widened to f32 on reading, which is what the f32 copy of it held before, bit for bit. A u16
//! table holds each channel as a 16-bit step of that channel's range over the layer
//! ([`Quantisation`]); its values are decoded to f32 on reading, so it samples exactly as the f32
//! table of its decoded values does.

use half::f16;
use serde::{Deserialize, Serialize};

use super::param::{CHANNELS, MARGIN};
use super::table::{Corners, Precision};
use crate::pages::{Pages, resize_on, to_vec_on_huge_pages};
use crate::trace::{Isa, with_widest_isa};

/// Nodes per brick edge (a power of two, so brick and offset are a shift and a mask).
pub const BRICK: usize = 4;
const BRICK_NODES: usize = BRICK * BRICK * BRICK;

/// A node's channels as one stored element type holds them.
pub trait Node: Copy + Default + PartialEq + std::fmt::Debug + Send + Sync + 'static {
    /// What a grid of these nodes needs besides them to give its values: nothing for floats,
    /// the channels' ranges for 16-bit codes.
    type Code: Copy + PartialEq + std::fmt::Debug + Send + Sync;
    /// The code that holds every one of `values` (row-major nodes of one layer).
    fn fit(values: &[[f32; CHANNELS]]) -> Self::Code;
    fn from_values(values: &[f32; CHANNELS], code: &Self::Code) -> Self;
    fn values(&self, code: &Self::Code) -> [f32; CHANNELS];
    /// Every channel interpolated over all eight corners of `cell` with AVX2 and F16C (see
    /// `vector`).
    ///
    /// # Safety
    /// The processor must have AVX2 and F16C. Inlined into its caller, it is vector code only
    /// where that caller is compiled for them (elsewhere each intrinsic is a call).
    #[cfg(target_arch = "x86_64")]
    unsafe fn interpolate_vector(nodes: &[Self], code: &Self::Code, cell: &Cell)
    -> [f64; CHANNELS];
}

/// An f32 node, aligned to its 32 bytes.
#[repr(C, align(32))]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NodeF32([f32; CHANNELS]);

/// An f16 node, aligned to its 16 bytes.
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NodeF16([f16; CHANNELS]);

/// A node of 16-bit codes ([`Quantisation`]), aligned to its 16 bytes.
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct NodeU16([u16; CHANNELS]);

/// How a u16 table's codes give its values: channel c of code q is `low[c] + step[c] * q`,
/// computed in f32 (a multiply, then an add: no fused multiply-add, so every machine and the
/// GPU's texels get the same bits). Fitted per layer to each channel's range, so a decoded code
/// is within `step / 2` of the value it stands for, plus the decode's f32 rounding (`step` is
/// the range over 65535).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Quantisation {
    pub low: [f32; CHANNELS],
    pub step: [f32; CHANNELS],
}

impl Quantisation {
    /// The largest code.
    pub const LEVELS: u16 = u16::MAX;

    /// Each channel's range over `values` cut into [`Quantisation::LEVELS`] steps.
    pub fn fit(values: &[[f32; CHANNELS]]) -> Quantisation {
        let mut low = [f32::INFINITY; CHANNELS];
        let mut high = [f32::NEG_INFINITY; CHANNELS];
        for v in values {
            for c in 0..CHANNELS {
                low[c] = low[c].min(v[c]);
                high[c] = high[c].max(v[c]);
            }
        }
        let mut step = [0.0; CHANNELS];
        for c in 0..CHANNELS {
            if !(low[c] <= high[c]) {
                low[c] = 0.0; // no values at all
            } else {
                // Rounded up, so the top code reaches the largest value.
                let exact = (f64::from(high[c]) - f64::from(low[c])) / f64::from(Self::LEVELS);
                step[c] = next_up(exact as f32, exact);
            }
        }
        Quantisation { low, step }
    }

    /// The codes nearest to `values`.
    #[inline]
    pub fn encode(&self, values: &[f32; CHANNELS]) -> [u16; CHANNELS] {
        std::array::from_fn(|c| {
            let at = if self.step[c] > 0.0 {
                ((f64::from(values[c]) - f64::from(self.low[c])) / f64::from(self.step[c])).round()
            } else {
                0.0
            };
            at.clamp(0.0, f64::from(Self::LEVELS)) as u16
        })
    }

    /// The values `codes` stand for.
    #[inline(always)]
    pub fn decode(&self, codes: &[u16; CHANNELS]) -> [f32; CHANNELS] {
        std::array::from_fn(|c| self.low[c] + self.step[c] * f32::from(codes[c]))
    }

    /// A quantisation whose numbers can decode a table: finite, steps not negative, and the
    /// largest value finite too; else the first channel that fails.
    pub fn implausible_channel(&self) -> Option<usize> {
        (0..CHANNELS).find(|&c| {
            let top = self.low[c] + self.step[c] * f32::from(Self::LEVELS);
            !(self.low[c].is_finite() && self.step[c] >= 0.0 && top.is_finite())
        })
    }
}

/// `rounded` (the f32 nearest `exact`) moved up by one ulp when it lies below `exact`.
fn next_up(rounded: f32, exact: f64) -> f32 {
    if f64::from(rounded) >= exact {
        rounded
    } else {
        f32::from_bits(rounded.to_bits() + 1)
    }
}

impl Node for NodeF32 {
    type Code = ();

    fn fit(_: &[[f32; CHANNELS]]) {}

    fn from_values(values: &[f32; CHANNELS], _: &()) -> Self {
        NodeF32(*values)
    }

    fn values(&self, _: &()) -> [f32; CHANNELS] {
        self.0
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn interpolate_vector(nodes: &[Self], _: &(), cell: &Cell) -> [f64; CHANNELS] {
        // SAFETY: the caller's, passed on.
        unsafe { vector::interpolate_f32(nodes, cell) }
    }
}

impl Node for NodeF16 {
    type Code = ();

    fn fit(_: &[[f32; CHANNELS]]) {}

    fn from_values(values: &[f32; CHANNELS], _: &()) -> Self {
        NodeF16(values.map(f16::from_f32))
    }

    fn values(&self, _: &()) -> [f32; CHANNELS] {
        let mut values = [0.0; CHANNELS];
        for (v, &h) in values.iter_mut().zip(&self.0) {
            *v = widen(h);
        }
        values
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn interpolate_vector(nodes: &[Self], _: &(), cell: &Cell) -> [f64; CHANNELS] {
        // SAFETY: the caller's, passed on.
        unsafe { vector::interpolate_f16(nodes, cell) }
    }
}

impl Node for NodeU16 {
    type Code = Quantisation;

    fn fit(values: &[[f32; CHANNELS]]) -> Quantisation {
        Quantisation::fit(values)
    }

    fn from_values(values: &[f32; CHANNELS], code: &Quantisation) -> Self {
        NodeU16(code.encode(values))
    }

    #[inline(always)]
    fn values(&self, code: &Quantisation) -> [f32; CHANNELS] {
        code.decode(&self.0)
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn interpolate_vector(
        nodes: &[Self],
        code: &Quantisation,
        cell: &Cell,
    ) -> [f64; CHANNELS] {
        // SAFETY: the caller's, passed on.
        unsafe { vector::interpolate_u16(nodes, code, cell) }
    }
}

/// `value` as f32, exactly (what `f16::to_f32` gives), in a form the compiler inlines and
/// vectorises: the bits shifted into an f32's places make the value times 2^-112, normal and
/// subnormal alike, and the multiplication by 2^112 is exact. (`half` converts through a call
/// per value or slice that the sampler's eight channels per corner cannot amortise.)
#[inline(always)]
fn widen(value: f16) -> f32 {
    const TWO_TO_112: f32 = f32::from_bits((127 + 112) << 23);
    let bits = u32::from(value.to_bits());
    let magnitude = (bits & 0x7fff) << 13;
    // Without branches, so the eight channels widen side by side.
    let widened = if bits & 0x7c00 == 0x7c00 {
        0x7f80_0000 | magnitude // infinity or NaN
    } else {
        (f32::from_bits(magnitude) * TWO_TO_112).to_bits()
    };
    f32::from_bits(widened | (bits & 0x8000) << 16)
}

/// The grid of one element type, brick by brick.
#[derive(Debug, PartialEq)]
pub struct Grid<N: Node> {
    layout: Bricks,
    code: N::Code,
    nodes: Vec<N>,
}

/// A copy's nodes on huge pages too: the error-budget chooser (`tradeoff::choose`) renders
/// through clones of its tables.
impl<N: Node> Clone for Grid<N> {
    fn clone(&self) -> Self {
        Grid {
            layout: self.layout,
            code: self.code,
            nodes: to_vec_on_huge_pages(&self.nodes),
        }
    }
}

/// Where a grid's nodes are stored, whatever their element type: its nodes along each axis and
/// its bricks along each axis (the last ones padded with nodes no cell reads).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Bricks {
    dims: [usize; 3],
    bricks: [u32; 3],
}

/// The cell a point falls in: where its first corner is stored, the step to the next node along
/// each axis, and the point's fraction of the cell along each. Corner k is the node offset by
/// (k & 1, k >> 1 & 1, k >> 2 & 1). Node numbers are u32 (a grid holds far fewer nodes than
/// 2^32, [`crate::limits::MAX_TABLE_NODES`]): vector lanes multiply 32-bit integers, not 64-bit
/// ones.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cell {
    base: u32,
    steps: [u32; 3],
    fractions: [f64; 3],
}

/// The cells of a group of points, a column per value, as [`Entries::find_cells`] finds them
/// side by side in vector lanes.
pub struct CellColumns<const G: usize> {
    base: [u32; G],
    steps: [[u32; G]; 3],
    fractions: [[f64; G]; 3],
}

impl<const G: usize> CellColumns<G> {
    /// Columns for [`Entries::find_cells`] to fill.
    pub const ZERO: CellColumns<G> = CellColumns {
        base: [0; G],
        steps: [[0; G]; 3],
        fractions: [[0.0; G]; 3],
    };

    /// Point `k`'s cell.
    #[inline(always)]
    pub fn get(&self, k: usize) -> Cell {
        Cell {
            base: self.base[k],
            steps: [0, 1, 2].map(|axis| self.steps[axis][k]),
            fractions: [0, 1, 2].map(|axis| self.fractions[axis][k]),
        }
    }
}

impl Cell {
    /// Where corner `k` is stored.
    #[inline(always)]
    fn node(&self, k: usize) -> usize {
        let k = k as u32;
        (self.base
            + (k & 1) * self.steps[0]
            + ((k >> 1) & 1) * self.steps[1]
            + ((k >> 2) & 1) * self.steps[2]) as usize
    }

    /// Corner `k`'s trilinear weight.
    #[inline(always)]
    fn weight(&self, k: usize) -> f64 {
        let along = |axis: usize| {
            let f = self.fractions[axis];
            if (k >> axis) & 1 == 1 { f } else { 1.0 - f }
        };
        along(0) * along(1) * along(2)
    }
}

/// Trilinear addressing of a coordinate in \[0, 1\] on `n` nodes (2 to 2^31): base index and
/// fraction. Nodes sit at k / (n - 1), so both ends of the domain are sampled exactly; a NaN
/// coordinate is taken as 0.
#[inline(always)]
pub fn address(coord: f64, n: u32) -> (u32, f64) {
    // `max` takes NaN to 0 (`clamp` keeps it), so t is in [0, n - 1] and its truncation (the
    // floor, without the libm call `floor` costs on baseline x86-64) fits an i32. A saturating
    // `as` would be split into scalar conversions and fix-ups, lane by lane.
    #[allow(clippy::manual_clamp)]
    let t = coord.max(0.0).min(1.0) * (n - 1) as f64;
    // SAFETY: t is finite and below 2^31 (above).
    let whole: i32 = unsafe { t.to_int_unchecked() };
    let i = (whole as u32).min(n - 2);
    (i, t - i as f64)
}

impl Bricks {
    /// Where node (i0, i1, i2) is stored.
    #[inline(always)]
    fn index(&self, [i0, i1, i2]: [u32; 3]) -> u32 {
        const B: u32 = BRICK as u32;
        let [b0, b1, _] = self.bricks;
        let brick = i0 / B + b0 * (i1 / B + b1 * (i2 / B));
        let within = i0 % B + B * (i1 % B + B * (i2 % B));
        brick * BRICK_NODES as u32 + within
    }

    /// Branch-free, so [`Grid::cells`] computes a group's cells side by side.
    #[inline(always)]
    fn cell(&self, coords: [f64; 3]) -> Cell {
        let [n0, n1, n2] = self.dims.map(|n| n as u32);
        let (i0, f0) = address(coords[0], n0);
        let (i1, f1) = address(coords[1], n1);
        let (i2, f2) = address(coords[2], n2);
        // The step to the next node along each axis: within the brick, or from the brick's last
        // layer of nodes to the next brick's first.
        let [b0, b1, _] = self.bricks;
        let brick_strides = [1, b0, b0 * b1];
        let step = |i: u32, axis: usize| {
            const B: u32 = BRICK as u32;
            let within = B.pow(axis as u32);
            if i % B == B - 1 {
                brick_strides[axis] * BRICK_NODES as u32 - (B - 1) * within
            } else {
                within
            }
        };
        Cell {
            base: self.index([i0, i1, i2]),
            steps: [step(i0, 0), step(i1, 1), step(i2, 2)],
            fractions: [f0, f1, f2],
        }
    }

    #[inline(always)]
    fn find_cells<const G: usize>(&self, coords: &[[f64; G]; 3], cells: &mut CellColumns<G>) {
        for (k, base) in cells.base.iter_mut().enumerate() {
            let cell = self.cell([coords[0][k], coords[1][k], coords[2][k]]);
            *base = cell.base;
            for axis in 0..3 {
                cells.steps[axis][k] = cell.steps[axis];
                cells.fractions[axis][k] = cell.fractions[axis];
            }
        }
    }
}

impl<N: Node> Grid<N> {
    fn from_row_major(pages: Pages, dims: [usize; 3], values: &[[f32; CHANNELS]]) -> Grid<N> {
        let code = N::fit(values);
        let mut grid = Grid::empty(pages, dims, code);
        for (k, v) in values.iter().enumerate() {
            let at = grid.layout.index(row_major_node(dims, k)) as usize;
            grid.nodes[at] = N::from_values(v, &code);
        }
        grid
    }

    /// A grid of default nodes, to be filled.
    fn empty(pages: Pages, dims: [usize; 3], code: N::Code) -> Grid<N> {
        let bricks = dims.map(|n| n.div_ceil(BRICK));
        let nodes = bricks.iter().product::<usize>() * BRICK_NODES;
        assert!(
            u32::try_from(nodes).is_ok(),
            "{dims:?} nodes are numbered in u32 (MAX_TABLE_NODES keeps tables far below)"
        );
        let mut storage = Vec::new();
        resize_on(pages, &mut storage, nodes, N::default());
        Grid {
            layout: Bricks {
                dims,
                bricks: bricks.map(|b| b as u32),
            },
            code,
            nodes: storage,
        }
    }

    #[inline(always)]
    fn prefetch(&self, cell: &Cell) {
        for k in 0..8 {
            prefetch(&self.nodes[cell.node(k)]);
        }
    }

    #[inline(always)]
    fn interpolate_on(&self, isa: Isa, cell: &Cell, corners: Corners) -> [f64; CHANNELS] {
        #[cfg(target_arch = "x86_64")]
        if corners == Corners::All && isa.has_avx2_f16c() {
            // SAFETY: `isa` is the set the caller is compiled for, one the processor has.
            return unsafe { N::interpolate_vector(&self.nodes, &self.code, cell) };
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = isa;
        self.interpolate_portable(cell, corners)
    }

    /// [`Grid::interpolate`] in plain Rust: what the vector path must equal bit for bit, and
    /// the only path for [`Corners::ValidOnly`].
    fn interpolate_portable(&self, cell: &Cell, corners: Corners) -> [f64; CHANNELS] {
        let mut out = [0.0; CHANNELS];
        let mut valid_out = [0.0; CHANNELS];
        let mut valid_weight = 0.0;
        for k in 0..8 {
            let w = cell.weight(k);
            let entry = self.nodes[cell.node(k)].values(&self.code);
            for (o, v) in out.iter_mut().zip(entry) {
                *o += w * v as f64;
            }
            if corners == Corners::ValidOnly && entry[MARGIN] >= 0.0 {
                valid_weight += w;
                for (o, v) in valid_out.iter_mut().zip(entry) {
                    *o += w * v as f64;
                }
            }
        }
        if corners == Corners::ValidOnly && valid_weight > 0.0 {
            let margin = out[MARGIN];
            out = valid_out.map(|v| v / valid_weight);
            out[MARGIN] = margin;
        }
        out
    }

    fn row_major(&self) -> impl Iterator<Item = [f32; CHANNELS]> + '_ {
        let layout = self.layout;
        (0..layout.dims.iter().product()).map(move |k| {
            self.nodes[layout.index(row_major_node(layout.dims, k)) as usize].values(&self.code)
        })
    }
}

/// Asks the cache for the line holding `node` ahead of its use. No effect on any value.
#[inline(always)]
fn prefetch<T>(node: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch is a hint: it reads no value, cannot fault, and SSE (which has it) is
    // part of every x86-64 CPU.
    unsafe {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        _mm_prefetch::<_MM_HINT_T0>((node as *const T).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = node;
}

/// The interpolation on x86-64 processors with AVX2 and F16C (the build assumes only SSE2,
/// which holds two f64 lanes and has no f16 conversion). A node's eight channels are one 256-bit
/// load (f32) or one 128-bit load widened by `vcvtph2ps` (f16, exact, as [`widen`] is), then two
/// vectors of four f64 that each corner's weight multiplies and the sum adds: separately, in the
/// portable path's order (no fused multiply-add), so every channel gets the same bits as there.
///
/// Nothing here carries a target feature of its own: all of it is inlined into a caller
/// compiled for the set ([`Isa`], handed out by [`with_widest_isa`]) and gets its features
/// there. The caller, not this code, knows which set it was compiled for.
#[cfg(target_arch = "x86_64")]
mod vector {
    use super::{CHANNELS, Cell, NodeF16, NodeF32, NodeU16, Quantisation};
    use std::arch::x86_64::{
        __m256, _mm_loadu_si128, _mm256_add_pd, _mm256_add_ps, _mm256_castps256_ps128,
        _mm256_cvtepi32_ps, _mm256_cvtepu16_epi32, _mm256_cvtph_ps, _mm256_cvtps_pd,
        _mm256_extractf128_ps, _mm256_loadu_ps, _mm256_mul_pd, _mm256_mul_ps, _mm256_set1_pd,
        _mm256_setzero_pd, _mm256_storeu_pd,
    };

    /// # Safety
    /// The processor must have AVX2.
    #[inline(always)]
    pub(super) unsafe fn interpolate_f32(nodes: &[NodeF32], cell: &Cell) -> [f64; CHANNELS] {
        // SAFETY: each load reads a whole node's eight f32; AVX2 is the caller's to ensure.
        unsafe {
            accumulate(
                cell,
                #[inline(always)]
                |node| _mm256_loadu_ps(nodes[node].0.as_ptr()),
            )
        }
    }

    /// # Safety
    /// The processor must have AVX2 and F16C.
    #[inline(always)]
    pub(super) unsafe fn interpolate_f16(nodes: &[NodeF16], cell: &Cell) -> [f64; CHANNELS] {
        // SAFETY: each load reads a whole node's eight f16 (16 bytes); AVX2 and F16C are the
        // caller's to ensure.
        unsafe {
            accumulate(
                cell,
                #[inline(always)]
                |node| _mm256_cvtph_ps(_mm_loadu_si128(nodes[node].0.as_ptr().cast())),
            )
        }
    }

    /// # Safety
    /// The processor must have AVX2.
    #[inline(always)]
    pub(super) unsafe fn interpolate_u16(
        nodes: &[NodeU16],
        code: &Quantisation,
        cell: &Cell,
    ) -> [f64; CHANNELS] {
        // SAFETY: each load reads a whole node's eight u16 (16 bytes) and the ranges' eight f32;
        // AVX2 is the caller's to ensure.
        unsafe {
            let low = _mm256_loadu_ps(code.low.as_ptr());
            let step = _mm256_loadu_ps(code.step.as_ptr());
            accumulate(
                cell,
                // Codes widened exactly to f32, then decoded as `Quantisation::decode` does: a
                // multiply, then an add.
                #[inline(always)]
                |node| {
                    let codes =
                        _mm256_cvtepu16_epi32(_mm_loadu_si128(nodes[node].0.as_ptr().cast()));
                    _mm256_add_ps(low, _mm256_mul_ps(step, _mm256_cvtepi32_ps(codes)))
                },
            )
        }
    }

    /// The weighted sum over the corners.
    ///
    /// # Safety
    /// The processor must have AVX2 (and whatever `load` needs).
    #[inline(always)]
    unsafe fn accumulate(cell: &Cell, load: impl Fn(usize) -> __m256) -> [f64; CHANNELS] {
        // SAFETY: AVX2 is the caller's to ensure; `out` holds the two vectors' eight f64.
        unsafe {
            let mut low = _mm256_setzero_pd();
            let mut high = _mm256_setzero_pd();
            for k in 0..8 {
                let w = _mm256_set1_pd(cell.weight(k));
                let values = load(cell.node(k));
                let value_low = _mm256_cvtps_pd(_mm256_castps256_ps128(values));
                let value_high = _mm256_cvtps_pd(_mm256_extractf128_ps::<1>(values));
                low = _mm256_add_pd(low, _mm256_mul_pd(w, value_low));
                high = _mm256_add_pd(high, _mm256_mul_pd(w, value_high));
            }
            let mut out = [0.0; CHANNELS];
            _mm256_storeu_pd(out.as_mut_ptr(), low);
            _mm256_storeu_pd(out.as_mut_ptr().add(4), high);
            out
        }
    }
}

/// Grid indices of entry `k` in row-major order (`i0 + n0 * (i1 + n1 * i2)`, the file's order).
fn row_major_node([n0, n1, _]: [usize; 3], k: usize) -> [u32; 3] {
    [k % n0, (k / n0) % n1, k / (n0 * n1)].map(|i| i as u32)
}

/// One wavelength's entries in the precision the table was baked with.
#[derive(Clone, Debug, PartialEq)]
pub enum Entries {
    F32(Grid<NodeF32>),
    F16(Grid<NodeF16>),
    U16(Grid<NodeU16>),
}

impl Entries {
    /// Entries from the row-major order of the file (`i0 + n0 * (i1 + n1 * i2)`), stored in
    /// `precision` (f16 rounds each value to nearest).
    ///
    /// # Panics
    /// When `values` does not hold exactly n0 n1 n2 entries (a caller's bug: readers check
    /// sizes against the sidecar first).
    pub fn from_row_major(
        dims: [usize; 3],
        precision: Precision,
        values: &[[f32; CHANNELS]],
    ) -> Entries {
        Entries::from_row_major_on(Pages::Plain, dims, precision, values)
    }

    /// [`Entries::from_row_major`] with the nodes on `pages`: huge pages for a table that is
    /// read from disk to be looked up in.
    pub(crate) fn from_row_major_on(
        pages: Pages,
        dims: [usize; 3],
        precision: Precision,
        values: &[[f32; CHANNELS]],
    ) -> Entries {
        assert_eq!(
            values.len(),
            dims.iter().product::<usize>(),
            "entries for a {dims:?} grid"
        );
        match precision {
            Precision::F32 => Entries::F32(Grid::from_row_major(pages, dims, values)),
            Precision::F16 => Entries::F16(Grid::from_row_major(pages, dims, values)),
            Precision::U16 => Entries::U16(Grid::from_row_major(pages, dims, values)),
        }
    }

    /// A u16 table's entries from its codes in the file's row-major order and the
    /// quantisation that decodes them (on huge pages: a table read from disk).
    ///
    /// # Panics
    /// When `codes` does not hold exactly n0 n1 n2 entries (readers check sizes first).
    pub(crate) fn from_codes(
        dims: [usize; 3],
        quantisation: Quantisation,
        codes: &[[u16; CHANNELS]],
    ) -> Entries {
        assert_eq!(
            codes.len(),
            dims.iter().product::<usize>(),
            "codes for a {dims:?} grid"
        );
        let mut grid: Grid<NodeU16> = Grid::empty(Pages::Huge, dims, quantisation);
        for (k, c) in codes.iter().enumerate() {
            let at = grid.layout.index(row_major_node(dims, k)) as usize;
            grid.nodes[at] = NodeU16(*c);
        }
        Entries::U16(grid)
    }

    /// A u16 table's quantisation and its codes in row-major order (what its file holds);
    /// None for a float table.
    pub fn codes(&self) -> Option<(Quantisation, Vec<[u16; CHANNELS]>)> {
        let Entries::U16(grid) = self else {
            return None;
        };
        let layout = grid.layout;
        let codes = (0..layout.dims.iter().product())
            .map(|k| grid.nodes[layout.index(row_major_node(layout.dims, k)) as usize].0)
            .collect();
        Some((grid.code, codes))
    }

    pub fn precision(&self) -> Precision {
        match self {
            Entries::F32(_) => Precision::F32,
            Entries::F16(_) => Precision::F16,
            Entries::U16(_) => Precision::U16,
        }
    }

    pub fn dims(&self) -> [usize; 3] {
        self.layout().dims
    }

    #[inline(always)]
    fn layout(&self) -> &Bricks {
        match self {
            Entries::F32(g) => &g.layout,
            Entries::F16(g) => &g.layout,
            Entries::U16(g) => &g.layout,
        }
    }

    /// Number of entries (n0 n1 n2; the padding of the last bricks is not counted).
    pub fn len(&self) -> usize {
        self.dims().iter().product()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Bytes the nodes take in memory, bricks' padding included.
    pub fn stored_bytes(&self) -> usize {
        match self {
            Entries::F32(g) => std::mem::size_of_val(g.nodes.as_slice()),
            Entries::F16(g) => std::mem::size_of_val(g.nodes.as_slice()),
            Entries::U16(g) => std::mem::size_of_val(g.nodes.as_slice()),
        }
    }

    /// The entries in row-major order, as f32 (what the file and the GPU textures hold).
    pub fn row_major(&self) -> Box<dyn Iterator<Item = [f32; CHANNELS]> + '_> {
        match self {
            Entries::F32(g) => Box::new(g.row_major()),
            Entries::F16(g) => Box::new(g.row_major()),
            Entries::U16(g) => Box::new(g.row_major()),
        }
    }

    /// The entry at grid node `node`.
    pub fn get(&self, node: [usize; 3]) -> [f32; CHANNELS] {
        let at = self.layout().index(node.map(|i| i as u32)) as usize;
        match self {
            Entries::F32(g) => g.nodes[at].values(&g.code),
            Entries::F16(g) => g.nodes[at].values(&g.code),
            Entries::U16(g) => g.nodes[at].values(&g.code),
        }
    }

    /// The same entries stored in `precision`, on huge pages (a copy is made to render with).
    pub fn to_precision(&self, precision: Precision) -> Entries {
        let values: Vec<_> = self.row_major().collect();
        Entries::from_row_major_on(Pages::Huge, self.dims(), precision, &values)
    }

    /// The cell holding table coordinates `coords` (clamped to \[0, 1\]^3).
    #[inline(always)]
    pub fn cell(&self, coords: [f64; 3]) -> Cell {
        self.layout().cell(coords)
    }

    /// [`Entries::cell`] of every point of a group (a column per coordinate) into `cells`, side
    /// by side in vector lanes where the caller is compiled for them. Written into the caller's
    /// columns: returned by value, they were copied once more, which cost several times what
    /// finding them does (a `rep movsb` of 2.5 KiB per group).
    #[inline(always)]
    pub fn find_cells<const G: usize>(&self, coords: &[[f64; G]; 3], cells: &mut CellColumns<G>) {
        self.layout().find_cells(coords, cells)
    }

    /// Asks the cache for `cell`'s corners ahead of [`Entries::interpolate`], so that the
    /// misses of several cells overlap; no effect on any value.
    #[inline(always)]
    pub fn prefetch(&self, cell: &Cell) {
        match self {
            Entries::F32(g) => g.prefetch(cell),
            Entries::F16(g) => g.prefetch(cell),
            Entries::U16(g) => g.prefetch(cell),
        }
    }

    /// Every channel interpolated in `cell`, the values taken from `corners`, in the widest
    /// instruction set this processor has.
    pub fn interpolate(&self, cell: &Cell, corners: Corners) -> [f64; CHANNELS] {
        with_widest_isa(
            #[inline(always)]
            |isa| self.interpolate_on(isa, cell, corners),
        )
    }

    /// [`Entries::interpolate`] from code compiled for `isa` (handed out by
    /// [`with_widest_isa`]); inlined there, so the vector path is compiled with it.
    #[inline(always)]
    pub(crate) fn interpolate_on(
        &self,
        isa: Isa,
        cell: &Cell,
        corners: Corners,
    ) -> [f64; CHANNELS] {
        match self {
            Entries::F32(g) => g.interpolate_on(isa, cell, corners),
            Entries::F16(g) => g.interpolate_on(isa, cell, corners),
            Entries::U16(g) => g.interpolate_on(isa, cell, corners),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const PRECISIONS: [Precision; 3] = [Precision::F32, Precision::F16, Precision::U16];

    /// `values` as a grid of `precision` holds them.
    fn stored(precision: Precision, values: &[[f32; CHANNELS]]) -> Vec<[f32; CHANNELS]> {
        let quantisation = Quantisation::fit(values);
        values
            .iter()
            .map(|v| match precision {
                Precision::F32 => *v,
                Precision::F16 => v.map(|x| f16::from_f32(x).to_f32()),
                Precision::U16 => quantisation.decode(&quantisation.encode(v)),
            })
            .collect()
    }

    fn ramp(dims: [usize; 3]) -> Vec<[f32; CHANNELS]> {
        (0..dims.iter().product::<usize>())
            .map(|k| std::array::from_fn(|c| (k * CHANNELS + c) as f32 * 0.25))
            .collect()
    }

    #[test]
    fn bricks_keep_every_entry_in_every_precision() {
        // Sizes that are not multiples of the brick, and one below it.
        for dims in [[5, 3, 7], [2, 2, 2], [9, 4, 6]] {
            let values = ramp(dims);
            for precision in PRECISIONS {
                let entries = Entries::from_row_major(dims, precision, &values);
                let rounded = stored(precision, &values);
                assert_eq!(entries.row_major().collect::<Vec<_>>(), rounded);
                for (k, v) in rounded.iter().enumerate() {
                    let node = row_major_node(dims, k).map(|i| i as usize);
                    assert_eq!(entries.get(node), *v);
                }
                assert_eq!(entries.precision(), precision);
                assert_eq!(entries.len(), values.len());
            }
        }
    }

    #[test]
    fn interpolation_is_bit_for_bit_the_row_major_one() {
        // The layout changes, the arithmetic does not: the corners in the same order with the
        // same weights, read from the file's row-major order, give the same bits.
        let dims = [9, 6, 7];
        let values: Vec<[f32; CHANNELS]> = (0..dims.iter().product::<usize>())
            .map(|k| {
                std::array::from_fn(|c| ((k * 7919 + c * 104_729) % 1000) as f32 * 0.0137 - 5.0)
            })
            .collect();
        for precision in PRECISIONS {
            let entries = Entries::from_row_major(dims, precision, &values);
            let held = stored(precision, &values);
            for step in 0..500 {
                let coords = [0.618_034, 0.414_214, 0.732_051].map(|a: f64| {
                    let t = (a * step as f64).fract();
                    t * 1.2 - 0.1
                });
                let [(i0, f0), (i1, f1), (i2, f2)] = [0, 1, 2].map(|axis| {
                    let (i, f) = address(coords[axis], dims[axis] as u32);
                    (i as usize, f)
                });
                let mut expected = [0.0f64; CHANNELS];
                for corner in 0..8 {
                    let (d0, d1, d2) = (corner & 1, (corner >> 1) & 1, (corner >> 2) & 1);
                    let w = if d0 == 1 { f0 } else { 1.0 - f0 }
                        * if d1 == 1 { f1 } else { 1.0 - f1 }
                        * if d2 == 1 { f2 } else { 1.0 - f2 };
                    let entry = held[(i0 + d0) + dims[0] * ((i1 + d1) + dims[1] * (i2 + d2))];
                    for (e, v) in expected.iter_mut().zip(entry) {
                        *e += w * v as f64;
                    }
                }
                let got = entries.interpolate(&entries.cell(coords), Corners::All);
                assert_eq!(
                    got.map(f64::to_bits),
                    expected.map(f64::to_bits),
                    "{coords:?}"
                );
            }
        }
    }

    #[test]
    fn vector_interpolation_is_the_portable_one_bit_for_bit() {
        // `interpolate` takes the vector path wherever the processor has the AVX2 set (with
        // F16C; no narrower set asked for), so on such a machine this compares the two paths.
        #[cfg(target_arch = "x86_64")]
        if std::env::var_os("LENSBAKE_ISA").is_none() && Isa::has_avx2_set() {
            assert!(with_widest_isa(|isa| isa.has_avx2_f16c()));
        }
        // Channel values of every sign and magnitude each precision holds (random bit patterns,
        // infinities and NaN left out), at random points in and around the grid.
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut random = move || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        let dims = [11, 7, 9];
        for precision in PRECISIONS {
            let values: Vec<[f32; CHANNELS]> = (0..dims.iter().product::<usize>())
                .map(|_| {
                    std::array::from_fn(|_| {
                        loop {
                            let bits = random();
                            let v = match precision {
                                Precision::F32 => f32::from_bits(bits as u32),
                                Precision::F16 => f16::from_bits(bits as u16).to_f32(),
                                // Codes of every value in ranges a table's channels span
                                // (a range of 1e38 would overflow its top code).
                                Precision::U16 => {
                                    (bits >> 11) as f32 / (1u64 << 53) as f32 * 2e3 - 1e3
                                }
                            };
                            if v.is_finite() {
                                break v;
                            }
                        }
                    })
                })
                .collect();
            let entries = Entries::from_row_major(dims, precision, &values);
            for _ in 0..4000 {
                let coords =
                    [0; 3].map(|_| (random() >> 11) as f64 / (1u64 << 53) as f64 * 1.2 - 0.1);
                let cell = entries.cell(coords);
                let portable = match &entries {
                    Entries::F32(g) => g.interpolate_portable(&cell, Corners::All),
                    Entries::F16(g) => g.interpolate_portable(&cell, Corners::All),
                    Entries::U16(g) => g.interpolate_portable(&cell, Corners::All),
                };
                let expected = portable.map(f64::to_bits);
                let dispatched = entries.interpolate(&cell, Corners::All);
                assert_eq!(
                    dispatched.map(f64::to_bits),
                    expected,
                    "{precision:?} {coords:?}"
                );
            }
        }
    }

    #[test]
    fn cell_corners_are_the_nodes_around_the_point() {
        let dims = [9, 6, 13];
        let grid: Grid<NodeF32> = Grid::from_row_major(Pages::Plain, dims, &ramp(dims));
        for i2 in 0..dims[2] - 1 {
            for i1 in 0..dims[1] - 1 {
                for i0 in 0..dims[0] - 1 {
                    let coords = [i0, i1, i2].map(|i| i as f64 + 0.5);
                    let cell = grid
                        .layout
                        .cell([0, 1, 2].map(|a| coords[a] / (dims[a] - 1) as f64));
                    for k in 0..8 {
                        let corner = [i0 + (k & 1), i1 + ((k >> 1) & 1), i2 + ((k >> 2) & 1)];
                        let corner = corner.map(|i| i as u32);
                        assert_eq!(
                            cell.node(k),
                            grid.layout.index(corner) as usize,
                            "{corner:?}"
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn cells_in_columns_are_the_cells_one_at_a_time() {
        const G: usize = 64;
        let dims = [9, 6, 13];
        let entries = Entries::from_row_major(dims, Precision::F32, &ramp(dims));
        let specials = [
            f64::NAN,
            -0.5,
            -0.0,
            0.0,
            1.0,
            1.5,
            f64::INFINITY,
            -f64::INFINITY,
        ];
        let mut coords = [[0.0; G]; 3];
        for (axis, column) in coords.iter_mut().enumerate() {
            for (k, c) in column.iter_mut().enumerate() {
                *c = match k {
                    0..8 => specials[(k + axis) % specials.len()],
                    _ => ((k * (axis + 3)) as f64 * 0.618_034).fract() * 1.2 - 0.1,
                };
            }
        }
        let mut cells = CellColumns::ZERO;
        entries.find_cells(&coords, &mut cells);
        for k in 0..G {
            let point = coords.map(|column| column[k]);
            assert_eq!(cells.get(k), entries.cell(point), "{point:?}");
        }
    }

    #[test]
    fn widen_is_the_f16_conversion_for_every_value() {
        for bits in 0..=u16::MAX {
            let value = f16::from_bits(bits);
            let (got, expected) = (widen(value), value.to_f32());
            if expected.is_nan() {
                assert!(got.is_nan(), "{bits:#06x}");
            } else {
                assert_eq!(got.to_bits(), expected.to_bits(), "{bits:#06x}");
            }
        }
    }

    #[test]
    fn f16_and_u16_grids_hold_half_the_bytes() {
        assert_eq!(std::mem::size_of::<NodeF32>(), 32);
        assert_eq!(std::mem::size_of::<NodeF16>(), 16);
        assert_eq!(std::mem::size_of::<NodeU16>(), 16);
        assert_eq!(std::mem::align_of::<NodeF32>(), 32);
        assert_eq!(std::mem::align_of::<NodeF16>(), 16);
        assert_eq!(std::mem::align_of::<NodeU16>(), 16);
        let dims = [16, 16, 16];
        let bytes = |p| Entries::from_row_major(dims, p, &ramp(dims)).stored_bytes();
        assert_eq!(bytes(Precision::U16) * 2, bytes(Precision::F32));
    }

    #[test]
    fn u16_codes_hold_every_value_within_half_a_step() {
        // Channels of very different ranges and offsets, one constant: each decoded value
        // lies within half a step of the value (plus the f32 rounding of the decode), and the
        // range's ends are codes 0 and 65535.
        let values: Vec<[f32; CHANNELS]> = (0..5000)
            .map(|k| {
                let t = (k as f32 * 0.618_034).fract();
                [
                    20.0 * t - 10.0,
                    1e-3 * t,
                    0.4 * (7.0 * t).sin(),
                    -3.0 - t,
                    5.0,
                    1e4 * t * t,
                    t - 0.5,
                    2.0 + 0.01 * t,
                ]
            })
            .collect();
        let q = Quantisation::fit(&values);
        assert_eq!(q.implausible_channel(), None);
        for c in 0..CHANNELS {
            let column = values.iter().map(|v| v[c]);
            let (low, high) = column.fold((f32::MAX, f32::MIN), |(l, h), x| (l.min(x), h.max(x)));
            assert_eq!(q.low[c], low);
            let top = q.decode(&[Quantisation::LEVELS; CHANNELS])[c];
            assert!(
                top >= high && top - high <= 2.0 * f32::EPSILON * high.abs().max(q.step[c]),
                "{c}"
            );
        }
        for v in &values {
            let decoded = q.decode(&q.encode(v));
            for c in 0..CHANNELS {
                // Half a step, and the decode's f32 rounding (of low + step * code).
                let bound = 0.5 * q.step[c] + 2.0 * f32::EPSILON * (q.low[c].abs() + v[c].abs());
                assert!(
                    (decoded[c] - v[c]).abs() <= bound,
                    "channel {c}: {} for {}",
                    decoded[c],
                    v[c]
                );
            }
        }
        // Half a step is what is lost: the codes are not coarser than the range asks.
        assert!(q.step[0] <= 20.0 / 65535.0 * (1.0 + 1e-6));
        assert_eq!(q.step[4], 0.0);
    }

    #[test]
    fn address_puts_nodes_at_both_ends_and_floors() {
        assert_eq!(address(0.0, 5), (0, 0.0));
        assert_eq!(address(1.0, 5), (3, 1.0));
        let (i, f) = address(0.6, 5);
        assert_eq!(i, 2);
        assert!((f - 0.4).abs() < 1e-12);
        // Just below a node, and out of range on both sides.
        assert_eq!(address(0.5 - 1e-12, 5).0, 1);
        assert_eq!(address(-3.0, 5), (0, 0.0));
        assert_eq!(address(7.0, 5), (3, 1.0));
        assert_eq!(address(f64::NAN, 5).0, 0);
    }
}
