//! One table for a focus range (unit focusing, the film moves): lookups from film planes between
//! the pupil's focus nodes against the exact trace, the sampling pupil's conservativeness and
//! density there, and the command line (bake a range, show it, evaluate and render inside it,
//! refuse outside it).
#![cfg(feature = "cli")]

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use lensbake::lrtf::bake::{
    BakeError, BakeRequest, FilmPointRays, bake, first_order, rear_search_radius,
};
use lensbake::lrtf::measure::table_error_focused;
use lensbake::lrtf::{FocusError, LrtfTable, Ray};
use lensbake::paraxial::{CannotFocus, ImageInsideLens};
use lensbake::prescription::{Medium, Prescription, Provenance, Shape, StopShape, Surface};
use lensbake::pupil::RearTest;
use lensbake::system::LensSystem;
use lensbake::trace::Tracer;

fn dgauss() -> LensSystem {
    lensbake::lenses::load("dgauss-50mm", &Default::default())
        .expect("bundled double Gauss")
        .system
}

/// The double Gauss focused from infinity to 1 m in one 32^3 table.
fn range_table(system: &LensSystem) -> LrtfTable {
    let request = BakeRequest {
        resolution: [32; 3],
        focus_mm: None,
        focus_near_mm: Some(1000.0),
        ..BakeRequest::default()
    };
    bake(system, &request).expect("the range bakes")
}

/// Film planes strictly between the sampling pupil's focus nodes (none on a node).
fn planes_between_nodes(table: &LrtfTable) -> Vec<f64> {
    let sampling = &table.layers[0].sampling;
    let [first, last] = sampling.film_z;
    let intervals = sampling.nodes.len() - 1;
    (0..intervals)
        .flat_map(|j| {
            [0.23, 0.5, 0.81].map(|f| first + (last - first) * (j as f64 + f) / intervals as f64)
        })
        .collect()
}

#[test]
fn range_lookups_between_focus_nodes_match_the_exact_trace_like_a_single_focus_table() {
    let system = dgauss();
    let design = system.at(system.design_wavelength_nm());
    let tracer = Tracer::new(&design);
    let table = range_table(&system);
    let focus = &table.info.focus;
    assert!(table.layers[0].sampling.nodes.len() >= 2);
    let [far_z, near_z] = focus.film_z_range();
    assert!(near_z > far_z + 2.0, "film travel {far_z}..{near_z}");
    // The sidecar's focus map puts the film where the paraxial bake does.
    for distance in [None, Some(1000.0), Some(1800.0)] {
        let paraxial = first_order(&design, distance).unwrap().z_image;
        let mapped = focus.film_z(distance);
        assert!(
            (mapped - paraxial).abs() < 1e-9 * paraxial,
            "{distance:?}: {mapped} vs {paraxial}"
        );
    }
    for film_z in [planes_between_nodes(&table)[1], 0.5 * (far_z + near_z)] {
        // The object distance focused on this plane, and a single-focus table baked for it.
        let distance = focus.focal_product / (film_z - focus.rear_focal_z) - focus.front_focal_z;
        let single = bake(
            &system,
            &BakeRequest {
                resolution: [32; 3],
                focus_mm: Some(distance),
                max_film_radius: Some(table.layers[0].sampling.max_film_radius()),
                ..BakeRequest::default()
            },
        )
        .unwrap();
        let efl = first_order(&design, Some(distance))
            .unwrap()
            .first_order
            .efl;
        let e = table_error_focused(&table, 0, film_z, &tracer, efl, 1920.0, 4000, 0xfeed);
        let s = table_error_focused(
            &single,
            0,
            single.layers[0].frame.film_plane_z,
            &tracer,
            efl,
            1920.0,
            4000,
            0xfeed,
        );
        eprintln!("film z {film_z:.3}: range {e:?}\n  single {s:?}");
        // Measured at 32^3, 4000 rays: range p99 0.029 mrad and 4.6 um against 0.027 mrad and
        // 4.5 um for the single-focus table; validity 14 against 7 mismatched rays (the
        // range's pupil circle between focus nodes is inflated, so more of its rays fall near
        // a vignetting edge). Allowed: 30 % more direction error, 2.5 times the mismatches,
        // and the bounds of the single-focus accuracy test (tests/lrtf_accuracy.rs). A range
        // table addressing rays through the wrong film plane errs by whole milliradians.
        assert!(
            e.direction_mrad.p99 < 1.3 * s.direction_mrad.p99 + 1e-3,
            "{e:?} vs {s:?}"
        );
        assert!(e.direction_mrad.p99 < 0.04, "{e:?}");
        assert!(e.position_um.p99 < 6.5, "{e:?}");
        assert!(
            e.validity_mismatch < 2.5 * s.validity_mismatch + 1e-3,
            "{e:?} vs {s:?}"
        );
        assert!(e.image_px.p99 < 0.5, "{e:?}");
    }
}

#[test]
fn sampling_pupil_holds_every_passing_ray_between_focus_nodes_and_its_pdf_integrates_to_one() {
    let system = dgauss();
    let table = range_table(&system);
    let layer = &table.layers[0];
    let at =
        lensbake::lrtf::bake::stopped_down(&system, layer.wavelength_nm, layer.stop_semi_aperture);
    let tracer = Tracer::new(&at);
    let rear_z = layer.frame.rear_plane_z;
    let search = rear_search_radius(&at);
    let max_r = layer.sampling.max_film_radius();
    let grid = 96;
    let rear_points: Vec<[f64; 2]> = (0..grid)
        .flat_map(|i| {
            (0..=grid / 2).map(move |j| {
                let step = 2.0 * search / (grid - 1) as f64;
                [-search + i as f64 * step, j as f64 * step]
            })
        })
        .collect();
    let (mut passing, mut outside, mut undomained) = (0usize, 0usize, 0usize);
    for film_z in planes_between_nodes(&table) {
        for k in 0..=24 {
            let film_radius = max_r * k as f64 / 24.0;
            let circle = layer.sampling.circle_at(film_radius, film_z);
            let rays = FilmPointRays {
                tracer: &tracer,
                film_radius,
                film_z,
                rear_z,
            };
            let mut passes = vec![false; rear_points.len()];
            rays.test(&rear_points, &mut passes);
            for (p, ok) in rear_points.iter().zip(passes) {
                if !ok {
                    continue;
                }
                passing += 1;
                if (p[0] - circle.centre_x).hypot(p[1]) > circle.radius {
                    outside += 1;
                }
                // The transfer table addresses the same line through the reference plane:
                // every passing ray lies in its domain.
                let d = [p[0] - film_radius, p[1], rear_z - film_z];
                let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
                let ray = Ray {
                    origin: [film_radius, 0.0, film_z],
                    direction: d.map(|v| v / n),
                };
                if !table.locate(0, &ray).is_some_and(|l| l.in_domain) {
                    undomained += 1;
                }
            }
            // The density of the interpolated circle integrates to one (midpoint rule).
            if k % 6 == 3 {
                let n = 400;
                let h = 2.0 * circle.radius / n as f64;
                let mut integral = 0.0;
                for i in 0..n {
                    for j in 0..n {
                        let p = [
                            circle.centre_x - circle.radius + (i as f64 + 0.5) * h,
                            -circle.radius + (j as f64 + 0.5) * h,
                        ];
                        integral += layer.sampling.pdf(film_radius, film_z, p) * h * h;
                    }
                }
                assert!((integral - 1.0).abs() < 5e-3, "integral {integral}");
                let s = layer.sampling.sample(film_radius, film_z, [0.3, 0.8]);
                assert_eq!(s.pdf, layer.sampling.pdf(film_radius, film_z, s.point));
            }
        }
    }
    eprintln!("{passing} passing rays, {outside} outside the circle, {undomained} off the table");
    assert!(passing > 100_000, "{passing}");
    assert_eq!(outside, 0);
    assert_eq!(undomained, 0);
}

fn lensbake(dir: &Path, args: &[&str]) -> Output {
    common::finished(
        Command::new(env!("CARGO_BIN_EXE_lensbake"))
            .current_dir(dir)
            .args(args),
        None,
    )
}

fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("lensbake-focus-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn the_command_line_bakes_a_range_and_serves_any_focus_inside_it() {
    let dir = scratch("cli");
    let bake = lensbake(
        &dir,
        &[
            "bake",
            "dgauss-50mm",
            "--resolution",
            "8",
            "--focus-mm",
            "2000..800",
        ],
    );
    assert!(bake.status.success(), "{}", text(&bake));
    let table = dir.join("tables/dgauss-50mm/focus-2000-800mm");
    assert!(table.join("lrtf.ron").exists(), "{}", text(&bake));
    let info = lensbake(&dir, &["lrtf", "info", table.to_str().unwrap()]);
    assert!(
        text(&info).starts_with("focus 2000..800 mm (film z"),
        "{}",
        text(&info)
    );
    std::fs::write(
        dir.join("rays.json"),
        r#"[{"origin": [1.0, 0.0, 90.0], "direction": [0.0, 0.0, -1.0]}]"#,
    )
    .unwrap();
    let eval = |focus: &str| {
        let args = [
            "lrtf",
            "eval",
            table.to_str().unwrap(),
            "--rays",
            "rays.json",
            "--focus-mm",
            focus,
        ];
        lensbake(&dir, &args)
    };
    let inside = eval("1200");
    assert!(inside.status.success(), "{}", text(&inside));
    assert!(
        text(&inside).contains("ray 0: ok  position"),
        "{}",
        text(&inside)
    );
    for outside in ["500", "inf"] {
        let refused = eval(outside);
        assert_eq!(refused.status.code(), Some(2), "{}", text(&refused));
        assert!(
            text(&refused).contains("outside the table's focus range 2000..800 mm"),
            "{}",
            text(&refused)
        );
    }
    // A render focused inside the range finds the table under tables/<lens>/ and bakes none;
    // one outside refuses the table named with --table.
    let render = |focus: &str, table_arg: Option<&Path>| {
        let mut args = vec![
            "render",
            "--lens",
            "dgauss-50mm",
            "--model",
            "baked",
            "--backend",
            "cpu",
            "--width",
            "24",
            "--height",
            "16",
            "--spp",
            "2",
            "--focus-mm",
            focus,
            "--out",
            "out.exr",
        ];
        if let Some(t) = table_arg {
            args.extend(["--table", t.to_str().unwrap()]);
        }
        lensbake(&dir, &args)
    };
    let reused = render("1000", None);
    assert!(reused.status.success(), "{}", text(&reused));
    assert!(!text(&reused).contains("baked "), "{}", text(&reused));
    assert!(dir.join("out.exr").exists());
    let refused = render("500", Some(&table));
    assert_eq!(refused.status.code(), Some(2), "{}", text(&refused));
    assert!(
        text(&refused).contains("outside the table's focus range"),
        "{}",
        text(&refused)
    );
    // A reversed range reads the same; a range with a budget is refused.
    let budget = lensbake(
        &dir,
        &[
            "bake",
            "dgauss-50mm",
            "--focus-mm",
            "800,2000",
            "--error-budget-px",
            "0.5",
        ],
    );
    assert_eq!(budget.status.code(), Some(2), "{}", text(&budget));
    assert!(text(&budget).contains("not a range"), "{}", text(&budget));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn focus_outside_a_range_is_a_typed_error() {
    let system = dgauss();
    let table = bake(
        &system,
        &BakeRequest {
            resolution: [4; 3],
            focus_mm: Some(3000.0),
            focus_near_mm: Some(1500.0),
            ..BakeRequest::default()
        },
    )
    .unwrap();
    let focus = &table.info.focus;
    assert!(focus.film_z_for(Some(2000.0)).is_ok());
    assert!(focus.film_z_for(Some(3000.0)).is_ok() && focus.film_z_for(Some(1500.0)).is_ok());
    for outside in [None, Some(1000.0), Some(5000.0)] {
        assert!(
            matches!(
                focus.film_z_for(outside),
                Err(FocusError::OutsideRange { .. })
            ),
            "{outside:?}"
        );
    }
    assert!(matches!(
        focus.film_z_for(Some(-3.0)),
        Err(FocusError::NotPositive(_))
    ));
    // The near end may not lie beyond the far one.
    let reversed = bake(
        &system,
        &BakeRequest {
            resolution: [4; 3],
            focus_mm: Some(1000.0),
            focus_near_mm: Some(2000.0),
            ..BakeRequest::default()
        },
    );
    assert!(reversed.is_err());
    // A table is focused on a real object: a virtual one (behind surface 1), which the
    // analyses take, is refused.
    let virtual_object = bake(
        &system,
        &BakeRequest {
            resolution: [4; 3],
            focus_mm: Some(-100.0),
            ..BakeRequest::default()
        },
    );
    assert!(
        virtual_object
            .as_ref()
            .is_err_and(|e| e.to_string().contains("object distance must be positive")),
        "{virtual_object:?}"
    );
    // A range reaching inside the front focal length (the telephoto's front focal point lies
    // 333 mm in front) has no real film plane at its near end.
    let telephoto = lensbake::lenses::load("telephoto-250mm", &Default::default())
        .unwrap()
        .system;
    let virtual_near = bake(
        &telephoto,
        &BakeRequest {
            resolution: [4; 3],
            focus_near_mm: Some(300.0),
            ..BakeRequest::default()
        },
    );
    let Err(BakeError::CannotFocus(CannotFocus {
        distance_mm,
        front_focal_mm,
    })) = virtual_near
    else {
        panic!("{virtual_near:?}");
    };
    let design = telephoto.at(telephoto.design_wavelength_nm());
    let first = first_order(&design, None).unwrap().first_order;
    assert_eq!((distance_mm, front_focal_mm), (300.0, -first.z_front_focal));
    assert!(front_focal_mm > 300.0, "{front_focal_mm}");
    // A lens whose rear focal point lies inside it: a plano-convex rod (R 10 mm, n 1.5, 40 mm
    // long, flat back) brings an axial beam to focus 30 mm in, and the flat back images that
    // point 10 / 1.5 mm in front of itself, at z = 40 - 6.667 mm, even for an object at infinity.
    let rod = LensSystem::from_prescription(Prescription {
        provenance: Provenance::default(),
        object_medium: Medium::Air,
        surfaces: vec![
            Surface {
                stop: Some(StopShape::Circle),
                ..Surface::open(Shape::from_radius(10.0), 40.0, Medium::Index(1.5), 4.0)
            },
            Surface::open(Shape::Plane, 10.0, Medium::Air, 4.0),
        ],
    })
    .unwrap();
    let error = bake(&rod, &BakeRequest::default()).unwrap_err();
    let BakeError::ImageInsideLens(ImageInsideLens {
        focus,
        film_z,
        last_vertex_z,
    }) = &error
    else {
        panic!("{error:?}");
    };
    assert_eq!((focus.as_str(), *last_vertex_z), ("infinity", 40.0));
    assert!((film_z - (40.0 - 10.0 / 1.5)).abs() < 1e-12, "{film_z}");
    assert!(
        error
            .to_string()
            .starts_with("cannot focus at infinity: its image plane z = 33.333333 mm"),
        "{error}"
    );
}

/// A table chosen by a budget goes where a plain bake at its focus would put it: a budget bake
/// for the demo scene (focus 2000 mm) must not take the infinity table's place.
#[test]
fn budget_bake_defaults_to_the_focus_directory() {
    let dir = scratch("budget");
    let o = lensbake(
        &dir,
        &[
            "bake",
            "dgauss-50mm",
            "--error-budget-px",
            "0.5",
            "--scene",
            "demo",
        ],
    );
    assert!(o.status.success(), "{}", text(&o));
    let lens_dir = dir.join("tables").join("dgauss-50mm");
    assert!(
        lens_dir.join("focus-2000mm").join("lrtf.ron").exists(),
        "{}",
        text(&o)
    );
    assert!(!lens_dir.join("lrtf.ron").exists(), "{}", text(&o));
    // The scene's options without a budget would be ignored: refused before any bake.
    let o = lensbake(
        &dir,
        &[
            "bake",
            "dgauss-50mm",
            "--film-fraction",
            "NaN",
            "--out",
            "ignored",
        ],
    );
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("without a budget"), "{}", text(&o));
    assert!(!dir.join("ignored").exists());
    let _ = std::fs::remove_dir_all(&dir);
}
