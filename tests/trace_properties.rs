//! Properties of the tracer over random rays: no NaN ever, unit directions, sensible outcomes,
//! forward/backward reversibility, and the batch path equal to the one-ray path.

mod common;

use common::{ORACLE_LENSES, load_oracle};
use lensbake::prescription::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
use lensbake::system::LensSystem;
use lensbake::trace::{Apertures, Outcome, Ray, RayBatch, Tracer, Travel, Vec3};
use proptest::prelude::*;
use std::sync::OnceLock;

/// A lens that exercises every profile: an even asphere, a hyperboloid, a 7-blade stop with
/// curved blades, and a dense glass that gives TIR for steep rays.
fn exotic_lens() -> Prescription {
    let surface = |shape, thickness, medium, semi_aperture, stop| Surface {
        shape,
        thickness,
        medium,
        semi_aperture,
        stop,
        obscuration: None,
    };
    Prescription {
        provenance: Provenance {
            title: "test: every profile".into(),
            ..Provenance::default()
        },
        object_medium: Medium::Air,
        surfaces: vec![
            surface(
                Shape::EvenAsphere {
                    curvature: 1.0 / 40.0,
                    conic: -0.5,
                    coefficients: vec![0.0, 1e-6, -2e-9],
                },
                6.0,
                Medium::Index(1.8),
                14.0,
                None,
            ),
            surface(
                Shape::Conic {
                    curvature: -1.0 / 60.0,
                    conic: -2.0,
                },
                3.0,
                Medium::Air,
                14.0,
                None,
            ),
            surface(
                Shape::Plane,
                3.0,
                Medium::Air,
                8.0,
                Some(StopShape::Blades {
                    count: 7,
                    rotation_deg: 10.0,
                    blade_curvature: 0.3,
                }),
            ),
            surface(
                Shape::Sphere {
                    curvature: -1.0 / 25.0,
                },
                5.0,
                Medium::Index(1.6),
                11.0,
                None,
            ),
            surface(
                Shape::Sphere {
                    curvature: -1.0 / 30.0,
                },
                40.0,
                Medium::Air,
                12.0,
                None,
            ),
        ],
    }
}

fn tracers() -> &'static Vec<Tracer> {
    static TRACERS: OnceLock<Vec<Tracer>> = OnceLock::new();
    TRACERS.get_or_init(|| {
        let mut prescriptions: Vec<Prescription> = ORACLE_LENSES
            .into_iter()
            .map(|name| load_oracle(name).prescription)
            .collect();
        prescriptions.push(exotic_lens());
        prescriptions
            .into_iter()
            .map(|p| {
                let system = LensSystem::from_prescription(p).expect("valid test lens");
                Tracer::new(&system.at(587.56))
            })
            .collect()
    })
}

fn length(v: Vec3) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn assert_sane(tracer: &Tracer, traced: lensbake::trace::Traced) -> Result<(), TestCaseError> {
    let (p, d) = (traced.ray.position(), traced.ray.direction());
    prop_assert!(
        p.iter().chain(&d).all(|v| v.is_finite()),
        "non-finite {:?}",
        traced
    );
    prop_assert!(
        (length(d) - 1.0).abs() < 1e-12,
        "direction not unit: {:?}",
        d
    );
    if let Some(surface) = traced.outcome.surface() {
        prop_assert!((1..=tracer.surface_count()).contains(&surface));
    }
    Ok(())
}

/// Directions from all over the sphere, with a share of grazing ones (|dz| tiny).
fn direction() -> impl Strategy<Value = Vec3> {
    prop_oneof![
        (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64),
        (-1.0..1.0f64, -1.0..1.0f64, -1e-9..1e-9f64),
        (-0.3..0.3f64, -0.3..0.3f64, 0.5..1.0f64),
    ]
    .prop_filter("non-zero", |(x, y, z)| x * x + y * y + z * z > 1e-12)
    .prop_map(|(x, y, z)| [x, y, z])
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(2000))]

    #[test]
    fn random_rays_never_produce_nan(
        lens in 0usize..5,
        x in -40.0..40.0f64,
        y in -40.0..40.0f64,
        z in -60.0..120.0f64,
        d in direction(),
        backward in any::<bool>(),
        apertures in any::<bool>(),
    ) {
        let tracer = &tracers()[lens];
        let travel = if backward { Travel::Backward } else { Travel::Forward };
        let apertures = if apertures { Apertures::Checked } else { Apertures::Ignored };
        let ray = Ray::new([x, y, z], d).unwrap();
        assert_sane(tracer, tracer.trace_with(ray, travel, apertures))?;
        let path = tracer.trace_path(ray, travel, apertures);
        prop_assert_eq!(path.traced, tracer.trace_with(ray, travel, apertures));
        for crossing in &path.crossings {
            prop_assert!(crossing.point.iter().chain(&crossing.direction).all(|v| v.is_finite()));
        }
    }

    #[test]
    fn reversed_ray_retraces_its_path(
        lens in 0usize..5,
        px in -1.0..1.0f64,
        py in -1.0..1.0f64,
        field in -0.4..0.4f64,
    ) {
        // A forward ray through the entrance pupil; reversing the ray that leaves the lens must
        // lead back along the ray that entered (Helmholtz reciprocity of the geometric path).
        let tracer = &tracers()[lens];
        let pupil = tracer.paraxial_entrance_pupil().unwrap();
        let start_z = tracer.front_start_z();
        let d = [0.0, field.sin(), field.cos()];
        let back = (pupil.z - start_z) / d[2];
        let start = Ray::new(
            [0.35 * pupil.diameter * px, 0.35 * pupil.diameter * py - back * d[1], start_z],
            d,
        ).unwrap();
        let forward = tracer.trace(start, Travel::Forward);
        prop_assume!(forward.outcome.is_ok());
        let out = forward.ray;
        let reversed = Ray::new(out.position(), out.direction().map(|v| -v)).unwrap();
        let backward = tracer.trace(reversed, Travel::Backward);
        prop_assert_eq!(backward.outcome, Outcome::Ok);
        let end = backward.ray;
        for (back, forth) in end.direction().into_iter().zip(d) {
            prop_assert!((back + forth).abs() < 1e-12);
        }
        let at_start = end.point_at_z(start_z).unwrap();
        for (back, forth) in at_start.into_iter().zip(start.position()) {
            prop_assert!((back - forth).abs() < 1e-9);
        }
    }
}

#[test]
fn on_axis_rays_stay_on_axis() {
    for tracer in tracers() {
        let forward = tracer.trace(
            Ray::new([0.0, 0.0, -100.0], [0.0, 0.0, 1.0]).unwrap(),
            Travel::Forward,
        );
        assert_eq!(forward.outcome, Outcome::Ok);
        let d = forward.ray.direction();
        assert_eq!(&d[..2], &[0.0, 0.0]);
        assert!((d[2] - 1.0).abs() < 1e-14, "still along +z: {d:?}");
        assert_eq!(&forward.ray.position()[..2], &[0.0, 0.0]);
        let backward = tracer.trace(
            Ray::new([0.0, 0.0, 500.0], [0.0, 0.0, -1.0]).unwrap(),
            Travel::Backward,
        );
        assert_eq!(backward.outcome, Outcome::Ok);
        let d = backward.ray.direction();
        assert_eq!(&d[..2], &[0.0, 0.0]);
        assert!((d[2] + 1.0).abs() < 1e-14, "still along -z: {d:?}");
        let end = backward.ray.position();
        assert_eq!(&end[..2], &[0.0, 0.0]);
        assert!(end[2].abs() < 1e-12, "ends at the first vertex: {end:?}");
    }
}

#[test]
fn blades_vignette_between_circle_and_polygon() {
    // The exotic lens's diaphragm (semi-aperture 8, 7 blades rotated 10 degrees, curvature 0.3)
    // put first, so axis-parallel rays reach it unbent. A corner direction passes just inside
    // radius 8; an edge middle (half a sector further) is stopped there, because its arc runs
    // at 8 cos(pi/7) + sagitta = 7.43; inside that the ray passes.
    let mut lens = exotic_lens();
    let stop = lens.surfaces.remove(2);
    lens.surfaces = vec![stop, lens.surfaces.pop().unwrap()];
    let system = LensSystem::from_prescription(lens).unwrap();
    let tracer = Tracer::new(&system.at(587.56));
    let through = |r: f64, angle_deg: f64| {
        let a = angle_deg.to_radians();
        let ray = Ray::new([r * a.cos(), r * a.sin(), -1.0], [0.0, 0.0, 1.0]).unwrap();
        tracer.trace(ray, Travel::Forward).outcome
    };
    let edge_middle = 10.0 + 360.0 / 14.0;
    assert_eq!(through(7.99, 10.0), Outcome::Ok);
    assert_eq!(through(7.99, 10.0 + 3.0 * 360.0 / 7.0), Outcome::Ok);
    assert_eq!(
        through(7.45, edge_middle),
        Outcome::Vignetted { surface: 1 }
    );
    assert_eq!(through(7.41, edge_middle), Outcome::Ok);
    assert_eq!(through(8.01, 10.0), Outcome::Vignetted { surface: 1 });
}

#[test]
fn batch_equals_single_rays() {
    let tracer = &tracers()[3];
    let bundle = lensbake::trace::FieldBundle::over_traceable_field(tracer).unwrap();
    let rays = bundle.sample(5000, 7);
    let batch = tracer.trace_batch(&rays, Travel::Forward, Apertures::Checked);
    assert_eq!(batch.outcomes.len(), rays.len());
    let mut expected_surfaces = 0u64;
    for (i, ray) in rays.iter().enumerate() {
        let single = tracer.trace(ray, Travel::Forward);
        assert_eq!(batch.outcomes[i], single.outcome);
        assert_eq!(batch.rays.get(i).unwrap(), single.ray);
        expected_surfaces += single.outcome.surface().unwrap_or(tracer.surface_count()) as u64;
    }
    assert_eq!(batch.ray_surfaces, expected_surfaces);
    let ok = batch.outcomes.iter().filter(|o| o.is_ok()).count();
    assert!(
        ok > 1000 && ok < 5000,
        "a mix of passing and vignetted rays: {ok}"
    );
    let empty = tracer.trace_batch(&RayBatch::new(), Travel::Forward, Apertures::Checked);
    assert!(empty.outcomes.is_empty() && empty.ray_surfaces == 0);
}

#[test]
fn random_sweep_reaches_every_outcome() {
    // The property tests above are only as strong as the rays they draw: make sure rays of the
    // same kind really end in every outcome on the exotic lens, in both directions.
    let tracer = &tracers()[4];
    let mut state = 0x2545_f491_4f6c_dd1du64;
    let mut unit = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    for travel in [Travel::Forward, Travel::Backward] {
        let mut seen = std::collections::HashSet::new();
        for i in 0..200_000 {
            let apertures = if i % 2 == 0 {
                Apertures::Checked
            } else {
                Apertures::Ignored
            };
            let sense = if travel == Travel::Forward { 1.0 } else { -1.0 };
            let start_z = if sense > 0.0 { -20.0 } else { 80.0 };
            let p = [40.0 * unit() - 20.0, 40.0 * unit() - 20.0, start_z];
            let d = [2.0 * unit() - 1.0, 2.0 * unit() - 1.0, sense * unit()];
            let Ok(ray) = Ray::new(p, d) else { continue };
            let traced = tracer.trace_with(ray, travel, apertures);
            assert!(
                traced
                    .ray
                    .position()
                    .iter()
                    .chain(&traced.ray.direction())
                    .all(|v| v.is_finite())
            );
            seen.insert(traced.outcome.status());
        }
        assert_eq!(
            seen.len(),
            4,
            "{travel:?}: ok, vignetted, TIR and missed all occur: {seen:?}"
        );
    }
}

#[test]
fn batch_equals_single_rays_for_every_outcome_and_direction() {
    // The batch path runs several rays in lockstep through vector kernels; it must give the
    // one-ray results bit for bit, whatever happens to the rays and in which lane.
    let mut state = 0x9e37_79b9_7f4a_7c15u64;
    let mut unit = move || {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    for tracer in tracers() {
        for travel in [Travel::Forward, Travel::Backward] {
            for apertures in [Apertures::Checked, Apertures::Ignored] {
                let sense = if travel == Travel::Forward { 1.0 } else { -1.0 };
                let start_z = if sense > 0.0 { -20.0 } else { 150.0 };
                let rays: RayBatch = (0..3001)
                    .filter_map(|_| {
                        let p = [30.0 * unit() - 15.0, 30.0 * unit() - 15.0, start_z];
                        let d = [
                            0.6 * unit() - 0.3,
                            0.6 * unit() - 0.3,
                            sense * (unit() - 0.05),
                        ];
                        Ray::new(p, d).ok()
                    })
                    .collect();
                let batch = tracer.trace_batch(&rays, travel, apertures);
                let mut kinds = std::collections::HashSet::new();
                for (i, ray) in rays.iter().enumerate() {
                    let single = tracer.trace_with(ray, travel, apertures);
                    assert_eq!(batch.outcomes[i], single.outcome, "ray {i} {travel:?}");
                    assert_eq!(batch.rays.get(i).unwrap(), single.ray, "ray {i} {travel:?}");
                    kinds.insert(single.outcome.status());
                }
                assert!(kinds.len() >= 2, "a mix of outcomes: {kinds:?}");
            }
        }
    }
}
