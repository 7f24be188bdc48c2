//! Analytic identities of first- and third-order optics, on lenses built in code and on the
//! oracle lenses: closed forms (singlet), invariants (Lagrange, chief ray through the stop
//! centre), inverse pairs (focusing), stop-shift formulas and aberration-free aspheres.

mod common;

use common::{ORACLE_LENSES, assert_close, load_oracle};
use lensbake::glass::{C_LINE_NM, F_LINE_NM};
use lensbake::paraxial::{
    Aperture, Field, FirstOrder, ObjectPosition, Paraxial, ParaxialError, ParaxialOptions,
    StopChoice, entrance_pupil, limiting_surface, object_in_focus, sensor_z,
};
use lensbake::prescription::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
use lensbake::seidel::{IndexDifferences, Seidel, aspheric_r4_departure};
use lensbake::system::{LensSystem, SystemAt};

const WAVELENGTH_NM: f64 = 587.56;

fn surface(shape: Shape, thickness: f64, n: f64, semi_aperture: f64, stop: bool) -> Surface {
    Surface {
        shape,
        thickness,
        medium: if n == 1.0 {
            Medium::Air
        } else {
            Medium::Index(n)
        },
        semi_aperture,
        stop: stop.then_some(StopShape::Circle),
        obscuration: None,
    }
}

fn sphere(curvature: f64) -> Shape {
    Shape::Sphere { curvature }
}

fn lens_system(surfaces: Vec<Surface>) -> LensSystem {
    LensSystem::from_prescription(Prescription {
        provenance: Provenance::default(),
        object_medium: Medium::Air,
        surfaces,
    })
    .expect("valid test lens")
}

fn system(surfaces: Vec<Surface>) -> SystemAt {
    lens_system(surfaces).at(WAVELENGTH_NM)
}

/// Biconvex singlet n = 1.5, R = +50 / -50, t = 10, stop on the front surface.
fn singlet() -> SystemAt {
    system(vec![
        surface(sphere(1.0 / 50.0), 10.0, 1.5, 15.0, true),
        surface(sphere(-1.0 / 50.0), 40.0, 1.0, 15.0, false),
    ])
}

fn oracle_system(name: &str) -> SystemAt {
    let oracle = load_oracle(name);
    LensSystem::from_prescription(oracle.prescription.clone())
        .unwrap()
        .at(oracle.wavelength_nm())
}

fn infinite_at(deg: f64) -> ParaxialOptions {
    ParaxialOptions {
        field: Field::Angle { deg },
        ..ParaxialOptions::default()
    }
}

#[test]
fn singlet_thick_lens_closed_form() {
    let f = FirstOrder::of(&singlet()).unwrap();
    // Thick-lens formulas: P = P1 + P2 - P1 P2 t / n, principal planes f P2 t / n inside the
    // front vertex and f P1 t / n inside the rear one. Here EFL = 1500/29 = 51.7241379...
    let (p1, p2, t, n) = (0.5 / 50.0, 0.5 / 50.0, 10.0, 1.5);
    let power = p1 + p2 - p1 * p2 * t / n;
    let efl = 1.0 / power;
    assert_close(efl, 1500.0 / 29.0, 1e-15, 0.0, "closed form itself");
    assert_close(f.efl, efl, 1e-12, 0.0, "EFL");
    assert_close(f.fl_object, efl, 1e-12, 0.0, "object-side focal length");
    let inset = efl * p2 * t / n; // 3.4482758620...
    assert_close(
        inset,
        100.0 / 29.0,
        1e-15,
        0.0,
        "principal-plane inset itself",
    );
    assert_close(
        f.z_front_principal,
        inset,
        1e-12,
        0.0,
        "front principal plane",
    );
    assert_close(
        f.z_rear_principal,
        t - inset,
        1e-12,
        0.0,
        "rear principal plane",
    );
    assert_close(f.bfl, efl - inset, 1e-12, 0.0, "BFL");
    assert_close(f.ffl, -(efl - inset), 1e-12, 0.0, "FFL");
    // In air the nodal points are the principal points.
    assert_close(
        f.z_front_nodal,
        f.z_front_principal,
        1e-12,
        0.0,
        "front nodal point",
    );
    assert_close(
        f.z_rear_nodal,
        f.z_rear_principal,
        1e-12,
        0.0,
        "rear nodal point",
    );
}

/// Different indices on both sides: the focal lengths differ by n'/n and the nodal points
/// move (n' - n)/power from the principal points.
#[test]
fn single_surface_between_media() {
    let (c, n) = (1.0 / 20.0, 1.6);
    let f = FirstOrder::of(&system(vec![surface(sphere(c), 50.0, n, 5.0, true)])).unwrap();
    let power = c * (n - 1.0);
    assert_close(f.efl, n / power, 1e-14, 0.0, "EFL");
    assert_close(
        f.fl_object,
        1.0 / power,
        1e-14,
        0.0,
        "object-side focal length",
    );
    assert_close(f.z_front_principal, 0.0, 0.0, 1e-14, "P at the vertex");
    assert_close(f.z_rear_principal, 0.0, 0.0, 1e-14, "P' at the vertex");
    // Both nodal points lie at the centre of curvature.
    assert_close(
        f.z_front_nodal,
        1.0 / c,
        1e-14,
        0.0,
        "N at the centre of curvature",
    );
    assert_close(
        f.z_rear_nodal,
        1.0 / c,
        1e-14,
        0.0,
        "N' at the centre of curvature",
    );
}

#[test]
fn a_plane_parallel_plate_is_afocal() {
    let plate = system(vec![
        surface(Shape::Plane, 5.0, 1.5, 10.0, true),
        surface(Shape::Plane, 10.0, 1.0, 10.0, false),
    ]);
    assert_eq!(FirstOrder::of(&plate), Err(ParaxialError::Afocal));
    assert_eq!(
        Paraxial::new(&plate, &ParaxialOptions::default()).unwrap_err(),
        ParaxialError::Afocal
    );
}

/// The r^2 term of an asphere curves the vertex: paraxially it is the sphere c + 2 a1, whether
/// the terms are in r^2 (even) or in r (odd, where the r and r^3 terms have no paraxial part).
#[test]
fn asphere_r2_term_is_vertex_curvature() {
    let (c, a1) = (1.0 / 40.0, 0.004);
    let plain = FirstOrder::of(&system(vec![surface(sphere(c), 30.0, 1.5, 5.0, true)])).unwrap();
    for asphere in [
        Shape::EvenAsphere {
            curvature: c - 2.0 * a1,
            conic: 0.0,
            coefficients: vec![a1],
        },
        Shape::OddAsphere {
            curvature: c - 2.0 * a1,
            conic: 0.0,
            coefficients: vec![3e-3, a1, -2e-5],
        },
    ] {
        let with = FirstOrder::of(&system(vec![surface(asphere, 30.0, 1.5, 5.0, true)])).unwrap();
        assert_close(with.efl, plain.efl, 1e-14, 0.0, "EFL");
    }
}

#[test]
fn focusing_round_trips_and_reports_where_no_image_exists() {
    let at = singlet();
    let f = FirstOrder::of(&at).unwrap();
    assert_eq!(
        sensor_z(&at, ObjectPosition::Infinite).unwrap(),
        f.z_rear_focal
    );
    assert_eq!(
        object_in_focus(&at, f.z_rear_focal).unwrap(),
        ObjectPosition::Infinite
    );
    for distance in [60.0, 100.0, 1000.0, 1e6] {
        let z = sensor_z(&at, ObjectPosition::Finite { distance }).unwrap();
        // Newton's equation x x' = -f f' with x, x' from the focal points; x' is a small
        // difference of positions, known to rounding of z.
        let (x, x_image) = (-distance - f.z_front_focal, z - f.z_rear_focal);
        assert_close(
            x_image,
            -f.efl * f.fl_object / x,
            1e-12,
            1e-14 * z.abs(),
            "Newton",
        );
        match object_in_focus(&at, z).unwrap() {
            ObjectPosition::Finite { distance: back } => {
                assert_close(back, distance, 1e-9, 0.0, "round trip")
            }
            ObjectPosition::Infinite => panic!("{distance} mm came back as infinity"),
        }
    }
    // The object exactly in the front focal plane.
    assert_eq!(
        sensor_z(&at, ObjectPosition::Finite { distance: -f.ffl }),
        Err(ParaxialError::ObjectAtFrontFocalPlane)
    );
    // Inside the front focal length the image is virtual.
    assert!(matches!(
        sensor_z(
            &at,
            ObjectPosition::Finite {
                distance: -f.ffl / 2.0
            }
        ),
        Err(ParaxialError::VirtualImage { .. })
    ));
    for distance in [0.0, -5.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            sensor_z(&at, ObjectPosition::Finite { distance }),
            Err(ParaxialError::ObjectNotInFront { .. })
        ));
    }
    // Sensors in front of the last vertex, or between it and F' (no real object there).
    assert!(matches!(
        object_in_focus(&at, f.z_last_vertex - 1.0),
        Err(ParaxialError::SensorInsideLens { .. })
    ));
    assert!(matches!(
        object_in_focus(&at, f.z_rear_focal - 1.0),
        Err(ParaxialError::NoRealObject { .. })
    ));
    // A diverging lens forms no real image of a distant object.
    let negative = system(vec![
        surface(sphere(-1.0 / 50.0), 3.0, 1.5, 10.0, true),
        surface(sphere(1.0 / 50.0), 20.0, 1.0, 10.0, false),
    ]);
    assert!(matches!(
        sensor_z(&negative, ObjectPosition::Infinite),
        Err(ParaxialError::VirtualImage { .. })
    ));
}

/// The entrance pupil is the image of the stop by the lens in front of it: the thick-lens
/// equation of that front group, run backwards, must land on the matrix result.
#[test]
fn entrance_pupil_is_the_stop_imaged_backwards() {
    let at = system(vec![
        surface(sphere(1.0 / 50.0), 10.0, 1.5, 15.0, false),
        surface(sphere(-1.0 / 50.0), 12.0, 1.0, 15.0, false),
        surface(Shape::Plane, 30.0, 1.0, 4.0, true),
    ]);
    let (z_pupil, scale) = entrance_pupil(&at, 2).unwrap();
    let front = FirstOrder::of(&system(vec![
        surface(sphere(1.0 / 50.0), 10.0, 1.5, 15.0, false),
        surface(sphere(-1.0 / 50.0), 12.0, 1.0, 15.0, true),
    ]))
    .unwrap();
    let z_stop = 22.0;
    assert_close(
        z_pupil,
        front.object_z(z_stop).unwrap(),
        1e-12,
        0.0,
        "EP position",
    );
    assert_close(
        1.0 / scale,
        1.0 / front.magnification(z_pupil, z_stop),
        1e-12,
        0.0,
        "EP scale",
    );
    // A stop on the first surface is its own entrance pupil.
    assert_eq!(entrance_pupil(&singlet(), 0).unwrap(), (0.0, 1.0));
}

/// On the oracle lenses, at both conjugates: the chief ray crosses the stop at its centre,
/// the marginal ray fills the stop, and the Lagrange invariant is the same in every space.
#[test]
fn ray_invariants_on_the_oracle_lenses() {
    for name in ORACLE_LENSES {
        let at = oracle_system(name);
        for object in [
            ObjectPosition::Infinite,
            ObjectPosition::Finite { distance: 700.0 },
        ] {
            let p = Paraxial::new(
                &at,
                &ParaxialOptions {
                    object,
                    aperture: Aperture::StopClearAperture,
                    field: Field::Angle { deg: 10.0 },
                    stop: StopChoice::Marked,
                },
            )
            .unwrap();
            let stop_ray = &p.chief.surfaces[p.stop];
            assert_close(
                stop_ray.y,
                0.0,
                0.0,
                1e-12,
                &format!("{name} chief ray at the stop"),
            );
            assert_close(
                p.marginal.surfaces[p.stop].y.abs(),
                at.surfaces[p.stop].semi_aperture,
                1e-12,
                0.0,
                &format!("{name} marginal ray fills the stop"),
            );
            for (k, (m, c)) in p
                .marginal
                .surfaces
                .iter()
                .zip(&p.chief.surfaces)
                .enumerate()
            {
                let n = at.surfaces[k].index_after;
                let h = n * (m.y * c.u_after - c.y * m.u_after);
                assert_close(
                    h,
                    p.lagrange_invariant,
                    1e-12,
                    0.0,
                    &format!("{name} H after surface {}", k + 1),
                );
            }
            // H = n' u' h' in the image: the marginal slope times the image height.
            let image = at.image_index() * (-p.marginal.image_slope()) * p.image_height;
            assert_close(
                image,
                p.lagrange_invariant,
                1e-11,
                0.0,
                &format!("{name} H in the image"),
            );
        }
    }
}

/// At the paraxial field limit the chief ray just touches one clear aperture and clears the
/// others; the limiting-stop search picks a surface the axial beam just fills.
#[test]
fn field_and_aperture_limits() {
    for name in ORACLE_LENSES {
        let at = oracle_system(name);
        let p = Paraxial::new(&at, &ParaxialOptions::default()).unwrap();
        let max = p
            .max_field_angle_deg
            .expect("some aperture limits the field");
        assert_eq!(p.field_angle_deg, max);
        let margins: Vec<f64> = p
            .chief
            .surfaces
            .iter()
            .zip(&at.surfaces)
            .map(|(ray, s)| s.semi_aperture - ray.y.abs())
            .collect();
        let tightest = margins.iter().copied().fold(f64::INFINITY, f64::min);
        assert_close(
            tightest,
            0.0,
            0.0,
            1e-12,
            &format!("{name} chief ray touches an aperture"),
        );

        let stop = limiting_surface(&at, ObjectPosition::Infinite).unwrap();
        let p = Paraxial::new(
            &at,
            &ParaxialOptions {
                stop: StopChoice::LimitingAxialBeam,
                field: Field::Angle { deg: 0.0 },
                ..ParaxialOptions::default()
            },
        )
        .unwrap();
        assert_eq!(p.stop, stop);
        for (k, (ray, s)) in p.marginal.surfaces.iter().zip(&at.surfaces).enumerate() {
            assert!(
                ray.y.abs() <= s.semi_aperture * (1.0 + 1e-12),
                "{name}: axial beam overfills surface {}",
                k + 1
            );
        }
        assert_close(
            p.marginal.surfaces[stop].y.abs(),
            at.surfaces[stop].semi_aperture,
            1e-12,
            0.0,
            "fills the stop",
        );
    }
}

/// Moving the stop changes the chief ray by E times the marginal ray (ybar* = ybar + E y),
/// and the sums follow Welford's stop-shift formulas exactly, S_V and its H term included.
#[test]
fn seidel_stop_shift_formulas() {
    let at = oracle_system("optiland_cooke_triplet");
    let options = |stop: StopChoice| ParaxialOptions {
        aperture: Aperture::EntrancePupilDiameter(10.0),
        field: Field::Angle { deg: 15.0 },
        stop,
        ..ParaxialOptions::default()
    };
    let original = Paraxial::new(&at, &options(StopChoice::Marked)).unwrap();
    let mut shifted_system = at.clone();
    shifted_system.stop = 0;
    let shifted = Paraxial::new(&shifted_system, &options(StopChoice::Marked)).unwrap();
    let s = Seidel::new(&at, &original, None).sums;
    let t = Seidel::new(&shifted_system, &shifted, None).sums;
    let e = (shifted.chief.surfaces[3].y - original.chief.surfaces[3].y)
        / original.marginal.surfaces[3].y;
    for (k, ((m, c), c_shifted)) in original
        .marginal
        .surfaces
        .iter()
        .zip(&original.chief.surfaces)
        .zip(&shifted.chief.surfaces)
        .enumerate()
    {
        assert_close(
            c_shifted.y,
            c.y + e * m.y,
            1e-12,
            1e-12,
            &format!("shifted chief ray at surface {}", k + 1),
        );
    }
    let tol = 1e-12
        * [s.spherical, s.coma, s.astigmatism, s.petzval, s.distortion]
            .iter()
            .map(|v| v.abs())
            .sum::<f64>();
    assert_close(t.spherical, s.spherical, 0.0, tol, "S_I");
    assert_close(t.coma, s.coma + e * s.spherical, 0.0, tol, "S_II");
    assert_close(
        t.astigmatism,
        s.astigmatism + 2.0 * e * s.coma + e * e * s.spherical,
        0.0,
        tol,
        "S_III",
    );
    assert_close(t.petzval, s.petzval, 0.0, tol, "S_IV");
    let distortion = s.distortion
        + e * (3.0 * s.astigmatism + s.petzval)
        + 3.0 * e * e * s.coma
        + e.powi(3) * s.spherical;
    assert_close(t.distortion, distortion, 0.0, tol, "S_V");
}

/// A refracting ellipsoid with k = -1/n^2 focuses a collimated beam perfectly (Descartes): its
/// aspheric S_I cancels the sphere's. The same departure as an r^4 term does the same.
#[test]
fn cartesian_ellipsoid_has_no_spherical_aberration() {
    let (c, n) = (1.0 / 30.0, 1.7);
    let conic = -1.0 / (n * n);
    let shapes = [
        Shape::Conic {
            curvature: c,
            conic,
        },
        Shape::EvenAsphere {
            curvature: c,
            conic: 0.0,
            coefficients: vec![0.0, conic * c.powi(3) / 8.0],
        },
        Shape::OddAsphere {
            curvature: c,
            conic: 0.0,
            coefficients: vec![0.0, 0.0, 0.0, conic * c.powi(3) / 8.0],
        },
    ];
    let sphere_sums = {
        let at = system(vec![surface(sphere(c), 60.0, n, 6.0, true)]);
        let p = Paraxial::new(&at, &infinite_at(5.0)).unwrap();
        Seidel::new(&at, &p, None).sums
    };
    assert!(
        sphere_sums.spherical > 1e-3,
        "the sphere itself is aberrated"
    );
    for shape in shapes {
        assert_close(
            aspheric_r4_departure(&shape),
            conic * c.powi(3) / 8.0,
            1e-14,
            0.0,
            "departure",
        );
        let at = system(vec![surface(shape.clone(), 60.0, n, 6.0, true)]);
        let p = Paraxial::new(&at, &infinite_at(5.0)).unwrap();
        let seidel = Seidel::new(&at, &p, None);
        assert_close(
            seidel.sums.spherical,
            0.0,
            0.0,
            1e-14 * sphere_sums.spherical,
            &format!("{shape:?} S_I"),
        );
        // At the stop the chief ray height is zero, so only S_I changes.
        for (ours, sphere) in [
            (seidel.sums.coma, sphere_sums.coma),
            (seidel.sums.astigmatism, sphere_sums.astigmatism),
            (seidel.sums.petzval, sphere_sums.petzval),
            (seidel.sums.distortion, sphere_sums.distortion),
        ] {
            assert_close(
                ours,
                sphere,
                1e-12,
                1e-15,
                "field terms unchanged by an asphere at the stop",
            );
        }
    }
}

/// The LensSystem path for colour: model glasses give nF - nC = (nd - 1) / vd by construction,
/// and C_I predicts the exact paraxial focus shift between F and C to first order in dn.
#[test]
fn colour_from_a_dispersive_lens_system() {
    let (nd, vd) = (1.5168, 64.17);
    let glass = Medium::Model { nd, vd };
    let mut front = surface(sphere(1.0 / 60.0), 6.0, 1.0, 12.0, true);
    front.medium = glass;
    let lens = lens_system(vec![
        front,
        surface(sphere(-1.0 / 60.0), 50.0, 1.0, 12.0, false),
    ]);
    let dn = IndexDifferences::fraunhofer(&lens).expect("the glass disperses");
    assert_eq!((dn.short_nm, dn.long_nm), (F_LINE_NM, C_LINE_NM));
    assert_close(dn.after[0], (nd - 1.0) / vd, 1e-12, 0.0, "nF - nC");
    assert_eq!((dn.object, dn.after[1]), (0.0, 0.0));
    assert!(
        IndexDifferences::fraunhofer(&lens_system(vec![surface(
            sphere(0.01),
            5.0,
            1.5,
            5.0,
            true
        )]))
        .is_none()
    );

    let at = lens.at(587.5618);
    let p = Paraxial::new(&at, &infinite_at(5.0)).unwrap();
    let seidel = Seidel::new(&at, &p, Some(&dn));
    let longitudinal = -seidel.transverse_colour.unwrap().ax / p.marginal.image_slope();
    let exact = FirstOrder::of(&lens.at(F_LINE_NM)).unwrap().bfl
        - FirstOrder::of(&lens.at(C_LINE_NM)).unwrap().bfl;
    // First order in dn / (n - 1) ~ 1.6 %: the two agree to a few times that.
    assert_close(
        longitudinal,
        exact,
        0.05,
        0.0,
        "axial colour vs exact F - C focus",
    );
    assert!(exact < 0.0, "a positive crown singlet focuses blue first");
}
