//! Ray aiming, the paraxial entrance pupil and the traceable field against the oracle files.

mod common;

use common::{ORACLE_LENSES, OracleLens, load_oracle, num, vec3};
use lensbake::system::LensSystem;
use lensbake::trace::{
    Apertures, Ray, RaySource, StopAim, Tracer, Travel, aim_at_stop, traceable_field_deg,
};
use serde_json::Value;

fn tracer(oracle: &OracleLens) -> Tracer {
    let system = LensSystem::from_prescription(oracle.prescription.clone()).unwrap();
    Tracer::new(&system.at(system.design_wavelength_nm()))
}

fn oracles() -> impl Iterator<Item = OracleLens> {
    ORACLE_LENSES.into_iter().map(load_oracle)
}

/// The oracle's aimed rays: real chief rays through the stop centre at each distortion field
/// (rayoptics, by root finding) and rays aimed at a stop height.
#[test]
fn aimed_rays_match_oracle_start_points() {
    let mut checked = 0;
    for oracle in oracles() {
        let (name, lens) = (&oracle.name, oracle.lens());
        let tracer = tracer(&oracle);
        let stop_radius =
            num(&lens["prescription"]["surfaces"][tracer.stop_surface() - 1]["semi_aperture"]);
        let mut cases: Vec<(Value, f64)> = lens["infinite_conjugate"]["distortion"]["points"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| (p["rayoptics"].clone(), 0.0))
            .collect();
        for ray in lens["infinite_conjugate"]["real_rays"]["rays"]
            .as_array()
            .unwrap()
        {
            let id = ray["id"].as_str().unwrap();
            if let Some(fraction) = id.split("_stop").nth(1) {
                cases.push((ray.clone(), fraction.parse::<f64>().unwrap() * stop_radius));
            }
        }
        assert!(cases.len() >= 4, "{name}: aimed rays present");
        for (ray, stop_y) in cases {
            let start = vec3(&ray["start_point"]);
            let direction = vec3(&ray["start_dir"]);
            let source = RaySource::Collimated {
                direction,
                start_z: start[2],
            };
            let aimed = aim_at_stop(&tracer, &source, [0.0, stop_y]).unwrap();
            let got = aimed.position();
            assert!(
                (got[0] - start[0]).abs() < 1e-9 && (got[1] - start[1]).abs() < 1e-9,
                "{name}: aimed start {got:?}, oracle {start:?}"
            );
            checked += 1;
        }
    }
    assert!(checked >= 16);
}

#[test]
fn aiming_a_point_source_off_axis_in_both_stop_coordinates() {
    // A skew aim from a finite object point: the ray found must cross the stop where asked.
    for oracle in oracles() {
        let lens = oracle.lens();
        let tracer = tracer(&oracle);
        let stop = tracer.stop_surface();
        let stop_radius = num(&lens["prescription"]["surfaces"][stop - 1]["semi_aperture"]);
        let source = RaySource::Point {
            position: [30.0, -120.0, -1000.0],
        };
        let target = [0.4 * stop_radius, -0.5 * stop_radius];
        let ray = aim_at_stop(&tracer, &source, target).unwrap();
        let at_stop = tracer
            .trace_to(
                ray,
                lensbake::trace::Travel::Forward,
                stop,
                lensbake::trace::Apertures::Ignored,
            )
            .ray
            .position();
        assert!((at_stop[0] - target[0]).abs() < 1e-11 && (at_stop[1] - target[1]).abs() < 1e-11);
        assert_eq!(ray.position(), [30.0, -120.0, -1000.0]);
    }
}

#[test]
fn traceable_field_within_oracle_bracket() {
    for oracle in oracles() {
        let (name, lens) = (&oracle.name, oracle.lens());
        let bracket =
            &lens["infinite_conjugate"]["max_field_with_traceable_chief_ray"]["with_apertures"];
        let (ok, fail) = (
            num(&bracket["last_ok_deg"]),
            num(&bracket["first_fail_deg"]),
        );
        let field = traceable_field_deg(&tracer(&oracle), 0.5);
        assert!(
            field >= ok - 1e-6 && field <= fail + 1e-6,
            "{name}: {field} not in [{ok}, {fail}]"
        );
    }
}

#[test]
fn aiming_finds_the_chief_ray_where_the_paraxial_guess_fails() {
    // A fisheye: at 70 degrees the paraxial entrance pupil is far from the real one, and the
    // ray through its centre misses the lens; the search must still find the chief ray.
    let lens = lensbake::lenses::load("fisheye-10mm", &Default::default()).unwrap();
    let tracer = Tracer::new(&lens.system.at(lens.system.design_wavelength_nm()));
    let angle = 70f64.to_radians();
    let direction = [0.0, angle.sin(), angle.cos()];
    let start_z = tracer.front_start_z();
    let pupil = tracer.paraxial_entrance_pupil().unwrap();
    let back = (pupil.z - start_z) / direction[2];
    let paraxial_guess = Ray::new([0.0, -back * direction[1], start_z], direction).unwrap();
    let stop = tracer.stop_surface();
    let guess_at_stop = tracer.trace_to(paraxial_guess, Travel::Forward, stop, Apertures::Ignored);
    assert!(
        !guess_at_stop.outcome.is_ok(),
        "the paraxial guess must fail for this test to mean anything"
    );
    let source = RaySource::Collimated { direction, start_z };
    let chief = aim_at_stop(&tracer, &source, [0.0, 0.0]).unwrap();
    let at_stop = tracer
        .trace_to(chief, Travel::Forward, stop, Apertures::Ignored)
        .ray
        .position();
    assert!(
        at_stop[0].abs() < 1e-11 && at_stop[1].abs() < 1e-11,
        "{at_stop:?}"
    );
}

#[test]
fn a_field_aimed_from_its_chief_ray_finds_the_rays_each_aim_finds() {
    // Every point of a pupil grid at the fisheye's top field, where the paraxial pupil misses
    // the lens, and a skew grid from a finite object point through the double Gauss: the aims
    // started from the chief ray cross the stop where asked and are the rays each separate aim
    // finds, point for point, unreachable points included.
    let cases = [
        ("fisheye-10mm", RaySource::collimated(77.95, 0.0)),
        (
            "dgauss-50mm",
            RaySource::Point {
                position: [30.0, -120.0, -1000.0],
            },
        ),
    ];
    for (name, source) in cases {
        let lens = lensbake::lenses::load(name, &Default::default()).unwrap();
        let at = lens.system.at(lens.system.design_wavelength_nm());
        let tracer = Tracer::new(&at);
        let source = match source {
            RaySource::Collimated { direction, .. } => RaySource::Collimated {
                direction,
                start_z: tracer.front_start_z(),
            },
            point => point,
        };
        let stop = tracer.stop_surface();
        let radius = at.surfaces[stop - 1].semi_aperture;
        let field = StopAim::new(&tracer, source);
        let (mut reached, mut points) = (0, 0);
        for i in 0..9 {
            for j in 0..9 {
                let target = [
                    radius * (i as f64 / 4.0 - 1.0),
                    radius * (j as f64 / 4.0 - 1.0),
                ];
                points += 1;
                let alone = aim_at_stop(&tracer, &source, target);
                let from_chief = field.aim(target);
                assert_eq!(alone.is_ok(), from_chief.is_ok(), "{name} {target:?}");
                let (Ok(alone), Ok(from_chief)) = (alone, from_chief) else {
                    continue;
                };
                reached += 1;
                let at_stop = tracer
                    .trace_to(from_chief, Travel::Forward, stop, Apertures::Ignored)
                    .ray
                    .position();
                assert!(
                    (at_stop[0] - target[0]).hypot(at_stop[1] - target[1]) < 1e-11,
                    "{name} {target:?}: {at_stop:?}"
                );
                for axis in 0..3 {
                    assert!(
                        (alone.position()[axis] - from_chief.position()[axis]).abs() < 1e-9
                            && (alone.direction()[axis] - from_chief.direction()[axis]).abs()
                                < 1e-12,
                        "{name} {target:?}: {alone:?} against {from_chief:?}"
                    );
                }
            }
        }
        assert!(
            reached >= points / 2,
            "{name}: {reached} of {points} reached"
        );
    }
}
