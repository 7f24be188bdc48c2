//! Afocal analysis (`analyze` of a telescope, a beam expander, a window) against the identities
//! of thin-lens telescopes, of a Keplerian telescope built from two real singlets whose own
//! focal lengths the focal analysis gives, of confocal paraboloids (a perfect afocal system:
//! zero wavefront error against a plane) and of third-order theory at small apertures.
#![cfg(feature = "cli")]

mod common;

use lensbake::analysis::{AnalyzeOptions, analyze, analyze_afocal};
use lensbake::paraxial::{AfocalParaxial, ParaxialError, StopChoice};
use lensbake::prescription::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
use lensbake::system::LensSystem;
use lensbake::trace::{Apertures, Ray, Tracer, Travel};
use lensbake::wave::{Sampling, afocal_wavefront, diffraction_limited_mtf};

const WAVELENGTH_NM: f64 = 587.5618;

fn prescription(surfaces: Vec<Surface>) -> LensSystem {
    LensSystem::from_prescription(Prescription {
        provenance: Provenance {
            design_wavelength_nm: Some(WAVELENGTH_NM),
            ..Provenance::default()
        },
        object_medium: Medium::Air,
        surfaces,
    })
    .unwrap()
}

fn stop(surface: Surface) -> Surface {
    Surface {
        stop: Some(StopShape::Circle),
        ..surface
    }
}

/// Two ideal thin lenses f1, f2 a distance f1 + f2 apart, the stop on the first.
fn thin_telescope(f1: f64, f2: f64) -> LensSystem {
    prescription(vec![
        stop(Surface::open(
            Shape::IdealLens { focal_length: f1 },
            f1 + f2,
            Medium::Air,
            30.0,
        )),
        Surface::open(
            Shape::IdealLens { focal_length: f2 },
            30.0,
            Medium::Air,
            30.0,
        ),
    ])
}

fn options(epd: f64, field_deg: f64) -> AnalyzeOptions {
    AnalyzeOptions {
        epd_mm: Some(epd),
        field_deg: Some(field_deg),
        ..AnalyzeOptions::default()
    }
}

#[test]
fn keplerian_and_galilean_telescopes_of_thin_lenses() {
    // (f1, f2): Keplerian (inverting, real exit pupil) and Galilean (erect, virtual one).
    for (f1, f2) in [(100.0, 10.0), (250.0, 25.0), (100.0, -10.0), (400.0, -50.0)] {
        let a = analyze_afocal(&thin_telescope(f1, f2), &options(20.0, 0.5)).unwrap();
        let what = format!("f1 {f1}, f2 {f2}");
        // Angular magnification -f1/f2 and beam magnification its inverse.
        common::assert_close(a.angular_magnification, -f1 / f2, 1e-13, 0.0, &what);
        common::assert_close(a.beam_magnification, -f2 / f1, 1e-13, 0.0, &what);
        // The exit pupil is the eyepiece's image of the objective: 1/s' = 1/f2 - 1/(f1 + f2)
        // gives s' = f2 (f1 + f2) / f1 behind the eyepiece (negative: virtual, Galilean).
        let relief = f2 * (f1 + f2) / f1;
        common::assert_close(a.eye_relief.unwrap(), relief, 1e-12, 0.0, &what);
        let xp = a.exit_pupil.unwrap();
        common::assert_close(xp.z, f1 + f2 + relief, 1e-12, 0.0, &what);
        common::assert_close(xp.diameter, 20.0 * (f2 / f1).abs(), 1e-12, 0.0, &what);
        // Apparent field: tan(theta') = gamma tan(theta), paraxially and for the real chief ray
        // (an ideal lens maps ray tangents linearly, so the telescope has no distortion).
        let tan = 0.5_f64.to_radians().tan() * (-f1 / f2);
        common::assert_close(
            a.apparent_field_deg,
            tan.atan().to_degrees(),
            1e-12,
            0.0,
            &what,
        );
        for p in &a.apparent_field {
            // 1e-12 relative, in percent (measured: 4e-14 percent).
            assert!(p.distortion_percent.abs() < 1e-10, "{what}: {p:?}");
        }
        // Ideal lenses have no aberration.
        assert_eq!(a.seidel.sums.as_array(), [0.0; 5], "{what}");
        // The focal analysis refuses it as afocal.
        let refused = analyze(&thin_telescope(f1, f2), &options(20.0, 0.5)).unwrap_err();
        assert!(refused.to_string().contains("afocal"), "{what}: {refused}");
    }
}

#[test]
fn a_lens_with_power_is_not_afocal() {
    let system = thin_telescope(100.0, 10.0);
    let mut p = system.prescription.clone();
    p.surfaces[0].thickness = 111.0;
    let at = LensSystem::from_prescription(p).unwrap().at(WAVELENGTH_NM);
    let error = AfocalParaxial::new(&at, Some(10.0), 0.0, StopChoice::Marked).unwrap_err();
    assert!(matches!(error, ParaxialError::NotAfocal { .. }), "{error}");
}

/// A biconvex N-BK7 singlet of radii +-r and centre thickness t, its stop on the front.
fn singlet(r: f64, t: f64, gap: f64, semi: f64) -> [Surface; 2] {
    [
        Surface::open(
            Shape::Sphere { curvature: 1.0 / r },
            t,
            Medium::Glass("N-BK7".into()),
            semi,
        ),
        Surface::open(
            Shape::Sphere {
                curvature: -1.0 / r,
            },
            gap,
            Medium::Air,
            semi,
        ),
    ]
}

#[test]
fn keplerian_of_thick_singlets_matches_the_focal_lengths_of_its_halves() {
    // Objective and eyepiece analysed alone by the focal analysis.
    let [o1, o2] = singlet(100.0, 6.0, 90.0, 15.0);
    let [e1, e2] = singlet(20.0, 4.0, 10.0, 8.0);
    let objective = analyze(
        &prescription(vec![stop(o1.clone()), o2.clone()]),
        &options(20.0, 0.0),
    )
    .unwrap()
    .first_order;
    let eyepiece = analyze(
        &prescription(vec![stop(e1.clone()), e2.clone()]),
        &options(5.0, 0.0),
    )
    .unwrap()
    .first_order;
    // The gap that puts the objective's rear focal point on the eyepiece's front one.
    let gap = objective.bfl - eyepiece.ffl;
    let telescope = prescription(vec![
        stop(o1),
        Surface {
            thickness: gap,
            ..o2
        },
        e1,
        e2,
    ]);
    let a = analyze_afocal(&telescope, &options(20.0, 1.0)).unwrap();
    common::assert_close(
        a.angular_magnification,
        -objective.efl / eyepiece.efl,
        1e-12,
        0.0,
        "gamma = -f1 / f2",
    );
    // The exit pupil is the eyepiece's image of the objective's own exit pupil (the stop imaged
    // by the objective's rear surface): by Newton's equation x x' = -f^2, x and x' measured
    // from the eyepiece's focal points.
    let objective_exit_pupil = objective.exit_pupil.unwrap().z;
    let x_object = objective_exit_pupil - objective.z_rear_focal;
    let x_image = -eyepiece.efl * eyepiece.efl / x_object;
    let z_rear_focal_eyepiece = a.z_last_vertex + eyepiece.bfl;
    common::assert_close(
        a.exit_pupil.unwrap().z,
        z_rear_focal_eyepiece + x_image,
        1e-11,
        0.0,
        "exit pupil by Newton's equation",
    );
    common::assert_close(
        a.exit_pupil.unwrap().diameter,
        20.0 * eyepiece.efl / objective.efl,
        1e-11,
        0.0,
        "exit pupil diameter = EPD / |gamma|",
    );
    // Lagrange invariant: n ybar_pupil u = n' ybar' u' at the pupils.
    let tan_in = 1.0_f64.to_radians().tan();
    let tan_out = a.apparent_field_deg.to_radians().tan();
    common::assert_close(
        20.0 * tan_in,
        a.exit_pupil.unwrap().diameter * tan_out.abs(),
        1e-12,
        0.0,
        "D tan(theta) = D' tan(theta')",
    );
}

/// Two confocal paraboloids, concave f1 and convex f2 sharing their focus (a Mersenne beam
/// compressor): perfect on axis in every order.
fn confocal_paraboloids(f1: f64, f2: f64, conic: f64) -> LensSystem {
    prescription(vec![
        stop(Surface::open(
            Shape::Conic {
                curvature: -1.0 / (2.0 * f1),
                conic,
            },
            -(f1 - f2),
            Medium::Mirror,
            25.0,
        )),
        Surface::open(
            Shape::Conic {
                curvature: -1.0 / (2.0 * f2),
                conic,
            },
            f1 - f2 + 20.0,
            Medium::Mirror,
            5.0,
        ),
    ])
}

#[test]
fn confocal_paraboloids_leave_a_plane_wave() {
    let system = confocal_paraboloids(100.0, 10.0, -1.0);
    let a = analyze_afocal(&system, &options(40.0, 0.0)).unwrap();
    common::assert_close(a.angular_magnification, 10.0, 1e-12, 0.0, "gamma = f1 / f2");
    let at = system.at(WAVELENGTH_NM);
    let paraxial = AfocalParaxial::new(&at, Some(40.0), 0.0, StopChoice::Marked).unwrap();
    let wave = afocal_wavefront(&at, &paraxial, 0.0, Sampling::default()).unwrap();
    // Rounding of 200 mm paths: measured 2.4e-11 waves.
    assert!(wave.stats.rms_waves < 1e-9, "{:?}", wave.stats);
    assert!(
        wave.rms_angular_spot_mrad < 1e-9,
        "{}",
        wave.rms_angular_spot_mrad
    );
    assert_eq!(wave.stats.transmitted_samples, wave.stats.pupil_samples);
    // A plane wave of diameter D' = 4 mm: cutoff n' D' / lambda, MTF the aberration-free one.
    let cutoff = 4.0 / (WAVELENGTH_NM * 1e-6) / 1e3;
    common::assert_close(wave.cutoff_per_mrad, cutoff, 1e-12, 0.0, "cutoff");
    let frequencies: Vec<f64> = (0..=10).map(|k| cutoff * k as f64 / 10.0).collect();
    let mtf = wave.mtf(&frequencies).unwrap();
    for (k, f) in frequencies.iter().enumerate() {
        let ideal = diffraction_limited_mtf(f / cutoff);
        // The sampled pupil's autocorrelation: within 0.01 on a 64-sample grid.
        assert!((mtf.tangential[k] - ideal).abs() < 0.01, "{f}: {mtf:?}");
        assert!((mtf.sagittal[k] - ideal).abs() < 0.01, "{f}: {mtf:?}");
    }
    // Spheres instead of paraboloids: spherical aberration, which a plane reference sees.
    let spheres = confocal_paraboloids(100.0, 10.0, 0.0).at(WAVELENGTH_NM);
    let paraxial = AfocalParaxial::new(&spheres, Some(40.0), 0.0, StopChoice::Marked).unwrap();
    let wave = afocal_wavefront(&spheres, &paraxial, 0.0, Sampling::default()).unwrap();
    assert!(wave.stats.rms_waves > 0.1, "{:?}", wave.stats);
}

/// A window whose front is a flat r^4 asphere (a Schmidt plate): zero power, pure spherical
/// aberration.
fn schmidt_plate(a4: f64) -> LensSystem {
    prescription(vec![
        stop(Surface::open(
            Shape::EvenAsphere {
                curvature: 0.0,
                conic: 0.0,
                coefficients: vec![0.0, a4],
            },
            5.0,
            Medium::Index(1.5),
            20.0,
        )),
        Surface::open(Shape::Plane, 20.0, Medium::Air, 20.0),
    ])
}

#[test]
fn third_order_angular_spherical_and_w040_match_the_real_trace_at_small_apertures() {
    let a4 = 1e-7;
    let system = schmidt_plate(a4);
    let at = system.at(WAVELENGTH_NM);
    let mut last_error = f64::INFINITY;
    for epd in [20.0, 10.0, 5.0] {
        let a = analyze_afocal(&system, &options(epd, 0.0)).unwrap();
        // S_I of an r^4 term alone: 8 a4 (n' - n) y^4.
        let y = epd / 2.0;
        common::assert_close(
            a.seidel.sums.spherical,
            8.0 * a4 * 0.5 * y.powi(4),
            1e-12,
            0.0,
            "S_I",
        );
        // The real marginal ray's exit slope against the angular form.
        let tracer = Tracer::new(&at);
        let ray = Ray::new([0.0, y, -1.0], [0.0, 0.0, 1.0]).unwrap();
        let traced = tracer.trace_with(ray, Travel::Forward, Apertures::Checked);
        assert!(traced.outcome.is_ok());
        let d = traced.ray.direction();
        let real_mrad = d[1] / d[2] * 1e3;
        let error = (real_mrad / a.seidel.angular.spherical - 1.0).abs();
        // Fifth order falls as the square of the aperture.
        assert!(error < 1e-3 && error < last_error / 3.0, "{epd}: {error}");
        last_error = error;
        // The wavefront against a plane: W040 rho^4 at the edge.
        let paraxial = AfocalParaxial::new(&at, Some(epd), 0.0, StopChoice::Marked).unwrap();
        // An odd grid puts samples on the pupil's centre and its rim.
        let sampling = Sampling {
            samples: 65,
            grid: 256,
        };
        let wave = afocal_wavefront(&at, &paraxial, 0.0, sampling).unwrap();
        let n = wave.samples;
        let row = (n / 2) * n;
        let edge = wave.opd_waves[row + n - 1].unwrap() - wave.opd_waves[row + n / 2].unwrap();
        let w040 = a.seidel.wavefront.w040;
        common::assert_close(edge, w040, 2e-3, 0.0, "OPD at the pupil edge");
    }
}

#[test]
fn corpus_zero_power_files_are_analysed_as_afocal() {
    // All planes, flat folds and a flat aspheric plate: gamma 1, no Seidel sums but the plate's.
    for name in [
        "rayoptics__dar_test.seq",
        "rayoptics__dec_test.seq",
        "rayoptics__dec_rev_tilt_test.seq",
        "rayoptics__dec_tilt_test.seq",
        "optiland__simple_fold_mirror_up.zmx",
        "rayoptics__asp46.seq",
    ] {
        let path = common::test_data(&format!("corpus/{name}"));
        let out = common::lensbake(&["analyze", path.to_str().unwrap(), "--json"]);
        assert!(
            out.status.success(),
            "{name}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(json["afocal"], true, "{name}");
        let gamma = json["angular_magnification"].as_f64().unwrap();
        assert!((gamma - 1.0).abs() < 1e-12, "{name}: {gamma}");
    }
}

#[test]
fn a_finite_object_is_refused_with_a_reason() {
    let out = common::lensbake(&[
        "analyze",
        common::test_data("corpus/rayoptics__dec_test.seq")
            .to_str()
            .unwrap(),
        "--object-distance-mm",
        "500",
    ]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        stderr.starts_with("error:") && stderr.contains("collimated beam"),
        "{stderr}"
    );
}
