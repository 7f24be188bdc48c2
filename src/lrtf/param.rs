//! The two ray parameterisations: how a film-side ray becomes three table coordinates in \[0, 1\]^3
//! (after factoring out the rotation about the axis and the mirror about the meridional plane),
//! and how the four stored values become the outgoing ray.
//!
//! Both work in the *canonical frame*: the frame rotated about z so that a reference point lies
//! on +x, and mirrored so that the remaining transverse coordinate is non-negative.

use serde::{Deserialize, Serialize};

use crate::pupil::{PupilCircle, PupilTable};

/// How rays are turned into table coordinates and values.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum Parameterisation {
    /// Seed 000's baseline: radius on the rear vertex plane plus the polar and azimuthal angles
    /// of the direction; output direction also as polar/azimuthal angles. The polar axis is a
    /// coordinate singularity (azimuth undefined there), right at the image centre.
    Spherical,
    /// Two planes: the film point (radius, the canonical frame puts it on +x) and the rear-plane
    /// point normalised to the effective-pupil circle of that film radius; output direction by
    /// stereographic projection. No singular point, and every texel lies in or near the pupil.
    PupilPlanes,
}

/// `LrtfParams::parameterisation` codes of the shader (`Parameterisation::shader_id`).
pub const PARAMETERISATION_SPHERICAL: u32 = 0;
pub const PARAMETERISATION_PUPIL_PLANES: u32 = 1;

impl Parameterisation {
    /// Bumped whenever coordinates or stored values change meaning; stored in the sidecar.
    pub fn version(self) -> u32 {
        match self {
            Parameterisation::Spherical => 1,
            Parameterisation::PupilPlanes => 1,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Parameterisation::Spherical => "spherical",
            Parameterisation::PupilPlanes => "pupil-planes",
        }
    }

    pub fn from_name(name: &str) -> Option<Parameterisation> {
        [Parameterisation::Spherical, Parameterisation::PupilPlanes]
            .into_iter()
            .find(|p| p.name() == name)
    }

    /// Shader constant selecting this parameterisation in `lrtf_sample.wgsl`.
    pub fn shader_id(self) -> u32 {
        match self {
            Parameterisation::Spherical => PARAMETERISATION_SPHERICAL,
            Parameterisation::PupilPlanes => PARAMETERISATION_PUPIL_PLANES,
        }
    }
}

/// The planes and ranges that fix the table coordinates of one wavelength's table (mm, radians).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Frame {
    /// z of the rear vertex plane (the last surface's vertex) in the lens frame.
    pub rear_plane_z: f64,
    /// z of the film plane the table was baked for.
    pub film_plane_z: f64,
    /// Largest film radius covered.
    pub max_film_radius: f64,
    /// Spherical only: largest rear-plane radius covered.
    pub max_rear_radius: f64,
    /// Spherical only: largest polar angle of the direction (from -z).
    pub max_polar_angle: f64,
}

/// Where a film-side ray lands in a table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Located {
    /// Table coordinates; inside \[0, 1\]^3 when `in_domain`.
    pub coords: [f64; 3],
    /// cos and sin of the rotation from the canonical frame back to the lens frame.
    pub rotation: [f64; 2],
    /// -1 when the canonical frame is mirrored (y -> -y), else +1.
    pub mirror: f64,
    pub in_domain: bool,
}

impl Located {
    /// A placeholder for a ray that lands nowhere in the table.
    pub(crate) const NOWHERE: Located = Located {
        coords: [2.0; 3],
        rotation: [1.0, 0.0],
        mirror: 1.0,
        in_domain: false,
    };
}

/// The sampler's ray in the lens frame (mm), direction unit length: plain fields, unchecked,
/// for the renderer's inner loops. Everywhere else the crate's ray is [`crate::Ray`] (checked
/// finite, direction normalised), which converts into this one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    pub origin: [f64; 3],
    pub direction: [f64; 3],
}

impl From<crate::trace::Ray> for Ray {
    fn from(ray: crate::trace::Ray) -> Ray {
        Ray {
            origin: ray.position(),
            direction: ray.direction(),
        }
    }
}

/// The exact values one table entry stores, in the canonical frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Transfer {
    /// Where the ray leaves surface 1 (mm).
    pub exit_point: [f64; 3],
    /// Unit direction of the outgoing ray (travelling -z, into object space).
    pub exit_direction: [f64; 3],
    /// Where the ray crosses the stop surface (x, y, mm).
    pub stop_point: [f64; 2],
}

/// Number of stored channels per entry: exit x, exit y, direction (2), aperture margin, stop x,
/// stop y, exit z. Laid out as two RGBA textures (see docs/lrtf.md).
pub const CHANNELS: usize = 8;

/// Channel names in the EXR file, in storage order.
pub const CHANNEL_NAMES: [&str; CHANNELS] = [
    "exit.x", "exit.y", "dir.a", "dir.b", "margin", "stop.x", "stop.y", "exit.z",
];

/// Index of the aperture-margin channel: the ray passes every aperture the stop-crossing test
/// does not cover where it is >= 0.
pub const MARGIN: usize = 4;

#[inline(always)]
fn rotate(v: [f64; 2], c: f64, s: f64) -> [f64; 2] {
    [c * v[0] - s * v[1], s * v[0] + c * v[1]]
}

/// Stereographic projection from the +z pole: any direction except exactly +z maps into the
/// plane, directions with dz <= 0 into the unit disk; smooth through the axis (-z -> origin).
#[inline(always)]
pub fn stereographic(d: [f64; 3]) -> [f64; 2] {
    let k = 1.0 / (1.0 - d[2]);
    [d[0] * k, d[1] * k]
}

#[inline(always)]
pub fn inverse_stereographic(s: [f64; 2]) -> [f64; 3] {
    let m = s[0] * s[0] + s[1] * s[1];
    let k = 1.0 / (1.0 + m);
    [2.0 * s[0] * k, 2.0 * s[1] * k, -(1.0 - m) * k]
}

#[inline(always)]
fn normalise(v: [f64; 3]) -> [f64; 3] {
    let per_length = 1.0 / (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
    v.map(|value| value * per_length)
}

/// Point where `ray` crosses the plane z = `z`, if it travels towards it (rays here travel -z).
#[inline(always)]
fn crossing(ray: &Ray, z: f64) -> Option<[f64; 2]> {
    let away = ray.direction[2] >= 0.0;
    (!away).then(|| crossing_of_plane(ray, z, 1.0 / ray.direction[2]))
}

/// Where the line of `ray` crosses the plane z = `z`, whichever way it travels, given
/// `per_z`, the reciprocal of the direction's z.
#[inline(always)]
fn crossing_of_plane(ray: &Ray, z: f64, per_z: f64) -> [f64; 2] {
    let t = (z - ray.origin[2]) * per_z;
    [
        ray.origin[0] + t * ray.direction[0],
        ray.origin[1] + t * ray.direction[1],
    ]
}

/// Distance of `p` from the axis and the canonical rotation (cos, sin) putting it on +x; the x
/// axis itself when p is the origin. The distance is the shader's `length`, sqrt(x^2 + y^2):
/// within an ulp of `hypot`, whose libm call cost 4 % of a baked frame on the CPU twin. It
/// overflows only 1e154 mm off axis (outside the domain either way) and underflows only within
/// 1e-154 mm of it (where any rotation serves).
#[inline(always)]
fn polar_of(p: [f64; 2]) -> (f64, [f64; 2]) {
    let r = (p[0] * p[0] + p[1] * p[1]).sqrt();
    let per_r = 1.0 / r;
    let rotation = if r > 0.0 {
        [p[0] * per_r, p[1] * per_r]
    } else {
        [1.0, 0.0]
    };
    (r, rotation)
}

/// Whether all three coordinates lie in \[0, 1\] (NaN does not); every test is made, so a
/// group's lanes make them side by side.
#[inline(always)]
fn in_unit(c: [f64; 3]) -> bool {
    (0.0..=1.0).contains(&c[0]) & (0.0..=1.0).contains(&c[1]) & (0.0..=1.0).contains(&c[2])
}

/// The distance from the axis at which a film-side ray crosses the film plane of `frame`: what
/// picks its circle of the coordinate pupil.
#[inline(always)]
pub(crate) fn film_radius_of(frame: &Frame, ray: &Ray) -> f64 {
    polar_of(crossing_of_plane(
        ray,
        frame.film_plane_z,
        1.0 / ray.direction[2],
    ))
    .0
}

/// Where a film-side ray lands in the pupil-planes coordinates of `frame`, given the
/// coordinate pupil's circle at its [`film_radius_of`] (`circle_at`), without branches (a
/// lookup's lanes run it side by side), and whether the ray reaches the planes at all (it
/// travels -z). Where it does not, the location is meaningless.
#[inline(always)]
pub(crate) fn locate_pupil_planes(
    frame: &Frame,
    circle_at: impl FnOnce(f64) -> PupilCircle,
    ray: &Ray,
) -> (Located, bool) {
    // Along the plane or away from it, never there (a NaN direction goes on, as one at a time).
    let away = ray.direction[2] >= 0.0;
    let reaches = !away;
    // One division for both crossings: the one divider takes about as long per lane as nine
    // multiplies take the two multiply pipes (`cargo bench --bench roofline`).
    let per_z = 1.0 / ray.direction[2];
    let rear = crossing_of_plane(ray, frame.rear_plane_z, per_z);
    let film = crossing_of_plane(ray, frame.film_plane_z, per_z);
    let (film_radius, [c, s]) = polar_of(film);
    let q = rotate(rear, c, -s);
    let mirror = if q[1] < 0.0 { -1.0 } else { 1.0 };
    let circle = circle_at(film_radius);
    let open = circle.radius > 0.0;
    let radial = film_radius / frame.max_film_radius;
    let per_radius = 1.0 / circle.radius;
    let across = 0.5 * ((q[0] - circle.centre_x) * per_radius + 1.0);
    let up = q[1] * mirror * per_radius;
    // A closed circle (no ray passes) gives coordinates outside the unit cube.
    let coords = [
        radial,
        if open { across } else { 2.0 },
        if open { up } else { 2.0 },
    ];
    let located = Located {
        coords,
        rotation: [c, s],
        mirror,
        in_domain: open & in_unit(coords),
    };
    (located, reaches)
}

impl Parameterisation {
    /// Table coordinates of a film-side ray travelling -z; None if it never reaches the planes.
    /// Only the ray's line and sense count: its direction need not be unit.
    #[inline(always)]
    pub fn locate(self, frame: &Frame, pupil: &PupilTable, ray: &Ray) -> Option<Located> {
        match self {
            Parameterisation::Spherical => {
                let rear = crossing(ray, frame.rear_plane_z)?;
                let (rear_radius, [c, s]) = polar_of(rear);
                let d = rotate([ray.direction[0], ray.direction[1]], c, -s);
                let mirror = if d[1] < 0.0 { -1.0 } else { 1.0 };
                let polar = (-normalise(ray.direction)[2]).clamp(-1.0, 1.0).acos();
                let azimuth = (d[1] * mirror).atan2(d[0]);
                let coords = [
                    rear_radius / frame.max_rear_radius,
                    polar / frame.max_polar_angle,
                    azimuth / std::f64::consts::PI,
                ];
                Some(Located {
                    coords,
                    rotation: [c, s],
                    mirror,
                    in_domain: in_unit(coords),
                })
            }
            Parameterisation::PupilPlanes => {
                let (located, reaches) =
                    locate_pupil_planes(frame, |r| pupil.interpolation().at(r), ray);
                reaches.then_some(located)
            }
        }
    }

    /// The film-side ray (canonical frame, origin on the film plane) at table coordinates.
    pub fn ray_at(self, frame: &Frame, pupil: &PupilTable, coords: [f64; 3]) -> Ray {
        let depth = frame.film_plane_z - frame.rear_plane_z;
        match self {
            Parameterisation::Spherical => {
                let rho = coords[0] * frame.max_rear_radius;
                let polar = coords[1] * frame.max_polar_angle;
                let azimuth = coords[2] * std::f64::consts::PI;
                let direction = [
                    polar.sin() * azimuth.cos(),
                    polar.sin() * azimuth.sin(),
                    -polar.cos(),
                ];
                // Start on the film plane so the trace meets the rear surface wherever it bulges.
                let t = depth / -direction[2];
                Ray {
                    origin: [
                        rho - t * direction[0],
                        -t * direction[1],
                        frame.film_plane_z,
                    ],
                    direction,
                }
            }
            Parameterisation::PupilPlanes => {
                let film_radius = coords[0] * frame.max_film_radius;
                let circle = pupil.circle_at(film_radius);
                let rear = [
                    circle.centre_x + circle.radius * (2.0 * coords[1] - 1.0),
                    circle.radius * coords[2],
                ];
                let origin = [film_radius, 0.0, frame.film_plane_z];
                Ray {
                    origin,
                    direction: normalise([rear[0] - film_radius, rear[1], -depth]),
                }
            }
        }
    }

    /// The two stored direction values of a unit direction (canonical frame).
    pub fn encode_direction(self, d: [f64; 3]) -> [f64; 2] {
        match self {
            Parameterisation::Spherical => [(-d[2]).clamp(-1.0, 1.0).acos(), d[1].atan2(d[0])],
            Parameterisation::PupilPlanes => stereographic(d),
        }
    }

    #[inline(always)]
    pub fn decode_direction(self, e: [f64; 2]) -> [f64; 3] {
        match self {
            Parameterisation::Spherical => [
                e[0].sin() * e[1].cos(),
                e[0].sin() * e[1].sin(),
                -e[0].cos(),
            ],
            Parameterisation::PupilPlanes => normalise(inverse_stereographic(e)),
        }
    }

    /// The stored channels of one exact transfer with its aperture margin.
    pub fn encode(self, transfer: &Transfer, margin: f64) -> [f64; CHANNELS] {
        let e = self.encode_direction(transfer.exit_direction);
        [
            transfer.exit_point[0],
            transfer.exit_point[1],
            e[0],
            e[1],
            margin,
            transfer.stop_point[0],
            transfer.stop_point[1],
            transfer.exit_point[2],
        ]
    }
}

/// Undoes the canonical frame: mirror, then rotate, for a transverse vector.
#[inline(always)]
pub fn to_lens_frame(v: [f64; 2], at: &Located) -> [f64; 2] {
    rotate([v[0], v[1] * at.mirror], at.rotation[0], at.rotation[1])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::pupil::PupilCircle;

    fn frame() -> Frame {
        Frame {
            rear_plane_z: 60.0,
            film_plane_z: 100.0,
            max_film_radius: 20.0,
            max_rear_radius: 15.0,
            max_polar_angle: 0.8,
        }
    }

    fn pupil() -> PupilTable {
        PupilTable {
            max_film_radius: 20.0,
            circles: vec![
                PupilCircle {
                    centre_x: 0.0,
                    radius: 10.0,
                },
                PupilCircle {
                    centre_x: -3.0,
                    radius: 7.0,
                },
            ],
        }
    }

    #[test]
    fn located_coordinates_round_trip_through_ray_at() {
        for p in [Parameterisation::Spherical, Parameterisation::PupilPlanes] {
            for coords in [[0.3, 0.2, 0.7], [0.9, 0.55, 0.1], [0.05, 0.5, 0.99]] {
                let ray = p.ray_at(&frame(), &pupil(), coords);
                let at = p.locate(&frame(), &pupil(), &ray).unwrap();
                for k in 0..3 {
                    assert!(
                        (at.coords[k] - coords[k]).abs() < 1e-12,
                        "{p:?} {coords:?} {at:?}"
                    );
                }
                assert!(at.in_domain);
            }
        }
    }

    #[test]
    fn stereographic_round_trips_and_is_smooth_through_the_axis() {
        for d in [
            [0.0, 0.0, -1.0],
            [0.3, -0.2, -0.9],
            [0.99, 0.0, -0.1],
            [0.6, 0.0, 0.8],
        ] {
            let d = normalise(d);
            let back = inverse_stereographic(stereographic(d));
            for k in 0..3 {
                assert!((back[k] - d[k]).abs() < 1e-14);
            }
        }
        assert_eq!(stereographic([0.0, 0.0, -1.0]), [0.0, 0.0]);
    }
}
