//! Each class of malformed input gets its own Problem, located by file, line, surface and field.

mod common;

use common::lens_file;
use lensbake::limits::LimitError;
use lensbake::prescription::formats::{
    Format, LoadOptions, PbrtThickness, read_bytes, read_file, read_str,
};
use lensbake::prescription::{Location, PrescriptionError, Problem};
use lensbake::system::LensSystem;
use std::path::{Path, PathBuf};

const FILE: &str = "bad.lens";

/// Reads `text` as `format` under the file name `bad.lens`, then validates and resolves it.
fn load(text: &str, format: Format) -> Result<LensSystem, PrescriptionError> {
    load_with(text, format, &LoadOptions::default())
}

fn load_with(
    text: &str,
    format: Format,
    options: &LoadOptions,
) -> Result<LensSystem, PrescriptionError> {
    let loaded = read_str(text, Some(Path::new(FILE)), format, options)?;
    LensSystem::new(loaded.prescription, &loaded.map)
}

fn error(text: &str, format: Format) -> PrescriptionError {
    match load(text, format) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e,
    }
}

/// Asserts where an error points: line, surface and field (None = not given).
fn assert_at(
    e: &PrescriptionError,
    line: Option<usize>,
    surface: Option<usize>,
    field: Option<&str>,
) {
    assert_eq!(e.location.file.as_deref(), Some(Path::new(FILE)), "{e}");
    assert_eq!(
        (
            e.location.line,
            e.location.surface,
            e.location.field.as_deref()
        ),
        (line, surface, field),
        "{e}"
    );
}

const PBRT_OK: &str = "# radius thickness index diameter\n50 5 1.5 20\n0 2 0 10\n-50 40 1 20\n";

#[test]
fn the_valid_base_file_loads() {
    load(PBRT_OK, Format::Pbrt).unwrap();
}

#[test]
fn empty_file() {
    for (text, format) in [
        ("", Format::Pbrt),
        ("# only a comment\n\n", Format::Pbrt),
        ("  \n", Format::Table),
        ("", Format::Ron),
        ("RDM N\nEPD 10\n", Format::CodeV),
        ("MODE SEQ\nSURF 0\nSURF 1\n", Format::Zemax),
    ] {
        let e = error(text, format);
        assert_eq!(e.problem, Problem::Empty, "{format}: {e}");
        assert_at(&e, None, None, None);
    }
}

#[test]
fn wrong_column_count() {
    let e = error("50 5 1.5 20\n0 2 0\n", Format::Pbrt);
    assert!(
        matches!(e.problem, Problem::WrongColumnCount { found: 3, .. }),
        "{e}"
    );
    assert_at(&e, Some(2), Some(2), None);
    let e = error("EPD 10\nS 0.02\n", Format::CodeV);
    assert!(
        matches!(e.problem, Problem::WrongColumnCount { found: 1, .. }),
        "{e}"
    );
    assert_at(&e, Some(2), Some(1), Some("S"));
}

#[test]
fn not_a_number() {
    let e = error("50 5 1.5 20\n0 2,5 0 10\n", Format::Pbrt);
    assert_eq!(e.problem, Problem::NotANumber { text: "2,5".into() });
    assert_at(&e, Some(2), Some(2), Some("thickness"));
    let e = error("MODE SEQ\nSURF 0\nSURF 1\n  CURV abc\n", Format::Zemax);
    assert_eq!(e.problem, Problem::NotANumber { text: "abc".into() });
    assert_at(&e, Some(4), Some(1), Some("CURV"));
}

#[test]
fn non_finite_number() {
    let e = error("50 5 1.5 20\n0 2 0 10\n-50 inf 1 20\n", Format::Pbrt);
    assert!(
        matches!(e.problem, Problem::NonFinite { value } if value.is_infinite()),
        "{e}"
    );
    assert_at(&e, Some(3), Some(3), Some("thickness"));
    let e = error("NaN 5 1.5 20\n", Format::Table);
    assert!(
        matches!(e.problem, Problem::NonFinite { value } if value.is_nan()),
        "{e}"
    );
    assert_at(&e, Some(1), Some(1), Some("radius"));
    // Non-finite values that RON can spell are caught by validation, at the surface's line.
    let ron = lensbake::prescription::formats::write_ron(
        &load(PBRT_OK, Format::Pbrt).unwrap().prescription,
    )
    .replacen("thickness: 2.0", "thickness: inf", 1);
    let e = error(&ron, Format::Ron);
    assert!(matches!(e.problem, Problem::NonFinite { .. }), "{e}");
    assert_eq!(
        (e.location.surface, e.location.field.as_deref()),
        (Some(2), Some("thickness"))
    );
    assert!(e.location.line.is_some());
}

#[test]
fn index_below_one() {
    let e = error("50 5 0.9 20\n0 2 0 10\n-50 40 1 20\n", Format::Pbrt);
    assert_eq!(e.problem, Problem::IndexBelowVacuum { index: 0.9 });
    assert_at(&e, Some(1), Some(1), Some("medium"));
}

/// An index past every optical material (an exponent gone wrong) is refused where it is
/// written, as a constant and as a model glass's nd; analyze had failed later on a
/// non-finite Seidel sum.
#[test]
fn index_above_the_limit() {
    let e = error("50 5 1e300 20\n0 2 0 10\n-50 40 1 20\n", Format::Pbrt);
    assert_eq!(e.problem, Problem::IndexAboveLimit { index: 1e300 });
    assert_at(&e, Some(1), Some(1), Some("medium"));
    // 10 itself passes (no material comes near it, but it is a number the trace holds).
    load("50 5 10 20\n0 2 0 10\n-50 40 1 20\n", Format::Pbrt).unwrap();
    let singlet = include_str!("../lenses/biconvex-singlet.ron");
    let text = singlet.replacen("medium: Index(1.5)", "medium: Model(nd: 11.0, vd: 60.0)", 1);
    assert_ne!(text, singlet);
    let e = error(&text, Format::Ron);
    assert_eq!(e.problem, Problem::IndexAboveLimit { index: 11.0 });
}

/// A model glass's Abbe number below 1 (but not 0, no dispersion) is refused at its medium: a
/// subnormal one had made the model's dispersion overflow and `lens check` print a NaN index.
#[test]
fn abbe_number_below_the_limit() {
    let singlet = include_str!("../lenses/biconvex-singlet.ron");
    let with_vd = |vd: &str| {
        let text = singlet.replacen(
            "medium: Index(1.5)",
            &format!("medium: Model(nd: 1.5311, vd: {vd})"),
            1,
        );
        assert_ne!(text, singlet);
        text
    };
    for (vd, value) in [("1e-320", 1e-320), ("0.5", 0.5), ("-20.0", -20.0)] {
        let e = error(&with_vd(vd), Format::Ron);
        assert_eq!(
            e.problem,
            Problem::AbbeNumberBelowLimit { vd: value },
            "{e}"
        );
        assert_eq!(
            (e.location.surface, e.location.field.as_deref()),
            (Some(1), Some("medium"))
        );
        assert!(e.location.line.is_some());
    }
    // No dispersion, and the smallest Abbe number allowed.
    for vd in ["0.0", "1.0"] {
        load(&with_vd(vd), Format::Ron).unwrap();
    }
}

#[test]
fn aperture_out_of_range() {
    let e = error("50 5 1.5 20\n0 2 0 0\n-50 40 1 20\n", Format::Pbrt);
    assert!(
        matches!(e.problem, Problem::OverLimit(LimitError::OutOfRange { value, .. }) if value == 0.0),
        "{e}"
    );
    assert_at(&e, Some(2), Some(2), Some("semi_aperture"));
    // Positive but below a nanometre (pbrt gives the diameter): a bake of it held NaN margins.
    let e = error("50 5 1.5 1e-300\n0 2 0 10\n-50 40 1 20\n", Format::Pbrt);
    assert!(
        matches!(e.problem, Problem::OverLimit(LimitError::OutOfRange { value, .. }) if value == 5e-301),
        "{e}"
    );
    assert_at(&e, Some(1), Some(1), Some("semi_aperture"));
}

/// A gap or decentre beyond the lens frame's +-1e9 mm is refused where the file states it: a
/// 1e300 mm gap made Seidel sums that could not be printed, a 1e300 mm `YDE` an infinite spot.
#[test]
fn lengths_beyond_the_lens_frame_are_refused_on_their_line() {
    let beyond = |e: &PrescriptionError, value: f64| {
        assert!(
            matches!(e.problem, Problem::OverLimit(LimitError::OutOfRange { value: v, .. }) if v == value),
            "{e}"
        );
    };
    let e = error("50 5 1.5 20\n0 1e300 0 10\n-50 40 1 20\n", Format::Pbrt);
    beyond(&e, 1e300);
    assert_at(&e, Some(2), Some(2), Some("thickness"));
    // 1e9 mm itself is a position the frame holds.
    load("50 5 1.5 20\n0 1e9 0 10\n-50 40 1 20\n", Format::Pbrt).unwrap();
    // The decentre's own line, not the line of the placement's first command (`REV`).
    let text = "S 50 5 N-BK7\nSTO\nS -50 20\nS 0 0\nREV\nXDE 1\nYDE -1e300\nS 0 10\n";
    let e = error(text, Format::CodeV);
    beyond(&e, -1e300);
    assert_eq!(
        (e.location.line, e.location.field.as_deref()),
        (Some(7), Some("YDE")),
        "{e}"
    );
}

#[test]
fn semi_aperture_larger_than_radius() {
    let e = error("50 5 1.5 20\n0 2 0 10\n-8 40 1 20\n", Format::Pbrt);
    assert_eq!(
        e.problem,
        Problem::ApertureExceedsRadius {
            semi_aperture: 10.0,
            radius: 8.0
        }
    );
    assert_at(&e, Some(3), Some(3), Some("semi_aperture"));
}

#[test]
fn surfaces_crossing() {
    // A 0.5 mm thick biconvex lens of 20 mm diameter: its faces cross at the rim.
    let e = error("50 0.5 1.5 20\n-50 2 1 20\n0 40 0 10\n", Format::Pbrt);
    assert!(
        matches!(e.problem, Problem::SurfacesCross { next: 2, .. }),
        "{e}"
    );
    assert_at(&e, Some(1), Some(1), Some("thickness"));
}

#[test]
fn no_stop() {
    let e = error("50 5 1.5 20\n-50 40 1 20\n", Format::Pbrt);
    assert_eq!(e.problem, Problem::NoStop);
    assert_at(&e, None, None, None);
}

#[test]
fn several_stops() {
    let e = error(
        "50 5 1.5 20\nN/A 2 1 10\n-50 4 1 20\n0 40 0 10\n",
        Format::Pbrt,
    );
    assert_eq!(
        e.problem,
        Problem::MultipleStops {
            surfaces: vec![2, 4]
        }
    );
    assert_at(&e, Some(4), Some(4), Some("stop"));
}

#[test]
fn unknown_glass() {
    let text = "RDM N\nS 0.02 5 NOSUCHGLASS\nCIR 10\nSTO\nS -0.02 40\nCIR 10\n";
    let e = error(text, Format::CodeV);
    assert!(
        matches!(&e.problem, Problem::UnknownGlass { name, .. } if name == "NOSUCHGLASS"),
        "{e}"
    );
    assert_at(&e, Some(2), Some(1), Some("medium"));
    // Without CIR the reader needs the index to derive apertures, and says so at the same line.
    let e = error(
        "RDM N\nS 0.02 5 NOSUCHGLASS\nSTO\nS -0.02 40\nEPD 10\n",
        Format::CodeV,
    );
    assert!(matches!(e.problem, Problem::UnknownGlass { .. }), "{e}");
    assert_at(&e, Some(2), Some(1), Some("medium"));
    // Close names are suggested.
    let e = error(
        "RDM N\nS 0.02 5 NBK8\nCIR 10\nSTO\nS -0.02 40\nCIR 10\n",
        Format::CodeV,
    );
    assert!(
        matches!(&e.problem, Problem::UnknownGlass { suggestions, .. } if suggestions.contains(&"N-BK7".to_string())),
        "{e}"
    );
}

#[test]
fn syntax_errors() {
    let e = error(
        "(\n  provenance: (title: \"x\"),\n  surfaces: [\n    ( shape: Plane,\n",
        Format::Ron,
    );
    assert!(matches!(e.problem, Problem::Syntax(_)), "{e}");
    assert_eq!(e.location.line, Some(4), "{e}");
    // The surface is found past non-ASCII text, brackets in strings and comments, and a
    // multi-byte char literal (the scan reads bytes).
    let e = error(
        "(\n  provenance: (title: \"Objectif \u{2014} f/2 (\u{00e9}tude) [1]\"),\n  \
         object_medium: Air, // ] ) \u{00e9}\n  surfaces: [\n    /* ( [ */ (shape: Plane, \
         thickness: 1.0, medium: Air, semi_aperture: 5.0, stop: None),\n    (shape: 'Ω',\n",
        Format::Ron,
    );
    assert!(matches!(e.problem, Problem::Syntax(_)), "{e}");
    assert_eq!(
        (e.location.line, e.location.surface),
        (Some(6), Some(2)),
        "{e}"
    );
    let e = error("MODE SEQ\nSURF 0\nSURF 2\n", Format::Zemax);
    assert!(matches!(e.problem, Problem::Syntax(_)), "{e}");
    assert_at(&e, Some(3), None, Some("SURF"));
    let e = error("MODE SEQ\nWAVM 99999999999 0.55 1\n", Format::Zemax);
    assert!(matches!(e.problem, Problem::Syntax(_)), "{e}");
    assert_at(&e, Some(2), None, Some("WAVM"));
    // Counts that would size the field and wavelength tables are bounded before anything is
    // allocated (u64::MAX fields panicked on capacity overflow, u32::MAX aborted).
    for ftyp in [
        "FTYP 0 0 18446744073709551615 3 0 0 0",
        "FTYP 0 0 3 4294967295 0 0 0",
    ] {
        let e = error(&format!("MODE SEQ\n{ftyp}\n"), Format::Zemax);
        assert!(e.to_string().contains("OpticStudio holds at most"), "{e}");
        assert_at(&e, Some(2), None, Some("FTYP"));
    }
    let e = error("MODE SEQ\nMNUM 3 4\n", Format::Zemax);
    assert!(
        e.to_string()
            .contains("the active configuration 4 is not one of the file's 3"),
        "{e}"
    );
    assert_at(&e, Some(2), None, Some("MNUM"));
    let e = error("STO\nS 1 1\n", Format::CodeV);
    assert!(matches!(e.problem, Problem::Syntax(_)), "{e}");
    assert_at(&e, Some(1), None, Some("STO"));
}

#[test]
fn unsupported_input_is_refused_by_name() {
    let cases = [
        ("EPD 10\nS 0.02 5 N-BK7\nXDE 1.0\n", Format::CodeV, 3, "XDE"),
        // CIR EDG (the mechanical edge) clips nothing and is skipped; an obscuration is read
        // (tests/mirrors.rs), but not with a second radius.
        (
            "EPD 10\nS 0.02 5\nCIR OBS 2 3\n",
            Format::CodeV,
            3,
            "CIR OBS",
        ),
        ("SO 0.1 100\n", Format::CodeV, 1, "curved object"),
        // A coordinate break that tilts the lens after it by 2 degrees.
        (
            "MODE SEQ\nSURF 0\nSURF 1\n  TYPE COORDBRK\n  PARM 3 2\nSURF 2\n  CURV 0.02\n  \
             DISZ 5\n  GLAS N-BK7\n  STOP\nSURF 3\n",
            Format::Zemax,
            6,
            "tilted 2.000000 deg to the axis (moved by `TYPE COORDBRK`)",
        ),
        (
            "MODE SEQ\nSURF 0\nSURF 1\n  OBSC 1 2\n",
            Format::Zemax,
            4,
            "annular obscuration",
        ),
        ("MODE NSC\n", Format::Zemax, 1, "NSC"),
        // An unknown keyword in a surface (one in the header is skipped with a note).
        (
            "MODE SEQ\nSURF 0\nSURF 1\n  FOOB 1\n",
            Format::Zemax,
            4,
            "FOOB",
        ),
    ];
    for (text, format, line, what) in cases {
        let e = read_str(text, Some(Path::new(FILE)), format, &LoadOptions::default()).unwrap_err();
        let message = match &e.problem {
            Problem::Unsupported(message) => message,
            // A lens off the axis is unsupported everywhere but in the 3-D trace.
            Problem::NotRotationallySymmetric { offence, .. } => offence,
            other => panic!("{other}"),
        };
        assert!(message.contains(what), "{e}");
        assert_eq!(e.location.line, Some(line), "{e}");
    }
}

#[test]
fn first_axial_position_not_zero() {
    let options = LoadOptions {
        pbrt_thickness: PbrtThickness::FromPrevious,
        ..LoadOptions::default()
    };
    let e = read_file(&lens_file("dgauss.50mm.dat"), &options).unwrap_err();
    assert_eq!(
        e.problem,
        Problem::FirstAxialPositionNotZero { value: 3.76 }
    );
    assert_eq!(
        (
            e.location.line,
            e.location.surface,
            e.location.field.as_deref()
        ),
        (Some(6), Some(1), Some("thickness"))
    );
    // The option belongs to pbrt files only; elsewhere it is refused, not ignored.
    let e = load_with("50 5 1.5 20\n", Format::Table, &options).unwrap_err();
    assert!(matches!(e.problem, Problem::Unsupported(_)), "{e}");
}

#[test]
fn unknown_format_and_io() {
    let unknown = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join("lens.xyz");
    std::fs::write(&unknown, "50 5 1.5 20\n").unwrap();
    let e = read_file(&unknown, &LoadOptions::default()).unwrap_err();
    assert_eq!(
        e.problem,
        Problem::UnknownFormat {
            extension: Some("xyz".into())
        }
    );
    assert_eq!(e.location.file, Some(unknown));
    // A file that is not there is that, whatever its name says about a format.
    let missing = read_file(Path::new("missing.xyz"), &LoadOptions::default()).unwrap_err();
    assert!(matches!(missing.problem, Problem::Io(_)), "{missing}");
    let missing = lens_file("no-such-file.dat");
    let e = read_file(&missing, &LoadOptions::default()).unwrap_err();
    assert!(matches!(e.problem, Problem::Io(_)), "{e}");
    assert_eq!(*e.location, Location::file(&missing));
}

/// A lens file over the lens-file limit is refused from its size, before it is read (the file
/// here is sparse: 17 MiB long, no bytes on disk); one at the limit is read and then judged on
/// its text.
#[test]
fn an_oversized_lens_file_is_refused_before_it_is_read() {
    let limit = lensbake::limits::MAX_LENS_FILE_BYTES;
    let dir = PathBuf::from(env!("CARGO_TARGET_TMPDIR"));
    for (name, length) in [("oversized.zmx", limit + 1), ("at-limit.zmx", limit)] {
        let path = dir.join(name);
        let file = std::fs::File::create(&path).unwrap();
        file.set_len(length).unwrap();
        drop(file);
        let e = read_file(&path, &LoadOptions::default()).unwrap_err();
        assert_eq!(*e.location, Location::file(&path));
        let refused_by_size = matches!(&e.problem, Problem::Io(message)
            if message.contains(&format!("{length} bytes, over the input limit of {limit} bytes")));
        assert_eq!(refused_by_size, length > limit, "{name}: {e}");
        std::fs::remove_file(&path).unwrap();
    }
}

#[test]
fn not_text() {
    let e = read_bytes(
        b"50 5 1.5 20\n0 2 \xff\xfe 10\n",
        Some(Path::new(FILE)),
        Format::Pbrt,
        &LoadOptions::default(),
    )
    .unwrap_err();
    assert_eq!(e.problem, Problem::NotText { byte_offset: 16 });
    assert_at(&e, Some(2), None, None);
}

#[test]
fn apertures_that_cannot_be_derived() {
    let e = error(
        "RDM N\nS 0.02 5 517000.6420\nSTO\nS -0.02 40\n",
        Format::CodeV,
    );
    assert!(
        matches!(e.problem, Problem::CannotDeriveApertures { .. }),
        "{e}"
    );
    assert_at(&e, Some(2), Some(1), Some("semi_aperture"));
    let e = error(
        "RDM N\nEPD 10\nYOB 0 10\nS 0.02 5\nSTO\nS -0.02 40\n",
        Format::CodeV,
    );
    assert!(
        matches!(&e.problem, Problem::CannotDeriveApertures { reason } if reason.contains("object heights")),
        "{e}"
    );
    // A floating aperture with a stop of no stated size (a file DeepLens wrote): the message
    // says what to add.
    let e = error(
        "MODE SEQ\nFLOA\nWAVM 1 0.55 1\nSURF 0\n  DISZ INFINITY\nSURF 1\n  CURV 0.02\n  \
         DISZ 5\n  GLAS N-BK7\n  DIAM 10\nSURF 2\n  STOP\n  DISZ 5\nSURF 3\n  CURV -0.02\n  \
         DISZ 40\n  DIAM 10\nSURF 4\n  DISZ 0\n",
        Format::Zemax,
    );
    assert!(
        matches!(&e.problem, Problem::CannotDeriveApertures { reason }
            if reason.contains("stop has no size") && reason.contains("DIAM")),
        "{e}"
    );
}

#[test]
fn model_errors_that_only_ron_can_express() {
    let base = lensbake::prescription::formats::write_ron(
        &load(PBRT_OK, Format::Pbrt).unwrap().prescription,
    );
    let asphere = base.replacen(
        "shape: Sphere(\n                curvature: 0.02,\n            )",
        "shape: EvenAsphere(curvature: 0.02, conic: 0.0, coefficients: [0,0,0,0,0,0,0,0,0,0,1e-30])",
        1,
    );
    assert_ne!(asphere, base, "the RON layout changed; update this test");
    let e = error(&asphere, Format::Ron);
    assert_eq!(e.problem, Problem::TooManyAsphereTerms { found: 11 });
    let first_surface_line = asphere
        .lines()
        .position(|l| l.trim() == "surfaces: [")
        .unwrap()
        + 2;
    assert_eq!(
        (e.location.surface, e.location.line),
        (Some(1), Some(first_surface_line)),
        "{e}"
    );
    let conic = base.replacen(
        "shape: Sphere(\n                curvature: 0.02,\n            )",
        "shape: Conic(curvature: 0.02, conic: 50.0)",
        1,
    );
    let e = error(&conic, Format::Ron);
    assert!(
        matches!(e.problem, Problem::ApertureExceedsConic { .. }),
        "{e}"
    );
    let blades = base.replacen(
        "stop: Some(Circle)",
        "stop: Some(Blades(count: 2, rotation_deg: 0.0, blade_curvature: 0.0))",
        1,
    );
    assert_ne!(blades, base, "the RON layout changed; update this test");
    let e = error(&blades, Format::Ron);
    assert_eq!(e.problem, Problem::TooFewBlades { count: 2 });
    assert_eq!(e.location.surface, Some(2));
    let bent = base.replacen(
        "stop: Some(Circle)",
        "stop: Some(Blades(count: 6, rotation_deg: 0.0, blade_curvature: 1.5))",
        1,
    );
    let e = error(&bent, Format::Ron);
    assert_eq!(e.problem, Problem::BladeCurvatureOutOfRange { value: 1.5 });
    assert_eq!(e.location.field.as_deref(), Some("stop"));
}

/// A file's claims are refused with the rule they break, not an interval of f64 extremes
/// (`outside [2.2250738585072014e-308, 1.7976931348623157e308]`).
#[test]
fn claims_that_cannot_hold_name_the_rule() {
    let base = include_str!("../lenses/dgauss-50mm.ron");
    for (claim, needle) in [
        (
            "claimed_f_number: Some(-2.0)",
            "must be positive and finite, got -2",
        ),
        (
            "claimed_f_number: Some(0.0)",
            "must be positive and finite, got 0",
        ),
        // Slower than any command takes: its pupil had hung `report` in the PSF plot.
        ("claimed_f_number: Some(1e300)", "1000"),
    ] {
        let text = base.replace("claimed_f_number: Some(2.0)", claim);
        assert_ne!(text, base);
        let e = error(&text, Format::Ron);
        let message = e.to_string();
        assert!(message.contains(needle), "{message}");
        assert!(
            !message.contains("e308") && !message.contains("e-308"),
            "{message}"
        );
        assert_eq!(
            e.location.field.as_deref(),
            Some("provenance.claimed_f_number")
        );
    }
}

/// An aperture a file states must be one: a pupil diameter, f-number or numerical aperture of 0
/// or below is refused on its line (before, the design conditions dropped it without a word and
/// took the stop's own).
#[test]
fn stated_apertures_must_be_positive() {
    for (text, format, line, field) in [
        ("MODE SEQ\nENPD -10\n", Format::Zemax, 2, "ENPD"),
        ("MODE SEQ\nFNUM 0 0\n", Format::Zemax, 2, "FNUM"),
        ("EPD 0\n", Format::CodeV, 1, "EPD"),
        ("DIM M\nFNO -2\n", Format::CodeV, 2, "FNO"),
    ] {
        let e = error(text, format);
        assert!(
            e.to_string().contains("must be positive and finite"),
            "{text}: {e}"
        );
        assert_at(&e, Some(line), None, Some(field));
    }
}

/// A wavelength outside what lensbake traces is refused on its line (WAVM in Zemax, WL in CODE
/// V); validation saw only the design wavelength, and named an internal field with no line.
#[test]
fn wavelengths_are_located_on_their_line() {
    let base = include_str!("../examples/lenses/cooke_triplet.zmx");
    // The design wavelength (PWAV 2) on line 22, another one in use on line 21.
    for (written, zero, line) in [
        ("WAVM 2 0.55 1", "WAVM 2 0 1", 22),
        ("WAVM 1 0.48 1", "WAVM 1 0 1", 21),
    ] {
        let text = base.replace(written, zero);
        assert_ne!(text, base);
        let e = error(&text, Format::Zemax);
        assert!(e.to_string().contains("the wavelength (nm) is 0"), "{e}");
        assert_at(&e, Some(line), None, Some("WAVM"));
    }
    // CODE V lists its wavelengths (nm) on one WL line.
    let e = error("DIM M\nWL 587.56 0\n", Format::CodeV);
    assert!(e.to_string().contains("the wavelength (nm) is 0"), "{e}");
    assert_at(&e, Some(2), None, Some("WL"));
}

/// Zemax writes a surface's fields one keyword to a line: a problem found after reading names
/// the line of the keyword that set the field (GLAS, DISZ, DIAM, ...), not the surface's SURF
/// line.
#[test]
fn zemax_fields_are_located_on_their_keyword_line() {
    let base = include_str!("../examples/lenses/cooke_triplet.zmx");
    let cases = [
        // SURF 1's glass, on line 41, unknown and without the nd and Vd that would make it a
        // model glass.
        (
            "  GLAS SK16 1 0 1.620408 60.32",
            "  GLAS NOSUCH 1 0 0 0",
            41,
            1,
            "GLAS",
        ),
        // SURF 2's gap to surface 3, on line 49, made to cross it.
        ("  DISZ 6.00755", "  DISZ -6.00755", 49, 2, "DISZ"),
        // SURF 1's semi-aperture, on line 42, made larger than its 22 mm radius.
        ("  DIAM 8.84 1", "  DIAM 30 1", 42, 1, "DIAM"),
    ];
    for (written, changed, line, surface, keyword) in cases {
        let text = base.replacen(written, changed, 1);
        assert_ne!(text, base);
        let e = error(&text, Format::Zemax);
        assert_at(&e, Some(line), Some(surface), Some(keyword));
    }
}

/// A RON file's surfaces are counted before RON builds them: one over the limit is refused on
/// the line of the first surface too many, whatever follows it (here, a syntax error RON would
/// otherwise report after parsing everything before it).
#[test]
fn ron_surfaces_over_the_limit_are_refused_before_parsing() {
    let surface = "(shape: Plane, thickness: 1.0, medium: Air, semi_aperture: 5.0, stop: None),\n";
    let over = lensbake::limits::MAX_SURFACES as usize + 1;
    let text = format!(
        "(\n provenance: (title: \"many\"),\n object_medium: Air,\n surfaces: [\n{}\n !! ],\n)\n",
        surface.repeat(over)
    );
    let e = error(&text, Format::Ron);
    assert!(
        matches!(e.problem, Problem::OverLimit(LimitError::OverLimit { .. })),
        "{e}"
    );
    // Lines 1-4 are the header; surface k (1-based) starts on line 4 + k.
    assert_at(&e, Some(4 + over), None, None);
}

/// CODE V sets a surface's fields on the `S` line or on command lines after it: a problem found
/// after reading names the command's line (CIR, GLA, K, ...) where the file wrote one.
#[test]
fn code_v_fields_are_located_on_their_command_line() {
    // Surface 2's clear aperture (line 6) beyond its 50 mm radius: the curvature on line 5
    // contradicts the CIR the file states, so the error points at the value and names the CIR.
    let e = error(
        "RDM N\nS 0.02 5 N-BK7\nCIR 10\nSTO\nS -0.02 40\nCIR 60\n",
        Format::CodeV,
    );
    assert_at(&e, Some(5), Some(2), Some("curvature"));
    assert!(e.to_string().contains("clear aperture of 60 (CIR)"), "{e}");
    // Surface 1's glass given on its own line (line 3); the mechanical edge (CIR EDG) on line 4
    // does not take the clear aperture's place.
    let e = error(
        "RDM N\nS 0.02 5\nGLA NOSUCHGLASS\nCIR EDG 12\nCIR 10\nSTO\nS -0.02 40\nCIR 10\n",
        Format::CodeV,
    );
    assert!(matches!(e.problem, Problem::UnknownGlass { .. }), "{e}");
    assert_at(&e, Some(3), Some(1), Some("GLA"));
    // On the S line itself, the S line.
    let e = error(
        "RDM N\nS 0.02 5 NOSUCHGLASS\nCIR 10\nSTO\nS -0.02 40\nCIR 10\n",
        Format::CodeV,
    );
    assert_at(&e, Some(2), Some(1), Some("medium"));
}

/// A RON file's stated wavelengths, weights, primary wavelength and field points are checked as
/// the Zemax and CODE V readers check theirs (a RON lens drew a wavelength of -480 nm, and a
/// primary past the list fell back to the first wavelength without a word).
#[test]
fn stated_spectrum_and_fields_of_a_ron_file_are_checked() {
    let base = include_str!("../lenses/cooke-triplet.ron");
    load(base, Format::Ron).unwrap();
    let edit = |from: &str, to: &str| {
        let text = base.replacen(from, to, 1);
        assert_ne!(text, base, "the RON layout changed; update this test");
        error(&text, Format::Ron)
    };
    let field = |e: &PrescriptionError| e.location.field.clone().unwrap_or_default();
    let e = edit("                480.0,", "                -480.0,");
    assert!(
        matches!(e.problem, Problem::OverLimit(LimitError::OutOfRange { value, .. }) if value == -480.0),
        "{e}"
    );
    assert_eq!(field(&e), "provenance.conditions.wavelengths_nm");
    let e = edit("primary: Some(1)", "primary: Some(3)");
    assert_eq!(field(&e), "provenance.conditions.primary", "{e}");
    let e = edit(
        "wavelength_weights: [\n                1.0,",
        "wavelength_weights: [\n                -1.0,",
    );
    assert_eq!(field(&e), "provenance.conditions.wavelength_weights", "{e}");
    let e = edit("weights: [\n                    1.0,\n", "weights: [\n");
    assert_eq!(field(&e), "provenance.conditions.fields.weights", "{e}");
    assert!(e.to_string().contains("2 weights for 3 entries"), "{e}");
    let e = edit("x: [\n                    0.0,\n", "x: [\n");
    assert_eq!(field(&e), "provenance.conditions.fields", "{e}");
}
