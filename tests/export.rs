//! `lens convert` to Zemax `.zmx` and pbrt `.dat`: lensbake -> file -> lensbake gives the same
//! surfaces (every f64 bit for bit, since numbers are written in their shortest exact form; pbrt
//! writes radii, so curvatures come back within one rounding) and the same first-order data; what a format cannot hold is refused, naming the surface.

use lensbake::analysis::{AnalyzeOptions, analyze};
use lensbake::glass::lookup;
use lensbake::lenses::load;
use lensbake::prescription::formats::{Format, LoadOptions, read_str, write_pbrt, write_zemax};
use lensbake::prescription::{Medium, Prescription, Problem};
use lensbake::system::LensSystem;
use std::path::{Path, PathBuf};

fn corpus(name: &str) -> String {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/corpus")
        .join(name)
        .to_string_lossy()
        .into_owned()
}

fn system(spec: &str) -> LensSystem {
    load(spec, &LoadOptions::default())
        .unwrap_or_else(|e| panic!("{spec}: {e}"))
        .system
}

fn read_back(text: &str, format: Format) -> LensSystem {
    let loaded = read_str(
        text,
        Some(Path::new("written")),
        format,
        &LoadOptions::default(),
    )
    .unwrap_or_else(|e| panic!("{e}\n{text}"));
    LensSystem::new(loaded.prescription, &loaded.map).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

/// Shape, thickness, clear aperture and stop of every surface, bit for bit; a format that
/// writes radii (pbrt) gives the curvature back as 1 / (1 / c), within one rounding of c.
fn assert_same_geometry(a: &Prescription, b: &Prescription, radii: bool, what: &str) {
    assert_eq!(a.surfaces.len(), b.surfaces.len(), "{what}");
    for (i, (x, y)) in a.surfaces.iter().zip(&b.surfaces).enumerate() {
        if radii {
            let (c, d) = (x.shape.curvature(), y.shape.curvature());
            assert!(
                (c - d).abs() <= 2.0 * f64::EPSILON * c.abs(),
                "{what} surface {}",
                i + 1
            );
        } else {
            assert_eq!(x.shape, y.shape, "{what} surface {}", i + 1);
        }
        assert_eq!(x.thickness, y.thickness, "{what} surface {}", i + 1);
        assert_eq!(x.semi_aperture, y.semi_aperture, "{what} surface {}", i + 1);
        assert_eq!(
            x.stop.is_some(),
            y.stop.is_some(),
            "{what} surface {}",
            i + 1
        );
    }
}

/// EFL, BFL, entrance pupil and Seidel sums at one wavelength, relative to 1e-12 (the sums to
/// 1e-12 of the largest).
fn assert_same_first_order(a: &LensSystem, b: &LensSystem, nm: f64, what: &str) {
    let options = AnalyzeOptions {
        wavelength_nm: Some(nm),
        epd_mm: Some(4.0),
        field_deg: Some(5.0),
        ..AnalyzeOptions::default()
    };
    let x = analyze(a, &options).unwrap();
    let y = analyze(b, &options).unwrap();
    let (f, g) = (&x.first_order, &y.first_order);
    for (name, p, q) in [
        ("efl", f.efl, g.efl),
        ("bfl", f.bfl, g.bfl),
        ("entrance pupil z", f.entrance_pupil.z, g.entrance_pupil.z),
    ] {
        assert!(
            (p - q).abs() <= 1e-12 * p.abs().max(1.0),
            "{what} {name}: {p} vs {q}"
        );
    }
    let (s, t) = (&x.seidel.sums, &y.seidel.sums);
    let ours = [s.spherical, s.coma, s.astigmatism, s.petzval, s.distortion];
    let theirs = [t.spherical, t.coma, t.astigmatism, t.petzval, t.distortion];
    let scale = ours.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (k, (p, q)) in ours.iter().zip(&theirs).enumerate() {
        assert!(
            (p - q).abs() <= 1e-12 * scale,
            "{what} S{}: {p} vs {q}",
            k + 1
        );
    }
}

#[test]
fn zemax_round_trip_keeps_surfaces_glasses_conditions_and_first_order() {
    for spec in [
        "cooke-triplet".to_string(),
        "codev-dgauss-f2".to_string(),
        "dgauss-50mm".to_string(),
        // An even asphere on a model-glass layer, glasses named with a maker suffix.
        corpus("rayoptics__CODV_49664.seq"),
        corpus("optiland__lens1.zmx"),
        // Odd aspheres, one with a cone term.
        PathBuf::from(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data/odd_asphere_cone.zmx")
            .to_string_lossy()
            .into_owned(),
    ] {
        let original = system(&spec);
        let text = write_zemax(&original.prescription).unwrap();
        let back = read_back(&text, Format::Zemax);
        let (a, b) = (&original.prescription, &back.prescription);
        assert_same_geometry(a, b, false, &spec);
        // A catalogue glass comes back as the same catalogue entry (its spelling may differ:
        // `SK16_HIKARI` in a bundled lens is `SK16` where no other catalogue has an SK16).
        for (x, y) in a.surfaces.iter().zip(&b.surfaces) {
            match (&x.medium, &y.medium) {
                (Medium::Glass(m), Medium::Glass(n)) => {
                    let (g, h) = (lookup(m).unwrap(), lookup(n).unwrap());
                    assert_eq!((g.name, g.maker), (h.name, h.maker), "{spec}");
                }
                (m, n) => assert_eq!(m, n, "{spec}"),
            }
        }
        // A lens without stated conditions gets its design wavelength as the file's one
        // wavelength (a Zemax file needs one); stated conditions come back whole.
        if a.provenance.conditions.is_some() {
            assert_eq!(
                a.provenance.conditions, b.provenance.conditions,
                "{spec}\n{text}"
            );
        }
        assert_eq!(
            original.design_wavelength_nm(),
            back.design_wavelength_nm(),
            "{spec}"
        );
        assert_same_first_order(&original, &back, original.design_wavelength_nm(), &spec);
    }
}

#[test]
fn pbrt_round_trip_keeps_surfaces_and_first_order_at_the_design_wavelength() {
    for spec in ["dgauss-50mm".to_string(), corpus("optiland__lens1.zmx")] {
        let original = system(&spec);
        let nm = original.design_wavelength_nm();
        let text = write_pbrt(&original.prescription, nm).unwrap();
        let back = read_back(&text, Format::Pbrt);
        assert_same_geometry(&original.prescription, &back.prescription, true, &spec);
        // pbrt holds one index per medium: the glass's index at the design wavelength.
        for (x, y) in original
            .prescription
            .surfaces
            .iter()
            .zip(&back.prescription.surfaces)
        {
            if x.stop.is_none() {
                let n = lensbake::glass::Dispersion::of(&x.medium)
                    .unwrap()
                    .index(nm);
                let expected = if n == 1.0 {
                    Medium::Air
                } else {
                    Medium::Index(n)
                };
                assert_eq!(y.medium, expected, "{spec}");
            }
        }
        assert_same_first_order(&original, &back, nm, &spec);
    }
}

#[test]
fn what_a_format_cannot_hold_is_refused_naming_the_surface() {
    let asphere = system(&corpus("rayoptics__CODV_49664.seq"));
    let refusal = |r: Result<String, Problem>| match r {
        Err(Problem::Unsupported(what)) => what,
        other => panic!("{other:?}"),
    };
    let why = refusal(write_pbrt(&asphere.prescription, 587.6));
    assert!(why.contains("surface 1") && why.contains("stop"), "{why}");
    let mut p = system("dgauss-50mm").prescription;
    p.surfaces[3].shape = lensbake::prescription::Shape::Conic {
        curvature: 0.02,
        conic: -0.5,
    };
    let why = refusal(write_pbrt(&p, 587.6));
    assert!(
        why.contains("surface 4: a conic or aspheric surface"),
        "{why}"
    );
    // A sphere of curvature 0 (or -0, or subnormal) is a plane: refused as one when it
    // refracts (its reciprocal radius was written as `inf`), written as radius 0 at the stop.
    for curvature in [0.0, -0.0, 5e-324] {
        let mut flat = system("dgauss-50mm").prescription;
        flat.surfaces[3].shape = lensbake::prescription::Shape::Sphere { curvature };
        let why = refusal(write_pbrt(&flat, 587.6));
        assert!(
            why.contains("surface 4: a plane refracting surface"),
            "{why}"
        );
        let stop = flat.surfaces.iter().position(|s| s.stop.is_some()).unwrap();
        flat.surfaces[3] = system("dgauss-50mm").prescription.surfaces[3].clone();
        flat.surfaces[stop].shape = lensbake::prescription::Shape::Sphere { curvature };
        let text = write_pbrt(&flat, 587.6).unwrap();
        assert!(!text.contains("inf"), "{text}");
        let back = read_back(&text, Format::Pbrt);
        assert_eq!(back.prescription.surfaces.len(), flat.surfaces.len());
    }
    p.surfaces[0].medium = Medium::Sellmeier {
        b: [1.0, 0.2, 1.0],
        c: [0.006, 0.02, 100.0],
    };
    let why = refusal(write_zemax(&p));
    assert!(
        why.contains("surface 1: a medium given by its own coefficients"),
        "{why}"
    );
}

/// The reflex lens goes to Zemax with its two mirrors (`GLAS MIRROR`, negative thicknesses) and
/// its obscuration (`OBSC 0 r`) and comes back the same lens; pbrt's RealisticCamera holds
/// neither, so the pbrt writer refuses it rather than flattening it.
#[test]
fn mirrors_and_obscurations_go_to_zemax_and_are_refused_by_pbrt() {
    let reflex = system("reflex-1000mm-f7.5");
    let text = write_zemax(&reflex.prescription).unwrap();
    let back = read_back(&text, Format::Zemax);
    assert_same_geometry(&reflex.prescription, &back.prescription, false, "reflex");
    for (a, b) in reflex
        .prescription
        .surfaces
        .iter()
        .zip(&back.prescription.surfaces)
    {
        assert_eq!(a.medium == Medium::Mirror, b.medium == Medium::Mirror);
        assert_eq!(a.obscuration, b.obscuration);
    }
    let efl = |s: &LensSystem| {
        analyze(s, &AnalyzeOptions::default())
            .unwrap()
            .first_order
            .efl
    };
    assert_eq!(efl(&reflex), efl(&back));
    match write_pbrt(&reflex.prescription, 587.56) {
        Err(Problem::Unsupported(what)) => assert!(what.contains("mirror"), "{what}"),
        other => panic!("{other:?}"),
    }
}

/// A bundled lens states no conditions but carries its source's claims (f-number, half field),
/// which lensbake analyses it under. Written to Zemax with the claims stated, it is analysed
/// under the same pupil and fields; written as it was, with `FLOA` and the axis alone, the
/// double Gauss lost its 22-degree field (the rule gave 29) and the telephoto its f-number.
#[test]
fn claims_go_to_zemax_as_the_conditions_lensbake_analyses_under() {
    use lensbake::analysis::{ConditionOverrides, DesignConditions, Origin, stated_as_analysed};
    let resolve = |system: &LensSystem| {
        DesignConditions::resolve(system, &ConditionOverrides::default()).unwrap()
    };
    for lens in lensbake::lenses::BUNDLED {
        let original = system(lens.name);
        let before = resolve(&original);
        let text = write_zemax(&stated_as_analysed(&original)).unwrap();
        let after = resolve(&read_back(&text, Format::Zemax));
        assert_eq!(after.fields_deg, before.fields_deg, "{}\n{text}", lens.name);
        assert_eq!(after.epd_mm, before.epd_mm, "{}\n{text}", lens.name);
        assert_eq!(after.reference_nm, before.reference_nm, "{}", lens.name);
        for (origin, became) in [
            (before.field_from, after.field_from),
            (before.aperture_from, after.aperture_from),
        ] {
            if origin == Origin::Source {
                assert_eq!(became, Origin::File, "{}", lens.name);
            }
        }
    }
    // A claim the stop does not allow (the double Gauss's f/2 needs a wider pupil than its
    // stop's) is not written: the lens is analysed wide open, as before.
    let dgauss = stated_as_analysed(&system("dgauss-50mm"));
    let aperture = dgauss.provenance.conditions.unwrap().aperture;
    assert_eq!(aperture, None);
    // Stated wavelengths without a primary are analysed at the first (656.3 nm here); the Zemax
    // file's PWAV had named the design wavelength's place (587.6 nm) instead.
    let mut p = system("codev-dgauss-f2").prescription;
    p.provenance.conditions.as_mut().unwrap().primary = None;
    let original = LensSystem::from_prescription(p).unwrap();
    let back = read_back(&write_zemax(&original.prescription).unwrap(), Format::Zemax);
    assert_eq!(resolve(&original).reference_nm, 656.3);
    assert_eq!(resolve(&back).reference_nm, 656.3);
}

/// A CODE V `FNO` with a finite object is a working f-number, which a Zemax file cannot state:
/// converted, it becomes the entrance-pupil diameter it gives (it was left out, and the copy
/// analysed wide open).
#[test]
fn a_working_f_number_goes_to_zemax_as_the_pupil_it_gives() {
    use lensbake::analysis::{ConditionOverrides, DesignConditions, stated_as_analysed};
    use lensbake::prescription::ApertureSpec;
    for fno in ["5.0", "0.005"] {
        // Written without RDM in curvatures, as CODE V reads such a file.
        let text = std::fs::read_to_string(corpus("rayoptics__singlet.seq"))
            .unwrap()
            .replacen("fno 5.0", &format!("fno {fno}"), 1)
            .replacen("tit", "rdm n\ntit", 1);
        let original = read_back(&text, Format::CodeV);
        let stated = original
            .prescription
            .provenance
            .conditions
            .as_ref()
            .unwrap();
        assert!(matches!(
            stated.aperture,
            Some(ApertureSpec::WorkingFNumber(_))
        ));
        let back = read_back(
            &write_zemax(&stated_as_analysed(&original)).unwrap(),
            Format::Zemax,
        );
        let epd = |system: &LensSystem| {
            DesignConditions::resolve(system, &ConditionOverrides::default())
                .unwrap()
                .epd_mm
        };
        let (before, after) = (epd(&original), epd(&back));
        assert!(
            (after - before).abs() <= 1e-12 * before,
            "FNO {fno}: {before} against {after}"
        );
    }
}

/// Constant indices at one wavelength: every bundled lens at the F line gives, at that
/// wavelength, the same indices bit for bit (so the same first-order data and Seidel sums), at any other
/// wavelength the same again (no dispersion left), the same geometry, and mirrors and air kept.
#[test]
fn indices_at_one_wavelength_keep_the_lens_at_that_wavelength() {
    let nm = lensbake::glass::F_LINE_NM;
    for lens in lensbake::lenses::BUNDLED {
        let original = system(lens.name);
        let frozen = original
            .prescription
            .with_indices_at(nm)
            .unwrap_or_else(|e| panic!("{}: {e}", lens.name));
        assert_same_geometry(&original.prescription, &frozen, false, lens.name);
        assert_eq!(frozen.provenance.design_wavelength_nm, Some(nm));
        let frozen = LensSystem::new(frozen, &Default::default()).unwrap();
        let indices = |s: &LensSystem, at: f64| {
            let at = s.at(at);
            let mut indices = vec![at.object_index];
            indices.extend(at.surfaces.iter().map(|s| s.index_after));
            indices
        };
        assert_eq!(
            indices(&frozen, nm),
            indices(&original, nm),
            "{}",
            lens.name
        );
        assert_eq!(
            indices(&frozen, 650.0),
            indices(&frozen, nm),
            "{}",
            lens.name
        );
        for (before, after) in original
            .prescription
            .surfaces
            .iter()
            .zip(&frozen.prescription.surfaces)
        {
            match &before.medium {
                Medium::Air | Medium::Mirror | Medium::Index(_) => {
                    assert_eq!(after.medium, before.medium)
                }
                _ => assert!(matches!(after.medium, Medium::Index(_)), "{}", lens.name),
            }
        }
        assert_same_first_order(&original, &frozen, nm, lens.name);
    }
}

/// A wavelength where a glass's formula is not defined names the surface and the field, and a
/// wavelength outside lensbake's range is refused before any medium is looked at.
#[test]
fn indices_at_a_wavelength_a_glass_lacks_name_the_surface() {
    let triplet = system("cooke-triplet").prescription;
    let e = triplet.with_indices_at(99_000.0).unwrap_err();
    assert_eq!(e.location.surface, Some(1));
    assert_eq!(e.location.field.as_deref(), Some("medium"));
    assert!(
        matches!(e.problem, Problem::WavelengthOutOfRange { .. }),
        "{e}"
    );
    let e = triplet.with_indices_at(f64::NAN).unwrap_err();
    assert_eq!(e.location.surface, None);
    assert!(e.to_string().contains("not a number"), "{e}");
}
