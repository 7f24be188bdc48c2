//! Seed 004's generalized focal surface (section 5.2): focus set per pixel by moving least squares
//! through several focus points, each holding the distance to be sharp at its pixel.
//!
//! The surface is the constant-basis moving-least-squares fit: at pixel p it minimises
//! sum_i w_i(p) (v - v_i)^2 over v, which gives v(p) = sum_i w_i v_i / sum_i w_i with the seed's
//! weights w_i = alpha_i / d_i^beta (d_i the screen distance from p to point i in output
//! pixels). As d_i -> 0 the weight of point i dominates, so the surface passes exactly through
//! each point (the singularity is handled by returning the point's own value there), and with
//! beta > 1 it is flat around each point, so a small region about each point is in its focus.
//! A larger beta narrows each point's region; the seed finds 2 to 4 useful.
//!
//! The value interpolated is the focus vergence 1/distance (dioptres, here 1/mm), not the
//! distance: the film position is linear in vergence to first order (Newton's form of the lens
//! equation), so blending vergences blends where the sensor would have to be, and a point at
//! infinity is the finite value 0.
//!
//! A defocus point (seed 004: "focus points that indicate out-of-focus regions") is a focus
//! point whose distance is deliberately off the scene's depth there; [`FocusPoint::defocused`]
//! makes one from the scene depth and an offset in dioptres.
//!
//! How a camera applies the surface is [`super::camera::Camera::with_focal_surface`].

use super::RenderError;

/// Most focus points a surface takes (each costs every pixel one weight).
pub const MAX_FOCUS_POINTS: usize = 64;
/// The falloff exponents accepted: below 1 a point's pull spreads over the whole frame (the
/// surface is no longer flat about a point), above 8 it becomes a set of steps.
pub const BETA_RANGE: [f64; 2] = [1.0, 8.0];
/// The seed's default falloff (its range is 2 to 4).
pub const DEFAULT_BETA: f64 = 3.0;

/// One focus point: the output pixel it sits on and the object distance to be sharp there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FocusPoint {
    /// Output-pixel coordinates (x right, y down, a pixel's centre at +0.5).
    pub pixel: [f64; 2],
    /// Object distance in focus at the point (mm in front of the first vertex; infinite for
    /// infinity).
    pub distance_mm: f64,
    /// Importance alpha: how strongly the point pulls the surface against the others (> 0).
    pub weight: f64,
}

impl FocusPoint {
    /// A point that focuses `dioptres` nearer than `scene_depth_mm` (negative: further), which
    /// blurs what lies there: 1/distance = 1/depth + dioptres / 1000 (dioptres are 1/m).
    /// Refused when the offset puts the focus past infinity.
    ///
    /// ```
    /// use lensbake::render::focal_surface::FocusPoint;
    /// let point = FocusPoint::defocused([10.0, 20.0], 2000.0, 0.5, 1.0).unwrap();
    /// assert!((point.distance_mm - 1000.0).abs() < 1e-9);
    /// assert!(FocusPoint::defocused([0.0, 0.0], 2000.0, -0.6, 1.0).is_err());
    /// ```
    pub fn defocused(
        pixel: [f64; 2],
        scene_depth_mm: f64,
        dioptres: f64,
        weight: f64,
    ) -> Result<FocusPoint, RenderError> {
        let vergence = 1.0 / scene_depth_mm + dioptres / 1000.0;
        if !(vergence.is_finite() && vergence >= 0.0) {
            return Err(RenderError::InvalidSetting(format!(
                "a defocus of {dioptres} dioptres from the surface {scene_depth_mm:.1} mm away \
                 focuses beyond infinity"
            )));
        }
        Ok(FocusPoint {
            pixel,
            distance_mm: 1.0 / vergence,
            weight,
        })
    }
}

/// A focal surface: focus points and the falloff exponent beta of their weights.
#[derive(Clone, Debug, PartialEq)]
pub struct FocalSurface {
    points: Vec<FocusPoint>,
    beta: f64,
}

impl FocalSurface {
    /// The surface through `points` with falloff `beta` (see the module). Refuses no points,
    /// more than [`MAX_FOCUS_POINTS`], a distance that is not positive, a weight that is not
    /// positive and finite, and a beta outside [`BETA_RANGE`].
    ///
    /// ```
    /// use lensbake::render::focal_surface::{FocalSurface, FocusPoint};
    /// let point = |x: f64, mm: f64| FocusPoint { pixel: [x, 50.0], distance_mm: mm, weight: 1.0 };
    /// let surface = FocalSurface::new(vec![point(0.0, 1000.0), point(100.0, 4000.0)], 3.0).unwrap();
    /// // Through each point exactly; halfway, the mean vergence (1/1000 + 1/4000) / 2.
    /// assert_eq!(surface.distance_at([0.0, 50.0]), 1000.0);
    /// assert!((surface.distance_at([50.0, 50.0]) - 1600.0).abs() < 1e-9);
    /// ```
    pub fn new(points: Vec<FocusPoint>, beta: f64) -> Result<FocalSurface, RenderError> {
        let invalid = |text: String| Err(RenderError::InvalidSetting(text));
        if points.is_empty() || points.len() > MAX_FOCUS_POINTS {
            return invalid(format!(
                "a focal surface takes 1 to {MAX_FOCUS_POINTS} focus points, got {}",
                points.len()
            ));
        }
        let [low, high] = BETA_RANGE;
        if !(beta >= low && beta <= high) {
            return invalid(format!(
                "the focal surface's falloff beta must lie in {low}..{high}, got {beta}"
            ));
        }
        for (i, p) in points.iter().enumerate() {
            let n = i + 1;
            if !p.pixel.iter().all(|v| v.is_finite()) {
                return invalid(format!("focus point {n}: its pixel is not a number"));
            }
            if !(p.distance_mm > 0.0) {
                return invalid(format!(
                    "focus point {n}: the distance must be positive mm, got {}",
                    p.distance_mm
                ));
            }
            if !(p.weight.is_finite() && p.weight > 0.0) {
                return invalid(format!(
                    "focus point {n}: the weight must be positive, got {}",
                    p.weight
                ));
            }
        }
        Ok(FocalSurface { points, beta })
    }

    pub fn points(&self) -> &[FocusPoint] {
        &self.points
    }

    pub fn beta(&self) -> f64 {
        self.beta
    }

    /// The focus vergence (1/mm, 0 at infinity) at output-pixel coordinates `pixel`.
    pub fn vergence_at(&self, pixel: [f64; 2]) -> f64 {
        let (mut weighted, mut total) = (0.0, 0.0);
        for p in &self.points {
            let d2 = (pixel[0] - p.pixel[0]).powi(2) + (pixel[1] - p.pixel[1]).powi(2);
            let vergence = 1.0 / p.distance_mm;
            if d2 == 0.0 {
                return vergence;
            }
            let w = p.weight / d2.powf(0.5 * self.beta);
            weighted += w * vergence;
            total += w;
        }
        weighted / total
    }

    /// The object distance in focus (mm, infinite at vergence 0) at `pixel`.
    pub fn distance_at(&self, pixel: [f64; 2]) -> f64 {
        1.0 / self.vergence_at(pixel)
    }

    /// The nearest and furthest vergences the surface takes anywhere: those of its points, as
    /// every value is a weighted mean of theirs.
    pub fn vergence_range(&self) -> [f64; 2] {
        self.points
            .iter()
            .fold([f64::INFINITY, 0.0], |[low, high], p| {
                let v = 1.0 / p.distance_mm;
                [low.min(v), high.max(v)]
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(pixel: [f64; 2], distance_mm: f64, weight: f64) -> FocusPoint {
        FocusPoint {
            pixel,
            distance_mm,
            weight,
        }
    }

    fn three() -> FocalSurface {
        FocalSurface::new(
            vec![
                point([10.0, 10.0], 1000.0, 1.0),
                point([90.0, 20.0], 2000.0, 1.0),
                point([50.0, 70.0], 6000.0, 1.0),
            ],
            3.0,
        )
        .unwrap()
    }

    #[test]
    fn the_surface_interpolates_its_points_and_stays_within_their_range() {
        let surface = three();
        for p in surface.points() {
            assert_eq!(surface.distance_at(p.pixel), p.distance_mm);
        }
        let [low, high] = surface.vergence_range();
        for x in 0..20 {
            for y in 0..16 {
                let v = surface.vergence_at([x as f64 * 5.3, y as f64 * 5.1]);
                assert!(v >= low * (1.0 - 1e-12) && v <= high * (1.0 + 1e-12), "{v}");
            }
        }
    }

    #[test]
    fn with_beta_above_one_the_surface_is_flat_about_each_point() {
        // The change of vergence one pixel from a point, against the change over the same pixel
        // halfway to the next point: beta 3 makes the first a small fraction of the second.
        let surface = three();
        let at = |x: f64, y: f64| surface.vergence_at([x, y]);
        let near = (at(11.0, 10.0) - at(10.0, 10.0)).abs();
        let between = (at(51.0, 15.0) - at(50.0, 15.0)).abs();
        assert!(near < 0.05 * between, "{near} against {between}");
        // A heavier point pulls the middle towards its own value.
        let mut heavy = surface.points().to_vec();
        heavy[0].weight = 10.0;
        let heavy = FocalSurface::new(heavy, 3.0).unwrap();
        let middle = [50.0, 33.0];
        let first = 1.0 / 1000.0;
        assert!(
            (heavy.vergence_at(middle) - first).abs() < (surface.vergence_at(middle) - first).abs()
        );
    }

    #[test]
    fn bad_surfaces_are_refused_with_what_is_wrong() {
        let ok = point([0.0, 0.0], 1000.0, 1.0);
        let cases = [
            (vec![], 3.0, "1 to 64"),
            (vec![ok], 0.5, "beta"),
            (vec![ok], f64::NAN, "beta"),
            (vec![ok, point([1.0, 1.0], -5.0, 1.0)], 3.0, "focus point 2"),
            (vec![point([1.0, 1.0], 500.0, 0.0)], 3.0, "weight"),
            (vec![point([f64::NAN, 1.0], 500.0, 1.0)], 3.0, "pixel"),
        ];
        for (points, beta, want) in cases {
            let err = FocalSurface::new(points, beta).unwrap_err().to_string();
            assert!(err.contains(want), "{err}");
        }
    }
}
