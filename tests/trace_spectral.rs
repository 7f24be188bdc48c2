//! Tracing at any wavelength: the tracer sees exactly the indices of `LensSystem::at`.

use lensbake::glass::Dispersion;
use lensbake::prescription::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
use lensbake::system::LensSystem;
use lensbake::trace::{RGB_WAVELENGTHS_NM, Ray, Tracer, Travel, rgb_tracers};

/// A biconvex N-BK7 singlet, R = +-50, 5 mm thick, stop on the front face.
fn singlet(medium: Medium) -> Prescription {
    Prescription {
        provenance: Provenance {
            title: "test singlet".into(),
            ..Provenance::default()
        },
        object_medium: Medium::Air,
        surfaces: vec![
            Surface {
                shape: Shape::Sphere { curvature: 0.02 },
                thickness: 5.0,
                medium,
                semi_aperture: 10.0,
                stop: Some(StopShape::Circle),
                obscuration: None,
            },
            Surface {
                shape: Shape::Sphere { curvature: -0.02 },
                thickness: 48.0,
                medium: Medium::Air,
                semi_aperture: 10.0,
                stop: None,
                obscuration: None,
            },
        ],
    }
}

fn axis_crossing(tracer: &Tracer, height: f64) -> f64 {
    let ray = Ray::new([0.0, height, -5.0], [0.0, 0.0, 1.0]).unwrap();
    let out = tracer.trace(ray, Travel::Forward);
    assert!(out.outcome.is_ok());
    let (p, d) = (out.ray.position(), out.ray.direction());
    p[2] - p[1] * d[2] / d[1]
}

#[test]
fn glass_at_any_wavelength_equals_its_constant_index() {
    let glass = LensSystem::from_prescription(singlet(Medium::Glass("N-BK7".into()))).unwrap();
    let index = Dispersion::of(&Medium::Glass("N-BK7".into())).unwrap();
    for nm in [404.66, 486.13, 587.56, 656.27, 706.52] {
        let constant =
            LensSystem::from_prescription(singlet(Medium::Index(index.index(nm)))).unwrap();
        let (a, b) = (Tracer::new(&glass.at(nm)), Tracer::new(&constant.at(nm)));
        for h in [0.5, 3.0, 8.0] {
            assert_eq!(axis_crossing(&a, h), axis_crossing(&b, h));
        }
    }
}

#[test]
fn rgb_tracers_show_axial_colour_of_a_positive_crown_lens() {
    let system = LensSystem::from_prescription(singlet(Medium::Glass("N-BK7".into()))).unwrap();
    let [red, green, blue] = rgb_tracers(&system);
    assert_eq!(
        [
            red.wavelength_nm(),
            green.wavelength_nm(),
            blue.wavelength_nm()
        ],
        RGB_WAVELENGTHS_NM
    );
    let focus = |t: &Tracer| axis_crossing(t, 1.0);
    // Normal dispersion: blue bends more, so it focuses first. The thin-lens estimate of the
    // red-blue focus shift is f (n_B - n_R) / (n - 1) ~ 50 * 0.0076 / 0.517 ~ 0.74 mm.
    let (r, g, b) = (focus(&red), focus(&green), focus(&blue));
    assert!(b < g && g < r, "foci B {b} G {g} R {r}");
    assert!((r - b) > 0.5 && (r - b) < 1.0, "red-blue shift {}", r - b);
}
