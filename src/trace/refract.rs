//! Snell's law in vector form.
//!
//! With unit incident direction `d`, unit normal `n` (either orientation) and `mu = n1 / n2`,
//! the refracted direction is `mu d + (s sqrt(1 - mu^2 (1 - (n.d)^2)) - mu (n.d)) n` where `s`
//! is the sign of `n.d`: the tangential component scales by `mu`, the normal component keeps its
//! side. A negative radicand is total internal reflection.

use super::Vec3;
use super::intersect::{clamped_sqrt, dot};

/// The normal of a plane surface, toward the object side: a plane's crossing carries none.
pub(crate) const PLANE_NORMAL: Vec3 = [0.0, 0.0, -1.0];

/// The direction `d` reflected off a surface of unit `normal` (either orientation).
#[inline(always)]
pub(crate) fn reflect(d: Vec3, normal: Vec3) -> Vec3 {
    let twice_cos = 2.0 * dot(d, normal);
    [
        (-twice_cos).mul_add(normal[0], d[0]),
        (-twice_cos).mul_add(normal[1], d[1]),
        (-twice_cos).mul_add(normal[2], d[2]),
    ]
}

/// Refracted unit direction, or None on total internal reflection.
#[inline(always)]
pub(crate) fn refract(d: Vec3, normal: Vec3, mu: f64) -> Option<Vec3> {
    let (out, radicand) = refract_candidate(d, normal, mu);
    (radicand >= 0.0).then_some(out)
}

/// [`refract`] without branches, for the lane kernels: the direction (meaningless when the
/// radicand is negative, total internal reflection) and the radicand.
#[inline(always)]
pub(crate) fn refract_candidate(d: Vec3, normal: Vec3, mu: f64) -> (Vec3, f64) {
    let (cos_signed, radicand) = refraction_radicand(d, normal, mu);
    (refracted(d, normal, mu, cos_signed, radicand), radicand)
}

/// The first stage of [`refract_candidate`] (no square root): the cosine `n.d` and the
/// radicand.
#[inline(always)]
pub(crate) fn refraction_radicand(d: Vec3, normal: Vec3, mu: f64) -> (f64, f64) {
    let cos_signed = dot(normal, d);
    let radicand = (-(mu * mu)).mul_add((-cos_signed).mul_add(cos_signed, 1.0), 1.0);
    (cos_signed, radicand)
}

/// The second stage of [`refract_candidate`]: the direction from the first stage's results.
#[inline(always)]
pub(crate) fn refracted(d: Vec3, normal: Vec3, mu: f64, cos_signed: f64, radicand: f64) -> Vec3 {
    refracted_given(d, normal, mu, cos_signed, clamped_sqrt(radicand))
}

/// [`refracted`] given the [`clamped_sqrt`] of the radicand.
#[inline(always)]
pub(crate) fn refracted_given(d: Vec3, normal: Vec3, mu: f64, cos_signed: f64, root: f64) -> Vec3 {
    let along = (-mu).mul_add(cos_signed, root.copysign(cos_signed));
    [
        along.mul_add(normal[0], mu * d[0]),
        along.mul_add(normal[1], mu * d[1]),
        along.mul_add(normal[2], mu * d[2]),
    ]
}

/// Refraction at a plane z = const, where the normal is the axis: the transverse components
/// scale by `mu` and z keeps its sign.
#[inline(always)]
pub(crate) fn refract_plane(d: Vec3, mu: f64) -> Option<Vec3> {
    let (out, radicand) = refract_plane_candidate(d, mu);
    (radicand >= 0.0).then_some(out)
}

/// [`refract_plane`] without branches: the direction and the radicand.
#[inline(always)]
pub(crate) fn refract_plane_candidate(d: Vec3, mu: f64) -> (Vec3, f64) {
    let (x, y) = (mu * d[0], mu * d[1]);
    let radicand = 1.0 - x.mul_add(x, y * y);
    ([x, y, clamped_sqrt(radicand).copysign(d[2])], radicand)
}

/// Deflection by an ideal thin lens of `power` (1/mm) met at transverse point `at`: the
/// direction tangents along the travel, t = (dx, dy) / |dz|, become t - power * at, and the ray
/// keeps its sense along z. The map is its own inverse under reversal (a reversed ray has
/// tangents -t' and leaves with -t' - power * at = -t), so forward and backward traces agree.
/// None when the tangents overflow (a ray grazing the plane): it leaves in no direction f64 holds.
#[inline(always)]
pub(crate) fn ideal_lens(d: Vec3, at: [f64; 2], power: f64) -> Option<Vec3> {
    let (direction, deflects) = ideal_lens_candidate(d, at, power);
    deflects.then_some(direction)
}

/// [`ideal_lens`] without branches, for the lane kernels: the direction (meaningless where the
/// tangents overflow) and whether they did not.
#[inline(always)]
pub(crate) fn ideal_lens_candidate(d: Vec3, at: [f64; 2], power: f64) -> (Vec3, bool) {
    let along = d[2].abs();
    let tx = (-power).mul_add(at[0], d[0] / along);
    let ty = (-power).mul_add(at[1], d[1] / along);
    let length = tx.mul_add(tx, ty.mul_add(ty, 1.0)).sqrt();
    (
        [tx / length, ty / length, (1.0 / length).copysign(d[2])],
        length.is_finite(),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cross(a: Vec3, b: Vec3) -> Vec3 {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    }

    fn unit(v: Vec3) -> Vec3 {
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        [v[0] / l, v[1] / l, v[2] / l]
    }

    #[test]
    fn snell_invariant_and_unit_length() {
        // n1 (d x N) = n2 (d' x N) for both normal orientations, and |d'| = 1.
        let (n1, n2) = (1.0, 1.7);
        let d = unit([0.1, -0.3, 1.0]);
        for normal in [unit([0.05, 0.2, -1.0]), unit([-0.05, -0.2, 1.0])] {
            let out = refract(d, normal, n1 / n2).unwrap();
            let (a, b) = (cross(d, normal), cross(out, normal));
            for k in 0..3 {
                assert!((n1 * a[k] - n2 * b[k]).abs() < 1e-15);
            }
            let len = out.iter().map(|v| v * v).sum::<f64>();
            assert!((len - 1.0).abs() < 1e-15);
            assert!(out[2] > 0.0, "stays on the far side");
        }
    }

    #[test]
    fn angle_of_refraction_matches_scalar_snell() {
        let theta: f64 = 0.6;
        let d = [theta.sin(), 0.0, theta.cos()];
        let out = refract(d, [0.0, 0.0, -1.0], 1.0 / 1.5).unwrap();
        let expected = (theta.sin() / 1.5).asin();
        assert!((out[0].atan2(out[2]) - expected).abs() < 1e-15);
        let flat = refract_plane(d, 1.0 / 1.5).unwrap();
        for k in 0..3 {
            assert!((flat[k] - out[k]).abs() < 1e-15);
        }
    }

    /// Rays from one point 150 mm before a lens of f = 100 mm, at any height and direction,
    /// meet again 300 mm behind it (1/150 + 1/300 = 1/100) at magnification -2; reversed, each
    /// ray returns along its own path.
    #[test]
    fn ideal_lens_images_a_point_perfectly_and_reverses() {
        let (object, power) = ([1.5, -2.0, -150.0], 0.01);
        for (x, y) in [(0.0, 0.0), (9.0, -3.0), (-20.0, 14.0), (35.0, 30.0)] {
            let d = unit([x - object[0], y - object[1], -object[2]]);
            let out = ideal_lens(d, [x, y], power).unwrap();
            let len = out.iter().map(|v| v * v).sum::<f64>();
            assert!((len - 1.0).abs() < 1e-15);
            let reach = 300.0 / out[2];
            let image = [x + reach * out[0], y + reach * out[1]];
            assert!((image[0] + 3.0).abs() < 1e-12 && (image[1] - 4.0).abs() < 1e-12);
            let back = ideal_lens([-out[0], -out[1], -out[2]], [x, y], power).unwrap();
            for k in 0..3 {
                assert!((back[k] + d[k]).abs() < 1e-15, "{back:?} vs {d:?}");
            }
        }
        // Grazing the plane: tangents of 1e300 square past f64.
        assert_eq!(ideal_lens([1.0, 0.0, 1e-300], [5.0, 0.0], power), None);
    }

    #[test]
    fn total_internal_reflection_beyond_critical_angle() {
        let critical = (1.0f64 / 1.5).asin();
        let above = critical + 1e-6;
        let below = critical - 1e-6;
        let dir = |a: f64| [a.sin(), 0.0, a.cos()];
        assert!(refract(dir(above), [0.0, 0.0, -1.0], 1.5).is_none());
        assert!(refract_plane(dir(above), 1.5).is_none());
        assert!(refract(dir(below), [0.0, 0.0, -1.0], 1.5).is_some());
    }
}
