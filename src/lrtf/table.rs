//! A baked table in memory and the one sampler that reads it (the CPU twin of
//! `lrtf_sample.wgsl`: same addressing, same trilinear weights, same aperture-margin test).

use serde::{Deserialize, Serialize};

use super::entries::{CellColumns, Entries};
use super::focus::{FocusError, FocusRange};
use super::param::{
    CHANNELS, Frame, Located, MARGIN, Parameterisation, Ray, film_radius_of, locate_pupil_planes,
    to_lens_frame,
};
use crate::pupil::{CircleInterpolation, FocusPupilTable, PupilCircle, PupilTable};
use crate::trace::{Isa, with_widest_isa};

/// Sample format on disk and in memory (see [`Entries`]): sampling a table in memory gives
/// exactly the error of its file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Precision {
    F32,
    /// Half floats: 11 significant bits, so a value's rounding grows with its magnitude (an
    /// exit point 20 mm off the axis is held to 8 um).
    F16,
    /// 16-bit codes spread evenly over each channel's range in the layer
    /// ([`super::entries::Quantisation`]): as small as f16, rounding within 1/131070 of the
    /// range, far below what the interpolation misses (docs/lrtf.md).
    U16,
}

impl Precision {
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F16 => "f16",
            Precision::U16 => "u16",
        }
    }

    pub fn from_name(name: &str) -> Option<Precision> {
        [Precision::F32, Precision::F16, Precision::U16]
            .into_iter()
            .find(|p| p.name() == name)
    }

    pub fn bytes(self) -> usize {
        match self {
            Precision::F32 => 4,
            Precision::F16 | Precision::U16 => 2,
        }
    }
}

/// One wavelength's table: its frame, effective pupil and entries.
#[derive(Clone, Debug, PartialEq)]
pub struct Layer {
    pub wavelength_nm: f64,
    pub frame: Frame,
    /// The effective pupil of the reference film plane: the circles the pupil-planes
    /// coordinates are normalised to, over the table's film-radius domain.
    pub pupil: PupilTable,
    /// The effective pupil lens samples are drawn in, over film radius and focus (one node for a
    /// single-focus table, where it equals `pupil`).
    pub sampling: FocusPupilTable,
    /// Stop semi-aperture the table was baked with (mm).
    pub stop_semi_aperture: f64,
    pub entries: Entries,
}

/// Everything that fixes what a table means; stored in the RON sidecar.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct TableInfo {
    pub parameterisation: Parameterisation,
    pub resolution: [usize; 3],
    pub precision: Precision,
    /// f-number the table was baked at (wide open by default); it serves this and above.
    pub f_number: f64,
    /// The object distances in focus the table serves, and the film plane of each.
    pub focus: FocusRange,
}

/// A whole table: one layer per wavelength.
#[derive(Clone, Debug, PartialEq)]
pub struct LrtfTable {
    pub info: TableInfo,
    pub layers: Vec<Layer>,
}

/// The WGSL uniform `LrtfParams` (64 bytes, std140-compatible; layout checked against naga).
/// The renderer uploads it as is.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GpuParams {
    pub rear_plane_z: f32,
    pub film_plane_z: f32,
    pub max_film_radius: f32,
    pub max_rear_radius: f32,
    pub max_polar_angle: f32,
    pub stop_radius_sq: f32,
    pub parameterisation: u32,
    /// Circles of the coordinate pupil, at the head of the pupil buffer.
    pub pupil_count: u32,
    pub dims: [u32; 3],
    /// [`super::io::FORMAT_VERSION`]: the shader refuses a block filled for another format.
    pub format_version: u32,
    /// Film radius of the sampling pupil's last circle per focus node.
    pub sampling_max_film_radius: f32,
    /// Circles per focus node of the sampling pupil, after the coordinate pupil in the buffer.
    pub sampling_count: u32,
    pub focus_count: u32,
    /// The render's film plane in focus-node units (0 at the first node).
    pub focus_coordinate: f32,
}

/// `LrtfResult::status` codes of the shader's `lrtf_sample`, one per [`Lookup`] variant.
pub const LRTF_PASSES: u32 = 0;
pub const LRTF_BLOCKED: u32 = 1;
pub const LRTF_OUTSIDE: u32 = 2;
/// The shader's status when `LrtfParams::format_version` is not the format it was compiled for
/// (an exported sampler bound to a table of another lensbake); the CPU reads the files and
/// refuses such a table when loading it instead.
pub const LRTF_VERSION_MISMATCH: u32 = 3;

/// What the table says about one film-side ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Lookup {
    /// The ray passes; `ray.origin` is where it leaves surface 1, `ray.direction` where it goes.
    Passes(Ray),
    /// Blocked somewhere in the lens (vignetted, TIR or missed: the table does not say which).
    Blocked,
    /// The ray falls outside what the table covers (film radius beyond its domain, or it never
    /// reaches the rear plane).
    OutsideDomain,
}

impl Lookup {
    /// The outgoing ray when the ray passes, as the crate's checked [`crate::Ray`].
    pub fn passed(&self) -> Option<crate::trace::Ray> {
        match self {
            Lookup::Passes(ray) => crate::trace::Ray::new(ray.origin, ray.direction).ok(),
            Lookup::Blocked | Lookup::OutsideDomain => None,
        }
    }
}

/// Why a table cannot answer for a focus or an f-number.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LookupError {
    #[error(transparent)]
    Focus(#[from] FocusError),
    #[error("f-number {asked} is faster than the table serves (baked at f/{baked:.3})")]
    FNumber { asked: f64, baked: f64 },
    #[error("layer {asked} does not exist: the table has {layers} (one per wavelength)")]
    Layer { asked: usize, layers: usize },
}

/// A table at one focus, f-number and wavelength layer ([`LrtfTable::focused`]): the film
/// plane and stop radius worked out once, for looking up many rays.
#[derive(Clone, Copy, Debug)]
pub struct FocusedTable<'a> {
    table: &'a LrtfTable,
    layer: usize,
    film_z: f64,
    stop_radius: f64,
}

impl FocusedTable<'_> {
    /// The same focus and f-number in layer `layer` (wavelength `table.layers[layer]`).
    pub fn layer(self, layer: usize) -> Result<Self, LookupError> {
        let layers = self.table.layers.len();
        if layer >= layers {
            return Err(LookupError::Layer {
                asked: layer,
                layers,
            });
        }
        // Every layer is baked at the same f-number, so the stop scales alike.
        let stop_radius = self.stop_radius / self.table.layers[self.layer].stop_semi_aperture
            * self.table.layers[layer].stop_semi_aperture;
        Ok(FocusedTable {
            layer,
            stop_radius,
            ..self
        })
    }

    /// z of the film plane in focus (lens frame, mm): film-side rays start on it.
    pub fn film_z(&self) -> f64 {
        self.film_z
    }

    /// Wavelength of the layer looked up, nm.
    pub fn wavelength_nm(&self) -> f64 {
        self.table.layers[self.layer].wavelength_nm
    }

    /// What the table says about `ray` (film side, travelling -z); a ray crossing the film
    /// plane beyond the film the table covers is [`Lookup::OutsideDomain`].
    pub fn lookup(&self, ray: &crate::trace::Ray) -> Lookup {
        self.table
            .lookup_focused(self.layer, &(*ray).into(), self.stop_radius, self.film_z)
    }
}

/// Which corners of the enclosing cell the transfer values are interpolated from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Corners {
    /// All eight, trilinearly (what the shader does): blocked corners hold the geometric
    /// continuation, so no sentinel is mixed in.
    #[default]
    All,
    /// Only the corners whose ray passes (margin >= 0), weights renormalised to sum to 1: the
    /// alternative measured in docs/lrtf.md. The margin itself is interpolated from all eight
    /// either way.
    ValidOnly,
}

impl Layer {
    /// Trilinear interpolation of every channel at table coordinates.
    pub fn fetch(&self, coords: [f64; 3]) -> [f64; CHANNELS] {
        self.fetch_from(coords, Corners::All)
    }

    /// Interpolation at table coordinates with the values taken from `corners`.
    pub fn fetch_from(&self, coords: [f64; 3], corners: Corners) -> [f64; CHANNELS] {
        self.entries
            .interpolate(&self.entries.cell(coords), corners)
    }
}

/// Rays a lookup handles together: it locates all of them (side by side, in vector lanes) before
/// it reads any table entry, so the reads of several rays are in flight at once (in a large
/// table most of them miss cache). 64, a quarter of a renderer's group of samples: at 16 the
/// compiler unrolled the lanes' loops whole instead of vectorising them, and at 256 a baked
/// frame was no faster while a lookup of one ray computed four times the lanes.
pub const LOOKUP_GROUP: usize = 64;

/// How many rays ahead of its interpolation a cell's corners are asked for: enough that the
/// misses of several cells overlap, few enough that the corners are still in the first-level
/// cache when read (a group's 512 corners fill it).
const PREFETCH_AHEAD: usize = 8;

/// Tables up to this size are read without prefetching: once read they stay in a core's
/// second-level cache (1-2 MiB on recent cores) or close to it (512 KiB on AMD's Zen 2, with the
/// third level a few dozen cycles away), and the prefetches cost their address arithmetic and
/// issue slots for nothing (about 3 % of a 16^3 table's frame; 1.5-2 % of a 32^3 one, 1 MiB in
/// f32, on Zen 2). An 8 MiB table (64^3 f32) gains from them (1.5 %).
const PREFETCH_ABOVE_BYTES: usize = 2 << 20;

/// What a located ray's place says before the table is read: it falls inside (`LRTF_PASSES`,
/// the lookup goes on), or outside the domain, or outside the conservative pupil bound
/// (`LRTF_BLOCKED`). Beyond the film radius a pupil-planes table covers, nothing is known.
#[inline(always)]
fn verdict(reaches: bool, at: &Located, pupil_planes: bool) -> u32 {
    // Every test made (no short circuits), so the lanes choose without branches.
    let beyond_film = pupil_planes & (at.coords[0] > 1.0);
    let inside = if at.in_domain {
        LRTF_PASSES
    } else {
        LRTF_BLOCKED
    };
    if !reaches | (!at.in_domain & beyond_film) {
        LRTF_OUTSIDE
    } else {
        inside
    }
}

/// How a parameterisation places a ray in its table and decodes a stored direction, each
/// inlined into the lookup's lanes.
trait Place {
    /// What is found for a whole group (columns x, y, z, dx, dy, dz) before any of its rays is
    /// located.
    type Prepared;
    fn prepare(&self, columns: &[[f64; LOOKUP_GROUP]; 6]) -> Self::Prepared;
    /// Where `ray`, ray `k` of the prepared group, lands, and its [`verdict`].
    fn locate(&self, prepared: &Self::Prepared, k: usize, ray: &Ray) -> (Located, u32);
    fn decode(&self, e: [f64; 2]) -> [f64; 3];
}

/// The pupil-planes parameterisation: without branches, so its lanes are vector code.
struct PupilPlanesPlace<'a> {
    frame: &'a Frame,
    circles: CircleInterpolation<'a>,
}

impl Place for PupilPlanesPlace<'_> {
    /// Each ray's circle of the coordinate pupil (centres, radii): where the circles lie is
    /// worked out in lanes, the circles read ray by ray. Read within the lanes that locate, the
    /// reads kept the compiler from vectorising any of it.
    type Prepared = [[f64; LOOKUP_GROUP]; 2];

    #[inline(always)]
    fn prepare(&self, columns: &[[f64; LOOKUP_GROUP]; 6]) -> Self::Prepared {
        let mut below = [0; LOOKUP_GROUP];
        let mut fraction = [0.0; LOOKUP_GROUP];
        for k in 0..LOOKUP_GROUP {
            let (i, f) = self
                .circles
                .position(film_radius_of(self.frame, &ray_of(columns, k)));
            below[k] = i;
            fraction[k] = f;
        }
        let mut circles = [[0.0; LOOKUP_GROUP]; 2];
        for k in 0..LOOKUP_GROUP {
            let circle = self.circles.between(below[k], fraction[k]);
            circles[0][k] = circle.centre_x;
            circles[1][k] = circle.radius;
        }
        circles
    }

    #[inline(always)]
    fn locate(&self, circles: &Self::Prepared, k: usize, ray: &Ray) -> (Located, u32) {
        let circle = PupilCircle {
            centre_x: circles[0][k],
            radius: circles[1][k],
        };
        let (at, reaches) = locate_pupil_planes(self.frame, |_| circle, ray);
        (at, verdict(reaches, &at, true))
    }

    #[inline(always)]
    fn decode(&self, e: [f64; 2]) -> [f64; 3] {
        Parameterisation::PupilPlanes.decode_direction(e)
    }
}

/// The spherical parameterisation (its angles are libm calls, lane by lane).
struct SphericalPlace<'a> {
    layer: &'a Layer,
}

impl Place for SphericalPlace<'_> {
    type Prepared = ();

    #[inline(always)]
    fn prepare(&self, _: &[[f64; LOOKUP_GROUP]; 6]) {}

    #[inline(always)]
    fn locate(&self, _: &(), _: usize, ray: &Ray) -> (Located, u32) {
        match Parameterisation::Spherical.locate(&self.layer.frame, &self.layer.pupil, ray) {
            Some(at) => (at, verdict(true, &at, false)),
            None => (Located::NOWHERE, LRTF_OUTSIDE),
        }
    }

    #[inline(always)]
    fn decode(&self, e: [f64; 2]) -> [f64; 3] {
        Parameterisation::Spherical.decode_direction(e)
    }
}

/// Ray `k` of a group in columns (x, y, z, dx, dy, dz).
#[inline(always)]
fn ray_of(columns: &[[f64; LOOKUP_GROUP]; 6], k: usize) -> Ray {
    Ray {
        origin: [columns[0][k], columns[1][k], columns[2][k]],
        direction: [columns[3][k], columns[4][k], columns[5][k]],
    }
}

/// The rays a lookup is given: one after the other, or the first `count` rays of a group
/// already in columns (x, y, z, dx, dy, dz) as the renderer builds them.
#[derive(Clone, Copy)]
enum LookupRays<'a> {
    Rays(&'a [Ray]),
    #[cfg(feature = "render")]
    Columns {
        columns: &'a [[f64; LOOKUP_GROUP]; 6],
        count: usize,
    },
}

/// The two largest columns a group of lookups is worked out in (7 KB). A caller that looks up
/// group after group keeps one and passes it each time, since every group overwrites what it
/// reads: a baked frame ran 2-3 % faster than with them cleared afresh per group. The other
/// columns stay the group's own: held here as well, they made the frame 8-9 % slower, the
/// compiler no longer knowing them apart from each other.
// Line-aligned, as a trace block is: no placement splits a column's vector access in two.
#[repr(align(64))]
pub(crate) struct LookupScratch {
    /// The interpolated channels; a lane whose ray is not placed keeps an earlier group's.
    values: [[f64; LOOKUP_GROUP]; CHANNELS],
    /// The outgoing rays (x, y, z, dx, dy, dz).
    leaving: [[f64; LOOKUP_GROUP]; 6],
}

impl LookupScratch {
    pub(crate) fn new() -> LookupScratch {
        LookupScratch {
            values: [[0.0; LOOKUP_GROUP]; CHANNELS],
            leaving: [[0.0; LOOKUP_GROUP]; 6],
        }
    }
}

/// One lookup's settings: the layer, the stop, the corners interpolated, and its
/// parameterisation's [`Place`].
struct LaneLookup<'a, P> {
    layer: &'a Layer,
    stop_radius: f64,
    corners: Corners,
    place: P,
}

impl<P: Place> LaneLookup<'_, P> {
    /// Looks `rays` up, handing ray k's result to `emit(k, ..)`, [`LOOKUP_GROUP`] at a time in
    /// vector lanes: every ray located, then every lane's cell addressed, the placed rays'
    /// corners prefetched (so the misses of the group overlap) and interpolated, then the stop
    /// and margin tests and the outgoing rays for all of them. Compiled for the widest
    /// instruction set; the lanes compute the same numbers one ray at a time would.
    fn run(
        &self,
        rays: LookupRays,
        scratch: &mut LookupScratch,
        emit: &mut impl FnMut(usize, Lookup),
    ) {
        with_widest_isa(
            #[inline(always)]
            |isa| match rays {
                LookupRays::Rays(rays) => {
                    for (chunk, rays) in rays.chunks(LOOKUP_GROUP).enumerate() {
                        // Columns of the rays; lanes past the last ray repeat the first.
                        let mut columns = [[0.0; LOOKUP_GROUP]; 6];
                        for k in 0..LOOKUP_GROUP {
                            let ray = rays[k.min(rays.len() - 1)];
                            for axis in 0..3 {
                                columns[axis][k] = ray.origin[axis];
                                columns[3 + axis][k] = ray.direction[axis];
                            }
                        }
                        let first = chunk * LOOKUP_GROUP;
                        self.group(isa, &columns, rays.len(), scratch, &mut |k, found| {
                            emit(first + k, found)
                        });
                    }
                }
                #[cfg(feature = "render")]
                LookupRays::Columns { columns, count } => {
                    self.group(isa, columns, count, scratch, emit)
                }
            },
        );
    }

    /// The first `n` rays of `columns` (x, y, z, dx, dy, dz) looked up, ray k's result handed to
    /// `emit(k, ..)` (to the renderer's own rays, with no array of results in between); the
    /// lanes past them are computed and not used. `isa` is the set the group is compiled for.
    #[inline(always)]
    fn group(
        &self,
        isa: Isa,
        columns: &[[f64; LOOKUP_GROUP]; 6],
        n: usize,
        scratch: &mut LookupScratch,
        emit: &mut impl FnMut(usize, Lookup),
    ) {
        const G: usize = LOOKUP_GROUP;
        // Where each lands, a column per value, so the lanes store whole vectors.
        let LookupScratch { values, leaving } = scratch;
        let mut coords = [[0.0; G]; 3];
        let mut rotation = [[0.0; G]; 2];
        let mut mirror = [0.0; G];
        let mut in_domain = [false; G];
        let mut verdicts = [LRTF_OUTSIDE; G];
        let prepared = self.place.prepare(columns);
        for k in 0..G {
            let (at, verdict) = self.place.locate(&prepared, k, &ray_of(columns, k));
            for (column, value) in coords.iter_mut().zip(at.coords) {
                column[k] = value;
            }
            rotation[0][k] = at.rotation[0];
            rotation[1][k] = at.rotation[1];
            mirror[k] = at.mirror;
            in_domain[k] = at.in_domain;
            verdicts[k] = verdict;
        }
        let located = |k: usize| Located {
            coords: [coords[0][k], coords[1][k], coords[2][k]],
            rotation: [rotation[0][k], rotation[1][k]],
            mirror: mirror[k],
            in_domain: in_domain[k],
        };
        let entries = &self.layer.entries;
        // Every lane's cell, in lanes (the coordinates outside the table are clamped into it),
        // then the corners of the placed rays' cells asked for, so the misses of the group
        // overlap instead of following each other.
        let mut cells = CellColumns::ZERO;
        entries.find_cells(&coords, &mut cells);
        let placed = |k: usize| verdicts[k] == LRTF_PASSES;
        let prefetching = entries.stored_bytes() > PREFETCH_ABOVE_BYTES;
        for k in (0..n.min(PREFETCH_AHEAD)).filter(|&k| prefetching && placed(k)) {
            entries.prefetch(&cells.get(k));
        }
        for k in 0..n {
            let ahead = k + PREFETCH_AHEAD;
            if prefetching && ahead < n && placed(ahead) {
                entries.prefetch(&cells.get(ahead));
            }
            if placed(k) {
                let v = entries.interpolate_on(isa, &cells.get(k), self.corners);
                for (column, value) in values.iter_mut().zip(v) {
                    column[k] = value;
                }
            }
        }
        let mut passes = [false; G];
        for k in 0..G {
            let v = std::array::from_fn(|channel| values[channel][k]);
            let (ray, through) = self.leaving(&located(k), &v);
            for axis in 0..3 {
                leaving[axis][k] = ray.origin[axis];
                leaving[3 + axis][k] = ray.direction[axis];
            }
            passes[k] = through;
        }
        for k in 0..n {
            let found = match verdicts[k] {
                LRTF_PASSES if passes[k] => Lookup::Passes(Ray {
                    origin: [leaving[0][k], leaving[1][k], leaving[2][k]],
                    direction: [leaving[3][k], leaving[4][k], leaving[5][k]],
                }),
                LRTF_PASSES | LRTF_BLOCKED => Lookup::Blocked,
                _ => Lookup::OutsideDomain,
            };
            emit(k, found);
        }
    }

    /// The outgoing ray in the lens frame for the interpolated channels `v` at `at`, and
    /// whether the ray passes the stop and aperture-margin tests.
    #[inline(always)]
    fn leaving(&self, at: &Located, v: &[f64; CHANNELS]) -> (Ray, bool) {
        let stop_ok = v[5] * v[5] + v[6] * v[6] <= self.stop_radius * self.stop_radius;
        let outside_an_aperture = v[MARGIN] < 0.0;
        let passes = !outside_an_aperture & stop_ok;
        let exit = to_lens_frame([v[0], v[1]], at);
        let d = self.place.decode([v[2], v[3]]);
        let d_xy = to_lens_frame([d[0], d[1]], at);
        let ray = Ray {
            origin: [exit[0], exit[1], v[7]],
            direction: [d_xy[0], d_xy[1], d[2]],
        };
        (ray, passes)
    }
}

impl LrtfTable {
    pub fn dims(&self) -> [usize; 3] {
        self.info.resolution
    }

    /// Stop radius that realises `f_number` (the stop scales as 1 / f-number, paraxially exact);
    /// None when it asks for more aperture than the table was baked with.
    pub fn stop_radius(&self, layer: usize, f_number: f64) -> Option<f64> {
        (f_number >= self.info.f_number * (1.0 - 1e-12))
            .then(|| self.layers[layer].stop_semi_aperture * self.info.f_number / f_number)
    }

    /// Where `ray` lands in layer `layer`'s coordinates.
    #[inline(always)]
    pub fn locate(&self, layer: usize, ray: &Ray) -> Option<Located> {
        let l = &self.layers[layer];
        self.info.parameterisation.locate(&l.frame, &l.pupil, ray)
    }

    /// The outgoing ray for a film-side ray travelling -z, with the lens focused at `focus_mm`
    /// (object distance in front of surface 1; None: the table's far focus, infinity unless it
    /// was baked for a finite distance) and stopped down to `f_number` (None: as baked). The
    /// first layer answers (the only one of a one-wavelength table); [`LrtfTable::focused`]
    /// checks the focus and the f-number once for many rays and picks other layers.
    ///
    /// ```
    /// use lensbake::{BakeRequest, LoadOptions, Lookup, Ray, bake, load_lens};
    ///
    /// let lens = load_lens("dgauss-50mm", &LoadOptions::default())?;
    /// let table = bake(&lens.system, &BakeRequest { resolution: [16; 3], ..Default::default() })?;
    /// let film_z = table.focused(None, None)?.film_z();
    /// // From the centre of the film straight towards the lens: out along the axis.
    /// let ray = Ray::new([0.0, 0.0, film_z], [0.0, 0.0, -1.0])?;
    /// let Lookup::Passes(out) = table.lookup(&ray, None, Some(4.0))? else { panic!() };
    /// assert!(out.direction[0].abs() < 1e-6 && out.direction[2] < -0.999_999);
    /// // Faster than the table was baked for: refused, not guessed.
    /// assert!(table.lookup(&ray, None, Some(0.5)).is_err());
    /// # Ok::<(), Box<dyn std::error::Error>>(())
    /// ```
    pub fn lookup(
        &self,
        ray: &crate::trace::Ray,
        focus_mm: Option<f64>,
        f_number: Option<f64>,
    ) -> Result<Lookup, LookupError> {
        Ok(self.focused(focus_mm, f_number)?.lookup(ray))
    }

    /// The first layer focused at `focus_mm` and stopped down to `f_number` (both as in
    /// [`LrtfTable::lookup`]), checked against what the table serves.
    pub fn focused(
        &self,
        focus_mm: Option<f64>,
        f_number: Option<f64>,
    ) -> Result<FocusedTable<'_>, LookupError> {
        let film_z = self
            .info
            .focus
            .film_z_for(focus_mm.or(self.info.focus.far_mm))?;
        let f_number = f_number.unwrap_or(self.info.f_number);
        if !f_number.is_finite() {
            return Err(LookupError::FNumber {
                asked: f_number,
                baked: self.info.f_number,
            });
        }
        let stop_radius = self.stop_radius(0, f_number).ok_or(LookupError::FNumber {
            asked: f_number,
            baked: self.info.f_number,
        })?;
        Ok(FocusedTable {
            table: self,
            layer: 0,
            film_z,
            stop_radius,
        })
    }

    /// The outgoing ray for a film-side ray travelling -z, through a stop of radius
    /// `stop_radius` (from [`LrtfTable::stop_radius`]). This is exactly what the shader does.
    pub fn lookup_layer(&self, layer: usize, ray: &Ray, stop_radius: f64) -> Lookup {
        self.lookup_from(layer, ray, stop_radius, Corners::All)
    }

    /// [`LrtfTable::lookup_layer`] of every ray in `rays` into `out` (same length), the same values
    /// as one at a time.
    pub fn lookup_group(&self, layer: usize, rays: &[Ray], stop_radius: f64, out: &mut [Lookup]) {
        assert_eq!(rays.len(), out.len(), "one lookup per ray");
        self.lookup_each(
            layer,
            LookupRays::Rays(rays),
            stop_radius,
            Corners::All,
            &mut LookupScratch::new(),
            &mut |k, found| out[k] = found,
        );
    }

    /// [`LrtfTable::lookup_group`] of the first `count` rays of a group held in columns
    /// (x, y, z, dx, dy, dz), as the renderer's CPU twin builds them: ray k's result is handed
    /// to `emit(k, ..)`, once for each k below `count`, in order. A direction need not be unit
    /// (a lookup reads only a ray's line and sense). `scratch` is worked in, and can be the
    /// same for every group.
    ///
    /// # Panics
    /// When `count` is above [`LOOKUP_GROUP`].
    #[cfg(feature = "render")]
    pub(crate) fn lookup_columns(
        &self,
        layer: usize,
        columns: &[[f64; LOOKUP_GROUP]; 6],
        count: usize,
        stop_radius: f64,
        scratch: &mut LookupScratch,
        mut emit: impl FnMut(usize, Lookup),
    ) {
        assert!(count <= LOOKUP_GROUP, "at most a group");
        self.lookup_each(
            layer,
            LookupRays::Columns { columns, count },
            stop_radius,
            Corners::All,
            scratch,
            &mut emit,
        );
    }

    /// [`LrtfTable::lookup_layer`] for a render focused on the film plane `film_z`: the table's domain
    /// on that plane ends at the film radius it was baked for, so a ray crossing the plane
    /// farther out is outside the domain (the transfer itself does not depend on the plane).
    pub fn lookup_focused(&self, layer: usize, ray: &Ray, stop_radius: f64, film_z: f64) -> Lookup {
        let t = (film_z - ray.origin[2]) / ray.direction[2];
        let film = [
            ray.origin[0] + t * ray.direction[0],
            ray.origin[1] + t * ray.direction[1],
        ];
        let reach = self.layers[layer].sampling.max_film_radius();
        // A ray that never crosses the plane (NaN) is outside too.
        let on_film = film[0].hypot(film[1]) <= reach * (1.0 + 1e-9);
        if !on_film {
            return Lookup::OutsideDomain;
        }
        self.lookup_layer(layer, ray, stop_radius)
    }

    /// [`LrtfTable::lookup_layer`] with the transfer values interpolated from `corners` (for
    /// measuring the alternative; the shader implements [`Corners::All`]).
    pub fn lookup_from(
        &self,
        layer: usize,
        ray: &Ray,
        stop_radius: f64,
        corners: Corners,
    ) -> Lookup {
        let mut found = Lookup::OutsideDomain;
        let rays = LookupRays::Rays(std::slice::from_ref(ray));
        let scratch = &mut LookupScratch::new();
        self.lookup_each(layer, rays, stop_radius, corners, scratch, &mut |_, f| {
            found = f
        });
        found
    }

    /// The one lookup: [`LOOKUP_GROUP`] rays at a time, each located (or settled outside the
    /// table) first, then the cells read and the outgoing rays decoded.
    fn lookup_each(
        &self,
        layer: usize,
        rays: LookupRays,
        stop_radius: f64,
        corners: Corners,
        scratch: &mut LookupScratch,
        emit: &mut impl FnMut(usize, Lookup),
    ) {
        let l = &self.layers[layer];
        // Each parameterisation's lanes compiled on their own, so the pupil-planes ones have
        // no call (acos, atan2) in the way of the vector instructions.
        match self.info.parameterisation {
            Parameterisation::PupilPlanes => LaneLookup {
                layer: l,
                stop_radius,
                corners,
                place: PupilPlanesPlace {
                    frame: &l.frame,
                    circles: l.pupil.interpolation(),
                },
            }
            .run(rays, scratch, emit),
            Parameterisation::Spherical => LaneLookup {
                layer: l,
                stop_radius,
                corners,
                place: SphericalPlace { layer: l },
            }
            .run(rays, scratch, emit),
        }
    }

    /// The uniform block `LrtfParams` of `lrtf_sample.wgsl` for one layer, stop radius and the
    /// film plane `film_z` lens samples are drawn for.
    pub fn gpu_params(&self, layer: usize, stop_radius: f64, film_z: f64) -> GpuParams {
        let l = &self.layers[layer];
        let [n0, n1, n2] = self.info.resolution;
        GpuParams {
            rear_plane_z: l.frame.rear_plane_z as f32,
            film_plane_z: l.frame.film_plane_z as f32,
            max_film_radius: l.frame.max_film_radius as f32,
            max_rear_radius: l.frame.max_rear_radius as f32,
            max_polar_angle: l.frame.max_polar_angle as f32,
            stop_radius_sq: (stop_radius * stop_radius) as f32,
            parameterisation: self.info.parameterisation.shader_id(),
            pupil_count: l.pupil.circles.len() as u32,
            dims: [n0 as u32, n1 as u32, n2 as u32],
            format_version: super::io::FORMAT_VERSION,
            sampling_max_film_radius: l.sampling.max_film_radius() as f32,
            sampling_count: l.sampling.nodes.first().map_or(0, |n| n.circles.len()) as u32,
            focus_count: l.sampling.nodes.len() as u32,
            focus_coordinate: l.sampling.focus_coordinate(film_z) as f32,
        }
    }

    /// The pupil buffer of `lrtf_sample.wgsl` for one layer: the coordinate pupil's circles,
    /// then the sampling pupil's, focus node by focus node, each as (centre_x, radius).
    pub fn gpu_pupil(&self, layer: usize) -> Vec<[f32; 2]> {
        let l = &self.layers[layer];
        std::iter::once(&l.pupil)
            .chain(&l.sampling.nodes)
            .flat_map(|table| &table.circles)
            .map(|c| [c.centre_x as f32, c.radius as f32])
            .collect()
    }

    /// Bytes of the entries as stored (both textures, all layers).
    pub fn entry_bytes(&self) -> usize {
        self.layers.iter().map(|l| l.entries.len()).sum::<usize>()
            * CHANNELS
            * self.info.precision.bytes()
    }

    /// The same table stored in `precision` (what a bake of the same request in that precision
    /// gives: the bake rounds every value to f32, then to the precision).
    pub fn to_precision(&self, precision: Precision) -> LrtfTable {
        LrtfTable {
            info: TableInfo {
                precision,
                ..self.info.clone()
            },
            layers: self
                .layers
                .iter()
                .map(|l| Layer {
                    wavelength_nm: l.wavelength_nm,
                    frame: l.frame.clone(),
                    pupil: l.pupil.clone(),
                    sampling: l.sampling.clone(),
                    stop_semi_aperture: l.stop_semi_aperture,
                    entries: l.entries.to_precision(precision),
                })
                .collect(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fetch_reproduces_a_trilinear_function_exactly() {
        // A function that is linear in each coordinate is reproduced to rounding by trilinear
        // interpolation: this pins down the index layout and the weights.
        let dims = [4, 3, 5];
        let f = |c: [f64; 3]| 1.0 + 2.0 * c[0] - 3.0 * c[1] + 0.5 * c[2] + c[0] * c[1] * c[2];
        let mut entries = Vec::new();
        for i2 in 0..dims[2] {
            for i1 in 0..dims[1] {
                for i0 in 0..dims[0] {
                    let c = [i0 as f64 / 3.0, i1 as f64 / 2.0, i2 as f64 / 4.0];
                    let mut e = [0.0f32; CHANNELS];
                    e[0] = f(c) as f32;
                    entries.push(e);
                }
            }
        }
        let pupil = PupilTable {
            max_film_radius: 1.0,
            circles: vec![crate::pupil::PupilCircle {
                centre_x: 0.0,
                radius: 1.0,
            }],
        };
        let layer = Layer {
            wavelength_nm: 587.56,
            frame: Frame {
                rear_plane_z: 0.0,
                film_plane_z: 1.0,
                max_film_radius: 1.0,
                max_rear_radius: 1.0,
                max_polar_angle: 1.0,
            },
            pupil: pupil.clone(),
            sampling: FocusPupilTable::single(1.0, pupil),
            stop_semi_aperture: 1.0,
            entries: Entries::from_row_major(dims, Precision::F32, &entries),
        };
        for c in [[0.1, 0.7, 0.33], [0.99, 0.01, 0.5], [0.5, 0.5, 1.0]] {
            assert!((layer.fetch(c)[0] - f(c)).abs() < 1e-5);
        }
    }
}
