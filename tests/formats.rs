//! Lens files in: every shared test lens, the oracle tables, each format's features, RON out.

mod common;

use common::{lens_file, oracle_table, relative, test_data};
use lensbake::glass::lookup;
use lensbake::lenses;
use lensbake::prescription::formats::{
    Format, LoadNote, LoadOptions, Loaded, PbrtThickness, read_bytes, read_file, read_str,
    write_ron, write_ron_file,
};
use lensbake::prescription::{
    Medium, Prescription, Problem, Provenance, Shape, StopShape, Surface,
};
use lensbake::system::LensSystem;
use serde_json::Value;
use std::path::Path;

/// Whether the reading notes only list skipped harmless keywords, solves read as written and
/// vignetting factors not applied (no derived apertures).
fn only_skipped_keywords(notes: &[LoadNote]) -> bool {
    notes.iter().all(|n| {
        matches!(
            n,
            LoadNote::SkippedKeywords { .. }
                | LoadNote::SolvesAsWritten { .. }
                | LoadNote::VignettingNotApplied { .. }
        )
    })
}

fn load(path: &Path, options: &LoadOptions) -> Loaded {
    read_file(path, options).unwrap_or_else(|e| panic!("{e}"))
}

fn from_previous() -> LoadOptions {
    LoadOptions {
        pbrt_thickness: PbrtThickness::FromPrevious,
        ..LoadOptions::default()
    }
}

/// Every f64 of a prescription as bits, in a fixed order, so comparisons are bit-exact.
fn float_bits(p: &Prescription) -> Vec<u64> {
    let mut v = Vec::new();
    let provenance = &p.provenance;
    for x in [
        provenance.design_wavelength_nm,
        provenance.claimed_focal_length_mm,
        provenance.claimed_f_number,
    ]
    .into_iter()
    .flatten()
    {
        v.push(x.to_bits());
    }
    let medium = |m: &Medium, v: &mut Vec<u64>| match m {
        Medium::Air | Medium::Glass(_) | Medium::Mirror => {}
        Medium::Index(n) => v.push(n.to_bits()),
        Medium::Sellmeier { b, c } => v.extend(b.iter().chain(c).map(|x| x.to_bits())),
        Medium::PowerSeries { a } => v.extend(a.iter().map(|x| x.to_bits())),
        Medium::Model { nd, vd } => v.extend([nd.to_bits(), vd.to_bits()]),
        Medium::Table {
            wavelengths_nm,
            indices,
        } => v.extend(wavelengths_nm.iter().chain(indices).map(|x| x.to_bits())),
    };
    medium(&p.object_medium, &mut v);
    for s in &p.surfaces {
        v.push(s.shape.curvature().to_bits());
        v.push(s.shape.conic().to_bits());
        v.extend(s.shape.aspheric_coefficients().iter().map(|x| x.to_bits()));
        v.extend([s.thickness.to_bits(), s.semi_aperture.to_bits()]);
        v.extend(s.obscuration.map(f64::to_bits));
        medium(&s.medium, &mut v);
        if let Some(StopShape::Blades {
            rotation_deg,
            blade_curvature,
            ..
        }) = &s.stop
        {
            v.extend([rotation_deg.to_bits(), blade_curvature.to_bits()]);
        }
    }
    v
}

fn assert_round_trip(p: &Prescription) {
    let text = write_ron(p);
    let back = read_str(&text, None, Format::Ron, &LoadOptions::default())
        .unwrap_or_else(|e| panic!("{e}\n{text}"))
        .prescription;
    assert_eq!(&back, p);
    assert_eq!(
        float_bits(&back),
        float_bits(p),
        "bits differ after a RON round trip"
    );
    assert_eq!(write_ron(&back), text, "RON output is not canonical");
}

/// Glass names compared the way the catalogue does: case, dashes and maker suffix ignored.
fn glass_key(name: &str) -> String {
    let upper = name.to_ascii_uppercase();
    let stem = upper.strip_suffix("_SCHOTT").unwrap_or(&upper);
    stem.chars().filter(char::is_ascii_alphanumeric).collect()
}

/// The oracle's table (radius, thickness, n, semi-aperture, stop) against a prescription whose
/// media are constant indices or air, exactly as the oracle builds it from the same file.
fn assert_matches_oracle_columns(p: &Prescription, table: &Value, scale: f64) {
    let rows = table["surfaces"].as_array().expect("surfaces");
    assert_eq!(p.surfaces.len(), rows.len());
    for (s, row) in p.surfaces.iter().zip(rows) {
        let k = row["surface"].as_u64().unwrap();
        match row["radius"].as_f64() {
            None => assert_eq!(s.shape, Shape::Plane, "surface {k}"),
            Some(r) => assert!(
                relative(s.shape.radius(), r * scale) < 1e-12,
                "surface {k} radius"
            ),
        }
        assert!(
            relative(s.thickness, row["thickness"].as_f64().unwrap() * scale) < 1e-12,
            "surface {k} thickness"
        );
        assert!(
            relative(
                s.semi_aperture,
                row["semi_aperture"].as_f64().unwrap() * scale
            ) < 1e-12,
            "surface {k} semi-aperture"
        );
        let n = row["n"].as_f64().unwrap();
        match &s.medium {
            Medium::Air => assert_eq!(n, 1.0, "surface {k}"),
            Medium::Index(index) => assert_eq!(*index, n, "surface {k}"),
            other => panic!("surface {k}: unexpected medium {other:?}"),
        }
        assert_eq!(
            s.stop.is_some(),
            row["stop"].as_bool().unwrap(),
            "surface {k} stop flag"
        );
    }
    assert_eq!(table["object_space_index"].as_f64(), Some(1.0));
    assert_eq!(p.object_medium, Medium::Air);
}

#[test]
fn every_shared_lens_file_parses_and_round_trips() {
    let dir = lens_file("");
    let mut seen = 0;
    for entry in std::fs::read_dir(&dir).expect("lens directory") {
        let path = entry.expect("entry").path();
        if path.extension().is_some_and(|e| e == "lis") {
            // A CODE V listing (program output), not a lens file: refused by extension.
            assert!(matches!(
                Format::from_path(&path),
                Err(Problem::UnknownFormat { .. })
            ));
            continue;
        }
        seen += 1;
        let name = path.file_name().unwrap().to_string_lossy().into_owned();
        let options = if name == "dgauss.dat" {
            from_previous()
        } else {
            LoadOptions::default()
        };
        match read_file(&path, &options) {
            Ok(loaded) => {
                assert!(!loaded.prescription.surfaces.is_empty(), "{name}");
                assert_round_trip(&loaded.prescription);
                if loaded
                    .prescription
                    .surfaces
                    .iter()
                    .all(|s| !matches!(s.medium, Medium::Glass(_)))
                {
                    LensSystem::new(loaded.prescription, &loaded.map)
                        .unwrap_or_else(|e| panic!("{e}"));
                }
            }
            // The CODE V file needs its glasses' indices to derive clear apertures; the only
            // acceptable failure is a glass the catalogue does not hold (yet).
            Err(e) => match &e.problem {
                Problem::UnknownGlass { name: glass, .. } if lookup(glass).is_err() => {
                    assert_eq!(Format::from_path(&path).unwrap(), Format::CodeV, "{e}")
                }
                _ => panic!("{e}"),
            },
        }
    }
    assert_eq!(
        seen, 5,
        "expected the five lens files of tests/data/truth/lenses"
    );
}

#[test]
fn dgauss_from_previous_equals_dgauss_50mm_to_next_at_twice_the_scale() {
    let unscaled = load(&lens_file("dgauss.dat"), &from_previous()).prescription;
    let scaled = load(&lens_file("dgauss.50mm.dat"), &LoadOptions::default()).prescription;
    assert_eq!(unscaled.surfaces.len(), 11);
    assert_eq!(scaled.surfaces.len(), 11);
    for (i, (a, b)) in unscaled.surfaces.iter().zip(&scaled.surfaces).enumerate() {
        let k = i + 1;
        assert!(
            relative(2.0 * a.shape.curvature(), b.shape.curvature()) < 1e-12,
            "surface {k} curvature"
        );
        assert!(
            relative(a.thickness, 2.0 * b.thickness) < 1e-12,
            "surface {k} thickness"
        );
        assert!(
            relative(a.semi_aperture, 2.0 * b.semi_aperture) < 1e-12,
            "surface {k} semi-aperture"
        );
        assert_eq!(a.medium, b.medium, "surface {k} medium");
        assert_eq!(a.stop, b.stop, "surface {k} stop");
    }
    assert_eq!(unscaled.stop_index(), Some(5));
    // Reading the unscaled file the pbrt way is possible, but says why it looks wrong, and the
    // lens then fails validation: surfaces 1 and 2 share a vertex.
    let wrong = load(&lens_file("dgauss.dat"), &LoadOptions::default());
    assert_eq!(wrong.notes, vec![LoadNote::PbrtFirstThicknessZero]);
    let error = LensSystem::new(wrong.prescription, &wrong.map).unwrap_err();
    assert!(
        matches!(error.problem, Problem::SurfacesCross { next: 2, .. }),
        "{error}"
    );
    assert_eq!(
        (error.location.line, error.location.surface),
        (Some(5), Some(1))
    );
}

#[test]
fn pbrt_dgauss_50mm_matches_the_oracle_table() {
    let loaded = load(&lens_file("dgauss.50mm.dat"), &LoadOptions::default());
    assert_eq!(loaded.format, Format::Pbrt);
    assert!(only_skipped_keywords(&loaded.notes), "{:?}", loaded.notes);
    assert_matches_oracle_columns(
        &loaded.prescription,
        &oracle_table("pbrt_dgauss_50mm.json"),
        1.0,
    );
    assert_eq!(
        loaded.prescription.provenance.title,
        "D-GAUSS F/2 22deg HFOV"
    );
    // Data rows start after the five comment lines.
    let lines: Vec<_> = loaded
        .map
        .surface_lines
        .iter()
        .map(|l| l.unwrap())
        .collect();
    assert_eq!(lines, (6..=16).collect::<Vec<_>>());
}

#[test]
fn both_kolb_tables_match_the_oracle_table() {
    let table = oracle_table("kolb_dgauss_1995_nobj1.json");
    let na_stop = load(&lens_file("kolb_dgauss_1995.dat"), &LoadOptions::default()).prescription;
    let zero_stop = load(
        &lens_file("kolb_dgauss_1995_nobj1.dat"),
        &LoadOptions::default(),
    )
    .prescription;
    assert_matches_oracle_columns(&na_stop, &table, 1.0);
    assert_matches_oracle_columns(&zero_stop, &table, 1.0);
    // The stop row's index 0 means the medium of the gap the stop sits in (here n = 1.00027715).
    assert_eq!(zero_stop.surfaces[5].medium, Medium::Index(1.00027715));
    assert_eq!(na_stop.surfaces, zero_stop.surfaces);
    // The N/A table is also a valid plain table, and reads the same that way.
    let as_table = read_file(
        &lens_file("kolb_dgauss_1995.dat"),
        &LoadOptions {
            format: Some(Format::Table),
            ..LoadOptions::default()
        },
    )
    .unwrap();
    assert_eq!(as_table.format, Format::Table);
    assert_eq!(as_table.prescription.surfaces, na_stop.surfaces);
}

#[test]
fn plain_table_features() {
    let text = "# Test singlet\nradius, thickness, index, diameter\n50, 5, 1.5168, 20\nSTO 2 1 10\n0 40 1 18\n";
    let loaded = read_str(text, None, Format::Table, &LoadOptions::default()).unwrap();
    let s = &loaded.prescription.surfaces;
    assert_eq!(s.len(), 3);
    assert_eq!(
        s[0].shape,
        Shape::Sphere {
            curvature: 1.0 / 50.0
        }
    );
    assert_eq!(s[0].medium, Medium::Index(1.5168));
    assert_eq!(s[0].semi_aperture, 10.0);
    assert_eq!(s[1].stop, Some(StopShape::Circle));
    assert_eq!(s[1].medium, Medium::Air);
    // In a plain table radius 0 is a plane surface, not a stop.
    assert_eq!(
        (s[2].shape.clone(), s[2].stop.clone()),
        (Shape::Plane, None)
    );
    assert_eq!(loaded.map.surface_lines, vec![Some(3), Some(4), Some(5)]);
    assert_eq!(loaded.prescription.provenance.title, "Test singlet");
    LensSystem::new(loaded.prescription, &loaded.map).unwrap();
}

/// The CODE V sample with its glass names replaced by fictitious glass codes carrying the
/// oracle's indices at 587.6 nm (a test-only stand-in for catalogue glasses), line numbers kept.
fn ag_dblgauss_with_oracle_indices() -> String {
    let table = oracle_table("codev_ag_dblgauss.json");
    let mut text = std::fs::read_to_string(lens_file("ag_dblgauss.seq")).unwrap();
    for row in table["surfaces"].as_array().unwrap() {
        let note = row["note"].as_str().unwrap();
        if note == "air" {
            continue;
        }
        let code = format!(
            "{}.0",
            row["n"]
                .as_f64()
                .unwrap()
                .to_string()
                .trim_start_matches("1.")
        );
        let name = format!("{}_SCHOTT", note.replace('-', ""));
        text = text.replace(&format!(" {name}\r"), &format!(" {code}\r"));
    }
    text
}

#[test]
fn ag_dblgauss_seq_matches_the_oracle_table() {
    let table = oracle_table("codev_ag_dblgauss.json");
    let rows = table["surfaces"].as_array().unwrap();
    // Give every surface the oracle's clear aperture, so no glass index is needed to read it.
    let original = std::fs::read_to_string(lens_file("ag_dblgauss.seq")).unwrap();
    let mut text = String::new();
    let mut surface = 0;
    for line in original.lines() {
        text.push_str(line);
        text.push('\n');
        if line.starts_with("S ") {
            text.push_str(&format!("  CIR {}\n", rows[surface]["semi_aperture"]));
            surface += 1;
        }
    }
    let loaded = read_str(&text, None, Format::CodeV, &LoadOptions::default()).unwrap();
    let p = &loaded.prescription;
    assert!(only_skipped_keywords(&loaded.notes), "{:?}", loaded.notes);
    assert_eq!(p.provenance.title, "Double Gauss F/2 -  Available Glasses");
    assert_eq!(p.provenance.design_wavelength_nm, Some(587.6));
    assert_eq!(p.surfaces.len(), 11);
    assert_eq!(p.stop_index(), Some(5), "stop on surface 6");
    for (s, row) in p.surfaces.iter().zip(rows) {
        let k = row["surface"].as_u64().unwrap();
        // serde_json's default float parsing may be one ulp off the correctly rounded value.
        assert!(
            relative(s.shape.curvature(), row["curvature"].as_f64().unwrap()) < 1e-15,
            "surface {k} curvature"
        );
        assert_eq!(
            s.thickness,
            row["thickness"].as_f64().unwrap(),
            "surface {k} thickness"
        );
        assert_eq!(
            s.semi_aperture,
            row["semi_aperture"].as_f64().unwrap(),
            "surface {k}"
        );
        let note = row["note"].as_str().unwrap();
        match &s.medium {
            Medium::Air => assert_eq!(note, "air", "surface {k}"),
            Medium::Glass(name) => assert_eq!(glass_key(name), glass_key(note), "surface {k}"),
            other => panic!("surface {k}: {other:?}"),
        }
    }
}

#[test]
fn ag_dblgauss_seq_derives_paraxial_clear_apertures() {
    let loaded = read_str(
        &ag_dblgauss_with_oracle_indices(),
        None,
        Format::CodeV,
        &LoadOptions::default(),
    )
    .unwrap();
    let p = &loaded.prescription;
    let lines: Vec<_> = loaded
        .map
        .surface_lines
        .iter()
        .map(|l| l.unwrap())
        .collect();
    assert_eq!(lines, [15, 17, 19, 21, 22, 24, 27, 29, 30, 32, 34]);
    assert_eq!(
        loaded.notes[..1],
        vec![LoadNote::AperturesDerived {
            surfaces: (1..=11).collect(),
            limited_at_edge: Vec::new(),
        }]
    );

    // Expected: the paraxial marginal and 14-degree chief rays of the oracle (rayoptics),
    // combined at the .seq's fields (0, 10, 14 deg) and vignetting factors (VUY, VLY).
    let rays = &lensbake_oracle_paraxial();
    let fields = [(0.0f64, 0.0, 0.0), (10.0, 0.2, 0.25), (14.0, 0.4, 0.4)];
    let table = oracle_table("codev_ag_dblgauss.json");
    let mut worst_vs_real: f64 = 0.0;
    for (i, s) in p.surfaces.iter().enumerate() {
        let (y, chief14) = (rays.0[i], rays.1[i]);
        let mut expected = y.abs();
        for (angle, vuy, vly) in fields {
            let ybar = chief14 * angle.to_radians().tan() / 14f64.to_radians().tan();
            expected = expected
                .max(y.hypot(ybar))
                .max((ybar + (1.0 - vuy) * y).abs())
                .max((ybar - (1.0 - vly) * y).abs());
        }
        // rayoptics puts the object at 1e10 mm, the .seq at 9.9e11: heights differ by ~1e-8.
        assert!(
            relative(s.semi_aperture, expected) < 1e-6,
            "surface {}: {} vs {expected}",
            i + 1,
            s.semi_aperture
        );
        let real = table["surfaces"][i]["semi_aperture"].as_f64().unwrap();
        worst_vs_real = worst_vs_real.max(relative(s.semi_aperture, real));
    }
    // The oracle's apertures are real-ray ones (rayoptics, rounded up to 0.01 mm); paraxial
    // heights are within about 10% of them for this F/2, 14-degree lens (surface 4: -10.1%).
    assert!(
        worst_vs_real > 0.05 && worst_vs_real < 0.11,
        "worst deviation {worst_vs_real}"
    );
    let system = LensSystem::new(loaded.prescription.clone(), &loaded.map).unwrap();
    let at = system.at(587.6);
    for (s, row) in at
        .surfaces
        .iter()
        .zip(table["surfaces"].as_array().unwrap())
    {
        assert!((s.index_after - row["n"].as_f64().unwrap()).abs() < 1e-15);
    }
}

/// Marginal heights and 14-degree chief heights at surfaces 1..11 from the oracle (rayoptics).
fn lensbake_oracle_paraxial() -> (Vec<f64>, Vec<f64>) {
    let lens = &common::oracle_json("codev_ag_dblgauss.json")["lenses"][0];
    let rays = &lens["infinite_conjugate"]["paraxial_rays"]["rayoptics"];
    let heights = |name: &str| -> Vec<f64> {
        rays[name].as_array().unwrap()[1..=11]
            .iter()
            .map(|r| r[0].as_f64().unwrap())
            .collect()
    };
    assert_eq!(lens["system"]["max_field_angle_deg"].as_f64(), Some(14.0));
    (heights("marginal"), heights("chief"))
}

#[test]
fn ag_dblgauss_seq_with_the_catalogue() {
    let path = lens_file("ag_dblgauss.seq");
    let names = ["NSSK2_SCHOTT", "NSK2_SCHOTT", "F5_SCHOTT", "NSK16_SCHOTT"];
    if names.iter().all(|n| lookup(n).is_ok()) {
        let lens = lenses::load(path.to_str().unwrap(), &LoadOptions::default()).unwrap();
        let table = oracle_table("codev_ag_dblgauss.json");
        let at = lens.system.at(587.6);
        for (s, row) in at
            .surfaces
            .iter()
            .zip(table["surfaces"].as_array().unwrap())
        {
            // Datasheet Sellmeier against CODE V's catalogue: agreement to the 6th decimal.
            assert!((s.index_after - row["n"].as_f64().unwrap()).abs() < 1e-5);
        }
    } else {
        // Until the catalogue holds these glasses, the reader names the first one it lacks,
        // at its surface's line.
        let error = read_file(&path, &LoadOptions::default()).unwrap_err();
        let Problem::UnknownGlass { name, .. } = &error.problem else {
            panic!("{error}")
        };
        assert!(names.contains(&name.as_str()), "{error}");
        let glass_lines = [15, 19, 21, 27, 29, 32];
        assert!(
            glass_lines.contains(&error.location.line.unwrap()),
            "{error}"
        );
        assert_eq!(error.location.field.as_deref(), Some("glass"));
    }
}

#[test]
fn zemax_cooke_triplet_matches_the_oracle_table() {
    let loaded = load(&test_data("cooke_triplet.zmx"), &LoadOptions::default());
    let p = &loaded.prescription;
    assert_eq!(loaded.format, Format::Zemax);
    assert!(only_skipped_keywords(&loaded.notes), "{:?}", loaded.notes);
    assert!(relative(p.provenance.design_wavelength_nm.unwrap(), 550.0) < 1e-12);
    let table = oracle_table("optiland_cooke_triplet.json");
    let rows = table["surfaces"].as_array().unwrap();
    assert_eq!(p.surfaces.len(), rows.len());
    assert_eq!(p.stop_index(), Some(3), "stop on the curved surface 4");
    for (s, row) in p.surfaces.iter().zip(rows) {
        let k = row["surface"].as_u64().unwrap();
        // One ulp of slack: serde_json's default float parsing is not always correctly rounded.
        assert!(
            relative(s.shape.curvature(), row["curvature"].as_f64().unwrap()) < 1e-15,
            "surface {k}"
        );
        assert!(matches!(s.shape, Shape::Sphere { .. }), "surface {k}");
        assert_eq!(
            s.thickness,
            row["thickness"].as_f64().unwrap(),
            "surface {k}"
        );
        assert_eq!(
            s.semi_aperture,
            row["semi_aperture"].as_f64().unwrap(),
            "surface {k}"
        );
        match (&s.medium, row["note"].as_str()) {
            (Medium::Air, None) => {}
            // GCAT SCHOTT HIKARI: F2 is SCHOTT's (HOYA sells one too), SK16 HIKARI's.
            (Medium::Glass(name), Some(note)) => {
                let glass = lookup(name).unwrap();
                let maker = if note == "SK16" { "HIKARI" } else { "SCHOTT" };
                assert_eq!((glass.name, glass.maker), (note, maker), "surface {k}");
            }
            (medium, note) => panic!("surface {k}: {medium:?} vs {note:?}"),
        }
    }
    // SURF 1 is on line 35, and every SURF block follows.
    assert_eq!(loaded.map.surface_lines[0], Some(35));
}

#[test]
fn zemax_units_even_aspheres_and_model_glass() {
    let text = "MODE SEQ\nUNIT CM\nENPD 1\nSURF 0\n  DISZ INFINITY\nSURF 1\n  STOP\n  TYPE EVENASPH\n  CURV 0.1\n  CONI -1\n  PARM 1 0\n  PARM 2 0.001\n  PARM 3 -2e-5\n  DISZ 0.5\n  GLAS ___BLANK 1 0 1.5 50 0 0 0\n  DIAM 2\nSURF 2\n  CURV -0.05\n  DISZ 4\n  DIAM 2\nSURF 3\n  DISZ 0\n";
    let loaded = read_str(text, None, Format::Zemax, &LoadOptions::default()).unwrap();
    let s = &loaded.prescription.surfaces;
    let Shape::EvenAsphere {
        curvature,
        conic,
        coefficients,
    } = &s[0].shape
    else {
        panic!("{:?}", s[0].shape)
    };
    // 1 cm = 10 mm: curvature /10, thickness and apertures x10, an r^(2j) term x10^(1-2j).
    assert!(relative(*curvature, 0.01) < 1e-15);
    assert_eq!(*conic, -1.0);
    assert_eq!(coefficients.len(), 3);
    assert_eq!(coefficients[0], 0.0);
    assert!(relative(coefficients[1], 0.001 * 1e-3) < 1e-15);
    assert!(relative(coefficients[2], -2e-5 * 1e-5) < 1e-15);
    assert_eq!((s[0].thickness, s[0].semi_aperture), (5.0, 20.0));
    assert_eq!(s[0].medium, Medium::Model { nd: 1.5, vd: 50.0 });
    assert_eq!(s[1].shape, Shape::Sphere { curvature: -0.005 });
    assert_eq!(s[1].medium, Medium::Air);
    assert_eq!(s[1].thickness, 40.0);
    LensSystem::new(loaded.prescription, &loaded.map).unwrap();
}

#[test]
fn derived_apertures_of_a_singlet_follow_the_paraxial_rays() {
    // Plano-convex singlet, stop on its front surface, EPD 10, field 10 deg, no vignetting.
    // Marginal: y1 = 5, u' = -y1 c (n - 1) / n, y2 = y1 + t u'. Chief through the stop centre:
    // y1 = 0, u' = tan(10)/n, y2 = t u'. Surface 2 needs |y2| + |ybar2|.
    let (c, n, t) = (0.02, 1.5, 4.0);
    let text = format!(
        "MODE SEQ\nENPD 10\nFTYP 0 0 2 1\nYFLN 0 10\nSURF 0\n  DISZ INFINITY\nSURF 1\n  STOP\n  CURV {c}\n  DISZ {t}\n  GLAS ___BLANK 1 0 {n} 0\nSURF 2\n  DISZ 90\nSURF 3\n"
    );
    let loaded = read_str(&text, None, Format::Zemax, &LoadOptions::default()).unwrap();
    let s = &loaded.prescription.surfaces;
    let y2 = 5.0 + t * (-5.0 * c * (n - 1.0) / n);
    let ybar2 = t * 10f64.to_radians().tan() / n;
    assert!(relative(s[0].semi_aperture, 5.0) < 1e-15);
    assert!(relative(s[1].semi_aperture, y2 + ybar2) < 1e-14);
    assert_eq!(
        loaded.notes,
        vec![LoadNote::AperturesDerived {
            surfaces: vec![1, 2],
            limited_at_edge: Vec::new(),
        }]
    );
}

#[test]
fn codev_radius_mode_units_conics_aspheres_and_clear_apertures() {
    let text = "! a comment line\nTITLE 'Test; asphere'\nDIM C\nEPD 1.0\nWL 550\nSO 0 1e20\nS 5.0 0.4 N-BK7 ! radius mode by default\n  ASP; K -0.5; A 1e-3; B -2e-5\n  CIR 1.2\n  STO\nS -10.0 3.0\n  CIR 1.1\nSI 0 0\nGO\nS 1 1 ! after GO: ignored\n";
    let loaded = read_str(text, None, Format::CodeV, &LoadOptions::default()).unwrap();
    let p = &loaded.prescription;
    assert_eq!(p.provenance.title, "Test; asphere");
    assert_eq!(p.provenance.design_wavelength_nm, Some(550.0));
    assert_eq!(p.surfaces.len(), 2);
    let Shape::EvenAsphere {
        curvature,
        conic,
        coefficients,
    } = &p.surfaces[0].shape
    else {
        panic!("{:?}", p.surfaces[0].shape)
    };
    assert!(relative(*curvature, 1.0 / 50.0) < 1e-15);
    assert_eq!(*conic, -0.5);
    assert_eq!(coefficients.len(), 3);
    assert!(
        relative(coefficients[1], 1e-3 * 1e-3) < 1e-15,
        "A is the r^4 term, scaled cm -> mm"
    );
    assert!(
        relative(coefficients[2], -2e-5 * 1e-5) < 1e-15,
        "B is the r^6 term"
    );
    assert_eq!(p.surfaces[0].medium, Medium::Glass("N-BK7".into()));
    assert_eq!(
        (p.surfaces[0].thickness, p.surfaces[0].semi_aperture),
        (4.0, 12.0)
    );
    assert_eq!(p.surfaces[1].shape, Shape::Sphere { curvature: -0.01 });
    assert_eq!(p.surfaces[0].stop, Some(StopShape::Circle));
    assert!(only_skipped_keywords(&loaded.notes), "{:?}", loaded.notes);
    LensSystem::new(loaded.prescription, &loaded.map).unwrap();
}

#[test]
fn codev_fictitious_glass_codes_are_model_glasses() {
    let text = "RDM N\nEPD 10\nS 0.02 5 517000.6420\nSTO\nS -0.02 50 620000.0\nS 0 10\n";
    let p = read_str(text, None, Format::CodeV, &LoadOptions::default())
        .unwrap()
        .prescription;
    assert_eq!(
        p.surfaces[0].medium,
        Medium::Model {
            nd: 1.517,
            vd: 64.2
        }
    );
    assert_eq!(p.surfaces[1].medium, Medium::Index(1.62));
}

#[test]
fn ron_round_trip_is_bit_exact_for_awkward_numbers() {
    let awkward = [
        0.1 + 0.2,
        1.0 / 3.0,
        -0.0,
        f64::MIN_POSITIVE,
        5e-324,
        1e300,
        -123456.78901234567,
    ];
    let p = Prescription {
        provenance: Provenance {
            title: "awkward \"quoted\" title, with unicode: f/1.4 µm ±".into(),
            source: Some("test".into()),
            design_wavelength_nm: Some(587.5618),
            claimed_focal_length_mm: Some(1.0 / 7.0),
            claimed_f_number: None,
            claimed_half_field_deg: Some(21.5),
            notes: Some("line one\nline two".into()),
            conditions: None,
        },
        object_medium: Medium::Sellmeier {
            b: [awkward[0], awkward[1], awkward[3]],
            c: [awkward[4], 2.0, 3.0],
        },
        surfaces: awkward
            .iter()
            .enumerate()
            .map(|(i, &x)| Surface {
                shape: match i % 4 {
                    0 => Shape::Plane,
                    1 => Shape::Sphere { curvature: x },
                    2 => Shape::Conic {
                        curvature: x,
                        conic: -x,
                    },
                    _ => Shape::EvenAsphere {
                        curvature: x,
                        conic: x,
                        coefficients: awkward.to_vec(),
                    },
                },
                thickness: x,
                medium: match i % 3 {
                    0 => Medium::Index(x),
                    1 => Medium::Model { nd: x, vd: -x },
                    _ => Medium::Glass(format!("G{i}")),
                },
                semi_aperture: x,
                stop: (i == 2).then_some(StopShape::Blades {
                    count: 7,
                    rotation_deg: x,
                    blade_curvature: 0.25,
                }),
                obscuration: None,
            })
            .collect(),
    };
    assert_round_trip(&p);
}

#[test]
fn ron_errors_and_validation_cite_lines() {
    let good = load(&lens_file("dgauss.50mm.dat"), &LoadOptions::default()).prescription;
    let text = write_ron(&good);
    let reread = read_str(&text, None, Format::Ron, &LoadOptions::default()).unwrap();
    // Each surface's entry starts on the line its `(` opens.
    let lines: Vec<&str> = text.lines().collect();
    for (i, line) in reread.map.surface_lines.iter().enumerate() {
        let line = line.unwrap();
        assert_eq!(lines[line - 1].trim(), "(", "surface {}", i + 1);
        assert!(
            lines[line].trim().starts_with("shape:"),
            "surface {}",
            i + 1
        );
    }
    // A semi-aperture larger than the radius on surface 3: validation names its RON line.
    let mut bad = good.clone();
    bad.surfaces[2].semi_aperture = 30.0;
    let bad_text = write_ron(&bad);
    let loaded = read_str(
        &bad_text,
        Some(Path::new("bad.ron")),
        Format::Ron,
        &LoadOptions::default(),
    )
    .unwrap();
    let error = LensSystem::new(loaded.prescription, &loaded.map).unwrap_err();
    assert!(
        matches!(error.problem, Problem::ApertureExceedsRadius { .. }),
        "{error}"
    );
    assert_eq!(error.location.surface, Some(3));
    assert_eq!(error.location.line, loaded.map.surface_lines[2]);
    // An unknown field is refused, at its line, inside the right surface.
    let fourth = text.match_indices("semi_aperture").nth(3).unwrap().0;
    let typo = format!(
        "{}semi_apertur{}",
        &text[..fourth],
        &text[fourth + "semi_aperture".len()..]
    );
    let error = read_str(&typo, None, Format::Ron, &LoadOptions::default()).unwrap_err();
    assert!(matches!(error.problem, Problem::Syntax(_)), "{error}");
    let typo_line = typo
        .lines()
        .enumerate()
        .find(|(_, l)| l.contains("semi_apertur:"))
        .unwrap()
        .0
        + 1;
    assert_eq!(error.location.line, Some(typo_line), "{error}");
    assert_eq!(error.location.surface, Some(4), "{error}");
}

#[test]
fn write_ron_file_is_atomic_and_replaces() {
    let dir = std::env::temp_dir().join(format!("lensbake-write-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("lens.ron");
    let p = load(&lens_file("kolb_dgauss_1995.dat"), &LoadOptions::default()).prescription;
    std::fs::write(&path, "old contents").unwrap();
    write_ron_file(&path, &p).unwrap();
    assert_eq!(load(&path, &LoadOptions::default()).prescription, p);
    let names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(
        names,
        vec![std::ffi::OsString::from("lens.ron")],
        "no temporary file left behind"
    );
    let missing = dir.join("no-such-dir/lens.ron");
    let error = write_ron_file(&missing, &p).unwrap_err();
    assert!(matches!(error.problem, Problem::Write(_)));
    assert!(error.to_string().contains("cannot write file"), "{error}");
    assert_eq!(error.location.file.as_deref(), Some(missing.as_path()));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn format_from_extension_and_names() {
    for (name, format) in [
        ("a.ron", Format::Ron),
        ("a.DAT", Format::Pbrt),
        ("a.txt", Format::Table),
        ("a.tsv", Format::Table),
        ("a.csv", Format::Table),
        ("a.seq", Format::CodeV),
        ("a.zmx", Format::Zemax),
    ] {
        assert_eq!(Format::from_path(Path::new(name)), Ok(format), "{name}");
    }
    assert_eq!(
        Format::from_path(Path::new("lens")),
        Err(Problem::UnknownFormat { extension: None })
    );
    for format in Format::ALL {
        assert_eq!(format.name().parse::<Format>(), Ok(format));
    }
    assert_eq!("zmx".parse::<Format>(), Ok(Format::Zemax));
    assert!("pdf".parse::<Format>().is_err());
}

#[test]
fn utf16_zemax_files_are_read() {
    let text = std::fs::read_to_string(test_data("cooke_triplet.zmx")).unwrap();
    let mut bytes = vec![0xFF, 0xFE];
    bytes.extend(text.encode_utf16().flat_map(u16::to_le_bytes));
    let utf16 = read_bytes(&bytes, None, Format::Zemax, &LoadOptions::default()).unwrap();
    let utf8 = read_str(&text, None, Format::Zemax, &LoadOptions::default()).unwrap();
    assert_eq!(utf16.prescription, utf8.prescription);
}

#[test]
fn lens_names_and_paths() {
    let path = lens_file("dgauss.50mm.dat");
    let lens = lenses::load(path.to_str().unwrap(), &LoadOptions::default()).unwrap();
    assert_eq!(lens.source.origin, lenses::LensOrigin::File(path.clone()));
    assert_eq!(lens.system.stop, 5);
    let error = lenses::read("no-such-lens", &LoadOptions::default()).unwrap_err();
    let lenses::LensError::NotFound { bundled, .. } = &error else {
        panic!("{error}")
    };
    assert_eq!(bundled.len(), lenses::BUNDLED.len());
    assert!(error.to_string().contains("no-such-lens"));
    for bundled in lenses::BUNDLED {
        assert_eq!(
            lenses::find(bundled.name).map(|l| l.name),
            Some(bundled.name)
        );
        let lens =
            lenses::load(bundled.name, &LoadOptions::default()).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(
            lens.source.origin,
            lenses::LensOrigin::Bundled(bundled.name)
        );
        assert_round_trip(&lens.system.prescription);
    }
    assert!(lenses::find("no-such-lens").is_none());
}

/// Vignetting factors that trim a field's pupil are named in a note (the analyses trace the whole
/// pupil): CODE V's VUY/VLY and Zemax's VDYN/VCYN on fields 2 and 3 of two double Gauss files.
/// Factors that are all zero (CODE V 65564's VUY 0.0, VLY 0.0) trim nothing and get no note.
#[test]
fn unapplied_vignetting_factors_are_named() {
    let vignetting_note = |path: &Path| {
        load(path, &LoadOptions::default())
            .notes
            .into_iter()
            .find(|n| matches!(n, LoadNote::VignettingNotApplied { .. }))
    };
    let trimmed = LoadNote::VignettingNotApplied { fields: vec![2, 3] };
    let corpus = test_data("corpus");
    assert_eq!(
        vignetting_note(&lens_file("ag_dblgauss.seq")).as_ref(),
        Some(&trimmed)
    );
    assert_eq!(
        vignetting_note(&corpus.join("rayoptics__US00583336-2-scaled.zmx")).as_ref(),
        Some(&trimmed)
    );
    assert_eq!(
        vignetting_note(&corpus.join("rayoptics__CODV_65564.seq")),
        None
    );
    let note = trimmed.to_string();
    assert!(
        note.starts_with("the vignetting factors of fields 2-3 are not applied"),
        "{note}"
    );
}
