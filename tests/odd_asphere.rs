//! Odd aspheres (Zemax `ODDASPHE`, terms on r, r^2, r^3, ...): read, traced exactly, and seen by
//! paraxial optics through their r^2 term alone.

mod common;

use lensbake::paraxial::FirstOrder;
use lensbake::prescription::formats::{LoadOptions, read_file};
use lensbake::prescription::{Medium, Shape};
use lensbake::system::LensSystem;
use lensbake::trace::{Outcome, Ray, Tracer, Travel};
use serde_json::Value;

const WAVELENGTH_NM: f64 = 587.5618;

fn peer() -> Value {
    let text = std::fs::read_to_string(common::test_data("odd_asphere_peer.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// The test lens `name`, its glass replaced by the index the peer used.
fn system(name: &str, glass_index: f64) -> LensSystem {
    let mut p = read_file(&common::test_data(name), &LoadOptions::default())
        .unwrap_or_else(|e| panic!("{name}: {e}"))
        .prescription;
    for s in &mut p.surfaces {
        if matches!(s.medium, Medium::Glass(_)) {
            s.medium = Medium::Index(glass_index);
        }
    }
    LensSystem::from_prescription(p).unwrap()
}

/// Traces the ray from (x, y) on the first vertex's plane along (tx, ty, 1) to the image plane.
fn image_point(tracer: &Tracer, image_z: f64, [x, y, tx, ty]: [f64; 4]) -> [f64; 3] {
    let traced = tracer.trace(
        Ray::new([x, y, 0.0], [tx, ty, 1.0]).unwrap(),
        Travel::Forward,
    );
    assert_eq!(traced.outcome, Outcome::Ok);
    let (p, d) = (traced.ray.position(), traced.ray.direction());
    let t = (image_z - p[2]) / d[2];
    [p[0] + t * d[0], p[1] + t * d[1], image_z]
}

#[test]
fn the_reader_keeps_each_term_on_its_power_of_r() {
    let p = read_file(
        &common::test_data("odd_asphere_cone.zmx"),
        &LoadOptions::default(),
    )
    .unwrap()
    .prescription;
    let Shape::OddAsphere {
        curvature,
        conic,
        coefficients,
    } = &p.surfaces[0].shape
    else {
        panic!("{:?}", p.surfaces[0].shape);
    };
    assert_eq!((*curvature, *conic), (0.02, -0.5));
    assert_eq!(coefficients, &[0.0, 1e-3, 2e-5, -3e-6, 1e-8]);
    assert_eq!(p.surfaces[1].shape.aspheric_term(1), 2e-3);
    assert_eq!(p.surfaces[1].shape.aspheric_term(3), -1e-5);
    assert_eq!(p.surfaces[1].shape.aspheric_term(6), 2e-9);
    // The sag as OpticStudio writes it, term by term.
    let r: f64 = 7.5;
    let base = 0.02 * r * r / (1.0 + (1.0 - 0.5 * 0.02 * 0.02 * r * r).sqrt());
    let terms = 1e-3 * r.powi(2) + 2e-5 * r.powi(3) - 3e-6 * r.powi(4) + 1e-8 * r.powi(5);
    common::assert_close(
        p.surfaces[0].shape.sag(r).unwrap(),
        base + terms,
        1e-15,
        0.0,
        "sag",
    );
}

/// Ray by ray against optiland 0.6.3's trace of both test lenses (tools/odd_asphere_peer.py):
/// rays up to 9.5 mm off the axis of a 22 mm singlet, oblique, through a cone term (r) on one
/// face and r^3, r^5 and r^6 terms on both. They agree to 1e-11 mm (below 1e-13 measured): both
/// follow the same sag and normals; reading PARM n as the coefficient of r^(2n), say, would move
/// them by millimetres.
#[test]
fn rays_land_where_optiland_traces_them() {
    let peer = peer();
    let glass_index = peer["glass_index"].as_f64().unwrap();
    for (name, lens) in peer["lenses"].as_object().unwrap() {
        let tracer = Tracer::new(&system(name, glass_index).at(WAVELENGTH_NM));
        let rays = common::nums_rows(&lens["rays"]);
        let expected = common::nums_rows(&lens["image_points"]);
        for (ray, want) in rays.iter().zip(&expected) {
            let got = image_point(&tracer, want[2], [ray[0], ray[1], ray[2], ray[3]]);
            for axis in 0..2 {
                assert!(
                    (got[axis] - want[axis]).abs() < 1e-11,
                    "{name} {ray:?}: {got:?} against {want:?}"
                );
            }
        }
    }
}

/// Paraxial optics sees an odd asphere's r^2 term (vertex curvature c + 2 a2): its focal length
/// is the exact trace's in the limit of small heights, here a ray 1e-7 mm above the axis (the r^3
/// terms bend it by a relative 1e-10). A paraxial trace from the curvature alone (optiland's)
/// is off by 8 %; a ray 1e-4 mm above the axis, which optiland traces exactly, lands where
/// lensbake traces it.
#[test]
fn paraxial_focal_length_is_the_exact_traces_small_height_limit() {
    let peer = peer();
    let glass_index = peer["glass_index"].as_f64().unwrap();
    let at = system("odd_asphere_singlet.zmx", glass_index).at(WAVELENGTH_NM);
    let tracer = Tracer::new(&at);
    let focal_length_at = |height: f64| {
        let traced = tracer.trace(
            Ray::new([0.0, height, 0.0], [0.0, 0.0, 1.0]).unwrap(),
            Travel::Forward,
        );
        let d = traced.ray.direction();
        -height / (d[1] / d[2])
    };
    let efl = FirstOrder::of(&at).unwrap().efl;
    common::assert_close(focal_length_at(1e-7), efl, 1e-9, 0.0, "paraxial limit");
    let optiland = &peer["near_axis_focal_length"];
    let height = optiland["height"].as_f64().unwrap();
    common::assert_close(
        focal_length_at(height),
        optiland["value"].as_f64().unwrap(),
        1e-11,
        0.0,
        "optiland's ray 1e-4 mm high",
    );
}
