//! The Zemax and CODE V readers on the constructs real files use: harmless keywords skipped and
//! listed once, located refusals, text encodings, GCAT, DIAM semantics, the file's conditions as
//! analysis defaults, gap tolerance, CODE V continuation lines, model glasses and the default stop.

use lensbake::analysis::{AnalyzeOptions, analyze};
use lensbake::glass::{D_LINE_NM, Dispersion, lookup};
use lensbake::prescription::formats::{
    Format, LoadNote, LoadOptions, Loaded, read_bytes, read_str,
};
use lensbake::prescription::{
    ApertureSpec, FieldKind, Medium, PrescriptionError, Problem, StopShape,
};
use lensbake::system::LensSystem;
use lensbake::trace::{Outcome, Ray, Tracer, Travel};
use std::path::Path;

const FILE: &str = "test.zmx";

/// An f/5 BK7 singlet (R = ±50 mm, 5 mm thick) as OpticStudio writes it, with the bookkeeping,
/// merit-function and tolerance lines real files carry.
fn singlet(extra_header: &str, surface_2: &str, trailer: &str) -> String {
    format!(
        "VERS 190513 80 123456\nMODE SEQ\nNAME Test singlet\nAUTH Someone\nLUID 42\n\
         UNIT MM X W X CM MR CPMM\nENPD 10\nGCAT SCHOTT\n{extra_header}\
         FTYP 0 0 2 3 0 0 0\nXFLN 0 0 0 0\nYFLN 0 5 0 0\nFWGN 1 2 1 1\n\
         WAVM 1 0.4861327 1\nWAVM 2 0.5875618 2\nWAVM 3 0.6562725 1\nWAVM 4 0.55 1\nPWAV 2\n\
         SURF 0\n  TYPE STANDARD\n  CURV 0.0 0 0 0 0 \"\"\n  DISZ INFINITY\n\
         SURF 1\n  STOP\n  TYPE STANDARD\n  CURV 0.02 0 0 0 0 \"\"\n  HIDE 0 0 0 0 0 0 0 0 0 0\n\
           DISZ 5\n  GLAS N-BK7 0 0 1.5168 64.17 0 0 0 0 0 0\n  DIAM 6 1 0 0 1 \"\"\n\
         SURF 2\n  TYPE STANDARD\n  CURV -0.02 0 0 0 0 \"\"\n  DISZ 47\n{surface_2}\
         SURF 3\n  TYPE STANDARD\n  CURV 0\n  DISZ 0\n\
         TOL TOFF 0 0 0 0 0 0\nMNUM 1 1\nEERA 0 0 0\n{trailer}"
    )
}

fn read(text: &str) -> Result<Loaded, PrescriptionError> {
    read_str(
        text,
        Some(Path::new(FILE)),
        Format::Zemax,
        &LoadOptions::default(),
    )
}

fn skipped(loaded: &Loaded) -> Vec<String> {
    let lists: Vec<&Vec<String>> = loaded
        .notes
        .iter()
        .filter_map(|n| match n {
            LoadNote::SkippedKeywords { keywords } => Some(keywords),
            _ => None,
        })
        .collect();
    assert!(lists.len() <= 1, "one note lists every skipped keyword");
    lists.first().map_or_else(Vec::new, |l| l.to_vec())
}

fn line_of(text: &str, needle: &str) -> usize {
    1 + text.lines().position(|l| l.contains(needle)).expect(needle)
}

#[test]
fn harmless_keywords_are_skipped_and_listed_in_one_note() {
    let text = singlet("", "  DIAM 6 0 0 0 1 \"\"\n", "REAY 1 2 0.5\nZQXW 1 2 3\n");
    let loaded = read(&text).unwrap();
    let keywords = skipped(&loaded);
    // Bookkeeping, display, tolerance and merit lines, and an operand lensbake has never seen
    // in the trailer (after the surface table) where only such lines live.
    for k in [
        "AUTH", "EERA", "HIDE", "LUID", "REAY", "TOL", "VERS", "ZQXW",
    ] {
        assert!(keywords.iter().any(|s| s == k), "{k} in {keywords:?}");
    }
    assert!(
        keywords.windows(2).all(|w| w[0] < w[1]),
        "sorted, once each"
    );
    let note = loaded
        .notes
        .iter()
        .find(|n| matches!(n, LoadNote::SkippedKeywords { .. }))
        .unwrap()
        .to_string();
    assert!(
        note.contains("AUTH, DIAM") || note.contains("AUTH, EERA"),
        "{note}"
    );
}

/// A multi-configuration file (here a zoom of the back focus: three thicknesses of surface 2)
/// is read as its active configuration, whose values OpticStudio keeps in the surface table, and
/// says so; the configuration records after the table are not applied.
#[test]
fn a_multi_configuration_file_is_read_as_its_active_configuration() {
    let records = "MNUM 3 2\n\
                   THIC 2 1 40 0 0 0 1 1 1 0 0 \"\" 0\n\
                   THIC 2 2 47 0 0 0 1 1 1 0 0 \"\" 0\n\
                   THIC 2 3 60 0 0 0 1 1 1 0 0 \"\" 0\n";
    let text = singlet("", "  DIAM 6 0 0 0 1 \"\"\n", "").replace("MNUM 1 1\n", records);
    let loaded = read(&text).unwrap();
    let single = read(&singlet("", "  DIAM 6 0 0 0 1 \"\"\n", "")).unwrap();
    assert_eq!(loaded.prescription.surfaces, single.prescription.surfaces);
    let note = LoadNote::ActiveConfiguration {
        active: 2,
        count: 3,
    };
    assert!(loaded.notes.contains(&note), "{:?}", loaded.notes);
    assert!(note.to_string().contains("configuration 2 of 3"), "{note}");
    assert!(
        !single
            .notes
            .iter()
            .any(|n| matches!(n, LoadNote::ActiveConfiguration { .. }))
    );
}

/// Header settings of a newer OpticStudio (before the surface table) are skipped and named in
/// their own note; the lens is the one the surfaces give. The same keyword inside a surface is
/// refused (below).
#[test]
fn unknown_header_keywords_are_skipped_and_named_apart() {
    let plain = read(&singlet("", "  DIAM 6 0 0 0 1 \"\"\n", "")).unwrap();
    let text = singlet(
        "STUD 1\nFSVY 3 2 2 0 0.71 0 \"\"\n",
        "  DIAM 6 0 0 0 1 \"\"\n",
        "",
    );
    let loaded = read(&text).unwrap();
    assert_eq!(loaded.prescription, plain.prescription);
    let unknown: Vec<&LoadNote> = loaded
        .notes
        .iter()
        .filter(|n| matches!(n, LoadNote::UnknownHeaderKeywords { .. }))
        .collect();
    assert_eq!(
        unknown,
        [&LoadNote::UnknownHeaderKeywords {
            keywords: vec!["FSVY".into(), "STUD".into()]
        }]
    );
    assert!(!skipped(&loaded).iter().any(|k| k == "STUD" || k == "FSVY"));
    assert!(unknown[0].to_string().contains("does not know: FSVY, STUD"));
}

#[test]
fn unknown_or_unsupported_surface_keywords_are_refused_where_they_stand() {
    let text = singlet("", "  ZQXW 1\n  DIAM 6 0 0 0 1 \"\"\n", "");
    let e = read(&text).unwrap_err();
    assert!(
        matches!(&e.problem, Problem::Unsupported(what) if what.contains("ZQXW")),
        "{e}"
    );
    assert_eq!(e.location.line, Some(line_of(&text, "ZQXW")));
    assert_eq!(e.location.surface, Some(2));
    assert_eq!(e.location.field.as_deref(), Some("ZQXW"));

    // A coordinate break that tilts the image plane 5 degrees: no centred lens describes it.
    let text = singlet("", "", "").replace(
        "SURF 2\n  TYPE STANDARD",
        "SURF 2\n  TYPE COORDBRK\n  PARM 3 5",
    );
    let e = read(&text).unwrap_err();
    assert!(
        matches!(&e.problem, Problem::NotRotationallySymmetric { offence, .. } if offence.contains("image plane is tilted 5.000000 deg")),
        "{e}"
    );
    assert_eq!(e.location.line, Some(line_of(&text, "SURF 3")));
    assert_eq!(e.location.field.as_deref(), Some("TYPE COORDBRK"));

    // A central obscuration is read (tests/mirrors.rs); a square aperture makes the lens one
    // that only the 3-D trace reads (tests/off_axis.rs), at its line; an elliptical one is not
    // read at all.
    let text = singlet("", "  SQAP 2 2\n", "");
    let e = read(&text).unwrap_err();
    assert!(
        matches!(&e.problem, Problem::NotRotationallySymmetric { offence, lens }
            if offence == "surface 2 has a rectangular clear aperture"
                && lens.outlines[1].is_some()),
        "{e}"
    );
    assert_eq!(e.location.surface, Some(2));
    assert_eq!(e.location.line, Some(line_of(&text, "SQAP")));
    let text = singlet("", "  ELOB 2 1\n", "");
    let e = read(&text).unwrap_err();
    assert!(
        matches!(&e.problem, Problem::Unsupported(what) if what.contains("ELOB")),
        "{e}"
    );
}

/// Older OpticStudio files carry WAVL/WAVN and WWGT lists beside the WAVM table, of other
/// lengths (a Thorlabs file: 12 wavelengths, 3 weights, 24 WAVM rows); the WAVM table wins and
/// the mismatch is no crash.
#[test]
fn wavelength_lists_of_other_lengths_than_the_wavm_table() {
    let plain = read(&singlet("", "", "")).unwrap();
    let text = singlet(
        "WAVN 0.4861 0.5876 0.6563 0.55 0.55 0.55\nWWGT 1 1 1\n",
        "",
        "",
    );
    let loaded = read(&text).unwrap();
    let conditions = |l: &Loaded| l.prescription.provenance.conditions.clone().unwrap();
    assert_eq!(conditions(&loaded), conditions(&plain));
}

/// OpticStudio writes merit-function operands unindented straight after the last surface
/// (`GLCB 3 1 ...` before any `TOL`); they open the trailer. In a file that indents no surface
/// line, an unknown keyword is still refused where it stands.
#[test]
fn unindented_operands_after_indented_surfaces_open_the_trailer() {
    let plain = read(&singlet("", "", "")).unwrap();
    let text = singlet("", "", "").replace("  DISZ 0\nTOL", "  DISZ 0\nGLCB 3 1 0 0 0\nTOL");
    let loaded = read(&text).unwrap();
    assert_eq!(loaded.prescription, plain.prescription);
    assert!(skipped(&loaded).iter().any(|k| k == "GLCB"));

    let unindented = singlet("", "ZQXW 1\n", "").replace("\n  ", "\n");
    let e = read(&unindented).unwrap_err();
    assert!(
        matches!(&e.problem, Problem::Unsupported(what) if what.contains("ZQXW")),
        "{e}"
    );
    assert_eq!(e.location.surface, Some(2));
}

/// UTF-16 (either byte order, with the mark OpticStudio writes) and Latin-1 read as UTF-8 does.
#[test]
fn encodings_opticstudio_writes_read_alike() {
    let text = singlet("", "  DIAM 6 0 0 0 1 \"\"\n", "").replace("Test singlet", "Test singlet é");
    let read_as = |bytes: Vec<u8>| {
        read_bytes(
            &bytes,
            Some(Path::new(FILE)),
            Format::Zemax,
            &LoadOptions::default(),
        )
        .unwrap()
        .prescription
    };
    let utf8 = read_as(text.as_bytes().to_vec());
    assert_eq!(utf8.provenance.title, "Test singlet é");
    let mut le = vec![0xFF, 0xFE];
    let mut be = vec![0xFE, 0xFF];
    for unit in text.encode_utf16() {
        le.extend(unit.to_le_bytes());
        be.extend(unit.to_be_bytes());
    }
    let latin1: Vec<u8> = text.chars().map(|c| c as u32 as u8).collect();
    assert!(
        std::str::from_utf8(&latin1).is_err(),
        "the é byte is not UTF-8"
    );
    for (name, bytes) in [("UTF-16LE", le), ("UTF-16BE", be), ("Latin-1", latin1)] {
        assert_eq!(read_as(bytes), utf8, "{name}");
    }
}

#[test]
fn gcat_order_resolves_glass_names_several_makers_use() {
    // SCHOTT and CDGM both sell an F2 (different coefficients).
    let with = |gcat: &str| {
        let text = singlet("", "  DIAM 6 0 0 0 1 \"\"\n", "")
            .replace("GCAT SCHOTT", gcat)
            .replace("GLAS N-BK7", "GLAS F2");
        let loaded = read(&text).unwrap();
        let Medium::Glass(name) = &loaded.prescription.surfaces[0].medium else {
            panic!("F2 is a catalogue glass")
        };
        lookup(name).unwrap().maker
    };
    assert_eq!(with("GCAT SCHOTT CDGM"), "SCHOTT");
    assert_eq!(with("GCAT CDGM SCHOTT"), "CDGM");
    assert_eq!(with("GCAT OHARA CDGM"), "CDGM");
}

/// DIAM is the envelope OpticStudio computed, CLAP a real aperture, and a DIAM of 0 (a dummy
/// surface never sized) no aperture: derived from the file's beams.
#[test]
fn diam_clap_and_unsized_surfaces() {
    let loaded = read(&singlet("", "  DIAM 0 0 0 0 1 \"\"\n", "")).unwrap();
    assert!(
        loaded.notes.contains(&LoadNote::AperturesDerived {
            surfaces: vec![2],
            limited_at_edge: Vec::new()
        }),
        "{:?}",
        loaded.notes
    );
    let p = &loaded.prescription;
    assert_eq!(p.surfaces[0].semi_aperture, 6.0);
    // Paraxial marginal (5 mm) plus chief ray at 5 deg on surface 2: more than the marginal.
    assert!(p.surfaces[1].semi_aperture > 5.0 && p.surfaces[1].semi_aperture < 6.0);
    let loaded = read(&singlet("", "  DIAM 6 0 0 0 1 \"\"\n  CLAP 0 5.5\n", "")).unwrap();
    assert_eq!(loaded.prescription.surfaces[1].semi_aperture, 5.5);
}

/// A DIAM envelope past where the singlet's faces meet (R = +-50 mm, 5 mm thick: at r^2 = 243.75
/// mm^2, where each sag is 2.5 mm) is cut there, with a note; the same circle as a CLAP, a real
/// aperture, is a lens that cannot be made and is refused.
#[test]
fn diam_envelopes_past_the_lens_edge_are_cut_where_its_faces_meet() {
    let edge = 243.75f64.sqrt();
    let text = singlet("", "  DIAM 20 0 0 0 1 \"\"\n", "").replace("DIAM 6 1", "DIAM 20 1");
    let loaded = read(&text).unwrap();
    let cut: Vec<(usize, f64)> = loaded
        .notes
        .iter()
        .find_map(|n| match n {
            LoadNote::EnvelopesCut { surfaces } => Some(surfaces.clone()),
            _ => None,
        })
        .expect("a note names the cut surfaces");
    assert_eq!(cut.iter().map(|c| c.0).collect::<Vec<_>>(), [1, 2]);
    for (surface, radius) in cut {
        assert!((radius - edge).abs() < 1e-9, "{radius} vs {edge}");
        assert_eq!(
            loaded.prescription.surfaces[surface - 1].semi_aperture,
            radius
        );
    }
    let system = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
    let tracer = Tracer::new(&system.at(D_LINE_NM));
    let parallel = |height: f64| {
        let ray = Ray::new([0.0, height, -1.0], [0.0, 0.0, 1.0]).unwrap();
        tracer.trace(ray, Travel::Forward).outcome
    };
    assert!(parallel(0.99 * edge).is_ok());
    assert_eq!(parallel(1.01 * edge), Outcome::Vignetted { surface: 1 });

    let clear = singlet("", "  CLAP 0 20\n", "").replace("DIAM 6 1 0 0 1 \"\"", "CLAP 0 20");
    let loaded = read(&clear).unwrap();
    let e = LensSystem::new(loaded.prescription, &loaded.map).unwrap_err();
    assert!(matches!(e.problem, Problem::SurfacesCross { .. }), "{e}");
}

#[test]
fn the_files_conditions_are_stored_and_become_the_analysis_defaults() {
    let text = singlet("", "  DIAM 6 0 0 0 1 \"\"\n", "");
    let loaded = read(&text).unwrap();
    let conditions = loaded.prescription.provenance.conditions.clone().unwrap();
    assert_eq!(conditions.object_distance_mm, None);
    assert_eq!(
        conditions.aperture,
        Some(ApertureSpec::EntrancePupilDiameter(10.0))
    );
    let fields = conditions.fields.unwrap();
    // FTYP says 2 fields and 3 wavelengths; OpticStudio writes every slot of its tables.
    assert_eq!(
        (fields.kind, fields.y.clone(), fields.weights.clone()),
        (FieldKind::AngleDeg, vec![0.0, 5.0], vec![1.0, 2.0])
    );
    assert_eq!(conditions.wavelengths_nm.len(), 3);
    assert_eq!(conditions.wavelength_weights, [1.0, 2.0, 1.0]);
    assert_eq!(conditions.primary, Some(1));

    let system = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
    let a = analyze(&system, &AnalyzeOptions::default()).unwrap();
    // 0.5875618 µm in nm, to the rounding of the unit change.
    assert!(
        (a.wavelength_nm - 587.5618).abs() < 1e-9,
        "{}",
        a.wavelength_nm
    );
    assert!((a.field_deg - 5.0).abs() < 1e-12, "{}", a.field_deg);
    assert!((a.first_order.entrance_pupil.diameter - 10.0).abs() < 1e-12);
    assert_eq!(a.object_distance_mm, None);
    // A flag still overrides the file.
    let flagged = AnalyzeOptions {
        epd_mm: Some(4.0),
        ..AnalyzeOptions::default()
    };
    let a = analyze(&system, &flagged).unwrap();
    assert!((a.first_order.entrance_pupil.diameter - 4.0).abs() < 1e-12);
}

/// A 1:1 relay at 100 mm: SURF 0 DISZ is the object distance, FNUM the image-space F-number
/// (at infinity), OBNA the object NA, FTYP 1 object heights.
#[test]
fn finite_objects_numerical_apertures_and_object_heights() {
    let text = singlet("", "  DIAM 6 0 0 0 1 \"\"\n", "")
        .replace("  DISZ INFINITY", "  DISZ 100")
        .replace("ENPD 10", "OBNA 0.04")
        .replace("FTYP 0 0 2 3", "FTYP 1 0 2 3")
        .replace("YFLN 0 5 0 0", "YFLN 0 3 0 0");
    let loaded = read(&text).unwrap();
    let conditions = loaded.prescription.provenance.conditions.clone().unwrap();
    assert_eq!(conditions.object_distance_mm, Some(100.0));
    let system = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
    let a = analyze(&system, &AnalyzeOptions::default()).unwrap();
    assert_eq!(a.object_distance_mm, Some(100.0));
    assert_eq!(a.first_order.object_height, Some(3.0));
    // The marginal ray leaves the axial object point at slope tan(asin(NA)).
    let u = 0.04f64.asin().tan();
    let z_pupil = a.first_order.entrance_pupil.z;
    let epd = a.first_order.entrance_pupil.diameter;
    assert!(
        (epd / 2.0 / (100.0 + z_pupil) - u).abs() < 1e-12,
        "EPD {epd}"
    );

    let text = singlet("", "  DIAM 6 0 0 0 1 \"\"\n", "").replace("ENPD 10", "FNUM 8 0");
    let loaded = read(&text).unwrap();
    let system = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
    let a = analyze(&system, &AnalyzeOptions::default()).unwrap();
    assert!(
        (a.first_order.f_number - 8.0).abs() < 1e-12,
        "{}",
        a.first_order.f_number
    );
}

/// An optimiser's -1e-8 mm gap is touching; a 1e-5 mm overlap is a crossing.
#[test]
fn tiny_negative_gaps_pass_and_real_overlaps_do_not() {
    let text = |gap: &str| {
        {
            singlet("", "  DIAM 6 0 0 0 1 \"\"\n", "").replace(
                "  CURV -0.02 0 0 0 0 \"\"\n  DISZ 47",
                &format!("  CURV 0 0 0 0 0 \"\"\n  DISZ {gap}\nSURF 3\n  CURV 0\n  DISZ 47"),
            )
        }
        .replace(
            "SURF 3\n  TYPE STANDARD\n  CURV 0\n  DISZ 0\n",
            "SURF 4\n  CURV 0\n  DISZ 0\n",
        )
        // Surface 3 is a window's face, so both planes bend rays (a plane between equal media
        // is a reference plane, exempt: below).
        .replace(
            "SURF 3\n  CURV 0\n  DISZ 47",
            "SURF 3\n  CURV 0\n  DISZ 47\n  GLAS N-F2",
        )
    };
    let load = |gap: &str| {
        let loaded = read(&text(gap)).unwrap();
        LensSystem::new(loaded.prescription, &loaded.map)
    };
    assert!(load("-1e-8").is_ok());
    let e = load("-1e-5").unwrap_err();
    assert!(
        matches!(e.problem, Problem::SurfacesCross { next: 3, .. }),
        "{e}"
    );
    assert_eq!(e.location.surface, Some(2));
}

/// A dummy plane inside the singlet (glass on both sides), left by an optimiser 1e-10 mm in
/// front of the rear surface, which curves back through it within the aperture: OpticStudio
/// traces rays to such a plane wherever it lies along them, and so does lensbake, so the file
/// loads and every ray leaves as it does from the singlet without the plane.
#[test]
fn a_reference_plane_crossed_by_its_neighbour_changes_no_ray() {
    let plain = singlet("", "  DIAM 6 0 0 0 1 \"\"\n", "");
    let with_dummy = plain
        .replace(
            "SURF 2\n  TYPE STANDARD\n  CURV -0.02",
            "SURF 2\n  TYPE STANDARD\n  CURV 0\n  DISZ 1e-10\n  GLAS N-BK7 0 0 1.5168 64.17 0 0 0 0 0 0\n  \
             DIAM 6 0 0 0 1 \"\"\n\
             SURF 3\n  TYPE STANDARD\n  CURV -0.02",
        )
        .replace("  DISZ 5\n", "  DISZ 4.9999999999\n")
        .replace("SURF 3\n  TYPE STANDARD\n  CURV 0\n  DISZ 0\n", "SURF 4\n  CURV 0\n  DISZ 0\n");
    let system = |text: &str| {
        let loaded = read(text).unwrap();
        LensSystem::new(loaded.prescription, &loaded.map).unwrap()
    };
    // Without a DIAM its aperture is derived from the file's beams, not cut where the rear
    // surface passes through it (1e-4 mm from the axis).
    let no_diam = with_dummy.replace("  DIAM 6 0 0 0 1 \"\"\nSURF 3", "SURF 3");
    assert_ne!(no_diam, with_dummy);
    let derived = read(&no_diam).unwrap().prescription.surfaces[1].semi_aperture;
    assert!(derived > 4.0, "{derived}");
    let (plain, dummy) = (system(&plain), system(&with_dummy));
    assert_eq!(dummy.prescription.surfaces.len(), 3);
    let tracers = [&plain, &dummy].map(|s| Tracer::new(&s.at(D_LINE_NM)));
    for k in 0..=20 {
        let y = -4.2 + 0.37 * k as f64;
        let ray = Ray::new([0.0, y, -10.0], [0.0, 0.05, 1.0]).unwrap();
        let [a, b] = tracers.each_ref().map(|t| t.trace(ray, Travel::Forward));
        assert!(a.outcome.is_ok() && b.outcome.is_ok(), "{y}: {a:?} {b:?}");
        for (u, v) in a.ray.position().iter().zip(b.ray.position()) {
            assert!((u - v).abs() < 1e-9, "{y}: {:?} vs {:?}", a.ray, b.ray);
        }
        for (u, v) in a.ray.direction().iter().zip(b.ray.direction()) {
            assert!((u - v).abs() < 1e-12, "{y}: {:?} vs {:?}", a.ray, b.ray);
        }
    }
}

fn codev(text: &str) -> Result<Loaded, PrescriptionError> {
    read_str(
        text,
        Some(Path::new("test.seq")),
        Format::CodeV,
        &LoadOptions::default(),
    )
}

#[test]
fn codev_continuation_lines_model_glasses_and_the_default_stop() {
    let text = "TITLE 'continued'\nEPD 10\nDIM M\nWL 486.1327 587.5618 &\n 656.2725\nREF 2\n\
                TEM 25\nYIM 0 4\nSO 0 1e20\nS 50 5 1.5168:64.17\nCIR 6\nS -50 47\nCIR 6\nSI 0 0\nGO\n";
    let loaded = codev(text).unwrap();
    let p = &loaded.prescription;
    assert_eq!(
        p.provenance.conditions.as_ref().unwrap().wavelengths_nm,
        [486.1327, 587.5618, 656.2725]
    );
    assert_eq!(p.provenance.design_wavelength_nm, Some(587.5618));
    assert_eq!(
        p.surfaces[0].medium,
        Medium::Model {
            nd: 1.5168,
            vd: 64.17
        }
    );
    // No STO: CODE V takes surface 1 as the stop.
    assert_eq!(p.surfaces[0].stop, Some(StopShape::Circle));
    assert_eq!(skipped(&loaded), ["TEM"]);
    let model = Dispersion::of(&p.surfaces[0].medium).unwrap();
    assert!((model.index(D_LINE_NM) - 1.5168).abs() < 1e-12);

    // YIM: paraxial image height 4 mm at infinity is the angle whose chief ray lands there.
    let system = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
    let a = analyze(&system, &AnalyzeOptions::default()).unwrap();
    assert!(
        (a.first_order.image_height.abs() - 4.0).abs() < 1e-9,
        "{}",
        a.first_order.image_height
    );
    assert!((a.first_order.entrance_pupil.diameter - 10.0).abs() < 1e-12);
}

#[test]
fn codev_refusals_name_the_command_and_line() {
    let text = "EPD 10\nS 50 5 N-BK7\nCIR 6\nPIK RDY S1 -1 0\nS -50 47\nCIR 6\nGO\n";
    let e = codev(text).unwrap_err();
    assert!(
        matches!(&e.problem, Problem::Unsupported(what) if what.contains("PIK")),
        "{e}"
    );
    assert_eq!((e.location.line, e.location.surface), (Some(4), Some(1)));
}

/// `lens convert` keeps the file's conditions: the RON of a Zemax lens reads back identical.
#[test]
fn conditions_survive_the_ron_round_trip() {
    let loaded = read(&singlet("", "  DIAM 6 0 0 0 1 \"\"\n", "")).unwrap();
    let ron = lensbake::prescription::formats::write_ron(&loaded.prescription);
    let back = read_str(&ron, None, Format::Ron, &LoadOptions::default()).unwrap();
    assert_eq!(back.prescription, loaded.prescription);
    assert!(ron.contains("conditions"), "{ron}");
}

/// `STOP` is CODE V's `STO` written out (CODE V reads a command by its first three letters):
/// a copy of rayoptics' achroMangin.seq with the mirror and the withdrawn SCHOTT glasses replaced
/// by refracting N-SK16 and N-KZFS4, and the stop moved behind surface 2 so that it differs from
/// CODE V's default (surface 1).
#[test]
fn codev_stop_written_out_marks_the_stop() {
    let text = "rdm y\nso 0 1e11\ns -9.435 0.346 N-SK16_Schott\ns 37.5 1.092 N-KZFS4_Schott\n\
                stop\ns -14.357 5\nsi 0 0\nwl 488. 587. 656.\nepd 5.0\nyan 0\n";
    let loaded = codev(text).unwrap();
    let stops: Vec<usize> = loaded
        .prescription
        .surfaces
        .iter()
        .enumerate()
        .filter_map(|(i, s)| s.stop.as_ref().map(|_| i + 1))
        .collect();
    assert_eq!(stops, [2]);
    let e = codev("EPD 4\nSO 0 1e11\nSTOP\nS 50 5 N-BK7\nSI 0 0\n").unwrap_err();
    assert_eq!(e.location.line, Some(3), "{e}");
}

/// `CUF 0.0`, which CODE V writes into every ASP block, leaves the asphere as K and A..J give
/// it; another value is refused where it stands.
#[test]
fn codev_cuf_zero_is_read_and_other_values_refused() {
    let asphere = |cuf: &str| {
        format!(
            "EPD 10\nSO 0 1e11\nS 50 5 N-BK7\n  ASP\n  K -0.5\n  CUF {cuf}\n  A 1e-6; B 0.0\n\
             S -50 47\nSI 0 0\n"
        )
    };
    let loaded = codev(&asphere("0.0")).unwrap();
    assert!(skipped(&loaded).contains(&"CUF 0".to_string()));
    let shape = &loaded.prescription.surfaces[0].shape;
    assert_eq!((shape.conic(), shape.curvature()), (-0.5, 0.02));
    let e = codev(&asphere("0.25")).unwrap_err();
    assert!(
        matches!(&e.problem, Problem::Unsupported(w) if w.contains("CUF 0.25")),
        "{e}"
    );
    assert_eq!((e.location.line, e.location.surface), (Some(6), Some(1)));
}

/// Solves in their long forms (`CUY UMY`, a curvature solved for a marginal ray angle, as the
/// CODE V singlet sample writes it; `THI HMY`, a thickness solved for a ray height) and `RED` on the object (a reduction ratio, the
/// magnification) keep what the file writes, as `CUM` and `PIM` do, and are named in the note;
/// a curvature solve lensbake does not know is refused where it stands.
#[test]
fn codev_long_form_solves_keep_the_written_values() {
    let singlet = |solve: &str| {
        format!(
            "EPD 20\nWL 500\nSO 0 150\n  RED 0.5\nS 50 5 N-BK7\n  STO\n  THI HMY 0\n\
             S 1175.7 96.6\n  {solve}\n  PIM\nSI 0 0\n"
        )
    };
    let loaded = codev(&singlet("CUY UMY -0.1")).unwrap();
    let solves = loaded
        .notes
        .iter()
        .find_map(|note| match note {
            LoadNote::SolvesAsWritten { solves } => Some(solves.clone()),
            _ => None,
        })
        .unwrap();
    assert_eq!(solves, ["CUY UMY", "PIM", "RED", "THI HMY"]);
    let surfaces = &loaded.prescription.surfaces;
    assert_eq!(surfaces[1].shape.curvature(), 1.0 / 1175.7);
    let conditions = loaded.prescription.provenance.conditions.as_ref().unwrap();
    assert_eq!(conditions.object_distance_mm, Some(150.0));
    let e = codev(&singlet("CUY QQY -0.1")).unwrap_err();
    assert!(
        e.to_string().contains("solve `CUY QQY`") && e.location.line == Some(9),
        "{e}"
    );
    let e = codev(&singlet("THI QQY 0")).unwrap_err();
    assert!(
        e.to_string().contains("solve `THI QQY`") && e.location.line == Some(9),
        "{e}"
    );
}

/// Pickups: item of surface k = scale * item of surface j + offset, evaluated after the last
/// surface, in file order (the Questar file's two forms, `PIK RDY S4 Z1 RDY S2 Z1` and
/// `PIK THI S3 Z1 THI S2 Z1 -1.0`, plus an offset and a chained pickup).
#[test]
fn codev_pickups_copy_radius_thickness_and_conic() {
    let text = "RDM N\nEPD 10\nSO 0 1e11\nS 0.02 5 N-BK7\n  CON\n  K -0.5\nS -0.01 3 N-SF5\n\
                S 0 40\nS 0 10\nSI 0 0\nPIK RDY S3 Z1 RDY S2 Z1 -2.0\n\
                PIK THI S4 Z1 THI S2 Z1 2.0 1.5\nPIK K S2 K S1\nPIK CUY S4 CUY S3\nGO\n";
    let loaded = codev(text).unwrap();
    let s = &loaded.prescription.surfaces;
    // R2 = -100, so R3 = -2 * -100 = 200; surface 4 then picks up its curvature 1/200.
    assert!((s[2].shape.curvature() - 1.0 / 200.0).abs() < 1e-15);
    assert!((s[3].shape.curvature() - 1.0 / 200.0).abs() < 1e-15);
    assert_eq!(s[3].thickness, 2.0 * 3.0 + 1.5);
    assert_eq!(s[1].shape.conic(), -0.5);

    for (pickup, why) in [
        ("PIK RDY S3 Z2 RDY S2 Z1", "between zoom positions"),
        ("PIK RDY S9 RDY S2", "surface S9"),
        ("PIK GLA S3 GLA S2", "item GLA"),
        ("PIK RDY S3 THI S2", "different items"),
    ] {
        let e = codev(&text.replace("PIK K S2 K S1", pickup)).unwrap_err();
        assert!(
            matches!(&e.problem, Problem::Unsupported(w) if w.contains(why)),
            "{e}"
        );
        assert_eq!(e.location.line, Some(line_of(text, "PIK K S2")), "{e}");
    }
}

/// A zoom file is read at the position asked (1 by default): zoomed thicknesses, radii, conics,
/// the object distance, EPD, fields take that position's ZOO value (here each differs from what
/// the lens data write, so the test sees which one is used); the pickups of that position apply
/// (a pickup written for position 2 only changes position 2, one written for no position applies
/// at every position without its own); other zoomed items are read as written and named in the
/// note; a position the file does not have is one error at the `ZOO n` line.
#[test]
fn codev_zoom_files_are_read_at_the_position_asked() {
    let text = "RDM Y\nEPD 10\nSO 0 1e11\nS 50 5 N-BK7\nS -50 30\nS 0 20\nSI 0 0\nYAN 0 5\n\
                ZOO 3\nZOO TIT\nTIT Z1 'wide'\nTIT Z2 'tele'\nZOO THI S2 40 50 60\n\
                ZOO RDY S1 45 55 65\nZOO K S1 -0.2 0 0\nZOO THI S0 5000 8000 INFINITY\n\
                ZOO EPD 8 9 10\nZOO YAN F2 5 4 3\nPIK THI S3 Z2 THI S2 Z2 2\n\
                PIK K S2 K S1 0.5\nPIK K S2 Z3 K S1 3\nGO\n";
    let at = |position: usize| {
        let options = LoadOptions {
            zoom_position: Some(position),
            ..LoadOptions::default()
        };
        read_str(text, Some(Path::new("zoom.seq")), Format::CodeV, &options)
    };
    let expected = [
        // R1, K1, t2, t3, object distance, EPD, field 2, K2.
        (45.0, -0.2, 40.0, 20.0, Some(5000.0), 8.0, 5.0, -0.1),
        (55.0, 0.0, 50.0, 100.0, Some(8000.0), 9.0, 4.0, 0.0),
        (65.0, 0.0, 60.0, 20.0, None, 10.0, 3.0, 0.0),
    ];
    for (k, (r1, k1, t2, t3, object, epd, field, k2)) in expected.into_iter().enumerate() {
        let loaded = at(k + 1).unwrap();
        let p = &loaded.prescription;
        assert_eq!(
            p.surfaces[0].shape.curvature(),
            1.0 / r1,
            "position {}",
            k + 1
        );
        assert_eq!(p.surfaces[0].shape.conic(), k1);
        assert_eq!(p.surfaces[1].thickness, t2);
        assert_eq!(p.surfaces[2].thickness, t3);
        assert_eq!(p.surfaces[1].shape.conic(), k2);
        let conditions = p.provenance.conditions.as_ref().unwrap();
        assert_eq!(conditions.object_distance_mm, object);
        assert_eq!(
            conditions.aperture,
            Some(ApertureSpec::EntrancePupilDiameter(epd))
        );
        assert_eq!(conditions.fields.as_ref().unwrap().y, [0.0, field]);
        let note = LoadNote::ZoomPosition {
            position: k + 1,
            count: 3,
            as_written: vec!["TIT".into()],
        };
        assert!(loaded.notes.contains(&note), "{:?}", loaded.notes);
        assert!(
            note.to_string()
                .contains(&format!("position {} of 3", k + 1)),
            "{note}"
        );
    }
    assert_eq!(
        codev(text).unwrap().prescription.surfaces,
        at(1).unwrap().prescription.surfaces
    );
    // A position the file does not have: one error naming the ZOO n line.
    for position in [0, 4] {
        let e = at(position).unwrap_err();
        assert!(
            e.to_string().contains("the file has zoom positions 1..=3"),
            "{e}"
        );
        assert_eq!(e.location.line, Some(line_of(text, "ZOO 3")), "{e}");
        assert_eq!(e.location.field.as_deref(), Some("ZOO"), "{e}");
    }
    // A zoomed line without a value for the position asked is refused at that line.
    let short = text.replace("ZOO EPD 8 9 10", "ZOO EPD 8 9");
    let options = LoadOptions {
        zoom_position: Some(3),
        ..LoadOptions::default()
    };
    let e = read_str(&short, None, Format::CodeV, &options).unwrap_err();
    assert!(e.to_string().contains("zoom position 3"), "{e}");
    assert_eq!(e.location.line, Some(line_of(&short, "ZOO EPD")), "{e}");
    // A file without zoom positions has position 1 only.
    let plain = "EPD 10\nSO 0 1e11\nS 50 5 N-BK7\nS -50 47\nSI 0 0\n";
    let options = LoadOptions {
        zoom_position: Some(2),
        ..LoadOptions::default()
    };
    let e = read_str(plain, None, Format::CodeV, &options).unwrap_err();
    assert!(e.to_string().contains("no zoom positions"), "{e}");
    // So has a lens in another format.
    let ron = lensbake::lenses::find("cooke-triplet").unwrap().ron;
    let e = read_str(ron, None, Format::Ron, &options).unwrap_err();
    assert!(e.to_string().contains("without zoom positions"), "{e}");
    // A zoomed surface the file does not have is an error at its line.
    let e = codev(&text.replace("ZOO K S1", "ZOO K S7")).unwrap_err();
    assert!(e.to_string().contains("ZOO names surface 7"), "{e}");
    assert_eq!(e.location.line, Some(line_of(text, "ZOO K S1")), "{e}");
}

/// A derived clear aperture never reaches past the end of its surface: a sphere of R = 4 mm in a
/// 10 mm beam ends at 4 mm (its hemisphere), a conic of R = -3 mm, k = 0.5 at 3 / sqrt(1.5); the note
/// says which surfaces were limited, and the lens loads. Without `RDM` the same numbers are
/// refused: read as radii by default they contradict the beam, which suggests curvatures.
#[test]
fn derived_apertures_stop_at_the_rim_of_the_surface() {
    let text = "RDM\nEPD 10\nSO 0 1e11\nS 4 4 N-BK7\nS -3 1\n  CON\n  K 0.5\nS 0 20\nSI 0 0\n";
    let loaded = codev(text).unwrap();
    let s = &loaded.prescription.surfaces;
    assert_eq!(s[0].semi_aperture, 4.0);
    let conic_rim = 3.0 / 1.5f64.sqrt();
    assert!(
        (s[1].semi_aperture - conic_rim).abs() < 1e-12,
        "{}",
        s[1].semi_aperture
    );
    // The plane's derived aperture is the marginal height there, unlimited.
    assert!(s[2].semi_aperture > 0.0);
    let note = loaded
        .notes
        .iter()
        .find(|n| matches!(n, LoadNote::AperturesDerived { .. }))
        .unwrap();
    assert_eq!(
        note,
        &LoadNote::AperturesDerived {
            surfaces: vec![1, 2, 3],
            limited_at_edge: vec![1, 2],
        }
    );
    assert!(
        note.to_string()
            .contains("surfaces 1-2 those rays reach beyond"),
        "{note}"
    );
    LensSystem::new(loaded.prescription, &loaded.map).unwrap();
    // An aperture the file states is the file's: larger than the sphere, it is refused at its
    // line, as a sign the values are not radii.
    let e = codev(&text.replace("S 4 4 N-BK7\n", "S 4 4 N-BK7\nCIR 4.5\n")).unwrap_err();
    assert!(
        matches!(e.problem, Problem::RadiusModeContradicted(_))
            && e.to_string().contains("RDM on line 1")
            && e.to_string().contains("clear aperture of 4.5 (CIR)")
            && e.to_string().contains("write `RDM N`"),
        "{e}"
    );
    assert_eq!(e.location.line, Some(line_of(text, "S 4 4")), "{e}");
    // Without RDM the numbers contradict the default radius reading.
    let e = codev(text.trim_start_matches("RDM\n")).unwrap_err();
    assert!(e.to_string().contains("add `RDM N`"), "{e}");
}

/// CODE V's FNO with a finite object is the working F-number 1 / (2 n' u') at that object
/// distance (rayoptics reads it so), and YIM image heights of a finite object are the paraxial
/// image heights the magnification gives: the analysis meets both.
#[test]
fn codev_f_number_and_image_heights_of_a_finite_object() {
    let text = "dim m\nso 0 200\ns 50 5 N-BK7\ns -50 100\nsi 0 0\nfno 5\nwl 587.5618\nyim 0 3\n";
    let loaded = codev(text).unwrap();
    let conditions = loaded.prescription.provenance.conditions.clone().unwrap();
    assert_eq!(conditions.aperture, Some(ApertureSpec::WorkingFNumber(5.0)));
    let system = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
    let a = analyze(&system, &AnalyzeOptions::default()).unwrap();
    assert!(
        (a.first_order.working_f_number - 5.0).abs() < 1e-12,
        "{}",
        a.first_order.working_f_number
    );
    assert!(
        (a.first_order.image_height.abs() - 3.0).abs() < 1e-9,
        "{}",
        a.first_order.image_height
    );
}

/// Nor does a derived aperture reach past the knife edge where a lens's two faces meet: a
/// biconvex singlet R = +-20 mm, 5 mm thick, has its edge at sqrt(20^2 - 17.5^2) mm, inside the
/// 30 mm beam the file asks for (optiland's lens_floa.zmx is this lens behind a floating stop).
#[test]
fn derived_apertures_stop_where_the_faces_of_a_lens_meet() {
    let loaded = codev("EPD 30\nSO 0 1e11\nS 20 5 N-BK7\nS -20 30\nSI 0 0\n").unwrap();
    let edge = (20.0f64 * 20.0 - 17.5 * 17.5).sqrt();
    for s in &loaded.prescription.surfaces {
        assert!((s.semi_aperture - edge).abs() < 1e-9, "{}", s.semi_aperture);
    }
    assert!(loaded.notes.contains(&LoadNote::AperturesDerived {
        surfaces: vec![1, 2],
        limited_at_edge: vec![1, 2],
    }));
    LensSystem::new(loaded.prescription, &loaded.map).unwrap();
}

/// A CODE V private glass given by Laurent coefficients (`PRV`, `LAU a0..a5`): the index is
/// n^2 = a0 + a1 l^2 + a2 / l^2 + a3 / l^4 + a4 / l^6 + a5 / l^8 (l in micrometres), here
/// Norland NOA61 as CODV_35571.seq gives it, n = 1.56 at 550 nm as Norland states; five
/// coefficients are refused.
#[test]
fn codev_private_glasses_by_laurent_coefficients() {
    let a = [
        2.36390625,
        0.0,
        0.025493134,
        -0.000580235,
        -0.349933e-5,
        0.445404e-7,
    ];
    let glass = format!("'NOA61' LAU {}", a.map(|v| v.to_string()).join(" "));
    let text = format!(
        "EPD 10\nWL 550\nPRV\nPWL 550\n{glass}\nEND\nSO 0 1e11\nS 50 5 'NOA61'\nSTO\nS -50 45\n\
         SI 0 0\n"
    );
    let loaded = codev(&text).unwrap();
    let system = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
    for nm in [450.0, 550.0, 650.0] {
        let l2 = (nm * 1e-3f64).powi(2);
        let n2 = a[0]
            + a[1] * l2
            + a[2] / l2
            + a[3] / l2.powi(2)
            + a[4] / l2.powi(3)
            + a[5] / l2.powi(4);
        let ours = system.at(nm).surfaces[0].index_after;
        assert!((ours - n2.sqrt()).abs() < 1e-15, "{nm} nm: {ours}");
    }
    assert!((system.at(550.0).surfaces[0].index_after - 1.56).abs() < 0.005);
    let e = codev(&text.replace(&glass, &glass[..glass.rfind(' ').unwrap()])).unwrap_err();
    assert!(e.to_string().contains("6 Laurent coefficients"), "{e}");
    assert_eq!(e.location.line, Some(5), "{e}");
}

fn data_file(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name)
}

/// The Cooke triplet of tests/data with `from` replaced by `to` in its text.
fn cooke_with(from: &str, to: &str) -> String {
    let text = std::fs::read_to_string(data_file("cooke_triplet.zmx")).unwrap();
    assert!(text.contains(from), "the test file changed: {from}");
    text.replacen(from, to, 1)
}

/// A glass no catalogue holds becomes the model glass of the nd and Vd OpticStudio writes beside
/// its name, with a note naming surface and glass: n(d) is nd and (nd - 1) / (nF - nC) is Vd
/// exactly, and the lens at the d line is the catalogue glass's lens to the rounding of the
/// written nd.
#[test]
fn an_unknown_glass_is_read_as_the_model_glass_its_file_writes() {
    let text = cooke_with(
        "GLAS F2 1 0 1.620040 36.37",
        "GLAS F2_FROM_NO_CATALOGUE 1 0 1.620040 36.37",
    );
    let loaded = read(&text).unwrap();
    assert_eq!(
        loaded.prescription.surfaces[2].medium,
        Medium::Model {
            nd: 1.62004,
            vd: 36.37
        }
    );
    let note = loaded
        .notes
        .iter()
        .find(|n| matches!(n, LoadNote::ModelGlasses { .. }))
        .expect("a note names the model glass");
    let said = note.to_string();
    assert!(
        said.contains("surface 3 F2_FROM_NO_CATALOGUE (nd 1.62004, Vd 36.37)"),
        "{said}"
    );
    let system = LensSystem::new(loaded.prescription.clone(), &loaded.map).unwrap();
    let model = &system.dispersions[2];
    let (d, f, c) = (
        model.index(D_LINE_NM),
        model.index(lensbake::glass::F_LINE_NM),
        model.index(lensbake::glass::C_LINE_NM),
    );
    assert!((d - 1.62004).abs() <= 1e-12, "n(d) {d}");
    assert!(((d - 1.0) / (f - c) - 36.37).abs() <= 1e-10, "Vd");
    let catalogue =
        read(&std::fs::read_to_string(data_file("cooke_triplet.zmx")).unwrap()).unwrap();
    let catalogue = LensSystem::new(catalogue.prescription, &catalogue.map).unwrap();
    let options = AnalyzeOptions {
        wavelength_nm: Some(D_LINE_NM),
        ..AnalyzeOptions::default()
    };
    let (x, y) = (
        analyze(&system, &options).unwrap().first_order.efl,
        analyze(&catalogue, &options).unwrap().first_order.efl,
    );
    // SCHOTT F2's formula gives n(d) within 1e-6 of its printed nd 1.62004.
    let catalogue_nd = lookup("F2").unwrap().dispersion().index(D_LINE_NM);
    assert!((catalogue_nd - 1.62004).abs() < 1e-5);
    assert!((x - y).abs() <= 1e-4 * y, "EFL {x} vs {y}");
}

/// Numbers that are no glass's are never made into one: `0 0` beside an unknown name, or a file
/// whose numbers beside catalogue glasses are not theirs (a writer that puts `1.5 40` beside
/// every name, as rayoptics__US08427765-1.ZMX does), leave the name unknown and refused.
#[test]
fn numbers_that_are_no_glass_are_not_made_into_a_model_glass() {
    let empty = cooke_with("GLAS F2 1 0 1.620040 36.37", "GLAS F2_UNLISTED 1 0 0 0");
    let placeholder = cooke_with("GLAS F2 1 0 1.620040 36.37", "GLAS F2_UNLISTED 1 0 1.5 40")
        .replacen("GLAS SK16 1 0 1.620408 60.32", "GLAS SK16 1 0 1.5 40", 1);
    for (label, text) in [("0 0", empty), ("placeholders", placeholder)] {
        let loaded = read(&text).unwrap();
        assert_eq!(
            loaded.prescription.surfaces[2].medium,
            Medium::Glass("F2_UNLISTED".into()),
            "{label}"
        );
        let error = LensSystem::new(loaded.prescription.clone(), &loaded.map).unwrap_err();
        assert!(
            matches!(error.problem, Problem::UnknownGlass { .. }),
            "{label}: {error}"
        );
        let contradicted = loaded
            .notes
            .iter()
            .any(|n| matches!(n, LoadNote::WrittenGlassDataContradicted(c) if c.name == "SK16"));
        assert_eq!(contradicted, label == "placeholders", "{label}");
    }
    // The corpus file that writes `1.5 40` beside every name names only catalogue glasses now
    // that its L-TIM28_MOLD reads as OHARA's L-TIM28: it loads, and no model glass is made.
    let corpus = data_file("corpus/rayoptics__US08427765-1.ZMX");
    let loaded =
        lensbake::prescription::formats::read_file(&corpus, &LoadOptions::default()).unwrap();
    assert!(LensSystem::new(loaded.prescription.clone(), &loaded.map).is_ok());
    assert!(
        !loaded
            .notes
            .iter()
            .any(|n| matches!(n, LoadNote::ModelGlasses { .. }))
    );
}

/// A lens table headed by its focal length alone on a line (ISET's pbrt lens files): the number
/// is the claimed focal length, compared with the EFL and never used for it.
#[test]
fn a_lens_table_headed_by_its_focal_length_reads_it_as_the_claim() {
    let path = data_file("lens-tables/iset3d__tessar.22deg.50.0mm.dat");
    let loaded =
        lensbake::prescription::formats::read_file(&path, &LoadOptions::default()).unwrap();
    assert_eq!(
        loaded.prescription.provenance.claimed_focal_length_mm,
        Some(50.0)
    );
    assert_eq!(loaded.prescription.surfaces.len(), 8);
    let system = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
    let efl = analyze(&system, &AnalyzeOptions::default())
        .unwrap()
        .first_order
        .efl;
    // The table was scaled to a 50 mm claim from a design of EFL 100.18 mm (Smith).
    assert!((efl - 50.0).abs() < 0.01 * 50.0, "EFL {efl}");

    let table = |text: &str| {
        read_str(
            text,
            Some(Path::new("t.dat")),
            Format::Pbrt,
            &LoadOptions::default(),
        )
    };
    let rows = "50 5 1.5 20\n0 5 0 10\n-50 40 1 20\n";
    assert_eq!(
        table(&format!("# focal length\n-80\n{rows}"))
            .unwrap()
            .prescription
            .provenance
            .claimed_focal_length_mm,
        Some(-80.0)
    );
    // After the first surface row, or a second one, a lone number is a short row.
    for text in [
        format!("{rows}50\n"),
        format!("50\n60\n{rows}"),
        format!("0\n{rows}"),
        format!("inf\n{rows}"),
    ] {
        let error = table(&text).unwrap_err();
        assert!(
            matches!(
                error.problem,
                Problem::WrongColumnCount { .. } | Problem::Syntax(_) | Problem::NonFinite { .. }
            ),
            "{text}: {error}"
        );
    }
}

/// A private glass table that ends 20 nm short of the file's 920 nm (400-900 nm) is continued
/// there, within 5% of its span, with a note naming surface, glass, wavelength and table; 930 nm
/// is refused.
#[test]
fn a_table_a_few_nm_short_of_a_wavelength_is_continued_with_a_note() {
    let lens = |nm: u32| {
        format!(
            "RDM\nEPD 10\nWL {nm}\nPRV\nPWL 900 650 400\n'G1' 1.5155 1.52 1.53\nEND\nSO 0 1e11\n\
             S 50 5 'G1'\nSTO\nS -50 45\nSI 0 0\n"
        )
    };
    let loaded = codev(&lens(920)).unwrap();
    let note = loaded
        .notes
        .iter()
        .find(|n| matches!(n, LoadNote::IndicesExtrapolated { .. }))
        .unwrap_or_else(|| panic!("{:?}", loaded.notes));
    let text = note.to_string();
    assert!(
        text.contains("surface 1") && text.contains("at 920 nm (table 400-900 nm)"),
        "{text}"
    );
    let system = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
    assert!(system.at_checked(920.0).is_ok());
    let loaded = codev(&lens(930)).unwrap();
    let error = LensSystem::new(loaded.prescription, &loaded.map)
        .and_then(|s| s.at_checked(930.0).map(|_| ()))
        .unwrap_err();
    assert!(
        matches!(error.problem, Problem::WavelengthOutOfRange { .. }),
        "{error}"
    );
}
