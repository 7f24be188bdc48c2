//! The opening of a bladed diaphragm.
//!
//! `count` blades leave a regular polygon whose corners lie on the circle of the stop's
//! semi-aperture R; corner j sits at angle `rotation + j * 2 pi / count` from +x towards +y.
//! Each edge is an arc through its two corners, bulging outward with curvature
//! `blade_curvature / R`: 0 gives straight edges, 1 puts the edges on the circle itself.
//!
//! Containment: the edge whose outward direction (the bisector of its two corners) has the
//! largest projection on the point is the edge whose wedge holds the point. Inside that wedge
//! the opening is the part of the disk bounded by the edge's arc (a half-plane for a straight
//! edge), because the arc's circle passes through both corners and holds the centre.

use crate::prescription::StopShape;

/// A bladed diaphragm, precomputed for the containment test.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Diaphragm {
    /// Unit outward direction of each edge (the bisector of its corners).
    edges: Vec<[f64; 2]>,
    /// Distance from the axis to the middle of a straight edge, R cos(pi / count).
    apothem: f64,
    /// For curved edges: the arc's circle, as the (signed) distance of its centre along the edge
    /// direction and its squared radius.
    arc: Option<(f64, f64)>,
}

impl Diaphragm {
    /// The diaphragm for a stop shape of semi-aperture `radius`; None for a circular stop, whose
    /// test is the plain semi-aperture check every surface makes. A blade curvature outside
    /// [0, 1] is taken at the nearer end of that range.
    pub fn new(shape: &StopShape, radius: f64) -> Option<Diaphragm> {
        let StopShape::Blades {
            count,
            rotation_deg,
            blade_curvature,
        } = *shape
        else {
            return None;
        };
        let count = count.max(3);
        let half = std::f64::consts::PI / f64::from(count);
        let rotation = rotation_deg.to_radians();
        let edges = (0..count)
            .map(|j| {
                let angle = rotation + (2 * j + 1) as f64 * half;
                [angle.cos(), angle.sin()]
            })
            .collect();
        let apothem = radius * half.cos();
        let curvature = blade_curvature.clamp(0.0, 1.0) / radius;
        let arc = (curvature > 0.0).then(|| {
            let arc_radius = 1.0 / curvature;
            let half_chord = radius * half.sin();
            let centre = apothem - (arc_radius * arc_radius - half_chord * half_chord).sqrt();
            (centre, arc_radius * arc_radius)
        });
        Some(Diaphragm {
            edges,
            apothem,
            arc,
        })
    }

    /// For each point (x[k], y[k]), the edge whose wedge holds it (its outward direction's two
    /// components) and the point's projection on that direction. The edge loop runs outside the
    /// points' loop, so that a block's lanes are one vector each; one point is `N = 1`.
    #[inline(always)]
    fn nearest_edges<const N: usize>(
        &self,
        x: &[f64; N],
        y: &[f64; N],
    ) -> ([f64; N], [f64; N], [f64; N]) {
        let (mut best_x, mut best_y) = ([1.0; N], [0.0; N]);
        let mut along = [f64::NEG_INFINITY; N];
        for edge in &self.edges {
            for k in 0..N {
                let u = x[k] * edge[0] + y[k] * edge[1];
                let nearer = u > along[k];
                along[k] = if nearer { u } else { along[k] };
                best_x[k] = if nearer { edge[0] } else { best_x[k] };
                best_y[k] = if nearer { edge[1] } else { best_y[k] };
            }
        }
        (best_x, best_y, along)
    }

    /// The edge whose wedge holds (x, y) and the point's projection on its outward direction.
    fn nearest_edge(&self, x: f64, y: f64) -> ([f64; 2], f64) {
        let ([best_x], [best_y], [along]) = self.nearest_edges(&[x], &[y]);
        ([best_x, best_y], along)
    }

    /// How far inside the opening (x, y) lies (mm): positive inside, zero on the blade edges,
    /// negative outside. It is continuous across the wedges (neighbouring edges give the same
    /// value on the corner ray between them), so an interpolated margin places the edge.
    pub fn margin(&self, x: f64, y: f64) -> f64 {
        let (best, along) = self.nearest_edge(x, y);
        match self.arc {
            None => self.apothem - along,
            Some((centre, radius_sq)) => {
                let across = -x * best[1] + y * best[0];
                radius_sq.sqrt() - (along - centre).hypot(across)
            }
        }
    }

    /// Whether the point (x, y) of the stop plane passes the blades.
    pub fn contains(&self, x: f64, y: f64) -> bool {
        let [inside] = self.contains_each(&[x], &[y]);
        inside
    }

    /// [`Diaphragm::contains`] for each point (x[k], y[k]), without branches on the points.
    #[inline(always)]
    pub fn contains_each<const N: usize>(&self, x: &[f64; N], y: &[f64; N]) -> [bool; N] {
        let (best_x, best_y, along) = self.nearest_edges(x, y);
        // A plain loop: built by `array::from_fn`, the kernels that test blades called its
        // closure once per stride instead of inlining it.
        let mut inside = [false; N];
        for k in 0..N {
            inside[k] = match self.arc {
                None => along[k] <= self.apothem,
                Some((centre, radius_sq)) => {
                    let across = -x[k] * best_y[k] + y[k] * best_x[k];
                    let u = along[k] - centre;
                    u * u + across * across <= radius_sq
                }
            };
        }
        inside
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn blades(count: u32, rotation_deg: f64, blade_curvature: f64) -> Diaphragm {
        Diaphragm::new(
            &StopShape::Blades {
                count,
                rotation_deg,
                blade_curvature,
            },
            10.0,
        )
        .unwrap()
    }

    /// Area by counting a fine grid of cell centres over the bounding square.
    fn grid_area(d: &Diaphragm) -> f64 {
        let n = 1000;
        let cell = 20.0 / n as f64;
        let mut inside = 0usize;
        for i in 0..n {
            for j in 0..n {
                let x = -10.0 + (i as f64 + 0.5) * cell;
                let y = -10.0 + (j as f64 + 0.5) * cell;
                inside += usize::from(d.contains(x, y));
            }
        }
        inside as f64 * cell * cell
    }

    /// Polygon area plus the circular segments the arcs add.
    fn analytic_area(count: u32, blade_curvature: f64) -> f64 {
        let r = 10.0;
        let n = f64::from(count);
        let polygon = 0.5 * n * r * r * (2.0 * PI / n).sin();
        if blade_curvature == 0.0 {
            return polygon;
        }
        let rho = r / blade_curvature;
        let half_chord = r * (PI / n).sin();
        let angle = 2.0 * (half_chord / rho).asin();
        polygon + n * 0.5 * rho * rho * (angle - angle.sin())
    }

    #[test]
    fn area_matches_polygon_plus_segments() {
        // Grid cells of 0.02 mm: the boundary error is about perimeter * cell / 4 ~ 0.3 mm^2
        // at worst; the check allows 0.5 mm^2, far below the 13 mm^2 a blade-count or
        // curvature mistake would change.
        for (count, curvature) in [(5, 0.0), (6, 0.0), (6, 0.5), (9, 0.3), (7, 1.0)] {
            let d = blades(count, 17.0, curvature);
            let (grid, exact) = (grid_area(&d), analytic_area(count, curvature));
            assert!(
                (grid - exact).abs() < 0.5,
                "{count} blades, {curvature}: {grid} vs {exact}"
            );
        }
        assert!((analytic_area(7, 1.0) - PI * 100.0).abs() < 1e-9);
    }

    #[test]
    fn corners_and_edges_where_expected() {
        // Hexagon with a corner on +x: the corner is inside, just beyond it is not; the middle of
        // the edge between the corners at 0 and 60 degrees sits at the apothem.
        let d = blades(6, 0.0, 0.0);
        assert!(d.contains(10.0 - 1e-9, 0.0));
        assert!(!d.contains(10.0 + 1e-9, 0.0));
        let apothem = 10.0 * (PI / 6.0).cos();
        let mid = PI / 6.0;
        assert!(d.contains((apothem - 1e-9) * mid.cos(), (apothem - 1e-9) * mid.sin()));
        assert!(!d.contains((apothem + 1e-9) * mid.cos(), (apothem + 1e-9) * mid.sin()));
        // Rotating by 30 degrees puts an edge middle on +x and a corner at 30 degrees.
        let rotated = blades(6, 30.0, 0.0);
        assert!(!rotated.contains(apothem + 1e-9, 0.0));
        assert!(rotated.contains(apothem - 1e-9, 0.0));
        assert!(rotated.contains((10.0 - 1e-9) * mid.cos(), (10.0 - 1e-9) * mid.sin()));
    }

    #[test]
    fn full_curvature_is_the_circle() {
        let d = blades(5, 12.0, 1.0);
        for k in 0..360 {
            let a = (k as f64).to_radians();
            assert!(d.contains(9.999_999 * a.cos(), 9.999_999 * a.sin()));
            assert!(!d.contains(10.000_001 * a.cos(), 10.000_001 * a.sin()));
        }
    }

    #[test]
    fn margin_is_positive_inside_zero_on_the_edge_and_continuous() {
        for (count, curvature) in [(6, 0.0), (5, 0.4), (9, 1.0)] {
            let d = blades(count, 17.0, curvature);
            // Its sign is the containment test wherever the point is not on the edge itself.
            let n = 200;
            for i in 0..n {
                for j in 0..n {
                    let (x, y) = (
                        -11.0 + 22.0 * i as f64 / n as f64,
                        -11.0 + 22.0 * j as f64 / n as f64,
                    );
                    let m = d.margin(x, y);
                    if m.abs() > 1e-9 {
                        assert_eq!(m > 0.0, d.contains(x, y), "{count} {curvature} ({x}, {y})");
                    }
                }
            }
            // Around a circle the margin changes by no more than the distance moved (it is a
            // 1-Lipschitz distance along the wedge's normal or to the arc's centre), also where
            // the nearest edge switches.
            let steps = 20_000;
            let step = 2.0 * PI * 8.0 / steps as f64;
            let at = |k: usize| {
                let a = 2.0 * PI * k as f64 / steps as f64;
                d.margin(8.0 * a.cos(), 8.0 * a.sin())
            };
            for k in 0..steps {
                assert!(
                    (at(k + 1) - at(k)).abs() <= step * (1.0 + 1e-9),
                    "{count} {curvature} {k}"
                );
            }
        }
        // A straight edge: the margin is the distance to it along its normal.
        let d = blades(6, 30.0, 0.0);
        let apothem = 10.0 * (PI / 6.0).cos();
        assert!((d.margin(apothem - 0.25, 0.0) - 0.25).abs() < 1e-12);
        assert!((d.margin(apothem + 0.5, 0.0) + 0.5).abs() < 1e-12);
    }

    #[test]
    fn circle_needs_no_diaphragm() {
        assert!(Diaphragm::new(&StopShape::Circle, 5.0).is_none());
    }
}
