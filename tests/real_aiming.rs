//! Real ray aiming (Zemax RAIM 2): a relative pupil coordinate is the real ray through that point
//! of the stop, scaled to the radius the axial beam fills there. Checked against optiland's
//! iterative aiming (tests/data/real_aiming_peer.json, tools/real_aiming_peer.py) on a corpus
//! lens that asks for it, and for what the file's RAIM line and the flags choose.
#![cfg(feature = "plot")]

mod common;

use lensbake::analysis::{ConditionOverrides, DesignConditions, Origin};
use lensbake::lenses;
use lensbake::paraxial::Paraxial;
use lensbake::prescription::RayAiming;
use lensbake::prescription::formats::{Format, LoadOptions, read_str, write_ron, write_zemax};
use lensbake::report::{Figure, FigureOptions, PlotKind, figure};
use lensbake::system::LensSystem;
use lensbake::trace::analyses::RealRays;
use lensbake::trace::{Apertures, Travel};
use serde_json::Value;

/// Where lensbake and optiland may differ: optiland's aiming stops within about 1e-13 mm of its
/// target on the stop, which moves the last surface's point by up to 1e-12 mm (measured:
/// 1.04e-12 mm, directions 1.6e-14).
const POINT_MM: f64 = 1e-10;
const DIRECTION: f64 = 1e-12;

fn corpus_system(name: &str) -> LensSystem {
    let path = common::test_data("corpus").join(name);
    lenses::load(path.to_str().unwrap(), &LoadOptions::default())
        .unwrap_or_else(|e| panic!("{name}: {e}"))
        .system
}

fn peer() -> Value {
    let text = std::fs::read_to_string(common::test_data("real_aiming_peer.json")).unwrap();
    serde_json::from_str(&text).unwrap()
}

/// The reference wavelength's real-ray analyses of `system` under its design conditions, with
/// `aiming` (and `epd_mm` where given), and the stop radius real aiming fills.
fn real_rays(
    system: &LensSystem,
    aiming: RayAiming,
    epd_mm: Option<f64>,
) -> (DesignConditions, RealRays, Option<f64>) {
    let overrides = ConditionOverrides {
        ray_aiming: Some(aiming),
        epd_mm,
        ..ConditionOverrides::default()
    };
    let conditions = DesignConditions::resolve(system, &overrides).unwrap();
    let at = system.at(conditions.reference_nm);
    let paraxial = Paraxial::new(&at, &conditions.paraxial_options()).unwrap();
    let real = RealRays::new(&at, paraxial);
    let radius = conditions.aiming_stop_radius(&real).unwrap();
    let real = match radius {
        Some(radius) => real.aimed_at_stop(radius),
        None => real,
    };
    (conditions, real, radius)
}

/// Where the ray of `field` at pupil (px, py) leaves the last surface: (x, y) there and its
/// direction cosines (L, M).
fn leaving(real: &RealRays, field: f64, pupil: [f64; 2]) -> ([f64; 2], [f64; 2]) {
    let ray = real.pupil_ray(field, pupil[0], pupil[1]).unwrap();
    let traced = real
        .tracer()
        .trace_with(ray, Travel::Forward, Apertures::Ignored);
    assert!(
        traced.outcome.is_ok(),
        "{field} deg {pupil:?}: {}",
        traced.outcome
    );
    let (p, d) = (traced.ray.position(), traced.ray.direction());
    ([p[0], p[1]], [d[0], d[1]])
}

fn pair(value: &Value) -> [f64; 2] {
    let v = common::nums(value);
    [v[0], v[1]]
}

#[test]
fn real_aiming_matches_optiland_and_fills_the_stop() {
    let peer = peer();
    let system = corpus_system(peer["lens"].as_str().unwrap());
    let (conditions, real, radius) = real_rays(&system, RayAiming::Real, None);
    assert_eq!(
        conditions.reference_nm,
        common::num(&peer["wavelength_nm"]),
        "the same wavelength"
    );
    let radius = radius.expect("real aiming fills a stop radius");
    let peer_radius = common::num(&peer["stop_radius_mm"]);
    assert!(
        (radius - peer_radius).abs() < 1e-12,
        "stop radius {radius} against optiland's {peer_radius}"
    );
    let (_, paraxially_aimed, _) = real_rays(&system, RayAiming::Paraxial, None);
    let stop = real.tracer().stop_surface();
    let mut largest_aiming_shift: f64 = 0.0;
    for ray in peer["rays"].as_array().unwrap() {
        let field = common::num(&ray["field_deg"]);
        let pupil = pair(&ray["pupil"]);
        let what = format!("{field} deg, pupil {pupil:?}");
        // The aimed ray crosses the stop where it was sent.
        let launched = real.pupil_ray(field, pupil[0], pupil[1]).unwrap();
        let at_stop = real
            .tracer()
            .trace_to(launched, Travel::Forward, stop, Apertures::Ignored)
            .ray
            .position();
        for axis in 0..2 {
            assert!(
                (at_stop[axis] - pupil[axis] * radius).abs() < 1e-11,
                "{what}: crosses the stop at {at_stop:?}"
            );
        }
        let (point, direction) = leaving(&real, field, pupil);
        let (peer_point, peer_direction) = (pair(&ray["last_surface"]), pair(&ray["direction"]));
        for axis in 0..2 {
            assert!(
                (point[axis] - peer_point[axis]).abs() < POINT_MM,
                "{what}: leaves the last surface at {point:?}, optiland {peer_point:?}"
            );
            assert!(
                (direction[axis] - peer_direction[axis]).abs() < DIRECTION,
                "{what}: direction {direction:?}, optiland {peer_direction:?}"
            );
        }
        let (unaimed, _) = leaving(&paraxially_aimed, field, pupil);
        largest_aiming_shift =
            largest_aiming_shift.max((unaimed[0] - point[0]).hypot(unaimed[1] - point[1]));
    }
    // The comparison tells the two aimings apart: paraxial aiming lands elsewhere by far more
    // than the tolerance.
    assert!(
        largest_aiming_shift > 1e3 * POINT_MM,
        "paraxial and real aiming differ by only {largest_aiming_shift} mm"
    );
}

#[test]
fn the_zemax_raim_line_chooses_the_aiming_and_a_flag_overrides_it() {
    let peer = peer();
    let system = corpus_system(peer["lens"].as_str().unwrap());
    let stated = DesignConditions::resolve(&system, &ConditionOverrides::default()).unwrap();
    assert_eq!(
        (stated.ray_aiming, stated.ray_aiming_from),
        (RayAiming::Real, Origin::File)
    );
    let flagged = DesignConditions::resolve(
        &system,
        &ConditionOverrides {
            ray_aiming: Some(RayAiming::Paraxial),
            ..ConditionOverrides::default()
        },
    )
    .unwrap();
    assert_eq!(
        (flagged.ray_aiming, flagged.ray_aiming_from),
        (RayAiming::Paraxial, Origin::Flag)
    );

    let cooke = include_str!("../examples/lenses/cooke_triplet.zmx");
    let aiming_of = |raim: &str| {
        let text = format!("{raim}\n{cooke}");
        read_str(&text, None, Format::Zemax, &LoadOptions::default())
            .map(|loaded| {
                loaded
                    .prescription
                    .provenance
                    .conditions
                    .and_then(|c| c.ray_aiming)
            })
            .map_err(|error| error.to_string())
    };
    assert_eq!(
        aiming_of("RAIM 0 0 1 1 0 0 0 0 0"),
        Ok(Some(RayAiming::Paraxial))
    );
    assert_eq!(
        aiming_of("RAIM 0 1 1 1 0 0 0 0 0"),
        Ok(Some(RayAiming::Paraxial))
    );
    assert_eq!(
        aiming_of("RAIM 0 2 1 1 0 0 0 0 0"),
        Ok(Some(RayAiming::Real))
    );
    assert_eq!(aiming_of(""), Ok(None));
    let error = aiming_of("RAIM 0 7 1 1 0 0 0 0 0").unwrap_err();
    assert!(
        error.contains("line 1") && error.contains("RAIM"),
        "an unknown aiming is refused where it is: {error}"
    );

    // Written as Zemax and as RON, the lens keeps the aiming it states.
    let aiming = |prescription: &lensbake::prescription::Prescription| {
        prescription
            .provenance
            .conditions
            .as_ref()
            .and_then(|c| c.ray_aiming)
    };
    let stated = &system.prescription;
    assert_eq!(aiming(stated), Some(RayAiming::Real));
    let zemax = write_zemax(stated).unwrap();
    let read_back = read_str(&zemax, None, Format::Zemax, &LoadOptions::default()).unwrap();
    assert_eq!(aiming(&read_back.prescription), Some(RayAiming::Real));
    let ron = write_ron(stated);
    let read_back = read_str(&ron, None, Format::Ron, &LoadOptions::default()).unwrap();
    assert_eq!(aiming(&read_back.prescription), Some(RayAiming::Real));
}

/// Where the stop radius comes from. Wide open (the design conditions' rule for dgauss-50mm)
/// the stop is filled to its clear semi-aperture: the axial rim ray crosses the stop at its edge,
/// which paraxial aiming (through the paraxial image of the stop) misses by the pupil's
/// spherical aberration (0.106 mm). With a smaller stated pupil, real aiming keeps the stated
/// beam: its rim ray is the paraxially aimed one, crossing the stop inside its edge.
#[test]
fn the_stop_is_filled_wide_open_and_a_stated_pupil_keeps_its_rim_ray() {
    let system = lenses::load("dgauss-50mm", &LoadOptions::default())
        .unwrap()
        .system;
    let rim_height = |real: &RealRays| {
        let ray = real.pupil_ray(0.0, 0.0, 1.0).unwrap();
        real.tracer()
            .trace_to(
                ray,
                Travel::Forward,
                real.tracer().stop_surface(),
                Apertures::Ignored,
            )
            .ray
            .position()[1]
    };
    // Real aiming stops within 1e-13 (1 + stop radius) mm of its target.
    const AIMED_MM: f64 = 1e-11;

    let (conditions, real, radius) = real_rays(&system, RayAiming::Real, None);
    let at = system.at(conditions.reference_nm);
    let semi_aperture = at.surfaces[at.stop].semi_aperture;
    assert_eq!(radius, Some(semi_aperture));
    assert!((rim_height(&real) - semi_aperture).abs() < AIMED_MM);
    let (_, paraxially_aimed, _) = real_rays(&system, RayAiming::Paraxial, None);
    assert!(
        (rim_height(&paraxially_aimed) - semi_aperture).abs() > 0.01,
        "paraxial aiming misses the rim by the pupil's aberration"
    );

    let stated = Some(20.0);
    let (_, real, radius) = real_rays(&system, RayAiming::Real, stated);
    let (_, paraxially_aimed, _) = real_rays(&system, RayAiming::Paraxial, stated);
    let rim = rim_height(&paraxially_aimed);
    let radius = radius.unwrap();
    assert!(
        radius < semi_aperture - 1.0,
        "{radius} against {semi_aperture}"
    );
    assert!((radius - rim).abs() < AIMED_MM, "{radius} against {rim}");
    assert!((rim_height(&real) - rim).abs() < AIMED_MM);
}

/// The 193 nm lithography lens (US 2003/0048547 A1, table 3) states an object NA whose paraxial
/// pupil is wider than its stop passes and asks for real aiming: with it the rays fill the stop,
/// and the wave figures that paraxial aiming cannot draw (its rim rays are totally reflected)
/// are drawn.
#[test]
fn the_lithography_lens_draws_its_wavefront_with_the_real_aiming_it_asks_for() {
    let name = "patent2zmx__US20030048547A1-embodiment-table-3.zmx";
    let system = corpus_system(name);
    let draw = |aiming| {
        figure(
            PlotKind::WavefrontMap,
            name,
            &system,
            &FigureOptions {
                ray_aiming: Some(aiming),
                ..FigureOptions::default()
            },
        )
    };
    assert!(
        draw(RayAiming::Paraxial).is_err(),
        "paraxial aiming sends rim rays the lens totally reflects"
    );
    let Ok(Figure::WavefrontMap(map)) = draw(RayAiming::Real) else {
        panic!("a wavefront map with real aiming")
    };
    // Diffraction limited by Maréchal's criterion (0.07 waves RMS), as a lithography lens must
    // be: 0.0053 waves measured.
    assert!(
        map.rms_waves < 0.07,
        "RMS wavefront error {} waves",
        map.rms_waves
    );
}

/// The fisheye's entrance pupil moves and grows with the field: at 54.56 degrees paraxial aiming
/// sends most rays of the hexapolar pattern where the lens stops them, and real aiming fills the
/// stop. At its claimed 77.95 degrees no ray passes either way, and the spot plot says so in a
/// panel of its own instead of leaving the row empty.
#[test]
fn the_fisheye_spot_fills_with_real_aiming_and_a_dark_field_says_so() {
    let system = lenses::load("fisheye-10mm", &LoadOptions::default())
        .unwrap()
        .system;
    let spots = |aiming| {
        let options = FigureOptions {
            ray_aiming: Some(aiming),
            ..FigureOptions::default()
        };
        let Ok(Figure::Spot(plot)) = figure(PlotKind::Spot, "fisheye-10mm", &system, &options)
        else {
            panic!("a spot plot")
        };
        plot.fields
            .iter()
            .map(|f| {
                (
                    f.field_deg,
                    f.spots.iter().map(|s| s.points.len()).collect(),
                )
            })
            .collect::<Vec<(f64, Vec<usize>)>>()
    };
    let (paraxial, real) = (spots(RayAiming::Paraxial), spots(RayAiming::Real));
    for drawn in [&paraxial, &real] {
        assert_eq!(drawn.len(), 3, "a row per design field: {drawn:?}");
        assert_eq!(
            drawn[0].1,
            [0],
            "the dark top field has its panel: {drawn:?}"
        );
    }
    let (passed_paraxial, passed_real) = (paraxial[1].1[0], real[1].1[0]);
    assert!(
        passed_real > 5 * passed_paraxial,
        "at {} deg: {passed_real} rays pass aimed at the stop, {passed_paraxial} aimed \
         paraxially",
        real[1].0
    );
}

/// Aimed at the stop, the two analytic lenses keep their perfect axial image: the plano-
/// hyperbolic relay images its object 40 mm out without aberration, and a refracting sphere
/// images a beam converging on its outer aplanatic point (a virtual object 50 mm behind the
/// vertex) onto the inner one. Real aiming from a point object (the unknowns are direction
/// tangents) and onto a virtual one (start points on a plane) both reach the same wavefront as
/// paraxial aiming: flat to rounding, every sample aimed and passed.
#[test]
fn real_aiming_keeps_the_analytic_lenses_perfect_on_axis() {
    use lensbake::wave::{PupilTrace, Sampling, WaveLens};
    for (file, distance) in [
        ("perfect_relay.ron", 40.0),
        ("aplanatic_surface.ron", -50.0),
    ] {
        let path = common::test_data(file);
        let system = lenses::load(path.to_str().unwrap(), &LoadOptions::default())
            .unwrap()
            .system;
        let lens = WaveLens::Real {
            system: &system,
            epd_mm: None,
            object_distance_mm: Some(distance),
            ray_aiming: RayAiming::Real,
        };
        let nm = system.design_wavelength_nm();
        let sampling = Sampling {
            samples: 32,
            grid: 64,
        };
        let stats = PupilTrace::trace(&lens, 0.0, nm, nm, sampling)
            .unwrap()
            .wavefront(0.0)
            .unwrap()
            .stats();
        // Measured: 4.8e-11 and 8.5e-11 waves.
        assert!(
            stats.pv_waves < 1e-9,
            "{file}: {} waves peak to valley",
            stats.pv_waves
        );
        assert_eq!(
            stats.transmitted_samples, stats.pupil_samples,
            "{file}: every aimed sample passes"
        );
    }
}
