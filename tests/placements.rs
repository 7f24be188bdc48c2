//! Decentres, tilts and coordinate breaks (Zemax `COORDBRK`, CODE V `XDE`..`CDE` with `DAR`,
//! `BEN`, `REV`): a lens folded by plane mirrors reads as the straight lens it folds, surface for
//! surface; decentres that return or move only planes between equal media change nothing; and a
//! lens that is not rotationally symmetric is refused with the surface, line and keyword.

use lensbake::analysis::{AnalyzeOptions, analyze};
use lensbake::prescription::formats::{Format, LoadNote, LoadOptions, Loaded, read_str};
use lensbake::prescription::{Medium, PrescriptionError};
use lensbake::system::LensSystem;
use std::path::Path;

const FILE: &str = "folded";

fn read(text: &str, format: Format) -> Result<Loaded, PrescriptionError> {
    read_str(text, Some(Path::new(FILE)), format, &LoadOptions::default())
}

fn codev(body: &str) -> Result<Loaded, PrescriptionError> {
    let image = if body.contains("SI ") { "" } else { "SI 0 0\n" };
    read(
        &format!("RDM Y\nEPD 10\nYAN 0 3 5\nWL 587.5618\nSO 0 1e11\n{body}{image}"),
        Format::CodeV,
    )
}

/// Two loaded lenses are the same lens: every surface to 1e-12 (mm, 1/mm), the same media, and
/// so the same first-order data and Seidel sums.
fn assert_same_lens(a: &Loaded, b: &Loaded) {
    let (pa, pb) = (&a.prescription, &b.prescription);
    assert_eq!(pa.surfaces.len(), pb.surfaces.len());
    for (i, (sa, sb)) in pa.surfaces.iter().zip(&pb.surfaces).enumerate() {
        let n = i + 1;
        assert!(
            (sa.thickness - sb.thickness).abs() < 1e-12,
            "surface {n} thickness {} vs {}",
            sa.thickness,
            sb.thickness
        );
        assert!(
            (sa.shape.curvature() - sb.shape.curvature()).abs() < 1e-12,
            "surface {n} curvature {} vs {}",
            sa.shape.curvature(),
            sb.shape.curvature()
        );
        assert_eq!(sa.shape.conic(), sb.shape.conic(), "surface {n}");
        assert_eq!(sa.medium, sb.medium, "surface {n}");
        assert_eq!(sa.stop, sb.stop, "surface {n}");
        assert!(
            (sa.semi_aperture - sb.semi_aperture).abs() < 1e-9,
            "surface {n} aperture {} vs {}",
            sa.semi_aperture,
            sb.semi_aperture
        );
    }
    let analysed = |l: &Loaded| {
        let system = LensSystem::new(l.prescription.clone(), &l.map).unwrap();
        analyze(&system, &AnalyzeOptions::default()).unwrap()
    };
    let (x, y) = (analysed(a), analysed(b));
    assert!((x.first_order.efl - y.first_order.efl).abs() < 1e-12 * x.first_order.efl.abs());
    assert!((x.first_order.bfl - y.first_order.bfl).abs() < 1e-11);
    let (sx, sy) = (x.seidel.sums.as_array(), y.seidel.sums.as_array());
    let scale = sx.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for (u, v) in sx.iter().zip(&sy) {
        assert!((u - v).abs() < 1e-12 * scale, "Seidel {sx:?} vs {sy:?}");
    }
}

fn folds(loaded: &Loaded) -> Vec<usize> {
    loaded
        .notes
        .iter()
        .find_map(|n| match n {
            LoadNote::Centred { folds } => Some(folds.clone()),
            _ => None,
        })
        .expect("a note says the lens was centred")
}

/// A singlet, a plane 20 mm behind it, a second singlet: the straight lens every fold below
/// must read as.
const STRAIGHT: &str = "S 50 5 N-BK7\nSTO\nS -50 20\nS 0 15\nS 80 4 N-F2\nS 200 30\n";

/// CODE V writes what follows a mirror in the frame the bend leaves: thicknesses and radii
/// change sign while light travels back along its z. Every single-axis fold, any angle, either
/// sense, in the y-z or x-z plane, is the straight lens.
#[test]
fn a_codev_fold_mirror_with_ben_reads_as_the_straight_lens() {
    let straight = codev(STRAIGHT).unwrap();
    for tilt in ["ADE 45", "ADE -45", "ADE 30", "BDE 45", "BDE -60", "ADE 10"] {
        let folded = codev(&format!(
            "S 50 5 N-BK7\nSTO\nS -50 20\nS 0 -15 REFL\n{tilt}\nBEN\nS -80 -4 N-F2\nS -200 -30\n"
        ))
        .unwrap_or_else(|e| panic!("{tilt}: {e}"));
        assert_eq!(folds(&folded), [3], "{tilt}");
        // The mirror became a plane in the air it was met in.
        assert_eq!(folded.prescription.surfaces[2].medium, Medium::Air);
        assert_same_lens(&folded, &straight);
    }
}

/// Two folds (a periscope and a right-angle turn) and a normal-incidence mirror: the folds
/// unfold, the mirror at normal incidence stays a mirror.
#[test]
fn two_folds_unfold_and_a_mirror_at_normal_incidence_stays() {
    let periscope = codev(
        "S 50 5 N-BK7\nSTO\nS -50 10\nS 0 -5 REFL\nADE 45\nBEN\nS 0 5 REFL\nADE -45\nBEN\n\
         S 80 4 N-F2\nS 200 30\n",
    )
    .unwrap();
    assert_eq!(folds(&periscope), [3, 4]);
    assert_eq!(periscope.prescription.surfaces.len(), 6);
    // Unfolded, the two mirrors are planes 5 mm apart, and the second singlet 5 mm further.
    let p = &periscope.prescription.surfaces;
    for (i, t) in [(1, 10.0), (2, 5.0), (3, 5.0)] {
        assert!((p[i].thickness - t).abs() < 1e-12, "{}", p[i].thickness);
    }
    let unfolded =
        codev("S 50 5 N-BK7\nSTO\nS -50 10\nS 0 5\nS 0 5\nS 80 4 N-F2\nS 200 30\n").unwrap();
    assert_same_lens(&periscope, &unfolded);

    let back = codev("S 50 5 N-BK7\nSTO\nS -50 20\nS -400 -30 REFL\nCDE 30\n").unwrap();
    assert!(
        folds(&back).is_empty(),
        "a mirror turned about its own axis is no fold"
    );
    assert_eq!(back.prescription.surfaces[2].medium, Medium::Mirror);
    assert_eq!(
        back.prescription.surfaces[2].shape.curvature(),
        -1.0 / 400.0
    );

    // A fold after that mirror becomes a plane in the air light travels in, not a mirror.
    let after_mirror =
        codev("S 50 5 N-BK7\nSTO\nS -50 20\nS -400 -15 REFL\nS 0 10 REFL\nADE 45\nBEN\n").unwrap();
    assert_eq!(folds(&after_mirror), [4]);
    let media: Vec<&Medium> = after_mirror
        .prescription
        .surfaces
        .iter()
        .map(|s| &s.medium)
        .collect();
    assert_eq!(media[2..], [&Medium::Mirror, &Medium::Air]);
}

/// Zemax writes a fold as a coordinate break, the mirror, a second break with the same tilt
/// (often a pickup, PPAR), then negative thicknesses and radii. Order flags and decentres that
/// a later break undoes (order 1, values negated) leave the lens as it was.
/// A Zemax file of `surfaces` (the text after each `SURF n`), behind an object at infinity and
/// before a plane image: ENPD 10, fields 0, 3 and 5 degrees, the d line.
fn zemax_lens(surfaces: &[&str]) -> Result<Loaded, PrescriptionError> {
    let mut text = String::from(
        "MODE SEQ\nUNIT MM X W X CM MR CPMM\nENPD 10\nGCAT SCHOTT\nFTYP 0 0 3 1 0 0 0\n\
         XFLN 0 0 0\nYFLN 0 3 5\nWAVM 1 0.5875618 1\nPWAV 1\n\
         SURF 0\n  TYPE STANDARD\n  CURV 0\n  DISZ INFINITY\n",
    );
    for (i, body) in surfaces
        .iter()
        .chain(&["TYPE STANDARD\n  CURV 0\n  DISZ 0"])
        .enumerate()
    {
        text.push_str(&format!("SURF {}\n  {body}\n", i + 1));
    }
    read(&text, Format::Zemax)
}

fn zemax_surface(curvature: &str, thickness: &str, glass: &str) -> String {
    format!("TYPE STANDARD\n  CURV {curvature}\n  DISZ {thickness}{glass}")
}

const BK7: &str = "\n  GLAS N-BK7 0 0 1.5168 64.17 0 0 0 0 0 0";
const F2: &str = "\n  GLAS N-F2 0 0 1.62 36.4 0 0 0 0 0 0";
const ZEMAX_MIRROR: &str =
    "TYPE STANDARD\n  CURV 0\n  DISZ 0\n  GLAS MIRROR 0 0 1.5 40 0 0 0 0 0 0";

/// A Zemax coordinate break: PARM 1..6 (decentre x, y, tilt about x, y, z, order) and DISZ.
fn coordinate_break(parms: [f64; 6], thickness: f64) -> String {
    let mut b = String::from("TYPE COORDBRK");
    for (k, v) in parms.iter().enumerate() {
        b.push_str(&format!("\n  PARM {} {v}", k + 1));
    }
    b + &format!("\n  DISZ {thickness}")
}

/// OpticStudio's DIAM records the beam's extent and clips no ray, so a fold mirror moved within
/// its own plane (along x, which a tilt about x leaves in the plane), whose DIAM circle then lies
/// off the beam's axis, is still the fold: its
/// aperture is derived as for a surface without one. A clear aperture (CLAP) there would clip,
/// off the axis, and is refused.
#[test]
fn a_fold_mirrors_envelope_off_the_axis_is_derived_again() {
    let first = zemax_surface("0.02", "5", BK7) + "\n  STOP";
    let second = zemax_surface("-0.02", "20", "");
    let folded = |shift: f64, mirror_aperture: &str| {
        zemax_lens(&[
            &first,
            &second,
            &coordinate_break([0.0, 0.0, 45.0, 0.0, 0.0, 0.0], 0.0),
            &coordinate_break([shift, 0.0, 0.0, 0.0, 0.0, 0.0], 0.0),
            &format!("{ZEMAX_MIRROR}{mirror_aperture}"),
            &coordinate_break([-shift, 0.0, 0.0, 0.0, 0.0, 0.0], 0.0),
            &coordinate_break([0.0, 0.0, 45.0, 0.0, 0.0, 0.0], -15.0),
            &zemax_surface("-0.0125", "-4", F2),
            &zemax_surface("-0.005", "-30", ""),
        ])
    };
    let centred = folded(0.0, "").unwrap();
    let shifted = folded(2.0, "\n  DIAM 12 1 0 0 1 \"\"").unwrap();
    assert_eq!(folds(&shifted), [5]);
    assert_same_lens(&shifted, &centred);
    let mirror = |l: &Loaded| l.prescription.surfaces[4].semi_aperture;
    assert!((mirror(&shifted) - mirror(&centred)).abs() < 1e-12);
    let e = folded(2.0, "\n  CLAP 0 12").unwrap_err();
    assert!(
        e.to_string()
            .contains("fold mirror whose stated clear aperture is centred 2.000000 mm"),
        "{e}"
    );
}

#[test]
fn zemax_coordinate_breaks_fold_and_undo() {
    let zemax = |surfaces: &[&str]| zemax_lens(surfaces).unwrap_or_else(|e| panic!("{e}"));
    let (bk7, f2) = (BK7, F2);
    let first = zemax_surface("0.02", "5", bk7) + "\n  STOP";
    let second = zemax_surface("-0.02", "20", "");
    let lens = zemax_surface;
    let breaker = coordinate_break;
    let mirror = ZEMAX_MIRROR;

    let straight = zemax(&[
        &first,
        &second,
        "TYPE STANDARD\n  CURV 0\n  DISZ 0",
        "TYPE STANDARD\n  CURV 0\n  DISZ 0",
        "TYPE STANDARD\n  CURV 0\n  DISZ 15",
        &lens("0.0125", "4", f2),
        &lens("0.005", "30", ""),
    ]);
    for angle in [45.0, -45.0, 22.5] {
        let folded = zemax(&[
            &first,
            &second,
            &breaker([0.0, 0.0, angle, 0.0, 0.0, 0.0], 0.0),
            mirror,
            &breaker([0.0; 6], -15.0).replace("PARM 3 0", "PARM 3 0\n  PPAR 3 3 1 0 0"),
            &lens("-0.0125", "-4", f2),
            &lens("-0.005", "-30", ""),
        ]);
        assert_eq!(folds(&folded), [4], "{angle}");
        assert_same_lens(&folded, &straight);
    }

    // A break with all three tilts and a decentre, undone by its inverse (order 1, values
    // negated): the frames compose to the identity, whatever the angles.
    let v = [1.5, -2.0, 7.0, -11.0, 23.0];
    let there = breaker([v[0], v[1], v[2], v[3], v[4], 0.0], 0.0);
    let back = breaker([-v[0], -v[1], -v[2], -v[3], -v[4], 1.0], 15.0);
    let undone = zemax(&[
        &first,
        &second,
        "TYPE STANDARD\n  CURV 0\n  DISZ 0",
        &there,
        &back,
        &lens("0.0125", "4", f2),
        &lens("0.005", "30", ""),
    ]);
    assert!(folds(&undone).is_empty());
    assert_same_lens(&undone, &straight);

    // The same break undone with order 0 is no inverse: the second singlet is tilted.
    let wrong = breaker([-v[0], -v[1], -v[2], -v[3], -v[4], 0.0], 15.0);
    let mut text = String::new();
    for (i, body) in [
        &first,
        &second,
        "TYPE STANDARD\n  CURV 0\n  DISZ 0",
        &there,
        &wrong,
    ]
    .iter()
    .enumerate()
    {
        text.push_str(&format!("SURF {}\n  {body}\n", i + 1));
    }
    let e = read(
        &format!(
            "MODE SEQ\nENPD 10\nFTYP 0 0 1 1 0 0 0\nYFLN 0\nWAVM 1 0.5875618 1\n\
             SURF 0\n  TYPE STANDARD\n  CURV 0\n  DISZ INFINITY\n{text}\
             SURF 6\n  TYPE STANDARD\n  CURV 0.0125\n  DISZ 4\n  GLAS N-F2 0 0 1.62 36.4 0 0 0 0 0 0\n\
             SURF 7\n  TYPE STANDARD\n  CURV 0\n  DISZ 0\n"
        ),
        Format::Zemax,
    )
    .unwrap_err();
    assert_eq!(e.location.surface, Some(6), "{e}");
    assert_eq!(e.location.field.as_deref(), Some("TYPE COORDBRK"), "{e}");
    assert!(e.to_string().contains("tilted"), "{e}");
}

/// CODE V's decentre-and-return (DAR) and a basic decentre reversed (REV) right after it move
/// only the surface they sit on; on a plane in air they change nothing.
#[test]
fn codev_decentres_that_return_change_nothing() {
    let straight = codev(STRAIGHT).unwrap();
    let returned = codev(
        "S 50 5 N-BK7\nSTO\nS -50 20\nS 0 0\nXDE 1.5\nYDE -2\nADE 7\nBDE -11\nCDE 23\n\
         S 0 15\nREV\nXDE 1.5\nYDE -2\nADE 7\nBDE -11\nCDE 23\nS 80 4 N-F2\nS 200 30\n",
    );
    // Two planes replace the straight lens's one: compare with that lens.
    let reference = codev("S 50 5 N-BK7\nSTO\nS -50 20\nS 0 0\nS 0 15\nS 80 4 N-F2\nS 200 30\n");
    assert_same_lens(&returned.unwrap(), &reference.unwrap());
    let dar =
        codev("S 50 5 N-BK7\nSTO\nS -50 20\nS 0 15\nYDE 3\nADE 12\nDAR\nS 80 4 N-F2\nS 200 30\n")
            .unwrap();
    assert!(folds(&dar).is_empty());
    assert_same_lens(&dar, &straight);
}

/// What no centred lens describes is refused where the file says it: a tilted or decentred
/// lens surface or image plane at the line of its own decentre; a surface that a fold sent off
/// the reflected axis at its own line, naming the keyword that moved it.
#[test]
fn lenses_off_the_axis_are_refused_with_surface_line_and_keyword() {
    let cases = [
        (
            "S 50 5 N-BK7\nADE 0.5\nSTO\nS -50 50\n",
            7,
            Some(1),
            "ADE",
            "tilted 0.500000 deg",
        ),
        (
            "S 50 5 N-BK7\nSTO\nS -50 50\nYDE 0.1\n",
            9,
            Some(2),
            "YDE",
            "decentred 0.100000 mm",
        ),
        (
            "S 50 5 N-BK7\nSTO\nS -50 50\nSI 0 0\nADE 2\n",
            10,
            None,
            "ADE",
            "image plane is tilted",
        ),
        (
            "S 50 5 N-BK7\nSTO\nS -50 20\nS 0 -15 REFL\nADE 45\nS -80 -4 N-F2\nS -200 -30\n",
            11,
            Some(4),
            "ADE",
            "tilted",
        ),
    ];
    let overflow = codev("S 50 5 N-BK7\nCDE 10\nSTO\nS -50 1e308\nS 0 1e308\n").unwrap_err();
    assert!(
        overflow.to_string().contains("beyond any finite position"),
        "{overflow}"
    );
    for (body, line, surface, field, says) in cases {
        let e = codev(body).unwrap_err();
        assert_eq!(e.location.line, Some(line), "{e}");
        assert_eq!(e.location.surface, surface, "{e}");
        assert_eq!(e.location.field.as_deref(), Some(field), "{e}");
        let message = e.to_string();
        assert!(message.contains(says), "{message}");
        assert!(message.contains("rotationally symmetric"), "{message}");
    }
}

/// A fold mirror's stated clear aperture is a circle in its tilted plane: the unfolded plane
/// keeps the circle inscribed in its footprint, r cos(tilt).
#[test]
fn a_fold_mirrors_stated_aperture_becomes_its_inscribed_circle() {
    let folded = codev(
        "S 50 5 N-BK7\nSTO\nS -50 20\nS 0 -15 REFL\nCIR 10\nADE 30\nBEN\nS -80 -4 N-F2\n\
         S -200 -30\n",
    )
    .unwrap();
    let r = folded.prescription.surfaces[2].semi_aperture;
    assert!((r - 10.0 * 30f64.to_radians().cos()).abs() < 1e-12, "{r}");
}
