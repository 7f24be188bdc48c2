//! Analyze, trace and bake at the extremes: a very fast aspheric lens, the fisheye at its widest
//! traceable field, a long telephoto, rays at the total-internal-reflection limit and grazing
//! rays, rays on and next to the axis, flat and nearly flat surfaces, tiny and huge apertures, the
//! closest focus, and both ends of the visible band. Every number that comes out is checked to be
//! finite, and each case is checked against an analytic truth where one exists.

mod common;

use lensbake::analysis::{AnalysisError, AnalyzeOptions, analyze};
use lensbake::glass::{D_LINE_NM, Dispersion, catalog};
use lensbake::lenses;
use lensbake::lrtf::bake::{BakeError, BakeRequest, bake, exact_transfer};
use lensbake::lrtf::measure::angle_between;
use lensbake::lrtf::{Lookup, LrtfTable, Parameterisation, Ray as LrtfRay};
use lensbake::paraxial::{ObjectPosition, ParaxialError, sensor_z};
use lensbake::prescription::{
    Medium, Prescription, Problem, Provenance, Shape, StopShape, Surface,
};
use lensbake::system::LensSystem;
use lensbake::trace::{
    Apertures, Outcome, Ray, RaySource, Tracer, Travel, aim_at_stop, traceable_field_deg,
};
use serde_json::Value;

fn bundled(name: &str) -> LensSystem {
    let text = lenses::find(name)
        .unwrap_or_else(|| panic!("no bundled lens {name}"))
        .ron;
    let prescription: Prescription = ron::from_str(text).expect("bundled lens parses");
    LensSystem::from_prescription(prescription).expect("bundled lens is valid")
}

/// Keys of the analyze report whose value may legitimately be null (documented as such).
const NULLABLE: &[&str] = &[
    "object_distance_mm",
    "exit_pupil",
    "magnification",
    "object_height",
    "max_field_deg_paraxial",
    "colour",
    "transverse_colour",
    "colour_wavelengths_nm",
];

/// Every number in `value` is finite (serde_json prints NaN and infinity as null, so a null
/// where a number belongs is the same failure) and nulls appear only under [`NULLABLE`] keys.
fn assert_json_finite(value: &Value, path: &str) {
    match value {
        Value::Null => {
            let key = path.rsplit('.').next().unwrap_or(path);
            assert!(NULLABLE.contains(&key), "null (NaN?) at {path}");
        }
        Value::Number(n) => {
            let x = n.as_f64().expect("a JSON number");
            assert!(x.is_finite(), "{path} = {x}");
        }
        Value::Array(items) => {
            for (i, item) in items.iter().enumerate() {
                assert_json_finite(item, &format!("{path}[{i}]"));
            }
        }
        Value::Object(map) => {
            for (key, item) in map {
                assert_json_finite(item, &format!("{path}.{key}"));
            }
        }
        Value::Bool(_) | Value::String(_) => {}
    }
}

/// `analyze` succeeds and its JSON holds only finite numbers.
fn analyze_finite(
    name: &str,
    system: &LensSystem,
    options: &AnalyzeOptions,
) -> lensbake::analysis::Analysis {
    let analysis = analyze(system, options)
        .unwrap_or_else(|e| panic!("{name} {options:?}: analyze failed: {e}"));
    let json = serde_json::to_value(&analysis).expect("analysis serialises");
    assert_json_finite(&json, name);
    analysis
}

/// The lenses bundled with catalogue glasses (the others use model glasses or fixed indices).
const CATALOGUE_GLASS_LENSES: [&str; 4] = ["codev-dgauss-f2", "cooke-triplet", "petzval", "tessar"];

#[test]
fn every_catalogue_glass_is_a_normal_glass_across_the_visible_band() {
    // 380 to 780 nm in 5 nm steps: a finite index of a transparent glass that falls with
    // wavelength (normal dispersion), inside the range of real optical glasses.
    // A tabulated glass (B 270) is checked over its table, where it is defined; a crystal (MISC)
    // over the band its source measured, where its index may lie outside the glasses' range
    // (MgF2 1.38, ZnSe 2.6).
    for glass in catalog() {
        let mut previous = f64::INFINITY;
        let (low, high) = glass.formula.resonance_window_nm();
        let crystal = glass.maker == "MISC";
        let indices = if crystal { 1.3..2.7 } else { 1.4..2.4 };
        for step in 0..=80 {
            let nm = 380.0 + 5.0 * step as f64;
            if matches!(glass.formula, Dispersion::Tabulated { .. }) && !(low..=high).contains(&nm)
            {
                continue;
            }
            if crystal
                && glass
                    .measured_nm
                    .is_some_and(|(from, to)| !(from..=to).contains(&nm))
            {
                continue;
            }
            let n = glass
                .formula
                .checked_index(nm)
                .unwrap_or_else(|e| panic!("{} at {nm} nm: {e}", glass.name));
            assert!(indices.contains(&n), "{} at {nm} nm: n = {n}", glass.name);
            assert!(n < previous, "{} at {nm} nm: n rises ({n})", glass.name);
            previous = n;
        }
    }
}

#[test]
fn lenses_with_catalogue_glasses_analyse_and_trace_at_380_and_780_nm() {
    for name in CATALOGUE_GLASS_LENSES {
        let system = bundled(name);
        let mut efl = Vec::new();
        for nm in [380.0, D_LINE_NM, 780.0] {
            let analysis = analyze_finite(
                name,
                &system,
                &AnalyzeOptions {
                    wavelength_nm: Some(nm),
                    ..AnalyzeOptions::default()
                },
            );
            efl.push(analysis.first_order.efl);
            // A parallel ray at half the entrance pupil crosses the axis within the lens's
            // longitudinal aberration of the paraxial focus (a few percent of the EFL here).
            let tracer = Tracer::new(&system.at(nm));
            let h = 0.25 * analysis.first_order.entrance_pupil.diameter;
            let start = Ray::new([0.0, h, tracer.front_start_z()], [0.0, 0.0, 1.0]).unwrap();
            let traced = tracer.trace(start, Travel::Forward);
            assert!(traced.outcome.is_ok(), "{name} at {nm} nm: {traced:?}");
            let (p, d) = (traced.ray.position(), traced.ray.direction());
            let crossing = p[2] - p[1] * d[2] / d[1];
            let paraxial = analysis.first_order.z_rear_focal;
            assert!(
                (crossing - paraxial).abs() < 0.05 * analysis.first_order.efl,
                "{name} at {nm} nm: real focus {crossing}, paraxial {paraxial}"
            );
        }
        // The focal shift across the whole visible band stays a small fraction of the focal
        // length in these colour-corrected lenses.
        assert!(
            (efl[0] - efl[2]).abs() < 0.02 * efl[1],
            "{name}: EFL at 380/587/780 nm {efl:?}"
        );
        // A table with the band's ends as its outer channels.
        let request = BakeRequest {
            resolution: [8, 8, 8],
            wavelengths_nm: vec![780.0, D_LINE_NM, 380.0],
            ..BakeRequest::default()
        };
        let table = bake(&system, &request).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_table_finite(&table, name);
    }
}

#[test]
fn baking_beyond_a_glass_formula_is_refused() {
    // Without the check, bake traced the Cooke triplet at 9000 nm (F2 at n = 0.31) and the
    // double Gauss at 150 nm.
    for (name, nm) in [("cooke-triplet", 9000.0), ("codev-dgauss-f2", 150.0)] {
        let request = BakeRequest {
            resolution: [4, 4, 4],
            wavelengths_nm: vec![nm],
            ..BakeRequest::default()
        };
        let result = bake(&bundled(name), &request);
        assert!(
            matches!(result, Err(BakeError::Wavelength(_))),
            "{name} baked at {nm} nm"
        );
    }
}

#[test]
fn a_wavelength_beyond_a_glass_formula_is_a_typed_error_naming_the_surface() {
    // Found by probing: at 150 nm the double Gauss's N-SSK2 (surface 1) is past its Sellmeier
    // resonance at 182.7 nm yet gives a plausible index, 1.71, while N-SK2 (surface 3) gives NaN,
    // and analyze called the lens "afocal"; at 200 nm F5 (surface 4, resonance at 213.9 nm)
    // gives 1.17. The Cooke triplet at 9000 nm (F2 on surface 3: n = 0.31) analysed "fine" with
    // an EFL of 14.6 mm.
    let cases = [
        ("codev-dgauss-f2", 150.0, 1),
        ("codev-dgauss-f2", 200.0, 4),
        ("cooke-triplet", 9000.0, 3),
        ("tessar", 150.0, 1),
    ];
    for (name, nm, surface) in cases {
        let system = bundled(name);
        let error = analyze(
            &system,
            &AnalyzeOptions {
                wavelength_nm: Some(nm),
                ..AnalyzeOptions::default()
            },
        )
        .expect_err("no analysis beyond the glass formula");
        let AnalysisError::Wavelength(error) = &error else {
            panic!("{name} at {nm} nm: wrong error {error:?}");
        };
        assert_eq!(
            error.problem,
            Problem::WavelengthOutOfRange { nm },
            "{name} at {nm} nm"
        );
        assert_eq!(error.location.surface, Some(surface), "{name} at {nm} nm");
        let checked = system
            .at_checked(nm)
            .expect_err("the checked view refuses it too");
        assert_eq!(&checked, error);
        let message = error.to_string();
        assert!(
            message.contains(&format!("surface {surface}")) && message.contains("medium"),
            "{message}"
        );
    }
    // Outside the range lensbake traces at all, the range is the cause, not the first medium.
    let tessar = bundled("tessar");
    for nm in [30.0, 1e30, f64::NAN] {
        let error = tessar.at_checked(nm).expect_err("outside every formula");
        assert!(
            matches!(error.problem, Problem::OverLimit(_)) && error.location.surface.is_none(),
            "{nm} nm: {error}"
        );
    }
    // The checked view at a good wavelength is the plain view.
    let system = bundled("codev-dgauss-f2");
    assert_eq!(system.at_checked(486.1327).unwrap(), system.at(486.1327));
    // Model glasses and constant indices are defined everywhere a wavelength is.
    let model = bundled("asph-50mm-f1.8");
    for nm in [100.0, 380.0, 780.0, 10_000.0] {
        assert!(model.at_checked(nm).is_ok(), "model glasses at {nm} nm");
    }
    assert!(matches!(
        lensbake::glass::Dispersion::of(&Medium::Glass("F5".into()))
            .unwrap()
            .checked_index(f64::NAN),
        Err(Problem::WavelengthOutOfRange { .. })
    ));
}

/// Every table entry finite, the frame and pupil too.
fn assert_table_finite(table: &LrtfTable, what: &str) {
    for layer in &table.layers {
        let f = &layer.frame;
        for v in [
            f.rear_plane_z,
            f.film_plane_z,
            f.max_film_radius,
            f.max_rear_radius,
            f.max_polar_angle,
            layer.stop_semi_aperture,
        ] {
            assert!(v.is_finite(), "{what}: frame {f:?}");
        }
        for c in &layer.pupil.circles {
            assert!(
                c.centre_x.is_finite() && c.radius.is_finite(),
                "{what}: {c:?}"
            );
        }
        for (k, entry) in layer.entries.row_major().enumerate() {
            assert!(
                entry.iter().all(|v| v.is_finite()),
                "{what}: entry {k} {entry:?}"
            );
        }
    }
}

/// The film-side ray from film point `film` on the table's film plane towards rear-plane point
/// `rear` (both in the lens frame, mm).
fn film_ray(table: &LrtfTable, film: [f64; 2], rear: [f64; 2]) -> LrtfRay {
    let frame = &table.layers[0].frame;
    let d = [
        rear[0] - film[0],
        rear[1] - film[1],
        frame.rear_plane_z - frame.film_plane_z,
    ];
    let norm = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    LrtfRay {
        origin: [film[0], film[1], frame.film_plane_z],
        direction: d.map(|v| v / norm),
    }
}

/// The table's answer for `ray` against the exact trace: both pass, and the outgoing
/// directions agree within `mrad`.
fn assert_lookup_matches_trace(
    table: &LrtfTable,
    tracer: &Tracer,
    ray: &LrtfRay,
    mrad: f64,
    what: &str,
) {
    let (exact, passes) = exact_transfer(tracer, ray);
    assert!(passes, "{what}: the exact trace is blocked");
    let exact = exact.expect("a passing ray has a transfer");
    let stop = table.layers[0].stop_semi_aperture;
    let Lookup::Passes(looked) = table.lookup_layer(0, ray, stop) else {
        panic!("{what}: the table blocks a ray the lens passes");
    };
    assert!(
        looked
            .origin
            .iter()
            .chain(&looked.direction)
            .all(|v| v.is_finite()),
        "{what}: {looked:?}"
    );
    let angle = angle_between(looked.direction, exact.exit_direction) * 1e3;
    assert!(angle < mrad, "{what}: direction off by {angle} mrad");
}

/// How far from the axis, along `direction` on the rear plane, rays from the film centre still
/// pass the lens (bisection with the exact trace inside the table's pupil circle).
fn pupil_rim_from_film_centre(table: &LrtfTable, tracer: &Tracer, direction: [f64; 2]) -> f64 {
    let passes = |t: f64| {
        let rear = [t * direction[0], t * direction[1]];
        exact_transfer(tracer, &film_ray(table, [0.0, 0.0], rear)).1
    };
    let circle = table.layers[0].pupil.circle_at(0.0);
    let (mut inside, mut outside) = (0.0, circle.radius);
    assert!(passes(inside) && !passes(outside), "pupil {circle:?}");
    for _ in 0..60 {
        let mid = 0.5 * (inside + outside);
        if passes(mid) {
            inside = mid;
        } else {
            outside = mid;
        }
    }
    inside
}

#[test]
fn stopped_far_down_the_pupil_still_holds_the_axial_ray() {
    // Found by this test: the pupil fit probes a 32 x 17 grid of the rear plane, which has no
    // node on the axis; once the pupil is smaller than a grid step nothing was found at the
    // film centre, so the f/0.95 singlet at f/64 could not be baked ("nothing passes") and the
    // double Gauss at f/64 got an axial pupil circle centred 1.3 mm off axis that excluded the
    // axial ray itself.
    let cases = [
        ("f/0.95 singlet", common::f095_singlet(false), 64.0),
        ("f/0.95 singlet", common::f095_singlet(false), 1000.0),
        ("dgauss-50mm", bundled("dgauss-50mm"), 64.0),
        ("dgauss-50mm", bundled("dgauss-50mm"), 1000.0),
    ];
    for (name, system, f_number) in cases {
        let what = format!("{name} at f/{f_number}");
        let request = BakeRequest {
            resolution: [8, 8, 8],
            f_number: Some(f_number),
            ..BakeRequest::default()
        };
        let table = bake(&system, &request).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert_table_finite(&table, &what);
        let layer = &table.layers[0];
        let axial = layer.pupil.circle_at(0.0);
        assert!(
            axial.centre_x.abs() < 1e-9 && axial.radius > 0.0,
            "{what}: the film centre's pupil {axial:?} is centred on the axis"
        );
        let stopped = Tracer::new(
            &system
                .at(system.design_wavelength_nm())
                .stopped_down(layer.stop_semi_aperture),
        );
        // The axial ray and one halfway to the true pupil's rim (the stored circle is a
        // looser, conservative bound); measured within 1e-5 mrad of the trace.
        let rim = pupil_rim_from_film_centre(&table, &stopped, [0.0, 1.0]);
        for rear in [[0.0, 0.0], [0.0, 0.5 * rim]] {
            let ray = film_ray(&table, [0.0, 0.0], rear);
            assert!(
                layer.pupil.pdf(0.0, rear) > 0.0,
                "{what}: rear point {rear:?} outside the pupil {axial:?}"
            );
            assert_lookup_matches_trace(
                &table,
                &stopped,
                &ray,
                1e-3,
                &format!(
                    "{what}, rear point {rear:?}, pupil {:?}",
                    &layer.pupil.circles[..2]
                ),
            );
        }
    }
}

/// Where a meridional-plane ray (any azimuth) crosses the axis: the z at which its radial
/// component vanishes.
fn axis_crossing(ray: &Ray) -> f64 {
    let (p, d) = (ray.position(), ray.direction());
    let radial = p[0].hypot(p[1]);
    let (ux, uy) = if radial > 0.0 {
        (p[0] / radial, p[1] / radial)
    } else {
        (0.0, 1.0)
    };
    let slope = d[0] * ux + d[1] * uy;
    p[2] - radial * d[2] / slope
}

/// Every coordinate of a traced ray is finite and its direction is a unit vector.
fn assert_traced_finite(traced: &lensbake::trace::Traced, what: &str) {
    let (p, d) = (traced.ray.position(), traced.ray.direction());
    assert!(
        p.iter().chain(&d).all(|v| v.is_finite()),
        "{what}: {traced:?}"
    );
    let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
    assert!((length - 1.0).abs() < 1e-14, "{what}: |d| = {length}");
}

#[test]
fn f095_aspheric_singlet_focuses_every_axial_ray_and_types_the_rest() {
    let conic = common::f095_singlet(false);
    let asphere = common::f095_singlet(true);
    for (form, system) in [("conic", &conic), ("even asphere", &asphere)] {
        let analysis = analyze_finite(
            "f/0.95 singlet",
            system,
            &AnalyzeOptions {
                field_deg: Some(5.0),
                ..AnalyzeOptions::default()
            },
        );
        let first = &analysis.first_order;
        common::assert_close(first.efl, 45.0, 1e-14, 0.0, "EFL = n R / (n - 1)");
        common::assert_close(first.z_rear_focal, 45.0, 1e-14, 0.0, "rear focus");
        common::assert_close(first.f_number, 45.0 / 47.4, 1e-14, 0.0, "f-number");
        assert!(first.f_number < 0.95);

        // The Cartesian ellipsoid is free of spherical aberration at every height: each
        // parallel ray inside the f/0.949 aperture crosses the axis at the paraxial focus.
        let tracer = Tracer::new(&system.at(D_LINE_NM));
        let start_z = tracer.front_start_z();
        let mut worst: f64 = 0.0;
        for k in 1..=200 {
            let h = 23.699 * k as f64 / 200.0;
            let azimuth = 0.37 * k as f64;
            let ray = Ray::new(
                [h * azimuth.cos(), h * azimuth.sin(), start_z],
                [0.0, 0.0, 1.0],
            )
            .unwrap();
            let traced = tracer.trace(ray, Travel::Forward);
            assert_eq!(traced.outcome, Outcome::Ok, "{form}: h = {h}");
            assert_traced_finite(&traced, form);
            worst = worst.max((axis_crossing(&traced.ray) - 45.0).abs());
        }
        assert!(worst < 1e-11, "{form}: focus spread {worst:e} mm");

        // Past the clear aperture the stop vignettes; past the ellipsoid's rim (R / sqrt(1 + k)
        // = 24.054 mm) even the bare geometry has no surface to meet.
        let rim = 20.0 / (1.0 - 1.0 / 3.24f64).sqrt();
        let parallel = |h: f64| Ray::new([0.0, h, start_z], [0.0, 0.0, 1.0]).unwrap();
        assert_eq!(
            tracer.trace(parallel(23.71), Travel::Forward).outcome,
            Outcome::Vignetted { surface: 1 }
        );
        for h in [rim * (1.0 + 1e-12), rim + 1e-6, 30.0, 1e6] {
            let traced = tracer.trace_with(parallel(h), Travel::Forward, Apertures::Ignored);
            assert_eq!(
                traced.outcome,
                Outcome::Missed { surface: 1 },
                "{form}: h = {h}"
            );
            assert_traced_finite(&traced, form);
        }
    }

    // Steep and skew rays over the bare geometry: every outcome typed and finite, and the
    // closed-form conic and the Newton asphere agree on each ray (same surface, two solvers).
    let conic_tracer = Tracer::new(&conic.at(D_LINE_NM));
    let asphere_tracer = Tracer::new(&asphere.at(D_LINE_NM));
    let mut seen = std::collections::BTreeSet::new();
    for i in 0..=40 {
        for j in 0..=40 {
            let angle = (-80.0 + 4.0 * i as f64).to_radians();
            let h = -30.0 + 1.3 * j as f64;
            let d = [0.2 * angle.sin(), angle.sin(), angle.cos()];
            let ray = Ray::new([0.3 * h, h, -40.0], d).unwrap();
            for apertures in [Apertures::Checked, Apertures::Ignored] {
                let a = conic_tracer.trace_with(ray, Travel::Forward, apertures);
                let b = asphere_tracer.trace_with(ray, Travel::Forward, apertures);
                assert_traced_finite(&a, "conic");
                assert_traced_finite(&b, "asphere");
                assert_eq!(a.outcome, b.outcome, "ray {ray:?}");
                if a.outcome.is_ok() {
                    for k in 0..3 {
                        assert!(
                            (a.ray.position()[k] - b.ray.position()[k]).abs() < 1e-9
                                && (a.ray.direction()[k] - b.ray.direction()[k]).abs() < 1e-11,
                            "ray {ray:?}: {a:?} vs {b:?}"
                        );
                    }
                }
                seen.insert(a.outcome.status());
            }
        }
    }
    assert_eq!(
        seen.len(),
        4,
        "ok, vignetted, TIR and missed all reached: {seen:?}"
    );

    // A wide-open bake (stop on the asphere itself) is finite and agrees with the trace on axis.
    let request = BakeRequest {
        resolution: [8, 8, 8],
        ..BakeRequest::default()
    };
    for (form, system) in [("conic", &conic), ("even asphere", &asphere)] {
        let table = bake(system, &request).unwrap_or_else(|e| panic!("{form}: {e}"));
        assert_table_finite(&table, form);
        common::assert_close(
            table.info.f_number,
            45.0 / 47.4,
            1e-9,
            0.0,
            "baked f-number",
        );
        let tracer = Tracer::new(&system.at(D_LINE_NM));
        let rim = pupil_rim_from_film_centre(&table, &tracer, [1.0, 0.0]);
        for rear in [[0.0, 0.0], [0.9 * rim, 0.0], [0.0, -0.5 * rim]] {
            let ray = film_ray(&table, [0.0, 0.0], rear);
            // This lens images the axial point perfectly, so the table's cells interpolate a
            // nearly linear transfer: measured below 1e-11 mrad.
            assert_lookup_matches_trace(&table, &tracer, &ray, 1e-6, form);
        }
    }
}

#[test]
fn bundled_aspheric_lens_opened_to_f095() {
    // The f/1.8 aspheric lens analysed with the entrance pupil of an f/0.95 lens, and traced
    // over that pupil with its clear apertures ignored: the rays its front group cannot bend
    // end as typed TIR or misses, never NaN.
    let system = bundled("asph-50mm-f1.8");
    let wide = analyze_finite("asph-50mm-f1.8", &system, &AnalyzeOptions::default());
    let epd = wide.first_order.efl / 0.95;
    let fast = analyze_finite(
        "asph-50mm-f1.8 at f/0.95",
        &system,
        &AnalyzeOptions {
            epd_mm: Some(epd),
            ..AnalyzeOptions::default()
        },
    );
    common::assert_close(fast.first_order.f_number, 0.95, 1e-12, 0.0, "f-number");
    // Paraxial quantities scale with the aperture: the marginal ray and S_I grow as EPD, EPD^4.
    let scale = epd / wide.first_order.entrance_pupil.diameter;
    common::assert_close(
        fast.seidel.sums.spherical,
        wide.seidel.sums.spherical * scale.powi(4),
        1e-10,
        0.0,
        "S_I scales as the fourth power of the aperture",
    );
    let tracer = Tracer::new(&system.at(system.design_wavelength_nm()));
    let pupil = tracer
        .paraxial_entrance_pupil()
        .expect("the stop images to a finite entrance pupil");
    let start_z = tracer.front_start_z();
    let mut counts = std::collections::BTreeMap::new();
    for i in -30..=30 {
        for j in 0..=30 {
            let (x, y) = (i as f64 / 30.0, j as f64 / 30.0);
            if x.hypot(y) > 1.0 {
                continue;
            }
            for field_deg in [0.0f64, 20.0, 35.0] {
                let u = field_deg.to_radians();
                let d = [0.0, u.sin(), u.cos()];
                let back = (pupil.z - start_z) / d[2];
                let start = [0.5 * epd * x, 0.5 * epd * y - back * d[1], start_z];
                let ray = Ray::new(start, d).unwrap();
                let traced = tracer.trace_with(ray, Travel::Forward, Apertures::Ignored);
                assert_traced_finite(&traced, "asph-50mm at f/0.95");
                *counts.entry(traced.outcome.status()).or_insert(0usize) += 1;
            }
        }
    }
    eprintln!("asph-50mm-f1.8 over an f/0.95 pupil, apertures ignored: {counts:?}");
    assert!(counts.get("ok").copied().unwrap_or(0) > 0, "{counts:?}");
    assert!(
        counts.len() > 1,
        "the f/0.95 pupil reaches past what the lens can bend"
    );
}

/// The real chief ray at `field_deg` (collimated, aimed at the stop centre), or None when it
/// cannot be aimed.
fn chief_ray(tracer: &Tracer, field_deg: f64) -> Option<Ray> {
    let u = field_deg.to_radians();
    let source = RaySource::Collimated {
        direction: [0.0, u.sin(), u.cos()],
        start_z: tracer.front_start_z(),
    };
    aim_at_stop(tracer, &source, [0.0, 0.0]).ok()
}

#[test]
fn fisheye_at_its_largest_traceable_field() {
    let system = bundled("fisheye-10mm");
    let tracer = Tracer::new(&system.at(system.design_wavelength_nm()));
    let widest = traceable_field_deg(&tracer, 1.0);
    // The paraxial chief ray leaves the clear apertures at 43.5 degrees; the real one, bent by
    // the strongly curved front meniscus and aimed by the searching aim, gets to 74.8 degrees.
    assert!(
        (70.0..80.0).contains(&widest),
        "traceable field {widest} degrees"
    );
    let inside = chief_ray(&tracer, widest - 1e-6).expect("aimed just inside the limit");
    assert_eq!(tracer.trace(inside, Travel::Forward).outcome, Outcome::Ok);
    let outside =
        chief_ray(&tracer, widest + 1e-6).map(|ray| tracer.trace(ray, Travel::Forward).outcome);
    assert!(
        outside.is_none_or(|o| !o.is_ok()),
        "just past the limit: {outside:?}"
    );

    // The whole pupil at the widest field, aimed ray by ray at points of the stop.
    let stop_radius = system.prescription.surfaces[system.stop].semi_aperture;
    let source = {
        let u = (widest - 1e-6).to_radians();
        RaySource::Collimated {
            direction: [0.0, u.sin(), u.cos()],
            start_z: tracer.front_start_z(),
        }
    };
    let mut passed = 0;
    for i in -6..=6 {
        for j in -6..=6 {
            let target = [stop_radius * i as f64 / 6.5, stop_radius * j as f64 / 6.5];
            if target[0].hypot(target[1]) > stop_radius {
                continue;
            }
            let Ok(ray) = aim_at_stop(&tracer, &source, target) else {
                continue;
            };
            let traced = tracer.trace(ray, Travel::Forward);
            assert_traced_finite(&traced, "fisheye, widest field");
            passed += usize::from(traced.outcome.is_ok());
        }
    }
    assert!(passed > 0, "some of the pupil passes at the widest field");
    // Beyond it, up to grazing incidence, rays still end typed.
    for deg in [70.0, 80.0, 89.0, 89.999] {
        let u = f64::to_radians(deg);
        for h in [-10.0, 0.0, 10.0] {
            let ray = Ray::new([0.0, h, tracer.front_start_z()], [0.0, u.sin(), u.cos()]).unwrap();
            for apertures in [Apertures::Checked, Apertures::Ignored] {
                let traced = tracer.trace_with(ray, Travel::Forward, apertures);
                assert_traced_finite(&traced, &format!("fisheye at {deg} degrees"));
            }
        }
    }

    let analysis = analyze_finite(
        "fisheye-10mm",
        &system,
        &AnalyzeOptions {
            field_deg: Some(widest),
            ..AnalyzeOptions::default()
        },
    );
    common::assert_close(analysis.field_deg, widest, 1e-12, 0.0, "analysed field");

    // A table covers the film out to the widest field's image; its rim answers like the trace.
    let table = bake(
        &system,
        &BakeRequest {
            resolution: [12, 12, 12],
            ..BakeRequest::default()
        },
    )
    .unwrap();
    assert_table_finite(&table, "fisheye table");
    // Near the film's rim, the middle of the passing rays along the meridian (film point on
    // +y, so the canonical x axis of the pupil circle runs along y).
    let edge = 0.98 * table.layers[0].frame.max_film_radius;
    let circle = table.layers[0].pupil.circle_at(edge);
    let passing: Vec<f64> = (0..=400)
        .map(|k| circle.centre_x + circle.radius * (k as f64 / 200.0 - 1.0))
        .filter(|&y| exact_transfer(&tracer, &film_ray(&table, [0.0, edge], [0.0, y])).1)
        .collect();
    assert!(!passing.is_empty(), "rays pass at the film's rim");
    let middle = 0.5 * (passing[0] + passing[passing.len() - 1]);
    let ray = film_ray(&table, [0.0, edge], [0.0, middle]);
    // Measured: 1.2 mrad at 12^3 (the table's worst region, the fisheye's film rim).
    assert_lookup_matches_trace(&table, &tracer, &ray, 2.5, "fisheye film rim");
}

#[test]
fn long_telephoto_is_shorter_than_its_focal_length_and_traces_to_its_paraxial_focus() {
    let system = bundled("telephoto-250mm");
    let analysis = analyze_finite("telephoto-250mm", &system, &AnalyzeOptions::default());
    let first = &analysis.first_order;
    common::assert_close(
        first.efl,
        250.0,
        0.02,
        0.0,
        "EFL against the claimed 250 mm",
    );
    // What makes it a telephoto: front vertex to focus is shorter than the focal length, so
    // the rear principal plane lies in front of the lens.
    assert!(first.z_rear_focal < first.efl, "{first:?}");
    assert!(first.z_rear_principal < 0.0, "{first:?}");
    // A near-axial real ray reproduces the paraxial EFL and focus (the f/5.4 aperture is
    // 46 mm; 1e-6 of it leaves third-order terms at 1e-12 relative).
    let tracer = Tracer::new(&system.at(system.design_wavelength_nm()));
    let h = 1e-6 * first.entrance_pupil.diameter;
    let ray = Ray::new([0.0, h, tracer.front_start_z()], [0.0, 0.0, 1.0]).unwrap();
    let traced = tracer.trace(ray, Travel::Forward);
    assert!(traced.outcome.is_ok());
    let d = traced.ray.direction();
    common::assert_close(-h * d[2] / d[1], first.efl, 1e-9, 0.0, "real-ray EFL");
    common::assert_close(
        axis_crossing(&traced.ray),
        first.z_rear_focal,
        1e-9,
        0.0,
        "real-ray focus",
    );
    let table = bake(
        &system,
        &BakeRequest {
            resolution: [12, 12, 12],
            ..BakeRequest::default()
        },
    )
    .unwrap();
    assert_table_finite(&table, "telephoto table");
    let rim = pupil_rim_from_film_centre(&table, &tracer, [0.6, 0.8]);
    for rear in [[0.0, 0.0], [0.9 * rim, 0.0], [0.0, -0.5 * rim]] {
        let ray = film_ray(&table, [0.0, 0.0], rear);
        // Measured: 0.019 mrad at 12^3.
        assert_lookup_matches_trace(&table, &tracer, &ray, 0.05, "telephoto on axis");
    }
}

/// Two surfaces in air: `first` then `second` with glass of index `n` between them.
fn two_surface_lens(first: Shape, second: Shape, n: f64, thickness: f64, semi: f64) -> LensSystem {
    LensSystem::from_prescription(Prescription {
        provenance: Provenance {
            title: "test lens".into(),
            ..Provenance::default()
        },
        object_medium: Medium::Air,
        surfaces: vec![
            Surface {
                shape: first,
                thickness,
                medium: Medium::Index(n),
                semi_aperture: semi,
                stop: Some(StopShape::Circle),
                obscuration: None,
            },
            Surface {
                shape: second,
                thickness: 50.0,
                medium: Medium::Air,
                semi_aperture: semi,
                stop: None,
                obscuration: None,
            },
        ],
    })
    .expect("valid test lens")
}

#[test]
fn total_internal_reflection_switches_on_exactly_at_the_critical_angle() {
    let n = 1.5;
    // Convex exit sphere: a parallel ray at height h meets it at incidence asin(h / R), so the
    // critical angle asin(1 / n) is reached at h = R / n.
    let radius = 20.0;
    let system = two_surface_lens(
        Shape::Plane,
        Shape::Sphere {
            curvature: -1.0 / radius,
        },
        n,
        20.0,
        19.9,
    );
    let tracer = Tracer::new(&system.at(D_LINE_NM));
    let at_height = |h: f64| {
        let ray = Ray::new([0.0, h, -1.0], [0.0, 0.0, 1.0]).unwrap();
        tracer.trace(ray, Travel::Forward)
    };
    let critical = radius / n;
    for margin in [1e-6, 1e-9, 1e-12] {
        let below = at_height(critical * (1.0 - margin));
        let above = at_height(critical * (1.0 + margin));
        assert_eq!(below.outcome, Outcome::Ok, "margin {margin}");
        assert_eq!(
            above.outcome,
            Outcome::Tir { surface: 2 },
            "margin {margin}"
        );
        assert_traced_finite(&below, "just below the critical angle");
        assert_traced_finite(&above, "just above the critical angle");
        // Just below, the ray leaves grazing the surface: refraction angle near 90 degrees,
        // as Snell's law n sin(i) = sin(r) gives for sin(i) = (1 - margin) / n.
        let q = below.ray.position();
        let normal = [0.0, -q[1] / radius, -(q[2] - (20.0 - radius)) / radius];
        let d = below.ray.direction();
        // Compared as cos^2 r, the Snell radicand, whose rounding is absolute (a few ulp of 1).
        let cos_r = (d[1] * normal[1] + d[2] * normal[2]).abs();
        let expected = 1.0 - (1.0 - margin).powi(2);
        assert!(
            (cos_r * cos_r - expected).abs() < 1e-15,
            "margin {margin}: cos^2 r = {}, Snell {expected}",
            cos_r * cos_r
        );
    }
    // The switch sits at the critical height to rounding.
    let (mut ok, mut tir) = (critical * 0.99, critical * 1.01);
    for _ in 0..200 {
        let mid = 0.5 * (ok + tir);
        if at_height(mid).outcome.is_ok() {
            ok = mid;
        } else {
            tir = mid;
        }
    }
    assert!(
        (ok / critical - 1.0).abs() < 1e-14,
        "switch at {ok}, critical {critical}"
    );

    // Plane exit face: a ray aimed at the front sphere's centre enters at normal incidence
    // and meets the plane at its own inclination, so TIR starts at asin(1 / n) there too.
    let front_radius = 30.0;
    let system = two_surface_lens(
        Shape::Sphere {
            curvature: 1.0 / front_radius,
        },
        Shape::Plane,
        n,
        12.0,
        21.0,
    );
    let tracer = Tracer::new(&system.at(D_LINE_NM));
    let at_angle = |theta: f64| {
        let d = [0.0, theta.sin(), theta.cos()];
        let start = [
            0.0,
            -front_radius * d[1],
            front_radius - front_radius * d[2],
        ];
        let ray = Ray::new(start, d).unwrap();
        tracer.trace(ray, Travel::Forward)
    };
    let critical_angle = (1.0 / n).asin();
    for margin in [1e-6, 1e-9, 1e-12] {
        let below = at_angle(critical_angle * (1.0 - margin));
        let above = at_angle(critical_angle * (1.0 + margin));
        assert_eq!(below.outcome, Outcome::Ok, "plane, margin {margin}");
        assert_eq!(
            above.outcome,
            Outcome::Tir { surface: 2 },
            "plane, margin {margin}"
        );
        assert_traced_finite(&below, "plane, below");
        assert_traced_finite(&above, "plane, above");
    }
}

#[test]
fn grazing_rays_end_typed() {
    // A sphere of radius 10 mm met by parallel rays ever closer to its equator (the tangent
    // line), with apertures ignored, then with rays almost perpendicular to the axis.
    let radius = 10.0;
    let system = two_surface_lens(
        Shape::Sphere {
            curvature: 1.0 / radius,
        },
        Shape::Plane,
        1.5,
        radius,
        radius,
    );
    let tracer = Tracer::new(&system.at(D_LINE_NM));
    let parallel = |h: f64| Ray::new([0.0, h, -5.0], [0.0, 0.0, 1.0]).unwrap();
    for k in 1..=15 {
        let h = radius * (1.0 - 10f64.powi(-k));
        for apertures in [Apertures::Checked, Apertures::Ignored] {
            let traced = tracer.trace_with(parallel(h), Travel::Forward, apertures);
            assert_traced_finite(&traced, &format!("h = R (1 - 1e-{k})"));
            // Inside, the ray enters at nearly grazing incidence, is bent to the critical angle
            // and meets the plane back face far beyond the critical angle there.
            if k >= 3 {
                assert_eq!(traced.outcome, Outcome::Tir { surface: 2 }, "1e-{k}");
            }
        }
    }
    // On the equator the surface turns parallel to the ray (no crossing in the travel sense);
    // beyond it there is nothing to meet.
    for h in [radius, radius * (1.0 + 1e-15), radius + 1e-9, 1e300] {
        let traced = tracer.trace_with(parallel(h), Travel::Forward, Apertures::Ignored);
        assert_eq!(traced.outcome, Outcome::Missed { surface: 1 }, "h = {h}");
        assert_traced_finite(&traced, "beyond the equator");
    }
    // Rays whose direction barely has a z component, or none.
    for dz in [1e-300, 1e-15, 1e-8, 0.0, -1e-15] {
        for start in [[0.0, 0.0, -5.0], [0.0, 3.0, 5.0], [1e3, -2.0, 0.5]] {
            let ray = Ray::new(start, [1.0, 0.3, dz]).unwrap();
            for travel in [Travel::Forward, Travel::Backward] {
                for apertures in [Apertures::Checked, Apertures::Ignored] {
                    let traced = tracer.trace_with(ray, travel, apertures);
                    assert_traced_finite(&traced, &format!("dz = {dz}, start {start:?}"));
                }
            }
        }
    }
}

/// Radial offsets of rays on and next to the axis.
const NEAR_AXIS: [f64; 3] = [0.0, 1e-300, 1e-12];

#[test]
fn rays_on_and_next_to_the_axis_trace_to_the_paraxial_focus() {
    for lens in lenses::BUNDLED {
        let system = bundled(lens.name);
        let analysis = analyze_finite(lens.name, &system, &AnalyzeOptions::default());
        let focus = analysis.first_order.z_rear_focal;
        // The reflex lens's secondary mirror shadows the axis; the geometry behind it is what
        // these rays test.
        let tracer = Tracer::new(&system.at(system.design_wavelength_nm()))
            .unobscured()
            .into_owned();
        let azimuth: f64 = 0.7;
        for r in NEAR_AXIS {
            let start = [r * azimuth.cos(), r * azimuth.sin(), tracer.front_start_z()];
            let traced = tracer.trace(Ray::new(start, [0.0, 0.0, 1.0]).unwrap(), Travel::Forward);
            assert_eq!(traced.outcome, Outcome::Ok, "{} at r = {r}", lens.name);
            assert_traced_finite(&traced, lens.name);
            let (p, d) = (traced.ray.position(), traced.ray.direction());
            if r == 0.0 {
                assert_eq!(
                    [p[0], p[1], d[0], d[1]],
                    [0.0; 4],
                    "{}: off axis",
                    lens.name
                );
                continue;
            }
            // Linear in r all the way down: the ray stays in its meridional plane and crosses
            // the axis at the paraxial focus (even at 1e-300 mm, where every second-order term
            // underflows to zero).
            assert!(
                (p[1] * azimuth.cos() - p[0] * azimuth.sin()).abs() <= 1e-12 * p[0].hypot(p[1]),
                "{} at r = {r}: left the meridional plane {p:?}",
                lens.name
            );
            let crossing = axis_crossing(&traced.ray);
            assert!(
                (crossing - focus).abs() < 1e-10 * analysis.first_order.efl.abs(),
                "{} at r = {r}: crosses at {crossing}, paraxial focus {focus}",
                lens.name
            );
        }
    }
}

#[test]
fn lrtf_lookups_on_and_next_to_the_axis() {
    // The spherical parameterisation has its pole on the axis (azimuth undefined), the
    // pupil-planes one its film-radius origin there: both must answer film-centre rays with
    // finite values that are continuous as the film point approaches the axis.
    let system = bundled("dgauss-50mm");
    let tracer = Tracer::new(&system.at(system.design_wavelength_nm()));
    for parameterisation in [Parameterisation::PupilPlanes, Parameterisation::Spherical] {
        let table = bake(
            &system,
            &BakeRequest {
                parameterisation,
                resolution: [16, 16, 16],
                ..BakeRequest::default()
            },
        )
        .unwrap();
        assert_table_finite(&table, parameterisation.name());
        let rim = pupil_rim_from_film_centre(&table, &tracer, [1.0, 0.0]);
        let stop = table.layers[0].stop_semi_aperture;
        // Measured at 16^3: pupil-planes within 0.01 mrad of the trace here; spherical, whose
        // error peaks at its pole, within 16.4 mrad.
        let allowed_mrad = match parameterisation {
            Parameterisation::PupilPlanes => 0.05,
            Parameterisation::Spherical => 25.0,
        };
        for rear in [[0.0, 0.0], [0.5 * rim, 0.0], [0.0, 0.7 * rim]] {
            let mut answers = Vec::new();
            for r in NEAR_AXIS {
                let ray = film_ray(&table, [r, 0.0], rear);
                let what = format!("{} r = {r} rear {rear:?}", parameterisation.name());
                assert_lookup_matches_trace(&table, &tracer, &ray, allowed_mrad, &what);
                let Lookup::Passes(looked) = table.lookup_layer(0, &ray, stop) else {
                    unreachable!("checked above")
                };
                answers.push(looked);
            }
            for looked in &answers[1..] {
                for k in 0..3 {
                    assert!(
                        (looked.origin[k] - answers[0].origin[k]).abs() < 1e-9
                            && (looked.direction[k] - answers[0].direction[k]).abs() < 1e-9,
                        "{}: discontinuous at the axis: {answers:?}",
                        parameterisation.name()
                    );
                }
            }
        }
    }
}

/// The y component of the exit direction of a parallel ray refracted out of glass of index `n`
/// where the surface's slope dz/dr is `slope`: Snell's law in angles, incidence i = atan(slope),
/// refraction r = asin(n sin i), deviation r - i.
fn exit_through_slope(n: f64, slope: f64) -> f64 {
    let i = slope.atan();
    ((n * i.sin()).asin() - i).sin()
}

/// Slope dz/dr of a sphere (or a conic-free even asphere without terms) of curvature c at r.
fn sphere_slope(c: f64, r: f64) -> f64 {
    c * r / (1.0 - c * c * r * r).sqrt()
}

/// Slope of the paraboloid z = c r^2 / 2.
fn paraboloid_slope(c: f64, r: f64) -> f64 {
    c * r
}

/// A surface's slope (dz/drho) at a height, given its curvature.
type SlopeOf = fn(f64, f64) -> f64;

#[test]
fn nearly_flat_surfaces_behave_as_planes_plus_their_first_order_effect() {
    // Exit surface of a glass block met by parallel rays. For |R| up to 1e300 the sag and the
    // deviation are tiny but must still come out right to rounding relative to themselves:
    // no catastrophic cancellation in the sag, the intersection or the normal.
    let n = 1.5;
    let vertex = 5.0;
    for curvature in [1e-9, -1e-10, 1e-12, -1e-300] {
        let shapes: [(&str, Shape, SlopeOf); 3] = [
            ("sphere", Shape::Sphere { curvature }, sphere_slope),
            (
                "paraboloid",
                Shape::Conic {
                    curvature,
                    conic: -1.0,
                },
                paraboloid_slope,
            ),
            (
                "even asphere",
                Shape::EvenAsphere {
                    curvature,
                    conic: 0.0,
                    coefficients: vec![0.0; 4],
                },
                sphere_slope,
            ),
        ];
        for (name, shape, slope) in shapes {
            let system = two_surface_lens(Shape::Plane, shape.clone(), n, vertex, 10.0);
            let tracer = Tracer::new(&system.at(D_LINE_NM));
            for h in [0.5, 3.0, 9.5] {
                let ray = Ray::new([0.0, h, -1.0], [0.0, 0.0, 1.0]).unwrap();
                let traced = tracer.trace(ray, Travel::Forward);
                assert_eq!(traced.outcome, Outcome::Ok);
                let (p, d) = (traced.ray.position(), traced.ray.direction());
                let what = format!("{name}, c = {curvature:e}, h = {h}");
                let expected_dy = exit_through_slope(n, slope(curvature, h));
                assert!(
                    (d[1] - expected_dy).abs() <= 1e-12 * expected_dy.abs(),
                    "{what}: dy {:e}, Snell {expected_dy:e}",
                    d[1]
                );
                let sag = shape.sag(h).unwrap();
                assert!(
                    (p[2] - (vertex + sag)).abs() <= 2.0 * f64::EPSILON * vertex,
                    "{what}: exit z {} vs {}",
                    p[2],
                    vertex + sag
                );
            }
        }
        // First order: a plano-convex front (R = 50 mm) with this nearly flat back has the
        // thick-lens power (n - 1) (c1 - c2) + (n - 1)^2 t c1 c2 / n.
        let c1 = 1.0 / 50.0;
        let system = two_surface_lens(
            Shape::Sphere { curvature: c1 },
            Shape::Sphere { curvature },
            n,
            vertex,
            10.0,
        );
        let analysis = analyze_finite(
            "nearly flat back",
            &system,
            &AnalyzeOptions {
                field_deg: Some(10.0),
                ..AnalyzeOptions::default()
            },
        );
        let power = (n - 1.0) * (c1 - curvature) + (n - 1.0).powi(2) * vertex * c1 * curvature / n;
        common::assert_close(
            analysis.first_order.efl,
            1.0 / power,
            1e-14,
            0.0,
            "thick-lens EFL with a nearly flat surface",
        );
    }
    // Shape::from_radius keeps radii up to infinity apart: 1e12 mm is a sphere, infinity a plane.
    assert_eq!(Shape::from_radius(1e12), Shape::Sphere { curvature: 1e-12 });
    assert_eq!(Shape::from_radius(f64::INFINITY), Shape::Plane);
}

#[test]
fn apertures_from_a_pinhole_to_a_hemisphere() {
    // Paraxial quantities are linear in the aperture: nothing over- or underflows between an
    // entrance pupil of 1 nm and one of 1 km.
    let system = bundled("dgauss-50mm");
    let reference = analyze_finite("dgauss-50mm", &system, &AnalyzeOptions::default());
    for epd in [1e-6, 1e6] {
        let analysis = analyze_finite(
            "dgauss-50mm",
            &system,
            &AnalyzeOptions {
                epd_mm: Some(epd),
                ..AnalyzeOptions::default()
            },
        );
        common::assert_close(
            analysis.first_order.f_number,
            reference.first_order.efl / epd,
            1e-14,
            0.0,
            "f-number at an extreme pupil",
        );
        let scale = epd / reference.first_order.entrance_pupil.diameter;
        common::assert_close(
            analysis.seidel.sums.coma,
            reference.seidel.sums.coma * scale.powi(3),
            1e-10,
            0.0,
            "S_II scales as the cube of the aperture",
        );
    }
    for epd in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let error = analyze(
            &system,
            &AnalyzeOptions {
                epd_mm: Some(epd),
                ..AnalyzeOptions::default()
            },
        )
        .expect_err("no such pupil");
        assert!(
            matches!(
                error,
                AnalysisError::Paraxial(ParaxialError::InvalidEntrancePupilDiameter { .. })
            ),
            "EPD {epd}: {error:?}"
        );
    }

    // A 1 nm stop still passes the ray aimed at its centre and stops one aimed just outside.
    let pinhole = system.at(system.design_wavelength_nm()).stopped_down(1e-6);
    let tracer = Tracer::new(&pinhole);
    let source = RaySource::Collimated {
        direction: [0.0, 0.1f64.sin(), 0.1f64.cos()],
        start_z: tracer.front_start_z(),
    };
    for (target, passes) in [
        ([0.0, 0.0], true),
        ([0.0, 0.9e-6], true),
        ([1.1e-6, 0.0], false),
    ] {
        let ray = aim_at_stop(&tracer, &source, target).expect("aimed through the pinhole");
        let traced = tracer.trace(ray, Travel::Forward);
        assert_traced_finite(&traced, "pinhole");
        assert_eq!(
            traced.outcome.is_ok(),
            passes,
            "target {target:?}: {traced:?}"
        );
    }

    // A hemisphere: the clear aperture equals the radius, so parallel rays run up to the
    // equator, where incidence turns grazing; in the glass they meet the flat back beyond the
    // critical angle.
    let radius = 10.0;
    let hemisphere = two_surface_lens(
        Shape::Sphere {
            curvature: 1.0 / radius,
        },
        Shape::Plane,
        1.5,
        radius,
        radius,
    );
    analyze_finite(
        "hemisphere",
        &hemisphere,
        &AnalyzeOptions {
            field_deg: Some(10.0),
            ..AnalyzeOptions::default()
        },
    );
    let tracer = Tracer::new(&hemisphere.at(D_LINE_NM));
    let mut outcomes = Vec::new();
    for k in 0..=1000 {
        let h = radius * k as f64 / 1000.0;
        let ray = Ray::new([0.0, h, -1.0], [0.0, 0.0, 1.0]).unwrap();
        let traced = tracer.trace(ray, Travel::Forward);
        assert_traced_finite(&traced, "hemisphere");
        outcomes.push(traced.outcome);
    }
    // Past h = R sin(i) with n sin(i - asin(sin(i) / n)) = 1 the back face reflects; the
    // switch is reached once and the outcome never flips back.
    let first_tir = outcomes
        .iter()
        .position(|o| *o == Outcome::Tir { surface: 2 })
        .expect("TIR at the back face");
    assert!(outcomes[..first_tir].iter().all(|o| o.is_ok()));
    assert!(
        outcomes[first_tir..1000]
            .iter()
            .all(|o| *o == Outcome::Tir { surface: 2 }),
        "{outcomes:?}"
    );
    assert_eq!(
        outcomes[1000],
        Outcome::Missed { surface: 1 },
        "the equator"
    );
    let exit_sine = |k: usize| {
        let incidence = (k as f64 / 1000.0).asin();
        1.5 * (incidence - (incidence.sin() / 1.5).asin()).sin()
    };
    assert!(exit_sine(first_tir - 1) < 1.0 && exit_sine(first_tir) > 1.0);
}

#[test]
fn closest_focus_approaches_the_front_focal_plane() {
    let system = bundled("dgauss-50mm");
    let at = system.at(system.design_wavelength_nm());
    let infinity = analyze_finite("dgauss-50mm", &system, &AnalyzeOptions::default());
    let first = &infinity.first_order;
    let front_focus_distance = -first.z_front_focal;
    let efl = first.efl;
    // Newton's equation in air: an object x beyond the front focal point images f^2 / x beyond
    // the rear one. The image distance is a cancelling difference of vergences, so its
    // rounding grows as 1 / x: the tolerance scales with it.
    for k in 1..=9 {
        let x = front_focus_distance * 10f64.powi(-k);
        let distance = front_focus_distance + x;
        let analysis = analyze_finite(
            "dgauss-50mm",
            &system,
            &AnalyzeOptions {
                object_distance_mm: Some(distance),
                ..AnalyzeOptions::default()
            },
        );
        let beyond = analysis.first_order.z_paraxial_image - first.z_rear_focal;
        let relative = 1e-14 * 10f64.powi(k);
        common::assert_close(beyond, efl * efl / x, relative, 0.0, "Newton's x x' = f^2");
        let sensor = sensor_z(&at, ObjectPosition::Finite { distance }).unwrap();
        common::assert_close(
            sensor,
            analysis.first_order.z_paraxial_image,
            relative,
            0.0,
            "sensor for the closest focus",
        );
    }
    // In the front focal plane the image is at infinity; inside it the image is virtual: no
    // sensor can take it (analyze still reports the virtual image).
    let at_focal_plane = ObjectPosition::Finite {
        distance: front_focus_distance,
    };
    assert_eq!(
        sensor_z(&at, at_focal_plane),
        Err(ParaxialError::ObjectAtFrontFocalPlane)
    );
    let error = analyze(
        &system,
        &AnalyzeOptions {
            object_distance_mm: Some(front_focus_distance),
            ..AnalyzeOptions::default()
        },
    )
    .unwrap_err();
    assert_eq!(
        error,
        AnalysisError::Paraxial(ParaxialError::ObjectAtFrontFocalPlane)
    );
    let inside = 0.5 * front_focus_distance;
    assert!(matches!(
        sensor_z(&at, ObjectPosition::Finite { distance: inside }),
        Err(ParaxialError::VirtualImage { .. })
    ));
    let virtual_image = analyze_finite(
        "dgauss-50mm",
        &system,
        &AnalyzeOptions {
            object_distance_mm: Some(inside),
            ..AnalyzeOptions::default()
        },
    );
    assert!(virtual_image.first_order.z_paraxial_image < first.z_last_vertex);
    for distance in [0.0, -10.0, f64::NAN, f64::INFINITY] {
        assert!(
            matches!(
                sensor_z(&at, ObjectPosition::Finite { distance }),
                Err(ParaxialError::ObjectNotInFront { .. })
            ),
            "distance {distance}"
        );
    }
    // Baking refuses a focus with no real image; just outside the front focal plane it bakes
    // (film a few metres back) and the table is finite.
    for distance in [inside, front_focus_distance] {
        let request = BakeRequest {
            resolution: [8, 8, 8],
            focus_mm: Some(distance),
            ..BakeRequest::default()
        };
        let error = bake(&system, &request).unwrap_err();
        assert!(
            matches!(error, BakeError::Paraxial(_) | BakeError::CannotFocus(_)),
            "focus {distance}: {error}"
        );
    }
    let near = front_focus_distance * 1.001;
    let table = bake(
        &system,
        &BakeRequest {
            resolution: [8, 8, 8],
            focus_mm: Some(near),
            ..BakeRequest::default()
        },
    )
    .unwrap();
    assert_table_finite(&table, "closest focus");
    common::assert_close(
        table.layers[0].frame.film_plane_z,
        sensor_z(&at, ObjectPosition::Finite { distance: near }).unwrap(),
        1e-6,
        0.0,
        "baked film plane at the closest focus",
    );
}

#[test]
fn a_long_grazing_flight_keeps_the_next_intersection_exact() {
    // Found by the random-ray property test: a ray leaving the axis 34 mm in front of the lens
    // with dz = 7e-10 flies 5e10 mm to reach the first (plane, air to air) surface. Solved from
    // there, the next sphere's quadratic had coefficients of 1e20 that cancelled to a spurious
    // hit with a non-unit normal: the ray went on with |d| = 2.6 and ended as "TIR" at surface
    // 3. The line misses the sphere by 5e10 mm.
    let surface = |shape, thickness, medium, stop| Surface {
        shape,
        thickness,
        medium,
        semi_aperture: 4.0,
        stop,
        obscuration: None,
    };
    let system = LensSystem::from_prescription(Prescription {
        provenance: Provenance {
            title: "plane, sphere, plane".into(),
            ..Provenance::default()
        },
        object_medium: Medium::Air,
        surfaces: vec![
            surface(Shape::Plane, 3.0, Medium::Air, Some(StopShape::Circle)),
            surface(
                Shape::Sphere {
                    curvature: 1.0 / 15.0,
                },
                3.0,
                Medium::Index(1.45),
                None,
            ),
            surface(Shape::Plane, 20.0, Medium::Air, None),
        ],
    })
    .unwrap();
    let tracer = Tracer::new(&system.at(D_LINE_NM));
    let ray = Ray::new(
        [0.0, 0.0, -34.036979398375976],
        [
            0.3307296271292779,
            0.8239653228457696,
            7.084444120458869e-10,
        ],
    )
    .unwrap();
    let traced = tracer.trace_with(ray, Travel::Forward, Apertures::Ignored);
    assert_traced_finite(&traced, "grazing flight");
    assert_eq!(traced.outcome, Outcome::Missed { surface: 2 });
    // The same line started where it crosses surface 1: the same outcome.
    let restarted = Ray::new(traced.ray.position(), ray.direction()).unwrap();
    assert_eq!(
        tracer
            .trace_with(restarted, Travel::Forward, Apertures::Ignored)
            .outcome,
        Outcome::Missed { surface: 2 }
    );
}

#[test]
fn an_aspheric_stop_stopped_far_down_still_bakes_its_field() {
    // The f/0.95 singlet with its stop on the even-asphere front surface, baked at f/64. The
    // tracer limits an even asphere's Newton search to twice the surface's extent; stopping
    // down used to shrink that extent with the stop (one semi-aperture field for both), so at
    // f/64 the bare geometry of the front surface ended 0.7 mm from the axis, the chief-ray
    // search in chief_ray_film_radius found no ray pair to bisect, and the table covered a
    // film radius of 0 (58.5 mm at f/8, 49.8 mm at f/22). Stopping down now changes only the
    // limiting radius: the conic form of the same surface (closed-form intersection, never
    // affected) covers 59.0 mm at every f-number, and so must the asphere.
    let request = BakeRequest {
        resolution: [8, 8, 8],
        f_number: Some(64.0),
        ..BakeRequest::default()
    };
    let system = common::f095_singlet(true);
    let table = bake(&system, &request).unwrap();
    assert!(
        table.layers[0].frame.max_film_radius > 59.0,
        "{:?}",
        table.layers[0].frame
    );
    // The root: with apertures ignored, the lens closed to a 0.1 mm stop traces a ray 15 mm off
    // the axis bit for bit as the lens wide open does; with apertures on the stop blocks it.
    let wide = system.at(system.design_wavelength_nm());
    let closed = wide.stopped_down(0.1);
    let ray = Ray::new([0.0, 15.0, -10.0], [0.0, -0.1, 1.0]).unwrap();
    let trace = |at: &lensbake::system::SystemAt, apertures| {
        Tracer::new(at).trace_with(ray, Travel::Forward, apertures)
    };
    let open = trace(&wide, Apertures::Ignored);
    assert!(open.outcome.is_ok(), "{open:?}");
    assert_eq!(trace(&closed, Apertures::Ignored), open);
    assert_eq!(
        trace(&closed, Apertures::Checked).outcome,
        Outcome::Vignetted { surface: 1 }
    );
}

/// A relay of two positive singlets further apart than their focal lengths together: the
/// image of a distant object is real (99 mm behind the last vertex) but the focal length is
/// negative. The analysis reports it as it is; models, bakes and tradeoffs, which stop a lens
/// down by comparing f-numbers, refuse it by name (they had refused it as `f-number -2.54 is
/// faster than the lens wide open (f/-2.542)`).
#[test]
fn a_lens_of_negative_focal_length_is_analysed_and_refused_by_name_for_models_and_tables() {
    use lensbake::model::{FirstOrderModels, ModelError};
    let relay = "50 5 1.5 20\n-50 75 1 20\n0 75 0 10\n50 5 1.5 20\n-50 60 1 20\n";
    use lensbake::prescription::formats::{Format, LoadOptions, read_str};
    let loaded = read_str(relay, None, Format::Pbrt, &LoadOptions::default()).unwrap();
    let system = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
    let report = analyze_finite("relay", &system, &AnalyzeOptions::default());
    let efl = report.first_order.efl;
    assert!((-50.1..-49.9).contains(&efl), "EFL {efl}");
    assert!(
        report.first_order.bfl > 99.0,
        "BFL {}",
        report.first_order.bfl
    );
    let diverging =
        |e: &ParaxialError| matches!(e, ParaxialError::Diverging { efl: e } if *e == efl);
    match FirstOrderModels::of(&system, None) {
        Err(ModelError::Paraxial(e)) => assert!(diverging(&e), "{e}"),
        other => panic!("{other:?}"),
    }
    let request = BakeRequest {
        resolution: [4, 4, 4],
        ..BakeRequest::default()
    };
    match bake(&system, &request) {
        Err(BakeError::Paraxial(e)) => assert!(diverging(&e), "{e}"),
        other => panic!("{:?}", other.map(|_| "a table")),
    }
}
