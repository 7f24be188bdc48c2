//! The real-ray plots carry the data a designer expects: checked on the figures `lensbake plot`
//! draws for bundled lenses, at the identities that hold whatever the design (chief ray and axis
//! are aberration-free references) and against the lens's own reported numbers.
#![cfg(feature = "plot")]

use lensbake::lenses::BUNDLED;
use lensbake::plot::{Format, render};
use lensbake::report::{Figure, FigureOptions, PlotKind, figure};
use lensbake::system::LensSystem;

fn system(name: &str) -> LensSystem {
    let lens = BUNDLED
        .iter()
        .find(|l| l.name == name)
        .unwrap_or_else(|| panic!("no bundled lens {name}"));
    LensSystem::from_prescription(ron::from_str(lens.ron).unwrap()).unwrap()
}

fn plot(kind: PlotKind, lens: &str) -> Figure {
    figure(kind, lens, &system(lens), &FigureOptions::default())
        .unwrap_or_else(|e| panic!("{kind} of {lens}: {e}"))
}

const COOKE: &str = "cooke-triplet";

/// The fans are measured from the pupil-centre ray, so their zero is that ray by construction
/// (checking it compares a ray with itself). What can fail: the lens is mirror-symmetric about
/// the meridional plane, so a sagittal fan's x error is odd in the pupil coordinate at every
/// field, and on axis the tangential fan's y error is odd too. A reference point off the
/// meridional plane, a fan drawn from the wrong error component or pupil axis, or a pupil
/// coordinate mapped with the wrong sign breaks that.
#[test]
fn ray_fans_are_odd_where_the_lens_is_symmetric() {
    let Figure::RayFan(fan) = plot(PlotKind::RayFan, COOKE) else {
        panic!("not a fan")
    };
    assert_eq!(fan.fields.len(), 3);
    assert!(
        fan.fields.iter().any(|f| f.field_deg == 0.0),
        "the axis is one of the fields"
    );
    let mut largest = 0.0f64;
    let mut pairs = 0;
    for field in &fan.fields {
        assert_eq!(field.tangential.len(), 3, "F, d, C at {}°", field.field_deg);
        let odd: Vec<_> = if field.field_deg == 0.0 {
            field.tangential.iter().chain(&field.sagittal).collect()
        } else {
            field.sagittal.iter().collect()
        };
        for curve in odd {
            for &(rho, error) in &curve.points {
                let (_, mirrored) = curve
                    .points
                    .iter()
                    .min_by(|a, b| (a.0 + rho).abs().total_cmp(&(b.0 + rho).abs()))
                    .filter(|p| (p.0 + rho).abs() < 1e-12)
                    .unwrap_or_else(|| {
                        panic!("no mirror of pupil point {rho} at {}°", field.field_deg)
                    });
                assert!(
                    (error + mirrored).abs() < 1e-12,
                    "{} nm, {}°: error {error} at {rho}, {mirrored} at {}",
                    curve.wavelength_nm,
                    field.field_deg,
                    -rho
                );
                pairs += 1;
            }
        }
        for curve in field.tangential.iter().chain(&field.sagittal) {
            largest = curve
                .points
                .iter()
                .map(|p| p.1.abs())
                .fold(largest, f64::max);
        }
    }
    assert!(pairs >= 300, "{pairs} mirrored points compared");
    // A real triplet at full aperture is aberrated by tens of micrometres: the fans are not flat.
    assert!(
        largest > 5e-3 && largest < 1.0,
        "largest ray error {largest} mm"
    );
}

#[test]
fn lsa_vanishes_at_zero_pupil_height_and_grows_toward_the_rim() {
    let design_nm = system(COOKE).design_wavelength_nm();
    let Figure::Lsa(lsa) = plot(PlotKind::Lsa, COOKE) else {
        panic!("not an LSA plot")
    };
    let reference = lsa
        .curves
        .iter()
        .find(|c| (c.wavelength_nm - design_nm).abs() < 1e-9)
        .expect("a curve at the design wavelength");
    let (rho0, lsa0) = reference.points[0];
    let &(rho1, lsa1) = reference.points.last().unwrap();
    assert!(rho0 <= 1e-3 && rho1 == 1.0);
    // Spherical aberration is even in the pupil height: ~rho^2 near the axis.
    assert!(lsa1.abs() > 1e-3, "marginal LSA {lsa1} mm");
    assert!(
        lsa0.abs() <= 10.0 * lsa1.abs() * (rho0 / rho1).powi(2) + 1e-9,
        "LSA {lsa0} mm at pupil height {rho0}"
    );
    // The F and C curves start at their paraxial foci: apart from the design wavelength's.
    for curve in lsa.curves.iter().filter(|c| c.wavelength_nm != design_nm) {
        assert!(
            (curve.points[0].1 - lsa0).abs() > 1e-3,
            "no axial colour at {} nm",
            curve.wavelength_nm
        );
    }
}

#[test]
fn distortion_vanishes_on_axis() {
    for lens in [COOKE, "dgauss-50mm"] {
        let Figure::Distortion(d) = plot(PlotKind::Distortion, lens) else {
            panic!("not a distortion plot")
        };
        let (f0, d0) = d.points[0];
        let &(f1, d1) = d.points.last().unwrap();
        assert!(f0 > 0.0 && f0 < 1e-2 * f1, "{lens}: first field {f0}°");
        assert!(d1.abs() > 1e-2, "{lens}: {d1} % at the edge");
        assert!(
            d0.abs() <= 10.0 * d1.abs() * (f0 / f1).powi(2),
            "{lens}: {d0} % at {f0}°"
        );
    }
}

#[test]
fn axial_spot_at_the_paraxial_focus_has_a_finite_radius() {
    let design_nm = system(COOKE).design_wavelength_nm();
    let Figure::Spot(spots) = plot(PlotKind::Spot, COOKE) else {
        panic!("not a spot plot")
    };
    let axis = spots.fields.iter().find(|f| f.field_deg == 0.0).unwrap();
    let design = axis
        .spots
        .iter()
        .find(|s| (s.wavelength_nm - design_nm).abs() < 1e-9)
        .unwrap();
    assert!(design.rms_radius_mm.is_finite() && design.rms_radius_mm > 0.0);
    assert!(design.rms_radius_mm <= design.geometric_radius_mm);
    assert!(design.rms_radius_mm < 0.1, "{} mm", design.rms_radius_mm);
    // The axial spot is centred on the axis (its own centroid is the reference).
    let mean_y = design.points.iter().map(|p| p.1).sum::<f64>() / design.points.len() as f64;
    assert!(mean_y.abs() < 1e-12);
    // Airy radius 1.22 lambda N_w: micrometres at visible wavelengths and f/4-ish.
    assert!(design.airy_radius_mm > 1e-3 && design.airy_radius_mm < 1e-2);
}

#[test]
fn field_curves_meet_on_axis() {
    let Figure::FieldCurves(curves) = plot(PlotKind::FieldCurves, COOKE) else {
        panic!("not field curves")
    };
    for curve in &curves.curves {
        let (field, s, t) = curve.points[0];
        assert_eq!(field, 0.0);
        assert!(
            (s - t).abs() < 1e-6,
            "{} nm: S {s} T {t}",
            curve.wavelength_nm
        );
        let &(_, s_edge, t_edge) = curve.points.last().unwrap();
        assert!((s_edge - t_edge).abs() > 1e-3, "no astigmatism at the edge");
    }
}

#[test]
fn nothing_is_vignetted_on_axis() {
    // The Cooke triplet's axial beam passes whole (dgauss-50mm's clear apertures clip 1.4 % of
    // it, so it would not do here).
    let Figure::Vignetting(v) = plot(PlotKind::Vignetting, COOKE) else {
        panic!("not a vignetting plot")
    };
    let (field, relative, unvignetted) = v.points[0];
    assert_eq!(field, 0.0);
    assert_eq!(relative, 1.0);
    assert!((unvignetted - 1.0).abs() < 1e-12, "{COOKE}: {unvignetted}");
    // Relative illumination falls off toward the edge of the field.
    assert!(v.points.last().unwrap().1 < 1.0);
}

#[test]
fn lateral_colour_is_zero_on_axis_and_absent_without_dispersion() {
    let Figure::LateralColor(colour) = plot(PlotKind::LateralColor, COOKE) else {
        panic!("not a lateral colour plot")
    };
    assert_eq!(colour.curves.len(), 2, "F and C against d");
    for curve in &colour.curves {
        assert_eq!(curve.points[0], (0.0, 0.0));
        assert!(curve.points.last().unwrap().1.abs() > 1e-5);
    }

    let plain = plot(PlotKind::LateralColor, "dgauss-50mm");
    let Figure::LateralColor(colour) = &plain else {
        panic!("not a lateral colour plot")
    };
    assert!(!colour.disperses && colour.curves.is_empty());
    let drawn = render(&plain, Format::Svg).unwrap().drawn;
    assert!(
        drawn.messages().any(|m| m.contains("no lateral colour")),
        "{:?}",
        drawn.messages().collect::<Vec<_>>()
    );
}

/// Layout rays are whole: each starts in front of the lens and crosses at least surface 1 (a
/// ray stopped outside the first clear aperture once floated as a fragment below the lens), and
/// the legend says what the faint (vignetted) rays are.
#[test]
fn layouts_draw_only_complete_rays_and_name_the_faint_ones() {
    for lens in ["dgauss-50mm", "fisheye-10mm", "petzval"] {
        let Figure::Layout(layout) = plot(PlotKind::Layout, lens) else {
            panic!("not a layout")
        };
        assert!(
            layout.rays.iter().any(|r| r.vignetted),
            "{lens}: no vignetted ray"
        );
        for ray in &layout.rays {
            assert!(ray.path.len() >= 3, "{lens}: a fragment {:?}", ray.path);
            assert!(
                ray.path[0].0 < ray.path[1].0,
                "{lens}: a ray drawn backwards from its start"
            );
        }
        let drawn = render(&layout, Format::Svg).unwrap().drawn;
        assert!(
            drawn
                .messages()
                .any(|m| m.starts_with("faint: vignetted rays")),
            "{lens}"
        );
    }
}
