//! Invariants over random lenses (proptest): the trace is reversible, the Lagrange invariant is
//! the same at every surface, the real-ray EFL converges to the paraxial EFL as h^2, the pupil
//! sampling density integrates to one, and no random ray in a random valid lens yields NaN.
//!
//! Random lenses: 2 to 6 spherical (or plane) surfaces, |R| 15-200 mm, gaps 3-15 mm, each gap
//! air or glass of index 1.45-1.95, clear semi-aperture 4-10 mm (below 0.9 |R|), one of the
//! surfaces the stop, air behind; only prescriptions that pass validation are used.

use lensbake::lrtf::bake::{BakeRequest, bake};
use lensbake::paraxial::{Aperture, Field, FirstOrder, ObjectPosition, Paraxial, ParaxialOptions};
use lensbake::prescription::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
use lensbake::pupil::{PupilCircle, PupilTable};
use lensbake::system::LensSystem;
use lensbake::trace::{Apertures, Outcome, Ray, Tracer, Travel, Vec3};
use proptest::prelude::*;
use proptest::test_runner::RngSeed;

const WAVELENGTH_NM: f64 = 587.56;

/// One surface of a random lens: radius (infinite = plane), gap after it, glass index after it
/// (None = air).
type SurfaceSpec = (f64, f64, Option<f64>);

fn surface_spec() -> impl Strategy<Value = SurfaceSpec> {
    let radius = prop_oneof![
        1 => Just(f64::INFINITY),
        6 => (15.0..200.0f64, any::<bool>()).prop_map(|(r, negative)| if negative { -r } else { r }),
    ];
    let medium = prop_oneof![Just(None), (1.45..1.95f64).prop_map(Some)];
    (radius, 3.0..15.0f64, medium)
}

fn build_lens(specs: &[SurfaceSpec], stop: usize, semi: f64, back: f64) -> Option<LensSystem> {
    let last = specs.len() - 1;
    let surfaces = specs
        .iter()
        .enumerate()
        .map(|(i, &(radius, gap, glass))| Surface {
            shape: Shape::from_radius(radius),
            thickness: if i == last { back } else { gap },
            medium: match glass {
                Some(n) if i != last => Medium::Index(n),
                _ => Medium::Air,
            },
            semi_aperture: semi.min(0.9 * radius.abs()),
            stop: (i == stop).then_some(StopShape::Circle),
            obscuration: None,
        })
        .collect();
    LensSystem::from_prescription(Prescription {
        provenance: Provenance {
            title: "random lens".into(),
            ..Provenance::default()
        },
        object_medium: Medium::Air,
        surfaces,
    })
    .ok()
}

/// A random lens that passes validation.
fn lens() -> impl Strategy<Value = LensSystem> {
    (2usize..=6)
        .prop_flat_map(|count| {
            (
                prop::collection::vec(surface_spec(), count),
                0..count,
                4.0..10.0f64,
                20.0..80.0f64,
            )
        })
        .prop_filter_map("valid prescription", |(specs, stop, semi, back)| {
            build_lens(&specs, stop, semi, back)
        })
}

fn tracer(system: &LensSystem) -> Tracer {
    Tracer::new(&system.at(WAVELENGTH_NM))
}

fn length(v: Vec3) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn distance(a: Vec3, b: Vec3) -> f64 {
    length([a[0] - b[0], a[1] - b[1], a[2] - b[2]])
}

/// A fixed seed keeps CI runs identical; failures print the minimal case.
fn config(cases: u32, seed: u64) -> ProptestConfig {
    ProptestConfig {
        cases,
        rng_seed: RngSeed::Fixed(seed),
        failure_persistence: None,
        ..ProptestConfig::default()
    }
}

/// Rounding budget of a reversed trace, in units of f64 epsilon per unit of conditioning: each
/// refraction amplifies errors by 1 / cos(r), so the budget scales with the sum of 1 / cos(r)
/// over the surfaces crossed (1 for a surface between equal media). Measured over 31000
/// random rays in random lenses: at most 3.7 epsilon in direction and 3.1 epsilon per mm of
/// path in position per unit of that sum (raw errors reached 51 epsilon for a ray refracted
/// near grazing, where the sum was 317).
const DIRECTION_EPSILONS: f64 = 16.0;
const POSITION_EPSILONS: f64 = 16.0;

/// Sum over the crossings of a traced path of 1 / cos(r), r the angle of refraction: the
/// conditioning of the trace. The normal at each crossing is recovered from Snell's law, along
/// which d_out - mu d_in points.
fn refraction_conditioning(
    system: &LensSystem,
    start: Vec3,
    path: &lensbake::trace::TracedPath,
) -> f64 {
    let at = system.at(WAVELENGTH_NM);
    let mut d_in = start;
    let mut sum = 0.0;
    for crossing in &path.crossings {
        let d_out = crossing.direction;
        let surface = crossing.surface - 1;
        let mu = at.index_before(surface) / at.surfaces[surface].index_after;
        sum += if mu == 1.0 {
            1.0
        } else {
            let normal = [
                d_out[0] - mu * d_in[0],
                d_out[1] - mu * d_in[1],
                d_out[2] - mu * d_in[2],
            ];
            let cos_r = (d_out[0] * normal[0] + d_out[1] * normal[1] + d_out[2] * normal[2])
                / length(normal);
            1.0 / cos_r.abs()
        };
        d_in = d_out;
    }
    sum
}

proptest! {
    #![proptest_config(config(512, 0x5eed_0001))]

    #[test]
    fn reversing_the_exit_ray_retraces_the_entering_ray(
        system in lens(),
        rays in prop::collection::vec(
            ((-1.0..1.0f64, -1.0..1.0f64), (-0.3..0.3f64, -0.3..0.3f64)),
            4,
        ),
    ) {
        // Geometry only (apertures ignored): reversibility is a property of refraction and
        // intersection, and ignoring apertures keeps most random rays in play.
        let tracer = tracer(&system);
        let start_z = tracer.front_start_z();
        let semi = system.prescription.surfaces[0].semi_aperture;
        for ((px, py), (ax, ay)) in rays {
            let start = Ray::new([px * semi, py * semi, start_z], [ax, ay, 1.0]).unwrap();
            let forward = tracer.trace_path(start, Travel::Forward, Apertures::Ignored);
            if !forward.traced.outcome.is_ok() {
                continue;
            }
            let mut path = 0.0;
            let mut previous = start.position();
            for crossing in &forward.crossings {
                path += distance(previous, crossing.point);
                previous = crossing.point;
            }
            let out = forward.traced.ray;
            let reversed = Ray::new(out.position(), out.direction().map(|v| -v)).unwrap();
            let backward = tracer.trace_with(reversed, Travel::Backward, Apertures::Ignored);
            prop_assert_eq!(backward.outcome, Outcome::Ok);
            let end = backward.ray;
            let conditioning = refraction_conditioning(&system, start.direction(), &forward);
            let direction_error = length([
                end.direction()[0] + start.direction()[0],
                end.direction()[1] + start.direction()[1],
                end.direction()[2] + start.direction()[2],
            ]);
            prop_assert!(
                direction_error <= DIRECTION_EPSILONS * conditioning * f64::EPSILON,
                "direction off by {:e} (conditioning {})", direction_error, conditioning
            );
            let position_error = distance(end.point_at_z(start_z).unwrap(), start.position());
            prop_assert!(
                position_error <= POSITION_EPSILONS * conditioning * f64::EPSILON * path,
                "position off by {:e} mm over a {} mm path (conditioning {})",
                position_error, path, conditioning
            );
        }
    }

    #[test]
    fn lagrange_invariant_is_the_same_at_every_surface(
        system in lens(),
        object in prop_oneof![
            Just(ObjectPosition::Infinite),
            (200.0..5000.0f64).prop_map(|distance| ObjectPosition::Finite { distance }),
        ],
        field_deg in -20.0..20.0f64,
    ) {
        let at = system.at(WAVELENGTH_NM);
        let options = ParaxialOptions {
            object,
            aperture: Aperture::StopClearAperture,
            field: Field::Angle { deg: field_deg },
            ..ParaxialOptions::default()
        };
        // Afocal lenses and lenses whose stop images to infinity have no such rays.
        let paraxial = Paraxial::new(&at, &options);
        prop_assume!(paraxial.is_ok(), "no paraxial model: {:?}", paraxial);
        let paraxial = paraxial.unwrap();
        let h = paraxial.lagrange_invariant;
        for ((i, _, n_before, n_after), (m, c)) in at
            .path()
            .zip(paraxial.marginal.surfaces.iter().zip(&paraxial.chief.surfaces))
        {
            for (n, u, u_chief) in [
                (n_before, m.u_before, c.u_before),
                (n_after, m.u_after, c.u_after),
            ] {
                let here = n * (m.y * u_chief - c.y * u);
                // Rounding relative to the two products the invariant is the difference of.
                let scale = n * ((m.y * u_chief).abs() + (c.y * u).abs()) + h.abs();
                prop_assert!(
                    (here - h).abs() <= 1e-13 * scale,
                    "surface {}: H = {} vs {} at surface 1", i + 1, here, h
                );
            }
        }
    }

    #[test]
    fn real_ray_focal_length_converges_to_the_paraxial_one_as_height_squared(system in lens()) {
        let at = system.at(WAVELENGTH_NM);
        let first = FirstOrder::of(&at);
        prop_assume!(first.is_ok(), "afocal");
        let first = first.unwrap();
        let tracer = Tracer::new(&at);
        let h0 = 0.2 * system.prescription.surfaces[0].semi_aperture;
        // EFL(h) = -h / u' for a parallel ray at height h (u' its image-space slope).
        let errors: Vec<f64> = (0..=10)
            .map(|k| {
                let h = h0 / f64::from(1u32 << k);
                let ray = Ray::new([0.0, h, tracer.front_start_z()], [0.0, 0.0, 1.0]).unwrap();
                let traced = tracer.trace_with(ray, Travel::Forward, Apertures::Ignored);
                assert!(traced.outcome.is_ok(), "a near-axial ray passes the bare geometry");
                let d = traced.ray.direction();
                -h * d[2] / d[1] - first.efl
            })
            .collect();
        // Halving h divides the error by 4: the exponent log2(e(2h) / e(h)) is 2 (measured
        // 1.998 to 2.001 over 4000 random lenses) once h is small and while the error stays
        // well above rounding (1e-11 of the EFL).
        let floor = 1e-11 * first.efl.abs();
        let exponents: Vec<f64> = errors
            .windows(2)
            .skip(3)
            .filter(|pair| pair[1].abs() > floor)
            .map(|pair| (pair[0] / pair[1]).log2())
            .collect();
        prop_assume!(exponents.len() >= 3, "the lens is too well corrected to measure");
        for exponent in &exponents {
            prop_assert!((exponent - 2.0).abs() < 0.01, "exponents {:?}", exponents);
        }
        prop_assert!(
            errors[10].abs() <= 1.1 * errors[0].abs() / 4f64.powi(10) + 1e-13 * first.efl.abs(),
            "errors {:?}", errors
        );
    }
}

/// A pupil table of 2 to 6 random circles over a random film radius range.
fn pupil_table() -> impl Strategy<Value = PupilTable> {
    (
        1.0..30.0f64,
        prop::collection::vec((-8.0..8.0f64, 0.05..12.0f64), 2..=6),
    )
        .prop_map(|(max_film_radius, circles)| PupilTable {
            max_film_radius,
            circles: circles
                .into_iter()
                .map(|(centre_x, radius)| PupilCircle { centre_x, radius })
                .collect(),
        })
}

/// Integral of the sampling density over the rear plane, using only `pdf` (a black box):
/// midpoint rule over rows across the disk's bounding box, each row's support found by
/// bisection from the circle's centre line.
fn integrate_pdf(table: &PupilTable, film_radius: f64) -> f64 {
    let circle = table.circle_at(film_radius);
    let rows = 4000;
    let dy = 2.0 * circle.radius / rows as f64;
    let mut integral = 0.0;
    for j in 0..rows {
        let y = -circle.radius + (j as f64 + 0.5) * dy;
        let density = table.pdf(film_radius, [circle.centre_x, y]);
        if density == 0.0 {
            continue;
        }
        let edge = |sign: f64| {
            let (mut inside, mut outside) = (0.0, 2.0 * circle.radius);
            for _ in 0..60 {
                let mid = 0.5 * (inside + outside);
                if table.pdf(film_radius, [circle.centre_x + sign * mid, y]) > 0.0 {
                    inside = mid;
                } else {
                    outside = mid;
                }
            }
            inside
        };
        integral += density * (edge(1.0) + edge(-1.0)) * dy;
    }
    integral
}

proptest! {
    #![proptest_config(config(48, 0x5eed_0002))]

    #[test]
    fn pupil_sampling_density_integrates_to_one(
        table in pupil_table(),
        at in 0.0..1.2f64,
        strata in prop::collection::vec((0.0..1.0f64, 0.0..1.0f64), 64),
    ) {
        // `at` beyond 1 asks past the last node, where the table holds its last circle.
        let film_radius = at * table.max_film_radius;
        let integral = integrate_pdf(&table, film_radius);
        // The midpoint rule over a disk's chord profile converges as rows^-1.5: 4000 rows
        // leave about 1e-5.
        prop_assert!((integral - 1.0).abs() < 1e-4, "integral {}", integral);
        // Every sample lies where the density is positive and reports that density.
        for (u, v) in strata {
            let sample = table.sample(film_radius, [u, v]);
            prop_assert!(sample.pdf > 0.0);
            prop_assert_eq!(sample.pdf, table.pdf(film_radius, sample.point));
        }
    }
}

#[test]
fn baked_pupil_density_integrates_to_one() {
    // The pupil table of a real bake (double Gauss at f/4, where the pupil circles shift and
    // shrink with the film radius), at its nodes and between them.
    let prescription: Prescription =
        ron::from_str(lensbake::lenses::find("dgauss-50mm").unwrap().ron).unwrap();
    let system = LensSystem::from_prescription(prescription).unwrap();
    let request = BakeRequest {
        resolution: [8, 4, 4],
        f_number: Some(4.0),
        ..BakeRequest::default()
    };
    let table = bake(&system, &request).unwrap();
    let pupil = &table.layers[0].pupil;
    for k in 0..=21 {
        let film_radius = pupil.max_film_radius * k as f64 / 21.0;
        let integral = integrate_pdf(pupil, film_radius);
        assert!(
            (integral - 1.0).abs() < 1e-4,
            "film radius {film_radius}: {integral}"
        );
    }
}

/// Directions from all over the sphere, a share of them grazing (|dz| tiny) or along the axis.
fn direction() -> impl Strategy<Value = Vec3> {
    prop_oneof![
        (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64),
        (-1.0..1.0f64, -1.0..1.0f64, -1e-9..1e-9f64),
        (-0.3..0.3f64, -0.3..0.3f64, 0.5..1.0f64),
        Just((0.0, 0.0, 1.0)),
    ]
    .prop_filter("non-zero", |(x, y, z)| x * x + y * y + z * z > 1e-12)
    .prop_map(|(x, y, z)| [x, y, z])
}

proptest! {
    #![proptest_config(config(512, 0x5eed_0003))]

    #[test]
    fn no_random_ray_in_a_random_lens_yields_nan(
        system in lens(),
        rays in prop::collection::vec(
            ((-30.0..30.0f64, -30.0..30.0f64, -40.0..150.0f64), direction(), any::<bool>(), any::<bool>()),
            32,
        ),
    ) {
        let tracer = tracer(&system);
        for ((x, y, z), d, backward, checked) in rays {
            let travel = if backward { Travel::Backward } else { Travel::Forward };
            let apertures = if checked { Apertures::Checked } else { Apertures::Ignored };
            let path = tracer.trace_path(Ray::new([x, y, z], d).unwrap(), travel, apertures);
            let (p, d) = (path.traced.ray.position(), path.traced.ray.direction());
            prop_assert!(p.iter().chain(&d).all(|v| v.is_finite()), "{:?}", path.traced);
            prop_assert!((length(d) - 1.0).abs() < 1e-12, "{:?}", path.traced);
            if let Some(surface) = path.traced.outcome.surface() {
                prop_assert!((1..=tracer.surface_count()).contains(&surface));
            }
            for crossing in &path.crossings {
                prop_assert!(crossing.point.iter().chain(&crossing.direction).all(|v| v.is_finite()));
            }
        }
    }
}
