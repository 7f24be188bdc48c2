//! The crossing check: an overlap within the rounding of a printed table (1e-5 of the lens's
//! size) is touching at any scale; published lenses whose glass cannot exist are refused, with
//! the deepest overlap stated.

mod common;

use lensbake::prescription::formats::{LoadOptions, read_file};
use lensbake::prescription::{
    Medium, Prescription, PrescriptionError, Problem, Provenance, Shape, StopShape, Surface,
};
use lensbake::system::LensSystem;

fn load(path: &str) -> Result<LensSystem, PrescriptionError> {
    let loaded = read_file(&common::test_data(path), &LoadOptions::default()).unwrap();
    LensSystem::new(loaded.prescription, &loaded.map)
}

/// Sag of a sphere of radius `radius` at height `r`.
fn sag(radius: f64, r: f64) -> f64 {
    radius - radius.signum() * (radius * radius - r * r).sqrt()
}

#[test]
fn published_lenses_whose_faces_cross_are_refused_with_the_deepest_overlap() {
    // ISET's fisheye: surface 6 (R -133.93) and 7 (R -79.34), 2.16 mm apart, within surface
    // 7's 29 mm semi-aperture; the sags cross most at the rim.
    let error = load("lens-tables/iset3d__fisheye.87deg.50.0mm.dat").unwrap_err();
    let Problem::SurfacesCross { next, radius, gap } = error.problem else {
        panic!("{error}");
    };
    assert_eq!((next, error.location.surface), (7, Some(6)));
    assert_eq!(radius, 29.0);
    let expected = 2.16 + sag(-79.34, 29.0) - sag(-133.93, 29.0);
    assert!((gap - expected).abs() < 1e-12, "{gap} vs {expected}");
    // 0.15 mm: a thousandth of the lens's 160 mm aperture, a hundred times the rounding.
    assert!(gap < -0.15, "{gap}");

    // After a mirror, an element 0.25 mm thick on axis whose front curves back 0.28 mm at its
    // 0.875 mm rim: its faces cross by 0.033 mm, 1.9% of its diameter.
    let error = load("corpus/rayoptics__lens_reflection_test.seq").unwrap_err();
    let Problem::SurfacesCross { next, gap, .. } = error.problem else {
        panic!("{error}");
    };
    assert_eq!(next, 4);
    assert!((-0.034..-0.032).contains(&gap), "{gap}");
}

/// A plate of semi-aperture `semi` followed by a second plate `-overlap` mm behind it: its
/// faces overlap by `overlap` everywhere.
fn overlapping_plates(semi: f64, overlap: f64) -> Result<LensSystem, PrescriptionError> {
    let glass = Medium::Index(1.5);
    LensSystem::from_prescription(Prescription {
        provenance: Provenance::default(),
        object_medium: Medium::Air,
        surfaces: vec![
            Surface {
                stop: Some(StopShape::Circle),
                ..Surface::open(Shape::Plane, semi / 5.0, glass.clone(), semi)
            },
            Surface::open(Shape::Plane, -overlap, Medium::Air, semi),
            Surface::open(Shape::Plane, semi / 5.0, glass, semi),
            Surface::open(Shape::Plane, 10.0, Medium::Air, semi),
        ],
    })
}

#[test]
fn the_tolerance_scales_with_the_lens() {
    for semi in [5.0, 50.0, 500.0] {
        let diameter = 2.0 * semi;
        assert!(
            overlapping_plates(semi, 0.5e-5 * diameter).is_ok(),
            "{semi}"
        );
        let error = overlapping_plates(semi, 2e-5 * diameter).unwrap_err();
        assert!(
            matches!(error.problem, Problem::SurfacesCross { next: 3, .. }),
            "{semi}: {error}"
        );
    }
}
