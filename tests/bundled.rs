//! The bundled lenses: canonical RON that round-trips, validates and cites its source, and
//! surface tables that match the files and oracle tables they were taken from.

mod common;

use lensbake::glass::lookup;
use lensbake::lenses::BUNDLED;
use lensbake::prescription::{Medium, Prescription, Shape, StopShape};
use lensbake::system::{LensSystem, SystemAt};

fn bundled(name: &str) -> Prescription {
    let lens = BUNDLED
        .iter()
        .find(|l| l.name == name)
        .unwrap_or_else(|| panic!("no bundled lens {name}"));
    ron::from_str(lens.ron).unwrap_or_else(|e| panic!("{name}: {e}"))
}

fn system(name: &str) -> LensSystem {
    LensSystem::from_prescription(bundled(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// Paraxial trace of a ray parallel to the axis at height 1: (EFL, height at the stop, BFL).
/// Independent of the crate's paraxial module on purpose: it only has to tell a transcription
/// error (wrong sign, wrong scale, wrong row) from the lens the source describes.
fn first_order(at: &SystemAt) -> (f64, f64, f64) {
    let (mut y, mut nu) = (1.0, 0.0);
    let mut y_stop = f64::NAN;
    let mut last = (y, nu);
    for (i, s, n_before, n_after) in at.path() {
        if i == at.stop {
            y_stop = y;
        }
        nu -= y * s.curvature() * (n_after - n_before);
        last = (y, nu);
        y += s.thickness * nu / n_after;
    }
    let n_image = at.image_index();
    let (y_last, nu_last) = last;
    (-n_image / nu_last, y_stop, -y_last * n_image / nu_last)
}

/// Rows of a whitespace-separated table file, comments (`#`) skipped.
fn table_rows(relative: &str) -> Vec<Vec<String>> {
    let path = common::testdata_dir().join(relative);
    std::fs::read_to_string(&path)
        .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
        .map(|l| l.split_whitespace().map(str::to_string).collect())
        .collect()
}

fn medium_of_index(n: f64) -> Medium {
    if n == 1.0 {
        Medium::Air
    } else {
        Medium::Index(n)
    }
}

#[test]
fn bundled_names_are_sorted_unique_and_match_the_lens_files() {
    let names: Vec<&str> = BUNDLED.iter().map(|l| l.name).collect();
    let mut sorted = names.clone();
    sorted.sort();
    sorted.dedup();
    assert_eq!(
        names, sorted,
        "BUNDLED must be sorted by name without duplicates"
    );

    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("lenses");
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .filter_map(|f| f.strip_suffix(".ron").map(str::to_string))
        .collect();
    files.sort();
    assert_eq!(
        files, names,
        "every lenses/*.ron is registered, and only those"
    );
    for lens in BUNDLED {
        let on_disk = std::fs::read_to_string(dir.join(format!("{}.ron", lens.name))).unwrap();
        assert_eq!(
            on_disk, lens.ron,
            "{}: embedded text differs from the file",
            lens.name
        );
    }

    for name in [
        "kolb-dgauss",
        "dgauss-50mm",
        "wide-22mm",
        "fisheye-10mm",
        "telephoto-250mm",
        "codev-dgauss-f2",
        "cooke-triplet",
        "tessar",
        "petzval",
        "biconvex-singlet",
        "reflex-1000mm-f7.5",
    ] {
        assert!(names.contains(&name), "{name} is not bundled");
    }
}

/// Canonical form: the file is exactly what `to_string_pretty` writes, so parse -> write -> parse
/// loses nothing and rewrites nothing.
#[test]
fn every_bundled_lens_round_trips_bit_exactly() {
    for lens in BUNDLED {
        let parsed: Prescription = ron::from_str(lens.ron).unwrap();
        let written =
            ron::ser::to_string_pretty(&parsed, ron::ser::PrettyConfig::default()).unwrap();
        // What was written reads back to the same prescription (every f64 bit for bit)...
        let again: Prescription = ron::from_str(&written).unwrap();
        assert_eq!(again, parsed, "{}", lens.name);
        // ...and is the bundled file itself.
        assert_eq!(
            written + "\n",
            lens.ron,
            "{} is not in canonical form",
            lens.name
        );
    }
}

#[test]
fn every_bundled_lens_validates_cites_its_source_and_names_known_glasses() {
    for lens in BUNDLED {
        let p = bundled(lens.name);
        let provenance = &p.provenance;
        assert!(
            !provenance.title.trim().is_empty(),
            "{}: no title",
            lens.name
        );
        assert!(
            provenance
                .source
                .as_deref()
                .is_some_and(|s| !s.trim().is_empty()),
            "{}: no source",
            lens.name
        );
        for medium in std::iter::once(&p.object_medium).chain(p.surfaces.iter().map(|s| &s.medium))
        {
            if let Medium::Glass(name) = medium {
                lookup(name).unwrap_or_else(|e| panic!("{}: {e}", lens.name));
            }
        }
        LensSystem::from_prescription(p).unwrap_or_else(|e| panic!("{}: {e}", lens.name));
    }
}

/// Each source's claims against the lens as transcribed. Focal lengths are nominal (scaled
/// designs, product names): within 1%. F-numbers follow from the stop size the source gives:
/// within 4% (the worst, pbrt's telephoto, is f/5.42 for the designer's F/5.6).
#[test]
fn computed_focal_length_and_f_number_agree_with_the_claims() {
    for lens in BUNDLED {
        let sys = system(lens.name);
        let at = sys.at(sys.design_wavelength_nm());
        let (efl, y_stop, _) = first_order(&at);
        let claims = &sys.prescription.provenance;
        if let Some(f) = claims.claimed_focal_length_mm {
            assert!(
                ((efl - f) / f).abs() < 0.01,
                "{}: EFL {efl} vs claimed {f}",
                lens.name
            );
        }
        if let Some(claimed) = claims.claimed_f_number {
            let entrance_pupil = 2.0 * sys.prescription.surfaces[sys.stop].semi_aperture / y_stop;
            let f_number = efl / entrance_pupil;
            assert!(
                ((f_number - claimed) / claimed).abs() < 0.04,
                "{}: f-number {f_number} vs claimed {claimed}",
                lens.name
            );
        }
    }
}

/// pbrt's reading of a `.dat` row: radius, thickness to the next surface, index (0 on the stop
/// row: the medium does not change), aperture diameter.
#[test]
fn dgauss_50mm_is_the_pbrt_file() {
    let p = bundled("dgauss-50mm");
    let rows = table_rows("lenses/dgauss.50mm.dat");
    assert_eq!(p.surfaces.len(), rows.len());
    let mut medium = Medium::Air;
    for (i, (s, row)) in p.surfaces.iter().zip(&rows).enumerate() {
        let v: Vec<f64> = row.iter().map(|x| x.parse().unwrap()).collect();
        let is_stop = v[0] == 0.0;
        if !(is_stop && v[2] == 0.0) {
            medium = medium_of_index(v[2]);
        }
        assert_eq!(s.shape, Shape::from_radius(v[0]), "surface {}", i + 1);
        assert_eq!(s.thickness, v[1], "surface {}", i + 1);
        assert_eq!(s.medium, medium, "surface {}", i + 1);
        assert_eq!(s.semi_aperture, v[3] / 2.0, "surface {}", i + 1);
        assert_eq!(s.stop.is_some(), is_stop, "surface {}", i + 1);
    }
    assert_eq!(p.stop_index(), Some(5));
}

#[test]
fn kolb_dgauss_is_the_kolb_table() {
    let p = bundled("kolb-dgauss");
    let rows = table_rows("lenses/kolb_dgauss_1995.dat");
    assert_eq!(p.surfaces.len(), rows.len());
    assert_eq!(p.object_medium, Medium::Air);
    for (i, (s, row)) in p.surfaces.iter().zip(&rows).enumerate() {
        let is_stop = row[0] == "N/A";
        let radius = if is_stop {
            0.0
        } else {
            row[0].parse().unwrap()
        };
        let v: Vec<f64> = row[1..].iter().map(|x| x.parse().unwrap()).collect();
        assert_eq!(s.shape, Shape::from_radius(radius), "surface {}", i + 1);
        assert_eq!(s.thickness, v[0], "surface {}", i + 1);
        assert_eq!(s.medium, medium_of_index(v[1]), "surface {}", i + 1);
        assert_eq!(s.semi_aperture, v[2] / 2.0, "surface {}", i + 1);
        assert_eq!(
            s.stop,
            is_stop.then_some(StopShape::Circle),
            "surface {}",
            i + 1
        );
    }
    assert_eq!(p.surfaces[1].medium, Medium::Index(1.00027715));
}

/// Geometry to 1e-12 relative; indices at the oracle's wavelengths (n, and nF/nC where the
/// oracle lists them; constant-index tables give n at the lens wavelength only).
fn assert_matches_oracle(name: &str, oracle_file: &str, index_tolerance: f64) {
    let sys = system(name);
    let oracle = common::oracle_json(oracle_file);
    let lens = &oracle["lenses"][0];
    let table = &lens["prescription"];
    let surfaces = table["surfaces"].as_array().unwrap();
    assert_eq!(sys.prescription.surfaces.len(), surfaces.len(), "{name}");
    assert_eq!(
        sys.stop + 1,
        table["stop_surface"].as_u64().unwrap() as usize,
        "{name}: stop surface"
    );
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs().max(1.0);
    for (s, o) in sys.prescription.surfaces.iter().zip(surfaces) {
        let k = o["surface"].as_u64().unwrap();
        match o["radius"].as_f64() {
            Some(r) => assert!(close(s.shape.radius(), r), "{name} surface {k}: radius"),
            None => assert_eq!(s.shape, Shape::Plane, "{name} surface {k}"),
        }
        assert!(close(s.shape.curvature(), o["curvature"].as_f64().unwrap()));
        assert!(
            close(s.thickness, o["thickness"].as_f64().unwrap()),
            "{name} surface {k}"
        );
        assert_eq!(
            s.semi_aperture,
            o["semi_aperture"].as_f64().unwrap(),
            "{name} surface {k}"
        );
        assert_eq!(
            s.stop.is_some(),
            o["stop"].as_bool().unwrap(),
            "{name} surface {k}"
        );
    }
    let object_index = sys.at(587.56).object_index;
    assert_eq!(
        object_index,
        table["object_space_index"].as_f64().unwrap(),
        "{name}"
    );
    for key in ["n", "nF", "nC"] {
        let nm = table["index_wavelengths_nm"][key]
            .as_f64()
            .or_else(|| (key == "n").then(|| lens["wavelength_nm"].as_f64().unwrap()));
        let Some(nm) = nm else { continue };
        let at = sys.at(nm);
        for (s, o) in at.surfaces.iter().zip(surfaces) {
            let expected = o[key].as_f64().unwrap();
            assert!(
                (s.index_after - expected).abs() <= index_tolerance,
                "{name} surface {}: {key} at {nm} nm is {} vs oracle {expected}",
                o["surface"],
                s.index_after
            );
        }
    }
}

#[test]
fn dgauss_50mm_and_kolb_match_their_oracle_tables() {
    // Constant indices: equal to the last bit.
    assert_matches_oracle("dgauss-50mm", "pbrt_dgauss_50mm.json", 0.0);
    assert_matches_oracle("kolb-dgauss", "kolb_dgauss_1995_nobj1.json", 0.0);
}

#[test]
fn codev_dgauss_f2_matches_the_oracle_table() {
    assert_matches_oracle("codev-dgauss-f2", "codev_ag_dblgauss.json", 1e-9);
    let sys = system("codev-dgauss-f2");
    let (efl, _, bfl) = first_order(&sys.at(587.6));
    // CODE V prints EFL 100.0038 and BFL 61.4875.
    assert!((efl - 100.0038).abs() <= 5e-5, "EFL {efl}");
    assert!((bfl - 61.4875).abs() <= 5e-5, "BFL {bfl}");
}

#[test]
fn cooke_triplet_matches_the_oracle_table() {
    assert_matches_oracle("cooke-triplet", "optiland_cooke_triplet.json", 1e-9);
    // optiland's own focal length at its primary wavelength, 550 nm, as the oracle records it.
    let oracle = common::oracle_json("optiland_cooke_triplet.json");
    let native = oracle["lenses"][0]["source"]["native_settings"]["efl_native_primary_wvl"]
        .as_f64()
        .unwrap();
    let (efl, _, _) = first_order(&system("cooke-triplet").at(550.0));
    assert!(
        ((efl - native) / native).abs() < 1e-10,
        "EFL {efl} vs optiland {native}"
    );
    let p = bundled("cooke-triplet");
    assert!(
        matches!(p.surfaces[3].shape, Shape::Sphere { .. }),
        "the stop sits on a curved surface"
    );
}

/// n = 1.5, R = +-50, t = 10: power (n-1)(2/50) - (n-1)^2 t / (n 50^2) gives EFL 1500/29 and a
/// back focal distance 1400/29 (principal planes 100/29 = 3.448 mm inside each vertex).
#[test]
fn biconvex_singlet_is_the_analytic_lens() {
    let sys = system("biconvex-singlet");
    let p = &sys.prescription;
    assert_eq!(p.surfaces.len(), 2);
    assert_eq!(
        p.surfaces[0].shape,
        Shape::Sphere {
            curvature: 1.0 / 50.0
        }
    );
    assert_eq!(
        p.surfaces[1].shape,
        Shape::Sphere {
            curvature: -1.0 / 50.0
        }
    );
    assert_eq!(p.surfaces[0].thickness, 10.0);
    assert_eq!(p.surfaces[0].medium, Medium::Index(1.5));
    assert_eq!(p.surfaces[1].medium, Medium::Air);
    assert!(!sys.disperses());
    let (efl, _, bfl) = first_order(&sys.at(550.0));
    assert!((efl - 1500.0 / 29.0).abs() < 1e-12, "EFL {efl}");
    assert!((efl - 51.7241).abs() < 5e-5);
    assert!((bfl - 1400.0 / 29.0).abs() < 1e-12, "BFL {bfl}");
    assert!(
        (p.surfaces[1].thickness - bfl).abs() < 1e-12,
        "film at the paraxial focus"
    );
}

/// The Laikin designs against optiland 0.6.3, which ships them (Tessar in the book's inches,
/// Petzval scaled to mm): `TessarLens().paraxial.f2()` = 3.9977777470211935,
/// `PetzvalLens().paraxial.f2()` = 50.58453173454362, both at 587.5618 nm with the same SCHOTT
/// coefficients. Agreement to 1e-10 checks the transcription, the 25.4 scale and the glasses.
#[test]
fn laikin_designs_match_optiland() {
    for (name, optiland_efl) in [
        ("tessar", 3.9977777470211935 * 25.4),
        ("petzval", 50.58453173454362),
    ] {
        let (efl, _, _) = first_order(&system(name).at(587.5618));
        assert!(
            ((efl - optiland_efl) / optiland_efl).abs() < 1e-10,
            "{name}: EFL {efl} vs optiland {optiland_efl}"
        );
    }
}

#[test]
fn asphere_lens_carries_even_aspheres() {
    let p = bundled("asph-50mm-f1.8");
    let aspheres = p
        .surfaces
        .iter()
        .filter(|s| matches!(s.shape, Shape::EvenAsphere { .. }))
        .count();
    assert_eq!(aspheres, 2);
}
