//! Where lens samples are drawn, and the conservative bound that keeps a tilted sensor's samples
//! inside the effective pupil.

use crate::lrtf::bake::rear_search_radius;
use crate::pupil::{PupilCircle, PupilTable};
use crate::system::SystemAt;

/// Where lens samples are drawn: uniformly over a circle on the plane `z`, the circle looked up
/// by film radius in `circles` (film point rotated onto +x).
#[derive(Clone, Debug, PartialEq)]
pub struct PupilSampling {
    pub z: f64,
    pub circles: PupilTable,
}

impl PupilSampling {
    /// One circle, centred on the axis, for every film point: a paraxial exit pupil.
    pub fn disc(z: f64, radius: f64) -> PupilSampling {
        PupilSampling {
            z,
            circles: PupilTable {
                max_film_radius: 0.0,
                circles: vec![PupilCircle {
                    centre_x: 0.0,
                    radius,
                }],
            },
        }
    }
}

/// Most a pupil circle may be widened for film points off the plane it was fitted on, as the
/// growth factor m of [`OffPlaneBound`] (the radius grows by at least 1 / (1 - m)): a sensor
/// tilted further is refused rather than sampled through a bound this loose.
pub const MAX_PUPIL_BOUND_GROWTH: f64 = 0.5;

/// A conservative pupil for film points off the plane the circles were fitted on.
///
/// A ray from a film point P off that plane is the same line as the ray from the point Q where
/// it crosses the plane, so its rear-plane point R lies in the circle of Q. Q moves from P's
/// projection by k |R - P| with k = |z_P - z_film| / (z_P - z_rear); the circles' centre
/// vector and radius are Lipschitz in Q (constant `lipschitz`, the interpolated table's largest
/// slopes, plus `centre_slack` = 2 |centre at radius 0|, which a fit leaves within rounding of
/// the axis), so with m = lipschitz k < 1 every passing R lies within
/// (radius(P) + m |centre(P) - P| + slack) / (1 - m) of P's own centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OffPlaneBound {
    pub lipschitz: f64,
    pub centre_slack: f64,
}

impl OffPlaneBound {
    /// The growth factor m for a film point at z `point_z`, the circles fitted on the plane
    /// `film_plane_z`, samples on the plane `pupil_z`.
    pub fn growth(&self, point_z: f64, film_plane_z: f64, pupil_z: f64) -> f64 {
        self.lipschitz * (point_z - film_plane_z).abs() / (point_z - pupil_z)
    }
}

impl PupilSampling {
    /// The off-plane bound of these circles (zero for a single circle: a paraxial exit pupil
    /// is the aperture itself, the same for every film point).
    pub fn off_plane_bound(&self) -> OffPlaneBound {
        let table = &self.circles;
        let n = table.circles.len();
        if n < 2 || table.max_film_radius <= 0.0 {
            return OffPlaneBound {
                lipschitz: 0.0,
                centre_slack: 0.0,
            };
        }
        let spacing = table.max_film_radius / (n - 1) as f64;
        let slope = |value: fn(&PupilCircle) -> f64| {
            table
                .circles
                .windows(2)
                .map(|w| (value(&w[1]) - value(&w[0])).abs() / spacing)
                .fold(0.0, f64::max)
        };
        OffPlaneBound {
            lipschitz: slope(|c| c.radius) + slope(|c| c.centre_x),
            centre_slack: 2.0 * table.circles[0].centre_x.abs(),
        }
    }

    /// The disc lens samples for `film` are drawn from, on the plane `self.z`: its centre
    /// (lens-frame x, y) and radius. `film_plane_z` is the plane the circles were fitted on;
    /// off it the circle grows by `bound` (see [`OffPlaneBound`]).
    pub fn disc_for(
        &self,
        bound: &OffPlaneBound,
        film: [f64; 3],
        film_plane_z: f64,
    ) -> ([f64; 2], f64) {
        let film_radius = film[0].hypot(film[1]);
        let azimuth = if film_radius > 0.0 {
            [film[0] / film_radius, film[1] / film_radius]
        } else {
            [1.0, 0.0]
        };
        let circle = self.circles.circle_at(film_radius);
        let centre = azimuth.map(|a| a * circle.centre_x);
        if film[2] == film_plane_z {
            return (centre, circle.radius);
        }
        let m = bound.growth(film[2], film_plane_z, self.z);
        let drift = (centre[0] - film[0]).hypot(centre[1] - film[1]);
        (
            centre,
            (circle.radius + m * drift + bound.centre_slack) / (1.0 - m),
        )
    }
}

/// Largest film radius on the plane `film_z` that the effective pupil must cover for a sensor
/// reaching `corner_radius` from the axis and `off_plane` mm off that plane: rays from its
/// points towards the rear search disc cross the plane within this radius (see
/// [`OffPlaneBound`]).
pub fn pupil_film_radius(
    system: &SystemAt,
    film_z: f64,
    corner_radius: f64,
    off_plane: f64,
) -> f64 {
    let depth = film_z - system.last_vertex_z();
    // A sensor reaching the rear plane is refused by `Camera::new`; the nearest film points
    // are the worst case, k = off / (depth - off).
    if off_plane <= 0.0 || off_plane >= depth {
        return corner_radius;
    }
    let k = off_plane / (depth - off_plane);
    corner_radius + k * (corner_radius + rear_search_radius(system))
}
