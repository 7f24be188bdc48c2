//! Analyze, trace and bake at the extremes: a very fast aspheric lens, the fisheye at its widest
//! traceable field, a long telephoto, rays at the total-internal-reflection limit and grazing
//! rays, rays on and next to the axis, flat and nearly flat surfaces, tiny and huge apertures, the
//! closest focus, and both ends of the visible band. Every number that comes out is checked to be
//! finite, and each case is checked against an analytic truth where one exists.

mod common;

use lensbake::analysis::{AnalysisError, AnalyzeOptions, analyze};
use lensbake::glass::{CATALOG, D_LINE_NM};
use lensbake::lenses;
use lensbake::prescription::{Medium, Prescription, Problem};
use lensbake::system::LensSystem;
use lensbake::trace::{Ray, Tracer, Travel};
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
    let analysis = analyze(name, system, options)
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
    for glass in CATALOG {
        let mut previous = f64::INFINITY;
        for step in 0..=80 {
            let nm = 380.0 + 5.0 * step as f64;
            let n = glass
                .formula
                .checked_index(nm)
                .unwrap_or_else(|e| panic!("{} at {nm} nm: {e}", glass.name));
            assert!(
                (1.4..2.2).contains(&n),
                "{} at {nm} nm: n = {n}",
                glass.name
            );
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
        // Normal dispersion makes a positive lens shorter in the blue; the colour stays a
        // small fraction of the focal length in a corrected lens.
        assert!(
            (efl[0] - efl[2]).abs() < 0.02 * efl[1],
            "{name}: EFL at 380/587/780 nm {efl:?}"
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
        ("tessar", 30.0, 1),
    ];
    for (name, nm, surface) in cases {
        let system = bundled(name);
        let error = analyze(
            name,
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
