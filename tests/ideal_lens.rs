//! Ideal lenses (Zemax's paraxial surface, `Shape::IdealLens`) against the identities of a
//! perfect thin lens: its focal length and the thin-lens conjugates, zero Seidel sums, real rays
//! that meet in one point at any height and slope, both trace paths alike; and the Zemax reader,
//! the writers and the analyses that cannot take one.
#![cfg(feature = "cli")]

mod common;

use lensbake::analysis::{AnalyzeOptions, analyze};
use lensbake::prescription::RayAiming;
use lensbake::prescription::formats::{Format, LoadOptions, read_str, write_pbrt, write_zemax};
use lensbake::prescription::{
    Medium, Prescription, Problem, Provenance, Shape, StopShape, Surface,
};
use lensbake::system::LensSystem;
use lensbake::trace::{Apertures, Ray, RayBatch, Tracer, Travel};
use lensbake::wave::{PupilTrace, Sampling, WaveError, WaveLens};

const WAVELENGTH_NM: f64 = 587.5618;

/// A stop 10 mm before an ideal lens of focal length `f`, the film `film` behind it.
fn ideal(f: f64, film: f64) -> Prescription {
    Prescription {
        provenance: Provenance {
            title: "ideal lens".into(),
            design_wavelength_nm: Some(WAVELENGTH_NM),
            ..Provenance::default()
        },
        object_medium: Medium::Air,
        surfaces: vec![
            Surface {
                stop: Some(StopShape::Circle),
                ..Surface::open(Shape::Plane, 10.0, Medium::Air, 10.0)
            },
            Surface::open(
                Shape::IdealLens { focal_length: f },
                film,
                Medium::Air,
                20.0,
            ),
        ],
    }
}

fn system(p: Prescription) -> LensSystem {
    LensSystem::from_prescription(p).unwrap()
}

#[test]
fn focal_length_conjugates_and_zero_seidel_sums() {
    let lens = system(ideal(100.0, 100.0));
    let options = AnalyzeOptions {
        epd_mm: Some(20.0),
        field_deg: Some(10.0),
        ..AnalyzeOptions::default()
    };
    let a = analyze(&lens, &options).unwrap();
    assert!(
        (a.first_order.efl - 100.0).abs() < 1e-12,
        "{}",
        a.first_order.efl
    );
    assert!(
        (a.first_order.bfl - 100.0).abs() < 1e-12,
        "{}",
        a.first_order.bfl
    );
    let sums = a.seidel.sums;
    for (what, value) in [
        ("S_I", sums.spherical),
        ("S_II", sums.coma),
        ("S_III", sums.astigmatism),
        ("S_IV", sums.petzval),
        ("S_V", sums.distortion),
    ] {
        assert_eq!(value, 0.0, "{what}");
    }

    // An object 150 mm before the lens (140 mm before the stop) images 300 mm behind it at -2x:
    // 1/150 + 1/300 = 1/100.
    let finite = AnalyzeOptions {
        object_distance_mm: Some(140.0),
        ..options
    };
    let a = analyze(&lens, &finite).unwrap();
    assert!((a.first_order.z_paraxial_image - 310.0).abs() < 1e-9);
    assert!((a.first_order.magnification.unwrap() + 2.0).abs() < 1e-12);
}

/// Every ray of a parallel bundle at 10 degrees meets the focal plane at f tan(10 deg); every
/// ray from an off-axis point 150 mm before the lens meets the one point 300 mm behind it at
/// -2 times its height. Exact, not paraxial: heights up to the lens's 20 mm rim.
#[test]
fn real_rays_meet_in_one_point_at_every_height_and_slope() {
    let f = 100.0;
    let tracer = Tracer::new(&system(ideal(f, f)).at(WAVELENGTH_NM));
    let slope = 10f64.to_radians().tan();
    let mut parallel = 0;
    for k in 0..=20 {
        for j in 0..=20 {
            let (x, y) = (-9.0 + 0.9 * f64::from(k), -9.0 + 0.9 * f64::from(j));
            let ray = Ray::new([x, y, -5.0], [0.0, slope, 1.0]).unwrap();
            let out = tracer.trace_with(ray, Travel::Forward, Apertures::Ignored);
            if !out.outcome.is_ok() {
                continue;
            }
            let at = out.ray.point_at_z(10.0 + f).unwrap();
            assert!(
                at[0].abs() < 1e-12 && (at[1] - f * slope).abs() < 1e-12,
                "{at:?}"
            );
            parallel += 1;
        }
    }
    assert_eq!(parallel, 441);
    let object = [2.0, -3.0, -140.0];
    for k in 0..40 {
        let angle = f64::from(k) * 0.7;
        let radius = 0.45 * f64::from(k);
        let target = [radius * angle.cos(), radius * angle.sin(), 10.0];
        let d = [0, 1, 2].map(|i| target[i] - object[i]);
        let out = tracer.trace_with(
            Ray::new(object, d).unwrap(),
            Travel::Forward,
            Apertures::Ignored,
        );
        assert!(out.outcome.is_ok());
        let at = out.ray.point_at_z(10.0 + 300.0).unwrap();
        assert!(
            (at[0] + 4.0).abs() < 1e-11 && (at[1] - 6.0).abs() < 1e-11,
            "{at:?}"
        );
        // Reversed, the ray goes back to the object point.
        let back = tracer.trace_with(
            Ray::new(at, out.ray.direction().map(|v| -v)).unwrap(),
            Travel::Backward,
            Apertures::Ignored,
        );
        assert!(back.outcome.is_ok());
        let start = back.ray.point_at_z(object[2]).unwrap();
        assert!((start[0] - object[0]).abs() < 1e-10 && (start[1] - object[1]).abs() < 1e-10);
    }
}

#[test]
fn the_batch_trace_crosses_an_ideal_lens_as_the_one_ray_trace_does() {
    let tracer = Tracer::new(&system(ideal(-60.0, 50.0)).at(WAVELENGTH_NM));
    let mut batch = RayBatch::new();
    for i in 0..300 {
        let a = f64::from(i) * 0.37;
        let r = 14.0 * (f64::from(i) / 300.0).sqrt();
        batch.push(
            Ray::new(
                [r * a.cos(), r * a.sin(), -3.0],
                [0.02 * a.sin(), 0.05, 1.0],
            )
            .unwrap(),
        );
    }
    let passed = common::batch_matches_one_ray(&tracer, &batch);
    assert!(passed > 100 && passed < 300, "{passed} rays passed");
}

/// `TYPE PARAXIAL` with its focal length in PARM 1 and OPD mode in PARM 2, a pickup of PARM 1
/// from another column (SURF 0's thickness) read as written; written back as the same surface.
const ZEMAX: &str = "VERS 190513 80 123456\nMODE SEQ\nUNIT MM X W X CM MR CPMM\nENPD 20\n\
    WAVM 1 0.5875618 1\nPWAV 1\n\
    SURF 0\n  TYPE STANDARD\n  CURV 0.0\n  DISZ 100\n\
    SURF 1\n  TYPE PARAXIAL\n  CURV 0.0\n  PARM 1 100\n\
      PPAR 1 0 1.0 0.0 2\n  PARM 2 1\n  DISZ 10\n  DIAM 20 0 0 0 1 \"\"\n\
    SURF 2\n  STOP\n  TYPE STANDARD\n  CURV 0.0\n  DISZ 50\n  DIAM 10 0 0 0 1 \"\"\n\
    SURF 3\n  TYPE PARAXIAL\n  CURV 0.0\n  PARM 1 50\n  DISZ 50\n  DIAM 10 0 0 0 1 \"\"\n\
    SURF 4\n  TYPE STANDARD\n  CURV 0\n  DISZ 0\n";

fn zemax(text: &str) -> Result<LensSystem, lensbake::prescription::PrescriptionError> {
    let loaded = read_str(text, None, Format::Zemax, &LoadOptions::default())?;
    LensSystem::new(loaded.prescription, &loaded.map)
}

#[test]
fn zemax_paraxial_surfaces_read_write_and_refuse_what_they_cannot_be() {
    let lens = zemax(ZEMAX).unwrap();
    let shapes: Vec<&Shape> = lens
        .prescription
        .surfaces
        .iter()
        .map(|s| &s.shape)
        .collect();
    assert_eq!(
        shapes,
        [
            &Shape::IdealLens {
                focal_length: 100.0
            },
            &Shape::Plane,
            &Shape::IdealLens { focal_length: 50.0 },
        ]
    );
    // A point 100 mm before a lens of 100 mm is collimated, and the second lens focuses: the
    // image lies at its focus, 50 mm behind it.
    let a = analyze(&lens, &AnalyzeOptions::default()).unwrap();
    assert!((a.first_order.z_paraxial_image - 110.0).abs() < 1e-9);

    let written = write_zemax(&lens.prescription).unwrap();
    assert!(written.contains("TYPE PARAXIAL"), "{written}");
    let again = zemax(&written).unwrap();
    assert_eq!(again.prescription.surfaces, lens.prescription.surfaces);
    assert!(matches!(
        write_pbrt(&lens.prescription, WAVELENGTH_NM),
        Err(Problem::Unsupported(what)) if what.contains("ideal lens")
    ));

    let curved = ZEMAX.replacen("TYPE PARAXIAL\n  CURV 0.0", "TYPE PARAXIAL\n  CURV 0.01", 1);
    let e = zemax(&curved).unwrap_err();
    assert_eq!(e.location.field.as_deref(), Some("TYPE PARAXIAL"), "{e}");
    let in_glass = ZEMAX.replacen("  PARM 2 1\n", "  PARM 2 1\n  GLAS N-BK7 0 0 1.5 40\n", 1);
    let e = zemax(&in_glass).unwrap_err();
    assert!(
        matches!(&e.problem, Problem::Unsupported(what) if what.contains("ideal lens between air and N-BK7")),
        "{e}"
    );
    assert_eq!(e.location.surface, Some(1));
}

#[test]
fn wave_optics_refuses_an_ideal_lens_by_its_surface() {
    let lens = system(ideal(100.0, 100.0));
    let wave_lens = WaveLens::Real {
        system: &lens,
        epd_mm: None,
        object_distance_mm: None,
        ray_aiming: RayAiming::Paraxial,
    };
    let sampling = Sampling::default();
    let e = PupilTrace::trace(&wave_lens, 0.0, WAVELENGTH_NM, WAVELENGTH_NM, sampling).unwrap_err();
    assert!(matches!(e, WaveError::IdealLensPath { surface: 2 }), "{e}");
}

/// As a user runs it: `lens check` names the ideal lenses, and `report` draws every figure but
/// the wave-optics ones, which it skips with the reason.
#[test]
fn the_cli_lists_ideal_lenses_and_the_report_says_why_wave_figures_are_skipped() {
    let dir = std::env::temp_dir().join(format!("lensbake-ideal-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("paraxial.zmx");
    std::fs::write(&file, ZEMAX).unwrap();
    let run = |args: &[&str]| {
        std::process::Command::new(env!("CARGO_BIN_EXE_lensbake"))
            .args(args)
            .output()
            .unwrap()
    };
    let check = run(&["lens", "check", file.to_str().unwrap()]);
    assert_eq!(check.status.code(), Some(0));
    let listing = String::from_utf8_lossy(&check.stdout);
    assert!(
        listing.contains("ideal lens:  surface 1, focal length 100.0000 mm"),
        "{listing}"
    );
    let out = dir.join("report");
    let report = run(&[
        "report",
        file.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    let stderr = String::from_utf8_lossy(&report.stderr);
    assert_eq!(report.status.code(), Some(0), "{stderr}");
    assert!(out.join("spot.png").is_file());
    assert!(!out.join("mtf-field.png").exists());
    assert!(
        stderr.contains("mtf-field skipped: surface 1 is an ideal lens"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A focal length too short for the trace to hold its bends is refused where it is written, and
/// a ray grazing an ideal lens ends as a miss there, never with a NaN direction.
#[test]
fn extreme_focal_lengths_and_grazing_rays() {
    for focal_length in ["0", "1e-320", "5e-7"] {
        let text = ZEMAX.replacen("  PARM 1 100\n", &format!("  PARM 1 {focal_length}\n"), 1);
        let e = zemax(&text).unwrap_err();
        assert_eq!(e.location.field.as_deref(), Some("focal_length"), "{e}");
        assert_eq!(e.location.surface, Some(1), "{e}");
    }
    // A fifth PPAR field that is no number is refused where it stands, not read as a column.
    let garbled = ZEMAX.replacen("PPAR 1 0 1.0 0.0 2", "PPAR 1 0 1.0 0.0 two", 1);
    let e = zemax(&garbled).unwrap_err();
    assert_eq!(e.location.field.as_deref(), Some("PPAR"), "{e}");
    let tracer = Tracer::new(&system(ideal(100.0, 100.0)).at(WAVELENGTH_NM));
    let grazing = Ray::new([0.0, 0.0, -10.0], [1.0, 0.0, 1e-300]).unwrap();
    let out = tracer.trace_with(grazing, Travel::Forward, Apertures::Ignored);
    assert_eq!(out.outcome, lensbake::trace::Outcome::Missed { surface: 2 });
    assert!(out.ray.direction().iter().all(|v| v.is_finite()));
}

/// After a mirror light is back in the medium it met the mirror in: an ideal lens there lies in
/// air when the mirror does, and in glass behind a Mangin mirror's glass.
#[test]
fn an_ideal_lens_after_a_mirror_takes_the_medium_before_it() {
    let lens_after = |first: Medium| Prescription {
        provenance: Provenance::default(),
        object_medium: Medium::Air,
        surfaces: vec![
            Surface::open(Shape::Plane, 5.0, first, 20.0),
            Surface {
                stop: Some(StopShape::Circle),
                ..Surface::open(Shape::from_radius(-200.0), -50.0, Medium::Mirror, 20.0)
            },
            Surface::open(
                Shape::IdealLens { focal_length: 80.0 },
                -40.0,
                Medium::Air,
                20.0,
            ),
        ],
    };
    assert_eq!(lens_after(Medium::Air).medium_before(2), &Medium::Air);
    LensSystem::from_prescription(lens_after(Medium::Air)).unwrap();
    let e = LensSystem::from_prescription(lens_after(Medium::Index(1.5))).unwrap_err();
    assert!(
        matches!(&e.problem, Problem::Unsupported(what) if what.contains("ideal lens between n = 1.5")),
        "{e}"
    );
}
