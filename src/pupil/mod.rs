//! Effective-pupil bounding circles: for each film radius, a circle on the rear reference plane
//! that contains every rear-plane crossing of the rays that pass the whole lens.
//!
//! By rotational symmetry the film point is taken on the +x axis, so the set of passing rays is
//! mirror-symmetric about the x axis and the smallest enclosing circle has its centre on it: a
//! circle is (centre_x, radius). Circles are stored at evenly spaced film radii (nodes) and
//! interpolated linearly; the node radii are inflated during fitting until the interpolated circle
//! contains the pupils measured between the nodes, so interpolation stays conservative. Sampling is
//! uniform over the interpolated circle and its pdf is exactly `1 / (pi r^2)` per mm^2, so an
//! estimator that divides by it has no seams between bins (pbrt's 64-ring artefact came from
//! ignoring the bound's pdf).

use serde::{Deserialize, Serialize};

/// One bounding circle on the rear reference plane, film point on the +x axis (mm).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PupilCircle {
    pub centre_x: f64,
    pub radius: f64,
}

/// Bounding circles at film radii `max_film_radius * k / (n - 1)`, k = 0..n.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PupilTable {
    pub max_film_radius: f64,
    pub circles: Vec<PupilCircle>,
}

/// A point on the rear plane and the density it was drawn with.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PupilSample {
    /// Rear-plane point in the frame where the film point lies on +x (mm).
    pub point: [f64; 2],
    /// Probability density per unit rear-plane area (1/mm^2).
    pub pdf: f64,
}

impl PupilTable {
    /// The interpolated circle at film radius `r` (clamped to the table's range). A table with
    /// no circles (only a hostile file makes one) has the empty circle, where nothing passes.
    pub fn circle_at(&self, film_radius: f64) -> PupilCircle {
        self.interpolation().at(film_radius)
    }

    /// The circles as [`CircleInterpolation::at`] reads them, for many film radii in a row.
    pub(crate) fn interpolation(&self) -> CircleInterpolation<'_> {
        let n = self.circles.len();
        let spread = n > 1 && self.max_film_radius > 0.0;
        CircleInterpolation {
            circles: if n == 0 { &NO_CIRCLE } else { &self.circles },
            max_film_radius: self.max_film_radius,
            intervals: if spread { (n - 1) as f64 } else { 0.0 },
        }
    }
    /// Maps a unit-square sample to a point uniform over the circle for `film_radius`.
    /// Uses the concentric (Shirley-Chiu) map, which keeps strata compact.
    pub fn sample(&self, film_radius: f64, unit: [f64; 2]) -> PupilSample {
        uniform_in(self.circle_at(film_radius), unit)
    }

    /// Density of [`PupilTable::sample`] at a rear-plane point (zero outside the circle).
    pub fn pdf(&self, film_radius: f64, point: [f64; 2]) -> f64 {
        density_in(self.circle_at(film_radius), point)
    }

    /// Largest distance from the optical axis reached by any circle (mm).
    pub fn max_extent(&self) -> f64 {
        self.circles
            .iter()
            .map(|c| c.centre_x.abs() + c.radius)
            .fold(0.0, f64::max)
    }
}

/// What a table without circles holds: the empty circle.
const NO_CIRCLE: [PupilCircle; 1] = [PupilCircle {
    centre_x: 0.0,
    radius: 0.0,
}];

/// A [`PupilTable`]'s circles (never none: the empty circle stands in) and the intervals between
/// them, 0 where there is a single circle or no film radius to spread them over.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CircleInterpolation<'a> {
    circles: &'a [PupilCircle],
    max_film_radius: f64,
    intervals: f64,
}

impl CircleInterpolation<'_> {
    /// [`PupilTable::circle_at`] without branches, so that a group of rays gets its circles in
    /// vector lanes.
    #[inline(always)]
    pub(crate) fn at(&self, film_radius: f64) -> PupilCircle {
        let (below, fraction) = self.position(film_radius);
        self.between(below, fraction)
    }

    /// The circle at or below `film_radius` and the fraction of the way to the next: the
    /// arithmetic of [`CircleInterpolation::at`], which a group's lanes do side by side before
    /// they read any circle.
    #[inline(always)]
    pub(crate) fn position(&self, film_radius: f64) -> (u32, f64) {
        let last = self.circles.len() - 1;
        let t = (film_radius / self.max_film_radius).clamp(0.0, 1.0) * self.intervals;
        // The index of the circle below t, clamped in f64 (`max` takes NaN to 0) to the last
        // interval and to i32, so that the floor is a truncation and the truncation one plain
        // conversion: a saturating `as` is taken apart into scalar conversions and fix-ups, lane
        // by lane. (A table's sidecar, at most `limits::MAX_INPUT_BYTES` = 1 GiB of text, holds
        // far fewer than 2^31 circles.)
        let below = t
            .max(0.0)
            .min(last.saturating_sub(1) as f64)
            .min(f64::from(i32::MAX));
        // SAFETY: `below` is finite and in [0, i32::MAX].
        let i: i32 = unsafe { below.to_int_unchecked() };
        (i as u32, t - f64::from(i))
    }

    /// The circle `fraction` of the way from circle `below` to the next (the last circle
    /// where there is no next).
    #[inline(always)]
    pub(crate) fn between(&self, below: u32, fraction: f64) -> PupilCircle {
        let last = self.circles.len() - 1;
        let i = below as usize;
        // SAFETY: both indices are at most `last`, and `circles` is never empty. Unchecked, so a
        // group's lanes load them without a branch each.
        let (a, b) = unsafe {
            (
                *self.circles.get_unchecked(i.min(last)),
                *self.circles.get_unchecked((i + 1).min(last)),
            )
        };
        let between = PupilCircle {
            centre_x: a.centre_x + (b.centre_x - a.centre_x) * fraction,
            radius: a.radius + (b.radius - a.radius) * fraction,
        };
        if self.intervals > 0.0 { between } else { a }
    }
}

/// A point uniform over `circle` for a unit-square sample, and its density.
fn uniform_in(circle: PupilCircle, unit: [f64; 2]) -> PupilSample {
    let [dx, dy] = concentric_disk(unit);
    PupilSample {
        point: [circle.centre_x + circle.radius * dx, circle.radius * dy],
        pdf: density_in(circle, [circle.centre_x, 0.0]),
    }
}

/// Density of the uniform distribution over `circle` at `point` (zero outside).
fn density_in(circle: PupilCircle, point: [f64; 2]) -> f64 {
    let inside = (point[0] - circle.centre_x).hypot(point[1]) <= circle.radius;
    if inside && circle.radius > 0.0 {
        1.0 / (std::f64::consts::PI * circle.radius * circle.radius)
    } else {
        0.0
    }
}

/// Concentric map from \[0, 1\]^2 onto the unit disk; area-preserving up to a constant, so a
/// uniform square sample gives a uniform disk sample.
pub fn concentric_disk(unit: [f64; 2]) -> [f64; 2] {
    let a = 2.0 * unit[0] - 1.0;
    let b = 2.0 * unit[1] - 1.0;
    if a == 0.0 && b == 0.0 {
        return [0.0, 0.0];
    }
    let quarter = std::f64::consts::FRAC_PI_4;
    let (r, phi) = if a.abs() > b.abs() {
        (a, quarter * (b / a))
    } else {
        (b, 2.0 * quarter - quarter * (a / b))
    };
    [r * phi.cos(), r * phi.sin()]
}

/// How densely [`fit_pupil`] probes the rear plane.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PupilFitSettings {
    /// Grid points across the search disk diameter (the half y >= 0 is probed).
    pub grid: usize,
    /// Directions (over the half-plane) along which the boundary is located by bisection.
    pub boundary_directions: usize,
    /// Extra radius as a fraction of the radius, covering boundary between probed directions.
    pub relative_margin: f64,
}

impl Default for PupilFitSettings {
    fn default() -> Self {
        PupilFitSettings {
            grid: 32,
            boundary_directions: 48,
            relative_margin: 0.01,
        }
    }
}

/// Which rear-plane points pass the lens, for one film point on +x. It answers a batch at once,
/// so a tracer can trace the points side by side; any `Fn([f64; 2]) -> bool` answers one by one.
pub trait RearTest: Sync {
    /// Sets `passes[k]` for `points[k]`.
    fn test(&self, points: &[[f64; 2]], passes: &mut [bool]);

    fn passes(&self, point: [f64; 2]) -> bool {
        let mut out = [false];
        self.test(&[point], &mut out);
        out[0]
    }
}

impl<F: Fn([f64; 2]) -> bool + Sync> RearTest for F {
    fn test(&self, points: &[[f64; 2]], passes: &mut [bool]) {
        for (p, out) in points.iter().zip(passes) {
            *out = self(*p);
        }
    }
}

/// The points of `points` that pass.
fn passing(test: &dyn RearTest, points: &[[f64; 2]]) -> Vec<[f64; 2]> {
    let mut passes = vec![false; points.len()];
    test.test(points, &mut passes);
    points
        .iter()
        .zip(passes)
        .filter_map(|(p, ok)| ok.then_some(*p))
        .collect()
}

/// The smallest circle centred on the x axis around every passing rear-plane point of one film
/// point, or None when no probed ray passes. `passes` answers for rear-plane points (film point
/// on +x); `search_radius` bounds where passing points can be (e.g. the rear clear aperture plus
/// a margin). Every probe of one stage goes to `passes` as one batch.
pub fn fit_pupil(
    passes: &dyn RearTest,
    search_radius: f64,
    settings: &PupilFitSettings,
) -> Option<PupilCircle> {
    let n = settings.grid.max(4);
    let mut step = 2.0 * search_radius / (n - 1) as f64;
    let grid: Vec<[f64; 2]> = (0..n / 2 + 1)
        .flat_map(|j| (0..n).map(move |i| [-search_radius + i as f64 * step, j as f64 * step]))
        .filter(|p| p[0] * p[0] + p[1] * p[1] <= search_radius * search_radius)
        .collect();
    let mut inside = passing(passes, &grid);
    if inside.is_empty() {
        // A pupil smaller than a grid step (a lens stopped far down) falls between the nodes.
        // It is symmetric about the x axis, so a connected pupil crosses it: scan the axis.
        let (point, spacing) = scan_axis(passes, search_radius)?;
        inside.push(point);
        step = spacing;
    }
    let count = inside.len() as f64;
    // The pupil is symmetric about the x axis: its centroid lies on it.
    let seed = [inside.iter().map(|p| p[0]).sum::<f64>() / count, 0.0];
    let seed = if passes.passes(seed) { seed } else { inside[0] };
    // Bisection from a passing point outwards along each direction finds the boundary to a small
    // fraction of a grid step; the grid points cover regions the directions might miss. All
    // directions march and bisect in lockstep, one batch per step.
    let directions: Vec<[f64; 2]> = (0..=settings.boundary_directions)
        .map(|k| {
            let angle = std::f64::consts::PI * k as f64 / settings.boundary_directions as f64;
            [angle.cos(), angle.sin()]
        })
        .collect();
    let at = |k: usize, t: f64| {
        [
            seed[0] + directions[k][0] * t,
            seed[1] + directions[k][1] * t,
        ]
    };
    // March in sub-grid steps so a thin passing neck is not jumped over, then bisect.
    let reach = 2.0 * search_radius;
    let mut last_in = vec![0.0; directions.len()];
    let mut marching: Vec<usize> = (0..directions.len()).collect();
    let mut t = 0.0;
    let mut points = Vec::with_capacity(directions.len());
    let mut results = vec![false; directions.len()];
    while t < reach && !marching.is_empty() {
        t += step * 0.5;
        points.clear();
        points.extend(marching.iter().map(|&k| at(k, t)));
        passes.test(&points, &mut results[..points.len()]);
        let mut still = 0;
        for j in 0..marching.len() {
            let k = marching[j];
            if results[j] {
                last_in[k] = t;
            } else if t - last_in[k] > 2.0 * step {
                continue;
            }
            marching[still] = k;
            still += 1;
        }
        marching.truncate(still);
    }
    // 14 halvings leave the boundary within step / 2^15 (~0.05 um for a 50 mm lens), far below
    // the margin added afterwards.
    let mut bracket: Vec<(f64, f64)> = last_in.iter().map(|&t| (t, t + step * 0.5)).collect();
    for _ in 0..14 {
        points.clear();
        points.extend(
            bracket
                .iter()
                .enumerate()
                .map(|(k, (lo, hi))| at(k, 0.5 * (lo + hi))),
        );
        passes.test(&points, &mut results);
        for ((lo, hi), inside) in bracket.iter_mut().zip(&results) {
            let mid = 0.5 * (*lo + *hi);
            if *inside {
                *lo = mid;
            } else {
                *hi = mid;
            }
        }
    }
    let mut boundary = inside;
    boundary.extend(bracket.iter().enumerate().map(|(k, &(_, hi))| at(k, hi)));
    let circle = enclosing_circle_on_axis(&boundary);
    Some(PupilCircle {
        centre_x: circle.centre_x,
        radius: circle.radius * (1.0 + settings.relative_margin) + 0.5 * step * 0.1,
    })
}

/// Finest spacing of [`scan_axis`]: the search diameter over 2^14, which resolves the pupil of
/// a 50 mm lens down to about f/2000.
const AXIS_SCAN_LEVELS: u32 = 14;

/// The first passing point on the x axis within `search_radius`, probed on ever finer dyadic
/// grids (each level adds the midpoints of the last), with the spacing it was found at.
fn scan_axis(passes: &dyn RearTest, search_radius: f64) -> Option<([f64; 2], f64)> {
    (1..=AXIS_SCAN_LEVELS).find_map(|level| {
        let spacing = 2.0 * search_radius / f64::from(1u32 << level);
        let level_points: Vec<[f64; 2]> = (1..1u32 << level)
            .step_by(2)
            .map(|j| [-search_radius + f64::from(j) * spacing, 0.0])
            .collect();
        passing(passes, &level_points)
            .first()
            .map(|&p| (p, spacing))
    })
}

/// Smallest circle with its centre on the x axis containing `points` (and their mirror images).
/// The farthest-point distance is convex in the centre position, so a ternary search converges.
pub fn enclosing_circle_on_axis(points: &[[f64; 2]]) -> PupilCircle {
    // Compared squared: the square root is monotonic, and taken once at the end.
    let radius_sq_for = |cx: f64| {
        points
            .iter()
            .map(|p| (p[0] - cx) * (p[0] - cx) + p[1] * p[1])
            .fold(0.0, f64::max)
    };
    let (mut lo, mut hi) = points
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p[0]), hi.max(p[0]))
        });
    for _ in 0..100 {
        let a = lo + (hi - lo) / 3.0;
        let b = hi - (hi - lo) / 3.0;
        if radius_sq_for(a) < radius_sq_for(b) {
            hi = b;
        } else {
            lo = a;
        }
    }
    let centre_x = 0.5 * (lo + hi);
    PupilCircle {
        centre_x,
        radius: radius_sq_for(centre_x).sqrt(),
    }
}

/// The exact pupils of one film plane: fitted circles at the film-radius nodes (None where
/// nothing passes) and at points between them (cell, fraction, circle).
struct Row {
    at_nodes: Vec<Option<PupilCircle>>,
    between: Vec<(usize, f64, PupilCircle)>,
}

impl Row {
    fn measure(
        pupil_at: &(dyn Fn(f64) -> Option<PupilCircle> + Sync),
        max_film_radius: f64,
        nodes: usize,
        between: usize,
    ) -> Row {
        use rayon::prelude::*;
        let node_r = |k: usize| max_film_radius * k as f64 / (nodes - 1) as f64;
        let at_nodes = (0..nodes)
            .into_par_iter()
            .map(|k| pupil_at(node_r(k)))
            .collect();
        let between = (0..nodes - 1)
            .into_par_iter()
            .flat_map_iter(|k| {
                (1..=between).filter_map(move |j| {
                    let f = j as f64 / (between + 1) as f64;
                    pupil_at(node_r(k) + f * (node_r(k + 1) - node_r(k))).map(|c| (k, f, c))
                })
            })
            .collect();
        Row { at_nodes, between }
    }

    /// The node circles, a node where nothing passes taking its nearest measured neighbour's
    /// centre with zero radius, so the interpolated circle shrinks towards where the last rays
    /// pass.
    fn node_circles(&self) -> Vec<PupilCircle> {
        let measured = &self.at_nodes;
        (0..measured.len())
            .map(|k| {
                measured[k].unwrap_or_else(|| {
                    let neighbour = measured[..k]
                        .iter()
                        .rev()
                        .chain(measured[k..].iter())
                        .flatten()
                        .next();
                    PupilCircle {
                        centre_x: neighbour.map_or(0.0, |c| c.centre_x),
                        radius: 0.0,
                    }
                })
            })
            .collect()
    }
}

/// An exact pupil inside a grid cell: film-radius cell `k` at fraction `fr`, focus cell `j` at
/// fraction `ft`.
struct Probe {
    k: usize,
    fr: f64,
    j: usize,
    ft: f64,
    circle: PupilCircle,
}

/// How far `probe`'s circle reaches beyond the bilinear interpolant of `grid` (rows of circles
/// per focus node) at its point: |centre offset| + radius - interpolated radius.
fn deficit(grid: &[Vec<PupilCircle>], probe: &Probe) -> f64 {
    let lerp = |a: PupilCircle, b: PupilCircle, f: f64| PupilCircle {
        centre_x: a.centre_x + (b.centre_x - a.centre_x) * f,
        radius: a.radius + (b.radius - a.radius) * f,
    };
    let j1 = (probe.j + 1).min(grid.len() - 1);
    let row = |j: usize| lerp(grid[j][probe.k], grid[j][probe.k + 1], probe.fr);
    let c = lerp(row(probe.j), row(j1), probe.ft);
    (probe.circle.centre_x - c.centre_x).abs() + probe.circle.radius - c.radius
}

/// Grows node radii until every probe's circle lies inside the interpolated one: a probe's
/// deficit is added to each corner of its cell that carries weight there, which raises the
/// interpolant at the probe by exactly the deficit (the weights sum to one). Radii only grow,
/// so a probe once contained stays contained and one sweep suffices.
fn inflate(grid: &mut [Vec<PupilCircle>], probes: &[Probe]) {
    for probe in probes {
        let d = deficit(grid, probe);
        if d <= 0.0 {
            continue;
        }
        let j1 = (probe.j + 1).min(grid.len() - 1);
        for (j, wj) in [(probe.j, 1.0 - probe.ft), (j1, probe.ft)] {
            for (k, wk) in [(probe.k, 1.0 - probe.fr), (probe.k + 1, probe.fr)] {
                if wj * wk > 0.0 {
                    grid[j][k].radius += d;
                }
            }
        }
    }
}

/// Builds a conservative table from exact pupils: `pupil_at(r)` gives the fitted circle at film
/// radius r (None where nothing passes). Circles are measured at `nodes` film radii and at
/// `between` radii inside each interval; node radii grow until every in-between circle lies inside
/// the linearly interpolated one.
pub fn build_table(
    pupil_at: &(dyn Fn(f64) -> Option<PupilCircle> + Sync),
    max_film_radius: f64,
    nodes: usize,
    between: usize,
) -> PupilTable {
    let nodes = nodes.max(2);
    let row = Row::measure(pupil_at, max_film_radius, nodes, between);
    let mut grid = vec![row.node_circles()];
    let probes: Vec<Probe> = row
        .between
        .iter()
        .map(|&(k, fr, circle)| Probe {
            k,
            fr,
            j: 0,
            ft: 0.0,
            circle,
        })
        .collect();
    inflate(&mut grid, &probes);
    PupilTable {
        max_film_radius,
        circles: grid.pop().expect("one row"),
    }
}

/// Effective-pupil circles over film radius and focus (unit focusing: the film moves): one
/// [`PupilTable`] per focus node, the nodes on film planes evenly spaced from `film_z[0]` to
/// `film_z[1]`, interpolated bilinearly in film radius and film-plane z. Node radii are inflated
/// so the interpolant stays conservative between nodes in both directions, and sampling is
/// uniform over the interpolated circle with the exact pdf `1 / (pi r^2)`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FocusPupilTable {
    /// Film planes (lens-frame z, mm) of the first and last focus node; equal with one node.
    pub film_z: [f64; 2],
    /// Circles per focus node, all over the same film radii.
    pub nodes: Vec<PupilTable>,
}

impl FocusPupilTable {
    /// One focus: the film plane `film_z` and its circles.
    pub fn single(film_z: f64, table: PupilTable) -> FocusPupilTable {
        FocusPupilTable {
            film_z: [film_z, film_z],
            nodes: vec![table],
        }
    }

    pub fn max_film_radius(&self) -> f64 {
        self.nodes.first().map_or(0.0, |n| n.max_film_radius)
    }

    /// Position of the film plane `film_z` in focus-node units (0 at the first node, clamped to
    /// the range): the coordinate the shader's bilinear lookup takes.
    pub fn focus_coordinate(&self, film_z: f64) -> f64 {
        let span = self.film_z[1] - self.film_z[0];
        if self.nodes.len() < 2 || span <= 0.0 {
            return 0.0;
        }
        ((film_z - self.film_z[0]) / span).clamp(0.0, 1.0) * (self.nodes.len() - 1) as f64
    }

    /// Focus cell and fraction of film plane `film_z`.
    fn focus_cell(&self, film_z: f64) -> (usize, f64) {
        let t = self.focus_coordinate(film_z);
        if self.nodes.len() < 2 {
            return (0, 0.0);
        }
        // t >= 0 (or NaN): truncation is the floor.
        let j = (t as usize).min(self.nodes.len() - 2);
        (j, t - j as f64)
    }

    /// The interpolated circle at film radius `film_radius` on the film plane `film_z`. A table
    /// with no nodes (only a hostile file makes one) has the empty circle.
    pub fn circle_at(&self, film_radius: f64, film_z: f64) -> PupilCircle {
        if self.nodes.is_empty() {
            return PupilCircle {
                centre_x: 0.0,
                radius: 0.0,
            };
        }
        let (j, f) = self.focus_cell(film_z);
        let a = self.nodes[j].circle_at(film_radius);
        let b = self.nodes[(j + 1).min(self.nodes.len() - 1)].circle_at(film_radius);
        PupilCircle {
            centre_x: a.centre_x + (b.centre_x - a.centre_x) * f,
            radius: a.radius + (b.radius - a.radius) * f,
        }
    }

    /// The circles of one film plane: the bilinear interpolant at `film_z` is linear in film
    /// radius between the same nodes, so this table interpolates to exactly the same circles.
    pub fn at_film_z(&self, film_z: f64) -> PupilTable {
        let Some(first) = self.nodes.first() else {
            return PupilTable {
                max_film_radius: 0.0,
                circles: Vec::new(),
            };
        };
        let (j, f) = self.focus_cell(film_z);
        let b = &self.nodes[(j + 1).min(self.nodes.len() - 1)];
        PupilTable {
            max_film_radius: first.max_film_radius,
            circles: self.nodes[j]
                .circles
                .iter()
                .zip(&b.circles)
                .map(|(a, b)| PupilCircle {
                    centre_x: a.centre_x + (b.centre_x - a.centre_x) * f,
                    radius: a.radius + (b.radius - a.radius) * f,
                })
                .collect(),
        }
    }

    /// A point uniform over the circle of `film_radius` on the film plane `film_z`.
    pub fn sample(&self, film_radius: f64, film_z: f64, unit: [f64; 2]) -> PupilSample {
        uniform_in(self.circle_at(film_radius, film_z), unit)
    }

    /// Density of [`FocusPupilTable::sample`] at a rear-plane point.
    pub fn pdf(&self, film_radius: f64, film_z: f64, point: [f64; 2]) -> f64 {
        density_in(self.circle_at(film_radius, film_z), point)
    }
}

/// How many focus nodes a [`FocusPupilTable`] gets.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct FocusNodeSettings {
    /// Focus intervals are halved while a pupil fitted halfway between two nodes reaches beyond
    /// their interpolated circle by more than this fraction of the largest pupil radius there.
    /// Inflation keeps the table conservative either way; this bounds what it costs in
    /// tightness.
    pub relative_tolerance: f64,
    pub max_nodes: usize,
}

impl Default for FocusNodeSettings {
    /// 4 %: fits on neighbouring film planes already scatter by 2-3 % of the pupil radius
    /// (where the directions probing the boundary fall relative to a cat's-eye corner moves
    /// with the plane; measured on the double Gauss, infinity..1 m and 3..0.5 m), so a finer
    /// tolerance would halve intervals chasing that scatter up to `max_nodes`.
    fn default() -> Self {
        FocusNodeSettings {
            relative_tolerance: 0.04,
            max_nodes: 17,
        }
    }
}

/// Builds a conservative [`FocusPupilTable`] over film radii up to `max_film_radius` and the
/// film planes `film_z[0]..=film_z[1]` from exact pupils `pupil_at(film_radius, film_z)`.
///
/// Each film plane's circles come from [`build_table`]'s measurement (`radius_nodes` nodes,
/// `between` checks per interval). Focus nodes start at the two ends; while the pupils fitted
/// halfway between two nodes stick out of the interpolated circle by more than
/// `settings.relative_tolerance` of the largest of them, every focus interval is halved (the
/// halfway film planes become nodes). Then the node radii are inflated until every check, between
/// film radii and halfway between focus nodes, lies inside the bilinear interpolant.
pub fn build_focus_table(
    pupil_at: &(dyn Fn(f64, f64) -> Option<PupilCircle> + Sync),
    max_film_radius: f64,
    radius_nodes: usize,
    between: usize,
    film_z: [f64; 2],
    settings: &FocusNodeSettings,
) -> FocusPupilTable {
    let radius_nodes = radius_nodes.max(2);
    let measure = |z: f64| {
        Row::measure(
            &|r: f64| pupil_at(r, z),
            max_film_radius,
            radius_nodes,
            between,
        )
    };
    if film_z[1] <= film_z[0] {
        let table = build_table(
            &|r| pupil_at(r, film_z[0]),
            max_film_radius,
            radius_nodes,
            between,
        );
        return FocusPupilTable::single(film_z[0], table);
    }
    let z_at = |j: usize, nodes: usize| {
        film_z[0] + (film_z[1] - film_z[0]) * j as f64 / (nodes - 1) as f64
    };
    let mut rows = vec![measure(film_z[0]), measure(film_z[1])];
    loop {
        let nodes = rows.len();
        let halfway: Vec<Row> = (0..nodes - 1)
            .map(|j| measure(0.5 * (z_at(j, nodes) + z_at(j + 1, nodes))))
            .collect();
        let mut grid: Vec<Vec<PupilCircle>> = rows.iter().map(Row::node_circles).collect();
        let mut probes: Vec<Probe> = Vec::new();
        for (j, row) in rows.iter().enumerate() {
            let (cell, ft) = if j + 1 < nodes {
                (j, 0.0)
            } else {
                (j - 1, 1.0)
            };
            probes.extend(row.between.iter().map(|&(k, fr, circle)| Probe {
                k,
                fr,
                j: cell,
                ft,
                circle,
            }));
        }
        inflate(&mut grid, &probes);
        let mut halfway_probes: Vec<Probe> = Vec::new();
        for (j, row) in halfway.iter().enumerate() {
            for (k, circle) in row.at_nodes.iter().enumerate() {
                if let Some(circle) = circle {
                    let (cell, fr) = if k + 1 < radius_nodes {
                        (k, 0.0)
                    } else {
                        (k - 1, 1.0)
                    };
                    halfway_probes.push(Probe {
                        k: cell,
                        fr,
                        j,
                        ft: 0.5,
                        circle: *circle,
                    });
                }
            }
            halfway_probes.extend(row.between.iter().map(|&(k, fr, circle)| Probe {
                k,
                fr,
                j,
                ft: 0.5,
                circle,
            }));
        }
        let largest = halfway_probes
            .iter()
            .map(|p| p.circle.radius)
            .fold(0.0, f64::max);
        let worst = halfway_probes
            .iter()
            .map(|p| deficit(&grid, p) / largest)
            .fold(0.0, f64::max);
        let finer = 2 * nodes - 1;
        if worst <= settings.relative_tolerance || finer > settings.max_nodes.max(2) {
            inflate(&mut grid, &halfway_probes);
            return FocusPupilTable {
                film_z,
                nodes: grid
                    .into_iter()
                    .map(|circles| PupilTable {
                        max_film_radius,
                        circles,
                    })
                    .collect(),
            };
        }
        // The halfway planes become nodes between the old ones.
        let mut halfway = halfway.into_iter();
        rows = std::mem::take(&mut rows)
            .into_iter()
            .flat_map(|row| std::iter::once(row).chain(halfway.next()))
            .collect();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Classic two-aperture vignetting: passing points lie in the intersection of two circles,
    /// one fixed (rear element) and one sliding with the film radius (front element's image).
    fn two_circle_pupil(film_radius: f64) -> impl Fn([f64; 2]) -> bool + Sync {
        move |p: [f64; 2]| p[0].hypot(p[1]) <= 10.0 && (p[0] + 0.8 * film_radius).hypot(p[1]) <= 9.0
    }

    #[test]
    fn fitted_circle_contains_every_passing_point_and_is_tight() {
        for film_radius in [0.0, 5.0, 12.0] {
            let passes = two_circle_pupil(film_radius);
            let circle = fit_pupil(&passes, 12.0, &PupilFitSettings::default()).unwrap();
            let mut outside = 0;
            let mut dense_passing = Vec::new();
            for i in 0..400 {
                for j in 0..200 {
                    let p = [-12.0 + 24.0 * i as f64 / 399.0, 12.0 * j as f64 / 199.0];
                    let inside = (p[0] - circle.centre_x).hypot(p[1]) <= circle.radius;
                    if passes(p) && !inside {
                        outside += 1;
                    }
                    if passes(p) {
                        dense_passing.push(p);
                    }
                }
            }
            assert_eq!(
                outside, 0,
                "film radius {film_radius}: passing points outside"
            );
            // Tight: no more than the margin above the smallest axis-centred circle around a
            // dense sampling of the true region (at r = 0 that is the 9 mm disk itself).
            let ideal = enclosing_circle_on_axis(&dense_passing);
            assert!(
                circle.radius <= ideal.radius * 1.025,
                "film radius {film_radius}: {circle:?} vs ideal {ideal:?}"
            );
        }
    }

    #[test]
    fn interpolated_circles_stay_conservative_between_nodes() {
        let settings = PupilFitSettings::default();
        let pupil_at = |r: f64| fit_pupil(&two_circle_pupil(r), 25.0, &settings);
        let table = build_table(&pupil_at, 20.0, 5, 3);
        for k in 0..=200 {
            let r = 20.0 * k as f64 / 200.0;
            let Some(exact) = pupil_at(r) else { continue };
            let c = table.circle_at(r);
            // The fitted circle at r is itself measured on a grid; allow its own margin only.
            let excess = (exact.centre_x - c.centre_x).abs() + exact.radius - c.radius;
            assert!(excess < 0.02 * exact.radius, "r = {r}: excess {excess} mm");
        }
    }

    #[test]
    fn sampling_pdf_integrates_to_one_and_matches_the_histogram() {
        let table = PupilTable {
            max_film_radius: 10.0,
            circles: vec![
                PupilCircle {
                    centre_x: 0.0,
                    radius: 4.0,
                },
                PupilCircle {
                    centre_x: -2.0,
                    radius: 3.0,
                },
            ],
        };
        let film_radius = 3.7;
        let circle = table.circle_at(film_radius);
        // Midpoint quadrature of the pdf over a box around the circle.
        let n = 800;
        let (x0, y0) = (circle.centre_x - circle.radius, -circle.radius);
        let h = 2.0 * circle.radius / n as f64;
        let mut integral = 0.0;
        for i in 0..n {
            for j in 0..n {
                let p = [x0 + (i as f64 + 0.5) * h, y0 + (j as f64 + 0.5) * h];
                integral += table.pdf(film_radius, p) * h * h;
            }
        }
        assert!((integral - 1.0).abs() < 2e-3, "integral {integral}");
        // The concentric map is uniform: equal-area annuli get equal counts.
        let strata = 256;
        let mut annulus = [0usize; 4];
        for i in 0..strata {
            for j in 0..strata {
                let u = [
                    (i as f64 + 0.5) / strata as f64,
                    (j as f64 + 0.5) / strata as f64,
                ];
                let s = table.sample(film_radius, u);
                assert_eq!(s.pdf, table.pdf(film_radius, s.point));
                let rel = (s.point[0] - circle.centre_x).hypot(s.point[1]) / circle.radius;
                annulus[((rel * rel * 4.0) as usize).min(3)] += 1;
            }
        }
        let expected = (strata * strata / 4) as f64;
        for count in annulus {
            assert!((count as f64 / expected - 1.0).abs() < 0.03, "{annulus:?}");
        }
    }

    /// A pupil that also changes with the film plane, non-linearly: the sliding circle's offset
    /// grows with the square of z (a film moving back sees the front element's image shift).
    fn focus_dependent_pupil(film_radius: f64, film_z: f64) -> impl Fn([f64; 2]) -> bool + Sync {
        let slide = 0.4 * film_radius * (1.0 + 0.15 * film_z * film_z);
        move |p: [f64; 2]| p[0].hypot(p[1]) <= 10.0 && (p[0] + slide).hypot(p[1]) <= 9.0
    }

    #[test]
    fn focus_table_stays_conservative_between_focus_nodes_and_refines_where_needed() {
        let settings = PupilFitSettings::default();
        let pupil_at = |r: f64, z: f64| fit_pupil(&focus_dependent_pupil(r, z), 25.0, &settings);
        let film_z = [0.0, 2.0];
        let table = build_focus_table(
            &pupil_at,
            20.0,
            17,
            2,
            film_z,
            &FocusNodeSettings::default(),
        );
        // Linear interpolation over z in [0, 2] misses the quadratic slide by far more than
        // 1 % of the radius: the focus intervals were halved.
        assert!(table.nodes.len() > 2, "{} focus nodes", table.nodes.len());
        assert!(table.nodes.iter().all(|n| n.circles.len() == 17));
        // Densely between the nodes in both directions, no passing point lies outside the
        // interpolated circle, and the one-plane table at z interpolates to the same circle.
        for i in 0..=40 {
            let z = film_z[0] + (film_z[1] - film_z[0]) * i as f64 / 40.0;
            for k in 0..=40 {
                let r = 20.0 * k as f64 / 40.0;
                let c = table.circle_at(r, z);
                let passes = focus_dependent_pupil(r, z);
                for a in 0..120 {
                    for b in 0..=60 {
                        let p = [-11.0 + 22.0 * a as f64 / 119.0, 11.0 * b as f64 / 60.0];
                        assert!(
                            !passes(p) || (p[0] - c.centre_x).hypot(p[1]) <= c.radius,
                            "r {r} z {z}: passing {p:?} outside {c:?}"
                        );
                    }
                }
                let slice = table.at_film_z(z).circle_at(r);
                assert!((slice.radius - c.radius).abs() < 1e-12 * c.radius.max(1.0));
                assert!((slice.centre_x - c.centre_x).abs() < 1e-12 * c.radius.max(1.0));
            }
        }
        // With a tolerance above the miss, two nodes are enough, and inflation alone keeps the
        // interpolant around the pupil fitted halfway.
        let coarse = build_focus_table(
            &pupil_at,
            20.0,
            17,
            2,
            film_z,
            &FocusNodeSettings {
                relative_tolerance: 10.0,
                max_nodes: 17,
            },
        );
        assert_eq!(coarse.nodes.len(), 2);
        let radius_nodes = 17;
        for k in 0..radius_nodes {
            let r = 20.0 * k as f64 / (radius_nodes - 1) as f64;
            let Some(exact) = pupil_at(r, 1.0) else {
                continue;
            };
            let c = coarse.circle_at(r, 1.0);
            let excess = (exact.centre_x - c.centre_x).abs() + exact.radius - c.radius;
            assert!(excess < 1e-9, "coarse, r {r}: excess {excess} mm");
        }
    }

    #[test]
    fn focus_table_pdf_integrates_to_one_between_focus_nodes() {
        let row = |centre: f64, radius: f64| PupilTable {
            max_film_radius: 10.0,
            circles: vec![
                PupilCircle {
                    centre_x: 0.0,
                    radius: 4.0,
                },
                PupilCircle {
                    centre_x: centre,
                    radius,
                },
            ],
        };
        let table = FocusPupilTable {
            film_z: [50.0, 52.0],
            nodes: vec![row(-2.0, 3.0), row(-1.0, 2.5), row(-3.0, 3.5)],
        };
        let (film_radius, film_z) = (6.3, 51.37);
        let circle = table.circle_at(film_radius, film_z);
        // Bilinear: halfway between node rows 1 and 2 at 0.37 of the way, 0.63 along the radius.
        let expect = |a: f64, b: f64, c: f64| {
            let f = 0.63;
            let (lo, hi) = (a + (b - a) * f, a + (c - a) * f);
            lo + (hi - lo) * 0.37
        };
        assert!((circle.radius - expect(4.0, 2.5, 3.5)).abs() < 1e-12);
        assert!((circle.centre_x - expect(0.0, -1.0, -3.0)).abs() < 1e-12);
        let n = 800;
        let (x0, y0) = (circle.centre_x - circle.radius, -circle.radius);
        let h = 2.0 * circle.radius / n as f64;
        let mut integral = 0.0;
        for i in 0..n {
            for j in 0..n {
                let p = [x0 + (i as f64 + 0.5) * h, y0 + (j as f64 + 0.5) * h];
                integral += table.pdf(film_radius, film_z, p) * h * h;
            }
        }
        assert!((integral - 1.0).abs() < 2e-3, "integral {integral}");
        for u in [[0.1, 0.9], [0.5, 0.5], [0.97, 0.03]] {
            let s = table.sample(film_radius, film_z, u);
            assert_eq!(s.pdf, table.pdf(film_radius, film_z, s.point));
        }
    }
}
