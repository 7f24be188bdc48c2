//! The baked table against the exact trace on held-out rays (the renderer's distribution, drawn
//! with a seed the bake never saw), for the pbrt 50 mm double Gauss of the oracle data.
#![cfg(feature = "render")]

mod common;

use lensbake::lrtf::bake::{BakeRequest, bake, first_order};
use lensbake::lrtf::measure::{table_error, table_error_from};
use lensbake::lrtf::{Corners, Lookup, LrtfTable, Parameterisation, Precision, Ray};
use lensbake::system::LensSystem;
use lensbake::trace::Tracer;

fn dgauss() -> LensSystem {
    let (_, file) = common::oracle_files()
        .into_iter()
        .find(|(name, _)| name.contains("pbrt_dgauss_50mm"))
        .expect("pbrt double Gauss oracle");
    LensSystem::from_prescription(common::oracle_prescription(&file["lenses"][0])).unwrap()
}

#[test]
fn pupil_planes_table_matches_the_exact_trace_within_measured_bounds() {
    let system = dgauss();
    let design = system.at(system.design_wavelength_nm());
    let tracer = Tracer::new(&design);
    let efl = first_order(&design, None).unwrap().first_order.efl;
    let request = BakeRequest {
        parameterisation: Parameterisation::PupilPlanes,
        resolution: [32, 32, 32],
        precision: Precision::F32,
        ..BakeRequest::default()
    };
    let table = bake(&system, &request).unwrap();
    let e = table_error(&table, 0, &tracer, efl, 1920.0, 4000, 0xfeed);
    eprintln!("{e:?}");
    // Measured at 32^3 on 20k rays (docs/lrtf.md): direction p99 0.027 mrad, max 0.05 mrad;
    // position p99 4.2 um. Bounds sit ~1.5x above those figures. Validity: 1 ray in 4000 here
    // with the signed aperture margin; the thresholded 0/1 flag it replaced missed 1.4 %.
    assert!(e.direction_mrad.p99 < 0.04, "{e:?}");
    assert!(e.direction_mrad.max < 0.08, "{e:?}");
    assert!(e.position_um.p99 < 6.5, "{e:?}");
    assert!(e.validity_mismatch < 0.002, "{e:?}");
    // The seed's spherical baseline at the same resolution is an order of magnitude worse in
    // direction: the comparison docs/lrtf.md reports must hold.
    let spherical = bake(
        &system,
        &BakeRequest {
            parameterisation: Parameterisation::Spherical,
            ..request
        },
    )
    .unwrap();
    let s = table_error(&spherical, 0, &tracer, efl, 1920.0, 4000, 0xfeed);
    assert!(
        s.direction_mrad.p99 > 10.0 * e.direction_mrad.p99,
        "{s:?} vs {e:?}"
    );
}

/// Issue 6's targets for the default table (128^3, pupil-planes, f32, wide open, infinity focus)
/// of the bundled 50 mm double Gauss, on 20k held-out renderer rays: p99 image error under
/// 0.5 px of a 1920-pixel frame and validity agreement above 99.5 %. Also pins the two measured
/// comparisons docs/lrtf.md reports at this size: the spherical baseline and renormalised
/// valid-corner weights are both clearly worse. About 5 s of CPU in release.
#[test]
fn default_double_gauss_table_meets_the_issue_targets() {
    let system = lensbake::lenses::load(
        "dgauss-50mm",
        &lensbake::prescription::formats::LoadOptions::default(),
    )
    .unwrap()
    .system;
    let design = system.at(system.design_wavelength_nm());
    let tracer = Tracer::new(&design);
    let efl = first_order(&design, None).unwrap().first_order.efl;
    let request = BakeRequest::default();
    assert_eq!(request.resolution, [128, 128, 128]);
    let table = bake(&system, &request).unwrap();
    let rays = 20_000;
    let e = table_error(&table, 0, &tracer, efl, 1920.0, rays, 0xfeed);
    eprintln!("default: {e:?}");
    // Measured: p99 0.010 px; agreement 99.985 % (3 rays in 20k) with the signed aperture
    // margin, against 99.5-99.6 % for the thresholded 0/1 flag it replaced. The second bound
    // fails if the margin's second-order edge is lost.
    assert!(e.image_px.p99 < 0.5, "{e:?}");
    assert!(1.0 - e.validity_mismatch > 0.995, "{e:?}");
    assert!(1.0 - e.validity_mismatch > 0.999, "{e:?}");
    let renormalised = table_error_from(
        &table,
        0,
        &tracer,
        efl,
        1920.0,
        rays,
        0xfeed,
        Corners::ValidOnly,
    );
    // Measured 1.0 px against 0.010 px.
    assert!(
        renormalised.image_px.p99 > 20.0 * e.image_px.p99,
        "{renormalised:?} vs {e:?}"
    );
    let spherical = bake(
        &system,
        &BakeRequest {
            parameterisation: Parameterisation::Spherical,
            ..request
        },
    )
    .unwrap();
    let s = table_error(&spherical, 0, &tracer, efl, 1920.0, rays, 0xfeed);
    eprintln!("spherical: {s:?}");
    // Measured 0.15 px against 0.010 px.
    assert!(s.image_px.p99 > 5.0 * e.image_px.p99, "{s:?} vs {e:?}");
}

/// Rays from film points past the domain through rear points past the pupil (unit directions):
/// some pass, some are blocked, some fall outside the domain.
fn lattice_rays(table: &LrtfTable) -> Vec<Ray> {
    let frame = &table.layers[0].frame;
    let reach = 1.2 * frame.max_film_radius;
    let rear = 1.5 * table.layers[0].pupil.max_extent();
    let depth = frame.film_plane_z - frame.rear_plane_z;
    (0..997)
        .map(|k| {
            let u = |a: f64| (a * k as f64).fract() * 2.0 - 1.0;
            let film = [reach * u(0.618_034), reach * u(0.381_966) * 0.5];
            let to = [
                rear * u(0.414_214) - film[0],
                rear * u(0.732_051) - film[1],
                -depth,
            ];
            let n = (to[0] * to[0] + to[1] * to[1] + to[2] * to[2]).sqrt();
            Ray {
                origin: [film[0], film[1], frame.film_plane_z],
                direction: to.map(|v| v / n),
            }
        })
        .collect()
}

fn small_table(system: &LensSystem, parameterisation: Parameterisation) -> LrtfTable {
    let request = BakeRequest {
        parameterisation,
        resolution: [16, 16, 16],
        ..BakeRequest::default()
    };
    bake(system, &request).unwrap()
}

/// The renderer looks rays up in groups (table reads overlapping); each ray's outcome must be
/// the one it gets alone, for rays that pass, are blocked and fall outside the domain, in both
/// parameterisations.
#[test]
fn group_lookups_are_single_lookups() {
    let system = dgauss();
    for parameterisation in [Parameterisation::PupilPlanes, Parameterisation::Spherical] {
        let table = small_table(&system, parameterisation);
        let mut rays = lattice_rays(&table);
        // Every tenth ray turned round, away from the lens: outside either domain.
        let away: Vec<Ray> = rays
            .iter()
            .step_by(10)
            .map(|r| Ray {
                direction: r.direction.map(|v| -v),
                ..*r
            })
            .collect();
        rays.extend(away);
        let stop = table.stop_radius(0, table.info.f_number).unwrap();
        let mut grouped = vec![Lookup::Blocked; rays.len()];
        table.lookup_group(0, &rays, stop, &mut grouped);
        let single: Vec<Lookup> = rays
            .iter()
            .map(|r| table.lookup_layer(0, r, stop))
            .collect();
        assert_eq!(grouped, single, "{parameterisation:?}");
        let count = |f: fn(&Lookup) -> bool| single.iter().filter(|l| f(l)).count();
        let counts = [
            count(|l| matches!(l, Lookup::Passes(_))),
            count(|l| matches!(l, Lookup::Blocked)),
            count(|l| matches!(l, Lookup::OutsideDomain)),
        ];
        assert!(
            counts.iter().all(|&c| c > 50),
            "{parameterisation:?}: {counts:?}"
        );
    }
}

/// A lookup reads a ray's line and sense, not the length of its direction (the renderer hands
/// the table film-side directions it has not made unit): the same rays with their directions
/// scaled give the same outcomes and, to rounding, the same outgoing rays, in both
/// parameterisations.
#[test]
fn lookups_do_not_depend_on_the_length_of_the_direction() {
    let system = dgauss();
    for parameterisation in [Parameterisation::PupilPlanes, Parameterisation::Spherical] {
        let table = small_table(&system, parameterisation);
        let rays = lattice_rays(&table);
        let stop = table.stop_radius(0, table.info.f_number).unwrap();
        let mut unit = vec![Lookup::Blocked; rays.len()];
        table.lookup_group(0, &rays, stop, &mut unit);
        for scale in [3.7, 0.013] {
            let scaled: Vec<Ray> = rays
                .iter()
                .map(|r| Ray {
                    direction: r.direction.map(|v| v * scale),
                    ..*r
                })
                .collect();
            let mut looked = vec![Lookup::Blocked; rays.len()];
            table.lookup_group(0, &scaled, stop, &mut looked);
            let mut largest = 0.0f64;
            for (k, (a, b)) in unit.iter().zip(&looked).enumerate() {
                match (a, b) {
                    (Lookup::Passes(a), Lookup::Passes(b)) => {
                        let apart = a.origin.iter().zip(&b.origin);
                        let turned = a.direction.iter().zip(&b.direction);
                        for (x, y) in apart.chain(turned) {
                            largest = largest.max((x - y).abs());
                        }
                    }
                    _ => assert_eq!(a, b, "{parameterisation:?}, scale {scale}, ray {k}"),
                }
            }
            // Rounding of f64 values of order 10 mm (measured: 9e-15 pupil-planes, 1.1e-13
            // spherical), far below the table's own error (micrometres, docs/lrtf.md).
            assert!(
                largest < 1e-12,
                "{parameterisation:?}, scale {scale}: {largest:e}"
            );
        }
        assert!(
            unit.iter()
                .filter(|l| matches!(l, Lookup::Passes(_)))
                .count()
                > 50
        );
    }
}
