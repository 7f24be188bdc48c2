//! Lenses placed off one common axis (tilted mirrors, decentred lenses, tilted image planes):
//! refused by the readers with the lens as placed, and traced exactly in three dimensions.
#![cfg(feature = "cli")]

mod common;

use common::lensbake;

use lensbake::prescription::formats::{Format, LoadOptions, PlacedLens, read_file, read_str};
use lensbake::prescription::{Medium, Problem};
use lensbake::trace::Outcome;
use lensbake::trace::placed::PlacedTracer;
use serde_json::Value;

fn placed(name: &str) -> PlacedLens {
    let path = common::test_data(&format!("corpus/{name}"));
    let error = read_file(&path, &LoadOptions::default()).unwrap_err();
    match error.problem {
        Problem::NotRotationallySymmetric { lens, .. } => *lens,
        other => panic!("{name}: {other}"),
    }
}

fn unit(tx: f64, ty: f64) -> [f64; 3] {
    let length = (tx * tx + ty * ty + 1.0).sqrt();
    [tx / length, ty / length, 1.0 / length]
}

/// Ray by ray against the peers' 3-D traces (tools/off_axis_peer.py): optiland 0.6.3 for two
/// tilted four-mirror telescopes, a tilted three-mirror one whose third mirror is a toroid, and
/// a chain of fold mirrors ending in a decentred singlet; rayoptics 0.9.8 for a tilted and
/// decentred image plane and a three-mirror telescope of off-axis segments. The 25 points agree
/// to 1e-11 mm (8.5e-14 measured) on lenses 100-500 mm across: both sides follow every
/// surface's tilt and decentre, every mirror, the toroid and the image plane's frame.
#[test]
fn rays_meet_the_image_where_the_peers_trace_them() {
    let text = std::fs::read_to_string(common::test_data("corpus/off_axis_peers.json")).unwrap();
    let peers: Value = serde_json::from_str(&text).unwrap();
    let mut compared = 0;
    for (name, peer) in peers.as_object().unwrap() {
        let mut lens = placed(name);
        let glass_indices = peer.get("glass_indices").and_then(Value::as_object);
        if let Some(indices) = glass_indices.filter(|i| !i.is_empty()) {
            // One glass in the lens: it takes the peer's index (its data set is not lensbake's).
            let index = common::num(indices.values().next().unwrap());
            let glasses: Vec<&mut Medium> = lens
                .prescription
                .surfaces
                .iter_mut()
                .map(|s| &mut s.medium)
                .filter(|m| matches!(m, Medium::Glass(_)))
                .collect();
            assert_eq!((indices.len(), glasses.len()), (1, 1));
            for medium in glasses {
                *medium = Medium::Index(index);
            }
        }
        let tracer = PlacedTracer::new(&lens, peer["wavelength_nm"].as_f64().unwrap()).unwrap();
        let rays = common::nums_rows(&peer["rays"]);
        let (expected, global) = match peer.get("image") {
            Some(points) => (common::nums_rows(points), false),
            None => (common::nums_rows(&peer["global"]), true),
        };
        for (ray, want) in rays.iter().zip(&expected) {
            let traced = tracer.trace([ray[0], ray[1], 0.0], unit(ray[2], ray[3]));
            assert_eq!(traced.outcome, Outcome::Ok, "{name} {ray:?}");
            let got = if global {
                traced.position.to_vec()
            } else {
                tracer.image_coordinates(traced.position).to_vec()
            };
            for (g, w) in got.iter().zip(want) {
                assert!(
                    (g - w).abs() < 1e-11,
                    "{name} {ray:?}: {got:?} against {want:?}"
                );
            }
            compared += 1;
        }
    }
    assert_eq!(compared, 25);
}

/// An off-axis paraboloid: a collimated beam along the paraboloid's axis, through a stop
/// decentred 60 mm from it, meets the focus R/2 behind the vertex exactly (a paraboloid images
/// an axial point at infinity without aberration), whatever part of the mirror it uses. The
/// chief ray is aimed at the decentred stop's centre by real rays and lands on the focus; every
/// ray of the pupil grid does.
#[test]
fn an_off_axis_paraboloid_focuses_a_collimated_beam_to_a_point() {
    let text = "RDM\nEPD 20\nYAN 0\nWL 550\nSO 0 1e20\nS 0 100\nSTO\nYDE 60\nDAR\n\
                S -400 -200 REFL\nCON\nK -1\nSI 0 0\nGO\n";
    let error = read_str(text, None, Format::CodeV, &LoadOptions::default()).unwrap_err();
    let Problem::NotRotationallySymmetric { offence, lens } = error.problem else {
        panic!("{}", error.problem);
    };
    assert!(
        offence.contains("surface 1 is decentred 60.000000 mm"),
        "{offence}"
    );
    let tracer = PlacedTracer::new(&lens, 550.0).unwrap();
    let spot = tracer.collimated_spot([0.0, 0.0], 20.0, 16).unwrap();
    assert_eq!(spot.arrived, spot.launched);
    assert!(spot.launched > 150, "{}", spot.launched);
    assert!(
        spot.chief[0].abs() < 1e-12 && spot.chief[1].abs() < 1e-11,
        "{:?}",
        spot.chief
    );
    assert!(spot.rms_radius.unwrap() < 1e-11, "{:?}", spot.rms_radius);
    // The beam's numerical aperture about its chief ray is geometry alone: each ray of the 16x16
    // grid (10 mm pupil radius) leaves the mirror at (x, 60 + y, r^2 / 4f) for the focus
    // (0, 0, f), and the chief ray leaves (0, 60, 60^2 / 4f).
    let f = 200.0;
    let from_focus = |x: f64, y: f64| [x, y, (x * x + y * y) / (4.0 * f) - f];
    let chief = from_focus(0.0, 60.0);
    let mut widest: f64 = 0.0;
    for row in 0..16 {
        for column in 0..16 {
            let (u, v) = (
                (2 * column + 1) as f64 / 16.0 - 1.0,
                (2 * row + 1) as f64 / 16.0 - 1.0,
            );
            if u * u + v * v <= 1.0 {
                let q = from_focus(10.0 * u, 60.0 + 10.0 * v);
                let cross = [
                    q[1] * chief[2] - q[2] * chief[1],
                    q[2] * chief[0] - q[0] * chief[2],
                    q[0] * chief[1] - q[1] * chief[0],
                ];
                let norm = |a: [f64; 3]| (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
                widest = widest.max(norm(cross) / (norm(q) * norm(chief)));
            }
        }
    }
    assert!(
        (spot.image_numerical_aperture - widest).abs() < 1e-12,
        "{} against {widest}",
        spot.image_numerical_aperture
    );
    // Tilting the beam by a small angle turns the reflected chief ray by as much about the mirror
    // point at height h = 60 mm, which lies L = f + h^2 / 4f from the focus (f = 200 mm); the
    // ray meets the focal plane at cos(theta) = (f - h^2 / 4f) / L to the axis, so the image
    // moves L angle / cos(theta) = 1.8668 mm along it. Coma of the off-axis segment blurs it.
    let tilted = tracer.collimated_spot([0.0, 0.5], 20.0, 16).unwrap();
    let h = 60.0;
    let length = f + h * h / (4.0 * f);
    let cos_theta = (f - h * h / (4.0 * f)) / length;
    let shift = length * 0.5_f64.to_radians() / cos_theta;
    let moved = tilted.centroid.unwrap()[1].abs();
    assert!(
        (moved - shift).abs() < 1e-3 * shift,
        "{moved} against {shift}"
    );
    assert!(tilted.rms_radius.unwrap() > 1e-4, "{tilted:?}");
}

/// `lens check` prints where each surface sits and the 3-D trace of the file's fields; every
/// other command refuses the lens in one located `error:` line that points to `lens check`.
#[test]
fn lens_check_traces_a_lens_off_the_axis_and_other_commands_refuse_it() {
    let file = "tests/data/corpus/rayoptics__HoO-V2C18Ex66.zmx";
    let check = lensbake(&["lens", "check", file]);
    let listing = String::from_utf8_lossy(&check.stdout);
    assert_eq!(check.status.code(), Some(0), "{listing}");
    for says in [
        "off the axis: surface 3 is tilted 16.440000 deg to the axis (moved by `TYPE COORDBRK`)",
        "object at infinity, entrance pupil 20 mm (32x32 grid)",
        "812/812",
    ] {
        assert!(listing.contains(says), "{says} in {listing}");
    }
    // Five fields, as the file lists them; the 9 deg fields mirror each other in x.
    let rows: Vec<Vec<f64>> = listing
        .lines()
        .skip_while(|l| !l.contains("chief ray x"))
        .skip(1)
        .map(|l| {
            l.split_whitespace()
                .take(4)
                .map(|v| v.parse().unwrap())
                .collect()
        })
        .collect();
    assert_eq!(rows.len(), 5, "{listing}");
    assert_eq!(rows[3][2], -rows[4][2]);
    assert_eq!(rows[3][3], rows[4][3]);

    // `analyze` takes it in three dimensions; the centred wave optics refuse it, naming where.
    let analyze = lensbake(&["analyze", file]);
    let report = String::from_utf8_lossy(&analyze.stdout);
    assert_eq!(analyze.status.code(), Some(0), "{report}");
    assert!(
        report.contains("from real rays of the 3-D trace"),
        "{report}"
    );
    let wave = lensbake(&["wavefront", file, "--field-deg", "0"]);
    let stderr = String::from_utf8_lossy(&wave.stderr);
    assert_eq!(wave.status.code(), Some(2), "{stderr}");
    assert_eq!(
        stderr.lines().filter(|l| l.starts_with("error:")).count(),
        1,
        "{stderr}"
    );
    assert!(
        stderr.contains(":100, surface 3, field `TYPE COORDBRK`"),
        "{stderr}"
    );
    assert!(
        stderr
            .contains("(`lensbake lens check`, `analyze`, `trace` and `plot spot` trace this lens"),
        "{stderr}"
    );
}

/// The 3-D trace takes an object at infinity with an entrance-pupil diameter; other conditions
/// are refused in one `error:` line, exit 2.
#[test]
fn lens_check_refuses_conditions_the_3d_trace_does_not_take() {
    let dir = std::env::temp_dir().join(format!("lensbake-off-axis-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("near.seq");
    std::fs::write(
        &file,
        "RDM\nEPD 20\nYAN 0\nWL 550\nSO 0 500\nS 0 100\nSTO\nYDE 60\nDAR\n\
         S -400 -200 REFL\nCON\nK -1\nSI 0 0\nGO\n",
    )
    .unwrap();
    let check = lensbake(&["lens", "check", file.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&check.stderr);
    assert_eq!(check.status.code(), Some(2), "{stderr}");
    assert_eq!(
        stderr.lines().filter(|l| l.starts_with("error:")).count(),
        1,
        "{stderr}"
    );
    assert!(stderr.contains("an object at infinity"), "{stderr}");

    // A field whose chief ray misses a mirror (a sphere of radius 10 mm, 60 mm below the
    // decentred stop) is reported in its row; the command still succeeds.
    let file = dir.join("miss.seq");
    std::fs::write(
        &file,
        "RDM\nEPD 2\nYAN 0\nWL 550\nSO 0 1e20\nS 0 100\nSTO\nYDE 60\nDAR\nS -10 -5 REFL\nSI 0 0\n",
    )
    .unwrap();
    let check = lensbake(&["lens", "check", file.to_str().unwrap()]);
    let listing = String::from_utf8_lossy(&check.stdout);
    assert_eq!(check.status.code(), Some(0), "{listing}");
    assert!(
        listing.contains(
            "not traced: the chief ray of field (0.000000, 0.000000) deg misses surface 2"
        ),
        "{listing}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A centred three-mirror anastigmat whose mirrors are off-axis segments (rectangular apertures
/// centred up to 397 mm off the axis) and whose beam the file sizes by an F-number: the focal
/// length from a near-axial real ray matches rayoptics 0.9.8's paraxial EFL (499.9996204043674
/// mm) to 1e-9, and a tilted lens has none.
#[test]
fn a_centred_lens_with_off_axis_segments_has_the_peers_focal_length() {
    let lens = placed("rayoptics__US08011793-1.zmx");
    assert_eq!(lens.outlines.iter().flatten().count(), 3);
    let tracer = PlacedTracer::new(&lens, 550.0).unwrap();
    let f = tracer.centred_focal_length().unwrap();
    assert!(common::relative(f, 499.9996204043674) < 1e-9, "{f}");
    let tilted = PlacedTracer::new(&placed("rayoptics__HoO-V2C18Ex66.zmx"), 550.0).unwrap();
    assert_eq!(tilted.centred_focal_length(), None);
}

/// `plot spot` on a lens off the axis draws the 3-D trace's spots: the library's spot diagrams of
/// a tilted four-mirror telescope (HoO-V2C18Ex66, symmetric about its y-z plane) hold, per field
/// of the file, every ray `lens check` counts with its RMS radius; the fields (9, 0) and (-9, 0)
/// deg give mirror-image spots; the Airy disk is 0.61 lambda / NA; and the command writes the
/// picture where other plots of the lens are refused.
#[test]
fn spot_diagrams_of_a_lens_off_the_axis_come_from_the_3d_trace() {
    use lensbake::report::{FigureOptions, placed_spot_plot};
    use lensbake::trace::placed::{PlacedBeam, SPOT_GRID};
    let lens = placed("rayoptics__HoO-V2C18Ex66.zmx");
    let plot = placed_spot_plot("Ex66", &lens, &FigureOptions::default()).unwrap();
    let tracer = PlacedTracer::new(&lens, 550.0).unwrap();
    let beam = PlacedBeam::of(&lens, &tracer).unwrap();
    assert_eq!(plot.fields.len(), beam.fields_deg.len());
    for (panel, field) in plot.fields.iter().zip(&beam.fields_deg) {
        assert_eq!([panel.field_x_deg, panel.field_deg], *field);
        let spot = tracer
            .collimated_spot(*field, beam.pupil_diameter, SPOT_GRID)
            .unwrap();
        let [drawn] = panel.spots.as_slice() else {
            panic!("one wavelength: {:?}", panel.spots.len());
        };
        assert_eq!(drawn.points.len(), spot.arrived);
        assert_eq!(drawn.rms_radius_mm, spot.rms_radius.unwrap());
        let airy = 0.5 * 1.219_67 * 550e-6 / spot.image_numerical_aperture;
        assert!(
            (drawn.airy_radius_mm - airy).abs() < 1e-15,
            "{}",
            drawn.airy_radius_mm
        );
    }
    let side = |x: f64| {
        let panel = plot.fields.iter().find(|f| f.field_x_deg == x).unwrap();
        let mut points = panel.spots[0].points.clone();
        points.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
        points
    };
    let (right, left) = (side(9.0), side(-9.0));
    let mut mirrored: Vec<(f64, f64)> = left.iter().map(|&(x, y)| (-x, y)).collect();
    mirrored.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.total_cmp(&b.1)));
    assert_eq!(right.len(), mirrored.len());
    for (a, b) in right.iter().zip(&mirrored) {
        assert!(
            (a.0 - b.0).abs() < 1e-9 && (a.1 - b.1).abs() < 1e-9,
            "{a:?} {b:?}"
        );
    }

    let path = common::test_data("corpus/rayoptics__HoO-V2C18Ex66.zmx");
    let out = std::env::temp_dir().join(format!("lensbake-placed-spot-{}.svg", std::process::id()));
    let plot = |kind: &str| {
        let args = [
            "plot",
            kind,
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        lensbake(&args)
    };
    let o = plot("spot");
    assert_eq!(
        o.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    let svg = std::fs::read_to_string(&out).unwrap();
    assert!(svg.contains("spot diagrams"), "the title");
    std::fs::remove_file(&out).unwrap();
    let o = plot("ray-fan");
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("`plot spot`"));
    assert!(!out.exists());
}

/// A file whose aperture floats by the stop's size (Zemax `FLOA`) gets, in the 3-D trace, the
/// on-axis beam that fills the stop: for a lens centred but for a rectangular aperture behind
/// the stop, the paraxial entrance pupil of the same lens with a round aperture there (the stop
/// sits between two singlets, so the pupil is not the stop itself).
#[test]
fn a_floating_aperture_fills_the_stop_in_the_3d_trace() {
    use lensbake::system::LensSystem;
    use lensbake::trace::Tracer;
    use lensbake::trace::placed::{PlacedBeam, PupilFrom};
    let zemax = |aperture: &str| {
        format!(
            "MODE SEQ\nFLOA\nWAVM 1 0.55 1\nSURF 0\n  DISZ INFINITY\nSURF 1\n  CURV 0.02\n  \
             DISZ 5\n  GLAS N-BK7\n  CLAP 0 12 0\nSURF 2\n  CURV -0.01\n  DISZ 10\n  \
             CLAP 0 12 0\nSURF 3\n  STOP\n  DISZ 8\n  CLAP 0 4 0\nSURF 4\n  CURV -0.03\n  \
             DISZ 4\n  GLAS N-BK7\n  {aperture}\nSURF 5\n  CURV -0.01\n  DISZ 60\n  \
             CLAP 0 12 0\nSURF 6\n  DISZ 0\n"
        )
    };
    let read = |text: &str| read_str(text, None, Format::Zemax, &LoadOptions::default());
    let round = read(&zemax("CLAP 0 12 0")).unwrap();
    let system = LensSystem::from_prescription(round.prescription).unwrap();
    let paraxial = Tracer::new(&system.at(550.0))
        .paraxial_entrance_pupil()
        .unwrap()
        .diameter;
    assert!(
        (paraxial - 8.0).abs() > 0.1,
        "the pupil is not the stop: {paraxial}"
    );
    let e = read(&zemax("SQAP 12 9 0")).unwrap_err();
    let Problem::NotRotationallySymmetric { lens, .. } = e.problem else {
        panic!("{e}");
    };
    let tracer = PlacedTracer::new(&lens, 550.0).unwrap();
    let beam = PlacedBeam::of(&lens, &tracer).unwrap();
    assert_eq!(beam.pupil_from, PupilFrom::StopSize { semi_aperture: 4.0 });
    assert!(
        (beam.pupil_diameter - paraxial).abs() < 1e-9 * paraxial,
        "{} against {paraxial}",
        beam.pupil_diameter
    );
}

/// Rectangular and decentred clear apertures (CODE V `REX`, `REY`, `ADX`, `ADY`) clip where the
/// surface's own frame puts them: a beam parallel to a paraboloid's axis meets it at the height
/// it was launched at, so the aperture's edges are the launch plane's.
#[test]
fn rectangular_and_decentred_apertures_clip_at_their_edges() {
    let lens = |aperture: &str| {
        let text = format!(
            "RDM\nEPD 20\nYAN 0\nWL 550\nSO 0 1e20\nS 0 100\nSTO\nYDE 60\nDAR\n\
             S -400 -200 REFL\nCON\nK -1\n{aperture}\nSI 0 0\nGO\n"
        );
        match read_str(&text, None, Format::CodeV, &LoadOptions::default()).map(|_| ()) {
            Err(e) => match e.problem {
                Problem::NotRotationallySymmetric { lens, .. } => {
                    PlacedTracer::new(&lens, 550.0).unwrap()
                }
                other => panic!("{other}"),
            },
            Ok(()) => panic!("read as a centred lens"),
        }
    };
    let outcome =
        |tracer: &PlacedTracer, x: f64, y: f64| tracer.trace([x, y, 0.0], [0.0, 0.0, 1.0]).outcome;
    let clipped = Outcome::Vignetted { surface: 2 };
    let rectangle = lens("REX 5; REY 3; ADX 1; ADY 60");
    for (x, y, passes) in [
        (5.99, 62.99, true),
        (-3.99, 57.01, true),
        (6.01, 60.0, false),
        (-4.01, 60.0, false),
        (1.0, 63.01, false),
        (1.0, 56.99, false),
    ] {
        let want = if passes { Outcome::Ok } else { clipped };
        assert_eq!(outcome(&rectangle, x, y), want, "rectangle at ({x}, {y})");
    }
    let circle = lens("CIR 4; ADY 60");
    for (x, y, passes) in [(0.0, 63.99, true), (2.8, 62.8, true), (2.9, 62.9, false)] {
        let want = if passes { Outcome::Ok } else { clipped };
        assert_eq!(outcome(&circle, x, y), want, "circle at ({x}, {y})");
    }
    // A central obscuration moves with the aperture's decentre.
    let ring = lens("CIR 4; CIR OBS 1; ADY 60");
    for (x, y, passes) in [(0.0, 60.99, false), (0.0, 61.01, true), (0.0, 0.5, false)] {
        let want = if passes { Outcome::Ok } else { clipped };
        assert_eq!(outcome(&ring, x, y), want, "ring at ({x}, {y})");
    }
    // An ellipse of semi-axes 5 (x) and 3 (y): (4, 1.7) is inside (0.64 + 0.32), (4, 1.9) is
    // not (0.64 + 0.40), though both are inside the rectangle around it.
    let ellipse = lens("ELX 5; ELY 3; ADY 60");
    for (x, y, passes) in [
        (4.99, 60.0, true),
        (0.0, 57.01, true),
        (4.0, 61.7, true),
        (4.0, 61.9, false),
        (-4.0, 58.1, false),
        (5.01, 60.0, false),
    ] {
        let want = if passes { Outcome::Ok } else { clipped };
        assert_eq!(outcome(&ellipse, x, y), want, "ellipse at ({x}, {y})");
    }
    // Half a rectangle or an ellipse is refused where it stands, and so is an ellipse on a
    // rectangle.
    for (aperture, why) in [
        ("REX 5", "needs both REX and REY"),
        ("ELY 5", "needs both ELX and ELY"),
        (
            "REX 5\nREY 3\nELX 4\nELY 2",
            "both a rectangular and an elliptical",
        ),
    ] {
        let text = format!(
            "RDM\nEPD 20\nSO 0 1e20\nS 0 100\nSTO\nS -400 -200 REFL\n{aperture}\nSI 0 0\nGO\n"
        );
        let e = read_str(&text, None, Format::CodeV, &LoadOptions::default()).unwrap_err();
        assert!(e.to_string().contains(why), "{e}");
        assert_eq!(e.location.line, Some(7));
    }
}

/// Zemax `ELAP a b` is an elliptical clear aperture (semi-axes a in x, b in y), which leaves
/// the lens to the 3-D trace; with equal axes it is the circle `CLAP 0 a` and the lens stays
/// centred. CODE V's `ELX`, `ELY` with equal axes are its `CIR`.
#[test]
fn elliptical_apertures_are_outlines_and_round_ones_circles() {
    let zemax = |aperture: &str| {
        format!(
            "MODE SEQ\nENPD 10\nWAVM 1 0.55 1\nSURF 0\n  DISZ INFINITY\nSURF 1\n  STOP\n  \
             CURV 0.02\n  DISZ 5\n  GLAS N-BK7\n  {aperture}\nSURF 2\n  CURV -0.02\n  \
             DISZ 47\n  CLAP 0 8 0\nSURF 3\n  DISZ 0\n"
        )
    };
    let read = |text: &str, format| read_str(text, None, format, &LoadOptions::default());
    let e = read(&zemax("ELAP 6 4 0"), Format::Zemax).unwrap_err();
    let Problem::NotRotationallySymmetric { offence, lens } = e.problem else {
        panic!("{e}");
    };
    assert!(offence.contains("elliptical clear aperture"), "{offence}");
    let tracer = PlacedTracer::new(&lens, 550.0).unwrap();
    let outcome = |x: f64, y: f64| tracer.trace([x, y, -1.0], [0.0, 0.0, 1.0]).outcome;
    assert_eq!(outcome(5.9, 0.0), Outcome::Ok);
    assert_eq!(outcome(0.0, 3.9), Outcome::Ok);
    assert_eq!(outcome(0.0, 4.1), Outcome::Vignetted { surface: 1 });
    assert_eq!(outcome(4.5, 3.0), Outcome::Vignetted { surface: 1 });
    let round = read(&zemax("ELAP 6 6 0"), Format::Zemax).unwrap();
    assert_eq!(round.prescription.surfaces[0].semi_aperture, 6.0);
    let round = read(
        "EPD 10\nSO 0 1e20\nS 50 5 N-BK7\nELX 6\nELY 6\nS -50 47\nCIR 8\nSI 0 0\nGO\n",
        Format::CodeV,
    )
    .unwrap();
    assert_eq!(round.prescription.surfaces[0].semi_aperture, 6.0);
    let e = read(&zemax("ELAP 6 0 0"), Format::Zemax).unwrap_err();
    assert!(e.to_string().contains("passes no ray"), "{e}");
}

/// A cylinder is the circle z(y) at every x: a ray in a plane x = const stays in it (the normal
/// has no x component) and crosses the cylindrical lens exactly as the meridional ray of the
/// same height crosses the spherical lens of the same radius, which the centred tracer traces.
#[test]
fn a_cylindrical_lens_bends_rays_in_y_as_the_spherical_lens_of_its_section() {
    let zemax = |kind: &str| {
        format!(
            "MODE SEQ\nUNIT MM\nENPD 3.2\nWAVM 1 0.5876 1\nSURF 0\n  DISZ INFINITY\nSURF 1\n  \
             STOP\n  TYPE {kind}\n  CURV 0.495\n  DISZ 3.8\n  GLAS N-BK7\n  DIAM 2\nSURF 2\n  \
             CURV 0\n  DISZ 1.03\n  DIAM 2\nSURF 3\n"
        )
    };
    let (offence, line, cylinder, tracer) = toroidal_and_standard(zemax, 587.6);
    assert_eq!(offence, "surface 1 is a cylinder");
    assert_eq!(line, Some(7));
    for (x, y) in [(0.0, 0.3), (1.7, -0.9), (-2.5, 1.5), (3.0, 1.9)] {
        let through_cylinder = cylinder.trace([x, y, 0.0], [0.0, 0.0, 1.0]);
        assert_eq!(through_cylinder.outcome, Outcome::Ok);
        let meridional = lensbake::trace::Ray::new([0.0, y, -1.0], [0.0, 0.0, 1.0]).unwrap();
        let through_sphere = tracer.trace(meridional, lensbake::trace::Travel::Forward);
        assert_eq!(through_sphere.outcome, Outcome::Ok);
        // The centred trace ends on the last surface; carry it on to the image plane.
        let (last, b) = (
            through_sphere.ray.position(),
            through_sphere.ray.direction(),
        );
        let to_image = (3.8 + 1.03 - last[2]) / b[2];
        let q: Vec<f64> = (0..3).map(|k| last[k] + to_image * b[k]).collect();
        let p = through_cylinder.position;
        assert_eq!(p[0], x, "({x}, {y})");
        assert_eq!(through_cylinder.direction[0], 0.0);
        assert!(
            (p[1] - q[1]).abs() < 1e-12 && (p[2] - q[2]).abs() < 1e-12,
            "{p:?} {q:?}"
        );
        let a = through_cylinder.direction;
        assert!(
            (a[1] - b[1]).abs() < 1e-14 && (a[2] - b[2]).abs() < 1e-14,
            "{a:?} {b:?}"
        );
    }
}

/// A toroid whose radius of rotation equals its y-z radius is the sphere of that radius: skew
/// rays reflected by it land where the centred tracer's sphere sends them.
#[test]
fn a_toroid_turned_on_its_own_radius_is_the_sphere() {
    let zemax = |kind: &str| {
        format!(
            "MODE SEQ\nUNIT MM\nENPD 20\nWAVM 1 0.55 1\nSURF 0\n  DISZ INFINITY\nSURF 1\n  \
             DISZ 10\nSURF 2\n  STOP\n  TYPE {kind}\n  CURV 0.01\n  PARM 1 100\n  DISZ -50\n  \
             GLAS MIRROR\n  DIAM 15\nSURF 3\n"
        )
    };
    let (offence, _, toroid, tracer) = toroidal_and_standard(zemax, 550.0);
    assert_eq!(offence, "surface 2 is a toroid");
    for (x, y, tx, ty) in [
        (-5.0, 2.0, 0.01, 0.02),
        (-5.0, 2.0, 0.1, 0.0),
        (5.0, 0.0, 0.0, 0.1),
    ] {
        let d = unit(tx, ty);
        let through_toroid = toroid.trace([x, y, 0.0], d);
        assert_eq!(through_toroid.outcome, Outcome::Ok);
        let start = lensbake::trace::Ray::new([x, y, 0.0], d).unwrap();
        let through_sphere = tracer.trace(start, lensbake::trace::Travel::Forward);
        let (last, b) = (
            through_sphere.ray.position(),
            through_sphere.ray.direction(),
        );
        let to_image = (-40.0 - last[2]) / b[2];
        for k in 0..3 {
            let q = last[k] + to_image * b[k];
            assert!(
                (through_toroid.position[k] - q).abs() < 1e-11,
                "{through_toroid:?} {q}"
            );
        }
    }
}

/// A Zemax file with a TOROIDAL surface read for the 3-D trace (the refusal's offence and line,
/// the tracer), and the same file with that surface STANDARD read by the centred tracer.
fn toroidal_and_standard(
    zemax: impl Fn(&str) -> String,
    wavelength_nm: f64,
) -> (String, Option<usize>, PlacedTracer, lensbake::trace::Tracer) {
    let options = LoadOptions::default();
    let error = read_str(&zemax("TOROIDAL"), None, Format::Zemax, &options).unwrap_err();
    let Problem::NotRotationallySymmetric { offence, lens } = error.problem else {
        panic!("{}", error.problem);
    };
    let placed = PlacedTracer::new(&lens, wavelength_nm).unwrap();
    let sphere = read_str(&zemax("STANDARD"), None, Format::Zemax, &options).unwrap();
    let system = lensbake::system::LensSystem::new(sphere.prescription, &sphere.map).unwrap();
    let centred = lensbake::trace::Tracer::new(&system.at(wavelength_nm));
    (offence, error.location.line, placed, centred)
}

/// `trace` runs a lens off the axis through the 3-D trace: JSON rays in the global frame land
/// where optiland puts them, with the image-plane point; backward rays are refused.
#[test]
fn the_trace_command_traces_a_lens_off_the_axis_forward() {
    let text = std::fs::read_to_string(common::test_data("corpus/off_axis_peers.json")).unwrap();
    let peers: Value = serde_json::from_str(&text).unwrap();
    let peer = &peers["rayoptics__HoO-V2C18Ex66.zmx"];
    let dir = std::env::temp_dir().join(format!("lensbake-off-axis-trace-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let rays = dir.join("rays.json");
    let inputs: Vec<String> = common::nums_rows(&peer["rays"])
        .iter()
        .map(|r| {
            let d = unit(r[2], r[3]);
            format!(
                "{{\"origin\": [{}, {}, 0], \"direction\": [{}, {}, {}]}}",
                r[0], r[1], d[0], d[1], d[2]
            )
        })
        .collect();
    std::fs::write(&rays, format!("[{}]", inputs.join(", "))).unwrap();
    let file = "tests/data/corpus/rayoptics__HoO-V2C18Ex66.zmx";
    let rays = rays.to_str().unwrap();
    let run = lensbake(&["trace", file, "--rays", rays, "--json"]);
    assert_eq!(
        run.status.code(),
        Some(0),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let traced: Value = serde_json::from_slice(&run.stdout).unwrap();
    let expected = common::nums_rows(&peer["global"]);
    assert_eq!(traced.as_array().unwrap().len(), expected.len());
    for (ray, want) in traced.as_array().unwrap().iter().zip(&expected) {
        assert_eq!(ray["status"], "ok");
        assert_eq!(ray["image"].as_array().unwrap().len(), 2);
        for (g, w) in common::nums(&ray["position"]).iter().zip(want) {
            assert!((g - w).abs() < 1e-11, "{ray} against {want:?}");
        }
    }
    let backward = lensbake(&["trace", file, "--rays", rays, "--backward"]);
    let stderr = String::from_utf8_lossy(&backward.stderr);
    assert_eq!(backward.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("runs forward only"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}
