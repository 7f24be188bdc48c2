//! Mirrors and central obscurations: paraxial optics, Seidel sums and the exact trace against
//! identities that hold for reflecting surfaces (the mirror equation, a paraboloid's perfect axial
//! focus, a fold mirror that only turns the lens round), real rays against third-order sums, and
//! the readers' mirror and obscuration keywords.
#![cfg(feature = "render")]

mod common;

use lensbake::analysis::{Analysis, AnalyzeOptions, analyze};
use lensbake::lrtf::bake::{BakeError, BakeRequest, bake};
use lensbake::model::{FirstOrderModels, ModelError};
use lensbake::prescription::formats::{Format, LoadOptions, read_file, read_str};
use lensbake::prescription::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
use lensbake::system::LensSystem;
use lensbake::trace::{Apertures, Outcome, Ray, RayBatch, Tracer, Travel};
use std::path::PathBuf;

fn sphere(radius: f64) -> Shape {
    Shape::from_radius(radius)
}

fn stopped(s: Surface) -> Surface {
    Surface {
        stop: Some(StopShape::Circle),
        ..s
    }
}

fn system(surfaces: Vec<Surface>) -> LensSystem {
    LensSystem::from_prescription(Prescription {
        provenance: Provenance {
            title: "mirror test".into(),
            design_wavelength_nm: Some(587.5618),
            ..Provenance::default()
        },
        object_medium: Medium::Air,
        surfaces,
    })
    .unwrap()
}

fn analysis(system: &LensSystem, epd: f64, field_deg: f64) -> Analysis {
    let options = AnalyzeOptions {
        epd_mm: Some(epd),
        field_deg: Some(field_deg),
        ..AnalyzeOptions::default()
    };
    analyze(system, &options).unwrap()
}

/// A concave mirror of radius -200 mm, stop on the mirror, the image plane at its focus.
fn concave_mirror(conic: f64) -> LensSystem {
    let shape = if conic == 0.0 {
        sphere(-200.0)
    } else {
        Shape::Conic {
            curvature: -1.0 / 200.0,
            conic,
        }
    };
    system(vec![stopped(Surface::open(
        shape,
        -100.0,
        Medium::Mirror,
        12.0,
    ))])
}

/// Fits y(rho) = a rho + b rho^3 + c rho^5 + d rho^7 to the heights `heights` of marginal rays at
/// pupil fractions `rhos` in the paraxial image plane and returns b, the third-order transverse
/// aberration at the pupil edge.
fn third_order_coefficient(rhos: &[f64], heights: &[f64]) -> f64 {
    // Normal equations of the four-term polynomial, solved by Gaussian elimination.
    let basis = |rho: f64| [rho, rho.powi(3), rho.powi(5), rho.powi(7)];
    let mut m = [[0.0f64; 5]; 4];
    for (&rho, &y) in rhos.iter().zip(heights) {
        let b = basis(rho);
        for i in 0..4 {
            for j in 0..4 {
                m[i][j] += b[i] * b[j];
            }
            m[i][4] += b[i] * y;
        }
    }
    for col in 0..4 {
        for row in col + 1..4 {
            let f = m[row][col] / m[col][col];
            let pivot_row = m[col];
            for (entry, pivot) in m[row].iter_mut().zip(pivot_row).skip(col) {
                *entry -= f * pivot;
            }
        }
    }
    let mut x = [0.0; 4];
    for row in (0..4).rev() {
        let tail: f64 = (row + 1..4).map(|k| m[row][k] * x[k]).sum();
        x[row] = (m[row][4] - tail) / m[row][row];
    }
    x[1]
}

/// Heights in the paraxial image plane of axial rays entering at pupil fractions `rhos` of
/// `epd`, collimated, from `start_z`.
fn marginal_heights(
    system: &LensSystem,
    a: &Analysis,
    epd: f64,
    start_z: f64,
    rhos: &[f64],
) -> Vec<f64> {
    let tracer = Tracer::new(&system.at(system.design_wavelength_nm()));
    rhos.iter()
        .map(|rho| {
            let ray = Ray::new([0.0, rho * epd / 2.0, start_z], [0.0, 0.0, 1.0]).unwrap();
            let traced = tracer.trace(ray, Travel::Forward);
            assert_eq!(traced.outcome, Outcome::Ok, "rho {rho}");
            traced
                .ray
                .point_at_z(a.first_order.z_paraxial_image)
                .unwrap()[1]
        })
        .collect()
}

/// The transverse spherical aberration S_I / (2 n' u') against the third-order term fitted to
/// real rays in the paraxial image plane.
fn assert_spherical_matches_real_rays(system: &LensSystem, a: &Analysis, epd: f64, start_z: f64) {
    let rhos: Vec<f64> = (1..=15).map(|k| 0.02 * k as f64).collect();
    let heights = marginal_heights(system, a, epd, start_z, &rhos);
    let fitted = third_order_coefficient(&rhos, &heights);
    // The aperture at which the fit reads the cubic term is rho = 1.
    let image_slope = a.paraxial_rays.marginal.last().unwrap().u_after;
    let seidel = a.seidel.sums.spherical / (2.0 * a.first_order.image_index * image_slope);
    assert!(
        (fitted - seidel).abs() < 1e-4 * seidel.abs(),
        "third-order transverse spherical: real rays {fitted}, Seidel {seidel}"
    );
}

#[test]
fn a_spherical_mirror_obeys_the_mirror_equation() {
    let lens = concave_mirror(0.0);
    let a = analysis(&lens, 20.0, 1.0);
    let f = &a.first_order;
    // Signed indices (n' = -1 after the mirror), as CODE V and rayoptics report a mirror: the
    // focal length is n'/power = R/2 = -100 mm, the focus 100 mm in front of the mirror.
    assert!((f.efl + 100.0).abs() < 1e-12, "EFL {}", f.efl);
    assert!((f.bfl + 100.0).abs() < 1e-12, "BFL {}", f.bfl);
    assert!((f.z_paraxial_image + 100.0).abs() < 1e-12);
    assert_eq!(f.image_index, -1.0);
    // f/5: 100 mm of focal length over a 20 mm pupil, positive for a converging mirror.
    assert!((f.f_number - 5.0).abs() < 1e-12, "f/{}", f.f_number);
    // S_I = -A^2 y delta(u/n) with A = y c, delta(u/n) = 2 y c: -2 y^4 c^3 = 0.0025 mm, and the
    // Petzval sum -H^2 c delta(1/n) = 2 H^2 c.
    let y: f64 = 10.0;
    let c: f64 = -1.0 / 200.0;
    assert!((a.seidel.sums.spherical - (-2.0 * y.powi(4) * c.powi(3))).abs() < 1e-15);
    assert!(
        (a.seidel.sums.petzval - 2.0 * a.first_order.lagrange_invariant.powi(2) * c).abs() < 1e-15,
        "Petzval {}",
        a.seidel.sums.petzval
    );
    assert_spherical_matches_real_rays(&lens, &a, 20.0, -10.0);
}

#[test]
fn a_paraboloid_focuses_an_axial_beam_perfectly() {
    let lens = concave_mirror(-1.0);
    let a = analysis(&lens, 20.0, 1.0);
    // The conic term k c^3 y^4 (n' - n) = 2 c^3 y^4 cancels the sphere's -2 y^4 c^3.
    assert!(
        a.seidel.sums.spherical.abs() < 1e-15,
        "{}",
        a.seidel.sums.spherical
    );
    // Every axial ray meets the axis at the focus, 100 mm in front of the vertex, out to the rim.
    let tracer = Tracer::new(&lens.at(587.5618));
    for k in 0..=12 {
        let y = k as f64;
        let traced = tracer.trace(
            Ray::new([0.0, y, -10.0], [0.0, 0.0, 1.0]).unwrap(),
            Travel::Forward,
        );
        assert_eq!(traced.outcome, Outcome::Ok);
        assert!(
            traced.ray.direction()[2] < 0.0,
            "reflected rays travel back"
        );
        let at_focus = traced.ray.point_at_z(-100.0).unwrap();
        assert!(
            at_focus[1].abs() < 1e-12,
            "ray at {y} mm crosses the focal plane at {}",
            at_focus[1]
        );
    }
}

#[test]
fn a_fold_mirror_turns_the_lens_round_and_changes_nothing_else() {
    // A stop plane and a glass singlet, and the same lens behind a flat mirror in the stop
    // plane: every vertex and curvature mirrored in z. The mirror reflects the whole lens, so
    // the signed focal lengths change sign, the Seidel sums are the same, and a ray through
    // the folded lens is the mirror image of the ray through the straight one.
    let glass = Medium::Glass("N-BK7".into());
    let straight = system(vec![
        stopped(Surface::open(Shape::Plane, 20.0, Medium::Air, 8.0)),
        Surface::open(sphere(60.0), 6.0, glass.clone(), 14.0),
        Surface::open(sphere(-90.0), 80.0, Medium::Air, 14.0),
    ]);
    let folded = system(vec![
        stopped(Surface::open(Shape::Plane, -20.0, Medium::Mirror, 8.0)),
        Surface::open(sphere(-60.0), -6.0, glass, 14.0),
        Surface::open(sphere(90.0), -80.0, Medium::Air, 14.0),
    ]);
    let (a, b) = (analysis(&straight, 12.0, 5.0), analysis(&folded, 12.0, 5.0));
    let (fa, fb) = (&a.first_order, &b.first_order);
    assert!(
        (fa.efl + fb.efl).abs() < 1e-12 * fa.efl.abs(),
        "{} vs {}",
        fa.efl,
        fb.efl
    );
    assert!((fa.bfl + fb.bfl).abs() < 1e-12 * fa.bfl.abs());
    assert!((fa.f_number - fb.f_number).abs() < 1e-12 * fa.f_number);
    let (sa, sb) = (a.seidel.sums.as_array(), b.seidel.sums.as_array());
    let scale = sa.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for k in 0..5 {
        assert!(
            (sa[k] - sb[k]).abs() < 1e-12 * scale,
            "S{}: {} vs {}",
            k + 1,
            sa[k],
            sb[k]
        );
    }
    let (ta, tb) = (
        Tracer::new(&straight.at(587.5618)),
        Tracer::new(&folded.at(587.5618)),
    );
    for (y, slope) in [(0.0, 0.05), (5.0, 0.0), (-6.0, 0.08), (3.0, -0.1)] {
        let ray = Ray::new([1.0, y, -5.0], [0.02, slope, 1.0]).unwrap();
        let (ra, rb) = (
            ta.trace(ray, Travel::Forward),
            tb.trace(ray, Travel::Forward),
        );
        assert_eq!(ra.outcome, rb.outcome);
        let (pa, pb) = (
            ra.ray.point_at_z(100.0).unwrap(),
            rb.ray.point_at_z(-100.0).unwrap(),
        );
        let (da, db) = (ra.ray.direction(), rb.ray.direction());
        for k in 0..2 {
            assert!(
                (pa[k] - pb[k]).abs() < 1e-12 * (1.0 + pa[k].abs()),
                "{pa:?} vs {pb:?}"
            );
            assert!((da[k] - db[k]).abs() < 1e-14);
        }
        assert!((da[2] + db[2]).abs() < 1e-14);
    }
}

fn corpus(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/corpus")
        .join(name)
}

fn load(path: &std::path::Path) -> LensSystem {
    let loaded = read_file(path, &LoadOptions::default()).unwrap();
    LensSystem::new(loaded.prescription, &loaded.map).unwrap()
}

/// The Ritchey-Chretien telescope of rayoptics' samples, two conic mirrors: real rays at small
/// apertures confirm lensbake's S_I (0.0036045 mm; rayoptics 0.9.8 reports 0.0036070, see
/// tests/corpus.rs).
#[test]
fn two_conic_mirrors_spherical_aberration_matches_real_rays() {
    let lens = load(&corpus("rayoptics__rc_f16.seq"));
    let a = analyze(&lens, &AnalyzeOptions::default()).unwrap();
    // The primary's sag reaches -370 mm at its rim: start in front of it. The real rays agree
    // with lensbake's sum to 1e-4 of it (below)...
    assert_spherical_matches_real_rays(&lens, &a, a.first_order.entrance_pupil.diameter, -1000.0);
    // ...and rayoptics' 0.0036070 mm lies 7e-4 of it away, seven times that tolerance.
    let rayoptics = 0.0036069543756624967;
    let ours = a.seidel.sums.spherical;
    assert!(
        (rayoptics - ours).abs() > 5e-4 * ours.abs(),
        "{ours} vs {rayoptics}"
    );
}

/// The bundled reflex lens: two Mangin mirrors, a central obscuration, a relay behind.
fn reflex() -> LensSystem {
    lensbake::lenses::load("reflex-1000mm-f7.5", &Default::default())
        .unwrap()
        .system
}

#[test]
fn rays_through_two_mangin_mirrors_retrace_their_path_backward() {
    let lens = reflex();
    let tracer = Tracer::new(&lens.at(587.5618));
    let mut traced_rays = 0;
    for (x, y) in [(30.0, 0.0), (0.0, 40.0), (-35.0, 20.0), (10.0, -55.0)] {
        let start = Ray::new([x, y, -20.0], [0.001, -0.002, 1.0]).unwrap();
        let forward = tracer.trace(start, Travel::Forward);
        assert_eq!(forward.outcome, Outcome::Ok, "ray at ({x}, {y})");
        assert!(
            forward.ray.direction()[2] > 0.0,
            "two mirrors send it on towards +z"
        );
        let back = Ray::new(forward.ray.position(), forward.ray.direction().map(|v| -v)).unwrap();
        let returned = tracer.trace(back, Travel::Backward);
        assert_eq!(returned.outcome, Outcome::Ok);
        // Back at surface 1, travelling out along the incoming ray's line.
        let d = returned.ray.direction();
        let p = returned.ray.point_at_z(-20.0).unwrap();
        assert!(
            (p[0] - x).abs() < 1e-9 && (p[1] - y).abs() < 1e-9,
            "returned to {p:?}"
        );
        for k in 0..3 {
            assert!((d[k] + start.direction()[k]).abs() < 1e-12, "{d:?}");
        }
        traced_rays += 1;
    }
    assert_eq!(traced_rays, 4);
}

#[test]
fn the_central_obscuration_vignettes_the_centre_of_the_beam() {
    let lens = reflex();
    let tracer = Tracer::new(&lens.at(587.5618));
    let outcome = |y: f64| {
        tracer
            .trace(
                Ray::new([0.0, y, -20.0], [0.0, 0.0, 1.0]).unwrap(),
                Travel::Forward,
            )
            .outcome
    };
    // Surface 2's obscuration is 25 mm in radius; the entering beam bends a little on the
    // corrector, so test clear of the edge.
    assert_eq!(outcome(0.0), Outcome::Vignetted { surface: 2 });
    assert_eq!(outcome(20.0), Outcome::Vignetted { surface: 2 });
    assert_eq!(outcome(40.0), Outcome::Ok);
    // Ignoring apertures, the axial ray passes: the obscuration is an aperture, not geometry.
    let axial = Ray::new([0.0, 0.0, -20.0], [0.0, 0.0, 1.0]).unwrap();
    assert_eq!(
        tracer
            .trace_with(axial, Travel::Forward, Apertures::Ignored)
            .outcome,
        Outcome::Ok
    );
    // The reference tracer of chief rays has no obscuration.
    assert_eq!(
        tracer.unobscured().trace(axial, Travel::Forward).outcome,
        Outcome::Ok
    );
}

#[test]
fn the_lane_path_traces_mirrors_bit_for_bit_as_the_one_ray_path() {
    let lens = reflex();
    let tracer = Tracer::new(&lens.at(587.5618));
    let mut batch = RayBatch::new();
    for i in 0..97 {
        let a = i as f64 * 0.7;
        let r = 70.0 * (i as f64 / 97.0).sqrt();
        batch.push(
            Ray::new(
                [r * a.cos(), r * a.sin(), -20.0],
                [0.003 * a.sin(), 0.01, 1.0],
            )
            .unwrap(),
        );
    }
    let passed = common::batch_matches_one_ray(&tracer, &batch);
    assert!(passed > 30, "{passed} rays passed");
    // Backward, as the renderer traces: the rays that came through, reversed. Behind the
    // primary the light meets the elements travelling -z, in the lane kernels too.
    let reversed: RayBatch = batch
        .iter()
        .map(|ray| tracer.trace(ray, Travel::Forward))
        .filter(|traced| traced.outcome.is_ok())
        .map(|traced| {
            let [dx, dy, dz] = traced.ray.direction();
            Ray::new(traced.ray.position(), [-dx, -dy, -dz]).unwrap()
        })
        .collect();
    let returned = common::batch_matches_one_ray_going(&tracer, &reversed, Travel::Backward);
    assert_eq!(
        returned,
        reversed.len(),
        "every reversed ray retraces its path"
    );
}

/// Every chief ray of an obscured lens runs through the obscuration's shadow, so the film a
/// table covers by default is the one the same lens without the obscuration covers (a film of
/// radius 0 before, written as a table no reader would load); the table reads back.
#[test]
fn an_obscured_lens_bakes_the_film_its_clear_twin_covers() {
    let obscured = reflex();
    let mut prescription = obscured.prescription.clone();
    for surface in &mut prescription.surfaces {
        surface.obscuration = None;
    }
    let clear = LensSystem::from_prescription(prescription).unwrap();
    let request = BakeRequest {
        resolution: [4; 3],
        ..BakeRequest::default()
    };
    let table = bake(&obscured, &request).unwrap();
    let radius = table.layers[0].frame.max_film_radius;
    let clear_table = bake(&clear, &request).unwrap();
    assert_eq!(radius, clear_table.layers[0].frame.max_film_radius);
    // The file's largest field is a paraxial image height of 21 mm; its chief ray passes.
    assert!(radius > 21.0, "{radius}");
    let dir = std::env::temp_dir().join(format!("lensbake-mirrors-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    lensbake::lrtf::io::write_table(&table, "reflex", &obscured.prescription, &dir).unwrap();
    let read = lensbake::lrtf::io::read_table(&dir, Some(&obscured.prescription));
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(read.unwrap().layers[0].frame.max_film_radius, radius);
}

/// The catadioptric HoO-V2C18Ex27 with a tenth-power term of 360 on its aspheric surface 3 (a
/// case the command fuzzer made): light still reaches the film centre, but no chief ray from
/// any film point passes the lens. The bake and the trade-off refuse it before any work, where
/// the bake had traced its table and then failed to write it (and before that wrote a table of
/// film radius 0).
#[test]
fn a_lens_no_chief_ray_passes_is_refused_before_the_bake() {
    let text = std::fs::read_to_string(corpus("rayoptics__HoO-V2C18Ex27.zmx")).unwrap();
    let at = text.find("SURF 3").unwrap();
    let (head, tail) = text.split_at(at);
    let text = format!("{head}{}", tail.replacen("PARM 5 0", "PARM 5 360", 1));
    let loaded = read_str(&text, None, Format::Zemax, &LoadOptions::default()).unwrap();
    let lens = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
    let request = BakeRequest {
        resolution: [4; 3],
        ..BakeRequest::default()
    };
    let refused = lensbake::lrtf::bake::BakePlan::new(&lens, &request);
    assert!(
        matches!(refused, Err(BakeError::NoChiefRay { .. })),
        "{:?}",
        refused.err()
    );
    let domain = lensbake::tradeoff::Domain::of(&lens, &Default::default());
    assert!(
        domain.as_ref().is_err_and(|e| e
            .to_string()
            .starts_with("no chief ray from the film plane")),
        "{:?}",
        domain.err()
    );
    // An explicit film radius of 0 is refused as such.
    let zero = BakeRequest {
        max_film_radius: Some(0.0),
        ..request
    };
    assert!(matches!(
        lensbake::lrtf::bake::BakePlan::new(&reflex(), &zero),
        Err(BakeError::FilmRadius(_))
    ));
}

/// rayoptics' unfolded_lenses_w_ape (the folded lenses test laid out straight): from a film
/// point, the stop height of rays aimed across the rear plane with apertures ignored turns back
/// near the rim, so the scan's first sign change is no chief ray. The chief ray is the sign
/// change whose ray passes; the first one alone left the film no radius and the bake refused
/// the lens.
#[test]
fn a_chief_ray_is_found_past_a_sign_change_that_no_passing_ray_makes() {
    let loaded = read_file(
        &corpus("rayoptics__unfolded_lenses_w_ape.seq"),
        &LoadOptions::default(),
    )
    .unwrap();
    let lens = LensSystem::new(loaded.prescription, &loaded.map).unwrap();
    let table = bake(
        &lens,
        &BakeRequest {
            resolution: [4; 3],
            ..BakeRequest::default()
        },
    )
    .unwrap();
    // The paraxial estimate of the same limit: the focal length times the tangent of the
    // largest field whose paraxial chief ray clears every aperture (148.2 mm); the real chief
    // ray, which bends off the paraxial one, ends 2.4 % short of it (144.6 mm).
    let first = analyze(&lens, &AnalyzeOptions::default())
        .unwrap()
        .first_order;
    let paraxial = first.efl * first.max_field_deg_paraxial.unwrap().to_radians().tan();
    let radius = table.layers[0].frame.max_film_radius;
    assert!(
        (radius / paraxial - 1.0).abs() < 0.05,
        "{radius} against {paraxial}"
    );
}

#[test]
fn an_odd_number_of_mirrors_is_analysed_but_not_rendered_or_baked() {
    let lens = concave_mirror(-1.0);
    assert!(!lens.images_behind());
    assert!(matches!(
        FirstOrderModels::of(&lens, None),
        Err(ModelError::ImageInFront)
    ));
    assert!(matches!(
        bake(&lens, &BakeRequest::default()),
        Err(BakeError::ImageInFront)
    ));
    assert!(reflex().images_behind());
}

#[test]
fn a_surface_behind_a_mirror_must_lie_on_the_side_the_light_returns_to() {
    // After the mirror light travels -z, so the next surface 5 mm behind it (+5) is crossed.
    let prescription = Prescription {
        provenance: Provenance::default(),
        object_medium: Medium::Air,
        surfaces: vec![
            stopped(Surface::open(sphere(-200.0), 5.0, Medium::Mirror, 12.0)),
            Surface::open(Shape::Plane, -50.0, Medium::Air, 12.0),
        ],
    };
    let error = LensSystem::from_prescription(prescription)
        .unwrap_err()
        .to_string();
    assert!(
        error.contains("surface 1") && error.contains("crosses"),
        "{error}"
    );
}

#[test]
fn zemax_and_code_v_mirrors_and_obscurations_are_read() {
    let zemax = "MODE SEQ\nUNIT MM\nENPD 20\nWAVM 1 0.55 1\nSURF 0\n  DISZ INFINITY\nSURF 1\n  \
                 CURV 0.0\n  DISZ 50\n  DIAM 12\n  OBSC 0 3\nSURF 2\n  STOP\n  CURV -0.005\n  \
                 CONI -1\n  DISZ -100\n  GLAS MIRROR 0 0 1.5 40\n  DIAM 12\nSURF 3\n";
    let loaded = read_str(zemax, None, Format::Zemax, &LoadOptions::default()).unwrap();
    let surfaces = &loaded.prescription.surfaces;
    assert_eq!(surfaces[0].obscuration, Some(3.0));
    assert_eq!(surfaces[1].medium, Medium::Mirror);
    assert_eq!(surfaces[1].thickness, -100.0);
    // An annular aperture (Zemax CLAP r R) is the clear aperture R with a central obscuration
    // r; with an OBSC as well, the larger of the two blocks the middle.
    let annular = |extra: &str| {
        let text = zemax.replace("  OBSC 0 3\n", &format!("  CLAP 4 10\n{extra}"));
        read_str(&text, None, Format::Zemax, &LoadOptions::default())
    };
    let first = annular("").unwrap().prescription.surfaces[0].clone();
    assert_eq!((first.semi_aperture, first.obscuration), (10.0, Some(4.0)));
    for (extra, blocked) in [("  OBSC 0 3\n", 4.0), ("  OBSC 0 5\n", 5.0)] {
        let first = &annular(extra).unwrap().prescription.surfaces[0];
        assert_eq!(first.obscuration, Some(blocked), "{extra}");
    }
    let e = read_str(
        &zemax.replace("  OBSC 0 3\n", "  CLAP 10 4\n"),
        None,
        Format::Zemax,
        &LoadOptions::default(),
    )
    .unwrap_err();
    assert!(e.to_string().contains("passes no ray"), "{e}");
    let codev = "LEN\nEPD 20\nWL 550\nSO 0 1e10\nS 0 50\n  CIR 12\n  CIR OBS L'A' 3\nS -200 -100 \
                 REFL\n  STO\n  K -1\n  CIR 12\n  CIR HOL 2\nSI 0 0\nGO\n";
    let loaded = read_str(codev, None, Format::CodeV, &LoadOptions::default()).unwrap();
    let surfaces = &loaded.prescription.surfaces;
    assert_eq!(surfaces[0].obscuration, Some(3.0));
    assert_eq!(surfaces[0].semi_aperture, 12.0);
    assert_eq!(surfaces[1].medium, Medium::Mirror);
    assert_eq!(surfaces[1].obscuration, Some(2.0));
    // Both describe an f/5 paraboloid.
    let lens = LensSystem::from_prescription(loaded.prescription).unwrap();
    let a = analyze(&lens, &AnalyzeOptions::default()).unwrap();
    assert!((a.first_order.efl + 100.0).abs() < 1e-12);
    assert!((a.first_order.f_number - 5.0).abs() < 1e-12);
}

/// A secondary mirror sitting in its primary's hole: inside the hole there is no primary, so
/// the secondary may reach past where the primary's sphere would be; outside the hole, in the
/// ring light crosses, surfaces that cross are refused as before.
#[test]
fn a_secondary_in_the_primarys_hole_does_not_cross_it() {
    let telescope = |hole: Option<f64>, secondary_semi_aperture: f64| Prescription {
        provenance: Provenance::default(),
        object_medium: Medium::Air,
        surfaces: vec![
            Surface {
                shape: Shape::Sphere {
                    curvature: -1.0 / 200.0,
                },
                thickness: -0.5,
                medium: Medium::Mirror,
                semi_aperture: 50.0,
                stop: Some(StopShape::Circle),
                obscuration: hole,
            },
            Surface {
                shape: Shape::Sphere {
                    curvature: 1.0 / 20.0,
                },
                thickness: 30.0,
                medium: Medium::Mirror,
                semi_aperture: secondary_semi_aperture,
                stop: None,
                obscuration: None,
            },
        ],
    };
    // At r = 10 the secondary (sag 2.68 mm) lies 2.43 mm beyond the primary's sphere.
    let crosses = |p: Prescription| match LensSystem::from_prescription(p) {
        Err(e) => matches!(
            e.problem,
            lensbake::prescription::Problem::SurfacesCross { .. }
        ),
        Ok(_) => false,
    };
    assert!(
        crosses(telescope(None, 12.0)),
        "no hole: the surfaces cross"
    );
    assert!(
        !crosses(telescope(Some(15.0), 12.0)),
        "the secondary sits in the hole"
    );
    assert!(
        crosses(telescope(Some(15.0), 19.0)),
        "beyond the hole they cross"
    );
}
