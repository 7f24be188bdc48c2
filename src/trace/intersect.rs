//! Where a ray meets a surface.
//!
//! Every function works in the surface's vertex frame (vertex at the origin, axis along z) and
//! takes a unit direction `d` and the travel sense `sense` (+1 forward, -1 backward).
//!
//! # Which root
//!
//! A sphere or conic `c (x^2 + y^2 + e z^2) - 2 z = 0` (e = 1 + k) meets a line twice. Its
//! gradient over two, `N = (c x, c y, c e z - 1)`, points towards -z (the object side) everywhere
//! on the sheet that contains the vertex (there `c e z < 1`) and towards +z on the far sheet.
//! The sequential model wants the crossing of the vertex sheet in the travel sense: from the
//! object side to the image side going forward (`N . d <= 0`), the other way going backward.
//! Writing the line as `p + t d` gives `a t^2 - 2 B t + C = 0` with `N . d = a t - B` at a root,
//! so the two roots carry `N . d = +-sqrt(B^2 - a C)` and the wanted one is the root with
//! `N . d = -sense * sqrt(B^2 - a C)`, i.e. `t = (B - sense sqrt(D)) / a = C / (B + sense sqrt(D))`.
//! We evaluate whichever of the two forms adds numbers of the same sign (no cancellation); the
//! second form stays finite as the curvature, or `a` itself (k = -1 with an axial ray), goes to
//! zero and then reduces to the plane or to the linear equation. A hit that lands on the far
//! sheet counts as a miss: that point is outside the surface the prescription describes.
//!
//! The line is extended both ways, as in every sequential design program: a ray that starts
//! just behind a vertex (a cemented pair with zero gap, a start plane chosen inside a deep
//! front curve) still meets the surface it is meant to meet. So every solver may, and does,
//! first move the start point along the line to the point nearest the vertex: from a distant
//! start the quadratic's coefficients grow as the squared distance and cancel to garbage (a
//! grazing ray that had flown 5e10 mm met a sphere it misses by as much).

use super::Vec3;

/// Surface profile in the vertex frame, with the numbers the hot loop needs precomputed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Profile {
    Plane,
    Sphere {
        curvature: f64,
    },
    Conic {
        curvature: f64,
        /// 1 + k.
        conic_factor: f64,
    },
    Asphere {
        curvature: f64,
        conic_factor: f64,
        /// Index into the tracer's table of aspheric coefficient sets.
        terms: usize,
    },
    /// A plane that deflects rays as an ideal thin lens of this power (1/mm) does
    /// ([`crate::prescription::Shape::IdealLens`]).
    IdealLens {
        power: f64,
    },
}

/// An asphere's polynomial: `coefficients[i] * (r^2)^(i + 1)` (even) or `coefficients[i] *
/// r^(i + 1)` (odd), padded with zeros.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct AsphereTerms {
    pub coefficients: [f64; crate::prescription::MAX_ASPHERE_TERMS],
    pub len: usize,
    /// Whether the terms are in powers of r rather than r^2 (an odd asphere).
    pub odd: bool,
    /// Largest radial height the Newton search may wander to (the clear aperture, doubled).
    pub search_radius: f64,
}

impl Profile {
    /// The power (1/mm) of an ideal lens; None for every other profile.
    #[inline(always)]
    pub(crate) fn ideal_power(&self) -> Option<f64> {
        match *self {
            Profile::IdealLens { power } => Some(power),
            _ => None,
        }
    }
}

impl AsphereTerms {
    /// The terms of `shape` (none for a shape without them), each at most
    /// [`crate::prescription::MAX_ASPHERE_TERMS`].
    pub(crate) fn of(shape: &crate::prescription::Shape, search_radius: f64) -> AsphereTerms {
        let coefficients = shape.aspheric_coefficients();
        let mut terms = AsphereTerms {
            coefficients: [0.0; crate::prescription::MAX_ASPHERE_TERMS],
            len: coefficients.len(),
            odd: matches!(shape, crate::prescription::Shape::OddAsphere { .. }),
            search_radius,
        };
        terms.coefficients[..coefficients.len()].copy_from_slice(coefficients);
        terms
    }
}

/// A surface crossing: the point in the vertex frame and the unit surface normal pointing to the
/// object side (negative z component).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Hit {
    pub point: Vec3,
    pub normal: Vec3,
}

/// Most Newton steps an asphere intersection may take before it is declared missed.
pub(crate) const ASPHERE_MAX_STEPS: usize = 40;
/// The asphere search stops when the sag residual is below this times (1 + search radius), or
/// when a step moves the ray parameter t by less than [`ASPHERE_STEP_TOLERANCE`] (1 + |t|): a
/// few f64 ulps of the quantities involved.
const ASPHERE_SAG_TOLERANCE: f64 = 1e-15;
const ASPHERE_STEP_TOLERANCE: f64 = 1e-14;

/// Meets a plane z = 0: only when the ray crosses it in the travel sense.
#[inline(always)]
pub(crate) fn plane(p: Vec3, d: Vec3, sense: f64) -> Option<Vec3> {
    let (q, crosses) = plane_candidate(p, d, sense);
    crosses.then_some(q)
}

/// [`plane`] without branches, for the lane kernels: the point, and whether it is a crossing.
#[inline(always)]
pub(crate) fn plane_candidate(p: Vec3, d: Vec3, sense: f64) -> (Vec3, bool) {
    let t = -p[2] / d[2];
    (
        [t.mul_add(d[0], p[0]), t.mul_add(d[1], p[1]), 0.0],
        d[2] * sense > 0.0,
    )
}

/// The wanted root of `a t^2 - 2 B t + C = 0` (see the module notes) without branches: the root
/// (meaningless when the line misses) and whether the discriminant is non-negative. One
/// division whichever form is taken, so a vector of lanes divides once.
#[inline(always)]
fn root_candidate(a: f64, b: f64, c: f64, sense: f64) -> (f64, bool) {
    let disc = discriminant(a, b, c);
    (root_from(a, b, c, disc, sense), disc >= 0.0)
}

/// The discriminant `B^2 - a C` of `a t^2 - 2 B t + C = 0`.
#[inline(always)]
fn discriminant(a: f64, b: f64, c: f64) -> f64 {
    b.mul_add(b, -(a * c))
}

/// The wanted root given the [`discriminant`] (meaningless when it is negative): one square
/// root and one division, the form that does not cancel.
#[inline(always)]
pub(crate) fn root_from(a: f64, b: f64, c: f64, disc: f64, sense: f64) -> f64 {
    root_given(a, b, c, clamped_sqrt(disc), sense)
}

/// The square root of `v`, or 0 where rounding made `v` negative.
#[inline(always)]
pub(crate) fn clamped_sqrt(v: f64) -> f64 {
    v.max(0.0).sqrt()
}

/// [`root_from`] given the [`clamped_sqrt`] of the discriminant.
#[inline(always)]
pub(crate) fn root_given(a: f64, b: f64, c: f64, root: f64, sense: f64) -> f64 {
    let near = sense * b >= 0.0;
    // Chosen by selects, not a branch: as a branch (which the compiler made of plain `if`s
    // here) the block kernels' stride loops stayed scalar.
    let numerator = std::hint::select_unpredictable(near, c, b - sense * root);
    let denominator = std::hint::select_unpredictable(near, b + sense * root, a);
    numerator / denominator
}

/// The point of the line `p + t d` (d unit) nearest the vertex.
#[inline(always)]
fn nearest_to_vertex(p: Vec3, d: Vec3) -> Vec3 {
    along(p, d, -dot(p, d))
}

/// The point `p + t d`, each component with one rounding.
#[inline(always)]
fn along(p: Vec3, d: Vec3, t: f64) -> Vec3 {
    [
        t.mul_add(d[0], p[0]),
        t.mul_add(d[1], p[1]),
        t.mul_add(d[2], p[2]),
    ]
}

/// The dot product as every path of the tracer rounds it (two fused multiply-adds).
#[inline(always)]
pub(crate) fn dot(a: Vec3, b: Vec3) -> f64 {
    a[2].mul_add(b[2], a[1].mul_add(b[1], a[0] * b[0]))
}

/// The cross product a x b, each component one fused multiply-add.
#[inline(always)]
pub(crate) fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [
        a[1].mul_add(b[2], -(a[2] * b[1])),
        a[2].mul_add(b[0], -(a[0] * b[2])),
        a[0].mul_add(b[1], -(a[1] * b[0])),
    ]
}

/// Squared distance of a hit point from the axis, as every path of the tracer rounds it.
#[inline(always)]
pub(crate) fn radius_sq(q: Vec3) -> f64 {
    q[0].mul_add(q[0], q[1] * q[1])
}

/// Meets the sphere `c (x^2 + y^2 + z^2) - 2 z = 0` on its vertex sheet. The normal
/// `(c x, c y, c z - 1)` has unit length on the sphere, so it needs no normalisation.
#[inline(always)]
pub(crate) fn sphere(p: Vec3, d: Vec3, curvature: f64, sense: f64) -> Option<Hit> {
    let (point, nz, hit) = sphere_candidate(p, d, curvature, sense);
    hit.then_some(Hit {
        point,
        normal: [curvature * point[0], curvature * point[1], nz],
    })
}

/// [`sphere`] without branches, for the lane kernels: the point, the normal's z component and
/// whether it is a crossing of the vertex sheet (the point may still be too far out to be
/// finite).
#[inline(always)]
pub(crate) fn sphere_candidate(p: Vec3, d: Vec3, curvature: f64, sense: f64) -> (Vec3, f64, bool) {
    let quadratic = SphereQuadratic::new(p, d, curvature);
    let t = root_from(curvature, quadratic.b, quadratic.c, quadratic.disc, sense);
    sphere_meet(quadratic.start, quadratic.disc, d, curvature, t)
}

/// The first of [`sphere_candidate`]'s three stages ([`SphereQuadratic::new`], [`root_from`],
/// [`sphere_meet`]: multiply-adds, then the square root and division, then multiply-adds), kept
/// apart so that the lane kernels can run each over a whole block before the next: the rays'
/// chains of dependent operations are then short and many overlap.
#[derive(Clone, Copy)]
pub(crate) struct SphereQuadratic {
    /// The start point: the point of the ray nearest the vertex (relative to it).
    pub start: Vec3,
    /// `B` and `C` of the quadratic in the distance from `start`, and its discriminant.
    pub b: f64,
    pub c: f64,
    pub disc: f64,
}

impl SphereQuadratic {
    /// The quadratic of the ray from `p` (relative to the vertex) along `d`.
    #[inline(always)]
    pub fn new(p: Vec3, d: Vec3, curvature: f64) -> SphereQuadratic {
        let p = nearest_to_vertex(p, d);
        let c = curvature;
        let b = (-c).mul_add(dot(p, d), d[2]);
        let cc = c.mul_add(dot(p, p), -2.0 * p[2]);
        SphereQuadratic {
            start: p,
            b,
            c: cc,
            disc: discriminant(c, b, cc),
        }
    }
}

/// The last stage of [`sphere_candidate`]: the point at distance `t` (from [`root_from`]) along
/// `d` from the quadratic's start point, the normal's z there, and whether it is a crossing of
/// the vertex sheet.
#[inline(always)]
pub(crate) fn sphere_meet(
    start: Vec3,
    disc: f64,
    d: Vec3,
    curvature: f64,
    t: f64,
) -> (Vec3, f64, bool) {
    let q = along(start, d, t);
    let nz = curvature.mul_add(q[2], -1.0);
    (q, nz, (disc >= 0.0) & t.is_finite() & (nz < 0.0))
}

/// Meets the conic `c (x^2 + y^2 + e z^2) - 2 z = 0` (e = 1 + k) on its vertex sheet.
#[inline(always)]
pub(crate) fn conic(
    p: Vec3,
    d: Vec3,
    curvature: f64,
    conic_factor: f64,
    sense: f64,
) -> Option<Hit> {
    let (q, crosses) = conic_candidate(p, d, curvature, conic_factor, sense);
    crosses.then(|| Hit {
        point: q,
        normal: conic_normal(q, curvature, conic_factor),
    })
}

/// The unit normal of the conic at its point `q`, pointing to the object side.
#[inline(always)]
pub(crate) fn conic_normal(q: Vec3, curvature: f64, conic_factor: f64) -> Vec3 {
    let nz = (curvature * conic_factor).mul_add(q[2], -1.0);
    normalised([curvature * q[0], curvature * q[1], nz])
}

/// [`conic`] without branches, for the lane kernels: the point, and whether it is a crossing of
/// the vertex sheet.
#[inline(always)]
pub(crate) fn conic_candidate(
    p: Vec3,
    d: Vec3,
    curvature: f64,
    conic_factor: f64,
    sense: f64,
) -> (Vec3, bool) {
    let p = nearest_to_vertex(p, d);
    let (c, e) = (curvature, conic_factor);
    let a = c * dot(d, [d[0], d[1], e * d[2]]);
    let b = (-c).mul_add(dot(p, [d[0], d[1], e * d[2]]), d[2]);
    let cc = c.mul_add(dot(p, [p[0], p[1], e * p[2]]), -2.0 * p[2]);
    let (t, real) = root_candidate(a, b, cc, sense);
    let q = along(p, d, t);
    let nz = (c * e).mul_add(q[2], -1.0);
    (q, real & t.is_finite() & (nz < 0.0))
}

/// Sag of the conic base and of the whole asphere, and d(sag)/d(r^2), at `rho = r^2`; None
/// beyond the rim of the conic base.
#[inline(always)]
pub(crate) fn asphere_sag(
    rho: f64,
    curvature: f64,
    conic_factor: f64,
    terms: &AsphereTerms,
) -> Option<(f64, f64)> {
    let (sag, slope, exists) = conic_base(rho, curvature, conic_factor);
    if !exists {
        return None;
    }
    let x = polynomial_variable(terms.odd, rho);
    let (poly, dpoly) = horner(terms, x);
    let (poly_sag, poly_slope) =
        polynomial_part(terms.odd, terms.coefficients[1], rho, x, poly, dpoly);
    Some((sag + poly_sag, slope + poly_slope))
}

/// The conic base's sag and d(sag)/d(r^2) at `rho = r^2`, and whether the base reaches that far
/// (the numbers are meaningless where it does not).
#[inline(always)]
fn conic_base(rho: f64, curvature: f64, conic_factor: f64) -> (f64, f64, bool) {
    let c = curvature;
    let under = 1.0 - conic_factor * c * c * rho;
    let root = under.sqrt();
    (c * rho / (1.0 + root), 0.5 * c / root, under > 0.0)
}

/// The variable [`horner`] runs over: r for an odd asphere, r^2 for an even one.
#[inline(always)]
fn polynomial_variable(odd: bool, rho: f64) -> f64 {
    if odd { rho.sqrt() } else { rho }
}

/// The polynomial's sag and d(sag)/d(r^2) at `rho = r^2` from [`horner`]'s `poly` and `dpoly`
/// over `x` ([`polynomial_variable`]). For an odd asphere d/d(r^2) = d/dr / (2 r), whose limit on
/// the axis is the r^2 coefficient `a1` (zero-padded when there is none; an r term's cone has a
/// slope there, but no direction: the gradient takes slope times (x, y), which vanishes).
#[inline(always)]
fn polynomial_part(odd: bool, a1: f64, rho: f64, x: f64, poly: f64, dpoly: f64) -> (f64, f64) {
    if odd {
        let slope = std::hint::select_unpredictable(x > 0.0, dpoly / (2.0 * x), a1);
        (poly * x, slope)
    } else {
        (poly * rho, dpoly)
    }
}

/// `sum a_i x^i` and `sum (i + 1) a_i x^i` over the coefficients a_i of `terms`, by Horner's
/// rule: the polynomial over x (to be multiplied by x) and its derivative.
#[inline(always)]
fn horner(terms: &AsphereTerms, x: f64) -> (f64, f64) {
    let mut poly = 0.0;
    let mut dpoly = 0.0;
    for i in (0..terms.len).rev() {
        let a = terms.coefficients[i];
        poly = poly * x + a;
        dpoly = dpoly * x + (i + 1) as f64 * a;
    }
    (poly, dpoly)
}

/// An asphere's Newton residual at the point `q` of a line along `d`, from the sag and its
/// slope there: g (the sag minus q's z: positive while q is on the object side), the gradient
/// of the implicit form and dg/dt.
#[inline(always)]
fn asphere_residual(q: Vec3, d: Vec3, sag: f64, slope: f64) -> (f64, Vec3, f64) {
    let g = sag - q[2];
    let gradient = [2.0 * slope * q[0], 2.0 * slope * q[1], -1.0];
    let dg = 2.0 * slope * (q[0] * d[0] + q[1] * d[1]) - d[2];
    (g, gradient, dg)
}

/// Meets an asphere by Newton's method on the ray parameter, started at the crossing of
/// its conic base (or of the vertex plane when the base is missed). Newton steps are limited to
/// the size of the search region, and once two iterates straddle the surface every step stays
/// inside that bracket (a step that would leave it bisects instead). No convergence within
/// [`ASPHERE_MAX_STEPS`], or a crossing in the wrong sense, is a miss.
///
/// Inlined, as the conic and the Newton search are, into the traces compiled for an instruction
/// set: as functions of their own they were compiled for the baseline set, where every
/// `mul_add` is a library call.
#[inline(always)]
pub(crate) fn asphere(
    p: Vec3,
    d: Vec3,
    curvature: f64,
    conic_factor: f64,
    terms: &AsphereTerms,
    sense: f64,
) -> Option<Hit> {
    let (p, start, starts) = asphere_start(p, d, curvature, conic_factor, sense);
    if !starts {
        return None;
    }
    let max_rho = terms.search_radius * terms.search_radius;
    let search = NewtonSearch::from(p, d, start);
    newton_crossing(p, d, search, terms.search_radius, sense, |q| {
        let rho = q[0] * q[0] + q[1] * q[1];
        let (sag, slope) = (rho <= max_rho)
            .then(|| asphere_sag(rho, curvature, conic_factor, terms))
            .flatten()?;
        Some(asphere_residual(q, d, sag, slope))
    })
}

/// Where an asphere's Newton search starts: the point of the line nearest the vertex, the
/// crossing of the conic base (or of the vertex plane when the base is missed), and whether the
/// line meets either in the travel sense.
#[inline(always)]
fn asphere_start(
    p: Vec3,
    d: Vec3,
    curvature: f64,
    conic_factor: f64,
    sense: f64,
) -> (Vec3, Vec3, bool) {
    let p = nearest_to_vertex(p, d);
    let (on_conic, meets_conic) = conic_candidate(p, d, curvature, conic_factor, sense);
    let (on_plane, meets_plane) = plane_candidate(p, d, sense);
    let start = std::hint::select_unpredictable(meets_conic, on_conic, on_plane);
    (p, start, meets_conic | meets_plane)
}

/// Rays whose Newton searches [`AsphereLanes::meet`] runs side by side.
pub(crate) const NEWTON_LANES: usize = 16;

/// A group of [`NEWTON_LANES`] values, one per lane.
pub(crate) type Lanes<T> = [T; NEWTON_LANES];

/// Lines in vector lanes: the columns x, y, z of a point on each and of its direction (unit),
/// in a surface's vertex frame.
pub(crate) struct LaneLines {
    pub p: [Lanes<f64>; 3],
    pub d: [Lanes<f64>; 3],
}

/// Where lines in vector lanes meet a surface: whether each does, and the points and unit
/// normals where it does.
#[derive(Default)]
pub(crate) struct LaneHits {
    pub met: Lanes<bool>,
    pub points: [Lanes<f64>; 3],
    pub normals: [Lanes<f64>; 3],
}

/// An asphere as its lane search ([`AsphereLanes::meet`]) reads it: the profile, and the sense
/// the rays travel in.
#[derive(Clone, Copy)]
pub(crate) struct AsphereLanes<'a> {
    pub curvature: f64,
    pub conic_factor: f64,
    pub terms: &'a AsphereTerms,
    pub sense: f64,
}

impl AsphereLanes<'_> {
    /// [`asphere`] of the lines in vector lanes into `hits`: whether each meets the surface, and
    /// the points and normals where it does (kept from before where it does not). Every
    /// lane takes Newton steps until every lane has converged or failed (a settled lane keeps
    /// its result), each stage over all lanes before the next, with no branch on a lane's
    /// numbers; each lane's arithmetic is [`asphere`]'s, so the results are the same bits.
    #[inline(always)]
    pub(crate) fn meet(&self, lines: &LaneLines, hits: &mut LaneHits) {
        // The odd and even polynomials compiled apart, so that neither lane loop holds the
        // other's square root and division.
        if self.terms.odd {
            self.meet_as::<true>(lines, hits)
        } else {
            self.meet_as::<false>(lines, hits)
        }
    }

    /// [`AsphereLanes::meet`] for an odd (`ODD`) or even asphere.
    #[inline(always)]
    fn meet_as<const ODD: bool>(&self, lines: &LaneLines, hits: &mut LaneHits) {
        const L: usize = NEWTON_LANES;
        let LaneLines { p, d } = lines;
        let AsphereLanes {
            curvature,
            conic_factor,
            terms,
            sense,
        } = *self;
        let direction = |l: usize| [d[0][l], d[1][l], d[2][l]];
        // The searches, a column per number (see `NewtonSearch`).
        let mut nearest = [[0.0; L]; 3];
        let [mut t, mut t_object, mut t_image, mut last_inside] = [[0.0; L]; 4];
        let mut progress = [NEWTON_FAILED; L];
        for l in 0..L {
            let arriving = [p[0][l], p[1][l], p[2][l]];
            let (near, start, starts) =
                asphere_start(arriving, direction(l), curvature, conic_factor, sense);
            let search = NewtonSearch::from(near, direction(l), start);
            for axis in 0..3 {
                nearest[axis][l] = near[axis];
            }
            [t[l], t_object[l], t_image[l], last_inside[l]] = search.columns();
            progress[l] = std::hint::select_unpredictable(starts, NEWTON_SEARCHING, NEWTON_FAILED);
        }
        let max_rho = terms.search_radius * terms.search_radius;
        let mut gradients = [[0.0; L]; 2];
        for _ in 0..ASPHERE_MAX_STEPS {
            if !progress.contains(&NEWTON_SEARCHING) {
                break;
            }
            let mut q = [[0.0; L]; 3];
            let [mut rho, mut x, mut base_sag, mut base_slope] = [[0.0; L]; 4];
            let mut exists = [0u64; L];
            for l in 0..L {
                let near = [nearest[0][l], nearest[1][l], nearest[2][l]];
                let at = newton_point(near, direction(l), t[l]);
                for axis in 0..3 {
                    q[axis][l] = at[axis];
                }
                rho[l] = at[0] * at[0] + at[1] * at[1];
                let (sag, slope, reaches) = conic_base(rho[l], curvature, conic_factor);
                (base_sag[l], base_slope[l]) = (sag, slope);
                exists[l] = u64::from(reaches & (rho[l] <= max_rho));
                x[l] = polynomial_variable(ODD, rho[l]);
            }
            let mut poly = [0.0; L];
            let mut dpoly = [0.0; L];
            for i in (0..terms.len).rev() {
                let a = terms.coefficients[i];
                for l in 0..L {
                    poly[l] = poly[l] * x[l] + a;
                    dpoly[l] = dpoly[l] * x[l] + (i + 1) as f64 * a;
                }
            }
            for l in 0..L {
                let at = [q[0][l], q[1][l], q[2][l]];
                let (poly_sag, poly_slope) =
                    polynomial_part(ODD, terms.coefficients[1], rho[l], x[l], poly[l], dpoly[l]);
                let (g, gradient, dg) = asphere_residual(
                    at,
                    direction(l),
                    base_sag[l] + poly_sag,
                    base_slope[l] + poly_slope,
                );
                let search = NewtonSearch::of([t[l], t_object[l], t_image[l], last_inside[l]]);
                let (next, step) = search.advance(exists[l] == 1, g, dg, terms.search_radius);
                let searching = progress[l] == NEWTON_SEARCHING;
                let met = searching & (step == NEWTON_MET);
                let next = next.columns();
                for (column, value) in [&mut t, &mut t_object, &mut t_image, &mut last_inside]
                    .into_iter()
                    .zip(next)
                {
                    column[l] = std::hint::select_unpredictable(searching, value, column[l]);
                }
                progress[l] = std::hint::select_unpredictable(searching, step, progress[l]);
                for (column, value) in hits.points.iter_mut().zip(at) {
                    column[l] = std::hint::select_unpredictable(met, value, column[l]);
                }
                for axis in 0..2 {
                    gradients[axis][l] =
                        std::hint::select_unpredictable(met, gradient[axis], gradients[axis][l]);
                }
            }
        }
        for l in 0..L {
            let gradient = [gradients[0][l], gradients[1][l], -1.0];
            let (normal, crosses) = finish_candidate(gradient, direction(l), sense);
            for (column, value) in hits.normals.iter_mut().zip(normal) {
                column[l] = value;
            }
            hits.met[l] = crosses & (progress[l] == NEWTON_MET);
        }
    }
}

/// Meets a toroid: the y-z curve z(y) of `curvature`, `conic_factor` and `terms` (coefficients
/// on y^2, y^4, ...) turned about the line parallel to y through (0, 0, `rotation_radius`); an
/// infinite radius gives a cylinder, z(x, y) = z(y). With w = R - z(y) the surface is
/// z = R - sign(w) sqrt(w^2 - x^2), whose slopes are sign(w) x / s and |w| z'(y) / s for
/// s = sqrt(w^2 - x^2). Newton's method as for [`asphere`], from the vertex plane's
/// crossing; outside the search region or where the surface does not exist is a miss.
pub(crate) fn toroid(
    p: Vec3,
    d: Vec3,
    curvature: f64,
    conic_factor: f64,
    terms: &AsphereTerms,
    rotation_radius: f64,
    sense: f64,
) -> Option<Hit> {
    let p = nearest_to_vertex(p, d);
    let start = plane(p, d, sense)?;
    let reach = terms.search_radius;
    let search = NewtonSearch::from(p, d, start);
    newton_crossing(p, d, search, reach, sense, |q| {
        if !(q[0].abs() <= reach && q[1].abs() <= reach) {
            return None;
        }
        let (profile, slope) = asphere_sag(q[1] * q[1], curvature, conic_factor, terms)?;
        let profile_slope = 2.0 * slope * q[1];
        let (z, dz_dx, dz_dy) = if rotation_radius.is_infinite() {
            (profile, 0.0, profile_slope)
        } else {
            let w = rotation_radius - profile;
            let under = w * w - q[0] * q[0];
            if !(under > 0.0) {
                return None;
            }
            let s = under.sqrt();
            (
                rotation_radius - s.copysign(w),
                q[0] / s * w.signum(),
                w.abs() * profile_slope / s,
            )
        };
        let g = z - q[2];
        let dg = dz_dx * d[0] + dz_dy * d[1] - d[2];
        Some((g, [dz_dx, dz_dy, -1.0], dg))
    })
}

/// Newton's method on the ray parameter for the crossing of `p + t d` with a surface, from
/// `search`. `surface(q)` gives, at a point q of the line, g (the surface's z there minus q's z:
/// positive on the object side), the gradient of the surface's implicit form (z component -1)
/// and dg/dt; None outside the region where the surface exists.
#[inline(always)]
fn newton_crossing(
    p: Vec3,
    d: Vec3,
    mut search: NewtonSearch,
    search_radius: f64,
    sense: f64,
    surface: impl Fn(Vec3) -> Option<(f64, Vec3, f64)>,
) -> Option<Hit> {
    for _ in 0..ASPHERE_MAX_STEPS {
        let q = search.point(p, d);
        let found = surface(q);
        let (g, gradient, dg) = found.unwrap_or((f64::NAN, [f64::NAN; 3], f64::NAN));
        let (next, progress) = search.advance(found.is_some(), g, dg, search_radius);
        match progress {
            NEWTON_SEARCHING => search = next,
            NEWTON_MET => return finish_asphere(q, gradient, d, sense),
            _ => return None,
        }
    }
    None
}

/// The point at `t` on the line `p + t d` as the Newton search rounds it (a multiply and an add
/// per axis, not [`along`]'s fused multiply-add: the search's iterates keep the bits they had
/// before it ran in lanes).
#[inline(always)]
fn newton_point(p: Vec3, d: Vec3, t: f64) -> Vec3 {
    [p[0] + t * d[0], p[1] + t * d[1], p[2] + t * d[2]]
}

/// What a Newton step came to: still searching, converged (the point is on the surface), or
/// failed (the search has nowhere left to go). 64-bit, to share vector lanes with the f64
/// comparisons they come from.
const NEWTON_SEARCHING: u64 = 0;
const NEWTON_MET: u64 = 1;
const NEWTON_FAILED: u64 = 2;

/// Where one ray's Newton search stands: the ray parameter t of its iterate; the ray parameters
/// known to lie on the object side (g > 0) and on the image side (g < 0) of the surface, NaN
/// until found (once both are known they bracket the crossing); and the last iterate inside the
/// region where the surface exists, NaN until there is one.
#[derive(Clone, Copy, Debug)]
struct NewtonSearch {
    t: f64,
    t_object: f64,
    t_image: f64,
    last_inside: f64,
}

impl NewtonSearch {
    /// A search of the line `p + t d` that starts at its point `start`.
    #[inline(always)]
    fn from(p: Vec3, d: Vec3, start: Vec3) -> NewtonSearch {
        NewtonSearch {
            t: (start[0] - p[0]) * d[0] + (start[1] - p[1]) * d[1] + (start[2] - p[2]) * d[2],
            t_object: f64::NAN,
            t_image: f64::NAN,
            last_inside: f64::NAN,
        }
    }

    /// A search whose numbers are `columns` (t, t_object, t_image, last_inside).
    #[inline(always)]
    fn of(columns: [f64; 4]) -> NewtonSearch {
        let [t, t_object, t_image, last_inside] = columns;
        NewtonSearch {
            t,
            t_object,
            t_image,
            last_inside,
        }
    }

    /// The numbers of the search, as [`NewtonSearch::of`] takes them.
    #[inline(always)]
    fn columns(&self) -> [f64; 4] {
        [self.t, self.t_object, self.t_image, self.last_inside]
    }

    /// The iterate: the point at t on the line `p + t d` ([`newton_point`]).
    #[inline(always)]
    fn point(&self, p: Vec3, d: Vec3) -> Vec3 {
        newton_point(p, d, self.t)
    }

    /// One Newton step from the residual `g` and its derivative `dg` at the iterate (`valid`:
    /// whether the surface exists there), without branches: the search after it, and what it
    /// came to. Outside the surface's region the search falls back towards known ground (the
    /// bracket's middle, or halfway to the last iterate inside); steps are limited to
    /// `search_radius`; once two iterates straddle the surface a step that would leave that
    /// bracket bisects instead. It converges when the residual is below
    /// [`ASPHERE_SAG_TOLERANCE`] (1 + `search_radius`) or a step moves t by less than
    /// [`ASPHERE_STEP_TOLERANCE`] (1 + |t|).
    #[inline(always)]
    fn advance(&self, valid: bool, g: f64, dg: f64, search_radius: f64) -> (NewtonSearch, u64) {
        use std::hint::select_unpredictable as select;
        let t = self.t;
        let was_bracketed = self.t_object.is_finite() & self.t_image.is_finite();
        let fallback = NewtonSearch {
            t: select(
                was_bracketed,
                0.5 * (self.t_object + self.t_image),
                0.5 * (t + self.last_inside),
            ),
            ..*self
        };
        let can_fall_back = was_bracketed | self.last_inside.is_finite();
        let object_side = g > 0.0;
        let t_object = select(object_side, t, self.t_object);
        let t_image = select(object_side, self.t_image, t);
        let step = -g / dg;
        let mut next = t + step.clamp(-search_radius, search_radius);
        let (lo, hi) = (t_object.min(t_image), t_object.max(t_image));
        let bracketed = t_object.is_finite() & t_image.is_finite();
        next = select(
            bracketed & !((next > lo) & (next < hi)),
            0.5 * (lo + hi),
            next,
        );
        let stepped = NewtonSearch {
            t: next,
            t_object,
            t_image,
            last_inside: t,
        };
        let settled = g.abs() <= ASPHERE_SAG_TOLERANCE * (1.0 + search_radius);
        let still = (next - t).abs() <= ASPHERE_STEP_TOLERANCE * (1.0 + t.abs());
        let inside_progress = select(
            settled,
            NEWTON_MET,
            select(
                step.is_nan(),
                NEWTON_FAILED,
                select(still, NEWTON_MET, NEWTON_SEARCHING),
            ),
        );
        let outside_progress = select(can_fall_back, NEWTON_SEARCHING, NEWTON_FAILED);
        let (stepped, fallback) = (stepped.columns(), fallback.columns());
        (
            NewtonSearch::of(std::array::from_fn(|k| {
                select(valid, stepped[k], fallback[k])
            })),
            select(valid, inside_progress, outside_progress),
        )
    }
}

/// Accepts an asphere crossing only in the travel sense (object side to image side forward).
#[inline(always)]
fn finish_asphere(q: Vec3, gradient: Vec3, d: Vec3, sense: f64) -> Option<Hit> {
    let (normal, crosses) = finish_candidate(gradient, d, sense);
    crosses.then_some(Hit { point: q, normal })
}

/// [`finish_asphere`] without branches: the unit normal along `gradient`, and whether a ray
/// along `d` crosses there in the travel sense.
#[inline(always)]
fn finish_candidate(gradient: Vec3, d: Vec3, sense: f64) -> (Vec3, bool) {
    let normal = normalised(gradient);
    (normal, sense * dot(normal, d) < 0.0)
}

#[inline(always)]
pub(crate) fn normalised(v: Vec3) -> Vec3 {
    let inv = 1.0 / dot(v, v).sqrt();
    [v[0] * inv, v[1] * inv, v[2] * inv]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(v: Vec3) -> Vec3 {
        normalised(v)
    }

    fn on_conic(q: Vec3, c: f64, e: f64) -> f64 {
        c * (q[0] * q[0] + q[1] * q[1] + e * q[2] * q[2]) - 2.0 * q[2]
    }

    #[test]
    fn axial_ray_meets_sphere_at_vertex_both_ways() {
        for c in [0.05, -0.05] {
            let hit = sphere([0.0, 0.0, -5.0], [0.0, 0.0, 1.0], c, 1.0).unwrap();
            assert_eq!(hit.point, [0.0, 0.0, 0.0]);
            assert_eq!(hit.normal, [0.0, 0.0, -1.0]);
            let hit = sphere([0.0, 0.0, 5.0], [0.0, 0.0, -1.0], c, -1.0).unwrap();
            assert_eq!(hit.point, [0.0, 0.0, 0.0]);
        }
    }

    #[test]
    fn sphere_hit_is_on_vertex_sheet_at_expected_height() {
        // Axis-parallel ray at height h meets the sphere at sag R - sqrt(R^2 - h^2).
        let (radius, h) = (20.0, 12.0);
        let hit = sphere([0.0, h, -3.0], [0.0, 0.0, 1.0], 1.0 / radius, 1.0).unwrap();
        let sag = radius - (radius * radius - h * h).sqrt();
        assert!((hit.point[2] - sag).abs() < 1e-14);
        assert!((hit.point[1] - h).abs() < 1e-15);
        // Backward from behind the far sheet: still the vertex-sheet point.
        let hit = sphere([0.0, h, 100.0], [0.0, 0.0, -1.0], 1.0 / radius, -1.0).unwrap();
        assert!((hit.point[2] - sag).abs() < 1e-13);
    }

    #[test]
    fn ray_through_far_sheet_only_is_missed() {
        // A sphere of radius 10: a ray at z = 15 (beyond the centre) crossing sideways meets only
        // the far sheet.
        let c = 0.1;
        assert!(sphere([-30.0, 0.0, 15.0], [1.0, 0.0, 0.0], c, 1.0).is_none());
        // And a ray missing the sphere entirely.
        assert!(sphere([0.0, 11.0, -5.0], [0.0, 0.0, 1.0], c, 1.0).is_none());
    }

    #[test]
    fn near_flat_sphere_matches_plane() {
        let p = [1.0, -2.0, -7.0];
        let d = unit([0.1, 0.2, 1.0]);
        let flat = plane(p, d, 1.0).unwrap();
        let hit = sphere(p, d, 1e-15, 1.0).unwrap();
        for (on_sphere, on_plane) in hit.point.into_iter().zip(flat) {
            assert!((on_sphere - on_plane).abs() < 1e-12);
        }
    }

    #[test]
    fn conic_with_zero_conic_constant_is_the_sphere() {
        let p = [0.3, 2.0, -4.0];
        let d = unit([0.02, -0.1, 1.0]);
        let s = sphere(p, d, 0.04, 1.0).unwrap();
        let k = conic(p, d, 0.04, 1.0, 1.0).unwrap();
        for i in 0..3 {
            assert!((s.point[i] - k.point[i]).abs() < 1e-13);
            assert!((s.normal[i] - k.normal[i]).abs() < 1e-13);
        }
    }

    #[test]
    fn paraboloid_axial_ray_degenerate_quadratic() {
        // k = -1 and an axis-parallel ray: a = 0, the equation is linear.
        let c = 0.02;
        let h = 7.0;
        for sense in [1.0, -1.0] {
            let hit = conic([0.0, h, -5.0 * sense], [0.0, 0.0, sense], c, 0.0, sense).unwrap();
            assert!((hit.point[2] - 0.5 * c * h * h).abs() < 1e-14);
            assert!(on_conic(hit.point, c, 0.0).abs() < 1e-14);
        }
        // On axis exactly.
        let hit = conic([0.0, 0.0, -5.0], [0.0, 0.0, 1.0], c, 0.0, 1.0).unwrap();
        assert_eq!(hit.point, [0.0, 0.0, 0.0]);
    }

    #[test]
    fn hyperboloid_far_sheet_is_not_taken() {
        // k = -3: second sheet at z = 2 / (c (1 + k)) = -50 for c = 0.02. A backward ray coming
        // from +z along the axis must stop at the vertex, never at the far sheet.
        let c = 0.02;
        let hit = conic([0.0, 1.0, 10.0], [0.0, 0.0, -1.0], c, -2.0, -1.0).unwrap();
        assert!(hit.point[2].abs() < 0.1);
        assert!(hit.normal[2] < 0.0);
    }

    #[test]
    fn asphere_newton_lands_on_surface() {
        let mut coefficients = [0.0; crate::prescription::MAX_ASPHERE_TERMS];
        coefficients[0] = 1e-3; // r^2
        coefficients[1] = -2e-5; // r^4
        coefficients[2] = 3e-8; // r^6
        let terms = AsphereTerms {
            coefficients,
            len: 3,
            odd: false,
            search_radius: 30.0,
        };
        let (c, e) = (0.03, 0.4);
        for (y, dy) in [(0.0, 0.0), (5.0, 0.05), (-9.0, 0.2), (12.0, -0.3)] {
            let d = unit([0.01, dy, 1.0]);
            let hit = asphere([0.2, y, -6.0], d, c, e, &terms, 1.0).unwrap();
            let q = hit.point;
            let (sag, _) = asphere_sag(q[0] * q[0] + q[1] * q[1], c, e, &terms).unwrap();
            assert!((sag - q[2]).abs() < 1e-13, "residual {}", sag - q[2]);
        }
    }

    #[test]
    fn odd_asphere_of_even_powers_is_the_even_asphere() {
        // 1e-3 r^2 - 2e-5 r^4 + 3e-8 r^6, written once in r^2 and once in r.
        let mut even = [0.0; crate::prescription::MAX_ASPHERE_TERMS];
        even[..3].copy_from_slice(&[1e-3, -2e-5, 3e-8]);
        let mut odd = [0.0; crate::prescription::MAX_ASPHERE_TERMS];
        odd[..6].copy_from_slice(&[0.0, 1e-3, 0.0, -2e-5, 0.0, 3e-8]);
        let terms = |coefficients, len, odd| AsphereTerms {
            coefficients,
            len,
            odd,
            search_radius: 30.0,
        };
        let (even, odd) = (terms(even, 3, false), terms(odd, 6, true));
        let (c, e) = (0.03, 0.4);
        for rho in [0.0, 1e-6, 2.0, 40.0, 140.0] {
            let (a, b) = (
                asphere_sag(rho, c, e, &even).unwrap(),
                asphere_sag(rho, c, e, &odd).unwrap(),
            );
            assert!(
                (a.0 - b.0).abs() < 1e-15 * (1.0 + a.0.abs()),
                "{rho}: {a:?} {b:?}"
            );
            assert!(
                (a.1 - b.1).abs() < 1e-13 * (1.0 + a.1.abs()),
                "{rho}: {a:?} {b:?}"
            );
        }
        for (y, dy) in [(0.0, 0.0), (5.0, 0.05), (-9.0, 0.2), (12.0, -0.3)] {
            let d = unit([0.01, dy, 1.0]);
            let a = asphere([0.2, y, -6.0], d, c, e, &even, 1.0).unwrap();
            let b = asphere([0.2, y, -6.0], d, c, e, &odd, 1.0).unwrap();
            for i in 0..3 {
                assert!((a.point[i] - b.point[i]).abs() < 1e-12);
                assert!((a.normal[i] - b.normal[i]).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn odd_asphere_hit_is_on_the_sag_with_its_normal() {
        // A cone term, an r^3 and an r^5 term on a conic base: the crossing satisfies the sag
        // written out term by term, and the normal is the sag's gradient by central differences.
        let mut coefficients = [0.0; crate::prescription::MAX_ASPHERE_TERMS];
        coefficients[..5].copy_from_slice(&[2e-3, 0.0, 4e-5, 0.0, -3e-8]);
        let terms = AsphereTerms {
            coefficients,
            len: 5,
            odd: true,
            search_radius: 30.0,
        };
        let (c, k) = (-0.02, -0.6);
        let sag = |x: f64, y: f64| {
            let r = x.hypot(y);
            c * r * r / (1.0 + (1.0 - (1.0 + k) * c * c * r * r).sqrt())
                + 2e-3 * r
                + 4e-5 * r.powi(3)
                - 3e-8 * r.powi(5)
        };
        for (y, dy) in [(3.0, 0.0), (-7.0, 0.1), (11.0, -0.25)] {
            let d = unit([0.02, dy, 1.0]);
            let hit = asphere([0.4, y, -5.0], d, c, 1.0 + k, &terms, 1.0).unwrap();
            let q = hit.point;
            assert!((sag(q[0], q[1]) - q[2]).abs() < 1e-13, "{q:?}");
            let h = 1e-6;
            let gradient = unit([
                (sag(q[0] + h, q[1]) - sag(q[0] - h, q[1])) / (2.0 * h),
                (sag(q[0], q[1] + h) - sag(q[0], q[1] - h)) / (2.0 * h),
                -1.0,
            ]);
            for i in 0..3 {
                assert!(
                    (hit.normal[i] - gradient[i]).abs() < 1e-8,
                    "{:?} {gradient:?}",
                    hit.normal
                );
            }
        }
        // Through the cone's point: it is met, with the axis as normal.
        let hit = asphere([0.0, 0.0, -5.0], [0.0, 0.0, 1.0], c, 1.0 + k, &terms, 1.0).unwrap();
        assert_eq!(hit.point, [0.0, 0.0, 0.0]);
        assert_eq!(hit.normal, [0.0, 0.0, -1.0]);
    }

    #[test]
    fn asphere_without_terms_is_the_conic() {
        let terms = AsphereTerms {
            coefficients: [0.0; crate::prescription::MAX_ASPHERE_TERMS],
            len: 0,
            odd: false,
            search_radius: 20.0,
        };
        let p = [0.5, 3.0, -2.0];
        let d = unit([0.0, -0.15, 1.0]);
        let a = asphere(p, d, -0.05, 0.3, &terms, 1.0).unwrap();
        let k = conic(p, d, -0.05, 0.3, 1.0).unwrap();
        for i in 0..3 {
            assert!((a.point[i] - k.point[i]).abs() < 1e-13);
            assert!((a.normal[i] - k.normal[i]).abs() < 1e-12);
        }
    }

    #[test]
    fn parallel_ray_misses_plane() {
        assert!(plane([0.0, 0.0, -1.0], [1.0, 0.0, 0.0], 1.0).is_none());
        assert!(plane([0.0, 0.0, -1.0], [0.0, 0.0, -1.0], 1.0).is_none());
    }
}
